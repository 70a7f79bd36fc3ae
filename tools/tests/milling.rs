//! A milling job end to end: `vmt run` on scenarios/milling_slot.toml (the NC program through
//! the controller and feed drives, the cut with regenerative chatter), then `vmt chatter
//! detect` on the run's MCAP, for a depth above the stability limit and one below it.

mod common;
#[path = "common/python.rs"]
mod python;

use common::{stderr, vmt};
use std::path::{Path, PathBuf};

/// The shipped slot scenario at `depth_mm`, written with its program into `dir`.
fn scenario(dir: &Path, depth_mm: f64) -> PathBuf {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios");
    let text = std::fs::read_to_string(format!("{root}/milling_slot.toml")).unwrap();
    let text = text.replace(
        "axial_depth_mm = 0.5",
        &format!("axial_depth_mm = {depth_mm}"),
    );
    std::fs::create_dir_all(dir.join("milling")).unwrap();
    std::fs::copy(
        format!("{root}/milling/slot.nc"),
        dir.join("milling/slot.nc"),
    )
    .unwrap();
    let p = dir.join("slot.toml");
    std::fs::write(&p, text).unwrap();
    p
}

/// Runs the slot at `depth_mm`: (ground truth, `vmt run`'s summary, `vmt chatter detect`'s
/// report).
fn run(dir: &Path, depth_mm: f64) -> (serde_json::Value, String, String) {
    let s = scenario(dir, depth_mm);
    let out = dir.join("out");
    let o = vmt(&[
        "run",
        s.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let summary = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        !summary.contains("NaN") && !summary.contains("null") && !summary.contains("backlash"),
        "{summary}"
    );
    let truth = std::fs::read_to_string(out.join("ground_truth.json")).unwrap();
    let d = vmt(&[
        "chatter",
        "detect",
        out.join("run.mcap").to_str().unwrap(),
        "--detector",
        "better",
    ]);
    assert!(d.status.success(), "{}", stderr(&d));
    (
        serde_json::from_str(&truth).unwrap(),
        summary,
        String::from_utf8_lossy(&d.stdout).into_owned(),
    )
}

#[test]
fn a_slot_beyond_the_limit_chatters_near_the_mode_and_is_detected() {
    let dir = tempfile::tempdir().unwrap();
    let (truth, summary, detect) = run(dir.path(), 0.5);
    let m = &truth["milling"];
    // The summary prints the milling truth: chatter onset and frequency, the surface.
    // On the job's clock, as the log's times (and the cut's own).
    let onset = m["chatter_onset_s"].as_f64().unwrap();
    let cut_start = truth["cut_start_s"].as_f64().unwrap();
    assert!(
        cut_start > 0.5,
        "the cut starts after the approach: {cut_start} s"
    );
    let said = format!(
        "truth: chatter from {:.3} s ({onset:.3} s into the cut) at {:.1} Hz (15000 rpm, 2 teeth: tooth passing 500.0 Hz)",
        cut_start + onset,
        m["chatter_frequency_hz"].as_f64().unwrap()
    );
    assert!(summary.contains(&said), "`{said}` not in {summary}");
    let ra = format!(
        "truth: surface Ra {:.3} um, Rz ",
        m["ra_um"].as_f64().unwrap()
    );
    assert!(
        summary.contains(&ra) && summary.contains("SLE mean"),
        "{summary}"
    );
    assert_eq!(m["chatter"], true, "{m:#}");
    // Regenerative chatter just above the 922 Hz mode, away from the 500 Hz tooth passing.
    let f = m["chatter_frequency_hz"].as_f64().unwrap();
    assert!((f - 930.0).abs() < 40.0, "chatter at {f} Hz");
    assert_eq!(m["spindle_rpm"], 15000.0);
    assert!(
        (m["feed_per_tooth_mm"].as_f64().unwrap() - 0.1).abs() < 1e-9,
        "F3000 S15000 on two teeth"
    );
    // The recording shows the cut: accelerometers, forces, deflection, spindle and feed
    // override over time, beside the drives' following errors (it had held only the boxes).
    let rrd = python::python("read_rrd.py", &dir.path().join("out/run.rrd"));
    let e = &rrd["entities"];
    for entity in [
        "/series/accelerometer_m_s_2/ax",
        "/series/accelerometer_m_s_2/ay",
        "/series/cutting_N/fx",
        "/series/cutting_m/uy",
        "/series/cutting_rpm/spindle_rpm",
        "/series/servo_1/feed_override",
        "/series/following_error_um/x",
    ] {
        let rows = e[entity]["rows"].as_u64().unwrap_or(0);
        assert!(rows > 1000, "{entity}: {rows} rows in {}", e);
    }
    // The detectors report on the log's clock too: soon after the onset (within a frame of
    // 0.1 s, which resolves the 250 Hz spindle's orders, and two hops), not 1 s before the cut
    // as when they counted from the first accelerometer sample.
    let at = detect
        .lines()
        .find_map(|l| l.split("better:   CHATTER at ").nth(1))
        .and_then(|r| r.split(' ').next())
        .and_then(|t| t.parse::<f64>().ok())
        .unwrap_or_else(|| panic!("{detect}"));
    assert!(
        at > cut_start + onset && at < cut_start + onset + 0.2,
        "detected at {at} s, onset {} s: {detect}",
        cut_start + onset
    );
}

#[test]
fn a_slot_below_the_limit_is_stable_and_not_flagged() {
    let dir = tempfile::tempdir().unwrap();
    let (truth, summary, detect) = run(dir.path(), 0.2);
    assert_eq!(truth["milling"]["chatter"], false, "{truth:#}");
    assert!(
        summary.contains("truth: no chatter (15000 rpm"),
        "{summary}"
    );
    assert!(!detect.contains("CHATTER"), "{detect}");
}

/// The feed per tooth of the program's first cutting block, and a program with none, are
/// refused at load naming the program file (and its line), not when the cut starts.
#[test]
fn a_program_whose_cut_cannot_be_milled_is_refused_at_its_line() {
    let dir = tempfile::tempdir().unwrap();
    let s = scenario(dir.path(), 0.2);
    let nc = dir.path().join("milling/slot.nc");
    let program = std::fs::read_to_string(&nc).unwrap();
    let refused = |text: &str| {
        std::fs::write(&nc, text).unwrap();
        let out = dir.path().join("out");
        let o = vmt(&["run", s.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        assert!(!o.status.success());
        stderr(&o)
    };
    let e = refused(&program.replace("S15000", "S1"));
    assert!(
        e.contains("slot.nc:5:1: the first cutting block's feed per tooth F / (N·S) = 3000 / (2 × 1) = 1500 mm"),
        "{e}"
    );
    let e = refused(&program.replace("G1 X210 F3000", "G0 X210"));
    assert!(
        e.contains("slot.nc: the milling program has no cutting block"),
        "{e}"
    );
}

/// `vmt run --diagnose` of a milling job does what `vmt chatter detect` does on the run's
/// accelerometers: the same report, printed and in DIR/diagnosis/report.txt, and the
/// per-window figures of `--csv` in DIR/diagnosis/chatter.csv.
#[test]
fn run_diagnose_of_a_milling_job_detects_chatter_as_chatter_detect_does() {
    let dir = tempfile::tempdir().unwrap();
    let s = scenario(dir.path(), 0.5);
    let out = dir.path().join("out");
    let o = vmt(&[
        "run",
        s.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
        "--diagnose",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let printed = String::from_utf8_lossy(&o.stdout).into_owned();
    let csv = dir.path().join("detect.csv");
    let mcap = out.join("run.mcap");
    let d = vmt(&[
        "chatter",
        "detect",
        mcap.to_str().unwrap(),
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert!(d.status.success(), "{}", stderr(&d));
    let detect = String::from_utf8_lossy(&d.stdout).into_owned();
    let report = detect
        .lines()
        .filter(|l| !l.starts_with("wrote "))
        .collect::<Vec<_>>();
    let report = report.join("\n") + "\n";
    assert!(
        report.contains("kim:") && report.contains("better:"),
        "{report}"
    );
    assert!(printed.contains(&report), "{printed}\n---\n{report}");
    let diagnosis = out.join("diagnosis");
    assert_eq!(
        std::fs::read_to_string(diagnosis.join("report.txt")).unwrap(),
        report
    );
    assert_eq!(
        std::fs::read(diagnosis.join("chatter.csv")).unwrap(),
        std::fs::read(&csv).unwrap()
    );
}
