//! HDF5 cubes, sequences and product bundles (cargo feature `hdf5`, system libhdf5).
//!
//! # Cube layout
//!
//! | object | shape / type | content |
//! |---|---|---|
//! | `/radiance` | `[band, row, col]`, f32 | one cube |
//! | `/frames` | `[frame, band, row, col]`, f32 | a sequence (read in preference to `/radiance`) |
//!
//! Attributes on the dataset:
//!
//! | attribute | type | required | meaning |
//! |---|---|---|---|
//! | `wavelength_um` | f64 array | yes | band centres, µm, strictly increasing or strictly decreasing |
//! | `units` (or `radiance_units`) | string | yes, unless `--radiance-units` is given | radiance units in any spelling of [`crate::scene::units`]: `W m-2 sr-1 um-1`, `W/(m2 sr nm)`, `uW cm-2 sr-1 nm-1`, `W m-2 sr-1` (band-integrated)… |
//! | `fwhm_um` | f64 array | no | band full widths at half maximum, µm |
//! | `fov_deg` | f64 `[h, v]` | no | full field of view, degrees |
//! | `ifov_rad` | f64 `[x, y]` | no | angular pixel spacing, rad (instead of `fov_deg`) |
//! | `fov` | f64 `[h, v]` or `h` | no | full field of view, degrees, as other tools name it (used when neither `fov_deg` nor `ifov_rad` is present) |
//! | `range_m` | f64 | no | range to the scene, m (only with a field of view) |
//! | `frame_time_s` | f64 | no (`/frames` only) | time between frames, s |
//!
//! The metadata goes through the path every reader shares ([`super::metadata`]): the unit
//! statements are parsed by the one unit parser and values are converted to eoir's units
//! as they are read (`--radiance-units` overrides the file); the field of view follows
//! the documented precedence (`--fov-deg` always wins, then `fov_deg` / `ifov_rad`, then
//! `fov`); a wavelength list in decreasing order is handed out in increasing order. Any
//! other attribute is listed in the warnings and otherwise ignored. Unlike the ENVI and
//! NPY readers, which assume spectral radiance per µm with a warning, the HDF5 reader
//! requires a unit statement (or the override): the layout is eoir's own, and a file
//! without one was not written to it.
//!
//! [`read_band`](super::CubeReader::read_band) reads one band with a hyperslab selection,
//! and [`read_bands`](super::CubeReader::read_bands) reads each run of adjacent stored
//! bands with one hyperslab (one pass over a chunked, compressed dataset instead of one
//! per band): memory does not grow with the number of bands. Other numeric storage types
//! (f64, integers) are converted to f32 by the HDF5 library on reading.
//!
//! # Bundles
//!
//! [`write_bundle`] writes named 2-D products (u16 DN, f32 electrons, radiance,
//! temperature…) into one file, each a root-level dataset with string attributes, plus
//! string attributes on the file.

use std::fmt::Display;
use std::path::{Path, PathBuf};

use hdf5_metno::types::{FixedAscii, FixedUnicode, TypeDescriptor, VarLenAscii, VarLenUnicode};
use hdf5_metno::{Dataset, File, Location};
use ndarray::{s, Array2, Array3, ArrayView2, ArrayView4, Axis};

use crate::error::{Error, Result};
use crate::scene::{check_radiance_plane, Cube, CubeMeta};

use super::metadata::{order_bands, resolve_geometry, resolve_units, BandOrder, ReadOptions};

/// Name of the single-cube dataset.
pub const RADIANCE: &str = "radiance";
/// Name of the sequence dataset.
pub const FRAMES: &str = "frames";

/// Attributes of the cube layout (anything else is a warning).
const KNOWN_ATTRIBUTES: [&str; 9] = [
    "wavelength_um",
    "units",
    "radiance_units",
    "fwhm_um",
    "fov_deg",
    "ifov_rad",
    "fov",
    "range_m",
    "frame_time_s",
];

/// Longest fixed-length string attribute read (longer ones are truncated by HDF5).
const MAX_FIXED_STRING: usize = 4096;

