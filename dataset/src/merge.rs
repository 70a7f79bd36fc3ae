//! Merging the shards of a dataset: the parts (one shared folder, or a folder per shard) are
//! checked to be one dataset, every run to be there once and whole, and the manifest is
//! written. The merged folder is the one a single invocation of `vmt dataset` writes for the
//! same scenario, seed and count, byte for byte.
//!
//! A part is a dataset folder: `dataset.json` (the same seed, scenario text, count and labels
//! format in every part), `runs/<id>/` and the records of the shards written into it
//! (`.shards/<I>-of-<N>.json`). Nothing is written before every check has passed: a missing
//! run is named by index and shard (and, when its task was interrupted, by the half-written
//! folder it left), a damaged one by its file and what is wrong with it.

use crate::Error;
use crate::folder::{
    IDENTITY_FILE, Identity, RUN_FILES, SHARDS_DIR, ScannedRuns, claim, lock_whole, read_identity,
    read_shard_records, scan_runs,
};
use crate::generate::run_seed;
use crate::manifest::{read_run_labels, write_manifest};
use crate::shard::Shard;
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Runs listed by id per shard in an error.
const IDS_LISTED: usize = 8;

/// What a merge did.
#[derive(Clone, Debug, PartialEq)]
pub struct Merged {
    /// The merged folder.
    pub out: PathBuf,
    /// Runs in it (the dataset's count).
    pub runs: u64,
    /// Runs copied into it from other folders.
    pub copied: u64,
    /// The number of shards the parts were written as, if they were sharded.
    pub shards: Option<u64>,
    /// Runs found in more than one part, the same bytes in each (kept once).
    pub duplicates: Vec<String>,
}

/// A complete run found in a part.
struct Found {
    part: usize,
    path: PathBuf,
}

/// Merges `parts` into `out`, or the one part in place when `out` is None or that part.
pub fn merge(parts: &[PathBuf], out: Option<&Path>) -> Result<Merged, Error> {
    let out = match (parts, out) {
        ([], _) => {
            return Err(Error::Request(
                "no folder to merge: give the dataset folders of the shards".into(),
            ));
        }
        ([only], None) => only.clone(),
        (_, None) => {
            return Err(Error::Request(format!(
                "{} folders to merge and no --out: give --out DIR, the folder to merge them into \
                 (one folder that all shards wrote into is merged in place without --out)",
                parts.len()
            )));
        }
        (_, Some(out)) => out.to_path_buf(),
    };
    let mut folders: Vec<PathBuf> = parts.to_vec();
    // A merge resumed into its folder, or into one of the parts: its runs count as found.
    if out.join(IDENTITY_FILE).is_file() && !folders.iter().any(|p| same(p, &out)) {
        folders.push(out.clone());
    }
    let identity = one_dataset(&folders)?;
    let _locks = folders
        .iter()
        .chain(std::iter::once(&out))
        .filter(|p| p.is_dir())
        .map(|p| (p.canonicalize().unwrap_or_else(|_| p.clone()), p))
        .collect::<BTreeMap<_, _>>()
        .into_values()
        .map(|p| lock_whole(p))
        .collect::<Result<Vec<_>, _>>()?;
    let shards = shard_count(&folders)?;
    let scans = folders
        .iter()
        .map(|p| scan_runs(p))
        .collect::<Result<Vec<_>, _>>()?;
    let (found, duplicates, mut damaged) = gather(&folders, &scans, &identity)?;
    damaged.extend(check_runs(&found, &identity));
    let absent: Vec<u64> = (0..identity.count)
        .filter(|i| !found.contains_key(i))
        .collect();
    if !absent.is_empty() || !damaged.is_empty() {
        return Err(Error::Request(incomplete(
            &folders, &scans, &identity, shards, &absent, &damaged,
        )));
    }
    claim(&out, &identity, None)?;
    let copied = copy_runs(&found, &out)?;
    write_manifest(&out)?;
    let records = out.join(SHARDS_DIR);
    if records.is_dir() {
        std::fs::remove_dir_all(&records).map_err(|e| Error::output(&records, e))?;
    }
    Ok(Merged {
        out,
        runs: identity.count,
        copied,
        shards,
        duplicates,
    })
}

