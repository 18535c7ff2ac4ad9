//! Restoration of a recorded frame with the sensor's own transfer function.
//!
//! Every filter here is a regularised inverse on the detector grid,
//!
//! ```text
//! F̂(u,v) = G(u,v) · H(u,v) / (H(u,v)² + R(u,v)),    R(0,0) = 0,
//! ```
//!
//! with G the DFT of the recorded image (mirror-padded, below), H the system transfer
//! function (real and signed: sinc and defocus lobes reverse contrast, so H* = H) and R
//! the regulariser of the [`Method`]:
//!
//! - **wiener** (FOI-R--2135--SE eq. 3.6): `R = P_n / P_f(ρ)`, the noise-to-signal power
//!   ratio, with `P_n = N·σ²` the white-noise power per DFT coefficient of the N-pixel
//!   padded frame and `P_f(ρ) = A ρ^β` a power law fitted (least squares in log–log) to
//!   the radially averaged object spectrum `(⟨|G|²⟩ − P_n)/⟨H²⟩` over the annuli where
//!   the signal clearly exceeds the noise (natural scenes have β ≈ −2 … −3; van der Schaaf
//!   & van Hateren, Vision Res. 36, 2759 (1996)).
//! - **wiener-hunt** (Hunt 1973, IEEE Trans. Computers C-22, 805; the Tikhonov–Miller
//!   filter with a smoothness prior): `R = λ·|C(u,v)|²`, `C = 4 − 2cos 2πu − 2cos 2πv`
//!   the transfer function of the 5-point discrete Laplacian, so rough solutions are
//!   penalised; λ is the value of least estimated error (below).
//! - **constant**: `R = NSR` at every frequency but zero (`--nsr`, or, inside the auto
//!   choice, the NSR of least estimated error).
//! - **none**: the input unchanged.
//!
//! **Noise.** σ is the image's own noise by Immerkær's operator on its unmasked pixels
//! (rule **auto**, [`crate::processing::noise_estimate`]) or the sensor model's noise at
//! the image's mean level (rule **model**). (The FOI report's §3.6 rule — the image
//! power where |H| is negligible — was dropped: a camera whose |H| stays above 0.02 up
//! to Nyquist has no such frequency, and the edge's own power was taken for noise.)
//!
//! **Estimated error and the automatic choice** ([`restore_rule`]): for `G = H·F + noise`
//! the filter `W = H/(H² + R)` leaves the expected squared error
//! `(W H − 1)² |F|² + W² P_n` at each frequency; with `|F|²` estimated from the image
//! independently of every candidate (per frequency without bias where |H| ≥
//! [`restore_rule::RISK_MIN_H`], pooled over an annulus below), the sum over the
//! frequencies estimates the restoration's squared error against the unblurred scene
//! (Parseval; Stein's unbiased risk estimate for a filter diagonal in frequency). λ
//! (Wiener–Hunt) and the constant NSR minimise it over ten values per decade from 1e−10
//! to 1e4; **auto** returns whichever of wiener, wiener-hunt, constant and **none** has
//! the least estimate — the input itself when no filter is expected to improve on it.
//! Every candidate and its error relative to the input's
//! ([`restore_rule::Candidate::relative_risk`]) is reported.
//!
//! **Noise power of the padded frame.** The pads hold cross-faded copies of the image,
//! `w·x_a + (1 − w)·x_b`, whose noise variance is `(w² + (1 − w)²)σ²` (σ² where both taps
//! are the same pixel), so the noise power per DFT coefficient of the padded frame is
//! `P_n = σ² Σ_pixels v = σ² (Σ_j v_j)(Σ_k v_k)` (Parseval; the taps are separable),
//! not `N σ²`. This is the noise power of the error estimate; the classic Wiener filter
//! keeps `P_n = N σ²` for its spectrum fit and NSR.
//!
//! **Sharpness guard.** Wherever the sensor passes a frequency at |H| ≥ ½, R is lowered
//! to at most |H|(1 − |H|), so the restored transfer function `H²/(H² + R)` is at least
//! |H| there: a restoration never makes the image blurrier than the input at the
//! frequencies the input still resolves (in particular at its MTF50). The constant rule
//! given by the user is applied as given.
//!
//! **DC.** The zero-frequency coefficient passes unchanged: R(0,0) = 0 for every filter
//! (the constant NSR included) and H(0,0) = 1 (checked), so its gain `H/(H² + R)` is
//! exactly 1 and the mean of the *padded* frame is kept exactly. The mean of the cropped
//! output differs from the input's only by what the filter moves between the image and
//! its pads (under 0.1 % in the tests; `restore::restoration_of_a_bar_scene…`). The
//! zero frequency is left out of the error estimate (every candidate treats it alike).
//!
//! **Clipped sources**: small clusters of clipped pixels are first filled from the PSF's
//! wings ([`crate::processing::clipped_fill`]); the fill's prediction variance, summed
//! over the filled pixels (the flat mean power per DFT coefficient of an error confined
//! to them), is added to the noise power of the estimate's error term `W² P_n`, not to
//! the noise subtracted from the object power.
//!
//! **Masks** ([`RestoreMasks`]): dead, hot, stuck and saturated pixels are left out of the
//! noise estimate; defects must be replaced before filtering (the caller does so,
//! [`crate::processing::bad_pixels::find_image_defects`]); saturated pixels keep their
//! clipped value as input, and after filtering any saturated pixel the filter brought
//! below its recorded value is raised back to it (the scene there is at least that
//! bright).
//!
//! Boundaries: the DFT is circular, so the frame is extended on every side by its own
//! mirror image and the two mirrors are cross-faded with a raised cosine across the pad
//! (as `imaging` pads each band): the circular frame is continuous, the filter
//! does not ring at the image border, and the output is cropped back to the input size.
//!
//! Sampling and aliasing: H is evaluated at the detector-grid frequencies (cycles per
//! pixel up to ±½, the detector Nyquist), spectrally weighted over the band
//! ([`SensorTransfer`]). Frequencies of the optical image above Nyquist that aliased
//! into the base band are indistinguishable from signal there and cannot be undone; they
//! are treated as signal.

