//! Errors of the command line: what went wrong, where, and what would be accepted.

use thiserror::Error;
use vmt_scenario::ScenarioError;

/// Anything a `vmt` command can fail with.
#[derive(Debug, Error)]
pub enum CliError {
    /// The scenario file.
    #[error("{0}")]
    Scenario(#[from] ScenarioError),
    /// An input file (points CSV ...), with the line and column when known.
    #[error("{file}{}: {message}", line.map(|l| format!(":{l}")).unwrap_or_default())]
    Input {
        /// The file.
        file: String,
        /// 1-based line.
        line: Option<usize>,
        /// What is wrong and what is accepted.
        message: String,
    },
    /// A command-line argument.
    #[error("{0}")]
    Argument(String),
    /// Writing an output.
    #[error("cannot write {path}: {message}")]
    Output {
        /// The file.
        path: String,
        /// The reason.
        message: String,
    },
    /// The model refused a computation (thermal run, deformation).
    #[error("{0}")]
    Model(String),
}

impl CliError {
    /// An input error at `line` of `file`.
    pub fn input(file: &str, line: Option<usize>, message: impl Into<String>) -> Self {
        CliError::Input {
            file: file.to_string(),
            line,
            message: message.into(),
        }
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
        Self::output_message(path, with_causes(&e))
    }

    /// An output error for `path` with a reason in words (a check of ours, not an error value).
    pub fn output_message(path: &std::path::Path, message: impl Into<String>) -> Self {
        CliError::Output {
            path: path.display().to_string(),
            message: message.into(),
        }
    }
}

/// `e` and its chain of sources joined by `: `, each left out when the text so far holds it
/// already. Writers wrap the operating system's error in their own ("I/O error from writing,
/// or reading a compression stream"), whose text alone hides what happened ("File too large
/// (os error 27)").
pub fn with_causes(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(cause) = source {
        let more = cause.to_string();
        if !text.contains(&more) {
            text = format!("{text}: {more}");
        }
        source = cause.source();
    }
    text
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A writer's error wrapping the operating system's, as the MCAP writer's does.
    #[derive(Debug, Error)]
    #[error("I/O error from writing")]
    struct Wrapper(#[source] std::io::Error);

    #[test]
    fn an_output_error_names_the_cause_under_the_writers_error() {
        let os = std::io::Error::from_raw_os_error(27);
        let e = CliError::output(std::path::Path::new("out/run.mcap"), Wrapper(os));
        assert_eq!(
            e.to_string(),
            "cannot write out/run.mcap: I/O error from writing: File too large (os error 27)"
        );
    }

    /// A cause whose text the error's own text holds already (serde_json prints its I/O
    /// error) is not repeated.
    #[test]
    fn a_cause_already_in_the_text_is_not_repeated() {
        #[derive(Debug, Error)]
        #[error("writing JSON: {0}")]
        struct Says(#[source] std::io::Error);
        let os = std::io::Error::from_raw_os_error(28);
        let text = with_causes(&Says(os));
        assert_eq!(text, "writing JSON: No space left on device (os error 28)");
    }
}
