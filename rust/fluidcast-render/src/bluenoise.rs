//! Blue-noise offsets for jittered ray marching (Morrical et al. 2023, Sec. 3.3.3, after
//! Wolfe et al. 2022, "Spatiotemporal Blue Noise Masks").
//!
//! A 64×64 blue-noise mask, made once by Ulichney's void-and-cluster method (no file to ship),
//! gives each pixel its offset; pass k adds k times the golden ratio's fraction (mod 1), so
//! that each pixel's offsets over passes are a low-discrepancy sequence while each pass's
//! offsets stay blue over the screen. This is the common approximation of a spatiotemporal
//! mask (Wolfe et al. optimise every slice jointly); it keeps the property the paper relies
//! on: a single pass's noise has no low frequencies, and passes average out faster than
//! independent white noise.

use std::sync::OnceLock;

/// Side of the mask in pixels.
pub const MASK_SIDE: usize = 64;
const N: usize = MASK_SIDE * MASK_SIDE;
/// Standard deviation of the energy filter (pixels), Ulichney's 1.5.
const SIGMA: f64 = 1.5;
/// 1/φ, the golden ratio's fraction: the temporal step of each pixel's offset.
pub const GOLDEN: f64 = 0.618_033_988_749_894_9;

/// The mask's ranks as values in [0, 1): `(rank + ½)/4096`, row-major, one per pixel.
pub fn mask() -> &'static [f32] {
    static MASK: OnceLock<Vec<f32>> = OnceLock::new();
    MASK.get_or_init(void_and_cluster)
}

/// The offset in [0, 1) of pixel (i, j) in pass `pass`, for the random stream `stream`
/// (streams read the mask at toroidal shifts of each other).
#[inline]
pub fn blue_offset(i: u32, j: u32, pass: u32, stream: u32) -> f64 {
    let h = crate::rbf::mix32(stream);
    let (sx, sy) = (h as usize % MASK_SIDE, (h >> 16) as usize % MASK_SIDE);
    let (x, y) = ((i as usize + sx) % MASK_SIDE, (j as usize + sy) % MASK_SIDE);
    let v = f64::from(mask()[y * MASK_SIDE + x]) + f64::from(pass) * GOLDEN;
    v - v.floor()
}

/// Energy of a point at toroidal offset (dx, dy): a Gaussian of [`SIGMA`].
fn kernel() -> Vec<f64> {
    let wrap = |d: usize| d.min(MASK_SIDE - d) as f64;
    (0..N)
        .map(|k| {
            let (dx, dy) = (wrap(k % MASK_SIDE), wrap(k / MASK_SIDE));
            (-(dx * dx + dy * dy) / (2.0 * SIGMA * SIGMA)).exp()
        })
        .collect()
}

/// A set of pixels and the energy every pixel receives from it.
struct Pattern {
    on: Vec<bool>,
    energy: Vec<f64>,
    lut: Vec<f64>,
}

impl Pattern {
    fn toggle(&mut self, p: usize, on: bool) {
        self.on[p] = on;
        let sign = if on { 1.0 } else { -1.0 };
        let (px, py) = (p % MASK_SIDE, p / MASK_SIDE);
        for (q, e) in self.energy.iter_mut().enumerate() {
            let dx = (q % MASK_SIDE + MASK_SIDE - px) % MASK_SIDE;
            let dy = (q / MASK_SIDE + MASK_SIDE - py) % MASK_SIDE;
            *e += sign * self.lut[dy * MASK_SIDE + dx];
        }
    }

    /// The set pixel with the most energy (the tightest cluster), or the unset one with the
    /// least (the largest void); the first of equals.
    fn extreme(&self, on: bool) -> usize {
        let mut best: Option<usize> = None;
        for q in (0..N).filter(|&q| self.on[q] == on) {
            let better = match best {
                None => true,
                Some(b) if on => self.energy[q] > self.energy[b],
                Some(b) => self.energy[q] < self.energy[b],
            };
            if better {
                best = Some(q);
            }
        }
        best.unwrap_or(0)
    }
}

/// Ulichney's void-and-cluster: a relaxed initial pattern of a tenth of the pixels, ranked
/// by removing its tightest clusters, then every other pixel ranked by filling the largest
/// void.
fn void_and_cluster() -> Vec<f32> {
    let mut p = Pattern {
        on: vec![false; N],
        energy: vec![0.0; N],
        lut: kernel(),
    };
    // Initial points from a fixed hash, then relaxed: move the tightest cluster's point
    // to the largest void until that puts it back.
    let mut count = 0;
    let mut k = 0u32;
    while count < N / 10 {
        let q = crate::rbf::mix32(k.wrapping_mul(0x9e37_79b9)) as usize % N;
        k += 1;
        if !p.on[q] {
            p.toggle(q, true);
            count += 1;
        }
    }
    for _ in 0..N {
        let c = p.extreme(true);
        p.toggle(c, false);
        let v = p.extreme(false);
        p.toggle(v, true);
        if v == c {
            break;
        }
    }
    let initial = p.on.clone();
    let energy = p.energy.clone();
    let mut rank = vec![0usize; N];
    // Phase 1: ranks count-1 down to 0, removing the tightest cluster.
    for r in (0..count).rev() {
        let c = p.extreme(true);
        p.toggle(c, false);
        rank[c] = r;
    }
    // Phase 2: from the initial pattern, ranks count.. by filling the largest void.
    p.on = initial;
    p.energy = energy;
    for r in count..N {
        let v = p.extreme(false);
        p.toggle(v, true);
        rank[v] = r;
    }
    rank.into_iter()
        .map(|r| ((r as f64 + 0.5) / N as f64) as f32)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mask_ranks_every_pixel_once_and_has_no_low_frequencies() {
        let m = mask();
        let mut ranks: Vec<usize> = m.iter().map(|&v| (v as f64 * N as f64) as usize).collect();
        ranks.sort_unstable();
        assert!(
            ranks.iter().enumerate().all(|(k, &r)| k == r),
            "a permutation"
        );
        // Means of 4×4 blocks: 16 independent uniforms vary with variance 1/192; blue
        // noise, whose energy is at high frequencies, far less.
        let mut var = 0.0;
        for by in 0..MASK_SIDE / 4 {
            for bx in 0..MASK_SIDE / 4 {
                let mean: f64 = (0..16)
                    .map(|k| {
                        let (x, y) = (bx * 4 + k % 4, by * 4 + k / 4);
                        f64::from(m[y * MASK_SIDE + x])
                    })
                    .sum::<f64>()
                    / 16.0;
                var += (mean - 0.5).powi(2);
            }
        }
        let var = var / (MASK_SIDE * MASK_SIDE / 16) as f64;
        assert!(
            var < 0.25 / 192.0,
            "block variance {var} vs white noise's {}",
            1.0 / 192.0
        );
        // Each pixel's offsets over passes are spread over [0, 1): any 8 consecutive passes
        // leave no gap wider than 1/4.
        for pass in 0..20 {
            let mut v: Vec<f64> = (pass..pass + 8).map(|k| blue_offset(5, 9, k, 3)).collect();
            v.sort_by(f64::total_cmp);
            let gaps = v.windows(2).map(|w| w[1] - w[0]).chain([1.0 - v[7] + v[0]]);
            assert!(gaps.fold(0.0, f64::max) < 0.25);
        }
    }
}
