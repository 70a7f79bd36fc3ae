//! The gap of a milling model against measured accelerometer logs: where it sits in frequency,
//! which tool-point or cutting parameter explains it, and how much fitting it buys.
//!
//! - Features: the third-octave band levels of each accelerometer axis ([`crate::spectrum`]).
//!   The residual of a band is the level difference in decibels,
//!   `r = 20 log10(L_meas / sqrt(L_model² + N_b²))`, where the model is simulated without
//!   sensor noise and `N_b = σ sqrt(bw / (f_s/2))` is the band share of the instrument's white
//!   noise σ (the scenario's `instruments.accelerometer.noise_m_s2`): a band where both hold
//!   only noise has no gap.
//! - Split: every log is cut into thirds in time, and third `k` of log `i` plays the role
//!   `(k + i) mod 3` of fit, select and judge, as the ball bar's segments do
//!   ([`crate::split`]): the candidates are fitted on the fit pieces, ranked and gated on the
//!   select pieces, and the held-out figures and the confirmation that the chosen effects
//!   explain the gap are read from the judge pieces, used for neither.
//! - Candidates: each tool-point mode (stiffness, natural frequency, damping ratio: the
//!   spindle's and holder's compliance is part of the tool-point mode, as an impact test
//!   measures it) and the radial cutting coefficient Kr (the tangential one scales the forced
//!   response as the stiffness does, so it is left to the stiffness). Each is fitted on the fit
//!   pieces by Levenberg–Marquardt through the milling simulator (forward-difference Jacobian in
//!   units of each parameter's step, damping `λ·diag(JᵀJ)`), and scored on the select pieces;
//!   effects are added by forward selection while the fit BIC drops and the select mean square
//!   shrinks, as for the ball bar ([`crate::select`]); a fit whose values a tool and holder of
//!   the class cannot have ([`crate::effects::Plausible`]) is set aside as implausible.
//! - How much: the RMS of the band residuals on the untouched judge pieces, dB, before and
//!   after the chosen effects.
//! - Where: by band, axis, tooth-passing harmonic or not, piece, and in time: the band levels
//!   of windows of [`WINDOW_S`] along each log against the model's, and the (window, band)
//!   cells where the residual peaks.

use crate::align::GapError;
use crate::effects::{Effect, Implausible, Param, Plausible, Scale};
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
                let scaled = |name: &str,
                              unit: &'static str,
                              field: &str,
                              (step, typ): (f64, f64),
                              plausible: Plausible| {
                    let v = self.value(&key(field)).unwrap_or(0.0).abs();
                    Param {
                        name: format!("{name} {up}{}", i + 1),
                        unit,
                        keys: vec![key(field)],
                        step: step * v,
                        typical: typ * v,
                        increase_only: false,
                        plausible,
                        scale: Scale::Same,
                    }
                };
                out.push(Effect {
                    key: format!("tool_mode_{axis}{}", i + 1),
                    description: format!(
                        "tool-point mode {} in {up} at {f:.0} Hz (tool, holder and spindle): stiffness, natural frequency, damping",
                        i + 1
                    ),
                    params: vec![
                        scaled("stiffness", "N/um", "stiffness_n_per_um", (0.02, 0.2), MODE_STIFFNESS),
                        scaled("natural frequency", "Hz", "frequency_hz", (0.005, 0.03), MODE_FREQUENCY),
                        scaled("damping ratio", "", "damping_ratio", (0.05, 0.3), MODE_DAMPING),
                    ],
                    baseline: false,
                    whole_travel: None,
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
                plausible: RADIAL_COEFFICIENT,
                scale: Scale::Same,
            }],
            baseline: false,
            whole_travel: None,
        });
        out
    }
}

