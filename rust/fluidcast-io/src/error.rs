use std::path::{Path, PathBuf};

/// A file could not be read; `Display` names the file and the problem.
#[derive(Debug, thiserror::Error)]
#[error("{}{}: {kind}", path.display(), listed_in.as_ref().map(|p| format!(" (listed in {})", p.display())).unwrap_or_default())]
pub struct ReadError {
    /// The file at fault.
    pub path: PathBuf,
    /// The `.pvd` collection that referenced it, if any.
    pub listed_in: Option<PathBuf>,
    /// What was wrong with it.
    pub kind: ReadErrorKind,
}

impl ReadError {
    /// A problem `kind` with the file at `path`.
    pub fn new(path: impl AsRef<Path>, kind: ReadErrorKind) -> Self {
        ReadError {
            path: path.as_ref().to_path_buf(),
            listed_in: None,
            kind,
        }
    }

    /// The same error, saying which `.pvd` listed the file.
    pub fn listed_in(mut self, collection: impl AsRef<Path>) -> Self {
        self.listed_in = Some(collection.as_ref().to_path_buf());
        self
    }
}

/// The problem with a file.
#[derive(Debug, thiserror::Error)]
pub enum ReadErrorKind {
    /// The operating system's error (missing file, permission).
    #[error("cannot read file: {0}")]
    Io(#[from] std::io::Error),
    /// An extension no reader takes.
    #[error("unsupported file extension '{0}' (expected .vtu, .vtp, .pvtu, .pvtp, .vtk or .pvd)")]
    UnsupportedExtension(String),
    /// XML that does not parse.
    #[error("malformed XML: {0}")]
    Xml(String),
    /// A file that parses but does not hold what its format says, in words.
    #[error("{0}")]
    Format(String),
    /// A data set that is not particles: a structured grid or image (its geometry lies in
    /// its structure, not its points), or a file listed in a `.pvd` of another kind.
    #[error("{0}")]
    NotParticles(String),
    /// An array that cannot be decoded.
    #[error("array '{array}': {problem}")]
    Array {
        /// The array's name.
        array: String,
        /// What is wrong with it.
        problem: String,
    },
    /// The file ends before what it declares.
    #[error("truncated file: {0}")]
    Truncated(String),
    /// More than the memory budget allows (what it would take, in words).
    #[error("too large: {0}")]
    TooLarge(String),
}
