//! Radiometric calibration through the simulated sensor: "the way back" from DN to
//! apparent temperature and in-band radiance (issues 4, 9, 12; docs/design.md §1
//! processing, §4.9).
//!
//! [`Calibration::new`] does what a laboratory does with a real camera: it views a
//! uniform blackbody at a few temperatures *through the same detector instance* that
//! records the scene (same fixed pattern and defects; fresh temporal noise), averages M
//! frames per level and derives
//!
//! 1. the per-pixel polynomial NUC ([`NucCoefficients`]) mapping each pixel's DN onto the
//!    **ideal DN** of the mean detector model, `DN*(T) = model.expected_dn(μ_e(T))`, with
//!    `μ_e(T) = camera_equation.electrons_blackbody(T, S)` (docs/design.md §4.1; S the spectral
//!    response τ_filter τ_optics τ_atm η). A uniform blackbody gives uniform mean electrons
//!    (blur preserves the mean, so no imaging is needed); when `optics.cos4` is on, each
//!    pixel's electrons are multiplied by its cos⁴θ (θ the off-axis angle of the pixel
//!    centre, as the imaging engine does), and because the reference stays the on-axis DN*,
//!    the NUC also flattens the cos⁴ roll-off: corrected DN are "on-axis equivalent";
//! 2. the bad-pixel map: [`bad_pixels::detect`] on the coldest and hottest level averages,
//!    united with the pixels the NUC fit could not determine and those clipped at a level;
//! 3. two lookup tables of the sensor's own blackbody response (docs/design.md §4.9):
//!    `T → DN*(T)` (inverted for the apparent temperature) and `T → L_band(T)`, the
//!    **in-band radiance** defined here as
//!
//!    `L_band(T) = ∫ S(λ) L_λ(λ, T) dλ / max_λ S(λ)`,  W m-2 sr-1,
//!
//!    i.e. the blackbody radiance weighted by the normalised spectral response (peak 1), so
//!    that for a flat-topped band it is the radiance within the band.
//!
//! **Reference temperatures** ([`CalibrationOptions::temperatures_k`]): given explicitly,
//! else the sensor file's `[calibration] temperatures_k`, else chosen from the sensor's own
//! range at about 10/50/90 % of full scale ([`levels`]).
//!
//! **The level averages** ([`FrameRoute`]): by default each M-frame average is drawn in one
//! pass from its exact per-pixel mean and variance through the instance
//! ([`flat_field`]: fixed pattern, nonlinearity, shot and read noise, rounding, defects),
//! which costs one frame whatever M is; [`FrameRoute::Exposed`] exposes every frame
//! ([`DetectorInstance::expose`], frame indices from [`CALIBRATION_FRAME_BASE`]) and
//! averages, as a laboratory would; the two agree within their statistical error (tests
//! `calibration::statistical_route_matches_exposed_frames`).
//!
//! The radiance table spans [`CalibrationOptions::radiance_range_k`] (150–1000 K by
//! default: radiance is not limited by the ADC). The DN table covers `lut_range_k` trimmed
//! to where DN* rises strictly: above the temperature at which the ideal pixel reaches full
//! scale (ADC or full well) DN* is flat and no temperature can be recovered. Corrected
//! values outside the table become NaN and are counted; raw DN at the ADC limits (0 or
//! 2^bits − 1) are clipped measurements and also become NaN (unless the pixel is a flagged
//! defect, which is replaced), so a saturated pixel never yields a wrong temperature.

pub mod band_quadrature;
pub mod flat_field;
pub mod instance;
pub mod levels;
pub mod netd_measurement;

use std::sync::Arc;

use ndarray::{Array2, ArrayView2, Zip};
use rayon::prelude::*;

use crate::detector::{DetectorInstance, DetectorModel};
use crate::error::{require_positive, Error, Result};
use crate::processing::bad_pixels::{self, BadPixelCriteria, BadPixelMap};
use crate::processing::nuc::{self, NucCoefficients};
use crate::processing::temperature::{HermiteTable, InverseLookup, InverseTable};
use crate::processing::{median_in_place, netd};
use crate::radiometry::{band_radiance, CameraEquation, TemperatureLut};
use crate::sensor::Sensor;
use crate::spectrum::Spectrum;
use band_quadrature::{BandQuadrature, C2_M_K};
pub use netd_measurement::{measured_netd, measured_netd_sampled, NetdSample};

/// First frame index of the calibration frames of [`FrameRoute::Exposed`]: level l, frame
/// i uses `CALIBRATION_FRAME_BASE + l·M + i` (independent temporal noise from scene frames,
/// which count from 0); [`FrameRoute::Statistical`] keys its draws by the same index of the
/// level's first frame.
pub const CALIBRATION_FRAME_BASE: u64 = 1_000_000;
/// First frame index of the flat fields of [`Calibration::residual_nonuniformity`].
pub const VALIDATION_FRAME_BASE: u64 = 2_000_000;
/// First frame index of the frames of [`measured_netd`] (T at `+i`, T + ΔT at
/// `+1_000_000 + i`).
pub const NETD_FRAME_BASE: u64 = 3_000_000;

