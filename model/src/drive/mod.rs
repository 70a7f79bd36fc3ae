//! Feed drives: servo control, ball screws with backlash, LuGre friction, the two-mass axis.

pub mod axis;
mod exp;
pub mod friction;
pub mod servo;
pub mod transmission;

pub use axis::{CarriageState, Drive, DriveParams, Feedback, ReducedAxis};
pub use friction::{LuGre, LuGreParams, LuGreStep};
pub use servo::{AxisCommand, ServoController, ServoParams};
pub use transmission::ScrewParams;
