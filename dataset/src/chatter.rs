//! A labelled set of simulated milling cuts, logged at several sample rates, and the chatter
//! detectors scored on it at each rate.
//!
//! # The cuts
//!
//! Straight half-immersion down-milling cuts of aluminium (K_t = 700, K_r = 210 N/mm²,
//! 0.05 mm per tooth) with a 12 mm four-flute end mill (30° helix) at 3000–12 000 rev/min
//! (tooth passing 200–800 Hz: the real spindle-housing exports' 4-flute cuts, above a quarter of
//! a 1.6 kHz rate from 6000 rev/min on), 0.5–5 mm deep ([`SetSpec`]): the depths cross the
//! stability boundary of the spindle mode, about 2–3 mm between its lobes' peaks, so that a
//! quarter of the cuts chatter, most of them at 610–640 Hz and, near 6300 rev/min, by period
//! doubling at 1.5 times the tooth-passing frequency, on the spindle-rotation comb. The tool
//! point has two modes in each direction ([`tool_modes`]): the spindle and holder at 620 Hz
//! and the tool at 2.9 kHz. Half of the cuts have run-out (every other point of the speed ×
//! depth grid, so that each speed and each depth has cuts with and without): the teeth at radii
//! R + r·cos(φ − j·2π/N) (vmt-model's `EndMill::tooth_radius`), r from 5 to 15 µm and φ
//! uniform, drawn from the cut's seed — the tool-holder run-out of collet chucks. Run-out and
//! regenerative chatter are not painted on: the simulator's cut (vmt-sim `milling`) has the
//! teeth at those radii, the chip from its surface memory, the modes integrated exactly; the
//! spindle-rotation lines and the chatter emerge.
//!
//! # Labels
//!
//! From the simulator's ground truth, never from the sensors: a cut chatters when a chatter
//! interval (the tool's once-per-tooth, or with run-out once-per-revolution and alternating,
//! deviation growing past 2 % of the feed per tooth, or holding a quarter of it) is still open
//! at the end of the cut, from its start (a closed one is the tool's entry transient).
//!
//! # Rates
//!
//! Each cut is simulated once per rate with the accelerometers sampled at that rate through the
//! signal chain a data acquisition system gives them (`AccelerometerParams::at_rate`: the
//! mounted resonance, a 4th-order Butterworth anti-alias filter at 0.45 of the rate, noise,
//! a 16-bit ADC). Not the 20 kHz log downsampled: an instrument logging at 1.6 kHz records what
//! its own filter lets through, the forced lines above its Nyquist frequency folded into its
//! band (7 dB down at 0.55·f_s, 28 dB at f_s), which an ideal decimation would remove and which
//! the detectors must cope with on real exports. The cut does not depend on the sensors (their
//! noise has a generator of its own), so its labels are the same at every rate.

use rayon::prelude::*;
use serde_json::Value;
use std::fmt::Write as _;
use thiserror::Error;
use vmt_chatter::detect::eval::{LabelledRun, Scores, evaluate};
use vmt_chatter::detect::kim::{self, KimSettings, weakest_mode};
use vmt_chatter::detect::spectral::{self, SpectralSettings};
use vmt_chatter::detect::{DetectError, Verdict};
use vmt_model::cutting::{
    CutGeometry, CuttingCoefficients, EndMill, MillingDirection, Mode, ToolDynamics,
};
use vmt_sim::milling::{
    AccelerometerParams, Feed, MillingDrive, MillingError, MillingSetup, simulate_milling,
};

/// Feed per tooth of every cut, m.
pub const FEED_PER_TOOTH_M: f64 = 0.05e-3;
/// Teeth of the end mill.
pub const TEETH: usize = 4;
/// Spindle speeds of the default grid, rev/min.
pub const SPEEDS_RPM: (f64, f64) = (3000.0, 12_000.0);
/// Axial depths of the default grid, mm.
pub const DEPTHS_MM: (f64, f64) = (0.5, 5.0);
/// Run-out radii drawn, µm.
pub const RUNOUT_UM: (f64, f64) = (5.0, 15.0);
/// Cut step, s: a whole fraction of the output period at 1.6, 8 and 20 kHz (100, 20 and 8
/// steps), 55 steps per period of the 2.9 kHz mode.
pub const STEP_S: f64 = 1.0 / 160_000.0;

