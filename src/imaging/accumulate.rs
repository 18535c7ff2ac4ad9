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
///
/// For f32 spectra (the default precision) the AVX2 loop is [`accumulate_block_f32_avx2`]:
/// four samples at a time, the same operations per sample, hence the same bits.
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
        if let Some(blocks) = T::as_f32_slices(blocks) {
            // SAFETY: the CPU supports AVX2 (checked just above).
            unsafe { accumulate_block_f32_avx2(acc, radial, blocks, weights, profile) };
        } else {
            // SAFETY: the CPU supports AVX2 (checked just above).
            unsafe { accumulate_block_avx2(acc, radial, blocks, weights, profile) };
        }
        return;
    }
    accumulate_block_body(acc, radial, blocks, weights, profile);
}

/// [`accumulate_block_body`] for f32 spectra, four frequency samples per step with AVX2
/// intrinsics (the scalar loop spends most of its instructions moving single lanes: one
/// table position, one weight and one factor at a time).
///
/// Per step of four samples, with the samples as the four lanes:
/// 1. ρ and A of the four samples; the table position `i` and `frac` computed as
///    [`ChunkProfile::eval_all`] computes them (`min(⌊max(t, 0)⌋, len − 2)` equals its
///    saturating `t as u32` clamped to `len − 2`, and `min(t − i, 1)` its `frac`);
/// 2. the two table rows of each sample loaded (their lanes are the bands) and transposed
///    4 × 4 so that the lanes are the samples;
/// 3. per band c: `a + frac·(b − a)`, 0 beyond the band's cut, times the aerosol plateau,
///    then the factor `(w_c·A)·g` and `acc += s·factor` for the two pairs of samples
///    (one 256-bit vector holds two complex f64), bands in order 0, 1, 2, 3.
///
/// Two tests are made once per step rather than per band: where no sample is beyond the
/// chunk's smallest cut, the cut masks are skipped (they would keep every value), and
/// where every sample is above the bound past which every lane is certainly on its aerosol
/// plateau (the profile's, which [`ChunkProfile::eval_all`] uses too), the exact per-lane
/// plateau test is skipped.
///
/// These are the scalar loop's IEEE operations in its order, lane by lane (no FMA), so the
/// result is the same bit for bit (`the_f32_avx2_loop_equals_the_scalar_loop_bit_for_bit`).
/// Steps where a sample has A = 0 (the scalar loop skips it) or where a sample is not past
/// every band's aerosol table (the scalar loop then evaluates the tables; only next to
/// ρ = 0) and the last `n mod 4` samples go through the scalar loop itself.
///
/// # Safety
/// The CPU must support AVX2 (`is_x86_feature_detected!("avx2")`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn accumulate_block_f32_avx2(
    acc: &mut [Complex64],
    radial: &[[f64; 2]],
    blocks: [&[num_complex::Complex<f32>]; CHUNK_LANES],
    weights: [f64; CHUNK_LANES],
    profile: &ChunkProfile,
) {
    use super::fft::transpose_4x4_pd;
    use std::arch::x86_64::*;
    const _: () = assert!(CHUNK_LANES == 4);
    let n = acc.len().min(radial.len());
    let (acc, radial) = (&mut acc[..n], &radial[..n]);
    let blocks = blocks.map(|b| &b[..n]);
    let lanes = profile.lanes();
    let values = lanes.values;
    if values.len() < 2 {
        accumulate_block_body(acc, radial, blocks, weights, profile);
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
    let steps = n / 4;
    for q in 0..steps {
        let k = 4 * q;
        // [ρ0, A0, ρ1, A1] and [ρ2, A2, ρ3, A3] → [ρ0, ρ1, ρ2, ρ3] and [A0, A1, A2, A3].
        let r01 = _mm256_loadu_pd(radial[k..k + 2].as_ptr().cast());
        let r23 = _mm256_loadu_pd(radial[k + 2..k + 4].as_ptr().cast());
        let rho = _mm256_permute4x64_pd::<0b11_01_10_00>(_mm256_unpacklo_pd(r01, r23));
        let amp = _mm256_permute4x64_pd::<0b11_01_10_00>(_mm256_unpackhi_pd(r01, r23));
        let mut scalar = _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_EQ_OQ>(amp, zero)) != 0;
        let surely_past = _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_GT_OQ>(rho, past_from));
        if let (Some((sc, end, _)), false) = (&plateau, surely_past == 0b1111) {
            let mut past = _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_mul_pd(rho, sc[0]), end[0]);
            for c in 1..CHUNK_LANES {
                let p = _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_mul_pd(rho, sc[c]), end[c]);
                past = _mm256_and_pd(past, p);
            }
            scalar |= _mm256_movemask_pd(past) != 0b1111;
        }
        if scalar {
            accumulate_block_body(
                &mut acc[k..k + 4],
                &radial[k..k + 4],
                blocks.map(|b| &b[k..k + 4]),
                weights,
                profile,
            );
            continue;
        }
        let t = _mm256_mul_pd(rho, inv_step);
        // 0 ≤ max(t, 0) clamped to len − 2 < 2^22: the conversion to i32 is exact.
        let pos = _mm256_cvttpd_epi32(_mm256_min_pd(_mm256_max_pd(t, zero), top));
        let frac = _mm256_min_pd(_mm256_sub_pd(t, _mm256_cvtepi32_pd(pos)), one);
        let at = [
            _mm_cvtsi128_si32(pos),
            _mm_extract_epi32::<1>(pos),
            _mm_extract_epi32::<2>(pos),
            _mm_extract_epi32::<3>(pos),
        ];
        // SAFETY: each position is in 0 ..= len − 2 (clamped above), so rows i and i + 1
        // are inside `values`.
        let row = |j: usize, d: usize| {
            _mm256_loadu_pd(values.as_ptr().add(at[j] as usize + d).cast::<f64>())
        };
        let a = [row(0, 0), row(1, 0), row(2, 0), row(3, 0)];
        let b = [row(0, 1), row(1, 1), row(2, 1), row(3, 1)];
        let d = [0, 1, 2, 3].map(|j| _mm256_sub_pd(b[j], a[j]));
        let (a, d) = (transpose_4x4_pd(a), transpose_4x4_pd(d));
        let any_cut = _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_GT_OQ>(rho, first_cut)) != 0;
        let mut s01 = _mm256_loadu_pd(acc[k..k + 2].as_ptr().cast());
        let mut s23 = _mm256_loadu_pd(acc[k + 2..k + 4].as_ptr().cast());
        for c in 0..CHUNK_LANES {
            let v = _mm256_add_pd(a[c], _mm256_mul_pd(frac, d[c]));
            let mut g = if any_cut {
                _mm256_andnot_pd(_mm256_cmp_pd::<_CMP_GT_OQ>(rho, cut[c]), v)
            } else {
                v
            };
            if let Some((_, _, beyond)) = &plateau {
                g = _mm256_mul_pd(g, beyond[c]);
            }
            let f = _mm256_mul_pd(_mm256_mul_pd(w[c], amp), g);
            // [f0, f0, f1, f1] and [f2, f2, f3, f3]: one factor per complex sample.
            let f01 = _mm256_permute4x64_pd::<0b01_01_00_00>(f);
            let f23 = _mm256_permute4x64_pd::<0b11_11_10_10>(f);
            let x01 = _mm256_cvtps_pd(_mm_loadu_ps(blocks[c][k..k + 2].as_ptr().cast()));
            let x23 = _mm256_cvtps_pd(_mm_loadu_ps(blocks[c][k + 2..k + 4].as_ptr().cast()));
            s01 = _mm256_add_pd(s01, _mm256_mul_pd(x01, f01));
            s23 = _mm256_add_pd(s23, _mm256_mul_pd(x23, f23));
        }
        _mm256_storeu_pd(acc[k..k + 2].as_mut_ptr().cast(), s01);
        _mm256_storeu_pd(acc[k + 2..k + 4].as_mut_ptr().cast(), s23);
    }
    let k = 4 * steps;
    accumulate_block_body(
        &mut acc[k..],
        &radial[k..],
        blocks.map(|b| &b[k..]),
        weights,
        profile,
    );
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
            let n = 4 * 2500 + 3;
            let radial: Vec<[f64; 2]> = (0..n)
                .map(|k| {
                    let rho = match k % 5 {
                        // Past the grid's end and across every cut.
                        0 => 1.2 * rho_max * rng.random::<f64>(),
                        // The aerosol cores (ρ < a/λ, a few cycles/rad).
                        1 if k < 400 => 3.0 * rng.random::<f64>(),
                        // A smooth run, as along a column of the spectrum.
                        _ => rho_max * (k as f64 / n as f64),
                    };
                    let amp = match k % 97 {
                        13 => 0.0,
                        41 => -0.0,
                        _ => 2.0 * rng.random::<f64>() - 0.5,
                    };
                    [rho, amp]
                })
                .collect();
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
            accumulate_block_full(&mut fast, &radial, blocks, weights, &profile);
            accumulate_block_body(&mut slow, &radial, blocks, weights, &profile);
            let mut changed = 0;
            for (k, ((f, s), s0)) in fast.iter().zip(&slow).zip(&start).enumerate() {
                assert!(
                    f.re.to_bits() == s.re.to_bits() && f.im.to_bits() == s.im.to_bits(),
                    "aerosol {aerosol}, diffraction {diffraction}, sample {k} (ρ {}, A {}): \
                     {f:?} against {s:?}",
                    radial[k][0],
                    radial[k][1]
                );
                changed += (s != s0) as usize;
            }
            // Most samples received something (the loops did work, the test can fail).
            assert!(changed > n / 2, "only {changed} of {n} samples changed");
        }
    }
}
