//! A trace prepared for fitting: cos θ and sin θ of every sample, its progress, and the trace
//! averaged into short groups of consecutive samples for the least-squares fit.
//!
//! The trigonometric functions come from a table of 1024 angles and the Taylor series of the
//! remainder (see [`sin_cos_deg`]): exact to a few 1e-16, and each sample independent of the
//! others, so the loop runs at the processor's throughput rather than waiting on a recurrence.
//! A block of samples close together shares one tabulated angle (see [`trig`]).

use crate::signatures::Point;
use crate::trace::{Sense, Trace};

/// The most groups a trace is averaged into for the fit.
pub const MAX_GROUPS: usize = 1024;

/// Where the samples of a trace lie, whatever its deviation: cos θ, sin θ and the progress
/// over the test of every sample (the passes of a diagnosis share them).
#[derive(Clone, Debug)]
pub struct Placement {
    /// cos θ per sample.
    pub cos: Vec<f64>,
    /// sin θ per sample.
    pub sin: Vec<f64>,
    /// Progress over the test per sample, −½…½.
    pub progress: Vec<f64>,
}

impl Placement {
    /// The placement of a validated trace with the progress of each sample over the test.
    pub fn new(t: &Trace, progress: Vec<f64>) -> Self {
        let (cos, sin) = trig(&t.angle_deg);
        Self { cos, sin, progress }
    }

    /// Returns the buffers to the pool.
    pub fn recycle(self) {
        for v in [self.cos, self.sin, self.progress] {
            recycle(v);
        }
    }
}

/// The samples of one trace in the form the signatures take.
#[derive(Clone, Debug)]
pub struct Samples<'a> {
    /// cos θ per sample.
    pub cos: &'a [f64],
    /// sin θ per sample.
    pub sin: &'a [f64],
    /// Progress over the test per sample, −½…½.
    pub progress: &'a [f64],
    /// Deviation per sample, µm.
    pub deviation_um: &'a [f64],
    /// Sense of travel.
    pub sense: Sense,
    /// Nominal radius, µm.
    pub radius_um: f64,
    /// Feed, µm/ms.
    pub feed_um_per_ms: f64,
    /// The trace averaged over groups of consecutive samples, at most [`MAX_GROUPS`] of them:
    /// (point at the group's mean angle and progress, mean deviation, samples in the group).
    pub groups: Vec<(Point, f64, usize)>,
    /// Whether each group enters the fit (see [`Samples::fit_groups`]).
    pub fitted: Vec<bool>,
    /// Samples per group (the last may hold fewer).
    pub group_size: usize,
}

impl<'a> Samples<'a> {
    /// The samples of a validated trace placed by `place`, with the deviations `deviation_um`
    /// (the trace's own or corrected ones): one pass computes the group sums.
    pub fn new(t: &'a Trace, place: &'a Placement, deviation_um: &'a [f64]) -> Self {
        let angle_deg = &t.angle_deg;
        let n = angle_deg.len();
        let size = n.div_ceil(MAX_GROUPS).max(1);
        let (radius_um, feed_um_per_ms) = (t.radius_mm * 1e3, t.feed_um_per_ms());
        let table = table();
        let groups: Vec<(Point, f64, usize)> = angle_deg
            .chunks(size)
            .zip(place.progress.chunks(size))
            .zip(deviation_um.chunks(size))
            .map(|((a, p), d)| {
                let k = a.len() as f64;
                let (s, c) = sin_cos_deg(a.iter().sum::<f64>() / k, table);
                let point = Point {
                    cos: c,
                    sin: s,
                    sense: t.sense,
                    progress: p.iter().sum::<f64>() / k,
                    radius_um,
                    feed_um_per_ms,
                };
                (point, d.iter().sum::<f64>() / k, a.len())
            })
            .collect();
        let mut s = Self {
            cos: &place.cos,
            sin: &place.sin,
            progress: &place.progress,
            deviation_um,
            sense: t.sense,
            radius_um,
            feed_um_per_ms,
            groups,
            fitted: Vec::new(),
            group_size: size,
        };
        let skip = s.transient_deg();
        let (a, b) = (angle_deg[0], angle_deg[n - 1]);
        let (lo, hi) = (a.min(b) + skip, a.max(b) - skip);
        s.fitted = (0..s.groups.len())
            .map(|k| {
                let mid = (k * size + size / 2).min(n - 1);
                (lo..=hi).contains(&angle_deg[mid])
            })
            .collect();
        s
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.cos.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.cos.is_empty()
    }

    /// Sample `i` as a signature point.
    pub fn point(&self, i: usize) -> Point {
        Point {
            cos: self.cos[i],
            sin: self.sin[i],
            sense: self.sense,
            progress: self.progress[i],
            radius_um: self.radius_um,
            feed_um_per_ms: self.feed_um_per_ms,
        }
    }
}

