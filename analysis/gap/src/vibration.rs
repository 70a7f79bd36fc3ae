//! The gap of a milling model against measured accelerometer logs: where it sits in frequency,
//! which tool-point or cutting parameter explains it, and how much fitting it buys.
//!
//! - Features: the third-octave band levels of each accelerometer axis ([`crate::spectrum`]).
//!   The residual of a band is the level difference in decibels,
//!   `r = 20 log10(L_meas / sqrt(L_model² + N_b²))`, where the model is simulated without
//!   sensor noise and `N_b = σ sqrt(bw / (f_s/2))` is the band share of the instrument's white
//!   noise σ (the scenario's `instruments.accelerometer.noise_m_s2`): a band where both hold
//!   only noise has no gap.
//! - Split: with several logs, every other log is held out (another depth of cut when the logs
//!   are runs of ours at other depths); with one log, its first half fits and its second half
//!   judges (and a drift between them shows).
//! - Candidates: each tool-point mode (stiffness, natural frequency, damping ratio: the
//!   spindle's and holder's compliance is part of the tool-point mode, as an impact test
//!   measures it) and the radial cutting coefficient Kr (the tangential one scales the forced
//!   response as the stiffness does, so it is left to the stiffness). Each is fitted on the calibration
//!   pieces by Levenberg–Marquardt through the milling simulator (forward-difference Jacobian in
//!   units of each parameter's step, damping `λ·diag(JᵀJ)`), and judged on the held-out pieces;
//!   effects are added by forward selection while the calibration BIC drops and the held-out
//!   mean square shrinks, as for the ball bar ([`crate::select`]).
//! - How much: the held-out RMS of the band residuals, dB, before and after each effect.

use crate::align::GapError;
use crate::effects::{Effect, Param};
use crate::select::{bic, explained, rss};
use crate::spectrum::{Band, band_levels, bands};
use crate::whiteness::{Whiteness, ljung_box};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use std::path::PathBuf;
use vmt_scenario::edit::Template;

/// An accelerometer log.
#[derive(Clone, Debug, PartialEq)]
pub struct Log {
    /// Name for messages (the file).
    pub name: String,
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Axis (`ax`, `ay`, `az`) and samples, m/s².
    pub channels: Vec<(String, Vec<f64>)>,
    /// Axial depth of cut, mm, when the log records it (a run of ours); else the model's.
    pub axial_depth_mm: Option<f64>,
    /// Spindle speed, rpm, when the log records it.
    pub spindle_rpm: Option<f64>,
    /// Teeth of the cutter, when the log records it.
    pub teeth: Option<u32>,
}

/// A milling scenario as a forward model of accelerometer logs.
pub struct MillingModel {
    template: Template,
    file: String,
    base_dir: Option<PathBuf>,
    tool: String,
    /// The instrument's noise, m/s² RMS per sample (simulated as zero by [`Self::new`], added
    /// per band).
    pub noise_m_s2: f64,
    /// The model's log as given.
    pub base: Log,
}

fn model_error(file: &str, e: impl std::fmt::Display) -> GapError {
    GapError::Model(format!("{file}: {e}"))
}

impl MillingModel {
    /// The milling scenario `text` (named `file`; the NC program and tables resolved in
    /// `base_dir`), simulated once as given.
    pub fn new(text: &str, file: &str, base_dir: Option<PathBuf>) -> Result<Self, GapError> {
        Self::build(text, file, base_dir, true)
    }

    /// The scenario as written, sensor noise included: a stand-in for a real machine in
    /// closed-loop studies.
    pub fn instrumented(
        text: &str,
        file: &str,
        base_dir: Option<PathBuf>,
    ) -> Result<Self, GapError> {
        Self::build(text, file, base_dir, false)
    }

    fn build(
        text: &str,
        file: &str,
        base_dir: Option<PathBuf>,
        quiet: bool,
    ) -> Result<Self, GapError> {
        let given = Template::parse(text, file).map_err(|e| model_error(file, e))?;
        let tool = given
            .text("job.tool")
            .map_err(|e| model_error(file, e))?
            .ok_or_else(|| {
                model_error(
                    file,
                    "no milling job ([job] kind = \"milling\" with a tool) to simulate",
                )
            })?;
        let noise_m_s2 = given
            .value("instruments.accelerometer.noise_m_s2")
            .map_err(|e| model_error(file, e))?
            .unwrap_or(0.0);
        let template = if quiet {
            let text = given
                .with_inserted(&[("instruments.accelerometer.noise_m_s2", 0.0)])
                .map_err(|e| model_error(file, e))?;
            Template::parse(&text, file).map_err(|e| model_error(file, e))?
        } else {
            given
        };
        let mut model = Self {
            template,
            file: file.to_string(),
            base_dir,
            tool,
            noise_m_s2,
            base: Log {
                name: file.to_string(),
                sample_rate_hz: 0.0,
                channels: Vec::new(),
                axial_depth_mm: None,
                spindle_rpm: None,
                teeth: None,
            },
        };
        model.base = model.log(&[])?;
        Ok(model)
    }

