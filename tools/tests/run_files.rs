//! `vmt run` end to end: one clear error per bad job, and byte-identical MCAP files for the same
//! scenario and seed.

use std::path::Path;
mod common;
#[path = "common/python.rs"]
mod python;

use common::{stderr, vmt};

/// The built-in scenario with its `[job]` section replaced by `job` and every `(from, to)`
/// text replacement applied, written to `dir/name`.
fn scenario(dir: &Path, name: &str, job: &str, edits: &[(&str, &str)]) -> String {
    let text = vmt_scenario::BUILTIN_DEFAULT;
    let start = text.find("[job]").unwrap();
    let end = text.find("[instruments.ballbar]").unwrap();
    let mut out = format!("{}{job}\n\n{}", &text[..start], &text[end..]);
    for (from, to) in edits {
        assert!(out.contains(from), "{from}");
        out = out.replace(from, to);
    }
    let p = dir.join(name);
    std::fs::write(&p, out).unwrap();
    p.display().to_string()
}

/// `vmt run` on a program job whose file `bad.nc` holds `program`: exit code, stderr and
/// whether a recording was written.
fn run_program(program: &str, edits: &[(&str, &str)]) -> (Option<i32>, String, bool) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("bad.nc"), program).unwrap();
    let job = "[job]\nkind = \"program\"\nprogram = \"bad.nc\"";
    let s = scenario(dir.path(), "s.toml", job, edits);
    let out = dir.path().join("out");
    let o = vmt(&["run", &s, "--out", out.to_str().unwrap(), "--quiet"]);
    (o.status.code(), stderr(&o), out.join("run.mcap").exists())
}

/// The program starts with the axes at 0; tool length 100 mm, so the tool point is at Z -100.
const MOVE: &str = "G0 X100 Y100 Z0\n";

#[test]
fn malformed_gcode_names_file_line_and_column() {
    let (code, e, written) = run_program(&format!("{MOVE}G1 X110 F500\nG1 X1..2\n"), &[]);
    assert_ne!(code, Some(0));
    assert!(!written);
    assert!(e.contains("bad.nc:3:7: "), "{e}");
    assert!(e.contains("`.2`"), "{e}");
}

#[test]
fn an_arc_whose_end_is_off_its_circle_is_refused() {
    let (_, e, written) = run_program(&format!("{MOVE}G3 X90 Y110.01 I-10 F500\n"), &[]);
    assert!(!written);
    assert!(
        e.contains("bad.nc:2:1: the end point is not on the arc's circle"),
        "{e}"
    );
    assert!(e.contains("10.0000 mm") && e.contains("10.0100 mm"), "{e}");
}

#[test]
fn a_zero_feed_is_refused() {
    let (_, e, written) = run_program(&format!("{MOVE}F0\nG1 X110\n"), &[]);
    assert!(!written);
    assert!(
        e.contains("bad.nc:2:1: F0: the feed must be > 0 (mm/min)"),
        "{e}"
    );
}

#[test]
fn travel_beyond_a_stroke_is_refused_before_the_run() {
    let (_, e, written) = run_program(&format!("{MOVE}G1 X300 F2000\nG1 X520\n"), &[]);
    assert!(!written, "refused before the run");
    assert!(
        e.contains("bad.nc:3: block at line 3: the X axis would reach 520.000 mm"),
        "{e}"
    );
    assert!(e.contains("beyond its stroke 0 to 500 mm"), "{e}");
}

/// A program longer than the interpolator holds is refused at the file and line of the block
/// that passes the limit, in whole seconds (it printed `600001.1140000001 s` without the file).
#[test]
fn a_program_too_long_names_file_and_line_in_whole_seconds() {
    for (block, line) in [("G1 X110 F500\nG1 X101 F0.0001\n", 3), ("G4 P100000\n", 2)] {
        let (code, e, written) = run_program(&format!("{MOVE}{block}"), &[]);
        assert_eq!(code, Some(2), "{e}");
        assert!(!written);
        let at = format!("bad.nc:{line}: the program lasts about ");
        assert!(e.contains(&at), "{e}");
        assert!(
            e.contains("longer than the 16777 s the interpolator holds"),
            "{e}"
        );
        let seconds = e
            .split("lasts about ")
            .nth(1)
            .unwrap()
            .split(' ')
            .next()
            .unwrap();
        assert!(seconds.parse::<u64>().is_ok(), "{seconds}: {e}");
    }
}

