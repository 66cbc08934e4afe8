use std::borrow::Cow;
use std::time::Instant;

use fluidcast_grid::{PerspectiveGrid, Ray, SampleDepths};
use fluidcast_image::Image;
use fluidcast_plan::{BundleSummary, FieldParams, PlanParams, SamplingPlan};
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, TfLookup, TransferFunction};
use rayon::prelude::*;

use crate::raycast::Compositor;
use crate::span::{BundleRays, Reach, Reaching, Scatter, SpanDepths, SpanSums, LANES};
use crate::steps::Steps;
use crate::{ms, validate, RenderError, RenderParams, RenderStats};

/// Neighbour-count ratio below which a particle counts as a surface particle (see
/// [`Particles::surface_flags`]).
pub const SURFACE_THRESHOLD: f64 = 0.75;

/// The result of the grid renderer: the image (with AOVs `error_bound`, `level` and
/// `superpixel`, per pixel from its bundle), stage timings, and the grid and plan it used.
#[derive(Debug, Clone)]
pub struct AdaptiveRender {
    /// The image and its plan AOVs.
    pub image: Image,
    /// Timings and counts.
    pub stats: RenderStats,
    /// The sparse perspective grid of the view.
    pub grid: PerspectiveGrid,
    /// The sampling plan cast.
    pub plan: SamplingPlan,
}

