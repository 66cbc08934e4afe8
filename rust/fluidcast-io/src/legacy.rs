//! Legacy `.vtk` files (versions 2.0 to 5.1, ASCII and big-endian BINARY), read by our own
//! parser so that every error names the line and what was expected.
//!
//! Only `DATASET UNSTRUCTURED_GRID` and `DATASET POLYDATA` hold particles. The parser keeps
//! the points, the point data (`SCALARS`, `VECTORS`, `NORMALS`, `TENSORS`, `TENSORS6`,
//! `TEXTURE_COORDINATES`, `COLOR_SCALARS`, `GLOBAL_IDS`, `PEDIGREE_IDS`, `FIELD` arrays) and
//! the data-set field data (`FIELD FieldData n` after `DATASET`, e.g. `TIME`); cells
//! (4.x `CELLS n size` or 5.1 `OFFSETS`/`CONNECTIVITY`), cell data, lookup tables and
//! `METADATA` blocks are skipped, the cells and cell data counted by kind and name
//! ([`crate::Cells`], from the cell sections and `CELL_TYPES`). Counts from the file are
//! checked against the bytes that remain before anything is allocated.

use std::path::Path;

use crate::cells::PolyCells;
use crate::xml::parse_token;
use crate::{Cells, DataArray, Dataset, DatasetKind, ReadError, ReadErrorKind, ScalarType};

/// A position in the file with the helpers the legacy grammar needs.
struct Cursor<'a> {
    b: &'a [u8],
    pos: usize,
    binary: bool,
    /// Where the first binary data block starts, once one was read.
    first_binary: Option<usize>,
}

type Res<T> = Result<T, String>;

impl<'a> Cursor<'a> {
    /// Where byte `at` is, for messages: its line (1-based) while only text precedes it,
    /// its byte offset once binary data does (whose bytes may hold newlines).
    fn place(&self, at: usize) -> String {
        if self.first_binary.is_some_and(|b| at > b) {
            return format!("byte {at}");
        }
        let line = 1 + self.b.iter().take(at).filter(|&&c| c == b'\n').count();
        format!("line {line}")
    }

    /// `msg` prefixed with where byte `at` is.
    fn msg(&self, at: usize, msg: impl std::fmt::Display) -> String {
        format!("{}: {msg}", self.place(at))
    }

    fn err<T>(&self, at: usize, msg: impl std::fmt::Display) -> Res<T> {
        Err(self.msg(at, msg))
    }

    fn skip_ws(&mut self) {
        while self.b.get(self.pos).is_some_and(u8::is_ascii_whitespace) {
            self.pos += 1;
        }
    }

    /// The next whitespace-separated word and where it starts, consuming nothing (binary
    /// data may follow, whose leading bytes must not be skipped as whitespace).
    fn peek(&self) -> Option<(usize, &'a str)> {
        let rest = self.b.get(self.pos..)?;
        let ws = rest.iter().take_while(|c| c.is_ascii_whitespace()).count();
        let rest = rest.get(ws..)?;
        let n = rest.iter().take_while(|c| !c.is_ascii_whitespace()).count();
        let w = rest.get(..n)?;
        (n > 0).then(|| (self.pos + ws, std::str::from_utf8(w).unwrap_or("\u{fffd}")))
    }

    /// The rest of the current line (after skipping leading whitespace), consuming its
    /// newline: binary data starts right after it.
    fn line(&mut self) -> (usize, &'a str) {
        self.skip_ws();
        let start = self.pos;
        let rest = self.b.get(start..).unwrap_or_default();
        let n = rest.iter().position(|&c| c == b'\n').unwrap_or(rest.len());
        self.pos = start + n + usize::from(n < rest.len());
        let text = std::str::from_utf8(rest.get(..n).unwrap_or_default()).unwrap_or("\u{fffd}");
        (start, text.trim_end_matches('\r'))
    }

    /// A header line split into words, its first word checked to be `key`.
    fn header(&mut self, key: &str, nargs: usize) -> Res<(usize, Vec<&'a str>)> {
        let (at, text) = self.line();
        let w: Vec<&str> = text.split_ascii_whitespace().collect();
        if !w.first().is_some_and(|k| k.eq_ignore_ascii_case(key)) || w.len() < nargs + 1 {
            return self.err(
                at,
                format!("expected '{key}' and {nargs} value(s), found '{text}'"),
            );
        }
        Ok((at, w))
    }

