//! The withheld-physics cases' right answers against the simulator's physics, and one case's
//! analysis against an independent closed form.
//!
//! Where a rail bump's case says the circle passes the defect, the simulated bar's reading
//! changes (within the stretch where the change is above half its largest value). The truth
//! angles come from the bench's geometry (blocks' spacing, circle, defect place); the change
//! comes from the guideway model of the simulator (`vmt_model::geometric`), which knows
//! nothing of angles: the two agree only if the bench states the right "where".

use vmt_ballbar::Plane;
use vmt_gap::bench::{Answer, Physics};
use vmt_gap::model::{Forward, ScenarioModel};
use vmt_gap::physics;
use vmt_gap::select::{Linearisation, Options, select};
use vmt_gap::split::Split;
use vmt_scenario::edit::Template;

/// The built-in machine's test in `plane` (the bench's: 100 mm at 2000 mm/min).
fn model(plane: &str) -> (String, ScenarioModel) {
    let t = Template::parse(vmt_scenario::BUILTIN_DEFAULT, "vmc500.toml").unwrap();
    let text = t
        .with(&[("job.radius_mm", 100.0), ("job.feed_mm_min", 2000.0)])
        .unwrap();
    let text = Template::parse(&text, "vmc500.toml")
        .unwrap()
        .with_text(&[("job.plane", plane)])
        .unwrap();
    let m = ScenarioModel::new(&text, "vmc500.toml", None).unwrap();
    (text, m)
}

/// The "real" machine of scenario `text`, its bar with the instrument's noise and resolution.
fn measured(text: &str) -> Vec<vmt_ballbar::Trace> {
    ScenarioModel::instrumented(text, "case", None)
        .unwrap()
        .traces(&[])
        .unwrap()
}

/// The bench case of `m` whose name starts with `name`, and the runs of `text` with its
/// physics switched on.
fn case_run(text: &str, m: &ScenarioModel, name: &str) -> (Physics, Vec<vmt_ballbar::Trace>) {
    let case = physics::cases(m, Plane::Xy)
        .unwrap()
        .into_iter()
        .find(|c| c.name.starts_with(name))
        .unwrap();
    let with = Template::parse(text, "case")
        .unwrap()
        .with_fragments(&case.fragments)
        .unwrap();
    let runs = measured(&with);
    (case, runs)
}

/// The selection of `m` against `measured` over the library's candidates named `keys`.
fn select_among(
    m: &ScenarioModel,
    measured: &[vmt_ballbar::Trace],
    keys: &[&str],
) -> vmt_gap::select::Selection {
    let lib: Vec<_> = m
        .library(&[('x', 'y')])
        .into_iter()
        .filter(|e| keys.contains(&e.key.as_str()))
        .collect();
    assert_eq!(lib.len(), keys.len());
    select(
        m,
        &Linearisation::new(m, &lib).unwrap(),
        measured,
        &lib,
        Split::automatic(measured).unwrap(),
        &Options::default(),
    )
    .unwrap()
}

/// The stretch of angles (deg, unwrapped) around the largest change of the reading with the
/// case's physics switched on, where the change stays above half its largest value.
fn changed_span(text: &str, base: &ScenarioModel, case: &Physics) -> (f64, f64) {
    let with = Template::parse(text, "case")
        .unwrap()
        .with_fragments(&case.fragments)
        .unwrap();
    let changed = ScenarioModel::new(&with, "case", None)
        .unwrap()
        .traces(&[])
        .unwrap();
    let reference = base.traces(&[]).unwrap();
    let (mut best, mut span) = (0.0, (0.0, 0.0));
    for (r, c) in reference.iter().zip(&changed) {
        let d: Vec<f64> = r
            .deviation_um
            .iter()
            .zip(&c.deviation_um)
            .map(|(a, b)| (b - a).abs())
            .collect();
        let (i, top) = d
            .iter()
            .copied()
            .enumerate()
            .fold((0, 0.0), |m, (i, v)| if v > m.1 { (i, v) } else { m });
        if top > best {
            let lo = (0..i)
                .rev()
                .find(|&j| d[j] < 0.5 * top)
                .map_or(0, |j| j + 1);
            let hi = (i..d.len())
                .find(|&j| d[j] < 0.5 * top)
                .map_or(d.len() - 1, |j| j - 1);
            best = top;
            let (a, b) = (r.angle_deg[lo], r.angle_deg[hi]);
            span = (a.min(b), a.max(b));
        }
    }
    assert!(
        best > 0.3,
        "{}: the bar changed by {best} µm only",
        case.name
    );
    span
}

