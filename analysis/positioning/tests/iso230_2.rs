//! ISO 230-2 evaluation: the figures' laws over arbitrary readings, a scale error and a
//! backlash recovered from readings made by formula, and the refusals of unusable input.

use proptest::prelude::*;
use vmt_positioning::{Approach, PositioningError, PositioningRun, Reading, evaluate};

/// Readings of `targets` × `runs` per direction from `f(target_mm, approach, run)`.
fn readings(targets: &[f64], runs: usize, f: impl Fn(f64, Approach, usize) -> f64) -> Vec<Reading> {
    let mut v = Vec::new();
    for run in 1..=runs {
        for approach in [Approach::Forward, Approach::Backward] {
            for &target_mm in targets {
                v.push(Reading {
                    target_mm,
                    approach,
                    run,
                    deviation_um: f(target_mm, approach, run),
                });
            }
        }
    }
    v
}

/// A test of 2-8 targets, 2-6 runs and deviations within ±20 µm.
fn any_test() -> impl Strategy<Value = (Vec<f64>, usize, Vec<f64>)> {
    (2usize..8, 2usize..6).prop_flat_map(|(n, runs)| {
        (
            Just((0..n).map(|i| 50.0 * i as f64 + 10.0).collect::<Vec<_>>()),
            Just(runs),
            prop::collection::vec(-20.0..20.0f64, 2 * n * runs),
        )
    })
}

fn run_of(targets: &[f64], runs: usize, x: &[f64]) -> PositioningRun {
    let n = targets.len();
    let v = readings(targets, runs, |t, a, j| {
        let i = targets.iter().position(|&p| p == t).unwrap();
        let d = usize::from(a == Approach::Backward);
        x[((j - 1) * 2 + d) * n + i]
    });
    PositioningRun::new("X", v).unwrap()
}

proptest! {
    /// A constant offset of every deviation (a laser zeroed elsewhere) changes no figure but
    /// the trend's level; B̄ and every span are differences.
    #[test]
    fn an_offset_changes_no_figure((targets, runs, x) in any_test(), c in -50.0..50.0f64) {
        let a = evaluate(&run_of(&targets, runs, &x)).iso230_2;
        let shifted: Vec<f64> = x.iter().map(|v| v + c).collect();
        let b = evaluate(&run_of(&targets, runs, &shifted)).iso230_2;
        for (p, q) in [(a.a_um, b.a_um), (a.e_um, b.e_um), (a.m_um, b.m_um), (a.r_um, b.r_um),
                       (a.b_um, b.b_um), (a.b_mean_um, b.b_mean_um), (a.a_forward_um, b.a_forward_um)] {
            prop_assert!((p - q).abs() < 1e-9, "{p} vs {q}");
        }
    }

    /// Swapping the directions negates every reversal and leaves the bidirectional figures.
    #[test]
    fn swapping_directions_negates_the_reversal((targets, runs, x) in any_test()) {
        let a = evaluate(&run_of(&targets, runs, &x));
        let r: Vec<Reading> = run_of(&targets, runs, &x).readings.into_iter().map(|mut r| {
            r.approach = match r.approach {
                Approach::Forward => Approach::Backward,
                Approach::Backward => Approach::Forward,
            };
            r
        }).collect();
        let swapped = evaluate(&PositioningRun::new("X", r).unwrap());
        let (a, b) = (&a.iso230_2, &swapped.iso230_2);
        prop_assert!((a.b_mean_um + b.b_mean_um).abs() < 1e-9);
        for (p, q) in [(a.a_um, b.a_um), (a.e_um, b.e_um), (a.m_um, b.m_um), (a.r_um, b.r_um), (a.b_um, b.b_um),
                       (a.a_forward_um, b.a_backward_um), (a.r_forward_um, b.r_backward_um)] {
            prop_assert!((p - q).abs() < 1e-9, "{p} vs {q}");
        }
    }

    /// The standard's figures nest: A ≥ E ≥ M, E ≥ E↑, E↓; R ≥ R↑, R↓ and R ≥ B; A ≥ A↑, A↓;
    /// and scaling every deviation by k > 0 scales every figure by k.
    #[test]
    fn figures_nest_and_scale((targets, runs, x) in any_test(), k in 0.1..10.0f64) {
        let f = evaluate(&run_of(&targets, runs, &x)).iso230_2;
        let eps = 1e-9;
        prop_assert!(f.a_um + eps >= f.e_um && f.e_um + eps >= f.m_um);
        prop_assert!(f.e_um + eps >= f.e_forward_um.max(f.e_backward_um));
        prop_assert!(f.r_um + eps >= f.r_forward_um.max(f.r_backward_um));
        prop_assert!(f.r_um + eps >= f.b_um);
        prop_assert!(f.a_um + eps >= f.a_forward_um.max(f.a_backward_um));
        let scaled: Vec<f64> = x.iter().map(|v| v * k).collect();
        let g = evaluate(&run_of(&targets, runs, &scaled)).iso230_2;
        for (p, q) in [(f.a_um, g.a_um), (f.e_um, g.e_um), (f.m_um, g.m_um), (f.r_um, g.r_um), (f.b_um, g.b_um)] {
            prop_assert!((p * k - q).abs() < 1e-9 * (1.0 + q.abs()), "{p}·{k} vs {q}");
        }
    }
}

