//! Legacy `.vtk` (4.x and 5.1; ascii and big-endian binary) through vtkio.
//!
//! Two adaptations: VTK writes data-set-level field data (`FIELD FieldData n`, e.g. `TIME`)
//! between the `DATASET` line and `POINTS`, which vtkio's grammar does not accept, so that
//! block is cut out and parsed by vtkio on its own as a field-only file; and any panic
//! inside vtkio is caught and reported as an error naming the file.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

use vtkio::model::{Attribute, DataSet, FieldArray, IOBuffer, Piece};

use crate::xml::find;
use crate::{DataArray, Dataset, DatasetKind, ReadError, ReadErrorKind, ScalarType};

fn line_end(b: &[u8], from: usize) -> usize {
    find(b, b"\n", from).map(|p| p + 1).unwrap_or(b.len())
}

fn vtkio_parse(bytes: &[u8]) -> Result<vtkio::Vtk, String> {
    let owned = bytes.to_vec();
    match catch_unwind(AssertUnwindSafe(move || {
        vtkio::Vtk::parse_legacy_be(owned.as_slice())
    })) {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(format!("{e:?}")),
        Err(p) => Err(format!(
            "vtkio panicked: {}",
            p.downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default()
        )),
    }
}

fn buffer(buf: &IOBuffer) -> (ScalarType, Vec<f64>) {
    macro_rules! c {
        ($v:expr, $t:expr) => {
            ($t, $v.iter().map(|&x| x as f64).collect())
        };
    }
    match buf {
        IOBuffer::Bit(v) | IOBuffer::U8(v) => c!(v, ScalarType::U8),
        IOBuffer::I8(v) => c!(v, ScalarType::I8),
        IOBuffer::U16(v) => c!(v, ScalarType::U16),
        IOBuffer::I16(v) => c!(v, ScalarType::I16),
        IOBuffer::U32(v) => c!(v, ScalarType::U32),
        IOBuffer::I32(v) => c!(v, ScalarType::I32),
        IOBuffer::U64(v) => c!(v, ScalarType::U64),
        IOBuffer::I64(v) => c!(v, ScalarType::I64),
        IOBuffer::F32(v) => c!(v, ScalarType::F32),
        IOBuffer::F64(v) => c!(v, ScalarType::F64),
    }
}

fn field_arrays(arrays: &[FieldArray]) -> Vec<DataArray> {
    arrays
        .iter()
        .map(|f| {
            let (st, values) = buffer(&f.data);
            DataArray {
                name: f.name.clone(),
                scalar_type: st,
                num_components: (f.elem as usize).max(1),
                values,
            }
        })
        .collect()
}

/// VTK names 64-bit attribute arrays `vtktypeint64` / `vtktypeuint64`; vtkio only accepts
/// those names on 5.1 `OFFSETS`/`CONNECTIVITY` lines. Rename them to `long` /
/// `unsigned_long` (which vtkio reads as 64-bit) on every other line.
fn rename_int64_types(b: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let rest = &b[i..];
        let (pat, repl): (&[u8], &[u8]) = if rest.starts_with(b" vtktypeint64") {
            (b" vtktypeint64", b" long")
        } else if rest.starts_with(b" vtktypeuint64") {
            (b" vtktypeuint64", b" unsigned_long")
        } else {
            out.push(b[i]);
            i += 1;
            continue;
        };
        let line_start = b[..i]
            .iter()
            .rposition(|&c| c == b'\n')
            .map(|p| p + 1)
            .unwrap_or(0);
        let line = &b[line_start..i];
        if line.starts_with(b"OFFSETS") || line.starts_with(b"CONNECTIVITY") {
            out.extend_from_slice(pat);
        } else {
            out.extend_from_slice(repl);
        }
        i += pat.len();
    }
    out
}

pub(crate) fn parse(bytes: &[u8], path: &Path) -> Result<Dataset, ReadError> {
    let err = |k| ReadError::new(path, k);
    if !bytes.starts_with(b"# vtk DataFile") {
        return Err(err(ReadErrorKind::Format(
            "not a legacy VTK file (no '# vtk DataFile' header)".into(),
        )));
    }
    // Header: version line, title line, ASCII|BINARY line.
    let l1 = line_end(bytes, 0);
    let l2 = line_end(bytes, l1);
    let l3 = line_end(bytes, l2);
    let header = &bytes[..l3];
    let ds_line = find(bytes, b"DATASET", l3)
        .ok_or_else(|| err(ReadErrorKind::Format("no DATASET line".into())))?;
    let after_ds = line_end(bytes, ds_line);
    let mut field_data = Vec::new();
    let mut body: Vec<u8> = bytes.to_vec();
    if bytes[after_ds..].starts_with(b"FIELD") {
        let end = find(bytes, b"\nPOINTS ", after_ds)
            .map(|p| p + 1)
            .ok_or_else(|| {
                err(ReadErrorKind::Format(
                    "FIELD block not followed by POINTS".into(),
                ))
            })?;
        let mut mini = header.to_vec();
        mini.extend_from_slice(&bytes[after_ds..end]);
        let v = vtkio_parse(&mini)
            .map_err(|m| err(ReadErrorKind::Library(format!("field data: {m}"))))?;
        if let DataSet::Field { data_array, .. } = &v.data {
            field_data = field_arrays(data_array);
        }
        body = bytes[..after_ds].to_vec();
        body.extend_from_slice(&bytes[end..]);
    }
    let body = rename_int64_types(&body);
    let v = vtkio_parse(&body).map_err(|m| err(ReadErrorKind::Library(m)))?;
    let (kind, points, attrs) = match v.data {
        DataSet::UnstructuredGrid { pieces, .. } => match pieces.into_iter().next() {
            Some(Piece::Inline(p)) => (DatasetKind::UnstructuredGrid, p.points, p.data),
            _ => return Err(err(ReadErrorKind::Format("no inline piece".into()))),
        },
        DataSet::PolyData { pieces, .. } => match pieces.into_iter().next() {
            Some(Piece::Inline(p)) => (DatasetKind::PolyData, p.points, p.data),
            _ => return Err(err(ReadErrorKind::Format("no inline piece".into()))),
        },
        _ => {
            return Err(err(ReadErrorKind::Format(
                "only UNSTRUCTURED_GRID and POLYDATA legacy files hold particles".into(),
            )))
        }
    };
    let (_, pv) = buffer(&points);
    if pv.len() % 3 != 0 {
        return Err(err(ReadErrorKind::Format(
            "POINTS holds a number of values not divisible by 3".into(),
        )));
    }
    let points: Vec<[f64; 3]> = pv.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    let mut point_data = Vec::new();
    for a in &attrs.point {
        match a {
            Attribute::DataArray(d) => {
                let (st, values) = buffer(&d.data);
                point_data.push(DataArray {
                    name: d.name.clone(),
                    scalar_type: st,
                    num_components: d.elem.num_comp() as usize,
                    values,
                });
            }
            Attribute::Field { data_array, .. } => point_data.extend(field_arrays(data_array)),
        }
    }
    Ok(Dataset {
        path: path.to_path_buf(),
        kind,
        points,
        point_data,
        field_data,
    })
}