/// Attaches the file and what was being done to an HDF5 error.
trait Context<T> {
    fn ctx(self, path: &Path, what: impl Display) -> Result<T>;
}

impl<T> Context<T> for hdf5_metno::Result<T> {
    fn ctx(self, path: &Path, what: impl Display) -> Result<T> {
        self.map_err(|e| Error::format(path, format!("{what}: {e}")))
    }
}

/// Reads cubes and sequences in the layout of the [module documentation](self), one band
/// (or one run of adjacent bands) at a time.
pub struct Hdf5Reader {
    path: PathBuf,
    meta: CubeMeta,
    dataset: Dataset,
    sequence: bool,
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
}

impl Hdf5Reader {
    /// Opens a file and reads its metadata (no pixel data): `/frames` if present, else
    /// `/radiance`.
    pub fn open(path: &Path) -> Result<Self> {
        Self::open_with(path, &ReadOptions::default())
    }

    /// Like [`open`](Self::open), with reading options (a radiance-unit override).
    pub fn open_with(path: &Path, options: &ReadOptions) -> Result<Self> {
        // Refuses FIFOs, devices and directories without blocking, before libhdf5 opens it.
        drop(crate::io::input::open_regular(path)?);
        let file = File::with_options()
            .with_fapl(|p| p.file_locking(false))
            .open(path)
            .ctx(path, "not a readable HDF5 file")?;
        close_on_exec(path);
        let mut warnings = Vec::new();
        let sequence = file.link_exists(FRAMES);
        if !sequence && !file.link_exists(RADIANCE) {
            return Err(Error::format(
                path,
                format!("no `/{RADIANCE}` [band, row, col] or `/{FRAMES}` [frame, band, row, col] dataset"),
            ));
        }
        if sequence && file.link_exists(RADIANCE) {
            warnings.push(format!(
                "{}: the file has both `/{FRAMES}` and `/{RADIANCE}`; read the sequence `/{FRAMES}` and ignored `/{RADIANCE}`",
                path.display()
            ));
        }
        let name = if sequence { FRAMES } else { RADIANCE };
        let dataset = file
            .dataset(name)
            .ctx(path, format!("cannot open dataset `/{name}`"))?;
        let shape = dataset.shape();
        let expected_ndim = if sequence { 4 } else { 3 };
        if shape.len() != expected_ndim {
            return Err(Error::format(
                path,
                format!(
                    "dataset `/{name}` has shape {shape:?}; expected {}",
                    if sequence {
                        "4 dimensions [frame, band, row, col]"
                    } else {
                        "3 dimensions [band, row, col]"
                    }
                ),
            ));
        }
        if shape.contains(&0) {
            return Err(Error::format(
                path,
                format!("dataset `/{name}` has shape {shape:?}, with a zero-length dimension"),
            ));
        }
        let dtype = dataset
            .dtype()
            .and_then(|t| t.to_descriptor())
            .ctx(path, format!("cannot read the type of `/{name}`"))?;
        if !matches!(
            dtype,
            TypeDescriptor::Float(_) | TypeDescriptor::Integer(_) | TypeDescriptor::Unsigned(_)
        ) {
            return Err(Error::format(
                path,
                format!("dataset `/{name}` holds {dtype}; expected numbers (f32)"),
            ));
        }
        let frames = if sequence { shape[0] } else { 1 };
        let (bands, rows, cols) = (
            shape[expected_ndim - 3],
            shape[expected_ndim - 2],
            shape[expected_ndim - 1],
        );
        // One band plane (f32) and its read buffer, before any plane is read.
        crate::limits::check_alloc(
            &format!("reading {}", path.display()),
            &[("rows", rows as u64), ("cols", cols as u64)],
            8,
        )?;

        let loc: &Location = &dataset;
        for attr in loc.attr_names().ctx(path, "cannot list attributes")? {
            if !KNOWN_ATTRIBUTES.contains(&attr.as_str()) {
                warnings.push(format!(
                    "{}: attribute `{}` of `/{name}` is not an eoir key and was ignored",
                    path.display(),
                    crate::error::escape_token(&attr)
                ));
            }
        }
        let wavelength_um = read_f64s(path, name, loc, "wavelength_um")?.ok_or_else(|| {
            missing(
                path,
                name,
                "wavelength_um",
                "band centre wavelengths, µm, one per band",
            )
        })?;
        if wavelength_um.len() != bands {
            return Err(Error::format(
                path,
                format!(
                    "attribute `wavelength_um` of `/{name}` has {} values but the dataset has {bands} bands",
                    wavelength_um.len()
                ),
            ));
        }
        let fwhm_um = read_f64s(path, name, loc, "fwhm_um")?;
        if let Some(f) = &fwhm_um {
            if f.len() != bands {
                return Err(Error::format(
                    path,
                    format!(
                        "attribute `fwhm_um` of `/{name}` has {} values but the dataset has {bands} bands",
                        f.len()
                    ),
                ));
            }
        }

        let mut statements = Vec::new();
        for key in ["units", "radiance_units"] {
            if let Some(u) = read_string(path, name, loc, key)? {
                statements.push((format!("attribute `{key}`"), u));
            }
        }
        let resolved =
            resolve_units(path, &statements, options, &mut warnings)?.ok_or_else(|| {
                missing(
                    path,
                    name,
                    "units",
                    &format!(
                        "the radiance units, e.g. {}; or pass --radiance-units",
                        crate::scene::units::EXAMPLES
                    ),
                )
            })?;

        let frame_time_s = read_scalar(path, name, loc, "frame_time_s")?;
        match frame_time_s {
            Some(t) if !sequence => warnings.push(format!(
                "{}: attribute `frame_time_s` = {t} of `/{name}` ignored: a single cube has no frame time",
                path.display()
            )),
            Some(t) if !(t.is_finite() && t > 0.0) => {
                return Err(Error::format(
                    path,
                    format!("attribute `frame_time_s` of `/{name}` = {t}: expected a time > 0 s"),
                ))
            }
            _ => {}
        }
        let frame_time_s = frame_time_s.filter(|_| sequence);

        let pair = |key: &str| -> Result<Option<[f64; 2]>> {
            match read_f64s(path, name, loc, key)? {
                None => Ok(None),
                Some(v) if v.len() == 2 => Ok(Some([v[0], v[1]])),
                Some(v) => Err(Error::format(
                    path,
                    format!(
                        "attribute `{key}` of `/{name}` has {} values; expected 2 [horizontal, vertical]",
                        v.len()
                    ),
                )),
            }
        };
        let own_fov = pair("fov_deg")?;
        let own_ifov = pair("ifov_rad")?;
        let mut common = Vec::new();
        if let Some(v) = read_f64s(path, name, loc, "fov")? {
            common.push(("fov".to_string(), v));
        }
        let range_m = read_scalar(path, name, loc, "range_m")?;
        let geometry = resolve_geometry(
            path,
            [
                "attribute `fov_deg`",
                "attribute `ifov_rad`",
                "attribute `range_m`",
            ],
            own_fov,
            own_ifov,
            &common,
            range_m,
            rows,
            cols,
            &mut warnings,
        )?;
        let BandOrder {
            wavelength_um,
            fwhm_um,
            band_map,
            reversed,
        } = order_bands(path, wavelength_um, fwhm_um)?;
        if reversed {
            warnings.push(format!(
                "{}: wavelengths are listed in decreasing order; bands are handed out in increasing wavelength (band 0 = stored band {})",
                path.display(),
                bands - 1
            ));
        }
        let meta = CubeMeta {
            wavelength_um,
            fwhm_um,
            units: resolved.scale.units,
            geometry,
            rows,
            cols,
        };
        meta.validate(&path.display().to_string())?;
        Ok(Hdf5Reader {
            path: path.to_path_buf(),
            meta,
            dataset,
            sequence,
            frames,
            frame_time_s,
            band_map,
            to_eoir: resolved.scale.to_eoir,
            units_source: resolved.source,
            warnings,
            options: options.clone(),
        })
    }

