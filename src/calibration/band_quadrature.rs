//! One spectral quadrature shared by every blackbody band integral of a calibration
//! (issue 9: the response tables from one Planck evaluation per wavelength node).
//!
//! The calibration tabulates, over a temperature range `[T_min, T_max]`, four band
//! integrals of the sensor's spectral response S(λ) (docs/design.md §4.1, §4.9):
//!
//! - the band **photon** radiance `Q(T) = ∫ S L_q dλ` (times the camera's étendue·time it
//!   is the signal electrons) and `dQ/dT`;
//! - the band **energy** radiance `R(T) = ∫ S L_λ dλ` (the in-band radiance before the
//!   division by max S) and `dR/dT`;
//!
//! with Planck's law `L_λ = c1L λ⁻⁵ / (eˣ − 1)`, `L_q = L_λ λ/(hc)`, `x = c2/(λT)`, and
//! `∂L/∂T = L · x/(T (1 − e⁻ˣ))` for both forms (differentiate `1/(eˣ − 1)` with
//! `dx/dT = −x/T`).
//!
//! The four integrands are one family: S(λ) times smooth functions of λ whose steepness in λ
//! grows with x, i.e. is largest at `T_min` and smallest at `T_max`. A single composite
//! rule therefore serves every temperature of the range: the nodes λ_k and weights w_k of
//! 8-point Gauss–Legendre rules (Abramowitz & Stegun 25.4.29; nodes by Newton's method on
//! the Legendre recurrence) on sub-intervals of the support of S, split at its
//! breakpoints (where S has kinks or jumps) and halved until, for each of the eight
//! *probe* integrands (the four at `T_min` and at `T_max`), the 8-point value on a
//! sub-interval and the sum of the 8-point values on its two halves agree to
//! [`SUBINTERVAL_REL_TOL`] of the probe's whole-band integral. The halves are ~2¹⁶ times
//! more accurate than the whole (error ∝ h¹⁶), so that difference is the error of the
//! accepted sub-interval; summed over the (tens of) sub-intervals the relative error of
//! every integral is ≲ 1e-10 (tested against the adaptive Gauss–Kronrod integrals of
//! [`crate::radiometry`] from 150 K to 1000 K).
//!
//! Per temperature, [`BandQuadrature::eval`] then costs one `expm1` per node for all four
//! integrals, instead of four adaptive integrations (about 30× fewer Planck evaluations).

use crate::constants::{BOLTZMANN_K, PLANCK_H, SPEED_OF_LIGHT_C};
use crate::error::{require_positive, Error, Result};
use crate::radiometry::integrate;
use crate::spectrum::Spectrum;

/// First radiation constant for radiance, c1L = 2hc², W m² sr-1.
const C1L: f64 = 2.0 * PLANCK_H * SPEED_OF_LIGHT_C * SPEED_OF_LIGHT_C;

/// Second radiation constant c2 = hc/k, m K (exact with the 2019 SI constants).
pub const C2_M_K: f64 = PLANCK_H * SPEED_OF_LIGHT_C / BOLTZMANN_K;

/// Points of each Gauss–Legendre rule (exact for polynomials of degree 15).
const GAUSS_POINTS: usize = 8;

/// Largest accepted difference between a sub-interval's rule and the sum over its halves,
/// relative to the probe's whole-band integral.
pub const SUBINTERVAL_REL_TOL: f64 = 1e-12;

/// Relative tolerance of the adaptive reference integrals that set the scale of each probe.
const REFERENCE_REL_TOL: f64 = 1e-10;

/// Most halvings of one breakpoint interval (2⁻⁴⁰ of it is far below any response detail).
const MAX_DEPTH: u32 = 40;

/// Most sub-intervals of the rule.
const MAX_SUBINTERVALS: usize = 100_000;

/// The four band integrals at one temperature (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BandIntegrals {
    /// `∫ S L_q dλ`, photons s-1 m-2 sr-1 (S dimensionless).
    pub photon: f64,
    /// `d/dT ∫ S L_q dλ`, photons s-1 m-2 sr-1 K-1.
    pub photon_per_k: f64,
    /// `∫ S L_λ dλ`, W m-2 sr-1.
    pub energy: f64,
    /// `d/dT ∫ S L_λ dλ`, W m-2 sr-1 K-1.
    pub energy_per_k: f64,
}

/// The composite Gauss–Legendre rule of a spectral response (module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct BandQuadrature {
    /// Node wavelengths, m.
    lambda_m: Vec<f64>,
    /// `w_k S(λ_k) c1L λ_k⁻⁵ · 1e-6` (W m-2 sr-1 per unit `1/(eˣ − 1)`: the per-µm radiance
    /// times the node weight in µm).
    energy_weight: Vec<f64>,
    /// `energy_weight · λ_k/(hc)` (photons instead of joules).
    photon_weight: Vec<f64>,
}

