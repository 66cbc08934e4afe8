//! Our own VTK XML reader for `.vtu` / `.vtp` (and the `.pvd` parser's XML helpers).
//!
//! The XML head (everything before `<AppendedData>`) is parsed with quick-xml; appended data
//! is addressed by byte (raw) or character (base64) offsets, so it never goes through the XML
//! parser — raw binary is not valid XML text. Binary payloads are decoded by [`crate::payload`],
//! which checks every header against the XML and the file's length before allocating.
//!
//! The reader is as strict as VTK's: unknown byte orders, encodings, header types, formats
//! and types are errors; a file that does not end with `</VTKFile>` (truncated, or followed
//! by garbage) is an error; integer values outside their type's range are errors.

use std::collections::HashMap;
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use quick_xml::events::{BytesStart, Event};

use crate::cells::PolyCells;
use crate::payload::{decode_base64, decode_raw_values, Compressor, Ctx};
use crate::{Arrays, Cells, DataArray, Dataset, DatasetKind, ReadError, ReadErrorKind, ScalarType};

/// Attributes of one element as owned strings.
pub(crate) fn attrs(e: &BytesStart) -> Result<HashMap<String, String>, String> {
    let mut m = HashMap::new();
    for a in e.attributes() {
        let a = a.map_err(|e| e.to_string())?;
        let k = String::from_utf8_lossy(a.key.as_ref()).into_owned();
        let v = a.unescape_value().map_err(|e| e.to_string())?.into_owned();
        m.insert(k, v);
    }
    Ok(m)
}

/// The attributes of a start tag, refusing one whose text holds a `<` (an unclosed tag
/// swallowing the next one, which quick-xml would read as attribute text but expat, VTK's
/// parser, rejects).
pub(crate) fn tag_attrs(e: &BytesStart, at: u64) -> Result<HashMap<String, String>, String> {
    if e.contains(&b'<') {
        return Err(format!(
            "'<' inside the <{}> tag (an unclosed tag?) near byte {at}",
            String::from_utf8_lossy(e.name().as_ref())
        ));
    }
    attrs(e)
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Section {
    None,
    Points,
    PointData,
    FieldData,
    /// An unstructured grid's `<Cells>` (connectivity, offsets, types).
    Cells,
    CellData,
    /// A poly data's `<Verts>`, `<Lines>`, `<Strips>`, `<Polys>`.
    Other,
}

struct ArrayDecl {
    attrs: HashMap<String, String>,
    text: Vec<u8>,
    section: Section,
    piece: usize,
}

#[derive(Default)]
struct Piece {
    num_points: usize,
    /// The cells the `<Piece>` declares.
    counts: CellCounts,
    points: Option<Vec<[f64; 3]>>,
    point_data: Vec<DataArray>,
}

/// The cell counts a `<Piece>` declares: `NumberOfCells` (unstructured grid), and
/// `NumberOfVerts`, `NumberOfLines`, `NumberOfStrips`, `NumberOfPolys` (poly data).
#[derive(Default, Clone, Copy)]
struct CellCounts {
    cells: usize,
    verts: usize,
    lines: usize,
    strips: usize,
    polys: usize,
}

impl CellCounts {
    fn of(a: &HashMap<String, String>) -> Result<CellCounts, ReadErrorKind> {
        Ok(CellCounts {
            cells: parse_count(a, "NumberOfCells")?,
            verts: parse_count(a, "NumberOfVerts")?,
            lines: parse_count(a, "NumberOfLines")?,
            strips: parse_count(a, "NumberOfStrips")?,
            polys: parse_count(a, "NumberOfPolys")?,
        })
    }
}

/// Position of the first `needle` in `hay` at or after `from`.
pub(crate) fn find(hay: &[u8], needle: &[u8], from: usize) -> Option<usize> {
    hay.get(from..)?
        .windows(needle.len())
        .position(|w| w == needle)
        .map(|p| p + from)
}

/// The appended-data section: its bytes from just after the `_` marker, and its encoding.
struct Appended<'a> {
    /// The section's bytes from offset `first` on (0: all of it; a lazy read holds one
    /// array's bytes at a time).
    data: &'a [u8],
    first: usize,
    base64: bool,
    /// Where the data ends: the position of `</AppendedData>` less the whitespace before it.
    end: usize,
    /// Every array's `offset`, sorted: each payload must end where the next one starts.
    offsets: Vec<usize>,
}

impl Appended<'_> {
    /// Checks that the payload at `off`, `used` bytes long, ends exactly where the next
    /// array (or the appended data) starts: VTK writes payloads back to back, so a gap or an
    /// overlap means a header of the wrong size (`header_type` mislabelled) or damage.
    fn check_extent(&self, off: usize, used: usize) -> Result<(), String> {
        let end = off.saturating_add(used);
        let next = next_offset(&self.offsets, off, self.end);
        if end != next {
            return Err(format!(
                "its data ends at byte {end} of the appended section but the next {} at byte \
                 {next}: the header_type or an offset does not match the data",
                if next == self.end {
                    "section ends"
                } else {
                    "array starts"
                }
            ));
        }
        Ok(())
    }
}

