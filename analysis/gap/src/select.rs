//! Which unmodelled effect explains the gap, how much adding it buys, and which others would
//! explain it as well.
//!
//! The measured runs' residual bins (1° of the angle by default) are dealt out between fit,
//! select and judge ([`crate::split`]). Every free parameter `β_p` of every available
//! candidate gets its sensitivity by a finite difference through the simulator,
//! `J_p = (m(β₀ + h_p e_p) − m(β₀)) / h_p`, where `m` is the model's deviation at the measured
//! angles averaged into the bins. Before any candidate, the fit and select bins of each plane
//! are scanned for a change of one axis' error over a stretch ([`crate::axis_change`], against
//! the smooth shapes up to the cubic and the sensitivities of the other candidates, whose
//! mismatch is in the same residual); when the circles see that change begin and end, the
//! candidates that are that error's shape over the whole travel ([`Effect::whole_travel`]: a
//! positioning curve, a straightness) are set aside, since what is local is none of them.
//! Effects are then added by forward selection:
//!
//! 1. for each candidate `c` not yet chosen, the parameters of the chosen effects and of `c`
//!    (with the bar's set-up, the baseline) are fitted jointly to the fit bins,
//!    `min ‖r_fit − J_fit β‖²` (Gauss–Newton step from the model as given, the effects being
//!    near-linear at the micrometre level), and scored on the select bins by the residual the
//!    linear model predicts there;
//! 2. the candidates that lower the fit bins' BIC `n ln(RSS/n) + k ln n` by at least
//!    [`Options::min_bic_drop`] are taken in the order of their predicted select residual. One
//!    whose fitted values a machine of the model's class cannot have
//!    ([`crate::effects::Plausible`]) is set aside as implausible, before or after its
//!    simulation; the first plausible one is simulated at its values, refined by one more
//!    Gauss–Newton step on the fit bins, and accepted when its simulated fit BIC drops by at
//!    least [`Options::min_bic_drop`], the select bins' mean square shrinks by at least
//!    [`Options::min_select_shrink`] of what is left and changes by at least
//!    [`Options::min_effect_um`] RMS;
//! 3. when no single candidate passes, two effects the gap needs together are tried in one
//!    step: a pair fitted jointly with the chosen effects that lowers the fit BIC by
//!    [`Options::min_bic_drop`] below the current one and below each of its effects alone,
//!    and whose linear prediction passes the shrink and change gates, is verified and gated
//!    as one candidate (best predicted select residual first). A physics outside the library that
//!    two candidates' shapes span together (a screw warmed over part of its length: a scale,
//!    a bow and a growth in time) passes no gate one shape at a time, each leaving most of
//!    what the other would remove.
//!
//! Selection does not start when the select bins' gap is already at
//! [`Options::explained_floor_um`], and stops when no candidate passes. Then the judge bins,
//! untouched so far, give the held-out figures: the RMS of the model as given (its set-up
//! fitted) and with the chosen effects, both simulated. The gap counts as explained when the
//! chosen effects explain it on the select bins and the judge bins confirm it; with too few
//! judge bins no untouched figure is given ([`Judged`]).
//!
//! Ambiguity is an answer too. For each chosen effect, every other candidate and pair of
//! candidates is fitted in its place (the other chosen effects kept) on the fit bins, and its
//! residual on the judge bins compared with the chosen one's by a paired test over the judge
//! segments: `d_s` = the segment's mean square with the rival less with the chosen effect,
//! `t = mean(d) / (sd(d)/√S)` against Student's t with S − 1 degrees of freedom. A rival
//! that would itself explain the gap on the judge bins (the same floor and fraction as the
//! chosen effects) and is not worse at level [`Options::ambiguity_level`] by the linearised
//! prediction is simulated (the most promising [`MAX_RIVALS_SIMULATED`]) and tested again on
//! its simulated residual; what passes both is an equally good explanation, reported with the
//! size it would need. A pair holding an effect that is as good alone is not listed. A rival
//! whose size is implausible is reported as such and is not an explanation.

use crate::align::{GapError, TracePair};
use crate::axis_change::AxisChange;
use crate::effects::{Effect, Implausible, Param, Scale};
use crate::model::Forward;
use crate::peaks::Circle;
use crate::split::{Role, Rows, Split};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use statrs::distribution::{ContinuousCDF, StudentsT};
use std::sync::OnceLock;
use std::sync::atomic::{AtomicUsize, Ordering};
use vmt_ballbar::Trace;

/// Rivals of a chosen effect simulated to confirm an ambiguity, at most.
pub const MAX_RIVALS_SIMULATED: usize = 3;

/// Settings of the selection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// Bin width of the residual vectors, deg.
    pub bin_deg: f64,
    /// Least drop of the fit bins' BIC for an effect to be added.
    pub min_bic_drop: f64,
    /// Least shrink of the select bins' mean square, as a fraction of what is left.
    pub min_select_shrink: f64,
    /// Most effects added.
    pub max_effects: usize,
    /// Least RMS change an effect must make to the select bins' residual, µm: above the ball
    /// bar's resolution (0.1 µm) and the level at which a model's other small mismatches
    /// (the bench's nuisance) already change the residual.
    pub min_effect_um: f64,
    /// The gap counts as explained when what the chosen effects leave is at most this RMS, µm
    /// (the level of a model's other small mismatches)…
    pub explained_floor_um: f64,
    /// …or at most this fraction of the gap's RMS before them (2 % of its mean square): an
    /// effect of the library that is the gap's cause, fitted at its size, leaves its
    /// nonlinearity and the other small mismatches, a few per cent of its signature; a rival
    /// that only resembles it leaves the difference of their shapes (a bow's curvature where
    /// a squareness is straight). Otherwise the chosen effects are reported as partial
    /// candidates and the gap as unexplained.
    pub explained_fraction: f64,
    /// Significance level of the paired test that calls a rival worse than the chosen effect.
    pub ambiguity_level: f64,
    /// While a step verifies its candidate, verify beside it the one the next step would
    /// verify first if this one is taken: the same answer, sooner where a core is otherwise
    /// idle, and wasted work where it is not (many selections run side by side).
    pub speculate: bool,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            bin_deg: 1.0,
            min_bic_drop: 10.0,
            min_select_shrink: 0.3,
            max_effects: 4,
            min_effect_um: 0.15,
            explained_floor_um: 0.2,
            explained_fraction: 0.15,
            ambiguity_level: 0.05,
            speculate: true,
        }
    }
}

/// A fitted parameter.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Fitted {
    /// Parameter name.
    pub name: String,
    /// Offset from the model's value.
    pub value: f64,
    /// Unit.
    pub unit: String,
    /// The values its keys take, where the parameter is in other terms than its keys (a heat
    /// capacity fitted as its reciprocal, [`crate::effects::Scale::Reciprocal`]); empty
    /// otherwise.
    pub keys: Vec<(String, f64)>,
}

impl std::fmt::Display for Fitted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} {:+.3} {}", self.name, self.value, self.unit)?;
        for (key, value) in &self.keys {
            write!(f, " (`{key}` = {value:.1})")?;
        }
        Ok(())
    }
}

/// One accepted effect.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Step {
    /// Effect key.
    pub effect: String,
    /// What it is.
    pub description: String,
    /// Its parameters' offsets, with those of the effects before it refitted (the baseline's
    /// are left out), fitted on the fit bins.
    pub values: Vec<Fitted>,
    /// RMS of the fit bins after it, µm.
    pub fit_rms_um: f64,
    /// RMS of the select bins after it, µm.
    pub select_rms_um: f64,
    /// Shrink of the select bins' mean square from before this effect, fraction.
    pub select_shrink: f64,
    /// RMS of the judge bins after it, µm, when they are enough to judge.
    pub judge_rms_um: Option<f64>,
    /// The effect added in the same step, when neither passed the gates alone
    /// (the module doc's joint step): the two appear as two steps with the same figures, each
    /// naming the other.
    pub together_with: Option<String>,
}

/// A candidate's score in the last round, for the report.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Score {
    /// Effect key.
    pub effect: String,
    /// Predicted RMS of the select bins with it, µm.
    pub select_rms_um: f64,
    /// Predicted change of the fit bins' BIC.
    pub bic_change: f64,
}

/// A candidate set aside because a machine of the model's class cannot have its fitted size.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Rejected {
    /// Effect key.
    pub effect: String,
    /// The value it would need.
    pub implausible: Implausible,
}

