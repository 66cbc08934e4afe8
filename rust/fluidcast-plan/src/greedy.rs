//! The greedy of Sec. 4.4 and 5.3 (plan.wgsl's `greedy` stage): per bundle, back to front,
//! the cheapest level or super-pixel per cell under the error budget, then the merged spans.

use crate::analyse::{analyse_cells, CellSamples, View};
use crate::params::{FieldParams, PlanParams};
use crate::probe::cast_work;
use crate::{Bound, BundlePlan, BundleSummary, PlanStats, SamplingPlan, Span, MAX_SPAN_SAMPLES};
use fluidcast_grid::{merged_ref_count, Cell, PerspectiveGrid};

#[derive(Clone, Copy, PartialEq)]
pub(crate) enum Choice {
    Level(u8),
    SuperPixel,
}

/// One cell of a bundle as the greedy sees it: its strict full-rate bound, that bound
/// relaxed (Sec. 5.1), and its per-sample bounds for coarser levels (`None` for a surface
/// cell, which keeps level 0 and is never a super-pixel).
pub(crate) struct CellAnalysis {
    pub(crate) full: Bound,
    pub(crate) relaxed: Bound,
    pub(crate) samples: Option<CellSamples>,
}

/// Sec. 5.1: the lower bounds of `bl` (a cell's bound at some level) move up by
/// E_relax × the width of `b0` (its level-0 bound).
pub(crate) fn relax(bl: &Bound, b0: &Bound, relax: f64) -> Bound {
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
pub(crate) fn level_error(front_t: f64, cell: &Bound, back: &Bound) -> f64 {
    let wt = cell.hi[3] - cell.lo[3];
    let colour = (0..3)
        .map(|ch| cell.hi[ch] - cell.lo[ch] + wt * back.hi[ch])
        .fold(wt * back.hi[3], f64::max);
    front_t * colour
}

/// The greedy of Sec. 4.4 and 5.3, back to front: per cell, among full rate, the coarser
/// levels up to the cap ([`level_error`] below E_I; only those levels are composited) and a
/// super-pixel, the cheapest whose composite with the relaxed full-rate front and the chosen
/// back stays below `budget` (full rate when none does). Returns the choices and the
/// composited bound of the plan.
///
/// A coarser level in front of a super-pixel is held to its unrelaxed bound. Relaxation
/// (Sec. 5.1) leaves out of a cell's bound the lateral variation its rays share with full
/// rate; a super-pixel behind it puts the lateral error back (Sec. 5.2 bounds the super-pixel
/// itself unrelaxed for that reason), and both errors reach the same pixels. With relaxed
/// levels in front of super-pixels, 0.03–0.15 % of the pixels of a three-phase dam break
/// not used in development (71k particles, t = 0, velocity, 1024 × 768, three views; 0.14–0.19
/// % without the image-space refinement) were above E_I, where the rule allows 0.05 %, and
/// neither levels alone nor super-pixels alone left any. See [`choose_level`].
pub(crate) fn choose_levels(
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
    let mut superpixel_behind = false;
    for c in (0..n).rev() {
        let chosen = choose_level(
            &cells[c],
            (&front[c], &back),
            maxl,
            (tol, budget),
            params,
            superpixel_behind,
        );
        choice[c] = chosen.0;
        superpixel_behind |= chosen.0 == Choice::SuperPixel;
        back = chosen.1.over(&back);
    }
    (choice, back)
}

/// One cell's choice in [`choose_levels`] and the bound it is composited with: behind the
/// relaxed full-rate `front`, in front of the chosen `back`; `superpixel_behind`: a cell
/// behind it is a super-pixel, so that its coarser levels are held to their unrelaxed
/// bounds.
fn choose_level(
    cell: &CellAnalysis,
    (front, back): (&Bound, &Bound),
    maxl: usize,
    (tol, budget): (f64, f64),
    params: &PlanParams,
    superpixel_behind: bool,
) -> (Choice, Bound) {
    let fits = |cb: &Bound| front.over(&cb.over(back)).width() < budget;
    // The cheapest option under the budget, trying them from the most expensive (full
    // rate, also where none fits) to the cheapest (super-pixel). (The paper takes the
    // widest bound under the budget, which is the same where wider bounds come with
    // coarser levels; two levels whose bounds agree up to rounding went to the finer one
    // by a last-digit difference, and the CPU and GPU could choose differently.)
    let mut chosen = (Choice::Level(0), cell.relaxed);
    let Some(samples) = &cell.samples else {
        return chosen;
    };
    for l in 1..=maxl {
        let next = samples.level(l);
        if level_error(front.hi[3], &next, back) >= tol {
            break;
        }
        let cb = match superpixel_behind {
            true => next,
            false => relax(&next, &cell.full, params.relax),
        };
        if fits(&cb) {
            chosen = (Choice::Level(l as u8), cb);
        }
    }
    if params.superpixels && fits(&cell.full) {
        chosen = (Choice::SuperPixel, cell.full);
    }
    chosen
}

/// Cell merging (Sec. 6.2): the spans of a bundle's `cells` (the first at index `first` of
/// the grid's cells) with their chosen levels: pairs of aligned runs of equal size and level,
/// level by level up to `maxl` doublings, while the merged span samples at most
/// [`MAX_SPAN_SAMPLES`] depths (`dz` samples per cell at full rate); a super-pixel is a span
/// of its own.
pub(crate) fn merge_spans(
    cells: &[Cell],
    first: u32,
    choice: &[Choice],
    cells_in: &[CellAnalysis],
    (maxl, dz): (usize, u32),
) -> Vec<Span> {
    let spans = cells.iter().enumerate().map(|(i, cell)| {
        let (level, sp) = match choice[i] {
            Choice::Level(l) => (l, None),
            Choice::SuperPixel => (0, Some(cells_in[i].full.mid().map(|v| v as f32))),
        };
        let span = Span {
            first: first + i as u32,
            count: 1,
            level,
            superpixel: sp,
        };
        (span, cell.z)
    });
    merge_runs(spans.collect(), (cells, first), maxl, dz)
}

/// Merges pairs of aligned runs (`(span, first cell's z)`, front to back) of equal size and
/// level, `maxl` times, where the merged span samples at most [`MAX_SPAN_SAMPLES`] depths
/// and the merge pays ([`merge_pays`]). A span references each particle once where single
/// cells reference it once per cell: the ray caster's work per reference (its sample range,
/// its closest approach to each lane group) is done once instead of in every cell its
/// support crosses. `cells` are the bundle's, the first at index `first` of the grid's.
fn merge_runs(
    mut spans: Vec<(Span, u32)>,
    (cells, first): (&[Cell], u32),
    maxl: usize,
    dz: u32,
) -> Vec<Span> {
    let pays = |a: &Span, b: &Span| merge_pays(cells, first, dz, a, b);
    for m in 0..maxl as u32 {
        let size = 1u32 << m;
        let fits = |level: u8| (2 * size * dz) >> level <= MAX_SPAN_SAMPLES;
        let mut merged = Vec::with_capacity(spans.len());
        let mut i = 0;
        while i < spans.len() {
            let (a, za) = spans[i];
            if let Some(&(bs, zb)) = spans.get(i + 1) {
                if a.superpixel.is_none()
                    && bs.superpixel.is_none()
                    && a.level == bs.level
                    && fits(a.level)
                    && a.count == size
                    && bs.count == size
                    && za % (2 * size) == 0
                    && zb == za + size
                    && pays(&a, &bs)
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

/// Whether merging run `a` with the run `b` behind it pays: always within D_z samples (the
/// paper's merging, Sec. 6.2: levels above 0); beyond, where the references the merge saves
/// (those of `a`'s last cell that `b`'s first repeats) are at least those it may read in vain
/// (`b`'s others: a bundle whose rays all stop inside `a` would not have read them). The
/// worst case, not a fitted share: merging every full-rate run cast 8–16 % faster on most
/// scenes but 10 % slower on a 1.9M-particle frame (about one sample per reference, rays
/// stopping within a few cells), where this rule merges about as often as before.
fn merge_pays(cells: &[Cell], first: u32, dz: u32, a: &Span, b: &Span) -> bool {
    if (2 * a.count * dz) >> a.level <= dz {
        return true;
    }
    let cell = |c: u32| &cells[(c - first) as usize];
    let back = &cells[(b.first - first) as usize..][..b.count as usize];
    let reads = merged_ref_count(back) as u32;
    let last = cell(a.first + a.count - 1);
    let shared = last.end - last.unique_end;
    shared >= reads.saturating_sub(shared)
}

/// Counts into `stats` the cells merged into a neighbour and the particle references the ray
/// caster reads (each particle once per span) of a bundle's `spans`.
fn count_spans(grid: &PerspectiveGrid, spans: &[Span], stats: &mut PlanStats) {
    for s in spans.iter().filter(|s| s.superpixel.is_none()) {
        stats.merged_cells += (s.count - 1) as u64;
        let run = &grid.cells[s.first as usize..][..s.count as usize];
        stats.refs_sampled += merged_ref_count(run) as u64;
    }
}

/// Bundle `b` at full rate without an analysis, its cells merged into spans where that pays
/// ([`merge_runs`]): `bound` is what its plan and full-rate bounds claim (none is known:
/// [`Bound::ANY`]).
pub(crate) fn full_rate_bundle(grid: &PerspectiveGrid, b: usize, bound: Bound) -> BundlePlan {
    let cells = grid.bundle_cells(b);
    let first = grid.bundle_first_cell(b) as u32;
    let n = cells.len();
    let mut stats = PlanStats {
        cells: n as u64,
        ..Default::default()
    };
    stats.level_cells[0] = n as u64;
    let work = cells
        .iter()
        .map(|c| cast_work(c.end - c.start, Choice::Level(0)))
        .sum();
    let cells_at = cells.iter().enumerate();
    let spans = merge_runs(
        cells_at
            .map(|(i, c)| (Span::full_rate(first + i as u32), c.z))
            .collect(),
        (cells, first),
        grid.params.max_level() as usize,
        grid.params.depth_samples,
    );
    count_spans(grid, &spans, &mut stats);
    BundlePlan {
        spans,
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

/// Each cell's level (or [`SamplingPlan::SUPERPIXEL`]) from its choice, counted into
/// `stats`; and the counts of full-rate, adapted and super-pixel cells and the adapted
/// levels' sum.
fn tally(choice: &[Choice], stats: &mut PlanStats) -> (Vec<u8>, (u32, u32, u32, u32)) {
    let mut levels = vec![0u8; choice.len()];
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
    (levels, (nfull, nadapt, nsp, lsum))
}

/// Bundle `b`'s plan: its analysis and greedy choice of levels, and cell merging (full rate
/// without a tolerance, or where `analyse` is false).
pub(crate) fn plan_bundle(
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

    let dz = grid.params.depth_samples;
    let spans = merge_spans(cells, first, &choice, &cells_in, (maxl, dz));

    // Statistics and the bundle summary.
    let (levels, counts) = tally(&choice, &mut stats);
    count_spans(grid, &spans, &mut stats);
    let work = cells.iter().zip(&choice).fold([0, 0], |[f, p], (c, &ch)| {
        let refs = c.end - c.start;
        [
            f + cast_work(refs, Choice::Level(0)),
            p + cast_work(refs, ch),
        ]
    });
    let (nfull, nadapt, nsp, lsum) = counts;
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
