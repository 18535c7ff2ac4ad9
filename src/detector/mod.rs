//! The detector: mean photo-electrons per pixel → digital numbers (docs/design.md §1).
//!
//! [`DetectorModel::build`] (called by [`crate::sensor::Sensor::build`], which validates the
//! whole sensor first) resolves the `[detector]` table ([`DetectorConfig`]: dark current,
//! background, noise switches, loaded maps) and fixes the conversion gain K (configured,
//! full well → full scale, or `[detector.auto_gain]`; for `reference = "scene_mean"` the
//! gain stays *pending* until the run knows the scene's mean signal).
//! [`DetectorInstance::new`] draws the fixed-pattern maps of one physical sensor from a
//! seed, and [`DetectorInstance::expose`] turns one frame of mean electrons (the output of
//! [`crate::imaging`]) into DN. Per pixel, in this order (each step a small pure function
//! in this module):
//!
//! 1. mean total `μ = max(signal, 0) + dark + background` electrons ([`mean_total_e`]);
//! 2. shot noise: ONE Poisson draw of μ ([`shot`]; a sum of independent Poisson counts is
//!    Poisson, docs/design.md §1; FOI report eq. 2.24–2.28);
//! 3. full-well clip ([`clip_full_well`]; FOI report §2.2.2.1: a saturated pixel holds
//!    μ_e,sat with no variance);
//! 4. fixed pattern: `e·g + o` with the gain g (1 + PRNU) and offset o (DSNU, column, row,
//!    measured maps) of the pixel ([`apply_fpn`]; FOI report eq. 2.38, 2.46);
//! 5. nonlinearity `e + a·e²` ([`apply_nonlinearity`]);
//! 6. Gaussian read noise (FOI report eq. 2.32);
//! 7. conversion `DN = K·e + offset_dn` (FOI report eq. 2.33);
//! 8. ADC: round to the nearest integer, clip to [0, 2^bits − 1] ([`adc`]);
//! 9. defects: dead → 0, hot → 2^bits − 1, stuck → a fixed random DN.
//!
//! Randomness follows docs/design.md §3 (see the `rng` submodule): one seed, one stream per
//! effect, per exposure and frame (temporal effects) and per row, so the fixed pattern is
//! identical in every frame, switching one effect does not change another's realisation,
//! the same seed gives bit-identical frames and the result does not depend on the number of threads.
//!
//! The expected temporal noise for a mean signal (for NETD and SNR) is
//! [`DetectorModel::temporal_noise_e`] / [`DetectorModel::temporal_noise_dn`].

pub mod config;
pub mod drift;
mod fpn;
mod gain;
pub mod ipc;
pub mod memory;
pub mod persistence;
mod poisson;
pub mod readout;
pub(crate) mod rng;
pub mod rts;
mod staged;

use std::path::Path;

use ndarray::{Array2, ArrayView1};
use rand::RngExt;
use rand_distr::{Distribution, Poisson, StandardNormal};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::io::raster;
use crate::radiometry::CameraEquation;
use crate::spectrum::{resolve_path as resolve, Spectrum};

pub use config::{
    AutoGainConfig, AutoGainReference, BackgroundConfig, DarkModelConfig, DefectsConfig,
    DetectorConfig, FpnConfig, NonlinearityConfig,
};
pub use gain::{background_electrons, reference_electrons, REFLECTIVE_LIMIT_UM};
pub use staged::FrameExtras;

use rng::{temporal_stream, Effect};

/// Standard deviations above the full well beyond which a Poisson draw can no longer fall
/// below it (probability < 1e-300); such pixels are set to the full well without drawing.
const POISSON_SATURATION_SIGMAS: f64 = 40.0;

/// Code of a pixel in the defect map.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Defect {
    /// A working pixel (code 0).
    Ok = 0,
    /// Always reads 0 DN (code 1).
    Dead = 1,
    /// Always reads full scale 2^bits − 1 (code 2).
    Hot = 2,
    /// Always reads one fixed DN, drawn uniformly over the ADC range (code 3).
    Stuck = 3,
}

impl Defect {
    /// The defect of a map code (0–3), `None` for any other value.
    pub fn from_code(code: u16) -> Option<Defect> {
        match code {
            0 => Some(Defect::Ok),
            1 => Some(Defect::Dead),
            2 => Some(Defect::Hot),
            3 => Some(Defect::Stuck),
            _ => None,
        }
    }
}

