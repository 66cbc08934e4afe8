//! What a file holds besides particles ([`fluidcast_io::Cells`]): counted by the full read,
//! the lazy read and `cells_of` alike, on VTK-written particle files and on small meshes.
//! (`tests/python/test_cells_vs_vtk.py` holds the counts against VTK's readers in every
//! encoding.)
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // tests may fail loudly

mod common;

use std::path::{Path, PathBuf};

use common::fixture;
use fluidcast_io::{cells_of, open_lazy, read_dataset, Arrays, Cells, ReadErrorKind};

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// The cells by the full read, the lazy read and `cells_of`, which must agree.
fn cells(path: &Path) -> Cells {
    let full = read_dataset(path).unwrap().cells;
    let lazy = open_lazy(path, &Arrays::All).unwrap().cells().unwrap();
    let quick = cells_of(path).unwrap();
    assert_eq!(full, lazy, "{}", path.display());
    assert_eq!(full, quick, "{}", path.display());
    full
}

#[test]
fn vtk_written_particle_files_hold_vertices_only() {
    let dir = std::fs::read_dir(fixture("")).unwrap();
    let mut checked = 0;
    for entry in dir {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        if !name.starts_with("lattice_") {
            continue;
        }
        let c = cells(&path);
        assert!(c.only_vertices(), "{name}: {c:?}");
        assert_eq!(c.dropped(), None, "{name}");
        // make_fixtures.py gives each of the 256 particles a vertex.
        assert_eq!(c.count, 256, "{name}");
        checked += 1;
    }
    assert!(checked >= 40, "{checked} fixtures");
    // Two pieces of 256 vertices.
    assert_eq!(cells(&fixture("pieces.pvtu")).count, 512);
}

const TETRA_VTU: &str = r#"<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian">
<UnstructuredGrid><Piece NumberOfPoints="5" NumberOfCells="3">
<Points><DataArray type="Float32" NumberOfComponents="3" format="ascii">
0 0 0 1 0 0 0 1 0 0 0 1 1 1 1</DataArray></Points>
<Cells>
<DataArray type="Int64" Name="connectivity" format="ascii">0 1 2 3 4 0 1 2</DataArray>
<DataArray type="Int64" Name="offsets" format="ascii">4 5 8</DataArray>
<DataArray type="UInt8" Name="types" format="ascii">10 1 5</DataArray>
</Cells>
<CellData><DataArray type="Int32" Name="element_id" format="ascii">0 1 2</DataArray></CellData>
</Piece></UnstructuredGrid></VTKFile>
"#;

#[test]
fn a_tetrahedral_grid_names_its_cells_and_cell_data() {
    let dir = tempfile::tempdir().unwrap();
    let c = cells(&write(dir.path(), "tetra.vtu", TETRA_VTU));
    assert_eq!(c.count, 3);
    assert_eq!(
        c.other,
        vec![("tetra".to_string(), 1), ("triangle".to_string(), 1)]
    );
    assert_eq!(c.cell_arrays, vec!["element_id".to_string()]);
    assert_eq!(
        c.dropped().unwrap(),
        "2 cells that are not vertices (1 tetra, 1 triangle) and 1 cell-data array (element_id)"
    );
}

