//! The layout moves of the 2-D transform ([`super::fft::RealFft2`]): the column gather
//! and scatter of the standard-layout column pass, the transposing tile store of the
//! engine's row pass (AVX for f32, with streaming stores where asked), and the
//! untranspose of a `[cols/2+1][rows]` buffer. All are pure copies: the same bits
//! whatever the implementation or the thread count.

use ndarray::{ArrayView2, ArrayViewMut2, Axis};
#[cfg(target_arch = "x86_64")]
use num_complex::Complex;
use rayon::prelude::*;

#[cfg(doc)]
use super::fft_float::{FftFloat, RowStores};

/// The portable [`FftFloat::store_tile_transposed`], from column `u0` on.
pub(super) fn store_tile_transposed_scalar<C: Copy>(
    tile: &[C],
    hc: usize,
    nr: usize,
    t0: usize,
    pieces: &mut [&mut [C]],
    u0: usize,
) {
    for (u, piece) in pieces.iter_mut().enumerate().skip(u0) {
        for (dr, d) in piece[t0..t0 + nr].iter_mut().enumerate() {
            *d = tile[dr * hc + u];
        }
    }
}

/// 4 × 4 transpose of 64-bit lanes, `out[c][j] = x[j][c]`, by unpacking and 128-bit
/// permutes (a pure move of bits). Shared by the transposing store and the accumulation's
/// AVX2 loop.
///
/// # Safety
/// The CPU must support AVX; call it from a function compiled with AVX so that it is
/// inlined.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(super) unsafe fn transpose_4x4_pd(
    x: [std::arch::x86_64::__m256d; 4],
) -> [std::arch::x86_64::__m256d; 4] {
    use std::arch::x86_64::*;
    let (lo01, hi01) = (
        _mm256_unpacklo_pd(x[0], x[1]),
        _mm256_unpackhi_pd(x[0], x[1]),
    );
    let (lo23, hi23) = (
        _mm256_unpacklo_pd(x[2], x[3]),
        _mm256_unpackhi_pd(x[2], x[3]),
    );
    [
        _mm256_permute2f128_pd(lo01, lo23, 0x20),
        _mm256_permute2f128_pd(hi01, hi23, 0x20),
        _mm256_permute2f128_pd(lo01, lo23, 0x31),
        _mm256_permute2f128_pd(hi01, hi23, 0x31),
    ]
}

/// [`FftFloat::store_tile_transposed`] of a whole f32 tile ([`TILE_ROWS`] = 8 rows) with
/// AVX: each complex f32 moved as one 64-bit lane, four columns at a time (two 4 × 4
/// transposes by unpack and 128-bit permute), each column's 8 samples stored as 64
/// contiguous bytes, with non-temporal stores if `streaming` where they are 32-byte
/// aligned; the columns left over (`hc` mod 4) by the scalar loop.
///
/// # Safety
/// The CPU must support AVX (`is_x86_feature_detected!("avx")`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
pub(super) unsafe fn store_tile8_transposed_avx(
    tile: &[Complex<f32>],
    hc: usize,
    t0: usize,
    pieces: &mut [&mut [Complex<f32>]],
    streaming: bool,
) {
    use std::arch::x86_64::*;
    const _: () = assert!(TILE_ROWS == 8);
    assert!(tile.len() >= TILE_ROWS * hc && pieces.len() >= hc);
    let n4 = hc / 4 * 4;
    for u in (0..n4).step_by(4) {
        // Row r, columns u..u+4: 4 complex f32 = 32 bytes, in bounds (u + 4 ≤ hc).
        let ld = |r: usize| _mm256_loadu_pd(tile[r * hc + u..r * hc + u + 4].as_ptr().cast());
        let top = transpose_4x4_pd([ld(0), ld(1), ld(2), ld(3)]);
        let bottom = transpose_4x4_pd([ld(4), ld(5), ld(6), ld(7)]);
        for j in 0..4 {
            // Bounds-checked: 8 samples of column u + j from row t0 on.
            let dst = pieces[u + j][t0..t0 + TILE_ROWS].as_mut_ptr().cast::<f64>();
            if streaming && (dst as usize) % 32 == 0 {
                // Aligned (a `SpectrumBuffer` whose columns are a multiple of 4 samples
                // long): two streaming stores write the whole 64-byte line without reading
                // it first. The caller fences before the spectra are read
                // ([`super::fft::stream_fence`]).
                _mm256_stream_pd(dst, top[j]);
                _mm256_stream_pd(dst.add(4), bottom[j]);
            } else {
                _mm256_storeu_pd(dst, top[j]);
                _mm256_storeu_pd(dst.add(4), bottom[j]);
            }
        }
    }
    store_tile_transposed_scalar(tile, hc, TILE_ROWS, t0, pieces, n4);
}

/// Rows moved together by the column gather and scatter (see [`super::fft`]'s documentation).
pub const TILE_ROWS: usize = 8;

/// `blk[j·rows + r] = cols[r, j]`: the columns of `cols` (`[rows][n]`, each row contiguous)
/// into `blk` as `[n][rows]`, [`TILE_ROWS`] rows at a time.
pub(super) fn gather_columns<C: Copy>(cols: ArrayView2<C>, blk: &mut [C]) {
    let rows = cols.nrows();
    let mut r0 = 0;
    for tile in cols.axis_chunks_iter(Axis(0), TILE_ROWS) {
        let nr = tile.nrows();
        if nr == TILE_ROWS {
            let src: [&[C]; TILE_ROWS] =
                std::array::from_fn(|i| tile.row(i).to_slice().expect("contiguous rows"));
            for (j, col) in blk.chunks_exact_mut(rows).enumerate() {
                for (d, s) in col[r0..r0 + TILE_ROWS].iter_mut().zip(&src) {
                    *d = s[j];
                }
            }
        } else {
            for (i, row) in tile.rows().into_iter().enumerate() {
                for (col, x) in blk.chunks_exact_mut(rows).zip(row) {
                    col[r0 + i] = *x;
                }
            }
        }
        r0 += nr;
    }
}