    /// Checks a frame and band index against the file.
    fn check_index(&self, frame: usize, band: usize) -> Result<()> {
        if frame >= self.frames {
            return Err(Error::OutOfRange(format!(
                "{}: frame {frame} requested but the file has frames 0..{}",
                self.path.display(),
                self.frames
            )));
        }
        let bands = self.meta.bands();
        if band >= bands {
            return Err(Error::OutOfRange(format!(
                "{}: band {band} requested but the cube has bands 0..{bands}",
                self.path.display()
            )));
        }
        Ok(())
    }

    /// Reads stored bands `first..first + n` of `frame` with one hyperslab selection.
    fn read_stored(&self, frame: usize, first: usize, n: usize) -> Result<Array3<f32>> {
        let what = || {
            if n == 1 {
                format!("cannot read frame {frame}, band {first}")
            } else {
                format!(
                    "cannot read frame {frame}, stored bands {first}..{}",
                    first + n
                )
            }
        };
        crate::limits::check_alloc(
            &format!("reading {n} bands of {}", self.path.display()),
            &[
                ("bands", n as u64),
                ("rows", self.meta.rows as u64),
                ("cols", self.meta.cols as u64),
            ],
            4,
        )?;
        if self.sequence {
            self.dataset
                .read_slice::<f32, _, ndarray::Ix3>(s![frame, first..first + n, .., ..])
        } else {
            self.dataset
                .read_slice::<f32, _, ndarray::Ix3>(s![first..first + n, .., ..])
        }
        .ctx(&self.path, what())
    }

