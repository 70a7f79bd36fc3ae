//! The interpolator of the CNC: from an NC [`Program`] to position, velocity and acceleration
//! setpoints at the servo rate.
//!
//! It works as a controller's interpolator does (Altintas, *Manufacturing Automation*, 2nd ed.,
//! ch. 6 "Trajectory generation"; Biagiotti & Melchiorri, *Trajectory Planning for Automatic
//! Machines and Robots*, 2008, ch. 3 and 4 on trapezoidal and double-S profiles and their
//! generation by FIR filters), in four stages. Units are SI: m, s, m/s, m/s², m/s³.
//!
//! 1. **Path geometry** ([`path`]). Every motion block is a segment parameterised by its path
//!    length `s`. Lines `p(s) = p₀ + s·d`; arcs and helices exactly from centre, radius and angle,
//!    `p = c + r·(cos θ·u + sin θ·v) + n·h·s/L`, `θ = θ₀ + φ·s/L` (no chords). A full circle is an
//!    arc whose end equals its start (sweep exactly ±360°); its direction is counter-clockwise
//!    (G3) or clockwise (G2) seen from the `+` end of the plane normal (Z for G17, Y for G18, X for
//!    G19). G0 is a straight line at the rapid rate. Blocks shorter than 1 pm are skipped.
//!
//! 2. **Feed planning with look-ahead** ([`planning`]). The blocks between two stops form a
//!    *section* that is planned as a whole. Each segment's speed is the programmed feed (the rapid
//!    rate for G0), reduced so that no axis exceeds its velocity, and on arcs so that the
//!    centripetal acceleration `v²κ` stays within [`feed_limits::CENTRIPETAL_SHARE`] of the
//!    in-plane axis acceleration limits; its tangential acceleration is `a_max`, reduced for the
//!    axis acceleration limits ([`feed_limits`]). Corners get the junction speed of
//!    [`junction`]: the smaller of the *velocity-jump rule* `v ≤ min_i A_i T_ipo / |Δt_i|` and
//!    the *junction-deviation rule* with the corner tolerance `δ`; tangent junctions keep their
//!    speed. A stop (a junction at rest) is made at the program start and end, at every dwell,
//!    before and after every rapid move (in-position check, as Fanuc and Siemens do by default),
//!    at every junction in exact-stop mode, and at reversals. Backward and forward passes give the
//!    time-optimal trapezoidal-velocity (constant-acceleration) profile from rest to rest.
//!
//! 3. **Jerk limitation** ([`profile`]). The path parameter (not the axes: the path stays exact)
//!    is smoothed by a moving-average FIR filter of length `T_j = N·T_ipo`,
//!    `N = ⌈a_max / (j_max T_ipo)⌉`:
//!    `s_f(t) = (1/T_j) ∫_{t−T_j}^{t} s(τ) dτ`, which turns each acceleration step of at most
//!    `a_max` into a ramp of jerk at most `a_max / T_j ≤ j_max` (the planner keeps the raw
//!    profile from accelerating and decelerating within one window, capping short peaks). A
//!    rest-to-rest section of raw duration `T` lasts `T + T_j` after filtering; a long line at feed
//!    `F` (cruise reached, `F/a_max ≥ T_j`) takes `L/F + F/a_max + T_j`, the time of the
//!    seven-phase double-S profile with `T_j = a_max/j_max`. The filtered profile is evaluated
//!    exactly at the IPO instants `t_k = k·T_ipo` (equivalently: a discrete FIR of `N` taps over
//!    the per-period means of `s`). Every section and dwell starts on an IPO tick; dwells are
//!    rounded up to whole IPO periods.
//!
//! 4. **Fine interpolation** ([`fine`]). From the IPO samples `(s_k, ṡ_k)` a cubic Hermite
//!    polynomial gives `s`, `ṡ`, `s̈` at every servo tick `t = k·T_s` (`T_s` divides `T_ipo`;
//!    defaults 1 ms and 125 µs), then `p = p(s)`, `ṗ = p′(s)·ṡ`, `p̈ = p″(s)·ṡ² + p′(s)·s̈` for
//!    the controller's feed-forward. At a corner passed at speed `v` the axis velocities step by
//!    `v·Δt` (at most `A_i T_ipo` each) from one servo tick to the next; the reported acceleration
//!    is the smooth part. Within an IPO interval that lies on one segment the axes are
//!    fine-interpolated instead, as a controller's fine interpolator does: the same cubic per
//!    axis through `p(s_k)`, `p′(s_k)·ṡ_k` and `p(s_{k+1})`, `p′(s_{k+1})·ṡ_{k+1}` (the path
//!    evaluated at the interval's ends only). By the Hermite remainder it strays from `p(s(t))`
//!    by at most `(T_ipo⁴/384)·max|d⁴p/dt⁴|`, with `d⁴p/dt⁴ = p⁗ṡ⁴ + 6p‴ṡ²s̈ + p″(3s̈² + 4ṡs⃛)`
//!    (`s` is a cubic in t) and the segment's bounds on `|p″|`, `|p‴|`, `|p⁗|`
//!    (`Geometry::derivative_bounds`). Where that exceeds 1 pm (a 150 mm circle at 1000 mm/min:
//!    6e-20 m; a 1 mm radius at 6 m/min accelerating at 2 m/s²: 6e-10 m), at a segment change
//!    and at the end of a motion, the path is evaluated at every servo tick. This takes the
//!    arc's trigonometry, a tenth of a reduced plant's tick, off the servo rate.
//!
//! Memory is the IPO samples (16 bytes per IPO period: 1 MB per minute at 1 ms) and the phases of
//! the profile; servo setpoints are computed on demand. No randomness, no clock: the same program
//! and configuration give the same setpoints, bit for bit.

