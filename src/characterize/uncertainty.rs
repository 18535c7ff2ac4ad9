//! Standard uncertainties of the EMVA 1288 figures, by linear propagation of the
//! uncertainties of the measured quantities they are computed from (GUM, JCGM 100:2008
//! §5.1.2, uncorrelated inputs), with the partial derivatives taken by central
//! differences of the figures' own formulas ([`figures`]), so the propagation cannot drift
//! from what is reported.
//!
//! The measured quantities and their standard uncertainties (N pixels per frame):
//! - K and R: the standard error of the least-squares slope,
//!   `√(Σ r² / (n − 2) / Σ (x − x̄)²)` ([`slope_standard_error`]);
//! - a pair's mean μ_y: `σ_y/√(2N)` (two frames of N pixels, temporal noise);
//! - a pair's variance σ²_y (half the variance of the difference of N pixels):
//!   `σ²_y √(2/N)` (the sample variance of N normal values has variance `2σ⁴/N`);
//! - a stack's spatial variance s²: `s² √(2/(N − 1))`, likewise;
//! - the dark currents: the slope's standard error.
//!
//! These are the statistical (type A) uncertainties of one acquisition set; the
//! illumination's own calibration (photon counts) is not included, so η, R and μ_p.min
//! carry only the fit's part.

use std::collections::BTreeMap;

/// The measured quantities the figures are computed from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measured {
    /// System gain K, DN/e⁻.
    pub k: f64,
    /// Responsivity R, DN/photon (NaN when unknown).
    pub r: f64,
    /// Saturation net signal μ_y.sat − μ_y.dark, DN.
    pub y_sat: f64,
    /// Measured σ²_y.dark, DN².
    pub dark_var: f64,
    /// Spatial variance of the dark stack, DN².
    pub s2_dark: f64,
    /// Spatial variance of the bright stack, DN².
    pub s2_bright: f64,
    /// Net spatial mean of the bright stack, DN.
    pub net_spatial: f64,
}

impl Measured {
    fn to_array(self) -> [f64; 7] {
        [
            self.k,
            self.r,
            self.y_sat,
            self.dark_var,
            self.s2_dark,
            self.s2_bright,
            self.net_spatial,
        ]
    }

    fn from_array(a: [f64; 7]) -> Self {
        Measured {
            k: a[0],
            r: a[1],
            y_sat: a[2],
            dark_var: a[3],
            s2_dark: a[4],
            s2_bright: a[5],
            net_spatial: a[6],
        }
    }
}

/// Lower limit of σ²_y.dark, DN² (EMVA 1288 Release 4.0 Linear: below it the dark noise is
/// dominated by quantisation, and the standard takes 0.24 DN² instead).
pub const QUANTISATION_LIMIT_DN2: f64 = 0.24;

/// Quantisation noise variance of integer data, DN² (q = 1).
pub const QUANTISATION_VARIANCE_DN2: f64 = 1.0 / 12.0;

