//! The sampling plan of one view: the sampling error analysis of Hochstetter et al. 2016
//! (Sec. 4), relaxed estimation and super-pixels (Sec. 5), surface cells (Sec. 4.2) and cell
//! merging (Sec. 6.2), on a [`PerspectiveGrid`].
//!
//! For every cell the analysis bounds, per depth sample, the quantity seen by all rays of the
//! bundle (CSPH is an affine combination of the contributing particles' values, so it lies
//! between their minimum and maximum), maps the quantity bounds to colour/opacity bounds with
//! exact transfer-function extremes ([`TfBounds`]), and composites them into cell bounds per
//! sampling level l (D_z/2^l samples, each standing for 2^l full-rate steps). A greedy pass per
//! bundle, back to front, then raises each cell's level (or renders it as a super-pixel) while
//! the composited bound of the whole bundle stays below the error tolerance (Eq. 4–5).
//!
//! Where the paper leaves room, this implementation chooses:
//! * A sample whose bundle cross-section is not entirely inside one particle's support may be
//!   empty for some rays; its bound then includes "nothing" (I = 0, T = 1). This keeps the
//!   strict bound honest at free surfaces without relying on the surface test.
//! * Coverage: the bundle is split into 4 × 4 sub-bundles (2 × 2 rays for D_xy = 8); a
//!   sample is surely non-empty when each sub-bundle's cross-section at that depth lies inside
//!   one particle's support.
//! * Surface particles come from [`fluidcast_sph::Particles::surface_flags`]: fewer
//!   neighbours within H/2 than 0.75 × the median (a neighbourhood deficiency, in the spirit
//!   of Orthmann et al. 2013). A
//!   *surface cell* references a surface particle and has a coverage gap (some of its rays
//!   may leave the fluid inside it); it keeps level 0 and is never a super-pixel. Cells that
//!   merely touch surface particles but are covered throughout adapt like bulk cells. Only
//!   relaxed plans use the rule ([`PlanParams::uses_surface_cells`]); strict bounds need none.
//! * Only cells with the same chosen level are merged, so merged cells sample exactly the
//!   planned positions (the paper also merges a cell into a coarser neighbour at its finer
//!   level) and the bound stays a bound.
//! * Early ray termination at transmittance `min_transmittance` can change a pixel by at most
//!   that much, so the greedy keeps the bound below `E_I − min_transmittance`.
//! * The level cap (Sec. 4.2: a cell's strict bound at level l no wider than E_I) is taken
//!   as seen on the screen: the cell's width times the largest transparency in front of it,
//!   plus what its transparency's width lets through of the chosen back (`level_error`).
//!   Behind fluid that hides most of a cell, the cell may coarsen although it varies more
//!   than E_I; in front of nothing it is the paper's cap.
//! * The probe (beyond the paper, [`PlanParams::probe`]): an eighth of the bundles, spread
//!   evenly, is analysed and planned first; where their plans save less than a fifth of their
//!   cast work, the other bundles are planned at full rate without an analysis, which would
//!   cost more than it saves (on data whose field varies across every bundle by more than
//!   E_I). Each bundle is planned on its own, so the probe's bundles get the plan they would
//!   get without it.
//! * The greedy takes the cheapest option under the budget (super-pixel, then the highest
//!   level), where the paper takes the widest bound; they differ only where a finer level's
//!   bound is wider.

mod extremes;
mod interval;
mod tfbounds;

use fluidcast_grid::{Bundle, Cell, PerspectiveGrid, ViewParticle, COVER_MARGIN};
use fluidcast_sph::{FieldKind, Kernel};
use fluidcast_view::TransferFunction;
use rayon::prelude::*;

pub use interval::Bound;
pub use tfbounds::{TfBounds, TfRange};

/// Largest number of sampling levels (D_z ≤ 64 gives levels 0..=6).
const LEVELS: usize = 7;

/// How the field is sampled: kernel, field kind and the ray caster's early-termination
/// transmittance (which the error budget accounts for).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldParams {
    pub kernel: Kernel,
    pub field: FieldKind,
    pub min_transmittance: f64,
}

/// What the user asks of the adaptive sampling.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanParams {
    /// Screen-space error tolerance E_I (in colour/alpha units, 0..1), or `None` for no
    /// adaptivity (every cell at full rate).
    pub tolerance: Option<f64>,
    /// E_relax ∈ [0, 1]: 1 removes the lateral (level-0) width from the estimate (Sec. 5.1),
    /// 0 is the strict bound.
    pub relax: f64,
    /// Allow cells to be rendered as super-pixels (Sec. 5.2).
    pub superpixels: bool,
    /// Force cells that reference surface particles to full rate (Sec. 4.2).
    pub surface_cells: bool,
    /// Relaxed mode only: cast every second pixel of every second row first, and interpolate
    /// the pixels between where the image is smooth (image-space refinement, beyond the
    /// paper: `fluidcast_render::interpolate`).
    pub interpolate: bool,
    /// Analyse a sample of the bundles first (beyond the paper; see the crate's
    /// documentation) and plan the others at full rate, without their analysis, where the
    /// sample predicts that adapting saves the ray caster less than the analysis costs.
    pub probe: bool,
}

impl Default for PlanParams {
    fn default() -> Self {
        PlanParams {
            tolerance: Some(0.004),
            relax: 1.0,
            superpixels: true,
            surface_cells: true,
            interpolate: true,
            probe: true,
        }
    }
}

impl PlanParams {
    /// True when surface particles matter: an adaptive, relaxed plan with the surface rule
    /// on. Unrelaxed bounds already include "no particle" wherever a ray may leave the fluid,
    /// so the strict mode needs no surface test.
    pub fn uses_surface_cells(&self) -> bool {
        self.tolerance.is_some() && self.surface_cells && self.relax > 0.0
    }

    /// Checks the ranges: E_I and E_relax in [0, 1].
    pub fn validate(&self) -> Result<(), PlanError> {
        if let Some(e) = self.tolerance {
            if !(0.0..=1.0).contains(&e) {
                return Err(PlanError::Tolerance(e));
            }
        }
        if !(0.0..=1.0).contains(&self.relax) {
            return Err(PlanError::Relax(self.relax));
        }
        Ok(())
    }

    /// The strict mode: no relaxation, no super-pixels and no interpolation, so the bound is
    /// a guarantee.
    pub fn strict(mut self) -> Self {
        self.relax = 0.0;
        self.superpixels = false;
        self.interpolate = false;
        self
    }
}

/// Why a plan could not be made.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    #[error("error tolerance {0} must be in [0, 1]")]
    Tolerance(f64),
    #[error("relaxation {0} must be in [0, 1]")]
    Relax(f64),
    #[error("surface flags: {0} given for {1} particles")]
    SurfaceFlags(usize, usize),
    #[error("depth stops: {0} given for {1} bundles")]
    Stops(usize, usize),
}

/// A run of consecutive cells of one bundle that the ray caster treats as one: `count`
/// (a power of two) cells merged, sampled every `2^level` depth samples, or a single cell
/// drawn as a super-pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Span {
    /// Index of the first cell in [`PerspectiveGrid::cells`].
    pub first: u32,
    pub count: u32,
    pub level: u8,
    /// Super-pixel value (I rgb, T), the midpoint of the cell's full-rate bound.
    pub superpixel: Option<[f32; 4]>,
}

/// Per-bundle results of the analysis, for diagnostics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BundleSummary {
    /// Predicted error: the width of the composited bound of the chosen levels (the relaxed
    /// estimate when relaxation is on; a guarantee in strict mode).
    pub predicted_error: f32,
    /// Mean sampling level over the bundle's sampled cells.
    pub mean_level: f32,
    /// Shares of the bundle's cells at full rate, adapted in depth, and super-pixels.
    pub full: f32,
    pub adapted: f32,
    pub superpixel: f32,
    /// 1 when the bundle's first (front-most) cell is sampled, 0 when it is a super-pixel or
    /// the bundle is empty: where rays spend their work, since they stop in the first cells
    /// of opaque fluid (the image-space refinement refines only such bundles).
    pub front_sampled: f32,
}