    /// The model's value at `key`, if it sets a number there.
    pub fn value(&self, key: &str) -> Option<f64> {
        self.template.value(key).ok().flatten()
    }

    /// The accelerometer log of the model's job with `(key, value)` written in.
    pub fn log(&self, values: &[(String, f64)]) -> Result<Log, GapError> {
        let pairs: Vec<(&str, f64)> = values.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        let text = self
            .template
            .with(&pairs)
            .map_err(|e| model_error(&self.file, e))?;
        let s = vmt_scenario::parse(&text, &self.file, self.base_dir.as_deref())
            .map_err(|e| GapError::Model(e.to_string()))?;
        let (Some(exec), Some(milling)) = (
            s.execution.as_ref(),
            s.execution.as_ref().and_then(|e| e.milling.as_ref()),
        ) else {
            return Err(model_error(&self.file, "the model has no milling job"));
        };
        let run = vmt_sim::machining::simulate_machining(
            &s.machine,
            &exec.axes,
            &exec.controller,
            &exec.job,
            milling,
            &exec.settings,
            &text,
            None,
            &mut |_| {},
        )
        .map_err(|e| model_error(&self.file, e))?;
        let accel = run
            .streams
            .iter()
            .find(|s| s.name == "accelerometer")
            .ok_or_else(|| model_error(&self.file, "the milling run has no accelerometer"))?;
        let truth = &run.ground_truth["milling"];
        Ok(Log {
            name: self.file.clone(),
            sample_rate_hz: milling.setup.accelerometer.sample_rate_hz,
            channels: accel
                .channels
                .iter()
                .map(|c| (c.name.clone(), c.values.clone()))
                .collect(),
            axial_depth_mm: truth["axial_depth_mm"].as_f64(),
            spindle_rpm: truth["spindle_rpm"].as_f64(),
            teeth: truth["teeth"].as_u64().and_then(|t| u32::try_from(t).ok()),
        })
    }

    /// The name of the job's tool in the scenario's tool table.
    pub fn tool(&self) -> &str {
        &self.tool
    }

    /// Tooth-passing frequency of the model's cut, Hz.
    pub fn tooth_passing_hz(&self) -> f64 {
        self.base.spindle_rpm.unwrap_or(0.0) / 60.0 * f64::from(self.base.teeth.unwrap_or(0))
    }

    /// The candidates the model can express: each tool-point mode of its job's tool, and the
    /// radial cutting coefficient. Steps and typical sizes are fractions of the model's values.
    pub fn library(&self) -> Vec<Effect> {
        let mut out = Vec::new();
        for axis in ['x', 'y'] {
            for i in 0.. {
                let key = |field: &str| format!("tools.{}.modes_{axis}[{i}].{field}", self.tool);
                let Some(f) = self.value(&key("frequency_hz")) else {
                    break;
                };
                let up = axis.to_ascii_uppercase();
                let scaled = |name: &str, unit: &'static str, field: &str, step: f64, typ: f64| {
                    let v = self.value(&key(field)).unwrap_or(0.0).abs();
                    Param {
                        name: format!("{name} {up}{}", i + 1),
                        unit,
                        keys: vec![key(field)],
                        step: step * v,
                        typical: typ * v,
                        increase_only: false,
                    }
                };
                out.push(Effect {
                    key: format!("tool_mode_{axis}{}", i + 1),
                    description: format!(
                        "tool-point mode {} in {up} at {f:.0} Hz (tool, holder and spindle): stiffness, natural frequency, damping",
                        i + 1
                    ),
                    params: vec![
                        scaled("stiffness", "N/um", "stiffness_n_per_um", 0.02, 0.2),
                        scaled("natural frequency", "Hz", "frequency_hz", 0.005, 0.03),
                        scaled("damping ratio", "", "damping_ratio", 0.05, 0.3),
                    ],
                    baseline: false,
                });
            }
        }
        // Only the radial coefficient: the tangential one sets the force level, which scales
        // the forced response exactly as the tool-point stiffness does (the response is
        // F·H(ω) with H ∝ 1/k), so accelerometer logs cannot tell the two apart and the
        // stiffness carries the level. Kr turns the force and changes the harmonics apart.
        let key = "job.material.kr_n_per_mm2".to_string();
        let kr = self.value(&key).unwrap_or(0.0).abs();
        out.push(Effect {
            key: "radial_force".into(),
            description: "radial cutting coefficient of the material (the force's direction)"
                .into(),
            params: vec![Param {
                name: "Kr".into(),
                unit: "N/mm2",
                keys: vec![key],
                step: 0.02 * kr,
                typical: 0.25 * kr,
                increase_only: false,
            }],
            baseline: false,
        });
        out
    }
}

