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
//!
//! **Rows that share their columns** ([`LatticeInverse::sample_common_x`], a global
//! shutter's frame): when every wanted row is sampled at the same columns with the same
//! sub-sample shift, the fold along the rows is the same linear map for every row, so it
//! commutes with the column transforms and is done first, on the spectrum: column u of
//! the half spectrum lands on lattice bin `q = u mod M_x` times its shift and start
//! phases, and the mirrored bins take the conjugate-reversed column (the inverse DFT of
//! `conj Y[(M − v') mod M]` is `conj` of the inverse DFT of `Y`). Only `M_x/2 + 1` column
//! transforms remain instead of `N_x/2 + 1`, and each row is one real inverse of length
//! `M_x`. Samples of a column that are exactly 0 (the scene grid's taper zeroes the
//! corners of the spectrum, [`super::scene_band`]) are skipped: their terms add nothing.

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

/// Fills column u's factors at the row frequencies outside a gap: `(u, (a, b), out)`
/// must set `out[v]` for every `v < a` and `v ≥ b` (rows `a..b` are not read).
pub type ColumnFillOutside<'a> = &'a (dyn Fn(usize, (usize, usize), &mut [Complex64]) + Sync);

/// The run of exact zeros around the middle of a column held in the real FFT's order
/// (0, Δ, 2Δ, …, then the negative half): `(a, b)` with `col[a..b]` all 0 and
/// `a ≤ rows/2 + 1 ≤ b` (`a == b`: none). The highest frequencies of both signs lie
/// there, where the scene grid's taper zeroes the spectrum.
pub fn zero_gap(col: &[Complex64]) -> (usize, usize) {
    let rows = col.len();
    let split = (rows / 2 + 1).min(rows);
    let zero = |z: &Complex64| z.re == 0.0 && z.im == 0.0;
    // Whole runs of GAP_RUN samples first, each tested at once (the bits of ±0 shifted
    // left by one are 0, and of no other number), then sample by sample.
    let all_zero = |run: &[Complex64]| {
        run.iter().fold(0u64, |acc, z| {
            acc | ((z.re.to_bits() | z.im.to_bits()) << 1)
        }) == 0
    };
    let mut a = split;
    while a >= GAP_RUN && all_zero(&col[a - GAP_RUN..a]) {
        a -= GAP_RUN;
    }
    while a > 0 && zero(&col[a - 1]) {
        a -= 1;
    }
    let mut b = split;
    while b + GAP_RUN <= rows && all_zero(&col[b..b + GAP_RUN]) {
        b += GAP_RUN;
    }
    while b < rows && zero(&col[b]) {
        b += 1;
    }
    (a, b)
}

/// The [`zero_gap`] of every column of a half spectrum held transposed (`spec_t`, columns
/// of `rows` samples one after another), in column order: what
/// [`LatticeInverse::sample_common_x`] finds itself when not handed them, computed once
/// for a spectrum that many frames sample.
pub fn column_zero_gaps(spec_t: &[Complex64], rows: usize) -> Vec<(usize, usize)> {
    spec_t.par_chunks(rows.max(1)).map(zero_gap).collect()
}

/// Samples [`zero_gap`] tests at once.
const GAP_RUN: usize = 8;

/// `e^{2πi u s/cols}`, the factor of a shift by `s` samples at column frequency u of a
/// `cols`-long real row; on an even row's Nyquist bin the average of the ± ramps,
/// `cos(πs)` ([`super::sampling::shift_phase`]).
fn shift_factor(cols: usize, u: usize, s: f64) -> Complex64 {
    use std::f64::consts::PI;
    if s == 0.0 {
        Complex64::new(1.0, 0.0)
    } else if cols % 2 == 0 && u == cols / 2 {
        Complex64::new((PI * s).cos(), 0.0)
    } else {
        Complex64::from_polar(1.0, 2.0 * PI * (u as f64) * s / cols as f64)
    }
}

/// `y ← (y + conj y[(M − v) mod M]) / 2`: the spectrum of the real part of `y`'s inverse
/// DFT.
fn symmetrize(y: &mut [Complex64]) {
    let my = y.len();
    let orig = y.to_vec();
    for (v, d) in y.iter_mut().enumerate() {
        *d = 0.5 * (orig[v] + orig[(my - v) % my].conj());
    }
}

