use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use fluidcast_backend::{
    defaults, device_note, Backend, BackendError, March, Marched, Mode, PlanItem, RenderPlan,
    RenderStats, Rendered, Renderer, Scene, Tiles,
};
use fluidcast_image::Image;
use fluidcast_io::{Arrays, Frame, Input};
use fluidcast_sph::{ParticleSpec, Particles};
use fluidcast_view::Camera;
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

use crate::movie;
use crate::options::ParticleArgs;
use crate::surface::{IsoSource, SurfaceArgs};
use crate::view::{RangeChoice, SamplingArgs, ViewArgs};

#[derive(clap::Args)]
pub struct RenderArgs {
    /// A .vtu, .vtp, .pvtu, .pvtp, legacy .vtk file, or a series: a .pvd, several files, a
    /// glob ('run/PartFluid_*.vtk', quoted) or a printf pattern (run/PartFluid_%04d.vtk) of
    /// numbered files, taken in natural order (_2 before _10).
    #[arg(required = true, num_args = 1..)]
    input: Vec<PathBuf>,
    /// Output image: .png (8-bit over --background, colour values written as VTK and ParaView
    /// write them; see --srgb) or .exr (float RGBA premultiplied + Z). For several frames or
    /// views, a pattern such as out_%04d.png (numbered 0, 1, 2, ... as written), or a movie:
    /// .mp4, .webm, .gif, .mkv or .mov (encoded by ffmpeg at --fps).
    #[arg(help_heading = "Output, series and movies", short, long)]
    output: PathBuf,
    #[command(flatten)]
    particles: ParticleArgs,
    #[command(flatten)]
    view: ViewArgs,
    #[command(flatten)]
    sampling: SamplingArgs,
    #[command(flatten)]
    surface: SurfaceArgs,
    /// Background colour for PNG output: r,g,b (0..1), #rrggbb, or white, black, grey,
    /// paraview.
    #[arg(
        help_heading = "Output, series and movies",
        long,
        default_value = "1,1,1"
    )]
    background: String,
    /// Encode PNG output with the sRGB transfer curve, treating colours as linear light. By
    /// default colours are written as they are, like a VTK/ParaView screenshot.
    #[arg(help_heading = "Output, series and movies", long)]
    srgb: bool,
    /// Frames of a .pvd series, START:END (end exclusive), START:END:STEP or one index.
    #[arg(help_heading = "Output, series and movies", long)]
    frames: Option<String>,
    /// Write timings and counts as JSON here (for a series: one object per frame in a list).
    #[arg(help_heading = "Output, series and movies", long)]
    stats: Option<PathBuf>,
    /// For a series: read each frame only after the previous one is written. By default the
    /// next frame is read and turned into particles on a second thread while the current one
    /// renders (two frames in memory at once).
    #[arg(help_heading = "Expert: the sampling plan", long)]
    no_prefetch: bool,
    /// With PNG output and an error tolerance, also write NAME.plan.png (per bundle: grey =
    /// cells at full rate, green = adapted in depth, yellow = super-pixels, as in the paper's
    /// Fig. 3) and NAME.error.png (predicted error bound / E_I, white = E_I or more). EXR
    /// output always carries these as channels error_bound, level and superpixel.
    #[arg(help_heading = "Expert: the sampling plan", long)]
    aovs: bool,
    #[command(flatten)]
    split: SplitArgs,
    #[command(flatten)]
    rbf: crate::rbf::RbfArgs,
    /// Particle level of detail (Fraedrich et al. 2010): merge the particles of each block of
    /// 2³ cells into one, level by level (volume, mass and the attribute's volume-weighted
    /// mean kept), and render each part of the view at the coarsest level whose cells are at
    /// most this many pixels at its depth (0: every particle). It pays where particles are
    /// about a pixel or smaller; `fluidcast bench --lod` reports its speed and error against
    /// full detail.
    #[arg(help_heading = "Large data", long, allow_hyphen_values = true, value_parser = crate::checked::real("--lod"))]
    lod: Option<f64>,
    /// The most kernel evaluations a frame may be estimated to take before it runs (each
    /// particle's footprint in pixels times the depth samples through it; default 5e10,
    /// about 10 s on 2 cores): above it the render is refused with what the view needs (a
    /// support radius far too large, a camera inside the fluid). `off`: no limit.
    #[arg(help_heading = "Large data", long, allow_hyphen_values = true, value_parser = parse_max_work)]
    max_work: Option<f64>,
    #[command(flatten)]
    movie: movie::MovieArgs,
}

