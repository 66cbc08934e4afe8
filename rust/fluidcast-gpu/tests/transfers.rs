//! What a frame moves between host and device: particles uploaded only when they change, the
//! image read back in half precision and without depth when the caller asks for less
//! (`RenderParams::output`), and the counts `RenderStats::transfers` reports.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;

use common::{cloud, cloud_tf, gpu, orbit};
use fluidcast_gpu::Gpu;
use fluidcast_render::{ImageOutput, PlanParams, RenderParams, Rendered};
use fluidcast_sph::Particles;

const W: u32 = 96;
const H: u32 = 72;

fn params(output: ImageOutput, tolerance: Option<f64>) -> RenderParams {
    RenderParams {
        width: W,
        height: H,
        adaptive: PlanParams {
            tolerance,
            ..Default::default()
        },
        output,
        ..Default::default()
    }
}

fn render(g: &Gpu, p: &Particles, prm: &RenderParams) -> Rendered {
    let cam = orbit(p, 20.0, 15.0);
    g.render_adaptive(p, None, &cam, &cloud_tf(), prm).unwrap()
}

/// The particles go up with the first frame; a second frame of the same particles uploads
/// none of them (a few hundred bytes of uniforms and depths) and draws the same image; a
/// frame whose particles differ in one value only uploads them again and draws it.
#[test]
fn particles_are_uploaded_only_when_they_change() {
    let Some(g) = gpu() else { return };
    let mut p = cloud(3000, 11);
    let prm = params(ImageOutput::FULL, None);
    let first = render(&g, &p, &prm);
    let again = render(&g, &p, &prm);
    let world = 32 * p.len() as u64;
    let (up1, up2) = (
        first.stats.transfers.uploaded_bytes,
        again.stats.transfers.uploaded_bytes,
    );
    assert!(
        up1 >= world,
        "first frame uploaded {up1} bytes, the particles are {world}"
    );
    assert!(
        up2 + world <= up1,
        "second frame uploaded {up2} bytes, the first {up1}: the particles went up again"
    );
    assert_eq!(first.image.rgba, again.image.rgba);
    // The particle nearest the image's centre pixel gets another value.
    let centre = (H / 2 * W + W / 2) as usize;
    assert!(
        first.image.rgba[centre][3] > 0.05,
        "the centre pixel is empty"
    );
    let (lo, hi) = p.value_range();
    for v in p.values.iter_mut() {
        *v = if *v > (lo + hi) / 2.0 { lo } else { hi };
    }
    let changed = render(&g, &p, &prm);
    assert!(changed.stats.transfers.uploaded_bytes >= world);
    let moved = (0..first.image.rgba.len())
        .filter(|&k| first.image.rgba[k] != changed.image.rgba[k])
        .count();
    assert!(
        moved > first.image.rgba.len() / 10,
        "new values changed only {moved} pixels: the old particles were drawn"
    );
}

/// Values of `shown` within one binary16 ulp of `full`'s; how many differ at all.
fn within_half_ulp(full: &[[f32; 4]], shown: &[[f32; 4]]) -> usize {
    let mut rounded = 0;
    for (k, (a, b)) in full.iter().zip(shown).enumerate() {
        for c in 0..4 {
            // One ulp of binary16 at a's magnitude (normal numbers from 2^-14).
            let ulp = a[c].abs().max(2f32.powi(-14)).log2().floor().exp2() / 1024.0;
            let d = (a[c] - b[c]).abs();
            assert!(d <= ulp, "pixel {k} channel {c}: {} vs {}", a[c], b[c]);
            rounded += usize::from(d > 0.0);
        }
    }
    rounded
}

/// `ImageOutput::DISPLAY`: half-precision colour within a binary16 ulp of the full image,
/// no depth (+∞), and 12 bytes a pixel fewer read back; the same in relaxed mode (whose
/// refinement, where it runs, reads its passes at full precision).
#[test]
fn display_output_reads_back_half_colour_and_no_depth() {
    let Some(g) = gpu() else { return };
    let p = cloud(3000, 12);
    for tolerance in [None, Some(0.004)] {
        let full = render(&g, &p, &params(ImageOutput::FULL, tolerance));
        let shown = render(&g, &p, &params(ImageOutput::DISPLAY, tolerance));
        let rounded = within_half_ulp(&full.image.rgba, &shown.image.rgba);
        assert!(full.image.depth.iter().any(|z| z.is_finite()));
        if shown.stats.interpolated > 0 {
            assert_eq!(rounded, 0, "{tolerance:?}: refined passes were halved");
            continue;
        }
        assert!(
            rounded > 0,
            "{tolerance:?}: no value was rounded: not halved"
        );
        assert!(shown.image.depth.iter().all(|z| z.is_infinite()));
        // The packing pass has two timestamps of its own (8 bytes each) where there are any.
        let stamps = 16 * u64::from(g.has_timestamps());
        let (a, b) = (full.stats.transfers, shown.stats.transfers);
        assert_eq!(
            a.readback_bytes + stamps - b.readback_bytes,
            12 * u64::from(W * H),
            "{tolerance:?}"
        );
    }
}

