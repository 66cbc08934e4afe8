//! `fluidcast bench`: adaptive vs full-rate vs reference over a camera orbit and/or frames.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use fluidcast_backend::{Mode, RenderPlan, RenderStats, Renderer, Scene};
use fluidcast_image::{compare, Image};
use fluidcast_io::{Arrays, Input};
use fluidcast_sph::Particles;
use serde_json::json;

use crate::options::ParticleArgs;
use crate::view::{parse_tolerance, SamplingArgs, ViewArgs};

#[derive(clap::Args)]
pub struct BenchArgs {
    /// A .vtu, .vtp, .pvtu, .pvtp, legacy .vtk file, or a .pvd series.
    pub(crate) input: PathBuf,
    #[command(flatten)]
    pub(crate) particles: ParticleArgs,
    #[command(flatten)]
    pub(crate) view: ViewArgs,
    /// Grid and optimisation options (--mode and --error-tolerance are ignored: the bench
    /// sweeps --tolerances).
    #[command(flatten)]
    pub(crate) sampling: SamplingArgs,
    /// Views on a camera orbit (azimuth steps of 360°/N about the first view).
    #[arg(long, default_value_t = 8)]
    pub(crate) views: usize,
    /// Frames of a .pvd series, START:END[:STEP] (default: the first frame).
    #[arg(long)]
    pub(crate) frames: Option<String>,
    /// With --field rbf: the RBF options (the bench times, per frame, the BVH's build and
    /// refit and the render, for each of --leaf-sizes).
    #[command(flatten)]
    pub(crate) rbf: crate::rbf::RbfArgs,
    /// --field rbf: BVH leaf sizes to compare, comma-separated (default: --leaf-size).
    #[arg(long)]
    pub(crate) leaf_sizes: Option<String>,
    /// --field rbf --shadows: the world direction toward the light, X,Y,Z.
    #[arg(long, allow_hyphen_values = true)]
    pub(crate) light: Option<String>,
    /// Error tolerances to compare, comma-separated; `off` is always included.
    #[arg(long, default_value = "0.001,0.004,0.01")]
    tolerances: String,
    /// Skip the reference renderer.
    #[arg(long)]
    no_reference: bool,
    /// Also time the object-space baseline (per-sample gathering from a world-space
    /// neighbour grid, the paper's comparison; slow: try a small --size first).
    #[arg(long)]
    object_space: bool,
    /// Also time the perspective grid renderer (Fraedrich et al. 2010; --grid-cell pixels
    /// per column).
    #[arg(long)]
    perspective_grid: bool,
    /// Particle level of detail: compare the default render of per-view cuts through the
    /// particle hierarchy at these tolerances (pixels, comma-separated, e.g. 2,4,8) with full
    /// detail: time per view, particles and the error against the full-detail image.
    #[arg(long)]
    pub(crate) lod: Option<String>,
    /// Write the results as JSON here.
    #[arg(long)]
    pub(crate) json: Option<PathBuf>,
    /// As `fluidcast render --max-work`: the most kernel evaluations a view may be estimated
    /// to take (default 5e10); `off` benchmarks heavier views (a close-up at 1920 × 1080).
    #[arg(long, allow_hyphen_values = true, value_parser = crate::render::parse_max_work)]
    pub(crate) max_work: Option<f64>,
    /// Also measure the machine's kernel-evaluation limit (a plain, vectorised f32 loop of
    /// cubic-spline evaluations on every core) and print each row's time as a multiple of the
    /// time its views' full-rate work takes at that limit.
    #[arg(long)]
    pub(crate) limit: bool,
}

/// What every bench starts from: the render parameters and transfer function the options
/// give, the input, its frames and those chosen, and the particles' spec.
pub(crate) struct Setup {
    pub base: fluidcast_backend::RenderParams,
    pub base_tf: fluidcast_view::TransferFunction,
    pub input: Input,
    pub all: Vec<(Option<f64>, PathBuf)>,
    pub frames: Vec<usize>,
    pub spec: fluidcast_sph::ParticleSpec,
}

