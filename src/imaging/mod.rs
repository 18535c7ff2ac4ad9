//! The imaging engine: spectral radiance cube → mean photo-electrons on the detector grid.
//!
//! Exactly the flow of docs/design.md §1:
//!
//! 1. **Spectral weights** ([`SpectralWeights`]): electrons per unit radiance for every
//!    input band, `w_b = t_int · A_det · π/(4N²)(1−R²) / (hc) · ∫ S(λ) λ φ_b(λ) dλ` with
//!    `S = τ_filter τ_optics τ_atm η` and φ_b the linear-interpolation hat of band b
//!    ([`hat_weights`]; for band-integrated input `S(λ_b) λ_b / (hc)` per bin).
//! 2. **Frequency-domain accumulation**: each band is padded (mirror extensions
//!    cross-faded across the pad, so the circular frame has no jump), transformed once
//!    (real 2-D FFT), multiplied by `w_b · OTF(u, v; λ_b)` and summed.
//! 3. **One inverse transform per frame** onto the detector grid ([`Sampling`]): for an
//!    integer ratio k of detector to scene sampling the accumulated spectrum is shifted by
//!    a phase ramp so that each detector pixel lands on a sample at the centre of its k×k
//!    block, inverse-FFT'd and point-sampled; for any other ratio the band-limited image is
//!    evaluated exactly at the detector pixel centres by a separable inverse DFT
//!    (trigonometric interpolation).
//!
//! Geometry convention (paraxial): scene sample `c` (0-based) looks at angle
//! `(c − (n_s − 1)/2)·ifov_s` from the boresight and detector pixel `j` at
//! `(j − (n_d − 1)/2)·ifov_d`, with `ifov_d = pitch / focal length`. The detector field of
//! view is centred in the scene's and must lie inside it.

mod accumulate;
pub mod distortion;
pub mod fft;
mod fft_float;
pub mod lattice;
pub mod motion;
pub mod otf_table;
pub use accumulate::{accumulate_chunk, RadialGrid};
pub use sampling::{AxisSampling, Sampling, COARSER_TOLERANCE};
mod padding;
mod r2c;
mod sampling;
use sampling::shift_phase;
pub mod relative_illumination;
pub mod scene_band;
mod spectral_weights;
pub use spectral_weights::{check_coverage, hat_weights, SpectralWeights, MAX_UNCOVERED_RESPONSE};
pub mod space_variant;
pub mod zone_error;
use scene_band::GridTaper;
mod transpose;
mod workspace;
pub use workspace::ColumnWorkspace;
pub use workspace::PROFILE_CACHE_BYTES;
use workspace::{FramePool, ProfileCache};

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use ndarray::{Array2, ArrayView2, Axis};
use num_complex::Complex64;
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::io::{BandPlanes, CubeReader};
use crate::scene::{CubeMeta, Geometry};
use crate::sensor::{FrequencyGrid, Sensor, SystemOtf};

use fft::{FftFloat, FftPrecision, RealFft2, RowStores, SpectrumBuffer};
use lattice::{ColumnFactors, LatticeInverse};
use otf_table::{BandProfile, ChunkProfile, RadialTables, CHUNK_LANES};
pub use padding::pad_width;
use padding::{FramePad, PadMap};

/// Bands read, row-transformed and accumulated together: the column pass then adds all of
/// them to an accumulator block while it is in cache, and each parallel phase has enough
/// work for the workers. Memory is a fixed number of planes and row spectra, whatever the
/// number of bands in the cube. It is the lane count of the chunk's OTF profile
/// ([`otf_table::CHUNK_LANES`], one 256-bit vector of f64), so the two cannot disagree.
pub const BANDS_PER_CHUNK: usize = CHUNK_LANES;

/// Default tolerance on wrap-around: the largest |line-spread function| sample allowed at
/// the wrap-around distance and beyond, as a fraction of the LSF's sum (see [`pad_width`]).
pub const DEFAULT_WRAP_TOLERANCE: f64 = 1e-4;

/// The smallest 2,3,5-smooth integer ≥ n (fast FFT sizes).
pub use crate::fft_size::next_fast_len;

/// Timings and sizes of one imaging run.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ImagingStats {
    /// Bands read and transformed.
    pub bands_used: usize,
    /// Padded FFT frame (rows, cols).
    pub padded_shape: (usize, usize),
    /// Seconds spent reading bands (from the second chunk on, overlapped with the
    /// transforms of the previous chunk).
    pub read_s: f64,
    /// Seconds in the row pass of the forward FFTs (padding fused in).
    pub fft_s: f64,
    /// Seconds in the fused column pass: column FFTs, OTF lookup and accumulation.
    pub otf_s: f64,
    /// Seconds in the inverse transform and sampling.
    pub inverse_s: f64,
    /// Precision of the forward transforms.
    pub precision: FftPrecision,
    /// The zones and errors of `[optics.wavefront]` imaging ([`space_variant`]), if any.
    pub wavefront: Option<Box<space_variant::WavefrontImagingReport>>,
}