mod config;
mod error;
pub mod feed_limits;
pub mod fine;
pub mod junction;
pub mod path;
pub mod planning;
pub mod profile;

use std::ops::Range;
use std::sync::OnceLock;

use nalgebra::Vector3;

pub use config::{InterpolatorConfig, Limits};
pub use error::InterpolatorError;

use crate::nc::program::{Program, Spindle};
use fine::IpoSamples;
use path::{Dwell, MoveKind, Segment, Step, build_steps};
use profile::{PathState, RawProfile};

/// Corners slower than this (m/s) are stops.
const MIN_CORNER_SPEED_M_S: f64 = 1e-6;
/// The largest number of IPO ticks a program may take (2²⁴: 4.6 h at 1 ms, 256 MB of samples).
const MAX_IPO_TICKS: usize = 1 << 24;
/// Relative slack when rounding durations up to whole IPO periods.
const TICK_SLACK: f64 = 1e-9;
/// The most the axes' fine interpolation may stray from the path, m (module doc, stage 4).
const AXIS_HERMITE_TOLERANCE_M: f64 = 1e-12;

/// One servo-rate setpoint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Setpoint {
    /// Time since the program start, s (`k·T_s`).
    pub time_s: f64,
    /// Commanded tool position relative to the workpiece, m.
    pub position: Vector3<f64>,
    /// Commanded velocity, m/s (`p′(s)·ṡ`).
    pub velocity: Vector3<f64>,
    /// Commanded acceleration for feed-forward, m/s² (`p″(s)·ṡ² + p′(s)·s̈`).
    pub acceleration: Vector3<f64>,
    /// Index in [`Program::blocks`] of the block being executed; `None` before any motion (an
    /// empty program).
    pub block: Option<usize>,
    /// Spindle state of that block.
    pub spindle: Spindle,
}

/// What happens during a stretch of IPO ticks.
#[derive(Clone, Debug)]
enum Activity {
    /// A rest-to-rest motion over `segments` (indices into [`Interpolator::segments`]) from
    /// path length `s_start` (m).
    Motion {
        segments: Range<usize>,
        s_start: f64,
        profile: RawProfile,
    },
    /// A dwell at path length `s` (m), position `position` (m).
    Dwell {
        dwell: Dwell,
        s: f64,
        position: Vector3<f64>,
    },
}

/// An activity and the IPO ticks `start..end` it occupies.
#[derive(Clone, Debug)]
struct Item {
    start: usize,
    end: usize,
    activity: Activity,
}

/// The interpolated program: built once by [`Interpolator::new`], then queried for setpoints at
/// any servo tick.
#[derive(Clone, Debug)]
pub struct Interpolator {
    start: Vector3<f64>,
    segments: Vec<Segment>,
    items: Vec<Item>,
    /// Sampled on first use: a check of the path's bounds needs none.
    samples: OnceLock<IpoSamples>,
    ipo_period_s: f64,
    servo_period_s: f64,
    ticks_per_ipo: usize,
    window_s: f64,
}

