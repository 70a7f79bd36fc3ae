//! `vmt dataset`: the dataset built by [`vmt_dataset`] (whole, or a shard given or read from
//! the scheduler's environment), its launchers written, its shards merged, and what was done
//! printed.

use crate::error::CliError;
use std::path::{Path, PathBuf};
use vmt_dataset::launch::{self, Launch, Scheduler};
use vmt_dataset::shard::{self, Shard};
use vmt_dataset::{Request, build};

/// What `vmt dataset` was asked to make: the request (its shard still to be found) and the
/// shard's options.
pub struct Make<'a> {
    /// The dataset, every run.
    pub request: Request<'a>,
    /// `--shard I/N`.
    pub shard: Option<&'a str>,
    /// `--shards N`.
    pub shards: Option<u64>,
}

/// The shard to make: `--shard`, else the scheduler's environment, else none (every run);
/// with the words saying where it came from.
fn which_shard(m: &Make) -> Result<Option<(Shard, String)>, CliError> {
    if let Some(text) = m.shard {
        let s = Shard::parse(text)?;
        return Ok(Some((s, format!("--shard {text}"))));
    }
    Ok(shard::from_env(|k| std::env::var(k).ok(), m.shards)?)
}

/// `vmt dataset`: builds the dataset (or a shard of it) and prints what was done.
pub fn command(m: &Make) -> Result<(), CliError> {
    let start = std::time::Instant::now();
    let count = m.request.count;
    let shard = match which_shard(m)? {
        Some((s, from)) => {
            let s = s.check(count, &from)?;
            crate::outln!(
                "shard {s} from {from}: its {} of the {count} runs (run i for i mod {} = {})",
                s.len(count),
                s.count,
                s.index
            )?;
            Some(s)
        }
        None => None,
    };
    let out = m.request.out;
    let o = build(&Request { shard, ..m.request })?;
    for note in &o.notes {
        crate::errln!("note: {note}");
    }
    for path in &o.removed {
        crate::outln!(
            "removed {}: it scored fewer runs than the dataset now holds (run `vmt accuracy` again)",
            path.display()
        )?;
    }
    let minutes = start.elapsed().as_secs_f64() / 60.0;
    let done = format!(
        "{} runs simulated in {:.1} min ({:.1} runs/min on {} threads), {} already complete",
        o.simulated,
        minutes,
        o.simulated as f64 / minutes.max(1e-9),
        rayon::current_num_threads(),
        o.skipped,
    );
    match (shard, o.rows) {
        (Some(s), _) => crate::outln!(
            "{done}; shard {s} is complete in {}. Once every shard is, merge them: `vmt dataset \
             merge {}` (a folder all shards wrote into) or `vmt dataset merge PART... --out DIR`",
            out.display(),
            out.display()
        )?,
        (None, rows) => crate::outln!(
            "{done}; manifest of {} runs: {}",
            rows.unwrap_or_default(),
            out.join("manifest.{csv,parquet}").display()
        )?,
    }
    Ok(())
}

/// How the launcher of `vmt dataset --emit` spreads the dataset.
pub struct Emit<'a> {
    /// The dataset asked for.
    pub make: Make<'a>,
    /// The scheduler.
    pub scheduler: Scheduler,
    /// `--max-parallel`.
    pub parallel: Option<u64>,
    /// `--cpus-per-task`.
    pub cpus: u64,
    /// `--image`.
    pub image: Option<&'a str>,
}

/// `vmt dataset --emit slurm|k8s`: prints the scheduler's launcher of the dataset; simulates
/// nothing.
pub fn emit(e: &Emit) -> Result<(), CliError> {
    let (m, r) = (&e.make, &e.make.request);
    if m.shard.is_some() {
        return Err(CliError::Argument(
            "--shard with --emit: the launcher runs every shard; give --shards N for their \
             number"
                .into(),
        ));
    }
    if !(1..=vmt_dataset::MAX_RUNS).contains(&r.count) {
        return Err(CliError::Argument(format!(
            "--count {}: a dataset holds from 1 to {} runs (ids of six digits)",
            r.count,
            vmt_dataset::MAX_RUNS
        )));
    }
    if e.cpus == 0 {
        return Err(CliError::option(
            "--cpus-per-task",
            0,
            "a task needs at least 1 core",
        ));
    }
    let template = vmt_dataset::generate::read_template(r.scenario)?;
    let (shards, parallel) = launch::plan(e.scheduler, r.count, m.shards, e.parallel)?;
    let here = |p: std::io::Result<PathBuf>, what: &str| {
        p.map(|p| p.display().to_string())
            .map_err(|err| CliError::Argument(format!("{what}: {err}")))
    };
    let file_name = r.scenario.file_name().map_or_else(
        || "scenario.toml".into(),
        |n| n.to_string_lossy().into_owned(),
    );
    let l = Launch {
        scenario: template.file,
        scenario_file: (file_name, template.text),
        count: r.count,
        seed: r.seed,
        out: r.out.display().to_string(),
        shards,
        parallel,
        cpus: e.cpus,
        vmt: here(std::env::current_exe(), "the path of this vmt")?,
        workdir: here(std::env::current_dir(), "the current folder")?,
        image: e.image.map_or_else(
            || format!("vmt:{}", env!("CARGO_PKG_VERSION")),
            str::to_string,
        ),
    };
    let text = match e.scheduler {
        Scheduler::Slurm => l.slurm(),
        Scheduler::Kubernetes => l.kubernetes(),
    };
    crate::out!("{text}")?;
    Ok(())
}

/// `vmt dataset merge`: merges the shards and prints what was done.
pub fn merge(parts: &[PathBuf], out: Option<&Path>) -> Result<(), CliError> {
    let m = vmt_dataset::merge(parts, out)?;
    for id in &m.duplicates {
        crate::errln!("note: run {id} was in two folders, the same bytes in both; kept once");
    }
    let split = m
        .shards
        .map_or_else(String::new, |n| format!(" of {n} shards"));
    crate::outln!(
        "merged {} runs{split} into {} ({} copied); manifest: {}",
        m.runs,
        m.out.display(),
        m.copied,
        m.out.join("manifest.{csv,parquet}").display()
    )?;
    Ok(())
}
