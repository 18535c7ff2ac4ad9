//! Processing of recorded frames: calibration and characterisation of the detector.
//!
//! Everything here works on plain arrays (`Array2<f64>` frames `[row, col]`, `Array3<f64>`
//! stacks `[frame, row, col]`), so it serves simulated and measured data alike:
//!
//! - [`nuc`]: per-pixel polynomial non-uniformity correction (two-point and higher order),
//!   its coefficient files, and the residual non-uniformity figure of merit.
//! - [`bad_pixels`]: out-of-family pixel detection from a calibration response and
//!   replacement by the median of valid neighbours.
//! - [`photon_transfer`]: EMVA 1288 characterisation (conversion gain K, read noise, η,
//!   DSNU, PRNU, saturation capacity), docs/design.md §4.10.
//! - [`netd`]: analytic and measured noise-equivalent temperature difference.
//! - [`temperature`]: DN ↔ radiance calibration and apparent-temperature images,
//!   docs/design.md §4.9.
//! - [`wiener`]: restoration with the sensor's own transfer function on the detector
//!   grid: classic Wiener (FOI report eq. 3.6) and Wiener–Hunt (Laplacian prior).
//! - [`clipped_fill`]: the blurred intensity of small clipped clusters from the PSF's
//!   wings, filled in before a restoration filter.
//! - [`restore_rule`]: the estimated error of each restoration filter and the automatic
//!   choice among them (the input itself included).
//! - [`edge_mtf`]: ISO 12233 slanted-edge MTF measurement.
//! - [`noise_estimate`]: the white-noise level of one image (Immerkær 1996).
//! - [`multi_frame`]: multi-frame restoration of a sequence (register, shift-and-add,
//!   restore on the finer grid).
//! - [`registration`]: sub-pixel translation between frames by phase correlation.
//! - [`shift_and_add`]: registered frames accumulated on a finer grid, and its transfer
//!   function.
//!
//! Frames stored as integers (`Array2<u16>` from an ADC) are converted with [`to_f64`].

pub mod bad_pixels;
pub mod clipped_fill;
pub mod edge_mtf;
pub mod multi_frame;
pub mod netd;
pub mod noise_estimate;
pub mod nuc;
pub mod photon_transfer;
pub mod registration;
pub mod restore_rule;
pub mod shift_and_add;
pub mod temperature;
pub mod wiener;

use ndarray::{Array2, ArrayView2, ArrayView3, Axis};

use crate::error::{Error, Result};

/// Converts an integer frame (e.g. `u16` DN from the ADC) to `f64` for processing.
pub fn to_f64<T: Copy + Into<f64>>(frame: ArrayView2<T>) -> Array2<f64> {
    frame.mapv(Into::into)
}

/// The per-pixel average of a stack of frames `[frame, row, col]` (the "averaged image"
/// NUC and EMVA 1288 spatial statistics are computed from).
///
/// Errors: an empty stack (no frames, rows or columns).
pub fn mean_frame(stack: ArrayView3<f64>) -> Result<Array2<f64>> {
    check_stack("stack", stack)?;
    stack
        .mean_axis(Axis(0))
        .ok_or_else(|| Error::param("stack", "0 frames", "at least one frame"))
}

/// Checks that a stack `[frame, row, col]` has at least one frame and a non-empty frame.
pub(crate) fn check_stack(field: &str, stack: ArrayView3<f64>) -> Result<()> {
    let (f, r, c) = stack.dim();
    if f == 0 || r == 0 || c == 0 {
        return Err(Error::param(
            field,
            format!("shape [{f}, {r}, {c}]"),
            "a stack [frame, row, col] with at least one frame of at least 1×1 pixels",
        ));
    }
    Ok(())
}

/// Checks that a frame is non-empty.
pub(crate) fn check_frame(field: &str, frame: ArrayView2<f64>) -> Result<()> {
    let (r, c) = frame.dim();
    if r == 0 || c == 0 {
        return Err(Error::param(
            field,
            format!("shape [{r}, {c}]"),
            "a frame of at least 1×1 pixels",
        ));
    }
    Ok(())
}

/// Checks that `shape` equals the `expected` frame shape.
pub(crate) fn check_shape(
    field: &str,
    shape: (usize, usize),
    expected: (usize, usize),
) -> Result<()> {
    if shape != expected {
        return Err(Error::param(
            field,
            format!("shape [{}, {}]", shape.0, shape.1),
            format!("the frame shape [{}, {}]", expected.0, expected.1),
        ));
    }
    Ok(())
}

/// Median of a slice (reordered in place by selection, O(n); NaN must have been removed).
/// The mean of the two middle values for an even count; `None` when empty.
pub(crate) fn median_in_place(values: &mut [f64]) -> Option<f64> {
    let n = values.len();
    if n == 0 {
        return None;
    }
    let (lower, upper, _) = values.select_nth_unstable_by(n / 2, f64::total_cmp);
    let upper = *upper;
    Some(if n % 2 == 1 {
        upper
    } else {
        // The other middle value is the largest of the lower half.
        0.5 * (lower.iter().copied().fold(f64::NEG_INFINITY, f64::max) + upper)
    })
}

/// Mean and unbiased (n − 1) variance of an iterator of values, by Welford's update.
/// `None` for fewer than two values.
pub(crate) fn mean_variance(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let mut n = 0usize;
    let mut mean = 0.0;
    let mut m2 = 0.0;
    for v in values {
        n += 1;
        let d = v - mean;
        mean += d / n as f64;
        m2 += d * (v - mean);
    }
    (n >= 2).then(|| (mean, m2 / (n - 1) as f64))
}

/// Ordinary least-squares straight line `y = slope·x + intercept` through `(x, y)` pairs
/// (centred sums). `None` with fewer than two points or no spread in x.
pub(crate) fn fit_line(points: &[(f64, f64)]) -> Option<(f64, f64)> {
    let n = points.len();
    if n < 2 {
        return None;
    }
    let mx = points.iter().map(|p| p.0).sum::<f64>() / n as f64;
    let my = points.iter().map(|p| p.1).sum::<f64>() / n as f64;
    let sxx: f64 = points.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    if sxx.is_nan() || sxx <= 0.0 {
        return None;
    }
    let slope = sxy / sxx;
    Some((slope, my - slope * mx))
}
