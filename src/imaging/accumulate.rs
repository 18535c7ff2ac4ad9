//! The fused column pass of the imaging engine: per block of column frequencies, the
//! column transforms of a chunk's bands, their chromatic and achromatic transfer functions
//! and the spectral weights, added to the frame's f64 accumulator while the block is in
//! cache (see [`accumulate_chunk`]), and the frequency samples it reads ([`RadialGrid`]).

use ndarray::Array2;
use num_complex::Complex64;
use rayon::prelude::*;

use super::fft::{FftFloat, RealFft2, BLOCK_COLS};
use super::otf_table::{ChunkProfile, CHUNK_LANES};
use super::workspace::ColumnWorkspace;
#[cfg(doc)]
use super::Imager;
use crate::memory::vec_on_huge_pages;
use crate::sensor::FrequencyGrid;

/// The half-plane frequency samples of a padded frame as the fused accumulation reads them
/// ([`accumulate_chunk`]), in the accumulator's transposed layout `[fx][fy]` (sample
/// (fy index v, fx index u) at `u·rows + v`):
/// - the radial frequency ρ = `fx.hypot(fy)` (cycles/rad) is stored for the rows
///   `v = 0 ..= rows/2` of each column only: ρ is even in fy and the frequency of row
///   `rows − v` is exactly minus that of row v, so the other rows read the same value
///   mirrored (a column's half, a few KiB, is still in L1 when the mirrored rows need it);
/// - the achromatic product A (every component that does not depend on λ: footprint,
///   motion, jitter, Gaussian, measured MTFs; not even in fy, for a smear at an angle) is
///   stored for every sample, in f32.
///
/// The accumulation streams this array once per chunk of bands beside the f64 accumulator.
/// Per sample it reads about 8 bytes instead of the 16 of `[ρ, A]` in f64, which frees
/// memory bandwidth and last-level cache for the row spectra; ρ keeps its f64 bits, and A
/// in f32 is within 2^−24 (6e-8) relative of its f64 value, well inside the tables' 1e-6
/// ([`super::otf_table::TABLE_TOLERANCE`]).
#[derive(Debug, Clone, PartialEq)]
pub struct RadialGrid {
    /// Rows of the padded frame (fy samples).
    rows: usize,
    /// ρ of rows `0 ..= rows/2` of each column, `[u·(rows/2 + 1) + v]`.
    rho: Vec<f64>,
    /// A per sample, `[u·rows + v]`.
    achromatic: Vec<f32>,
    /// The largest ρ.
    rho_max: f64,
}

/// ρ values stored per column of `rows` rows: rows `0 ..= rows/2` ([`RadialGrid`]).
fn stored_rows(rows: usize) -> usize {
    rows / 2 + 1
}

/// The stored row that holds row `v`'s ρ: v itself up to rows/2, its mirror `rows − v`
/// above (ρ is even in fy, and row `rows − v`'s frequency is exactly minus row v's).
#[inline(always)]
fn stored_row(rows: usize, v: usize) -> usize {
    v.min(rows - v)
}

impl RadialGrid {
    /// The samples of `grid` with the achromatic product `achromatic` (shape `[fy, fx]`,
    /// as [`crate::sensor::GridOtf`] gives it).
    ///
    /// # Panics
    /// If `achromatic`'s shape is not `[grid.fy.len(), grid.fx.len()]` (a caller error).
    pub fn new(grid: &FrequencyGrid, achromatic: &Array2<f64>) -> Self {
        assert_eq!(
            achromatic.dim(),
            (grid.fy.len(), grid.fx.len()),
            "RadialGrid::new: the achromatic product's shape is not the grid's"
        );
        Self::from_fn(grid, |u, v| achromatic[[v, u]])
    }

    /// The samples of `grid` with the achromatic product `achromatic(u, v)` at fx index u,
    /// fy index v, evaluated once per sample straight into the stored layout (no
    /// frame-sized f64 array). The engine fills whole columns ([`RadialGrid::from_columns`]).
    pub fn from_fn(grid: &FrequencyGrid, achromatic: impl Fn(usize, usize) -> f64 + Sync) -> Self {
        Self::from_columns(grid, |u, column| {
            for (v, a) in column.iter_mut().enumerate() {
                *a = achromatic(u, v);
            }
        })
    }

    /// The samples of `grid` with the achromatic product of each column filled by
    /// `column(u, out)`: `out[v]` the product at fx index u, fy index v (for example
    /// [`crate::sensor::AchromaticSampler::column`]), columns in parallel, each through a
    /// per-worker f64 column into the stored f32.
    pub fn from_columns(grid: &FrequencyGrid, column: impl Fn(usize, &mut [f64]) + Sync) -> Self {
        let (rows, cols) = (grid.fy.len(), grid.fx.len());
        let half = stored_rows(rows);
        let mut a = vec_on_huge_pages(rows * cols, 0.0f32);
        a.par_chunks_mut(rows.max(1)).enumerate().for_each_init(
            || vec![0.0f64; rows],
            |scratch, (u, col)| {
                column(u, scratch);
                for (x, s) in col.iter_mut().zip(scratch.iter()) {
                    *x = *s as f32;
                }
            },
        );
        let mut rho = vec_on_huge_pages(if rows == 0 { 0 } else { cols * half }, 0.0f64);
        rho.par_iter_mut()
            .enumerate()
            .for_each(|(i, r)| *r = grid.fx[i / half].hypot(grid.fy[i % half]));
        RadialGrid {
            rows,
            rho_max: grid.rho_max(),
            rho,
            achromatic: a,
        }
    }

