//! Two-dimensional real FFT in f32 or f64, with plans reused across bands and frames and
//! scratch per worker.
//!
//! A real 2-D transform of a `rows × cols` frame is done in two passes:
//!
//! 1. **Row pass** ([`RealFft2::rows_forward`]): real-to-complex transforms of the rows
//!    (`realfft`), rows in parallel, each worker with its own row buffer and scratch. The
//!    caller's `fill` writes each row just before it is transformed, so padding and the
//!    f32 → T conversion are fused into this pass (no frame-sized real buffer).
//! 2. **Column pass in blocks** ([`RealFft2::column_block`]): [`BLOCK_COLS`] columns of the
//!    row spectra are gathered into a small contiguous per-worker buffer (`[column][row]`,
//!    138 KiB for 1080 rows in f32: it stays in the core's L2 cache), transformed there
//!    (`rustfft`, complex, length `rows`) and handed to the caller while still in cache.
//!    No frame-sized transpose runs: [`RealFft2::forward`] and
//!    [`RealFft2::inverse`] scatter each transformed block straight back into the columns
//!    it came from ([`RealFft2::columns_in_place`]), so the standard layout costs no
//!    frame-sized transpose either (the frame is read and written once per pass, as
//!    pocketfft's `rfft2` does).
//!
//! 3. **The engine's path** ([`RealFft2::rows_forward_transposed`],
//!    [`RealFft2::column_region_forward`]): the row pass writes its spectra transposed,
//!    `[cols/2+1][rows]`, [`TILE_ROWS`] rows at a time (each column receives a whole cache
//!    line), so every column is one contiguous run; the imaging engine copies each block
//!    of columns into a per-worker buffer (the row spectra stay clean in cache and are
//!    never written back), transforms it there and adds it, OTF-weighted, to its
//!    accumulator while it is still in cache. No gather, no scatter; the same plans and
//!    data, so the same values bit for bit. In f32 the transposing store moves four
//!    columns at a time with AVX where the CPU has it ([`FftFloat::store_tile_transposed`];
//!    a bit copy, so the same result on every CPU). When a chunk's row spectra are too
//!    large to be read back from the cache (19 MB at 1080² for 4 bands, against a 32 MiB
//!    shared L3) it uses non-temporal stores into a cache-line-aligned [`SpectrumBuffer`]
//!    ([`RowStores::Streaming`]): each 64-byte line is written without first being read
//!    from memory (no read-for-ownership).
//!
//! The gather and the scatter move [`TILE_ROWS`] rows at a time: each column of the block
//! then receives 8 consecutive samples (64 B in f32, 128 B in f64: whole cache lines)
//! instead of one sample per row visit, which measured 5–20 % faster for the whole
//! transform (f64–f32) at 1080² than row-at-a-time copies.
//!
//! Each sample of the result is computed by one worker with the same instructions whatever
//! the number of threads or the block a column falls in, so results do not depend on the
//! thread count (bit for bit). The spectrum layout of [`RealFft2::forward`] is
//! `[row frequency, column frequency]` = `[rows, cols/2 + 1]`, the half-plane of
//! [`crate::sensor::FrequencyGrid::real_fft`]; the engine's accumulator is its transpose
//! `[cols/2 + 1, rows]`.
//!
//! **Precision.** `T = f32` transforms run about twice as fast as f64 (twice the SIMD lanes,
//! half the memory traffic). Their rounding error is ~ε_f32·log2(n) relative to the
//! spectrum's energy; accumulated in f64 across bands (see [`FftPrecision`]) the error of a
//! mean electron image is measured in tests/all/perf_determinism.rs (≤ 1e-6 of the mean).

use std::str::FromStr;
use std::sync::Arc;

use ndarray::{s, Array2, ArrayView2, ArrayViewMut2, Axis};
use num_complex::Complex;
use rayon::prelude::*;
use realfft::ComplexToReal;

pub use super::fft_float::{FftFloat, RowStores};
use super::r2c::RealForward;
use super::transpose::{gather_columns, scatter_columns};
pub use super::transpose::{untranspose, TILE_ROWS};
use rustfft::{Fft, FftDirection};

