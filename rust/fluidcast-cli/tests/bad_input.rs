//! Bad input gets a clear error naming the file and the problem, never a panic.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/fixtures")
        .join(name)
}

/// `fluidcast ARGS`: (success, stderr).
fn run(args: &[&str]) -> (bool, String) {
    let (code, _, err) = common::run(args);
    (code == Some(0), err)
}

/// `fluidcast render INPUT -o o.png --size 32x24 EXTRA`: (wrote the image, stderr).
fn render(input: &Path, extra: &[&str]) -> (bool, String) {
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
    (ok && out.exists(), err)
}

fn render_err(input: &Path, extra: &[&str]) -> String {
    let (ok, err) = render(input, extra);
    assert!(!ok, "expected failure for {input:?} {extra:?}");
    err
}

/// A render that must succeed: its stderr.
fn render_ok(input: &Path, extra: &[&str]) -> String {
    let (ok, err) = render(input, extra);
    assert!(ok, "{input:?} {extra:?}: {err}");
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

/// Volumes are mass / density: a zero density (SPlisHSPlasH writes one for a particle emitted
/// in that frame) or a zero volume is an error naming the particle and the values it came
/// from, with what to do; equal volumes then render.
#[test]
fn zero_densities_and_volumes_are_explained() {
    let dir = tempfile::tempdir().unwrap();
    let mass_density = r#"<DataArray type="Float32" Name="mass" format="ascii">0.5 0.5 0.5</DataArray>
<DataArray type="Float32" Name="density" format="ascii">1000 1000 0</DataArray>"#;
    let volume =
        r#"<DataArray type="Float32" Name="volume" format="ascii">1e-3 0 1e-3</DataArray>"#;
    for (name, arrays, says, hint) in [
        (
            "emitted.vtu",
            mass_density,
            "volume of particle 2 is inf (mass 0.5 / density 0;",
            true,
        ),
        (
            "zero_volume.vtu",
            volume,
            "volume of particle 1 is 0 (array 'volume';",
            false,
        ),
    ] {
        let points = "0 0 0 0.1 0 0 0 0.1 0";
        let p = write(dir.path(), name, ascii_vtu(points, 3, arrays).as_bytes());
        let err = render_err(&p, &["--support-radius", "0.2"]);
        assert!(err.contains(name) && err.contains(says), "{err}");
        assert_eq!(
            err.contains("hint:") && err.contains("--uniform-volume"),
            hint,
            "{err}"
        );
        // The way out the hint names: equal volumes render.
        render_ok(&p, &["--support-radius", "0.2", "--uniform-volume"]);
    }
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
    let err = render_ok(&p, &["--support-radius", "0.02"]);
    assert!(err.contains("skipped 2 particles with NaN/Inf"), "{err}");
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

/// Runs the CLI under an address-space limit (as a user's `ulimit -v` would), through sh.
fn run_limited(limit_kib: u64, args: &[&str]) -> (i32, String) {
    let quoted: Vec<String> = args.iter().map(|a| format!("'{a}'")).collect();
    let o = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v {limit_kib}; exec '{}' {}",
            env!("CARGO_BIN_EXE_fluidcast"),
            quoted.join(" ")
        ))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(!err.contains("panicked"), "panic: {err}");
    assert!(!err.contains("memory allocation"), "abort: {err}");
    (o.status.code().unwrap_or(-1), err)
}

fn lattice(n: usize, extra: &[[f64; 3]]) -> String {
    let mut pts: Vec<[f64; 3]> = (0..n * n * n)
        .map(|i| {
            [
                (i % n) as f64 * 0.1,
                (i / n % n) as f64 * 0.1,
                (i / n / n) as f64 * 0.1,
            ]
        })
        .collect();
    pts.extend_from_slice(extra);
    let text: Vec<String> = pts
        .iter()
        .map(|p| format!("{} {} {}", p[0], p[1], p[2]))
        .collect();
    ascii_vtu(&text.join(" "), pts.len(), "")
}

