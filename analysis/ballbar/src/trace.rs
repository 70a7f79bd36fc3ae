//! A ball-bar trace as an instrument records it, and the checks it must pass before analysis.
//!
//! A trace is one direction of one circular test: for each sample the bar's angle in the test
//! plane (degrees from the plane's first axis, unwrapped, increasing for a counter-clockwise
//! run as seen from the plane's normal) and the bar's length minus its nominal length (µm,
//! positive outward), optionally the sample time (s).

use serde::Serialize;
use std::fmt;
use thiserror::Error;

/// The test plane and its axes `(p, q)`: the angle is measured from `p` towards `q`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum Plane {
    /// X then Y (G17).
    Xy,
    /// Z then X (G18).
    Zx,
    /// Y then Z (G19).
    Yz,
}

impl Plane {
    /// The three planes.
    pub const ALL: [Plane; 3] = [Plane::Xy, Plane::Zx, Plane::Yz];

    /// `XY`, `ZX` or `YZ`.
    pub const fn name(self) -> &'static str {
        match self {
            Plane::Xy => "XY",
            Plane::Zx => "ZX",
            Plane::Yz => "YZ",
        }
    }

    /// The plane's first and second axis letters, `(p, q)`.
    pub const fn axes(self) -> (char, char) {
        match self {
            Plane::Xy => ('X', 'Y'),
            Plane::Zx => ('Z', 'X'),
            Plane::Yz => ('Y', 'Z'),
        }
    }

    /// The letter of the axis normal to the plane.
    pub const fn normal(self) -> char {
        match self {
            Plane::Xy => 'Z',
            Plane::Zx => 'Y',
            Plane::Yz => 'X',
        }
    }

    /// The plane named `s` (`XY`, `ZX`/`XZ`, `YZ`/`ZY`, any case).
    pub fn parse(s: &str) -> Option<Plane> {
        match s.to_ascii_uppercase().as_str() {
            "XY" | "YX" => Some(Plane::Xy),
            "ZX" | "XZ" => Some(Plane::Zx),
            "YZ" | "ZY" => Some(Plane::Yz),
            _ => None,
        }
    }
}

impl fmt::Display for Plane {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The sense of travel round the circle.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum Sense {
    /// Clockwise: the angle decreases.
    Cw,
    /// Counter-clockwise: the angle increases.
    Ccw,
}

impl Sense {
    /// +1 for CCW, −1 for CW: the sign of dθ/dt.
    pub const fn sign(self) -> f64 {
        match self {
            Sense::Cw => -1.0,
            Sense::Ccw => 1.0,
        }
    }

    /// `cw` or `ccw`.
    pub const fn name(self) -> &'static str {
        match self {
            Sense::Cw => "cw",
            Sense::Ccw => "ccw",
        }
    }

    /// `cw` or `ccw` (any case).
    pub fn parse(s: &str) -> Option<Sense> {
        match s.to_ascii_lowercase().as_str() {
            "cw" => Some(Sense::Cw),
            "ccw" => Some(Sense::Ccw),
            _ => None,
        }
    }
}

/// One ball-bar trace.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Trace {
    /// Label for reports.
    pub label: String,
    /// Test plane.
    pub plane: Plane,
    /// Sense of travel.
    pub sense: Sense,
    /// Nominal radius (bar length), mm.
    pub radius_mm: f64,
    /// Programmed feed, mm/min.
    pub feed_mm_min: f64,
    /// Unwrapped angle of each sample, deg.
    pub angle_deg: Vec<f64>,
    /// Measured minus nominal length, µm.
    pub deviation_um: Vec<f64>,
    /// Sample times, s, when the instrument recorded them.
    pub time_s: Option<Vec<f64>>,
}

