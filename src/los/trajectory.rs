//! The `[trajectory]` and `[motion]` schema: what moves the image, and its validation.
//!
//! Every component is an *image displacement of the scene* on the focal plane, as an
//! object-space angle in rad, `[x, y]`: x along detector columns (+x = increasing column),
//! y along rows (+y = increasing row index, downward). See the module [`crate::los`].

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::error::{require_non_negative, require_positive, Error, Result};

/// `[motion]`: the scene's motion in the image. Give exactly one of `smear_rad`,
/// `angular_rate_rad_s`, or `velocity_m_s` with `range_m`. Within one exposure it is the
/// linear smear of the transfer-function cascade; over a clocked sequence it is a
/// constant-rate drift of the image ([`MotionConfig::rate_rad_s`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotionConfig {
    /// Include this component (`false` keeps the section but leaves it out: no smear in
    /// the cascade and no drift over a sequence, e.g. for the unblurred reference of a run).
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub enabled: bool,
    /// Angular smear length during one integration, rad.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub smear_rad: Option<f64>,
    /// Line-of-sight angular rate, rad/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angular_rate_rad_s: Option<f64>,
    /// Transverse velocity of the scene relative to the sensor, m/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity_m_s: Option<f64>,
    /// Range to the moving scene, m (with `velocity_m_s`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub range_m: Option<f64>,
    /// Direction of motion in the image, degrees from +x (columns) toward +y (rows).
    #[serde(default)]
    pub direction_deg: f64,
}

/// Serde default of `enabled`.
fn yes() -> bool {
    true
}

/// Whether `enabled` is the default (then not written).
fn is_true(v: &bool) -> bool {
    *v
}

impl MotionConfig {
    /// The image's angular rate `[x, y]`, rad/s: the speed v/R (`velocity_m_s` /
    /// `range_m`), or `angular_rate_rad_s`, or `smear_rad` / `integration_time_s`, along
    /// `direction_deg` (from +x toward +y): rate · (cos θ, sin θ). Returns an error naming
    /// the field when the section is incomplete or a value is not finite.
    pub fn rate_rad_s(&self, integration_time_s: f64) -> Result<[f64; 2]> {
        let speed = match (self.smear_rad, self.angular_rate_rad_s, self.velocity_m_s) {
            (Some(s), None, None) => {
                require_non_negative("motion.smear_rad", s)?;
                s / require_positive("detector.integration_time_s", integration_time_s)?
            }
            (None, Some(w), None) => finite("motion.angular_rate_rad_s", w)?,
            (None, None, Some(v)) => {
                let v = finite("motion.velocity_m_s", v)?;
                let r = self.range_m.ok_or_else(|| {
                    Error::param(
                        "motion.range_m",
                        "missing",
                        "the range to the moving scene, m, when velocity_m_s is given",
                    )
                })?;
                v / require_positive("motion.range_m", r)?
            }
            _ => {
                return Err(Error::param(
                    "motion",
                    "not exactly one of smear_rad / angular_rate_rad_s / velocity_m_s",
                    "exactly one of them",
                ))
            }
        };
        let theta = finite("motion.direction_deg", self.direction_deg)?.to_radians();
        Ok([speed * theta.cos(), speed * theta.sin()])
    }
}

fn finite(field: &str, v: f64) -> Result<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(Error::param(field, v, "a finite number"))
    }
}

