//! Radiometry: Planck's law, band integrals, the camera equation, apparent temperature.

use crate::constants::{BOLTZMANN_K, PLANCK_H, SPEED_OF_LIGHT_C};

/// First radiation constant for radiance, c1L = 2hc², W m² sr-1.
const C1L: f64 = 2.0 * PLANCK_H * SPEED_OF_LIGHT_C * SPEED_OF_LIGHT_C;
/// Second radiation constant c2 = hc/k, m K.
const C2: f64 = PLANCK_H * SPEED_OF_LIGHT_C / BOLTZMANN_K;

/// Planck spectral radiance of a blackbody, W m-2 sr-1 µm-1.
///
/// `L_λ(λ, T) = 2hc² / λ⁵ / (exp(hc/(λkT)) − 1)` (Planck's law, energy form), evaluated in
/// SI and converted to per-µm. Returns 0 for T ≤ 0 or λ ≤ 0.
pub fn planck_spectral_radiance(wavelength_um: f64, temperature_k: f64) -> f64 {
    if wavelength_um <= 0.0 || temperature_k <= 0.0 {
        return 0.0;
    }
    let lambda_m = wavelength_um * 1e-6;
    let x = C2 / (lambda_m * temperature_k);
    // exp_m1 keeps precision in the Rayleigh–Jeans limit (small x).
    C1L / lambda_m.powi(5) / x.exp_m1() * 1e-6
}

/// Planck spectral photon radiance, photons s-1 m-2 sr-1 µm-1.
///
/// `L_q(λ, T) = L_λ(λ, T) · λ/(hc) = 2c / λ⁴ / (exp(hc/(λkT)) − 1)` (photon form).
pub fn planck_photon_radiance(wavelength_um: f64, temperature_k: f64) -> f64 {
    planck_spectral_radiance(wavelength_um, temperature_k) * wavelength_um * 1e-6
        / (PLANCK_H * SPEED_OF_LIGHT_C)
}
