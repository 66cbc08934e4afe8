//! Jittered ray marching of the attribute-aware RBF field (Morrical et al. 2023, Sec.
//! 3.3.1) with progressive accumulation.
//!
//! Each 8×8-pixel tile asks the BVH once for the spheres that reach its frustum
//! ([`fluidcast_rbf::ClusterBvh::for_each_in_planes`]); each pixel's ray then finds, once, those
//! it crosses among them, sorted by where it enters them. Every pass
//! then marches the ray at equal world steps offset by a per-pixel, per-pass random fraction
//! of a step (the paper's jitter against "wood grain"), summing at each sample the particles
//! whose spheres hold it (those the ray is inside: the same particles a point range query
//! returns there), and composites front to back with the Beer–Lambert law until the ray is
//! opaque. The image is the mean of the passes: a Monte Carlo estimate whose noise falls as
//! 1/√(passes) ([`RbfRenderParams::spp`]).

use std::ops::Range;
use std::time::Instant;

use fluidcast_image::Image;
use fluidcast_rbf::{sphere_crossing, Colouring, Profile, RayHit, RbfField, RbfSample, SIGMAS};
use fluidcast_sph::FieldKind;
use fluidcast_view::{Camera, TfLookup, TransferFunction, ViewFrame};
use rayon::prelude::*;

use crate::raycast::Compositor;
use crate::{ms, refuse_surfaces, validate, RenderError, RenderParams, RenderStats};

/// The most samples one ray may take in one pass; a step that would need more over the
/// data's extent is refused instead of running for hours.
pub const MAX_RBF_STEPS: f64 = 1e6;

/// Pixels a side of the screen tiles whose rays share one BVH frustum query.
const TILE: u32 = 8;

/// How to march and accumulate the RBF field.
#[derive(Debug, Clone, PartialEq)]
pub struct RbfRenderParams {
    /// Jittered passes averaged into the image (samples per pixel, >= 1).
    pub spp: u32,
    /// The index of the first pass: a later render that starts where an earlier one stopped
    /// draws new offsets, so that the two images average into one of both passes' count.
    pub first_pass: u32,
    /// Seed of the per-pixel offsets.
    pub seed: u32,
    /// The step along each ray (world units); `None`: half the median particle's standard
    /// deviation (σ = r/3) divided by [`RenderParams::sampling_scale`].
    pub step: Option<f64>,
    /// Single scattering with shadows instead of emission–absorption ([`RbfShadows`]).
    pub shadows: Option<RbfShadows>,
    /// Where the offsets come from.
    pub noise: Noise,
}

/// The random offsets of the jittered march, the shade points and the shadow rays.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Noise {
    /// Blue noise over the screen, a golden-ratio sequence over passes
    /// ([`crate::bluenoise`]): less visible noise in one pass, faster convergence.
    #[default]
    Blue,
    /// Independent per pixel and pass (a hash): the plain Monte Carlo estimate, whose error
    /// falls as 1/√passes.
    White,
}

impl Default for RbfRenderParams {
    fn default() -> Self {
        RbfRenderParams {
            spp: 1,
            first_pass: 0,
            seed: 0,
            step: None,
            shadows: None,
            noise: Noise::Blue,
        }
    }
}

impl RbfRenderParams {
    /// The world step for `field` under `params`; `None` when no particle is visible.
    pub fn step_for(&self, field: &RbfField, params: &RenderParams) -> Option<f64> {
        match self.step {
            Some(s) => Some(s),
            None => {
                let sigma = field.median_radius() / SIGMAS;
                (sigma > 0.0).then(|| 0.5 * sigma / params.sampling_scale)
            }
        }
    }
}

/// The constants of [`white_offset`]'s hash: the seed's offset, the multiplier of each
/// number hashed in, and "lowbias32"'s two multipliers (the GPU's copy is written from these).
pub const HASH_SEED: u32 = 0x9e37_79b9;
/// See [`HASH_SEED`].
pub const HASH_IN: u32 = 0x85eb_ca6b;
/// See [`HASH_SEED`].
pub const HASH_MUL: [u32; 2] = [0x7feb_352d, 0x846c_a68b];

