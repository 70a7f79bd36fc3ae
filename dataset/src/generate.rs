//! Generating a dataset: every run still missing (of a shard, when one is asked for) drawn,
//! simulated and written, then the manifest rebuilt (a merge writes it for shards).

use crate::Error;
use crate::folder::{
    FAILED_DIR, FolderLock, Identity, LABELS_FORMAT, MAX_RUNS, SHARDS_DIR, TMP_PREFIX, claim,
    complete_runs, fnv1a64, lock_shard, lock_whole, name_of, record_shard, remove_leftovers,
    remove_stale_reports, run_id, sync, write_synced,
};
use crate::manifest::write_manifest;
use crate::shard::Shard;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde_json::{Map, Value, json};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use vmt_logs::write_mcap;
use vmt_scenario::dataset::{self, Dataset};

/// Runs named in an error about many.
const IDS_LISTED: usize = 5;

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
    /// Only the runs of this shard, and no manifest (a merge writes it); None: every run.
    pub shard: Option<Shard>,
}

/// What an invocation did.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// Runs simulated now.
    pub simulated: usize,
    /// Runs already complete (of the shard, for a shard).
    pub skipped: usize,
    /// Rows of the manifest; None for a shard, which writes none.
    pub rows: Option<usize>,
    /// Accuracy reports removed because the dataset got more runs.
    pub removed: Vec<PathBuf>,
    /// What the scenario's job accepts but will not do as asked ([`crate::job::notes`]).
    pub notes: Vec<String>,
}

