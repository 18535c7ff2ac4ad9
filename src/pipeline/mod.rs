//! The chain, stage by stage: input cube → mean electrons on the detector → DN → products.
//!
//! ```text
//! image      image::ImagingStage           spectral weights, transfer functions, sampling;
//!                                          CFA sensors: one image per colour, mosaicked
//! expose     expose::Exposure              dark, shot noise, full well, FPN, nonlinearity,
//!                                          read noise, K, ADC, defects
//! demosaic   colour::colour_image          CFA sensors: black level, Malvar, white balance
//! calibrate  calibrate::FrameCalibration   thermal sensors: NUC, bad pixels, DN → radiance
//!                                          → apparent temperature
//! hand on    FrameConsumer                 each frame as soon as it is exposed, in order
//! report     report::RunReport::assemble   figures of merit, provenance, timings
//! write      ProductWriter                 dn.tiff/png, electrons_mean, radiance, temperature,
//!                                          rgb.png, dn_stack.npy, config.toml, report.json
//! ```
//!
//! **Streaming.** [`run_streaming`] hands every frame to a [`FrameConsumer`] as soon as it
//! is exposed and calibrated, in frame order, and keeps only frame 0 (for the report), so
//! its memory does not depend on the frame count: `eoir run` writes each frame into the
//! staging product set as it arrives ([`ProductWriter`]). [`run`] is the same loop with a
//! consumer that collects the frames in a `Vec` (Python, tests): its memory grows with
//! the frame count, as it returns them all.
//!
//! Every stage takes the resolved [`Sensor`]: nothing here reads a sensor file or
//! re-validates.

pub mod calibrate;
pub mod colour;
pub mod expose;
pub mod field_pictures;
pub mod focal_plane;
pub mod frames;
pub mod image;
pub mod motion;
mod output;
pub mod report_html;

use std::time::Instant;

use ndarray::Array2;

use crate::calibration::CalibrationOptions;
use crate::error::{Error, Result};
use crate::imaging::DEFAULT_WRAP_TOLERANCE;
use crate::io::CubeReader;
use crate::report::{RunFacts, RunReport};
use crate::scene::{CubeMeta, Geometry};
use crate::sensor::Sensor;

use focal_plane::FocalPlaneTruth;
use image::ImagingStage;
use motion::{SequenceMotion, TruthRow};

pub use output::ProductWriter;

/// Options of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunOptions {
    /// Seed for every random effect (noise, fixed pattern, defects).
    pub seed: u64,
    /// Field of view to use when the input does not carry one (or to override it).
    pub geometry: Option<Geometry>,
    /// Wrap-around tolerance that sets the FFT padding (see [`crate::imaging::pad_width`]).
    pub wrap_tolerance: f64,
    /// Where the input came from (for the report).
    pub input_name: String,
    /// Number of frames to expose of a single-frame (static) input: the mean image is
    /// formed once and exposed `frames` times (fixed pattern identical, temporal noise
    /// independent). Ignored for a multi-frame input.
    pub frames: usize,
    /// Radiometric calibration for thermal sensors (response beyond 3 µm): NUC fitted on
    /// blackbody frames through the same sensor instance, then DN → in-band radiance →
    /// apparent temperature. `None` skips it.
    pub calibration: Option<CalibrationOptions>,
    /// Index, within the whole sequence, of this run's first frame: frame `i` of the run
    /// draws the temporal noise of sequence frame `first_frame + i` (the fixed pattern does
    /// not depend on it). A sequence cut into pieces (e.g. chunks on several machines) and
    /// run piece by piece with the right `first_frame` gives the same DN as one run.
    pub first_frame: u64,
    /// Precision of the imaging engine's per-band forward FFTs (f32 with f64 accumulation
    /// by default; f64 for the reference path), see [`crate::imaging::fft::FftPrecision`].
    pub fft_precision: crate::imaging::fft::FftPrecision,
    /// Frames of a sequence imaged at the same time, each with its own reader
    /// ([`CubeReader::reopen`]): `None` = one per thread of the pool; fewer when the memory
    /// budget does not allow them, and 1 when the reader cannot be reopened (see
    /// [`frames`]). The products do not depend on it.
    pub frames_in_flight: Option<usize>,
    /// Frames of the whole sequence this run is a piece of (`None`: `first_frame + frames`).
    /// A moving camera's random wander is synthesised over the whole sequence's time span,
    /// so pieces run apart (Dask) see the same trajectory as one run when each is told the
    /// total.
    pub sequence_frames: Option<u64>,
    /// The input is a time-varying (rendered) sequence even when it holds one frame: a
    /// one-frame piece of a 4-D input (e.g. a Dask chunk of one frame). A one-frame input
    /// is otherwise a static scene, which a moving camera sweeps over and a piece replays
    /// from; a rendered frame already shows the platform's motion, and the frames before
    /// a piece are not in it. A run of a multi-frame input is always time-varying.
    pub time_varying: bool,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            seed: 1,
            geometry: None,
            wrap_tolerance: DEFAULT_WRAP_TOLERANCE,
            input_name: String::from("memory"),
            frames: 1,
            calibration: Some(CalibrationOptions::default()),
            first_frame: 0,
            fft_precision: Default::default(),
            frames_in_flight: None,
            sequence_frames: None,
            time_varying: false,
        }
    }
}

