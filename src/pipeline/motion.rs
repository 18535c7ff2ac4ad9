//! The moving camera of a sequence (docs/motion.md): the sensor's `[clock]` and line of
//! sight ([`crate::los`]) turned into each frame's [`FrameMotion`] for the imaging engine,
//! the transfer-function cascade the engine uses, and the truth table (`los.csv`).
//!
//! Positions are relative to the reference: the line of sight averaged over the exposure
//! of frame 0 of the sequence (for a rolling shutter, of frame 0's middle row), so an
//! unmoving first frame is the still image. Frame `g` of a run is frame
//! `first_frame + g` of the sequence, so a sequence cut into pieces gives the same
//! motion piece by piece.
//!
//! **Blur.** A constant-rate motion (drift from `[motion]`, pan) has the same linear
//! smear in every row of every frame: it stays in the cascade's achromatic product as the
//! motion component (a `[motion]`-only sensor keeps its own, so its first frame is the
//! still camera's image bit for bit) and only the shifts move per frame. Any other motion
//! (vibration, wander, a measured trajectory) blurs each frame with the transfer function
//! of its own path, and the cascade has no motion component.
//!
//! **Rolling shutter.** Every row has its own window, hence its own displacement (applied
//! exactly along x, within [`ROW_POSITION_TOLERANCE_PX`] along y). Rows share a blur while
//! their paths about their means differ by at most the same tolerance from the group's
//! first row ([`WindowPath::max_deviation_rad`]); the group uses its middle row's path.

use crate::error::Result;
use crate::imaging::motion::{FrameMotion, MotionGroup, ROW_POSITION_TOLERANCE_PX};
use crate::los::{Clock, LineOfSight, WindowPath};
use crate::sensor::{Sensor, SystemOtf};

/// A run's clock and line of sight, and how its frames move.
#[derive(Debug)]
pub struct SequenceMotion {
    clock: Clock,
    los: LineOfSight,
    rows: usize,
    ifov_rad: f64,
    first_frame: usize,
    reference_rad: [f64; 2],
    /// Middle of the reference window, s.
    reference_s: f64,
    /// The `[motion]` drift a rendered (4-D) input already holds, rad/s: taken out of the
    /// displacements between frames (zero for a static scene).
    drift_rate_rad_s: [f64; 2],
    blur_in_cascade: bool,
    tolerance_rad: f64,
    path_tolerance_rad: f64,
}

/// How closely the piecewise-linear path the blur is computed from follows the line of
/// sight, detector pixels. Its transfer function then errs by at most
/// 2π·f·0.005 px (0.016 at the detector Nyquist, far less where the path is smooth); a
/// 1 px sinusoid's blur variance comes out 0.7 % low (0.02 px would give 2.6 %).
pub const PATH_TOLERANCE_PX: f64 = 0.005;

/// One line of the truth table: a frame (global shutter) or one row of a frame (rolling
/// shutter), its exposure window, mean displacement and smear, in detector pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct TruthRow {
    /// Frame index within the sequence.
    pub frame: u64,
    /// First and last detector row this line describes.
    pub rows: (usize, usize),
    /// Exposure window start and end, s.
    pub window_s: (f64, f64),
    /// Mean image displacement over the window, detector pixels `[x, y]` (the scene
    /// content moved by +d: x toward higher columns, y toward higher rows).
    pub displacement_px: [f64; 2],
    /// Extent of the path within the window, detector pixels.
    pub smear_px: f64,
}