#[test]
fn huge_images_are_refused_before_allocating() {
    let sample = common::sample();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.png");
    let (o, s) = (out.to_str().unwrap(), sample.to_str().unwrap());
    // 16384x8192 passes the size check but needs more than the 4 GiB a user allows (and
    // more work than the default limit: off, so that the memory check is what answers).
    let (code, err) = run_limited(
        4 << 20,
        &[
            "render",
            s,
            "-o",
            o,
            "--size",
            "16384x8192",
            "--max-work",
            "off",
        ],
    );
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("a 16384x8192 render needs") && err.contains("GiB"),
        "{err}"
    );
    // 4096x4096 fits the image but not the grid's particle–cell pairs in 2 GiB.
    let (code, err) = run_limited(
        2 << 20,
        &[
            "render",
            s,
            "-o",
            o,
            "--size",
            "4096x4096",
            "--array",
            "velocity",
            "--max-work",
            "off",
        ],
    );
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("particle–cell pairs") && err.contains("address-space limit"),
        "{err}"
    );
}

#[test]
fn forged_png_header_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    // A valid PNG signature and IHDR claiming 100000 x 100000 RGBA, with no pixel data.
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend(100000u32.to_be_bytes());
    ihdr.extend(100000u32.to_be_bytes());
    ihdr.extend([8, 6, 0, 0, 0]);
    png.extend(13u32.to_be_bytes());
    png.extend(&ihdr);
    png.extend(crc32(&ihdr).to_be_bytes());
    // An IDAT chunk holding an empty zlib stream, and IEND.
    for (kind, data) in [
        (
            &b"IDAT"[..],
            &[0x78, 0x9C, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01][..],
        ),
        (b"IEND", &[]),
    ] {
        let chunk = [kind, data].concat();
        png.extend((data.len() as u32).to_be_bytes());
        png.extend(&chunk);
        png.extend(crc32(&chunk).to_be_bytes());
    }
    let p = write(dir.path(), "huge.png", &png);
    let (code, err) = run_limited(
        4 << 20,
        &["compare", p.to_str().unwrap(), p.to_str().unwrap()],
    );
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("huge.png") && err.contains("100000x100000"),
        "{err}"
    );
}