/// The seed of run `i` of a dataset with seed `k`: splitmix64 (Steele et al. 2014) of the
/// state k + (i + 1)·γ, shifted to 63 bits so it is a TOML integer.
pub fn run_seed(k: u64, i: u64) -> u64 {
    let mut z = k.wrapping_add(i.wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    (z ^ (z >> 31)) >> 1
}

/// A dataset scenario read and checked.
pub struct Template {
    /// The file as given.
    pub file: String,
    /// Its text.
    pub text: String,
    /// Its `[dataset]` section.
    pub dataset: Dataset,
    /// The scenario itself, as every run's starts.
    pub scenario: vmt_scenario::Scenario,
}

/// Reads the dataset scenario `path`: it must have a `[dataset]` section and load itself, so
/// that a scenario error is reported once, not per run.
pub fn read_template(path: &Path) -> Result<Template, Error> {
    let file = path.display().to_string();
    let text =
        std::fs::read_to_string(path).map_err(|e| Error::input(&file, None, e.to_string()))?;
    let base = path.parent().unwrap_or(Path::new("."));
    let dataset = dataset::from_text(&text, &file)?.ok_or_else(|| {
        Error::input(
            &file,
            None,
            "no [dataset] section: `vmt dataset` needs [dataset.parameters]",
        )
    })?;
    let scenario = vmt_scenario::parse(&text, &file, Some(base))?;
    Ok(Template {
        file,
        text,
        dataset,
        scenario,
    })
}

/// Simulates the runs of `req` (of its shard) that are not complete yet; rebuilds the
/// manifest, unless a shard was asked for.
pub fn build(req: &Request) -> Result<Outcome, Error> {
    if !(1..=MAX_RUNS).contains(&req.count) {
        return Err(Error::Request(format!(
            "--count {}: a dataset holds from 1 to {MAX_RUNS} runs (ids of six digits)",
            req.count
        )));
    }
    if let Some(s) = req.shard {
        s.check(req.count, &format!("--shard {s}"))?;
    }
    let mine = |i: &u64| req.shard.is_none_or(|s| s.holds(*i));
    let Template {
        file,
        text,
        dataset: ds,
        scenario: template,
    } = read_template(req.scenario)?;
    let base = req.scenario.parent().unwrap_or(Path::new("."));
    // Only the runs still to do: a resumed dataset of many runs does not draw them all again.
    let done_before: BTreeSet<String> = if req.out.join("runs").is_dir() {
        complete_runs(req.out)?.iter().map(|p| name_of(p)).collect()
    } else {
        BTreeSet::new()
    };
    check_draws(&ds, &file, base, req, &done_before)?;
    let _lock = take_folder(req, &file, &text)?;
    let runs = req.out.join("runs");
    let done: BTreeSet<String> = complete_runs(req.out)?
        .iter()
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect();
    let todo: Vec<u64> = (0..req.count)
        .filter(mine)
        .filter(|i| !done.contains(&run_id(*i)))
        .collect();
    let total = (0..req.count).filter(mine).count();
    let removed = if todo.is_empty() {
        Vec::new()
    } else {
        remove_stale_reports(req.out)?
    };
    let bar = progress(todo.len() as u64, req.quiet);
    let results: Vec<(u64, Result<(), Error>)> = todo
        .par_iter()
        .map(|&i| {
            let r = simulate_one(&ds, &file, base, &runs, i, run_seed(req.seed, i));
            bar.inc(1);
            (i, r)
        })
        .collect();
    bar.finish_and_clear();
    let rows = match req.shard {
        Some(_) => None,
        None => Some(write_manifest(req.out)?),
    };
    let failed: Vec<(u64, Error)> = results
        .into_iter()
        .filter_map(|(i, r)| r.err().map(|e| (i, e)))
        .collect();
    if !failed.is_empty() {
        return Err(failed_runs(req, &ds, &file, todo.len(), failed));
    }
    if req.shard.is_none() && rows == Some(req.count as usize) {
        // Whole: the shards' records of how it was split are of no more use.
        let records = req.out.join(SHARDS_DIR);
        if records.is_dir() {
            std::fs::remove_dir_all(&records).map_err(|e| Error::output(&records, e))?;
        }
    }
    Ok(Outcome {
        simulated: todo.len(),
        skipped: total - todo.len(),
        rows,
        removed,
        notes: template
            .execution
            .as_ref()
            .map(crate::job::notes)
            .unwrap_or_default(),
    })
}

/// Takes the output folder for `req`: its lock (shared with the other shards, for a shard),
/// its identity claimed, the shard recorded, and what an interrupted invocation left
/// half-written removed.
fn take_folder(req: &Request, file: &str, text: &str) -> Result<FolderLock, Error> {
    let lock = match req.shard {
        None => lock_whole(req.out)?,
        Some(s) => lock_shard(req.out, s)?,
    };
    let identity = Identity {
        seed: req.seed,
        scenario: file.to_string(),
        scenario_fnv1a64: fnv1a64(text),
        count: req.count,
        labels_format: LABELS_FORMAT,
    };
    claim(req.out, &identity, req.shard)?;
    if let Some(s) = req.shard {
        record_shard(req.out, s)?;
    }
    let runs = req.out.join("runs");
    std::fs::create_dir_all(&runs).map_err(|e| Error::output(&runs, e))?;
    remove_leftovers(req.out, req.shard)?;
    Ok(lock)
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
) -> Result<(), Error> {
    let refused: Vec<(u64, vmt_scenario::ScenarioError)> = (0..req.count)
        .into_par_iter()
        .filter(|i| req.shard.is_none_or(|s| s.holds(*i)))
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
    Err(Error::Request(format!(
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
    failed: Vec<(u64, Error)>,
) -> Error {
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
    Error::Model(format!(
        "{} of the {simulated} runs simulated failed ({}); the others are written. Run {} \
         ({scenario}): {e}. The runs are drawn from --seed, so running again fails the same \
         way: change the distributions in [dataset.parameters] of {file} so that such machines \
         are not drawn, and write the dataset into a new --out folder",
        failed.len(),
        listed(failed.iter().map(|f| f.0)),
        run_id(*first)
    ))
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

/// Samples, simulates and writes run `i` into a temporary folder, then renames it into place.
fn simulate_one(
    ds: &Dataset,
    file: &str,
    base: &Path,
    runs: &Path,
    i: u64,
    seed: u64,
) -> Result<(), Error> {
    let id = run_id(i);
    let sample = ds.sample(seed);
    let scenario = vmt_scenario::parse(&sample.text, &format!("{file} (run {id})"), Some(base))?;
    let run = crate::job::simulate(&scenario, &sample.text, None, &mut |_| {}, None)
        .map_err(|e| Error::Model(format!("seed {seed}: {e}")))?;
    let tmp = runs.join(format!("{TMP_PREFIX}{id}"));
    std::fs::create_dir_all(&tmp).map_err(|e| Error::output(&tmp, e))?;
    write_mcap(&run, &tmp.join("run.mcap"))?;
    write_synced(&tmp.join("scenario.toml"), &sample.text)?;
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
    write_synced(&tmp.join("labels.json"), &format!("{labels:#}\n"))?;
    // On the disk before the rename makes the run complete: a node lost after it (its page
    // cache with it) leaves the run whole, one lost before it a temporary folder.
    sync(&tmp.join("run.mcap"))?;
    sync(&tmp)?;
    let dest = runs.join(&id);
    // A folder of this id is an incomplete one (the run is only simulated when it is not
    // complete): the new run, the same bytes as the lost one, takes its place.
    if dest.exists() {
        std::fs::remove_dir_all(&dest).map_err(|e| Error::output(&dest, e))?;
    }
    std::fs::rename(&tmp, &dest).map_err(|e| Error::output(&dest, e))
}
