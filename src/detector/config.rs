//! The optional `[detector.*]` sub-tables of a sensor file that switch detector effects on,
//! and their validation.
//!
//! Every effect is off when its key or table is absent (shot noise excepted: it is on
//! unless `shot_noise = false`). The whole `[detector]` table ([`DetectorConfig`]) lives here,
//! next to the model that uses it; [`crate::sensor::SensorConfig`] holds it as its `detector`
//! field. This module depends on nothing in `sensor` but the [`SpectrumConfig`] leaf type.
//!
//! ```toml
//! [detector]
//! dark_current_e_per_s = 2e5
//! read_noise_e = 150.0
//! shot_noise = true
//! [detector.dark_model]
//! kind = "diffusion"
//! fpa_temperature_k = 80.0
//! reference_temperature_k = 77.0
//! reference_e_per_s = 2e5
//! bandgap_ev = 0.25
//! [detector.background]
//! temperature_k = 293.0
//! emissivity = 0.05
//! [detector.fpn]
//! prnu_sigma_rel = 0.01
//! dsnu_sigma_e = 200.0
//! bias_gain_correlation = 0.5
//! correlation_length_px = 0.0
//! column_sigma_e = 0.0
//! row_sigma_e = 0.0
//! [detector.nonlinearity]
//! quadratic_mean_per_e = -1e-9
//! quadratic_sigma_per_e = 1e-10
//! [detector.defects]
//! dead_fraction = 0.001
//! hot_fraction = 0.0005
//! stuck_fraction = 0.0
//! [detector.auto_gain]
//! reference_temperature_k = 300.0
//! fraction = 0.5
//! ```

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::constants::BOLTZMANN_K;
use crate::error::{require_in_range, require_non_negative, require_positive, Error, Result};
use crate::spectrum::SpectrumConfig;

/// Elementary charge, C (SI 2019 exact): converts eV to J.
const ELEMENTARY_CHARGE_C: f64 = 1.602_176_634e-19;

/// `[detector]`: the focal-plane array and its electronics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DetectorConfig {
    /// Number of pixel rows.
    pub rows: usize,
    /// Number of pixel columns.
    pub cols: usize,
    /// Pixel pitch (centre-to-centre spacing), m, the same in x and y.
    pub pitch_m: f64,
    /// Photosensitive width of a pixel along x, m (≤ pitch).
    pub active_width_m: f64,
    /// Photosensitive height along y, m (defaults to `active_width_m`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub active_height_m: Option<f64>,
    /// Include the detector footprint transfer function `sinc(f·w/F)` in the cascade
    /// (`false`: pixels sample the image at their centres, e.g. for the unblurred
    /// reference of a run).
    #[serde(default = "footprint_on", skip_serializing_if = "is_footprint_on")]
    pub footprint_enabled: bool,
    /// Integration (exposure) time, s.
    pub integration_time_s: f64,
    /// Quantum efficiency η(λ), electrons per photon.
    pub quantum_efficiency: SpectrumConfig,
    /// Full-well capacity, electrons.
    #[serde(default = "default_full_well")]
    pub full_well_e: f64,
    /// ADC resolution, bits (1–16).
    #[serde(default = "default_bits")]
    pub bits: u32,
    /// Conversion gain K, DN per electron. Omitted: chosen so that `full_well_e` maps to
    /// full scale.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gain_dn_per_e: Option<f64>,
    /// Black level (offset) added after conversion, DN.
    #[serde(default)]
    pub offset_dn: f64,
    /// Constant dark current, electrons per second per pixel (absent or 0 = off).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dark_current_e_per_s: Option<f64>,
    /// Temperature-dependent dark current instead of the constant (see
    /// [`DarkModelConfig`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dark_model: Option<DarkModelConfig>,
    /// Gaussian read noise, electrons rms (absent or 0 = off).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub read_noise_e: Option<f64>,
    /// Poisson shot noise on signal + dark + background (absent = on).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shot_noise: Option<bool>,
    /// Optics self-emission background (see [`BackgroundConfig`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub background: Option<BackgroundConfig>,
    /// Fixed-pattern noise (see [`FpnConfig`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fpn: Option<FpnConfig>,
    /// Per-pixel quadratic nonlinearity (see [`NonlinearityConfig`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nonlinearity: Option<NonlinearityConfig>,
    /// Dead, hot and stuck pixels (see [`DefectsConfig`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub defects: Option<DefectsConfig>,
    /// Conversion gain chosen from a reference scene (see
    /// [`AutoGainConfig`]); excludes `gain_dn_per_e`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub auto_gain: Option<AutoGainConfig>,
    /// Readout-ordered correlated noise and crosstalk between outputs (see
    /// [`super::readout::ReadoutNoiseConfig`]; docs/focal-plane.md).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub readout_noise: Option<super::readout::ReadoutNoiseConfig>,
    /// Random telegraph pixels (see [`super::rts::RtsConfig`]; needs `[clock]`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rts: Option<super::rts::RtsConfig>,
    /// Persistence: charge trapped in bright frames and released later (see
    /// [`super::persistence::PersistenceConfig`]; needs `[clock]`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub persistence: Option<super::persistence::PersistenceConfig>,
    /// Inter-pixel capacitance (see [`super::ipc::IpcConfig`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ipc: Option<super::ipc::IpcConfig>,
    /// Drift of the fixed pattern over the sequence (see [`super::drift::DriftConfig`];
    /// needs `[clock]`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drift: Option<super::drift::DriftConfig>,
}

