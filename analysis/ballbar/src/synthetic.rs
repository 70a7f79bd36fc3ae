//! Synthetic ball-bar traces from physical displacement laws with exact geometry (not from the
//! first-order signatures the diagnosis fits), with seeded Gaussian noise and 0.1 µm resolution:
//! traces that did not come from the simulator, for tests, benchmarks and what-if studies.
//!
//! The tool moves on the nominal circle at the feed, sampled at 1 kHz; it is displaced by
//! `δp = ε_p p − τ_p v_p + β_p − (l_q/2) sign v_q + S_q (1 − (q/R)²) [− γ q] +
//! A sin(2π p/P + 0.3) − sign(v_p) H_p g((t − t_r)/τ_H)` and likewise for q (see
//! [`crate::signatures`] for each law). The last term is the reversal spike: after the axis
//! reverses at `t_r` it lags against its new motion by the pulse `g(x) = x e^(1−x)`, which
//! peaks at `x = 1` and is `2.446 τ_H` wide at half height, as friction holds it until the
//! velocity loop's integral breaks it free. The backlash `β_p` is a play operator of width
//! `b_p` on the axis' nominal position (a semi-closed loop: the carriage stays where it is
//! until a flank of the nut pushes it), starting on the flank of the axis' first motion:
//! `−(b_p/2) sign v_p` away from reversals, taken up over the motor's first `b_p` of travel
//! after each (see [`crate::signatures`]), or over another reach `a_p` when one is given
//! (the carriage's offset then moves `b_p/a_p` times as fast as the motor until it meets the
//! other flank; `a_p ≤ 0` is a sudden step). A negative `b_p` (a compensation that jumps the
//! motor across the gap and beyond) is the step `−(b_p/2) sign v_p`. The bar reads `|tool − pivot(t)| − R` plus a sine
//! vibration, a start transient `T e^(−t/τ_T)` (the radial following error left by a feed-in
//! at the corner onto the circle, decaying with the position loop) and N(0, σ²) noise,
//! rounded to 0.1 µm.

use crate::trace::{Plane, Sense, Trace};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};

/// Physical errors of a synthetic test: `[p, q]` pairs for the plane's axes.
#[derive(Clone, Copy, Debug, Default)]
pub struct Errors {
    /// Pivot offset from the programmed centre, µm.
    pub pivot_um: [f64; 2],
    /// Pivot drift over the whole test, µm.
    pub pivot_drift_um: [f64; 2],
    /// Scale error of each axis, ppm.
    pub scale_ppm: [f64; 2],
    /// ISO squareness of the plane, µrad.
    pub squareness_urad: f64,
    /// Servo lag of each axis, ms.
    pub lag_ms: [f64; 2],
    /// Backlash of each axis, µm.
    pub backlash_um: [f64; 2],
    /// Motor travel over which each axis' backlash is taken up after a reversal, µm: `None`
    /// for a gap held by friction (its own width); less for a screw's stretch that the
    /// carriage follows on its guides' presliding compliance.
    pub backlash_reach_um: [Option<f64>; 2],
    /// Lateral play of each axis (across it, flipping when it reverses), µm.
    pub lateral_um: [f64; 2],
    /// Straightness bow of each axis over the diameter, µm.
    pub straightness_um: [f64; 2],
    /// Cyclic error: axis (0 p, 1 q), pitch mm, amplitude µm.
    pub cyclic: Option<(usize, f64, f64)>,
    /// Vibration: frequency Hz, amplitude µm.
    pub vibration: Option<(f64, f64)>,
    /// Reversal spike of each axis: height `H` (µm, lag against the new motion) and the pulse's
    /// time constant `τ_H` (ms).
    pub spike: [Option<(f64, f64)>; 2],
    /// Start transient of every run: radial offset `T` at the first sample (µm, + outward) and
    /// its time constant `τ_T` (ms).
    pub start_transient: Option<(f64, f64)>,
    /// Reading noise σ, µm.
    pub noise_um: f64,
}