/// The untouched judgement: the judge bins' RMS before and after the chosen effects.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Judged {
    /// Judge bins used.
    pub bins: usize,
    /// Judge segments of at least half a segment.
    pub segments: usize,
    /// RMS of the model as given (set-up fitted on the fit bins), µm.
    pub before_um: f64,
    /// RMS with the chosen effects, µm.
    pub after_um: f64,
}

impl Judged {
    /// The fraction of the judge bins' mean square the chosen effects remove.
    pub fn shrink(&self) -> f64 {
        1.0 - (self.after_um / self.before_um).powi(2)
    }
}

/// An explanation as good as a chosen effect on the data that judge it.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Alternative {
    /// The chosen effect it could stand in for.
    pub instead_of: String,
    /// Its effects: one, or a pair.
    pub effects: Vec<String>,
    /// The sizes it would need (its own parameters), fitted on the fit bins.
    pub values: Vec<Fitted>,
    /// RMS of the judging bins with it, µm (simulated, or the linear prediction when
    /// implausible).
    pub rms_um: f64,
    /// RMS of the judging bins with the chosen effect, on the same footing, µm.
    pub chosen_rms_um: f64,
    /// Paired t statistic of its mean-square excess over the chosen effect's, per judging
    /// segment (positive: worse).
    pub t: f64,
    /// One-sided p-value of that excess: above [`Options::ambiguity_level`] it is not worse.
    pub p_value: f64,
    /// When a size it needs is beyond what the machine's class can have: it is then no
    /// explanation, only a fit.
    pub implausible: Option<Implausible>,
    /// The values the explanation writes into the model (absolute, by key): its own and the
    /// other chosen effects', refitted with it.
    pub edits: Vec<(String, f64)>,
}

/// The outcome of the selection.
#[derive(Clone, Debug, PartialEq)]
pub struct Selection {
    /// The protocol used.
    pub split: Split,
    /// Bins that fit, select and judge.
    pub bins: [usize; 3],
    /// RMS of the fit bins of the model as given (with the baseline fitted), µm.
    pub fit_before_um: f64,
    /// RMS of the select bins of the model as given (with the baseline fitted), µm.
    pub select_before_um: f64,
    /// The untouched judgement, when the judge bins are enough.
    pub judged: Option<Judged>,
    /// The baseline parameters (the bar's set-up), fitted before any effect and with each.
    pub baseline: Vec<Fitted>,
    /// The effects added, in order.
    pub steps: Vec<Step>,
    /// Candidates set aside as implausible, in the order they were tried.
    pub rejected: Vec<Rejected>,
    /// Changes of one axis' error over a stretch the circles see begin and end, in the
    /// residual of the model as given (fit and select bins; one per plane at most): the
    /// candidates that are that error's smooth shape over the whole travel are set aside.
    pub local_changes: Vec<AxisChange>,
    /// The candidates set aside for it.
    pub set_aside: Vec<String>,
    /// Explanations as good as a chosen one on the judging bins (plausible or not; see
    /// [`Alternative::implausible`]).
    pub alternatives: Vec<Alternative>,
    /// Which bins judged the alternatives: `judge`, or `select` when the judge bins are too
    /// few.
    pub alternatives_judged_on: &'static str,
    /// Candidates the model file cannot express (effect, missing key).
    pub unavailable: Vec<(String, String)>,
    /// Scores of the round that stopped the selection.
    pub last_round: Vec<Score>,
    /// The final simulated traces' residuals against the measured ones.
    pub final_pairs: Vec<TracePair>,
    /// The model's residuals before any effect (with the baseline fitted).
    pub initial_pairs: Vec<TracePair>,
    /// The final values of every chosen effect's keys (absolute, as written into the model).
    pub final_values: Vec<(String, f64)>,
    /// Simulations run for the selection (besides the linearisation's).
    pub simulations: usize,
}

impl Selection {
    /// RMS of the select bins after the chosen effects, µm.
    pub fn select_after_um(&self) -> f64 {
        self.steps
            .last()
            .map_or(self.select_before_um, |s| s.select_rms_um)
    }

    /// Whether the chosen effects explain the gap: on the select bins
    /// ([`Options::explained_floor_um`], [`Options::explained_fraction`]) and, when they are
    /// enough to judge, on the untouched judge bins too. A gap with no effect chosen is not
    /// explained.
    pub fn explained(&self, o: &Options) -> bool {
        let by = |before: f64, after: f64| {
            explained(before, after, o.explained_floor_um, o.explained_fraction)
        };
        !self.steps.is_empty()
            && by(self.select_before_um, self.select_after_um())
            && self.judged.is_none_or(|j| by(j.before_um, j.after_um))
    }

    /// The untouched held-out shrink: the fraction of the judge bins' mean square removed by
    /// the chosen effects, when the judge bins are enough.
    pub fn judge_shrink(&self) -> Option<f64> {
        self.judged.map(|j| j.shrink())
    }

    /// The plausible alternatives to the chosen effect `key`: the ambiguity set beside it.
    pub fn equally_good(&self, key: &str) -> Vec<&Alternative> {
        self.alternatives
            .iter()
            .filter(|a| a.instead_of == key && a.implausible.is_none())
            .collect()
    }
}

/// A parameter available in the model.
#[derive(Clone)]
struct Available {
    effect: usize,
    param: Param,
    /// The keys with the model's values.
    keys: Vec<(String, f64)>,
}

impl Available {
    fn models(&self) -> Vec<f64> {
        self.keys.iter().map(|(_, v)| *v).collect()
    }
}

/// The simulated traces matched to the measured ones, aligned and binned.
/// Pairs each measured trace with a simulated one of the same test: the k-th measured trace
/// of a (plane, direction, radius, feed) with the k-th simulated one, so repeated tests (Kwon's
/// steps 1 and 2) pair in order.
///
/// Without `grid` the bins are the pairs' own; with it (the keyed bins of the model as given,
/// per measured trace) every trace is binned on that grid, so that all simulations give vectors
/// of one length, bin for bin at the same angles (see [`on_grid`]).
fn residuals(
    measured: &[Trace],
    simulated: &[Trace],
    bin_deg: f64,
    grid: Option<&Grid>,
) -> Result<(Vec<TracePair>, Vec<Vec<f64>>), GapError> {
    let pairs = pair_up(measured, simulated)?;
    let bins = match grid {
        None => pairs.iter().map(|p| values(&bin(p, bin_deg))).collect(),
        Some(g) => pairs
            .iter()
            .zip(g)
            .map(|(p, reference)| on_grid(p, bin_deg, reference))
            .collect(),
    };
    Ok((pairs, bins))
}

/// Each measured trace aligned with the simulated trace of the same test (see [`residuals`]).
fn pair_up(measured: &[Trace], simulated: &[Trace]) -> Result<Vec<TracePair>, GapError> {
    partners(measured, simulated)?
        .into_iter()
        .zip(measured)
        .map(|(s, m)| TracePair::align(m, &simulated[s]))
        .collect()
}

/// For each measured trace, the index of the simulated trace of the same test it pairs with:
/// the k-th measured trace of a (plane, direction, radius, feed) with the k-th simulated one.
pub fn partners(measured: &[Trace], simulated: &[Trace]) -> Result<Vec<usize>, GapError> {
    let same = |s: &Trace, m: &Trace| {
        s.plane == m.plane
            && s.sense == m.sense
            && (s.radius_mm - m.radius_mm).abs() <= 1e-6 * s.radius_mm
            && (s.feed_mm_min - m.feed_mm_min).abs() <= 1e-3 * s.feed_mm_min
    };
    let mut out = Vec::with_capacity(measured.len());
    for (i, m) in measured.iter().enumerate() {
        let k = measured[..i].iter().filter(|x| same(x, m)).count();
        let in_job: Vec<usize> = (0..simulated.len())
            .filter(|s| same(&simulated[*s], m))
            .collect();
        let s = match in_job.get(k) {
            Some(s) => *s,
            None if in_job.is_empty() => return Err(not_in_job(m, simulated)),
            None => {
                return Err(GapError::MoreThanInJob {
                    label: m.label.clone(),
                    test: test_name(m),
                    given: measured.iter().filter(|x| same(x, m)).count(),
                    in_job: in_job.len(),
                });
            }
        };
        out.push(s);
    }
    Ok(out)
}

