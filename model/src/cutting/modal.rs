//! The tool point's structural dynamics as uncoupled modes per direction (Altintas,
//! "Manufacturing Automation", 2nd ed., §3.3; Ewins, "Modal Testing").
//!
//! Each mode k of direction X or Y is a single-degree-of-freedom oscillator in modal coordinate
//! q_k, with the tool displacement the sum of the modal coordinates:
//!
//! ```text
//! m_k·q̈_k + c_k·q̇_k + k_k·q_k = F        x = Σ_k q_k
//! ω_k = 2π·f_k,  m_k = k_k/ω_k²,  c_k = 2ζ_k·√(k_k·m_k)
//! Φ(iω) = Σ_k 1 / (k_k·(1 - (ω/ω_k)² + 2iζ_k·ω/ω_k))     receptance, m/N
//! ```

use nalgebra::Complex;

use super::{CuttingError, positive};

/// One vibration mode at the tool point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mode {
    /// Natural frequency f_n, Hz.
    pub natural_frequency_hz: f64,
    /// Viscous damping ratio ζ, 0 ≤ ζ < 1.
    pub damping_ratio: f64,
    /// Modal stiffness k, N/m.
    pub stiffness: f64,
}

impl Mode {
    /// A mode from its modal mass m (kg), f_n (Hz) and ζ: k = m·ω_n².
    pub fn from_mass(mass: f64, natural_frequency_hz: f64, damping_ratio: f64) -> Self {
        let wn = std::f64::consts::TAU * natural_frequency_hz;
        Self {
            natural_frequency_hz,
            damping_ratio,
            stiffness: mass * wn * wn,
        }
    }

    /// Natural angular frequency ω_n, rad/s.
    pub fn omega(&self) -> f64 {
        std::f64::consts::TAU * self.natural_frequency_hz
    }

    /// Modal mass m = k/ω_n², kg.
    pub fn mass(&self) -> f64 {
        self.stiffness / (self.omega() * self.omega())
    }

    /// Viscous damping c = 2ζ·√(k·m), N·s/m.
    pub fn damping(&self) -> f64 {
        2.0 * self.damping_ratio * (self.stiffness * self.mass()).sqrt()
    }

    /// Receptance of this mode at angular frequency ω (rad/s), m/N.
    pub fn receptance(&self, omega: f64) -> Complex<f64> {
        let r = omega / self.omega();
        Complex::new(1.0 - r * r, 2.0 * self.damping_ratio * r).inv() / self.stiffness
    }

    fn validate(&self, index: usize) -> Result<(), CuttingError> {
        positive("natural frequency", self.natural_frequency_hz)?;
        positive("modal stiffness", self.stiffness)?;
        if !(self.damping_ratio.is_finite() && (0.0..1.0).contains(&self.damping_ratio)) {
            return Err(CuttingError::DampingOutOfRange {
                mode: index,
                value: self.damping_ratio,
            });
        }
        Ok(())
    }
}

/// The tool point's modes in the feed (X) and normal (Y) directions; X and Y are uncoupled.
#[derive(Clone, Debug, PartialEq)]
pub struct ToolDynamics {
    /// Modes acting along X.
    pub x: Vec<Mode>,
    /// Modes acting along Y.
    pub y: Vec<Mode>,
}

impl ToolDynamics {
    /// The same modes in X and Y (a symmetric tool).
    pub fn symmetric(modes: Vec<Mode>) -> Self {
        Self {
            x: modes.clone(),
            y: modes,
        }
    }

    /// Checks every mode; modes are numbered from 0, X first.
    pub fn validate(&self) -> Result<(), CuttingError> {
        if self.x.is_empty() {
            return Err(CuttingError::NoModes { direction: "X" });
        }
        if self.y.is_empty() {
            return Err(CuttingError::NoModes { direction: "Y" });
        }
        self.x
            .iter()
            .chain(&self.y)
            .enumerate()
            .try_for_each(|(i, m)| m.validate(i))
    }

    /// Highest natural frequency of all modes, Hz: what the integration step must resolve.
    pub fn highest_frequency_hz(&self) -> f64 {
        self.x
            .iter()
            .chain(&self.y)
            .map(|m| m.natural_frequency_hz)
            .fold(0.0, f64::max)
    }

    /// Receptances (Φ_xx, Φ_yy) at ω (rad/s), m/N.
    pub fn receptance(&self, omega: f64) -> (Complex<f64>, Complex<f64>) {
        let sum = |modes: &[Mode]| modes.iter().map(|m| m.receptance(omega)).sum();
        (sum(&self.x), sum(&self.y))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn receptance_is_static_compliance_at_rest_and_peaks_at_resonance() {
        let m = Mode::from_mass(0.03993, 922.0, 0.011);
        assert!((m.receptance(0.0).re - 1.0 / m.stiffness).abs() < 1e-20);
        // At ω_n the response is purely imaginary, -1/(2ζk): it lags the force by 90°.
        let r = m.receptance(m.omega());
        assert!(r.re.abs() < 1e-12 * r.im.abs());
        assert!(
            (r.im * 2.0 * 0.011 * m.stiffness + 1.0).abs() < 1e-12,
            "{r}"
        );
        assert!((m.mass() - 0.03993).abs() < 1e-15);
    }

    #[test]
    fn negative_damping_is_refused() {
        let bad = Mode {
            damping_ratio: -0.01,
            ..Mode::from_mass(0.04, 900.0, 0.01)
        };
        let dynamics = ToolDynamics::symmetric(vec![bad]);
        assert_eq!(
            dynamics.validate(),
            Err(CuttingError::DampingOutOfRange {
                mode: 0,
                value: -0.01
            })
        );
    }
}
