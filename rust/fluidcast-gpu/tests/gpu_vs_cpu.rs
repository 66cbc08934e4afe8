//! Images of the GPU renderer (every stage on the GPU) against the CPU renderer's.
//! Stage-by-stage comparisons are in stages.rs. Without a wgpu adapter the tests skip (see
//! `common::gpu`).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;

use common::{cloud, cloud_tf, gpu, modes, orbit, shared_ddb, shared_pysph};
use fluidcast_gpu::{Gpu, GpuError};
use fluidcast_render::{render_adaptive, PlanParams, RenderParams};
use fluidcast_sph::{FieldKind, Kernel, Particles};
use fluidcast_view::{Camera, TransferFunction};

/// (max abs, RMSE, share of pixels above 1e-3) between the CPU and GPU images. Depth must
/// agree too: the GPU composites in f32, so a ray whose transmittance crosses 1/2 within
/// rounding may cross one sample earlier or later; at most 0.1 % of pixels may differ, each
/// by at most 2 % of its depth, and none may have a depth in one image only.
fn compare(
    g: &Gpu,
    p: &Particles,
    cam: &Camera,
    tf: &TransferFunction,
    prm: &RenderParams,
) -> (f64, f64, f64) {
    let cpu = render_adaptive(p, None, cam, tf, prm).unwrap();
    let gpu = g.render_adaptive(p, None, cam, tf, prm).unwrap();
    // Image-space interpolation (relaxed mode): the same pixels interpolated, but for a few
    // whose lattice neighbours round across a threshold in f32.
    let (ci, gi) = (cpu.stats.interpolated, gpu.stats.interpolated);
    let pixels = u64::from(prm.width) * u64::from(prm.height);
    assert!(
        ci.abs_diff(gi) as f64 <= 0.002 * pixels as f64,
        "interpolated: CPU {ci}, GPU {gi} of {pixels} pixels"
    );
    INTERPOLATED.fetch_add(gi, std::sync::atomic::Ordering::Relaxed);
    let (c, _) = fluidcast_image::compare(&cpu.image, &gpu.image, 1e-3).unwrap();
    assert!(
        c.depth_frac_differ <= 1e-3,
        "depth differs in {} of the pixels",
        c.depth_frac_differ
    );
    for (a, b) in cpu.image.depth.iter().zip(&gpu.image.depth) {
        let ok = a == b || (a.is_finite() && b.is_finite() && (a - b).abs() <= 0.02 * a.max(*b));
        assert!(ok, "depth: CPU {a}, GPU {b}");
    }

    assert!(
        cpu.image.rgba.iter().any(|q| q[3] > 0.1),
        "nothing rendered"
    );
    (c.max_abs, c.rmse, c.frac_above)
}

/// Pixels the GPU interpolated in `compare`, over all calls.
static INTERPOLATED: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

#[test]
fn gpu_matches_cpu_for_every_mode_kernel_and_field() {
    let Some(g) = gpu() else { return };
    let p = cloud(4000, 11);
    let tf = cloud_tf();
    let persp = Camera {
        position: [0.4, 0.6, 2.4],
        focal_point: [0.0; 3],
        view_up: [0.0, 1.0, 0.0],
        ..Default::default()
    };
    let par = Camera {
        parallel_projection: true,
        parallel_scale: 0.7,
        ..persp.clone()
    };
    // Tolerance. The GPU works in f32, the CPU in f64, summing in the same order. Nearly all
    // pixels agree to 1e-3. The exception: a sample whose only contributing particle lies
    // within rounding of its support edge exists in one precision and not the other, and with
    // Shepard normalisation such a sample carries the particle's full value (and the Gaussian
    // kernel, cut at 3σ, jumps there), so that pixel moves by up to one step's opacity.
    // Allowed: at most 0.1 % of pixels above 1e-3, none above 0.05.
    let mut worst = (0.0f64, 0.0f64, 0.0f64);
    for (name, adaptive) in modes() {
        for (cam, cname) in [(&persp, "perspective"), (&par, "parallel")] {
            for kernel in [
                Kernel::CubicSpline,
                Kernel::WendlandC2,
                Kernel::Quintic,
                Kernel::Gaussian,
            ] {
                for field in [FieldKind::Csph, FieldKind::Density] {
                    let prm = RenderParams {
                        width: 96,
                        height: 72,
                        kernel,
                        field,
                        adaptive,
                        ..Default::default()
                    };
                    let mut t = tf.clone();
                    if field == FieldKind::Density {
                        t = t.with_range(0.0, 3.0).unwrap();
                    }
                    let (max, rmse, frac) = compare(&g, &p, cam, &t, &prm);
                    worst = (worst.0.max(max), worst.1.max(rmse), worst.2.max(frac));
                    assert!(
                        max <= 0.05 && frac <= 1e-3,
                        "{name} {cname} {kernel} {field:?}: max abs {max}, RMSE {rmse}, {frac} of pixels above 1e-3"
                    );
                }
            }
        }
    }
    eprintln!(
        "GPU vs CPU: worst max abs {:.2e}, RMSE {:.2e}, share above 1e-3 {:.2e}",
        worst.0, worst.1, worst.2
    );
    // The relaxed renders here interpolate (supports of several pixels): the GPU's two-pass
    // path is exercised and agrees.
    let n = INTERPOLATED.load(std::sync::atomic::Ordering::Relaxed);
    assert!(n > 10_000, "the GPU interpolated only {n} pixels");
}

