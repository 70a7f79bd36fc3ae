//! Launchers: a dataset as a Slurm job array or a Kubernetes Indexed Job over its shards, each
//! task making one shard into a shared folder, then a merge step writing the manifest.
//!
//! The launchers hold no list of runs: their size does not grow with the dataset's, and a
//! task learns its shard from the scheduler's environment ([`crate::shard::from_env`]).
//!
//! Limits: Slurm's default `MaxArraySize` is 1001 (task ids 0 to 1000), so an array has at most
//! [`SLURM_MAX_ARRAY_SIZE`] tasks; a Kubernetes Indexed Job's parallelism is at most 10⁵
//! ([`K8S_MAX_INDEXED`], the API server's validation), and its completions are kept within the
//! same bound.

use crate::Error;
use crate::shard::K8S_INDEX;
use std::fmt::Write as _;

/// Tasks of a Slurm job array with the default `MaxArraySize` (1001: ids 0 to 1000).
pub const SLURM_MAX_ARRAY_SIZE: u64 = 1001;
/// The largest completions and parallelism of a Kubernetes Indexed Job.
pub const K8S_MAX_INDEXED: u64 = 100_000;
/// Runs a shard gets by default: about a minute of one core per 700 runs of the XY study.
pub const RUNS_PER_SHARD: u64 = 1000;
/// The most shards chosen by default, within Slurm's default array size.
pub const DEFAULT_MAX_SHARDS: u64 = 1000;
/// Tasks running at once by default (the array's `%` cap, the Job's parallelism).
pub const DEFAULT_PARALLEL: u64 = 100;

/// The scheduler a launcher is written for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scheduler {
    /// A Slurm job array (sbatch script).
    Slurm,
    /// A Kubernetes Indexed Job (YAML manifest).
    Kubernetes,
}

impl Scheduler {
    /// The most tasks (shards) the scheduler takes in one array or Job.
    pub fn max_tasks(self) -> u64 {
        match self {
            Scheduler::Slurm => SLURM_MAX_ARRAY_SIZE,
            Scheduler::Kubernetes => K8S_MAX_INDEXED,
        }
    }
}

/// A dataset to launch: the `vmt dataset` arguments and how to spread them.
#[derive(Clone, Debug)]
pub struct Launch {
    /// The scenario file as given (Slurm tasks run in `workdir`, so a relative path works).
    pub scenario: String,
    /// The scenario file's name and text (the Kubernetes manifest carries it in a ConfigMap).
    pub scenario_file: (String, String),
    /// Runs.
    pub count: u64,
    /// The dataset's seed K.
    pub seed: u64,
    /// The output folder: for Slurm as given (on a file system every node sees); for
    /// Kubernetes, its last name is the folder in the volume mounted at `/data`.
    pub out: String,
    /// Shards (array tasks, completions).
    pub shards: u64,
    /// Tasks at once.
    pub parallel: u64,
    /// Cores per task (threads of each shard).
    pub cpus: u64,
    /// The `vmt` executable the Slurm tasks run.
    pub vmt: String,
    /// The folder the Slurm tasks run in.
    pub workdir: String,
    /// The container image of the Kubernetes pods, with `vmt` on its PATH.
    pub image: String,
}

/// The shards and parallelism of a launch of `count` runs on `scheduler`: `shards` or about
/// [`RUNS_PER_SHARD`] runs each (at most [`DEFAULT_MAX_SHARDS`]), `parallel` or
/// [`DEFAULT_PARALLEL`] (never more than the shards). A count of shards beyond the scheduler's
/// limit or the runs is refused, naming the limit.
pub fn plan(
    scheduler: Scheduler,
    count: u64,
    shards: Option<u64>,
    parallel: Option<u64>,
) -> Result<(u64, u64), Error> {
    let shards = shards.unwrap_or_else(|| count.div_ceil(RUNS_PER_SHARD).min(DEFAULT_MAX_SHARDS));
    let max = scheduler.max_tasks();
    let why = match scheduler {
        Scheduler::Slurm => {
            "a Slurm job array holds at most 1001 tasks with the default MaxArraySize (ids 0 \
             to 1000)"
        }
        Scheduler::Kubernetes => "an Indexed Job's completions and parallelism are at most 100000",
    };
    if shards == 0 || shards > max {
        return Err(Error::Request(format!(
            "--shards {shards}: {why}; give from 1 to {max} shards (each holds count/shards runs)"
        )));
    }
    if shards > count {
        return Err(Error::Request(format!(
            "--shards {shards}: more shards than the {count} runs; give at most {count}"
        )));
    }
    let parallel = parallel.unwrap_or(DEFAULT_PARALLEL).min(shards);
    if parallel == 0 {
        return Err(Error::Request(
            "--max-parallel 0: at least one task must run at a time".into(),
        ));
    }
    Ok((shards, parallel))
}

