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
    widened(data_range(particles, kernel, field))
}

/// `range` itself, or a point `lo = hi` widened to `lo ± 0.5` (a colour map needs a span).
pub fn widened((lo, hi): (f64, f64)) -> (f64, f64) {
    if lo < hi {
        (lo, hi)
    } else {
        (lo - 0.5, lo + 0.5)
    }
}

/// [`auto_range`] before a point is widened: what a series' frames unite.
pub fn data_range(particles: &Particles, kernel: Kernel, field: FieldKind) -> (f64, f64) {
    match field {
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
    }
}

/// Why a colour map over `colour` misleads for a frame whose attribute spans `values`, when
/// that range is one value in all but name: within 1 % of its magnitude (or below 1e-30), as a colour map set
/// from a frame where the array is constant is (ParaView widens such a range by a few float
/// steps, so the constant sits at the map's first entry). `None` for a range of real width
/// (what a user chose is theirs) or values it holds.
pub fn single_value_range(values: (f64, f64), colour: (f64, f64)) -> Option<String> {
    let ((lo, hi), (a, b)) = (values, colour);
    let span = b - a;
    // ParaView's widening of 0 is to a denormal float: below any physical width.
    if !(span <= 0.01 * a.abs().max(b.abs()) || span < 1e-30) {
        return None;
    }
    let what = if lo < a - span || hi > b + span {
        format!("this frame's values [{lo:.6}, {hi:.6}] saturate at its ends")
    } else if lo == hi {
        format!(
            "the array is constant ({lo:.6}): every particle takes the map's first entry, \
             transparent where its opacity is 0"
        )
    } else {
        return None;
    };
    Some(format!(
        "the colour map's range [{a:.6}, {b:.6}] is a single value (set from a frame where \
         the array is constant, such as a series' first step at rest): {what}; give it the \
         range over every time step (ParaView: \"Rescale to data range over all timesteps\" \
         in the colour map editor, or RescaleTransferFunctionToDataRangeOverTime() in Python)"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// An n×n×n lattice of spacing `s` from `origin`, radius 2s, value `value(i)`.
    fn lattice(n: usize, s: f32, origin: [f32; 3], value: impl Fn(usize) -> f32) -> Particles {
        let mut positions = Vec::new();
        for i in 0..n * n * n {
            let (x, y, z) = (i % n, (i / n) % n, i / (n * n));
            positions.push([
                origin[0] + x as f32 * s,
                origin[1] + y as f32 * s,
                origin[2] + z as f32 * s,
            ]);
        }
        let m = positions.len();
        Particles {
            positions,
            radii: vec![2.0 * s; m],
            volumes: vec![s * s * s; m],
            masses: vec![s * s * s; m],
            values: (0..m).map(value).collect(),
            skipped_nonfinite: 0,
            notes: Vec::new(),
        }
    }

    #[test]
    fn the_automatic_camera_sees_every_support_and_looks_down_minus_z() {
        let p = lattice(6, 0.1, [1.0, -2.0, 5.0], |_| 1.0);
        let (lo, hi) = p.support_bounds();
        for parallel in [false, true] {
            let c = auto_camera(&p, parallel);
            assert_eq!(c.parallel_projection, parallel);
            let dir = DVec3::from(c.focal_point) - DVec3::from(c.position);
            assert!(
                dir.x.abs() < 1e-9 && dir.y.abs() < 1e-9 && dir.z < 0.0,
                "{dir:?}"
            );
            let f = c.frame(200, 150).unwrap();
            let mut seen = 0;
            for k in 0..8 {
                let corner =
                    [0, 1, 2].map(|a| f64::from(if k >> a & 1 == 1 { hi[a] } else { lo[a] }));
                let (x, y) = f.project(DVec3::from(corner)).unwrap();
                assert!(
                    (0.0..=200.0).contains(&x) && (0.0..=150.0).contains(&y),
                    "{x} {y}"
                );
                // The box fills the view along one axis at least (not a speck).
                seen += usize::from(!(60.0..=140.0).contains(&x) || !(45.0..=105.0).contains(&y));
            }
            assert!(
                seen >= 4,
                "parallel {parallel}: the box is a speck in the view"
            );
        }
    }

    #[test]
    fn the_unit_distance_is_the_diagonal_over_the_cube_root_of_the_count() {
        let p = lattice(8, 0.25, [0.0; 3], |_| 1.0);
        // Supports reach 2 × 0.25 past the lattice's 7 × 0.25 on each side: 2.75 per axis.
        let want = (3.0f64 * 2.75 * 2.75).sqrt() / 8.0;
        assert!(
            (auto_unit_distance(&p) - want).abs() < 1e-6,
            "{}",
            auto_unit_distance(&p)
        );
    }

    #[test]
    fn the_range_is_the_values_or_the_typical_sum_and_a_point_is_widened() {
        let p = lattice(5, 0.1, [0.0; 3], |i| i as f32 * 0.5);
        let (lo, hi) = auto_range(&p, Kernel::CubicSpline, FieldKind::Csph);
        assert_eq!((lo, hi), (0.0, 62.0));
        let c = lattice(5, 0.1, [0.0; 3], |_| 3.0);
        assert_eq!(
            auto_range(&c, Kernel::CubicSpline, FieldKind::Csph),
            (2.5, 3.5)
        );
        // The density's typical sum: below 2000 particles every particle is sampled, so the
        // range ends at the largest sum at a particle (the lattice's middle, about m / V = 1).
        let (lo, hi) = auto_range(&c, Kernel::CubicSpline, FieldKind::Density);
        let at: Vec<[f64; 3]> = c.positions.iter().map(|p| p.map(f64::from)).collect();
        let most = c
            .sample_many(Kernel::CubicSpline, &at)
            .iter()
            .map(|s| s.density)
            .fold(0.0, f64::max);
        assert_eq!((lo, hi), (0.0, most));
        assert!(most > 0.5 && most < 1.5, "{most}");
    }

    #[test]
    fn only_a_single_value_range_that_misleads_is_reported() {
        // ParaView's widening of 0.00981: a few float steps.
        let one = (0.00981, 0.00981 * (1.0 + 65536.0 * f64::from(f32::EPSILON)));
        let out = single_value_range((0.0098, 2.0), one).unwrap();
        assert!(
            out.contains("saturate") && out.contains("over all timesteps"),
            "{out}"
        );
        let pinned = single_value_range((0.00981, 0.00981), one).unwrap();
        assert!(pinned.contains("constant"), "{pinned}");
        let zero = single_value_range((0.0, 0.0), (0.0, 0.0)).unwrap();
        assert!(zero.contains("constant"), "{zero}");
        // ParaView's widening of [0, 0]: 65536 float steps above 0, a denormal.
        let denormal = f64::from(f32::from_bits(65536));
        assert!(single_value_range((0.0, 0.0), (0.0, denormal)).is_some());
        assert!(single_value_range((0.0, 1.5), (0.0, denormal)).is_some());
        // Values it holds, though not one value: nothing to say.
        assert_eq!(single_value_range((0.00981, 0.00982), one), None);
        // A range of real width, however narrow the user chose it: theirs.
        assert_eq!(single_value_range((0.0, 2.0), (0.5, 0.6)), None);
        assert_eq!(single_value_range((990.0, 1010.0), (995.0, 1006.0)), None);
        assert_eq!(single_value_range((0.0, 1.0), (f64::NAN, f64::NAN)), None);
    }
}