/// Settings of the vibration gap.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// Least drop of the calibration BIC for an effect to be added.
    pub min_bic_drop: f64,
    /// Least shrink of the held-out mean square, as a fraction of what is left.
    pub min_held_out_shrink: f64,
    /// Least RMS change an effect must make to the held-out residual, dB (above the scatter
    /// of Welch band levels of a 0.5 s piece, about 0.3 dB).
    pub min_effect_db: f64,
    /// The gap counts as explained at or below this held-out RMS, dB…
    pub explained_floor_db: f64,
    /// …or this fraction of the gap before.
    pub explained_fraction: f64,
    /// Most effects added.
    pub max_effects: usize,
    /// Most Levenberg–Marquardt iterations per fit.
    pub max_iterations: usize,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            min_bic_drop: 10.0,
            min_held_out_shrink: 0.3,
            min_effect_db: 0.5,
            explained_floor_db: 1.0,
            explained_fraction: 0.25,
            max_effects: 3,
            max_iterations: 8,
        }
    }
}

/// A piece of a measured log: the whole log, or one half of it.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Piece {
    log: usize,
    half: Option<usize>,
}

impl Piece {
    fn samples<'a>(&self, x: &'a [f64]) -> &'a [f64] {
        match self.half {
            None => x,
            Some(h) => {
                let mid = x.len() / 2;
                if h == 0 { &x[..mid] } else { &x[mid..] }
            }
        }
    }

    fn label(&self, logs: &[Log]) -> String {
        let name = &logs[self.log].name;
        match self.half {
            None => name.clone(),
            Some(0) => format!("{name} (first half)"),
            Some(_) => format!("{name} (second half)"),
        }
    }
}

/// One free parameter with its model value.
#[derive(Clone, Debug)]
struct Free {
    effect: usize,
    name: String,
    unit: &'static str,
    key: String,
    base: f64,
    step: f64,
}

/// A fitted parameter.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Fitted {
    /// Parameter name.
    pub name: String,
    /// The model's value.
    pub model: f64,
    /// The fitted value.
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
    /// Its parameters and those of the effects before it, refitted.
    pub values: Vec<Fitted>,
    /// Calibration RMS of the band residuals after it, dB.
    pub calibration_rms_db: f64,
    /// Held-out RMS after it, dB.
    pub held_out_rms_db: f64,
    /// Shrink of the held-out mean square from before it.
    pub held_out_shrink: f64,
}

/// A candidate's fit in the round that stopped the selection.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Score {
    /// Effect key.
    pub effect: String,
    /// Held-out RMS with it, dB.
    pub held_out_rms_db: f64,
    /// Change of the calibration BIC.
    pub bic_change: f64,
}

/// Where the residual sits: a place and its share of the residual's energy.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Share {
    /// The place (a band, an axis, a piece…).
    pub place: String,
    /// Its share of Σ r², fraction.
    pub share: f64,
    /// Its share if the residual were spread evenly over the bands, fraction.
    pub even: f64,
}

/// The vibration gap of a model against logs.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct VibrationGap {
    /// How the logs were split.
    pub split: String,
    /// Pieces that fit and pieces that judge.
    pub calibration: Vec<String>,
    /// Held-out pieces.
    pub held_out: Vec<String>,
    /// The bands.
    pub bands: Vec<Band>,
    /// The axes compared.
    pub channels: Vec<String>,
    /// Tooth-passing frequency of the model's cut, Hz.
    pub tooth_passing_hz: f64,
    /// Per piece, per axis, per band: measured level, m/s².
    pub measured: Vec<Vec<Vec<f64>>>,
    /// The model's levels (noise added per band) before any effect.
    pub model_before: Vec<Vec<Vec<f64>>>,
    /// The model's levels after the chosen effects.
    pub model_after: Vec<Vec<Vec<f64>>>,
    /// Calibration RMS before, dB.
    pub calibration_before_db: f64,
    /// Held-out RMS before, dB.
    pub held_out_before_db: f64,
    /// Effects added, in order.
    pub steps: Vec<Step>,
    /// Scores of the round that stopped the selection.
    pub last_round: Vec<Score>,
    /// Where the residual sits before: by band, by axis, harmonic or not, by piece.
    pub before_by_band: Vec<Share>,
    /// By axis.
    pub before_by_axis: Vec<Share>,
    /// Tooth-passing harmonics against the rest.
    pub before_by_kind: Vec<Share>,
    /// By piece (in time, with one log).
    pub before_by_piece: Vec<Share>,
    /// The same places after.
    pub after_by_band: Vec<Share>,
    /// Ljung–Box test of what is left, per piece and axis over the bands in frequency order
    /// ([`WHITENESS_LAGS`] lags): structure left across neighbouring bands shows as not white.
    pub whiteness_after: Option<Whiteness>,
    /// Simulations run.
    pub simulations: usize,
}

