//! Every command writes its report to stdout through one mechanism (`vmt_tools::out`): a
//! closed stdout (`vmt ... | head -1`) is an error naming `<stdout>` with exit code 2, never a
//! panic ("failed printing to stdout: Broken pipe", exit 101).

use std::process::Command;

/// Runs `vmt args` with stdout a pipe whose reading end is already closed; returns the exit
/// code and stderr.
fn with_closed_stdout(args: &[&str]) -> (Option<i32>, String) {
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let o = Command::new("timeout")
        .args(["300", env!("CARGO_BIN_EXE_vmt")])
        .args(args)
        .stdout(writer)
        .output()
        .unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn a_closed_stdout_is_an_error_not_a_panic_for_the_report_commands() {
    let dir = tempfile::tempdir().unwrap();
    let d = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let mut csv = String::from("angle_deg,deviation_um,direction\n");
    for i in 0..=720 {
        csv += &format!("{},{:.3},ccw\n", i as f64 * 0.5, (i as f64 * 0.01).sin());
    }
    std::fs::write(d("trace.csv"), csv).unwrap();
    std::fs::write(d("points.csv"), "x_mm,y_mm,z_mm\n100,100,100\n").unwrap();
    let (trace, points, map, thermal, run) =
        (d("trace.csv"), d("points.csv"), d("map"), d("th"), d("run"));
    let commands: Vec<Vec<&str>> = vec![
        vec!["topologies"],
        vec![
            "diagnose",
            &trace,
            "--radius-mm",
            "150",
            "--feed-mm-min",
            "1000",
            "--plane",
            "XY",
        ],
        vec![
            "volumetric",
            "--map",
            "--at-mm",
            "150",
            "--grid",
            "3",
            "--out",
            &map,
        ],
        vec!["volumetric", "--points", &points],
        vec!["thermal", "--out", &thermal],
        vec![
            "program",
            "ballbar",
            "--plane",
            "XY",
            "--radius-mm",
            "150",
            "--feed-mm-min",
            "1000",
        ],
        vec!["run", "--quiet", "--out", &run],
        vec!["lobes", "--out", &map],
    ];
    for args in commands {
        let (code, e) = with_closed_stdout(&args);
        assert!(!e.contains("panicked"), "vmt {args:?} panicked: {e}");
        assert_eq!(code, Some(2), "vmt {args:?}: {e}");
        assert!(e.contains("cannot write <stdout>"), "vmt {args:?}: {e}");
    }
}

/// With stderr closed as well (`vmt ... 2>&1 | head -1`), the error cannot be printed, but the
/// exit code still says so, without a panic (exit 101).
#[test]
fn closed_stdout_and_stderr_still_give_the_error_code() {
    for args in [vec!["topologies"], vec!["thermal", "--every-s", "3600"]] {
        let dir = tempfile::tempdir().unwrap();
        let (r1, w1) = std::io::pipe().unwrap();
        let (r2, w2) = std::io::pipe().unwrap();
        drop((r1, r2));
        let out = dir.path().join("th");
        let mut all = args.clone();
        if args[0] == "thermal" {
            all.extend(["--out", out.to_str().unwrap()]);
        }
        let status = Command::new(env!("CARGO_BIN_EXE_vmt"))
            .args(&all)
            .stdout(w1)
            .stderr(w2)
            .status()
            .unwrap();
        assert_eq!(status.code(), Some(2), "vmt {args:?}");
    }
}