/// Where the payload at `off` must end: at the next array's offset (`offsets` sorted), or at
/// `end`, the end of the appended data.
fn next_offset(offsets: &[usize], off: usize, end: usize) -> usize {
    offsets.iter().copied().find(|&o| o > off).unwrap_or(end)
}

/// Splits the file into the XML head and the appended data, checking the `<AppendedData>`
/// tag's encoding and that the file ends with `</AppendedData></VTKFile>`.
fn split_appended(bytes: &[u8]) -> Result<(&[u8], Option<Appended<'_>>), ReadErrorKind> {
    let Some(tag) = appended_tag(bytes)? else {
        return Ok((bytes, None));
    };
    let data = bytes.get(tag.data..).unwrap_or_default();
    let appended = Appended {
        data,
        first: 0,
        base64: tag.base64,
        end: appended_end(data)?,
        offsets: Vec::new(),
    };
    Ok((bytes.get(..tag.start).unwrap_or_default(), Some(appended)))
}

/// Where the `<AppendedData>` tag starts, where its data starts (after the `_` marker) and
/// whether it is base64; `None` when `bytes` has no such tag. `bytes` may be just the
/// start of the file, as long as it reaches the marker.
struct AppendedTag {
    start: usize,
    data: usize,
    base64: bool,
}

fn appended_tag(bytes: &[u8]) -> Result<Option<AppendedTag>, ReadErrorKind> {
    let Some(start) = find(bytes, b"<AppendedData", 0) else {
        return Ok(None);
    };
    let close = find(bytes, b">", start)
        .ok_or_else(|| ReadErrorKind::Truncated("unterminated <AppendedData> tag".into()))?;
    let tag = bytes.get(start + 1..close).unwrap_or_default();
    let tag = tag.strip_suffix(b"/").unwrap_or(tag);
    let encoding = attrs(&BytesStart::from_content(
        String::from_utf8_lossy(tag),
        "AppendedData".len(),
    ))
    .map_err(|m| ReadErrorKind::Xml(format!("<AppendedData>: {m}")))?
    .get("encoding")
    .cloned()
    .unwrap_or_else(|| "raw".into());
    let base64 = match encoding.as_str() {
        "raw" => false,
        "base64" => true,
        o => {
            return Err(ReadErrorKind::Format(format!(
                "unknown <AppendedData> encoding '{o}' (VTK writes 'raw' or 'base64')"
            )))
        }
    };
    let rest = bytes.get(close + 1..).unwrap_or_default();
    let lead = rest.iter().take_while(|c| c.is_ascii_whitespace()).count();
    if rest.get(lead) != Some(&b'_') {
        return Err(ReadErrorKind::Truncated(
            "appended data does not start with the '_' marker".into(),
        ));
    }
    Ok(Some(AppendedTag {
        start,
        data: close + 1 + lead + 1,
        base64,
    }))
}

/// The length of the appended data less the `</AppendedData></VTKFile>` (and whitespace)
/// that must close the file; `data` may be just the end of the data.
fn appended_end(data: &[u8]) -> Result<usize, ReadErrorKind> {
    trim_end(data)
        .strip_suffix(b"</VTKFile>")
        .map(trim_end)
        .and_then(|b| b.strip_suffix(b"</AppendedData>"))
        .map(|b| trim_end(b).len())
        .ok_or_else(|| {
            ReadErrorKind::Truncated(
                "the file does not end with </AppendedData></VTKFile> (cut short, or \
                 garbage after the end)"
                    .into(),
            )
        })
}

fn trim_end(b: &[u8]) -> &[u8] {
    let n = b
        .iter()
        .rev()
        .take_while(|c| c.is_ascii_whitespace())
        .count();
    b.get(..b.len() - n).unwrap_or_default()
}

/// What the XML head declares.
struct Head {
    file_attrs: HashMap<String, String>,
    kind: DatasetKind,
    pieces: Vec<Piece>,
    decls: Vec<ArrayDecl>,
}

/// Walks the XML head and collects the pieces and array declarations.
struct HeadParser {
    file_attrs: Option<HashMap<String, String>>,
    kind: Option<DatasetKind>,
    section: Section,
    pieces: Vec<Piece>,
    decls: Vec<ArrayDecl>,
    open_array: Option<ArrayDecl>,
    /// Depth of elements nested inside the open DataArray (VTK writes <InformationKey>s
    /// there, whose text is not array data).
    nested: usize,
    /// Open elements, to tell a complete document from a truncated one.
    depth: usize,
    root_closed: bool,
}

