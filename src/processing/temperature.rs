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

/// A smooth, increasing function of temperature (a blackbody band response: electrons,
/// in-band radiance) tabulated with its exact derivative and evaluated by cubic Hermite
/// interpolation in the reciprocal temperature u = 1/T.
///
/// Why 1/T: a Planck band response behaves like `f ∝ e^{−c u}` with c = hc/(λk) (Wien), so
/// in u every derivative scales as `cⁿ f` uniformly over the range and equal steps in u
/// give equal relative accuracy from 150 K to 1000 K. On a node interval of width Δu the
/// cubic Hermite remainder is at most `Δu⁴/384 · max|f⁗|` (e.g. Burden & Faires,
/// *Numerical Analysis*, Thm 3.9), i.e. a relative error of about `(c Δu)⁴/384`. Callers
/// choose Δu from the shortest wavelength of the response (c largest there): c Δu = 0.05
/// gives ≤ 1.6e-8 relative, a temperature error `1.6e-8 · T²/c` below 10 µK up to 1000 K.
/// Evaluating it
/// costs a few multiplications instead of an adaptive band integral, which is what makes
/// per-pixel Newton polishing of apparent temperatures cheap.
#[derive(Debug, Clone, PartialEq)]
pub struct HermiteTable {
    u0: f64,
    step_u: f64,
    value: Vec<f64>,
    /// df/du at each node.
    derivative: Vec<f64>,
}

impl HermiteTable {
    /// Tabulates `value_and_derivative(T) = (f(T), df/dT)` (evaluated in parallel) on
    /// `[t_min_k, t_max_k]` at nodes equally spaced in 1/T, at most `step_inv_k` (K⁻¹)
    /// apart.
    ///
    /// Errors: a range that is not finite, positive and increasing, a step that is not
    /// finite and > 0, more than 1 000 000 nodes, or a non-finite value or derivative
    /// (naming the temperature).
    pub fn new(
        value_and_derivative: impl Fn(f64) -> (f64, f64) + Sync,
        t_min_k: f64,
        t_max_k: f64,
        step_inv_k: f64,
    ) -> Result<Self> {
        use rayon::prelude::*;
        crate::error::require_positive("t_min_k", t_min_k)?;
        crate::error::require_positive("step_inv_k", step_inv_k)?;
        if !(t_max_k.is_finite() && t_max_k > t_min_k) {
            return Err(Error::param(
                "t_max_k",
                t_max_k,
                format!("a finite temperature in K greater than t_min_k = {t_min_k}"),
            ));
        }
        let (u0, u1) = (1.0 / t_max_k, 1.0 / t_min_k);
        let intervals = ((u1 - u0) / step_inv_k).ceil().max(1.0);
        if intervals > 1e6 {
            return Err(Error::param(
                "step_inv_k",
                step_inv_k,
                "a step giving at most 1 000 000 table intervals",
            ));
        }
        let n = intervals as usize + 1;
        let step_u = (u1 - u0) / intervals;
        let node_t = |i: usize| {
            if i == 0 {
                t_max_k
            } else if i == n - 1 {
                t_min_k
            } else {
                1.0 / (u0 + step_u * i as f64)
            }
        };
        let pairs: Vec<(f64, f64)> = (0..n)
            .into_par_iter()
            .map(|i| {
                let t = node_t(i);
                let (f, df_dt) = value_and_derivative(t);
                // du = −dT/T²  ⇒  df/du = −T² df/dT.
                (f, -t * t * df_dt)
            })
            .collect();
        if let Some((i, p)) = pairs
            .iter()
            .enumerate()
            .find(|(_, p)| !(p.0.is_finite() && p.1.is_finite()))
        {
            return Err(Error::OutOfRange(format!(
                "response table: value {} and derivative {} at T = {} K; both must be finite on [{t_min_k}, {t_max_k}] K",
                p.0,
                p.1,
                node_t(i)
            )));
        }
        let (value, derivative) = pairs.into_iter().unzip();
        Ok(HermiteTable {
            u0,
            step_u,
            value,
            derivative,
        })
    }

    /// The tabulated range `(t_min_k, t_max_k)`.
    pub fn range_k(&self) -> (f64, f64) {
        (
            1.0 / (self.u0 + self.step_u * (self.value.len() - 1) as f64),
            1.0 / self.u0,
        )
    }

    /// Number of nodes.
    pub fn nodes(&self) -> usize {
        self.value.len()
    }