/// The products of one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameProducts {
    /// Noise-free expected photo-electrons per pixel (the ground truth).
    pub electrons_mean: Array2<f32>,
    /// Digital numbers (for a colour-filter-array sensor: the raw mosaic).
    pub dn: Array2<u16>,
    /// For a colour-filter-array sensor: the demosaicked (Malvar–He–Cutler), black-level
    /// subtracted, sunlight white-balanced colour image, `[row, col, 3]`, with the 99.5th
    /// percentile at 255 (one scale, so grey stays grey).
    pub rgb: Option<ndarray::Array3<u8>>,
    /// Thermal sensors: in-band radiance (W m-2 sr-1, response-weighted, normalised to peak
    /// response 1) after NUC and bad-pixel replacement; NaN where it cannot be inverted.
    pub radiance: Option<Array2<f32>>,
    /// Thermal sensors: apparent (blackbody-equivalent) temperature, K; NaN outside the
    /// calibrated range.
    pub temperature: Option<Array2<f32>>,
}

/// Everything a run produced.
#[derive(Debug, Clone)]
pub struct RunOutput {
    /// One entry per frame.
    pub frames: Vec<FrameProducts>,
    /// The sensor configuration as resolved (written as `config.toml`).
    pub sensor: Sensor,
    /// Figures of merit, input summary and timings (written as `report.json`).
    pub report: RunReport,
    /// Warnings collected on the way.
    pub warnings: Vec<String>,
    /// A moving camera's truth: per frame (per row of each frame for a rolling shutter)
    /// the exposure window, mean displacement and smear (written as `los.csv`); `None`
    /// for a still camera.
    pub line_of_sight: Option<Vec<TruthRow>>,
    /// The focal plane's truth (RTS states, trapped charge, drift per frame); `None`
    /// without a focal-plane memory (docs/focal-plane.md).
    pub focal_plane: Option<FocalPlaneTruth>,
    /// Sections a caller adds to `report.html` after the run (e.g. the figures of merit,
    /// `eoir run --assess`); empty from [`run`].
    pub extra_sections: Vec<report_html::ExtraSection>,
}

/// A run whose frames were handed to a [`FrameConsumer`] as they were exposed
/// ([`run_streaming`]): everything of a [`RunOutput`] but the frames, of which it keeps
/// frame 0 (the report's pictures and statistics are of frame 0).
#[derive(Debug, Clone)]
pub struct StreamedRun {
    /// Frames the run exposed and handed on.
    pub frame_count: usize,
    /// Frame 0's products.
    pub first: FrameProducts,
    /// The sensor configuration as resolved (written as `config.toml`).
    pub sensor: Sensor,
    /// Figures of merit, input summary and timings (written as `report.json`).
    pub report: RunReport,
    /// Warnings collected on the way.
    pub warnings: Vec<String>,
    /// A moving camera's truth (`los.csv`), as in [`RunOutput::line_of_sight`].
    pub line_of_sight: Option<Vec<TruthRow>>,
    /// The focal plane's truth, as in [`RunOutput::focal_plane`] (held for every frame:
    /// RTS states, trapped charge and drift images per frame).
    pub focal_plane: Option<FocalPlaneTruth>,
    /// Sections a caller adds to `report.html`, as in [`RunOutput::extra_sections`].
    pub extra_sections: Vec<report_html::ExtraSection>,
}