/// Counts over all cells.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlanStats {
    pub cells: u64,
    /// Cells per chosen level (index 0 = full rate).
    pub level_cells: [u64; LEVELS],
    pub superpixel_cells: u64,
    /// Cells forced to full rate by the surface test.
    pub surface_cells: u64,
    /// Cells absorbed into a merged neighbour (cells − spans of sampled cells).
    pub merged_cells: u64,
    /// Particle references the ray caster reads (after merging removed repeats).
    pub refs_sampled: u64,
    /// Bundles with cells planned at full rate without their analysis, because the probe
    /// predicted that adapting would not pay ([`PlanParams::probe`]).
    pub unanalysed_bundles: u64,
}

impl PlanStats {
    /// Adds another plan's counts (another part of the same view).
    pub fn add(&mut self, o: &PlanStats) {
        self.cells += o.cells;
        for (a, b) in self.level_cells.iter_mut().zip(&o.level_cells) {
            *a += b;
        }
        self.superpixel_cells += o.superpixel_cells;
        self.surface_cells += o.surface_cells;
        self.merged_cells += o.merged_cells;
        self.refs_sampled += o.refs_sampled;
        self.unanalysed_bundles += o.unanalysed_bundles;
    }
}

/// The sampling plan for one view.
#[derive(Debug, Clone)]
pub struct SamplingPlan {
    pub spans: Vec<Span>,
    bundle_spans: Vec<u32>,
    /// Chosen level per grid cell ([`SamplingPlan::SUPERPIXEL`] for super-pixels).
    pub cell_levels: Vec<u8>,
    /// Per bundle: the full-rate (level 0, unrelaxed) bound, which holds every full-rate
    /// pixel of the bundle, and the bound of the chosen plan; empty without adaptivity.
    pub full_bounds: Vec<Bound>,
    pub plan_bounds: Vec<Bound>,
    pub summaries: Vec<BundleSummary>,
    pub stats: PlanStats,
}

struct BundlePlan {
    spans: Vec<Span>,
    levels: Vec<u8>,
    full: Bound,
    plan: Bound,
    summary: BundleSummary,
    stats: PlanStats,
    /// The ray caster's work at full rate and as planned ([`cast_work`]).
    work: [u64; 2],
}

/// Every `PROBE_STRIDE`-th bundle along each row, shifted by `PROBE_ROW_SHIFT` from row to
/// row, is in the probe ([`PlanParams::probe`]): an eighth of the image, spread evenly over
/// it. (plan.wgsl reads these constants.)
pub const PROBE_STRIDE: u32 = 8;
pub const PROBE_ROW_SHIFT: u32 = 3;

fn is_probe_bundle(bundles_x: u32, b: usize) -> bool {
    let (bx, by) = (b as u32 % bundles_x, b as u32 / bundles_x);
    (bx + PROBE_ROW_SHIFT * by).is_multiple_of(PROBE_STRIDE)
}

/// The ray caster's work in a cell, in particle-reference × depth-sample units of 1/64: each
/// of the cell's `refs` is visited at `D_z / 2^level` depth samples of every ray (none for a
/// super-pixel).
fn cast_work(refs: u32, choice: Choice) -> u64 {
    match choice {
        Choice::Level(l) => u64::from(refs) << (LEVELS - 1 - usize::from(l)),
        Choice::SuperPixel => 0,
    }
}

/// Adapting pays where the planned work of the probe's bundles is at least
/// `PROBE_SAVING_NUM / PROBE_SAVING_DEN` below their full-rate work. The analysis took 0.07
/// to 0.19 of the full-rate cast's time on the README's dam breaks (1024 × 768, velocity);
/// the probes of the frames where adapting paid predicted savings of 0.27 and more, those of
/// the frames where it did not 0.15 and less (`fluidcast bench`, README). A rough measure,
/// ignoring early termination and merging, with a margin on both sides. (plan.wgsl reads
/// these constants.)
pub const PROBE_SAVING_NUM: u64 = 1;
pub const PROBE_SAVING_DEN: u64 = 5;

/// Whether the probe's bundles, planned, predict that analysing the others pays: exactly
/// (den − num) · full ≥ den · planned, so an empty probe (no work) adapts.
fn probe_pays(work: impl Iterator<Item = [u64; 2]>) -> bool {
    let (full, planned) = work.fold((0, 0), |(f, p), [wf, wp]| (f + wf, p + wp));
    (PROBE_SAVING_DEN - PROBE_SAVING_NUM) * full >= PROBE_SAVING_DEN * planned
}

impl SamplingPlan {
    /// Level value marking a super-pixel cell in [`SamplingPlan::cell_levels`].
    pub const SUPERPIXEL: u8 = u8::MAX;

    /// Builds the plan. `surface` flags surface particles (by particle index, see
    /// [`fluidcast_sph::Particles::surface_flags`]); `None` means none are. `stops` holds, per
    /// bundle, the nearest view depth (world units) at which opaque geometry stops one of its
    /// rays (`+∞` where none does; `None`: no geometry): a step that ends past it may be cut
    /// short or skipped for some ray, so its bound includes "nothing", as an empty sample's.
    pub fn build(
        grid: &PerspectiveGrid,
        tf: &TransferFunction,
        surface: Option<&[bool]>,
        stops: Option<&[f64]>,
        params: &PlanParams,
        field: &FieldParams,
    ) -> Result<SamplingPlan, PlanError> {
        params.validate()?;
        if let Some(s) = surface {
            if s.len() != grid.particles.len() {
                return Err(PlanError::SurfaceFlags(s.len(), grid.particles.len()));
            }
        }
        if let Some(s) = stops {
            if s.len() != grid.bundle_count() {
                return Err(PlanError::Stops(s.len(), grid.bundle_count()));
            }
        }
        let tfb = TfBounds::new(tf);
        let reach = sample_reach(grid);
        let view = View {
            grid,
            tfb: &tfb,
            field,
            reach: &reach,
        };
        let plan_one = |b: usize, analyse: bool| {
            let stop = stops.map_or(f64::INFINITY, |s| s[b]);
            plan_bundle(&view, b, surface, stop, params, analyse)
        };
        let adaptive = params.tolerance.is_some();
        let probing = adaptive && params.probe;
        let is_probe = |b: usize| probing && is_probe_bundle(grid.bundles_x, b);
        let probed: Vec<BundlePlan> = (0..grid.bundle_count())
            .into_par_iter()
            .filter(|&b| is_probe(b))
            .map(|b| plan_one(b, true))
            .collect();
        let analyse_rest = adaptive && (!probing || probe_pays(probed.iter().map(|b| b.work)));
        let rest: Vec<BundlePlan> = (0..grid.bundle_count())
            .into_par_iter()
            .filter(|&b| !is_probe(b))
            .map(|b| plan_one(b, analyse_rest))
            .collect();
        let (mut probed, mut rest) = (probed.into_iter(), rest.into_iter());
        let bundles = (0..grid.bundle_count()).filter_map(|b| match is_probe(b) {
            true => probed.next(),
            false => rest.next(),
        });
        let mut plan = SamplingPlan {
            spans: Vec::new(),
            bundle_spans: vec![0],
            cell_levels: Vec::with_capacity(grid.cells.len()),
            full_bounds: Vec::new(),
            plan_bounds: Vec::new(),
            summaries: Vec::new(),
            stats: PlanStats::default(),
        };
        for bp in bundles {
            plan.spans.extend(bp.spans);
            plan.bundle_spans.push(plan.spans.len() as u32);
            plan.cell_levels.extend(bp.levels);
            if adaptive {
                plan.full_bounds.push(bp.full);
                plan.plan_bounds.push(bp.plan);
                plan.summaries.push(bp.summary);
            }
            plan.stats.add(&bp.stats);
        }
        Ok(plan)
    }

