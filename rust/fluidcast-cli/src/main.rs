//! `fluidcast`: volume rendering of SPH particle files from the command line.

/// `println!` that returns write errors (a closed pipe, a full disk) with `?` instead of
/// panicking; `main` ends quietly on a closed pipe, as other command-line tools do.
macro_rules! out {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        anyhow::Context::context(
            writeln!(std::io::stdout().lock(), $($t)*),
            "writing to standard output",
        )?
    }};
}

mod bench;
mod bench_limit;
mod bench_lod;
mod bench_rbf;
mod checked;
mod info;
mod lod;
mod movie;
mod options;
mod probe;
mod rbf;
mod render;
mod surface;
mod view;

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use fluidcast_sph::ParticleError;

#[derive(Parser)]
#[command(
    name = "fluidcast",
    version,
    about = "Direct volume rendering of SPH particle data (VTK .vtu/.vtp/.pvd/.vtk)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a particle file or a .pvd series to EXR/PNG.
    Render(Box<render::RenderArgs>),
    /// Print points, bounds, arrays, field data and a suggested support radius.
    Info(info::InfoArgs),
    /// Compare two images (EXR or PNG): max abs difference, RMSE, share of pixels above a tolerance.
    Compare(CompareArgs),
    /// Evaluate the reconstructed field at given points (CSV in, CSV out).
    Probe(probe::ProbeArgs),
    /// Time the adaptive renderer against full rate and the reference over a camera orbit.
    Bench(Box<bench::BenchArgs>),
}

#[derive(clap::Args)]
struct CompareArgs {
    a: PathBuf,
    b: PathBuf,
    /// Per-channel tolerance for `frac_above` (channel values in [0, 1]).
    #[arg(long, default_value_t = 1.0 / 255.0)]
    tolerance: f64,
    /// Write |a − b| / tolerance as a grey image here.
    #[arg(long)]
    diff: Option<PathBuf>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
}

fn compare(a: CompareArgs) -> Result<()> {
    let ia = fluidcast_image::Image::read(&a.a)?;
    let ib = fluidcast_image::Image::read(&a.b)?;
    let (c, diff) = fluidcast_image::compare(&ia, &ib, a.tolerance)
        .with_context(|| format!("comparing {} with {}", a.a.display(), a.b.display()))?;
    if let Some(d) = &a.diff {
        diff.save(d, [0.0; 3], fluidcast_image::PngEncoding::Vtk)
            .with_context(|| format!("writing {}", d.display()))?;
    }
    if a.json {
        out!(
            "{}",
            serde_json::json!({"max_abs": c.max_abs, "rmse": c.rmse, "frac_above": c.frac_above, "tolerance": c.tolerance,
                               "depth_max_abs": json_number(c.depth_max_abs), "depth_frac_differ": c.depth_frac_differ,
                               "width": ia.width, "height": ia.height})
        );
    } else {
        out!("max abs difference: {:.6}", c.max_abs);
        out!("RMSE:               {:.6}", c.rmse);
        out!(
            "pixels above {:.5}: {:.4} %",
            c.tolerance,
            c.frac_above * 100.0
        );
        out!("max depth difference: {:.6} world units", c.depth_max_abs);
        out!(
            "pixels whose depth differs: {:.4} %",
            c.depth_frac_differ * 100.0
        );
    }
    Ok(())
}

/// A JSON number, or the string "inf" for an infinite one (JSON has no infinity).
fn json_number(x: f64) -> serde_json::Value {
    if x.is_finite() {
        x.into()
    } else {
        "inf".into()
    }
}

/// The error and its causes on one line, each cause once: a library error that already
/// quotes its source (`"{0}"` with `#[from]`) is not followed by that source again.
fn one_line(e: &anyhow::Error) -> String {
    let mut msg = String::new();
    for cause in e.chain() {
        let c = cause.to_string();
        if !msg.contains(&c) {
            if !msg.is_empty() {
                msg.push_str(": ");
            }
            msg.push_str(&c);
        }
    }
    msg
}

fn main() {
    let cli = Cli::parse();
    let r = match cli.command {
        Command::Render(a) => render::run(*a),
        Command::Info(a) => info::run(a),
        Command::Compare(a) => compare(a),
        Command::Probe(a) => probe::run(a),
        Command::Bench(a) => bench::run(*a),
    };
    if let Err(e) = r {
        let closed_pipe = e.chain().any(|c| {
            c.downcast_ref::<std::io::Error>()
                .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
        });
        if closed_pipe {
            return; // the reader went away (`fluidcast info F | head`): nothing to report
        }
        eprintln!("error: {}", one_line(&e));
        if let Some(h) = hint(&e) {
            eprintln!("hint: {h}");
        }
        std::process::exit(1);
    }
}

/// What to do about a volume of mass / density that is not finite and positive (a zero
/// density: SPlisHSPlasH writes one for particles emitted in that frame).
const ZERO_DENSITY_HINT: &str = "volumes are mass / density; --uniform-volume gives every \
    particle the same volume (the default csph field is then the kernel-weighted mean of the \
    values), --volume-array NAME takes them from an array";

/// What a user can do about an error the data caused, where the CLI has an option for it.
fn hint(e: &anyhow::Error) -> Option<&'static str> {
    e.chain()
        .find_map(|c| match c.downcast_ref::<ParticleError>() {
            Some(ParticleError::BadVolume { from, .. }) if from.contains(" / ") => {
                Some(ZERO_DENSITY_HINT)
            }
            _ => None,
        })
}