use ndarray::{s, Array2, ArrayView2};
use num_complex::Complex64;

use crate::error::{Error, Result};
use crate::imaging::fft::RealFft2;
use crate::imaging::next_fast_len;
use crate::processing::bad_pixels::BadPixelMap;
use crate::processing::clipped_fill::fill_clipped;
use crate::processing::noise_estimate::immerkaer_sigma;
use crate::processing::restore_rule::{self, guard, Measured};
pub use crate::processing::restore_rule::{Candidate, Method};
use crate::radiometry::planck_photon_radiance;
use crate::sensor::{FrequencyGrid, Sensor, SystemOtf};

/// Number of wavelengths at which the band-weighted transfer function is sampled.
pub const SPECTRAL_SAMPLES: usize = 48;

/// A transfer function on the detector grid: frequencies in cycles per pixel.
pub trait DetectorTransfer: Sync {
    /// The transfer function on the half-plane grid of a real FFT of a `rows × cols`
    /// frame (shape `[rows, cols/2 + 1]`, the layout of [`FrequencyGrid::real_fft`] with
    /// unit sample spacing).
    fn on_grid(&self, rows: usize, cols: usize) -> Result<Array2<f64>>;

    /// Whether one transfer function describes the whole image (true unless overridden).
    /// A colour mosaic (CFA) is not shift-invariant: its colour pattern is imposed after
    /// the optics, so dividing by H would amplify the pattern itself; `Method::Auto`
    /// then returns the input unrestored.
    fn shift_invariant(&self) -> bool {
        true
    }
}

/// Any `Fn(fx, fy) -> H` (cycles per pixel along columns and rows) is a transfer function.
#[derive(Debug, Clone, Copy)]
pub struct FnTransfer<F>(pub F);

impl<F: Fn(f64, f64) -> f64 + Sync> DetectorTransfer for FnTransfer<F> {
    fn on_grid(&self, rows: usize, cols: usize) -> Result<Array2<f64>> {
        let g = FrequencyGrid::real_fft(rows, cols, 1.0, 1.0);
        Ok(Array2::from_shape_fn((g.fy.len(), g.fx.len()), |(j, k)| {
            (self.0)(g.fx[k], g.fy[j])
        }))
    }
}

/// A sensor's system transfer function on its detector grid, spectrally weighted over
/// its band: `H(u,v) = Σ_i w_i OTF(u/IFOV, v/IFOV; λ_i) / Σ_i w_i`, u, v in cycles per
/// pixel, with `w_i = S(λ_i) · L_q(λ_i, T_ref)` the sensor's spectral response (filter ×
/// optics transmission × QE) times the blackbody photon radiance (Planck, photon form) at
/// [`SensorTransfer::reference_temperature_k`], at [`SPECTRAL_SAMPLES`] equally spaced
/// wavelengths over the response's support: the transfer function of the photo-electron
/// image of a grey scene at that temperature. Every component the sensor enables enters
/// (diffraction, aberration, defocus, detector footprint, motion, jitter, turbulence,
/// aerosol, Gaussian, measured).
#[derive(Debug, Clone)]
pub struct SensorTransfer {
    otf: SystemOtf,
    ifov_rad: f64,
    wavelength_um: Vec<f64>,
    weights: Vec<f64>,
    reference_temperature_k: f64,
    mosaic: bool,
}

