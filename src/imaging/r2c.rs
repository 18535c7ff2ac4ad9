//! The real-to-complex transform of one row (length n, unnormalised, n/2 + 1 outputs) for
//! the engine's row pass.
//!
//! For even n this is the standard split algorithm (the one `realfft`'s
//! `RealToComplexEven` uses): the n reals are read as n/2 complex values z_m = x_2m +
//! i·x_2m+1, transformed by a complex FFT of length n/2 (Z), and each pair (k, n/2 − k)
//! is untangled with one twiddle w_k = ½·e^(−2πik/n):
//!
//! ```text
//! S = Z_k + Z_(n/2−k),  D = Z_k − Z_(n/2−k)
//! X_k       = ( ½S_re + (S_im w_re + D_re w_im),  ½D_im + (S_im w_im − D_re w_re))
//! X_(n/2−k) = ( ½S_re − (S_im w_re + D_re w_im), (S_im w_im − D_re w_re) − ½D_im)
//! X_0 = Z_0,re + Z_0,im,  X_(n/2) = Z_0,re − Z_0,im,  and for n mod 4 = 0 X_(n/4) = conj(Z_(n/4))
//! ```
//!
//! The same inner plan, the same twiddles and the same IEEE operations in the same order
//! as `realfft` 3.5, so the same bits (a unit test compares them for many lengths);
//! what differs is that the untangling loop, which `realfft` runs one pair at a time
//! (`perf`: 10 % of a 1024² × 128 run), runs four pairs per 256-bit vector for f32 on
//! CPUs with AVX ([`FftFloat::untangle_r2c`]). Odd n is left to `realfft`.

use std::sync::Arc;

use num_complex::Complex;
use realfft::RealToComplex;
use rustfft::{Fft, FftDirection};

#[cfg(all(test, target_arch = "x86_64"))]
use super::fft_float::untangle_pairs_f32_avx;
#[cfg(test)]
use super::fft_float::untangle_pairs_scalar;
use super::fft_float::FftFloat;

/// A planned real-to-complex transform of one length (see the module documentation).
pub(crate) struct RealForward<T: FftFloat> {
    plan: Plan<T>,
}

enum Plan<T: FftFloat> {
    /// Even length: inner complex FFT of n/2 and the untangling twiddles ½·e^(−2πik/n),
    /// k = 1 .. ⌈n/4⌉ − 1 (as `realfft` computes them: in f64, rounded to T, halved).
    Even {
        n: usize,
        inner: Arc<dyn Fft<T>>,
        twiddles: Vec<Complex<T>>,
        scratch_len: usize,
    },
    /// Odd length: `realfft`'s transform.
    Odd(Arc<dyn RealToComplex<T>>),
}

impl<T: FftFloat> std::fmt::Debug for RealForward<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "RealForward({})", self.len())
    }
}

impl<T: FftFloat> RealForward<T> {
    /// Plans the transform of length `n` ≥ 1.
    pub(crate) fn new(n: usize) -> Self {
        if n % 2 == 1 {
            return RealForward {
                plan: Plan::Odd(T::plan_real_forward(n)),
            };
        }
        let inner = T::plan_complex(n / 2, FftDirection::Forward);
        let count = if n % 4 == 0 { n / 4 } else { n / 4 + 1 };
        let half = T::nearest_from_f64(0.5);
        let twiddles = (1..count)
            .map(|k| {
                let angle = -2.0 * std::f64::consts::PI / n as f64 * k as f64;
                let w = Complex::new(
                    T::nearest_from_f64(angle.cos()),
                    T::nearest_from_f64(angle.sin()),
                );
                w * half
            })
            .collect();
        let scratch_len = inner.get_outofplace_scratch_len();
        RealForward {
            plan: Plan::Even {
                n,
                inner,
                twiddles,
                scratch_len,
            },
        }
    }

    /// Input length n.
    pub(crate) fn len(&self) -> usize {
        match &self.plan {
            Plan::Even { n, .. } => *n,
            Plan::Odd(p) => p.len(),
        }
    }

    /// A scratch buffer for [`RealForward::process`].
    pub(crate) fn make_scratch_vec(&self) -> Vec<Complex<T>> {
        let len = match &self.plan {
            Plan::Even { scratch_len, .. } => *scratch_len,
            Plan::Odd(p) => p.get_scratch_len(),
        };
        vec![Complex::new(T::zero(), T::zero()); len]
    }

    /// Transforms `input` (length n; used as work space, its contents are lost) into
    /// `output` (length n/2 + 1). `scratch` from [`RealForward::make_scratch_vec`].
    ///
    /// # Panics
    /// If a length does not match the plan (a programming error in the engine).
    pub(crate) fn process(
        &self,
        input: &mut [T],
        output: &mut [Complex<T>],
        scratch: &mut [Complex<T>],
    ) {
        match &self.plan {
            Plan::Odd(p) => p
                .process_with_scratch(input, output, scratch)
                .expect("RealForward: lengths match the plan"),
            Plan::Even {
                n,
                inner,
                twiddles,
                scratch_len,
            } => {
                let h = n / 2;
                assert!(
                    input.len() == *n && output.len() == h + 1 && scratch.len() >= *scratch_len,
                    "RealForward: lengths match the plan"
                );
                // SAFETY: `Complex<T>` is `#[repr(C)] { re: T, im: T }`, with T's alignment;
                // the n = 2h values of `input` are h complex values, borrowed mutably once.
                let z: &mut [Complex<T>] =
                    unsafe { std::slice::from_raw_parts_mut(input.as_mut_ptr().cast(), h) };
                inner.process_outofplace_with_scratch(
                    z,
                    &mut output[..h],
                    &mut scratch[..*scratch_len],
                );
                untangle(output, twiddles);
            }
        }
    }
}

