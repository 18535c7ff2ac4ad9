//! The line of sight and the sequence clock: when each frame and row is exposed, and
//! where the scene's image is at every instant (docs/motion.md, "Line of sight and clock").
//!
//! **Sign and units.** Everything here is the *image displacement of the scene* on the focal
//! plane, as an object-space angle in rad, `[x, y]`: x along detector columns (+x =
//! increasing column index), y along rows (+y = increasing row index, i.e. downward). A
//! displacement d moves the scene's image by d / IFOV pixels.
//!
//! The displacement d(t) is the sum of
//! - the drift of `[motion]` ([`MotionConfig::rate_rad_s`]): a constant rate v/R (or
//!   `angular_rate_rad_s`, or `smear_rad` / T) along `direction_deg` (from +x toward +y),
//!   d = rate·t;
//! - `[trajectory] pan_rate_rad_s = [x, y]`: a constant rate, d = rate·t;
//! - `[[trajectory.vibration]]`: d_axis = a·sin(2πνt + φ);
//! - `[trajectory.wander]`: a stationary Gaussian process per axis with a given PSD
//!   (module `wander`), from its own random stream;
//! - or, in place of pan, vibration and wander, a measured pointing `[trajectory] file`
//!   (t_s, az_rad, el_rad; [`MeasuredTrajectory`]), linearly interpolated, with dx = −Δaz
//!   and dy = +Δel relative to the pointing at the start of the sequence's span (pointing
//!   right moves the scene left; pointing up moves the scene down the rows).
//!
//! Over an exposure window the path is sampled so that its piecewise-linear interpolant
//! is within a tolerance of d(t) ([`LineOfSight::window`]), and [`WindowPath::otf`] is the
//! exact transfer function of that polyline.

mod clock;
mod csv;
mod path;
mod trajectory;
mod wander;

use std::path::Path;

pub use clock::{Clock, ClockConfig, Shutter};
pub use csv::{MeasuredTrajectory, MAX_TRAJECTORY_ROWS};
pub use path::WindowPath;
pub use trajectory::{LosAxis, MotionConfig, Psd, TrajectoryConfig, VibrationConfig, WanderConfig};
pub use wander::MAX_WANDER_SAMPLES;

use crate::error::{Error, Result};
use wander::Wander;

/// Largest number of segments [`LineOfSight::window`] uses for one exposure window.
pub const MAX_WINDOW_SEGMENTS: usize = 1 << 20;

/// One sinusoid on one axis.
#[derive(Debug, Clone, PartialEq)]
struct Vibration {
    axis: usize,
    amplitude_rad: f64,
    omega_rad_s: f64,
    phase_rad: f64,
}

/// The image displacement d(t), rad `[x, y]`, of a sequence (see the module docs).
#[derive(Debug, Clone)]
pub struct LineOfSight {
    /// Drift + pan, rad/s.
    rate_rad_s: [f64; 2],
    vibration: Vec<Vibration>,
    wander: Option<Wander>,
    /// The measured pointing and the reference time its displacement is taken from.
    measured: Option<(MeasuredTrajectory, f64)>,
}

impl LineOfSight {
    /// Builds the line of sight. `motion` is the sensor's `[motion]` section (the drift),
    /// `integration_time_s` turns its `smear_rad` into a rate; `seed` keys the wander's own
    /// random stream (one per axis, so the wander changes no other effect's draws);
    /// `span_s` is the clock's span ([`Clock::span_s`]; the wander is synthesised over it
    /// with a margin, and a measured file must cover it); `base_dir` resolves a relative
    /// `trajectory.file` (the sensor file's folder). Reads the file, if any.
    pub fn new(
        trajectory: Option<&TrajectoryConfig>,
        motion: Option<&MotionConfig>,
        integration_time_s: f64,
        seed: u64,
        span_s: (f64, f64),
        base_dir: Option<&Path>,
    ) -> Result<Self> {
        let measured = match trajectory.and_then(|t| t.file.as_ref()) {
            Some(file) => {
                let path = match base_dir {
                    Some(dir) => crate::spectrum::resolve_path(dir, file),
                    None => file.clone(),
                };
                Some(MeasuredTrajectory::from_csv(&path)?)
            }
            None => None,
        };
        Self::from_parts(
            trajectory,
            motion,
            integration_time_s,
            seed,
            span_s,
            measured,
        )
    }

