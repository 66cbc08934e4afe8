//! What the CLI tests share: the shipped sample and running the `fluidcast` binary.
#![allow(dead_code, clippy::unwrap_used)] // each test file uses part of it; tests may fail loudly

use std::path::PathBuf;
use std::process::Command;

/// The sample the README renders (`examples/data/sample_column.vtu`).
pub fn sample() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../examples/data/sample_column.vtu")
}

/// Runs `fluidcast ARGS`: (exit code, stdout, stderr). A panic is never an answer: its
/// message in stderr fails the test.
pub fn run(args: &[&str]) -> (Option<i32>, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_fluidcast"))
        .args(args)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(
        !err.contains("panicked"),
        "fluidcast {args:?} panicked: {err}"
    );
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).to_string(),
        err,
    )
}
