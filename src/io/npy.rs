//! NumPy `.npy` cubes with a `.json` sidecar for the metadata.
//!
//! The array is `[band, row, col]` (one cube) or `[frame, band, row, col]` (a sequence),
//! in C (row-major) order, with dtype `<f4`, `<f8`, `>f4`, `>f8`, `<u2`, `>u2`, `<i2` or
//! `>i2`. Format versions 1, 2 and 3 are read. The header is parsed here and each
//! [`read_band`](CubeReader::read_band) seeks straight to that band's bytes, so memory
//! does not grow with the number of bands or frames.
//!
//! The sidecar is `<stem>.json` next to `<stem>.npy`. Only `wavelength_um` is required;
//! keys eoir does not know (`layout`, `scene`, … as other tools write them) are listed in
//! the warnings and otherwise ignored:
//!
//! ```json
//! {
//!   "wavelength_um": [8.5, 10.5],
//!   "fwhm_um": [1.0, 1.0],
//!   "units": "W m-2 sr-1 um-1",
//!   "fov_deg": [10.0, 7.5],
//!   "range_m": 1000.0,
//!   "frame_time_s": 0.02
//! }
//! ```
//!
//! `units` (or `radiance_units`) is any radiance unit [`crate::scene::units`] parses —
//! `W m-2 sr-1 um-1` (spectral radiance, the default, with a warning when absent),
//! `W/(m2 sr nm)`, `uW cm-2 sr-1 nm-1`, `W m-2 sr-1` (band-integrated)… — and the values
//! are converted to eoir's units. Instead of `fov_deg` (full field of view, degrees,
//! horizontal then vertical) the sidecar may give `ifov_rad` (angular pixel spacing, rad,
//! x then y); a foreign `fov` key (`[h, v]` or the horizontal alone, degrees) is used when
//! neither is present (precedence in [`super::metadata`]). Wavelengths listed in strictly decreasing order are handed
//! out in increasing order (the bands are reversed transparently).
//!
//! [`write()`] stores `<f4` `[band, row, col]` (version 1.0) plus the sidecar, each
//! atomically, the array first; if the sidecar cannot be written the new array file is
//! removed again.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};

use ndarray::Array2;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::scene::{check_radiance_plane, Cube, CubeMeta};

use super::binary::{check_size, read_samples, PlanePool, SampleType};
use super::mapped::{map_plane, BandPlanes, DeferredCheck};
use super::metadata::{
    default_units, order_bands, resolve_geometry, resolve_units, BandOrder, ReadOptions,
};
use super::{atomic_write, write_all, CubeReader};

/// The NPY magic string.
const MAGIC: &[u8; 6] = b"\x93NUMPY";

/// The metadata sidecar of an `.npy` cube (`<stem>.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sidecar {
    /// Band centre wavelengths, µm, one per band.
    pub wavelength_um: Vec<f64>,
    /// Band full widths at half maximum, µm, one per band.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fwhm_um: Option<Vec<f64>>,
    /// Radiance units, any spelling of [`crate::scene::units`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub units: Option<String>,
    /// Full field of view `[horizontal, vertical]`, degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fov_deg: Option<[f64; 2]>,
    /// Angular pixel spacing `[x, y]`, rad (instead of `fov_deg`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ifov_rad: Option<[f64; 2]>,
    /// Range to the scene, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub range_m: Option<f64>,
    /// Time between frames of a `[frame, band, row, col]` array, s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame_time_s: Option<f64>,
    /// Every other key: `radiance_units` and `fov` are read (see the module
    /// documentation), the rest are warnings.
    #[serde(flatten)]
    pub extra: BTreeMap<String, serde_json::Value>,
}

/// The sidecar path for an `.npy` file: same stem, `.json`.
pub fn sidecar_path(path: &Path) -> PathBuf {
    path.with_extension("json")
}

/// A value of the Python literal subset an NPY header uses.
#[derive(Debug, Clone, PartialEq)]
enum Py {
    Str(String),
    Bool(bool),
    Int(u64),
    None,
    Seq(Vec<Py>),
    Dict(Vec<(Py, Py)>),
}

/// Deepest nesting of `(`, `[`, `{` an NPY header may use. A real header nests at most
/// four deep (dict → structured descr list → field tuple → sub-shape tuple); the bound keeps
/// the recursive descent's stack use independent of the input (a 35 KB header nested
/// 17,000 deep would otherwise overflow the stack).
pub const MAX_HEADER_DEPTH: usize = 16;