/// Points of the grid (plus the breakpoints) on which the peak of the spectral response is
/// searched: exact for piecewise-linear curves (top-hats, tables; the maximum lies on a
/// breakpoint or a flat top), ~1e-6 relative for a Gaussian (grid step ≈ 0.004 σ).
const PEAK_SEARCH_POINTS: usize = 4096;

/// Largest difference (K) between the fast image inversion ([`InverseTable`]) and the exact
/// inversion of the DN table at any interval midpoint of the inverse table.
pub const INVERSE_TOLERANCE_K: f64 = 1e-7;

/// Temperature step (K) used to test that DN* still rises at a temperature.
const RISE_STEP_K: f64 = 0.01;

/// How the M-frame average of a calibration level is obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FrameRoute {
    /// Drawn in one pass from the exact per-pixel mean and variance of the M-frame average
    /// through the instance ([`flat_field`]); the cost does not grow with M.
    #[default]
    Statistical,
    /// Every frame exposed through the instance and averaged (M exposures per level).
    Exposed,
}

/// Options of [`Calibration::new`].
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationOptions {
    /// Blackbody temperatures of the calibration levels, K (at least `degree + 1`,
    /// distinct). Empty (the default): the sensor file's `[calibration] temperatures_k`,
    /// else `max(3, degree + 2)` levels from 10 % to 90 % of the sensor's usable range
    /// (`levels::automatic`).
    pub temperatures_k: Vec<f64>,
    /// Frames averaged per level (M ≥ 1). Default 16.
    pub frames_per_level: usize,
    /// Degree N of the per-pixel NUC polynomial (1 = gain and offset). Default 1.
    pub degree: usize,
    /// Temperature range of the DN lookup table, K (trimmed at the top where the ideal pixel
    /// saturates). Default (200, 1000): below 200 K a mid-wave pixel's signal is under its
    /// noise, so a DN there is better NaN than a temperature.
    pub lut_range_k: (f64, f64),
    /// Temperature range of the in-band radiance table, K (not limited by the ADC).
    /// Default (150, 1000).
    pub radiance_range_k: (f64, f64),
    /// How the level averages are obtained. Default [`FrameRoute::Statistical`].
    pub route: FrameRoute,
}

impl Default for CalibrationOptions {
    fn default() -> Self {
        CalibrationOptions {
            temperatures_k: Vec::new(),
            frames_per_level: 16,
            degree: 1,
            lut_range_k: (200.0, 1000.0),
            radiance_range_k: (150.0, 1000.0),
            route: FrameRoute::Statistical,
        }
    }
}

impl CalibrationOptions {
    /// Checks every option, naming the field.
    pub fn validate(&self) -> Result<()> {
        if !self.temperatures_k.is_empty() {
            check_temperatures(&self.temperatures_k, self.degree)?;
        }
        if self.degree > nuc::MAX_DEGREE {
            return Err(Error::param(
                "degree",
                self.degree,
                format!("a NUC degree from 0 to {}", nuc::MAX_DEGREE),
            ));
        }
        if self.frames_per_level == 0 {
            return Err(Error::param(
                "frames_per_level",
                0,
                "at least 1 frame per calibration level",
            ));
        }
        for (name, (lo, hi)) in [
            ("lut_range_k", self.lut_range_k),
            ("radiance_range_k", self.radiance_range_k),
        ] {
            require_positive(&format!("{name}.0"), lo)?;
            if !(hi.is_finite() && hi > lo) {
                return Err(Error::param(
                    format!("{name}.1"),
                    hi,
                    format!("a finite temperature in K above {name}.0 = {lo}"),
                ));
            }
        }
        Ok(())
    }
}

/// Checks explicit reference temperatures: finite, > 0, at least max(2, degree + 1)
/// distinct.
fn check_temperatures(temperatures_k: &[f64], degree: usize) -> Result<()> {
    for (l, &t) in temperatures_k.iter().enumerate() {
        require_positive(&format!("temperatures_k[{l}]"), t)?;
    }
    let mut sorted = temperatures_k.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted.dedup();
    if sorted.len() < 2 || sorted.len() < degree + 1 {
        return Err(Error::param(
            "temperatures_k",
            format!("{} distinct temperature(s)", sorted.len()),
            format!(
                "at least max(2, degree + 1) = {} distinct blackbody temperatures",
                (degree + 1).max(2)
            ),
        ));
    }
    Ok(())
}

/// Node spacing of the blackbody response tables ([`HermiteTable`], equal steps in 1/T) in
/// units of the Wien exponent: `c Δu` with c = hc/(λ_min k) at the shortest wavelength of
/// the response, so the relative interpolation error is ≤ (c Δu)⁴/384 = 1.6e-8 everywhere
/// (about 360 nodes over 150–1000 K for a band from 4.5 µm).
const RESPONSE_TABLE_WIEN_STEP: f64 = 0.05;

/// Shortest wavelength (µm) used to size the table step (a response reaching below it is
/// tabulated as if it started there; 0.5 µm gives 3300 nodes for 150–1000 K).
const RESPONSE_TABLE_MIN_WAVELENGTH_UM: f64 = 0.5;

