//! Every file in ../shared/data renders; the encodings of DoubleDamBreak frame 0011 give
//! identical images.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;

use std::path::{Path, PathBuf};

/// `../shared/data/` beside the repository (see `fluidcast_testkit::shared_data`).
fn shared(rel: &str) -> Option<PathBuf> {
    fluidcast_testkit::shared_data(rel)
}

fn render(input: &Path, out: &Path, extra: &[&str]) {
    let (i, o) = (input.to_str().unwrap(), out.to_str().unwrap());
    let mut args = vec!["render", i, "-o", o, "--size", "96x72"];
    args.extend_from_slice(extra);
    let (code, _, err) = common::run(&args);
    assert_eq!(code, Some(0), "{}: {err}", input.display());
}

#[test]
fn every_shared_file_renders() {
    let Some(root) = shared("") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let mut n = 0;
    for sub in ["splash_doubledambreak", "pysph_dambreak3d"] {
        for f in std::fs::read_dir(root.join(sub)).unwrap() {
            let f = f.unwrap().path();
            if !matches!(
                f.extension().and_then(|e| e.to_str()),
                Some("vtu" | "vtp" | "pvd")
            ) {
                continue;
            }
            let out = dir.path().join(format!("{n}.exr"));
            // PySPH files carry a per-particle smoothing length h (Wendland C2, H = 2h).
            let extra: &[&str] = if sub == "pysph_dambreak3d" {
                &[
                    "--array",
                    "p",
                    "--radius-array",
                    "h",
                    "--radius-scale",
                    "2",
                    "--kernel",
                    "wendland-c2",
                ]
            } else {
                &["--array", "velocity:mag"]
            };
            render(&f, &out, extra);
            let img = fluidcast_image::Image::read(&out).unwrap();
            assert!(
                img.rgba.iter().any(|p| p[3] > 0.01),
                "{} rendered empty",
                f.display()
            );
            n += 1;
        }
    }
    assert!(n >= 20);
}

#[test]
fn double_dam_break_encodings_give_identical_images() {
    let Some(d) = shared("splash_doubledambreak") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let mut images = Vec::new();
    for (i, name) in [
        "DoubleDamBreak_r0.0125_0011.vtu",
        "DoubleDamBreak_r0.0125_0011.vtp",
        "DoubleDamBreak_r0.0125_0011_raw.vtu",
        "DoubleDamBreak_r0.0125_0011_raw.vtp",
        "DoubleDamBreak_r0.0125_0011_ascii.vtu",
    ]
    .iter()
    .enumerate()
    {
        let out = dir.path().join(format!("{i}.exr"));
        render(
            &d.join(name),
            &out,
            &[
                "--array",
                "velocity:mag",
                "--azimuth",
                "30",
                "--elevation",
                "25",
            ],
        );
        images.push(fluidcast_image::Image::read(&out).unwrap());
    }
    for img in &images[1..] {
        assert_eq!(img, &images[0]);
    }
}

/// The names of the files in `dir` that start with `prefix`, sorted.
fn names_starting(dir: &Path, prefix: &str) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .filter(|n| n.starts_with(prefix))
        .collect();
    v.sort();
    v
}

/// Distinct colours among the drawn (not white) pixels of a PNG.
fn colours(png: &Path) -> usize {
    let img = fluidcast_image::Image::read(png).unwrap();
    let mut seen: Vec<[u8; 3]> = img
        .rgba
        .iter()
        .map(|p| [0, 1, 2].map(|k| (p[k] * 255.0).round() as u8))
        .filter(|c| *c != [255; 3])
        .collect();
    seen.sort_unstable();
    seen.dedup();
    seen.len()
}

