//! `vmt accuracy`: the closed-loop accuracy of the ball-bar diagnosis on a dataset of
//! simulated machines (from `vmt dataset`): every run's first circular test is diagnosed and
//! each finding compared with the run's ground-truth figure of the same key.
//!
//! Per figure: n, bias (mean of diagnosed − truth), RMS, the 95th percentile of |error|
//! (nearest rank), the worst error and its run, the share within the tolerance of the issue's
//! goals, and the false-positive rate: among runs whose |truth| is below half the finding's
//! stated threshold, the share where the finding is reported present.
//!
//! Tolerances: max(0.3 µm, 5 % of |truth|) for lengths (backlash, lateral play, eccentricity,
//! closing error, straightness); scale mismatch as the length it makes over the radius R:
//! max(0.3 µm / R, 5 %) in ppm; 1 µm/m for squareness; 0.1 ms for servo mismatch. Goals: 95 %
//! within tolerance and false positives under 2 %; straightness is reported but is no goal.

use crate::dataset::complete_runs;
use crate::diagnose::{diagnose_file, truth_figures};
use crate::error::CliError;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;
use vmt_ballbar::Options;

/// Share of runs that must be within tolerance.
const GOAL_WITHIN: f64 = 0.95;
/// Largest accepted false-positive rate.
const GOAL_FALSE_POSITIVES: f64 = 0.02;
/// Worst runs listed per figure.
const WORST_LISTED: usize = 5;

/// A run's comparisons: (figure key, unit, the comparison or None when not diagnosed).
type RunComparisons = Vec<(String, String, Option<Comparison>)>;

/// One run's comparison for one figure.
#[derive(Clone, Debug)]
struct Comparison {
    id: String,
    truth: f64,
    value: f64,
    present: bool,
    threshold: f64,
    radius_mm: f64,
}

/// The statistics of one figure over the dataset.
#[derive(Clone, Debug, Serialize)]
pub struct FigureStats {
    /// Finding key.
    pub key: String,
    /// Unit of the figure.
    pub unit: String,
    /// Runs compared.
    pub n: usize,
    /// Runs whose diagnosis has no such finding.
    pub not_diagnosed: usize,
    /// Mean error (diagnosed − truth).
    pub bias: f64,
    /// Root mean square error.
    pub rms: f64,
    /// 95th percentile of |error|.
    pub p95_abs: f64,
    /// Largest |error| and its run.
    pub worst: f64,
    /// Id of the worst run.
    pub worst_id: String,
    /// The worst runs: (id, truth, diagnosed).
    pub worst_runs: Vec<(String, f64, f64)>,
    /// Share of runs within tolerance.
    pub within: f64,
    /// The tolerance, in words.
    pub tolerance: String,
    /// Runs whose |truth| is below half the threshold.
    pub fp_runs: usize,
    /// Share of those reported present (None without such runs).
    pub fp_rate: Option<f64>,
    /// Whether the issue sets a goal for this figure.
    pub goal: bool,
    /// Whether the goals are met (within and false positives).
    pub met: bool,
}

/// The study: one entry per figure key, and the runs that could not be diagnosed.
#[derive(Clone, Debug, Serialize)]
pub struct Study {
    /// Runs in the dataset.
    pub runs: usize,
    /// Per figure, in key order.
    pub figures: Vec<FigureStats>,
    /// Runs whose file could not be diagnosed, with the reason.
    pub failed: Vec<(String, String)>,
}

/// The tolerance of `key` for a run of radius `radius_mm` and truth `truth`, and its wording.
pub fn tolerance(key: &str, truth: f64, radius_mm: f64) -> (f64, &'static str) {
    if key.starts_with("squareness") {
        (1.0, "1 µm/m")
    } else if key.starts_with("servo_mismatch") {
        (0.1, "0.1 ms")
    } else if key.starts_with("scale_mismatch") {
        (
            (0.3 / (radius_mm * 1e-3)).max(0.05 * truth.abs()),
            "max(0.3 µm / R, 5 %)",
        )
    } else {
        (0.3f64.max(0.05 * truth.abs()), "max(0.3 µm, 5 %)")
    }
}

