//! `vmt chatter detect` end to end on logs written from formulas: chatter is found at the right
//! time and frequency in a CSV and in an MCAP run, a stable cut is not flagged, and bad CSVs get
//! errors naming the file, line and column.

mod common;

use common::{stderr, vmt};
use serde_json::json;
use std::f64::consts::TAU;
use std::path::Path;
use vmt_sim::run::{Channel, MachineSummary, Run, Stream};

const FS: f64 = 20_000.0;
/// 7500 rev/min, 4 teeth: tooth passing 500 Hz.
const F_TP: f64 = 500.0;
const F_CHATTER: f64 = 3130.0;
const ONSET_S: f64 = 0.3;

/// Acceleration (m/s²) of axis `k` at t: tooth harmonics k·500 Hz with amplitude e^{−f/3 kHz}
/// (the 13th, 6.5 kHz, raised to 0.5 m/s²), and with `chatter` a 3130 Hz component growing as
/// 1 − e^{−(t − 0.3 s)/30 ms} to 1 m/s² after the onset.
fn accel(t: f64, k: usize, chatter: bool) -> f64 {
    let phase = k as f64;
    let forced: f64 = (1..20)
        .map(|h| {
            let f = h as f64 * F_TP;
            let a = if h == 13 { 0.5 } else { (-f / 3000.0).exp() };
            a * (TAU * f * t + phase * h as f64).sin()
        })
        .sum();
    let grow = if chatter && t >= ONSET_S {
        1.0 - (-(t - ONSET_S) / 0.03).exp()
    } else {
        0.0
    };
    forced + grow * (TAU * F_CHATTER * t + phase).sin()
}

fn times(n: usize) -> Vec<f64> {
    (0..n).map(|i| i as f64 / FS).collect()
}

