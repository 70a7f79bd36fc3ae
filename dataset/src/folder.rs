//! The dataset folder: its identity (`dataset.json`), its complete runs, the locks an
//! invocation holds while it writes, the records of the shards written into it, and files
//! written aside and renamed into place.
//!
//! Locks (the operating system's advisory locks on files, released when the process ends,
//! killed or not): an invocation of the whole dataset, and a merge, hold `.lock` alone; a
//! shard holds `.lock` shared with the other shards and `.shards/<I>-of-<N>.lock` alone. So
//! shards write one folder side by side (a cluster file system), a shard is never run twice at
//! once, and nothing else writes while a shard does.

use crate::Error;
use crate::shard::Shard;
use serde_json::{Value, json};
use std::fs::{File, TryLockError};
use std::path::{Path, PathBuf};

/// Prefix of a run folder being written.
pub(crate) const TMP_PREFIX: &str = ".tmp-";

/// The file an invocation holds a lock on while it writes the folder. The operating system
/// releases the lock when the process ends, killed or not, so the file left behind does not
/// keep the next invocation out.
pub(crate) const LOCK_FILE: &str = ".lock";

/// The folder of the shards' records (`<I>-of-<N>.json`) and locks; a merge removes it.
pub const SHARDS_DIR: &str = ".shards";

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
/// `dataset.json` was written before it existed, in labels format 1, and is refused. A shard
/// (`shard`) also keeps the count: the shards of one folder are of one dataset.
pub(crate) fn claim(out: &Path, want: &Identity, shard: Option<Shard>) -> Result<(), Error> {
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
            if let Some(s) = shard.filter(|_| have.count != want.count) {
                differs.push(format!(
                    "it was started with --count {} and shard {s} has --count {}: the shards \
                     of one folder share the count",
                    have.count, want.count
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
    write_aside(out, IDENTITY_FILE, &aside_tag(shard), |tmp| {
        write_file(tmp, &record.json())
    })
}

/// The tag of the files `shard` writes aside (`.1-of-4`), so that shards writing the same
/// file into one folder at once do not write the same temporary file; none for the whole.
pub(crate) fn aside_tag(shard: Option<Shard>) -> String {
    shard.map(|s| format!(".{}", s.tag())).unwrap_or_default()
}

/// Writes `dir/name` with `write` into `dir/.tmp-name<tag>` and renames it in, so that a kill
/// leaves the previous file whole rather than half of a new one ([`aside_tag`]).
pub(crate) fn write_aside(
    dir: &Path,
    name: &str,
    tag: &str,
    write: impl FnOnce(&Path) -> Result<(), Error>,
) -> Result<(), Error> {
    let (tmp, path) = (dir.join(format!("{TMP_PREFIX}{name}{tag}")), dir.join(name));
    write(&tmp)?;
    std::fs::rename(&tmp, &path).map_err(|e| Error::output(&path, e))
}

/// The locks an invocation holds on a dataset folder while it writes (see the module's
/// documentation); dropped, they are released.
pub(crate) struct FolderLock {
    _files: Vec<File>,
}

/// Opens (creating) the lock file `path`.
fn lock_file(path: &Path) -> Result<File, Error> {
    std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(path)
        .map_err(|e| Error::output(path, e))
}

/// The error of a lock another process holds: `who` is writing `out`.
fn held(out: &Path, path: &Path, who: &str) -> Error {
    Error::Request(format!(
        "{}: {who} (it holds the lock {}); wait for it to finish, or give another --out folder",
        out.display(),
        path.display()
    ))
}

/// Takes the lock of dataset folder `out` (creating it) alone, so that a second `vmt dataset`,
/// a shard or a merge on the same folder is refused rather than writing the same runs.
pub(crate) fn lock_whole(out: &Path) -> Result<FolderLock, Error> {
    std::fs::create_dir_all(out).map_err(|e| Error::output(out, e))?;
    let path = out.join(LOCK_FILE);
    let file = lock_file(&path)?;
    match file.try_lock() {
        Ok(()) => Ok(FolderLock { _files: vec![file] }),
        Err(TryLockError::WouldBlock) => Err(held(
            out,
            &path,
            "another `vmt dataset` is writing this dataset folder",
        )),
        Err(TryLockError::Error(e)) => Err(Error::output(&path, e)),
    }
}

/// Takes the folder's lock shared with the other shards, and shard `shard`'s alone.
pub(crate) fn lock_shard(out: &Path, shard: Shard) -> Result<FolderLock, Error> {
    let dir = out.join(SHARDS_DIR);
    std::fs::create_dir_all(&dir).map_err(|e| Error::output(&dir, e))?;
    let path = out.join(LOCK_FILE);
    let folder = lock_file(&path)?;
    match folder.try_lock_shared() {
        Ok(()) => {}
        Err(TryLockError::WouldBlock) => {
            return Err(held(
                out,
                &path,
                "a `vmt dataset` of the whole dataset or a merge is writing this folder",
            ));
        }
        Err(TryLockError::Error(e)) => return Err(Error::output(&path, e)),
    }
    let path = dir.join(format!("{}.lock", shard.tag()));
    let own = lock_file(&path)?;
    match own.try_lock() {
        Ok(()) => Ok(FolderLock {
            _files: vec![folder, own],
        }),
        Err(TryLockError::WouldBlock) => Err(held(
            out,
            &path,
            &format!("another `vmt dataset` is making shard {shard} into this folder"),
        )),
        Err(TryLockError::Error(e)) => Err(Error::output(&path, e)),
    }
}

/// Records that shard `shard` writes into `out` (`.shards/<I>-of-<N>.json`), for a merge to
/// name the shard of a missing run. A folder holding records of another split into shards is
/// refused: the runs of a folder are split one way.
pub(crate) fn record_shard(out: &Path, shard: Shard) -> Result<(), Error> {
    if let Some(other) = read_shard_records(out)?
        .into_iter()
        .find(|s| s.count != shard.count)
    {
        return Err(Error::Request(format!(
            "{}: shard {shard} cannot join the shards of a split into {} written there \
             ({}/{SHARDS_DIR}/{}.json): a folder's runs are split one way; give --shard I/{}, \
             or another --out folder",
            out.display(),
            other.count,
            out.display(),
            other.tag(),
            other.count
        )));
    }
    let dir = out.join(SHARDS_DIR);
    let name = format!("{}.json", shard.tag());
    let text = format!(
        "{:#}\n",
        json!({"shard": shard.index, "shards": shard.count})
    );
    write_aside(&dir, &name, &aside_tag(Some(shard)), |tmp| {
        write_file(tmp, &text)
    })
}

/// The shards recorded in folder `dir`, in order.
pub fn read_shard_records(dir: &Path) -> Result<Vec<Shard>, Error> {
    let records = dir.join(SHARDS_DIR);
    if !records.is_dir() {
        return Ok(Vec::new());
    }
    let mut shards = Vec::new();
    for entry in std::fs::read_dir(&records).map_err(|e| Error::output(&records, e))? {
        let path = entry.map_err(|e| Error::output(&records, e))?.path();
        let name = name_of(&path);
        if name.starts_with(TMP_PREFIX) || !name.ends_with(".json") {
            continue;
        }
        let v = read_json(&path)?;
        let bad = || {
            Error::input(
                &path.display().to_string(),
                None,
                "not a shard's record: `vmt dataset --shard` writes {\"shard\": I, \"shards\": N}",
            )
        };
        let shard = Shard {
            index: v["shard"].as_u64().ok_or_else(bad)?,
            count: v["shards"].as_u64().ok_or_else(bad)?,
        };
        if shard.count == 0 || shard.index >= shard.count {
            return Err(bad());
        }
        shards.push(shard);
    }
    shards.sort();
    Ok(shards)
}

/// Removes the accuracy report of a dataset about to get more runs: it describes fewer runs
/// than the folder will hold. Returns the files removed.
pub(crate) fn remove_stale_reports(out: &Path) -> Result<Vec<PathBuf>, Error> {
    let mut removed = Vec::new();
    for name in ["accuracy.md", "accuracy.json"] {
        let path = out.join(name);
        // Shards writing one folder remove it at once: the one that finds it gone is done.
        match std::fs::remove_file(&path) {
            Ok(()) => removed.push(path),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(Error::output(&path, e)),
        }
    }
    Ok(removed)
}

/// Removes what an interrupted invocation left half-written: temporary run folders and files
/// written aside, and the scenarios of the runs that failed in the last one. A shard removes
/// only its own (its runs' folders and failed scenarios, the files it writes aside), which no
/// other invocation writes while it holds its lock; the whole dataset's invocation removes all.
pub(crate) fn remove_leftovers(out: &Path, shard: Option<Shard>) -> Result<(), Error> {
    let remove = |path: &Path| {
        let r = if path.is_dir() {
            std::fs::remove_dir_all(path)
        } else {
            std::fs::remove_file(path)
        };
        r.map_err(|e| Error::output(path, e))
    };
    // A run's id as the name of its folder or failed scenario, its temporary folder's.
    let ours = |name: &str| {
        let id = name
            .trim_start_matches(TMP_PREFIX)
            .trim_end_matches(".toml");
        match (shard, id.parse::<u64>()) {
            (None, _) => true,
            (Some(s), Ok(i)) => s.holds(i),
            (Some(_), Err(_)) => false,
        }
    };
    let tag = aside_tag(shard);
    let aside = |name: &str| {
        name.starts_with(TMP_PREFIX) && (shard.is_none() || name.ends_with(tag.as_str()))
    };
    for dir in [out.to_path_buf(), out.join(SHARDS_DIR)] {
        for path in entries(&dir)? {
            if path.is_file() && aside(&name_of(&path)) {
                remove(&path)?;
            }
        }
    }
    let failed = out.join(FAILED_DIR);
    for path in entries(&failed)? {
        if ours(&name_of(&path)) {
            remove(&path)?;
        }
    }
    if shard.is_none() && failed.is_dir() {
        remove(&failed)?;
    }
    for path in entries(&out.join("runs"))? {
        let name = name_of(&path);
        if name.starts_with(TMP_PREFIX) && ours(&name) {
            remove(&path)?;
        }
    }
    Ok(())
}

/// The entries of folder `dir`; none when it does not exist.
fn entries(dir: &Path) -> Result<Vec<PathBuf>, Error> {
    if !dir.is_dir() {
        return Ok(Vec::new());
    }
    std::fs::read_dir(dir)
        .map_err(|e| Error::output(dir, e))?
        .map(|e| e.map(|e| e.path()).map_err(|e| Error::output(dir, e)))
        .collect()
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

/// The run folders of a dataset folder, as [`scan_runs`] finds them.
pub struct ScannedRuns {
    /// Folders holding every file of a run, by name, sorted.
    pub complete: Vec<(String, PathBuf)>,
    /// Folders of runs left half-written (a temporary folder, or a folder missing a file), with
    /// the run's index where the name gives one.
    pub partial: Vec<(Option<u64>, PathBuf)>,
}

/// The complete and half-written run folders of dataset folder `dir`.
pub fn scan_runs(dir: &Path) -> Result<ScannedRuns, Error> {
    let mut scan = ScannedRuns {
        complete: Vec::new(),
        partial: Vec::new(),
    };
    for path in entries(&dir.join("runs"))? {
        let name = name_of(&path);
        if !name.starts_with(TMP_PREFIX) && RUN_FILES.iter().all(|f| path.join(f).is_file()) {
            scan.complete.push((name, path));
        } else {
            let id = name.trim_start_matches(TMP_PREFIX).parse().ok();
            scan.partial.push((id, path));
        }
    }
    scan.complete.sort_by_key(|(n, _)| (n.len(), n.clone()));
    Ok(scan)
}

/// Writes `text` into the new file `path` and flushes it to the disk, so that a run renamed
/// into place after its files survives a node lost with its page cache.
pub(crate) fn write_synced(path: &Path, text: &str) -> Result<(), Error> {
    use std::io::Write;
    let mut f = File::create(path).map_err(|e| Error::output(path, e))?;
    f.write_all(text.as_bytes())
        .and_then(|_| f.sync_all())
        .map_err(|e| Error::output(path, e))
}

/// Flushes file or folder `path` to the disk.
pub(crate) fn sync(path: &Path) -> Result<(), Error> {
    File::open(path)
        .and_then(|f| f.sync_all())
        .map_err(|e| Error::output(path, e))
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
