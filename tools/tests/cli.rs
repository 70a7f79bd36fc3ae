//! The `vmt` binary end to end: outputs that match the library, and one clear error per bad input.

use std::path::Path;
mod common;

use common::{stderr, vmt};
use std::process::Output;

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

fn rows(o: &Output) -> Vec<Vec<f64>> {
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect()
}

/// The library's volumetric error (µm) of the built-in machine at `mm` with every axis in
/// `direction`, at node temperatures `temps`.
fn library_um(mm: [f64; 3], direction: vmt_model::Direction, temps: &[f64]) -> [f64; 3] {
    let s = vmt_scenario::builtin().unwrap();
    let state =
        vmt_model::kinematics::AxisState::new(nalgebra::Vector3::from(mm) * 1e-3, direction);
    let e = s.machine.volumetric_error(&state, temps).unwrap() * 1e6;
    [e.x, e.y, e.z]
}

/// `got` and `want` (µm) agree to 1e-6 µm: the CLI prints six decimals, rounding by 5e-7 µm.
fn assert_um(got: &[f64], want: [f64; 3], what: &str) {
    assert_eq!(got.len(), 3, "{what}: {got:?}");
    for k in 0..3 {
        assert!(
            (got[k] - want[k]).abs() < 1e-6,
            "{what}: {got:?} vs {want:?}"
        );
    }
}