/// CRC-32 (ISO 3309), as PNG chunks carry it.
fn crc32(b: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &x in b {
        c ^= x as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

#[test]
fn far_outliers_render_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.png");
    for y in [-1e14, 1e15, 1e30] {
        let p = write(
            dir.path(),
            "outlier.vtu",
            lattice(4, &[[0.0, y, 0.0]]).as_bytes(),
        );
        for tol in ["0.004", "off"] {
            let o = Command::new(env!("CARGO_BIN_EXE_fluidcast"))
                .args([
                    "render",
                    p.to_str().unwrap(),
                    "-o",
                    out.to_str().unwrap(),
                    "--size",
                    "32x24",
                    "--error-tolerance",
                    tol,
                ])
                .output()
                .unwrap();
            let err = String::from_utf8_lossy(&o.stderr);
            assert!(o.status.success(), "y = {y}, {tol}: {err}");
            assert!(
                err.contains("warning: 1 of 65 particles lie far outside the rest"),
                "{err}"
            );
            // The spacing ignores the outlier: H = 2 × 0.1.
            assert!(err.contains("using 0.200000"), "{err}");
        }
    }
    let p = write(
        dir.path(),
        "two.vtu",
        ascii_vtu("0 0 0 1e30 0 0", 2, "").as_bytes(),
    );
    let err = render_err(&p, &[]);
    assert!(
        err.contains("no measurable spacing") && err.contains("1.000e30"),
        "{err}"
    );
}

#[test]
fn values_beyond_single_precision_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let big = (0..2).map(|_| "1e39").collect::<Vec<_>>().join(" ");
    let p = write(
        dir.path(),
        "big.vtu",
        ascii_vtu(
            "0 0 0 0.1 0 0",
            2,
            &format!(r#"<DataArray type="Float64" Name="q" format="ascii">{big}</DataArray>"#),
        )
        .as_bytes(),
    );
    let err = render_err(&p, &["--array", "q", "--support-radius", "0.2"]);
    assert!(
        err.contains("value of particle 0 is 1e39, outside single precision"),
        "{err}"
    );
    let err = render_err(&p, &["--support-radius", "1e-40"]);
    assert!(
        err.contains("--support-radius") && err.contains("not 1e-40"),
        "{err}"
    );
    // A NaN value would make every sample its support reaches not a number.
    let p = write(
        dir.path(),
        "nanvalue.vtu",
        ascii_vtu(
            "0 0 0 0.1 0 0",
            2,
            r#"<DataArray type="Float32" Name="q" format="ascii">1 nan</DataArray>"#,
        )
        .as_bytes(),
    );
    for field in [&["--array", "q"][..], &["--iso", "0.5", "--iso-field", "q"]] {
        let err = render_err(&p, &[field, &["--support-radius", "0.2"]].concat());
        assert!(
            err.contains("nanvalue.vtu") && err.contains("'q' of particle 1 is NaN"),
            "{field:?}: {err}"
        );
    }
}

#[test]
fn output_and_option_mistakes_are_errors() {
    let sample = common::sample();
    let err = render_err(&sample, &["--background", "nan,0,0"]);
    assert!(err.contains("--background 'nan,0,0'"), "{err}");
    let err = render_err(&sample, &["--background", "2,2,2"]);
    assert!(err.contains("--background '2,2,2'"), "{err}");
    let dir = tempfile::tempdir().unwrap();
    let pat = dir.path().join("x_%99999999d.png");
    let (ok, err) = run(&[
        "render",
        sample.to_str().unwrap(),
        "-o",
        pat.to_str().unwrap(),
        "--size",
        "8x8",
    ]);
    assert!(
        !ok && err.contains("a field width of 99999999 digits"),
        "{err}"
    );
    // Camera errors say their text once.
    let cam = write(
        dir.path(),
        "cam.json",
        br#"{"position":[0,0,1],"focal_point":[0,0,0]}"#,
    );
    let err = render_err(&sample, &["--camera", cam.to_str().unwrap()]);
    assert_eq!(err.matches("missing field `view_up`").count(), 1, "{err}");
    // probe: every row has three numbers.
    let pts = write(dir.path(), "p.csv", b"x,y,z\n0,0,0\n1,2\n");
    let (ok, err) = run(&[
        "probe",
        sample.to_str().unwrap(),
        "--points",
        pts.to_str().unwrap(),
        "-o",
        dir.path().join("o.csv").to_str().unwrap(),
    ]);
    assert!(!ok && err.contains("p.csv: line 3"), "{err}");
}

#[test]
fn closed_pipes_and_full_disks() {
    let sample = common::sample();
    let s = sample.to_str().unwrap();
    // The reader goes away: a quiet, successful end, as `cat F | true` has.
    let o = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "'{}' info '{s}' | true; echo \"rc=${{PIPESTATUS:-$?}}\"",
            env!("CARGO_BIN_EXE_fluidcast")
        ))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.is_empty(), "{err}");
    if Path::new("/dev/full").exists() {
        let o = Command::new("sh")
            .arg("-c")
            .arg(format!(
                "exec '{}' info '{s}' > /dev/full",
                env!("CARGO_BIN_EXE_fluidcast")
            ))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(
            err.contains("writing to standard output: No space left on device"),
            "{err}"
        );
    }
}

