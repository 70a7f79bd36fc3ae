//! `vmt chatter bench` and `vmt chatter compensate`: the detectors on a labelled set of
//! simulated cuts, and chatter suppression in the loop beside Kim, Song & Koh's table.
//!
//! The cuts are straight half-immersion down-milling cuts of a two-mode tool (vmt-sim's standalone milling driver, 20 kHz
//! accelerometers). A run is labelled chatter when the simulator's ground truth has a chatter
//! interval still open at the end of the cut (a closing one is the tool's entry transient),
//! with its start as the onset.

use crate::error::CliError;
use serde_json::Value;
use std::fmt::Write as _;
use vmt_chatter::detect::eval::{LabelledRun, Scores, evaluate};
use vmt_chatter::detect::{Verdict, kim, spectral};
use vmt_chatter::filter::{ChebyshevBandPass, SosFilter};
use vmt_dataset::chatter::{self, FEED_PER_TOOTH_M as FEED_PER_TOOTH};
use vmt_model::cutting::{Mode, ToolDynamics};
use vmt_sim::milling::{
    AccelWindow, AccelerometerParams, Feed, MillingDrive, MillingRun, MillingSetup,
    SupervisorCommand, simulate_milling, simulate_milling_with,
};

/// Spindle speeds accepted, rpm: the simulation's memory grows with the tooth passes (1e9 rpm
/// aborts on allocation).
pub const SPINDLE_RPM: (f64, f64) = (100.0, 60_000.0);
const SPINDLE_WHY: &str =
    "the speeds of milling spindles; the simulation's record grows with the tooth passes";
/// Cut durations accepted by `vmt chatter compensate`, s: its three runs keep their records of
/// about 8 MB (6000 rpm) to 25 MB (60 000 rpm) per second of cut each.
pub const COMPENSATE_DURATION_S: (f64, f64) = (0.1, 20.0);
/// Seconds of cut accepted in all of `vmt chatter bench` (speeds x depths x duration): every
/// run's 20 kHz accelerometer record is kept, and each thread simulates at 8-25 MB per second.
pub const BENCH_TOTAL_S: f64 = 2000.0;

/// Checks --spindle-rpm, --depth-mm and --duration-s of `vmt chatter compensate` in the units
/// typed.
fn check_compensate(a: &CompensateArgs) -> Result<(), CliError> {
    use crate::error::{check_positive, check_range};
    check_range(
        "--spindle-rpm",
        a.spindle_rpm,
        SPINDLE_RPM,
        "rpm",
        SPINDLE_WHY,
    )?;
    check_positive(
        "--depth-mm",
        a.depth_mm,
        30.0,
        "mm",
        "the axial depth of cut, within the bench tool's 30 mm flutes",
    )?;
    check_range(
        "--duration-s",
        a.duration_s,
        COMPENSATE_DURATION_S,
        "s",
        "each of the three runs keeps 8-25 MB per second of cut",
    )?;
    Ok(())
}

/// Checks the grid and duration of `vmt chatter bench`.
fn check_bench(a: &BenchArgs) -> Result<(), CliError> {
    use crate::error::{check_count, check_range};
    check_count("--speeds", a.speeds, (1, 200), "speeds of the grid")?;
    check_count("--depths", a.depths, (1, 200), "depths per speed")?;
    check_range(
        "--duration-s",
        a.duration_s,
        (0.1, 10.0),
        "s",
        "seconds of cut per run; Kim's blocks are 50 ms",
    )?;
    // The better detector's tuning: a share of the frame's power, a power ratio and a
    // look-back within the cut.
    if let Some(s) = a.developed_share {
        check_range(
            "--developed-share",
            s,
            (0.0, 1.0),
            "(fraction)",
            "a share of the frame's power",
        )?;
    }
    if let Some(g) = a.growth {
        check_range(
            "--growth",
            g,
            (1.0, 1e6),
            "×",
            "a growth of the peak's power",
        )?;
    }
    if let Some(w) = a.growth_window_s {
        check_range(
            "--growth-window-s",
            w,
            (0.0, a.duration_s),
            "s",
            "a look-back within the cut's --duration-s",
        )?;
    }
    let total = (a.speeds * a.depths) as f64 * a.duration_s;
    if total > BENCH_TOTAL_S {
        return Err(CliError::Argument(format!(
            "--speeds {} x --depths {} x --duration-s {} = {total} s of cut: at most {BENCH_TOTAL_S} s \
             is accepted (every run's accelerometer record is kept in memory)",
            a.speeds, a.depths, a.duration_s
        )));
    }
    Ok(())
}

