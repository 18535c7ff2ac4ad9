//! Built-in synthetic scenes: physically based spectral radiance cubes for testing and
//! demonstrating the sensor model from the visible to the LWIR.
//!
//! # Radiance model
//!
//! Every surface pixel is an opaque Lambertian surface at a physical temperature `T`:
//!
//! `L(λ) = ε(λ)·B(λ, T) + (1 − ε(λ))·[L_sky(λ) + E_dir(λ)/π]`,  `ε = 1 − ρ` (Kirchhoff)
//!
//! with `B` Planck's law ([`planck_spectral_radiance`], W m-2 sr-1 µm-1), `ρ` the
//! hemispherical reflectance of the surface material ([`Material`]), `L_sky` the downwelling
//! sky radiance averaged over the hemisphere with the cosine weight (`E_sky/π`), and `E_dir`
//! the direct solar irradiance on a horizontal surface (zero at night or in shadow). All
//! surfaces use the horizontal-surface irradiance; orientation effects are not modelled.
//!
//! # Atmosphere and sun ([`Environment`])
//!
//! - Top-of-atmosphere solar spectral irradiance `E₀(λ) = B(λ, 5772 K)·Ω_sun`, with
//!   `Ω_sun = π (R_sun / au)² = 6.794e-5 sr` (IAU 2015 nominal R_sun = 6.957e8 m and
//!   effective temperature 5772 K, Resolution B3). Its integral over λ is σT⁴Ω/π ≈ 1361 W m-2,
//!   the measured total solar irradiance (Kopp & Lean 2011).
//! - Direct beam on the ground: `E_dir = E₀ · cos θz · exp(−τ(λ)·m(θz))` with `τ` the zenith
//!   extinction optical depth (Rayleigh after Hansen & Travis 1974, aerosol after Ångström's
//!   law, molecular absorption from a smooth analytic band model, [`molecular_optical_depth`])
//!   and `m` the Kasten & Young (1989) relative air mass ([`relative_airmass`]).
//! - Sky radiance looking up at elevation `e`: thermal emission of an isothermal absorbing
//!   atmosphere `(1 − exp(−τ_abs·m(e)))·B(λ, T_air)` plus, in daylight, singly scattered
//!   sunlight for a plane-parallel atmosphere with an isotropic phase function
//!   `L = ω E₀/(4π) · μ₀/(μ₀ − μ) · (e^{−τ/μ₀} − e^{−τ/μ})` (the classical single-scattering
//!   solution, e.g. Liou, *An Introduction to Atmospheric Radiation*, 2002), with the
//!   air masses `m = 1/μ` taken from Kasten & Young so the horizon stays finite.
//!   The hemispheric downwelling term is the cosine-weighted average of this sky radiance,
//!   computed by quadrature. There is no moon or airglow: the night sky is thermal only.
//!
//! This is a documented caricature of a clear mid-latitude atmosphere, not a radiative
//! transfer code: it gets the qualitative behaviour right (blue daylight sky, warm horizon
//! and cold zenith in the LWIR window, opaque water and CO₂ bands) and is smooth in λ, so any
//! wavelength grid can be used.
//!
//! # Scenes
//!
//! [`thermal`] (a vehicle on textured terrain under a sky strip), [`bars`] (4-bar targets
//! at frequencies tied to the detector Nyquist frequency), [`edge`] (slanted edge),
//! [`blackbody`] (uniform) and [`ramp`] (temperature linear in x). The test patterns (bars,
//! edge, blackbody, ramp) are laboratory targets: they show emitted radiance only, as seen
//! in a collimator with a cold surround, and ignore `sun`.
//!
//! All scenes are sized relative to the image, so any `rows × cols` works; the cube has
//! `rows·k × cols·k` pixels for an oversampling factor `k`, and a detector pixel is centred on
//! its `k × k` block of scene pixels.

use ndarray::parallel::prelude::*;
use ndarray::{Array2, Array3, Axis};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

use super::{Cube, CubeMeta, Geometry, RadianceUnits};
use crate::constants::{BOLTZMANN_K, PLANCK_H, SPEED_OF_LIGHT_C};
use crate::error::{Error, Result};
use crate::radiometry::planck_spectral_radiance;

/// Effective temperature of the Sun, K (IAU 2015 Resolution B3 nominal value).
pub const SUN_TEMPERATURE_K: f64 = 5772.0;

/// Solid angle of the solar disc seen from 1 au, sr: `π (R_sun/au)²` with the IAU nominal
/// solar radius 6.957e8 m and au = 1.495978707e11 m.
pub const SUN_SOLID_ANGLE_SR: f64 = 6.794e-5;

/// Largest oversampling factor accepted by [`SceneParams::validate`].
pub const MAX_OVERSAMPLING: usize = 64;

/// Largest cube accepted by [`SceneParams::validate`], in values (bands × rows × cols):
/// 2³² f32 values are 16 GiB.
pub const MAX_CUBE_VALUES: u64 = 1 << 32;

/// Highest temperature a scene accepts, K.
pub const MAX_TEMPERATURE_K: f64 = 10_000.0;

/// Default tilt of the slanted edge from the vertical, degrees.
pub const DEFAULT_EDGE_ANGLE_DEG: f64 = 5.0;

/// The scene kinds by name for the CLI, with a one-line description each.
pub const KINDS: &[(&str, &str)] = &[
    (
        "thermal",
        "vehicle (hull, turret, tracks, hot exhaust) on textured vegetation/soil terrain under a sky strip",
    ),
    (
        "bars",
        "4-bar targets (7:1 bars) at up to 6 frequencies spaced by sqrt(2) up to the detector Nyquist frequency",
    ),
    ("edge", "slanted edge through the centre, area-weighted edge pixels"),
    ("blackbody", "uniform blackbody (or grey body) at one temperature"),
    ("ramp", "temperature linear across the field from left to right"),
];

// ---------------------------------------------------------------------------------------
// Parameters
// ---------------------------------------------------------------------------------------

/// Size, sampling, spectral grid and geometry shared by every synthetic scene.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneParams {
    /// Detector-scale number of rows (before oversampling).
    pub rows: usize,
    /// Detector-scale number of columns (before oversampling).
    pub cols: usize,
    /// Oversampling factor k ≥ 1: the cube is `(rows·k) × (cols·k)`.
    pub oversampling: usize,
    /// Band centre wavelengths, µm, strictly increasing.
    pub wavelength_um: Vec<f64>,
    /// Horizontal full field of view, degrees. The vertical field is
    /// `fov_x_deg · rows / cols` (square pixels).
    pub fov_x_deg: f64,
    /// Range from the sensor to the scene, m, if known.
    pub range_m: Option<f64>,
    /// Seed for the random textures (same seed ⇒ identical scene).
    pub seed: u64,
    /// Daylight: reflected and scattered sunlight on (true) or off (night).
    pub sun: bool,
}

impl Default for SceneParams {
    /// 640 × 480, no oversampling, 8–12 µm in 41 bands, 10° horizontal field, night, seed 1.
    fn default() -> Self {
        SceneParams {
            rows: 480,
            cols: 640,
            oversampling: 1,
            wavelength_um: (0..41).map(|i| 8.0 + 0.1 * i as f64).collect(),
            fov_x_deg: 10.0,
            range_m: None,
            seed: 1,
            sun: false,
        }
    }
}

impl SceneParams {
    /// Checks sizes, the wavelength grid and the geometry; errors name the field, the value
    /// and what would be valid.
    pub fn validate(&self) -> Result<()> {
        if self.rows == 0 {
            return Err(Error::param("rows", self.rows, "at least 1"));
        }
        if self.cols == 0 {
            return Err(Error::param("cols", self.cols, "at least 1"));
        }
        if !(1..=MAX_OVERSAMPLING).contains(&self.oversampling) {
            return Err(Error::param(
                "oversampling",
                self.oversampling,
                format!("an integer in [1, {MAX_OVERSAMPLING}]"),
            ));
        }
        if self.wavelength_um.is_empty() {
            return Err(Error::param(
                "wavelength_um",
                "[]",
                "at least one band centre wavelength in µm",
            ));
        }
        for (i, &w) in self.wavelength_um.iter().enumerate() {
            if !(w.is_finite() && w > 0.0) {
                return Err(Error::param(
                    format!("wavelength_um[{i}]"),
                    w,
                    "a finite wavelength > 0 µm",
                ));
            }
            if i > 0 && w <= self.wavelength_um[i - 1] {
                return Err(Error::param(
                    format!("wavelength_um[{i}]"),
                    w,
                    format!(
                        "wavelengths strictly increasing: greater than wavelength_um[{}] = {} µm",
                        i - 1,
                        self.wavelength_um[i - 1]
                    ),
                ));
            }
        }
        if !(self.fov_x_deg.is_finite() && self.fov_x_deg > 0.0 && self.fov_x_deg < 180.0) {
            return Err(Error::param(
                "fov_x_deg",
                self.fov_x_deg,
                "a field of view in (0, 180) degrees",
            ));
        }
        let fov_y = self.fov_y_deg();
        if !(fov_y > 0.0 && fov_y < 180.0) {
            return Err(Error::param(
                "fov_x_deg",
                self.fov_x_deg,
                format!(
                    "a field of view whose vertical extent fov_x·rows/cols = {fov_y}° lies in (0, 180) degrees"
                ),
            ));
        }
        if let Some(r) = self.range_m {
            if !(r.is_finite() && r > 0.0) {
                return Err(Error::param("range_m", r, "a finite range > 0 m"));
            }
        }
        let k = self.oversampling as u128;
        let values =
            self.rows as u128 * k * self.cols as u128 * k * self.wavelength_um.len() as u128;
        if values > MAX_CUBE_VALUES as u128 {
            return Err(Error::param(
                "rows × cols × oversampling² × bands",
                values,
                format!("at most {MAX_CUBE_VALUES} values (16 GiB of f32)"),
            ));
        }
        Ok(())
    }