/// Stiffness of a tool-point mode, N/µm.
const MODE_STIFFNESS: Plausible = Plausible {
    absolute: (0.1, 1000.0),
    relative: Some((1.0 / 3.0, 3.0)),
    reason: "tool-point stiffness of end mills in their holders: 1-100 N/um by impact tests; \
             the same tool held or worn otherwise differs by up to 3 times",
};
/// Natural frequency of a tool-point mode, Hz.
const MODE_FREQUENCY: Plausible = Plausible {
    absolute: (50.0, 20000.0),
    relative: Some((0.7, 1.4)),
    reason: "tool-point modes move with the stick-out, the clamping and the spindle's speed \
             (gyroscopic and centrifugal softening) by up to 30 %",
};
/// Damping ratio of a tool-point mode.
const MODE_DAMPING: Plausible = Plausible {
    absolute: (0.002, 0.2),
    relative: Some((0.25, 4.0)),
    reason: "tool-point damping ratios of 0.5-10 % by impact tests; joints and the cut's \
             process damping move them by up to 4 times",
};
/// Radial cutting coefficient, N/mm².
const RADIAL_COEFFICIENT: Plausible = Plausible {
    absolute: (0.0, 5000.0),
    relative: Some((1.0 / 3.0, 3.0)),
    reason: "radial cutting coefficients are 0.2-0.8 of the tangential one (Altintas, \
             Manufacturing Automation); the material's state and the edge's wear change them by \
             up to 3 times",
};

/// Settings of the vibration gap.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// Least drop of the fit pieces' BIC for an effect to be added.
    pub min_bic_drop: f64,
    /// Least shrink of the select pieces' mean square, as a fraction of what is left.
    pub min_select_shrink: f64,
    /// Least RMS change an effect must make to the select pieces' residual, dB (above the
    /// scatter of Welch band levels of a third of a log, about 0.3 dB).
    pub min_effect_db: f64,
    /// The gap counts as explained at or below this RMS, dB…
    pub explained_floor_db: f64,
    /// …or this fraction of the gap before.
    pub explained_fraction: f64,
    /// Most effects added.
    pub max_effects: usize,
    /// Most Levenberg–Marquardt iterations per fit.
    pub max_iterations: usize,
    /// Significance level of the paired test that calls a rival worse than the chosen effect.
    pub ambiguity_level: f64,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            min_bic_drop: 10.0,
            min_select_shrink: 0.3,
            min_effect_db: 0.5,
            explained_floor_db: 1.0,
            explained_fraction: 0.25,
            max_effects: 3,
            max_iterations: 8,
            ambiguity_level: 0.05,
        }
    }
}

/// A third of a measured log in time.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Piece {
    log: usize,
    third: usize,
}

impl Piece {
    fn samples<'a>(&self, x: &'a [f64]) -> &'a [f64] {
        let n = x.len();
        &x[self.third * n / 3..(self.third + 1) * n / 3]
    }

    fn label(&self, logs: &[Log]) -> String {
        let name = &logs[self.log].name;
        let which = ["first", "second", "last"][self.third];
        format!("{name} ({which} third)")
    }

    /// Its role: 0 fit, 1 select, 2 judge.
    fn role(&self) -> usize {
        (self.third + self.log) % 3
    }
}

/// Length of the windows of the time localisation, s.
pub const WINDOW_S: f64 = 0.25;

/// A (window, axis, band) cell of a log where the residual peaks.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TimePeak {
    /// The log.
    pub log: String,
    /// Start and end of the window, s from the log's start.
    pub from_s: f64,
    /// End of the window, s.
    pub to_s: f64,
    /// The axis.
    pub axis: String,
    /// The band.
    pub band: String,
    /// The residual there, dB (measured over the model).
    pub residual_db: f64,
}

/// A candidate that explains the judge pieces as well as a chosen effect.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Alternative {
    /// The chosen effect.
    pub instead_of: String,
    /// The rival.
    pub effect: String,
    /// Its fitted values.
    pub values: Vec<Fitted>,
    /// RMS of the judge pieces with it, dB.
    pub judge_rms_db: f64,
    /// With the chosen effect, dB.
    pub chosen_judge_rms_db: f64,
    /// Paired t of its excess mean square over the judge cells.
    pub t: f64,
    /// One-sided p-value of that excess.
    pub p_value: f64,
    /// When a value it needs is beyond the class's range.
    pub implausible: Option<Implausible>,
}

/// A candidate set aside because its fitted values are beyond the class's range.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Rejected {
    /// Effect key.
    pub effect: String,
    /// What it would need.
    pub implausible: Implausible,
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
    param: Param,
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
    /// RMS of the fit pieces' band residuals after it, dB.
    pub fit_rms_db: f64,
    /// RMS of the select pieces' after it, dB.
    pub select_rms_db: f64,
    /// Shrink of the select pieces' mean square from before it.
    pub select_shrink: f64,
    /// RMS of the judge pieces' after it, dB.
    pub judge_rms_db: f64,
}

