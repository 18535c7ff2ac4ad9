//! `[optics.relative_illumination]` and `[optics.distortion]` (docs/field-optics.md): the
//! irradiance fall-off across the field beyond (or instead of) the cos⁴θ law, and the
//! radial distortion of the image, both as functions of the normalised field height.
//!
//! The normalised field height is `H = r / r_corner`: `r` the distance of an image point
//! from the optical axis (the centre of the detector array) in the focal plane and
//! `r_corner = ½ √((cols·p)² + (rows·p)²)` the distance of the array's outer corner
//! (p the pixel pitch). H = 1 is the corner of the array.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// `[optics.relative_illumination]`: a table of relative illumination against field
/// height, interpolated linearly, the end values held outside it. It multiplies the
/// cos⁴θ law when `optics.cos4 = true` (it then holds only what cos⁴θ leaves out:
/// vignetting, pupil aberrations), and is the whole relative illumination otherwise.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RelativeIlluminationConfig {
    /// Normalised field heights H (1 = the array's corner), increasing, ≥ 0. Give this or
    /// `image_heights_mm`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub field_heights: Option<Vec<f64>>,
    /// Image heights in the focal plane, mm, increasing, ≥ 0. Give this or `field_heights`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image_heights_mm: Option<Vec<f64>>,
    /// Relative illumination at each height, in (0, 1].
    pub factors: Vec<f64>,
}

/// Where the relative-illumination table's heights are measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HeightUnit {
    /// Normalised field height H.
    Normalised,
    /// Image height, m.
    ImageM,
}

impl RelativeIlluminationConfig {
    /// The table's heights (normalised, or image heights in m) and their unit, checked:
    /// exactly one height list, as long as `factors`, at least two points, heights finite,
    /// ≥ 0 and strictly increasing, factors in (0, 1].
    pub fn heights(&self) -> Result<(Vec<f64>, HeightUnit)> {
        const T: &str = "optics.relative_illumination";
        let (name, heights, unit) = match (&self.field_heights, &self.image_heights_mm) {
            (Some(h), None) => ("field_heights", h.clone(), HeightUnit::Normalised),
            (None, Some(h)) => (
                "image_heights_mm",
                h.iter().map(|v| v * 1e-3).collect(),
                HeightUnit::ImageM,
            ),
            _ => return Err(Error::param(
                T,
                "both or neither of field_heights and image_heights_mm",
                "exactly one of field_heights (normalised, 1 = array corner) or image_heights_mm",
            )),
        };
        if heights.len() != self.factors.len() || heights.len() < 2 {
            return Err(Error::param(
                format!("{T}.{name} / factors"),
                format!(
                    "{} heights and {} factors",
                    heights.len(),
                    self.factors.len()
                ),
                "as many factors as heights, at least 2",
            ));
        }
        for (i, h) in heights.iter().enumerate() {
            let increasing = i == 0 || *h > heights[i - 1];
            if !(h.is_finite() && *h >= 0.0 && increasing) {
                return Err(Error::param(
                    format!("{T}.{name}[{i}]"),
                    h,
                    "finite, ≥ 0 and larger than the height before it",
                ));
            }
        }
        for (i, f) in self.factors.iter().enumerate() {
            if !(f.is_finite() && *f > 0.0 && *f <= 1.0) {
                return Err(Error::param(format!("{T}.factors[{i}]"), f, "in (0, 1]"));
            }
        }
        Ok((heights, unit))
    }
}

/// Linear interpolation of `values` at `x` over increasing `xs`, the end values held
/// outside them.
pub fn interpolate_held(xs: &[f64], values: &[f64], x: f64) -> f64 {
    let n = xs.len().min(values.len());
    if n == 0 {
        return 1.0;
    }
    if x <= xs[0] {
        return values[0];
    }
    if x >= xs[n - 1] {
        return values[n - 1];
    }
    let i = xs[..n].partition_point(|v| *v <= x).clamp(1, n - 1);
    let t = (x - xs[i - 1]) / (xs[i] - xs[i - 1]);
    values[i - 1] + t * (values[i] - values[i - 1])
}

/// `[optics.distortion]`: radial distortion in the Brown–Conrady form (D. C. Brown,
/// "Decentering distortion of lenses", Photogramm. Eng. 32, 444, 1966, radial terms) on the
/// normalised field height: `H_real = H (1 + k1 H² + k2 H⁴)`, H the paraxial height.
/// k1 + k2 is the distortion at the array's corner (−0.02: 2 % barrel).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DistortionConfig {
    /// Third-order coefficient k1 (of H²).
    #[serde(default)]
    pub k1: f64,
    /// Fifth-order coefficient k2 (of H⁴).
    #[serde(default)]
    pub k2: f64,
}

/// The paraxial field height up to which the distortion law must be one to one: twice the
/// array's corner, room for a scene larger than the detector's field.
pub const DISTORTION_CHECKED_H: f64 = 2.0;

impl DistortionConfig {
    /// `H_real / H` at paraxial height `h`.
    pub fn ratio(&self, h: f64) -> f64 {
        let h2 = h * h;
        1.0 + self.k1 * h2 + self.k2 * h2 * h2
    }

