//! vmt-gap: the sim-to-real gap. Measured runs are aligned with their simulations and the
//! residual (measured minus simulated) is localised: by angle, around axis reversals, by
//! direction, by harmonic order, by run and by time, with a whiteness test of what is left.
//!
//! - [`align`]: a measured trace beside the simulation of the same test, refused when the two
//!   are not the same test;
//! - [`localise`]: where the residual's energy sits, and where it concentrates;
//! - [`whiteness`]: the Ljung–Box test of the residual left after the structured parts.

pub mod align;
pub mod localise;
pub mod whiteness;

pub use align::{GapError, TracePair};
pub use localise::{Localisation, Options, Place};