fn footprint_on() -> bool {
    true
}

fn is_footprint_on(v: &bool) -> bool {
    *v
}

fn default_full_well() -> f64 {
    1.0e7
}

fn default_bits() -> u32 {
    14
}

impl DetectorConfig {
    /// Photosensitive height along y, m.
    pub fn active_height(&self) -> f64 {
        self.active_height_m.unwrap_or(self.active_width_m)
    }

    /// Fill factor = active area / pitch².
    pub fn fill_factor(&self) -> f64 {
        self.active_width_m * self.active_height() / (self.pitch_m * self.pitch_m)
    }

    /// Photosensitive area A_det, m².
    pub fn active_area_m2(&self) -> f64 {
        self.active_width_m * self.active_height()
    }

    /// Largest DN the ADC can output, 2^bits − 1.
    pub fn max_dn(&self) -> f64 {
        2f64.powi(self.bits as i32) - 1.0
    }

    /// Conversion gain K, DN/e-, before any auto gain: the configured value, or full well
    /// → full scale. The gain in use is `DetectorModel::gain_dn_per_e` (which applies
    /// `[detector.auto_gain]`).
    pub fn manual_gain(&self) -> f64 {
        self.gain_dn_per_e
            .unwrap_or_else(|| (self.max_dn() - self.offset_dn) / self.full_well_e)
    }
}

