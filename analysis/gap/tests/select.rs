//! Closed loop through the simulator: "measured" traces from the built-in machine with an
//! effect added, a model without it; the selection must name the effect, recover its size and
//! shrink the held-out gap. A short test (50 mm, 2000 mm/min) and a few candidates keep it fast;
//! `vmt gap-bench` runs the whole library.

use vmt_ballbar::Trace;
use vmt_gap::effects::{Effect, library};
use vmt_gap::model::{Forward, ScenarioModel};
use vmt_gap::select::{Linearisation, Options, Selection, select};
use vmt_gap::split::Split;

fn short_test() -> String {
    short_test_in("XY")
}

fn short_test_in(plane: &str) -> String {
    vmt_scenario::BUILTIN_DEFAULT
        .replace("plane = \"XY\"", &format!("plane = \"{plane}\""))
        .replace("radius_mm = 150.0", "radius_mm = 50.0")
        .replace(
            "feed_mm_min = 1000.0\narc_deg",
            "feed_mm_min = 2000.0\narc_deg",
        )
}

/// The run of the "real" machine: the model with `edits`, its ball bar keeping the noise
/// (0.1 µm) and resolution of the instrument, another seed.
fn measured(edits: &[(&str, f64)]) -> Vec<Trace> {
    measured_in("XY", edits)
}

fn measured_in(plane: &str, edits: &[(&str, f64)]) -> Vec<Trace> {
    let t = vmt_scenario::edit::Template::parse(&short_test_in(plane), "measured.toml").unwrap();
    let mut edits = edits.to_vec();
    edits.push(("simulation.seed", 7.0));
    let text = t.with(&edits).unwrap();
    let s = vmt_scenario::parse(&text, "measured.toml", None).unwrap();
    let e = s.execution.as_ref().unwrap();
    let run = e.simulate(&s.machine, &text, &mut |_| {}).unwrap();
    run.ballbar
        .iter()
        .map(|t| vmt_gap::model::trace_of(t).unwrap())
        .collect()
}

fn few(keys: &[&str]) -> Vec<Effect> {
    few_of(library('x', 'y'), keys)
}

fn few_of(lib: Vec<Effect>, keys: &[&str]) -> Vec<Effect> {
    lib.into_iter()
        .filter(|e| keys.contains(&e.key.as_str()))
        .collect()
}

#[test]
fn added_backlash_is_found_sized_and_closes_the_held_out_gap() {
    let model = ScenarioModel::new(&short_test(), "model.toml", None).unwrap();
    let truth = model.value("machine.axes.x.drive.backlash_um").unwrap() + 4.0;
    let real = measured(&[("machine.axes.x.drive.backlash_um", truth)]);
    let lib = few(&[
        "backlash_x",
        "backlash_y",
        "squareness",
        "servo_mismatch",
        "scale_mismatch",
    ]);
    let split = Split::automatic(&real).unwrap();
    let lin = Linearisation::new(&model, &lib).unwrap();
    let run = |o: &Options| select(&model, &lin, &real, &lib, split.clone(), o).unwrap();
    let s = run(&Options::default());
    assert_eq!(
        s.steps.first().map(|s| s.effect.as_str()),
        Some("backlash_x"),
        "{s:#?}"
    );
    // Verifying the next step's candidate ahead changes how many simulations ran, not the
    // answer.
    let plain = run(&Options {
        speculate: false,
        ..Options::default()
    });
    let uncounted = |s: &Selection| Selection {
        simulations: 0,
        ..s.clone()
    };
    assert_eq!(uncounted(&s), uncounted(&plain));
    let b = s.steps[0].values[0].value;
    assert!((b - 4.0).abs() < 0.4, "fitted {b} um, injected 4 um");
    let shrink = s
        .judge_shrink()
        .expect("a full circle both ways is enough to judge");
    assert!(shrink > 0.8, "untouched shrink {shrink}");
    assert_eq!(s.steps.len(), 1, "{:#?}", s.steps);
}

#[test]
fn a_model_that_matches_gets_no_effect() {
    let model = ScenarioModel::new(&short_test(), "model.toml", None).unwrap();
    let real = measured(&[]);
    let lib = few(&[
        "backlash_x",
        "squareness",
        "servo_mismatch",
        "scale_mismatch",
    ]);
    let s = select(
        &model,
        &Linearisation::new(&model, &lib).unwrap(),
        &real,
        &lib,
        Split::automatic(&real).unwrap(),
        &Options::default(),
    )
    .unwrap();
    assert!(s.steps.is_empty(), "{:#?}", s.steps);
}

