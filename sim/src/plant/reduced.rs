//! The reduced plant: three independent two-mass drives with lumped carriages.

use super::{AxisLayout, Plant};
use vmt_model::drive::{AxisCommand, CarriageState, Drive, ReducedAxis};

/// Lumped per-axis ODEs (see the module docs of `vmt_model::drive::axis`).
#[derive(Clone, Debug)]
pub struct ReducedPlant {
    axes: [ReducedAxis; 3],
    gravity_n: [f64; 3],
    /// Process force along each axis (axis coordinates), N.
    process_n: [f64; 3],
}

impl ReducedPlant {
    /// A plant at rest, each carriage where its drive's motor is (centred in the gap), the
    /// drives built for the carriages' moving masses.
    pub fn new(drives: [Drive; 3], layout: &[AxisLayout; 3]) -> Self {
        let axes = drives.map(|d| ReducedAxis {
            drive: d,
            carriage: CarriageState {
                position_m: d.motor_position_m,
                ..Default::default()
            },
        });
        Self {
            axes,
            gravity_n: layout.map(|l| l.gravity_n),
            process_n: [0.0; 3],
        }
    }
}

impl Plant for ReducedPlant {
    fn control(&mut self, commands: &[AxisCommand; 3], period_s: f64) {
        for (a, c) in self.axes.iter_mut().zip(commands) {
            a.control(c, period_s);
        }
    }

    fn step(&mut self, h: f64) {
        let external = std::array::from_fn(|i| self.gravity_n[i] + self.process_n[i]);
        ReducedAxis::step_all(&mut self.axes, h, external);
    }

    fn drive(&self, i: usize) -> &Drive {
        &self.axes[i].drive
    }

    fn carriages(&self) -> [CarriageState; 3] {
        std::array::from_fn(|i| self.axes[i].carriage)
    }

    fn set_tool_force(&mut self, force_n: nalgebra::Vector3<f64>) {
        self.process_n = [force_n.x, force_n.y, force_n.z];
    }
}
