//! Each GPU stage against its CPU mirror: the grid (pairs, radix sort, cells with merge
//! bits, bundle ranges), the plan (levels chosen per cell), the ray caster alone on a CPU
//! plan, and the strict error bound on the GPU's own images.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;

use std::collections::BTreeMap;

use common::{cloud, cloud_tf, gpu, modes, orbit, shared_ddb, shared_pysph};
use fluidcast_gpu::GpuDump;
use fluidcast_render::{plan_adaptive, render_adaptive, AdaptivePlan, PlanParams, RenderParams};
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, TransferFunction};

/// A cell as a comparable value: (bundle, z) → (refs without the merge bit, refs with it),
/// each sorted.
type Cells = BTreeMap<(u32, u32), (Vec<u32>, Vec<u32>)>;

fn cpu_cells(p: &AdaptivePlan) -> Cells {
    let g = &p.grid;
    let mut out = Cells::new();
    for b in 0..g.bundle_count() {
        for c in g.bundle_cells(b) {
            let r = |a: u32, e: u32| {
                let mut v = g.refs[a as usize..e as usize].to_vec();
                v.sort_unstable();
                v
            };
            out.insert(
                (b as u32, c.z),
                (r(c.start, c.unique_end), r(c.unique_end, c.end)),
            );
        }
    }
    out
}

fn gpu_cells(d: &GpuDump) -> Cells {
    let mut out = Cells::new();
    for (k, c) in d.cells.iter().enumerate() {
        let b = d.cell_bundles[k];
        assert!(
            d.bundle_cells[b as usize] as usize <= k && k < d.bundle_cells[b as usize + 1] as usize,
            "cell {k} of bundle {b} outside the bundle's range"
        );
        assert!(c.start <= c.unique_end && c.unique_end <= c.end && c.start < c.end);
        let r = |a: u32, e: u32| d.refs[a as usize..e as usize].to_vec();
        // The sort is stable and pairs are emitted by particle: refs ascend within a part.
        let (u, m) = (r(c.start, c.unique_end), r(c.unique_end, c.end));
        assert!(u.windows(2).all(|w| w[0] < w[1]) && m.windows(2).all(|w| w[0] < w[1]));
        assert!(
            out.insert((b, c.z), (u, m)).is_none(),
            "cell ({b}, {}) twice",
            c.z
        );
    }
    out
}

/// Cells whose references differ between CPU and GPU (or that only one has), of all cells.
/// (cells whose chosen level is the same, cells both grids have): the CPU plan against the
/// GPU's dump, cells matched by (bundle, z).
fn levels_agree(cpu: &AdaptivePlan, d: &GpuDump) -> (usize, usize) {
    let mut cpu_level = BTreeMap::new();
    for b in 0..cpu.grid.bundle_count() {
        let first = cpu.grid.bundle_first_cell(b);
        for (i, c) in cpu.grid.bundle_cells(b).iter().enumerate() {
            cpu_level.insert((b as u32, c.z), cpu.plan.cell_levels[first + i]);
        }
    }
    let (mut same, mut n) = (0usize, 0usize);
    for (k, c) in d.cells.iter().enumerate() {
        if let Some(&l) = cpu_level.get(&(d.cell_bundles[k], c.z)) {
            n += 1;
            same += (l == d.levels[k]) as usize;
        }
    }
    (same, n)
}

fn cell_mismatch(a: &Cells, b: &Cells) -> (usize, usize) {
    let keys: std::collections::BTreeSet<_> = a.keys().chain(b.keys()).collect();
    let differ = keys.iter().filter(|k| a.get(k) != b.get(k)).count();
    (differ, keys.len())
}

struct Scene {
    name: &'static str,
    p: Particles,
    tf: TransferFunction,
    cam: Camera,
    size: (u32, u32),
}

