//! The backend API: names, `auto`'s choice against the adapters present, adapters by name,
//! and one render call that gives the CPU renderer's image on the CPU and a matching one on
//! the GPU.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
use fluidcast_backend::{list_adapters, Backend, BackendError, GpuError, Renderer};
use fluidcast_render::{render_adaptive, RenderParams};
use fluidcast_view::{Camera, TransferFunction};

/// The adaptive renderer's frame of `p` on `r`, through the one entry point.
fn draw(
    r: &Renderer,
    p: &fluidcast_sph::Particles,
    cam: &Camera,
    tf: &TransferFunction,
    prm: &RenderParams,
) -> Result<fluidcast_backend::Rendered, BackendError> {
    let mut scene = fluidcast_backend::Scene::new(p.clone(), cam.clone(), tf.clone());
    let plan = fluidcast_backend::RenderPlan {
        params: prm.clone(),
        mode: Some(fluidcast_backend::Mode::Adaptive),
        ..Default::default()
    };
    r.render(&mut scene, &plan)
}

fn scene() -> (
    fluidcast_sph::Particles,
    TransferFunction,
    Camera,
    RenderParams,
) {
    let p = fluidcast_testkit::cloud(3000, 5, (0.12, 0.08));
    let mut tf = TransferFunction::preset("viridis")
        .unwrap()
        .with_range(-0.5, 1.0)
        .unwrap();
    tf.unit_distance = 0.15;
    let cam = Camera {
        position: [0.4, 0.6, 2.4],
        focal_point: [0.0; 3],
        view_up: [0.0, 1.0, 0.0],
        ..Default::default()
    };
    let prm = RenderParams {
        width: 64,
        height: 48,
        ..Default::default()
    };
    (p, tf, cam, prm)
}

#[test]
fn backend_names_round_trip_and_bad_names_are_errors() {
    for n in Backend::NAMES {
        let b: Backend = n.parse().unwrap();
        assert_eq!(b.to_string(), n);
    }
    assert_eq!("GPU".parse::<Backend>().unwrap(), Backend::Gpu);
    let e = "cuda".parse::<Backend>().unwrap_err();
    assert!(matches!(e, BackendError::Name(_)), "{e}");
    assert!(e.to_string().contains("auto, cpu or gpu"), "{e}");
}

#[test]
fn cpu_backend_is_the_cpu_renderer() {
    let (p, tf, cam, prm) = scene();
    let r = Renderer::open(Backend::Cpu, None).unwrap();
    assert!(r.gpu().is_none() && r.note().is_none());
    assert!(r.device().starts_with("CPU ("), "{}", r.device());
    let a = draw(&r, &p, &cam, &tf, &prm).unwrap();
    let b = render_adaptive(&p, None, &cam, &tf, &prm).unwrap();
    assert_eq!(a.image.rgba, b.image.rgba);
    assert_eq!(a.stats.samples, b.stats.samples);
}

/// `auto` takes a hardware GPU exactly when one is listed; otherwise the CPU, with a note that
/// says so (a software driver is never chosen by `auto`).
#[test]
fn auto_uses_a_hardware_gpu_or_the_cpu_with_a_note() {
    if std::env::var_os(fluidcast_backend::ADAPTER_ENV).is_some() {
        eprintln!("FLUIDCAST_ADAPTER is set: auto takes the named adapter");
        return;
    }
    let adapters = list_adapters();
    eprintln!("adapters: {adapters:?}");
    let hardware = adapters.iter().any(|a| !a.contains("software"));
    let r = Renderer::open(Backend::Auto, None).unwrap();
    eprintln!("auto: {} {:?}", r.device(), r.note());
    assert_eq!(r.gpu().is_some(), hardware, "{}", r.device());
    if let Some(g) = r.gpu() {
        assert!(!g.is_software(), "{}", g.adapter);
        assert_eq!(format!("GPU: {}", adapters[0]), r.device());
    } else {
        let note = r.note().expect("auto fell back without a note");
        assert!(note.contains("rendering on the CPU"), "{note}");
        assert!(r.device().starts_with("CPU"));
    }
}