/// `s` as one word of a POSIX shell: as it is when it holds only characters no shell treats
/// specially, else in single quotes.
pub fn shell_word(s: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || "_./:=+-,@%".contains(c);
    if !s.is_empty() && s.chars().all(plain) {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', r"'\''"))
    }
}

/// `s` as a YAML scalar: a JSON string, which YAML reads as the same text.
fn yaml_str(s: &str) -> String {
    serde_json::Value::String(s.to_string()).to_string()
}

impl Launch {
    /// Runs of the largest shard.
    fn per_shard(&self) -> u64 {
        self.count.div_ceil(self.shards)
    }

    /// The `vmt dataset` arguments every task shares (no shard: each reads its own).
    fn dataset_args(&self, scenario: &str, out: &str) -> Vec<String> {
        vec![
            "dataset".into(),
            "--scenario".into(),
            scenario.into(),
            "--count".into(),
            self.count.to_string(),
            "--seed".into(),
            self.seed.to_string(),
            "--out".into(),
            out.into(),
            "--quiet".into(),
        ]
    }

    /// The sbatch script: a job array of [`Launch::shards`] tasks, [`Launch::parallel`] at a
    /// time, each making the shard `SLURM_ARRAY_TASK_ID` into the shared folder; run with
    /// `bash` it submits itself and, after the array, the merge job.
    pub fn slurm(&self) -> String {
        let mut s = String::new();
        let (w, out, vmt) = (
            shell_word(&self.workdir),
            shell_word(&self.out),
            shell_word(&self.vmt),
        );
        let run: Vec<String> = self
            .dataset_args(&self.scenario, "OUT")
            .iter()
            .map(|a| {
                if a == "OUT" {
                    "\"$out\"".into()
                } else {
                    shell_word(a)
                }
            })
            .collect();
        let _ = write!(
            s,
            r#"#!/bin/bash
# vmt dataset on Slurm: {count} runs of {scenario} (seed {seed}) into {out_text}, as a job
# array of {shards} shards of at most {per} runs, {parallel} at a time, then a merge job.
#
#   bash THIS_FILE     submits the array and, once every task has ended, the merge job
#   sbatch THIS_FILE   submits the array alone (then: vmt dataset merge {out_text})
#
# Task k makes shard k of {shards} (vmt reads SLURM_ARRAY_TASK_ID and SLURM_ARRAY_TASK_COUNT)
# into {out_text}, a folder every node sees. A task killed, requeued or lost with its node
# leaves only whole runs: run again (scontrol requeue JOBID_k), it completes its shard without
# redoing or duplicating a run. The merge checks that every run is there once and whole, names
# the missing ones with their shards, and writes the manifest: the folder is then the one a
# single machine writes for the same scenario, seed and count.
#SBATCH --job-name=vmt-dataset
#SBATCH --array=0-{last}%{parallel}
#SBATCH --cpus-per-task={cpus}
#SBATCH --chdir={w}
#SBATCH --output=vmt-dataset-%A_%a.out
#SBATCH --open-mode=append
#SBATCH --requeue
set -euo pipefail
vmt={vmt}
out={out}
if [ -z "${{SLURM_ARRAY_TASK_ID:-}}" ]; then
    array=$(sbatch --parsable "$0")
    array=${{array%%;*}}
    merge=$(sbatch --parsable --job-name=vmt-dataset-merge --dependency=afterany:"$array" \
        --chdir={w} --output=vmt-dataset-merge-%j.out \
        --wrap="exec $(printf '%q' "$vmt") dataset merge $(printf '%q' "$out")")
    echo "submitted array job $array ({shards} tasks) and merge job ${{merge%%;*}}"
    exit 0
fi
export RAYON_NUM_THREADS="${{SLURM_CPUS_PER_TASK:-{cpus}}}"
exec "$vmt" {run}
"#,
            count = self.count,
            scenario = self.scenario,
            seed = self.seed,
            out_text = self.out,
            shards = self.shards,
            per = self.per_shard(),
            parallel = self.parallel,
            last = self.shards - 1,
            cpus = self.cpus,
            run = run.join(" "),
        );
        s
    }

