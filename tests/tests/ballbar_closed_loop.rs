//! Closed loop: the simulator runs a circular test on a machine with injected errors, the
//! ball-bar diagnosis reads only the traces, and its findings are compared with the run's
//! ground truth (the `figures` of the test, in the diagnosis' own keys and units).

use serde_json::Value;
use vmt_ballbar::{Diagnosis, Options, diagnose};
use vmt_sim::run::Run;

/// The built-in machine with its [job] replaced by `job` (a TOML fragment).
fn run(job: &str, instruments: &str) -> Run {
    run_on(vmt_scenario::BUILTIN_DEFAULT, job, instruments)
}

/// The machine of scenario `text` with its [job] replaced by `job`.
fn run_on(text: &str, job: &str, instruments: &str) -> Run {
    let cut = text.find("[job]").expect("the built-in scenario has a job");
    let toml = format!("{}{job}\n{instruments}\n", &text[..cut]);
    vmt_e2e::simulate_text(&toml, "closed_loop.toml")
}

/// Compares every truth figure of the first test with its finding: within `tol(key, truth)`.
fn compare(run: &Run, d: &Diagnosis, tol: impl Fn(&str, f64) -> f64) {
    let figures = &run.ground_truth["ballbar"]["tests"][0]["figures"];
    let Value::Object(figures) = figures else {
        panic!("no figures in the truth");
    };
    // Every figure of an XY test that the truth states (sim/src/truth.rs, `test_figures`), so
    // that a truth grown smaller cannot pass by comparing less.
    let mut failures: Vec<String> = [
        "eccentricity_x",
        "eccentricity_y",
        "straightness_x",
        "straightness_y",
        "scale_mismatch_xy",
        "squareness_xy",
        "servo_mismatch_xy",
        "backlash_x",
        "backlash_y",
        "lateral_play_x",
        "lateral_play_y",
        "angular_play_x",
        "angular_play_y",
        "cyclic_x",
        "cyclic_y",
        "closing_error_cw",
        "closing_error_ccw",
    ]
    .into_iter()
    .filter(|k| !figures.contains_key(*k))
    .map(|k| format!("{k}: not in the truth"))
    .collect();
    for (key, truth) in figures {
        let truth = truth.as_f64().expect("a number");
        let Some(f) = d.finding(key) else {
            failures.push(format!("{key}: not diagnosed"));
            continue;
        };
        let t = tol(key, truth);
        eprintln!(
            "{key:24} truth {truth:+10.4} diagnosed {:+10.4} (tolerance {t:.4})",
            f.value
        );
        if (f.value - truth).abs() > t {
            failures.push(format!("{key}: {} against {truth}", f.value));
        }
        // A truth under its tolerance is no recovery (a diagnosis of 0 would pass): the error
        // must then be reported absent.
        if truth.abs() < t && f.present {
            failures.push(format!("{key}: reported present at {truth} (under {t})"));
        }
    }
    assert!(
        failures.is_empty(),
        "{failures:#?}\n{}",
        vmt_ballbar::report::text(d)
    );
}

/// The acceptance tolerances of the closed-loop accuracy study: max(0.3 µm, 5 %) for lengths,
/// 1 µm/m for squareness, 0.1 ms... tightened here to 0.01 ms for servo mismatch, the scale
/// mismatch as the length it makes over the radius and the angular play as the length it makes
/// over half of it.
fn tolerance(radius_mm: f64) -> impl Fn(&str, f64) -> f64 {
    move |key, truth| {
        if key.starts_with("squareness") {
            1.0
        } else if key.starts_with("servo_mismatch") {
            0.01
        } else if key.starts_with("scale_mismatch") {
            (0.3 / (radius_mm * 1e-3)).max(0.05 * truth.abs())
        } else if key.starts_with("angular_play") {
            (0.3 / (0.5 * radius_mm * 1e-3)).max(0.05 * truth.abs())
        } else {
            0.3f64.max(0.05 * truth.abs())
        }
    }
}

