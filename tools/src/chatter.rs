//! `vmt chatter detect`: chatter detection on an accelerometer log.
//!
//! Inputs:
//! - a CSV file with a header holding `time_s` (s, strictly increasing, uniformly sampled to
//!   within 1 %) and one or more of `ax`, `ay`, `az` (acceleration, m/s²); other columns are
//!   ignored;
//! - a run of ours (`run.mcap`): the `/accelerometer` stream (fields `time_s`, `ax`, `ay`, `az`,
//!   m/s²) and the spindle speed and teeth from the ground truth (`milling.spindle_rpm`,
//!   `milling.teeth`, or `spindle_rpm`, `teeth` at its top level).
//!
//! Detectors: `vmt_chatter::detect::kim` (band-pass RMS against a limit) and
//! `vmt_chatter::detect::spectral` (non-harmonic spectral peak share).

use crate::error::CliError;
use clap::{Args, ValueEnum};
use serde_json::Value;
use std::io::Write;
use std::path::{Path, PathBuf};
use vmt_chatter::detect::kim::{self, KimResult, KimSettings};
use vmt_chatter::detect::spectral::{self, SpectralResult, SpectralSettings};
use vmt_logs::input::{self, Input};

/// The largest acceleration accepted from a CSV log, m/s² (10⁶, about 100 000 g: beyond the
/// range of shock accelerometers, so a value above it is a unit or data error).
const MAX_ACCELERATION_M_S2: f64 = 1e6;

/// Which detector to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Which {
    /// Kim, Song & Koh: band-pass (default 6–7 kHz), 50 ms block RMS against --limit.
    Kim,
    /// Share of the spectrum in the strongest peak that is not a tooth-passing harmonic.
    Better,
    /// Both.
    Both,
}

/// Arguments of `vmt chatter detect`.
#[derive(Args, Debug)]
pub struct DetectArgs {
    /// The log: run.mcap (its `accelerometer` stream) or a CSV file with header
    /// time_s,ax,ay,az (s; m/s²; at least one of ax, ay, az; time strictly increasing and
    /// uniformly sampled).
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
    /// Kim's RMS limit of the band-passed acceleration, m/s² (default: 3 × the largest block
    /// RMS over the first 0.2 s of the log, which assumes the log starts with a stable cut).
    #[arg(long)]
    pub limit: Option<f64>,
    /// Kim's pass band, Hz, as LOW,HIGH (stop edges 500 Hz outside it).
    #[arg(long, value_delimiter = ',', default_values_t = KIM_BAND_HZ)]
    pub band: Vec<f64>,
    /// Write the per-window figures of the detectors to this CSV file.
    #[arg(long)]
    pub csv: Option<PathBuf>,
}

/// Kim's pass band unless --band says otherwise, Hz (Kim, Song & Koh's 6–7 kHz).
pub const KIM_BAND_HZ: [f64; 2] = [6000.0, 7000.0];

impl DetectArgs {
    /// `vmt chatter detect LOG` with every option at its default.
    pub fn defaults(log: PathBuf) -> Self {
        Self {
            log,
            detector: Which::Both,
            spindle_rpm: None,
            teeth: None,
            limit: None,
            band: KIM_BAND_HZ.to_vec(),
            csv: None,
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
}

const AXES: [&str; 3] = ["ax", "ay", "az"];

const CSV_FORMAT: &str = "a header with time_s (s) and one or more of ax, ay, az (m/s²), then one row of numbers per sample";

/// Reads an MCAP run or a CSV log.
pub fn read(path: &Path) -> Result<Log, CliError> {
    let file = path.display().to_string();
    match input::open(path, &file)? {
        Input::Mcap => read_mcap(path, &file),
        Input::Other(bytes) => read_csv(&bytes, &file),
    }
}

fn read_csv(bytes: &[u8], file: &str) -> Result<Log, CliError> {
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
    let find = |n: &str| header.iter().position(|h| h == n);
    let found = || header.iter().collect::<Vec<_>>().join(",");
    let time = find("time_s").ok_or_else(|| {
        CliError::input(
            file,
            Some(1),
            format!(
                "no `time_s` column (found: {}); expected {CSV_FORMAT}",
                found()
            ),
        )
    })?;
    let axes: Vec<(&str, usize)> = AXES
        .iter()
        .filter_map(|a| find(a).map(|i| (*a, i)))
        .collect();
    if axes.is_empty() {
        return Err(CliError::input(
            file,
            Some(1),
            format!(
                "no `ax`, `ay` or `az` column (found: {}); expected {CSV_FORMAT}",
                found()
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
        let num = |col: usize, name: &str| -> Result<f64, CliError> {
            let cell = rec.get(col).unwrap_or("");
            cell.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    CliError::input(
                        file,
                        line,
                        format!("column `{name}`: `{cell}` is not a finite number"),
                    )
                })
        };
        let t = num(time, "time_s")?;
        if let Some(&prev) = times.last()
            && t <= prev
        {
            return Err(CliError::input(
                file,
                line,
                format!(
                    "column `time_s`: {t} does not increase (previous {prev}); times must be strictly increasing"
                ),
            ));
        }
        times.push(t);
        for ((name, col), v) in axes.iter().zip(&mut values) {
            let a = num(*col, name)?;
            if a.abs() > MAX_ACCELERATION_M_S2 {
                return Err(CliError::input(
                    file,
                    line,
                    format!(
                        "column `{name}`: {a:e} m/s² is not accepted; an acceleration within \
                         ±{MAX_ACCELERATION_M_S2:e} m/s² (check the unit: m/s², not g or mm/s²)"
                    ),
                ));
            }
            v.push(a);
        }
    }
    let channels = axes
        .iter()
        .map(|(n, _)| n.to_string())
        .zip(values)
        .collect();
    finish(file, &times, channels, None)
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
    })
}

/// What the detectors found.
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    /// Kim's detector, with the limit used.
    pub kim: Option<(KimResult, f64)>,
    /// The spectral detector, and where its tooth-passing frequency came from.
    pub spectral: Option<(SpectralResult, &'static str)>,
    /// Why the spectral detector was not run though asked for with Kim's (`--detector both`).
    pub spectral_skipped: Option<&'static str>,
}

/// Why the `better` detector cannot run on a log without spindle speed and teeth.
const NO_TOOTH_PASSING: &str = "the log gives no spindle speed and teeth: the `better` detector \
     needs --spindle-rpm and --teeth (its tooth-passing frequency is not guessed from the \
     spectrum, whose strongest peak may be the chatter itself)";

/// Spindle speeds accepted by --spindle-rpm.
pub const SPINDLE_RPM: (f64, f64) = (1.0, 200_000.0);
/// Teeth accepted by --teeth.
pub const TEETH: (usize, usize) = (1, 100);

/// Checks --spindle-rpm and --teeth (given together, clap makes sure) in the units typed.
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
    if let [lo, hi] = args.band[..]
        && !(lo.is_finite() && lo > 0.0 && lo < hi && hi.is_finite())
    {
        return Err(CliError::option(
            "--band",
            format!("{lo},{hi}"),
            "LOW,HIGH in Hz with 0 < LOW < HIGH is accepted",
        ));
    }
    if let Some(l) = args.limit
        && !(l.is_finite() && l > 0.0)
    {
        return Err(CliError::option("--limit", l, "must be > 0 m/s²"));
    }
    Ok(())
}