/// Recursive-descent parser for the NPY header dictionary, depth-bounded by
/// [`MAX_HEADER_DEPTH`].
struct PyParser<'a> {
    s: &'a [u8],
    i: usize,
    depth: usize,
}

impl PyParser<'_> {
    fn ws(&mut self) {
        while self.i < self.s.len() && self.s[self.i].is_ascii_whitespace() {
            self.i += 1;
        }
    }

    fn peek(&mut self) -> Option<u8> {
        self.ws();
        self.s.get(self.i).copied()
    }

    fn expect(&mut self, c: u8) -> std::result::Result<(), String> {
        if self.peek() == Some(c) {
            self.i += 1;
            Ok(())
        } else {
            Err(format!("expected `{}` at byte {}", c as char, self.i))
        }
    }

    /// Items up to `close`, separated by commas, trailing comma allowed.
    fn items(&mut self, close: u8) -> std::result::Result<Vec<Py>, String> {
        let mut v = Vec::new();
        loop {
            if self.peek() == Some(close) {
                self.i += 1;
                return Ok(v);
            }
            v.push(self.value()?);
            match self.peek() {
                Some(b',') => self.i += 1,
                Some(c) if c == close => {}
                _ => {
                    return Err(format!(
                        "expected `,` or `{}` at byte {}",
                        close as char, self.i
                    ))
                }
            }
        }
    }

    fn value(&mut self) -> std::result::Result<Py, String> {
        if matches!(self.peek(), Some(b'(' | b'[' | b'{')) {
            if self.depth >= MAX_HEADER_DEPTH {
                return Err(format!(
                    "nesting deeper than {MAX_HEADER_DEPTH} levels at byte {}",
                    self.i
                ));
            }
            self.depth += 1;
            let v = self.nested_value();
            self.depth -= 1;
            return v;
        }
        self.nested_value()
    }

    fn nested_value(&mut self) -> std::result::Result<Py, String> {
        match self.peek() {
            None => Err("unexpected end of header".into()),
            Some(q @ (b'\'' | b'"')) => {
                self.i += 1;
                let mut out = Vec::new();
                while let Some(&c) = self.s.get(self.i) {
                    self.i += 1;
                    if c == q {
                        return Ok(Py::Str(String::from_utf8_lossy(&out).into_owned()));
                    }
                    if c == b'\\' {
                        if let Some(&n) = self.s.get(self.i) {
                            out.push(n);
                            self.i += 1;
                        }
                    } else {
                        out.push(c);
                    }
                }
                Err("unterminated string".into())
            }
            Some(b'(') => {
                self.i += 1;
                self.items(b')').map(Py::Seq)
            }
            Some(b'[') => {
                self.i += 1;
                self.items(b']').map(Py::Seq)
            }
            Some(b'{') => {
                self.i += 1;
                let mut v = Vec::new();
                loop {
                    if self.peek() == Some(b'}') {
                        self.i += 1;
                        return Ok(Py::Dict(v));
                    }
                    let k = self.value()?;
                    self.expect(b':')?;
                    let val = self.value()?;
                    v.push((k, val));
                    match self.peek() {
                        Some(b',') => self.i += 1,
                        Some(b'}') => {}
                        _ => return Err(format!("expected `,` or `}}` at byte {}", self.i)),
                    }
                }
            }
            Some(c) if c.is_ascii_digit() => {
                let start = self.i;
                while self.i < self.s.len() && self.s[self.i].is_ascii_digit() {
                    self.i += 1;
                }
                let text = std::str::from_utf8(&self.s[start..self.i]).unwrap_or("");
                let n = text
                    .parse::<u64>()
                    .map_err(|_| format!("a number too large at byte {start} of the header"))?;
                // Python 2 long suffix.
                if matches!(self.s.get(self.i), Some(b'L' | b'l')) {
                    self.i += 1;
                }
                Ok(Py::Int(n))
            }
            Some(c) if c.is_ascii_alphabetic() => {
                let start = self.i;
                while self.i < self.s.len() && self.s[self.i].is_ascii_alphanumeric() {
                    self.i += 1;
                }
                match &self.s[start..self.i] {
                    b"True" => Ok(Py::Bool(true)),
                    b"False" => Ok(Py::Bool(false)),
                    b"None" => Ok(Py::None),
                    _ => Err(format!(
                        "unexpected word at byte {start} of the header; expected a number, True, False, None or a quoted string"
                    )),
                }
            }
            Some(c) => Err(format!(
                "unexpected character `{}` at byte {}",
                (c as char).escape_default(),
                self.i
            )),
        }
    }
}