/// The EMVA 1288 Release 4.0 Linear figures from the measured quantities, by name (the
/// names of `characterization.json`):
/// - `σ_y.dark = √max(σ²_y.dark, 0.24 DN²)`;
/// - `σ_d = √(σ²_y.dark − σ²_q)/K` with σ²_q = 1/12 DN² and the floored σ²_y.dark;
/// - `μ_e.min = σ_y.dark/K + ½` (the signal where SNR = 1, Release 4.0's form, which the
///   `emva1288` reference package also computes), `μ_p.min = μ_e.min/η`;
/// - `μ_e.sat = (μ_y.sat − μ_y.dark)/K`, `SNR_max = √μ_e.sat`, `DR = μ_e.sat/μ_e.min`;
/// - `η = R/K`; `DSNU₁₂₈₈ = s_y.dark/K`; `PRNU₁₂₈₈ = √(s²_y.50 − s²_y.dark)/(μ_y.50 − μ_y.dark)`.
pub fn figures(m: &Measured) -> BTreeMap<&'static str, f64> {
    let k = m.k;
    let s2_dark_y = m.dark_var.max(QUANTISATION_LIMIT_DN2);
    let sigma_y_dark = s2_dark_y.sqrt();
    let sigma_d = (s2_dark_y - QUANTISATION_VARIANCE_DN2).max(0.0).sqrt() / k;
    let u_e_min = sigma_y_dark / k + 0.5;
    let u_e_sat = m.y_sat / k;
    let snr_max = u_e_sat.max(0.0).sqrt();
    let dr = u_e_sat / u_e_min;
    let eta = m.r / k;
    let dsnu_dn = m.s2_dark.max(0.0).sqrt();
    let prnu = 100.0 * (m.s2_bright - m.s2_dark).max(0.0).sqrt() / m.net_spatial;
    let mut f = BTreeMap::new();
    f.insert("K_DN_per_e", k);
    f.insert("inverse_K_e_per_DN", 1.0 / k);
    f.insert("sigma_y_dark_DN", sigma_y_dark);
    f.insert("sigma_d_e", sigma_d);
    f.insert("u_e_min_e", u_e_min);
    f.insert("u_e_sat_e", u_e_sat);
    f.insert("u_y_sat_DN", m.y_sat);
    f.insert("SNR_max", snr_max);
    f.insert("SNR_max_dB", 20.0 * snr_max.log10());
    f.insert("DR", dr);
    f.insert("DR_dB", 20.0 * dr.log10());
    f.insert("DSNU1288_DN", dsnu_dn);
    f.insert("DSNU1288_e", dsnu_dn / k);
    f.insert("PRNU1288_percent", prnu);
    if m.r.is_finite() {
        f.insert("responsivity_DN_per_photon", m.r);
        f.insert("QE_percent", 100.0 * eta);
        f.insert("u_p_min", u_e_min / eta);
        f.insert("u_p_sat", u_e_sat / eta);
    }
    f
}

/// The standard uncertainty of every figure of [`figures`], given the standard
/// uncertainty `u` of each measured quantity: `u(F)² = Σ_i (∂F/∂x_i · u(x_i))²`, the
/// derivatives by central differences with step `10⁻⁴ u(x_i)` (exact for the figures that
/// are linear in an input, and within 10⁻⁸ relative for the smooth ones). A figure at a
/// kink (σ²_y.dark exactly at the 0.24 DN² floor) takes the one-sided mean of the two
/// slopes.
pub fn propagate(m: &Measured, u: &Measured) -> BTreeMap<&'static str, f64> {
    let x = m.to_array();
    let ux = u.to_array();
    let base = figures(m);
    let mut var: BTreeMap<&'static str, f64> = base.keys().map(|k| (*k, 0.0)).collect();
    for i in 0..x.len() {
        if !(ux[i].is_finite() && ux[i] > 0.0 && x[i].is_finite()) {
            continue;
        }
        let h = 1e-4 * ux[i];
        let mut hi = x;
        let mut lo = x;
        hi[i] += h;
        lo[i] -= h;
        let (fh, fl) = (
            figures(&Measured::from_array(hi)),
            figures(&Measured::from_array(lo)),
        );
        for (name, v) in var.iter_mut() {
            if let (Some(a), Some(b)) = (fh.get(name), fl.get(name)) {
                let d = (a - b) / (2.0 * h) * ux[i];
                if d.is_finite() {
                    *v += d * d;
                }
            }
        }
    }
    var.into_iter().map(|(k, v)| (k, v.sqrt())).collect()
}