    /// `bands` wavelengths evenly spaced from `lo_um` to `hi_um` inclusive (point samples of
    /// the spectrum, like `linspace`); a single band sits at the midpoint `(lo + hi)/2`.
    pub fn uniform_grid(lo_um: f64, hi_um: f64, bands: usize) -> Result<Vec<f64>> {
        if !(lo_um.is_finite() && lo_um > 0.0) {
            return Err(Error::param("lo_um", lo_um, "a finite wavelength > 0 µm"));
        }
        if !hi_um.is_finite() {
            return Err(Error::param("hi_um", hi_um, "a finite wavelength in µm"));
        }
        match bands {
            0 => Err(Error::param("bands", bands, "at least 1")),
            1 if hi_um >= lo_um => Ok(vec![0.5 * (lo_um + hi_um)]),
            1 => Err(Error::param(
                "hi_um",
                hi_um,
                format!("a wavelength >= lo_um = {lo_um} µm"),
            )),
            _ if hi_um > lo_um => {
                let step = (hi_um - lo_um) / (bands - 1) as f64;
                let mut v: Vec<f64> = (0..bands).map(|i| lo_um + step * i as f64).collect();
                v[bands - 1] = hi_um;
                Ok(v)
            }
            _ => Err(Error::param(
                "hi_um",
                hi_um,
                format!("a wavelength > lo_um = {lo_um} µm when bands = {bands} > 1"),
            )),
        }
    }

    /// Vertical full field of view, degrees: `fov_x · rows / cols` (square pixels).
    pub fn fov_y_deg(&self) -> f64 {
        self.fov_x_deg * self.rows as f64 / self.cols.max(1) as f64
    }

    /// Rows of the cube, `rows · oversampling`.
    pub fn cube_rows(&self) -> usize {
        self.rows * self.oversampling
    }

    /// Columns of the cube, `cols · oversampling`.
    pub fn cube_cols(&self) -> usize {
        self.cols * self.oversampling
    }

    /// The cube's viewing geometry.
    pub fn geometry(&self) -> Geometry {
        Geometry {
            fov_x_deg: self.fov_x_deg,
            fov_y_deg: self.fov_y_deg(),
            range_m: self.range_m,
        }
    }

    /// Detector-scale angular sample spacing (IFOV), rad: `fov_x / cols`.
    pub fn detector_ifov_rad(&self) -> f64 {
        self.fov_x_deg.to_radians() / self.cols.max(1) as f64
    }

    /// Metadata of the cube a scene generator returns (spectral radiance per µm, point
    /// samples in λ so no band widths).
    fn meta(&self) -> CubeMeta {
        CubeMeta {
            wavelength_um: self.wavelength_um.clone(),
            fwhm_um: None,
            units: RadianceUnits::SpectralPerUm,
            geometry: Some(self.geometry()),
            rows: self.cube_rows(),
            cols: self.cube_cols(),
        }
    }
}

/// Checks a temperature argument: finite, > 0 and ≤ [`MAX_TEMPERATURE_K`].
fn check_temperature(field: &str, t_k: f64) -> Result<()> {
    if t_k.is_finite() && t_k > 0.0 && t_k <= MAX_TEMPERATURE_K {
        Ok(())
    } else {
        Err(Error::param(
            field,
            t_k,
            format!("a temperature in kelvin, > 0 and <= {MAX_TEMPERATURE_K}"),
        ))
    }
}

// ---------------------------------------------------------------------------------------
// Planck's law per band, precomputed
// ---------------------------------------------------------------------------------------

/// Planck's law at one fixed wavelength, `L = k1 / (exp(k2/T) − 1)`, with
/// `k1 = 2hc²/λ⁵` (converted to W m-2 sr-1 µm-1) and `k2 = hc/(λk)` (K) precomputed, the
/// same law as [`planck_spectral_radiance`] but cheap to evaluate per pixel.
#[derive(Debug, Clone, Copy)]
struct PlanckBand {
    k1: f64,
    k2: f64,
}

impl PlanckBand {
    fn new(wavelength_um: f64) -> Self {
        let lambda_m = wavelength_um * 1e-6;
        PlanckBand {
            k1: 2.0 * PLANCK_H * SPEED_OF_LIGHT_C * SPEED_OF_LIGHT_C / lambda_m.powi(5) * 1e-6,
            k2: PLANCK_H * SPEED_OF_LIGHT_C / (BOLTZMANN_K * lambda_m),
        }
    }

    /// Spectral radiance, W m-2 sr-1 µm-1, at temperature `t_k` (0 for T ≤ 0).
    fn radiance(&self, t_k: f64) -> f64 {
        if t_k <= 0.0 {
            0.0
        } else {
            self.k1 / (self.k2 / t_k).exp_m1()
        }
    }
}

// ---------------------------------------------------------------------------------------
// Small smooth functions
// ---------------------------------------------------------------------------------------

/// Logistic step from 0 to 1 centred on `x0` with scale `width`.
fn logistic(x: f64, x0: f64, width: f64) -> f64 {
    1.0 / (1.0 + (-(x - x0) / width).exp())
}

/// Gaussian bump of unit height centred on `x0` with standard deviation `sigma`.
fn gauss(x: f64, x0: f64, sigma: f64) -> f64 {
    let z = (x - x0) / sigma;
    (-0.5 * z * z).exp()
}

/// Smoothstep from 0 (x ≤ e0) to 1 (x ≥ e1), C¹.
fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// `(1 − e^{−x})/x`, 1 at x = 0, accurate for any sign of x.
fn one_minus_exp_over(x: f64) -> f64 {
    if x.abs() < 1e-12 {
        1.0 - 0.5 * x
    } else {
        -(-x).exp_m1() / x
    }
}

// ---------------------------------------------------------------------------------------
// Materials
// ---------------------------------------------------------------------------------------

/// Opaque surface materials with smooth analytic hemispherical reflectance curves valid
/// from 0.3 to 20 µm; emissivity follows Kirchhoff's law, `ε(λ) = 1 − ρ(λ)`.
///
/// The curves reproduce the features of published spectra (e.g. the ASTER/ECOSTRESS
/// spectral library, Baldridge et al. 2009; Salisbury & D'Aria 1992 for the thermal
/// infrared) as smooth sums of logistic steps and Gaussian bands; they are representative
/// shapes, not measurements of a particular sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Material {
    /// Green vegetation: chlorophyll absorption in the blue and at 0.67 µm (ρ ≈ 0.03), green
    /// peak ≈ 0.11 at 0.55 µm, red edge at 0.715 µm to a NIR plateau ρ ≈ 0.5, leaf-water
    /// absorption at 0.97, 1.2, 1.45 and 1.94 µm with SWIR plateaus ≈ 0.33 and 0.21, dark
    /// beyond 2.5 µm (ρ ≈ 0.05 in the MWIR) and ε ≈ 0.975 in the LWIR.
    Vegetation,
    /// Dry loamy soil: reflectance rising smoothly from 0.06 at 0.4 µm to ≈ 0.26 in the SWIR
    /// with water (1.4, 1.9 µm) and clay (2.2 µm) dips, ρ ≈ 0.12 in the MWIR, ε ≈ 0.96 in the
    /// LWIR except the quartz reststrahlen band near 9 µm (ε ≈ 0.86).
    Soil,
    /// Green camouflage paint on the vehicle: green peak ≈ 0.10, red ≈ 0.06, a weaker red
    /// edge to a NIR plateau ≈ 0.22 (less NIR-bright than vegetation), ρ ≈ 0.12 in the MWIR,
    /// ε ≈ 0.93 in the LWIR.
    Paint,
    /// Tracks and road wheels (dirty rubber and steel): dark and nearly grey, ρ ≈ 0.06–0.08
    /// to 2.5 µm, ε ≈ 0.95 in the thermal infrared.
    Track,
    /// Oxidised steel of the exhaust outlet: grey body, ε = 0.9 at all wavelengths.
    Exhaust,
}

impl Material {
    /// All materials, in the order used for per-pixel mixing weights.
    pub const ALL: [Material; 5] = [
        Material::Vegetation,
        Material::Soil,
        Material::Paint,
        Material::Track,
        Material::Exhaust,
    ];