/// The resolved detector of a sensor: every switch and constant of the electrons → DN
/// conversion, with any measured maps loaded, and the conversion gain fixed.
#[derive(Debug, Clone)]
pub struct DetectorModel {
    rows: usize,
    cols: usize,
    full_well_e: f64,
    max_dn: f64,
    offset_dn: f64,
    gain_dn_per_e: f64,
    integration_time_s: f64,
    dark_e: f64,
    background_e: f64,
    shot_noise: bool,
    read_noise_e: f64,
    fpn: Option<config::FpnConfig>,
    gain_file: Option<Array2<f64>>,
    offset_file: Option<Array2<f64>>,
    nonlinearity: Option<config::NonlinearityConfig>,
    defects: Option<config::DefectsConfig>,
    defect_file: Option<Array2<u8>>,
    readout_noise: Option<readout::ReadoutNoiseConfig>,
    ipc_kernel: Option<[[f64; 3]; 3]>,
    rts: Option<rts::RtsConfig>,
    persistence: Option<persistence::PersistenceConfig>,
    drift: Option<drift::DriftConfig>,
    auto_gain_reference: Option<(AutoGainReference, f64)>,
    scene_gain_pending: Option<f64>,
    warnings: Vec<String>,
}

/// What the detector model needs from the rest of a sensor, resolved once by
/// [`crate::sensor::Sensor::build`].
#[derive(Debug, Clone, Copy)]
pub struct DetectorInputs<'a> {
    /// The whole spectral chain τ_filter·τ_optics·τ_atm·η (auto-gain references).
    pub response: &'a Spectrum,
    /// τ_filter·η only: what the optics' own emission passes (`[detector.background]`).
    pub filter_qe: &'a Spectrum,
    /// The camera equation of the sensor (docs/design.md §4.1).
    pub camera: &'a CameraEquation,
    /// Directory that relative map paths (`fpn.gain_map`, …) are resolved against.
    pub base_dir: &'a Path,
}

impl DetectorModel {
    /// Resolves the (already validated) `[detector]` table `d`: computes the dark and
    /// background electrons per frame, loads measured maps (paths relative to
    /// `inputs.base_dir`) and fixes the conversion gain: `gain_dn_per_e` if given, else the
    /// `[detector.auto_gain]` reference ([`reference_electrons`]) if present, else full
    /// well → full scale. With `reference = "scene_mean"` the gain is pending
    /// ([`DetectorModel::scene_mean_gain_fraction`]) and K stands at the full-well value
    /// until [`DetectorModel::set_gain_from_scene_mean`] fixes it.
    ///
    /// Only [`crate::sensor::Sensor::build`] calls this: it is the one place that reads
    /// the files a sensor refers to.
    pub fn build(d: &DetectorConfig, inputs: &DetectorInputs) -> Result<Self> {
        let dark_e = gain::dark_e_per_frame(d);
        let background_e = background_electrons(d, inputs.filter_qe, inputs.camera)?;
        let dims = (d.rows, d.cols);
        let base = inputs.base_dir;
        let mut gain_file = None;
        let mut offset_file = None;
        if let Some(f) = &d.fpn {
            if let Some(p) = &f.gain_map {
                let m = read_map_f32(&resolve(base, p), dims, "detector.fpn.gain_map")?;
                if let Some(v) = m.iter().find(|v| !(v.is_finite() && **v >= 0.0)) {
                    return Err(Error::format(
                        resolve(base, p),
                        format!("detector.fpn.gain_map: relative gains must be finite and >= 0, found {v}"),
                    ));
                }
                gain_file = Some(m);
            }
            if let Some(p) = &f.offset_map {
                let m = read_map_f32(&resolve(base, p), dims, "detector.fpn.offset_map")?;
                if let Some(v) = m.iter().find(|v| !v.is_finite()) {
                    return Err(Error::format(
                        resolve(base, p),
                        format!("detector.fpn.offset_map: offsets (electrons) must be finite, found {v}"),
                    ));
                }
                offset_file = Some(m);
            }
        }
        let mut defect_file = None;
        if let Some(p) = d.defects.as_ref().and_then(|x| x.map.as_ref()) {
            let path = resolve(base, p);
            let m = raster::read_tiff_u16(&path)?;
            check_dims(&path, m.dim(), dims, "detector.defects.map")?;
            if let Some(v) = m.iter().find(|v| Defect::from_code(**v).is_none()) {
                return Err(Error::format(
                    &path,
                    format!("detector.defects.map: code {v} is not a defect code (0 ok, 1 dead, 2 hot, 3 stuck)"),
                ));
            }
            defect_file = Some(m.mapv(|v| v as u8));
        }
        let mut model = DetectorModel {
            rows: d.rows,
            cols: d.cols,
            full_well_e: d.full_well_e,
            max_dn: d.max_dn().min(u16::MAX as f64),
            offset_dn: d.offset_dn,
            gain_dn_per_e: d.manual_gain(),
            integration_time_s: d.integration_time_s,
            dark_e,
            background_e,
            shot_noise: d.shot_noise.unwrap_or(true),
            read_noise_e: d.read_noise_e.unwrap_or(0.0),
            fpn: d.fpn.clone(),
            gain_file,
            offset_file,
            nonlinearity: d.nonlinearity.clone(),
            defects: d.defects.clone(),
            defect_file,
            readout_noise: d.readout_noise.clone(),
            ipc_kernel: d.ipc.as_ref().map(ipc::ipc_kernel),
            rts: d.rts.clone(),
            persistence: d.persistence.clone(),
            drift: d.drift.clone(),
            auto_gain_reference: None,
            scene_gain_pending: None,
            warnings: Vec::new(),
        };
        if let Some(a) = &d.auto_gain {
            let (k, kind, e_ref) = model.auto_gain_for(d, inputs.response, inputs.camera, a)?;
            let e_total = e_ref + dark_e + background_e;
            // With `scene_mean` the full well only stands in until the scene is imaged
            // ([`DetectorModel::set_gain_from_scene_mean`] checks the real mean).
            if e_total >= d.full_well_e && kind != AutoGainReference::SceneMean {
                model.warnings.push(format!(
                    "detector.auto_gain: the reference scene gives {e_total:.4e} e-, beyond the full well ({:.4e} e-); K is set for the full well",
                    d.full_well_e
                ));
            }
            model.gain_dn_per_e = k;
            if kind == AutoGainReference::SceneMean {
                model.scene_gain_pending = Some(a.fraction);
            } else {
                model.auto_gain_reference = Some((kind, e_ref));
            }
        }
        if model.gain_dn_per_e * model.full_well_e + model.offset_dn < 0.5 * model.max_dn
            && model.gain_dn_per_e > 0.0
        {
            model.warnings.push(format!(
                "detector: the full well ({:.4e} e-) reaches only {:.0} of {} DN: the ADC range is under-used",
                model.full_well_e,
                model.gain_dn_per_e * model.full_well_e + model.offset_dn,
                model.max_dn
            ));
        }
        Ok(model)
    }

