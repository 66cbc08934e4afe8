//! `fluidcast bench --field rbf`: per frame, the BVH's build and refit and the RBF render,
//! for each leaf size (Morrical et al. 2023, Tables 1–2 and Fig. 9's cluster sweep).

use std::time::Instant;

use anyhow::{bail, Context, Result};
use fluidcast_rbf::{RbfField, MAX_LEAF_SIZE};
use fluidcast_render::render_rbf;
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
            let t = Instant::now();
            let mut field = RbfField::build(&particles, tf, &opts)
                .with_context(|| format!("building the RBF field of {}", file.display()))?;
            let build_ms = ms(t);
            let t = Instant::now();
            field.set_radius_map(&opts.radius_map)?;
            let refit_ms = ms(t);
            let rp = a.rbf.render_params(cam0, a.light.as_deref())?;
            let mut row = Row {
                frame: fi,
                particles: particles.len(),
                leaf,
                read_ms,
                build_ms,
                refit_ms,
                render_ms: Vec::new(),
                bytes: field.memory_bytes(),
                bvh_bytes: field.bvh().memory_bytes(),
                samples: 0,
            };
            for v in 0..a.views {
                let cam = orbit(cam0, v, a.views);
                pb.set_message(format!("frame {fi}, leaf {leaf}, view {v}"));
                let t = Instant::now();
                let (_, s) = render_rbf(&field, &cam, tf, &base, &rp)
                    .with_context(|| format!("rendering {}", file.display()))?;
                row.render_ms.push(ms(t));
                row.samples += s.samples;
                pb.inc(1);
            }
            rows.push(row);
        }
    }
    pb.finish_and_clear();
    report(a, &base, &rows)
}

fn report(a: &BenchArgs, base: &fluidcast_render::RenderParams, rows: &[Row]) -> Result<()> {
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