/// One column folded onto `my` bins along the rows (see the [module documentation](self)):
/// `y[v'] = ramp[v'] · Σ_m col[v]·h[v]·alias[v]` over `v = v' + m·my` outside the zero gap
/// `gap` (whose terms are 0), in the order of [`LatticeInverse::sample`]. On x86-64 with
/// AVX2 the same loops compiled for it (the same operations on every value, so the same
/// result to the bit: no fused multiply-add is allowed to form).
fn fold_column(
    col: &[Complex64],
    h: Option<&[Complex64]>,
    alias: &[Complex64],
    ramp: &[Complex64],
    gap: (usize, usize),
    y: &mut [Complex64],
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        return unsafe { fold_column_avx2(col, h, alias, ramp, gap, y) };
    }
    fold_column_portable(col, h, alias, ramp, gap, y)
}

/// [`fold_column`] with AVX2 vectors, two complex samples per register: each complex
/// product is `(a·Re b) ∓± (swap(a)·Im b)` (`vaddsubpd`), which computes
/// `a.re·b.re − a.im·b.im` and `a.im·b.re + a.re·b.im`, the very operations of
/// `Complex64`'s product (the sum of the imaginary part in the other order, which IEEE
/// addition does not see), so the same values as [`fold_column_portable`] to the bit
/// (test); no fused multiply-add is formed (FMA is not enabled).
///
/// # Safety
/// The CPU must support AVX2 (`is_x86_feature_detected!("avx2")`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn fold_column_avx2(
    col: &[Complex64],
    h: Option<&[Complex64]>,
    alias: &[Complex64],
    ramp: &[Complex64],
    gap: (usize, usize),
    y: &mut [Complex64],
) {
    use std::arch::x86_64::*;
    /// Two complex products at once (`[re0, im0, re1, im1]`).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn cmul(a: __m256d, b: __m256d) -> __m256d {
        let b_re = _mm256_movedup_pd(b);
        let b_im = _mm256_permute_pd(b, 0b1111);
        let a_swap = _mm256_permute_pd(a, 0b0101);
        _mm256_addsub_pd(_mm256_mul_pd(a, b_re), _mm256_mul_pd(a_swap, b_im))
    }
    let (rows, my) = (col.len(), y.len());
    assert!(alias.len() >= rows && ramp.len() >= my && h.is_none_or(|h| h.len() >= rows));
    y.fill(Complex64::new(0.0, 0.0));
    let yp = y.as_mut_ptr() as *mut f64;
    let cp = col.as_ptr() as *const f64;
    let ap = alias.as_ptr() as *const f64;
    let mut b0 = 0;
    while b0 < rows {
        let b1 = (b0 + my).min(rows);
        for (s, e) in [(b0, gap.0.clamp(b0, b1)), (gap.1.clamp(b0, b1), b1)] {
            if s >= e {
                continue;
            }
            // Pairs of samples s + 2k (k < pairs), then the odd one left.
            let pairs = (e - s) / 2;
            // SAFETY (all pointer reads and writes below): samples s..e are inside `col`,
            // `h` and `alias` (length ≥ rows ≥ e, asserted above), and s − b0..e − b0 inside
            // `y` (e − b0 ≤ my).
            let (c, a, d) = (cp.add(2 * s), ap.add(2 * s), yp.add(2 * (s - b0)));
            match h {
                Some(h) => {
                    let hp = (h.as_ptr() as *const f64).add(2 * s);
                    for k in 0..pairs {
                        let o = 4 * k;
                        let p = cmul(
                            cmul(_mm256_loadu_pd(c.add(o)), _mm256_loadu_pd(hp.add(o))),
                            _mm256_loadu_pd(a.add(o)),
                        );
                        _mm256_storeu_pd(d.add(o), _mm256_add_pd(_mm256_loadu_pd(d.add(o)), p));
                    }
                }
                None => {
                    for k in 0..pairs {
                        let o = 4 * k;
                        let p = cmul(_mm256_loadu_pd(c.add(o)), _mm256_loadu_pd(a.add(o)));
                        _mm256_storeu_pd(d.add(o), _mm256_add_pd(_mm256_loadu_pd(d.add(o)), p));
                    }
                }
            }
            if (e - s) % 2 == 1 {
                let v = e - 1;
                let t = match h {
                    Some(h) => col[v] * h[v] * alias[v],
                    None => col[v] * alias[v],
                };
                y[v - b0] += t;
            }
        }
        b0 += my;
    }
    for (d, p) in y.iter_mut().zip(ramp) {
        *d *= p;
    }
}

