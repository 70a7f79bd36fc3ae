//! `vmt chatter detect`: chatter detection on an accelerometer log.
//!
//! Inputs:
//! - a CSV file with a header holding `time_s` (strictly increasing, uniformly sampled to
//!   within 1 %, at any offset) and one or more of `ax`, `ay`, `az`; other columns are ignored.
//!   An instrument's export is read as exported: `--columns` maps our names onto its headers,
//!   `--units` (or a unit written in a header) gives its units, s or ms, m/s² or g
//!   ([`crate::import`]);
//! - a run of ours (`run.mcap`): the `/accelerometer` stream (fields `time_s`, `ax`, `ay`, `az`,
//!   m/s²) and the spindle speed, teeth and tool-point modes from the ground truth
//!   (`milling.spindle_rpm`, `milling.teeth`, `milling.modes`, or at its top level).
//!
//! Detectors: `vmt_chatter::detect::kim` (band-pass RMS against a limit) and
//! `vmt_chatter::detect::spectral` (the share of the strongest line off the cut's forced comb).
//! `--detector both` runs what can run and says why the other cannot.

use crate::error::CliError;
use crate::import::{Import, ImportArgs};
use clap::{Args, ValueEnum};
use serde_json::Value;
use std::io::Write;
use std::path::{Path, PathBuf};
use vmt_chatter::detect::DetectError;
use vmt_chatter::detect::forced::AliasBand;
use vmt_chatter::detect::kim::{self, KimResult, KimSettings, weakest_mode};
use vmt_chatter::detect::spectral::{self, SpectralResult, SpectralSettings, TeethCheck};
use vmt_logs::csv_import::ACCELEROMETER_COLUMNS;
use vmt_logs::input::{self, Input};
use vmt_model::cutting::Mode;

/// The largest acceleration accepted from a CSV log, m/s² (10⁶, about 100 000 g: beyond the
/// range of shock accelerometers, so a value above it is a unit or data error).
const MAX_ACCELERATION_M_S2: f64 = 1e6;

/// Which detector to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Which {
    /// Kim, Song & Koh: band-pass, 50 ms block RMS against --limit.
    Kim,
    /// Share of the spectrum in the strongest line off the cut's forced comb.
    Better,
    /// Both where they can run.
    Both,
}

/// Arguments of `vmt chatter detect`.
#[derive(Args, Debug)]
pub struct DetectArgs {
    /// The log: run.mcap (its `accelerometer` stream) or a CSV file with header
    /// time_s,ax,ay,az (s; m/s²; at least one of ax, ay, az; time strictly increasing and
    /// uniformly sampled), or an instrument's export with --columns and --units.
    pub log: PathBuf,
    /// Detector(s) to run.
    #[arg(long, value_enum, default_value = "both")]
    pub detector: Which,
    /// Spindle speed, rev/min, given together with --teeth (default: the run's ground truth).
    /// Needed by the `better` detector for a CSV log, which carries no spindle speed.
    #[arg(long, requires = "teeth")]
    pub spindle_rpm: Option<f64>,
    /// Number of teeth of the cutter, given together with --spindle-rpm (default: the run's
    /// ground truth).
    #[arg(long, requires = "spindle_rpm")]
    pub teeth: Option<u32>,
    /// How far above the sample rate forced lines reach the log, in sample rates: 1 (default)
    /// masks the lines folded once (a sensor whose anti-alias filter is about 0.45 of its
    /// rate), 0.5 none (an ideal filter), 2 or more for a sensor with a weak filter.
    #[arg(long, default_value_t = 1.0)]
    pub alias_band: f64,
    /// Kim's RMS limit of the band-passed acceleration, m/s² (default: 3 × the largest block
    /// RMS over the first 0.2 s of the log, which assumes the log starts with a stable cut).
    #[arg(long)]
    pub limit: Option<f64>,
    /// Kim's pass band, Hz, as LOW,HIGH (stop edges half its width outside it); default: from
    /// --mode-hz, else from the run's tool-point modes, else the paper's 6000,7000.
    #[arg(long, value_delimiter = ',')]
    pub band: Option<Vec<f64>>,
    /// A tool-point mode, Hz, whose chatter band Kim's detector watches (0.9 to 1.2 times it).
    #[arg(long, conflicts_with = "band")]
    pub mode_hz: Option<f64>,
    /// Write the per-window figures of the detectors to this CSV file.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// A CSV export's columns and units.
    #[command(flatten)]
    pub import: ImportArgs,
}