/// Precision of the per-band forward transforms of the imaging engine. The accumulation
/// over bands, the OTF, the inverse transform and the sampling are f64 in both cases.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FftPrecision {
    /// f32 forward transforms, f64 accumulation (the default: about 1.5–2× faster; error
    /// against the f64 path ≤ 1e-6 of the mean signal, tests/all/perf_determinism.rs).
    #[default]
    F32,
    /// f64 throughout (the reference path).
    F64,
}

impl FftPrecision {
    /// `"f32"` or `"f64"`.
    pub fn as_str(self) -> &'static str {
        match self {
            FftPrecision::F32 => "f32",
            FftPrecision::F64 => "f64",
        }
    }
}

impl FromStr for FftPrecision {
    type Err = crate::error::Error;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "f32" => Ok(FftPrecision::F32),
            "f64" => Ok(FftPrecision::F64),
            other => Err(crate::error::Error::param(
                "FFT precision",
                other,
                "\"f32\" (f32 transforms, f64 accumulation) or \"f64\"",
            )),
        }
    }
}

/// Waits until this thread's non-temporal stores are globally visible (`sfence` on
/// x86-64; nothing elsewhere, where none are issued).
#[inline]
pub fn stream_fence() {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: `sfence` is part of SSE, in the x86-64 baseline.
    unsafe {
        std::arch::x86_64::_mm_sfence()
    };
}

/// A zeroed spectrum of `len` complex samples whose first sample is 64-byte aligned (one
/// cache line), the row spectra of [`RealFft2::rows_forward_transposed`]: when a column's
/// length is a multiple of 4 samples every 8-sample piece of a column is then a whole,
/// aligned line, which the f32 row pass can write with non-temporal stores
/// ([`RowStores::Streaming`]).
pub struct SpectrumBuffer<T: FftFloat> {
    buf: Vec<Complex<T>>,
    /// Samples skipped at the start of `buf` to reach the alignment.
    start: usize,
    len: usize,
}

impl<T: FftFloat> SpectrumBuffer<T> {
    /// Alignment of the first sample, bytes.
    pub const ALIGN: usize = 64;

    /// `len` zero samples.
    pub fn new(len: usize) -> Self {
        let size = std::mem::size_of::<Complex<T>>();
        let slack = Self::ALIGN / size;
        let buf = crate::memory::vec_on_huge_pages(len + slack, Complex::new(T::zero(), T::zero()));
        // The allocation is aligned to the sample's own alignment at least; the start is
        // the first sample on a 64-byte boundary (within `slack` samples).
        let start = buf.as_ptr().align_offset(Self::ALIGN).min(slack);
        SpectrumBuffer { buf, start, len }
    }

    /// The samples.
    pub fn as_slice(&self) -> &[Complex<T>] {
        &self.buf[self.start..self.start + self.len]
    }

    /// The samples, mutable.
    pub fn as_mut_slice(&mut self) -> &mut [Complex<T>] {
        &mut self.buf[self.start..self.start + self.len]
    }
}

impl<T: FftFloat> AsRef<[Complex<T>]> for SpectrumBuffer<T> {
    fn as_ref(&self) -> &[Complex<T>] {
        self.as_slice()
    }
}

impl<T: FftFloat> std::fmt::Debug for SpectrumBuffer<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "SpectrumBuffer({} samples)", self.len)
    }
}

/// Columns per block of the column pass: 16 complex f32 columns of 1080 rows are 138 KiB,
/// inside a core's L2 cache together with the accumulator block they are added to.
pub const BLOCK_COLS: usize = 16;

/// Forward and inverse plans for one frame size and precision.
pub struct RealFft2<T: FftFloat = f64> {
    rows: usize,
    cols: usize,
    r2c: RealForward<T>,
    c2r: Arc<dyn ComplexToReal<T>>,
    col_forward: Arc<dyn Fft<T>>,
    col_inverse: Arc<dyn Fft<T>>,
}

impl<T: FftFloat> std::fmt::Debug for RealFft2<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "RealFft2({} x {})", self.rows, self.cols)
    }
}

