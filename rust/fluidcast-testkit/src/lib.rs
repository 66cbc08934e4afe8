//! Deterministic scenes for tests: one random number generator and the random particle
//! cloud that the renderer, grid and GPU tests share, so that their scenes stay the same
//! particle for particle.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "test support only (a dev-dependency): a broken fixture must fail the test loudly"
)]

use std::path::PathBuf;

use fluidcast_sph::Particles;
use fluidcast_view::TransferFunction;

/// Set to 1 (the test command does) to turn a missing `../shared/data` file into a test failure
/// instead of a skip.
pub const REQUIRE_DATA_ENV: &str = "FLUIDCAST_REQUIRE_DATA";

/// The shared data folder when it is not `../shared/data` beside the repository:
/// `scripts/mutants.sh` sets it, since cargo-mutants tests a copy of the tree that has no
/// `../shared` beside it (the tests that read the data would skip, and their mutants seem
/// missed).
pub const SHARED_DATA_ENV: &str = "FLUIDCAST_SHARED_DATA";

/// `../shared/data/REL` beside the repository (or under `$FLUIDCAST_SHARED_DATA`), or `None`
/// with a SKIP line when it is missing; with `FLUIDCAST_REQUIRE_DATA=1` a missing file panics
/// instead, so that the test command cannot pass without the data.
pub fn shared_data(rel: &str) -> Option<PathBuf> {
    let base = std::env::var_os(SHARED_DATA_ENV).map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"),
        PathBuf::from,
    );
    let p = base.join(rel);
    if p.exists() {
        return Some(p);
    }
    if std::env::var(REQUIRE_DATA_ENV).as_deref() == Ok("1") {
        panic!("{REQUIRE_DATA_ENV}=1 but {} is missing", p.display());
    }
    eprintln!("SKIP: {} not present", p.display());
    None
}

/// A xorshift32 generator of values in [0, 1] (seed 0 is treated as 1).
pub fn rng(seed: u32) -> impl FnMut() -> f32 {
    let mut s = seed.max(1);
    move || {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        s as f32 / u32::MAX as f32
    }
}

/// `n` random particles in the unit cube around the origin: support radius
/// `radius.0 + radius.1 · u` (u uniform in [0, 1]), volume 0.001–0.003, mass 1–2, and the
/// smooth attribute x + 2y². Drawn in that order per particle, so a seed fixes the scene.
pub fn cloud(n: usize, seed: u32, radius: (f32, f32)) -> Particles {
    let mut rnd = rng(seed);
    let mut p = Particles::default();
    for _ in 0..n {
        let x = [rnd() - 0.5, rnd() - 0.5, rnd() - 0.5];
        p.positions.push(x);
        p.radii.push(radius.0 + radius.1 * rnd());
        p.volumes.push(0.002 * (0.5 + rnd()));
        p.masses.push(1.0 + rnd());
        p.values.push(x[0] + 2.0 * x[1] * x[1]);
    }
    p
}

/// A jittered `n`³ lattice filling the unit cube around the origin (support radius 2.5
/// spacings, volume and mass one cell) whose value is its z coordinate: seen along z, the
/// field changes along every ray and hardly across a bundle. Under a faint transfer function
/// each depth sample's bound is narrow, so the strict plan coarsens, but a coarse sample
/// stands for values up to a cell's depth away: the level bound must include the coarse
/// sample's bound (a plan without that term adapts the same cells and misses by several E_I).
pub fn depth_ramp(n: usize) -> Particles {
    let mut rnd = rng(99);
    let s = 1.0 / n as f32;
    let mut p = Particles::default();
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                let x = [i, j, k].map(|c| (c as f32 + 0.5) * s - 0.5 + 0.2 * s * (rnd() - 0.5));
                p.positions.push(x);
                p.radii.push(2.5 * s);
                p.volumes.push(s.powi(3));
                p.masses.push(s.powi(3));
                p.values.push(x[2]);
            }
        }
    }
    p
}

/// The transfer function for [`depth_ramp`]: Viridis over its values [−0.5, 0.5] with the
/// constant opacity `alpha` per 0.5 world units (the strict tests use 0.01–0.02).
pub fn depth_ramp_tf(alpha: f64) -> TransferFunction {
    let mut tf = TransferFunction::preset("Viridis")
        .expect("Viridis is a built-in preset")
        .with_range(-0.5, 0.5)
        .expect("a valid range");
    tf.opacity = vec![(0.0, alpha), (1.0, alpha)];
    tf.unit_distance = 0.5;
    tf
}

/// [`depth_ramp`]'s block with its front half (toward +z) at a constant, nearly opaque value
/// and its back half holding a field that varies across every bundle under a faint part of
/// the transfer function (also returned). Seen from +z, most back cells' own strict bounds
/// are wider than an E_I of 0.01, so the paper's level cap (w(C) ≤ E_I) keeps them at full
/// rate, but well under 1 % of the light from behind the front reaches a pixel: a cap that
/// weighs a cell by the transparency in front of it coarsens them.
pub fn behind_a_front() -> (Particles, TransferFunction) {
    let mut p = depth_ramp(20);
    for (x, v) in p.positions.iter().zip(p.values.iter_mut()) {
        *v = if x[2] > 0.0 {
            0.0
        } else {
            0.6 + 0.3 * (12.0 * x[0]).sin() * (12.0 * x[1]).cos()
        };
    }
    let mut tf = TransferFunction::preset("Viridis")
        .expect("Viridis is a built-in preset")
        .with_range(0.0, 1.0)
        .expect("a valid range");
    tf.opacity = vec![(0.0, 0.9), (0.1, 0.9), (0.2, 0.05), (1.0, 0.05)];
    tf.unit_distance = 0.1;
    (p, tf)
}

/// The depth-ramp cases the strict tests run on the CPU and the GPU: (opacity, E_I, azimuth
/// in degrees, parallel projection), each with 64 depth samples per cell.
pub const DEPTH_RAMP_CASES: [(f64, f64, f64, bool); 4] = [
    (0.01, 0.01, 5.0, false),
    (0.01, 0.01, -10.0, false),
    (0.01, 0.01, 5.0, true),
    (0.02, 0.02, 5.0, false),
];

/// Sheets of fluid stacked along z with empty gaps between them: `layers` layers of three
/// particle sheets at `spacing` (support radius 2.5 spacings), filling x, y ∈ [−`half`,
/// `half`], each layer's value its index plus a gentle ramp in z; the gaps are wider than a
/// support, so no particle's depth range spans two layers. Seen along z, cells start in a
/// layer and end in a gap or the reverse: a coarse sample may stand for empty steps, and an
/// empty one for filled steps, so the level bound must include "nothing" there.
pub fn layers(layers: usize, half: f32, spacing: f32) -> Particles {
    let n = (2.0 * half / spacing).round() as i32;
    let h = 2.5 * spacing;
    let pitch = 2.0 * spacing + 2.0 * h + 4.0 * spacing;
    let mut p = Particles::default();
    for l in 0..layers {
        let z0 = (l as f32 - 0.5 * (layers as f32 - 1.0)) * pitch;
        for k in 0..3 {
            let z = z0 + (k as f32 - 1.0) * spacing;
            for i in 0..=n {
                for j in 0..=n {
                    p.positions
                        .push([-half + i as f32 * spacing, -half + j as f32 * spacing, z]);
                    p.radii.push(h);
                    p.volumes.push(spacing.powi(3));
                    p.masses.push(spacing.powi(3));
                    p.values.push(l as f32 + 0.1 * (k as f32 - 1.0));
                }
            }
        }
    }
    p
}