impl DetectArgs {
    /// `vmt chatter detect LOG` with every option at its default.
    pub fn defaults(log: PathBuf) -> Self {
        Self {
            log,
            detector: Which::Both,
            spindle_rpm: None,
            teeth: None,
            alias_band: 1.0,
            limit: None,
            band: None,
            mode_hz: None,
            csv: None,
            import: ImportArgs::default(),
        }
    }
}

/// An accelerometer log.
#[derive(Debug, Clone, PartialEq)]
pub struct Log {
    /// Time of the first sample on the log's own clock (a run's: from the start of its job), s.
    /// The detectors count from it; their times are reported on the log's clock.
    pub start_s: f64,
    /// Sample rate, Hz (from the mean sample interval).
    pub sample_rate_hz: f64,
    /// Channel names and samples, m/s².
    pub channels: Vec<(String, Vec<f64>)>,
    /// Spindle speed (rev/min) and teeth from the run's ground truth, when present.
    pub spindle_rpm: Option<f64>,
    /// Teeth from the ground truth.
    pub teeth: Option<u32>,
    /// Axial depth of cut (mm) from the ground truth.
    pub axial_depth_mm: Option<f64>,
    /// The tool-point modes (X, then Y) from the ground truth.
    pub modes: Vec<Mode>,
    /// For a CSV: which of its columns were read, in which units.
    pub columns: Option<String>,
}

const AXES: [&str; 3] = ["ax", "ay", "az"];

const CSV_FORMAT: &str = "a header with time_s (s) and one or more of ax, ay, az (m/s²), then one row of numbers per sample (an export's own headers and units through --columns and --units)";

/// Reads an MCAP run or a CSV log (`import`: the CSV's columns and units).
pub fn read(path: &Path, import: &Import) -> Result<Log, CliError> {
    let file = path.display().to_string();
    match input::open(path, &file)? {
        Input::Mcap => {
            if import.given() {
                return Err(CliError::Argument(format!(
                    "{file} is a run of ours (MCAP), whose columns and units are its own: \
                     --columns and --units apply to CSV exports"
                )));
            }
            read_mcap(path, &file)
        }
        Input::Other(bytes) => read_csv(&bytes, &file, import),
    }
}

fn read_csv(bytes: &[u8], file: &str, import: &Import) -> Result<Log, CliError> {
    let mut r = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(bytes);
    let header = r
        .headers()
        .map_err(|e| {
            CliError::input(
                file,
                Some(1),
                format!("unreadable header: {e}; expected {CSV_FORMAT}"),
            )
        })?
        .clone();
    crate::traces::unique_columns(&header, file)?;
    let cols = import.resolve(
        &header,
        &ACCELEROMETER_COLUMNS,
        "an accelerometer log",
        file,
    )?;
    let time = cols.get("time_s").map_or(0, |c| c.index);
    let time_factor = cols.factor("time_s");
    let axes: Vec<(&str, usize, f64)> = AXES
        .iter()
        .filter_map(|a| cols.get(a).map(|c| (*a, c.index, cols.factor(a))))
        .collect();
    if axes.is_empty() {
        return Err(CliError::input(
            file,
            Some(1),
            format!(
                "no `ax`, `ay` or `az` column (found: {}); expected {CSV_FORMAT}",
                header.iter().collect::<Vec<_>>().join(", ")
            ),
        ));
    }
    let mut times = Vec::new();
    let mut values = vec![Vec::new(); axes.len()];
    for rec in r.records() {
        let rec = rec.map_err(|e| {
            let line = crate::traces::record_line(bytes, e.position(), 0);
            CliError::input(
                file,
                Some(line).filter(|&l| l > 0),
                format!("unreadable row: {e}"),
            )
        })?;
        let line = Some(crate::traces::record_line(bytes, rec.position(), 0)).filter(|&l| l > 0);
        let num = |col: usize| -> Result<f64, CliError> {
            let cell = rec.get(col).unwrap_or("");
            cell.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    CliError::input(
                        file,
                        line,
                        format!(
                            "column `{}`: `{cell}` is not a finite number",
                            header[col].trim()
                        ),
                    )
                })
        };
        let t = num(time)? * time_factor;
        if let Some(&prev) = times.last()
            && t <= prev
        {
            return Err(CliError::input(
                file,
                line,
                format!(
                    "column `{}`: {t} s does not increase (previous {prev} s); times must be strictly increasing",
                    header[time].trim()
                ),
            ));
        }
        times.push(t);
        for ((name, col, factor), v) in axes.iter().zip(&mut values) {
            let a = num(*col)? * factor;
            if a.abs() > MAX_ACCELERATION_M_S2 {
                return Err(CliError::input(
                    file,
                    line,
                    format!(
                        "column `{}`: {a:e} m/s² is not accepted; an acceleration within \
                         ±{MAX_ACCELERATION_M_S2:e} m/s² (check the unit: --units {name}=g or m/s^2)",
                        header[*col].trim()
                    ),
                ));
            }
            v.push(a);
        }
    }
    let channels = axes
        .iter()
        .map(|(n, _, _)| n.to_string())
        .zip(values)
        .collect();
    let mut log = finish(file, &times, channels, None)?;
    log.columns = Some(crate::import::echo(&cols));
    Ok(log)
}