    /// Hemispherical reflectance ρ(λ) in [0, 1] at `wavelength_um` (µm).
    pub fn reflectance(self, wavelength_um: f64) -> f64 {
        let l = wavelength_um;
        let rho = match self {
            Material::Vegetation => {
                let visible = 0.04 + 0.07 * gauss(l, 0.55, 0.04) - 0.015 * gauss(l, 0.675, 0.025);
                let nir = 0.50
                    - 0.03 * gauss(l, 0.97, 0.03)
                    - 0.05 * gauss(l, 1.18, 0.04)
                    - 0.17 * logistic(l, 1.38, 0.025)
                    - 0.12 * logistic(l, 1.88, 0.03)
                    - 0.12 * gauss(l, 1.45, 0.04)
                    - 0.12 * gauss(l, 1.94, 0.05);
                let infrared = 0.025 + 0.025 * (1.0 - logistic(l, 6.0, 0.6));
                let edge = logistic(l, 0.715, 0.01);
                let short = visible * (1.0 - edge) + nir * edge;
                let to_ir = logistic(l, 2.5, 0.05);
                short * (1.0 - to_ir) + infrared * to_ir
            }
            Material::Soil => {
                let rise = 0.06 + 0.22 * (1.0 - (-(l - 0.4).max(0.0) / 0.45).exp());
                let short = rise
                    - 0.04 * gauss(l, 1.41, 0.03)
                    - 0.05 * gauss(l, 1.92, 0.04)
                    - 0.03 * gauss(l, 2.2, 0.03);
                let infrared =
                    0.04 + 0.08 * (1.0 - logistic(l, 5.5, 0.5)) + 0.10 * gauss(l, 9.0, 0.45);
                let to_ir = logistic(l, 2.6, 0.1);
                short * (1.0 - to_ir) + infrared * to_ir
            }
            Material::Paint => {
                let visible = 0.05 + 0.05 * gauss(l, 0.56, 0.05);
                let nir = 0.22 - 0.07 * logistic(l, 1.6, 0.2);
                let edge = logistic(l, 0.71, 0.02);
                let short = visible * (1.0 - edge) + nir * edge;
                let infrared = 0.07 + 0.05 * (1.0 - logistic(l, 6.0, 0.7));
                let to_ir = logistic(l, 2.6, 0.1);
                short * (1.0 - to_ir) + infrared * to_ir
            }
            Material::Track => {
                let short = 0.06 + 0.02 * logistic(l, 0.9, 0.15);
                let to_ir = logistic(l, 2.6, 0.1);
                short * (1.0 - to_ir) + 0.05 * to_ir
            }
            Material::Exhaust => 0.1,
        };
        rho.clamp(0.0, 1.0)
    }

    /// Emissivity ε(λ) = 1 − ρ(λ) (Kirchhoff's law for an opaque surface).
    pub fn emissivity(self, wavelength_um: f64) -> f64 {
        1.0 - self.reflectance(wavelength_um)
    }
}

// ---------------------------------------------------------------------------------------
// Sun and atmosphere
// ---------------------------------------------------------------------------------------

/// Top-of-atmosphere solar spectral irradiance normal to the beam, W m-2 µm-1:
/// `E₀(λ) = B(λ, 5772 K) · Ω_sun`, the Sun as a blackbody at its effective temperature
/// filling [`SUN_SOLID_ANGLE_SR`]. Its integral over all λ is 1361 W m-2.
pub fn solar_spectral_irradiance_toa(wavelength_um: f64) -> f64 {
    planck_spectral_radiance(wavelength_um, SUN_TEMPERATURE_K) * SUN_SOLID_ANGLE_SR
}

/// Solar spectral irradiance on a horizontal surface, W m-2 µm-1, for a given beam
/// transmittance and solar zenith angle: `E₀(λ) · τ_atm · cos θz` (zero when the Sun is at
/// or below the horizon).
pub fn solar_spectral_irradiance(wavelength_um: f64, transmittance: f64, zenith_deg: f64) -> f64 {
    let cos_z = zenith_deg.to_radians().cos().max(0.0);
    solar_spectral_irradiance_toa(wavelength_um) * transmittance.max(0.0) * cos_z
}

/// Relative optical air mass at solar or viewing elevation `elevation_deg` (degrees above
/// the horizon), Kasten & Young (1989), Appl. Opt. 28, 4735:
/// `m = 1 / (sin h + 0.50572 (h + 6.07995°)^−1.6364)`. About 1 at the zenith, 37.9 at
/// the horizon; elevations below 0 are treated as 0.
pub fn relative_airmass(elevation_deg: f64) -> f64 {
    let h = elevation_deg.clamp(0.0, 90.0);
    1.0 / (h.to_radians().sin() + 0.50572 * (h + 6.07995).powf(-1.6364))
}

/// Rayleigh scattering optical depth of the whole atmosphere at sea level, vertical path:
/// `τ_R = 0.008569 λ⁻⁴ (1 + 0.0113 λ⁻² + 0.00013 λ⁻⁴)`, λ in µm (Hansen & Travis 1974,
/// Space Sci. Rev. 16, 527). 0.097 at 0.55 µm.
pub fn rayleigh_optical_depth(wavelength_um: f64) -> f64 {
    let l2 = 1.0 / (wavelength_um * wavelength_um);
    0.008569 * l2 * l2 * (1.0 + 0.0113 * l2 + 0.00013 * l2 * l2)
}

/// Zenith optical depth of molecular absorption (water vapour, CO₂, O₃, O₂), a smooth
/// analytic band model: a weak continuum (0.02 in the visible, rising to ≈ 0.27 in the
/// LWIR window for the water-vapour continuum) plus Gaussian or logistic bands at 0.76
/// (O₂), 0.94, 1.13, 1.38, 1.87, 2.7 (H₂O), 4.3 (CO₂), 5.6–7.4 (H₂O ν₂), 9.6 (O₃) and the
/// CO₂ band beyond 14 µm. Resulting zenith transmittances: ≈ 0.98 in the visible, ≈ 0.92 at
/// 4 µm, ≈ 0.73 at 10 µm, opaque at 2.7, 4.3, 6.3 and 15 µm. A caricature of a mid-latitude
/// clear atmosphere with moderate humidity, band centres as in HITRAN.
pub fn molecular_optical_depth(wavelength_um: f64) -> f64 {
    let l = wavelength_um;
    0.02 + 0.25 * logistic(l, 7.0, 0.5)
        + 0.3 * gauss(l, 0.761, 0.005)
        + 0.1 * gauss(l, 0.94, 0.02)
        + 0.15 * gauss(l, 1.13, 0.025)
        + 3.0 * gauss(l, 1.38, 0.04)
        + 3.0 * gauss(l, 1.87, 0.05)
        + 5.0 * gauss(l, 2.75, 0.15)
        + 6.0 * gauss(l, 4.3, 0.08)
        + 10.0 * logistic(l, 5.6, 0.12) * (1.0 - logistic(l, 7.4, 0.15))
        + 0.4 * gauss(l, 9.6, 0.25)
        + 8.0 * logistic(l, 13.8, 0.35)
}

/// Illumination and atmosphere of the [`thermal`] scene: air temperature, Sun position and
/// aerosol load.
#[derive(Debug, Clone, PartialEq)]
pub struct Environment {
    /// Air temperature near the ground (also the temperature of the isothermal emitting
    /// atmosphere), K.
    pub air_temperature_k: f64,
    /// Solar zenith angle, degrees, in [0, 85].
    pub solar_zenith_deg: f64,
    /// Aerosol optical depth at 0.55 µm (vertical path), ≥ 0; 0.1 is a clear rural day.
    pub aerosol_optical_depth_550: f64,
    /// Ångström exponent α of the aerosol optical depth `τ_a(λ) = τ_550 (λ/0.55)^−α`.
    pub angstrom_exponent: f64,
}

impl Default for Environment {
    /// 290 K air, Sun 45° from the zenith, aerosol optical depth 0.1 at 0.55 µm, α = 1.3.
    fn default() -> Self {
        Environment {
            air_temperature_k: 290.0,
            solar_zenith_deg: 45.0,
            aerosol_optical_depth_550: 0.1,
            angstrom_exponent: 1.3,
        }
    }
}

/// Number of cosine steps in the hemispheric sky integral (midpoint rule).
const SKY_QUADRATURE_STEPS: usize = 128;

impl Environment {
    /// Checks the fields; errors name the field, value and valid range.
    pub fn validate(&self) -> Result<()> {
        let t = self.air_temperature_k;
        if !(t.is_finite() && (180.0..=350.0).contains(&t)) {
            return Err(Error::param(
                "air_temperature_k",
                t,
                "an air temperature in [180, 350] K",
            ));
        }
        let z = self.solar_zenith_deg;
        if !(z.is_finite() && (0.0..=85.0).contains(&z)) {
            return Err(Error::param(
                "solar_zenith_deg",
                z,
                "a solar zenith angle in [0, 85] degrees",
            ));
        }
        let a = self.aerosol_optical_depth_550;
        if !(a.is_finite() && (0.0..=5.0).contains(&a)) {
            return Err(Error::param(
                "aerosol_optical_depth_550",
                a,
                "an optical depth in [0, 5]",
            ));
        }
        let e = self.angstrom_exponent;
        if !(e.is_finite() && (0.0..=4.0).contains(&e)) {
            return Err(Error::param("angstrom_exponent", e, "a number in [0, 4]"));
        }
        Ok(())
    }

