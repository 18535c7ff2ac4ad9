//! Shift-and-add of registered frames onto a grid finer by an integer factor, and the
//! transfer function of the result.
//!
//! Every pixel `(r, c)` of frame `k`, whose content is displaced by `d_k = (dx, dy)`
//! detector pixels from the reference frame ([`crate::processing::registration`]), is a
//! sample of the reference frame's continuous image at `(x, y) = (c − dx, r − dy)`. The
//! fine grid of factor R tiles every detector pixel with R × R cells; fine cell `(i, j)`
//! covers `x ∈ [(j/R) − ½, ((j+1)/R) − ½)` (and likewise y). Each sample is added to the
//! cell it falls in, and every cell holds the mean of its samples — the shift-and-add
//! estimate, which for pure translations and white Gaussian noise is the maximum
//! likelihood image on the fine grid before deblurring (Farsiu, Robinson, Elad & Milanfar
//! 2004, "Fast and robust multiframe super resolution", IEEE Trans. Image Process. 13,
//! 1327, §III). Cells no sample reached (holes) are filled from their filled neighbours
//! (the mean of the filled 8-neighbours, repeated outward until none is left); the weight
//! map counts the samples of each cell (0 for a filled hole). Non-finite samples (dead
//! pixels marked NaN) are skipped.
//!
//! Transfer function: every sample is the detector's image (optics, pixel footprint at the
//! coarse pitch, motion — the sensor's cascade H) at its own position; placing it at the
//! centre of its cell moves it by an error uniform over the cell, whose transfer function
//! is the cell's box, sinc(u)·sinc(v) (u, v in cycles per fine cell; the output-pixel
//! convolution of drizzle with a vanishing drop size, Fruchter & Hook 2002, PASP 114, 144).
//! On the fine grid the result's transfer function is therefore
//!
//! ```text
//! H_fine(u, v) = H(R·u, R·v) · sinc(u) · sinc(v)
//! ```
//!
//! with H in cycles per detector pixel ([`FineGridTransfer`]). Registration errors add a
//! further blur that is not modelled (for the errors of a few hundredths of a pixel the
//! registration reaches, its Gaussian transfer is > 0.99 up to the detector's Nyquist).

use ndarray::{Array2, ArrayView3};

use crate::error::{Error, Result};
use crate::processing::wiener::{DetectorTransfer, SensorTransfer};
use crate::sensor::FrequencyGrid;

/// Largest upsampling factor accepted (beyond it the fine grid is mostly holes for any
/// practical number of frames).
pub const MAX_FACTOR: usize = 8;

/// A shift-and-add image on a fine grid.
#[derive(Debug, Clone, PartialEq)]
pub struct FineImage {
    /// The image, `[R·rows, R·cols]`, in the frames' units.
    pub image: Array2<f64>,
    /// Number of samples averaged in each cell (0: a filled hole).
    pub samples: Array2<u32>,
    /// The upsampling factor R.
    pub factor: usize,
    /// Number of cells filled from their neighbours.
    pub holes_filled: usize,
    /// The mean over the cells holding at least 2 samples of the unbiased variance of
    /// their samples about the cell mean, image units² (`None` when no cell holds 2): the
    /// per-sample error of the fine image — temporal noise plus the spread of the image
    /// across the cell that the positioning error samples, plus registration error.
    pub sample_variance: Option<f64>,
}

impl FineImage {
    /// The mean of 1/n over the cells that hold samples: the fine image's noise variance
    /// per cell is this times the frames' per-pixel variance.
    pub fn mean_inverse_samples(&self) -> f64 {
        let (sum, count) = self
            .samples
            .iter()
            .filter(|n| **n > 0)
            .fold((0.0, 0usize), |(s, c), n| (s + 1.0 / *n as f64, c + 1));
        if count == 0 {
            1.0
        } else {
            sum / count as f64
        }
    }
}

/// Checks an upsampling factor.
pub fn check_factor(factor: usize) -> Result<()> {
    if factor == 0 || factor > MAX_FACTOR {
        return Err(Error::param(
            "upsample",
            factor,
            format!("an integer from 1 to {MAX_FACTOR}"),
        ));
    }
    Ok(())
}

