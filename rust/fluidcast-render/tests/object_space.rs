//! The object-space baseline (per-sample gathering from a world-space neighbour grid) takes
//! the reference renderer's samples by another route, so both images must agree: the same
//! oracle as the reference's brute-force test, on three kernels and fields, perspective and
//! parallel, plus an opaque surface that ends the rays, and the scene moved into the positive
//! octant, where simulation domains usually lie (no coordinate near or below 0).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly

mod common;
use common::{cloud, cloud_view};
use fluidcast_render::{render_object_space, render_reference, RenderParams};
use fluidcast_sph::{FieldKind, Kernel};

#[test]
fn object_space_equals_reference() {
    for (parallel, field, kernel, limit, shift) in [
        (false, FieldKind::Csph, Kernel::CubicSpline, None, [0.0; 3]),
        (true, FieldKind::Sph, Kernel::WendlandC2, None, [0.0; 3]),
        (false, FieldKind::Density, Kernel::Quintic, None, [0.0; 3]),
        (
            false,
            FieldKind::Csph,
            Kernel::WendlandC4,
            Some(0.5),
            [0.0; 3],
        ),
        (
            false,
            FieldKind::Csph,
            Kernel::CubicSpline,
            None,
            [1.5, 2.0, 0.8],
        ),
    ] {
        let mut p = cloud(80, 11);
        for x in &mut p.positions {
            *x = [0, 1, 2].map(|k| x[k] + shift[k] as f32);
        }
        let (mut cam, tf) = cloud_view(35.0, 20.0, parallel, field);
        cam.position = [0, 1, 2].map(|k| cam.position[k] + shift[k]);
        cam.focal_point = [0, 1, 2].map(|k| cam.focal_point[k] + shift[k]);
        let (w, h) = (32, 24);
        let mut prm = RenderParams {
            width: w,
            height: h,
            kernel,
            field,
            ..Default::default()
        };
        // `limit`: an opaque surface at that fraction of the particles' depth range.
        let (mut want, s) = render_reference(&p, &cam, &tf, &prm).unwrap();
        if let Some(f) = limit {
            let z = (s.near + f * (s.far - s.near)) as f32;
            prm.depth_limit = Some(vec![z; (w * h) as usize].into());
            want = render_reference(&p, &cam, &tf, &prm).unwrap().0;
        }
        let (got, stats) = render_object_space(&p, &cam, &tf, &prm).unwrap();
        let max = want
            .rgba
            .iter()
            .zip(&got.rgba)
            .flat_map(|(a, b)| (0..4).map(move |k| (a[k] - b[k]).abs()))
            .fold(0.0f32, f32::max);
        assert!(
            max < 1e-5,
            "parallel={parallel} {field:?} {kernel}: max abs {max}"
        );
        assert!(
            got.rgba.iter().any(|p| p[3] > 0.05),
            "{field:?} {limit:?}: nothing rendered"
        );
        assert!(stats.samples > 0);
    }
}
