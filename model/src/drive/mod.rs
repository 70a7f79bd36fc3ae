//! Feed drives: servo control, ball screws with backlash, LuGre friction, the two-mass axis.

pub mod axis;
pub mod friction;
pub mod servo;
pub mod transmission;

pub use axis::{CarriageState, Drive, DriveParams, Feedback, ReducedAxis, carriage_force};
pub use friction::{LuGre, LuGreParams};
pub use servo::{AxisCommand, ServoController, ServoParams};
pub use transmission::ScrewParams;