fn scenes() -> Vec<Scene> {
    let persp = Camera {
        position: [0.4, 0.6, 2.4],
        focal_point: [0.0; 3],
        view_up: [0.0, 1.0, 0.0],
        ..Default::default()
    };
    let mut out = vec![
        Scene {
            name: "cloud, perspective",
            p: cloud(4000, 11),
            tf: cloud_tf(),
            cam: persp.clone(),
            size: (96, 72),
        },
        Scene {
            name: "cloud, parallel",
            p: cloud(4000, 12),
            tf: cloud_tf(),
            cam: Camera {
                parallel_projection: true,
                parallel_scale: 0.7,
                ..persp
            },
            size: (90, 70),
        },
    ];
    let (p, tf) = checker_board();
    out.push(Scene {
        name: "checker board",
        cam: orbit(&p, 30.0, 20.0),
        p,
        tf,
        size: (128, 96),
    });
    let (p, tf) = fluidcast_testkit::behind_a_front();
    out.push(Scene {
        name: "behind a front",
        cam: orbit(&p, 5.0, 3.0),
        p,
        tf,
        size: (96, 72),
    });
    let (p, tf) = faint_cloud();
    out.push(Scene {
        name: "faint cloud",
        cam: orbit(&p, 160.0, -25.0),
        p,
        tf,
        size: (128, 96),
    });
    for (name, scene) in [
        ("double dam break", shared_ddb()),
        ("PySPH dam break", shared_pysph()),
    ] {
        if let Some((p, tf, cam)) = scene {
            out.push(Scene {
                name,
                p,
                tf,
                cam,
                size: (160, 120),
            });
        }
    }
    out
}

fn params(size: (u32, u32), adaptive: PlanParams) -> RenderParams {
    RenderParams {
        width: size.0,
        height: size.1,
        adaptive,
        ..Default::default()
    }
}

#[test]
fn gpu_grid_and_plan_match_the_cpu_mirror() {
    let Some(g) = gpu() else { return };
    // Probed plans where the probe paid and where it did not (then both leave the same
    // bundles unanalysed: the decision is exact integer arithmetic on both).
    let mut probed = [0, 0];
    for s in scenes() {
        let coarse = PlanParams {
            tolerance: Some(0.02),
            ..Default::default()
        };
        // Depth levels alone, where super-pixels would take the cells behind a front.
        let levels_only = PlanParams {
            tolerance: Some(0.01),
            superpixels: false,
            ..Default::default()
        };
        let extra = [("0.02", coarse), ("0.01 no super-pixels", levels_only)];
        for (mode, adaptive) in modes().into_iter().chain(extra) {
            let prm = params(s.size, adaptive);
            let cpu = plan_adaptive(&s.p, None, &s.cam, &s.tf, &prm).unwrap();
            let (r, d) = g.render_with_dump(&s.p, None, &s.cam, &s.tf, &prm).unwrap();
            // Grid. The footprints are computed in f32 on the GPU: a reference can appear or
            // vanish only where a support's bounding box or depth range ends within rounding
            // of a pixel centre or a depth sample, which is rare.
            let (cc, gc) = (cpu_cells(&cpu), gpu_cells(&d));
            let (differ, total) = cell_mismatch(&cc, &gc);
            eprintln!(
                "{} {mode}: {} pairs, {} cells, {differ} differ",
                s.name, r.stats.pairs, total
            );
            assert_eq!(r.stats.pairs, d.refs.len() as u64);
            assert!(
                differ as f64 <= 1e-3 * total as f64,
                "{} {mode}: {differ} of {total} cells differ",
                s.name
            );
            assert_eq!(
                (r.stats.depth_samples, r.stats.particles_visible),
                (cpu.stats.depth_samples, cpu.stats.particles_visible),
                "{}",
                s.name
            );
            // Plan: the level (or super-pixel) of every cell both grids have. Bounds are
            // composited in f32 against E_I, so a choice whose composited width lies within
            // rounding of the budget may go the other way; that is rare.
            let (same, n) = levels_agree(&cpu, &d);
            let cs = cpu.plan.stats.clone();
            let gs = r.stats.plan.clone().unwrap();
            eprintln!(
                "  levels agree on {same} of {n} cells; CPU levels {:?} sp {}, GPU {:?} sp {}",
                cs.level_cells, cs.superpixel_cells, gs.level_cells, gs.superpixel_cells
            );
            assert!(
                same as f64 >= 0.995 * n as f64,
                "{} {mode}: levels agree on {same} of {n} cells",
                s.name
            );
            assert_eq!(gs.unanalysed_bundles, cs.unanalysed_bundles, "{}", s.name);
            // Cell merging, full-rate runs included (up to MAX_SPAN_SAMPLES a span): the
            // same rule on both, up to the rare cells above.
            let (cm, gm) = (cs.merged_cells as f64, gs.merged_cells as f64);
            assert!(
                (cm - gm).abs() <= 0.02 * cm + 2.0 && (cm > 0.0 || adaptive.tolerance.is_some()),
                "{} {mode}: cells merged CPU {cm}, GPU {gm}",
                s.name
            );
            if adaptive.tolerance.is_some() && adaptive.probe {
                probed[usize::from(cs.unanalysed_bundles > 0)] += 1;
            }
        }
    }
    eprintln!("probed plans that paid, that did not: {probed:?}");
    assert!(probed[0] > 0 && probed[1] > 0, "{probed:?}");
}

