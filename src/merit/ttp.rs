//! Target task performance (TTP) metric and range performance (Vollmerhausen & Jacobs
//! 2004, "The targeting task performance (TTP) metric: a new model for predicting target
//! acquisition performance", NVESD technical report AMSEL-NV-TR-230; Vollmerhausen, Jacobs
//! & Driggers 2004, Opt. Eng. 43(11), 2806).
//!
//! **Eye.** The naked-eye contrast threshold is Barten's simplified formula (Barten 1999,
//! *Contrast Sensitivity of the Human Eye and Its Effects on Image Quality*, SPIE Press,
//! eq. 3.26), as NVThermIP uses it: `CTF_eye(u) = 1/CSF(u)`,
//! `CSF(u) = a·u·e^(−b·u)·√(1 + 0.06·e^(b·u))`,
//! `a = 540 (1 + 0.7/L)^(−0.2) / (1 + 12 / (w (1 + u/3)²))`, `b = 0.3 (1 + 100/L)^0.15`,
//! u in cycles/degree at the eye, L the display luminance (cd/m²), w the display's field
//! angle (degrees).
//!
//! **Display.** One detector pixel subtends `pixel_arcmin` at the eye, so the system
//! magnification is `M = pixel angle at the eye / IFOV`, and an object-space frequency ξ
//! (cycles/mrad) is seen at `ξ/M`. Display MTF = 1 (a fine display).
//!
//! **System CTF** (Vollmerhausen et al. 2004, their eq. for CTF with noise):
//! `CTF_sys(ξ) = CTF_eye(ξ/M)/MTF(ξ) · √(1 + α²·ρ²·Q(ξ)²)`,
//! α = 169.6 √Hz (the eye's noise calibration constant of that paper), ρ² = σ²·IFOV²/F_R
//! the noise spectral density for a per-pixel, per-frame noise σ expressed as a fraction of
//! the display's mean luminance (white over the pixel area and frame time), and
//! `Q(ξ) = ∫ B(ξ'/ξ)² dξ' = ξ·√(π/4.4)·e^(1/17.6)` the noise bandwidth of the eye's
//! channel filter `B(r) = exp(−2.2 ln² r)` at ξ (the closed form of the integral). For a
//! thermal sensor σ = NETD/SCT, with SCT the scene contrast temperature the display gain
//! maps to the mean luminance; the eye's temporal integration is inside α.
//!
//! **Target.** Contrast at range R: `C(R) = C₀·τ(R)`, `τ(R) = e^(−β R)` (Beer–Lambert, β
//! the extinction coefficient; path radiance neglected); thermal `C₀ = ΔT/(2·SCT)`,
//! reflective C₀ the reflectance contrast given.
//!
//! **TTP value.** `V = (s/R) · √(I_h · I_v)`, `I = ∫ √(C/CTF_sys(ξ)) dξ` over the band
//! where `C > CTF_sys`, for the horizontal and vertical CTF_sys, s the target's
//! characteristic size (√area), ξ in cycles/mrad and s/R in mrad. The band is limited to
//! the detector's Nyquist frequency (aliasing is not credited).
//!
//! **Probability.** `P = (V/V50)^E / (1 + (V/V50)^E)`, `E = 1.51 + 0.24·V/V50` (NVThermIP).
//! V50 defaults ([`DEFAULT_TASKS`]): identification 20.8 (the NVESD tactical-vehicle
//! identification value used with the TTP metric in Vollmerhausen & Jacobs 2004);
//! recognition and detection scaled from it by Johnson's 50 % criteria (Johnson 1958:
//! 0.75, 3 and 6 cycles across the critical dimension for detection, recognition and
//! identification), i.e. 20.8·0.75/6 = 2.6 and 20.8·3/6 = 10.4. These are defaults, to be
//! replaced by the V50 calibrated for the user's target set.

use serde::Serialize;

use crate::error::{Error, Result};

/// α of the noise term, √Hz (Vollmerhausen, Jacobs & Driggers 2004).
pub const ALPHA_SQRT_HZ: f64 = 169.6;

