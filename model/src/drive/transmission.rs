//! The ball screw between the motor and the carriage: axial stiffness, damping and the nut's
//! backlash gap.
//!
//! In linear coordinates (the motor angle θ maps to `x_m = θ·lead/2π`), the screw transmits
//!
//! ```text
//! δ = x_m - x_c                              (stretch of the screw-nut, m)
//! F = k·d(δ) + c·(v_m - v_c)   if |δ| > b/2   (in contact on one flank)
//! F = 0                         otherwise      (inside the gap)
//! d(δ) = δ - sign(δ)·b/2                      (dead zone of the gap b)
//! ```
//!
//! `F` pushes the carriage towards +x and the motor towards -x (N). `k` is the series axial
//! stiffness of screw, nut and thrust bearings (N/m), `c` its damping (N·s/m), `b` the total
//! gap between the nut's flanks (m). With `b = 0` this is a plain spring-damper.

/// Ball screw and nut parameters, SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScrewParams {
    /// Lead: carriage travel per motor revolution, m.
    pub lead_m: f64,
    /// Axial stiffness k of screw, nut and bearings in series, N/m.
    pub stiffness_n_per_m: f64,
    /// Axial damping c, N·s/m.
    pub damping_n_s_per_m: f64,
    /// Total gap b between the nut's flanks (the backlash), m.
    pub backlash_m: f64,
}

impl ScrewParams {
    /// Metres of travel per radian of the motor, `lead / 2π`.
    pub fn m_per_rad(&self) -> f64 {
        self.lead_m / std::f64::consts::TAU
    }

    /// The force the screw exerts on the carriage (N, towards +x) for motor-side position and
    /// velocity `x_m`, `v_m` and carriage position and velocity `x_c`, `v_c` (m, m/s).
    #[inline]
    pub fn force(&self, x_m: f64, v_m: f64, x_c: f64, v_c: f64) -> f64 {
        let half = 0.5 * self.backlash_m;
        let delta = x_m - x_c;
        if delta > half {
            self.stiffness_n_per_m * (delta - half) + self.damping_n_s_per_m * (v_m - v_c)
        } else if delta < -half {
            self.stiffness_n_per_m * (delta + half) + self.damping_n_s_per_m * (v_m - v_c)
        } else {
            0.0
        }
    }
}