/// An XY test of `radius_mm` at `feed_mm_min`, 360° CW and CCW, about the table's middle.
fn xy_test(radius_mm: f64, feed_mm_min: f64) -> String {
    format!(
        "[job]\nkind = \"ballbar\"\nplane = \"XY\"\ncenter_mm = [250.0, 200.0, 200.0]\n\
         radius_mm = {radius_mm:?}\nfeed_mm_min = {feed_mm_min:?}\narc_deg = 360.0\n\
         directions = [\"cw\", \"ccw\"]"
    )
}

/// The built-in machine (geometric errors of an uncompensated VMC, drive backlash and friction,
/// unequal gains) with a drifting pivot: every figure of the XY test within tolerance. The
/// job's program runs in and out over 45° arcs (the default of `vmt program ballbar` and of a
/// ball-bar job), so its data arcs start and end settled: the settling rule leaves nothing
/// out, and the ISO figures are the raw ones, X's reversal spike at 0° included.
#[test]
fn builtin_machine_xy_test_is_diagnosed_within_tolerance() {
    let bar = r#"[instruments.ballbar]
noise_um = 0.3
setup_eccentricity_um = [12.0, -7.0, 0.0]
setup_drift_um_per_min = [4.0, -2.0, 0.0]"#;
    let r = run(&xy_test(100.0, 2000.0), bar);
    let d = diagnose(&vmt_e2e::traces(&r), &Options::default()).expect("diagnosis");
    compare(&r, &d, tolerance(100.0));
    for s in &d.settling {
        assert_eq!(
            (s.start_excluded_deg, s.end_excluded_deg),
            (0.0, 0.0),
            "{s:?}"
        );
    }
    assert_eq!(d.iso, d.raw_iso);
}

/// The reversal spikes (1.8 µm over 40 ms on X at 2000 mm/min) follow each reversal in both
/// senses, so the CW and CCW runs differ by a short step at every turn. The diagnosis leaves
/// them out of its fit: on the built-in test at 100 mm and 2000 mm/min with a noise-free bar,
/// both backlash figures are within 0.02 µm of the truth and both closing errors within 0.04
/// µm (measured: −0.003 and −0.002, +0.017 and +0.003 µm). Fitted, the spikes had made all four
/// read 0.07–0.08 µm high.
#[test]
fn reversal_spikes_are_not_read_as_backlash_or_closing_error() {
    let r = run(
        &xy_test(100.0, 2000.0),
        "[instruments.ballbar]
noise_um = 0.0",
    );
    let d = diagnose(&vmt_e2e::traces(&r), &Options::default()).expect("diagnosis");
    let spike = d.finding("reversal_spike_x").expect("X's reversal spike");
    assert!(spike.value > 1.0, "{spike:?}");
    let default = tolerance(100.0);
    compare(&r, &d, |key, truth| {
        if key.starts_with("backlash") {
            0.02
        } else if key.starts_with("closing_error") {
            0.04
        } else {
            default(key, truth)
        }
    });
}

