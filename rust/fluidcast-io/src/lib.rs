//! Reading SPH particle output from VTK files.
//!
//! Supported inputs:
//! * VTK XML `.vtu` (UnstructuredGrid) and `.vtp` (PolyData), every encoding VTK and
//!   ParaView write: ascii, inline base64, appended base64, appended raw; uncompressed or
//!   zlib / lz4 / lzma compressed; UInt32 or UInt64 headers; little or big endian; XML
//!   version 0.1 files whose base64 header and data are padded separately (pyvisfile).
//!   These are read by our own parser ([`xml`]) because vtkio 0.7.0-rc2 rejects appended
//!   raw data, zlib arrays with a full last block, multi-block lzma arrays and compressed
//!   `.vtp` files (see `tests/vtkio_faults.rs`).
//! * `.pvd` collections ([`read_collection`]), each data set with its `timestep`.
//! * Parallel `.pvtu` / `.pvtp` files ([`parse_parallel`]): their pieces read in parallel and
//!   concatenated, ghost points dropped (module `parallel`).
//! * Legacy `.vtk` 2.0 to 5.1 (ascii and big-endian binary) by our own parser (module `legacy`),
//!   whose errors name the line.
//!
//! Damaged or hostile files are errors naming the file, never panics or allocations of what
//! a header claims: binary sizes are checked against the XML and the file before allocating
//! (module `payload`), and whole files are read only when they fit the memory budget
//! ([`fluidcast_mem`]).
//!
//! Only the points, the point data and the field data are kept: cells are irrelevant for
//! mesh-free particles (every point is a particle, whatever cells reference it). What a
//! file has besides (cells other than vertices, cell data) is counted in [`Cells`], so that
//! a front end that hands the data on can refuse a mesh instead of dropping its cells
//! ([`cells_of`]).
#![warn(missing_docs)]
// Input must not be able to make this crate panic or truncate a size.
#![cfg_attr(
    not(test),
    deny(clippy::indexing_slicing, clippy::cast_possible_truncation)
)]

mod cells;
mod error;
mod legacy;
pub mod numbered;
mod parallel;
mod payload;
mod pvd;
pub mod xml;

use std::path::{Path, PathBuf};

pub use cells::{cell_type_name, Cells};
pub use error::{ReadError, ReadErrorKind};
pub use parallel::{parse_parallel, ParallelFile};
pub use pvd::{parse_collection, read_collection, Collection, CollectionEntry};

/// The longest path a file list (`.pvtu` piece, `.pvd` entry) may name, in bytes: Linux's
/// PATH_MAX. A longer one cannot be opened; it is refused without being echoed.
pub const MAX_PATH_BYTES: usize = 4096;

/// Refuses a path of more than [`MAX_PATH_BYTES`] bytes, naming `what` and its length only.
pub(crate) fn check_path_length(path: &str, what: &str) -> Result<(), String> {
    if path.len() > MAX_PATH_BYTES {
        return Err(format!(
            "{what} is a path of {} bytes, longer than any file system takes ({MAX_PATH_BYTES})",
            path.len()
        ));
    }
    Ok(())
}

/// The numeric type an array had in the file. Values are always held as `f64`, which
/// represents every type exactly except 64-bit integers above 2^53.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScalarType {
    /// 8-bit signed integers (`Int8`).
    I8,
    /// 8-bit unsigned (`UInt8`).
    U8,
    /// 16-bit signed (`Int16`).
    I16,
    /// 16-bit unsigned (`UInt16`).
    U16,
    /// 32-bit signed (`Int32`).
    I32,
    /// 32-bit unsigned (`UInt32`).
    U32,
    /// 64-bit signed (`Int64`).
    I64,
    /// 64-bit unsigned (`UInt64`).
    U64,
    /// Single precision (`Float32`).
    F32,
    /// Double precision (`Float64`).
    F64,
}

