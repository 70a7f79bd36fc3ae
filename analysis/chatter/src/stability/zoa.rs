//! Zero-order approximation (ZOA) of milling stability: Altintas & Budak, "Analytical prediction
//! of stability lobes in milling", CIRP Annals 44(1), 1995; Altintas, "Manufacturing Automation",
//! 2nd ed., §3.4.
//!
//! The directional matrix D(t) is replaced by its average over the tooth period,
//! `A0 = (N/2π)·[α]` with the closed-form α's over the engagement (K_r = K_rc/K_tc):
//!
//! ```text
//! α_xx = ½[cos2φ - 2K_r·φ + K_r·sin2φ]      α_xy = ½[-sin2φ - 2φ + K_r·cos2φ]
//! α_yx = ½[-sin2φ + 2φ + K_r·cos2φ]         α_yy = ½[-cos2φ - 2K_r·φ - K_r·sin2φ]   (φ_st … φ_ex)
//! ```
//!
//! At a chatter frequency ω_c the characteristic equation `det[I + Λ·Φ0(iω_c)] = 0`, with
//! `Φ0 = [α_xx·Φ_xx α_xy·Φ_yy; α_yx·Φ_xx α_yy·Φ_yy]` (Φ the receptances, m/N), gives
//! Λ = -1/ν for each eigenvalue ν of Φ0, and with κ = Λ_I/Λ_R
//!
//! ```text
//! a_lim = -2π·Λ_R/(N·K_t)·(1 + κ²)     m (only Λ_R < 0 is physical)
//! ε = π - 2·atan κ,   T = (ε + 2kπ)/ω_c,   n = 60/(N·T) rpm,   lobe k = 0, 1, 2, …
//! ```

use nalgebra::{Complex, Matrix2};

use super::{Flexibility, MillingSystem, StabilityError, directional_integral};

/// One point of a lobe: spindle speed (rpm), critical axial depth (m), chatter frequency (Hz)
/// and lobe index k.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LobePoint {
    pub speed_rpm: f64,
    pub depth_m: f64,
    pub chatter_hz: f64,
    pub lobe: usize,
}

/// How finely the chatter frequency is swept and how many lobes are drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZoaSettings {
    /// Chatter frequencies swept evenly from `low_factor`·(lowest f_n) to `high_factor`·(highest f_n).
    pub frequencies: usize,
    pub low_factor: f64,
    pub high_factor: f64,
    /// Lobes k = 0 … lobes-1.
    pub lobes: usize,
}

impl Default for ZoaSettings {
    fn default() -> Self {
        Self {
            frequencies: 4000,
            low_factor: 0.5,
            high_factor: 2.0,
            lobes: 30,
        }
    }
}

/// Lobe curves: each a run of points of one lobe index and one eigenvalue branch, ordered by
/// chatter frequency, over which a_lim is positive.
#[derive(Clone, Debug, PartialEq)]
pub struct Lobes {
    pub curves: Vec<Vec<LobePoint>>,
}

impl Lobes {
    /// The critical depth at `speed_rpm`: the lowest of the lobes over that speed (linear
    /// interpolation along each curve), with its chatter frequency and lobe; None where no
    /// lobe reaches the speed.
    pub fn critical_depth(&self, speed_rpm: f64) -> Option<LobePoint> {
        let mut best: Option<LobePoint> = None;
        for w in self.curves.iter().flat_map(|c| c.windows(2)) {
            let (p, q) = (w[0], w[1]);
            let (lo, hi) = (p.speed_rpm.min(q.speed_rpm), p.speed_rpm.max(q.speed_rpm));
            if !(lo..=hi).contains(&speed_rpm) || hi == lo {
                continue;
            }
            let t = (speed_rpm - p.speed_rpm) / (q.speed_rpm - p.speed_rpm);
            let depth_m = p.depth_m + t * (q.depth_m - p.depth_m);
            if best.is_none_or(|b| depth_m < b.depth_m) {
                best = Some(LobePoint {
                    speed_rpm,
                    depth_m,
                    chatter_hz: p.chatter_hz + t * (q.chatter_hz - p.chatter_hz),
                    lobe: p.lobe,
                });
            }
        }
        best
    }
}

/// The averaged directional coefficients [α_xx α_xy; α_yx α_yy] (dimensionless) over the
/// engagement of `system`.
pub fn directional_coefficients(system: &MillingSystem) -> Matrix2<f64> {
    let (st, ex) = system.engagement_angles();
    directional_integral(st, ex, system.radial_ratio())
}

