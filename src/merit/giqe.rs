//! General Image Quality Equation, version 5 (GIQE 5), and the relative edge response
//! (RER) it takes.
//!
//! GIQE 5 as implemented in pyBSM (`pybsm.giqe5`; Leachtenauer et al. 1997, "General
//! Image-Quality Equation: GIQE", Appl. Opt. 36, 8322, refitted as GIQE 5 by the NGA, 2015):
//!
//! `NIIRS = 9.57 − 3.32·log10(GSD) + 3.32·(1 − e^(−1.9/SNR))·log10(RER) − 2·(log10 RER)⁴
//! − 1.8/SNR`,
//!
//! GSD in inches, taken as `GSD_ground / sin(elevation)^0.25` for an oblique look (pyBSM).
//! Worked value from the equation: RER 0.35, GSD 20.8 in, SNR 50 → 5.015.
//!
//! RER is the rise of the normalised edge response over one pixel about the edge,
//! `RER = ER(+0.5 px) − ER(−0.5 px)`. From a real, even system MTF (OTF) H(f), f in cycles
//! per pixel, the edge response is `ER(x) = 1/2 + (1/π) ∫₀^∞ H(f) sin(2πfx)/f df`, so
//!
//! `RER = (2/π) ∫₀^∞ H(f) sin(πf)/f df`;
//!
//! for a two-dimensional system pyBSM takes the geometric mean √(RER_x·RER_y). From a
//! measured edge, RER is read off the normalised edge-spread function at ±0.5 px about its
//! 50 % crossing ([`rer_from_esf`]).

use crate::error::{Error, Result};

/// Metres per inch (exact).
pub const METRES_PER_INCH: f64 = 0.0254;

/// GIQE 5 NIIRS for a ground sample distance `gsd_in` (inches, already divided by
/// sin(elevation)^0.25 if oblique, see [`oblique_gsd_in`]), relative edge response `rer`
/// and signal-to-noise ratio `snr` (module documentation).
///
/// Errors: a GSD, RER or SNR that is not finite and > 0.
pub fn giqe5_niirs(gsd_in: f64, rer: f64, snr: f64) -> Result<f64> {
    for (name, v) in [("gsd_in", gsd_in), ("rer", rer), ("snr", snr)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(Error::param(name, v, "a finite value > 0"));
        }
    }
    let l = rer.log10();
    Ok(
        9.57 - 3.32 * gsd_in.log10() + 3.32 * (1.0 - (-1.9 / snr).exp()) * l
            - 2.0 * l.powi(4)
            - 1.8 / snr,
    )
}

/// The GSD GIQE 5 takes, inches: `gsd_m / sin(elevation)^0.25 / 0.0254` (pyBSM), the
/// elevation angle of the line of sight above the ground plane in radians (π/2 = nadir).
///
/// Errors: a GSD not finite and > 0, or an elevation outside (0, π/2].
pub fn oblique_gsd_in(gsd_m: f64, elevation_rad: f64) -> Result<f64> {
    if !(gsd_m.is_finite() && gsd_m > 0.0) {
        return Err(Error::param("gsd_m", gsd_m, "a finite value > 0"));
    }
    if !(elevation_rad > 0.0 && elevation_rad <= std::f64::consts::FRAC_PI_2 + 1e-12) {
        return Err(Error::param(
            "elevation_rad",
            elevation_rad,
            "an elevation in (0, π/2] rad",
        ));
    }
    Ok(gsd_m / elevation_rad.sin().powf(0.25) / METRES_PER_INCH)
}

/// Upper frequency of the RER integral, cycles per pixel: beyond it the integrand
/// H(f)·sin(πf)/f of any system with a detector footprint (|H| ≤ 1/(πf)) contributes less
/// than 2/(π²·f_max) ≈ 1e-3.
pub const RER_MAX_CY_PER_PX: f64 = 256.0;

/// Integration steps per cycle/pixel of the RER integral (trapezoid; sin(πf) has period
/// 2, so 64 steps per unit resolve it to ~1e-4).
const RER_STEPS_PER_CY: usize = 64;

