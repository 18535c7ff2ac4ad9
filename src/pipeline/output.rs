//! Products on disk, frame by frame: [`ProductWriter`] writes each frame's files as the
//! frame arrives (it is the [`FrameConsumer`] `eoir run` streams a run into) and the
//! products of the whole run at the end; [`RunOutput::write`] writes a run held in memory
//! through the same writer, so both give the same bytes.
//!
//! What a sequence's products need of every frame, and how the writer gets it without
//! holding the frames:
//! - `dn_stack.npy`: the header states the frame count known at the start, each frame is
//!   appended as it arrives ([`crate::io::npy::StackWriter`]).
//! - `preview.png` (animated): one stretch over all frames, the 0.5 and 99.5 percentiles
//!   of every DN of the sequence. The writer counts the DN values of each frame in a
//!   65 536-bin histogram (the DN are 16-bit integers, so the percentiles read from it are
//!   exactly those of the sorted values) and at the end reads each frame's `dn.tiff` back,
//!   one at a time, to draw its preview frame.
//! - `products.h5` (feature `hdf5`): built at the end from the frames' TIFF files, read
//!   back one at a time, in the order the bundle has always held them.
//! - `report.json`, `report.html`: statistics of frame 0 only (kept by the run).

use std::path::{Path, PathBuf};

use ndarray::{Array2, ArrayView2};

use crate::error::{Error, Result};
use crate::io::npy::StackWriter;
use crate::io::raster;

use super::{FrameConsumer, FrameProducts, RunOutput, RunSummary};

/// Milliseconds between the frames of the animated preview.
const PREVIEW_DELAY_MS: u16 = 100;

/// Lower and upper percentiles (as fractions) of the preview's common stretch.
const PREVIEW_STRETCH: (f64, f64) = (0.005, 0.995);

/// Counts of every 16-bit DN value over the frames seen so far.
#[derive(Debug, Clone)]
struct DnHistogram {
    counts: Vec<u64>,
    total: u64,
}

impl DnHistogram {
    fn new() -> Self {
        DnHistogram {
            counts: vec![0; 1 << 16],
            total: 0,
        }
    }

    fn add(&mut self, dn: ArrayView2<u16>) {
        for &v in dn.iter() {
            self.counts[usize::from(v)] += 1;
        }
        self.total += dn.len() as u64;
    }

    /// The `k`-th smallest value counted (0-based), as sorting them all would give.
    fn kth(&self, k: u64) -> u16 {
        let mut seen = 0u64;
        for (v, &c) in self.counts.iter().enumerate() {
            seen += c;
            if seen > k {
                return v as u16;
            }
        }
        u16::MAX
    }

    /// The preview's stretch (black, span): the values at ranks ⌊(N − 1)·q⌋ of the N
    /// values counted for the two [`PREVIEW_STRETCH`] fractions q, the span at least 1 DN.
    fn stretch(&self) -> (f64, f64) {
        let pick = |q: f64| self.kth(((self.total.saturating_sub(1)) as f64 * q) as u64) as f64;
        let (lo, hi) = (pick(PREVIEW_STRETCH.0), pick(PREVIEW_STRETCH.1));
        (lo, (hi - lo).max(1.0))
    }
}

/// A DN frame as 8-bit with the preview's stretch `(lo, span)`.
fn preview_frame(dn: ArrayView2<u16>, (lo, span): (f64, f64)) -> Array2<u8> {
    dn.mapv(|v| ((v as f64 - lo) / span * 255.0).round().clamp(0.0, 255.0) as u8)
}

impl RunOutput {
    /// The DN frames as 8-bit images with one common stretch (0.5–99.5 percentiles over
    /// all frames), for the animated preview of a sequence.
    pub fn preview_frames(&self) -> Vec<Array2<u8>> {
        let mut histogram = DnHistogram::new();
        for f in &self.frames {
            histogram.add(f.dn.view());
        }
        let stretch = histogram.stretch();
        self.frames
            .iter()
            .map(|f| preview_frame(f.dn.view(), stretch))
            .collect()
    }