/// What the products written after the frames need of a run, borrowed from a
/// [`RunOutput`] ([`RunOutput::summary`]) or a [`StreamedRun`] ([`StreamedRun::summary`]):
/// the frame count, frame 0 and the run's report and truth.
#[derive(Debug, Clone, Copy)]
pub struct RunSummary<'a> {
    /// Frames of the run.
    pub frame_count: usize,
    /// Frame 0's products.
    pub first: &'a FrameProducts,
    /// The sensor as resolved.
    pub sensor: &'a Sensor,
    /// The run's report.
    pub report: &'a RunReport,
    /// Warnings collected on the way.
    pub warnings: &'a [String],
    /// A moving camera's truth.
    pub line_of_sight: Option<&'a [TruthRow]>,
    /// The focal plane's truth.
    pub focal_plane: Option<&'a FocalPlaneTruth>,
    /// Sections a caller added to `report.html`.
    pub extra_sections: &'a [report_html::ExtraSection],
}

impl StreamedRun {
    /// The summary the products after the frames are written from.
    pub fn summary(&self) -> RunSummary<'_> {
        RunSummary {
            frame_count: self.frame_count,
            first: &self.first,
            sensor: &self.sensor,
            report: &self.report,
            warnings: &self.warnings,
            line_of_sight: self.line_of_sight.as_deref(),
            focal_plane: self.focal_plane.as_ref(),
            extra_sections: &self.extra_sections,
        }
    }
}

impl RunOutput {
    /// The summary the products after the frames are written from.
    ///
    /// Errors: no frame (a `RunOutput` built by hand with an empty `frames`).
    pub fn summary(&self) -> Result<RunSummary<'_>> {
        let first = self
            .frames
            .first()
            .ok_or_else(|| Error::param("run output", "no frames", "at least one exposed frame"))?;
        Ok(RunSummary {
            frame_count: self.frames.len(),
            first,
            sensor: &self.sensor,
            report: &self.report,
            warnings: &self.warnings,
            line_of_sight: self.line_of_sight.as_deref(),
            focal_plane: self.focal_plane.as_ref(),
            extra_sections: &self.extra_sections,
        })
    }
}

/// Takes a run's frames one at a time, as soon as each is exposed (and, for a thermal
/// sensor, calibrated), in frame order: [`run_streaming`] hands them over and holds none
/// itself beyond frame 0. A `Vec<FrameProducts>` collects them ([`run`]); a
/// [`ProductWriter`] writes them to disk.
pub trait FrameConsumer {
    /// Called once before the first frame with the number of frames the run will hand
    /// over. Errors stop the run before any frame is imaged.
    fn start(&mut self, frames: usize) -> Result<()> {
        let _ = frames;
        Ok(())
    }

    /// Frame `index` (0, 1, … in order). An error stops the run with that error: no
    /// further frame is handed over.
    fn frame(&mut self, index: usize, frame: FrameProducts) -> Result<()>;

    /// How many of `frames` frames the consumer keeps in memory until the run ends (the
    /// run's memory check counts them): none by default, all for a collecting `Vec`.
    fn frames_held(&self, frames: usize) -> usize {
        let _ = frames;
        0
    }
}

/// The collecting consumer: every frame in order, all held in memory.
impl FrameConsumer for Vec<FrameProducts> {
    fn start(&mut self, frames: usize) -> Result<()> {
        self.reserve(frames);
        Ok(())
    }

    fn frame(&mut self, _index: usize, frame: FrameProducts) -> Result<()> {
        self.push(frame);
        Ok(())
    }

    fn frames_held(&self, frames: usize) -> usize {
        frames
    }
}