/// A configured imaging chain for one sensor and one input geometry: reusable across the
/// frames of a sequence.
#[derive(Debug)]
pub struct Imager {
    sensor: Sensor,
    otf: SystemOtf,
    weights: SpectralWeights,
    sampling: Sampling,
    fft: RealFft2<f64>,
    fft32: RealFft2<f32>,
    precision: FftPrecision,
    grid: FrequencyGrid,
    pad: FramePad,
    /// Chromatic components as 1-D tables, built once per run.
    tables: RadialTables,
    /// The half-plane frequency samples as the accumulation reads them (ρ for half of
    /// each column, the achromatic product per sample in f32), in the accumulator's
    /// transposed layout `[fx][fy]`: computed once per frame size.
    radial: RadialGrid,
    /// Frame buffers kept between frames (accumulator, row spectra, column workspace).
    frames: FramePool,
    /// The chunks' OTF profiles, kept between the frames of a sequence when asked
    /// ([`Imager::keep_chunk_profiles`]).
    profiles: ProfileCache,
    /// The radial taper of the OTF at the scene grid's Nyquist circle, when the optics
    /// pass more than the grid holds ([`scene_band`]); part of the achromatic product.
    taper: Option<GridTaper>,
    /// The inverse on the detector's lattice, for an integer sampling ratio above 1 (the
    /// padded lengths are whole multiples of it): every frame's inverse transform.
    lattice: Option<LatticeInverse>,
    /// The pupil OTFs over the field, replacing the aperture terms ([`space_variant`]).
    field: Option<space_variant::FieldOptics>,
}

/// A chunk's row spectra larger than this are written with non-temporal stores
/// ([`fft::RowStores::Streaming`]); smaller ones are kept in cache for the column pass.
/// Measured on the 2-core EPYC of BENCHMARKS.md (32 MiB L3 shared with other tenants):
/// streaming made the row pass 14 % faster at 1080² (19 MB per chunk of 4 f32 bands) and
/// the demo (864 × 625, 9 MB per chunk) 4–8 % slower; half the L3 of that machine.
pub const STREAM_ROW_SPECTRA_ABOVE_BYTES: usize = 16 << 20;

impl Imager {
    /// Prepares the chain. `geometry` is the scene's field of view (from the file or the
    /// command line). `wrap_tolerance` sets the padding (see [`pad_width`]).
    pub fn new(
        sensor: &Sensor,
        meta: &CubeMeta,
        geometry: &Geometry,
        wrap_tolerance: f64,
    ) -> Result<Self> {
        Self::with_otf(sensor, sensor.otf().clone(), meta, geometry, wrap_tolerance)
    }

