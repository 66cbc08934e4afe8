//! Building the hierarchy bottom-up (Fraedrich et al. 2010, Sec. 4.1).

use crate::{Level, LodError, LodHierarchy};
use fluidcast_sph::Particles;
use rayon::prelude::*;

/// Most levels above level 0: a Morton key holds 21 bits per axis.
pub const MAX_LEVELS: usize = 21;

/// Cells per axis a Morton key can tell apart.
const CELLS_PER_AXIS: f64 = (1u64 << MAX_LEVELS) as f64;

impl LodHierarchy {
    /// Builds the hierarchy of `particles` (taken: level 0 is them, sorted along a Morton
    /// curve). Positions, volumes, radii, masses and values must be finite.
    pub fn build(particles: Particles) -> Result<LodHierarchy, LodError> {
        if particles.is_empty() {
            return Err(LodError::Empty);
        }
        check_finite(&particles)?;
        let (lo, base_cell, extent) = base_grid(&particles);
        let mut keys = morton_keys(&particles, lo, base_cell);
        let order = sorted_order(&keys);
        keys = order.iter().map(|&i| keys[i]).collect();
        let level0 = particles.select(&order);
        drop(particles);
        let mut levels = vec![Level::full_detail(level0)];
        let mut cells = vec![base_cell];
        for k in 1..=MAX_LEVELS {
            let cell = base_cell * f64::powi(2.0, k as i32);
            let (next, next_keys) = merge_level(&mut levels, &mut keys, 3 * k as u32, cell);
            // A level that merged nothing is the one below again: not kept, but the next,
            // larger cells may still merge.
            if !next.particles.is_empty() {
                levels.push(next);
                cells.push(cell);
                keys = next_keys;
            }
            if keys.len() == 1 || cell > extent {
                break;
            }
        }
        Ok(LodHierarchy { levels, cells })
    }
}

fn check_finite(p: &Particles) -> Result<(), LodError> {
    let bad = |index: usize, what: &'static str, v: f32| LodError::NotFinite {
        index,
        what,
        value: f64::from(v),
    };
    for (i, x) in p.positions.iter().enumerate() {
        if let Some(c) = x.iter().find(|c| !c.is_finite()) {
            return Err(bad(i, "position", *c));
        }
    }
    for (what, a) in [
        ("volume", &p.volumes),
        ("support radius", &p.radii),
        ("mass", &p.masses),
        ("value", &p.values),
    ] {
        if let Some((i, v)) = a.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(bad(i, what, *v));
        }
    }
    Ok(())
}

/// A particle's size: the edge of a cube of its volume (world units); half its support
/// radius where the volume is not positive.
fn size_of(volume: f32, radius: f32) -> f64 {
    if volume > 0.0 {
        f64::from(volume).cbrt()
    } else {
        0.5 * f64::from(radius)
    }
}

/// Level 0's grid: the lower corner of the particles' bounds and the cell edge, the median
/// particle size (the simulation's resolution), widened where the bounds would need more
/// cells than a key holds (far outliers); and the bounds' largest extent.
fn base_grid(p: &Particles) -> ([f64; 3], f64, f64) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for x in &p.positions {
        for k in 0..3 {
            lo[k] = lo[k].min(f64::from(x[k]));
            hi[k] = hi[k].max(f64::from(x[k]));
        }
    }
    let mut sizes: Vec<f64> = p
        .volumes
        .iter()
        .zip(&p.radii)
        .map(|(&v, &h)| size_of(v, h))
        .collect();
    let mid = sizes.len() / 2;
    let median = *sizes.select_nth_unstable_by(mid, f64::total_cmp).1;
    let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
    let cell = median.max(extent / (CELLS_PER_AXIS - 1.0));
    // All particles at one point with no size: any positive cell holds them.
    (lo, if cell > 0.0 { cell } else { 1.0 }, extent)
}