impl ScalarType {
    /// Parses a VTK XML type name (`Float32`, `UInt64`, …; also the legacy names
    /// `float`, `double`, `int`, `unsigned_char`, … and VTK 4 XML aliases).
    pub fn from_vtk_name(name: &str) -> Option<ScalarType> {
        use ScalarType::*;
        Some(match name {
            "Int8" | "char" | "signed_char" => I8,
            "UInt8" | "unsigned_char" | "bit" => U8,
            "Int16" | "short" => I16,
            "UInt16" | "unsigned_short" => U16,
            "Int32" | "int" => I32,
            "UInt32" | "unsigned_int" => U32,
            "Int64" | "long" | "vtktypeint64" | "long_long" | "vtkIdType" => I64,
            "UInt64" | "unsigned_long" | "vtktypeuint64" | "unsigned_long_long" => U64,
            "Float32" | "float" => F32,
            "Float64" | "double" => F64,
            _ => return None,
        })
    }

    /// Size of one value in bytes.
    pub fn size(self) -> usize {
        use ScalarType::*;
        match self {
            I8 | U8 => 1,
            I16 | U16 => 2,
            I32 | U32 | F32 => 4,
            I64 | U64 | F64 => 8,
        }
    }

    /// The VTK XML name of this type.
    pub fn vtk_name(self) -> &'static str {
        use ScalarType::*;
        match self {
            I8 => "Int8",
            U8 => "UInt8",
            I16 => "Int16",
            U16 => "UInt16",
            I32 => "Int32",
            U32 => "UInt32",
            I64 => "Int64",
            U64 => "UInt64",
            F32 => "Float32",
            F64 => "Float64",
        }
    }

    /// The inclusive range of an integer type (as `i128`); the whole `i128` range for
    /// floating-point types.
    pub fn int_range(self) -> (i128, i128) {
        use ScalarType::*;
        match self {
            I8 => (i8::MIN.into(), i8::MAX.into()),
            U8 => (0, u8::MAX.into()),
            I16 => (i16::MIN.into(), i16::MAX.into()),
            U16 => (0, u16::MAX.into()),
            I32 => (i32::MIN.into(), i32::MAX.into()),
            U32 => (0, u32::MAX.into()),
            I64 => (i64::MIN.into(), i64::MAX.into()),
            U64 => (0, u64::MAX.into()),
            F32 | F64 => (i128::MIN, i128::MAX),
        }
    }

    /// Decodes `bytes` into `f64`s; an error when they are not a whole number of values.
    pub fn decode(self, bytes: &[u8], big_endian: bool) -> Result<Vec<f64>, String> {
        let mut out = Vec::with_capacity(bytes.len() / self.size());
        self.decode_into(bytes, big_endian, &mut out)?;
        Ok(out)
    }

    /// Decodes `bytes` into `f64`s appended to `out`; an error when they are not a whole
    /// number of values.
    pub fn decode_into(
        self,
        bytes: &[u8],
        big_endian: bool,
        out: &mut Vec<f64>,
    ) -> Result<(), String> {
        use ScalarType::*;
        let n = self.size();
        if !bytes.len().is_multiple_of(n) {
            return Err(format!(
                "{} bytes are not a whole number of {} values",
                bytes.len(),
                self.vtk_name()
            ));
        }
        macro_rules! conv {
            ($t:ty) => {
                out.extend(bytes.chunks_exact(n).map(|c| {
                    let mut a = [0u8; std::mem::size_of::<$t>()];
                    a.copy_from_slice(c);
                    (if big_endian {
                        <$t>::from_be_bytes(a)
                    } else {
                        <$t>::from_le_bytes(a)
                    }) as f64
                }))
            };
        }
        match self {
            I8 => conv!(i8),
            U8 => conv!(u8),
            I16 => conv!(i16),
            U16 => conv!(u16),
            I32 => conv!(i32),
            U32 => conv!(u32),
            I64 => conv!(i64),
            U64 => conv!(u64),
            F32 => conv!(f32),
            F64 => conv!(f64),
        }
        Ok(())
    }
}