/// The sensor's blackbody response chain (everything needed to evaluate DN*(T), μ_e(T)
/// and L_band(T)); cheap to clone into the lookup-table closures.
///
/// μ_e(T) and L_band(T) are band integrals. They are tabulated once per calibration, with
/// their exact temperature derivatives (the band integrals of `∂L/∂T = L · ∂ln L/∂T`), on
/// the whole LUT range at steps of [`RESPONSE_TABLE_WIEN_STEP`] in the Wien exponent, and
/// evaluated by cubic Hermite interpolation in 1/T ([`HermiteTable`]). All four integrals
/// of every table node come from one shared spectral rule ([`BandQuadrature`], ≲ 1e-10
/// relative, one Planck evaluation per wavelength node and temperature); outside the tables
/// the integrals are evaluated directly by adaptive quadrature (~1e-10 relative).
#[derive(Debug, Clone)]
struct Chain {
    camera: CameraEquation,
    response: Spectrum,
    model: DetectorModel,
    peak_response: f64,
    electrons_table: Option<Arc<HermiteTable>>,
    radiance_table: Option<Arc<HermiteTable>>,
}

impl Chain {
    /// The chain of `sensor` with `model`: the electrons table on `electrons_range_k`, the
    /// in-band radiance table on `radiance_range_k`.
    fn new(
        sensor: &Sensor,
        model: &DetectorModel,
        electrons_range_k: (f64, f64),
        radiance_range_k: (f64, f64),
    ) -> Result<Self> {
        let response = sensor.response().clone();
        let peak_response = peak_of(&response);
        if !(peak_response.is_finite() && peak_response > 0.0) {
            return Err(Error::param(
                "spectral response",
                peak_response,
                "a response with a positive peak inside a bounded band",
            ));
        }
        let mut chain = Chain {
            camera: *sensor.camera(),
            response,
            model: model.clone(),
            peak_response,
            electrons_table: None,
            radiance_table: None,
        };
        chain.camera.validate()?;
        let lambda_min_um = chain
            .response
            .support_um()
            .0
            .max(RESPONSE_TABLE_MIN_WAVELENGTH_UM);
        let step_inv_k = RESPONSE_TABLE_WIEN_STEP * lambda_min_um * 1e-6 / C2_M_K;
        let quadrature = BandQuadrature::new(
            &chain.response,
            (
                electrons_range_k.0.min(radiance_range_k.0),
                electrons_range_k.1.max(radiance_range_k.1),
            ),
        )?;
        let etendue_time = chain.camera.etendue_time();
        let peak = chain.peak_response;
        let electrons = HermiteTable::new(
            |t| {
                let b = quadrature.eval(t);
                (etendue_time * b.photon, etendue_time * b.photon_per_k)
            },
            electrons_range_k.0,
            electrons_range_k.1,
            step_inv_k,
        )?;
        let radiance = HermiteTable::new(
            |t| {
                let b = quadrature.eval(t);
                (b.energy / peak, b.energy_per_k / peak)
            },
            radiance_range_k.0,
            radiance_range_k.1,
            step_inv_k,
        )?;
        chain.electrons_table = Some(Arc::new(electrons));
        chain.radiance_table = Some(Arc::new(radiance));
        Ok(chain)
    }

    /// μ_e(T) by the band integral (camera equation, docs/design.md §4.1); NaN if it fails.
    fn electrons_exact(&self, t_k: f64) -> f64 {
        self.camera
            .electrons_blackbody(t_k, &self.response)
            .unwrap_or(f64::NAN)
    }

    /// L_band(T) by the band integral.
    fn band_radiance_exact(&self, t_k: f64) -> f64 {
        band_radiance(t_k, &self.response).unwrap_or(f64::NAN) / self.peak_response
    }

    /// Mean signal electrons of an on-axis pixel viewing a blackbody at `t_k`
    /// (camera equation, docs/design.md §4.1): the table inside its range, else the integral.
    fn electrons(&self, t_k: f64) -> f64 {
        self.electrons_table
            .as_ref()
            .and_then(|tab| tab.eval(t_k))
            .unwrap_or_else(|| self.electrons_exact(t_k))
    }

    /// Ideal DN `model.expected_dn(μ_e(T))` of the mean detector model.
    fn ideal_dn(&self, t_k: f64) -> f64 {
        self.model.expected_dn(self.electrons(t_k))
    }

    /// In-band radiance `∫ S L_λ dλ / max S`, W m-2 sr-1 (module documentation).
    fn band_radiance(&self, t_k: f64) -> f64 {
        self.radiance_table
            .as_ref()
            .and_then(|tab| tab.eval(t_k))
            .unwrap_or_else(|| self.band_radiance_exact(t_k))
    }

    /// [`Chain::band_radiance`] at the reciprocal temperature `u_per_k` = 1/T (K⁻¹).
    fn band_radiance_at_inverse(&self, u_per_k: f64) -> f64 {
        self.radiance_table
            .as_ref()
            .and_then(|tab| tab.eval_inverse(u_per_k))
            .unwrap_or_else(|| self.band_radiance_exact(1.0 / u_per_k))
    }