/// Per-worker buffers of the column pass (see [`RealFft2::column_scratch`]).
#[derive(Debug)]
pub struct ColumnScratch<T> {
    block: Vec<Complex<T>>,
    fft: Vec<Complex<T>>,
}

impl<T: FftFloat> RealFft2<T> {
    /// Plans transforms of a `rows × cols` real frame (both ≥ 1).
    pub fn new(rows: usize, cols: usize) -> Self {
        RealFft2 {
            rows,
            cols,
            r2c: RealForward::new(cols),
            c2r: T::plan_real_inverse(cols),
            col_forward: T::plan_complex(rows, FftDirection::Forward),
            col_inverse: T::plan_complex(rows, FftDirection::Inverse),
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

    /// Buffers for [`RealFft2::column_block`], one set per worker.
    pub fn column_scratch(&self) -> ColumnScratch<T> {
        let zero = Complex::new(T::zero(), T::zero());
        let n = self
            .col_forward
            .get_inplace_scratch_len()
            .max(self.col_inverse.get_inplace_scratch_len());
        ColumnScratch {
            block: vec![zero; BLOCK_COLS * self.rows],
            fft: vec![zero; n],
        }
    }

    /// Row pass: `fill(r, row)` writes row `r` (length `cols`) into a per-worker buffer,
    /// which is transformed (real → complex, unnormalised) straight into row `r` of
    /// `rowspec` (`[rows][cols/2+1]`, row-major). Rows in parallel.
    pub fn rows_forward(&self, fill: impl Fn(usize, &mut [T]) + Sync, rowspec: &mut [Complex<T>]) {
        let (rows, cols) = (self.rows, self.cols);
        let hc = cols / 2 + 1;
        assert_eq!(rowspec.len(), rows * hc, "RealFft2::rows_forward length");
        rowspec.par_chunks_mut(hc).enumerate().for_each_init(
            || (vec![T::zero(); cols], self.r2c.make_scratch_vec()),
            |(row, sc), (r, o)| {
                fill(r, row);
                self.r2c.process(row, o, sc);
            },
        );
    }

    /// Row pass into the **transposed** layout `[cols/2+1][rows]` (element `u·rows + v` is
    /// column frequency u of row v's spectrum), the layout the engine's fused column pass
    /// transforms block by block ([`RealFft2::column_region_forward`]): each column is one
    /// contiguous run, so the column pass needs no gather and no scatter. `fill` as in
    /// [`RealFft2::rows_forward`]. Ranges of whole [`TILE_ROWS`]-row tiles in parallel;
    /// each tile's rows are transformed into a per-worker `[TILE_ROWS][cols/2+1]` buffer
    /// (in L1/L2) with the same plan and input as [`RealFft2::rows_forward`] (so the same
    /// values bit for bit, whatever the split) and then transposed into place: every
    /// column receives `TILE_ROWS` consecutive samples (64 B in f32, a whole cache line).
    ///
    /// `stores` says whether the spectra should stay in cache on the way out
    /// ([`RowStores`]); either way the values are the same.
    pub fn rows_forward_transposed(
        &self,
        fill: impl Fn(usize, &mut [T]) + Sync,
        out_t: &mut [Complex<T>],
        stores: RowStores,
    ) {
        let (rows, cols) = (self.rows, self.cols);
        let hc = cols / 2 + 1;
        assert_eq!(
            out_t.len(),
            rows * hc,
            "RealFft2::rows_forward_transposed length"
        );
        let zero = Complex::new(T::zero(), T::zero());
        // A few row ranges per worker (load balance); each owns its piece of every column.
        let tiles = rows.div_ceil(TILE_ROWS);
        let tasks = (4 * rayon::current_num_threads()).clamp(1, tiles);
        let span = tiles.div_ceil(tasks) * TILE_ROWS;
        let mut groups: Vec<Vec<&mut [Complex<T>]>> = (0..rows.div_ceil(span))
            .map(|_| Vec::with_capacity(hc))
            .collect();
        for column in out_t.chunks_mut(rows) {
            for (g, piece) in column.chunks_mut(span).enumerate() {
                groups[g].push(piece);
            }
        }
        groups.into_par_iter().enumerate().for_each_init(
            || {
                (
                    vec![T::zero(); cols],
                    vec![zero; TILE_ROWS * hc],
                    self.r2c.make_scratch_vec(),
                )
            },
            |(row, tile, sc), (g, mut pieces)| {
                let r0 = g * span;
                let len = pieces.first().map_or(0, |p| p.len());
                for t0 in (0..len).step_by(TILE_ROWS) {
                    let nr = (len - t0).min(TILE_ROWS);
                    for (dr, spec) in tile.chunks_exact_mut(hc).take(nr).enumerate() {
                        fill(r0 + t0 + dr, row);
                        self.r2c.process(row, spec, sc);
                    }
                    T::store_tile_transposed(tile, hc, nr, t0, &mut pieces, stores);
                }
                if stores == RowStores::Streaming {
                    // The streaming stores are weakly ordered: complete them before the
                    // task ends (rayon's join then publishes them to the reading threads).
                    stream_fence();
                }
            },
        );
    }

    /// Forward column transforms, in place, of `region`: whole columns of a transposed
    /// spectrum ([`RealFft2::rows_forward_transposed`]), `[n][rows]`. Each column gets the
    /// same plan and data as in [`RealFft2::column_block`], hence the same values bit for
    /// bit.
    /// `scratch` comes from [`RealFft2::column_region_scratch`] (one per worker).
    pub fn column_region_forward(&self, region: &mut [Complex<T>], scratch: &mut [Complex<T>]) {
        debug_assert_eq!(region.len() % self.rows, 0);
        self.col_forward.process_with_scratch(region, scratch);
    }

    /// Scratch for [`RealFft2::column_region_forward`] (the column plan's own, no block
    /// buffer: the region is transformed where it lies).
    pub fn column_region_scratch(&self) -> Vec<Complex<T>> {
        let zero = Complex::new(T::zero(), T::zero());
        vec![zero; self.column_region_scratch_len()]
    }

    /// Length of [`RealFft2::column_region_scratch`].
    pub fn column_region_scratch_len(&self) -> usize {
        self.col_forward.get_inplace_scratch_len()
    }

    /// Column pass of one block: gathers columns `u0 .. u0+n` (n ≤ [`BLOCK_COLS`]) of the
    /// row spectra `rowspec` (`[rows][cols/2+1]`) into the worker's buffer as `[n][rows]`,
    /// transforms each column (forward, or inverse when `inverse`; unnormalised) and
    /// returns them: element `j·rows + v` is frequency (v, u0 + j) of the 2-D spectrum.
    pub fn column_block<'a>(
        &self,
        rowspec: &[Complex<T>],
        u0: usize,
        n: usize,
        inverse: bool,
        sc: &'a mut ColumnScratch<T>,
    ) -> &'a mut [Complex<T>] {
        let rows = self.rows;
        let hc = self.cols / 2 + 1;
        debug_assert!(n <= BLOCK_COLS && u0 + n <= hc);
        let blk = &mut sc.block[..n * rows];
        let all =
            ArrayView2::from_shape((rows, hc), rowspec).expect("RealFft2::column_block length");
        gather_columns(all.slice(s![.., u0..u0 + n]), blk);
        self.column_fft(inverse)
            .process_with_scratch(blk, &mut sc.fft);
        blk
    }

