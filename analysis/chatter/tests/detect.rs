//! Chatter detectors on signals built from formulas: tooth-passing harmonics shaped by a
//! structural mode, spindle run-out, white noise, and for chatter runs a component at a
//! non-harmonic frequency near the mode that grows from a known onset.
//!
//! Signal (m/s², fs = 20 kHz, 1 s):
//!   x(t) = Σ_k a_k sin(2π k f_tp t + φ_k) + 0.1·A sin(2π f_sp t) + σ·n(t)
//!          + C·g(t − t0)·[sin(2π f_c t) + 0.3 sin(2π (f_c ± f_tp) t)]
//! with a_k = A·(0.3 + 0.7u_k)·e^{−k f_tp / 3000 Hz} + 0.05·A / √((1 − r²)² + (2ζr)²),
//! r = k f_tp / f_n, ζ = 0.05 (the mode at f_n amplifies nearby harmonics), σ = 0.02·A,
//! g(τ) = 1 − e^{−τ/0.03 s} for τ ≥ 0 (0 before), f_c = (m + u)·f_tp near f_n, u ∈ [0.3, 0.7].

use vmt_chatter::detect::eval::{LabelledRun, evaluate};
use vmt_chatter::detect::kim::{self, KimSettings};
use vmt_chatter::detect::spectral::{self, SpectralSettings, tooth_passing_hz};
use vmt_chatter::detect::{DetectError, Verdict};

const FS: f64 = 20_000.0;
const TAU: f64 = std::f64::consts::TAU;

/// SplitMix64: seeded, reproducible.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.next()
    }
    fn gauss(&mut self) -> f64 {
        let (u, v) = (self.next().max(1e-300), self.next());
        (-2.0 * u.ln()).sqrt() * (TAU * v).cos()
    }
}

#[derive(Clone, Copy)]
struct Cut {
    rpm: f64,
    teeth: u32,
    mode_hz: f64,
    /// (onset s, amplitude C / A) of chatter.
    chatter: Option<(f64, f64)>,
}

/// The signal of the module doc, A = 1 m/s², and the chatter frequency used.
fn signal(cut: &Cut, rng: &mut Rng) -> (Vec<f64>, f64) {
    let f_tp = tooth_passing_hz(cut.rpm, cut.teeth);
    let f_sp = cut.rpm / 60.0;
    let harmonics: Vec<(f64, f64, f64)> = (1..)
        .map(|k| k as f64 * f_tp)
        .take_while(|&f| f < FS / 2.0)
        .map(|f| {
            let r = f / cut.mode_hz;
            let res = 0.05 / ((1.0 - r * r).powi(2) + (0.1 * r).powi(2)).sqrt();
            let a = rng.range(0.3, 1.0) * (-f / 3000.0).exp() + res;
            (f, a, rng.range(0.0, TAU))
        })
        .collect();
    let m = (cut.mode_hz / f_tp).floor();
    let f_c = (m + rng.range(0.3, 0.7)) * f_tp;
    let x = (0..FS as usize)
        .map(|i| {
            let t = i as f64 / FS;
            let forced: f64 = harmonics
                .iter()
                .map(|(f, a, p)| a * (TAU * f * t + p).sin())
                .sum();
            let chatter = cut.chatter.map_or(0.0, |(t0, c)| {
                let g = if t >= t0 {
                    1.0 - (-(t - t0) / 0.03).exp()
                } else {
                    0.0
                };
                let side = (TAU * (f_c - f_tp) * t).sin() + (TAU * (f_c + f_tp) * t).sin();
                c * g * ((TAU * f_c * t).sin() + 0.3 * side)
            });
            forced + 0.1 * (TAU * f_sp * t).sin() + 0.02 * rng.gauss() + chatter
        })
        .collect();
    (x, f_c)
}

fn run_of(cut: &Cut, rng: &mut Rng) -> LabelledRun {
    LabelledRun {
        channels: vec![signal(cut, rng).0],
        sample_rate_hz: FS,
        spindle_rpm: cut.rpm,
        teeth: cut.teeth,
        chatter_onset_s: cut.chatter.map(|c| c.0),
    }
}

/// Random cuts: 3000–12000 rev/min, 2–4 teeth, mode 2–8 kHz; every other run chatters with
/// C/A in 0.5–2 from an onset in 0.3–0.6 s.
fn random_cuts(n: usize, rng: &mut Rng) -> Vec<Cut> {
    (0..n)
        .map(|i| Cut {
            rpm: rng.range(3000.0, 12000.0),
            teeth: 2 + (rng.next() * 3.0) as u32,
            mode_hz: rng.range(2000.0, 8000.0),
            chatter: (i % 2 == 1).then(|| (rng.range(0.3, 0.6), rng.range(0.5, 2.0))),
        })
        .collect()
}

