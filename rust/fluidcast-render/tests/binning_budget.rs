//! The reference renderer checks the memory of its particle–tile bins before it allocates
//! them, and its estimate counts every reference: under a budget just large enough for
//! everything else, the error names exactly the number of (particle, 8×8 tile) pairs whose
//! rectangles overlap, counted here tile by tile. Its own test binary: it sets
//! FLUIDCAST_MEMORY_LIMIT, which every check in the process reads.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly

use fluidcast_grid::{screen_rect, view_particles};
use fluidcast_render::{render_reference, RenderParams};

#[test]
fn binning_estimate_counts_every_particle_tile_pair() {
    let p = fluidcast_testkit::cloud(6000, 21, (0.15, 0.45));
    let mut cam = fluidcast_view::Camera::default();
    cam.reset([-0.9; 3], [0.9; 3]);
    cam.azimuth(25.0);
    let tf = fluidcast_view::TransferFunction::preset("viridis").unwrap();
    let (w, h) = (36u32, 28u32);
    let prm = RenderParams {
        width: w,
        height: h,
        ..Default::default()
    };
    let frame = cam.frame(w, h).unwrap();
    let vp = view_particles(&p, &frame);
    let (near, far) = vp.range.unwrap();
    let tile = 8u32;
    let mut pairs = 0u64;
    for r in vp
        .list
        .iter()
        .filter_map(|q| screen_rect(&frame, q, near, far))
    {
        let [x0, x1, y0, y1] = r;
        for ty in 0..h.div_ceil(tile) {
            for tx in 0..w.div_ceil(tile) {
                let (tx0, ty0) = (tx * tile, ty * tile);
                let overlaps = tx0 < x1 && tx0 + tile > x0 && ty0 < y1 && ty0 + tile > y0;
                pairs += u64::from(overlaps);
            }
        }
    }
    // Every other allocation the renderer checks is far below this budget.
    let budget = 4 * pairs - 1;
    assert!(
        budget > 64 * u64::from(w * h),
        "{pairs} pairs: scene too small"
    );
    std::env::set_var("FLUIDCAST_MEMORY_LIMIT", budget.to_string());
    let e = render_reference(&p, &cam, &tf, &prm)
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    let want = format!("binning {pairs} particle–tile references at {w}x{h}");
    assert!(e.contains(&want), "want '{want}', got '{e}'");
    std::env::set_var("FLUIDCAST_MEMORY_LIMIT", (4 * pairs).to_string());
    assert!(render_reference(&p, &cam, &tf, &prm).is_ok());
}
