//! ISO 230-4:2022 figures of a circular test.
//!
//! With the deviation `Δr(θ)` (measured minus nominal radius, µm) and a centre offset `(a, b)`
//! (µm, the path centre relative to the pivot), the radial deviation from a circle about that
//! centre is `e(θ) = Δr(θ) − a cos θ − b sin θ`. The least-squares centre minimises `Σ (e − r₀)²`,
//! which to first order in `(a, b)/R` is the linear fit `Δr ≈ r₀ + a cos θ + b sin θ`
//! (the standard's least-squares circle, ISO 230-4 3.4 and Annex; Kwon 1998 "best fitting
//! circle"). Then, per direction:
//!
//! - circular deviation `G = max e − min e` (3.5), about the least-squares centre;
//! - radial deviation `F_max = max e`, `F_min = min e` from the nominal radius (3.7);
//! - bidirectional circular deviation `G(b)`: `max − min` of `e` over both directions about their
//!   common least-squares centre (3.6);
//! - circular hysteresis `H`: the largest radial difference between the CW and CCW paths at the
//!   same angle (3.8), where both cover that angle;
//! - minimum-zone circular deviation (optional): `min over (a, b) of max e − min e`, the width of
//!   the thinnest concentric annulus that holds the path; a convex problem solved here by
//!   Nelder–Mead from the least-squares centre to 1e-6 µm.

use crate::trace::Trace;
use serde::Serialize;

/// A least-squares circle: centre offset of the path (µm) and radius offset (µm).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Circle {
    /// Path centre along the plane's first axis relative to the pivot, µm.
    pub centre_p_um: f64,
    /// Path centre along the plane's second axis, µm.
    pub centre_q_um: f64,
    /// Mean radius minus nominal, µm.
    pub radius_offset_um: f64,
}

impl Circle {
    /// Radial deviation of a sample from this circle's centre (not its radius), µm.
    pub fn radial(&self, theta: f64, deviation_um: f64) -> f64 {
        self.radial_cs(theta.cos(), theta.sin(), deviation_um)
    }

    /// [`Circle::radial`] with cos θ and sin θ given.
    #[inline]
    pub fn radial_cs(&self, cos: f64, sin: f64, deviation_um: f64) -> f64 {
        deviation_um - self.centre_p_um * cos - self.centre_q_um * sin
    }
}

/// A trace with cos θ and sin θ of its samples (computed once, see [`crate::samples::trig`]).
struct Arc<'a> {
    t: &'a Trace,
    cos: std::borrow::Cow<'a, [f64]>,
    sin: std::borrow::Cow<'a, [f64]>,
}

impl<'a> Arc<'a> {
    fn new(t: &'a Trace) -> Self {
        let (cos, sin) = crate::samples::trig(&t.angle_deg);
        Self {
            t,
            cos: cos.into(),
            sin: sin.into(),
        }
    }

    /// (cos θ, sin θ, deviation) of every sample.
    fn samples(&self) -> impl Iterator<Item = (f64, f64, f64)> + '_ {
        self.cos
            .iter()
            .zip(self.sin.iter())
            .zip(&self.t.deviation_um)
            .map(|((c, s), d)| (*c, *s, *d))
    }
}

/// The least-squares circle of one or more traces together.
pub fn least_squares_circle(traces: &[&Trace]) -> Circle {
    let arcs: Vec<Arc> = traces.iter().map(|t| Arc::new(t)).collect();
    circle_of(&arcs.iter().collect::<Vec<_>>())
}

/// Partial sums advanced side by side in [`circle_sums`] (which the compiler keeps in vector
/// registers; one running sum would wait on each addition).
const LANES: usize = 4;