/// `[trajectory]`: how the line of sight moves over a sequence, besides `[motion]`.
///
/// ```toml
/// [trajectory]
/// pan_rate_rad_s = [1e-3, 0.0]      # constant image rate [x, y], rad/s
/// [[trajectory.vibration]]
/// axis = "x"                        # "x" | "y"
/// amplitude_rad = 5e-6
/// frequency_hz = 120.0
/// phase_deg = 0.0                   # optional
/// [trajectory.wander]               # a stationary Gaussian process, see WanderConfig
/// kind = "power_law"
/// psd_at_1hz_rad2_per_hz = 1e-10
/// exponent = -2.0
/// f_min_hz = 0.5
/// f_max_hz = 50.0
/// ```
/// or a measured line of sight: `file = "los.csv"` (columns `t_s, az_rad, el_rad`,
/// relative to the sensor file's folder), which excludes `pan_rate_rad_s`, `vibration`
/// and `wander` (it already holds the platform's whole line of sight).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrajectoryConfig {
    /// Constant image angular rate `[x, y]`, rad/s (pan/tilt).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pan_rate_rad_s: Option<[f64; 2]>,
    /// Sinusoidal vibrations (`[[trajectory.vibration]]`), summed.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub vibration: Vec<VibrationConfig>,
    /// Random wander (`[trajectory.wander]`), independent on each axis.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wander: Option<WanderConfig>,
    /// A measured line of sight: CSV with columns `t_s, az_rad, el_rad`, relative to the
    /// sensor file's folder.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<PathBuf>,
}

/// An image axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LosAxis {
    /// Along detector columns (+x = increasing column).
    X,
    /// Along detector rows (+y = increasing row index, downward).
    Y,
}

impl LosAxis {
    /// 0 for x, 1 for y.
    pub fn index(self) -> usize {
        match self {
            LosAxis::X => 0,
            LosAxis::Y => 1,
        }
    }
}

/// One sinusoidal vibration: d_axis(t) = amplitude · sin(2π·frequency·t + phase).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VibrationConfig {
    /// The image axis it moves.
    pub axis: LosAxis,
    /// Amplitude (zero to peak), rad.
    pub amplitude_rad: f64,
    /// Frequency, Hz (> 0).
    pub frequency_hz: f64,
    /// Phase at t = 0, degrees.
    #[serde(default)]
    pub phase_deg: f64,
}

/// `[trajectory.wander]`: a one-sided power spectral density S(f) in rad²/Hz of the image
/// displacement on *each* axis (the two axes are independent realisations of the same
/// PSD, each with its own random stream). Its variance per axis is ∫S df.
///
/// ```toml
/// [trajectory.wander]
/// kind = "table"                    # log-log interpolated, zero outside the table
/// frequency_hz = [1.0, 10.0, 100.0]
/// psd_rad2_per_hz = [1e-10, 1e-11, 1e-13]
/// ```
/// ```toml
/// [trajectory.wander]
/// kind = "power_law"                # S(f) = A·f^exponent on [f_min_hz, f_max_hz], 0 outside
/// psd_at_1hz_rad2_per_hz = 1e-10    # A
/// exponent = -2.0
/// f_min_hz = 0.5
/// f_max_hz = 50.0
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum WanderConfig {
    /// A tabulated PSD, interpolated linearly in log f – log S, zero outside the table.
    Table {
        /// Frequencies, Hz: finite, > 0, strictly increasing, at least 2.
        frequency_hz: Vec<f64>,
        /// PSD at those frequencies, rad²/Hz: finite and > 0.
        psd_rad2_per_hz: Vec<f64>,
    },
    /// S(f) = A·f^exponent on [f_min_hz, f_max_hz], zero outside.
    PowerLaw {
        /// A = S(1 Hz), rad²/Hz (≥ 0).
        psd_at_1hz_rad2_per_hz: f64,
        /// The exponent (finite; e.g. −2 for a random walk's spectrum).
        exponent: f64,
        /// Lowest frequency, Hz (> 0).
        f_min_hz: f64,
        /// Highest frequency, Hz (> f_min_hz).
        f_max_hz: f64,
    },
}

