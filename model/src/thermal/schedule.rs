//! Operating schedules of a thermal run (ISO 230-3 warm-up with the spindle
//! or the axes running, cool-down, a day of ambient drift) and their
//! simulation.

use super::{Operating, ThermalError, ThermalNetwork, ThermalStepper};

/// Steps end at the next multiple of `dt` unless that is closer than this
/// fraction of `dt`, which avoids needless round-off-sized steps.
const GRID_SNAP: f64 = 1e-9;

/// One segment of a schedule: the operating point `op` holds from the end of
/// the previous segment (or `t = 0`) until `until_s`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    /// End of the segment in s from the start of the run.
    pub until_s: f64,
    /// Operating point during the segment.
    pub op: Operating,
}

/// A piecewise-constant operating schedule starting at `t = 0`. Before
/// `t = 0` and after the last segment everything is stopped (a cool-down).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ThermalSchedule {
    segments: Vec<Segment>,
}

impl ThermalSchedule {
    /// Builds and validates a schedule: end times finite, `> 0` and strictly
    /// increasing; speeds finite and `>= 0`. An empty schedule (everything
    /// stopped: pure cool-down or ambient drift) is accepted.
    pub fn new(segments: Vec<Segment>) -> Result<Self, ThermalError> {
        let mut previous_s = 0.0;
        for (segment, s) in segments.iter().enumerate() {
            if !(s.until_s.is_finite() && s.until_s > previous_s) {
                return Err(ThermalError::InvalidSegmentEnd {
                    segment,
                    value: s.until_s,
                    previous_s,
                });
            }
            check_speeds(segment, &s.op)?;
            previous_s = s.until_s;
        }
        Ok(Self { segments })
    }

    /// The segments.
    pub fn segments(&self) -> &[Segment] {
        &self.segments
    }

    /// The operating point at `t_s`; segment `k` applies on
    /// `[until_s[k−1], until_s[k])`. Stopped before 0, after the last
    /// segment, and for a NaN time.
    pub fn operating_at(&self, t_s: f64) -> Operating {
        if t_s.is_nan() || t_s < 0.0 {
            return Operating::STOPPED;
        }
        self.segments
            .get(self.segment_index(t_s))
            .map_or(Operating::STOPPED, |s| s.op)
    }

    /// End of the last segment in s (0 for an empty schedule).
    pub fn duration_s(&self) -> f64 {
        self.segments.last().map_or(0.0, |s| s.until_s)
    }

    /// The first segment end strictly after `t_s`, if any.
    fn next_change_after(&self, t_s: f64) -> Option<f64> {
        self.segments
            .get(self.segment_index(t_s))
            .map(|s| s.until_s)
    }

    /// Index of the first segment ending strictly after `t_s`.
    fn segment_index(&self, t_s: f64) -> usize {
        self.segments.partition_point(|s| s.until_s <= t_s)
    }
}

fn check_speeds(segment: usize, op: &Operating) -> Result<(), ThermalError> {
    for (quantity, value) in Operating::SPEED_NAMES.into_iter().zip(op.speeds()) {
        if !(value.is_finite() && value >= 0.0) {
            return Err(ThermalError::InvalidSegmentSpeed {
                segment,
                quantity,
                value,
            });
        }
    }
    Ok(())
}

/// A simulation of a network following a schedule, from `t = 0` at the
/// network's initial temperatures.
///
/// Steps end at the multiples of `dt`, at every change of the schedule, and
/// at the requested times, so the heat is constant within each step and
/// piecewise-constant heat is integrated exactly; shorter steps are
/// discretised exactly too. The ambient temperature used for a step is its
/// value at the step's midpoint.
#[derive(Debug, Clone)]
pub struct ThermalRun<'a> {
    network: &'a ThermalNetwork,
    stepper: ThermalStepper,
    schedule: &'a ThermalSchedule,
    t_s: f64,
    temps: Vec<f64>,
}

impl<'a> ThermalRun<'a> {
    /// Starts a run at `t = 0` with the step `dt_s` (s, finite and `> 0`).
    pub fn new(
        network: &'a ThermalNetwork,
        schedule: &'a ThermalSchedule,
        dt_s: f64,
    ) -> Result<Self, ThermalError> {
        Ok(Self {
            network,
            stepper: network.discretize(dt_s)?,
            schedule,
            t_s: 0.0,
            temps: network.initial_temperatures(),
        })
    }

    /// The network simulated.
    pub fn network(&self) -> &'a ThermalNetwork {
        self.network
    }

    /// The schedule followed.
    pub fn schedule(&self) -> &'a ThermalSchedule {
        self.schedule
    }

    /// Current time in s.
    pub fn time_s(&self) -> f64 {
        self.t_s
    }

    /// Current node temperatures in °C.
    pub fn temperatures_c(&self) -> &[f64] {
        &self.temps
    }

    /// Advances the run to exactly `t_s` (s). Errors if `t_s` is not finite
    /// or before the current time; `t_s` equal to the current time does
    /// nothing. The cost is proportional to the number of steps,
    /// `(t_s − time_s()) / dt` plus the schedule changes crossed.
    pub fn advance_to(&mut self, t_s: f64) -> Result<(), ThermalError> {
        if !t_s.is_finite() {
            return Err(ThermalError::InvalidTime { value: t_s });
        }
        if t_s < self.t_s {
            return Err(ThermalError::BackwardsInTime {
                from_s: self.t_s,
                to_s: t_s,
            });
        }
        while self.t_s < t_s {
            let end = self.step_end(t_s);
            self.step_to(end);
        }
        Ok(())
    }

    /// End of the next step: the earliest of the next multiple of `dt`, the
    /// next schedule change and `target`. Always `> self.t_s`.
    fn step_end(&self, target: f64) -> f64 {
        let dt = self.stepper.dt_s();
        let mut grid = ((self.t_s / dt + GRID_SNAP).floor() + 1.0) * dt;
        if grid <= self.t_s {
            // Only when t/dt exceeds 2^53: fall back to one exact long step.
            grid = target;
        }
        let change = self.schedule.next_change_after(self.t_s).unwrap_or(target);
        grid.min(change).min(target)
    }

    /// One exactly discretised step from the current time to `end`.
    fn step_to(&mut self, end: f64) {
        let mid = 0.5 * (self.t_s + end);
        let heat = self.network.heat_input_w(&self.schedule.operating_at(mid));
        let ambient = self.network.ambient().celsius_at(mid);
        self.stepper
            .step_by(&mut self.temps, &heat, ambient, end - self.t_s);
        self.t_s = end;
    }
}

/// Node temperatures (°C) at each of `times_s` (s, finite and `>= 0`, in any
/// order, repeats allowed) for a run of `network` following `schedule` with
/// the step `dt_s`. Result `k` belongs to `times_s[k]`.
pub fn temperatures_at(
    network: &ThermalNetwork,
    schedule: &ThermalSchedule,
    dt_s: f64,
    times_s: &[f64],
) -> Result<Vec<Vec<f64>>, ThermalError> {
    let mut order: Vec<usize> = (0..times_s.len()).collect();
    order.sort_by(|&i, &j| times_s[i].total_cmp(&times_s[j]));
    let mut run = ThermalRun::new(network, schedule, dt_s)?;
    let mut result = vec![Vec::new(); times_s.len()];
    for i in order {
        run.advance_to(times_s[i])?;
        result[i] = run.temperatures_c().to_vec();
    }
    Ok(result)
}