/// What set to make.
#[derive(Debug, Clone, PartialEq)]
pub struct SetSpec {
    /// Spindle speeds, evenly spaced over `speed_range_rpm`.
    pub speeds: usize,
    /// Lowest and highest spindle speed, rev/min.
    pub speed_range_rpm: (f64, f64),
    /// Depths per speed, evenly spaced over `depth_range_mm`.
    pub depths: usize,
    /// Shallowest and deepest cut, mm.
    pub depth_range_mm: (f64, f64),
    /// Length of each cut, s.
    pub duration_s: f64,
    /// Seed of the first cut (cut i gets seed + i).
    pub seed: u64,
    /// The sample rates each cut is logged at, Hz.
    pub rates_hz: Vec<f64>,
}

impl Default for SetSpec {
    /// 20 speeds × 10 depths (200 cuts) over [`SPEEDS_RPM`] and [`DEPTHS_MM`], 2.5 s each,
    /// logged at 1.6, 8 and 20 kHz.
    fn default() -> Self {
        Self {
            speeds: 20,
            speed_range_rpm: SPEEDS_RPM,
            depths: 10,
            depth_range_mm: DEPTHS_MM,
            duration_s: 2.5,
            seed: 1,
            rates_hz: vec![1600.0, 8000.0, 20_000.0],
        }
    }
}

/// Why a set cannot be made or scored.
#[derive(Debug, Error)]
pub enum SetError {
    /// The simulator refused a cut.
    #[error("cut {index} ({rpm:.0} rev/min, {depth_mm:.2} mm) at {rate_hz} Hz: {source}")]
    Milling {
        /// The cut.
        index: usize,
        /// Its speed.
        rpm: f64,
        /// Its depth.
        depth_mm: f64,
        /// The rate.
        rate_hz: f64,
        /// The simulator's error.
        source: MillingError,
    },
    /// A detector refused a run.
    #[error("detector: {0}")]
    Detect(#[from] DetectError),
}

/// One cut of the set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cut {
    /// Its place in the set.
    pub index: usize,
    /// Spindle speed, rev/min.
    pub spindle_rpm: f64,
    /// Axial depth, mm.
    pub depth_mm: f64,
    /// Run-out radius, µm (0: none).
    pub runout_um: f64,
    /// Angle of the run-out from tooth 0, deg.
    pub runout_angle_deg: f64,
    /// Seed of the sensors' noise and of the run-out's draw.
    pub seed: u64,
}

/// SplitMix64 step: a seeded uniform draw in [0, 1).
fn uniform(state: &mut u64) -> f64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
}

/// The cuts of `spec`: the speed × depth grid, run-out on every other point.
pub fn cuts(spec: &SetSpec) -> Vec<Cut> {
    let step = |(lo, hi): (f64, f64), n: usize, i: usize| {
        lo + (hi - lo) * i as f64 / (n.max(2) - 1) as f64
    };
    (0..spec.speeds)
        .flat_map(|i| (0..spec.depths).map(move |j| (i, j)))
        .enumerate()
        .map(|(index, (i, j))| {
            let seed = spec.seed + index as u64;
            let mut state = seed;
            let (r, a) = (uniform(&mut state), uniform(&mut state));
            let runout = (i + j) % 2 == 1;
            Cut {
                index,
                spindle_rpm: step(spec.speed_range_rpm, spec.speeds, i),
                depth_mm: step(spec.depth_range_mm, spec.depths, j),
                runout_um: if runout {
                    RUNOUT_UM.0 + (RUNOUT_UM.1 - RUNOUT_UM.0) * r
                } else {
                    0.0
                },
                runout_angle_deg: if runout { 360.0 * a } else { 0.0 },
                seed,
            }
        })
        .collect()
}

/// The tool point's modes, the same in X and Y: the spindle and holder at 620 Hz (ζ = 0.03,
/// k = 1.6·10⁷ N/m, 1.05 kg of modal mass) and the tool at 2.9 kHz (ζ = 0.02, k = 1.0·10⁸ N/m).
/// The spindle mode's k·ζ is a sixth of the tool's, so it chatters first over the depths of the
/// set (the lower lobes); its chatter lies below the Nyquist frequency of every rate.
pub fn tool_modes() -> Vec<Mode> {
    vec![
        Mode {
            natural_frequency_hz: 620.0,
            damping_ratio: 0.03,
            stiffness: 1.6e7,
        },
        Mode {
            natural_frequency_hz: 2900.0,
            damping_ratio: 0.02,
            stiffness: 1.0e8,
        },
    ]
}

/// The set's end mill: 12 mm, [`TEETH`] flutes, 30° helix, 30 mm of flute, its run-out
/// `runout_m` (m) at `angle_rad` (rad).
pub fn end_mill(runout_m: f64, angle_rad: f64) -> EndMill {
    EndMill {
        diameter: 0.012,
        teeth: TEETH,
        helix: 30f64.to_radians(),
        flute_length: 0.03,
        runout: runout_m,
        runout_angle: angle_rad,
    }
}

