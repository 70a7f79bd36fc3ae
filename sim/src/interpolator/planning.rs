//! Feed planning with look-ahead over one rest-to-rest motion (a *section*: the blocks between
//! two stops).
//!
//! 1. **Limits along the path.** Each segment gets a speed and tangential acceleration limit
//!    ([`super::feed_limits`]); each corner between two segments a junction speed
//!    ([`super::junction`]).
//! 2. **Filter margins.** The jerk filter averages the raw profile over `T_j`, so the filtered
//!    speed at a point of the path is the mean raw speed over positions up to `ṡ·T_j` away. A
//!    speed limit `v` (of a segment, or of a corner) is therefore extended by `v·T_j` on both
//!    sides: the raw profile runs at most at `v` over that zone, spends at least `T_j` in it on
//!    each side, and the filtered speed obeys `v` everywhere the limit applies (a corner is passed
//!    at its junction speed or below). The acceleration limit of a stretch run at speed `v` is the
//!    smallest of those within `v·T_j` of it.
//! 3. **Backward and forward passes** over the stretches of constant limits give the speed at
//!    each boundary: `w_k ≤ √(w_{k+1}² + 2 a_k L_k)` (backward, so every stretch can reach its
//!    exit speed) and `w_{k+1} ≤ √(w_k² + 2 a_k L_k)` (forward), from rest to rest. Each stretch
//!    then accelerates, cruises at `min(v_k, √(a_k L_k + (w_k² + w_{k+1}²)/2))` and decelerates.
//! 4. **Jerk-filter condition.** The filtered jerk `(s̈(t) − s̈(t − T_j)) / T_j` stays within
//!    `a_max / T_j ≤ j_max` only if no window `T_j` holds both an accelerating and a decelerating
//!    phase. Valleys meet this by step 2 (they sit on a limit held for `2 T_j`); where a peak
//!    turns from acceleration to deceleration in less than `T_j`, the speed is capped at the
//!    level `v'` whose plateau `{s : v(s) ≥ v'}` lasts `T_j` at `v'` (bisection); a valley left
//!    too short by rounding is held at its speed for `T_j`. The passes are then run again.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use super::InterpolatorError;
use super::config::Limits;
use super::feed_limits::{FeedLimits, segment_limits};
use super::path::Segment;
use super::profile::{Phase, RawProfile};

/// Boundaries closer than this (m) are merged.
const SAME_POINT_M: f64 = 1e-12;
/// Relative margin by which a capped plateau exceeds the filter window.
const PLATEAU_MARGIN: f64 = 1e-6;
/// Relative slack when checking the jerk-filter condition.
const CHECK_SLACK: f64 = 1e-9;
/// Accelerating or decelerating phases shorter than this (s) are rounding, not motion.
const NEGLIGIBLE_PHASE_S: f64 = 1e-9;
/// Rounds of capping before giving up.
const MAX_ROUNDS: usize = 32;

/// A stretch of path with constant limits, in section coordinates (m).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Piece {
    s0: f64,
    s1: f64,
    limits: FeedLimits,
}

/// A speed limit over `[lo, hi]` (m).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Zone {
    lo: f64,
    hi: f64,
    speed: f64,
}

/// A place where the raw profile turns between acceleration and deceleration within one window.
#[derive(Clone, Copy, Debug)]
struct Turn {
    /// Accelerating then decelerating (a peak), or the other way round (a valley).
    peak: bool,
    /// Index of the phase before the turn.
    left: usize,
    /// Index of the phase after the turn.
    right: usize,
}

