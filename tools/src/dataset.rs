//! `vmt dataset`: N random machines drawn from a scenario's `[dataset]`, each simulated and
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

use crate::error::CliError;
use crate::formats::write_mcap;
use indicatif::{ProgressBar, ProgressStyle};
use parquet::basic::{LogicalType, Repetition, Type as Physical};
use parquet::data_type::{ByteArray, ByteArrayType, DoubleType, Int64Type};
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::types::Type;
use rayon::prelude::*;
use serde_json::{Map, Value, json};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use vmt_scenario::dataset::{self, Dataset};

/// Prefix of a run folder being written.
const TMP_PREFIX: &str = ".tmp-";
/// The file an invocation holds an exclusive lock on while it writes the folder. The
/// operating system releases the lock when the process ends, killed or not, so the file left
/// behind does not keep the next invocation out.
const LOCK_FILE: &str = ".lock";
/// The folder of the scenarios of runs that failed in simulation, kept to reproduce them with
/// `vmt run`; the next invocation removes it.
pub const FAILED_DIR: &str = "failed-runs";
/// Runs named in an error about many.
const IDS_LISTED: usize = 5;
/// The identity file of a dataset folder.
pub const IDENTITY_FILE: &str = "dataset.json";
/// The version of what `labels.json` holds: 5 since the truth states the drift over each
/// circular test, which the manifest lists (format 4 had none), and gives each axis' backlash
/// and lateral play at the circle's centre (format 4 gave their mean over the arc, which on a
/// partial arc differs by the angular play's growth), 4 since the truth states each
/// axis' angular play
/// (format 3 had none, and a dataset of both would lack it in some runs), 3 since the truth's
/// backlash and servo mismatch figures are the drives' lost motion and lag along the circle
/// (format 2 counted the guideways' viscous friction at the test feed as lost motion), 2 since
/// the injected squareness is in µrad (format 1, without the key in `dataset.json`, wrote it in
/// rad under the same keys). Runs of two formats never share a dataset. A change of a key's meaning or unit bumps it, and so
/// does a key added where the manifest lists it (every run must have its columns); keys only
/// added elsewhere (as the laser truth's drive share at rest was) do not, since no value read
/// before changes.
pub const LABELS_FORMAT: u64 = 5;

/// What `vmt dataset` is asked for.
pub struct Request<'a> {
    /// The scenario with a `[dataset]` section.
    pub scenario: &'a Path,
    /// Number of runs (ids 0..count).
    pub count: u64,
    /// The dataset's seed K.
    pub seed: u64,
    /// Output folder.
    pub out: &'a Path,
    /// No progress bar.
    pub quiet: bool,
}

/// What an invocation did.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// Runs simulated now.
    pub simulated: usize,
    /// Runs already complete.
    pub skipped: usize,
    /// Rows of the manifest.
    pub rows: usize,
    /// Accuracy reports removed because the dataset got more runs.
    pub removed: Vec<PathBuf>,
}

/// The seed of run `i` of a dataset with seed `k`: splitmix64 (Steele et al. 2014) of the
/// state k + (i + 1)·γ, shifted to 63 bits so it is a TOML integer.
pub fn run_seed(k: u64, i: u64) -> u64 {
    let mut z = k.wrapping_add(i.wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    (z ^ (z >> 31)) >> 1
}

/// The files of a complete run folder.
const RUN_FILES: [&str; 3] = ["run.mcap", "scenario.toml", "labels.json"];

/// The most runs of a dataset: their ids have six digits, so that they sort as numbers.
pub const MAX_RUNS: u64 = 1_000_000;

/// The id of run `i`: zero-padded so that names sort like numbers up to a million runs.
fn run_id(i: u64) -> String {
    format!("{i:06}")
}

/// FNV-1a (64 bit) of `text`, as 16 hex digits: the scenario's fingerprint in `dataset.json`.
pub fn fnv1a64(text: &str) -> String {
    let h = text.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    });
    format!("{h:016x}")
}

/// The identity of a dataset folder (`dataset.json`).
#[derive(Clone, Debug, PartialEq)]
pub struct Identity {
    /// The dataset's seed K.
    pub seed: u64,
    /// The scenario file as given when the dataset was started.
    pub scenario: String,
    /// FNV-1a of the scenario's text.
    pub scenario_fnv1a64: String,
    /// The number of runs last asked for.
    pub count: u64,
    /// [`LABELS_FORMAT`] of the runs (1 when `dataset.json` does not say).
    pub labels_format: u64,
}

impl Identity {
    fn json(&self) -> String {
        let v = json!({
            "seed": self.seed,
            "scenario": self.scenario,
            "scenario_fnv1a64": self.scenario_fnv1a64,
            "count": self.count,
            "labels_format": self.labels_format,
        });
        format!("{v:#}\n")
    }
}

