//! `vmt gap` end to end on ball-bar CSV traces that did not come from the simulator (written
//! from displacement laws), and the refusal of measurements of another test.

mod common;
#[path = "common/python.rs"]
mod python;

use common::{stderr, vmt};
use std::path::{Path, PathBuf};
use std::process::Output;
use vmt_ballbar::synthetic::{Errors, trace};
use vmt_ballbar::{Plane, Sense, Trace};

/// The built-in machine with its test shortened to a 50 mm circle at 2000 mm/min.
fn model(dir: &Path) -> PathBuf {
    let text = vmt_scenario::BUILTIN_DEFAULT
        .replace("radius_mm = 150.0", "radius_mm = 50.0")
        .replace(
            "feed_mm_min = 1000.0\narc_deg",
            "feed_mm_min = 2000.0\narc_deg",
        );
    let p = dir.join("model.toml");
    std::fs::write(&p, text).unwrap();
    p
}

fn write_csv(dir: &Path, name: &str, traces: &[Trace]) -> PathBuf {
    let mut s = String::from("angle_deg,deviation_um,direction\n");
    for t in traces {
        for (a, d) in t.angle_deg.iter().zip(&t.deviation_um) {
            s += &format!("{a},{d},{}\n", t.sense.name());
        }
    }
    let p = dir.join(name);
    std::fs::write(&p, s).unwrap();
    p
}

/// CW then CCW over the full circle from 0°, the tool displaced by `e`.
fn traces(radius_mm: f64, e: &Errors) -> Vec<Trace> {
    [(Sense::Cw, (0.0, 0.5), 1), (Sense::Ccw, (0.5, 1.0), 2)]
        .into_iter()
        .map(|(sense, progress, seed)| {
            trace(
                Plane::Xy,
                sense,
                radius_mm,
                2000.0,
                0.0,
                360.0,
                e,
                progress,
                seed,
            )
        })
        .collect()
}

/// `vmt gap` of `model` against the ball-bar CSV files `real`, XY at `radius_mm` and
/// 2000 mm/min, with `extra` arguments.
fn gap_csv(model: &Path, real: &[&Path], radius_mm: &str, extra: &[&str]) -> Output {
    let mut args = vec!["gap", "--model", model.to_str().unwrap(), "--real"];
    args.extend(real.iter().map(|p| p.to_str().unwrap()));
    args.extend([
        "--radius-mm",
        radius_mm,
        "--feed-mm-min",
        "2000",
        "--plane",
        "XY",
    ]);
    args.extend(extra);
    vmt(&args)
}