/// Whether `a` and `b` name the same folder.
fn same(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    }
}

/// The identity the folders share; an error naming two folders of different datasets and
/// how they differ, or a folder without `dataset.json`.
fn one_dataset(folders: &[PathBuf]) -> Result<Identity, Error> {
    let mut first: Option<(&PathBuf, Identity)> = None;
    for p in folders {
        let id = read_identity(p)?.ok_or_else(|| {
            Error::Request(format!(
                "{}: no {IDENTITY_FILE}: not a folder `vmt dataset` wrote; give the --out \
                 folders of the shards",
                p.display()
            ))
        })?;
        match &first {
            None => first = Some((p, id)),
            Some((q, want)) => {
                let differs = differences(want, &id);
                if !differs.is_empty() {
                    return Err(Error::Request(format!(
                        "{} and {} hold shards of two different datasets ({}); merge only the \
                         folders of one dataset: the same --scenario text, --seed and --count",
                        q.display(),
                        p.display(),
                        differs.join(", ")
                    )));
                }
            }
        }
    }
    Ok(first.map(|f| f.1).expect("at least one folder"))
}

/// How identity `b` differs from `a`, in words (the scenario's path may differ: its text may
/// not).
fn differences(a: &Identity, b: &Identity) -> Vec<String> {
    let mut d = Vec::new();
    if a.scenario_fnv1a64 != b.scenario_fnv1a64 {
        d.push(format!(
            "scenario text hash {} ({}) against {} ({})",
            a.scenario_fnv1a64, a.scenario, b.scenario_fnv1a64, b.scenario
        ));
    }
    if a.seed != b.seed {
        d.push(format!("seed {} against {}", a.seed, b.seed));
    }
    if a.count != b.count {
        d.push(format!("count {} against {}", a.count, b.count));
    }
    if a.labels_format != b.labels_format {
        d.push(format!(
            "labels format {} against {}",
            a.labels_format, b.labels_format
        ));
    }
    d
}

/// The number of shards the folders were written as (the same in all), None if none was
/// sharded.
fn shard_count(folders: &[PathBuf]) -> Result<Option<u64>, Error> {
    let mut count: Option<(u64, &PathBuf)> = None;
    for p in folders {
        for s in read_shard_records(p)? {
            match count {
                None => count = Some((s.count, p)),
                Some((n, q)) if n != s.count => {
                    return Err(Error::Request(format!(
                        "{} holds shards of a split into {n} and {} of a split into {}: the \
                         runs of one dataset are split one way; merge the folders of one split",
                        q.display(),
                        p.display(),
                        s.count
                    )));
                }
                Some(_) => {}
            }
        }
    }
    Ok(count.map(|c| c.0))
}

/// The complete runs of every folder by index (the first folder holding one), the runs held
/// by two folders with the same bytes, and the damaged: a folder of no run of this dataset, or
/// a run two folders hold with different bytes.
#[allow(clippy::type_complexity)]
fn gather(
    folders: &[PathBuf],
    scans: &[ScannedRuns],
    identity: &Identity,
) -> Result<(BTreeMap<u64, Found>, Vec<String>, Vec<(u64, String)>), Error> {
    let mut found: BTreeMap<u64, Found> = BTreeMap::new();
    let mut duplicates = Vec::new();
    let mut damaged = Vec::new();
    for (part, scan) in scans.iter().enumerate() {
        for (name, path) in &scan.complete {
            let Some(i) = name
                .parse::<u64>()
                .ok()
                .filter(|&i| i < identity.count && crate::folder::run_id(i) == *name)
            else {
                damaged.push((
                    u64::MAX,
                    format!(
                        "{}: not a run of this dataset (its runs are runs/000000 to runs/{})",
                        path.display(),
                        crate::folder::run_id(identity.count - 1)
                    ),
                ));
                continue;
            };
            match found.get(&i) {
                None => {
                    found.insert(
                        i,
                        Found {
                            part,
                            path: path.clone(),
                        },
                    );
                }
                Some(first) => {
                    if same(&first.path, path) {
                        continue;
                    }
                    if same_files(&first.path, path)? {
                        duplicates.push(name.clone());
                    } else {
                        damaged.push((
                            i,
                            format!(
                                "run {name} is in {} and in {} with different files: one of \
                                 them is not this dataset's run {name}",
                                folders[first.part].display(),
                                folders[part].display()
                            ),
                        ));
                    }
                }
            }
        }
    }
    Ok((found, duplicates, damaged))
}

