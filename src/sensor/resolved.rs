//! The resolved sensor: [`Sensor::build`] turns the schema ([`SensorConfig`]) into
//! everything the stages of a run need, once.
//!
//! Building validates every value, reads every file the description refers to (CSV
//! spectra, a measured MTF, detector maps) exactly once, samples the spectral response,
//! forms the camera equation, the transfer-function cascade ([`SystemOtf`]) and the
//! detector model ([`DetectorModel`]), and for a colour-filter-array sensor the response of
//! each filter colour and the white balance. The result is immutable: no stage reads a
//! file, re-validates, or sees `base_dir`.

use std::ops::Deref;

use crate::detector::{AutoGainConfig, DetectorInputs, DetectorModel};
use crate::error::{Error, Result};
use crate::optics::MeasuredMtf;
use crate::radiometry::{planck_spectral_radiance, CameraEquation};
use crate::spectrum::Spectrum;

use super::config::{resolve, SensorConfig};
use super::otf::SystemOtf;
use super::presets;

/// Wavelength (µm) beyond which a response counts as thermal: a sensor whose response
/// reaches past it sees thermal emission, so apparent temperature is a meaningful product.
pub const THERMAL_LIMIT_UM: f64 = 3.0;

/// Temperature of the solar photosphere used for white balance, K (a 5772 K blackbody is
/// the IAU nominal effective temperature of the Sun).
pub const SUN_TEMPERATURE_K: f64 = 5772.0;

/// Longest wavelength of the white-balance band integral, µm (the solar spectrum beyond it
/// is negligible for a colour camera).
const WHITE_BALANCE_MAX_UM: f64 = 50.0;

/// A sensor resolved for running: the configuration it came from plus everything derived
/// from it. Read the schema fields through [`Sensor::config`] (or directly: `Sensor`
/// dereferences to its [`SensorConfig`], so `sensor.detector.rows` and `sensor.ifov_rad()`
/// read the configuration).
#[derive(Debug, Clone)]
pub struct Sensor {
    config: SensorConfig,
    response: Spectrum,
    filter_qe: Spectrum,
    chain: Spectra,
    camera: CameraEquation,
    otf: SystemOtf,
    detector: DetectorModel,
    channels: Vec<Sensor>,
    white_balance: Option<[f64; 3]>,
    warnings: Vec<String>,
    /// The measured line-of-sight trajectory (`trajectory.file`), read once here.
    measured_trajectory: Option<crate::los::MeasuredTrajectory>,
}

impl Deref for Sensor {
    type Target = SensorConfig;

    fn deref(&self) -> &SensorConfig {
        &self.config
    }
}

/// The spectra a sensor file names, each built (and any CSV read) once: the factors of
/// the spectral response ([`Sensor::spectral_chain`]).
#[derive(Debug, Clone)]
pub struct Spectra {
    /// Filter transmission (`[filter]`; for a colour-filter-array channel, times its dye).
    pub filter: Spectrum,
    /// Optics transmission (`optics.transmission`).
    pub optics: Spectrum,
    /// Quantum efficiency (`detector.quantum_efficiency`).
    pub qe: Spectrum,
    /// Path transmission (`[atmosphere]`), if the file has one.
    pub atmosphere: Option<Spectrum>,
}

impl Spectra {
    /// Builds the curves, refusing a transmission, filter or quantum efficiency above 1.
    fn build(config: &SensorConfig) -> Result<Self> {
        let dir = &config.base_dir;
        let fraction = crate::spectrum::require_fraction;
        Ok(Spectra {
            filter: fraction("filter", config.filter.build(dir, "filter")?)?,
            optics: fraction(
                "optics.transmission",
                config
                    .optics
                    .transmission
                    .build(dir, "optics.transmission")?,
            )?,
            qe: fraction(
                "detector.quantum_efficiency",
                config
                    .detector
                    .quantum_efficiency
                    .build(dir, "detector.quantum_efficiency")?,
            )?,
            atmosphere: config
                .atmosphere
                .as_ref()
                .map(|a| {
                    fraction(
                        "atmosphere.transmission",
                        a.transmission.build(dir, "atmosphere.transmission")?,
                    )
                })
                .transpose()?,
        })
    }

