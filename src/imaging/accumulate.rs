//! The fused column pass of the imaging engine: per block of column frequencies, the
//! column transforms of a chunk's bands, their chromatic and achromatic transfer functions
//! and the spectral weights, added to the frame's f64 accumulator while the block is in
//! cache (see [`accumulate_chunk`]).

use num_complex::Complex64;
use rayon::prelude::*;

use super::fft::{FftFloat, RealFft2, BLOCK_COLS};
use super::otf_table::{ChunkProfile, CHUNK_LANES};
#[cfg(doc)]
use super::Imager;

/// The fused column pass of a chunk of bands: for every block of [`BLOCK_COLS`] column
/// frequencies (blocks in parallel), every band's columns are copied into a per-worker
/// buffer and transformed there ([`RealFft2::column_region_forward`]: the row pass left
/// them contiguous), then one pass over the block adds all bands, in band order, to each
/// accumulator sample:
/// `acc += spec_b · w_b · A(f) · P_b(ρ(f))`, with A the achromatic product and P_b band
/// b's chromatic profile, all bands interpolated at once from the chunk's common ρ grid
/// ([`ChunkProfile::eval_all`]; no per-band OTF array, no frame-sized transpose; the
/// accumulator and the ρ table are loaded once per chunk, not once per band). `acc_t`
/// and `radial` are in the transposed `[fx][fy]` layout. Every sample is computed by one
/// worker with the same operations in the same order whatever the thread count, so the
/// result does not depend on it.
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
    radial: &[[f64; 2]],
    acc_t: &mut [Complex64],
) {
    let rows = fft.shape().0;
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
    let zero = num_complex::Complex::new(T::zero(), T::zero());
    acc_t
        .par_chunks_mut(block)
        .zip(radial.par_chunks(block))
        .zip(regions.into_par_iter())
        .for_each_init(
            || (vec![zero; nb * block], fft.column_region_scratch()),
            |(buf, sc), ((a, r), bands)| {
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
                if let (Ok(blocks), Ok(w)) = (
                    <[&[num_complex::Complex<T>]; CHUNK_LANES]>::try_from(&blocks[..]),
                    <[f64; CHUNK_LANES]>::try_from(&weights[..nb]),
                ) {
                    accumulate_block_full(a, r, blocks, w, profile);
                    return;
                }
                let mut g = [0.0; CHUNK_LANES];
                for (k, (a, p)) in a.iter_mut().zip(r).enumerate() {
                    if p[1] == 0.0 {
                        continue;
                    }
                    profile.eval_all(p[0], &mut g);
                    let mut sum = *a;
                    for ((blk, w), gc) in blocks.iter().zip(weights).zip(&g) {
                        let s = blk[k];
                        let s = Complex64::new(s.re.widen(), s.im.widen());
                        sum += s * (w * p[1] * gc);
                    }
                    *a = sum;
                }
            },
        );
}

/// [`accumulate_chunk`]'s sample loop for a full chunk ([`CHUNK_LANES`] bands): the same
/// operations in the same order, with the bands as fixed-size arrays (no per-band bounds
/// checks or loop bookkeeping inside the loop over samples).
///
/// On x86-64 CPUs with AVX2 (detected at run time) the same source is compiled for AVX2
/// ([`accumulate_block_avx2`]): 256-bit vectors for the four lanes, the same IEEE
/// operations in the same order (Rust never fuses a multiply and an add into an FMA), so
/// the same result bit for bit on every CPU.
#[inline(never)]
fn accumulate_block_full<T: FftFloat>(
    acc: &mut [Complex64],
    radial: &[[f64; 2]],
    blocks: [&[num_complex::Complex<T>]; CHUNK_LANES],
    weights: [f64; CHUNK_LANES],
    profile: &ChunkProfile,
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        unsafe { accumulate_block_avx2(acc, radial, blocks, weights, profile) };
        return;
    }
    accumulate_block_body(acc, radial, blocks, weights, profile);
}

/// [`accumulate_block_body`] compiled for AVX2.
///
/// # Safety
/// The CPU must support AVX2 (`is_x86_feature_detected!("avx2")`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn accumulate_block_avx2<T: FftFloat>(
    acc: &mut [Complex64],
    radial: &[[f64; 2]],
    blocks: [&[num_complex::Complex<T>]; CHUNK_LANES],
    weights: [f64; CHUNK_LANES],
    profile: &ChunkProfile,
) {
    accumulate_block_body(acc, radial, blocks, weights, profile);
}

/// The sample loop of [`accumulate_block_full`].
#[inline(always)]
fn accumulate_block_body<T: FftFloat>(
    acc: &mut [Complex64],
    radial: &[[f64; 2]],
    blocks: [&[num_complex::Complex<T>]; CHUNK_LANES],
    weights: [f64; CHUNK_LANES],
    profile: &ChunkProfile,
) {
    let n = acc.len().min(radial.len());
    let blocks = blocks.map(|b| &b[..n]);
    let mut g = [0.0; CHUNK_LANES];
    for (k, (a, p)) in acc[..n].iter_mut().zip(&radial[..n]).enumerate() {
        if p[1] == 0.0 {
            continue;
        }
        profile.eval_all(p[0], &mut g);
        let mut sum = *a;
        for c in 0..CHUNK_LANES {
            let s = blocks[c][k];
            let s = Complex64::new(s.re.widen(), s.im.widen());
            sum += s * (weights[c] * p[1] * g[c]);
        }
        *a = sum;
    }
}
