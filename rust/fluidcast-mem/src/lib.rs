//! Memory budgets: how many bytes fluidcast may allocate, so that a size taken from a file
//! header or a user's option is refused with a clear error before it is allocated, instead
//! of aborting the process ("memory allocation of N bytes failed").
//!
//! The budget is the smallest of
//! * `MemAvailable` from `/proc/meminfo` (Linux; the memory the kernel can give without
//!   swapping),
//! * the address-space limit (`ulimit -v`, "Max address space" in `/proc/self/limits`)
//!   less the address space the process already uses (`VmSize` in `/proc/self/status`),
//! * `FLUIDCAST_MEMORY_LIMIT` (bytes, or with a `K`, `M`, `G` or `T` suffix, powers of 1024),
//!   which lets a user or a test set a lower limit.
//!
//! Where none of these can be read (not Linux), there is no budget and every check passes.
#![warn(missing_docs)]

use std::fmt;

/// The environment variable that caps fluidcast's memory use (bytes; K/M/G/T suffixes).
pub const ENV_LIMIT: &str = "FLUIDCAST_MEMORY_LIMIT";

/// A request for more memory than the budget allows.
#[derive(Debug, Clone, thiserror::Error)]
#[error("{what} needs {} but only {} is available{}", Bytes(*.needed), Bytes(*.available), hint(.source_of_limit))]
pub struct MemError {
    /// What the memory was for, e.g. "a 16384x8192 render".
    pub what: String,
    /// Bytes asked for.
    pub needed: u64,
    /// Bytes the budget allows.
    pub available: u64,
    /// Which limit applied.
    pub source_of_limit: &'static str,
}

fn hint(source: &str) -> String {
    format!(" ({source})")
}

/// A byte count printed with a binary unit (`1.5 GiB`).
#[derive(Debug, Clone, Copy)]
pub struct Bytes(pub u64);

impl fmt::Display for Bytes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const UNITS: [&str; 5] = ["bytes", "KiB", "MiB", "GiB", "TiB"];
        let mut v = self.0 as f64;
        let mut u = 0;
        while v >= 1024.0 && u + 1 < UNITS.len() {
            v /= 1024.0;
            u += 1;
        }
        match UNITS.get(u) {
            Some(&"bytes") | None => write!(f, "{} bytes", self.0),
            Some(unit) => write!(f, "{v:.1} {unit}"),
        }
    }
}

/// Parses `123`, `512K`, `1.5G`, … (powers of 1024).
pub fn parse_size(s: &str) -> Option<u64> {
    let s = s.trim();
    let (num, mul) = match s.char_indices().last()? {
        (i, c) if c.is_ascii_alphabetic() => {
            let m = match c.to_ascii_uppercase() {
                'K' => 1u64 << 10,
                'M' => 1 << 20,
                'G' => 1 << 30,
                'T' => 1 << 40,
                _ => return None,
            };
            (s.get(..i)?, m)
        }
        _ => (s, 1),
    };
    let v: f64 = num.trim().parse().ok()?;
    (v.is_finite() && v >= 0.0).then(|| (v * mul as f64).min(u64::MAX as f64) as u64)
}

/// A `/proc` line `Key: value [kB]` as bytes.
fn proc_value(text: &str, key: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(key))?;
    let mut it = line.get(key.len()..)?.split_whitespace();
    let v: u64 = it.next()?.parse().ok()?;
    Some(if it.next() == Some("kB") {
        v.saturating_mul(1024)
    } else {
        v
    })
}

/// The address-space soft limit from `/proc/self/limits`, if any.
fn address_space_limit() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/limits").ok()?;
    let line = text.lines().find(|l| l.starts_with("Max address space"))?;
    let soft = line
        .get("Max address space".len()..)?
        .split_whitespace()
        .next()?;
    soft.parse().ok()
}

/// The memory budget in bytes and which limit set it; `None` when no limit is known.
pub fn budget() -> Option<(u64, &'static str)> {
    let mut best: Option<(u64, &'static str)> = None;
    let mut take = |v: Option<u64>, src: &'static str| {
        if let Some(v) = v {
            if best.is_none_or(|(b, _)| v < b) {
                best = Some((v, src));
            }
        }
    };
    if let Ok(s) = std::env::var(ENV_LIMIT) {
        take(parse_size(&s), "FLUIDCAST_MEMORY_LIMIT");
    }
    if let Ok(m) = std::fs::read_to_string("/proc/meminfo") {
        take(
            proc_value(&m, "MemAvailable:"),
            "memory available on this machine",
        );
    }
    if let Some(limit) = address_space_limit() {
        let used = std::fs::read_to_string("/proc/self/status")
            .ok()
            .and_then(|s| proc_value(&s, "VmSize:"))
            .unwrap_or(0);
        take(
            Some(limit.saturating_sub(used)),
            "address-space limit, ulimit -v",
        );
    }
    best
}

/// The most physical memory this process has held so far (`VmHWM`, its peak resident set,
/// in bytes); `None` where `/proc/self/status` cannot be read (not Linux).
pub fn peak_resident() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    proc_value(&s, "VmHWM:")
}

/// The physical memory this process holds now (`VmRSS`, bytes); `None` where
/// `/proc/self/status` cannot be read (not Linux).
pub fn resident() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    proc_value(&s, "VmRSS:")
}

