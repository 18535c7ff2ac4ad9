//! Multi-frame restoration of a sequence: register, shift-and-add onto a finer grid, then
//! Wiener-restore with the fine grid's transfer function.
//!
//! 1. **Registration**: the displacement of every frame's content relative to frame 0, by
//!    phase correlation ([`crate::processing::registration`]) or given (the truth table
//!    `los.csv` of an eoir sequence). Pixels marked NaN (dead pixels) are replaced by the
//!    median of their neighbours for the registration only.
//! 2. **Shift-and-add** onto the grid finer by R ([`crate::processing::shift_and_add`]):
//!    a sequence whose displacements spread over the detector pixel samples the image at
//!    sub-pixel phases a single frame lacks, so frequencies above the detector's Nyquist
//!    (½ cycle per pixel) that alias in every frame are resolved on the fine grid (up to
//!    R/2 cycles per detector pixel).
//! 3. **Restoration**: [`wiener_restore`] of the fine image with
//!    `H_fine(u, v) = H(R·u, R·v)·sinc(u)·sinc(v)` ([`FineGridTransfer`]) — the footprint of
//!    the coarse pixel stays in it. The noise of a fine cell holding n samples has variance
//!    σ²/n; the model rule uses the frames' per-pixel variance σ² times the mean of 1/n
//!    over the cells ([`FineImage::mean_inverse_samples`]).

use ndarray::{Array3, ArrayView3, Axis};

use crate::error::{Error, Result};
use crate::processing::bad_pixels::BadPixelMap;
use crate::processing::registration::{register_stack, Translation};
use crate::processing::shift_and_add::{check_factor, shift_and_add, FineGridTransfer, FineImage};
use crate::processing::wiener::{wiener_restore, NoiseRule, Restoration, SensorTransfer};

/// How the noise-to-signal ratio of the fine-grid restoration is chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SequenceNoise {
    /// The scatter of the samples within the fine cells
    /// ([`FineImage::sample_variance`]) times the mean of 1/n: measured on the data, it
    /// holds the temporal noise and the errors of placing samples at cell centres and of
    /// the registration, which the sensor's noise model does not know.
    Scatter,
    /// The frames' per-pixel noise variance (image units²); the fine image's is this times
    /// the mean of 1/n.
    Model {
        /// Per-pixel noise variance of one frame, image units squared.
        frame_variance: f64,
    },
    /// A constant NSR.
    Constant(f64),
}

impl SequenceNoise {
    /// The rule a user names: a constant `nsr`, else `noise` = `auto` (the in-cell
    /// scatter) or `model` (one frame's temporal and quantisation noise of `model` at the
    /// mean of `signal`, the stack in DN above the black level; NaN samples skipped).
    /// Any other name is an error listing the valid ones.
    pub fn from_rule(
        nsr: Option<f64>,
        noise: &str,
        signal: ArrayView3<f64>,
        model: &crate::detector::DetectorModel,
    ) -> Result<Self> {
        Ok(match (nsr, noise) {
            (Some(x), _) => SequenceNoise::Constant(x),
            (None, "model") => {
                let (sum, n) = signal
                    .iter()
                    .filter(|v| v.is_finite())
                    .fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
                let mean_e = (sum / n.max(1) as f64 / model.gain_dn_per_e()).max(0.0);
                SequenceNoise::Model {
                    frame_variance: model.temporal_noise_dn(mean_e).powi(2)
                        + model.quantisation_noise_dn().powi(2),
                }
            }
            (None, "auto") => SequenceNoise::Scatter,
            (None, other) => return Err(Error::param("noise", other, "`auto` or `model`")),
        })
    }

    /// `scatter`, `model` or `constant` (restore.json's `noise_rule`).
    pub fn name(&self) -> &'static str {
        match self {
            SequenceNoise::Scatter => "scatter",
            SequenceNoise::Model { .. } => "model",
            SequenceNoise::Constant(_) => "constant",
        }
    }
}

/// What a multi-frame restoration did.
#[derive(Debug, Clone)]
pub struct SequenceRestoration {
    /// Displacement of every frame's content relative to frame 0 (estimated or given).
    pub shifts: Vec<Translation>,
    /// The shift-and-add image before restoration.
    pub fine: FineImage,
    /// The Wiener restoration of the fine image (`image` is `[R·rows, R·cols]`).
    pub restoration: Restoration,
    /// Per-cell noise variance the restoration used (scatter and model rules), image
    /// units².
    pub fine_noise_variance: Option<f64>,
}