#[test]
fn points_give_the_library_errors_and_reversal_shows_the_backlash() {
    let dir = tempfile::tempdir().unwrap();
    let csv = write(
        dir.path(),
        "p.csv",
        "x_mm,y_mm,z_mm,direction_x\n250,200,150,1\n250,200,150,-1\n0,0,0,1\n",
    );
    let o = vmt(&["volumetric", "--points", &csv]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r = rows(&o);
    assert_eq!(r.len(), 3);
    let s = vmt_scenario::builtin().unwrap();
    let temps = vec![20.0; 6];
    for (row, sign) in r.iter().zip([1, -1]) {
        let state = vmt_model::kinematics::AxisState {
            position: nalgebra::Vector3::new(0.25, 0.2, 0.15),
            direction: [
                vmt_model::Direction::from_sign(sign).unwrap(),
                vmt_model::Direction::Forward,
                vmt_model::Direction::Forward,
            ],
        };
        let e = s.machine.volumetric_error(&state, &temps).unwrap() * 1e6;
        for k in 0..3 {
            assert!((row[k] - e[k]).abs() < 1e-6, "{row:?} vs {e:?}");
        }
    }
    // Reversing X: the built-in 2 µm EXX backlash, plus 1.5 µrad of ECX (yaw) backlash turning
    // the lever y = 200 mm about +Z, which moves the tool by -1.5 µrad * 0.2 m = -0.3 µm in X.
    let reversal = r[1][0] - r[0][0];
    assert!(
        (reversal - (2.0 - 1.5 * 0.2)).abs() < 1e-5,
        "ΔX reversal {reversal} µm"
    );
}

#[test]
fn json_output_has_one_object_per_point() {
    let dir = tempfile::tempdir().unwrap();
    let csv = write(
        dir.path(),
        "p.csv",
        "z_mm,y_mm,x_mm\n10,20,30\n400,400,500\n",
    );
    let out = dir.path().join("e.json");
    let o = vmt(&[
        "volumetric",
        "--points",
        &csv,
        "--json",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out).unwrap()).unwrap();
    let arr = v.as_array().unwrap();
    assert_eq!(arr.len(), 2);
    assert!(arr[1]["dx_um"].as_f64().unwrap().abs() > 0.1);
    // The columns are read by name: the first row is x = 30, y = 20, z = 10 mm. JSON carries
    // the full double, so the objects equal the library's errors (forward, 20 °C) to rounding.
    for (obj, mm) in arr.iter().zip([[30.0, 20.0, 10.0], [500.0, 400.0, 400.0]]) {
        let got: Vec<f64> = ["dx_um", "dy_um", "dz_um"]
            .iter()
            .map(|k| obj[k].as_f64().unwrap())
            .collect();
        let want = library_um(mm, vmt_model::Direction::Forward, &[20.0; 6]);
        assert_um(&got, want, &format!("{mm:?}"));
    }
}

#[test]
fn time_in_the_thermal_run_warms_the_machine() {
    let dir = tempfile::tempdir().unwrap();
    let csv = write(
        dir.path(),
        "p.csv",
        "x_mm,y_mm,z_mm,time_s\n250,200,200,0\n250,200,200,10800\n",
    );
    let o = vmt(&["volumetric", "--points", &csv]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r = rows(&o);
    // After 3 h of warm-up the spindle head has grown down: ΔZ falls by more than 10 µm.
    assert!(r[1][2] - r[0][2] < -10.0, "{r:?}");
    // Each row is the library's error at the thermal run's node temperatures at its time.
    let s = vmt_scenario::builtin().unwrap();
    let (thermal, run) = (
        s.machine.thermal.as_ref().unwrap(),
        s.thermal_run.as_ref().unwrap(),
    );
    let temps = vmt_model::thermal::temperatures_at(
        &thermal.network,
        &run.schedule,
        run.step_s,
        &[0.0, 10800.0],
    )
    .unwrap();
    assert_eq!((r.len(), temps.len()), (2, 2));
    for (row, t) in r.iter().zip(&temps) {
        let want = library_um([250.0, 200.0, 200.0], vmt_model::Direction::Forward, t);
        assert_um(row, want, &format!("at {t:?} °C"));
    }
}

#[test]
fn a_missing_column_is_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let csv = write(dir.path(), "p.csv", "x_mm,y_mm\n1,2\n");
    let o = vmt(&["volumetric", "--points", &csv]);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(e.contains("p.csv:1: missing column z_mm"), "{e}");
    assert!(e.contains("accepted columns"), "{e}");
    let csv = write(dir.path(), "d.csv", "x_mm,y_mm,z_mm,y_mm\n1,2,3,4\n");
    let e = stderr(&vmt(&["volumetric", "--points", &csv]));
    assert!(
        e.contains("d.csv:1: column `y_mm` is given twice (columns 2 and 4)"),
        "{e}"
    );
    let header = "x_mm,y_mm,z_mm,temp_spindle_c,temp_column_c,temp_bed_c,temp_x_screw_c,temp_y_screw_c,temp_z_screw_c";
    let csv = write(
        dir.path(),
        "t.csv",
        &format!("{header}\n1,2,3,20,20,20,20,20,900\n"),
    );
    let e = stderr(&vmt(&["volumetric", "--points", &csv]));
    assert!(
        e.contains(
            "t.csv:2: temp_z_screw_c = 900 °C; a temperature from -50 to 150 °C is accepted"
        ),
        "{e}"
    );
}

#[test]
fn nan_and_bad_directions_are_refused_with_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let csv = write(dir.path(), "p.csv", "x_mm,y_mm,z_mm\n1,2,3\n1,NaN,3\n");
    let e = stderr(&vmt(&["volumetric", "--points", &csv]));
    assert!(
        e.contains("p.csv:3: column y_mm: `NaN` is not a finite number"),
        "{e}"
    );
    let csv = write(dir.path(), "q.csv", "x_mm,y_mm,z_mm,direction_y\n1,2,3,0\n");
    let e = stderr(&vmt(&["volumetric", "--points", &csv]));
    assert!(
        e.contains("q.csv:2: direction_y = 0; accepted: +1 (forward) or -1 (backward)"),
        "{e}"
    );
}

#[test]
fn points_beyond_the_stroke_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let csv = write(dir.path(), "p.csv", "x_mm,y_mm,z_mm\n520,0,0\n");
    let e = stderr(&vmt(&["volumetric", "--points", &csv]));
    assert!(
        e.contains("p.csv:2: x_mm = 520 mm is outside the X stroke 0 to 500 mm"),
        "{e}"
    );
}

