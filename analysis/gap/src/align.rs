//! A measured ball-bar trace beside the simulation of the same test.
//!
//! The residual is `r(θ) = measured(θ) - simulated(θ)` (µm) at each measured angle θ, the
//! simulated deviation linearly interpolated in angle. Both traces must be the same test: same
//! plane, sense, bar length (to 1e-6 relative) and feed (to 0.1 %), and the simulated arc must
//! cover at least 90 % of the measured one (after whole turns that bring the instrument's
//! angle zero onto the model's); measured samples outside the simulated arc are left out.

use thiserror::Error;
use vmt_ballbar::{Plane, Sense, Trace, TraceError};

/// Why a measured run cannot be compared with its simulation.
#[derive(Debug, Error, PartialEq)]
pub enum GapError {
    /// A trace failed its checks.
    #[error(transparent)]
    Trace(#[from] TraceError),
    /// The measured run is not the simulated test.
    #[error(
        "{label}: the measured {what} is {measured} but the model's job has {model}; measure the job the model runs, or change the scenario's job to match"
    )]
    Mismatch {
        /// The measured trace's label.
        label: String,
        /// Which setting differs (`plane`, `direction`, `radius_mm`, `feed_mm_min`, `arc`).
        what: &'static str,
        /// The measured value.
        measured: String,
        /// The model's value.
        model: String,
    },
    /// Nothing to localise.
    #[error("no measured run to compare")]
    Empty,
    /// The model could not be built or simulated.
    #[error("model: {0}")]
    Model(String),
    /// The measured runs hold a test more often than the model's job runs it.
    #[error(
        "{label}: the measured runs hold {given} {test} traces, the model's job runs it {in_job} \
         time(s); give each test of the job once (is a file given twice?)"
    )]
    MoreThanInJob {
        /// The measured trace in excess.
        label: String,
        /// The test, e.g. `XY 150 mm 1000 mm/min cw`.
        test: String,
        /// How many of the measured traces are of that test.
        given: usize,
        /// How many times the job runs it.
        in_job: usize,
    },
    /// A measured trace has no simulated counterpart in the model's job.
    #[error(
        "{label}: the model's job has no {plane} test of {radius_mm} mm at {feed_mm_min} mm/min {direction}; its tests are: {tests}"
    )]
    NotInJob {
        /// The measured trace.
        label: String,
        /// Its plane.
        plane: String,
        /// Its radius, mm.
        radius_mm: f64,
        /// Its feed, mm/min.
        feed_mm_min: f64,
        /// Its direction.
        direction: String,
        /// The model's tests.
        tests: String,
    },
}

/// One measured trace and its residual against the simulation.
#[derive(Clone, Debug, PartialEq)]
pub struct TracePair {
    /// The measured trace's label.
    pub label: String,
    /// Test plane.
    pub plane: Plane,
    /// Sense of travel.
    pub sense: Sense,
    /// Bar length, mm.
    pub radius_mm: f64,
    /// Feed, mm/min.
    pub feed_mm_min: f64,
    /// Measured angles, deg.
    pub angle_deg: Vec<f64>,
    /// Sample times, s (from the measured trace, else from the angle at the feed).
    pub time_s: Vec<f64>,
    /// Measured minus simulated deviation, µm.
    pub residual_um: Vec<f64>,
}

impl TracePair {
    /// Aligns `measured` with `simulated` and forms the residual.
    pub fn align(measured: &Trace, simulated: &Trace) -> Result<Self, GapError> {
        measured.validate()?;
        simulated.validate()?;
        check_same_test(measured, simulated)?;
        let (offset, (s0, s1)) = arc_overlap(measured, simulated)?;
        let sim = Monotone::new(&simulated.angle_deg, &simulated.deviation_um);
        let deg_per_s = (measured.feed_mm_min / 60.0 / measured.radius_mm).to_degrees();
        let a0 = measured.angle_deg[0];
        let keep: Vec<usize> = (0..measured.angle_deg.len())
            .filter(|i| (s0..=s1).contains(&(measured.angle_deg[*i] + offset)))
            .collect();
        let time_at = |i: usize| match &measured.time_s {
            Some(t) => t[i],
            None => (measured.angle_deg[i] - a0).abs() / deg_per_s,
        };
        let angle_deg: Vec<f64> = keep
            .iter()
            .map(|i| measured.angle_deg[*i] + offset)
            .collect();
        Ok(Self {
            label: measured.label.clone(),
            plane: measured.plane,
            sense: measured.sense,
            radius_mm: measured.radius_mm,
            feed_mm_min: measured.feed_mm_min,
            residual_um: keep
                .iter()
                .zip(&angle_deg)
                .map(|(i, a)| measured.deviation_um[*i] - sim.at(*a))
                .collect(),
            time_s: keep.iter().map(|i| time_at(*i)).collect(),
            angle_deg,
        })
    }

