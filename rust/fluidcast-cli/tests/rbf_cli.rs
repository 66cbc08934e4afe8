//! `fluidcast render --field rbf` from the command line.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;

use fluidcast_image::Image;

/// Renders the sample at 120x90 with the RBF field and `extra`: (exit code, stderr).
fn render(extra: &[&str], out: &std::path::Path) -> (Option<i32>, String) {
    common::render_sample(&["--field", "rbf", "--size", "120x90"], extra, out)
}

/// The options reach the image: classification, the radius map, the passes and the seed,
/// a density field without an array; stats carry the BVH's build and refit.
#[test]
fn rbf_options_change_the_image_as_they_say() {
    let dir = tempfile::tempdir().unwrap();
    let path = |n: &str| dir.path().join(n);
    let run = |extra: &[&str], name: &str| {
        let (code, err) = render(extra, &path(name));
        assert_eq!(code, Some(0), "{extra:?}: {err}");
        Image::read(&path(name)).unwrap()
    };
    let vel = ["--array", "velocity"];
    let stats = path("s.json");
    let post = run(
        &[&vel[..], &["--stats", stats.to_str().unwrap()]].concat(),
        "post.exr",
    );
    assert!(post.rgba.iter().any(|p| p[3] > 0.3), "drew something");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    for stage in ["bvh_ms", "refit_ms", "raycast_ms"] {
        assert!(s["timings"][stage].as_f64().is_some(), "{stage}: {s}");
    }
    assert!(s["rbf_memory_bytes"].as_u64().unwrap() > 0);
    let again = run(&vel, "again.exr");
    assert_eq!(
        common::max_diff(&post, &again),
        0.0,
        "same seed, same image"
    );
    let pre = run(
        &[&vel[..], &["--classification", "pre"]].concat(),
        "pre.exr",
    );
    assert!(
        common::max_diff(&post, &pre) > 0.01,
        "pre differs from post"
    );
    let seed = run(&[&vel[..], &["--seed", "7"]].concat(), "seed.exr");
    let d = common::max_diff(&post, &seed);
    assert!(
        d > 0.0 && d < 0.2,
        "another seed: other noise, same image ({d})"
    );
    let hidden = run(
        &[&vel[..], &["--radius-map", "0,0,1,0"]].concat(),
        "hidden.exr",
    );
    assert!(
        hidden.rgba.iter().all(|p| p[3] == 0.0),
        "radius 0 hides all"
    );
    let white = run(&[&vel[..], &["--noise", "white"]].concat(), "white.exr");
    assert!(common::max_diff(&post, &white) > 0.0, "other offsets");
    let spp = run(&[&vel[..], &["--spp", "4"]].concat(), "spp.exr");
    assert!(common::max_diff(&post, &spp) > 0.0);
    let density = run(&[], "density.exr");
    assert!(density.rgba.iter().any(|p| p[3] > 0.3));
    // Shadows: the same opacity, darker colours (ambient 0.25 and the fluid's own shadow).
    let lit = run(
        &[&vel[..], &["--shadows", "--light", "0,1,0", "--spp", "2"]].concat(),
        "lit.exr",
    );
    let two = run(&[&vel[..], &["--spp", "2"]].concat(), "two.exr");
    let (mut dark, mut n) = (0.0, 0);
    for (p, q) in lit.rgba.iter().zip(&two.rgba) {
        assert!((p[3] - q[3]).abs() < 1e-5, "alpha is emission-absorption's");
        if q[3] > 0.5 {
            dark += f64::from(p[0] + p[1] + p[2]) / f64::from(q[0] + q[1] + q[2]).max(1e-6);
            n += 1;
        }
    }
    let dark = dark / f64::from(n);
    assert!(dark < 0.9 && dark > 0.25, "lit / unlit colour {dark}");
}

#[test]
fn rbf_refuses_what_it_does_not_do() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.png");
    for (extra, says) in [
        (&["--mode", "reference"][..], "own ray marcher"),
        (&["--tiles", "4"][..], "screen tiles"),
        (&["--iso", "0.5"][..], "iso-surfaces"),
        (
            &["--array", "velocity", "--radius-map", "0,1,1"][..],
            "--radius-map",
        ),
        (&["--radius-map", "0,1,1,1"][..], "needs an attribute"),
        (&["--rbf-step", "-1"][..], "--rbf-step"),
        (&["--rbf-radius", "-1"][..], "--rbf-radius"),
        (&["--leaf-size", "0"][..], "--leaf-size"),
        (&["--spp", "0"][..], "spp"),
        (&["--shadows", "--light", "0,0,0"][..], "light direction"),
        (&["--shadows", "--light", "1,2"][..], "X,Y,Z"),
        (&["--shadows", "--shadow-ambient", "2"][..], "ambient"),
    ] {
        let (code, err) = render(extra, &out);
        assert_ne!(code, Some(0), "{extra:?}");
        assert!(err.contains(says), "{extra:?}: {err}");
    }
}

/// `fluidcast bench --field rbf`: a row per frame and leaf size, with the build, refit and
/// render times and memory; larger leaves hold fewer boxes.
#[test]
fn rbf_bench_reports_build_refit_render_and_memory_per_leaf_size() {
    let dir = tempfile::tempdir().unwrap();
    let js = dir.path().join("b.json");
    let sample = common::sample();
    let args = [
        "bench",
        sample.to_str().unwrap(),
        "--field",
        "rbf",
        "--array",
        "velocity",
        "--size",
        "64x48",
        "--views",
        "2",
        "--leaf-sizes",
        "1,16",
        "--json",
        js.to_str().unwrap(),
    ];
    let (code, out, err) = common::run(&args);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("refit"), "{out}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&js).unwrap()).unwrap();
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2);
    for r in rows {
        assert_eq!(r["render_ms"].as_array().unwrap().len(), 2, "{r}");
        assert!(
            r["build_ms"].as_f64().unwrap() >= 0.0 && r["samples_per_view"].as_u64().unwrap() > 0
        );
    }
    let bvh = |k: usize| rows[k]["bvh_bytes_per_particle"].as_f64().unwrap();
    assert!(
        bvh(1) < 0.6 * bvh(0),
        "leaf 16 {} vs leaf 1 {}",
        bvh(1),
        bvh(0)
    );
    let bad = [&args[..10], &["--leaf-sizes", "0"][..]].concat();
    let (code, _, err) = common::run(&bad);
    assert_ne!(code, Some(0));
    assert!(err.contains("--leaf-sizes"), "{err}");
}
