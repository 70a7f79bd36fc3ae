//! The end mill, its engagement with the workpiece, and the mechanistic force coefficients.
//!
//! Mechanistic (linear edge-force) model of Altintas, "Manufacturing Automation", 2nd ed., §2.3
//! and ch. 3: on an axial element dz of a tooth at immersion φ with chip thickness h,
//!
//! ```text
//! dF_t = (K_tc·h + K_te)·dz      tangential, N
//! dF_r = (K_rc·h + K_re)·dz      radial (towards the tool axis), N
//! dF_a = (K_ac·h + K_ae)·dz      axial, N
//! h    = f_t·sin φ               static chip thickness, m (f_t feed per tooth, m)
//! ```
//!
//! K_*c are the cutting coefficients (N/m²), K_*e the edge coefficients (N/m).

use super::{CuttingError, non_negative, positive};

/// Mechanistic cutting-force coefficients of a tool–material pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CuttingCoefficients {
    /// Tangential cutting coefficient K_tc, N/m².
    pub tangential: f64,
    /// Radial cutting coefficient K_rc, N/m².
    pub radial: f64,
    /// Axial cutting coefficient K_ac, N/m².
    pub axial: f64,
    /// Tangential edge coefficient K_te, N/m.
    pub tangential_edge: f64,
    /// Radial edge coefficient K_re, N/m.
    pub radial_edge: f64,
    /// Axial edge coefficient K_ae, N/m.
    pub axial_edge: f64,
}

impl CuttingCoefficients {
    /// Checks that the cutting coefficients are positive and the edge coefficients not negative.
    pub fn validate(&self) -> Result<(), CuttingError> {
        positive("tangential coefficient Kt", self.tangential)?;
        non_negative("radial coefficient Kr", self.radial)?;
        non_negative("axial coefficient Ka", self.axial)?;
        non_negative("tangential edge coefficient Kte", self.tangential_edge)?;
        non_negative("radial edge coefficient Kre", self.radial_edge)?;
        non_negative("axial edge coefficient Kae", self.axial_edge)?;
        Ok(())
    }
}

/// A cylindrical end mill with equally spaced helical flutes and a radial run-out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EndMill {
    /// Diameter D, m.
    pub diameter: f64,
    /// Number of teeth N.
    pub teeth: usize,
    /// Helix angle β, rad (0 for a straight-fluted tool).
    pub helix: f64,
    /// Flute length, m: the largest axial depth of cut the tool can take.
    pub flute_length: f64,
    /// Radial run-out ρ, m: the offset of the tool's axis from the spindle's axis of rotation.
    pub runout: f64,
    /// Angular position λ of the run-out offset, rad, measured like φ from tooth 1.
    pub runout_angle: f64,
}

impl EndMill {
    /// Checks the tool's geometry.
    pub fn validate(&self) -> Result<(), CuttingError> {
        if self.teeth == 0 {
            return Err(CuttingError::ZeroTeeth);
        }
        positive("tool diameter", self.diameter)?;
        positive("flute length", self.flute_length)?;
        non_negative("run-out", self.runout)?;
        if !(self.helix.is_finite() && (0.0..std::f64::consts::FRAC_PI_2).contains(&self.helix)) {
            return Err(CuttingError::HelixOutOfRange {
                value_deg: self.helix.to_degrees(),
            });
        }
        Ok(())
    }

    /// Tooth pitch angle 2π/N, rad.
    pub fn pitch_angle(&self) -> f64 {
        std::f64::consts::TAU / self.teeth as f64
    }

    /// Radius of tooth `j` about the spindle axis with the run-out offset:
    /// `R_j = R + ρ·cos(λ - j·2π/N)` (first order in ρ/R), m.
    pub fn tooth_radius(&self, j: usize) -> f64 {
        self.diameter / 2.0
            + self.runout * (self.runout_angle - j as f64 * self.pitch_angle()).cos()
    }

    /// Tooth-passing period τ = 60/(N·n) for spindle speed n (rpm), s: the regenerative delay.
    pub fn tooth_period(&self, spindle_rpm: f64) -> f64 {
        60.0 / (self.teeth as f64 * spindle_rpm)
    }
}

/// Up milling (conventional: the tooth enters at zero chip thickness) or down milling (climb).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MillingDirection {
    Up,
    Down,
}