/// A false-colour composite of runs of the channels of one camera (3-CCD, three-band): the
/// channels are ordered by their response-weighted mean wavelength and the longest goes to
/// red, the middle to green, the shortest to blue (so near-IR-bright vegetation is red, as
/// in a colour-infrared photograph). Each channel's DN image is stretched between
/// its own 0.5 and 99.5 percentiles. Returns `[row, col, 3]` bytes.
pub fn false_colour_composite(channels: &[(f64, &RunOutput)]) -> Result<ndarray::Array3<u8>> {
    if channels.len() != 3 {
        return Err(Error::param(
            "composite channels",
            channels.len(),
            "exactly 3 channel runs",
        ));
    }
    let firsts = channels
        .iter()
        .map(|(l, out)| Ok((*l, out.summary()?.first)))
        .collect::<Result<Vec<_>>>()?;
    false_colour_composite_of(&firsts)
}

/// [`false_colour_composite`] of the channels' first frames (e.g. of [`StreamedRun`]s'
/// [`StreamedRun::first`]), each with its response-weighted mean wavelength.
pub fn false_colour_composite_of(
    channels: &[(f64, &FrameProducts)],
) -> Result<ndarray::Array3<u8>> {
    if channels.len() != 3 {
        return Err(Error::param(
            "composite channels",
            channels.len(),
            "exactly 3 channel runs",
        ));
    }
    let mut order: Vec<&(f64, &FrameProducts)> = channels.iter().collect();
    order.sort_by(|a, b| b.0.total_cmp(&a.0));
    let planes: Vec<Array2<f64>> = order
        .iter()
        .map(|(_, frame)| frame.dn.mapv(|v| v as f64))
        .collect();
    crate::cfa::false_colour([planes[0].view(), planes[1].view(), planes[2].view()], 0.5)
}

/// Whether the sensor sees thermal emission (its response reaches beyond 3 µm), so that
/// apparent temperature is a meaningful product.
pub fn is_thermal(sensor: &Sensor) -> bool {
    sensor.is_thermal()
}

/// The scene's field of view: the options' override, else the input's own.
fn input_geometry(options: &RunOptions, meta: &CubeMeta) -> Result<Geometry> {
    let geometry = options.geometry.or(meta.geometry).ok_or_else(|| {
        Error::param(
            "input field of view",
            "missing",
            "a field of view: pass --fov-deg H,V, or put `eoir fov deg = {H, V}` in the ENVI header / `fov_deg` in the NPY sidecar",
        )
    })?;
    // A geometry given in code or on the command line gets the same checks as a file's.
    CubeMeta {
        geometry: Some(geometry),
        ..meta.clone()
    }
    .validate("the run's geometry (--fov-deg / RunOptions::geometry)")?;
    Ok(geometry)
}

/// Checks the run's largest allocations (padded FFT planes, scene and detector frames,
/// the `frames` frames of products held at once) against the memory budget before any is
/// made; returns the bytes counted (one frame in flight).
fn check_budget(
    imaging: &ImagingStage,
    meta: &CubeMeta,
    sensor: &Sensor,
    frames: usize,
) -> Result<u64> {
    let s = imaging.sampling();
    let d = &sensor.config().detector;
    crate::limits::check_run(
        (s.y.padded_len, s.x.padded_len),
        (meta.rows, meta.cols),
        (d.rows, d.cols),
        frames,
    )
}

/// The mean electrons of frame `f`, refused when a count is not finite or beyond the f32
/// range of the products (it would be written as inf).
fn finite_mean<'a>(e: &'a Array2<f64>, f: usize, input_name: &str) -> Result<&'a Array2<f64>> {
    let fits = |v: &f64| v.is_finite() && v.abs() <= f32::MAX as f64;
    // One pass without early exit (it vectorises) before looking for the culprit.
    if e.as_slice().is_some_and(|s| {
        s.iter()
            .fold(true, |ok, v| ok & (v.abs() <= f32::MAX as f64))
    }) {
        return Ok(e);
    }
    if let Some(v) = e.iter().find(|v| !fits(v)) {
        return Err(Error::OutOfRange(format!(
            "frame {f} of `{input_name}`: the mean signal overflowed ({v:e} electrons, beyond the f32 range of the products); the input radiance or the sensor's spectral response (detector.quantum_efficiency, transmissions, integration time, pixel area) is too large to give a finite count"
        )));
    }
    Ok(e)
}

/// Adds the warnings that appear only while running: the readers' (e.g. `data ignore
/// value` pixels counted band by band; the input reader's first, then those of the
/// reopened readers of frames in flight) and the exposure model's (a scene-mean auto gain
/// warns only once the scene is known).
fn add_late_warnings(readers: Vec<String>, model: &[String], warnings: &mut Vec<String>) {
    for w in readers.into_iter().chain(model.iter().cloned()) {
        if !warnings.contains(&w) {
            warnings.push(w);
        }
    }
}

