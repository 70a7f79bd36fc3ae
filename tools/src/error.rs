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
    pub fn stdout(e: impl std::fmt::Display) -> Self {
        Self::output(std::path::Path::new("<stdout>"), e)
    }

    /// An output error for `path`.
    pub fn output(path: &std::path::Path, e: impl std::fmt::Display) -> Self {
        CliError::Output {
            path: path.display().to_string(),
            message: e.to_string(),
        }
    }
}
