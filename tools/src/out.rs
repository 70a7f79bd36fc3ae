//! Standard output of every command. `println!` panics ("failed printing to stdout: Broken
//! pipe", exit 101) when stdout is closed, e.g. piped into `head -1`; the macros here write the
//! same text but return the failure as [`CliError`] naming `<stdout>`, which the command passes
//! up with `?` like any other output error.

use crate::error::CliError;
use std::io::Write;

/// Writes `args` to stdout and flushes; a failure (a closed pipe) is an error naming `<stdout>`.
pub fn print(args: std::fmt::Arguments) -> Result<(), CliError> {
    let mut w = std::io::stdout().lock();
    w.write_fmt(args)
        .and_then(|_| w.flush())
        .map_err(CliError::stdout)
}

/// `print!` that returns `Result<(), CliError>` instead of panicking on a closed stdout.
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::out::print(format_args!($($arg)*))
    };
}

/// `println!` that returns `Result<(), CliError>` instead of panicking on a closed stdout.
#[macro_export]
macro_rules! outln {
    () => {
        $crate::out::print(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::out::print(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// Writes `args` to stderr, ignoring a failure: with stderr closed too there is nowhere left
/// to report anything, and `eprintln!` would panic.
pub fn print_err(args: std::fmt::Arguments) {
    let mut w = std::io::stderr().lock();
    let _ = w.write_fmt(args).and_then(|_| w.flush());
}

/// `eprintln!` that does not panic on a closed stderr.
#[macro_export]
macro_rules! errln {
    ($($arg:tt)*) => {
        $crate::out::print_err(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// Creates the output folder `dir` (and its parents) before a command does its work, so that a
/// path that cannot be a folder (an existing file, a place without write access) is refused
/// at once, not after a long simulation.
pub fn output_dir(dir: &std::path::Path) -> Result<(), CliError> {
    std::fs::create_dir_all(dir).map_err(|e| CliError::output(dir, e))
}
