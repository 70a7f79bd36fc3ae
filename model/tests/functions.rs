//! Error functions, exact rotations and direction tracking.

use nalgebra::{Rotation3, Vector3};
use proptest::prelude::*;
use vmt_model::geometric::{ErrorTable, FunctionError, Interpolation, LegendreSeries};
use vmt_model::kinematics::rotation_matrix;
use vmt_model::{Direction, DirectionTracker};

fn legendre_closed_form(n: usize, x: f64) -> f64 {
    match n {
        0 => 1.0,
        1 => x,
        2 => 0.5 * (3.0 * x * x - 1.0),
        3 => 0.5 * (5.0 * x.powi(3) - 3.0 * x),
        4 => (35.0 * x.powi(4) - 30.0 * x * x + 3.0) / 8.0,
        _ => unreachable!(),
    }
}

proptest! {
    /// The recurrence gives P0..P4 over the stroke mapped to [-1, 1].
    #[test]
    fn legendre_series_matches_closed_forms(
        c in prop::collection::vec(-10.0..10.0f64, 5),
        lo in -1.0..0.0f64, len in 0.01..2.0f64, s in 0.0..=1.0f64,
    ) {
        let hi = lo + len;
        let q = lo + s * len;
        let xi = (2.0 * q - lo - hi) / (hi - lo);
        let series = LegendreSeries::new(c.clone(), lo, hi).unwrap();
        let expected: f64 = (0..5).map(|n| c[n] * legendre_closed_form(n, xi)).sum();
        prop_assert!((series.eval(q) - expected).abs() < 1e-12);
    }

    /// Both interpolations pass through every row and reproduce straight lines exactly.
    #[test]
    fn tables_interpolate_rows_and_lines(
        steps in prop::collection::vec(0.001..0.1f64, 2..20),
        a in -5.0..5.0f64, b in -5.0..5.0f64, s in 0.0..1.0f64,
    ) {
        let mut q = vec![0.0];
        for d in &steps { q.push(q[q.len() - 1] + d); }
        let line: Vec<f64> = q.iter().map(|x| a + b * x).collect();
        for interp in [Interpolation::Linear, Interpolation::Pchip] {
            let t = ErrorTable::new(q.clone(), line.clone(), interp).unwrap();
            for (x, v) in q.iter().zip(&line) {
                prop_assert!((t.eval(*x) - v).abs() < 1e-12);
            }
            let x = q[q.len() - 1] * s;
            prop_assert!((t.eval(x) - (a + b * x)).abs() < 1e-9);
        }
    }

    /// PCHIP keeps monotone data monotone (no overshoot between rows).
    #[test]
    fn pchip_is_monotone_on_monotone_data(
        dv in prop::collection::vec(0.0..3.0f64, 3..15),
    ) {
        let q: Vec<f64> = (0..=dv.len()).map(|i| i as f64 * 0.05).collect();
        let mut v = vec![0.0];
        for d in &dv { v.push(v[v.len() - 1] + d); }
        let t = ErrorTable::new(q.clone(), v, Interpolation::Pchip).unwrap();
        let mut last = f64::NEG_INFINITY;
        for i in 0..=1000 {
            let y = t.eval(q[q.len() - 1] * i as f64 / 1000.0);
            prop_assert!(y >= last - 1e-12);
            last = y;
        }
    }

    /// The exact rotation is the exponential map (nalgebra's axis-angle), orthonormal, det 1,
    /// on both sides of the series/trigonometric switch.
    #[test]
    fn rotation_is_exact_exponential_map(
        v in prop::array::uniform3(-1.0..1.0f64), scale_exp in -9.0..0.0f64,
    ) {
        let theta = Vector3::from(v) * 10f64.powf(scale_exp);
        let r = rotation_matrix(theta);
        let reference = Rotation3::new(theta);
        // A few ulp: each entry of RᵀR or det R sums three rounded products of entries that
        // are themselves within an ulp or two.
        let ulps = 8.0 * f64::EPSILON;
        prop_assert!((r - reference.matrix()).amax() < ulps);
        prop_assert!((r.transpose() * r - nalgebra::Matrix3::identity()).amax() < ulps);
        prop_assert!((r.determinant() - 1.0).abs() < ulps);
    }
}

