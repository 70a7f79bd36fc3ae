//! The take-up of backlash after each reversal (see the notes of [`crate::signatures`]) in
//! the fit and in the residual, and the group that straddles a reversal.
//!
//! The take-up of a gap `b` held by friction lasts until the motor has travelled `b` from its
//! turn: `√(2b/R)` rad of the circle, 1.05° for 25 µm on 150 mm, 0.36° for 3 µm. A step model
//! reads the parabola as part step and part spike: 25 µm gaps in the X and Y nuts of the
//! built-in machine read 26.15 and 22.90 µm against the bar's 27.29 and 24.23 µm, with reversal
//! spikes of 25 µm, stick-slip, transients at the start and a residual of 2.2 µm RMS (0.22 µm
//! with the take-up). A step that is the screw's stretch under friction (Z's, whose nut the
//! head's weight keeps on one flank) is passed in a fraction of its size, so the reach `a` of
//! the take-up (µm of motor travel from flank to flank) is fitted too, per axis, as a multiple
//! `k = a/|b|`: 0 (a sudden step) or `[K_MIN, K_MAX]`. A negative backlash (a compensation
//! that overshoots the gap, which a controller spreads over a few milliseconds) is taken over
//! its reach likewise.
//!
//! For a given reach the law is linear in `b` but for the window's length (`√b`), so the fit is
//! a fixed point (`Prepared::fixed_point`): fit the steps, move the means of the groups that
//! hold samples inside the windows of the fitted backlash onto the step model (in the normal
//! equations, [`Normal::shift`]: no pass over the other groups), fit again. Each round cuts
//! the change about tenfold; three to five rounds reach [`CONVERGED_UM`]. The reach is chosen
//! by a golden-section search of the residual's sum of squares over the samples it can move
//! (from each reversal to `WINDOW_MARGIN · K_MAX` times the step model's backlash of travel
//! after it), one axis after the other from `k = 1`.
//!
//! A window starts at the first sample after the axis' reversal inside the trace (after the
//! first of the flips of jitter about the turn, counting only the samples on the new side). A
//! run that starts on a turn does not say how its approach left the carriage: no take-up
//! there. In the fit a sample on the turn itself bears on the old flank (the first motion's,
//! at a turn the run starts on); in the residual it takes the flank that fits it
//! (`settle_flanks_at_reversals`).

use crate::model::{Fit, FitError, Normal, Term};
use crate::samples::Samples;
use crate::signatures::{self, ON_TURN, STARTS_ON_TURN};
use crate::trace::Plane;

/// The most rounds of the fixed point.
const MAX_ROUNDS: usize = 8;
/// The change of both backlash estimates (µm) below which the fixed point has converged.
pub const CONVERGED_UM: f64 = 1e-3;
/// The largest reach searched, in steps: a carriage held by static friction above the
/// Coulomb level waits longer than its gap (2.4 steps on the built-in machine's X guides with
/// their static friction raised from 65 to 250 N, at 100 mm/min).
pub const K_MAX: f64 = 8.0;
/// The smallest non-zero reach searched, in steps; a sudden step (0) is tried too. At 1 kHz,
/// 1000 mm/min and 150 mm the first sample after a turn is 0.0009 µm of travel from it: a
/// reach of 0.001 of a 20 µm step spans four samples, and 0.005 of it (ten samples) had been
/// read as 0.01 with a false spike of 7.8 µm when the search stopped there.
pub const K_MIN: f64 = 1e-3;
/// Golden-section steps of the search for the reach, on its logarithm: to within a factor
/// `exp(ln(K_MAX/K_MIN) · 0.618¹²)` = 1.03.
const SEARCH_STEPS: usize = 12;
/// The share of [`K_MAX`] above which a fitted reach is at the search's limit: the last
/// golden-section bracket's width on the logarithm.
const AT_LIMIT: f64 = 0.97;
/// The windows are laid out to this multiple of `K_MAX` times the step model's backlash,
/// which the take-up's fit exceeds by 15 % at most.
const WINDOW_MARGIN: f64 = 1.2;

/// How far some samples of a trace lie off the step model: (sample index, µm).
pub type Shifts = Vec<(usize, f64)>;

