//! The average of M frames of a uniform source through a detector instance, drawn in one
//! pass from its exact moments instead of exposing M frames (issue 9: calibration at a
//! fraction of the run's cost, same statistics).
//!
//! Per pixel, the instance's chain ([`crate::detector`] steps 1–9) with mean total
//! electrons μ, gain g, offset o (electrons), quadratic coefficient a, read noise σ_r,
//! conversion gain K and ADC offset is, frame by frame,
//!
//! `DN_i = round(K·n(g·P_i + o) + K·r_i + offset)`, P_i ~ Poisson(μ), r_i ~ N(0, σ_r²).
//!
//! Its mean and variance, with `y = gμ + o` and `n(y) = y + a y²`:
//!
//! - `E[n(gP + o)] = n(y) + a g² μ` exactly (a quadratic of a Poisson variable),
//!   `Var ≈ (n'(y))² g² μ` (delta method; the neglected term 2a²g⁴μ² is below 1e-6 of the
//!   variance for every |a| the presets use);
//! - plus the read noise σ_r² (independent), times K²;
//! - rounding: for a total σ ≥ 1 DN the rounding error is uniform and independent of the
//!   signal to within e^{−2π²σ²} < 3e-9 (Sheppard's correction, the Fourier series of the
//!   sawtooth under a Gaussian), so the mean is unchanged and the variance gains 1/12 DN²;
//!   below 1 DN the mean and variance of the rounded, ADC-clipped value are summed exactly
//!   over the integers within ±8σ (Gaussian cumulative probabilities).
//!
//! The M-frame average is then drawn as `mean + √(var/M)·z`, z ~ N(0, 1): the frames are
//! independent, so the average has exactly this mean and variance, and by the central limit
//! theorem (Poisson(Mμ)/M plus Gaussian read noise) this distribution. Defects read their
//! fixed value (dead 0, hot full scale, stuck its DN) with no noise.
//!
//! A pixel is marked *clipped* when the brute-force route would, more likely than not, have
//! seen it at 0 or full scale in at least one of the M frames: `1 − (1 − p)^M ≥ ½`, p the
//! per-frame probability of reading 0 or 2^bits − 1 (Gaussian tails of the unrounded DN),
//! or when its mean electrons come within 5σ of the full well.
//!
//! Randomness: one stream per (instance seed, level key, row), so the draw is deterministic
//! and independent of the number of threads, and independent of the detector's own temporal
//! streams.

use std::borrow::Cow;

use ndarray::{Array2, Zip};
use rand::{RngExt, SeedableRng};
use rand_distr::StandardNormal;
use rand_xoshiro::Xoshiro256PlusPlus;

use crate::detector::{apply_nonlinearity, mean_total_e, Defect, DetectorInstance};
use crate::error::{Error, Result};

/// Standard deviations of shot noise within which a mean approaching the full well counts
/// as clipped.
const FULL_WELL_SIGMAS: f64 = 5.0;

/// Total noise (DN) from which the rounding error is treated as uniform and independent.
const DITHERED_SIGMA_DN: f64 = 1.0;

/// Distance (σ) from the ADC limits beyond which the clip probability is taken as 0.
const CLIP_SEARCH_SIGMAS: f64 = 10.0;

/// Half-width (σ) of the exact sum over integer DN for a noise below [`DITHERED_SIGMA_DN`].
const EXACT_SUM_SIGMAS: f64 = 8.0;

/// The per-pixel maps of one instance for all levels: borrowed where the instance stores
/// them, built (constant) only where a pattern is off.
pub struct InstanceMaps<'a> {
    gain: Cow<'a, Array2<f64>>,
    offset_e: Cow<'a, Array2<f64>>,
    quadratic: Cow<'a, Array2<f64>>,
    defects: &'a Array2<u8>,
    stuck_dn: Option<&'a Array2<u16>>,
}

impl<'a> InstanceMaps<'a> {
    /// The maps of `instance`.
    pub fn of(instance: &'a DetectorInstance) -> Self {
        let [gain, offset_e, quadratic] = instance.stored_maps();
        let shape = (instance.model().rows(), instance.model().cols());
        let or = |map: Option<&'a Array2<f64>>, value: f64| match map {
            Some(m) => Cow::Borrowed(m),
            None => Cow::Owned(Array2::from_elem(shape, value)),
        };
        InstanceMaps {
            gain: or(gain, 1.0),
            offset_e: or(offset_e, 0.0),
            quadratic: or(quadratic, 0.0),
            defects: instance.defect_map(),
            stuck_dn: instance.stuck_dn_map(),
        }
    }
}