impl VibrationGap {
    /// Held-out RMS after the chosen effects, dB.
    pub fn held_out_after_db(&self) -> f64 {
        self.steps
            .last()
            .map_or(self.held_out_before_db, |s| s.held_out_rms_db)
    }

    /// Whether the chosen effects explain the gap.
    pub fn explained(&self, o: &Options) -> bool {
        !self.steps.is_empty()
            && explained(
                self.held_out_before_db,
                self.held_out_after_db(),
                o.explained_floor_db,
                o.explained_fraction,
            )
    }
}

/// Levels per piece, per axis, per band.
type Levels = Vec<Vec<Vec<f64>>>;

/// The fixed parts of one analysis: the measured levels and how the model is read against them.
struct Problem<'a> {
    model: &'a MillingModel,
    logs: &'a [Log],
    pieces: Vec<Piece>,
    calibration: Vec<usize>,
    held_out: Vec<usize>,
    channels: Vec<String>,
    bands: Vec<Band>,
    /// The instrument's noise per band, m/s².
    noise: Vec<f64>,
    measured: Levels,
    /// Per piece, the (axis, band) cells where the measured level stands [`ABOVE_NOISE`] over
    /// the instrument's noise: the residual's entries. Cells of noise alone carry no gap.
    cells: Vec<Vec<(usize, usize)>>,
    simulations: std::sync::atomic::AtomicUsize,
}

/// How far over the band's instrument noise a measured level must be to count (6 dB).
const ABOVE_NOISE: f64 = 2.0;

/// A floor under every level, m/s², so that a silent axis has a finite level in dB.
const TINY: f64 = 1e-9;

impl<'a> Problem<'a> {
    /// `quiet`: the logs were simulated without sensor noise, which is then added per band to
    /// them as to the model.
    fn new(model: &'a MillingModel, logs: &'a [Log], quiet: bool) -> Result<Self, GapError> {
        let first = logs.first().ok_or(GapError::Empty)?;
        for log in logs {
            check(model, log)?;
        }
        let pieces: Vec<Piece> = if logs.len() == 1 {
            (0..2)
                .map(|h| Piece {
                    log: 0,
                    half: Some(h),
                })
                .collect()
        } else {
            (0..logs.len())
                .map(|log| Piece { log, half: None })
                .collect()
        };
        let (calibration, held_out) = (0..pieces.len()).partition(|i| i % 2 == 0);
        let channels: Vec<String> = first
            .channels
            .iter()
            .map(|(n, _)| n.clone())
            .filter(|n| model.base.channels.iter().any(|(m, _)| m == n))
            .collect();
        if channels.is_empty() {
            return Err(GapError::Model(format!(
                "{}: no axis in common with the model's accelerometer (ax, ay, az)",
                first.name
            )));
        }
        // Every log must carry the axes read from the first: a log without one would otherwise
        // give that axis no samples, which reads as a log too short for a spectrum.
        for log in &logs[1..] {
            if let Some(c) = channels
                .iter()
                .find(|c| !log.channels.iter().any(|(n, _)| n == *c))
            {
                return Err(missing_channel(&log.name, c, &first.name));
            }
        }
        let fs = model.base.sample_rate_hz;
        let bands = bands(fs);
        let noise = bands
            .iter()
            .map(|b| model.noise_m_s2 * (b.width_hz() / (fs / 2.0)).sqrt())
            .collect();
        let mut p = Self {
            model,
            logs,
            pieces,
            calibration,
            held_out,
            channels,
            bands,
            noise,
            measured: Vec::new(),
            cells: Vec::new(),
            simulations: 0.into(),
        };
        p.measured = p.levels(logs, quiet)?;
        p.cells = p
            .measured
            .iter()
            .map(|piece| {
                piece
                    .iter()
                    .enumerate()
                    .flat_map(|(c, levels)| levels.iter().enumerate().map(move |(b, l)| (c, b, *l)))
                    .filter(|&(_, b, l)| l >= ABOVE_NOISE * p.noise[b])
                    .map(|(c, b, _)| (c, b))
                    .collect()
            })
            .collect();
        if p.cells.iter().any(Vec::is_empty) {
            return Err(GapError::Model(format!(
                "{}: no band of the log stands above the instrument's noise ({} m/s2)",
                first.name, model.noise_m_s2
            )));
        }
        Ok(p)
    }

