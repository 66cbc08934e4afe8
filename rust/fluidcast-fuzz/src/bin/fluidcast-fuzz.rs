//! Long fuzzing runs: `fluidcast-fuzz [--inputs N] [--seed S] [--render-every K]
//! [--out DIR] SEED_DIR...` (see `scripts/fuzz.sh`, which runs this under a 4 GiB
//! address-space limit).
//!
//! Every input is written to `DIR/current.bin` before it runs, so a crash (abort, out of
//! memory) leaves the input behind; panics are caught, saved under `DIR/panic-N.EXT` and
//! counted; an input running longer than 10 s is saved as `DIR/hang.EXT` and ends the run
//! with exit code 3. Progress (inputs, inputs/s, accepted, refused, findings) is printed
//! every 5 s; exit code 1 when anything was found.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use fluidcast_fuzz::{image_seeds, mutate, parses_as, run_input, seeds, watchdog, Outcome, Rng};

/// An input taking longer than this counts as a hang.
const HANG: Duration = Duration::from_secs(10);

struct Args {
    inputs: u64,
    seed: u64,
    render_every: u64,
    out: PathBuf,
    dirs: Vec<PathBuf>,
}

fn parse_args() -> Result<Args, String> {
    let mut a = Args {
        inputs: 100_000,
        seed: 1,
        render_every: 20,
        out: PathBuf::from("target/fuzz-out"),
        dirs: Vec::new(),
    };
    let mut it = std::env::args().skip(1);
    while let Some(x) = it.next() {
        let mut val = |name: &str| it.next().ok_or(format!("{name} needs a value"));
        match x.as_str() {
            "--inputs" => a.inputs = val("--inputs")?.parse().map_err(|e| format!("--inputs: {e}"))?,
            "--seed" => a.seed = val("--seed")?.parse().map_err(|e| format!("--seed: {e}"))?,
            "--render-every" => {
                a.render_every = val("--render-every")?
                    .parse()
                    .map_err(|e| format!("--render-every: {e}"))?
            }
            "--out" => a.out = PathBuf::from(val("--out")?),
            "-h" | "--help" => return Err("usage: fluidcast-fuzz [--inputs N] [--seed S] [--render-every K] [--out DIR] SEED_DIR...".into()),
            d => a.dirs.push(PathBuf::from(d)),
        }
    }
    if a.dirs.is_empty() {
        return Err("give at least one folder of seed files".into());
    }
    Ok(a)
}

fn main() {
    match run() {
        Ok(0) => {}
        Ok(_) => std::process::exit(1),
        Err(e) => {
            eprintln!("fluidcast-fuzz: {e}");
            std::process::exit(2);
        }
    }
}

fn run() -> Result<u64, String> {
    let a = parse_args()?;
    std::fs::create_dir_all(&a.out).map_err(|e| format!("{}: {e}", a.out.display()))?;
    let mut corpus = image_seeds().map_err(|e| format!("writing the image seeds: {e}"))?;
    for d in &a.dirs {
        corpus.extend(seeds(d).map_err(|e| format!("{}: {e}", d.display()))?);
    }
    if corpus.len() <= 2 {
        return Err("no seed files (.vtu .vtp .vtk .pvd .png .exr) in the given folders".into());
    }
    println!(
        "{} seeds; up to {} inputs, seed {}, every {}th input that parses is also rendered",
        corpus.len(),
        a.inputs,
        a.seed,
        a.render_every
    );
    std::panic::set_hook(Box::new(|_| {})); // panics are counted, not printed
    let out = a.out.clone();
    let watch = watchdog(HANG, move || {
        let _ = std::fs::copy(out.join("current.bin"), out.join("hang.bin"));
        eprintln!(
            "HANG: an input ran longer than {HANG:?}; saved as {}",
            out.join("hang.bin").display()
        );
    });
    let t0 = Instant::now();
    let mut rng = Rng::new(a.seed);
    let (mut accepted, mut refused, mut findings) = (0u64, 0u64, 0u64);
    let mut last_report = Instant::now();
    let current = a.out.join("current.bin");
    for i in 0..a.inputs {
        let Some((path, seed)) = corpus.get(rng.below(corpus.len())) else {
            break;
        };
        let ext = parses_as(path).unwrap_or("vtu");
        let input = mutate(seed, &mut rng);
        std::fs::write(&current, &input).map_err(|e| format!("{}: {e}", current.display()))?;
        watch.start();
        let render = a.render_every > 0 && i % a.render_every == 0;
        match run_input(&input, ext, render) {
            Ok(Outcome::Accepted) => accepted += 1,
            Ok(Outcome::Refused(_)) => refused += 1,
            Err(f) => {
                findings += 1;
                let p = a.out.join(format!("panic-{findings}.{ext}"));
                let _ = std::fs::write(&p, &input);
                println!(
                    "PANIC on a mutant of {}: {} (saved as {})",
                    path.display(),
                    f.message,
                    p.display()
                );
            }
        }
        watch.stop();
        if last_report.elapsed() > Duration::from_secs(5) || i + 1 == a.inputs {
            last_report = Instant::now();
            let s = t0.elapsed().as_secs_f64();
            println!(
                "{} inputs in {s:.0} s ({:.0} inputs/s): {accepted} accepted, {refused} refused, {findings} findings",
                i + 1,
                (i + 1) as f64 / s
            );
        }
    }
    Ok(findings)
}
