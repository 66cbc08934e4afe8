//! What the renderers report beside the image: the same composited-sample count and depth
//! range wherever they take the same samples, the particles in view, and stage timings that
//! are non-negative, in order and add up to no more than the total.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly

mod common;
use common::{cloud, cloud_view};
use fluidcast_render::{
    render_adaptive, render_object_space, render_reference, RenderParams, RenderStats,
};
use fluidcast_sph::FieldKind;
use std::time::Instant;

/// The stage names in order, each time finite and non-negative, the total positive and at
/// least the sum of the others (they are disjoint parts of it).
fn check_stages(name: &str, s: &RenderStats, want: &[&str]) {
    let names: Vec<&str> = s.stages.iter().map(|x| x.0).collect();
    assert_eq!(names, want, "{name}");
    for &(stage, t) in &s.stages {
        assert!(t.is_finite() && t >= 0.0, "{name} {stage}: {t} ms");
    }
    let total = s.stage("total").unwrap();
    let parts: f64 = s
        .stages
        .iter()
        .filter(|x| x.0 != "total")
        .map(|x| x.1)
        .sum();
    assert!(total > 0.0, "{name}: total {total} ms");
    assert!(
        parts <= total,
        "{name}: stages {parts} ms > total {total} ms"
    );
}

#[test]
fn renderers_report_the_same_samples_and_their_stages() {
    let mut p = cloud(150, 3);
    // Ten particles far off to the side: outside the view, never counted as visible.
    for k in 0..10 {
        p.positions.push([40.0 + k as f32, 0.0, 0.0]);
        p.radii.push(0.2);
        p.volumes.push(0.002);
        p.masses.push(1.0);
        p.values.push(0.0);
    }
    let (cam, tf) = cloud_view(30.0, 15.0, false, FieldKind::Csph);
    let mut prm = RenderParams {
        width: 40,
        height: 30,
        ..Default::default()
    };
    prm.adaptive.tolerance = None;
    let (ri, rs) = render_reference(&p, &cam, &tf, &prm).unwrap();
    let a = render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
    let (oi, os) = render_object_space(&p, &cam, &tf, &prm).unwrap();
    // The same image to single-precision rounding (see adaptive.rs).
    let diff = fluidcast_image::compare(&a.image, &ri, 1.0)
        .unwrap()
        .0
        .max_abs;
    assert!(diff <= 2e-6, "{diff}");
    assert!(oi.rgba.iter().any(|c| c[3] > 0.05));

    check_stages("reference", &rs, &["bin", "raycast", "total"]);
    check_stages("adaptive", &a.stats, &["grid", "adapt", "raycast", "total"]);
    check_stages("object space", &os, &["grid", "raycast", "total"]);
    // One sample per composited (non-empty) depth step: the three take the same samples.
    let ref_samples = rs.samples;
    assert!(ref_samples > 1000, "{ref_samples}");
    assert_eq!(a.stats.samples, ref_samples);
    assert_eq!(os.samples, ref_samples);
    for s in [&rs, &a.stats, &os] {
        assert_eq!((s.width, s.height, s.particles), (40, 30, 160));
        assert_eq!(s.depth_samples, rs.depth_samples);
        assert_eq!((s.near, s.far), (rs.near, rs.far));
    }
    assert!(rs.depth_samples > 10 && rs.near < rs.far);
    assert_eq!(rs.particles_visible, 150);
    assert_eq!(a.stats.particles_visible, 150);
    // The grid renderer's counts: 5 x 4 bundles of 8 x 8 pixels, its cells and references.
    assert_eq!(a.stats.bundles, 20);
    assert_eq!(a.stats.cells, a.grid.cells.len() as u64);
    assert_eq!(a.stats.pairs, a.grid.refs.len() as u64);
    assert!(
        a.stats.cells >= 20 && a.stats.pairs > a.stats.cells,
        "{:?}",
        a.stats
    );
    assert_eq!(a.stats.plan.as_ref(), Some(&a.plan.stats));
}

/// The stage times are milliseconds of this clock: the reported total lies within the wall
/// time the caller measured around the render, and (timings being noisy, in one of five
/// tries) it is most of it.
#[test]
fn stage_times_are_milliseconds_of_the_render() {
    let p = cloud(400, 9);
    let (cam, tf) = cloud_view(30.0, 15.0, false, FieldKind::Csph);
    let prm = RenderParams {
        width: 120,
        height: 90,
        ..Default::default()
    };
    let mut ratios = Vec::new();
    for _ in 0..5 {
        let t = Instant::now();
        let (_, s) = render_reference(&p, &cam, &tf, &prm).unwrap();
        let wall = t.elapsed().as_secs_f64() * 1e3;
        let total = s.stage("total").unwrap();
        assert!(total <= wall, "total {total} ms > wall {wall} ms");
        ratios.push(total / wall);
        if total >= 0.5 * wall {
            return;
        }
    }
    panic!("the reported total is never most of the wall time: {ratios:?}");
}

/// For SPH sums and density as for CSPH, the object-space baseline takes a sample only where
/// a particle reaches (a sum of nothing is no sample, not a zero): it composites as many
/// samples as the reference.
#[test]
fn object_space_samples_only_where_a_particle_reaches() {
    let p = cloud(150, 4);
    for field in [FieldKind::Sph, FieldKind::Density] {
        let (cam, tf) = cloud_view(-20.0, 25.0, false, field);
        let prm = RenderParams {
            width: 40,
            height: 30,
            field,
            ..Default::default()
        };
        let (_, rs) = render_reference(&p, &cam, &tf, &prm).unwrap();
        let (_, os) = render_object_space(&p, &cam, &tf, &prm).unwrap();
        assert!(rs.samples > 1000, "{field:?}: {}", rs.samples);
        assert_eq!(os.samples, rs.samples, "{field:?}");
    }
}