/// A yaw backlash of the X table of 10 µrad (the built-in machine's 1.5 µrad raised): reversing
/// X turns the table, so X's backlash grows across it by 10 µm/m, which the bar reads as
/// `σ (εR/2) |sin θ| cos θ`. The diagnosis fits it as X's angular play, within 0.5 µrad of the
/// truth and reported present, and the lateral plays stay within 0.05 µm of theirs (0). With
/// no angular play in the model the pivot-drift terms took the shape's first harmonic and
/// passed the rest to the lateral plays: 0.06–0.09 µm at the built-in 1.5 µrad.
#[test]
fn a_yaw_backlash_of_the_table_is_read_as_angular_play() {
    let from = "ECX_urad = [1.5, -4.0, 2.0]";
    assert!(
        vmt_scenario::BUILTIN_DEFAULT.contains(from),
        "the built-in yaw backlash"
    );
    let text = vmt_scenario::BUILTIN_DEFAULT.replacen(from, "ECX_urad = [10.0, -4.0, 2.0]", 1);
    let r = run_on(
        &text,
        &xy_test(100.0, 2000.0),
        "[instruments.ballbar]\nnoise_um = 0.3",
    );
    let d = diagnose(&vmt_e2e::traces(&r), &Options::default()).expect("diagnosis");
    let figures = &r.ground_truth["ballbar"]["tests"][0]["figures"];
    let truth = figures["angular_play_x"]
        .as_f64()
        .expect("X's angular play");
    assert!((truth + 10.0).abs() < 0.1, "{truth}");
    let found = d.finding("angular_play_x").expect("X's angular play");
    assert!(found.present, "{found:?}");
    let default = tolerance(100.0);
    compare(&r, &d, |key, truth| match key {
        "angular_play_x" => 0.5,
        "lateral_play_x" | "lateral_play_y" => 0.05,
        _ => default(key, truth),
    });
}

/// Periodic lead errors of the X and Y screws (1.5 µm and 1.0 µm over their 10 mm lead, at
/// other phases) on the built-in machine: the diagnosis finds each axis' cyclic error with the
/// lead as its pitch, and every other figure stays within tolerance.
#[test]
fn screw_lead_errors_are_diagnosed_as_cyclic_errors_of_their_pitch() {
    let text = vmt_scenario::BUILTIN_DEFAULT
        // The first zero lead error is X's, the next Y's.
        .replacen(
            "screw_cyclic_um = [0.0, 0.0]",
            "screw_cyclic_um = [1.2, 0.9]",
            1,
        )
        .replacen(
            "screw_cyclic_um = [0.0, 0.0]",
            "screw_cyclic_um = [0.0, -1.0]",
            1,
        );
    let r = run_on(
        &text,
        &xy_test(100.0, 2000.0),
        "[instruments.ballbar]\nnoise_um = 0.3",
    );
    let figures = &r.ground_truth["ballbar"]["tests"][0]["figures"];
    assert!((figures["cyclic_x"].as_f64().unwrap() - 1.5).abs() < 1e-9);
    assert!((figures["cyclic_y"].as_f64().unwrap() - 1.0).abs() < 1e-9);
    let d = diagnose(&vmt_e2e::traces(&r), &Options::default()).expect("diagnosis");
    for axis in ["x", "y"] {
        let f = d
            .finding(&format!("cyclic_{axis}"))
            .expect("a cyclic finding");
        let pitch = f.details.iter().find(|(k, _)| k == "pitch_mm").unwrap().1;
        assert!(f.present, "cyclic_{axis} not reported present: {f:?}");
        assert!((pitch - 10.0).abs() < 0.2, "cyclic_{axis} pitch {pitch} mm");
    }
    compare(&r, &d, tolerance(100.0));
}

/// A 4 µm gap in the Y nut (the built-in 1 µm is under the tolerance once the ball bar sees
/// it): the Y backlash the bar sees is recovered within tolerance and reported present, and
/// every other figure stays within tolerance.
#[test]
fn a_y_drive_backlash_is_recovered_as_backlash_of_y() {
    let second = vmt_scenario::BUILTIN_DEFAULT
        .match_indices("backlash_um = 1.0")
        .nth(1)
        .expect("Y's backlash")
        .0;
    let mut text = vmt_scenario::BUILTIN_DEFAULT.to_string();
    text.replace_range(
        second..second + "backlash_um = 1.0".len(),
        "backlash_um = 4.0",
    );
    let r = run_on(
        &text,
        &xy_test(100.0, 2000.0),
        "[instruments.ballbar]\nnoise_um = 0.3",
    );
    let truth = r.ground_truth["ballbar"]["tests"][0]["figures"]["backlash_y"]
        .as_f64()
        .unwrap();
    let t = tolerance(100.0)("backlash_y", truth);
    assert!(
        truth > 3.0 * t,
        "backlash_y truth {truth} µm, tolerance {t}"
    );
    let d = diagnose(&vmt_e2e::traces(&r), &Options::default()).expect("diagnosis");
    assert!(d.finding("backlash_y").is_some_and(|f| f.present));
    compare(&r, &d, tolerance(100.0));
}