    /// Aerosol optical depth at `wavelength_um` (Ångström's law).
    pub fn aerosol_optical_depth(&self, wavelength_um: f64) -> f64 {
        self.aerosol_optical_depth_550 * (wavelength_um / 0.55).powf(-self.angstrom_exponent)
    }

    /// Zenith extinction optical depth: Rayleigh + aerosol + molecular absorption.
    pub fn extinction_optical_depth(&self, wavelength_um: f64) -> f64 {
        rayleigh_optical_depth(wavelength_um)
            + self.aerosol_optical_depth(wavelength_um)
            + molecular_optical_depth(wavelength_um)
    }

    /// Direct-beam transmittance of the atmosphere towards the Sun, `exp(−τ m(θz))`.
    pub fn solar_transmittance(&self, wavelength_um: f64) -> f64 {
        let m = relative_airmass(90.0 - self.solar_zenith_deg);
        (-self.extinction_optical_depth(wavelength_um) * m).exp()
    }

    /// Direct solar spectral irradiance on horizontal ground, W m-2 µm-1:
    /// `E₀(λ) · exp(−τ m(θz)) · cos θz`.
    pub fn direct_solar_irradiance(&self, wavelength_um: f64) -> f64 {
        solar_spectral_irradiance(
            wavelength_um,
            self.solar_transmittance(wavelength_um),
            self.solar_zenith_deg,
        )
    }

    /// Thermal emission of the sky seen at `elevation_deg`, W m-2 sr-1 µm-1:
    /// `(1 − exp(−τ_abs m(e))) · B(λ, T_air)` for an isothermal absorbing atmosphere
    /// (Kirchhoff: a path of absorption optical depth τ emits `1 − e^{−τ}` of a blackbody).
    pub fn thermal_sky_radiance(&self, wavelength_um: f64, elevation_deg: f64) -> f64 {
        let m = relative_airmass(elevation_deg);
        let emissivity = -(-molecular_optical_depth(wavelength_um) * m).exp_m1();
        emissivity * planck_spectral_radiance(wavelength_um, self.air_temperature_k)
    }

    /// Singly scattered sunlight seen looking up at `elevation_deg`, W m-2 sr-1 µm-1:
    /// `ω E₀/(4π) · b e^{−a} (1 − e^{−(b−a)})/(b − a)` with `a = τ m_sun`, `b = τ m_view`
    /// and `ω = (τ_R + τ_a)/τ` (the plane-parallel single-scattering solution with an
    /// isotropic phase function, rewritten to be stable when the two air masses are equal).
    pub fn scattered_sky_radiance(&self, wavelength_um: f64, elevation_deg: f64) -> f64 {
        let tau_sca =
            rayleigh_optical_depth(wavelength_um) + self.aerosol_optical_depth(wavelength_um);
        let tau = tau_sca + molecular_optical_depth(wavelength_um);
        if tau <= 0.0 {
            return 0.0;
        }
        let albedo = tau_sca / tau;
        let a = tau * relative_airmass(90.0 - self.solar_zenith_deg);
        let b = tau * relative_airmass(elevation_deg);
        albedo * solar_spectral_irradiance_toa(wavelength_um) / (4.0 * std::f64::consts::PI)
            * b
            * (-a).exp()
            * one_minus_exp_over(b - a)
    }

    /// Sky radiance seen at `elevation_deg`, W m-2 sr-1 µm-1: thermal emission plus, with
    /// `sun`, scattered sunlight.
    pub fn sky_radiance(&self, wavelength_um: f64, elevation_deg: f64, sun: bool) -> f64 {
        let thermal = self.thermal_sky_radiance(wavelength_um, elevation_deg);
        if sun {
            thermal + self.scattered_sky_radiance(wavelength_um, elevation_deg)
        } else {
            thermal
        }
    }

    /// Downwelling sky irradiance on horizontal ground divided by π, W m-2 sr-1 µm-1:
    /// `E_sky/π = 2 ∫₀¹ L_sky(μ) μ dμ` (μ the sine of the elevation), by the midpoint rule.
    /// A Lambertian surface of reflectance ρ reflects `ρ · E_sky/π` of it.
    pub fn downwelling_sky_radiance(&self, wavelength_um: f64, sun: bool) -> f64 {
        let n = SKY_QUADRATURE_STEPS;
        let dmu = 1.0 / n as f64;
        let sum: f64 = (0..n)
            .map(|i| {
                let mu = (i as f64 + 0.5) * dmu;
                self.sky_radiance(wavelength_um, mu.asin().to_degrees(), sun) * mu
            })
            .sum();
        2.0 * sum * dmu
    }
}

// ---------------------------------------------------------------------------------------
// Smoothed noise
// ---------------------------------------------------------------------------------------

/// Value noise: uniform random values in [−1, 1] on a square lattice of spacing `cell`,
/// interpolated with the quintic fade `6t⁵ − 15t⁴ + 10t³` (C² continuous, Perlin 2002).
struct ValueNoise {
    cell: f64,
    nx: usize,
    ny: usize,
    values: Vec<f64>,
}

impl ValueNoise {
    fn new(rng: &mut Xoshiro256PlusPlus, cell: f64, width: f64, height: f64) -> Self {
        let nx = (width / cell).ceil() as usize + 2;
        let ny = (height / cell).ceil() as usize + 2;
        let values = (0..nx * ny)
            .map(|_| 2.0 * rng.random::<f64>() - 1.0)
            .collect();
        ValueNoise {
            cell,
            nx,
            ny,
            values,
        }
    }

    fn eval(&self, x: f64, y: f64) -> f64 {
        let fade = |t: f64| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
        let gx = (x / self.cell).max(0.0);
        let gy = (y / self.cell).max(0.0);
        let ix = (gx.floor() as usize).min(self.nx - 2);
        let iy = (gy.floor() as usize).min(self.ny - 2);
        let tx = fade((gx - ix as f64).clamp(0.0, 1.0));
        let ty = fade((gy - iy as f64).clamp(0.0, 1.0));
        let v = |i: usize, j: usize| self.values[j * self.nx + i];
        let top = v(ix, iy) + (v(ix + 1, iy) - v(ix, iy)) * tx;
        let bottom = v(ix, iy + 1) + (v(ix + 1, iy + 1) - v(ix, iy + 1)) * tx;
        top + (bottom - top) * ty
    }
}

/// Fractal sum of value-noise octaves (cell halves, amplitude × 0.55 per octave), from
/// `base_cell` down to the finest cell not below `min_cell`, standardised to zero mean and
/// unit standard deviation over a fixed 64 × 64 grid of the field. Coordinates are in
/// image heights, so the field does not depend on the oversampling.
struct Fbm {
    octaves: Vec<(f64, ValueNoise)>,
    mean: f64,
    scale: f64,
}

impl Fbm {
    /// Independent stream `stream` of `seed` (xoshiro jumps of 2¹²⁸ draws each).
    fn new(
        seed: u64,
        stream: usize,
        base_cell: f64,
        min_cell: f64,
        width: f64,
        height: f64,
    ) -> Self {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        for _ in 0..stream {
            rng.jump();
        }
        let mut octaves = Vec::new();
        // Never finer than min_cell, so the lattice stays proportional to the image size.
        let mut cell = base_cell.max(min_cell);
        let mut amplitude = 1.0;
        while octaves.is_empty() || (cell >= min_cell && octaves.len() < 8) {
            octaves.push((amplitude, ValueNoise::new(&mut rng, cell, width, height)));
            cell *= 0.5;
            amplitude *= 0.55;
        }
        let mut f = Fbm {
            octaves,
            mean: 0.0,
            scale: 1.0,
        };
        let n = 64;
        let (mut s1, mut s2) = (0.0, 0.0);
        for j in 0..n {
            for i in 0..n {
                let v = f.raw(
                    (i as f64 + 0.5) / n as f64 * width,
                    (j as f64 + 0.5) / n as f64 * height,
                );
                s1 += v;
                s2 += v * v;
            }
        }
        let count = (n * n) as f64;
        let mean = s1 / count;
        let sd = (s2 / count - mean * mean).max(0.0).sqrt();
        f.mean = mean;
        f.scale = if sd > 1e-12 { 1.0 / sd } else { 1.0 };
        f
    }

    fn raw(&self, x: f64, y: f64) -> f64 {
        self.octaves.iter().map(|(a, n)| a * n.eval(x, y)).sum()
    }

    fn eval(&self, x: f64, y: f64) -> f64 {
        (self.raw(x, y) - self.mean) * self.scale
    }
}

// ---------------------------------------------------------------------------------------
// Thermal scene
// ---------------------------------------------------------------------------------------

/// What each pixel of the [`thermal`] scene shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Region {
    /// Sky above the tree line.
    Sky,
    /// Tree line along the horizon (vegetation).
    Treeline,
    /// Open terrain: a mixture of vegetation and soil.
    Terrain,
    /// Terrain in the vehicle's shadow (no direct sun; only with `sun`).
    Shadow,
    /// Painted hull side.
    Hull,
    /// Rear part of the hull over the engine (warmer).
    EngineDeck,
    /// Painted turret.
    Turret,
    /// Gun barrel (painted).
    Barrel,
    /// Track and running gear.
    Track,
    /// Road wheels (warm bearings and rubber).
    Wheel,
    /// Hot exhaust outlet.
    Exhaust,
}

