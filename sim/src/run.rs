//! A run: what the instruments recorded, time-stamped, with the ground truth that produced it
//! and the scenario it came from.
//!
//! Channels are grouped in [`Stream`]s that share one clock. The simulator writes the stream
//! `servo` (logged at the log rate, 1 kHz by default) with the channels, for each axis
//! `a` in `x`, `y`, `z` (positions in the axis' coordinate: the commanded tool position relative
//! to the workpiece):
//! `command_a` (m), `position_a` (m, the carriage), `encoder_a` (m, quantised motor encoder),
//! `following_error_a` (m), `motor_force_a` (N), `motor_current_a` (A), `guide_friction_a` (N),
//! `screw_friction_a` (N), and `tool_x`, `tool_y`, `tool_z` (m, the actual tool point relative to
//! the workpiece through the error chain). Ball-bar traces are kept as [`BallbarTrace`]s, the
//! laser readings of a positioning test as a [`LaserRun`].
//! Times are simulation time in seconds from the start of the job; there is no wall clock in a
//! run, so the same scenario and seed give the same run.

use serde::Serialize;

pub use crate::laser::{LaserReading, LaserRun};

/// One recorded quantity.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Channel {
    /// Name, e.g. `following_error_x`.
    pub name: String,
    /// SI or engineering unit, e.g. `m`, `um`, `N`.
    pub unit: String,
    /// One value per sample of its stream.
    pub values: Vec<f64>,
}

/// Channels sampled at the same instants.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Stream {
    /// Name, e.g. `servo`, `ballbar`.
    pub name: String,
    /// What it is, for humans and for the files' documentation.
    pub description: String,
    /// Sample times, s.
    pub times_s: Vec<f64>,
    /// The channels.
    pub channels: Vec<Channel>,
}

impl Stream {
    /// The channel called `name`.
    pub fn channel(&self, name: &str) -> Option<&Channel> {
        self.channels.iter().find(|c| c.name == name)
    }
}

/// One ball-bar trace (one direction of one circular test), in the form ball-bar software uses.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BallbarTrace {
    /// Label, e.g. `XY 150 mm 1000 mm/min CCW`.
    pub label: String,
    /// `XY`, `ZX` or `YZ`.
    pub plane: String,
    /// `cw` or `ccw`.
    pub direction: String,
    /// Nominal bar length, mm.
    pub radius_mm: f64,
    /// Feed, mm/min.
    pub feed_mm_min: f64,
    /// Sample times, s.
    pub times_s: Vec<f64>,
    /// Angle of the bar in its plane from the plane's first axis, deg (unwrapped, increasing
    /// for CCW).
    pub angle_deg: Vec<f64>,
    /// Measured length minus nominal length, µm.
    pub deviation_um: Vec<f64>,
}

impl BallbarTrace {
    /// The trace with only its samples in `range` (none: its label, plane, direction, radius
    /// and feed).
    pub fn samples(&self, range: std::ops::Range<usize>) -> BallbarTrace {
        BallbarTrace {
            label: self.label.clone(),
            plane: self.plane.clone(),
            direction: self.direction.clone(),
            radius_mm: self.radius_mm,
            feed_mm_min: self.feed_mm_min,
            times_s: self.times_s[range.clone()].to_vec(),
            angle_deg: self.angle_deg[range.clone()].to_vec(),
            deviation_um: self.deviation_um[range].to_vec(),
        }
    }
}

/// What a viewer needs to draw the machine.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MachineSummary {
    /// Machine name.
    pub name: String,
    /// Topology, e.g. `WXYGZT` (see vmt-model's `Topology`).
    pub topology: String,
    /// Strokes of X, Y, Z as [min, max], m.
    pub strokes_m: [[f64; 2]; 3],
    /// Tool length, m.
    pub tool_length_m: f64,
}

/// A complete run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Run {
    /// Scenario name.
    pub scenario_name: String,
    /// The scenario text that made the run (TOML).
    pub scenario_toml: String,
    /// The seed of every random draw in the run.
    pub seed: u64,
    /// `reduced`, `multibody` or `compliant`.
    pub fidelity: String,
    /// The machine, for viewers.
    pub machine: MachineSummary,
    /// Recorded streams.
    pub streams: Vec<Stream>,
    /// Ball-bar traces, one per direction of each circular test.
    pub ballbar: Vec<BallbarTrace>,
    /// Laser readings of an ISO 230-2 positioning test, if the job is one.
    pub laser: Option<LaserRun>,
    /// Every injected parameter and derived figure, as a JSON object (the truth a diagnosis is
    /// scored against).
    pub ground_truth: serde_json::Value,
}

/// Where a run's records go while its job runs, so that a long job need not hold them all in
/// memory (a 17-minute job logged at 1 kHz has a million servo rows, about 220 MB) and what was
/// recorded is on its way to disk before the job ends.
pub trait LogSink {
    /// Once, before the first block: the run as it starts, with its streams' channels but no
    /// rows, its ball-bar traces with no samples, no laser readings and a `null` ground truth.
    fn start(&mut self, run: &Run) -> Result<(), String>;

    /// The records of the next stretch of the job; blocks follow each other in time (every
    /// record of a block is later than every record of the one before).
    fn block(&mut self, block: &LogBlock<'_>) -> Result<(), String>;
}

/// One block of a run's records for a [`LogSink`].
#[derive(Clone, Copy, Debug)]
pub struct LogBlock<'a> {
    /// The streams, each holding only this block's rows.
    pub streams: &'a [Stream],
    /// The ball-bar traces as recorded so far.
    pub ballbar: &'a [BallbarTrace],
    /// For each trace, the samples new in this block.
    pub new_samples: &'a [std::ops::Range<usize>],
}