/// Each particle's level-0 cell as a Morton key (x, y, z bits interleaved).
fn morton_keys(p: &Particles, lo: [f64; 3], cell: f64) -> Vec<u64> {
    let max = (1u64 << MAX_LEVELS) - 1;
    p.positions
        .par_iter()
        .map(|x| {
            let c = [0, 1, 2].map(|k| {
                let i = ((f64::from(x[k]) - lo[k]) / cell).floor();
                (i.max(0.0) as u64).min(max)
            });
            spread(c[0]) | spread(c[1]) << 1 | spread(c[2]) << 2
        })
        .collect()
}

/// The low 21 bits of `v`, two zero bits after each.
fn spread(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | x << 32) & 0x1f_0000_0000_ffff;
    x = (x | x << 16) & 0x1f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

/// Indices in ascending key order (ties in input order).
fn sorted_order(keys: &[u64]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..keys.len()).collect();
    order.par_sort_by_key(|&i| keys[i]);
    order
}

/// The level above the top of `levels` (its nodes' `keys`: level-0 Morton keys, sorted by
/// runs of `key >> shift`, one run per cell of the new level, `cell` wide). Within each run
/// the nodes smaller than `cell` are moved to the front (reordering the top level) and, where
/// the run's cell is interior, merged into one node; every other node is carried up. Returns
/// the new level (its own particles empty when nothing merged) and its nodes' keys.
fn merge_level(
    levels: &mut [Level],
    keys: &mut Vec<u64>,
    shift: u32,
    cell: f64,
) -> (Level, Vec<u64>) {
    let top = levels.len() - 1;
    let small: Vec<bool> = (0..keys.len())
        .map(|i| {
            let d = node_data(levels, top, i);
            size_of(d.volume, d.radius) < cell
        })
        .collect();
    let runs = runs_of(keys, shift);
    // Small nodes first within each run; stable, so the order stays Morton order.
    let mut order: Vec<usize> = Vec::with_capacity(keys.len());
    for &(a, b) in &runs {
        order.extend((a..b).filter(|&i| small[i]));
        order.extend((a..b).filter(|&i| !small[i]));
    }
    levels[top].reorder(&order);
    *keys = order.iter().map(|&i| keys[i]).collect();
    let small: Vec<bool> = order.iter().map(|&i| small[i]).collect();
    let occupied: Vec<u64> = runs.iter().map(|&(a, _)| keys[a] >> shift).collect();
    let mut next = Level::default();
    let mut next_keys = Vec::with_capacity(runs.len());
    for (a, b) in runs {
        let n_small = if interior(&occupied, keys[a] >> shift) {
            (a..b).take_while(|&i| small[i]).count()
        } else {
            0
        };
        let carried = if n_small >= 2 {
            let children: Vec<LodNode> = (a..a + n_small)
                .map(|i| node_data(levels, top, i))
                .collect();
            next.push_merged(merge(&children), a..a + n_small, top + 1);
            next_keys.push(keys[a]);
            a + n_small..b
        } else {
            a..b
        };
        for i in carried {
            next.push_carried(levels[top].origin(top, i), i);
            next_keys.push(keys[i]);
        }
    }
    (next, next_keys)
}

/// Node `i` of `level`'s particle.
pub(crate) fn node_data(levels: &[Level], level: usize, i: usize) -> LodNode {
    let (l, j) = levels[level].origin(level, i);
    let p = &levels[l].particles;
    LodNode {
        position: p.positions[j],
        radius: p.radii[j],
        volume: p.volumes[j],
        mass: p.masses[j],
        value: p.values[j],
    }
}