/// Where the last setpoint was found: its item and segment, and the IPO interval it lies in.
#[derive(Clone, Copy, Debug, Default)]
pub struct Cursor {
    item: usize,
    segment: usize,
    interval: Option<Interval>,
}

/// An IPO interval of a motion and, where its axes are fine-interpolated, its ends.
#[derive(Clone, Copy, Debug)]
struct Interval {
    /// The IPO tick that starts it.
    tick: usize,
    /// `None`: the path is evaluated at each servo tick.
    ends: Option<AxisEnds>,
}

/// Setpoints at both ends of an IPO interval that lies on one segment.
#[derive(Clone, Copy, Debug)]
struct AxisEnds {
    /// Position at the start and at the end, m.
    position: [Vector3<f64>; 2],
    /// Velocity at the start and at the end, m/s.
    velocity: [Vector3<f64>; 2],
    /// The segment's block and spindle.
    block: usize,
    spindle: Spindle,
}

impl AxisEnds {
    /// The setpoint at `τ` of the interval of `h` seconds, `time_s` (s) from the start.
    fn at(&self, tau: f64, h: f64, time_s: f64) -> Setpoint {
        let [position, velocity, acceleration] = fine::hermite(
            tau,
            h,
            self.position[0],
            self.velocity[0],
            self.position[1],
            self.velocity[1],
        );
        Setpoint {
            time_s,
            position,
            velocity,
            acceleration,
            block: Some(self.block),
            spindle: self.spindle,
        }
    }
}

/// The bound of the module doc (m) on how far the cubic Hermite polynomial of each axis over an
/// IPO interval of `h` seconds on `geometry`, between the path states `ends`, strays from the
/// path: `(h⁴/384)·max|d⁴p/dt⁴|`, with `|ṡ| ≤ max|ṡ_end| + h·max|s̈_end|`, `|s̈| ≤ max|s̈_end|`
/// (linear) and `s⃛` constant on the cubic of `s`.
fn remainder_bound(geometry: &path::Geometry, ends: &[PathState; 2], h: f64) -> f64 {
    let [k2, k3, k4] = geometry.derivative_bounds();
    let a = ends[0].a.abs().max(ends[1].a.abs());
    let v = ends[0].v.abs().max(ends[1].v.abs()) + h * a;
    let jerk = (ends[1].a - ends[0].a).abs() / h;
    let d4 = k4 * v.powi(4) + 6.0 * k3 * v * v * a + k2 * (3.0 * a * a + 4.0 * v * jerk);
    h.powi(4) / 384.0 * d4
}

/// The first index in `0..len` at which the monotone predicate `below` (true, then false) is
/// false, searched from `guess` in both directions: the same index as a bisection, found in a
/// step or two when the guess is the last answer and the queries advance slowly.
fn partition_from(len: usize, guess: usize, below: impl Fn(usize) -> bool) -> usize {
    let mut i = guess.min(len);
    while i < len && below(i) {
        i += 1;
    }
    while i > 0 && !below(i - 1) {
        i -= 1;
    }
    i
}

/// Collects steps into timeline items.
struct Builder<'a> {
    config: &'a InterpolatorConfig,
    window_s: f64,
    segments: Vec<Segment>,
    items: Vec<Item>,
    /// First segment of the open section and the junction speeds inside it.
    open: Option<usize>,
    corners: Vec<f64>,
    tick: usize,
}

impl<'a> Builder<'a> {
    fn new(config: &'a InterpolatorConfig, window_s: f64) -> Self {
        Builder {
            config,
            window_s,
            segments: Vec::new(),
            items: Vec::new(),
            open: None,
            corners: Vec::new(),
            tick: 0,
        }
    }

    /// Junction speed from the last segment into `next`; `None` for a stop.
    fn junction(&self, next: &Segment) -> Option<f64> {
        let prev = self.segments.last()?;
        if self.config.exact_stop || prev.kind == MoveKind::Rapid || next.kind == MoveKind::Rapid {
            return None;
        }
        let speed = junction::corner_speed(
            &prev.geometry.end_tangent(),
            &next.geometry.start_tangent(),
            &self.config.limits,
            self.config.ipo_period_s,
        );
        (speed >= MIN_CORNER_SPEED_M_S).then_some(speed)
    }

    fn add_move(&mut self, segment: Segment) -> Result<(), InterpolatorError> {
        match (self.open, self.junction(&segment)) {
            (Some(_), Some(corner)) => self.corners.push(corner),
            _ => {
                self.close()?;
                self.open = Some(self.segments.len());
            }
        }
        self.segments.push(segment);
        Ok(())
    }

