//! Errors of the command line: what went wrong, where, and what would be accepted.

use thiserror::Error;
use vmt_logs::FileError;
pub use vmt_logs::with_causes;
use vmt_scenario::ScenarioError;

/// Anything a `vmt` command can fail with.
#[derive(Debug, Error)]
pub enum CliError {
    /// The scenario file.
    #[error("{0}")]
    Scenario(#[from] ScenarioError),
    /// A file read (points CSV, a run, with the line when known) or written.
    #[error(transparent)]
    File(#[from] FileError),
    /// A command-line argument.
    #[error("{0}")]
    Argument(String),
    /// The model refused a computation (thermal run, deformation).
    #[error("{0}")]
    Model(String),
}

impl From<vmt_dataset::Error> for CliError {
    fn from(e: vmt_dataset::Error) -> Self {
        match e {
            vmt_dataset::Error::Scenario(e) => CliError::Scenario(e),
            vmt_dataset::Error::File(e) => CliError::File(e),
            vmt_dataset::Error::Request(m) => CliError::Argument(m),
            vmt_dataset::Error::Model(m) => CliError::Model(m),
        }
    }
}

impl CliError {
    /// An input error at `line` of `file`.
    pub fn input(file: &str, line: Option<usize>, message: impl Into<String>) -> Self {
        FileError::input(file, line, message).into()
    }

    /// Standard output could not be written (closed, e.g. piped into `head`).
    pub fn stdout(e: std::io::Error) -> Self {
        Self::output(std::path::Path::new("<stdout>"), e)
    }

    /// A command-line option's value refused: `--name value: accepted`.
    pub fn option(
        name: &str,
        value: impl std::fmt::Display,
        accepted: impl std::fmt::Display,
    ) -> Self {
        CliError::Argument(format!("{name} {value}: {accepted}"))
    }

    /// An output error for `path`: the error and the causes under it (see [`with_causes`]).
    pub fn output(path: &std::path::Path, e: impl std::error::Error) -> Self {
        FileError::output(path, e).into()
    }

    /// An output error for `path` with a reason in words (a check of ours, not an error value).
    pub fn output_message(path: &std::path::Path, message: impl Into<String>) -> Self {
        FileError::output_message(path, message).into()
    }
}

/// Checks option `name`'s `value` against `lo..=hi`; the error names the option and value, the
/// accepted range (followed by `unit`, the unit the user typed, when there is one) and `why` it
/// is bounded. A NaN is outside every range.
fn check_within<T: PartialOrd + Copy + std::fmt::Display>(
    name: &str,
    value: T,
    (lo, hi): (T, T),
    unit: &str,
    why: &str,
) -> Result<T, CliError> {
    if (lo..=hi).contains(&value) {
        return Ok(value);
    }
    let unit = if unit.is_empty() {
        String::new()
    } else {
        format!(" {unit}")
    };
    Err(CliError::option(
        name,
        value,
        format!("from {lo} to {hi}{unit} is accepted ({why})"),
    ))
}

/// `check_within` for a quantity in `unit`.
pub fn check_range(
    name: &str,
    value: f64,
    range: (f64, f64),
    unit: &str,
    why: &str,
) -> Result<f64, CliError> {
    check_within(name, value, range, unit, why)
}

/// `check_within` for a count.
pub fn check_count(
    name: &str,
    value: usize,
    range: (usize, usize),
    why: &str,
) -> Result<usize, CliError> {
    check_within(name, value, range, "", why)
}

/// Checks that option `name`'s `value` is a finite number above 0 and at most `hi` `unit`.
pub fn check_positive(
    name: &str,
    value: f64,
    hi: f64,
    unit: &str,
    why: &str,
) -> Result<f64, CliError> {
    if value.is_finite() && value > 0.0 && value <= hi {
        Ok(value)
    } else {
        Err(CliError::option(
            name,
            value,
            format!("must be > 0 and at most {hi} {unit} ({why})"),
        ))
    }
}