fn random_runs(n: usize, seed: u64) -> (Vec<Cut>, Vec<LabelledRun>) {
    let mut rng = Rng(seed);
    let cuts = random_cuts(n, &mut rng);
    let runs = cuts.iter().map(|c| run_of(c, &mut rng)).collect();
    (cuts, runs)
}

fn better(run: &LabelledRun) -> Result<Verdict, DetectError> {
    let s = SpectralSettings {
        tooth_passing_hz: Some(tooth_passing_hz(run.spindle_rpm, run.teeth)),
        ..Default::default()
    };
    Ok(spectral::detect(&run.slices(), run.sample_rate_hz, &s)?.verdict)
}

/// Largest block RMS (m/s²) of Kim's band-passed signal over stable runs of `cuts`.
fn stable_band_rms(cuts: &[Cut], seed: u64) -> f64 {
    let mut rng = Rng(seed);
    let mut worst = 0.0f64;
    for c in cuts {
        let stable = Cut {
            chatter: None,
            ..*c
        };
        let run = run_of(&stable, &mut rng);
        let r = kim::detect(&run.slices(), FS, &KimSettings::with_limit(1e9)).unwrap();
        worst = r.windows.iter().fold(worst, |m, w| m.max(w.rms));
    }
    worst
}

/// One limit for every cut, as the paper sets it from reference cuts: twice the largest band
/// RMS of stable cuts whose mode (3 kHz) is away from the band.
fn reference_limit() -> f64 {
    let reference: Vec<Cut> = [4000.0, 6000.0, 9000.0]
        .map(|rpm| Cut {
            rpm,
            teeth: 3,
            mode_hz: 3000.0,
            chatter: None,
        })
        .into();
    2.0 * stable_band_rms(&reference, 99)
}

fn kim_with(limit: f64) -> impl Fn(&LabelledRun) -> Result<Verdict, DetectError> {
    move |r| Ok(kim::detect(&r.slices(), FS, &KimSettings::with_limit(limit))?.verdict)
}

#[test]
fn kim_detector_with_one_limit_flags_stable_cuts() {
    let (_, runs) = random_runs(40, 7);
    let limit = reference_limit();
    let s = evaluate(&runs, kim_with(limit)).unwrap();
    eprintln!("Kim detector, one limit {limit:.3} m/s², 40 random cuts: {s:?}");
    // Harmonics amplified by a mode in 6–7 kHz exceed a limit set elsewhere.
    assert!(
        s.false_positive_rate >= 0.2,
        "false positives {}",
        s.false_positive_rate
    );
    assert!(s.accuracy < 0.8, "accuracy {}", s.accuracy);
}

#[test]
fn kim_detector_with_a_limit_per_cut_misses_chatter_outside_its_band() {
    let (cuts, runs) = random_runs(40, 7);
    let mut verdicts = Vec::new();
    for (k, (c, r)) in cuts.iter().zip(&runs).enumerate() {
        // The best case for the paper's method: a limit from the same cut run stably.
        let limit = 2.0 * stable_band_rms(std::slice::from_ref(c), 1000 + k as u64);
        verdicts.push(kim_with(limit)(r).unwrap());
    }
    let mut next = verdicts.into_iter();
    let s = evaluate(&runs, |_| Ok(next.next().expect("one verdict per run"))).unwrap();
    eprintln!("Kim detector, limit per cut, 40 random cuts: {s:?}");
    assert_eq!(s.false_positive_rate, 0.0);
    // Chatter near modes at 2–8 kHz lands in 6–7 kHz for a minority of the runs only.
    assert!(
        s.false_negative_rate >= 0.5,
        "false negatives {}",
        s.false_negative_rate
    );
}