#[test]
fn an_effect_outside_the_library_is_left_unexplained() {
    // Yaw of X (ECX) with the tool 100 mm out: an Abbe error no candidate here models.
    let model = ScenarioModel::new(&short_test(), "model.toml", None).unwrap();
    let yaw = model.value("machine.errors.x.forward.ECX_urad[1]").unwrap();
    let real = measured(&[
        ("machine.errors.x.forward.ECX_urad[1]", yaw + 60.0),
        ("machine.errors.x.backward.ECX_urad[1]", yaw + 60.0),
    ]);
    let lib = few(&["backlash_x", "backlash_y", "servo_mismatch"]);
    let s = select(
        &model,
        &Linearisation::new(&model, &lib).unwrap(),
        &real,
        &lib,
        Split::automatic(&real).unwrap(),
        &Options::default(),
    )
    .unwrap();
    assert!(s.steps.is_empty(), "{:#?}", s.steps);
    assert!(
        s.judged.unwrap().before_um > 0.3,
        "the yaw makes a gap: {:?}",
        s.judged
    );
}

/// Geometric and bar set-up offsets are replayed from the model's recorded motion; a drive
/// offset is simulated. The replay gives what a model that never ran would simulate.
#[test]
fn geometric_offsets_are_replays_that_match_a_simulation() {
    let values = vec![
        ("machine.errors.squareness.EC0Y_urad".to_string(), 30.0),
        (
            "instruments.ballbar.setup_eccentricity_um[1]".to_string(),
            4.0,
        ),
    ];
    let model = ScenarioModel::new(&short_test(), "model.toml", None).unwrap();
    assert_eq!(model.value(&values[0].0), Some(12.0));
    assert_eq!(model.value(&values[1].0), Some(-2.0));
    let base = model.traces(&[]).unwrap();
    let replayed = model.traces(&values).unwrap();
    assert_eq!(model.replays(), 1);
    let fresh = ScenarioModel::new(&short_test(), "model.toml", None).unwrap();
    let simulated = fresh.traces(&values).unwrap();
    assert_eq!(fresh.replays(), 0);
    assert_eq!(replayed.len(), 2, "a CW and a CCW circle");
    assert_eq!(simulated.len(), replayed.len());
    assert_eq!(base.len(), replayed.len());
    for ((r, s), b) in replayed.iter().zip(&simulated).zip(&base) {
        assert_eq!(r.deviation_um.len(), s.deviation_um.len(), "{}", r.label);
        assert_eq!(r.deviation_um.len(), b.deviation_um.len(), "{}", r.label);
        for (a, b) in r.deviation_um.iter().zip(&s.deviation_um) {
            assert!((a - b).abs() < 1e-9, "{a} vs {b}");
        }
        // The offsets change the reading, so the match above is not of two unchanged runs.
        // The pivot moves by Δe = 4 - (-2) = 6 µm in Y: the bar |tool - pivot| changes by
        // -Δe sin θ = -6 sin θ µm on the circle. EC0Y goes from 12 to 30 µrad: Δγ = 18 µrad
        // turns the Y axis about +Z, δx = -Δγ y with y = 200 mm + 50 mm sin θ (the circle's
        // centre is at Y 200 mm), radially δx cos θ = -3.6 cos θ - 0.45 sin 2θ µm: the centre
        // term, 18e-6 · 200 mm, is a second eccentricity. |3.6 cos θ + 6 sin θ + 0.45 sin 2θ|
        // is a first harmonic of √(3.6² + 6²) = 7.00 µm at θ = atan(6/3.6) = 59.0°, where
        // sin 2θ = 0.88 adds 0.40 µm; maximised over θ: 7.405 µm at 56.2° (and 236.2°; the
        // signs of the terms move the peak, not its size). Zero noise and resolution here.
        let largest = r
            .deviation_um
            .iter()
            .zip(&b.deviation_um)
            .map(|(r, b)| (r - b).abs())
            .fold(0.0, f64::max);
        assert!(
            (largest - 7.405).abs() < 0.02 * 7.405,
            "{}: largest change {largest} µm, 7.405 µm expected",
            r.label
        );
    }
    model
        .traces(&[("machine.axes.x.drive.backlash_um".to_string(), 2.0)])
        .unwrap();
    assert_eq!(model.replays(), 1, "a drive offset is simulated");
}

