//! Two-dimensional real FFT with plans and scratch reused across bands and frames.
//!
//! Real row transforms (`realfft`), a cache-oblivious transpose (`transpose`), complex
//! column transforms (`rustfft`), rows and columns processed in parallel with rayon. The
//! spectrum layout is `[row frequency, column frequency]` = `[rows, cols/2 + 1]`, the
//! half-plane of [`crate::sensor::FrequencyGrid::real_fft`].

use std::sync::Arc;

use ndarray::Array2;
use num_complex::Complex64;
use rayon::prelude::*;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::{Fft, FftPlanner};

/// Forward and inverse plans for one frame size.
pub struct RealFft2 {
    rows: usize,
    cols: usize,
    r2c: Arc<dyn RealToComplex<f64>>,
    c2r: Arc<dyn ComplexToReal<f64>>,
    col_forward: Arc<dyn Fft<f64>>,
    col_inverse: Arc<dyn Fft<f64>>,
}

impl std::fmt::Debug for RealFft2 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "RealFft2({} x {})", self.rows, self.cols)
    }
}

/// How many column transforms each parallel task handles.
const COLS_PER_TASK: usize = 16;

impl RealFft2 {
    /// Plans transforms of a `rows × cols` real frame (both ≥ 1).
    pub fn new(rows: usize, cols: usize) -> Self {
        let mut rp = RealFftPlanner::<f64>::new();
        let mut cp = FftPlanner::<f64>::new();
        RealFft2 {
            rows,
            cols,
            r2c: rp.plan_fft_forward(cols),
            c2r: rp.plan_fft_inverse(cols),
            col_forward: cp.plan_fft_forward(rows),
            col_inverse: cp.plan_fft_inverse(rows),
        }
    }

    /// Frame shape (rows, cols).
    pub fn shape(&self) -> (usize, usize) {
        (self.rows, self.cols)
    }

    /// Spectrum shape (rows, cols/2 + 1).
    pub fn spectrum_shape(&self) -> (usize, usize) {
        (self.rows, self.cols / 2 + 1)
    }

    /// Forward transform of `input` (`[rows, cols]`, standard layout; used as scratch and
    /// left unspecified) into `out` (`[rows, cols/2+1]`), unnormalised:
    /// `X[v,u] = Σ x[y,x] exp(−2πi (vy/rows + ux/cols))`. `scratch` is resized as needed
    /// and can be reused across calls (no allocation per band).
    pub fn forward(
        &self,
        input: &mut Array2<f64>,
        out: &mut Array2<Complex64>,
        scratch: &mut Vec<Complex64>,
    ) {
        let (rows, cols) = (self.rows, self.cols);
        let hc = cols / 2 + 1;
        assert_eq!(input.dim(), (rows, cols), "RealFft2::forward input shape");
        assert_eq!(out.dim(), (rows, hc), "RealFft2::forward output shape");
        let inp = input.as_slice_mut().expect("standard layout");
        let o = out.as_slice_mut().expect("standard layout");
        // Real transforms of the rows, straight into the output buffer.
        o.par_chunks_mut(hc)
            .zip(inp.par_chunks_mut(cols))
            .for_each_init(
                || self.r2c.make_scratch_vec(),
                |sc, (o, i)| {
                    // Lengths match the plan by construction.
                    let _ = self.r2c.process_with_scratch(i, o, sc);
                },
            );
        scratch.resize(rows * hc, Complex64::new(0.0, 0.0));
        transpose::transpose(o, scratch, hc, rows);
        self.columns(&self.col_forward, scratch);
        transpose::transpose(scratch, o, rows, hc);
    }

    /// Forward transform of a frame produced row by row: `fill(r, row)` writes row `r`
    /// (length `cols`) into a per-worker buffer, which is transformed straight into row `r`
    /// of `out`. Padding, the f32 → f64 conversion and the real row transforms are one pass
    /// over memory; no frame-sized real buffer exists. Otherwise as [`RealFft2::forward`]
    /// (same result, bit for bit, as filling a frame and calling it).
    pub fn forward_rows(
        &self,
        fill: impl Fn(usize, &mut [f64]) + Sync,
        out: &mut Array2<Complex64>,
        scratch: &mut Vec<Complex64>,
    ) {
        let (rows, cols) = (self.rows, self.cols);
        let hc = cols / 2 + 1;
        assert_eq!(out.dim(), (rows, hc), "RealFft2::forward_rows output shape");
        let o = out.as_slice_mut().expect("standard layout");
        o.par_chunks_mut(hc).enumerate().for_each_init(
            || (vec![0.0f64; cols], self.r2c.make_scratch_vec()),
            |(row, sc), (r, o)| {
                fill(r, row);
                // Lengths match the plan by construction.
                let _ = self.r2c.process_with_scratch(row, o, sc);
            },
        );
        scratch.resize(rows * hc, Complex64::new(0.0, 0.0));
        transpose::transpose(o, scratch, hc, rows);
        self.columns(&self.col_forward, scratch);
        transpose::transpose(scratch, o, rows, hc);
    }

