//! The inverse transform evaluated only on the detector's sampling lattice.
//!
//! A detector sampled every k-th scene sample needs the padded frame's inverse DFT only at
//! rows `r + j·ky` and columns `c + j·kx`. When the padded lengths are multiples of the
//! ratios (the engine chooses them so, [`crate::fft_size::next_fast_multiple`]), those
//! samples are an inverse DFT of length N/k of the *folded* spectrum (the decimation
//! theorem of the DFT: sampling every k-th point aliases the spectrum onto N/k bins),
//!
//! ```text
//! x[r + j·k] = 1/N · Σ_{v'<M} e^{2πi v'j/M} · Y_r[v'],
//! Y_r[v'] = e^{2πi v'r/N} · Σ_{m<k} e^{2πi m r/k} · X[v' + m·M],      M = N/k,
//! ```
//!
//! exactly, so a frame costs column transforms of length M instead of N and row
//! transforms of length N/kx instead of N: about k² less work than the full inverse
//! ([`super::fft::RealFft2::inverse_transposed_rows_with`]) it replaces, with the same
//! values to rounding (tests compare the two). Along the rows the half spectrum of a real
//! row is folded with its Hermitian mirror, `X[N − u] = conj X[u]`.

use std::sync::Arc;

use ndarray::Array2;
use num_complex::Complex64;
use rayon::prelude::*;
use realfft::{ComplexToReal, RealFftPlanner};
use rustfft::{Fft, FftPlanner};

/// The inverse of a real `rows × cols` frame's transposed half spectrum, sampled every
/// `ky`-th row and `kx`-th column (see the [module documentation](self)).
pub struct LatticeInverse {
    rows: usize,
    cols: usize,
    ky: usize,
    kx: usize,
    /// Folded lengths `rows / ky`, `cols / kx`.
    my: usize,
    mx: usize,
    col_inverse: Arc<dyn Fft<f64>>,
    c2r: Arc<dyn ComplexToReal<f64>>,
    /// `e^{2πi t/rows}` and `e^{2πi t/cols}` for t below the length (exact phases by index).
    unit_y: Vec<Complex64>,
    unit_x: Vec<Complex64>,
}

impl std::fmt::Debug for LatticeInverse {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "LatticeInverse({} x {} every {} x {})",
            self.rows, self.cols, self.ky, self.kx
        )
    }
}

fn unit_circle(n: usize) -> Vec<Complex64> {
    (0..n)
        .map(|t| Complex64::from_polar(1.0, 2.0 * std::f64::consts::PI * t as f64 / n as f64))
        .collect()
}

/// Fills a column's factors: `(u, out)` with `out` one factor per row frequency.
pub type ColumnFill<'a> = &'a (dyn Fn(usize, &mut [Complex64]) + Sync);

/// What the column fold multiplies the spectrum by before folding: per column frequency
/// u, a factor for every row frequency (e.g. a motion blur), and one factor per row
/// frequency shared by all columns (e.g. a sub-sample phase ramp).
pub struct ColumnFactors<'a> {
    /// Fills `out` (length rows) with column u's factors; `None`: all ones.
    pub per_column: Option<ColumnFill<'a>>,
    /// One factor per row frequency (length rows); `None`: all ones.
    pub per_row: Option<&'a [Complex64]>,
}

impl LatticeInverse {
    /// The lattice inverse of a `frame = (rows, cols)` frame sampled every
    /// `k = (ky, kx)` samples; `None` when a length is not a multiple of its ratio (or a
    /// ratio is 0, or both are 1: the full inverse is then the cheaper route).
    pub fn new(frame: (usize, usize), k: (usize, usize)) -> Option<Self> {
        let ((rows, cols), (ky, kx)) = (frame, k);
        if ky == 0 || kx == 0 || rows == 0 || cols == 0 || (ky == 1 && kx == 1) {
            return None;
        }
        if rows % ky != 0 || cols % kx != 0 {
            return None;
        }
        let (my, mx) = (rows / ky, cols / kx);
        Some(LatticeInverse {
            rows,
            cols,
            ky,
            kx,
            my,
            mx,
            col_inverse: FftPlanner::new().plan_fft_inverse(my),
            c2r: RealFftPlanner::<f64>::new().plan_fft_inverse(mx),
            unit_y: unit_circle(rows),
            unit_x: unit_circle(cols),
        })
    }