/// The modes where the plan adapts (the depth ramp: a third of the cells or more coarsen in
/// the strict plan; the relaxed one keeps its surface cells at full rate and adapts fewer):
/// the GPU's image is the CPU's within E_I. (Plans may differ in a cell whose composited
/// width lies within f32 rounding of the budget, measured once here: one bundle, 1.5e-3; each
/// image is within E_I of full rate, see stages.rs.)
#[test]
fn gpu_matches_cpu_where_the_plan_adapts() {
    let Some(g) = gpu() else { return };
    let p = fluidcast_testkit::depth_ramp(20);
    for (alpha, e, azimuth, parallel) in fluidcast_testkit::DEPTH_RAMP_CASES {
        let tf = fluidcast_testkit::depth_ramp_tf(alpha);
        let mut cam = orbit(&p, azimuth, 3.0);
        cam.zoom(1.2);
        cam.parallel_projection = parallel;
        // Every bundle analysed: on this small scene the probe would find that too few
        // relaxed cells adapt to pay (the probe has tests of its own in stages.rs).
        let relaxed = PlanParams {
            tolerance: Some(e),
            probe: false,
            ..Default::default()
        };
        for (name, adaptive) in [("relaxed", relaxed), ("strict", relaxed.strict())] {
            let mut prm = RenderParams {
                width: 96,
                height: 72,
                adaptive,
                ..Default::default()
            };
            prm.grid.depth_samples = 64;
            let cpu = render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
            let st = cpu.stats.plan.clone().unwrap();
            let adapted = st.level_cells[1..].iter().sum::<u64>() + st.superpixel_cells;
            let least = if name == "strict" { 0.3 } else { 0.01 };
            assert!(
                adapted as f64 >= least * st.cells as f64,
                "{name}: only {adapted} of {} cells adapt",
                st.cells
            );
            // (A faint scene: `compare`'s "something rendered" threshold does not apply.)
            assert!(
                cpu.image.rgba.iter().any(|q| q[3] > 0.01),
                "nothing rendered"
            );
            let gpu = g.render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
            let (c, _) = fluidcast_image::compare(&cpu.image, &gpu.image, 1e-3).unwrap();
            let (max, rmse, frac) = (c.max_abs, c.rmse, c.frac_above);
            eprintln!(
                "{name} E_I {e}: {adapted} of {} cells adapt; max {max:.2e}, RMSE {rmse:.2e}",
                st.cells
            );
            assert!(max <= e, "{name} E_I {e}: max {max}, {frac} above 1e-3");
        }
    }
}

#[test]
fn gpu_refuses_what_it_cannot_do() {
    let Some(g) = gpu() else { return };
    let p = cloud(100, 3);
    let tf = TransferFunction::preset("viridis").unwrap();
    let prm = RenderParams {
        width: 8,
        height: 8,
        grid: fluidcast_render::GridParams {
            bundle: 16,
            ..Default::default()
        },
        ..Default::default()
    };
    let e = g.render_adaptive(&p, None, &Camera::default(), &tf, &prm);
    assert!(matches!(e, Err(GpuError::BundleTooLarge(16))));
    // Bad parameters get the CPU renderer's errors.
    let bad = RenderParams {
        width: 0,
        ..Default::default()
    };
    let e = g.render_adaptive(&p, None, &Camera::default(), &tf, &bad);
    assert!(e.unwrap_err().to_string().contains("image size 0x512"));
    let bad = RenderParams {
        adaptive: fluidcast_render::PlanParams {
            tolerance: Some(2.0),
            ..Default::default()
        },
        ..Default::default()
    };
    let e = g.render_adaptive(&p, None, &Camera::default(), &tf, &bad);
    assert!(e.unwrap_err().to_string().contains("tolerance 2"));
    // Nothing to draw: no particles, or all behind the camera. A blank image, as on the CPU.
    let small = RenderParams {
        width: 16,
        height: 12,
        ..Default::default()
    };
    let behind = Camera {
        position: [0.0, 0.0, 5.0],
        focal_point: [0.0, 0.0, 10.0],
        ..Default::default()
    };
    for (q, cam) in [(Particles::default(), Camera::default()), (p, behind)] {
        let r = g.render_adaptive(&q, None, &cam, &tf, &small).unwrap();
        assert!(r.image.rgba.iter().all(|c| *c == [0.0; 4]));
        assert!(r.image.depth.iter().all(|z| z.is_infinite()));
        assert_eq!(r.stats.pairs, 0);
    }
}

