//! Mutation fuzzing of fluidcast's input paths on stable Rust.
//!
//! Seeds are real files (the fixtures in every VTK encoding, legacy files, `.pvd`
//! collections, PNG and EXR images); each input is a seed with one to four stacked
//! mutations: byte flips, random insertions and deletions, duplicated or truncated spans,
//! header words overwritten with edge values (0, 2^31, 2^32 − 1, 2^40, 2^63, 2^64 − 1, …) and
//! numbers in the XML text replaced by edge values (0, −1, 1e30, NaN, huge counts, …).
//!
//! [`run_input`] feeds one input to the matching parser and, for inputs that parse, renders
//! them small with the adaptive renderer: every outcome must be `Ok` or a clean error.
//! A panic is caught and reported as a [`Finding`]; aborts, hangs and huge allocations
//! are caught by the runner (`fluidcast-fuzz` binary), which runs under an address-space
//! limit and a watchdog.
//!
//! [`files`] generates inputs of several files (summaries and collections naming each other,
//! FIFOs, links); the `fluidcast-fuzz-files` binary runs them.
#![warn(missing_docs)]

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

pub mod files;

use fluidcast_render::RenderParams;
use fluidcast_sph::{ParticleSpec, Particles};
use fluidcast_view::{Camera, TransferFunction};

/// splitmix64: a small, fast, reproducible generator (a seed gives the same inputs on
/// every machine).
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    /// A generator whose sequence is fixed by `seed`.
    pub fn new(seed: u64) -> Rng {
        Rng(seed)
    }
    /// The next 64 random bits (SplitMix64).
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in `0..n` (`0` when `n` is 0).
    pub fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.next_u64() % n as u64) as usize
        }
    }
}

/// Header words that break naive size arithmetic.
const EDGE_WORDS: [u64; 12] = [
    0,
    1,
    7,
    0x7FFF_FFFF,
    0xFFFF_FFFF,
    1 << 32,
    1 << 40,
    3 << 30,
    1 << 63,
    u64::MAX,
    u64::MAX - 7,
    0x1_0000_0008,
];

/// Numbers written into XML/legacy text.
const EDGE_NUMBERS: [&str; 14] = [
    "0",
    "-1",
    "1",
    "3",
    "300",
    "4294967296",
    "18446744073709551615",
    "99999999999999999999",
    "1e30",
    "-1e14",
    "1e308",
    "nan",
    "inf",
    "1099511627776",
];

/// Returns `seed` with one to four random mutations applied.
pub fn mutate(seed: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut b = seed.to_vec();
    for _ in 0..1 + rng.below(4) {
        mutate_once(&mut b, rng);
    }
    b
}

fn mutate_once(b: &mut Vec<u8>, rng: &mut Rng) {
    let n = b.len();
    match rng.below(8) {
        0 => {
            let i = rng.below(n);
            if let Some(c) = b.get_mut(i) {
                *c ^= 1 << rng.below(8);
            }
        }
        1 => {
            let i = rng.below(n + 1);
            let k = 1 + rng.below(16);
            let bytes: Vec<u8> = (0..k).map(|_| rng.next_u64() as u8).collect();
            b.splice(i..i, bytes);
        }
        2 => {
            let i = rng.below(n);
            let k = (1 + rng.below(64)).min(n - i.min(n));
            b.drain(i..i + k);
        }
        3 => b.truncate(rng.below(n + 1)),
        4 => {
            let i = rng.below(n);
            let k = (1 + rng.below(256)).min(n - i.min(n));
            let span: Vec<u8> = b.get(i..i + k).unwrap_or_default().to_vec();
            let at = rng.below(n + 1);
            b.splice(at..at, span);
        }
        5 | 6 => edit_number(b, rng),
        _ => {
            let w = EDGE_WORDS[rng.below(EDGE_WORDS.len())];
            let le = rng.below(2) == 0;
            let bytes = if le { w.to_le_bytes() } else { w.to_be_bytes() };
            let size = if rng.below(2) == 0 { 4 } else { 8 };
            let i = rng.below(n.saturating_sub(size) + 1);
            for (k, v) in bytes.iter().take(size).enumerate() {
                if let Some(c) = b.get_mut(i + k) {
                    *c = *v;
                }
            }
        }
    }
}