    /// Rows of the padded frame (fy samples).
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Column frequencies of the half plane (fx samples).
    pub fn cols(&self) -> usize {
        self.achromatic.len().checked_div(self.rows).unwrap_or(0)
    }

    /// ρ (cycles/rad) at fx index `u`, fy index `v`.
    #[inline]
    pub fn rho(&self, u: usize, v: usize) -> f64 {
        self.rho[u * stored_rows(self.rows) + stored_row(self.rows, v)]
    }

    /// The achromatic product (as stored, f32) at fx index `u`, fy index `v`.
    #[inline]
    pub fn achromatic(&self, u: usize, v: usize) -> f64 {
        self.achromatic[u * self.rows + v] as f64
    }

    /// The largest ρ on the grid, cycles/rad (0 for an empty grid).
    pub fn rho_max(&self) -> f64 {
        self.rho_max
    }
}

/// The fused column pass of a chunk of bands: for every block of [`BLOCK_COLS`] column
/// frequencies (blocks in parallel), every band's columns are copied into a per-worker
/// buffer and transformed there ([`RealFft2::column_region_forward`]: the row pass left
/// them contiguous), then one pass over the block adds all bands, in band order, to each
/// accumulator sample:
/// `acc += spec_b · w_b · A(f) · P_b(ρ(f))`, with A the achromatic product and P_b band
/// b's chromatic profile, all bands interpolated at once from the chunk's common ρ grid
/// ([`ChunkProfile::eval_all`]; no per-band OTF array, no frame-sized transpose; the
/// accumulator and A are loaded once per chunk, not once per band). `acc_t` and `grid`
/// are in the transposed `[fx][fy]` layout. Every sample is computed by one worker with
/// the same operations in the same order whatever the thread count, so the result does
/// not depend on it.
///
/// `rowspecs[c]` is band c's transposed row pass ([`RealFft2::rows_forward_transposed`];
/// only read: each block of it is copied into a per-worker buffer and transformed there,
/// so its cache lines are never dirtied and written back), `weights[c]` its spectral
/// weight and lane c of `profile` ([`Imager::chunk_profile`]) its profile.
pub fn accumulate_chunk<T: FftFloat, R: AsRef<[num_complex::Complex<T>]>>(
    fft: &RealFft2<T>,
    rowspecs: &[R],
    weights: &[f64],
    profile: &ChunkProfile,
    grid: &RadialGrid,
    acc_t: &mut [Complex64],
    workspace: &ColumnWorkspace<T>,
) {
    let rows = fft.shape().0;
    debug_assert_eq!(rows, grid.rows());
    let nb = rowspecs.len().min(weights.len()).min(profile.bands());
    let block = BLOCK_COLS * rows;
    // Per block, every band's region of it (contiguous columns).
    let mut regions: Vec<Vec<&[num_complex::Complex<T>]>> = (0..acc_t.len().div_ceil(block))
        .map(|_| Vec::with_capacity(nb))
        .collect();
    for rs in rowspecs[..nb].iter() {
        for (bi, region) in rs.as_ref().chunks(block).enumerate() {
            regions[bi].push(region);
        }
    }
    let half = stored_rows(rows);
    acc_t
        .par_chunks_mut(block)
        .zip(grid.achromatic.par_chunks(block))
        .zip(grid.rho.par_chunks(BLOCK_COLS * half))
        .zip(regions.into_par_iter())
        .for_each_init(
            || workspace.lease(nb * block, fft),
            |lease, (((a, amp), rho), bands)| {
                // The first column's accumulator, A and ρ are on their way to the cache
                // during the transforms (the sample loop asks for each next column itself).
                crate::memory::prefetch_read(&a[..rows.min(a.len())]);
                crate::memory::prefetch_read(&amp[..rows.min(amp.len())]);
                crate::memory::prefetch_read(&rho[..half.min(rho.len())]);
                let (buf, sc) = lease.buffers();
                // Each band's region is copied into the worker's buffer and transformed
                // there: the row spectra are only read, so their cache lines stay clean
                // and are never written back to memory.
                let mut work: Vec<&mut [num_complex::Complex<T>]> = Vec::with_capacity(nb);
                for (region, dst) in bands.iter().zip(buf.chunks_mut(block)) {
                    let dst = &mut dst[..region.len()];
                    dst.copy_from_slice(region);
                    fft.column_region_forward(dst, sc);
                    work.push(dst);
                }
                let bands = work;
                let blocks: Vec<&[num_complex::Complex<T>]> = bands.iter().map(|b| &**b).collect();
                let columns = ColumnBlock {
                    rows,
                    rho,
                    achromatic: amp,
                };
                if let (Ok(blocks), Ok(w)) = (
                    <[&[num_complex::Complex<T>]; CHUNK_LANES]>::try_from(&blocks[..]),
                    <[f64; CHUNK_LANES]>::try_from(&weights[..nb]),
                ) {
                    accumulate_block_full(a, &columns, blocks, w, profile);
                    return;
                }
                let mut g = [0.0; CHUNK_LANES];
                for (j, (a, amp)) in a.chunks_mut(rows).zip(amp.chunks(rows)).enumerate() {
                    for (v, (a, amp)) in a.iter_mut().zip(amp).enumerate() {
                        let amp = *amp as f64;
                        if amp == 0.0 {
                            continue;
                        }
                        profile.eval_all(columns.rho(j, v), &mut g);
                        let mut sum = *a;
                        for ((blk, w), gc) in blocks.iter().zip(weights).zip(&g) {
                            let s = blk[j * rows + v];
                            let s = Complex64::new(s.re.widen(), s.im.widen());
                            sum += s * (w * amp * gc);
                        }
                        *a = sum;
                    }
                }
            },
        );
}