    /// The interpolated value at `t_k`, `None` outside the table (or for NaN).
    pub fn eval(&self, t_k: f64) -> Option<f64> {
        self.eval_inverse(1.0 / t_k)
    }

    /// The interpolated value at the reciprocal temperature `u_per_k` = 1/T (K⁻¹), the
    /// table's own coordinate: [`HermiteTable::eval`] without its division. `None` outside
    /// the table (or for NaN).
    #[inline]
    pub fn eval_inverse(&self, u_per_k: f64) -> Option<f64> {
        let s_all = (u_per_k - self.u0) / self.step_u;
        let last = self.value.len() - 1;
        // A tolerance of a few ulps keeps the end nodes inside despite the 1/T rounding.
        if !(s_all >= -1e-9 && s_all <= last as f64 + 1e-9) {
            return None;
        }
        let s_all = s_all.clamp(0.0, last as f64);
        // s_all ≥ 0 here, so the truncating cast is floor() (without a libm call on CPUs
        // the baseline target gives no rounding instruction).
        let i = (s_all as usize).min(last - 1);
        let s = s_all - i as f64;
        let h = self.step_u;
        let (y0, y1) = (self.value[i], self.value[i + 1]);
        let (d0, d1) = (self.derivative[i] * h, self.derivative[i + 1] * h);
        // Cubic Hermite basis on [0, 1].
        let s2 = s * s;
        let s3 = s2 * s;
        Some(
            (2.0 * s3 - 3.0 * s2 + 1.0) * y0
                + (s3 - 2.0 * s2 + s) * d0
                + (-2.0 * s3 + 3.0 * s2) * y1
                + (s3 - s2) * d1,
        )
    }
}

/// Fast inverse of a [`TemperatureLut`] for whole images: the reciprocal temperature
/// u = 1/T tabulated against the log-signal `w = ln(v − v_floor)` on equal steps and
/// interpolated by 4-point Lagrange cubics, each table interval checked against the exact
/// inversion ([`TemperatureLut::temperature`]). Each interval's cubic is stored as four
/// coefficients of powers of the interval fraction, so a lookup evaluates it by Horner's
/// rule (no divisions); the image conversion stays in 1/T ([`InverseTable::lookup`]) for
/// the radiance table, which is in 1/T too ([`HermiteTable::eval_inverse`]).
///
/// Why these coordinates: a blackbody band response above its zero-signal level
/// `v_floor` behaves like `v − v_floor ∝ e^{−c u}` (Wien, c = hc/(λk)), so u is nearly
/// linear in w over the whole table and a cubic in w is accurate to a small fraction of a
/// millikelvin with a few hundred nodes; the lookup is O(1) (no search), one logarithm and
/// a cubic per pixel, instead of a binary search and a Newton polish on the response.
///
/// Accuracy: the error of the cubic on an interval peaks near its midpoint (the node
/// polynomial `(s+1)s(s−1)(s−2)`); at construction every interval's midpoint is inverted
/// exactly and compared. The table starts at [`INVERSE_MIN_INTERVALS`] intervals and is
/// doubled (up to [`INVERSE_MAX_INTERVALS`]) until every midpoint is within
/// `tolerance_k`; intervals still outside it are flagged and their pixels use the exact
/// inversion, so the result is everywhere within about `tolerance_k` of
/// [`TemperatureLut::temperature`] (tested ≤ 1e-6 K over dense sweeps).
#[derive(Debug, Clone, PartialEq)]
pub struct InverseTable {
    floor: f64,
    value_range: (f64, f64),
    w0: f64,
    inv_step_w: f64,
    /// Per interval, the coefficients `[c0, c1, c2, c3]` of its cubic in the interval
    /// fraction s (`c0 + s(c1 + s(c2 + s c3))`, [`cubic_coefficients`]).
    coef: Vec<[f64; 4]>,
    /// Intervals inverted exactly (the cubic missed the tolerance there).
    exact: Vec<bool>,
}

/// Intervals of the first [`InverseTable`] (doubled as needed).
pub const INVERSE_MIN_INTERVALS: usize = 256;

/// Most intervals of an [`InverseTable`].
pub const INVERSE_MAX_INTERVALS: usize = 8192;