/// Replaces a run of ASCII digits (an attribute or a text value) with an edge number.
fn edit_number(b: &mut Vec<u8>, rng: &mut Rng) {
    let n = b.len();
    let start = rng.below(n);
    let Some(off) = b
        .get(start..)
        .and_then(|s| s.iter().position(u8::is_ascii_digit))
    else {
        return;
    };
    let i = start + off;
    let len = b
        .get(i..)
        .map(|s| {
            s.iter()
                .take_while(|c| c.is_ascii_digit() || **c == b'.')
                .count()
        })
        .unwrap_or(0);
    let num = EDGE_NUMBERS[rng.below(EDGE_NUMBERS.len())];
    b.splice(i..i + len, num.bytes());
}

/// What an input turned out to be.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Outcome {
    /// Parsed (and rendered, where asked) without error.
    Accepted,
    /// Refused with an error message.
    Refused(String),
}

/// A panic: the bug class this harness exists to find.
#[derive(Debug, Clone)]
pub struct Finding {
    /// The panic message and where it happened.
    pub message: String,
}

/// The parser an input goes to, by the seed's extension.
pub fn parses_as(path: &Path) -> Option<&'static str> {
    match path.extension()?.to_str()?.to_ascii_lowercase().as_str() {
        "vtu" => Some("vtu"),
        "vtp" => Some("vtp"),
        "vtk" => Some("vtk"),
        "pvd" => Some("pvd"),
        "pvtu" => Some("pvtu"),
        "pvtp" => Some("pvtp"),
        "png" => Some("png"),
        "exr" => Some("exr"),
        _ => None,
    }
}

/// Feeds `bytes` to the parser for `ext` (and, if `render` and it parses, to the
/// renderer). A panic anywhere is returned as a [`Finding`].
pub fn run_input(bytes: &[u8], ext: &str, render: bool) -> Result<Outcome, Finding> {
    catch_unwind(AssertUnwindSafe(|| run_unguarded(bytes, ext, render))).map_err(|p| Finding {
        message: panic_message(p.as_ref()),
    })
}

/// The message of a caught panic.
pub fn panic_message(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<String>()
        .cloned()
        .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_else(|| "panic with a non-string payload".into())
}

/// When the input (or case) now running started, for [`watchdog`].
pub struct Watch {
    t0: Instant,
    started_ms: Arc<AtomicU64>,
}

impl Watch {
    /// An input starts.
    pub fn start(&self) {
        let now = self.t0.elapsed().as_millis() as u64;
        self.started_ms.store(now, Ordering::Relaxed);
    }

    /// It ended.
    pub fn stop(&self) {
        self.started_ms.store(u64::MAX, Ordering::Relaxed);
    }
}

/// A thread that, when one input runs longer than `hang`, calls `on_hang` (which keeps the
/// input and says where) and ends the process with exit code 3.
pub fn watchdog(hang: Duration, on_hang: impl Fn() + Send + 'static) -> Watch {
    let watch = Watch {
        t0: Instant::now(),
        started_ms: Arc::new(AtomicU64::new(u64::MAX)),
    };
    let (t0, started) = (watch.t0, watch.started_ms.clone());
    std::thread::spawn(move || loop {
        std::thread::sleep(Duration::from_millis(500));
        let s = started.load(Ordering::Relaxed);
        let now = t0.elapsed().as_millis() as u64;
        if s != u64::MAX && now.saturating_sub(s) > hang.as_millis() as u64 {
            on_hang();
            std::process::exit(3);
        }
    });
    watch
}

fn run_unguarded(bytes: &[u8], ext: &str, render: bool) -> Outcome {
    let path = PathBuf::from(format!("fuzz-input.{ext}"));
    let refused = |e: &dyn std::fmt::Display| Outcome::Refused(e.to_string());
    match ext {
        "png" | "exr" => match fluidcast_image::Image::decode(bytes, &path) {
            Ok(_) => Outcome::Accepted,
            Err(e) => refused(&e),
        },
        "pvd" => match fluidcast_io::parse_collection(bytes, &path) {
            Ok(_) => Outcome::Accepted,
            Err(e) => refused(&e),
        },
        // The summary only: its pieces are files on disk, which a fuzzer must not pick.
        "pvtu" | "pvtp" => match fluidcast_io::parse_parallel(bytes, &path) {
            Ok(_) => Outcome::Accepted,
            Err(e) => refused(&e),
        },
        "vtu" | "vtp" => {
            read_lazily(bytes, ext);
            parsed(bytes, &path, render)
        }
        _ => parsed(bytes, &path, render),
    }
}

/// The reader that reads a data set at once, and a render of what it accepts.
fn parsed(bytes: &[u8], path: &Path, render: bool) -> Outcome {
    match fluidcast_io::parse_dataset(bytes, path) {
        Ok(ds) if render => match render_small(&ds) {
            Ok(()) => Outcome::Accepted,
            Err(e) => Outcome::Refused(e),
        },
        Ok(_) => Outcome::Accepted,
        Err(e) => Outcome::Refused(e.to_string()),
    }
}

