//! The grid renderer's inner loop: kernel sums of a bundle's rays over one span's samples,
//! filled particle by particle, [`LANES`] rays side by side: a 4 × 2 block of the bundle's
//! pixels ([`block_key`]).
//!
//! Every ray of a span samples the same depths (Hochstetter et al. 2016, Alg. 2), so the sums
//! of all its rays form one block, sample-major: `[sample][slot]`, the rays packed into whole
//! lane groups. A particle adds its weights to the lane groups its footprint reaches, a
//! whole group at a time over the samples of its depth extent; the lanes that it does
//! not reach (outside the footprint, no passage, ray already opaque) add an exact zero. The
//! sample loop is written in `pulp`'s SIMD operations and compiled for the best instruction
//! set the CPU has, chosen at run time (AVX2 + FMA on x86-64 where present, else scalar).
//!
//! The per-sample arithmetic is [`crate::raycast::Sums::scatter`]'s in single precision: the
//! closest approach of each ray to the particle is found in double precision (per particle and
//! lane group), then depths are taken relative to the span's first sample, so that the f32
//! differences along the ray lose nothing to the camera's distance. Twice the lanes of f64 in
//! a vector, and a square root that costs half. The sums then match the reference renderer's
//! to single-precision rounding (tested), not bit for bit.

use std::ops::Range;

use fluidcast_grid::{within, Ray, ViewParticle};
use fluidcast_sph::{FieldKind, Kernel};

/// Rays handled side by side: one lane group.
pub(crate) const LANES: usize = 8;

/// The order in which a bundle's rays fill lane groups: pixel (i, j) of the bundle by strips
/// of 4 columns (strips, then the rows along a strip, then the strip's columns), so that a
/// full bundle's groups are compact 4 × 2 blocks. A group costs its whole width wherever a
/// particle's footprint meets it, and a footprint that covers only some columns of the bundle
/// meets half the blocks it would meet as rows of 8: full-rate rendering of a 285k-particle
/// dam break at 1024 × 768 took 22.6 G instructions instead of 24.2 G (callgrind), the same
/// image. The passes of the image-space refinement keep to a strip too: the lattice (every
/// second pixel of every second row) packs 3 × 7 groups, the pixels between lattice pixels
/// 4 × 3 groups (by 4 × 2 blocks across the bundle they spanned 8 × 2 to 8 × 3): on a
/// 29k-particle spray at 1920 × 1080 the passes' kernel sums took 4.59 G instructions instead
/// of 4.84 G (callgrind), the same image. A ray's sums do not depend on its slot.
pub(crate) fn block_key(i: usize, j: usize) -> (usize, usize, usize) {
    (i / 4, j, i % 4)
}

/// One lane group: up to [`LANES`] rays of a bundle, their origins, directions and 1/|d|²,
/// component-wise, which lanes hold a ray (the others are padding), and the smallest columns ×
/// rows box of the bundle that holds them all.
#[derive(Debug, Clone, Copy)]
struct RayGroup {
    o: [[f64; LANES]; 3],
    d: [[f64; LANES]; 3],
    /// 1 / |d|² (for [`RayGroup::near`]) and |d|² (in single precision, for the samples).
    inv_dd: [f64; LANES],
    dd32: [f32; LANES],
    /// Whether the lane holds a ray (not padding).
    ray: [bool; LANES],
    cols: (u16, u16),
    rows: (u16, u16),
}

impl Default for RayGroup {
    fn default() -> Self {
        RayGroup {
            o: [[0.0; LANES]; 3],
            d: [[0.0; LANES]; 3],
            // Padding lanes hold no ray (never marked); dd = 1 keeps their arithmetic finite.
            inv_dd: [1.0; LANES],
            dd32: [1.0; LANES],
            ray: [false; LANES],
            cols: (u16::MAX, 0),
            rows: (u16::MAX, 0),
        }
    }
}

/// A particle's passage near the rays of a lane group (Ray::closest_approach per lane): depth
/// `t` of the closest approach relative to the span's origin depth, its squared distance `r2`,
/// the rays' |d|², and 1 for the lanes the particle reaches, 0 for the others.
struct Near {
    t: [f32; LANES],
    r2: [f32; LANES],
    dd: [f32; LANES],
    mask: [f32; LANES],
}