impl Region {
    /// True for the parts of the vehicle (the target).
    pub fn is_target(self) -> bool {
        matches!(
            self,
            Region::Hull
                | Region::EngineDeck
                | Region::Turret
                | Region::Barrel
                | Region::Track
                | Region::Wheel
                | Region::Exhaust
        )
    }
}

/// The [`thermal`] scene with the maps it was built from (useful as ground truth).
#[derive(Debug, Clone)]
pub struct ThermalScene {
    /// The spectral radiance cube.
    pub cube: Cube,
    /// What each cube pixel shows, `[row, col]`.
    pub region: Array2<Region>,
    /// Physical (thermodynamic) surface temperature, K, `[row, col]`; sky pixels carry the
    /// air temperature.
    pub temperature_k: Array2<f32>,
    /// Fraction of vegetation in the terrain mixture (1 on the tree line, 0 on the vehicle
    /// and the sky), `[row, col]`.
    pub vegetation_fraction: Array2<f32>,
}

/// Temperatures of the scene's parts, K.
struct Temperatures {
    air: f64,
    vegetation: f64,
    soil_dry: f64,
    /// Change of soil temperature from dry to fully moist soil (higher thermal inertia).
    soil_moist_delta: f64,
    treeline: f64,
    hull: f64,
    engine_extra: f64,
    exhaust: f64,
}

impl Temperatures {
    /// Night: the ground has cooled below the air by radiation to the sky, moist soil keeps
    /// its heat longer, the vehicle keeps some heat of its engine. Day: soil heats most in
    /// the sun, transpiring vegetation least, painted steel more than the ground.
    fn new(air: f64, sun: bool) -> Self {
        if sun {
            Temperatures {
                air,
                vegetation: air + 2.5,
                soil_dry: air + 11.0,
                soil_moist_delta: -6.0,
                treeline: air + 1.5,
                hull: air + 11.0,
                engine_extra: 10.0,
                exhaust: 550.0,
            }
        } else {
            Temperatures {
                air,
                vegetation: air - 1.5,
                soil_dry: air - 3.0,
                soil_moist_delta: 2.0,
                treeline: air - 0.8,
                hull: air + 3.0,
                engine_extra: 10.0,
                exhaust: 550.0,
            }
        }
    }
}

/// How to compute one pixel's spectrum: reflectance weights over [`Material::ALL`]
/// (`ρ = Σ wᵢ ρᵢ`), physical temperature and the fraction of direct sun it receives.
#[derive(Debug, Clone, Copy)]
struct Recipe {
    sky: bool,
    t_k: f32,
    sun: f32,
    weights: [f32; 5],
}

/// Point in polygon by the crossing-number rule.
fn in_polygon(x: f64, y: f64, poly: &[(f64, f64)]) -> bool {
    let mut inside = false;
    let mut j = poly.len() - 1;
    for i in 0..poly.len() {
        let (xi, yi) = poly[i];
        let (xj, yj) = poly[j];
        if (yi > y) != (yj > y) && x < (xj - xi) * (y - yi) / (yj - yi) + xi {
            inside = !inside;
        }
        j = i;
    }
    inside
}

/// Side view of the vehicle in its own coordinates, in units of the scene scale `s`:
/// ξ along the hull from the front (left), η height above the ground line.
mod vehicle {
    /// Hull side (front glacis sloping up to the left).
    pub const HULL: [(f64, f64); 6] = [
        (0.0, 0.062),
        (0.06, 0.112),
        (0.45, 0.112),
        (0.45, 0.066),
        (0.43, 0.055),
        (0.02, 0.055),
    ];
    /// Turret side.
    pub const TURRET: [(f64, f64); 4] =
        [(0.12, 0.112), (0.15, 0.158), (0.29, 0.158), (0.31, 0.112)];
    /// Engine compartment starts at this ξ.
    pub const ENGINE_START: f64 = 0.31;
    /// Barrel: ξ range and η range.
    pub const BARREL: (f64, f64, f64, f64) = (-0.16, 0.13, 0.131, 0.141);
    /// Track: a capsule around the segment ξ ∈ [0.035, 0.415] at η = 0.03, radius 0.03.
    pub const TRACK: (f64, f64, f64, f64) = (0.035, 0.415, 0.03, 0.03);
    /// Road wheels: count, first and last centre ξ, centre η, radius.
    pub const WHEELS: (usize, f64, f64, f64, f64) = (6, 0.065, 0.385, 0.03, 0.021);
    /// Exhaust outlet ellipse: centre ξ, η and semi-axes.
    pub const EXHAUST: (f64, f64, f64, f64) = (0.43, 0.095, 0.014, 0.009);
    /// Shadow on the ground: centre ξ, η and semi-axes.
    pub const SHADOW: (f64, f64, f64, f64) = (0.25, -0.004, 0.25, 0.022);
    /// Bounding box of everything above (ξ_min, ξ_max, η_min, η_max).
    pub const BBOX: (f64, f64, f64, f64) = (-0.17, 0.46, -0.03, 0.17);
}

/// Everything the thermal scene's pixels are computed from; coordinates in image heights,
/// x from the left edge (0…aspect), v from the top (0…1).
struct ThermalLayout {
    aspect: f64,
    /// Scene scale: 1 image height for 4:3 and wider images, less for narrower ones.
    scale: f64,
    x_front: f64,
    v_ground: f64,
    /// Geometric horizon (behind the trees), used for sky elevations.
    v_horizon: f64,
    sun: bool,
    temps: Temperatures,
    vegetation: Fbm,
    moisture: Fbm,
    texture: Fbm,
    crowns: Fbm,
    forest_edge: Fbm,
}

impl ThermalLayout {
    fn new(p: &SceneParams, env: &Environment) -> Self {
        let aspect = p.cols as f64 / p.rows as f64;
        let scale = (aspect / (4.0 / 3.0)).min(1.0);
        // The finest texture octave spans two detector pixels: the same scene for any k.
        let min_cell = 2.0 / p.rows as f64;
        let seed = p.seed;
        ThermalLayout {
            aspect,
            scale,
            x_front: 0.5 * aspect - 0.5 * 0.45 * scale,
            v_ground: 0.72,
            v_horizon: 0.235,
            sun: p.sun,
            temps: Temperatures::new(env.air_temperature_k, p.sun),
            vegetation: Fbm::new(seed, 0, 0.35, min_cell, aspect, 1.0),
            moisture: Fbm::new(seed, 1, 0.5, min_cell, aspect, 1.0),
            texture: Fbm::new(seed, 2, 0.25, min_cell, aspect, 1.0),
            crowns: Fbm::new(seed, 3, 0.05, min_cell, aspect, 1.0),
            forest_edge: Fbm::new(seed, 4, 0.2, min_cell, aspect, 1.0),
        }
    }

    /// The vehicle part at (x, v), if any.
    fn vehicle_part(&self, x: f64, v: f64) -> Option<Region> {
        use vehicle::*;
        let xi = (x - self.x_front) / self.scale;
        let eta = (self.v_ground - v) / self.scale;
        if xi < BBOX.0 || xi > BBOX.1 || eta < BBOX.2 || eta > BBOX.3 {
            return None;
        }
        let in_ellipse = |(cx, cy, ax, ay): (f64, f64, f64, f64)| {
            let (dx, dy) = ((xi - cx) / ax, (eta - cy) / ay);
            dx * dx + dy * dy <= 1.0
        };
        if in_ellipse(EXHAUST) {
            return Some(Region::Exhaust);
        }
        let (count, first, last, wheel_eta, radius) = WHEELS;
        for i in 0..count {
            let cx = first + (last - first) * i as f64 / (count - 1) as f64;
            if (xi - cx).hypot(eta - wheel_eta) <= radius {
                return Some(Region::Wheel);
            }
        }
        let (t0, t1, t_eta, t_r) = TRACK;
        if (xi - xi.clamp(t0, t1)).hypot(eta - t_eta) <= t_r {
            return Some(Region::Track);
        }
        if in_polygon(xi, eta, &HULL) {
            return Some(if xi >= ENGINE_START {
                Region::EngineDeck
            } else {
                Region::Hull
            });
        }
        if in_polygon(xi, eta, &TURRET) {
            return Some(Region::Turret);
        }
        let (b0, b1, b_lo, b_hi) = BARREL;
        if (b0..=b1).contains(&xi) && (b_lo..=b_hi).contains(&eta) {
            return Some(Region::Barrel);
        }
        if self.sun && in_ellipse(SHADOW) {
            return Some(Region::Shadow);
        }
        None
    }

    /// Top of the tree line (sky above) and its lower edge (open terrain below) at x.
    fn treeline(&self, x: f64) -> (f64, f64) {
        let v_top = 0.205 - 0.035 * (0.5 + 0.35 * self.crowns.eval(x, 0.5)).clamp(0.0, 1.0);
        let v_forest = 0.265 + 0.01 * self.forest_edge.eval(x, 0.5);
        (v_top, v_forest)
    }