    fn add_dwell(&mut self, dwell: Dwell, start: Vector3<f64>) -> Result<(), InterpolatorError> {
        self.close()?;
        let (s, position) = self
            .segments
            .last()
            .map_or((0.0, start), |seg| (seg.s_end(), seg.geometry.end()));
        let ticks = self.ticks(dwell.seconds, dwell.span.line)?;
        self.push(ticks, Activity::Dwell { dwell, s, position });
        Ok(())
    }

    /// Plans the open section, if any.
    fn close(&mut self) -> Result<(), InterpolatorError> {
        let Some(first) = self.open.take() else {
            return Ok(());
        };
        let range = first..self.segments.len();
        let segments = &self.segments[range.clone()];
        let profile =
            planning::plan_section(segments, &self.corners, &self.config.limits, self.window_s)?;
        self.corners.clear();
        let last_line = segments[segments.len() - 1].span.line;
        let ticks = self.ticks(profile.duration + self.window_s, last_line)?;
        let s_start = segments[0].s_start;
        self.push(
            ticks,
            Activity::Motion {
                segments: range,
                s_start,
                profile,
            },
        );
        Ok(())
    }

    /// Whole IPO periods covering `seconds`, refusing programs beyond [`MAX_IPO_TICKS`] at the
    /// block of `line`.
    fn ticks(&self, seconds: f64, line: usize) -> Result<usize, InterpolatorError> {
        let period = self.config.ipo_period_s;
        let ticks = (seconds / period * (1.0 - TICK_SLACK)).ceil().max(0.0);
        let total = self.tick as f64 + ticks;
        if total.is_nan() || total > MAX_IPO_TICKS as f64 {
            return Err(InterpolatorError::ProgramTooLong {
                line,
                duration_s: total * period,
                max_duration_s: MAX_IPO_TICKS as f64 * period,
            });
        }
        Ok(ticks as usize)
    }

    fn push(&mut self, ticks: usize, activity: Activity) {
        let start = self.tick;
        self.tick += ticks;
        self.items.push(Item {
            start,
            end: self.tick,
            activity,
        });
    }
}

impl Interpolator {
    /// Plans `program` under `config`: validates both, builds the path and plans every
    /// section; the IPO samples are computed when a setpoint first needs them.
    pub fn new(program: &Program, config: &InterpolatorConfig) -> Result<Self, InterpolatorError> {
        config.validate()?;
        let ticks_per_ipo = config.servo_ticks_per_ipo()?;
        let window_s = config.filter_taps() as f64 * config.ipo_period_s;
        let mut builder = Builder::new(config, window_s);
        for step in build_steps(program)? {
            match step {
                Step::Move(segment) => builder.add_move(*segment)?,
                Step::Dwell(dwell) => builder.add_dwell(dwell, program.start)?,
            }
        }
        builder.close()?;
        Ok(Interpolator {
            start: program.start,
            segments: builder.segments,
            items: builder.items,
            samples: OnceLock::new(),
            ipo_period_s: config.ipo_period_s,
            servo_period_s: config.servo_period_s,
            ticks_per_ipo,
            window_s,
        })
    }

    /// Total duration, s: the last IPO tick, at which the machine is at rest at the end point.
    pub fn duration_s(&self) -> f64 {
        self.ipo_ticks() as f64 * self.ipo_period_s
    }

    /// Servo period `T_s`, s.
    pub fn servo_period_s(&self) -> f64 {
        self.servo_period_s
    }

    /// Interpolation period `T_ipo`, s.
    pub fn ipo_period_s(&self) -> f64 {
        self.ipo_period_s
    }

    /// Length of the jerk filter window `T_j = N·T_ipo`, s.
    pub fn jerk_window_s(&self) -> f64 {
        self.window_s
    }

    /// Number of servo ticks, `duration_s / servo_period_s + 1` (ticks `0..=` the end).
    pub fn servo_ticks(&self) -> usize {
        self.ipo_ticks() * self.ticks_per_ipo + 1
    }

    /// The setpoint of the `k`-th servo tick (`t = k·T_s`); `None` after the end.
    pub fn setpoint(&self, k: usize) -> Option<Setpoint> {
        self.setpoint_from(k, &mut Cursor::default())
    }