    /// The number of lattice rows and columns, `(rows / ky, cols / kx)`.
    pub fn lattice_shape(&self) -> (usize, usize) {
        (self.my, self.mx)
    }

    /// Frame rows `wanted` (row i of the result is frame row `wanted[i]`), each at the
    /// frame columns `x_start[i] + j·kx` for `j < n_cols`, of the real frame whose half
    /// spectrum, held transposed (`spec_t[u·rows + v]`), times `factors` is the frame's
    /// spectrum. `row_hook(i, row)` may change row i's half spectrum (after the column
    /// transforms, before its row transform), as
    /// [`super::fft::RealFft2::inverse_transposed_rows_with`] allows. `spec_t` is not
    /// changed.
    ///
    /// # Panics
    /// If the lengths do not match the frame, a wanted row is outside it, `x_start` does
    /// not give one start per wanted row, or `n_cols` exceeds `cols / kx` (caller errors).
    pub fn sample(
        &self,
        spec_t: &[Complex64],
        factors: &ColumnFactors<'_>,
        wanted: &[usize],
        x_start: &[usize],
        n_cols: usize,
        row_hook: impl Fn(usize, &mut [Complex64]) + Sync,
    ) -> Array2<f64> {
        let (rows, cols, my) = (self.rows, self.cols, self.my);
        let hc = cols / 2 + 1;
        assert_eq!(
            spec_t.len(),
            rows * hc,
            "LatticeInverse::sample input length"
        );
        assert_eq!(
            wanted.len(),
            x_start.len(),
            "LatticeInverse::sample x_start"
        );
        assert!(n_cols <= self.mx, "LatticeInverse::sample n_cols");
        assert!(
            wanted.iter().all(|&y| y < rows),
            "LatticeInverse::sample row"
        );
        let mut out = Array2::<f64>::zeros((wanted.len(), n_cols));
        let zero = Complex64::new(0.0, 0.0);
        let mut residues: Vec<usize> = wanted.iter().map(|w| w % self.ky).collect();
        residues.sort_unstable();
        residues.dedup();
        let mut folded = vec![zero; hc * my];
        for r in residues {
            // e^{2πi m r/k} for alias m = v / M times the per-row factor of v, and
            // e^{2πi v' r/N} for every folded bin v'.
            let alias: Vec<Complex64> = (0..rows)
                .map(|v| {
                    let a = self.unit_y[((v / my) * my * r) % rows];
                    factors.per_row.map_or(a, |p| a * p[v])
                })
                .collect();
            let ramp: Vec<Complex64> = (0..my).map(|v| self.unit_y[(v * r) % rows]).collect();
            folded.par_chunks_mut(my).enumerate().for_each_init(
                || {
                    vec![
                        zero;
                        if factors.per_column.is_some() {
                            rows
                        } else {
                            0
                        }
                    ]
                },
                |h, (u, dst)| {
                    let col = &spec_t[u * rows..(u + 1) * rows];
                    dst.fill(zero);
                    if let Some(f) = factors.per_column {
                        f(u, h);
                        for ((src, hs), al) in col
                            .chunks_exact(my)
                            .zip(h.chunks_exact(my))
                            .zip(alias.chunks_exact(my))
                        {
                            for (((d, s), hv), a) in dst.iter_mut().zip(src).zip(hs).zip(al) {
                                *d += s * hv * a;
                            }
                        }
                    } else {
                        for (src, al) in col.chunks_exact(my).zip(alias.chunks_exact(my)) {
                            for ((d, s), a) in dst.iter_mut().zip(src).zip(al) {
                                *d += s * a;
                            }
                        }
                    }
                    for (d, p) in dst.iter_mut().zip(&ramp) {
                        *d *= p;
                    }
                },
            );
            folded.par_chunks_mut(my * 16).for_each_init(
                || vec![zero; self.col_inverse.get_inplace_scratch_len()],
                |sc, block| self.col_inverse.process_with_scratch(block, sc),
            );
            let folded: &[Complex64] = &folded;
            let rows_here: Vec<usize> = (0..wanted.len())
                .filter(|&i| wanted[i] % self.ky == r)
                .collect();
            let done: Vec<(usize, Vec<f64>)> = rows_here
                .par_iter()
                .map_init(
                    || {
                        (
                            vec![zero; hc],
                            vec![zero; self.mx / 2 + 1],
                            self.c2r.make_scratch_vec(),
                            vec![0.0; self.mx],
                        )
                    },
                    |(row, half, sc, line), &i| {
                        let j = (wanted[i] - r) / self.ky;
                        for (u, z) in row.iter_mut().enumerate() {
                            *z = folded[u * my + j];
                        }
                        row_hook(i, row);
                        self.fold_row(row, x_start[i], half);
                        let _ = self.c2r.process_with_scratch(half, line, sc);
                        (i, line[..n_cols].to_vec())
                    },
                )
                .collect();
            let norm = 1.0 / (rows * cols) as f64;
            for (i, line) in done {
                for (o, v) in out.row_mut(i).iter_mut().zip(line) {
                    *o = v * norm;
                }
            }
        }
        out
    }