#[test]
fn kim_detector_finds_in_band_chatter() {
    let mut rng = Rng(3);
    let mut latencies = Vec::new();
    for rpm in [5000.0, 7000.0, 11000.0] {
        let cut = Cut {
            rpm,
            teeth: 2,
            mode_hz: 6500.0,
            chatter: Some((0.4, 2.0)),
        };
        let limit = 2.0 * stable_band_rms(std::slice::from_ref(&cut), 4);
        let run = run_of(&cut, &mut rng);
        let r = kim::detect(&run.slices(), FS, &KimSettings::with_limit(limit)).unwrap();
        let t = r
            .verdict
            .detection_time_s
            .expect("in-band chatter detected");
        let t_spectral = better(&run)
            .unwrap()
            .detection_time_s
            .expect("spectral detection");
        latencies.push((t - 0.4, t_spectral - 0.4));
        // Feed override = limit / RMS once flagged, never above 1.
        for w in &r.windows {
            let expected = if w.chatter { limit / w.rms } else { 1.0 };
            assert!((w.feed_override - expected).abs() < 1e-12 && w.feed_override <= 1.0);
        }
    }
    // With 50 ms blocks and a limit at twice the stable level, Kim's detector needs two to
    // five blocks; the spectral detector fires sooner on the same runs.
    eprintln!("latencies (Kim, spectral) on in-band chatter, s: {latencies:?}");
    for &(kim, spectral) in &latencies {
        assert!(kim > 0.0 && kim < 0.3, "{latencies:?}");
        assert!(spectral > 0.0 && spectral < kim, "{latencies:?}");
    }
}

/// 7500 rev/min, 4 teeth: f_tp = 500 Hz, the 13th harmonic is at 6.5 kHz, on a mode at 6.5 kHz.
/// Stable, but its 6–7 kHz energy is far above a limit set on other cuts: Kim's detector calls
/// it chatter (and would slow the feed); the spectral detector, which removes tooth harmonics,
/// does not.
#[test]
fn stable_cut_with_a_tooth_harmonic_in_the_band() {
    let mut rng = Rng(11);
    let cut = Cut {
        rpm: 7500.0,
        teeth: 4,
        mode_hz: 6500.0,
        chatter: None,
    };
    let run = run_of(&cut, &mut rng);
    let kim = kim::detect(
        &run.slices(),
        FS,
        &KimSettings::with_limit(reference_limit()),
    )
    .unwrap();
    assert!(
        kim.verdict.chatter,
        "Kim's band detector flags the harmonic"
    );
    let spec = better(&run).unwrap();
    assert!(!spec.chatter, "spectral detector flagged a stable cut");
}

#[test]
fn chatter_frequency_and_estimated_tooth_passing() {
    let mut rng = Rng(5);
    let cut = Cut {
        rpm: 9000.0,
        teeth: 3,
        mode_hz: 4200.0,
        chatter: Some((0.3, 1.0)),
    };
    let (x, f_c) = signal(&cut, &mut rng);
    // Unknown spindle speed: f_tp is estimated from the first 8 frames (stable part).
    let r = spectral::detect(&[&x], FS, &SpectralSettings::default()).unwrap();
    assert!(
        (r.tooth_passing_hz - 450.0).abs() < 2.0,
        "estimated f_tp {}",
        r.tooth_passing_hz
    );
    let f = r.verdict.chatter_frequency_hz.expect("chatter found");
    assert!(
        (f - f_c).abs() < 10.0,
        "chatter frequency {f} Hz, injected {f_c} Hz"
    );
}

#[test]
fn bad_inputs_are_refused() {
    let x = vec![0.0; 100];
    assert!(
        spectral::detect(&[&x], FS, &SpectralSettings::default()).is_err(),
        "too short"
    );
    assert!(
        kim::detect(&[&x], FS, &KimSettings::with_limit(-1.0)).is_err(),
        "negative limit"
    );
    let y = vec![0.0; 99];
    assert!(
        kim::detect(
            &[&x, &y],
            FS,
            &KimSettings {
                window_s: 0.001,
                ..KimSettings::with_limit(1.0)
            }
        )
        .is_err()
    );
}

/// An air cut (spindle turning, no cutting): white noise only. The spectral-line condition
/// keeps noise peaks, however large their share of a small total, from counting as chatter.
#[test]
fn noise_only_is_not_flagged() {
    let mut rng = Rng(21);
    for f_tp in [150.0, 500.0, 1200.0] {
        let x: Vec<f64> = (0..FS as usize).map(|_| 0.02 * rng.gauss()).collect();
        let s = SpectralSettings {
            tooth_passing_hz: Some(f_tp),
            ..Default::default()
        };
        let r = spectral::detect(&[&x], FS, &s).unwrap();
        assert!(!r.verdict.chatter, "noise flagged at f_tp = {f_tp} Hz");
    }
}