    /// `true` when an effect couples pixels within a frame (inter-pixel capacitance,
    /// readout-ordered noise, crosstalk between outputs): the frame is then exposed in
    /// whole-frame stages ([`staged`]) rather than row by row.
    pub fn couples_pixels(&self) -> bool {
        self.ipc_kernel.is_some() || self.readout_noise.is_some()
    }

    /// The focal-plane effects with a memory across a sequence (RTS pixels, persistence,
    /// drift of the fixed pattern): `(rts, persistence, drift)`, each `None` when off.
    pub fn memory_effects(
        &self,
    ) -> (
        Option<&rts::RtsConfig>,
        Option<&persistence::PersistenceConfig>,
        Option<&drift::DriftConfig>,
    ) {
        (
            self.rts.as_ref(),
            self.persistence.as_ref(),
            self.drift.as_ref(),
        )
    }

    /// The readout-ordered noise and crosstalk configuration, if any.
    pub fn readout_noise(&self) -> Option<&readout::ReadoutNoiseConfig> {
        self.readout_noise.as_ref()
    }

    /// The inter-pixel capacitance kernel, if any (Kannawadi et al. 2016).
    pub fn ipc_kernel(&self) -> Option<&[[f64; 3]; 3]> {
        self.ipc_kernel.as_ref()
    }

    /// The conversion gain K that the auto-gain reference `a` gives this model (its dark,
    /// background, full well, nonlinearity and ADC range): the reference's signal
    /// electrons ([`reference_electrons`] through `response` and `camera`) plus dark and
    /// background land at `a.fraction` of the range above the offset. Returns
    /// `(K, reference used, reference signal electrons)`.
    ///
    /// Errors: a reference without signal in the band.
    pub fn auto_gain_for(
        &self,
        d: &DetectorConfig,
        response: &Spectrum,
        camera: &CameraEquation,
        a: &AutoGainConfig,
    ) -> Result<(f64, AutoGainReference, f64)> {
        let (kind, e_ref) = reference_electrons(d, response, camera, a)?;
        let e_total = e_ref + self.dark_e + self.background_e;
        Ok((gain::gain_for(self, a.fraction, e_total)?, kind, e_ref))
    }

    /// Number of pixel rows.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Number of pixel columns.
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// Conversion gain K, DN per electron.
    pub fn gain_dn_per_e(&self) -> f64 {
        self.gain_dn_per_e
    }

    /// Black level added after conversion, DN.
    pub fn offset_dn(&self) -> f64 {
        self.offset_dn
    }

    /// Largest DN of the ADC, 2^bits − 1.
    pub fn max_dn(&self) -> f64 {
        self.max_dn
    }

    /// Full-well capacity, electrons.
    pub fn full_well_e(&self) -> f64 {
        self.full_well_e
    }

    /// Integration (exposure) time, s.
    pub fn integration_time_s(&self) -> f64 {
        self.integration_time_s
    }

    /// The temporal-noise exposure key [`DetectorInstance::expose`] uses: the bit pattern
    /// of the integration time, so runs at different exposure times draw independent
    /// noise (see the `rng` submodule).
    pub fn exposure_key(&self) -> u64 {
        self.integration_time_s.to_bits()
    }

    /// Mean dark electrons per pixel per frame (dark current × integration time).
    pub fn dark_e(&self) -> f64 {
        self.dark_e
    }

    /// Mean optics self-emission electrons per pixel per frame.
    pub fn background_e(&self) -> f64 {
        self.background_e
    }