#[test]
fn a_bad_scenario_is_refused_with_file_line_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let text = vmt_scenario::BUILTIN_DEFAULT.replace("topology = \"WXYGZT\"", "topology = \"XYZ\"");
    let scenario = write(dir.path(), "m.toml", &text);
    let csv = write(dir.path(), "p.csv", "x_mm,y_mm,z_mm\n1,2,3\n");
    let e = stderr(&vmt(&["volumetric", &scenario, "--points", &csv]));
    let line = text
        .lines()
        .position(|l| l.starts_with("topology"))
        .unwrap()
        + 1;
    assert!(
        e.contains(&format!(
            "m.toml:{line}:12: key `machine.topology`: unknown topology `XYZ`"
        )),
        "{e}"
    );
}

#[test]
fn the_map_writes_csv_and_a_png_for_both_approaches() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let o = vmt(&[
        "volumetric",
        "--map",
        "--plane",
        "xz",
        "--at-mm",
        "200",
        "--grid",
        "5",
        "--out",
        out,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = std::fs::read_to_string(dir.path().join("volumetric_xz_y200mm.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 2 * 25);
    assert!(
        csv.lines()
            .nth(1)
            .unwrap()
            .starts_with("forward,0.000,200.000,0.000,")
    );
    // Forward then backward; Z (the plane's second axis) outer, X inner; 5 points over the
    // strokes: X 0, 125, ..., 500 mm, Z 0, 100, ..., 400 mm, Y held at 200 mm. Each row's
    // errors are the library's at that point, every axis approaching in that direction, 20 °C.
    let mut lines = csv.lines().skip(1);
    for (name, direction) in [
        ("forward", vmt_model::Direction::Forward),
        ("backward", vmt_model::Direction::Backward),
    ] {
        for iz in 0..5 {
            for ix in 0..5 {
                let mm = [125.0 * ix as f64, 200.0, 100.0 * iz as f64];
                let line = lines.next().unwrap();
                let (approach, numbers) = line.split_once(',').unwrap();
                assert_eq!(approach, name, "{line}");
                let v: Vec<f64> = numbers.split(',').map(|x| x.parse().unwrap()).collect();
                assert_eq!(v[..3], mm, "{line}");
                assert_um(&v[3..], library_um(mm, direction, &[20.0; 6]), line);
            }
        }
    }
    let png = std::fs::read(dir.path().join("volumetric_xz_y200mm.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let e = stderr(&vmt(&[
        "volumetric",
        "--map",
        "--plane",
        "xy",
        "--at-mm",
        "450",
        "--out",
        out,
    ]));
    assert!(
        e.contains("--at-mm 450 is outside the Z stroke 0 to 400 mm"),
        "{e}"
    );
}

#[test]
fn times_beyond_the_evaluated_range_are_refused_not_run_forever() {
    let dir = tempfile::tempdir().unwrap();
    let csv = write(dir.path(), "p.csv", "x_mm,y_mm,z_mm,time_s\n1,2,3,1e300\n");
    let e = stderr(&vmt(&["volumetric", "--points", &csv]));
    assert!(
        e.contains("p.csv:2: time_s = 1e300; a time from 0 to 1e7 s"),
        "{e}"
    );
    // Within that range but after the built-in thermal run (8 h): refused at its line, as
    // --time-h is.
    let csv = write(
        dir.path(),
        "late.csv",
        "x_mm,y_mm,z_mm,time_s\n1,2,3,28800\n\n1,2,3,28801\n",
    );
    let e = stderr(&vmt(&["volumetric", "--points", &csv]));
    assert!(
        e.contains("late.csv:4: time_s = 28801 s: the scenario's thermal run lasts 28800 s"),
        "{e}"
    );
    let e = stderr(&vmt(&[
        "thermal",
        "--every-s",
        "1e-12",
        "--out",
        dir.path().to_str().unwrap(),
    ]));
    assert!(e.contains("up to 1 000 000 are accepted"), "{e}");
}

#[test]
fn demo_takes_no_scenario() {
    let o = vmt(&["demo", "/nonexistent.toml"]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(e.contains("unexpected argument '/nonexistent.toml'"), "{e}");
    let help = String::from_utf8_lossy(&vmt(&["demo", "--help"]).stdout).into_owned();
    assert!(
        help.contains("Takes no scenario") && !help.contains("[SCENARIO]"),
        "{help}"
    );
}

#[test]
fn help_defaults_and_plane_spellings_agree_with_what_is_accepted() {
    let help = |args: &[&str]| String::from_utf8_lossy(&vmt(args).stdout).into_owned();
    // The default of --probe-mm is shown in the form that is accepted.
    let h = help(&["thermal", "--help"]);
    assert!(h.contains("[default: 250,200,200]"), "{h}");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let o = vmt(&["thermal", "--probe-mm", "250,200,200", "--out", out]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Not every run draws a polar plot.
    let h = help(&["run", "--help"]);
    assert!(h.contains("a polar plot per circular test"), "{h}");
    assert!(
        h.contains("ballbar_polar_<n>_<plane>_<radius>mm.png"),
        "{h}"
    );
    // One plane parser: zx is the xz map, as diagnose, program and gap accept it.
    for plane in ["zx", "XZ", "G18"] {
        let o = vmt(&[
            "volumetric",
            "--map",
            "--plane",
            plane,
            "--at-mm",
            "100",
            "--grid",
            "3",
            "--out",
            out,
        ]);
        assert!(o.status.success(), "--plane {plane}: {}", stderr(&o));
        assert!(String::from_utf8_lossy(&o.stdout).contains("on the xz plane"));
    }
    let e = stderr(&vmt(&[
        "volumetric",
        "--map",
        "--plane",
        "xx",
        "--at-mm",
        "100",
    ]));
    assert!(e.contains("the plane is XY, ZX (or XZ) or YZ"), "{e}");
    let o = vmt(&[
        "program",
        "ballbar",
        "--plane",
        "xz",
        "--radius-mm",
        "100",
        "--feed-mm-min",
        "1000",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn compensate_depth_is_refused_in_mm() {
    let e = stderr(&vmt(&["chatter", "compensate", "--depth-mm=-0.3"]));
    assert!(e.contains("--depth-mm -0.3: must be > 0"), "{e}");
    assert!(!e.contains("0.0003"), "{e}");
}

/// The largest thermal drift is taken over every step of the run, so it does not depend on how
/// often the history is sampled (it read 21.61 µm at 60 s and 20.77 µm at 7200 s).
#[test]
fn the_largest_thermal_drift_does_not_depend_on_the_sampling() {
    let dir = tempfile::tempdir().unwrap();
    let largest = |every: &str| {
        let out = dir.path().join(every);
        let o = vmt(&[
            "thermal",
            "--every-s",
            every,
            "--format",
            "svg",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let text = String::from_utf8_lossy(&o.stdout).to_string();
        text.lines()
            .find(|l| l.contains("largest drift"))
            .unwrap_or_else(|| panic!("{text}"))
            .to_string()
    };
    // 7 s is off the run's 10 s grid: its samples are not steps of the run.
    let (fine, coarse, off) = (largest("60"), largest("7200"), largest("7"));
    assert_eq!(fine, coarse);
    assert_eq!(fine, off);
    assert!(fine.contains("µm (at "), "{fine}");
}

#[test]
fn a_time_beyond_the_thermal_run_is_refused() {
    let e = stderr(&vmt(&[
        "volumetric",
        "--map",
        "--plane",
        "xy",
        "--at-mm",
        "200",
        "--time-h",
        "100",
    ]));
    assert!(
        e.contains("--time-h 100: the scenario's thermal run lasts 8 h"),
        "{e}"
    );
}
