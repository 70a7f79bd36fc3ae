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
//! gap between the nut's flanks (m). With `b = 0` this is a plain spring-damper. The dead zone
//! is the usual backlash model of a compliant transmission (Nordin & Gutman, "Controlling
//! mechanical systems with backlash — a survey", Automatica 38(10), 2002).
//!
//! The screw's periodic lead error (ISO 230-2 calls its trace the periodic or cyclic
//! positioning error; ISO 3408-3 grades ball screws by it, `v_2π`: the deviation within one
//! revolution) moves the nut by `e(x_m)` more than the motor angle says, once per revolution:
//!
//! ```text
//! e(x_m) = e_c cos(2π x_m / lead) + e_s sin(2π x_m / lead)          (m)
//! δ      = x_m + e(x_m) - x_c,   relative velocity (1 + e'(x_m)) v_m - v_c
//! ```
//!
//! Under semi-closed loop (motor encoder) the control does not see it and the carriage carries
//! `e` (amplitude `sqrt(e_c² + e_s²)`, pitch the lead); a linear scale removes it.
//!
//! With a preloaded double nut configured (`nut`), the stretch beyond the gap goes through the
//! nut's Hertzian halves in series with the shaft and bearings instead of the linear `k`
//! ([`ScrewParams::force_through`]).

use super::nut::NutSeries;

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
    /// Periodic lead error `[e_c, e_s]`: cosine and sine amplitudes over one revolution, m.
    pub cyclic_m: [f64; 2],
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
        let (nut, v_nut) = self.nut(x_m, v_m);
        let half = 0.5 * self.backlash_m;
        let delta = nut - x_c;
        if delta > half {
            self.stiffness_n_per_m * (delta - half) + self.damping_n_s_per_m * (v_nut - v_c)
        } else if delta < -half {
            self.stiffness_n_per_m * (delta + half) + self.damping_n_s_per_m * (v_nut - v_c)
        } else {
            0.0
        }
    }

    /// [`ScrewParams::force`] with the nut's share of the spring a preloaded double nut
    /// (`nut`): the stretch beyond the gap goes through the nut's Hertzian halves in series
    /// with the shaft and bearings, plus the damping.
    #[inline]
    pub fn force_through(&self, nut: &NutSeries, x_m: f64, v_m: f64, x_c: f64, v_c: f64) -> f64 {
        let (nut_at, v_nut) = self.nut(x_m, v_m);
        let half = 0.5 * self.backlash_m;
        let delta = nut_at - x_c;
        let stretch = if delta > half {
            delta - half
        } else if delta < -half {
            delta + half
        } else {
            return 0.0;
        };
        nut.force(stretch, nut.linear_guess(stretch)).0 + self.damping_n_s_per_m * (v_nut - v_c)
    }

    /// Where the screw puts the nut for a motor side at `x_m`, `v_m`: `x_m + e(x_m)` and its
    /// velocity, m and m/s.
    #[inline]
    pub fn nut(&self, x_m: f64, v_m: f64) -> (f64, f64) {
        let [c, s] = self.cyclic_m;
        if c == 0.0 && s == 0.0 {
            return (x_m, v_m);
        }
        let k = std::f64::consts::TAU / self.lead_m;
        let (sin, cos) = (k * x_m).sin_cos();
        (
            x_m + c * cos + s * sin,
            v_m * (1.0 + k * (s * cos - c * sin)),
        )
    }
}