    /// Read noise, electrons rms (0 = off).
    pub fn read_noise_e(&self) -> f64 {
        self.read_noise_e
    }

    /// Whether Poisson shot noise is drawn.
    pub fn shot_noise(&self) -> bool {
        self.shot_noise
    }

    /// While K is still to be set from the imaged scene (`reference = "scene_mean"`, before
    /// [`DetectorModel::set_gain_from_scene_mean`]): the fraction of the range the scene
    /// mean should reach. `None` once K is fixed.
    pub fn scene_mean_gain_fraction(&self) -> Option<f64> {
        self.scene_gain_pending
    }

    /// Sets K so that a pixel receiving `mean_signal_e` signal electrons (plus dark and
    /// background) lands at `fraction` of the range above the offset (the same rule as the
    /// other auto-gain references).
    pub fn set_gain_from_scene_mean(&mut self, mean_signal_e: f64, fraction: f64) -> Result<()> {
        let e_total = mean_signal_e + self.dark_e + self.background_e;
        if e_total >= self.full_well_e {
            self.warnings.push(format!(
                "detector.auto_gain: the scene mean gives {e_total:.4e} e-, beyond the full well ({:.4e} e-); K is set for the full well",
                self.full_well_e
            ));
        }
        self.gain_dn_per_e = gain::gain_for(self, fraction, e_total)?;
        self.auto_gain_reference = Some((AutoGainReference::SceneMean, mean_signal_e));
        self.scene_gain_pending = None;
        Ok(())
    }

    /// The auto-gain reference used and its mean signal electrons (without dark and
    /// background), when K came from `[detector.auto_gain]`.
    pub fn auto_gain_reference(&self) -> Option<(AutoGainReference, f64)> {
        self.auto_gain_reference
    }

    /// Things that are valid but probably not intended (saturating auto-gain reference,
    /// unused ADC range).
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// Expected temporal noise in electrons rms for a mean signal of `mean_signal_e`
    /// electrons: `√(μ + σ_r²)` with μ = signal + dark + background the Poisson mean (FOI
    /// report eq. 2.34, σ_e² = μ_e) when shot noise is on, σ_r the read noise. Fixed
    /// pattern, nonlinearity, saturation and quantisation are not included.
    pub fn temporal_noise_e(&self, mean_signal_e: f64) -> f64 {
        let shot = if self.shot_noise {
            mean_total_e(mean_signal_e, self.dark_e, self.background_e)
        } else {
            0.0
        };
        (shot + self.read_noise_e * self.read_noise_e).sqrt()
    }

    /// Expected temporal noise in DN rms: `K · temporal_noise_e` (FOI report eq. 2.34).
    /// Add [`DetectorModel::quantisation_noise_dn`] in quadrature for the ADC's share.
    pub fn temporal_noise_dn(&self, mean_signal_e: f64) -> f64 {
        self.gain_dn_per_e * self.temporal_noise_e(mean_signal_e)
    }

    /// rms of the rounding error of an ideal ADC, 1/√12 DN (uniform error over one step).
    pub fn quantisation_noise_dn(&self) -> f64 {
        1.0 / 12f64.sqrt()
    }

    /// Expected DN of a pixel with unit gain, zero offset and the mean nonlinearity for a
    /// mean signal of `mean_signal_e` electrons, before rounding, clipped to the ADC range:
    /// `K · n(min(signal + dark + background, full well)) + offset_dn`.
    pub fn expected_dn(&self, mean_signal_e: f64) -> f64 {
        let e = clip_full_well(
            mean_total_e(mean_signal_e, self.dark_e, self.background_e),
            self.full_well_e,
        );
        let a = self
            .nonlinearity
            .as_ref()
            .map_or(0.0, |n| n.quadratic_mean_per_e);
        (self.gain_dn_per_e * apply_nonlinearity(e, a) + self.offset_dn).clamp(0.0, self.max_dn)
    }
}

/// One physical sensor: a [`DetectorModel`] with its fixed-pattern and defect maps drawn
/// from a seed.
#[derive(Debug, Clone)]
pub struct DetectorInstance {
    model: DetectorModel,
    seed: u64,
    gain: Option<Array2<f64>>,
    offset_e: Option<Array2<f64>>,
    quadratic: Option<Array2<f64>>,
    defects: Array2<u8>,
    stuck_dn: Option<Array2<u16>>,
}