/// [`fold_column`] for any CPU.
#[inline(always)]
fn fold_column_portable(
    col: &[Complex64],
    h: Option<&[Complex64]>,
    alias: &[Complex64],
    ramp: &[Complex64],
    gap: (usize, usize),
    y: &mut [Complex64],
) {
    let (rows, my) = (col.len(), y.len());
    y.fill(Complex64::new(0.0, 0.0));
    let mut b0 = 0;
    while b0 < rows {
        let b1 = b0 + my;
        for (s, e) in [(b0, gap.0.clamp(b0, b1)), (gap.1.clamp(b0, b1), b1)] {
            if s >= e {
                continue;
            }
            let d = &mut y[s - b0..e - b0];
            match h {
                Some(h) => {
                    for (((d, s), hv), a) in
                        d.iter_mut().zip(&col[s..e]).zip(&h[s..e]).zip(&alias[s..e])
                    {
                        *d += s * hv * a;
                    }
                }
                None => {
                    for ((d, s), a) in d.iter_mut().zip(&col[s..e]).zip(&alias[s..e]) {
                        *d += s * a;
                    }
                }
            }
        }
        b0 = b1;
    }
    for (d, p) in y.iter_mut().zip(ramp) {
        *d *= p;
    }
}

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

    /// The residues `wanted[i] mod ky`, sorted, each once: the columns are folded once
    /// per residue.
    fn residues(&self, wanted: &[usize]) -> Vec<usize> {
        let mut residues: Vec<usize> = wanted.iter().map(|w| w % self.ky).collect();
        residues.sort_unstable();
        residues.dedup();
        residues
    }

    /// The factors of the fold along a column for the lattice rows of residue `r`: per
    /// frame row v, `e^{2πi m r/k}` for alias m = v / M times `per_row[v]`; and per folded
    /// bin v', `e^{2πi v' r/N}`.
    fn fold_factors(
        &self,
        r: usize,
        per_row: Option<&[Complex64]>,
    ) -> (Vec<Complex64>, Vec<Complex64>) {
        let (rows, my) = (self.rows, self.my);
        let alias = (0..rows)
            .map(|v| {
                let a = self.unit_y[((v / my) * my * r) % rows];
                per_row.map_or(a, |p| a * p[v])
            })
            .collect();
        let ramp = (0..my).map(|v| self.unit_y[(v * r) % rows]).collect();
        (alias, ramp)
    }

    /// The inverse transforms of length M of the folded columns (`folded`: columns of M
    /// samples, one after another), in place.
    fn column_inverses(&self, folded: &mut [Complex64]) {
        let zero = Complex64::new(0.0, 0.0);
        folded.par_chunks_mut(self.my * 16).for_each_init(
            || vec![zero; self.col_inverse.get_inplace_scratch_len()],
            |sc, block| self.col_inverse.process_with_scratch(block, sc),
        );
    }

    /// The indices i of the wanted rows of residue `r` (`wanted[i] mod ky = r`).
    fn rows_of_residue(&self, wanted: &[usize], r: usize) -> Vec<usize> {
        (0..wanted.len())
            .filter(|&i| wanted[i] % self.ky == r)
            .collect()
    }

    /// The number of lattice rows and columns, `(rows / ky, cols / kx)`.
    pub fn lattice_shape(&self) -> (usize, usize) {
        (self.my, self.mx)
    }

    /// Frame rows `wanted` (row i of the result is frame row `wanted[i]`), all at the
    /// same frame columns `x_start + j·kx` (`j < n_cols`) of the frame shifted by `x_shift`
    /// samples along x (bin u times `e^{2πi u·x_shift/cols}`, the Nyquist bin of an even
    /// row `cos(π·x_shift)`), of the real frame whose half spectrum, held transposed
    /// (`spec_t[u·rows + v]`), times `per_column` (filled outside each column's zero gap,
    /// [`zero_gap`]; `gaps`, when given, must be [`column_zero_gaps`] of `spec_t`) and `per_row` is the frame's spectrum: the fold along the rows done
    /// on the spectrum, before the column transforms (see the [module documentation](self)).
    /// Equals [`LatticeInverse::sample`] with the same factors, every row starting at
    /// `x_start` and shifted by `x_shift`, to rounding (test). `spec_t` is not changed.
    ///
    /// # Panics
    /// If the lengths do not match the frame, a wanted row is outside it, or `n_cols`
    /// exceeds `cols / kx` (caller errors).
    #[allow(clippy::too_many_arguments)]
    pub fn sample_common_x(
        &self,
        spec_t: &[Complex64],
        gaps: Option<&[(usize, usize)]>,
        per_column: Option<ColumnFillOutside<'_>>,
        per_row: Option<&[Complex64]>,
        wanted: &[usize],
        x_start: usize,
        x_shift: f64,
        n_cols: usize,
    ) -> Array2<f64> {
        let (rows, cols, my, mx) = (self.rows, self.cols, self.my, self.mx);
        let hc = cols / 2 + 1;
        let hq = mx / 2 + 1;
        assert_eq!(
            spec_t.len(),
            rows * hc,
            "LatticeInverse::sample_common_x input length"
        );
        assert!(n_cols <= mx, "LatticeInverse::sample_common_x n_cols");
        assert!(
            wanted.iter().all(|&y| y < rows),
            "LatticeInverse::sample_common_x row"
        );
        assert!(
            per_row.is_none_or(|p| p.len() == rows),
            "LatticeInverse::sample_common_x per_row length"
        );
        let mut out = Array2::<f64>::zeros((wanted.len(), n_cols));
        let zero = Complex64::new(0.0, 0.0);
        let c = x_start % cols;
        assert!(
            gaps.is_none_or(|g| g.len() == hc),
            "LatticeInverse::sample_common_x gaps length"
        );
        // The zero gap of every column, once for all residues (or once for the sequence).
        let found;
        let gaps = match gaps {
            Some(g) => g,
            None => {
                found = column_zero_gaps(spec_t, rows);
                &found[..]
            }
        };
        let mut folded = vec![zero; hq * my];
        for r in self.residues(wanted) {
            let (alias, ramp) = self.fold_factors(r, per_row);
            folded.par_chunks_mut(my).enumerate().for_each_init(
                || (vec![zero; rows], vec![zero; my]),
                |(h, y), (q, dst)| {
                    dst.fill(zero);
                    for m in 0..self.kx {
                        // Bin u of the full row lands on lattice bin q; above the half
                        // spectrum it is the mirror of column cols − u.
                        let u = q + m * mx;
                        let (src, mirror) = if u < hc { (u, false) } else { (cols - u, true) };
                        let col = &spec_t[src * rows..(src + 1) * rows];
                        let gap = gaps[src];
                        if let Some(f) = per_column {
                            f(src, gap, h);
                        }
                        fold_column(col, per_column.map(|_| &h[..]), &alias, &ramp, gap, y);
                        // The real inverse ignores the imaginary part of the DC and an even
                        // row's Nyquist bin: keep the real part of those columns' rows.
                        if src == 0 || (cols % 2 == 0 && src == cols / 2) {
                            symmetrize(y);
                        }
                        let p = shift_factor(cols, src, x_shift);
                        let start = self.unit_x[(u * c) % cols];
                        if mirror {
                            // dst[v] += conj(y[(my − v) mod my]·p)·start: bin 0 from bin 0,
                            // then the rest reversed.
                            let (d0, rest) = dst.split_first_mut().expect("my > 0");
                            *d0 += (y[0] * p).conj() * start;
                            for (d, z) in rest.iter_mut().zip(y[1..].iter().rev()) {
                                *d += (z * p).conj() * start;
                            }
                        } else {
                            let g = p * start;
                            for (d, z) in dst.iter_mut().zip(y.iter()) {
                                *d += z * g;
                            }
                        }
                    }
                },
            );
            self.column_inverses(&mut folded);
            let folded: &[Complex64] = &folded;
            let rows_here = self.rows_of_residue(wanted, r);
            let norm = 1.0 / (rows * cols) as f64;
            let done: Vec<(usize, Vec<f64>)> = rows_here
                .par_iter()
                .map_init(
                    || (vec![zero; hq], self.c2r.make_scratch_vec(), vec![0.0; mx]),
                    |(half, sc, line), &i| {
                        let j = (wanted[i] - r) / self.ky;
                        for (q, z) in half.iter_mut().enumerate() {
                            *z = folded[q * my + j];
                        }
                        half[0].im = 0.0;
                        if mx % 2 == 0 {
                            half[mx / 2].im = 0.0;
                        }
                        let _ = self.c2r.process_with_scratch(half, line, sc);
                        (i, line[..n_cols].iter().map(|v| v * norm).collect())
                    },
                )
                .collect();
            for (i, line) in done {
                out.row_mut(i).assign(&ndarray::ArrayView1::from(&line[..]));
            }
        }
        out
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
        let mut folded = vec![zero; hc * my];
        for r in self.residues(wanted) {
            let (alias, ramp) = self.fold_factors(r, factors.per_row);
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
            self.column_inverses(&mut folded);
            let folded: &[Complex64] = &folded;
            let rows_here = self.rows_of_residue(wanted, r);
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

    /// Rows that share their columns: the fold along the rows done on the spectrum equals
    /// the full inverse of the changed spectrum (blur, row factors, a shift along x by a
    /// fraction of a sample) sampled on the lattice, for even and odd lengths, ratios 1–4
    /// along x, several residues and starts, a spectrum whose columns have runs of zeros
    /// around their middle (skipped) and a blur filled only outside them.
    #[test]
    fn common_columns_match_the_full_inverse() {
        for (rows, cols, ky, kx, x_start, x_shift) in [
            (12usize, 20usize, 3usize, 2usize, 3usize, 0.37f64),
            (15, 21, 3, 3, 1, 0.0),
            (16, 16, 4, 4, 2, 0.81),
            (18, 15, 2, 3, 0, 0.5),
            (10, 9, 2, 1, 4, 0.25),
        ] {
            let hc = cols / 2 + 1;
            let x = frame(rows, cols);
            let mut spec = spectrum_t(&x);
            // Zero the highest row frequencies of the upper columns (as a taper does).
            for u in hc / 2..hc {
                let cut = 1 + (u - hc / 2).min(rows / 2 - 1);
                let mid = rows / 2;
                for v in mid + 1 - cut.min(mid)..(mid + cut).min(rows) {
                    spec[u * rows + v] = Complex64::new(0.0, 0.0);
                }
            }
            let blur = |u: usize, v: usize| {
                Complex64::from_polar(1.0 / (1.0 + 0.1 * (u + v) as f64), 0.3 * v as f64)
            };
            let fill_outside = |u: usize, gap: (usize, usize), out: &mut [Complex64]| {
                for (v, o) in out.iter_mut().enumerate() {
                    if v < gap.0 || v >= gap.1 {
                        *o = blur(u, v);
                    } else {
                        // Rows of the gap must not be read: poison them.
                        *o = Complex64::new(f64::NAN, f64::NAN);
                    }
                }
            };
            let per_row: Vec<Complex64> = (0..rows)
                .map(|v| Complex64::from_polar(1.0, -0.2 * v as f64))
                .collect();
            let mut full = spec.clone();
            for u in 0..hc {
                for v in 0..rows {
                    full[u * rows + v] *= blur(u, v) * per_row[v];
                }
            }
            let wanted: Vec<usize> = (0..rows).filter(|w| w % 3 != 1).collect();
            let fft = RealFft2::<f64>::new(rows, cols);
            let mut img = Array2::zeros((wanted.len(), cols));
            fft.inverse_transposed_rows_with(&mut full, &wanted, &mut img, |_, row| {
                for (u, z) in row.iter_mut().enumerate() {
                    *z *= shift_factor(cols, u, x_shift);
                }
            });
            let li = LatticeInverse::new((rows, cols), (ky, kx)).expect("divisible");
            let n = cols / kx - 1;
            let got = li.sample_common_x(
                &spec,
                None,
                Some(&fill_outside),
                Some(&per_row),
                &wanted,
                x_start,
                x_shift,
                n,
            );
            // The columns' gaps found once beforehand (a sequence's): the same bits.
            let gaps = column_zero_gaps(&spec, rows);
            assert!(gaps.iter().any(|g| g.1 > g.0), "{rows}x{cols}: some gap");
            let cached = li.sample_common_x(
                &spec,
                Some(&gaps),
                Some(&fill_outside),
                Some(&per_row),
                &wanted,
                x_start,
                x_shift,
                n,
            );
            assert!(
                cached
                    .iter()
                    .zip(&got)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "{rows}x{cols}: cached gaps"
            );
            for (i, _) in wanted.iter().enumerate() {
                for j in 0..n {
                    let want = img[[i, (x_start + j * kx) % cols]];
                    assert!(
                        (got[[i, j]] - want).abs() < 1e-11,
                        "{rows}x{cols} k {ky}x{kx}: row {i} col {j}: {} vs {want}",
                        got[[i, j]]
                    );
                }
            }
            // Without factors: the frame's own samples.
            let plain =
                li.sample_common_x(&spectrum_t(&x), None, None, None, &wanted, x_start, 0.0, n);
            for (i, &w) in wanted.iter().enumerate() {
                for j in 0..n {
                    let want = x[[w, (x_start + j * kx) % cols]];
                    assert!(
                        (plain[[i, j]] - want).abs() < 1e-11,
                        "{rows}x{cols}: {i},{j}"
                    );
                }
            }
        }
    }

    /// The zero gap is the run of exact zeros around a column's middle, and empty
    /// without one.
    #[test]
    fn zero_gap_finds_the_middle_zeros() {
        let z = Complex64::new(0.0, 0.0);
        let o = Complex64::new(1.0, 0.0);
        // rows = 8: split at 5; zeros at 3..7.
        let col = [o, o, o, z, z, z, z, o];
        assert_eq!(zero_gap(&col), (3, 7));
        assert_eq!(zero_gap(&[o; 7]), (4, 4));
        // A zero elsewhere is not part of the gap.
        let col = [z, o, o, o, z, o, o];
        assert_eq!(zero_gap(&col), (4, 5));
        // Long columns (whole runs tested at once): every gap edge position on both sides,
        // −0 counted as zero, the smallest subnormal and a lone nonzero imaginary part not.
        let m = Complex64::new(-0.0, 0.0);
        let tiny = Complex64::new(f64::from_bits(1), 0.0);
        let im = Complex64::new(0.0, -0.0);
        let im1 = Complex64::new(0.0, 1e-300);
        for rows in [40usize, 41] {
            let split = rows / 2 + 1;
            for a in 0..=split {
                for b in split..=rows {
                    for edge in [o, tiny, im1] {
                        let col: Vec<Complex64> = (0..rows)
                            .map(|v| match v {
                                v if (a..b).contains(&v) => [z, m, im][v % 3],
                                v if v + 1 == a || v == b => edge,
                                _ => [o, z][v % 2],
                            })
                            .collect();
                        assert_eq!(zero_gap(&col), (a, b), "rows {rows} gap {a}..{b}");
                    }
                }
            }
        }
    }

    /// The AVX2 build of the column fold gives the portable one's values to the bit (with
    /// and without a blur, with a zero gap and without).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_avx2_fold_is_the_portable_fold() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let c = |t: usize, a: f64| Complex64::new((a * t as f64).sin(), (0.7 * a * t as f64).cos());
        for (rows, my) in [(30usize, 10usize), (33, 11)] {
            let col: Vec<Complex64> = (0..rows).map(|t| c(t, 1.3)).collect();
            let h: Vec<Complex64> = (0..rows).map(|t| c(t, 0.37)).collect();
            let alias: Vec<Complex64> = (0..rows).map(|t| c(t, 2.1)).collect();
            let ramp: Vec<Complex64> = (0..my).map(|t| c(t, 0.9)).collect();
            let split = rows / 2 + 1;
            // No gap, and gaps whose pieces have odd and even lengths.
            for gap in [(split, split), (12, 21), (13, 17), (11, 26)] {
                for blur in [None, Some(&h[..])] {
                    let mut a = vec![Complex64::new(0.0, 0.0); my];
                    let mut b = a.clone();
                    fold_column_portable(&col, blur, &alias, &ramp, gap, &mut a);
                    // SAFETY: AVX2 is present (checked above).
                    unsafe { fold_column_avx2(&col, blur, &alias, &ramp, gap, &mut b) };
                    for (x, y) in a.iter().zip(&b) {
                        assert_eq!(
                            (x.re.to_bits(), x.im.to_bits()),
                            (y.re.to_bits(), y.im.to_bits()),
                            "{rows} rows, gap {gap:?}, blur {}",
                            blur.is_some()
                        );
                    }
                }
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