/// Reads `dir/dataset.json`; None when the folder has none.
pub fn read_identity(dir: &Path) -> Result<Option<Identity>, CliError> {
    let path = dir.join(IDENTITY_FILE);
    if !path.exists() {
        return Ok(None);
    }
    let v = read_json(&path)?;
    let file = path.display().to_string();
    let bad = |key: &str| {
        CliError::input(
            &file,
            None,
            format!("`{key}` missing or not valid: dataset.json is written by `vmt dataset`"),
        )
    };
    Ok(Some(Identity {
        seed: v["seed"].as_u64().ok_or_else(|| bad("seed"))?,
        scenario: v["scenario"]
            .as_str()
            .ok_or_else(|| bad("scenario"))?
            .into(),
        scenario_fnv1a64: v["scenario_fnv1a64"]
            .as_str()
            .ok_or_else(|| bad("scenario_fnv1a64"))?
            .into(),
        count: v["count"].as_u64().ok_or_else(|| bad("count"))?,
        labels_format: match &v["labels_format"] {
            Value::Null => 1,
            f => f.as_u64().ok_or_else(|| bad("labels_format"))?,
        },
    }))
}

/// Checks that `out` is a new folder or the same dataset (seed, scenario text and labels format)
/// as `want`, and that no complete run has an id of `want.count` or more; then records `want`
/// (keeping the scenario path the dataset was started with). A folder of runs without
/// `dataset.json` was written before it existed, in labels format 1, and is refused.
fn claim(out: &Path, want: &Identity) -> Result<(), CliError> {
    let dir = out.display();
    let done = if out.join("runs").is_dir() {
        complete_runs(out)?
    } else {
        Vec::new()
    };
    let mut record = want.clone();
    match read_identity(out)? {
        Some(have) => {
            record.scenario = have.scenario.clone();
            let mut differs = Vec::new();
            if have.seed != want.seed {
                differs.push(format!(
                    "it was made with --seed {}, this invocation has --seed {}",
                    have.seed, want.seed
                ));
            }
            if have.labels_format != want.labels_format {
                let which = if have.labels_format < want.labels_format {
                    "an older vmt's: format 3 had no angular play, format 2 also counted the \
                     viscous friction as backlash, format 1 or unknown also wrote the injected \
                     squareness in rad"
                } else {
                    "a newer vmt's"
                };
                return Err(CliError::Argument(format!(
                    "{dir} holds runs with labels in format {} ({which}) and this vmt writes \
                     format {}; the two are never mixed: give a new --out folder",
                    have.labels_format, want.labels_format
                )));
            }
            if have.scenario_fnv1a64 != want.scenario_fnv1a64 {
                differs.push(format!(
                    "it was made from another scenario text ({} when started, hash {}; {} now, hash {})",
                    have.scenario, have.scenario_fnv1a64, want.scenario, want.scenario_fnv1a64
                ));
            }
            if !differs.is_empty() {
                return Err(CliError::Argument(format!(
                    "{dir} holds another dataset: {}; continue it with the same --seed and \
                     scenario, or give a new --out folder",
                    differs.join(" and ")
                )));
            }
        }
        None => {
            if let Some(run) = done.first() {
                return Err(CliError::Argument(format!(
                    "{dir} holds runs (run {} and more) but no {IDENTITY_FILE}: an older vmt \
                     wrote them, in labels format 1 or unknown, which this vmt does not mix with \
                     its own; give a new --out folder",
                    name_of(run)
                )));
            }
        }
    }
    let beyond: Vec<String> = done
        .iter()
        .map(|p| name_of(p))
        .filter(|n| n.parse::<u64>().map_or(true, |i| i >= want.count))
        .collect();
    if let Some(last) = beyond.last() {
        return Err(CliError::Argument(format!(
            "--count {}: {dir} already holds complete runs up to id {last}, which a dataset of \
             ids below {} would leave out of its manifest; give --count {} or more to continue \
             this dataset, or a new --out folder",
            want.count,
            want.count,
            last.parse::<u64>()
                .map_or(0, |i| i + 1)
                .max(done.len() as u64)
        )));
    }
    std::fs::create_dir_all(out).map_err(|e| CliError::output(out, e))?;
    write_aside(out, IDENTITY_FILE, |tmp| write_file(tmp, &record.json()))
}

/// Writes `dir/name` with `write` into `dir/.tmp-name` and renames it in, so that a kill
/// leaves the previous file whole rather than half of a new one.
fn write_aside(
    dir: &Path,
    name: &str,
    write: impl FnOnce(&Path) -> Result<(), CliError>,
) -> Result<(), CliError> {
    let (tmp, path) = (dir.join(format!("{TMP_PREFIX}{name}")), dir.join(name));
    write(&tmp)?;
    std::fs::rename(&tmp, &path).map_err(|e| CliError::output(&path, e))
}

