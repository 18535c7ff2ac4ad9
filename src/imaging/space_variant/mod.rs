//! The wavefront in the imaging chain and space-variant imaging across the field
//! (docs/wavefront.md, "In the imaging chain" and "Across the field").
//!
//! With `[optics.wavefront]` the pupil's own transfer function (the normalised
//! autocorrelation of the generalised pupil, [`PupilTransfer`]) replaces the analytic
//! diffraction, obscuration, Shannon-aberration and defocus components; every other
//! component (footprint, motion, jitter, turbulence, aerosol, Gaussian, measured, the
//! scene-grid taper) stays cascaded.
//!
//! **Zones with source weights** (Flicker & Rigaut, "Anisoplanatic deconvolution of
//! adaptive optics images", JOSA A 22, 504, 2005; Denis, Thiébaut, Soulez, Becker &
//! Mourya, "Fast approximations of shift-variant blur", IJCV 115, 253, 2015): the field
//! is covered by a `g × g` grid of zone centres (the detector's corners and edges
//! included), each with the OTF of the wavefront at its own field height H and azimuth
//! (the local wavefront's tangential axis turned to point from the axis to the centre),
//! and the image is
//!
//! `E(f) = Σ_b w_b · C_b(f) · Σ_k OTF_{k,b}(f) · FFT(t_k ⊙ L_b)(f)`,
//!
//! with `C_b` the rest of the cascade and `t_k(x, y) = t_i(y) t_j(x)` bilinear tents on the
//! grid of centres (clamped to the edge zones beyond it): a smooth partition of unity,
//! `Σ_k t_k = 1` at every sample. So each source point is blurred by the bilinear blend of
//! the PSFs of the four centres around it, which at a centre is that centre's PSF, and
//! the flux is conserved (every OTF is 1 at f = 0). One zone is the field-independent
//! chain.
//!
//! **Error.** For a point source at s the approximation gives `Σ_k t_k(s) PSF_k` where
//! direct summation gives `PSF(s)`; the zone count is chosen as the smallest `g` whose
//! largest `|PSF(s) − Σ_k t_k(s) PSF_k|` over the cell centres and edge midpoints of the
//! grid (where bilinear blending errs most) is within `zone_tolerance` of `max PSF(s)`,
//! with the PSFs of the pupil at the shortest wavelength in use (the largest phase). By
//! linearity a scene's error is at most that per unit of its flux.
//! [`direct_summation`] is the slow exact reference (each source pixel blurred by the
//! PSF of its own position).
//!
//! **Wavelength.** Each zone's OTF is computed at wavelength nodes uniform in the phase
//! scale `s = λ_ref/λ` and interpolated linearly in s at fixed normalised frequency
//! `X = fλ/D`. With `Δs` the node spacing and PV the wavefront's peak-to-valley (waves at
//! λ_ref), the OTF `(1/A)∫ exp(2πi s ΔW)` with `|ΔW| ≤ PV` has `|∂²/∂s²| ≤ (2π PV)²`, so
//! the interpolation error is at most `(2π PV Δs)²/8`; nodes are spaced so this is
//! ≤ 1e-3, or placed at every band's own wavelength when that takes fewer.

use std::f64::consts::TAU;
use std::time::Instant;

use ndarray::Array2;
use num_complex::{Complex32, Complex64};
use rayon::prelude::*;
use serde::Serialize;

use super::{Imager, ImagingStats};
use crate::error::{Error, Result};
use crate::io::CubeReader;
use crate::sensor::{Sensor, SystemOtf};
use crate::wavefront::{
    FieldDependence, LocalWavefront, Pupil, PupilTransfer, Sampling, WavefrontModel,
};

/// Bound on the OTF's error from interpolating between wavelength nodes (see the module
/// documentation).
pub const WAVELENGTH_INTERPOLATION_BOUND: f64 = 1e-3;

/// Pupil samples across the diameter for the PSFs that choose the zone count (their
/// differences, not their absolute accuracy, matter; refined for steep wavefronts).
const CRITERION_SAMPLES: usize = 64;

/// What `report.json` says about the pupil transfer functions of a run
/// (`wavefront_imaging`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WavefrontImagingReport {
    /// Zones per field axis (the grid of zone centres is `g × g`).
    pub zones_per_axis: usize,
    /// Zones in all, K = g².
    pub zones: usize,
    /// How the zone count was set.
    pub zone_choice: String,
    /// The target point-source error, fraction of the PSF peak.
    pub zone_tolerance: f64,
    /// The largest point-source error of the zones against direct space-variant summation
    /// at the cell centres and edge midpoints of the zone grid, fraction of the PSF peak
    /// (0 with one zone and a wavefront that does not change over the field).
    pub point_source_error_of_peak: f64,
    /// Wavelength of those PSFs, µm.
    pub error_wavelength_um: f64,
    /// Wavelength nodes at which each zone's OTF is computed.
    pub wavelength_nodes: usize,
    /// Whether the nodes are the bands' own wavelengths (no interpolation).
    pub nodes_at_band_wavelengths: bool,
    /// Pupil samples across the diameter of the zone OTFs.
    pub pupil_samples_across: usize,
    /// The field angle of H = 1 (the detector's half-diagonal), mrad.
    pub full_field_mrad: f64,
    /// Measured on this run's frame when `optics.wavefront.measure_error = true`
    /// ([`super::zone_error`]): the largest |zones − direct summation| over the detector
    /// image of point sources at [`Self::measured_points`], as a fraction of the direct
    /// image's peak, at the run's own bands; absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub measured_error_of_peak: Option<f64>,
    /// The scene samples (row, col) of those point sources.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub measured_points: Vec<(usize, usize)>,
}

