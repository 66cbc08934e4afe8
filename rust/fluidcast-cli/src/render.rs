use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use fluidcast_io::{read_dataset, Input};
use fluidcast_render::{render_reference, RenderParams, RenderStats};
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, TransferFunction};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

use crate::options::ParticleArgs;

#[derive(clap::Args)]
pub struct RenderArgs {
    /// A .vtu, .vtp, legacy .vtk file, or a .pvd series.
    input: PathBuf,
    /// Output image: .png (8-bit sRGB over --background) or .exr (float RGBA premultiplied + Z).
    /// For several frames, a pattern such as out_%04d.png (the frame index).
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    particles: ParticleArgs,
    /// Camera JSON file (vtkCamera fields: position, focal_point, view_up, view_angle,
    /// parallel_projection, parallel_scale) or `auto` (vtkRenderer::ResetCamera on the data,
    /// looking down -z with y up).
    #[arg(long, default_value = "auto")]
    camera: String,
    /// Rotate the camera about view up (degrees, as vtkCamera::Azimuth), after --camera.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    azimuth: f64,
    /// Rotate the camera up/down about the focal point (degrees, as vtkCamera::Elevation).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    elevation: f64,
    /// Zoom factor (> 1 zooms in, as vtkCamera::Zoom).
    #[arg(long, default_value_t = 1.0)]
    zoom: f64,
    /// Use a parallel projection (for --camera auto).
    #[arg(long)]
    parallel: bool,
    /// Write the camera used (JSON) here.
    #[arg(long)]
    save_camera: Option<PathBuf>,
    /// Image size in pixels, WxH.
    #[arg(long, default_value = "800x600")]
    size: String,
    /// Transfer function: a built-in preset (Cool to Warm, Viridis, Inferno, Grayscale) or a
    /// ParaView colour-map preset .json file.
    #[arg(long, default_value = "Viridis")]
    tf: String,
    /// Data range mapped onto the colour map, lo,hi (default: the first frame's value range).
    #[arg(long, allow_hyphen_values = true)]
    range: Option<String>,
    /// Distance (world units) over which the transfer function's opacity applies, as
    /// ParaView's Scalar Opacity Unit Distance. Default: bounds diagonal / cbrt(particles).
    #[arg(long)]
    opacity_unit_distance: Option<f64>,
    /// Multiply the transfer function's opacities.
    #[arg(long, default_value_t = 1.0)]
    opacity_scale: f64,
    /// Depth samples per pixel footprint (1 = the depth step equals the pixel footprint).
    #[arg(long, default_value_t = 1.0)]
    sampling_scale: f64,
    /// Background colour (linear RGB, 0..1) for PNG output.
    #[arg(long, default_value = "1,1,1")]
    background: String,
    /// Frames of a .pvd series, START:END (end exclusive), START:END:STEP or one index.
    #[arg(long)]
    frames: Option<String>,
    /// Write timings and counts as JSON here (for a series: one object per frame in a list).
    #[arg(long)]
    stats: Option<PathBuf>,
}

fn parse_pair(s: &str, what: &str) -> Result<(f64, f64)> {
    let v: Vec<&str> = s.split(',').collect();
    if v.len() != 2 {
        bail!("{what} '{s}': expected two numbers, lo,hi");
    }
    Ok((
        v[0].trim()
            .parse()
            .with_context(|| format!("{what} '{s}'"))?,
        v[1].trim()
            .parse()
            .with_context(|| format!("{what} '{s}'"))?,
    ))
}

fn parse_size(s: &str) -> Result<(u32, u32)> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .with_context(|| format!("--size '{s}': expected WxH, e.g. 800x600"))?;
    let w: u64 = w.trim().parse().with_context(|| format!("--size '{s}'"))?;
    let h: u64 = h.trim().parse().with_context(|| format!("--size '{s}'"))?;
    if w == 0
        || h == 0
        || w > fluidcast_render::MAX_SIDE as u64
        || h > fluidcast_render::MAX_SIDE as u64
    {
        bail!(
            "--size {w}x{h}: each side must be 1..={} pixels",
            fluidcast_render::MAX_SIDE
        );
    }
    Ok((w as u32, h as u32))
}

fn parse_frames(s: &str, n: usize) -> Result<Vec<usize>> {
    let parts: Vec<&str> = s.split(':').collect();
    let num = |t: &str, d: usize| -> Result<usize> {
        if t.trim().is_empty() {
            Ok(d)
        } else {
            t.trim().parse().with_context(|| format!("--frames '{s}'"))
        }
    };
    let (a, b, step) = match parts.len() {
        1 => {
            let i = num(parts[0], 0)?;
            (i, i + 1, 1)
        }
        2 => (num(parts[0], 0)?, num(parts[1], n)?, 1),
        3 => (num(parts[0], 0)?, num(parts[1], n)?, num(parts[2], 1)?),
        _ => bail!("--frames '{s}': expected START:END[:STEP]"),
    };
    if step == 0 {
        bail!("--frames '{s}': step must be > 0");
    }
    let v: Vec<usize> = (a..b.min(n)).step_by(step).collect();
    if v.is_empty() {
        bail!(
            "--frames '{s}' selects no frame (the series has {n} frames, 0..{})",
            n.saturating_sub(1)
        );
    }
    Ok(v)
}