/// One trace: 360° (or `sweep_deg`) from `start_deg` in `sense`, sampled at 1 kHz, the tool
/// displaced by `e`, the progress of the test running from `s0` to `s1` over this trace.
#[allow(clippy::too_many_arguments)]
pub fn trace(
    plane: Plane,
    sense: Sense,
    radius_mm: f64,
    feed_mm_min: f64,
    start_deg: f64,
    sweep_deg: f64,
    e: &Errors,
    progress: (f64, f64),
    seed: u64,
) -> Trace {
    let r_um = radius_mm * 1e3;
    let f = feed_mm_min / 60.0; // µm/ms
    let duration_ms = sweep_deg.to_radians() * r_um / f;
    let n = duration_ms as usize;
    let mut rng = StdRng::seed_from_u64(seed);
    let offset_ms = progress.0 * duration_ms / (progress.1 - progress.0);
    let sg = sense.sign();
    let mut angle_deg = Vec::with_capacity(n);
    let mut deviation_um = Vec::with_capacity(n);
    let mut time_s = Vec::with_capacity(n);
    // The axes' first motions: their velocities at the start, or after the turn for an axis
    // that starts on it (within `STARTS_ON_TURN`, as the diagnosis takes it: the approach is
    // not known, and the carriage is taken to bear on the flank of the motion after the turn).
    let th0 = start_deg.to_radians();
    let first = |f: fn(f64) -> f64| {
        let v = f(th0);
        if v.abs() > crate::signatures::STARTS_ON_TURN {
            v
        } else {
            f(th0 + sg * 1e-3)
        }
    };
    let (s0, c0) = (first(f64::sin), first(f64::cos));
    let mut play = [
        Play::new(
            e.backlash_um[0],
            e.backlash_reach_um[0],
            r_um * th0.cos(),
            -sg * s0,
        ),
        Play::new(
            e.backlash_um[1],
            e.backlash_reach_um[1],
            r_um * th0.sin(),
            sg * c0,
        ),
    ];
    for i in 0..n {
        let t_ms = i as f64;
        let u = t_ms / duration_ms;
        let th = (start_deg + sg * sweep_deg * u).to_radians();
        let (s, c) = th.sin_cos();
        let (p, q) = (r_um * c, r_um * s);
        let (vp, vq) = (-sg * f * s, sg * f * c);
        let sign = |v: f64| if v > 0.0 { 1.0 } else { -1.0 };
        let mut dp = e.scale_ppm[0] * 1e-6 * p - e.lag_ms[0] * vp + play[0].at(p, vp)
            - 0.5 * e.lateral_um[1] * sign(vq)
            + e.straightness_um[1] * (1.0 - (q / r_um).powi(2));
        let mut dq = e.scale_ppm[1] * 1e-6 * q - e.lag_ms[1] * vq + play[1].at(q, vq)
            - 0.5 * e.lateral_um[0] * sign(vp)
            + e.straightness_um[0] * (1.0 - (p / r_um).powi(2));
        // Squareness: the q axis' line rotated by γ (sign per plane, ISO 230-1).
        let gamma = e.squareness_urad * 1e-6;
        match plane {
            Plane::Zx => dq += gamma * p,
            Plane::Xy | Plane::Yz => dp -= gamma * q,
        }
        if let Some((axis, pitch_mm, amp)) = e.cyclic {
            let x = if axis == 0 { p } else { q };
            let d = amp * (std::f64::consts::TAU * x / (pitch_mm * 1e3) + 0.3).sin();
            if axis == 0 { dp += d } else { dq += d }
        }
        for (axis, d) in [(0, &mut dp), (1, &mut dq)] {
            if let Some((h, tau_ms)) = e.spike[axis] {
                *d += spike_um(
                    h,
                    tau_ms,
                    t_ms,
                    start_deg,
                    sg,
                    duration_ms / sweep_deg,
                    axis,
                );
            }
        }
        let s_test = progress.0 + (progress.1 - progress.0) * u;
        let pivot = [
            e.pivot_um[0] + e.pivot_drift_um[0] * s_test,
            e.pivot_um[1] + e.pivot_drift_um[1] * s_test,
        ];
        let (x, y) = (p + dp - pivot[0], q + dq - pivot[1]);
        let mut d = (x * x + y * y).sqrt() - r_um;
        if let Some((hz, amp)) = e.vibration {
            d += amp * (std::f64::consts::TAU * hz * t_ms * 1e-3).sin();
        }
        if let Some((amp, tau_ms)) = e.start_transient {
            d += amp * (-t_ms / tau_ms).exp();
        }
        let n: f64 = StandardNormal.sample(&mut rng);
        d += e.noise_um * n;
        angle_deg.push(th.to_degrees());
        deviation_um.push((d / 0.1).round() * 0.1);
        time_s.push((t_ms + offset_ms) * 1e-3);
    }
    Trace {
        label: format!("{plane} {}", sense.name()),
        plane,
        sense,
        radius_mm,
        feed_mm_min,
        angle_deg,
        deviation_um,
        time_s: Some(time_s),
    }
}

