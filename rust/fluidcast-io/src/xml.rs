//! Our own VTK XML reader for `.vtu` / `.vtp` (and the `.pvd` parser's XML helpers).
//!
//! The XML head (everything before `<AppendedData>`) is parsed with quick-xml; appended data
//! is addressed by byte (raw) or character (base64) offsets, so it never goes through the XML
//! parser — raw binary is not valid XML text.
//!
//! Binary payloads follow VTK's layout: uncompressed = `[nbytes][data]`; compressed =
//! `[nblocks][block size][last block size][compressed size]*nblocks [blocks]`, where a last
//! block size of 0 means the last block is full (VTK writes this whenever the array size is an
//! exact multiple of the block size). Header words are UInt32 or UInt64 (`header_type`).

use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

use base64::Engine;
use quick_xml::events::{BytesStart, Event};

use crate::{DataArray, Dataset, DatasetKind, ReadError, ReadErrorKind, ScalarType};

#[derive(Debug, Clone, Copy, PartialEq)]
enum Compressor {
    Zlib,
    Lz4,
    Lzma,
}

#[derive(Debug, Clone, Copy)]
struct Ctx {
    big_endian: bool,
    header: ScalarType,
    compressor: Option<Compressor>,
}

impl Ctx {
    fn hb(&self) -> usize {
        self.header.size()
    }
    fn word(&self, b: &[u8], i: usize) -> Option<u64> {
        let hb = self.hb();
        let s = b.get(i * hb..(i + 1) * hb)?;
        Some(if hb == 4 {
            let a: [u8; 4] = s.try_into().ok()?;
            (if self.big_endian {
                u32::from_be_bytes(a)
            } else {
                u32::from_le_bytes(a)
            }) as u64
        } else {
            let a: [u8; 8] = s.try_into().ok()?;
            if self.big_endian {
                u64::from_be_bytes(a)
            } else {
                u64::from_le_bytes(a)
            }
        })
    }
}

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

#[derive(Debug, Clone, Copy, PartialEq)]
enum Section {
    None,
    Points,
    PointData,
    FieldData,
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
    points: Option<DataArray>,
    point_data: Vec<DataArray>,
}

/// Position of the first `needle` in `hay` at or after `from`.
pub(crate) fn find(hay: &[u8], needle: &[u8], from: usize) -> Option<usize> {
    if from >= hay.len() {
        return None;
    }
    hay[from..]
        .windows(needle.len())
        .position(|w| w == needle)
        .map(|p| p + from)
}

