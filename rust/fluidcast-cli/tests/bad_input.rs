//! Bad input gets a clear error naming the file and the problem, never a panic.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
use std::path::{Path, PathBuf};
use std::process::Command;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/fixtures")
        .join(name)
}

fn run(args: &[&str]) -> (bool, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_fluidcast"))
        .args(args)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(!err.contains("panicked"), "panic: {err}");
    (o.status.success(), err)
}

fn render_err(input: &Path, extra: &[&str]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.png");
    let mut args = vec![
        "render",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--size",
        "32x24",
    ];
    args.extend_from_slice(extra);
    let (ok, err) = run(&args);
    assert!(!ok, "expected failure for {input:?} {extra:?}");
    err
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn ascii_vtu(points: &str, n: usize, arrays: &str) -> String {
    format!(
        r#"<?xml version="1.0"?><VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">
<UnstructuredGrid><Piece NumberOfPoints="{n}" NumberOfCells="0"><PointData>{arrays}</PointData>
<Points><DataArray type="Float32" NumberOfComponents="3" format="ascii">{points}</DataArray></Points>
<Cells></Cells></Piece></UnstructuredGrid></VTKFile>"#
    )
}

#[test]
fn truncated_file() {
    let dir = tempfile::tempdir().unwrap();
    let full = std::fs::read(fixture("lattice_appended-raw_zlib_h64.vtu")).unwrap();
    let p = write(dir.path(), "cut.vtu", &full[..full.len() * 2 / 3]);
    let err = render_err(&p, &[]);
    assert!(
        err.contains("cut.vtu") && err.contains("truncated"),
        "{err}"
    );
}

#[test]
fn malformed_xml_and_unknown_extension() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "bad.vtu",
        b"<VTKFile type=\"UnstructuredGrid\"><Piece NumberOfPoints=\"x\"",
    );
    let err = render_err(&p, &[]);
    assert!(err.contains("bad.vtu"), "{err}");
    let q = write(dir.path(), "x.obj", b"v 0 0 0");
    assert!(render_err(&q, &[]).contains("unsupported file extension"));
    let missing = dir.path().join("nope.vtu");
    assert!(render_err(&missing, &[]).contains("nope.vtu"));
}

#[test]
fn wrong_array_length() {
    let dir = tempfile::tempdir().unwrap();
    let s = ascii_vtu(
        "0 0 0 1 0 0",
        2,
        r#"<DataArray type="Float32" Name="t" format="ascii">1 2 3</DataArray>"#,
    );
    let p = write(dir.path(), "len.vtu", s.as_bytes());
    let err = render_err(&p, &["--array", "t"]);
    assert!(
        err.contains("len.vtu") && err.contains("'t'") && err.contains("expected 2 tuples"),
        "{err}"
    );
}

#[test]
fn unknown_array_lists_available() {
    let err = render_err(
        &fixture("lattice_ascii_none_h64.vtu"),
        &["--array", "temperature"],
    );
    assert!(
        err.contains("no point array 'temperature'")
            && err.contains("velocity (3 comp.)")
            && err.contains("density"),
        "{err}"
    );
    let err = render_err(
        &fixture("lattice_ascii_none_h64.vtu"),
        &["--array", "velocity:5"],
    );
    assert!(err.contains("component 5"), "{err}");
}

#[test]
fn no_points() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "empty.vtu", ascii_vtu("", 0, "").as_bytes());
    let err = render_err(&p, &[]);
    assert!(
        err.contains("empty.vtu") && err.contains("no points"),
        "{err}"
    );
}