/// A random fraction in [0, 1) for pixel (i, j) in pass `pass` (a 32-bit integer hash,
/// "lowbias32", of the four numbers): independent between pixels and passes.
#[inline]
pub fn white_offset(i: u32, j: u32, pass: u32, seed: u32) -> f64 {
    let mut h = seed ^ HASH_SEED;
    for v in [i, j, pass] {
        h = mix32(h ^ v.wrapping_mul(HASH_IN));
    }
    f64::from(h >> 8) / f64::from(1u32 << 24)
}

/// "lowbias32" (Chris Wellons' integer hash).
#[inline]
pub fn mix32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(HASH_MUL[0]);
    x ^= x >> 15;
    x = x.wrapping_mul(HASH_MUL[1]);
    x ^ (x >> 16)
}

/// What one frame's rays share.
struct Marcher<'a> {
    field: &'a RbfField,
    tf: TfLookup<'a>,
    params: &'a RenderParams,
    rbf: &'a RbfRenderParams,
    frame: ViewFrame,
    /// World step.
    step: f64,
}

/// A pixel's rays over all passes: premultiplied RGBA summed, the first pass's depth, the
/// samples composited.
struct PixelSum {
    rgba: [f64; 4],
    depth: f32,
    samples: u64,
}

/// A particle the ray is inside: its crossing (index into the ray's hits), its RBF at the
/// next sample, the ratio of the one after to it, and that ratio's factor from one sample
/// to the next.
struct Active {
    hit: u32,
    phi: f64,
    ratio: f64,
    ratio_step: f64,
}

/// A composited sample of a lit pass: its view depth, the opacity accumulated through it,
/// and its colour (the albedo).
#[derive(Debug, Clone, Copy)]
struct Shade {
    t: f64,
    opacity: f64,
    rgb: [f64; 3],
}

/// A shadow ray's crossings and active set.
#[derive(Default)]
struct ShadowScratch {
    hits: Vec<RayHit>,
    active: Vec<Active>,
}

/// A camera ray's active set and shade points, and its shadow rays' buffers.
#[derive(Default)]
struct LitScratch {
    active: Vec<Active>,
    shade: Vec<Shade>,
    shadow: ShadowScratch,
}

/// Per-thread buffers: a tile's candidate spheres, a ray's crossings, and the rest.
#[derive(Default)]
struct Scratch {
    candidates: Vec<u32>,
    hits: Vec<RayHit>,
    lit: LitScratch,
}

/// Seeds (xor-ed into the user's) of the random streams beside the march's offsets: the
/// shade point's choice and the shadow rays' offsets.
pub const PICK_STREAM: u32 = 0x5bd1_e995;
/// See [`PICK_STREAM`].
pub const SHADOW_STREAM: u32 = 0x27d4_eb2f;

/// A shadow ray stops once its optical depth passes this (transmittance below 2e-9).
pub const MAX_OPTICAL_DEPTH: f64 = 20.0;

/// Single scattering toward a directional light (Morrical et al. 2023, Sec. 3.3.2): the
/// transfer function's colours become albedos.
#[derive(Debug, Clone, PartialEq)]
pub struct RbfShadows {
    /// The direction toward the light (world space, unit length).
    pub light: [f64; 3],
    /// The light a fully shadowed point still receives, as a share of the full light
    /// (0..1): keeps shadowed regions readable.
    pub ambient: f64,
    /// Shadow rays per pixel and pass (>= 1), averaged.
    pub samples: u32,
}

impl RbfShadows {
    /// The light a view gets when none is given: from above and behind the camera (view
    /// up, plus half the way back to the eye and a quarter to the right), so that shadows
    /// fall down and away from the viewer.
    pub fn default_light(frame: &ViewFrame) -> [f64; 3] {
        (frame.up - frame.forward * 0.5 + frame.right * 0.25).to_array()
    }

    /// Checks the values and makes the light direction unit length.
    pub fn new(light: [f64; 3], ambient: f64, samples: u32) -> Result<RbfShadows, RenderError> {
        let n = light.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !(n.is_finite() && n > 0.0) {
            return Err(RenderError::Rbf(format!(
                "light direction {light:?}: must be finite and not zero"
            )));
        }
        if !(0.0..=1.0).contains(&ambient) {
            return Err(RenderError::Rbf(format!(
                "ambient light {ambient}: must be in [0, 1]"
            )));
        }
        if samples == 0 {
            return Err(RenderError::Rbf("shadow samples must be at least 1".into()));
        }
        Ok(RbfShadows {
            light: light.map(|v| v / n),
            ambient,
            samples,
        })
    }
}