/// The sums of the least-squares circle's normal equations over one arc: the upper triangle of
/// Σ (1, c, s)ᵀ(1, c, s) and Σ d (1, c, s), each in [`LANES`] partial sums.
fn circle_sums(arc: &Arc) -> [f64; 9] {
    let (cos, sin, dev) = (&arc.cos[..], &arc.sin[..], &arc.t.deviation_um[..]);
    // Σ c, Σ s, Σ c², Σ cs, Σ s², Σ d, Σ dc, Σ ds, lane by lane.
    let mut l = [[0.0; LANES]; 8];
    let blocks = cos
        .chunks_exact(LANES)
        .zip(sin.chunks_exact(LANES))
        .zip(dev.chunks_exact(LANES));
    for ((c, s), d) in blocks {
        for j in 0..LANES {
            l[0][j] += c[j];
            l[1][j] += s[j];
            l[2][j] += c[j] * c[j];
            l[3][j] += c[j] * s[j];
            l[4][j] += s[j] * s[j];
            l[5][j] += d[j];
            l[6][j] += d[j] * c[j];
            l[7][j] += d[j] * s[j];
        }
    }
    let rest = cos.len() / LANES * LANES;
    for (i, (c, s, d)) in arc.samples().enumerate().skip(rest) {
        let j = i - rest;
        for (lane, t) in l
            .iter_mut()
            .zip([c, s, c * c, c * s, s * s, d, d * c, d * s])
        {
            lane[j] += t;
        }
    }
    let mut m = [0.0; 9];
    m[0] = cos.len() as f64;
    for (m, lane) in m[1..].iter_mut().zip(&l) {
        *m = lane.iter().sum();
    }
    m
}

fn circle_of(arcs: &[&Arc]) -> Circle {
    circle_of_sums(&arcs.iter().map(|a| circle_sums(a)).collect::<Vec<_>>())
}

fn circle_of_sums(sums: &[[f64; 9]]) -> Circle {
    let mut m = [0.0; 9];
    for s in sums {
        for (a, b) in m.iter_mut().zip(s) {
            *a += b;
        }
    }
    let ata = nalgebra::Matrix3::new(m[0], m[1], m[2], m[1], m[3], m[4], m[2], m[4], m[5]);
    let aty = nalgebra::Vector3::new(m[6], m[7], m[8]);
    // A trace of at least a few degrees makes the 3×3 system regular; validation ensures it.
    let x = ata
        .try_inverse()
        .map_or(nalgebra::Vector3::zeros(), |inv| inv * aty);
    Circle {
        centre_p_um: x[1],
        centre_q_um: x[2],
        radius_offset_um: x[0],
    }
}

/// ISO 230-4 figures of one direction.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Directional {
    /// Label of the trace.
    pub label: String,
    /// `cw` or `ccw`.
    pub sense: String,
    /// Angle swept by the samples the figures take, deg.
    pub sweep_deg: f64,
    /// The trace's whole sweep when it ran on past one revolution, deg: the figures take its
    /// first 360° (see [`one_revolution`]).
    pub recorded_sweep_deg: Option<f64>,
    /// Least-squares circle.
    pub circle: Circle,
    /// Circular deviation G, µm.
    pub circular_deviation_um: f64,
    /// Largest radial deviation F_max, µm.
    pub radial_deviation_max_um: f64,
    /// Smallest radial deviation F_min, µm.
    pub radial_deviation_min_um: f64,
    /// Minimum-zone circular deviation, µm, when asked for.
    pub minimum_zone_um: Option<f64>,
}

/// ISO 230-4 figures of a test.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Figures {
    /// Per direction.
    pub directions: Vec<Directional>,
    /// Bidirectional circular deviation G(b), µm, with both directions.
    pub bidirectional_deviation_um: Option<f64>,
    /// Circular hysteresis H, µm, with both directions.
    pub hysteresis_um: Option<f64>,
}

/// The figures of the traces of one test (one or two directions).
pub fn figures(traces: &[&Trace], minimum_zone: bool) -> Figures {
    let trig: Vec<(Vec<f64>, Vec<f64>)> = traces
        .iter()
        .map(|t| crate::samples::trig(&t.angle_deg))
        .collect();
    let refs: Vec<(&[f64], &[f64])> = trig
        .iter()
        .map(|(c, s)| (c.as_slice(), s.as_slice()))
        .collect();
    figures_with_trig(traces, &refs, minimum_zone)
}

/// [`figures`] with cos θ and sin θ of every sample of each trace already computed.
pub fn figures_with_trig(
    traces: &[&Trace],
    trig: &[(&[f64], &[f64])],
    minimum_zone: bool,
) -> Figures {
    let trimmed: Vec<Option<Trace>> = traces.iter().copied().map(one_revolution).collect();
    let arcs: Vec<Arc> = traces
        .iter()
        .zip(&trimmed)
        .zip(trig)
        .map(|((t, cut), (c, s))| {
            let t = cut.as_ref().unwrap_or(t);
            let n = t.angle_deg.len();
            Arc {
                t,
                cos: c[..n].into(),
                sin: s[..n].into(),
            }
        })
        .collect();
    let mut figures = figures_of(&arcs, minimum_zone);
    for ((d, t), cut) in figures.directions.iter_mut().zip(traces).zip(&trimmed) {
        d.recorded_sweep_deg = cut.as_ref().map(|_| t.sweep_deg());
    }
    figures
}

