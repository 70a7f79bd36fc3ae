//! The diagnosis of one circular test: ISO 230-4 figures, the fitted error model, the local
//! shapes of the residual, each error with its value, sign, confidence and contribution.
//!
//! Decision rule (stated in every report): a fitted error is *present* when its signature's
//! peak-to-valley over the test is at least [`MIN_CONTRIBUTION_UM`] and its value is at least
//! three standard errors from zero; a local shape (spike, stick-slip, vibration, transient,
//! cyclic error) when its size is at least [`MIN_CONTRIBUTION_UM`] and stands out of the noise
//! as its own rule says. The 95 % confidence is ±1.96 standard errors of the fit (or of the
//! spread between reversals for local shapes).

use crate::features::{self, Residual};
use crate::iso230_4::{self, Figures};
use crate::model::{self, Fit, FitError, Normal, Term, Terms, reversal_angles};
use crate::samples::{Placement, Samples};
use crate::signatures::{self, Point};
use crate::take_up;
use crate::trace::{Plane, Trace, TraceError};
use serde::Serialize;
use thiserror::Error;

/// The smallest peak-to-valley contribution (µm) for an error to be reported present.
pub const MIN_CONTRIBUTION_UM: f64 = 0.5;

/// What to compute besides the standard set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// Minimum-zone circular deviation.
    pub minimum_zone: bool,
    /// Search for cyclic errors (a periodogram per axis; the costliest step).
    pub cyclic: bool,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            minimum_zone: false,
            cyclic: true,
        }
    }
}

/// Why a test cannot be diagnosed.
#[derive(Debug, Error, PartialEq)]
pub enum DiagnosisError {
    /// A trace is malformed.
    #[error(transparent)]
    Trace(#[from] TraceError),
    /// The model cannot be fitted.
    #[error("{0}")]
    Fit(#[from] FitError),
    /// No traces.
    #[error("a test needs one or two traces (a CW and a CCW run of the same circle); got none")]
    Empty,
    /// Traces of different set-ups in one test.
    #[error(
        "trace `{label}` has {what} {got} but `{first}` has {expected}: the traces of one test must share plane, radius and feed"
    )]
    Mismatch {
        /// The odd trace.
        label: String,
        /// The first trace.
        first: String,
        /// Which set-up value.
        what: &'static str,
        /// Its value.
        got: String,
        /// The first trace's value.
        expected: String,
    },
    /// More than two traces or two of one sense.
    #[error(
        "a test holds at most one CW and one CCW trace; got {0} traces (split repeated runs into separate tests)"
    )]
    TooManyTraces(usize),
}

/// One diagnosed error.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Finding {
    /// Machine-readable key, e.g. `backlash_x`.
    pub key: String,
    /// Name for people, e.g. `Backlash X`.
    pub name: String,
    /// Value (signed), in `unit`.
    pub value: f64,
    /// Unit of `value` and `ci95`.
    pub unit: &'static str,
    /// Half width of the 95 % confidence interval.
    pub ci95: f64,
    /// Peak-to-valley of its signature on this test, µm.
    pub contribution_um: f64,
    /// The value from which this error is reported present (in `unit`, by magnitude).
    pub threshold: f64,
    /// Whether the decision rule reports it present.
    pub present: bool,
    /// Further numbers (per side, width, frequency...), name and value with unit in the name.
    pub details: Vec<(String, f64)>,
}

impl Finding {
    /// The biases this finding states for effects its test leaves out (its
    /// `bias_per_<unit>_of_<key>` details): the effect's key and the bias per unit of it.
    pub fn stated_biases(&self) -> impl Iterator<Item = (&str, f64)> + '_ {
        self.details.iter().filter_map(|(k, rate)| {
            let (_, key) = k.strip_prefix(BIAS_DETAIL_PREFIX)?.split_once("_of_")?;
            Some((key, *rate))
        })
    }

    /// The bias that the true values of the effects its test leaves out, as `truth` gives
    /// them by key, put on this finding by the rates it states; `None` when it states none or
    /// `truth` lacks one of the effects.
    pub fn left_out_bias(&self, truth: impl Fn(&str) -> Option<f64>) -> Option<f64> {
        let rates: Vec<(&str, f64)> = self.stated_biases().collect();
        if rates.is_empty() {
            return None;
        }
        rates
            .into_iter()
            .map(|(key, rate)| Some(rate * truth(key)?))
            .sum()
    }
}

/// An error the test cannot determine, and why.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NotComputed {
    /// Key, as a [`Finding`]'s.
    pub key: String,
    /// Why.
    pub reason: String,
}

/// The diagnosis of one test.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Diagnosis {
    /// Test plane.
    pub plane: Plane,
    /// Nominal radius, mm.
    pub radius_mm: f64,
    /// Feed, mm/min.
    pub feed_mm_min: f64,
    /// Labels of the traces.
    pub traces: Vec<String>,
    /// ISO 230-4 figures over the data arc past its settling ([`SETTLING_RULE`]), as instrument
    /// software gives them: over every sample when the runs start and end settled (a test with
    /// run-in and run-out arcs), without the feed-in's transient otherwise (a test without them,
    /// as Kwon's steps, carries the carriages' lag at the feed-in corner into G and H, 160 µm
    /// where the errors are a few).
    pub iso: Figures,
    /// ISO 230-4 figures over every sample of the data arc (its first revolution), transients
    /// included.
    pub raw_iso: Figures,
    /// Per trace, the data arc [`SETTLING_RULE`] left out of [`Diagnosis::iso`].
    pub settling: Vec<Settling>,
    /// Diagnosed errors, ranked by contribution to the circular deviation.
    pub findings: Vec<Finding>,
    /// Errors this test cannot determine.
    pub not_computed: Vec<NotComputed>,
    /// RMS of what the model and the local shapes leave, µm.
    pub residual_rms_um: f64,
    /// Robust estimate of the instrument noise, µm.
    pub noise_um: f64,
}

impl Diagnosis {
    /// The finding with `key`.
    pub fn finding(&self, key: &str) -> Option<&Finding> {
        self.findings.iter().find(|f| f.key == key)
    }
}

/// How the ISO 230-4 figures of [`Diagnosis::iso`] leave out the transients at the ends of a
/// run, stated in every report.
pub const SETTLING_RULE: &str = "A run is settled from the first sample after which its \
residual from the fitted error model, smoothed over 4 ms, stays within its noise band (the \
median of the settled residual ± 5 robust standard deviations, at least ±0.01 µm) for 3 deg of \
travel; the end likewise backwards. Applied where a transient is found at that end (the \
extreme of the smoothed residual in its first or last 5 deg at least 0.5 µm and 6 noise \
standard deviations above the residual's level, and above the largest reversal spike measured \
when the run starts at an axis reversal); the ISO 230-4 figures are taken over the settled \
part, the raw figures over the whole data arc.";

