//! Calibrated images: DN ↔ band radiance by a linear calibration, and apparent-temperature
//! images through the sensor's own blackbody lookup table
//! ([`TemperatureLut`], docs/design.md §4.9).
//!
//! A per-pixel radiometric calibration is a NUC whose reference is the source radiance:
//! [`NucCoefficients::fit`](super::nuc::NucCoefficients::fit) with `(L_band, frame)` levels
//! maps DN straight to radiance. [`LinearCalibration`] is the array-wide version
//! `DN = gain · L + offset` (after NUC, or for a model without fixed-pattern noise).

use ndarray::{Array2, ArrayView2, Zip};

use super::fit_line;
use crate::error::{Error, Result};
use crate::radiometry::TemperatureLut;

/// An apparent-temperature image with the count of pixels that could not be inverted.
#[derive(Debug, Clone, PartialEq)]
pub struct TemperatureImage {
    /// Apparent temperature, K; NaN where the input was NaN or outside the LUT's range.
    pub temperature_k: Array2<f64>,
    /// Number of NaN pixels in `temperature_k`.
    pub nan_count: usize,
}

/// Converts an image of LUT values (whatever the LUT tabulates: band radiance, electrons,
/// DN) to apparent temperature, in parallel; out-of-range and NaN inputs become NaN and
/// are counted.
pub fn apparent_temperature(values: ArrayView2<f64>, lut: &TemperatureLut) -> TemperatureImage {
    let temperature_k = Zip::from(&values).par_map_collect(|&v| lut.temperature_or_nan(v));
    let nan_count = temperature_k.iter().filter(|t| t.is_nan()).count();
    TemperatureImage {
        temperature_k,
        nan_count,
    }
}

/// Linear radiometric calibration `DN = gain · L + offset`, L in the units of the
/// calibration sources (band radiance W m-2 sr-1 unless stated otherwise).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearCalibration {
    /// DN per unit radiance.
    pub gain_dn_per_radiance: f64,
    /// DN at zero radiance.
    pub offset_dn: f64,
}

impl LinearCalibration {
    /// A calibration from its gain and offset.
    ///
    /// Errors: a gain that is zero or not finite, or a non-finite offset.
    pub fn new(gain_dn_per_radiance: f64, offset_dn: f64) -> Result<Self> {
        if !(gain_dn_per_radiance.is_finite() && gain_dn_per_radiance != 0.0) {
            return Err(Error::param(
                "gain_dn_per_radiance",
                gain_dn_per_radiance,
                "a finite, non-zero gain",
            ));
        }
        if !offset_dn.is_finite() {
            return Err(Error::param("offset_dn", offset_dn, "a finite offset"));
        }
        Ok(LinearCalibration {
            gain_dn_per_radiance,
            offset_dn,
        })
    }

    /// The line through two `(radiance, DN)` points (two-point calibration).
    ///
    /// Errors: equal radiances, equal DN, or non-finite values.
    pub fn from_two_points(p1: (f64, f64), p2: (f64, f64)) -> Result<Self> {
        Self::fit(&[p1, p2])
    }

    /// Least-squares line through `(radiance, DN)` points (two or more).
    ///
    /// Errors: fewer than two points, no spread in radiance, non-finite values, or a
    /// zero fitted gain.
    pub fn fit(points: &[(f64, f64)]) -> Result<Self> {
        if let Some(p) = points
            .iter()
            .find(|p| !(p.0.is_finite() && p.1.is_finite()))
        {
            return Err(Error::param(
                "calibration point",
                format!("({}, {})", p.0, p.1),
                "finite (radiance, DN) values",
            ));
        }
        let (gain, offset) = fit_line(points).ok_or_else(|| {
            Error::param(
                "calibration points",
                format!("{} point(s)", points.len()),
                "at least two points at different radiances",
            )
        })?;
        Self::new(gain, offset)
    }

    /// DN for radiance `radiance`.
    pub fn dn(&self, radiance: f64) -> f64 {
        self.gain_dn_per_radiance * radiance + self.offset_dn
    }

    /// Radiance for `dn`, `(DN − offset) / gain`.
    pub fn radiance(&self, dn: f64) -> f64 {
        (dn - self.offset_dn) / self.gain_dn_per_radiance
    }

    /// Radiance image from a DN image.
    pub fn radiance_image(&self, dn: ArrayView2<f64>) -> Array2<f64> {
        dn.mapv(|v| self.radiance(v))
    }

    /// DN image from a radiance image.
    pub fn dn_image(&self, radiance: ArrayView2<f64>) -> Array2<f64> {
        radiance.mapv(|v| self.dn(v))
    }

    /// Apparent temperature from a DN image: DN → radiance by this calibration, then
    /// radiance → T by `lut` (which must tabulate the same radiance).
    pub fn temperature_image(&self, dn: ArrayView2<f64>, lut: &TemperatureLut) -> TemperatureImage {
        apparent_temperature(self.radiance_image(dn).view(), lut)
    }
}
