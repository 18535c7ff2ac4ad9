//! A measured line of sight: a CSV file of pointing angles against time.
//!
//! ```text
//! # comments (after `#`) and blank lines are skipped
//! t_s, az_rad, el_rad
//! 0.000, 0.0,    0.0
//! 0.010, 1.2e-5, -3e-6
//! ```
//!
//! A header naming the three columns `t_s`, `az_rad`, `el_rad` (in any order) is
//! required; fields are separated by commas (spaces around them are ignored). Every data
//! line holds three finite numbers, times strictly increase, and at least two data lines
//! are needed. Errors name the file, the line number and what was expected; they never
//! quote the line's content.
//!
//! The pointing is interpolated linearly in time. A pointing change moves the image the
//! other way in azimuth and the same way in elevation: with the image axes of
//! [`crate::los`] (x along columns, y down the rows), dx = −Δaz and dy = +Δel (pointing up
//! moves the scene down the rows).

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Largest accepted trajectory file, data lines.
pub const MAX_TRAJECTORY_ROWS: usize = 10_000_000;

/// The pointing samples of a measured trajectory file.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasuredTrajectory {
    path: PathBuf,
    t_s: Vec<f64>,
    az_rad: Vec<f64>,
    el_rad: Vec<f64>,
    /// Line number of each sample, for messages.
    lines: Vec<usize>,
}

const COLUMNS: [&str; 3] = ["t_s", "az_rad", "el_rad"];

impl MeasuredTrajectory {
    /// Reads and checks a trajectory file (see the module documentation for the format).
    pub fn from_csv(path: &Path) -> Result<Self> {
        let text = crate::input::read_text(path)?;
        Self::parse(&text, path)
    }