/// Simulates the runs of `req` that are not complete yet and rebuilds the manifest.
pub fn build(req: &Request) -> Result<Outcome, CliError> {
    if !(1..=MAX_RUNS).contains(&req.count) {
        return Err(CliError::Argument(format!(
            "--count {}: a dataset holds from 1 to {MAX_RUNS} runs (ids of six digits)",
            req.count
        )));
    }
    let file = req.scenario.display().to_string();
    let text = std::fs::read_to_string(req.scenario)
        .map_err(|e| CliError::input(&file, None, e.to_string()))?;
    let base = req.scenario.parent().unwrap_or(Path::new("."));
    let ds = dataset::from_text(&text, &file)?.ok_or_else(|| {
        CliError::input(
            &file,
            None,
            "no [dataset] section: `vmt dataset` needs [dataset.parameters]",
        )
    })?;
    // The template itself must load, so a scenario error is reported once, not per run.
    vmt_scenario::parse(&text, &file, Some(base))?;
    // Only the runs still to do: a resumed dataset of many runs does not draw them all again.
    let done_before: BTreeSet<String> = if req.out.join("runs").is_dir() {
        complete_runs(req.out)?.iter().map(|p| name_of(p)).collect()
    } else {
        BTreeSet::new()
    };
    check_draws(&ds, &file, base, req, &done_before)?;
    let _lock = lock(req.out)?;
    claim(
        req.out,
        &Identity {
            seed: req.seed,
            scenario: file.clone(),
            scenario_fnv1a64: fnv1a64(&text),
            count: req.count,
            labels_format: LABELS_FORMAT,
        },
    )?;
    let runs = req.out.join("runs");
    std::fs::create_dir_all(&runs).map_err(|e| CliError::output(&runs, e))?;
    remove_leftovers(&runs)?;
    let done: BTreeSet<String> = complete_runs(req.out)?
        .iter()
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect();
    let todo: Vec<u64> = (0..req.count)
        .filter(|i| !done.contains(&run_id(*i)))
        .collect();
    let removed = if todo.is_empty() {
        Vec::new()
    } else {
        remove_stale_reports(req.out)?
    };
    let bar = progress(todo.len() as u64, req.quiet);
    let results: Vec<(u64, Result<(), CliError>)> = todo
        .par_iter()
        .map(|&i| {
            let r = simulate_one(&ds, &file, base, &runs, i, run_seed(req.seed, i));
            bar.inc(1);
            (i, r)
        })
        .collect();
    bar.finish_and_clear();
    let rows = write_manifest(req.out)?;
    let failed: Vec<(u64, CliError)> = results
        .into_iter()
        .filter_map(|(i, r)| r.err().map(|e| (i, e)))
        .collect();
    if !failed.is_empty() {
        return Err(failed_runs(req, &ds, &file, todo.len(), failed));
    }
    Ok(Outcome {
        simulated: todo.len(),
        skipped: req.count as usize - todo.len(),
        rows,
        removed,
    })
}

/// Takes the exclusive lock of dataset folder `out` (creating it), so that a second
/// `vmt dataset` on the same folder is refused rather than writing the same runs.
fn lock(out: &Path) -> Result<std::fs::File, CliError> {
    std::fs::create_dir_all(out).map_err(|e| CliError::output(out, e))?;
    let path = out.join(LOCK_FILE);
    let file = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .map_err(|e| CliError::output(&path, e))?;
    match file.try_lock() {
        Ok(()) => Ok(file),
        Err(std::fs::TryLockError::WouldBlock) => Err(CliError::Argument(format!(
            "{}: another `vmt dataset` is writing this dataset folder (it holds the lock {}); \
             wait for it to finish, or give another --out folder",
            out.display(),
            path.display()
        ))),
        Err(std::fs::TryLockError::Error(e)) => Err(CliError::output(&path, e)),
    }
}

/// Draws and builds every run's scenario, as each run does before it simulates, so that a
/// distribution drawing a value the scenario does not accept is refused before anything is
/// simulated or written (a draw is cheap; a run is not). The refusal names, per entry, its
/// line in the scenario, the share of the runs that draw an unacceptable value and the first
/// run's value and what is accepted.
fn check_draws(
    ds: &Dataset,
    file: &str,
    base: &Path,
    req: &Request,
    done: &BTreeSet<String>,
) -> Result<(), CliError> {
    let refused: Vec<(u64, vmt_scenario::ScenarioError)> = (0..req.count)
        .into_par_iter()
        .filter(|i| !done.contains(&run_id(*i)))
        .filter_map(|i| {
            let sample = ds.sample(run_seed(req.seed, i));
            let name = format!("{file} (run {})", run_id(i));
            vmt_scenario::parse(&sample.text, &name, Some(base))
                .err()
                .map(|e| (i, e))
        })
        .collect();
    if refused.is_empty() {
        return Ok(());
    }
    // Grouped by the entry that drew the refused key (or the key, when no entry draws it).
    let mut groups: Vec<(String, Vec<(u64, vmt_scenario::ScenarioError)>)> = Vec::new();
    for (i, e) in refused {
        let key = e.key.clone().unwrap_or_default();
        let group = ds.entry_of(&key).map_or(key, |p| p.name.clone());
        match groups.iter_mut().find(|g| g.0 == group) {
            Some(g) => g.1.push((i, e)),
            None => groups.push((group, vec![(i, e)])),
        }
    }
    let lines: Vec<String> = groups
        .iter()
        .map(|(_, runs)| refused_draws(ds, file, req.count, runs))
        .collect();
    Err(CliError::Argument(format!(
        "{}\nnothing was simulated: change the distributions so that every draw is accepted",
        lines.join("\n")
    )))
}

