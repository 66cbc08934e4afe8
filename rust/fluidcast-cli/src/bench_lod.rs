//! `fluidcast bench --lod T1,T2,…`: the default (adaptive) render of per-view cuts through the
//! particle hierarchy against full detail: time per view, particles, and the image error.

use std::time::Instant;

use anyhow::{bail, Context, Result};
use fluidcast_image::{compare, Image};
use fluidcast_lod::LodHierarchy;
use fluidcast_render::{render_adaptive, RenderParams, SURFACE_THRESHOLD};
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, TransferFunction};
use serde_json::json;

use crate::bench::{frame_particles, ms, orbit, BenchArgs, Setup};

/// Parses `--lod` (comma-separated tolerances in pixels, each finite and >= 0).
pub fn tolerances(s: &str) -> Result<Vec<f64>> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--lod '{s}': expected pixel tolerances, e.g. 2,4,8"))?;
    if v.is_empty() || v.iter().any(|t| !(t.is_finite() && *t >= 0.0)) {
        bail!("--lod '{s}': each tolerance must be a finite number of pixels >= 0");
    }
    Ok(v)
}

/// One configuration's per-view measurements.
#[derive(Default)]
struct Row {
    /// Per view: cut, surface flags of the cut, render (its own total), all in ms.
    cut_ms: Vec<f64>,
    surface_ms: Vec<f64>,
    render_ms: Vec<f64>,
    particles: Vec<usize>,
    /// Worst view's errors against full detail.
    rmse: f64,
    max_abs: f64,
    frac_above: f64,
}

impl Row {
    fn total(&self, v: usize) -> f64 {
        self.cut_ms.get(v).copied().unwrap_or(0.0)
            + self.surface_ms.get(v).copied().unwrap_or(0.0)
            + self.render_ms[v]
    }
    fn median_total(&self) -> f64 {
        let mut t: Vec<f64> = (0..self.render_ms.len()).map(|v| self.total(v)).collect();
        crate::bench::median(&mut t)
    }
}

/// The default render of `p` (surface flags given, or computed here and timed).
fn render(
    p: &Particles,
    surface: Option<&[bool]>,
    cam: &Camera,
    tf: &TransferFunction,
    prm: &RenderParams,
) -> Result<(Image, f64, f64)> {
    let t = Instant::now();
    let own;
    let surface = match surface {
        Some(s) => Some(s),
        None if prm.adaptive.surface_cells => {
            own = p.surface_flags(SURFACE_THRESHOLD);
            Some(own.as_slice())
        }
        None => None,
    };
    let surface_ms = ms(t);
    let r = render_adaptive(p, surface, cam, tf, prm)?;
    let total = r
        .stats
        .stages
        .iter()
        .find(|s| s.0 == "total")
        .map_or(f64::NAN, |s| s.1);
    Ok((r.image, surface_ms, total))
}

pub fn run(a: &BenchArgs, lods: &[f64]) -> Result<()> {
    let Setup {
        base,
        base_tf,
        input,
        all,
        frames,
        spec,
    } = Setup::new(a)?;
    let pb = crate::render::progress_bar(frames.len() * a.views * (1 + lods.len()), "renders");
    let mut full = Row::default();
    let mut rows: Vec<Row> = lods.iter().map(|_| Row::default()).collect();
    let mut builds = Vec::new();
    let mut setup = None;
    for &fi in &frames {
        let file = &all[fi].1;
        let particles = frame_particles(&input, &all[fi], &spec)?;
        let (cam0, tf) = match &setup {
            Some(s) => s,
            None => setup.insert(a.view.setup(&particles, &base, &base_tf, false)?),
        };
        // View-independent, once per time step: the hierarchy, and full detail's surface flags.
        let t = Instant::now();
        let h = LodHierarchy::build(particles).context("building the particle hierarchy")?;
        builds.push((ms(t), h.levels(), h.memory_bytes()));
        let p = h.full_detail();
        let surface = base
            .adaptive
            .surface_cells
            .then(|| p.surface_flags(SURFACE_THRESHOLD));
        for v in 0..a.views {
            let cam = orbit(cam0, v, a.views);
            pb.set_message(format!("frame {fi}, view {v}"));
            let (reference, _, t_full) = render(p, surface.as_deref(), &cam, tf, &base)
                .with_context(|| format!("rendering {}", file.display()))?;
            full.render_ms.push(t_full);
            full.particles.push(p.len());
            pb.inc(1);
            let frame = cam.frame(base.width, base.height)?;
            for (row, &tol) in rows.iter_mut().zip(lods) {
                let t = Instant::now();
                let c = h.cut(&frame, tol)?;
                row.cut_ms.push(ms(t));
                // Nothing merged: full detail, whose surface flags are at hand.
                let flags = surface.as_deref().filter(|_| c.is_full_detail());
                let (img, s_ms, r_ms) = render(&c.particles, flags, &cam, tf, &base)
                    .with_context(|| format!("rendering {} at --lod {tol}", file.display()))?;
                row.surface_ms.push(s_ms);
                row.render_ms.push(r_ms);
                row.particles.push(c.particles.len());
                let (e, _) = compare(&reference, &img, 1.0 / 255.0)?;
                row.rmse = row.rmse.max(e.rmse);
                row.max_abs = row.max_abs.max(e.max_abs);
                row.frac_above = row.frac_above.max(e.frac_above);
                pb.inc(1);
            }
        }
    }
    pb.finish_and_clear();
    report(a, &base, (&full, &rows, lods), &builds)
}

