//! The ENVI header: its `key = value` entries, the spectral units of its wavelength list,
//! and finding the data file that goes with it (see the [parent module](super) for the
//! keys eoir reads).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Header keys stating the radiance units, in precedence order.
pub(super) const UNIT_KEYS: [&str; 4] = [
    "eoir radiance units",
    "radiance units",
    "data units",
    "units",
];
/// Common header keys holding the full field of view in degrees, in precedence order.
pub(super) const FOV_KEYS: [&str; 2] = ["fov", "field of view"];

/// Data file extensions looked for next to a header, in order of preference.
pub(super) const DATA_EXTENSIONS: [&str; 6] = ["img", "dat", "raw", "bsq", "bil", "bip"];

/// How bands are arranged in the data file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Interleave {
    /// Band sequential: `[band, row, col]`.
    Bsq,
    /// Band interleaved by line: `[row, band, col]`.
    Bil,
    /// Band interleaved by pixel: `[row, col, band]`.
    Bip,
}

/// Spectral axis units of an ENVI `wavelength` list.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum SpectralUnits {
    /// A wavelength unit, with the factor that converts it to µm.
    Length(f64),
    /// Wavenumber, cm⁻¹.
    Wavenumber,
}

impl SpectralUnits {
    pub(super) fn parse(s: &str) -> Option<Self> {
        let t: String = s
            .to_lowercase()
            .replace(['µ', 'μ'], "u")
            .chars()
            .filter(|c| !c.is_whitespace())
            .collect();
        match t.as_str() {
            "micrometers" | "micrometer" | "micrometres" | "micrometre" | "microns" | "micron"
            | "um" => Some(SpectralUnits::Length(1.0)),
            "nanometers" | "nanometer" | "nanometres" | "nanometre" | "nm" => {
                Some(SpectralUnits::Length(1e-3))
            }
            "millimeters" | "millimeter" | "millimetres" | "millimetre" | "mm" => {
                Some(SpectralUnits::Length(1e3))
            }
            "meters" | "meter" | "metres" | "metre" | "m" => Some(SpectralUnits::Length(1e6)),
            "wavenumber" | "wavenumbers" | "cm-1" | "cm^-1" | "1/cm" => {
                Some(SpectralUnits::Wavenumber)
            }
            _ => None,
        }
    }

    /// Converts band centres to µm.
    pub(super) fn centres_um(self, v: &[f64]) -> Vec<f64> {
        match self {
            SpectralUnits::Length(f) => v.iter().map(|x| x * f).collect(),
            // λ [µm] = 10⁴ / ν [cm⁻¹]  (1 cm = 10⁴ µm).
            SpectralUnits::Wavenumber => v.iter().map(|nu| 1e4 / nu).collect(),
        }
    }

    /// Converts band widths to µm, given the band centres in the file's units.
    pub(super) fn widths_um(self, width: &[f64], centre: &[f64]) -> Vec<f64> {
        match self {
            SpectralUnits::Length(f) => width.iter().map(|x| x * f).collect(),
            // |dλ/dν| = 10⁴ / ν², so a narrow band of width Δν at ν spans
            // Δλ ≈ 10⁴ Δν / ν² µm (first order in Δν/ν).
            SpectralUnits::Wavenumber => width
                .iter()
                .zip(centre)
                .map(|(dnu, nu)| 1e4 * dnu / (nu * nu))
                .collect(),
        }
    }
}

/// One `key = value` entry of a header.
#[derive(Debug, Clone)]
pub(super) struct Entry {
    /// The value, without the braces of a `{…}` value.
    pub(super) value: String,
    /// Line number (1-based) the entry starts on.
    pub(super) line: usize,
}

/// The parsed header: entries by normalised key.
pub(super) struct Header {
    pub(super) path: PathBuf,
    pub(super) entries: HashMap<String, Entry>,
}