/// `[detector.dark_model]`: a temperature-dependent dark current, used instead of the
/// constant `dark_current_e_per_s`. Selected by `kind`; every kind is scaled so that the
/// rate at `reference_temperature_k` is `reference_e_per_s`:
///
/// `I(T) = I_ref · (T/T_ref)^p · exp(−(E_a/k)·(1/T − 1/T_ref))`
///
/// with k Boltzmann's constant and (p, E_a) given by the kind. The bandgap is taken as
/// constant over the temperature range (its Varshni temperature dependence is neglected).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum DarkModelConfig {
    /// Diffusion-limited photodiode (the usual case for cooled HgCdTe/InSb near and above
    /// their design temperature): `I ∝ n_i² ∝ T³ exp(−E_g/kT)`, i.e. p = 3, E_a = E_g
    /// (Sze & Ng, *Physics of Semiconductor Devices*, 3rd ed. 2007, §2.5 for n_i and §13
    /// for the diffusion current; Rogalski, *Infrared Detectors*, 2nd ed. 2011, ch. 9).
    Diffusion {
        /// Focal-plane-array operating temperature T, K.
        fpa_temperature_k: f64,
        /// Temperature at which `reference_e_per_s` was measured, K.
        reference_temperature_k: f64,
        /// Dark current at the reference temperature, electrons per second per pixel.
        reference_e_per_s: f64,
        /// Bandgap E_g of the absorber, eV.
        bandgap_ev: f64,
    },
    /// Generation–recombination in the depletion region (silicon CCD/CMOS at room
    /// temperature, IR diodes at low temperature): `I ∝ n_i ∝ T^{3/2} exp(−E_g/2kT)`, i.e.
    /// p = 1.5, E_a = E_g/2 (Janesick, *Scientific Charge-Coupled Devices*, SPIE 2001,
    /// dark-current chapter; Sze & Ng 2007).
    GenerationRecombination {
        /// Focal-plane-array operating temperature T, K.
        fpa_temperature_k: f64,
        /// Temperature at which `reference_e_per_s` was measured, K.
        reference_temperature_k: f64,
        /// Dark current at the reference temperature, electrons per second per pixel.
        reference_e_per_s: f64,
        /// Bandgap E_g of the absorber, eV.
        bandgap_ev: f64,
    },
    /// A general Arrhenius law with an explicit activation energy and temperature
    /// exponent (e.g. fitted to measurements).
    Arrhenius {
        /// Focal-plane-array operating temperature T, K.
        fpa_temperature_k: f64,
        /// Temperature at which `reference_e_per_s` was measured, K.
        reference_temperature_k: f64,
        /// Dark current at the reference temperature, electrons per second per pixel.
        reference_e_per_s: f64,
        /// Activation energy E_a, eV.
        activation_energy_ev: f64,
        /// Exponent p of the `(T/T_ref)^p` pre-factor (default 0).
        #[serde(default)]
        temperature_exponent: f64,
    },
}

impl DarkModelConfig {
    /// `(T, T_ref, I_ref, p, E_a in eV)` of the model.
    fn parts(&self) -> (f64, f64, f64, f64, f64) {
        match *self {
            DarkModelConfig::Diffusion {
                fpa_temperature_k,
                reference_temperature_k,
                reference_e_per_s,
                bandgap_ev,
            } => (
                fpa_temperature_k,
                reference_temperature_k,
                reference_e_per_s,
                3.0,
                bandgap_ev,
            ),
            DarkModelConfig::GenerationRecombination {
                fpa_temperature_k,
                reference_temperature_k,
                reference_e_per_s,
                bandgap_ev,
            } => (
                fpa_temperature_k,
                reference_temperature_k,
                reference_e_per_s,
                1.5,
                0.5 * bandgap_ev,
            ),
            DarkModelConfig::Arrhenius {
                fpa_temperature_k,
                reference_temperature_k,
                reference_e_per_s,
                activation_energy_ev,
                temperature_exponent,
            } => (
                fpa_temperature_k,
                reference_temperature_k,
                reference_e_per_s,
                temperature_exponent,
                activation_energy_ev,
            ),
        }
    }

    /// Dark current at the FPA temperature, electrons per second per pixel:
    /// `I_ref · (T/T_ref)^p · exp(−(E_a/k)(1/T − 1/T_ref))` (see the type's documentation).
    pub fn rate_e_per_s(&self) -> f64 {
        let (t, t_ref, i_ref, p, ea_ev) = self.parts();
        dark_rate_e_per_s(t, t_ref, i_ref, p, ea_ev)
    }

