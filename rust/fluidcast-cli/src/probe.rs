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
    /// Output CSV: x,y,z,value,shepard,density,neighbours. `value` is the rendered field,
    /// left empty where it is undefined: the CSPH quotient where no particle reaches the
    /// point (the SPH and density sums are 0 there, and printed as 0).
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    particles: ParticleArgs,
}

pub fn run(a: ProbeArgs) -> Result<()> {
    let ds = read_dataset(&a.input)?;
    let p = Particles::from_dataset(&ds, &a.particles.spec()?)?;
    let text = fluidcast_mem::read_text(&a.points)
        .with_context(|| format!("reading {}", a.points.display()))?;
    let pts = parse_points(&text).with_context(|| a.points.display().to_string())?;
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

/// Query points from CSV text: one `x,y,z` per line, an optional header line first, blank
/// lines ignored; any other line is an error naming it.
fn parse_points(text: &str) -> Result<Vec<[f64; 3]>> {
    let mut pts = Vec::new();
    for (n, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        let nums: Option<Vec<f64>> = f.iter().map(|x| x.parse::<f64>().ok()).collect();
        match (nums.as_deref(), n) {
            (Some(&[x, y, z]), _) if [x, y, z].iter().all(|v| v.is_finite()) => pts.push([x, y, z]),
            (None, 0) => {} // header
            _ => bail!(
                "line {}: expected three finite numbers x,y,z, found '{}'",
                n + 1,
                line.trim()
            ),
        }
    }
    if pts.is_empty() {
        bail!("no query points");
    }
    Ok(pts)
}

#[cfg(test)]
mod tests {
    use super::parse_points;

    #[test]
    fn csv_rows_must_have_three_numbers() {
        assert_eq!(parse_points("x,y,z\n1,2,3\n\n4, 5 ,6\n").unwrap().len(), 2);
        for bad in [
            "1,2\n",
            "1,2,3,4\n",
            "0,0,0\nx,y,z\n",
            "1,nan,2\n",
            "x,y,z\n",
        ] {
            assert!(parse_points(bad).is_err(), "{bad:?}");
        }
        let e = parse_points("0,0,0\n1,2\n").unwrap_err().to_string();
        assert!(e.contains("line 2") && e.contains("'1,2'"), "{e}");
    }
}