fn require_gpu() -> bool {
    std::env::var("FLUIDCAST_REQUIRE_GPU").as_deref() == Ok("1")
}

#[test]
fn gpu_backend_renders_what_the_cpu_renders_and_adapters_go_by_name() {
    let r = match Renderer::open(Backend::Gpu, None) {
        Ok(r) => r,
        Err(e) if !require_gpu() => return eprintln!("SKIPPED: {e}"),
        Err(e) => panic!("FLUIDCAST_REQUIRE_GPU=1 but: {e}"),
    };
    let (p, tf, cam, prm) = scene();
    let g = draw(&r, &p, &cam, &tf, &prm).unwrap();
    let c = draw(&Renderer::cpu(), &p, &cam, &tf, &prm).unwrap();
    let (cmp, _) = fluidcast_image::compare(&c.image, &g.image, 1e-3).unwrap();
    assert!(cmp.max_abs <= 1e-3, "GPU vs CPU max abs {}", cmp.max_abs);
    assert!(r.device().starts_with("GPU: "), "{}", r.device());
    // The adapter it opened, by a part of its name, in another case.
    let adapter = r.gpu().unwrap().adapter.clone();
    let part = adapter.split_whitespace().next().unwrap().to_uppercase();
    let named = Renderer::open(Backend::Gpu, Some(&part)).unwrap();
    assert_eq!(named.gpu().unwrap().adapter, adapter);
    // A name no adapter has: an error that lists the adapters.
    match Renderer::open(Backend::Gpu, Some("no-such-adapter-xyz")) {
        Err(BackendError::Gpu(GpuError::NoSuchAdapter(n, list))) => {
            assert_eq!(n, "no-such-adapter-xyz");
            assert!(list.contains(&adapter), "{list}");
        }
        other => panic!(
            "expected NoSuchAdapter, got {:?}",
            other.map(|r| r.device())
        ),
    }
    // auto with a named adapter takes it, software or not.
    let auto = Renderer::open(Backend::Auto, Some(&part)).unwrap();
    assert_eq!(auto.gpu().unwrap().adapter, adapter);
}