/// Groups a flat list of coordinates into points (a trailing partial point is dropped; the
/// readers check counts before).
pub(crate) fn xyz(values: &[f64]) -> impl Iterator<Item = [f64; 3]> + '_ {
    values.chunks_exact(3).map(|c| {
        let mut p = [0.0; 3];
        p.copy_from_slice(c);
        p
    })
}

/// One named array of tuples (point data or field data).
#[derive(Debug, Clone, PartialEq)]
pub struct DataArray {
    /// The array's `Name` in the file.
    pub name: String,
    /// The type the values had in the file.
    pub scalar_type: ScalarType,
    /// Components per tuple (3 for a vector).
    pub num_components: usize,
    /// Values, tuple after tuple (`num_tuples() * num_components` of them).
    pub values: Vec<f64>,
}

impl DataArray {
    /// Number of tuples.
    pub fn num_tuples(&self) -> usize {
        self.values.len() / self.num_components.max(1)
    }

    /// Minimum and maximum over all values (NaN ignored); `None` when empty or all NaN.
    pub fn range(&self) -> Option<(f64, f64)> {
        range_of(self.values.iter().copied())
    }

    /// Range of the Euclidean norm of the tuples (VTK's "Magnitude").
    pub fn magnitude_range(&self) -> Option<(f64, f64)> {
        let nc = self.num_components.max(1);
        range_of(
            self.values
                .chunks_exact(nc)
                .map(|t| t.iter().map(|v| v * v).sum::<f64>().sqrt()),
        )
    }
}

fn range_of(it: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let mut r: Option<(f64, f64)> = None;
    for v in it.filter(|v| !v.is_nan()) {
        r = Some(match r {
            None => (v, v),
            Some((a, b)) => (a.min(v), b.max(v)),
        });
    }
    r
}

/// The kind of VTK data set the particles came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DatasetKind {
    /// A `.vtu`, `.pvtu` or legacy unstructured grid.
    UnstructuredGrid,
    /// A `.vtp`, `.pvtp` or legacy poly data.
    PolyData,
}

/// Particles as read from one file: points, point data and field data, in world space
/// (the file's own units and axes).
#[derive(Debug, Clone)]
pub struct Dataset {
    /// The file this came from (used in every error message about it).
    pub path: PathBuf,
    /// Unstructured grid or poly data.
    pub kind: DatasetKind,
    /// Point coordinates; all pieces of the file concatenated.
    pub points: Vec<[f64; 3]>,
    /// Point data arrays, each with one tuple per point.
    pub point_data: Vec<DataArray>,
    /// Field data arrays (e.g. `TIME`, `support_radius`), any number of tuples.
    pub field_data: Vec<DataArray>,
    /// Point arrays the file has but the read did not decode ([`Arrays::Named`]), so that
    /// an error about a missing array can still list what the file holds.
    pub undecoded: Vec<(String, usize)>,
    /// The file's cells and cell data, which are not read: what a reader that hands the
    /// particles on as the file's data would drop ([`Cells::dropped`]).
    pub cells: Cells,
}

impl Dataset {
    /// The point array called `name`.
    pub fn point_array(&self, name: &str) -> Option<&DataArray> {
        self.point_data.iter().find(|a| a.name == name)
    }

    /// The field-data array called `name`.
    pub fn field_array(&self, name: &str) -> Option<&DataArray> {
        self.field_data.iter().find(|a| a.name == name)
    }

    /// First value of a field-data array, e.g. `support_radius` or `TIME`.
    pub fn field_scalar(&self, name: &str) -> Option<f64> {
        first_value(&self.field_data, name)
    }

    /// Every point array the file has, as (name, components): the decoded ones, then those
    /// the read left undecoded.
    pub fn point_arrays(&self) -> Vec<(String, usize)> {
        self.point_data
            .iter()
            .map(|a| (a.name.clone(), a.num_components))
            .chain(self.undecoded.iter().cloned())
            .collect()
    }

    /// Axis-aligned bounds of the finite points, `None` if there are none.
    pub fn bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        let mut any = false;
        for p in self
            .points
            .iter()
            .filter(|p| p.iter().all(|v| v.is_finite()))
        {
            any = true;
            for ((l, h), v) in lo.iter_mut().zip(hi.iter_mut()).zip(p) {
                *l = l.min(*v);
                *h = h.max(*v);
            }
        }
        any.then_some((lo, hi))
    }
}