/// A test as `XY 150 mm 1000 mm/min cw`.
fn test_name(t: &Trace) -> String {
    format!(
        "{} {} mm {} mm/min {}",
        t.plane,
        t.radius_mm,
        t.feed_mm_min,
        t.sense.name()
    )
}

fn not_in_job(m: &Trace, simulated: &[Trace]) -> GapError {
    let tests: Vec<String> = simulated.iter().map(test_name).collect();
    GapError::NotInJob {
        label: m.label.clone(),
        plane: m.plane.to_string(),
        radius_mm: m.radius_mm,
        feed_mm_min: m.feed_mm_min,
        direction: m.sense.name().into(),
        tests: tests.join(", "),
    }
}

/// Per measured trace, the keyed bins (angle bin index, mean residual µm) of the model as given.
type Grid = Vec<Vec<(i64, f64)>>;

/// Per trace, per bin: a change of the model's deviation on the own job's grid, µm, made from
/// the per-parameter sensitivities and the grid.
type Signature<'a> = &'a dyn Fn(&[Vec<Vec<f64>>], &Grid) -> Vec<Vec<f64>>;

/// Residual averaged into bins of the measured angle, in the run's order, each with its key
/// ⌊angle/width⌋ (the aligned angle is monotone along a run, so keys do not repeat).
fn bin(p: &TracePair, width: f64) -> Vec<(i64, f64)> {
    let mut out = Vec::new();
    let (mut sum, mut n, mut cur) = (0.0, 0usize, None);
    for (a, r) in p.angle_deg.iter().zip(&p.residual_um) {
        let b = (a / width).floor() as i64;
        if let Some(c) = cur.filter(|c| *c != b) {
            out.push((c, sum / n as f64));
            (sum, n) = (0.0, 0);
        }
        cur = Some(b);
        sum += r;
        n += 1;
    }
    if let Some(c) = cur {
        out.push((c, sum / n as f64));
    }
    out
}

fn values(bins: &[(i64, f64)]) -> Vec<f64> {
    bins.iter().map(|(_, v)| *v).collect()
}

/// The residual of `p` on the bins of `reference`. A simulation whose arc is cut differently
/// (another start or end of the overlap with the measured arc) lacks some bins at the ends;
/// they take the reference value: no change there, so a sensitivity of zero, instead of
/// shifting every later bin against its neighbour.
fn on_grid(p: &TracePair, width: f64, reference: &[(i64, f64)]) -> Vec<f64> {
    let own: std::collections::BTreeMap<i64, f64> = bin(p, width).into_iter().collect();
    reference
        .iter()
        .map(|(k, v)| own.get(k).copied().unwrap_or(*v))
        .collect()
}

/// The values of `bins` (per trace) at `rows` ((trace, bin) pairs), in order.
fn stack(bins: &[Vec<f64>], rows: &[(usize, usize)]) -> Vec<f64> {
    rows.iter().map(|(t, b)| bins[*t][*b]).collect()
}

/// Whether a gap of RMS `before` left at `after` counts as explained: at most `floor`, or at
/// most `fraction` of `before` (either unit).
pub(crate) fn explained(before: f64, after: f64, floor: f64, fraction: f64) -> bool {
    after <= floor || after <= fraction * before
}

pub(crate) fn rss(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum()
}

fn rms(v: &[f64]) -> f64 {
    (rss(v) / v.len().max(1) as f64).sqrt()
}

/// The RMS of `a − b`, element by element: how much a residual changed.
fn rms_between(a: &[f64], b: &[f64]) -> f64 {
    rms(&a.iter().zip(b).map(|(x, y)| x - y).collect::<Vec<_>>())
}

/// The Bayesian information criterion of a least-squares fit: `n ln(RSS/n) + k ln n`.
pub(crate) fn bic(rss: f64, n: usize, k: usize) -> f64 {
    let n_f = n as f64;
    n_f * (rss / n_f).max(1e-300).ln() + k as f64 * n_f.ln()
}

/// Least squares `min ‖y − A β‖²` by normal equations with a tiny ridge for safety.
fn solve(columns: &[&[f64]], y: &[f64]) -> Option<Vec<f64>> {
    let k = columns.len();
    let ata = DMatrix::from_fn(k, k, |i, j| {
        columns[i]
            .iter()
            .zip(columns[j])
            .map(|(a, b)| a * b)
            .sum::<f64>()
    });
    let aty = DVector::from_fn(k, |i, _| {
        columns[i].iter().zip(y).map(|(a, b)| a * b).sum::<f64>()
    });
    let scale = (0..k).map(|i| ata[(i, i)]).fold(0.0, f64::max);
    let ridge = DMatrix::identity(k, k) * (scale * 1e-12);
    (ata + ridge)
        .cholesky()
        .map(|c| c.solve(&aty).iter().copied().collect())
}

fn minus(y: &[f64], columns: &[&[f64]], beta: &[f64]) -> Vec<f64> {
    (0..y.len())
        .map(|i| y[i] - columns.iter().zip(beta).map(|(c, b)| c[i] * b).sum::<f64>())
        .collect()
}

fn slices(columns: &[Vec<f64>]) -> Vec<&[f64]> {
    columns.iter().map(Vec::as_slice).collect()
}

/// The paired test of a rival's residual `rival` against the chosen one's `chosen` over the
/// judging `segments` (positions into both): the t statistic of the per-segment excess of mean
/// square and its one-sided p-value (small: the rival is worse).
pub(crate) fn paired_excess(rival: &[f64], chosen: &[f64], segments: &[Vec<usize>]) -> (f64, f64) {
    let excess: Vec<f64> = segments
        .iter()
        .map(|s| {
            s.iter()
                .map(|&i| rival[i] * rival[i] - chosen[i] * chosen[i])
                .sum::<f64>()
                / s.len() as f64
        })
        .collect();
    let n = excess.len() as f64;
    if excess.len() < 2 {
        return (0.0, 1.0);
    }
    let mean = excess.iter().sum::<f64>() / n;
    let sd = (excess.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    let t = if sd > 0.0 {
        mean / (sd / n.sqrt())
    } else if mean > 0.0 {
        f64::INFINITY
    } else {
        0.0
    };
    let p = StudentsT::new(0.0, 1.0, n - 1.0).map_or(1.0, |d| 1.0 - d.cdf(t));
    (t, p)
}

/// A candidate's linear fit.
#[derive(Clone)]
struct Candidate {
    /// The effects it adds (one; two for a rival pair).
    effects: Vec<usize>,
    /// Every parameter fitted: the baseline's, the chosen effects', its own.
    params: Vec<usize>,
    beta: Vec<f64>,
    bic_change: f64,
    select_rss: f64,
}

/// The residual bins of a simulation: per measured trace.
type Simulated = (Vec<TracePair>, Vec<Vec<f64>>);

/// A candidate verified ahead of its step ([`Options::speculate`]): its fit as the step makes
/// it, its offsets after verification and the outcome.
struct Ahead {
    fit: Candidate,
    beta: Vec<f64>,
    outcome: Result<Simulated, GapError>,
}

/// The state of a forward selection.
struct Selector<'a> {
    model: &'a dyn Forward,
    measured: &'a [Trace],
    library: &'a [Effect],
    rows: Rows,
    o: &'a Options,
    available: Vec<Available>,
    /// Per available parameter, per measured trace: the model's binned sensitivity.
    sensitivities: Vec<Vec<Vec<f64>>>,
    /// The bins every simulation is read on.
    grid: Grid,
    /// The residual of the model as given on the fit, select and judge bins.
    given: [Vec<f64>; 3],
    simulations: AtomicUsize,
}