impl Setup {
    pub fn new(a: &BenchArgs) -> Result<Setup> {
        let input = Input::open(&a.input)?;
        if let Input::Series(c) = &input {
            crate::render::note_shared_times(c);
        }
        let all = input.frames();
        let frames = match &a.frames {
            Some(f) => crate::render::parse_frames(f, all.len())?,
            None => vec![0],
        };
        Ok(Setup {
            base: a.sampling.params(&a.view, &a.particles)?,
            base_tf: a.view.base_tf()?,
            input,
            all,
            frames,
            spec: a.particles.spec()?,
        })
    }
}

/// Milliseconds since `t`.
pub(crate) fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// The particles of one frame, reading only the arrays `spec` needs.
pub(crate) fn frame_particles(
    input: &Input,
    frame: &fluidcast_io::Frame,
    spec: &fluidcast_sph::ParticleSpec,
) -> Result<Particles> {
    let ds = input.open_frame(frame, &Arrays::Named(spec.arrays()))?;
    Ok(Particles::from_source(&ds, spec)?)
}

/// View `v` of `views` on the camera orbit: `first` turned by 360°·v/views about its view-up.
pub(crate) fn orbit(
    first: &fluidcast_view::Camera,
    v: usize,
    views: usize,
) -> fluidcast_view::Camera {
    let mut cam = first.clone();
    cam.azimuth(360.0 * v as f64 / views as f64);
    cam.orthogonalize_view_up();
    cam
}

pub(crate) fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Per configuration: per-view stage timings and errors against `off`.
#[derive(Default)]
struct Runs {
    stages: Vec<Vec<(&'static str, f64)>>,
    max_err: f64,
    /// Per view: share of pixels above E_I.
    frac_above: Vec<f64>,
    views_above: usize,
    samples: u64,
    /// GPU backend: the traffic between host and device, summed over the views.
    transfers: fluidcast_backend::Transfers,
}

impl Runs {
    fn add(&mut self, s: &RenderStats) {
        self.stages.push(s.stages.clone());
        self.samples += s.samples;
        self.transfers += s.transfers;
    }