/// The bench's tool: the dataset's 12 mm four-flute end mill in its aluminium, at half
/// immersion, on a two-mode tool point whose upper mode (6.5 kHz) sits in Kim's 6–7 kHz band.
fn setup(depth_mm: f64, seed: u64) -> MillingSetup {
    let modes = vec![
        Mode::from_mass(0.0144, 2300.0, 0.02),
        Mode::from_mass(0.003, 6500.0, 0.015),
    ];
    MillingSetup {
        tool: chatter::end_mill(0.0, 0.0),
        coefficients: chatter::ALUMINIUM,
        dynamics: ToolDynamics::symmetric(modes),
        axial_mode: None,
        cut: chatter::half_immersion(depth_mm * 1e-3),
        feed_per_tooth: FEED_PER_TOOTH,
        accelerometer: AccelerometerParams::default(),
        step_s: chatter::STEP_S,
        seed,
    }
}

fn drive(rpm: f64, duration_s: f64) -> MillingDrive {
    MillingDrive {
        spindle_rpm: rpm,
        feed: Feed::PerTooth(FEED_PER_TOOTH),
        duration_s,
        supervisor_window_s: 0.025,
    }
}

fn sim_error(e: impl std::fmt::Display) -> CliError {
    CliError::Model(format!("milling: {e}"))
}

/// The onset of a chatter interval still open at the end, from the truth.
fn persistent_onset(truth: &Value) -> Option<f64> {
    let last = truth["chatter_intervals_s"].as_array()?.last()?;
    last[1].is_null().then(|| last[0].as_f64()).flatten()
}

/// One labelled run at `rpm` and `depth_mm`.
fn labelled(rpm: f64, depth_mm: f64, seed: u64, duration_s: f64) -> Result<LabelledRun, CliError> {
    let run =
        simulate_milling(&setup(depth_mm, seed), &drive(rpm, duration_s)).map_err(sim_error)?;
    let acc = run
        .streams
        .iter()
        .find(|s| s.name == "accelerometer")
        .ok_or_else(|| sim_error("no accelerometer stream"))?;
    Ok(LabelledRun {
        channels: acc
            .channels
            .iter()
            .take(2)
            .map(|c| c.values.clone())
            .collect(),
        sample_rate_hz: 20_000.0,
        spindle_rpm: rpm,
        teeth: 4,
        chatter_onset_s: persistent_onset(&run.ground_truth),
    })
}

/// `vmt chatter bench` arguments.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Spindle speeds, evenly spaced from 6000 to 24 000 rpm.
    #[arg(long, default_value_t = 20)]
    pub speeds: usize,
    /// Axial depths per speed, evenly spaced from 0.05 to 1 mm.
    #[arg(long, default_value_t = 10)]
    pub depths: usize,
    /// Length of each cut, s.
    #[arg(long, default_value_t = 0.4)]
    pub duration_s: f64,
    /// Also write one row per run (speed, depth, label, onset, the better detector's verdict
    /// and time) to this CSV file.
    #[arg(long)]
    pub csv: Option<std::path::PathBuf>,
    /// Seed of the first run (run i gets seed + i): another seed and grid make a calibration
    /// set apart from the evaluation set.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The better detector's developed-chatter share (default: the library's).
    #[arg(long)]
    pub developed_share: Option<f64>,
    /// The better detector's growth factor of the peak power (default: the library's).
    #[arg(long)]
    pub growth: Option<f64>,
    /// The better detector's look-back of the growth test, s (default: the library's).
    #[arg(long)]
    pub growth_window_s: Option<f64>,
}

impl BenchArgs {
    fn spectral(&self, r: &LabelledRun) -> spectral::SpectralSettings {
        let d = spectral::SpectralSettings::new(r.spindle_rpm, r.teeth);
        spectral::SpectralSettings {
            developed_share: self.developed_share.unwrap_or(d.developed_share),
            growth: self.growth.unwrap_or(d.growth),
            growth_window_s: self.growth_window_s.unwrap_or(d.growth_window_s),
            ..d
        }
    }
}

fn grid(a: &BenchArgs) -> Vec<(f64, f64)> {
    let step =
        |lo: f64, hi: f64, n: usize, i: usize| lo + (hi - lo) * i as f64 / (n.max(2) - 1) as f64;
    (0..a.speeds)
        .flat_map(|i| {
            (0..a.depths).map(move |j| {
                (
                    step(6000.0, 24000.0, a.speeds, i),
                    step(0.05, 1.0, a.depths, j),
                )
            })
        })
        .collect()
}

