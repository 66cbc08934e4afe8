//! Cropping rays to a box of world space: the region an MPI rank owns, or a user's crop.

use fluidcast_view::Camera;

use crate::{RenderError, RenderParams};

/// Crops every ray of `params`' image to the world-space box `[lo, hi]` (e.g. the region one
/// MPI rank owns): `depth_near` becomes the view depth where the pixel's ray enters the box
/// and `depth_limit` the smaller of its own value and the depth where the ray leaves (a ray
/// that misses the box composites nothing). Boxes that partition space give rays cut at the
/// same depths on both sides of each shared face (one formula, the same numbers), so their
/// images composited in visibility order equal the image of the whole.
pub fn crop_to_box(
    params: &mut RenderParams,
    camera: &Camera,
    lo: [f64; 3],
    hi: [f64; 3],
) -> Result<(), RenderError> {
    if !(0..3).all(|k| lo[k].is_finite() && hi[k].is_finite() && lo[k] <= hi[k]) {
        return Err(RenderError::CropBox(lo, hi));
    }
    let (w, h) = (params.width, params.height);
    let frame = camera.frame(w, h)?;
    let bounds = [0, 1, 2].map(|k| [lo[k], hi[k]]);
    let n = w as usize * h as usize;
    let (mut near, mut far) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for j in 0..h {
        for i in 0..w {
            let (o, d) = frame.ray(i, j);
            let (z0, z1) = slab(&bounds, o.to_array(), d.to_array()).unwrap_or((0.0, 0.0));
            near.push(z0 as f32);
            far.push((z1 as f32).min(params.depth_limit_at(i, j) as f32));
        }
    }
    params.depth_near = Some(near.into());
    params.depth_limit = Some(far.into());
    Ok(())
}

/// The depth interval (z ≥ 0) of the line `o + z·d` inside the box, if it meets it.
pub(crate) fn slab(bounds: &[[f64; 2]; 3], o: [f64; 3], d: [f64; 3]) -> Option<(f64, f64)> {
    let (mut z0, mut z1) = (0.0f64, f64::INFINITY);
    for k in 0..3 {
        if d[k] == 0.0 {
            if o[k] < bounds[k][0] || o[k] > bounds[k][1] {
                return None;
            }
            continue;
        }
        let (a, b) = ((bounds[k][0] - o[k]) / d[k], (bounds[k][1] - o[k]) / d[k]);
        z0 = z0.max(a.min(b));
        z1 = z1.min(a.max(b));
    }
    (z0 <= z1).then_some((z0, z1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn inside(b: &[[f64; 2]; 3], x: [f64; 3], tol: f64) -> bool {
        (0..3).all(|k| x[k] >= b[k][0] - tol && x[k] <= b[k][1] + tol)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(500))]
        /// `slab` is the part of the ray in front of the eye (z >= 0) inside the box: its ends
        /// lie on the box, points just beyond them outside, and when it finds none no point
        /// of the ray is inside. Directions with zero components (parallel views) included.
        #[test]
        fn slab_is_the_rays_part_inside_the_box(
            lo in prop::array::uniform3(-2.0f64..1.0),
            size in prop::array::uniform3(0.1f64..2.0),
            o in prop::array::uniform3(-3.0f64..3.0),
            d in prop::array::uniform3(-1.0f64..1.0),
            zero in prop::array::uniform3(any::<bool>()),
        ) {
            let b = [0, 1, 2].map(|k| [lo[k], lo[k] + size[k]]);
            let d = [0, 1, 2].map(|k| if zero[k] { 0.0 } else { d[k] });
            prop_assume!(d.iter().any(|&v| v.abs() > 0.05));
            let at = |z: f64| [0, 1, 2].map(|k| o[k] + z * d[k]);
            match slab(&b, o, d) {
                Some((z0, z1)) => {
                    prop_assert!(0.0 <= z0 && z0 <= z1);
                    for f in [0.0, 0.5, 1.0] {
                        prop_assert!(inside(&b, at(z0 + f * (z1 - z0)), 1e-9));
                    }
                    let step = 1e-3;
                    if z0 > step {
                        prop_assert!(!inside(&b, at(z0 - step), 0.0), "before {}", z0);
                    }
                    prop_assert!(!inside(&b, at(z1 + step), 0.0), "after {}", z1);
                }
                None => {
                    for i in 0..=4000 {
                        prop_assert!(!inside(&b, at(i as f64 * 0.01), -1e-9), "at {}", i);
                    }
                }
            }
        }
    }
}
