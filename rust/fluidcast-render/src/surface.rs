//! Iso-surfaces of the reconstructed field, found exactly along each ray, shaded with analytic
//! gradients and composited in depth order with the volume (Fraedrich et al. 2010, Sec. 5;
//! the level set of the SPH sum itself, not of a resampled grid).
//!
//! Per ray, the particles whose support the ray passes are kept with their passage
//! ([`Pass`]). The iso field is summed at the ray's depth samples (the same depths the volume
//! uses); where consecutive samples lie on either side of an iso value, the crossing between
//! them is refined on the exact kernel sum along the ray (Illinois regula falsi, to 1e-9 of
//! the step), and the surface normal there is the analytic gradient
//! `∇f = Σ w_j shape'(q) / H_j · (x − c_j)/|x − c_j|` (with the quotient rule for CSPH), so
//! neither the depth nor the shading shows the sampling.

use std::ops::Range;
use std::sync::Arc;

use fluidcast_grid::{within, Ray, ViewParticle};
use fluidcast_sph::FieldKind;
use fluidcast_view::{Lighting, LightingError, TfLookup, ViewFrame};

use crate::raycast::{Compositor, Sums};
use crate::RenderParams;

/// The reconstructed field whose level sets are drawn.
#[derive(Debug, Clone, PartialEq)]
pub enum IsoField {
    /// The colour field `Σ V_j W_j` (V = m/ρ): about 1 inside the fluid, falling to 0 across
    /// one support radius at a free surface, so its 0.5 level is the usual SPH free surface.
    Colour,
    /// The density `Σ m_j W_j` (mass / world unit³).
    Density,
    /// The Shepard-normalised (CSPH) sum of a per-particle attribute: these values, one per
    /// particle in the particles' order, or the rendered values (`None`).
    Attribute(Option<Arc<[f32]>>),
}

impl IsoField {
    /// The command-line name of the field (`ARRAY` stands for an attribute).
    pub fn name(&self) -> &'static str {
        match self {
            IsoField::Colour => "colour",
            IsoField::Density => "density",
            IsoField::Attribute(_) => "attribute",
        }
    }
}

/// Iso-surfaces to draw, and how: what [`RenderParams::surfaces`] holds.
#[derive(Debug, Clone, PartialEq)]
pub struct Surfaces {
    /// The field whose iso-surfaces are drawn.
    pub field: IsoField,
    /// The iso values (in the field's units), at least one.
    pub values: Vec<f64>,
    /// Opacity of every surface, in (0, 1]: 1 hides what lies behind the first surface.
    pub opacity: f64,
    /// A solid linear RGB colour (0..1); `None`: the transfer function's colour of the
    /// rendered field at the surface point (the field as [`RenderParams::field`] says).
    pub colour: Option<[f64; 3]>,
    /// How the surfaces are lit.
    pub lighting: Lighting,
    /// Also composite the emission–absorption volume of the rendered field, in depth order
    /// with the surfaces (a step that a surface cuts is split there); `false`: surfaces only.
    pub volume: bool,
}

impl Default for Surfaces {
    fn default() -> Self {
        Surfaces {
            field: IsoField::Colour,
            values: vec![0.5],
            opacity: 1.0,
            colour: None,
            lighting: Lighting::default(),
            volume: false,
        }
    }
}

