//! The take-up of backlash after each reversal (see the notes of [`crate::signatures`]) in
//! the fit and in the residual, and the group that straddles a reversal.
//!
//! The take-up of a backlash `b` lasts until the motor has travelled `b` from its turn:
//! `√(2b/R)` rad of the circle, 1.05° for 25 µm on 150 mm, 0.36° for 3 µm. A step model reads
//! the parabola as part step and part spike: 25 µm gaps in the X and Y nuts of the built-in
//! machine read 26.15 and 22.90 µm against the bar's 27.29 and 24.23 µm, with reversal spikes
//! of 25 µm, stick-slip, transients at the start and a residual of 2.2 µm RMS (0.32 µm with
//! the take-up). The law is nonlinear in `b` (the flank's length goes with `√b`) but linear
//! in it for a given window, so the fit is a fixed point: fit the steps, shift the samples
//! inside the windows of the fitted backlash onto the step model (only the group means move,
//! [`Samples::shift_groups`], and the normal equations with them, [`Normal::shift`]), fit
//! again. Each round cuts the change about tenfold; three to five rounds reach
//! [`CONVERGED_UM`].
//!
//! A window starts at the first sample after the axis' reversal inside the trace: a run that
//! starts at a turn does not say how its approach left the carriage, and samples on the turn
//! itself take their flank from the residual (`settle_flanks_at_reversals`).

use crate::model::{Fit, FitError, Normal, Term};
use crate::samples::Samples;
use crate::signatures;
use crate::trace::Plane;

/// The most rounds of the fixed point.
const MAX_ROUNDS: usize = 8;
/// The change of both backlash estimates (µm) below which the fixed point has converged.
pub const CONVERGED_UM: f64 = 1e-3;
/// |sin θ| (p) or |cos θ| (q) at or below which a sample lies on the turn itself.
const ON_TURN: f64 = 1e-9;

/// How far some samples of a trace lie off the step model: (sample index, µm).
pub type Shifts = Vec<(usize, f64)>;

/// The fitted backlash of p and q, µm (0 for a term not in the model).
fn fitted_backlash(fit: &Fit) -> [f64; 2] {
    [0, 1].map(|axis| fit.get(Term::Backlash(axis)).map_or(0.0, |(b, _)| b))
}

/// How far the take-up of backlash `backlash_um` (p, q) moves each sample of a trace off the
/// step model: (sample index, µm), for the samples after each of the axes' reversals
/// (`reversals`, the first sample on the new side) whose motor is still within the gap.
pub fn shifts(s: &Samples, reversals: &[Vec<usize>; 2], backlash_um: [f64; 2]) -> Shifts {
    let mut out = Vec::new();
    for (axis, (at, &b)) in reversals.iter().zip(&backlash_um).enumerate() {
        if b <= 0.0 {
            continue;
        }
        let on_turn = |i: usize| {
            let pt = s.point(i);
            let along = if axis == 0 { pt.sin } else { pt.cos };
            along.abs() <= ON_TURN
        };
        for &first in at {
            if (0..first).all(on_turn) {
                continue; // the run starts on the turn: its approach is not known
            }
            for i in first..s.len() {
                let pt = s.point(i);
                if signatures::travel_from_turn(&pt, axis) >= b {
                    break;
                }
                if !on_turn(i) {
                    out.push((i, signatures::backlash_take_up(&pt, axis, b)));
                }
            }
        }
    }
    out
}

/// How far each sample of the group that holds a reversal lies off the step the fit takes for
/// the whole group (its flank is that of the group's mean angle): (sample index, µm), the
/// backlash `backlash_um` (p, q) of the sample's own flank less that of the group's, for the
/// samples on the other side of the turn. A group of 55 samples straddling the turn took a
/// quarter of the step into its mean and biased the fit of a step: 25 µm on Y read 24.66.
pub fn straddles(s: &Samples, reversals: &[Vec<usize>; 2], backlash_um: [f64; 2]) -> Shifts {
    let mut out = Vec::new();
    for (axis, (at, &b)) in reversals.iter().zip(&backlash_um).enumerate() {
        if b == 0.0 {
            continue;
        }
        let along = |pt: &crate::signatures::Point| if axis == 0 { pt.sin } else { pt.cos };
        for &first in at {
            let k = first / s.group_size;
            let group_flank = signatures::sign(along(&s.groups[k].0));
            let end = ((k + 1) * s.group_size).min(s.len());
            for i in k * s.group_size..end {
                let pt = s.point(i);
                let flank = signatures::sign(along(&pt));
                if flank != group_flank {
                    let u = |f: f64| signatures::backlash_on_flank(&pt, axis, f);
                    out.push((i, b * (u(flank) - u(group_flank))));
                }
            }
        }
    }
    out
}

/// The fit of `terms` to the traces `samples` with the take-up of the fitted backlash, and
/// each trace's [`shifts`] at the fitted backlash (to take from its residual). The groups of
/// `samples` are left shifted by the take-up and the [`straddles`] of the last round; each
/// round updates the normal equations with the groups that moved ([`Normal::shift`]).
pub fn fit(
    plane: Plane,
    terms: &[Term],
    samples: &mut [Samples],
    reversals: &[[Vec<usize>; 2]],
) -> Result<(Fit, Vec<Shifts>), FitError> {
    let mut normal = Normal::new(plane, terms, &samples.iter().collect::<Vec<_>>())?;
    let mut fit = normal.solve();
    let base: Vec<Vec<f64>> = samples
        .iter()
        .map(|s| s.groups.iter().map(|g| g.1).collect())
        .collect();
    let mut shifted = false;
    for _ in 0..MAX_ROUNDS {
        let b = fitted_backlash(&fit);
        let round: Vec<Shifts> = samples
            .iter()
            .zip(reversals)
            .map(|(s, rev)| [shifts(s, rev, b), straddles(s, rev, b)].concat())
            .collect();
        let none = round.iter().all(Vec::is_empty);
        if none && !shifted {
            break;
        }
        for (trace, ((s, m), sh)) in samples.iter_mut().zip(&base).zip(&round).enumerate() {
            let before: Vec<f64> = s.groups.iter().map(|g| g.1).collect();
            s.shift_groups(m, sh);
            for ((g, fitted), from) in s.groups.iter().zip(&s.fitted).zip(before) {
                if *fitted && g.1 != from {
                    normal.shift(trace, &g.0, g.2, from, g.1);
                }
            }
        }
        shifted = !none;
        fit = normal.solve();
        let next = fitted_backlash(&fit);
        if (0..2).all(|k| (next[k] - b[k]).abs() < CONVERGED_UM) {
            break;
        }
    }
    let b = fitted_backlash(&fit);
    let shifts = samples
        .iter()
        .zip(reversals)
        .map(|(s, rev)| shifts(s, rev, b))
        .collect();
    Ok((fit, shifts))
}
