//! The particle-file reader's side of the bridge (`vtkFluidCastReader`): reading a file,
//! a `.pvd`'s time steps, and which files the reader takes.
//!
//! The reader hands the file's data on to VTK and ParaView as particles: points, one vertex
//! each, point data and field data. It reads no file that holds more (a mesh's cells and cell
//! data), since it would drop that; ParaView's own readers keep it.

use std::path::Path;

use fluidcast_io::{DataArray, Dataset, ReadErrorKind};

use crate::{ffi, guarded};

/// A data set read from a file, flattened for C++.
pub struct ParticleFile {
    points: Vec<f64>,
    data: Dataset,
}

pub(crate) fn read_particle_file(path: &str) -> Result<Box<ParticleFile>, String> {
    guarded("read_particle_file", || {
        let data = fluidcast_io::read_dataset(path).map_err(|e| match e.kind {
            // A structured grid or image: say which reader takes it.
            ReadErrorKind::NotParticles(_) => format!("{e}; {OTHER_READER}"),
            _ => e.to_string(),
        })?;
        if let Some(dropped) = data.cells.dropped() {
            return Err(refusal(path, &dropped));
        }
        let points = data.points.iter().flatten().copied().collect();
        Ok(Box::new(ParticleFile { points, data }))
    })
}

/// Where a file the particle reader does not take is read in full.
const OTHER_READER: &str =
    "open it with ParaView's or VTK's own reader (ParaView: OpenDataFile or File > Open)";

/// Why the particle reader does not read a mesh: what it would drop, and which reader keeps it.
pub fn refusal(path: &str, dropped: &str) -> String {
    format!(
        "{path}: holds {dropped}, which fluidcast's particle reader would drop (it keeps \
         points, vertex cells, point data and field data only), so it does not read the file; \
         {OTHER_READER}, which keeps them"
    )
}

pub(crate) fn particle_reader_claims(path: &str) -> bool {
    guarded("particle_reader_claims", || Ok(claims(Path::new(path)))).unwrap_or(false)
}

/// [`particle_reader_claims`]: a `.pvd` is claimed as its first time's data sets are.
fn claims(path: &Path) -> bool {
    if !path.is_file() {
        return false;
    }
    let Some(ext) = extension(path) else {
        return false;
    };
    if ext != "pvd" {
        return PARTICLE_EXTENSIONS.contains(&ext.as_str()) && claims_file(path);
    }
    match fluidcast_io::read_collection(path) {
        Ok(c) => c.steps().next().is_some_and(|step| {
            step.iter().all(|e| {
                extension(&e.file).is_some_and(|x| PARTICLE_EXTENSIONS.contains(&x.as_str()))
                    && claims_file(&e.file)
            })
        }),
        // A damaged .pvd: the reader names the problem.
        Err(_) => true,
    }
}

/// The data set files the particle reader reads (a `.pvd` lists them).
const PARTICLE_EXTENSIONS: [&str; 3] = ["vtu", "vtp", "vtk"];

/// A `.vtu`, `.vtp` or `.vtk` is claimed unless it holds more than particles (cells other
/// than vertices, cell data) or is no particle data at all (a structured grid); a damaged
/// one is claimed, so that the reader can say what is wrong with it.
fn claims_file(path: &Path) -> bool {
    match fluidcast_io::cells_of(path) {
        Ok(cells) => cells.only_vertices(),
        Err(e) => !matches!(
            e.kind,
            ReadErrorKind::NotParticles(_) | ReadErrorKind::UnsupportedExtension(_)
        ),
    }
}

/// The lower-case extension of `path`.
fn extension(path: &Path) -> Option<String> {
    path.extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
}

pub(crate) fn read_series(path: &str) -> Result<Vec<ffi::SeriesStep>, String> {
    guarded("read_series", || {
        let c = fluidcast_io::read_collection(path).map_err(|e| e.to_string())?;
        let file = |e: &fluidcast_io::CollectionEntry| {
            e.file.to_str().map(str::to_owned).ok_or_else(|| {
                format!(
                    "{path}: the data set file '{}' is not valid UTF-8",
                    e.file.display()
                )
            })
        };
        c.steps()
            .map(|step| {
                Ok(ffi::SeriesStep {
                    time: step.first().map_or(0.0, |e| e.timestep),
                    files: step.iter().map(file).collect::<Result<_, String>>()?,
                })
            })
            .collect()
    })
}