fn read_mcap(path: &Path, file: &str) -> Result<Log, CliError> {
    let bad = |m: String| CliError::input(file, None, m);
    let mut truth: Option<Value> = None;
    let mut times = Vec::new();
    let mut values: Vec<Vec<f64>> = vec![Vec::new(); AXES.len()];
    for message in input::messages(path, file)? {
        let m = message?;
        match m.channel.topic.as_str() {
            "/ground_truth" => truth = serde_json::from_slice(&m.data).ok(),
            "/accelerometer" => {
                let v: Value = serde_json::from_slice(&m.data)
                    .map_err(|e| bad(format!("/accelerometer: a message that is not JSON: {e}")))?;
                let num = |k: &str| {
                    v[k].as_f64().ok_or_else(|| {
                        bad(format!("/accelerometer: a message without a number `{k}`"))
                    })
                };
                times.push(num("time_s")?);
                for (axis, vals) in AXES.iter().zip(&mut values) {
                    vals.push(num(axis)?);
                }
            }
            _ => {}
        }
    }
    if times.is_empty() {
        return Err(bad(
            "no /accelerometer topic: not a milling run (a run with an accelerometer stream is needed)".into(),
        ));
    }
    if times.windows(2).any(|w| w[1] <= w[0]) {
        return Err(bad("/accelerometer: times that do not increase".into()));
    }
    let channels = AXES.iter().map(|a| a.to_string()).zip(values).collect();
    finish(file, &times, channels, truth.as_ref())
}

/// `x` to 7 significant digits, without the binary noise of a difference (0.00505, not
/// 0.005049999999999999).
fn short(x: f64) -> String {
    format!("{x:.6e}")
        .parse::<f64>()
        .map_or_else(|_| x.to_string(), |v| v.to_string())
}

/// Sample rate from the mean interval; refuses irregular sampling (an interval off the mean by
/// more than 1 %), which the spectra and filters assume away.
fn finish(
    file: &str,
    times: &[f64],
    channels: Vec<(String, Vec<f64>)>,
    truth: Option<&Value>,
) -> Result<Log, CliError> {
    if times.len() < 2 {
        return Err(CliError::input(
            file,
            None,
            format!("{} samples: at least two are needed", times.len()),
        ));
    }
    let dt = (times[times.len() - 1] - times[0]) / (times.len() - 1) as f64;
    if let Some(i) = times
        .windows(2)
        .position(|w| ((w[1] - w[0]) - dt).abs() > 0.01 * dt)
    {
        return Err(CliError::input(
            file,
            None,
            format!(
                "sample {} (time {} s): interval {} s differs from the mean {} s by more than 1 %; uniform sampling is needed",
                i + 2,
                short(times[i + 1]),
                short(times[i + 1] - times[i]),
                short(dt)
            ),
        ));
    }
    // A job's run nests the cut under `milling`; a bare milling run has the keys at the top.
    let milling = truth.map(|t| {
        if t["milling"].is_object() {
            &t["milling"]
        } else {
            t
        }
    });
    Ok(Log {
        start_s: times[0],
        sample_rate_hz: 1.0 / dt,
        channels,
        spindle_rpm: milling.and_then(|m| m["spindle_rpm"].as_f64()),
        teeth: milling
            .and_then(|m| m["teeth"].as_u64())
            .and_then(|t| u32::try_from(t).ok()),
        axial_depth_mm: milling.and_then(|m| m["axial_depth_mm"].as_f64()),
        modes: milling.map_or_else(Vec::new, truth_modes),
        columns: None,
    })
}

