//! Minimum resolvable temperature difference (MRTD) in the classic analytic form of the
//! FLIR92 / NVTherm staring-array model (Ratches et al. 1975, "Night Vision Laboratory
//! static performance model for thermal viewing systems", ECOM-7043; as written for staring
//! arrays in Holst, *Electro-Optical Imaging System Performance*, ch. "MRT"):
//!
//! `MRTD(f) = (π² / (4√14)) · SNR_th · NETD · f / (MTF(f) · √(t_e · F_R))`,
//!
//! f the bar frequency in cycles per pixel along the bars' normal, MTF the system transfer
//! function there, SNR_th the observer's threshold signal-to-noise ratio, t_e the eye's
//! integration time and F_R the frame rate (the eye averages t_e·F_R independent frames).
//! The constant is the published one: π²/8 converts the square-wave bars to their
//! fundamental averaged over a bar (4/π · 2/π), and the bar length of 7 bar widths (aspect
//! [`BAR_ASPECT`]) sets the eye's spatial integration over the bars.
//! Display and eye MTFs are taken as 1; the NETD is the sensor's temporal NETD (the
//! same noise the measured NETD uses).
//!
//! Consequences the tests check: MRTD ∝ NETD at every frequency; at low frequency
//! MRTD/f → (π²/(4√14))·SNR_th·NETD/√(t_e F_R) (MTF → 1); MRTD → ∞ as MTF → 0.

use serde::Serialize;

use crate::error::{Error, Result};

/// Observer threshold SNR, FLIR92's value (Ratches et al. 1975).
pub const DEFAULT_SNR_THRESHOLD: f64 = 2.25;

/// Eye integration time, s (FLIR92 default).
pub const DEFAULT_EYE_INTEGRATION_S: f64 = 0.1;

/// Bar aspect ratio (length / width) of the standard 4-bar target.
pub const BAR_ASPECT: f64 = 7.0;

/// Observer and display assumptions of the MRTD.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MrtdObserver {
    /// Threshold SNR.
    pub snr_threshold: f64,
    /// Eye integration time t_e, s.
    pub eye_integration_s: f64,
    /// Sensor frame rate F_R, Hz.
    pub frame_rate_hz: f64,
}

impl MrtdObserver {
    /// FLIR92 defaults at frame rate `frame_rate_hz`.
    pub fn flir92(frame_rate_hz: f64) -> Self {
        MrtdObserver {
            snr_threshold: DEFAULT_SNR_THRESHOLD,
            eye_integration_s: DEFAULT_EYE_INTEGRATION_S,
            frame_rate_hz,
        }
    }

    fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("snr_threshold", self.snr_threshold),
            ("eye_integration_s", self.eye_integration_s),
            ("frame_rate_hz", self.frame_rate_hz),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::param(name, v, "a finite value > 0"));
            }
        }
        Ok(())
    }
}

/// MRTD (K) at bar frequency `f_cy_per_px` for a system of temporal NETD `netd_k` and
/// transfer function value `mtf` there (module documentation). Returns `f64::INFINITY`
/// where the MTF is ≤ 0 (the bars are not resolved).
///
/// Errors: invalid observer values, a frequency not finite and > 0, or a NETD not finite
/// and ≥ 0.
pub fn mrtd_k(f_cy_per_px: f64, mtf: f64, netd_k: f64, observer: &MrtdObserver) -> Result<f64> {
    observer.validate()?;
    if !(f_cy_per_px.is_finite() && f_cy_per_px > 0.0) {
        return Err(Error::param(
            "f_cy_per_px",
            f_cy_per_px,
            "a finite frequency > 0 cycles/pixel",
        ));
    }
    if !(netd_k.is_finite() && netd_k >= 0.0) {
        return Err(Error::param("netd_k", netd_k, "a finite NETD ≥ 0 K"));
    }
    if mtf.is_nan() || mtf <= 0.0 {
        return Ok(f64::INFINITY);
    }
    let k = std::f64::consts::PI.powi(2) / (4.0 * (2.0 * BAR_ASPECT).sqrt());
    let frames = observer.eye_integration_s * observer.frame_rate_hz;
    Ok(k * observer.snr_threshold * netd_k * f_cy_per_px / (mtf * frames.sqrt()))
}