    /// Checks every value, naming the field (`detector.dark_model.<field>`).
    pub fn validate(&self) -> Result<()> {
        let (t, t_ref, i_ref, p, ea) = self.parts();
        require_positive("detector.dark_model.fpa_temperature_k", t)?;
        require_positive("detector.dark_model.reference_temperature_k", t_ref)?;
        require_non_negative("detector.dark_model.reference_e_per_s", i_ref)?;
        let energy_field = match self {
            DarkModelConfig::Arrhenius { .. } => "detector.dark_model.activation_energy_ev",
            _ => "detector.dark_model.bandgap_ev",
        };
        require_non_negative(energy_field, ea)?;
        if !p.is_finite() {
            return Err(Error::param(
                "detector.dark_model.temperature_exponent",
                p,
                "a finite number",
            ));
        }
        let rate = self.rate_e_per_s();
        if !rate.is_finite() {
            return Err(Error::param(
                "detector.dark_model",
                rate,
                "parameters giving a finite dark current (check the temperatures and energy)",
            ));
        }
        Ok(())
    }
}

/// Temperature-scaled dark current, e-/s: `I_ref · (T/T_ref)^p · exp(−(E_a/k)(1/T − 1/T_ref))`
/// with `E_a` in eV and k Boltzmann's constant (see [`DarkModelConfig`] for the sources).
pub fn dark_rate_e_per_s(
    temperature_k: f64,
    reference_temperature_k: f64,
    reference_e_per_s: f64,
    exponent: f64,
    activation_energy_ev: f64,
) -> f64 {
    let ea_over_k = activation_energy_ev * ELEMENTARY_CHARGE_C / BOLTZMANN_K;
    reference_e_per_s
        * (temperature_k / reference_temperature_k).powf(exponent)
        * (-ea_over_k * (1.0 / temperature_k - 1.0 / reference_temperature_k)).exp()
}

/// `[detector.background]`: self-emission of the (warm) optics and housing seen by the
/// detector, modelled as a grey body of `emissivity` at `temperature_k` filling the
/// optical cone. Its electrons are the camera equation (docs/design.md §4.1) applied to
/// `ε·B(λ, T)` through the filter and the quantum efficiency only (the emitter sits inside
/// the optics, so τ_optics and τ_atm do not attenuate it).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BackgroundConfig {
    /// Temperature of the emitting optics, K.
    pub temperature_k: f64,
    /// Emissivity ε of the optics (0–1), e.g. 1 − τ_optics for absorbing lenses.
    pub emissivity: f64,
}

/// `[detector.fpn]`: fixed-pattern noise, drawn once per sensor instance.
///
/// Gain `g = (1 + σ_g z_g) · G_file` and offset
/// `o = σ_o (ρ z_g + √(1−ρ²) z_o) + c_j + r_i + O_file` (electrons), with z_g, z_o unit
/// normal fields (white, or spatially correlated when `correlation_length_px > 0`), ρ the
/// bias–gain correlation (Renhorn's correlated bias/gain model, FOI report eq. 2.46–2.48,
/// as a bivariate normal drawn with a 2×2 Cholesky factor), c_j and r_i per-column and
/// per-row offsets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FpnConfig {
    /// Photo-response non-uniformity σ_g: rms of the relative gain (0.01 = 1 %).
    #[serde(default)]
    pub prnu_sigma_rel: f64,
    /// Dark-signal non-uniformity σ_o: rms of the pixel offset, electrons.
    #[serde(default)]
    pub dsnu_sigma_e: f64,
    /// Correlation coefficient ρ between a pixel's gain and offset deviations, [−1, 1].
    #[serde(default)]
    pub bias_gain_correlation: f64,
    /// Spatial correlation length L, pixels: the gain and offset patterns have the
    /// autocorrelation `exp(−(d/L)²)` at lag d (Gaussian-filtered white noise). 0 = white.
    #[serde(default)]
    pub correlation_length_px: f64,
    /// rms of a per-column offset, electrons.
    #[serde(default)]
    pub column_sigma_e: f64,
    /// rms of a per-row offset, electrons.
    #[serde(default)]
    pub row_sigma_e: f64,
    /// Measured relative gain map (32-bit float TIFF, rows × cols, mean ≈ 1), multiplied
    /// into the gain; relative to the sensor file's directory.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gain_map: Option<PathBuf>,
    /// Measured offset map in electrons (32-bit float TIFF, rows × cols), added to the
    /// offset; relative to the sensor file's directory.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub offset_map: Option<PathBuf>,
}

