//! The machine limits and periods the interpolator works with.

use super::InterpolatorError;

/// Kinematic limits of the machine, in SI units, as the interpolator respects them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Path speed of rapid (G0) moves, m/s (reduced further by the axis velocity limits).
    pub rapid_m_s: f64,
    /// Highest programmable feed, m/s; larger feeds are clamped to it.
    pub max_feed_m_s: f64,
    /// Largest tangential path acceleration `a_max`, m/s².
    pub path_accel_m_s2: f64,
    /// Largest path jerk `j_max`, m/s³; sets the jerk filter window `T_j = a_max / j_max`.
    pub path_jerk_m_s3: f64,
    /// Velocity limit of each axis X, Y, Z, m/s.
    pub axis_velocity_m_s: [f64; 3],
    /// Acceleration limit of each axis X, Y, Z, m/s² (tangential plus centripetal).
    pub axis_accel_m_s2: [f64; 3],
    /// Corner tolerance `δ`, m: the deviation of the virtual arc of the junction-deviation rule
    /// that limits the speed through a corner (the path itself is never rounded).
    pub corner_tolerance_m: f64,
}

impl Default for Limits {
    /// A mid-size vertical machining centre: 30 m/min rapid, 10 m/min feed, 2 m/s² and 20 m/s³
    /// on the path, 5 m/s² per axis, 10 µm corner tolerance.
    fn default() -> Self {
        Limits {
            rapid_m_s: 0.5,
            max_feed_m_s: 10.0 / 60.0,
            path_accel_m_s2: 2.0,
            path_jerk_m_s3: 20.0,
            axis_velocity_m_s: [0.5; 3],
            axis_accel_m_s2: [5.0; 3],
            corner_tolerance_m: 10e-6,
        }
    }
}

/// Everything the interpolator needs besides the program.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InterpolatorConfig {
    /// Kinematic limits.
    pub limits: Limits,
    /// Interpolation (IPO) period `T_ipo`, s; 1 ms by default.
    pub ipo_period_s: f64,
    /// Servo (position loop) period `T_s`, s; 125 µs by default. Must divide `T_ipo` exactly.
    pub servo_period_s: f64,
    /// Exact stop (G61/G9 on every block): every junction is passed at rest.
    pub exact_stop: bool,
}

impl Default for InterpolatorConfig {
    fn default() -> Self {
        InterpolatorConfig::new(Limits::default())
    }
}

/// Relative slack when checking that the servo period divides the IPO period.
const DIVISOR_TOLERANCE: f64 = 1e-9;

impl InterpolatorConfig {
    /// The given limits with `T_ipo` = 1 ms, `T_s` = 125 µs and continuous-path mode.
    pub fn new(limits: Limits) -> Self {
        InterpolatorConfig {
            limits,
            ipo_period_s: 1e-3,
            servo_period_s: 125e-6,
            exact_stop: false,
        }
    }

    /// Checks that every value is finite and > 0, that the servo period divides the IPO period
    /// into a whole number of servo ticks, and that the jerk window `a_max / j_max` lasts at
    /// least one IPO period.
    pub fn validate(&self) -> Result<(), InterpolatorError> {
        for (name, value) in self.named_values() {
            if !(value.is_finite() && value > 0.0) {
                return Err(InterpolatorError::InvalidSetting { name, value });
            }
        }
        self.servo_ticks_per_ipo()?;
        let window_s = self.limits.path_accel_m_s2 / self.limits.path_jerk_m_s3;
        if window_s < self.ipo_period_s * (1.0 - DIVISOR_TOLERANCE) {
            return Err(InterpolatorError::JerkWindowTooShort {
                window_s,
                ipo_period_s: self.ipo_period_s,
            });
        }
        Ok(())
    }

    /// Number of servo ticks in one IPO period, `T_ipo / T_s`.
    pub(crate) fn servo_ticks_per_ipo(&self) -> Result<usize, InterpolatorError> {
        let ratio = self.ipo_period_s / self.servo_period_s;
        let whole = ratio.round();
        let refused = InterpolatorError::ServoPeriodNotDivisor {
            servo_period_s: self.servo_period_s,
            ipo_period_s: self.ipo_period_s,
        };
        if !(1.0..=1e9).contains(&whole) || (ratio - whole).abs() > DIVISOR_TOLERANCE * whole {
            return Err(refused);
        }
        Ok(whole as usize)
    }

    /// Number of IPO periods `N` of the jerk filter: `a_max / j_max` rounded up, so that the
    /// filtered jerk `a_max / (N T_ipo)` stays at or below `j_max`.
    pub(crate) fn filter_taps(&self) -> usize {
        let periods = self.limits.path_accel_m_s2 / self.limits.path_jerk_m_s3 / self.ipo_period_s;
        (periods * (1.0 - DIVISOR_TOLERANCE)).ceil().max(1.0) as usize
    }

    fn named_values(&self) -> [(&'static str, f64); 13] {
        let l = &self.limits;
        [
            ("limits.rapid_m_s", l.rapid_m_s),
            ("limits.max_feed_m_s", l.max_feed_m_s),
            ("limits.path_accel_m_s2", l.path_accel_m_s2),
            ("limits.path_jerk_m_s3", l.path_jerk_m_s3),
            ("limits.axis_velocity_m_s[0] (X)", l.axis_velocity_m_s[0]),
            ("limits.axis_velocity_m_s[1] (Y)", l.axis_velocity_m_s[1]),
            ("limits.axis_velocity_m_s[2] (Z)", l.axis_velocity_m_s[2]),
            ("limits.axis_accel_m_s2[0] (X)", l.axis_accel_m_s2[0]),
            ("limits.axis_accel_m_s2[1] (Y)", l.axis_accel_m_s2[1]),
            ("limits.axis_accel_m_s2[2] (Z)", l.axis_accel_m_s2[2]),
            ("limits.corner_tolerance_m", l.corner_tolerance_m),
            ("ipo_period_s", self.ipo_period_s),
            ("servo_period_s", self.servo_period_s),
        ]
    }
}
