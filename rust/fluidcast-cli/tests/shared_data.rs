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
