//! Why two renderings of one plan may differ where one sums in single precision: the
//! grid renderer's span loop (f32) against the reference (f64), or the GPU against the CPU.
//! Tests use it to tell rounding from bugs: every pixel that differs must be explained.

use fluidcast_image::Image;
use fluidcast_sph::Kernel;
use fluidcast_view::TransferFunction;

use crate::AdaptivePlan;

/// Why a pixel may differ between a single- and a double-precision rendering, found by
/// recasting its ray in f64 over the plan (an oracle that shares no code with either
/// renderer's inner loop):
/// * an *edge sample*: every particle that reaches the sample lies within 1e-4 H of its
///   support's edge. Shepard normalisation gives such a sample the particles' full value
///   however small their weight, and f32 rounding (~1e-5 H at view depths of a few support
///   radii) decides whether it exists at all;
/// * an *opaque sample*: the transfer function's opacity above 0.999, where the step alpha
///   1 − (1 − α)^(Δs/u) has unbounded slope, so the f32 value's last bits show.
///
/// Returns (edge, opaque) for pixel (i, j).
pub fn f32_explanation(
    planned: &AdaptivePlan,
    tf: &TransferFunction,
    kernel: Kernel,
    i: u32,
    j: u32,
) -> (bool, bool) {
    let g = &planned.grid;
    let Some(depths) = &g.depths else {
        return (false, false);
    };
    let dz = g.params.depth_samples as usize;
    let b = fluidcast_grid::bundle_of(g.frame.width, g.params.bundle, i, j);
    let ray = fluidcast_grid::Ray::through_pixel(&g.frame, i, j);
    let (mut edge, mut opaque) = (false, false);
    for s in planned.plan.bundle_spans(b) {
        let cells = &g.cells[s.first as usize..(s.first + s.count) as usize];
        let refs: Vec<u32> = g.merged_refs(cells).collect();
        let k0 = cells[0].z as usize * dz;
        for m in (0..dz * s.count as usize).step_by(1 << s.level) {
            let z = depths.z[k0 + m];
            let (mut inner, mut at_edge, mut ws, mut wq) = (0, 0, 0.0, 0.0);
            for &r in &refs {
                let p = &g.particles[r as usize];
                let d = ray.distance_at(z, p);
                let q = d / p.h();
                if q < 1.0 - 1e-4 {
                    inner += 1;
                } else if q < 1.0 + 1e-4 {
                    at_edge += 1;
                }
                let w = kernel.eval(d, p.h());
                ws += p.v() * w;
                wq += p.v() * p.a() * w;
            }
            edge |= inner == 0 && at_edge > 0;
            opaque |= ws > 0.0 && tf.eval(wq / ws).1 > 0.999;
        }
    }
    (edge, opaque)
}

/// Pixels where the images differ by more than 1e-3 in any channel, as (i, j).
pub fn differing_pixels(a: &Image, b: &Image) -> Vec<(u32, u32)> {
    a.rgba
        .iter()
        .zip(&b.rgba)
        .enumerate()
        .filter(|(_, (p, q))| (0..4).any(|c| (p[c] - q[c]).abs() > 1e-3))
        .map(|(k, _)| (k as u32 % a.width, k as u32 / a.width))
        .collect()
}
