//! The per-ray pieces both renderers share: scattering a particle into a ray's samples and
//! front-to-back compositing.

use fluidcast_grid::{within, Passage, Ray, ViewParticle};
use fluidcast_sph::{FieldKind, Kernel};
use fluidcast_view::TfLookup;

use crate::RenderParams;

/// Kernel sums of one ray at a set of sample depths.
#[derive(Debug, Clone)]
pub(crate) struct Sums {
    pub weighted: Vec<f64>,
    pub shepard: Vec<f64>,
    pub density: Vec<f64>,
}

impl Sums {
    pub fn new(n: usize) -> Sums {
        Sums {
            weighted: vec![0.0; n],
            shepard: vec![0.0; n],
            density: vec![0.0; n],
        }
    }

    /// Adds particle `p`'s kernel weights at the samples `zs` (ascending view depths) that lie
    /// inside its support along `ray`; returns the touched index range.
    #[inline]
    pub fn scatter(
        &mut self,
        ray: &Ray,
        p: &ViewParticle,
        zs: &[f64],
        kernel: Kernel,
    ) -> Option<std::ops::Range<usize>> {
        self.scatter_passage(ray, p, &ray.passage(p)?, zs, kernel)
    }

    /// [`Sums::scatter`] for a passage of `ray` through `p` already found.
    #[inline]
    pub fn scatter_passage(
        &mut self,
        ray: &Ray,
        p: &ViewParticle,
        pass: &Passage,
        zs: &[f64],
        kernel: Kernel,
    ) -> Option<std::ops::Range<usize>> {
        let range = within(zs, pass.z0, pass.z1);
        if range.is_empty() {
            return None;
        }
        // W = norm(H)·shape(r/H): the normalisation and the particle's weights once, the
        // shape per sample, in a loop per kernel that the compiler can vectorise.
        let norm = kernel.norm(p.h());
        let along = Along {
            t: pass.t,
            r2: pass.r2,
            dd: ray.dd,
            inv_h: 1.0 / p.h(),
        };
        let w = [p.v() * p.a() * norm, p.v() * norm, p.m() * norm];
        let out = [
            &mut self.weighted[range.clone()],
            &mut self.shepard[range.clone()],
            &mut self.density[range.clone()],
        ];
        let zs = &zs[range.clone()];
        match kernel {
            Kernel::CubicSpline => along.add(|q| Kernel::CubicSpline.shape(q), zs, w, out),
            Kernel::Quintic => along.add(|q| Kernel::Quintic.shape(q), zs, w, out),
            Kernel::WendlandC2 => along.add(|q| Kernel::WendlandC2.shape(q), zs, w, out),
            Kernel::WendlandC4 => along.add(|q| Kernel::WendlandC4.shape(q), zs, w, out),
            Kernel::Poly6 => along.add(|q| Kernel::Poly6.shape(q), zs, w, out),
            Kernel::Gaussian => along.add(|q| Kernel::Gaussian.shape(q), zs, w, out),
        }
        Some(range)
    }

    /// The field value at sample `k`, or `None` when no particle contributes there.
    #[inline]
    pub fn value(&self, k: usize, field: FieldKind) -> Option<f64> {
        let s = self.shepard[k];
        if s > 0.0 {
            Some(match field {
                FieldKind::Csph => self.weighted[k] / s,
                FieldKind::Sph => self.weighted[k],
                FieldKind::Density => self.density[k],
            })
        } else {
            None
        }
    }

    pub fn clear(&mut self, r: std::ops::Range<usize>) {
        self.weighted[r.clone()].fill(0.0);
        self.shepard[r.clone()].fill(0.0);
        self.density[r].fill(0.0);
    }
}

/// A ray's passage near a particle: closest approach at view depth `t` (squared distance
/// `r2`), the ray's |d|² and 1/H.
struct Along {
    t: f64,
    r2: f64,
    dd: f64,
    inv_h: f64,
}

impl Along {
    /// Adds `w · shape(r/H)` at each depth of `zs` to the three sums in `out`.
    #[inline(always)]
    fn add(&self, shape: impl Fn(f64) -> f64, zs: &[f64], w: [f64; 3], out: [&mut [f64]; 3]) {
        let [weighted, shepard, density] = out;
        let it = zs.iter().zip(weighted).zip(shepard).zip(density);
        for (((&z, a), b), c) in it {
            let dz = z - self.t;
            let s = shape((self.r2 + self.dd * dz * dz).sqrt() * self.inv_h);
            *a += w[0] * s;
            *b += w[1] * s;
            *c += w[2] * s;
        }
    }
}

/// What a ray makes of a sample's step ([`Compositor::step`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Step {
    /// The step starts at or beyond the ray's limit: the ray is done.
    Done,
    /// The step lies wholly in front of the ray's start: not a sample of this ray.
    Before,
    /// The step to composite, from view depth `.0` to `.1`, cut at the limit.
    Kept((f64, f64)),
}

