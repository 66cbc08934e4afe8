use rayon::prelude::*;

use crate::{Distinct, Kernel, NeighbourGrid, Particles};

/// Which reconstruction of the particle field to evaluate (Hochstetter et al. 2016, Eq. 1–2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FieldKind {
    /// Shepard/CSPH-normalised attribute `Σ V_j A_j W_j / Σ V_j W_j` (Eq. 2): reproduces a
    /// constant field exactly; undefined (no sample) where no particle reaches.
    #[default]
    Csph,
    /// Plain SPH sum `Σ V_j A_j W_j` (Eq. 1).
    Sph,
    /// Density `Σ m_j W_j`.
    Density,
}

impl FieldKind {
    /// Every field, in the order of their codes on the GPU (`FIELD_*` in WGSL).
    pub const ALL: [FieldKind; 3] = [FieldKind::Csph, FieldKind::Sph, FieldKind::Density];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            FieldKind::Csph => "csph",
            FieldKind::Sph => "sph",
            FieldKind::Density => "density",
        }
    }
}

impl std::str::FromStr for FieldKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "csph" | "shepard" => Ok(FieldKind::Csph),
            "sph" => Ok(FieldKind::Sph),
            "density" => Ok(FieldKind::Density),
            _ => Err(format!(
                "unknown field '{s}' (expected csph, sph or density)"
            )),
        }
    }
}

/// The sums of one field evaluation.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FieldSample {
    /// `Σ V_j A_j W_j`.
    pub weighted: f64,
    /// Shepard sum `Σ V_j W_j`.
    pub shepard: f64,
    /// `Σ m_j W_j`.
    pub density: f64,
    /// Number of particles whose support contains the point.
    pub neighbours: u32,
}

impl FieldSample {
    /// The field value of the given kind; `None` for CSPH where no particle contributes.
    pub fn value(&self, kind: FieldKind) -> Option<f64> {
        match kind {
            FieldKind::Csph => (self.shepard > 0.0).then(|| self.weighted / self.shepard),
            FieldKind::Sph => Some(self.weighted),
            FieldKind::Density => Some(self.density),
        }
    }
}

impl Particles {
    /// A neighbour grid whose cells are as large as the largest support radius.
    pub fn neighbour_grid(&self) -> NeighbourGrid<'_> {
        NeighbourGrid::new(&self.positions, self.max_radius())
    }

    /// Evaluates the field sums at one world-space point (double precision accumulation).
    pub fn sample(&self, grid: &NeighbourGrid, kernel: Kernel, x: [f64; 3]) -> FieldSample {
        let mut s = FieldSample::default();
        let xf = [x[0] as f32, x[1] as f32, x[2] as f32];
        grid.for_each_near(xf, self.max_radius(), |j, _| {
            let j = j as usize;
            let p = self.positions[j];
            let d = [p[0] as f64 - x[0], p[1] as f64 - x[1], p[2] as f64 - x[2]];
            let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let w = kernel.eval(r, self.radii[j] as f64);
            if w > 0.0 {
                let vw = self.volumes[j] as f64 * w;
                s.weighted += vw * self.values[j] as f64;
                s.shepard += vw;
                s.density += self.masses[j] as f64 * w;
                s.neighbours += 1;
            }
        });
        s
    }

    /// Flags surface particles by a neighbourhood deficiency: particle j is a surface
    /// particle when fewer than `threshold` × the median count of particles lie within
    /// H_j/2 of it (itself included). Interior particles see a full ball of neighbours; at a
    /// free surface (or where the data ends, e.g. at walls without boundary particles) about
    /// half of it is empty, so 0.75 flags a layer about one particle spacing thick.
    ///
    /// Memory beside the particles: the neighbour grid while counting, then two bytes a
    /// particle (the counts, saturating at 65,535) and the flags; the median comes from a
    /// histogram of the counts, not a sorted copy. (This runs over all particles before a
    /// memory limit's screen tiles can split the work.)
    ///
    /// Coincident particles are counted through their distinct positions ([`Distinct`]),
    /// each weighted by its copies: the counts are the same, and k copies of a point cost k
    /// queries over its distinct neighbours rather than k² (a `.pvtu` listing one piece
    /// 3000 times took minutes).
    ///
    /// Near-coincident clumps (not bit-equal) are bounded by counting up to a cap: a count
    /// above the cap changes neither the median, while the median and `threshold` × median
    /// stay below the cap, nor any flag. The cap starts at 256 and grows fourfold while the
    /// median reaches it (up to the 65,535 the counts saturate at), so the flags are those of
    /// counting every neighbour.
    pub fn surface_flags(&self, threshold: f64) -> Vec<bool> {
        let distinct = Distinct::of(&self.positions);
        let grid = NeighbourGrid::new(&distinct.points, 0.5 * self.max_radius());
        let saturated = u64::from(u16::MAX);
        let mut cap = 256u64;
        loop {
            let counts: Vec<u16> = (0..self.len())
                .into_par_iter()
                .map(|j| {
                    let (x, r) = (self.positions[j], 0.5 * self.radii[j]);
                    grid.weight_near(x, r, &distinct.weights, cap) as u16
                })
                .collect();
            let median = f64::from(median_count(&counts));
            let cut = threshold * median;
            if cap >= saturated || (median < cap as f64 && cut < cap as f64) {
                return counts.iter().map(|&c| f64::from(c) < cut).collect();
            }
            cap = (cap * 4).min(saturated);
        }
    }

    /// Evaluates the field at many points in parallel.
    pub fn sample_many(&self, kernel: Kernel, points: &[[f64; 3]]) -> Vec<FieldSample> {
        let grid = self.neighbour_grid();
        points
            .par_iter()
            .map(|&x| self.sample(&grid, kernel, x))
            .collect()
    }
}

