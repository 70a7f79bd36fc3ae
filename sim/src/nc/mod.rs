//! NC programs: G-code parsing into SI motion blocks, and generators of test programs.
//!
//! - [`program`]: the program as later stages see it — motion blocks in SI units and absolute
//!   coordinates (m, m/s, s), each with the line and column it came from.
//! - [`parse`](mod@parse): G-code text to a [`Program`] (G0–G4, G17–G21, G90/G91, F, S,
//!   M3/M4/M5, M2/M30), with located errors ([`NcError`]) and no panics on any input.
//! - [`ballbar`]: circular test programs for a ball bar — ISO 230-4 circles in any plane, with
//!   feed-in, overshoot and partial arcs, and Kwon's seven-step procedure.

pub mod ballbar;
pub mod parse;
pub mod program;

pub use ballbar::{
    CircularTest, InvalidTest, KwonStep, MarkedCircle, kwon_seven_step, kwon_steps, marked_circles,
};
pub use parse::{NcError, parse};
pub use program::{ArcDirection, Block, Motion, Plane, Program, SourceSpan, Spindle};
