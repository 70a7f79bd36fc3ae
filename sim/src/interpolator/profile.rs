//! The feed profile of one rest-to-rest motion: the acceleration-limited path parameter `s(t)`
//! as constant-acceleration phases, and its jerk-limiting moving-average (FIR) filter.
//!
//! The raw profile is piecewise quadratic in time (trapezoidal velocity, acceleration in
//! `{−a, 0, +a}`), starting and ending at rest: `s(t) = s₀ + v₀ (t − t₀) + ½ a (t − t₀)²` in each
//! phase, `s = 0` before it starts and `s = L` after it ends at `T`. The filtered profile is its
//! moving average over the window `T_j = N·T_ipo`:
//!
//! `s_f(t) = (1/T_j) ∫_{t−T_j}^{t} s(τ) dτ`, `ṡ_f(t) = (s(t) − s(t − T_j)) / T_j`,
//! `s̈_f(t) = (ṡ(t) − ṡ(t − T_j)) / T_j`, `s⃛_f(t) = (s̈(t) − s̈(t − T_j)) / T_j`.
//!
//! It lasts `T + T_j`, keeps `|ṡ_f| ≤ max ṡ` and `|s̈_f| ≤ max |s̈|` over the window, and its jerk
//! is at most `a_max / T_j ≤ j_max` provided no window holds both an accelerating and a
//! decelerating phase — which the planner guarantees.

/// One phase of constant acceleration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Phase {
    /// Start time from the start of the motion, s.
    pub t0: f64,
    /// Path parameter at the start, m (from the start of the motion).
    pub s0: f64,
    /// Speed at the start, m/s.
    pub v0: f64,
    /// Acceleration, m/s².
    pub a: f64,
}

impl Phase {
    fn s(&self, x: f64) -> f64 {
        self.s0 + x * (self.v0 + 0.5 * self.a * x)
    }

    fn v(&self, x: f64) -> f64 {
        self.v0 + self.a * x
    }

    /// `∫ s` from local time `x0` to `x1`.
    fn integral(&self, x0: f64, x1: f64) -> f64 {
        self.s0 * (x1 - x0)
            + self.v0 * (x1 * x1 - x0 * x0) / 2.0
            + self.a * (x1.powi(3) - x0.powi(3)) / 6.0
    }
}

/// The raw (acceleration-limited) profile of a rest-to-rest motion.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct RawProfile {
    /// The phases in time order, the first at `t0 = 0`.
    pub phases: Vec<Phase>,
    /// Duration `T`, s.
    pub duration: f64,
    /// Path length `L`, m.
    pub length: f64,
}

/// Path parameter, speed and acceleration at one instant.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct PathState {
    /// Path parameter, m.
    pub s: f64,
    /// Path speed, m/s.
    pub v: f64,
    /// Path acceleration, m/s².
    pub a: f64,
}

impl RawProfile {
    /// End time of phase `i`, s.
    pub fn phase_end(&self, i: usize) -> f64 {
        self.phases.get(i + 1).map_or(self.duration, |p| p.t0)
    }

    /// Speed at the end of phase `i`, m/s.
    pub fn phase_end_speed(&self, i: usize) -> f64 {
        let p = &self.phases[i];
        p.v(self.phase_end(i) - p.t0)
    }

    /// Index of the phase holding time `t` (clamped to the first and last phase).
    fn phase_at(&self, t: f64) -> usize {
        self.phases.partition_point(|p| p.t0 <= t).saturating_sub(1)
    }

    /// Raw state at time `t` (at rest before the start and after the end).
    pub fn state(&self, t: f64) -> PathState {
        if t <= 0.0 || self.phases.is_empty() {
            return PathState::default();
        }
        if t >= self.duration {
            return PathState {
                s: self.length,
                ..PathState::default()
            };
        }
        let phase = &self.phases[self.phase_at(t)];
        let x = t - phase.t0;
        PathState {
            s: phase.s(x).min(self.length),
            v: phase.v(x).max(0.0),
            a: phase.a,
        }
    }

    /// `∫ s(τ) dτ` over `[t0, t1]`, `t0 <= t1`.
    fn integral(&self, t0: f64, t1: f64) -> f64 {
        let after = (t1 - t0.max(self.duration)).max(0.0) * self.length;
        let (start, end) = (t0.max(0.0), t1.min(self.duration));
        if start >= end {
            return after;
        }
        let mut sum = 0.0;
        let mut i = self.phase_at(start);
        while i < self.phases.len() && self.phases[i].t0 < end {
            let phase = &self.phases[i];
            let x0 = start.max(phase.t0) - phase.t0;
            let x1 = end.min(self.phase_end(i)) - phase.t0;
            if x1 > x0 {
                sum += phase.integral(x0, x1);
            }
            i += 1;
        }
        sum + after
    }

    /// The filtered state at time `t` for the window `window` (s): moving average of `s` over
    /// `[t − window, t]`.
    pub fn filtered(&self, window: f64, t: f64) -> PathState {
        if t <= 0.0 || self.phases.is_empty() {
            return PathState::default();
        }
        if t >= self.duration + window {
            return PathState {
                s: self.length,
                ..PathState::default()
            };
        }
        let (now, before) = (self.state(t), self.state(t - window));
        PathState {
            s: (self.integral(t - window, t) / window).clamp(0.0, self.length),
            v: ((now.s - before.s) / window).max(0.0),
            a: (now.v - before.v) / window,
        }
    }

    /// The time in `[0, T + window]` at which the filtered path parameter reaches `s` (bisection
    /// on the non-decreasing `s_f`).
    pub fn filtered_time_at(&self, window: f64, s: f64) -> f64 {
        let (mut lo, mut hi) = (0.0, self.duration + window);
        if s <= 0.0 {
            return lo;
        }
        if s >= self.length {
            return hi;
        }
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                break;
            }
            if self.filtered(window, mid).s < s {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }
}