/// The double dam break series starts at rest (|v| constant): by default its colour range
/// covers every frame, so frames 1–9 are each the file rendered alone with that range under
/// the series' camera, and keep their colours; `--range first` saturates them (with a
/// warning), and `--range frame` gives each frame its own range.
#[test]
fn a_series_range_covers_every_frame() {
    let Some(pvd) = shared("splash_doubledambreak/DoubleDamBreak_r0.0125.pvd") else {
        return;
    };
    let d = tempfile::tempdir().unwrap();
    let p = |n: &str| d.path().join(n);
    let cam = p("cam.json");
    let (c, s) = (cam.to_str().unwrap(), p("f_%02d.png"));
    // The opacity unit distance given (else the series keeps the first frame's, and a file
    // alone takes its own).
    let args = [
        "render",
        pvd.to_str().unwrap(),
        "-o",
        s.to_str().unwrap(),
        "--size",
        "96x72",
        "--opacity-unit-distance",
        "0.05",
    ];
    let (code, _, err) =
        common::run(&[&args[..], &["--array", "velocity:mag", "--save-camera", c]].concat());
    assert_eq!(code, Some(0), "{err}");
    let note = err
        .lines()
        .find(|l| l.starts_with("note: colour range ["))
        .expect(&err);
    let range: Vec<f64> = note["note: colour range [".len()..]
        .split(']')
        .next()
        .unwrap()
        .split(", ")
        .map(|v| v.parse().unwrap())
        .collect();
    let range = format!("{:?},{:?}", range[0], range[1]);
    let files = fluidcast_io::read_collection(&pvd).unwrap();
    let files: Vec<PathBuf> = files.steps().map(|s| s[0].file.clone()).collect();
    assert_eq!(files.len(), 10);
    let first = p("g_%02d.png");
    let (code, _, err) = common::run(&[
        "render",
        pvd.to_str().unwrap(),
        "-o",
        first.to_str().unwrap(),
        "--size",
        "96x72",
        "--array",
        "velocity:mag",
        "--range",
        "first",
    ]);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains("--range all (the default) covers every frame"),
        "{err}"
    );
    for (k, file) in files.iter().enumerate().skip(1) {
        let alone = p(&format!("alone_{k}.png"));
        render(
            file,
            &alone,
            &[
                "--array",
                "velocity:mag",
                "--camera",
                c,
                "--range",
                &range,
                "--opacity-unit-distance",
                "0.05",
            ],
        );
        let series = p(&format!("f_{k:02}.png"));
        let (a, b) = (
            fluidcast_image::Image::read(&series).unwrap(),
            fluidcast_image::Image::read(&alone).unwrap(),
        );
        assert_eq!(common::max_diff(&a, &b), 0.0, "frame {k}");
        if k >= 3 {
            // In motion: many colours under the series' range, fewer where the first
            // frame's range saturates them.
            let (all, sat) = (colours(&series), colours(&p(&format!("g_{k:02}.png"))));
            assert!(
                all > 100 && all > 2 * sat,
                "frame {k}: {all} colours, {sat} with --range first"
            );
        }
    }
}

/// `--frames 0:10:3` writes frames 0, 3, 6 and 9 as out_0000 to out_0003 (ffmpeg's %04d input
/// stops at the first gap), each the frame it stands for.
#[test]
fn a_stepped_series_is_numbered_without_gaps() {
    let Some(pvd) = shared("splash_doubledambreak/DoubleDamBreak_r0.0125.pvd") else {
        return;
    };
    let d = tempfile::tempdir().unwrap();
    let p = |n: &str| d.path().join(n);
    let (out, cam) = (p("out_%04d.png"), p("cam.json"));
    let c = cam.to_str().unwrap();
    let options = [
        "--array",
        "velocity:mag",
        "--range",
        "0,4",
        "--opacity-unit-distance",
        "0.05",
    ];
    let stepped = ["--frames", "0:10:3", "--save-camera", c];
    render(&pvd, &out, &[&options[..], &stepped].concat());
    let written = names_starting(d.path(), "out_");
    let want = [
        "out_0000.png",
        "out_0001.png",
        "out_0002.png",
        "out_0003.png",
    ];
    assert_eq!(written, want);
    // out_0002 is frame 6: the same as frames 6..7 alone under the same camera.
    let six = ["--frames", "6:7", "--camera", c];
    render(&pvd, &p("six_%04d.png"), &[&options[..], &six].concat());
    let (a, b) = (
        fluidcast_image::Image::read(&p("out_0002.png")).unwrap(),
        fluidcast_image::Image::read(&p("six_0000.png")).unwrap(),
    );
    assert_eq!(common::max_diff(&a, &b), 0.0);
}