impl DetectorInstance {
    /// Draws the maps of one sensor from `seed` (each effect from its own stream; see the
    /// module documentation): gain `(1 + σ_g z_g)·G_file` (clipped at 0), offset
    /// `σ_o(ρ z_g + √(1−ρ²) z_o) + c_col + r_row + O_file` electrons, quadratic
    /// coefficients `a ~ N(μ_a, σ_a²)`, and defects.
    pub fn new(model: &DetectorModel, seed: u64) -> Result<Self> {
        let (rows, cols) = (model.rows, model.cols);
        let (gain, offset_e) = fixed_pattern(model, seed);
        let quadratic = model.nonlinearity.as_ref().and_then(|n| {
            if n.quadratic_mean_per_e == 0.0 && n.quadratic_sigma_per_e == 0.0 {
                None
            } else if n.quadratic_sigma_per_e == 0.0 {
                Some(Array2::from_elem((rows, cols), n.quadratic_mean_per_e))
            } else {
                let mut z = fpn::unit_field(seed, Effect::Nonlinearity, rows, cols, 0.0);
                z.mapv_inplace(|v| n.quadratic_mean_per_e + n.quadratic_sigma_per_e * v);
                Some(z)
            }
        });
        let defects = defect_map(model, seed);
        let stuck_dn = if defects.iter().any(|c| *c == Defect::Stuck as u8) {
            let levels = model.max_dn + 1.0;
            let u = fpn::par_rows(rows, cols, |i| {
                fpn::uniform_row(seed, Effect::StuckValue, i, cols)
            });
            Some(u.mapv(|v| (v * levels).floor().min(model.max_dn) as u16))
        } else {
            None
        };
        Ok(DetectorInstance {
            model: model.clone(),
            seed,
            gain,
            offset_e,
            quadratic,
            defects,
            stuck_dn,
        })
    }

    /// The model this instance was drawn from.
    pub fn model(&self) -> &DetectorModel {
        &self.model
    }

    /// The seed the maps were drawn from (temporal noise uses it too).
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Relative gain of every pixel (1 everywhere when no gain non-uniformity is set).
    pub fn gain_map(&self) -> Array2<f64> {
        self.gain
            .clone()
            .unwrap_or_else(|| Array2::ones((self.model.rows, self.model.cols)))
    }

    /// The gain, offset (electrons) and quadratic-coefficient maps as stored, without a
    /// copy: `None` where the pattern is off (gain 1, offset 0, coefficient 0 everywhere;
    /// [`DetectorInstance::gain_map`] and its siblings return those as arrays).
    pub fn stored_maps(&self) -> [Option<&Array2<f64>>; 3] {
        [
            self.gain.as_ref(),
            self.offset_e.as_ref(),
            self.quadratic.as_ref(),
        ]
    }

    /// Offset of every pixel, electrons (0 everywhere when no offset pattern is set).
    pub fn offset_map_e(&self) -> Array2<f64> {
        self.offset_e
            .clone()
            .unwrap_or_else(|| Array2::zeros((self.model.rows, self.model.cols)))
    }

    /// Quadratic nonlinearity coefficient of every pixel, per electron (0 when off).
    pub fn quadratic_map_per_e(&self) -> Array2<f64> {
        self.quadratic
            .clone()
            .unwrap_or_else(|| Array2::zeros((self.model.rows, self.model.cols)))
    }

    /// Defect code of every pixel ([`Defect`] as u8: 0 ok, 1 dead, 2 hot, 3 stuck).
    pub fn defect_map(&self) -> &Array2<u8> {
        &self.defects
    }

    /// The fixed DN of every stuck pixel (meaningful where the defect map says stuck);
    /// `None` when the instance has no stuck pixel.
    pub fn stuck_dn_map(&self) -> Option<&Array2<u16>> {
        self.stuck_dn.as_ref()
    }

    /// Simulates frame `frame_index` for the mean signal electrons `mean_e` (rows × cols,
    /// from the imaging engine; negative values, e.g. resampling ringing, count as 0) and
    /// returns its DN. The temporal noise is keyed by the exposure
    /// ([`DetectorModel::exposure_key`], from the integration time) and the frame, so a
    /// run at another exposure time draws independent noise. Deterministic in (seed,
    /// integration time, frame_index) and independent of the number of threads; rows are
    /// processed in parallel.
    ///
    /// Errors: wrong shape, or a non-finite value in `mean_e`.
    pub fn expose(&self, mean_e: &Array2<f64>, frame_index: u64) -> Result<Array2<u16>> {
        self.expose_exposure(mean_e, self.model.exposure_key(), frame_index)
    }

    /// As [`expose`](Self::expose) with an explicit exposure key: each distinct
    /// `exposure` gets its own temporal-noise streams (for series that vary the
    /// illumination at a fixed integration time, e.g. a photon-transfer measurement),
    /// while the fixed pattern stays that of this instance. Deterministic in
    /// (seed, exposure, frame_index).
    ///
    /// Errors: wrong shape, or a non-finite value in `mean_e`.
    pub fn expose_exposure(
        &self,
        mean_e: &Array2<f64>,
        exposure: u64,
        frame_index: u64,
    ) -> Result<Array2<u16>> {
        let m = &self.model;
        self.check_mean(mean_e)?;
        if m.couples_pixels() {
            return self.expose_staged(mean_e, exposure, frame_index, &FrameExtras::default());
        }
        let mut out = Array2::<u16>::zeros((m.rows, m.cols));
        out.as_slice_mut()
            .expect("a new array is contiguous")
            .par_chunks_mut(m.cols.max(1))
            .enumerate()
            .for_each(|(i, row)| self.expose_row(mean_e.row(i), i, exposure, frame_index, row));
        Ok(out)
    }

