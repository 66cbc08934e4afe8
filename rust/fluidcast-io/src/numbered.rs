//! Series as simulations write them: numbered files without a `.pvd` (DualSPHysics'
//! `PartFluid_%04d.vtk`, SPlisHSPlasH's `ParticleData_Fluid_%d.vtk`), named on a command line
//! as several paths, a glob (`run/PartFluid_*.vtk`) or a printf pattern
//! (`run/PartFluid_%04d.vtk`), in natural order (`_2` before `_10`).

use std::cmp::Ordering;
use std::path::{Path, PathBuf};

use crate::{Collection, CollectionEntry, ReadError, ReadErrorKind};

/// The files `args` name as one series, as a [`Collection`] whose time steps are the files'
/// positions (0, 1, 2, ...) and whose path is the pattern (or "N files") for messages; `None`
/// when `args` is one path without a pattern (a file or a `.pvd`, opened as today).
pub fn series_of(args: &[PathBuf]) -> Result<Option<Collection>, ReadError> {
    if let [one] = args {
        if !is_pattern(one) {
            return Ok(None);
        }
    }
    let mut files = Vec::new();
    for a in args {
        if a.extension().is_some_and(|e| e.eq_ignore_ascii_case("pvd")) {
            return Err(ReadError::new(
                a,
                other("a .pvd is a series itself: give it alone"),
            ));
        }
        if is_pattern(a) {
            files.extend(matching(a)?);
        } else if a.exists() {
            files.push(a.clone());
        } else {
            return Err(ReadError::new(a, other("no such file")));
        }
    }
    let path = match args {
        [one] => one.clone(),
        _ => PathBuf::from(format!("the {} files given", files.len())),
    };
    let entries = files
        .into_iter()
        .enumerate()
        .map(|(k, file)| CollectionEntry {
            timestep: k as f64,
            part: 0,
            file,
        })
        .collect();
    Ok(Some(Collection { path, entries }))
}

fn other(message: &str) -> ReadErrorKind {
    ReadErrorKind::Format(message.to_string())
}

/// Whether the file name holds a glob (`*`, `?`) or a printf field (`%d`, `%04d`).
fn is_pattern(p: &Path) -> bool {
    let name = p
        .file_name()
        .map(|n| n.to_string_lossy())
        .unwrap_or_default();
    name.contains(['*', '?']) || printf_field(&name).is_some()
}

/// The `%d`/`%0Nd` field of a file name: (start, end) byte offsets.
fn printf_field(name: &str) -> Option<(usize, usize)> {
    let start = name.find('%')?;
    let rest = name.get(start + 1..)?;
    let digits = rest.bytes().take_while(u8::is_ascii_digit).count();
    (rest.as_bytes().get(digits) == Some(&b'd')).then_some((start, start + digits + 2))
}

/// The files of `pattern`'s folder whose names match it, in natural order; an error names
/// the pattern when none does.
fn matching(pattern: &Path) -> Result<Vec<PathBuf>, ReadError> {
    let dir = match pattern.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = pattern
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let glob = match printf_field(&name) {
        // '#': a run of one or more digits.
        Some((a, b)) => format!(
            "{}#{}",
            name.get(..a).unwrap_or_default(),
            name.get(b..).unwrap_or_default()
        ),
        None => name.clone(),
    };
    let listing =
        std::fs::read_dir(&dir).map_err(|e| ReadError::new(pattern, ReadErrorKind::Io(e)))?;
    let mut files: Vec<PathBuf> = listing
        .filter_map(Result::ok)
        .filter(|e| e.file_type().is_ok_and(|t| t.is_file() || t.is_symlink()))
        .filter(|e| matches(glob.as_bytes(), e.file_name().to_string_lossy().as_bytes()))
        .map(|e| dir.join(e.file_name()))
        .collect();
    if files.is_empty() {
        return Err(ReadError::new(
            pattern,
            other(&format!(
                "no file in {} matches this pattern",
                dir.display()
            )),
        ));
    }
    files.sort_by(|a, b| natural(&a.to_string_lossy(), &b.to_string_lossy()));
    Ok(files)
}

/// Whether `name` matches `glob`: `*` any run, `?` one character, `#` a run of one or more
/// digits. Dynamic programming over (glob, name) suffixes: at most their lengths' product of
/// steps, whatever the pattern (a backtracking match is exponential in its stars).
fn matches(glob: &[u8], name: &[u8]) -> bool {
    let n = name.len();
    // ok[j]: the part of the glob after the current symbol matches name[j..].
    let mut ok: Vec<bool> = (0..=n).map(|j| j == n).collect();
    for &g in glob.iter().rev() {
        let mut row = vec![false; n + 1];
        for j in (0..=n).rev() {
            let next = |k: usize| ok.get(j + k).copied().unwrap_or(false);
            let here = name.get(j);
            let v = match g {
                b'*' => next(0) || row.get(j + 1).copied().unwrap_or(false),
                b'#' => {
                    let rest = name.get(j..).unwrap_or_default();
                    let run = rest.iter().take_while(|c| c.is_ascii_digit()).count();
                    (1..=run).any(next)
                }
                b'?' => here.is_some() && next(1),
                g => here == Some(&g) && next(1),
            };
            if let Some(r) = row.get_mut(j) {
                *r = v;
            }
        }
        ok = row;
    }
    ok.first().copied().unwrap_or(false)
}

