//! What a front-end chooses for a user who did not: the camera, the colour map's range and
//! the opacity unit distance for a set of particles. The CLI and the Python module take
//! them from here, so that their defaults are one.

use fluidcast_sph::{FieldKind, Kernel, Particles};
use fluidcast_view::Camera;

/// The camera that sees every particle's support: vtkRenderer::ResetCamera on the support
/// bounds, looking down -z with y up (parallel projection when `parallel`).
pub fn auto_camera(particles: &Particles, parallel: bool) -> Camera {
    let (lo, hi) = particles.support_bounds();
    let mut c = Camera {
        parallel_projection: parallel,
        ..Default::default()
    };
    c.reset(lo.map(f64::from), hi.map(f64::from));
    c
}

/// The opacity unit distance (world units): the support bounds' diagonal over the cube root
/// of the particle count, about the particle spacing.
pub fn auto_unit_distance(particles: &Particles) -> f64 {
    let (lo, hi) = particles.support_bounds();
    let diag = (0..3)
        .map(|k| f64::from(hi[k] - lo[k]).powi(2))
        .sum::<f64>()
        .sqrt();
    diag / (particles.len() as f64).cbrt()
}

/// The colour map's range for `field`: the attribute's range for CSPH; for sums, 0 up to
/// the typical field magnitude at a particle (a sample of 2000); a point widened to 1.
pub fn auto_range(particles: &Particles, kernel: Kernel, field: FieldKind) -> (f64, f64) {
    let (lo, hi) = match field {
        FieldKind::Csph => {
            let r = particles.value_range();
            (f64::from(r.0), f64::from(r.1))
        }
        _ => {
            let at: Vec<[f64; 3]> = particles
                .positions
                .iter()
                .step_by((particles.len() / 2000).max(1))
                .map(|p| p.map(f64::from))
                .collect();
            let s = particles.sample_many(kernel, &at);
            let v = s.iter().filter_map(|s| s.value(field));
            (0.0, v.fold(0.0, f64::max))
        }
    };
    if lo < hi {
        (lo, hi)
    } else {
        (lo - 0.5, lo + 0.5)
    }
}