/// Largest correlation length accepted, pixels (the filter costs O(L) per pixel).
pub const MAX_CORRELATION_LENGTH_PX: f64 = 256.0;

/// `[detector.nonlinearity]`: a per-pixel quadratic response `e' = e + a·e²`, with a drawn
/// once per instance from N(`quadratic_mean_per_e`, `quadratic_sigma_per_e`²).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NonlinearityConfig {
    /// Mean quadratic coefficient a, per electron (negative = compressive).
    #[serde(default)]
    pub quadratic_mean_per_e: f64,
    /// Pixel-to-pixel rms of a, per electron.
    #[serde(default)]
    pub quadratic_sigma_per_e: f64,
}

/// `[detector.defects]`: defective pixels, drawn once per instance (each kind from its own
/// random stream; where two kinds fall on one pixel, dead wins over hot over stuck).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DefectsConfig {
    /// Probability that a pixel is dead (always DN 0).
    #[serde(default)]
    pub dead_fraction: f64,
    /// Probability that a pixel is hot (always full scale, 2^bits − 1).
    #[serde(default)]
    pub hot_fraction: f64,
    /// Probability that a pixel is stuck at a fixed random DN (uniform over the ADC range).
    #[serde(default)]
    pub stuck_fraction: f64,
    /// Measured defect map: 16-bit TIFF, rows × cols, 0 ok, 1 dead, 2 hot, 3 stuck;
    /// relative to the sensor file's directory. Random defects are added where it says 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub map: Option<PathBuf>,
}

/// The reference scene that [`AutoGainConfig`] places at `fraction` of full scale.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AutoGainReference {
    /// A uniform blackbody at `reference_temperature_k` (thermal sensors).
    Blackbody,
    /// A Lambertian reflector of `reflectance` under the Sun at `sun_zenith_deg`
    /// (reflective-band sensors).
    ReflectedSun,
    /// The mean of the scene being imaged (FOI report §4.2: the three-band camera's gain
    /// puts the NIR band's scene mean at half range). K is set by the run once the first
    /// frame's mean electrons are known (`DetectorModel::set_gain_from_scene_mean`).
    SceneMean,
}

/// `[detector.auto_gain]`: choose K so that a reference scene lands at `fraction` of the
/// ADC range above the offset (FOI report §2.2.2: half the dynamic range for a 300 K
/// source in the thermal IR; reflected sunlight in the visible). Cannot be combined with
/// `gain_dn_per_e`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AutoGainConfig {
    /// Reference blackbody temperature, K (blackbody reference).
    #[serde(default = "default_reference_temperature_k")]
    pub reference_temperature_k: f64,
    /// Fraction of `2^bits − 1 − offset_dn` the reference maps to, (0, 1].
    #[serde(default = "default_fraction")]
    pub fraction: f64,
    /// Reference scene; omitted: reflected sun when the whole spectral response lies
    /// below [`crate::detector::REFLECTIVE_LIMIT_UM`], else the blackbody.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference: Option<AutoGainReference>,
    /// Lambertian reflectance of the reflected-sun reference (default 0.2).
    #[serde(default = "default_reflectance")]
    pub reflectance: f64,
    /// Solar zenith angle of the reflected-sun reference, degrees (default 45).
    #[serde(default = "default_sun_zenith_deg")]
    pub sun_zenith_deg: f64,
}

fn default_reference_temperature_k() -> f64 {
    300.0
}
fn default_fraction() -> f64 {
    0.5
}
fn default_reflectance() -> f64 {
    0.2
}
fn default_sun_zenith_deg() -> f64 {
    45.0
}