/// What an NPY header says about the array.
#[derive(Debug, Clone)]
pub(crate) struct NpyHeader {
    /// Element type.
    pub(crate) ty: SampleType,
    /// Big-endian elements.
    pub(crate) big_endian: bool,
    /// Array shape, C order.
    pub(crate) shape: Vec<usize>,
    /// Byte offset of the first array element.
    pub(crate) data_start: u64,
}

/// Parses the dtype string of a simple (non-structured) array.
fn parse_descr(path: &Path, d: &str) -> Result<(SampleType, bool)> {
    let supported = "supported dtypes are <f4, <f8, >f4, >f8, <u2, >u2, <i2, >i2 (convert with a.astype('<f4'))";
    // Split after the first character, not byte: a mutated header may hold non-ASCII.
    let (order, code) = d.split_at(d.chars().next().map_or(0, char::len_utf8));
    let big_endian = match order {
        "<" => false,
        ">" => true,
        "=" => cfg!(target_endian = "big"),
        _ => {
            return Err(Error::format(
                path,
                format!(
                    "array dtype `{}` is not supported; {supported}",
                    crate::limits::escape_token(d)
                ),
            ))
        }
    };
    let ty = match code {
        "f4" => SampleType::F32,
        "f8" => SampleType::F64,
        "u2" => SampleType::U16,
        "i2" => SampleType::I16,
        _ => {
            return Err(Error::format(
                path,
                format!(
                    "array dtype `{}` is not supported; {supported}",
                    crate::limits::escape_token(d)
                ),
            ))
        }
    };
    Ok((ty, big_endian))
}

/// Reads and checks the NPY preamble and header dictionary with the bounded parser (no
/// recursion on input, no allocation beyond the header's length, which is checked against
/// `file_len`). Other NPY readers of the crate (NUC coefficients) validate through it.
pub(crate) fn read_header(path: &Path, file: &mut File, file_len: u64) -> Result<NpyHeader> {
    let bad = |m: String| Error::format(path, m);
    let mut pre = [0u8; 8];
    if file_len < 10 {
        return Err(bad(format!(
            "not a NumPy .npy file: only {file_len} bytes (truncated?)"
        )));
    }
    file.read_exact(&mut pre).map_err(|e| Error::io(path, e))?;
    if &pre[..6] != MAGIC {
        return Err(bad(
            "not a NumPy .npy file (the magic string \\x93NUMPY is missing)".into(),
        ));
    }
    let major = pre[6];
    let (len_bytes, utf8) = match major {
        1 => (2usize, false),
        2 => (4, false),
        3 => (4, true),
        _ => {
            return Err(bad(format!(
                "NPY format version {major}.{} is not supported (versions 1, 2 and 3 are)",
                pre[7]
            )))
        }
    };
    let mut lb = [0u8; 4];
    file.read_exact(&mut lb[..len_bytes])
        .map_err(|e| Error::io(path, e))?;
    let header_len = u32::from_le_bytes(lb) as u64;
    let data_start = 8 + len_bytes as u64 + header_len;
    if data_start > file_len {
        return Err(bad(format!(
            "file is truncated: the NPY header claims {header_len} bytes but the file has only {file_len} bytes"
        )));
    }
    let mut hb = vec![0u8; header_len as usize];
    file.read_exact(&mut hb).map_err(|e| Error::io(path, e))?;
    let text: String = if utf8 {
        String::from_utf8(hb).map_err(|_| bad("NPY v3 header is not valid UTF-8".into()))?
    } else {
        hb.iter().map(|&b| b as char).collect()
    };
    let mut p = PyParser {
        s: text.as_bytes(),
        i: 0,
        depth: 0,
    };
    let dict = match p.value() {
        Ok(Py::Dict(d)) => d,
        Ok(_) => return Err(bad("NPY header is not a dictionary".into())),
        Err(e) => {
            return Err(bad(format!(
                "cannot parse the NPY header (the file's text is not shown): {e}"
            )))
        }
    };
    let get = |k: &str| {
        dict.iter()
            .find(|(key, _)| *key == Py::Str(k.into()))
            .map(|(_, v)| v)
    };
    let descr = match get("descr") {
        Some(Py::Str(s)) => s.clone(),
        Some(_) => {
            return Err(bad(
                "structured (record) arrays are not supported; save a plain numeric array".into(),
            ))
        }
        None => return Err(bad("NPY header has no `descr`".into())),
    };
    let (ty, big_endian) = parse_descr(path, &descr)?;
    match get("fortran_order") {
        Some(Py::Bool(false)) => {}
        Some(Py::Bool(true)) => {
            return Err(bad(
                "the array is stored in Fortran (column-major) order, which is not supported; save it in C order, e.g. np.save(path, np.ascontiguousarray(a))".into(),
            ))
        }
        _ => return Err(bad("NPY header has no boolean `fortran_order`".into())),
    }
    let shape = match get("shape") {
        Some(Py::Seq(s)) => s
            .iter()
            .map(|v| match v {
                Py::Int(n) => {
                    usize::try_from(*n).map_err(|_| bad(format!("dimension {n} is too large")))
                }
                _ => Err(bad("NPY `shape` holds a non-integer".into())),
            })
            .collect::<Result<Vec<usize>>>()?,
        _ => return Err(bad("NPY header has no `shape` tuple".into())),
    };
    Ok(NpyHeader {
        ty,
        big_endian,
        shape,
        data_start,
    })
}