/// One 2.5 ms step per servo period is beyond the X screw mode's limit
/// h < (2/ω)(√(1+ζ²) - ζ): k = 180 N/µm on the reduced mass of the 250 kg table and the motor
/// (0.003 kg·m² through a 10 mm lead: 1184 kg), c = 2e4 N·s/m.
#[test]
fn a_step_too_coarse_for_the_stiffest_mode_is_refused_with_the_largest_stable_step() {
    let edits = [
        ("servo_period_us = 125.0", "servo_period_us = 2500.0"),
        ("ipo_period_ms = 1.0", "ipo_period_ms = 2.5"),
    ];
    let (_, e, written) = run_program(&format!("{MOVE}G1 X110 F500\n"), &edits);
    assert!(!written);
    let mm = 0.003 * (std::f64::consts::TAU / 0.01_f64).powi(2);
    let m = mm * 250.0 / (mm + 250.0);
    let (k, c) = (1.8e8, 2e4);
    let (w, z) = ((k / m).sqrt(), c / (2.0 * (k * m).sqrt()));
    let limit_us = 2.0 / w * ((1.0 + z * z).sqrt() - z) * 1e6;
    let expected = format!(
        "a plant step of 2500.00 µs is too coarse for the screw axial mode of the X drive: the \
         largest stable step is {limit_us:.2} µs, and up to half of it ({:.2} µs) is accepted",
        limit_us / 2.0
    );
    assert!(e.contains(&expected), "{e}\nexpected: {expected}");
}

/// A short circular test: a quarter circle of 50 mm at 3000 mm/min, CCW.
const QUARTER_JOB: &str = "[job]\nkind = \"ballbar\"\nplane = \"XY\"\n\
    center_mm = [250.0, 200.0, 200.0]\nradius_mm = 50.0\nfeed_mm_min = 3000.0\narc_deg = 90.0\n\
    directions = [\"ccw\"]";

