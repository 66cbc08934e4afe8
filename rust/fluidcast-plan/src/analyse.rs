//! The sampling error analysis (Sec. 4.1–4.2): per cell, the quantity's bounds per depth
//! sample from the particles that reach it, mapped through the transfer function's exact
//! extremes and composited per sampling level (plan.wgsl's `analyse` stage).

use crate::coverage::{covers_middle, Coverage, Lanes, Parts, COVER_SPLIT};
use crate::greedy::{relax, CellAnalysis};
use crate::params::{FieldParams, PlanParams};
use crate::{extremes, Bound, TfBounds};
use fluidcast_grid::{Bundle, Cell, PerspectiveGrid};
use fluidcast_sph::FieldKind;
use rayon::prelude::*;

/// Per-sample bounds on colour and opacity, before the step-length correction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ValueBound {
    /// No particle reaches this depth: every ray's sample is empty.
    pub(crate) empty: bool,
    /// Some rays may find no particle here (the sample is skipped for them).
    pub(crate) may_be_empty: bool,
    pub(crate) rgb_lo: [f64; 3],
    pub(crate) rgb_hi: [f64; 3],
    /// Extinction κ bounds (per world unit).
    pub(crate) k_lo: f64,
    pub(crate) k_hi: f64,
}

impl ValueBound {
    const EMPTY: ValueBound = ValueBound {
        empty: true,
        may_be_empty: true,
        rgb_lo: [0.0; 3],
        rgb_hi: [0.0; 3],
        k_lo: 0.0,
        k_hi: 0.0,
    };

    pub(crate) fn union(&self, o: &ValueBound) -> ValueBound {
        match (self.empty, o.empty) {
            (true, true) => ValueBound::EMPTY,
            (true, false) => ValueBound {
                may_be_empty: true,
                ..*o
            },
            (false, true) => ValueBound {
                may_be_empty: true,
                ..*self
            },
            (false, false) => ValueBound {
                empty: false,
                may_be_empty: self.may_be_empty || o.may_be_empty,
                rgb_lo: [0, 1, 2].map(|c| self.rgb_lo[c].min(o.rgb_lo[c])),
                rgb_hi: [0, 1, 2].map(|c| self.rgb_hi[c].max(o.rgb_hi[c])),
                k_lo: self.k_lo.min(o.k_lo),
                k_hi: self.k_hi.max(o.k_hi),
            },
        }
    }

    /// Irradiance/transparency bound of one step of view-space length in `ds` (world units).
    #[inline]
    pub(crate) fn step(&self, ds: [f64; 2]) -> Bound {
        if self.empty {
            return Bound::EMPTY;
        }
        // Opacity 1 − exp(−κ ds) grows with κ and ds. Far outliers can make a step
        // infinitely long: no extinction over it still lets everything through, and a
        // product that is not a number widens the bound to all it could be.
        let t_lo = transmittance(self.k_hi, ds[1]).unwrap_or(0.0);
        let t_hi = transmittance(self.k_lo, ds[0]).unwrap_or(1.0);
        let (a_lo, a_hi) = (1.0 - t_hi, 1.0 - t_lo);
        let e = self.may_be_empty;
        Bound {
            lo: [
                if e { 0.0 } else { a_lo * self.rgb_lo[0] },
                if e { 0.0 } else { a_lo * self.rgb_lo[1] },
                if e { 0.0 } else { a_lo * self.rgb_lo[2] },
                t_lo,
            ],
            hi: [
                a_hi * self.rgb_hi[0],
                a_hi * self.rgb_hi[1],
                a_hi * self.rgb_hi[2],
                if e { 1.0 } else { t_hi },
            ],
        }
    }
}

/// `exp(−κ ds)`, exactly 1 where κ or ds is 0 (also for an infinite other factor); `None`
/// where the product is not a number.
#[inline]
pub(crate) fn transmittance(kappa: f64, ds: f64) -> Option<f64> {
    if kappa == 0.0 || ds == 0.0 {
        return Some(1.0);
    }
    let t = (-kappa * ds).exp();
    (!t.is_nan()).then_some(t)
}