/// The first value of the array called `name` among `arrays`.
fn first_value(arrays: &[DataArray], name: &str) -> Option<f64> {
    arrays
        .iter()
        .find(|a| a.name == name)
        .and_then(|a| a.values.first().copied())
}

/// Reads one particle file, choosing the format by extension (`.vtu`, `.vtp`, `.vtk`, and
/// `.pvtu`/`.pvtp`, whose pieces it reads too).
///
/// Point-data arrays whose tuple count differs from the point count are an error, as are
/// files with structural problems; every error names the file.
pub fn read_dataset(path: impl AsRef<Path>) -> Result<Dataset, ReadError> {
    read_dataset_with(path, &Arrays::All)
}

/// [`read_dataset`] decoding only the point arrays `arrays` selects (the points and the
/// field data are always read): a render needs a few of a file's arrays, and each array
/// not decoded is 8 bytes per value less in memory. Arrays that are not decoded are not
/// checked either. Legacy `.vtk` files are parsed whole and the rest dropped after.
pub fn read_dataset_with(path: impl AsRef<Path>, arrays: &Arrays) -> Result<Dataset, ReadError> {
    let path = path.as_ref();
    // The format first: an unsupported file (or /dev/zero) is refused before it is read.
    let format = Format::of(path)?;
    parse_as(format, &read_file(path)?, path, arrays)
}

/// Parses a particle file's bytes; `path` names it in errors and its extension chooses the
/// format. The entry point for fuzzing and for data that is not on disk.
pub fn parse_dataset(bytes: &[u8], path: &Path) -> Result<Dataset, ReadError> {
    parse_as(Format::of(path)?, bytes, path, &Arrays::All)
}

/// The cells and cell data of the particle file `path` ([`Cells`]), reading as little of
/// it as it can: the XML head and the cell types of an appended `.vtu`/`.vtp`; other files
/// (legacy, inline XML, parallel) are read whole. A file whose data set type is not
/// particles (a structured grid, image data) is [`ReadErrorKind::NotParticles`]; a damaged
/// file is the error a full read gives.
pub fn cells_of(path: impl AsRef<Path>) -> Result<Cells, ReadError> {
    match open_lazy(path, &Arrays::Named(Vec::new()))? {
        LazyDataset::Xml(x) => x.cells(),
        LazyDataset::Read(d) => Ok(d.cells),
    }
}

/// A particle file opened for reading one array at a time, so that what a render keeps of
/// an array (single precision, the particles' order) replaces it before the next one is
/// decoded: appended `.vtu`/`.vtp` files (what SPH codes and ParaView write) are read by
/// byte range, each array when asked for; other files are read at once (the arrays given).
pub enum LazyDataset {
    /// An appended XML file, read array by array by byte range.
    Xml(xml::LazyXml),
    /// Any other file, read at once.
    Read(Dataset),
}

/// Opens `path` for reading one array at a time ([`LazyDataset`]); `arrays`: what a file
/// that must be read at once keeps.
pub fn open_lazy(path: impl AsRef<Path>, arrays: &Arrays) -> Result<LazyDataset, ReadError> {
    let path = path.as_ref();
    let regular = std::fs::metadata(path).is_ok_and(|m| m.is_file());
    match Format::of(path)? {
        Format::Xml if regular => Ok(LazyDataset::Xml(xml::LazyXml::open(path)?)),
        _ => Ok(LazyDataset::Read(read_dataset_with(path, arrays)?)),
    }
}

impl LazyDataset {
    /// The file.
    pub fn path(&self) -> &Path {
        match self {
            LazyDataset::Xml(x) => x.path(),
            LazyDataset::Read(d) => &d.path,
        }
    }

    /// Number of points.
    pub fn num_points(&self) -> usize {
        match self {
            LazyDataset::Xml(x) => x.num_points(),
            LazyDataset::Read(d) => d.points.len(),
        }
    }

