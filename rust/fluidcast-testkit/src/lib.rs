//! Deterministic scenes for tests: one random number generator and the random particle
//! cloud that the renderer, grid and GPU tests share, so that their scenes stay the same
//! particle for particle.

use std::path::PathBuf;

use fluidcast_sph::Particles;

/// Set to 1 (the test command does) to turn a missing `../shared/data` file into a test failure
/// instead of a skip.
pub const REQUIRE_DATA_ENV: &str = "FLUIDCAST_REQUIRE_DATA";

/// `../shared/data/REL` beside the repository, or `None` with a SKIP line when it is missing;
/// with `FLUIDCAST_REQUIRE_DATA=1` a missing file panics instead, so that the test command
/// cannot pass without the data.
pub fn shared_data(rel: &str) -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data")
        .join(rel);
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
