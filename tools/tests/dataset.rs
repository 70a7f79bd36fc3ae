//! `vmt dataset` and `vmt accuracy` on tiny datasets (three machines, a 50 mm circle):
//! thread-count independence, restart after an interruption, the Parquet manifest read back
//! with pyarrow, and computed accuracy figures.

mod common;

use common::{stderr, vmt};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// scenarios/dataset_xy.toml with a 50 mm circle, `edit` applied (from, to), written into `dir`.
fn scenario(dir: &Path, edit: Option<(&str, &str)>) -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut text = std::fs::read_to_string(root.join("scenarios/dataset_xy.toml")).unwrap();
    for (from, to) in [("radius_mm = 100.0", "radius_mm = 50.0")]
        .into_iter()
        .chain(edit)
    {
        assert!(text.contains(from), "`{from}` not in the dataset scenario");
        text = text.replacen(from, to, 1);
    }
    let path = dir.join("ds.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// The statistics of figure `key` in an `accuracy.json` report.
fn figure<'a>(report: &'a Value, key: &str) -> &'a Value {
    let figures = report["figures"].as_array().expect("a list of figures");
    figures
        .iter()
        .find(|f| f["key"] == key)
        .unwrap_or_else(|| panic!("no figure {key}"))
}

/// Runs `vmt dataset --seed seed` on `threads` threads.
fn dataset_run(scenario: &Path, out: &Path, count: u32, seed: u64, threads: usize) -> Output {
    Command::new("timeout")
        .args(["300", env!("CARGO_BIN_EXE_vmt"), "dataset", "--quiet"])
        .args(["--seed", &seed.to_string()])
        .arg("--scenario")
        .arg(scenario)
        .args(["--count", &count.to_string()])
        .arg("--out")
        .arg(out)
        .env("RAYON_NUM_THREADS", threads.to_string())
        .output()
        .unwrap()
}