    /// [`Imager::new`] with the transfer-function cascade `otf` instead of the sensor's
    /// own (a moving camera's sequence replaces the motion component, see
    /// [`SystemOtf::with_motion_smear`]).
    pub fn with_otf(
        sensor: &Sensor,
        otf: SystemOtf,
        meta: &CubeMeta,
        geometry: &Geometry,
        wrap_tolerance: f64,
    ) -> Result<Self> {
        let weights = SpectralWeights::new(sensor, meta)?;
        let mut sampling = Sampling::new(sensor, meta, geometry)?;
        let active: Vec<f64> = weights
            .active_bands()
            .iter()
            .map(|b| weights.wavelength_um[*b])
            .collect();
        let extremes: Vec<f64> = match (active.first(), active.last()) {
            (Some(a), Some(b)) => vec![*a, *b],
            _ => vec![],
        };
        let (dy, dx) = sampling.scene_ifov_rad;
        let py = pad_width(
            &otf,
            dy,
            false,
            &extremes,
            wrap_tolerance,
            4 * meta.rows.max(8),
        );
        let px = pad_width(
            &otf,
            dx,
            true,
            &extremes,
            wrap_tolerance,
            4 * meta.cols.max(8),
        );
        // An integer ratio k pads to a multiple of k, so that the detector's samples form a
        // lattice of whole periods and the inverse can be folded onto it (`lattice`).
        let integer = sampling.integer;
        for (ax, p, n) in [
            (&mut sampling.y, py, meta.rows),
            (&mut sampling.x, px, meta.cols),
        ] {
            ax.pad_before = p;
            let k = if integer {
                ax.integer_ratio().unwrap_or(1)
            } else {
                1
            };
            ax.padded_len = crate::fft_size::next_fast_multiple(n + 2 * p, k);
        }
        crate::limits::check_run(
            (sampling.y.padded_len, sampling.x.padded_len),
            (meta.rows, meta.cols),
            (sensor.detector.rows, sensor.detector.cols),
            1,
        )?;
        let fft = RealFft2::<f64>::new(sampling.y.padded_len, sampling.x.padded_len);
        let lattice = if sampling.integer {
            LatticeInverse::new(
                (sampling.y.padded_len, sampling.x.padded_len),
                (
                    sampling.y.integer_ratio().unwrap_or(1),
                    sampling.x.integer_ratio().unwrap_or(1),
                ),
            )
        } else {
            None
        };
        let fft32 = RealFft2::<f32>::new(sampling.y.padded_len, sampling.x.padded_len);
        let grid = FrequencyGrid::real_fft(sampling.y.padded_len, sampling.x.padded_len, dy, dx);
        let pad = FramePad {
            y: PadMap::new(meta.rows, sampling.y.pad_before, sampling.y.padded_len),
            x: PadMap::new(meta.cols, sampling.x.pad_before, sampling.x.padded_len),
        };
        let (lo, hi) = active
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), l| {
                (lo.min(*l), hi.max(*l))
            });
        let (lo, hi) = if lo <= hi { (lo, hi) } else { (1.0, 1.0) };
        let taper = scene_band::grid_taper(&otf, (dy, dx), lo);
        if let (Some(t), Some(cutoff)) = (&taper, scene_band::optical_cutoff_cy_per_rad(&otf, lo)) {
            sampling.warnings.push(scene_band::coarse_scene_warning(
                t,
                cutoff,
                sensor.ifov_rad(),
                (dy, dx),
            ));
        }
        // The frequency samples and the chromatic tables are independent; both are
        // parallel loops with serial stretches between them (the tables' refinement
        // levels, the sampler's per-axis factors), which the other fills.
        let rest = space_variant::cascade_beside_pupil(sensor, &otf);
        let (radial, tables) = rayon::join(
            || {
                let sampler = otf.achromatic_sampler(&grid);
                RadialGrid::from_columns(&grid, |u, c| {
                    sampler.column(u, c);
                    if let Some(t) = &taper {
                        let fx = grid.fx[u];
                        for (a, fy) in c.iter_mut().zip(&grid.fy) {
                            *a *= t.factor(fx.hypot(*fy));
                        }
                    }
                })
            },
            || RadialTables::covering(rest.as_ref().unwrap_or(&otf), lo, hi, grid.rho_max()),
        );
        let field = space_variant::FieldOptics::new(sensor, &sampling, &active)?;
        let mut imager = Imager {
            sensor: sensor.clone(),
            otf,
            weights,
            sampling,
            fft,
            fft32,
            precision: FftPrecision::default(),
            grid,
            pad,
            tables,
            radial,
            frames: FramePool::default(),
            profiles: ProfileCache::new(active.len().div_ceil(BANDS_PER_CHUNK)),
            taper,
            lattice,
            field,
        };
        // `optics.wavefront.measure_error`: the zones' error measured on this frame.
        if sensor
            .optics
            .wavefront
            .as_ref()
            .is_some_and(|w| w.measure_error)
        {
            let (error, points) = zone_error::measure(&imager, meta)?;
            if let Some(f) = imager.field.as_mut() {
                f.set_measured_error(error, points);
            }
        }
        Ok(imager)
    }

    /// How the row pass writes a band's spectrum: streaming when a chunk's f32 row spectra
    /// exceed [`STREAM_ROW_SPECTRA_ABOVE_BYTES`], so they could not be read back from the
    /// cache anyway, cached otherwise. The values are the same either way.
    pub fn row_stores(&self) -> RowStores {
        let (ny, nx) = (self.sampling.y.padded_len, self.sampling.x.padded_len);
        let bytes = BANDS_PER_CHUNK * ny * (nx / 2 + 1) * std::mem::size_of::<[f32; 2]>();
        if bytes > STREAM_ROW_SPECTRA_ABOVE_BYTES {
            RowStores::Streaming
        } else {
            RowStores::Cached
        }
    }

    /// The spectral weights in use.
    pub fn weights(&self) -> &SpectralWeights {
        &self.weights
    }

    /// The sampling in use.
    pub fn sampling(&self) -> &Sampling {
        &self.sampling
    }

    /// The system transfer function in use.
    pub fn otf(&self) -> &SystemOtf {
        &self.otf
    }

    /// The radial taper the engine applies to the system OTF because the scene grid's
    /// Nyquist frequency is below the optical cutoff ([`scene_band`]), if any: the OTF
    /// the accumulation applies is [`SystemOtf::evaluate`] × [`GridTaper::factor`]`(ρ)`.
    pub fn grid_taper(&self) -> Option<&GridTaper> {
        self.taper.as_ref()
    }

    /// Selects the precision of the forward transforms (default [`FftPrecision::F32`]).
    pub fn with_precision(mut self, precision: FftPrecision) -> Self {
        self.precision = precision;
        self
    }

    /// The precision of the forward transforms.
    pub fn precision(&self) -> FftPrecision {
        self.precision
    }

    /// Sets of frame buffers (accumulator, row spectra, column workspace) this imager
    /// keeps for its next frames: one per frame imaged at the same time so far, held
    /// until [`Imager::release_frame_buffers`] or until the imager is dropped.
    pub fn kept_frame_buffers(&self) -> usize {
        self.frames.kept()
    }

    /// Frees the frame buffers kept for later frames (the next frame allocates afresh).
    /// The pipeline calls it once a run's frames are imaged, so that the stages after
    /// imaging (detector, calibration, products) run without the engine's 30-odd MB
    /// (at 1024²) held, as before the buffers were kept.
    pub fn release_frame_buffers(&self) {
        self.frames.clear();
    }

    /// Keeps the chunks' OTF profiles for the next frame, up to `max_bytes` of them in all
    /// (0, the default: none): for a sequence, whose every frame has the same bands, so
    /// each chunk's profile is built once per run instead of once per frame. The values
    /// are the same either way. The run's pipeline gives it what its memory budget leaves,
    /// at most [`PROFILE_CACHE_BYTES`]; a profile takes about 32 B per interval of its ρ
    /// grid ([`ChunkProfile::heap_bytes`]).
    pub fn keep_chunk_profiles(&self, max_bytes: usize) {
        self.profiles.keep(max_bytes);
    }

    /// Chunk profiles kept so far ([`Imager::keep_chunk_profiles`]).
    pub fn kept_chunk_profiles(&self) -> usize {
        self.profiles.kept()
    }

    /// Images frame `frame` of `reader`: returns the mean (noise-free) photo-electrons per
    /// detector pixel, `[rows, cols]`. `progress(bands done, bands)` is called after each
    /// chunk of [`BANDS_PER_CHUNK`] bands.
    ///
    /// Bands are read in chunks ([`CubeReader::read_bands`]); each chunk is padded and
    /// row-transformed (rows of all its bands in parallel), then the column pass runs over
    /// blocks of column frequencies in parallel, adding every band of the chunk, in band
    /// order, to the block of the f64 accumulator (`[fx][fy]` layout) it owns. Every
    /// accumulator sample is updated by one worker in band order, so the result is the
    /// same, bit for bit, for any number of threads.
    pub fn mean_electrons(
        &self,
        reader: &mut dyn CubeReader,
        frame: usize,
        progress: impl FnMut(usize, usize),
    ) -> Result<(Array2<f64>, ImagingStats)> {
        self.with_spectrum(reader, frame, progress, |acc_t| {
            Ok(self.detector_image_transposed(acc_t))
        })
    }

    /// Images frame `frame` of `reader` as [`Imager::mean_electrons`] does up to the
    /// inverse transform, and hands the band-summed spectrum (transposed, `[fx][fy]`, as
    /// [`Imager::detector_image_transposed`] takes it; `finish` may use it as scratch) to
    /// `finish`, whose result is returned with the imaging timings (`inverse_s` is the
    /// time `finish` took). A moving camera's static scene samples one spectrum once per
    /// frame of its sequence ([`Imager::detector_image_moving`]).
    pub fn with_spectrum<R>(
        &self,
        reader: &mut dyn CubeReader,
        frame: usize,
        progress: impl FnMut(usize, usize),
        finish: impl FnOnce(&mut [Complex64]) -> Result<R>,
    ) -> Result<(R, ImagingStats)> {
        if let Some(field) = &self.field {
            return space_variant::image_with_zones(self, field, reader, frame, progress, finish);
        }
        match self.precision {
            FftPrecision::F32 => {
                self.mean_electrons_in(&self.fft32, reader, frame, progress, finish)
            }
            FftPrecision::F64 => self.mean_electrons_in(&self.fft, reader, frame, progress, finish),
        }
    }

    /// [`Imager::with_spectrum`] with forward transforms in `T`.
    fn mean_electrons_in<T: FftFloat, R>(
        &self,
        fft: &RealFft2<T>,
        reader: &mut dyn CubeReader,
        frame: usize,
        mut progress: impl FnMut(usize, usize),
        finish: impl FnOnce(&mut [Complex64]) -> Result<R>,
    ) -> Result<(R, ImagingStats)> {
        let (ny, nx) = (self.sampling.y.padded_len, self.sampling.x.padded_len);
        let hc = nx / 2 + 1;
        // Kept from an earlier frame of this imager if there was one (accumulator zeroed).
        let buffers = self.frames.lease::<T>(hc * ny);
        let (mut acc_t, mut rowspecs, workspace) =
            (buffers.acc_t, buffers.rowspecs, buffers.columns);
        let mut stats = ImagingStats {
            padded_shape: (ny, nx),
            precision: self.precision,
            ..Default::default()
        };
        let active = self.weights.active_bands();
        let chunks: Vec<&[usize]> = active.chunks(BANDS_PER_CHUNK).collect();
        let t0 = Instant::now();
        let mut next = match chunks.first() {
            Some(c) => Some(reader.read_planes_deferred(frame, c)?),
            None => None,
        };
        stats.read_s += t0.elapsed().as_secs_f64();
        for (ci, chunk) in chunks.iter().enumerate() {
            // Mapped planes may come unchecked (`pending`): the row pass then tests every
            // row as it pads it, and a bad value stops the run with the reader's message
            // before the chunk is accumulated.
            let (planes, pending) = next.take().unwrap_or_default();
            if planes.len() != chunk.len() {
                return Err(Error::OutOfRange(format!(
                    "the reader returned {} planes for {} bands",
                    planes.len(),
                    chunk.len()
                )));
            }
            rowspecs.resize_with(chunk.len(), || SpectrumBuffer::new(ny * hc));
            let (mut fft_s, mut otf_s) = (0.0, 0.0);
            let mut unphysical = false;
            let checking = pending.is_some();
            // The chunk is transformed and accumulated on the worker pool while this thread
            // reads the next one (reading overlaps computing; the order of the arithmetic,
            // hence the result, is unchanged). Planes that come back (read into buffers,
            // for recycling, or holding a bad value, for the error message) are `kept`.
            let mut kept = None;
            let (read, read_s) = rayon::in_place_scope(|scope| {
                let (rs, acc, fft_s, otf_s) = (&mut rowspecs, &mut acc_t, &mut fft_s, &mut otf_s);
                let unphysical = &mut unphysical;
                let kept = &mut kept;
                let workspace = &workspace;
                scope.spawn(move |_| {
                    let t1 = Instant::now();
                    let wavelengths: Vec<f64> = chunk
                        .iter()
                        .map(|&b| self.weights.wavelength_um[b])
                        .collect();
                    // The chunk's OTF profile is built alongside its row pass.
                    let bad = AtomicBool::new(false);
                    let views = planes.views();
                    let ((), profile) = rayon::join(
                        || {
                            rs.par_iter_mut()
                                .zip(views.par_iter())
                                .for_each(|(rs, plane)| {
                                    let check = checking.then_some(&bad);
                                    self.rows_forward_band_checked(
                                        fft,
                                        plane.view(),
                                        rs.as_mut_slice(),
                                        check,
                                    )
                                })
                        },
                        || {
                            self.profiles
                                .get_or_build(ci, || self.chunk_profile(&wavelengths))
                        },
                    );
                    let t2 = Instant::now();
                    drop(views);
                    if bad.load(Ordering::Relaxed) {
                        *unphysical = true;
                        *kept = Some(planes);
                        return;
                    }
                    let weights: Vec<f64> = chunk
                        .iter()
                        .map(|&b| self.weights.electrons_per_unit[b])
                        .collect();
                    // The row pass is done with the planes: mapped ones are unmapped
                    // (page-table work, 0.6 ms per chunk of four 1024² planes) on one
                    // worker while the other starts accumulating, rather than on the
                    // reading thread between chunks, where it held up the next chunk.
                    rayon::join(
                        || match planes {
                            BandPlanes::Owned(buffers) => *kept = Some(BandPlanes::Owned(buffers)),
                            mapped => drop(mapped),
                        },
                        || {
                            accumulate_chunk(
                                fft,
                                &rs[..chunk.len()],
                                &weights,
                                &profile,
                                &self.radial,
                                acc,
                                workspace,
                            )
                        },
                    );
                    *fft_s = (t2 - t1).as_secs_f64();
                    *otf_s = t2.elapsed().as_secs_f64();
                });
                let t = Instant::now();
                let read = chunks
                    .get(ci + 1)
                    .map(|c| reader.read_planes_deferred(frame, c))
                    .transpose();
                (read, t.elapsed().as_secs_f64())
            });
            if unphysical {
                let planes = kept.take().unwrap_or_default();
                // The reader's own check names the band and the first bad pixel.
                pending
                    .as_ref()
                    .map_or(Ok(()), |check| check.run(&planes))?;
                return Err(Error::OutOfRange(
                    "a band held a non-physical radiance value that the full check did not find"
                        .to_string(),
                ));
            }
            if let Some(BandPlanes::Owned(planes)) = kept {
                reader.recycle(planes);
            }
            next = read?;
            stats.read_s += read_s;
            stats.fft_s += fft_s;
            stats.otf_s += otf_s;
            stats.bands_used += chunk.len();
            progress(stats.bands_used, active.len());
        }
        let t0 = Instant::now();
        let e = finish(&mut acc_t);
        stats.inverse_s = t0.elapsed().as_secs_f64();
        self.frames.give_back(workspace::FrameBuffers {
            acc_t,
            rowspecs,
            columns: workspace,
        });
        Ok((e?, stats))
    }

    /// The row pass of one band plane: padded ([`Imager::padded_band`]'s frame, one row at
    /// a time, never as a whole frame) and row-transformed into the transposed layout
    /// `[cols/2+1][rows]` whose contiguous columns [`accumulate_chunk`] transforms block
    /// by block ([`RealFft2::rows_forward_transposed`]).
    pub fn rows_forward_band<T: FftFloat>(
        &self,
        fft: &RealFft2<T>,
        plane: ArrayView2<f32>,
        rowspec: &mut [num_complex::Complex<T>],
    ) {
        self.rows_forward_band_checked(fft, plane, rowspec, None);
    }

    /// [`Imager::rows_forward_band`], and with `unphysical` given, every image row is
    /// tested ([`crate::scene::radiance_is_physical`]) in the padded row, just after it
    /// is copied there, while it is in cache: a NaN, ±Inf or negative value sets the flag
    /// (the caller then stops and names the value, [`crate::io::DeferredCheck::run`]).
    pub fn rows_forward_band_checked<T: FftFloat>(
        &self,
        fft: &RealFft2<T>,
        plane: ArrayView2<f32>,
        rowspec: &mut [num_complex::Complex<T>],
        unphysical: Option<&AtomicBool>,
    ) {
        let image_rows = self.pad.y.image_range();
        let image_cols = self.pad.x.image_range();
        fft.rows_forward_transposed(
            |r, row| {
                self.pad.row(&plane, r, row);
                // An image row's image part is a copy of the plane row (as f32 or exactly
                // widened; a NaN or ±Inf stays non-physical through the blend of a
                // strided row): checked there, in cache, rather than in the plane, where
                // the check was the row's first read from memory (with the AVX2 test:
                // `forward_fft` 0.91 of its time, and within 2 % of no check at all).
                if let (Some(flag), true) = (unphysical, image_rows.contains(&r)) {
                    if !T::all_physical(&row[image_cols.clone()]) {
                        flag.store(true, Ordering::Relaxed);
                    }
                }
            },
            rowspec,
            self.row_stores(),
        );
    }

    /// The detector image of an accumulated half-plane spectrum (`[fy, fx]`, the padded
    /// frame's [`Imager::frequency_grid`]): one inverse transform and point sampling for an
    /// integer detector/scene ratio, trigonometric interpolation otherwise (see
    /// [`Sampling`]), then cos⁴ if the optics ask for it. The same values as
    /// [`Imager::detector_image_transposed`] of its transpose, which the engine uses.
    pub fn detector_image(&self, acc: &Array2<Complex64>) -> Array2<f64> {
        if !self.sampling.integer {
            // The interpolant reads this layout itself.
            return self.with_cos4(self.sample_trigonometric(acc));
        }
        let (ny, hc) = acc.dim();
        let mut acc_t = vec![Complex64::new(0.0, 0.0); ny * hc];
        // `untranspose` with the roles of the axes swapped is the transpose.
        fft::untranspose(
            acc.as_standard_layout()
                .as_slice()
                .expect("standard layout"),
            &mut acc_t,
            hc,
            ny,
        );
        self.with_cos4(self.sample_integer(&mut acc_t))
    }

    /// [`Imager::detector_image`] of the spectrum as the engine accumulates it, transposed
    /// (`acc_t[u·rows + v]`, `[fx][fy]`; used as scratch). For an integer ratio the inverse
    /// runs on the transposed layout and only the sampled rows are row-transformed
    /// ([`RealFft2::inverse_transposed_rows`]): no frame-sized transpose and no padded
    /// image.
    pub fn detector_image_transposed(&self, acc_t: &mut [Complex64]) -> Array2<f64> {
        if self.sampling.integer {
            return self.with_cos4(self.sample_integer(acc_t));
        }
        let (ny, hc) = self.fft.spectrum_shape();
        let mut acc = Array2::<Complex64>::zeros((ny, hc));
        fft::untranspose(acc_t, acc.as_slice_mut().expect("standard layout"), ny, hc);
        self.with_cos4(self.sample_trigonometric(&acc))
    }

    /// The half-plane frequency samples (ρ and the achromatic product) as the accumulation
    /// reads them (the `grid` argument of [`accumulate_chunk`]).
    pub fn radial_grid(&self) -> &RadialGrid {
        &self.radial
    }

    /// The padded FFT frame of one band plane, as the engine transforms it (rows and
    /// columns as in [`Imager::sampling`]).
    pub fn padded_band(&self, plane: ArrayView2<f32>) -> Array2<f64> {
        let mut out = Array2::zeros((self.sampling.y.padded_len, self.sampling.x.padded_len));
        self.pad_into(plane, &mut out);
        out
    }

    /// The system transfer function at one band as a table in radial frequency ρ
    /// (chromatic components from the run's 1-D tables; see [`otf_table`]). Multiplied by
    /// the achromatic product it gives the OTF used in the accumulation, within
    /// [`otf_table::TABLE_TOLERANCE`] of direct evaluation.
    pub fn band_profile(&self, wavelength_um: f64) -> BandProfile {
        self.tables
            .band_profile(&self.otf, wavelength_um, self.radial.rho_max())
    }

    /// The chromatic transfer functions of up to [`otf_table::CHUNK_LANES`] bands on one
    /// common ρ grid, as the accumulation of a chunk uses them
    /// ([`RadialTables::chunk_profile`]).
    pub fn chunk_profile(&self, wavelengths_um: &[f64]) -> ChunkProfile {
        self.tables
            .chunk_profile(&self.otf, wavelengths_um, self.radial.rho_max())
    }

    /// The OTF the accumulation applies at `wavelength_um` on the half-plane frequency grid
    /// `[fy, fx]` (achromatic product × tabulated chromatic profile).
    pub fn tabulated_otf(&self, wavelength_um: f64) -> Array2<f64> {
        let profile = self.band_profile(wavelength_um);
        let (ny, hc) = self.fft.spectrum_shape();
        debug_assert_eq!((ny, hc), (self.radial.rows(), self.radial.cols()));
        Array2::from_shape_fn((ny, hc), |(j, k)| {
            self.radial.achromatic(k, j) * profile.eval(self.radial.rho(k, j))
        })
    }

    /// The half-plane frequency grid of the padded frame (cycles/rad).
    pub fn frequency_grid(&self) -> &FrequencyGrid {
        &self.grid
    }

    /// Pads a band plane into the FFT buffer (see `PadMap`).
    fn pad_into(&self, plane: ArrayView2<f32>, out: &mut Array2<f64>) {
        out.axis_iter_mut(Axis(0))
            .into_par_iter()
            .enumerate()
            .for_each(|(r, mut row)| {
                if let Some(row) = row.as_slice_mut() {
                    self.pad.row(&plane, r, row);
                }
            });
    }

    /// Integer ratio: shift by the fractional part of the first pixel position with a
    /// phase ramp (exact for the band-limited image; on an even axis the Nyquist bin takes
    /// the average of the ± ramps, cos(πs)), one inverse FFT evaluated at the sampled rows
    /// only, point sampling. `acc_t` is the transposed spectrum (used as scratch).
    fn sample_integer(&self, acc_t: &mut [Complex64]) -> Array2<f64> {
        let (sy, sx) = (&self.sampling.y, &self.sampling.x);
        let (ny, nx) = (sy.padded_len, sx.padded_len);
        let start_y = sy.position(0);
        let start_x = sx.position(0);
        let (fy, fx) = (start_y - start_y.floor(), start_x - start_x.floor());
        let (y0, x0) = (start_y.floor() as usize, start_x.floor() as usize);
        let (ky, kx) = (
            sy.integer_ratio().unwrap_or(1),
            sx.integer_ratio().unwrap_or(1),
        );
        let wanted: Vec<usize> = (0..sy.detector_len).map(|i| y0 + i * ky).collect();
        if let Some(lattice) = &self.lattice {
            // The sub-sample offsets as phases: along y folded with the columns, along x
            // on each row's spectrum (the same factors as the full route below).
            let ry: Vec<Complex64> = (0..ny).map(|v| shift_phase(ny, v, fy)).collect();
            let factors = ColumnFactors {
                per_column: None,
                per_row: (fy != 0.0).then_some(&ry[..]),
            };
            let starts = vec![x0; wanted.len()];
            return lattice.sample(
                acc_t,
                &factors,
                &wanted,
                &starts,
                sx.detector_len,
                |_, row| {
                    if fx != 0.0 {
                        for (u, z) in row.iter_mut().enumerate() {
                            *z *= shift_phase(nx, u, fx);
                        }
                    }
                },
            );
        }
        if fy != 0.0 || fx != 0.0 {
            let ry: Vec<Complex64> = (0..ny).map(|v| shift_phase(ny, v, fy)).collect();
            acc_t.par_chunks_mut(ny).enumerate().for_each(|(u, col)| {
                // u ≤ nx/2 (the half plane): its signed frequency is u itself.
                let x = shift_phase(nx, u, fx);
                for (a, r) in col.iter_mut().zip(&ry) {
                    *a *= r * x;
                }
            });
        }
        let mut img = Array2::<f64>::zeros((wanted.len(), nx));
        self.fft.inverse_transposed_rows(acc_t, &wanted, &mut img);
        Array2::from_shape_fn((sy.detector_len, sx.detector_len), |(i, j)| {
            img[[i, x0 + j * kx]]
        })
    }

    /// Any ratio: evaluate the band-limited (trigonometric) interpolant of the padded frame
    /// at the detector pixel centres by a separable inverse DFT. On even axes the Nyquist
    /// term uses the average of ± frequencies (a cosine), matching the FFT path.
    fn sample_trigonometric(&self, acc: &Array2<Complex64>) -> Array2<f64> {
        let (sy, sx) = (&self.sampling.y, &self.sampling.x);
        let ys: Vec<f64> = (0..sy.detector_len).map(|i| sy.position(i)).collect();
        self.sample_trigonometric_at(acc, &ys, sx.pad_before as f64 + sx.first)
    }

    /// The band-limited interpolant of the padded frame whose spectrum is `acc` at rows
    /// `ys` (padded-frame coordinates) and the detector's columns from `x0` on (column j at
    /// `x0 + j·ratio`): `[ys.len(), detector cols]`.
    fn sample_trigonometric_at(&self, acc: &Array2<Complex64>, ys: &[f64], x0: f64) -> Array2<f64> {
        let (sy, sx) = (&self.sampling.y, &self.sampling.x);
        let (ny, nx) = (sy.padded_len, sx.padded_len);
        let hx = nx / 2 + 1;
        // Step 1: along y for every column frequency: A[i, u] = Σ_v E[v, u] e^{2πi v' y_i / ny}.
        let a_rows: Vec<Vec<Complex64>> = ys
            .par_iter()
            .map(|&y| {
                let mut row = vec![Complex64::new(0.0, 0.0); hx];
                for v in 0..ny {
                    let w = shift_phase(ny, v, y);
                    for (r, e) in row.iter_mut().zip(acc.row(v)) {
                        *r += w * e;
                    }
                }
                row
            })
            .collect();
        // Step 2: along x, Hermitian half-plane: weight 1 for DC, 2 inside, 1 (cosine) at Nyquist.
        let basis: Vec<Vec<Complex64>> = (0..sx.detector_len)
            .map(|j| {
                let x = x0 + j as f64 * sx.ratio;
                (0..hx)
                    .map(|u| {
                        let p = shift_phase(nx, u, x);
                        if u == 0 || (nx % 2 == 0 && u == nx / 2) {
                            p
                        } else {
                            2.0 * p
                        }
                    })
                    .collect()
            })
            .collect();
        let norm = 1.0 / (nx * ny) as f64;
        let mut out = Array2::<f64>::zeros((ys.len(), sx.detector_len));
        out.axis_iter_mut(Axis(0))
            .into_par_iter()
            .zip(&a_rows)
            .for_each(|(mut o, a)| {
                for (v, b) in o.iter_mut().zip(&basis) {
                    let s: f64 = a.iter().zip(b).map(|(p, q)| (p * q).re).sum();
                    *v = s * norm;
                }
            });
        out
    }

    /// `e` times the relative illumination ([`relative_illumination::map`]: cos⁴θ and the
    /// `[optics.relative_illumination]` table), if the optics ask for one, else `e`.
    fn with_cos4(&self, mut e: Array2<f64>) -> Array2<f64> {
        // Sensor::build validated the table, so building the map cannot fail here.
        if let Ok(Some(m)) = relative_illumination::map(&self.sensor, e.nrows(), e.ncols()) {
            e *= &m;
        }
        e
    }
}