/// RER from a real, even one-dimensional transfer function `mtf(f)`, f in cycles per
/// pixel: `(2/π) ∫₀^{f_max} H(f) sin(πf)/f df` (module documentation) by the trapezoid rule
/// with [`RER_STEPS_PER_CY`] steps per cycle/pixel up to `max_cy_per_px` (e.g.
/// [`RER_MAX_CY_PER_PX`], or the frequency beyond which H is zero).
///
/// Errors: a `max_cy_per_px` not finite and > 0, or a non-finite transfer function.
pub fn rer_from_mtf(mtf: impl Fn(f64) -> f64, max_cy_per_px: f64) -> Result<f64> {
    if !(max_cy_per_px.is_finite() && max_cy_per_px > 0.0) {
        return Err(Error::param(
            "max_cy_per_px",
            max_cy_per_px,
            "a finite frequency > 0 cycles/pixel",
        ));
    }
    let n = ((max_cy_per_px * RER_STEPS_PER_CY as f64).ceil() as usize).max(2);
    let df = max_cy_per_px / n as f64;
    let integrand = |f: f64| {
        if f == 0.0 {
            std::f64::consts::PI * mtf(0.0) // lim sin(πf)/f = π
        } else {
            mtf(f) * (std::f64::consts::PI * f).sin() / f
        }
    };
    let mut sum = 0.5 * (integrand(0.0) + integrand(max_cy_per_px));
    for i in 1..n {
        sum += integrand(i as f64 * df);
    }
    let rer = 2.0 / std::f64::consts::PI * sum * df;
    if !rer.is_finite() {
        return Err(Error::OutOfRange(
            "RER: the transfer function is not finite".to_string(),
        ));
    }
    Ok(rer)
}

/// RER from a sampled transfer function (e.g. a slanted-edge measurement, which carries
/// the derivative and bin corrections of ISO 12233): `(2/π) ∫ H(f) sin(πf)/f df` by the
/// trapezoid rule over the samples `(freq_cy_per_px, mtf)`, from f = 0 (where the
/// integrand is π·H(0)) to the last sample. Beyond it the transfer function is taken as 0:
/// for a measurement up to 1 cycle/pixel the neglected tail is that of the system above
/// the detector footprint's first zero.
///
/// Errors: fewer than 2 samples, lengths that differ, or frequencies not increasing from ≥ 0.
pub fn rer_from_sampled_mtf(freq_cy_per_px: &[f64], mtf: &[f64]) -> Result<f64> {
    if freq_cy_per_px.len() < 2 || freq_cy_per_px.len() != mtf.len() {
        return Err(Error::param(
            "mtf samples",
            format!("{} frequencies, {} values", freq_cy_per_px.len(), mtf.len()),
            "at least 2 frequencies with one value each",
        ));
    }
    if freq_cy_per_px[0] < 0.0 || freq_cy_per_px.windows(2).any(|w| w[1] <= w[0]) {
        return Err(Error::param(
            "mtf frequencies",
            "not increasing",
            "strictly increasing frequencies ≥ 0",
        ));
    }
    let g = |f: f64, h: f64| {
        if f == 0.0 {
            std::f64::consts::PI * h
        } else {
            h * (std::f64::consts::PI * f).sin() / f
        }
    };
    let mut prev = (0.0, std::f64::consts::PI * mtf[0]);
    let mut sum = 0.0;
    for (&f, &h) in freq_cy_per_px.iter().zip(mtf) {
        let cur = (f, g(f, h));
        sum += 0.5 * (prev.1 + cur.1) * (cur.0 - prev.0);
        prev = cur;
    }
    Ok(2.0 / std::f64::consts::PI * sum)
}

