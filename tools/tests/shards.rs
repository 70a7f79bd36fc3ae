//! `vmt dataset` beyond one machine, on tiny datasets (a 50 mm circle): shards made in one
//! folder at once and in folders of their own, with `--shard` and with the schedulers'
//! variables, merged to the bytes of a one-machine run (the reference: the same command
//! without shards); a shard killed with SIGKILL and run again; the errors of bad input; and
//! the launchers of a dataset of a million runs against the schedulers' published limits
//! (Slurm's default MaxArraySize of 1001, Kubernetes' 10⁵ for an Indexed Job).

mod common;

use common::{stderr, vmt};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

/// scenarios/dataset_xy.toml with a 50 mm circle, written into `dir`.
fn scenario(dir: &Path) -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join("scenarios/dataset_xy.toml")).unwrap();
    assert!(text.contains("radius_mm = 100.0"));
    let path = dir.join("ds.toml");
    std::fs::write(
        &path,
        text.replacen("radius_mm = 100.0", "radius_mm = 50.0", 1),
    )
    .unwrap();
    path
}

/// `vmt dataset` of `count` runs with seed `seed` into `out` on one thread, with `extra`
/// arguments and environment variables, under `timeout`.
fn dataset_cmd(
    s: &Path,
    out: &Path,
    count: u64,
    seed: u64,
    extra: &[&str],
    env: &[(&str, &str)],
) -> Command {
    let mut c = Command::new("timeout");
    c.args(["300", env!("CARGO_BIN_EXE_vmt")]);
    dataset_args(c, s, out, count, seed, extra, env)
}

/// [`dataset_cmd`]'s arguments and environment given to `c`.
fn dataset_args(
    mut c: Command,
    s: &Path,
    out: &Path,
    count: u64,
    seed: u64,
    extra: &[&str],
    env: &[(&str, &str)],
) -> Command {
    c.args(["dataset", "--quiet"])
        .arg("--scenario")
        .arg(s)
        .args(["--count", &count.to_string(), "--seed", &seed.to_string()])
        .arg("--out")
        .arg(out)
        .args(extra)
        .env("RAYON_NUM_THREADS", "1");
    // The schedulers' variables of the environment the tests run in are not the test's.
    for k in [
        "SLURM_ARRAY_TASK_ID",
        "SLURM_ARRAY_TASK_COUNT",
        "SLURM_ARRAY_TASK_MIN",
        "SLURM_ARRAY_TASK_MAX",
        "SLURM_ARRAY_TASK_STEP",
        "JOB_COMPLETION_INDEX",
    ] {
        c.env_remove(k);
    }
    for (k, v) in env {
        c.env(k, v);
    }
    c
}

