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

/// On hardware (no loop limit) a full-rate frame waits for the device three times: the pair
/// count, the cell count, and the image, which comes back with the plan's summaries and the
/// timestamps (they took two waits of their own before). On a software driver each resumed
/// dispatch adds one.
#[test]
fn a_frame_counts_its_waits_and_submits() {
    let Some(g) = gpu() else { return };
    let p = cloud(2000, 13);
    let r = render(&g, &p, &params(ImageOutput::FULL, None));
    let t = r.stats.transfers;
    let resumed = match g.is_software() {
        true => r.stats.dispatches,
        false => 0,
    };
    assert_eq!(t.waits, 3 + resumed, "{t:?}");
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
}
