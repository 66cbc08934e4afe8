//! Long fuzzing runs of inputs made of several files (`fluidcast_fuzz::files`):
//! `fluidcast-fuzz-files [--cases N] [--seed S] [--out DIR] SEED_DIR...` (see
//! `scripts/fuzz.sh --files`, which runs it under a 4 GiB address-space limit).
//!
//! Each case is a new folder `DIR/case` of `.pvtu`/`.pvd` files, pieces, FIFOs, links and
//! folders naming each other, opened from one of them, read and rendered. Panics are caught
//! and the case's folder is kept as `DIR/panic-N`; a case running longer than 10 s is kept
//! as `DIR/case` and ends the run with exit code 3; a crash leaves it there too. Progress is
//! printed every 5 s; exit code 1 when anything was found.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use fluidcast_fuzz::files::{generate, open_and_render};
use fluidcast_fuzz::{panic_message, parses_as, seeds, watchdog, Rng};

/// A case taking longer than this counts as a hang.
const HANG: Duration = Duration::from_secs(10);

struct Args {
    cases: u64,
    seed: u64,
    out: PathBuf,
    dirs: Vec<PathBuf>,
}

fn parse_args() -> Result<Args, String> {
    let mut a = Args {
        cases: 100_000,
        seed: 1,
        out: PathBuf::from("target/fuzz-files"),
        dirs: Vec::new(),
    };
    let mut it = std::env::args().skip(1);
    while let Some(x) = it.next() {
        let mut val = |name: &str| it.next().ok_or(format!("{name} needs a value"));
        match x.as_str() {
            "--cases" => {
                a.cases = val("--cases")?
                    .parse()
                    .map_err(|e| format!("--cases: {e}"))?
            }
            "--seed" => a.seed = val("--seed")?.parse().map_err(|e| format!("--seed: {e}"))?,
            "--out" => a.out = PathBuf::from(val("--out")?),
            "-h" | "--help" => {
                return Err(
                    "usage: fluidcast-fuzz-files [--cases N] [--seed S] [--out DIR] SEED_DIR..."
                        .into(),
                )
            }
            d => a.dirs.push(PathBuf::from(d)),
        }
    }
    if a.dirs.is_empty() {
        return Err("give at least one folder of particle files".into());
    }
    Ok(a)
}

fn main() {
    match run() {
        Ok(0) => {}
        Ok(_) => std::process::exit(1),
        Err(e) => {
            eprintln!("fluidcast-fuzz-files: {e}");
            std::process::exit(2);
        }
    }
}

fn run() -> Result<u64, String> {
    let a = parse_args()?;
    let mut pieces = Vec::new();
    for d in &a.dirs {
        let found = seeds(d).map_err(|e| format!("{}: {e}", d.display()))?;
        pieces.extend(
            found
                .into_iter()
                .filter(|(p, _)| matches!(parses_as(p), Some("vtu" | "vtp" | "vtk"))),
        );
    }
    if pieces.is_empty() {
        return Err("no particle files (.vtu .vtp .vtk) in the given folders".into());
    }
    std::fs::create_dir_all(&a.out).map_err(|e| format!("{}: {e}", a.out.display()))?;
    println!(
        "{} pieces; {} cases, seed {}",
        pieces.len(),
        a.cases,
        a.seed
    );
    std::panic::set_hook(Box::new(|_| {})); // panics are counted, not printed
    let case = a.out.join("case");
    let kept = case.clone();
    let watch = watchdog(HANG, move || {
        eprintln!(
            "HANG: a case ran longer than {HANG:?}; kept in {}",
            kept.display()
        );
    });
    let t0 = Instant::now();
    let mut rng = Rng::new(a.seed);
    let (mut rendered, mut refused, mut findings) = (0u64, 0u64, 0u64);
    let mut last_report = Instant::now();
    for i in 0..a.cases {
        let _ = std::fs::remove_dir_all(&case);
        std::fs::create_dir_all(&case).map_err(|e| format!("{}: {e}", case.display()))?;
        let graph =
            generate(&mut rng, &case, &pieces).map_err(|e| format!("writing a case: {e}"))?;
        watch.start();
        match catch_unwind(AssertUnwindSafe(|| open_and_render(&graph.root))) {
            Ok(true) => rendered += 1,
            Ok(false) => refused += 1,
            Err(p) => {
                findings += 1;
                let kept = a.out.join(format!("panic-{findings}"));
                let _ = std::fs::remove_dir_all(&kept);
                let _ = std::fs::rename(&case, &kept);
                let message = panic_message(p.as_ref());
                println!(
                    "PANIC opening {} ({}): {message} (kept in {})",
                    graph.root.display(),
                    graph.description,
                    kept.display()
                );
            }
        }
        watch.stop();
        if last_report.elapsed() > Duration::from_secs(5) || i + 1 == a.cases {
            last_report = Instant::now();
            let s = t0.elapsed().as_secs_f64();
            println!(
                "{} cases in {s:.0} s ({:.0} cases/s): {rendered} rendered, {refused} refused, {findings} findings",
                i + 1,
                (i + 1) as f64 / s
            );
        }
    }
    let _ = std::fs::remove_dir_all(&case);
    Ok(findings)
}
