//! Which unmodelled effect explains the gap, and how much adding it buys.
//!
//! The measured traces are split into calibration and held-out runs ([`Split`]). Every free
//! parameter `β_p` of every available candidate gets its sensitivity by a finite difference
//! through the simulator, `J_p = (m(β₀ + h_p e_p) − m(β₀)) / h_p`, where `m` is the model's
//! deviation at the measured angles averaged into bins (1° by default). Effects are then added
//! by forward selection:
//!
//! 1. for each candidate `c` not yet chosen, the parameters of the chosen effects and of `c`
//!    are fitted jointly to the calibration residual, `min ‖r_cal − J_cal β‖²` (Gauss–Newton
//!    step from the model as given, the effects being near-linear at the micrometre level), and
//!    scored on the held-out residual the linear model predicts;
//! 2. the candidate with the smallest predicted held-out residual among those that lower the
//!    calibration BIC `n ln(RSS/n) + k ln n` by at least [`Options::min_bic_drop`] is simulated
//!    with its fitted values (the nonlinear check) and accepted when the simulated BIC drops by
//!    at least [`Options::min_bic_drop`] and the held-out mean square shrinks by at least
//!    [`Options::min_held_out_shrink`] of what is left;
//! 3. one more Gauss–Newton step from the simulated residual refines the values.
//!
//! Selection does not start when the held-out gap is already at [`Options::explained_floor_um`]
//! and stops when no candidate passes; what is left is reported as unexplained.

use crate::align::{GapError, TracePair};
use crate::effects::Effect;
use crate::model::Forward;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use std::sync::OnceLock;
use vmt_ballbar::Trace;

/// Settings of the selection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// Bin width of the residual vectors, deg.
    pub bin_deg: f64,
    /// Least drop of the calibration BIC for an effect to be added.
    pub min_bic_drop: f64,
    /// Least shrink of the held-out mean square, as a fraction of what is left.
    pub min_held_out_shrink: f64,
    /// Most effects added.
    pub max_effects: usize,
    /// Least RMS change an effect must make to the held-out residual, µm: above the ball
    /// bar's resolution (0.1 µm) and the level at which a model's other small mismatches
    /// (the bench's nuisance) already change the residual.
    pub min_effect_um: f64,
    /// The gap counts as explained when what the chosen effects leave on the held-out runs
    /// is at most this RMS, µm (the level of a model's other small mismatches)…
    pub explained_floor_um: f64,
    /// …or at most this fraction of the gap's RMS before them. Otherwise the chosen effects
    /// are reported as partial candidates and the gap as unexplained.
    pub explained_fraction: f64,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            bin_deg: 1.0,
            min_bic_drop: 10.0,
            min_held_out_shrink: 0.3,
            max_effects: 4,
            min_effect_um: 0.15,
            explained_floor_um: 0.2,
            explained_fraction: 0.25,
        }
    }
}

/// Which measured traces fit the effects and which judge them (indices into the measured list).
#[derive(Clone, Debug, PartialEq)]
pub struct Split {
    /// Calibration traces.
    pub calibration: Vec<usize>,
    /// Held-out traces.
    pub held_out: Vec<usize>,
    /// How the split was made, for the report.
    pub rule: String,
}

