//! Exact step of a damped single-degree-of-freedom oscillator under a force held constant over
//! the step (zero-order hold).
//!
//! For m·q̈ + c·q̇ + k·q = F with ω = √(k/m), ζ = c/(2√(k·m)) < 1, ω_d = ω·√(1-ζ²) and F
//! constant over [t, t+h], the state x = (q, q̇) advances exactly as
//!
//! ```text
//! x(t+h) = Φ·x(t) + Γ·F
//! Φ = e^{-ζωh} · [ cos ω_d h + ζω/ω_d·sin ω_d h      sin ω_d h / ω_d
//!                  -ω²/ω_d·sin ω_d h                 cos ω_d h - ζω/ω_d·sin ω_d h ]
//! Γ = ((1 - Φ₁₁)/k,  -Φ₂₁/k)
//! ```
//!
//! (the free response of x - (F/k, 0) about the static deflection F/k). Φ and Γ are computed
//! once per step size, so the step is unconditionally stable and exact for any h; the only
//! approximation is the hold of F. Source: Ogata, "Discrete-Time Control Systems", §5.3
//! (discretisation with a zero-order hold); the same scheme as Altintas' time-domain chatter
//! simulation ("Manufacturing Automation", 2nd ed., §3.7) with an exact instead of a
//! Runge–Kutta step.

use super::Mode;

/// A mode discretised for a fixed step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiscreteMode {
    phi: [[f64; 2]; 2],
    gamma: [f64; 2],
    /// ω², 1/s².
    omega2: f64,
    /// 2ζω, 1/s.
    two_zeta_omega: f64,
    /// 1/m, 1/kg.
    inv_mass: f64,
}

impl DiscreteMode {
    /// Discretises `mode` for the step `h` (s). The mode must be valid (0 ≤ ζ < 1, f_n > 0,
    /// k > 0; see [`Mode`]).
    pub fn new(mode: &Mode, h: f64) -> Self {
        let w = mode.omega();
        let z = mode.damping_ratio;
        let wd = w * (1.0 - z * z).sqrt();
        let e = (-z * w * h).exp();
        let (s, c) = (wd * h).sin_cos();
        let phi = [
            [e * (c + z * w / wd * s), e * s / wd],
            [-e * w * w / wd * s, e * (c - z * w / wd * s)],
        ];
        let k = mode.stiffness;
        Self {
            phi,
            gamma: [(1.0 - phi[0][0]) / k, -phi[1][0] / k],
            omega2: w * w,
            two_zeta_omega: 2.0 * z * w,
            inv_mass: 1.0 / mode.mass(),
        }
    }

    /// Advances the state (q in m, q̇ in m/s) by one step under the force `f` (N).
    #[inline]
    pub fn step(&self, state: &mut [f64; 2], f: f64) {
        let [q, v] = *state;
        state[0] = self.phi[0][0] * q + self.phi[0][1] * v + self.gamma[0] * f;
        state[1] = self.phi[1][0] * q + self.phi[1][1] * v + self.gamma[1] * f;
    }

    /// Acceleration q̈ = F/m - 2ζω·q̇ - ω²·q, m/s², of the state under the force `f` (N).
    #[inline]
    pub fn acceleration(&self, state: &[f64; 2], f: f64) -> f64 {
        f * self.inv_mass - self.two_zeta_omega * state[1] - self.omega2 * state[0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_response_matches_the_closed_form_and_settles_at_f_over_k() {
        let mode = Mode::from_mass(0.03993, 922.0, 0.011);
        let h = 2e-5;
        let d = DiscreteMode::new(&mode, h);
        let mut x = [0.0, 0.0];
        let n = 1000;
        for _ in 0..n {
            d.step(&mut x, 10.0);
        }
        // q(t) = F/k·[1 - e^{-ζωt}(cos ω_d t + ζω/ω_d sin ω_d t)]
        let (w, z, t) = (mode.omega(), 0.011_f64, n as f64 * h);
        let wd = w * (1.0 - z * z).sqrt();
        let q = 10.0 / mode.stiffness
            * (1.0 - (-z * w * t).exp() * ((wd * t).cos() + z * w / wd * (wd * t).sin()));
        assert!(
            (x[0] - q).abs() < 1e-9 * 10.0 / mode.stiffness,
            "{} vs {q}",
            x[0]
        );
        for _ in 0..200_000 {
            d.step(&mut x, 10.0);
        }
        assert!((x[0] * mode.stiffness / 10.0 - 1.0).abs() < 1e-9);
        assert!(d.acceleration(&x, 10.0).abs() < 1e-6);
    }
}