impl Selector<'_> {
    /// The parameters fitted with `chosen` effects and `extra` ones: the baseline's, then the
    /// effects', in library order.
    fn params(&self, chosen: &[usize], extra: &[usize]) -> Vec<usize> {
        (0..self.available.len())
            .filter(|i| {
                let owner = self.available[*i].effect;
                self.library[owner].baseline || chosen.contains(&owner) || extra.contains(&owner)
            })
            .collect()
    }

    fn columns(&self, params: &[usize], role: Role) -> Vec<Vec<f64>> {
        let rows = self.rows.of(role);
        params
            .iter()
            .map(|p| stack(&self.sensitivities[*p], rows))
            .collect()
    }

    fn given(&self, role: Role) -> &[f64] {
        &self.given[role as usize]
    }

    /// The linear fit of `chosen` and `extra` effects on the fit bins, scored on the select
    /// bins; `None` when singular.
    fn fit(&self, chosen: &[usize], extra: &[usize], cur_bic: f64) -> Option<Candidate> {
        let params = self.params(chosen, extra);
        let fit = self.columns(&params, Role::Fit);
        let select = self.columns(&params, Role::Select);
        let beta = solve(&slices(&fit), self.given(Role::Fit))?;
        let fit_rss = rss(&minus(self.given(Role::Fit), &slices(&fit), &beta));
        let select_rss = rss(&minus(self.given(Role::Select), &slices(&select), &beta));
        let bic_change = bic(fit_rss, self.given(Role::Fit).len(), params.len()) - cur_bic;
        Some(Candidate {
            effects: extra.to_vec(),
            params,
            beta,
            bic_change,
            select_rss,
        })
    }

    /// The effects that can be candidates: available, not baseline, not `chosen`, not hidden.
    fn pool(&self, chosen: &[usize], hidden: &[&str]) -> Vec<usize> {
        (0..self.library.len())
            .filter(|e| {
                !chosen.contains(e)
                    && !self.library[*e].baseline
                    && !hidden.contains(&self.library[*e].key.as_str())
                    && self.available.iter().any(|p| p.effect == *e)
            })
            .collect()
    }

    /// Every candidate of `pool`, fitted jointly with the chosen ones.
    fn candidates(&self, chosen: &[usize], pool: &[usize], cur_bic: f64) -> Vec<Candidate> {
        pool.iter()
            .filter_map(|e| self.fit(chosen, &[*e], cur_bic))
            .collect()
    }

    /// The first parameter of a non-baseline effect in `c` a machine cannot have.
    fn implausible(&self, c: &Candidate) -> Option<Rejected> {
        c.params.iter().zip(&c.beta).find_map(|(p, b)| {
            let a = &self.available[*p];
            if self.library[a.effect].baseline {
                return None;
            }
            a.param
                .check(&a.models(), *b)
                .err()
                .map(|implausible| Rejected {
                    effect: self.library[a.effect].key.clone(),
                    implausible,
                })
        })
    }

    /// The first of `ranked` a machine of the model's class can have, simulated at its fitted
    /// values ([`Selector::verify_ahead`]); the implausible ones, before or after their
    /// simulation, join `rejected` (once per effect). A fit the model refuses is passed over.
    fn first_plausible(
        &self,
        ranked: Vec<Candidate>,
        chosen: &[usize],
        hidden: &[&str],
        cur_bic: f64,
        ahead: &mut Option<Ahead>,
        rejected: &mut Vec<Rejected>,
    ) -> Result<Option<(Candidate, Simulated)>, GapError> {
        let mut reject = |r: Rejected| {
            if !rejected.iter().any(|x| x.effect == r.effect) {
                rejected.push(r);
            }
        };
        for mut c in ranked {
            if let Some(r) = self.implausible(&c) {
                reject(r);
                continue;
            }
            match self.verify_ahead(&mut c, chosen, hidden, cur_bic, ahead) {
                Ok(simulated) => match self.implausible(&c) {
                    Some(r) => reject(r),
                    None => return Ok(Some((c, simulated))),
                },
                Err(GapError::Model(_)) => continue,
                Err(e) => return Err(e),
            }
        }
        Ok(None)
    }

    /// The step's gates on verified candidate `c` with simulated residual `bins`, from the
    /// current residual `before` (select RSS `cur_select`, fit BIC `cur_bic`): the fit BIC
    /// drops by [`Options::min_bic_drop`], the select bins' mean square shrinks by
    /// [`Options::min_select_shrink`] of what is left and changes by
    /// [`Options::min_effect_um`] RMS. `(select RSS, BIC, shrink)` when it passes.
    fn gates(
        &self,
        c: &Candidate,
        bins: &[Vec<f64>],
        before: &[Vec<f64>],
        cur_select: f64,
        cur_bic: f64,
    ) -> Option<(f64, f64, f64)> {
        let o = self.o;
        let fit = rss(&stack(bins, &self.rows.fit));
        let select_new = stack(bins, &self.rows.select);
        let select = rss(&select_new);
        let new_bic = bic(fit, self.rows.fit.len(), c.params.len());
        let shrink = 1.0 - select / cur_select;
        let change = rms_between(&stack(before, &self.rows.select), &select_new);
        (new_bic <= cur_bic - o.min_bic_drop
            && shrink >= o.min_select_shrink
            && change >= o.min_effect_um)
            .then_some((select, new_bic, shrink))
    }

    /// The pairs of `pool` effects the gap needs together: fitted jointly with `chosen`, the
    /// pair lowers the fit BIC by [`Options::min_bic_drop`] from `cur_bic` and by as much from
    /// each of its effects alone (`singles`: each effect's BIC change alone), and its linear
    /// prediction passes the other gates from the current residual `now` (simulated; select
    /// RSS `cur_select`): a shrink of [`Options::min_select_shrink`] and a change of
    /// [`Options::min_effect_um`]. Best predicted select residual first; only these are
    /// simulated, two simulations each.
    fn needed_pairs(
        &self,
        chosen: &[usize],
        pool: &[usize],
        singles: &[(usize, f64)],
        (cur_bic, cur_select): (f64, f64),
        now: &[Vec<f64>],
    ) -> Vec<Candidate> {
        let alone = |e: usize| {
            singles
                .iter()
                .find(|(s, _)| *s == e)
                .map_or(0.0, |(_, b)| *b)
        };
        let o = self.o;
        let now = stack(now, &self.rows.select);
        let change = |c: &Candidate| rms_between(&now, &self.linear(c, Role::Select));
        let sets: Vec<[usize; 2]> = pool
            .iter()
            .enumerate()
            .flat_map(|(k, a)| pool[k + 1..].iter().map(move |b| [*a, *b]))
            .collect();
        let mut pairs: Vec<Candidate> = sets
            .par_iter()
            .filter_map(|set| self.fit(chosen, set, cur_bic))
            .filter(|c| {
                c.bic_change < -o.min_bic_drop
                    && c.effects
                        .iter()
                        .all(|e| c.bic_change < alone(*e) - o.min_bic_drop)
                    && 1.0 - c.select_rss / cur_select >= o.min_select_shrink
                    && change(c) >= o.min_effect_um
            })
            .collect();
        pairs.sort_by(|a, b| a.select_rss.total_cmp(&b.select_rss));
        pairs
    }

    /// Simulates the candidate at its fitted values, then once more after a Gauss–Newton step
    /// from the simulated residual on the fit bins, and keeps the better of the two.
    fn verify(&self, c: &mut Candidate) -> Result<Simulated, GapError> {
        let first = self.simulate(&c.params, &c.beta)?;
        let fit = self.columns(&c.params, Role::Fit);
        let Some(delta) = solve(&slices(&fit), &stack(&first.1, &self.rows.fit)) else {
            return Ok(first);
        };
        let refined: Vec<f64> = c.beta.iter().zip(&delta).map(|(b, d)| b + d).collect();
        let second = self.simulate(&c.params, &refined)?;
        let fit_rss = |s: &Simulated| rss(&stack(&s.1, &self.rows.fit));
        if fit_rss(&second) < fit_rss(&first) {
            c.beta = refined;
            Ok(second)
        } else {
            Ok(first)
        }
    }

    /// [`Selector::verify`] of `c`, taken from `ahead` if it was verified there, else
    /// simulated; with [`Options::speculate`], beside it the next step's likeliest candidate
    /// if `c` joins `chosen` ([`Selector::likeliest_after`]), kept in `ahead`. Verification is
    /// a function of the fit alone, so the answer is the same.
    fn verify_ahead(
        &self,
        c: &mut Candidate,
        chosen: &[usize],
        hidden: &[&str],
        cur_bic: f64,
        ahead: &mut Option<Ahead>,
    ) -> Result<Simulated, GapError> {
        if ahead
            .as_ref()
            .is_some_and(|a| a.fit.params == c.params && a.fit.beta == c.beta)
            && let Some(a) = ahead.take()
        {
            c.beta = a.beta;
            return a.outcome;
        }
        let next = (self.o.speculate && chosen.len() + 1 < self.o.max_effects)
            .then(|| self.likeliest_after(chosen, c, hidden, cur_bic))
            .flatten();
        let Some(fit) = next else {
            return self.verify(c);
        };
        let mut verified = fit.clone();
        let (outcome, next_outcome) = rayon::join(|| self.verify(c), || self.verify(&mut verified));
        *ahead = Some(Ahead {
            fit,
            beta: verified.beta,
            outcome: next_outcome,
        });
        outcome
    }

    /// The candidate the step after `c` joins `chosen` would verify first, judged on `c`'s
    /// linear fit in place of its simulation (its select bins' RSS and BIC, `cur_bic` being
    /// the current one): none if that step could not add an effect, else the best on the
    /// select bins of the plausible fits that pass the BIC gate.
    fn likeliest_after(
        &self,
        chosen: &[usize],
        c: &Candidate,
        hidden: &[&str],
        cur_bic: f64,
    ) -> Option<Candidate> {
        if !can_change(c.select_rss, self.rows.select.len(), self.o) {
            return None;
        }
        let with: Vec<usize> = chosen.iter().chain(&c.effects).copied().collect();
        self.candidates(&with, &self.pool(&with, hidden), cur_bic + c.bic_change)
            .into_iter()
            .filter(|n| n.bic_change < -self.o.min_bic_drop && self.implausible(n).is_none())
            .min_by(|a, b| a.select_rss.total_cmp(&b.select_rss))
    }

    fn simulate(&self, params: &[usize], beta: &[f64]) -> Result<Simulated, GapError> {
        self.simulations.fetch_add(1, Ordering::Relaxed);
        let traces = self.model.traces(&self.values(params, beta))?;
        residuals(self.measured, &traces, self.o.bin_deg, Some(&self.grid))
    }

    /// The absolute values of the keys of `params` at offsets `beta`.
    /// A key two parameters share (a guide's static force: friction level and stick-slip)
    /// takes the sum of their offsets' changes to it.
    fn values(&self, params: &[usize], beta: &[f64]) -> Vec<(String, f64)> {
        let mut out: Vec<(String, f64)> = Vec::new();
        for (p, b) in params.iter().zip(beta) {
            let a = &self.available[*p];
            for (k, v) in &a.keys {
                let change = a.param.key_value(*v, *b) - v;
                match out.iter_mut().find(|(key, _)| key == k) {
                    Some((_, total)) => *total += change,
                    None => out.push((k.clone(), v + change)),
                }
            }
        }
        out
    }

    /// The values `c` writes into the model for its effects (the baseline's left out).
    fn edits(&self, c: &Candidate) -> Vec<(String, f64)> {
        let (params, beta): (Vec<usize>, Vec<f64>) = c
            .params
            .iter()
            .zip(&c.beta)
            .filter(|(p, _)| !self.library[self.available[**p].effect].baseline)
            .unzip();
        self.values(&params, &beta)
    }

    /// Fits the baseline parameters (the set-up) alone and simulates them: the model as given,
    /// measured as it was set up. Without baseline parameters, the model as given.
    fn baseline(&self, given: Vec<TracePair>) -> Result<(Candidate, Simulated), GapError> {
        let params = self.params(&[], &[]);
        let fit = self.columns(&params, Role::Fit);
        let beta = match solve(&slices(&fit), self.given(Role::Fit)) {
            Some(b) if !params.is_empty() => b,
            _ => {
                let bins = given
                    .iter()
                    .zip(&self.grid)
                    .map(|(p, reference)| on_grid(p, self.o.bin_deg, reference))
                    .collect();
                let none = Candidate {
                    effects: Vec::new(),
                    params: Vec::new(),
                    beta: Vec::new(),
                    bic_change: 0.0,
                    select_rss: 0.0,
                };
                return Ok((none, (given, bins)));
            }
        };
        let mut c = Candidate {
            effects: Vec::new(),
            params,
            beta,
            bic_change: 0.0,
            select_rss: 0.0,
        };
        let simulated = self.verify(&mut c)?;
        Ok((c, simulated))
    }

    fn fitted(&self, c: &Candidate, only: impl Fn(usize) -> bool) -> Vec<Fitted> {
        c.params
            .iter()
            .zip(&c.beta)
            .filter(|(p, _)| only(self.available[**p].effect))
            .map(|(p, b)| {
                let a = &self.available[*p];
                let keys = match a.param.scale {
                    Scale::Same => Vec::new(),
                    Scale::Reciprocal(_) => a
                        .keys
                        .iter()
                        .map(|(k, v)| (k.clone(), a.param.key_value(*v, *b)))
                        .collect(),
                };
                Fitted {
                    name: a.param.name.clone(),
                    value: *b,
                    unit: a.param.unit.into(),
                    keys,
                }
            })
            .collect()
    }

    fn score(&self, c: &Candidate) -> Score {
        Score {
            effect: self.library[c.effects[0]].key.clone(),
            select_rms_um: (c.select_rss / self.given(Role::Select).len() as f64).sqrt(),
            bic_change: c.bic_change,
        }
    }

    fn judge_rms(&self, bins: &[Vec<f64>]) -> Option<f64> {
        self.rows
            .can_judge()
            .then(|| rms(&stack(bins, &self.rows.judge)))
    }

    /// The steps `c` adds: one per effect, the two of a joint step each naming the other.
    fn steps(&self, c: &Candidate, bins: &[Vec<f64>], shrink: f64) -> Vec<Step> {
        let key = |e: usize| self.library[e].key.clone();
        let values = self.fitted(c, |e| !self.library[e].baseline);
        let (fit_rms_um, select_rms_um) = (
            rms(&stack(bins, &self.rows.fit)),
            rms(&stack(bins, &self.rows.select)),
        );
        let judge_rms_um = self.judge_rms(bins);
        c.effects
            .iter()
            .map(|&e| Step {
                effect: key(e),
                description: self.library[e].description.clone(),
                values: values.clone(),
                fit_rms_um,
                select_rms_um,
                select_shrink: shrink,
                judge_rms_um,
                together_with: c.effects.iter().find(|o| **o != e).map(|o| key(*o)),
            })
            .collect()
    }

    /// The judging bins and segments: the judge's when they are enough, else the select's.
    fn judging(&self) -> (Role, &[Vec<usize>]) {
        if self.rows.can_judge() {
            (Role::Judge, &self.rows.judge_segments)
        } else {
            (Role::Select, &self.rows.select_segments)
        }
    }

    /// The residual the linearised model predicts on the bins of `role` with `c`'s values.
    fn linear(&self, c: &Candidate, role: Role) -> Vec<f64> {
        let columns = self.columns(&c.params, role);
        minus(self.given(role), &slices(&columns), &c.beta)
    }

    /// The rivals of each chosen effect that explain the judging bins as well (module doc);
    /// `chosen_bins` are the simulated residual with the chosen effects, `initial_bins` that
    /// of the model as given with its set-up fitted (the gap a rival must explain).
    fn alternatives(
        &self,
        chosen: &[usize],
        chosen_bins: &[Vec<f64>],
        initial_bins: &[Vec<f64>],
        hidden: &[&str],
    ) -> Result<Vec<Alternative>, GapError> {
        let (role, segments) = self.judging();
        let segments = segments.to_vec();
        let chosen_now = stack(chosen_bins, self.rows.of(role));
        let mut out = Vec::new();
        for &effect in chosen {
            let others: Vec<usize> = chosen.iter().copied().filter(|e| *e != effect).collect();
            let Some(mine) = self.fit(&others, &[effect], 0.0) else {
                continue;
            };
            let mine_linear = self.linear(&mine, role);
            let pool = self.pool(chosen, hidden);
            let mut sets: Vec<Vec<usize>> = pool.iter().map(|e| vec![*e]).collect();
            for (k, a) in pool.iter().enumerate() {
                sets.extend(pool[k + 1..].iter().map(|b| vec![*a, *b]));
            }
            let before = rms(&stack(initial_bins, self.rows.of(role)));
            let as_good = |r: &[f64], test: (f64, f64)| {
                test.1 > self.o.ambiguity_level
                    && explained(
                        before,
                        rms(r),
                        self.o.explained_floor_um,
                        self.o.explained_fraction,
                    )
            };
            let mut rivals: Vec<(Candidate, Vec<f64>, (f64, f64))> = sets
                .par_iter()
                .filter_map(|set| {
                    let c = self.fit(&others, set, 0.0)?;
                    let r = self.linear(&c, role);
                    let test = paired_excess(&r, &mine_linear, &segments);
                    as_good(&r, test).then_some((c, r, test))
                })
                .collect();
            // A pair holding an effect that is as good alone adds nothing to it.
            let singles: Vec<usize> = rivals
                .iter()
                .filter(|r| r.0.effects.len() == 1)
                .map(|r| r.0.effects[0])
                .collect();
            rivals.retain(|r| {
                r.0.effects.len() == 1 || !r.0.effects.iter().any(|e| singles.contains(e))
            });
            rivals.sort_by(|a, b| rss(&a.1).total_cmp(&rss(&b.1)));
            let chosen_key = self.library[effect].key.clone();
            let mut simulated = 0;
            for (mut c, r, (t, p)) in rivals {
                let own = |e: usize| c.effects.contains(&e);
                let mut alt = Alternative {
                    instead_of: chosen_key.clone(),
                    effects: c
                        .effects
                        .iter()
                        .map(|e| self.library[*e].key.clone())
                        .collect(),
                    values: self.fitted(&c, own),
                    rms_um: rms(&r),
                    chosen_rms_um: rms(&mine_linear),
                    t,
                    p_value: p,
                    implausible: self.implausible(&c).map(|r| r.implausible),
                    edits: self.edits(&c),
                };
                if alt.implausible.is_some() {
                    // Reported as a fit that needs an implausible size: no simulation.
                    out.push(alt);
                    continue;
                }
                if simulated == MAX_RIVALS_SIMULATED {
                    continue;
                }
                simulated += 1;
                let (_, bins) = match self.verify(&mut c) {
                    Ok(s) => s,
                    Err(GapError::Model(_)) => continue,
                    Err(e) => return Err(e),
                };
                let rival = stack(&bins, self.rows.of(role));
                let (t, p) = paired_excess(&rival, &chosen_now, &segments);
                if as_good(&rival, (t, p)) {
                    alt.values = self.fitted(&c, |e| c.effects.contains(&e));
                    alt.implausible = self.implausible(&c).map(|r| r.implausible);
                    alt.edits = self.edits(&c);
                    (alt.rms_um, alt.chosen_rms_um, alt.t, alt.p_value) =
                        (rms(&rival), rms(&chosen_now), t, p);
                    out.push(alt);
                }
            }
        }
        Ok(out)
    }
}