impl Split {
    /// With several tests (plane, radius, feed), every other test is held out; with one test
    /// of two directions, CW fits and CCW judges.
    pub fn automatic(measured: &[Trace]) -> Result<Self, GapError> {
        let mut tests: Vec<(String, f64, f64)> = Vec::new();
        let test_of: Vec<usize> = measured
            .iter()
            .map(|t| {
                let key = (t.plane.to_string(), t.radius_mm, t.feed_mm_min);
                tests.iter().position(|k| *k == key).unwrap_or_else(|| {
                    tests.push(key);
                    tests.len() - 1
                })
            })
            .collect();
        let (calibration, held_out, rule): (Vec<usize>, Vec<usize>, String) = if tests.len() >= 2 {
            let (c, h) = (0..measured.len()).partition(|i| test_of[*i].is_multiple_of(2));
            (
                c,
                h,
                "every other test (plane, radius, feed) held out".into(),
            )
        } else {
            let (c, h) =
                (0..measured.len()).partition(|i| measured[*i].sense == vmt_ballbar::Sense::Cw);
            (c, h, "CW fits, CCW judges".into())
        };
        if calibration.is_empty() || held_out.is_empty() {
            return Err(GapError::Model(
                "the gap analysis needs runs to fit and other runs to judge: give two directions or two tests".into(),
            ));
        }
        Ok(Self {
            calibration,
            held_out,
            rule,
        })
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
}

/// One accepted effect.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Step {
    /// Effect key.
    pub effect: String,
    /// What it is.
    pub description: String,
    /// Its parameters' offsets, with those of the effects before it refitted (the baseline's
    /// are left out).
    pub values: Vec<Fitted>,
    /// RMS of the calibration residual after it, µm.
    pub calibration_rms_um: f64,
    /// RMS of the held-out residual after it, µm.
    pub held_out_rms_um: f64,
    /// Shrink of the held-out mean square from before this effect, fraction.
    pub held_out_shrink: f64,
}

/// A candidate's score in the last round, for the report.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Score {
    /// Effect key.
    pub effect: String,
    /// Predicted held-out RMS with it, µm.
    pub held_out_rms_um: f64,
    /// Predicted change of the calibration BIC.
    pub bic_change: f64,
}

/// The outcome of the selection.
#[derive(Clone, Debug, PartialEq)]
pub struct Selection {
    /// The split used.
    pub split: Split,
    /// Held-out RMS of the model as given (with the baseline fitted), µm.
    pub held_out_before_um: f64,
    /// Calibration RMS of the model as given (with the baseline fitted), µm.
    pub calibration_before_um: f64,
    /// The baseline parameters (the bar's set-up), fitted before any effect and with each.
    pub baseline: Vec<Fitted>,
    /// The effects added, in order.
    pub steps: Vec<Step>,
    /// Candidates the model file cannot express (effect, missing key).
    pub unavailable: Vec<(String, String)>,
    /// Scores of the round that stopped the selection.
    pub last_round: Vec<Score>,
    /// The final simulated traces' residuals against the measured ones.
    pub final_pairs: Vec<TracePair>,
    /// The model's residuals before any effect (with the baseline fitted).
    pub initial_pairs: Vec<TracePair>,
    /// Simulations run for the selection (besides the linearisation's).
    pub simulations: usize,
}

impl Selection {
    /// Held-out RMS after the chosen effects, µm.
    pub fn held_out_after_um(&self) -> f64 {
        self.steps
            .last()
            .map_or(self.held_out_before_um, |s| s.held_out_rms_um)
    }

    /// Whether the chosen effects explain the gap ([`Options::explained_floor_um`],
    /// [`Options::explained_fraction`]); a gap with no effect chosen is not explained.
    pub fn explained(&self, o: &Options) -> bool {
        !self.steps.is_empty()
            && explained(
                self.held_out_before_um,
                self.held_out_after_um(),
                o.explained_floor_um,
                o.explained_fraction,
            )
    }

    /// The fraction of the held-out mean square removed by all the effects.
    pub fn held_out_shrink(&self) -> f64 {
        let after = self
            .steps
            .last()
            .map_or(self.held_out_before_um, |s| s.held_out_rms_um);
        1.0 - (after / self.held_out_before_um).powi(2)
    }
}

