//! The optical transfer function and point-spread function of a generalised pupil
//! `P(x, y) = A(x, y) · exp(2πi W(x, y) λ_ref/λ)` (Goodman, *Introduction to Fourier Optics*,
//! 3rd ed., §6.3–6.4: the OTF is the normalised autocorrelation of the generalised pupil), with `A` the aperture ([`Pupil`]) and `W` the
//! wavefront in waves at the reference wavelength λ_ref ([`LocalWavefront`]).
//!
//! The pupil is sampled with `n` samples across its diameter D on an `M × M` grid
//! (`M = padding · n`, padding ≥ 2), then
//! - PSF = |FFT(P)|² (normalised to unit sum); its sample is `Δθ = λ n/(M D)` rad, so it
//!   covers `n λ/D` in angle;
//! - OTF = FFT(PSF) normalised to 1 at zero frequency, which is the autocorrelation of P
//!   divided by `Σ|P|²` (Goodman §6.3). Padding ≥ 2 makes the circular autocorrelation
//!   equal the linear one. A pupil shift of one sample is the normalised frequency
//!   `X = f/f_c = 1/n`, with `f_c = D/λ` cycles/rad, so the OTF grid step is `D/(n λ)`
//!   cycles/rad: both the pupil sampling in frequency and the phase (∝ 1/λ for a fixed
//!   optical path difference) scale with λ.
//!
//! Accuracy (src/wavefront/tests.rs, docs/wavefront.md): the pupil transmission is binary
//! (1 where a cell centre transmits). With the default 256 samples across the pupil the
//! OTF of a zero wavefront is within 1e-3 of the analytic clear and obscured (R = 0.3, 0.5)
//! diffraction OTFs at every grid frequency; with 128 within 1.2e-3, with 64 within 5e-3.
//! The error comes from the pixelated pupil edge (lattice-point counting) and falls
//! roughly as n^(-3/2). Anti-aliased (area-fraction) edges were tried and were worse: they
//! smooth the OTF's cusp at zero frequency, which offsets the normalised OTF.

use std::f64::consts::TAU;

use ndarray::Array2;
use num_complex::Complex64;
use rustfft::FftPlanner;

use super::aberration::LocalWavefront;
use super::pupil::Pupil;
use crate::error::{Error, Result};

/// How finely the pupil is sampled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sampling {
    /// Samples across the pupil diameter (even, 8..=1024).
    pub samples_across: usize,
    /// Grid size / samples across (2..=8): 2 is enough for the OTF, 4 samples the PSF at
    /// λ/(4D) for pictures.
    pub padding: usize,
}

impl Default for Sampling {
    fn default() -> Self {
        Sampling {
            samples_across: DEFAULT_SAMPLES_ACROSS,
            padding: 2,
        }
    }
}

/// Default samples across the pupil: the OTF of a zero wavefront is then within 1e-3 of
/// the analytic one (see the module documentation); the grid is 512² at padding 2.
pub const DEFAULT_SAMPLES_ACROSS: usize = 256;

/// Largest wavefront slope per pupil sample accepted, waves: 1/4 wave per sample resolves
/// the phase (Nyquist is 1/2) and keeps the geometric blur inside half the PSF window.
pub const MAX_WAVES_PER_SAMPLE: f64 = 0.25;

impl Sampling {
    /// The default sampling, refined until the wavefront (scaled to `wavelength_m`) changes
    /// by at most [`MAX_WAVES_PER_SAMPLE`] per sample. Errors when that needs more than
    /// 1024 samples across the pupil.
    pub fn for_wavefront(
        wavefront: &LocalWavefront,
        reference_wavelength_m: f64,
        wavelength_m: f64,
        padding: usize,
    ) -> Result<Self> {
        Self::for_wavefront_from(
            wavefront,
            reference_wavelength_m,
            wavelength_m,
            padding,
            DEFAULT_SAMPLES_ACROSS,
        )
    }