/// What [`SETTLING_RULE`] left out of one trace.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Settling {
    /// Label of the trace.
    pub label: String,
    /// `cw` or `ccw`.
    pub sense: String,
    /// Data arc left out at the start, deg (0 when the run starts settled).
    pub start_excluded_deg: f64,
    /// Data arc left out at the end, deg.
    pub end_excluded_deg: f64,
    /// Level and half-width of the band the residual settles into, µm.
    pub band_um: (f64, f64),
    /// False when the residual does not settle within the first (or last) half of the run:
    /// the figures then keep that end.
    pub settled: bool,
    /// The samples kept.
    #[serde(skip)]
    pub kept: std::ops::Range<usize>,
}

/// Diagnoses a test of one or two traces (CW and CCW of the same circle).
pub fn diagnose(traces: &[Trace], options: &Options) -> Result<Diagnosis, DiagnosisError> {
    check_test(traces)?;
    let places: Vec<Placement> = traces
        .iter()
        .zip(progress(traces))
        .map(|(t, p)| Placement::new(t, p))
        .collect();
    let reversals: Vec<[Vec<usize>; 2]> = places
        .iter()
        .map(|p| features::reversals_cs(&p.cos, &p.sin))
        .collect();
    let test = Test {
        traces,
        places: &places,
        reversals: &reversals,
    };
    let measured: Vec<&[f64]> = traces.iter().map(|t| t.deviation_um.as_slice()).collect();
    let result = diagnose_test(&test, &measured, options);
    for p in places {
        p.recycle();
    }
    result
}

/// A test with what its passes share: the place of every sample and the axis reversals.
struct Test<'a> {
    traces: &'a [Trace],
    places: &'a [Placement],
    reversals: &'a [[Vec<usize>; 2]],
}

/// [`diagnose`] of a checked test whose traces have the deviations `measured`.
fn diagnose_test(
    test: &Test,
    measured: &[&[f64]],
    options: &Options,
) -> Result<Diagnosis, DiagnosisError> {
    let search = if options.cyclic {
        CyclicPass::Search
    } else {
        CyclicPass::Skip
    };
    let (first, cyclic) = diagnose_once(test, measured, search)?;
    let present: Vec<features::Cyclic> = cyclic
        .iter()
        .filter(|(_, f)| f.present)
        .map(|(c, _)| *c)
        .collect();
    let (mut findings, rms, noise, settling) = if present.is_empty() {
        first
    } else {
        // Near its reversals an axis stays within one pitch of its turning point (stationary
        // phase), so a cyclic error leaks into the first-order signatures there (a 10 mm pitch
        // on a 100 mm circle moves the fitted scale by several ppm): the first-order model is
        // fitted again with the cyclic errors found taken out of the traces. The ISO figures
        // stay those of the traces as measured.
        let corrected = without_cyclic(test, &present);
        let refs: Vec<&[f64]> = corrected.iter().map(Vec::as_slice).collect();
        // The cyclic errors' amplitudes are fitted again in that pass's residual with what
        // was taken out put back: the first-order fit of the first pass had absorbed part of
        // them (5 to 9 % for pitches of 10 to 20 mm on a 150 mm circle).
        let (mut second, refined) = diagnose_once(test, &refs, CyclicPass::Refine(&present))?;
        let absent = cyclic.into_iter().filter(|(_, f)| !f.present);
        second
            .0
            .extend(refined.into_iter().chain(absent).map(|(_, f)| f));
        second
    };
    findings.sort_by(|a, b| b.contribution_um.total_cmp(&a.contribution_um));
    let traces = test.traces;
    let first = &traces[0];
    let refs: Vec<&Trace> = traces.iter().collect();
    let trig: Vec<(&[f64], &[f64])> = test
        .places
        .iter()
        .map(|p| (p.cos.as_slice(), p.sin.as_slice()))
        .collect();
    let raw_iso = iso230_4::figures_with_trig(&refs, &trig, options.minimum_zone);
    let whole = |(t, s): (&Trace, &Settling)| s.kept == (0..t.angle_deg.len());
    let iso = if traces.iter().zip(&settling).all(whole) {
        raw_iso.clone()
    } else {
        let kept: Vec<Trace> = traces
            .iter()
            .zip(&settling)
            .map(|(t, s)| t.samples(s.kept.clone()))
            .collect();
        let trig: Vec<(&[f64], &[f64])> = trig
            .iter()
            .zip(&settling)
            .map(|((c, s), k)| (&c[k.kept.clone()], &s[k.kept.clone()]))
            .collect();
        iso230_4::figures_with_trig(
            &kept.iter().collect::<Vec<_>>(),
            &trig,
            options.minimum_zone,
        )
    };
    Ok(Diagnosis {
        plane: first.plane,
        radius_mm: first.radius_mm,
        feed_mm_min: first.feed_mm_min,
        traces: traces.iter().map(|t| t.label.clone()).collect(),
        iso,
        raw_iso,
        settling,
        findings,
        not_computed: not_computed(&Terms::for_test(&refs), first),
        residual_rms_um: rms,
        noise_um: noise,
    })
}

/// What [`SETTLING_RULE`] leaves of trace `t` with residual `res`. The start is searched where
/// the smoothed residual's extreme in the first 5° ([`features::start_transient`]) stands
/// [`smoothed_noise_floor`] (at least 0.5 µm) above its level, and above the reversal spike
/// there when the run starts at an axis' reversal: by the largest spike measured at that axis'
/// reversals inside the runs (`spikes`, µm), or at the other axis' where this one has none
/// inside them (a half circle): a run that starts where its axis reverses holds that axis'
/// spike in its first degrees, an error of the machine the figures must keep. The end likewise
/// with its last 5° ([`features::end_transient`]; a run ends before the reversal its spike
/// follows).
fn settling(t: &Trace, res: &Residual, spikes: [Option<f64>; 2], noise: f64) -> Settling {
    let n = t.angle_deg.len();
    let band = features::settled_band(res);
    let floor = MIN_CONTRIBUTION_UM.max(smoothed_noise_floor(res, noise));
    let spike = reversing_at_start(res)
        .map_or(0.0, |axis| spikes[axis].or(spikes[1 - axis]).unwrap_or(0.0));
    let start_transient = features::start_transient(res).is_some_and(|h| h.abs() >= floor + spike);
    let end_transient = features::end_transient(res).is_some_and(|h| h.abs() >= floor);
    let from = if start_transient {
        features::settles(res, band, false)
    } else {
        Some(0)
    };
    let to = if end_transient {
        features::settles(res, band, true)
    } else {
        Some(n)
    };
    let kept = from.unwrap_or(0)..to.unwrap_or(n);
    let a = &t.angle_deg;
    Settling {
        label: t.label.clone(),
        sense: t.sense.name().into(),
        start_excluded_deg: (a[kept.start] - a[0]).abs(),
        end_excluded_deg: (a[n - 1] - a[kept.end - 1]).abs(),
        band_um: band,
        settled: from.is_some() && to.is_some(),
        kept,
    }
}

