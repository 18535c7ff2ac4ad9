//! The sequence clock: when each frame, and each row of a rolling shutter, is exposed.
//!
//! Frame k starts at t_k (a constant rate, t_k = k / rate, or explicit start times); row r
//! of frame k integrates over [t_k + r·t_line, t_k + r·t_line + T] for a rolling shutter
//! and over [t_k, t_k + T] for a global one (T the detector's integration time). A frame's
//! exposure must fit its frame period — (rows − 1)·t_line + T ≤ period for a rolling
//! shutter, T ≤ period for a global one — so successive frames never overlap.

use serde::{Deserialize, Serialize};

use crate::error::{require_positive, Error, Result};

/// Relative slack in the "exposure fits the period" check, so a configuration written to
/// fill the period exactly (T = 1/rate) is not refused for a rounding error.
const FIT_SLACK: f64 = 1e-9;

/// `[clock]` section of a sensor file: the frame times and the shutter.
///
/// ```toml
/// [clock]
/// frame_rate_hz = 50.0          # or: frame_times_s = [0.0, 0.02, 0.041]
/// shutter = "rolling"           # "global" (default) | "rolling"
/// line_time_s = 20e-6           # rolling only
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClockConfig {
    /// Frame rate, Hz (frame k starts at k / rate). Exactly one of `frame_rate_hz` and
    /// `frame_times_s`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame_rate_hz: Option<f64>,
    /// Explicit frame start times, s: finite and strictly increasing, at least as many as
    /// frames are run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame_times_s: Option<Vec<f64>>,
    /// `"global"` (every row exposed at once, the default) or `"rolling"`.
    #[serde(default)]
    pub shutter: Shutter,
    /// Delay between the exposure starts of successive rows, s (rolling shutter only:
    /// required there, an error with a global shutter).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub line_time_s: Option<f64>,
}

/// How the rows of a frame are exposed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Shutter {
    /// Every row integrates over the same window.
    #[default]
    Global,
    /// Row r starts r line times after row 0.
    Rolling,
}

impl ClockConfig {
    /// Checks the section against the detector's `integration_time_s` and `rows`, naming
    /// the field (`clock.frame_rate_hz`, …) and what is valid. Does not need the number of
    /// frames (see [`Clock::new`]).
    pub fn validate(&self, integration_time_s: f64, rows: usize) -> Result<()> {
        require_positive("detector.integration_time_s", integration_time_s)?;
        let line = match (self.shutter, self.line_time_s) {
            (Shutter::Rolling, Some(l)) => require_positive("clock.line_time_s", l)?,
            (Shutter::Rolling, None) => {
                return Err(Error::param(
                    "clock.line_time_s",
                    "missing",
                    "the delay between successive rows' exposures, s (> 0), for shutter = \"rolling\"",
                ))
            }
            (Shutter::Global, Some(l)) => {
                return Err(Error::param(
                    "clock.line_time_s",
                    l,
                    "no line time with shutter = \"global\" (set shutter = \"rolling\" for a row-by-row exposure)",
                ))
            }
            (Shutter::Global, None) => 0.0,
        };
        // Time from the first row's start to the last row's end.
        let exposure = line * rows.saturating_sub(1) as f64 + integration_time_s;
        let what = match self.shutter {
            Shutter::Rolling => format!(
                "a frame period of at least line_time_s × (rows − 1) + integration_time_s = {line} s × {} + {integration_time_s} s = {exposure} s (frames must not overlap)",
                rows.saturating_sub(1)
            ),
            Shutter::Global => format!(
                "a frame period of at least the integration time {integration_time_s} s (frames must not overlap)"
            ),
        };
        match (self.frame_rate_hz, &self.frame_times_s) {
            (Some(rate), None) => {
                require_positive("clock.frame_rate_hz", rate)?;
                let period = 1.0 / rate;
                if exposure > period * (1.0 + FIT_SLACK) {
                    return Err(Error::param(
                        "clock.frame_rate_hz",
                        rate,
                        format!("a rate whose period 1/rate = {period} s allows {what}"),
                    ));
                }
            }
            (None, Some(times)) => {
                if times.is_empty() {
                    return Err(Error::param(
                        "clock.frame_times_s",
                        "[]",
                        "at least one frame start time, s",
                    ));
                }
                for (i, &t) in times.iter().enumerate() {
                    if !t.is_finite() {
                        return Err(Error::param(
                            format!("clock.frame_times_s[{i}]"),
                            t,
                            "a finite time, s",
                        ));
                    }
                    if i > 0 {
                        let prev = times[i - 1];
                        if t <= prev {
                            return Err(Error::param(
                                format!("clock.frame_times_s[{i}]"),
                                t,
                                format!(
                                    "a time greater than frame_times_s[{}] = {prev} s (times must strictly increase)",
                                    i - 1
                                ),
                            ));
                        }
                        let period = t - prev;
                        if exposure > period * (1.0 + FIT_SLACK) {
                            return Err(Error::param(
                                format!("clock.frame_times_s[{i}]"),
                                t,
                                format!(
                                    "a start {period} s after the previous frame's is too soon: {what}"
                                ),
                            ));
                        }
                    }
                }
            }
            (Some(_), Some(_)) | (None, None) => {
                return Err(Error::param(
                    "clock",
                    if self.frame_rate_hz.is_some() {
                        "frame_rate_hz and frame_times_s"
                    } else {
                        "neither frame_rate_hz nor frame_times_s"
                    },
                    "exactly one of `frame_rate_hz` or `frame_times_s`",
                ))
            }
        }
        Ok(())
    }
}