/// The middle element of `counts` sorted (index len/2), from a histogram; 0 when empty.
fn median_count(counts: &[u16]) -> u16 {
    let mut hist = vec![0usize; usize::from(u16::MAX) + 1];
    for &c in counts {
        hist[usize::from(c)] += 1;
    }
    let mut below = 0;
    for (v, &k) in hist.iter().enumerate() {
        below += k;
        if below > counts.len() / 2 {
            return v as u16;
        }
    }
    0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_count_is_the_sorted_middle() {
        let mut x = 7u32;
        for n in [0usize, 1, 2, 3, 10, 1001] {
            let c: Vec<u16> = (0..n)
                .map(|_| {
                    x ^= x << 13;
                    x ^= x >> 17;
                    x ^= x << 5;
                    (x % 300) as u16
                })
                .collect();
            let mut sorted = c.clone();
            sorted.sort_unstable();
            assert_eq!(
                median_count(&c),
                sorted.get(n / 2).copied().unwrap_or(0),
                "{n}"
            );
        }
    }

    fn jittered(n: usize, value: impl Fn([f32; 3]) -> f32) -> Particles {
        // Irregular particles: a lattice with deterministic jitter and varying volumes/radii.
        let mut p = Particles::default();
        let mut s = 12345u32;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            (s as f32 / u32::MAX as f32) - 0.5
        };
        for i in 0..n {
            for j in 0..n {
                for k in 0..n {
                    let x = [
                        i as f32 * 0.1 + 0.03 * rnd(),
                        j as f32 * 0.1 + 0.03 * rnd(),
                        k as f32 * 0.1 + 0.03 * rnd(),
                    ];
                    p.positions.push(x);
                    p.radii.push(0.2 + 0.05 * rnd());
                    p.volumes.push(0.001 * (1.0 + rnd()));
                    p.masses.push(1.0);
                    p.values.push(value(x));
                }
            }
        }
        p
    }

    /// Surface flags by brute force: every pair, no grid, no grouping of copies.
    fn brute_surface_flags(p: &Particles, threshold: f64) -> Vec<bool> {
        let counts: Vec<u16> = (0..p.len())
            .map(|j| {
                let r = 0.5 * p.radii[j];
                let n = (0..p.len())
                    .filter(|&k| {
                        let d: f32 = (0..3)
                            .map(|c| (p.positions[k][c] - p.positions[j][c]).powi(2))
                            .sum();
                        d < r * r
                    })
                    .count();
                n.min(usize::from(u16::MAX)) as u16
            })
            .collect();
        let mut sorted = counts.clone();
        sorted.sort_unstable();
        let median = f64::from(sorted[sorted.len() / 2]);
        counts
            .iter()
            .map(|&c| f64::from(c) < threshold * median)
            .collect()
    }

    #[test]
    fn surface_flags_count_every_copy_of_coincident_particles() {
        // Some particles stacked 2..=9 times (as a .pvtu listing a piece twice, or an
        // inflow): the flags must be those of counting every particle, copies included.
        let mut p = jittered(6, |_| 1.0);
        let n = p.len();
        for j in (0..n).step_by(5) {
            for _ in 0..(j % 8 + 1) {
                p.positions.push(p.positions[j]);
                p.radii.push(p.radii[j]);
                p.volumes.push(p.volumes[j]);
                p.masses.push(p.masses[j]);
                p.values.push(p.values[j]);
            }
        }
        let flags = p.surface_flags(0.75);
        assert_eq!(flags, brute_surface_flags(&p, 0.75));
        // The copies moved the flags: the test would see copies counted once.
        let single = jittered(6, |_| 1.0);
        assert_ne!(flags[..n], single.surface_flags(0.75)[..]);
    }

    #[test]
    fn surface_flags_of_clumps_and_dense_neighbourhoods_are_exact() {
        // A clump of 600 near-coincident particles (not bit-equal: no grouping helps) inside
        // a lattice: their counts are capped, and the flags are still the brute force's.
        let mut p = jittered(6, |_| 1.0);
        let mut s = 7u32;
        for _ in 0..600 {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let d = (s >> 8) as f32 / (1u32 << 24) as f32 * 1e-5;
            p.positions.push([0.25 + d, 0.25, 0.25 - d]);
            p.radii.push(0.2);
            p.volumes.push(0.001);
            p.masses.push(1.0);
            p.values.push(1.0);
        }
        assert_eq!(p.surface_flags(0.75), brute_surface_flags(&p, 0.75));
        // Supports so wide that the median count passes the first cap (256): it must grow.
        let mut wide = jittered(8, |_| 1.0);
        wide.radii.iter_mut().for_each(|r| *r = 1.1);
        let brute = brute_surface_flags(&wide, 0.75);
        let flagged = brute.iter().filter(|&&f| f).count();
        assert!(flagged > 0 && flagged < wide.len(), "{flagged}");
        assert_eq!(wide.surface_flags(0.75), brute);
    }

    #[test]
    fn csph_reproduces_a_constant_exactly() {
        let p = jittered(8, |_| 3.25);
        let pts: Vec<[f64; 3]> = (0..500)
            .map(|i| {
                [
                    0.1 + (i % 10) as f64 * 0.06,
                    0.1 + (i / 10 % 10) as f64 * 0.06,
                    0.05 * (i / 100) as f64,
                ]
            })
            .collect();
        for k in Kernel::ALL {
            for s in p.sample_many(k, &pts) {
                let v = s.value(FieldKind::Csph).unwrap();
                assert!((v - 3.25).abs() <= 1e-12 * 3.25, "{k}: {v}");
            }
        }
    }

    #[test]
    fn grid_query_equals_brute_force() {
        let p = jittered(6, |x| x[0] + 2.0 * x[1]);
        let grid = p.neighbour_grid();
        for i in 0..50 {
            let x = [0.05 * i as f64 % 0.5, 0.3, 0.011 * i as f64];
            let s = p.sample(&grid, Kernel::WendlandC2, x);
            let mut w = 0.0;
            for j in 0..p.len() {
                let q = p.positions[j];
                let r = ((q[0] as f64 - x[0]).powi(2)
                    + (q[1] as f64 - x[1]).powi(2)
                    + (q[2] as f64 - x[2]).powi(2))
                .sqrt();
                w += p.volumes[j] as f64
                    * p.values[j] as f64
                    * Kernel::WendlandC2.eval(r, p.radii[j] as f64);
            }
            assert!(
                (s.weighted - w).abs() <= 1e-12 + 1e-9 * w.abs(),
                "{} vs {w}",
                s.weighted
            );
        }
    }
}
