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

mod environment;
mod targets;
mod thermal;

pub use environment::*;
pub use targets::*;
pub use thermal::*;

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

/// Working set of the scene generators per (oversampled) pixel besides the cube, bytes:
/// the thermal scene's per-pixel `(Region, Recipe, f32)` list, held twice at the peak,
/// and its region, temperature and vegetation maps (about 90 B; the
/// `scene_working_set_bound` test in `thermal` checks it), or a target's f64 coverage map.
pub const SCENE_BYTES_PER_PIXEL: u64 = 128;

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
        // The cube (f32) and the generators' per-pixel working set, before either exists.
        let pixels = crate::limits::checked_count(
            "the synthetic scene",
            &[
                ("rows", self.rows as u64),
                ("cols", self.cols as u64),
                ("oversampling²", k as u64 * k as u64),
            ],
        )?;
        let bytes = (values as u64)
            .checked_mul(4)
            .and_then(|c| c.checked_add(pixels.checked_mul(SCENE_BYTES_PER_PIXEL)?));
        crate::limits::check_bytes(
            "the synthetic scene",
            &format!(
                "{values} f32 values + {pixels} pixels × {SCENE_BYTES_PER_PIXEL} B working set"
            ),
            bytes.unwrap_or(u64::MAX),
        )?;
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
                // Every band holds at least one value of the cube, and the grid itself is
                // bounded by the memory budget, before it is allocated.
                if bands as u64 > MAX_CUBE_VALUES {
                    return Err(Error::param(
                        "bands",
                        bands,
                        format!("at most {MAX_CUBE_VALUES} (the cube's value limit)"),
                    ));
                }
                crate::limits::check_alloc("the wavelength grid", &[("bands", bands as u64)], 8)?;
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
    use super::targets::half_plane_coverage;
    use super::thermal::Fbm;
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