/// Lower-cases a key and collapses white space to single spaces.
pub(super) fn normalise_key(k: &str) -> String {
    k.split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
        .to_lowercase()
}

impl Header {
    /// Parses header text; non-fatal oddities are appended to `warnings`.
    pub(super) fn parse(path: &Path, text: &str, warnings: &mut Vec<String>) -> Result<Self> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let mut lines = text.lines().enumerate().peekable();
        // First non-blank line: the magic word.
        loop {
            match lines.next() {
                None => {
                    return Err(Error::format(
                        path,
                        "empty file: an ENVI header starts with a line `ENVI`",
                    ))
                }
                Some((_, l)) if l.trim().is_empty() => continue,
                Some((_, l)) if l.trim().eq_ignore_ascii_case("envi") => break,
                Some((i, _)) => {
                    return Err(Error::format(
                        path,
                        format!(
                            "not an ENVI header: line {} is not `ENVI`; expected `ENVI` as the first line (the file's text is not shown)",
                            i + 1
                        ),
                    ))
                }
            }
        }
        let mut entries: HashMap<String, Entry> = HashMap::new();
        while let Some((i, raw)) = lines.next() {
            let l = raw.trim();
            if l.is_empty() || l.starts_with(';') {
                continue;
            }
            let Some((k, v)) = l.split_once('=') else {
                warnings.push(format!(
                    "{}: line {} ignored: expected `key = value`",
                    path.display(),
                    i + 1
                ));
                continue;
            };
            let key = normalise_key(k);
            let mut value = v.trim().to_string();
            if let Some(rest) = value.strip_prefix('{') {
                let mut inner = rest.to_string();
                loop {
                    if let Some(end) = inner.find('}') {
                        inner.truncate(end);
                        break;
                    }
                    match lines.next() {
                        Some((_, more)) => {
                            if more.trim_start().starts_with(';') {
                                continue;
                            }
                            inner.push('\n');
                            inner.push_str(more);
                        }
                        None => {
                            return Err(Error::format(
                                path,
                                format!(
                                    "line {}: the `{{` opened for `{key}` is never closed by `}}`",
                                    i + 1
                                ),
                            ))
                        }
                    }
                }
                value = inner.trim().to_string();
            }
            if entries.contains_key(&key) {
                warnings.push(format!(
                    "{}: `{key}` appears more than once; line {} wins",
                    path.display(),
                    i + 1
                ));
            }
            entries.insert(key, Entry { value, line: i + 1 });
        }
        Ok(Header {
            path: path.to_path_buf(),
            entries,
        })
    }

    pub(super) fn get(&self, key: &str) -> Option<&Entry> {
        self.entries.get(key)
    }

    pub(super) fn error(&self, key: &str, e: &Entry, expected: &str) -> Error {
        Error::format(
            &self.path,
            format!(
                "line {}: `{key} = {}`: expected {expected}",
                e.line, e.value
            ),
        )
    }

    pub(super) fn missing(&self, key: &str, example: &str) -> Error {
        Error::format(
            &self.path,
            format!("the header has no `{key}` (add e.g. `{key} = {example}`)"),
        )
    }

    /// A required whole number > 0.
    pub(super) fn count(&self, key: &str, example: &str) -> Result<usize> {
        let e = self.get(key).ok_or_else(|| self.missing(key, example))?;
        match e.value.parse::<usize>() {
            Ok(n) if n > 0 => Ok(n),
            _ => Err(self.error(key, e, "a whole number > 0")),
        }
    }

    /// An optional whole number ≥ 0.
    pub(super) fn opt_u64(&self, key: &str) -> Result<Option<u64>> {
        self.get(key)
            .map(|e| {
                e.value
                    .parse::<u64>()
                    .map_err(|_| self.error(key, e, "a whole number >= 0"))
            })
            .transpose()
    }

    /// An optional single number.
    pub(super) fn opt_f64(&self, key: &str) -> Result<Option<f64>> {
        self.get(key)
            .map(|e| {
                let v = e.value.trim_start_matches('{').trim_end_matches('}').trim();
                v.parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| self.error(key, e, "a number"))
            })
            .transpose()
    }

    /// An optional list of numbers separated by commas and/or white space; when `len` is
    /// given the list must have that many entries.
    pub(super) fn opt_list(&self, key: &str, len: Option<usize>) -> Result<Option<Vec<f64>>> {
        let Some(e) = self.get(key) else {
            return Ok(None);
        };
        let mut out = Vec::new();
        for tok in e
            .value
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|t| !t.is_empty())
        {
            match tok.parse::<f64>() {
                Ok(x) if x.is_finite() => out.push(x),
                _ => {
                    return Err(Error::format(
                        &self.path,
                        format!(
                            "line {}: `{key}` entry {} is `{tok}`, which is not a finite number",
                            e.line,
                            out.len()
                        ),
                    ))
                }
            }
        }
        if let Some(n) = len {
            if out.len() != n {
                return Err(Error::format(
                    &self.path,
                    format!(
                        "line {}: `{key}` has {} values but the header says bands = {n}",
                        e.line,
                        out.len()
                    ),
                ));
            }
        }
        Ok(Some(out))
    }

    /// An optional pair `{a, b}`.
    pub(super) fn opt_pair(&self, key: &str) -> Result<Option<[f64; 2]>> {
        match self.opt_list(key, None)? {
            None => Ok(None),
            Some(v) if v.len() == 2 => Ok(Some([v[0], v[1]])),
            Some(v) => Err(Error::format(
                &self.path,
                format!(
                    "`{key}` has {} values; expected two: `{key} = {{x, y}}`",
                    v.len()
                ),
            )),
        }
    }
}

