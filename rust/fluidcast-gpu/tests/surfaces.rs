//! Iso-surfaces on the GPU against the reference caster's (f64, CPU; no shared code but the
//! sample depths): the same pixels covered, the first surface's depth within one depth
//! sample, colour within 2/255 and normals within a few degrees on all but a few silhouette
//! pixels, where a ray grazes the level set and f32 against f64 decides whether it crosses.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;

use std::sync::Arc;

use common::{cloud, cloud_tf, gpu, shared_ddb};
use fluidcast_gpu::Gpu;
use fluidcast_image::Image;
use fluidcast_render::{render_reference, IsoField, RenderParams, RenderStats, Surfaces};
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, Light, Lighting, TransferFunction};

/// How far the GPU's surfaces are from the CPU's.
#[derive(Debug, Default)]
struct Diff {
    /// Pixels with a surface on either side.
    covered: usize,
    /// Pixels with a surface on one side only, or whose colour differs by more than 2/255,
    /// depth by more than one depth sample or normal by more than 0.05.
    off: usize,
    /// The largest colour difference among the other pixels (/255).
    max_rgb: f64,
}

/// The view depth between consecutive samples at depth z of a frame the CPU's stats describe
/// (logarithmic sampling of near..far in `depth_samples` steps).
fn sample_spacing(stats: &RenderStats, z: f64) -> f64 {
    let ratio = (stats.far / stats.near).powf(1.0 / stats.depth_samples as f64);
    z * (ratio - 1.0)
}

fn aov<'a>(im: &'a Image, name: &str) -> &'a [f32] {
    &im.aovs.iter().find(|a| a.0 == name).unwrap().1
}

fn compare(cpu: &(Image, RenderStats), gpu: &Image) -> Diff {
    let (c, stats) = cpu;
    let mut d = Diff::default();
    let normals = |im: &Image, p: usize| {
        ["normal_x", "normal_y", "normal_z"].map(|n| f64::from(aov(im, n)[p]))
    };
    for p in 0..c.rgba.len() {
        let (zc, zg) = (f64::from(c.depth[p]), f64::from(gpu.depth[p]));
        if zc.is_infinite() && zg.is_infinite() {
            continue;
        }
        d.covered += 1;
        if zc.is_infinite() != zg.is_infinite() {
            d.off += 1;
            continue;
        }
        let rgb = (0..4)
            .map(|k| f64::from((c.rgba[p][k] - gpu.rgba[p][k]).abs()) * 255.0)
            .fold(0.0, f64::max);
        let (nc, ng) = (normals(c, p), normals(gpu, p));
        let dn = (0..3).map(|k| (nc[k] - ng[k]).abs()).fold(0.0, f64::max);
        if rgb > 2.0 || (zc - zg).abs() > sample_spacing(stats, zc) || dn > 0.05 {
            d.off += 1;
        } else {
            d.max_rgb = d.max_rgb.max(rgb);
        }
    }
    d
}

fn params(w: u32, h: u32, surfaces: Surfaces) -> RenderParams {
    RenderParams {
        width: w,
        height: h,
        surfaces: Some(Arc::new(surfaces)),
        ..Default::default()
    }
}

/// Renders on both and checks: at most a fraction `most_off` of the covered pixels off (and
/// at least 2 allowed), at least `least_covered` covered; returns the GPU's stats. On lavapipe
/// none is off; without the search for crossings hidden between samples, 6 to 21 are, in
/// four of the five scenes.
fn check(
    g: &Gpu,
    what: &str,
    (p, cam, tf): (&Particles, &Camera, &TransferFunction),
    prm: &RenderParams,
    (least_covered, most_off): (usize, f64),
) -> RenderStats {
    let cpu = render_reference(p, cam, tf, prm).unwrap();
    let (gi, gs) = g.render_surfaces(p, cam, tf, prm).unwrap();
    let d = compare(&cpu, &gi);
    eprintln!(
        "{what}: {d:?}, {} dispatches, stages {:?}",
        gs.dispatches, gs.stages
    );
    assert!(d.covered >= least_covered, "{what}: {d:?}");
    assert!(
        d.off as f64 <= (most_off * d.covered as f64).max(2.0),
        "{what}: {} of {} covered pixels off",
        d.off,
        d.covered
    );
    gs
}

fn cloud_view() -> Camera {
    Camera {
        position: [0.4, 0.6, 2.4],
        focal_point: [0.0; 3],
        view_up: [0.0, 1.0, 0.0],
        ..Default::default()
    }
}

