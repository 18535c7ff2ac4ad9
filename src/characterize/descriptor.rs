//! EMVA 1288 acquisition-set descriptor files, in the format of the EMVA 1288 reference
//! implementation (the `emva1288` Python package, `ParseEmvaDescriptorFile`).
//!
//! A plain-text file, one command per line, `#` starts a comment line:
//!
//! ```text
//! v 3.0                      format version
//! n 12 640 480               bits per pixel, image width, image height (once)
//! d 5000000                  a dark series at exposure time 5 000 000 ns ...
//! i dark/d5000000_0.png      ... followed by its images, one `i` line each
//! i dark/d5000000_1.png
//! b 5000000 1234.5           a bright series: exposure time (ns), mean photons per pixel
//! i ptc/b000_0.png
//! i ptc/b000_1.png
//! ```
//!
//! A series of exactly two images is a *temporal* pair (photon transfer, dark current);
//! one of more than two is a *spatial* stack (DSNU, PRNU). Every series needs at least two
//! images. Image paths are relative to the descriptor's directory (`\` separators are
//! accepted); decimal commas in numbers are accepted as the reference parser does.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// One `d` or `b` block: an exposure time, the photons (bright only) and its images.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Exposure time, ns.
    pub exposure_ns: f64,
    /// Mean photons per pixel during the exposure (`None` for a dark series).
    pub photons_per_pixel: Option<f64>,
    /// Image paths as written in the file (relative to the descriptor's directory).
    pub images: Vec<String>,
    /// Line number (1-based) of the `d`/`b` command, for error messages.
    pub line: usize,
}

impl Series {
    /// Whether this series is a temporal pair (exactly two images) rather than a
    /// spatial stack.
    pub fn is_temporal(&self) -> bool {
        self.images.len() == 2
    }

    /// Whether this is a dark series.
    pub fn is_dark(&self) -> bool {
        self.photons_per_pixel.is_none()
    }
}

/// A parsed descriptor file.
#[derive(Debug, Clone, PartialEq)]
pub struct Descriptor {
    /// The `v` version string (the reference implementation writes `3.0`).
    pub version: String,
    /// Bits per pixel of the images.
    pub bits: u32,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// The series in file order.
    pub series: Vec<Series>,
}

fn number(path: &Path, line: usize, field: &str, text: &str) -> Result<f64> {
    let v: f64 = text.replace(',', ".").parse().map_err(|_| {
        Error::format(
            path,
            format!("line {line}: {field}: expected a number (the file's text is not shown)"),
        )
    })?;
    if !(v.is_finite() && v >= 0.0) {
        return Err(Error::format(
            path,
            format!("line {line}: {field} = {v}; expected a finite number >= 0"),
        ));
    }
    Ok(v)
}