/// A candidate's fit in the round that stopped the selection.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Score {
    /// Effect key.
    pub effect: String,
    /// RMS of the select pieces with it, dB.
    pub select_rms_db: f64,
    /// Change of the fit pieces' BIC.
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
    /// Pieces that fit.
    pub fit: Vec<String>,
    /// Pieces that select.
    pub select: Vec<String>,
    /// Pieces that judge, used neither to fit nor to select.
    pub judge: Vec<String>,
    /// The index (into the levels) of the first judge piece, for plots.
    pub first_judge_piece: usize,
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
    /// RMS of the fit pieces before, dB.
    pub fit_before_db: f64,
    /// RMS of the select pieces before, dB.
    pub select_before_db: f64,
    /// RMS of the judge pieces before, dB.
    pub judge_before_db: f64,
    /// RMS of the judge pieces after the chosen effects, dB.
    pub judge_after_db: f64,
    /// Effects added, in order.
    pub steps: Vec<Step>,
    /// Candidates set aside as implausible.
    pub rejected: Vec<Rejected>,
    /// Candidates that explain the judge pieces as well as a chosen effect did in its round
    /// (paired test over the judge cells; see [`crate::select`]).
    pub alternatives: Vec<Alternative>,
    /// Scores of the round that stopped the selection.
    pub last_round: Vec<Score>,
    /// Where the residual sits before: by band, by axis, harmonic or not, by piece.
    pub before_by_band: Vec<Share>,
    /// By axis.
    pub before_by_axis: Vec<Share>,
    /// Tooth-passing harmonics against the rest.
    pub before_by_kind: Vec<Share>,
    /// By piece (in time).
    pub before_by_piece: Vec<Share>,
    /// The (window, axis, band) cells where the residual before peaks, largest first.
    pub before_in_time: Vec<TimePeak>,
    /// The same places after.
    pub after_by_band: Vec<Share>,
    /// Ljung–Box test of what is left, per piece and axis over the bands in frequency order
    /// ([`WHITENESS_LAGS`] lags): structure left across neighbouring bands shows as not white.
    pub whiteness_after: Option<Whiteness>,
    /// Simulations run.
    pub simulations: usize,
}

impl VibrationGap {
    /// RMS of the select pieces after the chosen effects, dB.
    pub fn select_after_db(&self) -> f64 {
        self.steps
            .last()
            .map_or(self.select_before_db, |s| s.select_rms_db)
    }

    /// Whether the chosen effects explain the gap: on the select pieces and, untouched, on the
    /// judge pieces.
    pub fn explained(&self, o: &Options) -> bool {
        let by =
            |before, after| explained(before, after, o.explained_floor_db, o.explained_fraction);
        !self.steps.is_empty()
            && by(self.select_before_db, self.select_after_db())
            && by(self.judge_before_db, self.judge_after_db)
    }

    /// The fraction of the judge pieces' mean square the chosen effects remove.
    pub fn judge_shrink(&self) -> f64 {
        1.0 - (self.judge_after_db / self.judge_before_db).powi(2)
    }
}

/// Levels per piece, per axis, per band.
type Levels = Vec<Vec<Vec<f64>>>;