    /// Levels of `logs` (one per measured log, in order) on the pieces; the model's with its
    /// instrument noise added per band.
    fn levels(&self, logs: &[Log], model: bool) -> Result<Levels, GapError> {
        self.pieces
            .iter()
            .map(|piece| {
                let log = &logs[piece.log];
                self.channels
                    .iter()
                    .map(|c| {
                        let x = log
                            .channels
                            .iter()
                            .find(|(n, _)| n == c)
                            .map(|(_, x)| piece.samples(x))
                            .ok_or_else(|| missing_channel(&log.name, c, &self.logs[0].name))?;
                        let levels = band_levels(x, log.sample_rate_hz, &self.bands)
                            .ok_or_else(|| too_short(&piece.label(self.logs)))?;
                        Ok(levels
                            .iter()
                            .zip(&self.noise)
                            .map(|(l, n)| {
                                let n = if model { *n } else { 0.0 };
                                (l * l + n * n + TINY * TINY).sqrt()
                            })
                            .collect())
                    })
                    .collect()
            })
            .collect()
    }

    /// The model's logs at `values`, one per measured log (at its depth of cut).
    fn simulate(&self, values: &[(String, f64)]) -> Result<Vec<Log>, GapError> {
        let depths: Vec<Option<f64>> = self.logs.iter().map(|l| l.axial_depth_mm).collect();
        let mut distinct: Vec<Option<f64>> = Vec::new();
        for d in &depths {
            if !distinct.contains(d) {
                distinct.push(*d);
            }
        }
        // The model as given at its own depth is the log it made when it was built.
        let given = |d: &Option<f64>| {
            values.is_empty() && (d.is_none() || *d == self.model.base.axial_depth_mm)
        };
        let runs: Vec<Log> = distinct
            .par_iter()
            .map(|d| {
                if given(d) {
                    return Ok(self.model.base.clone());
                }
                let mut v = values.to_vec();
                v.extend(d.map(|d| ("job.axial_depth_mm".to_string(), d)));
                self.model.log(&v)
            })
            .collect::<Result<_, _>>()?;
        let simulated = distinct.iter().filter(|d| !given(d)).count();
        self.simulations
            .fetch_add(simulated, std::sync::atomic::Ordering::Relaxed);
        Ok(depths
            .iter()
            .map(|d| runs[distinct.iter().position(|x| x == d).unwrap_or(0)].clone())
            .collect())
    }

    /// The model's levels and the residuals (dB, per piece, flattened over axes and bands).
    fn evaluate(&self, values: &[(String, f64)]) -> Result<(Levels, Vec<Vec<f64>>), GapError> {
        let logs = self.simulate(values)?;
        let levels = self.levels(&logs, true)?;
        let residuals = self
            .cells
            .iter()
            .enumerate()
            .map(|(p, cells)| {
                cells
                    .iter()
                    .map(|&(c, b)| 20.0 * (self.measured[p][c][b] / levels[p][c][b]).log10())
                    .collect()
            })
            .collect();
        Ok((levels, residuals))
    }

    fn stack(&self, r: &[Vec<f64>], rows: &[usize]) -> Vec<f64> {
        rows.iter().flat_map(|i| r[*i].iter().copied()).collect()
    }
}

fn missing_channel(log: &str, channel: &str, first: &str) -> GapError {
    GapError::Model(format!(
        "{log}: no channel {channel}, which {first} has; every log must carry the same \
         accelerometer axes"
    ))
}

fn too_short(piece: &str) -> GapError {
    GapError::Model(format!(
        "{piece}: shorter than one spectrum segment ({} samples); a longer log is needed",
        crate::spectrum::SEGMENT
    ))
}

/// Refuses a log that is not of the model's job: another sample rate, spindle speed or cutter.
fn check(model: &MillingModel, log: &Log) -> Result<(), GapError> {
    let mismatch = |what: &'static str, measured: String, model: String| GapError::Mismatch {
        label: log.name.clone(),
        what,
        measured,
        model,
    };
    let fs = model.base.sample_rate_hz;
    if (log.sample_rate_hz - fs).abs() > 0.01 * fs {
        return Err(mismatch(
            "sample_rate_hz",
            format!("{:.1} Hz", log.sample_rate_hz),
            format!("{fs:.1} Hz"),
        ));
    }
    if let (Some(m), Some(s)) = (log.spindle_rpm, model.base.spindle_rpm)
        && (m - s).abs() > 0.005 * s
    {
        return Err(mismatch(
            "spindle_rpm",
            format!("{m} rpm"),
            format!("{s} rpm"),
        ));
    }
    if let (Some(m), Some(s)) = (log.teeth, model.base.teeth)
        && m != s
    {
        return Err(mismatch("teeth", m.to_string(), s.to_string()));
    }
    Ok(())
}

