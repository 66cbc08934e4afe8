//! Exact extremes of a piecewise-linear transfer function over a value interval (the
//! paper's 2D min/max texture of Sec. 4.1, as range-min/max tables over control points).

use fluidcast_view::TransferFunction;

/// Range minimum/maximum over a sequence (sparse table, O(1) queries).
#[derive(Debug, Clone)]
struct RangeTable {
    lo: Vec<Vec<f64>>,
    hi: Vec<Vec<f64>>,
}

impl RangeTable {
    fn new(v: &[f64]) -> RangeTable {
        let mut lo = vec![v.to_vec()];
        let mut hi = vec![v.to_vec()];
        let mut w = 1;
        while 2 * w <= v.len() {
            let (Some(pl), Some(ph)) = (lo.last(), hi.last()) else {
                break;
            };
            let n = v.len() + 1 - 2 * w;
            let nl: Vec<f64> = (0..n).map(|i| pl[i].min(pl[i + w])).collect();
            let nh: Vec<f64> = (0..n).map(|i| ph[i].max(ph[i + w])).collect();
            lo.push(nl);
            hi.push(nh);
            w *= 2;
        }
        RangeTable { lo, hi }
    }

    /// (min, max) over indices `a..b`, or `None` when empty.
    fn query(&self, a: usize, b: usize) -> Option<(f64, f64)> {
        if a >= b {
            return None;
        }
        let k = (usize::BITS - 1 - (b - a).leading_zeros()) as usize;
        let w = 1 << k;
        Some((
            self.lo[k][a].min(self.lo[k][b - w]),
            self.hi[k][a].max(self.hi[k][b - w]),
        ))
    }
}

/// Bounds of colour and opacity over a value interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TfRange {
    /// Lowest colour (r, g, b) over the interval.
    pub rgb_lo: [f64; 3],
    /// Highest colour over the interval.
    pub rgb_hi: [f64; 3],
    /// The lowest opacity per unit distance (before the step correction).
    pub alpha_lo: f64,
    /// The highest opacity per unit distance.
    pub alpha_hi: f64,
}

/// Exact min/max of τ_rgb and τ_α over [q⊥, q⊤] (Sec. 4.1). The functions are linear
/// between control points, so their extremes over an interval are at its ends or at a
/// control point inside it.
#[derive(Debug, Clone)]
pub struct TfBounds {
    tf: TransferFunction,
    colour_x: Vec<f64>,
    colour: [RangeTable; 3],
    opacity_x: Vec<f64>,
    opacity: RangeTable,
}

impl TfBounds {
    /// The range tables of `tf`'s colour and opacity control points.
    pub fn new(tf: &TransferFunction) -> TfBounds {
        let colour_x: Vec<f64> = tf.colors.iter().map(|c| c.0).collect();
        let colour = [0, 1, 2]
            .map(|k| RangeTable::new(&tf.colors.iter().map(|c| c.1[k]).collect::<Vec<_>>()));
        let opacity_x: Vec<f64> = tf.opacity.iter().map(|c| c.0).collect();
        let opacity = RangeTable::new(&tf.opacity.iter().map(|c| c.1).collect::<Vec<_>>());
        TfBounds {
            tf: tf.clone(),
            colour_x,
            colour,
            opacity_x,
            opacity,
        }
    }

    /// The transfer function the tables were made from.
    pub fn transfer_function(&self) -> &TransferFunction {
        &self.tf
    }

    /// Bounds over the data values [q0, q1] (q0 ≤ q1).
    pub fn range(&self, q0: f64, q1: f64) -> TfRange {
        let (t0, t1) = match (self.tf.normalised(q0), self.tf.normalised(q1)) {
            (Some(a), Some(b)) => (a.min(b), a.max(b)),
            _ => (0.0, 1.0),
        };
        let (c0, a0) = self.tf.eval_normalised(t0);
        let (c1, a1) = self.tf.eval_normalised(t1);
        let inside = |xs: &[f64]| {
            (
                xs.partition_point(|&x| x <= t0),
                xs.partition_point(|&x| x < t1),
            )
        };
        let mut r = TfRange {
            rgb_lo: [0, 1, 2].map(|k| c0[k].min(c1[k])),
            rgb_hi: [0, 1, 2].map(|k| c0[k].max(c1[k])),
            alpha_lo: a0.min(a1),
            alpha_hi: a0.max(a1),
        };
        let (a, b) = inside(&self.colour_x);
        for k in 0..3 {
            if let Some((lo, hi)) = self.colour[k].query(a, b) {
                r.rgb_lo[k] = r.rgb_lo[k].min(lo);
                r.rgb_hi[k] = r.rgb_hi[k].max(hi);
            }
        }
        let (a, b) = inside(&self.opacity_x);
        if let Some((lo, hi)) = self.opacity.query(a, b) {
            r.alpha_lo = r.alpha_lo.min(lo);
            r.alpha_hi = r.alpha_hi.max(hi);
        }
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every query of the sparse table equals the min and max counted over the range, for
    /// every range of sequences of 1 to 40 values (the minimum or maximum anywhere in it).
    #[test]
    fn range_table_answers_every_range_exactly() {
        let mut s = 7u32;
        for n in 1..=40usize {
            let v: Vec<f64> = (0..n)
                .map(|_| {
                    s = s.wrapping_mul(1664525).wrapping_add(1013904223);
                    (s >> 8) as f64 / (1u32 << 24) as f64
                })
                .collect();
            let t = RangeTable::new(&v);
            for a in 0..=n {
                assert_eq!(t.query(a, a), None);
                for b in a + 1..=n {
                    let lo = v[a..b].iter().copied().fold(f64::INFINITY, f64::min);
                    let hi = v[a..b].iter().copied().fold(f64::NEG_INFINITY, f64::max);
                    assert_eq!(t.query(a, b), Some((lo, hi)), "n {n}, {a}..{b}");
                }
            }
        }
    }

    #[test]
    fn bounds_contain_dense_samples_and_are_tight_at_points() {
        let mut tf = TransferFunction::preset("Cool to Warm").unwrap();
        tf.opacity = (0..40)
            .map(|i| (i as f64 / 39.0, if i % 2 == 0 { 0.9 } else { 0.05 }))
            .collect();
        let tf = tf.with_range(-2.0, 3.0).unwrap();
        let b = TfBounds::new(&tf);
        let mut s = 1u32;
        for _ in 0..300 {
            s = s.wrapping_mul(1664525).wrapping_add(1013904223);
            let q0 = -3.0 + 7.0 * (s >> 8) as f64 / (1u32 << 24) as f64;
            s = s.wrapping_mul(1664525).wrapping_add(1013904223);
            let q1 = q0 + 0.5 * (s >> 8) as f64 / (1u32 << 24) as f64;
            let r = b.range(q0, q1);
            for i in 0..=200 {
                let q = q0 + (q1 - q0) * i as f64 / 200.0;
                let (c, a) = tf.eval(q);
                for (k, ck) in c.iter().enumerate() {
                    assert!(*ck >= r.rgb_lo[k] - 1e-12 && *ck <= r.rgb_hi[k] + 1e-12);
                }
                assert!(a >= r.alpha_lo - 1e-12 && a <= r.alpha_hi + 1e-12);
            }
            // A single value gives a zero-width bound.
            let p = b.range(q0, q0);
            let (c, a) = tf.eval(q0);
            assert_eq!((p.rgb_lo, p.rgb_hi, p.alpha_lo, p.alpha_hi), (c, c, a, a));
        }
    }
}
