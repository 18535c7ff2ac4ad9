//! Sub-pixel translation between two frames by phase correlation.
//!
//! The frames are made periodic-friendly first: the mean is removed and each is multiplied
//! by a separable Tukey (tapered-cosine) window with taper fraction [`WINDOW_TAPER`]
//! (Harris 1978, "On the use of windows for harmonic analysis with the discrete Fourier
//! transform", Proc. IEEE 66, 51), flat in the middle so that content moving inside the
//! frame keeps its weight. With `G_r`, `G_m` their DFTs, the normalised cross-power
//! spectrum (Kuglin & Hines 1975, "The phase correlation image alignment method", Proc.
//! IEEE Conf. Cybernetics and Society, 163)
//!
//! ```text
//! R(f) = W(|f|) · G_m(f) G_r*(f) / |G_m(f) G_r*(f)|
//! ```
//!
//! is a pure phase ramp `exp(−2πi f·d)` when `moving(x) = reference(x − d)`, so its inverse
//! transform `r(x)` peaks at `x = d`. `W` is a low-pass weight: 1 up to
//! [`PASSBAND_CY_PER_PX`] and a raised cosine down to 0 at [`STOPBAND_CY_PER_PX`]
//! (cycles per pixel). It drops the frequencies of an under-sampled camera where the
//! aliases of content between 0.7 and 1 cycle per pixel land — their phases move against
//! the scene's (a sine of 0.625 cycles/px, aliased to 0.375, biased x by 0.15 px with a
//! stop band at 0.45) — and the noise that the normalisation would otherwise give full
//! weight (Stone et al.
//! 2001, "A fast direct Fourier-based algorithm for subpixel registration of images",
//! IEEE Trans. Geosci. Remote Sens. 39, 2235), and the noise that the normalisation would
//! otherwise give full weight.
//!
//! The integer peak of `r` (one inverse FFT) is refined by evaluating `r(x)` directly as
//! the DFT sum at non-integer `x` on two nested grids (steps of 1/20 px over ±1 px around
//! the integer peak, then 1/400 px over ±0.075 px) — the matrix-multiply upsampled DFT of
//! Guizar-Sicairos, Thurman & Fienup 2008 ("Efficient subpixel image registration
//! algorithms", Opt. Lett. 33, 156), which interpolates the correlation exactly as the
//! band-limited function the DFT defines, without zero-padding the whole array.
//!
//! Sign: a [`Translation`] `(dx_px, dy_px)` is the displacement of the moving frame's
//! content relative to the reference, +x toward higher columns and +y toward higher rows —
//! the convention of the truth table `los.csv` (docs/motion.md).

use ndarray::{Array2, ArrayView2, ArrayView3, Axis};
use num_complex::Complex64;

use crate::error::{Error, Result};
use crate::imaging::fft::RealFft2;

/// Taper fraction of the Tukey window (0: rectangular, 1: Hann).
pub const WINDOW_TAPER: f64 = 0.5;

/// Radial frequency (cycles per pixel) up to which the phase correlation weighs every
/// frequency fully.
pub const PASSBAND_CY_PER_PX: f64 = 0.2;

/// Radial frequency (cycles per pixel) from which the phase correlation ignores the
/// spectrum (between the two, a raised-cosine roll-off).
pub const STOPBAND_CY_PER_PX: f64 = 0.3;

/// Smallest frame side accepted for registration, pixels.
pub const MIN_SIDE_PX: usize = 8;

/// The translation of one frame's content relative to a reference frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Translation {
    /// Displacement along columns (+x toward higher column index), pixels.
    pub dx_px: f64,
    /// Displacement along rows (+y toward higher row index), pixels.
    pub dy_px: f64,
    /// Height of the phase-correlation peak relative to a perfect match (1 for identical
    /// content within the weighted band; near 0 when the frames share nothing).
    pub peak: f64,
}