/// Turns the inner transform Z (in `out[..n/2]`) into the real transform X in place (module
/// documentation): X_0 and X_(n/2) from Z_0, the pairs by [`FftFloat::untangle_r2c`], and
/// the middle sample conjugated when n/2 + 1 is odd. `realfft` 3.5's order of operations.
fn untangle<T: FftFloat>(out: &mut [Complex<T>], twiddles: &[Complex<T>]) {
    let len = out.len();
    let z0 = out[0];
    out[0] = Complex::new(z0.re + z0.im, T::zero());
    out[len - 1] = Complex::new(z0.re - z0.im, T::zero());
    // Pairs (k, n/2 − k), k = 1 ..: left runs up from 1, right down from n/2 − 1.
    let (left, right) = out.split_at_mut(len / 2);
    let left = &mut left[1..];
    let rl = right.len();
    let right = &mut right[..rl - 1];
    let pairs = twiddles.len().min(left.len()).min(right.len());
    let rl = right.len();
    T::untangle_r2c(
        &twiddles[..pairs],
        &mut left[..pairs],
        &mut right[rl - pairs..],
    );
    if len % 2 == 1 {
        let mid = &mut out[len / 2];
        mid.im = -mid.im;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check<T: FftFloat + PartialEq>(n: usize) {
        let reference = realfft::RealFftPlanner::<T>::new().plan_fft_forward(n);
        let ours = RealForward::<T>::new(n);
        assert_eq!(ours.len(), n);
        // A deterministic, irregular signal with a large mean (as radiance has).
        let x: Vec<T> = (0..n)
            .map(|i| {
                let t = i as f64;
                T::nearest_from_f64(
                    7.0 + (0.37 * t).sin() + 0.01 * (t * t * 0.013).cos() - (t / 97.0),
                )
            })
            .collect();
        let mut a = x.clone();
        let mut b = x;
        let mut out_a = reference.make_output_vec();
        let mut out_b = out_a.clone();
        let mut sa = reference.make_scratch_vec();
        let mut sb = ours.make_scratch_vec();
        reference
            .process_with_scratch(&mut a, &mut out_a, &mut sa)
            .unwrap();
        ours.process(&mut b, &mut out_b, &mut sb);
        for (k, (p, q)) in out_a.iter().zip(&out_b).enumerate() {
            assert!(
                p.re.widen().to_bits() == q.re.widen().to_bits()
                    && p.im.widen().to_bits() == q.im.widen().to_bits(),
                "n = {n}, k = {k}: realfft {p:?}, ours {q:?}"
            );
        }
    }

    #[test]
    fn the_row_transform_equals_realfft_bit_for_bit() {
        // Even lengths with n/2 odd and even, n mod 4 = 0 and 2, short ones (tails only),
        // the engine's padded sizes, and odd ones (delegated).
        let lengths = [
            1, 2, 3, 4, 6, 8, 10, 12, 14, 16, 18, 20, 30, 34, 36, 50, 64, 90, 100, 250, 270, 360,
            486, 540, 1000, 1024, 1080, 1125, 1350, 2048, 2160,
        ];
        for n in lengths {
            check::<f32>(n);
            check::<f64>(n);
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_avx_untangling_equals_the_portable_loop_bit_for_bit() {
        if !std::arch::is_x86_feature_detected!("avx") {
            return;
        }
        for pairs in [0usize, 1, 3, 4, 5, 8, 13, 269] {
            let tw: Vec<Complex<f32>> = (0..pairs)
                .map(|k| Complex::new((k as f32 * 0.1).cos() * 0.5, -(k as f32 * 0.1).sin() * 0.5))
                .collect();
            // Values with zeros, equal pairs (signed-zero cases) and mixed magnitudes.
            let v = |k: usize, s: f32| match k % 5 {
                0 => Complex::new(0.0, 0.0),
                1 => Complex::new(1.0, -1.0),
                _ => Complex::new(s * k as f32 * 1.7, -s * (k as f32).sqrt()),
            };
            let left: Vec<Complex<f32>> = (0..pairs).map(|k| v(k, 1.0)).collect();
            let right: Vec<Complex<f32>> = (0..pairs).map(|k| v(pairs - 1 - k, 1.0)).collect();
            let (mut l1, mut r1) = (left.clone(), right.clone());
            let (mut l2, mut r2) = (left, right);
            untangle_pairs_scalar(&tw, &mut l1, &mut r1);
            // SAFETY: AVX checked above.
            unsafe { untangle_pairs_f32_avx(&tw, &mut l2, &mut r2) };
            let bits = |v: &[Complex<f32>]| -> Vec<(u32, u32)> {
                v.iter().map(|c| (c.re.to_bits(), c.im.to_bits())).collect()
            };
            assert_eq!(bits(&l1), bits(&l2), "left, {pairs} pairs");
            assert_eq!(bits(&r1), bits(&r2), "right, {pairs} pairs");
        }
    }
}
