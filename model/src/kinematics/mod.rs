//! Kinematics of the three-axis machine: topologies, rigid transforms and the error chain.

pub mod chain;
pub mod htm;
pub mod topology;

pub use chain::{AxisState, Deflection, Kinematics, VolumetricEvaluator, VolumetricModel};
pub use htm::{Htm, rotation_matrix};
pub use topology::{Element, Side, Topology, TopologyError};