impl InverseTable {
    /// The inverse of `lut` in the log-signal coordinate `ln(v − floor)`, `floor` the
    /// response's zero-signal level (a floor at or above the table's smallest value is
    /// replaced by one table span below it), each interval within `tolerance_k` of the
    /// exact inversion or flagged (type documentation).
    ///
    /// Errors: a tolerance that is not finite and > 0, or an exact inversion that fails
    /// inside the table's range (naming the value).
    pub fn new(lut: &TemperatureLut, floor: f64, tolerance_k: f64) -> Result<Self> {
        use rayon::prelude::*;
        crate::error::require_positive("tolerance_k", tolerance_k)?;
        let (v_lo, v_hi) = lut.value_range();
        let floor = if floor.is_finite() && floor < v_lo {
            floor
        } else {
            v_lo - (v_hi - v_lo)
        };
        let (w0, w1) = ((v_lo - floor).ln(), (v_hi - floor).ln());
        let mut intervals = INVERSE_MIN_INTERVALS;
        loop {
            let step = (w1 - w0) / intervals as f64;
            // Node and midpoint values; the end nodes are the table's own end values.
            let value_at = |k2: usize| -> f64 {
                if k2 == 0 {
                    v_lo
                } else if k2 == 2 * intervals {
                    v_hi
                } else {
                    (floor + (w0 + 0.5 * step * k2 as f64).exp()).clamp(v_lo, v_hi)
                }
            };
            let t: Vec<f64> = (0..=2 * intervals)
                .into_par_iter()
                .map(|k2| lut.temperature(value_at(k2)))
                .collect::<Result<_>>()?;
            let u: Vec<f64> = t.iter().step_by(2).map(|t| 1.0 / t).collect();
            let coef = (0..intervals).map(|i| cubic_coefficients(&u, i)).collect();
            let mut table = InverseTable {
                floor,
                value_range: (v_lo, v_hi),
                w0,
                inv_step_w: 1.0 / step,
                coef,
                exact: vec![false; intervals],
            };
            let mut missed = 0;
            for i in 0..intervals {
                let t_exact = t[2 * i + 1];
                let t_cubic = 1.0 / table.cubic(i, 0.5);
                let within = (t_cubic - t_exact).abs() <= tolerance_k;
                if !within {
                    table.exact[i] = true;
                    missed += 1;
                }
            }
            if missed == 0 || intervals >= INVERSE_MAX_INTERVALS {
                return Ok(table);
            }
            intervals *= 2;
        }
    }

    /// Number of table intervals.
    pub fn intervals(&self) -> usize {
        self.exact.len()
    }

    /// Number of intervals inverted exactly (where the cubic missed the tolerance).
    pub fn exact_intervals(&self) -> usize {
        self.exact.iter().filter(|&&e| e).count()
    }

    /// 1/T by the cubic of interval `i` at fraction `s` ∈ [0, 1] of the interval.
    #[inline]
    fn cubic(&self, i: usize, s: f64) -> f64 {
        let [c0, c1, c2, c3] = self.coef[i];
        c0 + s * (c1 + s * (c2 + s * c3))
    }

    /// The temperature whose response is `value` (K), NaN for NaN or values outside the
    /// table's value range — the same values as `lut.temperature_or_nan(value)` to within
    /// the tolerance of the construction. `lut` must be the table this inverse was built
    /// from (it serves the flagged intervals).
    pub fn temperature_or_nan(&self, lut: &TemperatureLut, value: f64) -> f64 {
        match self.lookup(value) {
            InverseLookup::Outside => f64::NAN,
            InverseLookup::Exact => lut.temperature_or_nan(value),
            InverseLookup::Cubic(u) => 1.0 / u,
        }
    }

    /// Where `value` falls: outside the table (or NaN), in an interval inverted exactly,
    /// or 1/T (K⁻¹) from the interval's cubic — for callers that go on in 1/T
    /// ([`HermiteTable::eval_inverse`]) and so skip [`InverseTable::temperature_or_nan`]'s
    /// division.
    #[inline]
    pub fn lookup(&self, value: f64) -> InverseLookup {
        let (v_lo, v_hi) = self.value_range;
        if !(value >= v_lo && value <= v_hi) {
            return InverseLookup::Outside;
        }
        let n = self.exact.len();
        let pos = (((value - self.floor).ln() - self.w0) * self.inv_step_w).clamp(0.0, n as f64);
        let i = (pos as usize).min(n - 1);
        if self.exact[i] {
            return InverseLookup::Exact;
        }
        InverseLookup::Cubic(self.cubic(i, pos - i as f64))
    }
}

