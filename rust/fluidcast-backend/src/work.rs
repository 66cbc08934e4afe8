//! The work a frame will take, estimated before it runs, and the limit above which a render
//! is refused with a message rather than run for minutes (a support radius typed 1000 times
//! too large, a camera inside the fluid at 4K).
//!
//! The estimate counts kernel evaluations at full rate: a particle of support radius H at
//! view depth z covers a disc of r = H / (pixel size at z) pixels, and each ray through it
//! takes about 2 r × sampling scale depth samples inside its support, so it costs
//! min(π r², pixels of the disc inside the image) × max(1, 2 r s) evaluations. The adaptive
//! plan only ever samples less.

use rayon::prelude::*;

use fluidcast_render::RenderParams;
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, ViewFrame};
use glam::DVec3;

use crate::BackendError;

/// The default limit on a frame's estimated kernel evaluations ([`estimate`]): 5·10^10,
/// about 10 s of the CPU renderer on 2 cores (measured: estimates of 3·10^8, 2.9·10^9 and
/// 1.8·10^10 rendered in 0.5, 0.8 and 3.6 s; docs/performance.md). Real frames stay far
/// below it: a few pixels a particle is about 10^2 evaluations each, 10^9 for ten million.
pub const DEFAULT_WORK_LIMIT: f64 = 5e10;

/// Estimated kernel evaluations of a full-rate render of `particles` seen by `camera` with
/// `params` (size, sampling scale); see the module's description.
pub fn estimate(
    particles: &Particles,
    camera: &Camera,
    params: &RenderParams,
) -> Result<f64, BackendError> {
    let frame = camera.frame(params.width, params.height)?;
    let s = params.sampling_scale;
    Ok(particles
        .positions
        .par_iter()
        .zip(particles.radii.par_iter())
        .map(|(p, &h)| {
            let h = f64::from(h);
            let v = frame.to_view(DVec3::from(p.map(f64::from)));
            if frame.parallel.is_none() && v.z + h <= 0.0 {
                return 0.0; // behind the eye
            }
            // A support around the eye covers the screen: its depth is taken as H.
            let r = h / frame.pixel_size_at(v.z.max(h));
            on_screen(&frame, v, h, r) * (2.0 * r * s).max(1.0)
        })
        .sum())
}

/// The pixels of a particle's projected disc (radius `r` pixels; view-space centre `v`,
/// support radius `h`) inside the image: π r², clipped to the image where the disc's box, taken
/// half as wide again (the projection of a support off the axis is stretched), leaves it, 0
/// where that box misses the image. A support reaching to within 2 H of the eye is counted
/// whole (up to the image's pixels): its projection is far wider than `r`. A close-up of part
/// of a large data set counts the particles it shows, not those the camera looks past (a
/// 227k-particle dam break zoomed 4 times at 1024 × 768 was refused for 5.5·10¹⁰ evaluations).
fn on_screen(frame: &ViewFrame, v: DVec3, h: f64, r: f64) -> f64 {
    let (w, ht) = (f64::from(frame.width), f64::from(frame.height));
    let disc = std::f64::consts::PI * r * r;
    let near_eye = frame.parallel.is_none() && v.z < 2.0 * h;
    match frame.project_view(v) {
        Some((x, y)) if !near_eye => {
            let inside = |c: f64, n: f64| ((c + 1.5 * r).min(n) - (c - 1.5 * r).max(0.0)).max(0.0);
            disc.min(inside(x, w) * inside(y, ht))
        }
        _ => disc.min(w * ht),
    }
}