/// SplitMix64 finaliser (Steele, Lea & Flood, OOPSLA 2014), to key the row streams.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Stream constant of the flat-field draws ("FLATAVG").
const STREAM: u64 = 0x0046_4c41_5441_5647;

/// Standard normal cumulative distribution Φ(z).
fn normal_cdf(z: f64) -> f64 {
    0.5 * libm::erfc(-z / std::f64::consts::SQRT_2)
}

/// Mean and variance (DN, DN²) of one frame's ADC output for an unrounded DN that is
/// Gaussian with mean `x` and standard deviation `sigma`, and the probability that the
/// frame reads 0 or `max_dn` (module documentation).
fn adc_moments(x: f64, sigma: f64, max_dn: f64) -> (f64, f64, f64) {
    if sigma <= 0.0 {
        let v = x.round().clamp(0.0, max_dn);
        let clip = if v <= 0.0 || v >= max_dn { 1.0 } else { 0.0 };
        return (v, 0.0, clip);
    }
    // Beyond 10σ from both limits the clip probability is below 1e-23: skip the erfc.
    let p_clip =
        if x - CLIP_SEARCH_SIGMAS * sigma > 0.5 && x + CLIP_SEARCH_SIGMAS * sigma < max_dn - 0.5 {
            0.0
        } else {
            normal_cdf((0.5 - x) / sigma) + normal_cdf((x - (max_dn - 0.5)) / sigma)
        };
    if sigma >= DITHERED_SIGMA_DN {
        return (x.clamp(0.0, max_dn), sigma * sigma + 1.0 / 12.0, p_clip);
    }
    let lo = (x - EXACT_SUM_SIGMAS * sigma - 1.0).floor().max(0.0);
    let hi = (x + EXACT_SUM_SIGMAS * sigma + 1.0).ceil().min(max_dn);
    let (mut s0, mut s1, mut s2) = (0.0, 0.0, 0.0);
    let mut k = lo;
    while k <= hi {
        let below = if k <= 0.0 {
            0.0
        } else {
            normal_cdf((k - 0.5 - x) / sigma)
        };
        let above = if k >= max_dn {
            1.0
        } else {
            normal_cdf((k + 0.5 - x) / sigma)
        };
        let p = above - below;
        s0 += p;
        s1 += p * k;
        s2 += p * k * k;
        k += 1.0;
    }
    if s0 <= 0.0 {
        let v = x.round().clamp(0.0, max_dn);
        return (v, 0.0, p_clip);
    }
    let mean = s1 / s0;
    (mean, (s2 / s0 - mean * mean).max(0.0), p_clip)
}

/// Per-frame mean DN, variance DN² and whether the pixel counts as clipped, for a pixel
/// of signal `signal_e` with maps `(g, o, a)` through the chain `c` (module
/// documentation).
fn pixel_moments(
    c: &ChainConstants,
    signal_e: f64,
    (g, o, a): (f64, f64, f64),
) -> (f64, f64, bool) {
    let mu = mean_total_e(signal_e, c.dark_e, c.background_e);
    let var_e = if c.shot_noise { mu } else { 0.0 };
    let near_full_well = mu + FULL_WELL_SIGMAS * var_e.sqrt() >= c.full_well_e;
    let e = mu.min(c.full_well_e);
    let var_e = if mu >= c.full_well_e { 0.0 } else { var_e };
    let y = g * e + o;
    let var_y = g * g * var_e;
    let turn = if a == 0.0 { f64::INFINITY } else { -0.5 / a };
    let past = a != 0.0 && if a < 0.0 { y > turn } else { y < turn };
    let (z, var_z) = if a == 0.0 {
        (y, var_y)
    } else if past {
        (apply_nonlinearity(y, a), 0.0)
    } else {
        let slope = 1.0 + 2.0 * a * y;
        (apply_nonlinearity(y, a) + a * var_y, slope * slope * var_y)
    };
    let k = c.gain_dn_per_e;
    let r = c.read_noise_e;
    let x = k * z + c.offset_dn;
    let var_x = k * k * (var_z + r * r);
    let (mean, var, p_clip) = adc_moments(x, var_x.sqrt(), c.max_dn);
    // p_clip = 0 (every pixel 10 σ inside the ADC range) needs no power.
    let clipped =
        near_full_well || (p_clip > 0.0 && 1.0 - (1.0 - p_clip).powi(c.frames as i32) >= 0.5);
    (mean, var, clipped)
}