/// Tukey window of `n` samples with taper fraction `alpha` (Harris 1978), evaluated at
/// the continuous sample position `x` (0 … n − 1; 0 outside).
fn tukey_at(x: f64, n: usize, alpha: f64) -> f64 {
    let m = (n - 1) as f64;
    if !(0.0..=m).contains(&x) {
        return 0.0;
    }
    let edge = alpha * m / 2.0;
    let d = x.min(m - x);
    if edge <= 0.0 || d >= edge {
        1.0
    } else {
        0.5 * (1.0 - (std::f64::consts::PI * d / edge).cos())
    }
}

/// Tukey window of `n` samples, shifted by `shift` samples (the window of a frame whose
/// content moved by `shift`).
fn tukey(n: usize, alpha: f64, shift: f64) -> Vec<f64> {
    (0..n)
        .map(|i| tukey_at(i as f64 - shift, n, alpha))
        .collect()
}

/// Signed frequency (cycles per sample) of DFT bin `j` of an `n`-point transform.
fn bin_frequency(j: usize, n: usize) -> f64 {
    if j <= n / 2 {
        j as f64 / n as f64
    } else {
        j as f64 / n as f64 - 1.0
    }
}

/// The low-pass weight W(ρ) of the module documentation.
fn passband_weight(rho: f64) -> f64 {
    if rho <= PASSBAND_CY_PER_PX {
        1.0
    } else if rho >= STOPBAND_CY_PER_PX {
        0.0
    } else {
        let t = (rho - PASSBAND_CY_PER_PX) / (STOPBAND_CY_PER_PX - PASSBAND_CY_PER_PX);
        0.5 * (1.0 + (std::f64::consts::PI * t).cos())
    }
}

/// Registers frames of one size against a fixed reference frame.
#[derive(Debug)]
pub struct Registrar {
    rows: usize,
    cols: usize,
    fft: RealFft2<f64>,
    reference: Array2<Complex64>,
    /// W(ρ) times the multiplicity of each half-plane bin in the full spectrum.
    weight: Array2<f64>,
}

impl Registrar {
    /// Prepares the registration of frames against `reference` (`[row, col]`, finite).
    ///
    /// Errors: a frame smaller than [`MIN_SIDE_PX`] on a side, a non-finite value, or a
    /// reference without contrast in the weighted band.
    pub fn new(reference: ArrayView2<f64>) -> Result<Self> {
        let (rows, cols) = reference.dim();
        if rows < MIN_SIDE_PX || cols < MIN_SIDE_PX {
            return Err(Error::param(
                "registration frame",
                format!("{rows} × {cols} pixels"),
                format!("at least {MIN_SIDE_PX} × {MIN_SIDE_PX} pixels"),
            ));
        }
        let fft = RealFft2::new(rows, cols);
        let (sr, sc) = fft.spectrum_shape();
        let weight = Array2::from_shape_fn((sr, sc), |(j, k)| {
            let mult = if k == 0 || (cols % 2 == 0 && k == cols / 2) {
                1.0
            } else {
                2.0
            };
            let rho = bin_frequency(j, rows).hypot(k as f64 / cols as f64);
            mult * passband_weight(rho)
        });
        let mut r = Registrar {
            rows,
            cols,
            fft,
            reference: Array2::zeros((sr, sc)),
            weight,
        };
        r.reference = r.spectrum("reference frame", reference, 0.0, 0.0)?;
        if r.reference
            .iter()
            .zip(r.weight.iter())
            .skip(1)
            .all(|(g, w)| *w == 0.0 || g.norm() == 0.0)
        {
            return Err(Error::param(
                "reference frame",
                "no contrast",
                "a frame with structure to register on",
            ));
        }
        Ok(r)
    }

