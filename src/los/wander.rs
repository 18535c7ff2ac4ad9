//! Random line-of-sight wander: a stationary Gaussian process with a given one-sided PSD,
//! by spectral synthesis (random-phase Fourier series).
//!
//! On a grid of M samples with step Δt (period L = M·Δt, frequency step Δf = 1/L), each
//! axis is
//!
//! x(t) = Σ_{k=1}^{M/2−1} c_k·(a_k cos 2πf_k t + b_k sin 2πf_k t),  f_k = k·Δf,
//!
//! with a_k, b_k independent N(0, 1) and c_k² = ∫_{f_k−Δf/2}^{f_k+Δf/2} S(f) df, the PSD's
//! exact power in bin k (Shinozuka & Deodatis 1991, "Simulation of stochastic processes
//! by spectral representation", Appl. Mech. Rev. 44(4), 191, with Gaussian amplitudes so
//! the process is Gaussian). Its variance is E[x²] = Σ c_k² = ∫S df whenever the bins cover
//! the PSD's support, which the grid guarantees: Δt ≤ 1/(8 f_max) puts the Nyquist
//! frequency at ≥ 4 f_max, and L ≥ 4/f_min puts the first bin's lower edge Δf/2 below f_min.
//! The series is evaluated by two inverse FFTs (values and exact derivatives at the grid
//! nodes); between nodes x(t) is the cubic Hermite interpolant of those, whose error for a
//! sinusoid of frequency f is at most (2πfΔt)⁴/384 of its amplitude (≤ 1.0·10⁻³ at f_max).
//! The realisation is periodic with period L ≥ twice the sequence's span, so it is defined
//! at every t.
//!
//! The grid step is also ≤ T/8 (T the integration time), so a frame's window holds at least
//! eight grid intervals.

use num_complex::Complex64;
use rand::RngExt;
use rand_distr::StandardNormal;
use rustfft::FftPlanner;

use super::trajectory::Psd;
use crate::detector::rng::{stream, Effect};
use crate::error::{Error, Result};

/// Largest wander grid, samples per axis (2²³ ≈ 8.4 M: 4 arrays of f64 = 256 MiB plus an
/// FFT buffer); a PSD and span that need more are refused with a clear error.
pub const MAX_WANDER_SAMPLES: usize = 1 << 23;

/// A synthesised wander realisation on both axes.
#[derive(Debug, Clone)]
pub(crate) struct Wander {
    t0_s: f64,
    dt_s: f64,
    /// Values per axis at the grid nodes, rad.
    x: [Vec<f64>; 2],
    /// Exact derivatives per axis at the grid nodes, rad/s.
    v: [Vec<f64>; 2],
}

