//! The object-space baseline: each ray samples the reference renderer's depths and evaluates
//! the field at every sample point by gathering the particles around it from a uniform
//! world-space neighbour grid (per-sample gathering, the comparison of Hochstetter et al.
//! 2016, Sec. 6). No view-aligned grid, no sampling plan: what `fluidcast bench` measures
//! the grid renderer against. It takes the same samples as [`crate::render_reference`], so
//! its images equal the reference's.

use std::time::Instant;

use fluidcast_grid::SampleDepths;
use fluidcast_image::Image;
use fluidcast_sph::{NeighbourGrid, Particles};
use fluidcast_view::{Camera, TfLookup, TransferFunction, ViewFrame};
use rayon::prelude::*;

use crate::raycast::Compositor;
use crate::reference::RayView;
use crate::{ms, RenderError, RenderParams, RenderStats};

/// One image row: (premultiplied RGBA, depth) per pixel, samples taken.
type Row = (Vec<([f32; 4], f32)>, u64);

/// Renders `particles` by per-sample gathering (see the module documentation).
pub fn render_object_space(
    particles: &Particles,
    camera: &Camera,
    tf: &TransferFunction,
    params: &RenderParams,
) -> Result<(Image, RenderStats), RenderError> {
    let t0 = Instant::now();
    crate::refuse_surfaces(params, "the object-space renderer")?;
    let (w, h) = (params.width, params.height);
    let RayView {
        frame,
        mut stats,
        mut image,
        depths,
        ..
    } = RayView::new(particles, camera, params)?;
    stats.particles_visible = particles.len();
    let Some(depths) = depths else {
        stats.stages.push(("total", ms(t0)));
        return Ok((image, stats));
    };
    let scene = Gather {
        particles,
        grid: particles.neighbour_grid(),
        bounds: support_bounds(particles),
        frame: &frame,
        depths: &depths,
        tf: TfLookup::new(tf),
        params,
    };
    stats.stages.push(("grid", ms(t0)));

    let t1 = Instant::now();
    let rows: Vec<Row> = (0..h)
        .into_par_iter()
        .map(|j| {
            let pixels = (0..w).map(|i| {
                let c = scene.cast(i, j);
                (c.pixel(), c.samples)
            });
            let (px, n): (Vec<_>, Vec<u64>) = pixels.unzip();
            (px, n.iter().sum())
        })
        .collect();
    for (j, (px, n)) in rows.into_iter().enumerate() {
        stats.samples += n;
        for (i, (rgba, depth)) in px.into_iter().enumerate() {
            let idx = image.index(i as u32, j as u32);
            image.rgba[idx] = rgba;
            image.depth[idx] = depth;
        }
    }
    stats.stages.push(("raycast", ms(t1)));
    stats.stages.push(("total", ms(t0)));
    Ok((image, stats))
}

/// World-space box holding every particle's support: `[min, max]` per axis.
fn support_bounds(particles: &Particles) -> [[f64; 2]; 3] {
    let h = particles.max_radius() as f64;
    let mut b = [[f64::INFINITY, f64::NEG_INFINITY]; 3];
    for p in &particles.positions {
        for k in 0..3 {
            b[k][0] = b[k][0].min(p[k] as f64 - h);
            b[k][1] = b[k][1].max(p[k] as f64 + h);
        }
    }
    b
}

/// What every ray of a view gathers from.
struct Gather<'a> {
    particles: &'a Particles,
    grid: NeighbourGrid<'a>,
    /// World-space box of every support, `[min, max]` per axis.
    bounds: [[f64; 2]; 3],
    frame: &'a ViewFrame,
    depths: &'a SampleDepths,
    tf: TfLookup<'a>,
    params: &'a RenderParams,
}

impl Gather<'_> {
    /// The ray through pixel (i, j): every sample depth inside the support box, the field
    /// gathered there.
    fn cast(&self, i: u32, j: u32) -> Compositor {
        let (o, d) = self.frame.ray(i, j);
        let (o, d) = (o.to_array(), d.to_array());
        let dlen = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let prm = self.params;
        let mut comp = Compositor::for_pixel(prm, i, j);
        let Some((z0, z1)) = crate::crop::slab(&self.bounds, o, d) else {
            return comp;
        };
        let z = &self.depths.z;
        for k in self.depths.indices_within(z0, z1) {
            let x = [0, 1, 2].map(|a| o[a] + z[k] * d[a]);
            let s = self.particles.sample(&self.grid, prm.kernel, x);
            // As the other renderers: no sample where no particle reaches.
            if s.shepard > 0.0 {
                if let Some(q) = s.value(prm.field) {
                    comp.sample(&self.tf, q, (z[k], z[k + 1]), dlen, prm.min_transmittance);
                }
            }
            if comp.done {
                break;
            }
        }
        comp
    }
}
