//! The withheld-physics cases of the bench: physics the simulator has and the candidate
//! library lacks, each with its right answer.

use crate::align::GapError;
use crate::bench::Physics;
use crate::model::ScenarioModel;
use vmt_ballbar::Plane;

/// The withheld-physics cases for the bench's test in `plane` on `model`.
pub fn cases(_model: &ScenarioModel, _plane: Plane) -> Result<Vec<Physics>, GapError> {
    Ok(Vec::new())
}