/// The library's parameters the model can express, and the effects it cannot (with the first
/// missing key).
fn availability(
    model: &dyn Forward,
    library: &[Effect],
) -> (Vec<Available>, Vec<(String, String)>) {
    let (mut available, mut unavailable) = (Vec::new(), Vec::new());
    for (e, effect) in library.iter().enumerate() {
        let missing = effect
            .params
            .iter()
            .flat_map(|p| &p.keys)
            .find(|k| model.value(k).is_none());
        if let Some(key) = missing {
            unavailable.push((effect.key.clone(), key.clone()));
            continue;
        }
        available.extend(effect.params.iter().map(|p| {
            Available {
                effect: e,
                param: p.clone(),
                keys: p
                    .keys
                    .iter()
                    .map(|k| (k.clone(), model.value(k).unwrap_or_default()))
                    .collect(),
            }
        }));
    }
    (available, unavailable)
}

/// The model linearised about its given values: the simulated traces of the model as given
/// and with each available parameter stepped (one simulation each, in parallel). It depends on
/// the model only, so many measured sets can share it.
pub struct Linearisation {
    available: Vec<Available>,
    /// Effects the model cannot express, with the first missing key.
    pub unavailable: Vec<(String, String)>,
    base: Vec<Trace>,
    stepped: Vec<Vec<Trace>>,
    /// The model's own job read as a measurement, for [`Linearisation::visibility`]: made
    /// once, as every case of a bench asks for it.
    own: OnceLock<OwnJob>,
}

