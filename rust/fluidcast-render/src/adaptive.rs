use std::borrow::Cow;
use std::time::Instant;

use fluidcast_grid::{PerspectiveGrid, Ray, ViewParticle};
use fluidcast_image::Image;
use fluidcast_plan::{BundleSummary, FieldParams, PlanParams, SamplingPlan};
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, TransferFunction};
use rayon::prelude::*;

use crate::raycast::{Compositor, Sums};
use crate::{ms, validate, RenderError, RenderParams, RenderStats};

/// Neighbour-count ratio below which a particle counts as a surface particle (see
/// [`Particles::surface_flags`]).
pub const SURFACE_THRESHOLD: f64 = 0.75;

/// The result of the grid renderer: the image (with AOVs `error_bound`, `level` and
/// `superpixel`, per pixel from its bundle), stage timings, and the grid and plan it used.
#[derive(Debug, Clone)]
pub struct AdaptiveRender {
    pub image: Image,
    pub stats: RenderStats,
    pub grid: PerspectiveGrid,
    pub plan: SamplingPlan,
}

/// One bundle's output: bundle index, (premultiplied RGBA, depth) per pixel, samples taken.
type BundleResult = (usize, Vec<([f32; 4], f32)>, u64);

/// The surface flags a plan gets: those given, else, when the plan uses the surface rule
/// ([`PlanParams::uses_surface_cells`]), computed with [`SURFACE_THRESHOLD`]; `None` otherwise.
/// Shared by the CPU and GPU planners so that both see the same flags.
pub fn plan_surface<'a>(
    particles: &Particles,
    given: Option<&'a [bool]>,
    adaptive: &PlanParams,
) -> Option<Cow<'a, [bool]>> {
    match given {
        Some(s) => Some(Cow::Borrowed(s)),
        None if adaptive.uses_surface_cells() => {
            Some(Cow::Owned(particles.surface_flags(SURFACE_THRESHOLD)))
        }
        None => None,
    }
}

/// The first two stages of the adaptive renderer for one view: the sparse perspective grid and
/// the sampling plan, with their timings (`grid`, `adapt`) in `stats`. The ray casting stage
/// ([`render_adaptive`] on the CPU, `fluidcast-gpu` on the GPU) consumes it.
#[derive(Debug, Clone)]
pub struct AdaptivePlan {
    pub grid: PerspectiveGrid,
    pub plan: SamplingPlan,
    pub stats: RenderStats,
}

/// Builds the grid and the sampling plan (see [`AdaptivePlan`]); `surface` as for
/// [`render_adaptive`].
pub fn plan_adaptive(
    particles: &Particles,
    surface: Option<&[bool]>,
    camera: &Camera,
    tf: &TransferFunction,
    params: &RenderParams,
) -> Result<AdaptivePlan, RenderError> {
    let t0 = Instant::now();
    validate(params)?;
    let (w, h) = (params.width, params.height);
    let frame = camera.frame(w, h)?;
    let grid = PerspectiveGrid::build(particles, &frame, params.grid, params.sampling_scale)?;
    let mut stats = RenderStats {
        particles: particles.len(),
        particles_visible: grid.particles_visible,
        width: w,
        height: h,
        bundles: grid.bundle_count() as u64,
        cells: grid.cells.len() as u64,
        pairs: grid.pairs() as u64,
        ..Default::default()
    };
    if let Some(d) = &grid.depths {
        stats.depth_samples = d.len();
        stats.near = d.near;
        stats.far = d.far;
    }
    stats.stages.push(("grid", ms(t0)));

    let t1 = Instant::now();
    let a = &params.adaptive;
    let surface = plan_surface(particles, surface, a);
    let field = FieldParams {
        kernel: params.kernel,
        field: params.field,
        min_transmittance: params.min_transmittance,
    };
    let plan = SamplingPlan::build(&grid, tf, surface.as_deref(), a, &field)?;
    stats.plan = Some(plan.stats.clone());
    stats.stages.push(("adapt", ms(t1)));
    Ok(AdaptivePlan { grid, plan, stats })
}