/// The fit with the take-up of the fitted backlash.
#[derive(Clone, Debug)]
pub struct TakeUp {
    /// The fitted model.
    pub fit: Fit,
    /// Each trace's take-up at the fitted backlash and reach, to take from its residual.
    pub shifts: Vec<Shifts>,
    /// The reach of each axis' take-up (p, q), µm of motor travel; `None` where no reversal
    /// of the axis inside a run let it be fitted (its take-up is then taken over the
    /// backlash itself).
    pub reach_um: [Option<f64>; 2],
    /// Whether each axis' reach came out at the top of the search ([`K_MAX`] steps): the
    /// take-up may be longer than the model holds.
    pub at_limit: [bool; 2],
    /// The normal equations of the fit (of the deviations as measured; the design, which
    /// [`Normal::alias`] uses, is that of every fit of the search).
    pub normal: Normal,
}

/// The fitted backlash of p and q, µm (0 for a term not in the model).
fn fitted_backlash(fit: &Fit) -> [f64; 2] {
    [0, 1].map(|axis| fit.get(Term::Backlash(axis)).map_or(0.0, |(b, _)| b))
}

/// A sample after a reversal: its index, the motor's travel from the turn (µm) and Δr per µm
/// of backlash on its flank ([`signatures::backlash_on_flank`]).
#[derive(Clone, Copy, Debug)]
struct Near {
    i: usize,
    travel: f64,
    unit: f64,
}

impl Near {
    /// The take-up of backlash `b` over the reach `a` (µm) here
    /// ([`signatures::take_up_at`]).
    fn shift(&self, b: f64, a: f64) -> f64 {
        signatures::take_up_at(self.unit, self.travel, b, a)
    }
}

/// One trace's samples that the take-up and the straddling groups move.
#[derive(Debug, Default)]
struct Windows {
    /// Per axis, per reversal inside the run: its samples (not those on the turn) while the
    /// motor's travel is below the window's extent.
    after: [Vec<Vec<Near>>; 2],
    /// Per axis: (sample index, Δr per µm of backlash) of the samples of a group holding a
    /// reversal that lie on the other flank than the group's mean angle.
    straddle: [Vec<(usize, f64)>; 2],
}

impl Windows {
    /// The windows of trace `s` with reversals `reversals`, to `extent_um` of travel per axis.
    /// The flips of a sign that follow one another within a window (jitter about a turn) are
    /// one reversal: the carriage stays on its old flank until the take-up after the last of
    /// them. A run that starts on the turn ([`STARTS_ON_TURN`]) has no take-up at it.
    fn new(s: &Samples, reversals: &[Vec<usize>; 2], extent_um: [f64; 2]) -> Self {
        let mut w = Self::default();
        for (axis, at) in reversals.iter().enumerate() {
            let along = |i: usize| s.point(i).turning(axis);
            let window_end = |from: usize| {
                (from..s.len())
                    .find(|&i| signatures::travel_from_turn(&s.point(i), axis) >= extent_um[axis])
                    .unwrap_or(s.len())
            };
            // The samples still at the turn the run starts on, if it starts on one.
            let at_start = if !s.is_empty() && along(0).abs() <= STARTS_ON_TURN {
                window_end(0)
            } else {
                0
            };
            let mut straddled = Vec::new();
            let mut cluster: Option<usize> = None;
            for (j, &last) in at.iter().enumerate() {
                let end = window_end(last);
                let first = *cluster.get_or_insert(last);
                if at.get(j + 1).is_some_and(|&next| next < end) {
                    continue; // not the last flip of this turn
                }
                cluster = None;
                let known = first >= at_start;
                let group = first / s.group_size;
                if !straddled.contains(&group) {
                    straddled.push(group);
                    w.straddle[axis].extend(straddling(s, axis, first, known));
                }
                if !known {
                    continue;
                }
                // From the first flip on, the samples on the new side: between the flips the
                // carriage has not left its old flank.
                let new_side = signatures::sign(along(last));
                let near = (first..end)
                    .filter(|&i| along(i).abs() > ON_TURN && signatures::sign(along(i)) == new_side)
                    .map(|i| {
                        let pt = s.point(i);
                        let flank = signatures::sign(along(i));
                        Near {
                            i,
                            travel: signatures::travel_from_turn(&pt, axis),
                            unit: signatures::backlash_on_flank(&pt, axis, flank),
                        }
                    })
                    .collect();
                w.after[axis].push(near);
            }
        }
        w
    }