fn rms(v: &[f64]) -> f64 {
    (rss(v) / v.len().max(1) as f64).sqrt()
}

/// A fit: parameter values (in steps from the model's), the levels and residuals there.
struct Fit {
    free: Vec<usize>,
    theta: Vec<f64>,
    levels: Levels,
    residuals: Vec<Vec<f64>>,
}

struct Selector<'a> {
    problem: Problem<'a>,
    library: Vec<Effect>,
    free: Vec<Free>,
    o: Options,
}

impl Selector<'_> {
    fn values(&self, free: &[usize], theta: &[f64]) -> Vec<(String, f64)> {
        free.iter()
            .zip(theta)
            .map(|(i, t)| {
                let p = &self.free[*i];
                (p.key.clone(), p.base + t * p.step)
            })
            .collect()
    }

    fn cal_rss(&self, r: &[Vec<f64>]) -> f64 {
        rss(&self.problem.stack(r, &self.problem.calibration))
    }

    /// Levenberg–Marquardt on the calibration pieces from `theta`.
    fn fit(&self, free: Vec<usize>, mut theta: Vec<f64>) -> Result<Fit, GapError> {
        let (mut levels, mut residuals) = self.problem.evaluate(&self.values(&free, &theta))?;
        let mut cost = self.cal_rss(&residuals);
        let mut lambda: f64 = 1e-2;
        for _ in 0..self.o.max_iterations {
            let r0 = self.problem.stack(&residuals, &self.problem.calibration);
            let columns: Vec<Vec<f64>> = (0..free.len())
                .into_par_iter()
                .map(|j| {
                    let mut t = theta.clone();
                    t[j] += 1.0;
                    let (_, r) = self.problem.evaluate(&self.values(&free, &t))?;
                    let r = self.problem.stack(&r, &self.problem.calibration);
                    Ok(r.iter().zip(&r0).map(|(a, b)| a - b).collect())
                })
                .collect::<Result<_, GapError>>()?;
            let k = free.len();
            let jtj = DMatrix::from_fn(k, k, |a, b| {
                columns[a]
                    .iter()
                    .zip(&columns[b])
                    .map(|(x, y)| x * y)
                    .sum::<f64>()
            });
            let jtr = DVector::from_fn(k, |a, _| {
                columns[a].iter().zip(&r0).map(|(x, y)| x * y).sum::<f64>()
            });
            let mut improved = false;
            for _ in 0..6 {
                let mut a = jtj.clone();
                for d in 0..k {
                    a[(d, d)] += lambda * jtj[(d, d)].max(1e-12);
                }
                let Some(delta) = a.cholesky().map(|c| -c.solve(&jtr)) else {
                    lambda *= 4.0;
                    continue;
                };
                let trial: Vec<f64> = theta.iter().zip(delta.iter()).map(|(t, d)| t + d).collect();
                match self.problem.evaluate(&self.values(&free, &trial)) {
                    Ok((l, r)) if self.cal_rss(&r) < cost => {
                        let new = self.cal_rss(&r);
                        improved = (cost - new) > 1e-4 * cost;
                        (theta, levels, residuals, cost) = (trial, l, r, new);
                        lambda = (lambda / 3.0).max(1e-6);
                        break;
                    }
                    // A value the scenario refuses (a negative stiffness) is no better fit.
                    Ok(_) | Err(GapError::Model(_)) => lambda *= 4.0,
                    Err(e) => return Err(e),
                }
            }
            if !improved {
                break;
            }
        }
        Ok(Fit {
            free,
            theta,
            levels,
            residuals,
        })
    }

    fn fitted(&self, f: &Fit) -> Vec<Fitted> {
        f.free
            .iter()
            .zip(&f.theta)
            .map(|(i, t)| {
                let p = &self.free[*i];
                Fitted {
                    name: p.name.clone(),
                    model: p.base,
                    value: p.base + t * p.step,
                    unit: p.unit.to_string(),
                }
            })
            .collect()
    }
}

/// The vibration gap of `model` against the measured `logs`: where, which effects of the
/// model's library (forward selection), and how much.
pub fn analyse(model: &MillingModel, logs: &[Log], o: &Options) -> Result<VibrationGap, GapError> {
    analyse_without(model, logs, &[], o)
}

/// How far `offsets` (`(key, offset)` from the model's values) stand out on the model's job:
/// the held-out RMS of the band residual, dB, between the model with them and without, both
/// without sensor noise and with its share added per band.
pub fn visibility(model: &MillingModel, offsets: &[(String, f64)]) -> Result<f64, GapError> {
    let values: Vec<(String, f64)> = offsets
        .iter()
        .filter_map(|(k, d)| model.value(k).map(|v| (k.clone(), v + d)))
        .collect();
    let logs = [model.log(&values)?];
    let p = Problem::new(model, &logs, true)?;
    let (_, r) = p.evaluate(&[])?;
    Ok(rms(&p.stack(&r, &p.held_out)))
}