    /// Spectrum of a frame, mean removed, windowed by the Tukey window shifted by
    /// (`sx`, `sy`) pixels.
    fn spectrum(
        &self,
        what: &str,
        frame: ArrayView2<f64>,
        sx: f64,
        sy: f64,
    ) -> Result<Array2<Complex64>> {
        if frame.dim() != (self.rows, self.cols) {
            return Err(Error::param(
                what,
                format!("{} × {} pixels", frame.dim().0, frame.dim().1),
                format!("the reference frame's {} × {} pixels", self.rows, self.cols),
            ));
        }
        if let Some(((r, c), v)) = frame.indexed_iter().find(|(_, v)| !v.is_finite()) {
            return Err(Error::param(
                format!("{what}[{r}, {c}]"),
                v,
                "finite values (replace dead pixels first)",
            ));
        }
        let (wy, wx) = (
            tukey(self.rows, WINDOW_TAPER, sy),
            tukey(self.cols, WINDOW_TAPER, sx),
        );
        let mean = frame.mean().unwrap_or(0.0);
        let mut x = Array2::from_shape_fn((self.rows, self.cols), |(r, c)| {
            (frame[[r, c]] - mean) * wy[r] * wx[c]
        });
        let mut spec = Array2::<Complex64>::zeros(self.fft.spectrum_shape());
        self.fft.forward(&mut x, &mut spec, &mut Vec::new());
        Ok(spec)
    }

    /// The translation of `frame`'s content relative to the reference: a first estimate
    /// with the reference's window, then a second with the frame's window moved by that
    /// estimate, so that both windows cover the same content (a window fixed to the frame
    /// pulls the estimate toward zero by a few hundredths of a pixel per pixel of shift).
    ///
    /// Errors: a frame of another size or with non-finite values.
    pub fn register(&self, frame: ArrayView2<f64>) -> Result<Translation> {
        let first = self.register_with_window(frame, 0.0, 0.0)?;
        self.register_with_window(frame, first.dx_px, first.dy_px)
    }

    /// One phase correlation, the frame windowed by the window shifted by (`sx`, `sy`).
    fn register_with_window(
        &self,
        frame: ArrayView2<f64>,
        sx: f64,
        sy: f64,
    ) -> Result<Translation> {
        let g = self.spectrum("frame", frame, sx, sy)?;
        // Normalised, weighted cross-power spectrum (half plane, multiplicity included).
        let mut cross = Array2::<Complex64>::zeros(g.dim());
        let mut total = 0.0;
        ndarray::Zip::from(&mut cross)
            .and(&g)
            .and(&self.reference)
            .and(&self.weight)
            .for_each(|c, gm, gr, w| {
                let p = gm * gr.conj();
                let n = p.norm();
                if *w > 0.0 && n > 0.0 && n.is_finite() {
                    *c = p * (*w / n);
                    total += *w;
                }
            });
        cross[[0, 0]] = Complex64::new(0.0, 0.0);
        if total <= 0.0 {
            return Err(Error::param(
                "frame",
                "no contrast",
                "a frame with structure to register on",
            ));
        }
        // Integer peak: r = inverse DFT of the full-plane spectrum (the half-plane inverse
        // undoes the multiplicity, so divide it out first).
        let mut half = Array2::from_shape_fn(cross.dim(), |(j, k)| {
            let mult = if k == 0 || (self.cols % 2 == 0 && k == self.cols / 2) {
                1.0
            } else {
                2.0
            };
            cross[[j, k]] / mult
        });
        let mut r = Array2::<f64>::zeros((self.rows, self.cols));
        self.fft.inverse(&mut half, &mut r, &mut Vec::new());
        let ((py, px), _) = r
            .indexed_iter()
            .fold(((0, 0), f64::NEG_INFINITY), |best, (i, v)| {
                if *v > best.1 {
                    (i, *v)
                } else {
                    best
                }
            });
        let signed = |i: usize, n: usize| -> f64 {
            if i > n / 2 {
                i as f64 - n as f64
            } else {
                i as f64
            }
        };
        let (mut x0, mut y0) = (signed(px, self.cols), signed(py, self.rows));
        // Two nested direct-DFT refinements (Guizar-Sicairos et al. 2008).
        let mut best = f64::NEG_INFINITY;
        for (half_width, step) in [(1.0, 0.05), (0.075, 0.0025)] {
            let (x, y, v) = self.dft_peak(&cross, x0, y0, half_width, step);
            x0 = x;
            y0 = y;
            best = v;
        }
        Ok(Translation {
            dx_px: x0,
            dy_px: y0,
            peak: best / total,
        })
    }