/// Per trace, the fitted groups' points, mean residuals (µm) and sizes, in sample order: what
/// [`Normal::robust_std_errors`] weighs the fit's misfit from.
fn fitted_group_residuals(
    samples: &[Samples],
    residuals: &[Residual],
) -> Vec<Vec<(Point, f64, usize)>> {
    samples
        .iter()
        .zip(residuals)
        .map(|(s, r)| {
            s.groups
                .iter()
                .zip(&s.fitted)
                .zip(r.r.chunks(s.group_size))
                .filter(|((_, fitted), _)| **fitted)
                .map(|(((pt, _, w), _), chunk)| (*pt, chunk.iter().sum::<f64>() / *w as f64, *w))
                .collect()
        })
        .collect()
}

/// Leaves the reversal spikes of trace `t` out of the fit of `s`: the groups holding a sample
/// from an axis' reversal to [`features::SPIKE_ZONE_DEG`] of travel after it. A spike follows
/// its reversal in either sense, so the difference of the CW and CCW runs holds it as a short
/// step at the turn, of the sign of the backlash signature there. Fitted, the 1.8 µm spikes
/// of 40 ms of the built-in machine at 2000 mm/min on 100 mm (noise-free) read as 0.08 µm more
/// backlash on both axes, 0.07–0.08 µm of closing error and 0.10–0.14 µm of lateral play; with
/// 2° to 5° left out the backlash is within 0.005 µm of the truth, the closing errors within
/// 0.025 µm and the lateral plays 0.06–0.09 µm. The steps, the take-up and the spikes
/// themselves are read from the residual, which keeps every sample.
fn leave_out_spikes(s: &mut Samples, t: &Trace, reversals: &[Vec<usize>; 2]) {
    for &first in reversals.iter().flatten() {
        let turn = t.angle_deg[first];
        let end = t.angle_deg[first..]
            .iter()
            .position(|a| (a - turn).abs() >= features::SPIKE_ZONE_DEG)
            .map_or(t.angle_deg.len(), |k| first + k);
        s.leave_out(first..end);
    }
}

/// The findings of one pass (ranked), the residual's RMS and the noise (µm), and the settling
/// of each trace.
type Pass = (Vec<Finding>, f64, f64, Vec<Settling>);

/// What a pass of the diagnosis does about cyclic errors.
#[derive(Clone, Copy)]
enum CyclicPass<'a> {
    /// Nothing.
    Skip,
    /// Searches them in the residual.
    Search,
    /// These were taken out of the deviations: fits their amplitudes again, at their pitches,
    /// in the residual with them put back.
    Refine(&'a [features::Cyclic]),
}

/// One pass of the diagnosis on the deviations `deviation`, and the cyclic errors it found or
/// refined (see [`CyclicPass`]), which are not among its findings.
fn diagnose_once(
    test: &Test,
    deviation: &[&[f64]],
    cyclic_pass: CyclicPass,
) -> Result<(Pass, Vec<(features::Cyclic, Finding)>), DiagnosisError> {
    let traces = test.traces;
    let refs: Vec<&Trace> = traces.iter().collect();
    let plane = traces[0].plane;
    let mut samples: Vec<Samples> = traces
        .iter()
        .zip(test.places)
        .zip(deviation)
        .map(|((t, p), d)| Samples::new(t, p, d))
        .collect();
    for ((s, t), reversals) in samples.iter_mut().zip(traces).zip(test.reversals) {
        leave_out_spikes(s, t, reversals);
    }
    let terms = Terms::for_test(&refs);
    let take_up::TakeUp {
        fit,
        shifts,
        reach_um,
        at_limit,
        normal,
    } = take_up::fit(plane, &terms.terms, &samples, test.reversals)?;
    let sample_refs: Vec<&Samples> = samples.iter().collect();
    let left_out = left_out_effects(&normal, &terms, &sample_refs);
    // The aliases are in the order of `terms.terms`, which the fit keeps.
    debug_assert_eq!(fit.terms, terms.terms);
    let residuals: Vec<Residual> = traces
        .iter()
        .zip(&samples)
        .zip(test.reversals.iter().zip(&shifts))
        .map(|((t, s), (rev, shifts))| residual(t, s, rev, shifts, &fit))
        .collect();
    let fit = Fit {
        std_errors: normal.robust_std_errors(&fit, &fitted_group_residuals(&samples, &residuals)),
        ..fit
    };
    let mut findings = fitted_findings(&fit, &sample_refs, &terms.unresolved, &left_out);
    let noise = features::median(
        &residuals
            .iter()
            .map(|r| features::noise_sigma(&r.r))
            .collect::<Vec<_>>(),
    );
    findings.extend(closing_errors(&fit, traces, &samples));
    let (local, spikes) = local_findings(&mut findings, &fit, &residuals, traces, noise);
    take_up_details(&mut findings, reach_um, at_limit, plane);
    findings.extend(local);
    let settled: Vec<Settling> = traces
        .iter()
        .zip(&residuals)
        .map(|(t, res)| settling(t, res, spikes, noise))
        .collect();
    let groups = || {
        let mut g = cyclic_groups(&residuals, &samples);
        g.without_left_out(&terms, plane);
        g
    };
    let cyclic = match cyclic_pass {
        CyclicPass::Skip => Vec::new(),
        CyclicPass::Search => cyclic_findings(&fit, &groups()),
        CyclicPass::Refine(taken_out) => refined_cyclic(&fit, &groups(), taken_out),
    };
    if matches!(cyclic_pass, CyclicPass::Search) {
        findings.extend(cyclic.iter().map(|(_, f)| f.clone()));
    }
    for f in &mut findings {
        // A finding's own numbers first, the biases of left-out effects after them.
        f.details
            .sort_by_key(|(k, _)| k.starts_with(BIAS_DETAIL_PREFIX));
    }
    findings.sort_by(|a, b| b.contribution_um.total_cmp(&a.contribution_um));
    let n: usize = residuals.iter().map(|r| r.r.len()).sum();
    let rss: f64 = residuals.iter().map(|r| features::sum_sq(&r.r)).sum();
    for r in residuals {
        for v in [r.r, r.high_pass] {
            crate::samples::recycle(v);
        }
        r.sums.recycle();
    }
    Ok(((findings, (rss / n as f64).sqrt(), noise, settled), cyclic))
}