/// Default display luminance, cd/m².
pub const DEFAULT_LUMINANCE_CD_M2: f64 = 10.0;

/// Default angle one detector pixel subtends at the eye, arcmin.
pub const DEFAULT_PIXEL_ARCMIN: f64 = 2.0;

/// Default scene contrast temperature, K (an assumption of the defaults, not a measured
/// value: use the SCT of the scene class studied).
pub const DEFAULT_SCT_K: f64 = 4.0;

/// Default tasks (name, V50); see the module documentation for their source.
pub const DEFAULT_TASKS: [(&str, f64); 3] = [
    ("detection", 20.8 * 0.75 / 6.0),
    ("recognition", 20.8 * 3.0 / 6.0),
    ("identification", 20.8),
];

/// Barten's contrast sensitivity CSF(u) (module documentation) at `u_cy_per_deg` for a
/// display of luminance `luminance_cd_m2` and field angle `field_deg`.
pub fn barten_csf(u_cy_per_deg: f64, luminance_cd_m2: f64, field_deg: f64) -> f64 {
    let (u, l, w) = (u_cy_per_deg.max(0.0), luminance_cd_m2, field_deg);
    let a = 540.0 * (1.0 + 0.7 / l).powf(-0.2) / (1.0 + 12.0 / (w * (1.0 + u / 3.0).powi(2)));
    let b = 0.3 * (1.0 + 100.0 / l).powf(0.15);
    a * u * (-b * u).exp() * (1.0 + 0.06 * (b * u).exp()).sqrt()
}

/// `∫₀^∞ exp(−4.4 ln² r) dr = √(π/4.4)·e^(1/17.6)`: the eye channel filter's noise
/// bandwidth per unit frequency (module documentation).
pub fn eye_channel_bandwidth() -> f64 {
    (std::f64::consts::PI / 4.4).sqrt() * (1.0f64 / 17.6).exp()
}

/// The display and eye assumptions.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Display {
    /// Mean display luminance L, cd/m².
    pub luminance_cd_m2: f64,
    /// Angle one detector pixel subtends at the eye, arcmin.
    pub pixel_arcmin: f64,
    /// Display field angle w (Barten), degrees.
    pub field_deg: f64,
}

impl Display {
    /// The defaults for a detector `cols` pixels wide: [`DEFAULT_LUMINANCE_CD_M2`],
    /// [`DEFAULT_PIXEL_ARCMIN`], field = cols × pixel angle.
    pub fn default_for(cols: usize) -> Self {
        Display {
            luminance_cd_m2: DEFAULT_LUMINANCE_CD_M2,
            pixel_arcmin: DEFAULT_PIXEL_ARCMIN,
            field_deg: cols as f64 * DEFAULT_PIXEL_ARCMIN / 60.0,
        }
    }

    fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("display.luminance_cd_m2", self.luminance_cd_m2),
            ("display.pixel_arcmin", self.pixel_arcmin),
            ("display.field_deg", self.field_deg),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::param(name, v, "a finite value > 0"));
            }
        }
        Ok(())
    }
}

/// The sensor side of the system CTF.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TtpSensor {
    /// Instantaneous field of view of one pixel, rad.
    pub ifov_rad: f64,
    /// Frame rate F_R, Hz.
    pub frame_rate_hz: f64,
    /// Temporal noise per pixel and frame as a fraction of the display's mean luminance
    /// (thermal: NETD/SCT).
    pub noise_rel: f64,
}

/// One row of a CTF_sys table.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CtfSample {
    /// Object-space frequency ξ, cycles/mrad.
    pub freq_cy_per_mrad: f64,
    /// System MTF at ξ.
    pub mtf: f64,
    /// Naked-eye CTF at ξ/M.
    pub ctf_eye: f64,
    /// Noise factor √(1 + α²ρ²Q²).
    pub noise_factor: f64,
    /// CTF_sys (infinite where the MTF is ≤ 0; serialised as null).
    pub ctf_sys: f64,
}