#[test]
fn a_rail_bump_changes_the_bar_where_the_case_says_the_circle_passes_it() {
    for (plane, p) in [("XY", Plane::Xy), ("ZX", Plane::Zx)] {
        let (text, m) = model(plane);
        let cases = physics::cases(&m, p).unwrap();
        let bumps: Vec<&Physics> = cases
            .iter()
            .filter(|c| c.effect.starts_with("rail_bump") && c.name.ends_with("x1"))
            .collect();
        assert_eq!(bumps.len(), 2, "one per axis of the plane");
        for case in bumps {
            let Answer::Unexplained { places } = &case.answer else {
                panic!("{}: a rail defect is outside the library", case.name);
            };
            let (lo, hi) = changed_span(&text, &m, case);
            // The truth within the stretch (±10°), wherever the circle's angles start.
            let inside = places.iter().any(|t| {
                (-2..=2).any(|k| {
                    let t = t.angle_deg + 360.0 * f64::from(k);
                    t >= lo - 10.0 && t <= hi + 10.0
                })
            });
            assert!(
                inside,
                "{plane} {}: the reading changes over {lo:.1}..{hi:.1} deg, the case says {places:?}",
                case.name
            );
        }
    }
}

#[test]
fn every_case_states_its_answer_and_the_library_ones_name_a_candidate() {
    let (_, m) = model("XY");
    let cases = physics::cases(&m, Plane::Xy).unwrap();
    // Seven kinds on two axes at three sizes, and the compliant structure.
    assert_eq!(cases.len(), 7 * 2 * 3 + 1);
    let library: Vec<String> = m
        .library(&[('x', 'y')])
        .into_iter()
        .map(|e| e.key)
        .collect();
    for c in &cases {
        if let Answer::Library { effects } = &c.answer {
            assert!(!effects.is_empty(), "{}: no effect", c.name);
            for effect in effects {
                assert!(
                    library.contains(effect),
                    "{}: {effect} is no candidate",
                    c.name
                );
            }
        }
    }
}

/// A screw warm over the middle half of its stroke at the start and warming on where its nut
/// runs (the distributed conduction model, `vmt_model::thermal::screw`) is, to the library,
/// the plane's scale mismatch and the screw's heating during the runs. The heating's size is
/// checked against the steel of that screw, `ρc·πd²/4·L` from the fragment's own diameter and
/// span (an independent closed form), not against the lumped node's 6.9 kJ/K.
#[test]
fn a_warm_screw_is_a_scale_mismatch_and_the_heating_of_the_screws_own_steel() {
    let (text, m) = model("XY");
    let (_, measured) = case_run(&text, &m, "screw_warming X 2K");
    let s = select_among(
        &m,
        &measured,
        &[
            "scale_mismatch",
            "screw_heating_x",
            "screw_heating_y",
            "squareness",
            "straightness_x",
            "servo_mismatch",
            "setup",
            "bar_length",
        ],
    );
    let found: Vec<&str> = s.steps.iter().map(|s| s.effect.as_str()).collect();
    assert!(
        found.contains(&"scale_mismatch") && found.contains(&"screw_heating_x"),
        "{found:?}"
    );
    assert!(s.explained(&Options::default()), "{:?}", s.judged);
    let heating = s
        .steps
        .last()
        .unwrap()
        .values
        .iter()
        .find(|v| v.unit == "K/kJ")
        .unwrap();
    let model_c = m
        .value("machine.thermal.nodes[3].capacity_j_per_k")
        .unwrap();
    let capacity = 1000.0 / (1000.0 / model_c + heating.value);
    // The report states the capacity the fitted warming per kJ means.
    assert_eq!(heating.keys.len(), 1);
    assert!((heating.keys[0].1 - capacity).abs() < 1e-6 * capacity);
    // Steel: ρc = 3.6 MJ/(m³·K); the fragment's 28 mm screw spans the 500 mm stroke and
    // 100 mm beyond each end; the nut (100 mm) runs over X 150-350 mm on this circle.
    let steel = |length_m: f64| 3.6e6 * std::f64::consts::PI / 4.0 * 0.028_f64.powi(2) * length_m;
    let (running, whole) = (steel(0.3), steel(0.7));
    assert!(
        (running..=whole).contains(&capacity),
        "effective capacity {capacity:.0} J/K; the running section has {running:.0}, the whole screw {whole:.0}"
    );
}