/// Checks that `needed` bytes fit in the budget; `what` says what they are for.
pub fn check(what: impl FnOnce() -> String, needed: u64) -> Result<(), MemError> {
    match budget() {
        Some((available, source_of_limit)) if needed > available => Err(MemError {
            what: what(),
            needed,
            available,
            source_of_limit,
        }),
        _ => Ok(()),
    }
}

/// Why a whole file could not be read into memory.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    /// The operating system's error (missing file, permission).
    #[error("cannot read file: {0}")]
    Io(#[from] std::io::Error),
    /// A directory where a file was expected.
    #[error("is a directory, not a file")]
    Directory,
    /// A FIFO, socket or device: reading it could wait for a writer forever, or never end.
    #[error(
        "is {0}, not a regular file (reading it could wait forever): copy the data into a file"
    )]
    NotRegular(&'static str),
    /// More than the memory budget allows (what it would take, in words).
    #[error("too large: {0}")]
    TooLarge(String),
}

/// What kind of file `t` is, for [`FileError::NotRegular`].
fn kind_of(t: &std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if t.is_socket() {
            return "a socket";
        }
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
    }
    let _ = t;
    "not a regular file"
}

/// Refuses anything but a regular file: a directory, a FIFO, a socket or a device.
fn check_regular(t: &std::fs::FileType) -> Result<(), FileError> {
    if t.is_dir() {
        return Err(FileError::Directory);
    }
    if !t.is_file() {
        return Err(FileError::NotRegular(kind_of(t)));
    }
    Ok(())
}

/// Opens `path` for reading when it is a regular file, never blocking: a FIFO, socket or
/// device is [`FileError::NotRegular`] and a directory [`FileError::Directory`]. The kind is
/// checked before opening (a FIFO's open waits for a writer; a socket cannot be opened) and
/// again on the opened file, which is opened non-blocking, so that a file swapped in between
/// cannot block either.
pub fn open_regular(path: &std::path::Path) -> Result<std::fs::File, FileError> {
    check_regular(&std::fs::metadata(path)?.file_type())?;
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK);
    }
    let f = options.open(path)?;
    check_regular(&f.metadata()?.file_type())?;
    Ok(f)
}

/// Reads a whole regular file ([`open_regular`]), refusing one that does not fit the memory
/// budget.
pub fn read_file(path: &std::path::Path) -> Result<Vec<u8>, FileError> {
    use std::io::Read;
    let f = open_regular(path)?;
    let len = f.metadata()?.len();
    check(|| "reading this file".into(), len).map_err(|e| FileError::TooLarge(e.to_string()))?;
    let mut bytes = Vec::with_capacity(usize::try_from(len).unwrap_or(0));
    f.take(len.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > len {
        return Err(FileError::TooLarge(
            "the file grew while it was being read".into(),
        ));
    }
    Ok(bytes)
}

/// Reads a whole regular file as UTF-8 text ([`read_file`]).
pub fn read_text(path: &std::path::Path) -> Result<String, FileError> {
    String::from_utf8(read_file(path)?).map_err(|_| {
        FileError::Io(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            "not UTF-8 text",
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_regular_files_are_read() {
        let dir = std::env::temp_dir().join(format!("fluidcast_mem_kinds_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("a.txt");
        std::fs::write(&file, "ok").unwrap();
        assert_eq!(read_text(&file).unwrap(), "ok");
        assert!(matches!(read_file(&dir), Err(FileError::Directory)));
        #[cfg(unix)]
        {
            let e = read_file(std::path::Path::new("/dev/zero")).unwrap_err();
            assert_eq!(
                e.to_string(),
                "is a character device, not a regular file (reading it could wait forever): \
                 copy the data into a file"
            );
            // A FIFO with no writer: an open that waited for one would hang this test.
            let fifo = dir.join("fifo.vtu");
            let made = std::process::Command::new("mkfifo").arg(&fifo).status();
            assert!(
                made.is_ok_and(|s| s.success()),
                "mkfifo failed: cannot test FIFOs"
            );
            let e = read_file(&fifo).unwrap_err();
            assert!(
                matches!(e, FileError::NotRegular("a FIFO (named pipe)")),
                "{e}"
            );
            assert!(open_regular(&fifo).is_err());
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn sizes_parse_with_binary_suffixes() {
        assert_eq!(parse_size("123"), Some(123));
        assert_eq!(parse_size("2K"), Some(2048));
        assert_eq!(parse_size("1.5G"), Some(3 << 29));
        assert_eq!(parse_size("4t"), Some(4 << 40));
        assert_eq!(parse_size("x"), None);
        assert_eq!(parse_size("-1"), None);
        assert_eq!(parse_size("3Q"), None);
    }

    #[test]
    fn bytes_print_with_units() {
        assert_eq!(Bytes(100).to_string(), "100 bytes");
        assert_eq!(Bytes(3 << 29).to_string(), "1.5 GiB");
        assert_eq!(Bytes(1 << 50).to_string(), "1024.0 TiB");
    }

    #[test]
    fn proc_values_in_kilobytes() {
        let t = "MemTotal:  100 kB\nMemAvailable:   2048 kB\n";
        assert_eq!(proc_value(t, "MemAvailable:"), Some(2048 * 1024));
        assert_eq!(proc_value(t, "Nope:"), None);
    }

    #[test]
    fn linux_has_a_budget_below_a_petabyte() {
        if cfg!(target_os = "linux") {
            let (b, _) = budget().unwrap();
            assert!(b > 0 && b < 1 << 50, "{b}");
            assert!(check(|| "x".into(), 1 << 50).is_err());
            assert!(check(|| "x".into(), 1).is_ok());
        }
    }
}
