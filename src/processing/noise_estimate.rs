//! The white-noise level of a single image, without a noise-only frequency band.
//!
//! Immerkær (1996, "Fast noise variance estimation", Computer Vision and Image
//! Understanding 64(2), 300–302) filters the image with the difference of two discrete
//! Laplacians,
//!
//! ```text
//!     ⎡ 1 −2  1⎤
//! N = ⎢−2  4 −2⎥ ,
//!     ⎣ 1 −2  1⎦
//! ```
//!
//! which annihilates every polynomial of degree ≤ 1 in each coordinate (constants, ramps
//! and bilinear surfaces) and, on white noise of variance σ², returns a value of
//! variance Σ N² σ² = 36 σ². Immerkær takes the mean absolute response,
//! σ = √(π/2) · ⟨|N ⊛ I|⟩ / 6; edges and texture raise that mean. Here the scale is the
//! median absolute response instead (Gaussian: median |x| = 0.6745 σ_x, so
//! σ = 1.4826 · median|N ⊛ I| / 6), which ignores the minority of pixels on edges and in
//! texture — the "flat regions" of the image — without a separate edge detector, and
//! pixels whose 3 × 3 window touches a masked pixel (dead, hot, saturated, non-finite)
//! are left out. For signal-dependent (shot) noise the result is the noise of a typical
//! pixel.
//!
//! The blur of a camera makes its image smooth, so the operator sees noise only, unlike
//! the FOI report's §3.6 rule (noise power where |H| is negligible), which has nothing to
//! measure when the transfer function stays large up to Nyquist.

use ndarray::ArrayView2;

use super::bad_pixels::{BadPixelMap, MAD_TO_SIGMA};
use super::{check_shape, median_in_place};
use crate::error::{Error, Result};

/// √(Σ N²) of Immerkær's 3 × 3 operator: the rms response to unit white noise.
pub const IMMERKAER_GAIN: f64 = 6.0;

/// A noise estimate and the number of pixels it rests on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseEstimate {
    /// Per-pixel noise standard deviation, image units.
    pub sigma: f64,
    /// Pixels whose operator response entered the median.
    pub pixels: usize,
}

/// The per-pixel white-noise σ of `image` by Immerkær's operator with a median scale
/// (module documentation), skipping every pixel whose 3 × 3 window holds a pixel flagged
/// in `mask` or a non-finite value.
///
/// Errors: an image smaller than 3 × 3, a mask of another shape, or fewer than 9 usable
/// pixels.
pub fn immerkaer_sigma(
    image: ArrayView2<f64>,
    mask: Option<&BadPixelMap>,
) -> Result<NoiseEstimate> {
    let (rows, cols) = image.dim();
    if rows < 3 || cols < 3 {
        return Err(Error::param(
            "image",
            format!("{rows} × {cols} pixels"),
            "at least 3 × 3 pixels for a noise estimate",
        ));
    }
    if let Some(m) = mask {
        check_shape("noise mask", m.dim(), (rows, cols))?;
    }
    const K: [[f64; 3]; 3] = [[1.0, -2.0, 1.0], [-2.0, 4.0, -2.0], [1.0, -2.0, 1.0]];
    let mut responses = Vec::with_capacity((rows - 2) * (cols - 2));
    for r in 1..rows - 1 {
        'pixel: for c in 1..cols - 1 {
            let mut acc = 0.0;
            for (di, krow) in K.iter().enumerate() {
                for (dj, k) in krow.iter().enumerate() {
                    let (i, j) = (r + di - 1, c + dj - 1);
                    let v = image[[i, j]];
                    if !v.is_finite() || mask.is_some_and(|m| m.is_bad(i, j)) {
                        continue 'pixel;
                    }
                    acc += k * v;
                }
            }
            responses.push(acc.abs());
        }
    }
    let pixels = responses.len();
    if pixels < 9 {
        return Err(Error::param(
            "image",
            format!("{pixels} pixels with a clean 3 × 3 neighbourhood"),
            "at least 9 unmasked pixels to estimate the noise",
        ));
    }
    let med = median_in_place(&mut responses).unwrap_or(0.0);
    Ok(NoiseEstimate {
        sigma: MAD_TO_SIGMA * med / IMMERKAER_GAIN,
        pixels,
    })
}