/// Rendering a view in screen tiles, to bound memory.
#[derive(clap::Args, Clone, Debug, Default)]
#[command(next_help_heading = "Large data")]
pub struct SplitArgs {
    /// The most memory the process may hold while a view renders (bytes, or with a K, M, G
    /// or T suffix, powers of 1024): the view is rendered in as many screen tiles as that
    /// needs, each with only the particles that reach it, to the same image. Reading the file
    /// and the particles themselves come first and are not split: a limit below what they
    /// hold is an error that says how much they need.
    #[arg(long, value_parser = parse_memory_limit)]
    pub memory_limit: Option<u64>,
    /// Render each view in at least this many screen tiles (the same image at full rate,
    /// within the error tolerance with image-space interpolation; less memory, a little more
    /// time).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub tiles: Option<u32>,
}

/// The render plan's work limit from `--max-work`: 0, as the mapper's WorkLimit, and no
/// option mean the default.
pub(crate) fn work_limit(max_work: Option<f64>) -> Option<f64> {
    max_work.filter(|&w| w > 0.0)
}

pub(crate) fn parse_max_work(s: &str) -> Result<f64, String> {
    if s.eq_ignore_ascii_case("off") {
        return Ok(f64::INFINITY);
    }
    crate::checked::real("--max-work")(s)
}

fn parse_memory_limit(s: &str) -> Result<u64, String> {
    fluidcast_mem::parse_size(s)
        .filter(|&b| b > 0)
        .ok_or_else(|| format!("'{s}' is not a size: give bytes, or a number with K, M, G or T"))
}

impl SplitArgs {
    /// The plan's screen tiles: `--tiles`, and `--memory-limit` less what the process holds
    /// now.
    pub fn tiles(&self) -> Result<Tiles> {
        let Some(limit) = self.memory_limit else {
            return Ok(Tiles {
                count: self.tiles,
                budget_bytes: None,
            });
        };
        let Some(held) = fluidcast_mem::resident() else {
            bail!("--memory-limit needs the process' memory use, which this system does not report (/proc/self/status); use --tiles");
        };
        Ok(Tiles {
            count: self.tiles,
            budget_bytes: Some(limit.saturating_sub(held)),
        })
    }
}

/// `e` (the library's refusal of a plan, or a render's error) with the options behind it:
/// the refused part of the plan named by its flags, and what `--memory-limit` left.
fn option_error(a: &RenderArgs, e: BackendError) -> anyhow::Error {
    if let (Some(limit), Some(held), true) = (
        a.split.memory_limit,
        fluidcast_mem::resident(),
        e.is_memory_budget(),
    ) {
        return anyhow::Error::new(e).context(format!(
            "--memory-limit {}: the particles and what the process holds already take {}; \
             raise the limit",
            fluidcast_mem::Bytes(limit),
            fluidcast_mem::Bytes(held)
        ));
    }
    let flags = match e.item() {
        Some(PlanItem::Mode) => "--mode",
        Some(PlanItem::Tiles) => "--memory-limit/--tiles",
        Some(PlanItem::Lod) => "--lod",
        Some(PlanItem::Surfaces) => "--iso/--shade-volume",
        Some(PlanItem::Work) => "--max-work",
        None => return e.into(),
    };
    anyhow::Error::new(e).context(flags)
}

/// Opens the backend for the adaptive renderer (the reference renderer runs on the CPU), and
/// says where frames render.
pub fn open_backend(s: &SamplingArgs, mode: Mode) -> Result<Renderer> {
    let r = match (s.backend, mode) {
        (Backend::Gpu, Mode::Reference | Mode::PerspectiveGrid { .. } | Mode::ObjectSpace) => {
            bail!("--backend gpu renders the adaptive mode only (drop --mode)")
        }
        (_, Mode::Reference | Mode::PerspectiveGrid { .. } | Mode::ObjectSpace) => Renderer::cpu(),
        (b, Mode::Adaptive) => without_wayland_noise(|| Renderer::open(b, s.adapter.as_deref()))
            .with_context(|| format!("--backend {b}"))?,
    };
    if let Some(n) = r.note() {
        eprintln!("note: {n}");
    }
    if r.gpu().is_some() {
        eprintln!("{}", r.device());
    }
    Ok(r)
}

/// What Mesa's Vulkan drivers print on a machine without a desktop session when an instance
/// is made (libwayland looking for a display nobody asked for): not ours, and alarming.
const WAYLAND_NOISE: &str = "XDG_RUNTIME_DIR is invalid or not set in the environment.";

/// Runs `f` (which opens GPU adapters) with stderr captured, and passes on everything it
/// printed except libwayland's complaint about a missing display.
pub fn without_wayland_noise<T>(f: impl FnOnce() -> T) -> T {
    #[cfg(unix)]
    if let Ok(mut redirect) = gag::BufferRedirect::stderr() {
        let out = f();
        let mut text = String::new();
        let _ = std::io::Read::read_to_string(&mut redirect, &mut text);
        drop(redirect);
        for line in text.lines().filter(|l| !l.contains(WAYLAND_NOISE)) {
            eprintln!("{line}");
        }
        return out;
    }
    f()
}

