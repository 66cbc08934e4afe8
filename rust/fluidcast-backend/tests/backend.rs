//! The backend API: names, `auto`'s choice against the adapters present, adapters by name,
//! and one render call that gives the CPU renderer's image on the CPU and a matching one on
//! the GPU.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
use fluidcast_backend::{list_adapters, Backend, BackendError, GpuError, Renderer};
use fluidcast_render::{render_adaptive, RenderParams};
use fluidcast_view::{Camera, TransferFunction};

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
    let a = r.render(&p, None, &cam, &tf, &prm).unwrap();
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
    let g = r.render(&p, None, &cam, &tf, &prm).unwrap();
    let c = Renderer::cpu().render(&p, None, &cam, &tf, &prm).unwrap();
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
