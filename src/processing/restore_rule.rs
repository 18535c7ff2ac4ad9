//! The automatic choice among restoration filters: an estimate of each filter's error
//! against the unblurred scene, and the filter (or no filter) of least estimated error.
//!
//! Every filter of [`crate::processing::wiener`] is diagonal in frequency,
//! `F̂(u) = W(u)·G(u)` with `W = H/(H² + R)`. For `G = H·F + N`, N white noise of power
//! `P_n` per DFT coefficient, the expected squared error at one frequency is
//!
//! ```text
//! E|W G − F|² = (W H − 1)² |F|² + W² P_n                              (1)
//! ```
//!
//! and, by Parseval, the sum of (1) over the frequencies is the expected squared error of
//! the restored frame in the image domain. The only unknown is the object power `|F|²`.
//! Its unbiased estimate `(|G|² − P_n)/H²` (E|G|² = H²|F|² + P_n) makes the sum an
//! unbiased risk estimate in the sense of Stein (1981, Ann. Stat. 9, 1135) for a linear
//! filter, the deconvolution form of the "unbiased predictive risk" rule of Vogel
//! (*Computational Methods for Inverse Problems*, SIAM 2002, §7.1) with the error measured
//! against F rather than H·F. Where |H| < [`RISK_MIN_H`] that per-frequency estimate's
//! variance (∝ 1/H⁴) swamps it; there the object power is the same estimate pooled over
//! the frequencies of the annulus (one of [`ANNULI`]) that share the small |H|,
//! `Σ w(|G|² − P_n) / Σ w H²` (w the bins' multiplicities), when the pooled excess
//! `Σ w(|G|² − P_n)` exceeds [`SIGNIFICANCE`] times its noise standard deviation
//! `P_n √(Σ w²)`, and 0 otherwise. Without that test, an annulus where H ≈ 1e−5 turned
//! the noise's chance excess into an object power of 1e10·P_n, and the input (W = 1, bias
//! factor (1 − H)²) then beat every filter (bias factor ≈ 1) on that phantom power alone.
//! The pooled value is further capped by the least mean object power measured reliably
//! (|H| ≥ [`RISK_MIN_H`]) in any annulus at lower frequency (scene spectra fall with
//! frequency; [`bins`]).
//!
//! Why not a fitted model there: an earlier version used the power law `A ρ^β` that
//! the classic Wiener filter is built from. On a bar target the harmonics lift the fit far
//! above the true object power at high frequency, the error estimate then *agreed* with
//! the Wiener filter that amplifies those frequencies (its own model scored itself), and
//! the choice lost 13 dB at 10× read noise. The pooled estimate is independent of every
//! candidate, so no candidate marks its own work.
//!
//! The candidates ([`choose`]): the classic Wiener filter (`R = P_n/(A ρ^β)`), Wiener–Hunt
//! (`R = λ |C|²`, C the 5-point Laplacian's transfer function, λ of least estimated error
//! over [`regulariser_grid`]), a constant NSR (of least estimated error over the same grid)
//! and **none** (W = 1: the input itself). The sharpness guard ([`guard`]) applies to the
//! first three before their error is estimated. The zero frequency is left out of the sum:
//! every filter passes it with gain 1.

use crate::error::{Error, Result};

/// |H| from which the per-frequency object power `(|G|² − P_n)/H²` enters the estimated
/// error; below it the power pooled over the annulus stands in (module documentation).
pub const RISK_MIN_H: f64 = 0.1;

/// Standard deviations of the noise by which an annulus's pooled excess power must
/// exceed zero to count as object power (a one-sided 3σ test; below it, 0).
pub const SIGNIFICANCE: f64 = 3.0;

/// Number of radial annuli (up to the corner frequency √½ cycles/pixel) over which the
/// object power of the small-|H| frequencies is pooled.
pub const ANNULI: usize = 48;

/// Which regularised inverse filter restores the image (all of the form
/// `F̂ = G·H/(H² + R(u,v))`; [`crate::processing::wiener`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Classic Wiener: `R = P_n / P_f(ρ)`, P_f a power law fitted to the image.
    Wiener,
    /// Wiener–Hunt: `R = λ·|C(u,v)|²`, C the discrete Laplacian's transfer function, λ of
    /// least estimated error.
    WienerHunt,
    /// Whichever of Wiener, Wiener–Hunt, the constant NSR of least estimated error and
    /// the unrestored input has the least estimated error.
    Auto,
}