    /// Writes the products into `dir` (created if needed), each file atomically:
    /// `dn.tiff` (u16), `dn.png` (8-bit display, [`crate::display::dn_display`]), `electrons_mean.tiff` and
    /// `electrons_mean.exr` (f32), `config.toml` (the resolved sensor), `instance.json` (seed
    /// and sensor hash, [`crate::calibration::instance`]), `report.json`, and
    /// with the `hdf5` feature `products.h5` holding every product. A sequence writes
    /// `frame_NNNN_` prefixed DN and electron files, `dn_stack.npy` and the animated
    /// `preview.png`. Returns the paths written. The same bytes as a [`ProductWriter`]
    /// fed the run's frames as they were exposed.
    pub fn write(&self, dir: &Path) -> Result<Vec<PathBuf>> {
        let summary = self.summary()?;
        let mut writer = ProductWriter::new(dir)?;
        writer.start(self.frames.len())?;
        for (i, f) in self.frames.iter().enumerate() {
            writer.write_frame(i, f)?;
        }
        writer.finish(&summary)
    }
}

/// Writes a run's products into a directory as the frames arrive: each frame's files at
/// once (and its slice of `dn_stack.npy`), the products of the whole run in
/// [`ProductWriter::finish`]. It holds no frame: its memory is one frame's encoding
/// buffers and, for a sequence, a 512 KiB DN histogram. The files are those of
/// [`RunOutput::write`], byte for byte. Used as the [`FrameConsumer`] of
/// [`super::run_streaming`]; on an error the directory holds a partial set, which the
/// caller discards (the CLI writes into a [`crate::io::output::ProductSet`]'s staging
/// directory, dropped on error).
#[derive(Debug)]
pub struct ProductWriter {
    dir: PathBuf,
    /// Frames the run will hand over (set by [`FrameConsumer::start`]).
    frames: usize,
    /// The next frame expected.
    next: usize,
    written: Vec<PathBuf>,
    /// A sequence's `dn_stack.npy`, created with the first frame (its shape).
    stack: Option<StackWriter<u16>>,
    /// A sequence's DN histogram (the preview's stretch).
    histogram: Option<DnHistogram>,
    /// Per frame: whether it had radiance and temperature (the HDF5 bundle's items).
    #[cfg_attr(not(feature = "hdf5"), allow(dead_code))]
    calibrated: Vec<(bool, bool)>,
}

impl ProductWriter {
    /// A writer into `dir` (created if needed).
    pub fn new(dir: &Path) -> Result<Self> {
        // Guarded: a signal's clean-up that removed the staging directory is not undone.
        crate::io::output::create_dir_all_guarded(dir)?;
        Ok(ProductWriter {
            dir: dir.to_path_buf(),
            frames: 0,
            next: 0,
            written: Vec::new(),
            stack: None,
            histogram: None,
            calibrated: Vec::new(),
        })
    }

    /// The file-name prefix of frame `i`'s products: none for a single frame.
    fn prefix(&self, i: usize) -> String {
        if self.frames == 1 {
            String::new()
        } else {
            format!("frame_{i:04}_")
        }
    }