/// Whether run folders `a` and `b` hold the same bytes.
fn same_files(a: &Path, b: &Path) -> Result<bool, Error> {
    for f in RUN_FILES {
        let read = |p: &Path| {
            std::fs::read(p.join(f))
                .map_err(|e| Error::input(&p.join(f).display().to_string(), None, e.to_string()))
        };
        if read(a)? != read(b)? {
            return Ok(false);
        }
    }
    Ok(true)
}

/// The runs whose files are damaged, each with what is wrong.
fn check_runs(found: &BTreeMap<u64, Found>, identity: &Identity) -> Vec<(u64, String)> {
    found
        .par_iter()
        .filter_map(|(&i, f)| {
            check_run(&f.path, run_seed(identity.seed, i))
                .err()
                .map(|e| (i, e))
        })
        .collect()
}

/// Checks run folder `run`: its labels as `vmt dataset` writes them with the run's `seed`, its
/// MCAP file whole (the header's magic and a readable summary and footer) and its scenario
/// TOML.
fn check_run(run: &Path, seed: u64) -> Result<(), String> {
    let labels = read_run_labels(run).map_err(|e| e.to_string())?;
    if labels["seed"].as_u64() != Some(seed) {
        return Err(format!(
            "{}: `seed` is {}, not this dataset's seed of the run ({seed}): the run belongs to \
             another dataset",
            run.join("labels.json").display(),
            labels["seed"]
        ));
    }
    let mcap = run.join("run.mcap");
    if !framed_by_magic(&mcap).unwrap_or(false) || vmt_logs::input::summary(&mcap).is_none() {
        return Err(format!(
            "{}: not a whole MCAP file (its start, end or summary is missing or damaged)",
            mcap.display()
        ));
    }
    let toml_path = run.join("scenario.toml");
    let text =
        std::fs::read_to_string(&toml_path).map_err(|e| format!("{}: {e}", toml_path.display()))?;
    text.parse::<toml::Table>()
        .map_err(|e| format!("{}: not TOML: {e}", toml_path.display()))?;
    Ok(())
}

/// Whether file `path` starts and ends with the MCAP magic bytes, as a whole MCAP file does
/// (read without reading the file between them).
fn framed_by_magic(path: &Path) -> std::io::Result<bool> {
    use std::io::{Read, Seek, SeekFrom};
    let mut f = std::fs::File::open(path)?;
    let n = mcap::MAGIC.len();
    let mut head = vec![0; n];
    let mut tail = vec![0; n];
    f.read_exact(&mut head)?;
    f.seek(SeekFrom::End(-(n as i64)))?;
    f.read_exact(&mut tail)?;
    Ok(head == mcap::MAGIC && tail == mcap::MAGIC)
}