    /// `dH_real / dH` at paraxial height `h`.
    pub fn slope(&self, h: f64) -> f64 {
        let h2 = h * h;
        1.0 + 3.0 * self.k1 * h2 + 5.0 * self.k2 * h2 * h2
    }

    /// The real height of paraxial height `h`.
    pub fn real(&self, h: f64) -> f64 {
        h * self.ratio(h)
    }

    /// The area ratio of the mapping (real image area per paraxial image area) at paraxial
    /// height `h`: the Jacobian determinant of a radial map, `(H_real/H)·(dH_real/dH)`.
    pub fn jacobian(&self, h: f64) -> f64 {
        self.ratio(h) * self.slope(h)
    }

    /// The paraxial height whose real height is `h_real` (Newton's method from
    /// `h_real`; the law is increasing on [0, [`DISTORTION_CHECKED_H`]]). `None` when
    /// `h_real` lies beyond the checked range.
    pub fn paraxial(&self, h_real: f64) -> Option<f64> {
        if h_real > self.real(DISTORTION_CHECKED_H) {
            return None;
        }
        let mut h = h_real;
        for _ in 0..60 {
            let step = (self.real(h) - h_real) / self.slope(h);
            h = (h - step).clamp(0.0, DISTORTION_CHECKED_H);
            if step.abs() <= 1e-15 * (1.0 + h) {
                break;
            }
        }
        Some(h)
    }

    /// Checks the coefficients: finite, and the law increasing (a positive slope) on
    /// paraxial heights [0, [`DISTORTION_CHECKED_H`]], so that the mapping is one to one.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [("k1", self.k1), ("k2", self.k2)] {
            if !v.is_finite() || v.abs() > 10.0 {
                return Err(Error::param(
                    format!("optics.distortion.{name}"),
                    v,
                    "a finite number in [-10, 10]",
                ));
            }
        }
        let steps = 2000;
        for i in 0..=steps {
            let h = DISTORTION_CHECKED_H * i as f64 / steps as f64;
            if self.slope(h) <= 0.0 {
                return Err(Error::param(
                    "optics.distortion (k1, k2)",
                    format!("({}, {})", self.k1, self.k2),
                    format!(
                        "a law H(1 + k1 H² + k2 H⁴) that increases up to H = {DISTORTION_CHECKED_H} (it turns back at H = {h:.3})"
                    ),
                ));
            }
        }
        Ok(())
    }

    /// True when the law is the identity (k1 = k2 = 0): the run then skips the resampling.
    pub fn is_identity(&self) -> bool {
        self.k1 == 0.0 && self.k2 == 0.0
    }
}

/// Checks `[optics.relative_illumination]` and `[optics.distortion]` when present.
pub fn validate(
    relative_illumination: Option<&RelativeIlluminationConfig>,
    distortion: Option<&DistortionConfig>,
) -> Result<()> {
    if let Some(r) = relative_illumination {
        r.heights()?;
    }
    if let Some(d) = distortion {
        d.validate()?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_and_laws_are_checked_and_inverted() {
        let ok = RelativeIlluminationConfig {
            field_heights: Some(vec![0.0, 0.5, 1.0]),
            image_heights_mm: None,
            factors: vec![1.0, 0.9, 0.6],
        };
        assert_eq!(ok.heights().unwrap().1, HeightUnit::Normalised);
        let (xs, _) = ok.heights().unwrap();
        assert!((interpolate_held(&xs, &ok.factors, 0.75) - 0.75).abs() < 1e-15);
        assert_eq!(interpolate_held(&xs, &ok.factors, 3.0), 0.6);
        let bad = [
            (vec![0.0, 0.5, 0.5], vec![1.0, 0.9, 0.6], "field_heights[2]"),
            (vec![0.0, 1.0], vec![1.0, 1.2], "factors[1]"),
            (vec![0.0, 1.0], vec![1.0, 0.0], "factors[1]"),
            (vec![0.0, 1.0], vec![1.0], "factors"),
            (vec![-0.1, 1.0], vec![1.0, 0.5], "field_heights[0]"),
        ];
        for (h, f, field) in bad {
            let c = RelativeIlluminationConfig {
                field_heights: Some(h),
                image_heights_mm: None,
                factors: f,
            };
            let e = c.heights().unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        }
        let both = RelativeIlluminationConfig {
            image_heights_mm: Some(vec![0.0, 1.0]),
            ..ok.clone()
        };
        assert!(both.heights().is_err());

        let d = DistortionConfig {
            k1: -0.05,
            k2: 0.01,
        };
        d.validate().unwrap();
        for h in [0.0, 0.1, 0.7, 1.0, 1.9] {
            let back = d.paraxial(d.real(h)).unwrap();
            assert!((back - h).abs() < 1e-12, "{h} {back}");
            // Jacobian against a finite-difference area ratio of an annulus sector.
            let e = 1e-6;
            let hh = h.max(1e-3);
            let area = (d.real(hh + e).powi(2) - d.real(hh - e).powi(2))
                / ((hh + e).powi(2) - (hh - e).powi(2));
            assert!((area - d.jacobian(hh)).abs() < 1e-6, "{h}");
        }
        let folds = DistortionConfig { k1: -0.3, k2: 0.0 };
        assert!(folds
            .validate()
            .unwrap_err()
            .to_string()
            .contains("turns back"));
    }
}