    fn count(&self, at: usize, w: &[&str], i: usize, what: &str) -> Res<usize> {
        match w.get(i).map(|s| s.parse::<usize>()) {
            Some(Ok(n)) => Ok(n),
            _ => self.err(at, format!("bad {what} '{}'", w.get(i).unwrap_or(&""))),
        }
    }

    /// A legacy type name; case-insensitive, as VTK's reader (hand-written files say
    /// `FLOAT`).
    fn scalar_type(&self, at: usize, name: &str) -> Res<ScalarType> {
        let lower = name.to_ascii_lowercase();
        let known = ScalarType::from_vtk_name(&lower)
            .or_else(|| (lower == "vtkidtype").then_some(ScalarType::I64));
        match known {
            Some(_) if lower == "bit" && self.binary => {
                self.err(at, "binary 'bit' arrays are not supported")
            }
            Some(t) => Ok(t),
            None if lower == "string" => self.err(at, "string arrays are not supported"),
            None => self.err(at, format!("unknown data type '{name}'")),
        }
    }

    /// `n` values of type `st` (big-endian in binary files), or a truncation error.
    fn values(&mut self, n: usize, st: ScalarType, keep: bool) -> Res<Vec<f64>> {
        let at = self.pos;
        if self.binary {
            let len = n.checked_mul(st.size());
            let bytes = len
                .and_then(|l| self.b.get(self.pos..self.pos.checked_add(l)?))
                .ok_or_else(|| {
                    self.msg(
                        at,
                        format!(
                            "{n} {} values need {} bytes, the file has {} left (file truncated?)",
                            st.vtk_name(),
                            len.map_or("too many".into(), |l| l.to_string()),
                            self.b.len().saturating_sub(self.pos)
                        ),
                    )
                })?;
            self.first_binary.get_or_insert(at);
            self.pos += bytes.len();
            return if keep {
                st.decode(bytes, true)
            } else {
                Ok(Vec::new())
            };
        }
        // Each ASCII value takes at least two bytes with its separator.
        let left = self.b.len().saturating_sub(self.pos);
        if n > left.div_ceil(2) {
            return self.err(
                at,
                format!("{n} values announced, the file has {left} bytes left (file truncated?)"),
            );
        }
        let mut out = Vec::with_capacity(if keep { n } else { 0 });
        for i in 0..n {
            let Some((tat, tok)) = self.peek() else {
                return self.err(
                    self.pos,
                    format!("file ends after {i} of {n} values (truncated?)"),
                );
            };
            let v = match tok {
                "nan" | "-nan" | "NaN" | "-NaN" => f64::NAN,
                _ => parse_token(tok, st).map_err(|m| self.msg(tat, m))?,
            };
            self.pos = tat + tok.len();
            if keep {
                out.push(v);
            }
        }
        Ok(out)
    }

    /// Skips a `METADATA` block: lines up to and including the next empty line.
    fn skip_metadata(&mut self) {
        self.line();
        loop {
            let rest = self.b.get(self.pos..).unwrap_or_default();
            if rest.is_empty() {
                return;
            }
            let n = rest.iter().position(|&c| c == b'\n').unwrap_or(rest.len());
            let blank = rest
                .get(..n)
                .is_some_and(|l| l.iter().all(u8::is_ascii_whitespace));
            self.pos += n + usize::from(n < rest.len());
            if blank {
                return;
            }
        }
    }

    /// Skips an optional `METADATA` block after an array.
    fn maybe_metadata(&mut self) {
        if self.peek().is_some_and(|(_, w)| w == "METADATA") {
            self.skip_metadata();
        }
    }
}