    /// Region, recipe and vegetation fraction of the scene point (x, v), given the
    /// [`treeline`](Self::treeline) at x.
    fn pixel(&self, x: f64, v: f64, (v_top, v_forest): (f64, f64)) -> (Region, Recipe, f32) {
        let t = &self.temps;
        if v < v_top {
            let r = Recipe {
                sky: true,
                t_k: t.air as f32,
                sun: 0.0,
                weights: [0.0; 5],
            };
            return (Region::Sky, r, 0.0);
        }
        let n_t = self.texture.eval(x, v);
        let paint = |t_k: f64| Recipe {
            sky: false,
            t_k: (t_k + 0.3 * n_t) as f32,
            sun: 1.0,
            weights: [0.0, 0.0, 1.0, 0.0, 0.0],
        };
        let track = |t_k: f64| Recipe {
            sky: false,
            t_k: (t_k + 0.3 * n_t) as f32,
            sun: 1.0,
            weights: [0.0, 0.0, 0.0, 1.0, 0.0],
        };
        let part = self.vehicle_part(x, v);
        match part {
            Some(Region::Exhaust) => {
                let r = Recipe {
                    sky: false,
                    t_k: t.exhaust as f32,
                    sun: 1.0,
                    weights: [0.0, 0.0, 0.0, 0.0, 1.0],
                };
                return (Region::Exhaust, r, 0.0);
            }
            Some(Region::Wheel) => return (Region::Wheel, track(t.hull + 6.0), 0.0),
            Some(Region::Track) => return (Region::Track, track(t.hull + 3.0), 0.0),
            Some(Region::Hull) => return (Region::Hull, paint(t.hull), 0.0),
            Some(Region::EngineDeck) => {
                let xi = (x - self.x_front) / self.scale;
                let warm = smoothstep(vehicle::ENGINE_START, vehicle::ENGINE_START + 0.09, xi);
                return (
                    Region::EngineDeck,
                    paint(t.hull + t.engine_extra * warm),
                    0.0,
                );
            }
            Some(Region::Turret) => return (Region::Turret, paint(t.hull - 0.5), 0.0),
            Some(Region::Barrel) => return (Region::Barrel, paint(t.hull - 1.0), 0.0),
            _ => {}
        }
        if v < v_forest {
            let r = Recipe {
                sky: false,
                t_k: (t.treeline + 0.6 * n_t) as f32,
                sun: 1.0,
                weights: [1.0, 0.0, 0.0, 0.0, 0.0],
            };
            return (Region::Treeline, r, 1.0);
        }
        let a = smoothstep(-0.35, 0.35, self.vegetation.eval(x, v) + 0.15);
        let m = smoothstep(-1.2, 1.2, self.moisture.eval(x, v));
        let soil_t = t.soil_dry + t.soil_moist_delta * m;
        let mut t_k = a * t.vegetation + (1.0 - a) * soil_t + 0.8 * n_t;
        let shadow = part == Some(Region::Shadow);
        if shadow {
            // Shaded ground stays close to the air temperature.
            t_k = t.air + 0.3 * (t_k - t.air);
        }
        let r = Recipe {
            sky: false,
            t_k: t_k as f32,
            sun: if shadow { 0.0 } else { 1.0 },
            // Wet soil is darker at all wavelengths (and so more emissive).
            weights: [
                a as f32,
                ((1.0 - a) * (1.0 - 0.35 * m)) as f32,
                0.0,
                0.0,
                0.0,
            ],
        };
        let region = if shadow {
            Region::Shadow
        } else {
            Region::Terrain
        };
        (region, r, a as f32)
    }
}

/// Per-band constants of the thermal scene.
struct ThermalBand {
    planck: PlanckBand,
    reflectance: [f64; 5],
    /// Downwelling sky radiance E_sky/π.
    sky_down: f64,
    /// Direct sun E_dir/π (0 at night).
    sun_down: f64,
    /// Sky radiance seen by each cube row.
    sky_view: Vec<f64>,
}

/// The [`thermal`] scene under the default [`Environment`].
pub fn thermal(p: &SceneParams) -> Result<Cube> {
    thermal_scene(p, &Environment::default()).map(|s| s.cube)
}

/// A vehicle-like target on textured terrain under a sky strip, with its ground-truth maps.
///
/// Layout (sizes relative to the image height, scaled down for images narrower than 4:3):
/// sky above an undulating tree line near 20 % of the height (sky elevation measured from
/// a geometric horizon at 23.5 %, so the sky strip is warm near the trees and colder
/// higher up in the LWIR window); open terrain below, a seeded fractal mixture of
/// vegetation and soil with correlated soil moisture (darker, more emissive and, at night,
/// warmer) and ±0.8 K correlated temperature texture; a vehicle seen from the side,
/// centred, 0.45 image heights long, standing on a ground line at 72 % of the height:
/// hull (paint), warmer engine compartment at the rear, turret, barrel pointing left,
/// track with six warm road wheels and a hot exhaust outlet (550 K, ε = 0.9). In daylight
/// the vehicle casts a shadow (no direct sun, ground near air temperature) on the ground.
///
/// Temperatures (relative to the air temperature T_air): at night vegetation −1.5 K, dry
/// soil −3 K (moist soil up to +2 K warmer), hull +3 K; by day vegetation +2.5 K, dry soil
/// +11 K (moist soil up to 6 K cooler), hull +11 K; engine compartment up to +10 K above
/// the hull, wheels +6 K, track +3 K. The hull is therefore a few kelvin warmer than the
/// mean terrain.
///
/// Texture fields are defined in image coordinates with their finest detail at two
/// detector pixels, so changing the oversampling refines the same scene. Shapes are
/// point-sampled at the cube's pixel centres (use oversampling for smooth outlines).
pub fn thermal_scene(p: &SceneParams, env: &Environment) -> Result<ThermalScene> {
    p.validate()?;
    env.validate()?;
    let (rows, cols) = (p.cube_rows(), p.cube_cols());
    let layout = ThermalLayout::new(p, env);

    let column_x: Vec<f64> = (0..cols)
        .map(|c| (c as f64 + 0.5) / cols as f64 * layout.aspect)
        .collect();
    let treeline: Vec<(f64, f64)> = column_x.iter().map(|&x| layout.treeline(x)).collect();
    let mut pixels: Vec<(Region, Recipe, f32)> = Vec::with_capacity(rows * cols);
    let per_row: Vec<Vec<(Region, Recipe, f32)>> = (0..rows)
        .into_par_iter()
        .map(|r| {
            let v = (r as f64 + 0.5) / rows as f64;
            column_x
                .iter()
                .zip(&treeline)
                .map(|(&x, &tl)| layout.pixel(x, v, tl))
                .collect()
        })
        .collect();
    for row in per_row {
        pixels.extend(row);
    }

    let fov_y_deg = p.fov_y_deg();
    let row_elevation_deg: Vec<f64> = (0..rows)
        .map(|r| (layout.v_horizon - (r as f64 + 0.5) / rows as f64).max(0.0) * fov_y_deg)
        .collect();
    let bands: Vec<ThermalBand> = p
        .wavelength_um
        .par_iter()
        .map(|&l| {
            let mut reflectance = [0.0; 5];
            for (rho, m) in reflectance.iter_mut().zip(Material::ALL) {
                *rho = m.reflectance(l);
            }
            let sky_view = row_elevation_deg
                .iter()
                .map(|&e| env.sky_radiance(l, e, p.sun))
                .collect();
            ThermalBand {
                planck: PlanckBand::new(l),
                reflectance,
                sky_down: env.downwelling_sky_radiance(l, p.sun),
                sun_down: if p.sun {
                    env.direct_solar_irradiance(l) / std::f64::consts::PI
                } else {
                    0.0
                },
                sky_view,
            }
        })
        .collect();

    let mut data = Array3::<f32>::zeros((p.wavelength_um.len(), rows, cols));
    data.axis_iter_mut(Axis(0))
        .into_par_iter()
        .zip(bands.par_iter())
        .for_each(|(mut plane, band)| {
            for (r, mut row) in plane.outer_iter_mut().enumerate() {
                let recipes = &pixels[r * cols..(r + 1) * cols];
                for (value, (_, recipe, _)) in row.iter_mut().zip(recipes) {
                    *value = if recipe.sky {
                        band.sky_view[r] as f32
                    } else {
                        let rho: f64 = recipe
                            .weights
                            .iter()
                            .zip(band.reflectance)
                            .map(|(&w, rho)| w as f64 * rho)
                            .sum::<f64>()
                            .clamp(0.0, 1.0);
                        let emitted = (1.0 - rho) * band.planck.radiance(recipe.t_k as f64);
                        let reflected = rho * (band.sky_down + recipe.sun as f64 * band.sun_down);
                        (emitted + reflected) as f32
                    };
                }
            }
        });

    let region = Array2::from_shape_vec((rows, cols), pixels.iter().map(|p| p.0).collect())
        .map_err(|e| Error::OutOfRange(format!("thermal scene region map: {e}")))?;
    let temperature_k =
        Array2::from_shape_vec((rows, cols), pixels.iter().map(|p| p.1.t_k).collect())
            .map_err(|e| Error::OutOfRange(format!("thermal scene temperature map: {e}")))?;
    let vegetation_fraction =
        Array2::from_shape_vec((rows, cols), pixels.iter().map(|p| p.2).collect())
            .map_err(|e| Error::OutOfRange(format!("thermal scene vegetation map: {e}")))?;
    Ok(ThermalScene {
        cube: Cube::new(data, p.meta())?,
        region,
        temperature_k,
        vegetation_fraction,
    })
}