/// What a particle adds: its support's sample range `ks`, 1/H and its weights (rendered,
/// Shepard).
struct Particle {
    ks: Range<usize>,
    inv_h: f32,
    w: [f32; 2],
}

impl RayGroup {
    /// Up to [`LANES`] rays, each with its (column, row) in the bundle, in lane order.
    fn of(rays: &[((usize, usize), Ray)]) -> RayGroup {
        let mut g = RayGroup::default();
        for (l, &((i, j), ray)) in rays.iter().enumerate().take(LANES) {
            for a in 0..3 {
                g.o[a][l] = ray.o[a];
                g.d[a][l] = ray.d[a];
            }
            g.inv_dd[l] = 1.0 / ray.dd;
            g.dd32[l] = ray.dd as f32;
            let (i, j) = (
                i.min(usize::from(u16::MAX - 1)) as u16,
                j.min(usize::from(u16::MAX - 1)) as u16,
            );
            g.ray[l] = true;
            g.cols = (g.cols.0.min(i), g.cols.1.max(i));
            g.rows = (g.rows.0.min(j), g.rows.1.max(j));
        }
        g
    }

    /// True when some lane's ray lies in the footprint `cols` × `rows`.
    #[inline(always)]
    fn meets(&self, cols: &Range<usize>, rows: &Range<usize>) -> bool {
        let overlaps = |(lo, hi): (u16, u16), r: &Range<usize>| {
            usize::from(lo) < r.end && usize::from(hi) >= r.start
        };
        overlaps(self.cols, cols) & overlaps(self.rows, rows)
    }

    /// The closest approach of each lane's ray to `p` (its depth relative to `z_org`); `None`
    /// when no lane's ray is live and passes inside the support. (The footprint that
    /// [`RayGroup::meets`] tests holds every such ray, so it is not tested lane by lane.)
    #[inline(always)]
    fn near(&self, p: &ViewParticle, live: &[bool], z_org: f64) -> Option<Near> {
        let (o, d) = (&self.o, &self.d);
        let mut near = Near {
            t: [0.0; LANES],
            r2: [0.0; LANES],
            dd: self.dd32,
            mask: [0.0; LANES],
        };
        let h2 = p.h() * p.h();
        let mut any = false;
        for l in 0..LANES {
            let (cx, cy, cz) = (p.c[0] - o[0][l], p.c[1] - o[1][l], p.c[2] - o[2][l]);
            let t = (d[0][l] * cx + d[1][l] * cy + d[2][l] * cz) * self.inv_dd[l];
            let (qx, qy, qz) = (cx - t * d[0][l], cy - t * d[1][l], cz - t * d[2][l]);
            let r2 = qx * qx + qy * qy + qz * qz;
            let on = self.ray[l] & (r2 < h2) & live[l];
            near.t[l] = (t - z_org) as f32;
            near.r2[l] = r2 as f32;
            near.mask[l] = if on { 1.0 } else { 0.0 };
            any |= on;
        }
        any.then_some(near)
    }
}

/// Some rays of a bundle, packed [`LANES`] to a group in the order given: ray `r` of that
/// order is in slot `r` (lane `r % LANES` of group `r / LANES`). All of a bundle's rays in
/// [`block_key`] order fill its 4 × 2 blocks group by group; a subset (the pixels still to
/// cast) packs densely, so that rays not cast cost no lanes.
#[derive(Debug, Clone)]
pub(crate) struct BundleRays {
    groups: Vec<RayGroup>,
}

impl BundleRays {
    /// `rays`, each with its (column, row) in the bundle (below 2¹⁶).
    pub fn new(rays: impl IntoIterator<Item = ((usize, usize), Ray)>) -> BundleRays {
        let rays: Vec<((usize, usize), Ray)> = rays.into_iter().collect();
        BundleRays {
            groups: rays.chunks(LANES).map(RayGroup::of).collect(),
        }
    }

    /// Slots the rays take (whole groups).
    #[cfg(test)]
    pub fn slots(&self) -> usize {
        self.groups.len() * LANES
    }
}