    /// Mean square of the residual, µm².
    pub fn mean_square(&self) -> f64 {
        self.residual_um.iter().map(|r| r * r).sum::<f64>() / self.residual_um.len() as f64
    }
}

fn check_same_test(m: &Trace, s: &Trace) -> Result<(), GapError> {
    let mismatch = |what, measured: String, model: String| GapError::Mismatch {
        label: m.label.clone(),
        what,
        measured,
        model,
    };
    if m.plane != s.plane {
        return Err(mismatch("plane", m.plane.to_string(), s.plane.to_string()));
    }
    if m.sense != s.sense {
        return Err(mismatch(
            "direction",
            m.sense.name().into(),
            s.sense.name().into(),
        ));
    }
    if (m.radius_mm - s.radius_mm).abs() > 1e-6 * s.radius_mm {
        return Err(mismatch(
            "radius_mm",
            m.radius_mm.to_string(),
            s.radius_mm.to_string(),
        ));
    }
    if (m.feed_mm_min - s.feed_mm_min).abs() > 1e-3 * s.feed_mm_min {
        return Err(mismatch(
            "feed_mm_min",
            m.feed_mm_min.to_string(),
            s.feed_mm_min.to_string(),
        ));
    }
    Ok(())
}

/// The whole turns (deg) that bring the measured angles onto the simulated ones (instruments
/// count from their own zero), and the simulated arc, which must cover at least
/// [`MIN_OVERLAP`] of the measured one.
fn arc_overlap(m: &Trace, s: &Trace) -> Result<(f64, (f64, f64)), GapError> {
    let range = |a: &[f64]| {
        let (x, y) = (a[0], a[a.len() - 1]);
        (x.min(y), x.max(y))
    };
    let ((m0, m1), (s0, s1)) = (range(&m.angle_deg), range(&s.angle_deg));
    let offset = 360.0 * (((s0 + s1) - (m0 + m1)) / 720.0).round();
    let overlap = (m1 + offset).min(s1) - (m0 + offset).max(s0);
    if overlap < MIN_OVERLAP * (m1 - m0) {
        return Err(GapError::Mismatch {
            label: m.label.clone(),
            what: "arc",
            measured: format!("{m0:.1}..{m1:.1} deg"),
            model: format!("{s0:.1}..{s1:.1} deg"),
        });
    }
    Ok((offset, (s0, s1)))
}

/// The least share of a measured arc the simulated one must cover.
pub const MIN_OVERLAP: f64 = 0.9;

/// A piecewise-linear function of an angle that moves one way (either way).
struct Monotone {
    x: Vec<f64>,
    y: Vec<f64>,
}

impl Monotone {
    fn new(x: &[f64], y: &[f64]) -> Self {
        let (mut x, mut y) = (x.to_vec(), y.to_vec());
        if x[0] > x[x.len() - 1] {
            x.reverse();
            y.reverse();
        }
        Self { x, y }
    }

    /// Linear interpolation, held at the ends.
    fn at(&self, a: f64) -> f64 {
        let i = self.x.partition_point(|v| *v <= a);
        if i == 0 {
            return self.y[0];
        }
        if i == self.x.len() {
            return self.y[i - 1];
        }
        let (x0, x1) = (self.x[i - 1], self.x[i]);
        let t = if x1 > x0 { (a - x0) / (x1 - x0) } else { 0.0 };
        self.y[i - 1] + t * (self.y[i] - self.y[i - 1])
    }
}