    /// Inverse transform of a Hermitian half-plane spectrum (`[rows, cols/2+1]`, used as
    /// scratch) into `out` (`[rows, cols]`), normalised by 1/(rows·cols) so that
    /// `inverse(forward(x)) = x`. `scratch` as in [`RealFft2::forward`].
    pub fn inverse(
        &self,
        spectrum: &mut Array2<Complex64>,
        out: &mut Array2<f64>,
        scratch: &mut Vec<Complex64>,
    ) {
        let (rows, cols) = (self.rows, self.cols);
        let hc = cols / 2 + 1;
        assert_eq!(spectrum.dim(), (rows, hc), "RealFft2::inverse input shape");
        assert_eq!(out.dim(), (rows, cols), "RealFft2::inverse output shape");
        let s = spectrum.as_slice_mut().expect("standard layout");
        scratch.resize(rows * hc, Complex64::new(0.0, 0.0));
        transpose::transpose(s, scratch, hc, rows);
        self.columns(&self.col_inverse, scratch);
        transpose::transpose(scratch, s, rows, hc);
        let norm = 1.0 / (rows * cols) as f64;
        let o = out.as_slice_mut().expect("standard layout");
        o.par_chunks_mut(cols)
            .zip(s.par_chunks_mut(hc))
            .for_each_init(
                || self.c2r.make_scratch_vec(),
                |sc, (o, i)| {
                    // realfft requires exactly real DC (and Nyquist for even lengths) bins; for
                    // the spectrum of a real image they are real up to rounding.
                    i[0].im = 0.0;
                    if cols % 2 == 0 {
                        i[hc - 1].im = 0.0;
                    }
                    let _ = self.c2r.process_with_scratch(i, o, sc);
                    for v in o.iter_mut() {
                        *v *= norm;
                    }
                },
            );
    }

    /// Complex transforms of every length-`rows` run in `data`, in parallel.
    fn columns(&self, fft: &Arc<dyn Fft<f64>>, data: &mut [Complex64]) {
        let rows = self.rows;
        data.par_chunks_mut(rows * COLS_PER_TASK).for_each_init(
            || vec![Complex64::new(0.0, 0.0); fft.get_inplace_scratch_len()],
            |scratch, chunk| fft.process_with_scratch(chunk, scratch),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The forward transform equals the DFT definition summed directly, and the inverse
    /// recovers the input.
    #[test]
    fn matches_direct_dft_and_round_trips() {
        for (rows, cols) in [(6usize, 8usize), (5, 7), (4, 9)] {
            let x = Array2::from_shape_fn((rows, cols), |(r, c)| {
                ((r * 7 + c * 3) % 11) as f64 - 0.3 * c as f64
            });
            let fft = RealFft2::new(rows, cols);
            let mut inp = x.clone();
            let mut spec = Array2::zeros(fft.spectrum_shape());
            let mut scratch = Vec::new();
            fft.forward(&mut inp, &mut spec, &mut scratch);
            for v in 0..rows {
                for u in 0..cols / 2 + 1 {
                    let mut acc = Complex64::new(0.0, 0.0);
                    for y in 0..rows {
                        for xx in 0..cols {
                            let ph = -2.0
                                * std::f64::consts::PI
                                * ((v * y) as f64 / rows as f64 + (u * xx) as f64 / cols as f64);
                            acc += x[[y, xx]] * Complex64::new(ph.cos(), ph.sin());
                        }
                    }
                    assert!(
                        (acc - spec[[v, u]]).norm() < 1e-9,
                        "{rows}x{cols} bin {v},{u}"
                    );
                }
            }
            // Row-by-row filling gives the same spectrum bit for bit.
            let mut spec2 = Array2::zeros(fft.spectrum_shape());
            fft.forward_rows(
                |r, row| row.copy_from_slice(x.row(r).as_slice().unwrap()),
                &mut spec2,
                &mut scratch,
            );
            assert_eq!(spec, spec2);
            let mut back = Array2::zeros((rows, cols));
            fft.inverse(&mut spec, &mut back, &mut scratch);
            for (a, b) in back.iter().zip(x.iter()) {
                assert!((a - b).abs() < 1e-10);
            }
        }
    }
}
