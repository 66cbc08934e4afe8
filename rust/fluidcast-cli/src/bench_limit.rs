//! `fluidcast bench --limit`: the machine's kernel-evaluation limit, the rate at which a plain
//! loop evaluates the cubic spline kernel on f32 (distance, square root, the polynomial, a
//! sum), written so that the compiler vectorises it, on one core and on every core. A frame's
//! full-rate work ([`fluidcast_backend::work::estimate`], in kernel evaluations) divided by
//! that rate is the time no ray caster of the same arithmetic beats on this machine; the
//! bench prints each renderer's time as a multiple of it.

use std::time::Instant;

use rayon::prelude::*;

/// Particles in the micro-benchmark's box (SoA, f32), and samples each sums over.
const PARTICLES: usize = 4096;
const SAMPLES_PER_CHUNK: usize = 64;

/// Kernel evaluations per second (the limit): on one thread, and on all of rayon's.
#[derive(Debug, Clone, Copy)]
pub struct Limit {
    pub per_core: f64,
    pub all_cores: f64,
    pub threads: usize,
}

/// Positions on a lattice-like spread in the unit cube (deterministic, no RNG dependency).
fn spread(n: usize, salt: f32) -> [Vec<f32>; 3] {
    let f = |k: usize, a: f32| ((k as f32 * a + salt).sin() * 43758.547).fract().abs();
    [
        (0..n).map(|k| f(k, 12.9898)).collect(),
        (0..n).map(|k| f(k, 78.233)).collect(),
        (0..n).map(|k| f(k, 37.719)).collect(),
    ]
}

/// The cubic spline's shape at q = r / H (1 at 0, 0 from 1 on), branch-free:
/// 2 (1 − q)³₊ − 8 (½ − q)³₊.
#[inline(always)]
fn cubic(q: f32) -> f32 {
    let a = (1.0 - q).max(0.0);
    let b = (0.5 - q).max(0.0);
    2.0 * a * a * a - 8.0 * b * b * b
}

/// The sum over every particle of the kernel at one sample: `PARTICLES` evaluations.
#[inline(never)]
fn sum_at(p: &[Vec<f32>; 3], s: [f32; 3], inv_h: f32) -> f32 {
    let (xs, ys, zs) = (&p[0][..PARTICLES], &p[1][..PARTICLES], &p[2][..PARTICLES]);
    let mut acc = [0f32; 8];
    for ((x, y), z) in xs
        .chunks_exact(8)
        .zip(ys.chunks_exact(8))
        .zip(zs.chunks_exact(8))
    {
        for l in 0..8 {
            let (dx, dy, dz) = (x[l] - s[0], y[l] - s[1], z[l] - s[2]);
            acc[l] += cubic((dx * dx + dy * dy + dz * dz).sqrt() * inv_h);
        }
    }
    acc.iter().sum()
}

/// Evaluations per second of `chunks` chunks of samples, each on its own thread (rayon) or
/// all on this one; the sum is returned so that the work is not optimised away.
fn rate(p: &[Vec<f32>; 3], samples: &[Vec<f32>; 3], chunks: usize, parallel: bool) -> (f64, f32) {
    let chunk = |c: usize| -> f32 {
        (0..SAMPLES_PER_CHUNK)
            .map(|k| {
                let i = (c * SAMPLES_PER_CHUNK + k) % samples[0].len();
                sum_at(p, [samples[0][i], samples[1][i], samples[2][i]], 4.0)
            })
            .sum()
    };
    let t = Instant::now();
    let total: f32 = if parallel {
        (0..chunks).into_par_iter().map(chunk).sum()
    } else {
        (0..chunks).map(chunk).sum()
    };
    let evaluations = (chunks * SAMPLES_PER_CHUNK * PARTICLES) as f64;
    (evaluations / t.elapsed().as_secs_f64().max(1e-9), total)
}

/// Measures the limit: the best of three runs of about 0.2 s each, on one thread and on all.
pub fn measure() -> Limit {
    let p = spread(PARTICLES, 0.0);
    let samples = spread(1024, 0.5);
    let threads = rayon::current_num_threads();
    let mut best = (0f64, 0f64);
    let mut check = 0f32;
    // About 0.2 s at 1 G evaluations/s per core.
    let chunks = 200_000_000 / (SAMPLES_PER_CHUNK * PARTICLES);
    for _ in 0..3 {
        let (one, a) = rate(&p, &samples, chunks, false);
        let (all, b) = rate(&p, &samples, chunks * threads, true);
        best = (best.0.max(one), best.1.max(all));
        check += a + b;
    }
    std::hint::black_box(check);
    Limit {
        per_core: best.0,
        all_cores: best.1,
        threads,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The micro-benchmark's kernel is the cubic spline of fluidcast_sph, up to its
    /// normalisation: the shape at every q, from one formula each (no shared code).
    #[test]
    fn the_benchmark_kernel_is_the_cubic_spline() {
        let k = fluidcast_sph::Kernel::CubicSpline;
        for i in 0..=120 {
            let q = i as f64 / 100.0;
            let want = k.shape(q);
            assert!(
                (f64::from(cubic(q as f32)) - want).abs() < 1e-6,
                "q {q}: {want}"
            );
        }
    }

    /// The sum at a sample counts every particle within the support and no other.
    #[test]
    fn the_sum_covers_every_particle() {
        let mut p = [
            vec![5.0f32; PARTICLES],
            vec![5.0; PARTICLES],
            vec![5.0; PARTICLES],
        ];
        p[0][7] = 0.0; // one particle at the sample, the others beyond the support
        p[1][7] = 0.0;
        p[2][7] = 0.0;
        assert_eq!(sum_at(&p, [0.0; 3], 4.0), 1.0);
        let p = [
            vec![0f32; PARTICLES],
            vec![0.0; PARTICLES],
            vec![0.0; PARTICLES],
        ];
        assert_eq!(sum_at(&p, [0.0; 3], 4.0), PARTICLES as f32);
    }
}