    /// The spans of bundle `b`, front to back.
    pub fn bundle_spans(&self, b: usize) -> &[Span] {
        &self.spans[self.bundle_spans[b] as usize..self.bundle_spans[b + 1] as usize]
    }
}

/// Per-sample bounds on colour and opacity, before the step-length correction.
#[derive(Debug, Clone, Copy, PartialEq)]
struct ValueBound {
    /// No particle reaches this depth: every ray's sample is empty.
    empty: bool,
    /// Some rays may find no particle here (the sample is skipped for them).
    may_be_empty: bool,
    rgb_lo: [f64; 3],
    rgb_hi: [f64; 3],
    /// Extinction κ bounds (per world unit).
    k_lo: f64,
    k_hi: f64,
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

    fn union(&self, o: &ValueBound) -> ValueBound {
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
    fn step(&self, ds: [f64; 2]) -> Bound {
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
fn transmittance(kappa: f64, ds: f64) -> Option<f64> {
    if kappa == 0.0 || ds == 0.0 {
        return Some(1.0);
    }
    let t = (-kappa * ds).exp();
    (!t.is_nan()).then_some(t)
}

/// Sub-bundles per side for the coverage test (2×2 rays each for D_xy = 8).
const COVER_SPLIT: u32 = 4;

/// Most sub-bundle columns (and rows) of the coverage test.
const SIDE: usize = COVER_SPLIT as usize;

/// A bundle's sub-bundles for the coverage test, a `cols × rows` grid (as
/// [`Bundle::split`] cuts it, row-major): the rays' x extremes per column and y extremes per
/// row ([`Bundle::x`], [`Bundle::y`]), which the parts of a column (row) share.
struct Parts {
    x: [[f64; 2]; SIDE],
    y: [[f64; 2]; SIDE],
    cols: usize,
    rows: usize,
    parallel: bool,
    /// Bit s set for each part.
    all: u64,
    /// Smallest squared half diagonal of a part (at unit depth for a perspective view).
    r2_min: f64,
}

impl Parts {
    /// From `parts` of [`Bundle::split`] with `COVER_SPLIT`: `cols` parts share the first
    /// row's y extremes.
    fn new(parts: &[Bundle]) -> Parts {
        let cols = parts
            .iter()
            .take_while(|b| parts.first().is_some_and(|f| b.y == f.y))
            .count()
            .clamp(1, SIDE);
        let rows = (parts.len() / cols).min(SIDE);
        let mut out = Parts {
            x: [[0.0; 2]; SIDE],
            y: [[0.0; 2]; SIDE],
            cols,
            rows,
            parallel: parts.first().is_some_and(|b| b.parallel),
            all: (1u64 << (cols * rows)) - 1,
            r2_min: parts
                .iter()
                .map(|b| 0.25 * ((b.x[1] - b.x[0]).powi(2) + (b.y[1] - b.y[0]).powi(2)))
                .fold(f64::INFINITY, f64::min),
        };
        for (x, b) in out.x.iter_mut().zip(parts) {
            *x = b.x;
        }
        for (y, b) in out.y.iter_mut().zip(parts.iter().step_by(cols)).take(rows) {
            *y = b.y;
        }
        out
    }

    /// The parts in the plane of view depth `z` (see [`PartsAt`]).
    #[inline(always)]
    fn at(&self, z: f64) -> PartsAt {
        let at = |v: f64| if self.parallel { v } else { v * z };
        let side = |e: &[[f64; 2]; SIDE], n: usize| {
            std::array::from_fn(|u| match u < n {
                true => e[u].map(at),
                false => [f64::INFINITY; 2],
            })
        };
        let (x, y) = (side(&self.x, self.cols), side(&self.y, self.rows));
        let hull = |e: &[[f64; 2]; SIDE], n: usize| {
            e[..n]
                .iter()
                .fold([f64::INFINITY, f64::NEG_INFINITY], |h, e| {
                    [h[0].min(e[0]).min(e[1]), h[1].max(e[0]).max(e[1])]
                })
        };
        PartsAt {
            z,
            hull_x: hull(&x, self.cols),
            hull_y: hull(&y, self.rows),
            x,
            y,
            cols: self.cols,
            wide: self.r2_min * if self.parallel { 1.0 } else { z * z },
        }
    }
}

/// [`Parts`] in the plane of one sample depth `z`: the rays' x extremes per column and y
/// extremes per row there (infinitely far beyond the grid, so that fixed-size loops over
/// [`SIDE`] find nothing there), and the smallest squared half diagonal of a part, below
/// which a particle's disc covers none.
struct PartsAt {
    z: f64,
    x: [[f64; 2]; SIDE],
    y: [[f64; 2]; SIDE],
    /// The smallest and largest x (y) of all parts' rays.
    hull_x: [f64; 2],
    hull_y: [f64; 2],
    cols: usize,
    wide: f64,
}

/// A cell's value bounds per depth sample (Sec. 4.1–4.2), from which [`CellSamples::level`]
/// composites the cell's bound at a sampling level, and whether some sample that a particle
/// reaches may still be empty for some ray (`gappy`, a coverage gap).
struct CellSamples {
    /// Per sample (D_z of them): its value bound, its step length along the bundle's
    /// shortest and longest ray (world units), and that step's bound at full rate. Only the
    /// cell's own samples, where fixed arrays of the largest D_z took 5.6 KB a cell, copied
    /// on every move (about 6 M first level cache write misses on a 227k-particle dam break
    /// at 1024 × 768).
    steps: Vec<(ValueBound, [f64; 2], Bound)>,
    gappy: bool,
}

impl CellSamples {
    /// Sample k's value bound over its step `ds`, with the step's bound at full rate.
    fn step(vb: ValueBound, ds: [f64; 2]) -> (ValueBound, [f64; 2], Bound) {
        (vb, ds, vb.step(ds))
    }

    /// The cell's bound at level `l`: sample k is drawn with the value of sample
    /// ⌊k/2^l⌋·2^l over its own step, so the bound of step k is the union of both samples'
    /// bounds. Where both are equal (neighbouring samples mostly see the same particles,
    /// see [`cell_bounds`]) that is the step's full-rate bound, found once per cell: the
    /// step bound's two exponentials took most of the composite's time (0.23 G instructions
    /// of a default render of a 227k-particle dam break at 1024 × 768).
    fn level(&self, l: usize) -> Bound {
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
struct View<'a> {
    grid: &'a PerspectiveGrid,
    tfb: &'a TfBounds,
    field: &'a FieldParams,
    reach: &'a [(u32, u32)],
}

/// Each particle's depth samples: the half-open range of indices of the view's sample depths
/// inside its support's depth extent [c.z − H, c.z + H] (as [`fluidcast_grid::within`]
/// counts them), found once per view instead of once in every cell that references it.
fn sample_reach(grid: &PerspectiveGrid) -> Vec<(u32, u32)> {
    let Some(depths) = grid.depths.as_ref() else {
        return Vec::new();
    };
    let z = &depths.z;
    grid.particles
        .par_iter()
        .map(|p| {
            let lo = z.partition_point(|&d| d < p.c[2] - p.h());
            let hi = z.partition_point(|&d| d <= p.c[2] + p.h());
            (lo as u32, hi.max(lo) as u32)
        })
        .collect()
}

/// A particle's sample range (see [`sample_reach`]) within the cell whose `dz` samples start
/// at index `k0`, counted from `k0`: what `within` finds among the cell's depths.
#[inline]
fn cell_range((lo, hi): (u32, u32), k0: usize, dz: usize) -> std::ops::Range<usize> {
    let clamp = |i: u32| (i as usize).clamp(k0, k0 + dz) - k0;
    clamp(lo)..clamp(hi)
}

/// The value bounds of one cell's samples (see [`CellSamples`]). `parts` are the bundle's
/// sub-bundles for the coverage test; `stop` the nearest depth where opaque geometry stops a
/// ray of the bundle; `scratch` holds the cell's reaching particles for the coverage test
/// ([`Scratch`]).
#[inline(always)]
fn cell_bounds(
    view: &View,
    (bundle, parts): (&Bundle, &Parts),
    cell: &Cell,
    stop: f64,
    scratch: &mut Scratch,
) -> CellSamples {
    let (grid, tfb, params) = (view.grid, view.tfb, view.field);
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
    let mut sum_lo = [0.0f64; 64];
    let mut sum_hi = [0.0f64; 64];
    let mut any = 0u64;
    let (mx, my) = (
        0.5 * (bundle.x[0] + bundle.x[1]),
        0.5 * (bundle.y[0] + bundle.y[1]),
    );
    let Scratch {
        reaching,
        others,
        lanes,
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
    let tf = tfb.transfer_function();
    let mut steps = Vec::with_capacity(dz);
    // Neighbouring samples mostly see the same particles, so the same value range: its
    // colour and extinction bounds are found once.
    let mut last: Option<((f64, f64), ValueBound)> = None;
    for k in 0..dz {
        let step = depths.z[k0 + k + 1] - depths.z[k0 + k];
        let ds = [step * bundle.dlen[0], step * bundle.dlen[1]];
        if any & (1u64 << k) == 0 {
            steps.push(CellSamples::step(ValueBound::EMPTY, ds));
            continue;
        }
        let (a, b) = match params.field {
            FieldKind::Csph => (f64::from(qlo[k]), f64::from(qhi[k])),
            _ => (sum_lo[k], sum_hi[k]),
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
            may_be_empty: open >> k & 1 != 0 || stopped,
            ..bound
        };
        steps.push(CellSamples::step(vb, ds));
    }
    CellSamples {
        steps,
        // A sample left open is one that a particle reaches and some sub-bundle's rays may
        // miss.
        gappy: open != 0,
    }
}

/// [`cell_bounds`] run through [`pulp::Arch::dispatch`], which compiles it for the CPU's
/// best instruction set (the coverage test's fixed-size loops over sub-bundles vectorise).
struct CellBounds<'a> {
    view: &'a View<'a>,
    bundle: (&'a Bundle, &'a Parts),
    cell: &'a Cell,
    stop: f64,
    scratch: &'a mut Scratch,
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
fn bits(r: &std::ops::Range<usize>) -> u64 {
    (u64::MAX >> (64 - (r.end - r.start))) << r.start
}

/// A particle of a cell that reaches some of its samples, as [`cell_bounds`] keeps it for the
/// coverage test: its index and its samples in the cell (bit k for sample k).
struct Reacher {
    j: u32,
    samples: u64,
}

/// The working memory of [`cell_bounds`], kept across the cells of a bundle: the cell's
/// particles that reach some sample, those that reach the bundle's middle ray first
/// (`reaching`, with `others` while they are sorted), and the same particles as [`Lanes`]
/// once a sample of the cell keeps a coverage gap.
#[derive(Default)]
struct Scratch {
    reaching: Vec<Reacher>,
    others: Vec<Reacher>,
    lanes: Lanes,
}

/// The distance from `c` to the farther of the extremes `e` along one axis.
#[inline(always)]
fn far(e: [f64; 2], c: f64) -> f64 {
    (e[0] - c).abs().max((e[1] - c).abs())
}

/// The squared radius of the disc of a particle centred at depth `cz` with support radius `h`
/// in the plane of `at`, less the relative margin [`COVER_MARGIN`], or −∞ where the
/// particle does not reach the sample (`reaches`) or its disc is too small to cover any part.
#[inline(always)]
fn disc_limit(at: &PartsAt, (cz, h): (f64, f64), reaches: bool) -> f64 {
    let dz = at.z - cz;
    let lim = h * h - dz * dz;
    match reaches && lim > at.wide {
        true => lim * COVER_MARGIN,
        false => f64::NEG_INFINITY,
    }
}

/// The parts of `at` covered by the disc of squared radius `lim` (from [`disc_limit`])
/// around `(cx, cy)`: bit `v·cols + u` when every ray of part (u, v) is strictly inside it
/// ([`Bundle::covered_by`] of the part, by the same arithmetic). Only the bits of `want` are
/// sure to be found: a disc that covers the rectangle of all parts covers each (the far
/// corner of a part is no farther, rounded, than that of the rectangle), and at most
/// [`FEW_PARTS`] parts are tested one by one, more all at once.
#[inline(always)]
fn disc_cover(at: &PartsAt, (cx, cy): (f64, f64), lim: f64, want: u64, all: u64) -> u64 {
    if lim == f64::NEG_INFINITY {
        return 0;
    }
    let (fx, fy) = (far(at.hull_x, cx), far(at.hull_y, cy));
    if fx * fx + fy * fy < lim {
        return all;
    }
    match want.count_ones() <= FEW_PARTS {
        true => disc_few(at, (cx, cy), lim, want),
        false => disc_each(at, (cx, cy), lim),
    }
}

/// Whether the disc of squared radius `lim` around `(cx, cy)` covers part `s` of `at`.
#[inline(always)]
fn disc_covers(at: &PartsAt, (cx, cy): (f64, f64), lim: f64, s: usize) -> bool {
    let (fx, fy) = (far(at.x[s % at.cols], cx), far(at.y[s / at.cols], cy));
    fx * fx + fy * fy < lim
}

/// The parts of `want` covered by the disc of squared radius `lim` around `(cx, cy)` at
/// `at`, one by one.
#[inline(always)]
fn disc_few(at: &PartsAt, c: (f64, f64), lim: f64, want: u64) -> u64 {
    let mut bits = 0u64;
    let mut todo = want;
    while todo != 0 {
        let s = todo.trailing_zeros() as usize;
        todo &= todo - 1;
        bits |= u64::from(disc_covers(at, c, lim, s)) << s;
    }
    bits
}

/// The parts covered by the disc of squared radius `lim` around `(cx, cy)` at `at`, all
/// at once: the far-corner offsets once per column and row, in loops of fixed length.
#[inline(always)]
fn disc_each(at: &PartsAt, (cx, cy): (f64, f64), lim: f64) -> u64 {
    let (fx, fy) = (at.x.map(|e| far(e, cx)), at.y.map(|e| far(e, cy)));
    let nearest = |f: &[f64; SIDE]| f.iter().fold(f64::INFINITY, |a, &b| a.min(b));
    let (mx, my) = (nearest(&fx), nearest(&fy));
    if mx * mx + my * my >= lim {
        return 0; // not even the nearest column and row
    }
    let (fx2, fy2) = (fx.map(|x| x * x), fy.map(|y| y * y));
    let mut bits = 0u64;
    for (v, y2) in fy2.iter().enumerate() {
        let row = fx2
            .iter()
            .enumerate()
            .fold(0u64, |m, (u, x2)| m | (u64::from(x2 + y2 < lim) << u));
        bits |= row << (v * at.cols);
    }
    bits
}

/// The most open parts that [`disc_cover`] tests one by one rather than all at once (a
/// part alone costs about a sixth of all of them).
const FEW_PARTS: u32 = 3;

/// How many particles the coverage test takes at once.
const LANE_WIDTH: usize = 4;

/// [`LANE_WIDTH`] particles of [`Lanes`]: centres in view space, support radii, and the cell's
/// samples each reaches (none for a lane not filled).
#[derive(Clone, Copy)]
struct LaneChunk {
    cx: [f64; LANE_WIDTH],
    cy: [f64; LANE_WIDTH],
    cz: [f64; LANE_WIDTH],
    h: [f64; LANE_WIDTH],
    samples: [u64; LANE_WIDTH],
}

impl LaneChunk {
    const EMPTY: LaneChunk = LaneChunk {
        cx: [0.0; LANE_WIDTH],
        cy: [0.0; LANE_WIDTH],
        cz: [0.0; LANE_WIDTH],
        h: [0.0; LANE_WIDTH],
        samples: [0; LANE_WIDTH],
    };

    /// Per lane, [`disc_limit`] at sample `k`.
    #[inline(always)]
    fn limits(&self, at: &PartsAt, k: usize) -> [f64; LANE_WIDTH] {
        std::array::from_fn(|l| {
            disc_limit(at, (self.cz[l], self.h[l]), self.samples[l] >> k & 1 != 0)
        })
    }

    /// Whether some particle of the chunk that reaches sample `k` covers part `s` at `at`:
    /// bit `s` of [`disc_cover`] alone ([`disc_covers`] in every lane, without a branch).
    #[inline(always)]
    fn covers_part(&self, at: &PartsAt, k: usize, s: usize) -> bool {
        let lim = self.limits(at, k);
        (0..LANE_WIDTH).fold(false, |hit, l| {
            hit | disc_covers(at, (self.cx[l], self.cy[l]), lim[l], s)
        })
    }
}

/// Particles of a cell that reach some of its samples, [`LANE_WIDTH`] at a time, one array
/// per coordinate, for the coverage test's one-part tests: where a sample keeps a coverage
/// gap, every particle that reaches it is tested against one part, and reading them in order,
/// without looking each up by index and without a branch per particle, took the coverage
/// test from 0.94 G to 0.72 G instructions of a default render of a 254k-particle double dam
/// break.
#[derive(Default)]
struct Lanes {
    chunks: Vec<LaneChunk>,
    len: usize,
}

impl Lanes {
    fn clear(&mut self) {
        self.chunks.clear();
        self.len = 0;
    }

    /// The particles of `reaching`, in its order.
    fn fill(&mut self, reaching: &[Reacher], particles: &[ViewParticle]) {
        self.clear();
        for r in reaching {
            self.push(&particles[r.j as usize], r.samples);
        }
    }

    /// Adds `p`, which reaches the cell's `samples` (bit k for sample k).
    #[inline(always)]
    fn push(&mut self, p: &ViewParticle, samples: u64) {
        let lane = self.len % LANE_WIDTH;
        if lane == 0 {
            self.chunks.push(LaneChunk::EMPTY);
        }
        if let Some(c) = self.chunks.last_mut() {
            c.cx[lane] = p.c[0];
            c.cy[lane] = p.c[1];
            c.cz[lane] = p.c[2];
            c.h[lane] = p.h();
            c.samples[lane] = samples;
        }
        self.len += 1;
    }
}

/// True when `p`'s support reaches within half its radius of the bundle's middle ray
/// (`(mx, my)`, its x and y at unit depth, or in the view plane for a parallel view). Such
/// particles cover most of the bundle, so the coverage test takes them first.
#[inline]
fn covers_middle(p: &ViewParticle, (mx, my): (f64, f64), parallel: bool) -> bool {
    let s = if parallel { 1.0 } else { p.c[2] };
    let (dx, dy) = (mx * s - p.c[0], my * s - p.c[1]);
    4.0 * (dx * dx + dy * dy) < p.h() * p.h()
}

/// The coverage test of one cell (Sec. 4.2, see [`Parts`]): at each sample that a particle
/// reaches, whether every sub-bundle's rays are inside some particle's support.
struct Coverage<'a> {
    parts: &'a Parts,
    particles: &'a [ViewParticle],
    /// The particles that reach some sample, central ones first.
    reaching: &'a [Reacher],
    /// The cell's sample depths.
    zs: &'a [f64],
}

impl Coverage<'_> {
    /// The samples of `any` left open: some sub-bundle's rays are inside no particle's
    /// support there. A sample with a gap keeps it over neighbouring samples: one sub-bundle
    /// left open at the sample before is tested alone first, and where no particle covers it
    /// the sample is open without testing the others (3 in 4 tests on a 227k-particle dam
    /// break were on samples that stayed open). `lanes` holds the particles for those
    /// one-part tests, filled at the first.
    fn of(&self, any: u64, lanes: &mut Lanes) -> u64 {
        let all = self.parts.all;
        lanes.clear();
        let mut open = any;
        let mut gap: Option<usize> = None;
        let mut todo = any;
        while todo != 0 {
            let k = todo.trailing_zeros() as usize;
            todo &= todo - 1;
            let at = self.parts.at(self.zs[k]);
            if let Some(g) = gap {
                if lanes.len == 0 {
                    lanes.fill(self.reaching, self.particles);
                }
                if !lanes.chunks.iter().any(|c| c.covers_part(&at, k, g)) {
                    continue;
                }
            }
            // The sub-bundles covered at sample k.
            let mut cover = 0u64;
            for r in self.reaching.iter().filter(|r| r.samples >> k & 1 != 0) {
                let p = &self.particles[r.j as usize];
                let lim = disc_limit(&at, (p.c[2], p.h()), true);
                cover |= disc_cover(&at, (p.c[0], p.c[1]), lim, all & !cover, all);
                if cover == all {
                    open &= !(1u64 << k);
                    break;
                }
            }
            // The lowest sub-bundle left open, if any.
            let left = all & !cover;
            gap = (left != 0).then(|| left.trailing_zeros() as usize);
        }
        open
    }
}

#[derive(Clone, Copy, PartialEq)]
enum Choice {
    Level(u8),
    SuperPixel,
}

/// One cell of a bundle as the greedy sees it: its strict full-rate bound, that bound
/// relaxed (Sec. 5.1), and its per-sample bounds for coarser levels (`None` for a surface
/// cell, which keeps level 0 and is never a super-pixel).
struct CellAnalysis {
    full: Bound,
    relaxed: Bound,
    samples: Option<CellSamples>,
}

/// Sec. 5.1: the lower bounds of `bl` (a cell's bound at some level) move up by
/// E_relax × the width of `b0` (its level-0 bound).
fn relax(bl: &Bound, b0: &Bound, relax: f64) -> Bound {
    let mut r = *bl;
    for ch in 0..4 {
        let lo0 = b0.hi[ch] - (1.0 - relax) * (b0.hi[ch] - b0.lo[ch]);
        // max/min, not clamp: a NaN (from degenerate depths) becomes 0, never a panic.
        r.lo[ch] = (lo0 + (bl.lo[ch] - b0.lo[ch])).max(0.0).min(r.hi[ch]);
    }
    r
}

/// The most a cell's own change of level can move a pixel: every ray's segment through the
/// cell, at level l and at full rate, lies in `cell` (its strict bound at level l), so a
/// pixel I = F_I + F_T·(C_I + C_T·B_I), α = 1 − F_T·C_T·B_T moves by at most
/// F_T·(w(C_I) + w(C_T)·B_I) in colour and F_T·w(C_T)·B_T in alpha, with F_T at most
/// `front_t` (the largest transparency in front of the cell) and B at most `back`'s upper
/// bound. This is the level cap of Sec. 4.2 (w(C) ≤ E_I, which takes F_T = 1 and no
/// back) seen from the screen: a cell behind fluid that already hides most of it may vary
/// more.
fn level_error(front_t: f64, cell: &Bound, back: &Bound) -> f64 {
    let wt = cell.hi[3] - cell.lo[3];
    let colour = (0..3)
        .map(|ch| cell.hi[ch] - cell.lo[ch] + wt * back.hi[ch])
        .fold(wt * back.hi[3], f64::max);
    front_t * colour
}

/// Sec. 4.1–4.2 for each cell of bundle `b`: its bounds, and whether it is a surface cell.
fn analyse_cells(
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

/// The greedy of Sec. 4.4 and 5.3, back to front: per cell, among full rate, the coarser
/// levels up to the cap ([`level_error`] below E_I; only those levels are composited) and a
/// super-pixel, the cheapest whose composite with the relaxed full-rate front and the chosen
/// back stays below `budget` (full rate when none does). Returns the choices and the
/// composited bound of the plan.
fn choose_levels(
    cells: &[CellAnalysis],
    maxl: usize,
    tol: f64,
    field: &FieldParams,
    params: &PlanParams,
) -> (Vec<Choice>, Bound) {
    let n = cells.len();
    let budget = tol - field.min_transmittance.max(0.0);
    // Front composites of the relaxed full-rate bounds, F_c = cells 0..c.
    let mut front = Vec::with_capacity(n + 1);
    front.push(Bound::EMPTY);
    for c in 0..n {
        let f: Bound = front[c];
        front.push(f.over(&cells[c].relaxed));
    }
    let mut choice = vec![Choice::Level(0); n];
    let mut back = Bound::EMPTY;
    for c in (0..n).rev() {
        let cell = &cells[c];
        let fits = |cb: &Bound| front[c].over(&cb.over(&back)).width() < budget;
        // The cheapest option under the budget, trying them from the most expensive (full
        // rate, also where none fits) to the cheapest (super-pixel). (The paper takes the
        // widest bound under the budget, which is the same where wider bounds come with
        // coarser levels; two levels whose bounds agree up to rounding went to the finer one
        // by a last-digit difference, and the CPU and GPU could choose differently.)
        let mut chosen = (Choice::Level(0), cell.relaxed);
        if let Some(samples) = &cell.samples {
            for l in 1..=maxl {
                let next = samples.level(l);
                if level_error(front[c].hi[3], &next, &back) >= tol {
                    break;
                }
                let cb = relax(&next, &cell.full, params.relax);
                if fits(&cb) {
                    chosen = (Choice::Level(l as u8), cb);
                }
            }
            if params.superpixels && fits(&cell.full) {
                chosen = (Choice::SuperPixel, cell.full);
            }
        }
        choice[c] = chosen.0;
        back = chosen.1.over(&back);
    }
    (choice, back)
}

/// Cell merging (Sec. 6.2): the spans of a bundle's `cells` (the first at index `first` of
/// the grid's cells) with their chosen levels: pairs of aligned runs of equal size and level,
/// level by level up to `maxl`; a super-pixel is a span of its own.
fn merge_spans(
    cells: &[Cell],
    first: u32,
    choice: &[Choice],
    cells_in: &[CellAnalysis],
    maxl: usize,
) -> Vec<Span> {
    let mut spans: Vec<(Span, u32)> = cells
        .iter()
        .enumerate()
        .map(|(i, cell)| {
            let (level, sp) = match choice[i] {
                Choice::Level(l) => (l, None),
                Choice::SuperPixel => (0, Some(cells_in[i].full.mid().map(|v| v as f32))),
            };
            (
                Span {
                    first: first + i as u32,
                    count: 1,
                    level,
                    superpixel: sp,
                },
                cell.z,
            )
        })
        .collect();
    for m in 0..maxl as u32 {
        let size = 1u32 << m;
        let mut merged = Vec::with_capacity(spans.len());
        let mut i = 0;
        while i < spans.len() {
            let (a, za) = spans[i];
            if let Some(&(bs, zb)) = spans.get(i + 1) {
                if a.superpixel.is_none()
                    && bs.superpixel.is_none()
                    && a.level == bs.level
                    && a.level as u32 > m
                    && a.count == size
                    && bs.count == size
                    && za % (2 * size) == 0
                    && zb == za + size
                {
                    merged.push((
                        Span {
                            count: 2 * size,
                            ..a
                        },
                        za,
                    ));
                    i += 2;
                    continue;
                }
            }
            merged.push((a, za));
            i += 1;
        }
        spans = merged;
    }
    spans.into_iter().map(|s| s.0).collect()
}

/// Bundle `b` at full rate, one span per cell, without an analysis: `bound` is what its
/// plan and full-rate bounds claim (none is known: [`Bound::ANY`]).
fn full_rate_bundle(grid: &PerspectiveGrid, b: usize, bound: Bound) -> BundlePlan {
    let cells = grid.bundle_cells(b);
    let first = grid.bundle_first_cell(b) as u32;
    let n = cells.len();
    let refs: u64 = cells.iter().map(|c| (c.end - c.start) as u64).sum();
    let mut stats = PlanStats {
        cells: n as u64,
        refs_sampled: refs,
        ..Default::default()
    };
    stats.level_cells[0] = n as u64;
    let work = cells
        .iter()
        .map(|c| cast_work(c.end - c.start, Choice::Level(0)))
        .sum();
    BundlePlan {
        spans: (0..n as u32)
            .map(|i| Span {
                first: first + i,
                count: 1,
                level: 0,
                superpixel: None,
            })
            .collect(),
        levels: vec![0; n],
        full: bound,
        plan: bound,
        summary: BundleSummary {
            predicted_error: 0.0,
            mean_level: 0.0,
            full: 1.0,
            adapted: 0.0,
            superpixel: 0.0,
            front_sampled: if n > 0 { 1.0 } else { 0.0 },
        },
        stats,
        work: [work, work],
    }
}

/// Bundle `b`'s plan: its analysis and greedy choice of levels, and cell merging (full rate
/// without a tolerance, or where `analyse` is false).
fn plan_bundle(
    view: &View,
    b: usize,
    surface: Option<&[bool]>,
    stop: f64,
    params: &PlanParams,
    analyse: bool,
) -> BundlePlan {
    let (grid, field) = (view.grid, view.field);
    let tol = match params.tolerance {
        Some(tol) if analyse => tol,
        Some(_) => {
            let mut bp = full_rate_bundle(grid, b, Bound::ANY);
            bp.stats.unanalysed_bundles = u64::from(!bp.levels.is_empty());
            return bp;
        }
        None => return full_rate_bundle(grid, b, Bound::EMPTY),
    };
    let cells = grid.bundle_cells(b);
    let first = grid.bundle_first_cell(b) as u32;
    let n = cells.len();
    let mut stats = PlanStats {
        cells: n as u64,
        ..Default::default()
    };
    let cells_in = analyse_cells(view, b, surface, stop, params);
    stats.surface_cells = cells_in.iter().filter(|c| c.samples.is_none()).count() as u64;
    let maxl = grid.params.max_level() as usize;
    let (choice, back) = choose_levels(&cells_in, maxl, tol, field, params);
    let full = cells_in
        .iter()
        .rev()
        .fold(Bound::EMPTY, |acc, c| c.full.over(&acc));

    let spans = merge_spans(cells, first, &choice, &cells_in, maxl);

    // Statistics and the bundle summary.
    let mut levels = vec![0u8; n];
    let (mut nfull, mut nadapt, mut nsp, mut lsum) = (0u32, 0u32, 0u32, 0u32);
    for (c, ch) in choice.iter().enumerate() {
        match *ch {
            Choice::Level(l) => {
                levels[c] = l;
                stats.level_cells[l as usize] += 1;
                lsum += l as u32;
                if l == 0 {
                    nfull += 1;
                } else {
                    nadapt += 1;
                }
            }
            Choice::SuperPixel => {
                levels[c] = SamplingPlan::SUPERPIXEL;
                stats.superpixel_cells += 1;
                nsp += 1;
            }
        }
    }
    for s in &spans {
        if s.superpixel.is_none() {
            stats.merged_cells += (s.count - 1) as u64;
            let lo = (s.first - first) as usize;
            stats.refs_sampled +=
                grid.merged_refs(&cells[lo..lo + s.count as usize]).count() as u64;
        }
    }
    let work = cells.iter().zip(&choice).fold([0, 0], |[f, p], (c, &ch)| {
        let refs = c.end - c.start;
        [
            f + cast_work(refs, Choice::Level(0)),
            p + cast_work(refs, ch),
        ]
    });
    let nn = n.max(1) as f32;
    let front_sampled = match spans.first() {
        Some(s) if s.superpixel.is_none() => 1.0,
        _ => 0.0,
    };
    BundlePlan {
        spans,
        levels,
        full,
        plan: back,
        summary: BundleSummary {
            predicted_error: back.width() as f32,
            mean_level: lsum as f32 / (nfull + nadapt).max(1) as f32,
            full: nfull as f32 / nn,
            adapted: nadapt as f32 / nn,
            superpixel: nsp as f32 / nn,
            front_sampled,
        },
        stats,
        work,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use fluidcast_view::Camera;
    use proptest::prelude::*;

    static PARTIAL: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

    /// No extinction lets everything through, over any length (a far outlier's step can be
    /// infinitely long), and no length does too; a product that is not a number is `None`.
    #[test]
    fn transmittance_is_one_without_extinction_or_length() {
        assert_eq!(transmittance(0.0, f64::INFINITY), Some(1.0));
        assert_eq!(transmittance(f64::INFINITY, 0.0), Some(1.0));
        assert_eq!(transmittance(0.0, 2.0), Some(1.0));
        assert_eq!(transmittance(f64::INFINITY, 1.0), Some(0.0));
        assert_eq!(transmittance(f64::NAN, 1.0), None);
        let t = transmittance(2.0, 0.5).unwrap();
        assert!((t - (-1.0f64).exp()).abs() < 1e-15);
    }

    /// The probe's rule, exactly: the others are analysed where the probe's planned cast
    /// work is at least a fifth below its full-rate work, summed over its bundles; a probe
    /// without work (nothing in it) adapts.
    #[test]
    fn probe_pays_from_a_fifth_of_its_work_saved() {
        let pays = |w: &[[u64; 2]]| probe_pays(w.iter().copied());
        assert!(pays(&[]));
        assert!(pays(&[[0, 0]]));
        assert!(pays(&[[5, 4]]));
        assert!(!pays(&[[5, 5]]));
        assert!(pays(&[[1_000_000, 800_000]]));
        assert!(!pays(&[[1_000_000, 800_001]]));
        assert!(pays(&[[10, 10], [10, 6]]));
        assert!(!pays(&[[10, 10], [10, 7]]));
        assert!(pays(&[[u64::MAX / 8, 0]]));
    }

    /// The probe takes one bundle in every 8 consecutive ones along a row, and along a
    /// column, whatever the image's width: an eighth of the image, evenly.
    #[test]
    fn probe_bundles_are_one_in_eight_along_rows_and_columns() {
        for bx in [1u32, 3, 8, 13, 128] {
            let rows = 24u32;
            let probe = |x: u32, y: u32| is_probe_bundle(bx, (y * bx + x) as usize);
            for y in 0..rows {
                for x0 in 0..bx.saturating_sub(7) {
                    let n = (x0..x0 + 8).filter(|&x| probe(x, y)).count();
                    assert_eq!(n, 1, "row {y}, columns {x0}.. of {bx}");
                }
            }
            for x in 0..bx {
                for y0 in 0..rows - 7 {
                    let n = (y0..y0 + 8).filter(|&y| probe(x, y)).count();
                    assert_eq!(n, 1, "column {x}, rows {y0}.. of {bx}");
                }
            }
        }
    }

    /// The parts `p` covers at depth `z`, as the coverage test finds them (`p` reaching
    /// sample 0, three empty lanes beside it).
    fn covered_parts(parts: &Parts, p: &ViewParticle, z: f64) -> u64 {
        let at = parts.at(z);
        let lim = disc_limit(&at, (p.c[2], p.h()), true);
        disc_cover(&at, (p.c[0], p.c[1]), lim, parts.all, parts.all)
    }

    /// Coverage keeps a relative margin of 1e-9 below the support (so that rounding never
    /// claims a covered part, [`Bundle::covered_by`]'s rule): a disc whose far corner lies
    /// half a margin inside covers nothing, one twice a margin inside covers, in each
    /// projection.
    #[test]
    fn coverage_keeps_its_margin_at_the_support_edge() {
        for parallel in [false, true] {
            let camera = Camera {
                parallel_projection: parallel,
                parallel_scale: 0.6,
                ..Camera::default()
            };
            let frame = camera.frame(64, 48).unwrap();
            let bundle = Bundle::from_pixels(&frame, [10, 14, 20, 23]);
            let parts = Parts::new(&bundle.split(&frame, COVER_SPLIT));
            let z = 2.0;
            let [x0, x1, y0, y1] = bundle.rect_at(z);
            // Centred on one corner: the far corner is the opposite one.
            let d2 = (x1 - x0).powi(2) + (y1 - y0).powi(2);
            for (inside, covered) in [(0.5e-9, false), (2e-9, true)] {
                // H in single precision, as particles hold it; the centre moved along x
                // (from the corner) so that the far corner lies at exactly that depth inside.
                let h = f64::from((d2 / (1.0 - inside)).sqrt() as f32);
                let dx = (h * h * (1.0 - inside) - (y1 - y0).powi(2)).sqrt();
                let p = ViewParticle::new([x1 - dx, y0, z], h, 1.0, 1.0, 1.0);
                assert_eq!(bundle.covered_by(&p, z), covered, "{parallel} {inside}");
                assert_eq!(
                    covered_parts(&parts, &p, z) == parts.all,
                    covered,
                    "{parallel} {inside}"
                );
            }
            // A large disc (H² = 7 view units²) whose centre lies 1.7 units beyond the far
            // corner in x and in y (1.7² + 1.7² = 5.78 < 7): it covers every part, and the
            // early exit (nearest column and row) must not skip it.
            let c = [x1 - 1.7, y1 - 1.7, z];
            let p = ViewParticle::new(c, 7f64.sqrt(), 1.0, 1.0, 1.0);
            assert!(bundle.covered_by(&p, z));
            assert_eq!(covered_parts(&parts, &p, z), parts.all, "{parallel}");
        }
    }

    /// A cell has a coverage gap exactly where the brute force finds one, sample by sample
    /// (an open sample's value bound may be empty): a sample that some particle reaches is
    /// covered for a sub-bundle when any particle of the cell covers that part
    /// ([`Bundle::covered_by`]), tested for every particle and sample with no early exit and
    /// no pre-filter. Skipping particles, samples or the discs that reach a part only from
    /// behind the sample would claim gaps inside the fluid; taking a gap for the next sample's
    /// without testing would claim gaps where the fluid begins. A jittered block seen at an
    /// angle, both projections: about a third of the cells are covered throughout, the others
    /// (at the block's faces) are not.
    #[test]
    fn coverage_gaps_are_those_of_the_brute_force() {
        let p = fluidcast_testkit::depth_ramp(14);
        let tf = fluidcast_testkit::depth_ramp_tf(0.05);
        let tfb = TfBounds::new(&tf);
        let field = FieldParams {
            kernel: Kernel::CubicSpline,
            field: FieldKind::Csph,
            min_transmittance: 0.0,
        };
        for parallel in [false, true] {
            let camera = Camera {
                position: [0.9, 0.7, 2.2],
                focal_point: [0.0; 3],
                view_up: [0.0, 1.0, 0.0],
                parallel_projection: parallel,
                parallel_scale: 0.6,
                ..Camera::default()
            };
            let frame = camera.frame(96, 72).unwrap();
            let grid = PerspectiveGrid::build(&p, &frame, Default::default(), 1.0).unwrap();
            let depths = grid.depths.as_ref().unwrap();
            let dz = grid.params.depth_samples as usize;
            let reach = sample_reach(&grid);
            let view = View {
                grid: &grid,
                tfb: &tfb,
                field: &field,
                reach: &reach,
            };
            let (mut gaps, mut cells, mut open_samples) = (0, 0, 0);
            let mut scratch = Default::default();
            for b in 0..grid.bundle_count() {
                let bundle = grid.bundle(b);
                let split = bundle.split(&grid.frame, COVER_SPLIT);
                let parts = Parts::new(&split);
                for cell in grid.bundle_cells(b) {
                    let bounds = (&bundle, &parts);
                    let samples = cell_bounds(&view, bounds, cell, f64::INFINITY, &mut scratch);
                    let k0 = cell.z as usize * dz;
                    let refs = &grid.refs[cell.start as usize..cell.end as usize];
                    // Per sample: reached by some particle and not covered for every part.
                    let open: Vec<bool> = (k0..k0 + dz)
                        .map(|k| {
                            let z = depths.z[k];
                            let reached = refs.iter().any(|&j| {
                                let q = &grid.particles[j as usize];
                                q.c[2] - q.h() <= z && z <= q.c[2] + q.h()
                            });
                            let covered = split.iter().all(|part| {
                                refs.iter()
                                    .any(|&j| part.covered_by(&grid.particles[j as usize], z))
                            });
                            reached && !covered
                        })
                        .collect();
                    for (k, &o) in open.iter().enumerate() {
                        // (A sample no particle reaches has no value bound to widen.)
                        if !samples.steps[k].0.empty {
                            let m = samples.steps[k].0.may_be_empty;
                            assert_eq!(m, o, "{parallel} bundle {b} cell {} sample {k}", cell.z);
                            open_samples += usize::from(o);
                        }
                    }
                    let want = open.iter().any(|&o| o);
                    assert_eq!(samples.gappy, want, "{parallel} bundle {b} cell {}", cell.z);
                    gaps += usize::from(want);
                    cells += 1;
                }
            }
            assert!(
                gaps > 0 && cells - gaps >= 100 && open_samples > 2 * gaps,
                "{parallel}: {gaps} of {cells} gappy, {open_samples} open samples"
            );
        }
    }

    /// `level_error` is the largest pixel change that swapping a cell's segment for another
    /// inside its bound can make, front and back anywhere inside theirs: the maximum over
    /// the bounds' corners (the composite is monotone in every quantity), found by brute
    /// force, equals it.
    #[test]
    fn level_error_is_the_largest_pixel_change() {
        let mut rnd = fluidcast_testkit::rng(7);
        let mut r = |lo: f64, hi: f64| lo + (hi - lo) * f64::from(rnd());
        for _ in 0..2000 {
            let mut bound = || {
                let lo = [r(0.0, 0.5), r(0.0, 0.5), r(0.0, 0.5), r(0.0, 1.0)];
                let hi = [0, 1, 2, 3].map(|c| {
                    if c == 3 {
                        r(lo[c], 1.0)
                    } else {
                        lo[c] + r(0.0, 0.5)
                    }
                });
                Bound { lo, hi }
            };
            let (cell, back) = (bound(), bound());
            let front_t = r(0.0, 1.0);
            let corners = |b: &Bound| -> Vec<[f64; 4]> {
                (0..16)
                    .map(|m| [0, 1, 2, 3].map(|c| if m >> c & 1 == 1 { b.hi[c] } else { b.lo[c] }))
                    .collect()
            };
            let mut most = 0.0f64;
            for c1 in corners(&cell) {
                for c2 in corners(&cell) {
                    for bk in corners(&back) {
                        for f in [0.0, front_t] {
                            let px = |c: [f64; 4]| {
                                let v = [0, 1, 2].map(|ch| f * (c[ch] + c[3] * bk[ch]));
                                [v[0], v[1], v[2], 1.0 - f * c[3] * bk[3]]
                            };
                            let (a, b) = (px(c1), px(c2));
                            most = (0..4).map(|ch| (a[ch] - b[ch]).abs()).fold(most, f64::max);
                        }
                    }
                }
            }
            let e = level_error(front_t, &cell, &back);
            assert!(
                (e - most).abs() <= 1e-12,
                "level_error {e}, brute force {most}"
            );
        }
    }

    /// The property below sees partial coverage (some parts, not all) often.
    #[test]
    fn parts_cover_partially_often() {
        parts_cover_as_each_part_does();
        assert!(PARTIAL.load(std::sync::atomic::Ordering::Relaxed) > 50);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(500))]
        /// The coverage test of all parts at once equals each part's own
        /// [`Bundle::covered_by`], bit for bit: bundles of 1 to 11 pixels a side (1 to 4
        /// parts a side), perspective and parallel views, discs that cover none, some and all.
        #[test]
        fn parts_cover_as_each_part_does(
            parallel in any::<bool>(),
            (x0, y0) in (0u32..50, 0u32..36),
            (w, h) in (1u32..12, 1u32..12),
            z in 0.3f64..3.0,
            (fx, fy) in (-1.5f64..1.5, -1.5f64..1.5),
            dz in -0.5f64..0.5,
            r in 0.3f64..1.5,
        ) {
            let camera = Camera { parallel_projection: parallel, parallel_scale: 0.6, ..Camera::default() };
            let frame = camera.frame(64, 48).unwrap();
            let bundle = Bundle::from_pixels(&frame, [x0, x0 + w, y0, y0 + h]);
            let split = bundle.split(&frame, COVER_SPLIT);
            let parts = Parts::new(&split);
            // A disc centred near the bundle's middle ray at depth z, offset by fx, fy
            // bundle widths.
            let [bx0, bx1, by0, by1] = bundle.rect_at(z);
            let c = [
                0.5 * (bx0 + bx1) + fx * (bx1 - bx0),
                0.5 * (by0 + by1) + fy * (by1 - by0),
                z + dz * r * (bx1 - bx0).max(by1 - by0),
            ];
            // Support radius r bundle sizes (and at least a tiny one for one-pixel bundles).
            let h = (r * (bx1 - bx0).max(by1 - by0)).max(1e-4);
            let p = ViewParticle::new(c, h, 1.0, 1.0, 1.0);
            let want = split.iter().enumerate().fold(0u64, |m, (s, b)| m | (u64::from(b.covered_by(&p, z)) << s));
            prop_assert_eq!(covered_parts(&parts, &p, z), want);
            // Asked for one part alone, it finds the same.
            let mut lanes = Lanes::default();
            lanes.push(&p, 1);
            for s in 0..split.len() {
                let alone = lanes.chunks[0].covers_part(&parts.at(z), 0, s);
                prop_assert_eq!(alone, want >> s & 1 != 0);
            }
            // A particle that does not reach the sample covers nothing.
            let at = parts.at(z);
            let lim = disc_limit(&at, (p.c[2], p.h()), false);
            prop_assert_eq!(disc_cover(&at, (p.c[0], p.c[1]), lim, parts.all, parts.all), 0);
            // Asked for some parts, it finds those of them that are covered.
            let lim = disc_limit(&at, (p.c[2], p.h()), true);
            for some in [1u64, 0b110, 0b1011, 0b1000_0001, u64::MAX, 0] {
                let found = disc_cover(&at, (p.c[0], p.c[1]), lim, some & parts.all, parts.all);
                prop_assert_eq!(found & some, want & some);
            }
            // In a lane, a particle that does not reach the sample covers no part.
            prop_assert!((0..split.len()).all(|s| !lanes.chunks[0].covers_part(&at, 1, s)));
            prop_assert_eq!(parts.all.count_ones() as usize, split.len());
            PARTIAL.fetch_add(u64::from(want != 0 && want != parts.all), std::sync::atomic::Ordering::Relaxed);
        }
    }
}
