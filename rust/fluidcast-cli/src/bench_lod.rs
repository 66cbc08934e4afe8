//! `fluidcast bench --lod T1,T2,…`: the default (adaptive) render of per-view cuts through the
//! particle hierarchy against full detail: time per view, particles, and the image error.

use anyhow::{bail, Context, Result};
use fluidcast_backend::{Mode, RenderParams, RenderPlan, Rendered, Renderer, Scene};
use fluidcast_image::compare;
use serde_json::json;

use crate::bench::{frame_particles, orbit, BenchArgs, Setup};

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

/// The stage `name` of a render's statistics, milliseconds (0 when absent).
fn stage(r: &Rendered, name: &str) -> f64 {
    r.stats
        .stages
        .iter()
        .find(|s| s.0 == name)
        .map_or(0.0, |s| s.1)
}

pub fn run(a: &BenchArgs, lods: &[f64]) -> Result<()> {
    let s = Setup::new(a)?;
    let pb = crate::render::progress_bar(s.frames.len() * a.views * (1 + lods.len()), "renders");
    let mut full = Row::default();
    let mut rows: Vec<Row> = lods.iter().map(|_| Row::default()).collect();
    let mut builds = Vec::new();
    let mut first = None;
    let cpu = Renderer::cpu();
    let plan = |lod| RenderPlan {
        params: s.base.clone(),
        mode: Some(Mode::Adaptive),
        lod,
        ..Default::default()
    };
    for &fi in &s.frames {
        let file = &s.all[fi].1;
        let particles = frame_particles(&s.input, &s.all[fi], &s.spec)?;
        let (cam0, tf) = match &first {
            Some(v) => v,
            None => first.insert(a.view.setup(&particles, &s.base, &s.base_tf, false)?),
        };
        // View-independent, once per time step: full detail's surface flags, and the
        // hierarchy (built by the first cut, its time reported apart).
        let mut scene = Scene::new(particles, cam0.clone(), tf.clone());
        scene.prepare();
        let mut built = false;
        for v in 0..a.views {
            scene.camera = orbit(cam0, v, a.views);
            pb.set_message(format!("frame {fi}, view {v}"));
            let reference = cpu
                .render(&mut scene, &plan(None))
                .with_context(|| format!("rendering {}", file.display()))?;
            full.render_ms.push(stage(&reference, "total"));
            full.particles.push(scene.particles().len());
            pb.inc(1);
            for (row, &tol) in rows.iter_mut().zip(lods) {
                let r = cpu
                    .render(&mut scene, &plan(Some(tol)))
                    .with_context(|| format!("rendering {} at --lod {tol}", file.display()))?;
                let Some(l) = &r.lod else {
                    bail!("--lod {tol}: the render made no cut");
                };
                // This render's scene stage: the hierarchy (the first cut of a frame builds
                // it), the cut, and the cut's surface flags (none when it merged nothing).
                let build_ms = if built { 0.0 } else { l.build_ms };
                if !built {
                    builds.push((l.build_ms, l.levels, l.hierarchy_bytes));
                    built = true;
                }
                row.cut_ms.push(l.cut_ms);
                row.surface_ms
                    .push((stage(&r, "scene") - l.cut_ms - build_ms).max(0.0));
                row.render_ms.push(stage(&r, "total"));
                row.particles.push(l.rendered);
                let (e, _) = compare(&reference.image, &r.image, 1.0 / 255.0)?;
                row.rmse = row.rmse.max(e.rmse);
                row.max_abs = row.max_abs.max(e.max_abs);
                row.frac_above = row.frac_above.max(e.frac_above);
                pb.inc(1);
            }
        }
    }
    pb.finish_and_clear();
    report(a, &s.base, (&full, &rows, lods), &builds)
}

/// Prints the row of level-of-detail tolerance `tol` (speed-up over full detail's `full_t`
/// ms) and returns its JSON.
fn lod_row(r: &Row, tol: f64, full_t: f64) -> Result<serde_json::Value> {
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
    Ok(
        json!({"lod_px": tol, "particles": n, "cut_ms": med(&r.cut_ms), "surface_ms": med(&r.surface_ms),
              "render_ms": med(&r.render_ms), "total_ms": t, "speedup_vs_full_detail": full_t / t,
              "rmse_vs_full_detail": r.rmse, "max_abs_vs_full_detail": r.max_abs,
              "percent_pixels_above_1_255": 100.0 * r.frac_above}),
    )
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
        js.push(lod_row(r, *tol, full_t)?);
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
