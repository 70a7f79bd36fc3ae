//! `vmt run` and `vmt demo`: execute a scenario's job and write its files.
//!
//! Writes into the output folder: `run.mcap` (Foxglove, Python `mcap`), `run.rrd` (Rerun
//! viewer 0.36), one polar plot per circular test (`ballbar_polar.png`, or
//! `ballbar_polar_<n>_<plane>_<radius>mm.png` for each of several tests), for a positioning
//! test `laser_iso230_2.json` (the ISO 230-2 figures of the laser readings), and
//! `ground_truth.json`.

use crate::error::CliError;
use crate::plot::{self, Format};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use vmt_logs::live::RunFiles;
use vmt_logs::{mcap::write_mcap, rerun::write_rrd};
use vmt_scenario::Scenario;
use vmt_sim::plant::Fidelity;
use vmt_sim::run::{BallbarTrace, LogSink, Run};

/// The files a run wrote.
#[derive(Clone, Debug)]
pub struct Written {
    /// Every file written.
    pub files: Vec<PathBuf>,
}

/// Simulates the scenario's job (optionally at another fidelity) with a progress bar.
pub fn execute(
    scenario: &Scenario,
    text: &str,
    fidelity: Option<Fidelity>,
    quiet: bool,
) -> Result<Run, CliError> {
    execute_into(scenario, text, fidelity, quiet, None)
}

/// [`execute`] and the run's files written into the folder `dir`: `run.mcap` and `run.rrd`
/// while a job through the feed drives runs (see [`RunFiles`]; a milling run writes them
/// afterwards), then the rest of [`write`](fn@write)'s. The run of a job through the feed
/// drives comes back without the rows of its `servo` stream, which went to the files.
pub fn execute_and_write(
    scenario: &Scenario,
    text: &str,
    fidelity: Option<Fidelity>,
    quiet: bool,
    dir: &Path,
) -> Result<(Run, Written), CliError> {
    std::fs::create_dir_all(dir).map_err(|e| CliError::output(dir, e))?;
    if scenario
        .execution
        .as_ref()
        .is_some_and(|e| e.milling.is_some())
    {
        let run = execute(scenario, text, fidelity, quiet)?;
        let written = write(&run, dir)?;
        return Ok((run, written));
    }
    let mut files = RunFiles::new(dir);
    let (run, mut written) = match execute_into(scenario, text, fidelity, quiet, Some(&mut files)) {
        Ok(run) => files.finish(run)?,
        Err(e) => {
            // A writer's own error explains a simulation stopped by it.
            files.abandon()?;
            return Err(e);
        }
    };
    written.extend(write_others(&run, dir)?);
    Ok((run, Written { files: written }))
}

/// [`execute`] with the records handed to `sink` as the job runs, if there is one (not for a
/// milling job).
fn execute_into(
    scenario: &Scenario,
    text: &str,
    fidelity: Option<Fidelity>,
    quiet: bool,
    sink: Option<&mut dyn LogSink>,
) -> Result<Run, CliError> {
    let exec = vmt_dataset::job::execution(scenario)?;
    for note in vmt_dataset::job::notes(exec) {
        crate::errln!("note: {note}");
    }
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(1000)
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{msg} [{bar:40}] {percent:>3}% {elapsed_precise} (eta {eta})",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let shown = fidelity.unwrap_or(exec.settings.fidelity);
    bar.set_message(format!("simulating ({})", shown.name()));
    let mut progress = |f: f64| bar.set_position((f * 1000.0) as u64);
    let run = vmt_dataset::job::simulate(scenario, text, fidelity, &mut progress, sink)?;
    bar.finish_and_clear();
    Ok(run)
}

/// Writes the run's files into `dir`.
pub fn write(run: &Run, dir: &Path) -> Result<Written, CliError> {
    std::fs::create_dir_all(dir).map_err(|e| CliError::output(dir, e))?;
    let mut files = Vec::new();
    let mcap = dir.join("run.mcap");
    write_mcap(run, &mcap)?;
    files.push(mcap);
    let rrd = dir.join("run.rrd");
    write_rrd(run, &rrd)?;
    files.push(rrd);
    files.extend(write_others(run, dir)?);
    Ok(Written { files })
}

