//! Stability lobes against reference numbers: the semi-discretization (SD) on the delay
//! equations with published spectral radii, the zero-order approximation (ZOA) against its
//! closed form, SD convergence, and the 1-DOF milling benchmark of Insperger & Stépán (2004)
//! and Ding et al. (2010) by both methods.

use nalgebra::DMatrix;
use proptest::prelude::*;
use vmt_chatter::stability::sd::{
    MillingSd, PeriodicDelaySystem, SdSettings, critical_depth, sd_spectral_radius,
};
use vmt_chatter::stability::zoa::{ZoaSettings, feed_only_minimum_depth, lobes};
use vmt_chatter::stability::{StabilityError, benchmark_1dof, directional_integral};
use vmt_model::cutting::MillingDirection;

/// Hayes' equation ẋ(t) = a·x(t) + b·x(t - 1).
struct Hayes {
    a: f64,
    b: f64,
}

impl PeriodicDelaySystem for Hayes {
    fn delay(&self) -> f64 {
        1.0
    }
    fn delayed_outputs(&self) -> DMatrix<f64> {
        DMatrix::identity(1, 1)
    }
    fn mean_coefficients(&self, _: f64, _: f64) -> (DMatrix<f64>, DMatrix<f64>) {
        (
            DMatrix::from_element(1, 1, self.a),
            DMatrix::from_element(1, 1, self.b),
        )
    }
}

/// The damped delayed Mathieu equation ẍ + a1·ẋ + (δ + ε·cos t)·x = b0·x(t - 2π), with the
/// time-periodic coefficient averaged exactly over each step.
struct Mathieu {
    delta: f64,
    eps: f64,
    a1: f64,
    b0: f64,
}

impl PeriodicDelaySystem for Mathieu {
    fn delay(&self) -> f64 {
        std::f64::consts::TAU
    }
    fn delayed_outputs(&self) -> DMatrix<f64> {
        DMatrix::from_row_slice(1, 2, &[1.0, 0.0])
    }
    fn mean_coefficients(&self, t0: f64, t1: f64) -> (DMatrix<f64>, DMatrix<f64>) {
        let mean_cos = (t1.sin() - t0.sin()) / (t1 - t0);
        let a = DMatrix::from_row_slice(
            2,
            2,
            &[0.0, 1.0, -(self.delta + self.eps * mean_cos), -self.a1],
        );
        (a, DMatrix::from_row_slice(2, 1, &[0.0, self.b0]))
    }
}

#[test]
fn sd_reproduces_the_spectral_radius_of_hayes_equation() {
    // a = b = -1, first-order SD with a step of 0.1 of the delay. NOTES.md gives the radius of
    // the one-step map, 0.941189374166563; the equation is autonomous, so the monodromy over
    // the delay is that map to the 10th power.
    let m = 10;
    let rho = sd_spectral_radius(&Hayes { a: -1.0, b: -1.0 }, m).unwrap();
    let per_step = rho.powf(1.0 / m as f64);
    assert!(
        (per_step - 0.941189374166563).abs() < 1e-12,
        "{per_step:.15}"
    );
    // The exact multiplier is e^{Re λ} of the rightmost root of λ + 1 + e^{-λ} = 0,
    // λ = -0.6050209 ± 1.7881880i (Newton): 0.5460630. The step of 0.1 is within 0.2 %.
    assert!((rho / 0.5460630043605498 - 1.0).abs() < 2e-3, "{rho}");
}

#[test]
fn sd_reproduces_the_spectral_radius_of_the_delayed_mathieu_equation() {
    // δ = 3, ε = 2, b0 = -0.15, a1 = 0.1, T = 2π. The radius converges as O(h²) (the error
    // falls fourfold per halved step) to 0.51205; NOTES.md gives 0.5131596 for this equation,
    // 0.2 % above: close, but another discretisation of the time-periodic term than the
    // exact step average used here (an independent NumPy/SciPy SD of the same equation gives
    // 0.5118620028 at 100 steps, as this one does).
    let m = Mathieu {
        delta: 3.0,
        eps: 2.0,
        a1: 0.1,
        b0: -0.15,
    };
    let rho = |steps| sd_spectral_radius(&m, steps).unwrap();
    let (r50, r100, r200) = (rho(50), rho(100), rho(200));
    assert!((r100 - 0.5118620028493822).abs() < 1e-10, "{r100:.16}");
    let ratio = (r100 - r50) / (r200 - r100);
    assert!((ratio - 4.0).abs() < 0.4, "convergence ratio {ratio}");
    assert!((r200 / 0.5131596340374617 - 1.0).abs() < 5e-3, "{r200}");
}