/// Nodes and weights of the `n`-point Gauss–Legendre rule on [−1, 1]: the roots of P_n by
/// Newton's method from Tricomi's approximation `cos(π(i + 3/4)/(n + 1/2))`, weights
/// `2/((1 − x²) P_n'(x)²)` (Abramowitz & Stegun 25.4.29).
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut nodes = Vec::with_capacity(n);
    let mut weights = Vec::with_capacity(n);
    for i in 0..n {
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            // P_n(x) and P_{n−1}(x) by the three-term recurrence.
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            let (pn, pn1) = if n == 0 { (1.0, 0.0) } else { (p1, p0) };
            dp = n as f64 * (x * pn - pn1) / (x * x - 1.0);
            let dx = pn / dp;
            x -= dx;
            if dx.abs() <= 1e-16 {
                break;
            }
        }
        nodes.push(x);
        weights.push(2.0 / ((1.0 - x * x) * dp * dp));
    }
    (nodes, weights)
}

/// `1/(eˣ − 1)` and the relative temperature derivative factor `x (1 + 1/(eˣ − 1))`
/// (= `T ∂ln L/∂T`); both 0 where eˣ overflows (the radiance is then below 1e-300 of any
/// band's).
fn planck_factors(x: f64) -> (f64, f64) {
    let p = 1.0 / x.exp_m1();
    if p.is_finite() {
        (p, x * (1.0 + p))
    } else {
        (0.0, 0.0)
    }
}

/// The eight probe integrands at wavelength `w_um` (module documentation): photon and
/// energy forms, each with and without the T-derivative factor, at `t_min` and `t_max`.
fn probes(s: &Spectrum, w_um: f64, (t_min, t_max): (f64, f64)) -> [f64; 8] {
    let sw = s.eval(w_um);
    if sw == 0.0 {
        return [0.0; 8];
    }
    let lambda_m = w_um * 1e-6;
    let energy = sw * C1L / lambda_m.powi(5) * 1e-6;
    let photon = energy * lambda_m / (PLANCK_H * SPEED_OF_LIGHT_C);
    let mut out = [0.0; 8];
    for (i, t) in [t_min, t_max].into_iter().enumerate() {
        let (p, d) = planck_factors(C2_M_K / (lambda_m * t));
        out[4 * i] = photon * p;
        out[4 * i + 1] = photon * p * d / t;
        out[4 * i + 2] = energy * p;
        out[4 * i + 3] = energy * p * d / t;
    }
    out
}

/// The 8-point rule of the probes on `[a, b]`.
fn probe_rule(s: &Spectrum, a: f64, b: f64, t: (f64, f64), x: &[f64], w: &[f64]) -> [f64; 8] {
    let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
    let mut sum = [0.0; 8];
    for (xi, wi) in x.iter().zip(w) {
        let f = probes(s, c + h * xi, t);
        for (acc, v) in sum.iter_mut().zip(f) {
            *acc += wi * h * v;
        }
    }
    sum
}

