//! `fluidcast render --iso` on real data against `fluidcast probe`: the surface depth in the
//! EXR's Z channel is where the probed colour field first crosses the iso value along that
//! pixel's ray.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;

use std::path::Path;

use fluidcast_image::Image;
use fluidcast_view::Camera;

/// `fluidcast ARGS`, which must succeed: its stderr.
fn fluidcast(args: &[&str]) -> String {
    let (code, _, err) = common::run(args);
    assert_eq!(code, Some(0), "fluidcast {args:?}: {err}");
    err
}

/// The probe CSV's `shepard` column (Σ V W: the colour field), one value per line.
fn shepard_column(csv: &Path) -> Vec<f64> {
    let text = std::fs::read_to_string(csv).unwrap();
    text.lines()
        .skip(1)
        .map(|l| l.split(',').nth(4).unwrap().parse().unwrap())
        .collect()
}

/// On the SPlisHSPlasH double dam break, at every 23rd pixel that shows a surface and along
/// the ray of each, the colour field probed at twice the renderer's depth samples (same
/// logarithmic spacing, `fluidcast probe`, which shares no ray code with the renderer) first
/// crosses 0.5 within a quarter of a depth sample of the EXR's Z (the issue asks for one; a
/// Z taken at the nearest sample, unrefined, would be off by up to half a sample), at 97 % of
/// them or more (measured: all, the worst 0.09 samples off).
#[test]
fn surface_depth_is_the_first_crossing_of_the_probed_field() {
    let Some(file) =
        fluidcast_testkit::shared_data("splash_doubledambreak/DoubleDamBreak_r0.0125_0011.vtu")
    else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (exr, cam, stats) = (
        dir.path().join("s.exr"),
        dir.path().join("cam.json"),
        dir.path().join("s.json"),
    );
    let (w, h) = (160u32, 120u32);
    fluidcast(&[
        "render",
        file.to_str().unwrap(),
        "--array",
        "velocity:mag",
        "--iso",
        "0.5",
        "--azimuth",
        "30",
        "--elevation",
        "30",
        "--size",
        "160x120",
        "--save-camera",
        cam.to_str().unwrap(),
        "--stats",
        stats.to_str().unwrap(),
        "-o",
        exr.to_str().unwrap(),
    ]);
    let img = Image::read(&exr).unwrap();
    assert!(
        img.aovs.iter().any(|a| a.0 == "normal_x"),
        "normals in the EXR"
    );
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    let (near, far) = (s["near"].as_f64().unwrap(), s["far"].as_f64().unwrap());
    let n = s["depth_samples_per_ray"].as_u64().unwrap() as usize;
    let camera = Camera::from_json(&std::fs::read_to_string(&cam).unwrap()).unwrap();
    let frame = camera.frame(w, h).unwrap();
    let surfaced: Vec<(u32, u32)> = (0..h)
        .flat_map(|j| (0..w).map(move |i| (i, j)))
        .filter(|&(i, j)| img.depth[img.index(i, j)].is_finite())
        .step_by(11)
        .collect();
    assert!(surfaced.len() > 100, "{} pixels sampled", surfaced.len());
    // Twice the renderer's samples per ray, on the same logarithmic spacing.
    let depths: Vec<f64> = (0..=2 * n)
        .map(|k| near * (far / near).powf(k as f64 / (2 * n) as f64))
        .collect();
    let mut points = String::from("x,y,z\n");
    for &(i, j) in &surfaced {
        let (o, d) = frame.ray(i, j);
        for z in &depths {
            let x = o + d * *z;
            points += &format!("{:.17e},{:.17e},{:.17e}\n", x.x, x.y, x.z);
        }
    }
    let (pts, out) = (dir.path().join("p.csv"), dir.path().join("v.csv"));
    std::fs::write(&pts, points).unwrap();
    fluidcast(&[
        "probe",
        file.to_str().unwrap(),
        "--array",
        "velocity:mag",
        "--points",
        pts.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    let colour = shepard_column(&out);
    assert_eq!(colour.len(), surfaced.len() * depths.len());
    let step = (far / near).powf(1.0 / n as f64) - 1.0; // one depth sample, relative to depth
    let mut agree = 0;
    let mut worst = 0.0f64;
    for (r, &(i, j)) in surfaced.iter().enumerate() {
        let f = &colour[r * depths.len()..(r + 1) * depths.len()];
        let z = img.depth[img.index(i, j)] as f64;
        let first = (1..f.len()).find(|&k| (f[k - 1] >= 0.5) != (f[k] >= 0.5));
        let Some(k) = first else {
            panic!("pixel {i},{j}: Z {z} but the probed field never crosses 0.5");
        };
        // Linear interpolation inside the probe's bracket.
        let t = (0.5 - f[k - 1]) / (f[k] - f[k - 1]);
        let zp = depths[k - 1] + t * (depths[k] - depths[k - 1]);
        worst = worst.max((z - zp).abs() / (step * zp));
        if (z - zp).abs() <= 0.25 * step * zp {
            agree += 1;
        } else {
            eprintln!(
                "pixel {i},{j}: Z {z}, probe crossing {zp} ({:.2} samples)",
                (z - zp) / (step * zp)
            );
        }
    }
    eprintln!(
        "{agree} of {} pixels within a quarter depth sample of the probed crossing (worst {worst:.3} samples)",
        surfaced.len()
    );
    assert!(
        agree as f64 >= 0.97 * surfaced.len() as f64,
        "{agree} of {}",
        surfaced.len()
    );
}

/// Surfaces are refused by the renderers that do not draw them, with the way out named; bad
/// iso options are errors before any file is read.
#[test]
fn iso_options_are_checked_and_refused_where_not_drawn() {
    let sample = common::sample();
    let sample = sample.to_str().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.png");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "render",
            sample,
            "--size",
            "32x24",
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let (code, _, err) = common::run(&args);
        (code, err)
    };
    let cases: [(&[&str], &str); 8] = [
        (
            &["--shade-volume", "--mode", "adaptive"],
            "adaptive grid renderer does not draw a shaded volume",
        ),
        (&["--shade-volume", "--diffuse", "-1"], "diffuse -1"),
        (
            &[
                "--iso",
                "0.5",
                "--mode",
                "adaptive",
                "--volume",
                "--iso-opacity",
                "0.5",
            ],
            "adaptive grid renderer draws opaque surfaces over the volume only",
        ),
        (
            &["--shade-volume", "--backend", "gpu"],
            "GPU backend does not draw a shaded volume",
        ),
        (&["--iso", "0.5", "--iso-opacity", "0"], "opacity 0"),
        (&["--iso", "0.5", "--light", "0,0,0"], "light direction"),
        (&["--iso", "0.5", "--iso-field", "nosuch"], "nosuch"),
        (&["--iso", "0.5", "--shading", "maybe"], "--shading 'maybe'"),
    ];
    for (extra, want) in cases {
        let (code, err) = run(extra);
        assert_eq!(code, Some(1), "{extra:?}: {err}");
        assert!(err.contains(want), "{extra:?}: {err}");
    }
    let (code, err) = run(&["--shade-volume", "--array", "velocity", "--light", "1,0,0"]);
    assert_eq!(code, Some(0), "{err}");
    let (code, err) = run(&["--iso", "0.5", "--volume", "--mode", "adaptive"]);
    assert_eq!(code, Some(0), "{err}");
    let (code, err) = run(&[
        "--iso",
        "0.5,0.8",
        "--iso-field",
        "velocity:mag",
        "--array",
        "density",
        "--volume",
        "--light",
        "1,1,0",
    ]);
    assert_eq!(code, Some(0), "{err}");
}

/// Iso-surfaces with the adaptive mode asked for say who draws what (the exact caster the
/// surfaces, the adaptive renderer the volume), instead of rendering in silence; without a
/// mode the note says the reference ray caster was chosen.
#[test]
fn surfaces_in_the_adaptive_mode_are_noted() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.png");
    let sample = common::sample();
    let args = |extra: &[&'static str]| {
        let mut a = vec![sample.to_str().unwrap(), "-o", out.to_str().unwrap()];
        a.extend_from_slice(&["--size", "32x24", "--iso", "0.5"]);
        a.extend_from_slice(extra);
        a
    };
    let render = |extra: &[&'static str]| {
        let mut a = vec!["render"];
        a.extend(args(extra));
        fluidcast(&a)
    };
    let err = render(&["--mode", "adaptive"]);
    assert!(
        err.contains("note: --iso: iso-surfaces are found exactly along each ray on the CPU"),
        "{err}"
    );
    let err = render(&[]);
    assert!(
        err.contains("note: --iso: rendering with the reference ray caster"),
        "{err}"
    );
}