fn write_csv(dir: &Path, name: &str, chatter: bool) -> String {
    let mut text = String::from("time_s,ax,ay,az\n");
    for t in times(16_000) {
        let [x, y, z] = [0, 1, 2].map(|k| accel(t, k, chatter));
        text += &format!("{t},{x},{y},{z}\n");
    }
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

/// The number after `key` in `text` (e.g. "CHATTER at " → 0.345).
fn number_after(text: &str, key: &str) -> f64 {
    let rest = &text[text
        .find(key)
        .unwrap_or_else(|| panic!("no `{key}` in {text}"))
        + key.len()..];
    let end = rest
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(rest.len());
    rest[..end].parse().unwrap()
}

#[test]
fn csv_with_chatter_is_detected_at_its_time_and_frequency() {
    let dir = tempfile::tempdir().unwrap();
    let csv = write_csv(dir.path(), "accel.csv", true);
    let out = dir.path().join("windows.csv");
    let o = vmt(&[
        "chatter",
        "detect",
        &csv,
        "--spindle-rpm",
        "7500",
        "--teeth",
        "4",
        "--csv",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    let better = text.lines().find(|l| l.starts_with("better:")).unwrap();
    // Within a frame and two hops of the onset: frames of 4096 samples (0.2 s) resolve the
    // 125 Hz spindle's orders.
    let t = number_after(better, "CHATTER at ");
    assert!(t > ONSET_S && t < ONSET_S + 0.35, "{better}");
    let f = number_after(better, "chatter frequency ");
    assert!((f - F_CHATTER).abs() < 10.0, "{better}");
    let rows = std::fs::read_to_string(&out).unwrap();
    assert!(rows.starts_with("detector,window_end_s,"));
    assert!(rows.lines().filter(|l| l.starts_with("better,")).count() >= 10);
    assert!(rows.lines().filter(|l| l.starts_with("kim,")).count() == 16);
}

/// The stable cut's 6.5 kHz harmonic is in Kim's band: with a limit below its level Kim's
/// detector flags it; the spectral detector does not.
#[test]
fn stable_csv_is_not_flagged_by_the_spectral_detector() {
    let dir = tempfile::tempdir().unwrap();
    let csv = write_csv(dir.path(), "stable.csv", false);
    let o = vmt(&[
        "chatter",
        "detect",
        &csv,
        "--spindle-rpm",
        "7500",
        "--teeth",
        "4",
        "--limit",
        "0.2",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("better:   no chatter"), "{text}");
    assert!(text.contains("kim:      CHATTER at 0.050 s"), "{text}");
}

#[test]
fn mcap_run_uses_its_accelerometer_stream_and_ground_truth() {
    let dir = tempfile::tempdir().unwrap();
    let t = times(16_000);
    let channels = ["ax", "ay", "az"]
        .iter()
        .enumerate()
        .map(|(k, name)| Channel {
            name: name.to_string(),
            unit: "m/s²".into(),
            values: t.iter().map(|&t| accel(t, k, true)).collect(),
        })
        .collect();
    let run = Run {
        scenario_name: "test".into(),
        scenario_toml: String::new(),
        seed: 1,
        fidelity: "reduced".into(),
        machine: MachineSummary {
            name: "m".into(),
            topology: "WXYGZT".into(),
            strokes_m: [[0.0, 0.5]; 3],
            tool_length_m: 0.1,
        },
        streams: vec![Stream {
            name: "accelerometer".into(),
            description: "spindle housing acceleration".into(),
            times_s: t,
            channels,
        }],
        ballbar: vec![],
        laser: None,
        ground_truth: json!({ "milling": { "spindle_rpm": 7500.0, "teeth": 4 } }),
    };
    let path = dir.path().join("run.mcap");
    vmt_logs::write_mcap(&run, &path).unwrap();
    let o = vmt(&[
        "chatter",
        "detect",
        path.to_str().unwrap(),
        "--detector",
        "better",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("tooth passing 500.00 Hz from the run"),
        "{text}"
    );
    assert!(!text.contains("kim:"), "{text}");
    let f = number_after(&text, "chatter frequency ");
    assert!((f - F_CHATTER).abs() < 10.0, "{text}");
}

fn error_of(body: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.csv");
    std::fs::write(&p, body).unwrap();
    let o = vmt(&["chatter", "detect", p.to_str().unwrap()]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(e.contains("bad.csv"), "{e}");
    e
}

#[test]
fn bad_csvs_name_file_line_and_column() {
    let e = error_of("time_s,bx\n0,1\n");
    assert!(
        e.contains("bad.csv:1") && e.contains("no `ax`, `ay` or `az` column"),
        "{e}"
    );
    let e = error_of("ax,ay\n0,1\n");
    assert!(
        e.contains("bad.csv:1") && e.contains("no `time_s` column"),
        "{e}"
    );
    let e = error_of("time_s,ax\n0,1\n0.001,2\n0.001,3\n");
    assert!(
        e.contains("bad.csv:4") && e.contains("does not increase"),
        "{e}"
    );
    let e = error_of("time_s,ax\n0,1\n0.001,abc\n");
    assert!(
        e.contains("bad.csv:3") && e.contains("column `ax`: `abc`"),
        "{e}"
    );
    let e = error_of("time_s,ax\n0,1\n0.001,2\n0.003,3\n");
    assert!(e.contains("uniform sampling"), "{e}");
    let e = error_of("time_s,ax\n0,1\n0.001,-2e200\n");
    assert!(
        e.contains("bad.csv:3") && e.contains("column `ax`: -2e200 m/s² is not accepted"),
        "{e}"
    );
    let e = error_of("time_s,ax,ax,az\n0,1,2,3\n");
    assert!(
        e.contains("bad.csv:1") && e.contains("`ax` is given twice (columns 2 and 3)"),
        "{e}"
    );
}

/// Both detectors on the milling simulator's own runs (Insperger–Stépán single-mode benchmark:
/// 922 Hz, ζ = 0.011, 2 teeth, slotting; at 15 000 rev/min the ZOA critical depth is 0.373 mm),
/// which start with a free vibration at the mode (tool entry) that decays in stable cuts,
/// labelled by the simulator's ground truth: chatter when a chatter interval lasts to the end of
/// the cut. The simulator also opens (and closes) an interval for the entry transient, which at
/// 22 000 rev/min is all it finds: a few ms of free vibration, not chatter.
/// Start of the chatter interval still open at the end of the cut (`chatter_intervals_s`).
fn sustained_onset(truth: &serde_json::Value) -> Option<f64> {
    let intervals = truth["chatter_intervals_s"].as_array()?;
    let last = intervals.last()?;
    last[1].is_null().then(|| last[0].as_f64()).flatten()
}

#[test]
fn detectors_on_simulated_milling_runs() {
    use vmt_chatter::detect::eval::{LabelledRun, evaluate};
    use vmt_chatter::detect::kim::{self, KimSettings};
    use vmt_chatter::detect::spectral::{self, SpectralSettings};
    use vmt_model::cutting::{
        CutGeometry, CuttingCoefficients, EndMill, MillingDirection, Mode, ToolDynamics,
    };
    use vmt_sim::milling::{
        AccelerometerParams, Feed, MillingDrive, MillingSetup, simulate_milling,
    };
    let setup = |depth: f64, seed: u64| MillingSetup {
        tool: EndMill {
            diameter: 0.01,
            teeth: 2,
            helix: 0.0,
            flute_length: 0.02,
            runout: 0.0,
            runout_angle: 0.0,
        },
        coefficients: CuttingCoefficients {
            tangential: 6e8,
            radial: 2e8,
            axial: 0.0,
            tangential_edge: 0.0,
            radial_edge: 0.0,
            axial_edge: 0.0,
        },
        dynamics: ToolDynamics {
            x: vec![Mode::from_mass(0.03993, 922.0, 0.011)],
            y: vec![Mode {
                natural_frequency_hz: 4_000.0,
                damping_ratio: 0.05,
                stiffness: 1e10,
            }],
        },
        axial_mode: None,
        cut: CutGeometry {
            axial_depth: depth,
            radial_depth: 0.01,
            direction: MillingDirection::Down,
        },
        feed_per_tooth: 1e-4,
        accelerometer: AccelerometerParams::default(),
        step_s: 1e-5,
        seed,
    };
    let mut runs = Vec::new();
    // At 22 000 rev/min the ZOA limit is 3 mm: 0.6 and 1 mm are stable there.
    let cuts = [
        (15e3, 0.1),
        (15e3, 0.2),
        (15e3, 0.3),
        (15e3, 0.5),
        (15e3, 0.6),
        (15e3, 0.8),
        (22e3, 0.6),
        (22e3, 1.0),
    ];
    for (k, (rpm, depth_mm)) in cuts.into_iter().enumerate() {
        let drive = MillingDrive {
            spindle_rpm: rpm,
            feed: Feed::PerTooth(1e-4),
            duration_s: 0.3,
            supervisor_window_s: 0.01,
        };
        let run = simulate_milling(&setup(depth_mm * 1e-3, k as u64), &drive).unwrap();
        let s = run
            .streams
            .iter()
            .find(|s| s.name == "accelerometer")
            .unwrap();
        let truth = &run.ground_truth;
        runs.push(LabelledRun {
            channels: ["ax", "ay", "az"]
                .map(|a| s.channel(a).unwrap().values.clone())
                .into(),
            sample_rate_hz: 20_000.0,
            spindle_rpm: rpm,
            teeth: 2,
            chatter_onset_s: sustained_onset(truth),
        });
    }
    let better = evaluate(&runs, |r| {
        let s = SpectralSettings::new(r.spindle_rpm, r.teeth);
        Ok(spectral::detect(&r.slices(), r.sample_rate_hz, &s)?.verdict)
    })
    .unwrap();
    // Kim's limit: twice the largest block RMS of the stable 0.1 mm cut.
    let probe = kim::detect(&runs[0].slices(), 20_000.0, &KimSettings::with_limit(1e9)).unwrap();
    let limit = 2.0 * probe.windows.iter().map(|w| w.rms).fold(0.0, f64::max);
    let kim = evaluate(&runs, |r| {
        Ok(kim::detect(
            &r.slices(),
            r.sample_rate_hz,
            &KimSettings::with_limit(limit),
        )?
        .verdict)
    })
    .unwrap();
    let labels: Vec<Option<f64>> = runs.iter().map(|r| r.chatter_onset_s).collect();
    eprintln!("simulated runs, onsets {labels:?}\n better: {better:?}\n kim: {kim:?}");
    assert_eq!(
        labels.iter().filter(|l| l.is_some()).count(),
        3,
        "{labels:?}"
    );
    assert_eq!(better.accuracy, 1.0, "{better:?}");
    // About a frame and two hops: frames as long as the spindle's comb needs.
    assert!(better.p90_latency_s < 0.3, "{better:?}");
}

/// `vmt chatter compensate` on its default cut (20 000 rpm, 0.3 mm, half immersion: 5 % past
/// the semi-discretization boundary, chatter that grows slowly from the entry transient and
/// settles below the developed share): without control it chatters to the end; Kim's feed
/// override lowers the feed but cannot stop it (the linear stability does not depend on the
/// feed); the spindle-speed loop, fed by the better detector, moves to a stable lobe and the
/// chatter stops, at the same removal rate, with a smoother wall after the correction.
#[test]
fn compensate_suppresses_slowly_growing_chatter_by_spindle_speed() {
    let o = vmt(&["chatter", "compensate"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    let row = |name: &str| -> Vec<String> {
        let line = text
            .lines()
            .find(|l| l.starts_with(&format!("| {name}")))
            .unwrap_or_else(|| panic!("no row {name} in\n{text}"));
        line.split('|').map(|c| c.trim().to_string()).collect()
    };
    // Cells: "", control, chatter, first action, speed, feed, removal rate, Ra, Ra second half.
    let num = |c: &str| -> f64 { c.parse().unwrap_or_else(|_| panic!("not a number: {c}")) };
    let none = row("none");
    let kim = row("Kim:");
    let speed = row("better detector:");
    assert!(none[2].starts_with("yes"), "{none:?}");
    assert!(kim[2].starts_with("yes"), "{kim:?}");
    assert!(num(&kim[6]) < 0.5 * num(&none[6]), "{kim:?}");
    assert!(speed[2].starts_with("suppressed"), "{speed:?}");
    let acted = number_after(&speed[3], "");
    assert!(acted > 0.1 && acted < 0.25, "{speed:?}");
    assert_eq!(num(&speed[6]), num(&none[6]), "removal rate");
    assert!(num(&speed[8]) < 0.6 * num(&none[8]), "{speed:?} {none:?}");
}

#[test]
fn spindle_speed_and_teeth_come_together_and_a_csv_needs_them_for_the_better_detector() {
    let dir = tempfile::tempdir().unwrap();
    let csv = write_csv(dir.path(), "accel.csv", true);
    let e = |args: &[&str]| {
        let mut a = vec!["chatter", "detect", &csv];
        a.extend(args);
        let o = vmt(&a);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        stderr(&o)
    };
    let said = e(&["--spindle-rpm", "7500"]);
    assert!(said.contains("--teeth"), "{said}");
    let said = e(&["--teeth", "4"]);
    assert!(said.contains("--spindle-rpm"), "{said}");
    let said = e(&["--spindle-rpm", "7500", "--teeth", "0"]);
    assert!(said.contains("--teeth 0: from 1 to 100"), "{said}");
    let said = e(&["--spindle-rpm=-5", "--teeth", "4"]);
    assert!(
        said.contains("--spindle-rpm -5: from 1 to 200000 rpm"),
        "{said}"
    );
    assert!(!said.contains("Hz"), "{said}");
    // No spindle speed in a CSV: not guessed from the spectrum (where it could be the chatter).
    // Asked for alone, the better detector is refused; with Kim's (the default, both), Kim's
    // verdict is given and the better one's absence explained.
    let said = e(&["--detector", "better"]);
    assert!(
        said.contains("accel.csv") && said.contains("--spindle-rpm and --teeth"),
        "{said}"
    );
    let o = vmt(&["chatter", "detect", &csv]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("kim:"), "{text}");
    assert!(
        text.contains("better:   not run:") && text.contains("--spindle-rpm and --teeth"),
        "{text}"
    );
    let o = vmt(&["chatter", "detect", &csv, "--detector", "kim"]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn irregular_sampling_is_reported_in_short_numbers() {
    // Samples every 5 ms, then 0.0553 - 0.05 = 0.005299999999999999 in binary.
    let mut body = String::from("time_s,ax\n");
    for t in [
        "0", "0.005", "0.01", "0.015", "0.02", "0.025", "0.03", "0.035", "0.04", "0.045",
    ] {
        body += &format!("{t},1\n");
    }
    let e = error_of(&(body + "0.05,1\n0.0553,1\n"));
    assert!(e.contains("interval 0.0053 s"), "{e}");
    assert!(e.contains("mean 0.005027273 s"), "{e}");
}

/// A spindle-housing accelerometer export as a vertical machining centre's software writes it
/// (the shape of NOTES.md's real files: header `Time (s),Accel X (m/s^2),Accel Y (m/s^2),Accel Z
/// (m/s^2),CI Value`, 1.65 kHz, time from an arbitrary offset), written here from a formula: a
/// 4-flute cutter at 12 000 rev/min (tooth passing 800 Hz, above a quarter of the rate) with
/// run-out, its harmonics up to 6 kHz through a 4th-order anti-alias filter at 0.45 of the rate
/// and sampled, so that those above 825 Hz fold into the band (1600 Hz at 50 Hz), and with
/// `chatter` a 570 Hz line growing from 2 s after the start, with 0.01 m/s² of noise. Units:
/// `ms` writes the time in ms
/// and `g` the accelerations in g, with those units in the headers when `units_in_header`.
struct Export {
    /// Spindle frequency, Hz (200: 12 000 rev/min).
    spindle_hz: f64,
    chatter: bool,
    ms: bool,
    g: bool,
    units_in_header: bool,
}

const EXPORT_FS: f64 = 1650.0;
const EXPORT_T0: f64 = 1234.5;
const EXPORT_CHATTER_HZ: f64 = 570.0;

impl Export {
    fn accel(&self, i: usize, k: usize) -> f64 {
        let t = i as f64 / EXPORT_FS;
        let aa = |f: f64| 1.0 / (1.0 + (f / (0.45 * EXPORT_FS)).powi(8)).sqrt();
        let phase = k as f64 + 0.3;
        // Sensor noise, 0.01 m/s² uniform, from a multiplicative hash of sample and axis.
        let h = ((i * 3 + k) as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 11;
        let mut a = 0.02 * (h as f64 / (1u64 << 53) as f64 - 0.5);
        for order in 1..=30 {
            let f = order as f64 * self.spindle_hz;
            // Tooth passing (every 4th order) strong, run-out weaker, both falling with f.
            let level = if order % 4 == 0 { 3.0 } else { 0.4 } * (-f / 2000.0).exp();
            a += aa(f) * level * (TAU * f * t + phase * order as f64).sin();
        }
        let since = t - 2.0;
        if self.chatter && since > 0.0 {
            a += aa(EXPORT_CHATTER_HZ)
                * 2.0
                * (1.0 - (-since / 0.05).exp())
                * (TAU * EXPORT_CHATTER_HZ * t + phase).sin();
        }
        a
    }

    fn write(&self, dir: &Path, name: &str) -> String {
        let (t_unit, a_unit) = (
            if self.ms { "ms" } else { "s" },
            if self.g { "g" } else { "m/s^2" },
        );
        let header = if self.units_in_header {
            format!(
                "Time ({t_unit}),Accel X ({a_unit}),Accel Y ({a_unit}),Accel Z ({a_unit}),CI Value\n"
            )
        } else {
            "Time,Accel X,Accel Y,Accel Z,CI Value\n".to_string()
        };
        let mut text = header;
        for i in 0..(6.0 * EXPORT_FS) as usize {
            let t = i as f64 / EXPORT_FS;
            let clock = EXPORT_T0 + t;
            let time = if self.ms { 1e3 * clock } else { clock };
            let scale = if self.g { 1.0 / 9.806_65 } else { 1.0 };
            let [x, y, z] = [0, 1, 2].map(|k| scale * self.accel(i, k));
            text += &format!("{time:.6},{x:.6},{y:.6},{z:.6},{}\n", i % 7);
        }
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p.display().to_string()
    }
}

const EXPORT_COLUMNS: &str =
    "time_s=Time (s),ax=Accel X (m/s^2),ay=Accel Y (m/s^2),az=Accel Z (m/s^2)";

/// The export read through --columns, as exported: the chatter is found at its time on the
/// export's own clock and at its frequency; the run-out's and the folded lines are listed as
/// forced, never as chatter; Kim's paper band cannot run at 1.65 kHz and `both` says why and
/// gives the other's verdict; the report echoes which column was read in which unit.
#[test]
fn an_exported_accelerometer_csv_is_read_through_its_column_mapping() {
    let dir = tempfile::tempdir().unwrap();
    let export = Export {
        chatter: true,
        ms: false,
        g: false,
        units_in_header: true,
        spindle_hz: 200.0,
    };
    let csv = export.write(dir.path(), "export.csv");
    let o = vmt(&[
        "chatter",
        "detect",
        &csv,
        "--columns",
        EXPORT_COLUMNS,
        "--spindle-rpm",
        "12000",
        "--teeth",
        "4",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("columns: time_s = \"Time (s)\" in s (from the header), ax = \"Accel X (m/s^2)\" in m/s² (from the header)"),
        "{text}"
    );
    assert!(text.contains("9900 samples at 1650.0 Hz"), "{text}");
    let better = text.lines().find(|l| l.starts_with("better:")).unwrap();
    let t = number_after(better, "CHATTER at ");
    assert!(t > EXPORT_T0 + 2.0 && t < EXPORT_T0 + 3.0, "{better}");
    let f = number_after(better, "chatter frequency ");
    assert!((f - EXPORT_CHATTER_HZ).abs() < 5.0, "{better}");
    assert!(
        text.contains("kim:      not run:") && text.contains("Nyquist frequency 825 Hz"),
        "{text}"
    );
    assert!(text.contains("1×f_r 200.0 Hz (spindle rotation"), "{text}");
    assert!(
        text.contains("8×f_r 1600.0 Hz seen at 50.0 Hz (tooth passing"),
        "{text}"
    );
    assert!(!text.contains("WARNING"), "{text}");
}

/// The same export in ms and g: units written in the headers are taken from them, units the
/// headers do not state are given with --units; either way the verdict is the export's in s
/// and m/s². A stated unit against the header's is refused.
#[test]
fn an_export_in_ms_and_g_is_read_in_its_units() {
    let dir = tempfile::tempdir().unwrap();
    let reference = {
        let csv = Export {
            chatter: true,
            ms: false,
            g: false,
            units_in_header: true,
            spindle_hz: 200.0,
        }
        .write(dir.path(), "si.csv");
        let o = vmt(&[
            "chatter",
            "detect",
            &csv,
            "--columns",
            EXPORT_COLUMNS,
            "--spindle-rpm",
            "12000",
            "--teeth",
            "4",
            "--detector",
            "better",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .nth(2)
            .unwrap()
            .to_string()
    };
    let in_header = Export {
        chatter: true,
        ms: true,
        g: true,
        units_in_header: true,
        spindle_hz: 200.0,
    }
    .write(dir.path(), "ms_g.csv");
    let bare = Export {
        chatter: true,
        ms: true,
        g: true,
        units_in_header: false,
        spindle_hz: 200.0,
    }
    .write(dir.path(), "bare.csv");
    for (csv, columns, units) in [
        (
            &in_header,
            "time_s=Time (ms),ax=Accel X (g),ay=Accel Y (g),az=Accel Z (g)",
            None,
        ),
        (
            &bare,
            "time_s=Time,ax=Accel X,ay=Accel Y,az=Accel Z",
            Some("time_s=ms,ax=g,ay=g,az=g"),
        ),
    ] {
        let mut args = vec![
            "chatter",
            "detect",
            csv,
            "--columns",
            columns,
            "--spindle-rpm",
            "12000",
            "--teeth",
            "4",
            "--detector",
            "better",
        ];
        if let Some(u) = units {
            args.extend(["--units", u]);
        }
        let o = vmt(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(text.contains("in ms") && text.contains("in g"), "{text}");
        let better = text.lines().nth(2).unwrap();
        // The same verdict, time and frequency (the g values are rounded to 6 decimals).
        assert_eq!(
            number_after(better, "CHATTER at "),
            number_after(&reference, "CHATTER at "),
            "{better}\n{reference}"
        );
        assert!(
            (number_after(better, "frequency ") - number_after(&reference, "frequency ")).abs()
                < 0.5
        );
    }
    let o = vmt(&[
        "chatter",
        "detect",
        &in_header,
        "--columns",
        "time_s=Time (ms),ax=Accel X (g)",
        "--units",
        "ax=m/s^2",
        "--detector",
        "kim",
        "--band",
        "300,400",
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("ms_g.csv:1") && e.contains("`Accel X (g)` says g"),
        "{e}"
    );
}

/// Bad input, one clear error each: a mapping naming a column the export does not have (the
/// header it was looked for and the headers found), an unknown unit (the units accepted), no
/// teeth, and a spindle whose comb the rate cannot resolve.
#[test]
fn bad_mappings_units_teeth_and_speeds_are_refused_one_by_one() {
    let dir = tempfile::tempdir().unwrap();
    let csv = Export {
        chatter: false,
        ms: false,
        g: false,
        units_in_header: true,
        spindle_hz: 200.0,
    }
    .write(dir.path(), "export.csv");
    let run = |extra: &[&str]| {
        let mut args = vec!["chatter", "detect", &csv];
        args.extend(extra);
        let o = vmt(&args);
        assert!(!o.status.success(), "{extra:?}");
        stderr(&o)
    };
    let e = run(&[
        "--columns",
        "time_s=Time (s),ax=Accel Q (m/s^2)",
        "--spindle-rpm",
        "12000",
        "--teeth",
        "4",
    ]);
    assert!(
        e.contains("export.csv:1")
            && e.contains("maps `ax` to `Accel Q (m/s^2)`")
            && e.contains(
                "found: Time (s), Accel X (m/s^2), Accel Y (m/s^2), Accel Z (m/s^2), CI Value"
            ),
        "{e}"
    );
    let e = run(&["--columns", EXPORT_COLUMNS, "--units", "ax=furlong"]);
    assert!(
        e.contains("--units ax=furlong") && e.contains("accepted: m/s² or g"),
        "{e}"
    );
    let e = run(&[
        "--columns",
        EXPORT_COLUMNS,
        "--spindle-rpm",
        "12000",
        "--teeth",
        "0",
    ]);
    assert!(e.contains("--teeth 0: from 1 to 100"), "{e}");
    let e = run(&[
        "--columns",
        EXPORT_COLUMNS,
        "--spindle-rpm",
        "60",
        "--teeth",
        "4",
        "--detector",
        "better",
    ]);
    assert!(
        e.contains("export.csv")
            && e.contains("60 rev/min")
            && e.contains("1650 Hz")
            && e.contains("beyond the longest frame"),
        "{e}"
    );
}

/// The wrong number of teeth does not make the tooth-passing lines chatter (every spindle order
/// is forced), and the report names the count the comb supports. At 3046 rev/min (f_r =
/// 1650 Hz / 32.5), so that 16 spindle orders lie below the Nyquist frequency (at 12 000
/// rev/min only 4 do, too few for the comb to tell a tooth count) and the folded orders land
/// half-way between them (an order sharing its bins with a folded one is not read).
#[test]
fn wrong_teeth_are_warned_about_not_taken_for_chatter() {
    let dir = tempfile::tempdir().unwrap();
    let csv = Export {
        chatter: false,
        ms: false,
        g: false,
        units_in_header: true,
        spindle_hz: 1650.0 / 32.5,
    }
    .write(dir.path(), "export.csv");
    // Two teeth, a divisor of four, share half of the comb's strong lines and score within the
    // 3 dB the check allows on this comb: not asked here.
    for (teeth, warned) in [("3", true), ("5", true), ("4", false)] {
        let o = vmt(&[
            "chatter",
            "detect",
            &csv,
            "--columns",
            EXPORT_COLUMNS,
            "--spindle-rpm",
            "3046.153846",
            "--teeth",
            teeth,
            "--detector",
            "better",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(text.contains("better:   no chatter"), "{text}");
        assert_eq!(
            text.contains(&format!(
                "WARNING: the comb does not fit {teeth} teeth: it supports 4"
            )),
            warned,
            "{teeth} teeth: {text}"
        );
    }
}