impl Wander {
    /// Synthesises the wander of `psd` for a sequence spanning `span_s` with integration
    /// time `integration_time_s`, from the stream `(seed, LosWander, 0, axis)`.
    pub(crate) fn synthesise(
        psd: &Psd,
        seed: u64,
        span_s: (f64, f64),
        integration_time_s: f64,
    ) -> Result<Wander> {
        let (f_lo, f_hi) = psd.support_hz();
        let t_int = integration_time_s;
        let dt = (t_int / 8.0).min(1.0 / (8.0 * f_hi));
        let span_len = (span_s.1 - span_s.0).max(0.0) + 2.0 * t_int;
        let period_min = (2.0 * span_len).max(4.0 / f_lo);
        let needed = (period_min / dt).ceil();
        if !(needed.is_finite() && needed <= MAX_WANDER_SAMPLES as f64) {
            return Err(Error::param(
                "trajectory.wander",
                format!(
                    "a grid of {needed:.3e} samples (step {dt:.3e} s = min(T/8, 1/(8 f_max)) over {period_min:.3e} s = max(2 × span, 4/f_min))"
                ),
                format!(
                    "at most {MAX_WANDER_SAMPLES} samples: a higher f_min_hz / lowest table frequency, a lower f_max, a longer integration time or a shorter sequence"
                ),
            ));
        }
        let m = crate::fft_size::next_fast_len((needed as usize).max(16));
        crate::limits::check_alloc(
            "the line-of-sight wander grid",
            &[
                ("samples", m as u64),
                ("arrays (2 axes × value, slope, FFT)", 6),
            ],
            8,
        )?;
        let df = 1.0 / (m as f64 * dt);
        let mut fft = FftPlanner::<f64>::new();
        let inverse = fft.plan_fft_inverse(m);
        let mut x: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
        let mut v: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
        for axis in 0..2 {
            let mut rng = stream(seed, Effect::LosWander, 0, axis as u64);
            let mut spec = vec![Complex64::new(0.0, 0.0); m];
            for (k, z) in spec.iter_mut().enumerate().take(m.div_ceil(2)).skip(1) {
                let a: f64 = rng.sample(StandardNormal);
                let b: f64 = rng.sample(StandardNormal);
                let fk = k as f64 * df;
                let c = psd.integral(fk - 0.5 * df, fk + 0.5 * df).sqrt();
                *z = Complex64::new(c * a, -c * b);
            }
            let mut slope: Vec<Complex64> = spec
                .iter()
                .enumerate()
                .map(|(k, z)| z * Complex64::new(0.0, 2.0 * std::f64::consts::PI * k as f64 * df))
                .collect();
            inverse.process(&mut spec);
            inverse.process(&mut slope);
            x[axis] = spec.iter().map(|z| z.re).collect();
            v[axis] = slope.iter().map(|z| z.re).collect();
        }
        Ok(Wander {
            t0_s: span_s.0 - t_int,
            dt_s: dt,
            x,
            v,
        })
    }

    /// Grid interval index (wrapped into the period) and the fraction within it.
    fn locate(&self, t_s: f64) -> (usize, f64) {
        let m = self.x[0].len();
        let u = ((t_s - self.t0_s) / self.dt_s).rem_euclid(m as f64);
        let i = (u.floor() as usize).min(m - 1);
        (i, (u - i as f64).clamp(0.0, 1.0))
    }

    /// The displacement [x, y] at `t_s`, rad (cubic Hermite between grid nodes).
    pub(crate) fn eval(&self, t_s: f64) -> [f64; 2] {
        let m = self.x[0].len();
        let (i, s) = self.locate(t_s);
        let j = (i + 1) % m;
        let h = self.dt_s;
        let (s2, s3) = (s * s, s * s * s);
        let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
        let h10 = s3 - 2.0 * s2 + s;
        let h01 = -2.0 * s3 + 3.0 * s2;
        let h11 = s3 - s2;
        let mut out = [0.0; 2];
        for (axis, o) in out.iter_mut().enumerate() {
            let (x, v) = (&self.x[axis], &self.v[axis]);
            *o = h00 * x[i] + h10 * h * v[i] + h01 * x[j] + h11 * h * v[j];
        }
        out
    }

    /// max |d²x/dt²| per axis over the grid intervals that meet [t0, t1], rad/s²: the
    /// Hermite interpolant's second derivative is linear in each interval, so its maximum
    /// is at an interval's end, (±6(x₁−x₀) ∓ h(4v₀+2v₁) …)/h² in closed form.
    pub(crate) fn max_curvature(&self, t0_s: f64, t1_s: f64) -> [f64; 2] {
        let m = self.x[0].len();
        let h = self.dt_s;
        let intervals = (((t1_s - t0_s) / h).ceil() as usize)
            .saturating_add(2)
            .min(m);
        let (first, _) = self.locate(t0_s);
        let mut out = [0.0f64; 2];
        for n in 0..intervals {
            let i = (first + n) % m;
            let j = (i + 1) % m;
            for (axis, o) in out.iter_mut().enumerate() {
                let (x, v) = (&self.x[axis], &self.v[axis]);
                let dy = x[j] - x[i];
                let at0 = 6.0 * dy - h * (4.0 * v[i] + 2.0 * v[j]);
                let at1 = -6.0 * dy + h * (2.0 * v[i] + 4.0 * v[j]);
                *o = o.max(at0.abs().max(at1.abs()) / (h * h));
            }
        }
        out
    }
}
