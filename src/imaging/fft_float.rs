//! The element types of the imaging engine's transforms (f32 or f64, [`FftFloat`]) with
//! their per-type kernels: the untangling step of the real-to-complex row transform
//! (portable, and four pairs per AVX vector for f32) and the transposing tile store
//! (whose portable and AVX forms live with the other layout moves in
//! [`super::transpose`]); and [`RowStores`], how the row pass writes its spectra. Below
//! [`super::r2c`] and [`super::fft`], which use them.

use std::sync::Arc;

use num_complex::Complex;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::{Fft, FftDirection, FftNum, FftPlanner};

#[cfg(target_arch = "x86_64")]
use super::transpose::store_tile8_transposed_avx;
use super::transpose::{store_tile_transposed_scalar, TILE_ROWS};

/// How the row pass writes its spectra ([`super::fft::RealFft2::rows_forward_transposed`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RowStores {
    /// Ordinary stores: the spectra stay in cache for a reader that comes soon, while
    /// they still fit there.
    Cached,
    /// Non-temporal stores where the destination is aligned (a [`super::fft::SpectrumBuffer`]), f32
    /// on CPUs with AVX: each 64-byte line is written without first being read from
    /// memory (no read-for-ownership), and not kept in cache. For spectra too large to be
    /// read back from the cache anyway.
    Streaming,
}

/// Floating-point type of a transform (f32 or f64), with lossless widening to f64.
pub trait FftFloat: FftNum + Copy {
    /// A complex transform of length `n` (`rustfft`'s planner). Planned in this crate for
    /// each type (`#[inline(never)]`), so a generic user instantiated in another crate —
    /// [`super::fft::RealFft2`] in an example or a test — calls it instead of compiling
    /// `rustfft`'s algorithms for itself (a minute of build time each).
    fn plan_complex(n: usize, direction: FftDirection) -> Arc<dyn Fft<Self>>;
    /// A real-to-complex transform of length `n` (`realfft`'s planner), as
    /// [`Self::plan_complex`].
    fn plan_real_forward(n: usize) -> Arc<dyn RealToComplex<Self>>;
    /// A complex-to-real transform of length `n` (`realfft`'s planner), as
    /// [`Self::plan_complex`].
    fn plan_real_inverse(n: usize) -> Arc<dyn ComplexToReal<Self>>;

    /// Nearest value of this type (rounding for f32).
    fn nearest_from_f64(x: f64) -> Self;
    /// Exact widening to f64.
    fn widen(self) -> f64;

    /// Stores rows `0..nr` of `tile` (`[nr][hc]`, row-major) transposed: element u of row
    /// `dr` goes to `pieces[u][t0 + dr]` (the transposing store of
    /// [`super::fft::RealFft2::rows_forward_transposed`]), with `stores` as a hint (the f32 AVX store
    /// streams aligned lines for [`RowStores::Streaming`]). A pure copy: the same bits
    /// whatever the implementation.
    fn store_tile_transposed(
        tile: &[Complex<Self>],
        hc: usize,
        nr: usize,
        t0: usize,
        pieces: &mut [&mut [Complex<Self>]],
        _stores: RowStores,
    ) {
        store_tile_transposed_scalar(tile, hc, nr, t0, pieces, 0);
    }

    /// The untangling step of the real-to-complex row transform (`imaging::r2c`): pair i
    /// is `left[i]` with `right[right.len() − 1 − i]` and twiddle `tw[i]` (all three the
    /// same length). The same bits whatever the implementation.
    fn untangle_r2c(tw: &[Complex<Self>], left: &mut [Complex<Self>], right: &mut [Complex<Self>]) {
        untangle_pairs_scalar(tw, left, right);
    }

    /// Whether every value is physical radiance (finite and ≥ 0, at most `f32::MAX`):
    /// [`crate::scene::radiance_is_physical`] for values that are exact copies of f32
    /// input samples, as the image part of a padded row is.
    fn all_physical(values: &[Self]) -> bool {
        let max = f32::MAX as f64;
        values
            .iter()
            .fold(true, |ok, v| ok & (v.widen() >= 0.0) & (v.widen() <= max))
    }