    /// Whether DN* at `t_k` is finite, inside (0, max DN) and still rising.
    fn rising(&self, t_k: f64) -> bool {
        let d0 = self.ideal_dn(t_k);
        let d1 = self.ideal_dn(t_k + RISE_STEP_K);
        d0.is_finite() && d1.is_finite() && d0 > 0.0 && d1 < self.model.max_dn() && d1 > d0
    }
}

/// The result of a calibration: NUC coefficients, bad-pixel map and the lookup tables of
/// the sensor's own blackbody response (see the module documentation).
#[derive(Debug)]
pub struct Calibration {
    chain: Chain,
    nuc: NucCoefficients,
    bad: BadPixelMap,
    dn_lut: TemperatureLut,
    /// Fast inverse of `dn_lut` for whole images.
    dn_inverse: InverseTable,
    radiance_lut: TemperatureLut,
    cos4: Option<Array2<f64>>,
    frames_per_level: usize,
    route: FrameRoute,
    temperatures_k: Vec<f64>,
    /// `bad.positions()`, row-major.
    bad_positions: Vec<(usize, usize)>,
}

/// The relative illumination of each pixel centre as a uniform source shows it: cos⁴θ,
/// the `[optics.relative_illumination]` table and distortion's area ratio
/// ([`crate::imaging::relative_illumination::calibration_map`], the imaging engine's own
/// map), `None` when the optics add no fall-off.
pub(crate) fn cos4_map(sensor: &Sensor, rows: usize, cols: usize) -> Result<Option<Array2<f64>>> {
    crate::imaging::relative_illumination::calibration_map(sensor, rows, cols)
}

/// Largest value of `s` on its breakpoints and a [`PEAK_SEARCH_POINTS`] grid over its
/// support.
fn peak_of(s: &Spectrum) -> f64 {
    let (lo, hi) = s.support_um();
    let mut peak = s
        .breakpoints_um()
        .into_iter()
        .map(|w| s.eval(w))
        .fold(0.0, f64::max);
    if lo.is_finite() && hi.is_finite() && hi > lo {
        for k in 0..=PEAK_SEARCH_POINTS {
            let w = lo + (hi - lo) * k as f64 / PEAK_SEARCH_POINTS as f64;
            peak = peak.max(s.eval(w));
        }
    }
    peak
}

/// The mean-electron frame of a uniform blackbody at `t_k` (× cos⁴ when enabled).
fn flat_field_e(chain: &Chain, cos4: Option<&Array2<f64>>, t_k: f64) -> Result<Array2<f64>> {
    let (rows, cols) = (chain.model.rows(), chain.model.cols());
    let e = chain.camera.electrons_blackbody(t_k, &chain.response)?;
    Ok(match cos4 {
        Some(m) => m.mapv(|c| c * e),
        None => Array2::from_elem((rows, cols), e),
    })
}

/// Per-pixel average of `frames` exposures of `mean_e` with frame indices `first + i`, and
/// the mask of pixels that read 0 or `max_dn` (ADC-clipped) in at least one frame.
fn average_frames(
    instance: &DetectorInstance,
    mean_e: &Array2<f64>,
    first: u64,
    frames: usize,
) -> Result<(Array2<f64>, Array2<bool>)> {
    let max = instance.model().max_dn();
    let mut sum = Array2::<f64>::zeros(mean_e.dim());
    let mut clipped = Array2::from_elem(mean_e.dim(), false);
    for i in 0..frames {
        let dn = instance.expose(mean_e, first + i as u64)?;
        Zip::from(&mut sum)
            .and(&mut clipped)
            .and(&dn)
            .for_each(|s, c, &d| {
                let v = d as f64;
                *s += v;
                *c |= v <= 0.0 || v >= max;
            });
    }
    Ok((sum / frames as f64, clipped))
}

/// The reference temperatures: explicit, else the sensor file's `[calibration]`, else
/// automatic from the sensor's range ([`levels::automatic`]); checked like explicit ones.
fn reference_temperatures(
    sensor: &Sensor,
    chain: &Chain,
    opts: &CalibrationOptions,
) -> Result<Vec<f64>> {
    if !opts.temperatures_k.is_empty() {
        return Ok(opts.temperatures_k.clone());
    }
    if let Some(t) = sensor
        .config()
        .calibration
        .as_ref()
        .and_then(|c| c.temperatures_k.clone())
    {
        check_temperatures(&t, opts.degree).map_err(|e| {
            Error::OutOfRange(format!(
                "[calibration] temperatures_k of sensor `{}`: {e}",
                sensor.config().name
            ))
        })?;
        return Ok(t);
    }
    levels::automatic(chain, levels::SEARCH_RANGE_K, (opts.degree + 2).max(3))
}