/// The first revolution of a trace that runs on past 360° (a CSV with its overshoot kept, or a
/// second lap), or `None` for one within a revolution: ISO 230-4 evaluates the circle once,
/// and the overlap would count twice in the least-squares centre and in G. The angles are
/// unwrapped and monotonic (checked); the revolution holds the samples within 360° of the
/// first.
pub fn one_revolution(t: &Trace) -> Option<Trace> {
    let (a0, last) = (*t.angle_deg.first()?, *t.angle_deg.last()?);
    let past = |a: &f64| (a - a0).abs() > 360.0 + 1e-9;
    if !past(&last) {
        return None;
    }
    let n = t.angle_deg.iter().position(past)?;
    let mut one = t.clone();
    one.angle_deg.truncate(n);
    one.deviation_um.truncate(n);
    if let Some(time) = one.time_s.as_mut() {
        time.truncate(n);
    }
    Some(one)
}

fn figures_of(arcs: &[Arc], minimum_zone: bool) -> Figures {
    let sums: Vec<[f64; 9]> = arcs.iter().map(circle_sums).collect();
    let both = arcs.len() == 2 && arcs[0].t.sense != arcs[1].t.sense;
    let common = both.then(|| circle_of_sums(&sums));
    let mut lo_hi = (f64::INFINITY, f64::NEG_INFINITY);
    let mut blocks = Vec::new();
    let directions = arcs
        .iter()
        .zip(&sums)
        .map(|(a, s)| {
            let own = circle_of_sums(std::slice::from_ref(s));
            let (bounds, about_common, b) = radial_bounds(a, own, common.unwrap_or(own));
            blocks.push(b);
            lo_hi = (lo_hi.0.min(about_common.0), lo_hi.1.max(about_common.1));
            directional(a, own, bounds, minimum_zone)
        })
        .collect();
    Figures {
        directions,
        bidirectional_deviation_um: common.map(|_| lo_hi.1 - lo_hi.0),
        hysteresis_um: common
            .and_then(|c| hysteresis(&arcs[0], &blocks[0], &arcs[1], &c))
            .filter(|h| h.is_finite()),
    }
}

fn directional(a: &Arc, circle: Circle, (lo, hi): (f64, f64), minimum_zone: bool) -> Directional {
    let t = a.t;
    Directional {
        label: t.label.clone(),
        sense: t.sense.name().into(),
        sweep_deg: t.sweep_deg(),
        recorded_sweep_deg: None,
        circle,
        circular_deviation_um: hi - lo,
        radial_deviation_max_um: hi,
        radial_deviation_min_um: lo,
        minimum_zone_um: minimum_zone.then(|| minimum_zone_deviation(a, &circle)),
    }
}

fn radial(a: &Arc, c: &Circle) -> Vec<f64> {
    a.samples()
        .map(|(co, s, d)| c.radial_cs(co, s, d))
        .collect()
}

/// (min, max) of the radial deviation of `a` about `own` and about `common`, and the
/// [`Extremes`] of each block of [`BLOCK`] samples about `common`, in one pass.
fn radial_bounds(a: &Arc, own: Circle, common: Circle) -> (Bounds, Bounds, Vec<Extremes>) {
    let (mut about_own, mut about_common) = (EMPTY, EMPTY);
    let n = a.t.angle_deg.len();
    let blocks = (0..n)
        .step_by(BLOCK)
        .map(|i| {
            let r = i..(i + BLOCK).min(n);
            let (t, d) = (&a.t.angle_deg[r.clone()], &a.t.deviation_um[r.clone()]);
            let (cos, sin) = (&a.cos[r.clone()], &a.sin[r]);
            let (mut x, mut b) = (EMPTY, Extremes { e: EMPTY, t: EMPTY });
            for j in 0..t.len() {
                widen(&mut x, own.radial_cs(cos[j], sin[j], d[j]));
                widen(&mut b.e, common.radial_cs(cos[j], sin[j], d[j]));
                widen(&mut b.t, t[j]);
            }
            about_own = (about_own.0.min(x.0), about_own.1.max(x.1));
            about_common = (about_common.0.min(b.e.0), about_common.1.max(b.e.1));
            b
        })
        .collect();
    (about_own, about_common, blocks)
}

