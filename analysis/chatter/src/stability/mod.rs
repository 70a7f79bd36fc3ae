//! Milling stability lobes: the zero-order approximation ([`zoa`], Altintas & Budak 1995) and
//! the first-order semi-discretization ([`sd`], Insperger & Stépán 2002/2004/2011).
//!
//! Both methods linearise the regenerative milling model of Altintas ("Manufacturing
//! Automation", 2nd ed., §3.3; angles φ clockwise from +Y, feed +X, see `vmt_model::cutting`):
//!
//! ```text
//! F(t) = a·D(t)·[x(t) - x(t - τ)],     τ = 60/(N·n)  tooth period, s (n in rpm)
//! D(t) = (K_t/2)·Σ_j g(φ_j)·[a_xx a_xy; a_yx a_yy](φ_j),   φ_j = Ω·t + j·2π/N,  Ω = 2π·n/60
//! a_xx = -sin2φ - K_r(1 - cos2φ)      a_xy = -(1 + cos2φ) - K_r·sin2φ
//! a_yx = (1 - cos2φ) - K_r·sin2φ      a_yy = sin2φ - K_r(1 + cos2φ)
//! ```
//!
//! with a the axial depth (m), x = (x, y) the tool displacement (m), K_r = K_rc/K_tc the radial
//! coefficient ratio and g the screen function (1 while φ_st ≤ φ_j mod 2π ≤ φ_ex, else 0).
//! Edge coefficients do not enter the linear stability problem (they add a constant force, no
//! regeneration). Helix and run-out do, and both methods neglect them: the helix spreads each
//! tooth's entry and exit over the axial depth, which smooths D(t) and moves the flip
//! (period-doubling) lobes and the unstable islands of low radial immersion (Zatarain, Muñoa,
//! Peigné & Insperger, CIRP Annals 55(1), 2006); run-out makes the teeth cut unequal chips. The
//! time-domain simulator (`vmt_sim::milling`) models both, so its cuts near a lobe's edge may
//! disagree with these lobes, most at low immersion.

pub mod sd;
pub mod zoa;

use nalgebra::Matrix2;
use thiserror::Error;
use vmt_model::cutting::{
    CutGeometry, CuttingCoefficients, CuttingError, EndMill, MillingDirection, ToolDynamics,
};

/// Why a stability computation was refused or failed.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum StabilityError {
    #[error(transparent)]
    Cutting(#[from] CuttingError),
    #[error(
        "{name} range {start} … {end} is empty or inverted; give start < end, both finite and > 0"
    )]
    BadRange {
        name: &'static str,
        start: f64,
        end: f64,
    },
    #[error("{name} = {value} is out of range; accepted: {accepted}")]
    BadSetting {
        name: &'static str,
        value: f64,
        accepted: &'static str,
    },
    #[error("the Schur decomposition of the {size}×{size} monodromy matrix did not converge")]
    EigenNotConverged { size: usize },
}

/// Which directions of the tool are flexible.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Flexibility {
    /// X and Y, every mode of [`ToolDynamics`].
    Both,
    /// Only the feed direction X (the Y modes are taken as rigid): the 1-DOF model of
    /// Insperger & Stépán and Ding et al.
    FeedOnly,
}

/// A milling operation whose stability is asked for: tool, material, structure and engagement.
#[derive(Clone, Debug, PartialEq)]
pub struct MillingSystem {
    pub tool: EndMill,
    pub coefficients: CuttingCoefficients,
    pub dynamics: ToolDynamics,
    /// Radial depth of cut a_e, m.
    pub radial_depth: f64,
    pub direction: MillingDirection,
    pub flexibility: Flexibility,
}

impl MillingSystem {
    /// Checks every input (tool, coefficients, modes, engagement); the axial depth is the
    /// unknown here, so the engagement is checked at a depth of one flute length.
    pub fn validate(&self) -> Result<(), StabilityError> {
        self.tool.validate()?;
        self.coefficients.validate()?;
        self.dynamics.validate()?;
        self.geometry(self.tool.flute_length).validate(&self.tool)?;
        Ok(())
    }