/// One bundle's output: bundle index, its pixels cast (row-major index in the bundle,
/// premultiplied RGBA, depth), samples taken.
type BundleResult = (usize, Vec<(usize, [f32; 4], f32)>, u64);

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
    /// The sparse perspective grid of the view.
    pub grid: PerspectiveGrid,
    /// The sampling plan.
    pub plan: SamplingPlan,
    /// Timings and counts of the grid and plan stages.
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
    crate::refuse_surfaces(params, "the adaptive grid renderer")?;
    crate::check_weights(particles, params.kernel)?;
    let (w, h) = (params.width, params.height);
    let frame = camera.frame(w, h)?;
    let grid = PerspectiveGrid::build_within(
        particles,
        &frame,
        params.grid,
        params.sampling_scale,
        params.support_depths,
    )?;
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
    let stops = params.bundle_stops();
    let plan = SamplingPlan::build(&grid, tf, surface.as_deref(), stops.as_deref(), a, &field)?;
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

    let t2 = Instant::now();
    let lookup = TfLookup::new(tf);
    let mut cast = |p: &RenderParams, image: &mut Image| {
        stats.samples += cast_planned(&grid, &plan, &lookup, p, image);
        if crate::progress::cancelled(p.progress.as_deref()) {
            return Err(RenderError::Cancelled);
        }
        Ok::<_, RenderError>(())
    };
    let mut image = Image::new(params.width, params.height);
    match params.adaptive.tolerance {
        Some(e) if crate::interpolate::applies(particles, &grid.frame, params) => {
            let bundles = crate::interpolate::refined_bundles(&plan.summaries);
            let refined = crate::interpolate::cast_refined(
                params,
                &grid.frame,
                e,
                &bundles,
                &mut image,
                &mut cast,
            )?;
            stats.interpolated = refined.interpolated;
            stats.stages.extend(refined.stages);
        }
        _ => cast(params, &mut image)?,
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

/// The ray casting stage: casts the pixels of `grid` whose depth range is not empty with
/// `plan` into `image`, and returns the samples composited. The other pixels keep what they
/// hold, so that the passes of the image-space refinement fill one image, and so do the
/// pixels of bundles without cells (their rays meet no particle): `image` starts empty.
fn cast_planned(
    grid: &PerspectiveGrid,
    plan: &SamplingPlan,
    lookup: &TfLookup,
    params: &RenderParams,
    image: &mut Image,
) -> u64 {
    let Some(depths) = &grid.depths else {
        return 0;
    };
    let dz = grid.params.depth_samples as usize;
    // A bundle with no cells, or whose pixels all have empty depth ranges, casts nothing:
    // its rays pass through empty space, which the image holds before any pass.
    let casts = |b: usize| {
        let [x0, x1, y0, y1] = grid.bundle(b).pixels;
        (y0..y1).any(|j| {
            (x0..x1).any(|i| {
                let (near, far) = params.depth_range_at(i, j);
                near < far
            })
        })
    };
    let progress = params.progress.as_deref();
    crate::progress::start(progress, grid.bundle_count());
    let results: Vec<BundleResult> = (0..grid.bundle_count())
        .into_par_iter()
        .filter(|&b| {
            crate::progress::next(progress) && !grid.bundle_cells(b).is_empty() && casts(b)
        })
        .map_init(
            || BundleScratch::new(grid.params.bundle as usize, dz),
            |scratch, b| cast_bundle(grid, plan, depths, lookup, params, b, scratch),
        )
        .collect();
    let mut samples = 0;
    for (b, px, n) in results {
        samples += n;
        let [x0, x1, y0, _] = grid.bundle(b).pixels;
        let width = (x1 - x0) as usize;
        for (r, rgba, depth) in px {
            let idx = image.index(x0 + (r % width) as u32, y0 + (r / width) as u32);
            image.rgba[idx] = rgba;
            image.depth[idx] = depth;
        }
    }
    samples
}

/// Per-thread working memory of [`cast_bundle`]: the span's kernel sums and particles, and
/// which rays still take samples.
struct BundleScratch {
    sums: SpanSums,
    zs: SpanDepths,
    local: Vec<Reaching>,
    live: Vec<bool>,
    steps: Steps,
}

impl BundleScratch {
    fn new(bundle: usize, depth_samples: usize) -> BundleScratch {
        let slots = bundle * bundle.div_ceil(LANES) * LANES;
        BundleScratch {
            // A span samples at most MAX_SPAN_SAMPLES depths (the plan's merging keeps to it).
            sums: SpanSums::new(
                slots,
                depth_samples.max(fluidcast_plan::MAX_SPAN_SAMPLES as usize),
            ),
            zs: SpanDepths::default(),
            local: Vec::new(),
            live: vec![false; slots],
            steps: Steps::default(),
        }
    }
}

/// The columns and rows, relative to the bundle's first pixel `origin`, of the pixels of
/// `cast` (a box `[x0, x1) × [y0, y1)` of image pixels, the rays a pass casts) inside a
/// particle's pixel rectangle `rect` ([`PerspectiveGrid::rects`], which holds every pixel
/// whose ray can enter the support); `None` where they do not meet. Integer work where
/// projecting the support onto the bundle's rays took eight divisions, per particle, span
/// and pass; and a pass that casts a few pixels of a bundle drops the particles away from
/// them before any other work.
#[inline(always)]
fn reaching(rect: [u16; 4], cast: [u32; 4], origin: (u32, u32)) -> Option<Reach> {
    let r = rect.map(u32::from);
    let (c0, c1) = (r[0].max(cast[0]), r[1].min(cast[1]));
    let (r0, r1) = (r[2].max(cast[2]), r[3].min(cast[3]));
    // Bundles are at most 64 pixels a side (GridParams::validate): offsets fit in 8 bits.
    let at = |v: u32, o: u32| (v - o) as u8;
    (c0 < c1 && r0 < r1).then(|| Reach {
        cols: (at(c0, origin.0), at(c1, origin.0)),
        rows: (at(r0, origin.1), at(r1, origin.1)),
    })
}

/// The rays of a bundle that are cast: their pixels (indices into the bundle's pixels, in
/// block order), the rays by slot, the rays packed in lanes, and the image pixels they cover.
struct BundleCast {
    cast: Vec<usize>,
    rays: Vec<Ray>,
    lanes: BundleRays,
    cast_box: [u32; 4],
}

impl BundleCast {
    /// The compositors of bundle `b`'s pixels, and the rays of those not done before they
    /// start (a pixel whose depth range is empty takes no lane; see
    /// RenderParams::depth_range_at).
    fn new(
        grid: &PerspectiveGrid,
        b: usize,
        params: &RenderParams,
    ) -> (Vec<Compositor>, BundleCast) {
        let [x0, x1, y0, y1] = grid.bundle(b).pixels;
        let width = (x1 - x0) as usize;
        let pixels = (y0..y1).flat_map(|j| (x0..x1).map(move |i| (i, j)));
        let comps: Vec<Compositor> = pixels
            .map(|(i, j)| Compositor::for_pixel(params, i, j))
            .collect();
        let mut cast: Vec<usize> = (0..comps.len()).filter(|&r| !comps[r].done).collect();
        cast.sort_by_key(|&r| crate::span::block_key(r % width, r / width));
        // The rays of the pixels cast, by slot (a pass that casts a quarter of a bundle's
        // pixels forms a quarter of its rays).
        let pixel = |r: usize| (x0 + (r % width) as u32, y0 + (r / width) as u32);
        let rays: Vec<Ray> = cast
            .iter()
            .map(|&r| {
                let (i, j) = pixel(r);
                Ray::through_pixel(&grid.frame, i, j)
            })
            .collect();
        let lanes = BundleRays::new(
            cast.iter()
                .zip(&rays)
                .map(|(&r, &ray)| ((r % width, r / width), ray)),
        );
        // The image pixels of the rays cast: a particle's rectangle must meet them.
        let cast_box = cast
            .iter()
            .fold([u32::MAX, 0, u32::MAX, 0], |[a, b, c, d], &r| {
                let (i, j) = pixel(r);
                [a.min(i), b.max(i + 1), c.min(j), d.max(j + 1)]
            });
        let bc = BundleCast {
            cast,
            rays,
            lanes,
            cast_box,
        };
        (comps, bc)
    }
}

/// Composites each cast ray's samples of one span (those that received any weight) and
/// clears its sums. Run through [`pulp::Arch::dispatch`], which compiles it for the CPU's
/// best instruction set.
struct Composite<'a> {
    cast: &'a [usize],
    rays: &'a [Ray],
    comps: &'a mut [Compositor],
    sums: &'a mut SpanSums,
    zs: &'a SpanDepths,
    steps: &'a mut Steps,
    tf: &'a TfLookup<'a>,
    params: &'a RenderParams,
}