/// (min, max) of some values.
type Bounds = (f64, f64);

/// The bounds of no values.
const EMPTY: Bounds = (f64::INFINITY, f64::NEG_INFINITY);

/// Widens `b` to hold `x` (by comparisons, which the compiler keeps in vector registers).
#[inline]
fn widen(b: &mut Bounds, x: f64) {
    b.0 = if x < b.0 { x } else { b.0 };
    b.1 = if x > b.1 { x } else { b.1 };
}

/// The extremes of a block of samples: radial deviation about the common centre and angle.
#[derive(Clone, Copy, Debug)]
struct Extremes {
    e: Bounds,
    t: Bounds,
}

fn bounds(v: &[f64]) -> (f64, f64) {
    v.iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
            (lo.min(*x), hi.max(*x))
        })
}

fn span(v: &[f64]) -> f64 {
    let (lo, hi) = bounds(v);
    hi - lo
}

/// `x.rem_euclid(360.0)`, bit for bit, without the division or a conversion to an integer:
/// `x − 360 k` is exact for the integer k = ⌊x/360⌋, which the quotient by the reciprocal gives
/// to within one either way (corrected after).
#[inline]
fn rem360(x: f64) -> f64 {
    let q = x * (1.0 / 360.0);
    if q.abs() >= 1e15 {
        return x.rem_euclid(360.0);
    }
    const MAGIC: f64 = 6_755_399_441_055_744.0; // 1.5·2⁵²: adding it rounds to an integer
    let mut k = (q + MAGIC) - MAGIC;
    if k > q {
        k -= 1.0;
    }
    let r = x - 360.0 * k;
    if r < 0.0 {
        x - 360.0 * (k - 1.0)
    } else if r >= 360.0 {
        x - 360.0 * (k + 1.0)
    } else {
        r
    }
}

/// (angle in [0, 360), e about `c`) of each sample of `a`, appended to `p`.
fn extend_path(p: &mut Path, a: &Arc, c: &Circle) {
    let (angle, dev) = (&a.t.angle_deg[..], &a.t.deviation_um[..]);
    let blocks = angle
        .chunks(BLOCK)
        .zip(dev.chunks(BLOCK))
        .zip(a.cos.chunks(BLOCK).zip(a.sin.chunks(BLOCK)));
    let mut turn = [0.0; BLOCK];
    for ((x, d), (co, s)) in blocks {
        let turn = &mut turn[..x.len()];
        if !within_one_turn(x, turn) {
            for (t, x) in turn.iter_mut().zip(x) {
                *t = rem360(*x);
            }
        }
        let e = (co.iter().zip(s))
            .zip(d)
            .map(|((co, s), d)| c.radial_cs(*co, *s, *d));
        p.extend(turn.iter().copied().zip(e));
    }
}

/// [`rem360`] of every angle of `x` into `out` when all of them lie in [−360, 360) (a run
/// from 0° either way): x, or x + 360 below 0, which is what [`rem360`] gives there, bit for
/// bit, as long as x + 360 rounds below 360. False when an angle lies outside (`out` left
/// partly written), by one loop without branches.
fn within_one_turn(x: &[f64], out: &mut [f64]) -> bool {
    let mut ok = true;
    for (o, x) in out.iter_mut().zip(x) {
        *o = if *x < 0.0 { x + 360.0 } else { *x };
        ok &= (*x >= -360.0) & (*o < 360.0);
    }
    ok
}

/// A path as (angle, radial deviation) pairs.
type Path = Vec<(f64, f64)>;

