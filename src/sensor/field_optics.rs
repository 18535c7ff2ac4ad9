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

/// `[optics.distortion]`: radial distortion on the normalised field height, either in the
/// Brown–Conrady form (D. C. Brown, "Decentering distortion of lenses", Photogramm. Eng.
/// 32, 444, 1966, radial terms) `H_real = H (1 + k1 H² + k2 H⁴)`, H the paraxial height
/// (k1 + k2 is the distortion at the array's corner: −0.02 is 2 % barrel), or as a table
/// of real against paraxial height (normalised, or image heights in mm) as lens-design
/// programs print it, interpolated by the monotone piecewise-cubic Hermite interpolant
/// (Fritsch & Carlson, SIAM J. Numer. Anal. 17, 238, 1980; derivatives by Fritsch &
/// Butland, SIAM J. Sci. Stat. Comput. 5, 300, 1984) and continued beyond its last point
/// by a straight line with the last interval's slope. Resolved into a [`DistortionLaw`].
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DistortionConfig {
    /// Third-order coefficient k1 (of H²).
    #[serde(default)]
    pub k1: f64,
    /// Fifth-order coefficient k2 (of H⁴).
    #[serde(default)]
    pub k2: f64,
    /// Table: paraxial heights, normalised (1 = the array's corner), from 0, increasing.
    /// With `real_heights`; instead of k1, k2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub paraxial_heights: Option<Vec<f64>>,
    /// Table: the real (distorted) heights of `paraxial_heights`, normalised, from 0,
    /// increasing.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub real_heights: Option<Vec<f64>>,
    /// Table in the focal plane: paraxial image heights, mm, from 0, increasing. With
    /// `real_heights_mm`; instead of the normalised table.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub paraxial_heights_mm: Option<Vec<f64>>,
    /// Table in the focal plane: the real image heights of `paraxial_heights_mm`, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub real_heights_mm: Option<Vec<f64>>,
}

/// A distortion table's paraxial and real heights and whether they are in mm.
type HeightTable<'a> = (&'a [f64], &'a [f64], bool);

/// The paraxial field height up to which the distortion law must be one to one: twice the
/// array's corner, room for a scene larger than the detector's field.
pub const DISTORTION_CHECKED_H: f64 = 2.0;

/// A resolved distortion law `H_real(H)` on normalised heights ([`DistortionConfig::law`]).
#[derive(Debug, Clone, PartialEq)]
pub enum DistortionLaw {
    /// `H (1 + k1 H² + k2 H⁴)`.
    Polynomial {
        /// Coefficient of H².
        k1: f64,
        /// Coefficient of H⁴.
        k2: f64,
    },
    /// The monotone cubic Hermite interpolant through (`h[i]`, `real[i]`) with slopes
    /// `slope[i]`, a straight line beyond the last point.
    Table {
        /// Paraxial heights, from 0, increasing.
        h: Vec<f64>,
        /// Real heights, from 0, increasing.
        real: Vec<f64>,
        /// dH_real/dH at each point.
        slope: Vec<f64>,
    },
}

impl DistortionLaw {
    /// The table law through the points (`h`, `real`) (checked by the caller: at least
    /// two, from (0, 0), both strictly increasing): Fritsch–Butland slopes inside (the
    /// weighted harmonic mean of the neighbouring secants, which keeps the interpolant
    /// monotone); at H = 0 the first secant (the centred difference of the odd law
    /// `H_real(−H) = −H_real(H)`); at the last point the three-point one-sided formula
    /// kept within [secant/3, 3·secant]; then Fritsch & Carlson's limit (α² + β² ≤ 9 on
    /// every interval) so the cubic stays increasing.
    fn table(h: Vec<f64>, real: Vec<f64>) -> Self {
        let n = h.len();
        let step: Vec<f64> = (0..n - 1).map(|i| h[i + 1] - h[i]).collect();
        let secant: Vec<f64> = (0..n - 1)
            .map(|i| (real[i + 1] - real[i]) / step[i])
            .collect();
        let mut slope = vec![0.0; n];
        slope[0] = secant[0];
        slope[n - 1] = secant[n - 2];
        if n > 2 {
            let (a, b) = (step[n - 2], step[n - 3]);
            let (sa, sb) = (secant[n - 2], secant[n - 3]);
            let end = ((2.0 * a + b) * sa - a * sb) / (a + b);
            slope[n - 1] = end.clamp(sa / 3.0, 3.0 * sa);
        }
        for i in 1..n - 1 {
            let (w1, w2) = (2.0 * step[i] + step[i - 1], step[i] + 2.0 * step[i - 1]);
            slope[i] = (w1 + w2) / (w1 / secant[i - 1] + w2 / secant[i]);
        }
        for i in 0..n - 1 {
            let (alpha, beta) = (slope[i] / secant[i], slope[i + 1] / secant[i]);
            let norm = alpha.hypot(beta);
            if norm > 3.0 {
                slope[i] = 3.0 * alpha / norm * secant[i];
                slope[i + 1] = 3.0 * beta / norm * secant[i];
            }
        }
        DistortionLaw::Table { h, real, slope }
    }