/// The model's own traces as the measured ones: their rows, bins and sensitivities.
struct OwnJob {
    bin_deg: f64,
    rows: Rows,
    grid: Grid,
    sensitivities: Vec<Vec<Vec<f64>>>,
}

impl Linearisation {
    /// Simulates `model` as given and once per available parameter of `library`.
    pub fn new(model: &dyn Forward, library: &[Effect]) -> Result<Self, GapError> {
        let (available, unavailable) = availability(model, library);
        let stepped_traces = |p: &Available| {
            let values: Vec<(String, f64)> = p
                .keys
                .iter()
                .map(|(k, v)| (k.clone(), p.param.key_value(*v, p.param.step)))
                .collect();
            model.sensitivity_traces(&values)
        };
        // Parameters that change the motion are simulated beside the model as given; those a
        // replay of its recorded motion answers follow it, while the others still simulate.
        let replayable = |p: &Available| p.keys.iter().all(|(k, _)| model.replayable(k));
        let evaluate = |replays: bool| {
            available
                .par_iter()
                .map(|p| {
                    (replayable(p) == replays)
                        .then(|| stepped_traces(p))
                        .transpose()
                })
                .collect::<Result<Vec<Option<Vec<Trace>>>, GapError>>()
        };
        let ((base, replayed), moving) =
            rayon::join(|| (model.traces(&[]), evaluate(true)), || evaluate(false));
        let (base, replayed, moving) = (base?, replayed?, moving?);
        // Each parameter is either replayed or simulated.
        let stepped = replayed
            .into_iter()
            .zip(moving)
            .filter_map(|(r, m)| r.or(m))
            .collect();
        Ok(Self {
            available,
            unavailable,
            base,
            stepped,
            own: OnceLock::new(),
        })
    }

    /// Simulations it took.
    pub fn simulations(&self) -> usize {
        1 + self.stepped.len()
    }

    /// The model's traces as given.
    pub fn base(&self) -> &[Trace] {
        &self.base
    }

    /// Per parameter, per measured trace: the model's binned sensitivity at the measured angles.
    fn sensitivities(
        &self,
        measured: &[Trace],
        grid: &Grid,
        o: &Options,
    ) -> Result<Vec<Vec<Vec<f64>>>, GapError> {
        self.available
            .par_iter()
            .zip(&self.stepped)
            .map(|(p, traces)| {
                let (_, bins) = residuals(measured, traces, o.bin_deg, Some(grid))?;
                // Residual = measured − model, so the model's sensitivity is the residual's drop.
                Ok(grid
                    .iter()
                    .zip(&bins)
                    .map(|(b0, b1)| {
                        b0.iter()
                            .zip(b1)
                            .map(|((_, x), y)| (x - y) / p.param.step)
                            .collect()
                    })
                    .collect())
            })
            .collect()
    }

    fn own_job(&self, o: &Options) -> Result<OwnJob, GapError> {
        let split = Split::automatic(&self.base)?;
        let (pairs, _) = residuals(&self.base, &self.base, o.bin_deg, None)?;
        let grid: Grid = pairs.iter().map(|p| bin(p, o.bin_deg)).collect();
        let sensitivities = self.sensitivities(&self.base, &grid, o)?;
        Ok(OwnJob {
            bin_deg: o.bin_deg,
            rows: Rows::new(&split, &grid, o.bin_deg),
            grid,
            sensitivities,
        })
    }

    /// How far offsets of the model's parameters (`(key, offset)`, keys the model cannot
    /// express ignored; a parameter of several keys takes its first key's offset) stand out on
    /// the model's own job: the RMS change, µm, that the linearisation predicts once the
    /// baseline (the bar's set-up) is fitted to the fit bins, as the selection fits it, on the
    /// select bins and on the judge bins, whichever is less (the select bins alone when the
    /// judge bins are too few). Below [`Options::min_effect_um`] no selection can attribute
    /// them: it gates on the select bins and the judgement reads the judge bins.
    pub fn visibility(
        &self,
        library: &[Effect],
        offsets: &[(String, f64)],
        o: &Options,
    ) -> Result<f64, GapError> {
        let signature = |sens: &[Vec<Vec<f64>>], grid: &Grid| -> Vec<Vec<f64>> {
            let offset = |p: &Available| {
                offsets
                    .iter()
                    .find(|(k, _)| *k == p.keys[0].0)
                    .map_or(0.0, |(_, v)| *v)
            };
            (0..grid.len())
                .map(|t| {
                    (0..grid[t].len())
                        .map(|b| {
                            self.available
                                .iter()
                                .zip(sens)
                                .map(|(p, s)| s[t][b] * offset(p))
                                .sum()
                        })
                        .collect()
                })
                .collect()
        };
        self.own_visibility(library, o, &signature)
    }