/// Why a trace cannot be analysed.
#[derive(Debug, Error, PartialEq)]
pub enum TraceError {
    /// Too few samples.
    #[error("{label}: {n} samples; at least {min} are needed")]
    TooShort {
        /// Trace label.
        label: String,
        /// Samples given.
        n: usize,
        /// Samples needed.
        min: usize,
    },
    /// Columns of different lengths.
    #[error("{label}: {what} has {got} values but the trace has {expected} samples")]
    Length {
        /// Trace label.
        label: String,
        /// The column.
        what: &'static str,
        /// Its length.
        got: usize,
        /// The angle column's length.
        expected: usize,
    },
    /// A NaN or infinite value.
    #[error("{label}: sample {index}: {what} is {value}; every value must be a finite number")]
    NotFinite {
        /// Trace label.
        label: String,
        /// Sample index (0-based).
        index: usize,
        /// The column.
        what: &'static str,
        /// The value.
        value: f64,
    },
    /// The angle does not move in the trace's sense.
    #[error(
        "{label}: sample {index}: the angle goes from {from} to {to} deg, against the {sense} sense of the trace (angles must increase for CCW and decrease for CW, to within 0.05 deg)"
    )]
    Backwards {
        /// Trace label.
        label: String,
        /// Sample index (0-based).
        index: usize,
        /// Angle before, deg.
        from: f64,
        /// Angle at `index`, deg.
        to: f64,
        /// `CW` or `CCW`.
        sense: String,
    },
    /// A gap in the angle larger than allowed.
    #[error(
        "{label}: a gap of {gap:.2} deg between samples {index} and {next} (at {at:.2} deg); the largest accepted gap is {max:.2} deg"
    )]
    Gap {
        /// Trace label.
        label: String,
        /// Sample before the gap.
        index: usize,
        /// Sample after the gap.
        next: usize,
        /// Angle at the start of the gap, deg.
        at: f64,
        /// The gap, deg.
        gap: f64,
        /// Largest gap accepted, deg.
        max: f64,
    },
    /// Times that do not increase.
    #[error("{label}: sample {index}: time {to} s does not follow {from} s (times must increase)")]
    TimeBackwards {
        /// Trace label.
        label: String,
        /// Sample index.
        index: usize,
        /// Time before, s.
        from: f64,
        /// Time at `index`, s.
        to: f64,
    },
    /// The angles run against the trace's direction label over the whole run.
    #[error(
        "{label}: the angle runs from {from} to {to} deg, the other way from the {sense} the trace is labelled (angles must increase for CCW and decrease for CW); check the direction labels"
    )]
    WrongSense {
        /// Trace label.
        label: String,
        /// First angle, deg.
        from: f64,
        /// Last angle, deg.
        to: f64,
        /// `CW` or `CCW`.
        sense: String,
    },
    /// Too short an arc for a circular test.
    #[error(
        "{label}: the trace sweeps {sweep:.2} deg; a circular test needs a data arc of at least 90 deg, {min} deg of samples (below it the centre and radius of the circle cannot be told apart)"
    )]
    ShortArc {
        /// Trace label.
        label: String,
        /// Angle swept, deg.
        sweep: f64,
        /// Least accepted, deg.
        min: f64,
    },
    /// A deviation beyond any ball bar's measuring range.
    #[error(
        "{label}: sample {index}: deviation_um is {value}; a ball bar measures within ±{max} µm (check the unit: µm)"
    )]
    Deviation {
        /// Trace label.
        label: String,
        /// Sample index (0-based).
        index: usize,
        /// The value, µm.
        value: f64,
        /// Largest magnitude accepted, µm.
        max: f64,
    },
    /// The time column's speed along the arc disagrees with the stated feed.
    #[error(
        "{label}: the times give {implied:.1} mm/min along a circle of the bar's {radius_mm} mm, against the stated feed of {feed} mm/min (from {low:.0} % of it, or up to {MAX_INCLINED_RATIO} times it for a bar inclined out of the plane, is accepted); check the feed, the radius and the unit of time_s (s)",
        low = 100.0 / (1.0 + FEED_TOLERANCE)
    )]
    FeedMismatch {
        /// Trace label.
        label: String,
        /// Feed from the angles and times, mm/min.
        implied: f64,
        /// The stated radius, mm.
        radius_mm: f64,
        /// The stated feed, mm/min.
        feed: f64,
    },
    /// A plane or direction name that is not known.
    #[error("{label}: {what} `{value}` is not known; {accepted}")]
    Name {
        /// Trace label.
        label: String,
        /// `plane` or `direction`.
        what: &'static str,
        /// The name given.
        value: String,
        /// What is accepted.
        accepted: &'static str,
    },
    /// A non-physical set-up value.
    #[error("{label}: {what} = {value}; {accepted}")]
    Setup {
        /// Trace label.
        label: String,
        /// The quantity.
        what: &'static str,
        /// Its value.
        value: f64,
        /// What is accepted.
        accepted: &'static str,
    },
}

