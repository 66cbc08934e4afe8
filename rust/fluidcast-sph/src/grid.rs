use std::ops::ControlFlow;

use rayon::prelude::*;

/// A uniform world-space grid over particle positions for fixed-radius neighbour queries.
///
/// Particles are sorted by cell (counting sort); each cell stores a range into the sorted
/// index list. Queries with a radius up to the cell size visit 3×3×3 cells.
#[derive(Debug, Clone)]
pub struct NeighbourGrid<'a> {
    origin: [f32; 3],
    cell: f32,
    dims: [usize; 3],
    /// `starts[c]..starts[c+1]` indexes `indices` for cell `c`.
    starts: Vec<u32>,
    indices: Vec<u32>,
    /// The positions it was built over (borrowed: millions of particles need no copy).
    positions: &'a [[f32; 3]],
}

impl<'a> NeighbourGrid<'a> {
    /// Builds the grid with the given cell size (world units, > 0). The cell size is grown
    /// (by half, until it fits) where the grid would need more than 4 cells a particle, so
    /// that its table takes at most 16 bytes a particle: a thin sheet of 18M particles
    /// spread over a tank asked for 108M cells (433 MB) at half the support radius.
    pub fn new(positions: &'a [[f32; 3]], cell_size: f32) -> NeighbourGrid<'a> {
        let (lo, hi) = if positions.is_empty() {
            ([0.0; 3], [0.0; 3])
        } else {
            bounds(positions)
        };
        let mut cell = cell_size.max(f32::MIN_POSITIVE);
        let budget = (positions.len() * 4 + 64) as f64;
        let dims = loop {
            let d =
                [0, 1, 2].map(|k| (((hi[k] - lo[k]) / cell).floor() as usize).saturating_add(1));
            if (d[0] as f64) * (d[1] as f64) * (d[2] as f64) <= budget {
                break d;
            }
            cell *= 1.5;
        };
        let ncell = dims[0] * dims[1] * dims[2];
        let cid = |p: &[f32; 3]| -> usize {
            let c = [0, 1, 2].map(|k| (((p[k] - lo[k]) / cell) as usize).min(dims[k] - 1));
            (c[0] * dims[1] + c[1]) * dims[2] + c[2]
        };
        // Counting sort by cell. `counts[c]` is first cell c's start, then (as the fill's
        // cursor) its end, which is cell c + 1's start: shifted back by one afterwards, so
        // no second table of ncell entries is needed.
        let mut counts = vec![0u32; ncell + 1];
        for p in positions {
            counts[cid(p) + 1] += 1;
        }
        for i in 0..ncell {
            counts[i + 1] += counts[i];
        }
        let mut indices = vec![0u32; positions.len()];
        for (i, p) in positions.iter().enumerate() {
            let c = cid(p);
            indices[counts[c] as usize] = i as u32;
            counts[c] += 1;
        }
        counts.copy_within(..ncell, 1);
        counts[0] = 0;
        NeighbourGrid {
            origin: lo,
            cell,
            dims,
            starts: counts,
            indices,
            positions,
        }
    }

    /// Calls `f(index, squared distance)` for every particle within `radius` of `x`.
    #[inline]
    pub fn for_each_near(&self, x: [f32; 3], radius: f32, mut f: impl FnMut(u32, f32)) {
        self.try_for_each_near(x, radius, |j, d2| {
            f(j, d2);
            ControlFlow::Continue(())
        });
    }

    /// `Σ weights[k]` over the particles k within `radius` of `x`, counted up to `cap`: the
    /// search stops there, so that a clump of near-coincident particles costs each of its
    /// members `cap` candidates, not the clump's size.
    pub fn weight_near(&self, x: [f32; 3], radius: f32, weights: &[u32], cap: u64) -> u64 {
        let mut n = 0u64;
        self.try_for_each_near(x, radius, |k, _| {
            n += u64::from(weights[k as usize]);
            if n >= cap {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        });
        n.min(cap)
    }

    /// [`NeighbourGrid::for_each_near`] that stops when `f` breaks.
    #[inline]
    pub fn try_for_each_near(
        &self,
        x: [f32; 3],
        radius: f32,
        mut f: impl FnMut(u32, f32) -> ControlFlow<()>,
    ) {
        let r2 = radius * radius;
        let mut lo = [0usize; 3];
        let mut hi = [0usize; 3];
        for k in 0..3 {
            let a = ((x[k] - radius - self.origin[k]) / self.cell).floor();
            let b = ((x[k] + radius - self.origin[k]) / self.cell).floor();
            if b < 0.0 || a >= self.dims[k] as f32 {
                return;
            }
            lo[k] = a.max(0.0) as usize;
            hi[k] = (b as usize).min(self.dims[k] - 1);
        }
        for cx in lo[0]..=hi[0] {
            for cy in lo[1]..=hi[1] {
                let base = (cx * self.dims[1] + cy) * self.dims[2];
                let s = self.starts[base + lo[2]] as usize;
                let e = self.starts[base + hi[2] + 1] as usize;
                for &j in &self.indices[s..e] {
                    let p = self.positions[j as usize];
                    let d = [p[0] - x[0], p[1] - x[1], p[2] - x[2]];
                    let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                    if d2 < r2 && f(j, d2).is_break() {
                        return;
                    }
                }
            }
        }
    }
}

/// Axis-aligned bounds of `p` (±∞ when empty).
pub(crate) fn bounds(p: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for q in p {
        for k in 0..3 {
            lo[k] = lo[k].min(q[k]);
            hi[k] = hi[k].max(q[k]);
        }
    }
    (lo, hi)
}

/// The distinct positions of a point set: coincident particles (a piece listed twice in a
/// `.pvtu`, parts repeated in a `.pvd`, an inflow that stacks particles) see the same
/// neighbours, so neighbourhood work runs once per position, weighted by how many share it,
/// and stays linear however many copies there are.
#[derive(Debug, Clone, PartialEq)]
pub struct Distinct {
    /// Each distinct position once (world space), in order of first appearance.
    pub points: Vec<[f32; 3]>,
    /// How many of the input points lie at `points[k]`.
    pub weights: Vec<u32>,
    /// For every input point, the index of its position in `points`.
    pub of: Vec<u32>,
}

impl Distinct {
    /// The distinct positions of `positions` (bit-equal after turning -0 into 0; NaN
    /// coordinates compare by their bits).
    pub fn of(positions: &[[f32; 3]]) -> Distinct {
        let key = |i: u32| positions[i as usize].map(|v| (v + 0.0).to_bits());
        let mut order: Vec<u32> = (0..positions.len() as u32).collect();
        // Stable: equal keys stay in input order, so each group's first index comes first.
        order.par_sort_by_key(|&i| key(i));
        let mut of = vec![0u32; positions.len()];
        let mut firsts: Vec<u32> = Vec::new();
        let mut weights_sorted: Vec<u32> = Vec::new();
        for (k, &i) in order.iter().enumerate() {
            if k == 0 || key(i) != key(order[k - 1]) {
                firsts.push(i);
                weights_sorted.push(1);
            } else if let Some(w) = weights_sorted.last_mut() {
                *w += 1;
            }
            of[i as usize] = firsts.len() as u32 - 1;
        }
        // Renumber the groups in order of first appearance.
        let mut by_first: Vec<u32> = (0..firsts.len() as u32).collect();
        by_first.sort_unstable_by_key(|&g| firsts[g as usize]);
        let mut rank = vec![0u32; firsts.len()];
        for (r, &g) in by_first.iter().enumerate() {
            rank[g as usize] = r as u32;
        }
        for o in &mut of {
            *o = rank[*o as usize];
        }
        Distinct {
            points: by_first
                .iter()
                .map(|&g| positions[firsts[g as usize] as usize])
                .collect(),
            weights: by_first
                .iter()
                .map(|&g| weights_sorted[g as usize])
                .collect(),
            of,
        }
    }

    /// Whether every position is distinct.
    pub fn all_distinct(&self) -> bool {
        self.points.len() == self.of.len()
    }
}

#[cfg(test)]
mod distinct_tests {
    use super::*;

    #[test]
    fn groups_bit_equal_positions_in_order_of_first_appearance() {
        let p = [
            [1.0, 2.0, 3.0],
            [0.0, 0.0, 0.0],
            [1.0, 2.0, 3.0],
            [-0.0, 0.0, 0.0],
            [1.0, 2.0, 3.000001],
        ];
        let d = Distinct::of(&p);
        assert_eq!(
            d.points,
            vec![[1.0, 2.0, 3.0], [0.0, 0.0, 0.0], [1.0, 2.0, 3.000001]]
        );
        assert_eq!(d.weights, vec![2, 2, 1]);
        assert_eq!(d.of, vec![0, 1, 0, 1, 2]);
        assert!(!d.all_distinct());
        assert!(Distinct::of(&p[3..]).all_distinct());
    }
}
