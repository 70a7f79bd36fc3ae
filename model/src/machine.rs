//! A complete machine description: axes, error chain and thermal behaviour.

use crate::axis::Axis;
use crate::kinematics::{AxisState, VolumetricModel};
use crate::structure::Structure;
use crate::thermal::ThermalNetwork;
use crate::thermal::screw::ScrewThermalParams;
use crate::thermal_deformation::{DeformationError, ThermalDeformation, ThermalDeformationModel};
use nalgebra::Vector3;

/// Travel and moving mass of one axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisSpec {
    /// Lowest reachable coordinate, m.
    pub min_m: f64,
    /// Highest reachable coordinate, m.
    pub max_m: f64,
    /// Mass of the assembly this axis moves (its carriage and everything it carries), kg.
    pub moving_mass_kg: f64,
}

impl AxisSpec {
    /// Whether `q` (m) lies within the stroke.
    pub fn contains(&self, q: f64) -> bool {
        (self.min_m..=self.max_m).contains(&q)
    }
}

/// The thermal behaviour of a machine: its network of temperatures and the deformations they
/// cause.
#[derive(Clone, Debug)]
pub struct ThermalMachine {
    /// Lumped thermal network (nodes, conductances, heat sources, ambient).
    pub network: ThermalNetwork,
    /// Linear sensitivities of the chain's links and joints to node temperatures.
    pub deformation: ThermalDeformationModel,
    /// The screws of X, Y, Z whose temperature along their length a job simulates (their
    /// growth replaces the lumped expansion of the axis there), if any.
    pub screws: [Option<ScrewThermalParams>; 3],
}

/// A three-axis machining centre as the simulator sees it.
#[derive(Clone, Debug)]
pub struct Machine {
    /// Human-readable name.
    pub name: String,
    /// X, Y, Z travel and masses.
    pub axes: [AxisSpec; 3],
    /// Kinematic chain and geometric errors.
    pub volumetric: VolumetricModel,
    /// Thermal network and deformation model, if the machine has one.
    pub thermal: Option<ThermalMachine>,
    /// The carriages as rigid bodies on their guide blocks, if the machine describes them (the
    /// compliant plant needs them).
    pub structure: Option<Structure>,
}

impl Machine {
    /// The spec of `axis`.
    pub fn axis(&self, axis: Axis) -> &AxisSpec {
        &self.axes[axis.index()]
    }

    /// The first axis whose coordinate in `position` (m) is outside its stroke.
    pub fn outside_stroke(&self, position: &Vector3<f64>) -> Option<Axis> {
        Axis::ALL
            .into_iter()
            .find(|a| !self.axis(*a).contains(position[a.index()]))
    }

    /// The nominal tool point (relative to the workpiece, m) with every carriage at the middle
    /// of its stroke: the carriage positions plus the tool offset, so that a test circle
    /// programmed about it (programs give the tool point) is centred in the carriages' travel.
    pub fn mid_stroke_tool_point(&self) -> Vector3<f64> {
        let middle = Vector3::from_fn(|k, _| (self.axes[k].min_m + self.axes[k].max_m) / 2.0);
        self.volumetric.nominal_tool_point(&middle)
    }

    /// The thermal deformation at node temperatures `temps_c` (°C); zero without a thermal model.
    pub fn thermal_deformation(
        &self,
        temps_c: &[f64],
    ) -> Result<ThermalDeformation, DeformationError> {
        match &self.thermal {
            Some(t) => t.deformation.deformation(temps_c),
            None => Ok(ThermalDeformation::default()),
        }
    }

    /// The volumetric error (m) at `state` and node temperatures `temps_c`.
    pub fn volumetric_error(
        &self,
        state: &AxisState,
        temps_c: &[f64],
    ) -> Result<Vector3<f64>, DeformationError> {
        let d = self.thermal_deformation(temps_c)?;
        Ok(self.volumetric.volumetric_error(state, &d))
    }
}