/// The fixed parts of one analysis: the measured levels and how the model is read against them.
struct Problem<'a> {
    model: &'a MillingModel,
    logs: &'a [Log],
    pieces: Vec<Piece>,
    /// The pieces of each role: fit, select, judge.
    roles: [Vec<usize>; 3],
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
        let pieces: Vec<Piece> = (0..logs.len())
            .flat_map(|log| (0..3).map(move |third| Piece { log, third }))
            .collect();
        let roles = [0, 1, 2].map(|r| {
            (0..pieces.len())
                .filter(|i| pieces[*i].role() == r)
                .collect()
        });
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
            roles,
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
        rss(&self.problem.stack(r, &self.problem.roles[0]))
    }

    /// The first fitted value beyond what the class allows.
    fn implausible(&self, f: &Fit) -> Option<Implausible> {
        f.free.iter().zip(&f.theta).find_map(|(i, t)| {
            let p = &self.free[*i];
            p.param.check(&[p.base], t * p.step).err()
        })
    }

    /// Levenberg–Marquardt on the fit pieces from `theta`.
    fn fit(&self, free: Vec<usize>, mut theta: Vec<f64>) -> Result<Fit, GapError> {
        let (mut levels, mut residuals) = self.problem.evaluate(&self.values(&free, &theta))?;
        let mut cost = self.cal_rss(&residuals);
        let mut lambda: f64 = 1e-2;
        for _ in 0..self.o.max_iterations {
            let r0 = self.problem.stack(&residuals, &self.problem.roles[0]);
            let columns: Vec<Vec<f64>> = (0..free.len())
                .into_par_iter()
                .map(|j| {
                    let mut t = theta.clone();
                    t[j] += 1.0;
                    let (_, r) = self.problem.evaluate(&self.values(&free, &t))?;
                    let r = self.problem.stack(&r, &self.problem.roles[0]);
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
    Ok(rms(&p.stack(&r, &p.roles[2])))
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
                    param: p.clone(),
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
    let n_cal = p.stack(&before, &p.roles[0]).len();
    let held = |r: &[Vec<f64>]| p.stack(r, &p.roles[1]);
    let judge = |r: &[Vec<f64>]| rms(&p.stack(r, &p.roles[2]));
    let mut cur_held = rss(&held(&before));
    let mut cur_bic = bic(sel.cal_rss(&before), n_cal, 0);
    let select_before_db = rms(&held(&before));
    let (mut chosen, mut current, mut steps, mut last_round, mut rejected, mut alternatives) = (
        Vec::<usize>::new(),
        None::<Fit>,
        Vec::new(),
        Vec::new(),
        Vec::new(),
        Vec::new(),
    );
    while chosen.len() < o.max_effects && select_before_db > o.explained_floor_db {
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
            select_rms_db: rms(&held(&f.residuals)),
            bic_change: bic(sel.cal_rss(&f.residuals), n_cal, f.free.len()) - cur_bic,
        };
        last_round = fits.iter().map(score).collect();
        last_round.sort_by(|a, b| a.select_rms_db.total_cmp(&b.select_rms_db));
        let passing: Vec<usize> = (0..fits.len())
            .filter(|i| score(&fits[*i]).bic_change < -o.min_bic_drop)
            .collect();
        let best = passing
            .iter()
            .copied()
            .filter(|i| sel.implausible(&fits[*i].1).is_none())
            .min_by(|a, b| {
                rss(&held(&fits[*a].1.residuals)).total_cmp(&rss(&held(&fits[*b].1.residuals)))
            });
        // Fits that would have ranked first but need what the class cannot have.
        let best_rss = best.map_or(f64::INFINITY, |b| rss(&held(&fits[b].1.residuals)));
        rejected.extend(passing.iter().filter_map(|i| {
            let (e, f) = &fits[*i];
            (rss(&held(&f.residuals)) < best_rss).then_some(())?;
            Some(Rejected {
                effect: sel.library[*e].key.clone(),
                implausible: sel.implausible(f)?,
            })
        }));
        let Some(best) = best else {
            break;
        };
        let judge_cells = |f: &Fit| p.stack(&f.residuals, &p.roles[2]);
        let chosen_judge = judge_cells(&fits[best].1);
        let cells: Vec<Vec<usize>> = (0..chosen_judge.len()).map(|i| vec![i]).collect();
        let judge_before = judge(&before);
        for (i, (other, f)) in fits.iter().enumerate() {
            if i == best {
                continue;
            }
            let r = judge_cells(f);
            let (t, p_value) = crate::select::paired_excess(&r, &chosen_judge, &cells);
            if p_value > o.ambiguity_level
                && explained(
                    judge_before,
                    rms(&r),
                    o.explained_floor_db,
                    o.explained_fraction,
                )
            {
                alternatives.push(Alternative {
                    instead_of: sel.library[fits[best].0].key.clone(),
                    effect: sel.library[*other].key.clone(),
                    values: sel.fitted(f),
                    judge_rms_db: rms(&r),
                    chosen_judge_rms_db: rms(&chosen_judge),
                    t,
                    p_value,
                    implausible: sel.implausible(f),
                });
            }
        }
        let (e, fit) = fits.into_iter().nth(best).expect("an index into the fits");
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
        if shrink < o.min_select_shrink || change < o.min_effect_db {
            break;
        }
        steps.push(Step {
            effect: sel.library[e].key.clone(),
            description: sel.library[e].description.clone(),
            values: sel.fitted(&fit),
            fit_rms_db: rms(&p.stack(&fit.residuals, &p.roles[0])),
            select_rms_db: rms(&held_new),
            select_shrink: shrink,
            judge_rms_db: judge(&fit.residuals),
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
    let labels = |r: usize| -> Vec<String> {
        p.roles[r]
            .iter()
            .map(|i| p.pieces[*i].label(logs))
            .collect()
    };
    Ok(VibrationGap {
        split: "each log in thirds of its time, in turn fit, select and judge, turning by one \
                from log to log; the judge thirds are used neither to fit nor to choose"
            .into(),
        fit: labels(0),
        select: labels(1),
        judge: labels(2),
        first_judge_piece: p.roles[2].first().copied().unwrap_or(0),
        judge_before_db: judge(&before),
        judge_after_db: judge(&after),
        before_by_band: by_band(p, &before),
        before_by_axis: by_axis(p, &before),
        before_by_kind: by_kind(p, &before, f_tp),
        before_by_piece: by_piece(p, &before),
        before_in_time: in_time(p, &p.simulate(&[])?)?,
        after_by_band: by_band(p, &after),
        whiteness_after: whiteness(p, &after),
        bands: p.bands.clone(),
        channels: p.channels.clone(),
        tooth_passing_hz: f_tp,
        measured: p.measured.clone(),
        model_before: before_levels,
        model_after: after_levels,
        fit_before_db: rms(&p.stack(&before, &p.roles[0])),
        select_before_db,
        steps,
        rejected,
        alternatives,
        last_round,
        simulations: p.simulations.load(std::sync::atomic::Ordering::Relaxed),
    })
}

/// Most (window, axis, band) cells listed by the time localisation.
const TIME_PEAKS: usize = 5;

/// The band levels of windows of [`WINDOW_S`] along each measured log against the model's
/// log (`model`, one per measured log), and the cells where the residual's magnitude peaks
/// (only cells whose measured or model level stands above the instrument's noise).
fn in_time(p: &Problem, model: &[Log]) -> Result<Vec<TimePeak>, GapError> {
    let mut cells = Vec::new();
    for (log, sim) in p.logs.iter().zip(model) {
        let fs = log.sample_rate_hz;
        let n = ((WINDOW_S * fs) as usize).max(crate::spectrum::SEGMENT);
        for (c, name) in p.channels.iter().enumerate() {
            let find = |l: &Log| {
                l.channels
                    .iter()
                    .find(|(k, _)| k == name)
                    .map(|(_, x)| x.clone())
            };
            let (Some(x), Some(y)) = (find(log), find(sim)) else {
                continue;
            };
            for (w, (a, b)) in x.chunks_exact(n).zip(y.chunks_exact(n)).enumerate() {
                let (Some(la), Some(lb)) = (
                    band_levels(a, fs, &p.bands),
                    band_levels(b, sim.sample_rate_hz, &p.bands),
                ) else {
                    continue;
                };
                for (k, band) in p.bands.iter().enumerate() {
                    let noise = p.noise[k];
                    if la[k].max(lb[k]) < ABOVE_NOISE * noise {
                        continue;
                    }
                    let meas = (la[k] * la[k] + TINY * TINY).sqrt();
                    let modl = (lb[k] * lb[k] + noise * noise + TINY * TINY).sqrt();
                    cells.push(TimePeak {
                        log: log.name.clone(),
                        from_s: (w * n) as f64 / fs,
                        to_s: ((w + 1) * n) as f64 / fs,
                        axis: p.channels[c].clone(),
                        band: band_name(band),
                        residual_db: 20.0 * (meas / modl).log10(),
                    });
                }
            }
        }
    }
    cells.sort_by(|a, b| b.residual_db.abs().total_cmp(&a.residual_db.abs()));
    cells.truncate(TIME_PEAKS);
    Ok(cells)
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