/// Writes the files of the run but `run.mcap` and `run.rrd` into `dir`: the polar plot, the
/// ISO 230-2 figures and the ground truth.
fn write_others(run: &Run, dir: &Path) -> Result<Vec<PathBuf>, CliError> {
    let mut files = write_polars(run, dir)?;
    if let Some(l) = &run.laser {
        let path = dir.join("laser_iso230_2.json");
        let text =
            serde_json::to_string_pretty(&l.iso230_2()).map_err(|e| CliError::output(&path, e))?;
        std::fs::write(&path, text).map_err(|e| CliError::output(&path, e))?;
        files.push(path);
    }
    let truth = dir.join("ground_truth.json");
    let text =
        serde_json::to_string_pretty(&run.ground_truth).map_err(|e| CliError::output(&truth, e))?;
    std::fs::write(&truth, text).map_err(|e| CliError::output(&truth, e))?;
    files.push(truth);
    Ok(files)
}

/// What `vmt run --diagnose` made of a run: the report as printed and the files written.
pub struct RunDiagnosis {
    /// The report, as the diagnosing command prints it.
    pub text: String,
    /// The files written into the run's `diagnosis/` folder.
    pub files: Vec<PathBuf>,
}

/// `vmt run --diagnose`: the run in `dir` read back from its `run.mcap`, as a real log would
/// be, and evaluated into `dir/diagnosis` as the command for that kind of log does: `vmt
/// diagnose` for ball-bar traces and for a positioning test, `vmt chatter detect` (report and
/// per-window CSV) for a milling run's accelerometers. `None` for a run that recorded none of
/// these (an NC program without instruments).
pub fn diagnose(run: &Run, dir: &Path) -> Result<Option<RunDiagnosis>, CliError> {
    let mcap = dir.join("run.mcap");
    let into = dir.join(crate::outputs::DIAGNOSIS);
    if !run.ballbar.is_empty() {
        let options = vmt_ballbar::Options::default();
        let none = crate::import::Import::default();
        let d = crate::diagnose::diagnose_file(&mcap, None, &none, &options)?;
        let files = crate::diagnose::write(&d, &into)?;
        let text = crate::diagnose::text(&d);
        return Ok(Some(RunDiagnosis { text, files }));
    }
    if run.laser.is_some()
        && let Some(p) = crate::positioning::read(&mcap, None, &crate::import::Import::default())?
    {
        let files = crate::positioning::write(&p, &into)?;
        let text = crate::positioning::text(&p);
        return Ok(Some(RunDiagnosis { text, files }));
    }
    if run.streams.iter().any(|s| s.name == "accelerometer") {
        let (text, files) = crate::chatter::diagnose_run(&mcap, &into)?;
        return Ok(Some(RunDiagnosis { text, files }));
    }
    Ok(None)
}

/// One polar plot per circular test (its CW and CCW runs) with its traces' figures:
/// `ballbar_polar.png` for a run of one test, `ballbar_polar_<n>_<plane>_<radius>mm.png` (n
/// from 1 in run order, as `vmt diagnose` numbers the tests) for each of several.
fn write_polars(run: &Run, dir: &Path) -> Result<Vec<PathBuf>, CliError> {
    let tests = crate::traces::run_tests(&run.ballbar);
    let mut files = Vec::new();
    for (i, test) in tests.iter().enumerate() {
        let name = match (tests.len(), test.first()) {
            (1, _) | (_, None) => "ballbar_polar.png".to_string(),
            (_, Some(t)) => format!(
                "ballbar_polar_{}_{}_{}mm.png",
                i + 1,
                t.plane.to_ascii_lowercase(),
                t.radius_mm
            ),
        };
        let path = dir.join(name);
        let mut figures: Vec<String> = headline(test).into_iter().collect();
        figures.extend(test.iter().map(trace_figures));
        plot::draw_polar(test, &path, Format::Png, Some(&figures.join("\n")))?;
        files.push(path);
    }
    Ok(files)
}

/// The ISO 230-4 figures of a test as its diagnosis gives them (past the feed-in's settling,
/// the raw ones beside), for the headline of its polar plot; `None` for a test the diagnosis
/// does not take (an arc under 90°).
fn headline(test: &[BallbarTrace]) -> Option<String> {
    let traces = test
        .iter()
        .map(|t| crate::traces::from_run(t, "run"))
        .collect::<Result<Vec<_>, _>>()
        .ok()?;
    let d = vmt_ballbar::diagnose(&traces, &vmt_ballbar::Options::default()).ok()?;
    Some(crate::diagnose::iso_headline(&d))
}

