//! Parallel VTK XML files, `.pvtu` and `.pvtp`: the files MPI codes and ParaView write, one
//! piece file per rank plus a small summary that lists them.
//!
//! The summary declares the point arrays (`<PPointData>`) and lists the pieces
//! (`<Piece Source="…"/>`, relative to the summary's folder). The pieces are read in parallel
//! (each as its own `.vtu`/`.vtp`, with all that reader's checks) and concatenated in the
//! order listed, so the result equals the same particles written as one file. Points that a
//! piece marks as ghosts (`vtkGhostType` with the DUPLICATEPOINT or HIDDENPOINT bit: a copy
//! of another piece's particle, or not part of the data) are dropped, so that halo copies
//! are not counted twice.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use quick_xml::events::Event;

use crate::xml::tag_attrs;
use crate::{Arrays, Cells, DataArray, Dataset, DatasetKind, ReadError, ReadErrorKind};

/// VTK's ghost array and the bits that mark a point as not this piece's own
/// (`vtkDataSetAttributes::DUPLICATEPOINT | HIDDENPOINT`).
pub(crate) const GHOST_ARRAY: &str = "vtkGhostType";

/// A ghost value (a byte) not owned has one of the two lowest bits set: value mod 4 ≥ 1.
fn owned_ghost_value(v: f64) -> bool {
    v.is_nan() || v.rem_euclid(4.0) < 1.0
}

/// What a parallel summary file says: the data set kind, the declared point arrays and the
/// piece files (resolved against the summary's folder), in order.
#[derive(Debug, Clone, PartialEq)]
pub struct ParallelFile {
    /// The pieces' data set kind.
    pub kind: DatasetKind,
    /// The point arrays the summary declares.
    pub point_arrays: Vec<String>,
    /// The piece files, resolved against the summary's folder.
    pub pieces: Vec<PathBuf>,
}

/// Parses a `.pvtu`/`.pvtp` summary's bytes; `path` names it in errors and its folder
/// resolves the pieces' relative paths. It does not open the pieces.
pub fn parse_parallel(bytes: &[u8], path: &Path) -> Result<ParallelFile, ReadError> {
    let err = |k| ReadError::new(path, k);
    let format = |m: &str| err(ReadErrorKind::Format(m.into()));
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut reader = quick_xml::Reader::from_reader(bytes);
    let (mut kind, mut closed, mut in_point_data) = (None, false, false);
    let mut out = ParallelFile {
        kind: DatasetKind::UnstructuredGrid,
        point_arrays: Vec::new(),
        pieces: Vec::new(),
    };
    loop {
        let at = reader.buffer_position();
        let event = reader
            .read_event()
            .map_err(|e| err(ReadErrorKind::Xml(format!("{e} (near byte {at})"))))?;
        let opens = matches!(event, Event::Start(_));
        match event {
            Event::Start(e) | Event::Empty(e) => {
                let a = tag_attrs(&e, at).map_err(|m| err(ReadErrorKind::Xml(m)))?;
                match e.name().as_ref() {
                    b"VTKFile" => {
                        let ty = a.get("type").map_or("", String::as_str);
                        if !ty.starts_with('P') {
                            return Err(format(&format!(
                                "not a parallel VTK file (its type is '{ty}', not \
                                 PUnstructuredGrid or PPolyData)"
                            )));
                        }
                    }
                    b"PUnstructuredGrid" => kind = Some(DatasetKind::UnstructuredGrid),
                    b"PPolyData" => kind = Some(DatasetKind::PolyData),
                    b"PPointData" => in_point_data = opens,
                    b"PDataArray" if in_point_data => {
                        let name = a.get("Name").ok_or_else(|| {
                            format("a <PDataArray> in <PPointData> has no 'Name'")
                        })?;
                        out.point_arrays.push(name.clone());
                    }
                    b"Piece" => {
                        let source = a.get("Source").filter(|s| !s.trim().is_empty());
                        let source =
                            source.ok_or_else(|| format("a <Piece> without a 'Source' file"))?;
                        crate::check_path_length(source, "a <Piece>'s 'Source'")
                            .map_err(|m| format(&m))?;
                        out.pieces.push(dir.join(source.trim()));
                    }
                    _ => {}
                }
            }
            Event::End(e) => match e.name().as_ref() {
                b"PPointData" => in_point_data = false,
                b"VTKFile" => closed = true,
                _ => {}
            },
            Event::Eof => break,
            _ => {}
        }
    }
    out.kind = kind.ok_or_else(|| {
        format("not a parallel VTK file (no <PUnstructuredGrid> or <PPolyData> element)")
    })?;
    if !closed {
        return Err(err(ReadErrorKind::Truncated(
            "no </VTKFile> (file cut short?)".into(),
        )));
    }
    if out.pieces.is_empty() {
        return Err(format("the file lists no pieces"));
    }
    Ok(out)
}

/// Reads a parallel file: its summary from `bytes`, its pieces from disk.
pub(crate) fn parse(bytes: &[u8], path: &Path, arrays: &Arrays) -> Result<Dataset, ReadError> {
    let summary = parse_parallel(bytes, path)?;
    // The pieces are held together before they are merged: a summary that lists more (or
    // the same file many times) than memory holds is refused before any is read.
    let total: u64 = summary
        .pieces
        .iter()
        .filter_map(|p| std::fs::metadata(p).ok())
        .map(|m| m.len())
        .fold(0, u64::saturating_add);
    fluidcast_mem::check(
        || format!("reading the {} pieces", summary.pieces.len()),
        total.saturating_mul(2),
    )
    .map_err(|e| ReadError::new(path, ReadErrorKind::TooLarge(e.to_string())))?;
    let pieces = read_pieces(&summary.pieces, arrays)
        .into_iter()
        .map(|r| r.map_err(|e| e.listed_in(path)))
        .collect::<Result<Vec<_>, _>>()?;
    merge(path, &summary, pieces, arrays)
}