/// Why iso-surface parameters were refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SurfaceError {
    /// No iso value.
    #[error("no iso value given")]
    NoValues,
    /// An iso value that is NaN or infinite.
    #[error("iso value {0} is not finite")]
    Value(f64),
    /// A surface opacity outside (0, 1].
    #[error("surface opacity {0} must be in (0, 1]")]
    Opacity(f64),
    /// A surface colour outside 0..1.
    #[error("surface colour {0:?} must be three numbers in 0..1")]
    Colour([f64; 3]),
    /// Bad lighting coefficients or direction.
    #[error(transparent)]
    Lighting(#[from] LightingError),
    /// An iso attribute of another length than the particles (values, particles).
    #[error("the iso attribute has {0} values for {1} particles")]
    AttributeLength(usize, usize),
    /// A renderer (named) that draws no iso-surfaces yet.
    #[error("{0} does not draw iso-surfaces yet; render them with the reference renderer (CLI: --mode reference, which --iso chooses by default)")]
    Unsupported(&'static str),
    /// A renderer (named) that draws opaque surfaces over the volume only.
    #[error("{0} draws opaque surfaces over the volume only (the volume stops at the first surface); translucent surfaces with the volume render with the reference renderer (CLI: --mode reference)")]
    Translucent(&'static str),
}

impl Surfaces {
    /// Checks the parameters against `particles` particles.
    pub fn validate(&self, particles: usize) -> Result<(), SurfaceError> {
        if self.values.is_empty() {
            return Err(SurfaceError::NoValues);
        }
        if let Some(v) = self.values.iter().find(|v| !v.is_finite()) {
            return Err(SurfaceError::Value(*v));
        }
        if !(self.opacity > 0.0 && self.opacity <= 1.0) {
            return Err(SurfaceError::Opacity(self.opacity));
        }
        if let Some(c) = self.colour {
            if !c.iter().all(|x| (0.0..=1.0).contains(x)) {
                return Err(SurfaceError::Colour(c));
            }
        }
        self.lighting.validate()?;
        if let IsoField::Attribute(Some(v)) = &self.field {
            if v.len() != particles {
                return Err(SurfaceError::AttributeLength(v.len(), particles));
            }
        }
        Ok(())
    }

    /// Which of a [`Point`]'s sums is the iso field's numerator (1, 2 or 3), and whether it
    /// is divided by the Shepard sum.
    fn sum_index(&self) -> (usize, bool) {
        match self.field {
            IsoField::Colour => (SHEPARD, false),
            IsoField::Density => (DENSITY, false),
            IsoField::Attribute(_) => (ISO, true),
        }
    }
}

/// Which of a [`Point`]'s sums the rendered field is, and whether it is divided by the
/// Shepard sum (see [`Point::value`]).
fn rendered_pick(field: FieldKind) -> (usize, bool) {
    match field {
        FieldKind::Csph => (RENDERED, true),
        FieldKind::Sph => (RENDERED, false),
        FieldKind::Density => (DENSITY, false),
    }
}

/// Indices of a pass's weights and a point's sums: `norm(H) ·` V·A (the rendered attribute),
/// V (Shepard / colour), m (density), V·B (the iso attribute).
const RENDERED: usize = 0;
const SHEPARD: usize = 1;
const DENSITY: usize = 2;
const ISO: usize = 3;

/// One particle's passage through a ray: what evaluating the field exactly along it takes.
#[derive(Debug, Clone)]
struct Pass {
    /// Centre in view space.
    c: [f64; 3],
    /// Depth of closest approach and the squared distance there.
    t: f64,
    r2: f64,
    inv_h: f64,
    /// The ray's depth samples inside the support.
    k: Range<usize>,
    w: [f64; 4],
}

/// The four sums at one point of a ray and their view-space gradients.
#[derive(Debug, Clone, Copy, Default)]
struct Point {
    s: [f64; 4],
    g: [[f64; 3]; 4],
}

impl Point {
    /// The field `(numerator index, normalised)` at this point, `None` for a CSPH quotient
    /// where no particle reaches.
    fn value(&self, (n, norm): (usize, bool)) -> Option<f64> {
        if !norm {
            Some(self.s[n])
        } else if self.s[SHEPARD] > 0.0 {
            Some(self.s[n] / self.s[SHEPARD])
        } else {
            None
        }
    }

    /// The gradient of that field (quotient rule for CSPH), view space.
    fn gradient(&self, (n, norm): (usize, bool)) -> [f64; 3] {
        let (a, ga) = (self.s[n], self.g[n]);
        if !norm {
            return ga;
        }
        let (s, gs) = (self.s[SHEPARD], self.g[SHEPARD]);
        if s <= 0.0 {
            return [0.0; 3];
        }
        [0, 1, 2].map(|i| (ga[i] * s - a * gs[i]) / (s * s))
    }

    /// The rendered field, as the volume renderer reconstructs it.
    fn rendered(&self, field: FieldKind) -> Option<f64> {
        self.value(rendered_pick(field))
    }
}

/// Adds the first surfaces' world normals, one per pixel, to `image` as the AOVs
/// `normal_x`, `normal_y`, `normal_z` (0 where a pixel has no surface).
pub fn add_normal_aovs(image: &mut fluidcast_image::Image, normals: &[[f32; 3]]) {
    for (a, name) in ["normal_x", "normal_y", "normal_z"].into_iter().enumerate() {
        image
            .aovs
            .push((name.into(), normals.iter().map(|n| n[a]).collect()));
    }
}

/// Per-tile scratch of the surface caster: the ray's passes and the iso field's sums at the
/// depth samples (numerator, Shepard), zero outside the last ray's touched range.
pub(crate) struct SurfaceScratch {
    passes: Vec<Pass>,
    num: Vec<f64>,
    den: Vec<f64>,
}

impl SurfaceScratch {
    pub fn new(samples: usize) -> SurfaceScratch {
        SurfaceScratch {
            passes: Vec::new(),
            num: vec![0.0; samples],
            den: vec![0.0; samples],
        }
    }
}

/// What one ray of the surface caster gives: its compositing state and, where it met a
/// surface in its composited range, the first one's view depth and world-space unit normal
/// (facing the eye).
pub(crate) struct SurfaceRay {
    pub comp: Compositor,
    pub first: Option<(f32, [f32; 3])>,
}

/// The fixed inputs of one frame's surface casting.
pub(crate) struct SurfaceCaster<'a> {
    pub surfaces: &'a Surfaces,
    pub params: &'a RenderParams,
    pub frame: &'a ViewFrame,
    pub tf: &'a TfLookup<'a>,
    /// Sample depths: `zs.len()` samples, `zs[k + 1]` the end of step k (one more entry).
    pub zs: &'a [f64],
}

impl SurfaceCaster<'_> {
    /// Casts pixel (i, j)'s ray through `local` (the particles that may reach it, each with
    /// its iso attribute value `b`), with `sums` for the volume.
    pub fn cast(
        &self,
        ray: &Ray,
        local: &[(ViewParticle, f64)],
        scratch: &mut SurfaceScratch,
        sums: &mut Sums,
        (i, j): (u32, u32),
    ) -> SurfaceRay {
        let n = self.zs.len() - 1;
        let samples = &self.zs[..n];
        let kernel = self.params.kernel;
        let pick = self.surfaces.sum_index();
        scratch.passes.clear();
        let (mut lo, mut hi) = (usize::MAX, 0);
        for (p, b) in local {
            let Some(pass) = ray.passage(p) else { continue };
            let k = within(samples, pass.z0, pass.z1);
            if self.surfaces.volume {
                sums.scatter_passage(ray, p, &pass, samples, kernel);
            }
            if !k.is_empty() {
                (lo, hi) = (lo.min(k.start), hi.max(k.end));
            }
            let norm = kernel.norm(p.h());
            scratch.passes.push(Pass {
                c: p.c,
                t: pass.t,
                r2: pass.r2,
                inv_h: 1.0 / p.h(),
                k,
                w: [p.v() * p.a(), p.v(), p.m(), p.v() * b].map(|x| x * norm),
            });
        }
        let mut out = SurfaceRay {
            comp: Compositor::for_pixel(self.params, i, j),
            first: None,
        };
        if lo >= hi {
            return out;
        }
        // The walk adds each pass's weights when it reaches the pass's first sample, so a ray
        // that an opaque surface ends never sums what lies behind it.
        scratch
            .passes
            .sort_unstable_by_key(|p| (p.k.start, p.k.end));
        let mut walk = Walk {
            caster: self,
            ray,
            passes: &scratch.passes,
            num: &mut scratch.num,
            den: &mut scratch.den,
            added: 0,
            pick,
        };
        walk.run(lo.saturating_sub(1)..(hi + 1).min(n), sums, &mut out);
        scratch.num[lo..hi].fill(0.0);
        scratch.den[lo..hi].fill(0.0);
        if self.surfaces.volume {
            sums.clear(lo..hi);
        }
        out
    }
}

