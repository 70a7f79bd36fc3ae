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
//!
//! Coordinates: each axis' coordinate `q` is the commanded tool position relative to the
//! workpiece (ISO 841). A carriage on the workpiece side moves the opposite way (`-q` along the
//! axis); its drive force along `+q` is a physical force along `-axis`. The moving mass of an axis
//! is its carriage and everything it carries, as the scenario gives it.

mod layout;
mod multibody;
mod reduced;

pub use layout::{AxisLayout, PlantError, layout};
pub use multibody::MultibodyPlant;
pub use reduced::ReducedPlant;

use vmt_model::drive::{AxisCommand, CarriageState, Drive};

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
}

/// Which plant to build.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fidelity {
    /// Lumped per-axis ODEs.
    Reduced,
    /// rapier3d-f64 multibody.
    Multibody,
}

impl Fidelity {
    /// `reduced` or `multibody`.
    pub fn name(self) -> &'static str {
        match self {
            Fidelity::Reduced => "reduced",
            Fidelity::Multibody => "multibody",
        }
    }
}