    /// Scales a stored plane to eoir's units and checks it (output band `band`).
    fn finish_plane(&self, band: usize, mut plane: Array2<f32>) -> Result<Array2<f32>> {
        if self.to_eoir != 1.0 {
            let k = self.to_eoir;
            plane.mapv_inplace(|v| (v as f64 * k) as f32);
        }
        check_radiance_plane(
            &self.path.display().to_string(),
            band,
            self.meta.wavelength_um[band],
            plane.view(),
        )?;
        Ok(plane)
    }
}

impl super::CubeReader for Hdf5Reader {
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
        self.check_index(frame, band)?;
        let stored = self.read_stored(frame, self.band_map[band], 1)?;
        let plane = stored.index_axis_move(Axis(0), 0);
        self.finish_plane(band, plane)
    }

    /// Reads each run of requested bands that are adjacent in the file (in either order)
    /// with one hyperslab, then hands the planes out in the order asked for.
    fn read_bands(&mut self, frame: usize, bands: &[usize]) -> Result<Vec<Array2<f32>>> {
        for &b in bands {
            self.check_index(frame, b)?;
        }
        let mut out = Vec::with_capacity(bands.len());
        let mut i = 0;
        while i < bands.len() {
            // The longest run bands[i..j] whose stored indices step by +1 or −1.
            let s0 = self.band_map[bands[i]];
            let mut j = i + 1;
            let step = bands
                .get(j)
                .map(|&b| self.band_map[b] as isize - s0 as isize)
                .filter(|d| d.abs() == 1);
            if let Some(d) = step {
                while j < bands.len()
                    && self.band_map[bands[j]] as isize == s0 as isize + d * (j - i) as isize
                {
                    j += 1;
                }
            }
            let n = j - i;
            let first = if step == Some(-1) { s0 + 1 - n } else { s0 };
            let block = self.read_stored(frame, first, n)?;
            for (k, &b) in bands[i..j].iter().enumerate() {
                // Ascending runs start at `first`, descending ones end there.
                let idx = if step == Some(-1) { n - 1 - k } else { k };
                let plane = block.index_axis(Axis(0), idx).to_owned();
                out.push(self.finish_plane(b, plane)?);
            }
            i = j;
        }
        Ok(out)
    }

    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    fn units_source(&self) -> String {
        self.units_source.clone()
    }

    /// The same file opened again by path with the same options (an own file id).
    fn reopen(&self) -> Option<Result<Box<dyn super::CubeReader + Send>>> {
        Some(Self::open_with(&self.path, &self.options).map(|r| Box::new(r) as _))
    }
}