impl TrajectoryConfig {
    /// Checks every value, naming the field (`trajectory.vibration[0].frequency_hz`, …)
    /// and what is valid. The CSV file itself is read (and checked) by
    /// [`crate::los::LineOfSight::new`].
    pub fn validate(&self) -> Result<()> {
        if let Some(p) = self.pan_rate_rad_s {
            for (i, v) in p.iter().enumerate() {
                finite(&format!("trajectory.pan_rate_rad_s[{i}]"), *v)?;
            }
        }
        for (i, v) in self.vibration.iter().enumerate() {
            let f = |k: &str| format!("trajectory.vibration[{i}].{k}");
            require_non_negative(&f("amplitude_rad"), v.amplitude_rad)?;
            require_positive(&f("frequency_hz"), v.frequency_hz)?;
            finite(&f("phase_deg"), v.phase_deg)?;
        }
        if let Some(w) = &self.wander {
            w.psd()?;
        }
        if self.file.is_some()
            && (self.pan_rate_rad_s.is_some()
                || !self.vibration.is_empty()
                || self.wander.is_some())
        {
            return Err(Error::param(
                "trajectory.file",
                "given with pan_rate_rad_s / vibration / wander",
                "either a measured line of sight (`file`) or the modelled components (pan, vibration, wander), not both",
            ));
        }
        Ok(())
    }
}

impl WanderConfig {
    /// The validated PSD.
    pub fn psd(&self) -> Result<Psd> {
        match self {
            WanderConfig::Table {
                frequency_hz,
                psd_rad2_per_hz,
            } => {
                if frequency_hz.len() != psd_rad2_per_hz.len() || frequency_hz.len() < 2 {
                    return Err(Error::param(
                        "trajectory.wander",
                        format!(
                            "{} frequencies and {} PSD values",
                            frequency_hz.len(),
                            psd_rad2_per_hz.len()
                        ),
                        "frequency_hz and psd_rad2_per_hz of the same length, at least 2",
                    ));
                }
                for (i, &f) in frequency_hz.iter().enumerate() {
                    let field = format!("trajectory.wander.frequency_hz[{i}]");
                    require_positive(&field, f)?;
                    if i > 0 && f <= frequency_hz[i - 1] {
                        return Err(Error::param(
                            field,
                            f,
                            format!(
                                "a frequency above frequency_hz[{}] = {} Hz (strictly increasing)",
                                i - 1,
                                frequency_hz[i - 1]
                            ),
                        ));
                    }
                }
                for (i, &s) in psd_rad2_per_hz.iter().enumerate() {
                    require_positive(&format!("trajectory.wander.psd_rad2_per_hz[{i}]"), s)?;
                }
                Ok(Psd::Table {
                    f_hz: frequency_hz.clone(),
                    s: psd_rad2_per_hz.clone(),
                })
            }
            WanderConfig::PowerLaw {
                psd_at_1hz_rad2_per_hz,
                exponent,
                f_min_hz,
                f_max_hz,
            } => {
                require_non_negative(
                    "trajectory.wander.psd_at_1hz_rad2_per_hz",
                    *psd_at_1hz_rad2_per_hz,
                )?;
                finite("trajectory.wander.exponent", *exponent)?;
                require_positive("trajectory.wander.f_min_hz", *f_min_hz)?;
                require_positive("trajectory.wander.f_max_hz", *f_max_hz)?;
                if f_max_hz <= f_min_hz {
                    return Err(Error::param(
                        "trajectory.wander.f_max_hz",
                        f_max_hz,
                        format!("a frequency above f_min_hz = {f_min_hz} Hz"),
                    ));
                }
                let psd = Psd::PowerLaw {
                    a: *psd_at_1hz_rad2_per_hz,
                    exponent: *exponent,
                    f_min_hz: *f_min_hz,
                    f_max_hz: *f_max_hz,
                };
                let var = psd.integral(*f_min_hz, *f_max_hz);
                if !var.is_finite() {
                    return Err(Error::param(
                        "trajectory.wander",
                        "a power law whose variance ∫S df overflows",
                        "a finite variance: a smaller psd_at_1hz_rad2_per_hz, exponent or band",
                    ));
                }
                Ok(psd)
            }
        }
    }
}