impl TraceError {
    /// The index (0-based) of the sample at fault, where one is: the first of a NaN, a step
    /// back or a time out of order, the sample after a gap.
    pub fn sample(&self) -> Option<usize> {
        match self {
            Self::NotFinite { index, .. }
            | Self::Deviation { index, .. }
            | Self::Backwards { index, .. }
            | Self::TimeBackwards { index, .. } => Some(*index),
            Self::Gap { next, .. } => Some(*next),
            _ => None,
        }
    }
}

/// The largest angular gap between samples accepted by [`Trace::validate`], deg.
pub const MAX_GAP_DEG: f64 = 2.0;
/// How far (deg) the angle may step back against the trace's sense: a real tool point jitters
/// about the path by its following error and noise, most at the start of a run; a larger step
/// back is a broken log.
pub const MAX_BACKWARD_DEG: f64 = 0.05;
/// The fewest samples a trace may have.
pub const MIN_SAMPLES: usize = 16;
/// The shortest arc of samples accepted, deg: a 90° data arc, the shortest on which the
/// diagnosis fits scale and squareness (see [`crate::model::Terms`]) and the shortest a test
/// program may have, less up to a gap between samples at its ends; on less, the circle's
/// centre and radius are nearly collinear unknowns (a 10° arc put the centre 3.5 mm off).
pub const MIN_SWEEP_DEG: f64 = 90.0 - MAX_GAP_DEG;
/// The largest deviation accepted, µm: a ball bar's transducer travels about ±1 mm, so a larger
/// value is a unit slip (mm as µm) or a broken log.
pub const MAX_DEVIATION_UM: f64 = 2000.0;
/// How far the speed along a circle of the bar's length from the time column may fall below
/// the stated feed (relative): a feed override or a mistyped feed or radius beyond it would
/// scale every figure in ms.
pub const FEED_TOLERANCE: f64 = 0.1;
/// How far it may exceed the feed (a factor): a bar inclined out of the plane (Kwon's step 4)
/// runs a circle smaller than its length, down to a tenth of it here; beyond, the feed or the
/// radius is mistyped (a feed of 10 for 1000, a radius in µm).
pub const MAX_INCLINED_RATIO: f64 = 10.0;