impl Descriptor {
    /// Parses descriptor text; `path` only names the file in errors.
    ///
    /// Errors: an unknown command, a malformed `v`/`n`/`d`/`b`/`i` line, a second `n`
    /// line, a missing `n` line, an `i` line outside a series, a series with fewer than
    /// two images, or no series at all.
    pub fn parse(text: &str, path: &Path) -> Result<Self> {
        let mut version = None;
        let mut format: Option<(u32, usize, usize)> = None;
        let mut series: Vec<Series> = Vec::new();
        for (k, raw) in text.lines().enumerate() {
            let line = k + 1;
            let t = raw.trim();
            if t.is_empty() || t.starts_with('#') {
                continue;
            }
            let parts: Vec<&str> = t.split_whitespace().collect();
            let bad = |what: &str| Error::format(path, format!("line {line}: expected `{what}`"));
            match parts[0] {
                "v" if parts.len() == 2 => version = Some(parts[1].to_string()),
                "v" => return Err(bad("v version")),
                "n" => {
                    if parts.len() != 4 {
                        return Err(bad("n bits width height"));
                    }
                    if format.is_some() {
                        return Err(Error::format(
                            path,
                            format!("line {line}: only one `n bits width height` line is allowed"),
                        ));
                    }
                    let int = |s: &str, f: &str| -> Result<usize> {
                        s.parse::<usize>().ok().filter(|v| *v > 0).ok_or_else(|| {
                            Error::format(
                                path,
                                format!("line {line}: {f}: expected a positive integer"),
                            )
                        })
                    };
                    let bits = int(parts[1], "bits")?;
                    if bits > 16 {
                        return Err(Error::format(
                            path,
                            format!(
                                "line {line}: bits = {bits}; images of 1 to 16 bits are supported"
                            ),
                        ));
                    }
                    format = Some((
                        bits as u32,
                        int(parts[2], "width")?,
                        int(parts[3], "height")?,
                    ));
                }
                "d" => {
                    if parts.len() != 2 {
                        return Err(bad("d exposure_ns"));
                    }
                    series.push(Series {
                        exposure_ns: number(path, line, "exposure time", parts[1])?,
                        photons_per_pixel: None,
                        images: Vec::new(),
                        line,
                    });
                }
                "b" => {
                    if parts.len() != 3 {
                        return Err(bad("b exposure_ns photons"));
                    }
                    series.push(Series {
                        exposure_ns: number(path, line, "exposure time", parts[1])?,
                        photons_per_pixel: Some(number(path, line, "photons", parts[2])?),
                        images: Vec::new(),
                        line,
                    });
                }
                "i" => {
                    if parts.len() != 2 {
                        return Err(bad("i relative/path (no spaces)"));
                    }
                    let Some(s) = series.last_mut() else {
                        return Err(Error::format(
                            path,
                            format!("line {line}: image line before any `d` or `b` series"),
                        ));
                    };
                    s.images.push(parts[1].to_string());
                }
                _ => {
                    return Err(Error::format(
                        path,
                        format!(
                        "line {line}: unknown command; expected one of v, n, d, b, i, # comment"
                    ),
                    ))
                }
            }
        }
        let (bits, width, height) =
            format.ok_or_else(|| Error::format(path, "no `n bits width height` line"))?;
        if series.is_empty() {
            return Err(Error::format(path, "no `d` or `b` series"));
        }
        for s in &series {
            if s.images.len() < 2 {
                return Err(Error::format(
                    path,
                    format!(
                        "line {}: the series has {} image(s); every series needs at least 2 (a pair for the temporal noise, more for a spatial stack)",
                        s.line,
                        s.images.len()
                    ),
                ));
            }
        }
        Ok(Descriptor {
            version: version.unwrap_or_else(|| "3.0".to_string()),
            bits,
            width,
            height,
            series,
        })
    }

    /// Reads and parses `path`, and checks that every referenced image exists.
    ///
    /// Errors: as [`parse`](Self::parse), an unreadable file, or a missing image (named).
    pub fn read(path: &Path) -> Result<Self> {
        let text = crate::input::read_text(path)?;
        let d = Self::parse(&text, path)?;
        let dir = path.parent().unwrap_or(Path::new("."));
        for s in &d.series {
            for img in &s.images {
                let p = image_path(dir, img);
                match std::fs::metadata(&p) {
                    Ok(m) if m.is_file() => {}
                    Ok(m) => {
                        return Err(Error::format(
                            path,
                            format!(
                                "line {}: image `{}` ({}) is {}; images are read only from regular files",
                                s.line,
                                crate::limits::escape_token(img),
                                p.display(),
                                crate::input::kind_name(&m)
                            ),
                        ))
                    }
                    Err(_) => {
                        return Err(Error::format(
                            path,
                            format!(
                                "line {}: image `{img}` does not exist (looked for {})",
                                s.line,
                                p.display()
                            ),
                        ))
                    }
                }
            }
        }
        Ok(d)
    }

    /// The descriptor as text (the format of the module documentation).
    pub fn to_text(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(out, "# EMVA 1288 acquisition set written by eoir");
        let _ = writeln!(out, "v {}", self.version);
        let _ = writeln!(out, "n {} {} {}", self.bits, self.width, self.height);
        for s in &self.series {
            match s.photons_per_pixel {
                None => {
                    let _ = writeln!(out, "d {}", s.exposure_ns);
                }
                Some(p) => {
                    let _ = writeln!(out, "b {} {}", s.exposure_ns, p);
                }
            }
            for i in &s.images {
                let _ = writeln!(out, "i {i}");
            }
        }
        out
    }
}

/// The file an `i` line names: relative to `dir`, with `\` or `/` separators.
pub fn image_path(dir: &Path, relative: &str) -> PathBuf {
    let mut p = dir.to_path_buf();
    for part in relative.split(['\\', '/']).filter(|s| !s.is_empty()) {
        p.push(part);
    }
    p
}
