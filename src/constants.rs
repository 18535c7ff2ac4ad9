//! Physical constants, SI, exact values of the 2019 redefinition of the SI base units.

/// Planck constant h, J s (exact).
pub const PLANCK_H: f64 = 6.626_070_15e-34;
/// Speed of light in vacuum c, m/s (exact).
pub const SPEED_OF_LIGHT_C: f64 = 299_792_458.0;
/// Boltzmann constant k, J/K (exact).
pub const BOLTZMANN_K: f64 = 1.380_649e-23;
/// Stefan–Boltzmann constant σ = 2π⁵k⁴/(15h³c²), W m-2 K-4 (derived, exact to f64).
pub const STEFAN_BOLTZMANN_SIGMA: f64 = 5.670_374_419e-8;
/// Wien displacement constant b for the wavelength peak, m K (λ_max = b / T).
pub const WIEN_B_M_K: f64 = 2.897_771_955e-3;
/// Metres per micrometre.
pub const M_PER_UM: f64 = 1e-6;