    /// The real height and dH_real/dH at paraxial height `x`.
    fn eval(&self, x: f64) -> (f64, f64) {
        match self {
            DistortionLaw::Polynomial { k1, k2 } => {
                let x2 = x * x;
                (
                    x * (1.0 + k1 * x2 + k2 * x2 * x2),
                    1.0 + 3.0 * k1 * x2 + 5.0 * k2 * x2 * x2,
                )
            }
            DistortionLaw::Table { h, real, slope } => {
                let n = h.len();
                if x >= h[n - 1] {
                    return (real[n - 1] + slope[n - 1] * (x - h[n - 1]), slope[n - 1]);
                }
                let i = h.partition_point(|v| *v <= x).clamp(1, n - 1) - 1;
                let d = h[i + 1] - h[i];
                let t = (x - h[i]) / d;
                let (t2, t3) = (t * t, t * t * t);
                let value = real[i] * (2.0 * t3 - 3.0 * t2 + 1.0)
                    + d * slope[i] * (t3 - 2.0 * t2 + t)
                    + real[i + 1] * (-2.0 * t3 + 3.0 * t2)
                    + d * slope[i + 1] * (t3 - t2);
                let derivative = (real[i] * (6.0 * t2 - 6.0 * t)
                    + d * slope[i] * (3.0 * t2 - 4.0 * t + 1.0)
                    + real[i + 1] * (-6.0 * t2 + 6.0 * t)
                    + d * slope[i + 1] * (3.0 * t2 - 2.0 * t))
                    / d;
                (value, derivative)
            }
        }
    }

    /// `H_real / H` at paraxial height `h` (dH_real/dH at 0).
    pub fn ratio(&self, h: f64) -> f64 {
        if h > 0.0 {
            self.real(h) / h
        } else {
            self.slope(0.0)
        }
    }

    /// `dH_real / dH` at paraxial height `h`.
    pub fn slope(&self, h: f64) -> f64 {
        self.eval(h).1
    }

    /// The real height of paraxial height `h`.
    pub fn real(&self, h: f64) -> f64 {
        self.eval(h).0
    }

    /// The area ratio of the mapping (real image area per paraxial image area) at paraxial
    /// height `h`: the Jacobian determinant of a radial map, `(H_real/H)·(dH_real/dH)`.
    pub fn jacobian(&self, h: f64) -> f64 {
        self.ratio(h) * self.slope(h)
    }

    /// The paraxial height whose real height is `h_real` (Newton's method from
    /// `h_real`, bisection-guarded; the law is increasing on [0,
    /// [`DISTORTION_CHECKED_H`]]). `None` when `h_real` lies beyond the checked range.
    pub fn paraxial(&self, h_real: f64) -> Option<f64> {
        if h_real > self.real(DISTORTION_CHECKED_H) {
            return None;
        }
        let (mut lo, mut hi) = (0.0, DISTORTION_CHECKED_H);
        let mut h = h_real.clamp(lo, hi);
        for _ in 0..100 {
            let (v, d) = self.eval(h);
            if v > h_real {
                hi = h;
            } else {
                lo = h;
            }
            let mut next = h - (v - h_real) / d;
            if !(next > lo && next < hi) {
                next = 0.5 * (lo + hi);
            }
            let done = (next - h).abs() <= 1e-15 * (1.0 + h);
            h = next;
            if done {
                break;
            }
        }
        Some(h)
    }