/// Numbered files without a `.pvd` are a series, in natural order, whether named by a glob,
/// a printf pattern or one by one: three frames, the third `_10` (not `_2`).
#[test]
fn numbered_files_without_a_pvd_are_a_series() {
    let Some(dir) = shared("splash_doubledambreak") else {
        return;
    };
    let d = tempfile::tempdir().unwrap();
    let p = |n: &str| d.path().join(n);
    for (k, src) in [(1, "0003"), (2, "0006"), (10, "0009")] {
        let from = dir.join(format!("DoubleDamBreak_r0.0125_{src}.vtu"));
        std::fs::copy(from, p(&format!("PartFluid_{k}.vtu"))).unwrap();
    }
    let cam = p("cam.json");
    let c = cam.to_str().unwrap();
    let fixed = [
        "--array",
        "velocity:mag",
        "--range",
        "0,4",
        "--opacity-unit-distance",
        "0.05",
    ];
    let glob = p("PartFluid_*.vtu");
    let saved = [&fixed[..], &["--save-camera", c]].concat();
    render(&glob, &p("g_%02d.png"), &saved);
    let names = |prefix: &str| names_starting(d.path(), prefix);
    assert_eq!(names("g_"), ["g_00.png", "g_01.png", "g_02.png"]);
    let with_cam = [&fixed[..], &["--camera", c]].concat();
    render(&p("PartFluid_10.vtu"), &p("ten.png"), &with_cam);
    let img = |n: &str| fluidcast_image::Image::read(&p(n)).unwrap();
    assert_eq!(common::max_diff(&img("g_02.png"), &img("ten.png")), 0.0);
    assert!(common::max_diff(&img("g_01.png"), &img("ten.png")) > 0.1);
    // A printf pattern, and the files one by one: the same frames.
    render(&p("PartFluid_%d.vtu"), &p("f_%02d.png"), &with_cam);
    let one_by_one = ["PartFluid_1.vtu", "PartFluid_2.vtu", "PartFluid_10.vtu"].map(p);
    let (o, out) = (one_by_one, p("h_%02d.png"));
    let mut args = vec!["render"];
    args.extend(o.iter().map(|f| f.to_str().unwrap()));
    args.extend(["-o", out.to_str().unwrap(), "--size", "96x72"]);
    args.extend_from_slice(&with_cam);
    let (code, _, err) = common::run(&args);
    assert_eq!(code, Some(0), "{err}");
    for k in ["00", "01", "02"] {
        let g = img(&format!("g_{k}.png"));
        assert_eq!(
            common::max_diff(&img(&format!("f_{k}.png")), &g),
            0.0,
            "{k}"
        );
        assert_eq!(
            common::max_diff(&img(&format!("h_{k}.png")), &g),
            0.0,
            "{k}"
        );
    }
}