fn check_test(traces: &[Trace]) -> Result<(), DiagnosisError> {
    let first = traces.first().ok_or(DiagnosisError::Empty)?;
    if traces.len() > 2 || (traces.len() == 2 && traces[0].sense == traces[1].sense) {
        return Err(DiagnosisError::TooManyTraces(traces.len()));
    }
    for t in traces {
        t.validate()?;
        let mismatch = |what, got: String, expected: String| DiagnosisError::Mismatch {
            label: t.label.clone(),
            first: first.label.clone(),
            what,
            got,
            expected,
        };
        if t.plane != first.plane {
            return Err(mismatch(
                "plane",
                t.plane.to_string(),
                first.plane.to_string(),
            ));
        }
        if (t.radius_mm - first.radius_mm).abs() > 1e-6 * first.radius_mm {
            return Err(mismatch(
                "radius_mm",
                t.radius_mm.to_string(),
                first.radius_mm.to_string(),
            ));
        }
        if (t.feed_mm_min - first.feed_mm_min).abs() > 1e-6 * first.feed_mm_min {
            return Err(mismatch(
                "feed_mm_min",
                t.feed_mm_min.to_string(),
                first.feed_mm_min.to_string(),
            ));
        }
    }
    Ok(())
}

/// Progress of every sample over the whole test, −½…½ (0 in its middle, so that the pivot
/// offset and the radius are fitted as they are in the middle of the test, as a fit without
/// drift terms on a partial arc gives them): by time when every trace has times (one clock),
/// else by angle travelled with the traces run back to back in the given order.
fn progress(traces: &[Trace]) -> Vec<Vec<f64>> {
    if let Some(times) = traces
        .iter()
        .map(|t| t.time_s.as_ref())
        .collect::<Option<Vec<_>>>()
    {
        let t0 = times.iter().map(|t| t[0]).fold(f64::INFINITY, f64::min);
        let t1 = times
            .iter()
            .map(|t| t[t.len() - 1])
            .fold(f64::NEG_INFINITY, f64::max);
        let span = (t1 - t0).max(1e-12);
        return times
            .iter()
            .map(|t| {
                let mut p = crate::samples::buffer(t.len());
                p.extend(t.iter().map(|x| (x - t0) / span - 0.5));
                p
            })
            .collect();
    }
    let total: f64 = traces.iter().map(|t| t.sweep_deg()).sum::<f64>().max(1e-12);
    let mut before = 0.0;
    traces
        .iter()
        .map(|t| {
            let a0 = t.angle_deg[0];
            let p = t
                .angle_deg
                .iter()
                .map(|a| (before + (a - a0).abs()) / total - 0.5)
                .collect();
            before += t.sweep_deg();
            p
        })
        .collect()
}

/// The residual of trace `t` from the model `fit` with the backlash's take-up `shifts`
/// (the take-up's `shifts`, see [`take_up::TakeUp`]).
fn residual<'a>(
    t: &'a Trace,
    s: &'a Samples,
    reversals: &'a [Vec<usize>; 2],
    shifts: &[(usize, f64)],
    fit: &Fit,
) -> Residual<'a> {
    let model = fit.compiled(s.radius_um, s.feed_um_per_ms);
    let g = s.sense.sign();
    let mut r = crate::samples::filled(s.len());
    model.residuals(g, s.cos, s.sin, s.progress, s.deviation_um, &mut r);
    settle_flanks_at_reversals(&mut r, s, reversals, fit);
    for &(i, d) in shifts {
        r[i] -= d;
    }
    let n = t.angle_deg.len();
    let dt_ms = match &t.time_s {
        Some(ts) => (ts[n - 1] - ts[0]) / (n - 1) as f64 * 1e3,
        None => {
            let deg = t.sweep_deg() / (n - 1) as f64;
            deg.to_radians() * s.radius_um / s.feed_um_per_ms
        }
    };
    Residual::new(&t.angle_deg, s.cos, s.sin, s.sense, r, dt_ms, reversals)
        .settled_within(s.transient_deg())
}

/// A sample taken on an axis' reversal itself (the first or last sample of a run at 0°, 90°…,
/// or one that falls on the turn) has no direction of motion to say which flank of its backlash
/// the axis bears on: the model's backlash term there is 0 or the sign of a rounding error, and
/// the flank the axis really bears on then leaves half the backlash or all of it in the
/// residual, which the start transient and the spikes would take for a shape of their own.
/// Such samples (only the ends and the neighbours of a sign change can be) take the flank that
/// leaves the smaller residual; so do the first and last samples of a run within
/// [`signatures::STARTS_ON_TURN`] of a turn, whose approach is not known.
fn settle_flanks_at_reversals(r: &mut [f64], s: &Samples, reversals: &[Vec<usize>; 2], fit: &Fit) {
    let n = r.len();
    for (axis, at) in reversals.iter().enumerate() {
        let Some((b, _)) = fit.get(Term::Backlash(axis)) else {
            continue;
        };
        let mut near: Vec<usize> = [0, n - 1]
            .into_iter()
            .chain(at.iter().flat_map(|&i| [i - 1, i]))
            .collect();
        near.sort_unstable();
        near.dedup();
        for i in near {
            let pt = s.point(i);
            let (along, across) = (pt.turning(axis), pt.own(axis));
            let end = i == 0 || i == n - 1;
            let on_turn = along.abs() <= signatures::ON_TURN
                || (end && along.abs() <= signatures::STARTS_ON_TURN);
            if !on_turn || across == 0.0 {
                continue;
            }
            let term = |flank: f64| b * signatures::backlash_on_flank(&pt, axis, flank);
            let as_fitted = r[i] + term(signatures::sign(along));
            r[i] = [as_fitted - term(1.0), as_fitted - term(-1.0)]
                .into_iter()
                .min_by(|x, y| x.abs().total_cmp(&y.abs()))
                .unwrap_or(r[i]);
        }
    }
}

/// Key, name and unit of a fitted term in `plane`.
fn describe(term: Term, plane: Plane) -> Option<(String, String, &'static str)> {
    let (p, q) = plane.axes();
    let ax = |i: usize| if i == 0 { p } else { q };
    let lower = |c: char| c.to_ascii_lowercase();
    let pl = plane.name().to_lowercase();
    Some(match term {
        Term::Pivot(i) => (
            format!("eccentricity_{}", lower(ax(i))),
            format!(
                "Set-up eccentricity {} (pivot off the programmed centre)",
                ax(i)
            ),
            "µm",
        ),
        Term::Radius => (
            "radius_offset".into(),
            "Radius offset (bar length, bar temperature)".into(),
            "µm",
        ),
        Term::ScaleMismatch => (
            format!("scale_mismatch_{pl}"),
            format!("Scale mismatch {p} - {q}"),
            "ppm",
        ),
        Term::Squareness => (
            format!("squareness_{pl}"),
            format!(
                "Squareness {} (ISO {})",
                plane.name(),
                squareness_iso(plane)
            ),
            "µm/m",
        ),
        Term::ServoMismatch => (
            format!("servo_mismatch_{pl}"),
            format!("Servo mismatch {p} lag - {q} lag"),
            "ms",
        ),
        Term::Backlash(i) => (
            format!("backlash_{}", lower(ax(i))),
            format!("Backlash {}", ax(i)),
            "µm",
        ),
        Term::LateralPlay(i) => (
            format!("lateral_play_{}", lower(ax(i))),
            format!("Lateral play {} (across {})", ax(i), ax(1 - i)),
            "µm",
        ),
        Term::AngularPlay(i) => (
            format!("angular_play_{}", lower(ax(i))),
            format!(
                "Angular play {} (turns about {} as it reverses)",
                ax(i),
                plane.normal()
            ),
            "µrad",
        ),
        Term::Straightness(i) => (
            format!("straightness_{}", lower(ax(i))),
            format!(
                "Straightness {} (bow towards +{} over the diameter)",
                ax(i),
                ax(1 - i)
            ),
            "µm",
        ),
        Term::RadialDrift | Term::PivotDrift(_) => return None,
    })
}

