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
//! The CPU twin is laid out as the GPU's stages (fluidcast-gpu's plan.wgsl): `params`
//! (what a plan is asked for), `probe` (the bundles planned first), `analyse` (the
//! per-cell error analysis), `coverage` (the sub-bundle coverage geometry it uses) and
//! `greedy` (levels, super-pixels and merged spans per bundle); this file holds the plan
//! itself ([`SamplingPlan`]) and builds it.
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
//!   level) and the bound stays a bound. Beyond the paper's D_z samples a span grows, full
//!   rate included, up to [`MAX_SPAN_SAMPLES`] depths where that pays (`merge_pays`): the
//!   ray caster's work per particle reference is then done once per span, not once per cell
//!   the support crosses.
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
#![warn(missing_docs)]

mod analyse;
mod coverage;
mod extremes;
mod greedy;
mod interval;
mod params;
mod probe;
mod tfbounds;

use fluidcast_grid::PerspectiveGrid;
use fluidcast_view::TransferFunction;
use rayon::prelude::*;

use analyse::{sample_reach, View};
use greedy::plan_bundle;
pub use interval::Bound;
use params::LEVELS;
pub use params::{FieldParams, PlanError, PlanParams};
use probe::{is_probe_bundle, probe_pays};
pub use probe::{PROBE_ROW_SHIFT, PROBE_SAVING_DEN, PROBE_SAVING_NUM, PROBE_STRIDE};
pub use tfbounds::{TfBounds, TfRange};

/// The most depth samples one span of the plan takes (a merged run of cells, see
/// [`Span`]): the ray casters' per-span sums hold this many (the CPU's `SpanSums`, the GPU's
/// `MAXS` in raycast.wgsl, which the WGSL prelude takes from here). D_z is at most 64
/// ([`fluidcast_grid::GridParams::validate`]), so one cell always fits.
pub const MAX_SPAN_SAMPLES: u32 = 64;

/// A run of consecutive cells of one bundle that the ray caster treats as one: `count`
/// (a power of two) cells merged, sampled every `2^level` depth samples, or a single cell
/// drawn as a super-pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Span {
    /// Index of the first cell in [`PerspectiveGrid::cells`].
    pub first: u32,
    /// Cells in the span (a power of two).
    pub count: u32,
    /// Sampling level: every `2^level`-th depth sample.
    pub level: u8,
    /// Super-pixel value (I rgb, T), the midpoint of the cell's full-rate bound.
    pub superpixel: Option<[f32; 4]>,
}

impl Span {
    /// Cell `first` alone at full rate.
    pub fn full_rate(first: u32) -> Span {
        Span {
            first,
            count: 1,
            level: 0,
            superpixel: None,
        }
    }
}

/// Per-bundle results of the analysis, for diagnostics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BundleSummary {
    /// Predicted error: the width of the composited bound of the chosen levels (the relaxed
    /// estimate when relaxation is on; a guarantee in strict mode).
    pub predicted_error: f32,
    /// Mean sampling level over the bundle's sampled cells.
    pub mean_level: f32,
    /// Share of the bundle's cells at full rate.
    pub full: f32,
    /// Share adapted in depth (level above 0).
    pub adapted: f32,
    /// Share drawn as super-pixels.
    pub superpixel: f32,
    /// 1 when the bundle's first (front-most) cell is sampled, 0 when it is a super-pixel or
    /// the bundle is empty: where rays spend their work, since they stop in the first cells
    /// of opaque fluid (the image-space refinement refines only such bundles).
    pub front_sampled: f32,
}