/// The resolved clock of a sequence of `frames` frames.
#[derive(Debug, Clone, PartialEq)]
pub struct Clock {
    starts_s: Vec<f64>,
    integration_time_s: f64,
    line_time_s: Option<f64>,
    rows: usize,
}

impl Clock {
    /// Resolves `cfg` for a detector with `rows` rows and integration time
    /// `integration_time_s`, for `frames` frames. Validates everything
    /// [`ClockConfig::validate`] does, and that `frame_times_s` holds at least `frames`
    /// entries and `frames ≥ 1`.
    pub fn new(
        cfg: &ClockConfig,
        integration_time_s: f64,
        rows: usize,
        frames: usize,
    ) -> Result<Clock> {
        cfg.validate(integration_time_s, rows)?;
        if frames == 0 {
            return Err(Error::param("frames", 0, "at least 1 frame"));
        }
        if rows == 0 {
            return Err(Error::param("detector.rows", 0, "at least 1 row"));
        }
        let starts_s = match (cfg.frame_rate_hz, &cfg.frame_times_s) {
            (Some(rate), _) => {
                crate::limits::check_alloc(
                    "the clock's frame times",
                    &[("frames", frames as u64)],
                    8,
                )?;
                (0..frames).map(|k| k as f64 / rate).collect()
            }
            (None, Some(times)) => {
                if times.len() < frames {
                    return Err(Error::param(
                        "clock.frame_times_s",
                        format!("{} time(s)", times.len()),
                        format!("at least one start time per frame ({frames} frames are run)"),
                    ));
                }
                times[..frames].to_vec()
            }
            (None, None) => {
                return Err(Error::param(
                    "clock",
                    "neither frame_rate_hz nor frame_times_s",
                    "exactly one of `frame_rate_hz` or `frame_times_s`",
                ))
            }
        };
        Ok(Clock {
            starts_s,
            integration_time_s,
            line_time_s: match cfg.shutter {
                Shutter::Rolling => cfg.line_time_s,
                Shutter::Global => None,
            },
            rows,
        })
    }

    /// The clock of a run: `None` when the sensor has no `[clock]` section (a still camera:
    /// every frame is the same instant and nothing moves between frames, as before clocks
    /// existed), else [`Clock::new`].
    pub fn from_config(
        cfg: Option<&ClockConfig>,
        integration_time_s: f64,
        rows: usize,
        frames: usize,
    ) -> Result<Option<Clock>> {
        cfg.map(|c| Clock::new(c, integration_time_s, rows, frames))
            .transpose()
    }

    /// Start of frame `k` (its first row's exposure), s. Panics if `k ≥ frames()`.
    pub fn frame_start_s(&self, k: usize) -> f64 {
        self.starts_s[k]
    }

    /// The exposure window [start, end] of `row` in frame `k`, s.
    pub fn row_window_s(&self, k: usize, row: usize) -> (f64, f64) {
        let start = self.starts_s[k] + self.line_time_s.map_or(0.0, |l| row as f64 * l);
        (start, start + self.integration_time_s)
    }

    /// The integration time T, s.
    pub fn integration_time_s(&self) -> f64 {
        self.integration_time_s
    }

    /// The line time, s: `Some` only for a rolling shutter.
    pub fn line_time_s(&self) -> Option<f64> {
        self.line_time_s
    }

    /// Number of frames.
    pub fn frames(&self) -> usize {
        self.starts_s.len()
    }

    /// Detector rows the clock was made for.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Earliest start and latest end of any row window of any frame, s.
    pub fn span_s(&self) -> (f64, f64) {
        let first = self.row_window_s(0, 0).0;
        let last = self.row_window_s(self.frames() - 1, self.rows - 1).1;
        (first, last)
    }
}