/// The colour field's 0.5 level of a cloud of clumps, opaque, lit by the headlight: the
/// GPU's surfaces are the reference's.
#[test]
fn colour_field_surfaces_match_the_reference() {
    let Some(g) = gpu() else { return };
    let (p, tf, cam) = (cloud(3000, 5), cloud_tf(), cloud_view());
    let prm = params(96, 72, Surfaces::default());
    let stats = check(&g, "colour 0.5", (&p, &cam, &tf), &prm, (800, 0.001));
    assert!(stats.stage("surfaces").is_some());
    // A tenth of the loop budget: walks stop mid-way (in refinements, searches, shading)
    // and resume in many more dispatches, and the image is the same to the bit.
    let (a, _) = g.render_surfaces(&p, &cam, &tf, &prm).unwrap();
    let tight = gpu().unwrap().with_loop_limit(6_000);
    let (b, sb) = tight.render_surfaces(&p, &cam, &tf, &prm).unwrap();
    eprintln!(
        "tight: {} dispatches (default {})",
        sb.dispatches, stats.dispatches
    );
    assert!(sb.dispatches > stats.dispatches + 3);
    assert_eq!(a.rgba, b.rgba);
    assert_eq!(a.depth, b.depth);
    assert_eq!(a.aovs, b.aovs);
    // So few iterations that not one step of a walk fits: refused, never a wrong image.
    let starved = gpu().unwrap().with_loop_limit(1_000);
    let e = starved.render_surfaces(&p, &cam, &tf, &prm).unwrap_err();
    assert!(
        matches!(e, fluidcast_gpu::GpuError::LoopLimit { stage, .. } if stage.contains("iso-surfaces")),
        "{e}"
    );
}

/// Two translucent levels of the Shepard-normalised attribute with a directional light and
/// a solid colour; then the density field with several values and a given iso attribute.
#[test]
fn attribute_and_density_surfaces_match_the_reference() {
    let Some(g) = gpu() else { return };
    let (p, tf, cam) = (cloud(3000, 5), cloud_tf(), cloud_view());
    let lighting = Lighting {
        light: Light::Directional([0.3, 1.0, 0.5]),
        specular_power: 20.0,
        ..Default::default()
    };
    let translucent = Surfaces {
        field: IsoField::Attribute(None),
        values: vec![0.0, 0.5],
        opacity: 0.5,
        colour: Some([0.9, 0.5, 0.2]),
        lighting,
        volume: false,
    };
    let prm = params(96, 72, translucent);
    check(
        &g,
        "attribute 0, 0.5 at opacity 0.5",
        (&p, &cam, &tf),
        &prm,
        (500, 0.001),
    );
    let b: Arc<[f32]> = p.positions.iter().map(|x| x[1]).collect();
    let other = Surfaces {
        field: IsoField::Attribute(Some(b)),
        values: vec![0.05],
        ..Default::default()
    };
    let prm = params(96, 72, other);
    check(
        &g,
        "another attribute (y) 0.05",
        (&p, &cam, &tf),
        &prm,
        (300, 0.001),
    );
    let density = Surfaces {
        field: IsoField::Density,
        values: vec![50.0, 200.0, 800.0],
        opacity: 0.6,
        ..Default::default()
    };
    let prm = params(96, 72, density);
    check(
        &g,
        "density 50, 200, 800",
        (&p, &cam, &tf),
        &prm,
        (300, 0.001),
    );
}

/// A real frame (the shared SPlisHSPlasH double dam break, 42k particles) at 200x150: the free surface of the colour field on
/// lavapipe needs several dispatches, and the image is the reference's.
#[test]
fn a_shared_frame_has_the_references_free_surface() {
    let Some(g) = gpu() else { return };
    let Some((p, tf, cam)) = shared_ddb() else {
        return;
    };
    let prm = params(200, 150, Surfaces::default());
    let stats = check(
        &g,
        "shared double dam break",
        (&p, &cam, &tf),
        &prm,
        (3000, 0.001),
    );
    if g.is_software() {
        assert!(stats.dispatches >= 2, "{} dispatches", stats.dispatches);
    }
}

/// More iso values than the shader holds: a clear error, not a wrong image.
#[test]
fn too_many_iso_values_are_refused() {
    let Some(g) = gpu() else { return };
    let (p, tf, cam) = (cloud(300, 5), cloud_tf(), cloud_view());
    let many = Surfaces {
        values: vec![0.1, 0.2, 0.3, 0.4, 0.5],
        ..Default::default()
    };
    let e = g
        .render_surfaces(&p, &cam, &tf, &params(32, 24, many))
        .unwrap_err();
    assert!(e.to_string().contains("at most 4 iso-surfaces"), "{e}");
}

/// The shared double dam break at 1024x768: on lavapipe (128 MiB bindings) the walks in
/// progress do not fit one binding, so the rays are walked in two bands of rows of bundles;
/// the image is still the reference's.
#[test]
fn large_images_walk_in_bands() {
    let Some(g) = gpu() else { return };
    let Some((p, tf, cam)) = shared_ddb() else {
        return;
    };
    let prm = params(1024, 768, Surfaces::default());
    let stats = check(
        &g,
        "1024x768 in bands",
        (&p, &cam, &tf),
        &prm,
        (50_000, 0.001),
    );
    if g.is_software() {
        assert!(stats.dispatches >= 2, "{} dispatches", stats.dispatches);
    }
}