/// The start and end of a run the model is not fitted to, s: the acceleration from rest (or
/// the feed-in) and the deceleration at the end excite the servo loops, whose transients last a
/// few position-loop time constants (1/K_v ≈ 30 ms); the residual keeps them for the start
/// transient finding.
pub const TRANSIENT_S: f64 = 0.15;
/// The least angle left out at each end, deg.
pub const TRANSIENT_MIN_DEG: f64 = 3.0;

/// The angle left out at each end of a trace of radius `radius_mm` run at `feed_mm_min`, deg:
/// [`TRANSIENT_S`] of travel at the feed, at least [`TRANSIENT_MIN_DEG`] (also for a feed or
/// radius that gives no number). [`Samples::transient_deg`] is the same in its own units.
pub fn transient_deg(feed_mm_min: f64, radius_mm: f64) -> f64 {
    let travel_mm = feed_mm_min / 60.0 * TRANSIENT_S;
    (travel_mm / radius_mm).to_degrees().max(TRANSIENT_MIN_DEG)
}

impl Samples<'_> {
    /// The angle left out of the fit at each end of the trace, deg: [`TRANSIENT_S`] of travel
    /// at the feed, at least [`TRANSIENT_MIN_DEG`].
    pub fn transient_deg(&self) -> f64 {
        let travel_um = self.feed_um_per_ms * TRANSIENT_S * 1e3;
        (travel_um / self.radius_um)
            .to_degrees()
            .max(TRANSIENT_MIN_DEG)
    }

    /// Leaves out of the fit every group that holds a sample of `range` (sample indices).
    pub fn leave_out(&mut self, range: std::ops::Range<usize>) {
        let end = range.end.min(self.len());
        if range.start >= end {
            return;
        }
        let groups = range.start / self.group_size..=(end - 1) / self.group_size;
        for f in &mut self.fitted[groups] {
            *f = false;
        }
    }

    /// The groups without those within [`Samples::transient_deg`] of either end and those left
    /// out ([`Samples::leave_out`]: the diagnosis leaves out the reversal spikes).
    pub fn fit_groups(&self) -> impl Iterator<Item = &(Point, f64, usize)> + '_ {
        self.groups
            .iter()
            .zip(&self.fitted)
            .filter(|(_, f)| **f)
            .map(|(g, _)| g)
    }
}

/// Entries of the table [`sin_cos_deg`] reduces angles to: every 360/1024 deg.
const TABLE_N: usize = 1024;

fn table() -> &'static [(f64, f64); TABLE_N] {
    static TABLE: std::sync::OnceLock<[(f64, f64); TABLE_N]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        std::array::from_fn(|k| {
            let (s, c) = (std::f64::consts::TAU * k as f64 / TABLE_N as f64).sin_cos();
            (c, s)
        })
    })
}

/// (sin, cos) of an angle in degrees: the nearest of 1024 tabulated angles rotated by the
/// remainder ε (|ε| ≤ π/1024, see `rotate`). Agrees with `to_radians().sin_cos()` to a few
/// 1e-16, and each sample is independent of the others (no recurrence to wait for).
#[inline]
pub fn sin_cos_deg(a: f64, table: &[(f64, f64); TABLE_N]) -> (f64, f64) {
    if !reducible(a) {
        return a.to_radians().sin_cos();
    }
    let (e, k) = reduce(a);
    rotate(e, table[k])
}

/// Whether [`reduce`] is exact for `a` (|a| below about 3.5e17 deg).
#[inline]
fn reducible(a: f64) -> bool {
    (a * (TABLE_N as f64 / 360.0)).abs() < 1e15
}

/// Table steps per degree.
const STEPS_PER_DEG: f64 = TABLE_N as f64 / 360.0;
/// Radians per table step.
const RAD_PER_STEP: f64 = std::f64::consts::TAU / TABLE_N as f64;

/// The remainder ε (rad) of angle `a` (deg) from the nearest tabulated angle, and its index.
#[inline]
fn reduce(a: f64) -> (f64, usize) {
    let x = a * STEPS_PER_DEG;
    let (k, i) = nearest(x);
    ((x - k) * RAD_PER_STEP, i)
}

/// The integer k nearest to `x` (|x| < 1e15), and k mod [`TABLE_N`].
#[inline]
fn nearest(x: f64) -> (f64, usize) {
    const MAGIC: f64 = 6_755_399_441_055_744.0; // 1.5·2⁵²: adding it rounds to an integer
    let shifted = x + MAGIC;
    // The low bits of `shifted` are those of the integer k (two's complement): k mod TABLE_N
    // without a conversion.
    (shifted - MAGIC, shifted.to_bits() as usize & (TABLE_N - 1))
}