/// Opaque iso-surfaces over the adaptive volume: at full rate the backend's image is the
/// reference renderer's mixed rendering (the volume stopped at the first surface, as the
/// reference composites it) up to the minimum transmittance (1e-4: where the volume in front
/// is that opaque the reference stops before the surface, the overlay still adds it behind),
/// Z and normals are the surfaces'; at E_I = 0.004, strict, within E_I of it; the GPU's volume (lavapipe here) within 1e-3 of the CPU's. Surfaces alone are
/// the reference's surfaces exactly; translucent surfaces over the volume are refused.
#[test]
fn surfaces_stop_the_adaptive_volume_as_the_reference_does() {
    use fluidcast_render::{render_reference, Surfaces};
    use std::sync::Arc;
    let (p, tf, cam, prm) = scene();
    let with = |volume: bool, opacity: f64, tolerance: Option<f64>| {
        let mut q = RenderParams {
            surfaces: Some(Arc::new(Surfaces {
                values: vec![0.8],
                volume,
                opacity,
                ..Default::default()
            })),
            ..prm.clone()
        };
        q.adaptive.tolerance = tolerance;
        q
    };
    let cpu = Renderer::cpu();
    let want = render_reference(&p, &cam, &tf, &with(true, 1.0, None))
        .unwrap()
        .0;
    assert!(
        want.depth.iter().filter(|z| z.is_finite()).count() > 300,
        "surfaces shown"
    );
    let got = draw(&cpu, &p, &cam, &tf, &with(true, 1.0, None)).unwrap();
    let min_t = prm.min_transmittance as f32;
    let (c, _) = fluidcast_image::compare(&want, &got.image, 1e-5).unwrap();
    assert!(
        c.max_abs <= min_t as f64 + 1e-6,
        "full rate vs reference: {}",
        c.max_abs
    );
    for (k, (a, b)) in want.depth.iter().zip(&got.image.depth).enumerate() {
        let opaque_in_front = got.image.rgba[k][3] >= 1.0 - min_t;
        assert!(
            a == b || (a.is_infinite() && opaque_in_front),
            "Z {k}: {a} vs {b}"
        );
    }
    let names: Vec<&str> = got.image.aovs.iter().map(|a| a.0.as_str()).collect();
    assert!(
        names.starts_with(&["normal_x", "normal_y", "normal_z"]),
        "{names:?}"
    );
    assert!(got.stats.stage("surfaces").is_some() && got.stats.plan.is_some());
    let mut strict = with(true, 1.0, Some(0.004));
    strict.adaptive = strict.adaptive.strict();
    let adapted = draw(&cpu, &p, &cam, &tf, &strict).unwrap();
    let (c, _) = fluidcast_image::compare(&want, &adapted.image, 0.004).unwrap();
    assert!(
        c.max_abs <= 0.004 + min_t as f64 + 1e-6,
        "strict E_I 0.004 vs reference: {}",
        c.max_abs
    );
    let only = with(false, 1.0, None);
    let a = draw(&cpu, &p, &cam, &tf, &only).unwrap();
    let b = render_reference(&p, &cam, &tf, &only).unwrap().0;
    assert_eq!(a.image.rgba, b.rgba);
    let e = draw(&cpu, &p, &cam, &tf, &with(true, 0.5, None)).unwrap_err();
    assert!(
        e.to_string()
            .contains("opaque surfaces over the volume only"),
        "{e}"
    );
    match Renderer::open(Backend::Gpu, None) {
        Ok(gpu) => {
            let g = draw(&gpu, &p, &cam, &tf, &with(true, 1.0, None)).unwrap();
            let (c, _) = fluidcast_image::compare(&got.image, &g.image, 1e-3).unwrap();
            assert!(c.max_abs <= 1e-3, "GPU vs CPU with surfaces: {}", c.max_abs);
        }
        Err(e) if !require_gpu() => eprintln!("SKIPPED (GPU part): {e}"),
        Err(e) => panic!("FLUIDCAST_REQUIRE_GPU=1 but: {e}"),
    }
}

/// Adaptive sampling is skipped where its own work would cost more than it can be counted on
/// saving (here the cloud seen from 40 times further: its particles a pixel or two wide): the
/// render says so and is the full-rate image; with the probe off (`--no-probe`) the plan runs
/// anyway; where the particles are wide enough, it runs.
#[test]
fn adaptivity_is_skipped_where_it_cannot_pay() {
    let (p, tf, cam, prm) = scene();
    let r = Renderer::cpu();
    let skipped = |x: &fluidcast_backend::Rendered| {
        x.notes
            .iter()
            .any(|n| n.contains("adaptive sampling skipped"))
    };
    let far = Camera {
        position: cam.position.map(|c| 40.0 * c),
        ..cam.clone()
    };
    let mut full = prm.clone();
    full.adaptive.tolerance = None;
    let a = draw(&r, &p, &far, &tf, &prm).unwrap();
    assert!(skipped(&a), "{:?}", a.notes);
    let b = draw(&r, &p, &far, &tf, &full).unwrap();
    assert!(!skipped(&b));
    assert_eq!(a.image.rgba, b.image.rgba);
    assert!(
        a.image.rgba.iter().any(|px| px[3] > 0.0),
        "the far cloud is drawn"
    );
    let mut no_probe = prm.clone();
    no_probe.adaptive.probe = false;
    let c = draw(&r, &p, &far, &tf, &no_probe).unwrap();
    assert!(!skipped(&c));
    // At 64 × 48 the supports are about 6 pixels in radius, about 1,300 evaluations a
    // particle: more than the plan's own work, less than it can be counted on saving
    // (work::SAVED_SHARE), so skipped too. At 128 × 96 (about 12 pixels) the plan runs.
    let mid = prm.clone();
    let small = draw(&r, &p, &cam, &tf, &mid).unwrap();
    assert!(skipped(&small), "{:?}", small.notes);
    let big = RenderParams {
        width: 128,
        height: 96,
        ..prm.clone()
    };
    let near = draw(&r, &p, &cam, &tf, &big).unwrap();
    assert!(!skipped(&near), "{:?}", near.notes);
}