/// The sidecar content a user needs at minimum, for error messages.
fn minimal_sidecar(bands: usize) -> String {
    let example: Vec<String> = (0..bands.clamp(1, 3))
        .map(|i| format!("{}", 8 + i))
        .collect();
    format!(
        "{{\"wavelength_um\": [{}{}]}} (one wavelength in µm per band; optional keys: fwhm_um, units, fov_deg or ifov_rad, range_m, frame_time_s)",
        example.join(", "),
        if bands > 3 { ", …" } else { "" }
    )
}

/// Reads an `.npy` cube (or sequence of cubes) band by band.
#[derive(Debug)]
pub struct NpyReader {
    meta: CubeMeta,
    path: PathBuf,
    file: File,
    ty: SampleType,
    big_endian: bool,
    data_start: u64,
    frames: usize,
    frame_time_s: Option<f64>,
    /// Output band index → stored band index.
    band_map: Vec<usize>,
    /// Factor from the stated units to eoir's.
    to_eoir: f64,
    units_source: String,
    warnings: Vec<String>,
    /// The reading options it was opened with (for [`CubeReader::reopen`]).
    options: ReadOptions,
    /// Plane buffers handed back by the engine.
    pool: PlanePool,
    /// Set once mapping the file failed: later reads go straight to `read()`.
    map_failed: bool,
}

impl NpyReader {
    /// Opens an `.npy` cube and its `<stem>.json` sidecar, checking the header, the
    /// file's size and the metadata.
    pub fn open(path: &Path) -> Result<Self> {
        Self::open_with(path, &ReadOptions::default())
    }