impl BandQuadrature {
    /// The rule for `response` on its support, valid for temperatures in `t_range_k`.
    ///
    /// Errors: a response without bounded support, an invalid temperature range, a
    /// non-finite integrand, or a rule that does not converge within 40 halvings
    /// (naming the wavelength interval).
    pub fn new(response: &Spectrum, t_range_k: (f64, f64)) -> Result<Self> {
        let (t_min, t_max) = t_range_k;
        require_positive("t_min_k", t_min)?;
        if !(t_max.is_finite() && t_max >= t_min) {
            return Err(Error::param(
                "t_max_k",
                t_max,
                format!("a finite temperature in K at or above t_min_k = {t_min}"),
            ));
        }
        let (lo, hi) = response.support_um();
        let lo = lo.max(0.0);
        if !(hi.is_finite() && hi > lo) {
            return Err(Error::param(
                "spectral response",
                format!("support [{lo}, {hi}] µm"),
                "a response with a bounded band",
            ));
        }
        let breakpoints = response.breakpoints_um();
        // Scale of each probe: its whole-band integral by the adaptive integrator.
        let mut scale = [0.0; 8];
        for (p, sc) in scale.iter_mut().enumerate() {
            *sc = integrate(
                |w| probes(response, w, t_range_k)[p],
                lo,
                hi,
                &breakpoints,
                REFERENCE_REL_TOL,
            )
            .abs();
        }
        if scale.iter().any(|v| !v.is_finite()) {
            return Err(Error::OutOfRange(format!(
                "band quadrature: a blackbody band integral over [{lo}, {hi}] µm is not finite"
            )));
        }
        let (x, w) = gauss_legendre(GAUSS_POINTS);
        let mut edges: Vec<f64> = breakpoints
            .iter()
            .copied()
            .filter(|&b| b > lo && b < hi)
            .collect();
        edges.insert(0, lo);
        edges.push(hi);
        let mut accepted: Vec<(f64, f64)> = Vec::new();
        let mut stack: Vec<(f64, f64, u32)> =
            edges.windows(2).rev().map(|e| (e[0], e[1], 0)).collect();
        while let Some((a, b, depth)) = stack.pop() {
            let m = 0.5 * (a + b);
            let whole = probe_rule(response, a, b, t_range_k, &x, &w);
            let left = probe_rule(response, a, m, t_range_k, &x, &w);
            let right = probe_rule(response, m, b, t_range_k, &x, &w);
            let mut ok = true;
            for p in 0..8 {
                let diff = (whole[p] - (left[p] + right[p])).abs();
                if !diff.is_finite() {
                    return Err(Error::OutOfRange(format!(
                        "band quadrature: the blackbody integrand is not finite on [{a}, {b}] µm"
                    )));
                }
                ok &= diff <= SUBINTERVAL_REL_TOL * scale[p];
            }
            if ok {
                accepted.push((a, b));
            } else if depth >= MAX_DEPTH || accepted.len() + stack.len() >= MAX_SUBINTERVALS {
                return Err(Error::OutOfRange(format!(
                    "band quadrature: no convergence on [{a}, {b}] µm after {depth} halvings; the spectral response must be piecewise smooth between its breakpoints"
                )));
            } else {
                // Right half pushed first: sub-intervals are accepted in increasing λ.
                stack.push((m, b, depth + 1));
                stack.push((a, m, depth + 1));
            }
        }
        let n = accepted.len() * GAUSS_POINTS;
        let mut q = BandQuadrature {
            lambda_m: Vec::with_capacity(n),
            energy_weight: Vec::with_capacity(n),
            photon_weight: Vec::with_capacity(n),
        };
        for (a, b) in accepted {
            let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
            for (xi, wi) in x.iter().zip(&w) {
                let w_um = c + h * xi;
                let s = response.eval(w_um);
                if s == 0.0 {
                    continue;
                }
                let lambda_m = w_um * 1e-6;
                let energy = wi * h * s * C1L / lambda_m.powi(5) * 1e-6;
                q.lambda_m.push(lambda_m);
                q.energy_weight.push(energy);
                q.photon_weight
                    .push(energy * lambda_m / (PLANCK_H * SPEED_OF_LIGHT_C));
            }
        }
        Ok(q)
    }

    /// Number of wavelength nodes (where S ≠ 0).
    pub fn nodes(&self) -> usize {
        self.lambda_m.len()
    }

    /// The four band integrals at `t_k` (module documentation); meant for temperatures
    /// inside the range the rule was built for (outside it the error bound is not checked).
    pub fn eval(&self, t_k: f64) -> BandIntegrals {
        let (mut q, mut dq, mut r, mut dr) = (0.0, 0.0, 0.0, 0.0);
        let inv_t = 1.0 / t_k;
        for ((&l, &we), &wq) in self
            .lambda_m
            .iter()
            .zip(&self.energy_weight)
            .zip(&self.photon_weight)
        {
            let (p, d) = planck_factors(C2_M_K / (l * t_k));
            let pd = p * d * inv_t;
            q += wq * p;
            dq += wq * pd;
            r += we * p;
            dr += we * pd;
        }
        BandIntegrals {
            photon: q,
            photon_per_k: dq,
            energy: r,
            energy_per_k: dr,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The n-point rule integrates x^k exactly for k ≤ 2n − 1 (∫_{−1}^{1} x^k = 2/(k+1) for
    /// even k, 0 for odd k) and its weights sum to 2.
    #[test]
    fn gauss_legendre_is_exact_for_polynomials_of_degree_2n_minus_1() {
        for n in [1, 2, 5, 8, 12] {
            let (x, w) = gauss_legendre(n);
            for k in 0..2 * n {
                let got: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(k as i32)).sum();
                let exact = if k % 2 == 0 {
                    2.0 / (k as f64 + 1.0)
                } else {
                    0.0
                };
                assert!((got - exact).abs() < 1e-14, "n {n} k {k}: {got} vs {exact}");
            }
        }
    }

    /// The photon form is the energy form times λ/(hc): for a narrow top-hat the ratio of
    /// the two integrals is λ_centre/(hc) to the band's relative width squared.
    #[test]
    fn photon_and_energy_forms_are_consistent() {
        let s =
            Spectrum::top_hat(9.999, 10.001, 0.0, 1.0).unwrap_or_else(|_| Spectrum::constant(0.0));
        let q = BandQuadrature::new(&s, (200.0, 400.0)).expect("rule");
        let b = q.eval(300.0);
        let expect = 10e-6 / (PLANCK_H * SPEED_OF_LIGHT_C);
        assert!((b.photon / b.energy / expect - 1.0).abs() < 1e-7);
    }
}