/// The defects [`bad_pixels::detect`] finds on the coldest and hottest level averages
/// (the calibration's bad-pixel map unites them with the pixels the NUC fit could not
/// determine and those clipped at any level).
///
/// With relative illumination (`cos4`: cos⁴θ, the vignetting table, distortion's area
/// ratio) a level's pixels differ by design: each average is first moved by the ideal
/// pixel's own difference, `a − DN(e·m) + DN(e)` (the model's mean DN of a pixel receiving
/// e·m electrons against e), so the tests see only the instance's departures from the
/// ideal pixel. Without this, a vignetted corner (4 % below the centre) reads as a cluster
/// of low-gain pixels and converts to NaN.
fn detected_defects(
    chain: &Chain,
    averages: &[(f64, f64, Array2<f64>)],
    frames: usize,
    cos4: Option<&Array2<f64>>,
) -> Result<BadPixelMap> {
    let coldest = averages.iter().min_by(|a, b| a.0.total_cmp(&b.0));
    let hottest = averages.iter().max_by(|a, b| a.0.total_cmp(&b.0));
    let (Some(coldest), Some(hottest)) = (coldest, hottest) else {
        return Err(Error::param(
            "temperatures_k",
            "none",
            "at least two blackbody temperatures",
        ));
    };
    // Floor on the robust σ: the temporal noise left in an M-frame average plus the
    // quantisation step, so a nearly uniform array does not flag pixels one count off.
    let model = &chain.model;
    let noise = model.temporal_noise_dn(chain.electrons(coldest.0));
    let min_sigma = ((noise * noise + model.quantisation_noise_dn().powi(2)) / frames as f64)
        .sqrt()
        .max(model.quantisation_noise_dn());
    let criteria = BadPixelCriteria {
        min_sigma,
        ..BadPixelCriteria::default()
    };
    let flattened = |(t_k, _, avg): &(f64, f64, Array2<f64>)| -> Result<Array2<f64>> {
        let Some(m) = cos4 else {
            return Ok(avg.clone());
        };
        let e = chain.electrons_exact(*t_k);
        let uniform = model.expected_dn(e);
        let mut out = avg.clone();
        Zip::from(&mut out)
            .and(m)
            .for_each(|a, &f| *a += uniform - model.expected_dn(e * f));
        Ok(out)
    };
    let (dark, bright) = (flattened(coldest)?, flattened(hottest)?);
    Ok(bad_pixels::detect(dark.view(), bright.view(), &criteria)?.map)
}

/// The DN table on `lut_range_k` trimmed to where DN* rises, and the in-band radiance
/// table on `radiance_range_k`.
fn lookup_tables(
    chain: &Chain,
    opts: &CalibrationOptions,
) -> Result<(TemperatureLut, TemperatureLut)> {
    let (t_lo, t_hi) = opts.lut_range_k;
    if !chain.rising(t_lo) {
        return Err(Error::param(
            "lut_range_k.0",
            t_lo,
            "a lower LUT temperature at which the ideal pixel is not clipped and its DN rises with temperature",
        ));
    }
    let top = if chain.rising(t_hi) {
        t_hi
    } else {
        // Bisection for the last rising temperature (to 1 mK), then step back.
        let (mut a, mut b) = (t_lo, t_hi);
        while b - a > 1e-3 {
            let mid = 0.5 * (a + b);
            if chain.rising(mid) {
                a = mid;
            } else {
                b = mid;
            }
        }
        a
    };
    if top <= t_lo {
        return Err(Error::param(
            "lut_range_k",
            format!("({t_lo}, {t_hi})"),
            "a range in which the ideal pixel is unclipped over more than one point",
        ));
    }
    let c1 = chain.clone();
    let dn_lut = TemperatureLut::new(move |t| c1.ideal_dn(t), t_lo, top)?;
    let c2 = chain.clone();
    let (r_lo, r_hi) = opts.radiance_range_k;
    // L_band(T) does not depend on the ADC: the radiance table spans its own range, so an
    // in-band radiance image (`eoir temperature` on f32 radiance) inverts above the
    // temperature where the DN saturate.
    let radiance_lut = TemperatureLut::new(move |t| c2.band_radiance(t), r_lo, r_hi)?;
    Ok((dn_lut, radiance_lut))
}

/// The M-frame level averages of one instance, by either [`FrameRoute`].
struct LevelAverager<'a> {
    instance: &'a DetectorInstance,
    maps: Option<flat_field::InstanceMaps<'a>>,
    frames: usize,
}

impl<'a> LevelAverager<'a> {
    fn new(instance: &'a DetectorInstance, route: FrameRoute, frames: usize) -> Self {
        let maps =
            (route == FrameRoute::Statistical).then(|| flat_field::InstanceMaps::of(instance));
        LevelAverager {
            instance,
            maps,
            frames,
        }
    }

    /// The average of M frames of `mean_e` whose first frame index is `first`, and the
    /// clipped-pixel mask.
    fn average(&self, mean_e: &Array2<f64>, first: u64) -> Result<(Array2<f64>, Array2<bool>)> {
        match &self.maps {
            Some(maps) => flat_field::average(self.instance, maps, mean_e, self.frames, first),
            None => average_frames(self.instance, mean_e, first, self.frames),
        }
    }
}