/// The most table steps a remainder may span for [`rotate`]: its Taylor series hold to
/// 1e-19 up to ε = 2π/512.
const MAX_STEPS: f64 = 2.0;

/// (sin, cos) of the tabulated angle with cosine `c0` and sine `s0` rotated by ε = `e`
/// (|ε| ≤ [`MAX_STEPS`] table steps), whose sine and cosine are their Taylor series to ε⁷
/// and ε⁶ (truncation below 1e-19).
#[inline]
fn rotate(e: f64, (c0, s0): (f64, f64)) -> (f64, f64) {
    let e2 = e * e;
    let ce = 1.0 - e2 * (0.5 - e2 * (1.0 / 24.0 - e2 * (1.0 / 720.0)));
    let se = e * (1.0 - e2 * (1.0 / 6.0 - e2 * (1.0 / 120.0 - e2 * (1.0 / 5040.0))));
    (s0 * ce + c0 * se, c0 * ce - s0 * se)
}

thread_local! {
    /// Per-sample buffers of finished diagnoses, reused by the next on this thread: a trace's
    /// columns are hundreds of kB each, and fresh ones cost page faults and zeroing in the
    /// kernel at every diagnosis.
    static POOL: std::cell::RefCell<Vec<Vec<f64>>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// An empty buffer for at least `capacity` values, reused from the pool when there is one.
pub fn buffer(capacity: usize) -> Vec<f64> {
    let mut v = POOL.with(|p| p.borrow_mut().pop()).unwrap_or_default();
    v.clear();
    v.reserve(capacity);
    v
}

/// A buffer of `len` values to be overwritten (left over from its last use, zero where it
/// grows), from the pool when there is one.
pub fn filled(len: usize) -> Vec<f64> {
    let mut v = POOL.with(|p| p.borrow_mut().pop()).unwrap_or_default();
    v.resize(len, 0.0);
    v
}

/// Returns a buffer to the pool for [`buffer`] and [`filled`].
pub fn recycle(v: Vec<f64>) {
    POOL.with(|p| {
        let mut p = p.borrow_mut();
        if p.len() < 16 {
            p.push(v);
        }
    });
}

/// cos and sin of every angle (deg), see [`sin_cos_deg`].
pub fn trig(angle_deg: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let t = table();
    let (mut cos, mut sin) = (filled(angle_deg.len()), filled(angle_deg.len()));
    let mut block = TrigBlock::default();
    let blocks = angle_deg.chunks(TRIG_BLOCK);
    for ((a, c), s) in blocks
        .zip(cos.chunks_mut(TRIG_BLOCK))
        .zip(sin.chunks_mut(TRIG_BLOCK))
    {
        block.sin_cos(a, t, c, s);
    }
    (cos, sin)
}

/// Angles per block of [`TrigBlock::sin_cos`]: 0.2° at 1 kHz, 1000 mm/min and 150 mm, within
/// [`MAX_STEPS`] of one tabulated angle.
const TRIG_BLOCK: usize = 32;

/// The intermediate values of a block of [`trig`]: remainders, table indices, and the
/// tabulated cosines and sines.
struct TrigBlock {
    e: [f64; TRIG_BLOCK],
    k: [usize; TRIG_BLOCK],
    c0: [f64; TRIG_BLOCK],
    s0: [f64; TRIG_BLOCK],
}

impl Default for TrigBlock {
    fn default() -> Self {
        Self {
            e: [0.0; TRIG_BLOCK],
            k: [0; TRIG_BLOCK],
            c0: [0.0; TRIG_BLOCK],
            s0: [0.0; TRIG_BLOCK],
        }
    }
}

impl TrigBlock {
    /// [`trig`] of up to [`TRIG_BLOCK`] angles: the reduction and the rotation are loops of
    /// the same operations on every angle (which the compiler runs on vectors), the table
    /// look-ups a loop of loads between them.
    fn sin_cos(
        &mut self,
        a: &[f64],
        table: &[(f64, f64); TABLE_N],
        cos: &mut [f64],
        sin: &mut [f64],
    ) {
        if near_one_angle(a, table, cos, sin) {
            return;
        }
        if !a.iter().fold(true, |ok, x| ok & reducible(*x)) {
            for ((a, c), s) in a.iter().zip(cos).zip(sin) {
                (*s, *c) = sin_cos_deg(*a, table);
            }
            return;
        }
        for ((e, k), a) in self.e.iter_mut().zip(&mut self.k).zip(a) {
            (*e, *k) = reduce(*a);
        }
        let at = self.c0.iter_mut().zip(&mut self.s0);
        for ((c0, s0), k) in at.zip(&self.k[..a.len()]) {
            (*c0, *s0) = table[*k & (TABLE_N - 1)];
        }
        let out = sin.iter_mut().zip(cos.iter_mut());
        for (((s, c), e), (c0, s0)) in out.zip(&self.e).zip(self.c0.iter().zip(&self.s0)) {
            (*s, *c) = rotate(*e, (*c0, *s0));
        }
    }
}

/// [`trig`] of a block of angles all within [`MAX_STEPS`] table steps of the tabulated angle
/// nearest the first: that angle rotated by each remainder, in a loop of the same operations
/// on every angle without look-ups (which the compiler runs on vectors). False, with nothing
/// written, when an angle lies farther.
fn near_one_angle(
    a: &[f64],
    table: &[(f64, f64); TABLE_N],
    cos: &mut [f64],
    sin: &mut [f64],
) -> bool {
    let Some(&first) = a.first() else {
        return true;
    };
    if !reducible(first) {
        return false;
    }
    let (k, i) = nearest(first * STEPS_PER_DEG);
    let far = a.iter().fold(0.0, |m: f64, x| {
        let d = (x * STEPS_PER_DEG - k).abs();
        if d > m { d } else { m }
    });
    if far > MAX_STEPS {
        return false;
    }
    let at = table[i];
    for ((x, c), s) in a.iter().zip(cos).zip(sin) {
        (*s, *c) = rotate((x * STEPS_PER_DEG - k) * RAD_PER_STEP, at);
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The tabulated sine and cosine agree with sin_cos over a full trace of any step ≤ 2°,
        /// to a few rounding errors.
        #[test]
        fn tabulated_trig_matches_sin_cos(start in -360.0..0.0f64, step in 1e-4..2.0f64, n in 2usize..5000) {
            check_trig(start, step, n)?;
        }

        /// The same for the steps of 1 kHz sampling (0.001°–0.02°), where blocks of angles are
        /// rotated from one table angle.
        #[test]
        fn blocks_of_close_angles_match_sin_cos(start in -360.0..0.0f64, step in 1e-3..0.02f64, n in 2usize..5000) {
            check_trig(start, step, n)?;
        }
    }

    proptest! {
        /// [`Samples::leave_out`] takes out of the fit exactly the groups that hold a sample of
        /// its range (clipped to the trace) and leaves the others as they were.
        #[test]
        fn leave_out_takes_exactly_the_groups_of_its_range(
            n in 300usize..5000,
            start in 0usize..6000,
            len in 0usize..800,
        ) {
            let angle_deg: Vec<f64> = (0..n).map(|i| i as f64 * 360.0 / n as f64).collect();
            let t = Trace {
                label: "t".into(),
                plane: crate::trace::Plane::Xy,
                sense: Sense::Ccw,
                radius_mm: 100.0,
                feed_mm_min: 1000.0,
                deviation_um: vec![0.0; n],
                angle_deg,
                time_s: None,
            };
            let place = Placement::new(&t, vec![0.0; n]);
            let mut s = Samples::new(&t, &place, &t.deviation_um);
            let before = s.fitted.clone();
            s.leave_out(start..start + len);
            for (g, (&was, &is)) in before.iter().zip(&s.fitted).enumerate() {
                let held = g * s.group_size..((g + 1) * s.group_size).min(n);
                // An empty range holds no sample, whatever group it falls in.
                let hit = len > 0 && held.start < start + len && start < held.end;
                prop_assert_eq!(is, was && !hit, "group {}", g);
            }
        }
    }

    /// Angles from `start` (within ±360°) by `step`, at most one turn of them: the reduction to
    /// a table step rounds by about |θ| · 1e-16 rad, which beyond a turn would cover the
    /// rotation's truncation error that this checks.
    fn check_trig(start: f64, step: f64, n: usize) -> Result<(), TestCaseError> {
        let n = n.min((360.0 / step) as usize).max(2);
        let a: Vec<f64> = (0..n)
            .map(|i| start + step * i as f64)
            .filter(|x| x.abs() <= 360.0)
            .collect();
        let (c, s) = trig(&a);
        for (i, x) in a.iter().enumerate() {
            // The reference reduced to one turn first (exact), so that its angle in radians
            // rounds by at most 4e-16.
            let (se, ce) = x.rem_euclid(360.0).to_radians().sin_cos();
            prop_assert!(
                (c[i] - ce).abs() < 2e-15 && (s[i] - se).abs() < 2e-15,
                "{x}°: cos {} against {ce}, sin {} against {se}",
                c[i],
                s[i]
            );
        }
        Ok(())
    }
}
