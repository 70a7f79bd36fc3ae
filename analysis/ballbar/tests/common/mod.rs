//! Synthetic ball-bar traces computed from displacement laws with exact geometry (not from the
//! first-order signatures the diagnosis fits), with seeded Gaussian noise and 0.1 µm resolution.

use vmt_ballbar::{Plane, Sense, Trace};

/// Physical errors of a synthetic test, µm, ppm, µrad, ms.
#[derive(Clone, Copy, Debug, Default)]
pub struct Errors {
    pub pivot_um: [f64; 2],
    pub pivot_drift_um: [f64; 2],
    pub scale_ppm: [f64; 2],
    pub squareness_urad: f64,
    pub lag_ms: [f64; 2],
    pub backlash_um: [f64; 2],
    pub lateral_um: [f64; 2],
    pub straightness_um: [f64; 2],
    pub cyclic: Option<(usize, f64, f64)>,
    pub vibration: Option<(f64, f64)>,
    pub noise_um: f64,
}

/// A deterministic Gaussian sequence (Box–Muller on a 64-bit LCG).
pub struct Gauss(u64);

impl Gauss {
    pub fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    pub fn next(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
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
    let mut g = Gauss::new(seed);
    let offset_ms = progress.0 * duration_ms / (progress.1 - progress.0);
    let sg = sense.sign();
    let mut angle_deg = Vec::with_capacity(n);
    let mut deviation_um = Vec::with_capacity(n);
    let mut time_s = Vec::with_capacity(n);
    for i in 0..n {
        let t_ms = i as f64;
        let u = t_ms / duration_ms;
        let th = (start_deg + sg * sweep_deg * u).to_radians();
        let (s, c) = th.sin_cos();
        let (p, q) = (r_um * c, r_um * s);
        let (vp, vq) = (-sg * f * s, sg * f * c);
        let sign = |v: f64| if v > 0.0 { 1.0 } else { -1.0 };
        let mut dp = e.scale_ppm[0] * 1e-6 * p
            - e.lag_ms[0] * vp
            - 0.5 * e.backlash_um[0] * sign(vp)
            - 0.5 * e.lateral_um[1] * sign(vq)
            + e.straightness_um[1] * (1.0 - (q / r_um).powi(2));
        let mut dq = e.scale_ppm[1] * 1e-6 * q
            - e.lag_ms[1] * vq
            - 0.5 * e.backlash_um[1] * sign(vq)
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
        d += e.noise_um * g.next();
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