/// One row's inputs to [`ChainConstants::row`]: mean signal electrons, the instance's maps
/// and one normal draw per pixel.
struct RowInputs<'a> {
    signal: &'a [f64],
    gain: &'a [f64],
    offset: &'a [f64],
    quadratic: &'a [f64],
    z: &'a [f64],
}

/// The constants of the chain every pixel shares ([`pixel_moments`]), and the case of
/// [`pixel_moments`] almost every pixel takes, for a whole row at once
/// ([`ChainConstants::row`]): before
/// the nonlinearity's turning point (or none), a total noise of at least
/// [`DITHERED_SIGMA_DN`] and more than [`CLIP_SEARCH_SIGMAS`] σ inside the ADC range, so
/// the moments are `(x, σ² + 1/12)` and no clipping. Written without branches so that the
/// compiler vectorises it (compiled for AVX2 too, chosen at run time); every pixel gets
/// the same IEEE operations in the same order as in [`pixel_moments`] and
/// [`average`]'s draw, so the same bits. Pixels outside the case are left to the scalar
/// path (`settled[j]` false).
struct ChainConstants {
    dark_e: f64,
    background_e: f64,
    shot_noise: bool,
    full_well_e: f64,
    gain_dn_per_e: f64,
    read_noise_e: f64,
    offset_dn: f64,
    max_dn: f64,
    /// Frames averaged, M.
    frames: usize,
}

impl ChainConstants {
    fn of(instance: &DetectorInstance, frames: usize) -> Self {
        let m = instance.model();
        ChainConstants {
            dark_e: m.dark_e(),
            background_e: m.background_e(),
            shot_noise: m.shot_noise(),
            full_well_e: m.full_well_e(),
            gain_dn_per_e: m.gain_dn_per_e(),
            read_noise_e: m.read_noise_e(),
            offset_dn: m.offset_dn(),
            max_dn: m.max_dn(),
            frames,
        }
    }

    /// Sets `settled[j]` for the row's pixels in the common case and writes their
    /// `avg[j]` and `clipped[j]`; for the others it writes values the caller must replace
    /// (the scalar path).
    fn row(&self, r: RowInputs<'_>, avg: &mut [f64], clipped: &mut [bool], settled: &mut [bool]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            unsafe { self.row_avx2(r, avg, clipped, settled) };
            return;
        }
        self.row_body(r, avg, clipped, settled);
    }

    /// [`ChainConstants::row_body`] compiled for AVX2.
    ///
    /// # Safety
    /// The CPU must support AVX2 (`is_x86_feature_detected!("avx2")`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn row_avx2(
        &self,
        r: RowInputs<'_>,
        avg: &mut [f64],
        clipped: &mut [bool],
        settled: &mut [bool],
    ) {
        self.row_body(r, avg, clipped, settled);
    }

    /// The loop of [`ChainConstants::row`].
    #[inline(always)]
    fn row_body(
        &self,
        r: RowInputs<'_>,
        avg: &mut [f64],
        clipped: &mut [bool],
        settled: &mut [bool],
    ) {
        let n = avg
            .len()
            .min(clipped.len())
            .min(settled.len())
            .min(r.signal.len())
            .min(r.gain.len())
            .min(r.offset.len())
            .min(r.quadratic.len())
            .min(r.z.len());
        let (fw, k, max) = (self.full_well_e, self.gain_dn_per_e, self.max_dn);
        let rr = self.read_noise_e * self.read_noise_e;
        let frames = self.frames as f64;
        for j in 0..n {
            let (g, o, a) = (r.gain[j], r.offset[j], r.quadratic[j]);
            let mu = mean_total_e(r.signal[j], self.dark_e, self.background_e);
            let var_e = if self.shot_noise { mu } else { 0.0 };
            let near_full_well = mu + FULL_WELL_SIGMAS * var_e.sqrt() >= fw;
            let e = mu.min(fw);
            let var_e = if mu >= fw { 0.0 } else { var_e };
            let y = g * e + o;
            let var_y = g * g * var_e;
            let turn = -0.5 / a;
            // `&`/`|`, not `&&`/`||`: no short-circuit branches in the loop body.
            let past = (a != 0.0) & (((a < 0.0) & (y > turn)) | ((a > 0.0) & (y < turn)));
            let slope = 1.0 + 2.0 * a * y;
            let z = if a == 0.0 {
                y
            } else {
                y + a * y * y + a * var_y
            };
            let var_z = if a == 0.0 {
                var_y
            } else {
                slope * slope * var_y
            };
            let x = k * z + self.offset_dn;
            let var_x = k * k * (var_z + rr);
            let sigma = var_x.sqrt();
            let common = !past
                & (sigma >= DITHERED_SIGMA_DN)
                & (x - CLIP_SEARCH_SIGMAS * sigma > 0.5)
                & (x + CLIP_SEARCH_SIGMAS * sigma < max - 0.5);
            // In the common case x lies inside (0.5, max − 0.5), so the ADC mean is x
            // itself (no `clamp`, whose panic check keeps the loop scalar).
            let var = sigma * sigma + 1.0 / 12.0;
            let v = x + (var / frames).sqrt() * r.z[j];
            // Unconditional stores (so the loop vectorises): the scalar path overwrites
            // every pixel that is not settled here.
            avg[j] = v;
            clipped[j] = near_full_well;
            settled[j] = common;
        }
    }
}