    /// [`Sampling::for_wavefront`] starting from `min_samples` samples across the pupil
    /// (even, 8..=1024) instead of the default.
    pub fn for_wavefront_from(
        wavefront: &LocalWavefront,
        reference_wavelength_m: f64,
        wavelength_m: f64,
        padding: usize,
        min_samples: usize,
    ) -> Result<Self> {
        let scale = reference_wavelength_m / wavelength_m;
        // Largest |∇W| (waves per unit radius) on a polar set of points, by central
        // differences.
        let mut slope: f64 = 0.0;
        let h = 1e-4;
        for ir in 0..=32 {
            let r = ir as f64 / 32.0 * (1.0 - h);
            for it in 0..64 {
                let t = it as f64 / 64.0 * TAU;
                let (x, y) = (r * t.cos(), r * t.sin());
                let gx = (wavefront.waves(x + h, y) - wavefront.waves(x - h, y)) / (2.0 * h);
                let gy = (wavefront.waves(x, y + h) - wavefront.waves(x, y - h)) / (2.0 * h);
                slope = slope.max(gx.hypot(gy) * scale.abs());
            }
        }
        // One sample is 2/n of the radius: slope · 2/n ≤ MAX_WAVES_PER_SAMPLE.
        let need = (2.0 * slope / MAX_WAVES_PER_SAMPLE).ceil() as usize;
        let n = need.max(min_samples).next_multiple_of(2);
        if n > 1024 {
            return Err(Error::param(
                "wavefront",
                format!("{slope:.1} waves per pupil radius at the largest slope"),
                format!(
                    "a wavefront whose slope needs at most 1024 samples across the pupil \
                     (≤ {} waves per radius at this wavelength)",
                    MAX_WAVES_PER_SAMPLE * 512.0
                ),
            ));
        }
        Ok(Sampling {
            samples_across: n,
            padding,
        })
    }

    fn validate(&self) -> Result<()> {
        let n = self.samples_across;
        if !(8..=1024).contains(&n) || n % 2 != 0 {
            return Err(Error::param(
                "samples_across",
                n,
                "an even number of pupil samples in 8..=1024",
            ));
        }
        if !(2..=8).contains(&self.padding) {
            return Err(Error::param("padding", self.padding, "an integer in 2..=8"));
        }
        Ok(())
    }

    /// The grid size M.
    pub fn grid(&self) -> usize {
        self.samples_across * self.padding
    }
}

/// The PSF and OTF of one generalised pupil at one wavelength.
#[derive(Debug, Clone)]
pub struct PupilTransfer {
    wavelength_m: f64,
    diameter_m: f64,
    sampling: Sampling,
    /// OTF, centred: element (r, c) is at normalised frequency
    /// `(X, Y) = ((c − M/2)/n, (r − M/2)/n)`; 1 at (M/2, M/2).
    otf: Array2<Complex64>,
    /// PSF, centred, unit sum: element (r, c) is at angle `((c − M/2) Δθ, (r − M/2) Δθ)`.
    psf: Array2<f64>,
    /// `Σ|P|²`, the transmitting pupil area in samples.
    pupil_energy: f64,
    /// Peak of the PSF on its grid / peak of the same pupil without aberration.
    strehl: f64,
}

/// In-place 2-D complex FFT of a row-major `m × m` buffer (rows, then columns).
fn fft2(data: &mut [Complex64], m: usize, inverse: bool) {
    let mut planner = FftPlanner::<f64>::new();
    let fft = if inverse {
        planner.plan_fft_inverse(m)
    } else {
        planner.plan_fft_forward(m)
    };
    fft.process(data);
    let mut t = vec![Complex64::new(0.0, 0.0); m * m];
    for r in 0..m {
        for c in 0..m {
            t[c * m + r] = data[r * m + c];
        }
    }
    fft.process(&mut t);
    for r in 0..m {
        for c in 0..m {
            data[c * m + r] = t[r * m + c];
        }
    }
}

/// Moves the zero-frequency/zero-angle sample from index 0 to index m/2 on both axes.
fn centred<T: Copy>(data: &[T], m: usize) -> Array2<T> {
    let h = m / 2;
    Array2::from_shape_fn((m, m), |(r, c)| data[((r + h) % m) * m + (c + h) % m])
}

impl PupilTransfer {
    /// Samples the generalised pupil of `pupil` and `wavefront` (waves at
    /// `reference_wavelength_m`) at `wavelength_m`, for a pupil of diameter `diameter_m`,
    /// and computes its PSF and OTF. Pupil samples are taken at the centres of an `n × n`
    /// block of cells of width D/n (binary transmission).
    pub fn compute(
        pupil: &Pupil,
        wavefront: &LocalWavefront,
        reference_wavelength_m: f64,
        wavelength_m: f64,
        diameter_m: f64,
        sampling: Sampling,
    ) -> Result<Self> {
        Self::compute_at_azimuth(
            pupil,
            wavefront,
            &LocalWavefront::default(),
            std::f64::consts::FRAC_PI_2,
            reference_wavelength_m,
            wavelength_m,
            diameter_m,
            sampling,
        )
    }