impl pulp::WithSimd for Composite<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        // Every ray's steps first, then their colours and opacities, corrected in one pass,
        // then each ray's compositing: what Compositor::sample does sample by sample.
        self.steps.clear();
        for (slot, &r) in self.cast.iter().enumerate() {
            let (ray, comp) = (&self.rays[slot], &self.comps[r]);
            self.steps.begin_ray();
            // A ray done in an earlier span takes no steps.
            let touched = if comp.done {
                0..0
            } else {
                self.sums.touched(slot)
            };
            for m in touched {
                let Some(q) = self.sums.at(m, slot) else {
                    continue;
                };
                if !self
                    .steps
                    .push(comp, q, (self.zs.z()[m], self.zs.z()[m + 1]), ray.dlen)
                {
                    break;
                }
            }
            self.steps.end_ray();
        }
        self.sums.clear();
        self.steps.shade(self.tf, self.params.field);
        self.steps.correct(self.tf.tf);
        for (slot, &r) in self.cast.iter().enumerate() {
            self.steps
                .composite(slot, &mut self.comps[r], self.params.min_transmittance);
        }
    }
}

/// Composites each cast ray's samples of one span and clears its sums ([`Composite`]).
fn composite(
    cast: &[usize],
    rays: &[Ray],
    comps: &mut [Compositor],
    (sums, zs): (&mut SpanSums, &SpanDepths),
    steps: &mut Steps,
    tf: &TfLookup,
    params: &RenderParams,
) {
    pulp::Arch::new().dispatch(Composite {
        cast,
        rays,
        comps,
        sums,
        zs,
        steps,
        tf,
        params,
    });
}