/// The tool-point modes of a milling truth (`modes.x`, `modes.y`: frequency, damping ratio,
/// stiffness).
fn truth_modes(m: &Value) -> Vec<Mode> {
    ["x", "y"]
        .iter()
        .filter_map(|d| m["modes"][d].as_array())
        .flatten()
        .filter_map(|v| {
            Some(Mode {
                natural_frequency_hz: v["frequency_hz"].as_f64()?,
                damping_ratio: v["damping_ratio"].as_f64()?,
                stiffness: v["stiffness_n_per_m"].as_f64()?,
            })
        })
        .collect()
}

/// Where Kim's band came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BandSource {
    /// `--band`.
    Given,
    /// `--mode-hz`.
    Mode,
    /// The weakest tool-point mode of the run's truth.
    RunMode,
    /// The paper's 6–7 kHz.
    Paper,
}

impl BandSource {
    fn describe(self) -> &'static str {
        match self {
            BandSource::Given => "from --band",
            BandSource::Mode => "from --mode-hz",
            BandSource::RunMode => "from the run's weakest tool-point mode",
            BandSource::Paper => "the paper's",
        }
    }
}

/// What the detectors found, and what could not run and why.
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    /// Kim's detector, its settings (band, limit) and where the band came from.
    pub kim: Option<(KimResult, KimSettings, BandSource)>,
    /// Why Kim's detector did not run (with `--detector both`).
    pub kim_skipped: Option<String>,
    /// The spectral detector, and where its spindle speed and teeth came from.
    pub spectral: Option<(SpectralResult, &'static str)>,
    /// Why the spectral detector did not run (with `--detector both`).
    pub spectral_skipped: Option<String>,
}

/// Why the `better` detector cannot run on a log without spindle speed and teeth.
const NO_TOOTH_PASSING: &str = "the log gives no spindle speed and teeth: the `better` detector \
     needs --spindle-rpm and --teeth (the forced comb is not guessed from the spectrum, whose \
     strongest peak may be the chatter itself)";

/// Spindle speeds accepted by --spindle-rpm.
pub const SPINDLE_RPM: (f64, f64) = (1.0, 200_000.0);
/// Teeth accepted by --teeth.
pub const TEETH: (usize, usize) = (1, 100);

/// Checks the options in the units typed.
pub fn check_args(args: &DetectArgs) -> Result<(), CliError> {
    if let Some(n) = args.spindle_rpm {
        crate::error::check_range(
            "--spindle-rpm",
            n,
            SPINDLE_RPM,
            "rpm",
            "a spindle speed, rev/min",
        )?;
    }
    if let Some(z) = args.teeth {
        crate::error::check_count("--teeth", z as usize, TEETH, "the cutter's teeth")?;
    }
    if let Some(b) = &args.band {
        let ok =
            matches!(b[..], [lo, hi] if lo.is_finite() && lo > 0.0 && lo < hi && hi.is_finite());
        if !ok {
            return Err(CliError::option(
                "--band",
                b.iter().map(f64::to_string).collect::<Vec<_>>().join(","),
                "LOW,HIGH in Hz with 0 < LOW < HIGH is accepted",
            ));
        }
    }
    if let Some(f) = args.mode_hz
        && !(f.is_finite() && f > 0.0)
    {
        return Err(CliError::option(
            "--mode-hz",
            f,
            "a natural frequency > 0 Hz",
        ));
    }
    crate::error::check_range(
        "--alias-band",
        args.alias_band,
        (0.5, 10.0),
        "sample rates",
        "0.5 (no alias) to 10",
    )?;
    if let Some(l) = args.limit
        && !(l.is_finite() && l > 0.0)
    {
        return Err(CliError::option("--limit", l, "must be > 0 m/s²"));
    }
    Ok(())
}