impl SensorTransfer {
    /// Resolves the cascade of `sensor` and its spectral weights. The reference
    /// temperature is 300 K for a sensor whose response-weighted mean wavelength lies
    /// beyond 3 µm (a thermal scene) and 5772 K (sunlight) otherwise.
    pub fn new(sensor: &Sensor) -> Result<Self> {
        let otf = sensor.otf().clone();
        let response = sensor.response();
        let (lo, hi) = response.support_um();
        if !(lo.is_finite() && hi.is_finite() && hi > lo) {
            return Err(Error::param(
                "spectral response",
                format!("support [{lo}, {hi}] µm"),
                "a bounded band (give the sensor a [filter] or a QE with a cutoff)",
            ));
        }
        let n = SPECTRAL_SAMPLES;
        let wavelength_um: Vec<f64> = (0..n)
            .map(|i| lo + (hi - lo) * (i as f64 + 0.5) / n as f64)
            .collect();
        let s: Vec<f64> = wavelength_um.iter().map(|l| response.eval(*l)).collect();
        let s_sum: f64 = s.iter().sum();
        let mean_um = if s_sum > 0.0 {
            wavelength_um
                .iter()
                .zip(&s)
                .map(|(l, v)| l * v)
                .sum::<f64>()
                / s_sum
        } else {
            0.0
        };
        let reference_temperature_k = if mean_um > 3.0 { 300.0 } else { 5772.0 };
        let weights: Vec<f64> = wavelength_um
            .iter()
            .zip(&s)
            .map(|(l, v)| v * planck_photon_radiance(*l, reference_temperature_k))
            .collect();
        let total: f64 = weights.iter().sum();
        if !(total > 0.0 && total.is_finite()) {
            return Err(Error::param(
                "spectral response",
                "zero over its support",
                "a response with some non-zero transmission and quantum efficiency",
            ));
        }
        let weights = weights.into_iter().map(|w| w / total).collect();
        Ok(SensorTransfer {
            otf,
            ifov_rad: sensor.ifov_rad(),
            wavelength_um,
            weights,
            reference_temperature_k,
            mosaic: sensor.config().cfa.is_some(),
        })
    }

    /// The same transfer function (spectral weights kept) with its turbulence and aerosol
    /// over a path of `range_m` ([`SystemOtf::over_range`]).
    ///
    /// Errors: `range_m` not finite and > 0.
    pub fn over_range(&self, range_m: f64) -> Result<Self> {
        Ok(SensorTransfer {
            otf: self.otf.over_range(range_m)?,
            ifov_rad: self.ifov_rad,
            wavelength_um: self.wavelength_um.clone(),
            weights: self.weights.clone(),
            reference_temperature_k: self.reference_temperature_k,
            mosaic: self.mosaic,
        })
    }

    /// The blackbody temperature of the spectral weighting, K.
    pub fn reference_temperature_k(&self) -> f64 {
        self.reference_temperature_k
    }

    /// The wavelengths (µm) and normalised weights (sum 1) of the spectral average.
    pub fn spectral_weights(&self) -> (&[f64], &[f64]) {
        (&self.wavelength_um, &self.weights)
    }

    /// H at one frequency (fx, fy) in cycles per pixel.
    pub fn eval(&self, fx_cy_per_px: f64, fy_cy_per_px: f64) -> f64 {
        let (fx, fy) = (fx_cy_per_px / self.ifov_rad, fy_cy_per_px / self.ifov_rad);
        self.wavelength_um
            .iter()
            .zip(&self.weights)
            .filter(|(_, w)| **w > 0.0)
            .map(|(l, w)| w * self.otf.evaluate(fx, fy, *l))
            .sum()
    }
}

impl DetectorTransfer for SensorTransfer {
    fn on_grid(&self, rows: usize, cols: usize) -> Result<Array2<f64>> {
        let grid = FrequencyGrid::real_fft(rows, cols, self.ifov_rad, self.ifov_rad);
        let g = self.otf.on_grid(&grid);
        let mut acc = Array2::<f64>::zeros((grid.fy.len(), grid.fx.len()));
        let mut buf = acc.clone();
        for (l, w) in self.wavelength_um.iter().zip(&self.weights) {
            if *w <= 0.0 {
                continue;
            }
            g.at_wavelength_into(*l, &mut buf);
            acc.scaled_add(*w, &buf);
        }
        Ok(acc)
    }

    fn shift_invariant(&self) -> bool {
        !self.mosaic
    }
}

/// Where the white-noise level of the Wiener and Wiener–Hunt filters comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NoiseRule {
    /// The per-pixel σ measured on the image itself by Immerkær's operator on its
    /// unmasked pixels ([`crate::processing::noise_estimate::immerkaer_sigma`]).
    Auto,
    /// σ² given by the caller (the sensor's shot + read + quantisation noise at the
    /// image's signal level), image units squared.
    Model {
        /// Per-pixel noise variance, image units squared.
        noise_variance: f64,
    },
    /// A constant NSR at every frequency but zero (the classic constant-NSR Wiener
    /// filter; no noise level, no choice of method).
    Constant(f64),
}