// ---------------------------------------------------------------------------------------
// Test patterns
// ---------------------------------------------------------------------------------------

/// Fills a cube whose pixels are area mixtures of two blackbodies:
/// `L = f·B(λ, t_one) + (1 − f)·B(λ, t_zero)` with `f` the covered fraction of the pixel.
fn two_temperature_cube(
    p: &SceneParams,
    coverage: &Array2<f64>,
    t_one: f64,
    t_zero: f64,
) -> Result<Cube> {
    let (rows, cols) = coverage.dim();
    let mut data = Array3::<f32>::zeros((p.wavelength_um.len(), rows, cols));
    data.axis_iter_mut(Axis(0))
        .into_par_iter()
        .zip(p.wavelength_um.par_iter())
        .for_each(|(mut plane, &l)| {
            let one = planck_spectral_radiance(l, t_one);
            let zero = planck_spectral_radiance(l, t_zero);
            plane.zip_mut_with(coverage, |v, &f| *v = (f * one + (1.0 - f) * zero) as f32);
        });
    Cube::new(data, p.meta())
}

/// One 4-bar pattern of the [`bars`] scene, in cube pixel coordinates (pixel `i` spans
/// `[i, i+1)`, x to the right, y down).
#[derive(Debug, Clone, PartialEq)]
pub struct BarGroup {
    /// Spatial frequency of the bars, cycles/mrad (one cycle = one bar + one space).
    pub frequency_cy_per_mrad: f64,
    /// Width of one bar (= one space), cube pixels.
    pub bar_width_px: f64,
    /// false: vertical bars (modulation along x, measured on a row cut);
    /// true: horizontal bars (modulation along y, measured on a column cut).
    pub horizontal_bars: bool,
    /// Left edge of the pattern's 7w × 7w square.
    pub x0_px: f64,
    /// Top edge of the pattern's 7w × 7w square.
    pub y0_px: f64,
}

impl BarGroup {
    /// The four bars as rectangles `(x0, x1, y0, y1)` in cube pixels: bar `j` spans
    /// `[2jw, (2j+1)w]` across and `7w` along (7:1 aspect).
    pub fn bars(&self) -> [(f64, f64, f64, f64); 4] {
        let w = self.bar_width_px;
        std::array::from_fn(|j| {
            let a = 2.0 * j as f64 * w;
            if self.horizontal_bars {
                (
                    self.x0_px,
                    self.x0_px + 7.0 * w,
                    self.y0_px + a,
                    self.y0_px + a + w,
                )
            } else {
                (
                    self.x0_px + a,
                    self.x0_px + a + w,
                    self.y0_px,
                    self.y0_px + 7.0 * w,
                )
            }
        })
    }
}

/// Most 4-bar groups in the [`bars`] scene.
const MAX_BAR_GROUPS: usize = 6;

/// The layout of the [`bars`] scene.
///
/// Frequencies: the detector Nyquist frequency `f_N = 1/(2·IFOV)` (IFOV = fov_x/cols) and
/// below it by factors of √2, up to six groups (`f_N`, 0.71 f_N, … 0.18 f_N), so bar widths
/// are 1, √2, 2, … detector pixels. As many groups as fit are kept, highest frequencies
/// first: one row of vertical-bar patterns left to right from low to high frequency,
/// spaced by the widest bar width (at least 2 detector pixels), and, when the image is tall
/// enough, a second row below with the same groups as horizontal bars. The layout is
/// centred in the image; bar edges fall anywhere (area-weighted pixels).
pub fn bars_layout(p: &SceneParams) -> Result<Vec<BarGroup>> {
    p.validate()?;
    let (rows, cols) = (p.rows as f64, p.cols as f64);
    let f_nyquist_cy_per_mrad = 1.0 / (2.0 * p.detector_ifov_rad()) / 1000.0;
    let ratio = std::f64::consts::SQRT_2;
    let k = p.oversampling as f64;
    for groups in (1..=MAX_BAR_GROUPS).rev() {
        // Detector pixels, from the lowest frequency (widest bars) to the highest.
        let widths: Vec<f64> = (0..groups).rev().map(|j| ratio.powi(j as i32)).collect();
        let w_max = widths[0];
        let gap = w_max.max(2.0);
        let total_w = 7.0 * widths.iter().sum::<f64>() + (groups as f64 + 1.0) * gap;
        let one_row_h = 7.0 * w_max + 2.0 * gap;
        if total_w > cols || one_row_h > rows {
            continue;
        }
        let two_rows = 14.0 * w_max + 3.0 * gap <= rows;
        let row_centres: Vec<(bool, f64)> = if two_rows {
            let off = 3.5 * w_max + 0.5 * gap;
            vec![(false, rows / 2.0 - off), (true, rows / 2.0 + off)]
        } else {
            vec![(false, rows / 2.0)]
        };
        let mut layout = Vec::new();
        for (horizontal_bars, yc) in row_centres {
            let mut x = (cols - total_w) / 2.0 + gap;
            for &w in &widths {
                layout.push(BarGroup {
                    frequency_cy_per_mrad: f_nyquist_cy_per_mrad / w,
                    bar_width_px: w * k,
                    horizontal_bars,
                    x0_px: x * k,
                    y0_px: (yc - 3.5 * w) * k,
                });
                x += 7.0 * w + gap;
            }
        }
        return Ok(layout);
    }
    Err(Error::param(
        "rows × cols",
        format!("{} × {}", p.rows, p.cols),
        "at least 11 × 11 detector pixels for one 4-bar group at the Nyquist frequency with its margins",
    ))
}

/// Frequencies of the [`bars`] groups, cycles/mrad, in layout order (low to high); empty
/// when the parameters are invalid or the image is too small for one group.
pub fn bars_frequencies_cy_per_mrad(p: &SceneParams) -> Vec<f64> {
    bars_layout(p)
        .map(|groups| {
            groups
                .iter()
                .filter(|g| !g.horizontal_bars)
                .map(|g| g.frequency_cy_per_mrad)
                .collect()
        })
        .unwrap_or_default()
}

/// Length of the overlap of `[a0, a1]` and `[b0, b1]`.
fn overlap(a0: f64, a1: f64, b0: f64, b1: f64) -> f64 {
    (a1.min(b1) - a0.max(b0)).max(0.0)
}

/// 4-bar targets: blackbody bars at `t_bar_k` on a blackbody background at
/// `t_background_k` (see [`bars_layout`] for the geometry). Edge pixels hold the exact
/// area mixture of the two radiances.
pub fn bars(p: &SceneParams, t_bar_k: f64, t_background_k: f64) -> Result<Cube> {
    check_temperature("t_bar_k", t_bar_k)?;
    check_temperature("t_background_k", t_background_k)?;
    let layout = bars_layout(p)?;
    let (rows, cols) = (p.cube_rows(), p.cube_cols());
    let mut coverage = Array2::<f64>::zeros((rows, cols));
    for group in &layout {
        for (x0, x1, y0, y1) in group.bars() {
            let (c0, c1) = (x0.floor().max(0.0) as usize, (x1.ceil() as usize).min(cols));
            let (r0, r1) = (y0.floor().max(0.0) as usize, (y1.ceil() as usize).min(rows));
            for r in r0..r1 {
                let fy = overlap(r as f64, r as f64 + 1.0, y0, y1);
                for c in c0..c1 {
                    coverage[[r, c]] += fy * overlap(c as f64, c as f64 + 1.0, x0, x1);
                }
            }
        }
    }
    coverage.mapv_inplace(|f| f.min(1.0));
    two_temperature_cube(p, &coverage, t_bar_k, t_background_k)
}

/// Area of the unit pixel `[x0, x0+1] × [y0, y0+1]` where `nx·x + ny·y ≥ d` (|n| = 1),
/// by clipping the square with the half-plane (Sutherland–Hodgman) and the shoelace formula.
fn half_plane_coverage(x0: f64, y0: f64, nx: f64, ny: f64, d: f64) -> f64 {
    let centre = nx * (x0 + 0.5) + ny * (y0 + 0.5) - d;
    let reach = 0.5 * (nx.abs() + ny.abs());
    if centre >= reach {
        return 1.0;
    }
    if centre <= -reach {
        return 0.0;
    }
    let square = [
        (x0, y0),
        (x0 + 1.0, y0),
        (x0 + 1.0, y0 + 1.0),
        (x0, y0 + 1.0),
    ];
    let side = |(x, y): (f64, f64)| nx * x + ny * y - d;
    let mut clipped: Vec<(f64, f64)> = Vec::with_capacity(5);
    for i in 0..4 {
        let a = square[i];
        let b = square[(i + 1) % 4];
        let (sa, sb) = (side(a), side(b));
        if sa >= 0.0 {
            clipped.push(a);
        }
        if (sa >= 0.0) != (sb >= 0.0) {
            let t = sa / (sa - sb);
            clipped.push((a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1)));
        }
    }
    if clipped.len() < 3 {
        return 0.0;
    }
    let n = clipped.len();
    let twice_area: f64 = (0..n)
        .map(|i| {
            let (xa, ya) = clipped[i];
            let (xb, yb) = clipped[(i + 1) % n];
            xa * yb - xb * ya
        })
        .sum();
    (0.5 * twice_area.abs()).clamp(0.0, 1.0)
}