/// The columns `cols.0..cols.1` and rows `rows.0..rows.1` of a bundle's rays (relative to
/// its first pixel) that a particle's support can reach: a superset of those whose ray
/// enters it, the exact test being [`Ray::passage`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Reach {
    pub cols: (u8, u8),
    pub rows: (u8, u8),
}

impl Reach {
    fn ranges(&self) -> (Range<usize>, Range<usize>) {
        let r = |(a, b): (u8, u8)| usize::from(a)..usize::from(b);
        (r(self.cols), r(self.rows))
    }
}

/// A particle of a span and the rays of the bundle it can reach.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Reaching {
    pub p: ViewParticle,
    pub reach: Reach,
}

/// One span's scatter: every particle of `particles`, in order, into `sums` (see
/// [`SpanSums::scatter`]). Run through [`pulp::Arch::dispatch`], which compiles it for the
/// CPU's best instruction set.
pub(crate) struct Scatter<'a> {
    pub sums: &'a mut SpanSums,
    pub rays: &'a BundleRays,
    pub particles: &'a [Reaching],
    pub zs: &'a SpanDepths,
    pub live: &'a [bool],
    pub kernel: Kernel,
    pub field: FieldKind,
}

impl pulp::WithSimd for Scatter<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, simd: S) {
        if !LANES.is_multiple_of(S::F32_LANES) {
            // A vector wider than a lane group (AVX-512, not enabled in pulp's default
            // features): one lane at a time instead.
            return self.with_simd(pulp::Scalar::new());
        }
        for r in self.particles {
            let sums = &mut *self.sums;
            sums.scatter(
                simd,
                self.rays,
                &r.p,
                r.reach.ranges(),
                self.zs,
                self.live,
                self.kernel,
                self.field,
            );
        }
    }
}

/// A span's sample depths and the end of its last step (n + 1 ascending view depths, for the
/// support's sample range and the compositing steps), and the same in single precision
/// relative to the first (for the per-sample arithmetic).
#[derive(Debug, Clone, Default)]
pub(crate) struct SpanDepths {
    z: Vec<f64>,
    rel: Vec<f32>,
}

impl SpanDepths {
    /// Takes the depths `zs`: the samples' view depths, ascending, then the last step's end.
    pub fn set(&mut self, zs: impl Iterator<Item = f64>) {
        self.z.clear();
        self.z.extend(zs);
        let org = self.origin();
        self.rel.clear();
        self.rel.extend(self.z.iter().map(|&z| (z - org) as f32));
    }

    /// The depth the relative ones are measured from.
    fn origin(&self) -> f64 {
        self.z.first().copied().unwrap_or(0.0)
    }

    /// The view depths (the samples' and the last step's end).
    pub fn z(&self) -> &[f64] {
        &self.z
    }

    /// The samples' view depths.
    fn samples(&self) -> &[f64] {
        &self.z[..self.z.len().saturating_sub(1)]
    }
}

/// Kernel sums of a bundle's rays at a span's samples: `num` the rendered sum (Σ V·q·W for
/// CSPH and SPH, Σ m·W for density), `den` the Shepard sum Σ V·W, each `[group][sample][lane]`
/// (a lane group's samples side by side, see [`SpanSums::index`]); per lane group the sample
/// range any particle may have touched.
#[derive(Debug, Clone)]
pub(crate) struct SpanSums {
    /// Samples a span may have (the capacity of a group's block).
    samples: usize,
    num: Vec<f32>,
    den: Vec<f32>,
    /// Per lane group: the samples any particle may have touched, the union over its lanes.
    touched: Vec<(usize, usize)>,
}

impl SpanSums {
    /// Sums for `slots` rays (at least [`BundleRays::slots`]) and up to `samples` samples.
    pub fn new(slots: usize, samples: usize) -> SpanSums {
        SpanSums {
            samples,
            num: vec![0.0; slots * samples],
            den: vec![0.0; slots * samples],
            touched: vec![(usize::MAX, 0); slots.div_ceil(LANES)],
        }
    }