/// Adds the frames of `stack` (`[frame, row, col]`; NaN marks a pixel to skip), displaced
/// by `shifts` (`(dx, dy)` per frame, detector pixels, relative to the reference frame),
/// onto the grid finer by `factor` (module documentation).
///
/// Errors: fewer than 2 frames, a shift count other than the frame count, a non-finite
/// shift, a factor outside 1 … [`MAX_FACTOR`], or no finite sample at all.
pub fn shift_and_add(
    stack: ArrayView3<f64>,
    shifts: &[(f64, f64)],
    factor: usize,
) -> Result<FineImage> {
    check_factor(factor)?;
    let (frames, rows, cols) = stack.dim();
    if frames < 2 {
        return Err(Error::param(
            "frames",
            frames,
            "at least 2 frames to add (restore a single image with the single-frame restore)",
        ));
    }
    if rows == 0 || cols == 0 {
        return Err(Error::param(
            "frame",
            format!("{rows} × {cols} pixels"),
            "a non-empty frame",
        ));
    }
    if shifts.len() != frames {
        return Err(Error::param(
            "shifts",
            format!("{} shifts", shifts.len()),
            format!("one (dx, dy) per frame ({frames})"),
        ));
    }
    if let Some((k, s)) = shifts
        .iter()
        .enumerate()
        .find(|(_, s)| !(s.0.is_finite() && s.1.is_finite()))
    {
        return Err(Error::param(
            format!("shift of frame {k}"),
            format!("({}, {})", s.0, s.1),
            "finite displacements in pixels",
        ));
    }
    let (fr, fc) = (rows * factor, cols * factor);
    let rf = factor as f64;
    let mut sum = Array2::<f64>::zeros((fr, fc));
    let mut sum_sq = Array2::<f64>::zeros((fr, fc));
    let mut samples = Array2::<u32>::zeros((fr, fc));
    for (k, &(dx, dy)) in shifts.iter().enumerate() {
        let frame = stack.index_axis(ndarray::Axis(0), k);
        for ((r, c), v) in frame.indexed_iter() {
            if !v.is_finite() {
                continue;
            }
            let i = ((r as f64 - dy + 0.5) * rf).floor();
            let j = ((c as f64 - dx + 0.5) * rf).floor();
            if i < 0.0 || j < 0.0 || i >= fr as f64 || j >= fc as f64 {
                continue;
            }
            let (i, j) = (i as usize, j as usize);
            sum[[i, j]] += v;
            sum_sq[[i, j]] += v * v;
            samples[[i, j]] += 1;
        }
    }
    if samples.iter().all(|n| *n == 0) {
        return Err(Error::param(
            "frames",
            "no finite sample",
            "frames with finite pixel values",
        ));
    }
    let mut image = Array2::from_shape_fn((fr, fc), |(i, j)| {
        let n = samples[[i, j]];
        if n > 0 {
            sum[[i, j]] / n as f64
        } else {
            f64::NAN
        }
    });
    let (mut var_sum, mut var_cells) = (0.0, 0usize);
    for ((i, j), n) in samples.indexed_iter() {
        if *n >= 2 {
            let n = *n as f64;
            let mean = image[[i, j]];
            var_sum += ((sum_sq[[i, j]] - n * mean * mean) / (n - 1.0)).max(0.0);
            var_cells += 1;
        }
    }
    let sample_variance = (var_cells > 0).then(|| var_sum / var_cells as f64);
    let holes_filled = fill_holes(&mut image);
    Ok(FineImage {
        image,
        samples,
        factor,
        holes_filled,
        sample_variance,
    })
}

/// Fills the NaN cells of `image` with the mean of their finite 8-neighbours, in passes
/// (each pass sees only the previous pass's values) until none is left. Returns the
/// number of cells filled. The image must hold at least one finite cell.
fn fill_holes(image: &mut Array2<f64>) -> usize {
    let (rows, cols) = image.dim();
    let mut filled = 0;
    loop {
        let holes: Vec<(usize, usize, f64)> = image
            .indexed_iter()
            .filter(|(_, v)| v.is_nan())
            .filter_map(|((r, c), _)| {
                let (mut s, mut n) = (0.0, 0usize);
                for i in r.saturating_sub(1)..=(r + 1).min(rows - 1) {
                    for j in c.saturating_sub(1)..=(c + 1).min(cols - 1) {
                        let v = image[[i, j]];
                        if v.is_finite() {
                            s += v;
                            n += 1;
                        }
                    }
                }
                (n > 0).then(|| (r, c, s / n as f64))
            })
            .collect();
        if holes.is_empty() {
            return filled;
        }
        filled += holes.len();
        for (r, c, v) in holes {
            image[[r, c]] = v;
        }
    }
}

/// sinc(x) = sin(πx)/(πx), 1 at 0.
fn sinc(x: f64) -> f64 {
    if x == 0.0 {
        1.0
    } else {
        let p = std::f64::consts::PI * x;
        p.sin() / p
    }
}

/// The transfer function of a shift-and-add image on the grid finer by `factor`:
/// `H(R·u, R·v)·sinc(u)·sinc(v)` (module documentation), u, v in cycles per fine cell,
/// H the sensor's band-weighted cascade in cycles per detector pixel.
#[derive(Debug, Clone, Copy)]
pub struct FineGridTransfer<'a> {
    /// The sensor's transfer function on its detector grid.
    pub coarse: &'a SensorTransfer,
    /// The upsampling factor R.
    pub factor: usize,
}

