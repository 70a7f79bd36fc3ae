//! Every command writes its report to stdout through one mechanism (`vmt_tools::out`): a
//! closed stdout (`vmt ... | head -1`) is an error naming `<stdout>` with exit code 2, never a
//! panic ("failed printing to stdout: Broken pipe", exit 101).

use std::process::Command;

/// A pipe whose reading end is already closed: writing to it fails with a broken pipe.
fn closed_pipe() -> std::io::PipeWriter {
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    writer
}

/// `vmt args` under coreutils `timeout`, as the other CLI tests run it.
fn vmt_command(args: &[&str]) -> Command {
    let mut c = Command::new("timeout");
    c.args(["300", env!("CARGO_BIN_EXE_vmt")]).args(args);
    c
}

/// Runs `vmt args` with stdout a closed pipe; returns the exit code and stderr.
fn with_closed_stdout(args: &[&str]) -> (Option<i32>, String) {
    let o = vmt_command(args).stdout(closed_pipe()).output().unwrap();
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
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("th");
    let thermal = [
        "thermal",
        "--every-s",
        "3600",
        "--out",
        out.to_str().unwrap(),
    ];
    for args in [&["topologies"][..], &thermal] {
        let status = vmt_command(args)
            .stdout(closed_pipe())
            .stderr(closed_pipe())
            .status()
            .unwrap();
        assert_eq!(status.code(), Some(2), "vmt {args:?}");
    }
}