/// `%20`-style escapes in legacy array names (VTK writes spaces this way).
fn unescape(name: &str) -> String {
    let b = name.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = b
            .get(i + 1..i + 3)
            .and_then(|h| std::str::from_utf8(h).ok());
        match (b.get(i), hex.and_then(|h| u8::from_str_radix(h, 16).ok())) {
            (Some(b'%'), Some(v)) => {
                out.push(v);
                i += 3;
            }
            (Some(&c), _) => {
                out.push(c);
                i += 1;
            }
            (None, _) => break,
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Which attribute section the parser is in.
#[derive(Clone, Copy, PartialEq)]
enum Section {
    /// Before any `POINT_DATA`/`CELL_DATA`: `FIELD` is data-set field data.
    DataSet,
    Point(usize),
    Cell(usize),
}

#[derive(Default)]
struct Parsed {
    points: Option<Vec<[f64; 3]>>,
    point_data: Vec<DataArray>,
    field_data: Vec<DataArray>,
    point_data_count: Option<usize>,
    cells: Cells,
}

pub(crate) fn parse(bytes: &[u8], path: &Path) -> Result<Dataset, ReadError> {
    let err = |m: String| ReadError::new(path, ReadErrorKind::Format(m));
    let (kind, c) = parse_header(bytes).map_err(|k| ReadError::new(path, k))?;
    let p = parse_body(c).map_err(err)?;
    let points = p.points.ok_or_else(|| err("no POINTS section".into()))?;
    if let Some(n) = p.point_data_count.filter(|&n| n != points.len()) {
        return Err(err(format!(
            "POINT_DATA {n} does not match POINTS {}",
            points.len()
        )));
    }
    Ok(Dataset {
        path: path.to_path_buf(),
        kind,
        points,
        point_data: p.point_data,
        field_data: p.field_data,
        undecoded: Vec::new(),
        cells: p.cells,
    })
}

/// The three header lines and the `DATASET` line; a data set type other than an
/// unstructured grid or poly data is [`ReadErrorKind::NotParticles`].
fn parse_header(bytes: &[u8]) -> Result<(DatasetKind, Cursor<'_>), ReadErrorKind> {
    let (at, dataset, c) = parse_header_lines(bytes).map_err(ReadErrorKind::Format)?;
    let kind = match dataset.as_str() {
        "UNSTRUCTURED_GRID" => DatasetKind::UnstructuredGrid,
        "POLYDATA" => DatasetKind::PolyData,
        o => {
            return Err(ReadErrorKind::NotParticles(c.msg(
                at,
                format!("DATASET {o} is not particle data (only UNSTRUCTURED_GRID and POLYDATA)"),
            )))
        }
    };
    Ok((kind, c))
}

/// [`parse_header`]'s lines: where the `DATASET` line starts, its type (upper case) and the
/// cursor after it.
fn parse_header_lines(bytes: &[u8]) -> Res<(usize, String, Cursor<'_>)> {
    let mut c = Cursor {
        b: bytes,
        pos: 0,
        binary: false,
        first_binary: None,
    };
    if !bytes.starts_with(b"# vtk DataFile") {
        return Err("not a legacy VTK file (no '# vtk DataFile Version' header)".into());
    }
    c.line();
    // The title line may be empty: take it as it is, without skipping blank lines.
    let rest = bytes.get(c.pos..).unwrap_or_default();
    c.pos += rest
        .iter()
        .position(|&b| b == b'\n')
        .map_or(rest.len(), |n| n + 1);
    let (at, fmt) = c.line();
    c.binary = match fmt.trim().to_ascii_uppercase().as_str() {
        "ASCII" => false,
        "BINARY" => true,
        o => return c.err(at, format!("expected ASCII or BINARY, found '{o}'")),
    };
    let (at, w) = c.header("DATASET", 1)?;
    let dataset = w.get(1).map(|s| s.to_ascii_uppercase()).unwrap_or_default();
    Ok((at, dataset, c))
}

/// The `POINTS n type` section's coordinates.
fn points(c: &mut Cursor<'_>) -> Res<Vec<[f64; 3]>> {
    let (at, w) = c.header("POINTS", 2)?;
    let n = c.count(at, &w, 1, "point count")?;
    let st = c.scalar_type(at, w.get(2).unwrap_or(&""))?;
    let n3 = n
        .checked_mul(3)
        .ok_or_else(|| c.msg(at, "too many points"))?;
    let v = c.values(n3, st, true)?;
    let xyz = crate::xyz(&v).collect();
    c.maybe_metadata();
    Ok(xyz)
}

/// A `FIELD` section, whose arrays belong to the data set, the points or the cells as the
/// `section` it appears in.
fn field_section(c: &mut Cursor<'_>, section: Section, p: &mut Parsed) -> Res<()> {
    let tuples = match section {
        Section::DataSet => None,
        Section::Point(n) | Section::Cell(n) => Some(n),
    };
    let arrays = field(c, tuples)?;
    match section {
        Section::DataSet => p.field_data.extend(arrays),
        Section::Point(_) => p.point_data.extend(arrays),
        Section::Cell(_) => arrays.iter().for_each(|a| p.cells.add_array(&a.name)),
    }
    Ok(())
}

/// Every section after `DATASET`, keyword by keyword.
fn parse_body(mut c: Cursor<'_>) -> Res<Parsed> {
    let mut p = Parsed::default();
    let mut section = Section::DataSet;
    while let Some((at, key)) = c.peek() {
        match key.to_ascii_uppercase().as_str() {
            "POINTS" => p.points = Some(points(&mut c)?),
            // An unstructured grid's cells are counted by their CELL_TYPES.
            "CELLS" => {
                skip_cells(&mut c, key)?;
            }
            k @ ("VERTICES" | "LINES" | "POLYGONS" | "TRIANGLE_STRIPS") => {
                let kind = match k {
                    "VERTICES" => PolyCells::Verts,
                    "LINES" => PolyCells::Lines,
                    "POLYGONS" => PolyCells::Polys,
                    _ => PolyCells::Strips,
                };
                p.cells.add_poly(kind, skip_cells(&mut c, key)? as u64);
            }
            "CELL_TYPES" => {
                let (at, w) = c.header("CELL_TYPES", 1)?;
                let n = c.count(at, &w, 1, "cell count")?;
                p.cells.add_types(c.values(n, ScalarType::I32, true)?);
            }
            "METADATA" => c.skip_metadata(),
            "POINT_DATA" | "CELL_DATA" => {
                let point = key.eq_ignore_ascii_case("POINT_DATA");
                let (at, w) = c.header(key, 1)?;
                let n = c.count(at, &w, 1, "tuple count")?;
                section = if point {
                    Section::Point(n)
                } else {
                    Section::Cell(n)
                };
                if point {
                    p.point_data_count = Some(n);
                }
            }
            "FIELD" => field_section(&mut c, section, &mut p)?,
            _ => {
                let n = match section {
                    Section::Point(n) | Section::Cell(n) => n,
                    Section::DataSet => {
                        return c.err(
                            at,
                            format!("unexpected '{key}' (expected POINTS, cells or POINT_DATA)"),
                        )
                    }
                };
                match (section, attribute(&mut c, n)?) {
                    (Section::Point(_), Some(a)) => p.point_data.push(a),
                    (Section::Cell(_), Some(a)) => p.cells.add_array(&a.name),
                    _ => {}
                }
            }
        }
    }
    Ok(p)
}

/// Skips one cell section: 4.x `KEY n size` + `size` ints, or 5.1 `KEY noffsets nconn`
/// + `OFFSETS type` + values + `CONNECTIVITY type` + values. Returns its number of cells.
fn skip_cells(c: &mut Cursor<'_>, key: &str) -> Res<usize> {
    let (at, w) = c.header(key, 2)?;
    let a = c.count(at, &w, 1, "cell count")?;
    let b = c.count(at, &w, 2, "cell list size")?;
    if c.peek().is_some_and(|(_, k)| k == "OFFSETS") {
        for (k, n) in [("OFFSETS", a), ("CONNECTIVITY", b)] {
            let (at, w) = c.header(k, 1)?;
            let st = c.scalar_type(at, w.get(1).unwrap_or(&""))?;
            c.values(n, st, false)?;
        }
        // 5.1 counts the offsets, one more than the cells.
        return Ok(a.saturating_sub(1));
    }
    c.values(b, ScalarType::I32, false)?;
    Ok(a)
}

/// `FIELD name n` and its `n` arrays (`name ncomp ntuples type` + values); `tuples` is the
/// section's tuple count, which attribute arrays must match.
fn field(c: &mut Cursor<'_>, tuples: Option<usize>) -> Res<Vec<DataArray>> {
    let (at, w) = c.header("FIELD", 2)?;
    let n = c.count(at, &w, 2, "array count")?;
    let mut out = Vec::new();
    for _ in 0..n {
        let (at, line) = c.line();
        let w: Vec<&str> = line.split_ascii_whitespace().collect();
        if w.first() == Some(&"NULL_ARRAY") {
            continue;
        }
        if w.len() < 4 {
            return c.err(
                at,
                format!("expected 'name components tuples type', found '{line}'"),
            );
        }
        let nc = c.count(at, &w, 1, "component count")?;
        let nt = c.count(at, &w, 2, "tuple count")?;
        let st = c.scalar_type(at, w.get(3).unwrap_or(&""))?;
        if let Some(t) = tuples.filter(|&t| t != nt) {
            return c.err(at, format!("array has {nt} tuples, the section {t}"));
        }
        out.push(array_values(
            c,
            at,
            unescape(w.first().unwrap_or(&"")),
            st,
            nc,
            nt,
        )?);
    }
    Ok(out)
}

/// The values of an array whose header line starts at `at`: `nt` tuples of `nc` components,
/// then an optional METADATA block.
fn array_values(
    c: &mut Cursor<'_>,
    at: usize,
    name: String,
    st: ScalarType,
    nc: usize,
    nt: usize,
) -> Res<DataArray> {
    if nc == 0 {
        return c.err(at, "an array with 0 components");
    }
    let total = nt
        .checked_mul(nc)
        .ok_or_else(|| c.msg(at, "array too large"))?;
    let values = c.values(total, st, true)?;
    c.maybe_metadata();
    Ok(DataArray {
        name,
        scalar_type: st,
        num_components: nc,
        values,
    })
}

/// One attribute array of a `POINT_DATA`/`CELL_DATA` section with `n` tuples; `None` for
/// lookup tables.
fn attribute(c: &mut Cursor<'_>, n: usize) -> Res<Option<DataArray>> {
    let (at, line) = c.line();
    let w: Vec<&str> = line.split_ascii_whitespace().collect();
    let key = w
        .first()
        .map(|k| k.to_ascii_uppercase())
        .unwrap_or_default();
    let name = unescape(w.get(1).unwrap_or(&""));
    // Colour scalars and lookup tables: bytes in binary files, floats in 0..1 in ASCII ones.
    let color_type = if c.binary {
        ScalarType::U8
    } else {
        ScalarType::F32
    };
    let ty = |c: &Cursor<'_>, i: usize| c.scalar_type(at, w.get(i).unwrap_or(&""));
    let (st, nc) = match key.as_str() {
        "SCALARS" => {
            let nc = match w.get(3) {
                Some(_) => c.count(at, &w, 3, "component count")?,
                None => 1,
            };
            let st = ty(c, 2)?;
            if c.peek()
                .is_some_and(|(_, k)| k.eq_ignore_ascii_case("LOOKUP_TABLE"))
            {
                c.line();
            }
            (st, nc)
        }
        "VECTORS" | "NORMALS" => (ty(c, 2)?, 3),
        "TENSORS" => (ty(c, 2)?, 9),
        "TENSORS6" => (ty(c, 2)?, 6),
        "TEXTURE_COORDINATES" => (ty(c, 3)?, c.count(at, &w, 2, "dimension")?),
        "GLOBAL_IDS" | "PEDIGREE_IDS" => (ty(c, 2)?, 1),
        "COLOR_SCALARS" => (color_type, c.count(at, &w, 2, "component count")?),
        "LOOKUP_TABLE" => {
            let size = c.count(at, &w, 2, "table size")?;
            let total = size
                .checked_mul(4)
                .ok_or_else(|| c.msg(at, "table too large"))?;
            c.values(total, color_type, false)?;
            return Ok(None);
        }
        _ => {
            return c.err(
                at,
                format!(
                    "unexpected '{}' in a data section",
                    w.first().unwrap_or(&"")
                ),
            )
        }
    };
    array_values(c, at, name, st, nc, n).map(Some)
}