/// A scale error of 12 ppm, a backlash of 3 µm (the backward approach 3 µm short) and
/// alternating run-to-run scatter of ±0.5 µm: written by formula, not by the simulator.
#[test]
fn scale_error_and_backlash_from_readings_by_formula() {
    let targets: Vec<f64> = (0..11).map(|i| 50.0 * i as f64).collect();
    let v = readings(&targets, 5, |t, a, j| {
        let scatter = if j % 2 == 0 { 0.5 } else { -0.5 };
        let back = if a == Approach::Backward { -3.0 } else { 0.0 };
        12e-3 * t + back + scatter
    });
    let e = evaluate(&PositioningRun::new("X", v).unwrap());
    let f = &e.iso230_2;
    // Runs j = 1..5 give -0.5, +0.5, -0.5, +0.5, -0.5: mean -0.1, s = sqrt(5·0.16+... )/2.
    let s = ((3.0 * 0.4f64.powi(2) + 2.0 * 0.6f64.powi(2)) / 4.0).sqrt();
    assert!((f.s_forward_um[3] - s).abs() < 1e-12);
    assert!((f.b_um - 3.0).abs() < 1e-12 && (f.b_mean_um - 3.0).abs() < 1e-12);
    // E spans the scale over 500 mm (6 µm) plus the reversal (3 µm).
    assert!((f.e_um - 9.0).abs() < 1e-9, "E {}", f.e_um);
    assert!((f.m_um - 6.0).abs() < 1e-9, "M {}", f.m_um);
    // R = 2s + 2s + |B|.
    assert!((f.r_um - (4.0 * s + 3.0)).abs() < 1e-9, "R {}", f.r_um);
    assert!((f.a_um - (9.0 + 4.0 * s)).abs() < 1e-9, "A {}", f.a_um);
    assert!((e.trend.slope_um_per_m - 12.0).abs() < 1e-9);
    assert!(e.trend.residual_span_um < 1e-9);
    // The compensation table undoes the mean bidirectional deviation.
    let last = e.compensation.last().unwrap();
    assert!((last.bidirectional_um - (-(6.0 - 1.5 - 0.1))).abs() < 1e-9);
    assert!(e.notes.is_empty(), "{:?}", e.notes);
}

#[test]
fn fewer_runs_and_targets_than_the_standard_are_noted() {
    let v = readings(&[0.0, 100.0, 200.0], 3, |_, _, j| j as f64);
    let e = evaluate(&PositioningRun::new("Y", v).unwrap());
    assert_eq!(e.notes.len(), 2, "{:?}", e.notes);
    assert!(e.notes[0].contains("5 runs") && e.notes[0].contains("are 3"));
    assert!(e.notes[1].contains("this test has 3"));
}

