//! Interval arithmetic on (irradiance, transparency) for the error analysis (Sec. 4).

/// Bounds on a composited segment of a ray: channels 0–2 are premultiplied irradiance
/// I (red, green, blue) and channel 3 is transparency T. Every ray of a bundle, and both the
/// full-rate and the adaptive rendering, lie inside `[lo, hi]` per channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bound {
    /// Lower bounds of premultiplied intensity (r, g, b) and transmittance.
    pub lo: [f64; 4],
    /// Upper bounds of the same.
    pub hi: [f64; 4],
}

impl Bound {
    /// A segment that emits nothing and lets everything through (I = 0, T = 1), exactly.
    pub const EMPTY: Bound = Bound {
        lo: [0.0, 0.0, 0.0, 1.0],
        hi: [0.0, 0.0, 0.0, 1.0],
    };

    /// Every segment's values: premultiplied irradiance and transparency both lie in [0, 1].
    /// The bound of a bundle that was not analysed.
    pub const ANY: Bound = Bound {
        lo: [0.0; 4],
        hi: [1.0; 4],
    };

    /// `self` in front of `back` (Eq. 3/4): I = I_f + T_f·I_b, T = T_f·T_b. All quantities
    /// are non-negative, so lower bounds compose with lower bounds and upper with upper.
    #[inline]
    pub fn over(&self, back: &Bound) -> Bound {
        let (f, b) = (self, back);
        Bound {
            lo: [
                f.lo[0] + f.lo[3] * b.lo[0],
                f.lo[1] + f.lo[3] * b.lo[1],
                f.lo[2] + f.lo[3] * b.lo[2],
                f.lo[3] * b.lo[3],
            ],
            hi: [
                f.hi[0] + f.hi[3] * b.hi[0],
                f.hi[1] + f.hi[3] * b.hi[1],
                f.hi[2] + f.hi[3] * b.hi[2],
                f.hi[3] * b.hi[3],
            ],
        }
    }

    /// w(·): the largest width over the four channels, an upper bound on the difference of
    /// any two colours or alphas (α = 1 − T) inside the bound.
    #[inline]
    pub fn width(&self) -> f64 {
        (0..4).map(|c| self.hi[c] - self.lo[c]).fold(0.0, f64::max)
    }

    /// The midpoint (the super-pixel value of Sec. 5.2).
    pub fn mid(&self) -> [f64; 4] {
        [0, 1, 2, 3].map(|c| 0.5 * (self.lo[c] + self.hi[c]))
    }

    /// True when `v` (I rgb, T) lies inside, with slack `eps`.
    pub fn contains(&self, v: [f64; 4], eps: f64) -> bool {
        (0..4).all(|c| v[c] >= self.lo[c] - eps && v[c] <= self.hi[c] + eps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `contains` (what the tests hold pixels to) is false as soon as one channel leaves its
    /// interval by more than `eps`, on either side.
    #[test]
    fn contains_needs_every_channel_inside() {
        let b = Bound {
            lo: [0.1, 0.2, 0.3, 0.4],
            hi: [0.2, 0.3, 0.4, 0.5],
        };
        assert!(b.contains([0.15, 0.25, 0.35, 0.45], 0.0));
        assert!(b.contains([0.1, 0.3, 0.3, 0.5], 0.0));
        assert!(b.contains([0.09, 0.31, 0.3, 0.5], 0.011));
        for c in 0..4 {
            for v in [b.lo[c] - 0.01, b.hi[c] + 0.01] {
                let mut p = b.mid();
                p[c] = v;
                assert!(!b.contains(p, 0.005), "channel {c} at {v}");
                assert!(b.contains(p, 0.011), "channel {c} at {v} within eps");
            }
        }
    }
}