/// One line of [`check_draws`]' refusal: the runs whose draws of one entry are refused.
fn refused_draws(
    ds: &Dataset,
    file: &str,
    count: u64,
    runs: &[(u64, vmt_scenario::ScenarioError)],
) -> String {
    let (first, e) = &runs[0];
    let key = e.key.as_deref().unwrap_or_default();
    let share = format!(
        "{} of the {count} runs ({}) draw a value the scenario does not accept",
        runs.len(),
        listed(runs.iter().map(|r| r.0))
    );
    match ds.entry_of(key) {
        Some(p) => {
            let at = p
                .position
                .map(|(l, c)| format!(":{l}:{c}"))
                .unwrap_or_default();
            let entry = vmt_scenario::KeyPath::of(&["dataset", "parameters", &p.name]);
            format!(
                "{file}{at}: key `{entry}`: {share}; run {}: key `{key}`: {}",
                run_id(*first),
                e.message
            )
        }
        None => {
            // A key no entry draws, refused for what an entry beside it drew.
            let beside: Vec<String> = ds
                .entries_beside(key)
                .iter()
                .map(|p| {
                    let at = p.position.map(|(l, c)| format!(" ({file}:{l}:{c})"));
                    let entry = vmt_scenario::KeyPath::of(&["dataset", "parameters", &p.name]);
                    format!("`{entry}`{}", at.unwrap_or_default())
                })
                .collect();
            if beside.is_empty() {
                format!("{e}: {share}")
            } else {
                format!(
                    "{e}: {share}; entries drawing that table: {}",
                    beside.join(", ")
                )
            }
        }
    }
}

/// The first ids of `ids`, and how many more.
fn listed(ids: impl ExactSizeIterator<Item = u64>) -> String {
    let n = ids.len();
    let mut text: Vec<String> = ids.take(IDS_LISTED).map(run_id).collect();
    if n > IDS_LISTED {
        text.push(format!("and {} more", n - IDS_LISTED));
    }
    text.join(", ")
}

/// The error of runs that failed in simulation: each keeps its scenario in `failed-runs/` to be
/// reproduced with `vmt run`. The dataset stops incomplete: its draws come from --seed, so the
/// same runs fail again; the machines drawn must change (the distributions, so a new folder).
fn failed_runs(
    req: &Request,
    ds: &Dataset,
    file: &str,
    simulated: usize,
    failed: Vec<(u64, CliError)>,
) -> CliError {
    let dir = req.out.join(FAILED_DIR);
    let kept = std::fs::create_dir_all(&dir).is_ok()
        && failed.iter().all(|(i, _)| {
            let sample = ds.sample(run_seed(req.seed, *i));
            std::fs::write(dir.join(format!("{}.toml", run_id(*i))), sample.text).is_ok()
        });
    let (first, e) = &failed[0];
    let scenario = if kept {
        format!(
            "its scenario: {}",
            dir.join(format!("{}.toml", run_id(*first))).display()
        )
    } else {
        format!("its scenario could not be kept in {}", dir.display())
    };
    CliError::Model(format!(
        "{} of the {simulated} runs simulated failed ({}); the others are written. Run {} \
         ({scenario}): {e}. The runs are drawn from --seed, so running again fails the same \
         way: change the distributions in [dataset.parameters] of {file} so that such machines \
         are not drawn, and write the dataset into a new --out folder",
        failed.len(),
        listed(failed.iter().map(|f| f.0)),
        run_id(*first)
    ))
}

/// Removes the accuracy report of a dataset about to get more runs: it describes fewer runs
/// than the folder will hold. Returns the files removed.
fn remove_stale_reports(out: &Path) -> Result<Vec<PathBuf>, CliError> {
    let mut removed = Vec::new();
    for name in ["accuracy.md", "accuracy.json"] {
        let path = out.join(name);
        if path.is_file() {
            std::fs::remove_file(&path).map_err(|e| CliError::output(&path, e))?;
            removed.push(path);
        }
    }
    Ok(removed)
}

