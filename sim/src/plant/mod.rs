//! The plant: the moving assemblies of the machine driven by their feed drives.
//!
//! Two fidelities share the drive equations of `vmt_model::drive` (motor side, screw with
//! backlash, LuGre friction, current loop) and differ in how the carriages move:
//!
//! - [`ReducedPlant`]: each carriage is a lumped mass on its axis, `m_i dv/dt = F_screw - F_fc +
//!   F_gravity`, integrated by semi-implicit Euler (see `vmt_model::drive::axis`).
//! - [`MultibodyPlant`]: the carriages are the links of a rapier3d-f64 multibody (prismatic
//!   multibody joints from the ground outwards on both sides of the topology, contacts off), with
//!   their own masses. Two rates: the drives and the joint coordinates advance every plant step
//!   by semi-implicit Euler with the multibody's joint-space inverse mass and bias accelerations
//!   (gravity, Coriolis), and rapier advances the multibody every macro step (about 1 ms) under
//!   the mean drive forces, which refreshes those and sets the joint velocities.
//! - [`CompliantPlant`]: the carriages as rigid bodies with six degrees of freedom on their
//!   compliant guide blocks (a rapier3d-f64 multibody of free joints, the blocks as
//!   spring-dampers at their places, the drive force at the nut, gravity at the centres of
//!   mass): their tilts and offsets deflect the tool point, and the structure's modes are in the
//!   drives' loops.
//!
//! Coordinates: each axis' coordinate `q` is the commanded tool position relative to the
//! workpiece (ISO 841). A carriage on the workpiece side moves the opposite way (`-q` along the
//! axis); its drive force along `+q` is a physical force along `-axis`. The moving mass of an axis
//! is its carriage and everything it carries, as the scenario gives it.

mod compliant;
mod layout;
mod multibody;
mod reduced;

pub use compliant::CompliantPlant;
pub use layout::{AxisLayout, PlantError, layout};
pub use multibody::MultibodyPlant;
pub use reduced::ReducedPlant;

use nalgebra::Vector3;
use vmt_model::drive::{AxisCommand, CarriageState, Drive};
use vmt_model::kinematics::Deflection;

/// Standard gravity, m/s² (acting along -Z of the machine frame).
pub const GRAVITY_M_S2: f64 = 9.80665;

/// The interface the simulator steps, whatever the fidelity.
pub trait Plant {
    /// One servo period of the three axis controllers.
    fn control(&mut self, commands: &[AxisCommand; 3], period_s: f64);
    /// Advances the plant by `h` seconds.
    fn step(&mut self, h: f64);
    /// The drive (motor side and controller state) of axis `i` (0, 1, 2 for X, Y, Z).
    fn drive(&self, i: usize) -> &Drive;
    /// The carriages of X, Y, Z in axis coordinates (position, velocity, guideway friction).
    fn carriages(&self) -> [CarriageState; 3];
    /// The controllers' last following errors of X, Y, Z, m (one call per servo tick: the
    /// excess-error alarm's).
    fn following_errors(&self) -> [f64; 3] {
        std::array::from_fn(|i| self.drive(i).following_error_m())
    }
    /// The carriages' deflections on their guide blocks as the dynamic part of each axis'
    /// errors (see [`Deflection`]); `None` for a plant whose carriages do not deflect.
    fn deflections(&self) -> Option<[Deflection; 3]> {
        None
    }
    /// Each carriage's small motion on its guide blocks, X, Y, Z: its translation across its
    /// axis (m) and its rotation about its blocks' centroid (rad), machine axes; `None` for
    /// rigid carriages.
    fn carriage_motions(&self) -> Option<[(Vector3<f64>, Vector3<f64>); 3]> {
        None
    }
    /// The force of each guide block on its carriage along the block's normal (N), X's blocks
    /// first, in the order the structure lists them; empty for rigid carriages.
    fn block_normal_forces(&self) -> Vec<f64> {
        Vec::new()
    }
    /// Sets the force the workpiece exerts on the tool (N, machine axes), at the tool point,
    /// until it is set again; its reaction acts on the workpiece. A plant of rigid carriages
    /// takes its component along each axis on that axis' drive (in axis coordinates it is `F_i`
    /// on both sides of the machine).
    fn set_tool_force(&mut self, force_n: Vector3<f64>);
}

/// Which plant to build.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fidelity {
    /// Lumped per-axis ODEs.
    Reduced,
    /// rapier3d-f64 multibody of rigid carriages.
    Multibody,
    /// rapier3d-f64 multibody of the carriages on their compliant guide blocks.
    Compliant,
}

impl Fidelity {
    /// `reduced` or `multibody`.
    pub fn name(self) -> &'static str {
        match self {
            Fidelity::Reduced => "reduced",
            Fidelity::Multibody => "multibody",
            Fidelity::Compliant => "compliant",
        }
    }
}
