//! Feed drives: servo control, ball screws with backlash, LuGre friction, the two-mass axis,
//! and the optional physics of [`effects`]: motor cogging and torque ripple, encoder
//! interpolation error, a preloaded double nut, the GMS friction law.

pub mod axis;
pub mod effects;
pub mod encoder;
mod exp;
pub mod friction;
pub mod gms;
pub mod motor;
pub mod nut;
pub mod servo;
pub mod transmission;

pub use axis::{CarriageState, Drive, DriveParams, Feedback, ReducedAxis};
pub use effects::DriveEffects;
pub use friction::{LuGre, LuGreParams, LuGreStep};
pub use servo::{AxisCommand, ServoController, ServoParams};
pub use transmission::ScrewParams;