/// The bar's reading binned by 1° of the angle, per trace.
fn binned(traces: &[vmt_ballbar::Trace]) -> Vec<Vec<f64>> {
    traces
        .iter()
        .map(|t| {
            let mut sum = vec![(0.0, 0usize); 360];
            for (a, d) in t.angle_deg.iter().zip(&t.deviation_um) {
                let b = (a.rem_euclid(360.0) as usize).min(359);
                sum[b] = (sum[b].0 + d, sum[b].1 + 1);
            }
            sum.iter().map(|(s, n)| s / (*n).max(1) as f64).collect()
        })
        .collect()
}

/// What the compliant structure changes on the bar at `feed` mm/min, binned.
fn compliant_change(text: &str, feed: f64) -> Vec<Vec<f64>> {
    let at = Template::parse(text, "model")
        .unwrap()
        .with(&[("job.feed_mm_min", feed)])
        .unwrap();
    let compliant = Template::parse(&at, "model")
        .unwrap()
        .with_text(&[("simulation.fidelity", "compliant")])
        .unwrap();
    let traces = |t: &str| {
        ScenarioModel::new(t, "model", None)
            .unwrap()
            .traces(&[])
            .unwrap()
    };
    let (rigid, bent) = (binned(&traces(&at)), binned(&traces(&compliant)));
    rigid
        .iter()
        .zip(&bent)
        .map(|(r, b)| b.iter().zip(r).map(|(b, r)| b - r).collect())
        .collect()
}

/// The compliant structure's bench case is a geometric error because on a ball-bar test it is
/// quasi-static: what it changes on the bar at 2000 mm/min is what it changes at 500 mm/min
/// (a sixteenth of the inertial forces) to within 10 % of its RMS, and the change is there to
/// be seen. A closed form predicts it: `m v²/R` is 0.1 % of `m g` at 2000 mm/min on 100 mm.
#[test]
fn the_compliant_structure_changes_the_bar_alike_at_a_quarter_of_the_feed() {
    let (text, _) = model("XY");
    let (fast, slow) = (
        compliant_change(&text, 2000.0),
        compliant_change(&text, 500.0),
    );
    let rms = |v: &mut dyn Iterator<Item = f64>| {
        let (s, n) = v.fold((0.0, 0), |(s, n), x| (s + x * x, n + 1));
        (s / n as f64).sqrt()
    };
    // The mean and first harmonic of each trace are the bar's length and set-up (a carriage
    // sagging alike everywhere moves the circle's centre); the rest is what the analysis sees.
    let centred = |v: &[f64]| {
        let n = v.len() as f64;
        let angle = |b: usize| (b as f64 + 0.5).to_radians();
        let m = v.iter().sum::<f64>() / n;
        let c = 2.0 / n
            * v.iter()
                .enumerate()
                .map(|(b, x)| x * angle(b).cos())
                .sum::<f64>();
        let s = 2.0 / n
            * v.iter()
                .enumerate()
                .map(|(b, x)| x * angle(b).sin())
                .sum::<f64>();
        v.iter()
            .enumerate()
            .map(|(b, x)| x - m - c * angle(b).cos() - s * angle(b).sin())
            .collect::<Vec<f64>>()
    };
    let size = rms(&mut fast.iter().flat_map(|t| centred(t)));
    let apart = rms(&mut fast
        .iter()
        .zip(&slow)
        .flat_map(|(f, s)| centred(f).into_iter().zip(centred(s)).map(|(a, b)| a - b)));
    assert!(
        size > 0.1,
        "the structure changes the bar by {size} µm only"
    );
    assert!(apart < 0.1 * size, "{apart} µm apart of {size} µm");
}

