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
//!   every parameter, every ground-truth figure of the first circular test as `truth.<key>`.
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
/// The identity file of a dataset folder.
pub const IDENTITY_FILE: &str = "dataset.json";
/// The version of what `labels.json` holds: 2 since the truth's injected squareness is in µrad
/// (format 1, without the key in `dataset.json`, wrote it in rad under the same keys). Runs of
/// two formats never share a dataset. A change of a key's meaning or unit bumps it; keys only
/// added (as the laser truth's drive share at rest was) do not, since no value read before
/// changes.
pub const LABELS_FORMAT: u64 = 2;

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
                    "an older vmt's; format 1 or unknown wrote the injected squareness in rad"
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
    let bar = progress(todo.len() as u64, req.quiet);
    let results: Vec<Result<(), CliError>> = todo
        .par_iter()
        .map(|&i| {
            let r = simulate_one(&ds, &file, base, &runs, i, run_seed(req.seed, i));
            bar.inc(1);
            r
        })
        .collect();
    bar.finish_and_clear();
    let rows = write_manifest(req.out)?;
    results.into_iter().collect::<Result<Vec<()>, _>>()?;
    Ok(Outcome {
        simulated: todo.len(),
        skipped: req.count as usize - todo.len(),
        rows,
    })
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

/// Removes the temporary folders of runs an interrupted invocation did not finish.
fn remove_leftovers(runs: &Path) -> Result<(), CliError> {
    // A manifest half-written when the previous invocation was killed.
    if let Some(dir) = runs.parent() {
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
        .map_err(|e| CliError::Model(format!("run {id} (seed {seed}): {e}")))?;
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

/// The manifest: column names and one row per run (id, seed, then numbers or gaps).
struct Manifest {
    numbers: Vec<String>,
    rows: Vec<(String, i64, Vec<Option<f64>>)>,
}

/// Reads every complete run's labels into the manifest's rows.
fn manifest(dir: &Path) -> Result<Manifest, CliError> {
    let labels = complete_runs(dir)?
        .iter()
        .map(|p| read_run_labels(p))
        .collect::<Result<Vec<_>, _>>()?;
    let figures = |l: &Value| {
        crate::diagnose::truth_figures(&l["ground_truth"], 0)
            .cloned()
            .unwrap_or_default()
    };
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
    let numbers = names
        .into_iter()
        .chain(truths.into_iter().map(|k| format!("truth.{k}")))
        .collect();
    Ok(Manifest { numbers, rows })
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
    ["parameters", "keys", "ground_truth"]
        .into_iter()
        .find(|k| !v[k].is_object())
        .map(|k| format!("`{k}` is {}, not an object", v[k]))
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
    let props = Arc::new(WriterProperties::builder().build());
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
