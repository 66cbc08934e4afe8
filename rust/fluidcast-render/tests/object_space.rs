//! The object-space baseline (per-sample gathering from a world-space neighbour grid) takes
//! the reference renderer's samples by another route, so both images must agree: the same
//! oracle as the reference's brute-force test, on three kernels and fields, perspective and
//! parallel, plus an opaque surface that ends the rays.

mod common;
use common::{cloud, cloud_view};
use fluidcast_render::{render_object_space, render_reference, RenderParams};
use fluidcast_sph::{FieldKind, Kernel};

#[test]
fn object_space_equals_reference() {
    let p = cloud(80, 11);
    for (parallel, field, kernel, limit) in [
        (false, FieldKind::Csph, Kernel::CubicSpline, None),
        (true, FieldKind::Sph, Kernel::WendlandC2, None),
        (false, FieldKind::Density, Kernel::Quintic, None),
        (false, FieldKind::Csph, Kernel::WendlandC4, Some(0.5)),
    ] {
        let (cam, tf) = cloud_view(35.0, 20.0, parallel, field);
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