    /// As [`expose`](Self::expose), with what the focal plane's memory adds to this frame
    /// (`extras`, from [`memory::FocalPlaneMemory::step`]): RTS steps, persistence, drift.
    /// Empty extras give exactly [`expose`](Self::expose).
    ///
    /// Errors: wrong shapes, or a non-finite value in `mean_e`.
    pub fn expose_with(
        &self,
        mean_e: &Array2<f64>,
        frame_index: u64,
        extras: &FrameExtras,
    ) -> Result<Array2<u16>> {
        if extras.is_empty() {
            return self.expose(mean_e, frame_index);
        }
        self.check_mean(mean_e)?;
        self.expose_staged(mean_e, self.model.exposure_key(), frame_index, extras)
    }

    /// Refuses a mean-electron image of another shape than the detector, or with a
    /// non-finite value.
    fn check_mean(&self, mean_e: &Array2<f64>) -> Result<()> {
        self.check_mean_shape(mean_e)?;
        // One pass without early exit (it vectorises) before looking for the culprit.
        let all_finite = mean_e
            .as_slice()
            .is_some_and(|s| s.iter().fold(true, |ok, v| ok & v.is_finite()));
        if all_finite {
            return Ok(());
        }
        if let Some((idx, v)) = mean_e.indexed_iter().find(|(_, v)| !v.is_finite()) {
            return Err(Error::param(
                format!("mean electrons at row {}, column {}", idx.0, idx.1),
                v,
                "a finite number of electrons",
            ));
        }
        Ok(())
    }

    /// Refuses a mean-electron image of another shape than the detector.
    fn check_mean_shape(&self, mean_e: &Array2<f64>) -> Result<()> {
        let m = &self.model;
        if mean_e.dim() != (m.rows, m.cols) {
            return Err(Error::param(
                "mean electrons",
                format!("{} x {}", mean_e.nrows(), mean_e.ncols()),
                format!("the detector's {} x {} pixels", m.rows, m.cols),
            ));
        }
        Ok(())
    }

    /// As [`expose`](Self::expose) for the listed rows only: row k of the result is row
    /// `rows[k]` of frame `frame_index`, bit for bit (the temporal streams are keyed per
    /// row), at the cost of those rows — for measurements that need only a sample of the
    /// array (the calibration's NETD).
    ///
    /// Errors: `mean_e` of another shape than the detector, a row index outside it, or a
    /// non-finite value in a listed row.
    pub fn expose_rows(
        &self,
        mean_e: &Array2<f64>,
        rows: &[usize],
        frame_index: u64,
    ) -> Result<Array2<u16>> {
        let m = &self.model;
        self.check_mean_shape(mean_e)?;
        if let Some(&i) = rows.iter().find(|&&i| i >= m.rows) {
            return Err(Error::param(
                "row",
                i,
                format!("a row index below the detector's {} rows", m.rows),
            ));
        }
        if let Some((i, v)) = rows.iter().find_map(|&i| {
            mean_e
                .row(i)
                .iter()
                .find(|v| !v.is_finite())
                .map(|v| (i, *v))
        }) {
            return Err(Error::param(
                format!("mean electrons in row {i}"),
                v,
                "a finite number of electrons",
            ));
        }
        let exposure = m.exposure_key();
        if m.couples_pixels() {
            // The rows' values depend on their neighbours (IPC) and on the frame's readout
            // noise: expose the whole frame and keep the rows asked for.
            let all = self.expose_staged(mean_e, exposure, frame_index, &FrameExtras::default())?;
            return Ok(all.select(ndarray::Axis(0), rows));
        }
        let mut out = Array2::<u16>::zeros((rows.len(), m.cols));
        out.as_slice_mut()
            .expect("a new array is contiguous")
            .par_chunks_mut(m.cols.max(1))
            .zip(rows.par_iter())
            .for_each(|(row, &i)| self.expose_row(mean_e.row(i), i, exposure, frame_index, row));
        Ok(out)
    }