/// A straight edge through the centre of the image between blackbodies at `t_low_k` and
/// `t_high_k`, tilted by `angle_deg` from the vertical ([`DEFAULT_EDGE_ANGLE_DEG`] is the
/// usual slanted-edge choice).
///
/// The edge is the line `x = x_c + (y − y_c)·tan θ` (y down, so a positive angle makes the
/// edge cross lower rows further right: a counter-clockwise tilt as displayed); the hot side
/// is `(x − x_c) cos θ − (y − y_c) sin θ > 0`, i.e. the right for |θ| < 90°, the top for
/// θ = 90°. Pixels cut by the edge hold the exact area mixture of the two radiances, so
/// exactly half of the image area is hot.
pub fn edge(p: &SceneParams, t_low_k: f64, t_high_k: f64, angle_deg: f64) -> Result<Cube> {
    p.validate()?;
    check_temperature("t_low_k", t_low_k)?;
    check_temperature("t_high_k", t_high_k)?;
    if !(angle_deg.is_finite() && (-180.0..=180.0).contains(&angle_deg)) {
        return Err(Error::param(
            "angle_deg",
            angle_deg,
            "an edge angle from the vertical in [-180, 180] degrees",
        ));
    }
    let (rows, cols) = (p.cube_rows(), p.cube_cols());
    let theta = angle_deg.to_radians();
    let (nx, ny) = (theta.cos(), -theta.sin());
    // Coordinates relative to the image centre keep the arithmetic exact near the edge.
    let (xc, yc) = (cols as f64 / 2.0, rows as f64 / 2.0);
    let mut coverage = Array2::<f64>::zeros((rows, cols));
    coverage
        .axis_iter_mut(Axis(0))
        .into_par_iter()
        .enumerate()
        .for_each(|(r, mut row)| {
            for (c, f) in row.iter_mut().enumerate() {
                *f = half_plane_coverage(c as f64 - xc, r as f64 - yc, nx, ny, 0.0);
            }
        });
    two_temperature_cube(p, &coverage, t_high_k, t_low_k)
}

/// A uniform grey body: `L = ε·B(λ, T)` at every pixel (emitted radiance only, as for a
/// laboratory source seen against a cold surround).
pub fn blackbody(p: &SceneParams, t_k: f64, emissivity: f64) -> Result<Cube> {
    p.validate()?;
    check_temperature("t_k", t_k)?;
    if !(emissivity.is_finite() && (0.0..=1.0).contains(&emissivity)) {
        return Err(Error::param("emissivity", emissivity, "a number in [0, 1]"));
    }
    let (rows, cols) = (p.cube_rows(), p.cube_cols());
    let mut data = Array3::<f32>::zeros((p.wavelength_um.len(), rows, cols));
    data.axis_iter_mut(Axis(0))
        .into_par_iter()
        .zip(p.wavelength_um.par_iter())
        .for_each(|(mut plane, &l)| {
            plane.fill((emissivity * planck_spectral_radiance(l, t_k)) as f32);
        });
    Cube::new(data, p.meta())
}

/// A blackbody whose temperature rises linearly across the field, from `t_min_k` at the
/// left edge to `t_max_k` at the right edge; each pixel has the temperature at its centre,
/// `T = t_min + (t_max − t_min)·(c + ½)/cols` (cube columns), the same on every row.
pub fn ramp(p: &SceneParams, t_min_k: f64, t_max_k: f64) -> Result<Cube> {
    p.validate()?;
    check_temperature("t_min_k", t_min_k)?;
    check_temperature("t_max_k", t_max_k)?;
    if t_max_k < t_min_k {
        return Err(Error::param(
            "t_max_k",
            t_max_k,
            format!("a temperature >= t_min_k = {t_min_k} K"),
        ));
    }
    let (rows, cols) = (p.cube_rows(), p.cube_cols());
    let temperatures: Vec<f64> = (0..cols)
        .map(|c| t_min_k + (t_max_k - t_min_k) * (c as f64 + 0.5) / cols as f64)
        .collect();
    let mut data = Array3::<f32>::zeros((p.wavelength_um.len(), rows, cols));
    data.axis_iter_mut(Axis(0))
        .into_par_iter()
        .zip(p.wavelength_um.par_iter())
        .for_each(|(mut plane, &l)| {
            let planck = PlanckBand::new(l);
            let column: Vec<f32> = temperatures
                .iter()
                .map(|&t| planck.radiance(t) as f32)
                .collect();
            for mut row in plane.outer_iter_mut() {
                for (v, &x) in row.iter_mut().zip(&column) {
                    *v = x;
                }
            }
        });
    Cube::new(data, p.meta())
}

/// Default bar temperature of [`generate`]'s "bars", K.
pub const DEFAULT_BAR_TEMPERATURE_K: f64 = 305.0;
/// Default background temperature of [`generate`]'s "bars", "edge" (cold side) and
/// "blackbody", K.
pub const DEFAULT_BACKGROUND_TEMPERATURE_K: f64 = 300.0;
/// Default hot side of [`generate`]'s "edge", K.
pub const DEFAULT_EDGE_HIGH_K: f64 = 310.0;
/// Default temperature range of [`generate`]'s "ramp", K.
pub const DEFAULT_RAMP_K: (f64, f64) = (280.0, 320.0);

/// Builds the scene `kind` (a name from [`KINDS`]) with default temperatures: bars 305 K on
/// 300 K, edge 300/310 K at 5°, blackbody 300 K with ε = 1, ramp 280–320 K, thermal under
/// the default [`Environment`].
pub fn generate(kind: &str, p: &SceneParams) -> Result<Cube> {
    match kind {
        "thermal" => thermal(p),
        "bars" => bars(
            p,
            DEFAULT_BAR_TEMPERATURE_K,
            DEFAULT_BACKGROUND_TEMPERATURE_K,
        ),
        "edge" => edge(
            p,
            DEFAULT_BACKGROUND_TEMPERATURE_K,
            DEFAULT_EDGE_HIGH_K,
            DEFAULT_EDGE_ANGLE_DEG,
        ),
        "blackbody" => blackbody(p, DEFAULT_BACKGROUND_TEMPERATURE_K, 1.0),
        "ramp" => ramp(p, DEFAULT_RAMP_K.0, DEFAULT_RAMP_K.1),
        _ => Err(Error::param(
            "scene kind",
            kind,
            format!(
                "one of {}",
                KINDS.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", ")
            ),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn planck_band_matches_radiometry() {
        for &l in &[0.5, 1.0, 4.0, 10.0, 14.0] {
            for &t in &[250.0, 300.0, 800.0, 5772.0] {
                let a = PlanckBand::new(l).radiance(t);
                let b = planck_spectral_radiance(l, t);
                assert!(
                    (a - b).abs() <= 1e-12 * b.abs() + 1e-300,
                    "{l} {t}: {a} vs {b}"
                );
            }
        }
    }

    /// Coverage of a pixel by a half-plane against a fine point count.
    #[test]
    fn half_plane_coverage_matches_point_count() {
        let n = 400;
        for &(theta_deg, d) in &[
            (5.0f64, 0.13),
            (37.0, -0.4),
            (90.0, 0.2),
            (-60.0, 0.55),
            (0.0, 0.5),
        ] {
            let t = theta_deg.to_radians();
            let (nx, ny) = (t.cos(), -t.sin());
            let (x0, y0) = (-0.5, -0.5);
            let exact = half_plane_coverage(x0, y0, nx, ny, d);
            let mut count = 0usize;
            for j in 0..n {
                for i in 0..n {
                    let x = x0 + (i as f64 + 0.5) / n as f64;
                    let y = y0 + (j as f64 + 0.5) / n as f64;
                    if nx * x + ny * y >= d {
                        count += 1;
                    }
                }
            }
            let approx = count as f64 / (n * n) as f64;
            assert!(
                (exact - approx).abs() < 5e-3,
                "{theta_deg} {d}: {exact} vs {approx}"
            );
        }
    }

    #[test]
    fn fbm_is_standardised_and_seeded() {
        let a = Fbm::new(7, 0, 0.3, 0.01, 1.5, 1.0);
        let b = Fbm::new(7, 0, 0.3, 0.01, 1.5, 1.0);
        let c = Fbm::new(7, 1, 0.3, 0.01, 1.5, 1.0);
        let pts: Vec<(f64, f64)> = (0..500)
            .map(|i| ((i as f64 * 0.37) % 1.5, (i as f64 * 0.61) % 1.0))
            .collect();
        assert!(pts.iter().all(|&(x, y)| a.eval(x, y) == b.eval(x, y)));
        assert!(pts.iter().any(|&(x, y)| a.eval(x, y) != c.eval(x, y)));
        let v: Vec<f64> = pts.iter().map(|&(x, y)| a.eval(x, y)).collect();
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / v.len() as f64).sqrt();
        assert!(
            mean.abs() < 0.2 && (sd - 1.0).abs() < 0.2,
            "mean {mean} sd {sd}"
        );
    }
}