/// The standard error of the least-squares slope through `points` (with an intercept):
/// `√(Σ r² / (n − 2) / Σ (x − x̄)²)`; `None` with fewer than three points or no spread.
pub fn slope_standard_error(points: &[(f64, f64)], slope: f64, intercept: f64) -> Option<f64> {
    let n = points.len();
    if n < 3 {
        return None;
    }
    let mx = points.iter().map(|p| p.0).sum::<f64>() / n as f64;
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let rss: f64 = points
        .iter()
        .map(|p| (p.1 - slope * p.0 - intercept).powi(2))
        .sum();
    (sxx > 0.0).then(|| (rss / (n - 2) as f64 / sxx).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn measured() -> Measured {
        Measured {
            k: 0.05,
            r: 0.025,
            y_sat: 900.0,
            dark_var: 4.0,
            s2_dark: 1.0,
            s2_bright: 17.0,
            net_spatial: 400.0,
        }
    }

    /// Figures that are products of powers of the inputs have the closed-form relative
    /// uncertainty `√Σ (p_i u_i/x_i)²`: μ_e.sat = y/K, DSNU_e = √s²/K, η = R/K.
    #[test]
    fn propagation_matches_closed_forms() {
        let m = measured();
        let u = Measured {
            k: 0.001,
            r: 0.0002,
            y_sat: 3.0,
            dark_var: 0.1,
            s2_dark: 0.02,
            s2_bright: 0.3,
            net_spatial: 0.5,
        };
        let p = propagate(&m, &u);
        let f = figures(&m);
        let rel = |a: f64, b: f64| ((a - b) / b).abs();
        let want_sat =
            f["u_e_sat_e"] * ((3.0f64 / 900.0).powi(2) + (0.001f64 / 0.05).powi(2)).sqrt();
        assert!(
            rel(p["u_e_sat_e"], want_sat) < 1e-6,
            "{} {want_sat}",
            p["u_e_sat_e"]
        );
        let want_dsnu =
            f["DSNU1288_e"] * ((0.5 * 0.02f64 / 1.0).powi(2) + (0.001f64 / 0.05).powi(2)).sqrt();
        assert!(rel(p["DSNU1288_e"], want_dsnu) < 1e-6);
        let want_qe =
            f["QE_percent"] * ((0.0002f64 / 0.025).powi(2) + (0.001f64 / 0.05).powi(2)).sqrt();
        assert!(rel(p["QE_percent"], want_qe) < 1e-6);
        // μ_e.min = √v/K + ½: ∂/∂v = 1/(2K√v), ∂/∂K = −√v/K².
        let want_min =
            ((0.1f64 / (2.0 * 0.05 * 2.0)).powi(2) + (2.0 * 0.001 / 0.0025f64).powi(2)).sqrt();
        assert!(
            rel(p["u_e_min_e"], want_min) < 1e-6,
            "{} {want_min}",
            p["u_e_min_e"]
        );
    }

    /// Below the 0.24 DN² floor σ_y.dark is the floor, μ_e.min = √0.24/K + ½ (the
    /// issue's `ccd` numbers: K = 0.0514 DN/e⁻ gives σ_d = 7.7 e⁻ and μ_e.min = 10.0 e⁻).
    #[test]
    fn the_quantisation_floor() {
        let m = Measured {
            k: 0.0514,
            dark_var: 0.0,
            ..measured()
        };
        let f = figures(&m);
        assert!((f["sigma_y_dark_DN"] - 0.24f64.sqrt()).abs() < 1e-12);
        assert!((f["sigma_d_e"] - 7.7).abs() < 0.05, "{}", f["sigma_d_e"]);
        assert!((f["u_e_min_e"] - 10.0).abs() < 0.05, "{}", f["u_e_min_e"]);
    }

    /// Monte Carlo: the slope's standard error, averaged over 4000 noisy lines
    /// (σ = 0.3 normal noise on 21 points), matches the scatter of the fitted slopes and
    /// the closed form σ/√Σ(x − x̄)² within 3 %.
    #[test]
    fn slope_standard_error_matches_the_scatter_of_slopes() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(11);
        let noise = Normal::new(0.0, 0.3).unwrap();
        let x: Vec<f64> = (0..21).map(|i| i as f64).collect();
        let (mut slopes, mut se2) = (Vec::new(), 0.0);
        let trials = 4000;
        for _ in 0..trials {
            let pts: Vec<(f64, f64)> = x
                .iter()
                .map(|&x| (x, 2.0 * x + 1.0 + noise.sample(&mut rng)))
                .collect();
            let (s, b) = crate::processing::fit_line(&pts).unwrap();
            slopes.push(s);
            se2 += slope_standard_error(&pts, s, b).unwrap().powi(2) / trials as f64;
        }
        let mean = slopes.iter().sum::<f64>() / trials as f64;
        let scatter =
            (slopes.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / (trials - 1) as f64).sqrt();
        let closed = 0.3 / (x.iter().map(|x| (x - 10.0).powi(2)).sum::<f64>()).sqrt();
        assert!(
            (se2.sqrt() / closed - 1.0).abs() < 0.03,
            "{} {closed}",
            se2.sqrt()
        );
        assert!((scatter / closed - 1.0).abs() < 0.03, "{scatter} {closed}");
    }
}