/// Reads every piece, several at a time (one thread per core at most); results in order.
fn read_pieces(files: &[PathBuf], arrays: &Arrays) -> Vec<Result<Dataset, ReadError>> {
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(files.len());
    let next = AtomicUsize::new(0);
    let slots: Vec<Mutex<Option<Result<Dataset, ReadError>>>> =
        files.iter().map(|_| Mutex::new(None)).collect();
    std::thread::scope(|s| {
        for _ in 0..threads {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let (Some(file), Some(slot)) = (files.get(i), slots.get(i)) else {
                    break;
                };
                let r = crate::read_piece(file, arrays);
                if let Ok(mut g) = slot.lock() {
                    *g = Some(r);
                }
            });
        }
    });
    slots
        .into_iter()
        .zip(files)
        .map(|(slot, file)| {
            slot.into_inner().ok().flatten().unwrap_or_else(|| {
                Err(ReadError::new(
                    file,
                    ReadErrorKind::Format("the piece could not be read".into()),
                ))
            })
        })
        .collect()
}

/// The pieces' particles as one data set: points and point arrays concatenated in order
/// (each declared array must be in every piece; an undeclared one is kept where every piece
/// has it), ghost points dropped, the field data of the first piece.
fn merge(
    path: &Path,
    summary: &ParallelFile,
    pieces: Vec<Dataset>,
    arrays: &Arrays,
) -> Result<Dataset, ReadError> {
    let err = |m: String| ReadError::new(path, ReadErrorKind::Format(m));
    // Declared arrays the read did not decode are in no piece.
    let declared: Vec<&String> = summary
        .point_arrays
        .iter()
        .filter(|n| arrays.wants(n))
        .collect();
    for (p, ds) in summary.pieces.iter().zip(&pieces) {
        if ds.kind != summary.kind {
            return Err(err(format!(
                "piece {} is {:?}, the file declares {:?} pieces",
                p.display(),
                ds.kind,
                summary.kind
            )));
        }
        for name in &declared {
            if ds.point_array(name).is_none() {
                return Err(err(format!(
                    "piece {} lacks the declared point array '{name}'",
                    p.display()
                )));
            }
        }
    }
    let out = concat(path, summary.kind, &pieces);
    // Every declared array is in every piece (checked above): one that did not stay has
    // different component counts somewhere.
    let uneven = declared.iter().find(|d| out.point_array(d).is_none());
    if let Some(d) = uneven {
        return Err(err(format!(
            "the declared point array '{d}' has different component counts in the pieces"
        )));
    }
    Ok(out)
}

/// Data sets' particles as one, named `path`, of `kind`: points concatenated in order, the
/// point arrays every one of them has with the same component count (others are dropped, as
/// `vtkAppendPolyData` does), ghost points dropped, the field data of the first.
pub(crate) fn concat(path: &Path, kind: DatasetKind, pieces: &[Dataset]) -> Dataset {
    let mut names: Vec<(String, usize)> = pieces
        .first()
        .map(|first| {
            first
                .point_data
                .iter()
                .map(|a| (a.name.clone(), a.num_components))
                .collect()
        })
        .unwrap_or_default();
    for ds in pieces {
        names.retain(|(n, c)| ds.point_array(n).is_some_and(|a| a.num_components == *c));
    }
    let mut out = Dataset {
        path: path.to_path_buf(),
        kind,
        points: Vec::new(),
        point_data: Vec::new(),
        field_data: pieces
            .first()
            .map(|d| d.field_data.clone())
            .unwrap_or_default(),
        undecoded: pieces
            .first()
            .map(|d| d.undecoded.clone())
            .unwrap_or_default(),
        cells: Cells::default(),
    };
    for ds in pieces {
        out.cells.merge(&ds.cells);
    }
    out.point_data = names
        .iter()
        .filter_map(|(n, _)| pieces.first()?.point_array(n))
        .map(|a| DataArray {
            name: a.name.clone(),
            scalar_type: a.scalar_type,
            num_components: a.num_components,
            values: Vec::new(),
        })
        .collect();
    for ds in pieces {
        append_owned(&mut out, ds);
    }
    out
}

/// Appends the points of `piece` that it owns (not ghosts), with their values of every
/// array `out` keeps.
fn append_owned(out: &mut Dataset, piece: &Dataset) {
    let ghost = piece.point_array(GHOST_ARRAY);
    let owned = |i: usize| {
        ghost
            .and_then(|g| g.values.get(i))
            .is_none_or(|&v| owned_ghost_value(v))
    };
    let keep: Vec<usize> = (0..piece.points.len()).filter(|&i| owned(i)).collect();
    out.points
        .extend(keep.iter().filter_map(|&i| piece.points.get(i)));
    for a in &mut out.point_data {
        let Some(src) = piece.point_array(&a.name) else {
            continue;
        };
        let nc = a.num_components;
        for &i in &keep {
            if let Some(t) = src.values.get(i * nc..(i + 1) * nc) {
                a.values.extend_from_slice(t);
            }
        }
    }
}
