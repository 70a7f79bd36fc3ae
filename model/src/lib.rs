//! vmt-model: the physics of a three-axis machining centre as pure functions and small state
//! machines. No files, no clocks, no global state.
//!
//! - [`axis`]: the axes and their direction states.
//! - [`cutting`]: milling: the end mill, cutting-force coefficients, the tool point's modes.
//! - [`drive`]: feed drives: cascaded servo control, ball screw with backlash, LuGre friction.
//! - [`geometric`]: the 21 direction-dependent geometric errors of ISO 230-1.
//! - [`iso230_2`]: the positioning figures of ISO 230-2 (A, B, E, M, R), shared by the
//!   simulator's ground truth and the analysis of laser runs.
//! - [`machine`]: a whole machine: axes, error chain, thermal model.
//! - [`kinematics`]: the 24 topologies and the exact homogeneous-transform chain that gives the
//!   volumetric error.
//! - [`structure`]: the carriages as rigid bodies on their compliant guide blocks.
//! - [`thermal`]: the lumped thermal network (temperatures in time).
//! - [`thermal_deformation`]: from temperatures to thermal link and joint deformations.
//!
//! Units are SI (m, rad, s, K, W), conversions at the edges, except where a name carries its
//! unit: [`iso230_2`] works in mm and µm as the standard does, temperatures are in °C (the
//! thermal network and the machine's thermal evaluations) and spindle speeds in rpm.

pub mod axis;
pub mod cutting;
pub mod drive;
pub mod geometric;
pub mod iso230_2;
pub mod kinematics;
pub mod machine;
pub mod structure;
pub mod thermal;
pub mod thermal_deformation;

pub use axis::{Axis, Direction, DirectionTracker};