#[test]
fn a_servo_mismatch_in_hand_made_traces_is_found() {
    let dir = tempfile::tempdir().unwrap();
    let model = model(dir.path());
    // The model's axes lag equally (Kv 33 and 33.3/s: 30.3 and 30.0 ms); these traces carry a
    // 1 ms mismatch, ±(FΔτ/2)·sin 2θ = ±16.7 µm at 2000 mm/min, reversing with direction.
    let e = Errors {
        lag_ms: [31.3, 30.0],
        noise_um: 0.2,
        ..Default::default()
    };
    let csv = write_csv(dir.path(), "trace.csv", &traces(50.0, &e));
    let o = gap_csv(&model, &[&csv], "50", &["--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let first = &r["effects"][0];
    assert_eq!(first["effect"], "servo_mismatch", "{r:#}");
    // Δτ = ΔKv/Kv²: 1 ms more lag on X is Kv_X lower by about 33²·0.001 ≈ 1.1/s.
    let dkv = first["values"][0]["value"].as_f64().unwrap();
    assert!((dkv + 1.05).abs() < 0.2, "ΔKv_X {dkv} 1/s");
    assert!(r["judged"]["shrink"].as_f64().unwrap() > 0.8, "{r:#}");
}

#[test]
fn measurements_of_another_test_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let model = model(dir.path());
    let csv = write_csv(dir.path(), "trace.csv", &traces(60.0, &Errors::default()));
    let o = gap_csv(&model, &[&csv], "60", &[]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("60 mm") && e.contains("XY 50 mm 2000 mm/min"),
        "{e}"
    );
    // The job's own test given twice (the same file twice): named as such.
    let csv = write_csv(dir.path(), "trace50.csv", &traces(50.0, &Errors::default()));
    let o = gap_csv(&model, &[&csv, &csv], "50", &[]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("the measured runs hold 2 XY 50 mm 2000 mm/min")
            && e.contains("the model's job runs it 1 time(s)")
            && e.contains("given twice"),
        "{e}"
    );
    // A file that cannot be read is refused before the output folder is made.
    let out = dir.path().join("never");
    let missing = dir.path().join("missing.csv");
    let o = gap_csv(&model, &[&missing], "50", &["--out", out.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("missing.csv"), "{}", stderr(&o));
    assert!(!out.exists(), "a refused command made {}", out.display());
    // A laser positioning CSV is named as one, not asked for a ball bar's set-up.
    let laser = dir.path().join("laser.csv");
    std::fs::write(
        &laser,
        "target_mm,direction,run,deviation_um\n0,forward,1,0.5\n100,forward,1,1.0\n",
    )
    .unwrap();
    let o = vmt(&[
        "gap",
        "--model",
        model.to_str().unwrap(),
        "--real",
        laser.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("laser.csv:1: a laser positioning CSV (ISO 230-2)")
            && !e.contains("--radius-mm"),
        "{e}"
    );
}

/// The shipped milling slot at 0.2 mm depth (a stable cut), with its NC program, in `dir`.
fn milling_model(dir: &Path) -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios");
    let text = std::fs::read_to_string(root.join("milling_slot.toml"))
        .unwrap()
        .replace("axial_depth_mm = 0.5", "axial_depth_mm = 0.2");
    std::fs::create_dir_all(dir.join("milling")).unwrap();
    std::fs::copy(root.join("milling/slot.nc"), dir.join("milling/slot.nc")).unwrap();
    let p = dir.join("milling.toml");
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn a_tool_mode_is_found_from_an_accelerometer_csv() {
    let dir = tempfile::tempdir().unwrap();
    let model = milling_model(dir.path());
    // The "machine": its X mode 4 % lower than the model's, sensor noise kept, another seed.
    let text = std::fs::read_to_string(&model)
        .unwrap()
        .replace("frequency_hz = 922.0", "frequency_hz = 885.0")
        .replace("seed = 1", "seed = 5");
    let log =
        vmt_gap::vibration::MillingModel::instrumented(&text, "real", Some(dir.path().into()))
            .unwrap()
            .base;
    let mut csv = String::from("time_s,ax,ay,az\n");
    for i in 0..log.channels[0].1.len() {
        let v: Vec<String> = log.channels.iter().map(|(_, x)| x[i].to_string()).collect();
        csv += &format!("{},{}\n", i as f64 / log.sample_rate_hz, v.join(","));
    }
    let accel = dir.path().join("accel.csv");
    std::fs::write(&accel, csv).unwrap();
    let out = dir.path().join("gap");
    let o = vmt(&[
        "gap",
        "--model",
        model.to_str().unwrap(),
        "--real",
        accel.to_str().unwrap(),
        "--json",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let step = &r["gap"]["steps"][0];
    assert_eq!(step["effect"], "tool_mode_x1", "{r:#}");
    let f = step["values"][1]["value"].as_f64().unwrap();
    assert!((f - 885.0).abs() < 4.0, "fitted {f} Hz");
    assert!(out.join("band_levels.png").exists());
    // The residual spectra open with the Rerun SDK's own reader.
    let rrd = python::python("read_rrd.py", &out.join("gap.rrd"));
    for axis in ["ax", "ay", "az"] {
        for when in ["before", "after"] {
            let e = format!("/vibration/residual_db/{axis}/{when}");
            assert!(rrd["entities"][e.as_str()].is_object(), "{e}: {rrd:#}");
        }
    }
    // Ball-bar traces and accelerometer logs are not one analysis.
    let trace = write_csv(dir.path(), "trace.csv", &traces(50.0, &Errors::default()));
    let o = vmt(&[
        "gap",
        "--model",
        model.to_str().unwrap(),
        "--real",
        accel.to_str().unwrap(),
        trace.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("trace.csv: not an accelerometer log"),
        "{}",
        stderr(&o)
    );
}

/// The built-in machine's ISO 230-4 XY test as `vmt demo` runs it (150 mm, 1000 mm/min, CW
/// and CCW), simulated, with an ideal lost motion of X added by this test's own code: the
/// carriage lags its command by half the gap against its motion, `Δx = −(b/2)·sign(v_x)`,
/// which the bar reads as `Δx·cos θ`: the textbook backlash, a step of `b` at the X reversals
/// with no take-up, no friction and no elastic stretch.
fn demo_with_lost_motion(dir: &Path, b_um: f64) -> PathBuf {
    let text = vmt_scenario::BUILTIN_DEFAULT;
    let s = vmt_scenario::parse(text, "vmc500.toml", None).unwrap();
    let e = s.execution.as_ref().unwrap();
    let run = e.simulate(&s.machine, text, &mut |_| {}).unwrap();
    let mut csv = String::from("angle_deg,deviation_um,direction,time_s\n");
    for t in &run.ballbar {
        let a = &t.angle_deg;
        for i in 0..a.len() {
            let (j, k) = if i + 1 < a.len() {
                (i, i + 1)
            } else {
                (i - 1, i)
            };
            let v_x = a[k].to_radians().cos() - a[j].to_radians().cos();
            let dx = -0.5 * b_um * v_x.signum();
            let d = t.deviation_um[i] + dx * a[i].to_radians().cos();
            csv += &format!("{},{d},{},{}\n", a[i], t.direction, t.times_s[i]);
        }
    }
    let p = dir.join("demo_lost_motion.csv");
    std::fs::write(&p, csv).unwrap();
    p
}

/// The case: a 3 µm lost motion of X, which an earlier analysis gave to a Coulomb
/// friction of 319 N (6.4 times the model's 50 N). Backlash must come first, or stand in the
/// ambiguity set with a test that tells the two apart; no friction beyond the plausible range
/// (3 times the model's) may be accepted.
#[test]
fn an_ideal_lost_motion_of_x_is_backlash_not_an_implausible_friction() {
    let dir = tempfile::tempdir().unwrap();
    let csv = demo_with_lost_motion(dir.path(), 3.0);
    let model = dir.path().join("vmc500.toml");
    std::fs::write(&model, vmt_scenario::BUILTIN_DEFAULT).unwrap();
    let o = vmt(&[
        "gap",
        "--model",
        model.to_str().unwrap(),
        "--real",
        csv.to_str().unwrap(),
        "--radius-mm",
        "150",
        "--feed-mm-min",
        "1000",
        "--plane",
        "XY",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let effects = r["effects"].as_array().unwrap();
    let first = effects.first().map(|e| e["effect"].as_str().unwrap());
    let alternatives = r["alternatives"].as_array().unwrap();
    let backlash_rival = alternatives
        .iter()
        .any(|a| a["effects"] == serde_json::json!(["backlash_x"]) && a["implausible"].is_null());
    let tested = r["discriminating_tests"]
        .as_array()
        .unwrap()
        .iter()
        .any(|d| d["rival"] == "backlash_x" || d["instead_of"] == "backlash_x");
    assert!(
        first == Some("backlash_x") || (backlash_rival && tested),
        "{r:#}"
    );
    if first == Some("backlash_x") {
        let b = effects[0]["values"][0]["value"].as_f64().unwrap();
        assert!((b - 3.0).abs() < 0.5, "backlash offset {b} um, 3 um added");
    }
    for e in effects.iter().filter(|e| e["effect"] == "friction_x") {
        let offset = e["values"][0]["value"].as_f64().unwrap();
        assert!(
            50.0 + offset <= 150.0,
            "friction X accepted at {} N",
            50.0 + offset
        );
    }
    assert!(r["judged"]["shrink"].as_f64().unwrap() > 0.8, "{r:#}");
}