/// A trace's label, radial span and mean, on two lines (the plot's text block is narrower
/// than both together).
fn trace_figures(t: &BallbarTrace) -> String {
    let (lo, hi) = t
        .deviation_um
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let mean = t.deviation_um.iter().sum::<f64>() / t.deviation_um.len().max(1) as f64;
    format!(
        "{}:\n  span {:.2} um, mean {:+.2} um, {} samples",
        t.label,
        hi - lo,
        mean,
        t.deviation_um.len()
    )
}

/// One line per ball-bar trace: radial span (max - min of the deviation, the ISO 230-4 radial
/// deviation F about the nominal centre) and the mean; for a positioning test, the ISO 230-2
/// figures of the laser readings.
pub fn summary_figures(run: &Run) -> String {
    let laser = run.laser.as_ref().map(|l| {
        let f = l.iso230_2();
        format!(
            "ISO 230-2 {} ({} targets, {} runs): A {:.2} um, B {:.2} um, E {:.2} um, M {:.2} um, R {:.2} um",
            l.axis,
            l.targets_mm.len(),
            l.runs,
            f.a_um,
            f.b_um,
            f.e_um,
            f.m_um,
            f.r_um
        )
    });
    run.ballbar
        .iter()
        .map(trace_figures)
        .chain(laser)
        .collect::<Vec<_>>()
        .join("\n")
}

/// The lines of the run's ground truth that `vmt run` prints: for a milling run the chatter
/// (onset, frequency, or none), the cut and the surface (Ra, Rz, surface location error); for
/// a run through the feed drives, each axis' drive backlash and position-loop gain. A figure
/// the truth does not hold is left out, never printed as NaN or null.
pub fn truth_summary(truth: &serde_json::Value) -> Vec<String> {
    let mut lines = Vec::new();
    let m = &truth["milling"];
    if m.is_object() {
        let num = |k: &str| m[k].as_f64();
        let cut = match (
            num("spindle_rpm"),
            m["teeth"].as_u64(),
            num("tooth_passing_hz"),
        ) {
            (Some(n), Some(z), Some(f)) => {
                format!(" ({n:.0} rpm, {z} teeth: tooth passing {f:.1} Hz)")
            }
            _ => String::new(),
        };
        // The cut's truth counts from the cut's start; the log's clock from the job's.
        let cut_start = truth["cut_start_s"].as_f64().unwrap_or(0.0);
        let chatter = match (m["chatter"].as_bool(), num("chatter_onset_s")) {
            (Some(true), onset) => format!(
                "chatter{}{}",
                onset
                    .map(|t| format!(" from {:.3} s ({t:.3} s into the cut)", cut_start + t))
                    .unwrap_or_default(),
                num("chatter_frequency_hz")
                    .map(|f| format!(" at {f:.1} Hz"))
                    .unwrap_or_default()
            ),
            (Some(false), _) => "no chatter".to_string(),
            (None, _) => "chatter not recorded".to_string(),
        };
        lines.push(format!("  truth: {chatter}{cut}"));
        let surface: Vec<String> = [
            ("Ra", "ra_um", "um"),
            ("Rz", "rz_um", "um"),
            ("SLE mean", "sle_mean_um", "um"),
            ("max |SLE|", "sle_max_abs_um", "um"),
        ]
        .into_iter()
        .filter_map(|(name, key, unit)| num(key).map(|v| format!("{name} {v:.3} {unit}")))
        .collect();
        if !surface.is_empty() {
            lines.push(format!("  truth: surface {}", surface.join(", ")));
        }
    }
    if let Some(drives) = truth["drives"].as_object() {
        for (axis, d) in drives {
            let figures: Vec<String> = [
                d["backlash_um"]
                    .as_f64()
                    .map(|b| format!("drive backlash {b:.2} um")),
                d["kv_per_s"].as_f64().map(|k| format!("Kv {k} 1/s")),
            ]
            .into_iter()
            .flatten()
            .collect();
            if !figures.is_empty() {
                lines.push(format!(
                    "  truth {}: {}",
                    axis.to_uppercase(),
                    figures.join(", ")
                ));
            }
        }
    }
    lines
}
