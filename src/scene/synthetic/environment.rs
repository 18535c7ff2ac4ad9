//! Surface materials, the sun and a caricature clear-sky atmosphere ([`Environment`]):
//! the illumination model of the synthetic scenes (see the parent module for the equations).

use super::*;

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