    /// How far a change of the model's traces stands out on its own job, as
    /// [`Linearisation::visibility`] measures it: `changed` are the model's traces with the
    /// change (simulated noise-free), read as the selection reads a measurement.
    pub fn visibility_of(
        &self,
        library: &[Effect],
        changed: &[Trace],
        o: &Options,
    ) -> Result<f64, GapError> {
        let (_, bins) = residuals(changed, &self.base, o.bin_deg, None)?;
        let signature = |_: &[Vec<Vec<f64>>], grid: &Grid| -> Vec<Vec<f64>> {
            // The change on the own job's grid; a bin the changed run lacks changes nothing.
            grid.iter()
                .zip(&bins)
                .map(|(g, b)| {
                    (0..g.len())
                        .map(|i| b.get(i).copied().unwrap_or(0.0))
                        .collect()
                })
                .collect()
        };
        self.own_visibility(library, o, &signature)
    }

    fn own_visibility(
        &self,
        library: &[Effect],
        o: &Options,
        signature: Signature<'_>,
    ) -> Result<f64, GapError> {
        if self.own.get().is_none() {
            let _ = self.own.set(self.own_job(o)?);
        }
        let fresh;
        let own = match self.own.get() {
            Some(own) if own.bin_deg == o.bin_deg => own,
            _ => {
                fresh = self.own_job(o)?;
                &fresh
            }
        };
        let (rows, sens) = (&own.rows, &own.sensitivities);
        let signature = signature(sens, &own.grid);
        let baseline: Vec<usize> = (0..self.available.len())
            .filter(|i| library[self.available[*i].effect].baseline)
            .collect();
        let columns = |rows: &[(usize, usize)]| -> Vec<Vec<f64>> {
            baseline.iter().map(|p| stack(&sens[*p], rows)).collect()
        };
        let fit = columns(&rows.fit);
        let beta = solve(&slices(&fit), &stack(&signature, &rows.fit))
            .unwrap_or_else(|| vec![0.0; fit.len()]);
        let left = |rows: &[(usize, usize)]| {
            rms(&minus(
                &stack(&signature, rows),
                &slices(&columns(rows)),
                &beta,
            ))
        };
        // The selection gates on the select bins and the judgement reads the judge bins: an
        // effect is seen only as far as it stands out on both.
        Ok(if rows.can_judge() {
            left(&rows.select).min(left(&rows.judge))
        } else {
            left(&rows.select)
        })
    }
}

/// Runs the forward selection of `library` effects (the library `lin` was made from) on
/// `model` against `measured`.
pub fn select(
    model: &dyn Forward,
    lin: &Linearisation,
    measured: &[Trace],
    library: &[Effect],
    split: Split,
    o: &Options,
) -> Result<Selection, GapError> {
    select_without(model, lin, measured, library, &[], split, o)
}

/// [`select`] with the effects named in `hidden` left out of the candidates (a library that
/// lacks them, as in the out-of-library cases of the bench).
pub fn select_without(
    model: &dyn Forward,
    lin: &Linearisation,
    measured: &[Trace],
    library: &[Effect],
    hidden: &[&str],
    split: Split,
    o: &Options,
) -> Result<Selection, GapError> {
    let (given_pairs, base_bins) = residuals(measured, &lin.base, o.bin_deg, None)?;
    let grid: Grid = given_pairs.iter().map(|p| bin(p, o.bin_deg)).collect();
    let rows = Rows::new(&split, &grid, o.bin_deg);
    if rows.fit.is_empty() || rows.select.is_empty() {
        return Err(GapError::Model(
            "the measured runs hold no bins to fit or none to select with: give longer arcs, \
             two directions or more tests"
                .into(),
        ));
    }
    let sensitivities = lin.sensitivities(measured, &grid, o)?;
    // The other effects' shapes: what the library's candidates that are no whole-travel shape
    // (and are not hidden) would change, so that their mismatch is not taken for a change.
    let others: Vec<&Vec<Vec<f64>>> = lin
        .available
        .iter()
        .zip(&sensitivities)
        .filter(|(a, _)| {
            let e = &library[a.effect];
            !e.baseline && e.whole_travel.is_none() && !hidden.contains(&e.key.as_str())
        })
        .map(|(_, s)| s)
        .collect();
    let local_changes = local_changes(
        model,
        measured,
        (&lin.base, &given_pairs),
        (&grid, &others),
        &split,
        o,
    )?;
    let set_aside: Vec<&str> = library
        .iter()
        .filter(|e| {
            local_changes
                .iter()
                .any(|c| e.whole_travel == Some((c.axis, c.direction)))
        })
        .map(|e| e.key.as_str())
        .collect();
    let hidden: &[&str] = &[hidden, &set_aside].concat();
    let given = [Role::Fit, Role::Select, Role::Judge].map(|r| stack(&base_bins, rows.of(r)));
    let sel = Selector {
        model,
        measured,
        library,
        rows,
        o,
        simulations: AtomicUsize::new(0),
        available: lin.available.clone(),
        sensitivities,
        grid,
        given,
    };
    let n_fit = sel.rows.fit.len();
    let (base, (initial_pairs, initial_bins)) = sel.baseline(given_pairs)?;
    let baseline = sel.fitted(&base, |_| true);
    let select_of = |bins: &[Vec<f64>], rows: &Rows| stack(bins, &rows.select);
    let mut cur_select = rss(&select_of(&initial_bins, &sel.rows));
    let cur_fit = rss(&stack(&initial_bins, &sel.rows.fit));
    let mut cur_bic = bic(cur_fit, n_fit, base.params.len());
    let fit_before_um = (cur_fit / n_fit as f64).sqrt();
    let n_select = sel.rows.select.len();
    let select_before_um = (cur_select / n_select as f64).sqrt();
    let judge_before = sel.judge_rms(&initial_bins);
    let (mut chosen, mut steps, mut last_round, mut rejected) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut final_pairs, mut final_bins, mut best_so_far) =
        (initial_pairs.clone(), initial_bins.clone(), base);
    let mut ahead = None;
    // A gap already at the explained floor needs no effect: the model as given explains the
    // measurement to the level of its small mismatches.
    while chosen.len() < o.max_effects
        && select_before_um > o.explained_floor_um
        && can_change(cur_select, n_select, o)
    {
        let pool = sel.pool(&chosen, hidden);
        let candidates = sel.candidates(&chosen, &pool, cur_bic);
        last_round = candidates.iter().map(|c| sel.score(c)).collect();
        last_round.sort_by(|a, b| a.select_rms_um.total_cmp(&b.select_rms_um));
        let singles: Vec<(usize, f64)> = candidates
            .iter()
            .map(|c| (c.effects[0], c.bic_change))
            .collect();
        let ranked = passing_bic(candidates, o);
        let mut taken =
            sel.first_plausible(ranked, &chosen, hidden, cur_bic, &mut ahead, &mut rejected)?;
        let mut gates = taken
            .as_ref()
            .and_then(|(best, (_, bins))| sel.gates(best, bins, &final_bins, cur_select, cur_bic));
        // Two effects that the gap needs together, when neither passes alone.
        if gates.is_none() && chosen.len() + 2 <= o.max_effects {
            let pairs =
                sel.needed_pairs(&chosen, &pool, &singles, (cur_bic, cur_select), &final_bins);
            taken =
                sel.first_plausible(pairs, &chosen, hidden, cur_bic, &mut ahead, &mut rejected)?;
            gates = taken.as_ref().and_then(|(best, (_, bins))| {
                sel.gates(best, bins, &final_bins, cur_select, cur_bic)
            });
        }
        let (Some((best, (pairs, bins))), Some((select, new_bic, shrink))) = (taken, gates) else {
            break;
        };
        steps.extend(sel.steps(&best, &bins, shrink));
        chosen.extend(&best.effects);
        (cur_select, cur_bic, final_pairs, final_bins) = (select, new_bic, pairs, bins);
        best_so_far = best;
    }
    let judged = judge_before.map(|before_um| Judged {
        bins: sel.rows.judge.len(),
        segments: sel.rows.judge_segments.len(),
        before_um,
        after_um: sel.judge_rms(&final_bins).unwrap_or(before_um),
    });
    let alternatives = sel.alternatives(&chosen, &final_bins, &initial_bins, hidden)?;
    let final_values = sel.edits(&best_so_far);
    let alternatives_judged_on = if sel.rows.can_judge() {
        "judge"
    } else {
        "select"
    };
    Ok(Selection {
        bins: [
            sel.rows.fit.len(),
            sel.rows.select.len(),
            sel.rows.judge.len(),
        ],
        fit_before_um,
        select_before_um,
        judged,
        baseline,
        steps,
        rejected,
        local_changes,
        set_aside: set_aside.iter().map(|k| k.to_string()).collect(),
        alternatives,
        alternatives_judged_on,
        unavailable: lin.unavailable.clone(),
        last_round,
        final_pairs,
        initial_pairs,
        final_values,
        simulations: sel.simulations.into_inner(),
        split,
    })
}