    /// The maximum of r(x, y) = Σ_half Re(C e^{2πi(fx·x + fy·y)}) on the grid of `step`
    /// covering ±`half_width` around (x0, y0): (x, y, r).
    fn dft_peak(
        &self,
        cross: &Array2<Complex64>,
        x0: f64,
        y0: f64,
        half_width: f64,
        step: f64,
    ) -> (f64, f64, f64) {
        let m = (2.0 * half_width / step).round() as usize + 1;
        let xs: Vec<f64> = (0..m).map(|i| x0 - half_width + i as f64 * step).collect();
        let ys: Vec<f64> = (0..m).map(|i| y0 - half_width + i as f64 * step).collect();
        let (sr, sc) = cross.dim();
        let tau = std::f64::consts::TAU;
        // A[j, i] = Σ_k C[j, k] e^{2πi fx_k x_i}.
        let ex = Array2::from_shape_fn((sc, m), |(k, i)| {
            Complex64::from_polar(1.0, tau * k as f64 / self.cols as f64 * xs[i])
        });
        let a = cross.dot(&ex);
        let ey = Array2::from_shape_fn((m, sr), |(n, j)| {
            Complex64::from_polar(1.0, tau * bin_frequency(j, self.rows) * ys[n])
        });
        let r = ey.dot(&a);
        let mut best = (x0, y0, f64::NEG_INFINITY);
        for ((n, i), v) in r.indexed_iter() {
            if v.re > best.2 {
                best = (xs[i], ys[n], v.re);
            }
        }
        best
    }
}

