//! The withheld-physics cases' right answers against the simulator's physics: where a rail
//! bump's case says the circle passes the defect, the simulated bar's reading changes (within
//! the stretch where the change is above half its largest value).
//! The truth angles come from the bench's geometry (blocks' spacing, circle, defect place);
//! the change comes from the guideway model of the simulator (`vmt_model::geometric`), which
//! knows nothing of angles: the two agree only if the bench states the right "where".

use vmt_ballbar::Plane;
use vmt_gap::bench::{Answer, Physics};
use vmt_gap::model::{Forward, ScenarioModel};
use vmt_gap::physics;
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
        if let Answer::Library { effect } = &c.answer {
            assert!(
                library.contains(effect),
                "{}: {effect} is no candidate",
                c.name
            );
        }
    }
}