/// Progressive RBF passes are the device's own: a scene that accumulated passes on the GPU
/// and is then rendered on the CPU (ParaView's Backend switched) shows the CPU's first pass,
/// not the GPU's passes averaged with it, and back on the GPU the GPU's first pass again.
#[test]
fn progressive_passes_do_not_cross_devices() {
    use fluidcast_backend::{March, Marched, RbfOptions, RbfRenderParams, RenderPlan, Scene};
    let r = match Renderer::open(Backend::Gpu, None) {
        Ok(r) => r,
        Err(e) if !require_gpu() => return eprintln!("SKIPPED: {e}"),
        Err(e) => panic!("FLUIDCAST_REQUIRE_GPU=1 but: {e}"),
    };
    let (p, tf, cam, prm) = scene();
    let plan = RenderPlan {
        params: prm,
        march: Some(March {
            field: Marched::Rbf(RbfOptions::default()),
            params: RbfRenderParams::default(),
            progressive_passes: 4,
            time_refit: false,
        }),
        ..Default::default()
    };
    let fresh = |r: &Renderer| {
        let mut s = Scene::new(p.clone(), cam.clone(), tf.clone());
        r.render(&mut s, &plan).unwrap().image.rgba
    };
    let (cpu, gpu) = (Renderer::cpu(), &r);
    let mut scene = Scene::new(p.clone(), cam.clone(), tf.clone());
    let g1 = gpu.render(&mut scene, &plan).unwrap().image.rgba;
    let g2 = gpu.render(&mut scene, &plan).unwrap().image.rgba;
    assert_ne!(g1, g2, "the second GPU render added no pass");
    let c1 = cpu.render(&mut scene, &plan).unwrap().image.rgba;
    assert_eq!(c1, fresh(&cpu), "the CPU render reused the GPU's passes");
    let g1_again = gpu.render(&mut scene, &plan).unwrap().image.rgba;
    assert_eq!(
        g1_again,
        fresh(gpu),
        "the GPU render reused the CPU's passes"
    );
    assert_eq!(g1_again, g1);
}

/// A view whose particle–cell pairs do not fit one of the GPU's buffer bindings (here a
/// binding of three quarters of what they need) renders in screen tiles of fewer particles, to
/// the CPU's image at full rate; it was refused (TooManyPairs).
#[test]
fn views_past_the_gpu_buffers_render_in_tiles() {
    let gpu = match fluidcast_gpu::Gpu::new() {
        Ok(g) => g,
        Err(e) if !require_gpu() => return eprintln!("SKIPPED: {e}"),
        Err(e) => panic!("FLUIDCAST_REQUIRE_GPU=1 but: {e}"),
    };
    let (p, tf, cam, mut prm) = scene();
    (prm.width, prm.height) = (200, 150);
    // At full rate, where the plan (made per tile) cannot change the image.
    prm.adaptive.tolerance = None;
    let whole = draw(&Renderer::with_gpu(gpu), &p, &cam, &tf, &prm).unwrap();
    assert_eq!(whole.stats.tiles, 0);
    let (pairs, cells) = (whole.stats.pairs, whole.stats.cells);
    // Three quarters of the pairs' 4 bytes each; the cells' error bounds (224 bytes each)
    // fit, so the pairs are what does not.
    let limit = 3 * pairs;
    assert!(224 * cells < limit, "{cells} cells, {pairs} pairs");
    let small = fluidcast_gpu::Gpu::new().unwrap().with_binding_limit(limit);
    let tiled = draw(&Renderer::with_gpu(small), &p, &cam, &tf, &prm).unwrap();
    let (tiles, dispatches) = (tiled.stats.tiles, tiled.stats.dispatches);
    assert!(tiles > 1, "{tiles} tiles");
    // Each tile's ray casting dispatches, and traffic, add up.
    assert!(
        dispatches >= tiles as u64,
        "{dispatches} dispatches in {tiles} tiles"
    );
    assert!(tiled.stats.transfers.waits > whole.stats.transfers.waits);
    let cpu = draw(&Renderer::cpu(), &p, &cam, &tf, &prm).unwrap();
    let (c, _) = fluidcast_image::compare(&cpu.image, &tiled.image, 1e-3).unwrap();
    assert!(c.max_abs <= 1e-3, "tiled GPU vs CPU max abs {}", c.max_abs);
}