/// The backlash of one axis: the carriage's offset from the motor, µm.
struct Play {
    /// Width of the gap, µm.
    b: f64,
    /// The offset's change per µm of motor travel between the flanks: 1 for a gap held by
    /// friction, `b/a` for a reach `a`.
    rate: f64,
    /// Offset at the last sample, µm.
    offset: f64,
    /// Motor position at the last sample, µm.
    last: f64,
}

impl Play {
    /// A gap of `b` µm taken up over `reach` µm of travel (`None`: `b`; zero or less: a sudden
    /// step) with the motor at `x` µm, the carriage on the flank that a first motion of sign
    /// `first` pushes.
    fn new(b: f64, reach: Option<f64>, x: f64, first: f64) -> Self {
        Self {
            b,
            rate: reach.map_or(1.0, |a| if a > 0.0 { b / a } else { f64::INFINITY }),
            offset: -0.5 * b * first.signum(),
            last: x,
        }
    }

    /// The offset with the motor at `x` µm moving at `v`: the play operator for a gap, the
    /// step `−(b/2) sign v` for a negative `b`.
    fn at(&mut self, x: f64, v: f64) -> f64 {
        if self.b < 0.0 || self.rate.is_infinite() {
            return -0.5 * self.b * if v > 0.0 { 1.0 } else { -1.0 };
        }
        let half = 0.5 * self.b;
        self.offset = (self.offset - self.rate * (x - self.last)).clamp(-half, half);
        self.last = x;
        self.offset
    }
}

/// The displacement (µm) of axis `axis` (0 p, 1 q) at `t_ms` from the spike `H e^(1−x) x`,
/// `x = (t − t_r)/τ`, after its last reversal `t_r`, against its new direction of motion. The
/// trace starts at `start_deg` in the sense of sign `sg` and takes `ms_per_deg`. Axis p
/// reverses where sin θ = 0, q where cos θ = 0; a run that starts at a reversal starts from
/// rest there, which is not counted as one.
fn spike_um(
    h: f64,
    tau_ms: f64,
    t_ms: f64,
    start_deg: f64,
    sg: f64,
    ms_per_deg: f64,
    axis: usize,
) -> f64 {
    // Angles travelled since the last reversal: reversals every 180°, p's at 0°, q's at 90°.
    let first = if axis == 0 { 0.0 } else { 90.0 };
    let travelled = t_ms / ms_per_deg;
    let at = start_deg + sg * travelled;
    let since_deg = (sg * (at - first)).rem_euclid(180.0);
    if since_deg >= travelled {
        return 0.0; // no reversal yet in this run
    }
    let x = since_deg * ms_per_deg / tau_ms;
    let th = at.to_radians();
    // The velocity after the reversal: p's is −sg f sin θ, q's sg f cos θ.
    let v = if axis == 0 {
        -sg * th.sin()
    } else {
        sg * th.cos()
    };
    -v.signum() * h * x * (1.0 - x).exp()
}

/// A CW and a CCW full circle from 0°, the CW first, the test's progress split evenly.
pub fn test(plane: Plane, e: &Errors, seed: u64) -> Vec<Trace> {
    vec![
        trace(
            plane,
            Sense::Cw,
            150.0,
            1000.0,
            0.0,
            360.0,
            e,
            (0.0, 0.5),
            seed,
        ),
        trace(
            plane,
            Sense::Ccw,
            150.0,
            1000.0,
            0.0,
            360.0,
            e,
            (0.5, 1.0),
            seed + 1,
        ),
    ]
}
