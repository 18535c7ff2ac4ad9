//! How the scene grid maps onto the detector grid: per axis, the ratio k of detector to
//! scene sample spacing, where detector pixel 0's centre falls in the scene, and the
//! padding the transform adds; and whether point sampling (integer k on both axes) or
//! trigonometric interpolation turns the filtered scene into detector pixels.

use num_complex::Complex64;

use crate::error::{Error, Result};
use crate::scene::sizing::paraxial_extent_rad;
use crate::scene::{CubeMeta, Geometry};
use crate::sensor::Sensor;

/// How the scene grid maps onto the detector grid along one axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisSampling {
    /// Scene samples along the axis.
    pub scene_len: usize,
    /// Detector pixels along the axis.
    pub detector_len: usize,
    /// Ratio k = detector IFOV / scene IFOV (> 1: scene finer than the detector).
    pub ratio: f64,
    /// Scene-sample coordinate of detector pixel 0's centre; pixel j is at `first + j·ratio`.
    pub first: f64,
    /// Mirror padding added before the first scene sample.
    pub pad_before: usize,
    /// Padded (FFT) length.
    pub padded_len: usize,
}

impl AxisSampling {
    pub(super) fn new(
        scene_len: usize,
        scene_ifov: f64,
        detector_len: usize,
        detector_ifov: f64,
        axis: &str,
    ) -> Result<Self> {
        let ratio = detector_ifov / scene_ifov;
        let scene_fov = paraxial_extent_rad(scene_len, scene_ifov);
        let det_fov = paraxial_extent_rad(detector_len, detector_ifov);
        if det_fov > scene_fov * (1.0 + 1e-9) {
            return Err(Error::param(
                format!("sensor field of view ({axis})"),
                format!("{:.4} mrad ({detector_len} px × {:.4} µrad)", det_fov * 1e3, detector_ifov * 1e6),
                format!(
                    "at most the scene's {:.4} mrad ({scene_len} samples × {:.4} µrad): the sensor must look inside the scene",
                    scene_fov * 1e3,
                    scene_ifov * 1e6
                ),
            ));
        }
        let first = (scene_len as f64 - 1.0) / 2.0 - (detector_len as f64 - 1.0) / 2.0 * ratio;
        Ok(AxisSampling {
            scene_len,
            detector_len,
            ratio,
            first,
            pad_before: 0,
            padded_len: scene_len,
        })
    }

    /// The integer ratio if k is an integer (to 1e-9), else `None`.
    pub fn integer_ratio(&self) -> Option<usize> {
        let k = self.ratio.round();
        ((self.ratio - k).abs() < 1e-9 * self.ratio.max(1.0) && k >= 1.0).then_some(k as usize)
    }

    /// Padded-frame coordinate of detector pixel j.
    pub(super) fn position(&self, j: usize) -> f64 {
        self.pad_before as f64 + self.first + j as f64 * self.ratio
    }
}

/// The detector sampling of a scene: per-axis mapping and the method used.
#[derive(Debug, Clone, PartialEq)]
pub struct Sampling {
    /// Along rows (y).
    pub y: AxisSampling,
    /// Along columns (x).
    pub x: AxisSampling,
    /// Scene sample spacing (y, x), rad.
    pub scene_ifov_rad: (f64, f64),
    /// Whether both ratios are integers (exact point sampling after a phase-ramp shift).
    pub integer: bool,
    /// Things the user should know (e.g. the scene is coarser than the detector).
    pub warnings: Vec<String>,
}

/// Relative shortfall below one scene sample per detector pixel that counts as a coarser
/// scene: 0.1 %. A scene sampled within this of the detector (e.g. 0.99997, a field of view
/// rounded to 3 decimals) carries all the detail the detector resolves to within the
/// rounding, so it is not worth a warning.
pub const COARSER_TOLERANCE: f64 = 1e-3;