    /// Checks that the law increases (a positive slope) on paraxial heights [0,
    /// [`DISTORTION_CHECKED_H`]], so that the mapping is one to one; `what` names it.
    fn check_increasing(&self, what: &str, value: String) -> Result<()> {
        let steps = 2000;
        for i in 0..=steps {
            let h = DISTORTION_CHECKED_H * i as f64 / steps as f64;
            if self.slope(h) <= 0.0 {
                return Err(Error::param(
                    what,
                    value,
                    format!(
                        "a law that increases up to H = {DISTORTION_CHECKED_H} (it turns back at H = {h:.3})"
                    ),
                ));
            }
        }
        Ok(())
    }
}

impl DistortionConfig {
    /// The table's two height lists and whether they are in mm, `None` without a table.
    /// Errors: a list without its partner, both the normalised and the mm table, or a table
    /// beside non-zero k1, k2.
    fn table(&self) -> Result<Option<HeightTable<'_>>> {
        const T: &str = "optics.distortion";
        let table = match (
            &self.paraxial_heights,
            &self.real_heights,
            &self.paraxial_heights_mm,
            &self.real_heights_mm,
        ) {
            (None, None, None, None) => return Ok(None),
            (Some(p), Some(r), None, None) => (p.as_slice(), r.as_slice(), false),
            (None, None, Some(p), Some(r)) => (p.as_slice(), r.as_slice(), true),
            _ => {
                return Err(Error::param(
                    T,
                    "an incomplete or doubled height table",
                    "either paraxial_heights with real_heights (normalised, 1 = the array's corner) or paraxial_heights_mm with real_heights_mm",
                ))
            }
        };
        if self.k1 != 0.0 || self.k2 != 0.0 {
            return Err(Error::param(
                format!("{T} (k1, k2)"),
                format!("({}, {}) beside a height table", self.k1, self.k2),
                "either the coefficients k1, k2 or a height table, not both",
            ));
        }
        Ok(Some(table))
    }

    /// The law on normalised heights, `corner_height_m` the array's corner height (it
    /// converts a table in mm). Errors as [`DistortionConfig::validate`].
    pub fn law(&self, corner_height_m: f64) -> Result<DistortionLaw> {
        const T: &str = "optics.distortion";
        for (name, v) in [("k1", self.k1), ("k2", self.k2)] {
            if !v.is_finite() || v.abs() > 10.0 {
                return Err(Error::param(
                    format!("{T}.{name}"),
                    v,
                    "a finite number in [-10, 10]",
                ));
            }
        }
        let Some((paraxial, real, mm)) = self.table()? else {
            let law = DistortionLaw::Polynomial {
                k1: self.k1,
                k2: self.k2,
            };
            law.check_increasing(
                "optics.distortion (k1, k2)",
                format!("({}, {})", self.k1, self.k2),
            )?;
            return Ok(law);
        };
        let (pn, rn) = if mm {
            ("paraxial_heights_mm", "real_heights_mm")
        } else {
            ("paraxial_heights", "real_heights")
        };
        if paraxial.len() != real.len() || paraxial.len() < 2 {
            return Err(Error::param(
                format!("{T}.{pn} / {rn}"),
                format!("{} and {} heights", paraxial.len(), real.len()),
                "as many real as paraxial heights, at least 2",
            ));
        }
        for (name, list) in [(pn, paraxial), (rn, real)] {
            for (i, v) in list.iter().enumerate() {
                let ok = if i == 0 {
                    *v == 0.0
                } else {
                    v.is_finite() && *v > list[i - 1]
                };
                if !ok {
                    return Err(Error::param(
                        format!("{T}.{name}[{i}]"),
                        v,
                        if i == 0 {
                            "0 (the table starts on the axis)"
                        } else {
                            "finite and larger than the height before it (the law must be one to one)"
                        },
                    ));
                }
            }
        }
        let scale = if mm {
            if !(corner_height_m.is_finite() && corner_height_m > 0.0) {
                return Err(Error::param(
                    "corner height",
                    corner_height_m,
                    "a finite value > 0",
                ));
            }
            1e-3 / corner_height_m
        } else {
            1.0
        };
        let law = DistortionLaw::table(
            paraxial.iter().map(|v| v * scale).collect(),
            real.iter().map(|v| v * scale).collect(),
        );
        law.check_increasing(&format!("{T}.{rn}"), format!("{real:?}"))?;
        Ok(law)
    }

    /// Checks the law: coefficients finite and in [-10, 10], or a table whose lists pair
    /// up, start at 0 and increase; the law increasing (a positive slope) on paraxial
    /// heights [0, [`DISTORTION_CHECKED_H`]], so that the mapping is one to one. (The
    /// corner height only scales a table in mm, which changes neither check.)
    pub fn validate(&self) -> Result<()> {
        self.law(1.0).map(|_| ())
    }

    /// True when the law is the identity (k1 = k2 = 0, no table): the run then skips the
    /// resampling.
    pub fn is_identity(&self) -> bool {
        self.k1 == 0.0
            && self.k2 == 0.0
            && self.paraxial_heights.is_none()
            && self.real_heights.is_none()
            && self.paraxial_heights_mm.is_none()
            && self.real_heights_mm.is_none()
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
            ..DistortionConfig::default()
        };
        d.validate().unwrap();
        let d = d.law(1.0).unwrap();
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
        let folds = DistortionConfig {
            k1: -0.3,
            ..DistortionConfig::default()
        };
        assert!(folds
            .validate()
            .unwrap_err()
            .to_string()
            .contains("turns back"));
    }

    /// The table form: a table sampled from a k1, k2 law every 0.1 in H reproduces that
    /// law (within 5e-4 in H_real and 2e-2 in the Jacobian up to H = 2, where the law
    /// bends most; 3e-3 in the Jacobian up to H = 1.2: the interpolant's slopes are
    /// estimated from the table's secants), inverts to 1e-12, converts mm by the corner
    /// height, and bad tables are refused with the field and index named.
    #[test]
    fn a_height_table_is_the_law_it_samples_and_bad_tables_are_refused() {
        let poly = DistortionConfig {
            k1: -0.06,
            k2: 0.02,
            ..DistortionConfig::default()
        }
        .law(1.0)
        .unwrap();
        let h: Vec<f64> = (0..=20).map(|i| i as f64 * 0.1).collect();
        let real: Vec<f64> = h.iter().map(|v| poly.real(*v)).collect();
        let table = DistortionConfig {
            paraxial_heights: Some(h.clone()),
            real_heights: Some(real.clone()),
            ..DistortionConfig::default()
        };
        assert!(!table.is_identity());
        let law = table.law(1.0).unwrap();
        let (mut dv, mut dj, mut dj_inner): (f64, f64, f64) = (0.0, 0.0, 0.0);
        for i in 0..=400 {
            let x = i as f64 * 0.005;
            dv = dv.max((law.real(x) - poly.real(x)).abs());
            let e = (law.jacobian(x) - poly.jacobian(x)).abs();
            dj = dj.max(e);
            if x <= 1.2 {
                dj_inner = dj_inner.max(e);
            }
            let back = law.paraxial(law.real(x)).unwrap();
            assert!((back - x).abs() < 1e-12, "{x} {back}");
        }
        println!("table vs k1, k2: H_real {dv:.2e}, J {dj:.2e} (to H = 1.2: {dj_inner:.2e})");
        assert!(
            dv < 5e-4 && dj < 2e-2 && dj_inner < 3e-3,
            "{dv} {dj} {dj_inner}"
        );
        // In mm with a 0.5 mm corner: the same law.
        let mm = DistortionConfig {
            paraxial_heights_mm: Some(h.iter().map(|v| v * 0.5).collect()),
            real_heights_mm: Some(real.iter().map(|v| v * 0.5).collect()),
            ..DistortionConfig::default()
        }
        .law(0.5e-3)
        .unwrap();
        assert!((mm.real(0.73) - law.real(0.73)).abs() < 1e-12);
        let bad = [
            (
                Some(vec![0.0, 0.5, 1.0]),
                Some(vec![0.0, 0.6, 0.55]),
                None,
                "real_heights[2]",
            ),
            (
                Some(vec![0.1, 0.5]),
                Some(vec![0.0, 0.5]),
                None,
                "paraxial_heights[0]",
            ),
            (
                Some(vec![0.0, 0.5, 1.0]),
                Some(vec![0.0, 0.5]),
                None,
                "real_heights",
            ),
            (Some(vec![0.0, 1.0]), None, None, "paraxial_heights_mm"),
            (Some(vec![0.0, 1.0]), Some(vec![0.0, 0.9]), Some(0.1), "k1"),
        ];
        for (p, r, k1, needle) in bad {
            let c = DistortionConfig {
                paraxial_heights: p,
                real_heights: r,
                k1: k1.unwrap_or(0.0),
                ..DistortionConfig::default()
            };
            let e = c.validate().unwrap_err().to_string();
            assert!(e.contains(needle), "{needle}: {e}");
        }
    }
}
