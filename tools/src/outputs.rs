//! The names `vmt run` writes into its output folder and its `diagnosis/` subfolder, and the
//! removal of those an earlier run left there that this run does not write: a folder reused
//! with `--out` then holds one run's files (a laser run after `vmt demo` kept the demo's polar
//! plot and diagnosis beside its own, and a demo after Kwon's steps their plots 2 to 7).
//!
//! Only these names are ever removed, and only regular files with them: other files,
//! sub-folders and links stay.

use crate::error::CliError;
use std::path::{Path, PathBuf};

/// The subfolder of a run's folder that `vmt run --diagnose` writes.
pub const DIAGNOSIS: &str = "diagnosis";

/// Whether `name` is a file `vmt run` writes into its folder.
pub fn is_run_file(name: &str) -> bool {
    let polar_of_test = || {
        // ballbar_polar_<n>_<plane>_<radius>mm.png
        let Some(rest) = name
            .strip_prefix("ballbar_polar_")
            .and_then(|r| r.strip_suffix("mm.png"))
        else {
            return false;
        };
        let parts: Vec<&str> = rest.splitn(3, '_').collect();
        matches!(parts.as_slice(), [n, plane, radius]
            if is_count(n)
                && matches!(*plane, "xy" | "zx" | "yz")
                && radius.parse::<f64>().is_ok())
    };
    matches!(
        name,
        "run.mcap" | "run.rrd" | "ballbar_polar.png" | "laser_iso230_2.json" | "ground_truth.json"
    ) || polar_of_test()
}

/// Whether `name` is a file `vmt run --diagnose` writes into [`DIAGNOSIS`]: the reports, a
/// ball-bar test's `diagnosis_<n>.png`, a positioning test's plot, a milling run's chatter CSV.
pub fn is_diagnosis_file(name: &str) -> bool {
    let numbered = name
        .strip_prefix("diagnosis_")
        .and_then(|r| r.strip_suffix(".png"))
        .is_some_and(is_count);
    numbered
        || matches!(
            name,
            "report.txt" | "report.md" | "report.json" | "positioning.png" | "chatter.csv"
        )
}

/// `s` is a number 1, 2, ... as we write it.
fn is_count(s: &str) -> bool {
    !s.starts_with('0') && !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit())
}

/// Removes the regular files of `dir` whose names `ours` accepts and that are not among
/// `keep` (this run's files); returns their paths, sorted. A folder that does not exist has
/// nothing to remove.
pub fn remove_stale(
    dir: &Path,
    keep: &[PathBuf],
    ours: fn(&str) -> bool,
) -> Result<Vec<PathBuf>, CliError> {
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(CliError::output(dir, e)),
    };
    let kept = |name: &str| keep.iter().any(|k| k.file_name() == Some(name.as_ref()));
    let mut stale = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| CliError::output(dir, e))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        // The entry's own type: a link named like ours is not followed or removed.
        let file = entry.file_type().is_ok_and(|t| t.is_file());
        if file && ours(&name) && !kept(&name) {
            stale.push(entry.path());
        }
    }
    stale.sort();
    for path in &stale {
        std::fs::remove_file(path).map_err(|e| CliError::output(path, e))?;
    }
    Ok(stale)
}

/// Removes every diagnosis file of `dir`'s [`DIAGNOSIS`] subfolder (a run that is not
/// diagnosed has none), then the subfolder if that left it empty; returns what went.
pub fn clear_diagnosis(dir: &Path) -> Result<Vec<PathBuf>, CliError> {
    let sub = dir.join(DIAGNOSIS);
    let mut removed = remove_stale(&sub, &[], is_diagnosis_file)?;
    let empty = std::fs::read_dir(&sub).is_ok_and(|mut e| e.next().is_none());
    if empty {
        std::fs::remove_dir(&sub).map_err(|e| CliError::output(&sub, e))?;
        removed.push(sub);
    }
    Ok(removed)
}

/// The note `vmt run` prints for the files it removed from `dir`, or `None` if it removed none.
pub fn removed_note(dir: &Path, removed: &[PathBuf]) -> Option<String> {
    if removed.is_empty() {
        return None;
    }
    let names: Vec<String> = removed
        .iter()
        .map(|p| {
            // The folder itself is gone by now: told by its name.
            let name = p.strip_prefix(dir).unwrap_or(p).display().to_string();
            if name == DIAGNOSIS {
                format!("{name}/")
            } else {
                name
            }
        })
        .collect();
    Some(format!(
        "removed from {} what an earlier run left there and this run does not write: {}",
        dir.display(),
        names.join(", ")
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_our_own_names_are_recognised() {
        for name in [
            "run.mcap",
            "ballbar_polar.png",
            "ballbar_polar_7_yz_150mm.png",
            "ballbar_polar_12_xy_100.5mm.png",
            "laser_iso230_2.json",
        ] {
            assert!(is_run_file(name), "{name}");
        }
        for name in [
            "ballbar_polar_old.png",
            "ballbar_polar_1_xz_150mm.png",
            "ballbar_polar_01_xy_150mm.png",
            "ballbar_polar_1_xy_mm.png",
            "run.mcap.partial",
            "notes.txt",
            "report.txt",
        ] {
            assert!(!is_run_file(name), "{name}");
        }
        for name in [
            "report.md",
            "diagnosis_3.png",
            "positioning.png",
            "chatter.csv",
        ] {
            assert!(is_diagnosis_file(name), "{name}");
        }
        for name in [
            "diagnosis_.png",
            "diagnosis_x.png",
            "run.mcap",
            "report.pdf",
        ] {
            assert!(!is_diagnosis_file(name), "{name}");
        }
    }

    #[test]
    fn stale_files_of_ours_go_and_everything_else_stays() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        for name in [
            "run.mcap",
            "ballbar_polar.png",
            "notes.txt",
            "laser_iso230_2.json",
        ] {
            std::fs::write(d.join(name), "x").unwrap();
        }
        // A folder with one of our names is not ours to remove.
        std::fs::create_dir(d.join("ground_truth.json")).unwrap();
        let keep = [d.join("run.mcap"), d.join("laser_iso230_2.json")];
        let removed = remove_stale(d, &keep, is_run_file).unwrap();
        assert_eq!(removed, [d.join("ballbar_polar.png")]);
        for name in [
            "run.mcap",
            "notes.txt",
            "laser_iso230_2.json",
            "ground_truth.json",
        ] {
            assert!(d.join(name).exists(), "{name}");
        }
        assert!(
            remove_stale(&d.join("none"), &[], is_run_file)
                .unwrap()
                .is_empty()
        );
    }

    #[test]
    fn the_diagnosis_folder_goes_only_when_nothing_else_is_in_it() {
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join(DIAGNOSIS);
        std::fs::create_dir(&sub).unwrap();
        std::fs::write(sub.join("report.txt"), "x").unwrap();
        std::fs::write(sub.join("mine.txt"), "x").unwrap();
        assert_eq!(
            clear_diagnosis(dir.path()).unwrap(),
            [sub.join("report.txt")]
        );
        assert!(sub.join("mine.txt").exists());
        std::fs::remove_file(sub.join("mine.txt")).unwrap();
        std::fs::write(sub.join("diagnosis_1.png"), "x").unwrap();
        assert_eq!(
            clear_diagnosis(dir.path()).unwrap(),
            [sub.join("diagnosis_1.png"), sub.clone()]
        );
        assert!(!sub.exists());
    }
}