    /// Adds particle `p`'s kernel weights to the rays of `rays` in `cols` × `rows` (a
    /// footprint that holds every ray entering its support) whose slot is `live`, at the
    /// samples `zs`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn scatter<S: pulp::Simd>(
        &mut self,
        simd: S,
        rays: &BundleRays,
        p: &ViewParticle,
        (cols, rows): (Range<usize>, Range<usize>),
        zs: &SpanDepths,
        live: &[bool],
        kernel: Kernel,
        field: FieldKind,
    ) {
        let ks = within(zs.samples(), p.c[2] - p.h(), p.c[2] + p.h());
        if ks.is_empty() || cols.is_empty() || rows.is_empty() {
            return;
        }
        // W = norm(H)·shape(r/H), the weights as Sums::scatter forms them (in double
        // precision, then rounded once).
        let norm = kernel.norm(p.h());
        let w = match field {
            FieldKind::Csph | FieldKind::Sph => p.v() * p.a() * norm,
            FieldKind::Density => p.m() * norm,
        };
        let at = Particle {
            ks,
            inv_h: (1.0 / p.h()) as f32,
            w: [w as f32, (p.v() * norm) as f32],
        };
        let z_org = zs.origin();
        for (g, group) in rays.groups.iter().enumerate() {
            if !group.meets(&cols, &rows) {
                continue;
            }
            let slot = g * LANES;
            let live = &live[slot..][..LANES];
            if let Some(near) = group.near(p, live, z_org) {
                self.touch(slot, &at.ks);
                match kernel {
                    Kernel::CubicSpline => {
                        self.add(simd, |q| cubic(simd, q), &at, &near, &zs.rel, slot)
                    }
                    Kernel::Quintic => {
                        self.add(simd, |q| quintic(simd, q), &at, &near, &zs.rel, slot)
                    }
                    Kernel::WendlandC2 => {
                        self.add(simd, |q| wendland_c2(simd, q), &at, &near, &zs.rel, slot)
                    }
                    Kernel::WendlandC4 => {
                        self.add(simd, |q| wendland_c4(simd, q), &at, &near, &zs.rel, slot)
                    }
                    Kernel::Poly6 => self.add(simd, |q| poly6(simd, q), &at, &near, &zs.rel, slot),
                    Kernel::Gaussian => self.add(
                        simd,
                        |q| lane_by_lane(simd, q, |q| Kernel::Gaussian.shape(q)),
                        &at,
                        &near,
                        &zs.rel,
                        slot,
                    ),
                }
            }
        }
    }

    /// Widens the touched range of the lane group at `slot` to the samples `ks`: one range
    /// per group, not per lane. Per lane (the range of each lane the particle reached), the
    /// compiler made the update branch-free with masked stores (`vpmaskmovq`), which are slow
    /// on AMD's cores; with a branch per lane instead, the branch missed 15 M times on a
    /// 227k-particle dam break at 1024 × 768. One range per group took that frame's full-rate
    /// ray casting, on one thread, from 1,418 ms to 1,251 ms (medians of 3 views, 2 runs each,
    /// the same image). The rays of a group are neighbours; a sample in the group's range that
    /// a lane's particles missed costs that ray's compositing one comparison
    /// ([`SpanSums::at`]).
    #[inline(always)]
    fn touch(&mut self, slot: usize, ks: &Range<usize>) {
        if let Some(tc) = self.touched.get_mut(slot / LANES) {
            *tc = (tc.0.min(ks.start), tc.1.max(ks.end));
        }
    }

    /// Adds `w · shape(r/H)` of the particle to the lane group at `slot`, at its samples
    /// (`zs`: depths relative to the span's origin): the loop of Sums::scatter's `Along::add`,
    /// the lanes side by side in whole vectors (a group is whole vectors: see
    /// [`Scatter`]'s dispatch).
    #[inline(always)]
    fn add<S: pulp::Simd>(
        &mut self,
        simd: S,
        shape: impl Fn(S::f32s) -> S::f32s,
        at: &Particle,
        near: &Near,
        zs: &[f32],
        slot: usize,
    ) {
        let inv_h = simd.splat_f32s(at.inv_h);
        // One lane vector: num += wn·s, den += wd·s with s = shape(|r|/H) and the weights
        // × 1 or × 0 (shape is finite): an exact zero for the lanes off. Fused multiply-adds
        // where the CPU has them (pulp's `mul_add_e`; a product and a sum elsewhere).
        let step = |z: S::f32s,
                    t,
                    r2,
                    dd,
                    [wn, wd]: [S::f32s; 2],
                    num: &mut S::f32s,
                    den: &mut S::f32s| {
            let dz = simd.sub_f32s(z, t);
            let d2 = simd.mul_add_e_f32s(simd.mul_f32s(dd, dz), dz, r2);
            let s = shape(simd.mul_f32s(simd.sqrt_f32s(d2), inv_h));
            *num = simd.mul_add_e_f32s(wn, s, *num);
            *den = simd.mul_add_e_f32s(wd, s, *den);
        };
        let (t, _) = S::as_simd_f32s(&near.t);
        let (r2, _) = S::as_simd_f32s(&near.r2);
        let (dd, _) = S::as_simd_f32s(&near.dd);
        let (mask, _) = S::as_simd_f32s(&near.mask);
        let (wn, wd) = (simd.splat_f32s(at.w[0]), simd.splat_f32s(at.w[1]));
        // The group's rows of the sums, borrowed once: indexing `self.num` per sample reloaded
        // both vectors' pointers and lengths and checked two ranges each time (the stores
        // might have changed them, as far as the compiler knew): 45 instructions a sample
        // before, 22 now, though only about 2 % of the time (the square root and the stores
        // bound the loop).
        let ks = at.ks.clone();
        let rows = self.index(ks.start, slot)..self.index(ks.end, slot);
        let num_rows = self.num[rows.clone()].chunks_exact_mut(LANES);
        let den_rows = self.den[rows].chunks_exact_mut(LANES);
        for ((num, den), &z) in num_rows.zip(den_rows).zip(&zs[ks]) {
            let z = simd.splat_f32s(z);
            let (num, _) = S::as_mut_simd_f32s(num);
            let (den, _) = S::as_mut_simd_f32s(den);
            for c in 0..num.len().min(den.len()).min(t.len()) {
                let w = [simd.mul_f32s(wn, mask[c]), simd.mul_f32s(wd, mask[c])];
                step(z, t[c], r2[c], dd[c], w, &mut num[c], &mut den[c]);
            }
        }
    }

    /// Where sample `k` of `slot`'s ray is held: its group's block of `samples` × [`LANES`],
    /// sample-major within it, so that a particle's samples of a lane group, and what a span
    /// touched of a group ([`SpanSums::clear`]), are consecutive vectors. (Sample-major across
    /// the bundle, `[sample][slot]`, they were a bundle's width apart; no faster or slower
    /// alone, within the runs' spread.)
    #[inline(always)]
    fn index(&self, k: usize, slot: usize) -> usize {
        let (group, lane) = (slot / LANES, slot % LANES);
        (group * self.samples + k) * LANES + lane
    }

    /// The samples any particle may have touched for the ray in `slot` (and the others of its
    /// lane group).
    pub fn touched(&self, slot: usize) -> Range<usize> {
        let (lo, hi) = self.touched.get(slot / LANES).copied().unwrap_or((0, 0));
        lo..hi.max(lo)
    }

    /// The sums (rendered, Shepard) at sample `k` of `slot`, or `None` when no particle
    /// contributes there; [`field_value`] makes the field value of them.
    #[inline(always)]
    pub fn at(&self, k: usize, slot: usize) -> Option<[f32; 2]> {
        let i = self.index(k, slot);
        let s = self.den[i];
        (s > 0.0).then(|| [self.num[i], s])
    }

    /// Zeroes what the span touched, ready for the next span.
    pub fn clear(&mut self) {
        for g in 0..self.touched.len() {
            let (start, end) = self.touched[g];
            if start >= end {
                continue;
            }
            let rows = self.index(start, g * LANES)..self.index(end, g * LANES);
            self.num[rows.clone()].fill(0.0);
            self.den[rows].fill(0.0);
            self.touched[g] = (usize::MAX, 0);
        }
    }
}