/// Pixel masks a restoration honours.
#[derive(Debug, Clone, Copy, Default)]
pub struct RestoreMasks<'a> {
    /// Pixels left out of the noise estimate (dead, hot, stuck, saturated); they must
    /// already hold finite values (replaced, or the clipped level).
    pub noise: Option<&'a BadPixelMap>,
    /// Saturated pixels: the scene there is at least the recorded value, so the result
    /// is raised back to the recorded value wherever the filter brought it lower.
    pub saturated: Option<&'a BadPixelMap>,
}

/// What a restoration did.
#[derive(Debug, Clone, PartialEq)]
pub struct Restoration {
    /// The restored image, the input's size and units.
    pub image: Array2<f64>,
    /// The noise rule's name: `auto`, `model` or `constant`.
    pub rule: &'static str,
    /// The filter applied: `wiener`, `wiener-hunt`, `constant` or `none`.
    pub method: &'static str,
    /// Noise power per DFT coefficient of the padded frame, `σ²·Σv` (module
    /// documentation), image units² (auto and model rules).
    pub noise_power: Option<f64>,
    /// Per-pixel noise standard deviation used, image units (auto and model rules).
    pub noise_sigma: Option<f64>,
    /// The image's own noise σ by Immerkær's operator, image units (whatever the rule;
    /// `None` if it could not be estimated).
    pub noise_sigma_measured: Option<f64>,
    /// The constant NSR (constant rule), or the median regulariser R over the
    /// frequencies of the filter applied (0 for `none`).
    pub nsr_median: f64,
    /// The fitted object-spectrum exponent β (auto and model rules).
    pub spectrum_exponent: Option<f64>,
    /// Every filter considered, with its estimated error (auto and model rules).
    pub candidates: Vec<Candidate>,
    /// Frequencies (half-plane bins) where the regulariser was lowered so that the
    /// filter does not attenuate a frequency the sensor passes at ≥ 50 %.
    pub guarded_bins: usize,
    /// Pixels raised back to their recorded (saturated) value.
    pub saturated_raised: usize,
    /// Clipped pixels whose value the filter saw raised to the fit of the PSF's wings
    /// around them ([`crate::processing::clipped_fill`]).
    pub saturated_filled: usize,
    /// The fill's variance summed over the filled pixels (image units²,
    /// [`crate::processing::clipped_fill::ClippedFill::fill_variance`]): extra noise power
    /// per DFT coefficient in the error estimate.
    pub saturated_fill_variance: f64,
    /// Padded FFT frame (rows, cols).
    pub padded_shape: (usize, usize),
}

/// Pad width on each side for an `n`-pixel axis: a quarter of the axis, at least 16
/// pixels, so the cross-fade is long compared with the blur.
fn pad_for(n: usize) -> usize {
    (n / 4).max(16)
}

/// Index taps of the mirrored, cross-faded extension of an `n`-sample axis into `len`
/// samples with the image starting at `pad`: padded sample j = w·x[a] + (1 − w)·x[b],
/// x[a] the mirror of the image's right (bottom) end, x[b] of its left (top) end, w a
/// raised cosine falling from 1 to 0 across the gap between the two ends of the circular
/// frame. The mirrors stop (hold their value) half the gap deep.
fn pad_taps(n: usize, pad: usize, len: usize) -> Vec<(usize, usize, f64)> {
    let gap = len - n;
    let mirror = |i: isize| -> usize {
        // Whole-sample symmetric reflection (…2 1 0 | 0 1 2 … n−1 | n−1 n−2 …), repeated.
        let period = 2 * n as isize;
        let m = i.rem_euclid(period);
        (if m < n as isize { m } else { period - 1 - m }) as usize
    };
    (0..len)
        .map(|j| {
            let i = j as isize - pad as isize;
            if i >= 0 && (i as usize) < n {
                return (i as usize, i as usize, 1.0);
            }
            // Position in the gap, counted from the right edge of the image going right
            // (and wrapping round to the left edge).
            let g = if i >= n as isize {
                (i - n as isize) as usize
            } else {
                gap - pad + j
            };
            // Each mirror reaches at most half the gap deep, so content far from an edge
            // never leaks into the pad next to it.
            let depth = (gap / 2) as isize;
            let right = mirror(n as isize + (g as isize).min(depth));
            let left = mirror(-1 - (gap as isize - 1 - g as isize).min(depth));
            let t = (g as f64 + 0.5) / gap as f64;
            let w = 0.5 * (1.0 + (std::f64::consts::PI * t).cos());
            (right, left, w)
        })
        .collect()
}