fn progress(len: u64, quiet: bool) -> ProgressBar {
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(len)
    };
    bar.set_style(
        ProgressStyle::with_template(
            "runs [{bar:40}] {pos}/{len} {elapsed_precise} (eta {eta}, {per_sec})",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar
}

/// Removes the temporary folders of runs an interrupted invocation did not finish, and the
/// scenarios of the runs that failed in the last one.
fn remove_leftovers(runs: &Path) -> Result<(), CliError> {
    // A manifest half-written when the previous invocation was killed.
    if let Some(dir) = runs.parent() {
        let failed = dir.join(FAILED_DIR);
        if failed.is_dir() {
            std::fs::remove_dir_all(&failed).map_err(|e| CliError::output(&failed, e))?;
        }
        for name in ["manifest.csv", "manifest.parquet"] {
            let tmp = dir.join(format!("{TMP_PREFIX}{name}"));
            if tmp.exists() {
                std::fs::remove_file(&tmp).map_err(|e| CliError::output(&tmp, e))?;
            }
        }
    }
    for entry in std::fs::read_dir(runs).map_err(|e| CliError::output(runs, e))? {
        let path = entry.map_err(|e| CliError::output(runs, e))?.path();
        if name_of(&path).starts_with(TMP_PREFIX) {
            std::fs::remove_dir_all(&path).map_err(|e| CliError::output(&path, e))?;
        }
    }
    Ok(())
}

fn name_of(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// The complete run folders of dataset `dir`, sorted by id.
pub fn complete_runs(dir: &Path) -> Result<Vec<PathBuf>, CliError> {
    let runs = dir.join("runs");
    let mut out = Vec::new();
    for entry in std::fs::read_dir(&runs)
        .map_err(|e| CliError::input(&runs.display().to_string(), None, e.to_string()))?
    {
        let path = entry.map_err(|e| CliError::output(&runs, e))?.path();
        if !name_of(&path).starts_with(TMP_PREFIX)
            && RUN_FILES.iter().all(|f| path.join(f).is_file())
        {
            out.push(path);
        }
    }
    out.sort_by_key(|p| (name_of(p).len(), name_of(p)));
    Ok(out)
}

/// Samples, simulates and writes run `i` into a temporary folder, then renames it into place.
fn simulate_one(
    ds: &Dataset,
    file: &str,
    base: &Path,
    runs: &Path,
    i: u64,
    seed: u64,
) -> Result<(), CliError> {
    let id = run_id(i);
    let sample = ds.sample(seed);
    let scenario = vmt_scenario::parse(&sample.text, &format!("{file} (run {id})"), Some(base))?;
    let run = crate::job::execute(&scenario, &sample.text, None, true)
        .map_err(|e| CliError::Model(format!("seed {seed}: {e}")))?;
    let tmp = runs.join(format!("{TMP_PREFIX}{id}"));
    std::fs::create_dir_all(&tmp).map_err(|e| CliError::output(&tmp, e))?;
    write_mcap(&run, &tmp.join("run.mcap"))?;
    write_file(&tmp.join("scenario.toml"), &sample.text)?;
    let parameters: Map<String, Value> = sample
        .values
        .iter()
        .map(|(k, v)| (k.clone(), json!(v)))
        .collect();
    let keys: Map<String, Value> = ds
        .parameters
        .iter()
        .map(|p| (p.name.clone(), json!(p.keys)))
        .collect();
    let labels = json!({
        "id": id,
        "seed": seed,
        "parameters": parameters,
        "keys": keys,
        "ground_truth": run.ground_truth,
    });
    write_file(&tmp.join("labels.json"), &format!("{labels:#}\n"))?;
    let dest = runs.join(&id);
    // A folder of this id is an incomplete one (the run is only simulated when it is not
    // complete): the new run, the same bytes as the lost one, takes its place.
    if dest.exists() {
        std::fs::remove_dir_all(&dest).map_err(|e| CliError::output(&dest, e))?;
    }
    std::fs::rename(&tmp, &dest).map_err(|e| CliError::output(&dest, e))
}

fn write_file(path: &Path, text: &str) -> Result<(), CliError> {
    std::fs::write(path, text).map_err(|e| CliError::output(path, e))
}

/// The manifest: column names and one row per run (id, seed, then numbers or gaps), and what
/// the Parquet file's key-value metadata says of the columns.
struct Manifest {
    numbers: Vec<String>,
    rows: Vec<(String, i64, Vec<Option<f64>>)>,
    metadata: Vec<(String, String)>,
}

/// The unit of the number at a scenario key path, from its name's unit tokens (the scenario's
/// convention: `backlash_um`, `kv_per_s`, `coulomb_n`, `feed_mm_min`, `stiffness_n_per_um`,
/// `capacity_j_per_k`, `alpha_per_k`); None when a token is not one listed here.
fn key_unit(key: &str) -> Option<String> {
    // The last name of the path, without an index (`center_mm[0]`) or quotes.
    let last = key.rsplit('.').next().unwrap_or(key);
    let name = last.split('[').next().unwrap_or(last).trim_matches('"');
    let unit = |t: &str| -> Option<&'static str> {
        Some(match t {
            "um" => "µm",
            "mm" => "mm",
            "m" => "m",
            "urad" => "µrad",
            "deg" => "deg",
            "n" => "N",
            "j" => "J",
            "w" => "W",
            "kg" => "kg",
            "hz" => "Hz",
            "c" => "°C",
            "k" => "K",
            "s" => "s",
            "ms" => "ms",
            "ppm" => "ppm",
            "us" => "µs",
            "min" => "min",
            _ => return None,
        })
    };
    let tokens: Vec<&str> = name.split('_').collect();
    if let Some(p) = tokens.iter().position(|t| *t == "per") {
        // `<quantity>_per_<unit>` is 1/unit; `<unit>_per_<unit>` a ratio of the two.
        let below = unit(tokens.get(p + 1)?)?;
        if p + 2 != tokens.len() {
            return None;
        }
        let above = |q: usize| p.checked_sub(q).and_then(|i| unit(tokens[i]));
        return Some(match (above(2), above(1)) {
            (Some(a), Some(b)) => format!("{a}·{b}/{below}"),
            (None, Some(b)) => format!("{b}/{below}"),
            _ => format!("1/{below}"),
        });
    }
    match tokens.as_slice() {
        // `feed_mm_min`, `stribeck_m_s`: a speed.
        [.., a, t @ ("min" | "s")] if unit(a).is_some_and(|u| u.ends_with('m')) => {
            Some(format!("{}/{}", unit(a)?, unit(t)?))
        }
        [_, .., last] => unit(last).map(str::to_string),
        _ => None,
    }
}

/// The manifest's column of ground-truth figure `key` (as sim's `truth::test_figures` computes
/// them): `truth.<key>_<unit>`, the unit in the scenario's tokens (`um`, `ppm`, `um_per_m`, `ms`,
/// `urad`).
fn truth_column(key: &str) -> String {
    let unit = if key.starts_with("scale_mismatch") {
        "ppm"
    } else if key.starts_with("squareness") {
        "um_per_m"
    } else if key.starts_with("servo_mismatch") {
        "ms"
    } else if key.starts_with("angular_play") {
        "urad"
    } else {
        "um"
    };
    format!("truth.{key}_{unit}")
}

/// The Parquet key-value metadata: `unit.<column>` for every column of a known unit and
/// `keys.<column>` (a JSON list) for a parameter of an entry with `keys`.
fn column_metadata(names: &BTreeSet<String>, keys: &Map<String, Value>) -> Vec<(String, String)> {
    let mut out = vec![(
        "seed".to_string(),
        "each run's seed (simulation.seed)".into(),
    )];
    for name in names {
        let listed: Vec<&str> = keys
            .get(name.as_str())
            .and_then(Value::as_array)
            .into_iter()
            .flatten()
            .filter_map(Value::as_str)
            .collect();
        let units: BTreeSet<Option<String>> = listed.iter().map(|k| key_unit(k)).collect();
        match units.into_iter().collect::<Vec<_>>().as_slice() {
            [Some(unit)] => out.push((format!("unit.{name}"), unit.clone())),
            [] => out.extend(key_unit(name).map(|u| (format!("unit.{name}"), u))),
            _ => {}
        }
        if listed.len() > 1 || listed.first().is_some_and(|k| k != name) {
            out.push((format!("keys.{name}"), json!(listed).to_string()));
        }
    }
    out
}

/// Reads every complete run's labels into the manifest's rows; a run without a parameter the
/// others have is damaged.
fn manifest(dir: &Path) -> Result<Manifest, CliError> {
    let runs = complete_runs(dir)?;
    let labels = runs
        .iter()
        .map(|p| read_run_labels(p))
        .collect::<Result<Vec<_>, _>>()?;
    let figures =
        |l: &Value| crate::diagnose::truth_effects(&l["ground_truth"], 0).unwrap_or_default();
    let mut names = BTreeSet::new();
    let mut truths = BTreeSet::new();
    for l in &labels {
        names.extend(
            l["parameters"]
                .as_object()
                .into_iter()
                .flatten()
                .map(|(k, _)| k.clone()),
        );
        truths.extend(figures(l).keys().cloned());
    }
    // Every run of a dataset draws the same parameters and has the same truth figures (a
    // trace's closing error is missing only from a trace with no reading, which no run
    // completes), so one that lacks one the others have was edited.
    for (run, l) in runs.iter().zip(&labels) {
        let lacks = names
            .iter()
            .find(|n| !l["parameters"][n].is_number())
            .map(|n| format!("parameters.{n}"))
            .or_else(|| {
                let f = figures(l);
                truths.iter().find(|k| !f.contains_key(*k)).map(|k| {
                    let section = if k.contains("drift") {
                        "drift"
                    } else {
                        "figures"
                    };
                    format!("ground_truth.ballbar.tests[0].{section}.{k}")
                })
            });
        if let Some(key) = lacks {
            return Err(CliError::input(
                &run.join("labels.json").display().to_string(),
                None,
                format!(
                    "`{key}` is missing (other runs have it); the run is damaged: remove its \
                     folder and run `vmt dataset` again with the same arguments to simulate it \
                     anew"
                ),
            ));
        }
    }
    let rows = labels
        .iter()
        .map(|l| {
            let f = figures(l);
            let params = names.iter().map(|n| l["parameters"][n].as_f64());
            let truth = truths.iter().map(|k| f.get(k).and_then(Value::as_f64));
            (
                l["id"].as_str().unwrap_or_default().to_string(),
                l["seed"].as_i64().unwrap_or(-1),
                params.chain(truth).collect(),
            )
        })
        .collect();
    let keys = labels
        .first()
        .and_then(|l| l["keys"].as_object().cloned())
        .unwrap_or_default();
    let mut metadata = column_metadata(&names, &keys);
    let truth_columns: Vec<String> = truths.iter().map(|k| truth_column(k)).collect();
    metadata.extend(
        truth_columns
            .iter()
            .filter_map(|c| Some((format!("unit.{c}"), key_unit(c)?))),
    );
    let numbers = names.into_iter().chain(truth_columns).collect();
    Ok(Manifest {
        numbers,
        rows,
        metadata,
    })
}

fn read_json(path: &Path) -> Result<Value, CliError> {
    let file = path.display().to_string();
    let text =
        std::fs::read_to_string(path).map_err(|e| CliError::input(&file, None, e.to_string()))?;
    serde_json::from_str(&text).map_err(|e| CliError::input(&file, Some(e.line()), e.to_string()))
}

/// Reads run folder `run`'s `labels.json`, checked to be what `vmt dataset` writes: an
/// object with the run's `id` (the folder's name), its `seed` and the `parameters`, `keys` and
/// `ground_truth` objects. A label that is not JSON (named with serde's line and column) or
/// lacks one of them is a damaged run, an error naming the file: not a run to leave out.
pub fn read_run_labels(run: &Path) -> Result<Value, CliError> {
    let path = run.join("labels.json");
    let file = path.display().to_string();
    let damaged = |what: String| {
        format!(
            "{what}; the run is damaged: remove its folder and run `vmt dataset` again with the \
             same arguments to simulate it anew"
        )
    };
    let text =
        std::fs::read_to_string(&path).map_err(|e| CliError::input(&file, None, e.to_string()))?;
    let v: Value = serde_json::from_str(&text)
        .map_err(|e| CliError::input(&file, Some(e.line()), damaged(format!("not JSON ({e})"))))?;
    match label_problem(&v, &name_of(run)) {
        Some(what) => Err(CliError::input(&file, None, damaged(what))),
        None => Ok(v),
    }
}

/// What makes `v` not the label of run `id`, if anything.
fn label_problem(v: &Value, id: &str) -> Option<String> {
    let holds = "a label holds id, seed, parameters, keys and ground_truth";
    if !v.is_object() {
        return Some(format!("not a JSON object ({holds})"));
    }
    if let Some(k) = ["id", "seed", "parameters", "keys", "ground_truth"]
        .into_iter()
        .find(|k| v.get(k).is_none())
    {
        return Some(format!("the key `{k}` is missing ({holds})"));
    }
    if v["id"].as_str() != Some(id) {
        return Some(format!(
            "`id` is {}, not the run's folder name \"{id}\"",
            v["id"]
        ));
    }
    if v["seed"].as_u64().is_none() {
        return Some(format!("`seed` is {}, not a whole number", v["seed"]));
    }
    if let Some(k) = ["parameters", "keys", "ground_truth"]
        .into_iter()
        .find(|k| !v[k].is_object())
    {
        return Some(format!("`{k}` is {}, not an object", v[k]));
    }
    missing_number(v)
}

/// The first parameter or truth figure run label `v` lacks: every entry `keys` lists has its
/// number in `parameters`, and the truth has figures of its first circular test, each a number
/// (the manifest would hold NaN or an empty cell instead).
fn missing_number(v: &Value) -> Option<String> {
    let names = v["keys"].as_object().into_iter().flatten().map(|(k, _)| k);
    if let Some(name) = names.into_iter().find(|n| !v["parameters"][n].is_number()) {
        return Some(format!(
            "`parameters.{name}` is missing or not a number (`keys` lists the entry)"
        ));
    }
    let truth = &v["ground_truth"];
    let ballbar = truth.get("ballbar");
    if ballbar.is_some_and(Value::is_null) || (ballbar.is_none() && truth.get("milling").is_some())
    {
        // A job without a circular test (a positioning test's truth has a null `ballbar`, a
        // milling run's none but its `milling`; a damaged label lacks the key): no figures.
        return None;
    }
    let Some(figures) = crate::diagnose::truth_figures(&v["ground_truth"], 0) else {
        return Some(
            "`ground_truth.ballbar.tests[0].figures` is missing (the truth of the run's \
             circular test)"
                .into(),
        );
    };
    let drift = crate::diagnose::truth_drift(truth, 0).into_iter().flatten();
    figures
        .iter()
        .map(|kv| ("figures", kv))
        .chain(drift.map(|kv| ("drift", kv)))
        .find(|(_, (_, f))| !f.is_number())
        .map(|(section, (k, f))| {
            format!("`ground_truth.ballbar.tests[0].{section}.{k}` is {f}, not a number")
        })
}

/// Rebuilds `manifest.csv` and `manifest.parquet` from the labels; returns the number of rows.
pub fn write_manifest(dir: &Path) -> Result<usize, CliError> {
    let m = manifest(dir)?;
    write_aside(dir, "manifest.csv", |tmp| write_csv(&m, tmp))?;
    write_aside(dir, "manifest.parquet", |tmp| {
        write_parquet(&m, tmp).map_err(|e| CliError::output(&dir.join("manifest.parquet"), e))
    })?;
    Ok(m.rows.len())
}

fn write_csv(m: &Manifest, path: &Path) -> Result<(), CliError> {
    let err = |e: csv::Error| CliError::output(path, e);
    let mut w = csv::Writer::from_path(path).map_err(err)?;
    let header = ["id", "seed"].into_iter().map(String::from);
    w.write_record(header.chain(m.numbers.iter().cloned()))
        .map_err(err)?;
    for (id, seed, values) in &m.rows {
        let cells = values
            .iter()
            .map(|v| v.map(|x| x.to_string()).unwrap_or_default());
        w.write_record([id.clone(), seed.to_string()].into_iter().chain(cells))
            .map_err(err)?;
    }
    w.flush().map_err(|e| CliError::output(path, e))
}

/// One row group, written with parquet's column writers: `id` (string), `seed` (int64), and a
/// nullable double per number column (a run without that figure is a null).
fn column(
    name: &str,
    t: Physical,
    rep: Repetition,
) -> parquet::schema::types::PrimitiveTypeBuilder<'_> {
    Type::primitive_type_builder(name, t).with_repetition(rep)
}