impl Trace {
    /// A trace from its columns, the plane and direction given by name (`XY`, `ZX`, `YZ`;
    /// `cw`, `ccw`), validated.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        label: &str,
        plane: &str,
        direction: &str,
        radius_mm: f64,
        feed_mm_min: f64,
        angle_deg: Vec<f64>,
        deviation_um: Vec<f64>,
        time_s: Option<Vec<f64>>,
    ) -> Result<Self, TraceError> {
        let name = |what, value: &str, accepted| TraceError::Name {
            label: label.into(),
            what,
            value: value.into(),
            accepted,
        };
        let t = Trace {
            label: label.into(),
            plane: Plane::parse(plane).ok_or_else(|| name("plane", plane, "XY, ZX or YZ"))?,
            sense: Sense::parse(direction)
                .ok_or_else(|| name("direction", direction, "cw or ccw"))?,
            radius_mm,
            feed_mm_min,
            angle_deg,
            deviation_um,
            time_s,
        };
        t.validate()?;
        Ok(t)
    }

    /// Angle swept from the first to the last sample, deg (positive).
    pub fn sweep_deg(&self) -> f64 {
        match (self.angle_deg.first(), self.angle_deg.last()) {
            (Some(a), Some(b)) => (b - a).abs(),
            _ => 0.0,
        }
    }

    /// The trace of the samples `range` only (their times too).
    pub fn samples(&self, range: std::ops::Range<usize>) -> Trace {
        Trace {
            label: self.label.clone(),
            plane: self.plane,
            sense: self.sense,
            radius_mm: self.radius_mm,
            feed_mm_min: self.feed_mm_min,
            angle_deg: self.angle_deg[range.clone()].to_vec(),
            deviation_um: self.deviation_um[range.clone()].to_vec(),
            time_s: self.time_s.as_ref().map(|t| t[range].to_vec()),
        }
    }

    /// With times, the speed along a circle of the bar's length, mm/min: radius × angle swept
    /// over the time taken (the feed, for a bar in the plane of its circle).
    pub fn timed_speed_mm_min(&self) -> Option<f64> {
        let t = self.time_s.as_ref()?;
        let duration_min = (t[t.len() - 1] - t[0]) / 60.0;
        Some(self.radius_mm * self.sweep_deg().to_radians() / duration_min)
    }

    /// Feed as µm per ms (the unit in which a lag in ms gives µm).
    pub fn feed_um_per_ms(&self) -> f64 {
        self.feed_mm_min / 60.0
    }

    /// Checks lengths, finiteness, monotonic angles and times, gaps and the set-up values.
    pub fn validate(&self) -> Result<(), TraceError> {
        let label = || self.label.clone();
        for (what, value, accepted) in [
            (
                "radius_mm",
                self.radius_mm,
                "the bar length must be a positive number of mm",
            ),
            (
                "feed_mm_min",
                self.feed_mm_min,
                "the feed must be a positive number of mm/min",
            ),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(TraceError::Setup {
                    label: label(),
                    what,
                    value,
                    accepted,
                });
            }
        }
        let n = self.angle_deg.len();
        if n < MIN_SAMPLES {
            return Err(TraceError::TooShort {
                label: label(),
                n,
                min: MIN_SAMPLES,
            });
        }
        if self.columns_ok() {
            self.check_sweep()?;
            return self.check_feed();
        }
        let mut columns: Vec<(&'static str, &[f64])> = vec![
            ("angle_deg", &self.angle_deg),
            ("deviation_um", &self.deviation_um),
        ];
        if let Some(t) = &self.time_s {
            columns.push(("time_s", t));
        }
        for (what, values) in &columns {
            if values.len() != n {
                return Err(TraceError::Length {
                    label: label(),
                    what,
                    got: values.len(),
                    expected: n,
                });
            }
            if let Some((index, &value)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
                return Err(TraceError::NotFinite {
                    label: label(),
                    index,
                    what,
                    value,
                });
            }
        }
        if let Some((index, &value)) =
            (self.deviation_um.iter().enumerate()).find(|(_, v)| v.abs() > MAX_DEVIATION_UM)
        {
            return Err(TraceError::Deviation {
                label: label(),
                index,
                value,
                max: MAX_DEVIATION_UM,
            });
        }
        self.check_angles()?;
        self.check_sweep()?;
        if let Some(t) = &self.time_s
            && let Some(i) = (1..n).find(|&i| t[i] <= t[i - 1])
        {
            return Err(TraceError::TimeBackwards {
                label: label(),
                index: i,
                from: t[i - 1],
                to: t[i],
            });
        }
        self.check_feed()
    }

    /// Whether the columns pass every check of [`Trace::validate`] after the set-up values,
    /// found by counting the offending samples in loops without branches (which the compiler
    /// runs on vectors); the checks that find the first offending sample run only when this
    /// fails.
    fn columns_ok(&self) -> bool {
        let n = self.angle_deg.len();
        if self.deviation_um.len() != n || self.time_s.as_ref().is_some_and(|t| t.len() != n) {
            return false;
        }
        let s = self.sense.sign();
        let (a, d) = (&self.angle_deg[..n], &self.deviation_um[..n]);
        let mut bad = u64::from(!(a[0].is_finite() & (d[0].abs() <= MAX_DEVIATION_UM)));
        for i in 1..n {
            let step = (a[i] - a[i - 1]) * s;
            // NaN fails every comparison; an infinite angle makes a NaN or infinite step.
            let ok = (-MAX_BACKWARD_DEG..=MAX_GAP_DEG).contains(&step)
                & (d[i].abs() <= MAX_DEVIATION_UM);
            bad += u64::from(!ok);
        }
        if let Some(t) = &self.time_s {
            let t = &t[..n];
            bad += u64::from(!(t[0].is_finite() & t[n - 1].is_finite()));
            for i in 1..n {
                let later = t[i] > t[i - 1];
                bad += u64::from(!later);
            }
        }
        bad == 0
    }

    /// The run as a whole goes the labelled way, over at least [`MIN_SWEEP_DEG`] (sample to
    /// sample, [`Trace::check_angles`] lets small steps back through).
    fn check_sweep(&self) -> Result<(), TraceError> {
        let (from, to) = (self.angle_deg[0], self.angle_deg[self.angle_deg.len() - 1]);
        let sweep = (to - from) * self.sense.sign();
        if sweep < 0.0 {
            return Err(TraceError::WrongSense {
                label: self.label.clone(),
                from,
                to,
                sense: self.sense.name().to_uppercase(),
            });
        }
        if sweep < MIN_SWEEP_DEG {
            return Err(TraceError::ShortArc {
                label: self.label.clone(),
                sweep,
                min: MIN_SWEEP_DEG,
            });
        }
        Ok(())
    }

    /// With times, the speed along a circle of the bar's length (length × angle swept / time)
    /// is the stated feed: not below it by more than [`FEED_TOLERANCE`], and not above it by
    /// more than [`MAX_INCLINED_RATIO`] (an inclined bar's circle is smaller than its length).
    fn check_feed(&self) -> Result<(), TraceError> {
        let Some(implied) = self.timed_speed_mm_min() else {
            return Ok(());
        };
        let ratio = implied / self.feed_mm_min;
        if !(1.0 / (1.0 + FEED_TOLERANCE)..=MAX_INCLINED_RATIO).contains(&ratio) {
            return Err(TraceError::FeedMismatch {
                label: self.label.clone(),
                implied,
                radius_mm: self.radius_mm,
                feed: self.feed_mm_min,
            });
        }
        Ok(())
    }

    fn check_angles(&self) -> Result<(), TraceError> {
        let s = self.sense.sign();
        for (i, w) in self.angle_deg.windows(2).enumerate() {
            let step = (w[1] - w[0]) * s;
            if step < -MAX_BACKWARD_DEG {
                return Err(TraceError::Backwards {
                    label: self.label.clone(),
                    index: i + 1,
                    from: w[0],
                    to: w[1],
                    sense: self.sense.name().to_uppercase(),
                });
            }
            if step > MAX_GAP_DEG {
                return Err(TraceError::Gap {
                    label: self.label.clone(),
                    index: i,
                    next: i + 1,
                    at: w[0],
                    gap: step,
                    max: MAX_GAP_DEG,
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn trace(angles: Vec<f64>) -> Trace {
        let n = angles.len();
        Trace {
            label: "t".into(),
            plane: Plane::Xy,
            sense: Sense::Ccw,
            radius_mm: 150.0,
            feed_mm_min: 1000.0,
            angle_deg: angles,
            deviation_um: vec![0.0; n],
            time_s: None,
        }
    }

    #[test]
    fn a_gap_larger_than_allowed_is_refused_with_its_place() {
        let mut a: Vec<f64> = (0..100).map(|i| i as f64).collect();
        a[1..100].iter_mut().for_each(|v| *v *= 0.5);
        a.iter_mut().skip(50).for_each(|v| *v += 3.0);
        let e = trace(a).validate().unwrap_err();
        assert!(matches!(e, TraceError::Gap { index: 49, .. }), "{e}");
    }

    #[test]
    fn angles_against_the_sense_are_refused() {
        let mut t = trace((0..100).map(|i| i as f64).collect());
        t.sense = Sense::Cw;
        let e = t.validate().unwrap_err();
        assert!(e.to_string().contains("against the CW sense"), "{e}");
    }

    /// A CCW run labelled CW at 1 kHz steps 0.006° a sample, within the jitter allowed
    /// sample to sample: the run as a whole must still be refused.
    #[test]
    fn a_run_labelled_with_the_other_direction_is_refused() {
        let mut t = trace((0..60_000).map(|i| i as f64 * 0.006).collect());
        assert!(t.validate().is_ok());
        t.sense = Sense::Cw;
        let e = t.validate().unwrap_err();
        assert!(matches!(e, TraceError::WrongSense { .. }), "{e}");
        assert!(e.to_string().contains("check the direction labels"), "{e}");
    }

    #[test]
    fn an_arc_under_88_degrees_is_refused_and_88_accepted() {
        let e = trace((0..=870).map(|i| i as f64 * 0.1).collect())
            .validate()
            .unwrap_err();
        assert!(
            matches!(e, TraceError::ShortArc { sweep, .. } if (sweep - 87.0).abs() < 1e-9),
            "{e}"
        );
        assert!(
            trace((0..=880).map(|i| i as f64 * 0.1).collect())
                .validate()
                .is_ok()
        );
    }

    #[test]
    fn a_deviation_beyond_a_ball_bars_range_is_refused_at_its_sample() {
        let mut t = trace((0..3600).map(|i| i as f64 * 0.1).collect());
        t.deviation_um[7] = 1e300;
        let e = t.validate().unwrap_err();
        assert!(matches!(e, TraceError::Deviation { index: 7, .. }), "{e}");
        assert_eq!(e.sample(), Some(7));
        // The edge is ±2 mm in µm: 2000 µm either way passes, a nanometre more does not.
        t.deviation_um[7] = -2000.0;
        t.deviation_um[8] = 2000.0;
        assert!(t.validate().is_ok(), "{:?}", t.validate());
        t.deviation_um[8] = 2000.001;
        let e = t.validate().unwrap_err();
        assert!(matches!(e, TraceError::Deviation { index: 8, .. }), "{e}");
        assert!(e.to_string().contains("within ±2000 µm"), "{e}");
    }

    /// 150 mm at 1000 mm/min sweeps 360° in 56.55 s: times at that pace pass, the same times
    /// with the feed typed as 10 are refused with the speed they give.
    #[test]
    fn times_that_disagree_with_the_feed_are_refused() {
        let mut t = trace((0..3600).map(|i| i as f64 * 0.1).collect());
        let duration = 150.0 * 359.9_f64.to_radians() / 1000.0 * 60.0;
        t.time_s = Some((0..3600).map(|i| i as f64 * duration / 3599.0).collect());
        assert!(t.validate().is_ok(), "{:?}", t.validate());
        // The edges: under 91 % of the feed refused, an inclined bar's 2.5 times accepted,
        // over 10 times refused.
        for (ratio, ok) in [
            (0.90, false),
            (0.92, true),
            (2.5, true),
            (9.99, true),
            (10.01, false),
        ] {
            t.feed_mm_min = 1000.0 / ratio;
            assert_eq!(t.validate().is_ok(), ok, "{ratio}: {:?}", t.validate());
        }
        t.feed_mm_min = 10.0;
        let e = t.validate().unwrap_err();
        assert!(
            matches!(e, TraceError::FeedMismatch { implied, .. } if (implied - 1000.0).abs() < 1e-6),
            "{e}"
        );
    }
}