/// RER of a measured edge-spread function sampled every `bin_px` pixels along the edge
/// normal (e.g. the super-resolved ESF of
/// [`crate::processing::edge_mtf::slanted_edge_mtf`], `bin_px` = 1/4): the ESF is
/// normalised by the means of its first and last `plateau_fraction` of samples (0 → 1 from
/// the dark to the bright side, whichever way it runs), its 50 % crossing located by
/// linear interpolation, and `ER(+0.5) − ER(−0.5)` read off by linear interpolation.
///
/// Errors: fewer than 8 samples, a bin width or plateau fraction out of range, no step,
/// or a crossing too close to either end to read ±0.5 px.
pub fn rer_from_esf(esf: &[f64], bin_px: f64, plateau_fraction: f64) -> Result<f64> {
    let n = esf.len();
    if n < 8 {
        return Err(Error::param(
            "esf",
            format!("{n} samples"),
            "at least 8 samples",
        ));
    }
    if !(bin_px.is_finite() && bin_px > 0.0 && bin_px <= 0.5) {
        return Err(Error::param("bin_px", bin_px, "a bin width in (0, 0.5] px"));
    }
    if !(plateau_fraction > 0.0 && plateau_fraction < 0.5) {
        return Err(Error::param(
            "plateau_fraction",
            plateau_fraction,
            "a fraction in (0, 0.5)",
        ));
    }
    let k = ((n as f64 * plateau_fraction).round() as usize).max(1);
    let lo = esf[..k].iter().sum::<f64>() / k as f64;
    let hi = esf[n - k..].iter().sum::<f64>() / k as f64;
    let step = hi - lo;
    if !(step.is_finite() && step.abs() > 0.0) {
        return Err(Error::OutOfRange(
            "RER: the edge-spread function has no step".to_string(),
        ));
    }
    let e: Vec<f64> = esf.iter().map(|v| (v - lo) / step).collect();
    // The crossing nearest the middle of the steepest rise.
    let mut centre = None;
    let mut best = f64::INFINITY;
    for i in 0..n - 1 {
        if (e[i] - 0.5) * (e[i + 1] - 0.5) <= 0.0 && e[i + 1] != e[i] {
            let x = i as f64 + (0.5 - e[i]) / (e[i + 1] - e[i]);
            let d = (x - (n as f64 - 1.0) / 2.0).abs();
            if d < best {
                best = d;
                centre = Some(x);
            }
        }
    }
    let centre = centre.ok_or_else(|| {
        Error::OutOfRange("RER: the edge-spread function never crosses 50 %".to_string())
    })?;
    let at = |x: f64| -> Option<f64> {
        if x < 0.0 || x > (n - 1) as f64 {
            return None;
        }
        let i = (x.floor() as usize).min(n - 2);
        let f = x - i as f64;
        Some(e[i] * (1.0 - f) + e[i + 1] * f)
    };
    let half = 0.5 / bin_px;
    match (at(centre + half), at(centre - half)) {
        (Some(a), Some(b)) => Ok(a - b),
        _ => Err(Error::OutOfRange(
            "RER: the edge lies within 0.5 px of the end of the edge-spread function".to_string(),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn worked_value_of_the_equation() {
        // DESIGN of GIQE 5 as in pyBSM: RER 0.35, GSD 20.8 in, SNR 50 → 5.015.
        let n = giqe5_niirs(20.8, 0.35, 50.0).unwrap();
        assert!((n - 5.015).abs() < 5e-4, "{n}");
        // Each term separately, written out by hand (log10 values to 6 digits).
        let by_hand = 9.57 - 3.32 * 1.318_063 + 3.32 * (1.0 - (-0.038f64).exp()) * -0.455_932
            - 2.0 * 0.455_932f64.powi(4)
            - 0.036;
        assert!((n - by_hand).abs() < 1e-5, "{n} vs {by_hand}");
        assert!(giqe5_niirs(0.0, 0.35, 50.0).is_err());
        assert!(giqe5_niirs(20.8, f64::NAN, 50.0).is_err());
    }

    #[test]
    fn oblique_gsd_grows_as_the_quarter_power_of_the_elevation() {
        let nadir = oblique_gsd_in(0.5, std::f64::consts::FRAC_PI_2).unwrap();
        assert!((nadir - 0.5 / 0.0254).abs() < 1e-12);
        let at30 = oblique_gsd_in(0.5, 30f64.to_radians()).unwrap();
        assert!((at30 / nadir - 2f64.powf(0.25)).abs() < 1e-12);
        assert!(oblique_gsd_in(0.5, 0.0).is_err());
    }

    #[test]
    fn rer_of_a_gaussian_mtf_is_its_erf_closed_form() {
        // Gaussian LSF of σ px: H(f) = exp(−2π²σ²f²), ER(x) = Φ(x/σ), so
        // RER = erf(0.5/(σ√2)).
        for sigma in [0.3, 0.5, 1.0, 2.0] {
            let h = |f: f64| (-2.0 * std::f64::consts::PI.powi(2) * sigma * sigma * f * f).exp();
            let rer = rer_from_mtf(h, 16.0).unwrap();
            let truth = libm::erf(0.5 / (sigma * std::f64::consts::SQRT_2));
            assert!((rer - truth).abs() < 1e-4, "σ {sigma}: {rer} vs {truth}");
        }
    }

    #[test]
    fn rer_of_a_pixel_footprint_is_one() {
        // A box LSF one pixel wide (sinc MTF): the edge rises linearly over exactly one
        // pixel, RER = 1. The integrand decays as 1/f², so the truncation costs ~1e-3.
        let sinc = |f: f64| {
            if f == 0.0 {
                1.0
            } else {
                (std::f64::consts::PI * f).sin() / (std::f64::consts::PI * f)
            }
        };
        let rer = rer_from_mtf(sinc, RER_MAX_CY_PER_PX).unwrap();
        assert!((rer - 1.0).abs() < 2e-3, "{rer}");
    }

    #[test]
    fn rer_from_a_sampled_gaussian_edge() {
        // ESF of a Gaussian LSF σ = 0.7 px sampled every 1/4 px, running bright → dark.
        let sigma: f64 = 0.7;
        let esf: Vec<f64> = (0..64)
            .map(|i| {
                let x = (i as f64 - 31.3) * 0.25;
                10.0 - 8.0 * 0.5 * (1.0 + libm::erf(x / (sigma * std::f64::consts::SQRT_2)))
            })
            .collect();
        let rer = rer_from_esf(&esf, 0.25, 0.15).unwrap();
        let truth = libm::erf(0.5 / (sigma * std::f64::consts::SQRT_2));
        assert!((rer - truth).abs() < 0.01, "{rer} vs {truth}");
        assert!(rer_from_esf(&[1.0; 20], 0.25, 0.15).is_err());
    }
}