/// Plans the raw (acceleration-limited) profile of the rest-to-rest motion over `segments`,
/// with `corners[k]` the junction speed between `segments[k]` and `segments[k + 1]` (m/s) and
/// `window` the jerk filter window `T_j` (s).
pub(crate) fn plan_section(
    segments: &[Segment],
    corners: &[f64],
    limits: &Limits,
    window: f64,
) -> Result<RawProfile, InterpolatorError> {
    let Some(first) = segments.first() else {
        return Ok(RawProfile::default());
    };
    let bases = base_pieces(segments, limits);
    let mut pieces = margined_pieces(&bases, corners, window);
    for _ in 0..MAX_ROUNDS {
        let profile = profile_of(&pieces);
        let turns = short_turns(&profile, window);
        if turns.is_empty() {
            return Ok(profile);
        }
        let caps: Vec<Zone> = turns.iter().map(|t| cap(&profile, t, window)).collect();
        pieces = apply_caps(&pieces, &caps);
    }
    Err(InterpolatorError::Planning {
        line: first.span.line,
    })
}

/// One piece per segment, in section coordinates.
fn base_pieces(segments: &[Segment], limits: &Limits) -> Vec<Piece> {
    let origin = segments.first().map_or(0.0, |s| s.s_start);
    segments
        .iter()
        .map(|seg| Piece {
            s0: seg.s_start - origin,
            s1: seg.s_end() - origin,
            limits: segment_limits(seg, limits),
        })
        .collect()
}

/// Speed zones: every piece and corner limit widened by `v·window` on both sides.
fn zones(bases: &[Piece], corners: &[f64], window: f64) -> Vec<Zone> {
    let widen = |lo: f64, hi: f64, speed: f64| Zone {
        lo: lo - speed * window,
        hi: hi + speed * window,
        speed,
    };
    let pieces = bases.iter().map(|p| widen(p.s0, p.s1, p.limits.speed));
    let joints = bases.iter().zip(corners).filter(|(_, v)| v.is_finite());
    pieces
        .chain(joints.map(|(p, &v)| widen(p.s1, p.s1, v)))
        .collect()
}

/// Sorted, de-duplicated cut points in `[0, length]`.
fn cut_points(mut points: Vec<f64>, length: f64) -> Vec<f64> {
    points.retain(|x| *x > 0.0 && *x < length);
    points.push(0.0);
    points.push(length);
    points.sort_by(f64::total_cmp);
    let mut cuts: Vec<f64> = Vec::with_capacity(points.len());
    for x in points {
        match cuts.last() {
            Some(&last) if x - last < SAME_POINT_M => {}
            _ => cuts.push(x),
        }
    }
    if let Some(last) = cuts.last_mut() {
        *last = length;
    }
    cuts
}

/// The pieces with the filter margins of step 2 applied.
fn margined_pieces(bases: &[Piece], corners: &[f64], window: f64) -> Vec<Piece> {
    let length = bases.last().map_or(0.0, |p| p.s1);
    let mut zones = zones(bases, corners, window);
    let mut points: Vec<f64> = bases.iter().map(|p| p.s1).collect();
    points.extend(zones.iter().flat_map(|z| [z.lo, z.hi]));
    let cuts = cut_points(points, length);
    zones.sort_by(|a, b| a.lo.total_cmp(&b.lo));
    let accels = RangeMin::new(bases.iter().map(|p| p.limits.accel).collect());
    // Sweep: the zones that have begun, slowest first; those already ended are dropped lazily.
    let mut active: BinaryHeap<Slowest> = BinaryHeap::new();
    let mut next = 0;
    let mut pieces: Vec<Piece> = Vec::with_capacity(cuts.len());
    for pair in cuts.windows(2) {
        let (s0, s1) = (pair[0], pair[1]);
        let mid = 0.5 * (s0 + s1);
        while next < zones.len() && zones[next].lo <= mid {
            active.push(Slowest(zones[next]));
            next += 1;
        }
        while active.peek().is_some_and(|z| z.0.hi < mid) {
            active.pop();
        }
        let speed = active.peek().map_or(f64::INFINITY, |z| z.0.speed);
        let (lo, hi) = (s0 - speed * window, s1 + speed * window);
        let first = bases.partition_point(|p| p.s1 <= lo);
        let last = bases.partition_point(|p| p.s0 < hi).max(first + 1);
        let accel = accels.min(first.min(bases.len() - 1), last.min(bases.len()));
        push_merged(
            &mut pieces,
            Piece {
                s0,
                s1,
                limits: FeedLimits { speed, accel },
            },
        );
    }
    pieces
}

