//! Kwon's seven-step procedure end to end: the shipped scenario (`scenarios/kwon_seven_step.toml`)
//! is simulated, every step diagnosed from its traces alone, and the figures and the machine
//! report compared with the run's ground truth.

use serde_json::Value;
use std::path::PathBuf;
use std::sync::OnceLock;
use vmt_ballbar::kwon::{self, MachineReport};
use vmt_ballbar::{Diagnosis, Finding, Options, diagnose};
use vmt_sim::run::Run;

/// The run of the scenario and the diagnosis of each step, made once for all the tests here.
fn shared() -> &'static (Run, Vec<Diagnosis>) {
    static SHARED: OnceLock<(Run, Vec<Diagnosis>)> = OnceLock::new();
    SHARED.get_or_init(|| {
        let run = run_scenario();
        let d = diagnoses(&run);
        (run, d)
    })
}

fn run_scenario() -> Run {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenarios/kwon_seven_step.toml");
    let text = std::fs::read_to_string(&path).expect("the scenario file");
    vmt_e2e::simulate_text(&text, "kwon_seven_step.toml")
}

/// The diagnosis of each step (its CW and CCW traces, in the order run).
fn diagnoses(run: &Run) -> Vec<Diagnosis> {
    let traces = vmt_e2e::traces(run);
    traces
        .chunks(2)
        .map(|test| diagnose(test, &Options::default()).expect("diagnosis"))
        .collect()
}

fn truth_figures(run: &Run, step: usize) -> &serde_json::Map<String, Value> {
    run.ground_truth["ballbar"]["tests"][step - 1]["figures"]
        .as_object()
        .expect("the truth's figures")
}

/// The machine report by Kwon's formulas from the truth's figures of each step.
fn truth_report(run: &Run) -> MachineReport {
    kwon::report_from(
        |n, key| truth_figures(run, n as usize).get(key)?.as_f64(),
        |n| {
            truth_figures(run, n as usize)
                .keys()
                .map(|k| (k.clone(), k.clone(), ""))
                .collect()
        },
    )
}

/// The bias that finding `f` of `step` states for the effects its test leaves out (the bows,
/// angular plays and drift of a half circle), from their truth: the step's figures and drift.
fn stated_bias(run: &Run, step: usize, f: &Finding) -> f64 {
    if f.stated_biases().next().is_none() {
        return 0.0;
    }
    let test = &run.ground_truth["ballbar"]["tests"][step - 1];
    f.left_out_bias(|effect| {
        test["figures"][effect]
            .as_f64()
            .or(test["drift"][effect].as_f64())
    })
    .unwrap_or_else(|| panic!("step {step}: {} lacks the truth of an effect", f.key))
}

/// Every failure of `key` of `step` against its truth plus the bias it states, beyond `tol`.
fn check(run: &Run, d: &[Diagnosis], step: usize, key: &str, tol: f64, out: &mut Vec<String>) {
    let truth = truth_figures(run, step)[key].as_f64().expect("a number");
    let Some(f) = d[step - 1].finding(key) else {
        out.push(format!("step {step} {key}: not diagnosed"));
        return;
    };
    let expected = truth + stated_bias(run, step, f);
    if (f.value - expected).abs() > tol {
        out.push(format!(
            "step {step} {key}: {:+.3} against {truth:+.3} plus its stated bias, {expected:+.3} \
             (tolerance {tol})",
            f.value
        ));
    }
}