/// Expands a printf-style `%d` / `%0Nd` in the output path with the frame index.
fn frame_path(pattern: &Path, index: usize) -> Result<PathBuf> {
    let s = pattern.to_string_lossy();
    let Some(p) = s.find('%') else {
        bail!("output '{s}' needs a %04d-style frame pattern for several frames")
    };
    let rest = &s[p + 1..];
    let end = rest
        .find('d')
        .with_context(|| format!("output '{s}': unsupported pattern (use %d or %04d)"))?;
    let spec = &rest[..end];
    let width: usize = if spec.is_empty() {
        0
    } else {
        spec.trim_start_matches('0')
            .parse()
            .with_context(|| format!("output pattern '{s}'"))?
    };
    Ok(PathBuf::from(format!(
        "{}{:0width$}{}",
        &s[..p],
        index,
        &rest[end + 1..]
    )))
}

fn load_tf(spec: &str) -> Result<TransferFunction> {
    let p = Path::new(spec);
    if p.extension().map(|e| e.eq_ignore_ascii_case("json")) == Some(true) || p.exists() {
        let text = std::fs::read_to_string(p)
            .with_context(|| format!("reading transfer function {spec}"))?;
        Ok(TransferFunction::from_paraview_json(&text, spec)?)
    } else {
        Ok(TransferFunction::preset(spec)?)
    }
}

fn stats_json(s: &RenderStats, file: &Path, time: Option<f64>) -> serde_json::Value {
    let stages: serde_json::Map<String, serde_json::Value> = s
        .stages
        .iter()
        .map(|(k, v)| (format!("{k}_ms"), json!(v)))
        .collect();
    json!({"file": file, "time": time, "timings": stages, "particles": s.particles, "particles_visible": s.particles_visible,
           "samples": s.samples, "depth_samples_per_ray": s.depth_samples, "near": s.near, "far": s.far,
           "image": {"width": s.width, "height": s.height}})
}

