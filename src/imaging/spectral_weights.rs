//! Spectral weights: the electrons each band of a cube contributes per unit of its input
//! value (the camera equation's étendue × time × the band's share of the response), and
//! the check that the cube's wavelength grid covers the sensor's response.

use crate::constants::{PLANCK_H, SPEED_OF_LIGHT_C};
use crate::error::{Error, Result};
use crate::radiometry;
use crate::scene::{CubeMeta, RadianceUnits};
use crate::sensor::Sensor;
use crate::spectrum::Spectrum;

/// Fraction of the sensor's spectral response weight that may fall outside the input
/// wavelength grid (issue requirement: the grid must cover all but 0.1 %).
pub const MAX_UNCOVERED_RESPONSE: f64 = 1e-3;

/// Electrons per unit input value for every band of a cube.
#[derive(Debug, Clone, PartialEq)]
pub struct SpectralWeights {
    /// Band wavelengths, µm.
    pub wavelength_um: Vec<f64>,
    /// Electrons per (W m-2 sr-1 µm-1) for spectral input, or per (W m-2 sr-1) for
    /// band-integrated input, for each band.
    pub electrons_per_unit: Vec<f64>,
}

impl SpectralWeights {
    /// Computes the weights of `sensor` for the bands of `meta` and checks that the
    /// wavelength grid covers the sensor's response (all but [`MAX_UNCOVERED_RESPONSE`]).
    pub fn new(sensor: &Sensor, meta: &CubeMeta) -> Result<Self> {
        let response = sensor.response();
        check_coverage(response, &meta.wavelength_um)?;
        let etendue_time = sensor.camera().etendue_time();
        let per_joule = 1e-6 / (PLANCK_H * SPEED_OF_LIGHT_C); // λ/(hc) with λ in µm
        let wl = &meta.wavelength_um;
        let electrons_per_unit = match meta.units {
            RadianceUnits::SpectralPerUm => {
                if wl.len() < 2 {
                    return Err(Error::param(
                        "input wavelength grid",
                        format!("{} band", wl.len()),
                        "at least 2 wavelengths for spectral radiance (W m-2 sr-1 µm-1); a single band must be band-integrated (W m-2 sr-1)",
                    ));
                }
                hat_weights(response, wl)
                    .into_iter()
                    .map(|w| etendue_time * per_joule * w)
                    .collect()
            }
            RadianceUnits::BandIntegrated => wl
                .iter()
                .map(|l| etendue_time * per_joule * response.eval(*l) * l)
                .collect(),
        };
        Ok(SpectralWeights {
            wavelength_um: meta.wavelength_um.clone(),
            electrons_per_unit,
        })
    }

    /// Bands that contribute (non-zero weight).
    pub fn active_bands(&self) -> Vec<usize> {
        (0..self.electrons_per_unit.len())
            .filter(|b| self.electrons_per_unit[*b] != 0.0)
            .collect()
    }
}

/// Product-integration weights `∫ S(λ) λ φ_b(λ) dλ` (µm²) for each band b, with φ_b the
/// hat function that is 1 at λ_b and falls linearly to 0 at the neighbouring bands.
///
/// `Σ_b w_b L_b` is then the exact integral of `S(λ) λ L(λ)` for the piecewise-linear
/// interpolant of the sampled radiance L: the sensor's known response (sharp filter edges,
/// detector cutoff) is integrated exactly instead of being sampled at the band centres,
/// so the only error left is the curvature of the radiance between bands. (The
/// trapezoid rule `S(λ_b) λ_b Δλ_b` is the same rule with S also interpolated linearly;
/// it errs by ~1e-4 at filter edges even with 100 bands over the band.)
pub fn hat_weights(response: &Spectrum, wavelength_um: &[f64]) -> Vec<f64> {
    let bp = response.breakpoints_um();
    let n = wavelength_um.len();
    (0..n)
        .map(|b| {
            let c = wavelength_um[b];
            let mut w = 0.0;
            if b > 0 {
                let a = wavelength_um[b - 1];
                w += radiometry::integrate(
                    |l| response.eval(l) * l * (l - a) / (c - a),
                    a,
                    c,
                    &bp,
                    1e-11,
                );
            }
            if b + 1 < n {
                let d = wavelength_um[b + 1];
                w += radiometry::integrate(
                    |l| response.eval(l) * l * (d - l) / (d - c),
                    c,
                    d,
                    &bp,
                    1e-11,
                );
            }
            w
        })
        .collect()
}

/// Checks that the wavelength grid `[first, last]` covers the response `S` weighted by λ
/// (photon counting of a flat spectral radiance) except for at most
/// [`MAX_UNCOVERED_RESPONSE`] of it; the error names the uncovered range(s).
pub fn check_coverage(response: &Spectrum, wavelength_um: &[f64]) -> Result<()> {
    let (lo, hi) = response.support_um();
    let (first, last) = match (wavelength_um.first(), wavelength_um.last()) {
        (Some(a), Some(b)) => (*a, *b),
        _ => {
            return Err(Error::param(
                "input wavelength grid",
                "empty",
                "at least one band",
            ))
        }
    };
    // An unbounded response (e.g. no filter and a flat QE) cannot be checked: the grid
    // then defines the band.
    if !(lo.is_finite() && hi.is_finite()) {
        return Ok(());
    }
    let bp = response.breakpoints_um();
    let w = |l: f64| l * response.eval(l);
    let total = radiometry::integrate(w, lo, hi, &bp, 1e-9);
    if total <= 0.0 {
        return Err(Error::param(
            "sensor spectral response",
            "zero everywhere",
            "some wavelength where filter, optics, atmosphere and QE are all non-zero",
        ));
    }
    let below = if first > lo {
        radiometry::integrate(w, lo, first.min(hi), &bp, 1e-9)
    } else {
        0.0
    };
    let above = if last < hi {
        radiometry::integrate(w, last.max(lo), hi, &bp, 1e-9)
    } else {
        0.0
    };
    let missing = (below + above) / total;
    if missing > MAX_UNCOVERED_RESPONSE {
        let mut ranges = Vec::new();
        if below > 0.0 {
            ranges.push(format!("{lo:.4}–{:.4} µm", first.min(hi)));
        }
        if above > 0.0 {
            ranges.push(format!("{:.4}–{hi:.4} µm", last.max(lo)));
        }
        return Err(Error::param(
            "input wavelength grid",
            format!("{first:.4}–{last:.4} µm"),
            format!(
                "a grid covering the sensor response ({lo:.4}–{hi:.4} µm): {} uncovered, {:.2} % of the response (at most {} % allowed)",
                ranges.join(" and "),
                100.0 * missing,
                100.0 * MAX_UNCOVERED_RESPONSE
            ),
        ));
    }
    Ok(())
}
