//! Milling: the end mill and its engagement, the mechanistic cutting-force coefficients, and the
//! tool point's modal dynamics. Shared by the time-domain milling simulation (vmt-sim) and the
//! stability analysis (vmt-chatter), so both speak of the same tool in the same units.
//!
//! Angle convention (Altintas, "Manufacturing Automation", 2nd ed., ch. 3): the immersion angle
//! φ of a tooth is measured clockwise from the +Y axis, the feed is along +X, the spindle turns
//! clockwise seen from the spindle (M3). A tooth cuts while φ_st ≤ φ ≤ φ_ex. Up milling starts at
//! φ_st = 0; down milling ends at φ_ex = π.

pub mod forces;
pub mod integrator;
pub mod modal;
pub mod tool;

pub use modal::{Mode, ToolDynamics};
pub use tool::{CutGeometry, CuttingCoefficients, EndMill, MillingDirection};

use thiserror::Error;

/// A milling parameter outside its physical range. Each variant names the parameter (in the
/// TOML key's words) and what is accepted.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum CuttingError {
    #[error("the end mill has zero teeth; it needs at least one")]
    ZeroTeeth,
    #[error("{name} = {value} must be a finite number greater than zero")]
    NotPositive { name: &'static str, value: f64 },
    #[error("{name} = {value} must be a finite number, zero or greater")]
    Negative { name: &'static str, value: f64 },
    #[error("damping ratio {value} of mode {mode} is negative or not finite; accepted: 0 ≤ ζ < 1")]
    DampingOutOfRange { mode: usize, value: f64 },
    #[error(
        "axial depth of cut {depth_mm} mm is beyond the flute length {flute_mm} mm of the end mill"
    )]
    DepthBeyondFlute { depth_mm: f64, flute_mm: f64 },
    #[error(
        "radial depth of cut {radial_mm} mm must be greater than 0 and at most the tool diameter {diameter_mm} mm"
    )]
    RadialDepthOutOfRange { radial_mm: f64, diameter_mm: f64 },
    #[error("the tool has no mode in {direction}; give at least one mode per direction")]
    NoModes { direction: &'static str },
    #[error("helix angle {value_deg}° is outside the accepted range 0° ≤ helix < 90°")]
    HelixOutOfRange { value_deg: f64 },
}

pub(crate) fn positive(name: &'static str, value: f64) -> Result<f64, CuttingError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(CuttingError::NotPositive { name, value })
    }
}

pub(crate) fn non_negative(name: &'static str, value: f64) -> Result<f64, CuttingError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(CuttingError::Negative { name, value })
    }
}