/// 25 µm gaps in the X and Y nuts on the built-in test (150 mm, 1000 mm/min): after each
/// reversal the motor takes the gap up along the circle over about 1°, which the diagnosis
/// models (`vmt_ballbar::take_up`). Every figure is within tolerance, each backlash within 2 %
/// of what the bar sees, and neither stick-slip nor a start transient is reported. The servo
/// mismatch is held to 0.02 ms, not 0.01: the Y carriage lags the take-up by up to 4 µm
/// (its reversal spike, 5 µm over 120 ms), which moves it by 0.016 ms. A step model read Y
/// 5.5 % low, the servo mismatch 0.031 ms off and a straightness of 0.6 µm too much, and
/// reported stick-slip on both axes and transients at the start.
#[test]
fn large_backlash_taken_up_along_the_circle_is_recovered() {
    let text = vmt_scenario::BUILTIN_DEFAULT.replace("backlash_um = 1.0", "backlash_um = 25.0");
    assert_eq!(
        text.matches("backlash_um = 25.0").count(),
        2,
        "X's and Y's gaps"
    );
    let r = run_on(&text, &xy_test(150.0, 1000.0), "");
    let d = diagnose(&vmt_e2e::traces(&r), &Options::default()).expect("diagnosis");
    let within = tolerance(150.0);
    compare(&r, &d, |key, truth| match key {
        "servo_mismatch_xy" => 0.02,
        _ => within(key, truth),
    });
    let figures = &r.ground_truth["ballbar"]["tests"][0]["figures"];
    for key in ["backlash_x", "backlash_y"] {
        let truth = figures[key].as_f64().expect("a truth");
        let f = d.finding(key).expect("a finding");
        assert!(
            (f.value / truth - 1.0).abs() < 0.02,
            "{key}: {} against {truth}",
            f.value
        );
    }
    for f in &d.findings {
        let local = f.key.starts_with("stick_slip") || f.key.starts_with("start_transient");
        assert!(!(local && f.present), "{f:?}");
    }
}

