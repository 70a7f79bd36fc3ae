//! `vmt dataset`: the dataset built by [`vmt_dataset`], and what was done printed.

use crate::error::CliError;
use std::path::Path;
use vmt_dataset::{Request, build};

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