impl Calibration {
    /// Calibrates `instance` (drawn from `model`, the detector of `sensor`) against uniform
    /// blackbodies at the reference temperatures (see the module documentation for the
    /// method, the choice of temperatures, the frame routes and the definition of the
    /// in-band radiance).
    ///
    /// Errors: invalid options; an instance of another shape than the model; no usable
    /// range for automatic levels; a calibration level whose ideal DN is at or beyond the
    /// ADC limits or full well (the fit would see clipped data; choose lower temperatures
    /// or a lower gain); a spectral response without a bounded band; a LUT range whose
    /// lower end already saturates; errors of the NUC fit or bad-pixel detection.
    pub fn new(
        sensor: &Sensor,
        model: &DetectorModel,
        instance: &DetectorInstance,
        opts: &CalibrationOptions,
    ) -> Result<Self> {
        opts.validate()?;
        let (rows, cols) = (model.rows(), model.cols());
        let im = instance.model();
        if (im.rows(), im.cols()) != (rows, cols) {
            return Err(Error::param(
                "instance",
                format!("{} x {} pixels", im.rows(), im.cols()),
                format!("an instance of the model's {rows} x {cols} detector"),
            ));
        }
        // The electrons table covers the DN table and the search for automatic levels.
        let electrons_range_k = (
            opts.lut_range_k.0.min(levels::SEARCH_RANGE_K.0),
            opts.lut_range_k.1.max(levels::SEARCH_RANGE_K.1),
        );
        let chain = Chain::new(sensor, model, electrons_range_k, opts.radiance_range_k)?;
        let temperatures_k = reference_temperatures(sensor, &chain, opts)?;
        let cos4 = cos4_map(sensor, rows, cols)?;

        // Calibration levels: averaged frames and their ideal-DN references.
        let m = opts.frames_per_level;
        let averager = LevelAverager::new(instance, opts.route, m);
        let mut averages = Vec::with_capacity(temperatures_k.len());
        let mut clipped = Array2::from_elem((rows, cols), false);
        for (l, &t) in temperatures_k.iter().enumerate() {
            let e = chain.camera.electrons_blackbody(t, &chain.response)?;
            let total = e + model.dark_e() + model.background_e();
            let reference = model.expected_dn(e);
            if !(total < model.full_well_e() && reference > 0.0 && reference < model.max_dn()) {
                return Err(Error::param(
                    format!("temperatures_k[{l}]"),
                    t,
                    format!(
                        "a blackbody the ideal pixel records unclipped (it gives {total:.4e} e- of full well {:.4e} and {reference:.1} DN of (0, {}))",
                        model.full_well_e(),
                        model.max_dn()
                    ),
                ));
            }
            let mean_e = flat_field_e(&chain, cos4.as_ref(), t)?;
            let first = CALIBRATION_FRAME_BASE + (l * m) as u64;
            let (avg, clip) = averager.average(&mean_e, first)?;
            Zip::from(&mut clipped).and(&clip).for_each(|a, &b| *a |= b);
            averages.push((t, reference, avg));
        }
        let levels: Vec<(f64, ArrayView2<f64>)> =
            averages.iter().map(|(_, r, a)| (*r, a.view())).collect();
        // The defect tests need the level averages only, not the fit: side by side.
        let (nuc, defects) = rayon::join(
            || NucCoefficients::fit(&levels, opts.degree),
            || detected_defects(&chain, &averages, m, cos4.as_ref()),
        );
        let nuc = nuc?;
        let bad = defects?
            .union(&nuc.rank_deficient_map())?
            .union(&BadPixelMap::from_mask(clipped))?;
        let (dn_lut, radiance_lut) = lookup_tables(&chain, opts)?;
        let dn_inverse = InverseTable::new(&dn_lut, model.expected_dn(0.0), INVERSE_TOLERANCE_K)?;
        let bad_positions = bad.positions();
        Ok(Calibration {
            chain,
            nuc,
            bad,
            dn_lut,
            dn_inverse,
            radiance_lut,
            cos4,
            frames_per_level: m,
            route: opts.route,
            temperatures_k,
            bad_positions,
        })
    }

    /// The per-pixel NUC coefficients (raw DN → ideal DN).
    pub fn nuc(&self) -> &NucCoefficients {
        &self.nuc
    }

    /// The bad-pixel map (detected defects ∪ pixels the NUC fit could not determine).
    pub fn bad_pixels(&self) -> &BadPixelMap {
        &self.bad
    }

    /// The lookup table `T → DN*(T)` (ideal DN of the mean model).
    pub fn dn_lut(&self) -> &TemperatureLut {
        &self.dn_lut
    }

    /// The lookup table `T → L_band(T)`, in-band radiance W m-2 sr-1 (module documentation).
    pub fn radiance_lut(&self) -> &TemperatureLut {
        &self.radiance_lut
    }

    /// Temperatures of the calibration levels, K.
    pub fn temperatures_k(&self) -> &[f64] {
        &self.temperatures_k
    }