pub fn run(a: RenderArgs) -> Result<()> {
    let (width, height) = parse_size(&a.size)?;
    let background = {
        let v: Vec<f32> = a
            .background
            .split(',')
            .filter_map(|x| x.trim().parse().ok())
            .collect();
        if v.len() != 3 {
            bail!("--background '{}': expected r,g,b in 0..1", a.background);
        }
        [v[0], v[1], v[2]]
    };
    let input = Input::open(&a.input)?;
    let all = input.frames();
    let frames: Vec<usize> = match (&a.frames, &input) {
        (Some(f), _) => parse_frames(f, all.len())?,
        (None, Input::Series(_)) if a.output.to_string_lossy().contains('%') => {
            (0..all.len()).collect()
        }
        (None, Input::Series(_)) => {
            eprintln!("note: {} has {} frames; rendering the first (use --frames and an out_%04d.png pattern for more)", a.input.display(), all.len());
            vec![0]
        }
        (None, Input::File(_)) => vec![0],
    };
    if frames.len() > 1 && !a.output.to_string_lossy().contains('%') {
        bail!(
            "{} frames selected: the output needs a frame pattern such as out_%04d.png",
            frames.len()
        );
    }
    let spec = a.particles.spec()?;
    let params = RenderParams {
        width,
        height,
        kernel: a.particles.kernel()?,
        field: a.particles.field()?,
        sampling_scale: a.sampling_scale,
        ..Default::default()
    };
    let mut tf = load_tf(&a.tf)?;
    if !(a.opacity_scale.is_finite() && a.opacity_scale >= 0.0) {
        bail!(
            "--opacity-scale {}: must be finite and >= 0",
            a.opacity_scale
        );
    }
    tf.scale_opacity(a.opacity_scale);

    let progress = (frames.len() > 1).then(|| {
        let pb = ProgressBar::new(frames.len() as u64);
        pb.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} frames {msg}",
            )
            .unwrap(),
        );
        pb
    });
    let mut camera: Option<Camera> = None;
    let mut all_stats = Vec::new();
    for (n, &fi) in frames.iter().enumerate() {
        let t_read = Instant::now();
        let (time, file) = &all[fi];
        let ds = read_dataset(file)?;
        let read_ms = t_read.elapsed().as_secs_f64() * 1e3;
        let t_prep = Instant::now();
        let particles = Particles::from_dataset(&ds, &spec)?;
        if particles.skipped_nonfinite > 0 {
            eprintln!(
                "warning: {}: skipped {} particles with NaN/Inf coordinates",
                file.display(),
                particles.skipped_nonfinite
            );
        }
        if n == 0 {
            for note in &particles.notes {
                eprintln!("note: {note}");
            }
            // Camera, range and opacity unit are fixed from the first frame for a whole series.
            let mut cam = if a.camera == "auto" {
                let (lo, hi) = particles.support_bounds();
                let mut c = Camera {
                    parallel_projection: a.parallel,
                    ..Default::default()
                };
                c.reset(lo.map(f64::from), hi.map(f64::from));
                c
            } else {
                let text = std::fs::read_to_string(&a.camera)
                    .with_context(|| format!("reading camera file {}", a.camera))?;
                Camera::from_json(&text).with_context(|| format!("camera file {}", a.camera))?
            };
            cam.azimuth(a.azimuth);
            cam.elevation(a.elevation);
            cam.orthogonalize_view_up();
            if !(a.zoom.is_finite() && a.zoom > 0.0) {
                bail!("--zoom {}: must be > 0", a.zoom);
            }
            cam.zoom(a.zoom);
            if let Some(p) = &a.save_camera {
                std::fs::write(p, serde_json::to_string_pretty(&cam)?)
                    .with_context(|| format!("writing {}", p.display()))?;
            }
            camera = Some(cam);
            let (lo, hi) = match &a.range {
                Some(r) => parse_pair(r, "--range")?,
                None => {
                    let (lo, hi) = match params.field {
                        fluidcast_sph::FieldKind::Csph => {
                            let r = particles.value_range();
                            (r.0 as f64, r.1 as f64)
                        }
                        // For sums, map up to the typical field magnitude at a particle.
                        _ => {
                            let s = particles.sample_many(
                                params.kernel,
                                &particles
                                    .positions
                                    .iter()
                                    .step_by((particles.len() / 2000).max(1))
                                    .map(|p| p.map(f64::from))
                                    .collect::<Vec<_>>(),
                            );
                            let v: Vec<f64> =
                                s.iter().filter_map(|s| s.value(params.field)).collect();
                            (0.0, v.iter().copied().fold(0.0, f64::max))
                        }
                    };
                    if lo < hi {
                        (lo, hi)
                    } else {
                        (lo - 0.5, lo + 0.5)
                    }
                }
            };
            tf = tf.clone().with_range(lo, hi)?;
            tf.unit_distance = match a.opacity_unit_distance {
                Some(u) if u.is_finite() && u > 0.0 => u,
                Some(u) => bail!("--opacity-unit-distance {u}: must be finite and > 0"),
                None => {
                    let (lo, hi) = particles.support_bounds();
                    let diag = (0..3)
                        .map(|k| ((hi[k] - lo[k]) as f64).powi(2))
                        .sum::<f64>()
                        .sqrt();
                    diag / (particles.len() as f64).cbrt()
                }
            };
            if progress.is_none() {
                eprintln!(
                    "rendering {} particles at {width}x{height}, {} kernel, field {:?}, range [{lo:.6}, {hi:.6}], opacity unit distance {:.6}",
                    particles.len(),
                    params.kernel,
                    params.field,
                    tf.unit_distance
                );
            }
        }
        let prep_ms = t_prep.elapsed().as_secs_f64() * 1e3;
        let (image, mut stats) =
            render_reference(&particles, camera.as_ref().unwrap(), &tf, &params)
                .with_context(|| format!("rendering {}", file.display()))?;
        stats.stages.insert(0, ("read", read_ms));
        stats.stages.insert(1, ("particles", prep_ms));
        let out = if frames.len() > 1 || a.output.to_string_lossy().contains('%') {
            frame_path(&a.output, fi)?
        } else {
            a.output.clone()
        };
        let t_write = Instant::now();
        image
            .save(&out, background)
            .with_context(|| format!("writing {}", out.display()))?;
        stats
            .stages
            .push(("write", t_write.elapsed().as_secs_f64() * 1e3));
        all_stats.push(stats_json(&stats, file, *time));
        match &progress {
            Some(pb) => pb.inc(1),
            None => {
                // `total` already covers the renderer's own stages (bin, raycast).
                let total: f64 = stats
                    .stages
                    .iter()
                    .filter(|(k, _)| !matches!(*k, "bin" | "raycast"))
                    .map(|(_, v)| v)
                    .sum();
                eprintln!(
                    "wrote {} ({} depth samples/ray, {} samples composited) in {:.1} ms",
                    out.display(),
                    stats.depth_samples,
                    stats.samples,
                    total
                );
            }
        }
    }
    if let Some(pb) = progress {
        pb.finish_with_message("done");
    }
    if let Some(p) = &a.stats {
        let v = if all_stats.len() == 1 {
            all_stats.pop().unwrap()
        } else {
            serde_json::Value::Array(all_stats)
        };
        std::fs::write(p, serde_json::to_string_pretty(&v)?)
            .with_context(|| format!("writing {}", p.display()))?;
        eprintln!("stats: {}", p.display());
    }
    Ok(())
}