/// Finds a file named `name` in `dir`, trying the exact name first and then any letter
/// case.
pub(super) fn find_file(
    dir: &Path,
    name: &str,
    listing: &mut Option<Vec<PathBuf>>,
) -> Option<PathBuf> {
    let exact = dir.join(name);
    if exact.is_file() {
        return Some(exact);
    }
    let entries = listing.get_or_insert_with(|| {
        std::fs::read_dir(if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        })
        .map(|rd| rd.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default()
    });
    entries
        .iter()
        .find(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.eq_ignore_ascii_case(name))
                && p.is_file()
        })
        .map(|p| dir.join(p.file_name().unwrap_or_default()))
}

/// Returns `(header, data)` for either file of an ENVI pair.
pub(super) fn find_pair(path: &Path) -> Result<(PathBuf, PathBuf)> {
    if !path.is_file() {
        return Err(Error::io(
            path,
            std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
        ));
    }
    let dir = path.parent().unwrap_or(Path::new(""));
    let name = path
        .file_name()
        .and_then(|n| n.to_str())
        .ok_or_else(|| Error::format(path, "the file name is not valid UTF-8"))?;
    let is_header = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("hdr"));
    let stem = path
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or(name)
        .to_string();
    let mut listing = None;
    let candidates: Vec<String> = if is_header {
        std::iter::once(stem.clone())
            .chain(DATA_EXTENSIONS.iter().map(|e| format!("{stem}.{e}")))
            .collect()
    } else if path.extension().is_some() {
        vec![format!("{name}.hdr"), format!("{stem}.hdr")]
    } else {
        vec![format!("{name}.hdr")]
    };
    for c in &candidates {
        if let Some(p) = find_file(dir, c, &mut listing) {
            return Ok(if is_header {
                (path.to_path_buf(), p)
            } else {
                (p, path.to_path_buf())
            });
        }
    }
    let what = if is_header { "data file" } else { "header" };
    Err(Error::format(
        path,
        format!(
            "no ENVI {what} found next to it; tried {} (any letter case) in `{}`",
            candidates.join(", "),
            if dir.as_os_str().is_empty() {
                Path::new(".")
            } else {
                dir
            }
            .display()
        ),
    ))
}
