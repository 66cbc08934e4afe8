//! `fluidcast render --mode perspective-grid` from the command line.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;

use fluidcast_image::Image;

/// Renders the sample at 200x150 with `extra`: (exit code, stderr).
fn render(extra: &[&str], out: &std::path::Path) -> (Option<i32>, String) {
    common::render_sample(
        &[
            "--array",
            "velocity",
            "--size",
            "200x150",
            "--azimuth",
            "30",
        ],
        extra,
        out,
    )
}

/// One grid column per pixel gives the reference's image (single precision grid), with and
/// without surfaces; a coarser cell renders too; bad cells and the GPU backend are refused.
#[test]
fn perspective_grid_mode_renders_as_the_reference() {
    let dir = tempfile::tempdir().unwrap();
    for iso in [&[][..], &["--iso", "0.5"][..]] {
        let (a, b) = (dir.path().join("a.exr"), dir.path().join("b.exr"));
        let (code, err) = render(&[&["--mode", "reference"][..], iso].concat(), &a);
        assert_eq!(code, Some(0), "{err}");
        let (code, err) = render(&[&["--mode", "perspective-grid"][..], iso].concat(), &b);
        assert_eq!(code, Some(0), "{err}");
        let (a, b) = (Image::read(&a).unwrap(), Image::read(&b).unwrap());
        let off =
            |p: &[f32; 4], q: &[f32; 4]| (0..4).map(|c| (p[c] - q[c]).abs()).fold(0.0, f32::max);
        let worst = a
            .rgba
            .iter()
            .zip(&b.rgba)
            .map(|(p, q)| off(p, q))
            .fold(0.0, f32::max);
        let far = a
            .rgba
            .iter()
            .zip(&b.rgba)
            .filter(|(p, q)| off(p, q) > 0.1)
            .count();
        assert!(a.rgba.iter().any(|p| p[3] > 0.5), "drew something");
        if iso.is_empty() {
            assert!(worst < 1e-5, "volume: max abs {worst}");
        } else {
            // Grid surfaces are linear between slices, with finite-difference normals, and a
            // silhouette pixel may show a surface in one and not the other (measured: 16 of
            // 30,000 pixels off by more than 0.1 here; at 64x48, where the surface's bumps
            // are smaller than a pixel, 4 %).
            let share = far as f64 / a.rgba.len() as f64;
            eprintln!(
                "surfaces: {far} of {} pixels off by more than 0.1",
                a.rgba.len()
            );
            assert!(share < 0.005, "surfaces: {far} pixels off by more than 0.1");
        }
    }
    let out = dir.path().join("c.png");
    let (code, err) = render(&["--mode", "perspective-grid", "--grid-cell", "3"], &out);
    assert_eq!(code, Some(0), "{err}");
    let (code, err) = render(&["--mode", "perspective-grid", "--grid-cell", "0"], &out);
    assert_eq!(code, Some(2), "a usage error, as clap's");
    assert!(
        err.contains("'--grid-cell <GRID_CELL>': must be a whole number 1..=64 (pixels), not 0"),
        "{err}"
    );
    let (code, err) = render(&["--mode", "perspective-grid", "--backend", "gpu"], &out);
    assert_eq!(code, Some(1));
    assert!(
        err.contains("--backend gpu renders the adaptive mode only"),
        "{err}"
    );
}