    fn column_fft(&self, inverse: bool) -> &Arc<dyn Fft<T>> {
        if inverse {
            &self.col_inverse
        } else {
            &self.col_forward
        }
    }

    /// Column pass of a whole frame in place: `spec` (`[rows][cols/2+1]`, row-major) holds
    /// the row spectra on entry and the 2-D spectrum (forward, or inverse when `inverse`;
    /// unnormalised) in the same standard layout on return. Blocks of [`BLOCK_COLS`]
    /// columns in parallel, each gathered into the worker's buffer, transformed as in
    /// [`RealFft2::column_block`] (same plan, same data: the same result bit for bit) and
    /// scattered back into its own columns.
    pub fn columns_in_place(&self, spec: &mut [Complex<T>], inverse: bool) {
        let rows = self.rows;
        let hc = self.cols / 2 + 1;
        assert_eq!(spec.len(), rows * hc, "RealFft2::columns_in_place length");
        let fft = self.column_fft(inverse);
        let mut all = ArrayViewMut2::from_shape((rows, hc), spec).expect("length checked");
        // Column chunks of a row-major array are disjoint views: each worker owns its block.
        all.axis_chunks_iter_mut(Axis(1), BLOCK_COLS)
            .into_par_iter()
            .for_each_init(
                || self.column_scratch(),
                |sc, mut cols| {
                    let blk = &mut sc.block[..cols.ncols() * rows];
                    gather_columns(cols.view(), blk);
                    fft.process_with_scratch(blk, &mut sc.fft);
                    scatter_columns(blk, cols.view_mut());
                },
            );
    }