/// The frequency samples of one block of whole columns (see [`RadialGrid`]): the rows of a
/// column, ρ of rows `0 ..= rows/2` of each column (`[column · (rows/2 + 1) + row]`) and A
/// of every sample (`[column · rows + row]`).
struct ColumnBlock<'a> {
    rows: usize,
    rho: &'a [f64],
    achromatic: &'a [f32],
}

impl ColumnBlock<'_> {
    /// ρ of row `v` of the block's column `j`.
    #[inline]
    fn rho(&self, j: usize, v: usize) -> f64 {
        self.rho[j * stored_rows(self.rows) + stored_row(self.rows, v)]
    }

    /// The halves of the block's whole columns (within its first `len` samples), each with
    /// its ρ as one slice: rows `0 ..= rows/2` read the stored half in order, the rows
    /// above read `rho[1 ..= rows − rows/2 − 1]` of it backwards (row v's value is stored
    /// at `rows − v`), so every sample loop reads ρ in order or reversed.
    fn segments(&self, len: usize) -> impl Iterator<Item = Segment<'_>> {
        let (rows, half) = (self.rows, stored_rows(self.rows));
        let upper = rows.saturating_sub(half);
        let len = len.min(self.achromatic.len());
        self.rho
            .chunks_exact(half)
            .enumerate()
            .filter(move |(j, _)| (j + 1) * rows <= len)
            .flat_map(move |(j, rho)| {
                let start = j * rows;
                [
                    Segment {
                        samples: start..start + half,
                        rho,
                        mirrored: false,
                    },
                    Segment {
                        samples: start + half..start + rows,
                        rho: &rho[1..1 + upper],
                        mirrored: true,
                    },
                ]
            })
    }
}

/// Half of a column ([`ColumnBlock::segments`]): its samples in the block, and their ρ,
/// read backwards if `mirrored`.
struct Segment<'a> {
    samples: std::ops::Range<usize>,
    rho: &'a [f64],
    mirrored: bool,
}

/// [`accumulate_chunk`]'s sample loop for a full chunk ([`CHUNK_LANES`] bands): the same
/// operations in the same order, with the bands as fixed-size arrays (no per-band bounds
/// checks or loop bookkeeping inside the loop over samples).
///
/// On x86-64 CPUs with AVX2 (detected at run time) the same source is compiled for AVX2
/// ([`accumulate_block_avx2`]): 256-bit vectors for the four lanes, the same IEEE
/// operations in the same order (Rust never fuses a multiply and an add into an FMA), so
/// the same result bit for bit on every CPU.
///
/// For f32 spectra (the default precision) the AVX2 loop is [`accumulate_block_f32_avx2`]:
/// four samples at a time, the same operations per sample, hence the same bits.
#[inline(never)]
fn accumulate_block_full<T: FftFloat>(
    acc: &mut [Complex64],
    columns: &ColumnBlock,
    blocks: [&[num_complex::Complex<T>]; CHUNK_LANES],
    weights: [f64; CHUNK_LANES],
    profile: &ChunkProfile,
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        if let Some(blocks) = T::as_f32_slices(blocks) {
            // SAFETY: the CPU supports AVX2 (checked just above).
            unsafe { accumulate_block_f32_avx2(acc, columns, blocks, weights, profile) };
        } else {
            // SAFETY: the CPU supports AVX2 (checked just above).
            unsafe { accumulate_block_avx2(acc, columns, blocks, weights, profile) };
        }
        return;
    }
    accumulate_block_body(acc, columns, blocks, weights, profile);
}