#[test]
fn bad_radii() {
    let dir = tempfile::tempdir().unwrap();
    for (name, vals) in [
        ("nan.vtu", "0.1 nan"),
        ("neg.vtu", "0.1 -0.2"),
        ("zero.vtu", "0 0.1"),
    ] {
        let s = ascii_vtu(
            "0 0 0 1 0 0",
            2,
            &format!(r#"<DataArray type="Float32" Name="h" format="ascii">{vals}</DataArray>"#),
        );
        let p = write(dir.path(), name, s.as_bytes());
        let err = render_err(&p, &["--radius-array", "h"]);
        assert!(
            err.contains(name) && err.contains("support radius"),
            "{err}"
        );
    }
    let err = render_err(
        &fixture("lattice_ascii_none_h64.vtu"),
        &["--support-radius", "-1"],
    );
    assert!(err.contains("--support-radius"), "{err}");
}

#[test]
fn absurd_image_size() {
    for size in ["100000x100000", "0x10", "12", "axb"] {
        let err = render_err(&fixture("lattice_ascii_none_h64.vtu"), &["--size", size]);
        assert!(err.contains("--size"), "{size}: {err}");
    }
}

#[test]
fn nan_positions_are_skipped_with_a_count() {
    let dir = tempfile::tempdir().unwrap();
    let s = ascii_vtu("0 0 0 0.01 0 0 nan 0 0 0 inf 0 0 0.01 0", 5, "");
    let p = write(dir.path(), "nanpos.vtu", s.as_bytes());
    let out = dir.path().join("o.png");
    let (ok, err) = run(&[
        "render",
        p.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--size",
        "16x16",
        "--support-radius",
        "0.02",
    ]);
    assert!(ok, "{err}");
    assert!(err.contains("skipped 2 particles with NaN/Inf"), "{err}");
    assert!(out.exists());
    let all_nan = write(
        dir.path(),
        "allnan.vtu",
        ascii_vtu("nan 0 0", 1, "").as_bytes(),
    );
    assert!(render_err(&all_nan, &["--support-radius", "0.02"]).contains("NaN"));
}

#[test]
fn series_needs_a_pattern_and_renders_frames() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("f_%03d.png");
    let (ok, err) = run(&[
        "render",
        fixture("series.pvd").to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--frames",
        "0:2",
        "--size",
        "16x12",
        "--array",
        "density",
    ]);
    assert!(ok, "{err}");
    assert!(dir.path().join("f_000.png").exists() && dir.path().join("f_001.png").exists());
    let single = dir.path().join("one.png");
    let (ok, err) = run(&[
        "render",
        fixture("series.pvd").to_str().unwrap(),
        "-o",
        single.to_str().unwrap(),
        "--frames",
        "0:2",
    ]);
    assert!(!ok && err.contains("frame pattern"), "{err}");
}

#[test]
fn stats_and_compare() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.exr");
    let stats = dir.path().join("s.json");
    let input = fixture("lattice_binary_zlib_h64.vtp");
    let (ok, err) = run(&[
        "render",
        input.to_str().unwrap(),
        "-o",
        a.to_str().unwrap(),
        "--size",
        "40x30",
        "--array",
        "velocity:mag",
        "--stats",
        stats.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    for k in ["read_ms", "grid_ms", "adapt_ms", "raycast_ms", "total_ms"] {
        assert!(s["timings"][k].as_f64().unwrap() >= 0.0, "{k}");
    }
    assert_eq!(s["particles"], 256);
    let cells = s["grid"]["cells"].as_u64().unwrap();
    let c = &s["cells"];
    let z: u64 = c["z_adapted_per_level"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .sum();
    assert_eq!(
        c["full_rate"].as_u64().unwrap() + z + c["superpixel"].as_u64().unwrap(),
        cells,
        "every cell has one outcome"
    );
    // The same particles from the ascii file give the same image.
    let b = dir.path().join("b.exr");
    let (ok, _) = run(&[
        "render",
        fixture("lattice_ascii_none_h64.vtu").to_str().unwrap(),
        "-o",
        b.to_str().unwrap(),
        "--size",
        "40x30",
        "--array",
        "velocity:mag",
    ]);
    assert!(ok);
    let o = Command::new(env!("CARGO_BIN_EXE_fluidcast"))
        .args([
            "compare",
            a.to_str().unwrap(),
            b.to_str().unwrap(),
            "--json",
        ])
        .output()
        .unwrap();
    let c: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(c["max_abs"], 0.0);
    assert!(c["rmse"].is_number() && c["frac_above"].is_number());
}