    /// The traffic per view (mean): bytes uploaded and read back, submits, waits.
    fn transfers_per_view(&self) -> [f64; 4] {
        let t = &self.transfers;
        let n = self.stages.len().max(1) as f64;
        [t.uploaded_bytes, t.readback_bytes, t.submits, t.waits].map(|v| v as f64 / n)
    }
    fn median(&self, stage: &str) -> f64 {
        let mut v: Vec<f64> = self
            .stages
            .iter()
            .filter_map(|st| st.iter().find(|x| x.0 == stage).map(|x| x.1))
            .collect();
        median(&mut v)
    }
}

/// Prints the table row of a renderer the adaptive one is measured against (its set-up
/// stage `prep`, ray casting, total, and full rate's speed-up over it) and returns its JSON.
fn baseline_row(
    label: &str,
    mode: &str,
    runs: &Runs,
    prep: &str,
    off_total: f64,
) -> Result<serde_json::Value> {
    let t = runs.median("total");
    out!(
        "{:<10} {:>8.1} {:>8} {:>9.1} {:>9.1} {:>14} {:>10} {:>10} {:>10}",
        label,
        runs.median(prep),
        "-",
        runs.median("raycast"),
        t,
        format!("{:.2} (off: {:.2}x)", off_total / t, t / off_total),
        "-",
        "-",
        "-"
    );
    let mut row = json!({"mode": mode, "raycast_ms": runs.median("raycast"), "total_ms": t});
    row[format!("{prep}_ms")] = json!(runs.median(prep));
    row[format!("off_speedup_vs_{}", mode.replace('-', "_"))] = json!(t / off_total);
    Ok(row)
}

/// What the bench measured: per renderer and tolerance, over every view of every frame.
struct Measured {
    tols: Vec<Option<f64>>,
    runs: Vec<Runs>,
    gpu_runs: Vec<Runs>,
    gpu_memory: u64,
    reference: Runs,
    object: Runs,
    perspective: Runs,
    particles: usize,
    surface_ms: Vec<f64>,
    frames: Vec<usize>,
    /// With `--limit`: each view's full-rate work (kernel evaluations, estimated).
    work: Vec<f64>,
}

/// The plan of one bench render: `base` at tolerance `tol`, in `mode`.
fn plan(
    a: &BenchArgs,
    base: &fluidcast_backend::RenderParams,
    mode: Mode,
    tol: Option<f64>,
) -> RenderPlan {
    let mut params = base.clone();
    params.adaptive.tolerance = tol;
    RenderPlan {
        params,
        mode: Some(mode),
        work_limit: crate::render::work_limit(a.max_work),
        ..Default::default()
    }
}

/// The error tolerances to compare: `off` first, then `--tolerances`.
fn tolerances(a: &BenchArgs) -> Result<Vec<Option<f64>>> {
    let mut tols: Vec<Option<f64>> = vec![None];
    for t in a.tolerances.split(',').filter(|t| !t.trim().is_empty()) {
        if let Some(e) = parse_tolerance(t.trim()).context("--tolerances")? {
            tols.push(Some(e));
        }
    }
    Ok(tols)
}

pub fn run(a: BenchArgs) -> Result<()> {
    if a.views == 0 {
        bail!("--views must be at least 1");
    }
    if a.particles.rbf() {
        if a.lod.is_some() {
            bail!("--lod: the RBF field (--field rbf) has its own cluster hierarchy; drop --lod");
        }
        return crate::bench_rbf::run(&a);
    }
    if let Some(l) = &a.lod {
        return crate::bench_lod::run(&a, &crate::bench_lod::tolerances(l)?);
    }
    // With a GPU, every adaptive render is repeated on it and reported in a second table.
    let mut sampling = a.sampling.clone();
    sampling.mode = Some(crate::view::Mode::Adaptive);
    let backend = crate::render::open_backend(&sampling, Mode::Adaptive)?;
    let gpu = backend.gpu().is_some().then_some(&backend);
    let setup = Setup::new(&a)?;
    let m = measure(&a, &setup, tolerances(&a)?, gpu)?;
    let mut rows = report_cpu(&a, &setup.base, &m)?;
    let limit = a.limit.then(|| report_limit(&m, &mut rows)).transpose()?;
    let gpu_rows = match backend.gpu() {
        Some(g) => report_gpu(&g.adapter, &m)?,
        None => Vec::new(),
    };
    if let Some(p) = &a.json {
        let base = &setup.base;
        let v = json!({"input": a.input, "particles": m.particles, "width": base.width, "height": base.height,
                       "views": a.views, "frames": m.frames, "bundle": base.grid.bundle, "depth_samples": base.grid.depth_samples,
                       "relax": base.adaptive.relax, "superpixels": base.adaptive.superpixels,
                       "surface_cells": base.adaptive.surface_cells, "surface_flags_ms_per_frame": median(&mut m.surface_ms.clone()), "rows": rows,
                       "limit": limit.map(|l| json!({"evaluations_per_s_per_core": l.per_core, "evaluations_per_s": l.all_cores, "threads": l.threads})),
                       "gpu": backend.gpu().map(|g| json!({"adapter": g.adapter, "memory_bytes": m.gpu_memory, "rows": gpu_rows}))});
        std::fs::write(p, serde_json::to_string_pretty(&v)?)
            .with_context(|| format!("writing {}", p.display()))?;
        eprintln!("wrote {}", p.display());
    }
    Ok(())
}

/// Renders every view of every frame with each renderer and tolerance, through the library's
/// one entry point (the CPU renderer, and `gpu` when there is one).
fn measure(
    a: &BenchArgs,
    s: &Setup,
    tols: Vec<Option<f64>>,
    gpu: Option<&Renderer>,
) -> Result<Measured> {
    let per_view = tols.len() * (1 + usize::from(gpu.is_some()))
        + usize::from(!a.no_reference)
        + usize::from(a.object_space)
        + usize::from(a.perspective_grid);
    let pb = crate::render::progress_bar(s.frames.len() * a.views * per_view, "renders");
    let mut m = Measured {
        runs: (0..tols.len()).map(|_| Runs::default()).collect(),
        gpu_runs: (0..tols.len()).map(|_| Runs::default()).collect(),
        tols,
        gpu_memory: 0,
        reference: Runs::default(),
        object: Runs::default(),
        perspective: Runs::default(),
        particles: 0,
        surface_ms: Vec::new(),
        frames: s.frames.clone(),
        work: Vec::new(),
    };
    let mut first = None;
    for &fi in &s.frames {
        let file = &s.all[fi].1;
        let particles = frame_particles(&s.input, &s.all[fi], &s.spec)?;
        m.particles = m.particles.max(particles.len());
        let (cam0, tf) = match &first {
            Some(v) => v,
            None => first.insert(a.view.setup(&particles, &s.base, &s.base_tf, false)?),
        };
        let mut scene = Scene::new(particles, cam0.clone(), tf.clone());
        // View-independent: once per time step, reused by every view (as the VTK mapper does).
        let t = Instant::now();
        if s.base.adaptive.surface_cells {
            scene.prepare();
        }
        m.surface_ms.push(ms(t));
        for v in 0..a.views {
            scene.camera = orbit(cam0, v, a.views);
            pb.set_message(format!("frame {fi}, view {v}"));
            measure_view(a, s, &mut scene, gpu, &mut m, &pb)
                .with_context(|| format!("rendering {}", file.display()))?;
        }
    }
    pb.finish_and_clear();
    Ok(m)
}

/// One view: the baselines asked for, then the adaptive renderer at each tolerance (on the
/// CPU, and on the GPU when there is one), with errors against `off` and against the CPU.
fn measure_view(
    a: &BenchArgs,
    s: &Setup,
    scene: &mut Scene,
    gpu: Option<&Renderer>,
    m: &mut Measured,
    pb: &indicatif::ProgressBar,
) -> Result<()> {
    let cpu = Renderer::cpu();
    if a.limit {
        let work = fluidcast_backend::work::estimate(scene.particles(), &scene.camera, &s.base)?;
        m.work.push(work);
    }
    let cell = a.sampling.grid_cell;
    let baselines = [
        (!a.no_reference, Mode::Reference),
        (a.object_space, Mode::ObjectSpace),
        (a.perspective_grid, Mode::PerspectiveGrid { cell }),
    ];
    for (_, mode) in baselines.into_iter().filter(|b| b.0) {
        let r = cpu.render(scene, &plan(a, &s.base, mode, s.base.adaptive.tolerance))?;
        match mode {
            Mode::Reference => &mut m.reference,
            Mode::ObjectSpace => &mut m.object,
            _ => &mut m.perspective,
        }
        .add(&r.stats);
        pb.inc(1);
    }
    let mut off_img: Option<Image> = None;
    for (t, tol) in m.tols.clone().iter().enumerate() {
        let p = plan(a, &s.base, Mode::Adaptive, *tol);
        let r = cpu.render(scene, &p)?;
        m.runs[t].add(&r.stats);
        if let Some(g) = gpu {
            let rg = g.render(scene, &p).context("on the GPU")?;
            let (c, _) = compare(&r.image, &rg.image, 1e-3)?;
            let gr = &mut m.gpu_runs[t];
            gr.add(&rg.stats);
            gr.max_err = gr.max_err.max(c.max_abs);
            gr.frac_above.push(c.frac_above);
            m.gpu_memory = m.gpu_memory.max(rg.stats.gpu_memory_bytes);
            pb.inc(1);
        }
        match (&off_img, tol) {
            (None, _) => off_img = Some(r.image),
            (Some(off), Some(e)) => {
                let (c, _) = compare(off, &r.image, *e)?;
                let rr = &mut m.runs[t];
                rr.max_err = rr.max_err.max(c.max_abs);
                rr.frac_above.push(c.frac_above);
                rr.views_above += usize::from(c.max_abs > *e);
            }
            _ => {}
        }
        pb.inc(1);
    }
    Ok(())
}

/// `--limit`: measures the machine's kernel-evaluation limit, prints it and, per tolerance,
/// the median total time over the time the median view's full-rate work takes at the limit
/// (also into each row's JSON as `times_limit`).
fn report_limit(m: &Measured, rows: &mut [serde_json::Value]) -> Result<crate::bench_limit::Limit> {
    let l = crate::bench_limit::measure();
    let work = median(&mut m.work.clone());
    let at_limit_ms = 1e3 * work / l.all_cores;
    out!(
        "kernel-evaluation limit: {:.2} G evaluations/s per core, {:.2} G/s on {} threads; \
         a view's full-rate work {:.3} G evaluations (median) takes {at_limit_ms:.1} ms there",
        l.per_core * 1e-9,
        l.all_cores * 1e-9,
        l.threads,
        work * 1e-9
    );
    for (runs, tol) in m.runs.iter().zip(&m.tols) {
        let ratio = runs.median("total") / at_limit_ms;
        let name = tol.map_or("off".to_string(), |e| e.to_string());
        out!("  E_I {name}: {ratio:.2}x the limit");
        let adaptive = |r: &serde_json::Value| r["mode"] == "adaptive";
        let same = |r: &serde_json::Value| r["error_tolerance"] == json!(tol);
        if let Some(row) = rows.iter_mut().find(|r| adaptive(r) && same(r)) {
            row["times_limit"] = json!(ratio);
        }
    }
    Ok(l)
}

/// Prints the CPU table (the baselines, then each tolerance) and returns its JSON rows.
fn report_cpu(
    a: &BenchArgs,
    base: &fluidcast_backend::RenderParams,
    m: &Measured,
) -> Result<Vec<serde_json::Value>> {
    let (runs, tols) = (&m.runs, &m.tols);

    let off_total = runs[0].median("total");
    let off_rc = runs[0].median("raycast");
    out!(
        "{} ({} particles), {}x{}, {} view(s) x {} frame(s), D_xy {} D_z {}, relax {}, super-pixels {}, surface cells {}; medians in ms",
        a.input.display(),
        m.particles,
        base.width,
        base.height,
        a.views,
        m.frames.len(),
        base.grid.bundle,
        base.grid.depth_samples,
        base.adaptive.relax,
        base.adaptive.superpixels,
        base.adaptive.surface_cells
    );
    let surface_median = median(&mut m.surface_ms.clone());
    if base.adaptive.surface_cells {
        out!(
            "surface flags: {surface_median:.1} ms per frame (view-independent: computed once per time step and reused by every view, as the VTK mapper does; not in the rows below)"
        );
    }
    out!(
        "{:<10} {:>8} {:>8} {:>9} {:>9} {:>14} {:>10} {:>10} {:>10}",
        "E_I",
        "grid",
        "adapt",
        "raycast",
        "total",
        "speed-up RC/tot",
        "max err",
        "% px > E",
        "views > E"
    );
    let baselines = [
        (
            !a.no_reference,
            "reference",
            "reference",
            &m.reference,
            "bin",
        ),
        (a.object_space, "object", "object-space", &m.object, "grid"),
        (
            a.perspective_grid,
            "persp-grid",
            "perspective-grid",
            &m.perspective,
            "resample",
        ),
    ];
    let mut rows = Vec::new();
    for (_, label, mode, runs, prep) in baselines.into_iter().filter(|b| b.0) {
        rows.push(baseline_row(label, mode, runs, prep, off_total)?);
    }
    for (t, tol) in tols.iter().enumerate() {
        rows.push(adaptive_row(&runs[t], *tol, (off_rc, off_total))?);
    }
    Ok(rows)
}

/// Prints the table row of the adaptive renderer at tolerance `tol` (speed-ups over full
/// rate's ray casting and total, `off`) and returns its JSON.
fn adaptive_row(
    r: &Runs,
    tol: Option<f64>,
    (off_rc, off_total): (f64, f64),
) -> Result<serde_json::Value> {
    let name = tol.map_or("off".to_string(), |e| e.to_string());
    let (rc, tot) = (r.median("raycast"), r.median("total"));
    // Every view has the same pixel count, so the mean share is the overall share.
    let share = if r.frac_above.is_empty() {
        0.0
    } else {
        100.0 * r.frac_above.iter().sum::<f64>() / r.frac_above.len() as f64
    };
    let if_tol = |text: String| if tol.is_some() { text } else { "-".into() };
    out!(
        "{:<10} {:>8.1} {:>8.1} {:>9.1} {:>9.1} {:>14} {:>10} {:>10} {:>10}",
        name,
        r.median("grid"),
        r.median("adapt"),
        rc,
        tot,
        format!("{:.2} ({:.2})", off_rc / rc, off_total / tot),
        if_tol(format!("{:.5}", r.max_err)),
        if_tol(format!("{share:.4}")),
        if_tol(format!("{}/{}", r.views_above, r.stages.len())),
    );
    Ok(
        json!({"mode": "adaptive", "error_tolerance": tol, "grid_ms": r.median("grid"), "adapt_ms": r.median("adapt"),
              "raycast_ms": rc, "total_ms": tot, "speedup_raycast": off_rc / rc, "speedup_total": off_total / tot,
              "max_error": r.max_err, "percent_pixels_above": share, "views_above": r.views_above,
              "views": r.stages.len(), "samples": r.samples}),
    )
}

/// The traffic of `r` per view, as JSON.
fn transfers_json(r: &Runs) -> serde_json::Value {
    let [up, back, submits, waits] = r.transfers_per_view();
    json!({"uploaded_bytes": up, "readback_bytes": back, "submits": submits, "waits": waits})
}

/// Prints the GPU table (adapter `adapter`) and returns its JSON rows.
fn report_gpu(adapter: &str, m: &Measured) -> Result<Vec<serde_json::Value>> {
    let (runs, gpu_runs, tols, gpu_memory) = (&m.runs, &m.gpu_runs, &m.tols, m.gpu_memory);
    let mut gpu_rows = Vec::new();
    {
        out!(
            "\nGPU (every stage) on {}; GPU memory held {:.1} MiB; medians in ms (wall clock, then GPU timestamps)",
            adapter,
            gpu_memory as f64 / (1024.0 * 1024.0)
        );
        let kernels = ["gpu_grid", "gpu_sort", "gpu_adapt", "gpu_raycast"];
        out!(
            "{:<10} {:>8} {:>8} {:>9} {:>9} {:>9} {:>9} {:>10} {:>12} {:>14} {:>14} {:>12}",
            "E_I",
            "grid",
            "adapt",
            "raycast",
            "total",
            "k:grid",
            "k:sort",
            "k:adapt",
            "k:raycast",
            "total vs CPU",
            "max |GPU-CPU|",
            "% px > 1e-3"
        );
        let cell = |v: f64| {
            if v.is_nan() {
                "n/a".to_string()
            } else {
                format!("{v:.2}")
            }
        };
        for (t, tol) in tols.iter().enumerate() {
            let (r, c) = (&gpu_runs[t], &runs[t]);
            let name = tol.map_or("off".to_string(), |e| e.to_string());
            let k: Vec<f64> = kernels.iter().map(|s| r.median(s)).collect();
            let share = 100.0 * r.frac_above.iter().sum::<f64>() / r.frac_above.len().max(1) as f64;
            let speedup = c.median("total") / r.median("total");
            out!(
                "{:<10} {:>8.1} {:>8.1} {:>9.1} {:>9.1} {:>9} {:>9} {:>10} {:>12} {:>14} {:>14.5} {:>12.4}",
                name,
                r.median("grid"),
                r.median("adapt"),
                r.median("raycast"),
                r.median("total"),
                cell(k[0]),
                cell(k[1]),
                cell(k[2]),
                cell(k[3]),
                format!("{speedup:.2}x"),
                r.max_err,
                share
            );
            let opt = |v: f64| if v.is_nan() { None } else { Some(v) };
            gpu_rows.push(json!({"error_tolerance": tol, "grid_ms": r.median("grid"), "adapt_ms": r.median("adapt"),
                                 "raycast_ms": r.median("raycast"), "readback_ms": opt(r.median("readback")),
                                 "upload_ms": opt(r.median("upload")), "total_ms": r.median("total"),
                                 "gpu_grid_ms": opt(k[0]), "gpu_sort_ms": opt(k[1]), "gpu_adapt_ms": opt(k[2]),
                                 "gpu_raycast_ms": opt(k[3]), "speedup_total_vs_cpu": speedup,
                                 "max_abs_vs_cpu": r.max_err, "percent_pixels_above_1e-3": share,
                                 "per_view": transfers_json(r)}));
        }
        for (t, tol) in tols.iter().enumerate() {
            let [up, back, submits, waits] = gpu_runs[t].transfers_per_view();
            out!(
                "{:<10} per view: {:.2} MiB uploaded, {:.2} MiB read back, {submits:.1} submits, {waits:.1} waits for the GPU",
                tol.map_or("off".to_string(), |e| e.to_string()),
                up / (1024.0 * 1024.0),
                back / (1024.0 * 1024.0)
            );
        }
    }
    Ok(gpu_rows)
}