fn write_aov_pngs(image: &Image, out: &Path, tolerance: Option<f64>) -> Result<()> {
    if out.extension().map(|e| e.eq_ignore_ascii_case("exr")) == Some(true) {
        return Ok(());
    }
    let (Some(e), false) = (tolerance, image.aovs.is_empty()) else {
        eprintln!("note: --aovs: no error tolerance, so no plan to show");
        return Ok(());
    };
    let get = |name: &str| image.aovs.iter().find(|a| a.0 == name).map(|a| &a.1);
    let (Some(err), Some(level), Some(sp)) = (get("error_bound"), get("level"), get("superpixel"))
    else {
        return Ok(());
    };
    let stem = out.with_extension("");
    let mut plan = Image::new(image.width, image.height);
    let mut errimg = Image::new(image.width, image.height);
    for i in 0..plan.rgba.len() {
        // Cells not adapted or super-pixels are at full rate; colour by share, shade by level.
        let s = sp[i];
        let adapted = (level[i] / 4.0).min(1.0) * (1.0 - s);
        let full = (1.0 - s - adapted).max(0.0);
        let c = [
            0.5 * full + 0.1 * adapted + 1.0 * s,
            0.5 * full + 0.8 * adapted + 0.85 * s,
            0.5 * full + 0.1 * adapted,
        ];
        let covered = image.rgba[i][3] > 0.0;
        plan.rgba[i] = if covered {
            [c[0], c[1], c[2], 1.0]
        } else {
            [0.0; 4]
        };
        let v = (err[i] as f64 / e.max(1e-12)).min(1.0) as f32;
        errimg.rgba[i] = [v, v, v, 1.0];
    }
    for (img, suffix) in [(plan, "plan"), (errimg, "error")] {
        let p = PathBuf::from(format!("{}.{suffix}.png", stem.display()));
        img.write_png(&p, [1.0; 3], fluidcast_image::PngEncoding::Vtk)
            .with_context(|| format!("writing {}", p.display()))?;
        eprintln!("wrote {}", p.display());
    }
    Ok(())
}