/// The inverse of [`gather_columns`]: `cols[r, j] = blk[j·rows + r]`.
pub(super) fn scatter_columns<C: Copy>(blk: &[C], mut cols: ArrayViewMut2<C>) {
    let rows = cols.nrows();
    let mut r0 = 0;
    for mut tile in cols.axis_chunks_iter_mut(Axis(0), TILE_ROWS) {
        let nr = tile.nrows();
        if nr == TILE_ROWS {
            let mut it = tile.rows_mut().into_iter();
            let mut dst: [&mut [C]; TILE_ROWS] = std::array::from_fn(|_| {
                it.next()
                    .and_then(|r| r.into_slice())
                    .expect("contiguous rows")
            });
            for (j, col) in blk.chunks_exact(rows).enumerate() {
                for (d, s) in dst.iter_mut().zip(&col[r0..r0 + TILE_ROWS]) {
                    d[j] = *s;
                }
            }
        } else {
            for (i, mut row) in tile.rows_mut().into_iter().enumerate() {
                for (col, x) in blk.chunks_exact(rows).zip(row.iter_mut()) {
                    *x = col[r0 + i];
                }
            }
        }
        r0 += nr;
    }
}

/// Rows per task of [`untranspose`]: 16 rows read 16 consecutive elements of every
/// transposed column (one or two cache lines each).
const UNTRANSPOSE_ROWS: usize = 16;

/// `out[v·hc + u] = t[u·rows + v]`: a transposed `[hc][rows]` buffer back to `[rows][hc]`,
/// blocks of rows in parallel.
pub fn untranspose<C: Copy + Send + Sync>(t: &[C], out: &mut [C], rows: usize, hc: usize) {
    assert_eq!(t.len(), rows * hc, "untranspose length");
    assert_eq!(out.len(), rows * hc, "untranspose length");
    out.par_chunks_mut(UNTRANSPOSE_ROWS * hc)
        .enumerate()
        .for_each(|(bi, o)| {
            let v0 = bi * UNTRANSPOSE_ROWS;
            let nv = o.len() / hc;
            for u in 0..hc {
                let col = &t[u * rows + v0..u * rows + v0 + nv];
                for (dv, x) in col.iter().enumerate() {
                    o[dv * hc + u] = *x;
                }
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::imaging::fft::{stream_fence, FftFloat, RowStores, SpectrumBuffer};
    use num_complex::Complex;

    /// The f32 tile store (vectorised where the CPU allows) moves every bit pattern,
    /// NaN payloads included, exactly where the portable loop does, for widths that are
    /// and are not multiples of its 4 columns, into an aligned [`SpectrumBuffer`]
    /// (streaming stores when asked) and into a buffer one sample off the alignment (plain
    /// stores).
    #[test]
    fn tile_store_moves_bits_as_the_portable_loop() {
        for (hc, offset, stores) in [
            (1usize, 0usize, RowStores::Streaming),
            (4, 0, RowStores::Streaming),
            (6, 0, RowStores::Streaming),
            (13, 0, RowStores::Streaming),
            (541, 0, RowStores::Streaming),
            (541, 0, RowStores::Cached),
            (541, 1, RowStores::Streaming),
        ] {
            let rows = 24;
            let tile: Vec<Complex<f32>> = (0..TILE_ROWS * hc)
                .map(|i| {
                    let b = (i as u32).wrapping_mul(2_654_435_761);
                    Complex::new(f32::from_bits(b), f32::from_bits(b ^ 0x7fc0_0001))
                })
                .collect();
            let zero = Complex::new(0.0f32, 0.0);
            let mut buffer = SpectrumBuffer::<f32>::new(hc * rows + 1);
            assert_eq!(
                buffer.as_slice().as_ptr() as usize % SpectrumBuffer::<f32>::ALIGN,
                0
            );
            let got = &mut buffer.as_mut_slice()[offset..offset + hc * rows];
            let mut want = vec![zero; hc * rows];
            let mut g: Vec<&mut [Complex<f32>]> = got.chunks_mut(rows).collect();
            f32::store_tile_transposed(&tile, hc, TILE_ROWS, 8, &mut g, stores);
            stream_fence();
            let mut w: Vec<&mut [Complex<f32>]> = want.chunks_mut(rows).collect();
            store_tile_transposed_scalar(&tile, hc, TILE_ROWS, 8, &mut w, 0);
            let bits = |v: &[Complex<f32>]| -> Vec<(u32, u32)> {
                v.iter().map(|c| (c.re.to_bits(), c.im.to_bits())).collect()
            };
            assert_eq!(
                bits(got),
                bits(&want),
                "hc = {hc}, offset {offset}, {stores:?}"
            );
        }
    }

    #[test]
    fn untranspose_is_the_transpose() {
        let (rows, hc) = (37, 5);
        let t: Vec<usize> = (0..rows * hc).collect();
        let mut out = vec![0; rows * hc];
        untranspose(&t, &mut out, rows, hc);
        for v in 0..rows {
            for u in 0..hc {
                assert_eq!(out[v * hc + u], t[u * rows + v]);
            }
        }
    }
}