#[test]
fn tables_refuse_bad_rows() {
    let e = ErrorTable::new(vec![0.0, 0.2, 0.1], vec![0.0; 3], Interpolation::Linear);
    assert_eq!(
        e.unwrap_err(),
        FunctionError::NotIncreasing {
            index: 2,
            value: 0.1,
            previous: 0.2
        }
    );
    let e = ErrorTable::new(vec![0.0, 0.1], vec![0.0, f64::NAN], Interpolation::Linear);
    assert!(matches!(e, Err(FunctionError::NotFinite { index: 1, .. })));
    let e = ErrorTable::new(vec![0.0], vec![0.0], Interpolation::Linear);
    assert_eq!(e.unwrap_err(), FunctionError::TooShort(1));
    let e = LegendreSeries::new(vec![1.0], 0.5, 0.5);
    assert!(matches!(e, Err(FunctionError::BadInterval { .. })));
}

#[test]
fn direction_tracker_follows_the_last_motion_beyond_its_dead_band() {
    let mut t = DirectionTracker::new(0.0, Direction::Forward, 1e-7);
    assert_eq!(t.update(0.001), Direction::Forward);
    // Jitter inside the dead band keeps the state.
    assert_eq!(t.update(0.001 - 0.5e-7), Direction::Forward);
    assert_eq!(t.update(0.000_5), Direction::Backward);
    assert_eq!(t.update(0.000_4), Direction::Backward);
    assert_eq!(t.update(0.000_4 + 0.5e-7), Direction::Backward);
    assert_eq!(t.update(0.000_6), Direction::Forward);
}

/// An axis' six functions evaluated together (shared Legendre basis, shared table segment, or
/// one by one when their domains differ) equal each function evaluated on its own.
mod joint_evaluation {
    use proptest::prelude::*;
    use vmt_model::Direction;
    use vmt_model::geometric::{
        AxisErrors, Component, Directional, ErrorFunction, ErrorTable, Interpolation,
        LegendreSeries,
    };

    fn function(kind: u8, c: &[f64], shift: f64) -> ErrorFunction {
        let q: Vec<f64> = (0..c.len()).map(|i| i as f64 * 0.05 + shift).collect();
        match kind % 5 {
            0 => ErrorFunction::Zero,
            1 => ErrorFunction::Legendre(LegendreSeries::new(c.to_vec(), 0.0, 0.4).unwrap()),
            2 => ErrorFunction::Legendre(LegendreSeries::new(c.to_vec(), shift, 0.5).unwrap()),
            3 => {
                ErrorFunction::Table(ErrorTable::new(q, c.to_vec(), Interpolation::Pchip).unwrap())
            }
            _ => {
                ErrorFunction::Table(ErrorTable::new(q, c.to_vec(), Interpolation::Linear).unwrap())
            }
        }
    }

    proptest! {
        #[test]
        fn joint_evaluation_equals_separate_evaluation(
            kinds in prop::array::uniform6(0u8..5),
            same in any::<bool>(),
            c in prop::collection::vec(-1e-5..1e-5f64, 3..12),
            q in -0.05..0.6f64,
        ) {
            let mut axis = AxisErrors::zero();
            // The backward functions are the forward ones on the coefficients negated, so that
            // an evaluation that ignored the direction would be caught.
            let negated: Vec<f64> = c.iter().map(|v| -v).collect();
            for (k, comp) in Component::ALL.into_iter().enumerate() {
                // With `same`, every function shares kind and domain; otherwise they mix.
                let kind = if same { kinds[0] } else { kinds[k] };
                let shift = if same { 0.0 } else { 0.01 * k as f64 };
                let forward = function(kind, &c, shift);
                let backward = function(kind, &negated, shift);
                axis.set(comp, Directional { forward, backward });
            }
            for direction in [Direction::Forward, Direction::Backward] {
                let m = axis.motion(q, direction);
                for (k, comp) in Component::ALL.into_iter().enumerate() {
                    let f = axis.get(comp);
                    let direct = match direction {
                        Direction::Forward => f.forward.eval(q),
                        Direction::Backward => f.backward.eval(q),
                    };
                    // Negated coefficients negate the function (Legendre series and tables
                    // alike are linear in their values).
                    prop_assert!((f.backward.eval(q) + f.forward.eval(q)).abs() <= 1e-20);
                    let joint = if k < 3 { m.translation[k] } else { m.rotation[k - 3] };
                    prop_assert!((joint - direct).abs() <= 1e-20 + 1e-12 * direct.abs());
                }
            }
        }
    }
}

#[test]
fn a_nan_position_does_not_panic_in_a_non_uniform_table() {
    let t = ErrorTable::new(
        vec![0.0, 0.1, 0.35],
        vec![1.0, 2.0, 3.0],
        Interpolation::Pchip,
    )
    .unwrap();
    // The binary search used to underflow on NaN; any value is fine, a panic is not.
    let _ = t.eval(f64::NAN);
}