    /// [`Interpolator::setpoint`], searching the item and segment from where `cursor` found the
    /// last one (for ticks taken in order, the same or the next) instead of bisecting; the
    /// result is the same.
    pub fn setpoint_from(&self, k: usize, cursor: &mut Cursor) -> Option<Setpoint> {
        if k >= self.servo_ticks() {
            return None;
        }
        let (m, r) = (k / self.ticks_per_ipo, k % self.ticks_per_ipo);
        let time_s = k as f64 * self.servo_period_s;
        cursor.item = partition_from(self.items.len(), cursor.item, |i| self.items[i].end <= m);
        let Some(item) = self.items.get(cursor.item).or(self.items.last()) else {
            return Some(self.rest(time_s, self.start, None, Spindle::Stopped));
        };
        match &item.activity {
            Activity::Dwell {
                dwell, position, ..
            } => Some(self.rest(time_s, *position, Some(dwell.block), dwell.spindle)),
            Activity::Motion {
                segments,
                s_start,
                profile,
            } => {
                let tau = r as f64 / self.ticks_per_ipo as f64;
                let range = *s_start..s_start + profile.length;
                if cursor.interval.is_none_or(|i| i.tick != m) {
                    let ends = self.axis_ends(m, segments, range.clone(), cursor);
                    cursor.interval = Some(Interval { tick: m, ends });
                }
                Some(match cursor.interval.and_then(|i| i.ends) {
                    Some(ends) => ends.at(tau, self.ipo_period_s, time_s),
                    None => self.path_setpoint(m, tau, time_s, segments, range, cursor),
                })
            }
        }
    }

    /// The setpoint at `τ` of IPO interval `m` of a motion over `segments` and the path lengths
    /// `range`, the path evaluated at the fine-interpolated path state.
    fn path_setpoint(
        &self,
        m: usize,
        tau: f64,
        time_s: f64,
        segments: &Range<usize>,
        range: Range<f64>,
        cursor: &mut Cursor,
    ) -> Setpoint {
        let mut state = self.samples().at(m, tau);
        state.s = state.s.clamp(range.start, range.end);
        let at_end = state.s >= range.end;
        self.on_path(time_s, segments.clone(), state, at_end, cursor)
    }

    /// A box (lower and upper corner, m) that holds the position of every setpoint: the start
    /// and the bounds of every segment (setpoints lie on the segments' geometry, dwells at
    /// their ends).
    pub fn bounds(&self) -> (Vector3<f64>, Vector3<f64>) {
        self.segments
            .iter()
            .map(|seg| seg.geometry.bounds())
            .fold((self.start, self.start), |(lo, hi), (a, b)| {
                (lo.inf(&a), hi.sup(&b))
            })
    }