impl HeadParser {
    fn start(&mut self, e: &BytesStart, empty: bool, at: u64) -> Result<(), ReadErrorKind> {
        let a = tag_attrs(e, at).map_err(ReadErrorKind::Xml)?;
        if self.root_closed {
            return Err(ReadErrorKind::Format(format!(
                "content after </VTKFile> near byte {at}"
            )));
        }
        self.depth += usize::from(!empty);
        if self.open_array.is_some() {
            self.nested += usize::from(!empty);
            return Ok(());
        }
        match e.name().as_ref() {
            b"VTKFile" => self.file_attrs = Some(a),
            b"UnstructuredGrid" => self.kind = Some(DatasetKind::UnstructuredGrid),
            b"PolyData" => self.kind = Some(DatasetKind::PolyData),
            b"Piece" => self.pieces.push(Piece {
                num_points: parse_count(&a, "NumberOfPoints")?,
                counts: CellCounts::of(&a)?,
                ..Default::default()
            }),
            b"Points" if !empty => self.section = Section::Points,
            b"PointData" if !empty => self.section = Section::PointData,
            b"FieldData" if !empty => self.section = Section::FieldData,
            b"Cells" if !empty => self.section = Section::Cells,
            b"CellData" if !empty => self.section = Section::CellData,
            b"Verts" | b"Lines" | b"Strips" | b"Polys" if !empty => self.section = Section::Other,
            b"DataArray" | b"Array" => {
                let decl = ArrayDecl {
                    attrs: a,
                    text: Vec::new(),
                    section: self.section,
                    piece: self.pieces.len().saturating_sub(1),
                };
                if empty {
                    self.decls.push(decl);
                } else {
                    self.open_array = Some(decl);
                }
            }
            b"ImageData" | b"RectilinearGrid" | b"StructuredGrid" => {
                return Err(ReadErrorKind::NotParticles(format!(
                    "{} files are not particle data (expected UnstructuredGrid or PolyData)",
                    String::from_utf8_lossy(e.name().as_ref())
                )))
            }
            _ => {}
        }
        Ok(())
    }

    fn end(&mut self, name: &[u8]) {
        self.depth = self.depth.saturating_sub(1);
        if self.nested > 0 {
            self.nested -= 1;
            return;
        }
        match name {
            b"DataArray" | b"Array" => {
                if let Some(d) = self.open_array.take() {
                    self.decls.push(d);
                }
            }
            b"Points" | b"PointData" | b"FieldData" | b"CellData" | b"Cells" | b"Verts"
            | b"Lines" | b"Strips" | b"Polys" => self.section = Section::None,
            b"VTKFile" => self.root_closed = true,
            _ => {}
        }
    }

    fn text(&mut self, t: &[u8], cdata: bool, at: u64) -> Result<(), ReadErrorKind> {
        if self.root_closed {
            return Err(ReadErrorKind::Format(format!(
                "content after </VTKFile> near byte {at}"
            )));
        }
        if self.nested > 0 {
            return Ok(());
        }
        if let Some(d) = self.open_array.as_mut() {
            if !cdata {
                d.text.push(b' ');
            }
            d.text.extend_from_slice(t);
        }
        Ok(())
    }
}

/// Parses the XML head; `appended` says whether the file continues with appended data
/// (then `<VTKFile>` is still open where the head ends).
fn parse_head(head: &[u8], appended: bool) -> Result<Head, ReadErrorKind> {
    let mut reader = quick_xml::Reader::from_reader(head);
    reader.config_mut().trim_text(true);
    let mut p = HeadParser {
        file_attrs: None,
        kind: None,
        section: Section::None,
        pieces: Vec::new(),
        decls: Vec::new(),
        open_array: None,
        nested: 0,
        depth: 0,
        root_closed: false,
    };
    loop {
        let at = reader.buffer_position();
        let ev = reader
            .read_event()
            .map_err(|e| ReadErrorKind::Xml(format!("{e} (near byte {at})")))?;
        match ev {
            Event::Start(ref e) => p.start(e, false, at)?,
            Event::Empty(ref e) => p.start(e, true, at)?,
            Event::Text(t) => p.text(t.as_ref(), false, at)?,
            Event::CData(t) => p.text(t.as_ref(), true, at)?,
            Event::End(e) => p.end(e.name().as_ref()),
            Event::Eof => break,
            _ => {}
        }
    }
    let fa = p
        .file_attrs
        .ok_or_else(|| ReadErrorKind::Format("not a VTK XML file (no <VTKFile> element)".into()))?;
    let complete = if appended {
        p.depth == 1 && !p.root_closed
    } else {
        p.root_closed
    };
    if !complete {
        return Err(ReadErrorKind::Truncated(format!(
            "the XML ends with {} element(s) still open (expected the file to end with \
             </VTKFile>)",
            p.depth
        )));
    }
    let kind = p.kind.ok_or_else(|| {
        ReadErrorKind::Format(format!(
            "no <UnstructuredGrid> or <PolyData> element (VTKFile type is '{}'; only those \
             two hold particles)",
            fa.get("type").map(String::as_str).unwrap_or("?")
        ))
    })?;
    if p.pieces.is_empty() {
        return Err(ReadErrorKind::Format("no <Piece> element".into()));
    }
    Ok(Head {
        file_attrs: fa,
        kind,
        pieces: p.pieces,
        decls: p.decls,
    })
}

