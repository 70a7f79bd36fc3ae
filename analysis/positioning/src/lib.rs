//! vmt-positioning: the analysis of linear positioning tests (ISO 230-2:2014), from a laser
//! interferometer's readings, measured or simulated.
//!
//! - [`run`]: the readings of one axis' test, checked against what the standard's figures need.
//! - [`evaluation`]: the ISO 230-2 figures (A, B, B̄, E, M, R per direction and bidirectional;
//!   the formulas are those of `vmt_model::iso230_2`, which the simulator's ground truth uses
//!   too), the linear trend of the mean deviations (a scale error, ppm) and the pitch-error
//!   compensation table a controller would take.
//! - [`report`]: the evaluation as text and Markdown (JSON through serde).
//!
//! Positions are in mm, deviations and figures in µm, as in the standard's reports.

pub mod evaluation;
pub mod report;
pub mod run;

pub use evaluation::{Evaluation, evaluate};
pub use run::{PositioningError, PositioningRun, Reading};
pub use vmt_model::iso230_2::{Approach, Iso230_2};