#[test]
fn the_hayes_stability_boundary_is_b_equal_minus_a_for_small_delays() {
    // For a < 0 the exact boundary of ẋ = a·x + b·x(t-1) on the b > 0 side is b = -a: the
    // radius crosses 1 there whatever the step.
    for a in [-0.5, -1.0, -2.0] {
        let below = sd_spectral_radius(&Hayes { a, b: -a * 0.98 }, 20).unwrap();
        let above = sd_spectral_radius(&Hayes { a, b: -a * 1.02 }, 20).unwrap();
        assert!(below < 1.0 && above > 1.0, "a = {a}: {below}, {above}");
    }
}

#[test]
fn zoa_slotting_minimum_is_the_closed_form_of_the_benchmark() {
    // a_min = 2kζ(1+ζ)/(N·K_n/4) ≈ 0.298 mm (NOTES.md).
    let sys = benchmark_1dof(1.0, MillingDirection::Down);
    let mode = sys.dynamics.x[0];
    let by_hand =
        2.0 * mode.stiffness * mode.damping_ratio * (1.0 + mode.damping_ratio) / (2.0 * 2e8 / 4.0);
    let closed = feed_only_minimum_depth(&sys).unwrap();
    assert!(
        (closed / by_hand - 1.0).abs() < 1e-9,
        "{closed} vs {by_hand}"
    );
    assert!((closed * 1e3 - 0.298).abs() < 0.0015, "{closed}");
}

/// Where the slotting lobes sit, not only how deep: on a single mode the ZOA's minimum is where
/// Re Φ is most negative, r² = 1 + 2ζ (f_c = 922·√1.022 = 932.1 Hz). There the receptance
/// Φ = 1/(k(1 − r² + 2jζr)) has the phase θ = −π + atan r (both parts negative), the
/// modulation's phase is ε = 3π + 2θ = 4.723 rad, and lobe k runs at
/// n = 60·f_c/(N(k + ε/2π)): lobe 1 at 15 963 rpm with N = 2. A receptance with its imaginary
/// part flipped, or ε taken from the principal arctangent (π − 2·atan r = 1.56 rad), puts it
/// at 22 400 rpm.
#[test]
fn zoa_slotting_lobe_1_bottoms_out_at_the_closed_form_speed_and_frequency() {
    let sys = benchmark_1dof(1.0, MillingDirection::Down);
    let zeta: f64 = 0.011;
    let r = (1.0 + 2.0 * zeta).sqrt();
    let f_c = 922.0 * r;
    let theta = -std::f64::consts::PI + r.atan();
    let eps = 3.0 * std::f64::consts::PI + 2.0 * theta;
    let rpm = 60.0 * f_c / (2.0 * (1.0 + eps / std::f64::consts::TAU));
    assert!((rpm - 15_963.0).abs() < 1.0, "{rpm}");
    let l = lobes(&sys, &ZoaSettings::default()).unwrap();
    let bottom = l
        .curves
        .iter()
        .flatten()
        .filter(|p| p.lobe == 1)
        .min_by(|a, b| a.depth_m.total_cmp(&b.depth_m))
        .expect("lobe 1");
    assert!(
        (bottom.speed_rpm - rpm).abs() < 100.0,
        "lobe 1 bottoms out at {} rpm, closed form {rpm}",
        bottom.speed_rpm
    );
    assert!(
        (bottom.chatter_hz - f_c).abs() < 1.0,
        "{} Hz against {f_c}",
        bottom.chatter_hz
    );
}