    /// The dimensionless response of the chain behind `filter`, electrons per photon at
    /// the aperture: τ_filter · τ_optics · η · τ_atm (docs/design.md §1, spectral chain).
    fn chain(&self, filter: &Spectrum) -> Spectrum {
        let s = filter.product(&self.optics).product(&self.qe);
        match &self.atmosphere {
            Some(a) => s.product(a),
            None => s,
        }
    }
}

impl Sensor {
    /// Validates `config` and resolves it (see the module documentation).
    ///
    /// Errors: any invalid value (naming the field), an unreadable or malformed file the
    /// configuration refers to (naming the path), or a detector whose auto-gain reference
    /// gives no signal.
    pub fn build(config: &SensorConfig) -> Result<Sensor> {
        config.validate()?;
        let spectra = Spectra::build(config)?;
        let response = spectra.chain(&spectra.filter);
        let camera = config.camera_equation()?;
        let otf = SystemOtf::new(config, measured_mtf(config)?)?;
        let filter_qe = spectra.filter.product(&spectra.qe);
        let detector = DetectorModel::build(
            &config.detector,
            &DetectorInputs {
                response: &response,
                filter_qe: &filter_qe,
                camera: &camera,
                base_dir: &config.base_dir,
            },
        )?;
        let warnings = config.warnings();
        let measured_trajectory = match config.trajectory.as_ref().and_then(|t| t.file.as_ref()) {
            Some(file) => Some(crate::los::MeasuredTrajectory::from_csv(
                &crate::spectrum::resolve_path(&config.base_dir, file),
            )?),
            None => None,
        };
        let mut channels = Vec::new();
        if let Some(cfa) = &config.cfa {
            let dir = &config.base_dir;
            let dyes = [
                cfa.red.build(dir, "cfa.red")?,
                cfa.green.build(dir, "cfa.green")?,
                cfa.blue.build(dir, "cfa.blue")?,
            ];
            for (c, dye) in dyes.iter().enumerate() {
                let channel_config = presets::cfa_channel_with(config, c, &spectra.filter, dye)?;
                let filter = channel_config.filter.build(dir, "filter")?;
                channels.push(Sensor {
                    response: spectra.chain(&filter),
                    filter_qe: filter.product(&spectra.qe),
                    chain: Spectra {
                        filter,
                        ..spectra.clone()
                    },
                    config: channel_config,
                    camera,
                    otf: otf.clone(),
                    detector: detector.clone(),
                    channels: Vec::new(),
                    white_balance: None,
                    measured_trajectory: measured_trajectory.clone(),
                    warnings: warnings.clone(),
                });
            }
        }
        let white_balance = white_balance(&channels, &camera)?;
        Ok(Sensor {
            config: config.clone(),
            response,
            filter_qe,
            chain: spectra,
            camera,
            otf,
            detector,
            channels,
            white_balance,
            warnings,
            measured_trajectory,
        })
    }

    /// The measured line-of-sight trajectory of `trajectory.file`, read when the sensor
    /// was built (`None` without one).
    pub fn measured_trajectory(&self) -> Option<&crate::los::MeasuredTrajectory> {
        self.measured_trajectory.as_ref()
    }

    /// Filter transmission × quantum efficiency (electrons per photon reaching the filter,
    /// optics and atmosphere left out): what a flat-field photon-transfer measurement sees.
    pub fn filter_qe(&self) -> &Spectrum {
        &self.filter_qe
    }

    /// The configuration this sensor was built from (written as `config.toml`).
    pub fn config(&self) -> &SensorConfig {
        &self.config
    }

    /// The dimensionless spectral response of the chain, electrons per photon at the
    /// aperture: τ_filter · τ_optics · η · τ_atm (docs/design.md §1).
    pub fn response(&self) -> &Spectrum {
        &self.response
    }

    /// The factors of [`Sensor::response`]: filter, optics, quantum efficiency and
    /// atmosphere, as the sensor file gives them (for plots and reports).
    pub fn spectral_chain(&self) -> &Spectra {
        &self.chain
    }

    /// The on-axis camera equation (docs/design.md §4.1).
    pub fn camera(&self) -> &CameraEquation {
        &self.camera
    }

