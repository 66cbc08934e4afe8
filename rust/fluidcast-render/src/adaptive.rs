use std::borrow::Cow;
use std::time::Instant;

use fluidcast_grid::{PerspectiveGrid, Ray, SampleDepths, ViewParticle};
use fluidcast_image::Image;
use fluidcast_plan::{BundleSummary, FieldParams, PlanParams, SamplingPlan};
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, TfLookup, TransferFunction};
use rayon::prelude::*;

use crate::raycast::Compositor;
use crate::span::{BundleRays, Footprint, Scatter, SpanDepths, SpanSums, LANES};
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
    let mut cast = |p: &RenderParams| {
        let (image, samples) = cast_planned(&grid, &plan, &lookup, p);
        stats.samples += samples;
        Ok::<_, RenderError>(image)
    };
    let mut image = match params.adaptive.tolerance {
        Some(e) if crate::interpolate::applies(particles, &grid.frame, params) => {
            let bundles = crate::interpolate::refined_bundles(&plan.summaries);
            let (image, refined) =
                crate::interpolate::cast_refined(params, &grid.frame, e, &bundles, &mut cast)?;
            stats.interpolated = refined.interpolated;
            stats.stages.extend(refined.stages);
            image
        }
        _ => cast(params)?,
    };
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

/// The ray casting stage: the image of `grid` cast with `plan` (the pixels whose depth range
/// is not empty), and the samples composited.
fn cast_planned(
    grid: &PerspectiveGrid,
    plan: &SamplingPlan,
    lookup: &TfLookup,
    params: &RenderParams,
) -> (Image, u64) {
    let mut image = Image::new(params.width, params.height);
    let Some(depths) = &grid.depths else {
        return (image, 0);
    };
    let dz = grid.params.depth_samples as usize;
    // A bundle with no cells, or whose pixels all have empty depth ranges, casts nothing.
    let casts = |b: usize| {
        let [x0, x1, y0, y1] = grid.bundle(b).pixels;
        (y0..y1).any(|j| {
            (x0..x1).any(|i| {
                let (near, far) = params.depth_range_at(i, j);
                near < far
            })
        })
    };
    let results: Vec<BundleResult> = (0..grid.bundle_count())
        .into_par_iter()
        .filter(|&b| !grid.bundle_cells(b).is_empty() && casts(b))
        .map_init(
            || BundleScratch::new(grid.params.bundle as usize, dz),
            |scratch, b| cast_bundle(grid, plan, depths, lookup, params, b, scratch),
        )
        .collect();
    let mut samples = 0;
    for (b, px, n) in results {
        samples += n;
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
    (image, samples)
}

/// Per-thread working memory of [`cast_bundle`]: the span's kernel sums and particles, and
/// which rays still take samples.
struct BundleScratch {
    sums: SpanSums,
    zs: SpanDepths,
    local: Vec<ViewParticle>,
    live: Vec<bool>,
}

impl BundleScratch {
    fn new(bundle: usize, depth_samples: usize) -> BundleScratch {
        let slots = bundle * bundle.div_ceil(LANES) * LANES;
        BundleScratch {
            // A span samples at most 64 depths (the plan caps spans at 4 cells of 16).
            sums: SpanSums::new(slots, depth_samples.max(64)),
            zs: SpanDepths::default(),
            local: Vec::new(),
            live: vec![false; slots],
        }
    }
}

/// The bundle's rays as lines `o + z·d` (d.z = 1) per column and per row: column `i` has
/// x = `x[i].0 + z·x[i].1`, row `j` has y = `y[j].0 + z·y[j].1` (perspective rays start at
/// the eye, parallel ones are parallel to the view axis).
#[derive(Clone)]
struct BundleLines {
    x: Vec<(f64, f64)>,
    y: Vec<(f64, f64)>,
    fans: [Option<Fan>; 2],
}

/// Lines `o_k + z·d_k`, k = 0..n, whose `o` and `d` are affine in k, as a bundle's columns
/// (rows) are: pixel centres are evenly spaced in the image plane, so at any depth z the
/// lines are evenly spaced too, `x_k(z) = a(z) + k·s(z)` with a and s affine in z.
#[derive(Debug, Clone, Copy)]
struct Fan {
    o0: f64,
    d0: f64,
    so: f64,
    sd: f64,
    n: usize,
}

impl Fan {
    /// The fan through the first and last of `lines` (at least 2).
    fn of(lines: &[(f64, f64)]) -> Option<Fan> {
        let (&(o0, d0), &(o1, d1)) = (lines.first()?, lines.last()?);
        let n = lines.len();
        let k = (n as f64 - 1.0).max(1.0);
        (n >= 2).then_some(Fan {
            o0,
            d0,
            so: (o1 - o0) / k,
            sd: (d1 - d0) / k,
            n,
        })
    }

    /// The lines whose coordinate lies in [lo, hi] at some depth of [za, zb] (za ≤ zb, both
    /// ≥ 0). At one depth they are the k of an interval, `(lo − a)/s ≤ k ≤ (hi − a)/s`; its
    /// ends are ratios of affine functions of z, monotonic, so the union over [za, zb] (an
    /// interval, by continuity) runs from the smaller lower end to the larger upper end of
    /// the two depths. Where s = 0 (the perspective eye, z = 0, where every line passes) an
    /// end is ±∞ by the sign of s just beyond, or every line where the extent holds the eye.
    #[inline(always)]
    fn reach(&self, lo: f64, hi: f64, (za, zb): (f64, f64)) -> std::ops::Range<usize> {
        let (mut kmin, mut kmax) = (f64::INFINITY, f64::NEG_INFINITY);
        for z in [za, zb] {
            let a = self.o0 + z * self.d0;
            let s = self.so + z * self.sd;
            let s = if s == 0.0 {
                0.0f64.copysign(self.sd)
            } else {
                s
            };
            let (f, g) = ((lo - a) / s, (hi - a) / s);
            let (f, g) = if s.is_sign_negative() { (g, f) } else { (f, g) };
            // 0/0: the extent's edge passes through the eye, where every line does.
            kmin = kmin.min(if f.is_nan() { f64::NEG_INFINITY } else { f });
            kmax = kmax.max(if g.is_nan() { f64::INFINITY } else { g });
        }
        let n = self.n as f64;
        let (first, end) = (kmin.ceil().max(0.0), (kmax.floor() + 1.0).min(n));
        match first < end {
            true => first as usize..end as usize,
            false => self.n..self.n,
        }
    }
}

impl BundleLines {
    fn new(rays: &[Ray], width: usize) -> BundleLines {
        let x: Vec<(f64, f64)> = rays[..width].iter().map(|r| (r.o[0], r.d[0])).collect();
        let y: Vec<(f64, f64)> = rays
            .iter()
            .step_by(width)
            .map(|r| (r.o[1], r.d[1]))
            .collect();
        BundleLines {
            fans: [Fan::of(&x), Fan::of(&y)],
            x,
            y,
        }
    }
}

impl Footprint for BundleLines {
    /// The columns and rows whose rays can enter particle `p`'s support: those whose x
    /// (resp. y) lies within the support's extent [c − H, c + H] at some depth inside
    /// [c.z − H, c.z + H]. Conservative (a superset, widened against rounding); the exact
    /// test is [`Ray::passage`]. Empty ranges when none can.
    #[inline(always)]
    fn footprint(&self, p: &ViewParticle) -> (std::ops::Range<usize>, std::ops::Range<usize>) {
        let z = ((p.c[2] - p.h()).max(0.0), (p.c[2] + p.h()).max(0.0));
        (
            reach(&self.x, &self.fans[0], p.c[0], p.h(), z),
            reach(&self.y, &self.fans[1], p.c[1], p.h(), z),
        )
    }
}

/// The lines of `lines` (the same as `fan`, where there is one) whose coordinate lies within
/// [c − h, c + h], widened against rounding, at some depth of `z`.
#[inline(always)]
fn reach(
    lines: &[(f64, f64)],
    fan: &Option<Fan>,
    c: f64,
    h: f64,
    z: (f64, f64),
) -> std::ops::Range<usize> {
    let (lo, hi) = (c - h, c + h);
    let slack = 1e-9 * (lo.abs().max(hi.abs()) + h);
    let (lo, hi) = (lo - slack, hi + slack);
    if let Some(fan) = fan {
        return fan.reach(lo, hi, z);
    }
    // A line's coordinate is monotonic in z: its extremes over [z0, z1] are at the ends.
    let hit = |&(o, d): &(f64, f64)| {
        let (a, b) = (o + z.0 * d, o + z.1 * d);
        a.min(b) <= hi && a.max(b) >= lo
    };
    match lines.iter().position(hit) {
        Some(k) => k..lines.len() - lines.iter().rev().position(hit).unwrap_or(0),
        None => lines.len()..lines.len(),
    }
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
    let [x0, x1, y0, y1] = grid.bundle(b).pixels;
    let width = (x1 - x0) as usize;
    let pixels = (y0..y1).flat_map(|j| (x0..x1).map(move |i| (i, j)));
    let rays: Vec<Ray> = pixels
        .clone()
        .map(|(i, j)| Ray::through_pixel(&grid.frame, i, j))
        .collect();
    let lines = BundleLines::new(&rays, width);
    let mut comps: Vec<Compositor> = pixels
        .map(|(i, j)| Compositor::for_pixel(params, i, j))
        .collect();
    // The rays to cast, packed: a pixel whose depth range is empty is done before it starts
    // (see RenderParams::depth_range_at) and takes no lane; the others go in block order.
    let mut cast: Vec<usize> = (0..comps.len()).filter(|&r| !comps[r].done).collect();
    cast.sort_by_key(|&r| crate::span::block_key(r % width, r / width));
    let lanes = BundleRays::new(cast.iter().map(|&r| ((r % width, r / width), rays[r])));
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
        } = scratch;
        // The span's n samples and the end of the last one's step.
        zs.set((0..=n).map(|m| depths.z[k0 + m * step]));
        local.clear();
        local.extend(grid.merged_refs(cells).map(|j| grid.particles[j as usize]));
        for (slot, &r) in cast.iter().enumerate() {
            live[slot] = !comps[r].done;
        }
        pulp::Arch::new().dispatch(Scatter {
            sums,
            rays: &lanes,
            footprint: &lines,
            particles: local,
            zs,
            live,
            kernel: params.kernel,
            field: params.field,
        });
        for (slot, &r) in cast.iter().enumerate() {
            let (ray, c) = (&rays[r], &mut comps[r]);
            for m in sums.touched(slot) {
                if c.done {
                    break;
                }
                if let Some(q) = sums.value(m, slot, params.field) {
                    c.sample(
                        tf,
                        q,
                        (zs.z()[m], zs.z()[m + 1]),
                        ray.dlen,
                        params.min_transmittance,
                    );
                }
            }
            sums.clear(slot);
        }
    }
    let samples = comps.iter().map(|c| c.samples).sum();
    (b, comps.iter().map(Compositor::pixel).collect(), samples)
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
    use proptest::prelude::*;

    /// The rays of the 8×8 bundle at pixel (x0, y0) of a 64×48 view, perspective or parallel.
    fn bundle_rays(parallel: bool, x0: u32, y0: u32) -> Vec<Ray> {
        let camera = Camera {
            parallel_projection: parallel,
            parallel_scale: 0.6,
            ..Camera::default()
        };
        let frame = camera.frame(64, 48).unwrap();
        (y0..y0 + 8)
            .flat_map(|j| (x0..x0 + 8).map(move |i| (i, j)))
            .map(|(i, j)| Ray::through_pixel(&frame, i, j))
            .collect()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(400))]
        /// The footprint holds every ray that enters the support (the exact test) at a depth
        /// in front of the eye, where samples lie, for particles anywhere, the eye inside the
        /// support included. And it is tight: exactly the columns and rows whose lines meet
        /// the support's extent ([`lines_meeting`]), up to the rounding slack (a footprint
        /// grown by a column still renders right, but scatters for nothing).
        #[test]
        fn footprint_holds_every_ray_that_enters_and_no_more(
            parallel in any::<bool>(),
            bx in 0u32..8,
            by in 0u32..6,
            c in prop::array::uniform3(-1.5f64..1.5),
            h in 0.001f64..0.8,
        ) {
            let rays = bundle_rays(parallel, 8 * bx, 8 * by);
            let lines = BundleLines::new(&rays, 8);
            let p = ViewParticle::new(c, h, 1.0, 1.0, 1.0);
            let (cols, rows) = lines.footprint(&p);
            // The fans' closed form finds what testing line by line does.
            let by_line = BundleLines { fans: [None, None], ..lines.clone() };
            prop_assert_eq!((cols.clone(), rows.clone()), by_line.footprint(&p));
            for (r, ray) in rays.iter().enumerate() {
                if ray.passage(&p).is_some_and(|pass| pass.z1 >= 0.0) {
                    prop_assert!(cols.contains(&(r % 8)) && rows.contains(&(r / 8)),
                        "ray {} enters but lies outside {:?} × {:?}", r, cols, rows);
                }
            }
            for (got, l, c) in [(cols, &lines.x, p.c[0]), (rows, &lines.y, p.c[1])] {
                let (inner, outer) = (lines_meeting(l, c, &p, -1e-6), lines_meeting(l, c, &p, 1e-6));
                prop_assert!(inner.iter().all(|k| got.contains(k)), "{:?} misses {:?}", got, inner);
                prop_assert!(got.clone().all(|k| outer.contains(&k)), "{:?} beyond {:?}", got, outer);
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(400))]
        /// The same at the edge of the support: a particle whose centre lies just inside H
        /// of a chosen ray (perpendicular offset 0.95–0.9999 H) has that ray in its footprint.
        #[test]
        fn footprint_holds_grazing_rays(
            parallel in any::<bool>(),
            r in 0usize..64,
            z in 0.2f64..2.0,
            f in 0.95f64..0.9999,
            angle in 0.0f64..std::f64::consts::TAU,
            h in 0.001f64..0.5,
        ) {
            let rays = bundle_rays(parallel, 24, 16);
            let lines = BundleLines::new(&rays, 8);
            let ray = &rays[r];
            // Two unit vectors perpendicular to the ray's direction.
            let d = ray.d.map(|v| v / ray.dlen);
            let u = { let n = (d[0] * d[0] + d[2] * d[2]).sqrt(); [d[2] / n, 0.0, -d[0] / n] };
            let w = [d[1] * u[2] - d[2] * u[1], d[2] * u[0] - d[0] * u[2], d[0] * u[1] - d[1] * u[0]];
            let (ca, sa) = (angle.cos(), angle.sin());
            let c = [0, 1, 2].map(|k| ray.o[k] + z * ray.d[k] + f * h * (ca * u[k] + sa * w[k]));
            let p = ViewParticle::new(c, h, 1.0, 1.0, 1.0);
            prop_assert!(ray.passage(&p).is_some());
            let (cols, rows) = lines.footprint(&p);
            prop_assert!(cols.contains(&(r % 8)) && rows.contains(&(r / 8)),
                "ray {} grazes but lies outside {:?} × {:?}", r, cols, rows);
        }
    }

    /// The columns (rows) whose line x = o + z·d meets [c − H, c + H] somewhere in the
    /// particle's depth extent in front of the eye, by solving for the depths where it does
    /// (not by the footprint's end-point test); `grow` widens H.
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

    /// A small particle in front of the camera reaches a few of the bundle's rays, not all.
    #[test]
    fn footprint_of_a_small_particle_is_small() {
        for parallel in [false, true] {
            let rays = bundle_rays(parallel, 24, 16);
            let lines = BundleLines::new(&rays, 8);
            let centre = rays[3 * 8 + 3].d.map(|d| d * 0.5);
            let o = rays[3 * 8 + 3].o;
            let c = [o[0] + centre[0], o[1] + centre[1], o[2] + centre[2]];
            let p = ViewParticle::new(c, 0.01, 1.0, 1.0, 1.0);
            let (cols, rows) = lines.footprint(&p);
            assert!(cols.contains(&3) && rows.contains(&3), "{cols:?} {rows:?}");
            assert!(cols.len() <= 3 && rows.len() <= 3, "{cols:?} {rows:?}");
        }
    }

    /// A pass of the ray casting stage casts exactly the pixels whose depth range is not
    /// empty, each exactly as a pass over every pixel does (same bits: packing a ray into
    /// another lane changes nothing it sums), and leaves the others transparent at infinite
    /// depth. Random masks on a cloud of particles, relaxed and full-rate plans, both
    /// projections, an image whose edge cuts bundles.
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
            let (full, _) = cast_planned(&planned.grid, &planned.plan, &lookup, &params);
            assert!(full.rgba.iter().filter(|c| c[3] > 0.1).count() > 5000);
            for share in [0.1f32, 0.5, 0.9] {
                let mask: Vec<bool> = full.rgba.iter().map(|_| rnd() < share).collect();
                let pass = crate::interpolate::pass_params(&params, &mask);
                let (got, _) = cast_planned(&planned.grid, &planned.plan, &lookup, &pass);
                for (k, &m) in mask.iter().enumerate() {
                    let want = match m {
                        true => (full.rgba[k], full.depth[k]),
                        false => ([0.0; 4], f32::INFINITY),
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
