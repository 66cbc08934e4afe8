//! `open_lazy`: a file read one array at a time (appended arrays by byte range) gives the
//! points and arrays of a whole read, for every encoding; damaged files are errors that name
//! the file, at opening or when the damaged array is decoded.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;
use std::path::Path;

use common::{fixture, shared};
use fluidcast_io::{open_lazy, read_dataset, Arrays, LazyDataset};

/// Every point array, the points and the field data of `path`, lazily and whole, agree.
fn agrees(path: &Path) {
    let whole = read_dataset(path).unwrap_or_else(|e| panic!("{e}"));
    let lazy = open_lazy(path, &Arrays::All).unwrap_or_else(|e| panic!("{e}"));
    assert!(matches!(lazy, LazyDataset::Xml(_)), "{}", path.display());
    assert_eq!(lazy.num_points(), whole.points.len(), "{}", path.display());
    let flat: Vec<f64> = whole.points.iter().flatten().copied().collect();
    assert_eq!(*lazy.points().unwrap(), flat[..], "{}", path.display());
    let names: Vec<(String, usize)> = whole
        .point_data
        .iter()
        .map(|a| (a.name.clone(), a.num_components))
        .collect();
    assert_eq!(lazy.point_arrays(), names, "{}", path.display());
    for a in &whole.point_data {
        let b = lazy.point_array(&a.name).unwrap().unwrap();
        assert_eq!(*b, *a, "{} of {}", a.name, path.display());
    }
    assert!(lazy.point_array("no such array").unwrap().is_none());
    assert_eq!(
        lazy.field_data(),
        &whole.field_data[..],
        "{}",
        path.display()
    );
}

#[test]
fn every_xml_encoding_reads_lazily_as_whole() {
    let dir = fixture("");
    let mut n = 0;
    for f in std::fs::read_dir(&dir).unwrap() {
        let f = f.unwrap().path();
        let name = f.file_name().unwrap().to_string_lossy().to_string();
        if name.starts_with("lattice_") && (name.ends_with(".vtu") || name.ends_with(".vtp")) {
            agrees(&f);
            n += 1;
        }
    }
    assert!(n >= 20, "{n} fixtures");
    for name in [
        "fault_zlib_full_last_block.vtu",
        "fault_lzma_multiblock.vtu",
        "fault_compressed_polydata.vtp",
    ] {
        agrees(&fixture(name));
    }
}

#[test]
fn shared_frames_read_lazily_as_whole() {
    let Some(root) = shared("") else {
        return;
    };
    for rel in [
        "splash_doubledambreak/DoubleDamBreak_r0.0125_0011.vtu",
        "splash_doubledambreak/DoubleDamBreak_r0.0125_0011_raw.vtp",
        "splash_doubledambreak/DoubleDamBreak_r0.0125_0011_ascii.vtu",
        "pysph_dambreak3d/dam_break_3d_fluid_01180.vtu",
    ] {
        agrees(&root.join(rel));
    }
}

/// Several pieces in one file: concatenated, and an array some piece lacks is not offered.
#[test]
fn pieces_concatenate_and_keep_common_arrays() {
    let d = tempfile::tempdir().unwrap();
    let f = d.path().join("two.vtu");
    let piece = |x: f32, extra: &str| {
        format!(
            r#"<Piece NumberOfPoints="2" NumberOfCells="0"><PointData>
<DataArray type="Float32" Name="a" format="ascii">{x} {}</DataArray>{extra}</PointData>
<Points><DataArray type="Float32" NumberOfComponents="3" format="ascii">{x} 0 0 {x} 1 0</DataArray></Points></Piece>"#,
            x + 1.0
        )
    };
    let only = r#"<DataArray type="Float32" Name="b" format="ascii">7 8</DataArray>"#;
    std::fs::write(
        &f,
        format!(
            r#"<?xml version="1.0"?><VTKFile type="UnstructuredGrid" version="1.0"><UnstructuredGrid>{}{}</UnstructuredGrid></VTKFile>"#,
            piece(1.0, only),
            piece(5.0, "")
        ),
    )
    .unwrap();
    agrees(&f);
    let lazy = open_lazy(&f, &Arrays::All).unwrap();
    assert_eq!(
        lazy.point_array("a").unwrap().unwrap().values,
        [1.0, 2.0, 5.0, 6.0]
    );
    assert!(lazy.point_array("b").unwrap().is_none());
}

/// The damage a whole read refuses, the lazy read refuses too, naming the file: each
/// fixture of `tests/fixtures` cut short at several places, and bytes overwritten.
#[test]
fn damaged_files_are_refused_lazily_too() {
    let d = tempfile::tempdir().unwrap();
    let src = std::fs::read(fixture("lattice_appended-raw_zlib_h64.vtu")).unwrap();
    let mut refused = 0;
    let mut flipped = src.clone();
    let at = flipped.len() * 2 / 3;
    flipped[at..at + 8].copy_from_slice(b"\xff\xff\xff\xff\xff\xff\xff\xff");
    let cuts = [
        src.len() - 12,
        src.len() - 30,
        src.len() / 2,
        src.len() / 3,
        200,
    ];
    let files: Vec<Vec<u8>> = cuts
        .iter()
        .map(|&c| src[..c].to_vec())
        .chain([flipped])
        .collect();
    for (k, bytes) in files.iter().enumerate() {
        let f = d.path().join(format!("damaged{k}.vtu"));
        std::fs::write(&f, bytes).unwrap();
        if read_dataset(&f).is_ok() {
            continue;
        }
        let cut = k;
        let e = match open_lazy(&f, &Arrays::All) {
            Err(e) => e.to_string(),
            Ok(lazy) => {
                let arrays: Vec<String> = lazy.point_arrays().into_iter().map(|a| a.0).collect();
                let first_error = std::iter::once(lazy.points().err())
                    .chain(arrays.iter().map(|n| lazy.point_array(n).err()))
                    .flatten()
                    .next();
                first_error
                    .unwrap_or_else(|| panic!("cut at {cut}: read lazily"))
                    .to_string()
            }
        };
        assert!(e.contains(&f.display().to_string()), "{e}");
        refused += 1;
    }
    assert!(refused >= 5, "{refused}");
}