    /// Temperature range `(t_min, t_max)` K of the tables (the top trimmed where the ideal
    /// pixel saturates).
    pub fn lut_range_k(&self) -> (f64, f64) {
        self.dn_lut.range_k()
    }

    /// Peak of the spectral response S, the normalisation of the in-band radiance.
    pub fn peak_response(&self) -> f64 {
        self.chain.peak_response
    }

    /// Ideal DN `DN*(T) = model.expected_dn(camera_equation.electrons_blackbody(T, S))`.
    pub fn ideal_dn(&self, t_k: f64) -> f64 {
        self.chain.ideal_dn(t_k)
    }

    /// Mean signal electrons of an on-axis pixel viewing a blackbody at `t_k`
    /// (camera equation, docs/design.md §4.1).
    ///
    /// Errors: invalid temperature or an unbounded spectral response.
    pub fn blackbody_electrons(&self, t_k: f64) -> Result<f64> {
        self.chain
            .camera
            .electrons_blackbody(t_k, &self.chain.response)
    }

    /// In-band radiance `L_band(T) = ∫ S L_λ(λ, T) dλ / max S`, W m-2 sr-1.
    pub fn band_radiance(&self, t_k: f64) -> f64 {
        self.chain.band_radiance(t_k)
    }

    /// Scene DN → corrected DN: the NUC polynomial per pixel; raw values at the ADC limits
    /// (0 or 2^bits − 1: clipped, carrying no scene information) become NaN; then flagged
    /// bad pixels are replaced by the median of their valid 3×3 neighbours
    /// ([`bad_pixels::replace`]), or become NaN when they have none.
    ///
    /// Errors: a frame of another shape.
    pub fn correct(&self, dn: ArrayView2<u16>) -> Result<Array2<f64>> {
        let max = self.chain.model.max_dn();
        let out = self
            .nuc
            .apply_masked(dn, |v| v as f64, |r| r <= 0.0 || r >= max)?;
        Ok(self.replace_bad(out))
    }

    /// Replaces the flagged pixels of a corrected frame by the median of their valid
    /// (unflagged, finite) 3×3 neighbours, as [`bad_pixels::replace`] does; a flagged pixel
    /// without any valid neighbour in its 3×3 window becomes NaN rather than borrowing a
    /// value from farther away (e.g. across a saturated region). All replacements are
    /// taken from the frame before any is written, so the order does not matter.
    fn replace_bad(&self, mut corrected: Array2<f64>) -> Array2<f64> {
        if self.bad_positions.is_empty() {
            return corrected;
        }
        let (rows, cols) = corrected.dim();
        let mask = self.bad.mask();
        let frame = &corrected;
        let values: Vec<f64> = self
            .bad_positions
            .par_iter()
            .map(|&(r, c)| {
                let (r0, r1) = (r.saturating_sub(1), (r + 1).min(rows - 1));
                let (c0, c1) = (c.saturating_sub(1), (c + 1).min(cols - 1));
                let mut window = [0.0; 9];
                let mut n = 0;
                for i in r0..=r1 {
                    for j in c0..=c1 {
                        let v = frame[[i, j]];
                        if !mask[[i, j]] && v.is_finite() {
                            window[n] = v;
                            n += 1;
                        }
                    }
                }
                median_in_place(&mut window[..n]).unwrap_or(f64::NAN)
            })
            .collect();
        for (&(r, c), v) in self.bad_positions.iter().zip(values) {
            corrected[[r, c]] = v;
        }
        corrected
    }

    /// As [`Calibration::correct`] for a frame already in f64 (e.g. an average of frames).
    ///
    /// Errors: as [`Calibration::correct`].
    pub fn correct_f64(&self, dn: ArrayView2<f64>) -> Result<Array2<f64>> {
        let max = self.chain.model.max_dn();
        let out = self
            .nuc
            .apply_masked(dn, |v| v, |r| !(r > 0.0 && r < max))?;
        Ok(self.replace_bad(out))
    }

    /// Corrected DN → `(apparent temperature K, in-band radiance W m-2 sr-1, NaN count)`:
    /// T by inverting the DN* table (docs/design.md §4.9; through its fast
    /// [`InverseTable`], within [`INVERSE_TOLERANCE_K`] of
    /// `dn_lut().temperature_or_nan`), the radiance as `L_band(T)` of the blackbody at that
    /// temperature. Values outside the table (or NaN) give NaN in both images and are
    /// counted.
    pub fn to_temperature(&self, corrected: ArrayView2<f64>) -> (Array2<f64>, Array2<f64>, usize) {
        self.converted(corrected, |v| v)
    }

    /// [`Calibration::to_temperature`] with the images in f32 (the values rounded from the
    /// same f64 results), as the run's products store them: no f64 images are made.
    pub fn to_temperature_f32(
        &self,
        corrected: ArrayView2<f64>,
    ) -> (Array2<f32>, Array2<f32>, usize) {
        self.converted(corrected, |v| v as f32)
    }