/// The ISO 230-1 name of the squareness a plane's test measures.
pub const fn squareness_iso(plane: Plane) -> &'static str {
    match plane {
        Plane::Xy => "EC0Y",
        Plane::Zx => "EB0Z",
        Plane::Yz => "EA0Z",
    }
}

/// An effect that a test leaves out of its fit (a bow, an angular play, a radial or pivot drift
/// on too short an arc; a servo mismatch, lateral play, backlash or drift on one direction) and
/// what it would do to the fitted terms.
struct LeftOut {
    term: Term,
    /// Peak-to-valley of one unit of its signature on the test, µm.
    per_unit: f64,
    /// How much it moves every fitted term per unit of it ([`Normal::alias`], in the order of
    /// the fit's terms).
    alias: Vec<f64>,
}

/// The effects that the test leaves out of its fit: unfitted, they are read as the fitted
/// terms. Over a 220° arc of 100 mm in ZX, 1 µm of Z's bow moves the squareness by −6.0 µm/m
/// and 1 µm of X's bow the scale mismatch by +11.9 ppm; run back and forth over the arc, the
/// progress is the sense times the angle travelled, so 1 µm of drift over the test moves the
/// lateral plays by up to about ±0.5 µm; run one way only, a servo mismatch is read as
/// squareness, and a drift (whose progress then follows the angle) as the circle's shapes.
fn left_out_effects(normal: &Normal, terms: &Terms, samples: &[&Samples]) -> Vec<LeftOut> {
    let left: Vec<Term> = terms.left_out.iter().map(|(t, _)| *t).collect();
    if left.is_empty() {
        return Vec::new();
    }
    let per_unit = model::unit_contributions(normal.plane(), &left, samples);
    left.into_iter()
        .zip(per_unit)
        .map(|(term, per_unit)| LeftOut {
            term,
            per_unit,
            alias: normal.alias(term),
        })
        .collect()
}