/// A cell's value bounds per depth sample (Sec. 4.1–4.2), from which [`CellSamples::level`]
/// composites the cell's bound at a sampling level, and whether some sample that a particle
/// reaches may still be empty for some ray (`gappy`, a coverage gap).
pub(crate) struct CellSamples {
    /// Per sample (D_z of them): its value bound, its step length along the bundle's
    /// shortest and longest ray (world units), and that step's bound at full rate. Only the
    /// cell's own samples, where fixed arrays of the largest D_z took 5.6 KB a cell, copied
    /// on every move (about 6 M first level cache write misses on a 227k-particle dam break
    /// at 1024 × 768).
    pub(crate) steps: Vec<(ValueBound, [f64; 2], Bound)>,
    pub(crate) gappy: bool,
}

impl CellSamples {
    /// Sample k's value bound over its step `ds`, with the step's bound at full rate.
    pub(crate) fn step(vb: ValueBound, ds: [f64; 2]) -> (ValueBound, [f64; 2], Bound) {
        (vb, ds, vb.step(ds))
    }

    /// The cell's bound at level `l`: sample k is drawn with the value of sample
    /// ⌊k/2^l⌋·2^l over its own step, so the bound of step k is the union of both samples'
    /// bounds. Where both are equal (neighbouring samples mostly see the same particles,
    /// see [`cell_bounds`]) that is the step's full-rate bound, found once per cell: the
    /// step bound's two exponentials took most of the composite's time (0.23 G instructions
    /// of a default render of a 227k-particle dam break at 1024 × 768).
    pub(crate) fn level(&self, l: usize) -> Bound {
        let step = 1usize << l;
        let mut acc = Bound::EMPTY;
        for (k, (vb, ds, full)) in self.steps.iter().enumerate() {
            let first = &self.steps[k / step * step].0;
            let u = match k % step == 0 || first == vb {
                true => *full,
                false => first.union(vb).step(*ds),
            };
            acc = acc.over(&u);
        }
        acc
    }
}

/// What the analysis of every bundle of a view shares: the grid, the transfer function's
/// bounds, the field, and each particle's sample range ([`sample_reach`]).
pub(crate) struct View<'a> {
    pub(crate) grid: &'a PerspectiveGrid,
    pub(crate) tfb: &'a TfBounds,
    pub(crate) field: &'a FieldParams,
    pub(crate) reach: &'a [(u32, u32)],
}

/// Each particle's depth samples: the half-open range of indices of the view's sample depths
/// inside its support's depth extent [c.z − H, c.z + H] (as [`fluidcast_grid::within`]
/// counts them), found once per view instead of once in every cell that references it.
pub(crate) fn sample_reach(grid: &PerspectiveGrid) -> Vec<(u32, u32)> {
    let Some(depths) = grid.depths.as_ref() else {
        return Vec::new();
    };
    let z = &depths.z;
    grid.particles
        .par_iter()
        .map(|p| {
            let k = fluidcast_grid::within(z, p.c[2] - p.h(), p.c[2] + p.h());
            (k.start as u32, k.end as u32)
        })
        .collect()
}

/// A particle's sample range (see [`sample_reach`]) within the cell whose `dz` samples start
/// at index `k0`, counted from `k0`: what `within` finds among the cell's depths.
#[inline]
pub(crate) fn cell_range((lo, hi): (u32, u32), k0: usize, dz: usize) -> std::ops::Range<usize> {
    let clamp = |i: u32| (i as usize).clamp(k0, k0 + dz) - k0;
    clamp(lo)..clamp(hi)
}

/// The value bounds of one cell's samples (see [`CellSamples`]). `parts` are the bundle's
/// sub-bundles for the coverage test; `stop` the nearest depth where opaque geometry stops a
/// ray of the bundle; `scratch` holds the cell's reaching particles for the coverage test
/// ([`Scratch`]).
#[inline(always)]
pub(crate) fn cell_bounds(
    view: &View,
    (bundle, parts): (&Bundle, &Parts),
    cell: &Cell,
    stop: f64,
    scratch: &mut Scratch,
) -> CellSamples {
    let grid = view.grid;
    #[allow(
        clippy::expect_used,
        reason = "a grid has cells only once its depths are set (GridBuilder); the hot path keeps no error branch"
    )]
    let depths = grid.depths.as_ref().expect("cells exist only with depths");
    let dz = grid.params.depth_samples as usize;
    let k0 = cell.z as usize * dz;
    let zs = &depths.z[k0..k0 + dz];
    // Quantity bounds per depth sample from the particles whose depth range reaches it (in
    // single precision, as particles hold the quantity: their extremes are exact), and bit k
    // of `any` set for each sample some particle reaches.
    let mut extremes = extremes::RangeExtremes::new(dz);
    let mut sums = ([0.0f64; 64], [0.0f64; 64]);
    let any = gather(
        view,
        (bundle, cell),
        (k0, dz),
        (&mut extremes, &mut sums),
        scratch,
    );
    let Scratch {
        reaching,
        others,
        lanes,
    } = scratch;
    let (qlo, qhi) = extremes.per_sample();
    // Central particles first.
    reaching.append(others);
    let coverage = Coverage {
        parts,
        particles: &grid.particles,
        reaching,
        zs,
    };
    // Bit k set for each sample k that some particle reaches and some sub-bundle's rays may
    // miss.
    let open = coverage.of(any, lanes);
    let q = Quantity {
        qlo: &qlo,
        qhi: &qhi,
        sum_lo: &sums.0,
        sum_hi: &sums.1,
        any,
        open,
    };
    let steps = sample_steps(view, bundle, (k0, dz), &q, stop);
    CellSamples {
        steps,
        // A sample left open is one that a particle reaches and some sub-bundle's rays may
        // miss.
        gappy: open != 0,
    }
}