    /// Writes frame `i` (the next in order) of the run: DN TIFF and PNG, mean electrons
    /// TIFF and EXR, radiance and temperature TIFF and EXR when calibrated, the colour
    /// image of a CFA sensor; for a sequence its slice of `dn_stack.npy`.
    ///
    /// Errors: a frame out of order or beyond the count [`FrameConsumer::start`] was
    /// given, I/O.
    pub fn write_frame(&mut self, i: usize, f: &FrameProducts) -> Result<()> {
        if i != self.next || i >= self.frames {
            return Err(Error::OutOfRange(format!(
                "product writer: frame {i} handed over after frame {} of {} (frames come once each, in order)",
                self.next, self.frames
            )));
        }
        let dir = self.dir.clone();
        let prefix = self.prefix(i);
        let p = dir.join(format!("{prefix}dn.tiff"));
        raster::write_tiff_u16(&p, f.dn.view())?;
        self.written.push(p);
        let p = dir.join(format!("{prefix}dn.png"));
        let (grey, _) = crate::display::dn_display(f.dn.view());
        let samples: Vec<u8> = grey.iter().copied().collect();
        let png = crate::display::encode_png(grey.ncols(), grey.nrows(), 1, &samples)?;
        crate::display::write_png_bytes(&p, &png)?;
        self.written.push(p);
        let p = dir.join(format!("{prefix}electrons_mean.tiff"));
        raster::write_tiff_f32(&p, f.electrons_mean.view())?;
        self.written.push(p);
        let p = dir.join(format!("{prefix}electrons_mean.exr"));
        raster::write_exr_f32(&p, f.electrons_mean.view(), "electrons_mean")?;
        self.written.push(p);
        for (name, img) in [("radiance", &f.radiance), ("temperature", &f.temperature)] {
            if let Some(img) = img {
                let p = dir.join(format!("{prefix}{name}.tiff"));
                raster::write_tiff_f32(&p, img.view())?;
                self.written.push(p);
                let p = dir.join(format!("{prefix}{name}.exr"));
                raster::write_exr_f32(&p, img.view(), name)?;
                self.written.push(p);
            }
        }
        if let Some(rgb) = &f.rgb {
            let p = dir.join(format!("{prefix}rgb.png"));
            raster::write_png_rgb8(&p, rgb.view())?;
            self.written.push(p);
        }
        self.calibrated
            .push((f.radiance.is_some(), f.temperature.is_some()));
        if self.frames > 1 {
            let stack = match &mut self.stack {
                Some(s) => s,
                None => {
                    let (r, c) = f.dn.dim();
                    let s = StackWriter::u16(&dir.join("dn_stack.npy"), self.frames, r, c)?;
                    self.stack.insert(s)
                }
            };
            stack.push(f.dn.view())?;
            self.histogram
                .get_or_insert_with(DnHistogram::new)
                .add(f.dn.view());
        }
        self.next += 1;
        Ok(())
    }

    /// Writes the products of the whole run once every frame was written: the HDF5
    /// bundle (feature `hdf5`), a sequence's animated preview and `dn_stack.npy`,
    /// `los.csv`, the focal plane's truth, `distortion.csv` (with `[optics.distortion]`), `config.toml`, `instance.json`, `report.json`,
    /// the pictures and `report.html`. Returns every path written, the frames' first.
    ///
    /// Errors: fewer frames written than the run has, I/O.
    pub fn finish(mut self, run: &RunSummary) -> Result<Vec<PathBuf>> {
        if self.next != run.frame_count || self.frames != run.frame_count {
            return Err(Error::OutOfRange(format!(
                "product writer: {} of the run's {} frames were written",
                self.next, run.frame_count
            )));
        }
        let dir = self.dir.clone();
        #[cfg(feature = "hdf5")]
        self.write_bundle(run)?;
        if let Some(histogram) = self.histogram.take() {
            let p = dir.join("preview.png");
            let stretch = histogram.stretch();
            let shape = run.first.dn.dim();
            raster::write_apng_gray8_with(&p, self.frames, shape, PREVIEW_DELAY_MS, |i| {
                let dn = raster::read_tiff_u16(&dir.join(format!("{}dn.tiff", self.prefix(i))))?;
                Ok(preview_frame(dn.view(), stretch))
            })?;
            self.written.push(p);
        }
        if let Some(stack) = self.stack.take() {
            stack.finish()?;
            self.written.push(dir.join("dn_stack.npy"));
        }
        if let Some(truth) = run.line_of_sight {
            let p = dir.join("los.csv");
            let text = super::motion::truth_csv(truth);
            crate::io::atomic_write(&p, |w| crate::io::write_all(w, text.as_bytes(), &p))?;
            self.written.push(p);
        }
        if let Some(truth) = run.focal_plane {
            self.written.extend(truth.write(&dir)?);
        }
        let distortion = run.sensor.optics.distortion.as_ref();
        if let Some(law) = distortion.filter(|d| !d.is_identity()) {
            let p = dir.join("distortion.csv");
            let text = crate::imaging::distortion::truth_csv(run.sensor, law)?;
            crate::io::atomic_write(&p, |w| crate::io::write_all(w, text.as_bytes(), &p))?;
            self.written.push(p);
        }
        let p = dir.join("config.toml");
        let text = run.sensor.to_toml_string()?;
        crate::io::atomic_write(&p, |w| crate::io::write_all(w, text.as_bytes(), &p))?;
        self.written.push(p);
        let instance =
            crate::calibration::instance::SensorInstance::of(run.sensor, run.report.seed)?;
        self.written.push(instance.write(&dir)?);
        let p = dir.join("report.json");
        let text = serde_json::to_string_pretty(run.report)
            .map_err(|e| Error::format(&p, e.to_string()))?;
        crate::io::atomic_write(&p, |w| crate::io::write_all(w, text.as_bytes(), &p))?;
        self.written.push(p);
        self.written.extend(super::report_html::write(run, &dir)?);
        Ok(self.written)
    }