/// The cutting coefficients of the set's aluminium, N/m²: K_tc 700 MPa, K_rc 210 MPa (a
/// third of it), no axial or edge forces.
pub const ALUMINIUM: CuttingCoefficients = CuttingCoefficients {
    tangential: 700e6,
    radial: 210e6,
    axial: 0.0,
    tangential_edge: 0.0,
    radial_edge: 0.0,
    axial_edge: 0.0,
};

/// The set's engagement at `axial_depth_m` (m): half the tool's diameter radially (6 mm), down
/// milling.
pub fn half_immersion(axial_depth_m: f64) -> CutGeometry {
    CutGeometry {
        axial_depth: axial_depth_m,
        radial_depth: 0.006,
        direction: MillingDirection::Down,
    }
}

/// The simulator's set-up of `cut` logged at `rate_hz`.
pub fn setup(cut: &Cut, rate_hz: f64) -> MillingSetup {
    MillingSetup {
        tool: end_mill(cut.runout_um * 1e-6, cut.runout_angle_deg.to_radians()),
        coefficients: ALUMINIUM,
        dynamics: ToolDynamics::symmetric(tool_modes()),
        axial_mode: None,
        cut: half_immersion(cut.depth_mm * 1e-3),
        feed_per_tooth: FEED_PER_TOOTH_M,
        accelerometer: AccelerometerParams::at_rate(rate_hz),
        step_s: STEP_S,
        seed: cut.seed,
    }
}

/// A cut of the set with its label and its logs.
#[derive(Debug, Clone)]
pub struct Labelled {
    /// The cut.
    pub cut: Cut,
    /// Chatter onset from the truth, s (`None`: stable).
    pub onset_s: Option<f64>,
    /// Chatter frequency from the truth, Hz.
    pub chatter_hz: Option<f64>,
    /// The X and Y accelerometers at each rate of the spec, in its order.
    pub runs: Vec<LabelledRun>,
}

/// The onset of a chatter interval still open at the end of the cut.
fn persistent_onset(truth: &Value) -> Option<f64> {
    let last = truth["chatter_intervals_s"].as_array()?.last()?;
    last[1].is_null().then(|| last[0].as_f64()).flatten()
}

/// Simulates `cut` at every rate of `spec`.
pub fn simulate(cut: &Cut, spec: &SetSpec) -> Result<Labelled, SetError> {
    let drive = MillingDrive {
        spindle_rpm: cut.spindle_rpm,
        feed: Feed::PerTooth(FEED_PER_TOOTH_M),
        duration_s: spec.duration_s,
        supervisor_window_s: 0.025,
    };
    let mut runs = Vec::new();
    let mut label = None;
    for &rate in &spec.rates_hz {
        let run =
            simulate_milling(&setup(cut, rate), &drive).map_err(|source| SetError::Milling {
                index: cut.index,
                rpm: cut.spindle_rpm,
                depth_mm: cut.depth_mm,
                rate_hz: rate,
                source,
            })?;
        let acc = run.streams.iter().find(|s| s.name == "accelerometer");
        let channels = acc.map_or_else(Vec::new, |s| {
            s.channels
                .iter()
                .take(2)
                .map(|c| c.values.clone())
                .collect()
        });
        let truth = &run.ground_truth;
        label.get_or_insert((
            persistent_onset(truth),
            truth["chatter_frequency_hz"].as_f64(),
        ));
        runs.push(LabelledRun {
            channels,
            sample_rate_hz: rate,
            spindle_rpm: cut.spindle_rpm,
            teeth: TEETH as u32,
            chatter_onset_s: label.and_then(|l| l.0),
        });
    }
    let (onset_s, chatter_hz) = label.unwrap_or((None, None));
    Ok(Labelled {
        cut: *cut,
        onset_s,
        chatter_hz,
        runs,
    })
}

/// Simulates every cut of `spec` on all cores; `progress` is called after each.
pub fn simulate_set(spec: &SetSpec, progress: impl Fn() + Sync) -> Result<Vec<Labelled>, SetError> {
    cuts(spec)
        .par_iter()
        .map(|c| {
            let l = simulate(c, spec);
            progress();
            l
        })
        .collect()
}

/// How Kim's detector fared at one rate.
#[derive(Debug, Clone, PartialEq)]
pub enum KimOutcome {
    /// Run with this band (Hz) and limit (m/s²).
    Scored {
        /// Pass band, Hz.
        band_hz: (f64, f64),
        /// RMS limit, m/s².
        limit: f64,
        /// Its scores.
        scores: Scores,
    },
    /// Not run, and why.
    NotRun(String),
}