#[test]
fn zoa_lobes_touch_their_closed_form_minimum_at_every_immersion() {
    for immersion in [1.0, 0.5, 0.1, 0.05] {
        for direction in [MillingDirection::Down, MillingDirection::Up] {
            let sys = benchmark_1dof(immersion, direction);
            let l = lobes(&sys, &ZoaSettings::default()).unwrap();
            let lowest = l
                .curves
                .iter()
                .flatten()
                .map(|p| p.depth_m)
                .fold(f64::INFINITY, f64::min);
            let closed = feed_only_minimum_depth(&sys).unwrap();
            assert!(
                (lowest / closed - 1.0).abs() < 2e-3,
                "a/D {immersion} {direction:?}: lobes {lowest}, closed form {closed}"
            );
        }
    }
}

#[test]
fn sd_critical_depths_converge_with_the_number_of_steps() {
    // First-order SD converges as O(h²): the default number of steps is within 1 % of 320.
    for immersion in [1.0, 0.5, 0.1, 0.05] {
        let sys = benchmark_1dof(immersion, MillingDirection::Down);
        for rpm in [8_000.0, 15_000.0, 21_000.0] {
            let at = |steps| {
                critical_depth(&sys, rpm, 0.02, &SdSettings { steps })
                    .unwrap()
                    .unwrap()
            };
            let (coarse, fine) = (at(SdSettings::default().steps), at(320));
            assert!(
                (coarse / fine - 1.0).abs() < 0.01,
                "a/D {immersion} at {rpm} rpm: default {coarse}, m=320 {fine}"
            );
        }
    }
}

/// The lowest SD critical depth over 5–25 krpm (m) and its speed: a scan every 500 rpm with
/// 30 steps, refined every 50 rpm around the lowest with the default steps.
fn sd_minimum(immersion: f64) -> (f64, f64) {
    let sys = benchmark_1dof(immersion, MillingDirection::Down);
    let depth = |rpm: f64, steps| {
        critical_depth(&sys, rpm, 0.02, &SdSettings { steps })
            .unwrap()
            .unwrap()
    };
    let lowest = |speeds: Vec<f64>, steps| {
        speeds
            .into_iter()
            .map(|n| (depth(n, steps), n))
            .fold((f64::INFINITY, 0.0), |a, b| if b.0 < a.0 { b } else { a })
    };
    let coarse = lowest((0..=40).map(|i| 5_000.0 + 500.0 * i as f64).collect(), 30);
    let around = (-5..=5).map(|i| coarse.1 + 50.0 * i as f64).collect();
    lowest(around, SdSettings::default().steps)
}

