//! `fluidcast bench --field rbf`: per frame, the BVH's build and refit and the RBF render,
//! for each leaf size (Morrical et al. 2023, Tables 1–2 and Fig. 9's cluster sweep).

use std::time::Instant;

use anyhow::{bail, Context, Result};
use fluidcast_backend::{March, Marched, RenderPlan, Renderer, Scene, MAX_LEAF_SIZE};
use serde_json::json;

use crate::bench::{frame_particles, ms, orbit, BenchArgs, Setup};

/// Parses `--leaf-sizes` (comma-separated, each 1..=64).
fn leaf_sizes(s: &str) -> Result<Vec<usize>> {
    let v: Vec<usize> = s
        .split(',')
        .map(|x| x.trim().parse::<usize>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--leaf-sizes '{s}': expected numbers, e.g. 1,4,16"))?;
    if v.is_empty() || v.iter().any(|&k| !(1..=MAX_LEAF_SIZE).contains(&k)) {
        bail!("--leaf-sizes '{s}': each must be 1..={MAX_LEAF_SIZE}");
    }
    Ok(v)
}

/// One frame at one leaf size: milliseconds of build, refit and each view's render, and the
/// field's bytes.
struct Row {
    frame: usize,
    particles: usize,
    leaf: usize,
    read_ms: f64,
    build_ms: f64,
    refit_ms: f64,
    render_ms: Vec<f64>,
    bytes: usize,
    bvh_bytes: usize,
    samples: u64,
}

pub fn run(a: &BenchArgs) -> Result<()> {
    let leaves = match &a.leaf_sizes {
        Some(s) => leaf_sizes(s)?,
        None => vec![a.rbf.leaf_size],
    };
    let Setup {
        base,
        base_tf,
        input,
        all,
        frames,
        spec,
    } = Setup::new(a)?;
    let mut opts = a.rbf.options(a.particles.array.is_some())?;
    let pb = crate::render::progress_bar(frames.len() * leaves.len() * a.views, "renders");
    let mut setup = None;
    let mut rows = Vec::new();
    let cpu = Renderer::cpu();
    for &fi in &frames {
        let file = &all[fi].1;
        let t = Instant::now();
        let particles = frame_particles(&input, &all[fi], &spec)?;
        let read_ms = ms(t);
        let (cam0, tf) = match &setup {
            Some(s) => s,
            None => setup.insert(a.view.setup(&particles, &base, &base_tf, false)?),
        };
        for &leaf in &leaves {
            opts.leaf_size = leaf;
            // A new scene per leaf size: the first view builds the field (stage bvh) and
            // times one refit (stage refit); the other views reuse it.
            let mut scene = Scene::new(particles.clone(), cam0.clone(), tf.clone());
            let mut plan = RenderPlan {
                params: base.clone(),
                march: Some(March {
                    field: Marched::Rbf(opts.clone()),
                    params: a.rbf.render_params(cam0, a.light.as_deref())?,
                    progressive_passes: 0,
                    time_refit: true,
                }),
                ..Default::default()
            };
            let mut row = Row {
                frame: fi,
                particles: particles.len(),
                leaf,
                read_ms,
                build_ms: 0.0,
                refit_ms: 0.0,
                render_ms: Vec::new(),
                bytes: 0,
                bvh_bytes: 0,
                samples: 0,
            };
            for v in 0..a.views {
                scene.camera = orbit(cam0, v, a.views);
                pb.set_message(format!("frame {fi}, leaf {leaf}, view {v}"));
                measure_view(&cpu, &mut scene, &mut plan, &mut row)
                    .with_context(|| format!("rendering {}", file.display()))?;
                pb.inc(1);
            }
            rows.push(row);
        }
    }
    pb.finish_and_clear();
    report(a, &base, &rows)
}

/// Renders one view of `scene` and adds it to `row`: the first render of a field reports its
/// build and one refit (stages bvh and refit), which are not part of the render's time.
fn measure_view(
    cpu: &Renderer,
    scene: &mut Scene,
    plan: &mut RenderPlan,
    row: &mut Row,
) -> Result<()> {
    let t = Instant::now();
    let r = cpu.render(scene, plan)?;
    let stage = |name| r.stats.stages.iter().find(|s| s.0 == name).map(|s| s.1);
    let (bvh, refit) = (stage("bvh"), stage("refit").unwrap_or(0.0));
    if let Some(b) = bvh {
        (row.build_ms, row.refit_ms) = (b, refit);
    }
    let built = bvh.unwrap_or(0.0) + refit;
    row.render_ms.push((ms(t) - built).max(0.0));
    row.bytes = r.march_bytes.unwrap_or(0);
    row.bvh_bytes = r.march_bvh_bytes.unwrap_or(0);
    row.samples += r.stats.samples;
    if let Some(m) = &mut plan.march {
        m.time_refit = false; // once per field, as the build
    }
    Ok(())
}

fn report(a: &BenchArgs, base: &fluidcast_backend::RenderParams, rows: &[Row]) -> Result<()> {
    out!(
        "{}: RBF field, {}x{}, {} view(s) a frame, --spp {}{}; times in ms (render: median over views)",
        a.input.display(),
        base.width,
        base.height,
        a.views,
        a.rbf.spp,
        if a.rbf.shadows { ", shadows" } else { "" }
    );
    out!(
        "{:>6} {:>10} {:>5} {:>9} {:>9} {:>9} {:>10} {:>10} {:>12} {:>14}",
        "frame",
        "particles",
        "leaf",
        "read",
        "build",
        "refit",
        "render",
        "BVH B/p",
        "field B/p",
        "samples/view"
    );
    let mut js = Vec::new();
    for r in rows {
        let mut v = r.render_ms.clone();
        v.sort_by(f64::total_cmp);
        let render = v.get(v.len() / 2).copied().unwrap_or(f64::NAN);
        let per = r.bytes as f64 / r.particles.max(1) as f64;
        let bvh = r.bvh_bytes as f64 / r.particles.max(1) as f64;
        let samples = r.samples / r.render_ms.len().max(1) as u64;
        out!(
            "{:>6} {:>10} {:>5} {:>9.1} {:>9.2} {:>9.2} {:>10.1} {:>10.1} {:>12.1} {:>14}",
            r.frame,
            r.particles,
            r.leaf,
            r.read_ms,
            r.build_ms,
            r.refit_ms,
            render,
            bvh,
            per,
            samples
        );
        js.push(json!({"frame": r.frame, "particles": r.particles, "leaf_size": r.leaf,
                       "read_ms": r.read_ms, "build_ms": r.build_ms, "refit_ms": r.refit_ms,
                       "render_ms": r.render_ms, "render_ms_median": render,
                       "field_bytes": r.bytes, "bytes_per_particle": per,
                       "bvh_bytes": r.bvh_bytes, "bvh_bytes_per_particle": bvh, "samples_per_view": samples}));
    }
    if let Some(p) = &a.json {
        let v = json!({"input": a.input, "field": "rbf", "width": base.width, "height": base.height,
                       "views": a.views, "spp": a.rbf.spp, "shadows": a.rbf.shadows, "rows": js});
        std::fs::write(p, serde_json::to_string_pretty(&v)?)
            .with_context(|| format!("writing {}", p.display()))?;
        eprintln!("wrote {}", p.display());
    }
    Ok(())
}