    /// The field data (read at open: it is small).
    pub fn field_data(&self) -> &[DataArray] {
        match self {
            LazyDataset::Xml(x) => x.field_data(),
            LazyDataset::Read(d) => &d.field_data,
        }
    }

    /// First value of a field-data array (as [`Dataset::field_scalar`]).
    pub fn field_scalar(&self, name: &str) -> Option<f64> {
        first_value(self.field_data(), name)
    }

    /// The file's cells and cell data ([`Cells`]; decoded now for an appended file).
    pub fn cells(&self) -> Result<Cells, ReadError> {
        match self {
            LazyDataset::Xml(x) => x.cells(),
            LazyDataset::Read(d) => Ok(d.cells.clone()),
        }
    }

    /// Every point array the file has, as (name, components), decoded or not.
    pub fn point_arrays(&self) -> Vec<(String, usize)> {
        match self {
            LazyDataset::Xml(x) => x.point_arrays(),
            LazyDataset::Read(d) => d.point_arrays(),
        }
    }

    /// The points, decoded now, x, y, z of each in turn (borrowed from a file read at once).
    pub fn points(&self) -> Result<std::borrow::Cow<'_, [f64]>, ReadError> {
        match self {
            LazyDataset::Xml(x) => x.points().map(std::borrow::Cow::Owned),
            LazyDataset::Read(d) => Ok(std::borrow::Cow::Borrowed(bytemuck::cast_slice(&d.points))),
        }
    }

    /// Point array `name`, decoded now; `None` when the file has no such array (in every
    /// piece, with one number of components).
    pub fn point_array(
        &self,
        name: &str,
    ) -> Result<Option<std::borrow::Cow<'_, DataArray>>, ReadError> {
        match self {
            LazyDataset::Xml(x) => Ok(x.point_array(name)?.map(std::borrow::Cow::Owned)),
            LazyDataset::Read(d) => Ok(d.point_array(name).map(std::borrow::Cow::Borrowed)),
        }
    }
}

/// Which point-data arrays a read decodes.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub enum Arrays {
    /// Every array (what `fluidcast info` shows).
    #[default]
    All,
    /// Only these names, and the ghost flags a parallel file's pieces need.
    Named(Vec<String>),
}

impl Arrays {
    /// Whether the point array `name` is to be decoded.
    pub fn wants(&self, name: &str) -> bool {
        match self {
            Arrays::All => true,
            Arrays::Named(names) => {
                name == parallel::GHOST_ARRAY || names.iter().any(|n| n == name)
            }
        }
    }
}

/// The data-set formats, chosen by extension.
#[derive(Clone, Copy)]
enum Format {
    /// `.vtu`, `.vtp`
    Xml,
    /// `.vtk`
    Legacy,
    /// `.pvtu`, `.pvtp`: a summary listing piece files.
    Parallel,
}

impl Format {
    fn of(path: &Path) -> Result<Format, ReadError> {
        let ext = extension(path);
        match ext.as_str() {
            "vtu" | "vtp" => Ok(Format::Xml),
            "vtk" => Ok(Format::Legacy),
            "pvtu" | "pvtp" => Ok(Format::Parallel),
            "pvd" => Err(ReadError::new(
                path,
                ReadErrorKind::Format(
                    "this is a .pvd collection where one data set (.vtu, .vtp or .vtk) was \
                     expected; a .pvd cannot list another .pvd"
                        .into(),
                ),
            )),
            _ => Err(ReadError::new(
                path,
                ReadErrorKind::UnsupportedExtension(ext),
            )),
        }
    }
}

fn parse_as(
    format: Format,
    bytes: &[u8],
    path: &Path,
    arrays: &Arrays,
) -> Result<Dataset, ReadError> {
    let mut ds = match format {
        Format::Xml => xml::parse_with(bytes, path, arrays),
        Format::Legacy => legacy::parse(bytes, path),
        Format::Parallel => parallel::parse(bytes, path, arrays),
    }?;
    let (kept, dropped): (Vec<DataArray>, Vec<DataArray>) = std::mem::take(&mut ds.point_data)
        .into_iter()
        .partition(|a| arrays.wants(&a.name));
    ds.point_data = kept;
    ds.undecoded
        .extend(dropped.into_iter().map(|a| (a.name, a.num_components)));
    validate(&ds)?;
    Ok(ds)
}