impl Marcher<'_> {
    /// The offset in [0, 1) of pixel (i, j) in pass `pass` for random stream `stream`.
    #[inline]
    fn offset(&self, i: u32, j: u32, pass: u32, stream: u32) -> f64 {
        let seed = self.rbf.seed ^ stream;
        match self.rbf.noise {
            Noise::Blue => crate::bluenoise::blue_offset(i, j, pass, seed),
            Noise::White => white_offset(i, j, pass, seed),
        }
    }

    /// The pixels of tile `(columns, rows)`, row by row: its frustum's candidate spheres from
    /// the BVH once, then each ray's crossings among them.
    fn tile(&self, (columns, rows): (Range<u32>, Range<u32>), sc: &mut Scratch) -> Vec<PixelSum> {
        let planes = tile_planes(&self.frame, (&columns, &rows));
        sc.candidates.clear();
        let bvh = self.field.bvh();
        bvh.for_each_in_planes(&planes, |s| sc.candidates.push(s));
        let mut out = Vec::with_capacity(columns.len() * rows.len());
        for j in rows {
            for i in columns.clone() {
                out.push(self.pixel(i, j, sc));
            }
        }
        out
    }

    fn pixel(&self, i: u32, j: u32, sc: &mut Scratch) -> PixelSum {
        let (o, d) = self.frame.ray(i, j);
        let (o, d) = (o.to_array(), d.to_array());
        let dd: f64 = d.iter().map(|v| v * v).sum();
        let (near, limit) = self.params.depth_range_at(i, j);
        let range = (near.max(0.0), limit);
        let bvh = self.field.bvh();
        sc.hits.clear();
        for &slot in &sc.candidates {
            if let Some(hit) = sphere_crossing(bvh.sphere(slot), slot, (o, d, dd), range) {
                sc.hits.push(hit);
            }
        }
        sc.hits.sort_unstable_by(|a, b| a.t_in.total_cmp(&b.t_in));
        let mut sum = PixelSum {
            rgba: [0.0; 4],
            depth: f32::INFINITY,
            samples: 0,
        };
        if sc.hits.is_empty() {
            return sum;
        }
        for pass in self.rbf.first_pass..self.rbf.first_pass.saturating_add(self.rbf.spp) {
            let comp = match &self.rbf.shadows {
                Some(sh) => {
                    let ray = (o, d);
                    self.lit_pass(
                        (&sc.hits, &mut sc.lit),
                        ray,
                        (i, j, pass),
                        (near, limit),
                        sh,
                    )
                }
                None => {
                    let xi = self.offset(i, j, pass, 0);
                    let hits = (&sc.hits[..], &mut sc.lit.active);
                    self.march(hits, d, xi, (near, limit), None)
                }
            };
            let (rgba, depth) = comp.pixel();
            for (s, v) in sum.rgba.iter_mut().zip(rgba) {
                *s += f64::from(v);
            }
            if pass == self.rbf.first_pass {
                sum.depth = depth;
            }
            sum.samples += comp.samples;
        }
        sum
    }

    /// The samples of one pass along a ray of direction `d` (`dd = |d|²`; t = view depth
    /// for a camera ray): at `t_k = (k + xi)·Δt` over the crossed spheres `hits` (sorted by
    /// entry), in order, handed to `visit(t, Δt, sums)` until it returns false. A particle is
    /// summed at the samples between its entry and exit (where its sphere holds them); its
    /// Gaussian there, `w·exp(−A·(m² + |d|²(t − t_c)²))` with `A = 4.5/r²`, is evaluated once
    /// on entry and then stepped by two products a sample (the ratio of consecutive values
    /// changes by a constant factor).
    fn for_each_sample(
        &self,
        hits: &[RayHit],
        active: &mut Vec<Active>,
        (dd, xi): (f64, f64),
        mut visit: impl FnMut(f64, f64, &RbfSample) -> bool,
    ) {
        let dt = self.step / dd.sqrt();
        let Some(first) = hits.first() else {
            return;
        };
        let last = hits
            .iter()
            .map(|h| h.t_out)
            .fold(f64::NEG_INFINITY, f64::max);
        let first_k = |t: f64| (t / dt - xi).ceil();
        let mut k = first_k(first.t_in);
        let mut next = 0;
        // The earliest exit among the active particles: none leaves before it.
        let mut exit = f64::INFINITY;
        active.clear();
        loop {
            let t = (k + xi) * dt;
            if t > last {
                return;
            }
            while next < hits.len() && hits[next].t_in <= t {
                active.push(self.enter(&hits[next], next as u32, t, (dd, dt)));
                exit = exit.min(hits[next].t_out);
                next += 1;
            }
            if exit < t {
                active.retain(|a| hits[a.hit as usize].t_out >= t);
                exit = active
                    .iter()
                    .map(|a| hits[a.hit as usize].t_out)
                    .fold(f64::INFINITY, f64::min);
            }
            if active.is_empty() {
                match hits.get(next) {
                    Some(h) => {
                        k = first_k(h.t_in).max(k + 1.0);
                        continue;
                    }
                    None => return,
                }
            }
            let mut s = RbfSample::default();
            let profile = self.field.profile();
            for a in active.iter_mut() {
                let h = &hits[a.hit as usize];
                let (w, theta) = self.field.weight_theta(h.slot);
                let phi = match profile {
                    Profile::Gaussian => {
                        let phi = a.phi;
                        a.phi *= a.ratio;
                        a.ratio *= a.ratio_step;
                        phi
                    }
                    // An SPH kernel: evaluated where the sample is.
                    sph => {
                        let r = f64::from(self.field.bvh().sphere(h.slot)[3]);
                        let d2 = h.miss2 + dd * (t - h.closest).powi(2);
                        sph.eval(d2.max(0.0).sqrt(), r, f64::from(w))
                    }
                };
                s.density += phi;
                for (acc, th) in s.weighted.iter_mut().zip(theta) {
                    *acc += phi * f64::from(th);
                }
            }
            if s.density > 0.0 && !visit(t, dt, &s) {
                return;
            }
            k += 1.0;
        }
    }

    /// One emission–absorption pass along the camera ray of direction `d`, composited front
    /// to back (each sample standing for the step around it) between view depths `near` and
    /// `limit`; with `shade`, each composited sample's view depth, the opacity accumulated
    /// through it and its colour are recorded there.
    fn march(
        &self,
        (hits, active): (&[RayHit], &mut Vec<Active>),
        d: [f64; 3],
        xi: f64,
        (near, limit): (f64, f64),
        mut shade: Option<&mut Vec<Shade>>,
    ) -> Compositor {
        let dd = d.iter().map(|v| v * v).sum::<f64>();
        let mut comp = Compositor::between(near, limit);
        if let Some(v) = shade.as_deref_mut() {
            v.clear();
        }
        self.for_each_sample(hits, active, (dd, xi), |t, dt, s| {
            let (rgb, mu) = self.classify(s);
            let trans = (-mu * self.step).exp();
            let a = 1.0 - trans;
            comp.samples += 1;
            let z = (t - 0.5 * dt, t + 0.5 * dt);
            let min_t = self.params.min_transmittance;
            comp.add([a * rgb[0], a * rgb[1], a * rgb[2], trans], z, min_t);
            if let Some(v) = shade.as_deref_mut() {
                v.push(Shade {
                    t,
                    opacity: 1.0 - comp.trans,
                    rgb,
                });
            }
            !comp.done
        });
        comp
    }

    /// The transmittance from world point `x` toward the light (direction `l`), by a
    /// jittered march (offset `xi`) through the spheres the shadow ray crosses.
    fn transmittance(&self, x: [f64; 3], l: [f64; 3], xi: f64, sc: &mut ShadowScratch) -> f64 {
        sc.hits.clear();
        let (hits, active) = (&mut sc.hits, &mut sc.active);
        let range = (0.0, f64::INFINITY);
        self.field
            .bvh()
            .for_each_on_ray(x, l, range, |h| hits.push(h));
        hits.sort_unstable_by(|a, b| a.t_in.total_cmp(&b.t_in));
        let mut tau = 0.0;
        self.for_each_sample(hits, active, (1.0, xi), |_, _, s| {
            tau += self.classify(s).1 * self.step;
            tau < MAX_OPTICAL_DEPTH
        });
        (-tau).exp()
    }

    /// One pass with single scattering (Sec. 3.3.2): the pass's opacity as emission–
    /// absorption composites it, and its colour from one shade point chosen with the
    /// probability that light scatters there (sample k with `T_k·α_k` of the total
    /// opacity, by the opacity accumulated through it: the paper's free-flight distance on
    /// the Riemann sum), lit by the light as the shadow rays see it plus the ambient share.
    fn lit_pass(
        &self,
        (hits, sc): (&[RayHit], &mut LitScratch),
        (o, d): ([f64; 3], [f64; 3]),
        (i, j, pass): (u32, u32, u32),
        (near, limit): (f64, f64),
        shadows: &RbfShadows,
    ) -> Compositor {
        let xi = self.offset(i, j, pass, 0);
        let mut comp = self.march(
            (hits, &mut sc.active),
            d,
            xi,
            (near, limit),
            Some(&mut sc.shade),
        );
        let Some(total) = sc.shade.last().map(|s| s.opacity) else {
            return comp;
        };
        let pick = self.offset(i, j, pass, PICK_STREAM) * total;
        let k = sc
            .shade
            .partition_point(|s| s.opacity < pick)
            .min(sc.shade.len() - 1);
        let Shade { t, rgb, .. } = sc.shade[k];
        let x = [0, 1, 2].map(|a| o[a] + t * d[a]);
        let n = shadows.samples.max(1);
        let lit: f64 = (0..n)
            .map(|s| {
                let xi = self.offset(i, j, pass.wrapping_mul(n).wrapping_add(s), SHADOW_STREAM);
                self.transmittance(x, shadows.light, xi, &mut sc.shadow)
            })
            .sum::<f64>()
            / f64::from(n);
        let light = shadows.ambient + (1.0 - shadows.ambient) * lit;
        comp.color = rgb.map(|c| total * c * light);
        comp
    }

    /// Particle `hit` entering the march at sample `t` (steps of `dt`, `dd = |d|²`).
    #[inline]
    fn enter(&self, h: &RayHit, hit: u32, t: f64, (dd, dt): (f64, f64)) -> Active {
        if self.field.profile() != Profile::Gaussian {
            // SPH kernels are evaluated at each sample: no stepping state.
            return Active {
                hit,
                phi: 0.0,
                ratio: 0.0,
                ratio_step: 0.0,
            };
        }
        let r = f64::from(self.field.bvh().sphere(h.slot)[3]);
        let w = f64::from(self.field.weight_theta(h.slot).0);
        let a = SIGMAS * SIGMAS * 0.5 / (r * r) * dd;
        let s = t - h.closest;
        Active {
            hit,
            phi: w * (-(SIGMAS * SIGMAS * 0.5 / (r * r)) * h.miss2 - a * s * s).exp(),
            ratio: (-a * (2.0 * s * dt + dt * dt)).exp(),
            ratio_step: (-2.0 * a * dt * dt).exp(),
        }
    }

    /// A sample's colour (linear RGB) and extinction (per world unit): post-classification
    /// maps Θ through the colour map, pre-classification is Θ; their extinction is Φ per
    /// opacity unit distance (a particle of weight w alone, at its centre, is as opaque as
    /// opacity w over that distance, to first order). A density field maps Φ through the
    /// whole transfer function, as the SPH renderers map theirs.
    fn classify(&self, s: &RbfSample) -> ([f64; 3], f64) {
        let unit = self.tf.tf.unit_distance;
        if let Profile::Sph(_, kind) = self.field.profile() {
            // As the SPH renderers classify their fields.
            let q = match kind {
                FieldKind::Csph => s.weighted[0] / s.density,
                FieldKind::Sph => s.weighted[0],
                FieldKind::Density => s.density,
            };
            let (rgb, alpha) = self.tf.eval(q);
            return (rgb, self.tf.tf.extinction(alpha));
        }
        match self.field.colouring() {
            Colouring::Post => {
                let theta = s.weighted[0] / s.density;
                (self.tf.eval(theta).0, s.density / unit)
            }
            Colouring::Pre => (s.weighted.map(|w| w / s.density), s.density / unit),
            Colouring::Density => {
                let (rgb, alpha) = self.tf.eval(s.density);
                (rgb, self.tf.tf.extinction(alpha))
            }
        }
    }
}

