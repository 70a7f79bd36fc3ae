//! Cogging and torque ripple of the permanent-magnet servo motor.
//!
//! A synchronous servo motor's torque is not exactly what its current loop commands. Two
//! position-periodic parts add to it (Jahns & Soong, "Pulsating torque minimization techniques
//! for permanent magnet AC motor drives — a review", IEEE Trans. Industrial Electronics 43(2),
//! 1996; Zhu & Howe, "Influence of design parameters on cogging torque in permanent magnet
//! machines", IEEE Trans. Energy Conversion 15(4), 2000):
//!
//! ```text
//! T_cog(θ)    = A sin(N θ + φ_c)                   cogging: magnets against the stator teeth,
//!                                                  present without current
//! T_rip(θ, T) = r T sin(h p θ + φ_r)               ripple: back-EMF and current harmonics,
//!                                                  proportional to the motor torque T
//! ```
//!
//! with θ the rotor angle (rad), `N` the cogging periods per revolution (the least common
//! multiple of the slot and pole numbers: 36 slots and 8 poles give 72), `A` the cogging
//! amplitude (N·m), `p` the pole pairs, `h` the harmonic of the electrical angle `pθ` (6 for the
//! 5th and 7th back-EMF harmonics of a three-phase machine with sinusoidal currents) and `r` its
//! relative amplitude. In the linear coordinates of the drive (`x_m = θ·lead/2π`, forces
//! `F = T·2π/lead`) both enter the motor side of the two-mass drive (`axis`) as a force
//!
//! ```text
//! F_pulse(x_m, F) = A (2π/lead) sin(N k x_m + φ_c) + r F sin(h p k x_m + φ_r),   k = 2π/lead
//! ```
//!
//! evaluated at the start of each plant step from the motor position and the motor force of the
//! current lag, and held over the step like the screw force (semi-implicit Euler, see `axis`).
//! Its frequency is `N v/lead` (cogging) and `h p v/lead` (ripple): on a 10 mm lead at
//! 1000 mm/min 120 Hz for N = 72 and 40 Hz for h = 6, p = 4, where the velocity loop rejects
//! it only partly, so the carriage carries a small position ripple.
//!
//! Plausible sizes for the motors of a 500 × 400 × 400 mm machining centre (servo motors of
//! 4–6 N·m rated, 12 N·m peak): cogging 0.5–2 % of the rated torque (manufacturers' data
//! sheets quote 0.5–2 %; skewed motors lower), i.e. A ≈ 0.02–0.12 N·m, 19–75 N on a 10 mm lead;
//! torque ripple 1–3 % of the torque at the 6th electrical harmonic.

use std::f64::consts::TAU;

/// Cogging and torque-ripple parameters of a servo motor, SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorPulsation {
    /// Cogging amplitude A, N·m (>= 0).
    pub cogging_n_m: f64,
    /// Cogging periods per motor revolution N (LCM of slots and poles, >= 1).
    pub cogging_periods_per_rev: u32,
    /// Cogging phase φ_c at rotor angle 0, rad.
    pub cogging_phase_rad: f64,
    /// Pole pairs p (>= 1).
    pub pole_pairs: u32,
    /// Relative torque-ripple amplitude r (0.01 = 1 % of the motor torque).
    pub ripple_fraction: f64,
    /// Harmonic h of the electrical angle at which the ripple pulses (6 for a three-phase
    /// machine's 5th and 7th back-EMF harmonics).
    pub ripple_harmonic: u32,
    /// Ripple phase φ_r at rotor angle 0, rad.
    pub ripple_phase_rad: f64,
}

impl MotorPulsation {
    /// A description of the first value outside what a servo motor can have, if any.
    pub fn check(&self) -> Result<(), String> {
        let finite = [
            self.cogging_n_m,
            self.cogging_phase_rad,
            self.ripple_fraction,
            self.ripple_phase_rad,
        ]
        .iter()
        .all(|v| v.is_finite());
        if !finite {
            return Err("cogging and ripple parameters must be finite numbers".into());
        }
        if self.cogging_n_m < 0.0 || self.ripple_fraction < 0.0 {
            return Err("the cogging amplitude and the ripple fraction must be >= 0".into());
        }
        if self.cogging_periods_per_rev == 0 || self.pole_pairs == 0 || self.ripple_harmonic == 0 {
            return Err(
                "the cogging periods per revolution, pole pairs and ripple harmonic must be >= 1"
                    .into(),
            );
        }
        Ok(())
    }