/// The binary layout declared by the `<VTKFile>` attributes, strictly checked.
fn file_ctx(fa: &HashMap<String, String>) -> Result<Ctx, ReadErrorKind> {
    let big_endian = match fa.get("byte_order").map(String::as_str) {
        None | Some("LittleEndian") => false,
        Some("BigEndian") => true,
        Some(o) => {
            return Err(ReadErrorKind::Format(format!(
                "unknown byte_order '{o}' (expected LittleEndian or BigEndian)"
            )))
        }
    };
    let header = match fa.get("header_type").map(String::as_str) {
        None | Some("UInt32") => ScalarType::U32,
        Some("UInt64") => ScalarType::U64,
        Some(o) => {
            return Err(ReadErrorKind::Format(format!(
                "unsupported header_type '{o}' (expected UInt32 or UInt64)"
            )))
        }
    };
    let compressor = match fa.get("compressor").map(String::as_str) {
        None | Some("") => None,
        Some("vtkZLibDataCompressor") => Some(Compressor::Zlib),
        Some("vtkLZ4DataCompressor") => Some(Compressor::Lz4),
        Some("vtkLZMADataCompressor") => Some(Compressor::Lzma),
        Some(o) => {
            return Err(ReadErrorKind::Format(format!(
                "unsupported compressor '{o}'"
            )))
        }
    };
    Ok(Ctx {
        big_endian,
        header,
        compressor,
    })
}

/// Parses a `.vtu` or `.vtp` file's bytes.
pub fn parse(bytes: &[u8], path: &Path) -> Result<Dataset, ReadError> {
    parse_with(bytes, path, &Arrays::All)
}

/// [`parse`] decoding only the point arrays `arrays` selects.
pub fn parse_with(bytes: &[u8], path: &Path, arrays: &Arrays) -> Result<Dataset, ReadError> {
    let err = |k: ReadErrorKind| ReadError::new(path, k);
    let (head, mut appended) = split_appended(bytes).map_err(err)?;
    let h = parse_head(head, appended.is_some()).map_err(err)?;
    if let Some(app) = appended.as_mut() {
        app.offsets = appended_offsets(&h.decls);
    }
    let ctx = file_ctx(&h.file_attrs).map_err(err)?;
    let counts: Vec<CellCounts> = h.pieces.iter().map(|p| p.counts).collect();
    let cells = piece_cells(h.kind, &counts, &h.decls, |d, n| {
        read_array(d, Some(n), ctx, appended.as_ref())
    })
    .map_err(err)?;
    let mut pieces = h.pieces;
    let mut field_data = Vec::new();
    let mut undecoded = Vec::new();
    // The points first: VTK writes them after the point data, and their two copies (flat
    // and grouped) are best held while nothing else is.
    let mut decls = h.decls;
    decls.sort_by_key(|d| d.section != Section::Points);
    for d in decls {
        if matches!(
            d.section,
            Section::Other | Section::None | Section::Cells | Section::CellData
        ) {
            continue; // cells and cell data are not particles' (counted in `cells`)
        }
        let name = name_of(&d);
        if d.section == Section::PointData && !arrays.wants(name) {
            if d.piece == 0 {
                undecoded.push((name.to_string(), components_of(&d)));
            }
            continue;
        }
        let expected_tuples = match d.section {
            Section::Points | Section::PointData => pieces.get(d.piece).map(|p| p.num_points),
            _ => None,
        };
        let Some(arr) = read_array(&d, expected_tuples, ctx, appended.as_ref()).map_err(err)?
        else {
            continue;
        };
        let Some(piece) = pieces.get_mut(d.piece) else {
            continue;
        };
        match d.section {
            // Grouped at once, so that the flat values are freed before the next array.
            Section::Points => piece.points = Some(crate::xyz(&arr.values).collect()),
            Section::PointData => piece.point_data.push(arr),
            Section::FieldData => field_data.push(arr),
            _ => {}
        }
    }
    let (points, point_data) = concat_pieces(pieces).map_err(err)?;
    Ok(Dataset {
        path: path.to_path_buf(),
        kind: h.kind,
        points,
        point_data,
        field_data,
        undecoded,
        cells,
    })
}

