//! Reading radiance cubes and writing products, one module per file format.
//!
//! The format is chosen from the file extension:
//!
//! | extension | format | module |
//! |---|---|---|
//! | `.hdr` (or the data file next to it) | ENVI header + binary | [`envi`] |
//! | `.exr` | spectral OpenEXR (Fichet et al. 2021 layout) | [`exr`] |
//! | `.npy` | NumPy array + `.json` sidecar | [`npy`] |
//! | `.h5`, `.hdf5` | HDF5 (cargo feature `hdf5`) | `hdf5` |
//!
//! Readers implement [`CubeReader`], which hands out one band plane at a time so that a
//! caller that streams (the imaging engine) needs memory for one band, not the whole
//! cube, where the format allows it. Every plane is checked for NaN, ±Inf and negative
//! radiance as it is read. Writers go through [`atomic_write`], so a failure never leaves
//! a half-written file behind.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use ndarray::{Array2, Array3};

use crate::error::{Error, Result};
use crate::scene::{Cube, CubeMeta};

pub(crate) mod binary;
pub mod dir_lock;
pub mod envi;
pub mod exr;
#[cfg(feature = "hdf5")]
pub mod hdf5;
pub mod input;
pub mod mapped;
pub mod metadata;
pub mod npy;
pub mod npy_stack;
pub mod output;
pub mod raster;
pub(crate) mod spill;

pub use mapped::{BandPlanes, DeferredCheck};
pub use metadata::ReadOptions;

/// A source of radiance planes: one or more frames of a cube with shared metadata.
pub trait CubeReader {
    /// Wavelengths, units, size and geometry.
    fn meta(&self) -> &CubeMeta;
    /// Number of frames (1 for a single cube).
    fn frames(&self) -> usize {
        1
    }
    /// Time between frames, s, if the source says.
    fn frame_time_s(&self) -> Option<f64> {
        None
    }
    /// Reads band `band` of frame `frame` as `[row, col]`, in the cube's units, after
    /// checking every value is finite and non-negative.
    fn read_band(&mut self, frame: usize, band: usize) -> Result<Array2<f32>>;
    /// Reads several bands of frame `frame` (in the order given), each checked as
    /// [`CubeReader::read_band`] checks it. Interleaved formats (BIL, BIP) override this to
    /// read the frame in one pass instead of one strided pass per band; the default reads
    /// band by band. Callers bound memory by asking for a few bands at a time.
    fn read_bands(&mut self, frame: usize, bands: &[usize]) -> Result<Vec<Array2<f32>>> {
        bands.iter().map(|&b| self.read_band(frame, b)).collect()
    }
    /// The bands [`CubeReader::read_bands`] reads, as [`BandPlanes`]: views of a memory
    /// map of the file where the reader can serve them without a copy (ENVI
    /// band-sequential f32 or NPY `<f4` in the machine's byte order, unscaled, see
    /// [`mapped`]), else
    /// `read_bands`'s buffers (the default). Checked as `read_band` checks them. The
    /// imaging engine reads through this.
    fn read_planes(&mut self, frame: usize, bands: &[usize]) -> Result<BandPlanes> {
        self.read_bands(frame, bands).map(BandPlanes::Owned)
    }
    /// [`CubeReader::read_planes`], except that memory-mapped planes may come back
    /// **unchecked**, with the [`DeferredCheck`] the caller then owes them: it must test
    /// every value ([`crate::scene::radiance_is_physical`]) before it uses a plane and, if
    /// a value fails, return [`DeferredCheck::run`]'s error. The imaging engine does this
    /// row by row inside its row pass, where each row is in cache anyway, instead of
    /// reading every mapped plane from memory once more. `None`: already checked (the
    /// default).
    fn read_planes_deferred(
        &mut self,
        frame: usize,
        bands: &[usize],
    ) -> Result<(BandPlanes, Option<DeferredCheck>)> {
        Ok((self.read_planes(frame, bands)?, None))
    }
    /// Things the reader assumed or worked around that the user should know about
    /// (e.g. a unit the file did not state). Empty when the file was unambiguous.
    fn warnings(&self) -> Vec<String> {
        Vec::new()
    }
    /// Where the radiance units came from: an override, a statement in the file (which
    /// key), or the reader's default rule (see [`metadata`]). Recorded in the run report.
    fn units_source(&self) -> String {
        format!("eoir's units: {}", self.meta().units.as_str())
    }
    /// An independent reader of the same input, with its own file handle and position, so
    /// that several frames of a sequence can be read at once (the run images frames in
    /// parallel with one reader each, see `pipeline::frames`). Planes read through it are
    /// the planes `self` reads. `None` (the default) when the reader cannot be duplicated
    /// cheaply: the run then images one frame at a time through `self`. A file reader
    /// opens the file again by its path with the same options.
    fn reopen(&self) -> Option<Result<Box<dyn CubeReader + Send>>> {
        None
    }
    /// Gives planes returned by [`CubeReader::read_bands`] back once they are used, so
    /// the reader can fill the same buffers with the next bands (no allocation and no
    /// page faults per band). The default drops them.
    fn recycle(&mut self, planes: Vec<Array2<f32>>) {
        drop(planes);
    }
}

