//! `--columns` and `--units`: the options that let the CSV readers (accelerometer, ball-bar,
//! laser) take an instrument's export as it is exported (`vmt_logs::csv_import`).

use crate::error::CliError;
use vmt_logs::csv_import::{Column, ColumnMap, ImportError, Resolved, Units, resolve};

/// The options, as typed.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct ImportArgs {
    /// A CSV export's headers for our columns, NAME=HEADER pairs separated by commas, e.g.
    /// "time_s=Time (s),ax=Accel X (m/s^2),ay=Accel Y (m/s^2),az=Accel Z (m/s^2)"; a column
    /// not named is looked for under our own name, the export's other columns are ignored.
    #[arg(long)]
    pub columns: Option<String>,
    /// The units a CSV export gives our columns in, NAME=UNIT pairs, e.g. "ax=g,time_s=ms":
    /// time s or ms, acceleration m/s^2 or g, lengths um or mm, angles deg or rad (default:
    /// ours, or the unit written in the mapped header, as "(m/s^2)" in "Accel X (m/s^2)").
    #[arg(long)]
    pub units: Option<String>,
}

/// The options, parsed.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Import {
    /// `--columns`.
    pub map: ColumnMap,
    /// `--units`.
    pub units: Units,
}

impl ImportArgs {
    /// Parses both options (nothing given: every column under our name, in our units).
    pub fn parse(&self) -> Result<Import, CliError> {
        let syntax = |e: ImportError| CliError::Argument(e.to_string());
        Ok(Import {
            map: self
                .columns
                .as_deref()
                .map(ColumnMap::parse)
                .transpose()
                .map_err(syntax)?
                .unwrap_or_default(),
            units: self
                .units
                .as_deref()
                .map(Units::parse)
                .transpose()
                .map_err(syntax)?
                .unwrap_or_default(),
        })
    }
}

impl Import {
    /// Whether either option was given.
    pub fn given(&self) -> bool {
        !self.map.pairs.is_empty() || !self.units.pairs.is_empty()
    }

    /// Whether `--columns` maps our column `name`.
    pub fn maps(&self, name: &str) -> bool {
        self.map.pairs.iter().any(|(k, _)| k == name)
    }

    /// The `columns` of a reader of `what` found in the header of `file`: a mapping or unit the
    /// file's header contradicts is an error of the file (line 1, naming the header); one the
    /// reader does not take, an error of the option.
    pub fn resolve(
        &self,
        header: &csv::StringRecord,
        columns: &[Column],
        what: &'static str,
        file: &str,
    ) -> Result<Resolved, CliError> {
        let cells: Vec<&str> = header.iter().collect();
        resolve(&cells, columns, &self.map, &self.units, what).map_err(|e| match e {
            ImportError::MissingHeader { .. }
            | ImportError::MissingColumn { .. }
            | ImportError::UnitConflict { .. }
            | ImportError::Ambiguous(_) => CliError::input(file, Some(1), e.to_string()),
            ImportError::Syntax { .. }
            | ImportError::UnknownColumn { .. }
            | ImportError::UnknownUnit { .. } => CliError::Argument(e.to_string()),
        })
    }
}

/// The line a report gives the columns read: `columns: time_s = "Time (s)" in s (from the
/// header), …`.
pub fn echo(resolved: &Resolved) -> String {
    format!("columns: {resolved}")
}