/// Bad view files and bad input to the other subcommands: an error naming the file and the
/// problem, exit code 1, no panic.
#[test]
fn bad_camera_and_tf_files_and_tool_inputs() {
    let sample = common::sample();
    let d = tempfile::tempdir().unwrap();
    let cam = |name: &str, json: &str| {
        let p = write(d.path(), name, json.as_bytes());
        render_err(&sample, &["--camera", p.to_str().unwrap()])
    };
    let view = r#""position":[0,0,1],"focal_point":[0,0,0]"#;
    for (name, json, want) in [
        (
            "c1.json",
            r#"{"position":[0,0,1],"focal_point":[0,0,1],"view_up":[0,1,0]}"#,
            "position equals the focal point",
        ),
        (
            "c2.json",
            r#"{"position":[0,0,1e400],"focal_point":[0,0,0],"view_up":[0,1,0]}"#,
            "number out of range",
        ),
        (
            "c3.json",
            &format!(r#"{{{view},"view_up":[0,0,1]}}"#),
            "view up is parallel",
        ),
        (
            "c4.json",
            &format!(r#"{{{view},"view_up":[0,1,0],"view_angle":0}}"#),
            "view angle 0°",
        ),
        ("c5.json", "[1, 2", "camera"),
    ] {
        let err = cam(name, json);
        assert!(err.contains(name) && err.contains(want), "{name}: {err}");
    }
    let tf = |name: &str, json: &str| {
        let p = write(d.path(), name, json.as_bytes());
        render_err(&sample, &["--tf", p.to_str().unwrap()])
    };
    for (name, json, want) in [
        ("t1.json", "not json", "invalid JSON"),
        ("t2.json", r#"[{"Name":"x"}]"#, "no preset with 'RGBPoints'"),
        (
            "t3.json",
            r#"[{"Name":"x","RGBPoints":[0,1,0,0,"nan",0,1,0]}]"#,
            "non-number",
        ),
        ("t4.json", "[]", "no preset with 'RGBPoints'"),
        (
            "t5.json",
            r#"[{"Name":"x","RGBPoints":[0,1,0]}]"#,
            "groups of 4 numbers",
        ),
    ] {
        let err = tf(name, json);
        assert!(err.contains(name) && err.contains(want), "{name}: {err}");
    }
    let missing = d.path().join("missing.json");
    let err = render_err(&sample, &["--tf", missing.to_str().unwrap()]);
    assert!(
        err.contains("missing.json") && err.contains("No such file"),
        "{err}"
    );

    // compare: a missing file, a file that is not an image, images of different sizes.
    let img = |name: &str, size: &str| {
        let p = d.path().join(name);
        let (ok, err) = run(&[
            "render",
            sample.to_str().unwrap(),
            "-o",
            p.to_str().unwrap(),
            "--size",
            size,
        ]);
        assert!(ok, "{err}");
        p
    };
    let (a, b) = (img("a.png", "8x8"), img("b.png", "9x8"));
    let garbage = write(d.path(), "g.png", b"garbage");
    for (x, y, want) in [
        (a.clone(), d.path().join("nope.png"), "nope.png"),
        (a.clone(), garbage.clone(), "g.png"),
        (a.clone(), b.clone(), "a.png"),
    ] {
        let (ok, err) = run(&["compare", x.to_str().unwrap(), y.to_str().unwrap()]);
        assert!(!ok && err.contains(want), "{err}");
    }
    let (_, err) = run(&["compare", a.to_str().unwrap(), b.to_str().unwrap()]);
    assert!(err.contains("8x8 vs 9x8") && err.contains("b.png"), "{err}");

    // info: a missing file, an unsupported extension, broken XML.
    let broken = write(d.path(), "t.vtu", b"<VTKFile");
    for (p, want) in [
        (d.path().join("nope.vtu"), "nope.vtu"),
        (garbage.clone(), "unsupported file extension"),
        (broken, "malformed XML"),
    ] {
        let (ok, err) = run(&["info", p.to_str().unwrap()]);
        assert!(!ok && err.contains(want), "{err}");
    }
    // probe: a missing points file, a non-finite point, a missing data file.
    let nan = write(d.path(), "n.csv", b"x,y,z\nnan,0,0\n");
    let out = d.path().join("o.csv");
    for (data, pts, want) in [
        (sample.clone(), d.path().join("nope.csv"), "nope.csv"),
        (sample.clone(), nan.clone(), "n.csv: line 2"),
        (d.path().join("nope.vtu"), nan.clone(), "nope.vtu"),
    ] {
        let (ok, err) = run(&[
            "probe",
            data.to_str().unwrap(),
            "--points",
            pts.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(!ok && err.contains(want), "{err}");
    }
}

/// A FIFO with no writer, as the input, as a camera and as a transfer function: an error
/// naming it, where an open that waited for a writer would hang the command (and this test).
#[test]
fn fifos_are_refused_not_waited_on() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("fifo.vtu");
    let json = dir.path().join("fifo.json");
    for p in [&fifo, &json] {
        assert!(Command::new("mkfifo").arg(p).status().unwrap().success());
    }
    let (ok, err) = run(&["info", fifo.to_str().unwrap()]);
    assert!(
        !ok && err.contains("fifo.vtu") && err.contains("a FIFO (named pipe)"),
        "{err}"
    );
    let sample = fixture("lattice_ascii_none_h64.vtu");
    for extra in [
        ["--camera", json.to_str().unwrap()],
        ["--tf", json.to_str().unwrap()],
    ] {
        let err = render_err(&sample, &extra);
        assert!(
            err.contains("fifo.json") && err.contains("a FIFO (named pipe)"),
            "{err}"
        );
    }
}

/// Issue 45's unclear messages: each says what was wrong and what to give instead.
#[test]
fn option_mistakes_say_what_to_give() {
    let series = fixture("series.pvd");
    for (extra, says) in [
        (
            &["--frames", ""][..],
            "give one frame index or START:END[:STEP]",
        ),
        (
            &["--frames=-1"][..],
            "'-1' is not a frame index (whole numbers from 0)",
        ),
        (&["--frames", "0:x"][..], "'x' is not a frame index"),
        (
            &["--zoom", "1e-30"][..],
            "must stay below 180°; --zoom must be at least",
        ),
    ] {
        let err = render_err(&series, extra);
        assert!(err.contains(says), "{extra:?}: {err}");
        assert!(!err.contains("invalid digit"), "{extra:?}: {err}");
    }
    let dir = tempfile::tempdir().unwrap();
    let one = dir.path().join("one.png");
    let (one, series_path) = (one.to_str().unwrap(), series.to_str().unwrap());
    let (ok, err) = run(&["render", series_path, "-o", one, "--size", "64x48x3"]);
    assert!(
        !ok && err.contains("expected WxH, two whole numbers of pixels"),
        "{err}"
    );
    let out = dir.path().join("x_%d_%d.png");
    let (ok, err) = run(&[
        "render",
        series.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(
        !ok && err.contains("one frame pattern (%d or %04d) only"),
        "{err}"
    );
    assert!(!dir.path().join("x_0_%d.png").exists());
    // A piece path no file system takes is refused without echoing 100,000 characters.
    let long = format!(
        r#"<?xml version="1.0"?><VTKFile type="PUnstructuredGrid" version="0.1"><PUnstructuredGrid><PPoints><PDataArray type="Float32" NumberOfComponents="3"/></PPoints><Piece Source="{}.vtu"/></PUnstructuredGrid></VTKFile>"#,
        "a".repeat(100_000)
    );
    let p = write(dir.path(), "long.pvtu", long.as_bytes());
    let err = render_err(&p, &[]);
    assert!(
        err.contains("a path of 100004 bytes") && err.len() < 1000,
        "{err}"
    );
}

/// A support radius far too large is refused up front with the work the view needs, not
/// rendered for minutes; `--max-work off` renders it anyway.
#[test]
fn a_view_beyond_the_work_limit_is_refused_with_what_it_needs() {
    let sample = common::sample();
    let err = render_err(&sample, &["--support-radius", "1000", "--max-work", "1e6"]);
    assert!(
        err.contains("--max-work: this view needs about")
            && err.contains("more than the limit of 1.0e6"),
        "{err}"
    );
    render_ok(&sample, &["--support-radius", "1000", "--max-work", "off"]);
    let err = render_err(&sample, &["--max-work", "-1"]);
    assert!(
        err.contains("'--max-work <MAX_WORK>': must be a number >= 0"),
        "{err}"
    );
}