/// A validated one-sided PSD, rad²/Hz.
#[derive(Debug, Clone, PartialEq)]
pub enum Psd {
    /// Log-log interpolated table, zero outside.
    Table {
        /// Frequencies, Hz.
        f_hz: Vec<f64>,
        /// Values, rad²/Hz.
        s: Vec<f64>,
    },
    /// A·f^exponent on [f_min_hz, f_max_hz].
    PowerLaw {
        /// S(1 Hz).
        a: f64,
        /// Exponent.
        exponent: f64,
        /// Lower band edge, Hz.
        f_min_hz: f64,
        /// Upper band edge, Hz.
        f_max_hz: f64,
    },
}

/// ∫_{lo}^{hi} s0·(f/f0)^b df = s0·f0·∫_{lo/f0}^{hi/f0} u^b du, closed form (b = −1:
/// s0·f0·ln(hi/lo)); written in u = f/f0 so steep exponents do not overflow.
fn power_integral(s0: f64, f0: f64, b: f64, lo: f64, hi: f64) -> f64 {
    if hi <= lo {
        return 0.0;
    }
    let (u0, u1) = (lo / f0, hi / f0);
    if (b + 1.0).abs() < 1e-9 {
        s0 * f0 * (u1 / u0).ln()
    } else {
        s0 * f0 * (u1.powf(b + 1.0) - u0.powf(b + 1.0)) / (b + 1.0)
    }
}

impl Psd {
    /// S(f), rad²/Hz (zero outside the support).
    pub fn eval(&self, f_hz: f64) -> f64 {
        match self {
            Psd::Table { f_hz: fs, s } => {
                let n = fs.len();
                if !(f_hz >= fs[0] && f_hz <= fs[n - 1]) {
                    return 0.0;
                }
                let j = fs.partition_point(|&x| x <= f_hz).clamp(1, n - 1);
                let b = (s[j] / s[j - 1]).ln() / (fs[j] / fs[j - 1]).ln();
                s[j - 1] * (f_hz / fs[j - 1]).powf(b)
            }
            Psd::PowerLaw {
                a,
                exponent,
                f_min_hz,
                f_max_hz,
            } => {
                if f_hz >= *f_min_hz && f_hz <= *f_max_hz {
                    a * f_hz.powf(*exponent)
                } else {
                    0.0
                }
            }
        }
    }

    /// The support [lowest, highest] frequency with S > 0, Hz.
    pub fn support_hz(&self) -> (f64, f64) {
        match self {
            Psd::Table { f_hz, .. } => (f_hz[0], f_hz[f_hz.len() - 1]),
            Psd::PowerLaw {
                f_min_hz, f_max_hz, ..
            } => (*f_min_hz, *f_max_hz),
        }
    }

    /// ∫_{lo}^{hi} S(f) df, rad², exact: every table segment of a log-log interpolation
    /// is itself a power law S_i·(f/f_i)^b_i, integrated in closed form.
    pub fn integral(&self, lo_hz: f64, hi_hz: f64) -> f64 {
        let (s_lo, s_hi) = self.support_hz();
        let lo = lo_hz.max(s_lo);
        let hi = hi_hz.min(s_hi);
        if hi.is_nan() || lo.is_nan() || hi <= lo {
            return 0.0;
        }
        match self {
            Psd::Table { f_hz, s } => {
                let mut sum = 0.0;
                for j in 1..f_hz.len() {
                    let a = lo.max(f_hz[j - 1]);
                    let b = hi.min(f_hz[j]);
                    if b > a {
                        let e = (s[j] / s[j - 1]).ln() / (f_hz[j] / f_hz[j - 1]).ln();
                        sum += power_integral(s[j - 1], f_hz[j - 1], e, a, b);
                    }
                }
                sum
            }
            Psd::PowerLaw { a, exponent, .. } => power_integral(*a, 1.0, *exponent, lo, hi),
        }
    }

    /// The variance per axis, ∫S df, rad².
    pub fn variance_rad2(&self) -> f64 {
        let (lo, hi) = self.support_hz();
        self.integral(lo, hi)
    }
}