impl ParticleFile {
    pub(crate) fn points(&self) -> &[f64] {
        &self.points
    }
    fn arrays(&self, field_data: bool) -> &[DataArray] {
        if field_data {
            &self.data.field_data
        } else {
            &self.data.point_data
        }
    }
    pub(crate) fn array_count(&self, field_data: bool) -> usize {
        self.arrays(field_data).len()
    }
    pub(crate) fn array_name(&self, field_data: bool, i: usize) -> &str {
        self.arrays(field_data)
            .get(i)
            .map_or("", |a| a.name.as_str())
    }
    pub(crate) fn array_type(&self, field_data: bool, i: usize) -> &str {
        self.arrays(field_data)
            .get(i)
            .map_or("", |a| a.scalar_type.vtk_name())
    }
    pub(crate) fn array_components(&self, field_data: bool, i: usize) -> usize {
        self.arrays(field_data)
            .get(i)
            .map_or(0, |a| a.num_components)
    }
    pub(crate) fn array_values(&self, field_data: bool, i: usize) -> &[f64] {
        self.arrays(field_data)
            .get(i)
            .map_or(&[], |a| a.values.as_slice())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn fixture(name: &str) -> String {
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../tests/fixtures")
            .join(name)
            .to_string_lossy()
            .into_owned()
    }

    fn write(dir: &Path, name: &str, text: &str) -> String {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p.to_string_lossy().into_owned()
    }

    const MESH_VTU: &str = r#"<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian">
<UnstructuredGrid><Piece NumberOfPoints="4" NumberOfCells="1">
<Points><DataArray type="Float32" NumberOfComponents="3" format="ascii">
0 0 0 1 0 0 0 1 0 0 0 1</DataArray></Points>
<Cells>
<DataArray type="Int64" Name="connectivity" format="ascii">0 1 2 3</DataArray>
<DataArray type="Int64" Name="offsets" format="ascii">4</DataArray>
<DataArray type="UInt8" Name="types" format="ascii">10</DataArray>
</Cells>
</Piece></UnstructuredGrid></VTKFile>
"#;

    fn pvd(dir: &Path, name: &str, files: &[&str]) -> String {
        let rows: String = files
            .iter()
            .map(|f| format!("<DataSet timestep=\"0\" part=\"0\" file=\"{f}\"/>\n"))
            .collect();
        write(
            dir,
            name,
            &format!(
                "<VTKFile type=\"Collection\" version=\"0.1\"><Collection>\n{rows}\
                 </Collection></VTKFile>\n"
            ),
        )
    }

    #[test]
    fn particle_files_are_claimed() {
        for name in [
            "lattice_appended-raw_zlib_h64.vtu",
            "lattice_ascii_none_h32.vtp",
            "lattice_legacy42_ascii.vtk",
            "lattice_legacy51_binary.vtk",
            "pyvisfile_v01_base64.vtu",
            "series.pvd",
        ] {
            assert!(particle_reader_claims(&fixture(name)), "{name}");
        }
        assert!(read_particle_file(&fixture("lattice_binary_zlib_h64.vtu")).is_ok());
    }

    #[test]
    fn meshes_are_declined_and_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let mesh = write(dir.path(), "tetra.vtu", MESH_VTU);
        assert!(!particle_reader_claims(&mesh));
        let e = read_particle_file(&mesh).err().unwrap();
        assert!(
            e.starts_with(&format!(
                "{mesh}: holds 1 cell that is not vertices (1 tetra)"
            )),
            "{e}"
        );
        assert!(e.contains("own reader"), "{e}");
        // A .pvd is declined when a data set of its first time is a mesh, beside particles too.
        let lattice = fixture("lattice_ascii_none_h64.vtu");
        assert!(!particle_reader_claims(&pvd(
            dir.path(),
            "m.pvd",
            &["tetra.vtu"]
        )));
        assert!(!particle_reader_claims(&pvd(
            dir.path(),
            "p.pvd",
            &[&lattice, "tetra.vtu"]
        )));
        assert!(particle_reader_claims(&pvd(
            dir.path(),
            "q.pvd",
            &[&lattice]
        )));
    }

    #[test]
    fn other_data_sets_and_files_are_declined() {
        let dir = tempfile::tempdir().unwrap();
        let grid = write(
            dir.path(),
            "grid.vtk",
            "# vtk DataFile Version 4.2\ng\nASCII\nDATASET STRUCTURED_GRID\nDIMENSIONS 1 1 1\n",
        );
        assert!(!particle_reader_claims(&grid));
        let e = read_particle_file(&grid).err().unwrap();
        assert!(
            e.contains("not particle data") && e.contains("own reader"),
            "{e}"
        );
        let text = write(dir.path(), "notes.txt", "particles");
        assert!(!particle_reader_claims(&text));
        assert!(!particle_reader_claims(&fixture("pieces.pvtu")));
        assert!(!particle_reader_claims(
            &dir.path().join("none.vtu").to_string_lossy()
        ));
        assert!(!particle_reader_claims(&dir.path().to_string_lossy()));
        write(dir.path(), "image.vti", "<VTKFile type=\"ImageData\"/>");
        assert!(!particle_reader_claims(&pvd(
            dir.path(),
            "i.pvd",
            &["image.vti"]
        )));
    }

    #[test]
    fn damaged_files_are_claimed_so_the_reader_can_say_what_is_wrong() {
        let dir = tempfile::tempdir().unwrap();
        let cut = write(dir.path(), "cut.vtu", &MESH_VTU[..MESH_VTU.len() / 2]);
        assert!(particle_reader_claims(&cut));
        assert!(read_particle_file(&cut).err().unwrap().contains("cut.vtu"));
        let bad_pvd = write(dir.path(), "bad.pvd", "<VTKFile type=\"Collection\"><Coll");
        assert!(particle_reader_claims(&bad_pvd));
    }
}