/// How the tool engages the workpiece.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CutGeometry {
    /// Axial depth of cut a_p, m.
    pub axial_depth: f64,
    /// Radial depth of cut a_e, m (equal to the diameter in slotting).
    pub radial_depth: f64,
    /// Up or down milling.
    pub direction: MillingDirection,
}

impl CutGeometry {
    /// Checks the engagement against the tool: 0 < a_e ≤ D and 0 < a_p ≤ flute length.
    pub fn validate(&self, tool: &EndMill) -> Result<(), CuttingError> {
        positive("axial depth of cut", self.axial_depth)?;
        if !(self.radial_depth.is_finite()
            && self.radial_depth > 0.0
            && self.radial_depth <= tool.diameter * (1.0 + 1e-12))
        {
            return Err(CuttingError::RadialDepthOutOfRange {
                radial_mm: self.radial_depth * 1e3,
                diameter_mm: tool.diameter * 1e3,
            });
        }
        if self.axial_depth > tool.flute_length {
            return Err(CuttingError::DepthBeyondFlute {
                depth_mm: self.axial_depth * 1e3,
                flute_mm: tool.flute_length * 1e3,
            });
        }
        Ok(())
    }

    /// Radial immersion a_e/D.
    pub fn immersion(&self, tool: &EndMill) -> f64 {
        (self.radial_depth / tool.diameter).min(1.0)
    }

    /// Entry and exit angles (φ_st, φ_ex), rad: up milling 0 … arccos(1 - 2a_e/D), down milling
    /// arccos(2a_e/D - 1) … π.
    pub fn engagement_angles(&self, tool: &EndMill) -> (f64, f64) {
        let r = self.immersion(tool);
        match self.direction {
            MillingDirection::Up => (0.0, (1.0 - 2.0 * r).acos()),
            MillingDirection::Down => ((2.0 * r - 1.0).acos(), std::f64::consts::PI),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{FRAC_PI_2, PI};

    fn tool(teeth: usize) -> EndMill {
        EndMill {
            diameter: 0.02,
            teeth,
            helix: 30f64.to_radians(),
            flute_length: 0.03,
            runout: 0.0,
            runout_angle: 0.0,
        }
    }

    #[test]
    fn engagement_angles_of_slotting_and_half_immersion() {
        let t = tool(2);
        let slot = CutGeometry {
            axial_depth: 1e-3,
            radial_depth: 0.02,
            direction: MillingDirection::Down,
        };
        assert_eq!(slot.engagement_angles(&t), (0.0, PI));
        let half_up = CutGeometry {
            radial_depth: 0.01,
            direction: MillingDirection::Up,
            ..slot
        };
        let (st, ex) = half_up.engagement_angles(&t);
        assert!(st == 0.0 && (ex - FRAC_PI_2).abs() < 1e-15);
        let half_down = CutGeometry {
            direction: MillingDirection::Down,
            ..half_up
        };
        let (st, ex) = half_down.engagement_angles(&t);
        assert!((st - FRAC_PI_2).abs() < 1e-15 && ex == PI);
    }

    #[test]
    fn bad_tools_and_cuts_are_refused_by_name() {
        assert_eq!(tool(0).validate(), Err(CuttingError::ZeroTeeth));
        let deep = CutGeometry {
            axial_depth: 0.031,
            radial_depth: 0.01,
            direction: MillingDirection::Up,
        };
        let err = deep.validate(&tool(4)).unwrap_err();
        assert!(
            err.to_string().contains("beyond the flute length 30 mm"),
            "{err}"
        );
        let wide = CutGeometry {
            axial_depth: 0.001,
            radial_depth: 0.021,
            ..deep
        };
        assert!(matches!(
            wide.validate(&tool(4)),
            Err(CuttingError::RadialDepthOutOfRange { .. })
        ));
    }

    #[test]
    fn runout_makes_opposite_teeth_differ_by_twice_the_offset() {
        let t = EndMill {
            runout: 5e-6,
            ..tool(2)
        };
        assert!(((t.tooth_radius(0) - t.tooth_radius(1)) - 10e-6).abs() < 1e-15);
        assert!((t.tooth_period(12_000.0) - 60.0 / 24_000.0).abs() < 1e-18);
    }
}
