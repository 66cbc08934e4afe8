//! The RBF field on the GPU against the CPU renderer: the same passes and offsets.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;

use fluidcast_rbf::{Colouring, RbfField, RbfOptions};
use fluidcast_render::{render_rbf, Noise, RbfRenderParams, RbfShadows, RenderParams};
use fluidcast_view::Camera;

/// Small scenes: on a software driver (lavapipe, what CI has) every point query is charged
/// the most one can take against the driver's loop limit, so a pixel affords a few hundred.
const PARTICLES: usize = 60;
const LEAF: usize = 16;
const STEP: Option<f64> = Some(0.04);

/// CPU (f64, Gaussians stepped along each ray) and GPU (f32, a point query per sample) on a
/// 60-particle cloud, both projections, every colouring, both noises, a continued pass
/// range. Stated tolerance: max |GPU − CPU| <= 2e-3 per channel and RMSE <= 2e-4 (single
/// precision sample positions and sums; a sample at a sphere's edge, where the Gaussian is
/// cut at 1.1 % of its weight, may fall on either side).
#[test]
fn gpu_rbf_passes_match_the_cpu() {
    let Some(gpu) = common::gpu() else {
        return;
    };
    let p = common::cloud(PARTICLES, 17);
    let tf = common::cloud_tf();
    let mut worst = 0f64;
    for (parallel, colouring, noise, first_pass) in [
        (false, Colouring::Post, Noise::Blue, 0),
        (true, Colouring::Pre, Noise::White, 3),
        (false, Colouring::Density, Noise::White, 0),
    ] {
        let opts = RbfOptions {
            colouring,
            leaf_size: LEAF,
            ..Default::default()
        };
        let field = RbfField::build(&p, &tf, &opts).unwrap();
        let mut cam = Camera {
            parallel_projection: parallel,
            ..Default::default()
        };
        cam.reset([-0.7; 3], [0.7; 3]);
        cam.azimuth(25.0);
        let prm = RenderParams {
            width: 48,
            height: 40,
            ..Default::default()
        };
        let rbf = RbfRenderParams {
            spp: 2,
            first_pass,
            seed: 9,
            noise,
            step: STEP,
            ..Default::default()
        };
        let (a, _) = render_rbf(&field, &cam, &tf, &prm, &rbf).unwrap();
        let (b, stats) = gpu.render_rbf(&field, &cam, &tf, &prm, &rbf).unwrap();
        let (mut max, mut sq) = (0f64, 0f64);
        for (x, y) in a.rgba.iter().zip(&b.rgba) {
            for c in 0..4 {
                let d = f64::from(x[c] - y[c]).abs();
                max = max.max(d);
                sq += d * d;
            }
        }
        let rmse = (sq / (4 * a.rgba.len()) as f64).sqrt();
        eprintln!("{colouring:?}, parallel {parallel}, {noise:?}: max {max:.2e}, RMSE {rmse:.2e}");
        assert!(a.rgba.iter().any(|p| p[3] > 0.3), "drew something");
        assert!(
            max <= 2e-3 && rmse <= 2e-4,
            "{colouring:?}: max {max}, RMSE {rmse}"
        );
        assert!(stats.stage("raycast").is_some());
        worst = worst.max(max);
    }
    eprintln!("worst max |GPU - CPU| {worst:.2e}");
}

/// Shadows: the same shade points and shadow rays. A pixel whose accumulated opacity lies
/// within single precision's rounding of its pick chooses the neighbouring sample on one
/// side, so the stated tolerance is on the image as a whole: RMSE <= 2e-3 and at most 1 % of
/// the channels off by more than 1e-2.
#[test]
fn gpu_rbf_shadows_match_the_cpu() {
    let Some(gpu) = common::gpu() else {
        return;
    };
    let p = common::cloud(PARTICLES, 17);
    let tf = common::cloud_tf();
    let opts = RbfOptions {
        leaf_size: LEAF,
        ..Default::default()
    };
    let field = RbfField::build(&p, &tf, &opts).unwrap();
    let mut cam = Camera::default();
    cam.reset([-0.7; 3], [0.7; 3]);
    cam.elevation(20.0);
    let prm = RenderParams {
        width: 40,
        height: 32,
        ..Default::default()
    };
    for noise in [Noise::White, Noise::Blue] {
        let rbf = RbfRenderParams {
            spp: 2,
            noise,
            step: STEP,
            shadows: Some(RbfShadows::new([0.3, 1.0, 0.2], 0.2, 2).unwrap()),
            ..Default::default()
        };
        let (a, _) = render_rbf(&field, &cam, &tf, &prm, &rbf).unwrap();
        let (b, _) = gpu.render_rbf(&field, &cam, &tf, &prm, &rbf).unwrap();
        let unlit = RbfRenderParams {
            shadows: None,
            ..rbf.clone()
        };
        let (c, _) = render_rbf(&field, &cam, &tf, &prm, &unlit).unwrap();
        let (mut sq, mut far, mut moved) = (0f64, 0usize, 0f64);
        for ((x, y), z) in a.rgba.iter().zip(&b.rgba).zip(&c.rgba) {
            for k in 0..4 {
                let d = f64::from(x[k] - y[k]).abs();
                sq += d * d;
                far += usize::from(d > 1e-2);
                moved = moved.max(f64::from(x[k] - z[k]).abs());
            }
        }
        let n = 4 * a.rgba.len();
        let rmse = (sq / n as f64).sqrt();
        eprintln!("shadows, {noise:?}: RMSE {rmse:.2e}, {far} of {n} channels above 1e-2; lit vs unlit max {moved:.3}");
        assert!(
            rmse <= 2e-3 && far * 100 <= n,
            "{noise:?}: RMSE {rmse}, {far} far"
        );
        assert!(moved > 0.05, "shadows change the image");
    }
}