/// Runs the chosen detectors on `log` (read from `file`).
pub fn detect(log: &Log, file: &str, args: &DetectArgs) -> Result<Report, CliError> {
    let fs = log.sample_rate_hz;
    let slices: Vec<&[f64]> = log.channels.iter().map(|(_, v)| v.as_slice()).collect();
    let model = |e: vmt_chatter::detect::DetectError| CliError::input(file, None, e.to_string());
    let kim = if args.detector != Which::Better {
        let band = match args.band[..] {
            [lo, hi] => (lo, hi),
            _ => {
                return Err(CliError::Argument(
                    "--band LOW,HIGH: two frequencies in Hz".into(),
                ));
            }
        };
        let mut s = KimSettings {
            band_hz: band,
            ..KimSettings::with_limit(1.0)
        };
        s.limit = match args.limit {
            Some(l) => l,
            None => default_limit(&slices, fs, &s).map_err(model)?,
        };
        Some((kim::detect(&slices, fs, &s).map_err(model)?, s.limit))
    } else {
        None
    };
    let spectral = if args.detector != Which::Kim {
        let rpm = args.spindle_rpm.or(log.spindle_rpm);
        let teeth = args.teeth.or(log.teeth);
        // The tooth-passing frequency is not estimated from the spectrum: on a chattering cut
        // the strongest peak is the chatter itself (929 Hz on scenarios/milling_slot.toml).
        let (cut, source) = match (rpm, teeth) {
            (Some(n), Some(z)) => {
                let source = if args.spindle_rpm.is_some() {
                    "from --spindle-rpm, --teeth"
                } else {
                    "from the run"
                };
                ((n, z), source)
            }
            _ if args.detector == Which::Both => {
                // Kim's verdict stands on its own; say why the other is missing.
                return Ok(Report {
                    kim,
                    spectral: None,
                    spectral_skipped: Some(NO_TOOTH_PASSING),
                });
            }
            _ => {
                return Err(CliError::input(
                    file,
                    None,
                    format!("{NO_TOOTH_PASSING}, or run --detector kim"),
                ));
            }
        };
        let s = SpectralSettings::new(cut.0, cut.1);
        Some((spectral::detect(&slices, fs, &s).map_err(model)?, source))
    } else {
        None
    };
    Ok(Report {
        kim,
        spectral,
        spectral_skipped: None,
    })
}

/// 3 × the largest block RMS within the first 0.2 s.
fn default_limit(
    slices: &[&[f64]],
    fs: f64,
    s: &KimSettings,
) -> Result<f64, vmt_chatter::detect::DetectError> {
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
    // On the log's clock, where a viewer of the same file finds the cut.
    let when = |t: Option<f64>| {
        t.map_or("no chatter".to_string(), |t| {
            format!("CHATTER at {:.3} s", log.start_s + t)
        })
    };
    if let Some((k, limit)) = &r.kim {
        let peak = k.windows.iter().map(|w| w.rms).fold(0.0, f64::max);
        let feed = k
            .windows
            .iter()
            .map(|w| w.feed_override)
            .fold(1.0, f64::min);
        out += &format!(
            "kim:      {} (limit {limit:.4} m/s², largest block RMS {peak:.4} m/s², lowest feed override {feed:.3})\n",
            when(k.verdict.detection_time_s)
        );
    }
    if let Some((s, source)) = &r.spectral {
        let freq = s
            .verdict
            .chatter_frequency_hz
            .map(|f| format!(", chatter frequency {f:.1} Hz"))
            .unwrap_or_default();
        let peak = s.frames.iter().map(|f| f.share).fold(0.0, f64::max);
        out += &format!(
            "better:   {}{freq} (tooth passing {:.2} Hz {source}, frame {} samples, largest share {peak:.3})\n",
            when(s.verdict.detection_time_s),
            s.tooth_passing_hz,
            s.frame_len
        );
    }
    if let Some(why) = r.spectral_skipped {
        out += &format!("better:   not run: {why}\n");
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
    if let Some((k, _)) = &r.kim {
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
    let log = read(mcap)?;
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
    let log = read(&args.log)?;
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