/// The four planes (`[n, d]`, `|n| = 1`, `n·x + d >= 0` inside) of the frustum through the
/// outer edges of the pixels `columns × rows`: every ray through one of their centres lies in
/// it. Each plane holds two adjacent corner rays (`o + t·d`): the points `o_a`, `o_a + d_a`
/// and `o_b + d_b` (the eye and two directions in perspective; a row or column of parallel
/// rays otherwise).
fn tile_planes(frame: &ViewFrame, (columns, rows): (&Range<u32>, &Range<u32>)) -> [[f64; 4]; 4] {
    let (x0, x1) = (f64::from(columns.start), f64::from(columns.end));
    let (y0, y1) = (f64::from(rows.start), f64::from(rows.end));
    let corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)].map(|(x, y)| frame.ray_at(x, y));
    let (oc, dc) = frame.ray_at(0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let inner = oc + dc;
    std::array::from_fn(|k| {
        let (oa, da) = corners[k];
        let (ob, db) = corners[(k + 1) % 4];
        let n = da.cross(ob + db - oa).normalize_or_zero();
        let d = -n.dot(oa);
        if n.dot(inner) + d < 0.0 {
            [-n.x, -n.y, -n.z, -d]
        } else {
            [n.x, n.y, n.z, d]
        }
    })
}

