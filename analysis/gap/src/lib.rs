//! vmt-gap: the sim-to-real gap. Measured runs are aligned with their simulations and the
//! residual (measured minus simulated) is localised: by angle, around axis reversals, by
//! direction, by harmonic order, by run and by time, with a whiteness test of what is left.
//!
//! - [`align`]: a measured trace beside the simulation of the same test, refused when the two
//!   are not the same test;
//! - [`localise`]: where the residual's energy sits, and where it concentrates;
//! - [`peaks`]: the angles where it concentrates within a few degrees, as axis positions;
//! - [`axis_change`]: where along an axis its error changes over a stretch of the travel;
//! - [`whiteness`]: the Ljung–Box test of the residual left after the structured parts;
//! - [`effects`]: the library of candidate effects, as the scenario keys they change;
//! - [`model`]: a scenario re-simulated with parameter offsets (the forward model);
//! - [`split`]: which data fit the candidates, which choose between them, which judge them;
//! - [`select`]: which effects explain the gap (forward selection, plausible sizes only), how
//!   much they buy on data untouched by the fit and the choice, and which rivals would explain
//!   it as well;
//! - [`discriminate`]: the test that tells equally good explanations apart;
//! - [`bench`](mod@bench): the withheld-effect check: effects switched off in the model, and
//!   physics the library lacks switched on in the measured machine;
//! - [`spectrum`]: third-octave band levels of accelerometer signals;
//! - [`vibration`]: the gap of a milling model against accelerometer logs, by band;
//! - [`vibration_bench`]: the withheld-effect check of the vibration gap.

pub mod align;
pub mod axis_change;
pub mod bench;
pub mod discriminate;
pub mod effects;
pub mod localise;
pub mod model;
pub mod peaks;
pub mod physics;
pub mod select;
pub mod spectrum;
pub mod split;
pub mod vibration;
pub mod vibration_bench;
pub mod whiteness;

pub use align::{GapError, TracePair};
pub use localise::{Localisation, Options, Place};