/// A spindle head that starts 15 K warm cools during the test and moves the tool with it
/// (3.5 µm/K in Z, 0.8 µm/K in Y on the built-in machine, time constant about 21 min). In a
/// ZX test the drift is found and sized; in an XY test it stays below what the test can show,
/// and the visibility says so before any fitting.
#[test]
fn a_warm_spindle_head_is_found_as_thermal_drift_in_a_vertical_plane() {
    let key = "machine.thermal.nodes[0].initial_c";
    let zx = ScenarioModel::new(&short_test_in("ZX"), "model.toml", None).unwrap();
    let start = zx
        .value(key)
        .expect("the built-in machine sets the spindle's start");
    let real = measured_in("ZX", &[(key, start + 15.0)]);
    let lib = few_of(
        zx.library(&[('z', 'x')]),
        &[
            "thermal_drift",
            "backlash_x",
            "squareness",
            "scale_mismatch",
            "setup",
            "bar_length",
        ],
    );
    let lin = Linearisation::new(&zx, &lib).unwrap();
    let o = Options::default();
    let visible = lin
        .visibility(&lib, &[(key.to_string(), 15.0)], &o)
        .unwrap();
    let s = select(&zx, &lin, &real, &lib, Split::automatic(&real).unwrap(), &o).unwrap();
    assert_eq!(
        s.steps.first().map(|s| s.effect.as_str()),
        Some("thermal_drift"),
        "{s:#?}"
    );
    let t = s.steps[0].values[0].value;
    assert!((t - 15.0).abs() < 1.5, "fitted {t} K, injected 15 K");
    let shrink = s
        .judge_shrink()
        .expect("a full circle both ways is enough to judge");
    assert!(shrink > 0.8, "untouched shrink {shrink}");
    // The visibility predicts the held-out gap the drift makes (instrument noise aside).
    let before = s.judged.unwrap().before_um;
    assert!(
        visible > o.min_effect_um && (visible - before).abs() < 0.25 * before,
        "visible {visible} um, held-out gap {before} um"
    );
    let xy = ScenarioModel::new(&short_test(), "model.toml", None).unwrap();
    let lib = few_of(
        xy.library(&[('x', 'y')]),
        &["thermal_drift", "setup", "bar_length"],
    );
    let lin = Linearisation::new(&xy, &lib).unwrap();
    let visible = lin
        .visibility(&lib, &[(key.to_string(), 15.0)], &o)
        .unwrap();
    assert!(visible < o.min_effect_um, "XY visibility {visible} um");
}

/// A change of a screw's periodic lead error changes the motion, but under a motor encoder the
/// carriage follows the nut: the sensitivity replay moves the recorded carriages by it and
/// stays within 2 % of what a simulation gives (the dynamic and phase parts left out); the
/// traces proper are always simulated.
#[test]
fn a_lead_error_sensitivity_replays_within_two_per_cent_of_a_simulation() {
    let key = "machine.axes.x.drive.screw_cyclic_um[0]";
    let values = vec![(key.to_string(), 1.0)];
    let model = ScenarioModel::new(&short_test(), "model.toml", None).unwrap();
    assert!(model.replayable(key));
    let base = model.traces(&[]).unwrap();
    let replayed = model.sensitivity_traces(&values).unwrap();
    assert_eq!(model.replays(), 1);
    let simulated = model.traces(&values).unwrap();
    assert_eq!(model.replays(), 1, "traces() simulates a lead error change");
    let (mut change, mut miss) = (0.0f64, 0.0f64);
    for ((b, r), s) in base.iter().zip(&replayed).zip(&simulated) {
        for ((b, r), s) in b
            .deviation_um
            .iter()
            .zip(&r.deviation_um)
            .zip(&s.deviation_um)
        {
            change = change.max((s - b).abs());
            miss = miss.max((r - s).abs());
        }
    }
    assert!(
        change > 0.5,
        "a 1 um lead error moves the trace: {change} um"
    );
    assert!(
        miss < 0.02 * change,
        "replay off by {miss} um of {change} um"
    );
}

/// The bench injects each effect at 1, −2 and 3 times its typical size; on the built-in machine
/// every one of those stays within the class's plausible range, so that the bench never asks
/// the analysis to accept what no machine has.
#[test]
fn the_bench_sizes_are_plausible_on_the_built_in_machine() {
    for plane in ["XY", "ZX", "YZ"] {
        let model = ScenarioModel::new(&short_test_in(plane), "model.toml", None).unwrap();
        let lib = model.library(&[('x', 'y'), ('z', 'x'), ('y', 'z')]);
        for e in lib.iter().filter(|e| !e.baseline) {
            for p in &e.params {
                // A candidate the model cannot express is not injected.
                let Some(models) = p
                    .keys
                    .iter()
                    .map(|k| model.value(k))
                    .collect::<Option<Vec<f64>>>()
                else {
                    continue;
                };
                for m in [1.0f64, -2.0, 3.0] {
                    let size = if p.increase_only { m.abs() } else { m } * p.typical;
                    assert!(
                        p.check(&models, size).is_ok(),
                        "{} {}: {:?}",
                        e.key,
                        p.name,
                        p.check(&models, size)
                    );
                }
            }
        }
    }
}