#[test]
fn poly_data_cells_are_counted_from_the_piece() {
    let dir = tempfile::tempdir().unwrap();
    let vtp = r#"<?xml version="1.0"?>
<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian">
<PolyData><Piece NumberOfPoints="4" NumberOfVerts="4" NumberOfLines="1" NumberOfStrips="0" NumberOfPolys="2">
<Points><DataArray type="Float32" NumberOfComponents="3" format="ascii">
0 0 0 1 0 0 0 1 0 0 0 1</DataArray></Points>
<Verts><DataArray type="Int64" Name="connectivity" format="ascii">0 1 2 3</DataArray>
<DataArray type="Int64" Name="offsets" format="ascii">1 2 3 4</DataArray></Verts>
<Lines><DataArray type="Int64" Name="connectivity" format="ascii">0 1</DataArray>
<DataArray type="Int64" Name="offsets" format="ascii">2</DataArray></Lines>
<Polys><DataArray type="Int64" Name="connectivity" format="ascii">0 1 2 1 2 3</DataArray>
<DataArray type="Int64" Name="offsets" format="ascii">3 6</DataArray></Polys>
</Piece></PolyData></VTKFile>
"#;
    let c = cells(&write(dir.path(), "mesh.vtp", vtp));
    assert_eq!(c.count, 7);
    assert_eq!(
        c.other,
        vec![("lines".to_string(), 1), ("polygons".to_string(), 2)]
    );
    assert!(c.cell_arrays.is_empty());
    // Vertices alone are particles.
    let verts_only = vtp
        .replace(r#"NumberOfLines="1""#, r#"NumberOfLines="0""#)
        .replace(r#"NumberOfPolys="2""#, r#"NumberOfPolys="0""#);
    let c = cells(&write(dir.path(), "verts.vtp", &verts_only));
    assert_eq!((c.count, c.only_vertices()), (4, true));
}

#[test]
fn legacy_cells_and_cell_data_are_counted() {
    let dir = tempfile::tempdir().unwrap();
    let ugrid = "# vtk DataFile Version 4.2\nmesh\nASCII\nDATASET UNSTRUCTURED_GRID\n\
                 POINTS 5 float\n0 0 0 1 0 0 0 1 0 0 0 1 1 1 1\n\
                 CELLS 2 7\n4 0 1 2 3\n1 4\nCELL_TYPES 2\n10\n1\n\
                 CELL_DATA 2\nSCALARS quality float 1\nLOOKUP_TABLE default\n0.5 1\n\
                 POINT_DATA 5\nSCALARS t float 1\nLOOKUP_TABLE default\n1 2 3 4 5\n";
    let c = cells(&write(dir.path(), "tetra.vtk", ugrid));
    assert_eq!(c.count, 2);
    assert_eq!(c.other, vec![("tetra".to_string(), 1)]);
    assert_eq!(c.cell_arrays, vec!["quality".to_string()]);
    // 5.1 writes offsets: POLYGONS counts one more offset than polygons.
    let poly = "# vtk DataFile Version 5.1\nmesh\nASCII\nDATASET POLYDATA\n\
                POINTS 4 float\n0 0 0 1 0 0 0 1 0 0 0 1\n\
                VERTICES 3 2\nOFFSETS vtktypeint64\n0 1 2\nCONNECTIVITY vtktypeint64\n0 3\n\
                POLYGONS 3 6\nOFFSETS vtktypeint64\n0 3 6\nCONNECTIVITY vtktypeint64\n\
                0 1 2 1 2 3\n";
    let c = cells(&write(dir.path(), "poly.vtk", poly));
    assert_eq!(c.count, 4);
    assert_eq!(c.other, vec![("polygons".to_string(), 2)]);
}

#[test]
fn structured_data_sets_are_not_particles() {
    let dir = tempfile::tempdir().unwrap();
    let legacy = write(
        dir.path(),
        "grid.vtk",
        "# vtk DataFile Version 4.2\ngrid\nASCII\nDATASET STRUCTURED_POINTS\n\
         DIMENSIONS 2 2 2\nORIGIN 0 0 0\nSPACING 1 1 1\n",
    );
    let image = write(
        dir.path(),
        "image.vtu",
        r#"<?xml version="1.0"?><VTKFile type="ImageData" version="1.0"><ImageData WholeExtent="0 1 0 1 0 1"><Piece Extent="0 1 0 1 0 1"></Piece></ImageData></VTKFile>"#,
    );
    for path in [legacy, image] {
        let e = cells_of(&path).unwrap_err();
        assert!(
            matches!(e.kind, ReadErrorKind::NotParticles(_)),
            "{}: {e}",
            path.display()
        );
        assert!(e.to_string().contains("not particle data"), "{e}");
    }
}

#[test]
fn a_grid_with_cells_but_no_types_is_damaged() {
    let dir = tempfile::tempdir().unwrap();
    let no_types = TETRA_VTU.replace(
        r#"<DataArray type="UInt8" Name="types" format="ascii">10 1 5</DataArray>"#,
        "",
    );
    let e = cells_of(write(dir.path(), "no_types.vtu", &no_types)).unwrap_err();
    assert!(matches!(e.kind, ReadErrorKind::Format(_)), "{e}");
    assert!(e.to_string().contains("no cell 'types' array"), "{e}");
    let short = TETRA_VTU.replace(">10 1 5<", ">10 1<");
    let e = cells_of(write(dir.path(), "short.vtu", &short)).unwrap_err();
    assert!(e.to_string().contains("types"), "{e}");
}