/// Kim's settings for `log` (limit 1, set later) and where the band came from.
fn kim_band(log: &Log, args: &DetectArgs) -> (KimSettings, BandSource) {
    if let Some(&[lo, hi]) = args.band.as_deref() {
        let s = KimSettings {
            band_hz: (lo, hi),
            ..KimSettings::with_limit(1.0)
        };
        return (s, BandSource::Given);
    }
    if let Some(f) = args.mode_hz {
        return (KimSettings::for_mode(f, 1.0), BandSource::Mode);
    }
    match weakest_mode(&log.modes) {
        Some(f) => (KimSettings::for_mode(f, 1.0), BandSource::RunMode),
        None => (KimSettings::with_limit(1.0), BandSource::Paper),
    }
}

/// Runs the chosen detectors on `log` (read from `file`): with `--detector both`, those that
/// can run; an error when the one asked for (or neither of both) cannot.
pub fn detect(log: &Log, file: &str, args: &DetectArgs) -> Result<Report, CliError> {
    let fs = log.sample_rate_hz;
    let slices: Vec<&[f64]> = log.channels.iter().map(|(_, v)| v.as_slice()).collect();
    let model = |e: DetectError| CliError::input(file, None, e.to_string());
    let mut report = Report {
        kim: None,
        kim_skipped: None,
        spectral: None,
        spectral_skipped: None,
    };
    if args.detector != Which::Better {
        let (mut s, source) = kim_band(log, args);
        match s.fits(fs) {
            Ok(()) => {
                s.limit = match args.limit {
                    Some(l) => l,
                    None => default_limit(&slices, fs, &s).map_err(model)?,
                };
                report.kim = Some((kim::detect(&slices, fs, &s).map_err(model)?, s, source));
            }
            Err(e) => {
                let why = format!(
                    "{e} ({} band; give --band or --mode-hz for a band below it)",
                    source.describe()
                );
                if args.detector == Which::Kim {
                    return Err(CliError::input(file, None, why));
                }
                report.kim_skipped = Some(why);
            }
        }
    }
    if args.detector != Which::Kim {
        let rpm = args.spindle_rpm.or(log.spindle_rpm);
        let teeth = args.teeth.or(log.teeth);
        // The comb is not estimated from the spectrum: on a chattering cut the strongest peak
        // is the chatter itself (929 Hz on scenarios/milling_slot.toml).
        let outcome = match (rpm, teeth) {
            (Some(n), Some(z)) => {
                let source = if args.spindle_rpm.is_some() {
                    "from --spindle-rpm, --teeth"
                } else {
                    "from the run"
                };
                let s = SpectralSettings {
                    alias_band: AliasBand {
                        sample_rates: args.alias_band,
                    },
                    ..SpectralSettings::new(n, z)
                };
                spectral::detect(&slices, fs, &s)
                    .map(|r| (r, source))
                    .map_err(|e| e.to_string())
            }
            _ => Err(NO_TOOTH_PASSING.to_string()),
        };
        match outcome {
            Ok(r) => report.spectral = Some(r),
            Err(why) if args.detector == Which::Both => report.spectral_skipped = Some(why),
            Err(why) => return Err(CliError::input(file, None, why)),
        }
    }
    if let (None, None, Some(k), Some(b)) = (
        &report.kim,
        &report.spectral,
        &report.kim_skipped,
        &report.spectral_skipped,
    ) {
        return Err(CliError::input(
            file,
            None,
            format!("neither detector can run on this log: kim: {k}; better: {b}"),
        ));
    }
    Ok(report)
}