    /// [`PupilTransfer::compute`] for a field point in the direction `azimuth_rad` (counter-
    /// clockwise from +x) of the frame whose axes are the pupil's `x` and `y`: the local
    /// wavefront `wavefront` (tangential axis along the field direction) is turned so that
    /// its tangential axis points along the azimuth, while the aperture (obscuration,
    /// spider vanes) and `fixed`, a wavefront fixed to the lens (e.g. field-independent
    /// Zernike terms), are not. A frame point `(x, y)` is the local point
    /// `x' = x sin α − y cos α` (sagittal), `y' = x cos α + y sin α` (tangential); at
    /// α = 90° (field along +y) the two frames coincide, which is
    /// [`PupilTransfer::compute`].
    #[allow(clippy::too_many_arguments)]
    pub fn compute_at_azimuth(
        pupil: &Pupil,
        wavefront: &LocalWavefront,
        fixed: &LocalWavefront,
        azimuth_rad: f64,
        reference_wavelength_m: f64,
        wavelength_m: f64,
        diameter_m: f64,
        sampling: Sampling,
    ) -> Result<Self> {
        sampling.validate()?;
        if !azimuth_rad.is_finite() {
            return Err(Error::param("azimuth", azimuth_rad, "a finite angle"));
        }
        let (sin_a, cos_a) = if azimuth_rad == std::f64::consts::FRAC_PI_2 {
            (1.0, 0.0)
        } else {
            azimuth_rad.sin_cos()
        };
        for (field, v) in [
            ("reference_wavelength_m", reference_wavelength_m),
            ("wavelength_m", wavelength_m),
            ("diameter_m", diameter_m),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::param(field, v, "a finite value > 0"));
            }
        }
        let n = sampling.samples_across;
        let m = sampling.grid();
        let scale = reference_wavelength_m / wavelength_m;
        let mut p = vec![Complex64::new(0.0, 0.0); m * m];
        let mut amplitude_sum = 0.0;
        let mut any_phase = false;
        // Cell centres at (i − n/2 + ½)·2/n, i = 0..n, placed at the start of the grid:
        // the PSF intensity does not depend on where the pupil sits in the grid.
        for i in 0..n {
            let y = (i as f64 - n as f64 / 2.0 + 0.5) * 2.0 / n as f64;
            for k in 0..n {
                let x = (k as f64 - n as f64 / 2.0 + 0.5) * 2.0 / n as f64;
                if pupil.transmits(x, y) {
                    let (xl, yl) = (x * sin_a - y * cos_a, x * cos_a + y * sin_a);
                    let w = (wavefront.waves(xl, yl) + fixed.waves(x, y)) * scale;
                    any_phase |= w != 0.0;
                    p[i * m + k] = Complex64::from_polar(1.0, TAU * w);
                    amplitude_sum += 1.0;
                }
            }
        }
        if amplitude_sum == 0.0 {
            return Err(Error::param(
                "pupil",
                "no transmitting sample",
                "an aperture that transmits (obscuration and spider vanes block everything)",
            ));
        }
        fft2(&mut p, m, false);
        let intensity: Vec<f64> = p.iter().map(|v| v.norm_sqr()).collect();
        let total: f64 = intensity.iter().sum();
        let peak = intensity.iter().cloned().fold(0.0, f64::max);
        // The unaberrated peak of the same pupil is |Σ A|² at θ = 0 (index 0).
        let strehl = if any_phase {
            peak / (amplitude_sum * amplitude_sum)
        } else {
            1.0
        };
        let mut spectrum: Vec<Complex64> = intensity
            .iter()
            .map(|&v| Complex64::new(v / total, 0.0))
            .collect();
        let psf = centred(&intensity.iter().map(|v| v / total).collect::<Vec<_>>(), m);
        fft2(&mut spectrum, m, false);
        let dc = spectrum[0].re;
        for v in spectrum.iter_mut() {
            *v /= dc;
        }
        Ok(PupilTransfer {
            wavelength_m,
            diameter_m,
            sampling,
            otf: centred(&spectrum, m),
            psf,
            pupil_energy: amplitude_sum,
            strehl,
        })
    }

    /// The wavelength, m.
    pub fn wavelength_m(&self) -> f64 {
        self.wavelength_m
    }

    /// The sampling used.
    pub fn sampling(&self) -> Sampling {
        self.sampling
    }

    /// The diffraction cutoff D/λ, cycles/rad.
    pub fn cutoff_cy_per_rad(&self) -> f64 {
        self.diameter_m / self.wavelength_m
    }

    /// The centred OTF grid; element (r, c) is at normalised frequency
    /// `((c − M/2)/n, (r − M/2)/n)` in units of the cutoff D/λ (x sagittal, y tangential).
    pub fn otf_grid(&self) -> &Array2<Complex64> {
        &self.otf
    }

    /// The centred PSF, unit sum; element (r, c) is at angle
    /// `((c − M/2) Δθ, (r − M/2) Δθ)` with Δθ = [`Self::psf_sample_rad`].
    pub fn psf(&self) -> &Array2<f64> {
        &self.psf
    }

    /// The PSF sample, rad: `λ n / (M D)`.
    pub fn psf_sample_rad(&self) -> f64 {
        self.wavelength_m / self.diameter_m / self.sampling.padding as f64
    }

    /// `Σ|P|²`: the transmitting pupil area in samples (the PSF's energy before
    /// normalisation is `M² Σ|P|²`, Parseval).
    pub fn pupil_energy(&self) -> f64 {
        self.pupil_energy
    }

    /// Peak of the PSF on its grid over the peak of the unaberrated PSF of the same pupil
    /// (a lower bound of the Strehl ratio: the true peak may fall between samples).
    pub fn strehl(&self) -> f64 {
        self.strehl
    }

    /// The OTF at normalised frequency (`x`, `y`) = f/f_c (sagittal, tangential), by
    /// bilinear interpolation on the grid; 0 beyond it.
    pub fn at_normalised(&self, x: f64, y: f64) -> Complex64 {
        let n = self.sampling.samples_across as f64;
        let m = self.otf.nrows();
        let c = x * n + (m / 2) as f64;
        let r = y * n + (m / 2) as f64;
        if !(c >= 0.0 && r >= 0.0 && c <= (m - 1) as f64 && r <= (m - 1) as f64) {
            return Complex64::new(0.0, 0.0);
        }
        let (c0, r0) = (c.floor() as usize, r.floor() as usize);
        let (c1, r1) = ((c0 + 1).min(m - 1), (r0 + 1).min(m - 1));
        let (tc, tr) = (c - c0 as f64, r - r0 as f64);
        let o = &self.otf;
        o[(r0, c0)] * ((1.0 - tc) * (1.0 - tr))
            + o[(r0, c1)] * (tc * (1.0 - tr))
            + o[(r1, c0)] * ((1.0 - tc) * tr)
            + o[(r1, c1)] * (tc * tr)
    }

    /// The OTF at angular frequency (`fx`, `fy`), cycles/rad in object space.
    pub fn at_cy_per_rad(&self, fx_cy_per_rad: f64, fy_cy_per_rad: f64) -> Complex64 {
        let fc = self.cutoff_cy_per_rad();
        self.at_normalised(fx_cy_per_rad / fc, fy_cy_per_rad / fc)
    }

    /// The tangential MTF |OTF(0, X)| at normalised frequency X (frequency along the
    /// field direction y).
    pub fn tangential_mtf(&self, x: f64) -> f64 {
        self.at_normalised(0.0, x).norm()
    }

    /// The sagittal MTF |OTF(X, 0)| at normalised frequency X.
    pub fn sagittal_mtf(&self, x: f64) -> f64 {
        self.at_normalised(x, 0.0).norm()
    }

    /// The tangential and sagittal MTFs at angular frequencies `f_cy_per_rad` (cycles/rad
    /// in object space): |OTF| along the field direction y and across it, x.
    pub fn tangential_sagittal_cy_per_rad(&self, f_cy_per_rad: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let fc = self.cutoff_cy_per_rad();
        f_cy_per_rad
            .iter()
            .map(|&f| (self.tangential_mtf(f / fc), self.sagittal_mtf(f / fc)))
            .unzip()
    }

    /// The PSF centroid (x, y), rad, from the sampled PSF.
    pub fn centroid_rad(&self) -> (f64, f64) {
        let m = self.psf.nrows();
        let h = (m / 2) as f64;
        let (mut sx, mut sy) = (0.0, 0.0);
        for ((r, c), &v) in self.psf.indexed_iter() {
            sx += (c as f64 - h) * v;
            sy += (r as f64 - h) * v;
        }
        let d = self.psf_sample_rad();
        (sx * d, sy * d)
    }

    /// Full width at half maximum, rad, as the diameter of the disc whose area equals the
    /// area where the PSF is at least half its peak (the usual FWHM for a round PSF, a
    /// mean width for an asymmetric one).
    pub fn fwhm_rad(&self) -> f64 {
        let peak = self.psf.iter().cloned().fold(0.0, f64::max);
        let count = self.psf.iter().filter(|&&v| v >= 0.5 * peak).count() as f64;
        let d = self.psf_sample_rad();
        2.0 * (count / std::f64::consts::PI).sqrt() * d
    }
}