/// `info` on PySPH's frame (per-particle `h`, no `support_radius`) suggests the radius array,
/// not a spacing-based radius; on SPlisHSPlasH's it reports the field data.
#[test]
fn info_suggests_the_radius_array_a_file_has() {
    let Some(pysph) = shared("pysph_dambreak3d/dam_break_3d_fluid_01180.vtu") else {
        return;
    };
    let (code, out, err) = common::run(&["info", pysph.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("--radius-array h --radius-scale 2"), "{out}");
    assert!(!out.contains("suggested support radius"), "{out}");
    let (_, json, _) = common::run(&["info", pysph.to_str().unwrap(), "--json"]);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(v["suggested_radius_array"]["name"], "h");
    let splash = shared("splash_doubledambreak/DoubleDamBreak_r0.0125_0011.vtu").unwrap();
    let (_, out, _) = common::run(&["info", splash.to_str().unwrap()]);
    assert!(
        out.contains("support radius: 0.05") && !out.contains("--radius-array"),
        "{out}"
    );
}

/// A camera path over a series: each frame takes the camera at its time, the keyframes'
/// exactly (one given as ParaView's saved camera state, .pvcc), a blend between them; one
/// file is rendered --path-frames times along the path, from the first keyframe's view.
#[test]
fn a_camera_path_moves_the_view_through_its_keyframes() {
    let Some(pvd) = shared("splash_doubledambreak/DoubleDamBreak_r0.0125.pvd") else {
        return;
    };
    let d = tempfile::tempdir().unwrap();
    let p = |n: &str| d.path().join(n);
    let pvcc = r#"<PVCameraConfiguration version="1.0"><Proxy group="views" type="RenderView">
<Property name="CameraPosition"><Element index="0" value="0.8"/><Element index="1" value="1.5"/><Element index="2" value="3.5"/></Property>
<Property name="CameraFocalPoint"><Element index="0" value="0"/><Element index="1" value="0.3"/><Element index="2" value="0"/></Property>
<Property name="CameraViewUp"><Element index="0" value="0"/><Element index="1" value="1"/><Element index="2" value="0"/></Property>
<Property name="CameraViewAngle"><Element index="0" value="30"/></Property>
</Proxy></PVCameraConfiguration>"#;
    std::fs::write(p("start.pvcc"), pvcc).unwrap();
    let end = r#"{"position": [3.5, 1.0, 0.5], "focal_point": [0, 0.3, 0], "view_up": [0, 1, 0], "view_angle": 30}"#;
    let start = r#"{"position": [0.8, 1.5, 3.5], "focal_point": [0, 0.3, 0], "view_up": [0, 1, 0], "view_angle": 30}"#;
    std::fs::write(p("end.json"), end).unwrap();
    std::fs::write(p("start.json"), start).unwrap();
    let path = format!(
        r#"{{"keyframes": [{{"time": 0.001, "pvcc": "start.pvcc"}}, {{"time": 0.101, "camera": {end}}}]}}"#
    );
    std::fs::write(p("path.json"), path).unwrap();
    let fixed = [
        "--array",
        "velocity:mag",
        "--range",
        "0,4",
        "--opacity-unit-distance",
        "0.05",
    ];
    let cp = p("path.json");
    let along = ["--frames", "0:3", "--camera-path", cp.to_str().unwrap()];
    render(&pvd, &p("s_%02d.png"), &[&fixed[..], &along].concat());
    let img = |n: &str| fluidcast_image::Image::read(&p(n)).unwrap();
    let files = fluidcast_io::read_collection(&pvd).unwrap();
    let files: Vec<PathBuf> = files.steps().map(|s| s[0].file.clone()).collect();
    for (k, cam) in [(0, "start.json"), (2, "end.json")] {
        let c = p(cam);
        let alone = format!("alone_{k}.png");
        render(
            &files[k],
            &p(&alone),
            &[&fixed[..], &["--camera", c.to_str().unwrap()]].concat(),
        );
        assert_eq!(
            common::max_diff(&img(&format!("s_{k:02}.png")), &img(&alone)),
            0.0,
            "frame {k}"
        );
    }
    let (mid, a, b) = (img("s_01.png"), img("alone_0.png"), img("alone_2.png"));
    assert!(common::max_diff(&mid, &a) > 0.1 && common::max_diff(&mid, &b) > 0.1);
    // One file along the path: 5 images, the first from the first keyframe's view.
    let one = ["--camera-path", cp.to_str().unwrap(), "--path-frames", "5"];
    render(&files[0], &p("one_%02d.png"), &[&fixed[..], &one].concat());
    assert!(p("one_04.png").exists() && !p("one_05.png").exists());
    assert_eq!(common::max_diff(&img("one_00.png"), &a), 0.0);
}