/// The lowest ZOA critical depth over 5–25 krpm, m.
fn zoa_minimum(immersion: f64) -> f64 {
    let sys = benchmark_1dof(immersion, MillingDirection::Down);
    let l = lobes(&sys, &ZoaSettings::default()).unwrap();
    (0..=800)
        .filter_map(|i| l.critical_depth(5_000.0 + 25.0 * i as f64))
        .map(|p| p.depth_m)
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn sd_slotting_minimum_is_within_two_per_cent_of_the_published_value() {
    // NOTES.md: semi-discretization gives about 0.32 mm near 15–16 krpm for slotting.
    let (depth, rpm) = sd_minimum(1.0);
    assert!((depth * 1e3 / 0.32 - 1.0).abs() < 0.02, "{depth} m");
    assert!((15_000.0..=16_500.0).contains(&rpm), "at {rpm} rpm");
}

#[test]
fn zoa_and_sd_minima_agree_at_high_immersion_and_part_at_low_immersion() {
    // The ZOA keeps only the period average of the directional coefficients. At a/D ≥ 0.5 a
    // tooth is in the cut much of the period and the minima differ by under 10 %; at a/D ≤ 0.1
    // the force is a train of short pulses, SD finds the period-doubling lobes, and the ZOA's
    // minimum is 30 % or more too high.
    for (immersion, close) in [(1.0, true), (0.5, true), (0.1, false), (0.05, false)] {
        let (sd, _) = sd_minimum(immersion);
        let zoa = zoa_minimum(immersion);
        let diff = zoa / sd - 1.0;
        if close {
            assert!(diff.abs() < 0.10, "a/D {immersion}: ZOA {zoa}, SD {sd}");
        } else {
            assert!(diff > 0.30, "a/D {immersion}: ZOA {zoa}, SD {sd}");
        }
    }
}

#[test]
fn a_bad_speed_depth_or_step_count_is_refused() {
    let sys = benchmark_1dof(0.5, MillingDirection::Down);
    let steps = |steps| SdSettings { steps };
    assert!(matches!(
        MillingSd::new(&sys, 0.0, &steps(40)),
        Err(StabilityError::BadSetting { .. })
    ));
    assert!(matches!(
        MillingSd::new(&sys, 10_000.0, &steps(1)),
        Err(StabilityError::BadSetting { .. })
    ));
    let sd = MillingSd::new(&sys, 10_000.0, &steps(40)).unwrap();
    assert!(sd.spectral_radius(f64::NAN).is_err());
    assert!(sd.spectral_radius(-1e-3).is_err());
    let mut no_teeth = sys.clone();
    no_teeth.tool.teeth = 0;
    let err = lobes(&no_teeth, &ZoaSettings::default()).unwrap_err();
    assert!(err.to_string().contains("teeth"), "{err}");
}

proptest! {
    /// The closed-form integral of the directional coefficients is additive over adjacent
    /// intervals and matches a midpoint quadrature of the integrand.
    #[test]
    fn directional_integral_matches_quadrature(
        phi0 in 0.0..3.0f64, len in 0.01..3.0f64, kr in 0.0..1.0f64,
    ) {
        let phi1 = phi0 + len;
        let mid = phi0 + 0.37 * len;
        let whole = directional_integral(phi0, phi1, kr);
        let split = directional_integral(phi0, mid, kr) + directional_integral(mid, phi1, kr);
        prop_assert!((whole - split).abs().max() < 1e-12);
        let n = 2000;
        let h = len / n as f64;
        let mut q = nalgebra::Matrix2::zeros();
        for i in 0..n {
            let p = phi0 + (i as f64 + 0.5) * h;
            let (s2, c2) = (2.0 * p).sin_cos();
            q += nalgebra::Matrix2::new(
                -s2 - kr * (1.0 - c2),
                -(1.0 + c2) - kr * s2,
                (1.0 - c2) - kr * s2,
                s2 - kr * (1.0 + c2),
            ) * h;
        }
        prop_assert!((whole - q).abs().max() < 1e-5, "{whole} vs {q}");
    }
}

#[test]
fn sd_minima_match_an_independent_converged_computation() {
    // No published table of the benchmark's critical depths at a/D = 0.5, 0.1 and 0.05 was
    // found (the papers give charts). The reference here is an independent implementation
    // (Python, first-order SD of the cut window with one exact free-flight step, M = 50 and
    // 100 steps, Richardson-extrapolated; November 2026): the lowest lobe over 5–25 krpm, its
    // depth and speed. Its slotting minimum, 0.317 mm near 15.9 krpm, is NOTES.md's 0.32 mm.
    for (immersion, depth_mm, rpm) in [
        (0.5, 0.600, 21_725.0),
        (0.1, 0.742, 18_130.0),
        (0.05, 1.078, 18_190.0),
    ] {
        let sys = benchmark_1dof(immersion, MillingDirection::Down);
        let at = critical_depth(&sys, rpm, 0.02, &SdSettings::default())
            .unwrap()
            .unwrap();
        assert!(
            (at * 1e3 / depth_mm - 1.0).abs() < 0.01,
            "a/D {immersion} at {rpm} rpm: {at} m against {depth_mm} mm"
        );
        let (lowest, at_rpm) = sd_minimum(immersion);
        assert!(
            (lowest * 1e3 / depth_mm - 1.0).abs() < 0.02 && (at_rpm - rpm).abs() < 150.0,
            "a/D {immersion}: minimum {lowest} m at {at_rpm} rpm against {depth_mm} mm at {rpm}"
        );
    }
}