/// The findings of the fitted terms, without those the test cannot resolve (`unresolved`,
/// listed as not computed instead). A finding that an effect of `left_out` moves by at least
/// [`BIAS_MIN_SHARE`] of that effect's own signature states by how much, in its unit per unit
/// of the effect, as the detail `bias_per_<unit>_of_<key>` (`bias_per_um_of_straightness_z`):
/// a bias of the test, not in its confidence interval, that the effect measured otherwise
/// corrects.
fn fitted_findings(
    fit: &Fit,
    samples: &[&Samples],
    unresolved: &[(Term, &'static str)],
    left_out: &[LeftOut],
) -> Vec<Finding> {
    let one_sense = fit.get(Term::ServoMismatch).is_none();
    let unit = fit.unit_contributions(samples);
    fit.terms
        .iter()
        .zip(unit)
        .enumerate()
        .filter(|(_, (term, _))| !unresolved.iter().any(|(t, _)| t == *term))
        .filter_map(|(index, (&term, per_unit))| {
            let (key, mut name, unit) = describe(term, fit.plane)?;
            let (value, se) = fit.get(term)?;
            let contribution = per_unit * value.abs();
            let threshold = if per_unit > 0.0 {
                MIN_CONTRIBUTION_UM / per_unit
            } else {
                f64::INFINITY
            };
            if term == Term::Squareness && one_sense {
                name.push_str(" with servo mismatch (one direction only)");
            }
            let present = term != Term::Radius
                && contribution >= MIN_CONTRIBUTION_UM
                && value.abs() >= 3.0 * se;
            Some(Finding {
                key,
                name,
                value,
                unit,
                ci95: 1.96 * se,
                contribution_um: contribution,
                threshold,
                present,
                details: biases(left_out, index, size_per_unit(term, per_unit), fit.plane),
            })
        })
        .collect()
}

/// The size (µm) of one unit of `term`'s signature on the test, for weighing a bias on it: its
/// span `per_unit`, or 1 µm for the radius, whose signature is the same everywhere (no span).
fn size_per_unit(term: Term, per_unit: f64) -> f64 {
    if term == Term::Radius { 1.0 } else { per_unit }
}

/// The prefix of the details of a finding that state the bias of an effect the test leaves out,
/// per unit of the effect: `bias_per_<unit>_of_<key>`.
pub const BIAS_DETAIL_PREFIX: &str = "bias_per_";

/// The least share of a left-out effect's signature (peak to valley) that it must move a
/// finding's signature by for the finding to state the bias.
pub const BIAS_MIN_SHARE: f64 = 0.1;

/// The `bias_per_<unit>_of_<key>` details of the fitted term at `index`, whose unit spans
/// `per_unit` µm on the test (see [`fitted_findings`]).
fn biases(left_out: &[LeftOut], index: usize, per_unit: f64, plane: Plane) -> Vec<(String, f64)> {
    left_out
        .iter()
        .filter(|l| {
            l.per_unit > 0.0 && per_unit * l.alias[index].abs() >= BIAS_MIN_SHARE * l.per_unit
        })
        .filter_map(|l| {
            let (key, unit) = effect_key(l.term, plane)?;
            let unit = unit.replace('µ', "u");
            Some((
                format!("{BIAS_DETAIL_PREFIX}{unit}_of_{key}"),
                l.alias[index],
            ))
        })
        .collect()
}

/// The key and unit of an effect a test may leave out: a finding's, or for the drifts, which
/// are no finding of their own, `radial_drift` and `pivot_drift_<axis>` (µm over the test).
fn effect_key(term: Term, plane: Plane) -> Option<(String, &'static str)> {
    let (p, q) = plane.axes();
    match term {
        Term::RadialDrift => Some(("radial_drift".into(), "µm")),
        Term::PivotDrift(i) => {
            let axis = if i == 0 { p } else { q };
            Some((format!("pivot_drift_{}", axis.to_ascii_lowercase()), "µm"))
        }
        t => describe(t, plane).map(|(key, _, unit)| (key, unit)),
    }
}

/// Closing error of each full trace (Kwon): the drift of the model between its first and last
/// sample at the start angle, µm.
fn closing_errors(fit: &Fit, traces: &[Trace], samples: &[Samples]) -> Vec<Finding> {
    let drift = [Term::RadialDrift, Term::PivotDrift(0), Term::PivotDrift(1)];
    if drift.iter().any(|t| fit.get(*t).is_none()) {
        return Vec::new();
    }
    traces
        .iter()
        .zip(samples)
        .map(|(t, s)| {
            let (first, last) = (s.point(0), s.point(s.len() - 1));
            let mut end = first;
            end.progress = last.progress;
            let only_drift = |term: Term| !drift.contains(&term);
            let value = fit.model(&end, only_drift) - fit.model(&first, only_drift);
            let ds = last.progress - first.progress;
            let var: f64 = drift
                .iter()
                .filter_map(|term| fit.get(*term))
                .zip([1.0, first.cos, first.sin])
                .map(|((_, se), k)| (se * k * ds).powi(2))
                .sum();
            let se = var.sqrt();
            Finding {
                key: format!("closing_error_{}", t.sense.name()),
                name: format!("Closing error {}", t.sense.name().to_uppercase()),
                value,
                unit: "µm",
                ci95: 1.96 * se,
                contribution_um: value.abs(),
                threshold: MIN_CONTRIBUTION_UM,
                present: value.abs() >= MIN_CONTRIBUTION_UM && value.abs() >= 3.0 * se,
                details: Vec::new(),
            }
        })
        .collect()
}

fn not_computed(terms: &Terms, first: &Trace) -> Vec<NotComputed> {
    let mut out: Vec<NotComputed> = terms
        .left_out
        .iter()
        .chain(&terms.unresolved)
        .filter_map(|(term, why)| {
            let key = match term {
                Term::RadialDrift | Term::PivotDrift(_) => "closing_error".to_string(),
                t => describe(*t, first.plane)?.0,
            };
            Some(NotComputed {
                key,
                reason: why.to_string(),
            })
        })
        .collect();
    out.dedup_by(|a, b| a.key == b.key);
    out
}

fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let sd = if v.len() > 1 {
        (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
    } else {
        0.0
    };
    (m, sd)
}

/// The local findings, and the largest reversal spike measured per axis (µm).
fn local_findings(
    findings: &mut [Finding],
    fit: &Fit,
    residuals: &[Residual],
    traces: &[Trace],
    noise: f64,
) -> (Vec<Finding>, [Option<f64>; 2]) {
    let (p, q) = fit.plane.axes();
    let mut out = Vec::new();
    let mut spikes = [None; 2];
    for (axis, measured) in spikes.iter_mut().enumerate() {
        let letter = if axis == 0 { p } else { q };
        let l = letter.to_ascii_lowercase();
        let spike = spike_finding(residuals, axis, letter, noise);
        *measured = spike.as_ref().map(|(_, largest)| *largest);
        out.extend(spike.map(|(f, _)| f));
        if let Some(sides) = side_details(fit, residuals, axis, letter)
            && let Some(b) = findings
                .iter_mut()
                .find(|f| f.key == format!("backlash_{l}"))
        {
            // The per-side steps first; any stated bias of a left-out effect stays.
            b.details.splice(0..0, sides);
        }
        if let Some((near, far, pp)) = features::stick_slip(residuals, axis) {
            let ratio = near / far.max(1e-9);
            // Peak-to-peak of a sawtooth with the RMS that the reversal zones add to the noise.
            let excess = 2.0 * 3f64.sqrt() * (near * near - far * far).max(0.0).sqrt();
            out.push(Finding {
                key: format!("stick_slip_{l}"),
                name: format!("Stick-slip {letter} (near its reversals)"),
                value: excess,
                unit: "µm",
                ci95: 1.96 * 2.0 * 3f64.sqrt() * far,
                contribution_um: excess,
                threshold: MIN_CONTRIBUTION_UM,
                present: ratio >= 2.0 && excess >= MIN_CONTRIBUTION_UM,
                details: vec![
                    ("rms_ratio_near_to_far".into(), ratio),
                    ("peak_to_peak_near_um".into(), pp),
                ],
            });
        }
    }
    out.extend(vibration_finding(residuals, noise));
    for (t, res) in traces.iter().zip(residuals) {
        out.extend(start_transient_finding(t, res, noise, spikes, [p, q]));
    }
    (out, spikes)
}

/// The axis that may reverse at the start of a run (p at θ = 0° or 180°, q at 90° or 270°,
/// within the spike zone), if one does.
fn reversing_at_start(res: &Residual) -> Option<usize> {
    let (c, s) = (res.cos[0].abs(), res.sin[0].abs());
    let near = features::SPIKE_ZONE_DEG.to_radians().sin() * 2.0;
    // p reverses where sin θ = 0, q where cos θ = 0.
    (s.min(c) < near).then_some(usize::from(c < s))
}

/// Adds to each backlash finding reported present the reach of its take-up, `take_up_um` (µm
/// of motor travel from one flank to the other, see [`take_up`]), and says so in its name when
/// the reach came out at the search's limit.
fn take_up_details(
    findings: &mut [Finding],
    reach_um: [Option<f64>; 2],
    at_limit: [bool; 2],
    plane: Plane,
) {
    let (p, q) = plane.axes();
    for (axis, letter) in [p, q].into_iter().enumerate() {
        let key = format!("backlash_{}", letter.to_ascii_lowercase());
        let found = findings.iter_mut().find(|f| f.key == key && f.present);
        if let (Some(reach), Some(f)) = (reach_um[axis], found) {
            f.details.push(("take_up_um".into(), reach));
            if at_limit[axis] {
                f.name.push_str(&format!(
                    " (taken up over {} steps or more: the take-up's limit)",
                    take_up::K_MAX
                ));
            }
        }
    }
}

/// The transient at the start of a run, against the noise of its smoothed residual.
///
/// A run that starts where an axis can reverse (p at θ = 0° or 180°, q at 90° or 270°) may hold
/// that axis' reversal spike in its first degrees as well (it does when the axis reverses
/// there, not when the feed-in already moved it the way the arc goes on): the transient is then
/// known only to within that spike, taken as the largest measured at the axis' reversals inside
/// the runs (`spikes`, µm), which widens its interval and raises its threshold. With no spike
/// measured the two cannot be told apart, and the transient is reported with no contribution.
fn start_transient_finding(
    t: &Trace,
    res: &Residual,
    noise: f64,
    spikes: [Option<f64>; 2],
    letters: [char; 2],
) -> Option<Finding> {
    let h = features::start_transient(res)?;
    let floor = MIN_CONTRIBUTION_UM.max(smoothed_noise_floor(res, noise));
    let sense = t.sense.name();
    let mut name = format!("Transient at the start, {}", sense.to_uppercase());
    let mut details = Vec::new();
    let spike = match reversing_at_start(res) {
        None => Some(0.0),
        Some(axis) => {
            let letter = letters[axis];
            match spikes[axis] {
                Some(v) => {
                    name.push_str(&format!(" ({letter} reversal, within its spike)"));
                    details.push((format!("{}_spike_um", letter.to_ascii_lowercase()), v));
                }
                None => name.push_str(&format!(" ({letter} reversal, spike not separable)")),
            }
            spikes[axis]
        }
    };
    let (ci95, threshold, contribution) = match spike {
        Some(spike) => (1.96 * noise + spike, floor + spike, h.abs()),
        None => (1.96 * noise, f64::INFINITY, 0.0),
    };
    Some(Finding {
        key: format!("start_transient_{sense}"),
        name,
        value: h,
        unit: "µm",
        ci95,
        contribution_um: contribution,
        threshold,
        present: h.abs() >= threshold,
        details,
    })
}

/// The step of the backlash at each end of the axis' travel (reversals at θ = 0° and 180° for
/// p, 90° and 270° for q), µm, as finding details.
fn side_details(
    fit: &Fit,
    residuals: &[Residual],
    axis: usize,
    letter: char,
) -> Option<Vec<(String, f64)>> {
    let (b, _) = fit.get(Term::Backlash(axis))?;
    let ends = reversal_angles(axis);
    let mut per_end: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    let basis = Term::Backlash(axis);
    // The backlash moves the axis by ±b/2: Δr is that times cos θ (p) or sin θ (q), which the
    // windows 2–12° from the turn hold at 0.99 on the median; per unit of it the step is b.
    let along_axis = |res: &Residual, j: usize| res.point(j).own(axis).abs();
    for res in residuals {
        let unit = |j: usize| basis.basis(&res.point(j), fit.plane) / along_axis(res, j);
        let partial = |j: usize| res.r[j] / along_axis(res, j) + b * unit(j);
        for &i in &res.reversals[axis] {
            let Some(step) = features::step(res, partial, i) else {
                continue;
            };
            let (before, after) = (unit(i - 1), unit(i));
            let unit_step = after - before;
            if unit_step.abs() < 0.5 {
                continue;
            }
            let off = (res.angle_deg[i] - ends[1]).rem_euclid(360.0);
            let end = usize::from(off.min(360.0 - off) < 45.0);
            per_end[end].push(step / unit_step);
        }
    }
    let l = letter.to_ascii_lowercase();
    let details: Vec<(String, f64)> = per_end
        .iter()
        .zip(["plus", "minus"])
        .filter(|(v, _)| !v.is_empty())
        .map(|(v, side)| (format!("at_{side}_{l}_end_um"), mean_sd(v).0))
        .collect();
    (!details.is_empty()).then_some(details)
}

/// The floor a local shape on `res` must clear: six standard deviations of the noise `noise`
/// (µm) left by the smoothing over [`features::SMOOTH_MS`], taken as SMOOTH_MS/dt samples (the
/// centred window holds one more, so the floor errs high).
fn smoothed_noise_floor(res: &Residual, noise: f64) -> f64 {
    6.0 * noise / (features::SMOOTH_MS / res.dt_ms).max(1.0).sqrt()
}

/// The reversal spike of an axis (the mean over its reversals inside the runs), and the largest
/// of the spikes measured, µm.
fn spike_finding(
    residuals: &[Residual],
    axis: usize,
    letter: char,
    noise: f64,
) -> Option<(Finding, f64)> {
    let mut found = Vec::new();
    let mut floor: f64 = 0.0;
    for res in residuals {
        floor = floor.max(smoothed_noise_floor(res, noise));
        for &i in &res.reversals[axis] {
            found.extend(features::spike(res, i));
        }
    }
    if found.is_empty() {
        return None;
    }
    let heights: Vec<f64> = found.iter().map(|s| s.height_um).collect();
    let largest = heights.iter().fold(0.0, |m: f64, h| m.max(h.abs()));
    let widths: Vec<f64> = found.iter().map(|s| s.width_ms).collect();
    let (h, sd) = mean_sd(&heights);
    let (w, _) = mean_sd(&widths);
    let threshold = MIN_CONTRIBUTION_UM.max(floor);
    let l = letter.to_ascii_lowercase();
    let finding = Finding {
        key: format!("reversal_spike_{l}"),
        name: format!("Reversal spike {letter}"),
        value: h,
        unit: "µm",
        ci95: 1.96 * sd / (heights.len() as f64).sqrt(),
        contribution_um: h.abs(),
        threshold,
        present: h.abs() >= threshold,
        details: vec![
            ("width_ms".into(), w),
            ("reversals".into(), heights.len() as f64),
        ],
    };
    Some((finding, largest))
}

/// The strongest line of the residuals' spectra above 5 Hz, past their start transients (a
/// feed-in's ringing, [`features::transient_end`]). It is a vibration when it spans the
/// smallest contribution reported and stands ten times above the spectrum, both as a whole and
/// about its own frequency: a transient raises the spectrum about its frequency as broadly as
/// the line, where a sustained vibration stands alone. Its interval is that of the largest of
/// the bins searched ([`features::Vibration::ci95_um`]).
fn vibration_finding(residuals: &[Residual], noise: f64) -> Option<Finding> {
    let v = features::vibration(residuals, 5.0)?;
    let (hz, amp) = (v.hz, v.amplitude_um);
    let res = &residuals[v.residual];
    let n = res.r.len() - v.start;
    let se = noise * (2.0 / n as f64).sqrt();
    let floor = v.median_um.max(v.local_median_um).max(se);
    let present = 2.0 * amp >= MIN_CONTRIBUTION_UM && amp >= 10.0 * floor;
    Some(Finding {
        key: "servo_vibration".into(),
        name: "High servo gain vibration".into(),
        value: amp,
        unit: "µm",
        ci95: v.ci95_um().max(1.96 * se),
        contribution_um: 2.0 * amp,
        threshold: MIN_CONTRIBUTION_UM / 2.0,
        present,
        details: vec![
            ("frequency_hz".into(), hz),
            ("spectrum_from_s".into(), v.start as f64 * res.dt_ms * 1e-3),
        ],
    })
}

/// The fit's groups of the residuals (the same chunks, the transients at the ends of a run
/// left out: they are no cyclic error, and near a reversal of the axis at the start they
/// would read as one): the point of each, its mean residual (µm) and its samples.
struct CyclicGroups {
    points: Vec<Point>,
    r: Vec<f64>,
    w: Vec<f64>,
}

fn cyclic_groups(residuals: &[Residual], samples: &[Samples]) -> CyclicGroups {
    let mut g = CyclicGroups {
        points: Vec::new(),
        r: Vec::new(),
        w: Vec::new(),
    };
    for (res, s) in residuals.iter().zip(samples) {
        let size = res.r.len().div_ceil(crate::samples::MAX_GROUPS).max(1);
        let fitted = res.r.chunks(size).enumerate().filter(|(k, _)| s.fitted[*k]);
        for (k, chunk) in fitted {
            let i = k * size + chunk.len() / 2;
            g.points.push(s.point(i));
            g.r.push(chunk.iter().sum::<f64>() / chunk.len() as f64);
            g.w.push(chunk.len() as f64);
        }
    }
    g
}

impl CyclicGroups {
    /// Takes the shapes of the effects the test leaves out of its fit out of the residuals,
    /// fitted jointly with the fitted terms' (a least-squares projection, by SVD: run one way
    /// the drift is nearly the circle's own shapes). Left in, an unfitted effect is a smooth
    /// residual that the search, which weighs an amplitude against white noise, reads as a
    /// cyclic error: the XY circles of the accuracy study run one way found one in 5 % of the
    /// runs with the drift left in. Nothing is done when the test leaves nothing out.
    fn without_left_out(&mut self, terms: &Terms, plane: Plane) {
        if terms.left_out.is_empty() || self.r.is_empty() {
            return;
        }
        let columns: Vec<Term> = terms
            .terms
            .iter()
            .copied()
            .chain(terms.left_out.iter().map(|(t, _)| *t))
            .collect();
        let a = nalgebra::DMatrix::from_fn(self.r.len(), columns.len(), |i, j| {
            self.w[i].sqrt() * columns[j].basis(&self.points[i], plane)
        });
        let b = nalgebra::DVector::from_fn(self.r.len(), |i, _| self.w[i].sqrt() * self.r[i]);
        let Ok(x) = a.clone().svd(true, true).solve(&b, 1e-9) else {
            return;
        };
        let fitted = a * x;
        for (i, r) in self.r.iter_mut().enumerate() {
            *r -= fitted[i] / self.w[i].sqrt();
        }
    }

    /// The residuals with the radial deviation of `cyclic` taken out (`sign` −1) or put
    /// back (+1).
    fn with(&self, cyclic: &[features::Cyclic], sign: f64) -> Vec<f64> {
        with_cyclic(&self.points, &self.r, cyclic, sign)
    }
}

/// The residuals `r` at `points` with `sign` times the radial deviation of `cyclic` added.
fn with_cyclic(points: &[Point], r: &[f64], cyclic: &[features::Cyclic], sign: f64) -> Vec<f64> {
    points
        .iter()
        .zip(r)
        .map(|(pt, r)| {
            let radius_mm = pt.radius_um * 1e-3;
            r + sign
                * cyclic
                    .iter()
                    .map(|c| c.radial_um(pt.cos, pt.sin, radius_mm))
                    .sum::<f64>()
        })
        .collect()
}

/// The cyclic error of each axis, searched in the fit's groups of the residuals.
///
/// An axis' cyclic error projects onto the other axis' signatures (both are periodic in the
/// angle), so each axis searched in the same residual would find a phantom of the other's: the
/// more significant one is searched first and taken out of the residual before the other is
/// searched, and when both are present the first is searched again with the second taken out.
fn cyclic_findings(fit: &Fit, g: &CyclicGroups) -> Vec<(features::Cyclic, Finding)> {
    let sigma = fit.sample_sigma_um;
    let search = |axis: usize, taken_out: Option<features::Cyclic>| {
        let r = match taken_out {
            None => std::borrow::Cow::Borrowed(&g.r),
            Some(c) => std::borrow::Cow::Owned(g.with(&[c], -1.0)),
        };
        features::cyclic(&g.points, &r, &g.w, axis, sigma).map(|c| features::Cyclic {
            std_error_um: features::robust_cyclic_error(&g.points, &r, &g.w, &c),
            ..c
        })
    };
    let mut found = [search(0, None), search(1, None)];
    let significance = |c: &Option<features::Cyclic>| {
        c.map_or(0.0, |c| {
            c.amplitude_um / c.std_error_um.max(f64::MIN_POSITIVE)
        })
    };
    let first = usize::from(significance(&found[1]) > significance(&found[0]));
    let present = |c: &Option<features::Cyclic>| c.is_some_and(|c| cyclic_present(&c));
    if present(&found[first]) {
        found[1 - first] = search(1 - first, found[first]);
        if present(&found[1 - first]) {
            found[first] = search(first, found[1 - first]);
        }
    }
    found
        .into_iter()
        .flatten()
        .map(|c| (c, cyclic_finding(&c, fit.plane)))
        .collect()
}

/// The cyclic errors `taken_out` of the deviations, their amplitudes fitted again together at
/// their pitches in the groups' residuals with them put back.
fn refined_cyclic(
    fit: &Fit,
    g: &CyclicGroups,
    taken_out: &[features::Cyclic],
) -> Vec<(features::Cyclic, Finding)> {
    let r = g.with(taken_out, 1.0);
    let refined = features::refit_cyclic(&g.points, &r, &g.w, taken_out, fit.sample_sigma_um);
    let robust = |k: usize| {
        // Each error's own residual: the traces less the others refined.
        let others: Vec<features::Cyclic> = (0..refined.len())
            .filter(|j| *j != k)
            .map(|j| refined[j])
            .collect();
        let own = with_cyclic(&g.points, &r, &others, -1.0);
        features::robust_cyclic_error(&g.points, &own, &g.w, &refined[k])
    };
    (0..refined.len())
        .map(|k| features::Cyclic {
            std_error_um: robust(k),
            ..refined[k]
        })
        .map(|c| (c, cyclic_finding(&c, fit.plane)))
        .collect()
}

/// The threshold of a cyclic error's amplitude, µm: the smallest contribution reported, or
/// five standard errors.
fn cyclic_threshold(c: &features::Cyclic) -> f64 {
    (MIN_CONTRIBUTION_UM / 2.0).max(5.0 * c.std_error_um)
}

fn cyclic_present(c: &features::Cyclic) -> bool {
    c.amplitude_um >= cyclic_threshold(c)
}

fn cyclic_finding(c: &features::Cyclic, plane: Plane) -> Finding {
    let (p, q) = plane.axes();
    let letter = if c.axis == 0 { p } else { q };
    Finding {
        key: format!("cyclic_{}", letter.to_ascii_lowercase()),
        name: format!("Cyclic error {letter}"),
        value: c.amplitude_um,
        unit: "µm",
        ci95: c.ci95_um(),
        contribution_um: 2.0 * c.amplitude_um,
        threshold: cyclic_threshold(c),
        present: cyclic_present(c),
        details: vec![("pitch_mm".into(), c.pitch_mm)],
    }
}

/// The deviations of the traces with the radial deviation of `cyclic` taken out.
fn without_cyclic(test: &Test, cyclic: &[features::Cyclic]) -> Vec<Vec<f64>> {
    test.traces
        .iter()
        .zip(test.places)
        .map(|(t, p)| {
            t.deviation_um
                .iter()
                .zip(p.cos.iter().zip(&p.sin))
                .map(|(d, (c, s))| {
                    d - cyclic
                        .iter()
                        .map(|e| e.radial_um(*c, *s, t.radius_mm))
                        .sum::<f64>()
                })
                .collect()
        })
        .collect()
}
