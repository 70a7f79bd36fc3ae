//! Running the `vmt` binary from the integration tests.

use std::process::{Command, Output};

/// Runs `vmt` with `args` under coreutils `timeout`, so that a command that hangs fails its
/// test instead of stalling the suite.
pub fn vmt(args: &[&str]) -> Output {
    Command::new("timeout")
        .args(["300", env!("CARGO_BIN_EXE_vmt")])
        .args(args)
        .output()
        .unwrap()
}

/// The command's standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}