/// Counts over all cells.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlanStats {
    /// Non-empty cells of the grid.
    pub cells: u64,
    /// Cells per chosen level (index 0 = full rate).
    pub level_cells: [u64; LEVELS],
    /// Cells drawn as super-pixels.
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
    /// Every bundle's spans, bundle after bundle, front to back ([`SamplingPlan::bundle_spans`]).
    pub spans: Vec<Span>,
    bundle_spans: Vec<u32>,
    /// Chosen level per grid cell ([`SamplingPlan::SUPERPIXEL`] for super-pixels).
    pub cell_levels: Vec<u8>,
    /// Per bundle: the full-rate (level 0, unrelaxed) bound, which holds every full-rate
    /// pixel of the bundle, and the bound of the chosen plan; empty without adaptivity.
    pub full_bounds: Vec<Bound>,
    /// Per bundle: the bound of the chosen plan.
    pub plan_bounds: Vec<Bound>,
    /// Per bundle: what the analysis chose, for diagnostics.
    pub summaries: Vec<BundleSummary>,
    /// Counts over all cells.
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analyse::*;
    use crate::coverage::*;
    use crate::greedy::*;
    use crate::params::*;
    use fluidcast_grid::{Bundle, ViewParticle};
    use fluidcast_sph::{FieldKind, Kernel};
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

    /// A cell of two depth samples (`ds` 1 world unit, extinction κ everywhere) whose values
    /// span the colours `a` and then `b` (grey, per sample), as the analysis leaves it for
    /// the greedy: its full-rate bound, that bound relaxed, its per-sample bounds.
    fn two_sample_cell(kappa: f64, a: [f64; 2], b: [f64; 2], relax_by: f64) -> CellAnalysis {
        let vb = |[lo, hi]: [f64; 2]| ValueBound {
            empty: false,
            may_be_empty: false,
            rgb_lo: [lo; 3],
            rgb_hi: [hi; 3],
            k_lo: kappa,
            k_hi: kappa,
        };
        let samples = CellSamples {
            steps: vec![
                CellSamples::step(vb(a), [1.0, 1.0]),
                CellSamples::step(vb(b), [1.0, 1.0]),
            ],
            gappy: false,
        };
        let full = samples.level(0);
        CellAnalysis {
            full,
            relaxed: relax(&full, &full, relax_by),
            samples: Some(samples),
        }
    }

    /// A coarser level in front of a super-pixel is held to its unrelaxed bound: here the
    /// front cell's level 1 fits relaxed (and is chosen in front of a level-adapted back) but
    /// not unrelaxed, so in front of the super-pixel it stays at full rate. With α = 1 % a
    /// step: the front's widths are 0.0030 at full rate and 0.0035 at level 1 (0.0005
    /// relaxed), the back's 0.0015; E_I 0.004.
    #[test]
    fn levels_in_front_of_a_superpixel_are_not_relaxed() {
        let kappa = -(0.99f64).ln();
        let params = PlanParams::default();
        let field = FieldParams {
            kernel: Kernel::CubicSpline,
            field: FieldKind::Csph,
            min_transmittance: 0.0,
        };
        let front = two_sample_cell(kappa, [0.0, 0.05], [0.05, 0.3025], 1.0);
        let back = two_sample_cell(kappa, [0.5, 0.5754], [0.5, 0.5754], 1.0);
        let tol = 0.004;
        // The premises: level 1 of the front fits relaxed, not unrelaxed, and the front
        // itself is too wide for a super-pixel in front of the back.
        let samples = front.samples.as_ref().unwrap();
        let (l1, b) = (samples.level(1), back.full);
        assert!(level_error(1.0, &l1, &b) < tol);
        assert!(relax(&l1, &front.full, 1.0).over(&b).width() < tol);
        assert!(l1.over(&b).width() >= tol);
        assert!(front.full.over(&b).width() >= tol);
        let cells = [front, back];
        let (choice, plan) = choose_levels(&cells, 1, tol, &field, &params);
        assert!(choice[0] == Choice::Level(0) && choice[1] == Choice::SuperPixel);
        assert!(plan.width() < tol);
        // Without super-pixels the back takes level 1, relaxed, and so does the front.
        let no_sp = PlanParams {
            superpixels: false,
            ..params
        };
        let (choice, _) = choose_levels(&cells, 1, tol, &field, &no_sp);
        assert!(choice[0] == Choice::Level(1) && choice[1] == Choice::Level(1));
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