/// The field value of a sample's sums `[num, den]` (den > 0, see [`SpanSums::at`]): the
/// normalised CSPH value, or the plain sum.
#[inline(always)]
pub(crate) fn field_value([num, den]: [f32; 2], field: FieldKind) -> f64 {
    match field {
        FieldKind::Csph => f64::from(num) / f64::from(den),
        FieldKind::Sph | FieldKind::Density => f64::from(num),
    }
}

// Kernel::shape on lanes in single precision, for the polynomial kernels; 0 at q ≥ 1 (tested
// against Kernel::shape: `lane_kernels_equal_the_shapes`).

#[inline(always)]
fn support<S: pulp::Simd>(simd: S, q: S::f32s, v: S::f32s) -> S::f32s {
    let inside = simd.less_than_f32s(q, simd.splat_f32s(1.0));
    simd.select_f32s(inside, v, simd.splat_f32s(0.0))
}

#[inline(always)]
fn cubic<S: pulp::Simd>(s: S, q: S::f32s) -> S::f32s {
    let c = |x| s.splat_f32s(x);
    // 6q²(q − 1) + 1 within q ≤ ½, 2(1 − q)³ beyond, 0 from q = 1 on (1 − q clamped at 0).
    let near = s.mul_add_e_f32s(
        s.mul_f32s(s.mul_f32s(c(6.0), q), q),
        s.sub_f32s(q, c(1.0)),
        c(1.0),
    );
    let t = s.max_f32s(s.sub_f32s(c(1.0), q), c(0.0));
    let far = s.mul_f32s(s.add_f32s(t, t), s.mul_f32s(t, t));
    s.select_f32s(s.less_than_or_equal_f32s(q, c(0.5)), near, far)
}

