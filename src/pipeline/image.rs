//! Stage 1, image: the input cube → mean photo-electrons on the detector grid, through
//! [`crate::imaging::Imager`]. A colour-filter-array sensor is imaged once per filter
//! colour (each through its own spectral response) and the three mean images are
//! mosaicked before the detector ([`crate::cfa::mosaic`]): the CFA stage.

use ndarray::Array2;
use num_complex::Complex64;

use crate::error::Result;
use crate::imaging::fft::FftPrecision;
use crate::imaging::motion::FrameMotion;
use crate::imaging::{Imager, ImagingStats, Sampling, BANDS_PER_CHUNK};
use crate::io::CubeReader;
use crate::scene::{CubeMeta, Geometry};
use crate::sensor::Sensor;

use super::motion::SequenceMotion;

/// The imaging stage of a run: one [`Imager`] per colour channel (one for a sensor
/// without a colour filter array), reusable across the frames of a sequence. Imaging a
/// frame takes `&self`, so several frames can be imaged at once, each from its own reader
/// (see [`super::frames`]).
#[derive(Debug)]
pub struct ImagingStage {
    imagers: Vec<Imager>,
    pattern: Option<crate::cfa::CfaPattern>,
    /// A moving camera's sequence: how each frame moves (`None`: a still camera).
    motion: Option<SequenceMotion>,
}

