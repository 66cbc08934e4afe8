//! A cut rendered against full detail: on particles about a pixel apart, a cut at a few
//! pixels renders a fraction of the particles to nearly the same image (the renderer is the
//! oracle's, the hierarchy shares no code with it).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly

use fluidcast_image::compare;
use fluidcast_lod::LodHierarchy;
use fluidcast_render::{render_adaptive, RenderParams};
use fluidcast_sph::Particles;
use fluidcast_testkit::rng;
use fluidcast_view::{Camera, TransferFunction};

/// A jittered `n`³ lattice of spacing `s` (support 2 spacings, volume and mass one cell),
/// valued by a smooth function of position.
fn block(n: usize, s: f32) -> Particles {
    let mut rnd = rng(21);
    let mut p = Particles::default();
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                let x = [i, j, k].map(|c| (c as f32 + 0.3 * (rnd() - 0.5)) * s);
                p.positions.push(x);
                p.radii.push(2.0 * s);
                p.volumes.push(s * s * s);
                p.masses.push(s * s * s);
                p.values.push((6.0 * x[0]).sin() + 4.0 * x[1] * x[2]);
            }
        }
    }
    p
}

#[test]
fn a_cut_renders_fewer_particles_to_nearly_the_same_image() {
    let (n, s) = (40, 0.01);
    let h = LodHierarchy::build(block(n, s)).unwrap();
    let full = h.full_detail();
    let size = 64;
    let params = RenderParams {
        width: size,
        height: size,
        ..RenderParams::default()
    };
    let mut tf = TransferFunction::preset("viridis")
        .unwrap()
        .with_range(-1.0, 1.5)
        .unwrap();
    tf.unit_distance = 0.1;
    for (az, el) in [(30.0, 20.0), (-110.0, -35.0)] {
        let mut cam = Camera::default();
        let e = (n - 1) as f64 * f64::from(s);
        cam.reset([0.0; 3], [e; 3]);
        cam.azimuth(az);
        cam.elevation(el);
        cam.orthogonalize_view_up();
        let frame = cam.frame(size, size).unwrap();
        let spacing_px =
            f64::from(s) / frame.pixel_size_at(frame.to_view(glam::DVec3::splat(e / 2.0)).z);
        assert!(spacing_px < 1.0, "particles {spacing_px} px apart");
        let want = render_adaptive(full, None, &cam, &tf, &params).unwrap();
        let c = h.cut(&frame, 4.0).unwrap();
        assert!(
            c.particles.len() * 3 < full.len(),
            "{} of {} particles",
            c.particles.len(),
            full.len()
        );
        let got = render_adaptive(&c.particles, None, &cam, &tf, &params).unwrap();
        let (e, _) = compare(&want.image, &got.image, 1.0 / 255.0).unwrap();
        eprintln!(
            "azimuth {az}: {} of {} particles, {e:?}",
            c.particles.len(),
            full.len()
        );
        // Measured: RMSE 5e-4 and 3e-4, at most 1/255. Merging at the edge of the block
        // gives RMSE 0.063; supports a quarter larger than the cover, 0.03 in one pixel.
        assert!(e.rmse <= 0.002, "RMSE {} against full detail", e.rmse);
        assert!(
            e.max_abs <= 1.5 / 255.0,
            "{} against full detail",
            e.max_abs
        );
    }
}