    /// Parses trajectory text; `path` names it in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let err = |msg: String| Error::format(path, msg);
        let mut order: Option<[usize; 3]> = None;
        let (mut t_s, mut az_rad, mut el_rad, mut lines) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (index, raw) in text.lines().enumerate() {
            let line_no = index + 1;
            let content = raw.split('#').next().unwrap_or("").trim();
            if content.is_empty() {
                continue;
            }
            let fields: Vec<&str> = content.split(',').map(str::trim).collect();
            let Some(order) = order else {
                // The header.
                let mut o = [usize::MAX; 3];
                let ok = fields.len() == 3
                    && fields.iter().enumerate().all(|(i, f)| {
                        match COLUMNS.iter().position(|c| c.eq_ignore_ascii_case(f)) {
                            Some(c) if o[c] == usize::MAX => {
                                o[c] = i;
                                true
                            }
                            _ => false,
                        }
                    });
                if !ok {
                    return Err(err(format!(
                        "line {line_no}: expected the header naming the 3 columns `t_s, az_rad, el_rad` (comma-separated, any order), found {} field(s) that do not name them",
                        fields.len()
                    )));
                }
                order = Some(o);
                continue;
            };
            if fields.len() != 3 {
                return Err(err(format!(
                    "line {line_no}: expected 3 comma-separated numbers (t_s, az_rad, el_rad), found {} field(s)",
                    fields.len()
                )));
            }
            if t_s.len() == MAX_TRAJECTORY_ROWS {
                return Err(err(format!(
                    "line {line_no}: more than {MAX_TRAJECTORY_ROWS} data lines"
                )));
            }
            let mut v = [0.0; 3];
            for (c, name) in COLUMNS.iter().enumerate() {
                let x: f64 = fields[order[c]].parse().map_err(|_| {
                    err(format!(
                        "line {line_no}: column `{name}` is not a number (expected a finite decimal number)"
                    ))
                })?;
                if !x.is_finite() {
                    return Err(err(format!(
                        "line {line_no}: column `{name}` is not finite (NaN or infinite); expected a finite number"
                    )));
                }
                v[c] = x;
            }
            if let (Some(&prev), Some(&prev_line)) = (t_s.last(), lines.last()) {
                if v[0] <= prev {
                    return Err(err(format!(
                        "line {line_no}: t_s does not increase over line {prev_line}; times must strictly increase"
                    )));
                }
            }
            t_s.push(v[0]);
            az_rad.push(v[1]);
            el_rad.push(v[2]);
            lines.push(line_no);
        }
        if order.is_none() {
            return Err(err(
                "no header: expected a first line `t_s, az_rad, el_rad` and at least 2 data lines"
                    .to_string(),
            ));
        }
        if t_s.len() < 2 {
            return Err(err(format!(
                "{} data line(s); a trajectory needs at least 2 (t_s, az_rad, el_rad)",
                t_s.len()
            )));
        }
        Ok(MeasuredTrajectory {
            path: path.to_path_buf(),
            t_s,
            az_rad,
            el_rad,
            lines,
        })
    }

    /// The file it was read from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// First and last sample time, s.
    pub fn time_span_s(&self) -> (f64, f64) {
        (self.t_s[0], self.t_s[self.t_s.len() - 1])
    }

    /// Checks that [t0, t1] lies within the file's time span (no extrapolation), naming
    /// the file, its first and last data lines and the times needed.
    pub fn check_covers(&self, t0_s: f64, t1_s: f64) -> Result<()> {
        let (a, b) = self.time_span_s();
        if t0_s < a || t1_s > b {
            return Err(Error::format(
                &self.path,
                format!(
                    "the trajectory covers t = {a} s (line {}) to {b} s (line {}), but the sequence's exposures span {t0_s} s to {t1_s} s; extend the file or change [clock]",
                    self.lines[0],
                    self.lines[self.lines.len() - 1]
                ),
            ));
        }
        Ok(())
    }

    /// Index j of the segment [t_j, t_{j+1}] holding `t_s` (clamped to the ends).
    fn segment(&self, t_s: f64) -> usize {
        let n = self.t_s.len();
        self.t_s.partition_point(|&x| x <= t_s).clamp(1, n - 1) - 1
    }

    /// The pointing (az, el) at `t_s`, rad, linearly interpolated; held at the first or
    /// last sample outside the file's span.
    pub fn pointing_rad(&self, t_s: f64) -> [f64; 2] {
        let n = self.t_s.len();
        if t_s <= self.t_s[0] {
            return [self.az_rad[0], self.el_rad[0]];
        }
        if t_s >= self.t_s[n - 1] {
            return [self.az_rad[n - 1], self.el_rad[n - 1]];
        }
        let j = self.segment(t_s);
        let w = (t_s - self.t_s[j]) / (self.t_s[j + 1] - self.t_s[j]);
        [
            self.az_rad[j] + w * (self.az_rad[j + 1] - self.az_rad[j]),
            self.el_rad[j] + w * (self.el_rad[j + 1] - self.el_rad[j]),
        ]
    }

    /// The image displacement [−az, +el] at `t_s` relative to the pointing at `t_ref_s`.
    pub fn displacement_rad(&self, t_s: f64, t_ref_s: f64) -> [f64; 2] {
        let p = self.pointing_rad(t_s);
        let r = self.pointing_rad(t_ref_s);
        [-(p[0] - r[0]), p[1] - r[1]]
    }

    /// Range (max − min) of the image-displacement slope per axis over the segments that
    /// meet [t0, t1], rad/s: bounds the chord error of a sampled piecewise-linear path
    /// (see [`crate::los::LineOfSight::window`]).
    pub(crate) fn slope_range(&self, t0_s: f64, t1_s: f64) -> [f64; 2] {
        let (j0, j1) = (self.segment(t0_s), self.segment(t1_s));
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for j in j0..=j1 {
            let dt = self.t_s[j + 1] - self.t_s[j];
            let s = [
                -(self.az_rad[j + 1] - self.az_rad[j]) / dt,
                (self.el_rad[j + 1] - self.el_rad[j]) / dt,
            ];
            for a in 0..2 {
                lo[a] = lo[a].min(s[a]);
                hi[a] = hi[a].max(s[a]);
            }
        }
        // Outside the file the pointing is held: slope 0 joins the range.
        let (a, b) = self.time_span_s();
        if t0_s < a || t1_s > b {
            for axis in 0..2 {
                lo[axis] = lo[axis].min(0.0);
                hi[axis] = hi[axis].max(0.0);
            }
        }
        [hi[0] - lo[0], hi[1] - lo[1]]
    }
}
