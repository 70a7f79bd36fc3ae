//! Options that size an allocation are bounded at the command line: a value beyond the range
//! is refused in the unit typed, naming the option and the accepted range, before anything is
//! allocated (no abort on allocation, no unbounded growth).

mod common;

use common::{stderr, vmt};

/// Runs `vmt args`, expects a clean refusal (exit 2, no panic or abort) containing `words`.
fn refused(args: &[&str], words: &[&str]) {
    let o = vmt(args);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "vmt {args:?}: {e}");
    assert!(
        !e.contains("panicked") && !e.contains("memory allocation"),
        "{e}"
    );
    for w in words {
        assert!(e.contains(w), "vmt {args:?}: `{w}` not in: {e}");
    }
}

#[test]
fn ball_bar_radius_and_feed_of_a_csv_trace_are_bounded() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("t.csv");
    let mut text = String::from("angle_deg,deviation_um,direction\n");
    for i in 0..=720 {
        text += &format!("{},0,ccw\n", i as f64 * 0.5);
    }
    std::fs::write(&csv, text).unwrap();
    let f = csv.to_str().unwrap();
    let setup = |r: &'static str, v: &'static str| {
        let mut a = vec![
            "--radius-mm",
            "150",
            "--feed-mm-min",
            "1000",
            "--plane",
            "XY",
        ];
        let i = a.iter().position(|x| *x == r).unwrap();
        a[i + 1] = v;
        a
    };
    for (option, value) in [
        ("--radius-mm", "1e7"),
        ("--radius-mm", "1e9"),
        ("--radius-mm", "0"),
    ] {
        let mut args = vec!["diagnose", f];
        args.extend(setup(option, value));
        refused(
            &args,
            &[option, "from 1 to 1500 mm is accepted", "ball bars"],
        );
    }
    let mut args = vec!["diagnose", f];
    args.extend(setup("--feed-mm-min", "1e-300"));
    refused(&args, &["--feed-mm-min", "mm/min is accepted"]);
    let mut args = vec!["gap", "--model", "x.toml", "--real", f];
    args.extend(setup("--radius-mm", "1e7"));
    refused(&args, &["--radius-mm", "1500 mm"]);
    // The largest bar is diagnosed.
    let mut args = vec!["diagnose", f];
    args.extend(setup("--radius-mm", "1500"));
    let o = vmt(&args);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn chatter_compensate_and_bench_are_bounded() {
    refused(
        &["chatter", "compensate", "--spindle-rpm", "1e9"],
        &["--spindle-rpm 1000000000", "from 100 to 60000 rpm"],
    );
    refused(
        &["chatter", "compensate", "--duration-s", "1000"],
        &["--duration-s 1000", "from 0.1 to 20 s"],
    );
    refused(
        &[
            "chatter",
            "bench",
            "--speeds",
            "100",
            "--depths",
            "100",
            "--duration-s",
            "1",
        ],
        &[
            "--speeds 100 x --depths 100",
            "10000 s of cut",
            "at most 2000 s",
        ],
    );
    refused(
        &["chatter", "bench", "--duration-s", "1e6"],
        &["--duration-s"],
    );
}

#[test]
fn lobes_grids_are_bounded_and_named() {
    refused(
        &["lobes", "--speeds", "100000000"],
        &["--speeds 100000000", "from 2 to 5000"],
    );
    refused(
        &["lobes", "--depths", "1"],
        &["--depths 1", "from 2 to 2000"],
    );
    refused(&["lobes", "--sd-steps", "100000"], &["--sd-steps 100000"]);
    refused(
        &[
            "lobes",
            "--speed-min-rpm",
            "9000",
            "--speed-max-rpm",
            "8000",
        ],
        &["--speed-min-rpm 9000 must be below --speed-max-rpm 8000"],
    );
}

#[test]
fn gap_bench_settings_are_bounded() {
    refused(
        &["gap-bench", "--nuisance=-0.1", "--quiet"],
        &["--nuisance -0.1: from 0 to 1"],
    );
    refused(
        &["gap-bench", "--repeats", "0", "--quiet"],
        &["--repeats 0: from 1 to 100"],
    );
    refused(
        &["gap-bench", "--nulls", "100000", "--quiet"],
        &["--nulls 100000: from 0 to 1000"],
    );
    // The test's radius and feed are the options', not a line of the model's scenario.
    refused(
        &["gap-bench", "--radius-mm", "0", "--quiet"],
        &["--radius-mm 0: from 50 to 600 mm"],
    );
    // Each of several radii is checked, and their count.
    refused(
        &["gap-bench", "--radius-mm", "100,40", "--quiet"],
        &["--radius-mm 40: from 50 to 600 mm"],
    );
    refused(
        &[
            "gap-bench",
            "--radius-mm",
            "60,70,80,90,100,110,120,130,140",
            "--quiet",
        ],
        &["--radius-mm: 9 radii given; 1 to 8 are accepted"],
    );
    refused(
        &["gap-bench", "--feed-mm-min", "1e9", "--quiet"],
        &["--feed-mm-min 1000000000: from 0.1 to 100000 mm/min"],
    );
    // The second centre's shift: two numbers within a machine's travel; one that takes the
    // circles past a stroke is refused by the model's scenario, at the centre's key.
    refused(
        &["gap-bench", "--center-shift-mm", "80", "--quiet"],
        &["--center-shift-mm: two numbers are accepted", "; 1 given"],
    );
    refused(
        &["gap-bench", "--center-shift-mm", "80,5000", "--quiet"],
        &["--center-shift-mm 5000: from -1000 to 1000 mm"],
    );
    refused(
        &["gap-bench", "--center-shift-mm", "-200,0", "--quiet"],
        &["job.center_mm", "beyond its stroke"],
    );
}

#[test]
fn the_better_detectors_tuning_in_chatter_bench_is_bounded() {
    refused(
        &["chatter", "bench", "--developed-share", "2"],
        &["--developed-share 2: from 0 to 1"],
    );
    refused(
        &["chatter", "bench", "--growth", "0.5"],
        &["--growth 0.5: from 1 to 1000000"],
    );
    refused(
        &["chatter", "bench", "--growth-window-s", "5"],
        &["--growth-window-s 5: from 0 to 0.4 s"],
    );
}