#[inline(always)]
fn quintic<S: pulp::Simd>(s: S, q: S::f32s) -> S::f32s {
    let c = |x| s.splat_f32s(x);
    let s3 = s.mul_f32s(c(3.0), q);
    let p5 = |x: S::f32s| {
        let x = s.max_f32s(x, c(0.0));
        s.mul_f32s(s.mul_f32s(s.mul_f32s(s.mul_f32s(x, x), x), x), x)
    };
    let a = p5(s.sub_f32s(c(3.0), s3));
    let b = s.mul_f32s(c(6.0), p5(s.sub_f32s(c(2.0), s3)));
    let e = s.mul_f32s(c(15.0), p5(s.sub_f32s(c(1.0), s3)));
    support(s, q, s.add_f32s(s.sub_f32s(a, b), e))
}

#[inline(always)]
fn wendland_c2<S: pulp::Simd>(s: S, q: S::f32s) -> S::f32s {
    let c = |x| s.splat_f32s(x);
    let t = s.sub_f32s(c(1.0), q);
    let t4 = s.mul_f32s(s.mul_f32s(s.mul_f32s(t, t), t), t);
    support(
        s,
        q,
        s.mul_f32s(t4, s.add_f32s(c(1.0), s.mul_f32s(c(4.0), q))),
    )
}

#[inline(always)]
fn wendland_c4<S: pulp::Simd>(s: S, q: S::f32s) -> S::f32s {
    let c = |x| s.splat_f32s(x);
    let t = s.sub_f32s(c(1.0), q);
    let t2 = s.mul_f32s(t, t);
    let t6 = s.mul_f32s(s.mul_f32s(t2, t2), t2);
    let poly = s.add_f32s(
        s.add_f32s(c(1.0), s.mul_f32s(c(6.0), q)),
        s.mul_f32s(s.mul_f32s(c(35.0 / 3.0), q), q),
    );
    support(s, q, s.mul_f32s(t6, poly))
}

#[inline(always)]
fn poly6<S: pulp::Simd>(s: S, q: S::f32s) -> S::f32s {
    let d = s.sub_f32s(s.splat_f32s(1.0), s.mul_f32s(q, q));
    support(s, q, s.mul_f32s(s.mul_f32s(d, d), d))
}