/// The average of `frames` frames of `mean_e` (mean signal electrons per pixel) through
/// `instance`, drawn from its exact moments with the streams of `level_key`, and the mask
/// of pixels that count as clipped (module documentation).
///
/// Errors: `mean_e` of another shape than the instance, a non-finite value, or
/// `frames` = 0.
pub fn average(
    instance: &DetectorInstance,
    maps: &InstanceMaps<'_>,
    mean_e: &Array2<f64>,
    frames: usize,
    level_key: u64,
) -> Result<(Array2<f64>, Array2<bool>)> {
    let m = instance.model();
    let (rows, cols) = (m.rows(), m.cols());
    if mean_e.dim() != (rows, cols) {
        return Err(Error::param(
            "mean electrons",
            format!("{} x {}", mean_e.nrows(), mean_e.ncols()),
            format!("the detector's {rows} x {cols} pixels"),
        ));
    }
    if frames == 0 {
        return Err(Error::param("frames", 0, "at least 1 frame to average"));
    }
    if let Some(v) = mean_e.iter().find(|v| !v.is_finite()) {
        return Err(Error::param(
            "mean electrons",
            v,
            "a finite number of electrons",
        ));
    }
    let key = mix(mix(mix(instance.seed()) ^ STREAM) ^ level_key);
    let max = m.max_dn();
    let chain = ChainConstants::of(instance, frames);
    let mut avg = Array2::zeros((rows, cols));
    let mut clipped = Array2::from_elem((rows, cols), false);
    Zip::indexed(avg.rows_mut())
        .and(clipped.rows_mut())
        .par_for_each(|i, mut avg, mut clipped| {
            let (Some(avg), Some(clipped)) = (avg.as_slice_mut(), clipped.as_slice_mut()) else {
                unreachable!("rows of a fresh standard-layout array are contiguous")
            };
            let signal = mean_e.row(i);
            let (gain, offset) = (maps.gain.row(i), maps.offset_e.row(i));
            let (quadratic, defects) = (maps.quadratic.row(i), maps.defects.row(i));
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(mix(key ^ i as u64));
            // One normal draw per pixel, in pixel order, whatever its path.
            let z: Vec<f64> = (0..cols).map(|_| rng.sample(StandardNormal)).collect();
            let mut settled = vec![false; cols];
            if let (Some(s), Some(g), Some(o), Some(a)) = (
                signal.as_slice(),
                gain.as_slice(),
                offset.as_slice(),
                quadratic.as_slice(),
            ) {
                chain.row(
                    RowInputs {
                        signal: s,
                        gain: g,
                        offset: o,
                        quadratic: a,
                        z: &z,
                    },
                    avg,
                    clipped,
                    &mut settled,
                );
            }
            for j in 0..cols {
                let fixed = match Defect::from_code(defects[j] as u16) {
                    Some(Defect::Dead) => Some(0.0),
                    Some(Defect::Hot) => Some(max),
                    Some(Defect::Stuck) => maps.stuck_dn.as_ref().map(|s| s[[i, j]] as f64),
                    _ => None,
                };
                if let Some(v) = fixed {
                    avg[j] = v;
                    clipped[j] = v <= 0.0 || v >= max;
                    continue;
                }
                if settled[j] {
                    continue;
                }
                let (mean, var, clip) =
                    pixel_moments(&chain, signal[j], (gain[j], offset[j], quadratic[j]));
                avg[j] = mean + (var / frames as f64).sqrt() * z[j];
                clipped[j] = clip;
            }
        });
    Ok((avg, clipped))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The row path gives every pixel it settles the scalar path's value bit for bit, and
    /// marks the others (past the turning point, noise below 1 DN, near the ADC limits) as
    /// not settled, for the scalar path to overwrite; both paths are exercised.
    #[test]
    fn the_row_path_equals_pixel_moments_bit_for_bit() {
        let mut settled_total = 0;
        let mut left_total = 0;
        for (shot_noise, read_noise_e, gain_dn_per_e) in [
            (true, 40.0, 0.01),
            (false, 0.5, 0.001),
            (true, 0.0, 0.012),
            (false, 2000.0, 0.01),
        ] {
            let c = ChainConstants {
                dark_e: 1200.0,
                background_e: 300.5,
                shot_noise,
                full_well_e: 1.5e6,
                gain_dn_per_e,
                read_noise_e,
                offset_dn: 250.0,
                max_dn: 16383.0,
                frames: 16,
            };
            let n = 600;
            let signal: Vec<f64> = (0..n).map(|j| -500.0 + 2.2e3 * j as f64).collect();
            let gain: Vec<f64> = (0..n).map(|j| 0.9 + 0.0007 * (j % 300) as f64).collect();
            let offset: Vec<f64> = (0..n).map(|j| -40.0 + (j % 7) as f64 * 13.0).collect();
            // No nonlinearity, mild ones of both signs, and strong ones past their turn.
            let quadratic: Vec<f64> = (0..n)
                .map(|j| [0.0, 1e-8, -1e-8, 3e-7, -3e-6][j % 5])
                .collect();
            let z: Vec<f64> = (0..n)
                .map(|j| ((j * 37 % 101) as f64 - 50.0) / 17.0)
                .collect();
            // The row path writes every pixel; only the settled ones are its to keep.
            let (mut avg, mut clipped, mut settled) =
                (vec![0.0; n], vec![false; n], vec![false; n]);
            let r = RowInputs {
                signal: &signal,
                gain: &gain,
                offset: &offset,
                quadratic: &quadratic,
                z: &z,
            };
            c.row(r, &mut avg, &mut clipped, &mut settled);
            for j in 0..n {
                let (mean, var, clip) =
                    pixel_moments(&c, signal[j], (gain[j], offset[j], quadratic[j]));
                let v = mean + (var / c.frames as f64).sqrt() * z[j];
                if settled[j] {
                    settled_total += 1;
                    assert_eq!(
                        (avg[j].to_bits(), clipped[j]),
                        (v.to_bits(), clip),
                        "pixel {j}: row path {} / {}, scalar {v} / {clip}",
                        avg[j],
                        clipped[j]
                    );
                } else {
                    left_total += 1;
                }
            }
        }
        assert!(
            settled_total > 1200 && left_total > 800,
            "{settled_total} settled, {left_total} left"
        );
    }

    /// Exact moments of the rounded Gaussian agree with Sheppard's form once σ ≥ 1 DN,
    /// and a noiseless pixel rounds.
    #[test]
    fn adc_moments_match_sheppard_and_the_noiseless_limit() {
        let (m, v, p) = adc_moments(100.3, 0.0, 16383.0);
        assert_eq!((m, v, p), (100.0, 0.0, 0.0));
        for x in [100.0, 100.25, 100.5, 100.8] {
            // Exact sum at σ = 0.999 vs Sheppard at σ = 1: both ~σ² + 1/12.
            let (m_exact, v_exact, _) = adc_moments(x, 0.999_999, 16383.0);
            assert!((m_exact - x).abs() < 1e-6, "{x}: {m_exact}");
            assert!(
                (v_exact - (1.0 + 1.0 / 12.0)).abs() < 1e-4,
                "{x}: {v_exact}"
            );
        }
        // Half-way between two DN with σ = 0.1: mean exactly the midpoint by symmetry.
        let (m, v, _) = adc_moments(100.5, 0.1, 16383.0);
        assert!(
            (m - 100.5).abs() < 1e-12 && (v - 0.25).abs() < 1e-12,
            "{m} {v}"
        );
    }

    #[test]
    fn clip_probability_at_the_adc_limits() {
        let (_, _, p) = adc_moments(0.0, 2.0, 16383.0);
        assert!((p - normal_cdf(0.25)).abs() < 1e-12);
        let (_, _, p) = adc_moments(16383.0, 0.0, 16383.0);
        assert_eq!(p, 1.0);
    }
}
