//! The sort stage (the GPU's sort.wgsl): each bundle's keys sorted by (cell, merge bit,
//! particle), and the bundle's cells read off the sorted keys.

use rayon::prelude::*;

use crate::Cell;

/// Working memory of [`sort_bundle_pairs`], kept per thread across bundles.
#[derive(Default)]
pub(crate) struct SortScratch {
    /// Per (cell, merge bit) slot: first the count, then the next place to write.
    next: Vec<u32>,
    sorted: Vec<u64>,
}

/// Sorts one bundle's keys `(cell << 33) | (merge bit << 32) | particle` (as `build_within`
/// lays them out) into ascending order. The keys arrive in particle order, and a particle
/// has one key per cell, so a stable counting sort by the upper half (cell and merge bit)
/// puts them in the order a full sort does, in a few passes: 0.22 G instructions less than
/// `sort_unstable` for the 227k-particle dam break at 1024 × 768 (callgrind, the whole
/// render). Where the bundle's cells span far more depths than it holds keys (a few
/// particles far apart in depth), counting would cost more than sorting.
pub(crate) fn sort_bundle_pairs(keys: &mut [u64], scratch: &mut SortScratch) {
    if keys.is_empty() {
        return;
    }
    let (lo, hi) = keys.iter().fold((u64::MAX, 0), |(lo, hi), &k| {
        (lo.min(k >> 32), hi.max(k >> 32))
    });
    let slots = (hi - lo + 1) as usize;
    if slots > 2 * keys.len() + 64 || !keys.windows(2).all(|w| (w[0] as u32) <= (w[1] as u32)) {
        keys.sort_unstable();
        return;
    }
    let SortScratch { next, sorted } = scratch;
    next.clear();
    next.resize(slots + 1, 0);
    for &k in keys.iter() {
        next[((k >> 32) - lo) as usize + 1] += 1;
    }
    for s in 1..=slots {
        next[s] += next[s - 1];
    }
    sorted.clear();
    sorted.resize(keys.len(), 0);
    for &k in keys.iter() {
        let at = &mut next[((k >> 32) - lo) as usize];
        sorted[*at as usize] = k;
        *at += 1;
    }
    keys.copy_from_slice(sorted);
}

/// Sorts each bundle's keys (between `offsets`) by (cell, merge bit, particle), in parallel,
/// and returns each bundle's cells, front to back.
pub(crate) fn sorted_cells(keys: &mut [u64], offsets: &[usize]) -> Vec<Vec<Cell>> {
    let nb = offsets.len() - 1;
    let mut slices: Vec<&mut [u64]> = Vec::with_capacity(nb);
    let mut rest = keys;
    for b in 0..nb {
        let (a, r) = rest.split_at_mut(offsets[b + 1] - offsets[b]);
        slices.push(a);
        rest = r;
    }
    slices
        .into_par_iter()
        .enumerate()
        .map_init(SortScratch::default, |scratch, (b, s)| {
            sort_bundle_pairs(s, scratch);
            cells_of(s, offsets[b] as u32)
        })
        .collect()
}

/// The cells of one bundle's sorted keys `s`, whose references start at `base`.
pub(crate) fn cells_of(s: &[u64], base: u32) -> Vec<Cell> {
    let mut cells: Vec<Cell> = Vec::new();
    for (i, &k) in s.iter().enumerate() {
        let z = (k >> 33) as u32;
        let bit = (k >> 32) & 1 == 1;
        let i = base + i as u32;
        match cells.last_mut() {
            Some(c) if c.z == z => {
                c.end = i + 1;
                if !bit {
                    c.unique_end = i + 1;
                }
            }
            _ => cells.push(Cell {
                z,
                start: i,
                unique_end: if bit { i } else { i + 1 },
                end: i + 1,
            }),
        }
    }
    cells
}
