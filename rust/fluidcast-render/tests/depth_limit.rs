//! Rays stop at opaque geometry: `RenderParams::depth_limit`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;
use std::sync::Arc;

use common::{cloud, composite_under, max_channel_diff, slab, slab_scene};
use fluidcast_render::{render_adaptive, render_reference, PlanParams, RenderParams};
use fluidcast_view::{Camera, TransferFunction};

fn renders(
    p: &fluidcast_sph::Particles,
    cam: &Camera,
    tf: &TransferFunction,
    prm: &RenderParams,
) -> Vec<(&'static str, fluidcast_image::Image)> {
    let off = RenderParams {
        adaptive: PlanParams {
            tolerance: None,
            ..Default::default()
        },
        ..prm.clone()
    };
    let strict = RenderParams {
        adaptive: PlanParams::default().strict(),
        ..prm.clone()
    };
    vec![
        ("reference", render_reference(p, cam, tf, prm).unwrap().0),
        (
            "adaptive off",
            render_adaptive(p, None, cam, tf, &off).unwrap().image,
        ),
        (
            "adaptive strict",
            render_adaptive(p, None, cam, tf, &strict).unwrap().image,
        ),
    ]
}

#[test]
fn slab_cut_by_a_plane_has_the_closed_form_transmittance() {
    // The slab's medium spans view depths 2.5 .. 3.1 on the central rays; an opaque plane at
    // view depth 2.8 leaves 0.3 of it: T = exp(-σ · 0.3).
    let p = slab(9);
    let (cam, tf, sigma) = slab_scene();
    for (limit, front) in [(2.8f32, 0.3), (2.0, 0.0), (2.5, 0.0), (f32::INFINITY, 0.6)] {
        let prm = RenderParams {
            width: 2,
            height: 2,
            sampling_scale: 10.0,
            min_transmittance: 0.0,
            depth_limit: Some(Arc::from(vec![limit; 4])),
            ..Default::default()
        };
        let expected = (-sigma * front).exp();
        for (name, img) in renders(&p, &cam, &tf, &prm) {
            let t = 1.0 - img.rgba[0][3] as f64;
            // The strict plan may differ from full rate by its tolerance E_I = 0.004.
            let tol = if name == "adaptive strict" {
                5e-3
            } else {
                1e-3
            };
            assert!(
                (t - expected).abs() < tol,
                "{name}, plane at {limit}: T = {t}, expected {expected}"
            );
        }
    }
}

/// 3000 particles of [`cloud`] seen from (0.3, 0.4, 2.2), Viridis over -0.5..1.
fn cloud_scene() -> (fluidcast_sph::Particles, Camera, TransferFunction) {
    let cam = Camera {
        position: [0.3, 0.4, 2.2],
        focal_point: [0.0; 3],
        view_up: [0.0, 1.0, 0.0],
        ..Default::default()
    };
    let mut tf = TransferFunction::preset("viridis")
        .unwrap()
        .with_range(-0.5, 1.0)
        .unwrap();
    tf.unit_distance = 0.2;
    (cloud(3000, 5), cam, tf)
}

#[test]
fn per_pixel_limit_off_equals_reference_and_infinity_changes_nothing() {
    let (p, cam, tf) = cloud_scene();
    let (w, h) = (64u32, 48u32);
    // A tilted plane cutting through the cloud (view depths 1.8 .. 2.6) and a hole with no
    // geometry.
    let limit: Vec<f32> = (0..h)
        .flat_map(|j| (0..w).map(move |i| (i, j)))
        .map(|(i, j)| {
            if i < 8 && j < 8 {
                f32::INFINITY
            } else {
                1.8 + 0.8 * (i as f32 / w as f32)
            }
        })
        .collect();
    let base = RenderParams {
        width: w,
        height: h,
        ..Default::default()
    };
    let cut = RenderParams {
        depth_limit: Some(Arc::from(limit)),
        ..base.clone()
    };
    let r = renders(&p, &cam, &tf, &cut);
    let diff = |a: &fluidcast_image::Image, b: &fluidcast_image::Image| {
        fluidcast_image::compare(a, b, 1e-5).unwrap().0.max_abs
    };
    assert!(diff(&r[0].1, &r[1].1) <= 1e-5, "adaptive off vs reference");
    assert!(
        diff(&r[0].1, &r[2].1) <= 0.004 + 1e-4,
        "strict vs reference"
    );
    // The cut removes something, and pixels without geometry equal the uncut image.
    let full = render_reference(&p, &cam, &tf, &base).unwrap().0;
    assert!(diff(&full, &r[0].1) > 0.05, "the plane hides nothing");
    for j in 0..8 {
        for i in 0..8 {
            let k = full.index(i, j);
            assert_eq!(full.rgba[k], r[0].1.rgba[k]);
        }
    }
    let inf = RenderParams {
        depth_limit: Some(Arc::from(vec![f32::INFINITY; (w * h) as usize])),
        ..base.clone()
    };
    assert_eq!(render_reference(&p, &cam, &tf, &inf).unwrap().0, full);
}