impl Method {
    /// Parses `wiener`, `wiener-hunt` or `auto`.
    ///
    /// Errors: any other name.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "wiener" => Ok(Method::Wiener),
            "wiener-hunt" => Ok(Method::WienerHunt),
            "auto" => Ok(Method::Auto),
            other => Err(Error::param(
                "method",
                format!("`{other}`"),
                "wiener, wiener-hunt or auto",
            )),
        }
    }
}

/// One filter the restoration considered, with its estimated error.
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// `wiener`, `wiener-hunt`, `constant` or `none` (the input unchanged).
    pub name: &'static str,
    /// The filter's parameter: λ (wiener-hunt), the NSR (constant); `None` otherwise.
    pub parameter: Option<f64>,
    /// Estimated squared error of the result against the unblurred scene, relative to
    /// that of the unrestored input (`none` is 1; lower is better).
    pub relative_risk: f64,
}

/// One half-plane frequency bin as the error estimate sees it.
#[derive(Debug, Clone, Copy)]
pub struct Bin {
    /// Transfer function H.
    pub h: f64,
    /// Estimated object power |F|² (image units², per DFT coefficient).
    pub f2: f64,
    /// Multiplicity in the full plane (1 or 2).
    pub w: f64,
    /// |C|² of the discrete Laplacian, `(4 − 2 cos 2πu − 2 cos 2πv)²`.
    pub c2: f64,
    /// The classic Wiener regulariser `P_n / (A ρ^β)` (∞ when there is no fit).
    pub wiener: f64,
}

/// One non-zero frequency as measured: |G|², H, radial frequency (cycles/pixel),
/// multiplicity, |C|², and the Wiener regulariser.
#[derive(Debug, Clone, Copy)]
pub struct Measured {
    /// Image power |G|².
    pub power: f64,
    /// Transfer function H.
    pub h: f64,
    /// Radial frequency, cycles per pixel.
    pub rho: f64,
    /// Multiplicity in the full plane.
    pub w: f64,
    /// |C|² of the discrete Laplacian.
    pub c2: f64,
    /// The classic Wiener regulariser.
    pub wiener: f64,
}

/// The bins of the error estimate: the object power of each measured frequency by the
/// per-frequency unbiased estimate where |H| ≥ [`RISK_MIN_H`] and by the positive part of
/// the annulus-pooled estimate elsewhere (module documentation). `pn`: noise power per
/// DFT coefficient.
pub fn bins(measured: &[Measured], pn: f64) -> Vec<Bin> {
    let rho_max = 0.5f64.hypot(0.5);
    let annulus = |r: f64| ((r / rho_max * ANNULI as f64) as usize).min(ANNULI - 1);
    let mut excess = [0.0f64; ANNULI];
    let mut h2 = [0.0f64; ANNULI];
    let mut w2 = [0.0f64; ANNULI];
    for m in measured.iter().filter(|m| m.h.abs() < RISK_MIN_H) {
        let a = annulus(m.rho);
        excess[a] += m.w * (m.power - pn);
        h2[a] += m.w * m.h * m.h;
        w2[a] += m.w * m.w;
    }
    // Only an excess the noise cannot explain counts: |G|² of pure noise is P_n times an
    // exponential variate (standard deviation P_n), so Σ w(|G|² − P_n) has standard
    // deviation P_n √(Σ w²); below SIGNIFICANCE of those the object power is taken as 0.
    for a in 0..ANNULI {
        if excess[a] <= SIGNIFICANCE * pn * w2[a].sqrt() {
            excess[a] = 0.0;
        }
    }
    // The object power of an annulus is not allowed to exceed the least mean object
    // power measured reliably (|H| ≥ RISK_MIN_H) in any annulus at lower frequency: the
    // spectra of scenes fall with frequency (natural scenes as ρ^−2…−3, van der Schaaf &
    // van Hateren 1996; a target's harmonics under their envelope). Without it, power
    // that H did not put there (the mirror pads' seams, aliasing) divided by a tiny ΣwH²
    // posed as object power.
    let mut reliable = [(0.0f64, 0.0f64); ANNULI];
    for m in measured.iter().filter(|m| m.h.abs() >= RISK_MIN_H) {
        let a = annulus(m.rho);
        reliable[a].0 += m.w * (m.power - pn) / (m.h * m.h);
        reliable[a].1 += m.w;
    }
    let mut cap = [f64::INFINITY; ANNULI];
    let mut running = f64::INFINITY;
    for a in 0..ANNULI {
        if reliable[a].1 > 0.0 {
            running = running.min((reliable[a].0 / reliable[a].1).max(0.0));
        }
        cap[a] = running;
    }
    measured
        .iter()
        .map(|m| {
            let f2 = if m.h.abs() >= RISK_MIN_H {
                (m.power - pn) / (m.h * m.h)
            } else {
                let a = annulus(m.rho);
                if h2[a] > 0.0 {
                    (excess[a] / h2[a]).min(cap[a])
                } else {
                    0.0
                }
            };
            Bin {
                h: m.h,
                f2,
                w: m.w,
                c2: m.c2,
                wiener: m.wiener,
            }
        })
        .collect()
}