thread_local! {
    /// The sorted path of [`hysteresis`], reused between calls on a thread.
    static PATH: std::cell::RefCell<Path> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Largest |e_a(θ) − e_b(θ)| at the angles of `a` that `b` covers (linear interpolation of b).
/// The path of `b` is sorted by angle (stably: a trace is a few monotonic runs, which the sort
/// merges in linear time). The samples of `a` are taken in blocks, each with a bound on the
/// differences in it from the extremes of e_a and of the samples of `b` it can fall between:
/// blocks are evaluated largest bound first, until the bound falls below the largest difference
/// found (the rest cannot hold the maximum, which is the same value, computed the same way).
fn hysteresis(a: &Arc, blocks: &[Extremes], b: &Arc, c: &Circle) -> Option<f64> {
    PATH.with(|cell| {
        let pb = &mut *cell.borrow_mut();
        pb.clear();
        extend_path(pb, b, c);
        sort_by_angle(pb);
        let n = a.t.angle_deg.len();
        let mut order: Vec<(f64, usize)> = blocks
            .iter()
            .enumerate()
            .map(|(j, x)| (block_bound(x, pb), j * BLOCK))
            .collect();
        order.sort_unstable_by(|x, y| y.0.total_cmp(&x.0));
        let (mut worst, mut found) = (0.0f64, false);
        for (bound, i) in order {
            if bound < worst {
                break;
            }
            if let Some(w) = block_worst(a, c, pb, i..(i + BLOCK).min(n)) {
                worst = worst.max(w);
                found = true;
            }
        }
        found.then_some(worst)
    })
}

/// Sorts a path by angle as a stable sort in `total_cmp` order does, passing over it when it
/// is sorted already (a run in one sense starting at 0°): one loop without branches counts
/// the pairs out of order and the angles with their sign bit set (−0, which that order puts
/// before +0). The angles are finite (the traces are validated).
fn sort_by_angle(p: &mut Path) {
    let mut bad = u64::from(p.first().is_some_and(|x| x.0.is_sign_negative()));
    for w in p.windows(2) {
        bad += u64::from(w[0].0 > w[1].0) + u64::from(w[1].0.is_sign_negative());
    }
    if bad > 0 {
        p.sort_by(|x, y| x.0.total_cmp(&y.0));
    }
}

/// Samples per block of [`radial_bounds`] and [`hysteresis`].
const BLOCK: usize = 64;

/// An upper bound of the differences [`block_worst`] finds for a block of samples with the
/// extremes `x` (−∞ when none of them falls between two samples of `b`; +∞ when their angles
/// wrap round). Interpolation stays between the two samples of `b` to a few ulps, which the
/// margin covers.
fn block_bound(x: &Extremes, pb: &[(f64, f64)]) -> f64 {
    // rem360 is exact, so monotonic within a turn; the ends in one turn hold the block in it.
    let (x_lo, x_hi) = (rem360(x.t.0), rem360(x.t.1));
    if x_lo > x_hi || x.t.1 - x.t.0 >= 360.0 {
        return f64::INFINITY;
    }
    // Every sample's neighbours are pb[k − 1] and pb[k] with k between those of the ends.
    let first = pb.partition_point(|q| q.0 < x_lo).max(1);
    let last = pb
        .partition_point(|q| q.0 < x_hi)
        .min(pb.len().saturating_sub(1));
    if first > last {
        return f64::NEG_INFINITY;
    }
    let mut b = EMPTY;
    for q in &pb[first - 1..=last] {
        widen(&mut b, q.1);
    }
    let (e, b) = (x.e, b);
    let margin = 1e-12 * (e.0.abs() + e.1.abs() + b.0.abs() + b.1.abs());
    (e.1 - b.0).max(b.1 - e.0) + margin
}

/// The largest |e_a − e_b| over the samples `range` of `a` that fall between two samples of
/// the sorted path `pb` at most two gaps apart, None when none does.
fn block_worst(
    a: &Arc,
    c: &Circle,
    pb: &[(f64, f64)],
    range: std::ops::Range<usize>,
) -> Option<f64> {
    let max_step = 2.0 * crate::trace::MAX_GAP_DEG;
    let (mut worst, mut found) = (0.0f64, false);
    let mut k = 0;
    let (t, d) = (
        &a.t.angle_deg[range.clone()],
        &a.t.deviation_um[range.clone()],
    );
    let (cos, sin) = (&a.cos[range.clone()], &a.sin[range]);
    for (((t, co), s), d) in t.iter().zip(cos).zip(sin).zip(d) {
        let (x, e) = (rem360(*t), c.radial_cs(*co, *s, *d));
        k = first_at_or_after(pb, x, k);
        if k == 0 || k == pb.len() {
            continue;
        }
        let (lo, hi) = (pb[k - 1], pb[k]);
        if hi.0 - lo.0 > max_step {
            continue;
        }
        let w = if hi.0 > lo.0 {
            (x - lo.0) / (hi.0 - lo.0)
        } else {
            0.0
        };
        let eb = lo.1 + w * (hi.1 - lo.1);
        worst = worst.max((e - eb).abs());
        found = true;
    }
    found.then_some(worst)
}

/// The index of the first element of the sorted path `p` at or after angle `x`, stepping from
/// `k` (the previous sample's) when it is a few steps away, else by bisection (where `a` wraps
/// round).
#[inline]
fn first_at_or_after(p: &[(f64, f64)], x: f64, mut k: usize) -> usize {
    for _ in 0..8 {
        if k < p.len() && p[k].0 < x {
            k += 1;
        } else if k > 0 && p[k - 1].0 >= x {
            k -= 1;
        } else {
            return k;
        }
    }
    p.partition_point(|q| q.0 < x)
}

/// Minimum-zone circular deviation of an arc, µm, starting from the least-squares centre `c`.
fn minimum_zone_deviation(a: &Arc, c: &Circle) -> f64 {
    let trig: Vec<(f64, f64, f64)> = a.samples().collect();
    let zone = |x: [f64; 2]| {
        let (lo, hi) = trig.iter().fold(
            (f64::INFINITY, f64::NEG_INFINITY),
            |(lo, hi), (co, s, d)| {
                let e = d - x[0] * co - x[1] * s;
                (lo.min(e), hi.max(e))
            },
        );
        hi - lo
    };
    let start = [c.centre_p_um, c.centre_q_um];
    let scale = span(&radial(a, c)).max(1e-3);
    nelder_mead(zone, start, 0.1 * scale, 1e-6)
}

/// Nelder–Mead minimisation of a function of two variables; returns the minimum.
fn nelder_mead(f: impl Fn([f64; 2]) -> f64, x0: [f64; 2], step: f64, tol: f64) -> f64 {
    let mut s = [x0, [x0[0] + step, x0[1]], [x0[0], x0[1] + step]].map(|x| (x, f(x)));
    for _ in 0..2000 {
        s.sort_by(|a, b| a.1.total_cmp(&b.1));
        if s[2].1 - s[0].1 < tol {
            break;
        }
        let c = [(s[0].0[0] + s[1].0[0]) / 2.0, (s[0].0[1] + s[1].0[1]) / 2.0];
        let along = |k: f64| [c[0] + k * (s[2].0[0] - c[0]), c[1] + k * (s[2].0[1] - c[1])];
        let r = along(-1.0);
        let fr = f(r);
        if fr < s[0].1 {
            let e = along(-2.0);
            let fe = f(e);
            s[2] = if fe < fr { (e, fe) } else { (r, fr) };
        } else if fr < s[1].1 {
            s[2] = (r, fr);
        } else {
            let k = along(if fr < s[2].1 { -0.5 } else { 0.5 });
            let fk = f(k);
            if fk < s[2].1.min(fr) {
                s[2] = (k, fk);
            } else {
                let best = s[0].0;
                for v in s.iter_mut().skip(1) {
                    let x = [(v.0[0] + best[0]) / 2.0, (v.0[1] + best[1]) / 2.0];
                    *v = (x, f(x));
                }
            }
        }
    }
    s.iter().map(|v| v.1).fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::{Plane, Sense};

    /// The shift into one turn gives what the reduction gives, bit for bit, on [−360, 360)
    /// (at its ends, at ±0 and next to them), and declines angles outside and those just below
    /// 0 whose shift rounds up to 360.
    #[test]
    fn one_turn_shift_is_the_reduction_bit_for_bit() {
        let mut x = vec![
            -360.0,
            (-360.0f64).next_up(),
            -1e-13,
            -0.0,
            0.0,
            0.0f64.next_up(),
            360.0f64.next_down(),
        ];
        x.extend((0..7200).map(|i| -360.0 + 0.1 * i as f64 + 1e-9 * (i % 7) as f64));
        let mut out = vec![0.0; x.len()];
        assert!(within_one_turn(&x, &mut out));
        for (v, o) in x.iter().zip(&out) {
            assert_eq!(
                o.to_bits(),
                rem360(*v).to_bits(),
                "{v}: {o} against {}",
                rem360(*v)
            );
        }
        for declined in [(-360.0f64).next_down(), -1e-14, 360.0, f64::NAN] {
            assert!(!within_one_turn(&[declined], &mut [0.0]), "{declined}");
        }
    }

    fn trace(sense: Sense, f: impl Fn(f64) -> f64) -> Trace {
        let angle_deg: Vec<f64> = (0..3600).map(|i| sense.sign() * i as f64 * 0.1).collect();
        let deviation_um = angle_deg.iter().map(|a| f(a.to_radians())).collect();
        Trace {
            label: sense.name().into(),
            plane: Plane::Xy,
            sense,
            radius_mm: 150.0,
            feed_mm_min: 1000.0,
            angle_deg,
            deviation_um,
            time_s: None,
        }
    }

    #[test]
    fn an_offset_circle_has_its_centre_found_and_no_deviation() {
        let t = trace(Sense::Ccw, |th| 2.0 + 5.0 * th.cos() - 3.0 * th.sin());
        let f = figures(&[&t], true);
        let d = &f.directions[0];
        assert!((d.circle.centre_p_um - 5.0).abs() < 1e-9);
        assert!((d.circle.centre_q_um + 3.0).abs() < 1e-9);
        assert!((d.circle.radius_offset_um - 2.0).abs() < 1e-9);
        assert!(d.circular_deviation_um < 1e-9);
    }

    /// An ellipse `A cos 2θ` has G = 2A, F = ±A; the minimum zone can be no wider; CW and
    /// CCW paths differing by a constant c give H = c.
    #[test]
    fn ellipse_and_hysteresis_have_their_closed_form_figures() {
        let cw = trace(Sense::Cw, |th| 4.0 * (2.0 * th).cos() + 1.5);
        let ccw = trace(Sense::Ccw, |th| 4.0 * (2.0 * th).cos());
        let f = figures(&[&cw, &ccw], true);
        let d = &f.directions[1];
        assert!((d.circular_deviation_um - 8.0).abs() < 1e-6);
        assert!((d.radial_deviation_max_um - 4.0).abs() < 1e-6);
        assert!((d.radial_deviation_min_um + 4.0).abs() < 1e-6);
        assert!(d.minimum_zone_um.unwrap() <= d.circular_deviation_um + 1e-9);
        assert!((f.hysteresis_um.unwrap() - 1.5).abs() < 1e-6);
        assert!((f.bidirectional_deviation_um.unwrap() - 9.5).abs() < 1e-6);
    }

    /// H pairs the CW and CCW deviations at the same angle. Odd signatures tell a right pairing
    /// from a wrong one (θ with −θ, a mean or a single angle), which an even path or a constant
    /// offset cannot: a servo mismatch ∓A sin 2θ gives H = 2A (at 45°), an X backlash
    /// ±(b/2) sgn(sin θ) cos θ gives H = b (at 0° and 180°), and neither changes when the CW
    /// run starts at 90° instead of 0°.
    #[test]
    fn hysteresis_pairs_the_two_directions_at_the_same_angle() {
        let (a, b) = (1.25, 3.0);
        let servo = |g: f64| move |th: f64| g * a * (2.0 * th).sin();
        let backlash = |g: f64| move |th: f64| g * 0.5 * b * th.sin().signum() * th.cos();
        for start_deg in [0.0, 90.0] {
            let cases: [(Trace, Trace, f64); 2] = [
                (
                    trace_from(Sense::Cw, start_deg, servo(-1.0)),
                    trace(Sense::Ccw, servo(1.0)),
                    2.0 * a,
                ),
                (
                    trace_from(Sense::Cw, start_deg, backlash(1.0)),
                    trace(Sense::Ccw, backlash(-1.0)),
                    b,
                ),
            ];
            for (cw, ccw, expected) in cases {
                let h = figures(&[&cw, &ccw], false).hysteresis_um.unwrap();
                assert!(
                    (h - expected).abs() < 1e-4,
                    "start {start_deg}°: H {h}, expected {expected}"
                );
            }
        }
    }

    /// [`trace`] starting at `start_deg`: the angles start + sense · i · 0.1°, the deviation
    /// `f` of each.
    fn trace_from(sense: Sense, start_deg: f64, f: impl Fn(f64) -> f64) -> Trace {
        let mut t = trace(sense, |_| 0.0);
        t.angle_deg = t.angle_deg.iter().map(|x| x + start_deg).collect();
        t.deviation_um = t.angle_deg.iter().map(|x| f(x.to_radians())).collect();
        t
    }

    /// A run that goes on for 40° past its revolution (a CSV with its overshoot kept) is
    /// evaluated on its first 360°: the same figures, bit for bit, as the revolution alone,
    /// with the whole sweep recorded. Over all 400° the overlap had counted twice: a 3 µm
    /// cos 3θ lobe with a 1 µm offset in X made G differ.
    #[test]
    fn a_run_past_one_revolution_is_evaluated_on_its_first() {
        let shape = |th: f64| 3.0 * (3.0 * th).cos() + th.cos();
        let mut long = trace_from(Sense::Ccw, -20.0, shape);
        let extra: Vec<f64> = (1..=400).map(|i| 339.9 + 0.1 * i as f64).collect();
        long.deviation_um
            .extend(extra.iter().map(|a| shape(a.to_radians()) + 0.5));
        long.angle_deg.extend(extra);
        let mut one = long.clone();
        let n = 3601;
        one.angle_deg.truncate(n);
        one.deviation_um.truncate(n);
        let (a, b) = (figures(&[&long], false), figures(&[&one], false));
        assert_eq!(a.directions[0].recorded_sweep_deg, Some(long.sweep_deg()));
        assert_eq!(b.directions[0].recorded_sweep_deg, None);
        assert_eq!(
            a.directions[0].circular_deviation_um,
            b.directions[0].circular_deviation_um
        );
        assert_eq!(a.directions[0].circle, b.directions[0].circle);
        let arcs: Vec<Arc> = [&long].iter().map(|t| Arc::new(t)).collect();
        let whole = figures_of(&arcs, false);
        assert!(
            (whole.directions[0].circular_deviation_um - b.directions[0].circular_deviation_um)
                .abs()
                > 0.1
        );
    }

    /// The hysteresis found block by block is the largest difference over all samples: noisy
    /// paths, angles stepping back, and a CW run that starts elsewhere and wraps round.
    #[test]
    fn hysteresis_by_blocks_equals_the_walk_over_every_sample() {
        let noise = |i: usize| ((i * 7919 % 1013) as f64 / 1013.0 - 0.5) * 0.8;
        for (start, sweep) in [(0.0, 360.0), (37.0, 250.0), (300.0, 370.0)] {
            let mut cw = trace(Sense::Cw, |th| 3.0 * (2.0 * th).cos() + 0.7);
            let mut ccw = trace(Sense::Ccw, |th| 3.0 * (2.0 * th).cos());
            for t in [&mut cw, &mut ccw] {
                let n = (sweep * 10.0) as usize;
                let g = t.sense.sign();
                t.angle_deg = (0..n)
                    .map(|i| start + g * (i as f64 * 0.1 - if i % 5 == 2 { 0.04 } else { 0.0 }))
                    .collect();
                t.deviation_um = (0..n)
                    .map(|i| t.deviation_um[i % 3600] + noise(i))
                    .collect();
            }
            let (a, b) = (Arc::new(&cw), Arc::new(&ccw));
            let c = least_squares_circle(&[&cw, &ccw]);
            let (_, _, extremes) = radial_bounds(&a, c, c);
            let blocks = hysteresis(&a, &extremes, &b, &c).unwrap();
            let mut pb = Path::new();
            extend_path(&mut pb, &b, &c);
            pb.sort_by(|x, y| x.0.total_cmp(&y.0));
            let walk = block_worst(&a, &c, &pb, 0..cw.angle_deg.len()).unwrap();
            assert_eq!(
                blocks.to_bits(),
                walk.to_bits(),
                "start {start}, sweep {sweep}"
            );
        }
    }

    /// The minimum zone found by Nelder–Mead matches a brute-force search over centres and is
    /// never wider than the least-squares band.
    #[test]
    fn minimum_zone_matches_a_brute_force_search() {
        let mut t = trace(Sense::Ccw, |th| {
            (2.0 * th).cos()
                + 0.6 * (3.0 * th).cos()
                + 0.3 * (5.0 * th).sin()
                + 0.8 * th.cos().max(0.0)
        });
        // Every 10th sample (1°), so that a fine grid of centres stays quick.
        t.angle_deg = t.angle_deg.into_iter().step_by(10).collect();
        t.deviation_um = t.deviation_um.into_iter().step_by(10).collect();
        let f = figures(&[&t], true);
        let d = &f.directions[0];
        let z = d.minimum_zone_um.unwrap();
        let mut best = f64::INFINITY;
        let arc = Arc::new(&t);
        for i in -300..=300 {
            for j in -300..=300 {
                let c = Circle {
                    centre_p_um: d.circle.centre_p_um + i as f64 * 4e-3,
                    centre_q_um: d.circle.centre_q_um + j as f64 * 4e-3,
                    radius_offset_um: 0.0,
                };
                best = best.min(span(&radial(&arc, &c)));
            }
        }
        assert!(
            z <= best + 1e-6 && z > best - 1e-2,
            "Nelder-Mead {z}, grid {best}"
        );
        assert!(
            z < d.circular_deviation_um - 0.01,
            "{z} vs G {}",
            d.circular_deviation_um
        );
    }
}