/// `--iso 0.5 --backend gpu` finds the surfaces on the GPU: the note says so, the stats
/// time the GPU's surface walk (`gpu_surfaces_ms` where the adapter has timestamps, and its
/// dispatches), and the image is the CPU's within 2/255 with Z within one depth sample. With
/// `--volume` the GPU's adaptive volume in front of them matches too.
#[test]
fn gpu_backend_finds_the_surfaces_itself() {
    let dir = tempfile::tempdir().unwrap();
    let sample = common::sample();
    let path = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let render = |extra: &[&str], out: &str| {
        let mut a = vec!["render", sample.to_str().unwrap(), "-o", out];
        a.extend_from_slice(&["--size", "120x90", "--iso", "0.5"]);
        a.extend_from_slice(extra);
        common::run(&a)
    };
    let (gpu, stats) = (path("gpu.exr"), path("gpu.json"));
    let (code, _, err) = render(&["--backend", "gpu", "--stats", &stats], &gpu);
    if code != Some(0)
        && err.contains("no GPU adapter")
        && std::env::var("FLUIDCAST_REQUIRE_GPU").as_deref() != Ok("1")
    {
        return eprintln!("SKIPPED: {err}");
    }
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("note: --iso: iso-surfaces are found exactly along each ray on the GPU"),
        "{err}"
    );
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    assert!(s["timings"]["surfaces_ms"].as_f64().is_some(), "{s}");
    assert!(s["dispatches"].as_u64().unwrap() >= 1, "{s}");
    let cpu = path("cpu.exr");
    let (code, _, err) = render(&["--backend", "cpu"], &cpu);
    assert_eq!(code, Some(0), "{err}");
    let (c, g) = (
        Image::read(Path::new(&cpu)).unwrap(),
        Image::read(Path::new(&gpu)).unwrap(),
    );
    assert!(
        common::max_diff(&c, &g) <= 2.0 / 255.0,
        "{}",
        common::max_diff(&c, &g)
    );
    let drawn = c.depth.iter().filter(|z| z.is_finite()).count();
    assert!(drawn > 1000, "{drawn} pixels show a surface");
    // Logarithmic samples: one step at depth z is z ((far/near)^(1/N) - 1).
    let (near, far) = (s["near"].as_f64().unwrap(), s["far"].as_f64().unwrap());
    let n = s["depth_samples_per_ray"].as_f64().unwrap();
    for (a, b) in c.depth.iter().zip(&g.depth) {
        assert_eq!(a.is_finite(), b.is_finite());
        if a.is_finite() {
            let step = f64::from(*a) * ((far / near).powf(1.0 / n) - 1.0);
            assert!(f64::from((a - b).abs()) <= step, "Z {a} vs {b}");
        }
    }
    let (gv, cv) = (path("gv.exr"), path("cv.exr"));
    let (code, _, err) = render(&["--backend", "gpu", "--volume"], &gv);
    assert_eq!(code, Some(0), "{err}");
    let (code, _, err) = render(&["--backend", "cpu", "--mode", "adaptive", "--volume"], &cv);
    assert_eq!(code, Some(0), "{err}");
    let (c, g) = (
        Image::read(Path::new(&cv)).unwrap(),
        Image::read(Path::new(&gv)).unwrap(),
    );
    assert!(
        common::max_diff(&c, &g) <= 2.0 / 255.0,
        "{}",
        common::max_diff(&c, &g)
    );
}
