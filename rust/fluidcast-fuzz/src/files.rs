//! Structure-aware fuzzing of inputs made of several files: a random graph of `.pvtu`
//! summaries and `.pvd` collections in a folder of its own, whose entries name each other
//! (cycles, a file listing itself), pieces (seed files, some mutated), the same piece
//! thousands of times, FIFOs, symbolic links (to a node, to themselves, dangling, to a
//! folder), folders, missing files, `..` and absolute paths; opened from one of them as the
//! CLI opens its input, every frame read (whole and one array at a time) and, where that
//! succeeds, rendered small. Everything but a panic, an abort or a hang is fine.

use std::path::{Path, PathBuf};

use fluidcast_io::{Arrays, Input};
use fluidcast_sph::{ParticleSpec, Particles};

use crate::{mutate, render_small, Rng};

/// What a node of the graph is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Piece,
    Summary,
    Collection,
    Fifo,
    Link,
    Folder,
}

const KINDS: [Kind; 6] = [
    Kind::Piece,
    Kind::Summary,
    Kind::Collection,
    Kind::Fifo,
    Kind::Link,
    Kind::Folder,
];

/// One generated input: the file to open and a line that says what the graph was.
#[derive(Debug, Clone)]
pub struct Graph {
    /// The file the case opens.
    pub root: PathBuf,
    /// The nodes, "name:kind" each, for a finding's report.
    pub description: String,
}

/// Writes a random graph into the empty folder `dir` from the particle-file `pieces` (name,
/// bytes), and returns it.
pub fn generate(
    rng: &mut Rng,
    dir: &Path,
    pieces: &[(PathBuf, Vec<u8>)],
) -> std::io::Result<Graph> {
    let count = 2 + rng.below(5);
    let kinds: Vec<Kind> = (0..count).map(|_| KINDS[rng.below(KINDS.len())]).collect();
    let names: Vec<String> = kinds
        .iter()
        .enumerate()
        .map(|(i, k)| match k {
            Kind::Summary => format!("n{i}.pvtu"),
            Kind::Collection => format!("n{i}.pvd"),
            Kind::Piece | Kind::Fifo | Kind::Link | Kind::Folder => {
                format!("n{i}.{}", ["vtu", "vtp", "vtk"][rng.below(3)])
            }
        })
        .collect();
    for (i, kind) in kinds.iter().enumerate() {
        write_node(rng, dir, *kind, &names, i, pieces)?;
    }
    // The root: a summary or collection when there is one (the multi-file readers), else any.
    let multi: Vec<usize> = (0..count)
        .filter(|&i| matches!(kinds[i], Kind::Summary | Kind::Collection))
        .collect();
    let root = match multi.len() {
        0 => rng.below(count),
        n => multi[rng.below(n)],
    };
    let description = names
        .iter()
        .zip(&kinds)
        .map(|(n, k)| format!("{n}:{k:?}"))
        .collect::<Vec<_>>()
        .join(" ");
    Ok(Graph {
        root: dir.join(&names[root]),
        description,
    })
}

fn write_node(
    rng: &mut Rng,
    dir: &Path,
    kind: Kind,
    names: &[String],
    i: usize,
    pieces: &[(PathBuf, Vec<u8>)],
) -> std::io::Result<()> {
    let path = dir.join(&names[i]);
    match kind {
        Kind::Piece => {
            let (_, bytes) = &pieces[rng.below(pieces.len())];
            let bytes = if rng.below(4) == 0 {
                mutate(bytes, rng)
            } else {
                bytes.clone()
            };
            std::fs::write(path, bytes)
        }
        Kind::Summary => std::fs::write(path, summary(rng, names)),
        Kind::Collection => std::fs::write(path, collection(rng, names)),
        Kind::Fifo => fifo(&path),
        Kind::Link => {
            let target = match rng.below(4) {
                0 => PathBuf::from(&names[i]), // itself: a loop
                1 => PathBuf::from("missing.vtu"),
                2 => PathBuf::from("."),
                _ => PathBuf::from(&names[rng.below(names.len())]),
            };
            std::os::unix::fs::symlink(target, path)
        }
        Kind::Folder => std::fs::create_dir(path),
    }
}

