//! Noise-equivalent temperature difference (NETD): the scene temperature change that gives
//! a signal change equal to the temporal noise,
//!
//! `NETD = σ_temporal / (∂S/∂T)`,
//!
//! with S the detector output (DN) for a uniform blackbody scene at temperature T
//! (FOI report §2.2.2.1 on temporal noise; e.g. Holst, *Testing and Evaluation of Infrared
//! Imaging Systems*, NETD = noise / responsivity).
//!
//! [`analytic_netd`] takes the modelled response `S(T)` and the modelled noise;
//! [`measured_netd`] takes two stacks of frames of a uniform scene at T and T + ΔT.

use ndarray::{Array2, ArrayView3, Axis, Zip};

use super::bad_pixels::BadPixelMap;
use super::{check_shape, check_stack, median_in_place};
use crate::error::{require_non_negative, require_positive, Error, Result};

/// Relative step of the central difference in [`responsivity_dn_per_k`]: h = 1e-3 · T.
/// Its truncation error h²·S'''/6 is ~1e-6 of S' for Planck-type responses at 300 K (their
/// scale of variation is tens of kelvin) while the round-off ε·S/h stays ~1e-12.
pub const DIFFERENCE_STEP_FRACTION: f64 = 1e-3;

/// Responsivity `dS/dT` (DN/K) of a response `signal_dn(T)` at `temperature_k`, by the
/// central difference `(S(T+h) − S(T−h)) / 2h`, h = [`DIFFERENCE_STEP_FRACTION`] · T.
///
/// Errors: a temperature not finite and > 0, or a non-finite difference.
pub fn responsivity_dn_per_k(signal_dn: impl Fn(f64) -> f64, temperature_k: f64) -> Result<f64> {
    require_positive("temperature_k", temperature_k)?;
    let h = DIFFERENCE_STEP_FRACTION * temperature_k;
    let d = (signal_dn(temperature_k + h) - signal_dn(temperature_k - h)) / (2.0 * h);
    if !d.is_finite() {
        return Err(Error::OutOfRange(format!(
            "responsivity: the signal response is not finite around T = {temperature_k} K"
        )));
    }
    Ok(d)
}

/// Analytic NETD (K): `noise_dn / |dS/dT|` at `temperature_k`, the derivative from
/// [`responsivity_dn_per_k`].
///
/// Errors: invalid temperature or noise (must be finite and ≥ 0), or a zero responsivity.
pub fn analytic_netd(
    signal_dn: impl Fn(f64) -> f64,
    temperature_k: f64,
    noise_dn: f64,
) -> Result<f64> {
    require_non_negative("noise_dn", noise_dn)?;
    let r = responsivity_dn_per_k(signal_dn, temperature_k)?;
    if r == 0.0 {
        return Err(Error::OutOfRange(format!(
            "NETD: the signal does not change with temperature at T = {temperature_k} K"
        )));
    }
    Ok(noise_dn / r.abs())
}

/// The NETD of a corrected array with and without its residual fixed pattern (see
/// [`netd_with_spatial_noise`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpatialNetd {
    /// Temporal noise, DN rms.
    pub temporal_noise_dn: f64,
    /// Spatial noise of one corrected frame, DN rms (residual fixed pattern and that
    /// frame's temporal noise together).
    pub spatial_noise_dn: f64,
    /// Responsivity, DN/K.
    pub responsivity_dn_per_k: f64,
    /// `σ_t / |R|`, K.
    pub temporal_netd_k: f64,
    /// `max(σ_t, σ_s) / |R|`, K: the temperature difference equal to the total noise a
    /// viewer of one corrected frame sees across the array.
    pub total_netd_k: f64,
}

/// NETD including spatial noise after a NUC. One corrected frame of a uniform source
/// varies across the array by `σ_s² = σ_t² + σ_fp²` (its own temporal noise plus the
/// residual fixed pattern σ_fp; the 3-D noise model's σ_tvh and σ_vh in quadrature,
/// D'Agostino & Webb 1991, Proc. SPIE 1488), so the NETD including spatial noise is
/// `σ_s/|R|` beside the temporal `σ_t/|R|`. When sampling makes σ_s fall below σ_t, the
/// total is taken as σ_t/|R| (the fixed pattern cannot be negative).
///
/// Errors: a negative or non-finite noise, or a zero or non-finite responsivity.
pub fn netd_with_spatial_noise(
    temporal_noise_dn: f64,
    spatial_noise_dn: f64,
    responsivity_dn_per_k: f64,
) -> Result<SpatialNetd> {
    require_non_negative("temporal_noise_dn", temporal_noise_dn)?;
    require_non_negative("spatial_noise_dn", spatial_noise_dn)?;
    if !(responsivity_dn_per_k.is_finite() && responsivity_dn_per_k != 0.0) {
        return Err(Error::param(
            "responsivity",
            responsivity_dn_per_k,
            "a finite, non-zero DN/K (the levels must differ)",
        ));
    }
    let r = responsivity_dn_per_k.abs();
    Ok(SpatialNetd {
        temporal_noise_dn,
        spatial_noise_dn,
        responsivity_dn_per_k,
        temporal_netd_k: temporal_noise_dn / r,
        total_netd_k: temporal_noise_dn.max(spatial_noise_dn) / r,
    })
}