/// A zone ordered so that the slowest is the greatest (for a max-heap).
#[derive(Clone, Copy, Debug)]
struct Slowest(Zone);

impl PartialEq for Slowest {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Slowest {}

impl PartialOrd for Slowest {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Slowest {
    fn cmp(&self, other: &Self) -> Ordering {
        other.0.speed.total_cmp(&self.0.speed)
    }
}

/// Minimum over index ranges of a fixed list (sparse table: `O(n log n)` build, `O(1)` query).
struct RangeMin {
    levels: Vec<Vec<f64>>,
}

impl RangeMin {
    fn new(values: Vec<f64>) -> Self {
        let mut levels = vec![values];
        let mut span = 1;
        while let Some(prev) = levels.last().filter(|l| l.len() > span) {
            let next = (0..prev.len() - span)
                .map(|i| prev[i].min(prev[i + span]))
                .collect();
            levels.push(next);
            span *= 2;
        }
        RangeMin { levels }
    }

    /// Minimum over `first..last` (infinity when empty).
    fn min(&self, first: usize, last: usize) -> f64 {
        if last <= first {
            return f64::INFINITY;
        }
        let level = (usize::BITS - 1 - (last - first).leading_zeros()) as usize;
        let row = &self.levels[level];
        row[first].min(row[last - (1 << level)])
    }
}

/// Appends `piece`, merging it with the last one when their limits are equal.
fn push_merged(pieces: &mut Vec<Piece>, piece: Piece) {
    match pieces.last_mut() {
        Some(last) if last.limits == piece.limits => last.s1 = piece.s1,
        _ => pieces.push(piece),
    }
}

/// Boundary speeds (m/s) from the backward and forward passes, from rest to rest.
fn boundary_speeds(pieces: &[Piece]) -> Vec<f64> {
    let n = pieces.len();
    let mut w = vec![0.0; n + 1];
    for k in 1..n {
        w[k] = pieces[k - 1].limits.speed.min(pieces[k].limits.speed);
    }
    let reach = |v: f64, p: &Piece| (v * v + 2.0 * p.limits.accel * (p.s1 - p.s0)).sqrt();
    for k in (0..n).rev() {
        w[k] = w[k].min(reach(w[k + 1], &pieces[k]));
    }
    for k in 0..n {
        w[k + 1] = w[k + 1].min(reach(w[k], &pieces[k]));
    }
    w
}

/// The raw profile: each piece accelerates, cruises and decelerates between its boundary speeds.
fn profile_of(pieces: &[Piece]) -> RawProfile {
    let w = boundary_speeds(pieces);
    let mut phases = Vec::with_capacity(3 * pieces.len());
    let mut t = 0.0;
    for (k, piece) in pieces.iter().enumerate() {
        let (w0, w1) = (w[k], w[k + 1]);
        let (a, length) = (piece.limits.accel, piece.s1 - piece.s0);
        let top = (a * length + 0.5 * (w0 * w0 + w1 * w1)).sqrt();
        let vp = piece.limits.speed.min(top).max(w0).max(w1);
        let d_acc = ((vp * vp - w0 * w0) / (2.0 * a)).max(0.0);
        let d_dec = ((vp * vp - w1 * w1) / (2.0 * a)).max(0.0);
        let d_cruise = (length - d_acc - d_dec).max(0.0);
        let mut push = |dt: f64, s0: f64, v0: f64, a: f64| {
            if dt > 0.0 {
                phases.push(Phase { t0: t, s0, v0, a });
                t += dt;
            }
        };
        push((vp - w0) / a, piece.s0, w0, a);
        if vp > 0.0 {
            push(d_cruise / vp, piece.s0 + d_acc, vp, 0.0);
        }
        push((vp - w1) / a, piece.s0 + d_acc + d_cruise, vp, -a);
    }
    RawProfile {
        phases,
        duration: t,
        length: pieces.last().map_or(0.0, |p| p.s1),
    }
}

/// Turns between acceleration and deceleration less than `window` apart.
fn short_turns(profile: &RawProfile, window: f64) -> Vec<Turn> {
    let mut turns = Vec::new();
    let mut last: Option<(f64, usize, f64)> = None;
    for (i, phase) in profile.phases.iter().enumerate() {
        let end = profile.phase_end(i);
        if phase.a == 0.0 || end - phase.t0 < NEGLIGIBLE_PHASE_S {
            continue;
        }
        let sign = phase.a.signum();
        if let Some((last_sign, left, last_end)) = last
            && last_sign != sign
            && phase.t0 - last_end < window * (1.0 - CHECK_SLACK)
        {
            turns.push(Turn {
                peak: last_sign > 0.0,
                left,
                right: i,
            });
        }
        last = Some((sign, i, end));
    }
    turns
}

/// The speed cap that gives the turn a plateau of one window.
fn cap(profile: &RawProfile, turn: &Turn, window: f64) -> Zone {
    let target = window * (1.0 + PLATEAU_MARGIN);
    let level = profile.phase_end_speed(turn.left);
    if !turn.peak {
        let s_a = profile.phases[turn.left + 1].s0;
        let s_b = profile.phases[turn.right].s0;
        let (centre, half) = (0.5 * (s_a + s_b), 0.5 * level * target);
        return Zone {
            lo: centre - half,
            hi: centre + half,
            speed: level,
        };
    }
    let plateau = |v: f64| {
        let (lo, hi) = plateau_bounds(profile, turn, v);
        (hi - lo) / v
    };
    let (mut lo, mut hi) = (0.0, level);
    for _ in 0..64 {
        let mid = 0.5 * (lo + hi);
        if plateau(mid) >= target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let (s_lo, s_hi) = plateau_bounds(profile, turn, lo);
    Zone {
        lo: s_lo,
        hi: s_hi,
        speed: lo,
    }
}

/// The stretch of path around the peak `turn` where the speed is at least `level`.
fn plateau_bounds(profile: &RawProfile, turn: &Turn, level: f64) -> (f64, f64) {
    let phases = &profile.phases;
    let at_level = |p: &Phase| p.s0 + (level * level - p.v0 * p.v0) / (2.0 * p.a);
    let lo = phases[..=turn.left]
        .iter()
        .rev()
        .find(|p| p.v0 < level)
        .map_or(0.0, |p| if p.a > 0.0 { at_level(p) } else { p.s0 });
    let hi = (turn.right..phases.len())
        .find(|&j| profile.phase_end_speed(j) < level)
        .map_or(profile.length, |j| {
            let p = &phases[j];
            if p.a < 0.0 { at_level(p) } else { p.s0 }
        });
    (lo, hi)
}

/// The pieces with the caps applied (split at the cap ends, speed lowered inside).
fn apply_caps(pieces: &[Piece], caps: &[Zone]) -> Vec<Piece> {
    let length = pieces.last().map_or(0.0, |p| p.s1);
    let mut points: Vec<f64> = pieces.iter().map(|p| p.s1).collect();
    points.extend(caps.iter().flat_map(|c| [c.lo, c.hi]));
    let cuts = cut_points(points, length);
    let mut out: Vec<Piece> = Vec::with_capacity(cuts.len());
    for pair in cuts.windows(2) {
        let mid = 0.5 * (pair[0] + pair[1]);
        let k = pieces
            .partition_point(|p| p.s1 <= mid)
            .min(pieces.len() - 1);
        let mut limits = pieces[k].limits;
        for c in caps.iter().filter(|c| c.lo <= mid && mid <= c.hi) {
            limits.speed = limits.speed.min(c.speed);
        }
        push_merged(
            &mut out,
            Piece {
                s0: pair[0],
                s1: pair[1],
                limits,
            },
        );
    }
    out
}