/// Reads one piece of a parallel file: a `.vtu`, `.vtp` or `.vtk`, never another parallel
/// file (which could list itself).
fn read_piece(path: &Path, arrays: &Arrays) -> Result<Dataset, ReadError> {
    match Format::of(path)? {
        Format::Parallel => Err(ReadError::new(
            path,
            ReadErrorKind::Format(
                "a piece of a parallel file must be a .vtu or .vtp, not another parallel file"
                    .into(),
            ),
        )),
        format => parse_as(format, &read_file(path)?, path, arrays),
    }
}

fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default()
}

/// Reads a whole regular file within the memory budget ([`fluidcast_mem::read_file`]); a
/// FIFO, socket or device is refused without blocking; errors name the file.
pub fn read_file(path: &Path) -> Result<Vec<u8>, ReadError> {
    fluidcast_mem::read_file(path).map_err(|e| file_error(path, e))
}

/// Opens a regular file for reading ([`fluidcast_mem::open_regular`]); errors name it.
pub(crate) fn open_file(path: &Path) -> Result<std::fs::File, ReadError> {
    fluidcast_mem::open_regular(path).map_err(|e| file_error(path, e))
}

fn file_error(path: &Path, e: fluidcast_mem::FileError) -> ReadError {
    use fluidcast_mem::FileError;
    let kind = match e {
        FileError::Io(io) => ReadErrorKind::Io(io),
        FileError::Directory | FileError::NotRegular(_) => ReadErrorKind::Format(e.to_string()),
        FileError::TooLarge(m) => ReadErrorKind::TooLarge(m),
    };
    ReadError::new(path, kind)
}

fn validate(ds: &Dataset) -> Result<(), ReadError> {
    let n = ds.points.len();
    for a in &ds.point_data {
        if a.num_components == 0 || a.values.len() != n * a.num_components {
            return Err(ReadError::new(
                &ds.path,
                ReadErrorKind::Format(format!(
                    "point array '{}' has {} values with {} components, but there are {} points",
                    a.name,
                    a.values.len(),
                    a.num_components,
                    n
                )),
            ));
        }
    }
    Ok(())
}

/// One frame of an [`Input`]: its time (`None` for a single file) and the file that names
/// it (for a `.pvd` time with several parts, the first; read it with [`Input::read_frame`]).
pub type Frame = (Option<f64>, PathBuf);

/// What a user pointed the tool at: one file or a time series.
#[derive(Debug, Clone)]
pub enum Input {
    /// A single `.vtu`/`.vtp`/`.vtk` file.
    File(PathBuf),
    /// A `.pvd` collection, entries sorted by time.
    Series(Collection),
}