    /// The take-up of backlash `b` over `reach` (µm, per axis) at each sample it moves.
    fn take_up(&self, b: [f64; 2], reach: [f64; 2]) -> impl Iterator<Item = (usize, f64)> + '_ {
        (0..2).flat_map(move |axis| {
            let (b, a) = (b[axis], reach[axis]);
            let live = b != 0.0 && a > 0.0;
            self.after[axis]
                .iter()
                .filter(move |_| live)
                .flat_map(move |w| w.iter().take_while(move |n| n.travel < a))
                .map(move |n| (n.i, n.shift(b, a)))
        })
    }

    /// Every shift of the fit's groups at backlash `b` and reach `reach`: the take-up and the
    /// straddling samples.
    fn all(&self, b: [f64; 2], reach: [f64; 2]) -> impl Iterator<Item = (usize, f64)> + '_ {
        let straddle = (0..2).flat_map(move |axis| {
            self.straddle[axis]
                .iter()
                .map(move |&(i, unit)| (i, b[axis] * unit))
        });
        self.take_up(b, reach).chain(straddle)
    }
}

/// The samples of the group that holds reversal `first` of `axis` on the other side of the
/// turn than the group's mean angle, each with Δr per µm of backlash by which its own flank
/// differs from the group's (the fit takes the group's flank for all of it: a group of 55
/// samples straddling the turn took a quarter of the step into its mean and biased the fit of
/// a step, 25 µm on Y read 24.66). A sample on the turn itself bears on the old flank, where
/// the take-up starts, or, at a turn the run starts on (`known` false), on the flank of its
/// first motion.
fn straddling(s: &Samples, axis: usize, first: usize, known: bool) -> Vec<(usize, f64)> {
    let k = first / s.group_size;
    let group_flank = signatures::sign(s.groups[k].0.turning(axis));
    let end = ((k + 1) * s.group_size).min(s.len());
    let new_flank = (first..s.len())
        .map(|i| s.point(i).turning(axis))
        .find(|a| a.abs() > ON_TURN)
        .map_or(0.0, signatures::sign);
    let on_turn_flank = if known { -new_flank } else { new_flank };
    (k * s.group_size..end)
        .filter_map(|i| {
            let pt = s.point(i);
            let a = pt.turning(axis);
            let flank = if a.abs() <= ON_TURN {
                on_turn_flank
            } else {
                signatures::sign(a)
            };
            let u = |f: f64| signatures::backlash_on_flank(&pt, axis, f);
            (flank != group_flank).then(|| (i, u(flank) - u(group_flank)))
        })
        .collect()
}

/// The sum of `shifts` per group of `group_size` samples, by group: runs of one group are
/// summed as they come (the shifts of a window are in sample order), then the few runs sorted.
fn per_group(shifts: impl Iterator<Item = (usize, f64)>, group_size: usize) -> Vec<(usize, f64)> {
    let mut sums: Vec<(usize, f64)> = Vec::new();
    for (i, d) in shifts {
        let g = i / group_size;
        match sums.last_mut() {
            Some((last, sum)) if *last == g => *sum += d,
            _ => sums.push((g, d)),
        }
    }
    sums.sort_unstable_by_key(|(g, _)| *g);
    sums.dedup_by(|next, kept| {
        let same = next.0 == kept.0;
        if same {
            kept.1 += next.1;
        }
        same
    });
    sums
}

/// What every fit of the search starts from.
struct Prepared<'a> {
    samples: &'a [Samples<'a>],
    /// The normal equations of the deviations as measured.
    normal: Normal,
    windows: Vec<Windows>,
}

impl Prepared<'_> {
    /// The fixed point of the fit with the take-up over the reaches `k` (p, q, in steps), from
    /// the backlash `b0`.
    fn fixed_point(&self, k: [f64; 2], b0: [f64; 2]) -> Fit {
        let mut normal = self.normal.clone();
        let mut applied: Vec<Vec<(usize, f64)>> = vec![Vec::new(); self.samples.len()];
        let (mut b, mut round) = (b0, 1);
        loop {
            let reach = [k[0] * b[0].abs(), k[1] * b[1].abs()];
            for (trace, (s, w)) in self.samples.iter().zip(&self.windows).enumerate() {
                let next = per_group(w.all(b, reach), s.group_size);
                move_groups(&mut normal, trace, s, &applied[trace], &next);
                applied[trace] = next;
            }
            let fit = normal.solve();
            let nb = fitted_backlash(&fit);
            if round == MAX_ROUNDS || (0..2).all(|a| (nb[a] - b[a]).abs() < CONVERGED_UM) {
                return fit;
            }
            (b, round) = (nb, round + 1);
        }
    }

    /// Σ r² of the residual of `fit` with its take-up over the reaches `k` at the samples of
    /// the windows of `axis`.
    fn window_sum_sq(&self, fit: &Fit, k: [f64; 2], axis: usize) -> f64 {
        let b = fitted_backlash(fit)[axis];
        let reach = k[axis] * b.abs();
        let mut sum = 0.0;
        for (s, w) in self.samples.iter().zip(&self.windows) {
            let model = fit.compiled(s.radius_um, s.feed_um_per_ms);
            for near in w.after[axis].iter().filter(|n| !n.is_empty()) {
                let at = near[0].i..near[near.len() - 1].i + 1;
                let mut r = vec![0.0; at.len()];
                model.residuals(
                    s.sense.sign(),
                    &s.cos[at.clone()],
                    &s.sin[at.clone()],
                    &s.progress[at.clone()],
                    &s.deviation_um[at.clone()],
                    &mut r,
                );
                if b != 0.0 && reach > 0.0 {
                    for n in near.iter().take_while(|n| n.travel < reach) {
                        r[n.i - at.start] -= n.shift(b, reach);
                    }
                }
                sum += r.iter().map(|x| x * x).sum::<f64>();
            }
        }
        sum
    }
}