/// The cells of a file's pieces: the counts they declare, each unstructured piece's cell
/// types (its `types` array, decoded by `types` with the piece's cell count), and the
/// cell-data arrays' names.
fn piece_cells(
    kind: DatasetKind,
    counts: &[CellCounts],
    decls: &[ArrayDecl],
    mut types: impl FnMut(&ArrayDecl, usize) -> Result<Option<DataArray>, ReadErrorKind>,
) -> Result<Cells, ReadErrorKind> {
    let mut cells = Cells::default();
    for d in decls.iter().filter(|d| d.section == Section::CellData) {
        cells.add_array(name_of(d));
    }
    for (i, c) in counts.iter().enumerate() {
        match kind {
            DatasetKind::PolyData => {
                cells.add_poly(PolyCells::Verts, c.verts as u64);
                cells.add_poly(PolyCells::Lines, c.lines as u64);
                cells.add_poly(PolyCells::Strips, c.strips as u64);
                cells.add_poly(PolyCells::Polys, c.polys as u64);
            }
            DatasetKind::UnstructuredGrid if c.cells > 0 => {
                let decl = decls
                    .iter()
                    .find(|d| d.piece == i && d.section == Section::Cells && name_of(d) == "types");
                let missing = || {
                    ReadErrorKind::Format(format!(
                        "piece {i} has {} cells but no cell 'types' array",
                        c.cells
                    ))
                };
                let array = types(decl.ok_or_else(missing)?, c.cells)?.ok_or_else(missing)?;
                cells.add_types(array.values);
            }
            DatasetKind::UnstructuredGrid => {}
        }
    }
    Ok(cells)
}

/// Reads one declared array; `None` for arrays that cannot be rendered (strings).
fn read_array(
    d: &ArrayDecl,
    expected_tuples: Option<usize>,
    ctx: Ctx,
    appended: Option<&Appended>,
) -> Result<Option<DataArray>, ReadErrorKind> {
    let name = name_of(d).to_string();
    let type_name = d.attrs.get("type").map(String::as_str).unwrap_or("");
    if type_name == "String" {
        return Ok(None); // string arrays (e.g. field-data labels) cannot be rendered
    }
    let aerr = |problem: String| ReadErrorKind::Array {
        array: if name.is_empty() {
            "(unnamed)".into()
        } else {
            name.clone()
        },
        problem,
    };
    let st = ScalarType::from_vtk_name(type_name)
        .ok_or_else(|| aerr(format!("unknown type '{type_name}'")))?;
    let nc = match d.attrs.get("NumberOfComponents") {
        Some(s) => s
            .trim()
            .parse::<usize>()
            .map_err(|_| aerr(format!("bad NumberOfComponents '{s}'")))?,
        None => 1,
    };
    if nc == 0 {
        return Err(aerr("NumberOfComponents is 0".into()));
    }
    if d.section == Section::Points && nc != 3 {
        return Err(aerr(format!("points need 3 components, found {nc}")));
    }
    let expected_tuples = match (expected_tuples, d.attrs.get("NumberOfTuples")) {
        (Some(n), _) => Some(n),
        (None, Some(s)) => Some(
            s.trim()
                .parse::<usize>()
                .map_err(|_| aerr(format!("bad NumberOfTuples '{s}'")))?,
        ),
        (None, None) => None,
    };
    let expected_values = expected_tuples
        .map(|t| {
            t.checked_mul(nc)
                .ok_or_else(|| aerr(format!("{t} tuples × {nc} components overflow")))
        })
        .transpose()?;
    let expected_bytes = expected_values.and_then(|v| v.checked_mul(st.size()));
    let values = decode_values(d, st, ctx, appended, expected_bytes).map_err(&aerr)?;
    if let Some(ev) = expected_values {
        if values.len() != ev {
            return Err(aerr(format!(
                "expected {} tuples x {nc} components = {ev} values, found {}",
                expected_tuples.unwrap_or_default(),
                values.len()
            )));
        }
    }
    if !values.len().is_multiple_of(nc) {
        return Err(aerr(format!(
            "{} values do not make whole tuples of {nc} components",
            values.len()
        )));
    }
    Ok(Some(DataArray {
        name,
        scalar_type: st,
        num_components: nc,
        values,
    }))
}

/// The array's values, from whichever encoding its `format` names.
fn decode_values(
    d: &ArrayDecl,
    st: ScalarType,
    ctx: Ctx,
    appended: Option<&Appended>,
    expected_bytes: Option<usize>,
) -> Result<Vec<f64>, String> {
    let format = d.attrs.get("format").map(String::as_str).unwrap_or("ascii");
    let raw = match format {
        "ascii" => return parse_ascii(&d.text, st),
        "binary" => {
            let text: Vec<u8> = d
                .text
                .iter()
                .copied()
                .filter(|c| !c.is_ascii_whitespace())
                .collect();
            decode_base64(&text, ctx, expected_bytes)?.0
        }
        "appended" => {
            let app = appended.ok_or("format is 'appended' but the file has no <AppendedData>")?;
            let off: usize = d
                .attrs
                .get("offset")
                .and_then(|s| s.trim().parse().ok())
                .ok_or("appended array without a valid offset")?;
            let src = off
                .checked_sub(app.first)
                .and_then(|a| app.data.get(a..app.end - app.first))
                .ok_or_else(|| {
                    format!("offset {off} is beyond the end of the appended data (file truncated?)")
                })?;
            if !app.base64 {
                // Straight to values: no copy of the array's decompressed bytes beside them.
                let (values, used) = decode_raw_values(src, ctx, expected_bytes, st)?;
                app.check_extent(off, used)?;
                return Ok(values);
            }
            let (raw, used) = decode_base64(src, ctx, expected_bytes)?;
            app.check_extent(off, used)?;
            raw
        }
        o => {
            return Err(format!(
                "unknown format '{o}' (expected ascii, binary or appended)"
            ))
        }
    };
    st.decode(&raw, ctx.big_endian)
}

