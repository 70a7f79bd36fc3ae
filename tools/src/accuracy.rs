//! `vmt accuracy`: the study of [`vmt_dataset::accuracy`] run, printed and written.

use crate::error::CliError;
use std::path::Path;
use vmt_dataset::accuracy::{markdown, study, write};

/// `vmt accuracy`: runs the study on `dir`, prints the table and writes the reports.
pub fn command(dir: &Path) -> Result<(), CliError> {
    let s = study(dir)?;
    for w in &s.warnings {
        crate::errln!("warning: {w}");
    }
    if s.failed.len() == s.runs {
        let why = s.failed.first().map_or_else(
            || "it holds no complete run".to_string(),
            |(id, e)| {
                format!(
                    "none of its {} runs could be diagnosed (run {id}: {e})",
                    s.runs
                )
            },
        );
        return Err(CliError::Argument(format!(
            "{}: nothing to score: {why}; `vmt accuracy` scores ball-bar datasets",
            dir.display()
        )));
    }
    crate::out!("{}", markdown(&s))?;
    write(&s, dir)?;
    crate::outln!(
        "\nwrote {}\nwrote {}",
        dir.join("accuracy.md").display(),
        dir.join("accuracy.json").display()
    )?;
    Ok(())
}