fn scores_line(out: &mut String, name: &str, s: &Scores) {
    let _ = writeln!(
        out,
        "| {name} | {:.1} % | {:.1} % | {:.1} % | {:.1} ms | {:.1} ms |",
        100.0 * s.accuracy,
        100.0 * s.false_positive_rate,
        100.0 * s.false_negative_rate,
        1e3 * s.median_latency_s,
        1e3 * s.p90_latency_s
    );
}

/// Kim's limit: three times the largest block RMS of stable calibration cuts (not in the set).
fn kim_limit(band: (f64, f64)) -> Result<f64, CliError> {
    let mut worst: f64 = 0.0;
    for (k, rpm) in [7000.0, 13000.0, 19000.0].into_iter().enumerate() {
        let run = labelled(rpm, 0.05, 10_000 + k as u64, 0.3)?;
        let settings = kim::KimSettings {
            band_hz: band,
            ..kim::KimSettings::with_limit(f64::MAX)
        };
        let r = kim::detect(&run.slices(), run.sample_rate_hz, &settings).map_err(sim_error)?;
        worst = r.windows.iter().map(|w| w.rms).fold(worst, f64::max);
    }
    Ok(3.0 * worst)
}

/// Runs `vmt chatter bench`.
pub fn bench(a: &BenchArgs) -> Result<(), CliError> {
    use rayon::prelude::*;
    check_bench(a)?;
    let runs: Vec<LabelledRun> = grid(a)
        .par_iter()
        .enumerate()
        .map(|(i, (rpm, d))| labelled(*rpm, *d, a.seed + i as u64, a.duration_s))
        .collect::<Result<_, _>>()?;
    let chatter = runs.iter().filter(|r| r.chatter_onset_s.is_some()).count();
    let verdicts = std::cell::RefCell::new(Vec::new());
    let better = evaluate(&runs, |r| {
        let v =
            spectral::detect(&r.slices(), r.sample_rate_hz, &a.spectral(r)).map(|x| x.verdict)?;
        verdicts.borrow_mut().push(v);
        Ok(v)
    })
    .map_err(sim_error)?;
    if let Some(path) = &a.csv {
        let mut text = String::from(
            "spindle_rpm,depth_mm,chatter,onset_s,better_chatter,better_time_s,better_frequency_hz\n",
        );
        for (((rpm, d), r), v) in grid(a).iter().zip(&runs).zip(verdicts.borrow().iter()) {
            let opt = |x: Option<f64>| x.map_or(String::new(), |x| x.to_string());
            let _ = writeln!(
                text,
                "{rpm},{d},{},{},{},{},{}",
                r.chatter_onset_s.is_some(),
                opt(r.chatter_onset_s),
                v.chatter,
                opt(v.detection_time_s),
                opt(v.chatter_frequency_hz)
            );
        }
        std::fs::write(path, text).map_err(|e| CliError::output(path, e))?;
    }
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Labelled set: {} simulated half-immersion cuts ({} chatter, {} stable), {} speeds 6000-24000 rpm x {} depths 0.05-1 mm, {} s each, 20 kHz accelerometers; labels from the simulator's truth.\n",
        runs.len(),
        chatter,
        runs.len() - chatter,
        a.speeds,
        a.depths,
        a.duration_s
    );
    let _ = writeln!(
        out,
        "| Detector | Accuracy | False positives | Missed | Median latency | p90 latency |\n|---|---|---|---|---|---|"
    );
    scores_line(&mut out, "better (spectral share, no band)", &better);
    for (name, band) in [
        ("Kim, paper band 6-7 kHz", (6000.0, 7000.0)),
        ("Kim, band at the 2.3 kHz mode", (1900.0, 2700.0)),
    ] {
        let limit = kim_limit(band)?;
        let settings = kim::KimSettings {
            band_hz: band,
            ..kim::KimSettings::with_limit(limit)
        };
        let s = evaluate(&runs, |r| {
            kim::detect(&r.slices(), r.sample_rate_hz, &settings).map(|x| x.verdict)
        })
        .map_err(sim_error)?;
        scores_line(&mut out, &format!("{name} (limit {limit:.2} m/s²)"), &s);
    }
    crate::out!("{out}")?;
    Ok(())
}