/// Concatenates pieces; keeps the point arrays present (same name, components) in every
/// piece.
fn concat_pieces(mut pieces: Vec<Piece>) -> Result<(Vec<[f64; 3]>, Vec<DataArray>), ReadErrorKind> {
    let mut points: Vec<[f64; 3]> = Vec::new();
    for (i, p) in pieces.iter_mut().enumerate() {
        match p.points.take() {
            Some(a) if points.is_empty() => points = a,
            Some(a) => points.extend(a),
            None if p.num_points == 0 => {}
            None => {
                return Err(ReadErrorKind::Format(format!(
                    "piece {i} has {} points but no <Points> array",
                    p.num_points
                )))
            }
        }
    }
    let mut it = pieces.into_iter();
    let mut point_data = it.next().map(|p| p.point_data).unwrap_or_default();
    for p in it {
        point_data.retain_mut(|a| {
            match p
                .point_data
                .iter()
                .find(|b| b.name == a.name && b.num_components == a.num_components)
            {
                Some(b) => {
                    a.values.extend_from_slice(&b.values);
                    true
                }
                None => false,
            }
        });
    }
    Ok((points, point_data))
}

fn parse_count(a: &HashMap<String, String>, key: &str) -> Result<usize, ReadErrorKind> {
    match a.get(key) {
        Some(s) => s
            .trim()
            .parse()
            .map_err(|_| ReadErrorKind::Format(format!("bad {key} '{s}'"))),
        None => Ok(0),
    }
}

/// Parses one ASCII token as a value of type `st`, refusing values outside its range.
pub(crate) fn parse_token(tok: &str, st: ScalarType) -> Result<f64, String> {
    let bad = || format!("cannot parse '{tok}' as {}", st.vtk_name());
    match st {
        ScalarType::F32 | ScalarType::F64 => {
            // Float32 arrays hold f32 values: round exactly as VTK's reader does.
            let v = if st == ScalarType::F32 {
                tok.parse::<f32>().map(f64::from).map_err(|_| bad())?
            } else {
                tok.parse::<f64>().map_err(|_| bad())?
            };
            let literal_inf = tok.trim_start_matches(['+', '-']).to_ascii_lowercase();
            if v.is_infinite() && !literal_inf.starts_with("inf") {
                return Err(format!("'{tok}' is out of range for {}", st.vtk_name()));
            }
            Ok(v)
        }
        _ => {
            let i = tok.parse::<i128>().map_err(|_| bad())?;
            let (lo, hi) = st.int_range();
            if i < lo || i > hi {
                return Err(format!(
                    "{tok} is out of range for {} ({lo}..={hi})",
                    st.vtk_name()
                ));
            }
            Ok(i as f64)
        }
    }
}

fn parse_ascii(text: &[u8], st: ScalarType) -> Result<Vec<f64>, String> {
    let s = std::str::from_utf8(text).map_err(|_| "ascii data is not valid text".to_string())?;
    s.split_ascii_whitespace()
        .map(|tok| parse_token(tok, st))
        .collect()
}

/// A `.vtu`/`.vtp` file read one array at a time ([`crate::LazyDataset`]): the XML head is
/// parsed when the file is opened; an appended array is read from the file, its own byte
/// range only, each time it is asked for; an inline array is decoded from the head. A
/// render then holds one array's bytes at a time, not the file.
pub struct LazyXml {
    path: PathBuf,
    kind: DatasetKind,
    ctx: Ctx,
    /// Points per piece.
    pieces: Vec<usize>,
    /// The cells each piece declares.
    counts: Vec<CellCounts>,
    /// The points' and point data's declarations.
    decls: Vec<ArrayDecl>,
    /// The cells' and cell data's declarations (read by [`LazyXml::cells`] only).
    cell_decls: Vec<ArrayDecl>,
    field_data: Vec<DataArray>,
    appended: Option<AppendedFile>,
}

/// Where a file's appended data lies: its first byte's position in the file, its length
/// less the closing tags, its encoding and every array's offset (sorted).
struct AppendedFile {
    start: u64,
    end: usize,
    base64: bool,
    offsets: Vec<usize>,
}

/// Bytes of a file's end read to find `</AppendedData></VTKFile>`.
const TAIL_BYTES: usize = 4096;