/// A parameter available in the model.
#[derive(Clone)]
struct Available {
    effect: usize,
    name: String,
    unit: &'static str,
    keys: Vec<(String, f64)>,
    step: f64,
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
    let same = |s: &Trace, m: &Trace| {
        s.plane == m.plane
            && s.sense == m.sense
            && (s.radius_mm - m.radius_mm).abs() <= 1e-6 * s.radius_mm
            && (s.feed_mm_min - m.feed_mm_min).abs() <= 1e-3 * s.feed_mm_min
    };
    let mut pairs = Vec::with_capacity(measured.len());
    for (i, m) in measured.iter().enumerate() {
        let k = measured[..i].iter().filter(|x| same(x, m)).count();
        let in_job: Vec<&Trace> = simulated.iter().filter(|s| same(s, m)).collect();
        let s = match in_job.get(k) {
            Some(s) => s,
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
        pairs.push(TracePair::align(m, s)?);
    }
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

fn stack(bins: &[Vec<f64>], rows: &[usize]) -> Vec<f64> {
    rows.iter().flat_map(|i| bins[*i].iter().copied()).collect()
}

/// Whether a gap of held-out RMS `before` left at `after` counts as explained: at most `floor`,
/// or at most `fraction` of `before` (either unit).
pub(crate) fn explained(before: f64, after: f64, floor: f64, fraction: f64) -> bool {
    after <= floor || after <= fraction * before
}

pub(crate) fn rss(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum()
}

/// The Bayesian information criterion of a least-squares fit: `n ln(RSS/n) + k ln n`.
pub(crate) fn bic(rss: f64, n: usize, k: usize) -> f64 {
    let n_f = n as f64;
    n_f * (rss / n_f).max(1e-300).ln() + k as f64 * n_f.ln()
}

/// Least squares `min ‖y − A β‖²` by QR-free normal equations with a tiny ridge for safety.
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

/// A candidate's linear fit in one round.
struct Candidate {
    effect: usize,
    params: Vec<usize>,
    beta: Vec<f64>,
    bic_change: f64,
    held_rss: f64,
}

/// The residual bins of a simulation: per measured trace.
type Simulated = (Vec<TracePair>, Vec<Vec<f64>>);

/// The state of a forward selection.
struct Selector<'a> {
    model: &'a dyn Forward,
    measured: &'a [Trace],
    library: &'a [Effect],
    split: &'a Split,
    o: &'a Options,
    available: Vec<Available>,
    /// Per available parameter, per measured trace: the model's binned sensitivity.
    sensitivities: Vec<Vec<Vec<f64>>>,
    /// The bins every simulation is read on.
    grid: Grid,
    cal0: Vec<f64>,
    held0: Vec<f64>,
    simulations: usize,
}

impl Selector<'_> {
    /// The parameters fitted with `chosen` effects and `extra`: the baseline's, then the
    /// effects', in library order.
    fn params(&self, chosen: &[usize], extra: Option<usize>) -> Vec<usize> {
        (0..self.available.len())
            .filter(|i| {
                let owner = self.available[*i].effect;
                self.library[owner].baseline || chosen.contains(&owner) || Some(owner) == extra
            })
            .collect()
    }

    fn column(&self, p: usize, rows: &[usize]) -> Vec<f64> {
        stack(&self.sensitivities[p], rows)
    }

    fn columns(&self, params: &[usize], rows: &[usize]) -> Vec<Vec<f64>> {
        params.iter().map(|p| self.column(*p, rows)).collect()
    }

    /// Every candidate not yet chosen, fitted jointly with the chosen ones.
    fn candidates(&self, chosen: &[usize], cur_bic: f64) -> Vec<Candidate> {
        let n_cal = self.cal0.len();
        (0..self.library.len())
            .filter(|e| {
                !chosen.contains(e)
                    && !self.library[*e].baseline
                    && self.available.iter().any(|p| p.effect == *e)
            })
            .filter_map(|e| {
                let params = self.params(chosen, Some(e));
                let cal = self.columns(&params, &self.split.calibration);
                let held = self.columns(&params, &self.split.held_out);
                let cal: Vec<&[f64]> = cal.iter().map(Vec::as_slice).collect();
                let held: Vec<&[f64]> = held.iter().map(Vec::as_slice).collect();
                let beta = solve(&cal, &self.cal0)?;
                let cal_rss = rss(&minus(&self.cal0, &cal, &beta));
                let held_rss = rss(&minus(&self.held0, &held, &beta));
                let bic_change = bic(cal_rss, n_cal, params.len()) - cur_bic;
                Some(Candidate {
                    effect: e,
                    params,
                    beta,
                    bic_change,
                    held_rss,
                })
            })
            .collect()
    }