/// The bench's test in XY (100 mm at 2000 mm/min) about two centres, the second 80 mm along X
/// and 40 mm along Y from the first ([`vmt_gap::bench::with_second_centre`]).
fn two_centre_model() -> (String, ScenarioModel) {
    let (text, _) = model("XY");
    let text = vmt_gap::bench::with_second_centre(
        &text,
        "vmc500.toml",
        None,
        Plane::Xy,
        Some([80.0, 40.0]),
    )
    .unwrap();
    let m = ScenarioModel::new(&text, "vmc500.toml", None).unwrap();
    (text, m)
}

/// The selection over a few candidates with the smooth positioning curves among them.
fn select_positioning(
    m: &ScenarioModel,
    measured: &[vmt_ballbar::Trace],
) -> vmt_gap::select::Selection {
    let keys = [
        "positioning_x",
        "scale_mismatch",
        "backlash_x",
        "setup",
        "bar_length",
    ];
    select_among(m, measured, &keys)
}

/// A 2 µm rail-joint step under X's blocks (the guideway model of the simulator) changes X's
/// error over the 100 mm a block takes to ride over it, centred where the block is over the
/// step: at carriage position 300 mm here (the bench places the defect 150 mm, half the
/// blocks' spacing, beyond it). About two centres the circles see that change begin and end,
/// so the positioning curve, a shape of the whole travel that can fit the stretch one circle
/// sees, is set aside and the gap stays unexplained, with the change at its place.
#[test]
fn a_rail_step_seen_begin_and_end_is_no_positioning_curve() {
    let (text, m) = two_centre_model();
    let (case, measured) = case_run(&text, &m, "rail_step X 2µm");
    assert!(case.name.contains("at 450 mm"), "{}", case.name);
    let s = select_positioning(&m, &measured);
    let [c] = s.local_changes.as_slice() else {
        panic!("one local change: {:?}", s.local_changes);
    };
    assert_eq!((c.axis, c.direction, c.width_mm), ('X', 'X', 100.0), "{c}");
    assert!((c.at_mm - 300.0).abs() <= 10.0, "{c}");
    assert_eq!(s.set_aside, ["positioning_x"]);
    assert!(!s.explained(&Options::default()), "{:?}", s.steps);
}

/// A non-linear positioning error of X (the bow and S of its curve, Legendre c2 = 2 µm and
/// c3 = −2 µm over the stroke) is a shape of the whole travel: no change over a stretch stands
/// out against the smooth shapes, and `positioning_x` is found, at its sizes.
#[test]
fn a_positioning_curve_is_found_about_two_centres() {
    let (text, m) = two_centre_model();
    let key = |d: &str, k: usize| format!("machine.errors.x.{d}.EXX_um[{k}]");
    let mut edits: Vec<(String, f64)> = Vec::new();
    for d in ["forward", "backward"] {
        for (k, add) in [(2, 2.0), (3, -2.0)] {
            edits.push((key(d, k), m.value(&key(d, k)).unwrap() + add));
        }
    }
    let pairs: Vec<(&str, f64)> = edits.iter().map(|(k, v)| (k.as_str(), *v)).collect();
    let measured = measured(
        &Template::parse(&text, "case")
            .unwrap()
            .with(&pairs)
            .unwrap(),
    );
    let s = select_positioning(&m, &measured);
    assert!(s.set_aside.is_empty(), "{:?}", s.local_changes);
    let found: Vec<&str> = s.steps.iter().map(|s| s.effect.as_str()).collect();
    assert_eq!(found.first(), Some(&"positioning_x"), "{found:?}");
    let values: Vec<f64> = s.steps[0].values.iter().map(|v| v.value).collect();
    assert!(
        (values[0] - 2.0).abs() < 0.3 && (values[1] + 2.0).abs() < 0.3,
        "{values:?}"
    );
}