    /// As [`LineOfSight::new`], with the measured trajectory already read (e.g. once when
    /// the sensor is built, [`MeasuredTrajectory::from_csv`]) instead of read here: reads
    /// no file. `measured` must be given exactly when `trajectory.file` is.
    pub fn from_parts(
        trajectory: Option<&TrajectoryConfig>,
        motion: Option<&MotionConfig>,
        integration_time_s: f64,
        seed: u64,
        span_s: (f64, f64),
        measured: Option<MeasuredTrajectory>,
    ) -> Result<Self> {
        if !(span_s.0.is_finite() && span_s.1.is_finite() && span_s.1 >= span_s.0) {
            return Err(Error::param(
                "span_s",
                format!("({}, {})", span_s.0, span_s.1),
                "a finite time span (start ≤ end), s",
            ));
        }
        crate::error::require_positive("detector.integration_time_s", integration_time_s)?;
        let mut rate = match motion {
            Some(m) => m.rate_rad_s(integration_time_s)?,
            None => [0.0; 2],
        };
        let mut vibration = Vec::new();
        let mut wander = None;
        if let Some(t) = trajectory {
            t.validate()?;
            if let Some(p) = t.pan_rate_rad_s {
                rate = [rate[0] + p[0], rate[1] + p[1]];
            }
            for v in &t.vibration {
                if v.amplitude_rad > 0.0 {
                    vibration.push(Vibration {
                        axis: v.axis.index(),
                        amplitude_rad: v.amplitude_rad,
                        omega_rad_s: 2.0 * std::f64::consts::PI * v.frequency_hz,
                        phase_rad: v.phase_deg.to_radians(),
                    });
                }
            }
            if let Some(w) = &t.wander {
                let psd = w.psd()?;
                if psd.variance_rad2() > 0.0 {
                    wander = Some(Wander::synthesise(&psd, seed, span_s, integration_time_s)?);
                }
            }
        }
        let file_given = trajectory.is_some_and(|t| t.file.is_some());
        let measured = match (file_given, measured) {
            (true, Some(m)) => {
                m.check_covers(span_s.0, span_s.1)?;
                Some((m, span_s.0))
            }
            (false, None) => None,
            (true, None) => {
                return Err(Error::param(
                    "trajectory.file",
                    "given but not read",
                    "the measured trajectory, read with MeasuredTrajectory::from_csv (or use LineOfSight::new)",
                ))
            }
            (false, Some(_)) => {
                return Err(Error::param(
                    "trajectory.file",
                    "absent while a measured trajectory was passed",
                    "a measured trajectory only with `trajectory.file`",
                ))
            }
        };
        Ok(LineOfSight {
            rate_rad_s: rate,
            vibration,
            wander,
            measured,
        })
    }

    /// No component at all: d(t) ≡ 0.
    pub fn is_still(&self) -> bool {
        self.rate_rad_s == [0.0; 2] && self.is_linear()
    }

    /// Only constant-rate components (drift, pan): the path within every window is the
    /// same straight segment, so the in-frame blur is the same sinc in every frame.
    pub fn is_linear(&self) -> bool {
        self.vibration.is_empty() && self.wander.is_none() && self.measured.is_none()
    }

    /// The constant-rate part (drift + pan), rad/s `[x, y]`.
    pub fn rate_rad_s(&self) -> [f64; 2] {
        self.rate_rad_s
    }

    /// The image displacement d(t), rad `[x, y]`.
    pub fn displacement_rad(&self, t_s: f64) -> [f64; 2] {
        let mut d = [self.rate_rad_s[0] * t_s, self.rate_rad_s[1] * t_s];
        for v in &self.vibration {
            d[v.axis] += v.amplitude_rad * (v.omega_rad_s * t_s + v.phase_rad).sin();
        }
        if let Some(w) = &self.wander {
            let x = w.eval(t_s);
            d = [d[0] + x[0], d[1] + x[1]];
        }
        if let Some((m, t_ref)) = &self.measured {
            let x = m.displacement_rad(t_s, *t_ref);
            d = [d[0] + x[0], d[1] + x[1]];
        }
        d
    }

