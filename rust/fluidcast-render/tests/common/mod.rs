//! Scene generators shared by the render tests.
#![allow(dead_code)]

use fluidcast_sph::{FieldKind, Particles};
use fluidcast_view::{Camera, TransferFunction};

#[allow(unused_imports)]
pub use fluidcast_testkit::rng;

/// `n` random particles in the unit cube around the origin, with varied radii (0.15–0.25)
/// and volumes and the smooth attribute x + 2y².
pub fn cloud(n: usize, seed: u32) -> Particles {
    fluidcast_testkit::cloud(n, seed, (0.15, 0.1))
}

/// The view of [`cloud`] the renderer-vs-renderer tests use: the cube from an azimuth and
/// elevation (degrees), perspective or parallel, and Viridis over a range that suits the
/// field kind, with opacity unit distance 0.3.
pub fn cloud_view(
    azimuth: f64,
    elevation: f64,
    parallel: bool,
    field: FieldKind,
) -> (Camera, TransferFunction) {
    let mut cam = Camera::default();
    cam.reset([-0.7; 3], [0.7; 3]);
    cam.azimuth(azimuth);
    cam.elevation(elevation);
    cam.parallel_projection = parallel;
    let (lo, hi) = match field {
        FieldKind::Density => (0.0, 800.0),
        FieldKind::Sph => (0.0, 0.2),
        FieldKind::Csph => (-0.5, 1.0),
    };
    let mut tf = TransferFunction::preset("viridis")
        .unwrap()
        .with_range(lo, hi)
        .unwrap();
    tf.unit_distance = 0.3;
    (cam, tf)
}

/// A lattice slab of (2·6+1)² × `nz` particles, spacing 0.05, support radius 0.1, value 0.7,
/// filling z = 0 .. (nz−1)·0.05. The CSPH field is exactly 0.7 wherever a particle reaches:
/// on the central ray from z = −0.1 to (nz−1)·0.05 + 0.1.
pub fn slab(nz: usize) -> Particles {
    let (spacing, h) = (0.05f32, 0.1f32);
    let mut p = Particles::default();
    for i in -6..=6 {
        for j in -6..=6 {
            for k in 0..nz {
                p.positions
                    .push([i as f32 * spacing, j as f32 * spacing, k as f32 * spacing]);
                p.radii.push(h);
                p.volumes.push(spacing.powi(3));
                p.masses.push(1.0);
                p.values.push(0.7);
            }
        }
    }
    p
}

/// A parallel camera looking down −z at the slab's central rays (view depth 2.5 .. 3.1 for
/// `slab(9)`), and a grey transfer function with constant opacity 0.4 per 0.25 world units;
/// also returns the extinction σ = −ln(1 − 0.4)/0.25.
pub fn slab_scene() -> (Camera, TransferFunction, f64) {
    let cam = Camera {
        position: [0.0, 0.0, 3.0],
        focal_point: [0.0; 3],
        view_up: [0.0, 1.0, 0.0],
        parallel_projection: true,
        parallel_scale: 0.002,
        ..Default::default()
    };
    let alpha = 0.4;
    let mut tf = TransferFunction::preset("grayscale")
        .unwrap()
        .with_range(0.0, 1.0)
        .unwrap();
    tf.opacity = vec![(0.0, alpha), (1.0, alpha)];
    tf.unit_distance = 0.25;
    let sigma = -(1.0f64 - alpha).ln() / tf.unit_distance;
    (cam, tf, sigma)
}

/// Premultiplied `part` composited under what `over` holds (front to back): what ordered
/// compositing of regions' images does.
pub fn composite_under(over: &mut [[f32; 4]], part: &[[f32; 4]]) {
    for (o, px) in over.iter_mut().zip(part) {
        let t = 1.0 - o[3];
        for c in 0..4 {
            o[c] += t * px[c];
        }
    }
}

/// The largest difference of any channel of any pixel.
pub fn max_channel_diff(a: &[[f32; 4]], b: &[[f32; 4]]) -> f32 {
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| (0..4).map(move |c| (x[c] - y[c]).abs()))
        .fold(0.0f32, f32::max)
}
