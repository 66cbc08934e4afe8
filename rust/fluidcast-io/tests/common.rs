#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
#![allow(dead_code)]
use std::path::PathBuf;

/// `tests/fixtures/` at the repository root (written by `tests/make_fixtures.py` with VTK).
pub fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/fixtures")
        .join(name)
}

/// `../shared/data/` beside the repository (see `fluidcast_testkit::shared_data`).
pub fn shared(rel: &str) -> Option<PathBuf> {
    fluidcast_testkit::shared_data(rel)
}