#[test]
fn gpu_rbf_refuses_what_it_does_not_draw() {
    let Some(gpu) = common::gpu() else {
        return;
    };
    let p = common::cloud(50, 3);
    let tf = common::cloud_tf();
    let field = RbfField::build(&p, &tf, &RbfOptions::default()).unwrap();
    let mut cam = Camera::default();
    cam.reset([-0.7; 3], [0.7; 3]);
    let prm = RenderParams {
        width: 8,
        height: 8,
        ..Default::default()
    };
    let lit = RbfRenderParams {
        shadows: Some(RbfShadows::new([0.0, 1.0, 0.0], 0.3, 1).unwrap()),
        ..Default::default()
    };
    let _ = lit;
    // A limit below what one point query takes is refused, not drawn wrong.
    let starved = common::gpu().unwrap().with_loop_limit(3);
    let e = starved
        .render_rbf(&field, &cam, &tf, &prm, &RbfRenderParams::default())
        .unwrap_err();
    assert!(e.to_string().contains("loop"), "{e}");
    // An image past one storage binding is refused with what it takes, not a wgpu panic
    // (lavapipe binds 128 MiB: 8.4M pixels; a hardware GPU may take it).
    let huge = RenderParams {
        width: 4096,
        height: 4096,
        ..Default::default()
    };
    match gpu.render_rbf(&field, &cam, &tf, &huge, &RbfRenderParams::default()) {
        Err(e @ fluidcast_gpu::GpuError::ImageTooLarge(..)) => {
            assert!(e.to_string().contains("4096x4096"), "{e}")
        }
        Err(e) => panic!("{e}"),
        Ok(_) => assert!(!gpu.is_software(), "lavapipe's bindings hold 8.4M pixels"),
    }
    let zero = RbfRenderParams {
        spp: 0,
        ..Default::default()
    };
    assert!(gpu.render_rbf(&field, &cam, &tf, &prm, &zero).is_err());
}

/// Where a pixel's point queries would pass the loop limit, its march stops before a query
/// and the next dispatch resumes there: the image is the one a single dispatch gives, bit for
/// bit (the same f32 arithmetic in the same order), in more dispatches; with and without
/// shadows (a stop in the shade-point march and in the shadow rays). A 3000-particle cloud,
/// which a software driver refused before, and the CPU within the stated tolerance.
#[test]
fn gpu_rbf_resumes_past_the_loop_limit() {
    let Some(gpu) = common::gpu() else {
        return;
    };
    let tight = common::gpu().unwrap().with_loop_limit(16_000);
    let p = common::cloud(3000, 5);
    let tf = common::cloud_tf();
    let field = RbfField::build(&p, &tf, &RbfOptions::default()).unwrap();
    let mut cam = Camera::default();
    cam.reset([-0.7; 3], [0.7; 3]);
    let prm = RenderParams {
        width: 24,
        height: 20,
        ..Default::default()
    };
    let lit = RbfShadows::new([0.0, 1.0, 0.0], 0.3, 2).unwrap();
    for shadows in [None, Some(lit)] {
        let rbf = RbfRenderParams {
            spp: 2,
            step: STEP,
            shadows,
            ..Default::default()
        };
        let (a, sa) = gpu.render_rbf(&field, &cam, &tf, &prm, &rbf).unwrap();
        let (b, sb) = tight.render_rbf(&field, &cam, &tf, &prm, &rbf).unwrap();
        let what = if rbf.shadows.is_some() {
            "shadows"
        } else {
            "no shadows"
        };
        assert!(a.rgba.iter().any(|q| q[3] > 0.1), "{what}: nothing drawn");
        assert!(
            sb.dispatches > sa.dispatches,
            "{what}: {} and {} dispatches",
            sa.dispatches,
            sb.dispatches
        );
        assert_eq!(a.rgba, b.rgba, "{what}: colours");
        assert_eq!(a.depth, b.depth, "{what}: depths");
        let (c, _) = render_rbf(&field, &cam, &tf, &prm, &rbf).unwrap();
        let (cmp, _) = fluidcast_image::compare(&c, &a, 2e-3).unwrap();
        eprintln!(
            "{what}: GPU vs CPU max {} rmse {}, dispatches {} / {}",
            cmp.max_abs, cmp.rmse, sa.dispatches, sb.dispatches
        );
        assert!(cmp.max_abs <= 2e-3 && cmp.rmse <= 2e-4, "{what}: {cmp:?}");
    }
}