/// Field geometry of the padded FFT frame: where the zone centres are and the field
/// height and azimuth of any sample.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldFrame {
    /// Padded-frame coordinates (row, col) of the detector field's centre.
    centre: (f64, f64),
    /// Half-size of the detector field (rows, cols), scene samples.
    half: (f64, f64),
    /// Scene sample spacing (y, x), rad.
    ifov_rad: (f64, f64),
    /// The field angle of H = 1, rad.
    full_field_rad: f64,
}

impl FieldFrame {
    fn new(s: &super::Sampling) -> Self {
        let axis = |a: &super::AxisSampling| {
            (
                a.pad_before as f64 + a.first + (a.detector_len as f64 - 1.0) / 2.0 * a.ratio,
                a.detector_len as f64 * a.ratio / 2.0,
            )
        };
        let (cy, hy) = axis(&s.y);
        let (cx, hx) = axis(&s.x);
        let (dy, dx) = s.scene_ifov_rad;
        FieldFrame {
            centre: (cy, cx),
            half: (hy, hx),
            ifov_rad: (dy, dx),
            full_field_rad: (hy * dy).hypot(hx * dx),
        }
    }

    /// Field height H (clamped to 1) and azimuth (rad, from +x toward +y = increasing
    /// rows; 90° on the axis) of padded-frame position (row, col).
    pub fn field_point(&self, row: f64, col: f64) -> (f64, f64) {
        let y = (row - self.centre.0) * self.ifov_rad.0;
        let x = (col - self.centre.1) * self.ifov_rad.1;
        let h = if self.full_field_rad > 0.0 {
            (x.hypot(y) / self.full_field_rad).min(1.0)
        } else {
            0.0
        };
        // On the axis the local frame is the image frame (field along +y).
        let azimuth = if x == 0.0 && y == 0.0 {
            std::f64::consts::FRAC_PI_2
        } else {
            y.atan2(x)
        };
        (h, azimuth)
    }

    /// Padded-frame coordinate of node `i` of `g` along an axis (0: rows, 1: cols).
    fn node(&self, axis: usize, i: f64, g: usize) -> f64 {
        let (c, h) = if axis == 0 {
            (self.centre.0, self.half.0)
        } else {
            (self.centre.1, self.half.1)
        };
        if g == 1 {
            c
        } else {
            c - h + 2.0 * h * i / (g - 1) as f64
        }
    }

    /// The tent weight of node `i` of `g` along `axis` at padded coordinate `p`: bilinear
    /// hat functions on the nodes, the edge nodes' held constant beyond them, so the
    /// weights of the g nodes sum to 1 everywhere.
    pub fn tent(&self, axis: usize, i: usize, g: usize, p: f64) -> f64 {
        if g == 1 {
            return 1.0;
        }
        let first = self.node(axis, 0.0, g);
        let step = self.node(axis, 1.0, g) - first;
        let t = if step > 0.0 {
            ((p - first) / step).clamp(0.0, (g - 1) as f64)
        } else {
            0.0
        };
        (1.0 - (t - i as f64).abs()).max(0.0)
    }
}

mod tables;
use tables::{BandTaps, HalfPlaneOtf, TableWindow, Tap};

#[cfg(test)]
mod lookup_tests;

/// The pupil transfer functions of an imaging chain: zones, their OTFs at the wavelength
/// nodes, and the report.
#[derive(Debug, Clone)]
pub struct FieldOptics {
    model: WavefrontModel,
    pupil: Pupil,
    diameter_m: f64,
    frame: FieldFrame,
    per_axis: usize,
    /// Phase scales s = λ_ref/λ of the nodes, increasing.
    node_scale: Vec<f64>,
    /// The stored window of every zone's tables (all share the pupil sampling).
    window: TableWindow,
    /// `otfs[k][j]`: zone k (row-major over the grid) at node j.
    otfs: Vec<Vec<HalfPlaneOtf>>,
    /// Zones whose tables were computed from the pupil (the others are mirror images).
    computed_zones: usize,
    report: WavefrontImagingReport,
}