/// The file formats eoir reads and writes cubes in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CubeFormat {
    /// ENVI `.hdr` + raw binary.
    Envi,
    /// Spectral OpenEXR.
    Exr,
    /// NumPy `.npy` + `.json` sidecar.
    Npy,
    /// HDF5 (cargo feature `hdf5`).
    Hdf5,
}

impl CubeFormat {
    /// Picks the format from a path's extension.
    pub fn from_path(path: &Path) -> Result<Self> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase())
            .unwrap_or_default();
        match ext.as_str() {
            "hdr" | "img" | "bsq" | "bil" | "bip" | "raw" | "dat" => Ok(CubeFormat::Envi),
            "exr" => Ok(CubeFormat::Exr),
            "npy" => Ok(CubeFormat::Npy),
            "h5" | "hdf5" | "he5" => Ok(CubeFormat::Hdf5),
            _ => Err(Error::format(
                path,
                format!(
                    "unknown cube format (extension `.{ext}`); use .hdr (ENVI), .exr (spectral OpenEXR), .npy (NumPy + .json sidecar) or .h5 (HDF5)"
                ),
            )),
        }
    }
}

/// Opens a cube file for band-by-band reading; the format comes from the extension.
pub fn open(path: &Path) -> Result<Box<dyn CubeReader>> {
    open_with(path, &ReadOptions::default())
}

/// Like [`open`], with options (e.g. a radiance-unit override) that change how the
/// metadata is read.
pub fn open_with(path: &Path, options: &ReadOptions) -> Result<Box<dyn CubeReader>> {
    match CubeFormat::from_path(path)? {
        CubeFormat::Envi => Ok(Box::new(envi::EnviReader::open_with(path, options)?)),
        CubeFormat::Exr => Ok(Box::new(exr::ExrReader::open_with(path, options)?)),
        CubeFormat::Npy => Ok(Box::new(npy::NpyReader::open_with(path, options)?)),
        #[cfg(feature = "hdf5")]
        CubeFormat::Hdf5 => Ok(Box::new(hdf5::Hdf5Reader::open_with(path, options)?)),
        #[cfg(not(feature = "hdf5"))]
        CubeFormat::Hdf5 => Err(hdf5_missing(path)),
    }
}

/// Reads frame `frame` of a cube file completely into memory.
pub fn read_cube_frame(reader: &mut dyn CubeReader, frame: usize) -> Result<Cube> {
    let meta = reader.meta().clone();
    crate::limits::check_alloc(
        "reading the whole cube into memory",
        &[
            ("bands", meta.bands() as u64),
            ("rows", meta.rows as u64),
            ("cols", meta.cols as u64),
        ],
        4,
    )?;
    let mut data = Array3::<f32>::zeros((meta.bands(), meta.rows, meta.cols));
    for b in 0..meta.bands() {
        let plane = reader.read_band(frame, b)?;
        data.index_axis_mut(ndarray::Axis(0), b).assign(&plane);
    }
    Cube::new(data, meta)
}