/// The cell `key` (a Morton key of cells at one level) has all six face neighbours among
/// `occupied` (sorted keys of the level's non-empty cells): it is not at the boundary of the
/// particles, where a merge would move the edge of the field.
fn interior(occupied: &[u64], key: u64) -> bool {
    let c = [0, 1, 2].map(|k| compact(key >> k));
    let max = (1u64 << MAX_LEVELS) - 1;
    (0..3).all(|axis| {
        [-1i64, 1].iter().all(|&d| {
            let mut n = c;
            let v = n[axis] as i64 + d;
            if v < 0 || v as u64 > max {
                return false;
            }
            n[axis] = v as u64;
            let nk = spread(n[0]) | spread(n[1]) << 1 | spread(n[2]) << 2;
            occupied.binary_search(&nk).is_ok()
        })
    })
}

/// The inverse of [`spread`]: every third bit of `v`, packed.
fn compact(v: u64) -> u64 {
    let mut x = v & 0x1249_2492_4924_9249;
    x = (x | x >> 2) & 0x10c3_0c30_c30c_30c3;
    x = (x | x >> 4) & 0x100f_00f0_0f00_f00f;
    x = (x | x >> 8) & 0x1f_0000_ff00_00ff;
    x = (x | x >> 16) & 0x1f_0000_0000_ffff;
    x = (x | x >> 32) & 0x1f_ffff;
    x
}

/// Runs `[a, b)` of equal `key >> shift`.
fn runs_of(keys: &[u64], shift: u32) -> Vec<(usize, usize)> {
    let mut runs = Vec::new();
    let mut a = 0;
    for i in 1..=keys.len() {
        if i == keys.len() || keys[i] >> shift != keys[a] >> shift {
            runs.push((a, i));
            a = i;
        }
    }
    runs
}

/// One node's particle: world-space position, support radius, volume, mass and value (the
/// units of [`Particles`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LodNode {
    /// World-space centre.
    pub position: [f32; 3],
    /// Support radius (world units).
    pub radius: f32,
    /// Volume (world units³).
    pub volume: f32,
    /// Mass.
    pub mass: f32,
    /// The rendered attribute (volume-weighted mean of the merged particles).
    pub value: f32,
}

/// Merges `children` (see the crate's rules).
pub(crate) fn merge(children: &[LodNode]) -> LodNode {
    let (mut v, mut m, mut va) = (0.0f64, 0.0f64, 0.0f64);
    let mut vx = glam::DVec3::ZERO;
    let mut sum_x = glam::DVec3::ZERO;
    let mut sum_a = 0.0f64;
    for c in children {
        let vi = f64::from(c.volume);
        let xi = glam::Vec3::from(c.position).as_dvec3();
        let ai = f64::from(c.value);
        v += vi;
        m += f64::from(c.mass);
        va += vi * ai;
        vx += vi * xi;
        sum_x += xi;
        sum_a += ai;
    }
    let n = children.len().max(1) as f64;
    // No volume to weigh by: plain means.
    let (x, a) = if v > 0.0 {
        (vx / v, va / v)
    } else {
        (sum_x / n, sum_a / n)
    };
    // The centre as stored (f32), so that the radius covers the children from there.
    let x = x.as_vec3();
    let centre = x.as_dvec3();
    let cover = children
        .iter()
        .map(|c| glam::Vec3::from(c.position).as_dvec3().distance(centre) + f64::from(c.radius))
        .fold(0.0, f64::max);
    let mut radius = cover as f32;
    while f64::from(radius) < cover {
        radius = f32::from_bits(radius.to_bits() + 1);
    }
    LodNode {
        position: x.to_array(),
        radius,
        volume: v as f32,
        mass: m as f32,
        value: a as f32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_bits_interleave_and_come_back() {
        let mut x = 0x2545_f491u64;
        for _ in 0..1000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let v = x & 0x1f_ffff;
            let s = spread(v);
            for b in 0..21 {
                assert_eq!((s >> (3 * b)) & 1, (v >> b) & 1, "bit {b} of {v:#x}");
            }
            assert_eq!(s & !0x1249_2492_4924_9249, 0);
            assert_eq!(compact(s), v);
        }
    }
}