/// Reads the file's head: up to the appended data's `_` marker, or all of it when there is
/// no appended data. `Some(tag)` when there is.
fn read_head(f: &mut File, len: u64) -> Result<(Vec<u8>, Option<AppendedTag>), ReadErrorKind> {
    let mut head = Vec::new();
    let mut chunk = 1u64 << 16;
    loop {
        let before = head.len();
        let want = chunk.min(len.saturating_sub(before as u64));
        fluidcast_mem::check(|| "the file's XML head".into(), before as u64 + want)
            .map_err(|e| ReadErrorKind::TooLarge(e.to_string()))?;
        (&mut *f).take(want).read_to_end(&mut head)?;
        let at_end = head.len() as u64 >= len || head.len() == before;
        match appended_tag(&head) {
            Ok(Some(tag)) => return Ok((head, Some(tag))),
            Ok(None) if at_end => return Ok((head, None)),
            Err(e) if at_end => return Err(e),
            // No tag yet, or a tag cut at the chunk's end: read on.
            _ => chunk = chunk.saturating_mul(2),
        }
    }
}

/// Reads `len` bytes at `pos`, refusing what does not fit the memory budget.
fn read_range(f: &File, pos: u64, len: usize, what: &str) -> Result<Vec<u8>, ReadErrorKind> {
    fluidcast_mem::check(|| what.to_string(), len as u64)
        .map_err(|e| ReadErrorKind::TooLarge(e.to_string()))?;
    let mut buf = Vec::with_capacity(len);
    let mut g = f;
    g.seek(SeekFrom::Start(pos))?;
    g.take(len as u64).read_to_end(&mut buf)?;
    if buf.len() != len {
        return Err(ReadErrorKind::Truncated(format!(
            "{what}: {} of {len} bytes (the file changed while it was read?)",
            buf.len()
        )));
    }
    Ok(buf)
}