    /// One row of [`DetectorInstance::expose`], row `i` of the frame, into `out`. On
    /// x86-64 with AVX2 the same code compiled for it: the rounding steps (`round`,
    /// `floor`, also inside the Poisson draw) become single instructions instead of
    /// calls, with the same results (they are exact operations, and no fused
    /// multiply-add may form), so the same DN to the bit.
    fn expose_row(
        &self,
        signal: ArrayView1<f64>,
        i: usize,
        exposure: u64,
        frame: u64,
        out: &mut [u16],
    ) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe { self.expose_row_avx2(signal, i, exposure, frame, out) };
        }
        self.expose_row_portable(signal, i, exposure, frame, out)
    }

    /// [`DetectorInstance::expose_row`] compiled for AVX2.
    ///
    /// # Safety
    /// The CPU must support AVX2 (`is_x86_feature_detected!("avx2")`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn expose_row_avx2(
        &self,
        signal: ArrayView1<f64>,
        i: usize,
        exposure: u64,
        frame: u64,
        out: &mut [u16],
    ) {
        self.expose_row_portable(signal, i, exposure, frame, out)
    }

    /// [`DetectorInstance::expose_row`] for any CPU.
    #[inline(always)]
    fn expose_row_portable(
        &self,
        signal: ArrayView1<f64>,
        i: usize,
        exposure: u64,
        frame: u64,
        out: &mut [u16],
    ) {
        let m = &self.model;
        let mut shot_rng = temporal_stream(self.seed, Effect::Shot, exposure, frame, i as u64);
        let mut read_rng = temporal_stream(self.seed, Effect::Read, exposure, frame, i as u64);
        let gain = self.gain.as_ref().map(|g| g.row(i));
        let offset = self.offset_e.as_ref().map(|o| o.row(i));
        let quad = self.quadratic.as_ref().map(|q| q.row(i));
        let defects = self.defects.row(i);
        let stuck = self.stuck_dn.as_ref().map(|s| s.row(i));
        debug_assert_eq!(out.len(), m.cols);
        for (j, o) in out.iter_mut().enumerate() {
            *o = {
                let mu = mean_total_e(signal[j], m.dark_e, m.background_e);
                let mut e = if m.shot_noise {
                    shot(mu, m.full_well_e, &mut shot_rng)
                } else {
                    mu
                };
                e = clip_full_well(e, m.full_well_e);
                e = apply_fpn(
                    e,
                    gain.as_ref().map_or(1.0, |g| g[j]),
                    offset.as_ref().map_or(0.0, |o| o[j]),
                );
                if let Some(q) = &quad {
                    e = apply_nonlinearity(e, q[j]);
                }
                if m.read_noise_e > 0.0 {
                    e += m.read_noise_e * read_rng.sample::<f64, _>(StandardNormal);
                }
                let dn = adc(m.gain_dn_per_e * e + m.offset_dn, m.max_dn);
                apply_defect(defects[j], dn, m.max_dn, stuck.as_ref().map(|s| s[j]))
            };
        }
    }
}

/// Step 9: a defect's DN in place of `dn` (map code 1 dead → 0, 2 hot → full scale, 3 stuck
/// → its own `stuck_dn`; 0 keeps `dn`).
#[inline]
pub(crate) fn apply_defect(code: u8, dn: u16, max_dn: f64, stuck_dn: Option<u16>) -> u16 {
    match code {
        1 => 0,
        2 => max_dn as u16,
        3 => stuck_dn.unwrap_or(dn),
        _ => dn,
    }
}

/// Step 1: mean total electrons `max(signal, 0) + dark + background` (docs/design.md §1).
#[inline]
pub fn mean_total_e(signal_e: f64, dark_e: f64, background_e: f64) -> f64 {
    signal_e.max(0.0) + dark_e + background_e
}

/// Step 2: one Poisson draw of mean `mean_e` (FOI report eq. 2.24): for means ≥ 12
/// Ahrens–Dieter 1982 (`poisson::ahrens_dieter`, constant time however large the mean,
/// the very draws of `rand_distr`'s `Poisson`), below 12 `rand_distr`'s multiplication
/// method. Means more than 40 σ above `full_well_e` return the full well without drawing
/// (the draw cannot fall below it), which also keeps means beyond `Poisson::MAX_LAMBDA`
/// valid; so does a mean that is not a finite number. Always inlined: in the detector's
/// AVX2 row loop the draw's `floor`s are then single instructions, not library calls.
#[inline(always)]
pub fn shot<R: rand::Rng + ?Sized>(mean_e: f64, full_well_e: f64, rng: &mut R) -> f64 {
    if mean_e <= 0.0 {
        return 0.0;
    }
    if mean_e > full_well_e + POISSON_SATURATION_SIGMAS * (mean_e.sqrt() + 1.0) {
        return full_well_e;
    }
    if mean_e < poisson::SMALLEST_MEAN {
        return match Poisson::new(mean_e) {
            Ok(p) => p.sample(rng),
            Err(_) => full_well_e,
        };
    }
    if mean_e <= Poisson::<f64>::MAX_LAMBDA {
        poisson::ahrens_dieter(mean_e, rng)
    } else {
        full_well_e
    }
}

/// Step 3: a pixel holds at most `full_well_e` electrons.
#[inline]
pub fn clip_full_well(e: f64, full_well_e: f64) -> f64 {
    e.min(full_well_e)
}

/// Step 4: fixed pattern `e·g + o` (gain g, offset o in electrons; FOI report eq. 2.46).
#[inline]
pub fn apply_fpn(e: f64, gain: f64, offset_e: f64) -> f64 {
    e * gain + offset_e
}

/// Step 5: quadratic nonlinearity `e + a·e²`, held at its extreme value `−1/(4a)` beyond
/// the turning point `e = −1/(2a)` so the response never folds back.
#[inline]
pub fn apply_nonlinearity(e: f64, a: f64) -> f64 {
    if a == 0.0 {
        return e;
    }
    let turn = -0.5 / a;
    let past = if a < 0.0 { e > turn } else { e < turn };
    if past {
        -0.25 / a
    } else {
        e + a * e * e
    }
}