/// One point of an MRTD curve.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MrtdPoint {
    /// Bar frequency, cycles per pixel.
    pub freq_cy_per_px: f64,
    /// System MTF at that frequency.
    pub mtf: f64,
    /// MRTD, K (infinite beyond the cutoff; serialised as null).
    pub mrtd_k: f64,
}

/// The MRTD curve at `n` frequencies evenly spaced in (0, `max_cy_per_px`] (e.g. 0.5, the
/// Nyquist frequency of a staring array) for the transfer function `mtf(f)`.
///
/// Errors: as [`mrtd_k`], or `n` = 0.
pub fn mrtd_curve(
    mtf: impl Fn(f64) -> f64,
    netd_k: f64,
    observer: &MrtdObserver,
    max_cy_per_px: f64,
    n: usize,
) -> Result<Vec<MrtdPoint>> {
    if n == 0 {
        return Err(Error::param("n", n, "at least one frequency"));
    }
    (1..=n)
        .map(|i| {
            let f = max_cy_per_px * i as f64 / n as f64;
            let h = mtf(f);
            Ok(MrtdPoint {
                freq_cy_per_px: f,
                mtf: h,
                mrtd_k: mrtd_k(f, h, netd_k, observer)?,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sinc_gauss(f: f64) -> f64 {
        // A footprint (sinc) times a Gaussian optics blur: first zero at 1 cy/px.
        let s = if f == 0.0 {
            1.0
        } else {
            (std::f64::consts::PI * f).sin() / (std::f64::consts::PI * f)
        };
        s * (-2.0 * std::f64::consts::PI.powi(2) * 0.3f64.powi(2) * f * f).exp()
    }

    #[test]
    fn mrtd_is_proportional_to_netd_and_to_f_at_low_frequency() {
        let obs = MrtdObserver::flir92(30.0);
        let a = mrtd_curve(sinc_gauss, 0.05, &obs, 0.5, 50).unwrap();
        let b = mrtd_curve(sinc_gauss, 0.10, &obs, 0.5, 50).unwrap();
        for (p, q) in a.iter().zip(&b) {
            assert!((q.mrtd_k / p.mrtd_k - 2.0).abs() < 1e-12);
        }
        // Low-frequency limit: MTF → 1, MRTD/f → π²/(4√14)·SNR·NETD/√(t_e F_R), with the
        // numbers written out: π²/(4·3.741657) = 0.659442; √(0.1·30) = 1.732051.
        let limit = 0.659_442 * 2.25 * 0.05 / 1.732_051;
        let f = 1e-4;
        let m = mrtd_k(f, sinc_gauss(f), 0.05, &obs).unwrap();
        assert!((m / f / limit - 1.0).abs() < 1e-5, "{} vs {limit}", m / f);
        // More frames integrated by the eye lower the MRTD as 1/√F_R.
        let fast = mrtd_k(0.2, 0.5, 0.05, &MrtdObserver::flir92(120.0)).unwrap();
        assert!((mrtd_k(0.2, 0.5, 0.05, &obs).unwrap() / fast - 2.0).abs() < 1e-12);
    }

    #[test]
    fn mrtd_rises_monotonically_and_diverges_toward_the_cutoff() {
        let obs = MrtdObserver::flir92(30.0);
        let c = mrtd_curve(sinc_gauss, 0.05, &obs, 0.999, 200).unwrap();
        for w in c.windows(2) {
            assert!(w[1].mrtd_k > w[0].mrtd_k);
        }
        assert!(c.last().unwrap().mrtd_k > 1e3 * c[0].mrtd_k);
        assert_eq!(mrtd_k(1.0, 0.0, 0.05, &obs).unwrap(), f64::INFINITY);
        assert!(mrtd_k(0.0, 0.5, 0.05, &obs).is_err());
        assert!(mrtd_k(0.1, 0.5, -1.0, &obs).is_err());
    }
}
