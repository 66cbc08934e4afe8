//! Regression tests, one per known vtkio 0.7.0-rc2 fault (see ../shared/data/README.md).
//! Each fixture was written by VTK itself (tests/make_fixtures.py); the first test shows
//! vtkio really fails on them, the others that our reader layer handles them.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly
mod common;
use common::fixture;
use fluidcast_io::read_dataset;

fn lattice_z(i: usize) -> f64 {
    // make_fixtures.py: lattice(32,16,16) spacing 0.01, z = (i % 16) * 0.01 as float32
    ((i % 16) as f64 * 0.01) as f32 as f64
}

#[test]
fn vtkio_itself_fails_on_these_files() {
    for name in [
        "lattice_appended-raw_none_h64.vtu",
        "fault_zlib_full_last_block.vtu",
        "fault_compressed_polydata.vtp",
    ] {
        let path = fixture(name);
        let r = std::panic::catch_unwind(|| vtkio::Vtk::import(&path).map(|_| ()));
        match &r {
            Ok(Err(e)) => assert!(
                !format!("{e:?}").contains("feature"),
                "vtkio built without XML: {e:?}"
            ),
            Ok(Ok(())) => panic!("vtkio now reads {name}: the workaround may be obsolete"),
            Err(_) => {} // panicked, as documented
        }
    }
}

#[test]
fn appended_raw_encoding() {
    let d = read_dataset(fixture("lattice_appended-raw_none_h64.vtu")).unwrap();
    assert_eq!(d.points.len(), 256);
}

#[test]
fn zlib_last_block_of_size_zero() {
    let d = read_dataset(fixture("fault_zlib_full_last_block.vtu")).unwrap();
    assert_eq!(d.points.len(), 8192); // 8192 * 12 bytes = 3 full 32 KiB blocks
    let z = d.point_array("z").unwrap();
    for (i, v) in z.values.iter().enumerate() {
        assert_eq!(*v, lattice_z(i));
    }
}

#[test]
fn multi_block_lzma() {
    let d = read_dataset(fixture("fault_lzma_multiblock.vtu")).unwrap();
    assert_eq!(d.points.len(), 8192);
    assert_eq!(d.point_array("z").unwrap().values[8191], lattice_z(8191));
}

#[test]
fn compressed_polydata_with_empty_cell_arrays() {
    let d = read_dataset(fixture("fault_compressed_polydata.vtp")).unwrap();
    assert_eq!(d.points.len(), 256);
    assert_eq!(d.point_data.len(), 6);
}

#[test]
fn version_0_1_with_separately_padded_base64() {
    let d = read_dataset(fixture("pyvisfile_v01_base64.vtu")).unwrap();
    assert_eq!(d.points.len(), 256);
    let rho = d.point_array("rho").unwrap();
    assert_eq!(rho.values[10], 1010.0);
    assert_eq!(d.points[1], [0.0, 0.0, 0.01f32 as f64]);
}