/// The reader that reads a file one array at a time, on a copy of `bytes` in a file of this
/// process' own: its particles are built (every outcome but a panic is fine: it checks less
/// up front than the whole read, so it may accept what that refuses).
fn read_lazily(bytes: &[u8], ext: &str) {
    let dir = std::env::temp_dir().join(format!("fluidcast-fuzz-{}", std::process::id()));
    let file = dir.join(format!("input.{ext}"));
    if std::fs::create_dir_all(&dir).is_err() || std::fs::write(&file, bytes).is_err() {
        return;
    }
    if let Ok(lazy) = fluidcast_io::open_lazy(&file, &fluidcast_io::Arrays::All) {
        let mut spec = ParticleSpec::default();
        if let Some((name, _)) = lazy.point_arrays().first() {
            spec.quantity = name.parse::<fluidcast_sph::Quantity>().ok();
        }
        let _ = Particles::from_source(&lazy, &spec);
    }
    let _ = std::fs::remove_file(&file);
    let _ = std::fs::remove_dir(&dir);
}

/// Renders a data set at 24x16 pixels as the CLI does by default: auto camera, density or
/// first point array, Viridis over the data range, adaptive at E_I = 0.004.
pub fn render_small(ds: &fluidcast_io::Dataset) -> Result<(), String> {
    let mut spec = ParticleSpec::default();
    if let Some(a) = ds.point_data.first() {
        spec.quantity = a.name.parse::<fluidcast_sph::Quantity>().ok();
    }
    let p = Particles::from_dataset(ds, &spec).map_err(|e| e.to_string())?;
    let (lo, hi) = p.support_bounds();
    let mut cam = Camera::default();
    cam.reset(lo.map(f64::from), hi.map(f64::from));
    let (vlo, vhi) = p.value_range();
    let (vlo, vhi) = (f64::from(vlo), f64::from(vhi));
    let (vlo, vhi) = if vlo < vhi {
        (vlo, vhi)
    } else {
        (vlo - 0.5, vlo + 0.5)
    };
    let mut tf = TransferFunction::preset("Viridis")
        .and_then(|t| t.with_range(vlo, vhi))
        .map_err(|e| e.to_string())?;
    let diag = (0..3)
        .map(|k| f64::from(hi[k] - lo[k]).powi(2))
        .sum::<f64>()
        .sqrt();
    tf.unit_distance = diag / (p.len().max(1) as f64).cbrt();
    let params = RenderParams {
        width: 24,
        height: 16,
        ..Default::default()
    };
    fluidcast_render::render_adaptive(&p, None, &cam, &tf, &params)
        .map(|_| ())
        .map_err(|e| e.to_string())
}

/// The seed files under `dir` that a parser takes, sorted by name.
pub fn seeds(dir: &Path) -> std::io::Result<Vec<(PathBuf, Vec<u8>)>> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir)? {
        let p = e?.path();
        if parses_as(&p).is_some() {
            let b = std::fs::read(&p)?;
            out.push((p, b));
        }
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(out)
}

/// Small PNG and EXR seeds (a 6x4 gradient with depth and one AOV), written by fluidcast's
/// own image writer into a scratch folder and read back as bytes, so that no image needs
/// to live in the repository.
pub fn image_seeds() -> std::io::Result<Vec<(PathBuf, Vec<u8>)>> {
    let mut img = fluidcast_image::Image::new(6, 4);
    for (k, p) in img.rgba.iter_mut().enumerate() {
        let t = k as f32 / 24.0;
        *p = [t, 0.5 * t, 1.0 - t, 0.25 + 0.5 * t];
    }
    for (k, z) in img.depth.iter_mut().enumerate() {
        *z = if k % 5 == 0 { f32::INFINITY } else { k as f32 };
    }
    img.aovs.push(("level".into(), vec![1.0; 24]));
    let dir = std::env::temp_dir().join(format!("fluidcast-fuzz-seeds-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let mut out = Vec::new();
    for name in ["seed.png", "seed.exr"] {
        let p = dir.join(name);
        img.save(&p, [1.0, 1.0, 1.0], fluidcast_image::PngEncoding::Vtk)
            .map_err(std::io::Error::other)?;
        out.push((PathBuf::from(name), std::fs::read(&p)?));
    }
    let _ = std::fs::remove_dir_all(&dir);
    Ok(out)
}