/// The error for a required attribute that is absent.
fn missing(path: &Path, dataset: &str, attr: &str, what: &str) -> Error {
    Error::format(
        path,
        format!("dataset `/{dataset}` has no attribute `{attr}` (required: {what})"),
    )
}

/// Whether `loc` has attribute `name`.
fn has_attr(path: &Path, loc: &Location, name: &str) -> Result<bool> {
    Ok(loc
        .attr_names()
        .ctx(path, "cannot list attributes")?
        .iter()
        .any(|n| n == name))
}

/// A numeric attribute as f64 values (any shape, converted by HDF5), if present.
fn read_f64s(path: &Path, dataset: &str, loc: &Location, name: &str) -> Result<Option<Vec<f64>>> {
    if !has_attr(path, loc, name)? {
        return Ok(None);
    }
    let values = loc.attr(name).and_then(|a| a.read_raw::<f64>()).ctx(
        path,
        format!("attribute `{name}` of `/{dataset}` is not numeric"),
    )?;
    Ok(Some(values))
}

/// A numeric scalar attribute (or one-element array), if present.
fn read_scalar(path: &Path, dataset: &str, loc: &Location, name: &str) -> Result<Option<f64>> {
    match read_f64s(path, dataset, loc, name)? {
        None => Ok(None),
        Some(v) if v.len() == 1 => Ok(Some(v[0])),
        Some(v) => Err(Error::format(
            path,
            format!(
                "attribute `{name}` of `/{dataset}` has {} values; expected one",
                v.len()
            ),
        )),
    }
}

/// A string attribute (variable or fixed length, ASCII or UTF-8), if present.
fn read_string(path: &Path, dataset: &str, loc: &Location, name: &str) -> Result<Option<String>> {
    if !has_attr(path, loc, name)? {
        return Ok(None);
    }
    let what = format!("attribute `{name}` of `/{dataset}`");
    let attr = loc.attr(name).ctx(path, &what)?;
    let dtype = attr
        .dtype()
        .and_then(|t| t.to_descriptor())
        .ctx(path, &what)?;
    let s = match dtype {
        TypeDescriptor::VarLenUnicode => attr
            .read_scalar::<VarLenUnicode>()
            .map(|s| s.as_str().to_string()),
        TypeDescriptor::VarLenAscii => attr
            .read_scalar::<VarLenAscii>()
            .map(|s| s.as_str().to_string()),
        TypeDescriptor::FixedAscii(_) => attr
            .read_scalar::<FixedAscii<MAX_FIXED_STRING>>()
            .map(|s| s.as_str().to_string()),
        TypeDescriptor::FixedUnicode(_) => attr
            .read_scalar::<FixedUnicode<MAX_FIXED_STRING>>()
            .map(|s| s.as_str().to_string()),
        other => {
            return Err(Error::format(
                path,
                format!("{what} holds {other}; expected a string"),
            ))
        }
    }
    .ctx(path, &what)?;
    Ok(Some(s))
}

/// Writes a scalar UTF-8 string attribute.
fn put_string(path: &Path, loc: &Location, name: &str, value: &str) -> Result<()> {
    let v: VarLenUnicode = value.parse().map_err(|_| {
        Error::param(
            format!("HDF5 attribute `{name}`"),
            format!("{value:?}"),
            "a string without NUL characters",
        )
    })?;
    loc.new_attr::<VarLenUnicode>()
        .create(name)
        .and_then(|a| a.write_scalar(&v))
        .ctx(path, format!("cannot write attribute `{name}`"))
}

/// Writes a 1-D f64 attribute.
fn put_f64s(path: &Path, loc: &Location, name: &str, values: &[f64]) -> Result<()> {
    loc.new_attr_builder()
        .with_data(values)
        .create(name)
        .map(|_| ())
        .ctx(path, format!("cannot write attribute `{name}`"))
}

/// Writes a scalar f64 attribute.
fn put_f64(path: &Path, loc: &Location, name: &str, value: f64) -> Result<()> {
    loc.new_attr::<f64>()
        .create(name)
        .and_then(|a| a.write_scalar(&value))
        .ctx(path, format!("cannot write attribute `{name}`"))
}