/// The seven steps on the built-in machine: the pivot offsets in the middle of each test, the
/// figures Kwon takes from each step and the machine report all agree with the truth, with
/// tolerances a few times the run's own scatter. It failed on the Z direction the truth assumed
/// for the XY steps (EA0Z differs by direction: steps 3 and 5 follow a descent), on the
/// gravity-loaded Z nut (no gap crossed at the top of the half circles), on eccentricities
/// taken at the start of a test against a truth in its middle, on cyclic errors found in the
/// start transient, and on the half circles' X lost motion read as servo mismatch. On the half
/// circles a finding reads its truth plus the bias it states for what the arc leaves out (step
/// 7's lateral play of Z: −0.24 µm, mostly Z's angular play of −3 µrad).
#[test]
fn seven_steps_agree_with_the_truth() {
    let (run, d) = shared();
    assert_eq!(d.len(), 7);
    let mut failures = Vec::new();
    for step in 1..=5 {
        for key in ["eccentricity_x", "eccentricity_y"] {
            check(run, d, step, key, 0.1, &mut failures);
        }
        for key in ["straightness_x", "straightness_y"] {
            check(run, d, step, key, 0.1, &mut failures);
        }
        // At 4000 mm/min (step 5) the reversal spikes (2 µm over 30 ms on X) had made the
        // fitted steps read 0.22 µm (X) and 0.15 µm (Y) high until the spikes were left out of
        // the fit: now +0.055 and +0.001 µm.
        for key in ["backlash_x", "backlash_y"] {
            check(run, d, step, key, 0.1, &mut failures);
        }
        check(run, d, step, "servo_mismatch_xy", 0.01, &mut failures);
        check(run, d, step, "squareness_xy", 0.5, &mut failures);
    }
    for step in 1..=4 {
        check(run, d, step, "scale_mismatch_xy", 0.5, &mut failures);
    }
    for (step, across) in [(6, "eccentricity_x"), (7, "eccentricity_y")] {
        check(run, d, step, "backlash_z", 0.15, &mut failures);
        check(run, d, step, "lateral_play_z", 0.05, &mut failures);
        // The pivot offset across the half circle moves by 0.17 µm per µm of the axes' bows.
        check(run, d, step, across, 0.5, &mut failures);
    }
    check(run, d, 6, "backlash_x", 0.15, &mut failures);
    check(run, d, 6, "servo_mismatch_zx", 0.02, &mut failures);
    check(run, d, 7, "backlash_y", 0.15, &mut failures);
    check(run, d, 7, "servo_mismatch_yz", 0.02, &mut failures);
    // No screw here has a periodic lead error, the Stribeck curves give no stick-slip at
    // 500 mm/min and no gain is high enough to vibrate: nothing may be reported as any of these
    // (the start transient at the feed-in's axis reversal read as stick-slip of 5-33 µm before
    // it was left out of the windows; step 5's feed-in ringing, 1.25 µm at 5 Hz, read as a
    // vibration before a line had to stand above the spectrum about its own frequency).
    for (i, diag) in d.iter().enumerate() {
        let spurious = |f: &&Finding| {
            f.key.starts_with("cyclic")
                || f.key.starts_with("stick_slip")
                || f.key == "servo_vibration"
        };
        for f in diag.findings.iter().filter(spurious) {
            if f.present {
                failures.push(format!("step {}: {} present: {f:?}", i + 1, f.key));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// On the half circles of steps 6 and 7 the figures an unfitted bow moves most are reported as
/// not computed, with the reason, instead of with a value.
#[test]
fn half_circles_say_what_they_cannot_tell() {
    let (_, d) = shared();
    for (step, plane) in [(6, "zx"), (7, "yz")] {
        let diag = &d[step - 1];
        for key in [
            "radius_offset".to_string(),
            "eccentricity_z".to_string(),
            format!("scale_mismatch_{plane}"),
            format!("squareness_{plane}"),
        ] {
            assert!(diag.finding(&key).is_none(), "step {step} reports {key}");
            let n = diag.not_computed.iter().find(|n| n.key == key);
            assert!(
                n.is_some_and(|n| n.reason.contains("bow")),
                "step {step}: {key} not listed as not computed: {:?}",
                diag.not_computed
            );
        }
    }
}

/// The machine report: every figure with a truth within its tolerance (µm/m, µm, ms).
#[test]
fn machine_report_agrees_with_the_truth() {
    let (run, d) = shared();
    let report = kwon::machine_report(d);
    let truth = truth_report(run);
    let tolerance = |key: &str| match key {
        "squareness_zx_kwon" | "squareness_yz_kwon" => 0.6,
        "tilt_x_per_height_kwon" | "tilt_y_per_height_kwon" => 0.3,
        "servo_mismatch_xy" => 0.005,
        "scale_mismatch_xy" => 0.5,
        "squareness_xy" => 0.5,
        _ => 0.15,
    };
    let mut failures = Vec::new();
    for f in &report.figures {
        let Some(t) = truth.figures.iter().find(|t| t.key == f.key) else {
            continue;
        };
        let tol = tolerance(&f.key);
        eprintln!(
            "{:28} truth {:+9.3} diagnosed {:+9.3} (tolerance {tol})",
            f.key, t.value, f.value
        );
        if (f.value - t.value).abs() > tol {
            failures.push(format!(
                "{}: {:+.3} against {:+.3}",
                f.key, f.value, t.value
            ));
        }
    }
    for key in [
        "squareness_zx_kwon",
        "squareness_yz_kwon",
        "backlash_z",
        "servo_mismatch_xy",
    ] {
        if !report.figures.iter().any(|f| f.key == key) {
            failures.push(format!("{key}: not in the report"));
        }
        if !truth.figures.iter().any(|f| f.key == key) {
            failures.push(format!("{key}: not in the truth"));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Kwon's XZ and YZ squareness measure the machine's: with EB0Z and EA0Z raised by 20 µrad
/// (both directions of Y), the diagnosed figures of the machine report move by +20 µm/m (they
/// moved 20.002 and 20.001). A differential run, so that the expected change is the injected
/// one, not a number from the formulas under test (the report's absolute figures also hold the
/// axes' tilts and bows over the link heights).
#[test]
fn kwon_squareness_follows_the_injected_squareness() {
    let (_, d) = shared();
    let before = kwon::machine_report(d);
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../scenarios/kwon_seven_step.toml");
    let text = std::fs::read_to_string(&path).expect("the scenario file");
    let (eb, ea) = (
        "EB0Z_urad = -8.0",
        "EA0Z_urad = { forward = 6.0, backward = 9.0 }",
    );
    assert!(text.contains(eb) && text.contains(ea));
    let text = text
        .replace(eb, "EB0Z_urad = 12.0")
        .replace(ea, "EA0Z_urad = { forward = 26.0, backward = 29.0 }");
    let after = kwon::machine_report(&diagnoses(&vmt_e2e::simulate_text(
        &text,
        "kwon_seven_step.toml",
    )));
    let value = |r: &MachineReport, key: &str| {
        r.figures
            .iter()
            .find(|f| f.key == key)
            .map(|f| f.value)
            .unwrap_or_else(|| panic!("{key} not in the report"))
    };
    for key in ["squareness_zx_kwon", "squareness_yz_kwon"] {
        let moved = value(&after, key) - value(&before, key);
        eprintln!("{key} moved {moved:+.3} µm/m");
        assert!((moved - 20.0).abs() < 0.2, "{key} moved {moved} µm/m");
    }
}

/// Step 5's runs start straight off the radial feed-in (no overshoot), so each begins with the
/// carriages' lag at the corner (Kwon's transient start peak, Section III.6). The diagnosed
/// transient is that lag as the servo log records it: the carriages' distance from the circle's
/// centre less the command's, at its largest in the first 5°, less its median over the rest of
/// the run (174 µm). The diagnosis reads it about 3 % low (its 4 ms smoothing of a decay of
/// about 30 ms); 5 % is allowed.
#[test]
fn step_5_start_transient_is_the_logged_lag_at_the_corner() {
    let (run, d) = shared();
    let servo = run
        .streams
        .iter()
        .find(|s| s.name == "servo")
        .expect("the servo stream");
    let values = |name: &str| &servo.channel(name).expect(name).values;
    let (cx, cy, px, py) = (
        values("command_x"),
        values("command_y"),
        values("position_x"),
        values("position_y"),
    );
    let report = kwon::machine_report(d);
    let step5 = d
        .iter()
        .find(|diag| kwon::step_of(diag) == Some(5))
        .expect("step 5's diagnosis");
    for sense in ["cw", "ccw"] {
        let trace = run
            .ballbar
            .iter()
            .find(|t| t.label.starts_with("step 5:") && t.direction == sense)
            .expect("step 5's trace");
        let (t0, t1) = (trace.times_s[0], trace.times_s[trace.times_s.len() - 1]);
        let start_deg = trace.angle_deg[0];
        let sweep = trace.angle_deg[trace.angle_deg.len() - 1] - start_deg;
        let five_deg_s = (t1 - t0) * 5.0 / sweep.abs();
        let run_samples: Vec<usize> = (0..servo.times_s.len())
            .filter(|&i| (t0..=t1).contains(&servo.times_s[i]))
            .collect();
        // The commanded circle's centre, from the extremes of the commands.
        let centre = |c: &[f64]| {
            let (lo, hi) = run_samples
                .iter()
                .map(|&i| c[i])
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                    (a.min(v), b.max(v))
                });
            0.5 * (lo + hi)
        };
        let (x0, y0) = (centre(cx), centre(cy));
        // The carriages' radial lag (µm) at each servo sample of the run.
        let mut early = f64::NEG_INFINITY;
        let mut rest = Vec::new();
        for &i in &run_samples {
            // Distances from the centre: a lag along the path moves the carriages along the
            // circle, not off it (its projection on the commanded radius would read -L²/2R).
            let radial = ((px[i] - x0).hypot(py[i] - y0) - (cx[i] - x0).hypot(cy[i] - y0)) * 1e6;
            let t = servo.times_s[i] - t0;
            if t <= five_deg_s {
                early = early.max(radial);
            } else if t >= 2.0 * five_deg_s {
                rest.push(radial);
            }
        }
        rest.sort_by(f64::total_cmp);
        let logged = early - rest[rest.len() / 2];
        let key = format!("start_transient_{sense}");
        let diagnosed = step5.finding(&key).expect("a start transient");
        let in_report = report.figures.iter().find(|f| f.key == key);
        eprintln!(
            "{key}: diagnosed {:.2} µm, logged lag {logged:.2} µm",
            diagnosed.value
        );
        assert!(diagnosed.present, "{diagnosed:?}");
        assert!(
            (diagnosed.value - logged).abs() <= 0.05 * logged.abs(),
            "{key}: diagnosed {:.2} µm against the logged {logged:.2} µm",
            diagnosed.value
        );
        assert_eq!(in_report.map(|f| f.value), Some(diagnosed.value));
    }
}

/// Kwon's programs have no run-in arc: every run starts with the carriages' lag at the feed-in
/// corner, some 160 µm of radial deviation in its first samples (the raw G of every step is
/// 60–190 µm). The headline figures are taken past the lag's settling: no step's G is
/// dominated by it (each under 30 µm: the machine's errors, step 5's servo mismatch at
/// 4000 mm/min the largest), and on the half circles of steps 6 and 7 the headline G, H and
/// G(b) are within 1.5 µm of the same figures over the arcs without their first and last 15°
/// (an exclusion far past any transient, computed here from the traces by the ISO 230-4
/// formulas). The raw figures, lag included, stay in the diagnosis beside them.
#[test]
fn headline_figures_are_taken_past_the_feed_in_transient() {
    let (run, d) = shared();
    let traces = vmt_e2e::traces(run);
    for (i, diag) in d.iter().enumerate() {
        let step = i + 1;
        for (dir, raw) in diag.iso.directions.iter().zip(&diag.raw_iso.directions) {
            let (g, g_raw) = (dir.circular_deviation_um, raw.circular_deviation_um);
            eprintln!("step {step} {}: G {g:.2} µm, raw {g_raw:.2} µm", dir.sense);
            assert!(g < 30.0, "step {step} {}: G {g} µm", dir.sense);
            assert!(g_raw > 50.0, "step {step} {}: raw G {g_raw} µm", dir.sense);
        }
        assert!(
            diag.settling
                .iter()
                .all(|s| s.settled && s.start_excluded_deg > 0.0),
            "step {step}: {:?}",
            diag.settling
        );
    }
    for step in [6, 7] {
        let test = &traces[2 * (step - 1)..2 * step];
        let inner: Vec<vmt_ballbar::Trace> = test
            .iter()
            .map(|t| {
                let (a0, a1) = (t.angle_deg[0], t.angle_deg[t.angle_deg.len() - 1]);
                let keep: Vec<usize> = (0..t.angle_deg.len())
                    .filter(|&k| {
                        (t.angle_deg[k] - a0).abs() >= 15.0 && (a1 - t.angle_deg[k]).abs() >= 15.0
                    })
                    .collect();
                t.samples(keep[0]..keep[keep.len() - 1] + 1)
            })
            .collect();
        let reference = vmt_ballbar::iso230_4::figures(&inner.iter().collect::<Vec<_>>(), false);
        let headline = &d[step - 1].iso;
        let mut pairs: Vec<(&str, f64, f64)> = headline
            .directions
            .iter()
            .zip(&reference.directions)
            .map(|(h, r)| ("G", h.circular_deviation_um, r.circular_deviation_um))
            .collect();
        pairs.push((
            "H",
            headline.hysteresis_um.unwrap(),
            reference.hysteresis_um.unwrap(),
        ));
        pairs.push((
            "G(b)",
            headline.bidirectional_deviation_um.unwrap(),
            reference.bidirectional_deviation_um.unwrap(),
        ));
        for (name, h, r) in pairs {
            eprintln!("step {step} {name}: headline {h:.2} µm, past 15° {r:.2} µm");
            assert!((h - r).abs() < 1.5, "step {step} {name}: {h} against {r}");
        }
    }
}