    /// Simulates the candidate at its fitted values, then once more after a Gauss–Newton step
    /// from the simulated residual, and keeps the better of the two.
    fn verify(&mut self, c: &mut Candidate) -> Result<Simulated, GapError> {
        let first = simulate_at(
            self.model,
            self.measured,
            &self.available,
            &c.params,
            &c.beta,
            &self.grid,
            self.o,
        )?;
        self.simulations += 1;
        let cal = self.columns(&c.params, &self.split.calibration);
        let cal: Vec<&[f64]> = cal.iter().map(Vec::as_slice).collect();
        let cal_rss = |s: &Simulated| rss(&stack(&s.1, &self.split.calibration));
        let Some(delta) = solve(&cal, &stack(&first.1, &self.split.calibration)) else {
            return Ok(first);
        };
        let refined: Vec<f64> = c.beta.iter().zip(&delta).map(|(b, d)| b + d).collect();
        let second = simulate_at(
            self.model,
            self.measured,
            &self.available,
            &c.params,
            &refined,
            &self.grid,
            self.o,
        )?;
        self.simulations += 1;
        if cal_rss(&second) < cal_rss(&first) {
            c.beta = refined;
            Ok(second)
        } else {
            Ok(first)
        }
    }

    /// Fits the baseline parameters (the set-up) alone and simulates them: the model as given,
    /// measured as it was set up. Without baseline parameters, the model as given.
    fn baseline(&mut self, given: Vec<TracePair>) -> Result<(Vec<Fitted>, Simulated), GapError> {
        let params = self.params(&[], None);
        let cal = self.columns(&params, &self.split.calibration);
        let cal: Vec<&[f64]> = cal.iter().map(Vec::as_slice).collect();
        let beta = match solve(&cal, &self.cal0) {
            Some(b) if !params.is_empty() => b,
            _ => {
                let bins = given
                    .iter()
                    .zip(&self.grid)
                    .map(|(p, reference)| on_grid(p, self.o.bin_deg, reference))
                    .collect();
                return Ok((Vec::new(), (given, bins)));
            }
        };
        let mut c = Candidate {
            effect: usize::MAX,
            params,
            beta,
            bic_change: 0.0,
            held_rss: 0.0,
        };
        let simulated = self.verify(&mut c)?;
        Ok((self.fitted(&c), simulated))
    }

    fn fitted(&self, c: &Candidate) -> Vec<Fitted> {
        c.params
            .iter()
            .zip(&c.beta)
            .map(|(p, b)| Fitted {
                name: self.available[*p].name.clone(),
                value: *b,
                unit: self.available[*p].unit.into(),
            })
            .collect()
    }

    fn score(&self, c: &Candidate) -> Score {
        Score {
            effect: self.library[c.effect].key.clone(),
            held_out_rms_um: (c.held_rss / self.held0.len() as f64).sqrt(),
            bic_change: c.bic_change,
        }
    }

    fn step(&self, c: &Candidate, cal: f64, held: f64, shrink: f64) -> Step {
        let effect = &self.library[c.effect];
        Step {
            effect: effect.key.clone(),
            description: effect.description.clone(),
            values: self
                .fitted(c)
                .into_iter()
                .zip(&c.params)
                .filter(|(_, p)| !self.library[self.available[**p].effect].baseline)
                .map(|(f, _)| f)
                .collect(),
            calibration_rms_um: (cal / self.cal0.len() as f64).sqrt(),
            held_out_rms_um: (held / self.held0.len() as f64).sqrt(),
            held_out_shrink: shrink,
        }
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
                name: p.name.clone(),
                unit: p.unit,
                keys: p
                    .keys
                    .iter()
                    .map(|k| (k.clone(), model.value(k).unwrap_or_default()))
                    .collect(),
                step: p.step,
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

/// The model's own traces as the measured ones: their split, bins and sensitivities.
struct OwnJob {
    bin_deg: f64,
    split: Split,
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
                .map(|(k, v)| (k.clone(), v + p.step))
                .collect();
            model.sensitivity_traces(&values)
        };
        // Parameters that change the motion are simulated beside the model as given; those a
        // replay of its recorded motion answers wait for it.
        let replayable = |p: &Available| p.keys.iter().all(|(k, _)| model.replayable(k));
        let (base, moving) = rayon::join(
            || model.traces(&[]),
            || {
                available
                    .par_iter()
                    .map(|p| (!replayable(p)).then(|| stepped_traces(p)).transpose())
                    .collect::<Result<Vec<Option<Vec<Trace>>>, GapError>>()
            },
        );
        let (base, moving) = (base?, moving?);
        let stepped = available
            .par_iter()
            .zip(moving)
            .map(|(p, done)| done.map_or_else(|| stepped_traces(p), Ok))
            .collect::<Result<_, GapError>>()?;
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

    /// Per parameter, per measured trace: the model's binned sensitivity at the measured angles.
    fn sensitivities(
        &self,
        measured: &[Trace],
        grid: &Grid,
        o: &Options,
    ) -> Result<Vec<Vec<Vec<f64>>>, GapError> {
        self.available
            .iter()
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
                            .map(|((_, x), y)| (x - y) / p.step)
                            .collect()
                    })
                    .collect())
            })
            .collect()
    }
}