/// Collects the particles of `cell` that reach each of its samples: their quantity's extremes
/// and (for sums) the sums' bounds per sample, and, for the coverage test, those that cover
/// the bundle's middle first (`scratch.reaching`) and the others (`scratch.others`). Returns
/// bit k set for each sample k some particle reaches.
#[inline(always)]
fn gather(
    view: &View,
    (bundle, cell): (&Bundle, &Cell),
    (k0, dz): (usize, usize),
    (extremes, (sum_lo, sum_hi)): (&mut extremes::RangeExtremes, &mut ([f64; 64], [f64; 64])),
    scratch: &mut Scratch,
) -> u64 {
    let (grid, params) = (view.grid, view.field);
    let mut any = 0u64;
    let (mx, my) = (
        0.5 * (bundle.x[0] + bundle.x[1]),
        0.5 * (bundle.y[0] + bundle.y[1]),
    );
    let Scratch {
        reaching, others, ..
    } = scratch;
    reaching.clear();
    others.clear();
    for &j in &grid.refs[cell.start as usize..cell.end as usize] {
        let r = cell_range(view.reach[j as usize], k0, dz);
        if r.is_empty() {
            continue;
        }
        let p = &grid.particles[j as usize];
        // (cell_range lies within the cell's D_z <= 64 samples.)
        let samples = bits(&r);
        any |= samples;
        let reacher = Reacher { j, samples };
        match covers_middle(p, (mx, my), bundle.parallel) {
            true => reaching.push(reacher),
            false => others.push(reacher),
        }
        // A NaN quantity moves neither bound (as f64::min and max ignored it before).
        extremes.add(r.start, r.end, p.a32);
        if params.field != FieldKind::Csph {
            let wmax = params.kernel.eval(0.0, p.h());
            let (slo, shi) = match params.field {
                FieldKind::Sph => {
                    let s = p.a() * p.v() * wmax;
                    (s.min(0.0), s.max(0.0))
                }
                _ => (0.0, p.m() * wmax),
            };
            for k in r.clone() {
                sum_lo[k] += slo;
                sum_hi[k] += shi;
            }
        }
    }
    any
}

/// What a cell's samples hold: the quantity's extremes (CSPH) or the sums' bounds per sample,
/// the samples some particle reaches (`any`) and those some ray may miss (`open`).
struct Quantity<'a> {
    qlo: &'a [f32],
    qhi: &'a [f32],
    sum_lo: &'a [f64; 64],
    sum_hi: &'a [f64; 64],
    any: u64,
    open: u64,
}

