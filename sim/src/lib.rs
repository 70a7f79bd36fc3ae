//! vmt-sim: executes a job in time. NC program -> interpolator -> controller -> plant -> error
//! chain -> instruments -> a run (channels and ground truth).
//!
//! - [`nc`]: NC programs: G-code parsing into SI motion blocks, and generators of test programs
//!   (ISO 230-4 circular tests, Kwon's seven-step ball-bar procedure).
//! - [`interpolator`]: path speed planning with acceleration and jerk limits, exact arcs, the
//!   interpolation period and fine interpolation down to the servo rate.
//! - [`plant`]: the moving assemblies and their drives, reduced or rapier3d multibody.
//! - [`simulate`]: runs a job through interpolator, controllers, plant, error chain and
//!   instruments ([`ballbar`], [`laser`]: the ISO 230-2 positioning test); [`truth`] writes its
//!   ground truth; [`replay`] reads the ball bar of a run again on a machine with other
//!   geometric errors or another bar set-up, without simulating the motion again.
//! - [`milling`]: time-domain milling with regenerative chatter: forces, tool modes, surface
//!   memory, spindle-housing accelerometers, the machined wall and the chatter truth;
//!   [`machining`] drives it from an NC program through the controller and feed drives, with a
//!   supervisor (chatter detection and compensation) in the loop.
//! - [`run`]: what a simulation produces: time-stamped streams, ball-bar traces, ground truth.

pub mod ballbar;
pub mod interpolator;
pub mod laser;
pub mod machining;
pub mod milling;
pub mod nc;
pub mod plant;
pub mod replay;
pub mod run;
pub mod simulate;
pub mod truth;
