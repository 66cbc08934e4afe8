//! `fluidcast`: volume rendering of SPH particle files from the command line.

mod bench;
mod info;
mod options;
mod probe;
mod render;
mod view;

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};

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
    let (c, diff) = fluidcast_image::compare(&ia, &ib, a.tolerance)?;
    if let Some(d) = &a.diff {
        diff.save(d, [0.0; 3], fluidcast_image::PngEncoding::Vtk)
            .with_context(|| format!("writing {}", d.display()))?;
    }
    if a.json {
        println!(
            "{}",
            serde_json::json!({"max_abs": c.max_abs, "rmse": c.rmse, "frac_above": c.frac_above, "tolerance": c.tolerance,
                               "width": ia.width, "height": ia.height})
        );
    } else {
        println!("max abs difference: {:.6}", c.max_abs);
        println!("RMSE:               {:.6}", c.rmse);
        println!(
            "pixels above {:.5}: {:.4} %",
            c.tolerance,
            c.frac_above * 100.0
        );
    }
    Ok(())
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
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