/// Front-to-back compositing state of one ray: premultiplied colour, transmittance and the
/// depth where opacity first exceeded ½. Only the part of the ray between view depths `near`
/// (the start of a cropping region) and `limit` (an opaque surface, or the region's end) is
/// composited; a step that straddles either is cut as a homogeneous segment.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Compositor {
    pub color: [f64; 3],
    pub trans: f64,
    pub depth: f32,
    pub samples: u64,
    pub done: bool,
    pub near: f64,
    pub limit: f64,
}

impl Compositor {
    /// A fresh ray that ends at view depth `limit` (`f64::INFINITY`: no opaque surface).
    #[cfg(test)]
    pub fn new(limit: f64) -> Compositor {
        Compositor::between(f64::NEG_INFINITY, limit)
    }

    /// A fresh ray that composites only from view depth `near` to `limit`.
    pub fn between(near: f64, limit: f64) -> Compositor {
        Compositor {
            color: [0.0; 3],
            trans: 1.0,
            depth: f32::INFINITY,
            samples: 0,
            // An empty range composites nothing: the ray is done before it starts.
            done: limit <= near,
            near,
            limit,
        }
    }

    /// The ray of pixel (i, j) as `params` bound it ([`RenderParams::depth_range_at`]).
    pub fn for_pixel(params: &RenderParams, i: u32, j: u32) -> Compositor {
        let (near, limit) = params.depth_range_at(i, j);
        Compositor::between(near, limit)
    }

    /// Composites a sample of value `q` standing for the step from view depth `z0` to `z1`
    /// (`dlen` world units per unit of view depth along this ray); a step that reaches past
    /// the limit or starts before `near` is cut there.
    #[inline]
    pub fn sample(&mut self, tf: &TfLookup, q: f64, z: (f64, f64), dlen: f64, min_t: f64) {
        self.sample_lit(tf, q, z, dlen, min_t, |rgb| rgb);
    }

    /// [`Compositor::sample`] with the transfer function's colour passed through `light`
    /// (called only for a sample that is composited and not fully transparent).
    #[inline]
    pub fn sample_lit(
        &mut self,
        tf: &TfLookup,
        q: f64,
        z: (f64, f64),
        dlen: f64,
        min_t: f64,
        light: impl FnOnce([f64; 3]) -> [f64; 3],
    ) {
        let (z0, z1) = match self.step(z) {
            Step::Done => {
                self.done = true;
                return;
            }
            Step::Before => return,
            Step::Kept(z) => z,
        };
        let (rgb, alpha) = tf.eval(q);
        let a = tf.tf.step_alpha(alpha, (z1 - z0) * dlen);
        let rgb = if a > 0.0 { light(rgb) } else { rgb };
        self.composite_step(rgb, a, (z0, z1), min_t);
    }

    /// What this ray makes of a sample's step from view depth `z0` to `z1`: the ray is done at
    /// a step that starts at or beyond its limit; a step wholly in front of its start is not
    /// a sample of it; any other is kept, cut at the limit. (Cut here, so that `add` sees it
    /// ending there and does not cut it again; `add` cuts its front at `near`, which for one
    /// homogeneous step is the same.)
    #[inline]
    pub fn step(&self, (z0, z1): (f64, f64)) -> Step {
        if z0 >= self.limit {
            Step::Done
        } else if z1 <= self.near {
            Step::Before
        } else {
            Step::Kept((z0, z1.min(self.limit)))
        }
    }

    /// Composites a sample of colour `rgb` and opacity `a` (already corrected for its length)
    /// over the step `z` that [`Compositor::step`] kept.
    #[inline]
    pub fn composite_step(&mut self, rgb: [f64; 3], a: f64, z: (f64, f64), min_t: f64) {
        self.samples += 1;
        self.add([a * rgb[0], a * rgb[1], a * rgb[2], 1.0 - a], z, min_t);
    }

    /// Composites a premultiplied (I rgb, T) segment from view depth `z0` to `z1`. Outside
    /// [near, limit] it is cut as a homogeneous segment would be: T^f and I (1 − T^f)/(1 − T)
    /// for the fraction f kept.
    #[inline]
    pub fn add(&mut self, mut it: [f64; 4], (z0, z1): (f64, f64), min_t: f64) {
        if z0 >= self.limit {
            self.done = true;
            return;
        }
        if z1 <= self.near {
            return;
        }
        let (a, b) = (z0.max(self.near), z1.min(self.limit));
        if a > z0 || b < z1 {
            let f = (b - a) / (z1 - z0);
            let t = it[3].powf(f);
            let s = if it[3] < 1.0 {
                (1.0 - t) / (1.0 - it[3])
            } else {
                f
            };
            it = [it[0] * s, it[1] * s, it[2] * s, t];
            self.done = b < z1;
        }
        for (c, i) in self.color.iter_mut().zip(it) {
            *c += self.trans * i;
        }
        self.trans *= it[3];
        if self.trans < 0.5 && self.depth.is_infinite() {
            self.depth = a as f32;
        }
        if self.trans < min_t {
            self.done = true;
        }
    }