/// Parses a `.vtu` or `.vtp` file's bytes.
pub fn parse(bytes: &[u8], path: &Path) -> Result<Dataset, ReadError> {
    let err = |k: ReadErrorKind| ReadError::new(path, k);
    // Split off the appended section before XML parsing.
    let (head, appended, appended_b64) = match find(bytes, b"<AppendedData", 0) {
        Some(start) => {
            let close = find(bytes, b">", start).ok_or_else(|| {
                err(ReadErrorKind::Truncated(
                    "unterminated <AppendedData> tag".into(),
                ))
            })?;
            let tag = String::from_utf8_lossy(&bytes[start..close]);
            let b64 = tag.contains("encoding=\"base64\"") || tag.contains("encoding='base64'");
            let us = find(bytes, b"_", close).ok_or_else(|| {
                err(ReadErrorKind::Truncated(
                    "appended data has no '_' marker".into(),
                ))
            })?;
            (&bytes[..start], Some(&bytes[us + 1..]), b64)
        }
        None => (bytes, None, false),
    };

    let mut reader = quick_xml::Reader::from_reader(head);
    reader.config_mut().trim_text(true);
    let mut file_attrs: Option<HashMap<String, String>> = None;
    let mut kind = None;
    let mut section = Section::None;
    let mut pieces: Vec<Piece> = Vec::new();
    let mut decls: Vec<ArrayDecl> = Vec::new();
    let mut open_array: Option<ArrayDecl> = None;
    // Depth of elements nested inside the open DataArray (VTK writes <InformationKey>s there,
    // whose text is not array data).
    let mut nested = 0usize;
    let mut field_counts: Vec<Option<usize>> = Vec::new();
    loop {
        let ev = reader.read_event().map_err(|e| {
            err(ReadErrorKind::Xml(format!(
                "{e} (at byte {})",
                reader.buffer_position()
            )))
        })?;
        match ev {
            Event::Start(ref e) | Event::Empty(ref e) => {
                let empty = matches!(ev, Event::Empty(_));
                if open_array.is_some() {
                    nested += usize::from(!empty);
                    continue;
                }
                let a = attrs(e).map_err(|m| err(ReadErrorKind::Xml(m)))?;
                match e.name().as_ref() {
                    b"VTKFile" => file_attrs = Some(a),
                    b"UnstructuredGrid" => kind = Some(DatasetKind::UnstructuredGrid),
                    b"PolyData" => kind = Some(DatasetKind::PolyData),
                    b"Piece" => {
                        let n = parse_count(&a, "NumberOfPoints").map_err(&err)?;
                        pieces.push(Piece {
                            num_points: n,
                            ..Default::default()
                        });
                    }
                    b"Points" if !empty => section = Section::Points,
                    b"PointData" if !empty => section = Section::PointData,
                    b"FieldData" if !empty => section = Section::FieldData,
                    b"CellData" | b"Cells" | b"Verts" | b"Lines" | b"Strips" | b"Polys" if !empty => {
                        section = Section::Other
                    }
                    b"DataArray" | b"Array" => {
                        let decl = ArrayDecl {
                            attrs: a,
                            text: Vec::new(),
                            section,
                            piece: pieces.len().saturating_sub(1),
                        };
                        if empty {
                            decls.push(decl);
                        } else {
                            open_array = Some(decl);
                        }
                    }
                    b"ImageData" | b"RectilinearGrid" | b"StructuredGrid" => {
                        return Err(err(ReadErrorKind::Format(format!(
                            "{} files are not particle data (expected UnstructuredGrid or PolyData)",
                            String::from_utf8_lossy(e.name().as_ref())
                        ))))
                    }
                    _ => {}
                }
            }
            Event::Text(t) if nested == 0 => {
                if let Some(d) = open_array.as_mut() {
                    d.text.push(b' ');
                    d.text.extend_from_slice(t.as_ref());
                }
            }
            Event::CData(t) if nested == 0 => {
                if let Some(d) = open_array.as_mut() {
                    d.text.extend_from_slice(t.as_ref());
                }
            }
            Event::End(_) if nested > 0 => nested -= 1,
            Event::End(e) => match e.name().as_ref() {
                b"DataArray" | b"Array" => {
                    if let Some(d) = open_array.take() {
                        decls.push(d);
                    }
                }
                b"Points" | b"PointData" | b"FieldData" | b"CellData" | b"Cells" | b"Verts"
                | b"Lines" | b"Strips" | b"Polys" => section = Section::None,
                _ => {}
            },
            Event::Eof => break,
            _ => {}
        }
    }
    let fa = file_attrs.ok_or_else(|| {
        err(ReadErrorKind::Format(
            "not a VTK XML file (no <VTKFile> element)".into(),
        ))
    })?;
    let kind = kind.ok_or_else(|| {
        err(ReadErrorKind::Format(format!(
            "VTKFile type '{}' is not supported (expected UnstructuredGrid or PolyData)",
            fa.get("type").map(String::as_str).unwrap_or("?")
        )))
    })?;
    if pieces.is_empty() {
        return Err(err(ReadErrorKind::Format("no <Piece> element".into())));
    }
    let big_endian = fa
        .get("byte_order")
        .map(|s| s == "BigEndian")
        .unwrap_or(false);
    let header = match fa.get("header_type").map(String::as_str) {
        None | Some("UInt32") => ScalarType::U32,
        Some("UInt64") => ScalarType::U64,
        Some(o) => {
            return Err(err(ReadErrorKind::Format(format!(
                "unsupported header_type '{o}'"
            ))))
        }
    };
    let compressor = match fa.get("compressor").map(String::as_str) {
        None | Some("") => None,
        Some("vtkZLibDataCompressor") => Some(Compressor::Zlib),
        Some("vtkLZ4DataCompressor") => Some(Compressor::Lz4),
        Some("vtkLZMADataCompressor") => Some(Compressor::Lzma),
        Some(o) => {
            return Err(err(ReadErrorKind::Format(format!(
                "unsupported compressor '{o}'"
            ))))
        }
    };
    let ctx = Ctx {
        big_endian,
        header,
        compressor,
    };

    let mut field_data = Vec::new();
    for d in decls {
        if matches!(d.section, Section::Other | Section::None) {
            continue; // cells and cell data do not matter for particles
        }
        let name = d.attrs.get("Name").cloned().unwrap_or_default();
        let type_name = d.attrs.get("type").map(String::as_str).unwrap_or("");
        if type_name == "String" {
            continue; // string arrays (e.g. field-data labels) cannot be rendered
        }
        let aerr = |problem: String| {
            err(ReadErrorKind::Array {
                array: if name.is_empty() {
                    "(unnamed)".into()
                } else {
                    name.clone()
                },
                problem,
            })
        };
        let st = ScalarType::from_vtk_name(type_name)
            .ok_or_else(|| aerr(format!("unknown type '{type_name}'")))?;
        let nc: usize = match d.attrs.get("NumberOfComponents") {
            Some(s) => s
                .trim()
                .parse()
                .map_err(|_| aerr(format!("bad NumberOfComponents '{s}'")))?,
            None => 1,
        };
        if nc == 0 {
            return Err(aerr("NumberOfComponents is 0".into()));
        }
        let expected_tuples = match d.section {
            Section::Points | Section::PointData => Some(pieces[d.piece].num_points),
            _ => match d.attrs.get("NumberOfTuples") {
                Some(s) => Some(
                    s.trim()
                        .parse()
                        .map_err(|_| aerr(format!("bad NumberOfTuples '{s}'")))?,
                ),
                None => None,
            },
        };
        let format = d.attrs.get("format").map(String::as_str).unwrap_or("ascii");
        let values = match format {
            "ascii" => parse_ascii(&d.text, st).map_err(&aerr)?,
            "binary" => {
                let text: Vec<u8> = d
                    .text
                    .iter()
                    .copied()
                    .filter(|c| !c.is_ascii_whitespace())
                    .collect();
                st.decode(
                    &decode_base64_payload(&text, ctx).map_err(&aerr)?,
                    big_endian,
                )
            }
            "appended" => {
                let app = appended.ok_or_else(|| {
                    aerr("format is 'appended' but the file has no <AppendedData>".into())
                })?;
                let off: usize = d
                    .attrs
                    .get("offset")
                    .and_then(|s| s.trim().parse().ok())
                    .ok_or_else(|| aerr("appended array without a valid offset".into()))?;
                let src = app.get(off..).ok_or_else(|| {
                    aerr(format!(
                        "offset {off} is beyond the end of the appended data (file truncated?)"
                    ))
                })?;
                let raw = if appended_b64 {
                    decode_base64_payload(src, ctx)
                } else {
                    decode_raw_payload(src, ctx)
                }
                .map_err(&aerr)?;
                st.decode(&raw, big_endian)
            }
            o => return Err(aerr(format!("unknown format '{o}'"))),
        };
        let arr = DataArray {
            name: name.clone(),
            scalar_type: st,
            num_components: nc,
            values,
        };
        if let Some(nt) = expected_tuples {
            if arr.values.len() != nt * nc {
                return Err(aerr(format!(
                    "expected {} tuples x {} components = {} values, found {}",
                    nt,
                    nc,
                    nt * nc,
                    arr.values.len()
                )));
            }
        }
        match d.section {
            Section::Points => {
                if nc != 3 {
                    return Err(aerr(format!("points need 3 components, found {nc}")));
                }
                pieces[d.piece].points = Some(arr);
            }
            Section::PointData => pieces[d.piece].point_data.push(arr),
            Section::FieldData => {
                field_counts.push(expected_tuples);
                field_data.push(arr)
            }
            _ => {}
        }
    }

    // Concatenate pieces; keep point arrays present (same name, components) in every piece.
    let mut points = Vec::new();
    for (i, p) in pieces.iter().enumerate() {
        match &p.points {
            Some(a) => points.extend(a.values.chunks_exact(3).map(|c| [c[0], c[1], c[2]])),
            None if p.num_points == 0 => {}
            None => {
                return Err(err(ReadErrorKind::Format(format!(
                    "piece {i} has {} points but no <Points> array",
                    p.num_points
                ))))
            }
        }
    }
    let mut point_data: Vec<DataArray> = pieces[0].point_data.clone();
    for p in &pieces[1..] {
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
    Ok(Dataset {
        path: path.to_path_buf(),
        kind,
        points,
        point_data,
        field_data,
    })
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

fn parse_ascii(text: &[u8], st: ScalarType) -> Result<Vec<f64>, String> {
    let s = std::str::from_utf8(text).map_err(|_| "ascii data is not valid text".to_string())?;
    let float = matches!(st, ScalarType::F32 | ScalarType::F64);
    s.split_ascii_whitespace()
        .map(|tok| {
            let v = if st == ScalarType::F32 {
                // Float32 arrays hold f32 values: round exactly as VTK's reader does.
                tok.parse::<f32>().ok().map(f64::from)
            } else if float {
                tok.parse::<f64>().ok()
            } else {
                tok.parse::<i128>().ok().map(|i| i as f64)
            };
            v.ok_or_else(|| format!("cannot parse '{tok}' as {}", st.vtk_name()))
        })
        .collect()
}

fn decompress(c: Compressor, data: &[u8], size: usize) -> Result<Vec<u8>, String> {
    let out = match c {
        Compressor::Zlib => {
            let mut out = Vec::with_capacity(size);
            flate2::read::ZlibDecoder::new(data)
                .read_to_end(&mut out)
                .map_err(|e| format!("zlib block: {e}"))?;
            out
        }
        Compressor::Lz4 => {
            lz4_flex::block::decompress(data, size).map_err(|e| format!("lz4 block: {e}"))?
        }
        Compressor::Lzma => {
            let mut out = Vec::with_capacity(size);
            lzma_rs::xz_decompress(&mut std::io::Cursor::new(data), &mut out)
                .map_err(|e| format!("lzma block: {e}"))?;
            out
        }
    };
    if out.len() != size {
        return Err(format!(
            "a compressed block gave {} bytes, its header says {size}",
            out.len()
        ));
    }
    Ok(out)
}

struct BlockHeader {
    block_size: usize,
    last_size: usize,
    compressed: Vec<usize>,
}

impl BlockHeader {
    fn parse(b: &[u8], ctx: Ctx) -> Result<BlockHeader, String> {
        let short = || "compression header is truncated".to_string();
        let nb = ctx.word(b, 0).ok_or_else(short)? as usize;
        if nb > b.len() {
            return Err(format!(
                "compression header claims {nb} blocks, more than the file holds"
            ));
        }
        let block_size = ctx.word(b, 1).ok_or_else(short)? as usize;
        let last = ctx.word(b, 2).ok_or_else(short)? as usize;
        let compressed = (0..nb)
            .map(|i| ctx.word(b, 3 + i).map(|w| w as usize).ok_or_else(short))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(BlockHeader {
            block_size,
            last_size: if last == 0 { block_size } else { last },
            compressed,
        })
    }
    fn len(&self, ctx: Ctx) -> usize {
        (3 + self.compressed.len()) * ctx.hb()
    }
    fn total_compressed(&self) -> usize {
        self.compressed.iter().sum()
    }
    fn inflate(&self, data: &[u8], c: Compressor) -> Result<Vec<u8>, String> {
        let nb = self.compressed.len();
        let mut out = Vec::with_capacity(nb * self.block_size);
        let mut pos = 0usize;
        for (i, &cs) in self.compressed.iter().enumerate() {
            let blk = data.get(pos..pos + cs).ok_or_else(|| {
                format!(
                    "compressed block {i} of {nb} runs past the end of the data (file truncated?)"
                )
            })?;
            let size = if i + 1 == nb {
                self.last_size
            } else {
                self.block_size
            };
            out.extend(decompress(c, blk, size)?);
            pos += cs;
        }
        Ok(out)
    }
}

/// Decodes one raw binary payload (header + data) starting at `src`.
fn decode_raw_payload(src: &[u8], ctx: Ctx) -> Result<Vec<u8>, String> {
    match ctx.compressor {
        None => {
            let n = ctx.word(src, 0).ok_or("data header is truncated")? as usize;
            let hb = ctx.hb();
            src.get(hb..hb.saturating_add(n))
                .map(<[u8]>::to_vec)
                .ok_or_else(|| {
                    format!("header says {n} bytes but the file ends first (file truncated?)")
                })
        }
        Some(c) => {
            let h = BlockHeader::parse(src, ctx)?;
            h.inflate(&src[h.len(ctx).min(src.len())..], c)
        }
    }
}

fn b64(text: &[u8]) -> Result<Vec<u8>, String> {
    base64::engine::general_purpose::STANDARD
        .decode(text)
        .map_err(|e| format!("invalid base64: {e}"))
}

fn b64_chars(nbytes: usize) -> usize {
    nbytes.div_ceil(3) * 4
}

fn b64_slice(text: &[u8], from: usize, len: usize) -> Result<&[u8], String> {
    text.get(from..from + len)
        .ok_or_else(|| "base64 data ends early (file truncated?)".to_string())
}

/// Decodes a base64 payload (header + data). VTK encodes header and data either as one
/// base64 stream or as two separately padded ones (VTK's compressed arrays, pyvisfile's
/// version 0.1 files); the two differ only where the header's last quantum holds padding.
fn decode_base64_payload(text: &[u8], ctx: Ctx) -> Result<Vec<u8>, String> {
    let hb = ctx.hb();
    match ctx.compressor {
        None => {
            let hc = b64_chars(hb);
            let head = b64(b64_slice(text, 0, hc)?)?;
            let n = ctx.word(&head, 0).ok_or("data header is truncated")? as usize;
            let separate = !hb.is_multiple_of(3) && text.get(hc - 1) == Some(&b'=');
            if separate {
                b64(b64_slice(text, hc, b64_chars(n))?)
            } else {
                let all = b64(b64_slice(text, 0, b64_chars(hb + n))?)?;
                Ok(all[hb..hb + n].to_vec())
            }
        }
        Some(c) => {
            // The first three words take exactly 4*hb characters (3*hb bytes, no padding).
            let first = b64(b64_slice(text, 0, 4 * hb)?)?;
            let nb = ctx
                .word(&first, 0)
                .ok_or("compression header is truncated")? as usize;
            let hlen = (3 + nb) * hb;
            let hc = b64_chars(hlen);
            if hc > text.len() {
                return Err(
                    "compression header runs past the end of the data (file truncated?)".into(),
                );
            }
            let separate = hlen.is_multiple_of(3) || text.get(hc - 1) == Some(&b'=');
            let header_bytes = b64(b64_slice(text, 0, hc)?)?;
            let h = BlockHeader::parse(&header_bytes, ctx)?;
            let total = h.total_compressed();
            let data = if separate {
                b64(b64_slice(text, hc, b64_chars(total))?)?
            } else {
                let all = b64(b64_slice(text, 0, b64_chars(hlen + total))?)?;
                all[hlen..].to_vec()
            };
            h.inflate(&data, c)
        }
    }
}