/// The names in folder `dir`, sorted.
fn names_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// [`QUARTER_JOB`] with the built-in noise and set-up eccentricity; `run` names its output
/// folder.
fn quarter(dir: &Path, seed: u64, run: &str) -> Vec<u8> {
    let name = format!("s{seed}.toml");
    let s = scenario(
        dir,
        &name,
        QUARTER_JOB,
        &[("seed = 1", &format!("seed = {seed}"))],
    );
    let out = dir.join(run);
    let o = vmt(&["run", &s, "--out", out.to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::read(out.join("run.mcap")).unwrap()
}

#[test]
fn the_same_scenario_and_seed_give_byte_identical_mcap_files() {
    let dir = tempfile::tempdir().unwrap();
    let a = quarter(dir.path(), 1, "a");
    let b = quarter(dir.path(), 1, "b");
    assert!(a.len() > 10_000, "{} bytes", a.len());
    assert!(a == b, "two runs of seed 1 differ");
    let c = quarter(dir.path(), 2, "c");
    assert!(a != c, "seeds 1 and 2 give the same file");
}

/// `vmt run` writes its MCAP file block by block while the job runs; the file is byte for byte
/// the one written from the finished run. At the servo rate (8 kHz) the quarter circle with its
/// feed arcs logs about 32 500 rows, four blocks of the simulator's 8192.
#[test]
fn the_mcap_written_while_the_job_runs_equals_the_finished_runs() {
    let dir = tempfile::tempdir().unwrap();
    let edit = ("log_rate_hz = 1000.0", "log_rate_hz = 8000.0");
    let s = scenario(dir.path(), "s.toml", QUARTER_JOB, &[edit]);
    let out = dir.path().join("out");
    let o = vmt(&["run", &s, "--out", out.to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let streamed = std::fs::read(out.join("run.mcap")).unwrap();

    let text = std::fs::read_to_string(&s).unwrap();
    let scenario = vmt_scenario::load(Path::new(&s)).unwrap();
    let run = vmt_tools::job::execute(&scenario, &text, None, true).unwrap();
    let rows = run.streams[0].times_s.len();
    assert!(rows > 3 * 8192, "{rows} rows");
    let whole = dir.path().join("whole.mcap");
    vmt_logs::write_mcap(&run, &whole).unwrap();
    let whole = std::fs::read(whole).unwrap();
    assert!(
        streamed == whole,
        "{} and {} bytes",
        streamed.len(),
        whole.len()
    );
    // The recording is not byte-identical between writes (Rerun's chunk ids), but its entities,
    // row counts, components and first and last values are the finished run's.
    let whole_rrd = dir.path().join("whole.rrd");
    vmt_logs::write_rrd(&run, &whole_rrd).unwrap();
    let (a, b) = (
        python::python("read_rrd.py", &out.join("run.rrd")),
        python::python("read_rrd.py", &whole_rrd),
    );
    assert_eq!(a["entities"], b["entities"]);
    assert_eq!(a["entities"]["/series/following_error_um/x"]["rows"], rows);
    let names = names_in(&out);
    assert_eq!(
        names,
        [
            "ballbar_polar.png",
            "ground_truth.json",
            "run.mcap",
            "run.rrd"
        ]
    );
}

/// A file that cannot be written stops the job with that file's error, and the other file's
/// partial recording is removed.
#[test]
fn a_file_that_cannot_be_written_stops_the_job_and_leaves_nothing_half_written() {
    let dir = tempfile::tempdir().unwrap();
    let s = scenario(dir.path(), "s.toml", QUARTER_JOB, &[]);
    let out = dir.path().join("out");
    // A folder where the MCAP file's partial file goes.
    std::fs::create_dir_all(out.join("run.mcap.partial")).unwrap();
    let o = vmt(&["run", &s, "--out", out.to_str().unwrap(), "--quiet"]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(e.contains("run.mcap") && !e.contains("partial"), "{e}");
    let names = names_in(&out);
    assert_eq!(names, ["run.mcap.partial"], "{e}");
    assert!(out.join("run.mcap.partial").is_dir());
}

/// The two files of a run appear together or not at all: when `run.rrd` cannot take its
/// name (a folder is in the way), the complete `run.mcap` is not left behind either.
#[test]
fn a_run_has_both_files_or_neither() {
    let dir = tempfile::tempdir().unwrap();
    let s = scenario(dir.path(), "s.toml", QUARTER_JOB, &[]);
    let out = dir.path().join("out");
    std::fs::create_dir_all(out.join("run.rrd")).unwrap();
    let o = vmt(&["run", &s, "--out", out.to_str().unwrap(), "--quiet"]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(e.contains("run.rrd"), "{e}");
    let names = names_in(&out);
    assert_eq!(names, ["run.rrd"], "{e}");
}

/// A program feed above the controller's largest runs at that largest, as on a controller, and
/// the run says so, naming the line; the built-in's ball bar, with no DATA markers in the
/// program to record, is noted too.
#[test]
fn a_feed_above_the_controllers_largest_is_noted_at_its_line() {
    let (code, e, written) = run_program(&format!("{MOVE}G1 X300 F50000\nG1 X200 F500\n"), &[]);
    assert_eq!(code, Some(0), "{e}");
    assert!(written);
    assert!(
        e.contains("bad.nc:2: F50000 mm/min is above controller.max_feed_mm_min = 10000 mm/min; the controller runs it at 10000"),
        "{e}"
    );
    assert!(!e.contains("bad.nc:3:"), "{e}");
    assert!(
        e.contains("note: [instruments.ballbar] records nothing: bad.nc marks no data arc"),
        "{e}"
    );
}

#[test]
fn an_output_folder_that_cannot_be_made_is_refused_before_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("taken");
    std::fs::write(&file, "a file, not a folder").unwrap();
    let kwon = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/kwon_seven_step.toml"
    );
    for out in [file.clone(), file.join("sub")] {
        let start = std::time::Instant::now();
        let o = vmt(&["run", kwon, "--out", out.to_str().unwrap(), "--quiet"]);
        // Kwon's seven steps take seconds to simulate; the refusal comes before them.
        let took = start.elapsed().as_secs_f64();
        assert!(!o.status.success());
        assert!(stderr(&o).contains(out.to_str().unwrap()), "{}", stderr(&o));
        assert!(took < 4.0, "refused after {took} s: after the simulation");
    }
}

/// A file that outgrows the file size limit (as on a full disk) stops the job with the
/// operating system's reason under the writer's own error, not the writer's error alone.
/// A milling run writes its MCAP before its .rrd, so the MCAP writer meets the limit first.
#[test]
fn a_write_error_gives_the_operating_systems_reason() {
    let dir = tempfile::tempdir().unwrap();
    let slot = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/milling_slot.toml"
    );
    let out = dir.path().join("out");
    // SIGXFSZ ignored, so the write fails with EFBIG instead of the signal ending the process;
    // 100 KiB is less than the slot's MCAP file.
    let o = std::process::Command::new("bash")
        .arg("-c")
        .arg(format!(
            "trap '' XFSZ; ulimit -f 100; exec timeout 300 {} run {slot} --out {} --quiet",
            env!("CARGO_BIN_EXE_vmt"),
            out.display()
        ))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains(&format!(
            "cannot write {}: I/O error from writing, or reading a compression stream: File too \
             large (os error 27)",
            out.join("run.mcap").display()
        )),
        "{e}"
    );
}

/// Kwon's procedure with `steps` only, written to `dir/kwon.toml`.
fn kwon_steps(dir: &Path, steps: &str) -> String {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/kwon_seven_step.toml"
    ))
    .unwrap();
    let all = "steps = [1, 2, 3, 4, 5, 6, 7]";
    assert!(text.contains(all));
    let p = dir.join("kwon.toml");
    std::fs::write(&p, text.replace(all, &format!("steps = {steps}"))).unwrap();
    p.display().to_string()
}