#[test]
fn gpu_ray_caster_on_the_cpu_plan_matches_the_cpu_caster() {
    let Some(g) = gpu() else { return };
    for s in scenes() {
        for (mode, mut adaptive) in modes() {
            // The ray casting stage alone: one pass over every pixel (image-space
            // interpolation runs it more than once: gpu_vs_cpu.rs).
            adaptive.interpolate = false;
            let prm = params(s.size, adaptive);
            let planned = plan_adaptive(&s.p, None, &s.cam, &s.tf, &prm).unwrap();
            let cpu = render_adaptive(&s.p, None, &s.cam, &s.tf, &prm).unwrap();
            let r = g.render_planned(&planned, &s.tf, &prm).unwrap();
            let (c, _) = fluidcast_image::compare(&cpu.image, &r.image, 1e-3).unwrap();
            eprintln!(
                "{} {mode}: max {:.2e}, RMSE {:.2e}, above 1e-3 {:.2e}",
                s.name, c.max_abs, c.rmse, c.frac_above
            );
            // Same plan, same summation order; f32 against f64, and samples at a support's
            // edge (see gpu_vs_cpu.rs): at most 0.1 % of the pixels, none by more than 0.05.
            assert!(
                c.max_abs <= 0.05 && c.frac_above <= 1e-3 && c.rmse <= 1e-3,
                "{} {mode}: max {}, RMSE {}, {} above 1e-3",
                s.name,
                c.max_abs,
                c.rmse,
                c.frac_above
            );
        }
    }
}

/// Blocks of constant value on a lattice (the paper's Checker Board); blocks 0–3 transparent,
/// so cells that see only those have zero-width bounds and even the strict plan adapts.
fn checker_board() -> (Particles, TransferFunction) {
    let s = 1.0f32 / 20.0;
    let mut p = Particles::default();
    for i in 0..20 {
        for j in 0..20 {
            for k in 0..20 {
                let x = [i, j, k].map(|v| (v as f32 + 0.5) * s - 0.5);
                let b = x.map(|c| if c < 0.0 { 0 } else { 1 });
                p.positions.push(x);
                p.radii.push(2.0 * s);
                p.volumes.push(s * s * s);
                p.masses.push(1.0);
                p.values.push((b[0] + 2 * b[1] + 4 * b[2]) as f32);
            }
        }
    }
    let mut tf = TransferFunction::preset("viridis")
        .unwrap()
        .with_range(0.0, 7.0)
        .unwrap();
    tf.opacity = vec![(0.0, 0.0), (0.49, 0.0), (0.51, 0.6), (1.0, 0.3)];
    tf.unit_distance = 0.3;
    (p, tf)
}