/// [`accumulate_block_body`] for f32 spectra, four rows of a column and their four mirror
/// rows per step with AVX2 intrinsics (the scalar loop spends most of its instructions
/// moving single lanes: one table position, one weight and one factor at a time).
///
/// ρ is even in fy: rows `1 + k … 4 + k` of a column and their mirrors `rows − 4 − k …
/// rows − 1 − k` have the same four ρ, reversed ([`RadialGrid`]). Per step, with the four
/// ρ as the four lanes:
/// 1. ρ and A of the eight samples; the table position `i` and `frac` computed as
///    [`ChunkProfile::eval_all`] computes them (`min(⌊max(t, 0)⌋, len − 2)` equals its
///    saturating `t as u32` clamped to `len − 2`, and `min(t − i, 1)` its `frac`), a step
///    ahead of their use so that their latency overlaps the step before;
/// 2. the two table rows of each ρ loaded (their lanes are the bands) and transposed
///    4 × 4 so that the lanes are the samples;
/// 3. per band c: `g = a + frac·(b − a)`, 0 beyond the band's cut, times the aerosol
///    plateau, once for both halves; then the factors `(w_c·A)·g` of the four rows and
///    `(w_c·A)·g` with g's lanes reversed of their mirrors, and `acc += s·factor` for the
///    four pairs of samples (one 256-bit vector holds two complex f64), bands in order
///    0, 1, 2, 3.
///
/// Two tests are made once per step rather than per band: where no ρ is beyond the
/// chunk's smallest cut, the cut masks are skipped (they would keep every value), and
/// where every ρ is above the bound past which every lane is certainly on its aerosol
/// plateau (the profile's, which [`ChunkProfile::eval_all`] uses too), the exact per-lane
/// plateau test is skipped.
///
/// These are the scalar loop's IEEE operations in its order, sample by sample (no FMA),
/// so the result is the same bit for bit
/// (`the_f32_avx2_loop_equals_the_scalar_loop_bit_for_bit`). Row 0 (its own mirror), an
/// even column's Nyquist row (likewise), the `upper mod 4` pairs left over, and steps
/// where one of the eight samples has A = 0 (the scalar loop skips it) or a ρ is not past
/// every band's aerosol table (the scalar loop then evaluates the tables; only next to
/// ρ = 0) go through the scalar loop itself.
///
/// # Safety
/// The CPU must support AVX2 (`is_x86_feature_detected!("avx2")`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn accumulate_block_f32_avx2(
    acc: &mut [Complex64],
    columns: &ColumnBlock,
    blocks: [&[num_complex::Complex<f32>]; CHUNK_LANES],
    weights: [f64; CHUNK_LANES],
    profile: &ChunkProfile,
) {
    use super::transpose::transpose_4x4_pd;
    use std::arch::x86_64::*;
    const _: () = assert!(CHUNK_LANES == 4);
    let lanes = profile.lanes();
    let values = lanes.values;
    if values.len() < 2 {
        accumulate_block_body(acc, columns, blocks, weights, profile);
        return;
    }
    let last = values.len() - 1;
    let inv_step = _mm256_set1_pd(lanes.inv_step);
    let top = _mm256_set1_pd((last - 1) as f64);
    let zero = _mm256_setzero_pd();
    let one = _mm256_set1_pd(1.0);
    let cut = lanes.cut.map(|c| _mm256_set1_pd(c));
    let w = weights.map(|x| _mm256_set1_pd(x));
    let plateau = lanes.plateau.map(|(sc, end, beyond, _)| {
        (
            sc.map(|x| _mm256_set1_pd(x)),
            end.map(|x| _mm256_set1_pd(x)),
            beyond.map(|x| _mm256_set1_pd(x)),
        )
    });
    // Above it every lane is certainly past its aerosol table (`ChunkProfile`'s bound).
    let past_from = _mm256_set1_pd(lanes.plateau.map_or(f64::INFINITY, |p| p.3));
    // Below the smallest cut no lane is cut: the per-band cut masks are skipped.
    let first_cut = _mm256_set1_pd(lanes.cut.iter().copied().fold(f64::INFINITY, f64::min));
    let rows = columns.rows;
    let half = stored_rows(rows);
    // Rows above the stored half: row v ≥ half reads ρ of row `rows − v`.
    let upper = rows.saturating_sub(half);
    let whole_columns = (acc.len() / rows.max(1)).min(columns.achromatic.len() / rows.max(1));
    // The next column's accumulator, A and ρ are asked into the cache a step at a time
    // while this column is worked on: each column is a few 4 KiB pages of each array, and
    // the hardware's stream prefetcher stops at every page (measured: `otf_and_accumulate`
    // takes 0.94 of its time without the hints). A hint, with no effect on values.
    let (acc_all, amp_all, rho_all) = (
        acc.as_ptr(),
        columns.achromatic.as_ptr(),
        columns.rho.as_ptr(),
    );
    for j in 0..whole_columns {
        let start = j * rows;
        let ahead = j + 1 < whole_columns;
        let prefetch = |lo: usize, hi: usize| {
            if ahead {
                let (n_lo, n_hi) = (start + rows + lo, start + rows + hi);
                let n_rho = (j + 1) * half + lo;
                for p in [
                    acc_all.wrapping_add(n_lo).cast::<i8>(),
                    acc_all.wrapping_add(n_hi).cast(),
                    amp_all.wrapping_add(n_lo).cast(),
                    amp_all.wrapping_add(n_hi).cast(),
                    rho_all.wrapping_add(n_rho).cast(),
                ] {
                    // SAFETY: a prefetch only hints the cache and never faults (the
                    // addresses are inside the next column, which exists).
                    _mm_prefetch::<_MM_HINT_T0>(p);
                }
            }
        };
        let rho = &columns.rho[j * half..(j + 1) * half];
        let acc = &mut acc[start..start + rows];
        let amp = &columns.achromatic[start..start + rows];
        let blocks = blocks.map(|b| &b[start..start + rows]);
        // The scalar loop for rows `v0 .. v0 + n` of the column, ρ from `rho` (backwards
        // if `mirrored`).
        let scalar_rows =
            |acc: &mut [Complex64], v0: usize, n: usize, rho: &[f64], mirrored: bool| {
                accumulate_samples(
                    &mut acc[v0..v0 + n],
                    rho,
                    mirrored,
                    &amp[v0..v0 + n],
                    blocks.map(|b| &b[v0..v0 + n]),
                    weights,
                    profile,
                )
            };
        // Row 0 has no mirror.
        scalar_rows(acc, 0, 1, &rho[..1], false);
        // Rows 1 + k … 4 + k (ρ = rho[1 + k .. 5 + k]) and their mirrors rows − 4 − k …
        // rows − 1 − k (the same ρ, reversed) share one table lookup.
        let steps = upper / 4;
        // Step q's table positions and fractions (rows 1 + 4q … 4 + 4q), computed one
        // step ahead: their conversion and lane extraction then overlap the step before
        // instead of heading its chain of dependent loads.
        let position = |q: usize| {
            let rho4 = _mm256_loadu_pd(rho[1 + 4 * q..5 + 4 * q].as_ptr());
            let t = _mm256_mul_pd(rho4, inv_step);
            // 0 ≤ max(t, 0) clamped to len − 2 < 2^22: the conversion to i32 is exact.
            let pos = _mm256_cvttpd_epi32(_mm256_min_pd(_mm256_max_pd(t, zero), top));
            let frac = _mm256_min_pd(_mm256_sub_pd(t, _mm256_cvtepi32_pd(pos)), one);
            let at = [
                _mm_cvtsi128_si32(pos),
                _mm_extract_epi32::<1>(pos),
                _mm_extract_epi32::<2>(pos),
                _mm_extract_epi32::<3>(pos),
            ];
            (at, frac)
        };
        let mut ahead = (steps > 0).then(|| position(0));
        for q in 0..steps {
            let k = 4 * q;
            let (lo, hi) = (1 + k, rows - 4 - k);
            let (at, frac) = ahead.take().unwrap_or_else(|| position(q));
            if q + 1 < steps {
                ahead = Some(position(q + 1));
            }
            prefetch(lo, hi);
            let r4 = &rho[lo..lo + 4];
            let rho4 = _mm256_loadu_pd(r4.as_ptr());
            let amp_lo = _mm256_cvtps_pd(_mm_loadu_ps(amp[lo..lo + 4].as_ptr()));
            let amp_hi = _mm256_cvtps_pd(_mm_loadu_ps(amp[hi..hi + 4].as_ptr()));
            let mut scalar = (_mm256_movemask_pd(_mm256_cmp_pd::<_CMP_EQ_OQ>(amp_lo, zero))
                | _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_EQ_OQ>(amp_hi, zero)))
                != 0;
            let surely_past = _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_GT_OQ>(rho4, past_from));
            if let (Some((sc, end, _)), false) = (&plateau, surely_past == 0b1111) {
                let mut past = _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_mul_pd(rho4, sc[0]), end[0]);
                for c in 1..CHUNK_LANES {
                    let p = _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_mul_pd(rho4, sc[c]), end[c]);
                    past = _mm256_and_pd(past, p);
                }
                scalar |= _mm256_movemask_pd(past) != 0b1111;
            }
            if scalar {
                scalar_rows(acc, lo, 4, r4, false);
                scalar_rows(acc, hi, 4, r4, true);
                continue;
            }
            // SAFETY: each position is in 0 ..= len − 2 (clamped above), so rows i and
            // i + 1 are inside `values`.
            let row = |j: usize, d: usize| {
                _mm256_loadu_pd(values.as_ptr().add(at[j] as usize + d).cast::<f64>())
            };
            let a = [row(0, 0), row(1, 0), row(2, 0), row(3, 0)];
            let b = [row(0, 1), row(1, 1), row(2, 1), row(3, 1)];
            let d = [0, 1, 2, 3].map(|j| _mm256_sub_pd(b[j], a[j]));
            let (a, d) = (transpose_4x4_pd(a), transpose_4x4_pd(d));
            let any_cut = _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_GT_OQ>(rho4, first_cut)) != 0;
            let mut lo01 = _mm256_loadu_pd(acc[lo..lo + 2].as_ptr().cast());
            let mut lo23 = _mm256_loadu_pd(acc[lo + 2..lo + 4].as_ptr().cast());
            let mut hi01 = _mm256_loadu_pd(acc[hi..hi + 2].as_ptr().cast());
            let mut hi23 = _mm256_loadu_pd(acc[hi + 2..hi + 4].as_ptr().cast());
            for c in 0..CHUNK_LANES {
                let v = _mm256_add_pd(a[c], _mm256_mul_pd(frac, d[c]));
                let mut g = if any_cut {
                    _mm256_andnot_pd(_mm256_cmp_pd::<_CMP_GT_OQ>(rho4, cut[c]), v)
                } else {
                    v
                };
                if let Some((_, _, beyond)) = &plateau {
                    g = _mm256_mul_pd(g, beyond[c]);
                }
                // The mirrored rows run the other way: their factors, lanes reversed.
                let g_hi = _mm256_permute4x64_pd::<0b00_01_10_11>(g);
                let f_lo = _mm256_mul_pd(_mm256_mul_pd(w[c], amp_lo), g);
                let f_hi = _mm256_mul_pd(_mm256_mul_pd(w[c], amp_hi), g_hi);
                let x =
                    |v: usize| _mm256_cvtps_pd(_mm_loadu_ps(blocks[c][v..v + 2].as_ptr().cast()));
                // [f0, f0, f1, f1] and [f2, f2, f3, f3]: one factor per complex sample.
                let pair01 = |f| _mm256_permute4x64_pd::<0b01_01_00_00>(f);
                let pair23 = |f| _mm256_permute4x64_pd::<0b11_11_10_10>(f);
                lo01 = _mm256_add_pd(lo01, _mm256_mul_pd(x(lo), pair01(f_lo)));
                lo23 = _mm256_add_pd(lo23, _mm256_mul_pd(x(lo + 2), pair23(f_lo)));
                hi01 = _mm256_add_pd(hi01, _mm256_mul_pd(x(hi), pair01(f_hi)));
                hi23 = _mm256_add_pd(hi23, _mm256_mul_pd(x(hi + 2), pair23(f_hi)));
            }
            _mm256_storeu_pd(acc[lo..lo + 2].as_mut_ptr().cast(), lo01);
            _mm256_storeu_pd(acc[lo + 2..lo + 4].as_mut_ptr().cast(), lo23);
            _mm256_storeu_pd(acc[hi..hi + 2].as_mut_ptr().cast(), hi01);
            _mm256_storeu_pd(acc[hi + 2..hi + 4].as_mut_ptr().cast(), hi23);
        }
        // The pairs left over: rows 1 + 4·steps ..= upper and their mirrors.
        let k = 4 * steps;
        let left = upper - k;
        scalar_rows(acc, 1 + k, left, &rho[1 + k..1 + upper], false);
        scalar_rows(acc, half, left, &rho[1 + k..1 + upper], true);
        // An even column's Nyquist row (rows/2) is its own mirror.
        if 1 + upper < half {
            scalar_rows(
                acc,
                1 + upper,
                half - 1 - upper,
                &rho[1 + upper..half],
                false,
            );
        }
    }
}