/// A job of several circular tests gets one polar plot per test (its CW and CCW runs), named
/// by the test's number, plane and radius; a job of one test keeps `ballbar_polar.png`.
#[test]
fn a_job_of_several_tests_gets_one_polar_plot_per_test() {
    let dir = tempfile::tempdir().unwrap();
    let s = kwon_steps(dir.path(), "[5, 7]");
    let out = dir.path().join("out");
    let o = vmt(&["run", &s, "--out", out.to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let polar: Vec<String> = names_in(&out)
        .into_iter()
        .filter(|n| n.ends_with(".png"))
        .collect();
    assert_eq!(
        polar,
        [
            "ballbar_polar_1_xy_100mm.png",
            "ballbar_polar_2_yz_150mm.png"
        ]
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("wrote ") && stdout.contains("ballbar_polar_2_yz_150mm.png"));
    let s = scenario(dir.path(), "one.toml", QUARTER_JOB, &[]);
    let one = dir.path().join("one");
    let o = vmt(&["run", &s, "--out", one.to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(one.join("ballbar_polar.png").is_file());
}

/// A diagnosis that cannot be written fails the command after the run's files are complete,
/// and says so before its error (the note of what it removed had read as a contradiction).
#[test]
fn a_diagnosis_that_cannot_be_written_says_the_run_is_complete() {
    let dir = tempfile::tempdir().unwrap();
    let s = scenario(dir.path(), "s.toml", QUARTER_JOB, &[]);
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    // A file where the diagnosis folder goes.
    std::fs::write(out.join("diagnosis"), "in the way").unwrap();
    let o = vmt(&[
        "run",
        &s,
        "--out",
        out.to_str().unwrap(),
        "--quiet",
        "--diagnose",
    ]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    let note = e.find("its diagnosis failed (below)").expect(&e);
    let error = e.find("error: ").expect(&e);
    assert!(note < error && e[error..].contains("diagnosis"), "{e}");
    assert!(out.join("run.mcap").is_file() && out.join("run.rrd").is_file());
}

/// `vmt run ARGS --out DIR --quiet`, which must succeed; its standard error.
fn run_into(dir: &Path, args: &[&str]) -> String {
    let mut all = args.to_vec();
    all.extend(["--out", dir.to_str().unwrap(), "--quiet"]);
    let o = vmt(&all);
    assert!(o.status.success(), "{}", stderr(&o));
    stderr(&o)
}

/// A reused output folder holds one run's files: vmt's own names that the new run does not
/// write are removed, and a note lists them; a user's files in the folder and in its
/// diagnosis/ stay. (The demo's polar plot and diagnosis survived a later laser run, Kwon's
/// later plots a demo.)
#[test]
fn a_reused_output_folder_keeps_only_this_runs_files() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let laser = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/iso230_2_x.toml");
    let kwon = kwon_steps(dir.path(), "[5, 7]");
    std::fs::create_dir_all(out.join("diagnosis")).unwrap();
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    std::fs::write(out.join("diagnosis/mine.txt"), "mine").unwrap();
    run_into(&out, &["run", &kwon, "--diagnose"]);
    let e = run_into(&out, &["demo"]);
    let note = e
        .lines()
        .find(|l| l.starts_with("note: removed"))
        .unwrap_or("");
    for gone in [
        "ballbar_polar_1_xy_100mm.png",
        "ballbar_polar_2_yz_150mm.png",
        "diagnosis/diagnosis_2.png",
    ] {
        assert!(note.contains(gone), "{gone}: {e}");
        assert!(!out.join(gone).exists(), "{gone}");
    }
    assert!(
        !note.contains("diagnosis_1") && !note.contains("mine"),
        "{e}"
    );
    let e = run_into(&out, &["run", laser]);
    assert_eq!(
        names_in(&out),
        [
            "diagnosis",
            "ground_truth.json",
            "laser_iso230_2.json",
            "notes.txt",
            "run.mcap",
            "run.rrd"
        ],
        "{e}"
    );
    assert_eq!(names_in(&out.join("diagnosis")), ["mine.txt"], "{e}");
    assert!(
        e.contains(&format!(
            "note: removed from {} what an earlier run left there and this run does not write: \
             ballbar_polar.png, diagnosis/diagnosis_1.png, diagnosis/report.json, \
             diagnosis/report.md, diagnosis/report.txt",
            out.display()
        )),
        "{e}"
    );
    // Nothing of an earlier run left: no note; an emptied diagnosis/ goes too.
    std::fs::remove_file(out.join("diagnosis/mine.txt")).unwrap();
    let e = run_into(&out, &["run", laser, "--diagnose"]);
    assert!(!e.contains("note: removed"), "{e}");
    let e = run_into(&out, &["run", laser]);
    assert!(
        e.contains("diagnosis/report.txt") && e.contains(", diagnosis/"),
        "{e}"
    );
    assert!(!out.join("diagnosis").exists());
}

/// A program job records nothing to diagnose: `--diagnose` says so instead of doing nothing.
#[test]
fn run_diagnose_of_a_job_with_nothing_to_diagnose_says_so() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("p.nc"), format!("{MOVE}G1 X110 F500\n")).unwrap();
    let job = "[job]\nkind = \"program\"\nprogram = \"p.nc\"";
    let s = scenario(dir.path(), "s.toml", job, &[]);
    let e = run_into(&dir.path().join("out"), &["run", &s, "--diagnose"]);
    assert!(
        e.contains("note: --diagnose: the run recorded no ball-bar traces, laser readings or accelerometers to diagnose"),
        "{e}"
    );
    assert!(!dir.path().join("out/diagnosis").exists());
}