/// 3 × the largest block RMS within the first 0.2 s.
fn default_limit(slices: &[&[f64]], fs: f64, s: &KimSettings) -> Result<f64, DetectError> {
    let probe = kim::detect(
        slices,
        fs,
        &KimSettings {
            limit: f64::MAX,
            ..*s
        },
    )?;
    let start = probe.windows.iter().take_while(|w| w.end_s <= 0.2 + 1e-9);
    let rms = start.map(|w| w.rms).fold(0.0, f64::max);
    Ok(if rms > 0.0 {
        3.0 * rms
    } else {
        f64::MIN_POSITIVE
    })
}

/// Forced lines listed in the text report, strongest first.
const LINES_LISTED: usize = 8;

/// The report as text.
pub fn text(log: &Log, r: &Report) -> String {
    let n = log.channels.first().map_or(0, |c| c.1.len());
    let names: Vec<&str> = log.channels.iter().map(|c| c.0.as_str()).collect();
    let mut out = format!(
        "{n} samples at {:.1} Hz ({:.3} s from {:.3} s), channels {}\n",
        log.sample_rate_hz,
        n as f64 / log.sample_rate_hz,
        log.start_s,
        names.join(", ")
    );
    if let Some(c) = &log.columns {
        out += &format!("{c}\n");
    }
    // On the log's clock, where a viewer of the same file finds the cut.
    let when = |t: Option<f64>| {
        t.map_or("no chatter".to_string(), |t| {
            format!("CHATTER at {:.3} s", log.start_s + t)
        })
    };
    if let Some((k, s, source)) = &r.kim {
        let peak = k.windows.iter().map(|w| w.rms).fold(0.0, f64::max);
        let feed = k
            .windows
            .iter()
            .map(|w| w.feed_override)
            .fold(1.0, f64::min);
        out += &format!(
            "kim:      {} (band {:.0}–{:.0} Hz {}, limit {:.4} m/s², largest block RMS {peak:.4} m/s², lowest feed override {feed:.3})\n",
            when(k.verdict.detection_time_s),
            s.band_hz.0,
            s.band_hz.1,
            source.describe(),
            s.limit
        );
    }
    if let Some(why) = &r.kim_skipped {
        out += &format!("kim:      not run: {why}\n");
    }
    if let Some((s, source)) = &r.spectral {
        out += &spectral_text(log, s, source, &when);
    }
    if let Some(why) = &r.spectral_skipped {
        out += &format!("better:   not run: {why}\n");
    }
    out
}

/// The spectral detector's lines of the text report: its verdict, the forced lines it saw, the
/// teeth the comb supports, a line it could not tell from the comb.
fn spectral_text(
    log: &Log,
    s: &SpectralResult,
    source: &str,
    when: &dyn Fn(Option<f64>) -> String,
) -> String {
    let fs = log.sample_rate_hz;
    let freq = s
        .verdict
        .chatter_frequency_hz
        .map(|f| format!(", chatter frequency {f:.1} Hz as logged"))
        .unwrap_or_default();
    let peak = s.frames.iter().map(|f| f.share).fold(0.0, f64::max);
    let mut out = format!(
        "better:   {}{freq} (spindle {:.2} Hz, tooth passing {:.2} Hz {source}; frame {} samples, {:.0} % of the spectrum on forced lines; largest share {peak:.3})\n",
        when(s.verdict.detection_time_s),
        s.spindle_hz,
        s.tooth_passing_hz,
        s.frame_len,
        100.0 * s.masked_share
    );
    if s.seen.is_empty() {
        out += "          forced lines seen: none 10 dB above the noise\n";
    } else {
        let lines: Vec<String> = s
            .seen
            .iter()
            .take(LINES_LISTED)
            .map(|l| {
                let kind = if l.line.tooth_passing {
                    "tooth passing"
                } else {
                    "spindle rotation"
                };
                let at = if l.line.folded(fs) {
                    format!(" seen at {:.1} Hz", l.line.alias_hz)
                } else {
                    String::new()
                };
                format!(
                    "{}×f_r {:.1} Hz{at} ({kind}, {:+.0} dB)",
                    l.line.order, l.line.frequency_hz, l.level_db
                )
            })
            .collect();
        let more = s.seen.len().saturating_sub(LINES_LISTED);
        let more = if more > 0 {
            format!(" and {more} more")
        } else {
            String::new()
        };
        out += &format!(
            "          forced lines seen (never chatter): {}{more}\n",
            lines.join(", ")
        );
    }
    match s.teeth_check {
        TeethCheck::Mismatch {
            stated,
            stated_contrast_db,
            supported,
            contrast_db,
        } => {
            out += &format!(
                "          WARNING: the comb does not fit {stated} teeth: it supports {supported} (its multiples of f_r stand {contrast_db:.0} dB above the other orders, those of {stated} {stated_contrast_db:.0} dB); check --teeth\n"
            );
        }
        TeethCheck::Undecided => {
            out += "          teeth not checked: every spindle order about as strong (run-out or unbalance dominates the comb)\n";
        }
        TeethCheck::NotSeen | TeethCheck::Consistent { .. } => {}
    }
    if let Some(h) = &s.hidden {
        let kind = if h.line.tooth_passing {
            "a tooth-passing harmonic"
        } else {
            "a spindle-rotation harmonic"
        };
        out += &format!(
            "          cannot tell: a line grew ×{:.0} by {:.3} s on {}×f_r ({:.1} Hz, {kind}, seen at {:.1} Hz): chatter there is indistinguishable from the forced line at this rate and speed\n",
            h.growth,
            log.start_s + h.end_s,
            h.line.order,
            h.line.frequency_hz,
            h.line.alias_hz
        );
    }
    out
}