/// The detectors at one rate.
#[derive(Debug, Clone, PartialEq)]
pub struct RateScores {
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// The spectral detector.
    pub better: Scores,
    /// Its verdicts, in the set's order.
    pub verdicts: Vec<Verdict>,
    /// Stable cuts with run-out it called chatter.
    pub runout_false_alarms: usize,
    /// Stable cuts with run-out.
    pub runout_stable: usize,
    /// Cuts where a line grew on a forced line that it could not tell from it.
    pub hidden: usize,
    /// Its frame lengths, s (shortest, longest).
    pub frames_s: (f64, f64),
    /// Kim's detector, band from the tool's weakest mode.
    pub kim: KimOutcome,
}

/// Kim's limit at `rate_hz` for `band`: three times the largest block RMS of three shallow,
/// stable cuts apart from the set (0.1 mm at 3500, 7000 and 11 000 rev/min, seeds 10 000 on).
fn kim_limit(spec: &SetSpec, rate_hz: f64, band: (f64, f64)) -> Result<f64, SetError> {
    let one = SetSpec {
        rates_hz: vec![rate_hz],
        duration_s: 0.5,
        ..spec.clone()
    };
    let mut worst: f64 = 0.0;
    for (k, rpm) in [3500.0, 7000.0, 11_000.0].into_iter().enumerate() {
        let cut = Cut {
            index: usize::MAX,
            spindle_rpm: rpm,
            depth_mm: 0.1,
            runout_um: 0.0,
            runout_angle_deg: 0.0,
            seed: 10_000 + k as u64,
        };
        let l = simulate(&cut, &one)?;
        let settings = KimSettings {
            band_hz: band,
            ..KimSettings::with_limit(f64::MAX)
        };
        let r = kim::detect(&l.runs[0].slices(), rate_hz, &settings)?;
        worst = r.windows.iter().map(|w| w.rms).fold(worst, f64::max);
    }
    Ok(3.0 * worst)
}

/// Scores both detectors on `set` at every rate of `spec`.
pub fn score(set: &[Labelled], spec: &SetSpec) -> Result<Vec<RateScores>, SetError> {
    spec.rates_hz
        .iter()
        .enumerate()
        .map(|(r, &rate)| {
            let runs: Vec<LabelledRun> = set.iter().map(|l| l.runs[r].clone()).collect();
            let mut results = Vec::new();
            let better = evaluate(&runs, |run| {
                let s = SpectralSettings::new(run.spindle_rpm, run.teeth);
                let res = spectral::detect(&run.slices(), run.sample_rate_hz, &s)?;
                let v = res.verdict;
                results.push(res);
                Ok(v)
            })?;
            let frames: Vec<f64> = results.iter().map(|x| x.frame_len as f64 / rate).collect();
            let stable_runout = |l: &&Labelled| l.onset_s.is_none() && l.cut.runout_um > 0.0;
            let runout_stable = set.iter().filter(stable_runout).count();
            let runout_false_alarms = set
                .iter()
                .zip(&results)
                .filter(|(l, x)| stable_runout(l) && x.verdict.chatter)
                .count();
            let band = weakest_mode(&tool_modes()).map(|f| KimSettings::for_mode(f, 1.0));
            let kim = match band {
                None => KimOutcome::NotRun("the tool has no mode".into()),
                Some(k) => match k.fits(rate) {
                    Err(e) => KimOutcome::NotRun(e.to_string()),
                    Ok(()) => {
                        let limit = kim_limit(spec, rate, k.band_hz)?;
                        let settings = KimSettings { limit, ..k };
                        let scores = evaluate(&runs, |run| {
                            Ok(kim::detect(&run.slices(), rate, &settings)?.verdict)
                        })?;
                        KimOutcome::Scored {
                            band_hz: k.band_hz,
                            limit,
                            scores,
                        }
                    }
                },
            };
            Ok(RateScores {
                rate_hz: rate,
                better,
                verdicts: results.iter().map(|x| x.verdict).collect(),
                runout_false_alarms,
                runout_stable,
                hidden: results.iter().filter(|x| x.hidden.is_some()).count(),
                frames_s: (
                    frames.iter().copied().fold(f64::INFINITY, f64::min),
                    frames.iter().copied().fold(0.0, f64::max),
                ),
                kim,
            })
        })
        .collect()
}