/// The formula chatter of these cuts rises as 1 − e^{−τ/30 ms} to a level that, for the weaker
/// ones over resonant harmonics, holds a share below the developed 0.12: such a line is found
/// while it grows (power ×4 within the 0.15 s look-back). With the earlier 25 ms look-back two
/// of the 20 chatter runs were missed and the p90 latency was 0.13 s; now none is missed, the
/// median latency is 39 ms and the p90 85 ms, and no stable cut is flagged.
#[test]
fn better_detector_classifies_random_cuts_quickly() {
    let (_, runs) = random_runs(40, 7);
    let s = evaluate(&runs, better).unwrap();
    eprintln!("better detector on 40 random cuts: {s:?}");
    assert!(s.accuracy >= 0.95, "accuracy {}", s.accuracy);
    assert_eq!(s.false_positive_rate, 0.0);
    assert_eq!(s.false_negative_rate, 0.0, "missed chatter runs");
    assert!(
        s.median_latency_s < 0.05,
        "median latency {}",
        s.median_latency_s
    );
    assert!(s.p90_latency_s < 0.1, "p90 latency {}", s.p90_latency_s);
    assert!(
        s.latencies_s.iter().all(|&l| l > 0.0),
        "fired before onset: {:?}",
        s.latencies_s
    );
}

/// Tool entry excites the mode: a free vibration off the harmonics that decays as e^{−ζωt}
/// (here 2 m/s², 1 kHz, ζ = 0.01: τ = 16 ms), four times the harmonics at first. The share alone
/// exceeds the threshold for tens of ms; the detector waits for a peak that holds, so the
/// stable cut is not flagged, and the same cut with growing chatter still is.
#[test]
fn decaying_entry_transient_is_not_chatter() {
    let mut rng = Rng(31);
    for chatter in [None, Some((0.3, 1.0))] {
        let cut = Cut {
            rpm: 7500.0,
            teeth: 4,
            mode_hz: 3000.0,
            chatter,
        };
        let mut run = run_of(&cut, &mut rng);
        let tau = 1.0 / (0.01 * TAU * 1000.0);
        for (i, x) in run.channels[0].iter_mut().enumerate() {
            let t = i as f64 / FS;
            *x += 2.0 * (-t / tau).exp() * (TAU * 1000.0 * t).sin();
        }
        let v = better(&run).unwrap();
        assert_eq!(v.chatter, chatter.is_some(), "{v:?}");
        if let Some(t) = v.detection_time_s {
            assert!(t > 0.3, "fired at {t} s, before the onset");
        }
    }
}

/// Tooth harmonics of 500 Hz (1, 0.5, 0.25 m/s² at 500, 1000, 1500 Hz), white noise 0.02 m/s²,
/// and a line at 3130 Hz (off the harmonics) of amplitude `line(t)`, m/s².
fn line_over_harmonics(line: impl Fn(f64) -> f64, seed: u64) -> Vec<f64> {
    let mut rng = Rng(seed);
    (0..(0.4 * FS) as usize)
        .map(|i| {
            let t = i as f64 / FS;
            (TAU * 500.0 * t).sin()
                + 0.5 * (TAU * 1000.0 * t + 1.0).sin()
                + 0.25 * (TAU * 1500.0 * t + 2.0).sin()
                + line(t) * (TAU * 3130.0 * t).sin()
                + 0.02 * rng.gauss()
        })
        .collect()
}

fn settings_500() -> SpectralSettings {
    SpectralSettings {
        tooth_passing_hz: Some(500.0),
        ..Default::default()
    }
}

/// Near the stability boundary a stable cut's closed-loop mode is lightly damped and the cut's
/// own broad-band excitation keeps it ringing: a stationary line off the harmonics (the bench's
/// false alarms at 14 526, 17 368 and 22 105 rpm, shares 0.03–0.06 held for the whole cut). Here
/// the line holds 0.3 m/s² against harmonics of total power (1 + 0.25 + 0.0625)/2: share
/// 0.045/(0.656 + 0.045) ≈ 0.064, above the 0.05 threshold, below the developed share 0.12, and
/// it never grows: not chatter. The old rule (any held peak above 0.05) flagged it.
#[test]
fn a_stationary_line_below_the_developed_share_is_not_chatter() {
    let x = line_over_harmonics(|_| 0.3, 41);
    let r = spectral::detect(&[&x], FS, &settings_500()).unwrap();
    let late: Vec<f64> = r.frames.iter().skip(4).map(|f| f.share).collect();
    let (lo, hi) = late
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &s| (a.min(s), b.max(s)));
    assert!(lo > 0.05 && hi < 0.08, "shares {lo}..{hi}");
    assert!(r.frames.iter().filter(|f| f.chatter).count() > 20);
    assert!(!r.verdict.chatter, "{:?}", r.verdict);
    let old = SpectralSettings {
        developed_share: 1.0,
        growth: 1.0,
        ..settings_500()
    };
    assert!(spectral::detect(&[&x], FS, &old).unwrap().verdict.chatter);
}