#[test]
fn gpu_matches_cpu_on_the_shared_datasets() {
    let Some(g) = gpu() else { return };
    for (data, scene) in [
        ("double dam break", shared_ddb()),
        ("PySPH dam break", shared_pysph()),
    ] {
        let Some((p, tf, cam)) = scene else { continue };
        for (name, adaptive) in modes() {
            let prm = RenderParams {
                width: 160,
                height: 120,
                adaptive,
                ..Default::default()
            };
            let (max, rmse, frac) = compare(&g, &p, &cam, &tf, &prm);
            eprintln!("{data} {name}: max {max:.3e}, RMSE {rmse:.2e}, above 1e-3 {frac:.2e}");
            // As above: only support-edge samples differ, in at most 0.1 % of the pixels, none
            // by more than 0.05 (one step's opacity; 6e-3 measured).
            assert!(
                max <= 0.05 && frac <= 1e-3 && rmse <= 1e-3,
                "{data} {name}: max {max}, RMSE {rmse}, {frac} above 1e-3"
            );
        }
    }
}

/// The cloud from (0.3, 0.4, 2.2), close enough that planes of view depth cut through it.
fn near_camera() -> Camera {
    Camera {
        position: [0.3, 0.4, 2.2],
        focal_point: [0.0; 3],
        view_up: [0.0, 1.0, 0.0],
        ..Default::default()
    }
}

#[test]
fn gpu_matches_cpu_with_opaque_geometry() {
    let Some(g) = gpu() else { return };
    let (p, tf, cam) = (cloud(4000, 5), cloud_tf(), near_camera());
    let (w, h) = (96u32, 72u32);
    // A tilted plane through the cloud, and a corner with nothing opaque.
    let limit: Vec<f32> = (0..h)
        .flat_map(|j| (0..w).map(move |i| (i, j)))
        .map(|(i, j)| {
            if i < 16 && j < 16 {
                f32::INFINITY
            } else {
                1.8 + 0.8 * i as f32 / w as f32
            }
        })
        .collect();
    for (name, adaptive) in modes() {
        let prm = RenderParams {
            width: w,
            height: h,
            adaptive,
            depth_limit: Some(std::sync::Arc::from(limit.clone())),
            ..Default::default()
        };
        let (max, rmse, frac) = compare(&g, &p, &cam, &tf, &prm);
        eprintln!("depth limit {name}: max {max:.3e}, RMSE {rmse:.2e}, above 1e-3 {frac:.2e}");
        assert!(
            max <= 0.05 && frac <= 1e-3,
            "{name}: max {max}, {frac} above 1e-3"
        );
    }
}

/// Rays cropped to a depth interval (`depth_near` alone, and with `depth_limit`: what an MPI
/// rank's box gives) composite the same part of the ray on the GPU as on the CPU.
#[test]
fn gpu_matches_cpu_cropped_to_a_depth_interval() {
    let Some(g) = gpu() else { return };
    let (p, tf, cam) = (cloud(4000, 5), cloud_tf(), near_camera());
    let (w, h) = (96u32, 72u32);
    let plane = |z0: f32, dz: f32| -> std::sync::Arc<[f32]> {
        (0..h)
            .flat_map(|j| (0..w).map(move |i| z0 + dz * (i + j) as f32 / (w + h) as f32))
            .collect()
    };
    let (near, far) = (plane(1.9, 0.3), plane(2.3, 0.2));
    // The last case places the samples over a wider depth range (a whole data set's, of which
    // these particles would be one MPI rank's part).
    let cases = [
        (&near, None, None),
        (&near, Some(&far), None),
        (&near, Some(&far), Some((1.0, 3.5))),
    ];
    for (crop, limit, support_depths) in cases {
        for (name, adaptive) in modes() {
            let prm = RenderParams {
                width: w,
                height: h,
                adaptive,
                depth_near: Some(crop.clone()),
                depth_limit: limit.cloned(),
                support_depths,
                ..Default::default()
            };
            let (max, rmse, frac) = compare(&g, &p, &cam, &tf, &prm);
            let what = match (limit, support_depths) {
                (None, _) => "near",
                (_, None) => "near and far",
                _ => "near, far and support depths",
            };
            eprintln!("{what} {name}: max {max:.3e}, RMSE {rmse:.2e}, above 1e-3 {frac:.2e}");
            assert!(
                max <= 0.05 && frac <= 1e-3,
                "{what} {name}: max {max}, {frac} above 1e-3"
            );
        }
    }
}