    /// The same slices typed as f32, if `Self` is f32 (for loops written for f32 data
    /// only, such as the AVX2 accumulation of [`super::accumulate_chunk`]); `None` for f64.
    fn as_f32_slices<const N: usize>(
        slices: [&[Complex<Self>]; N],
    ) -> Option<[&[Complex<f32>]; N]> {
        let _ = slices;
        None
    }
}

/// The [`FftFloat`] planning methods, the same body for f32 and f64: each a monomorphic
/// function of this crate (`#[inline(never)]`), see [`FftFloat::plan_complex`].
macro_rules! plans_in_this_crate {
    () => {
        #[inline(never)]
        fn plan_complex(n: usize, direction: FftDirection) -> Arc<dyn Fft<Self>> {
            FftPlanner::new().plan_fft(n, direction)
        }
        #[inline(never)]
        fn plan_real_forward(n: usize) -> Arc<dyn RealToComplex<Self>> {
            RealFftPlanner::new().plan_fft_forward(n)
        }
        #[inline(never)]
        fn plan_real_inverse(n: usize) -> Arc<dyn ComplexToReal<Self>> {
            RealFftPlanner::new().plan_fft_inverse(n)
        }
    };
}

impl FftFloat for f32 {
    plans_in_this_crate!();
    fn all_physical(values: &[Self]) -> bool {
        crate::scene::radiance_is_physical(values)
    }
    fn as_f32_slices<const N: usize>(
        slices: [&[Complex<Self>]; N],
    ) -> Option<[&[Complex<f32>]; N]> {
        Some(slices)
    }
    fn untangle_r2c(tw: &[Complex<Self>], left: &mut [Complex<Self>], right: &mut [Complex<Self>]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx") {
            // SAFETY: the CPU supports AVX (checked just above).
            unsafe { untangle_pairs_f32_avx(tw, left, right) };
            return;
        }
        untangle_pairs_scalar(tw, left, right);
    }
    #[inline]
    fn nearest_from_f64(x: f64) -> Self {
        x as f32
    }
    #[inline]
    fn widen(self) -> f64 {
        self as f64
    }
    fn store_tile_transposed(
        tile: &[Complex<Self>],
        hc: usize,
        nr: usize,
        t0: usize,
        pieces: &mut [&mut [Complex<Self>]],
        stores: RowStores,
    ) {
        #[cfg(target_arch = "x86_64")]
        if nr == TILE_ROWS && std::arch::is_x86_feature_detected!("avx") {
            let streaming = stores == RowStores::Streaming;
            // SAFETY: the CPU supports AVX (checked just above).
            unsafe { store_tile8_transposed_avx(tile, hc, t0, pieces, streaming) };
            return;
        }
        let _ = stores;
        store_tile_transposed_scalar(tile, hc, nr, t0, pieces, 0);
    }
}

impl FftFloat for f64 {
    plans_in_this_crate!();
    #[inline]
    fn nearest_from_f64(x: f64) -> Self {
        x
    }
    #[inline]
    fn widen(self) -> f64 {
        self
    }
}

/// The portable untangling of pairs: `left[i]` pairs with `right[right.len() − 1 − i]`
/// and twiddle `tw[i]` (`realfft` 3.5's loop, operation for operation).
pub(super) fn untangle_pairs_scalar<T: FftFloat>(
    tw: &[Complex<T>],
    left: &mut [Complex<T>],
    right: &mut [Complex<T>],
) {
    let half = T::nearest_from_f64(0.5);
    for ((w, out), out_rev) in tw.iter().zip(left.iter_mut()).zip(right.iter_mut().rev()) {
        let sum = *out + *out_rev;
        let diff = *out - *out_rev;
        let twiddled_re_sum = sum * w.re;
        let twiddled_im_sum = sum * w.im;
        let twiddled_re_diff = diff * w.re;
        let twiddled_im_diff = diff * w.im;
        let half_sum_re = half * sum.re;
        let half_diff_im = half * diff.im;
        let output_twiddled_real = twiddled_re_sum.im + twiddled_im_diff.re;
        let output_twiddled_im = twiddled_im_sum.im - twiddled_re_diff.re;
        *out = Complex::new(
            half_sum_re + output_twiddled_real,
            half_diff_im + output_twiddled_im,
        );
        *out_rev = Complex::new(
            half_sum_re - output_twiddled_real,
            output_twiddled_im - half_diff_im,
        );
    }
}

