use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use fluidcast_io::read_dataset;
use fluidcast_sph::Particles;

use crate::options::ParticleArgs;

#[derive(clap::Args)]
pub struct ProbeArgs {
    /// Particle file.
    input: PathBuf,
    /// CSV of query points, one `x,y,z` per line (a header line is skipped).
    #[arg(long)]
    points: PathBuf,
    /// Output CSV: x,y,z,value,shepard,density,neighbours (value empty where undefined).
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    particles: ParticleArgs,
}

pub fn run(a: ProbeArgs) -> Result<()> {
    let ds = read_dataset(&a.input)?;
    let p = Particles::from_dataset(&ds, &a.particles.spec()?)?;
    let text = std::fs::read_to_string(&a.points)
        .with_context(|| format!("reading {}", a.points.display()))?;
    let mut pts = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() < 3 {
            continue;
        }
        match (
            f[0].parse::<f64>(),
            f[1].parse::<f64>(),
            f[2].parse::<f64>(),
        ) {
            (Ok(x), Ok(y), Ok(z)) => pts.push([x, y, z]),
            _ if n == 0 => {} // header
            _ => bail!(
                "{}: line {}: expected x,y,z numbers",
                a.points.display(),
                n + 1
            ),
        }
    }
    let kind = a.particles.field()?;
    let samples = p.sample_many(a.particles.kernel()?, &pts);
    let f = std::fs::File::create(&a.output)
        .with_context(|| format!("writing {}", a.output.display()))?;
    let mut w = std::io::BufWriter::new(f);
    writeln!(w, "x,y,z,value,shepard,density,neighbours")?;
    for (x, s) in pts.iter().zip(samples) {
        let v = s
            .value(kind)
            .map(|v| format!("{v:.17e}"))
            .unwrap_or_default();
        writeln!(
            w,
            "{},{},{},{v},{:.17e},{:.17e},{}",
            x[0], x[1], x[2], s.shepard, s.density, s.neighbours
        )?;
    }
    Ok(())
}