/// Checks a stack for multi-frame restoration: at least 2 frames of at least 8 × 8
/// pixels.
pub fn check_sequence(stack: ArrayView3<f64>) -> Result<()> {
    let (frames, rows, cols) = stack.dim();
    if frames < 2 {
        return Err(Error::param(
            "frames",
            frames,
            "a sequence of at least 2 frames (restore a single image with the single-frame restore)",
        ));
    }
    let min = crate::processing::registration::MIN_SIDE_PX;
    if rows < min || cols < min {
        return Err(Error::param(
            "frame",
            format!("{rows} × {cols} pixels"),
            format!("frames of at least {min} × {min} pixels"),
        ));
    }
    Ok(())
}

/// The stack with every non-finite pixel replaced by the median of its valid neighbours
/// ([`crate::processing::bad_pixels::replace`]), for registration, which needs finite
/// values. (A constant fill would put a fixed pattern in every frame, which correlates at
/// zero displacement and pulls the estimates toward it.)
fn finite_for_registration(stack: ArrayView3<f64>) -> Result<Array3<f64>> {
    let mut out = stack.to_owned();
    for (k, mut frame) in out.axis_iter_mut(Axis(0)).enumerate() {
        if frame.iter().all(|v| v.is_finite()) {
            continue;
        }
        if !frame.iter().any(|v| v.is_finite()) {
            return Err(Error::param(
                format!("frame {k}"),
                "no finite pixel",
                "frames with finite pixel values",
            ));
        }
        let map = BadPixelMap::from_mask(frame.mapv(|v| !v.is_finite()));
        let filled = crate::processing::bad_pixels::replace(frame.view(), &map)?;
        frame.assign(&filled);
    }
    Ok(out)
}

/// Restores the sequence `stack` (`[frame, row, col]`, NaN marking pixels to skip) on
/// the grid finer by `factor`: registration by phase correlation when `shifts` is `None`
/// (else the given `(dx, dy)` per frame, relative to frame 0), shift-and-add, and Wiener
/// restoration with `transfer` (the recording sensor's) on the fine grid.
///
/// Errors: fewer than 2 frames, frames smaller than 8 × 8, a factor outside 1 … 8, a
/// shift count other than the frame count, a negative or non-finite noise figure, and
/// those of the steps.
pub fn restore_sequence(
    stack: ArrayView3<f64>,
    shifts: Option<&[(f64, f64)]>,
    factor: usize,
    transfer: &SensorTransfer,
    noise: SequenceNoise,
) -> Result<SequenceRestoration> {
    check_sequence(stack)?;
    check_factor(factor)?;
    if let SequenceNoise::Model { frame_variance } = noise {
        if !(frame_variance.is_finite() && frame_variance > 0.0) {
            return Err(Error::param(
                "noise variance",
                frame_variance,
                "a finite number > 0 (image units squared)",
            ));
        }
    }
    let shifts: Vec<Translation> = match shifts {
        Some(s) => {
            if s.len() != stack.dim().0 {
                return Err(Error::param(
                    "shifts",
                    format!("{} shifts", s.len()),
                    format!("one (dx, dy) per frame ({})", stack.dim().0),
                ));
            }
            s.iter()
                .map(|&(dx_px, dy_px)| Translation {
                    dx_px,
                    dy_px,
                    peak: f64::NAN,
                })
                .collect()
        }
        None => register_stack(finite_for_registration(stack)?.view(), 0)?,
    };
    let pairs: Vec<(f64, f64)> = shifts.iter().map(|t| (t.dx_px, t.dy_px)).collect();
    let fine = shift_and_add(stack, &pairs, factor)?;
    let h = FineGridTransfer {
        coarse: transfer,
        factor,
    };
    let (rule, fine_noise_variance) = match noise {
        SequenceNoise::Scatter => {
            let Some(s) = fine.sample_variance.filter(|v| *v > 0.0) else {
                return Err(Error::param(
                    "noise",
                    "no fine cell holds two differing samples",
                    "a sequence with enough frames for repeated samples per cell (or give the noise model or a constant NSR)",
                ));
            };
            let v = s * fine.mean_inverse_samples();
            (NoiseRule::Model { noise_variance: v }, Some(v))
        }
        SequenceNoise::Constant(x) => (NoiseRule::Constant(x), None),
        SequenceNoise::Model { frame_variance } => {
            let v = frame_variance * fine.mean_inverse_samples();
            (NoiseRule::Model { noise_variance: v }, Some(v))
        }
    };
    let restoration = wiener_restore(fine.image.view(), &h, rule)?;
    Ok(SequenceRestoration {
        shifts,
        fine,
        restoration,
        fine_noise_variance,
    })
}