/// Self-excitation: the same line growing as e^{t/20 ms} from 0.02 m/s² at 0.1 s, capped at
/// 0.35 m/s² (share ≈ 0.085 < 0.12, the tool leaving the cut): its power grows by e² ≈ 7.4 per
/// 20 ms, past the factor 4 within the 0.15 s look-back, so it is chatter, detected while it
/// crosses the 0.05 share: the amplitude reaches 0.26 m/s² (share 0.05) at 0.1 + 0.02·ln 13 =
/// 0.151 s, and a frame of 512 samples (25.6 ms) plus two hops (12.8 ms) later at the most.
#[test]
fn a_growing_line_below_the_developed_share_is_chatter() {
    let x = line_over_harmonics(
        |t| {
            if t < 0.1 {
                0.0
            } else {
                (0.02 * ((t - 0.1) / 0.02).exp()).min(0.35)
            }
        },
        43,
    );
    let r = spectral::detect(&[&x], FS, &settings_500()).unwrap();
    assert!(r.frames.iter().all(|f| f.share < 0.12));
    let t = r
        .verdict
        .detection_time_s
        .expect("growing line not flagged");
    assert!((0.151..0.151 + 0.04).contains(&t), "detected at {t} s");
    let f = r.verdict.chatter_frequency_hz.unwrap();
    assert!((f - 3130.0).abs() < 10.0, "{f} Hz");
}

/// Chatter just past the boundary: the line grows slowly (amplitude e^{t/70 ms} from 0.05 m/s²
/// at 0.05 s: power ×2 per 25 ms) and settles at 0.33 m/s² (share ≈ 0.077 < 0.12), the limit
/// cycle of a cut whose teeth leave the thin chip at the exit (the 20 000 rpm, 0.3 mm cut of
/// `vmt chatter compensate`). Its power grows by 4 within the 0.15 s look-back, so it is
/// chatter, found once its share passes 0.05 (amplitude 0.26 m/s² at 0.05 + 0.07·ln 5.2 =
/// 0.165 s) within a frame and two hops. A look-back of 25 ms, where the growth is only ×2,
/// never flags it.
#[test]
fn a_slowly_growing_line_that_settles_below_the_developed_share_is_chatter() {
    let x = line_over_harmonics(
        |t| {
            if t < 0.05 {
                0.0
            } else {
                (0.05 * ((t - 0.05) / 0.07).exp()).min(0.33)
            }
        },
        45,
    );
    let r = spectral::detect(&[&x], FS, &settings_500()).unwrap();
    assert!(r.frames.iter().all(|f| f.share < 0.12));
    let t = r
        .verdict
        .detection_time_s
        .expect("slowly growing line not flagged");
    assert!((0.165..0.165 + 0.045).contains(&t), "detected at {t} s");
    let short = SpectralSettings {
        growth_window_s: 0.025,
        ..settings_500()
    };
    let r = spectral::detect(&[&x], FS, &short).unwrap();
    assert!(!r.verdict.chatter, "{:?}", r.verdict);
}

/// Developed chatter from the first frame (fast chatter at deep cuts: the tool leaves the cut
/// within a few teeth, before the first frame closes) shows no growth, but a line of 1 m/s²
/// holds a share of 0.5/(0.656 + 0.5) ≈ 0.43 > 0.12: chatter, at the end of the third frame
/// (512 + 2·128 samples = 38.4 ms).
#[test]
fn a_dominant_line_from_the_start_is_chatter() {
    let x = line_over_harmonics(|_| 1.0, 47);
    let r = spectral::detect(&[&x], FS, &settings_500()).unwrap();
    assert!(r.frames.iter().all(|f| f.share > 0.35 && f.share < 0.5));
    assert_eq!(r.verdict.detection_time_s, Some(0.0384));
}

#[test]
fn growth_settings_out_of_range_are_refused() {
    let x = line_over_harmonics(|_| 0.0, 1);
    for s in [
        SpectralSettings {
            developed_share: 0.01,
            ..settings_500()
        },
        SpectralSettings {
            growth: 0.5,
            ..settings_500()
        },
        SpectralSettings {
            growth_window_s: -1.0,
            ..settings_500()
        },
    ] {
        assert!(matches!(
            spectral::detect(&[&x], FS, &s),
            Err(DetectError::Setting { .. })
        ));
    }
}
