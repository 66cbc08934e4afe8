//! Hilbert curve keys for sorting particles into spatially coherent clusters (Morrical et al.
//! 2023, Sec. 3.2.3: "reorder particles along a Hilbert space filling curve").

/// Bits per axis of [`hilbert_key`] (three axes fit a `u64`).
pub const HILBERT_BITS: u32 = 21;

/// The position of lattice point `x` (each coordinate below `2^bits`, `1 <= bits <=
/// HILBERT_BITS`) along the 3D Hilbert curve through the `2^bits`-cube: consecutive keys are
/// lattice neighbours. Skilling's transpose algorithm ("Programming the Hilbert curve", AIP
/// Conf. Proc. 707, 2004): axes to transpose, then the transpose's bits interleaved.
pub fn hilbert_key(x: [u32; 3], bits: u32) -> u64 {
    let bits = bits.clamp(1, HILBERT_BITS);
    let mut x = x.map(|c| c & ((1u32 << bits) - 1));
    let m = 1u32 << (bits - 1);
    // Inverse undo of the excess work.
    let mut q = m;
    while q > 1 {
        let p = q - 1;
        for i in 0..3 {
            if x[i] & q != 0 {
                x[0] ^= p;
            } else {
                let t = (x[0] ^ x[i]) & p;
                x[0] ^= t;
                x[i] ^= t;
            }
        }
        q >>= 1;
    }
    // Gray encode.
    x[1] ^= x[0];
    x[2] ^= x[1];
    let mut t = 0;
    let mut q = m;
    while q > 1 {
        if x[2] & q != 0 {
            t ^= q - 1;
        }
        q >>= 1;
    }
    for c in &mut x {
        *c ^= t;
    }
    // Interleave: the most significant bit of x[0], of x[1], of x[2], then the next bits.
    let mut key = 0u64;
    for b in (0..bits).rev() {
        for c in x {
            key = (key << 1) | u64::from((c >> b) & 1);
        }
    }
    key
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_walk_the_lattice_one_step_at_a_time() {
        for bits in 1..=4u32 {
            let n = 1u32 << bits;
            let mut cells: Vec<(u64, [u32; 3])> = (0..n * n * n)
                .map(|i| {
                    let x = [i % n, i / n % n, i / (n * n)];
                    (hilbert_key(x, bits), x)
                })
                .collect();
            cells.sort();
            // A bijection onto 0..n³ ...
            for (k, c) in cells.iter().enumerate() {
                assert_eq!(c.0, k as u64, "bits {bits}");
            }
            // ... whose consecutive cells are face neighbours.
            for w in cells.windows(2) {
                let d: u32 = (0..3).map(|a| w[0].1[a].abs_diff(w[1].1[a])).sum();
                assert_eq!(d, 1, "bits {bits}: {:?} -> {:?}", w[0], w[1]);
            }
        }
    }
}