/// Step 8: round to the nearest DN and clip to [0, `max_dn`].
#[inline]
pub fn adc(dn: f64, max_dn: f64) -> u16 {
    dn.round().clamp(0.0, max_dn) as u16
}

/// Gain and offset maps of one instance (`None` when that part is all 1 / all 0).
fn fixed_pattern(model: &DetectorModel, seed: u64) -> (Option<Array2<f64>>, Option<Array2<f64>>) {
    let (rows, cols) = (model.rows, model.cols);
    let mut gain = model.gain_file.clone();
    let mut offset = model.offset_file.clone();
    let Some(f) = &model.fpn else {
        return (gain, offset);
    };
    let rho = f.bias_gain_correlation;
    let need_zg = f.prnu_sigma_rel > 0.0 || (f.dsnu_sigma_e > 0.0 && rho != 0.0);
    let need_zo = f.dsnu_sigma_e > 0.0 && rho.abs() < 1.0;
    let l = f.correlation_length_px;
    let zg = need_zg.then(|| fpn::unit_field(seed, Effect::Gain, rows, cols, l));
    let zo = need_zo.then(|| fpn::unit_field(seed, Effect::Offset, rows, cols, l));
    if f.prnu_sigma_rel > 0.0 {
        if let Some(z) = &zg {
            let g = z.mapv(|v| (1.0 + f.prnu_sigma_rel * v).max(0.0));
            gain = Some(match gain {
                Some(file) => file * &g,
                None => g,
            });
        }
    }
    let mut add = |o: Array2<f64>| {
        offset = Some(match offset.take() {
            Some(prev) => prev + &o,
            None => o,
        });
    };
    if f.dsnu_sigma_e > 0.0 {
        // 2×2 Cholesky factor of [[1, ρ], [ρ, 1]]: (z_g, ρ z_g + √(1−ρ²) z_o).
        let c = (1.0 - rho * rho).max(0.0).sqrt();
        let mut o = Array2::zeros((rows, cols));
        if let Some(z) = &zg {
            o.scaled_add(f.dsnu_sigma_e * rho, z);
        }
        if let Some(z) = &zo {
            o.scaled_add(f.dsnu_sigma_e * c, z);
        }
        add(o);
    }
    if f.column_sigma_e > 0.0 {
        let c = fpn::normal_row(seed, Effect::Column, 0, cols);
        add(Array2::from_shape_fn((rows, cols), |(_, j)| {
            f.column_sigma_e * c[j]
        }));
    }
    if f.row_sigma_e > 0.0 {
        let r = fpn::normal_row(seed, Effect::Row, 0, rows);
        add(Array2::from_shape_fn((rows, cols), |(i, _)| {
            f.row_sigma_e * r[i]
        }));
    }
    (gain, offset)
}

/// Defect codes of one instance: the measured map, plus random dead, hot and stuck pixels
/// (each kind from its own stream; dead wins over hot over stuck) where the map says 0.
fn defect_map(model: &DetectorModel, seed: u64) -> Array2<u8> {
    let (rows, cols) = (model.rows, model.cols);
    let mut map = model
        .defect_file
        .clone()
        .unwrap_or_else(|| Array2::zeros((rows, cols)));
    let Some(d) = &model.defects else {
        return map;
    };
    // Lowest priority first, so a later kind overwrites an earlier one.
    for (fraction, effect, code) in [
        (d.stuck_fraction, Effect::Stuck, Defect::Stuck),
        (d.hot_fraction, Effect::Hot, Defect::Hot),
        (d.dead_fraction, Effect::Dead, Defect::Dead),
    ] {
        if fraction <= 0.0 {
            continue;
        }
        let u = fpn::par_rows(rows, cols, |i| fpn::uniform_row(seed, effect, i, cols));
        let from_file = model.defect_file.as_ref();
        for ((idx, c), uv) in map.indexed_iter_mut().zip(u.iter()) {
            let file_says_ok = from_file.is_none_or(|f| f[idx] == 0);
            if file_says_ok && *uv < fraction {
                *c = code as u8;
            }
        }
    }
    map
}

/// Reads a 32-bit float TIFF map and checks its shape.
fn read_map_f32(path: &Path, dims: (usize, usize), field: &str) -> Result<Array2<f64>> {
    let m = raster::read_tiff_f32(path)?;
    check_dims(path, m.dim(), dims, field)?;
    Ok(m.mapv(|v| v as f64))
}

fn check_dims(path: &Path, got: (usize, usize), want: (usize, usize), field: &str) -> Result<()> {
    if got != want {
        return Err(Error::format(
            path,
            format!(
                "{field}: the map is {} x {} pixels, the detector {} x {} (rows x cols)",
                got.0, got.1, want.0, want.1
            ),
        ));
    }
    Ok(())
}