/// Reads the first (or only) frame of a cube file into memory.
pub fn read_cube(path: &Path) -> Result<Cube> {
    let mut r = open(path)?;
    read_cube_frame(r.as_mut(), 0)
}

/// Writes a cube in the format given by the extension as one set ([`write_cube_set`]).
pub fn write_cube(path: &Path, cube: &Cube) -> Result<()> {
    write_cube_set(path, cube).map(|_| ())
}

/// Writes a cube in the format given by the extension and returns the paths written. The
/// files of the format (ENVI header and data, NPY array and JSON sidecar) are one
/// [`output::ProductSet`]: written into a staging directory beside `path` and moved into
/// place only when all of them were written and every target may be replaced, so an error
/// or SIGINT/SIGTERM leaves the earlier files exactly as they were, never a mismatched pair.
pub fn write_cube_set(path: &Path, cube: &Cube) -> Result<Vec<PathBuf>> {
    let format = CubeFormat::from_path(path)?;
    let name = path
        .file_name()
        .ok_or_else(|| Error::format(path, "names no file to write the cube to"))?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let set = output::ProductSet::begin(dir)?;
    let staged = set.staging_dir().join(name);
    match format {
        CubeFormat::Envi => envi::write(&staged, cube),
        CubeFormat::Exr => exr::write(&staged, cube),
        CubeFormat::Npy => npy::write(&staged, cube),
        #[cfg(feature = "hdf5")]
        CubeFormat::Hdf5 => hdf5::write(&staged, cube),
        #[cfg(not(feature = "hdf5"))]
        CubeFormat::Hdf5 => Err(hdf5_missing(path)),
    }
    // Name the file the user asked for, not its staging place.
    .map_err(|e| set.name_final(e))?;
    // Every file lands beside `path`: name them as the caller spelled `path`.
    Ok(set
        .commit()?
        .iter()
        .map(|p| path.with_file_name(p.file_name().unwrap_or_default()))
        .collect())
}

#[cfg(not(feature = "hdf5"))]
fn hdf5_missing(path: &Path) -> Error {
    Error::format(
        path,
        "HDF5 support is not compiled in; rebuild with `cargo build --release --features hdf5` (needs libhdf5-dev)",
    )
}

/// The temporary name a file is written under before it is renamed into place.
fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(
        ".{name}{}{}",
        output::TEMP_MARKER,
        std::process::id()
    ))
}

/// Writes a file atomically: `write` fills a temporary file in the same directory, which
/// is synced and renamed over `path` only if `write` succeeds; otherwise it is removed and
/// `path` is untouched. `path` must be absent or a regular file (see
/// [`output::check_output_target`]); the temporary file is removed on SIGINT/SIGTERM
/// once [`output::install_signal_handler`] ran.
pub fn atomic_write<F>(path: &Path, write: F) -> Result<()>
where
    F: FnOnce(&mut BufWriter<File>) -> Result<()>,
{
    let mut file = AtomicFile::create(path)?;
    write(file.writer())?;
    file.commit()
}

/// A file written atomically over several calls (a stack that grows frame by frame): the
/// [`atomic_write`] rules, with the writer kept between calls. [`AtomicFile::commit`]
/// syncs it and renames it into place; dropped uncommitted (an error on the way), the
/// temporary file is removed and `path` is untouched.
#[derive(Debug)]
pub struct AtomicFile {
    path: PathBuf,
    tmp: PathBuf,
    writer: Option<BufWriter<File>>,
}

