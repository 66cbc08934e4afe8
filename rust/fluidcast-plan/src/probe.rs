//! The probe (beyond the paper, [`crate::PlanParams::probe`]): which bundles are planned
//! first, and whether their plans saved enough to plan the others (plan.wgsl's `probe`
//! stage reads the same constants).

use crate::greedy::Choice;
use crate::params::LEVELS;

/// Every `PROBE_STRIDE`-th bundle along each row, shifted by `PROBE_ROW_SHIFT` from row to
/// row, is in the probe ([`crate::PlanParams::probe`]): an eighth of the image, spread evenly over
/// it. (plan.wgsl reads these constants.)
pub const PROBE_STRIDE: u32 = 8;
/// See [`PROBE_STRIDE`].
pub const PROBE_ROW_SHIFT: u32 = 3;

pub(crate) fn is_probe_bundle(bundles_x: u32, b: usize) -> bool {
    let (bx, by) = (b as u32 % bundles_x, b as u32 / bundles_x);
    (bx + PROBE_ROW_SHIFT * by).is_multiple_of(PROBE_STRIDE)
}

/// The ray caster's work in a cell, in particle-reference × depth-sample units of 1/64: each
/// of the cell's `refs` is visited at `D_z / 2^level` depth samples of every ray (none for a
/// super-pixel).
pub(crate) fn cast_work(refs: u32, choice: Choice) -> u64 {
    match choice {
        Choice::Level(l) => u64::from(refs) << (LEVELS - 1 - usize::from(l)),
        Choice::SuperPixel => 0,
    }
}

/// Adapting pays where the planned work of the probe's bundles is at least
/// `PROBE_SAVING_NUM / PROBE_SAVING_DEN` below their full-rate work. The analysis took 0.07
/// to 0.19 of the full-rate cast's time on the dam breaks of docs/how-it-renders.md (1024 × 768, velocity);
/// the probes of the frames where adapting paid predicted savings of 0.27 and more, those of
/// the frames where it did not 0.15 and less (`fluidcast bench`, docs/how-it-renders.md). A rough measure,
/// ignoring early termination and merging, with a margin on both sides. (plan.wgsl reads
/// these constants.)
pub const PROBE_SAVING_NUM: u64 = 1;
/// See [`PROBE_SAVING_NUM`].
pub const PROBE_SAVING_DEN: u64 = 5;

/// Whether the probe's bundles, planned, predict that analysing the others pays: exactly
/// (den − num) · full ≥ den · planned, so an empty probe (no work) adapts.
pub(crate) fn probe_pays(work: impl Iterator<Item = [u64; 2]>) -> bool {
    let (full, planned) = work.fold((0, 0), |(f, p), [wf, wp]| (f + wf, p + wp));
    (PROBE_SAVING_DEN - PROBE_SAVING_NUM) * full >= PROBE_SAVING_DEN * planned
}