/// Each sample's value bound over its step along the bundle's shortest and longest ray: the
/// transfer function's colour and extinction bounds over the sample's quantity range, with
/// "nothing" among its values where some ray may miss it or stop before its end (`stop`).
#[inline(always)]
fn sample_steps(
    view: &View,
    bundle: &Bundle,
    (k0, dz): (usize, usize),
    q: &Quantity,
    stop: f64,
) -> Vec<(ValueBound, [f64; 2], Bound)> {
    let (tfb, params) = (view.tfb, view.field);
    #[allow(
        clippy::expect_used,
        reason = "a grid has cells only once its depths are set (GridBuilder); the hot path keeps no error branch"
    )]
    let depths = view
        .grid
        .depths
        .as_ref()
        .expect("cells exist only with depths");
    let tf = tfb.transfer_function();
    let mut steps = Vec::with_capacity(dz);
    // Neighbouring samples mostly see the same particles, so the same value range: its
    // colour and extinction bounds are found once.
    let mut last: Option<((f64, f64), ValueBound)> = None;
    for k in 0..dz {
        let step = depths.z[k0 + k + 1] - depths.z[k0 + k];
        let ds = [step * bundle.dlen[0], step * bundle.dlen[1]];
        if q.any & (1u64 << k) == 0 {
            steps.push(CellSamples::step(ValueBound::EMPTY, ds));
            continue;
        }
        let (a, b) = match params.field {
            FieldKind::Csph => (f64::from(q.qlo[k]), f64::from(q.qhi[k])),
            _ => (q.sum_lo[k], q.sum_hi[k]),
        };
        let bound = match last {
            Some((range, bound)) if range == (a, b) => bound,
            _ => {
                let r = tfb.range(a, b);
                let bound = ValueBound {
                    empty: false,
                    may_be_empty: false,
                    rgb_lo: r.rgb_lo,
                    rgb_hi: r.rgb_hi,
                    k_lo: tf.extinction(r.alpha_lo),
                    k_hi: tf.extinction(r.alpha_hi),
                };
                last = Some(((a, b), bound));
                bound
            }
        };
        // A step that ends past `stop` may be cut short or skipped for some ray: "nothing"
        // is then one of its values, as for a coverage gap (the rest of the ray is empty).
        let stopped = depths.z[k0 + k + 1] > stop;
        let vb = ValueBound {
            may_be_empty: q.open >> k & 1 != 0 || stopped,
            ..bound
        };
        steps.push(CellSamples::step(vb, ds));
    }
    steps
}

/// [`cell_bounds`] run through [`pulp::Arch::dispatch`], which compiles it for the CPU's
/// best instruction set (the coverage test's fixed-size loops over sub-bundles vectorise).
pub(crate) struct CellBounds<'a> {
    pub(crate) view: &'a View<'a>,
    pub(crate) bundle: (&'a Bundle, &'a Parts),
    pub(crate) cell: &'a Cell,
    pub(crate) stop: f64,
    pub(crate) scratch: &'a mut Scratch,
}

impl pulp::WithSimd for CellBounds<'_> {
    type Output = CellSamples;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) -> CellSamples {
        cell_bounds(self.view, self.bundle, self.cell, self.stop, self.scratch)
    }
}

/// Bit k set for each sample k of `r` (not empty, within 0..64).
#[inline]
pub(crate) fn bits(r: &std::ops::Range<usize>) -> u64 {
    (u64::MAX >> (64 - (r.end - r.start))) << r.start
}

/// A particle of a cell that reaches some of its samples, as [`cell_bounds`] keeps it for the
/// coverage test: its index and its samples in the cell (bit k for sample k).
pub(crate) struct Reacher {
    pub(crate) j: u32,
    pub(crate) samples: u64,
}

/// The working memory of [`cell_bounds`], kept across the cells of a bundle: the cell's
/// particles that reach some sample, those that reach the bundle's middle ray first
/// (`reaching`, with `others` while they are sorted), and the same particles as [`Lanes`]
/// once a sample of the cell keeps a coverage gap.
#[derive(Default)]
pub(crate) struct Scratch {
    pub(crate) reaching: Vec<Reacher>,
    pub(crate) others: Vec<Reacher>,
    pub(crate) lanes: Lanes,
}

/// Sec. 4.1–4.2 for each cell of bundle `b`: its bounds, and whether it is a surface cell.
pub(crate) fn analyse_cells(
    view: &View,
    b: usize,
    surface: Option<&[bool]>,
    stop: f64,
    params: &PlanParams,
) -> Vec<CellAnalysis> {
    let grid = view.grid;
    let bundle = grid.bundle(b);
    let parts = Parts::new(&bundle.split(&grid.frame, COVER_SPLIT));
    let mut scratch = Scratch::default();
    grid.bundle_cells(b)
        .iter()
        .map(|cell| {
            let samples = pulp::Arch::new().dispatch(CellBounds {
                view,
                bundle: (&bundle, &parts),
                cell,
                stop,
                scratch: &mut scratch,
            });
            let full = samples.level(0);
            let is_surface = params.uses_surface_cells()
                && samples.gappy
                && surface.is_some_and(|s| {
                    grid.refs[cell.start as usize..cell.end as usize]
                        .iter()
                        .any(|&j| s[j as usize])
                });
            CellAnalysis {
                full,
                relaxed: relax(&full, &full, params.relax),
                samples: (!is_surface).then_some(samples),
            }
        })
        .collect()
}