/// The cloud's smooth field through a faint transfer function: small bound widths, so the
/// strict plan adapts where the bound is not trivially zero.
fn faint_cloud() -> (Particles, TransferFunction) {
    let mut tf = cloud_tf();
    tf.unit_distance = 8.0;
    (cloud(3000, 21), tf)
}

#[test]
fn strict_bound_holds_on_the_gpu() {
    let Some(g) = gpu() else { return };
    let (p, tf) = checker_board();
    let (q, qtf) = faint_cloud();
    let mut worst = 0.0f64;
    let mut adapted_per_scene = [0u64; 2];
    let views = [(30.0, 20.0), (160.0, -25.0), (250.0, 40.0)];
    for (k, (p, tf, (az, el))) in views
        .iter()
        .map(|v| (&p, &tf, v))
        .chain(views.iter().map(|v| (&q, &qtf, v)))
        .enumerate()
    {
        let cam = orbit(p, *az, *el);
        let off = g
            .render_adaptive(p, None, &cam, tf, &params((128, 96), modes()[0].1))
            .unwrap();
        for e in [0.004, 0.01] {
            let strict = PlanParams {
                tolerance: Some(e),
                ..Default::default()
            }
            .strict();
            let r = g
                .render_adaptive(p, None, &cam, tf, &params((128, 96), strict))
                .unwrap();
            let (c, _) = fluidcast_image::compare(&off.image, &r.image, e).unwrap();
            let st = r.stats.plan.unwrap();
            let adapted: u64 = st.level_cells[1..].iter().sum();
            eprintln!(
                "view {k}, strict E_I = {e}: max abs {:.2e}, {adapted} of {} cells adapted",
                c.max_abs, st.cells
            );
            adapted_per_scene[k / views.len()] += adapted;
            assert!(c.max_abs <= e, "view {k}, E_I {e}: max abs {}", c.max_abs);
            worst = worst.max(c.max_abs / e);
        }
    }
    eprintln!("strict: worst error / E_I = {worst:.3}, cells adapted {adapted_per_scene:?}");
    assert!(
        adapted_per_scene.iter().all(|&a| a > 0),
        "the strict plan adapted nothing in a scene: {adapted_per_scene:?}"
    );
}

/// The strict bound where a coarse sample stands for values a whole cell away (the field
/// grows along the view, 64 depth samples per cell; `fluidcast_testkit::depth_ramp`): the
/// GPU's plan adapts a third of the cells or more and stays within E_I. Without the coarse
/// sample's term in `plan.wgsl`'s level bound it misses by more than 2 E_I.
#[test]
fn strict_bound_holds_along_a_depth_ramp_on_the_gpu() {
    let Some(g) = gpu() else { return };
    let p = fluidcast_testkit::depth_ramp(20);
    for (alpha, e, azimuth, parallel) in fluidcast_testkit::DEPTH_RAMP_CASES {
        let tf = fluidcast_testkit::depth_ramp_tf(alpha);
        let mut cam = orbit(&p, azimuth, 3.0);
        cam.parallel_projection = parallel;
        cam.zoom(1.2);
        let mut prm = params((96, 72), modes()[0].1);
        prm.grid.depth_samples = 64;
        let off = g.render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
        prm.adaptive = PlanParams {
            tolerance: Some(e),
            ..Default::default()
        }
        .strict();
        let r = g.render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
        let (c, _) = fluidcast_image::compare(&off.image, &r.image, e).unwrap();
        let st = r.stats.plan.unwrap();
        let adapted = st.level_cells[1..].iter().sum::<u64>() as f64 / st.cells as f64;
        let what = format!("alpha {alpha}, azimuth {azimuth}, parallel {parallel}, E_I {e}");
        eprintln!(
            "{what}: {adapted:.3} of the cells adapt, max abs {:.2e}",
            c.max_abs
        );
        assert!(
            adapted >= 0.3,
            "{what}: only {adapted:.3} of the cells adapt"
        );
        assert!(c.max_abs > 0.0, "{what}: adapting changed nothing");
        assert!(
            c.max_abs <= e,
            "{what}: strict max abs error {} above E_I",
            c.max_abs
        );
    }
}