/// What adaptive sampling's own work costs per particle, in kernel evaluations of the full-rate
/// cast (measured on 2 cores, 2026-12-04, docs/performance.md: the cast 0.7–1.2 ns per
/// estimated evaluation; the plan's analysis about 0.07 µs per particle beyond full rate's; the
/// surface flags 0.17–0.18 µs per particle, once per particle set). Taken at the cast's slowest
/// evaluation, so that these costs are not overstated.
pub const ANALYSIS_EVALUATIONS_PER_PARTICLE: f64 = 60.0;
/// See [`ANALYSIS_EVALUATIONS_PER_PARTICLE`]: the surface flags.
pub const FLAGS_EVALUATIONS_PER_PARTICLE: f64 = 150.0;
/// The share of the full-rate work that adaptive sampling is counted on saving where it
/// runs. On the scenes developed on (docs/performance.md, issue 47) every view where the
/// default lost to full rate had at most 2,146 estimated evaluations a particle, every view
/// where it won or broke even at least 3,902 (a 42k-particle frame at 1024 × 768) or 10,856;
/// with this share the threshold falls between them, at 3,360. It amounts to supports of
/// about 8 pixels' radius and more (a particle of radius r pixels costs about 2π r³
/// evaluations), where the paper's plans have room to adapt.
pub const SAVED_SHARE: f64 = 1.0 / 16.0;

/// Whether adaptive sampling can pay for its own work on a view whose full-rate cast takes
/// `work` kernel evaluations ([`estimate`]) for `particles` particles: only if the share of
/// the cast it can be counted on saving ([`SAVED_SHARE`]) exceeds the analysis and the
/// surface flags. Below, the default would make a user wait longer than full rate (a million
/// particles a few pixels wide: 11 evaluations a particle at 320 × 240; the 338k-particle dam
/// break at 1024 × 768: 494).
///
/// The flags count even where a front-end keeps them from an earlier render (the VTK mapper,
/// ParaView, a series of views): the decision must depend on the view alone, so that the CLI,
/// the mapper and the Python module draw the same image of the same view (the pyvista test
/// that compares the mapper's first and later renders with the CLI caught a mapper that had
/// the flags adapting where the CLI did not).
pub fn adaptivity_can_pay(work: f64, particles: usize) -> bool {
    let per_particle = ANALYSIS_EVALUATIONS_PER_PARTICLE + FLAGS_EVALUATIONS_PER_PARTICLE;
    work * SAVED_SHARE >= per_particle * particles as f64
}

/// Refuses a frame whose [`estimate`] exceeds `limit`, saying how much it needs and what
/// usually causes it.
pub fn check(
    particles: &Particles,
    camera: &Camera,
    params: &RenderParams,
    limit: f64,
) -> Result<(), BackendError> {
    refuse_above(estimate(particles, camera, params)?, particles, limit)
}