/// The report of a scored set, as Markdown.
pub fn markdown(set: &[Labelled], spec: &SetSpec, scores: &[RateScores]) -> String {
    let chatter = set.iter().filter(|l| l.onset_s.is_some()).count();
    let runout = set.iter().filter(|l| l.cut.runout_um > 0.0).count();
    let runout_chatter = set
        .iter()
        .filter(|l| l.cut.runout_um > 0.0 && l.onset_s.is_some())
        .count();
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Labelled set: {} simulated half-immersion down-milling cuts of a 12 mm four-flute end \
         mill ({} chatter, {} stable; {} with run-out of {}–{} µm, {} of them chatter), {} \
         speeds {:.0}–{:.0} rev/min × {} depths {}–{} mm, {} s each, seeds from {}; labels from \
         the simulator's truth; each cut logged at {} Hz.\n",
        set.len(),
        chatter,
        set.len() - chatter,
        runout,
        RUNOUT_UM.0,
        RUNOUT_UM.1,
        runout_chatter,
        spec.speeds,
        spec.speed_range_rpm.0,
        spec.speed_range_rpm.1,
        spec.depths,
        spec.depth_range_mm.0,
        spec.depth_range_mm.1,
        spec.duration_s,
        spec.seed,
        spec.rates_hz
            .iter()
            .map(|r| format!("{r}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let _ = writeln!(
        out,
        "| Rate | Detector | Accuracy | False positives | Run-out cuts called chatter | Missed | \
         Median latency | p90 latency |\n|---|---|---|---|---|---|---|---|"
    );
    let pct = |x: f64| {
        if x.is_nan() {
            "–".to_string()
        } else {
            format!("{:.1} %", 100.0 * x)
        }
    };
    let ms = |x: f64| {
        if x.is_nan() {
            "–".to_string()
        } else {
            format!("{:.0} ms", 1e3 * x)
        }
    };
    for r in scores {
        let b = &r.better;
        let _ = writeln!(
            out,
            "| {:.1} kHz | better (frames {:.2}–{:.2} s) | {} | {} | {} of {} | {} | {} | {} |",
            r.rate_hz / 1e3,
            r.frames_s.0,
            r.frames_s.1,
            pct(b.accuracy),
            pct(b.false_positive_rate),
            r.runout_false_alarms,
            r.runout_stable,
            pct(b.false_negative_rate),
            ms(b.median_latency_s),
            ms(b.p90_latency_s)
        );
        match &r.kim {
            KimOutcome::Scored {
                band_hz,
                limit,
                scores: k,
            } => {
                let _ = writeln!(
                    out,
                    "| {:.1} kHz | Kim, band {:.0}–{:.0} Hz from the {:.0} Hz mode (limit {limit:.3} m/s²) | {} | {} | – | {} | {} | {} |",
                    r.rate_hz / 1e3,
                    band_hz.0,
                    band_hz.1,
                    weakest_mode(&tool_modes()).unwrap_or(f64::NAN),
                    pct(k.accuracy),
                    pct(k.false_positive_rate),
                    pct(k.false_negative_rate),
                    ms(k.median_latency_s),
                    ms(k.p90_latency_s)
                );
            }
            KimOutcome::NotRun(why) => {
                let _ = writeln!(
                    out,
                    "| {:.1} kHz | Kim: not run: {why} | | | | | | |",
                    r.rate_hz / 1e3
                );
            }
        }
    }
    let hidden: Vec<String> = scores
        .iter()
        .map(|r| format!("{} at {:.1} kHz", r.hidden, r.rate_hz / 1e3))
        .collect();
    let _ = writeln!(
        out,
        "\nLines that grew on a forced line, where the detector cannot tell chatter from it \
         (reported, not called chatter): {}.",
        hidden.join(", ")
    );
    out
}

/// One row per cut and rate: the cut, its label and the better detector's verdict.
pub fn csv(set: &[Labelled], scores: &[RateScores]) -> String {
    let mut text = String::from(
        "rate_hz,spindle_rpm,depth_mm,runout_um,chatter,onset_s,truth_chatter_hz,better_chatter,better_time_s,better_frequency_hz\n",
    );
    let opt = |x: Option<f64>| x.map_or(String::new(), |x| x.to_string());
    for r in scores {
        for (l, v) in set.iter().zip(&r.verdicts) {
            let _ = writeln!(
                text,
                "{},{},{},{},{},{},{},{},{},{}",
                r.rate_hz,
                l.cut.spindle_rpm,
                l.cut.depth_mm,
                l.cut.runout_um,
                l.onset_s.is_some(),
                opt(l.onset_s),
                opt(l.chatter_hz),
                v.chatter,
                opt(v.detection_time_s),
                opt(v.chatter_frequency_hz)
            );
        }
    }
    text
}