/// The world step of `rbf` for `field` (see [`RbfRenderParams::step_for`]), refused when a
/// ray across the data would take more than [`MAX_RBF_STEPS`] samples; `None` when no
/// particle is visible.
pub fn rbf_step_checked(
    field: &RbfField,
    params: &RenderParams,
    rbf: &RbfRenderParams,
) -> Result<Option<f64>, RenderError> {
    let Some(step) = rbf.step_for(field, params) else {
        return Ok(None);
    };
    let b = field.bvh().bounds();
    let extent = (0..3)
        .map(|a| f64::from(b.hi[a] - b.lo[a]).powi(2))
        .sum::<f64>()
        .sqrt();
    if !(step.is_finite() && step > 0.0) || extent / step > MAX_RBF_STEPS {
        return Err(RenderError::Rbf(format!(
            "a step of {step:e} world units over data {extent:e} across would take more than {MAX_RBF_STEPS:e} samples a ray: raise the step (or lower the sampling scale)"
        )));
    }
    Ok(Some(step))
}

/// Renders the RBF field `field` (built with `tf`, see [`RbfField::build`]): each pixel the
/// mean of `rbf.spp` jittered passes. Uses `params`' size, minimum transmittance, sampling
/// scale and per-pixel depth range; refuses iso-surfaces and lighting.
pub fn render_rbf(
    field: &RbfField,
    camera: &Camera,
    tf: &TransferFunction,
    params: &RenderParams,
    rbf: &RbfRenderParams,
) -> Result<(Image, RenderStats), RenderError> {
    validate(params)?;
    refuse_surfaces(params, "the RBF renderer")?;
    if rbf.spp == 0 {
        return Err(RenderError::Rbf(
            "samples per pixel must be at least 1".into(),
        ));
    }
    let (w, h) = (params.width, params.height);
    let frame = camera.frame(w, h)?;
    let mut stats = RenderStats {
        particles: field.bvh().len(),
        width: w,
        height: h,
        ..Default::default()
    };
    let mut image = Image::new(w, h);
    let Some(step) = rbf_step_checked(field, params, rbf)? else {
        return Ok((image, stats)); // nothing visible
    };
    let marcher = Marcher {
        field,
        tf: TfLookup::new(tf),
        params,
        rbf,
        frame,
        step,
    };
    let t0 = Instant::now();
    let (tx, ty) = (w.div_ceil(TILE), h.div_ceil(TILE));
    let tile_range = |t: u32| {
        let (x, y) = (t % tx * TILE, t / tx * TILE);
        (x..(x + TILE).min(w), y..(y + TILE).min(h))
    };
    let tiles: Vec<(u32, Vec<PixelSum>)> = (0..tx * ty)
        .into_par_iter()
        .map_init(Scratch::default, |sc, t| {
            (t, marcher.tile(tile_range(t), sc))
        })
        .collect();
    let inv = 1.0 / f64::from(rbf.spp);
    for (t, pixels) in tiles {
        let (columns, rows) = tile_range(t);
        let coords = rows.flat_map(|j| columns.clone().map(move |i| (i, j)));
        for ((i, j), p) in coords.zip(pixels) {
            let k = image.index(i, j);
            image.rgba[k] = p.rgba.map(|v| (v * inv) as f32);
            image.depth[k] = p.depth;
            stats.samples += p.samples;
        }
    }
    stats.stages.push(("raycast", ms(t0)));
    stats.stages.push(("total", ms(t0)));
    Ok((image, stats))
}
