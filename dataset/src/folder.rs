//! The dataset folder: its identity (`dataset.json`), its complete runs, the lock an
//! invocation holds while it writes, and files written aside and renamed into place.

use crate::Error;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

/// Prefix of a run folder being written.
pub(crate) const TMP_PREFIX: &str = ".tmp-";

/// The file an invocation holds an exclusive lock on while it writes the folder. The
/// operating system releases the lock when the process ends, killed or not, so the file left
/// behind does not keep the next invocation out.
pub(crate) const LOCK_FILE: &str = ".lock";

/// The folder of the scenarios of runs that failed in simulation, kept to reproduce them with
/// `vmt run`; the next invocation removes it.
pub const FAILED_DIR: &str = "failed-runs";

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

/// The files of a complete run folder.
pub(crate) const RUN_FILES: [&str; 3] = ["run.mcap", "scenario.toml", "labels.json"];

/// The most runs of a dataset: their ids have six digits, so that they sort as numbers.
pub const MAX_RUNS: u64 = 1_000_000;

/// The id of run `i`: zero-padded so that names sort like numbers up to a million runs.
pub(crate) fn run_id(i: u64) -> String {
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
pub fn read_identity(dir: &Path) -> Result<Option<Identity>, Error> {
    let path = dir.join(IDENTITY_FILE);
    if !path.exists() {
        return Ok(None);
    }
    let v = read_json(&path)?;
    let file = path.display().to_string();
    let bad = |key: &str| {
        Error::input(
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
pub(crate) fn claim(out: &Path, want: &Identity) -> Result<(), Error> {
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
                return Err(Error::Request(format!(
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
                return Err(Error::Request(format!(
                    "{dir} holds another dataset: {}; continue it with the same --seed and \
                     scenario, or give a new --out folder",
                    differs.join(" and ")
                )));
            }
        }
        None => {
            if let Some(run) = done.first() {
                return Err(Error::Request(format!(
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
        return Err(Error::Request(format!(
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
    std::fs::create_dir_all(out).map_err(|e| Error::output(out, e))?;
    write_aside(out, IDENTITY_FILE, |tmp| write_file(tmp, &record.json()))
}

/// Writes `dir/name` with `write` into `dir/.tmp-name` and renames it in, so that a kill
/// leaves the previous file whole rather than half of a new one.
pub(crate) fn write_aside(
    dir: &Path,
    name: &str,
    write: impl FnOnce(&Path) -> Result<(), Error>,
) -> Result<(), Error> {
    let (tmp, path) = (dir.join(format!("{TMP_PREFIX}{name}")), dir.join(name));
    write(&tmp)?;
    std::fs::rename(&tmp, &path).map_err(|e| Error::output(&path, e))
}

/// Takes the exclusive lock of dataset folder `out` (creating it), so that a second
/// `vmt dataset` on the same folder is refused rather than writing the same runs.
pub(crate) fn lock(out: &Path) -> Result<std::fs::File, Error> {
    std::fs::create_dir_all(out).map_err(|e| Error::output(out, e))?;
    let path = out.join(LOCK_FILE);
    let file = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .map_err(|e| Error::output(&path, e))?;
    match file.try_lock() {
        Ok(()) => Ok(file),
        Err(std::fs::TryLockError::WouldBlock) => Err(Error::Request(format!(
            "{}: another `vmt dataset` is writing this dataset folder (it holds the lock {}); \
             wait for it to finish, or give another --out folder",
            out.display(),
            path.display()
        ))),
        Err(std::fs::TryLockError::Error(e)) => Err(Error::output(&path, e)),
    }
}

/// Removes the accuracy report of a dataset about to get more runs: it describes fewer runs
/// than the folder will hold. Returns the files removed.
pub(crate) fn remove_stale_reports(out: &Path) -> Result<Vec<PathBuf>, Error> {
    let mut removed = Vec::new();
    for name in ["accuracy.md", "accuracy.json"] {
        let path = out.join(name);
        if path.is_file() {
            std::fs::remove_file(&path).map_err(|e| Error::output(&path, e))?;
            removed.push(path);
        }
    }
    Ok(removed)
}

/// Removes the temporary folders of runs an interrupted invocation did not finish, and the
/// scenarios of the runs that failed in the last one.
pub(crate) fn remove_leftovers(runs: &Path) -> Result<(), Error> {
    // A manifest half-written when the previous invocation was killed.
    if let Some(dir) = runs.parent() {
        let failed = dir.join(FAILED_DIR);
        if failed.is_dir() {
            std::fs::remove_dir_all(&failed).map_err(|e| Error::output(&failed, e))?;
        }
        for name in ["manifest.csv", "manifest.parquet"] {
            let tmp = dir.join(format!("{TMP_PREFIX}{name}"));
            if tmp.exists() {
                std::fs::remove_file(&tmp).map_err(|e| Error::output(&tmp, e))?;
            }
        }
    }
    for entry in std::fs::read_dir(runs).map_err(|e| Error::output(runs, e))? {
        let path = entry.map_err(|e| Error::output(runs, e))?.path();
        if name_of(&path).starts_with(TMP_PREFIX) {
            std::fs::remove_dir_all(&path).map_err(|e| Error::output(&path, e))?;
        }
    }
    Ok(())
}

pub(crate) fn name_of(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// The complete run folders of dataset `dir`, sorted by id.
pub fn complete_runs(dir: &Path) -> Result<Vec<PathBuf>, Error> {
    let runs = dir.join("runs");
    let mut out = Vec::new();
    for entry in std::fs::read_dir(&runs)
        .map_err(|e| Error::input(&runs.display().to_string(), None, e.to_string()))?
    {
        let path = entry.map_err(|e| Error::output(&runs, e))?.path();
        if !name_of(&path).starts_with(TMP_PREFIX)
            && RUN_FILES.iter().all(|f| path.join(f).is_file())
        {
            out.push(path);
        }
    }
    out.sort_by_key(|p| (name_of(p).len(), name_of(p)));
    Ok(out)
}

pub(crate) fn write_file(path: &Path, text: &str) -> Result<(), Error> {
    std::fs::write(path, text).map_err(|e| Error::output(path, e))
}

pub(crate) fn read_json(path: &Path) -> Result<Value, Error> {
    let file = path.display().to_string();
    let text =
        std::fs::read_to_string(path).map_err(|e| Error::input(&file, None, e.to_string()))?;
    serde_json::from_str(&text).map_err(|e| Error::input(&file, Some(e.line()), e.to_string()))
}