    /// All setpoints from `t = 0` to the end, at the servo rate.
    pub fn iter(&self) -> impl Iterator<Item = Setpoint> + '_ {
        let mut cursor = Cursor::default();
        (0..self.servo_ticks()).filter_map(move |k| self.setpoint_from(k, &mut cursor))
    }

    /// For every executed block, in order: its index, and the times (s) at which the setpoint
    /// enters and leaves it (a dwell: from its start to its end on the IPO grid). Skipped
    /// zero-length blocks are not listed.
    pub fn block_times(&self) -> Vec<(usize, f64, f64)> {
        let mut times = Vec::with_capacity(self.segments.len());
        for item in &self.items {
            let t0 = item.start as f64 * self.ipo_period_s;
            match &item.activity {
                Activity::Dwell { dwell, .. } => {
                    times.push((dwell.block, t0, item.end as f64 * self.ipo_period_s));
                }
                Activity::Motion {
                    segments,
                    s_start,
                    profile,
                } => {
                    for seg in &self.segments[segments.clone()] {
                        let at = |s: f64| t0 + profile.filtered_time_at(self.window_s, s - s_start);
                        times.push((seg.block, at(seg.s_start), at(seg.s_end())));
                    }
                }
            }
        }
        times
    }

    fn ipo_ticks(&self) -> usize {
        self.items.last().map_or(0, |item| item.end)
    }

    fn rest(
        &self,
        time_s: f64,
        position: Vector3<f64>,
        block: Option<usize>,
        spindle: Spindle,
    ) -> Setpoint {
        Setpoint {
            time_s,
            position,
            velocity: Vector3::zeros(),
            acceleration: Vector3::zeros(),
            block,
            spindle,
        }
    }

    /// The ends of IPO interval `m` of a motion over `segments` and the path lengths `range`,
    /// if the axes are fine-interpolated over it: both on one segment, short of the motion's
    /// end, and the Hermite remainder within [`AXIS_HERMITE_TOLERANCE_M`] (module doc).
    fn axis_ends(
        &self,
        m: usize,
        segments: &Range<usize>,
        range: Range<f64>,
        cursor: &mut Cursor,
    ) -> Option<AxisEnds> {
        let samples = [self.samples().sample(m)?, self.samples().sample(m + 1)?];
        if !samples.iter().all(|e| range.contains(&e.s)) {
            return None;
        }
        let run = &self.segments[segments.clone()];
        let guess = cursor.segment.saturating_sub(segments.start);
        let [i0, i1] = samples.map(|e| partition_from(run.len(), guess, |j| run[j].s_end() <= e.s));
        let seg = run.get(i0).filter(|_| i0 == i1)?;
        let cubic = [self.samples().at(m, 0.0), self.samples().at(m, 1.0)];
        if remainder_bound(&seg.geometry, &cubic, self.ipo_period_s) > AXIS_HERMITE_TOLERANCE_M {
            return None;
        }
        // The start is the last interval's end when that one was fine-interpolated too.
        let start = match cursor.interval {
            Some(Interval {
                tick,
                ends: Some(e),
            }) if tick + 1 == m => (e.position[1], e.velocity[1]),
            _ => {
                let p = self.on_path(0.0, segments.clone(), samples[0], false, cursor);
                (p.position, p.velocity)
            }
        };
        let end = self.on_path(0.0, segments.clone(), samples[1], false, cursor);
        Some(AxisEnds {
            position: [start.0, end.position],
            velocity: [start.1, end.velocity],
            block: seg.block,
            spindle: seg.spindle,
        })
    }

    /// The setpoint at path state `state` on one of `segments` (at the end point of the last
    /// one if `at_end`).
    fn on_path(
        &self,
        time_s: f64,
        segments: Range<usize>,
        state: PathState,
        at_end: bool,
        cursor: &mut Cursor,
    ) -> Setpoint {
        let first = segments.start;
        let run = &self.segments[segments];
        let guess = cursor.segment.saturating_sub(first);
        let i = partition_from(run.len(), guess, |j| run[j].s_end() <= state.s).min(run.len() - 1);
        cursor.segment = first + i;
        let seg = &run[i];
        let local = if at_end {
            seg.geometry.length()
        } else {
            state.s - seg.s_start
        };
        let point = seg.geometry.point(local);
        Setpoint {
            time_s,
            position: point.position,
            velocity: point.tangent * state.v,
            acceleration: point.curvature * (state.v * state.v) + point.tangent * state.a,
            block: Some(seg.block),
            spindle: seg.spindle,
        }
    }

    /// The filtered path state at every IPO tick, sampled on first use.
    fn samples(&self) -> &IpoSamples {
        self.samples.get_or_init(|| self.sample_ipo())
    }

    /// Samples the filtered path state at every IPO tick.
    fn sample_ipo(&self) -> IpoSamples {
        let total = self.ipo_ticks();
        let mut samples = IpoSamples::with_capacity(self.ipo_period_s, total + 1);
        let mut last_s = 0.0;
        for item in &self.items {
            for k in item.start..item.end {
                let t = (k - item.start) as f64 * self.ipo_period_s;
                let (s, v) = match &item.activity {
                    Activity::Dwell { s, .. } => (*s, 0.0),
                    Activity::Motion {
                        s_start, profile, ..
                    } => {
                        let f = profile.filtered(self.window_s, t);
                        (s_start + f.s, f.v)
                    }
                };
                samples.push(s, v);
            }
            last_s = match &item.activity {
                Activity::Dwell { s, .. } => *s,
                Activity::Motion {
                    s_start, profile, ..
                } => s_start + profile.length,
            };
        }
        samples.push(last_s, 0.0);
        debug_assert_eq!(samples.len(), total + 1);
        samples
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nc::parse::parse;
    use proptest::prelude::*;

    fn config() -> InterpolatorConfig {
        InterpolatorConfig::new(Limits {
            rapid_m_s: 0.5,
            max_feed_m_s: 1.0,
            path_accel_m_s2: 2.0,
            path_jerk_m_s3: 40.0,
            axis_velocity_m_s: [1.0; 3],
            axis_accel_m_s2: [5.0; 3],
            corner_tolerance_m: 10e-6,
        })
    }

    /// Per block of `text` run from the origin, its fine-interpolated motion ticks and all its
    /// motion ticks, after checking every setpoint against the path evaluated at its path
    /// state: position within [`AXIS_HERMITE_TOLERANCE_M`], velocity and acceleration within
    /// Birkhoff and Priver's bounds for the cubic Hermite's derivatives (`√3/216 h³` and
    /// `h²/12` times max|d⁴p/dt⁴|, which the position's `h⁴/384` bounds), the same block and
    /// spindle.
    fn compare(text: &str) -> Vec<(usize, usize)> {
        let program = parse(text, Vector3::zeros()).expect("the program parses");
        let ipo = Interpolator::new(&program, &config()).expect("the program plans");
        let h = ipo.ipo_period_s;
        let d4 = AXIS_HERMITE_TOLERANCE_M * 384.0 / h.powi(4);
        let tolerance = [
            AXIS_HERMITE_TOLERANCE_M + 1e-15,
            3f64.sqrt() / 216.0 * h.powi(3) * d4 + 1e-12,
            h * h / 12.0 * d4 + 1e-9,
        ];
        let mut cursor = Cursor::default();
        let mut counts = vec![(0, 0); program.blocks.len()];
        for k in 0..ipo.servo_ticks() {
            let sp = ipo.setpoint_from(k, &mut cursor).expect("a setpoint");
            let item = &ipo.items[cursor.item.min(ipo.items.len() - 1)];
            let Activity::Motion {
                segments,
                s_start,
                profile,
            } = &item.activity
            else {
                continue;
            };
            let count = &mut counts[sp.block.expect("a motion's block")];
            count.0 += usize::from(cursor.interval.is_some_and(|i| i.ends.is_some()));
            count.1 += 1;
            let (m, r) = (k / ipo.ticks_per_ipo, k % ipo.ticks_per_ipo);
            let tau = r as f64 / ipo.ticks_per_ipo as f64;
            let range = *s_start..s_start + profile.length;
            let on_path =
                ipo.path_setpoint(m, tau, sp.time_s, segments, range, &mut Cursor::default());
            let errors = [
                (sp.position - on_path.position).norm(),
                (sp.velocity - on_path.velocity).norm(),
                (sp.acceleration - on_path.acceleration).norm(),
            ];
            for ((e, t), name) in errors
                .iter()
                .zip(tolerance)
                .zip(["position", "velocity", "acc"])
            {
                assert!(
                    e <= &t,
                    "tick {k}: {name} off the path by {e} (at most {t})"
                );
            }
            assert_eq!(
                (sp.block, sp.spindle),
                (on_path.block, on_path.spindle),
                "tick {k}"
            );
        }
        counts
    }

    /// A line out to `r` (mm) on X, a full circle, a helix rising `rise` mm, a line back.
    fn circles(r: f64, rise: f64, ccw: bool, feed: f64) -> String {
        let (g, back) = if ccw { ("G3", "G2") } else { ("G2", "G3") };
        format!(
            "G90 G17 G21 F{feed}\nG1 X{r} Y0 Z0\n{g} X{r} Y0 I{} J0\n\
             {back} X{r} Y0 Z{rise} I{} J0\nG1 X0 Y0 Z0\nM30\n",
            -r, -r
        )
    }

    #[test]
    fn the_iso_230_4_circle_is_fine_interpolated_by_axis_almost_throughout() {
        let (fine, ticks) = compare(&circles(150.0, 0.0, true, 1000.0))[1];
        assert!(fine as f64 > 0.999 * ticks as f64, "{fine} of {ticks}");
    }

    #[test]
    fn a_tight_arc_at_speed_is_evaluated_on_the_path() {
        // A 1 mm circle at 3 m/min: once it runs at speed the remainder bound is above 1 pm;
        // only the slow start and end are fine-interpolated by axis.
        let (fine, ticks) = compare(&circles(1.0, 0.0, false, 3000.0))[1];
        assert!((fine as f64) < 0.2 * ticks as f64, "{fine} of {ticks}");
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

        #[test]
        fn fine_interpolated_axes_stay_within_a_picometre_of_the_path(
            r in 0.5..200.0f64,
            rate in 100.0..3000.0f64,
            rise in -5.0..5.0f64,
            ccw: bool,
        ) {
            compare(&circles(r, rise, ccw, r * rate));
        }
    }
}