/// Moves the means of the fitted groups of trace `trace` from their shifts `from` to `to`
/// (group, Σ µm, both by group) in `normal`.
fn move_groups(
    normal: &mut Normal,
    trace: usize,
    s: &Samples,
    from: &[(usize, f64)],
    to: &[(usize, f64)],
) {
    let mut changes: Vec<(usize, f64, f64)> = from.iter().map(|&(g, x)| (g, x, 0.0)).collect();
    for &(g, y) in to {
        match changes.binary_search_by_key(&g, |c| c.0) {
            Ok(k) => changes[k].2 = y,
            Err(k) => changes.insert(k, (g, 0.0, y)),
        }
    }
    for (g, old, new) in changes {
        let (pt, mean, w) = &s.groups[g];
        if s.fitted[g] && old != new {
            let n = *w as f64;
            normal.shift(trace, pt, *w, mean - old / n, mean - new / n);
        }
    }
}

/// The `k`, 0 or in `[K_MIN, K_MAX]`, that minimises `cost`: a golden-section search on
/// `ln k`, then 0 if it does better.
fn golden(mut cost: impl FnMut(f64) -> f64) -> f64 {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut a, mut b) = (K_MIN.ln(), K_MAX.ln());
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (cost(c.exp()), cost(d.exp()));
    for _ in 0..SEARCH_STEPS {
        if fc <= fd {
            (b, d, fd) = (d, c, fc);
            c = b - g * (b - a);
            fc = cost(c.exp());
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + g * (b - a);
            fd = cost(d.exp());
        }
    }
    let (k, best) = if fc <= fd {
        (c.exp(), fc)
    } else {
        (d.exp(), fd)
    };
    if cost(0.0) < best { 0.0 } else { k }
}

/// The fit of `terms` to the traces `samples` with the take-up of the fitted backlash over
/// the fitted reach.
pub fn fit(
    plane: Plane,
    terms: &[Term],
    samples: &[Samples],
    reversals: &[[Vec<usize>; 2]],
) -> Result<TakeUp, FitError> {
    let normal = Normal::new(plane, terms, &samples.iter().collect::<Vec<_>>())?;
    let step = fitted_backlash(&normal.solve());
    let extent = step.map(|b| WINDOW_MARGIN * K_MAX * b.abs());
    let prepared = Prepared {
        samples,
        windows: samples
            .iter()
            .zip(reversals)
            .map(|(s, rev)| Windows::new(s, rev, extent))
            .collect(),
        normal,
    };
    let mut k = [1.0, 1.0];
    let mut fit = prepared.fixed_point(k, step);
    let mut searched = [false; 2];
    for axis in 0..2 {
        let b = fitted_backlash(&fit);
        let windows = prepared.windows.iter().flat_map(|w| &w.after[axis]);
        if b[axis] == 0.0 || windows.clone().all(Vec::is_empty) {
            continue;
        }
        searched[axis] = true;
        k[axis] = golden(|x| {
            let mut trial = k;
            trial[axis] = x;
            let f = prepared.fixed_point(trial, b);
            prepared.window_sum_sq(&f, trial, axis)
        });
        fit = prepared.fixed_point(k, b);
    }
    let b = fitted_backlash(&fit);
    let reach = [k[0] * b[0].abs(), k[1] * b[1].abs()];
    let shifts = prepared
        .windows
        .iter()
        .map(|w| w.take_up(b, reach).collect())
        .collect();
    Ok(TakeUp {
        fit,
        shifts,
        reach_um: [0, 1].map(|a| searched[a].then_some(reach[a])),
        at_limit: [0, 1].map(|a| searched[a] && k[a] >= K_MAX * AT_LIMIT),
        normal: prepared.normal,
    })
}