/// Writes the per-window figures of `log`: one row per Kim block and per spectral frame, the
/// window ends on the log's clock.
pub fn write_csv(log: &Log, r: &Report, w: &mut impl Write) -> std::io::Result<()> {
    writeln!(
        w,
        "detector,window_end_s,rms_m_s2,feed_override,share,free_ratio,peak_hz,chatter"
    )?;
    if let Some((k, _, _)) = &r.kim {
        for b in &k.windows {
            writeln!(
                w,
                "kim,{},{},{},,,,{}",
                log.start_s + b.end_s,
                b.rms,
                b.feed_override,
                b.chatter
            )?;
        }
    }
    if let Some((s, _)) = &r.spectral {
        for f in &s.frames {
            writeln!(
                w,
                "better,{},,,{},{},{},{}",
                log.start_s + f.end_s,
                f.share,
                f.free_ratio,
                f.peak_hz,
                f.chatter
            )?;
        }
    }
    Ok(())
}

/// `vmt chatter detect RUN --csv DIR/chatter.csv` of a milling run, whose report also goes to
/// `DIR/report.txt`: the report and the files written.
pub fn diagnose_run(mcap: &Path, dir: &Path) -> Result<(String, Vec<PathBuf>), CliError> {
    let args = DetectArgs::defaults(mcap.to_path_buf());
    let log = read(mcap, &Import::default())?;
    let report = detect(&log, &mcap.display().to_string(), &args)?;
    let text = text(&log, &report);
    std::fs::create_dir_all(dir).map_err(|e| CliError::output(dir, e))?;
    let txt = dir.join("report.txt");
    std::fs::write(&txt, &text).map_err(|e| CliError::output(&txt, e))?;
    let csv = dir.join("chatter.csv");
    let f = std::fs::File::create(&csv).map_err(|e| CliError::output(&csv, e))?;
    let mut w = std::io::BufWriter::new(f);
    write_csv(&log, &report, &mut w)
        .and_then(|_| w.flush())
        .map_err(|e| CliError::output(&csv, e))?;
    Ok((text, vec![txt, csv]))
}

/// `vmt chatter detect`.
pub fn command(args: &DetectArgs) -> Result<(), CliError> {
    check_args(args)?;
    let log = read(&args.log, &args.import.parse()?)?;
    let report = detect(&log, &args.log.display().to_string(), args)?;
    crate::out!("{}", text(&log, &report))?;
    if let Some(path) = &args.csv {
        let f = std::fs::File::create(path).map_err(|e| CliError::output(path, e))?;
        let mut w = std::io::BufWriter::new(f);
        write_csv(&log, &report, &mut w)
            .and_then(|_| w.flush())
            .map_err(|e| CliError::output(path, e))?;
        crate::outln!("wrote {}", path.display())?;
    }
    Ok(())
}