    /// Column pass of a whole frame: the 2-D spectrum of the row spectra `rowspec`
    /// (`[rows][cols/2+1]`) in transposed layout `out_t[u·rows + v]`, blocks in parallel.
    pub fn columns_transposed(
        &self,
        rowspec: &[Complex<T>],
        out_t: &mut [Complex<T>],
        inverse: bool,
    ) {
        let rows = self.rows;
        assert_eq!(out_t.len(), rowspec.len(), "RealFft2 column pass length");
        out_t
            .par_chunks_mut(BLOCK_COLS * rows)
            .enumerate()
            .for_each_init(
                || self.column_scratch(),
                |sc, (bi, o)| {
                    let n = o.len() / rows;
                    o.copy_from_slice(self.column_block(rowspec, bi * BLOCK_COLS, n, inverse, sc));
                },
            );
    }

    /// Forward transform of `input` (`[rows, cols]`, standard layout; left unchanged) into
    /// `out` (`[rows, cols/2+1]`), unnormalised:
    /// `X[v,u] = Σ x[y,x] exp(−2πi (vy/rows + ux/cols))`. `scratch` is not used (the
    /// column pass works in place, [`RealFft2::columns_in_place`]); it stays in the
    /// signature so that callers written for the earlier transposing pass still compile.
    pub fn forward(
        &self,
        input: &mut Array2<T>,
        out: &mut Array2<Complex<T>>,
        scratch: &mut Vec<Complex<T>>,
    ) {
        let inp = input.as_standard_layout();
        self.forward_rows(
            |r, row| row.copy_from_slice(inp.row(r).as_slice().expect("standard layout")),
            out,
            scratch,
        );
    }

    /// Forward transform of a frame produced row by row (`fill` as in
    /// [`RealFft2::rows_forward`]); otherwise as [`RealFft2::forward`] (same result, bit
    /// for bit).
    pub fn forward_rows(
        &self,
        fill: impl Fn(usize, &mut [T]) + Sync,
        out: &mut Array2<Complex<T>>,
        scratch: &mut Vec<Complex<T>>,
    ) {
        let (rows, hc) = self.spectrum_shape();
        assert_eq!(out.dim(), (rows, hc), "RealFft2::forward output shape");
        let o = out.as_slice_mut().expect("standard layout");
        self.rows_forward(fill, o);
        self.columns_in_place(o, false);
        // The column pass works in place: no frame-sized scratch is needed any more.
        let _ = scratch;
    }

    /// Inverse transform of a Hermitian half-plane spectrum (`[rows, cols/2+1]`, used as
    /// scratch) into `out` (`[rows, cols]`), normalised by 1/(rows·cols) so that
    /// `inverse(forward(x)) = x`. `scratch` as in [`RealFft2::forward`].
    pub fn inverse(
        &self,
        spectrum: &mut Array2<Complex<T>>,
        out: &mut Array2<T>,
        scratch: &mut Vec<Complex<T>>,
    ) {
        let (rows, cols) = (self.rows, self.cols);
        let hc = cols / 2 + 1;
        assert_eq!(spectrum.dim(), (rows, hc), "RealFft2::inverse input shape");
        assert_eq!(out.dim(), (rows, cols), "RealFft2::inverse output shape");
        let s = spectrum.as_slice_mut().expect("standard layout");
        self.columns_in_place(s, true);
        let _ = scratch; // kept in the signature for callers; the column pass is in place
        let o = out.as_slice_mut().expect("standard layout");
        o.par_chunks_mut(cols)
            .zip(s.par_chunks_mut(hc))
            .for_each_init(
                || self.c2r.make_scratch_vec(),
                |sc, (o, i)| self.inverse_row(i, o, sc),
            );
    }