/// Runs `vmt dataset` (see [`dataset_cmd`]) and checks that it succeeded; returns its stdout.
fn dataset(s: &Path, out: &Path, count: u64, extra: &[&str], env: &[(&str, &str)]) -> String {
    let o = dataset_cmd(s, out, count, 7, extra, env).output().unwrap();
    assert!(o.status.success(), "vmt dataset failed: {}", stderr(&o));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn merge(args: &[&Path], out: Option<&Path>) -> Output {
    let mut a: Vec<String> = vec!["dataset".into(), "merge".into()];
    a.extend(args.iter().map(|p| p.display().to_string()));
    if let Some(o) = out {
        a.extend(["--out".into(), o.display().to_string()]);
    }
    vmt(&a.iter().map(String::as_str).collect::<Vec<_>>())
}

/// Every file under `dir` but the lock files, by path relative to it, with its bytes.
fn tree(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut files = BTreeMap::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                todo.push(p);
            } else if p.file_name().is_some_and(|n| n != ".lock") {
                let rel = p.strip_prefix(dir).unwrap().to_path_buf();
                files.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    files
}

/// Asserts that dataset folder `b` holds the files of `a`, byte for byte, and no other.
fn same_files(a: &Path, b: &Path) {
    let (ta, tb) = (tree(a), tree(b));
    let names = |t: &BTreeMap<PathBuf, Vec<u8>>| t.keys().cloned().collect::<Vec<_>>();
    assert_eq!(
        names(&ta),
        names(&tb),
        "{} and {}",
        a.display(),
        b.display()
    );
    for (f, bytes) in &ta {
        assert!(
            tb[f] == *bytes,
            "{} differs from {}",
            b.join(f).display(),
            a.display()
        );
    }
    for f in [
        "manifest.csv",
        "manifest.parquet",
        "dataset.json",
        "runs/000003/run.mcap",
    ] {
        assert!(ta.contains_key(Path::new(f)), "{f} missing");
    }
}

/// Shards made at once into one folder, and into folders of their own from the Slurm and
/// Kubernetes variables, merge to the one-machine run's files, byte for byte, and `vmt
/// accuracy` gives the same report on both.
#[test]
fn shards_merge_to_the_bytes_of_a_one_machine_run() {
    let tmp = tempfile::tempdir().unwrap();
    let s = scenario(tmp.path());
    let one = tmp.path().join("one");
    dataset(&s, &one, 4, &[], &[]);

    // Two shards writing one folder at the same time, as on a cluster file system.
    let shared = tmp.path().join("shared");
    let children: Vec<_> = (0..2)
        .map(|k| {
            dataset_cmd(&s, &shared, 4, 7, &["--shard", &format!("{k}/2")], &[])
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for c in children {
        let o = c.wait_with_output().unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
        let said = String::from_utf8_lossy(&o.stdout);
        assert!(said.contains("2 runs simulated"), "{said}");
    }
    assert!(
        !shared.join("manifest.csv").exists(),
        "a shard wrote the manifest"
    );
    let o = merge(&[&shared], None);
    assert!(o.status.success(), "{}", stderr(&o));
    same_files(&one, &shared);

    // A folder per shard, the shard read from the schedulers' variables.
    let (p0, p1) = (tmp.path().join("p0"), tmp.path().join("p1"));
    let said = dataset(
        &s,
        &p0,
        4,
        &["--shards", "2"],
        &[("JOB_COMPLETION_INDEX", "0")],
    );
    assert!(
        said.contains("shard 0/2 from JOB_COMPLETION_INDEX=0, --shards 2"),
        "{said}"
    );
    let slurm = [
        ("SLURM_ARRAY_TASK_ID", "5"),
        ("SLURM_ARRAY_TASK_MIN", "3"),
        ("SLURM_ARRAY_TASK_MAX", "5"),
        ("SLURM_ARRAY_TASK_STEP", "2"),
    ];
    let said = dataset(&s, &p1, 4, &[], &slurm);
    assert!(
        said.contains("shard 1/2 from SLURM_ARRAY_TASK_ID=5, SLURM_ARRAY_TASK_MIN=3, step 2"),
        "{said}"
    );
    let merged = tmp.path().join("merged");
    let o = merge(&[&p0, &p1], Some(&merged));
    assert!(o.status.success(), "{}", stderr(&o));
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(said.contains("merged 4 runs of 2 shards"), "{said}");
    same_files(&one, &merged);

    for d in [&one, &merged] {
        let o = vmt(&["accuracy", d.to_str().unwrap()]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    for f in ["accuracy.md", "accuracy.json"] {
        assert!(
            std::fs::read(one.join(f)).unwrap() == std::fs::read(merged.join(f)).unwrap(),
            "{f} differs between the one-machine run and the merged shards"
        );
    }
}

/// A shard killed with SIGKILL in the middle leaves only whole runs; run again, it completes
/// without redoing the finished ones, and the merge is the one-machine run's bytes.
#[test]
fn a_killed_shard_run_again_completes_without_redoing_a_run() {
    let tmp = tempfile::tempdir().unwrap();
    let s = scenario(tmp.path());
    let one = tmp.path().join("one");
    dataset(&s, &one, 6, &[], &[]);
    let out = tmp.path().join("ds");
    // Shard 1/2 holds runs 1, 3 and 5; shard 0/2 is made whole first.
    dataset(&s, &out, 6, &["--shard", "0/2"], &[]);
    // vmt itself, not under `timeout`, so that the kill reaches it.
    let vmt_bin = Command::new(env!("CARGO_BIN_EXE_vmt"));
    let mut child = dataset_args(vmt_bin, &s, &out, 6, 7, &["--shard", "1/2"], &[])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let complete = |i: u32| out.join(format!("runs/{i:06}/labels.json")).is_file();
    let start = std::time::Instant::now();
    while !complete(1) && start.elapsed().as_secs() < 120 {
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    assert!(complete(1), "run 1 never completed");
    let whole = (0..6).filter(|&i| complete(i)).count();
    assert!(whole < 6, "the shard finished before it was killed");
    // What a merge says of the folder now: the missing runs by index and shard.
    let o = merge(&[&out], None);
    let e = stderr(&o);
    assert!(!o.status.success(), "{e}");
    let missing: Vec<String> = [3, 5]
        .into_iter()
        .filter(|&i| !complete(i))
        .map(|i| format!("{i:06}"))
        .collect();
    assert!(
        e.contains(&format!("shard 1/2: runs {}", missing.join(", "))),
        "{e}"
    );
    assert!(e.contains("run shard 1 of 2 again"), "{e}");
    assert!(!out.join("manifest.csv").exists(), "{e}");

    let said = dataset(&s, &out, 6, &["--shard", "1/2"], &[]);
    assert!(
        said.contains(&format!("{} runs simulated", missing.len()))
            && said.contains(&format!("{} already complete", 3 - missing.len())),
        "{said}"
    );
    let o = merge(&[&out], None);
    assert!(o.status.success(), "{}", stderr(&o));
    same_files(&one, &out);
}

/// A shard index out of range, given or read from the environment, is refused naming where
/// it came from and the accepted range; nothing is written.
#[test]
fn a_shard_index_out_of_range_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let s = scenario(tmp.path());
    let out = tmp.path().join("ds");
    for (extra, env, said) in [
        (
            &["--shard", "2/2"][..],
            &[][..],
            "--shard 2/2: shard index 2 is out of range: the 2 shards are numbered 0 to 1",
        ),
        (
            &[][..],
            &[
                ("SLURM_ARRAY_TASK_ID", "4"),
                ("SLURM_ARRAY_TASK_COUNT", "4"),
            ][..],
            "SLURM_ARRAY_TASK_ID=4, SLURM_ARRAY_TASK_COUNT=4: shard index 4 is out of range: \
             the 4 shards are numbered 0 to 3",
        ),
        (
            &["--shard", "1/9"][..],
            &[][..],
            "--shard 1/9: 9 shards for 4 runs would leave shards without a run",
        ),
        (
            &["--shard", "one/2"][..],
            &[][..],
            "--shard one/2: give the shard's index and the number of shards as I/N",
        ),
    ] {
        let o = dataset_cmd(&s, &out, 4, 7, extra, env).output().unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert!(e.contains(said), "`{said}` not in: {e}");
        assert!(!out.exists(), "{e}");
    }
}

/// Shards of two different datasets given to merge, and folders with a run missing, a run
/// half-written, or a damaged run, are refused with the folder, run and shard named; nothing
/// is merged.
#[test]
fn merge_refuses_other_datasets_and_missing_or_damaged_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let s = scenario(tmp.path());
    let (a, b, c) = (
        tmp.path().join("a"),
        tmp.path().join("b"),
        tmp.path().join("c"),
    );
    dataset(&s, &a, 3, &["--shard", "0/2"], &[]);
    dataset(&s, &b, 3, &["--shard", "1/2"], &[]);
    // Shard 1 of a dataset of seed 8.
    let o = dataset_cmd(&s, &c, 3, 8, &["--shard", "1/2"], &[])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let out = tmp.path().join("out");

    let o = merge(&[&a, &c], Some(&out));
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    let said = format!(
        "{} and {} hold shards of two different datasets (seed 7 against 8)",
        a.display(),
        c.display()
    );
    assert!(e.contains(&said), "`{said}` not in: {e}");
    assert!(!out.exists(), "{e}");

    // Shard 1 missing altogether.
    let o = merge(&[&a], Some(&out));
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(
        e.contains("runs missing or damaged: 1 of 3")
            && e.contains("shard 1/2: all its runs: 000001 (no folder holds any"),
        "{e}"
    );
    assert!(!out.join("manifest.csv").exists(), "{e}");

    // A run left half-written by a killed task, and a damaged MCAP file.
    let run2 = a.join("runs/000002");
    std::fs::rename(&run2, a.join("runs/.tmp-000002")).unwrap();
    std::fs::remove_file(a.join("runs/.tmp-000002/labels.json")).unwrap();
    let mcap = b.join("runs/000001/run.mcap");
    let bytes = std::fs::read(&mcap).unwrap();
    std::fs::write(&mcap, &bytes[..bytes.len() / 2]).unwrap();
    let o = merge(&[&a, &b], Some(&out));
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    for said in [
        "runs missing or damaged: 2 of 3".to_string(),
        format!(
            "shard 0/2: runs 000002 (half-written by an interrupted task: {})",
            a.join("runs/.tmp-000002").display()
        ),
        format!(
            "damaged: {}: not a whole MCAP file",
            b.join("runs/000001/run.mcap").display()
        ),
        "run shards 0, 1 of 2 again".into(),
    ] {
        assert!(e.contains(&said), "`{said}` not in: {e}");
    }
    assert!(!out.join("manifest.csv").exists(), "{e}");

    // Made again, the two shards merge.
    std::fs::remove_dir_all(b.join("runs/000001")).unwrap();
    dataset(&s, &a, 3, &["--shard", "0/2"], &[]);
    dataset(&s, &b, 3, &["--shard", "1/2"], &[]);
    let o = merge(&[&a, &b], Some(&out));
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        std::fs::read_to_string(out.join("manifest.csv"))
            .unwrap()
            .lines()
            .count(),
        4
    );
}

/// Reads a number after `key` in `text` (`key` then digits).
fn number_after(text: &str, key: &str) -> u64 {
    let at = text
        .find(key)
        .unwrap_or_else(|| panic!("no `{key}` in:\n{text}"))
        + key.len();
    text[at..]
        .chars()
        .take_while(char::is_ascii_digit)
        .collect::<String>()
        .parse()
        .unwrap()
}

/// The launchers of a dataset of a million runs: a Slurm array of 1000 tasks (ids 0-999,
/// within the default MaxArraySize of 1001) of 1000 runs each, 100 at a time, a valid bash
/// script that submits the merge after the array; a Kubernetes Indexed Job of 1000
/// completions, parallelism 100 (within 10⁵), its pods' shards from JOB_COMPLETION_INDEX and
/// a merge Job, read back by PyYAML. Neither grows with the runs; beyond the limits, refused.
#[test]
fn launchers_of_a_million_runs_keep_within_the_schedulers_limits() {
    let tmp = tempfile::tempdir().unwrap();
    let s = scenario(tmp.path());
    let emit = |to: &str, extra: &[&str]| {
        let mut a = vec![
            "dataset",
            "--scenario",
            s.to_str().unwrap(),
            "--count",
            "1000000",
            "--seed",
            "1",
            "--out",
            "/shared/ds",
            "--emit",
            to,
        ];
        a.extend(extra);
        vmt(&a)
    };
    let o = emit("slurm", &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let script = String::from_utf8(o.stdout).unwrap();
    let path = tmp.path().join("ds.sbatch");
    std::fs::write(&path, &script).unwrap();
    let syntax = Command::new("bash").arg("-n").arg(&path).output().unwrap();
    assert!(syntax.status.success(), "{}", stderr(&syntax));
    let array = script
        .lines()
        .find_map(|l| l.strip_prefix("#SBATCH --array="))
        .expect("an --array directive");
    assert_eq!(array, "0-999%100");
    let tasks = number_after(array, "0-") + 1;
    assert!(
        tasks <= 1001,
        "{tasks} tasks beyond Slurm's default MaxArraySize"
    );
    let per = 1_000_000u64.div_ceil(tasks);
    assert_eq!(per, 1000);
    assert!(script.contains("shards of at most 1000 runs"), "{script}");
    for line in [
        "#SBATCH --requeue",
        "#SBATCH --open-mode=append",
        "#SBATCH --cpus-per-task=1",
        "--dependency=afterany:\"$array\"",
        "dataset merge",
        "out=/shared/ds",
        "--count 1000000 --seed 1 --out \"$out\" --quiet",
    ] {
        assert!(script.contains(line), "`{line}` not in:\n{script}");
    }
    assert!(
        !script.contains("--shard "),
        "the tasks read their shard: {script}"
    );
    assert!(script.len() < 4096, "{} bytes", script.len());

    let o = emit("k8s", &["--max-parallel", "50", "--cpus-per-task", "2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let manifest = String::from_utf8(o.stdout).unwrap();
    let path = tmp.path().join("ds.yaml");
    std::fs::write(&path, &manifest).unwrap();
    let check = r#"
import sys, yaml
docs = list(yaml.safe_load_all(open(sys.argv[1])))
kinds = [(d["kind"], d["metadata"]["name"], d["metadata"]["labels"]["vmt.dev/step"]) for d in docs]
assert kinds == [("ConfigMap", "vmt-dataset-scenario", "shards"), ("Job", "vmt-dataset", "shards"), ("Job", "vmt-dataset-merge", "merge")], kinds
job = docs[1]["spec"]
assert job["completionMode"] == "Indexed" and job["completions"] == 1000 and job["parallelism"] == 50, job
pod = job["template"]["spec"]
c = pod["containers"][0]
cmd = c["command"]
assert cmd[:2] == ["vmt", "dataset"] and cmd[cmd.index("--shards") + 1] == "1000" and cmd[cmd.index("--count") + 1] == "1000000", cmd
assert cmd[cmd.index("--out") + 1] == "/data/ds" and cmd[cmd.index("--scenario") + 1] == "/etc/vmt/ds.toml", cmd
assert "--shard" not in cmd, cmd
assert c["resources"]["requests"]["cpu"] == "2" and {"name": "RAYON_NUM_THREADS", "value": "2"} in c["env"], c
mounts = {m["name"]: m["mountPath"] for m in c["volumeMounts"]}
assert mounts == {"data": "/data", "scenario": "/etc/vmt"}, mounts
assert pod["volumes"][0]["persistentVolumeClaim"]["claimName"] == "vmt-dataset", pod["volumes"]
assert "radius_mm = 50.0" in docs[0]["data"]["ds.toml"]
merge = docs[2]["spec"]["template"]["spec"]["containers"][0]["command"]
assert merge == ["vmt", "dataset", "merge", "/data/ds"], merge
print("ok")
"#;
    let py = Command::new("python3")
        .args(["-c", check])
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        py.status.success(),
        "{}\n{manifest}",
        String::from_utf8_lossy(&py.stderr)
    );

    for (to, shards, said) in [
        ("slurm", "1002", "MaxArraySize"),
        ("k8s", "100001", "at most 100000"),
    ] {
        let o = emit(to, &["--shards", shards]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert!(
            e.contains(&format!("--shards {shards}")) && e.contains(said),
            "{e}"
        );
    }
}