/// The wavefront's peak-to-valley over the pupil, waves at the reference wavelength (a
/// polar set of points, rim included).
fn peak_to_valley(w: &LocalWavefront) -> f64 {
    let (mut lo, mut hi) = (w.waves(0.0, 0.0), w.waves(0.0, 0.0));
    for ir in 1..=32 {
        let r = ir as f64 / 32.0;
        for it in 0..64 {
            let t = it as f64 / 64.0 * TAU;
            let v = w.waves(r * t.cos(), r * t.sin());
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    hi - lo
}

impl FieldOptics {
    /// The pupil transfer functions of `sensor`'s `[optics.wavefront]` for `imager`'s
    /// frame and the active band wavelengths `active_um`; `None` without the section.
    pub(super) fn new(
        sensor: &Sensor,
        sampling: &super::Sampling,
        active_um: &[f64],
    ) -> Result<Option<Self>> {
        let Some(w) = &sensor.optics.wavefront else {
            return Ok(None);
        };
        let model = w.model()?;
        let pupil = w.pupil(sensor.optics.obscuration_ratio)?;
        let settings = w.zone_settings()?;
        let diameter_m = sensor.optics.focal_length_m / sensor.optics.f_number;
        let frame = FieldFrame::new(sampling);
        let mut bands: Vec<f64> = active_um.to_vec();
        bands.sort_by(f64::total_cmp);
        bands.dedup();
        let (lo_um, hi_um) = match (bands.first(), bands.last()) {
            (Some(a), Some(b)) => (*a, *b),
            _ => (1.0, 1.0),
        };
        let mut fo = FieldOptics {
            model,
            pupil,
            diameter_m,
            frame,
            per_axis: 1,
            node_scale: Vec::new(),
            window: TableWindow::new(1, 2, 0.0, 0.0),
            otfs: Vec::new(),
            computed_zones: 0,
            report: WavefrontImagingReport {
                zones_per_axis: 1,
                zones: 1,
                zone_choice: String::new(),
                zone_tolerance: settings.zone_tolerance,
                point_source_error_of_peak: 0.0,
                error_wavelength_um: lo_um,
                wavelength_nodes: 0,
                nodes_at_band_wavelengths: false,
                pupil_samples_across: 0,
                full_field_mrad: 0.0,
                measured_error_of_peak: None,
                measured_points: Vec::new(),
            },
        };
        fo.report.full_field_mrad = fo.frame.full_field_rad * 1e3;
        let lambda_min_m = lo_um * 1e-6;
        let (g, error, choice) = if let Some(g) = settings.zones_per_axis {
            let e = if g == 1 && fo.model.is_field_independent() {
                0.0
            } else {
                fo.grid_error(g, lambda_min_m)?
            };
            (g, e, "set (optics.wavefront.zones_per_axis)".to_string())
        } else if fo.model.is_field_independent() {
            (
                1,
                0.0,
                "automatic: one zone, the wavefront does not change over the field".to_string(),
            )
        } else {
            let mut chosen = None;
            let mut last = (0, f64::INFINITY);
            for g in 2..=settings.max_zones_per_axis.max(2) {
                let e = fo.grid_error(g, lambda_min_m)?;
                last = (g, e);
                if e <= settings.zone_tolerance {
                    chosen = Some((g, e));
                    break;
                }
            }
            match chosen {
                Some((g, e)) => (
                    g,
                    e,
                    "automatic (optics.wavefront.zone_tolerance)".to_string(),
                ),
                None => (
                    last.0,
                    last.1,
                    format!(
                        "automatic, capped at optics.wavefront.max_zones_per_axis = {}: the \
                         tolerance is not met",
                        settings.max_zones_per_axis
                    ),
                ),
            }
        };
        fo.per_axis = g;
        fo.report.zones_per_axis = g;
        fo.report.zones = g * g;
        fo.report.zone_choice = choice;
        fo.report.point_source_error_of_peak = error;
        // Zone centres and their local wavefronts.
        let centres: Vec<(f64, f64)> = (0..g * g)
            .map(|k| {
                fo.frame.field_point(
                    fo.frame.node(0, (k / g) as f64, g),
                    fo.frame.node(1, (k % g) as f64, g),
                )
            })
            .collect();
        let locals: Vec<(LocalWavefront, LocalWavefront)> =
            centres.iter().map(|c| fo.wavefront_at(c.0)).collect();
        // Wavelength nodes.
        let reference_m = fo.model.reference_wavelength_m();
        let pv = locals
            .iter()
            .map(|(a, b)| peak_to_valley(a) + peak_to_valley(b))
            .fold(0.0, f64::max);
        let (s_lo, s_hi) = (reference_m / (hi_um * 1e-6), reference_m / (lo_um * 1e-6));
        let spacing = (8.0 * WAVELENGTH_INTERPOLATION_BOUND).sqrt() / (TAU * pv.max(1e-300));
        let needed = if pv == 0.0 || s_hi == s_lo {
            1
        } else {
            ((s_hi - s_lo) / spacing).ceil() as usize + 1
        };
        let at_bands = needed >= bands.len();
        fo.node_scale = if at_bands {
            bands
                .iter()
                .rev()
                .map(|l| reference_m / (l * 1e-6))
                .collect()
        } else if needed == 1 {
            vec![s_lo]
        } else {
            (0..needed)
                .map(|j| s_lo + (s_hi - s_lo) * j as f64 / (needed - 1) as f64)
                .collect()
        };
        fo.report.wavelength_nodes = fo.node_scale.len();
        fo.report.nodes_at_band_wavelengths = at_bands;
        // One sampling for every zone and node: the steepest wavefront at the shortest
        // wavelength.
        let mut samples = settings.pupil_samples_across;
        for c in &centres {
            samples = samples.max(fo.samples_for(c.0, lambda_min_m, samples)?);
        }
        let pupil_sampling = Sampling {
            samples_across: samples,
            padding: 2,
        };
        fo.report.pupil_samples_across = samples;
        // The frame's largest |fx| and |fy| at the longest wavelength, in X = fλ/D.
        let grid = crate::sensor::FrequencyGrid::real_fft(
            sampling.y.padded_len,
            sampling.x.padded_len,
            sampling.scene_ifov_rad.0,
            sampling.scene_ifov_rad.1,
        );
        let largest = |f: &[f64]| f.iter().fold(0.0, |m: f64, v| m.max(v.abs()));
        let scale = hi_um * 1e-6 / diameter_m;
        fo.window = TableWindow::new(
            samples,
            samples * pupil_sampling.padding,
            largest(&grid.fx) * scale,
            largest(&grid.fy) * scale,
        );
        let window = fo.window;
        // Mirror symmetry: the zone centres are symmetric about the axis, and the Seidel
        // terms are even in the local sagittal coordinate, so with a mirror-symmetric
        // aperture (no spider vanes) and no Zernike terms the zone mirrored across the
        // field's vertical (horizontal) axis has the pupil mirrored in x (y) and its OTF
        // mirrored: only the zones of one quadrant are computed ([`HalfPlaneOtf::mirrored`]).
        let symmetric = fo.pupil.is_radially_symmetric()
            && locals.iter().all(|(t, f)| {
                t.zernike_rms_waves.iter().all(|c| *c == 0.0)
                    && f.zernike_rms_waves.iter().all(|c| *c == 0.0)
            });
        let source = |k: usize| -> (usize, bool, bool) {
            let (i, j) = (k / g, k % g);
            if !symmetric {
                return (k, false, false);
            }
            let (si, sj) = (i.min(g - 1 - i), j.min(g - 1 - j));
            (si * g + sj, si != i, sj != j)
        };
        let jobs: Vec<(usize, usize)> = (0..g * g)
            .filter(|&k| source(k).0 == k)
            .flat_map(|k| (0..fo.node_scale.len()).map(move |j| (k, j)))
            .collect();
        let computed: Vec<HalfPlaneOtf> = jobs
            .par_iter()
            .map(|&(k, j)| {
                let t = PupilTransfer::compute_at_azimuth(
                    &fo.pupil,
                    &locals[k].0,
                    &locals[k].1,
                    centres[k].1,
                    reference_m,
                    reference_m / fo.node_scale[j],
                    diameter_m,
                    pupil_sampling,
                )?;
                Ok(HalfPlaneOtf::from_transfer(&t, window))
            })
            .collect::<Result<Vec<_>>>()?;
        let nodes = fo.node_scale.len();
        let mut it = computed.into_iter();
        let own: Vec<Option<Vec<HalfPlaneOtf>>> = (0..g * g)
            .map(|k| (source(k).0 == k).then(|| it.by_ref().take(nodes).collect()))
            .collect();
        fo.otfs = (0..g * g)
            .map(|k| {
                let (from, flip_y, flip_x) = source(k);
                own[from]
                    .as_ref()
                    .map(|tables| tables.iter().map(|t| t.mirrored(flip_x, flip_y)).collect())
                    .unwrap_or_default()
            })
            .collect();
        fo.computed_zones = own.iter().filter(|t| t.is_some()).count();
        Ok(Some(fo))
    }

    /// The wavefront at field height `h` as the part that turns with the field azimuth
    /// (Seidel terms, and with a field table every term: local values for a field point
    /// along +y) and the part fixed to the lens (the field-independent Zernike terms of
    /// `field_dependence = "seidel"`, given in the image frame: x along columns, y along
    /// rows).
    fn wavefront_at(&self, h: f64) -> (LocalWavefront, LocalWavefront) {
        let w = self.model.at_field(h);
        match self.model.field() {
            FieldDependence::Seidel { .. } => (
                LocalWavefront {
                    seidel: w.seidel,
                    zernike_rms_waves: Vec::new(),
                },
                LocalWavefront {
                    zernike_rms_waves: w.zernike_rms_waves,
                    ..LocalWavefront::default()
                },
            ),
            FieldDependence::Table(_) => (w, LocalWavefront::default()),
        }
    }

    /// Pupil samples across for `wavefront_at(h)` at `lambda_m`, at least `min_samples`:
    /// the samples each part needs added (the slope of a sum is at most the sum of the
    /// slopes).
    fn samples_for(&self, h: f64, lambda_m: f64, min_samples: usize) -> Result<usize> {
        let (turning, fixed) = self.wavefront_at(h);
        let reference_m = self.model.reference_wavelength_m();
        let need = |w: &LocalWavefront| -> Result<usize> {
            Ok(Sampling::for_wavefront_from(w, reference_m, lambda_m, 2, 8)?.samples_across)
        };
        let n = (need(&turning)? + need(&fixed)?).max(min_samples);
        if n > 1024 {
            return Err(Error::param(
                "optics.wavefront",
                format!("{n} pupil samples across needed"),
                "a wavefront whose slope needs at most 1024 samples across the pupil",
            ));
        }
        Ok(n.next_multiple_of(2))
    }

    /// What `report.json` records.
    pub fn report(&self) -> &WavefrontImagingReport {
        &self.report
    }

    /// Records the error measured on sample point sources ([`super::zone_error`]).
    pub(super) fn set_measured_error(&mut self, error_of_peak: f64, points: Vec<(usize, usize)>) {
        self.report.measured_error_of_peak = Some(error_of_peak);
        self.report.measured_points = points;
    }

    /// Zones per axis.
    pub fn zones_per_axis(&self) -> usize {
        self.per_axis
    }

    /// The field geometry of the padded frame.
    pub fn frame(&self) -> &FieldFrame {
        &self.frame
    }

    /// The pupil transfer function of the wavefront at padded-frame position (row, col)
    /// (its own H and azimuth) at wavelength `lambda_m`, sampled by `sampling`.
    fn transfer_at(
        &self,
        row: f64,
        col: f64,
        lambda_m: f64,
        sampling: Sampling,
    ) -> Result<PupilTransfer> {
        let (h, az) = self.frame.field_point(row, col);
        let (turning, fixed) = self.wavefront_at(h);
        PupilTransfer::compute_at_azimuth(
            &self.pupil,
            &turning,
            &fixed,
            az,
            self.model.reference_wavelength_m(),
            lambda_m,
            self.diameter_m,
            sampling,
        )
    }

    /// The pupil PSF at padded-frame position (row, col) and wavelength `lambda_m` with
    /// `samples` across the pupil (the same sampling for every point).
    fn psf_at(&self, row: f64, col: f64, lambda_m: f64, samples: usize) -> Result<Array2<f64>> {
        let sampling = Sampling {
            samples_across: samples,
            padding: 2,
        };
        Ok(self
            .transfer_at(row, col, lambda_m, sampling)?
            .psf()
            .clone())
    }

    /// The largest point-source error of a `g × g` zone grid against the exact PSF at the
    /// cell centres and edge midpoints, as a fraction of the exact PSF's peak.
    fn grid_error(&self, g: usize, lambda_m: f64) -> Result<f64> {
        // Node index coordinates (ty, tx) of the sample points; g = 1 samples the corners.
        let mut points: Vec<(f64, f64)> = Vec::new();
        if g == 1 {
            points.extend([(0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (1.0, 1.0)]);
        } else {
            for i in 0..g {
                for j in 0..g {
                    let (a, b) = (i as f64, j as f64);
                    if i + 1 < g {
                        points.push((a + 0.5, b));
                    }
                    if j + 1 < g {
                        points.push((a, b + 0.5));
                    }
                    if i + 1 < g && j + 1 < g {
                        points.push((a + 0.5, b + 0.5));
                    }
                }
            }
        }
        let pos = |ty: f64, tx: f64| {
            if g == 1 {
                (self.frame.node(0, ty, 2), self.frame.node(1, tx, 2))
            } else {
                (self.frame.node(0, ty, g), self.frame.node(1, tx, g))
            }
        };
        // A common pupil sampling: the steepest wavefront at the nodes and points.
        let mut samples = CRITERION_SAMPLES;
        let all: Vec<(f64, f64)> = (0..g * g)
            .map(|k| ((k / g) as f64, (k % g) as f64))
            .chain(points.iter().copied())
            .collect();
        for &(ty, tx) in &all {
            let (r, c) = pos(ty, tx);
            samples =
                samples.max(self.samples_for(self.frame.field_point(r, c).0, lambda_m, samples)?);
        }
        let psfs: Vec<Array2<f64>> = all
            .par_iter()
            .map(|&(ty, tx)| {
                let (r, c) = pos(ty, tx);
                self.psf_at(r, c, lambda_m, samples)
            })
            .collect::<Result<Vec<_>>>()?;
        let (nodes, exact) = psfs.split_at(g * g);
        if g == 1 {
            // One zone: its centre PSF against the corners'.
            return Ok(exact
                .iter()
                .map(|e| relative_difference(e, &nodes[0]))
                .fold(0.0, f64::max));
        }
        let errors: Vec<f64> = points
            .par_iter()
            .zip(exact)
            .map(|(&(ty, tx), e)| {
                let mut blend = Array2::<f64>::zeros(e.raw_dim());
                for (k, p) in nodes.iter().enumerate() {
                    let (i, j) = (k / g, k % g);
                    let w = (1.0 - (ty - i as f64).abs()).max(0.0)
                        * (1.0 - (tx - j as f64).abs()).max(0.0);
                    if w > 0.0 {
                        blend.scaled_add(w, p);
                    }
                }
                relative_difference(e, &blend)
            })
            .collect();
        Ok(errors.into_iter().fold(0.0, f64::max))
    }

    /// Zone k's OTF at angular frequency (fx ≥ 0, fy) cycles/rad for a band at
    /// `wavelength_um`: the wavelength nodes interpolated linearly in s = λ_ref/λ. (The
    /// imaging loop uses [`FieldOptics::band_taps`] and [`FieldOptics::tapped`], the same
    /// arithmetic with the taps computed once per band.)
    #[cfg_attr(not(test), allow(dead_code))]
    fn otf_at(
        &self,
        k: usize,
        node: (usize, f64),
        fx: f64,
        fy: f64,
        wavelength_um: f64,
    ) -> Complex64 {
        let scale = wavelength_um * 1e-6 / self.diameter_m;
        let (x, y) = (fx * scale, fy * scale);
        let (j, t) = node;
        let a = self.otfs[k][j].at(x, y);
        if t == 0.0 {
            a
        } else {
            a * (1.0 - t) + self.otfs[k][j + 1].at(x, y) * t
        }
    }

    /// The bilinear taps of a band at `wavelength_um` on the half-plane grid `fx` (≥ 0),
    /// `fy` (cycles/rad): the same normalised frequencies `X = fx λ/D`, `Y = fy λ/D` as
    /// [`FieldOptics::otf_at`], computed once per band instead of once per sample, zone
    /// and node.
    fn band_taps(&self, fx: &[f64], fy: &[f64], wavelength_um: f64) -> BandTaps {
        let scale = wavelength_um * 1e-6 / self.diameter_m;
        BandTaps {
            rows: fy.iter().map(|f| self.window.row_tap(f * scale)).collect(),
            cols: fx
                .iter()
                .map(|f| self.window.column_tap(f * scale))
                .collect(),
        }
    }

    /// Zone k's OTF between the taps `row` and `col` of a band in node bracket `node`:
    /// [`FieldOptics::otf_at`] at the frequency the taps were made for, to the bit.
    #[inline]
    fn tapped(&self, k: usize, node: (usize, f64), row: Tap, col: Tap) -> Complex64 {
        let (j, t) = node;
        let v = self.otfs[k][j].tapped(row, col);
        let a = Complex64::new(v.re as f64, v.im as f64);
        if t == 0.0 {
            a
        } else {
            let v = self.otfs[k][j + 1].tapped(row, col);
            a * (1.0 - t) + Complex64::new(v.re as f64, v.im as f64) * t
        }
    }

    /// The node bracket (j, t) of a band: s between node j and j + 1 at fraction t.
    fn node_of(&self, wavelength_um: f64) -> (usize, f64) {
        let s = self.model.reference_wavelength_m() / (wavelength_um * 1e-6);
        let n = self.node_scale.len();
        if n == 1 {
            return (0, 0.0);
        }
        if let Some(j) = self
            .node_scale
            .iter()
            .position(|v| (v - s).abs() <= 1e-12 * s)
        {
            return (j, 0.0);
        }
        let j = self.node_scale.partition_point(|v| *v <= s).clamp(1, n - 1) - 1;
        let t = ((s - self.node_scale[j]) / (self.node_scale[j + 1] - self.node_scale[j]))
            .clamp(0.0, 1.0);
        (j, t)
    }
}

impl Imager {
    /// The pupil transfer functions of `[optics.wavefront]` as `report.json` records them
    /// (zones, their error, wavelength nodes); `None` without the section.
    pub fn wavefront_report(&self) -> Option<&WavefrontImagingReport> {
        self.field.as_ref().map(|f| f.report())
    }
}

/// The cascade the tables of `sensor`'s imaging chain are built from when it has
/// `[optics.wavefront]`: `otf` without the aperture components, which the pupil's OTF
/// replaces ([`SystemOtf::without_aperture`]); `None` (the cascade itself) without it.
pub(super) fn cascade_beside_pupil(sensor: &Sensor, otf: &SystemOtf) -> Option<SystemOtf> {
    sensor
        .optics
        .wavefront
        .is_some()
        .then(|| otf.without_aperture())
}

/// `max |a − b| / max a`.
fn relative_difference(a: &Array2<f64>, b: &Array2<f64>) -> f64 {
    let peak = a.iter().cloned().fold(0.0, f64::max);
    let d = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    if peak > 0.0 {
        d / peak
    } else {
        0.0
    }
}

/// `w_b · C_b(f)` on the half plane `[fy][fx]`: the spectral weight times the rest of the
/// cascade (achromatic product with the scene-grid taper, and the chromatic components
/// left beside the pupil: turbulence, aerosol), written into `out` (reused across bands).
fn cascade_rest(imager: &Imager, wavelength_um: f64, weight: f64, out: &mut Vec<f64>) {
    let profile = imager.band_profile(wavelength_um);
    let (ny, hc) = imager.fft.spectrum_shape();
    out.resize(ny * hc, 0.0);
    out.par_chunks_mut(hc).enumerate().for_each(|(v, row)| {
        for (u, o) in row.iter_mut().enumerate() {
            *o = weight * imager.radial.achromatic(u, v) * profile.eval(imager.radial.rho(u, v));
        }
    });
}

/// Images frame `frame` through the zones (the engine's [`Imager::with_spectrum`] when
/// the sensor has `[optics.wavefront]`): per band, per zone, the source weighted by the
/// zone's tent, padded, transformed (f64), multiplied by the zone's OTF and the rest of
/// the cascade, and added; then `finish` on the band-summed spectrum (transposed layout).
/// Bands and zones in a fixed order, each sample by one worker: the same result for any
/// number of threads.
///
/// Cost (docs/field-optics.md, "Speed"). The tents are separable, `t_k = t_i(y) t_j(x)`,
/// and a row transform is linear, so the row spectra of `t_k ⊙ L` are those of
/// `t_j(x) ⊙ L` scaled row by row by `t_i(y)`: per band g row passes (not g²) and g²
/// column passes. The OTF lookups use taps computed once per band
/// ([`FieldOptics::band_taps`]). With one zone the band is transformed as before, with no
/// tent.
pub(super) fn image_with_zones<R>(
    imager: &Imager,
    field: &FieldOptics,
    reader: &mut dyn CubeReader,
    frame: usize,
    mut progress: impl FnMut(usize, usize),
    finish: impl FnOnce(&mut [Complex64]) -> Result<R>,
) -> Result<(R, ImagingStats)> {
    let (ny, hc) = imager.fft.spectrum_shape();
    let nx = imager.fft.shape().1;
    let mut stats = ImagingStats {
        padded_shape: (ny, nx),
        precision: super::fft::FftPrecision::F64,
        wavefront: Some(Box::new(field.report.clone())),
        ..Default::default()
    };
    let active = imager.weights.active_bands();
    let g = field.per_axis;
    let mut acc = vec![Complex64::new(0.0, 0.0); ny * hc];
    let mut spec = Array2::<Complex64>::zeros((ny, hc));
    let mut scratch = Vec::new();
    let mut rest = Vec::new();
    let tent_y: Vec<Vec<f64>> = (0..g)
        .map(|i| {
            (0..ny)
                .map(|r| field.frame.tent(0, i, g, r as f64))
                .collect()
        })
        .collect();
    let tent_x: Vec<Vec<f64>> = (0..g)
        .map(|j| {
            (0..nx)
                .map(|c| field.frame.tent(1, j, g, c as f64))
                .collect()
        })
        .collect();
    // The row spectra of the band weighted by each column tent (g > 1).
    let mut by_column_tent: Vec<Vec<Complex64>> = if g > 1 {
        vec![vec![Complex64::new(0.0, 0.0); ny * hc]; g]
    } else {
        Vec::new()
    };
    let fx = &imager.grid.fx;
    let fy = &imager.grid.fy;
    for (done, &b) in active.iter().enumerate() {
        let t0 = Instant::now();
        let planes = reader.read_planes(frame, &[b])?;
        let views = planes.views();
        let plane = views.first().ok_or_else(|| {
            Error::OutOfRange(format!("the reader returned no plane for band {b}"))
        })?;
        stats.read_s += t0.elapsed().as_secs_f64();
        let lambda = imager.weights.wavelength_um[b];
        cascade_rest(
            imager,
            lambda,
            imager.weights.electrons_per_unit[b],
            &mut rest,
        );
        let node = field.node_of(lambda);
        let taps = field.band_taps(fx, fy, lambda);
        // Columns beyond the last tap are beyond the OTF's support (fx grows with u).
        let u_end = taps
            .cols
            .iter()
            .rposition(Option::is_some)
            .map_or(0, |u| u + 1);
        let t1 = Instant::now();
        if g > 1 {
            by_column_tent
                .par_iter_mut()
                .zip(&tent_x)
                .for_each(|(out, tx)| {
                    imager.fft.rows_forward(
                        |r, row: &mut [f64]| {
                            imager.pad.row(plane, r, row);
                            for (v, wx) in row.iter_mut().zip(tx) {
                                *v *= wx;
                            }
                        },
                        out,
                    )
                });
        }
        stats.fft_s += t1.elapsed().as_secs_f64();
        for k in 0..g * g {
            let t1 = Instant::now();
            if g == 1 {
                imager.fft.forward_rows(
                    |r, row: &mut [f64]| imager.pad.row(plane, r, row),
                    &mut spec,
                    &mut scratch,
                );
            } else {
                let (ty, rows) = (&tent_y[k / g], &by_column_tent[k % g]);
                let s = spec.as_slice_mut().expect("standard layout");
                s.par_chunks_mut(hc)
                    .zip(rows.par_chunks(hc))
                    .zip(ty.par_iter())
                    .for_each(|((o, i), &wy)| {
                        if wy == 0.0 {
                            o.fill(Complex64::new(0.0, 0.0));
                        } else {
                            for (o, i) in o.iter_mut().zip(i) {
                                *o = i * wy;
                            }
                        }
                    });
                imager.fft.columns_in_place(s, false);
            }
            let t2 = Instant::now();
            let s = spec.as_slice().expect("standard layout");
            acc.par_chunks_mut(hc)
                .zip(s.par_chunks(hc))
                .zip(rest.par_chunks(hc))
                .zip(taps.rows.par_iter())
                .for_each(|(((a, sp), c), row)| {
                    let Some(row) = *row else {
                        return;
                    };
                    for (u, col) in taps.cols[..u_end].iter().enumerate() {
                        if let (Some(col), true) = (col, c[u] != 0.0) {
                            a[u] += sp[u] * c[u] * field.tapped(k, node, row, *col);
                        }
                    }
                });
            stats.fft_s += (t2 - t1).as_secs_f64();
            stats.otf_s += t2.elapsed().as_secs_f64();
        }
        stats.bands_used += 1;
        progress(done + 1, active.len());
    }
    let t0 = Instant::now();
    let mut acc_t = transposed(&acc, ny, hc);
    let r = finish(&mut acc_t);
    stats.inverse_s = t0.elapsed().as_secs_f64();
    Ok((r?, stats))
}

/// `[v][u]` (rows ny, cols hc) → `[u][v]`.
fn transposed(acc: &[Complex64], ny: usize, hc: usize) -> Vec<Complex64> {
    let mut t = vec![Complex64::new(0.0, 0.0); ny * hc];
    for v in 0..ny {
        for u in 0..hc {
            t[u * ny + v] = acc[v * hc + u];
        }
    }
    t
}

/// The slow exact reference: every scene sample blurred by the PSF of its own field
/// position (its pupil OTF at its own H and azimuth, at each band's own wavelength, times
/// the rest of the cascade), summed in the frequency domain
/// (`E(f) = Σ_b w_b C_b(f) Σ_s L_b(s) e^{−2πi f·s} OTF(f; s, λ_b)`), then sampled onto the
/// detector as the engine samples. The sources are the samples of the padded frame the
/// engine transforms ([`Imager::padded_band`]: the scene and the mirror extensions its
/// padding adds beyond the scene's edges, each at its own field position, H held at 1
/// beyond the field), so the reference and the engine image the same periodic frame.
/// Samples with zero radiance are skipped. One pupil computation per non-zero sample and
/// band: for small images and tests only.
///
/// Errors: the imager has no `[optics.wavefront]`, or a reader error.
pub fn direct_summation(
    imager: &Imager,
    reader: &mut dyn CubeReader,
    frame: usize,
) -> Result<Array2<f64>> {
    let Some(field) = &imager.field else {
        return Err(Error::param(
            "optics.wavefront",
            "absent",
            "a sensor with [optics.wavefront] for direct space-variant summation",
        ));
    };
    let (ny, hc) = imager.fft.spectrum_shape();
    let nx = imager.fft.shape().1;
    let mut acc = vec![Complex64::new(0.0, 0.0); ny * hc];
    let sampling = Sampling {
        samples_across: field.report.pupil_samples_across,
        padding: 2,
    };
    let mut rest = Vec::new();
    for &b in &imager.weights.active_bands() {
        let planes = reader.read_planes(frame, &[b])?;
        let views = planes.views();
        let Some(plane) = views.first() else {
            continue;
        };
        let frame_plane = imager.padded_band(plane.view());
        let lambda = imager.weights.wavelength_um[b];
        cascade_rest(
            imager,
            lambda,
            imager.weights.electrons_per_unit[b],
            &mut rest,
        );
        for ((r, c), &l) in frame_plane.indexed_iter() {
            if l == 0.0 {
                continue;
            }
            let (row, col) = (r as f64, c as f64);
            let t = field.transfer_at(row, col, lambda * 1e-6, sampling)?;
            let ex: Vec<Complex64> = (0..hc)
                .map(|u| Complex64::from_polar(1.0, -TAU * u as f64 * col / nx as f64))
                .collect();
            let ey: Vec<Complex64> = (0..ny)
                .map(|v| Complex64::from_polar(1.0, -TAU * v as f64 * row / ny as f64))
                .collect();
            let grid = &imager.grid;
            acc.par_chunks_mut(hc)
                .zip(rest.par_chunks(hc))
                .enumerate()
                .for_each(|(v, (a, cr))| {
                    for u in 0..hc {
                        if cr[u] != 0.0 {
                            a[u] += ey[v]
                                * ex[u]
                                * (l * cr[u])
                                * t.at_cy_per_rad(grid.fx[u], grid.fy[v]);
                        }
                    }
                });
        }
    }
    let mut acc_t = transposed(&acc, ny, hc);
    Ok(imager.detector_image_transposed(&mut acc_t))
}