/// The CTF_sys table at `n` frequencies evenly spaced over (0, Nyquist] along one axis,
/// `mtf(f)` the system MTF along that axis (f in cycles/pixel).
///
/// Errors: invalid display or sensor values, or `n` < 2.
pub fn ctf_sys_table(
    mtf: impl Fn(f64) -> f64,
    sensor: &TtpSensor,
    display: &Display,
    n: usize,
) -> Result<Vec<CtfSample>> {
    display.validate()?;
    for (name, v) in [
        ("ifov_rad", sensor.ifov_rad),
        ("frame_rate_hz", sensor.frame_rate_hz),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(Error::param(name, v, "a finite value > 0"));
        }
    }
    if !(sensor.noise_rel.is_finite() && sensor.noise_rel >= 0.0) {
        return Err(Error::param(
            "noise_rel",
            sensor.noise_rel,
            "a finite value ≥ 0",
        ));
    }
    if n < 2 {
        return Err(Error::param("n", n, "at least 2 frequencies"));
    }
    let ifov_mrad = sensor.ifov_rad * 1e3;
    let eye_deg_per_px = display.pixel_arcmin / 60.0;
    let rho2 = sensor.noise_rel.powi(2) * sensor.ifov_rad.powi(2) / sensor.frame_rate_hz;
    let q0 = eye_channel_bandwidth();
    Ok((1..=n)
        .map(|i| {
            let f_px = 0.5 * i as f64 / n as f64;
            let xi = f_px / ifov_mrad; // cycles/mrad
            let u = f_px / eye_deg_per_px; // cycles/degree at the eye
            let h = mtf(f_px);
            let ctf_eye = 1.0 / barten_csf(u, display.luminance_cd_m2, display.field_deg);
            let q = q0 * xi * 1e3; // cycles/rad
            let noise_factor = (1.0 + ALPHA_SQRT_HZ.powi(2) * rho2 * q * q).sqrt();
            let ctf_sys = if h > 0.0 {
                ctf_eye / h * noise_factor
            } else {
                f64::INFINITY
            };
            CtfSample {
                freq_cy_per_mrad: xi,
                mtf: h,
                ctf_eye,
                noise_factor,
                ctf_sys,
            }
        })
        .collect())
}

/// `I = ∫ √(C/CTF_sys) dξ` (cycles/mrad) over the table where C > CTF_sys, by the
/// trapezoid rule on the table's points, the first interval from ξ = 0 (where the
/// integrand is taken as 0: CTF_eye → ∞ at zero frequency).
pub fn ttp_integral(table: &[CtfSample], contrast: f64) -> f64 {
    let g = |s: &CtfSample| {
        if contrast > s.ctf_sys {
            (contrast / s.ctf_sys).sqrt()
        } else {
            0.0
        }
    };
    let mut prev = (0.0, 0.0);
    let mut sum = 0.0;
    for s in table {
        let cur = (s.freq_cy_per_mrad, g(s));
        sum += 0.5 * (cur.1 + prev.1) * (cur.0 - prev.0);
        prev = cur;
    }
    sum
}

/// TTP value V (cycles on target) of a target of size `size_m` at `range_m` with apparent
/// contrast `contrast` (module documentation).
pub fn ttp_value(
    horizontal: &[CtfSample],
    vertical: &[CtfSample],
    contrast: f64,
    size_m: f64,
    range_m: f64,
) -> f64 {
    let angle_mrad = size_m / range_m * 1e3;
    angle_mrad * (ttp_integral(horizontal, contrast) * ttp_integral(vertical, contrast)).sqrt()
}

/// Task probability `P = (V/V50)^E / (1 + (V/V50)^E)`, `E = 1.51 + 0.24·V/V50`.
pub fn probability(v: f64, v50: f64) -> f64 {
    if v.is_nan() || v <= 0.0 {
        return 0.0;
    }
    let r = v / v50;
    let e = 1.51 + 0.24 * r;
    let x = r.powf(e);
    if x.is_infinite() {
        1.0
    } else {
        x / (1.0 + x)
    }
}