pub fn parse_frames(s: &str, n: usize) -> Result<Vec<usize>> {
    if s.trim().is_empty() {
        bail!("--frames '': give one frame index or START:END[:STEP] (e.g. 3, 0:10, 0:10:2)");
    }
    let parts: Vec<&str> = s.split(':').collect();
    let num = |t: &str, d: usize| -> Result<usize> {
        let t = t.trim();
        if t.is_empty() {
            return Ok(d);
        }
        t.parse().ok().with_context(|| {
            format!("--frames '{s}': '{t}' is not a frame index (whole numbers from 0)")
        })
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

/// The widest `%0Nd` frame field accepted (a frame index has at most 20 digits).
const MAX_PATTERN_WIDTH: usize = 32;

/// Expands a printf-style `%d` / `%0Nd` in the output path with the frame index.
fn frame_path(pattern: &Path, index: usize) -> Result<PathBuf> {
    let s = pattern.to_string_lossy();
    let Some(p) = s.find('%') else {
        bail!("output '{s}' needs a %04d-style frame pattern for several frames")
    };
    if s.matches('%').count() > 1 {
        bail!("output '{s}': one frame pattern (%d or %04d) only, and no other '%'");
    }
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
    if width > MAX_PATTERN_WIDTH {
        bail!("output pattern '{s}': a field width of {width} digits; at most {MAX_PATTERN_WIDTH}");
    }
    Ok(PathBuf::from(format!(
        "{}{:0width$}{}",
        &s[..p],
        index,
        &rest[end + 1..]
    )))
}

pub fn stats_json(s: &RenderStats, file: &Path, time: Option<f64>) -> serde_json::Value {
    let stages: serde_json::Map<String, serde_json::Value> = s
        .stages
        .iter()
        .map(|(k, v)| (format!("{k}_ms"), json!(v)))
        .collect();
    let mut v = json!({"file": file, "time": time, "timings": stages, "particles": s.particles, "particles_visible": s.particles_visible,
           "samples": s.samples, "tiles": s.tiles, "culled": s.culled, "interpolated": s.interpolated, "dispatches": s.dispatches, "depth_samples_per_ray": s.depth_samples, "near": s.near, "far": s.far,
           "image": {"width": s.width, "height": s.height}});
    // The GPU's traffic: bytes each way, command buffers, and waits for the device.
    let t = &s.transfers;
    if t.submits > 0 {
        v["transfers"] = json!({"uploaded_bytes": t.uploaded_bytes, "readback_bytes": t.readback_bytes,
            "submits": t.submits, "waits": t.waits});
    }
    // The process' peak resident memory so far (all frames up to this one).
    if let Some(b) = fluidcast_mem::peak_resident() {
        v["peak_memory_bytes"] = json!(b);
    }
    if let Some(p) = &s.plan {
        v["grid"] = json!({"bundles": s.bundles, "cells": s.cells, "particle_cell_pairs": s.pairs});
        if s.gpu_memory_bytes > 0 {
            v["gpu_memory_bytes"] = json!(s.gpu_memory_bytes);
        }
        v["cells"] = json!({
            "full_rate": p.level_cells[0],
            "z_adapted_per_level": &p.level_cells[1..],
            "superpixel": p.superpixel_cells,
            "surface": p.surface_cells,
            "merged": p.merged_cells,
        });
        v["particle_refs_sampled"] = json!(p.refs_sampled);
        v["bundles_not_analysed"] = json!(p.unanalysed_bundles);
    }
    v
}

/// `--background r,g,b`: three finite numbers in 0..1.
fn parse_background(s: &str) -> Result<[f32; 3]> {
    let bad = || {
        anyhow::anyhow!(
            "--background '{s}': expected r,g,b (three numbers in 0..1), #rrggbb, or white, \
             black, grey, paraview (ParaView's blue-grey)"
        )
    };
    let named = match s.trim().to_ascii_lowercase().as_str() {
        "white" => Some([1.0, 1.0, 1.0]),
        "black" => Some([0.0, 0.0, 0.0]),
        "grey" | "gray" => Some([0.5, 0.5, 0.5]),
        "paraview" => Some([0.32, 0.34, 0.43]),
        _ => None,
    };
    if let Some(c) = named {
        return Ok(c);
    }
    if let Some(hex) = s.trim().strip_prefix('#') {
        let byte = |k: usize| {
            hex.get(2 * k..2 * k + 2)
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .map(|b| f32::from(b) / 255.0)
        };
        return match (hex.len(), byte(0), byte(1), byte(2)) {
            (6, Some(r), Some(g), Some(b)) => Ok([r, g, b]),
            _ => Err(bad()),
        };
    }
    let v = s
        .split(',')
        .map(|x| x.trim().parse::<f32>().map_err(|_| bad()))
        .collect::<Result<Vec<f32>>>()?;
    match v[..] {
        [r, g, b] if v.iter().all(|c| (0.0..=1.0).contains(c)) => Ok([r, g, b]),
        _ => Err(bad()),
    }
}

/// Prints the particles' notes; warnings keep their own prefix.
pub fn print_notes(notes: &[String]) {
    for note in notes {
        if note.starts_with("warning:") {
            eprintln!("{note}");
        } else {
            eprintln!("note: {note}");
        }
    }
}

/// One frame read and turned into particles, and how long each took (milliseconds).
struct Loaded {
    index: usize,
    particles: Particles,
    /// The iso-surface field's array when it is another than the rendered one.
    iso_values: Option<Arc<[f32]>>,
    read_ms: f64,
    prep_ms: f64,
}

/// What turns a data set into what a frame renders: the particles' spec and the iso-surface
/// options (for a second array).
struct Recipe<'a> {
    spec: &'a ParticleSpec,
    surface: &'a SurfaceArgs,
    array: Option<&'a str>,
}

impl Recipe<'_> {
    /// The point arrays a frame needs: the particles' and the iso-surface field's.
    fn arrays(&self) -> Arrays {
        let mut names = self.spec.arrays();
        if let Ok(IsoSource::Other(q)) = self.surface.source(self.array) {
            names.push(q.array);
        }
        Arrays::Named(names)
    }
}

fn load(input: &Input, frame: &Frame, recipe: &Recipe, index: usize) -> Result<Loaded> {
    let file = &frame.1;
    let t_read = Instant::now();
    let ds = input.open_frame(frame, &recipe.arrays())?;
    let read_ms = t_read.elapsed().as_secs_f64() * 1e3;
    let t_prep = Instant::now();
    let particles = Particles::from_source(&ds, recipe.spec)?;
    let iso_values = recipe
        .surface
        .other_values(recipe.array, &ds)
        .with_context(|| format!("--iso-field {}", recipe.surface.iso_field))?;
    if particles.skipped_nonfinite > 0 {
        eprintln!(
            "warning: {}: skipped {} particles with NaN/Inf coordinates",
            file.display(),
            particles.skipped_nonfinite
        );
    }
    Ok(Loaded {
        index,
        particles,
        iso_values,
        read_ms,
        prep_ms: t_prep.elapsed().as_secs_f64() * 1e3,
    })
}

/// Hands the `frames` of `all` to `render` in order. With `prefetch` a second thread loads
/// the next frame while `render` works on the current one (a rendezvous channel: at most two
/// frames in memory); the first error, of either, ends the loop and is returned.
fn for_each_frame(
    input: &Input,
    all: &[Frame],
    frames: &[usize],
    recipe: &Recipe,
    prefetch: bool,
    mut render: impl FnMut(Loaded) -> Result<()>,
) -> Result<()> {
    if !prefetch || frames.len() < 2 {
        for &fi in frames {
            render(load(input, &all[fi], recipe, fi)?)?;
        }
        return Ok(());
    }
    std::thread::scope(|scope| {
        let (tx, rx) = std::sync::mpsc::sync_channel::<Result<Loaded>>(0);
        scope.spawn(move || {
            for &fi in frames {
                let loaded = load(input, &all[fi], recipe, fi);
                let failed = loaded.is_err();
                // A closed channel: the renderer stopped (an error); stop reading.
                if tx.send(loaded).is_err() || failed {
                    break;
                }
            }
        });
        for loaded in rx {
            render(loaded?)?;
        }
        Ok(())
    })
}