impl Sampling {
    /// Relates a scene of `meta`'s size and `geometry` to the detector of `sensor`.
    pub fn new(sensor: &Sensor, meta: &CubeMeta, geometry: &Geometry) -> Result<Self> {
        let dy = geometry.ifov_y_rad(meta.rows);
        let dx = geometry.ifov_x_rad(meta.cols);
        let d = sensor.ifov_rad();
        let y = AxisSampling::new(meta.rows, dy, sensor.detector.rows, d, "vertical")?;
        let x = AxisSampling::new(meta.cols, dx, sensor.detector.cols, d, "horizontal")?;
        let mut warnings = Vec::new();
        if x.ratio < 1.0 - COARSER_TOLERANCE || y.ratio < 1.0 - COARSER_TOLERANCE {
            warnings.push(format!(
                "the scene is coarser than the detector: {:.5} x {:.5} scene samples per detector pixel (x, y), fewer than 1: it lacks the detail the sensor could resolve",
                x.ratio, y.ratio
            ));
        }
        let integer = x.integer_ratio().is_some() && y.integer_ratio().is_some();
        Ok(Sampling {
            y,
            x,
            scene_ifov_rad: (dy, dx),
            integer,
            warnings,
        })
    }
}

/// The factor that shifts an `n`-point axis by `s` samples at frequency bin `k`:
/// `e^{2πi k′ s / n}`, with k′ the signed frequency (`k − n` above n/2). On an even axis the
/// Nyquist bin (k = n/2) is its own negative, so it takes the average of the two factors,
/// `cos(πs)` (real): the shifted frame stays real. Both detector-sampling paths (the
/// integer ratio's phase ramp and the trigonometric interpolant) use it.
pub(super) fn shift_phase(n: usize, k: usize, s: f64) -> Complex64 {
    if n % 2 == 0 && k == n / 2 {
        return Complex64::new((std::f64::consts::PI * s).cos(), 0.0);
    }
    let signed = if k > n / 2 {
        k as f64 - n as f64
    } else {
        k as f64
    };
    Complex64::from_polar(1.0, 2.0 * std::f64::consts::PI * signed * s / n as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shift theorem against an analytic signal: a real band-limited signal sampled
    /// at n points (cosines of several bins, and the Nyquist bin on even n), transformed by
    /// a direct DFT, multiplied by `shift_phase(n, k, s)` and transformed back, equals the
    /// signal evaluated at j + s. Also the DC factor is exactly 1.
    #[test]
    fn shift_phase_shifts_a_band_limited_signal() {
        use std::f64::consts::PI;
        for n in [7usize, 8, 12] {
            let signal = |t: f64| {
                let mut x = 0.3 + (2.0 * PI * t / n as f64 + 0.4).cos();
                x += 0.5 * (2.0 * PI * 3.0 * t / n as f64 - 1.1).cos();
                if n % 2 == 0 {
                    // The Nyquist cosine; its band-limited real interpolant is cos(πt).
                    x += 0.25 * (PI * t).cos();
                }
                x
            };
            let dft: Vec<Complex64> = (0..n)
                .map(|k| {
                    (0..n)
                        .map(|j| {
                            signal(j as f64)
                                * Complex64::from_polar(1.0, -2.0 * PI * (k * j) as f64 / n as f64)
                        })
                        .sum()
                })
                .collect();
            for s in [0.37, -0.8, 2.25] {
                assert_eq!(shift_phase(n, 0, s), Complex64::new(1.0, 0.0));
                for j in 0..n {
                    let x: Complex64 = (0..n)
                        .map(|k| {
                            dft[k]
                                * shift_phase(n, k, s)
                                * Complex64::from_polar(1.0, 2.0 * PI * (k * j) as f64 / n as f64)
                        })
                        .sum::<Complex64>()
                        / n as f64;
                    let want = signal(j as f64 + s);
                    assert!(
                        (x.re - want).abs() < 1e-12,
                        "n {n}, s {s}, j {j}: {} vs {want}",
                        x.re
                    );
                    assert!(
                        x.im.abs() < 1e-12,
                        "n {n}, s {s}, j {j}: imaginary {}",
                        x.im
                    );
                }
            }
        }
    }
}