    /// Folds one row's half spectrum (`cols/2+1` bins, the imaginary parts of the DC and
    /// an even row's Nyquist bin ignored as the real inverse ignores them) shifted by `c`
    /// samples onto the `cols/kx/2+1` bins of the lattice row.
    fn fold_row(&self, row: &mut [Complex64], c: usize, half: &mut [Complex64]) {
        let (cols, mx) = (self.cols, self.mx);
        let hc = row.len();
        row[0].im = 0.0;
        if cols % 2 == 0 {
            row[hc - 1].im = 0.0;
        }
        let c = c % cols;
        for (q, h) in half.iter_mut().enumerate() {
            let mut acc = Complex64::new(0.0, 0.0);
            for m in 0..self.kx {
                let u = q + m * mx;
                let z = if u < hc { row[u] } else { row[cols - u].conj() };
                acc += z * self.unit_x[(u * c) % cols];
            }
            *h = acc;
        }
        half[0].im = 0.0;
        if mx % 2 == 0 {
            half[mx / 2].im = 0.0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::imaging::fft::RealFft2;

    fn frame(rows: usize, cols: usize) -> Array2<f64> {
        Array2::from_shape_fn((rows, cols), |(r, c)| {
            ((r * 7 + c * 3) % 11) as f64 - 0.3 * c as f64 + (0.37 * r as f64).sin()
        })
    }

    /// The transposed half spectrum of a frame.
    fn spectrum_t(x: &Array2<f64>) -> Vec<Complex64> {
        let (rows, cols) = x.dim();
        let fft = RealFft2::<f64>::new(rows, cols);
        let mut inp = x.clone();
        let mut spec = Array2::zeros(fft.spectrum_shape());
        fft.forward(&mut inp, &mut spec, &mut Vec::new());
        let hc = cols / 2 + 1;
        let mut t = vec![Complex64::new(0.0, 0.0); rows * hc];
        for v in 0..rows {
            for u in 0..hc {
                t[u * rows + v] = spec[[v, u]];
            }
        }
        t
    }

    /// Sampling the inverse on the lattice returns the frame's own samples (the forward
    /// transform's input, an independent truth), for even and odd lengths, ratios 2–4,
    /// several residues and column starts.
    #[test]
    fn lattice_samples_are_the_frame_samples() {
        for (rows, cols, ky, kx) in [
            (12usize, 18usize, 2usize, 3usize),
            (15, 20, 3, 4),
            (16, 16, 4, 2),
            (9, 10, 3, 1),
            (10, 9, 1, 3),
        ] {
            let x = frame(rows, cols);
            let spec = spectrum_t(&x);
            let li = LatticeInverse::new((rows, cols), (ky, kx)).expect("divisible");
            let wanted: Vec<usize> = (0..rows).step_by(2).collect();
            let starts: Vec<usize> = wanted.iter().map(|w| w % kx).collect();
            let n = cols / kx - 1;
            let none = ColumnFactors {
                per_column: None,
                per_row: None,
            };
            let got = li.sample(&spec, &none, &wanted, &starts, n, |_, _| {});
            for (i, &w) in wanted.iter().enumerate() {
                for j in 0..n {
                    let want = x[[w, (starts[i] + j * kx) % cols]];
                    assert!(
                        (got[[i, j]] - want).abs() < 1e-11,
                        "{rows}x{cols} k {ky}x{kx}: row {w} col {j}: {} vs {want}",
                        got[[i, j]]
                    );
                }
            }
        }
    }

    /// With factors and a row hook, the lattice equals the full inverse of the changed
    /// spectrum sampled on the lattice.
    #[test]
    fn factors_and_hook_match_the_full_inverse() {
        let (rows, cols, ky, kx) = (12usize, 20usize, 3usize, 2usize);
        let hc = cols / 2 + 1;
        let x = frame(rows, cols);
        let spec = spectrum_t(&x);
        let per_col = |u: usize, out: &mut [Complex64]| {
            for (v, o) in out.iter_mut().enumerate() {
                *o = Complex64::from_polar(1.0 / (1.0 + 0.1 * (u + v) as f64), 0.3 * v as f64);
            }
        };
        let per_row: Vec<Complex64> = (0..rows)
            .map(|v| Complex64::from_polar(1.0, -0.2 * v as f64))
            .collect();
        let hook = |i: usize, row: &mut [Complex64]| {
            for (u, z) in row.iter_mut().enumerate() {
                *z *= Complex64::from_polar(1.0, 0.05 * (i * u) as f64);
            }
        };
        // Truth: the same spectrum changed in full, inverted in full, then sampled.
        let mut full = spec.clone();
        let mut h = vec![Complex64::new(0.0, 0.0); rows];
        for u in 0..hc {
            per_col(u, &mut h);
            for v in 0..rows {
                full[u * rows + v] *= h[v] * per_row[v];
            }
        }
        let wanted = vec![1usize, 4, 7, 10, 2];
        let starts = vec![1usize, 0, 1, 3, 2];
        let fft = RealFft2::<f64>::new(rows, cols);
        let mut img = Array2::zeros((wanted.len(), cols));
        fft.inverse_transposed_rows_with(&mut full, &wanted, &mut img, hook);
        let li = LatticeInverse::new((rows, cols), (ky, kx)).expect("divisible");
        let f = ColumnFactors {
            per_column: Some(&per_col),
            per_row: Some(&per_row),
        };
        let got = li.sample(&spec, &f, &wanted, &starts, 8, hook);
        for i in 0..wanted.len() {
            for j in 0..8 {
                let want = img[[i, (starts[i] + j * kx) % cols]];
                assert!((got[[i, j]] - want).abs() < 1e-11, "{i},{j}");
            }
        }
    }

    /// Lengths that are not multiples of the ratio have no lattice inverse.
    #[test]
    fn indivisible_lengths_have_none() {
        assert!(LatticeInverse::new((10, 12), (3, 2)).is_none());
        assert!(LatticeInverse::new((12, 12), (1, 1)).is_none());
        assert!(LatticeInverse::new((12, 12), (0, 2)).is_none());
    }
}