    /// Like [`open`](Self::open), with reading options (a radiance-unit override).
    pub fn open_with(path: &Path, options: &ReadOptions) -> Result<Self> {
        let mut file = crate::io::input::open_regular(path)?;
        let file_len = file.metadata().map_err(|e| Error::io(path, e))?.len();
        let h = read_header(path, &mut file, file_len)?;
        let (frames, bands, rows, cols) = match h.shape[..] {
            [b, r, c] => (1, b, r, c),
            [f, b, r, c] => (f, b, r, c),
            _ => {
                return Err(Error::format(
                    path,
                    format!(
                        "array shape has {} dimensions; expected [band, row, col] or [frame, band, row, col]",
                        h.shape.len()
                    ),
                ))
            }
        };
        if h.shape.contains(&0) {
            return Err(Error::format(
                path,
                format!("array shape {:?} has a zero-length dimension", h.shape),
            ));
        }
        let payload = [frames, bands, rows, cols, h.ty.size()]
            .iter()
            .try_fold(1u64, |acc, &n| acc.checked_mul(n as u64))
            .and_then(|n| n.checked_add(h.data_start))
            .ok_or_else(|| Error::format(path, "array shape is too large"))?;
        let layout = format!(
            "{} header bytes + shape {:?} × {} bytes",
            h.data_start,
            h.shape,
            h.ty.size()
        );
        check_size(path, file_len, payload, &layout)?;
        crate::limits::check_alloc(
            &format!("reading one band of {}", path.display()),
            &[("rows", rows as u64), ("cols", cols as u64)],
            4 + h.ty.size() as u64,
        )?;

        let side = sidecar_path(path);
        let text = match crate::io::input::read_text(&side) {
            Ok(t) => t,
            Err(Error::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => {
                return Err(Error::format(
                    path,
                    format!(
                        "the metadata sidecar `{}` is missing; create it with at least {}",
                        side.display(),
                        minimal_sidecar(bands)
                    ),
                ))
            }
            Err(e) => return Err(e),
        };
        let sc: Sidecar = serde_json::from_str(&text).map_err(|e| {
            Error::format(
                &side,
                format!("{e}; expected e.g. {}", minimal_sidecar(bands)),
            )
        })?;
        if sc.wavelength_um.len() != bands {
            return Err(Error::format(
                &side,
                format!(
                    "wavelength_um has {} values but the array has {bands} bands (shape {:?})",
                    sc.wavelength_um.len(),
                    h.shape
                ),
            ));
        }
        if let Some(f) = &sc.fwhm_um {
            if f.len() != bands {
                return Err(Error::format(
                    &side,
                    format!(
                        "fwhm_um has {} values but the array has {bands} bands",
                        f.len()
                    ),
                ));
            }
        }
        let mut warnings = Vec::new();
        let mut statements = Vec::new();
        if let Some(u) = &sc.units {
            statements.push(("units".to_string(), u.clone()));
        }
        let mut common = Vec::new();
        for (key, value) in &sc.extra {
            match (key.as_str(), value) {
                ("radiance_units", serde_json::Value::String(u)) => {
                    statements.push((key.clone(), u.clone()))
                }
                ("fov", v) => {
                    let values = match v {
                        serde_json::Value::Number(n) => n.as_f64().map(|x| vec![x]),
                        serde_json::Value::Array(a) => a.iter().map(|x| x.as_f64()).collect(),
                        _ => None,
                    }
                    .ok_or_else(|| {
                        Error::format(
                            &side,
                            format!("`fov` = {v}: expected degrees, [horizontal, vertical] or one horizontal value"),
                        )
                    })?;
                    common.push((key.clone(), values));
                }
                _ => warnings.push(format!(
                    "{}: key `{key}` is not an eoir key and was ignored",
                    side.display()
                )),
            }
        }
        let resolved = match resolve_units(&side, &statements, options, &mut warnings)? {
            Some(r) => r,
            None => default_units(&side, "`units` or `radiance_units`", &mut warnings),
        };
        let units = resolved.scale.units;
        if let Some(t) = sc.frame_time_s {
            if !(t.is_finite() && t > 0.0) {
                return Err(Error::format(
                    &side,
                    format!("frame_time_s = {t}: expected a time > 0 s"),
                ));
            }
        }
        let geometry = resolve_geometry(
            &side,
            ["fov_deg", "ifov_rad", "range_m"],
            sc.fov_deg,
            sc.ifov_rad,
            &common,
            sc.range_m,
            rows,
            cols,
            &mut warnings,
        )?;
        let BandOrder {
            wavelength_um,
            fwhm_um,
            band_map,
            reversed,
        } = order_bands(&side, sc.wavelength_um, sc.fwhm_um)?;
        if reversed {
            warnings.push(format!(
                "{}: wavelengths are listed in decreasing order; bands are handed out in increasing wavelength (band 0 = stored band {})",
                side.display(),
                bands - 1
            ));
        }
        let meta = CubeMeta {
            wavelength_um,
            fwhm_um,
            units,
            geometry,
            rows,
            cols,
        };
        meta.validate(&side.display().to_string())?;
        Ok(NpyReader {
            options: options.clone(),
            pool: PlanePool::default(),
            map_failed: false,
            meta,
            path: path.to_path_buf(),
            file,
            ty: h.ty,
            big_endian: h.big_endian,
            data_start: h.data_start,
            frames,
            frame_time_s: sc.frame_time_s,
            band_map,
            to_eoir: resolved.scale.to_eoir,
            units_source: resolved.source,
            warnings,
        })
    }
}

impl CubeReader for NpyReader {
    fn meta(&self) -> &CubeMeta {
        &self.meta
    }

    fn frames(&self) -> usize {
        self.frames
    }

    fn frame_time_s(&self) -> Option<f64> {
        self.frame_time_s
    }