/// [`check`] of a view whose [`estimate`] is already known: `work` kernel evaluations.
pub fn refuse_above(work: f64, particles: &Particles, limit: f64) -> Result<(), BackendError> {
    if work <= limit {
        return Ok(());
    }
    let largest = particles.radii.iter().copied().fold(0.0f32, f32::max);
    Err(BackendError::Refused {
        item: crate::PlanItem::Work,
        why: format!(
            "this view needs about {work:.1e} kernel evaluations ({} particles, the largest \
             support radius {largest:e} world units), more than the limit of {limit:.1e}: check \
             the support radius and the camera, or raise the limit",
            particles.len()
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One particle of radius `h` at distance 10 in front of a 90° camera.
    fn single(h: f32) -> (Particles, Camera) {
        let mut p = Particles::default();
        p.positions.push([0.0, 0.0, 0.0]);
        p.radii.push(h);
        p.volumes.push(1.0);
        p.masses.push(1.0);
        p.values.push(1.0);
        let camera = Camera {
            position: [0.0, 0.0, 10.0],
            focal_point: [0.0, 0.0, 0.0],
            view_up: [0.0, 1.0, 0.0],
            view_angle: 90.0,
            ..Camera::default()
        };
        (p, camera)
    }

    /// A 100 × 100 image.
    fn square() -> RenderParams {
        RenderParams {
            width: 100,
            height: 100,
            ..Default::default()
        }
    }

    #[test]
    fn a_disc_of_pixels_times_the_samples_through_it() {
        let params = square();
        // At depth 10 with 90°, the screen spans 20 units: 0.2 units a pixel; H = 1 is 5 px.
        let (p, cam) = single(1.0);
        let r: f64 = 5.0;
        let want = std::f64::consts::PI * r * r * 2.0 * r;
        let got = estimate(&p, &cam, &params).unwrap();
        assert!((got / want - 1.0).abs() < 1e-6, "{got} vs {want}");
        // Twice the depth samples per pixel footprint: twice the samples through it.
        let fine = RenderParams {
            sampling_scale: 2.0,
            ..params.clone()
        };
        let got = estimate(&p, &cam, &fine).unwrap();
        assert!(
            (got / (2.0 * want) - 1.0).abs() < 1e-6,
            "{got} vs {}",
            2.0 * want
        );
        // Behind the eye (depth -11, its support ending 10 before the eye): no work.
        let mut behind = p.clone();
        behind.positions[0] = [0.0, 0.0, 21.0];
        assert_eq!(estimate(&behind, &cam, &params).unwrap(), 0.0);
        // Centre just behind the eye (depth -0.5), support reaching in front: it covers the
        // screen.
        behind.positions[0] = [0.0, 0.0, 10.5];
        assert!(estimate(&behind, &cam, &params).unwrap() >= 1e4);
        // A radius 100 times larger covers the screen: pixels × samples, not r².
        let (p, cam) = single(100.0);
        let got = estimate(&p, &cam, &params).unwrap();
        assert!(got <= 1e4 * 2.0 * 100.0 / 0.2 * 1.01, "{got}");
        assert!(got > 7e5, "{got}");
        let e = check(&p, &cam, &params, 1e5).unwrap_err().to_string();
        assert!(e.contains("needs about 7.9e5 kernel evaluations"), "{e}");
        assert!(check(&p, &cam, &params, 1e7).is_ok());
    }

    /// Only the part of a footprint inside the image counts: a close-up does not pay for the
    /// particles beside it.
    #[test]
    fn particles_beside_the_image_cost_nothing() {
        let params = square();
        // 0.2 units a pixel at depth 10: H = 1 is a disc of 5 px radius, 10 samples deep.
        let (mut p, cam) = single(1.0);
        let whole = std::f64::consts::PI * 25.0 * 10.0;
        let at = |p: &Particles| estimate(p, &cam, &params).unwrap();
        assert!((at(&p) / whole - 1.0).abs() < 1e-6);
        // Centred 60 px right of the image's centre (10 px beyond its edge): its box, 7.5 px
        // to each side, misses the image.
        p.positions[0] = [12.0, 0.0, 0.0];
        assert_eq!(at(&p), 0.0);
        // Centred 2.5 px beyond the edge: 5 of the box's 15 columns are inside.
        p.positions[0] = [10.5, 0.0, 0.0];
        let got = at(&p);
        assert!((got / (5.0 * 15.0 * 10.0) - 1.0).abs() < 1e-6, "{got}");
        // Centred on the edge: half the box (7.5 × 15 px) is inside, more than half the disc.
        p.positions[0] = [10.0, 0.0, 0.0];
        assert!((at(&p) / whole - 1.0).abs() < 1e-6);
        // Close to the eye (depth 1.5, support 1) it covers the image however far aside.
        p.positions[0] = [3.0, 0.0, 8.5];
        assert!(at(&p) > 0.0);
        // Not within 2 H of the eye (support 0.5 at depth 1.5, a 17 px disc 100 px from the
        // image's centre), it is clipped as any other: nothing of it is inside.
        p.radii[0] = 0.5;
        assert_eq!(at(&p), 0.0);
    }

    /// The break-even: the share of the cast's work per particle that a plan can be counted
    /// on saving, against the plan's own and the surface flags'.
    #[test]
    fn adaptivity_pays_only_above_its_own_work() {
        let n = 1000;
        let per = ANALYSIS_EVALUATIONS_PER_PARTICLE + FLAGS_EVALUATIONS_PER_PARTICLE;
        let threshold = per * n as f64 / SAVED_SHARE;
        assert!(adaptivity_can_pay(threshold, n));
        assert!(!adaptivity_can_pay(threshold - 1.0, n));
        assert!(adaptivity_can_pay(0.0, 0), "no particles: nothing to lose");
    }
}