/// [`analyse`] with the effects named in `hidden` left out of the candidates.
pub fn analyse_without(
    model: &MillingModel,
    logs: &[Log],
    hidden: &[&str],
    o: &Options,
) -> Result<VibrationGap, GapError> {
    let problem = Problem::new(model, logs, false)?;
    let library = model.library();
    let free: Vec<Free> = library
        .iter()
        .enumerate()
        .flat_map(|(e, effect)| {
            effect.params.iter().filter_map(move |p| {
                let key = p.keys.first()?.clone();
                Some(Free {
                    effect: e,
                    name: p.name.clone(),
                    unit: p.unit,
                    base: model.value(&key)?,
                    key,
                    step: p.step,
                })
            })
        })
        .filter(|f| f.step > 0.0)
        .collect();
    let sel = Selector {
        problem,
        library,
        free,
        o: *o,
    };
    let p = &sel.problem;
    let (before_levels, before) = p.evaluate(&[])?;
    let n_cal = p.stack(&before, &p.calibration).len();
    let held = |r: &[Vec<f64>]| p.stack(r, &p.held_out);
    let mut cur_held = rss(&held(&before));
    let mut cur_bic = bic(sel.cal_rss(&before), n_cal, 0);
    let held_out_before_db = rms(&held(&before));
    let (mut chosen, mut current, mut steps, mut last_round) =
        (Vec::<usize>::new(), None::<Fit>, Vec::new(), Vec::new());
    while chosen.len() < o.max_effects && held_out_before_db > o.explained_floor_db {
        let fits: Vec<(usize, Fit)> = (0..sel.library.len())
            .filter(|e| !chosen.contains(e) && !hidden.contains(&sel.library[*e].key.as_str()))
            .collect::<Vec<_>>()
            .into_par_iter()
            .filter_map(|e| {
                let (mut free, mut theta) =
                    current.as_ref().map_or((Vec::new(), Vec::new()), |f| {
                        (f.free.clone(), f.theta.clone())
                    });
                let own: Vec<usize> = (0..sel.free.len())
                    .filter(|i| sel.free[*i].effect == e)
                    .collect();
                if own.is_empty() {
                    return None;
                }
                theta.extend(own.iter().map(|_| 0.0));
                free.extend(own);
                sel.fit(free, theta).ok().map(|f| (e, f))
            })
            .collect();
        let score = |(e, f): &(usize, Fit)| Score {
            effect: sel.library[*e].key.clone(),
            held_out_rms_db: rms(&held(&f.residuals)),
            bic_change: bic(sel.cal_rss(&f.residuals), n_cal, f.free.len()) - cur_bic,
        };
        last_round = fits.iter().map(score).collect();
        last_round.sort_by(|a, b| a.held_out_rms_db.total_cmp(&b.held_out_rms_db));
        let best = fits
            .into_iter()
            .filter(|x| score(x).bic_change < -o.min_bic_drop)
            .min_by(|a, b| rss(&held(&a.1.residuals)).total_cmp(&rss(&held(&b.1.residuals))));
        let Some((e, fit)) = best else {
            break;
        };
        let held_new = held(&fit.residuals);
        let prev = current
            .as_ref()
            .map_or_else(|| held(&before), |f| held(&f.residuals));
        let change = rms(&prev
            .iter()
            .zip(&held_new)
            .map(|(a, b)| a - b)
            .collect::<Vec<_>>());
        let shrink = 1.0 - rss(&held_new) / cur_held;
        if shrink < o.min_held_out_shrink || change < o.min_effect_db {
            break;
        }
        steps.push(Step {
            effect: sel.library[e].key.clone(),
            description: sel.library[e].description.clone(),
            values: sel.fitted(&fit),
            calibration_rms_db: rms(&p.stack(&fit.residuals, &p.calibration)),
            held_out_rms_db: rms(&held_new),
            held_out_shrink: shrink,
        });
        cur_held = rss(&held_new);
        cur_bic = bic(sel.cal_rss(&fit.residuals), n_cal, fit.free.len());
        chosen.push(e);
        current = Some(fit);
    }
    let (after_levels, after) = current.map_or((before_levels.clone(), before.clone()), |f| {
        (f.levels, f.residuals)
    });
    let f_tp = model.tooth_passing_hz();
    Ok(VibrationGap {
        split: if logs.len() == 1 {
            "one log: its first half fits, its second half judges".into()
        } else {
            "every other log held out".into()
        },
        calibration: p
            .calibration
            .iter()
            .map(|i| p.pieces[*i].label(logs))
            .collect(),
        held_out: p
            .held_out
            .iter()
            .map(|i| p.pieces[*i].label(logs))
            .collect(),
        before_by_band: by_band(p, &before),
        before_by_axis: by_axis(p, &before),
        before_by_kind: by_kind(p, &before, f_tp),
        before_by_piece: by_piece(p, &before),
        after_by_band: by_band(p, &after),
        whiteness_after: whiteness(p, &after),
        bands: p.bands.clone(),
        channels: p.channels.clone(),
        tooth_passing_hz: f_tp,
        measured: p.measured.clone(),
        model_before: before_levels,
        model_after: after_levels,
        calibration_before_db: rms(&p.stack(&before, &p.calibration)),
        held_out_before_db,
        steps,
        last_round,
        simulations: p.simulations.load(std::sync::atomic::Ordering::Relaxed),
    })
}