fn write_parquet(m: &Manifest, path: &Path) -> parquet::errors::Result<()> {
    let mut fields = vec![
        Arc::new(
            column("id", Physical::BYTE_ARRAY, Repetition::REQUIRED)
                .with_logical_type(Some(LogicalType::String))
                .build()?,
        ),
        Arc::new(column("seed", Physical::INT64, Repetition::REQUIRED).build()?),
    ];
    for n in &m.numbers {
        fields.push(Arc::new(
            column(n, Physical::DOUBLE, Repetition::OPTIONAL).build()?,
        ));
    }
    let schema = Arc::new(
        Type::group_type_builder("manifest")
            .with_fields(fields)
            .build()?,
    );
    let file = std::fs::File::create(path)?;
    let metadata = m
        .metadata
        .iter()
        .map(|(k, v)| KeyValue::new(k.clone(), v.clone()))
        .collect();
    let props = Arc::new(
        WriterProperties::builder()
            .set_key_value_metadata(Some(metadata))
            .build(),
    );
    let mut writer = SerializedFileWriter::new(file, schema, props)?;
    let mut group = writer.next_row_group()?;
    let mut index = 0;
    while let Some(mut col) = group.next_column()? {
        match index {
            0 => {
                let ids: Vec<ByteArray> = m.rows.iter().map(|r| r.0.as_str().into()).collect();
                col.typed::<ByteArrayType>().write_batch(&ids, None, None)?;
            }
            1 => {
                let seeds: Vec<i64> = m.rows.iter().map(|r| r.1).collect();
                col.typed::<Int64Type>().write_batch(&seeds, None, None)?;
            }
            _ => {
                let cells = m.rows.iter().map(|r| r.2[index - 2]);
                let values: Vec<f64> = cells.clone().flatten().collect();
                let defined: Vec<i16> = cells.map(|c| i16::from(c.is_some())).collect();
                col.typed::<DoubleType>()
                    .write_batch(&values, Some(&defined), None)?;
            }
        }
        col.close()?;
        index += 1;
    }
    group.close()?;
    writer.close()?;
    Ok(())
}