/// The short test about two centres, the bar set up at each with its own pivot offset.
fn two_centres() -> String {
    short_test()
        .replace(
            "center_mm = [250.0, 200.0, 200.0]",
            "center_mm = [[250.0, 200.0, 200.0], [330.0, 240.0, 200.0]]",
        )
        .replace(
            "setup_eccentricity_um = [3.0, -2.0, 0.0]",
            "setup_eccentricity_um = [[3.0, -2.0, 0.0], [3.0, -2.0, 0.0]]",
        )
}

/// Circles about two centres, the bar set up anew at each: the "real" machine's pivot sat
/// 4 µm off the model's in X at the first centre and 5 µm off in Y at the second, and its X
/// backlash is 4 µm larger. The set-up is fitted per centre (the library splits the pivot
/// offset into one per centre), so the backlash alone is found, at its size, and the untouched
/// judge data keep no more than the noise. One pivot offset for both centres could not take
/// the two set-ups: what it leaves is a first harmonic of several µm at one centre (checked
/// here on the same data, so that the test fails if the split stops mattering).
#[test]
fn a_bar_set_up_anew_at_each_centre_is_fitted_per_centre() {
    let text = two_centres();
    let model = ScenarioModel::new(&text, "model.toml", None).unwrap();
    let lib = few_of(model.library(&[('x', 'y')]), &["backlash_x", "setup"]);
    let mut pivots: Vec<&str> = lib
        .iter()
        .find(|e| e.key == "setup")
        .unwrap()
        .params
        .iter()
        .flat_map(|p| p.keys.iter().map(String::as_str))
        .collect();
    pivots.sort();
    let per_centre = [0, 1]
        .map(|c| [0, 1].map(|i| format!("instruments.ballbar.setup_eccentricity_um[{c}][{i}]")));
    assert_eq!(pivots, per_centre.concat());
    let backlash = model.value("machine.axes.x.drive.backlash_um").unwrap() + 4.0;
    let t = vmt_scenario::edit::Template::parse(&text, "measured.toml").unwrap();
    let real_text = t
        .with(&[
            ("machine.axes.x.drive.backlash_um", backlash),
            ("instruments.ballbar.setup_eccentricity_um[0][0]", 3.0 + 4.0),
            (
                "instruments.ballbar.setup_eccentricity_um[1][1]",
                -2.0 - 5.0,
            ),
            ("simulation.seed", 7.0),
        ])
        .unwrap();
    let s = vmt_scenario::parse(&real_text, "measured.toml", None).unwrap();
    let run = s
        .execution
        .as_ref()
        .unwrap()
        .simulate(&s.machine, &real_text, &mut |_| {})
        .unwrap();
    let real: Vec<Trace> = run
        .ballbar
        .iter()
        .map(|t| vmt_gap::model::trace_of(t).unwrap())
        .collect();
    assert_eq!(real.len(), 4, "two directions about each centre");
    let split = Split::automatic(&real).unwrap();
    let lin = Linearisation::new(&model, &lib).unwrap();
    let sel = select(&model, &lin, &real, &lib, split, &Options::default()).unwrap();
    let found: Vec<&str> = sel.steps.iter().map(|s| s.effect.as_str()).collect();
    assert_eq!(found, ["backlash_x"], "{:#?}", sel.steps);
    let b = sel.steps[0].values[0].value;
    assert!((b - 4.0).abs() < 0.4, "fitted {b} um, injected 4 um");
    let judged = sel.judged.unwrap();
    assert!(judged.after_um < 0.2, "{judged:?}");
    // The model's job about the first centre alone keeps that centre's set-up.
    let one = model
        .for_job("kind = \"ballbar\"\nplane = \"XY\"\nradius_mm = 50.0\nfeed_mm_min = 2000.0\n")
        .unwrap();
    assert_eq!(
        one.value("instruments.ballbar.setup_eccentricity_um[1]"),
        Some(-2.0)
    );
    // One offset for both pivots: the same data leave the set-up's mismatch unexplained.
    let shared = few_of(
        vmt_gap::effects::library('x', 'y'),
        &["backlash_x", "setup"],
    );
    let flat = ScenarioModel::new(
        &text.replace(
            "setup_eccentricity_um = [[3.0, -2.0, 0.0], [3.0, -2.0, 0.0]]",
            "setup_eccentricity_um = [3.0, -2.0, 0.0]",
        ),
        "model.toml",
        None,
    )
    .unwrap();
    let lin = Linearisation::new(&flat, &shared).unwrap();
    let split = Split::automatic(&real).unwrap();
    let sel = select(&flat, &lin, &real, &shared, split, &Options::default()).unwrap();
    let before = sel.judged.unwrap().before_um;
    assert!(
        before > 1.0,
        "one pivot offset for two set-ups leaves {before} um"
    );
}
