//! Fine interpolation: the path parameter between IPO samples, at the servo rate.
//!
//! The IPO stage stores `s_k` and `ṡ_k` at `t_k = k·T_ipo`. Between two samples the fine
//! interpolator evaluates the cubic Hermite polynomial through `(s_k, ṡ_k)` and
//! `(s_{k+1}, ṡ_{k+1})`, `τ = (t − t_k)/T_ipo ∈ [0, 1)`, `Δ = s_{k+1} − s_k`, `h = T_ipo`:
//!
//! `s = s_k + (3τ² − 2τ³)Δ + (τ − 2τ² + τ³) h ṡ_k + (τ³ − τ²) h ṡ_{k+1}`.
//!
//! Position and velocity are continuous across samples; the acceleration is linear within an
//! interval and may step by `O(j_max T_ipo)` at a sample. The cubic's jerk is a positive-weight
//! average (Peano kernel `6τ(1 − τ)`) of the jerk of the sampled profile, so it never exceeds
//! `j_max`.

use super::profile::PathState;

/// Path parameter and speed at every IPO tick.
#[derive(Clone, Debug, Default)]
pub(crate) struct IpoSamples {
    /// `(s, ṡ)` at `t_k = k·T_ipo`, m and m/s.
    samples: Vec<[f64; 2]>,
    /// `T_ipo`, s.
    period: f64,
}

impl IpoSamples {
    /// Empty, for the period `period` (s).
    pub fn with_capacity(period: f64, capacity: usize) -> Self {
        IpoSamples {
            samples: Vec::with_capacity(capacity),
            period,
        }
    }

    /// Appends the sample of the next tick.
    pub fn push(&mut self, s: f64, v: f64) {
        self.samples.push([s, v]);
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// The interpolated state at `τ ∈ [0, 1)` of the interval starting at tick `k`; the sample
    /// itself (acceleration 0) at the last tick.
    pub fn at(&self, k: usize, tau: f64) -> PathState {
        let Some(&[s0, v0]) = self.samples.get(k) else {
            return PathState::default();
        };
        let Some(&[s1, v1]) = self.samples.get(k + 1) else {
            return PathState {
                s: s0,
                v: v0,
                a: 0.0,
            };
        };
        let h = self.period;
        let delta = s1 - s0;
        let (t2, t3) = (tau * tau, tau * tau * tau);
        PathState {
            s: s0
                + (3.0 * t2 - 2.0 * t3) * delta
                + (tau - 2.0 * t2 + t3) * h * v0
                + (t3 - t2) * h * v1,
            v: ((6.0 * tau - 6.0 * t2) * delta
                + (1.0 - 4.0 * tau + 3.0 * t2) * h * v0
                + (3.0 * t2 - 2.0 * tau) * h * v1)
                / h,
            a: ((6.0 - 12.0 * tau) * delta
                + (6.0 * tau - 4.0) * h * v0
                + (6.0 * tau - 2.0) * h * v1)
                / (h * h),
        }
    }
}