    /// The row step of the inverse: the half spectrum `row` (`cols/2+1`, used as scratch)
    /// to the real row `out` (`cols`), normalised by 1/(rows·cols) for the whole 2-D
    /// inverse. realfft requires exactly real DC (and, for even lengths, Nyquist) bins;
    /// for the spectrum of a real image they are real up to rounding, so their imaginary
    /// parts are set to 0.
    fn inverse_row(&self, row: &mut [Complex<T>], out: &mut [T], scratch: &mut [Complex<T>]) {
        let hc = row.len();
        row[0].im = T::zero();
        if self.cols % 2 == 0 {
            row[hc - 1].im = T::zero();
        }
        let _ = self.c2r.process_with_scratch(row, out, scratch);
        let norm = T::nearest_from_f64(1.0 / (self.rows * self.cols) as f64);
        for v in out.iter_mut() {
            *v = *v * norm;
        }
    }

    /// [`RealFft2::inverse`] of a half-plane spectrum held transposed (`spec_t[u·rows + v]`,
    /// `[cols/2+1][rows]`, as the engine accumulates it; used as scratch), evaluated at the
    /// frame rows `wanted` only: row i of `out` (`[wanted.len(), cols]`) is frame row
    /// `wanted[i]`. The column transforms run in place on the contiguous columns (no
    /// gather, no scatter, no frame-sized transpose), then each wanted row is gathered from
    /// the columns and transformed; the other rows are never transformed. The same plans,
    /// data and operations as [`RealFft2::inverse`], so the same values bit for bit.
    ///
    /// # Panics
    /// If the lengths do not match the frame or a wanted row is outside it (caller errors).
    pub fn inverse_transposed_rows(
        &self,
        spec_t: &mut [Complex<T>],
        wanted: &[usize],
        out: &mut Array2<T>,
    ) {
        self.inverse_transposed_rows_with(spec_t, wanted, out, |_, _| {});
    }

