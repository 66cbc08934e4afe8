use std::path::{Path, PathBuf};

use quick_xml::events::Event;

use crate::xml::tag_attrs;
use crate::{ReadError, ReadErrorKind};

/// One data set of a `.pvd` collection.
#[derive(Debug, Clone, PartialEq)]
pub struct CollectionEntry {
    /// The `timestep` attribute (simulation time; 0 when absent).
    pub timestep: f64,
    /// `part` attribute (0 when absent).
    pub part: u32,
    /// The data set's file, resolved relative to the `.pvd`'s folder.
    pub file: PathBuf,
}

/// A ParaView `.pvd` collection: a time series of particle files.
#[derive(Debug, Clone)]
pub struct Collection {
    /// The `.pvd` file.
    pub path: PathBuf,
    /// Entries sorted by time step (ParaView's order), stable for equal times.
    pub entries: Vec<CollectionEntry>,
}

impl Collection {
    /// The entries grouped by time, in time order: one group a distinct time. ParaView shows
    /// the data sets of one time together (the `part`s of one step: fluid and boundary, or one
    /// file per phase); `fluidcast render` and `vtkFluidCastReader` append them.
    pub fn steps(&self) -> impl Iterator<Item = &[CollectionEntry]> {
        self.entries.chunk_by(|a, b| a.timestep == b.timestep)
    }

    /// The times at which the collection lists more than one data set, with how many.
    pub fn shared_times(&self) -> Vec<(f64, usize)> {
        self.steps()
            .filter(|s| s.len() > 1)
            .filter_map(|s| Some((s.first()?.timestep, s.len())))
            .collect()
    }
}

/// Reads a `.pvd` file's `<DataSet>` list (it does not open the data sets).
pub fn read_collection(path: impl AsRef<Path>) -> Result<Collection, ReadError> {
    let path = path.as_ref();
    let bytes = crate::read_file(path)?;
    parse_collection(&bytes, path)
}

/// Parses a `.pvd` file's bytes; `path` names it in errors and its folder resolves the
/// data sets' relative paths.
pub fn parse_collection(bytes: &[u8], path: &Path) -> Result<Collection, ReadError> {
    let err = |k| ReadError::new(path, k);
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut reader = quick_xml::Reader::from_reader(bytes);
    let mut entries = Vec::new();
    let mut saw_collection = false;
    let mut collection_closed = false;
    loop {
        let at = reader.buffer_position();
        match reader
            .read_event()
            .map_err(|e| err(ReadErrorKind::Xml(format!("{e} (near byte {at})"))))?
        {
            Event::End(e) if e.name().as_ref() == b"Collection" => collection_closed = true,
            Event::Start(e) | Event::Empty(e) => match e.name().as_ref() {
                b"Collection" => saw_collection = true,
                b"DataSet" => {
                    let a = tag_attrs(&e, at).map_err(|m| err(ReadErrorKind::Xml(m)))?;
                    let file = a.get("file").ok_or_else(|| {
                        err(ReadErrorKind::Format(
                            "<DataSet> without a 'file' attribute".into(),
                        ))
                    })?;
                    crate::check_path_length(file, "a <DataSet>'s 'file'")
                        .map_err(|m| err(ReadErrorKind::Format(m)))?;
                    let timestep = match a.get("timestep") {
                        Some(t) => t.trim().parse::<f64>().map_err(|_| {
                            err(ReadErrorKind::Format(format!(
                                "bad timestep '{t}' for {file}"
                            )))
                        })?,
                        None => 0.0,
                    };
                    let part = a
                        .get("part")
                        .and_then(|p| p.trim().parse().ok())
                        .unwrap_or(0);
                    entries.push(CollectionEntry {
                        timestep,
                        part,
                        file: dir.join(file),
                    });
                }
                _ => {}
            },
            Event::Eof => break,
            _ => {}
        }
    }
    if !saw_collection {
        return Err(err(ReadErrorKind::Format(
            "not a .pvd collection (no <Collection> element)".into(),
        )));
    }
    if !collection_closed {
        return Err(err(ReadErrorKind::Truncated(
            "the collection has no </Collection> (file cut short?)".into(),
        )));
    }
    if entries.is_empty() {
        return Err(err(ReadErrorKind::Format(
            "the collection lists no data sets".into(),
        )));
    }
    entries.sort_by(|a, b| a.timestep.total_cmp(&b.timestep));
    Ok(Collection {
        path: path.to_path_buf(),
        entries,
    })
}