/// `vmt dataset`: builds the dataset and prints what was done.
pub fn command(
    scenario: &Path,
    count: u64,
    seed: u64,
    out: &Path,
    quiet: bool,
) -> Result<(), CliError> {
    let start = std::time::Instant::now();
    let o = build(&Request {
        scenario,
        count,
        seed,
        out,
        quiet,
    })?;
    for path in &o.removed {
        crate::outln!(
            "removed {}: it scored fewer runs than the dataset now holds (run `vmt accuracy` again)",
            path.display()
        )?;
    }
    let minutes = start.elapsed().as_secs_f64() / 60.0;
    crate::outln!(
        "{} runs simulated in {:.1} min ({:.1} runs/min on {} threads), {} already complete; \
         manifest of {} runs: {}",
        o.simulated,
        minutes,
        o.simulated as f64 / minutes.max(1e-9),
        rayon::current_num_threads(),
        o.skipped,
        o.rows,
        out.join("manifest.{csv,parquet}").display()
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::key_unit;

    /// Units read from the scenario's key names, compound ones included (a suffix match had
    /// given `µm` for N/µm and `1/K` for J/K).
    #[test]
    fn units_follow_the_key_names() {
        for (key, unit) in [
            ("machine.axes.x.drive.backlash_um", Some("µm")),
            ("machine.axes.x.servo.kv_per_s", Some("1/s")),
            ("machine.axes.x.drive.guide_friction.coulomb_n", Some("N")),
            ("job.feed_mm_min", Some("mm/min")),
            (
                "machine.axes.x.drive.guide_friction.stribeck_m_s",
                Some("m/s"),
            ),
            ("instruments.ballbar.setup_drift_um_per_min", Some("µm/min")),
            (
                "machine.axes.x.drive.screw_stiffness_n_per_um",
                Some("N/µm"),
            ),
            (
                "machine.axes.x.drive.guide_friction.sigma1_n_s_per_m",
                Some("N·s/m"),
            ),
            ("machine.thermal.nodes[0].capacity_j_per_k", Some("J/K")),
            (
                "machine.thermal.links.\"G-Z\".translation_um_per_k",
                Some("µm/K"),
            ),
            ("instruments.ballbar.bar_alpha_per_k", Some("1/K")),
            ("machine.axes.x.drive.encoder_counts_per_rev", None),
            ("machine.errors.squareness.ec0y_urad", Some("µrad")),
            ("truth.backlash_x_um", Some("µm")),
            ("truth.scale_mismatch_xy_ppm", Some("ppm")),
            ("truth.squareness_xy_um_per_m", Some("µm/m")),
            ("truth.servo_mismatch_xy_ms", Some("ms")),
        ] {
            assert_eq!(key_unit(key).as_deref(), unit, "{key}");
        }
    }
}