    /// Premultiplied RGBA and depth.
    pub fn pixel(&self) -> ([f32; 4], f32) {
        (
            [
                self.color[0] as f32,
                self.color[1] as f32,
                self.color[2] as f32,
                (1.0 - self.trans) as f32,
            ],
            self.depth,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A homogeneous segment of extinction `sigma` (per view-depth unit) and colour `c` over
    /// `len`: premultiplied (c (1 − T), T) with T = exp(−σ len), in closed form.
    fn homogeneous(c: [f64; 3], sigma: f64, len: f64) -> [f64; 4] {
        let t = (-sigma * len).exp();
        [c[0] * (1.0 - t), c[1] * (1.0 - t), c[2] * (1.0 - t), t]
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12
    }

    /// A segment (a super-pixel's span) that reaches past opaque geometry keeps exactly the
    /// part in front of it: the same medium over the shorter length, and the ray ends there.
    #[test]
    fn a_segment_cut_by_the_limit_keeps_its_front_part() {
        let c = [0.9, 0.4, 0.1];
        for sigma in [0.3, 2.0, 7.0] {
            for (z0, z1, limit) in [(1.0, 3.0, 1.8), (0.5, 0.9, 0.55), (2.0, 6.0, 5.9)] {
                let mut comp = Compositor::new(limit);
                comp.add(homogeneous(c, sigma, z1 - z0), (z0, z1), 0.0);
                let want = homogeneous(c, sigma, limit - z0);
                for (got, w) in comp.color.iter().zip(want) {
                    assert!(close(*got, w), "{sigma} {limit}: {comp:?}");
                }
                assert!(close(comp.trans, want[3]), "{sigma} {limit}: {comp:?}");
                assert!(comp.done);
            }
        }
        // Nothing but emission (T = 1): the front fraction of it.
        let mut comp = Compositor::new(2.5);
        comp.add([0.2, 0.1, 0.05, 1.0], (2.0, 4.0), 0.0);
        assert_eq!((comp.color, comp.trans), ([0.05, 0.025, 0.0125], 1.0));
        assert!(comp.done);
    }

    /// In front of the limit a segment is composited whole (over what came before), at or
    /// beyond it not at all; the ray stops once transmittance falls below the minimum, and
    /// its depth is where it first fell below ½.
    #[test]
    fn segments_composite_front_to_back_up_to_the_limit() {
        let mut comp = Compositor::new(10.0);
        let a = homogeneous([1.0, 0.0, 0.0], 0.5, 1.0);
        let b = homogeneous([0.0, 1.0, 0.0], 1.0, 1.0);
        comp.add(a, (1.0, 2.0), 0.0);
        assert!(!comp.done && comp.depth.is_infinite());
        comp.add(b, (2.0, 3.0), 0.0);
        assert!(close(comp.color[0], a[0]) && close(comp.color[1], a[3] * b[1]));
        assert!(close(comp.trans, a[3] * b[3]));
        assert!(comp.trans < 0.5 && !comp.done);
        assert_eq!(comp.depth, 2.0);
        comp.add(b, (3.0, 4.0), 0.1);
        assert!(comp.done, "transmittance {} below 0.1", comp.trans);
        assert_eq!(comp.depth, 2.0);
        let (before, t) = (comp.color, comp.trans);
        let mut beyond = Compositor::new(3.0);
        beyond.add(a, (3.0, 4.0), 0.0);
        assert_eq!((beyond.color, beyond.trans), ([0.0; 3], 1.0));
        assert!(beyond.done);
        assert_eq!((comp.color, comp.trans), (before, t));
    }

    /// Both thresholds are strict: transmittance exactly ½ is not yet "opacity above ½" (no
    /// depth), and transmittance exactly at the minimum does not stop the ray.
    #[test]
    fn thresholds_are_crossed_only_below_them() {
        let mut comp = Compositor::new(10.0);
        comp.add([0.5, 0.0, 0.0, 0.5], (1.0, 2.0), 0.5);
        assert_eq!(comp.trans, 0.5);
        assert!(comp.depth.is_infinite() && !comp.done, "{comp:?}");
        comp.add([0.0, 0.5, 0.0, 0.5], (2.0, 3.0), 0.5);
        assert_eq!(comp.depth, 2.0);
        assert!(comp.done, "{comp:?}");
    }
}