/// Mirror-pads `image` (finite values) to `(ny, nx)` with cross-faded seams.
fn pad_image(image: ArrayView2<f64>, ny: usize, nx: usize) -> (Array2<f64>, usize, usize) {
    let (rows, cols) = image.dim();
    let (py, px) = (pad_for(rows), pad_for(cols));
    let ty = pad_taps(rows, py, ny);
    let tx = pad_taps(cols, px, nx);
    let out = Array2::from_shape_fn((ny, nx), |(j, k)| {
        let (ya, yb, wy) = ty[j];
        let (xa, xb, wx) = tx[k];
        let v = |y: usize| wx * image[[y, xa]] + (1.0 - wx) * image[[y, xb]];
        wy * v(ya) + (1.0 - wy) * v(yb)
    });
    (out, py, px)
}

/// Σ over the padded frame's pixels of their noise variance in units of the image's
/// per-pixel variance σ² (module documentation): `(Σ_j v_j)(Σ_k v_k)` over the taps of
/// [`pad_taps`], `v = w² + (1 − w)²`, or 1 where both taps are one pixel.
fn pad_noise_factor(rows: usize, cols: usize, ny: usize, nx: usize) -> f64 {
    let axis = |n: usize, len: usize| -> f64 {
        pad_taps(n, pad_for(n), len)
            .iter()
            .map(|(a, b, w)| {
                if a == b {
                    1.0
                } else {
                    w * w + (1.0 - w) * (1.0 - w)
                }
            })
            .sum()
    };
    axis(rows, ny) * axis(cols, nx)
}

/// Radial frequency (cycles per pixel) of each half-plane bin of an `ny × nx` real FFT.
fn radial_frequency(ny: usize, nx: usize) -> Array2<f64> {
    let g = FrequencyGrid::real_fft(ny, nx, 1.0, 1.0);
    Array2::from_shape_fn((g.fy.len(), g.fx.len()), |(j, k)| g.fx[k].hypot(g.fy[j]))
}

/// Multiplicity of each half-plane bin in the full spectrum (columns 1 … ⌈nx/2⌉−1 stand
/// for two conjugate bins), so that averages over the half plane equal full-plane ones.
fn bin_weight(k: usize, nx: usize) -> f64 {
    if k == 0 || (nx % 2 == 0 && k == nx / 2) {
        1.0
    } else {
        2.0
    }
}

/// Restores `image` with the classic Wiener filter and no masks:
/// [`restore`]`(image, transfer, rule, Method::Wiener, RestoreMasks::default())`.
///
/// Errors: as [`restore`].
pub fn wiener_restore(
    image: ArrayView2<f64>,
    transfer: &dyn DetectorTransfer,
    rule: NoiseRule,
) -> Result<Restoration> {
    restore(
        image,
        transfer,
        rule,
        Method::Wiener,
        RestoreMasks::default(),
    )
}