/// `vmt chatter compensate` arguments.
#[derive(clap::Args, Debug)]
pub struct CompensateArgs {
    /// Spindle speed, rpm (100 to 60 000).
    #[arg(long, default_value_t = 20000.0)]
    pub spindle_rpm: f64,
    /// Axial depth, mm (> 0, at most 30).
    #[arg(long, default_value_t = 0.3)]
    pub depth_mm: f64,
    /// Length of the cut, s.
    #[arg(long, default_value_t = 1.0)]
    pub duration_s: f64,
}

/// Kim's loop: the band-passed RMS of each 25 ms window against the limit; the override is
/// multiplied by limit / RMS while the RMS is above the limit (never raised again).
fn kim_supervisor(
    limit: f64,
    band: (f64, f64),
) -> Result<impl FnMut(&AccelWindow<'_>) -> SupervisorCommand, CliError> {
    let spec = kim::KimSettings {
        band_hz: band,
        ..kim::KimSettings::with_limit(limit)
    }
    .spec(20_000.0);
    let design = ChebyshevBandPass::design(spec).map_err(sim_error)?;
    let (mut fx, mut fy): (SosFilter, SosFilter) = (design.runner(), design.runner());
    Ok(move |w: &AccelWindow<'_>| {
        let e: f64 =
            w.ax.iter()
                .zip(w.ay)
                .map(|(x, y)| fx.step(*x).powi(2) + fy.step(*y).powi(2))
                .sum();
        let rms = (e / w.ax.len() as f64).sqrt();
        let o = if rms > limit {
            w.feed_override * limit / rms
        } else {
            w.feed_override
        };
        SupervisorCommand {
            feed_override: o,
            spindle_rpm: w.spindle_rpm,
        }
    })
}

/// The spindle-speed loop: the better detector on each window; on chatter at f_c, the tooth
/// passing frequency is set to f_c / k with k the whole number nearest to the current ratio,
/// towards the top of the nearest stable lobe (Smith & Tlusty), and the history starts afresh.
///
/// The detector sees the last 4096 samples (0.2 s at 20 kHz), longer than its growth look-back
/// (0.15 s), so chatter that grows slowly from the entry transient is judged on its growth, not
/// only on its level. Where the first move lands next to the boundary the vibration at the new
/// speed is flagged in turn and the next move starts from its frequency: the iteration of Smith
/// & Tlusty (at 20 000 rpm, 0.3 mm: 17 169 then 16 224 rpm, the lobe top).
fn speed_supervisor(teeth: u32) -> impl FnMut(&AccelWindow<'_>) -> SupervisorCommand {
    let mut history: Vec<Vec<f64>> = vec![Vec::new(), Vec::new()];
    move |w: &AccelWindow<'_>| {
        history[0].extend_from_slice(w.ax);
        history[1].extend_from_slice(w.ay);
        let keep = |h: &mut Vec<f64>| {
            let n = h.len().saturating_sub(4096);
            h.drain(..n);
        };
        history.iter_mut().for_each(keep);
        let f_tp = vmt_chatter::detect::forced::tooth_passing_hz(w.spindle_rpm, teeth);
        let s = spectral::SpectralSettings {
            persistence: 1,
            ..spectral::SpectralSettings::new(w.spindle_rpm, teeth)
        };
        let same = SupervisorCommand {
            feed_override: w.feed_override,
            spindle_rpm: w.spindle_rpm,
        };
        let Ok(r) = spectral::detect(&[&history[0], &history[1]], w.sample_rate_hz, &s) else {
            return same;
        };
        match r.verdict {
            Verdict {
                chatter: true,
                chatter_frequency_hz: Some(fc),
                ..
            } => {
                let k = (fc / f_tp).round().max(1.0);
                history.iter_mut().for_each(Vec::clear);
                SupervisorCommand {
                    feed_override: w.feed_override,
                    spindle_rpm: 60.0 * fc / (k * teeth as f64),
                }
            }
            _ => same,
        }
    }
}

/// Ra of the wall cut over the second half of the cut's length (to 3 f_t before the end of the
/// profile, where the last stamps are partial), m: the part cut after a controller acted.
fn ra_second_half(run: &MillingRun) -> f64 {
    let x = &run.surface.profile_x_m;
    let (Some(first), Some(last)) = (x.first(), x.last()) else {
        return f64::NAN;
    };
    run.surface
        .roughness_between(0.5 * (first + last), last - 3.0 * FEED_PER_TOOTH)
        .0
}

