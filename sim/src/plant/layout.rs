//! From the topology and the moving masses to each carriage's direction, own mass and gravity.

use super::GRAVITY_M_S2;
use thiserror::Error;
use vmt_model::Axis;
use vmt_model::kinematics::{Element, Side, Topology};

/// How one axis sits in the machine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisLayout {
    /// The axis.
    pub axis: Axis,
    /// +1 if the carriage moves the tool (moves along +q), -1 if it moves the workpiece.
    pub sign: f64,
    /// Mass of everything this axis moves (carriage and what it carries), kg.
    pub moving_mass_kg: f64,
    /// Mass of the carriage alone, kg.
    pub link_mass_kg: f64,
    /// Gravity on the moving mass along +q, N.
    pub gravity_n: f64,
    /// The axis whose carriage carries this one (towards the ground), if any.
    pub parent: Option<Axis>,
}

/// A machine that cannot be built as a plant.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum PlantError {
    /// The moving masses do not make a physical chain.
    #[error(
        "axis {outer} moves {outer_kg} kg but is carried by axis {inner}, which moves only {inner_kg} kg; \
         an axis' moving mass includes everything it carries, so it must be larger"
    )]
    Masses {
        /// The carrying axis.
        inner: Axis,
        /// Its moving mass, kg.
        inner_kg: f64,
        /// The carried axis.
        outer: Axis,
        /// Its moving mass, kg.
        outer_kg: f64,
    },
    /// rapier refused a joint of the multibody.
    #[error("the multibody refused the joint of axis {0}")]
    Joint(Axis),
    /// A carriage of the structure is no rigid body on guide blocks.
    #[error(transparent)]
    Structure(#[from] vmt_model::structure::StructureError),
    /// The compliant plant needs the carriages' description.
    #[error(
        "the compliant plant needs each axis' carriage: [machine.axes.<axis>.carriage] with its box, nut and guide blocks"
    )]
    NoStructure,
    /// The plant step is too coarse for the stiffest mode of the carriages on their blocks.
    #[error(
        "a plant step of {step_us:.2} µs is too coarse for the stiffest mode of the carriages on their guide blocks ({mode_hz:.0} Hz, mostly the {axis} carriage): up to {accepted_us:.2} µs is accepted, where semi-implicit Euler keeps the mode's frequency within 5 %; raise plant_substeps (scenario key controller.plant_substeps)"
    )]
    StepTooCoarse {
        /// The carriage moving most in the mode.
        axis: Axis,
        /// Its frequency, Hz.
        mode_hz: f64,
        /// The step, µs.
        step_us: f64,
        /// The largest accepted step, µs.
        accepted_us: f64,
    },
}

/// The layout of the three axes of `topology` with moving masses `moving_kg` (X, Y, Z).
pub fn layout(topology: &Topology, moving_kg: [f64; 3]) -> Result<[AxisLayout; 3], PlantError> {
    let chain = topology.chain();
    let g = topology.ground_index();
    // Each side's axes ordered from the ground outwards.
    let tool_side: Vec<Axis> = chain[g + 1..5].iter().filter_map(axis_of).collect();
    let work_side: Vec<Axis> = chain[1..g].iter().rev().filter_map(axis_of).collect();
    let mut out = Axis::ALL.map(|axis| AxisLayout {
        axis,
        sign: match topology.axis_side(axis) {
            Side::Tool => 1.0,
            Side::Workpiece => -1.0,
        },
        moving_mass_kg: moving_kg[axis.index()],
        link_mass_kg: moving_kg[axis.index()],
        gravity_n: 0.0,
        parent: None,
    });
    for side in [&tool_side, &work_side] {
        for pair in side.windows(2) {
            let (inner, outer) = (pair[0], pair[1]);
            let (mi, mo) = (moving_kg[inner.index()], moving_kg[outer.index()]);
            if mi <= mo {
                return Err(PlantError::Masses {
                    inner,
                    inner_kg: mi,
                    outer,
                    outer_kg: mo,
                });
            }
            out[inner.index()].link_mass_kg = mi - mo;
            out[outer.index()].parent = Some(inner);
        }
    }
    let z = &mut out[Axis::Z.index()];
    z.gravity_n = -z.sign * z.moving_mass_kg * GRAVITY_M_S2;
    Ok(out)
}

fn axis_of(e: &Element) -> Option<Axis> {
    match e {
        Element::Axis(a) => Some(*a),
        _ => None,
    }
}