/// The changes of one axis' error over a stretch ([`crate::axis_change::scan_beyond`]) in the
/// residual of the model as given, `pairs` (of `measured` against `base`), on the fit and
/// select bins alone (the judge bins stay untouched), each plane's runs apart, against the
/// smooth shapes up to the cubic and the `others`' shapes (per shape, per run, on `grid`):
/// those the circles see begin and end, both ends of the stretch within the axis positions
/// they reach, to the scan's step. Such a change is local, a defect under a carriage or a
/// worn stretch of a screw, not the smooth shape of an error of the whole travel, however well
/// a curve over the travel fits the stretch it is seen on.
fn local_changes(
    model: &dyn Forward,
    measured: &[Trace],
    (base, pairs): (&[Trace], &[TracePair]),
    (grid, others): (&Grid, &[&Vec<Vec<f64>>]),
    split: &Split,
    o: &Options,
) -> Result<Vec<AxisChange>, GapError> {
    let known = model.circles();
    if known.is_empty() {
        return Ok(Vec::new());
    }
    let circles: Vec<Option<Circle>> = partners(measured, base)?
        .into_iter()
        .map(|i| known.get(i).copied())
        .collect();
    Ok(crate::peaks::once_each(pairs.iter().map(|p| p.plane))
        .into_iter()
        .filter_map(|plane| {
            let runs: Vec<usize> = (0..pairs.len())
                .filter(|i| pairs[*i].plane == plane)
                .collect();
            let untouched: Vec<TracePair> = runs
                .iter()
                .map(|i| without_judge(&pairs[*i], *i, split))
                .collect();
            let own: Vec<Option<Circle>> = runs.iter().map(|i| circles[*i]).collect();
            let shapes: Vec<crate::axis_change::Shape> = others
                .iter()
                .map(|s| {
                    runs.iter()
                        .map(|i| by_degree(&grid[*i], &s[*i], o.bin_deg))
                        .collect()
                })
                .collect();
            // Against the smooth shapes the library's candidates have (a positioning S too).
            let c = crate::axis_change::scan_beyond(&untouched, &own, o.min_effect_um, 3, &shapes)?;
            let side = usize::from(plane.axes().1 == c.axis);
            let (lo, hi) = crate::axis_change::reach(&untouched, &own, side)?;
            let step = crate::axis_change::PLACE_STEP_MM;
            let (from, to) = (c.at_mm - 0.5 * c.width_mm, c.at_mm + 0.5 * c.width_mm);
            (from >= lo - step && to <= hi + step).then_some(c)
        })
        .collect())
}

/// A run's `values` on its `grid` bins (keys `⌊angle/width⌋`) by degree of the angle
/// (`⌊angle⌋ mod 360`), the mean of the bins that fall in a degree; zero where none does.
fn by_degree(grid: &[(i64, f64)], values: &[f64], width: f64) -> [f64; 360] {
    let (mut sum, mut n) = ([0.0; 360], [0usize; 360]);
    for ((key, _), v) in grid.iter().zip(values) {
        let first = (*key as f64 * width).floor() as i64;
        let last = (((key + 1) as f64 * width).ceil() as i64 - 1).max(first);
        for d in first..=last {
            let d = d.rem_euclid(360) as usize;
            sum[d] += v;
            n[d] += 1;
        }
    }
    std::array::from_fn(|d| if n[d] > 0 { sum[d] / n[d] as f64 } else { 0.0 })
}

/// Run number `run` of `p` without its samples in judge segments.
fn without_judge(p: &TracePair, run: usize, split: &Split) -> TracePair {
    let keep: Vec<bool> = p
        .angle_deg
        .iter()
        .map(|a| Role::of(split.segment(*a), run) != Role::Judge)
        .collect();
    let pick = |v: &[f64]| -> Vec<f64> {
        v.iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(x, _)| *x)
            .collect()
    };
    TracePair {
        angle_deg: pick(&p.angle_deg),
        residual_um: pick(&p.residual_um),
        time_s: pick(&p.time_s),
        ..p.clone()
    }
}

/// The candidates whose fit lowers the fit bins' BIC by at least [`Options::min_bic_drop`],
/// best predicted select residual first.
fn passing_bic(candidates: Vec<Candidate>, o: &Options) -> Vec<Candidate> {
    let mut ranked: Vec<Candidate> = candidates
        .into_iter()
        .filter(|c| c.bic_change < -o.min_bic_drop)
        .collect();
    ranked.sort_by(|a, b| a.select_rss.total_cmp(&b.select_rss));
    ranked
}

/// Whether an effect could still pass: its change `c` of the select bins' residual `r` (RMS)
/// must reach [`Options::min_effect_um`] while leaving at most `1 − s` of the mean square, and
/// `c ≤ rms(r) + rms(r_new) ≤ rms(r)·(1 + sqrt(1 − s))`; a residual below that bound needs no
/// candidate simulated.
fn can_change(select_rss: f64, n: usize, o: &Options) -> bool {
    let now = (select_rss / n.max(1) as f64).sqrt();
    now * (1.0 + (1.0 - o.min_select_shrink).max(0.0).sqrt()) >= o.min_effect_um
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pair(angles: std::ops::Range<i32>, residual: impl Fn(f64) -> f64) -> TracePair {
        let angle_deg: Vec<f64> = angles.map(|a| a as f64 * 0.5).collect();
        TracePair {
            label: "t".into(),
            plane: vmt_ballbar::Plane::Xy,
            sense: vmt_ballbar::Sense::Ccw,
            radius_mm: 100.0,
            feed_mm_min: 1000.0,
            time_s: angle_deg.iter().map(|a| a / 10.0).collect(),
            residual_um: angle_deg.iter().map(|a| residual(*a)).collect(),
            angle_deg,
        }
    }

    #[test]
    fn a_simulation_cut_shorter_is_read_on_the_reference_bins() {
        // Reference: 0 … 99.5° in 1° bins; the other simulation covers 3 … 96.5° only and
        // differs from the reference by 1 µm everywhere it has samples.
        let reference = bin(&pair(0..200, |a| a), 1.0);
        let short = pair(6..194, |a| a - 1.0);
        let on = on_grid(&short, 1.0, &reference);
        assert_eq!(on.len(), reference.len());
        for ((key, r), v) in reference.iter().zip(&on) {
            let expected = if (3..97).contains(key) { r - 1.0 } else { *r };
            assert!((v - expected).abs() < 1e-12, "bin {key}: {v} vs {expected}");
        }
    }

    /// The paired test against a closed form: segments whose excess is a constant c plus
    /// alternating ±e have mean c and sample sd e·sqrt(S/(S−1)), so t = c·sqrt(S−1)/e.
    #[test]
    fn the_paired_excess_is_students_t_of_the_segments() {
        let (c, e, s): (f64, f64, usize) = (0.02, 0.01, 6);
        let segments: Vec<Vec<usize>> = (0..s).map(|i| vec![2 * i, 2 * i + 1]).collect();
        let chosen = vec![0.1; 2 * s];
        let rival: Vec<f64> = (0..2 * s)
            .map(|i| {
                let sign: f64 = if (i / 2) % 2 == 0 { 1.0 } else { -1.0 };
                (0.01 + c + sign * e).sqrt()
            })
            .collect();
        let (t, p) = paired_excess(&rival, &chosen, &segments);
        let expected = c * ((s - 1) as f64).sqrt() / e;
        assert!((t - expected).abs() < 1e-9, "t {t} vs {expected}");
        // Student's t with 5 dof: P(T > 4.472) = 0.00329 (tables).
        assert!((p - 0.00329).abs() < 2e-4, "p {p}");
        let (t, p) = paired_excess(&chosen, &chosen, &segments);
        assert_eq!((t, p), (0.0, 0.5));
    }
}