fn row(out: &mut String, name: &str, run: &MillingRun) {
    let truth = &run.ground_truth;
    let f = |k: &str| truth[k].as_f64().unwrap_or(f64::NAN);
    let intervals = truth["chatter_intervals_s"]
        .as_array()
        .cloned()
        .unwrap_or_default();
    let at = |v: &Value| v.as_f64().map_or("-".into(), |t| format!("{t:.3} s"));
    let chatter = match (intervals.first(), persistent_onset(truth)) {
        (_, Some(t)) => format!("yes, from {t:.3} s to the end"),
        (Some(first), None) => format!(
            "suppressed: from {} to {}",
            at(&first[0]),
            intervals.last().map_or("-".into(), |l| at(&l[1]))
        ),
        (None, None) => "no".into(),
    };
    let commands = truth["supervisor_commands"]
        .as_array()
        .cloned()
        .unwrap_or_default();
    let acts = commands.first().map_or("-".into(), |c| at(&c["time_s"]));
    // What the machine runs at the end: the last command, else as programmed.
    let last = |k: &str, programmed: f64| {
        commands
            .last()
            .and_then(|c| c[k].as_f64())
            .unwrap_or(programmed)
    };
    let end_rpm = last("spindle_rpm", f("spindle_rpm"));
    let end_feed = last("feed_override", 1.0) * f("feed_mm_min");
    let _ = writeln!(
        out,
        "| {name} | {chatter} | {acts} | {:.0} / {end_rpm:.0} | {:.0} / {end_feed:.0} | {:.0} | {:.2} | {:.2} |",
        f("mean_spindle_rpm"),
        f("mean_feed_mm_min"),
        f("removal_rate_mm3_s"),
        run.surface.ra_m * 1e6,
        ra_second_half(run) * 1e6
    );
}

/// Runs `vmt chatter compensate`.
pub fn compensate(a: &CompensateArgs) -> Result<(), CliError> {
    check_compensate(a)?;
    let (s, d) = (setup(a.depth_mm, 1), drive(a.spindle_rpm, a.duration_s));
    let none = simulate_milling(&s, &d).map_err(sim_error)?;
    let band = (1900.0, 2700.0);
    let mut kim_loop = kim_supervisor(kim_limit(band)?, band)?;
    let kim = simulate_milling_with(&s, &d, &mut kim_loop).map_err(sim_error)?;
    let mut speed_loop = speed_supervisor(4);
    let speed = simulate_milling_with(&s, &d, &mut speed_loop).map_err(sim_error)?;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Half-immersion down-milling cut of {} mm at {} rpm, 0.05 mm per tooth, {} s (12 mm four-flute tool, modes 2.3 and 6.5 kHz):\n",
        a.depth_mm, a.spindle_rpm, a.duration_s
    );
    let _ = writeln!(
        out,
        "| Control | Chatter | First action | Speed, mean / at the end (rpm) | Feed, mean / at the end (mm/min) | Removal rate (mm³/s) | Ra (µm) | Ra, second half (µm) |\n|---|---|---|---|---|---|---|---|"
    );
    row(&mut out, "none", &none);
    row(&mut out, "Kim: feed override = limit / RMS", &kim);
    row(
        &mut out,
        "better detector: spindle speed to a stable lobe",
        &speed,
    );
    let _ = writeln!(
        out,
        "\nKim, Song & Koh report for their feed-override loop: feed 200 -> about 152 mm/min, Ra 4.2 -> 4.0 µm."
    );
    crate::out!("{out}")?;
    Ok(())
}