/// The regulariser values searched for λ (Wiener–Hunt) and the constant NSR:
/// 10^(−10 + i/10), i = 0 … 140 (ten per decade from 1e−10 to 1e4).
pub fn regulariser_grid() -> impl Iterator<Item = f64> {
    (0..=140).map(|i| 10f64.powf(-10.0 + 0.1 * i as f64))
}

/// The regulariser after the sharpness guard: where the sensor passes a frequency at
/// |H| ≥ ½, R is lowered to at most |H|(1 − |H|), which makes the restored transfer
/// function `H²/(H² + R)` at least |H| there, so the result is never blurrier than the
/// input where the input is still sharp (in particular at the input's MTF50).
pub fn guard(r: f64, h: f64) -> f64 {
    let a = h.abs();
    if a >= 0.5 {
        r.min(a * (1.0 - a))
    } else {
        r
    }
}

/// The filter gain `W = H/(H² + R)` (0 where the denominator vanishes).
pub fn gain(h: f64, r: f64) -> f64 {
    let d = h * h + r;
    if d > 0.0 && d.is_finite() {
        h / d
    } else {
        0.0
    }
}

/// The estimated error (1) summed over `bins` of the filter with regulariser `reg`
/// (guarded), or of the input itself (`reg = None`, W = 1).
pub fn risk(bins: &[Bin], pn: f64, reg: Option<&dyn Fn(&Bin) -> f64>) -> f64 {
    bins.iter()
        .map(|b| {
            let w = match reg {
                None => 1.0,
                Some(f) => gain(b.h, guard(f(b), b.h)),
            };
            let e = w * b.h - 1.0;
            b.w * (e * e * b.f2 + w * w * pn)
        })
        .sum()
}

/// The parameter p of least estimated error over [`regulariser_grid`] for the
/// regulariser `R = p·shape(bin)`: (p, error).
pub fn best_parameter(bins: &[Bin], pn: f64, shape: fn(&Bin) -> f64) -> (f64, f64) {
    regulariser_grid()
        .map(|p| (p, risk(bins, pn, Some(&|b: &Bin| p * shape(b)))))
        .fold(
            (f64::NAN, f64::INFINITY),
            |a, c| if c.1 < a.1 { c } else { a },
        )
}

/// What [`choose`] decided.
#[derive(Debug, Clone, PartialEq)]
pub struct Choice {
    /// The filter chosen: `wiener`, `wiener-hunt`, `constant` or `none`.
    pub name: &'static str,
    /// λ of Wiener–Hunt.
    pub lambda: f64,
    /// The constant NSR of least estimated error.
    pub nsr: f64,
    /// Every candidate with its relative error.
    pub candidates: Vec<Candidate>,
}