impl ImagingStage {
    /// Prepares the imagers of `sensor` for an input of `meta` with field of view
    /// `geometry` (padding from `options.wrap_tolerance`, see
    /// [`crate::imaging::pad_width`]; transforms in `options.fft_precision`).
    ///
    /// With `motion` (a moving camera's sequence, [`SequenceMotion`]) every frame is
    /// imaged as it moved, and the transfer-function cascade's motion component is the
    /// one the motion asks for ([`SequenceMotion::cascade`]).
    pub fn new(
        sensor: &Sensor,
        meta: &CubeMeta,
        geometry: &Geometry,
        options: &super::RunOptions,
        motion: Option<SequenceMotion>,
    ) -> Result<Self> {
        let channels: Vec<&Sensor> = match sensor.cfa_channels() {
            [] => vec![sensor],
            cs => cs.iter().collect(),
        };
        let imagers = channels
            .into_iter()
            .map(|s| {
                let otf = match &motion {
                    Some(m) => m.cascade(s),
                    None => s.otf().clone(),
                };
                Imager::with_otf(s, otf, meta, geometry, options.wrap_tolerance)
                    .map(|i| i.with_precision(options.fft_precision))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(ImagingStage {
            imagers,
            pattern: sensor.cfa.as_ref().map(|c| c.pattern),
            motion,
        })
    }

    /// The moving camera's sequence motion, if the camera moves.
    pub fn motion(&self) -> Option<&SequenceMotion> {
        self.motion.as_ref()
    }

    /// Lets the imagers keep their chunks' OTF profiles for the next frame, up to
    /// `max_bytes` in all ([`Imager::keep_chunk_profiles`]; shared evenly between colour
    /// channels): for a sequence.
    pub fn keep_chunk_profiles(&self, max_bytes: usize) {
        let each = max_bytes / self.imagers.len().max(1);
        for imager in &self.imagers {
            imager.keep_chunk_profiles(each);
        }
    }

    /// Frees the frame buffers the imagers keep between frames
    /// ([`Imager::release_frame_buffers`]): for when the run's last frame is imaged.
    pub fn release_frame_buffers(&self) {
        for imager in &self.imagers {
            imager.release_frame_buffers();
        }
    }

    /// Bands with a non-zero weight, summed over the colour channels (the progress total
    /// of one frame).
    pub fn bands_used(&self) -> usize {
        self.imagers
            .iter()
            .map(|i| i.weights().active_bands().len())
            .sum()
    }

    /// The input bands no colour channel uses (zero spectral weight), as one warning:
    /// the engine never reads them, so they are not checked for NaN, ±Inf or negative
    /// radiance (README, "Input"). `None` when every band is read.
    pub fn unread_bands_warning(&self, meta: &CubeMeta) -> Option<String> {
        let mut used = vec![false; meta.bands()];
        for im in &self.imagers {
            for b in im.weights().active_bands() {
                used[b] = true;
            }
        }
        let unread: Vec<usize> = (0..used.len()).filter(|&b| !used[b]).collect();
        if unread.is_empty() {
            return None;
        }
        // Runs of consecutive bands, as `a–b (λa–λb µm)`.
        let mut runs: Vec<String> = Vec::new();
        let mut i = 0;
        while i < unread.len() {
            let mut j = i;
            while j + 1 < unread.len() && unread[j + 1] == unread[j] + 1 {
                j += 1;
            }
            let (a, b) = (unread[i], unread[j]);
            let (la, lb) = (meta.wavelength_um[a], meta.wavelength_um[b]);
            runs.push(if a == b {
                format!("{a} ({la} µm)")
            } else {
                format!("{a}–{b} ({la}–{lb} µm)")
            });
            i = j + 1;
        }
        Some(format!(
            "{} of {} input bands have zero sensor response and were not read (so not checked for NaN, ±Inf or negative radiance): band {}",
            unread.len(),
            meta.bands(),
            runs.join(", ")
        ))
    }

    /// Scene → detector sampling (the same for every channel).
    pub fn sampling(&self) -> &Sampling {
        self.imagers[0].sampling()
    }

    /// Bytes one frame in flight holds while it is imaged, beyond what
    /// [`crate::limits::check_run`] already counts for the run: per colour channel the f64
    /// accumulator (`[fx][fy]`) and room for an untransposed copy at the end (2 × 16 B per
    /// half-spectrum sample; only a non-integer detector/scene ratio makes the copy, so for
    /// integer ratios this is an upper bound), the row spectra of one chunk of [`BANDS_PER_CHUNK`] bands
    /// (8 B per sample in f32, 16 B in f64), the planes of the chunk being transformed and
    /// of the one being read (2 × [`BANDS_PER_CHUNK`] scene planes, f32), and the f64
    /// detector image it hands over (`detector` = (rows, cols)). This is what a second,
    /// third … frame in flight adds to the run's peak.
    pub fn frame_bytes_in_flight(&self, meta: &CubeMeta, detector: (usize, usize)) -> u64 {
        let s = self.sampling();
        let half = (s.y.padded_len as u64) * (s.x.padded_len as u64 / 2 + 1);
        let spectrum_bytes = match self.imagers[0].precision() {
            FftPrecision::F32 => 8,
            FftPrecision::F64 => 16,
        };
        let chunk = BANDS_PER_CHUNK as u64;
        let planes = 2 * chunk * (meta.rows as u64) * (meta.cols as u64) * 4;
        let detector_image = (detector.0 as u64) * (detector.1 as u64) * 8;
        let per_channel = half * (2 * 16 + chunk * spectrum_bytes) + planes + detector_image;
        per_channel.saturating_mul(self.imagers.len() as u64)
    }

    /// Mean signal electrons of frame `frame` (mosaicked for a CFA sensor) and the
    /// imaging timings of this frame. `progress(bands done in this frame)` is called after
    /// each chunk of bands. The result depends only on the frame's planes, never on the
    /// thread doing the work or on other frames imaged at the same time.
    pub fn mean_electrons(
        &self,
        reader: &mut dyn CubeReader,
        frame: usize,
        mut progress: impl FnMut(usize),
    ) -> Result<(Array2<f64>, ImagingStats)> {
        let mut planes = Vec::with_capacity(self.imagers.len());
        let mut stats = ImagingStats::default();
        let mut done = 0;
        let moved = self.motion.as_ref().map(|m| m.frame(frame));
        for im in &self.imagers {
            let (e, s) = im.with_spectrum(
                reader,
                frame,
                |b, _| progress(done + b),
                |acc| match moved.as_ref().filter(|m| !m.is_identity()) {
                    Some(m) => im.detector_image_moving(acc, m, &mut Vec::new()),
                    None => Ok(im.detector_image_transposed(acc)),
                },
            )?;
            done += s.bands_used;
            add_stats(&mut stats, &s);
            planes.push(e);
        }
        Ok((self.mosaic(planes)?, stats))
    }

    /// One mean image from the channels' images (mosaicked for a CFA sensor).
    fn mosaic(&self, mut planes: Vec<Array2<f64>>) -> Result<Array2<f64>> {
        match self.pattern {
            Some(p) => crate::cfa::mosaic([&planes[0], &planes[1], &planes[2]], p),
            None => Ok(planes.swap_remove(0)),
        }
    }

    /// A static scene seen by a moving camera: the scene (frame 0 of `reader`) is imaged
    /// once up to its band-summed spectrum, then every one of `frames` frames is sampled
    /// from it as it moved ([`Imager::detector_image_moving`]: one multiplication and one
    /// inverse transform per frame and channel) and handed to `each(frame, mean image,
    /// earlier)` in frame order. Without motion, every frame is the still image.
    ///
    /// `earlier(k)` images frame `k` of the *sequence* (counted from its start, not from
    /// the run's first frame) the same way: a piece of a sequence replays the focal plane's
    /// persistence over the frames before its first with it.
    pub fn static_sequence(
        &self,
        reader: &mut dyn CubeReader,
        frames: usize,
        mut progress: impl FnMut(usize),
        mut each: impl FnMut(usize, Array2<f64>, &dyn Fn(usize) -> Result<Array2<f64>>) -> Result<()>,
    ) -> Result<ImagingStats> {
        let mut stats = ImagingStats::default();
        let mut spectra = Vec::with_capacity(self.imagers.len());
        let mut done = 0;
        for im in &self.imagers {
            let (spec, s) =
                im.with_spectrum(reader, 0, |b, _| progress(done + b), |acc| Ok(acc.to_vec()))?;
            done += s.bands_used;
            add_stats(&mut stats, &s);
            // Each column's zero gap, found once for every frame that samples `spec`.
            let gaps = im.spectrum_zero_gaps(&spec);
            spectra.push((spec, gaps));
        }
        // The mean image of a frame that moved by `moved`.
        let image_moved =
            |moved: Option<FrameMotion>, scratch: &mut Vec<Complex64>| -> Result<Array2<f64>> {
                let mut planes = Vec::with_capacity(self.imagers.len());
                for (im, (spec, gaps)) in self.imagers.iter().zip(&spectra) {
                    planes.push(match moved.as_ref().filter(|m| !m.is_identity()) {
                        Some(m) => im.detector_image_moving_with_gaps(spec, gaps, m, scratch)?,
                        None => {
                            scratch.clear();
                            scratch.extend_from_slice(spec);
                            im.detector_image_transposed(scratch)
                        }
                    });
                }
                self.mosaic(planes)
            };
        // Frame g's mean image and the seconds it took.
        let image = |g: usize, scratch: &mut Vec<Complex64>| -> (Result<Array2<f64>>, f64) {
            let t0 = std::time::Instant::now();
            let e = image_moved(self.motion.as_ref().map(|m| m.frame(g)), scratch);
            (e, t0.elapsed().as_secs_f64())
        };
        let earlier = |k: usize| {
            image_moved(
                self.motion.as_ref().map(|m| m.sequence_frame(k)),
                &mut Vec::new(),
            )
        };
        // Frame g + 1 is imaged on a thread of its own while `each` exposes frame g on
        // this one (the imaging reads only the spectra and immutable tables, so the image
        // is the same as one at a time; errors keep their frame order).
        let mut scratch = Vec::new();
        let mut next = (frames > 0).then(|| image(0, &mut scratch));
        for g in 0..frames {
            let Some((current, seconds)) = next.take() else {
                break;
            };
            stats.inverse_s += seconds;
            let current = current?;
            let (exposed, imaged) = std::thread::scope(|sc| {
                let worker = (g + 1 < frames).then(|| {
                    let (image, scratch) = (&image, &mut scratch);
                    sc.spawn(move || image(g + 1, scratch))
                });
                let exposed = each(g, current, &earlier);
                let imaged = worker.map(|w| match w.join() {
                    Ok(r) => r,
                    Err(panic) => std::panic::resume_unwind(panic),
                });
                (exposed, imaged)
            });
            exposed?;
            next = imaged;
        }
        Ok(stats)
    }
}

/// Adds the timings and band count of `s` to `total` (the padded shape, precision and
/// wavefront zones are the same for every channel and frame of a run).
pub fn add_stats(total: &mut ImagingStats, s: &ImagingStats) {
    total.read_s += s.read_s;
    total.fft_s += s.fft_s;
    total.otf_s += s.otf_s;
    total.inverse_s += s.inverse_s;
    total.bands_used += s.bands_used;
    total.padded_shape = s.padded_shape;
    total.precision = s.precision;
    if s.wavefront.is_some() {
        total.wavefront.clone_from(&s.wavefront);
    }
}
