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