/// Restores `image` (`[row, col]`, finite values: replace dead pixels and NaN first) with
/// the filter `F̂ = G·H/(H² + R)` of `method` (module documentation), the noise level of
/// `rule`, and the `masks`. The output has the input's size and units. DC: R(0) = 0 for
/// every method and H(0) = 1, so the zero-frequency gain is exactly 1 and the mean of the
/// padded frame is kept.
///
/// Errors: an empty or non-finite image, masks of another shape, a negative or
/// non-finite constant NSR or noise variance, a transfer function that is not 1 at zero
/// frequency, no usable noise estimate (auto rule), or (Wiener and Wiener–Hunt methods)
/// an image with too little signal above the noise to fit its spectrum.
pub fn restore(
    image: ArrayView2<f64>,
    transfer: &dyn DetectorTransfer,
    rule: NoiseRule,
    method: Method,
    masks: RestoreMasks<'_>,
) -> Result<Restoration> {
    let (rows, cols) = image.dim();
    if rows < 2 || cols < 2 {
        return Err(Error::param(
            "image",
            format!("{rows} × {cols} pixels"),
            "at least 2 × 2 pixels",
        ));
    }
    if let Some(((r, c), v)) = image.indexed_iter().find(|(_, v)| !v.is_finite()) {
        return Err(Error::param(
            format!("image[{r}, {c}]"),
            v,
            "finite values (replace dead pixels and NaN before restoring)",
        ));
    }
    for (name, m) in [
        ("noise mask", masks.noise),
        ("saturation mask", masks.saturated),
    ] {
        if let Some(m) = m {
            crate::processing::check_shape(name, m.dim(), (rows, cols))?;
        }
    }
    match rule {
        NoiseRule::Constant(x) if !(x.is_finite() && x >= 0.0) => {
            return Err(Error::param("nsr", x, "a finite number >= 0"))
        }
        NoiseRule::Model { noise_variance }
            if !(noise_variance.is_finite() && noise_variance > 0.0) =>
        {
            return Err(Error::param(
                "noise variance",
                noise_variance,
                "a finite number > 0 (image units squared)",
            ))
        }
        _ => {}
    }
    let measured = immerkaer_sigma(image, masks.noise).ok().map(|e| e.sigma);
    let variance = match rule {
        NoiseRule::Constant(_) => None,
        NoiseRule::Model { noise_variance } => Some(noise_variance),
        NoiseRule::Auto => {
            let s = measured.ok_or_else(|| {
                Error::param(
                    "image",
                    "too few unmasked pixels",
                    "an image with unmasked 3 × 3 neighbourhoods to measure the noise (or --noise model, --nsr)",
                )
            })?;
            Some(s * s)
        }
    };
    let ny = next_fast_len(rows + 2 * pad_for(rows));
    let nx = next_fast_len(cols + 2 * pad_for(cols));
    let fft = RealFft2::new(ny, nx);
    let mut spec = Array2::<Complex64>::zeros(fft.spectrum_shape());
    let mut scratch = Vec::new();
    let h = transfer.on_grid(ny, nx)?;
    if h.dim() != spec.dim() {
        return Err(Error::param(
            "transfer function grid",
            format!("{:?}", h.dim()),
            format!("the half-plane shape {:?}", spec.dim()),
        ));
    }
    if (h[[0, 0]] - 1.0).abs() > 1e-6 {
        return Err(Error::param(
            "transfer function at zero frequency",
            h[[0, 0]],
            "1 (a normalised transfer function)",
        ));
    }
    // Small clipped clusters: their blurred values estimated from the PSF's wings
    // (processing::clipped_fill), so that the filter does not see a clipped plateau.
    let (filled, saturated_filled, fill_variance) = match masks.saturated {
        Some(m) if m.count() > 0 => {
            let mut hs = h.mapv(|v| Complex64::new(v, 0.0));
            let mut psf = Array2::<f64>::zeros((ny, nx));
            fft.inverse(&mut hs, &mut psf, &mut scratch);
            let at = |dy: isize, dx: isize| {
                psf[[
                    dy.rem_euclid(ny as isize) as usize,
                    dx.rem_euclid(nx as isize) as usize,
                ]]
            };
            let fill = fill_clipped(image, m, masks.noise, at)?;
            (fill.image, fill.raised, fill.fill_variance)
        }
        _ => (image.to_owned(), 0, 0.0),
    };
    let (mut padded, py, px) = pad_image(filled.view(), ny, nx);
    fft.forward(&mut padded, &mut spec, &mut scratch);
    let npix = pad_noise_factor(rows, cols, ny, nx);
    let mut exponent = None;
    let mut candidates = Vec::new();
    let (name, reg): (&'static str, Option<Array2<f64>>) = match (rule, variance) {
        (NoiseRule::Constant(x), _) => ("constant", Some(Array2::from_elem(spec.dim(), x))),
        (_, None) => unreachable_rule()?,
        (_, Some(var)) => {
            // The error estimate takes the padded frame's own noise power; the classic
            // Wiener filter keeps its definition `P_n = N·σ²` (N the padded frame's
            // pixels) for its spectrum fit and NSR, as before the automatic rule.
            let pn = npix * var;
            let pn_wiener = (ny * nx) as f64 * var;
            let power = spec.mapv(|g| g.norm_sqr());
            let rho = radial_frequency(ny, nx);
            let fit = match fit_object_spectrum(&power, &h, &rho, pn_wiener, nx) {
                Err(e) if method == Method::Wiener => return Err(e),
                fit => fit.ok(),
            };
            exponent = fit.map(|(_, beta)| beta);
            let wiener_r = |j: usize, k: usize| match fit {
                Some((a, beta)) => pn_wiener / (a * rho[[j, k]].powf(beta)),
                None => f64::INFINITY,
            };
            let g = FrequencyGrid::real_fft(ny, nx, 1.0, 1.0);
            let two_pi = 2.0 * std::f64::consts::PI;
            let laplacian2 = |j: usize, k: usize| {
                let c = 4.0 - 2.0 * (two_pi * g.fx[k]).cos() - 2.0 * (two_pi * g.fy[j]).cos();
                c * c
            };
            let measured: Vec<Measured> = power
                .indexed_iter()
                .filter(|((j, k), _)| *j != 0 || *k != 0)
                .map(|((j, k), p)| Measured {
                    power: *p,
                    h: h[[j, k]],
                    rho: rho[[j, k]],
                    w: bin_weight(k, nx),
                    c2: laplacian2(j, k),
                    wiener: wiener_r(j, k),
                })
                .collect();
            let bins = restore_rule::bins(&measured, pn);
            // The fill's own uncertainty (its prediction variance, an error confined to
            // the filled pixels: flat power Σ var per DFT coefficient) is noise every
            // filter amplifies; it enters the error term W²·P of the estimate, not the
            // object power, which the filled image measures as it is.
            let mut choice = restore_rule::choose(&bins, pn + fill_variance, method, fit.is_some());
            if method == Method::Auto && !transfer.shift_invariant() {
                // A colour mosaic: no filter of one transfer function applies.
                choice.name = "none";
                choice.candidates.retain(|c| c.name == "none");
            }
            candidates = choice.candidates;
            let reg = |j: usize, k: usize| -> f64 {
                let r = match choice.name {
                    "wiener" => wiener_r(j, k),
                    "wiener-hunt" => choice.lambda * laplacian2(j, k),
                    _ => choice.nsr,
                };
                guard(r, h[[j, k]])
            };
            match choice.name {
                "none" => ("none", None),
                name => (
                    name,
                    Some(Array2::from_shape_fn(spec.dim(), |(j, k)| reg(j, k))),
                ),
            }
        }
    };
    let (image_out, nsr_median, guarded_bins) = match reg {
        None => (image.to_owned(), 0.0, 0),
        Some(mut r) => {
            r[[0, 0]] = 0.0;
            let guarded_bins = if name == "constant" {
                0
            } else {
                r.iter()
                    .zip(h.iter())
                    .filter(|(v, hv)| {
                        hv.abs() >= 0.5 && **v >= hv.abs() * (1.0 - hv.abs()) && **v > 0.0
                    })
                    .count()
            };
            let mut finite: Vec<f64> = r.iter().copied().filter(|v| !v.is_nan()).collect();
            let nsr_median = crate::processing::median_in_place(&mut finite).unwrap_or(0.0);
            ndarray::Zip::from(&mut spec)
                .and(&h)
                .and(&r)
                .for_each(|g, h, n| {
                    let d = h * h + n;
                    *g *= if d > 0.0 && d.is_finite() { h / d } else { 0.0 };
                });
            let mut out = Array2::<f64>::zeros((ny, nx));
            fft.inverse(&mut spec, &mut out, &mut scratch);
            (
                out.slice(s![py..py + rows, px..px + cols]).to_owned(),
                nsr_median,
                guarded_bins,
            )
        }
    };
    let mut image_out = image_out;
    let mut saturated_raised = 0;
    if let Some(m) = masks.saturated {
        for (r, c) in m.positions() {
            if image_out[[r, c]] < image[[r, c]] {
                image_out[[r, c]] = image[[r, c]];
                saturated_raised += 1;
            }
        }
    }
    Ok(Restoration {
        image: image_out,
        rule: match rule {
            NoiseRule::Auto => "auto",
            NoiseRule::Model { .. } => "model",
            NoiseRule::Constant(_) => "constant",
        },
        method: name,
        noise_power: variance.map(|v| npix * v),
        noise_sigma: variance.map(f64::sqrt),
        noise_sigma_measured: measured,
        nsr_median,
        spectrum_exponent: exponent,
        candidates,
        guarded_bins,
        saturated_raised,
        saturated_filled,
        saturated_fill_variance: fill_variance,
        padded_shape: (ny, nx),
    })
}

