//! vmt-dataset: datasets of N random machines drawn from a scenario's `[dataset]`, each simulated and
//! written with its labels, and a manifest of all of them (CSV and Parquet).
//!
//! Layout of the output folder:
//! - `runs/<id>/run.mcap`, `runs/<id>/scenario.toml` (the sampled machine, an ordinary
//!   scenario), `runs/<id>/labels.json` (`id`, `seed`, `parameters` by name, `keys` of each
//!   parameter, `ground_truth`). A run is written into `runs/.tmp-<id>` and renamed into place
//!   when complete, so a listed run is always whole; an interrupted invocation (kill -9
//!   included) leaves at most temporary folders, which the next one removes before it
//!   continues with the runs still missing. A run folder missing one of its files (deleted
//!   by hand) is not complete: it is simulated again and replaced.
//! - `manifest.csv`, `manifest.parquet`: one row per complete run, sorted by id: `id`, `seed`,
//!   every parameter, every ground-truth figure of the first circular test and its drift
//!   (`radial_drift`, `pivot_drift_<axis>`, µm over the test) as `truth.<key>_<unit>`.
//! - `dataset.json`: the dataset's identity, written before the first run: `seed`, `scenario`
//!   (the file as given), `scenario_fnv1a64` (a hash of its text), `count` (the runs last asked
//!   for) and `labels_format` ([`LABELS_FORMAT`]). An invocation into a folder made with another
//!   seed, scenario text or labels format is refused, and so is one whose --count would leave
//!   complete runs out of the manifest.
//!
//! Run `i`'s seed is splitmix64 of (K, i), so a run does not depend on the number of threads
//! nor on which runs were already done.
//!
//! Beyond one machine, the runs are split into [`shard`]s, run `i` in shard `i mod N`: each
//! shard is made by its own invocation (a Slurm array task, a Kubernetes Indexed Job's pod),
//! into one shared folder or a folder each, and [`merge()`] checks the parts and writes the
//! manifest: the merged folder is byte-identical to a one-machine run's. [`launch`] writes
//! the scheduler's files. A shard writes no manifest; it records itself in
//! `.shards/<I>-of-<N>.json` (which the merge removes), so that a missing run is named with
//! its shard.
//!
//! Modules: [`generate`] makes the runs, [`manifest`] lists them, [`folder`] keeps the folder
//! whole, [`job`] executes one scenario's job, [`shard`], [`mod@merge`] and [`launch`] spread a
//! dataset over a cluster, and [`accuracy`] scores the ball-bar diagnosis on a dataset against
//! its truth. [`chatter`] is the labelled set of simulated milling cuts the chatter detectors
//! are scored on.

pub mod accuracy;
pub mod chatter;
pub mod folder;
pub mod generate;
pub mod job;
pub mod launch;
pub mod manifest;
pub mod merge;
pub mod shard;

pub use folder::{
    FAILED_DIR, IDENTITY_FILE, Identity, LABELS_FORMAT, MAX_RUNS, complete_runs, fnv1a64,
    read_identity,
};
pub use generate::{Outcome, Request, build, run_seed};
pub use manifest::{read_run_labels, write_manifest};
pub use merge::{Merged, merge};
pub use shard::Shard;

use std::path::Path;
use thiserror::Error;
use vmt_logs::FileError;
use vmt_scenario::ScenarioError;

/// What generating or scoring a dataset can fail with.
#[derive(Debug, Error)]
pub enum Error {
    /// The scenario file.
    #[error("{0}")]
    Scenario(#[from] ScenarioError),
    /// A file read or written: which one, where, and why.
    #[error(transparent)]
    File(#[from] FileError),
    /// What was asked for cannot be done (a count out of range, a folder of another dataset),
    /// with what would be accepted.
    #[error("{0}")]
    Request(String),
    /// A run that failed in simulation.
    #[error("{0}")]
    Model(String),
}

impl Error {
    /// An input error at `line` of `file`.
    pub fn input(file: &str, line: Option<usize>, message: impl Into<String>) -> Self {
        FileError::input(file, line, message).into()
    }

    /// An output error for `path`, with the causes under `e`.
    pub fn output(path: &Path, e: impl std::error::Error) -> Self {
        FileError::output(path, e).into()
    }
}