    /// [`RealFft2::inverse_transposed_rows`] with `row_hook(i, spectrum)` called on the
    /// half spectrum of output row i (`cols/2+1` column frequencies) after the column
    /// transforms and before that row's own transform: a per-row multiplication there
    /// (e.g. a phase ramp that shifts one row along x, used for a rolling shutter's
    /// row-by-row displacement) acts on that row alone. With a hook that does nothing,
    /// the same values as [`RealFft2::inverse_transposed_rows`] bit for bit.
    ///
    /// # Panics
    /// As [`RealFft2::inverse_transposed_rows`].
    pub fn inverse_transposed_rows_with(
        &self,
        spec_t: &mut [Complex<T>],
        wanted: &[usize],
        out: &mut Array2<T>,
        row_hook: impl Fn(usize, &mut [Complex<T>]) + Sync,
    ) {
        let (rows, cols) = (self.rows, self.cols);
        let hc = cols / 2 + 1;
        assert_eq!(
            spec_t.len(),
            rows * hc,
            "RealFft2::inverse_transposed_rows input length"
        );
        assert_eq!(
            out.dim(),
            (wanted.len(), cols),
            "RealFft2::inverse_transposed_rows output shape"
        );
        assert!(
            wanted.iter().all(|&y| y < rows),
            "RealFft2::inverse_transposed_rows: row outside the frame"
        );
        let zero = Complex::new(T::zero(), T::zero());
        spec_t.par_chunks_mut(BLOCK_COLS * rows).for_each_init(
            || vec![zero; self.col_inverse.get_inplace_scratch_len()],
            |sc, block| self.col_inverse.process_with_scratch(block, sc),
        );
        let spec_t: &[Complex<T>] = spec_t;
        out.axis_iter_mut(Axis(0))
            .into_par_iter()
            .zip(wanted.par_iter().enumerate())
            .for_each_init(
                || (vec![zero; hc], self.c2r.make_scratch_vec()),
                |(row, sc), (mut o, (i, &y))| {
                    for (u, x) in row.iter_mut().enumerate() {
                        *x = spec_t[u * rows + y];
                    }
                    row_hook(i, row);
                    self.inverse_row(row, o.as_slice_mut().expect("standard layout"), sc);
                },
            );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_complex::Complex64;

    /// The forward transform equals the DFT definition summed directly, and the inverse
    /// recovers the input; shapes span more than one column block.
    #[test]
    fn matches_direct_dft_and_round_trips() {
        for (rows, cols) in [(6usize, 8usize), (5, 7), (4, 9), (7, 40), (3, 35)] {
            let x = Array2::from_shape_fn((rows, cols), |(r, c)| {
                ((r * 7 + c * 3) % 11) as f64 - 0.3 * c as f64
            });
            let fft = RealFft2::<f64>::new(rows, cols);
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
            // The f32 transform agrees to f32 rounding.
            let f32fft = RealFft2::<f32>::new(rows, cols);
            let mut spec32 = Array2::zeros(f32fft.spectrum_shape());
            let mut s32 = Vec::new();
            f32fft.forward(&mut x.mapv(|v| v as f32), &mut spec32, &mut s32);
            let scale = x.iter().map(|v| v.abs()).sum::<f64>();
            for (a, b) in spec32.iter().zip(spec.iter()) {
                let d = Complex64::new(a.re as f64, a.im as f64) - b;
                assert!(d.norm() < 1e-6 * scale, "f32 vs f64 {rows}x{cols}");
            }
            let mut back = Array2::zeros((rows, cols));
            fft.inverse(&mut spec, &mut back, &mut scratch);
            for (a, b) in back.iter().zip(x.iter()) {
                assert!((a - b).abs() < 1e-10);
            }
        }
    }

    /// The in-place column pass (tiled gather, transform, tiled scatter) equals the
    /// transposing pass followed by [`untranspose`], bit for bit, in both directions, for
    /// row counts that are not multiples of [`TILE_ROWS`] and column counts that are not
    /// multiples of [`BLOCK_COLS`].
    #[test]
    fn in_place_column_pass_equals_transposing_pass() {
        for (rows, cols) in [(37usize, 70usize), (8, 30), (5, 3), (1080, 64)] {
            let fft = RealFft2::<f64>::new(rows, cols);
            let (_, hc) = fft.spectrum_shape();
            let spec: Vec<Complex<f64>> = (0..rows * hc)
                .map(|i| Complex::new((i % 97) as f64 - 40.0, ((i * 7) % 53) as f64))
                .collect();
            for inverse in [false, true] {
                let mut t = vec![Complex::new(0.0, 0.0); rows * hc];
                fft.columns_transposed(&spec, &mut t, inverse);
                let mut want = vec![Complex::new(0.0, 0.0); rows * hc];
                untranspose(&t, &mut want, rows, hc);
                let mut got = spec.clone();
                fft.columns_in_place(&mut got, inverse);
                assert_eq!(got, want, "{rows}x{cols} inverse={inverse}");
            }
        }
    }

    /// The transposed row pass and its in-place column transforms equal the standard
    /// row pass and column blocks bit for bit, for shapes with a partial last block, row
    /// counts not multiple of the tile, 1 or 3 threads (different row splits), and cached
    /// or streaming stores.
    #[test]
    fn transposed_row_pass_and_column_regions_equal_standard_ones() {
        for (threads, stores) in [
            (1, RowStores::Cached),
            (1, RowStores::Streaming),
            (3, RowStores::Streaming),
        ] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            for (rows, cols) in [
                (37usize, 70usize),
                (8, 30),
                (5, 3),
                (19, 33),
                (130, 40),
                (40, 70),
            ] {
                let x = Array2::from_shape_fn((rows, cols), |(r, c)| {
                    ((r * 7 + c * 3) % 11) as f32 - 0.3 * c as f32
                });
                let fft = RealFft2::<f32>::new(rows, cols);
                let hc = cols / 2 + 1;
                let fill =
                    |r: usize, row: &mut [f32]| row.copy_from_slice(x.row(r).as_slice().unwrap());
                let zero = Complex::new(0.0f32, 0.0);
                let mut std_spec = vec![zero; rows * hc];
                // Cache-line aligned, as the engine's (streaming stores where a column's
                // pieces are aligned: every piece for 8 or 40 rows, every other for 130).
                let mut t = SpectrumBuffer::<f32>::new(rows * hc);
                fft.rows_forward(fill, &mut std_spec);
                pool.install(|| fft.rows_forward_transposed(fill, t.as_mut_slice(), stores));
                let t = t.as_mut_slice();
                for v in 0..rows {
                    for u in 0..hc {
                        assert_eq!(
                            t[u * rows + v],
                            std_spec[v * hc + u],
                            "{rows}x{cols} row pass"
                        );
                    }
                }
                let (mut a, mut b) = (fft.column_scratch(), fft.column_region_scratch());
                for (bi, region) in t.chunks_mut(BLOCK_COLS * rows).enumerate() {
                    let n = region.len() / rows;
                    let want = fft.column_block(&std_spec, bi * BLOCK_COLS, n, false, &mut a);
                    fft.column_region_forward(region, &mut b);
                    for (g, w) in region.iter().zip(want.iter()) {
                        assert_eq!(g.re.to_bits(), w.re.to_bits(), "{rows}x{cols} block {bi}");
                        assert_eq!(g.im.to_bits(), w.im.to_bits(), "{rows}x{cols} block {bi}");
                    }
                }
            }
        }
    }