    /// `products.h5`: every frame's radiance and temperature (when calibrated), then every
    /// frame's DN and mean electrons, each read back from the frame's TIFF file, with the
    /// sensor and the report (without what varies from one run to the next on the same
    /// input and seed: timings, threads and frames in flight) as file attributes.
    #[cfg(feature = "hdf5")]
    fn write_bundle(&self, run: &RunSummary) -> Result<()> {
        use crate::io::hdf5::{write_bundle_with, BundleSpec, OwnedBundleData};
        let single = self.frames == 1;
        let name = |i: usize, what: &str| {
            if single {
                what.to_string()
            } else {
                format!("frame_{i:04}_{what}")
            }
        };
        const RADIANCE_UNITS: &str = "W m-2 sr-1 (in-band, normalised to peak response)";
        const TEMPERATURE_UNITS: &str = "K (apparent, blackbody-equivalent)";
        // (dataset name, file name of its TIFF, u16?, units)
        let mut items: Vec<(String, PathBuf, bool, &str)> = Vec::new();
        for (i, &(rad, temp)) in self.calibrated.iter().enumerate() {
            let prefix = self.prefix(i);
            if rad {
                let p = self.dir.join(format!("{prefix}radiance.tiff"));
                items.push((name(i, "radiance"), p, false, RADIANCE_UNITS));
            }
            if temp {
                let p = self.dir.join(format!("{prefix}temperature.tiff"));
                items.push((name(i, "temperature"), p, false, TEMPERATURE_UNITS));
            }
        }
        for i in 0..self.frames {
            let prefix = self.prefix(i);
            let p = self.dir.join(format!("{prefix}dn.tiff"));
            items.push((name(i, "dn"), p, true, "DN"));
            let p = self.dir.join(format!("{prefix}electrons_mean.tiff"));
            items.push((
                name(i, "electrons_mean"),
                p,
                false,
                "electrons (mean, noise-free)",
            ));
        }
        let specs: Vec<BundleSpec> = items
            .iter()
            .map(|(n, _, _, units)| BundleSpec {
                name: n,
                attrs: vec![("units", units.to_string())],
            })
            .collect();
        let p = self.dir.join("products.h5");
        let mut report =
            serde_json::to_value(run.report).map_err(|e| Error::format(&p, e.to_string()))?;
        if let Some(fields) = report.as_object_mut() {
            fields.remove("timings_s");
            fields.remove("execution");
        }
        let report = report.to_string();
        write_bundle_with(
            &p,
            &specs,
            |k| {
                let (_, path, is_u16, _) = &items[k];
                Ok(if *is_u16 {
                    OwnedBundleData::U16(raster::read_tiff_u16(path)?)
                } else {
                    OwnedBundleData::F32(raster::read_tiff_f32(path)?)
                })
            },
            &[("sensor", run.sensor.to_toml_string()?), ("report", report)],
        )
    }
}

impl FrameConsumer for ProductWriter {
    fn start(&mut self, frames: usize) -> Result<()> {
        if self.next > 0 {
            return Err(Error::OutOfRange(
                "product writer: started again after frames were written".into(),
            ));
        }
        self.frames = frames;
        self.calibrated.try_reserve(frames).map_err(|_| {
            Error::param(
                "frames",
                frames,
                "a count whose per-frame record fits in memory (it overflows)",
            )
        })?;
        Ok(())
    }

    fn frame(&mut self, index: usize, frame: FrameProducts) -> Result<()> {
        self.write_frame(index, &frame)
    }
}