/// Checks the detector-effect fields of `d` (everything added for the detector model),
/// naming the offending field. Called from [`crate::sensor::SensorConfig::validate`].
pub fn validate_effects(d: &DetectorConfig) -> Result<()> {
    if let Some(r) = d.dark_current_e_per_s {
        require_non_negative("detector.dark_current_e_per_s", r)?;
    }
    if let Some(m) = &d.dark_model {
        if d.dark_current_e_per_s.is_some_and(|r| r > 0.0) {
            return Err(Error::param(
                "detector.dark_model",
                "given together with dark_current_e_per_s",
                "either a constant `dark_current_e_per_s` or a `[detector.dark_model]`, not both",
            ));
        }
        m.validate()?;
    }
    if let Some(r) = d.read_noise_e {
        require_non_negative("detector.read_noise_e", r)?;
    }
    if let Some(b) = &d.background {
        require_positive("detector.background.temperature_k", b.temperature_k)?;
        require_in_range("detector.background.emissivity", b.emissivity, 0.0, 1.0)?;
    }
    if let Some(f) = &d.fpn {
        require_in_range("detector.fpn.prnu_sigma_rel", f.prnu_sigma_rel, 0.0, 1.0)?;
        require_non_negative("detector.fpn.dsnu_sigma_e", f.dsnu_sigma_e)?;
        require_in_range(
            "detector.fpn.bias_gain_correlation",
            f.bias_gain_correlation,
            -1.0,
            1.0,
        )?;
        require_in_range(
            "detector.fpn.correlation_length_px",
            f.correlation_length_px,
            0.0,
            MAX_CORRELATION_LENGTH_PX,
        )?;
        require_non_negative("detector.fpn.column_sigma_e", f.column_sigma_e)?;
        require_non_negative("detector.fpn.row_sigma_e", f.row_sigma_e)?;
    }
    if let Some(n) = &d.nonlinearity {
        if !n.quadratic_mean_per_e.is_finite() {
            return Err(Error::param(
                "detector.nonlinearity.quadratic_mean_per_e",
                n.quadratic_mean_per_e,
                "a finite number (per electron)",
            ));
        }
        require_non_negative(
            "detector.nonlinearity.quadratic_sigma_per_e",
            n.quadratic_sigma_per_e,
        )?;
    }
    if let Some(x) = &d.defects {
        require_in_range("detector.defects.dead_fraction", x.dead_fraction, 0.0, 1.0)?;
        require_in_range("detector.defects.hot_fraction", x.hot_fraction, 0.0, 1.0)?;
        require_in_range(
            "detector.defects.stuck_fraction",
            x.stuck_fraction,
            0.0,
            1.0,
        )?;
    }
    if let Some(r) = &d.readout_noise {
        r.validate(d.rows, d.cols)?;
    }
    if let Some(r) = &d.rts {
        r.validate()?;
    }
    if let Some(p) = &d.persistence {
        p.validate()?;
    }
    if let Some(i) = &d.ipc {
        i.validate()?;
    }
    if let Some(x) = &d.drift {
        x.validate()?;
    }
    if let Some(a) = &d.auto_gain {
        if d.gain_dn_per_e.is_some() {
            return Err(Error::param(
                "detector.auto_gain",
                "given together with gain_dn_per_e",
                "either a fixed `gain_dn_per_e` or `[detector.auto_gain]`, not both",
            ));
        }
        require_positive(
            "detector.auto_gain.reference_temperature_k",
            a.reference_temperature_k,
        )?;
        if !(a.fraction.is_finite() && a.fraction > 0.0 && a.fraction <= 1.0) {
            return Err(Error::param(
                "detector.auto_gain.fraction",
                a.fraction,
                "a fraction of full scale in (0, 1]",
            ));
        }
        if !(a.reflectance.is_finite() && a.reflectance > 0.0 && a.reflectance <= 1.0) {
            return Err(Error::param(
                "detector.auto_gain.reflectance",
                a.reflectance,
                "a reflectance in (0, 1]",
            ));
        }
        if !(a.sun_zenith_deg.is_finite() && (0.0..90.0).contains(&a.sun_zenith_deg)) {
            return Err(Error::param(
                "detector.auto_gain.sun_zenith_deg",
                a.sun_zenith_deg,
                "a zenith angle in [0, 90) degrees",
            ));
        }
    }
    Ok(())
}