/// Scores the candidates on `bins` and picks `method`'s filter: the requested one, or
/// (auto) the one of least estimated error, `none` included. `has_wiener`: whether the
/// classic Wiener filter exists (its power-law fit succeeded).
pub fn choose(bins: &[Bin], pn: f64, method: Method, has_wiener: bool) -> Choice {
    let r_none = risk(bins, pn, None);
    let rel = |r: f64| if r_none > 0.0 { r / r_none } else { 1.0 };
    let (lambda, r_hunt) = best_parameter(bins, pn, |b| b.c2);
    let (nsr, r_const) = best_parameter(bins, pn, |_| 1.0);
    let mut candidates = Vec::with_capacity(4);
    if has_wiener {
        candidates.push(Candidate {
            name: "wiener",
            parameter: None,
            relative_risk: rel(risk(bins, pn, Some(&|b: &Bin| b.wiener))),
        });
    }
    candidates.extend([
        Candidate {
            name: "wiener-hunt",
            parameter: Some(lambda),
            relative_risk: rel(r_hunt),
        },
        Candidate {
            name: "constant",
            parameter: Some(nsr),
            relative_risk: rel(r_const),
        },
        Candidate {
            name: "none",
            parameter: None,
            relative_risk: 1.0,
        },
    ]);
    let name = match method {
        Method::Wiener => "wiener",
        Method::WienerHunt => "wiener-hunt",
        Method::Auto => {
            // Ties go to the later (simpler) candidate, so `none` wins an exact tie.
            candidates
                .iter()
                .fold(None::<&Candidate>, |a, c| match a {
                    Some(a) if a.relative_risk < c.relative_risk => Some(a),
                    _ => Some(c),
                })
                .map_or("none", |c| c.name)
        }
    };
    Choice {
        name,
        lambda,
        nsr,
        candidates,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The estimated error of a filter is unbiased: averaged over many noise
    /// realisations of a known object spectrum, it matches the true squared error of
    /// the filtered spectrum (computed from the realisations, not from equation (1)).
    #[test]
    fn estimated_error_matches_the_monte_carlo_error() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(7);
        let n = 400;
        let pn = 1.0;
        // Object: complex coefficients of power 50/(1+k/20)²; H from 1 down to 0.15.
        let f: Vec<f64> = (0..n)
            .map(|k| (50.0f64).sqrt() / (1.0 + k as f64 / 20.0))
            .collect();
        let h: Vec<f64> = (0..n).map(|k| 1.0 - 0.85 * k as f64 / n as f64).collect();
        let normal = Normal::new(0.0, (pn / 2.0f64).sqrt()).unwrap();
        let lambda = 0.05;
        let (mut est, mut truth) = (0.0, 0.0);
        let trials = 400;
        for _ in 0..trials {
            let measured: Vec<Measured> = (0..n)
                .map(|k| {
                    let (re, im) = (
                        h[k] * f[k] + normal.sample(&mut rng),
                        normal.sample(&mut rng),
                    );
                    let w = gain(h[k], guard(lambda, h[k]));
                    truth += (w * re - f[k]).powi(2) + (w * im).powi(2);
                    Measured {
                        power: re * re + im * im,
                        h: h[k],
                        rho: 0.3,
                        w: 1.0,
                        c2: 1.0,
                        wiener: 1.0,
                    }
                })
                .collect();
            let b = bins(&measured, pn);
            est += risk(&b, pn, Some(&|_: &Bin| lambda));
        }
        let (est, truth) = (est / trials as f64, truth / trials as f64);
        assert!(((est - truth) / truth).abs() < 0.02, "{est} vs {truth}");
    }

    #[test]
    fn auto_returns_none_when_nothing_is_resolved_above_the_noise() {
        // No object power at all: every filter only reshapes the noise; the input
        // (W = 1 where H = 1) is the least error of W ≥ 1 guarded filters.
        let measured: Vec<Measured> = (0..200)
            .map(|k| Measured {
                power: 1.0,
                h: 0.6 + 0.4 * k as f64 / 200.0,
                rho: 0.2,
                w: 2.0,
                c2: 1.0,
                wiener: 1e-3,
            })
            .collect();
        let b = bins(&measured, 1.0);
        let c = choose(&b, 1.0, Method::Auto, true);
        assert_eq!(c.name, "none", "{c:?}");
    }
}