/// A target and the path to it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TtpTarget {
    /// Characteristic size (√area), m.
    pub size_m: f64,
    /// Inherent contrast C₀ (thermal: ΔT/(2·SCT)).
    pub contrast: f64,
    /// Extinction coefficient β of the path, 1/m.
    pub extinction_per_m: f64,
}

impl TtpTarget {
    /// Apparent contrast at `range_m`: `C₀·e^(−β R)`.
    pub fn contrast_at(&self, range_m: f64) -> f64 {
        self.contrast * (-self.extinction_per_m * range_m).exp()
    }

    /// V at `range_m` for the given CTF_sys tables.
    pub fn value_at(&self, h: &[CtfSample], v: &[CtfSample], range_m: f64) -> f64 {
        ttp_value(h, v, self.contrast_at(range_m), self.size_m, range_m)
    }
}

/// The range (m) at which the task probability falls to `p`, between `min_range_m` and
/// `max_range_m`, by bisection on `P(V(R))` (V decreases with R). `None` when P is below
/// `p` already at the shortest range or still above it at the longest.
pub fn range_at_probability(
    p: f64,
    v50: f64,
    value_at: impl Fn(f64) -> f64,
    min_range_m: f64,
    max_range_m: f64,
) -> Option<f64> {
    let pr = |r: f64| probability(value_at(r), v50);
    if pr(min_range_m) < p || pr(max_range_m) >= p {
        return None;
    }
    let (mut lo, mut hi) = (min_range_m, max_range_m);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if pr(mid) >= p {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-9 * hi {
            break;
        }
    }
    Some(0.5 * (lo + hi))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::radiometry::integrate;

    #[test]
    fn probability_is_one_half_at_v50_and_follows_the_exponent() {
        for v50 in [2.6, 10.4, 20.8] {
            assert_eq!(probability(v50, v50), 0.5);
        }
        // V = 2·V50: E = 1.99, P = 2^1.99 / (1 + 2^1.99), written out: 2^1.99 = 3.97237.
        assert!((probability(2.0, 1.0) - 3.972_37 / 4.972_37).abs() < 1e-5);
        assert_eq!(probability(0.0, 1.0), 0.0);
    }

    #[test]
    fn eye_channel_bandwidth_matches_quadrature() {
        let q = integrate(
            |r: f64| {
                if r > 0.0 {
                    (-4.4 * r.ln().powi(2)).exp()
                } else {
                    0.0
                }
            },
            1e-6,
            50.0,
            &[1.0],
            1e-10,
        );
        assert!((q / eye_channel_bandwidth() - 1.0).abs() < 1e-6, "{q}");
    }

    #[test]
    fn barten_csf_peaks_near_a_few_cycles_per_degree() {
        // The photopic CSF of Barten's formula at 100 cd/m², 10° field peaks between 2 and
        // 6 cycles/degree with a sensitivity of a few hundred (Barten 1999, fig. 3.7).
        let (mut best_u, mut best) = (0.0, 0.0);
        for i in 1..400 {
            let u = i as f64 * 0.1;
            let s = barten_csf(u, 100.0, 10.0);
            if s > best {
                best = s;
                best_u = u;
            }
        }
        assert!((2.0..6.0).contains(&best_u), "peak at {best_u}");
        assert!((100.0..1000.0).contains(&best), "peak {best}");
        // Dimmer displays are less sensitive.
        assert!(barten_csf(4.0, 1.0, 10.0) < barten_csf(4.0, 100.0, 10.0));
    }

    #[test]
    fn range_at_probability_inverts_the_curve() {
        // V(R) = 100 km / R: P50 at V = V50 exactly → R = 100 km / V50.
        let r = range_at_probability(0.5, 10.0, |r| 1e5 / r, 100.0, 1e6).unwrap();
        assert!((r - 1e4).abs() < 1e-3, "{r}");
        assert!(range_at_probability(0.5, 10.0, |r| 1e5 / r, 2e4, 1e6).is_none());
    }
}