/// The XY bench's model (100 and 50 mm about two centres), its library, and the runs of its
/// case `name` among `repeats` draws: the withheld physics with the bench's nuisance on every
/// other parameter and the instrument's noise, seeded as the bench seeds it.
fn bench_case(
    name: &str,
    repeats: usize,
) -> (
    ScenarioModel,
    Vec<vmt_gap::effects::Effect>,
    Vec<vmt_ballbar::Trace>,
) {
    let (text, _) = model("XY");
    let text = Template::parse(&text, "vmc500.toml")
        .unwrap()
        .with_fragment("job", "radius_mm = [100.0, 50.0]")
        .unwrap();
    let text =
        vmt_gap::bench::with_second_centre(&text, "vmc500.toml", None, Plane::Xy, None).unwrap();
    let m = ScenarioModel::new(&text, "vmc500.toml", None).unwrap();
    let lib = m.library(&[('x', 'y')]);
    let physics = physics::cases(&m, Plane::Xy).unwrap();
    let settings = vmt_gap::bench::Settings {
        repeats,
        ..Default::default()
    };
    let cases = vmt_gap::bench::cases(&m, &lib, &physics, &settings);
    let case = cases.iter().find(|c| c.name == name).unwrap();
    let mut edits: Vec<(&str, f64)> = case.edits.iter().map(|(k, v)| (k.as_str(), *v)).collect();
    edits.push(("simulation.seed", case.seed as f64));
    let nuisance = Template::parse(&text, "case")
        .unwrap()
        .with(&edits)
        .unwrap();
    let with = Template::parse(&nuisance, "case")
        .unwrap()
        .with_fragments(case.physics.as_ref().unwrap())
        .unwrap();
    let runs = measured(&with);
    (m, lib, runs)
}

/// The selection of the bench's whole library on `runs`.
fn select_all(
    m: &ScenarioModel,
    lib: &[vmt_gap::effects::Effect],
    runs: &[vmt_ballbar::Trace],
) -> vmt_gap::select::Selection {
    select(
        m,
        &Linearisation::new(m, lib).unwrap(),
        runs,
        lib,
        Split::automatic(runs).unwrap(),
        &Options::default(),
    )
    .unwrap()
}

/// A screw warmed over the middle half of its stroke (the simulator's conduction model of the
/// screw, `vmt_model::thermal::screw`, apart from the library), as the XY bench runs it (the
/// case `screw_warming X 3.5K x2`, its first draw): the circles about the second centre run
/// past the warm stretch's end, so X's positioning error is a scale, a bow and a growth in
/// time. Once the scale is taken, neither the bow nor the growth passes the gates alone, each
/// leaving most of what the other removes; taken in one step they explain the gap on the
/// judge bins, untouched by the fit and the choice.
#[test]
fn a_screw_warmed_over_part_of_its_length_needs_its_bow_and_heating_together() {
    let (m, lib, runs) = bench_case("screw_warming X 3.5K x2", 1);
    let s = select_all(&m, &lib, &runs);
    let steps: Vec<(&str, Option<&str>)> = s
        .steps
        .iter()
        .map(|x| (x.effect.as_str(), x.together_with.as_deref()))
        .collect();
    assert_eq!(
        steps,
        [
            ("scale_mismatch", None),
            ("positioning_x", Some("screw_heating_x")),
            ("screw_heating_x", Some("positioning_x")),
        ]
    );
    assert!(s.explained(&Options::default()), "{:?}", s.judged);
}

/// The 3.5 µm rail-joint step on X as the XY bench's second draw runs it, with the nuisance
/// of every other parameter: against the smooth shapes alone the change at its place took 36 %
/// of what they leave (under the scan's 50 %), the rest being the other effects' mismatch, so
/// the positioning curve stood and explained the step. Against the library's other effects'
/// shapes too, the change is found where a block rides over the step (X 193 mm: the bench
/// places the defect 150 mm, half the blocks' spacing, before it), the positioning curve is
/// set aside and the gap stays unexplained.
#[test]
fn a_rail_step_stands_out_of_the_other_effects_mismatch() {
    let (m, lib, runs) = bench_case("rail_step X 3.5µm at 43 mm x2 (draw 2)", 2);
    let s = select_all(&m, &lib, &runs);
    let [c] = s.local_changes.as_slice() else {
        panic!("one local change: {:?}", s.local_changes);
    };
    assert_eq!((c.axis, c.direction, c.width_mm), ('X', 'X', 100.0), "{c}");
    assert!((c.at_mm - 192.6).abs() <= 5.0, "{c}");
    assert!(
        s.set_aside.contains(&"positioning_x".to_string()),
        "{:?}",
        s.set_aside
    );
    assert!(!s.explained(&Options::default()), "{:?}", s.steps);
}
