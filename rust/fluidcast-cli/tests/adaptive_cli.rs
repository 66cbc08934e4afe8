//! The adaptive renderer's options from the command line, and `fluidcast bench`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;

use std::process::Command;

use common::sample;

/// `fluidcast ARGS`: (success, stdout, stderr).
fn run(args: &[&str]) -> (bool, String, String) {
    let (code, out, err) = common::run(args);
    (code == Some(0), out, err)
}

/// Renders the sample at 64x48 with `extra` options: (success, stderr).
fn try_render(out: &std::path::Path, extra: &[&str]) -> (bool, String) {
    let s = sample();
    let mut args = vec![
        "render",
        s.to_str().unwrap(),
        "--array",
        "velocity:mag",
        "--size",
        "64x48",
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let (ok, _, err) = run(&args);
    (ok, err)
}

fn render(out: &std::path::Path, extra: &[&str]) -> String {
    let (ok, err) = try_render(out, extra);
    assert!(ok, "{extra:?}: {err}");
    err
}

/// (max abs colour difference, max abs depth difference) from `fluidcast compare --json`.
fn compare(a: &std::path::Path, b: &std::path::Path) -> (f64, f64) {
    let (ok, out, err) = run(&[
        "compare",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--json",
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let depth = match &v["depth_max_abs"] {
        serde_json::Value::String(s) if s == "inf" => f64::INFINITY,
        d => d.as_f64().unwrap(),
    };
    (v["max_abs"].as_f64().unwrap(), depth)
}

#[test]
fn modes_agree_within_their_promises() {
    let d = tempfile::tempdir().unwrap();
    let p = |n: &str| d.path().join(n);
    render(&p("ref.exr"), &["--mode", "reference"]);
    render(&p("off.exr"), &["--error-tolerance", "off"]);
    // --no-probe: the adaptive plan runs on this small view, which it would skip by default
    // (its supports are too few pixels wide for the plan to save more than it costs).
    render(
        &p("strict.exr"),
        &["--error-tolerance", "0.004", "--strict", "--no-probe"],
    );
    render(&p("default.png"), &["--aovs", "--no-probe"]);
    render(&p("default.exr"), &["--no-probe"]);
    // The EXRs keep depth: the reference and full rate put it on the same sample plane; the
    // colours agree to single-precision rounding (full rate sums in f32).
    let (colour, depth) = compare(&p("ref.exr"), &p("off.exr"));
    assert!(colour <= 2e-6 && depth == 0.0, "{colour} {depth}");
    assert!(compare(&p("off.exr"), &p("strict.exr")).0 <= 0.004);
    assert!(p("default.plan.png").exists() && p("default.error.png").exists());
    let img = fluidcast_image_channels(&p("default.exr"));
    for c in ["error_bound", "level", "superpixel"] {
        assert!(img.contains(&c.to_string()), "{c} missing from {img:?}");
    }
}

/// Channel names of an EXR (read through `compare`'s reader would drop them; read the
/// header names from the file bytes instead).
fn fluidcast_image_channels(p: &std::path::Path) -> Vec<String> {
    let bytes = std::fs::read(p).unwrap();
    ["error_bound", "level", "superpixel", "R", "Z"]
        .iter()
        .filter(|n| {
            bytes
                .windows(n.len() + 1)
                .any(|w| &w[..n.len()] == n.as_bytes() && w[n.len()] == 0)
        })
        .map(|n| n.to_string())
        .collect()
}

#[test]
fn bad_adaptive_options_are_clear_errors() {
    let d = tempfile::tempdir().unwrap();
    let s = sample();
    let o = d.path().join("o.png");
    for (extra, msg) in [
        (
            vec!["--error-tolerance", "2"],
            "must be a number >= 0 and <= 1",
        ),
        (vec!["--error-tolerance", "fast"], "expected a number"),
        (vec!["--depth-samples", "12"], "power of two"),
        (
            vec!["--bundle", "0"],
            "'--bundle <BUNDLE>': must be a whole number 1..=64",
        ),
        (vec!["--support-radius", "inf"], "must be 0 or a length"),
        (vec!["--support-radius", "-1"], "not -1"),
        (vec!["--relax", "1.5"], "--relax"),
    ] {
        let mut args = vec![
            "render",
            s.to_str().unwrap(),
            "-o",
            o.to_str().unwrap(),
            "--size",
            "32x24",
        ];
        args.extend(extra.iter().copied());
        let (ok, _, err) = run(&args);
        assert!(!ok, "{extra:?} should fail");
        assert!(err.contains(msg), "{extra:?}: {err}");
    }
}

#[test]
fn bench_prints_a_table_and_json() {
    let d = tempfile::tempdir().unwrap();
    let j = d.path().join("b.json");
    let s = sample();
    let (ok, out, err) = run(&[
        "bench",
        s.to_str().unwrap(),
        "--array",
        "velocity:mag",
        "--size",
        "48x36",
        "--views",
        "2",
        "--tolerances",
        "0.004",
        "--json",
        j.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(
        out.contains("reference") && out.contains("off") && out.contains("0.004"),
        "{out}"
    );
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&j).unwrap()).unwrap();
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 3);
    let adaptive = &rows[2];
    assert_eq!(adaptive["views"], 2);
    assert!(adaptive["total_ms"].as_f64().unwrap() > 0.0);
    assert!(adaptive["max_error"].as_f64().unwrap() >= 0.0);
}

#[test]
fn gpu_backend_from_the_command_line() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let s = sample();
    // The reference renderer has no GPU path: a clear error, before any GPU is touched.
    let (ok, _, err) = run(&[
        "render",
        s.to_str().unwrap(),
        "--mode",
        "reference",
        "--backend",
        "gpu",
        "-o",
        dir.join("x.png").to_str().unwrap(),
    ]);
    assert!(!ok && err.contains("adaptive mode only"), "{err}");
    let cpu = dir.join("cpu.exr");
    // --no-probe: the adaptive plan on both, which this small view would skip by default.
    render(&cpu, &["--backend", "cpu", "--no-probe"]);
    let gpu = dir.join("gpu.exr");
    let (ok, err) = try_render(&gpu, &["--backend", "gpu", "--no-probe"]);
    if !ok
        && err.contains("no GPU adapter")
        && std::env::var("FLUIDCAST_REQUIRE_GPU").as_deref() != Ok("1")
    {
        eprintln!("SKIPPED: {err}");
        return;
    }
    assert!(ok, "{err}");
    let (ok, out, err) = run(&[
        "compare",
        cpu.to_str().unwrap(),
        gpu.to_str().unwrap(),
        "--tolerance",
        "0.001",
        "--json",
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let frac = v["frac_above"].as_f64().unwrap();
    let max = v["max_abs"].as_f64().unwrap();
    assert!(frac <= 1e-3 && max <= 0.05, "GPU vs CPU: {out}");
    // auto: the GPU when `info --adapters` lists a hardware one, else the CPU with a note.
    let (ok, out, err) = run(&["info", "--adapters"]);
    assert!(ok, "{err}");
    let hardware = out
        .lines()
        .any(|l| l.starts_with("adapter ") && !l.contains("software"));
    let (ok, err) = try_render(&dir.join("auto.exr"), &["--backend", "auto"]);
    assert!(ok, "{err}");
    if std::env::var_os("FLUIDCAST_ADAPTER").is_none() {
        assert_eq!(err.contains("GPU: "), hardware, "{out}\n{err}");
        assert_eq!(
            err.contains("rendering on the CPU"),
            !hardware,
            "{out}\n{err}"
        );
    }
    // Probing adapters prints nothing of the drivers' own: Mesa's Vulkan drivers have
    // libwayland complain about XDG_RUNTIME_DIR on a machine without a desktop session.
    let o = Command::new(env!("CARGO_BIN_EXE_fluidcast"))
        .args(["info", "--adapters"])
        .env_remove("XDG_RUNTIME_DIR")
        .output()
        .unwrap();
    let noise = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && !noise.contains("XDG_RUNTIME_DIR"),
        "{noise}"
    );
    // An adapter no machine has: an error naming it.
    let (ok, err) = try_render(
        &dir.join("n.exr"),
        &["--backend", "gpu", "--adapter", "no-such-gpu"],
    );
    assert!(!ok && err.contains("'no-such-gpu'"), "{err}");
}

/// An ASCII .vtu of a jittered 6³ lattice of particles at `offset` (spacing 0.1) with the
/// point array `value` = `scale` · i / 8 for the i-th lattice column along x (exact in f32).
fn lattice_vtu(offset: [f32; 3], scale: f32) -> String {
    let (pts, vals) = lattice(offset, scale);
    ascii_vtu(216, &pts, &vals)
}

/// The points and values of [`lattice_vtu`], as ASCII lists.
fn lattice(offset: [f32; 3], scale: f32) -> (String, String) {
    let (mut pts, mut vals) = (String::new(), String::new());
    for i in 0..6 {
        for j in 0..6 {
            for k in 0..6 {
                let x = [i, j, k].map(|c| c as f32 * 0.1);
                let x = [0, 1, 2].map(|c| x[c] + offset[c] + 0.01 * ((i * j + k) % 3) as f32);
                pts += &format!("{} {} {} ", x[0], x[1], x[2]);
                vals += &format!("{} ", scale * i as f32 / 8.0);
            }
        }
    }
    (pts, vals)
}

/// An ASCII .vtu of `n` points (`pts`, x y z each) with the point array `value` (`vals`).
fn ascii_vtu(n: usize, pts: &str, vals: &str) -> String {
    format!(
        r#"<?xml version="1.0"?><VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">
<UnstructuredGrid><Piece NumberOfPoints="{n}" NumberOfCells="0"><PointData>
<DataArray type="Float32" Name="value" format="ascii">{vals}</DataArray></PointData>
<Points><DataArray type="Float32" NumberOfComponents="3" format="ascii">{pts}</DataArray></Points>
<Cells></Cells></Piece></UnstructuredGrid></VTKFile>"#
    )
}

/// A series renders each frame's own particles under the first frame's camera and, with
/// `--range first`, its colour range: frame 1 of the series equals frame 1's file rendered
/// alone with frame 0's saved camera and value range, and differs from frame 0 and from
/// frame 1 under its own automatic view. With `--range frame` frame 1 takes its own range
/// under the series' camera.
#[test]
fn series_frames_render_their_own_particles_under_the_first_frames_view() {
    let d = tempfile::tempdir().unwrap();
    let p = |n: &str| d.path().join(n);
    std::fs::write(p("a.vtu"), lattice_vtu([0.0; 3], 1.0)).unwrap();
    std::fs::write(p("b.vtu"), lattice_vtu([0.2, -0.1, 0.05], 3.0)).unwrap();
    std::fs::write(
        p("s.pvd"),
        r#"<?xml version="1.0"?><VTKFile type="Collection" version="0.1"><Collection>
<DataSet timestep="0" file="a.vtu"/><DataSet timestep="1" file="b.vtu"/></Collection></VTKFile>"#,
    )
    .unwrap();
    let common = [
        "--array",
        "value",
        "--size",
        "40x30",
        "--support-radius",
        "0.2",
        "--opacity-unit-distance",
        "0.2",
    ];
    let render = |input: &str, out: &str, extra: &[&str]| {
        let (i, o) = (p(input), p(out));
        let mut args = vec!["render", i.to_str().unwrap(), "-o", o.to_str().unwrap()];
        args.extend_from_slice(&common);
        args.extend_from_slice(extra);
        let (ok, _, err) = run(&args);
        assert!(ok, "{args:?}: {err}");
    };
    let cam = p("cam.json");
    render(
        "s.pvd",
        "f_%03d.exr",
        &[
            "--frames",
            "0:2",
            "--save-camera",
            cam.to_str().unwrap(),
            "--range",
            "first",
        ],
    );
    render("a.vtu", "a.exr", &[]);
    // a.vtu's values span [0, 5/8]: the range the series keeps.
    let range = "0,0.625";
    render(
        "b.vtu",
        "b_fixed.exr",
        &["--camera", cam.to_str().unwrap(), "--range", range],
    );
    render("b.vtu", "b_auto.exr", &[]);
    render("a.vtu", "a_range.exr", &["--range", range]);
    assert_eq!(compare(&p("f_000.exr"), &p("a.exr")), (0.0, 0.0));
    assert_eq!(compare(&p("a.exr"), &p("a_range.exr")).0, 0.0, "range");
    assert_eq!(compare(&p("f_001.exr"), &p("b_fixed.exr")), (0.0, 0.0));
    assert!(compare(&p("f_001.exr"), &p("f_000.exr")).0 > 0.1);
    assert!(compare(&p("f_001.exr"), &p("b_auto.exr")).0 > 0.1);
    // Each frame its own range: frame 1 as b.vtu alone under the series' camera.
    render(
        "s.pvd",
        "h_%03d.exr",
        &["--frames", "0:2", "--range", "frame"],
    );
    render("b.vtu", "b_cam.exr", &["--camera", cam.to_str().unwrap()]);
    assert_eq!(compare(&p("h_001.exr"), &p("b_cam.exr")), (0.0, 0.0));
    assert!(compare(&p("h_001.exr"), &p("f_001.exr")).0 > 0.1);
    // Read in turn instead of one frame ahead: the same frames.
    render(
        "s.pvd",
        "g_%03d.exr",
        &["--frames", "0:2", "--no-prefetch", "--range", "first"],
    );
    for k in ["000", "001"] {
        let (f, g) = (p(&format!("f_{k}.exr")), p(&format!("g_{k}.exr")));
        assert_eq!(compare(&f, &g), (0.0, 0.0), "frame {k}");
    }
}

/// A `.pvd` that lists two data sets for one time (the parts ParaView shows together) has
/// one frame for that time: it renders as one file holding both parts' particles (written
/// here by hand), with a note saying so; a series of one data set a time has no note.
#[test]
fn the_parts_of_one_time_render_as_one_frame() {
    let d = tempfile::tempdir().unwrap();
    let p = |n: &str| d.path().join(n);
    let (a, b) = (lattice([0.0; 3], 1.0), lattice([0.45, -0.1, 0.05], 3.0));
    std::fs::write(p("a.vtu"), ascii_vtu(216, &a.0, &a.1)).unwrap();
    std::fs::write(p("b.vtu"), ascii_vtu(216, &b.0, &b.1)).unwrap();
    let both = ascii_vtu(432, &(a.0 + &b.0), &(a.1 + &b.1));
    std::fs::write(p("both.vtu"), both).unwrap();
    let render = |input: &str, out: &str, frames: &str| {
        let (i, o) = (p(input), p(out));
        let mut args = vec!["render", i.to_str().unwrap(), "-o", o.to_str().unwrap()];
        args.extend_from_slice(&["--array", "value", "--size", "20x15"]);
        args.extend_from_slice(&["--support-radius", "0.2", "--range", "0,1.875"]);
        if !frames.is_empty() {
            args.extend_from_slice(&["--frames", frames]);
        }
        run(&args)
    };
    std::fs::write(
        p("s.pvd"),
        r#"<VTKFile type="Collection"><Collection><DataSet timestep="0.5" part="0" file="a.vtu"/>
<DataSet timestep="0.5" part="1" file="b.vtu"/><DataSet timestep="1" file="a.vtu"/>
</Collection></VTKFile>"#,
    )
    .unwrap();
    let (ok, _, err) = render("s.pvd", "f_%03d.exr", "0:2");
    assert!(ok, "{err}");
    assert!(
        err.contains("s.pvd lists 2 data sets at t = 0.5 (1 such times)"),
        "{err}"
    );
    let (ok, _, err) = render("both.vtu", "both.exr", "");
    assert!(ok, "{err}");
    assert_eq!(compare(&p("f_000.exr"), &p("both.exr")), (0.0, 0.0));
    // The second time is a.vtu alone: another image.
    assert!(compare(&p("f_001.exr"), &p("both.exr")).0 > 0.01);
    // The appended frame is named as such (a particle index in a message counts in it).
    let pvd = p("s.pvd");
    let (ok, out, err) = run(&["info", pvd.to_str().unwrap()]);
    assert!(ok, "{err}");
    assert!(
        out.contains("2 frames (3 data sets)")
            && out.contains("s.pvd at t = 0.5 (")
            && out.contains("and 1 more data sets)")
            && out.contains("points: 432"),
        "{out}"
    );
    // Two times, so two frames (three data sets).
    let (ok, _, err) = render("s.pvd", "g_%03d.exr", "0:3");
    assert!(ok && err.contains("\n2 frames in"), "{err}");
    std::fs::write(
        p("s.pvd"),
        r#"<VTKFile type="Collection"><Collection><DataSet timestep="0" file="a.vtu"/>
<DataSet timestep="1" file="b.vtu"/></Collection></VTKFile>"#,
    )
    .unwrap();
    let (ok, _, err) = render("s.pvd", "h_%03d.exr", "0:2");
    assert!(ok && !err.contains("data sets at t"), "{err}");
}

/// A damaged frame in the middle of a series, read one frame ahead (`--range first`): the
/// frames before it are written, the error names the file, and nothing after it is
/// rendered. By default (`--range all`) every frame is read for the colour range before the
/// first renders: the same error comes first, saying so, and nothing is written.
#[test]
fn a_damaged_frame_stops_a_prefetched_series_with_its_name() {
    let d = tempfile::tempdir().unwrap();
    let p = |n: &str| d.path().join(n);
    std::fs::write(p("a.vtu"), lattice_vtu([0.0; 3], 1.0)).unwrap();
    std::fs::write(p("b.vtu"), b"<VTKFile type=\"UnstructuredGrid\"><Unstruct").unwrap();
    std::fs::write(p("c.vtu"), lattice_vtu([0.1; 3], 2.0)).unwrap();
    std::fs::write(
        p("s.pvd"),
        r#"<?xml version="1.0"?><VTKFile type="Collection" version="0.1"><Collection>
<DataSet timestep="0" file="a.vtu"/><DataSet timestep="1" file="b.vtu"/>
<DataSet timestep="2" file="c.vtu"/></Collection></VTKFile>"#,
    )
    .unwrap();
    let (i, o) = (p("s.pvd"), p("f_%03d.png"));
    let args = [
        "render",
        i.to_str().unwrap(),
        "-o",
        o.to_str().unwrap(),
        "--array",
        "value",
        "--size",
        "20x15",
        "--support-radius",
        "0.2",
    ];
    let (ok, _, err) = run(&args);
    assert!(!ok);
    assert!(
        err.contains("b.vtu") && err.contains("--range all"),
        "{err}"
    );
    assert!(!p("f_000.png").exists());
    let (ok, _, err) = run(&[&args[..], &["--range", "first"]].concat());
    assert!(!ok);
    assert!(err.contains("b.vtu"), "{err}");
    assert!(p("f_000.png").exists());
    assert!(!p("f_001.png").exists() && !p("f_002.png").exists());
}

/// `--tiles` and `--memory-limit` render the same image in screen tiles, in every mode, and
/// say so; a limit below what the particles already hold is an error with the numbers.
#[test]
fn tiles_and_memory_limits_keep_the_image() {
    let d = tempfile::tempdir().unwrap();
    let p = |n: &str| d.path().join(n);
    for (name, mode) in [
        // (Without the probe, which each tile decides for itself: tiles.rs.)
        ("adaptive", &["--error-tolerance", "0.02", "--no-probe"][..]),
        ("reference", &["--mode", "reference"][..]),
        (
            "grid",
            &["--mode", "perspective-grid", "--grid-cell", "2"][..],
        ),
    ] {
        let whole = p(&format!("{name}.exr"));
        render(&whole, mode);
        let tiled = p(&format!("{name}_tiles.exr"));
        let err = render(&tiled, &[mode, &["--tiles", "5"]].concat());
        assert!(err.contains(" screen tiles"), "{err}");
        assert_eq!(compare(&whole, &tiled), (0.0, 0.0), "{name}");
    }
    // A limit far above what the view needs: one render.
    let whole = p("adaptive.exr");
    let limited = p("limited.exr");
    let err = render(
        &limited,
        &[
            "--error-tolerance",
            "0.02",
            "--no-probe",
            "--memory-limit",
            "64G",
        ],
    );
    assert!(!err.contains("screen tiles"), "{err}");
    assert_eq!(compare(&whole, &limited), (0.0, 0.0));
    let (ok, err) = try_render(&limited, &["--memory-limit", "1M"]);
    assert!(
        !ok && err.contains("--memory-limit 1.0 MiB") && err.contains("raise the limit"),
        "{err}"
    );
    let (ok, err) = try_render(&limited, &["--memory-limit", "lots"]);
    assert!(!ok && err.contains("'lots' is not a size"), "{err}");
}

/// The render line's time is the frame's wall time: never more than the whole process took
/// (it once added the refinement passes on top of the ray cast that holds them: 1.8x the
/// process here).
#[test]
fn the_render_line_says_the_wall_time() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("s.png");
    let t = std::time::Instant::now();
    let (code, err) = common::render_sample(&["--array", "velocity"], &[], &out);
    let wall = t.elapsed().as_secs_f64() * 1e3;
    assert_eq!(code, Some(0), "{err}");
    let line = err.lines().find(|l| l.starts_with("wrote ")).unwrap();
    let ms: f64 = line
        .split(" in ")
        .nth(1)
        .unwrap()
        .split(" ms")
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(
        ms <= wall && ms > 0.3 * wall,
        "{line}: the process took {wall:.1} ms"
    );
}

/// `--orbit 8` writes 8 different views of one file, turned 45° apart about the focal point
/// (the third is `--azimuth 90`); `-o orbit.mp4` encodes them, 8 frames by ffprobe; several
/// views need a pattern or a movie.
#[test]
fn an_orbit_writes_its_views_and_a_movie_holds_them() {
    let d = tempfile::tempdir().unwrap();
    let p = |n: &str| d.path().join(n);
    let opts = ["--array", "velocity", "--size", "64x48"];
    let pattern = p("o_%02d.png");
    let orbit = [&opts[..], &["--orbit", "8"]].concat();
    let (code, err) = common::render_sample(&orbit, &[], &pattern);
    assert_eq!(code, Some(0), "{err}");
    let img = |n: &str| fluidcast_image::Image::read(&p(n)).unwrap();
    let views: Vec<_> = (0..8).map(|k| img(&format!("o_{k:02}.png"))).collect();
    for k in 1..8 {
        assert!(
            common::max_diff(&views[0], &views[k]) > 0.05,
            "view {k} = view 0"
        );
    }
    let turned = [&opts[..], &["--azimuth", "90"]].concat();
    let (code, err) = common::render_sample(&turned, &[], &p("ninety.png"));
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(common::max_diff(&views[2], &img("ninety.png")), 0.0);
    let movie = p("orbit.mp4");
    let (code, err) = common::render_sample(&orbit, &["--fps", "12"], &movie);
    assert_eq!(code, Some(0), "{err}");
    let probe = std::process::Command::new("ffprobe")
        .args(["-v", "error", "-count_frames", "-select_streams", "v:0"])
        .args(["-show_entries", "stream=nb_read_frames", "-of", "csv=p=0"])
        .arg(&movie)
        .output()
        .expect("ffprobe (scripts/setup_system.sh installs ffmpeg)");
    assert_eq!(String::from_utf8_lossy(&probe.stdout).trim(), "8");
    let (code, err) = common::render_sample(&orbit, &[], &p("one.png"));
    assert_ne!(code, Some(0));
    assert!(err.contains("write several views"), "{err}");
}

/// The names users type elsewhere render as fluidcast's own: `--cmap plasma` is `--tf
/// Plasma` (and not Viridis), `--clim` is `--range`, `--background white` and `#000000` are
/// the numbers, `velocity:Magnitude` and `velocity:X` are `:mag` and `:0`.
#[test]
fn colour_maps_and_names_users_know() {
    let d = tempfile::tempdir().unwrap();
    let p = |n: &str| d.path().join(n);
    let img = |args: &[&str], name: &str| {
        let size = ["--size", "48x36"];
        let (code, err) = common::render_sample(&[&size[..], args].concat(), &[], &p(name));
        assert_eq!(code, Some(0), "{args:?}: {err}");
        fluidcast_image::Image::read(&p(name)).unwrap()
    };
    let same = |a: &[&str], b: &[&str]| {
        let (x, y) = (img(a, "a.png"), img(b, "b.png"));
        assert_eq!(common::max_diff(&x, &y), 0.0, "{a:?} vs {b:?}");
    };
    let v = ["--array", "velocity"];
    same(
        &[&v[..], &["--cmap", "plasma"]].concat(),
        &[&v[..], &["--tf", "Plasma"]].concat(),
    );
    let plasma = img(&[&v[..], &["--cmap", "plasma"]].concat(), "p.png");
    assert!(
        common::max_diff(&plasma, &img(&v, "v.png")) > 0.1,
        "plasma is not viridis"
    );
    same(
        &[&v[..], &["--clim", "0,2"]].concat(),
        &[&v[..], &["--range", "0,2"]].concat(),
    );
    same(&[&v[..], &["--background", "white"]].concat(), &v);
    same(
        &[&v[..], &["--background", "#000000"]].concat(),
        &[&v[..], &["--background", "0,0,0"]].concat(),
    );
    same(
        &["--array", "velocity:Magnitude"],
        &["--array", "velocity:mag"],
    );
    same(&["--array", "velocity:X"], &["--array", "velocity:0"]);
}

/// `render --help` is grouped under headings users look for, and the sampling plan's expert
/// switches sit under their own heading, not beside everyday options.
#[test]
fn render_help_is_grouped_with_expert_switches_apart() {
    let (ok, out, _) = run(&["render", "--help"]);
    assert!(ok);
    let headings = [
        "Output, series and movies:",
        "Particles:",
        "Camera, colour and opacity:",
        "Quality and backend:",
        "Expert: the sampling plan:",
        "Surfaces:",
        "Large data:",
        "RBF volumes and shadows:",
    ];
    let at: Vec<usize> = headings
        .iter()
        .map(|h| {
            out.find(&format!("\n{h}\n"))
                .unwrap_or_else(|| panic!("{h} missing"))
        })
        .collect();
    assert!(at.windows(2).all(|w| w[0] < w[1]), "headings out of order");
    let (expert, next) = (at[4], at[5]);
    for flag in ["--bundle", "--relax", "--no-probe", "--depth-samples"] {
        let k = out
            .find(&format!("\n      {flag}"))
            .unwrap_or_else(|| panic!("{flag}"));
        assert!(
            expert < k && k < next,
            "{flag} is not under the expert heading"
        );
    }
    for flag in ["--array", "--camera", "--orbit", "--error-tolerance"] {
        let k = out
            .find(&format!("\n      {flag}"))
            .unwrap_or_else(|| panic!("{flag}"));
        assert!(k < expert || k > next, "{flag} is under the expert heading");
    }
}