/// One line per written frame when there is no progress bar; `total` is the frame's wall
/// time in milliseconds (reading, particles, render and writing).
fn report_frame(out: &Path, stats: &RenderStats, total: f64) {
    let peak = fluidcast_mem::peak_resident()
        .map(|b| format!(", peak memory {}", fluidcast_mem::Bytes(b)))
        .unwrap_or_default();
    let tiles = if stats.tiles > 0 {
        format!(", in {} screen tiles", stats.tiles)
    } else {
        String::new()
    };
    eprintln!(
        "wrote {} ({} depth samples/ray, {} samples composited) in {:.1} ms{tiles}{peak}",
        out.display(),
        stats.depth_samples,
        stats.samples,
        total
    );
}

/// The frames to render: `--frames`, else all of a series when the output is a pattern, else
/// the first; several frames need an output pattern.
fn select_frames(a: &RenderArgs, input: &Input, n: usize) -> Result<Vec<usize>> {
    let frames: Vec<usize> = match (&a.frames, input) {
        (Some(f), _) => parse_frames(f, n)?,
        (None, Input::Series(_)) if a.output.to_string_lossy().contains('%') => (0..n).collect(),
        (None, Input::Series(_)) => {
            eprintln!("note: the series has {n} frames; rendering the first (use --frames and an out_%04d.png pattern for more)");
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
    Ok(frames)
}

/// Says (once per command) that a `.pvd` lists several data sets for some times, which
/// are rendered together as one frame ([`Input::frames`]).
pub(crate) fn note_shared_times(c: &fluidcast_io::Collection) {
    let shared = c.shared_times();
    if let Some(&(t, n)) = shared.first() {
        eprintln!(
            "note: {} lists {n} data sets at t = {t} ({} such times): the data sets of one time \
             are one frame, their particles appended (the point arrays every one has), as \
             ParaView shows them together",
            c.path.display(),
            shared.len()
        );
    }
}

/// A progress bar over `len` things counted as `unit` ("frames", "renders").
pub(crate) fn progress_bar(len: usize, unit: &str) -> ProgressBar {
    let pb = ProgressBar::new(len as u64);
    let template =
        format!("{{spinner}} [{{elapsed_precise}}] {{bar:40}} {{pos}}/{{len}} {unit} {{msg}}");
    pb.set_style(
        ProgressStyle::with_template(&template).unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    pb
}

/// `--field rbf`, or an SPH field with `--shadows`: what the stochastic ray marcher draws.
/// What the march does not draw with it (a mode, tiles, surfaces, level of detail) is the
/// library's to refuse ([`RenderPlan::check`], in [`base_plan`]).
fn rbf_setup(a: &RenderArgs) -> Result<Option<Marched>> {
    if !a.particles.rbf() && !a.rbf.shadows {
        return Ok(None);
    }
    // The march's own errors (bad --light, --rbf-step), before reading.
    a.rbf
        .render_params(&Camera::default(), a.surface.light.as_deref())?;
    if !a.particles.rbf() {
        if a.sampling.backend == Backend::Gpu {
            bail!("--shadows on an SPH field renders on the CPU (the GPU draws the lit RBF field only): drop --backend gpu");
        }
        return Ok(Some(Marched::Sph));
    }
    Ok(Some(Marched::Rbf(
        a.rbf.options(a.particles.array.is_some())?,
    )))
}

/// The plan every frame starts from, and the backend it needs; says what the library
/// chose for the options.
fn base_plan(a: &RenderArgs) -> Result<(RenderPlan, Renderer)> {
    let mut params = a.sampling.params(&a.view, &a.particles)?;
    let array = a.particles.array.as_deref();
    params.surfaces = a.surface.surfaces(array, None)?; // the options' own errors, before reading
    params.volume_lighting = a.surface.volume_lighting()?;
    if a.surface.shade_volume && a.sampling.backend == Backend::Gpu {
        bail!("--shade-volume: the GPU backend does not draw a shaded volume yet; drop --backend gpu (it renders on the CPU)");
    }
    let march = rbf_setup(a)?.map(|field| March {
        field,
        params: Default::default(),
        progressive_passes: 0,
        time_refit: a.stats.is_some(),
    });
    let plan = RenderPlan {
        params,
        mode: a.sampling.plan_mode(),
        tiles: Tiles::default(),
        lod: a.lod,
        march,
        work_limit: work_limit(a.max_work),
    };
    // The library's refusals of option combinations, before reading (the tiles the options
    // ask for stand in for the budget each frame computes).
    let asked = Tiles {
        count: a.split.tiles,
        budget_bytes: a.split.memory_limit,
    };
    let early = RenderPlan {
        tiles: asked,
        ..plan.clone()
    };
    early.check().map_err(|e| option_error(a, e))?;
    let (mode, note) = plan.mode_for(a.sampling.backend);
    // The marched field on the CPU, or on the GPU with --backend gpu (auto: a hardware GPU).
    let open_mode = if plan.march.is_some() {
        Mode::Adaptive
    } else {
        mode
    };
    let renderer = open_backend(&a.sampling, open_mode)?;
    let note = device_note(note, renderer.gpu().is_some());
    if let (Some(n), None) = (note, &plan.march) {
        let what = if a.surface.on() {
            "--iso"
        } else {
            "--shade-volume"
        };
        let how = if mode == Mode::Reference {
            " (--mode reference)"
        } else {
            ""
        };
        eprintln!("note: {what}: {n}{how}");
    }
    Ok((plan, renderer))
}

/// Renders `scene` with `plan`; a frame still rendering after a second shows a progress bar
/// on a terminal (the share of bundles or tiles cast; not for a series, which has its own).
fn render_watched(
    renderer: &Renderer,
    scene: &mut Scene,
    mut plan: RenderPlan,
    quiet: bool,
) -> Result<Rendered, BackendError> {
    let progress = Arc::new(fluidcast_backend::Progress::default());
    plan.params.progress = Some(progress.clone());
    let finished = std::sync::atomic::AtomicBool::new(false);
    std::thread::scope(|s| {
        let watcher = (!quiet).then(|| s.spawn(|| show_progress(&progress, &finished)));
        // A panic in the renderer stops the bar too, then goes on: the scope would otherwise
        // wait for the bar's thread for ever (a wgpu validation panic hung the process).
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            renderer.render(scene, &plan)
        }));
        finished.store(true, std::sync::atomic::Ordering::Relaxed);
        // Wake it now: the frame is not to wait for the bar's next tick.
        if let Some(w) = &watcher {
            w.thread().unpark();
        }
        r.unwrap_or_else(|p| std::panic::resume_unwind(p))
    })
}

