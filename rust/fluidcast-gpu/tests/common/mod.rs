//! Scenes and helpers shared by the GPU tests.
#![allow(dead_code)]

use fluidcast_gpu::Gpu;
use fluidcast_render::PlanParams;
use fluidcast_sph::Particles;
use fluidcast_view::{Camera, TransferFunction};

/// The GPU, or `None` (with a SKIPPED line) when there is no adapter. Without any wgpu adapter
/// the tests print why and skip, unless FLUIDCAST_REQUIRE_GPU=1 (scripts/test.sh sets it: it
/// installs Mesa's lavapipe), which turns that into a failure.
pub fn gpu() -> Option<Gpu> {
    match Gpu::new() {
        Ok(g) => {
            eprintln!("GPU adapter: {}", g.adapter);
            Some(g)
        }
        Err(e) => {
            if std::env::var("FLUIDCAST_REQUIRE_GPU").as_deref() == Ok("1") {
                panic!("FLUIDCAST_REQUIRE_GPU=1 but: {e}");
            }
            eprintln!("SKIPPED: {e}");
            None
        }
    }
}

pub fn cloud(n: usize, seed: u32) -> Particles {
    fluidcast_testkit::cloud(n, seed, (0.12, 0.08))
}

/// Viridis over the cloud's values [-0.5, 1], opacity per 0.15 world units.
pub fn cloud_tf() -> TransferFunction {
    let mut tf = TransferFunction::preset("viridis")
        .unwrap()
        .with_range(-0.5, 1.0)
        .unwrap();
    tf.unit_distance = 0.15;
    tf
}

/// Full rate, the default relaxed plan at E_I = 0.004, and the strict plan.
pub fn modes() -> [(&'static str, PlanParams); 3] {
    [
        (
            "off",
            PlanParams {
                tolerance: None,
                ..Default::default()
            },
        ),
        ("0.004", PlanParams::default()),
        ("strict 0.004", PlanParams::default().strict()),
    ]
}

/// A shared dataset coloured by velocity magnitude (inferno over its range, opacity per 0.1
/// world units) under an oblique camera that frames it, or `None` with a SKIPPED line when
/// ../shared/data does not hold it.
pub fn shared_scene(file: &str) -> Option<(Particles, TransferFunction, Camera)> {
    let path = fluidcast_testkit::shared_data(file)?;
    let ds = fluidcast_io::read_dataset(&path).unwrap();
    let spec = fluidcast_sph::ParticleSpec {
        quantity: Some("velocity:mag".parse().unwrap()),
        ..Default::default()
    };
    let p = Particles::from_dataset(&ds, &spec).unwrap();
    let (lo, hi) = p.value_range();
    let mut tf = TransferFunction::preset("inferno")
        .unwrap()
        .with_range(lo as f64, hi as f64)
        .unwrap();
    tf.unit_distance = 0.1;
    let mut cam = Camera::default();
    let (a, b) = p.support_bounds();
    cam.reset(a.map(f64::from), b.map(f64::from));
    cam.azimuth(30.0);
    cam.elevation(25.0);
    cam.orthogonalize_view_up();
    Some((p, tf, cam))
}

/// The shared SPlisHSPlasH double dam break (see [`shared_scene`]).
pub fn shared_ddb() -> Option<(Particles, TransferFunction, Camera)> {
    shared_scene("splash_doubledambreak/DoubleDamBreak_r0.0125_0011.vtu")
}

/// The shared PySPH 3D dam break, fluid only (see [`shared_scene`]).
pub fn shared_pysph() -> Option<(Particles, TransferFunction, Camera)> {
    shared_scene("pysph_dambreak3d/dam_break_3d_fluid_01180.vtu")
}

/// Why a pixel may differ between the f64 CPU and the f32 GPU, found by recasting its ray in
/// f64 over the CPU's own plan (an oracle that shares no code with the GPU):
/// * an *edge sample*: every particle that reaches the sample lies within 1e-4 H of its
///   support's edge. Shepard normalisation gives such a sample the particles' full value
///   however small their weight, and f32 rounding (~1e-5 H at view depths of a few support
///   radii) decides whether it exists at all;
/// * an *opaque sample*: the transfer function's opacity above 0.999, where the step alpha
///   1 − (1 − α)^(Δs/u) has unbounded slope, so the f32 value's last bits show.
///
/// Returns (edge, opaque) for pixel (i, j).
pub fn f32_explanation(
    planned: &fluidcast_render::AdaptivePlan,
    tf: &TransferFunction,
    kernel: fluidcast_sph::Kernel,
    i: u32,
    j: u32,
) -> (bool, bool) {
    let g = &planned.grid;
    let Some(depths) = &g.depths else {
        return (false, false);
    };
    let dz = g.params.depth_samples as usize;
    let b = ((j / g.params.bundle) * g.bundles_x + i / g.params.bundle) as usize;
    let ray = fluidcast_grid::Ray::through_pixel(&g.frame, i, j);
    let (mut edge, mut opaque) = (false, false);
    for s in planned.plan.bundle_spans(b) {
        let cells = &g.cells[s.first as usize..(s.first + s.count) as usize];
        let refs: Vec<u32> = g.merged_refs(cells).collect();
        let k0 = cells[0].z as usize * dz;
        for m in (0..dz * s.count as usize).step_by(1 << s.level) {
            let z = depths.z[k0 + m];
            let (mut inner, mut at_edge, mut ws, mut wq) = (0, 0, 0.0, 0.0);
            for &r in &refs {
                let p = &g.particles[r as usize];
                let d = ray.distance_at(z, p);
                let q = d / p.h();
                if q < 1.0 - 1e-4 {
                    inner += 1;
                } else if q < 1.0 + 1e-4 {
                    at_edge += 1;
                }
                let w = kernel.eval(d, p.h());
                ws += p.v() * w;
                wq += p.v() * p.a() * w;
            }
            edge |= inner == 0 && at_edge > 0;
            opaque |= ws > 0.0 && tf.eval(wq / ws).1 > 0.999;
        }
    }
    (edge, opaque)
}

/// Pixels where the images differ by more than 1e-3 in any channel, as (i, j).
pub fn differing_pixels(a: &fluidcast_image::Image, b: &fluidcast_image::Image) -> Vec<(u32, u32)> {
    a.rgba
        .iter()
        .zip(&b.rgba)
        .enumerate()
        .filter(|(_, (p, q))| (0..4).any(|c| (p[c] - q[c]).abs() > 1e-3))
        .map(|(k, _)| (k as u32 % a.width, k as u32 / a.width))
        .collect()
}

/// A camera that frames the particles, turned by azimuth and elevation (degrees).
pub fn orbit(p: &Particles, azimuth: f64, elevation: f64) -> Camera {
    let mut cam = Camera::default();
    let (a, b) = p.support_bounds();
    cam.reset(a.map(f64::from), b.map(f64::from));
    cam.azimuth(azimuth);
    cam.elevation(elevation);
    cam.orthogonalize_view_up();
    cam
}