impl FineGridTransfer<'_> {
    /// H_fine at (u, v), cycles per fine cell.
    pub fn eval(&self, u: f64, v: f64) -> f64 {
        let r = self.factor as f64;
        self.coarse.eval(r * u, r * v) * sinc(u) * sinc(v)
    }
}

impl DetectorTransfer for FineGridTransfer<'_> {
    fn on_grid(&self, rows: usize, cols: usize) -> Result<Array2<f64>> {
        let g = FrequencyGrid::real_fft(rows, cols, 1.0, 1.0);
        Ok(Array2::from_shape_fn((g.fy.len(), g.fx.len()), |(j, k)| {
            self.eval(g.fx[k], g.fy[j])
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array3;

    /// A continuous test image (a smooth 2-D cosine pattern) and frames that sample it at
    /// pixel centres displaced by `shifts`.
    fn pattern(x: f64, y: f64) -> f64 {
        10.0 + (0.9 * x + 0.3).cos() + 0.5 * (0.7 * y - 0.2).sin()
    }

    #[test]
    fn four_half_pixel_dithers_fill_the_factor_two_grid_exactly() {
        // Shifts (0,0), (½,0), (0,½), (½,½): frame k's pixel (r, c) samples the
        // reference image at (c − ½·a, r − ½·b), the lower corner of fine cell
        // (2r + 1 − b, 2c + 1 − a) — every cell gets one sample, no holes, and cell
        // (i, j) holds the pattern at (j/2 − ½, i/2 − ½).
        let (rows, cols) = (6, 7);
        let shifts = [(0.0, 0.0), (0.5, 0.0), (0.0, 0.5), (0.5, 0.5)];
        let stack = Array3::from_shape_fn((4, rows, cols), |(k, r, c)| {
            let (dx, dy) = shifts[k];
            pattern(c as f64 - dx, r as f64 - dy)
        });
        let f = shift_and_add(stack.view(), &shifts, 2).unwrap();
        assert_eq!(f.image.dim(), (12, 14));
        assert_eq!(f.holes_filled, 0);
        assert!(f.samples.iter().all(|n| *n == 1));
        for ((i, j), v) in f.image.indexed_iter() {
            let want = pattern(j as f64 / 2.0 - 0.5, i as f64 / 2.0 - 0.5);
            assert!((v - want).abs() < 1e-12, "cell ({i}, {j})");
        }
        assert!((f.mean_inverse_samples() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn holes_are_filled_and_nan_samples_skipped() {
        // Two frames without relative motion on a factor-2 grid: only the cells holding
        // pixel centres (x = c lies in cell 2c + 1) get samples; the rest are filled from
        // neighbours. A NaN pixel in one frame leaves its cell with one sample.
        let mut stack = Array3::from_shape_fn((2, 4, 4), |(_, r, c)| (r * 4 + c) as f64);
        stack[[1, 2, 2]] = f64::NAN;
        let f = shift_and_add(stack.view(), &[(0.0, 0.0), (0.0, 0.0)], 2).unwrap();
        assert_eq!(f.samples.iter().filter(|n| **n > 0).count(), 16);
        assert_eq!(f.holes_filled, 64 - 16);
        assert_eq!(f.samples[[5, 5]], 1);
        assert_eq!(f.samples[[1, 1]], 2);
        assert!(f.image.iter().all(|v| v.is_finite()));
        // A filled hole lies within the range of the samples.
        assert!(f.image.iter().all(|v| (0.0..=15.0).contains(v)));
        // Identical frames: no scatter within a cell.
        assert_eq!(f.sample_variance, Some(0.0));
        // Mean of 1/n: 15 cells with 2 samples, one with 1.
        assert!((f.mean_inverse_samples() - (15.0 * 0.5 + 1.0) / 16.0).abs() < 1e-12);
    }

    #[test]
    fn bad_inputs_are_refused() {
        let stack = Array3::<f64>::zeros((2, 4, 4));
        let s = [(0.0, 0.0), (0.5, 0.5)];
        assert!(shift_and_add(stack.view(), &s, 0).is_err());
        assert!(shift_and_add(stack.view(), &s, MAX_FACTOR + 1).is_err());
        assert!(shift_and_add(stack.view(), &s[..1], 2).is_err());
        assert!(shift_and_add(stack.slice(ndarray::s![..1, .., ..]), &s[..1], 2).is_err());
        assert!(shift_and_add(stack.view(), &[(0.0, 0.0), (f64::NAN, 0.0)], 2).is_err());
        let nan = Array3::<f64>::from_elem((2, 4, 4), f64::NAN);
        assert!(shift_and_add(nan.view(), &s, 2).is_err());
    }
}