/// A bar of `progress` from a second after the start until `finished`.
fn show_progress(progress: &fluidcast_backend::Progress, finished: &std::sync::atomic::AtomicBool) {
    use std::sync::atomic::Ordering;
    let start = std::time::Instant::now();
    let mut bar: Option<ProgressBar> = None;
    while !finished.load(Ordering::Relaxed) {
        std::thread::park_timeout(std::time::Duration::from_millis(100));
        if finished.load(Ordering::Relaxed) {
            break;
        }
        if start.elapsed().as_secs_f64() < 1.0 {
            continue;
        }
        let b = bar.get_or_insert_with(|| {
            let b = ProgressBar::new(1000);
            b.set_style(
                ProgressStyle::with_template("rendering {bar:30} {percent:>3}% {elapsed}")
                    .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            b
        });
        b.set_position((progress.fraction() * 1000.0) as u64);
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
}

/// The colour range over the frames `frames` of a series (`--range all`): each frame read
/// (only the arrays its particles need) and its values' range found as a single file's would
/// be, the ranges united, and a point widened only if the union is one.
fn series_range(
    input: &Input,
    all: &[Frame],
    frames: &[usize],
    recipe: &Recipe,
    params: &fluidcast_backend::RenderParams,
) -> Result<(f64, f64)> {
    let bar = progress_bar(
        frames.len(),
        "frames read for the colour range (--range all)",
    );
    let mut range = (f64::INFINITY, f64::NEG_INFINITY);
    for &fi in frames {
        let l = load(input, &all[fi], recipe, fi).context(
            "reading every frame for the colour range (--range all; --range first renders \
             the frames before this one)",
        )?;
        let (lo, hi) = defaults::data_range(&l.particles, params.kernel, params.field);
        range = (range.0.min(lo), range.1.max(hi));
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok(defaults::widened(range))
}

/// Whether the plan colours an RBF field by its density (its range comes from a render).
fn colours_by_density(plan: &RenderPlan) -> bool {
    plan.march.as_ref().is_some_and(|m| {
        matches!(&m.field, Marched::Rbf(o) if o.colouring == fluidcast_backend::Colouring::Density)
    })
}

/// What stays from frame to frame of one `fluidcast render`.
struct Job<'a> {
    a: &'a RenderArgs,
    all: &'a [Frame],
    plan: RenderPlan,
    renderer: Renderer,
    /// Camera and transfer function, fixed from the first frame for a whole series.
    view: Option<(Camera, fluidcast_view::TransferFunction)>,
    progress: Option<ProgressBar>,
    stats: Vec<serde_json::Value>,
    several: bool,
    /// `--background`, parsed once.
    background: [f32; 3],
    /// One frame is rendered (`--orbit N` then makes N views of it).
    single_frame: bool,
    /// `--camera-path`, read.
    path: Option<fluidcast_view::CameraPath>,
    /// Whether a frame outside the first frame's range was reported (`--range first`).
    warned_range: bool,
    /// When the frame being rendered was handed over (read and particles before it).
    frame_started: Option<Instant>,
}

impl Job<'_> {
    /// The scene of one loaded frame; the first sets the camera and transfer function.
    fn scene(&mut self, particles: Particles) -> Result<Scene> {
        let (camera, tf) = match self.view.take() {
            Some((camera, tf)) => (camera, self.frame_range(&particles, tf)?),
            None => {
                print_notes(&particles.notes);
                let base = self.a.view.base_tf()?;
                let quiet = self.progress.is_none();
                self.a
                    .view
                    .setup(&particles, &self.plan.params, &base, quiet)?
            }
        };
        Ok(Scene::new(particles, camera, tf))
    }

    /// The colour map of a frame after the first: its own range with `--range frame`; the
    /// series' otherwise, with a warning (once) where `--range first` saturates this frame.
    fn frame_range(
        &mut self,
        particles: &Particles,
        tf: fluidcast_view::TransferFunction,
    ) -> Result<fluidcast_view::TransferFunction> {
        let p = &self.plan.params;
        let choice = self.a.view.range_choice()?;
        if choice == RangeChoice::Frame {
            let (lo, hi) = defaults::auto_range(particles, p.kernel, p.field);
            return Ok(tf.with_range(lo, hi)?);
        }
        // Only --range first warns (once), so only then is the frame's own range needed.
        if choice != RangeChoice::First || self.warned_range {
            return Ok(tf);
        }
        let (lo, hi) = defaults::data_range(particles, p.kernel, p.field);
        let (a, b) = tf.range;
        let slack = 0.01 * (b - a);
        if lo < a - slack || hi > b + slack {
            eprintln!(
                "warning: a frame's values [{lo:.6}, {hi:.6}] lie outside the colour range \
                 [{a:.6}, {b:.6}] of the first frame (--range first): they saturate; \
                 --range all (the default) covers every frame"
            );
            self.warned_range = true;
        }
        Ok(tf)
    }

    /// The plan of one frame: its iso-surface values, and the march's passes and light
    /// from the camera.
    fn frame_plan(&self, scene: &Scene, iso: Option<Arc<[f32]>>) -> Result<RenderPlan> {
        let a = self.a;
        let mut plan = self.plan.clone();
        plan.params.surfaces = a.surface.surfaces(a.particles.array.as_deref(), iso)?;
        if let Some(m) = &mut plan.march {
            m.params = a
                .rbf
                .render_params(&scene.camera, a.surface.light.as_deref())?;
            m.progressive_passes = m.params.spp;
        }
        if plan.march.is_none() {
            plan.tiles = a.split.tiles()?;
        }
        Ok(plan)
    }

    /// Renders one loaded frame and writes it.
    fn frame(&mut self, loaded: Loaded) -> Result<()> {
        self.frame_started = Some(Instant::now());
        let a = self.a;
        let first = self.view.is_none();
        let (time, file) = &self.all[loaded.index];
        let mut scene = self.scene(loaded.particles)?;
        let plan = self.frame_plan(&scene, loaded.iso_values)?;
        if first && colours_by_density(&plan) && !a.view.has_range() {
            let (lo, hi) = self
                .renderer
                .rbf_density_range(&mut scene, &plan)
                .with_context(|| format!("rendering {}", file.display()))?;
            scene.tf = scene.tf.clone().with_range(lo, hi)?;
        }
        let quiet_bar = self.progress.is_some(); // a series shows its own bar
        let base = scene.camera.clone();
        let at = (self.stats.len(), *time);
        for camera in a
            .movie
            .views(self.path.as_ref(), &base, self.single_frame, at)
        {
            scene.camera = camera;
            let r = render_watched(&self.renderer, &mut scene, plan.clone(), quiet_bar)
                .map_err(|e| option_error(a, e))
                .with_context(|| format!("rendering {}", file.display()))?;
            if let (Some(l), None) = (&r.lod, &self.progress) {
                eprintln!("{}", l.line());
            }
            self.write(r, (loaded.read_ms, loaded.prep_ms), (*time, file))?;
        }
        self.view = Some((base, scene.tf));
        Ok(())
    }

    /// Writes a frame's image (and AOVs), the next in the output's numbering, and keeps its
    /// statistics.
    fn write(
        &mut self,
        r: Rendered,
        (read_ms, prep_ms): (f64, f64),
        (time, file): (Option<f64>, &PathBuf),
    ) -> Result<()> {
        let a = self.a;
        let Rendered {
            image, mut stats, ..
        } = r;
        stats.stages.insert(0, ("read", read_ms));
        stats.stages.insert(1, ("particles", prep_ms));
        // Numbered in the order written (0, 1, 2, ...) whatever --frames skips, so that
        // ffmpeg's %04d input reads every frame; --stats names each frame's file and time.
        let out = if self.several || a.output.to_string_lossy().contains('%') {
            frame_path(&a.output, self.stats.len())?
        } else {
            a.output.clone()
        };
        let t_write = Instant::now();
        let encoding = if a.srgb {
            fluidcast_image::PngEncoding::Srgb
        } else {
            fluidcast_image::PngEncoding::Vtk
        };
        image
            .save(&out, self.background, encoding)
            .with_context(|| format!("writing {}", out.display()))?;
        if a.aovs {
            write_aov_pngs(&image, &out, self.plan.params.adaptive.tolerance)?;
        }
        stats
            .stages
            .push(("write", t_write.elapsed().as_secs_f64() * 1e3));
        let mut js = stats_json(&stats, file, time);
        if let Some(b) = r.march_bytes {
            js["rbf_memory_bytes"] = json!(b);
        }
        if let Some(l) = &r.lod {
            js["lod"] = crate::lod::json(l);
        }
        self.stats.push(js);
        match &self.progress {
            Some(pb) => pb.inc(1),
            None => {
                let render = self
                    .frame_started
                    .map_or(0.0, |t| t.elapsed().as_secs_f64() * 1e3);
                report_frame(&out, &stats, read_ms + prep_ms + render);
            }
        }
        Ok(())
    }

    /// The series' summary line and the `--stats` file.
    fn finish(mut self, frames: usize, seconds: f64) -> Result<()> {
        if frames > 1 {
            eprintln!(
                "{frames} frames in {seconds:.2} s: {:.2} frames/s ({})",
                frames as f64 / seconds,
                if self.a.no_prefetch {
                    "frames read in turn, --no-prefetch"
                } else {
                    "each frame read while the one before rendered"
                }
            );
        }
        if let Some(pb) = &self.progress {
            pb.finish_with_message("done");
        }
        if let Some(p) = &self.a.stats {
            let v = if self.stats.len() == 1 {
                self.stats.pop().unwrap_or_default()
            } else {
                serde_json::Value::Array(self.stats)
            };
            std::fs::write(p, serde_json::to_string_pretty(&v)?)
                .with_context(|| format!("writing {}", p.display()))?;
            eprintln!("stats: {}", p.display());
        }
        Ok(())
    }
}

pub fn run(mut a: RenderArgs) -> Result<()> {
    let background = parse_background(&a.background)?;
    let movie = movie::Movie::for_output(&a.output)?;
    if let Some(m) = &movie {
        a.output = m.pattern();
    }
    let path = a.movie.path()?;
    let views = a.movie.orbit.is_some_and(|n| n > 1) || path.is_some();
    if views && !a.output.to_string_lossy().contains('%') {
        bail!(
            "--orbit and --camera-path write several views: the output needs a pattern such \
             as o_%02d.png, or a movie (-o orbit.mp4)"
        );
    }
    let input = Input::open_all(&a.input)?;
    if let Input::Series(c) = &input {
        note_shared_times(c);
    }
    let all = input.frames();
    let frames = select_frames(&a, &input, all.len())?;
    let spec = a.particles.spec()?;
    let (plan, renderer) = base_plan(&a)?;
    let scan = frames.len() > 1 && a.view.range_choice()? == RangeChoice::All;
    if scan && !colours_by_density(&plan) {
        let recipe = Recipe {
            spec: &spec,
            surface: &a.surface,
            array: a.particles.array.as_deref(),
        };
        let range = series_range(&input, &all, &frames, &recipe, &plan.params)?;
        eprintln!(
            "note: colour range [{:?}, {:?}] over the {} frames (--range all; first or frame \
             choose otherwise)",
            range.0,
            range.1,
            frames.len()
        );
        a.view.fix_range(range);
    }
    let recipe = Recipe {
        spec: &spec,
        surface: &a.surface,
        array: a.particles.array.as_deref(),
    };
    let mut job = Job {
        a: &a,
        all: &all,
        plan,
        renderer,
        view: None,
        progress: (frames.len() > 1).then(|| progress_bar(frames.len(), "frames")),
        stats: Vec::new(),
        several: frames.len() > 1 || views,
        single_frame: frames.len() == 1,
        path,
        background,
        warned_range: false,
        frame_started: None,
    };
    let started = Instant::now();
    for_each_frame(&input, &all, &frames, &recipe, !a.no_prefetch, |f| {
        job.frame(f)
    })?;
    let written = job.stats.len();
    job.finish(frames.len(), started.elapsed().as_secs_f64())?;
    match movie {
        Some(m) => m.encode(a.movie.fps, written),
        None => Ok(()),
    }
}