/// Natural order: digit runs compared as numbers (then by their length, so `2` < `002`),
/// the rest byte by byte.
fn natural(a: &str, b: &str) -> Ordering {
    let (x, y) = (tokens(a.as_bytes()), tokens(b.as_bytes()));
    for (p, q) in x.iter().zip(&y) {
        let o = match (number(p), number(q)) {
            (Some(u), Some(v)) => u.len().cmp(&v.len()).then_with(|| u.cmp(v)),
            _ => p.cmp(q),
        }
        .then(p.len().cmp(&q.len()));
        if o != Ordering::Equal {
            return o;
        }
    }
    x.len().cmp(&y.len())
}

/// `s` in runs of digits and single other bytes.
fn tokens(s: &[u8]) -> Vec<&[u8]> {
    s.chunk_by(|a, b| a.is_ascii_digit() && b.is_ascii_digit())
        .collect()
}

/// A run of digits without its leading zeros (one zero kept), or None for other bytes.
fn number(t: &[u8]) -> Option<&[u8]> {
    if !t.first().is_some_and(u8::is_ascii_digit) {
        return None;
    }
    let z = t.iter().take_while(|&&c| c == b'0').count();
    t.get(z.min(t.len() - 1)..)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn natural_order_counts_numbers() {
        let mut v = vec![
            "f_10.vtk",
            "f_2.vtk",
            "f_1.vtk",
            "f_002.vtk",
            "g_0.vtk",
            "f_.vtk",
        ];
        v.sort_by(|a, b| natural(a, b));
        assert_eq!(
            v,
            [
                "f_.vtk",
                "f_1.vtk",
                "f_2.vtk",
                "f_002.vtk",
                "f_10.vtk",
                "g_0.vtk"
            ]
        );
    }

    #[test]
    fn globs_and_printf_fields_match_what_they_say() {
        assert!(matches(b"P_*.vtk", b"P_0012.vtk"));
        assert!(matches(b"P_?.vtk", b"P_3.vtk") && !matches(b"P_?.vtk", b"P_30.vtk"));
        assert!(matches(b"P_#.vtk", b"P_30.vtk") && !matches(b"P_#.vtk", b"P_x.vtk"));
        assert!(!matches(b"P_*.vtk", b"P_1.vtu") && !matches(b"P_#.vtk", b"P_.vtk"));
        assert_eq!(printf_field("PartFluid_%04d.vtk"), Some((10, 14)));
        assert_eq!(printf_field("a%d"), Some((1, 3)));
        assert_eq!(printf_field("100%.vtk"), None);
        // Many stars against a long name that does not match: quick, not exponential.
        let long = [b'a'; 250];
        assert!(!matches(b"*a*a*a*a*a*a*a*a*a*a*b", &long));
    }

    #[test]
    fn a_folder_of_numbered_files_is_a_series_in_natural_order() {
        let d = tempfile::tempdir().unwrap();
        for n in ["P_10.vtk", "P_2.vtk", "P_1.vtk", "other.vtk"] {
            std::fs::write(d.path().join(n), b"x").unwrap();
        }
        let names = |c: Collection| -> Vec<String> {
            c.entries
                .iter()
                .map(|e| e.file.file_name().unwrap().to_string_lossy().to_string())
                .collect()
        };
        for pattern in ["P_*.vtk", "P_%d.vtk", "P_%04d.vtk"] {
            let c = series_of(&[d.path().join(pattern)]).unwrap().unwrap();
            assert_eq!(names(c), ["P_1.vtk", "P_2.vtk", "P_10.vtk"], "{pattern}");
        }
        let two = [d.path().join("other.vtk"), d.path().join("P_1.vtk")];
        let c = series_of(&two).unwrap().unwrap();
        assert_eq!(names(c.clone()), ["other.vtk", "P_1.vtk"]); // as given
        assert_eq!(c.entries[1].timestep, 1.0);
        assert!(series_of(&[d.path().join("P_1.vtk")]).unwrap().is_none());
        let e = series_of(&[d.path().join("Q_*.vtk")])
            .unwrap_err()
            .to_string();
        assert!(e.contains("Q_*.vtk") && e.contains("matches"), "{e}");
        let e = series_of(&[d.path().join("P_1.vtk"), d.path().join("s.pvd")]).unwrap_err();
        assert!(e.to_string().contains("give it alone"), "{e}");
    }
}