/// One ray's walk over its samples: finds, refines, shades and composites the crossings,
/// and the volume between them.
struct Walk<'a> {
    caster: &'a SurfaceCaster<'a>,
    ray: &'a Ray,
    /// The ray's passes in the order of their first sample.
    passes: &'a [Pass],
    /// The iso field's numerator and Shepard sums at the samples, complete up to the first
    /// sample of `passes[added]`.
    num: &'a mut [f64],
    den: &'a mut [f64],
    added: usize,
    pick: (usize, bool),
}

impl Walk<'_> {
    /// Adds the passes that reach sample `k` or an earlier one (so the sums are complete
    /// there and at every sample before it).
    fn sum_to(&mut self, k: usize) {
        let (zs, kernel) = (self.caster.zs, self.caster.params.kernel);
        let n = self.pick.0;
        while let Some(p) = self.passes.get(self.added).filter(|p| p.k.start <= k) {
            for s in p.k.clone() {
                let dz = zs[s] - p.t;
                let w = kernel.shape((p.r2 + self.ray.dd * dz * dz).sqrt() * p.inv_h);
                self.num[s] += p.w[n] * w;
                self.den[s] += p.w[SHEPARD] * w;
            }
            self.added += 1;
        }
    }

    /// The iso field at sample k (`None`: an undefined CSPH quotient).
    fn at(&self, k: usize) -> Option<f64> {
        if !self.pick.1 {
            Some(self.num[k])
        } else if self.den[k] > 0.0 {
            Some(self.num[k] / self.den[k])
        } else {
            None
        }
    }

    /// The sums (and gradients when asked) exactly at view depth `z` along the ray.
    fn point(&self, z: f64, gradient: bool) -> Point {
        let kernel = self.caster.params.kernel;
        let (o, d) = (self.ray.o, self.ray.d);
        let x = [o[0] + z * d[0], o[1] + z * d[1], o[2] + z * d[2]];
        let mut pt = Point::default();
        for p in self.passes {
            let dz = z - p.t;
            let r = (p.r2 + self.ray.dd * dz * dz).sqrt();
            let q = r * p.inv_h;
            if q >= 1.0 {
                continue;
            }
            let s = kernel.shape(q);
            for (sum, w) in pt.s.iter_mut().zip(p.w) {
                *sum += w * s;
            }
            if gradient && r > 0.0 {
                let f = kernel.shape_slope(q) * p.inv_h / r;
                let dx = [x[0] - p.c[0], x[1] - p.c[1], x[2] - p.c[2]];
                for (g, w) in pt.g.iter_mut().zip(p.w) {
                    for a in 0..3 {
                        g[a] += w * f * dx[a];
                    }
                }
            }
        }
        pt
    }

    /// The depth in `(za, zb)` where the field crosses `v`, given its values `fa`, `fb` on
    /// either side (Illinois regula falsi on the exact sum). `None` where the iteration meets
    /// a gap in which no particle reaches (an undefined CSPH quotient): the field jumps across
    /// the gap rather than crossing the level, so there is no surface there.
    fn refine(&self, v: f64, (za, fa): (f64, f64), (zb, fb): (f64, f64)) -> Option<f64> {
        let (mut a, mut ga, mut b, mut gb) = (za, fa - v, zb, fb - v);
        let linear = |a: f64, ga: f64, b: f64, gb: f64| {
            let z = (a * gb - b * ga) / (gb - ga);
            if z > a && z < b {
                z
            } else {
                0.5 * (a + b)
            }
        };
        let mut kept = 0i8; // which end stayed twice in a row (Illinois halves its value)
        for _ in 0..60 {
            let z = linear(a, ga, b, gb);
            if b - a <= 1e-9 * (zb - za) {
                return Some(z);
            }
            let f = self.point(z, false).value(self.pick)?;
            let g = f - v;
            if (g >= 0.0) == (ga >= 0.0) {
                (a, ga) = (z, g);
                if kept == 1 {
                    gb *= 0.5;
                }
                kept = 1;
            } else {
                (b, gb) = (z, g);
                if kept == -1 {
                    ga *= 0.5;
                }
                kept = -1;
            }
        }
        Some(linear(a, ga, b, gb))
    }

    /// Adds the crossings between samples k and k + 1, refined: (depth, rising).
    fn crossings(&self, k: usize, out: &mut Vec<(f64, bool)>) {
        let (Some(fa), Some(fb)) = (self.at(k), self.at(k + 1)) else {
            return;
        };
        let zs = self.caster.zs;
        for &v in &self.caster.surfaces.values {
            if (fa >= v) != (fb >= v) {
                if let Some(z) = self.refine(v, (zs[k], fa), (zs[k + 1], fb)) {
                    out.push((z, fb >= v));
                }
            }
        }
    }

    /// Adds the crossings hidden between samples m − 1 and m + 1: where sample m is a local
    /// maximum below an iso value (or a minimum above it), the field between the samples may
    /// still pass the value (a ray grazing a surface at a silhouette, a sheet or droplet
    /// thinner than a depth sample). The extremum of the exact sum on that span (golden
    /// section) decides; beyond the value, the crossings on either side of it are refined.
    /// Searched only where the value lies within the samples' own swing of the extremum
    /// sample (`|v − f_m| ≤ |f_m − f_{m±1}|`, the farther neighbour): a parabola through the
    /// samples overshoots its largest sample by at most 1/8 of that swing, so a field that
    /// needs more between two samples is far from smooth at this sampling, while the ripples
    /// inside a fluid (colour ≈ 1 against a value of 0.5) cost no search.
    fn hidden(&self, m: usize, out: &mut Vec<(f64, bool)>) {
        let zs = self.caster.zs;
        if m == 0 || m + 1 >= zs.len() - 1 {
            return;
        }
        let (Some(a), Some(f), Some(b)) = (self.at(m - 1), self.at(m), self.at(m + 1)) else {
            return;
        };
        let values = &self.caster.surfaces.values;
        let swing = (f - a).abs().max((f - b).abs());
        let near = |v: f64| (v - f).abs() <= swing;
        let max = f >= a && f >= b && values.iter().any(|&v| f < v && near(v));
        let min = f <= a && f <= b && values.iter().any(|&v| f >= v && near(v));
        if !(max || min) {
            return;
        }
        let Some((ze, fe)) = self.extremum(zs[m - 1], zs[m + 1], max) else {
            return;
        };
        for &v in values {
            let beyond = if max {
                f < v && fe >= v
            } else {
                f >= v && fe < v
            };
            if beyond {
                if let Some(z) = self.refine(v, (zs[m - 1], a), (ze, fe)) {
                    out.push((z, max));
                }
                if let Some(z) = self.refine(v, (ze, fe), (zs[m + 1], b)) {
                    out.push((z, !max));
                }
            }
        }
    }

    /// The largest (`max`) or smallest value of the exact field on `[a, b]` by golden-section
    /// search, and where; `None` where the field is undefined on the way.
    fn extremum(&self, mut a: f64, mut b: f64, max: bool) -> Option<(f64, f64)> {
        let sign = if max { 1.0 } else { -1.0 };
        let f = |z: f64| self.point(z, false).value(self.pick).map(|x| sign * x);
        let g = 0.5 * (5f64.sqrt() - 1.0);
        let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
        let (mut fc, mut fd) = (f(c)?, f(d)?);
        for _ in 0..30 {
            if fc > fd {
                (b, d, fd) = (d, c, fc);
                c = b - g * (b - a);
                fc = f(c)?;
            } else {
                (a, c, fc) = (c, d, fd);
                d = a + g * (b - a);
                fd = f(d)?;
            }
        }
        let z = 0.5 * (a + b);
        Some((z, sign * f(z)?))
    }

    /// Walks steps `range` front to back, compositing volume parts and surfaces.
    fn run(&mut self, range: Range<usize>, sums: &Sums, out: &mut SurfaceRay) {
        let (zs, params) = (self.caster.zs, self.caster.params);
        let min_t = params.min_transmittance;
        // Crossings found but not yet composited (a hidden one may lie in the next step).
        let mut pending: Vec<(f64, bool)> = Vec::new();
        for k in range {
            self.sum_to(k + 2); // crossings to k + 1, extrema at k + 1 (its neighbour k + 2)
            if k + 1 < zs.len() - 1 {
                self.crossings(k, &mut pending);
                self.hidden(k + 1, &mut pending);
                pending.sort_by(|a, b| a.0.total_cmp(&b.0));
            }
            let here = pending.partition_point(|h| h.0 < zs[k + 1]);
            let hits: Vec<(f64, bool)> = pending.drain(..here).collect();
            let volume = self
                .caster
                .surfaces
                .volume
                .then(|| sums.value(k, params.field))
                .flatten();
            let mut z0 = zs[k];
            let light = |rgb| self.lit(zs[k], rgb);
            for &(z, rising) in &hits {
                if let Some(q) = volume {
                    out.comp
                        .sample_lit(self.caster.tf, q, (z0, z), self.ray.dlen, min_t, light);
                }
                z0 = z;
                self.surface(z, rising, out);
                if out.comp.done {
                    return;
                }
            }
            if let Some(q) = volume {
                let z = (z0, zs[k + 1]);
                out.comp
                    .sample_lit(self.caster.tf, q, z, self.ray.dlen, min_t, light);
            }
            if out.comp.done {
                return;
            }
        }
    }

    /// A volume sample's colour at depth `z` lit as [`RenderParams::volume_lighting`] says,
    /// its normal the analytic gradient of the rendered field there (unlit without).
    fn lit(&self, z: f64, rgb: [f64; 3]) -> [f64; 3] {
        let Some(lighting) = &self.caster.params.volume_lighting else {
            return rgb;
        };
        let pick = rendered_pick(self.caster.params.field);
        let g = self.point(z, true).gradient(pick);
        let (n, to_eye) = self.caster.facing(self.ray, g, true);
        let forward = self.caster.frame.forward.to_array();
        lighting.shade_volume(rgb, n, to_eye, forward)
    }

    /// Shades and composites the surface at depth `z` (`rising`: the field grows past it).
    fn surface(&self, z: f64, rising: bool, out: &mut SurfaceRay) {
        if z >= out.comp.limit || z <= out.comp.near {
            out.composite_outside(z);
            return;
        }
        let pt = self.point(z, true);
        let hit = Hit {
            z,
            gradient: pt.gradient(self.pick),
            rising,
            rendered: pt.rendered(self.caster.params.field),
        };
        self.caster.shade(self.ray, &hit, out);
    }
}