impl Linearisation {
    fn own_job(&self, o: &Options) -> Result<OwnJob, GapError> {
        let split = Split::automatic(&self.base)?;
        let (pairs, _) = residuals(&self.base, &self.base, o.bin_deg, None)?;
        let grid: Grid = pairs.iter().map(|p| bin(p, o.bin_deg)).collect();
        let sensitivities = self.sensitivities(&self.base, &grid, o)?;
        Ok(OwnJob {
            bin_deg: o.bin_deg,
            split,
            grid,
            sensitivities,
        })
    }

    /// How far offsets of the model's parameters (`(key, offset)`, keys the model cannot
    /// express ignored; a parameter of several keys takes its first key's offset) stand out on
    /// the model's own job: the RMS change of the held-out runs, µm, that the linearisation
    /// predicts once the baseline (the bar's set-up) is fitted to the calibration runs, as the
    /// selection fits it. Below [`Options::min_effect_um`] no selection can attribute them.
    pub fn visibility(
        &self,
        library: &[Effect],
        offsets: &[(String, f64)],
        o: &Options,
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
        let (split, grid, sens) = (&own.split, &own.grid, &own.sensitivities);
        let offset = |p: &Available| {
            offsets
                .iter()
                .find(|(k, _)| *k == p.keys[0].0)
                .map_or(0.0, |(_, v)| *v)
        };
        let signature: Vec<Vec<f64>> = (0..self.base.len())
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
            .collect();
        let baseline: Vec<usize> = (0..self.available.len())
            .filter(|i| library[self.available[*i].effect].baseline)
            .collect();
        let columns = |rows: &[usize]| -> Vec<Vec<f64>> {
            baseline.iter().map(|p| stack(&sens[*p], rows)).collect()
        };
        let (cal, held) = (columns(&split.calibration), columns(&split.held_out));
        let cal: Vec<&[f64]> = cal.iter().map(Vec::as_slice).collect();
        let held: Vec<&[f64]> = held.iter().map(Vec::as_slice).collect();
        let y_cal = stack(&signature, &split.calibration);
        let y_held = stack(&signature, &split.held_out);
        let beta = solve(&cal, &y_cal).unwrap_or_else(|| vec![0.0; cal.len()]);
        let left = minus(&y_held, &held, &beta);
        Ok((rss(&left) / left.len().max(1) as f64).sqrt())
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
    let sensitivities = lin.sensitivities(measured, &grid, o)?;
    let mut sel = Selector {
        model,
        measured,
        library,
        split: &split,
        o,
        simulations: 0,
        available: lin.available.clone(),
        sensitivities,
        grid,
        cal0: stack(&base_bins, &split.calibration),
        held0: stack(&base_bins, &split.held_out),
    };
    let n_cal = sel.cal0.len();
    let (baseline, (initial_pairs, initial_bins)) = sel.baseline(given_pairs)?;
    let mut cur_held = rss(&stack(&initial_bins, &split.held_out));
    let cur_cal = rss(&stack(&initial_bins, &split.calibration));
    let mut cur_bic = bic(cur_cal, n_cal, baseline.len());
    let calibration_before_um = (cur_cal / n_cal as f64).sqrt();
    let held_out_before_um = (cur_held / sel.held0.len() as f64).sqrt();
    let (mut chosen, mut steps, mut last_round) = (Vec::new(), Vec::new(), Vec::new());
    let (mut final_pairs, mut held_bins) =
        (initial_pairs.clone(), stack(&initial_bins, &split.held_out));
    // A gap already at the explained floor needs no effect: the model as given explains the
    // measurement to the level of its small mismatches.
    while chosen.len() < o.max_effects
        && held_out_before_um > o.explained_floor_um
        && can_change(cur_held, sel.held0.len(), o)
    {
        let candidates: Vec<Candidate> = sel
            .candidates(&chosen, cur_bic)
            .into_iter()
            .filter(|c| !hidden.contains(&library[c.effect].key.as_str()))
            .collect();
        last_round = candidates.iter().map(|c| sel.score(c)).collect();
        last_round.sort_by(|a, b| a.held_out_rms_um.total_cmp(&b.held_out_rms_um));
        let mut ranked: Vec<Candidate> = candidates
            .into_iter()
            .filter(|c| c.bic_change < -o.min_bic_drop)
            .collect();
        ranked.sort_by(|a, b| a.held_rss.total_cmp(&b.held_rss));
        // The best candidate the model accepts: a fitted value the scenario refuses (a
        // negative friction force, say) is not a physical explanation.
        let mut verified = None;
        for mut c in ranked {
            match sel.verify(&mut c) {
                Ok(simulated) => {
                    verified = Some((c, simulated));
                    break;
                }
                Err(GapError::Model(_)) => continue,
                Err(e) => return Err(e),
            }
        }
        let Some((best, (pairs, bins))) = verified else {
            break;
        };
        let cal = rss(&stack(&bins, &split.calibration));
        let held_new = stack(&bins, &split.held_out);
        let held = rss(&held_new);
        let new_bic = bic(cal, n_cal, best.params.len());
        let shrink = 1.0 - held / cur_held;
        let change = (rss(&held_bins
            .iter()
            .zip(&held_new)
            .map(|(a, b)| a - b)
            .collect::<Vec<_>>())
            / held_new.len() as f64)
            .sqrt();
        if new_bic > cur_bic - o.min_bic_drop
            || shrink < o.min_held_out_shrink
            || change < o.min_effect_um
        {
            break;
        }
        steps.push(sel.step(&best, cal, held, shrink));
        chosen.push(best.effect);
        (cur_held, cur_bic, final_pairs, held_bins) = (held, new_bic, pairs, held_new);
    }
    Ok(Selection {
        held_out_before_um,
        calibration_before_um,
        baseline,
        steps,
        unavailable: lin.unavailable.clone(),
        last_round,
        final_pairs,
        initial_pairs,
        simulations: sel.simulations,
        split,
    })
}

/// Whether an effect could still pass: its change `c` of the held-out residual `r` (RMS) must
/// reach [`Options::min_effect_um`] while leaving at most `1 − s` of the mean square, and
/// `c ≤ rms(r) + rms(r_new) ≤ rms(r)·(1 + sqrt(1 − s))`; a residual below that bound needs no
/// candidate simulated.
fn can_change(held_rss: f64, n: usize, o: &Options) -> bool {
    let now = (held_rss / n.max(1) as f64).sqrt();
    now * (1.0 + (1.0 - o.min_held_out_shrink).max(0.0).sqrt()) >= o.min_effect_um
}

fn simulate_at(
    model: &dyn Forward,
    measured: &[Trace],
    available: &[Available],
    params: &[usize],
    beta: &[f64],
    grid: &Grid,
    o: &Options,
) -> Result<Simulated, GapError> {
    let values: Vec<(String, f64)> = params
        .iter()
        .zip(beta)
        .flat_map(|(p, b)| {
            available[*p]
                .keys
                .iter()
                .map(move |(k, v)| (k.clone(), v + b))
        })
        .collect();
    let traces = model.traces(&values)?;
    residuals(measured, &traces, o.bin_deg, Some(grid))
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
}