/// Waits for the device beyond the resumed dispatches a software driver needs.
fn waits(g: &Gpu, r: &Rendered) -> u64 {
    let resumed = match g.is_software() {
        true => r.stats.dispatches,
        false => 0,
    };
    r.stats.transfers.waits - resumed
}

/// On hardware (no loop limit) a device's first full-rate frame waits for it three times: the
/// pair count, the cell count, and the image, which comes back with the plan's summaries and
/// the timestamps (they took two waits of their own before). A later frame sizes its plan from
/// the last cell count and reads its own with the image: two waits. On a software driver each
/// resumed dispatch adds one.
#[test]
fn a_frame_counts_its_waits_and_submits() {
    let Some(g) = gpu() else { return };
    let p = cloud(2000, 13);
    let r = render(&g, &p, &params(ImageOutput::FULL, None));
    let t = r.stats.transfers;
    assert_eq!(waits(&g, &r), 3, "{t:?}");
    // The plan's statistics and the timestamps came back with the image.
    assert!(r.stats.plan.is_some(), "{:?}", r.stats);
    assert_eq!(
        g.has_timestamps(),
        r.stats.stages.iter().any(|(s, _)| *s == "gpu_raycast"),
        "{:?}",
        r.stats.stages
    );
    assert!(
        t.submits >= t.waits && t.readback_bytes >= 16 * u64::from(W * H),
        "{t:?}"
    );
    let again = render(&g, &p, &params(ImageOutput::FULL, None));
    assert_eq!(waits(&g, &again), 2, "{:?}", again.stats.transfers);
    assert_eq!(again.stats.cells, r.stats.cells);
    assert_eq!(again.image.rgba, r.image.rgba);
    assert!(r.image.rgba.iter().any(|c| c[3] > 0.05), "nothing drawn");
}

/// A frame with many more cells than the last passes the capacity its plan was sized for
/// from the last count; it is made again with its own count known (the waits of a device's
/// first frame), and draws what a device that never saw the small frame draws; the next frame
/// fits (one wait fewer), at full rate and with the relaxed mode's refinement.
#[test]
fn a_frame_past_the_last_cell_count_is_made_again() {
    let Some(g) = gpu() else { return };
    let p = cloud(3000, 14);
    for tolerance in [None, Some(0.004)] {
        let small = RenderParams {
            width: 16,
            height: 12,
            ..params(ImageOutput::FULL, tolerance)
        };
        let large = RenderParams {
            width: 320,
            height: 240,
            ..params(ImageOutput::FULL, tolerance)
        };
        let fresh = render(&gpu().unwrap(), &p, &large);
        let drawn = fresh.image.rgba.iter().filter(|c| c[3] > 0.05).count();
        assert!(
            drawn > fresh.image.rgba.len() / 20,
            "{tolerance:?}: {drawn} pixels drawn"
        );
        let s = render(&g, &p, &small);
        let l = render(&g, &p, &large);
        assert!(
            l.stats.cells > 3 * s.stats.cells / 2 + 1024,
            "{tolerance:?}: cells {} after {}: within the capacity",
            l.stats.cells,
            s.stats.cells
        );
        // As many waits as a device's first frame (three, and with the refinement its
        // passes' and the plan's summaries'), one more than a frame that fits.
        let first = waits(&g, &fresh);
        assert_eq!(
            waits(&g, &l),
            first,
            "{tolerance:?}: {:?}",
            l.stats.transfers
        );
        assert_eq!(l.stats.cells, fresh.stats.cells);
        assert_eq!(l.image.rgba, fresh.image.rgba, "{tolerance:?}");
        let again = render(&g, &p, &large);
        assert_eq!(again.image.rgba, fresh.image.rgba, "{tolerance:?}");
        assert_eq!(waits(&g, &again), first - 1, "{tolerance:?}");
    }
}