/// Readings 5 mm off at every target (a laser not zeroed at a datum) and readings in mm
/// written as µm give the same figures' laws but are noted: the first would put −5 mm into
/// every compensation, the second an A of some nm. The same test as written is not noted.
#[test]
fn offset_readings_and_readings_in_the_wrong_unit_are_noted() {
    let targets: Vec<f64> = (0..6).map(|i| 100.0 * i as f64).collect();
    let test = |offset: f64, scale: f64| {
        let v = readings(&targets, 5, |t, a, j| {
            let back = if a == Approach::Backward { -3.0 } else { 0.0 };
            scale * (offset + 12e-3 * t + back + 0.1 * j as f64)
        });
        evaluate(&PositioningRun::new("X", v).unwrap())
    };
    assert!(test(0.0, 1.0).notes.is_empty());
    // Just inside: a mean deviation of +99.6 µm at the first target.
    assert!(test(99.6 - 0.3 + 1.5, 1.0).notes.is_empty());
    let offset = test(5000.0, 1.0);
    assert_eq!(offset.notes.len(), 1, "{:?}", offset.notes);
    assert!(
        offset.notes[0].contains("the nearest is +4998.8 µm"),
        "{}",
        offset.notes[0]
    );
    let mm = test(0.0, 1e-3);
    assert_eq!(mm.notes.len(), 1, "{:?}", mm.notes);
    assert!(mm.notes[0].contains("within 0.0094 µm"), "{}", mm.notes[0]);
}

/// Five targets per metre hold up to 2000 mm of travel; beyond it the standard's procedure for
/// long axes (ISO 230-2, 6.2) applies, which the report says instead of asking for targets.
#[test]
fn long_axes_are_noted_as_such() {
    let every = |step: f64, travel: f64| -> Vec<f64> {
        (0..=(travel / step) as usize)
            .map(|i| step * i as f64)
            .collect()
    };
    let at_limit = readings(&every(200.0, 2000.0), 5, |_, _, j| j as f64);
    let e = evaluate(&PositioningRun::new("X", at_limit).unwrap());
    assert!(e.notes.is_empty(), "{:?}", e.notes);
    let sparse = readings(&every(250.0, 2000.0), 5, |_, _, j| j as f64);
    let e = evaluate(&PositioningRun::new("X", sparse).unwrap());
    assert_eq!(e.notes.len(), 1, "{:?}", e.notes);
    assert!(e.notes[0].contains("(10 over 2000 mm); this test has 9"));
    let long = readings(&every(250.0, 3000.0), 5, |_, _, j| j as f64);
    let e = evaluate(&PositioningRun::new("X", long).unwrap());
    assert_eq!(e.notes.len(), 1, "{:?}", e.notes);
    assert!(
        e.notes[0].contains("tested travel is 3000 mm"),
        "{}",
        e.notes[0]
    );
}

#[test]
fn unusable_readings_are_refused_with_the_reason() {
    assert_eq!(
        PositioningRun::new("X", vec![]),
        Err(PositioningError::Empty)
    );
    let one_target = readings(&[100.0], 5, |_, _, _| 0.0);
    assert_eq!(
        PositioningRun::new("X", one_target),
        Err(PositioningError::TooFewTargets(1))
    );
    let mut nan = readings(&[0.0, 100.0], 5, |_, _, _| 0.0);
    nan[7].deviation_um = f64::NAN;
    let e = PositioningRun::new("X", nan).unwrap_err();
    assert!(
        e.to_string().starts_with("reading 7: deviation_um is NaN"),
        "{e}"
    );
    let mut dup = readings(&[0.0, 100.0], 3, |_, _, _| 0.0);
    dup[4].run = 1;
    let e = PositioningRun::new("X", dup).unwrap_err();
    assert!(
        matches!(
            e,
            PositioningError::Duplicate {
                reading: 4,
                run: 1,
                ..
            }
        ),
        "{e}"
    );
    // One backward run at 100 mm: no repeatability can be estimated there.
    let mut short = readings(&[0.0, 100.0], 2, |_, _, _| 0.0);
    short.retain(|r| !(r.target_mm == 100.0 && r.approach == Approach::Backward && r.run == 2));
    let e = PositioningRun::new("X", short).unwrap_err();
    assert_eq!(
        e.to_string(),
        "target 100 mm has 1 backward reading(s); ISO 230-2 needs at least 2 per target and direction to estimate the repeatability (the standard asks for 5)"
    );
}