/// Runs `vmt dataset --seed 7` on `threads` threads.
fn dataset(scenario: &Path, out: &Path, count: u32, threads: usize) -> String {
    let o = dataset_run(scenario, out, count, 7, threads);
    assert!(o.status.success(), "vmt dataset failed: {}", stderr(&o));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn bytes(dir: &Path, file: &str) -> Vec<u8> {
    std::fs::read(dir.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"))
}

#[test]
fn same_seed_gives_identical_files_with_one_and_two_threads_and_resumes() {
    let tmp = tempfile::tempdir().unwrap();
    let s = scenario(tmp.path(), None);
    let (one, two) = (tmp.path().join("one"), tmp.path().join("two"));
    dataset(&s, &one, 3, 1);
    dataset(&s, &two, 3, 2);
    let files = [
        "manifest.csv",
        "manifest.parquet",
        "runs/000000/run.mcap",
        "runs/000001/run.mcap",
        "runs/000002/run.mcap",
        "runs/000002/labels.json",
    ];
    for f in files {
        assert!(
            bytes(&one, f) == bytes(&two, f),
            "{f} differs between 1 and 2 threads"
        );
    }
    let csv = String::from_utf8(bytes(&one, "manifest.csv")).unwrap();
    let header = csv.lines().next().unwrap();
    for column in [
        "id,seed,",
        "machine.axes.x.drive.backlash_um",
        "scale_x",
        "truth.backlash_x_um",
        "truth.servo_mismatch_xy_ms",
        "truth.pivot_drift_x_um",
        "truth.pivot_drift_y_um",
        "truth.radial_drift_um",
    ] {
        assert!(header.contains(column), "{column} not in {header}");
    }
    assert_eq!(csv.lines().count(), 4);
    // An interruption: run 2 lost, run 1 left half-written in its temporary folder.
    std::fs::remove_dir_all(two.join("runs/000002")).unwrap();
    std::fs::create_dir(two.join("runs/.tmp-000001")).unwrap();
    std::fs::write(two.join("runs/.tmp-000001/run.mcap"), b"half").unwrap();
    let said = dataset(&s, &two, 3, 2);
    assert!(
        said.contains("1 runs simulated") && said.contains("2 already complete"),
        "{said}"
    );
    assert!(!two.join("runs/.tmp-000001").exists());
    for f in files {
        assert!(
            bytes(&one, f) == bytes(&two, f),
            "{f} differs after the restart"
        );
    }
    // Files deleted by hand from complete runs: those runs are simulated again and replaced.
    std::fs::remove_file(two.join("runs/000000/run.mcap")).unwrap();
    std::fs::remove_file(two.join("runs/000001/labels.json")).unwrap();
    let said = dataset(&s, &two, 3, 2);
    assert!(
        said.contains("2 runs simulated") && said.contains("1 already complete"),
        "{said}"
    );
    for f in files
        .iter()
        .chain(&["runs/000000/run.mcap", "runs/000001/labels.json"])
    {
        assert!(
            bytes(&one, f) == bytes(&two, f),
            "{f} differs after the repair"
        );
    }
}

#[test]
fn parquet_manifest_reads_back_with_pyarrow_as_the_csv() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("ds");
    dataset(&scenario(tmp.path(), None), &out, 2, 2);
    let script = r#"
import csv, json, sys
import pyarrow.parquet as pq
t = pq.read_table(sys.argv[1] + "/manifest.parquet")
rows = list(csv.reader(open(sys.argv[1] + "/manifest.csv")))
meta = {k.decode(): v.decode() for k, v in (pq.read_metadata(sys.argv[1] + "/manifest.parquet").metadata or {}).items()}
print(json.dumps({"columns": t.column_names, "types": [str(f.type) for f in t.schema],
                  "parquet": t.to_pylist(), "csv": rows, "meta": meta}))
"#;
    let o = Command::new("python3")
        .args(["-c", script])
        .arg(&out)
        .output()
        .expect("python3 with pyarrow (pip install -r tools/tests/requirements.txt)");
    assert!(
        o.status.success(),
        "pyarrow could not read the manifest (pip install -r tools/tests/requirements.txt): {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    let csv = v["csv"].as_array().unwrap();
    let header: Vec<&str> = csv[0]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_str().unwrap())
        .collect();
    let columns: Vec<&str> = v["columns"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_str().unwrap())
        .collect();
    assert_eq!(columns, header);
    assert_eq!(v["types"][0], "string");
    assert_eq!(v["types"][1], "int64");
    assert_eq!(v["types"][2], "double");
    let rows = v["parquet"].as_array().unwrap();
    assert_eq!(rows.len(), 2);
    // The key-value metadata gives the units and the keys of an entry with `keys`.
    let meta = &v["meta"];
    for (key, value) in [
        ("unit.machine.axes.x.drive.backlash_um", "µm"),
        ("unit.machine.axes.x.servo.kv_per_s", "1/s"),
        ("unit.scale_x", "µm"),
        (
            "keys.scale_x",
            r#"["machine.errors.x.forward.EXX_um[1]","machine.errors.x.backward.EXX_um[1]"]"#,
        ),
        ("unit.truth.backlash_x_um", "µm"),
        ("unit.truth.scale_mismatch_xy_ppm", "ppm"),
        ("unit.truth.servo_mismatch_xy_ms", "ms"),
        ("unit.truth.squareness_xy_um_per_m", "µm/m"),
        ("unit.truth.pivot_drift_x_um", "µm"),
    ] {
        assert_eq!(meta[key], value, "{key} in {meta}");
    }
    for (row, line) in rows.iter().zip(&csv[1..]) {
        for (name, cell) in header.iter().zip(line.as_array().unwrap()) {
            let cell = cell.as_str().unwrap();
            let got = &row[*name];
            match *name {
                "id" => assert_eq!(got.as_str(), Some(cell)),
                "seed" => assert_eq!(got.as_i64().map(|s| s.to_string()).as_deref(), Some(cell)),
                _ if cell.is_empty() => assert!(got.is_null(), "{name}"),
                _ => assert_eq!(got.as_f64(), Some(cell.parse::<f64>().unwrap()), "{name}"),
            }
        }
    }
}

/// On the 220° arc in ZX (`scenarios/dataset_zx.toml`) with bows of 3 µm on both axes, the
/// squareness and the scale mismatch read several times their tolerance off; with the bias
/// their findings state for the unfitted bows taken off, from the true bows, they are within
/// it. The machine warms up during the test: its drift, read as lateral play and servo
/// mismatch, is taken off theirs, from the true drift.
#[test]
fn accuracy_on_a_partial_arc_takes_off_the_stated_bias_of_the_bows_and_the_drift() {
    let tmp = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join("scenarios/dataset_zx.toml")).unwrap();
    let mut doc: toml_edit::DocumentMut = text.parse().unwrap();
    for (entry, bow) in [("bow_x", 3.0), ("bow_z", -3.0)] {
        let e = doc["dataset"]["parameters"][entry]
            .as_inline_table_mut()
            .expect("a bow entry");
        e.retain(|k, _| k == "keys");
        e.insert("distribution", "constant".into());
        e.insert("value", bow.into());
    }
    let scenario = tmp.path().join("zx.toml");
    std::fs::write(&scenario, doc.to_string()).unwrap();
    let out = tmp.path().join("ds");
    dataset(&scenario, &out, 3, 2);
    let o = vmt(&["accuracy", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report: Value = serde_json::from_slice(&bytes(&out, "accuracy.json")).unwrap();
    let fig = |k: &str| figure(&report, k);
    // Tolerances: 1 µm/m; 0.3 µm over R = 100 mm, 3 ppm.
    for (key, tolerance) in [("squareness_zx", 1.0), ("scale_mismatch_zx", 3.0)] {
        let f = fig(key);
        let w = &f["without_left_out"];
        assert_eq!(w["runs_stating"], 3, "{f}");
        let (rms, worst) = (f["rms"].as_f64().unwrap(), w["worst"].as_f64().unwrap());
        assert!(
            rms > 3.0 * tolerance,
            "{key}: RMS {rms} with the bows read as it"
        );
        assert!(
            worst < 0.5 * tolerance,
            "{key}: worst {worst} with their bias taken off"
        );
    }
    // Measured: lateral plays 0.088 and 0.056 µm RMS, 0.013 and 0.004 with the drift's bias
    // taken off; servo mismatch 0.0026 and 0.0004 ms.
    for key in ["lateral_play_x", "lateral_play_z", "servo_mismatch_zx"] {
        let f = fig(key);
        let w = &f["without_left_out"];
        assert_eq!(w["runs_stating"], 3, "{f}");
        let (rms, without) = (f["rms"].as_f64().unwrap(), w["rms"].as_f64().unwrap());
        assert!(
            without < 0.3 * rms,
            "{key}: RMS {rms}, {without} without the drift"
        );
    }
    let md = String::from_utf8(bytes(&out, "accuracy.md")).unwrap();
    assert!(md.contains("taken off, where the truth gives them"), "{md}");
}

#[test]
fn accuracy_compares_the_diagnosis_with_the_truth() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("ds");
    // Every machine has 4 um of drive backlash on X.
    let edit = (
        r#""machine.axes.x.drive.backlash_um" = { distribution = "uniform", min = 0.0, max = 6.0, p_absent = 0.33 }"#,
        r#""machine.axes.x.drive.backlash_um" = { distribution = "constant", value = 4.0 }"#,
    );
    dataset(&scenario(tmp.path(), Some(edit)), &out, 3, 2);
    let o = vmt(&["accuracy", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let printed = String::from_utf8_lossy(&o.stdout);
    assert!(printed.contains("| backlash_x | µm | 3 |"), "{printed}");
    let report: Value = serde_json::from_slice(&bytes(&out, "accuracy.json")).unwrap();
    assert!(out.join("accuracy.md").is_file());
    let fig = |k: &str| figure(&report, k);
    let b = fig("backlash_x");
    let labels: Value = serde_json::from_slice(&bytes(&out, "runs/000000/labels.json")).unwrap();
    let truth = labels["ground_truth"]["ballbar"]["tests"][0]["figures"]["backlash_x"]
        .as_f64()
        .unwrap();
    // The ball bar sees most of the 4 um, and the diagnosis recovers it within 0.3 um.
    assert!((3.0..5.0).contains(&truth), "truth {truth}");
    assert_eq!(b["n"], 3);
    let (rms, worst, p95) = (
        b["rms"].as_f64().unwrap(),
        b["worst"].as_f64().unwrap(),
        b["p95_abs"].as_f64().unwrap(),
    );
    assert!(rms > 0.0 && rms < 0.3, "rms {rms}");
    assert!(p95 <= worst && rms <= worst, "{b}");
    assert_eq!(b["within"], 1.0);
    // Backlash is present in every run, so no run is quiet (eligible for a false positive).
    assert_eq!(b["quiet_runs"], 0);
    assert_eq!(report["runs"], 3);
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
    assert_eq!(report["warnings"].as_array().map(Vec::len), Some(0));
    // An interrupted dataset: run 2 never finished, the manifest never written.
    std::fs::remove_dir_all(out.join("runs/000002")).unwrap();
    std::fs::remove_file(out.join("manifest.csv")).unwrap();
    let o = vmt(&["accuracy", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    for w in [
        "warning:",
        "incomplete: 2 of the 3 runs",
        "manifest.csv is missing",
    ] {
        assert!(e.contains(w), "`{w}` not in: {e}");
    }
    let md = String::from_utf8(bytes(&out, "accuracy.md")).unwrap();
    assert!(
        md.contains("**Warning:**") && md.contains("quiet runs"),
        "{md}"
    );
    // Runs none of which can be diagnosed are an error, not an empty table.
    for r in run_names(&out) {
        std::fs::write(out.join("runs").join(r).join("run.mcap"), "not an MCAP").unwrap();
    }
    let o = vmt(&["accuracy", out.to_str().unwrap()]);
    let e = stderr(&o);
    assert!(!o.status.success(), "{e}");
    assert!(
        e.contains("nothing to score: none of its 2 runs could be diagnosed (run 000000"),
        "{e}"
    );
}

/// A run's labels.json that is not JSON, or lacks one of its keys, is a damaged dataset:
/// `vmt accuracy` stops with an error naming the file (and serde's line and column) instead of
/// scoring the dataset without it, and so does `vmt dataset` when it rebuilds the manifest.
#[test]
fn a_corrupt_label_is_an_error_naming_its_file() {
    let tmp = tempfile::tempdir().unwrap();
    let s = scenario(tmp.path(), None);
    let out = tmp.path().join("ds");
    dataset(&s, &out, 2, 2);
    let labels = out.join("runs/000001/labels.json");
    let good = std::fs::read_to_string(&labels).unwrap();
    let refused = |expected: &[&str]| {
        let o = vmt(&["accuracy", out.to_str().unwrap()]);
        let e = stderr(&o);
        assert!(!o.status.success(), "a corrupt label was scored: {e}");
        for x in expected {
            assert!(e.contains(x), "`{x}` not in: {e}");
        }
        assert!(!out.join("accuracy.json").exists(), "{e}");
    };
    let file = format!("{}", labels.display());
    // Not JSON: the value of `seed` on line 3 is garbage.
    std::fs::write(&labels, "{\n  \"id\": \"000001\",\n  \"seed\": x\n}\n").unwrap();
    refused(&[
        &format!("{file}:3: not JSON"),
        "line 3 column 11",
        "damaged",
    ]);
    // JSON, but without the ground truth.
    let mut v: Value = serde_json::from_str(&good).unwrap();
    v.as_object_mut().unwrap().remove("ground_truth");
    std::fs::write(&labels, v.to_string()).unwrap();
    refused(&[&file, "the key `ground_truth` is missing"]);
    // A parameter or the truth of the circular test deleted: the manifest would hold NaN or
    // empty cells.
    for (path, said) in [
        (
            &["parameters", "scale_x"][..],
            "`parameters.scale_x` is missing",
        ),
        (
            &["ground_truth", "ballbar"][..],
            "`ground_truth.ballbar.tests[0].figures` is missing",
        ),
    ] {
        let mut v: Value = serde_json::from_str(&good).unwrap();
        v[path[0]].as_object_mut().unwrap().remove(path[1]);
        std::fs::write(&labels, v.to_string()).unwrap();
        refused(&[&file, said]);
        let o = dataset_run(&s, &out, 2, 7, 1);
        let e = stderr(&o);
        assert!(
            !o.status.success() && e.contains(&file) && e.contains(said),
            "{e}"
        );
    }
    // One truth figure or drift deleted: the manifest would have an empty cell where the
    // others have a number.
    for (section, key) in [("figures", "backlash_x"), ("drift", "pivot_drift_x")] {
        let mut v: Value = serde_json::from_str(&good).unwrap();
        v["ground_truth"]["ballbar"]["tests"][0][section]
            .as_object_mut()
            .unwrap()
            .remove(key);
        std::fs::write(&labels, v.to_string()).unwrap();
        let o = dataset_run(&s, &out, 2, 7, 1);
        let e = stderr(&o);
        let said = format!(
            "`ground_truth.ballbar.tests[0].{section}.{key}` is missing (other runs have it)"
        );
        assert!(
            !o.status.success() && e.contains(&file) && e.contains(&said),
            "{e}"
        );
    }
    // A drift that is not a number.
    let mut v: Value = serde_json::from_str(&good).unwrap();
    v["ground_truth"]["ballbar"]["tests"][0]["drift"]["radial_drift"] = Value::Null;
    std::fs::write(&labels, v.to_string()).unwrap();
    refused(&[
        &file,
        "`ground_truth.ballbar.tests[0].drift.radial_drift` is null, not a number",
    ]);
    // Another run's label.
    let other = good.replacen("\"000001\"", "\"000000\"", 1);
    std::fs::write(&labels, other).unwrap();
    refused(&[&file, "not the run's folder name \"000001\""]);
    // `vmt dataset` continuing the folder reads the labels into the manifest: refused too.
    let o = dataset_run(&s, &out, 2, 7, 1);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains(&file), "{e}");
    // Restored, the dataset is scored.
    std::fs::write(&labels, good).unwrap();
    let o = vmt(&["accuracy", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// The run folders of `out`, by name.
fn run_names(out: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(out.join("runs"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn a_folder_of_another_seed_scenario_or_smaller_count_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let s = scenario(tmp.path(), None);
    let out = tmp.path().join("ds");
    dataset(&s, &out, 2, 2);
    let identity: Value = serde_json::from_slice(&bytes(&out, "dataset.json")).unwrap();
    assert_eq!(identity["seed"], 7);
    assert_eq!(identity["count"], 2);
    let refused = |o: Output, words: &[&str]| {
        assert!(
            !o.status.success(),
            "accepted: {}",
            String::from_utf8_lossy(&o.stdout)
        );
        let e = stderr(&o);
        assert!(!e.contains("panicked"), "{e}");
        for w in words {
            assert!(e.contains(w), "`{w}` not in: {e}");
        }
        assert_eq!(run_names(&out), ["000000", "000001"], "{e}");
    };
    let folder = out.display().to_string();
    refused(
        dataset_run(&s, &out, 3, 8, 2),
        &[&folder, "--seed 7", "--seed 8"],
    );
    let edited = tmp.path().join("edited");
    std::fs::create_dir(&edited).unwrap();
    let e = scenario(&edited, Some(("radius_mm = 50.0", "radius_mm = 60.0")));
    refused(dataset_run(&e, &out, 3, 7, 2), &[&folder, "scenario text"]);
    refused(
        dataset_run(&s, &out, 1, 7, 2),
        &[&folder, "--count 1", "000001", "--count 2 or more"],
    );
    refused(
        dataset_run(&s, &out, 0, 7, 2),
        &["--count 0", "from 1 to 1000000"],
    );
    // Runs in labels format 1 (an older vmt: dataset.json without the key, or no dataset.json)
    // are never mixed with this vmt's.
    let identity: Value = serde_json::from_slice(&bytes(&out, "dataset.json")).unwrap();
    assert_eq!(identity["labels_format"], 5);
    let mut old = identity.clone();
    old.as_object_mut().unwrap().remove("labels_format");
    std::fs::write(out.join("dataset.json"), old.to_string()).unwrap();
    refused(
        dataset_run(&s, &out, 2, 7, 2),
        &[
            &folder,
            "labels in format 1 (an older vmt's",
            "writes format 5",
            "new --out",
        ],
    );
    std::fs::remove_file(out.join("dataset.json")).unwrap();
    refused(
        dataset_run(&s, &out, 2, 7, 2),
        &[&folder, "dataset.json", "run 000000", "format 1 or unknown"],
    );
    let fresh = tmp.path().join("fresh");
    for count in [0, 1_000_001] {
        let o = dataset_run(&s, &fresh, count, 7, 2);
        assert!(
            !o.status.success() && stderr(&o).contains(&format!("--count {count}")),
            "{}",
            stderr(&o)
        );
        assert!(!fresh.exists(), "--count {count} wrote {}", fresh.display());
    }
}

/// A second `vmt dataset` on a folder being written is refused (the first holds the folder's
/// lock; the test holds it here), and writes nothing; the lock left behind by a process that
/// ended does not keep the next one out. A dataset that gets runs loses its stale accuracy
/// report.
#[test]
fn a_folder_being_written_is_refused_to_a_second_vmt_dataset() {
    let tmp = tempfile::tempdir().unwrap();
    let s = scenario(tmp.path(), None);
    let out = tmp.path().join("ds");
    std::fs::create_dir(&out).unwrap();
    let lock = std::fs::File::create(out.join(".lock")).unwrap();
    lock.try_lock().unwrap();
    let o = dataset_run(&s, &out, 2, 7, 1);
    let e = stderr(&o);
    assert!(!o.status.success(), "{e}");
    for w in [
        &out.display().to_string(),
        "another `vmt dataset` is writing this dataset folder",
    ] {
        assert!(e.contains(w), "`{w}` not in: {e}");
    }
    assert!(!out.join("runs").exists() && !out.join("dataset.json").exists());
    drop(lock);
    dataset(&s, &out, 2, 1);
    // A report of the two runs is stale once a third is added: removed, and said so.
    std::fs::write(out.join("accuracy.md"), "2 runs").unwrap();
    std::fs::write(out.join("accuracy.json"), "{}").unwrap();
    let said = dataset(&s, &out, 3, 1);
    assert!(
        said.contains(&format!("removed {}", out.join("accuracy.md").display())),
        "{said}"
    );
    assert!(!out.join("accuracy.md").exists() && !out.join("accuracy.json").exists());
}

/// The line of `scenario` that starts with `entry`.
fn line_of(scenario: &Path, entry: &str) -> usize {
    let text = std::fs::read_to_string(scenario).unwrap();
    1 + text.lines().position(|l| l.starts_with(entry)).unwrap()
}

/// A distribution drawing values the scenario refuses is refused before any run: the error
/// names the entry's line, the key, the share of the runs and the first value.
#[test]
fn bad_draws_are_refused_before_anything_is_simulated() {
    let tmp = tempfile::tempdir().unwrap();
    let entry =
        r#""machine.axes.x.drive.backlash_um" = { distribution = "normal", mean = 0.0, sd = 3.0 }"#;
    let (s, e) = refused_draw(tmp.path(), entry, 7);
    let at = format!("{}:{}:", s.display(), line_of(&s, entry));
    for w in [
        at.as_str(),
        "key `dataset.parameters.\"machine.axes.x.drive.backlash_um\"`",
        "of the 20 runs (",
        "is out of range; a backlash (µm) from 0 to 1000 is accepted",
        "nothing was simulated",
    ] {
        assert!(e.contains(w), "`{w}` not in: {e}");
    }
}

/// The dataset scenario in `dir` with X's backlash entry replaced by `entry`, given to a
/// `vmt dataset` of 20 runs with `seed`, which must fail before writing its folder: the
/// scenario's path and the standard error.
fn refused_draw(dir: &Path, entry: &str, seed: u64) -> (PathBuf, String) {
    let s = scenario(
        dir,
        Some((
            r#""machine.axes.x.drive.backlash_um" = { distribution = "uniform", min = 0.0, max = 6.0, p_absent = 0.33 }"#,
            entry,
        )),
    );
    let out = dir.join("ds");
    let o = dataset_run(&s, &out, 20, seed, 2);
    let e = stderr(&o);
    assert!(!o.status.success(), "{e}");
    assert!(!out.exists(), "{e}");
    (s, e)
}

/// A circle drawn past the strokes is refused at `job.center_mm`, which no entry draws (the
/// check weighs the centre against the radius): the refusal names the entry that draws a key
/// of that table, `job.radius_mm`, at its line.
#[test]
fn a_draw_refused_at_another_key_names_the_entries_of_its_table() {
    let tmp = tempfile::tempdir().unwrap();
    let entry = r#""job.radius_mm" = { distribution = "uniform", min = 100.0, max = 300.0 }"#;
    let (s, e) = refused_draw(tmp.path(), entry, 1);
    let at = format!(
        "entries drawing that table: `dataset.parameters.\"job.radius_mm\"` ({}:{}:",
        s.display(),
        line_of(&s, entry)
    );
    for w in ["key `job.center_mm`", "beyond its stroke", at.as_str()] {
        assert!(e.contains(w), "`{w}` not in: {e}");
    }
}

/// A run that fails in simulation (a gain so low that the ball bar reads beyond its range)
/// stops the dataset naming the run and the scenario kept to reproduce it; the other runs
/// are written, and `vmt accuracy` does not advise running `vmt dataset` again.
#[test]
fn a_run_failing_in_simulation_is_named_with_its_scenario() {
    let tmp = tempfile::tempdir().unwrap();
    let s = scenario(
        tmp.path(),
        Some((
            r#""machine.axes.x.servo.kv_per_s" = { distribution = "normal", mean = 33.0, sd = 1.5, p_absent = 0.58, absent = 33.0 }"#,
            r#""machine.axes.x.servo.kv_per_s" = { distribution = "uniform", min = 1.0, max = 33.0 }"#,
        )),
    );
    let out = tmp.path().join("ds");
    let o = dataset_run(&s, &out, 4, 1, 2);
    let e = stderr(&o);
    assert!(!o.status.success(), "{e}");
    let failed = out.join("failed-runs/000001.toml");
    for w in [
        "2 of the 4 runs simulated failed (000001, 000003)",
        &format!("Run 000001 (its scenario: {})", failed.display()),
        "beyond its measuring range",
        "new --out folder",
    ] {
        assert!(e.contains(w), "`{w}` not in: {e}");
    }
    assert!(failed.is_file());
    assert_eq!(run_names(&out), ["000000", "000002"]);
    let o = vmt(&["accuracy", out.to_str().unwrap()]);
    let e = stderr(&o);
    assert!(
        e.contains("runs failed in simulation") && !e.contains("run it again"),
        "{e}"
    );
}

#[test]
fn accuracy_refuses_a_folder_that_is_no_dataset() {
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("a.toml");
    std::fs::write(&file, "").unwrap();
    let run = tmp.path().join("run");
    std::fs::create_dir(&run).unwrap();
    std::fs::write(run.join("run.mcap"), "").unwrap();
    for (dir, why) in [
        (tmp.path().to_path_buf(), "it has no runs/ folder"),
        (file, "it is a file"),
        (run, "it holds one run"),
    ] {
        let o = vmt(&["accuracy", dir.to_str().unwrap()]);
        let e = stderr(&o);
        assert!(!o.status.success(), "{e}");
        let said = format!("{} is not a dataset folder: {why}", dir.display());
        assert!(
            e.contains(&said) && e.contains("written by `vmt dataset`"),
            "{e}"
        );
    }
}

/// A label holding a parameter the first run's `keys` does not list (edited by hand) is a
/// column of its own in the manifest: rebuilding it had panicked on the missing key.
#[test]
fn a_label_with_an_extra_parameter_does_not_panic_the_manifest() {
    let tmp = tempfile::tempdir().unwrap();
    let s = scenario(tmp.path(), None);
    let out = tmp.path().join("ds");
    dataset(&s, &out, 1, 1);
    let labels = out.join("runs/000000/labels.json");
    let mut v: Value = serde_json::from_str(&std::fs::read_to_string(&labels).unwrap()).unwrap();
    v["parameters"]["extra_um"] = 1.0.into();
    std::fs::write(&labels, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    let o = dataset_run(&s, &out, 1, 7, 1);
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = std::fs::read_to_string(out.join("manifest.csv")).unwrap();
    assert!(csv.lines().next().unwrap().contains("extra_um"), "{csv}");
}

/// A dataset of positioning tests has no circular test to take truth figures from: its runs are
/// complete without them (they had been reported damaged, for ever).
#[test]
fn a_dataset_without_a_circular_test_completes() {
    let tmp = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join("scenarios/iso230_2_x.toml")).unwrap();
    let short = text
        .replacen("count = 11", "count = 2", 1)
        .replacen("runs = 5", "runs = 2", 1)
        .replacen("dwell_s = 2.0", "dwell_s = 1.5", 1)
        .replacen("range_mm = [25.0, 475.0]", "range_mm = [25.0, 75.0]", 1);
    let s = tmp.path().join("laser.toml");
    std::fs::write(
        &s,
        format!(
            "{short}\n[dataset.parameters]\n\"machine.axes.x.drive.backlash_um\" = {{ distribution = \"uniform\", min = 0.0, max = 6.0 }}\n"
        ),
    )
    .unwrap();
    let out = tmp.path().join("ds");
    let o = dataset_run(&s, &out, 1, 3, 1);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.join("runs/000000/labels.json").is_file());
}