    /// The Kubernetes manifest: a ConfigMap with the scenario, the Indexed Job of the shards
    /// (label `vmt.dev/step: shards`) and the merge Job (`vmt.dev/step: merge`), both with the
    /// PersistentVolumeClaim `vmt-dataset` mounted at `/data`.
    pub fn kubernetes(&self) -> String {
        let (file, text) = &self.scenario_file;
        let folder = std::path::Path::new(&self.out)
            .file_name()
            .map_or_else(|| "dataset".into(), |n| n.to_string_lossy().into_owned());
        let out = format!("/data/{folder}");
        let scenario = format!("/etc/vmt/{file}");
        let mut shard_args = self.dataset_args(&scenario, &out);
        shard_args.extend(["--shards".into(), self.shards.to_string()]);
        let command = |args: &[String]| {
            let words: Vec<String> = std::iter::once("vmt")
                .chain(args.iter().map(String::as_str))
                .map(yaml_str)
                .collect();
            format!("[{}]", words.join(", "))
        };
        let indented: String = text.lines().map(|l| format!("    {l}\n")).collect();
        let mut s = String::new();
        let _ = write!(
            s,
            r#"# vmt dataset on Kubernetes: {count} runs of {file} (seed {seed}) into {out} on the
# volume claim vmt-dataset (ReadWriteMany), as an Indexed Job of {shards} shards of at most
# {per} runs, {parallel} pods at a time, then a merge Job:
#
#   kubectl apply -f THIS_FILE -l vmt.dev/step=shards
#   kubectl wait --for=condition=complete --timeout=-1s job/vmt-dataset
#   kubectl apply -f THIS_FILE -l vmt.dev/step=merge
#   kubectl wait --for=condition=complete --timeout=-1s job/vmt-dataset-merge
#
# Pod k makes shard k of {shards} (the Job sets {index}; the count is --shards).
# A pod killed or evicted leaves only whole runs; its replacement (same index) completes the
# shard without redoing or duplicating a run. The merge checks that every run is there once and
# whole, names the missing ones with their shards, and writes the manifest. The image must
# hold vmt on its PATH, and any file the scenario names (tables, NC programs) beside it.
apiVersion: v1
kind: ConfigMap
metadata:
  name: vmt-dataset-scenario
  labels:
    app.kubernetes.io/name: vmt-dataset
    vmt.dev/step: shards
data:
  {file_key}: |
{indented}---
apiVersion: batch/v1
kind: Job
metadata:
  name: vmt-dataset
  labels:
    app.kubernetes.io/name: vmt-dataset
    vmt.dev/step: shards
spec:
  completionMode: Indexed
  completions: {shards}
  parallelism: {parallel}
  backoffLimitPerIndex: 3
  template:
    spec:
      restartPolicy: Never
      containers:
        - name: shard
          image: {image}
          command: {shard_command}
          env:
            - name: RAYON_NUM_THREADS
              value: "{cpus}"
          resources:
            requests:
              cpu: "{cpus}"
            limits:
              cpu: "{cpus}"
          volumeMounts:
            - name: data
              mountPath: /data
            - name: scenario
              mountPath: /etc/vmt
              readOnly: true
      volumes:
        - name: data
          persistentVolumeClaim:
            claimName: vmt-dataset
        - name: scenario
          configMap:
            name: vmt-dataset-scenario
---
apiVersion: batch/v1
kind: Job
metadata:
  name: vmt-dataset-merge
  labels:
    app.kubernetes.io/name: vmt-dataset
    vmt.dev/step: merge
spec:
  backoffLimit: 0
  template:
    spec:
      restartPolicy: Never
      containers:
        - name: merge
          image: {image}
          command: {merge_command}
          volumeMounts:
            - name: data
              mountPath: /data
      volumes:
        - name: data
          persistentVolumeClaim:
            claimName: vmt-dataset
"#,
            count = self.count,
            seed = self.seed,
            shards = self.shards,
            per = self.per_shard(),
            parallel = self.parallel,
            index = K8S_INDEX,
            file_key = yaml_str(file),
            image = yaml_str(&self.image),
            shard_command = command(&shard_args),
            merge_command = command(&["dataset".into(), "merge".into(), out.clone()]),
            cpus = self.cpus,
        );
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shell_words_survive_the_shell() {
        assert_eq!(shell_word("scenarios/a.toml"), "scenarios/a.toml");
        assert_eq!(shell_word("my data"), "'my data'");
        assert_eq!(shell_word("it's"), r"'it'\''s'");
        assert_eq!(shell_word(""), "''");
    }

    #[test]
    fn plans_keep_within_the_schedulers_limits() {
        assert_eq!(plan(Scheduler::Slurm, 20, None, None).unwrap(), (1, 1));
        assert_eq!(
            plan(Scheduler::Slurm, 1_000_000, None, None).unwrap(),
            (1000, 100)
        );
        assert_eq!(
            plan(Scheduler::Slurm, 1_000_000, Some(1001), Some(10)).unwrap(),
            (1001, 10)
        );
        let e = plan(Scheduler::Slurm, 1_000_000, Some(1002), None).unwrap_err();
        assert!(e.to_string().contains("MaxArraySize"), "{e}");
        assert!(plan(Scheduler::Kubernetes, 1_000_000, Some(100_000), None).is_ok());
        let e = plan(Scheduler::Kubernetes, 1_000_000, Some(100_001), None).unwrap_err();
        assert!(e.to_string().contains("100000"), "{e}");
        let e = plan(Scheduler::Slurm, 3, Some(4), None).unwrap_err();
        assert!(e.to_string().contains("more shards than the 3 runs"), "{e}");
    }
}
