//! vmt-logs: a run's log files. A simulated [`Run`] written as files that other tools open,
//! and read back as the analysis takes a real instrument's log.
//!
//! - [`mcap`]: an MCAP file of JSON messages with JSON-Schema schemas, for Foxglove and the
//!   `mcap` readers (Python, C++, Rust, Go, ...).
//! - [`rerun`]: a Rerun recording (`.rrd`) with the machine in 3D, the tool path, ball-bar polar
//!   traces, time series and a viewer layout, for the Rerun viewer 0.36.
//! - [`live`]: both written while the job runs, from the simulator's blocks of records.
//! - [`input`]: an MCAP file streamed back, message by message; [`ballbar`]: its ball-bar
//!   traces grouped into circular tests; [`truth`]: the figures of the ground truth it carries.
//! - [`csv_import`]: an instrument's CSV export read as it is exported: its columns mapped onto
//!   ours and its units converted.
//!
//! Both use the simulation time of the run as their clock; nothing in them comes from the wall
//! clock of the computer that wrote them (see each module for what that means for its format).
//! The topics and entity paths are documented in the modules and in `docs/formats.md`.

pub mod ballbar;
pub mod csv_import;
pub mod error;
pub mod input;
pub mod live;
pub mod mcap;
pub mod rerun;
pub mod truth;

pub use error::{FileError, with_causes};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use vmt_sim::run::{BallbarTrace, Run, Stream};

pub use self::mcap::write_mcap;
pub use self::rerun::write_rrd;

/// A file of a run written block by block: created for the run as it starts, given its records
/// block by block (while the job runs, see [`live`]), completed with the finished run. Both
/// writers ([`mcap::McapFile`], [`rerun::RrdFile`]) write `<path>.partial` and rename it when
/// finished; dropped unfinished (an error), they remove it.
pub trait RunFile: Sized {
    /// Creates the file `path` for the run `opening`: its streams' channels and its traces,
    /// with or without their samples.
    fn create(path: &Path, opening: &Run) -> Result<Self, FileError>;

    /// Writes every row of `streams` and every sample of `traces` (the run's streams and
    /// traces, in the order of the opening run's, holding just the records of this block).
    fn block(&mut self, streams: &[Stream], traces: &[BallbarTrace]) -> Result<(), FileError>;

    /// Writes what needs the finished `run` and completes the file, still under its partial
    /// name.
    fn complete(self, run: &Run) -> Result<Partial, FileError>;

    /// [`RunFile::complete`], then renamed to its path.
    fn finish(self, run: &Run) -> Result<(), FileError> {
        self.complete(run)?.commit()
    }
}

/// `run` written whole to `path` as a file of kind `F`: all its records in one block.
fn write_whole<F: RunFile>(run: &Run, path: &Path) -> Result<(), FileError> {
    let mut file = F::create(path, run)?;
    file.block(&run.streams, &run.ballbar)?;
    file.finish(run)
}

/// Writes the file `path` through `write`, which is given a sibling path to write instead
/// (see [`Partial`]). On an error the partial file is removed, and the error names `path`, the
/// file asked for.
pub(crate) fn atomically(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), FileError>,
) -> Result<(), FileError> {
    let partial = Partial::new(path);
    write(partial.path()).map_err(|e| match e {
        FileError::Output { path: p, message } if Path::new(&p) == partial.path() => {
            FileError::output_message(path, message)
        }
        e => e,
    })?;
    partial.commit()
}

/// A file written as `<path>.partial` until it is complete, then renamed to `path` in one
/// step, so that no truncated `path` ever looks finished and a file from an earlier run stays
/// whole until it is replaced. Dropped before it is committed (a write that failed: a full
/// disk, a folder in the way), the partial file is removed; a process killed while writing
/// (Ctrl-C, kill -9) leaves it.
pub struct Partial {
    target: PathBuf,
    partial: PathBuf,
    committed: bool,
}

impl Partial {
    pub(crate) fn new(target: &Path) -> Self {
        let mut partial = target.as_os_str().to_owned();
        partial.push(".partial");
        Self {
            target: target.to_path_buf(),
            partial: PathBuf::from(partial),
            committed: false,
        }
    }

    /// The path to write: `<path>.partial`.
    pub(crate) fn path(&self) -> &Path {
        &self.partial
    }

    /// The path asked for, which errors name.
    pub(crate) fn target(&self) -> &Path {
        &self.target
    }