/// Frames a run produces: every frame of a sequence (`rendered`: a time-varying input,
/// whatever its frame count), or `requested` exposures of a static (single-frame) input. `requested = 0` is an error, never quietly one frame; so is a
/// `first_frame` whose last frame index would pass 2⁶⁴ − 1 (the noise streams are keyed
/// by it and must not wrap onto frame 0's).
fn frame_count(
    input_frames: usize,
    rendered: bool,
    requested: usize,
    first_frame: u64,
) -> Result<usize> {
    if requested == 0 {
        return Err(Error::param(
            "frames",
            0,
            "at least 1 (exposures of a static scene; a sequence runs all its frames)",
        ));
    }
    let n = if rendered { input_frames } else { requested };
    if first_frame.checked_add(n as u64).is_none() {
        return Err(Error::param(
            "first_frame",
            first_frame,
            format!("at most 2^64 - 1 - {n} (the frame count)"),
        ));
    }
    Ok(n)
}

impl FrameProducts {
    /// A frame before calibration: mean electrons, DN and (CFA sensors) the colour image.
    fn raw(
        electrons_mean: &Array2<f64>,
        dn: Array2<u16>,
        rgb: Option<ndarray::Array3<u8>>,
    ) -> Self {
        FrameProducts {
            electrons_mean: electrons_mean.mapv(|v| v as f32),
            dn,
            rgb,
            radiance: None,
            temperature: None,
        }
    }
}

/// Frames of products a run holds at once with `consumer`: what the consumer keeps, or,
/// when it keeps fewer than all, that plus two (the copy of frame 0 the run keeps for its
/// report and the frame being handed over), never more than the frame count.
fn frames_held(consumer: &dyn FrameConsumer, n_frames: usize) -> usize {
    let held = consumer.frames_held(n_frames);
    if held >= n_frames {
        n_frames
    } else {
        held.saturating_add(2).min(n_frames)
    }
}

/// Runs the chain on every frame of `reader` (a static input is imaged once and exposed
/// `options.frames` times) and returns every frame's products in memory (the collecting
/// [`FrameConsumer`] of [`run_streaming`]). Nothing is written: call
/// [`RunOutput::write`]. `progress(done, total)` is called after each band of each frame.
pub fn run(
    sensor: &Sensor,
    reader: &mut dyn CubeReader,
    options: &RunOptions,
    progress: impl FnMut(usize, usize),
) -> Result<RunOutput> {
    let mut frames: Vec<FrameProducts> = Vec::new();
    let s = run_streaming(sensor, reader, options, progress, &mut frames)?;
    Ok(RunOutput {
        frames,
        sensor: s.sensor,
        report: s.report,
        warnings: s.warnings,
        line_of_sight: s.line_of_sight,
        focal_plane: s.focal_plane,
        extra_sections: s.extra_sections,
    })
}

