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

use std::ops::{Add, Div, Mul, Sub};

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

    /// The sample of tick `k`: `s` (m) and `ṡ` (m/s), acceleration 0.
    pub fn sample(&self, k: usize) -> Option<PathState> {
        let &[s, v] = self.samples.get(k)?;
        Some(PathState { s, v, a: 0.0 })
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
        let [s, v, a] = hermite(tau, self.period, s0, v0, s1, v1);
        PathState { s, v, a }
    }
}

/// The cubic Hermite polynomial of the module doc through `(x₀, ẋ₀)` at `τ = 0` and `(x₁, ẋ₁)`
/// at `τ = 1` of an interval of `h` seconds: its value, rate and second rate at `τ` (`x₀` and
/// `ẋ₀` exactly at `τ = 0`). For the path parameter and for the axes' positions alike.
#[inline]
pub(crate) fn hermite<T>(tau: f64, h: f64, x0: T, v0: T, x1: T, v1: T) -> [T; 3]
where
    T: Copy + Add<Output = T> + Sub<Output = T> + Mul<f64, Output = T> + Div<f64, Output = T>,
{
    let delta = x1 - x0;
    let (t2, t3) = (tau * tau, tau * tau * tau);
    [
        x0 + delta * (3.0 * t2 - 2.0 * t3)
            + v0 * ((tau - 2.0 * t2 + t3) * h)
            + v1 * ((t3 - t2) * h),
        (delta * (6.0 * tau - 6.0 * t2)
            + v0 * ((1.0 - 4.0 * tau + 3.0 * t2) * h)
            + v1 * ((3.0 * t2 - 2.0 * tau) * h))
            / h,
        (delta * (6.0 - 12.0 * tau) + v0 * ((6.0 * tau - 4.0) * h) + v1 * ((6.0 * tau - 2.0) * h))
            / (h * h),
    ]
}