impl SequenceMotion {
    /// The motion of `frames` frames of the run (sequence frames `options.first_frame …`
    /// of a sequence of `options.sequence_frames`) of `sensor`, the wander drawn from
    /// `options.seed`'s own stream; `None` for a still camera: no `[clock]` section, or
    /// nothing moves.
    ///
    /// A time-varying input (`rendered`: more than one frame, or
    /// [`super::RunOptions::time_varying`]) was rendered by its scene generator with
    /// the platform already moving: `[motion]` then blurs each frame as before but does
    /// not also drift the frames (only `[trajectory]` moves them); without a
    /// `[trajectory]` such an input is imaged as by a still camera.
    pub fn new(
        sensor: &Sensor,
        frames: usize,
        rendered: bool,
        options: &super::RunOptions,
    ) -> Result<Option<Self>> {
        let (first_frame, seed) = (options.first_frame, options.seed);
        let config = sensor.config();
        let Some(clock_cfg) = config.clock.as_ref() else {
            return Ok(None);
        };
        if rendered && config.trajectory.is_none() {
            return Ok(None);
        }
        let d = &config.detector;
        let first = usize::try_from(first_frame).map_err(|_| {
            crate::error::Error::param(
                "first_frame",
                first_frame,
                "an index this machine can address",
            )
        })?;
        let total = first.checked_add(frames).ok_or_else(|| {
            crate::error::Error::param(
                "first_frame",
                first_frame,
                "a frame count that does not overflow",
            )
        })?;
        let whole = options
            .sequence_frames
            .and_then(|n| usize::try_from(n).ok())
            .map_or(total, |n| n.max(total));
        let clock = Clock::new(clock_cfg, d.integration_time_s, d.rows, total)?;
        // The line of sight over the whole sequence, so that its pieces agree.
        let span = Clock::new(clock_cfg, d.integration_time_s, d.rows, whole)?.span_s();
        let los = LineOfSight::from_parts(
            config.trajectory.as_ref(),
            config.motion.as_ref().filter(|m| m.enabled),
            d.integration_time_s,
            seed,
            span,
            sensor.measured_trajectory().cloned(),
        )?;
        if los.is_still() {
            return Ok(None);
        }
        let drift_rate_rad_s = match (config.motion.as_ref().filter(|m| m.enabled), rendered) {
            (Some(m), true) => m.rate_rad_s(d.integration_time_s)?,
            _ => [0.0; 2],
        };
        let ifov_rad = sensor.ifov_rad();
        let tolerance_rad = ROW_POSITION_TOLERANCE_PX * ifov_rad;
        let path_tolerance_rad = PATH_TOLERANCE_PX * ifov_rad;
        let mut motion = SequenceMotion {
            rows: d.rows,
            ifov_rad,
            first_frame: first,
            reference_rad: [0.0; 2],
            reference_s: 0.0,
            drift_rate_rad_s,
            blur_in_cascade: los.is_linear(),
            tolerance_rad,
            path_tolerance_rad,
            clock,
            los,
        };
        let middle = if motion.clock.line_time_s().is_some() {
            motion.rows / 2
        } else {
            0
        };
        let (t0, t1) = motion.clock.row_window_s(0, middle);
        motion.reference_s = 0.5 * (t0 + t1);
        motion.reference_rad = motion
            .los
            .window(t0, t1, motion.path_tolerance_rad)
            .mean_rad;
        Ok(Some(motion))
    }

    /// The transfer-function cascade the imaging engine uses: the sensor's, with the
    /// motion component the constant-rate smear (or none, when each frame's blur comes
    /// from its own path).
    pub fn cascade(&self, sensor: &Sensor) -> SystemOtf {
        let otf = sensor.otf();
        if !self.blur_in_cascade {
            return otf.with_motion_smear(None);
        }
        let has_pan = sensor
            .config()
            .trajectory
            .as_ref()
            .is_some_and(|t| t.pan_rate_rad_s.is_some_and(|p| p != [0.0, 0.0]));
        if !has_pan {
            // `[motion]` alone: its own smear, exactly as the still camera's.
            return otf.clone();
        }
        let r = self.los.rate_rad_s();
        let t = self.clock.integration_time_s();
        otf.with_motion_smear(Some((r[0].hypot(r[1]) * t, r[1].atan2(r[0]))))
    }

    /// The path of detector row `row` during frame `k` of the sequence (not of the run),
    /// and its displacement from the reference (rad): the window's mean, less the drift a
    /// rendered input holds.
    fn window(&self, k: usize, row: usize) -> (WindowPath, [f64; 2]) {
        let (t0, t1) = self.clock.row_window_s(k, row);
        let w = self.los.window(t0, t1, self.path_tolerance_rad);
        let dt = 0.5 * (t0 + t1) - self.reference_s;
        let d = [
            w.mean_rad[0] - self.reference_rad[0] - self.drift_rate_rad_s[0] * dt,
            w.mean_rad[1] - self.reference_rad[1] - self.drift_rate_rad_s[1] * dt,
        ];
        (w, d)
    }

    /// Frame `g`'s motion for the engine (frame `first_frame + g` of the sequence).
    pub fn frame(&self, g: usize) -> FrameMotion {
        self.sequence_frame(self.first_frame + g)
    }