    /// The cascade of enabled transfer functions.
    pub fn otf(&self) -> &SystemOtf {
        &self.otf
    }

    /// The detector model (electrons → DN) with its conversion gain.
    pub fn detector(&self) -> &DetectorModel {
        &self.detector
    }

    /// For a colour-filter-array sensor the single-colour sensors under the red, green and
    /// blue filters (indices [`crate::cfa::RED`], `GREEN`, `BLUE`; each with the response
    /// `τ_filter · τ_cfa,c · τ_optics · η · τ_atm` and the whole array's detector model);
    /// empty otherwise.
    pub fn cfa_channels(&self) -> &[Sensor] {
        &self.channels
    }

    /// For a colour-filter-array sensor the gain of each colour channel that makes a
    /// spectrally grey surface lit by the sun (radiance shaped like a 5772 K blackbody)
    /// give the same signal as green.
    pub fn white_balance(&self) -> Option<[f64; 3]> {
        self.white_balance
    }

    /// Whether the response reaches beyond [`THERMAL_LIMIT_UM`] (thermal emission is
    /// seen, so calibration to apparent temperature is meaningful).
    pub fn is_thermal(&self) -> bool {
        self.response.support_um().1 > THERMAL_LIMIT_UM
    }

    /// Things in the configuration that are valid but probably not what the user meant
    /// (the detector's own warnings are [`DetectorModel::warnings`]).
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The conversion gain K (DN/e-) that the auto-gain reference `config` gives this
    /// sensor, whatever its own `gain_dn_per_e` or `[detector.auto_gain]` say: the
    /// reference signal plus dark and background electrons lands at `config.fraction` of
    /// `2^bits − 1 − offset_dn` (see [`crate::detector::reference_electrons`]).
    ///
    /// Errors: an invalid `config`, or a reference that gives no signal in the band.
    pub fn auto_gain(&self, config: &AutoGainConfig) -> Result<f64> {
        let mut d = self.config.detector.clone();
        d.gain_dn_per_e = None;
        d.auto_gain = Some(config.clone());
        crate::detector::config::validate_effects(&d)?;
        Ok(self
            .detector
            .auto_gain_for(&d, &self.response, &self.camera, config)?
            .0)
    }
}

/// The measured MTF of the `[measured]` section: its CSV table (read here, once, relative
/// to the sensor file) or the inline `freq_cy_per_mrad` / `mtf` lists. `None` without the
/// section.
fn measured_mtf(config: &SensorConfig) -> Result<Option<MeasuredMtf>> {
    let Some(m) = &config.measured else {
        return Ok(None);
    };
    Ok(Some(match (&m.csv, &m.freq_cy_per_mrad, &m.mtf) {
        (Some(path), _, _) => MeasuredMtf::from_csv(&resolve(&config.base_dir, path))?,
        (None, Some(f), Some(v)) => MeasuredMtf::new(f.clone(), v.clone())?,
        _ => {
            return Err(Error::param(
                "measured",
                "incomplete",
                "either `csv` or both `freq_cy_per_mrad` and `mtf`",
            ))
        }
    }))
}

/// White-balance gains of the three colour channels: each channel is scaled so that a
/// spectrally grey surface lit by the sun (radiance ∝ B(λ, 5772 K)) gives the same mean
/// electrons as green, `g_c = e_green / e_c` with `e_c` the camera equation of the channel
/// (docs/design.md §4.1). `None` without a colour filter array.
fn white_balance(channels: &[Sensor], camera: &CameraEquation) -> Result<Option<[f64; 3]>> {
    if channels.len() != 3 {
        return Ok(None);
    }
    let mut e = [0.0; 3];
    for (c, s) in channels.iter().enumerate() {
        let (lo, hi) = s.response.support_um();
        let sun = |l: f64| planck_spectral_radiance(l, SUN_TEMPERATURE_K);
        e[c] = camera.electrons_spectral(&s.response, sun, lo, hi.min(WHITE_BALANCE_MAX_UM))?;
    }
    Ok(Some(e.map(|v| if v > 0.0 { e[1] / v } else { 1.0 })))
}