/// The eigenvalues Λ of `det[I + Λ·Φ0(iω)] = 0` at ω (rad/s); one is None where ν = 0 (a rigid
/// direction).
fn lambdas(system: &MillingSystem, alpha: &Matrix2<f64>, omega: f64) -> [Option<Complex<f64>>; 2] {
    let (fx, mut fy) = system.dynamics.receptance(omega);
    if system.flexibility == Flexibility::FeedOnly {
        fy = Complex::new(0.0, 0.0);
    }
    let (a, b) = (fx * alpha[(0, 0)], fy * alpha[(0, 1)]);
    let (c, d) = (fx * alpha[(1, 0)], fy * alpha[(1, 1)]);
    let half_trace = (a + d) * 0.5;
    let root = (half_trace * half_trace - (a * d - b * c)).sqrt();
    [half_trace + root, half_trace - root].map(|nu| (nu.norm() > 0.0).then(|| -nu.inv()))
}

/// Zero-order stability lobes of `system` (validated first).
pub fn lobes(system: &MillingSystem, settings: &ZoaSettings) -> Result<Lobes, StabilityError> {
    system.validate()?;
    check_settings(settings)?;
    let alpha = directional_coefficients(system);
    let modes = system.dynamics.x.iter().chain(&system.dynamics.y);
    let f_lo = modes
        .clone()
        .map(|m| m.natural_frequency_hz)
        .fold(f64::INFINITY, f64::min);
    let f_hi = system.dynamics.highest_frequency_hz();
    let freqs = super::grid(
        "chatter frequency, Hz",
        settings.low_factor * f_lo,
        settings.high_factor * f_hi,
        settings.frequencies,
    )?;
    let (n, kt) = (system.teeth(), system.coefficients.tangential);
    let mut curves = Vec::new();
    for branch in 0..2 {
        for k in 0..settings.lobes {
            let mut run: Vec<LobePoint> = Vec::new();
            for &f in &freqs {
                let wc = std::f64::consts::TAU * f;
                let point = lambdas(system, &alpha, wc)[branch].and_then(|lam| {
                    let kappa = lam.im / lam.re;
                    let depth_m =
                        -std::f64::consts::TAU * lam.re / (n * kt) * (1.0 + kappa * kappa);
                    let eps = std::f64::consts::PI - 2.0 * kappa.atan();
                    let period = (eps + std::f64::consts::TAU * k as f64) / wc;
                    (depth_m.is_finite() && depth_m > 0.0).then_some(LobePoint {
                        speed_rpm: 60.0 / (n * period),
                        depth_m,
                        chatter_hz: f,
                        lobe: k,
                    })
                });
                match point {
                    Some(p) => run.push(p),
                    None if run.len() > 1 => curves.push(std::mem::take(&mut run)),
                    None => run.clear(),
                }
            }
            if run.len() > 1 {
                curves.push(run);
            }
        }
    }
    Ok(Lobes { curves })
}

fn check_settings(s: &ZoaSettings) -> Result<(), StabilityError> {
    if s.frequencies < 2 || s.lobes == 0 {
        return Err(StabilityError::BadSetting {
            name: "ZOA frequencies/lobes",
            value: s.frequencies.min(s.lobes) as f64,
            accepted: "at least 2 frequencies and 1 lobe",
        });
    }
    if !(s.low_factor > 0.0 && s.low_factor < s.high_factor && s.high_factor.is_finite()) {
        return Err(StabilityError::BadRange {
            name: "chatter frequency factor",
            start: s.low_factor,
            end: s.high_factor,
        });
    }
    Ok(())
}

/// Closed-form minimum of the ZOA lobes for a single mode in X ([`Flexibility::FeedOnly`]):
/// with Λ = -1/(α_xx·Φ_xx) the limit is a = 2π/(N·K_t·α_xx·G) (G = Re Φ_xx), smallest at the
/// extreme of G of the sign of α_xx: G_min = -1/(4kζ(1+ζ)), G_max = 1/(4kζ(1-ζ)). Slotting
/// (α_xx = -π·K_r) gives a_min = 2kζ(1+ζ)/(N·K_rc/4). None for several modes or two directions.
pub fn feed_only_minimum_depth(system: &MillingSystem) -> Option<f64> {
    let [mode] = system.dynamics.x.as_slice() else {
        return None;
    };
    if system.flexibility != Flexibility::FeedOnly {
        return None;
    }
    let axx = directional_coefficients(system)[(0, 0)];
    let (k, z) = (mode.stiffness, mode.damping_ratio);
    let g_extreme = if axx < 0.0 {
        -1.0 / (4.0 * k * z * (1.0 + z))
    } else {
        1.0 / (4.0 * k * z * (1.0 - z))
    };
    Some(
        std::f64::consts::TAU / (system.teeth() * system.coefficients.tangential * axx * g_extreme),
    )
}