#[test]
fn bad_depth_limits_are_errors() {
    let p = cloud(10, 1);
    let tf = TransferFunction::preset("viridis").unwrap();
    let cam = Camera::default();
    for (limit, msg) in [(vec![1.0f32; 3], "3 values"), (vec![f32::NAN; 4], "NaN")] {
        let prm = RenderParams {
            width: 2,
            height: 2,
            depth_limit: Some(Arc::from(limit)),
            ..Default::default()
        };
        let e = render_reference(&p, &cam, &tf, &prm)
            .unwrap_err()
            .to_string();
        assert!(e.contains(msg), "{e}");
        let e = render_adaptive(&p, None, &cam, &tf, &prm)
            .unwrap_err()
            .to_string();
        assert!(e.contains(msg), "{e}");
    }
}

/// `bundle_stops` holds, per bundle, the nearest depth limit over exactly the pixels the grid
/// gives that bundle (edge bundles cut at the image's border).
#[test]
fn bundle_stops_are_the_nearest_limit_of_each_bundles_pixels() {
    let p = cloud(200, 5);
    let (cam, tf) = common::cloud_view(20.0, 10.0, false, fluidcast_sph::FieldKind::Csph);
    for (w, h, d) in [(37u32, 23u32, 8u32), (16, 16, 4), (9, 30, 5)] {
        let limit: Vec<f32> = (0..w * h)
            .map(|k| 1.0 + ((k * 7919) % 113) as f32)
            .collect();
        let prm = RenderParams {
            width: w,
            height: h,
            grid: fluidcast_render::GridParams {
                bundle: d,
                depth_samples: 16,
            },
            depth_limit: Some(Arc::from(limit.clone())),
            ..Default::default()
        };
        let stops = prm.bundle_stops().unwrap();
        let plan = fluidcast_render::plan_adaptive(&p, None, &cam, &tf, &prm).unwrap();
        assert_eq!(stops.len(), plan.grid.bundle_count());
        for (b, &s) in stops.iter().enumerate() {
            let [x0, x1, y0, y1] = plan.grid.bundle(b).pixels;
            let limit = &limit;
            let want = (y0..y1)
                .flat_map(|j| (x0..x1).map(move |i| limit[(j * w + i) as usize]))
                .fold(f32::INFINITY, f32::min);
            assert_eq!(s, want as f64, "{w}x{h}, bundle {b}");
        }
        let none = RenderParams {
            depth_limit: None,
            ..prm
        };
        assert!(none.bundle_stops().is_none());
    }
}

/// `depth_near` with `depth_limit` crops each ray to a depth interval: the images of
/// intervals that partition every ray (here three, cut by two tilted planes that fall inside
/// sampling steps), composited front to back, equal the uncropped image. This is what MPI
/// ranks owning boxes of space rely on.
#[test]
fn depth_intervals_composited_in_order_equal_the_whole_ray() {
    let (p, cam, tf) = cloud_scene();
    let (w, h) = (40u32, 30u32);
    let plane = |z0: f32, dz: f32| -> Arc<[f32]> {
        (0..h)
            .flat_map(|j| (0..w).map(move |i| z0 + dz * (i + j) as f32 / (w + h) as f32))
            .collect()
    };
    let (s1, s2) = (plane(1.9, 0.3), plane(2.25, 0.1));
    // No early ray termination: a back region cannot know how opaque the front ones are.
    let base = RenderParams {
        width: w,
        height: h,
        min_transmittance: 0.0,
        ..Default::default()
    };
    let region = |near: Option<&Arc<[f32]>>, far: Option<&Arc<[f32]>>| RenderParams {
        depth_near: near.cloned(),
        depth_limit: far.cloned(),
        ..base.clone()
    };
    let parts = [
        region(None, Some(&s1)),
        region(Some(&s1), Some(&s2)),
        region(Some(&s2), None),
    ];
    let whole = renders(&p, &cam, &tf, &base);
    let split: Vec<_> = parts
        .iter()
        .map(|prm| renders(&p, &cam, &tf, prm))
        .collect();
    for (r, (name, whole)) in whole.iter().enumerate() {
        let mut over = vec![[0.0f32; 4]; whole.rgba.len()];
        for part in &split {
            let img = &part[r].1;
            assert!(
                img.rgba.iter().any(|px| px[3] > 0.05),
                "{name}: a region is empty"
            );
            composite_under(&mut over, &img.rgba);
        }
        let max = max_channel_diff(&over, &whole.rgba);
        // Each strict region is within E_I = 0.004 of full rate, as the whole is.
        let tol = if *name == "adaptive strict" {
            0.013
        } else {
            2e-6
        };
        assert!(max <= tol, "{name}: composited regions differ by {max}");
    }
}
