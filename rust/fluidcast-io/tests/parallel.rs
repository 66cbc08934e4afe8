//! Parallel files (`.pvtu`, `.pvtp`): the pieces, read and concatenated, equal the same
//! particles written as one file; ghost copies are dropped; every way a summary or its
//! pieces can be wrong is an error that names the file at fault and the summary.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::Path;

use fluidcast_io::{read_dataset, Dataset};

/// Particles `range` of a 4×4×4 lattice, with a scalar `p`, a vector `v` and a `vtkGhostType`
/// of 0 unless `ghost` is given.
struct Part {
    range: std::ops::Range<usize>,
    ghost: Option<u8>,
}

fn lattice(i: usize) -> [f64; 3] {
    [
        (i % 4) as f64 * 0.1,
        (i / 4 % 4) as f64 * 0.1,
        (i / 16) as f64 * 0.1 + 0.05,
    ]
}

/// ASCII VTK XML of some parts: `poly` writes PolyData (vertices), else an UnstructuredGrid.
fn xml(parts: &[Part], poly: bool, with_ghosts: bool) -> String {
    let ids: Vec<usize> = parts.iter().flat_map(|p| p.range.clone()).collect();
    let ghosts: Vec<u8> = parts
        .iter()
        .flat_map(|p| p.range.clone().map(|_| p.ghost.unwrap_or(0)))
        .collect();
    let join = |v: Vec<String>| v.join(" ");
    let pts = join(
        ids.iter()
            .flat_map(|&i| lattice(i).map(|c| format!("{c}")))
            .collect(),
    );
    let p = join(
        ids.iter()
            .map(|&i| format!("{}", i as f64 * 0.5 - 3.0))
            .collect(),
    );
    let v = join(
        ids.iter()
            .map(|&i| format!("{i} {} 0.25", -(i as f64)))
            .collect(),
    );
    let g = join(ghosts.iter().map(|g| g.to_string()).collect());
    let ghost_array = if with_ghosts {
        format!(r#"<DataArray type="UInt8" Name="vtkGhostType" format="ascii">{g}</DataArray>"#)
    } else {
        String::new()
    };
    let (ty, cells) = if poly {
        ("PolyData", r#"NumberOfVerts="0""#)
    } else {
        ("UnstructuredGrid", r#"NumberOfCells="0""#)
    };
    format!(
        r#"<?xml version="1.0"?>
<VTKFile type="{ty}" version="1.0" byte_order="LittleEndian">
<{ty}>
<FieldData><DataArray type="Float64" Name="TIME" NumberOfTuples="1" format="ascii">1.5</DataArray></FieldData>
<Piece NumberOfPoints="{n}" {cells}>
<PointData>
<DataArray type="Float64" Name="p" format="ascii">{p}</DataArray>
<DataArray type="Float32" Name="v" NumberOfComponents="3" format="ascii">{v}</DataArray>
{ghost_array}
</PointData>
<Points><DataArray type="Float64" NumberOfComponents="3" format="ascii">{pts}</DataArray></Points>
</Piece>
</{ty}>
</VTKFile>
"#,
        n = ids.len()
    )
}

/// A parallel summary listing `sources`, declaring the point arrays `arrays`.
fn summary(poly: bool, arrays: &[&str], sources: &[&str]) -> String {
    let ty = if poly {
        "PPolyData"
    } else {
        "PUnstructuredGrid"
    };
    let decl: String = arrays
        .iter()
        .map(|a| format!(r#"<PDataArray type="Float64" Name="{a}"/>"#))
        .collect();
    let pieces: String = sources
        .iter()
        .map(|s| format!(r#"<Piece Source="{s}"/>"#))
        .collect();
    format!(
        r#"<?xml version="1.0"?>
<VTKFile type="{ty}" version="1.0" byte_order="LittleEndian">
<{ty} GhostLevel="0">
<PPointData>{decl}</PPointData>
<PPoints><PDataArray type="Float64" NumberOfComponents="3"/></PPoints>
{pieces}
</{ty}>
</VTKFile>
"#
    )
}

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn same_particles(a: &Dataset, b: &Dataset) {
    assert_eq!(a.points, b.points);
    assert_eq!(a.kind, b.kind);
    let names = |d: &Dataset| {
        d.point_data
            .iter()
            .map(|a| a.name.clone())
            .collect::<Vec<_>>()
    };
    assert_eq!(names(a), names(b));
    for (x, y) in a.point_data.iter().zip(&b.point_data) {
        assert_eq!(
            (x.num_components, &x.values),
            (y.num_components, &y.values),
            "{}",
            x.name
        );
    }
    assert_eq!(a.field_scalar("TIME"), b.field_scalar("TIME"));
}

#[test]
fn pieces_concatenate_to_the_whole() {
    for poly in [false, true] {
        let dir = tempfile::tempdir().unwrap();
        let (ext, pext) = if poly {
            ("vtp", "pvtp")
        } else {
            ("vtu", "pvtu")
        };
        let part = |r: std::ops::Range<usize>| Part {
            range: r,
            ghost: None,
        };
        let whole = write(
            dir.path(),
            &format!("whole.{ext}"),
            &xml(&[part(0..64)], poly, false),
        );
        // Uneven pieces, one of them empty (a rank without particles), in a sub-folder.
        std::fs::create_dir(dir.path().join("pieces")).unwrap();
        let mut sources = Vec::new();
        for (k, r) in [0..20, 20..20, 20..57, 57..64].into_iter().enumerate() {
            let name = format!("pieces/part_{k}.{ext}");
            write(dir.path(), &name, &xml(&[part(r)], poly, false));
            sources.push(name);
        }
        let refs: Vec<&str> = sources.iter().map(String::as_str).collect();
        let s = write(
            dir.path(),
            &format!("all.{pext}"),
            &summary(poly, &["p", "v"], &refs),
        );
        let (a, b) = (read_dataset(&s).unwrap(), read_dataset(&whole).unwrap());
        assert_eq!(a.points.len(), 64);
        same_particles(&a, &b);
        assert_eq!(a.path, s);
    }
}

#[test]
fn ghost_copies_are_dropped() {
    let dir = tempfile::tempdir().unwrap();
    let part = |r: std::ops::Range<usize>, g| Part {
        range: r,
        ghost: Some(g),
    };
    let whole = write(
        dir.path(),
        "whole.vtu",
        &xml(&[part(0..64, 0)], false, true),
    );
    // Each piece also holds a halo: copies of its neighbour's particles, marked as
    // duplicates (1) or hidden (2), or both with other bits set (1 | 8).
    write(
        dir.path(),
        "a.vtu",
        &xml(&[part(0..30, 0), part(30..36, 1)], false, true),
    );
    write(
        dir.path(),
        "b.vtu",
        &xml(&[part(24..30, 2), part(30..50, 0)], false, true),
    );
    write(
        dir.path(),
        "c.vtu",
        &xml(&[part(44..50, 9), part(50..64, 0)], false, true),
    );
    let s = write(
        dir.path(),
        "x.pvtu",
        &summary(false, &["p"], &["a.vtu", "b.vtu", "c.vtu"]),
    );
    same_particles(&read_dataset(&s).unwrap(), &read_dataset(&whole).unwrap());
}

fn refused(dir: &Path, name: &str, text: &str) -> String {
    let s = write(dir, name, text);
    let e = read_dataset(&s).expect_err("must be refused").to_string();
    assert!(e.contains(name), "'{e}' does not name {name}");
    e
}

#[test]
fn bad_summaries_and_pieces_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let part = |r| Part {
        range: r,
        ghost: None,
    };
    write(d, "a.vtu", &xml(&[part(0..10)], false, false));
    write(d, "poly.vtp", &xml(&[part(10..20)], true, false));
    let cases: Vec<(&str, String, &str)> = vec![
        (
            "missing.pvtu",
            summary(false, &["p"], &["a.vtu", "gone.vtu"]),
            "gone.vtu",
        ),
        (
            "undeclared.pvtu",
            summary(false, &["p", "rho"], &["a.vtu"]),
            "'rho'",
        ),
        (
            "kinds.pvtu",
            summary(false, &[], &["a.vtu", "poly.vtp"]),
            "PolyData",
        ),
        (
            "itself.pvtu",
            summary(false, &[], &["itself.pvtu"]),
            "not another parallel",
        ),
        ("none.pvtu", summary(false, &[], &[]), "lists no pieces"),
        ("series.pvtu", summary(false, &[], &["a.pvd"]), ".pvd"),
        (
            "nosource.pvtu",
            summary(false, &[], &[""]),
            "without a 'Source'",
        ),
        (
            "plain.pvtu",
            xml(&[part(0..3)], false, false),
            "not a parallel VTK file",
        ),
    ];
    for (name, text, want) in cases {
        let e = refused(d, name, &text);
        assert!(e.contains(want), "{name}: '{e}' does not say {want}");
    }
    // Listed pieces are named with the summary that listed them.
    let e = refused(d, "missing2.pvtu", &summary(false, &[], &["gone.vtu"]));
    assert!(e.contains("gone.vtu") && e.contains("listed in"), "{e}");
    // Cut short: no </VTKFile>.
    let full = summary(false, &["p"], &["a.vtu"]);
    let cut = &full[..full.find("</VTKFile>").unwrap()];
    let e = refused(d, "cut.pvtu", cut);
    assert!(e.contains("cut short"), "{e}");
}

/// A summary that lists more than memory holds (here one small piece 2,000 times under a
/// 1 MiB budget) is refused before any piece is read. The other tests of this binary read
/// files of a few KiB, far below that budget.
#[test]
fn a_summary_listing_more_than_memory_holds_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let part = |r| Part {
        range: r,
        ghost: None,
    };
    let a = write(dir.path(), "a.vtu", &xml(&[part(0..64)], false, false));
    let size = std::fs::metadata(&a).unwrap().len();
    let n = 2000;
    assert!(2 * n * size > 1 << 20, "the pieces must exceed the budget");
    let sources = vec!["a.vtu"; n as usize];
    std::env::set_var("FLUIDCAST_MEMORY_LIMIT", "1M");
    let e = refused(dir.path(), "many.pvtu", &summary(false, &[], &sources));
    assert!(e.contains("reading the 2000 pieces"), "{e}");
}

/// A `.pvd` series whose frames are parallel files (what a parallel run writes over time):
/// each frame reads its own pieces.
#[test]
fn a_series_of_parallel_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let part = |r| Part {
        range: r,
        ghost: None,
    };
    for (t, r) in [(0, 0..30), (1, 30..64)] {
        write(d, &format!("f{t}.vtu"), &xml(&[part(r)], false, false));
        write(
            d,
            &format!("f{t}.pvtu"),
            &summary(false, &["p"], &[&format!("f{t}.vtu")]),
        );
    }
    let pvd = write(
        d,
        "run.pvd",
        r#"<VTKFile type="Collection"><Collection>
<DataSet timestep="0.1" file="f0.pvtu"/><DataSet timestep="0.2" file="f1.pvtu"/>
</Collection></VTKFile>"#,
    );
    let input = fluidcast_io::Input::open(&pvd).unwrap();
    let counts: Vec<usize> = input
        .frames()
        .iter()
        .map(|(_, f)| input.read(f).unwrap().points.len())
        .collect();
    assert_eq!(counts, [30, 34]);
}