/// The (impossible) combination of a noise rule that needs a variance without one.
fn unreachable_rule() -> Result<(&'static str, Option<Array2<f64>>)> {
    Err(Error::param(
        "noise rule",
        "no noise level",
        "auto, model or constant",
    ))
}

/// Fits `P_f(ρ) = A ρ^β` to the radially averaged object spectrum `(⟨|G|²⟩ − P_n)/⟨H²⟩`
/// in 48 annuli up to the corner frequency, using the annuli where `⟨|G|²⟩ > 2 P_n` and
/// `⟨H²⟩ > 1e-4`; β is clamped to [−6, 0]. Returns (A, β).
fn fit_object_spectrum(
    power: &Array2<f64>,
    h: &Array2<f64>,
    rho: &Array2<f64>,
    pn: f64,
    nx: usize,
) -> Result<(f64, f64)> {
    const ANNULI: usize = 48;
    let rho_max = 0.5f64.hypot(0.5);
    let mut sum_p = [0.0f64; ANNULI];
    let mut sum_h2 = [0.0f64; ANNULI];
    let mut sum_r = [0.0f64; ANNULI];
    let mut sum_w = [0.0f64; ANNULI];
    for ((j, k), p) in power.indexed_iter() {
        let r = rho[[j, k]];
        if r <= 0.0 {
            continue;
        }
        let b = ((r / rho_max * ANNULI as f64) as usize).min(ANNULI - 1);
        let w = bin_weight(k, nx);
        sum_p[b] += w * p;
        sum_h2[b] += w * h[[j, k]] * h[[j, k]];
        sum_r[b] += w * r;
        sum_w[b] += w;
    }
    let mut pts = Vec::new();
    for b in 0..ANNULI {
        if sum_w[b] == 0.0 {
            continue;
        }
        let (p, h2, r) = (
            sum_p[b] / sum_w[b],
            sum_h2[b] / sum_w[b],
            sum_r[b] / sum_w[b],
        );
        if p > 2.0 * pn && h2 > 1e-4 {
            pts.push((r.ln(), ((p - pn) / h2).ln()));
        }
    }
    let Some((beta, ln_a)) = crate::processing::fit_line(&pts).filter(|_| pts.len() >= 3) else {
        return Err(Error::param(
            "noise model",
            format!("{} frequency annuli with signal above twice the noise", pts.len()),
            "an image whose spectrum exceeds the modelled noise in at least 3 annuli (use --noise auto or --nsr)",
        ));
    };
    let beta = beta.clamp(-6.0, 0.0);
    // Refit the amplitude with the clamped exponent.
    let ln_a = if pts.is_empty() {
        ln_a
    } else {
        pts.iter().map(|(x, y)| y - beta * x).sum::<f64>() / pts.len() as f64
    };
    Ok((ln_a.exp(), beta))
}