    fn read_band(&mut self, frame: usize, band: usize) -> Result<Array2<f32>> {
        let offset = self.plane_offset(frame, band)?;
        let (rows, cols) = (self.meta.rows, self.meta.cols);
        // The plane is contiguous ([frame, band, row, col] in C order): one sequential
        // read (in 4 MiB pieces for larger planes), decoded as it arrives.
        let mut values = self.pool.take(rows * cols);
        let scale = (self.to_eoir != 1.0).then_some((self.to_eoir, 0.0));
        read_samples(
            &mut self.file,
            &self.path,
            offset,
            rows * cols,
            self.ty,
            self.big_endian,
            scale,
            &mut values,
        )?;
        let plane = Array2::from_shape_vec((rows, cols), values)
            .map_err(|e| Error::format(&self.path, e.to_string()))?;
        check_radiance_plane(
            &self.path.display().to_string(),
            band,
            self.meta.wavelength_um[band],
            plane.view(),
        )?;
        Ok(plane)
    }

    /// `<f4` data in the machine's byte order, in eoir's units, comes zero-copy from
    /// memory maps of the file (see [`super::mapped`]; the NPY header pads the data to a
    /// 64-byte boundary); everything else as [`CubeReader::read_bands`] reads it.
    fn read_planes(&mut self, frame: usize, bands: &[usize]) -> Result<BandPlanes> {
        let (planes, check) = self.read_planes_deferred(frame, bands)?;
        if let Some(check) = check {
            check.run(&planes)?;
        }
        Ok(planes)
    }

    /// As `read_planes`, the mapped planes unchecked (see the trait method).
    fn read_planes_deferred(
        &mut self,
        frame: usize,
        bands: &[usize],
    ) -> Result<(BandPlanes, Option<DeferredCheck>)> {
        let native = self.big_endian == cfg!(target_endian = "big");
        if self.options.no_memory_map
            || self.map_failed
            || self.ty != SampleType::F32
            || !native
            || self.to_eoir != 1.0
            || bands.is_empty()
        {
            return Ok((self.read_bands(frame, bands).map(BandPlanes::Owned)?, None));
        }
        let (rows, cols) = (self.meta.rows, self.meta.cols);
        let mut planes = Vec::with_capacity(bands.len());
        for &b in bands {
            let offset = self.plane_offset(frame, b)?;
            let Some(plane) = map_plane(&self.file, offset, rows, cols) else {
                self.map_failed = true;
                return Ok((self.read_bands(frame, bands).map(BandPlanes::Owned)?, None));
            };
            planes.push(plane);
        }
        let check = DeferredCheck::new(&self.path, bands, &self.meta.wavelength_um);
        Ok((BandPlanes::Mapped(planes), Some(check)))
    }

    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    fn units_source(&self) -> String {
        self.units_source.clone()
    }

    /// The same file opened again by path with the same options: an own file handle.
    fn reopen(&self) -> Option<Result<Box<dyn CubeReader + Send>>> {
        Some(Self::open_with(&self.path, &self.options).map(|r| Box::new(r) as _))
    }