/// Diagnoses every complete run of dataset `dir` and computes the statistics.
pub fn study(dir: &Path) -> Result<Study, CliError> {
    let runs = complete_runs(dir)?;
    let per_run: Vec<Result<RunComparisons, (String, String)>> =
        runs.par_iter().map(|p| compare_run(p)).collect();
    let mut by_key: BTreeMap<String, (String, Vec<Option<Comparison>>)> = BTreeMap::new();
    let mut failed = Vec::new();
    for r in per_run {
        match r {
            Ok(list) => {
                for (key, unit, c) in list {
                    let e = by_key
                        .entry(key)
                        .or_insert_with(|| (String::new(), Vec::new()));
                    if e.0.is_empty() {
                        e.0 = unit;
                    }
                    e.1.push(c);
                }
            }
            Err(f) => failed.push(f),
        }
    }
    let figures = by_key
        .into_iter()
        .map(|(key, (unit, cs))| stats(&key, &unit, &cs))
        .collect();
    Ok(Study {
        runs: runs.len(),
        figures,
        failed,
    })
}

/// Every truth figure of run `path`'s first test with its finding (None when not diagnosed).
fn compare_run(path: &Path) -> Result<RunComparisons, (String, String)> {
    let id = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let fail = |m: String| (id.clone(), m);
    let d = diagnose_file(&path.join("run.mcap"), None, &Options::default())
        .map_err(|e| fail(e.to_string()))?;
    let truth = d
        .ground_truth
        .as_ref()
        .ok_or_else(|| fail("no ground truth".into()))?;
    let figures = truth_figures(truth, 0).ok_or_else(|| fail("no truth figures".into()))?;
    let (_, diag) = d
        .tests
        .first()
        .ok_or_else(|| fail("no circular test".into()))?;
    Ok(figures
        .iter()
        .filter_map(|(key, t)| Some((key, t.as_f64()?)))
        .map(|(key, truth)| {
            let f = diag.finding(key);
            let unit = f.map(|f| f.unit.to_string()).unwrap_or_default();
            let c = f.map(|f| Comparison {
                id: id.clone(),
                truth,
                value: f.value,
                present: f.present,
                threshold: f.threshold,
                radius_mm: diag.radius_mm,
            });
            (key.clone(), unit, c)
        })
        .collect())
}

fn stats(key: &str, unit: &str, cs: &[Option<Comparison>]) -> FigureStats {
    let done: Vec<&Comparison> = cs.iter().flatten().collect();
    let n = done.len();
    let errors: Vec<f64> = done.iter().map(|c| c.value - c.truth).collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let squares: Vec<f64> = errors.iter().map(|e| e * e).collect();
    let mut ranked: Vec<(f64, &Comparison)> = errors
        .iter()
        .map(|e| e.abs())
        .zip(done.iter().copied())
        .collect();
    ranked.sort_by(|a, b| b.0.total_cmp(&a.0).then_with(|| a.1.id.cmp(&b.1.id)));
    let abs: Vec<f64> = ranked.iter().map(|r| r.0).rev().collect();
    let p95 = match n {
        0 => f64::NAN,
        _ => abs[((GOAL_WITHIN * n as f64).ceil() as usize).clamp(1, n) - 1],
    };
    let within = done
        .iter()
        .filter(|c| (c.value - c.truth).abs() <= tolerance(key, c.truth, c.radius_mm).0)
        .count() as f64
        / n.max(1) as f64;
    let quiet: Vec<&&Comparison> = done
        .iter()
        .filter(|c| c.truth.abs() < 0.5 * c.threshold)
        .collect();
    let fp_rate = (!quiet.is_empty())
        .then(|| quiet.iter().filter(|c| c.present).count() as f64 / quiet.len() as f64);
    let goal = !key.starts_with("straightness");
    let not_diagnosed = cs.len() - n;
    let met = within >= GOAL_WITHIN
        && fp_rate.is_none_or(|r| r < GOAL_FALSE_POSITIVES)
        && not_diagnosed == 0;
    FigureStats {
        key: key.to_string(),
        unit: unit.to_string(),
        n,
        not_diagnosed,
        bias: mean(&errors),
        rms: mean(&squares).sqrt(),
        p95_abs: p95,
        worst: ranked.first().map_or(f64::NAN, |r| r.0),
        worst_id: ranked.first().map(|r| r.1.id.clone()).unwrap_or_default(),
        worst_runs: ranked
            .iter()
            .take(WORST_LISTED)
            .map(|(_, c)| (c.id.clone(), c.truth, c.value))
            .collect(),
        within,
        tolerance: tolerance(key, 0.0, 100.0).1.to_string(),
        fp_runs: quiet.len(),
        fp_rate,
        goal,
        met,
    }
}

