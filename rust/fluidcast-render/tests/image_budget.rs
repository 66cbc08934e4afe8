//! `validate` checks the image's memory (`IMAGE_BYTES_PER_PIXEL` per pixel) against the
//! budget before anything is allocated: a budget one byte short of a 300×200 image's is an
//! error that names the render, the exact budget is not. Its own test binary: it sets
//! FLUIDCAST_MEMORY_LIMIT, which every check in the process reads.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly

use fluidcast_render::{validate, RenderParams, IMAGE_BYTES_PER_PIXEL};

#[test]
fn the_image_must_fit_the_memory_budget() {
    let (w, h) = (300u32, 200u32);
    let prm = RenderParams {
        width: w,
        height: h,
        ..Default::default()
    };
    let needed = u64::from(w * h) * IMAGE_BYTES_PER_PIXEL;
    std::env::set_var("FLUIDCAST_MEMORY_LIMIT", (needed - 1).to_string());
    let e = validate(&prm)
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    // 3,840,000 bytes.
    assert!(e.contains("a 300x200 render needs 3.7 MiB"), "got '{e}'");
    std::env::set_var("FLUIDCAST_MEMORY_LIMIT", needed.to_string());
    assert!(validate(&prm).is_ok());
}
