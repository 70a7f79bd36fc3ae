//! Errors of reading and writing log files: which file, where in it, and what went wrong.

use std::path::Path;
use thiserror::Error;

/// A file that cannot be read as what it should hold, or written.
#[derive(Debug, Error)]
pub enum FileError {
    /// An input file (a run's MCAP, a CSV ...), with the line when known.
    #[error("{file}{}: {message}", line.map(|l| format!(":{l}")).unwrap_or_default())]
    Input {
        /// The file.
        file: String,
        /// 1-based line.
        line: Option<usize>,
        /// What is wrong and what is accepted.
        message: String,
    },
    /// Writing an output.
    #[error("cannot write {path}: {message}")]
    Output {
        /// The file.
        path: String,
        /// The reason.
        message: String,
    },
}

impl FileError {
    /// An input error at `line` of `file`.
    pub fn input(file: &str, line: Option<usize>, message: impl Into<String>) -> Self {
        FileError::Input {
            file: file.to_string(),
            line,
            message: message.into(),
        }
    }

    /// An output error for `path`: the error and the causes under it (see [`with_causes`]).
    pub fn output(path: &Path, e: impl std::error::Error) -> Self {
        Self::output_message(path, with_causes(&e))
    }

    /// An output error for `path` with a reason in words (a check of ours, not an error value).
    pub fn output_message(path: &Path, message: impl Into<String>) -> Self {
        FileError::Output {
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
        let e = FileError::output(Path::new("out/run.mcap"), Wrapper(os));
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
