//! What can go wrong when a configuration or a program is handed to the interpolator.

use crate::short;

/// Why a configuration or a program was refused. Program errors name the block by the line (and
/// column) of its source, and give the offending value in SI units.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum InterpolatorError {
    /// A configuration value is not a finite number greater than zero.
    #[error(
        "interpolator setting `{name}` = {} is not valid: it must be a finite number > 0",
        short(*.value)
    )]
    InvalidSetting {
        /// The field, e.g. `limits.path_jerk_m_s3`.
        name: &'static str,
        /// The value given (SI unit in the name).
        value: f64,
    },
    /// The servo period does not divide the interpolation period into whole servo ticks.
    #[error(
        "the servo period {} s does not divide the interpolation period {} s into a whole \
         number of servo ticks (e.g. 125 µs into 1 ms = 8 ticks)",
        short(*.servo_period_s),
        short(*.ipo_period_s)
    )]
    ServoPeriodNotDivisor {
        /// Servo period, s.
        servo_period_s: f64,
        /// Interpolation (IPO) period, s.
        ipo_period_s: f64,
    },
    /// The jerk filter window `a_max / j_max` is shorter than one interpolation period.
    #[error(
        "the jerk filter window path_accel / path_jerk = {} s is shorter than one \
         interpolation period ({} s): lower `path_jerk_m_s3` or raise `path_accel_m_s2`",
        short(*.window_s),
        short(*.ipo_period_s)
    )]
    JerkWindowTooShort {
        /// `a_max / j_max`, s.
        window_s: f64,
        /// Interpolation period, s.
        ipo_period_s: f64,
    },
    /// A block carries a value that is not usable (NaN, infinite, zero or negative feed, negative
    /// dwell, a length too large to represent).
    #[error(
        "block at line {line}, column {column}: {what} = {} is not valid: {reason}",
        short(*.value)
    )]
    InvalidBlock {
        /// Source line, 1-based.
        line: usize,
        /// Source column, 1-based.
        column: usize,
        /// What the value is, with its unit, e.g. `feed (m/s)`.
        what: &'static str,
        /// The value given.
        value: f64,
        /// What would be accepted.
        reason: &'static str,
    },
    /// The arc centre coincides with the start point.
    #[error("block at line {line}, column {column}: the arc centre coincides with its start point")]
    ArcRadiusZero {
        /// Source line, 1-based.
        line: usize,
        /// Source column, 1-based.
        column: usize,
    },
    /// The end point of an arc is not on the circle through the start point.
    #[error(
        "block at line {line}, column {column}: the arc starts {} mm from its centre but ends \
         {} mm from it; the difference may be at most {} mm",
        short(.start_radius_m * 1e3),
        short(.end_radius_m * 1e3),
        short(.tolerance_m * 1e3)
    )]
    ArcRadiusMismatch {
        /// Source line, 1-based.
        line: usize,
        /// Source column, 1-based.
        column: usize,
        /// Distance of the start point from the centre in the arc plane, m.
        start_radius_m: f64,
        /// Distance of the end point from the centre in the arc plane, m.
        end_radius_m: f64,
        /// The accepted difference, m.
        tolerance_m: f64,
    },
    /// The program would need more interpolation samples than the interpolator holds.
    #[error(
        "the program lasts about {duration_s:.0} s by the block at line {line}, longer than \
         the {max_duration_s:.0} s the interpolator holds at this interpolation period"
    )]
    ProgramTooLong {
        /// Source line of the block at which the limit is passed, 1-based.
        line: usize,
        /// The planned duration, s.
        duration_s: f64,
        /// The longest accepted duration, s.
        max_duration_s: f64,
    },
    /// The feed planner could not meet the jerk-filter condition (a bug, reported rather than
    /// hidden).
    #[error(
        "internal error: the feed profile of the motion starting at line {line} could not be \
         shaped for the jerk filter"
    )]
    Planning {
        /// Source line of the first block of the motion, 1-based.
        line: usize,
    },
}

impl InterpolatorError {
    /// The source line of the block a program error is about; `None` for a configuration error.
    pub fn line(&self) -> Option<usize> {
        match self {
            Self::InvalidBlock { line, .. }
            | Self::ArcRadiusZero { line, .. }
            | Self::ArcRadiusMismatch { line, .. }
            | Self::ProgramTooLong { line, .. }
            | Self::Planning { line } => Some(*line),
            Self::InvalidSetting { .. }
            | Self::ServoPeriodNotDivisor { .. }
            | Self::JerkWindowTooShort { .. } => None,
        }
    }
}