/// A surface point on a ray: its view depth, the iso field's view-space gradient there,
/// whether the field grows past it, and the rendered field's value (for the colour map).
pub(crate) struct Hit {
    pub z: f64,
    pub gradient: [f64; 3],
    pub rising: bool,
    pub rendered: Option<f64>,
}

impl SurfaceRay {
    /// A surface at depth `z` outside the ray's composited range: past its limit the ray is
    /// done; in front of its start nothing happens.
    pub fn composite_outside(&mut self, z: f64) {
        if z >= self.comp.limit {
            self.comp.done = true; // behind opaque geometry or past the ray's region
        }
    }
}

impl SurfaceCaster<'_> {
    /// The world-space unit normal of a level set with view-space gradient `g` on `ray`
    /// (against the gradient where the field rises along the ray, `rising`, else along it:
    /// facing back toward the ray's origin; the direction to the eye where `g` is 0), and the
    /// direction to the eye.
    fn facing(&self, ray: &Ray, g: [f64; 3], rising: bool) -> ([f64; 3], [f64; 3]) {
        let to_eye = ray.d.map(|x| -x / ray.dlen);
        let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
        let n = if len > 0.0 {
            let s = if rising { -1.0 / len } else { 1.0 / len };
            g.map(|x| x * s)
        } else {
            to_eye
        };
        let f = self.frame;
        (f.direction_to_world(n), f.direction_to_world(to_eye))
    }

    /// Lights `hit` on `ray` (normal facing back along the ray, in world space) and
    /// composites it; the first one composited is the ray's surface (Z and normal).
    pub fn shade(&self, ray: &Ray, hit: &Hit, out: &mut SurfaceRay) {
        let (n, to_eye) = self.facing(ray, hit.gradient, hit.rising);
        let f = self.frame;
        let base = match self.surfaces.colour {
            Some(rgb) => rgb,
            None => hit.rendered.map_or([0.8; 3], |q| self.tf.eval(q).0),
        };
        let rgb = self
            .surfaces
            .lighting
            .shade(base, n, to_eye, f.forward.to_array());
        let a = self.surfaces.opacity;
        out.comp.add(
            [a * rgb[0], a * rgb[1], a * rgb[2], 1.0 - a],
            (hit.z, hit.z),
            self.params.min_transmittance,
        );
        if out.first.is_none() {
            out.first = Some((hit.z as f32, n.map(|x| x as f32)));
        }
    }
}