/// In relaxed mode each screen tile refines only its own pixels: the pixels interpolated over
/// all tiles are at most the image's (each tile estimated the whole image and counted the
/// empty pixels outside it: 1.4 M for this 30,000-pixel view in 139 tiles), and fewer than
/// one render interpolates (pixels at a tile's edge are cast).
#[test]
fn tiles_interpolate_only_their_own_pixels() {
    let (p, tf, cam, mut prm) = scene();
    (prm.width, prm.height) = (200, 150);
    let r = Renderer::cpu();
    let whole = draw(&r, &p, &cam, &tf, &prm).unwrap();
    assert!(
        whole.stats.interpolated > 1000,
        "{}",
        whole.stats.interpolated
    );
    let mut scene = fluidcast_backend::Scene::new(p.clone(), cam.clone(), tf.clone());
    let plan = fluidcast_backend::RenderPlan {
        params: prm.clone(),
        mode: Some(fluidcast_backend::Mode::Adaptive),
        tiles: fluidcast_backend::Tiles {
            count: Some(7),
            budget_bytes: None,
        },
        ..Default::default()
    };
    let t = r.render(&mut scene, &plan).unwrap();
    assert!(t.stats.tiles > 7, "{} tiles", t.stats.tiles);
    let (got, one) = (t.stats.interpolated, whole.stats.interpolated);
    assert!(
        got > 0 && got <= one,
        "{got} pixels interpolated in tiles, {one} in one render"
    );
}

/// A close-up is charged for the particles it shows: zooming k times into a sheet wider than
/// the view makes each particle in view k³ times the work (k² the pixels, k the depth samples)
/// and shows a k²-th of them, so the estimate grows about k-fold, not k³-fold as it did when
/// the particles beside the image counted (a 227k-particle dam break zoomed 4 times at
/// 1024 × 768 was refused for 5.5·10¹⁰ evaluations). Under a limit that the whole view's
/// work times 8 sets, the close-up renders.
#[test]
fn a_close_up_is_charged_for_what_it_shows() {
    let p = fluidcast_testkit::layers(1, 1.0, 0.02);
    let tf = TransferFunction::preset("viridis")
        .unwrap()
        .with_range(-0.5, 1.0)
        .unwrap();
    let whole = Camera {
        position: [0.0, 0.0, 2.0],
        focal_point: [0.0; 3],
        view_up: [0.0, 1.0, 0.0],
        view_angle: 30.0,
        ..Default::default()
    };
    let mut close = whole.clone();
    close.zoom(4.0);
    let prm = RenderParams {
        width: 64,
        height: 48,
        ..Default::default()
    };
    let work = |c: &Camera| fluidcast_backend::work::estimate(&p, c, &prm).unwrap();
    let ratio = work(&close) / work(&whole);
    assert!(
        (2.0..8.0).contains(&ratio),
        "zoom 4 costs {ratio} times the whole view"
    );
    let r = Renderer::open(Backend::Cpu, None).unwrap();
    let mut scene = fluidcast_backend::Scene::new(p.clone(), close, tf);
    let plan = fluidcast_backend::RenderPlan {
        params: prm.clone(),
        mode: Some(fluidcast_backend::Mode::Adaptive),
        work_limit: Some(8.0 * work(&whole)),
        ..Default::default()
    };
    let drawn = r.render(&mut scene, &plan).unwrap();
    assert!(drawn.stats.samples > 0);
    // The same limit still refuses what exceeds it.
    let tight = fluidcast_backend::RenderPlan {
        work_limit: Some(0.5 * work(&scene.camera)),
        ..plan
    };
    let e = r.render(&mut scene, &tight).unwrap_err();
    assert!(e.to_string().contains("kernel evaluations"), "{e}");
}