/// A file name an entry gives: another node, a missing file, a path up or absolute, or
/// an odd one.
fn reference(rng: &mut Rng, names: &[String]) -> String {
    match rng.below(12) {
        0 => "missing.vtu".into(),
        1 => "../outside.vtu".into(),
        2 => "/dev/zero".into(),
        3 => "/proc/self/status".into(),
        4 => String::new(),
        5 => ".".into(),
        _ => names[rng.below(names.len())].clone(),
    }
}

/// How many entries a summary or collection lists: mostly a few, sometimes thousands (of
/// the same few files).
fn entries(rng: &mut Rng) -> usize {
    match rng.below(100) {
        0 => 2000,
        1..=4 => 50,
        n => n % 5,
    }
}

fn summary(rng: &mut Rng, names: &[String]) -> String {
    let kind = ["PUnstructuredGrid", "PPolyData"][rng.below(2)];
    let mut s = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"{kind}\" version=\"0.1\" \
         byte_order=\"LittleEndian\">\n<{kind} GhostLevel=\"{}\">\n<PPointData>\n",
        rng.below(3)
    );
    for name in ["density", "velocity", "q"].iter().take(rng.below(4)) {
        s += &format!("<PDataArray type=\"Float64\" Name=\"{name}\"/>\n");
    }
    s += "</PPointData>\n<PPoints><PDataArray type=\"Float32\" NumberOfComponents=\"3\"/></PPoints>\n";
    let pieces: Vec<String> = (0..1 + rng.below(3))
        .map(|_| reference(rng, names))
        .collect();
    for k in 0..entries(rng) {
        s += &format!("<Piece Source=\"{}\"/>\n", pieces[k % pieces.len()]);
    }
    if rng.below(10) != 0 {
        s += &format!("</{kind}>\n</VTKFile>\n");
    }
    s
}

fn collection(rng: &mut Rng, names: &[String]) -> String {
    let mut s = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n",
    );
    let times = ["0", "0", "1", "0.5", "nan", "1e400", "-1", "x"];
    for _ in 0..entries(rng) {
        s += &format!(
            "<DataSet timestep=\"{}\" part=\"{}\" file=\"{}\"/>\n",
            times[rng.below(times.len())],
            rng.below(3),
            reference(rng, names)
        );
    }
    if rng.below(10) != 0 {
        s += "</Collection>\n</VTKFile>\n";
    }
    s
}

/// A FIFO at `path` (the `mkfifo` program: unsafe code is forbidden in this workspace).
fn fifo(path: &Path) -> std::io::Result<()> {
    let status = std::process::Command::new("mkfifo").arg(path).status()?;
    if status.success() {
        Ok(())
    } else {
        Err(std::io::Error::other(format!(
            "mkfifo {}: {status}",
            path.display()
        )))
    }
}

/// Opens `root` as the CLI opens its input, reads up to two frames whole and one array at a
/// time, and renders what reads. `Ok(true)` when a frame rendered, `Ok(false)` when the input
/// was refused; a panic propagates (the caller catches it).
pub fn open_and_render(root: &Path) -> bool {
    let Ok(input) = Input::open(root) else {
        return false;
    };
    let mut rendered = false;
    for frame in input.frames().iter().take(2) {
        if let Ok(lazy) = input.open_frame(frame, &Arrays::All) {
            let _ = Particles::from_source(&lazy, &ParticleSpec::default());
        }
        if let Ok(ds) = input.read_frame(frame, &Arrays::All) {
            rendered |= render_small(&ds).is_ok();
        }
    }
    rendered
}
