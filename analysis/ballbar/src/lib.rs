//! Ball-bar (circular test) diagnosis: the ISO 230-4 figures of a trace and the machine errors
//! behind it, from simulated or measured logs alike.
//!
//! - [`trace`]: the trace as an instrument records it, and its checks;
//! - [`iso230_4`]: circular deviation G, radial deviation F, bidirectional deviation, hysteresis
//!   H, least-squares and minimum-zone centres;
//! - [`signatures`]: the radial signature of each physical error, to first order;
//! - [`model`]: the error model and its weighted least-squares fit with confidences;
//! - [`take_up`]: the take-up of backlash after each reversal, in the fit and the residual;
//! - [`moving_mean`]: centred moving means from prefix sums;
//! - [`features`]: reversal spikes, per-side backlash, stick-slip, vibration, start transient and
//!   cyclic errors in the residual;
//! - [`diagnosis`]: one test diagnosed into ranked findings;
//! - [`kwon`]: Kwon's seven-step procedure analysed into one machine report;
//! - [`report`]: the diagnosis as text, Markdown and JSON;
//! - [`synthetic`]: traces from displacement laws, for tests and what-if studies.

pub mod diagnosis;
pub mod features;
pub mod iso230_4;
pub mod kwon;
pub mod model;
pub mod moving_mean;
pub mod report;
pub mod samples;
pub mod signatures;
pub mod synthetic;
pub mod take_up;
pub mod trace;

pub use diagnosis::{
    BIAS_DETAIL_PREFIX, Diagnosis, DiagnosisError, Finding, Options, SETTLING_RULE, Settling,
    diagnose,
};
pub use trace::{Plane, Sense, Trace, TraceError};