impl LazyXml {
    /// Opens a regular `.vtu`/`.vtp` file: reads and checks its head and its field data.
    pub fn open(path: &Path) -> Result<LazyXml, ReadError> {
        let err = |k: ReadErrorKind| ReadError::new(path, k);
        let mut f = crate::open_file(path)?;
        let len = f.metadata().map_err(|e| err(e.into()))?.len();
        let (mut head, tag) = read_head(&mut f, len).map_err(err)?;
        let appended = match &tag {
            None => None,
            Some(tag) => {
                let data_len = usize::try_from(len - tag.data as u64).map_err(|_| {
                    err(ReadErrorKind::TooLarge(
                        "the appended data does not fit this machine's address space".into(),
                    ))
                })?;
                let tail_len = data_len.min(TAIL_BYTES);
                let tail = read_range(&f, len - tail_len as u64, tail_len, "the file's end")
                    .map_err(err)?;
                let closing = tail_len - appended_end(&tail).map_err(err)?;
                head.truncate(tag.start);
                Some(AppendedFile {
                    start: tag.data as u64,
                    end: data_len - closing,
                    base64: tag.base64,
                    offsets: Vec::new(),
                })
            }
        };
        let h = parse_head(&head, appended.is_some()).map_err(err)?;
        drop(head);
        let ctx = file_ctx(&h.file_attrs).map_err(err)?;
        let mut lazy = LazyXml {
            path: path.to_path_buf(),
            kind: h.kind,
            ctx,
            pieces: h.pieces.iter().map(|p| p.num_points).collect(),
            counts: h.pieces.iter().map(|p| p.counts).collect(),
            decls: Vec::new(),
            cell_decls: Vec::new(),
            field_data: Vec::new(),
            appended,
        };
        if let Some(app) = lazy.appended.as_mut() {
            app.offsets = appended_offsets(&h.decls);
        }
        for d in h.decls {
            match d.section {
                Section::Points | Section::PointData => lazy.decls.push(d),
                Section::FieldData => {
                    if let Some(a) = lazy.decode(&d, None, &f).map_err(err)? {
                        lazy.field_data.push(a);
                    }
                }
                Section::Cells | Section::CellData => lazy.cell_decls.push(d),
                _ => {}
            }
        }
        Ok(lazy)
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Unstructured grid or poly data.
    pub fn kind(&self) -> DatasetKind {
        self.kind
    }

    /// The file's cells and cell data ([`Cells`]): the pieces' declared counts and, for an
    /// unstructured grid, its cell types, decoded now (one byte per cell in the file).
    pub fn cells(&self) -> Result<Cells, ReadError> {
        let err = |k: ReadErrorKind| ReadError::new(&self.path, k);
        let f = crate::open_file(&self.path)?;
        piece_cells(self.kind, &self.counts, &self.cell_decls, |d, n| {
            self.decode(d, Some(n), &f)
        })
        .map_err(err)
    }

    /// Points of all pieces.
    pub fn num_points(&self) -> usize {
        self.pieces.iter().sum()
    }

    /// The field data (read at open).
    pub fn field_data(&self) -> &[DataArray] {
        &self.field_data
    }

    /// The point arrays every piece has with the same number of components (those a full
    /// read keeps), as (name, components), in the first piece's order.
    pub fn point_arrays(&self) -> Vec<(String, usize)> {
        let of_piece = |i: usize| {
            self.decls
                .iter()
                .filter(move |d| d.section == Section::PointData && d.piece == i)
                .map(|d| (name_of(d).to_string(), components_of(d)))
        };
        let mut names: Vec<(String, usize)> = of_piece(0).collect();
        for i in 1..self.pieces.len() {
            let piece: Vec<(String, usize)> = of_piece(i).collect();
            names.retain(|a| piece.contains(a));
        }
        names
    }

    /// Decodes an array's declaration, reading an appended payload from `f`.
    fn decode(
        &self,
        d: &ArrayDecl,
        expected_tuples: Option<usize>,
        f: &File,
    ) -> Result<Option<DataArray>, ReadErrorKind> {
        let Some(app) = self.appended.as_ref().filter(|_| is_appended(d)) else {
            return read_array(d, expected_tuples, self.ctx, None);
        };
        let off: usize = d
            .attrs
            .get("offset")
            .and_then(|s| s.trim().parse().ok())
            .unwrap_or(usize::MAX);
        let next = next_offset(&app.offsets, off, app.end);
        let bytes = if off <= next {
            read_range(f, app.start + off as u64, next - off, "an array's data")?
        } else {
            Vec::new() // an offset past the end: read_array says so
        };
        let part = Appended {
            data: &bytes,
            first: off.min(next),
            base64: app.base64,
            end: next,
            offsets: app.offsets.clone(),
        };
        read_array(d, expected_tuples, self.ctx, Some(&part))
    }

    /// The declarations of `section` named `name` (any name for the points), one per piece,
    /// or `None` when a piece has none.
    fn per_piece(&self, section: Section, name: &str) -> Option<Vec<&ArrayDecl>> {
        (0..self.pieces.len())
            .map(|i| {
                self.decls.iter().find(|d| {
                    d.piece == i
                        && d.section == section
                        && (section == Section::Points || name_of(d) == name)
                })
            })
            .collect()
    }

    /// All pieces' points, decoded now: x, y, z of each point in turn (not grouped, so
    /// that the decoded values are not copied once more).
    pub fn points(&self) -> Result<Vec<f64>, ReadError> {
        let err = |k: ReadErrorKind| ReadError::new(&self.path, k);
        let f = crate::open_file(&self.path)?;
        let mut points: Vec<f64> = Vec::new();
        for (i, &n) in self.pieces.iter().enumerate() {
            let d = self
                .decls
                .iter()
                .find(|d| d.piece == i && d.section == Section::Points);
            match d {
                Some(d) => {
                    if let Some(a) = self.decode(d, Some(n), &f).map_err(err)? {
                        if points.is_empty() {
                            points = a.values;
                        } else {
                            points.extend_from_slice(&a.values);
                        }
                    }
                }
                None if n == 0 => {}
                None => {
                    return Err(err(ReadErrorKind::Format(format!(
                        "piece {i} has {n} points but no <Points> array"
                    ))))
                }
            }
        }
        Ok(points)
    }

    /// The point array `name` of all pieces, decoded now; `None` when a piece lacks it or
    /// the pieces' component counts differ.
    pub fn point_array(&self, name: &str) -> Result<Option<DataArray>, ReadError> {
        let err = |k: ReadErrorKind| ReadError::new(&self.path, k);
        let Some(decls) = self.per_piece(Section::PointData, name) else {
            return Ok(None);
        };
        if !self.point_arrays().iter().any(|(n, _)| n == name) {
            return Ok(None);
        }
        let f = crate::open_file(&self.path)?;
        let mut out: Option<DataArray> = None;
        for (d, &n) in decls.into_iter().zip(&self.pieces) {
            let Some(a) = self.decode(d, Some(n), &f).map_err(err)? else {
                return Ok(None);
            };
            match out.as_mut() {
                None => out = Some(a),
                Some(o) => o.values.extend_from_slice(&a.values),
            }
        }
        Ok(out)
    }
}

fn name_of(d: &ArrayDecl) -> &str {
    d.attrs.get("Name").map_or("", String::as_str)
}

/// Declared components (1 when not given or not a number: decoding checks it).
fn components_of(d: &ArrayDecl) -> usize {
    d.attrs
        .get("NumberOfComponents")
        .and_then(|s| s.trim().parse().ok())
        .unwrap_or(1)
}

/// Whether the array's data lies in the appended section.
fn is_appended(d: &ArrayDecl) -> bool {
    d.attrs.get("format").is_some_and(|f| f == "appended")
}

/// Every appended array's offset, sorted.
fn appended_offsets(decls: &[ArrayDecl]) -> Vec<usize> {
    let mut offsets: Vec<usize> = decls
        .iter()
        .filter(|d| is_appended(d))
        .filter_map(|d| d.attrs.get("offset").and_then(|s| s.trim().parse().ok()))
        .collect();
    offsets.sort_unstable();
    offsets
}
