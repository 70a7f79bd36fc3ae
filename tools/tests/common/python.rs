//! Reading our files back with the Python readers of tools/tests (mcap, rerun-sdk).

use serde_json::Value;
use std::path::Path;
use std::process::Command;

/// Runs a reader script of tools/tests and parses its JSON output; fails with the script's
/// message (e.g. a missing Python package) otherwise.
pub fn python(script: &str, file: &Path) -> Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests")
        .join(script);
    let out = Command::new("python3")
        .arg(&script)
        .arg(file)
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "cannot run python3 ({e}): the format tests need Python 3 with \
                 `python3 -m pip install -r tools/tests/requirements.txt`"
            )
        });
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "{} failed ({}):\n{stderr}\nThe format tests need the Python packages of \
         tools/tests/requirements.txt: python3 -m pip install -r tools/tests/requirements.txt",
        script.display(),
        out.status
    );
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "{} printed no JSON ({e}): {}",
            script.display(),
            String::from_utf8_lossy(&out.stdout)
        )
    })
}
