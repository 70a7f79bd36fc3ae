//! A trace prepared for fitting: cos θ and sin θ of every sample, its progress, and the trace
//! averaged into short groups of consecutive samples for the least-squares fit.
//!
//! The trigonometric functions are advanced by the rotation of each angle step,
//! `(c, s)ᵢ = R(Δθ)(c, s)ᵢ₋₁` with `cos Δθ`, `sin Δθ` from their Taylor series to Δθ⁷ (exact to
//! 1e-16 for steps under 2°, the largest gap a trace may have), and re-anchored on `sin_cos`
//! every 256 samples so round-off cannot accumulate.

use crate::signatures::Point;
use crate::trace::{Sense, Trace};

/// The most groups a trace is averaged into for the fit.
pub const MAX_GROUPS: usize = 1024;

/// The samples of one trace in the form the signatures take.
#[derive(Clone, Debug)]
pub struct Samples {
    /// cos θ per sample.
    pub cos: Vec<f64>,
    /// sin θ per sample.
    pub sin: Vec<f64>,
    /// Progress 0…1 per sample.
    pub progress: Vec<f64>,
    /// Deviation per sample, µm.
    pub deviation_um: Vec<f64>,
    /// Sense of travel.
    pub sense: Sense,
    /// Nominal radius, µm.
    pub radius_um: f64,
    /// Feed, µm/ms.
    pub feed_um_per_ms: f64,
}

impl Samples {
    /// The samples of a validated trace with the progress of each sample over the test.
    pub fn new(t: &Trace, progress: Vec<f64>) -> Self {
        let (cos, sin) = trig(&t.angle_deg);
        Self {
            cos,
            sin,
            progress,
            deviation_um: t.deviation_um.clone(),
            sense: t.sense,
            radius_um: t.radius_mm * 1e3,
            feed_um_per_ms: t.feed_um_per_ms(),
        }
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

    /// The trace averaged over groups of consecutive samples, at most [`MAX_GROUPS`] of them:
    /// (point at the group's mean angle and progress, mean deviation, samples in the group).
    pub fn groups(&self, angle_deg: &[f64]) -> Vec<(Point, f64, usize)> {
        let n = self.len();
        let size = n.div_ceil(MAX_GROUPS).max(1);
        (0..n)
            .step_by(size)
            .map(|start| {
                let end = (start + size).min(n);
                let k = (end - start) as f64;
                let mean = |v: &[f64]| v[start..end].iter().sum::<f64>() / k;
                let (s, c) = mean(angle_deg).to_radians().sin_cos();
                let point = Point {
                    cos: c,
                    sin: s,
                    sense: self.sense,
                    progress: mean(&self.progress),
                    radius_um: self.radius_um,
                    feed_um_per_ms: self.feed_um_per_ms,
                };
                (point, mean(&self.deviation_um), end - start)
            })
            .collect()
    }
}

/// The start and end of a run the model is not fitted to, s: the acceleration from rest (or
/// the feed-in) and the deceleration at the end excite the servo loops, whose transients last a
/// few position-loop time constants (1/K_v ≈ 30 ms); the residual keeps them for the start
/// transient finding.
pub const TRANSIENT_S: f64 = 0.15;
/// The least angle left out at each end, deg.
pub const TRANSIENT_MIN_DEG: f64 = 3.0;

impl Samples {
    /// The angle left out of the fit at each end of the trace, deg: [`TRANSIENT_S`] of travel
    /// at the feed, at least [`TRANSIENT_MIN_DEG`].
    pub fn transient_deg(&self) -> f64 {
        let travel_um = self.feed_um_per_ms * TRANSIENT_S * 1e3;
        (travel_um / self.radius_um)
            .to_degrees()
            .max(TRANSIENT_MIN_DEG)
    }

    /// [`Samples::groups`] without those within [`Samples::transient_deg`] of either end.
    pub fn fit_groups(&self, angle_deg: &[f64]) -> Vec<(Point, f64, usize)> {
        let skip = self.transient_deg();
        let (a, b) = (angle_deg[0], angle_deg[angle_deg.len() - 1]);
        let (lo, hi) = (a.min(b) + skip, a.max(b) - skip);
        let n = self.len();
        let size = n.div_ceil(MAX_GROUPS).max(1);
        self.groups(angle_deg)
            .into_iter()
            .enumerate()
            .filter(|(k, _)| {
                let mid = (k * size + size / 2).min(n - 1);
                (lo..=hi).contains(&angle_deg[mid])
            })
            .map(|(_, g)| g)
            .collect()
    }
}

/// cos and sin of every angle (deg), by rotation from the previous sample.
pub fn trig(angle_deg: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = angle_deg.len();
    let (mut cos, mut sin) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let (mut c, mut s) = (1.0, 0.0);
    for (i, a) in angle_deg.iter().enumerate() {
        if i % 256 == 0 {
            (s, c) = a.to_radians().sin_cos();
        } else {
            let d = (a - angle_deg[i - 1]).to_radians();
            let d2 = d * d;
            let cd = 1.0 - d2 / 2.0 * (1.0 - d2 / 12.0 * (1.0 - d2 / 30.0));
            let sd = d * (1.0 - d2 / 6.0 * (1.0 - d2 / 20.0 * (1.0 - d2 / 42.0)));
            (c, s) = (c * cd - s * sd, s * cd + c * sd);
        }
        cos.push(c);
        sin.push(s);
    }
    (cos, sin)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The rotation recurrence agrees with sin_cos over a full trace of any step ≤ 2°.
        #[test]
        fn recurrence_matches_sin_cos(start in -720.0..720.0f64, step in 1e-4..2.0f64, n in 2usize..5000) {
            let a: Vec<f64> = (0..n).map(|i| start + step * i as f64).collect();
            let (c, s) = trig(&a);
            for (i, x) in a.iter().enumerate() {
                let (se, ce) = x.to_radians().sin_cos();
                prop_assert!((c[i] - ce).abs() < 1e-12 && (s[i] - se).abs() < 1e-12);
            }
        }
    }
}