    /// The motion of frame `k` of the sequence, counted from the sequence start, for any
    /// `k` up to the run's last frame: a piece of a sequence (`first_frame` > 0) images the
    /// frames before its first with it to replay the focal plane's persistence.
    pub fn sequence_frame(&self, k: usize) -> FrameMotion {
        if self.clock.line_time_s().is_none() {
            let (w, d) = self.window(k, 0);
            let blur = (!self.blur_in_cascade).then_some(w);
            return FrameMotion::uniform(self.rows, d, blur);
        }
        let (windows, shifts): (Vec<WindowPath>, Vec<[f64; 2]>) =
            (0..self.rows).map(|r| self.window(k, r)).unzip();
        if self.blur_in_cascade {
            return FrameMotion {
                groups: vec![MotionGroup {
                    rows: (0..self.rows).collect(),
                    displacement_rad: shifts,
                    blur: None,
                }],
            };
        }
        let mut groups = Vec::new();
        let mut start = 0;
        while start < self.rows {
            let mut end = start + 1;
            while end < self.rows
                && windows[end].max_deviation_rad(&windows[start]) <= self.tolerance_rad
            {
                end += 1;
            }
            let middle = (start + end - 1) / 2;
            groups.push(MotionGroup {
                rows: (start..end).collect(),
                displacement_rad: shifts[start..end].to_vec(),
                blur: Some(windows[middle].clone()),
            });
            start = end;
        }
        FrameMotion { groups }
    }

    /// The truth table of the run's `frames` frames: one line per frame (global shutter)
    /// or per row of each frame (rolling shutter).
    pub fn truth(&self, frames: usize) -> Vec<TruthRow> {
        let rolling = self.clock.line_time_s().is_some();
        let rows: Vec<usize> = if rolling {
            (0..self.rows).collect()
        } else {
            vec![0]
        };
        let mut out = Vec::with_capacity(frames * rows.len());
        for g in 0..frames {
            for &r in &rows {
                let k = self.first_frame + g;
                let (w, d) = self.window(k, r);
                out.push(TruthRow {
                    frame: k as u64,
                    rows: if rolling { (r, r) } else { (0, self.rows - 1) },
                    window_s: self.clock.row_window_s(k, r),
                    displacement_px: [d[0] / self.ifov_rad, d[1] / self.ifov_rad],
                    smear_px: w.smear_rad() / self.ifov_rad,
                });
            }
        }
        out
    }

    /// Whether the shutter rolls.
    pub fn rolling(&self) -> bool {
        self.clock.line_time_s().is_some()
    }
}

/// The truth table as CSV text (`los.csv`): a header, then one line per [`TruthRow`].
pub fn truth_csv(rows: &[TruthRow]) -> String {
    let mut s = String::from("frame,row_first,row_last,t_start_s,t_end_s,dx_px,dy_px,smear_px\n");
    for r in rows {
        s.push_str(&format!(
            "{},{},{},{:.9},{:.9},{:.6},{:.6},{:.6}\n",
            r.frame,
            r.rows.0,
            r.rows.1,
            r.window_s.0,
            r.window_s.1,
            r.displacement_px[0],
            r.displacement_px[1],
            r.smear_px
        ));
    }
    s
}

/// A plot of the truth table (`trajectory.png`, PNG bytes): the mean displacement x and y (detector
/// pixels) at the middle of every exposure window against time, and the smear; each
/// point is one window (one frame, or one row of a rolling-shutter frame), so the frame
/// windows are where the points are.
pub fn trajectory_png(truth: &[TruthRow]) -> Result<Vec<u8>> {
    use crate::plot::{render_line_plot, LinePlot, Series};
    let t: Vec<f64> = truth
        .iter()
        .map(|r| 0.5 * (r.window_s.0 + r.window_s.1))
        .collect();
    let x: Vec<f64> = truth.iter().map(|r| r.displacement_px[0]).collect();
    let y: Vec<f64> = truth.iter().map(|r| r.displacement_px[1]).collect();
    let s: Vec<f64> = truth.iter().map(|r| r.smear_px).collect();
    render_line_plot(&LinePlot {
        title: "Line of sight: mean image displacement per exposure window",
        x_label: "time at the middle of the window (s)",
        y_label: "detector pixels",
        series: vec![
            Series {
                label: "x displacement",
                x: &t,
                y: &x,
            },
            Series {
                label: "y displacement",
                x: &t,
                y: &y,
            },
            Series {
                label: "smear length",
                x: &t,
                y: &s,
            },
        ],
        markers: Vec::new(),
        y_range: None,
        size_px: (900, 480),
    })
}