    /// The pulsating torque (N·m) at rotor angle `theta` (rad) with motor torque `torque`
    /// (N·m).
    pub fn torque_n_m(&self, theta: f64, torque: f64) -> f64 {
        let n = self.cogging_periods_per_rev as f64;
        let e = (self.ripple_harmonic * self.pole_pairs) as f64;
        self.cogging_n_m * (n * theta + self.cogging_phase_rad).sin()
            + self.ripple_fraction * torque * (e * theta + self.ripple_phase_rad).sin()
    }

    /// This motor on a screw of lead `lead_m` (m), in the drive's linear coordinates.
    pub fn on_lead(&self, lead_m: f64) -> LinearPulsation {
        let k = TAU / lead_m;
        LinearPulsation {
            cogging_n: self.cogging_n_m * k,
            cogging_per_m: self.cogging_periods_per_rev as f64 * k,
            cogging_phase_rad: self.cogging_phase_rad,
            ripple_fraction: self.ripple_fraction,
            ripple_per_m: (self.ripple_harmonic * self.pole_pairs) as f64 * k,
            ripple_phase_rad: self.ripple_phase_rad,
        }
    }
}

/// [`MotorPulsation`] in the linear coordinates of a drive: forces in N, wave numbers in rad/m
/// of motor travel (`x_m = θ·lead/2π`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearPulsation {
    cogging_n: f64,
    cogging_per_m: f64,
    cogging_phase_rad: f64,
    ripple_fraction: f64,
    ripple_per_m: f64,
    ripple_phase_rad: f64,
}

impl LinearPulsation {
    /// The pulsating force (N) on the motor side at motor position `x_m` (m) with motor force
    /// `force_n` (N).
    #[inline]
    pub fn force_n(&self, x_m: f64, force_n: f64) -> f64 {
        self.cogging_n * (self.cogging_per_m * x_m + self.cogging_phase_rad).sin()
            + self.ripple_fraction
                * force_n
                * (self.ripple_per_m * x_m + self.ripple_phase_rad).sin()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn motor() -> MotorPulsation {
        MotorPulsation {
            cogging_n_m: 0.05,
            cogging_periods_per_rev: 72,
            cogging_phase_rad: 0.3,
            pole_pairs: 4,
            ripple_fraction: 0.02,
            ripple_harmonic: 6,
            ripple_phase_rad: -0.4,
        }
    }

    /// Against the conversion by hand: a torque T on a screw of lead L pushes with 2πT/L
    /// (virtual work, T dθ = F dx with dx = L dθ/2π).
    #[test]
    fn the_linear_force_is_the_torque_times_two_pi_over_the_lead() {
        let (m, lead) = (motor(), 0.01);
        let lin = m.on_lead(lead);
        for i in 0..200 {
            let x = i as f64 * 1.37e-4;
            let force = -300.0 + 3.0 * i as f64;
            let theta = TAU * x / lead;
            let torque = force * lead / TAU;
            let expected = m.torque_n_m(theta, torque) * TAU / lead;
            assert!((lin.force_n(x, force) - expected).abs() < 1e-9, "{x}");
        }
        // One cogging period is 1/72 of a revolution: 0.139 mm of a 10 mm lead.
        let cog_only = MotorPulsation {
            ripple_fraction: 0.0,
            ..m
        }
        .on_lead(lead);
        let period = lead / 72.0;
        assert!(
            (cog_only.force_n(0.1234, 0.0) - cog_only.force_n(0.1234 + period, 0.0)).abs() < 1e-9
        );
        // The amplitude: 0.05 N·m on 10 mm is 31.4 N.
        let peak = (0..10_000)
            .map(|i| cog_only.force_n(i as f64 * period / 10_000.0, 0.0).abs())
            .fold(0.0, f64::max);
        assert!((peak - 0.05 * TAU / lead).abs() < 1e-3, "{peak}");
    }

    #[test]
    fn invalid_motors_are_refused() {
        assert!(motor().check().is_ok());
        let bad = [
            MotorPulsation {
                cogging_n_m: -0.1,
                ..motor()
            },
            MotorPulsation {
                pole_pairs: 0,
                ..motor()
            },
            MotorPulsation {
                ripple_fraction: f64::NAN,
                ..motor()
            },
        ];
        for m in bad {
            assert!(m.check().is_err(), "{m:?}");
        }
    }
}