/// Runs the chain as [`run`] does, handing every frame to `consumer` as soon as it is
/// exposed (and calibrated), in frame order, and keeping only frame 0: the memory the run
/// holds does not depend on the frame count (the memory check counts the frames the
/// consumer says it holds, [`FrameConsumer::frames_held`]). The frames are the same, bit
/// for bit, as [`run`]'s. An error (the run's or the consumer's) stops the run; frames
/// handed over before it are the consumer's to discard.
pub fn run_streaming(
    sensor: &Sensor,
    reader: &mut dyn CubeReader,
    options: &RunOptions,
    mut progress: impl FnMut(usize, usize),
    consumer: &mut dyn FrameConsumer,
) -> Result<StreamedRun> {
    let t_start = Instant::now();
    let meta = reader.meta().clone();
    let geometry = input_geometry(options, &meta)?;
    let mut warnings = reader.warnings();
    warnings.extend(sensor.warnings().iter().cloned());
    let t_setup = Instant::now();
    let input_frames = reader.frames();
    let rendered = input_frames > 1 || options.time_varying;
    let n_frames = frame_count(input_frames, rendered, options.frames, options.first_frame)?;
    let motion = SequenceMotion::new(sensor, n_frames, rendered, options)?;
    let imaging = ImagingStage::new(sensor, &meta, &geometry, options, motion)?;
    let setup_s = t_setup.elapsed().as_secs_f64();
    warnings.extend(setup_warnings(&imaging, &meta, sensor, n_frames));
    let held = frames_held(consumer, n_frames);
    let run_bytes = check_budget(&imaging, &meta, sensor, held)?;
    let truth = imaging.motion().map(|m| m.truth(n_frames));
    let job = frames::FrameJob {
        stage: &imaging,
        meta: &meta,
        sensor,
        options,
        input_frames,
        rendered,
        n_frames,
        run_bytes,
    };
    let done = frames::image_and_expose(&job, reader, &mut progress, consumer)?;
    // Every frame is imaged: the engine's kept frame buffers are not needed any more.
    imaging.release_frame_buffers();
    let (first, mut exposure) = (done.first, done.exposure);
    let focal_plane = FocalPlaneTruth::take(&mut exposure, options.first_frame);
    let read_warnings = [reader.warnings(), done.reader_warnings].concat();
    add_late_warnings(read_warnings, exposure.model().warnings(), &mut warnings);
    let t_cal = Instant::now();
    let outcome = done.calibration.finish(sensor, &exposure)?;
    let calibration = outcome.into_report(&mut warnings);
    let calibration_s = done.calibration_s + t_cal.elapsed().as_secs_f64();
    let mut report = RunReport::assemble(RunFacts {
        sensor,
        model: exposure.model(),
        seed: options.seed,
        input_name: &options.input_name,
        meta: &meta,
        geometry: &geometry,
        frames: n_frames,
        bands_used: imaging.bands_used(),
        sampling: imaging.sampling(),
        imaging: &done.stats,
        wrap_tolerance: options.wrap_tolerance,
        first_electrons: &first.electrons_mean,
        first_dn: &first.dn,
        calibration,
        warnings: warnings.clone(),
        setup_s,
        detector_s: done.detector_s,
        calibration_s,
        total_s: t_start.elapsed().as_secs_f64(),
        execution: done.execution,
    });
    report.input.units_source = reader.units_source();
    report.focal_plane = focal_plane::report(&exposure, focal_plane.as_ref(), &report);
    add_saturation_warning(sensor, &first, &mut report, &mut warnings);
    Ok(StreamedRun {
        frame_count: n_frames,
        first,
        sensor: sensor.clone(),
        report,
        warnings,
        line_of_sight: truth,
        focal_plane,
        extra_sections: Vec::new(),
    })
}

/// The saturation warning of frame 0 ([`crate::report::saturation_warning`]), if any, in
/// the report and the run's warnings.
fn add_saturation_warning(
    sensor: &Sensor,
    first: &FrameProducts,
    report: &mut RunReport,
    warnings: &mut Vec<String>,
) {
    if let Some(w) = crate::report::saturation_warning(sensor, &first.electrons_mean, &first.dn) {
        report.warnings.push(w.clone());
        warnings.push(w);
    }
}

/// What the set-up found for the user: the sampling's and the detector model's warnings,
/// input bands never read, and a still camera asked for a moving sequence.
fn setup_warnings(
    imaging: &ImagingStage,
    meta: &CubeMeta,
    sensor: &Sensor,
    frames: usize,
) -> Vec<String> {
    let mut w = imaging.sampling().warnings.clone();
    w.extend(imaging.unread_bands_warning(meta));
    w.extend(sensor.detector().warnings().iter().cloned());
    w.extend(still_camera_warning(sensor, frames));
    w
}

/// A sequence of several frames whose sensor has motion but no `[clock]`: every frame is
/// the same instant (a still camera), which a user who set `[motion]` may not expect.
fn still_camera_warning(sensor: &Sensor, frames: usize) -> Option<String> {
    let c = sensor.config();
    let moves = c.motion.is_some() || c.trajectory.is_some();
    (frames > 1 && moves && c.clock.is_none()).then(|| {
        "the sensor has [motion]/[trajectory] but no [clock]: every frame is exposed at the same instant, so nothing moves between frames (set clock.frame_rate_hz, e.g. --set clock.frame_rate_hz=50, for a moving camera)".to_string()
    })
}