/// Writes the cube attributes of the layout onto a dataset.
fn put_meta(path: &Path, loc: &Location, meta: &CubeMeta) -> Result<()> {
    put_f64s(path, loc, "wavelength_um", &meta.wavelength_um)?;
    put_string(path, loc, "units", meta.units.as_str())?;
    if let Some(f) = &meta.fwhm_um {
        put_f64s(path, loc, "fwhm_um", f)?;
    }
    if let Some(g) = &meta.geometry {
        put_f64s(path, loc, "fov_deg", &[g.fov_x_deg, g.fov_y_deg])?;
        if let Some(r) = g.range_m {
            put_f64(path, loc, "range_m", r)?;
        }
    }
    Ok(())
}

/// Makes sure the written bytes reach the disk before the file is renamed into place.
fn sync(path: &Path) -> Result<()> {
    std::fs::File::open(path)
        .and_then(|f| f.sync_all())
        .map_err(|e| Error::io(path, e))
}

/// Writes `cube` as `/radiance` with its attributes, atomically (temporary file, then
/// rename). Fails, writing nothing, if any value is NaN, infinite or negative.
pub fn write(path: &Path, cube: &Cube) -> Result<()> {
    let meta = &cube.meta;
    let source = path.display().to_string();
    cube.check(&source)?;
    for (b, plane) in cube.data.axis_iter(Axis(0)).enumerate() {
        check_radiance_plane(&source, b, meta.wavelength_um[b], plane)?;
    }
    let data = cube.data.as_standard_layout();
    super::atomic_write_path(path, |tmp| {
        {
            let file = create_file(tmp)?;
            let ds = file
                .new_dataset_builder()
                .with_data(data.view())
                .create(RADIANCE)
                .ctx(tmp, format!("cannot write dataset `/{RADIANCE}`"))?;
            put_meta(tmp, &ds, meta)?;
            file.flush().ctx(tmp, "cannot flush HDF5 file")?;
        }
        sync(tmp)
    })
}

/// Writes a sequence `[frame, band, row, col]` as `/frames` with the cube attributes of
/// `meta` and, if given, `frame_time_s` (time between frames, s), atomically. Fails,
/// writing nothing, if any value is NaN, infinite or negative.
pub fn write_frames(
    path: &Path,
    meta: &CubeMeta,
    frames: ArrayView4<f32>,
    frame_time_s: Option<f64>,
) -> Result<()> {
    let source = path.display().to_string();
    meta.validate(&source)?;
    let (n, bands, rows, cols) = frames.dim();
    if n == 0 || (bands, rows, cols) != (meta.bands(), meta.rows, meta.cols) {
        return Err(Error::param(
            "frames shape",
            format!("[{n}, {bands}, {rows}, {cols}]"),
            format!(
                "[n >= 1, {}, {}, {}] as the metadata says",
                meta.bands(),
                meta.rows,
                meta.cols
            ),
        ));
    }
    if let Some(t) = frame_time_s {
        crate::error::require_positive("frame_time_s", t)?;
    }
    for frame in frames.axis_iter(Axis(0)) {
        for (b, plane) in frame.axis_iter(Axis(0)).enumerate() {
            check_radiance_plane(&source, b, meta.wavelength_um[b], plane)?;
        }
    }
    let data = frames.as_standard_layout();
    super::atomic_write_path(path, |tmp| {
        {
            let file = create_file(tmp)?;
            let ds = file
                .new_dataset_builder()
                .with_data(data.view())
                .create(FRAMES)
                .ctx(tmp, format!("cannot write dataset `/{FRAMES}`"))?;
            put_meta(tmp, &ds, meta)?;
            if let Some(t) = frame_time_s {
                put_f64(tmp, &ds, "frame_time_s", t)?;
            }
            file.flush().ctx(tmp, "cannot flush HDF5 file")?;
        }
        sync(tmp)
    })
}