/// Opaque geometry in the plan: where a wall stops some rays of a bundle, the steps past
/// its nearest depth may be empty, so fewer cells coarsen (strict, on the depth ramp); the
/// GPU's plan makes the same choices as the CPU's.
#[test]
fn gpu_plan_honours_opaque_geometry_as_the_cpu_does() {
    let Some(g) = gpu() else { return };
    let p = fluidcast_testkit::depth_ramp(20);
    let (alpha, e, azimuth, _) = fluidcast_testkit::DEPTH_RAMP_CASES[0];
    let tf = fluidcast_testkit::depth_ramp_tf(alpha);
    let mut cam = orbit(&p, azimuth, 3.0);
    cam.zoom(1.2);
    let strict = PlanParams {
        tolerance: Some(e),
        ..Default::default()
    }
    .strict();
    let (w, h) = (96u32, 72u32);
    let mut prm = params((w, h), strict);
    prm.grid.depth_samples = 64;
    let open = plan_adaptive(&p, None, &cam, &tf, &prm).unwrap();
    // A wall at mid-depth over the left 60 % of the image.
    let (near, far) = (open.stats.near, open.stats.far);
    let z = (0.5 * (near + far)) as f32;
    let wall: Vec<f32> = (0..w * h)
        .map(|k| if k % w < 58 { z } else { f32::INFINITY })
        .collect();
    prm.depth_limit = Some(std::sync::Arc::from(wall));
    let cpu = plan_adaptive(&p, None, &cam, &tf, &prm).unwrap();
    let adapted = |s: &fluidcast_render::PlanStats| s.level_cells[1..].iter().sum::<u64>();
    let (a_open, a_wall) = (adapted(&open.plan.stats), adapted(&cpu.plan.stats));
    assert!(
        a_wall < a_open,
        "the wall changed nothing: {a_wall} vs {a_open} cells adapt"
    );
    let (r, d) = g.render_with_dump(&p, None, &cam, &tf, &prm).unwrap();
    let (same, n) = levels_agree(&cpu, &d);
    let gpu_adapted = adapted(&r.stats.plan.unwrap());
    eprintln!(
        "adapted cells: open {a_open}, wall CPU {a_wall}, GPU {gpu_adapted}; levels agree on {same} of {n}"
    );
    assert!(
        same as f64 >= 0.995 * n as f64,
        "levels agree on {same} of {n} cells"
    );
}

/// A block seen from its front (+z): the front half's value varies across every bundle and
/// slowly in depth, the back half's is uniform, under a faint Viridis. At E_I 0.01 (no probe,
/// no surface rule) the back's cells become super-pixels and the front's coarser levels fit
/// only relaxed, which in front of a super-pixel they may not be (`choose_level`): with
/// relaxed levels there 9 of the front's cells adapt, so a GPU plan that still relaxes them
/// disagrees on about 3 % of the cells (339 of 348 agree).
fn levels_before_superpixels() -> (Particles, TransferFunction) {
    let mut p = fluidcast_testkit::depth_ramp(20);
    for (x, v) in p.positions.iter().zip(p.values.iter_mut()) {
        *v = match x[2] > 0.0 {
            true => 0.5 + 0.1 * (12.0 * x[0]).sin() * (12.0 * x[1]).cos() + 0.1 * x[2],
            false => 0.5,
        };
    }
    let mut tf = TransferFunction::preset("viridis")
        .unwrap()
        .with_range(0.0, 1.0)
        .unwrap();
    tf.scale_opacity(0.05);
    // About what `fluidcast render` takes by default here (support-bounds diagonal / ∛N).
    tf.unit_distance = 0.1;
    (p, tf)
}