    /// The apparent temperature and in-band radiance of every corrected value, stored
    /// through `store`, and the NaN count.
    fn converted<F: Copy + Send + Sync>(
        &self,
        corrected: ArrayView2<f64>,
        store: impl Fn(f64) -> F + Sync,
    ) -> (Array2<F>, Array2<F>, usize) {
        let mut t = Array2::from_elem(corrected.dim(), store(0.0));
        let mut l = Array2::from_elem(corrected.dim(), store(0.0));
        let nan_per_row = Zip::from(t.rows_mut())
            .and(l.rows_mut())
            .and(corrected.rows())
            .par_map_collect(|mut t, mut l, v| {
                let mut nan = 0;
                for ((t, l), &v) in t.iter_mut().zip(l.iter_mut()).zip(v) {
                    let converted = match self.dn_inverse.lookup(v) {
                        // 1/T from the table: the radiance table is in 1/T too, so T's
                        // division is not undone by another.
                        InverseLookup::Cubic(u) => {
                            Some((1.0 / u, self.chain.band_radiance_at_inverse(u)))
                        }
                        InverseLookup::Exact => {
                            let t = self.dn_lut.temperature_or_nan(v);
                            (!t.is_nan()).then(|| (t, self.chain.band_radiance(t)))
                        }
                        InverseLookup::Outside => None,
                    };
                    let (temperature, radiance) = converted.unwrap_or_else(|| {
                        nan += 1;
                        (f64::NAN, f64::NAN)
                    });
                    *t = store(temperature);
                    *l = store(radiance);
                }
                nan
            });
        let nan = nan_per_row.sum();
        (t, l, nan)
    }

    /// Residual non-uniformity σ/mean of a flat field at `t_k` (a temperature not used in
    /// the fit), `(raw, corrected)`: the average of M (= `frames_per_level`) frames of
    /// `instance` (frame indices from [`VALIDATION_FRAME_BASE`]; by the calibration's
    /// [`FrameRoute`]), raw and through
    /// [`Calibration::correct_f64`]. Both are taken over the pixels not flagged bad, so the
    /// figure measures the fixed-pattern correction, not defect replacement; the
    /// corrected value keeps the temporal noise of the average (σ_t/√M).
    ///
    /// Errors: an invalid temperature, an instance of another shape, or fewer than two
    /// valid pixels.
    pub fn residual_nonuniformity(
        &self,
        instance: &DetectorInstance,
        t_k: f64,
    ) -> Result<(f64, f64)> {
        require_positive("t_k", t_k)?;
        let mean_e = flat_field_e(&self.chain, self.cos4.as_ref(), t_k)?;
        let averager = LevelAverager::new(instance, self.route, self.frames_per_level);
        let (avg, _) = averager.average(&mean_e, VALIDATION_FRAME_BASE)?;
        let raw = nuc::residual_nonuniformity(avg.view(), Some(&self.bad))?;
        let corrected = self.correct_f64(avg.view())?;
        let cor = nuc::residual_nonuniformity(corrected.view(), Some(&self.bad))?;
        Ok((raw, cor))
    }

    /// Analytic NETD (K) at `t_ref_k`: temporal noise / dDN*/dT ([`netd::analytic_netd`]),
    /// the noise `√(σ_t² + 1/12)` DN with σ_t = `model.temporal_noise_dn(μ_e(T))` (shot
    /// and read noise, FOI report eq. 2.34) and the ADC's rounding noise 1/√12 DN.
    ///
    /// Errors: an invalid temperature, or a flat response (saturated at `t_ref_k`).
    pub fn netd_analytic_k(&self, t_ref_k: f64) -> Result<f64> {
        require_positive("t_ref_k", t_ref_k)?;
        let m = &self.chain.model;
        let sigma = m.temporal_noise_dn(self.blackbody_electrons(t_ref_k)?);
        let noise = (sigma * sigma + m.quantisation_noise_dn().powi(2)).sqrt();
        let c = &self.chain;
        netd::analytic_netd(|t| c.ideal_dn(t), t_ref_k, noise)
    }
}

/// The lookup table `T → L_band(T)` (in-band radiance, W m-2 sr-1, module documentation)
/// of `sensor` on `range_k`, for inverting radiance images: no detector, NUC or ADC is
/// involved, so it spans the whole range however the DN saturate.
///
/// Errors: a spectral response without a bounded band or positive peak, or an invalid
/// range.
pub fn band_radiance_lut(sensor: &Sensor, range_k: (f64, f64)) -> Result<TemperatureLut> {
    let chain = Chain::new(sensor, sensor.detector(), range_k, range_k)?;
    TemperatureLut::new(move |t| chain.band_radiance(t), range_k.0, range_k.1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peak_of_top_hat_is_its_peak() {
        let s = Spectrum::top_hat(4.0, 5.0, 0.1, 0.85).unwrap_or_else(|_| Spectrum::constant(0.0));
        assert!((peak_of(&s) - 0.85).abs() < 1e-12);
    }

    #[test]
    fn default_options_validate() {
        assert!(CalibrationOptions::default().validate().is_ok());
        let bad = CalibrationOptions {
            temperatures_k: vec![300.0, 300.0],
            ..CalibrationOptions::default()
        };
        assert!(bad.validate().is_err());
    }
}