    /// The inverse of a transposed spectrum at chosen rows equals the same rows of the
    /// full inverse bit for bit (f32 and f64; even and odd sizes; more than one column
    /// block; rows in any order, repeated, first and last).
    #[test]
    fn inverse_at_rows_of_a_transposed_spectrum_equals_the_full_inverse() {
        fn check<T: FftFloat + PartialEq + std::fmt::Debug>(rows: usize, cols: usize) {
            let fft = RealFft2::<T>::new(rows, cols);
            let hc = cols / 2 + 1;
            let spec = Array2::from_shape_fn((rows, hc), |(v, u)| {
                let (v, u) = (v as f64, u as f64);
                Complex::new(
                    T::nearest_from_f64((0.37 * v + 1.3 * u).sin() / (1.0 + u)),
                    T::nearest_from_f64((0.11 * v * u + 0.5).cos() - 0.2),
                )
            });
            let mut full = Array2::<T>::zeros((rows, cols));
            fft.inverse(&mut spec.clone(), &mut full, &mut Vec::new());
            let mut t = vec![Complex::new(T::zero(), T::zero()); rows * hc];
            untranspose(spec.as_slice().unwrap(), &mut t, hc, rows);
            let wanted = [rows - 1, 0, rows / 2, 1 % rows, rows - 1];
            let mut out = Array2::<T>::zeros((wanted.len(), cols));
            fft.inverse_transposed_rows(&mut t, &wanted, &mut out);
            for (i, &y) in wanted.iter().enumerate() {
                assert_eq!(out.row(i), full.row(y), "{rows}x{cols}, row {y}");
            }
        }
        for (rows, cols) in [(40, 36), (33, 35), (7, 8), (1, 5)] {
            check::<f64>(rows, cols);
            check::<f32>(rows, cols);
        }
    }

    #[test]
    fn precision_parses_and_rejects() {
        assert_eq!("f32".parse::<FftPrecision>().unwrap(), FftPrecision::F32);
        assert_eq!("f64".parse::<FftPrecision>().unwrap(), FftPrecision::F64);
        let e = "f16".parse::<FftPrecision>().unwrap_err().to_string();
        assert!(e.contains("f16") && e.contains("f64"), "{e}");
    }
}