/// [`accumulate_block_body`] compiled for AVX2.
///
/// # Safety
/// The CPU must support AVX2 (`is_x86_feature_detected!("avx2")`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn accumulate_block_avx2<T: FftFloat>(
    acc: &mut [Complex64],
    columns: &ColumnBlock,
    blocks: [&[num_complex::Complex<T>]; CHUNK_LANES],
    weights: [f64; CHUNK_LANES],
    profile: &ChunkProfile,
) {
    accumulate_block_body(acc, columns, blocks, weights, profile);
}

/// The sample loop of [`accumulate_block_full`], column by column, each in its two halves
/// ([`ColumnBlock::segments`]).
#[inline(always)]
fn accumulate_block_body<T: FftFloat>(
    acc: &mut [Complex64],
    columns: &ColumnBlock,
    blocks: [&[num_complex::Complex<T>]; CHUNK_LANES],
    weights: [f64; CHUNK_LANES],
    profile: &ChunkProfile,
) {
    for seg in columns.segments(acc.len()) {
        let s = seg.samples;
        accumulate_samples(
            &mut acc[s.clone()],
            seg.rho,
            seg.mirrored,
            &columns.achromatic[s.clone()],
            blocks.map(|b| &b[s.clone()]),
            weights,
            profile,
        );
    }
}