impl AtomicFile {
    /// Creates the temporary file for `path` (absent or a regular file).
    pub fn create(path: &Path) -> Result<Self> {
        output::check_output_target(path)?;
        let tmp = temp_path(path);
        output::register_cleanup(&tmp);
        let mut this = AtomicFile {
            path: path.to_path_buf(),
            tmp,
            writer: None,
        };
        // Readable too: a writer may fix up what it wrote (e.g. the EXR header order).
        // Errors name the target the user gave, not the temporary file beside it.
        let file = File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&this.tmp)
            .map_err(|e| Error::io(path, e))?;
        this.writer = Some(BufWriter::new(file));
        Ok(this)
    }

    /// The target path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The writer of the temporary file.
    pub fn writer(&mut self) -> &mut BufWriter<File> {
        self.writer
            .as_mut()
            .expect("an AtomicFile has its writer until commit consumes it")
    }

    /// Flushes, syncs and renames the file into place.
    pub fn commit(mut self) -> Result<()> {
        let path = self.path.clone();
        let w = self
            .writer
            .take()
            .expect("an AtomicFile has its writer until commit consumes it");
        let file = w
            .into_inner()
            .map_err(|e| Error::io(&path, e.into_error()))?;
        file.sync_all().map_err(|e| Error::io(&path, e))?;
        std::fs::rename(&self.tmp, &path).map_err(|e| Error::io(&path, e))?;
        output::unregister_cleanup(&self.tmp);
        // Renamed: nothing for Drop to remove.
        self.tmp = PathBuf::new();
        Ok(())
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if !self.tmp.as_os_str().is_empty() {
            drop(self.writer.take());
            let _ = std::fs::remove_file(&self.tmp);
            output::unregister_cleanup(&self.tmp);
        }
    }
}

/// Like [`atomic_write`] for libraries that want a path rather than a writer: `write` is
/// given the temporary path to create.
pub fn atomic_write_path<F>(path: &Path, write: F) -> Result<()>
where
    F: FnOnce(&Path) -> Result<()>,
{
    output::check_output_target(path)?;
    let tmp = temp_path(path);
    output::register_cleanup(&tmp);
    let result =
        write(&tmp).and_then(|_| std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e)));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    output::unregister_cleanup(&tmp);
    result
}

/// Writes all of `bytes` to `w`, mapping errors to `path`.
pub fn write_all(w: &mut impl Write, bytes: &[u8], path: &Path) -> Result<()> {
    w.write_all(bytes).map_err(|e| Error::io(path, e))
}

/// A cube already in memory, served band by band (for library users who build cubes in
/// code, and for tests). Planes are checked like a file's. Clones (and
/// [`CubeReader::reopen`]) share the frames.
#[derive(Debug, Clone)]
pub struct MemoryCube {
    frames: std::sync::Arc<Vec<Cube>>,
    frame_time_s: Option<f64>,
}

impl MemoryCube {
    /// One frame.
    pub fn new(cube: Cube) -> Self {
        MemoryCube {
            frames: std::sync::Arc::new(vec![cube]),
            frame_time_s: None,
        }
    }

    /// A sequence of frames sharing wavelength grid, size and geometry.
    pub fn sequence(frames: Vec<Cube>, frame_time_s: Option<f64>) -> Result<Self> {
        let first = frames
            .first()
            .ok_or_else(|| Error::param("sequence", "0 frames", "at least one frame"))?;
        if let Some((i, _)) = frames
            .iter()
            .enumerate()
            .find(|(_, f)| f.meta != first.meta)
        {
            return Err(Error::param(
                "sequence",
                format!("frame {i}"),
                "the same wavelengths, size, units and geometry as frame 0",
            ));
        }
        Ok(MemoryCube {
            frames: std::sync::Arc::new(frames),
            frame_time_s,
        })
    }
}

impl CubeReader for MemoryCube {
    fn meta(&self) -> &CubeMeta {
        &self.frames[0].meta
    }
    fn frames(&self) -> usize {
        self.frames.len()
    }
    fn frame_time_s(&self) -> Option<f64> {
        self.frame_time_s
    }
    fn reopen(&self) -> Option<Result<Box<dyn CubeReader + Send>>> {
        Some(Ok(Box::new(self.clone())))
    }
    fn read_band(&mut self, frame: usize, band: usize) -> Result<Array2<f32>> {
        let cube = self.frames.get(frame).ok_or_else(|| {
            Error::param("frame", frame, format!("< {} frames", self.frames.len()))
        })?;
        if band >= cube.meta.bands() {
            return Err(Error::param(
                "band",
                band,
                format!("< {} bands", cube.meta.bands()),
            ));
        }
        let plane = cube.data.index_axis(ndarray::Axis(0), band);
        crate::scene::check_radiance_plane(
            "memory cube",
            band,
            cube.meta.wavelength_um[band],
            plane,
        )?;
        Ok(plane.to_owned())
    }
}