/// The pixels of one bundle product, stored in their own type.
#[derive(Debug, Clone)]
pub enum BundleData<'a> {
    /// Unsigned 16-bit values (digital numbers), stored as u16.
    U16(ArrayView2<'a, u16>),
    /// 32-bit floats (electrons, radiance, temperature…), stored as f32.
    F32(ArrayView2<'a, f32>),
}

/// One named 2-D product of a bundle with its string attributes (e.g. `units`).
#[derive(Debug, Clone)]
pub struct BundleItem<'a> {
    /// Dataset name (no `/`), unique in the bundle.
    pub name: &'a str,
    /// The values.
    pub data: BundleData<'a>,
    /// String attributes attached to the dataset.
    pub attrs: Vec<(&'a str, String)>,
}

/// Checks attribute names: non-empty, unique.
fn check_attr_names(owner: &str, attrs: &[(&str, String)]) -> Result<()> {
    for (i, (name, _)) in attrs.iter().enumerate() {
        if name.is_empty() || name.contains('\0') {
            return Err(Error::param(
                format!("{owner} attribute name"),
                format!("{name:?}"),
                "a non-empty name without NUL characters",
            ));
        }
        if attrs[..i].iter().any(|(n, _)| n == name) {
            return Err(Error::param(
                format!("{owner} attribute name"),
                name,
                "each attribute name once",
            ));
        }
    }
    Ok(())
}

/// Creates (truncates) an HDF5 file for writing without object modification times, so the
/// same content gives the same bytes (a rerun with the same seed reproduces every product
/// file exactly; HDF5 would otherwise stamp the root group with the time of writing), and
/// without HDF5's own file lock: eoir writes a temporary file and renames it (readers
/// never see a file being written), and a lock held through a descriptor that a child
/// process inherited would make the next open fail ("unable to lock file").
fn create_file(tmp: &Path) -> Result<File> {
    let file = File::with_options()
        .with_fcpl(|p| p.obj_track_times(false))
        .with_fapl(|p| p.file_locking(false))
        .create(tmp)
        .ctx(tmp, "cannot create HDF5 file")?;
    close_on_exec(tmp);
    Ok(file)
}

/// Marks the descriptors this process holds on `path` close-on-exec. libhdf5 opens files
/// without `O_CLOEXEC` and locks them with `flock`: a child process started while the file
/// is open (a program embedding eoir that spawns tools, a test harness running commands in
/// parallel) would inherit the descriptor, and with it the lock, for its whole life — and
/// the next open of the file would fail with "unable to lock file". Linux only (the
/// descriptors are found in `/proc/self/fd`); elsewhere, and on any failure, nothing
/// changes.
fn close_on_exec(path: &Path) {
    #[cfg(target_os = "linux")]
    {
        let Ok(target) = std::fs::canonicalize(path) else {
            return;
        };
        let Ok(entries) = std::fs::read_dir("/proc/self/fd") else {
            return;
        };
        for e in entries.flatten() {
            let Some(fd) = e.file_name().to_str().and_then(|n| n.parse::<i32>().ok()) else {
                continue;
            };
            if std::fs::read_link(e.path()).is_ok_and(|l| l == target) {
                // SAFETY: fcntl on a descriptor number this process holds open (a stale
                // number fails with EBADF, which is ignored); only the FD_CLOEXEC flag is set.
                unsafe {
                    let flags = libc::fcntl(fd, libc::F_GETFD);
                    if flags >= 0 {
                        libc::fcntl(fd, libc::F_SETFD, flags | libc::FD_CLOEXEC);
                    }
                }
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = path;
}

/// Writes one HDF5 file holding named 2-D products (e.g. `"dn"` u16, `"electrons_mean"`,
/// `"radiance"`, `"temperature"` f32) as root-level datasets with string attributes per
/// product, and string attributes on the file, atomically. Values are written as given
/// (NaN is allowed, e.g. for a temperature that could not be inverted).
pub fn write_bundle(
    path: &Path,
    products: &[BundleItem<'_>],
    file_attrs: &[(&str, String)],
) -> Result<()> {
    let specs: Vec<BundleSpec> = products
        .iter()
        .map(|p| BundleSpec {
            name: p.name,
            attrs: p.attrs.clone(),
        })
        .collect();
    write_bundle_core(path, &specs, |k| Ok(products[k].data.clone()), file_attrs)
}

/// The name and attributes of one product of a bundle written by [`write_bundle_with`].
#[derive(Debug, Clone)]
pub struct BundleSpec<'a> {
    /// Dataset name (no `/`), unique in the bundle.
    pub name: &'a str,
    /// String attributes attached to the dataset.
    pub attrs: Vec<(&'a str, String)>,
}

/// The pixels of one bundle product, owned (made by the caller of [`write_bundle_with`]
/// when the product is written).
#[derive(Debug, Clone)]
pub enum OwnedBundleData {
    /// Unsigned 16-bit values (digital numbers), stored as u16.
    U16(Array2<u16>),
    /// 32-bit floats, stored as f32.
    F32(Array2<f32>),
}

/// [`write_bundle`] with each product's pixels made only when it is written, by
/// `data(k)` for `specs[k]`, `k` = 0, 1, … in order: one product is held at a time (a
/// sequence's bundle, its frames read back from disk). The same bytes as [`write_bundle`]
/// of the same products.
pub fn write_bundle_with(
    path: &Path,
    specs: &[BundleSpec<'_>],
    data: impl FnMut(usize) -> Result<OwnedBundleData>,
    file_attrs: &[(&str, String)],
) -> Result<()> {
    write_bundle_core(path, specs, data, file_attrs)
}

/// Pixels a bundle dataset is made of.
trait BundlePixels {
    /// Creates dataset `name` in `file` holding the pixels.
    fn create(&self, file: &File, name: &str) -> hdf5_metno::Result<Dataset>;
}

impl BundlePixels for BundleData<'_> {
    fn create(&self, file: &File, name: &str) -> hdf5_metno::Result<Dataset> {
        match self {
            BundleData::U16(a) => {
                let a = a.as_standard_layout();
                file.new_dataset_builder().with_data(a.view()).create(name)
            }
            BundleData::F32(a) => {
                let a = a.as_standard_layout();
                file.new_dataset_builder().with_data(a.view()).create(name)
            }
        }
    }
}

impl BundlePixels for OwnedBundleData {
    fn create(&self, file: &File, name: &str) -> hdf5_metno::Result<Dataset> {
        match self {
            OwnedBundleData::U16(a) => BundleData::U16(a.view()).create(file, name),
            OwnedBundleData::F32(a) => BundleData::F32(a.view()).create(file, name),
        }
    }
}

/// The checks and the writing of [`write_bundle`] and [`write_bundle_with`].
fn write_bundle_core<D: BundlePixels>(
    path: &Path,
    products: &[BundleSpec<'_>],
    mut data: impl FnMut(usize) -> Result<D>,
    file_attrs: &[(&str, String)],
) -> Result<()> {
    if products.is_empty() {
        return Err(Error::param(
            "bundle products",
            "none",
            "at least one product",
        ));
    }
    for (i, p) in products.iter().enumerate() {
        if p.name.is_empty() || p.name.contains('/') || p.name.contains('\0') || p.name == "." {
            return Err(Error::param(
                "bundle product name",
                format!("{:?}", p.name),
                "a non-empty name without `/` or NUL",
            ));
        }
        if products[..i].iter().any(|q| q.name == p.name) {
            return Err(Error::param(
                "bundle product name",
                p.name,
                "each product name once",
            ));
        }
        check_attr_names(&format!("product `{}`", p.name), &p.attrs)?;
    }
    check_attr_names("file", file_attrs)?;

    super::atomic_write_path(path, |tmp| {
        {
            let file = create_file(tmp)?;
            for (k, p) in products.iter().enumerate() {
                let what = format!("cannot write dataset `/{}`", p.name);
                let pixels = data(k)?;
                let ds = pixels.create(&file, p.name).ctx(tmp, what)?;
                drop(pixels);
                for (name, value) in &p.attrs {
                    put_string(tmp, &ds, name, value)?;
                }
            }
            for (name, value) in file_attrs {
                put_string(tmp, &file, name, value)?;
            }
            file.flush().ctx(tmp, "cannot flush HDF5 file")?;
        }
        sync(tmp)
    })
}
