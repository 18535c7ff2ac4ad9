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
//! | `wavelength_um` | f64 array | yes | band centres, µm, strictly increasing |
//! | `units` | string | yes | [`RadianceUnits::as_str`] (`"W m-2 sr-1 um-1"` or `"W m-2 sr-1"`) |
//! | `fwhm_um` | f64 array | no | band full widths at half maximum, µm |
//! | `fov_deg` | f64 `[h, v]` | no | full field of view, degrees |
//! | `range_m` | f64 | no | range to the scene, m (only with `fov_deg`) |
//! | `frame_time_s` | f64 | no (`/frames` only) | time between frames, s |
//!
//! Datasets are stored contiguously, so [`read_band`](super::CubeReader::read_band) reads one band with a
//! hyperslab selection: memory does not grow with the number of bands. Other numeric
//! storage types (f64, integers) are converted to f32 by the HDF5 library on reading.
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
use ndarray::{s, Array2, ArrayView2, ArrayView4, Axis};

use crate::error::{Error, Result};
use crate::scene::{check_radiance_plane, Cube, CubeMeta, Geometry, RadianceUnits};

/// Name of the single-cube dataset.
pub const RADIANCE: &str = "radiance";
/// Name of the sequence dataset.
pub const FRAMES: &str = "frames";

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
/// at a time.
pub struct Hdf5Reader {
    path: PathBuf,
    meta: CubeMeta,
    dataset: Dataset,
    sequence: bool,
    frames: usize,
    frame_time_s: Option<f64>,
    warnings: Vec<String>,
}

impl Hdf5Reader {
    /// Opens a file and reads its metadata (no pixel data): `/frames` if present, else
    /// `/radiance`.
    pub fn open(path: &Path) -> Result<Self> {
        // Regular files only, checked without blocking: the HDF5 library's own open would
        // block forever on a FIFO.
        drop(crate::io::input::open_regular(path)?);
        let file = File::open(path).ctx(path, "not a readable HDF5 file")?;
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
                "the file has both `/{FRAMES}` and `/{RADIANCE}`; read the sequence `/{FRAMES}` and ignored `/{RADIANCE}`"
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
        let wavelength_um = read_f64s(path, name, loc, "wavelength_um")?.ok_or_else(|| {
            missing(
                path,
                name,
                "wavelength_um",
                "band centre wavelengths, µm, one per band",
            )
        })?;
        let units_text = read_string(path, name, loc, "units")?.ok_or_else(|| {
            missing(
                path,
                name,
                "units",
                &format!(
                    "`{}` or `{}`",
                    RadianceUnits::SpectralPerUm.as_str(),
                    RadianceUnits::BandIntegrated.as_str()
                ),
            )
        })?;
        let units = RadianceUnits::parse(&units_text).ok_or_else(|| {
            Error::format(
                path,
                format!(
                    "attribute `units` of `/{name}` = `{units_text}`: expected `{}` or `{}`",
                    RadianceUnits::SpectralPerUm.as_str(),
                    RadianceUnits::BandIntegrated.as_str()
                ),
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
        let fov = read_f64s(path, name, loc, "fov_deg")?;
        let range_m = read_scalar(path, name, loc, "range_m")?;
        let frame_time_s = if sequence {
            read_scalar(path, name, loc, "frame_time_s")?
        } else {
            None
        };
        if let Some(t) = frame_time_s {
            if !(t.is_finite() && t > 0.0) {
                return Err(Error::format(
                    path,
                    format!("attribute `frame_time_s` of `/{name}` = {t}: expected a time > 0 s"),
                ));
            }
        }
        let geometry = match fov {
            Some(f) if f.len() == 2 => Some(Geometry {
                fov_x_deg: f[0],
                fov_y_deg: f[1],
                range_m,
            }),
            Some(f) => {
                return Err(Error::format(
                    path,
                    format!(
                        "attribute `fov_deg` of `/{name}` has {} values; expected 2 [horizontal, vertical] degrees",
                        f.len()
                    ),
                ))
            }
            None => {
                if range_m.is_some() {
                    warnings.push(format!(
                        "attribute `range_m` of `/{name}` ignored: without `fov_deg` the file has no geometry"
                    ));
                }
                None
            }
        };
        let meta = CubeMeta {
            wavelength_um,
            fwhm_um,
            units,
            geometry,
            rows,
            cols,
        };
        meta.validate(&path.display().to_string())?;
        if frames == 0 {
            return Err(Error::format(
                path,
                format!("dataset `/{FRAMES}` has no frames"),
            ));
        }
        Ok(Hdf5Reader {
            path: path.to_path_buf(),
            meta,
            dataset,
            sequence,
            frames,
            frame_time_s,
            warnings,
        })
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
        if frame >= self.frames {
            return Err(Error::param(
                "frame",
                frame,
                format!(
                    "an index below {} (frames in {})",
                    self.frames,
                    self.path.display()
                ),
            ));
        }
        let bands = self.meta.bands();
        if band >= bands {
            return Err(Error::param(
                "band",
                band,
                format!("an index below {bands} (bands in {})", self.path.display()),
            ));
        }
        let plane: Array2<f32> = if self.sequence {
            self.dataset.read_slice_2d(s![frame, band, .., ..])
        } else {
            self.dataset.read_slice_2d(s![band, .., ..])
        }
        .ctx(
            &self.path,
            format!("cannot read frame {frame}, band {band}"),
        )?;
        check_radiance_plane(
            &self.path.display().to_string(),
            band,
            self.meta.wavelength_um[band],
            plane.view(),
        )?;
        Ok(plane)
    }

    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
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
            let file = File::create(tmp).ctx(tmp, "cannot create HDF5 file")?;
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
            let file = File::create(tmp).ctx(tmp, "cannot create HDF5 file")?;
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

/// Writes one HDF5 file holding named 2-D products (e.g. `"dn"` u16, `"electrons_mean"`,
/// `"radiance"`, `"temperature"` f32) as root-level datasets with string attributes per
/// product, and string attributes on the file, atomically. Values are written as given
/// (NaN is allowed, e.g. for a temperature that could not be inverted).
pub fn write_bundle(
    path: &Path,
    products: &[BundleItem<'_>],
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
            let file = File::create(tmp).ctx(tmp, "cannot create HDF5 file")?;
            for p in products {
                let what = format!("cannot write dataset `/{}`", p.name);
                let ds = match &p.data {
                    BundleData::U16(a) => {
                        let a = a.as_standard_layout();
                        file.new_dataset_builder()
                            .with_data(a.view())
                            .create(p.name)
                    }
                    BundleData::F32(a) => {
                        let a = a.as_standard_layout();
                        file.new_dataset_builder()
                            .with_data(a.view())
                            .create(p.name)
                    }
                }
                .ctx(tmp, what)?;
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