/// A scalar shape applied lane by lane (kernels without a lane form).
#[inline(always)]
fn lane_by_lane<S: pulp::Simd>(s: S, q: S::f32s, shape: impl Fn(f64) -> f64) -> S::f32s {
    // Room for the widest vector (16 lanes of AVX-512).
    let mut buf = [0.0f32; 16];
    let lanes = &mut buf[..S::F32_LANES.min(16)];
    s.partial_store_f32s(lanes, q);
    for x in lanes.iter_mut() {
        *x = shape(f64::from(*x)) as f32;
    }
    s.partial_load_f32s(lanes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use fluidcast_view::Camera;
    use proptest::prelude::*;

    /// In [`block_key`] order a full 8 × 8 bundle's rays fill each lane group with a 4 × 2
    /// block, the lattice's (even columns and rows) with a 3 × 7 box, and the other pixels'
    /// (the refinement's second pass) with at most a 4 × 3 box.
    #[test]
    fn block_order_packs_compact_blocks() {
        let extent = |g: &[(usize, usize)]| {
            let (cols, rows) = (g.iter().map(|p| p.0), g.iter().map(|p| p.1));
            let span = |v: Vec<usize>| v.iter().max().unwrap() - v.iter().min().unwrap() + 1;
            (span(cols.collect()), span(rows.collect()))
        };
        let mut all: Vec<(usize, usize)> =
            (0..8).flat_map(|j| (0..8).map(move |i| (i, j))).collect();
        all.sort_by_key(|&(i, j)| block_key(i, j));
        for g in all.chunks(LANES) {
            assert_eq!(extent(g), (4, 2), "{g:?}");
        }
        type Pixels = Vec<(usize, usize)>;
        let (lattice, between): (Pixels, Pixels) =
            all.iter().partition(|&&(i, j)| i % 2 == 0 && j % 2 == 0);
        for g in lattice.chunks(LANES) {
            assert_eq!(extent(g), (3, 7), "{g:?}");
        }
        for g in between.chunks(LANES) {
            let (cols, rows) = extent(g);
            assert!(cols <= 4 && rows <= 3, "{g:?}");
        }
    }

    /// Each kernel's lane form equals `Kernel::shape` to 3e-6 relative (the quintic's terms
    /// cancel), at q from 0 to 1.2 (both sides of the cubic's and quintic's joints, and beyond
    /// the support), on the CPU's best instruction set and on scalar lanes.
    #[test]
    fn lane_kernels_equal_the_shapes() {
        struct Shapes(Vec<f32>);
        impl pulp::WithSimd for Shapes {
            type Output = Vec<[f32; 6]>;
            #[inline(always)]
            fn with_simd<S: pulp::Simd>(self, simd: S) -> Self::Output {
                let mut out = Vec::new();
                let mut buf = [0.0f32; 16];
                let n = S::F32_LANES.min(16);
                for q in self.0.chunks(n) {
                    buf[..q.len()].copy_from_slice(q);
                    let v = simd.partial_load_f32s(&buf[..n]);
                    let ks = [
                        cubic(simd, v),
                        quintic(simd, v),
                        wendland_c2(simd, v),
                        wendland_c4(simd, v),
                        poly6(simd, v),
                        v,
                    ];
                    let mut lanes = [[0.0f32; 16]; 6];
                    for (l, k) in lanes.iter_mut().zip(ks) {
                        simd.partial_store_f32s(&mut l[..n], k);
                    }
                    out.extend((0..q.len()).map(|i| [0, 1, 2, 3, 4, 5].map(|k| lanes[k][i])));
                }
                out
            }
        }
        let qs: Vec<f32> = (0..=1200)
            .map(|i| i as f32 / 1000.0)
            .chain([0.5f32.next_up(), 1.0f32.next_down(), 1.0f32.next_up()])
            .collect();
        let kernels = [
            Kernel::CubicSpline,
            Kernel::Quintic,
            Kernel::WendlandC2,
            Kernel::WendlandC4,
            Kernel::Poly6,
        ];
        for got in [
            pulp::Arch::new().dispatch(Shapes(qs.clone())),
            pulp::WithSimd::with_simd(Shapes(qs.clone()), pulp::Scalar::new()),
        ] {
            for (q, v) in qs.iter().zip(&got) {
                assert_eq!(v[5], *q);
                for (k, kernel) in kernels.iter().enumerate() {
                    let want = kernel.shape(f64::from(*q));
                    assert!(
                        (f64::from(v[k]) - want).abs() <= 3e-6 * want.abs().max(1.0),
                        "{kernel:?} at q = {q}: {} vs {want}",
                        v[k]
                    );
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]
        /// `near` marks exactly the lanes whose ray is live and passes inside the support (as
        /// [`Ray::passage`] decides), with each lane's closest approach, and is `None` when it
        /// marks none; `meets` holds, for the particle's stored pixel rectangle, for every
        /// group that has such a lane, and for a footprint `cols` × `rows` that holds any of
        /// the group's rays. The rays are a random subset of an 11 × 3 bundle, packed
        /// densely: a group mixes rows, and the last one has padding lanes, never marked.
        #[test]
        fn near_marks_exactly_the_live_lanes_in_reach(
            parallel in any::<bool>(),
            c in prop::array::uniform3(-0.6f64..0.6),
            depth in 0.5f64..3.0,
            h in 0.01f64..0.4,
            (c0, c1) in (0usize..11, 0usize..12),
            (r0, r1) in (0usize..3, 0usize..4),
            cast in prop::collection::vec(any::<bool>(), 33),
            live in prop::collection::vec(any::<bool>(), 40),
            j in 0usize..3,
            org in -0.5f64..0.5,
        ) {
            let camera = Camera { parallel_projection: parallel, parallel_scale: 0.6, ..Camera::default() };
            let frame = camera.frame(64, 48).unwrap();
            let (x0, y0, w) = (20u32, 17u32, 11usize);
            let pixels: Vec<(usize, usize)> = (0..33).filter(|&r| cast[r]).map(|r| (r % w, r / w)).collect();
            let ray = |(i, j): (usize, usize)| Ray::through_pixel(&frame, x0 + i as u32, y0 + j as u32);
            let bundle = BundleRays::new(pixels.iter().map(|&px| (px, ray(px))));
            prop_assert_eq!(bundle.slots(), pixels.len().div_ceil(LANES) * LANES);
            let (cols, rows) = (c0.min(c1)..c0.max(c1), r0.min(r1)..r0.max(r1));
            // The particle near the middle ray of row j, at the given depth.
            let mid = ray((5, j));
            let p = ViewParticle::new(
                [0, 1, 2].map(|k| mid.o[k] + depth * mid.d[k] + c[k] * h * 3.0),
                h, 1.0, 1.0, 1.0,
            );
            // The span's origin: somewhere near the particle's depth.
            let z_org = depth + org;
            for (g, group) in bundle.groups.iter().enumerate() {
                let got = group.near(&p, &live[g * LANES..][..LANES], z_org);
                let mut any = false;
                for l in 0..LANES {
                    let px = pixels.get(g * LANES + l).copied();
                    let r = px.map(ray);
                    let pass = r.as_ref().and_then(|r| r.passage(&p));
                    let on = px.is_some() && live[g * LANES + l] && pass.is_some();
                    any |= on;
                    if let (Some(n), true, Some(r)) = (&got, on, &r) {
                        let (t, r2) = r.closest_approach(&p);
                        // Single precision, relative to the span's origin.
                        let rel = t - z_org;
                        let tol = 2e-7 * rel.abs() + 1e-12 * t.abs().max(1.0);
                        prop_assert!((f64::from(n.t[l]) - rel).abs() <= tol, "{} vs {}", n.t[l], rel);
                        prop_assert!((f64::from(n.r2[l]) - r2).abs() <= 2e-7 * r2 + 1e-12 * h * h);
                        prop_assert_eq!(n.dd[l], r.dd as f32);
                    }
                    if let Some(n) = &got {
                        prop_assert_eq!(n.mask[l], if on { 1.0 } else { 0.0 }, "group {} lane {}", g, l);
                    }
                }
                prop_assert_eq!(got.is_some(), any, "group {}", g);
                // The stored rectangle, relative to the bundle, holds every ray that passes.
                let [a, b, c, d] = fluidcast_grid::stored_rect(&frame, &p, 1e-3, 1e3).map(usize::from);
                let rel = |v: usize, o: u32| v.saturating_sub(o as usize);
                let (rc, rr) = (rel(a, x0)..rel(b, x0), rel(c, y0)..rel(d, y0));
                prop_assert!(!any || group.meets(&rc, &rr), "group {}", g);
                let holds = (0..LANES).filter_map(|l| pixels.get(g * LANES + l))
                    .any(|(i, j)| cols.contains(i) && rows.contains(j));
                prop_assert!(!holds || group.meets(&cols, &rows), "group {}", g);
            }
        }
    }
}