/// The GPU's greedy holds coarser levels in front of a super-pixel to their unrelaxed bounds
/// as the CPU's does ([`levels_before_superpixels`]).
#[test]
fn gpu_plan_holds_levels_in_front_of_superpixels_as_the_cpu_does() {
    let Some(g) = gpu() else { return };
    let (p, tf) = levels_before_superpixels();
    let cam = orbit(&p, 5.0, 3.0);
    let adaptive = PlanParams {
        tolerance: Some(0.01),
        surface_cells: false,
        probe: false,
        ..Default::default()
    };
    let prm = params((128, 96), adaptive);
    let cpu = plan_adaptive(&p, None, &cam, &tf, &prm).unwrap();
    let (r, d) = g.render_with_dump(&p, None, &cam, &tf, &prm).unwrap();
    let (same, n) = levels_agree(&cpu, &d);
    let (cs, gs) = (&cpu.plan.stats, r.stats.plan.unwrap());
    eprintln!(
        "CPU levels {:?} sp {}, GPU {:?} sp {}; levels agree on {same} of {n}",
        cs.level_cells, cs.superpixel_cells, gs.level_cells, gs.superpixel_cells
    );
    assert!(
        cs.superpixel_cells > 0,
        "no super-pixels: the scene tests nothing"
    );
    assert!(
        same as f64 >= 0.995 * n as f64,
        "levels agree on {same} of {n} cells"
    );
}

#[test]
fn gpu_buffers_are_reused_across_frames() {
    let Some(g) = gpu() else { return };
    let tf = cloud_tf();
    let cam = Camera {
        position: [0.4, 0.6, 2.4],
        focal_point: [0.0; 3],
        view_up: [0.0, 1.0, 0.0],
        ..Default::default()
    };
    let prm = params((96, 72), PlanParams::default());
    let mut held = Vec::new();
    for seed in 1..=4 {
        let p = cloud(3000, seed);
        let r = g.render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
        held.push(r.stats.gpu_memory_bytes);
        // GPU stage timings appear exactly when the adapter has timestamp queries.
        for stage in ["gpu_grid", "gpu_sort", "gpu_adapt", "gpu_raycast"] {
            assert_eq!(
                r.stats.stage(stage).is_some(),
                g.has_timestamps(),
                "{stage}"
            );
        }
    }
    eprintln!("GPU memory held after each frame: {held:?} bytes");
    assert!(held[0] > 0);
    // Similar frames fit the buffers of the first (grown by half when made).
    assert_eq!(held[1], held[3], "buffers were reallocated: {held:?}");
}

/// The scans and the radix sort with subgroup operations (where the adapter has them:
/// lavapipe does, so CI runs this variant) give the same grid, plan and image as in workgroup
/// memory alone, bit for bit: both are exact integer sums.
#[test]
fn subgroup_and_workgroup_prefix_sums_build_the_same_grid() {
    let Some(g) = gpu() else { return };
    if g.is_software() {
        assert!(
            g.uses_subgroups(),
            "lavapipe has subgroup operations: {}",
            g.adapter
        );
    }
    let plain = gpu().unwrap().without_subgroups().unwrap();
    assert!(!plain.uses_subgroups());
    for s in scenes() {
        for (mode, adaptive) in modes() {
            let prm = params(s.size, adaptive);
            let (a, da) = g.render_with_dump(&s.p, None, &s.cam, &s.tf, &prm).unwrap();
            let (b, db) = plain
                .render_with_dump(&s.p, None, &s.cam, &s.tf, &prm)
                .unwrap();
            assert!(!da.refs.is_empty(), "{} {mode}: an empty grid", s.name);
            assert_eq!(da.cells, db.cells, "{} {mode}", s.name);
            assert_eq!(da.refs, db.refs, "{} {mode}", s.name);
            assert_eq!(da.levels, db.levels, "{} {mode}", s.name);
            assert_eq!(a.image.rgba, b.image.rgba, "{} {mode}", s.name);
        }
    }
}