/// Renders with the adaptive grid renderer (Hochstetter et al. 2016): grid, sampling plan
/// for `params.adaptive` (no error tolerance: every cell at full rate), bundle-coherent ray
/// casting. `surface` flags surface particles; `None` computes them when the surface test is
/// on (pass them to avoid recomputing for many views of one frame).
pub fn render_adaptive(
    particles: &Particles,
    surface: Option<&[bool]>,
    camera: &Camera,
    tf: &TransferFunction,
    params: &RenderParams,
) -> Result<AdaptiveRender, RenderError> {
    let t0 = Instant::now();
    let AdaptivePlan {
        grid,
        plan,
        mut stats,
    } = plan_adaptive(particles, surface, camera, tf, params)?;
    let frame = grid.frame;
    let (w, h) = (params.width, params.height);

    let t2 = Instant::now();
    let mut image = Image::new(w, h);
    if let Some(depths) = &grid.depths {
        let dz = grid.params.depth_samples as usize;
        let results: Vec<BundleResult> = (0..grid.bundle_count())
            .into_par_iter()
            .filter(|&b| !grid.bundle_cells(b).is_empty())
            .map_init(
                || (Sums::new(dz), Vec::<ViewParticle>::new()),
                |(sums, local), b| {
                    let bd = grid.bundle(b);
                    let [x0, x1, y0, y1] = bd.pixels;
                    let pixels = (y0..y1).flat_map(|j| (x0..x1).map(move |i| (i, j)));
                    let rays: Vec<Ray> = pixels
                        .clone()
                        .map(|(i, j)| Ray::through_pixel(&frame, i, j))
                        .collect();
                    let mut comps: Vec<Compositor> = pixels
                        .map(|(i, j)| Compositor::new(params.depth_limit_at(i, j)))
                        .collect();
                    let mut zs = [0.0f64; 65];
                    for span in plan.bundle_spans(b) {
                        if comps.iter().all(|c| c.done) {
                            break;
                        }
                        let first = span.first as usize;
                        let k0 = grid.cells[first].z as usize * dz;
                        if let Some(sp) = span.superpixel {
                            let it = sp.map(f64::from);
                            let z = (depths.z[k0], depths.z[k0 + span.count as usize * dz]);
                            for c in comps.iter_mut().filter(|c| !c.done) {
                                c.add(it, z, params.min_transmittance);
                            }
                            continue;
                        }
                        // Alg. 2: every ray of the bundle samples the same particles, at
                        // D_z positions spaced 2^level samples apart.
                        let step = 1usize << span.level;
                        let n = span.count as usize * dz / step;
                        for (m, z) in zs[..=n].iter_mut().enumerate() {
                            *z = depths.z[k0 + m * step];
                        }
                        let cells = &grid.cells[first..first + span.count as usize];
                        local.clear();
                        local.extend(grid.merged_refs(cells).map(|j| grid.particles[j as usize]));
                        for (ray, c) in rays.iter().zip(comps.iter_mut()) {
                            if c.done {
                                continue;
                            }
                            let (lo, hi) = local
                                .iter()
                                .filter_map(|p| sums.scatter(ray, p, &zs[..n], params.kernel))
                                .fold((usize::MAX, 0), |(a, b), r| (a.min(r.start), b.max(r.end)));
                            for m in lo..hi {
                                if let Some(q) = sums.value(m, params.field) {
                                    let z = (zs[m], zs[m + 1]);
                                    c.sample(tf, q, z, ray.dlen, params.min_transmittance);
                                    if c.done {
                                        break;
                                    }
                                }
                            }
                            if lo < hi {
                                sums.clear(lo..hi);
                            }
                        }
                    }
                    let samples = comps.iter().map(|c| c.samples).sum();
                    (b, comps.iter().map(Compositor::pixel).collect(), samples)
                },
            )
            .collect();
        for (b, px, n) in results {
            stats.samples += n;
            let [x0, x1, y0, y1] = grid.bundle(b).pixels;
            let mut k = 0;
            for j in y0..y1 {
                for i in x0..x1 {
                    let idx = image.index(i, j);
                    image.rgba[idx] = px[k].0;
                    image.depth[idx] = px[k].1;
                    k += 1;
                }
            }
        }
    }
    stats.stages.push(("raycast", ms(t2)));
    image.aovs = plan_aovs(&grid, &plan, image.width, image.height);
    stats.stages.push(("total", ms(t0)));
    Ok(AdaptiveRender {
        image,
        stats,
        grid,
        plan,
    })
}

/// The plan's per-pixel diagnostics (`error_bound`, `level`, `superpixel`, each from the
/// pixel's bundle), as image AOVs; empty without a plan.
pub fn plan_aovs(
    grid: &PerspectiveGrid,
    plan: &SamplingPlan,
    width: u32,
    height: u32,
) -> Vec<(String, Vec<f32>)> {
    bundle_aovs(&plan.summaries, grid.params.bundle, width, height)
}

/// The per-pixel AOVs `error_bound`, `level` and `superpixel` from per-bundle summaries
/// (row-major bundles of `bundle × bundle` pixels, as [`PerspectiveGrid::bundle`]); none
/// without summaries (no error analysis).
pub fn bundle_aovs(
    summaries: &[BundleSummary],
    bundle: u32,
    width: u32,
    height: u32,
) -> Vec<(String, Vec<f32>)> {
    if summaries.is_empty() {
        return Vec::new();
    }
    let n = width as usize * height as usize;
    let bx = width.div_ceil(bundle);
    let mut aov = [vec![0f32; n], vec![0f32; n], vec![0f32; n]];
    for (b, s) in summaries.iter().enumerate() {
        let (x0, y0) = ((b as u32 % bx) * bundle, (b as u32 / bx) * bundle);
        for j in y0..(y0 + bundle).min(height) {
            for i in x0..(x0 + bundle).min(width) {
                let idx = j as usize * width as usize + i as usize;
                aov[0][idx] = s.predicted_error;
                aov[1][idx] = s.mean_level;
                aov[2][idx] = s.superpixel;
            }
        }
    }
    let [e, l, sp] = aov;
    vec![
        ("error_bound".into(), e),
        ("level".into(), l),
        ("superpixel".into(), sp),
    ]
}
