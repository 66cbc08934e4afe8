//! The fuzzer's smoke run, part of every test run: 20,000 mutated inputs from every seed
//! (the VTK fixtures in all encodings, legacy files, a .pvd, a .pvtu summary, PNG and EXR), one in 20 that
//! parses also rendered, through the `fluidcast-fuzz` runner under a 4 GiB address-space
//! limit. A panic, an abort (an allocation a header merely claims), or an input running
//! longer than 10 s fails it. Long runs: `scripts/fuzz.sh`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly

use std::path::PathBuf;
use std::process::Command;

/// Runs fuzzer `bin` with `args` on the fixtures under a 4 GiB address-space limit, into a
/// folder of its own; its output, which must end with exit code 0.
fn run_capped(bin: &str, args: &str) -> String {
    let fixtures = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/fixtures");
    let out = tempfile::tempdir().unwrap();
    let o = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v 4194304; exec '{bin}' {args} --out '{}' '{}'",
            out.path().display(),
            fixtures.display()
        ))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stdout).to_string() + &String::from_utf8_lossy(&o.stderr);
    println!("{text}");
    assert_eq!(o.status.code(), Some(0), "{bin} {args} failed:\n{text}");
    text
}

#[test]
fn twenty_thousand_mutants_without_a_crash() {
    let text = run_capped(
        env!("CARGO_BIN_EXE_fluidcast-fuzz"),
        "--inputs 20000 --seed 7 --render-every 20",
    );
    assert!(
        text.contains("20000 inputs in") && text.contains(", 0 findings"),
        "{text}"
    );
    // Both outcomes occur: the mutants reach past the first checks, and most are refused.
    let last = text
        .lines()
        .rev()
        .find(|l| l.contains("inputs in"))
        .unwrap();
    let accepted: u64 = last
        .split(": ")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(accepted > 500 && accepted < 19_000, "{last}");
}

/// The multi-file fuzzer's smoke run: 3,000 random graphs of `.pvtu`/`.pvd` files, pieces,
/// FIFOs, links and folders naming each other (`fluidcast_fuzz::files`), opened, read and
/// rendered under a 4 GiB address-space limit. A panic, an abort or a case running longer
/// than 10 s (a FIFO read, a cycle followed) fails it. Long runs: `scripts/fuzz.sh --files`.
#[test]
fn three_thousand_file_graphs_without_a_crash() {
    let text = run_capped(
        env!("CARGO_BIN_EXE_fluidcast-fuzz-files"),
        "--cases 3000 --seed 7",
    );
    let last = text.lines().rev().find(|l| l.contains("cases in")).unwrap();
    assert!(
        last.starts_with("3000 cases in") && last.ends_with(", 0 findings"),
        "{last}"
    );
    // Both outcomes occur: some graphs read and render, most are refused.
    let rendered: u64 = last
        .split(": ")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(rendered > 30 && rendered < 2900, "{last}");
}