/// [`untangle_pairs_scalar`] for f32 with AVX, four pairs per iteration: left samples
/// i..i+4 and the matching right samples (loaded as one vector and reversed) are untangled
/// lane by lane with the same IEEE operations (a − b as a + (−b) where the lanes need
/// opposite signs: the same result bit for bit), the pairs left over by the scalar loop.
///
/// # Safety
/// The CPU must support AVX (`is_x86_feature_detected!("avx")`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
pub(super) unsafe fn untangle_pairs_f32_avx(
    tw: &[Complex<f32>],
    left: &mut [Complex<f32>],
    right: &mut [Complex<f32>],
) {
    use std::arch::x86_64::*;
    let pairs = tw.len();
    assert!(left.len() == pairs && right.len() == pairs);
    let n4 = pairs / 4 * 4;
    // Lanes [re, im, re, im, …]: the odd (imaginary) lanes' sign bit.
    let odd_sign = _mm256_castsi256_ps(_mm256_setr_epi32(
        0,
        i32::MIN,
        0,
        i32::MIN,
        0,
        i32::MIN,
        0,
        i32::MIN,
    ));
    let half = _mm256_set1_ps(0.5);
    // Reverses the order of four complex f32 (64-bit elements).
    let reverse = |v: __m256| {
        _mm256_castpd_ps(_mm256_permute2f128_pd(
            _mm256_permute_pd(_mm256_castps_pd(v), 0b0101),
            _mm256_permute_pd(_mm256_castps_pd(v), 0b0101),
            0x01,
        ))
    };
    for i in (0..n4).step_by(4) {
        // Right samples of pairs i..i+4: right[pairs−1−i−3 ..= pairs−1−i], reversed.
        let r0 = pairs - i - 4;
        let lp = left[i..i + 4].as_mut_ptr().cast::<f32>();
        let rp = right[r0..r0 + 4].as_mut_ptr().cast::<f32>();
        let w = _mm256_loadu_ps(tw[i..i + 4].as_ptr().cast::<f32>());
        let l = _mm256_loadu_ps(lp);
        let r = reverse(_mm256_loadu_ps(rp));
        let sum = _mm256_add_ps(l, r);
        let diff = _mm256_sub_ps(l, r);
        // [S_im w_re, S_im w_im] and [D_re w_im, D_re w_re].
        let p = _mm256_mul_ps(_mm256_movehdup_ps(sum), w);
        let q = _mm256_mul_ps(_mm256_moveldup_ps(diff), _mm256_permute_ps(w, 0b1011_0001));
        // [S_im w_re + D_re w_im, S_im w_im − D_re w_re]: the twiddled outputs.
        let o = _mm256_add_ps(p, _mm256_xor_ps(q, odd_sign));
        // [½S_re, ½D_im].
        let h = _mm256_mul_ps(half, _mm256_blend_ps(sum, diff, 0b1010_1010));
        let out = _mm256_add_ps(h, o);
        let out_rev = _mm256_blend_ps(_mm256_sub_ps(h, o), _mm256_sub_ps(o, h), 0b1010_1010);
        _mm256_storeu_ps(lp, out);
        _mm256_storeu_ps(rp, reverse(out_rev));
    }
    let rest = pairs - n4;
    untangle_pairs_scalar(&tw[n4..], &mut left[n4..], &mut right[..rest]);
}