/// A NETD measured from frame stacks (see [`measured_netd`]).
#[derive(Debug, Clone, PartialEq)]
pub struct NetdMeasurement {
    /// NETD of the array: temporal noise / mean responsivity, K.
    pub netd_k: f64,
    /// Temporal noise at T: root of the pixel-averaged temporal variance, DN.
    pub temporal_noise_dn: f64,
    /// Mean responsivity (mean DN difference / ΔT), DN/K.
    pub responsivity_dn_per_k: f64,
    /// Per-pixel NETD σ_ij / R_ij, K (NaN for excluded pixels).
    pub pixel_netd_k: Array2<f64>,
    /// Median of the per-pixel NETD over valid pixels, K.
    pub median_pixel_netd_k: f64,
    /// Number of pixels used.
    pub pixels: usize,
}

/// Measured NETD from stacks `[frame, row, col]` of a uniform scene at T (`at_t`) and at
/// T + ΔT (`at_t_plus`, ΔT = `delta_t_k`).
///
/// Per pixel, the temporal variance σ_ij² ((L − 1)-normalised, over the frames at T) and
/// the responsivity `R_ij = (⟨S⟩_{T+ΔT} − ⟨S⟩_T) / ΔT`. The array NETD is
/// `√(mean σ_ij²) / mean R_ij` over the pixels not excluded; averaging variances rather
/// than σ avoids the small-sample bias of the sample standard deviation.
///
/// Errors: stacks of fewer than 2 frames or of different frame shapes, a map of another
/// shape, ΔT not finite and > 0, no valid pixel, or a zero mean responsivity.
pub fn measured_netd(
    at_t: ArrayView3<f64>,
    at_t_plus: ArrayView3<f64>,
    delta_t_k: f64,
    exclude: Option<&BadPixelMap>,
) -> Result<NetdMeasurement> {
    check_stack("at_t", at_t)?;
    check_stack("at_t_plus", at_t_plus)?;
    require_positive("delta_t_k", delta_t_k)?;
    let (l, rows, cols) = at_t.dim();
    check_shape(
        "at_t_plus frames",
        (at_t_plus.len_of(Axis(1)), at_t_plus.len_of(Axis(2))),
        (rows, cols),
    )?;
    if l < 2 {
        return Err(Error::param(
            "at_t",
            format!("{l} frame"),
            "at least 2 frames to measure the temporal noise",
        ));
    }
    if let Some(m) = exclude {
        check_shape("bad-pixel map", m.dim(), (rows, cols))?;
    }
    let mean_t = at_t
        .mean_axis(Axis(0))
        .ok_or_else(|| Error::param("at_t", "0 frames", "at least 2 frames"))?;
    let mean_t2 = at_t_plus
        .mean_axis(Axis(0))
        .ok_or_else(|| Error::param("at_t_plus", "0 frames", "at least 1 frame"))?;
    let mut var = Array2::<f64>::zeros((rows, cols));
    for frame in at_t.outer_iter() {
        Zip::from(&mut var)
            .and(&frame)
            .and(&mean_t)
            .for_each(|v, &y, &m| *v += (y - m) * (y - m));
    }
    var /= (l - 1) as f64;
    let resp = (&mean_t2 - &mean_t) / delta_t_k;

    let mut sum_var = 0.0;
    let mut sum_resp = 0.0;
    let mut n = 0usize;
    let mut pixel_netd_k = Array2::from_elem((rows, cols), f64::NAN);
    let mut valid_netd = Vec::with_capacity(rows * cols);
    for ((i, j), &v) in var.indexed_iter() {
        let r = resp[[i, j]];
        if exclude.is_some_and(|m| m.is_bad(i, j)) || !(v.is_finite() && r.is_finite()) {
            continue;
        }
        sum_var += v;
        sum_resp += r;
        n += 1;
        let p = v.sqrt() / r.abs();
        pixel_netd_k[[i, j]] = p;
        valid_netd.push(p);
    }
    if n == 0 {
        return Err(Error::param(
            "frames",
            "no valid pixel",
            "at least one finite, unflagged pixel",
        ));
    }
    let temporal_noise_dn = (sum_var / n as f64).sqrt();
    let responsivity = sum_resp / n as f64;
    if responsivity == 0.0 {
        return Err(Error::OutOfRange(
            "measured NETD: the mean signal does not change between T and T + ΔT".to_string(),
        ));
    }
    let median_pixel_netd_k = median_in_place(&mut valid_netd).unwrap_or(f64::NAN);
    Ok(NetdMeasurement {
        netd_k: temporal_noise_dn / responsivity.abs(),
        temporal_noise_dn,
        responsivity_dn_per_k: responsivity,
        pixel_netd_k,
        median_pixel_netd_k,
        pixels: n,
    })
}