/// The translation of every frame of `stack` (`[frame, row, col]`) relative to frame
/// `reference`, by [`Registrar::register`]; the reference's own is (0, 0) with peak 1.
///
/// Errors: a reference index outside the stack, and those of [`Registrar`].
pub fn register_stack(stack: ArrayView3<f64>, reference: usize) -> Result<Vec<Translation>> {
    let frames = stack.dim().0;
    if reference >= frames {
        return Err(Error::param(
            "reference frame",
            reference,
            format!("an index below the stack's {frames} frames"),
        ));
    }
    let reg = Registrar::new(stack.index_axis(Axis(0), reference))?;
    (0..frames)
        .map(|k| {
            if k == reference {
                Ok(Translation {
                    dx_px: 0.0,
                    dy_px: 0.0,
                    peak: 1.0,
                })
            } else {
                reg.register(stack.index_axis(Axis(0), k))
                    .map_err(|e| Error::param(format!("frame {k}"), "registration", e.to_string()))
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    use rand_xoshiro::Xoshiro256PlusPlus;

    /// A periodic band-limited random field of `n × n` samples (white noise low-passed by
    /// a Gaussian of σ_f = 0.12 cycles/sample) and the same field shifted by (dx, dy) by
    /// an exact Fourier phase ramp — the ground truth of a translation.
    fn field_pair(n: usize, dx: f64, dy: f64, seed: u64) -> (Array2<f64>, Array2<f64>) {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let normal = Normal::new(0.0, 1.0).unwrap();
        let mut x = Array2::from_shape_fn((n, n), |_| normal.sample(&mut rng));
        let fft = RealFft2::new(n, n);
        let mut spec = Array2::<Complex64>::zeros(fft.spectrum_shape());
        fft.forward(&mut x, &mut spec, &mut Vec::new());
        let sigma_f: f64 = 0.12;
        let mut shifted = spec.clone();
        for ((j, k), g) in spec.indexed_iter_mut() {
            let (fy, fx) = (bin_frequency(j, n), k as f64 / n as f64);
            let w = (-(fx * fx + fy * fy) / (2.0 * sigma_f * sigma_f)).exp();
            *g *= w;
            let phase = Complex64::from_polar(1.0, -std::f64::consts::TAU * (fx * dx + fy * dy));
            shifted[[j, k]] = *g * phase;
            if (n % 2 == 0) && (k == n / 2 || j == n / 2) {
                // The Nyquist bins of a real signal must stay real: drop them (w ≈ 0 there).
                *g = Complex64::new(0.0, 0.0);
                shifted[[j, k]] = Complex64::new(0.0, 0.0);
            }
        }
        let mut a = Array2::zeros((n, n));
        let mut b = Array2::zeros((n, n));
        fft.inverse(&mut spec, &mut a, &mut Vec::new());
        fft.inverse(&mut shifted, &mut b, &mut Vec::new());
        (a, b)
    }

    #[test]
    fn known_subpixel_shifts_are_recovered_on_noisy_non_periodic_crops() {
        // Crops of 64 × 64 from a 128 × 128 field (so the frames are not periodic and the
        // window matters), white noise at 5 % of the field's rms added to both.
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(7);
        let mut worst: f64 = 0.0;
        for (i, (dx, dy)) in [
            (0.0, 0.0),
            (0.37, -0.81),
            (-2.62, 1.15),
            (3.5, 0.25),
            (-0.5, -3.9),
        ]
        .into_iter()
        .enumerate()
        {
            let (a, b) = field_pair(128, dx, dy, 11 + i as u64);
            let rms = (a.iter().map(|v| v * v).sum::<f64>() / a.len() as f64).sqrt();
            let noise = Normal::new(0.0, 0.05 * rms).unwrap();
            let crop = |f: &Array2<f64>, rng: &mut Xoshiro256PlusPlus| {
                f.slice(ndarray::s![32..96, 32..96])
                    .mapv(|v| v + noise.sample(rng))
            };
            let (ra, rb) = (crop(&a, &mut rng), crop(&b, &mut rng));
            let reg = Registrar::new(ra.view()).unwrap();
            let t = reg.register(rb.view()).unwrap();
            worst = worst.max((t.dx_px - dx).abs()).max((t.dy_px - dy).abs());
            assert!(t.peak > 0.3 && t.peak <= 1.0 + 1e-9, "peak {}", t.peak);
        }
        assert!(worst < 0.05, "worst shift error {worst} px");
    }

    #[test]
    fn tukey_window_is_flat_in_the_middle_and_zero_at_the_ends() {
        let w = tukey(65, 0.5, 0.0);
        assert_eq!(w[0], 0.0);
        assert!((w[64]).abs() < 1e-15);
        assert!(w[16..=48].iter().all(|v| *v == 1.0));
        // The taper is a raised cosine: half height half way into it.
        assert!((w[8] - 0.5).abs() < 1e-12);
        // Shifted by 2.5 samples: the same curve moved, zero before its start.
        let v = tukey(65, 0.5, 2.5);
        assert_eq!(v[2], 0.0);
        assert!((v[13] - tukey_at(10.5, 65, 0.5)).abs() < 1e-15);
        assert!(
            (tukey_at(10.5, 65, 0.5) - 0.5 * (1.0 - (std::f64::consts::PI * 10.5 / 16.0).cos()))
                .abs()
                < 1e-15
        );
    }

    #[test]
    fn bad_inputs_are_refused() {
        let a = Array2::<f64>::zeros((4, 16));
        assert!(Registrar::new(a.view()).is_err());
        let flat = Array2::<f64>::from_elem((16, 16), 3.0);
        assert!(Registrar::new(flat.view()).is_err());
        let (a, _) = field_pair(32, 0.0, 0.0, 1);
        let reg = Registrar::new(a.view()).unwrap();
        assert!(reg.register(Array2::<f64>::zeros((32, 31)).view()).is_err());
        let mut nan = a.clone();
        nan[[3, 4]] = f64::NAN;
        assert!(reg.register(nan.view()).is_err());
        let stack = ndarray::Array3::<f64>::zeros((2, 16, 16));
        assert!(register_stack(stack.view(), 2).is_err());
    }
}