/// The error of a merge with runs missing or damaged: by shard, the missing runs' ids and the
/// half-written folders of interrupted tasks; then the damaged runs; then what to do.
fn incomplete(
    folders: &[PathBuf],
    scans: &[ScannedRuns],
    identity: &Identity,
    shards: Option<u64>,
    absent: &[u64],
    damaged: &[(u64, String)],
) -> String {
    let bad: BTreeSet<u64> = damaged
        .iter()
        .map(|d| d.0)
        .filter(|&i| i != u64::MAX)
        .collect();
    let mut s = format!(
        "runs missing or damaged: {} of {}, in {}:",
        absent.len() + bad.len(),
        identity.count,
        folders
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    let partial: BTreeMap<u64, &PathBuf> = scans
        .iter()
        .flat_map(|scan| scan.partial.iter())
        .filter_map(|(i, p)| Some(((*i)?, p)))
        .collect();
    let shard_of = |i: u64| shards.map(|n| Shard::of_run(i, n));
    let mut groups: BTreeMap<Option<Shard>, Vec<u64>> = BTreeMap::new();
    for &i in absent {
        groups.entry(shard_of(i)).or_default().push(i);
    }
    for (shard, ids) in &groups {
        let mut listed: Vec<String> = ids
            .iter()
            .take(IDS_LISTED)
            .map(|&i| crate::folder::run_id(i))
            .collect();
        if ids.len() > IDS_LISTED {
            listed.push(format!("and {} more", ids.len() - IDS_LISTED));
        }
        let listed = listed.join(", ");
        let left: Vec<String> = ids
            .iter()
            .filter_map(|i| partial.get(i))
            .map(|p| p.display().to_string())
            .collect();
        let _ = match shard {
            Some(sh) if sh.len(identity.count) == ids.len() as u64 && left.is_empty() => write!(
                s,
                "\n- shard {sh}: all its runs: {listed} (no folder holds any: its task never \
                 ran, or wrote elsewhere)"
            ),
            Some(sh) => write!(s, "\n- shard {sh}: runs {listed}"),
            None => write!(s, "\n- runs {listed}"),
        };
        if !left.is_empty() {
            let _ = write!(
                s,
                " (half-written by an interrupted task: {})",
                left.join(", ")
            );
        }
    }
    for (_, why) in damaged {
        let _ = write!(s, "\n- damaged: {why}");
    }
    let rerun: BTreeSet<Shard> = absent
        .iter()
        .chain(&bad)
        .filter_map(|&i| shard_of(i))
        .collect();
    let again = match shards {
        Some(n) => {
            let which: Vec<String> = rerun.iter().map(|sh| sh.index.to_string()).collect();
            format!(
                "run shard{} {} of {n} again with the same arguments (`vmt dataset ... --shard \
                 I/{n}`, or requeue the task: scontrol requeue JOBID_I), which completes {} \
                 without redoing a finished run",
                if which.len() > 1 { "s" } else { "" },
                which.join(", "),
                if which.len() > 1 { "them" } else { "it" }
            )
        }
        None => "run `vmt dataset` again with the same arguments, which completes the dataset \
                 without redoing a finished run"
            .into(),
    };
    let remove = if damaged.is_empty() {
        ""
    } else {
        "remove the damaged run folders, "
    };
    let _ = write!(s, "\nnothing was merged: {remove}{again}, then merge again");
    s
}

/// Copies every run into `out` that is not there: hard links where the file system allows
/// (a run's files never change once complete), else copies; each run written aside and
/// renamed into place. Returns the number of runs copied.
fn copy_runs(found: &BTreeMap<u64, Found>, out: &Path) -> Result<u64, Error> {
    let runs = out.join("runs");
    std::fs::create_dir_all(&runs).map_err(|e| Error::output(&runs, e))?;
    let copied: Vec<bool> = found
        .par_iter()
        .map(|(&i, f)| {
            let id = crate::folder::run_id(i);
            let dest = runs.join(&id);
            if same(&f.path, &dest) {
                return Ok(false);
            }
            let tmp = runs.join(format!("{}{id}", crate::folder::TMP_PREFIX));
            if tmp.exists() {
                std::fs::remove_dir_all(&tmp).map_err(|e| Error::output(&tmp, e))?;
            }
            std::fs::create_dir(&tmp).map_err(|e| Error::output(&tmp, e))?;
            for name in RUN_FILES {
                let (from, to) = (f.path.join(name), tmp.join(name));
                if std::fs::hard_link(&from, &to).is_err() {
                    std::fs::copy(&from, &to).map_err(|e| Error::output(&to, e))?;
                }
            }
            if dest.exists() {
                std::fs::remove_dir_all(&dest).map_err(|e| Error::output(&dest, e))?;
            }
            std::fs::rename(&tmp, &dest).map_err(|e| Error::output(&dest, e))?;
            Ok(true)
        })
        .collect::<Result<_, Error>>()?;
    Ok(copied.into_iter().filter(|&c| c).count() as u64)
}