/// Prints the table and writes `--json`.
fn report(
    a: &BenchArgs,
    base: &RenderParams,
    (full, rows, lods): (&Row, &[Row], &[f64]),
    builds: &[(f64, usize, usize)],
) -> Result<()> {
    let mut build_ms: Vec<f64> = builds.iter().map(|b| b.0).collect();
    let build = crate::bench::median(&mut build_ms);
    let (levels, bytes) = builds.last().map_or((0, 0), |b| (b.1, b.2));
    let full_t = full.median_total();
    out!(
        "{} ({} particles), {}x{}, {} view(s); default render (E_I {:?}); medians in ms per view",
        a.input.display(),
        full.particles.first().copied().unwrap_or(0),
        base.width,
        base.height,
        a.views,
        base.adaptive.tolerance
    );
    out!(
        "hierarchy: {levels} levels, {:.1} MiB, built in {build:.0} ms per frame (view-independent, like full detail's surface flags: not in the rows)",
        bytes as f64 / (1024.0 * 1024.0)
    );
    out!(
        "{:<10} {:>11} {:>8} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>12}",
        "LOD px",
        "particles",
        "cut",
        "surface",
        "render",
        "total",
        "speed-up",
        "RMSE",
        "max err",
        "% px > 1/255"
    );
    out!(
        "{:<10} {:>11} {:>8} {:>9} {:>9.1} {:>9.1} {:>9} {:>9} {:>9} {:>12}",
        "full",
        full.particles.first().copied().unwrap_or(0),
        "-",
        "-",
        full_t,
        full_t,
        "1.00x",
        "-",
        "-",
        "-"
    );
    let mut js = Vec::new();
    for (r, tol) in rows.iter().zip(lods) {
        let med = |v: &[f64]| crate::bench::median(&mut v.to_vec());
        let n = {
            let mut p: Vec<f64> = r.particles.iter().map(|&n| n as f64).collect();
            crate::bench::median(&mut p)
        };
        let t = r.median_total();
        out!(
            "{:<10} {:>11.0} {:>8.1} {:>9.1} {:>9.1} {:>9.1} {:>9} {:>9.5} {:>9.4} {:>12.4}",
            tol,
            n,
            med(&r.cut_ms),
            med(&r.surface_ms),
            med(&r.render_ms),
            t,
            format!("{:.2}x", full_t / t),
            r.rmse,
            r.max_abs,
            100.0 * r.frac_above
        );
        js.push(json!({"lod_px": tol, "particles": n, "cut_ms": med(&r.cut_ms), "surface_ms": med(&r.surface_ms),
                       "render_ms": med(&r.render_ms), "total_ms": t, "speedup_vs_full_detail": full_t / t,
                       "rmse_vs_full_detail": r.rmse, "max_abs_vs_full_detail": r.max_abs,
                       "percent_pixels_above_1_255": 100.0 * r.frac_above}));
    }
    out!("errors: the worst view's, against the full-detail image of the same view");
    if let Some(p) = &a.json {
        let v = json!({"input": a.input, "width": base.width, "height": base.height, "views": a.views,
                       "error_tolerance": base.adaptive.tolerance, "hierarchy_levels": levels,
                       "hierarchy_bytes": bytes, "hierarchy_build_ms": build,
                       "full_detail": {"particles": full.particles.first(), "total_ms": full_t},
                       "rows": js});
        std::fs::write(p, serde_json::to_string_pretty(&v)?)
            .with_context(|| format!("writing {}", p.display()))?;
        eprintln!("wrote {}", p.display());
    }
    Ok(())
}
