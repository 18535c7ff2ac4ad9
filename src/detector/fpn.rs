//! Random fields for the fixed-pattern maps: unit-variance normal deviates, white or
//! spatially correlated, drawn once per sensor instance from per-row streams.

use ndarray::Array2;
use rand::RngExt;
use rand_distr::StandardNormal;
use rayon::prelude::*;

use super::rng::{stream, Effect};

/// Truncation of the Gaussian filter kernel, in kernel standard deviations.
const KERNEL_HALF_WIDTH_SIGMAS: f64 = 4.0;

/// One row of `n` standard normal deviates from the stream `(seed, effect, 0, row)`.
pub(crate) fn normal_row(seed: u64, effect: Effect, row: usize, n: usize) -> Vec<f64> {
    let mut rng = stream(seed, effect, 0, row as u64);
    (0..n)
        .map(|_| rng.sample::<f64, _>(StandardNormal))
        .collect()
}

/// One row of `n` uniform deviates in [0, 1) from the stream `(seed, effect, 0, row)`.
pub(crate) fn uniform_row(seed: u64, effect: Effect, row: usize, n: usize) -> Vec<f64> {
    let mut rng = stream(seed, effect, 0, row as u64);
    (0..n).map(|_| rng.random::<f64>()).collect()
}

/// Builds a `rows × cols` array from rows computed in parallel by `row(i)` (each of length
/// `cols`); the result does not depend on the number of threads.
pub(crate) fn par_rows(
    rows: usize,
    cols: usize,
    row: impl Fn(usize) -> Vec<f64> + Sync,
) -> Array2<f64> {
    let data: Vec<f64> = (0..rows)
        .into_par_iter()
        .flat_map_iter(|i| {
            let r = row(i);
            debug_assert_eq!(r.len(), cols);
            r.into_iter()
        })
        .collect();
    // Every row has `cols` values, so the shape always matches.
    Array2::from_shape_vec((rows, cols), data).unwrap_or_else(|_| Array2::zeros((rows, cols)))
}

/// A `rows × cols` field of standard normal deviates of `effect`.
///
/// `correlation_length_px = L = 0`: independent (white) deviates.
/// `L > 0`: white noise on a grid padded by the kernel half-width is convolved with a
/// separable Gaussian kernel of standard deviation `s = L/2` pixels (truncated at 4 s) and
/// divided by the kernel's root-sum-of-squares `Σ k_i²` (the 2-D kernel is `k_i k_j`), so
/// every pixel still has unit variance, and the autocorrelation at lag d is
/// `exp(−d²/(4 s²)) = exp(−(d/L)²)` (the autocorrelation of a Gaussian kernel of variance
/// s² is a Gaussian of variance 2s²). The padding keeps the statistics the same at the
/// borders as in the middle. Cost O(rows · cols · L).
pub(crate) fn unit_field(
    seed: u64,
    effect: Effect,
    rows: usize,
    cols: usize,
    correlation_length_px: f64,
) -> Array2<f64> {
    if correlation_length_px <= 0.0 {
        return par_rows(rows, cols, |i| normal_row(seed, effect, i, cols));
    }
    let s = 0.5 * correlation_length_px;
    let r = (KERNEL_HALF_WIDTH_SIGMAS * s).ceil().max(1.0) as usize;
    let kernel: Vec<f64> = (0..=2 * r)
        .map(|k| {
            let d = k as f64 - r as f64;
            (-d * d / (2.0 * s * s)).exp()
        })
        .collect();
    let sum_sq: f64 = kernel.iter().map(|k| k * k).sum();
    let (prow, pcol) = (rows + 2 * r, cols + 2 * r);
    // Horizontal pass on every padded row: (rows + 2r) × cols.
    let horizontal = par_rows(prow, cols, |i| {
        let white = normal_row(seed, effect, i, pcol);
        (0..cols)
            .map(|j| {
                kernel
                    .iter()
                    .zip(&white[j..j + 2 * r + 1])
                    .map(|(k, w)| k * w)
                    .sum::<f64>()
            })
            .collect()
    });
    // Vertical pass: rows × cols.
    par_rows(rows, cols, |i| {
        let mut out = vec![0.0; cols];
        for (k, kv) in kernel.iter().enumerate() {
            let src = horizontal.row(i + k);
            for (o, v) in out.iter_mut().zip(src.iter()) {
                *o += kv * v;
            }
        }
        for o in &mut out {
            *o /= sum_sq;
        }
        out
    })
}