    /// The engagement at axial depth `axial_depth` (m).
    pub fn geometry(&self, axial_depth: f64) -> CutGeometry {
        CutGeometry {
            axial_depth,
            radial_depth: self.radial_depth,
            direction: self.direction,
        }
    }

    /// Entry and exit angles (φ_st, φ_ex), rad.
    pub fn engagement_angles(&self) -> (f64, f64) {
        self.geometry(self.tool.flute_length)
            .engagement_angles(&self.tool)
    }

    /// Radial-to-tangential coefficient ratio K_r = K_rc/K_tc.
    pub fn radial_ratio(&self) -> f64 {
        self.coefficients.radial / self.coefficients.tangential
    }

    /// Number of teeth N as a float.
    pub fn teeth(&self) -> f64 {
        self.tool.teeth as f64
    }
}

/// `∫_{φ0}^{φ1} [a_xx a_xy; a_yx a_yy](φ) dφ` with K_r = `kr` in closed form; over the engagement
/// it is Altintas' \[α\] (eq. 3.87, the ½[…] terms of [`zoa`]). The building block of both the ZOA's averaged coefficients and
/// the semi-discretization's step-averaged directional matrix.
pub fn directional_integral(phi0: f64, phi1: f64, kr: f64) -> Matrix2<f64> {
    let f = |p: f64| {
        let (s2, c2) = (2.0 * p).sin_cos();
        Matrix2::new(
            0.5 * c2 - kr * p + 0.5 * kr * s2,
            -0.5 * s2 - p + 0.5 * kr * c2,
            -0.5 * s2 + p + 0.5 * kr * c2,
            -0.5 * c2 - kr * p - 0.5 * kr * s2,
        )
    };
    f(phi1) - f(phi0)
}

/// An evenly spaced grid of `count` values from `start` to `end` (both included), refused
/// when empty, inverted or not finite and positive. `name` names the quantity in the error.
pub fn grid(
    name: &'static str,
    start: f64,
    end: f64,
    count: usize,
) -> Result<Vec<f64>, StabilityError> {
    if !(start.is_finite() && end.is_finite() && start > 0.0 && start < end) {
        return Err(StabilityError::BadRange { name, start, end });
    }
    if count < 2 {
        return Err(StabilityError::BadSetting {
            name: "grid size",
            value: count as f64,
            accepted: "at least 2 points",
        });
    }
    let step = (end - start) / (count - 1) as f64;
    Ok((0..count).map(|i| start + step * i as f64).collect())
}

/// The 1-DOF benchmark of Insperger & Stépán (2004) and Ding et al. (2010): m = 0.03993 kg,
/// f_n = 922 Hz, ζ = 0.011 in X only, K_t = 6e8 N/m², K_n = 2e8 N/m², 2 teeth, down milling at
/// radial immersion a_e/D = `immersion`. The tool (D = 20 mm, straight flutes) is a stand-in:
/// only a_e/D enters the stability problem.
pub fn benchmark_1dof(immersion: f64, direction: MillingDirection) -> MillingSystem {
    use vmt_model::cutting::Mode;
    let diameter = 0.02;
    let mode = Mode::from_mass(0.03993, 922.0, 0.011);
    MillingSystem {
        tool: EndMill {
            diameter,
            teeth: 2,
            helix: 0.0,
            flute_length: 0.05,
            runout: 0.0,
            runout_angle: 0.0,
        },
        coefficients: CuttingCoefficients {
            tangential: 6e8,
            radial: 2e8,
            axial: 0.0,
            tangential_edge: 0.0,
            radial_edge: 0.0,
            axial_edge: 0.0,
        },
        dynamics: ToolDynamics::symmetric(vec![mode]),
        radial_depth: immersion * diameter,
        direction,
        flexibility: Flexibility::FeedOnly,
    }
}