    /// The path over [t0, t1], sampled at n + 1 equal steps so that its piecewise-linear
    /// interpolant is within `tolerance_rad` of d(t) everywhere in the window.
    ///
    /// Bound used (per axis, combined as a vector): a chord of length h deviates from a
    /// function with |d''| ≤ M₂ by at most h²M₂/8, and from a piecewise-linear function
    /// whose slopes span ΔS by at most h·ΔS/4. M₂ = Σ a(2πν)² over the vibrations plus the
    /// wander interpolant's exact maximum curvature in the window; ΔS is the measured
    /// trajectory's slope range in the window; the rates add nothing. So a linear motion
    /// gets one segment. n is capped at [`MAX_WINDOW_SEGMENTS`]; when the tolerance would
    /// need more, the capped path is returned and its
    /// [`WindowPath::interpolation_bound_rad`] says what was reached ([`Self::try_window`]
    /// returns an error instead).
    pub fn window(&self, t0_s: f64, t1_s: f64, tolerance_rad: f64) -> WindowPath {
        let (n, _) = self.segments_for(t0_s, t1_s, tolerance_rad);
        self.sampled(t0_s, t1_s, n.min(MAX_WINDOW_SEGMENTS))
    }

    /// As [`Self::window`], but an error when the tolerance would need more than
    /// [`MAX_WINDOW_SEGMENTS`] segments, or is not a finite number > 0.
    pub fn try_window(&self, t0_s: f64, t1_s: f64, tolerance_rad: f64) -> Result<WindowPath> {
        crate::error::require_positive("tolerance_rad", tolerance_rad)?;
        let (n, needed) = self.segments_for(t0_s, t1_s, tolerance_rad);
        if n > MAX_WINDOW_SEGMENTS {
            return Err(Error::param(
                "tolerance_rad",
                tolerance_rad,
                format!(
                    "a tolerance reachable with at most {MAX_WINDOW_SEGMENTS} segments over the {} s window (needs {needed:.3e})",
                    t1_s - t0_s
                ),
            ));
        }
        Ok(self.sampled(t0_s, t1_s, n))
    }

    /// (A, B) of the bound A·h² + B·h over [t0, t1].
    fn bound_coefficients(&self, t0_s: f64, t1_s: f64) -> (f64, f64) {
        let mut m2 = [0.0f64; 2];
        for v in &self.vibration {
            m2[v.axis] += v.amplitude_rad * v.omega_rad_s * v.omega_rad_s;
        }
        if let Some(w) = &self.wander {
            let c = w.max_curvature(t0_s, t1_s);
            m2 = [m2[0] + c[0], m2[1] + c[1]];
        }
        let ds = match &self.measured {
            Some((m, _)) => m.slope_range(t0_s, t1_s),
            None => [0.0; 2],
        };
        (m2[0].hypot(m2[1]) / 8.0, ds[0].hypot(ds[1]) / 4.0)
    }

    /// Segments needed for `tolerance_rad` (uncapped, as usize and as a float).
    fn segments_for(&self, t0_s: f64, t1_s: f64, tolerance_rad: f64) -> (usize, f64) {
        let len = (t1_s - t0_s).abs();
        let (a, b) = self.bound_coefficients(t0_s, t1_s);
        if len == 0.0 || (a == 0.0 && b == 0.0) {
            return (1, 1.0);
        }
        // The positive root of A h² + B h = tol, in the form without cancellation.
        let tol = if tolerance_rad > 0.0 {
            tolerance_rad
        } else {
            0.0
        };
        let h = 2.0 * tol / (b + (b * b + 4.0 * a * tol).sqrt());
        let needed = (len / h).ceil().max(1.0);
        if needed.is_finite() && needed < (MAX_WINDOW_SEGMENTS as f64) * 2.0 {
            (needed as usize, needed)
        } else {
            (MAX_WINDOW_SEGMENTS + 1, needed)
        }
    }

    /// The window sampled with `n` equal segments, with its bound.
    fn sampled(&self, t0_s: f64, t1_s: f64, n: usize) -> WindowPath {
        let n = n.max(1);
        let step = (t1_s - t0_s) / n as f64;
        let points: Vec<[f64; 2]> = (0..=n)
            .map(|i| self.displacement_rad(if i == n { t1_s } else { t0_s + i as f64 * step }))
            .collect();
        let (a, b) = self.bound_coefficients(t0_s, t1_s);
        let h = step.abs();
        WindowPath::from_points(&points, a * h * h + b * h)
    }
}
