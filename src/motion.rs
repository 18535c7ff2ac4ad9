//! Platform and line-of-sight motion: linear smear, random jitter and a global Gaussian blur.
//!
//! Every transfer function here takes angular spatial frequencies in cycles/rad in object
//! space (docs/design.md §3) and returns a real, signed value (docs/design.md §4.6). The smear length,
//! jitter and blur widths are angles in rad.

use std::f64::consts::PI;

use crate::optics::sinc;

/// Linear motion blur transfer function (docs/design.md §4.6): `sinc(f_along · d)`.
///
/// The image moves uniformly over an angle `d = smear_rad` during the integration time,
/// so the point-spread function is a box of width `d` along the motion direction, centred
/// on the mean position. Its Fourier transform is `sinc(f_along · d)` with
/// `f_along = fx cos θ + fy sin θ`, θ = `direction_rad` measured from +x toward +y.
/// Frequencies in cycles/rad; the result is real and signed (contrast reverses between
/// the first and second zero, at `f_along · d` = 1 and 2). Frequency components
/// perpendicular to the motion are not affected. The sign of `smear_rad` does not matter.
pub fn linear_motion(
    fx_cy_per_rad: f64,
    fy_cy_per_rad: f64,
    smear_rad: f64,
    direction_rad: f64,
) -> f64 {
    let (sin_t, cos_t) = direction_rad.sin_cos();
    let f_along = fx_cy_per_rad * cos_t + fy_cy_per_rad * sin_t;
    sinc(f_along * smear_rad)
}

/// Angular smear (rad) from a relative transverse velocity: `d = v · t_int / R`
/// (docs/design.md §4.6), with `v` in m/s, `t_int` in s and the range `R` in m.
///
/// Small-angle form: valid while `d ≪ 1` rad, which holds for any realistic exposure.
/// The caller validates the inputs (a range of 0 gives an infinite smear).
pub fn smear_from_velocity(velocity_m_s: f64, integration_time_s: f64, range_m: f64) -> f64 {
    velocity_m_s * integration_time_s / range_m
}

/// Angular smear (rad) from a line-of-sight angular rate: `d = ω · t_int`, with ω in rad/s
/// and `t_int` in s (docs/design.md §4.6).
pub fn smear_from_angular_rate(rate_rad_s: f64, integration_time_s: f64) -> f64 {
    rate_rad_s * integration_time_s
}

/// Random line-of-sight jitter transfer function (docs/design.md §4.6):
/// `exp(−2π²σ²(fx² + fy²))`.
///
/// The jitter is a zero-mean Gaussian random angle of rms `σ = sigma_rad` on each axis,
/// independent between axes, so the time-averaged PSF is the 2-D Gaussian
/// `exp(−(x² + y²)/(2σ²)) / (2πσ²)` whose Fourier transform this is. Frequencies in
/// cycles/rad.
pub fn jitter(fx_cy_per_rad: f64, fy_cy_per_rad: f64, sigma_rad: f64) -> f64 {
    gaussian(fx_cy_per_rad, fy_cy_per_rad, sigma_rad, sigma_rad)
}

/// Global Gaussian blur transfer function (docs/design.md §4.6), with separate rms widths per
/// axis: `exp(−2π²(σx² fx² + σy² fy²))`.
///
/// The Fourier transform of the unit-area PSF
/// `exp(−x²/(2σx²) − y²/(2σy²)) / (2πσxσy)`; σ in rad, frequencies in cycles/rad. Kept
/// separate from [`jitter`] so a sensor can configure both (they multiply, i.e. their
/// variances add).
pub fn gaussian(fx_cy_per_rad: f64, fy_cy_per_rad: f64, sigma_x_rad: f64, sigma_y_rad: f64) -> f64 {
    let ax = sigma_x_rad * fx_cy_per_rad;
    let ay = sigma_y_rad * fy_cy_per_rad;
    (-2.0 * PI * PI * (ax * ax + ay * ay)).exp()
}