/// Ray casts bundle `b` of the plan: per span (Alg. 2: every ray of the bundle samples the
/// same particles, at D_z positions spaced 2^level samples apart), each particle adds its
/// kernel weights to the rays its footprint reaches, then each ray composites the samples
/// that received any. Per ray the particles are summed in the span's order, as a ray-by-ray
/// loop would.
fn cast_bundle(
    grid: &PerspectiveGrid,
    plan: &SamplingPlan,
    depths: &SampleDepths,
    tf: &TfLookup,
    params: &RenderParams,
    b: usize,
    scratch: &mut BundleScratch,
) -> BundleResult {
    let dz = grid.params.depth_samples as usize;
    let [x0, _, y0, _] = grid.bundle(b).pixels;
    let (mut comps, rays) = BundleCast::new(grid, b, params);
    let BundleCast {
        cast,
        rays,
        lanes,
        cast_box,
    } = rays;
    for span in plan.bundle_spans(b) {
        if cast.iter().all(|&r| comps[r].done) {
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
        let step = 1usize << span.level;
        let n = span.count as usize * dz / step;
        let cells = &grid.cells[first..first + span.count as usize];
        let BundleScratch {
            sums,
            zs,
            local,
            live,
            steps,
        } = scratch;
        // The span's n samples and the end of the last one's step.
        zs.set((0..=n).map(|m| depths.z[k0 + m * step]));
        local.clear();
        local.extend(grid.merged_refs(cells).filter_map(|j| {
            // (Every particle has its rectangle; were one missing, the whole bundle.)
            let rect = grid.rects.get(j as usize).copied();
            let reach = reaching(
                rect.unwrap_or([0, u16::MAX, 0, u16::MAX]),
                cast_box,
                (x0, y0),
            )?;
            Some(Reaching {
                p: grid.particles[j as usize],
                reach,
            })
        }));
        for (slot, &r) in cast.iter().enumerate() {
            live[slot] = !comps[r].done;
        }
        pulp::Arch::new().dispatch(Scatter {
            sums,
            rays: &lanes,
            particles: local,
            zs,
            live,
            kernel: params.kernel,
            field: params.field,
        });
        composite(&cast, &rays, &mut comps, (sums, zs), steps, tf, params);
    }
    let samples = comps.iter().map(|c| c.samples).sum();
    let pixels = cast.iter().map(|&r| {
        let (rgba, depth) = comps[r].pixel();
        (r, rgba, depth)
    });
    (b, pixels.collect(), samples)
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
    let mut aov = [vec![0f32; n], vec![0f32; n], vec![0f32; n]];
    for (b, s) in summaries.iter().enumerate() {
        let [x0, x1, y0, y1] = fluidcast_grid::bundle_pixels(width, height, bundle, b);
        for j in y0..y1 {
            for i in x0..x1 {
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

#[cfg(test)]
mod tests {
    use super::*;
    use fluidcast_grid::{stored_rect, ViewParticle};
    use fluidcast_view::ViewFrame;
    use proptest::prelude::*;

    /// The view (64×48, perspective or parallel) and the rays of its 8×8 bundle at pixel
    /// (x0, y0).
    fn bundle_rays(parallel: bool, x0: u32, y0: u32) -> (ViewFrame, Vec<Ray>) {
        let camera = Camera {
            parallel_projection: parallel,
            parallel_scale: 0.6,
            ..Camera::default()
        };
        let frame = camera.frame(64, 48).unwrap();
        let rays = (y0..y0 + 8)
            .flat_map(|j| (x0..x0 + 8).map(move |i| (i, j)))
            .map(|(i, j)| Ray::through_pixel(&frame, i, j))
            .collect();
        (frame, rays)
    }

    /// The near and far depth of the grid in these tests.
    const NEAR_FAR: (f64, f64) = (1e-3, 100.0);

    /// What [`cast_bundle`] does: the particle's rectangle as the grid stores it, cut to
    /// the bundle at (x0, y0) (all of it cast).
    fn reach_in_bundle(frame: &ViewFrame, p: &ViewParticle, x0: u32, y0: u32) -> Option<Reach> {
        let (near, far) = NEAR_FAR;
        let rect = stored_rect(frame, p, near, far);
        reaching(rect, [x0, x0 + 8, y0, y0 + 8], (x0, y0))
    }

    /// True when ray `r` (of 8 × 8) lies in `reach`.
    fn holds(reach: Option<Reach>, r: usize) -> bool {
        reach.is_some_and(|reach| {
            let (cols, rows) = (reach.cols, reach.rows);
            (usize::from(cols.0)..usize::from(cols.1)).contains(&(r % 8))
                && (usize::from(rows.0)..usize::from(rows.1)).contains(&(r / 8))
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(400))]
        /// A particle's reach in a bundle holds every ray that enters its support beyond the
        /// near depth, for particles anywhere, the eye inside the support included. And it
        /// is tight: for a support in front of the eye, exactly the columns and rows whose
        /// lines meet the support's extent ([`lines_meeting`]), up to the rounding slack (a
        /// reach grown by a column still renders right, but scatters for nothing).
        #[test]
        fn reach_holds_every_ray_that_enters_and_no_more(
            parallel in any::<bool>(),
            bx in 0u32..8,
            by in 0u32..6,
            c in prop::array::uniform3(-1.5f64..1.5),
            h in 0.001f64..0.8,
        ) {
            let (frame, rays) = bundle_rays(parallel, 8 * bx, 8 * by);
            let p = ViewParticle::new(c, h, 1.0, 1.0, 1.0);
            let reach = reach_in_bundle(&frame, &p, 8 * bx, 8 * by);
            for (r, ray) in rays.iter().enumerate() {
                if ray.passage(&p).is_some_and(|pass| pass.z1 >= NEAR_FAR.0) {
                    prop_assert!(holds(reach, r), "ray {} enters but lies outside {:?}", r, reach);
                }
            }
            if c[2] - h <= NEAR_FAR.0 {
                return Ok(()); // the support reaches around the eye: all of the image
            }
            let line = |axis: usize, k: usize| (rays[k].o[axis], rays[k].d[axis]);
            let xs: Vec<_> = (0..8).map(|k| line(0, k)).collect();
            let ys: Vec<_> = (0..8).map(|k| line(1, 8 * k)).collect();
            let (cols, rows) = reach.map_or(((8, 8), (8, 8)), |r| (r.cols, r.rows));
            for ((lo, hi), l, c) in [(cols, &xs, p.c[0]), (rows, &ys, p.c[1])] {
                let got = usize::from(lo)..usize::from(hi);
                let (inner, outer) = (lines_meeting(l, c, &p, -1e-4), lines_meeting(l, c, &p, 1e-4));
                // Where one axis has no line, the reach is empty: the other says nothing.
                if reach.is_some() {
                    prop_assert!(inner.iter().all(|k| got.contains(k)), "{:?} misses {:?}", got, inner);
                }
                prop_assert!(got.clone().all(|k| outer.contains(&k)), "{:?} beyond {:?}", got, outer);
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(400))]
        /// The same at the edge of the support: a particle whose centre lies just inside H
        /// of a chosen ray (perpendicular offset 0.95–0.9999 H) has that ray in its reach.
        #[test]
        fn reach_holds_grazing_rays(
            parallel in any::<bool>(),
            r in 0usize..64,
            z in 0.2f64..2.0,
            f in 0.95f64..0.9999,
            angle in 0.0f64..std::f64::consts::TAU,
            h in 0.001f64..0.5,
        ) {
            let (frame, rays) = bundle_rays(parallel, 24, 16);
            let ray = &rays[r];
            // Two unit vectors perpendicular to the ray's direction.
            let d = ray.d.map(|v| v / ray.dlen);
            let u = { let n = (d[0] * d[0] + d[2] * d[2]).sqrt(); [d[2] / n, 0.0, -d[0] / n] };
            let w = [d[1] * u[2] - d[2] * u[1], d[2] * u[0] - d[0] * u[2], d[0] * u[1] - d[1] * u[0]];
            let (ca, sa) = (angle.cos(), angle.sin());
            let c = [0, 1, 2].map(|k| ray.o[k] + z * ray.d[k] + f * h * (ca * u[k] + sa * w[k]));
            let p = ViewParticle::new(c, h, 1.0, 1.0, 1.0);
            prop_assert!(ray.passage(&p).is_some());
            let reach = reach_in_bundle(&frame, &p, 24, 16);
            prop_assert!(holds(reach, r), "ray {} grazes but lies outside {:?}", r, reach);
        }
    }

    /// The columns (rows) whose line x = o + z·d meets [c − H, c + H] somewhere in the
    /// particle's depth extent in front of the eye, by solving for the depths where it does;
    /// `grow` widens H.
    fn lines_meeting(lines: &[(f64, f64)], c: f64, p: &ViewParticle, grow: f64) -> Vec<usize> {
        let (za, zb) = ((p.c[2] - p.h()).max(0.0), (p.c[2] + p.h()).max(0.0));
        let h = p.h() * (1.0 + grow);
        let meets = |&(o, d): &(f64, f64)| {
            if d == 0.0 {
                return (o - c).abs() <= h;
            }
            let (s0, s1) = ((c - h - o) / d, (c + h - o) / d);
            s0.min(s1).max(za) <= s1.max(s0).min(zb)
        };
        (0..lines.len()).filter(|&k| meets(&lines[k])).collect()
    }

    /// A small particle in front of the camera reaches a few of the bundle's rays, not all;
    /// a pass that casts pixels away from it drops it.
    #[test]
    fn reach_of_a_small_particle_is_small() {
        for parallel in [false, true] {
            let (frame, rays) = bundle_rays(parallel, 24, 16);
            let centre = rays[3 * 8 + 3].d.map(|d| d * 0.5);
            let o = rays[3 * 8 + 3].o;
            let c = [o[0] + centre[0], o[1] + centre[1], o[2] + centre[2]];
            let p = ViewParticle::new(c, 0.01, 1.0, 1.0, 1.0);
            let reach = reach_in_bundle(&frame, &p, 24, 16).unwrap();
            assert!(holds(Some(reach), 3 * 8 + 3), "{reach:?}");
            for (lo, hi) in [reach.cols, reach.rows] {
                assert!(hi - lo <= 3, "{reach:?}");
            }
            let (near, far) = NEAR_FAR;
            let rect = stored_rect(&frame, &p, near, far);
            assert_eq!(reaching(rect, [30, 32, 16, 24], (24, 16)), None);
            assert!(reaching(rect, [24, 32, 16, 24], (24, 16)).is_some());
        }
    }

    /// A pass of the ray casting stage casts exactly the pixels whose depth range is not
    /// empty, each exactly as a pass over every pixel does (same bits: packing a ray into
    /// another lane changes nothing it sums), and leaves the others as the image held them,
    /// as it does the pixels of bundles without cells (empty in a fresh image). Random masks
    /// on a cloud of particles, relaxed and full-rate plans, both projections, an image whose
    /// edge cuts bundles.
    #[test]
    fn a_pass_casts_exactly_its_pixels() {
        // Supports of 2–5 pixels' radius: footprints smaller than a bundle.
        let p = fluidcast_testkit::cloud(3000, 3, (0.02, 0.03));
        let mut tf = TransferFunction::preset("Viridis").unwrap();
        (tf.range, tf.unit_distance) = ((-0.5, 1.0), 0.05);
        let lookup = TfLookup::new(&tf);
        let mut rnd = fluidcast_testkit::rng(9);
        for (parallel, tolerance) in [(false, None), (true, Some(0.01)), (false, Some(0.004))] {
            let camera = Camera {
                position: [0.4, 0.3, 2.2],
                parallel_projection: parallel,
                parallel_scale: 0.6,
                ..Camera::default()
            };
            let params = RenderParams {
                width: 181,
                height: 133,
                adaptive: PlanParams {
                    tolerance,
                    ..Default::default()
                },
                ..Default::default()
            };
            let planned = plan_adaptive(&p, None, &camera, &tf, &params).unwrap();
            let mut full = Image::new(params.width, params.height);
            cast_planned(&planned.grid, &planned.plan, &lookup, &params, &mut full);
            assert!(full.rgba.iter().filter(|c| c[3] > 0.1).count() > 5000);
            // What the image held before the pass: a pixel it does not cast keeps it.
            let before = ([0.25, -1.0, 7.0, 0.5], -3.0f32);
            for share in [0.1f32, 0.5, 0.9] {
                let mask: Vec<bool> = full.rgba.iter().map(|_| rnd() < share).collect();
                let pass = crate::interpolate::pass_params(&params, &mask);
                let mut got = Image::new(params.width, params.height);
                got.rgba.fill(before.0);
                got.depth.fill(before.1);
                cast_planned(&planned.grid, &planned.plan, &lookup, &pass, &mut got);
                for (k, &m) in mask.iter().enumerate() {
                    let w = params.width;
                    let (i, j) = ((k % w as usize) as u32, (k / w as usize) as u32);
                    let b = fluidcast_grid::bundle_of(w, params.grid.bundle, i, j);
                    let want = match m && !planned.grid.bundle_cells(b).is_empty() {
                        true => (full.rgba[k], full.depth[k]),
                        false => before,
                    };
                    assert_eq!((got.rgba[k], got.depth[k]), want, "pixel {k}, cast {m}");
                }
            }
        }
    }

    /// Surface flags (52 ms for 227k particles) are computed only for plans that use them:
    /// relaxed, adaptive, with the surface rule on (not strict, off or without the rule).
    /// Given flags are passed through as they are.
    #[test]
    fn surface_flags_only_where_the_plan_uses_them() {
        let mut p = Particles::default();
        for i in 0..27 {
            p.positions
                .push([(i % 3) as f32, (i / 3 % 3) as f32, (i / 9) as f32]);
        }
        p.radii = vec![1.5; 27];
        p.volumes = vec![1.0; 27];
        p.values = vec![1.0; 27];
        p.masses = vec![1.0; 27];
        let relaxed = PlanParams {
            tolerance: Some(0.004),
            ..Default::default()
        };
        assert!(relaxed.uses_surface_cells());
        let flags = plan_surface(&p, None, &relaxed).expect("relaxed plans use the surface");
        assert_eq!(&*flags, &p.surface_flags(SURFACE_THRESHOLD)[..]);
        let off = PlanParams {
            tolerance: None,
            ..relaxed
        };
        let no_rule = PlanParams {
            surface_cells: false,
            ..relaxed
        };
        for other in [relaxed.strict(), off, no_rule] {
            assert!(plan_surface(&p, None, &other).is_none(), "{other:?}");
        }
        let given = vec![true; 27];
        let passed = plan_surface(&p, Some(&given), &PlanParams::default());
        assert!(matches!(passed, Some(Cow::Borrowed(s)) if s.as_ptr() == given.as_ptr()));
    }
}