/// `vmt chatter rates` arguments: the labelled set of `vmt_dataset::chatter`.
#[derive(clap::Args, Debug)]
pub struct RatesArgs {
    /// Spindle speeds, evenly spaced over --speed-range-rpm.
    #[arg(long, default_value_t = 20)]
    pub speeds: usize,
    /// Lowest and highest spindle speed, rev/min, as LOW,HIGH.
    #[arg(long, value_delimiter = ',', default_values_t = [vmt_dataset::chatter::SPEEDS_RPM.0, vmt_dataset::chatter::SPEEDS_RPM.1])]
    pub speed_range_rpm: Vec<f64>,
    /// Axial depths per speed, evenly spaced over --depth-range-mm.
    #[arg(long, default_value_t = 10)]
    pub depths: usize,
    /// Shallowest and deepest cut, mm, as LOW,HIGH.
    #[arg(long, value_delimiter = ',', default_values_t = [vmt_dataset::chatter::DEPTHS_MM.0, vmt_dataset::chatter::DEPTHS_MM.1])]
    pub depth_range_mm: Vec<f64>,
    /// Length of each cut, s.
    #[arg(long, default_value_t = 2.5)]
    pub duration_s: f64,
    /// Sample rates every cut is logged at, Hz.
    #[arg(long, value_delimiter = ',', default_values_t = [1600.0, 8000.0, 20_000.0])]
    pub rates_hz: Vec<f64>,
    /// Seed of the first cut (cut i gets seed + i).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Also write one row per cut and rate (cut, label, the better detector's verdict) to this
    /// CSV file.
    #[arg(long)]
    pub csv: Option<std::path::PathBuf>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Sample rates `vmt chatter rates` accepts, Hz: the cut's step is 1/160 000 s and a log's
/// period a whole number of steps of at least 8.
const RATES_HZ: (f64, f64) = (500.0, 20_000.0);

/// Checks the grid, duration and rates of `vmt chatter rates`.
fn check_rates(a: &RatesArgs) -> Result<(), CliError> {
    use crate::error::{check_count, check_range};
    check_count("--speeds", a.speeds, (1, 200), "speeds of the grid")?;
    check_count("--depths", a.depths, (1, 200), "depths per speed")?;
    check_range(
        "--duration-s",
        a.duration_s,
        (0.5, 10.0),
        "s",
        "seconds of cut per run; the longest frame at 3000 rev/min is 0.32 s",
    )?;
    for (name, range, limits, unit, why) in [
        (
            "--speed-range-rpm",
            &a.speed_range_rpm,
            SPINDLE_RPM,
            "rev/min",
            SPINDLE_WHY,
        ),
        (
            "--depth-range-mm",
            &a.depth_range_mm,
            (0.01, 30.0),
            "mm",
            "axial depths within the tool's 30 mm flutes",
        ),
    ] {
        for &v in range {
            check_range(name, v, limits, unit, why)?;
        }
        if range.len() != 2 || range[0] > range[1] {
            return Err(CliError::option(
                name,
                format!("{range:?}"),
                "LOW,HIGH with LOW <= HIGH",
            ));
        }
    }
    check_count("--rates-hz", a.rates_hz.len(), (1, 8), "sample rates")?;
    for &r in &a.rates_hz {
        check_range(
            "--rates-hz",
            r,
            RATES_HZ,
            "Hz",
            "a sample rate whose period is a whole number of the cut's 1/160 000 s steps",
        )?;
        let steps = 1.0 / (r * vmt_dataset::chatter::STEP_S);
        if (steps - steps.round()).abs() > 1e-9 {
            return Err(CliError::option(
                "--rates-hz",
                r,
                "a rate whose period is a whole number of the cut's 1/160 000 s steps (160 000 / n Hz: 1600, 8000, 20 000, ...)",
            ));
        }
    }
    let total = (a.speeds * a.depths * a.rates_hz.len()) as f64 * a.duration_s;
    if total > BENCH_TOTAL_S {
        return Err(CliError::Argument(format!(
            "--speeds {} x --depths {} x {} rates x --duration-s {} = {total} s of cut: at most \
             {BENCH_TOTAL_S} s is accepted (every run's accelerometer record is kept in memory)",
            a.speeds,
            a.depths,
            a.rates_hz.len(),
            a.duration_s
        )));
    }
    Ok(())
}

/// Runs `vmt chatter rates`: simulates the set, scores the detectors at each rate and prints
/// the table.
pub fn rates(a: &RatesArgs) -> Result<(), CliError> {
    use vmt_dataset::chatter::{SetSpec, cuts, markdown, score, simulate_set};
    check_rates(a)?;
    let spec = SetSpec {
        speeds: a.speeds,
        speed_range_rpm: (a.speed_range_rpm[0], a.speed_range_rpm[1]),
        depths: a.depths,
        depth_range_mm: (a.depth_range_mm[0], a.depth_range_mm[1]),
        duration_s: a.duration_s,
        seed: a.seed,
        rates_hz: a.rates_hz.clone(),
    };
    let bar = if a.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(cuts(&spec).len() as u64)
    };
    bar.set_message("cuts simulated");
    let set = simulate_set(&spec, || bar.inc(1)).map_err(sim_error)?;
    bar.finish_and_clear();
    let scores = score(&set, &spec).map_err(sim_error)?;
    if let Some(path) = &a.csv {
        std::fs::write(path, vmt_dataset::chatter::csv(&set, &scores))
            .map_err(|e| CliError::output(path, e))?;
    }
    crate::out!("{}", markdown(&set, &spec, &scores))?;
    Ok(())
}
