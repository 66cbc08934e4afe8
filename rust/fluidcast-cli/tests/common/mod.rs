//! What the CLI tests share: the shipped sample, running the `fluidcast` binary on it, and
//! comparing images.
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

/// Renders the sample with `options` then `extra`, into `out`: (exit code, stderr).
pub fn render_sample(
    options: &[&str],
    extra: &[&str],
    out: &std::path::Path,
) -> (Option<i32>, String) {
    let sample = sample();
    let mut args = vec!["render", sample.to_str().unwrap()];
    args.extend_from_slice(options);
    args.extend_from_slice(extra);
    args.extend_from_slice(&["-o", out.to_str().unwrap()]);
    let (code, _, err) = run(&args);
    (code, err)
}

/// The largest difference of any RGBA channel.
pub fn max_diff(a: &fluidcast_image::Image, b: &fluidcast_image::Image) -> f32 {
    a.rgba
        .iter()
        .zip(&b.rgba)
        .flat_map(|(p, q)| (0..4).map(move |c| (p[c] - q[c]).abs()))
        .fold(0.0, f32::max)
}