impl Input {
    /// Opens `path`: a `.pvd` is read as a collection (not its data sets yet), anything
    /// else is a single file.
    pub fn open(path: impl AsRef<Path>) -> Result<Input, ReadError> {
        let path = path.as_ref();
        if path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.eq_ignore_ascii_case("pvd"))
            == Some(true)
        {
            Ok(Input::Series(read_collection(path)?))
        } else {
            if !path.exists() {
                return Err(ReadError::new(
                    path,
                    ReadErrorKind::Io(std::io::Error::new(
                        std::io::ErrorKind::NotFound,
                        "no such file",
                    )),
                ));
            }
            Ok(Input::File(path.to_path_buf()))
        }
    }

    /// Opens what a command line names: one file or `.pvd` ([`Input::open`]), or several
    /// files, a glob or a printf pattern as a series of numbered files
    /// ([`numbered::series_of`]).
    pub fn open_all(paths: &[PathBuf]) -> Result<Input, ReadError> {
        match numbered::series_of(paths)? {
            Some(c) => Ok(Input::Series(c)),
            None => match paths {
                [one] => Input::open(one),
                _ => Err(ReadError::new(
                    Path::new("(command line)"),
                    ReadErrorKind::Format("no input file given".into()),
                )),
            },
        }
    }

    /// Reads one of [`Input::frames`]' files; an error names the `.pvd` that listed it.
    pub fn read(&self, file: &Path) -> Result<Dataset, ReadError> {
        self.read_with(file, &Arrays::All)
    }

    /// Opens one of [`Input::frames`]' files for reading one array at a time
    /// ([`open_lazy`]); an error opening it names the `.pvd` that listed it.
    pub fn open_lazy(&self, file: &Path, arrays: &Arrays) -> Result<LazyDataset, ReadError> {
        match self {
            Input::File(_) => open_lazy(file, arrays),
            Input::Series(c) => open_lazy(file, arrays).map_err(|e| e.listed_in(&c.path)),
        }
    }

    /// [`Input::read`] decoding only the point arrays `arrays` selects.
    pub fn read_with(&self, file: &Path, arrays: &Arrays) -> Result<Dataset, ReadError> {
        match self {
            Input::File(_) => read_dataset_with(file, arrays),
            Input::Series(c) => read_dataset_with(file, arrays).map_err(|e| e.listed_in(&c.path)),
        }
    }

    /// Reads one of [`Input::frames`], decoding the point arrays `arrays` selects: its file,
    /// or every part of its time appended (points, and the point arrays every part has),
    /// named in messages as "SERIES.pvd at t = T (FIRST and N more data sets)" so that a
    /// particle index points into the appended frame, not into its first file.
    pub fn read_frame(&self, frame: &Frame, arrays: &Arrays) -> Result<Dataset, ReadError> {
        let (Input::Series(c), Some(time), Some(parts)) = (self, frame.0, self.parts_at(frame.0))
        else {
            return self.read_with(&frame.1, arrays);
        };
        let pieces = parts
            .iter()
            .map(|p| self.read_with(p, arrays))
            .collect::<Result<Vec<_>, _>>()?;
        let kind = pieces.first().map_or(DatasetKind::PolyData, |d| d.kind);
        let name = format!(
            "{} at t = {time} ({} and {} more data sets)",
            c.path.display(),
            frame.1.display(),
            parts.len() - 1
        );
        Ok(parallel::concat(Path::new(&name), kind, &pieces))
    }

    /// [`Input::open_lazy`] of one of [`Input::frames`]; a frame of several parts is read
    /// and appended at once ([`Input::read_frame`]).
    pub fn open_frame(&self, frame: &Frame, arrays: &Arrays) -> Result<LazyDataset, ReadError> {
        match self.parts_at(frame.0) {
            Some(_) => self.read_frame(frame, arrays).map(LazyDataset::Read),
            None => self.open_lazy(&frame.1, arrays),
        }
    }

    /// The files a `.pvd` lists for `time` when there are several (in its order), else None.
    fn parts_at(&self, time: Option<f64>) -> Option<Vec<PathBuf>> {
        let (Input::Series(c), Some(time)) = (self, time) else {
            return None;
        };
        let step = c
            .steps()
            .find(|s| s.first().is_some_and(|e| e.timestep == time))?;
        (step.len() > 1).then(|| step.iter().map(|e| e.file.clone()).collect())
    }

    /// Frames as (time, file); a single file has one frame at the time in its `TIME` field
    /// data if the caller reads it, reported here as `None`. A `.pvd` has one frame a time:
    /// the data sets it lists for one time (its `part`s) are one frame, named by the first
    /// of them and read appended (points, and the point arrays every part has), as ParaView
    /// shows them together.
    pub fn frames(&self) -> Vec<Frame> {
        match self {
            Input::File(p) => vec![(None, p.clone())],
            Input::Series(c) => c
                .steps()
                .filter_map(|s| s.first())
                .map(|e| (Some(e.timestep), e.file.clone()))
                .collect(),
        }
    }
}