/// Default threshold of [`replace_invalid_pixels`], in robust standard deviations.
pub const IMPULSE_K_SIGMA: f64 = 6.0;

/// Replaces the pixels a Fourier-domain filter must not see: non-finite values and the
/// clusters of dead, hot and stuck pixels found by
/// [`crate::processing::bad_pixels::find_image_defects`] (no ADC limit known), each by
/// the median of its valid neighbours ([`crate::processing::bad_pixels::replace`]).
/// Returns the cleaned image and the count.
///
/// Errors: an empty image, a non-positive `k_sigma`, or no finite pixel.
pub fn replace_invalid_pixels(
    image: ArrayView2<f64>,
    k_sigma: f64,
) -> Result<(Array2<f64>, usize)> {
    let found = crate::processing::bad_pixels::find_image_defects(image, k_sigma, None)?;
    let count = found.defects.count();
    if count == 0 {
        return Ok((image.to_owned(), 0));
    }
    Ok((
        crate::processing::bad_pixels::replace(image, &found.defects)?,
        count,
    ))
}

/// Peak signal-to-noise ratio of `estimate` against `truth`, dB: `10 log10(peak² / MSE)`
/// with `peak` the truth's range (max − min). Errors on shape mismatch or a flat truth.
pub fn psnr_db(estimate: ArrayView2<f64>, truth: ArrayView2<f64>) -> Result<f64> {
    if estimate.dim() != truth.dim() {
        return Err(Error::param(
            "estimate shape",
            format!("{:?}", estimate.dim()),
            format!("the truth's shape {:?}", truth.dim()),
        ));
    }
    let (lo, hi) = truth
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let peak = hi - lo;
    if peak.is_nan() || peak <= 0.0 {
        return Err(Error::param(
            "truth",
            "flat image",
            "an image with some contrast",
        ));
    }
    let mse = estimate
        .iter()
        .zip(truth.iter())
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        / truth.len() as f64;
    Ok(10.0 * (peak * peak / mse).log10())
}

/// The summary `restore.json` gives of an image: mean, standard deviation (population),
/// minimum and maximum.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ImageStats {
    /// Mean.
    pub mean: f64,
    /// Standard deviation, √(Σ(v − mean)²/n).
    pub std: f64,
    /// Minimum.
    pub min: f64,
    /// Maximum.
    pub max: f64,
}

impl ImageStats {
    /// The statistics of `a` (NaN mean and std for an empty image).
    pub fn of(a: &Array2<f64>) -> Self {
        let n = a.len() as f64;
        let mean = a.sum() / n;
        let var = a.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n;
        let (min, max) = a
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                (l.min(*v), h.max(*v))
            });
        ImageStats {
            mean,
            std: var.sqrt(),
            min,
            max,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pad_taps_are_continuous_across_the_circular_seam() {
        // A ramp padded circularly: neighbouring padded samples never jump by more than
        // the ramp's own range over the cross-fade, and the image part is copied.
        let n = 40;
        let x: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let pad = pad_for(n);
        let len = next_fast_len(n + 2 * pad);
        let t = pad_taps(n, pad, len);
        let v: Vec<f64> = t
            .iter()
            .map(|(a, b, w)| w * x[*a] + (1.0 - w) * x[*b])
            .collect();
        for i in 0..n {
            assert_eq!(v[pad + i], x[i]);
        }
        let max_step = (0..len)
            .map(|j| (v[(j + 1) % len] - v[j]).abs())
            .fold(0.0f64, f64::max);
        // The cross-fade goes from n−1 to 0 over the gap: steps ≤ π/2·(n−1)/gap + 1.
        let gap = (len - n) as f64;
        assert!(max_step <= std::f64::consts::FRAC_PI_2 * (n as f64 - 1.0) / gap + 1.0 + 1e-9);
    }
}