    fn recycle(&mut self, planes: Vec<Array2<f32>>) {
        self.pool.give(planes, self.meta.rows * self.meta.cols);
    }
}

impl NpyReader {
    /// The byte offset of band `band` of frame `frame` (output numbering), after checking
    /// both exist.
    fn plane_offset(&self, frame: usize, band: usize) -> Result<u64> {
        let bands = self.meta.bands();
        if frame >= self.frames {
            return Err(Error::OutOfRange(format!(
                "{}: frame {frame} requested but the file has frames 0..{}",
                self.path.display(),
                self.frames
            )));
        }
        if band >= bands {
            return Err(Error::OutOfRange(format!(
                "{}: band {band} requested but the cube has bands 0..{bands}",
                self.path.display()
            )));
        }
        let (rows, cols) = (self.meta.rows, self.meta.cols);
        let plane_bytes = (rows * cols * self.ty.size()) as u64;
        let index = (frame * bands + self.band_map[band]) as u64;
        Ok(self.data_start + index * plane_bytes)
    }
}

/// The NPY v1.0 preamble + header for a C-order `<f4` array of `shape`, padded with
/// spaces and a newline so the data starts on a 64-byte boundary.
fn npy_header_f32(shape: &[usize]) -> Vec<u8> {
    npy_header("<f4", shape)
}

/// The NPY v1.0 preamble + header for a C-order array of type `descr` (e.g. `<u2`).
pub(super) fn npy_header(descr: &str, shape: &[usize]) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(|n| n.to_string()).collect();
    let shape_txt = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut dict =
        format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape_txt}, }}");
    // 6 magic + 2 version + 2 length bytes, then the dictionary and a final '\n'.
    let unpadded = 10 + dict.len() + 1;
    let pad = (64 - unpadded % 64) % 64;
    dict.push_str(&" ".repeat(pad));
    dict.push('\n');
    let mut out = Vec::with_capacity(10 + dict.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&[1, 0]);
    out.extend_from_slice(&(dict.len() as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out
}

/// Writes a cube as `<f4` `[band, row, col]` `.npy` plus its `<stem>.json` sidecar,
/// both atomically.
pub fn write(path: &Path, cube: &Cube) -> Result<()> {
    cube.check(&path.display().to_string())?;
    let meta = &cube.meta;
    let (b, r, c) = cube.data.dim();
    let side = sidecar_path(path);
    if side == path {
        return Err(Error::format(
            path,
            "an .npy cube needs a file name ending in .npy (the sidecar is <stem>.json)",
        ));
    }
    let sc = Sidecar {
        wavelength_um: meta.wavelength_um.clone(),
        fwhm_um: meta.fwhm_um.clone(),
        units: Some(meta.units.as_str().to_string()),
        fov_deg: meta.geometry.map(|g| [g.fov_x_deg, g.fov_y_deg]),
        ifov_rad: None,
        range_m: meta.geometry.and_then(|g| g.range_m),
        frame_time_s: None,
        extra: BTreeMap::new(),
    };
    let mut json = serde_json::to_string_pretty(&sc)
        .map_err(|e| Error::format(&side, format!("cannot encode the sidecar: {e}")))?;
    json.push('\n');

    atomic_write(path, |w| {
        write_all(w, &npy_header_f32(&[b, r, c]), path)?;
        let mut buf = Vec::with_capacity(r * c * 4);
        for plane in cube.data.outer_iter() {
            buf.clear();
            for v in plane.iter() {
                buf.extend_from_slice(&v.to_le_bytes());
            }
            write_all(w, &buf, path)?;
        }
        Ok(())
    })?;
    let res = atomic_write(&side, |w| write_all(w, json.as_bytes(), &side));
    if res.is_err() {
        // An array without its metadata cannot be read back; do not leave it behind.
        let _ = std::fs::remove_file(path);
    }
    res
}

/// Reads a `[frame, row, col]` stack (`<u2`, `<i2`, `<f4`, `<f8` or big-endian, C order;
/// e.g. a run's `dn_stack.npy`) as f32 values: a regular file only, the header parsed by
/// the bounded parser and the size checked against the memory budget and the file length
/// before anything is allocated.
///
/// Errors: not a 3-D C-order array of a supported type, a truncated file, a stack beyond
/// the memory budget.
pub fn read_stack(path: &Path) -> Result<ndarray::Array3<f32>> {
    let mut file = crate::input::open_regular(path)?;
    let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let header = read_header(path, &mut file, len)?;
    let [frames, rows, cols] = header.shape[..] else {
        return Err(Error::format(
            path,
            format!(
                "a stack of frames needs 3 dimensions [frame, row, col], found {}",
                header.shape.len()
            ),
        ));
    };
    let dims = [
        ("frames", frames as u64),
        ("rows", rows as u64),
        ("cols", cols as u64),
    ];
    crate::limits::check_alloc(&format!("reading {}", path.display()), &dims, 4)?;
    let count = frames * rows * cols;
    let bytes = (count as u64).saturating_mul(header.ty.size() as u64);
    super::binary::check_size(
        path,
        len.saturating_sub(header.data_start),
        bytes,
        "[frame, row, col]",
    )?;
    let mut out = Vec::new();
    super::binary::read_samples(
        &mut file,
        path,
        header.data_start,
        count,
        header.ty,
        header.big_endian,
        None,
        &mut out,
    )?;
    ndarray::Array3::from_shape_vec((frames, rows, cols), out)
        .map_err(|e| Error::format(path, e.to_string()))
}

// The `[frame, row, col]` stack writers live in `npy_stack` (this file holds the reader).
pub use super::npy_stack::{write_f32_stack, write_u16_stack, StackWriter};