/// Lags of the whiteness test over the bands.
pub const WHITENESS_LAGS: usize = 3;

/// Ljung–Box over each piece's and axis' residual, bands in frequency order.
fn whiteness(p: &Problem, r: &[Vec<f64>]) -> Option<Whiteness> {
    let series: Vec<Vec<f64>> = p
        .cells
        .iter()
        .zip(r)
        .flat_map(|(cells, values)| {
            (0..p.channels.len()).map(move |c| {
                cells
                    .iter()
                    .zip(values)
                    .filter(|((axis, _), _)| *axis == c)
                    .map(|(_, v)| *v)
                    .collect()
            })
        })
        .collect();
    ljung_box(&series, WHITENESS_LAGS)
}

/// A place for [`shares`]: its name and which (axis index, band index) cells it holds.
type Place = (String, Box<dyn Fn(usize, usize) -> bool>);

/// Shares of Σ r² over `places`, with the share an even spread over the cells would give.
fn shares(p: &Problem, r: &[Vec<f64>], places: Vec<Place>) -> Vec<Share> {
    let total: f64 = r.iter().map(|x| rss(x)).sum::<f64>().max(1e-300);
    let cells: usize = p.cells.iter().map(Vec::len).sum();
    places
        .into_iter()
        .map(|(place, holds)| {
            let (mut sum, mut count) = (0.0, 0usize);
            for (piece, values) in p.cells.iter().zip(r) {
                for (&(c, b), v) in piece.iter().zip(values) {
                    if holds(c, b) {
                        sum += v * v;
                        count += 1;
                    }
                }
            }
            Share {
                place,
                share: sum / total,
                even: count as f64 / cells.max(1) as f64,
            }
        })
        .collect()
}

fn band_name(b: &Band) -> String {
    format!(
        "{:.0} Hz band ({:.0}-{:.0} Hz)",
        b.centre_hz, b.lo_hz, b.hi_hz
    )
}

fn by_band(p: &Problem, r: &[Vec<f64>]) -> Vec<Share> {
    let places = p
        .bands
        .iter()
        .enumerate()
        .map(|(k, b)| {
            let f: Box<dyn Fn(usize, usize) -> bool> = Box::new(move |_, j| j == k);
            (band_name(b), f)
        })
        .collect();
    shares(p, r, places)
}

fn by_axis(p: &Problem, r: &[Vec<f64>]) -> Vec<Share> {
    let places = p
        .channels
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let f: Box<dyn Fn(usize, usize) -> bool> = Box::new(move |a, _| a == k);
            (c.clone(), f)
        })
        .collect();
    shares(p, r, places)
}

/// Bands holding a tooth-passing harmonic (forced vibration) against the others (free
/// vibration: chatter near a mode, or a resonance the model misplaces).
fn by_kind(p: &Problem, r: &[Vec<f64>], f_tp: f64) -> Vec<Share> {
    let harmonic: Vec<bool> = p
        .bands
        .iter()
        .map(|b| {
            f_tp > 0.0
                && (1..)
                    .map(|k| k as f64 * f_tp)
                    .take_while(|f| *f < b.hi_hz)
                    .any(|f| b.holds(f))
        })
        .collect();
    let (h1, h2) = (harmonic.clone(), harmonic);
    shares(
        p,
        r,
        vec![
            (
                "bands with a tooth-passing harmonic".into(),
                Box::new(move |_, j| h1[j]),
            ),
            (
                "bands between harmonics".into(),
                Box::new(move |_, j| !h2[j]),
            ),
        ],
    )
}

fn by_piece(p: &Problem, r: &[Vec<f64>]) -> Vec<Share> {
    let total: f64 = r.iter().map(|x| rss(x)).sum::<f64>().max(1e-300);
    p.pieces
        .iter()
        .zip(r)
        .map(|(piece, x)| Share {
            place: piece.label(p.logs),
            share: rss(x) / total,
            even: 1.0 / r.len() as f64,
        })
        .collect()
}