/// The study as a Markdown table, with the worst runs of each figure that misses its goals.
pub fn markdown(s: &Study) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Runs: {} ({} could not be diagnosed)\n",
        s.runs,
        s.failed.len()
    );
    let _ = writeln!(
        out,
        "| figure | unit | n | bias | RMS | p95 \\|err\\| | worst (run) | tolerance | within | FP runs | FP rate | goals |"
    );
    let _ = writeln!(
        out,
        "|---|---|---:|---:|---:|---:|---:|---|---:|---:|---:|---|"
    );
    for f in &s.figures {
        let fp = f
            .fp_rate
            .map_or("–".into(), |r| format!("{:.1} %", 100.0 * r));
        let verdict = match (f.goal, f.met) {
            (false, _) => "no goal",
            (true, true) => "met",
            (true, false) => "MISSED",
        };
        let _ = writeln!(
            out,
            "| {} | {} | {} | {:+.3} | {:.3} | {:.3} | {:.3} ({}) | {} | {:.1} % | {} | {} | {} |",
            f.key,
            f.unit,
            f.n,
            f.bias,
            f.rms,
            f.p95_abs,
            f.worst,
            f.worst_id,
            f.tolerance,
            100.0 * f.within,
            f.fp_runs,
            fp,
            verdict
        );
    }
    for f in s.figures.iter().filter(|f| f.goal && !f.met) {
        let runs: Vec<String> = f
            .worst_runs
            .iter()
            .map(|(id, t, v)| format!("{id} (truth {t:+.3}, diagnosed {v:+.3})"))
            .collect();
        let _ = writeln!(
            out,
            "\n{} misses its goals; worst runs: {}",
            f.key,
            runs.join(", ")
        );
    }
    for (id, why) in &s.failed {
        let _ = writeln!(out, "\nrun {id} not diagnosed: {why}");
    }
    out
}

/// Writes `accuracy.md` and `accuracy.json` into `dir`.
pub fn write(s: &Study, dir: &Path) -> Result<(), CliError> {
    let md = dir.join("accuracy.md");
    let text = format!("# Ball-bar diagnosis accuracy\n\n{}", markdown(s));
    std::fs::write(&md, text).map_err(|e| CliError::output(&md, e))?;
    let js = dir.join("accuracy.json");
    let text = serde_json::to_string_pretty(s).map_err(|e| CliError::output(&js, e))?;
    std::fs::write(&js, text + "\n").map_err(|e| CliError::output(&js, e))
}

/// `vmt accuracy`: runs the study on `dir`, prints the table and writes the reports.
pub fn command(dir: &Path) -> Result<(), CliError> {
    let s = study(dir)?;
    print!("{}", markdown(&s));
    write(&s, dir)?;
    println!(
        "\nwrote {}\nwrote {}",
        dir.join("accuracy.md").display(),
        dir.join("accuracy.json").display()
    );
    Ok(())
}