/// A slow circle (50 mm, 100 mm/min) past the X guides' Stribeck dip, with their static
/// friction raised from 65 to 250 N (and the Stribeck velocity from 1 to 0.5 mm/s): the X
/// carriage holds as it turns round until the screw has built up its breakaway force, so the
/// motor travels 7 times as far (1.8 µm on the machine as built, 12.7 µm) before the carriage
/// follows, and the step grows (3.45 to 5.26 µm), as the truth's does (5.24 µm: the screw's
/// stretch under the Stribeck curve along the circle, `vmt_sim::truth`; it had counted the
/// Coulomb level alone, 3.26 µm). Y's spike stays as it was, and
/// neither axis shows stick-slip: at this feed an axis passes through
/// the Stribeck range in a fraction of a second and the velocity loop keeps it moving (the
/// simulated drives stick and slip at creep feeds, `sim/tests/friction_physics.rs`). Nothing
/// about the take-up is injected into the trace: it comes from the LuGre friction against the
/// compliant drive. (This test asserted stick-slip on X until the diagnosis modelled the
/// take-up of backlash: the 0.7 µm it found was the step model's misfit of the take-up.)
#[test]
fn a_static_friction_peak_on_x_lengthens_its_take_up() {
    let slow = xy_test(50.0, 100.0);
    let stock = "coulomb_n = 50.0, static_n = 65.0, stribeck_mm_s = 1.0";
    let sticky = vmt_scenario::BUILTIN_DEFAULT.replacen(
        stock,
        "coulomb_n = 50.0, static_n = 250.0, stribeck_mm_s = 0.5",
        1,
    );
    assert_ne!(
        sticky,
        vmt_scenario::BUILTIN_DEFAULT,
        "the X guides' friction"
    );
    let detail = |f: &vmt_ballbar::Finding, key: &str| {
        f.details.iter().find(|(k, _)| k == key).map(|(_, v)| *v)
    };
    // Per axis: (backlash µm, its take-up's reach µm, spike height µm); and X's true backlash.
    let figures = |text: &str| {
        let r = run_on(text, &slow, "[instruments.ballbar]\nnoise_um = 0.1");
        let d = diagnose(&vmt_e2e::traces(&r), &Options::default()).expect("diagnosis");
        let truth = r.ground_truth["ballbar"]["tests"][0]["figures"]["backlash_x"]
            .as_f64()
            .expect("X's backlash");
        let found = ["x", "y"].map(|a| {
            let stick_slip = d.finding(&format!("stick_slip_{a}")).expect("stick-slip");
            assert!(!stick_slip.present, "{stick_slip:?}");
            let b = d.finding(&format!("backlash_{a}")).expect("a backlash");
            let spike = d.finding(&format!("reversal_spike_{a}")).expect("a spike");
            // Only a backlash reported present has its take-up's reach (Y's is 0.3 µm or less).
            let reach = detail(b, "take_up_um").unwrap_or(f64::NAN);
            (b.value, reach, spike.value.abs())
        });
        (found, truth)
    };
    let ([x0, y0], _) = figures(vmt_scenario::BUILTIN_DEFAULT);
    let ([x1, y1], truth) = figures(&sticky);
    assert!(
        (x1.0 / truth - 1.0).abs() < 0.02,
        "X: {x1:?} against {truth}"
    );
    assert!(
        x1.1 > 4.0 * x0.1 && x1.0 > 1.3 * x0.0,
        "X: {x0:?} to {x1:?}"
    );
    assert!(
        (y1.2 / y0.2 - 1.0).abs() < 0.1,
        "Y's spike: {y0:?} to {y1:?}"
    );
}

/// A wide Stribeck range on the X guides (250 N static over 50 N Coulomb, down to 5 mm/s) on
/// the built-in test (150 mm, 1000 mm/min): X slides below 5 mm/s for ±17° about each of its
/// reversals, where its screw stretches under more than the Coulomb force. The bar reads this
/// hump partly as lost motion (+1.9 µm) and partly as a lead of X (−0.08 ms of servo
/// mismatch); the truth projects it as the diagnosis fits it, and every figure is within
/// tolerance. (A truth at the Coulomb level was 2 µm and 0.1 ms off.)
#[test]
fn a_wide_stribeck_range_on_x_is_read_as_its_truth_says() {
    let text = vmt_scenario::BUILTIN_DEFAULT.replacen(
        "coulomb_n = 50.0, static_n = 65.0, stribeck_mm_s = 1.0",
        "coulomb_n = 50.0, static_n = 250.0, stribeck_mm_s = 5.0",
        1,
    );
    assert_ne!(
        text,
        vmt_scenario::BUILTIN_DEFAULT,
        "the X guides' friction"
    );
    let r = run_on(&text, &xy_test(150.0, 1000.0), "");
    let figures = &r.ground_truth["ballbar"]["tests"][0]["figures"];
    // At the Coulomb level the drive's lost motion is 1 + 2·50/180 µm; the X error chain adds
    // about 1.7 µm.
    let backlash = figures["backlash_x"].as_f64().expect("X's backlash");
    assert!(backlash > 5.0, "{backlash}");
    let d = diagnose(&vmt_e2e::traces(&r), &Options::default()).expect("diagnosis");
    compare(&r, &d, tolerance(150.0));
}