/// Consecutive samples of one column (ρ from `rho`, read backwards if `mirrored`; A and
/// each band's spectrum per sample): `acc += Σ_c s_c · ((w_c · A) · g_c(ρ))`, bands in
/// order, samples with A = 0 skipped.
#[inline(always)]
fn accumulate_samples<T: FftFloat>(
    acc: &mut [Complex64],
    rho: &[f64],
    mirrored: bool,
    achromatic: &[f32],
    blocks: [&[num_complex::Complex<T>]; CHUNK_LANES],
    weights: [f64; CHUNK_LANES],
    profile: &ChunkProfile,
) {
    let n = acc.len().min(rho.len()).min(achromatic.len());
    let blocks = blocks.map(|b| &b[..n]);
    let rho = &rho[..n];
    let mut g = [0.0; CHUNK_LANES];
    for (k, (a, amp)) in acc[..n].iter_mut().zip(&achromatic[..n]).enumerate() {
        let amp = *amp as f64;
        if amp == 0.0 {
            continue;
        }
        let r = if mirrored { rho[n - 1 - k] } else { rho[k] };
        profile.eval_all(r, &mut g);
        let mut sum = *a;
        for c in 0..CHUNK_LANES {
            let s = blocks[c][k];
            let s = Complex64::new(s.re.widen(), s.im.widen());
            sum += s * (weights[c] * amp * g[c]);
        }
        *a = sum;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::imaging::otf_table::RadialTables;
    use crate::sensor::{Sensor, SensorConfig};
    use num_complex::Complex;
    use rand::{RngExt, SeedableRng};
    use rand_xoshiro::Xoshiro256PlusPlus;

    /// The every-component SWIR sensor of the benchmarks (obscured aperture, aberration,
    /// defocus, turbulence, aerosol and the achromatic terms), 1.0–1.7 µm.
    const SWIR: &str = include_str!("../../benches/swir_all_components.toml");

    /// The SWIR sensor with its `[aerosol]` section (the last one) removed or kept.
    fn swir(aerosol: bool) -> String {
        let at = SWIR
            .find("[aerosol]")
            .expect("the SWIR file has an aerosol section");
        let end = SWIR[at + 1..]
            .find("\n[")
            .map_or(SWIR.len(), |e| at + 1 + e + 1);
        if aerosol {
            SWIR.to_string()
        } else {
            format!("{}{}", &SWIR[..at], &SWIR[end..])
        }
    }

    /// Runs the sample loop chosen at run time ([`accumulate_block_full`]: the f32 AVX2
    /// loop on this CPU when it has AVX2) and the portable scalar loop on the same f32
    /// spectra and compares every accumulator bit. The samples cover: ρ across each
    /// band's aperture cut and past the table's end, the aerosol core next to ρ = 0 (where
    /// the AVX2 loop hands its step to the scalar loop), A = +0 and −0 (skipped), runs of
    /// samples that all take the vector path, and a tail of `n mod 4` samples. Without
    /// diffraction (defocus and aberration only) a band's profile does not reach 0 at its
    /// cut, so the cut itself is checked too.
    #[test]
    fn the_f32_avx2_loop_equals_the_scalar_loop_bit_for_bit() {
        for (aerosol, diffraction) in [(false, true), (true, true), (true, false)] {
            let overrides = if diffraction {
                vec![]
            } else {
                vec!["diffraction.enabled=false".to_string()]
            };
            let cfg = SensorConfig::from_toml_str(
                &swir(aerosol),
                "swir.toml",
                std::path::PathBuf::from("."),
                &overrides,
            )
            .unwrap();
            let otf = Sensor::build(&cfg).unwrap().otf().clone();
            assert_eq!(otf.aerosol_particle_radius_m().is_some(), aerosol);
            let tables = RadialTables::new(&otf, 1.0, 1.7);
            let rho_max = 1.3 * otf.cutoff_cy_per_rad(1.0);
            let profile = tables.chunk_profile(&otf, &[1.0, 1.25, 1.5, 1.7], rho_max);
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(0x5eed ^ aerosol as u64);
            // Five columns of an odd and of an even number of rows (tails of 3 and 2 in the
            // halves): fx = 0 and fx = 2 cycles/rad (the aerosol cores next to ρ = 0),
            // then columns further out, so that the cuts fall at different rows.
            for rows in [2509, 2502] {
                let half = rows / 2 + 1;
                let fx = [0.0, 2.0, 0.2 * rho_max, 0.5 * rho_max, 0.9 * rho_max];
                let fy: Vec<f64> = (0..half)
                    .map(|k| match k % 5 {
                        // Past the grid's end and across every cut.
                        0 => 1.2 * rho_max * rng.random::<f64>(),
                        // The aerosol cores (ρ < a/λ, a few cycles/rad).
                        1 if k < 400 => 3.0 * rng.random::<f64>(),
                        // Inside every band's cut at the end of the half, where the rows
                        // left over from the AVX2 loop's pairs of mirrored rows fall.
                        _ if k + 8 >= half => 0.3 * rho_max * (1.0 + rng.random::<f64>()),
                        // A smooth run, as along a column of the spectrum.
                        _ => rho_max * (k as f64 / half as f64),
                    })
                    .collect();
                let rho: Vec<f64> = fx
                    .iter()
                    .flat_map(|x| fy.iter().map(move |y| x.hypot(*y)))
                    .collect();
                let n = rows * fx.len();
                let achromatic: Vec<f32> = (0..n)
                    .map(|k| match k % 97 {
                        13 => 0.0,
                        41 => -0.0,
                        _ => (2.0 * rng.random::<f64>() - 0.5) as f32,
                    })
                    .collect();
                let columns = ColumnBlock {
                    rows,
                    rho: &rho,
                    achromatic: &achromatic,
                };
                let spectra: Vec<Vec<Complex<f32>>> = (0..CHUNK_LANES)
                    .map(|_| {
                        (0..n)
                            .map(|_| {
                                let re = (1e3 * (rng.random::<f64>() - 0.5)) as f32;
                                Complex::new(re, (1e3 * (rng.random::<f64>() - 0.5)) as f32)
                            })
                            .collect()
                    })
                    .collect();
                let blocks: [&[Complex<f32>]; CHUNK_LANES] =
                    std::array::from_fn(|c| spectra[c].as_slice());
                let weights = [0.7, 1.3e-3, 2.5, 0.11];
                let start: Vec<Complex64> = (0..n)
                    .map(|_| Complex64::new(rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5))
                    .collect();
                let mut fast = start.clone();
                let mut slow = start.clone();
                accumulate_block_full(&mut fast, &columns, blocks, weights, &profile);
                accumulate_block_body(&mut slow, &columns, blocks, weights, &profile);
                // Independent of both loops: every sample gets ρ of its own row, the mirror
                // of rows above rows/2 included, and A = 0 leaves it as it was.
                let mut plain = start.clone();
                let mut g = [0.0; CHUNK_LANES];
                for (k, p) in plain.iter_mut().enumerate() {
                    let (j, v) = (k / rows, k % rows);
                    let amp = achromatic[k] as f64;
                    if amp == 0.0 {
                        continue;
                    }
                    profile.eval_all(fx[j].hypot(fy[v.min(rows - v)]), &mut g);
                    for c in 0..CHUNK_LANES {
                        let s = blocks[c][k];
                        *p += Complex64::new(s.re as f64, s.im as f64) * (weights[c] * amp * g[c]);
                    }
                }
                let mut changed = 0;
                for (k, (((f, s), s0), p)) in
                    fast.iter().zip(&slow).zip(&start).zip(&plain).enumerate()
                {
                    let what = format!(
                        "aerosol {aerosol}, diffraction {diffraction}, rows {rows}, sample {k} \
                         (A {}): {f:?} against {s:?}",
                        achromatic[k]
                    );
                    assert!(
                        f.re.to_bits() == s.re.to_bits() && f.im.to_bits() == s.im.to_bits(),
                        "{what}"
                    );
                    assert!(
                        f.re.to_bits() == p.re.to_bits() && f.im.to_bits() == p.im.to_bits(),
                        "{what}, plain {p:?}"
                    );
                    changed += (s != s0) as usize;
                }
                // Most samples received something (the loops did work, the test can fail).
                assert!(changed > n / 2, "only {changed} of {n} samples changed");
            }
        }
    }

    /// The grid's ρ is the radial frequency of every sample (`hypot`, exactly, on both sides of rows/2),
    /// its A the achromatic product at the same sample in the transposed layout (to f32
    /// rounding), and `rho_max` the largest ρ of any sample, exactly.
    #[test]
    fn radial_grid_holds_rho_and_the_achromatic_product_of_every_sample() {
        for (ny, nx, cols) in [(30, 45, 23), (31, 44, 23)] {
            let grid = FrequencyGrid::real_fft(ny, nx, 1.7e-5, 2.3e-5);
            let rows = grid.fy.len();
            let achromatic = Array2::from_shape_fn((rows, cols), |(v, u)| {
                (0.3 * v as f64 + 0.07 * u as f64).cos() * 0.9
            });
            let g = RadialGrid::new(&grid, &achromatic);
            assert_eq!((g.rows(), g.cols()), (ny, cols));
            let mut largest: f64 = 0.0;
            for u in 0..cols {
                for v in 0..rows {
                    let rho = g.rho(u, v);
                    assert_eq!(rho, grid.fx[u].hypot(grid.fy[v]), "{ny}: ({u}, {v})");
                    largest = largest.max(rho);
                    let a = achromatic[[v, u]];
                    assert_eq!(g.achromatic(u, v), a as f32 as f64, "({u}, {v})");
                    assert!((g.achromatic(u, v) - a).abs() <= a.abs() * 6e-8);
                }
            }
            assert_eq!(g.rho_max(), largest);
        }
    }

    /// A column pass with a workspace left dirty by an earlier chunk of other data gives
    /// the bits of one with a fresh workspace, on 1 and on 2 threads; the sets are kept
    /// (returned after every pass) and, on one thread, the later pass allocates none.
    #[test]
    fn reused_column_workspaces_give_the_fresh_result() {
        let cfg = SensorConfig::from_toml_str(
            &swir(true),
            "swir.toml",
            std::path::PathBuf::from("."),
            &[],
        )
        .unwrap();
        let otf = Sensor::build(&cfg).unwrap().otf().clone();
        let (ny, nx) = (90, 72);
        let fft = RealFft2::<f32>::new(ny, nx);
        let spacing = 2e-5;
        let grid = FrequencyGrid::real_fft(ny, nx, spacing, spacing);
        let sampler = otf.achromatic_sampler(&grid);
        let radial = RadialGrid::from_columns(&grid, |u, c| sampler.column(u, c));
        let tables = RadialTables::new(&otf, 1.0, 1.7);
        let profile = tables.chunk_profile(&otf, &[1.0, 1.2, 1.4, 1.7], radial.rho_max());
        let weights = [0.7, 1.3, 2.5, 0.11];
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(0x3a5e);
        let mut spectra = |seed: f32| -> Vec<super::super::fft::SpectrumBuffer<f32>> {
            (0..CHUNK_LANES)
                .map(|_| {
                    let mut rs = super::super::fft::SpectrumBuffer::new(ny * (nx / 2 + 1));
                    let values: Vec<f32> =
                        (0..ny * nx).map(|_| seed * rng.random::<f32>()).collect();
                    fft.rows_forward_transposed(
                        |r, row| row.copy_from_slice(&values[r * nx..(r + 1) * nx]),
                        rs.as_mut_slice(),
                        super::super::fft::RowStores::Cached,
                    );
                    rs
                })
                .collect()
        };
        let (earlier, chunk) = (spectra(-3.0), spectra(1.0));
        let pass = |threads: usize, reuse: bool| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let workspace = ColumnWorkspace::new();
                let mut acc = vec![Complex64::new(0.0, 0.0); ny * (nx / 2 + 1)];
                if reuse {
                    let mut scrap = acc.clone();
                    accumulate_chunk(
                        &fft, &earlier, &weights, &profile, &radial, &mut scrap, &workspace,
                    );
                }
                let sets = workspace.sets();
                accumulate_chunk(
                    &fft, &chunk, &weights, &profile, &radial, &mut acc, &workspace,
                );
                assert!(workspace.sets() >= 1);
                // On one thread the pass holds one set at a time; on more, how many it
                // holds at once depends on work stealing.
                if reuse && threads == 1 {
                    assert_eq!(workspace.sets(), sets, "a set was not reused");
                }
                acc
            })
        };
        let fresh = pass(1, false);
        assert!(fresh.iter().filter(|c| c.norm() > 0.0).count() > fresh.len() / 2);
        for (threads, reuse) in [(1, true), (2, false), (2, true)] {
            let got = pass(threads, reuse);
            for (k, (a, b)) in got.iter().zip(&fresh).enumerate() {
                assert!(
                    a.re.to_bits() == b.re.to_bits() && a.im.to_bits() == b.im.to_bits(),
                    "{threads} threads, reuse {reuse}, sample {k}: {a} vs {b}"
                );
            }
        }
    }
}
