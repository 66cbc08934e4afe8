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

/// The most bytes read from something that is not a regular file (a pipe or a device such
/// as `/dev/zero`), whose length cannot be known in advance.
pub const MAX_STREAM_BYTES: u64 = 256 << 20;

/// Why a whole file could not be read into memory.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    #[error("cannot read file: {0}")]
    Io(#[from] std::io::Error),
    #[error("is a directory, not a file")]
    Directory,
    #[error("too large: {0}")]
    TooLarge(String),
}

/// Reads a whole file, refusing one that does not fit the memory budget and reading at
/// most [`MAX_STREAM_BYTES`] from pipes and devices.
pub fn read_file(path: &std::path::Path) -> Result<Vec<u8>, FileError> {
    use std::io::Read;
    let f = std::fs::File::open(path)?;
    let meta = f.metadata()?;
    if meta.is_dir() {
        return Err(FileError::Directory);
    }
    let limit = if meta.is_file() {
        check(|| "reading this file".into(), meta.len())
            .map_err(|e| FileError::TooLarge(e.to_string()))?;
        meta.len()
    } else {
        MAX_STREAM_BYTES
    };
    let mut bytes = Vec::with_capacity(usize::try_from(limit.min(MAX_STREAM_BYTES)).unwrap_or(0));
    f.take(limit.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(FileError::TooLarge(if meta.is_file() {
            "the file grew while it was being read".into()
        } else {
            format!(
                "not a regular file and longer than {} MiB: copy the data into a file first",
                MAX_STREAM_BYTES >> 20
            )
        }));
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

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
