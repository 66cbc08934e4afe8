//! `fluidcast render --lod` and `fluidcast bench --lod` from the command line.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;

use fluidcast_image::Image;

/// Renders the sample at 120x90 by velocity with `extra`: (exit code, stderr).
fn render(extra: &[&str], out: &std::path::Path) -> (Option<i32>, String) {
    common::render_sample(&["--array", "velocity", "--size", "120x90"], extra, out)
}

#[test]
fn lod_renders_a_cut_and_says_how_much() {
    let dir = tempfile::tempdir().unwrap();
    let path = |n: &str| dir.path().join(n);
    let run = |extra: &[&str], name: &str| {
        let (code, err) = render(extra, &path(name));
        assert_eq!(code, Some(0), "{extra:?}: {err}");
        (Image::read(&path(name)).unwrap(), err)
    };
    let (full, _) = run(&[], "full.exr");
    // 0 pixels: every particle, in the hierarchy's order (sums in another order: f32 rounding).
    let (zero, err) = run(&["--lod", "0"], "zero.exr");
    assert!(err.contains("6000 of 6000 particles"), "{err}");
    assert!(common::max_diff(&full, &zero) < 1e-5);
    let stats = path("s.json");
    let (cut, err) = run(
        &["--lod", "4", "--stats", stats.to_str().unwrap()],
        "cut.exr",
    );
    assert!(err.contains("level of detail 4 px"), "{err}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    let lod = &s["lod"];
    let (n, all) = (
        lod["rendered_particles"].as_u64().unwrap(),
        lod["full_detail_particles"].as_u64().unwrap(),
    );
    assert_eq!(all, 6000);
    assert!(n < 6000 * 9 / 10, "{lod}");
    assert_eq!(
        s["particles"].as_u64(),
        Some(n),
        "the renderer drew the cut"
    );
    let d = common::max_diff(&full, &cut);
    assert!(d > 0.0 && d < 0.02, "{d}");
}

#[test]
fn lod_refuses_what_it_cannot_do() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.png");
    for (extra, says) in [
        (
            &["--lod", "-1"][..],
            "must be a number >= 0 and <= 1000000 (pixels",
        ),
        (&["--lod", "nan"][..], "not NaN"),
        (
            &["--lod", "2", "--field", "rbf"][..],
            "own cluster hierarchy",
        ),
    ] {
        let (code, err) = render(extra, &out);
        assert_ne!(code, Some(0), "{extra:?}");
        assert!(err.contains(says), "{extra:?}: {err}");
    }
}

#[test]
fn bench_lod_reports_speed_and_error_per_tolerance() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("b.json");
    let sample = common::sample();
    let (code, out, err) = common::run(&[
        "bench",
        sample.to_str().unwrap(),
        "--array",
        "velocity",
        "--size",
        "80x60",
        "--views",
        "2",
        "--lod",
        "0,4",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("hierarchy:"), "{out}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2);
    // 0 pixels is full detail (f32 sums in another order); 4 pixels merges some.
    assert_eq!(rows[0]["particles"].as_f64(), Some(6000.0));
    assert!(rows[0]["max_abs_vs_full_detail"].as_f64().unwrap() < 1e-5);
    assert!(rows[1]["particles"].as_f64().unwrap() < 6000.0);
    assert!(rows[1]["max_abs_vs_full_detail"].as_f64().unwrap() > 0.0);
    assert!(rows[1]["speedup_vs_full_detail"].as_f64().unwrap() > 0.0);
    let (code, _, err) = common::run(&["bench", sample.to_str().unwrap(), "--lod", "2,x"]);
    assert_ne!(code, Some(0));
    assert!(err.contains("--lod '2,x'"), "{err}");
}