/// Where a value falls in an [`InverseTable`] ([`InverseTable::lookup`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InverseLookup {
    /// Outside the table's value range, or NaN: no temperature.
    Outside,
    /// In an interval the cubic missed the tolerance on: invert it exactly
    /// ([`TemperatureLut::temperature_or_nan`]).
    Exact,
    /// 1/T (K⁻¹) from the interval's cubic.
    Cubic(f64),
}

/// The cubic through the four nodes `u[j0 .. j0 + 4]` around interval `i` (one-sided at the
/// table's ends, `j0 = min(max(i − 1, 0), n − 3)`), as coefficients of powers of the
/// fraction s ∈ [0, 1] of interval i: Newton's forward differences of the nodes give the
/// polynomial in x = s + (i − j0), `u0 + Δ¹x + Δ²x(x−1)/2 + Δ³x(x−1)(x−2)/6`, whose powers
/// of x are then shifted to powers of s (Taylor shift by i − j0). The same cubic as the
/// 4-point Lagrange form, to rounding (tested).
fn cubic_coefficients(u: &[f64], i: usize) -> [f64; 4] {
    let n = u.len() - 1;
    let j0 = i.saturating_sub(1).min(n - 3);
    let (y0, y1, y2, y3) = (u[j0], u[j0 + 1], u[j0 + 2], u[j0 + 3]);
    let d1 = y1 - y0;
    let d2 = y2 - 2.0 * y1 + y0;
    let d3 = y3 - 3.0 * y2 + 3.0 * y1 - y0;
    // In powers of x: x(x−1)/2 = (x² − x)/2, x(x−1)(x−2)/6 = (x³ − 3x² + 2x)/6.
    let a = [y0, d1 - d2 / 2.0 + d3 / 3.0, d2 / 2.0 - d3 / 2.0, d3 / 6.0];
    // p(s + d) in powers of s.
    let d = (i - j0) as f64;
    [
        a[0] + d * (a[1] + d * (a[2] + d * a[3])),
        a[1] + d * (2.0 * a[2] + 3.0 * d * a[3]),
        a[2] + 3.0 * d * a[3],
        a[3],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 4-point Lagrange form of the cubic through `u[j0 .. j0 + 4]` at x (nodes at
    /// x = 0, 1, 2, 3), the definition `cubic_coefficients` is expanded from.
    fn lagrange(u: &[f64], j0: usize, x: f64) -> f64 {
        let (a, b, c, d) = (x, x - 1.0, x - 2.0, x - 3.0);
        let u = &u[j0..j0 + 4];
        -u[0] * b * c * d / 6.0 + u[1] * a * c * d / 2.0 - u[2] * a * b * d / 2.0
            + u[3] * a * b * c / 6.0
    }

    /// The power-series coefficients give the Lagrange cubic of every interval (interior,
    /// first and last: one-sided stencils) to within a few ulp, and pass through the
    /// interval's end nodes: on a table-like smooth sequence (1/T at equal steps of a
    /// log-signal) and on an irregular one.
    #[test]
    fn cubic_coefficients_are_the_lagrange_cubic() {
        let smooth: Vec<f64> = (0..=40)
            .map(|k| 1.0 / (200.0 + 20.0 * k as f64 + 0.3 * (k * k) as f64))
            .collect();
        let irregular: Vec<f64> = (0..=12)
            .map(|k| ((k * 7919) % 13) as f64 * 0.37 - 1.1 + 0.05 * k as f64)
            .collect();
        for u in [smooth, irregular] {
            let n = u.len() - 1;
            let scale = u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for i in 0..n {
                let c = cubic_coefficients(&u, i);
                let j0 = i.saturating_sub(1).min(n - 3);
                for s in [0.0, 0.125, 0.25, 0.5, 0.75, 0.9, 1.0] {
                    let horner = c[0] + s * (c[1] + s * (c[2] + s * c[3]));
                    let want = lagrange(&u, j0, s + (i - j0) as f64);
                    assert!(
                        (horner - want).abs() <= 1e-14 * scale,
                        "interval {i}, s {s}: {horner} vs {want}"
                    );
                }
                let at = |s: f64| c[0] + s * (c[1] + s * (c[2] + s * c[3]));
                assert!((at(0.0) - u[i]).abs() <= 1e-15 * scale);
                assert!((at(1.0) - u[i + 1]).abs() <= 1e-14 * scale);
            }
        }
    }
}