    /// Renames the complete partial file to its path.
    pub(crate) fn commit(mut self) -> Result<(), FileError> {
        std::fs::rename(&self.partial, &self.target)
            .map_err(|e| FileError::output(&self.target, e))?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for Partial {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.partial);
        }
    }
}

/// `text` as a lower-case name of ASCII letters, digits and single underscores, e.g.
/// `XY 150 mm 1000 mm/min CCW` -> `xy_150_mm_1000_mm_min_ccw`; `unnamed` if nothing is left.
pub fn slug(text: &str) -> String {
    let chars: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    for (i, &c) in chars.iter().enumerate() {
        let digit_before = i > 0 && chars[i - 1].is_ascii_digit();
        let digit_after = chars.get(i + 1).is_some_and(|n| n.is_ascii_digit());
        if c.is_ascii_alphanumeric() {
            out.push(c.to_ascii_lowercase());
        } else if c == '.' && digit_before && digit_after {
            // Keep decimal numbers readable: 0.5 mm -> 0p5_mm.
            out.push('p');
        } else if !out.is_empty() && !out.ends_with('_') {
            out.push('_');
        }
    }
    let out = out.trim_end_matches('_');
    if out.is_empty() {
        "unnamed".to_string()
    } else {
        out.to_string()
    }
}

/// Unique slugs of `names`, in order: a name whose slug repeats gets `_2`, `_3`, ... appended.
pub(crate) fn unique_slugs<'a>(names: impl Iterator<Item = &'a str>) -> Vec<String> {
    let mut seen = BTreeSet::new();
    names
        .map(|n| {
            let base = slug(n);
            let mut name = base.clone();
            let mut k = 2;
            while !seen.insert(name.clone()) {
                name = format!("{base}_{k}");
                k += 1;
            }
            name
        })
        .collect()
}

/// Simulation time `t_s` (s) as integer nanoseconds, or an error naming `what` when the time is
/// negative, not finite or beyond about 584 years.
pub(crate) fn time_ns(t_s: f64, what: &dyn Fn() -> String, path: &Path) -> Result<u64, FileError> {
    let ns = (t_s * 1e9).round();
    if ns.is_finite() && ns >= 0.0 && ns < u64::MAX as f64 {
        Ok(ns as u64)
    } else {
        Err(FileError::output_message(
            path,
            format!(
                "{}: time {t_s} s is not a finite, non-negative simulation time",
                what()
            ),
        ))
    }
}

/// Checks that every channel of `stream` has one value per sample time.
pub(crate) fn check_stream(stream: &Stream, path: &Path) -> Result<(), FileError> {
    let n = stream.times_s.len();
    match stream.channels.iter().find(|c| c.values.len() != n) {
        Some(c) => Err(FileError::output_message(
            path,
            format!(
                "stream `{}`: channel `{}` has {} values for {n} sample times",
                stream.name,
                c.name,
                c.values.len()
            ),
        )),
        None => Ok(()),
    }
}

/// Checks that a ball-bar trace has as many angles and deviations as sample times.
pub(crate) fn check_trace(trace: &BallbarTrace, path: &Path) -> Result<(), FileError> {
    let n = trace.times_s.len();
    if trace.angle_deg.len() == n && trace.deviation_um.len() == n {
        Ok(())
    } else {
        Err(FileError::output_message(
            path,
            format!(
                "ball-bar trace `{}`: {} times, {} angles and {} deviations (they must match)",
                trace.label,
                n,
                trace.angle_deg.len(),
                trace.deviation_um.len()
            ),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slugs() {
        assert_eq!(
            slug("XY 150 mm 1000 mm/min CCW"),
            "xy_150_mm_1000_mm_min_ccw"
        );
        assert_eq!(slug("  r = 0.5 mm "), "r_0p5_mm");
        assert_eq!(slug("/// "), "unnamed");
        assert_eq!(slug("µ"), "unnamed");
        let u = unique_slugs(["XY 150 CW", "xy 150 cw", "YZ"].into_iter());
        assert_eq!(u, ["xy_150_cw", "xy_150_cw_2", "yz"]);
    }

    #[test]
    fn times() {
        let p = Path::new("x");
        let w = || "w".to_string();
        assert_eq!(time_ns(1.5, &w, p).ok(), Some(1_500_000_000));
        assert!(time_ns(-1.0, &w, p).is_err());
        assert!(time_ns(f64::NAN, &w, p).is_err());
        assert!(time_ns(1e30, &w, p).is_err());
    }
}
