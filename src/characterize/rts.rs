//! Finding random telegraph signal (RTS) pixels in a dark sequence.
//!
//! A pixel with a two-level RTS has a bimodal distribution of values over the frames (two
//! Gaussian read-noise peaks separated by the RTS step, plus a few frames in between when
//! the state switched during the integration); a normal pixel has one peak. For every
//! pixel [`find_rts_pixels`]
//!
//! 1. takes its time series after subtracting each frame's median over the array (removes
//!    common-mode offsets such as a drifting bias or row-independent 1/f),
//! 2. splits the sorted values into a low and a high class at the threshold that
//!    maximises the between-class variance `w_0·w_1·(μ_1 − μ_0)²` (Otsu 1979, IEEE Trans.
//!    Syst. Man Cybern. 9, 62; the two-class k-means in one dimension), each class holding
//!    at least `min_frames` frames,
//! 3. measures the separation of the two classes in units of the pooled within-class
//!    standard deviation, `s = (μ_1 − μ_0) / sqrt((SS_0 + SS_1)/(N − 2))`,
//! 4. flags the pixel when `s ≥ threshold_sigma`, with the pooled σ floored at a quarter of
//!    the array's median (a pixel without temporal noise — dead, hot, stuck — whose value
//!    moves by one DN with the frame median would otherwise have s = ∞).
//!
//! For a pure Gaussian pixel the optimal split is near the median and s ≈ 2·0.798/0.603
//! ≈ 2.65 (the half-normal means ±0.798σ, the half-normal standard deviation 0.603σ), so
//! the default threshold 4 keeps false positives rare; an RTS pixel whose step is a few
//! read-noise σ or more and that visits both states for `min_frames` frames gives s close
//! to step/σ. The statistic is scale-free, so the stack may be in DN or in electrons.
//! This is a screening test in the spirit of the level-histogram methods of RTS studies
//! (e.g. Goiffon et al. 2009, IEEE Trans. Nucl. Sci. 56, 2132); it does not estimate
//! τ_high and τ_low.

use ndarray::{ArrayView3, Axis};
use rayon::prelude::*;

use crate::error::{Error, Result};

/// Settings of [`find_rts_pixels`].
#[derive(Debug, Clone, PartialEq)]
pub struct RtsSearch {
    /// Minimum separation of the two levels, in pooled within-level standard deviations
    /// (default 4).
    pub threshold_sigma: f64,
    /// Minimum number of frames in each level (default 3).
    pub min_frames: usize,
    /// Subtract each frame's median over the array first (default true).
    pub remove_frame_median: bool,
}

impl Default for RtsSearch {
    fn default() -> Self {
        RtsSearch {
            threshold_sigma: 4.0,
            min_frames: 3,
            remove_frame_median: true,
        }
    }
}

/// One pixel flagged as an RTS pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct RtsDetection {
    /// Flat index row·cols + col.
    pub pixel: usize,
    /// Row of the pixel.
    pub row: usize,
    /// Column of the pixel.
    pub col: usize,
    /// Mean of the high level minus mean of the low level, in the stack's unit.
    pub step: f64,
    /// Fraction of the frames in the high level.
    pub high_fraction: f64,
    /// Separation of the levels in pooled within-level standard deviations.
    pub separation_sigma: f64,
}

/// The RTS pixels of a dark sequence `stack` (frames × rows × cols, DN or e⁻), ascending
/// by flat index (method in the module documentation).
///
/// Errors: fewer frames than `2·min_frames + 2` (or than 8), a non-finite value in the
/// stack, a threshold that is not a finite number > 0, or `min_frames` = 0.
pub fn find_rts_pixels(stack: ArrayView3<f64>, search: &RtsSearch) -> Result<Vec<RtsDetection>> {
    let (frames, rows, cols) = stack.dim();
    if !(search.threshold_sigma.is_finite() && search.threshold_sigma > 0.0) {
        return Err(Error::param(
            "find_rts_pixels.threshold_sigma",
            search.threshold_sigma,
            "a finite number > 0",
        ));
    }
    if search.min_frames == 0 {
        return Err(Error::param("find_rts_pixels.min_frames", 0, "at least 1"));
    }
    let needed = (2 * search.min_frames + 2).max(8);
    if frames < needed {
        return Err(Error::param(
            "find_rts_pixels.stack",
            format!("{frames} frames"),
            format!("at least {needed} frames"),
        ));
    }
    if let Some(i) = stack.iter().position(|v| !v.is_finite()) {
        let per_frame = rows * cols;
        return Err(Error::param(
            "find_rts_pixels.stack",
            format!(
                "a non-finite value at frame {}, row {}, column {}",
                i / per_frame,
                (i % per_frame) / cols.max(1),
                i % cols.max(1)
            ),
            "finite values",
        ));
    }
    let medians: Vec<f64> = if search.remove_frame_median && rows * cols > 0 {
        stack
            .axis_iter(Axis(0))
            .into_par_iter()
            .map(|f| {
                let mut v: Vec<f64> = f.iter().copied().collect();
                let mid = v.len() / 2;
                let (_, m, _) = v.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
                *m
            })
            .collect()
    } else {
        vec![0.0; frames]
    };
    // Every pixel's split: (pixel, step, high fraction, pooled within-level σ).
    let splits: Vec<Vec<(usize, f64, f64, f64)>> = (0..rows)
        .into_par_iter()
        .map(|r| {
            let mut out = Vec::new();
            let mut series = vec![0.0; frames];
            let mut prefix = vec![0.0; frames + 1];
            let mut prefix_sq = vec![0.0; frames + 1];
            for c in 0..cols {
                for (k, s) in series.iter_mut().enumerate() {
                    *s = stack[[k, r, c]] - medians[k];
                }
                if let Some((step, high_fraction, pooled)) =
                    two_level_split(&mut series, &mut prefix, &mut prefix_sq, search.min_frames)
                {
                    out.push((r * cols + c, step, high_fraction, pooled));
                }
            }
            out
        })
        .collect();
    let splits: Vec<(usize, f64, f64, f64)> = splits.into_iter().flatten().collect();
    // A pixel without temporal noise (dead, hot, stuck, saturated) whose values move by a
    // quantum with the frame median is no RTS pixel: its spread is floored at a quarter of
    // the array's typical within-level σ (the median over the pixels; 0 for a noise-free
    // stack, which keeps every exact two-level pixel).
    let floor = {
        let mut p: Vec<f64> = splits.iter().map(|s| s.3).collect();
        if p.is_empty() {
            0.0
        } else {
            let mid = p.len() / 2;
            let (_, m, _) = p.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
            NOISE_FLOOR_FRACTION * *m
        }
    };
    Ok(splits
        .into_iter()
        .filter_map(|(pixel, step, high_fraction, pooled)| {
            let spread = pooled.max(floor);
            let separation_sigma = if spread > 0.0 {
                step / spread
            } else {
                f64::INFINITY
            };
            (separation_sigma >= search.threshold_sigma).then_some(RtsDetection {
                pixel,
                row: pixel / cols,
                col: pixel % cols,
                step,
                high_fraction,
                separation_sigma,
            })
        })
        .collect())
}

/// The floor of a pixel's within-level σ, as a fraction of the array's median
/// (see [`find_rts_pixels`]).
const NOISE_FLOOR_FRACTION: f64 = 0.25;

/// Otsu split of one time series: (step, high fraction, pooled within-level σ), or None
/// when the series is constant. `series` is sorted in place; the prefix buffers have
/// length `series.len() + 1`.
fn two_level_split(
    series: &mut [f64],
    prefix: &mut [f64],
    prefix_sq: &mut [f64],
    min_frames: usize,
) -> Option<(f64, f64, f64)> {
    let n = series.len();
    series.sort_by(|a, b| a.total_cmp(b));
    // Centre on the median so the sums of squares do not cancel.
    let centre = series[n / 2];
    for i in 0..n {
        let v = series[i] - centre;
        prefix[i + 1] = prefix[i] + v;
        prefix_sq[i + 1] = prefix_sq[i] + v * v;
    }
    let (total, total_sq) = (prefix[n], prefix_sq[n]);
    let mut best: Option<(f64, usize)> = None;
    for (k, &below) in prefix
        .iter()
        .enumerate()
        .take(n - min_frames + 1)
        .skip(min_frames)
    {
        let (n0, n1) = (k as f64, (n - k) as f64);
        let mu0 = below / n0;
        let mu1 = (total - below) / n1;
        let between = n0 * n1 * (mu1 - mu0) * (mu1 - mu0);
        if best.is_none_or(|(b, _)| between > b) {
            best = Some((between, k));
        }
    }
    let (_, k) = best?;
    let (n0, n1) = (k as f64, (n - k) as f64);
    let mu0 = prefix[k] / n0;
    let mu1 = (total - prefix[k]) / n1;
    let ss0 = (prefix_sq[k] - n0 * mu0 * mu0).max(0.0);
    let ss1 = ((total_sq - prefix_sq[k]) - n1 * mu1 * mu1).max(0.0);
    let pooled = ((ss0 + ss1) / (n as f64 - 2.0)).sqrt();
    let step = mu1 - mu0;
    if step.is_nan() || step <= 0.0 {
        return None;
    }
    Some((step, n1 / n as f64, pooled))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detector::rts::{RtsConfig, RtsPixels};
    use ndarray::Array3;
    use rand::{RngExt, SeedableRng};
    use rand_distr::StandardNormal;
    use rand_xoshiro::Xoshiro256PlusPlus;

    /// A dark sequence: a DSNU offset per pixel, Gaussian read noise σ = 10 e⁻, and RTS
    /// pixels from [`RtsPixels`] (global shutter, 15 ms integration every 20 ms).
    fn dark_sequence(
        cfg: &RtsConfig,
        frames: usize,
        rows: usize,
        cols: usize,
    ) -> (Array3<f64>, Vec<usize>) {
        let mut rts = RtsPixels::new(cfg, rows, cols, 2024);
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(99);
        let dsnu: Vec<f64> = (0..rows * cols)
            .map(|_| 100.0 + 30.0 * rng.sample::<f64, _>(StandardNormal))
            .collect();
        let mut stack = Array3::zeros((frames, rows, cols));
        for k in 0..frames {
            let t0 = k as f64 * 0.02;
            let f = rts.frame(&|_| (t0, t0 + 0.015), &|_| t0 + 0.015);
            let mut plane = stack.index_axis_mut(Axis(0), k);
            for (i, v) in plane.iter_mut().enumerate() {
                *v = dsnu[i] + 10.0 * rng.sample::<f64, _>(StandardNormal);
            }
            for (&p, e) in rts.pixels().iter().zip(&f.extra_e) {
                plane[[p / cols, p % cols]] += e;
            }
        }
        (stack, rts.pixels().to_vec())
    }

    #[test]
    fn finds_95_percent_of_the_planted_rts_pixels_with_under_1_percent_false_positives() {
        // High level = 2667 e⁻/s × 15 ms + 20 e⁻ = 60 e⁻ = 6 σ of the read noise.
        let cfg = RtsConfig {
            fraction: 0.02,
            tau_high_s: 0.3,
            tau_low_s: 0.7,
            dark_step_e_per_s: 40.0 / 0.015,
            offset_step_e: 20.0,
        };
        let (frames, rows, cols) = (300, 96, 96);
        let (stack, planted) = dark_sequence(&cfg, frames, rows, cols);
        assert!(planted.len() > 100);
        let found = find_rts_pixels(stack.view(), &RtsSearch::default()).unwrap();
        let hits = found
            .iter()
            .filter(|d| planted.binary_search(&d.pixel).is_ok())
            .count();
        let false_pos = found.len() - hits;
        let detection = hits as f64 / planted.len() as f64;
        let fp_rate = false_pos as f64 / (rows * cols - planted.len()) as f64;
        println!(
            "RTS finder: {hits}/{} planted found ({:.1} %), {false_pos} false positives \
             ({:.3} %)",
            planted.len(),
            100.0 * detection,
            100.0 * fp_rate
        );
        assert!(detection >= 0.95, "detection {detection}");
        assert!(fp_rate < 0.01, "false positives {fp_rate}");
        // The measured step of a clean two-level pixel is close to the planted 60 e⁻,
        // and its high fraction to τ_high/(τ_high+τ_low) on average.
        let steps: Vec<f64> = found.iter().map(|d| d.step).collect();
        let mean_step = steps.iter().sum::<f64>() / steps.len() as f64;
        assert!((mean_step - 60.0).abs() < 6.0, "mean step {mean_step}");
        assert!(found.windows(2).all(|w| w[0].pixel < w[1].pixel));
    }

    #[test]
    fn detection_rate_against_the_step_in_read_noise_sigma() {
        // Same sequence as above with the high level (2/3 dark step, 1/3 offset step)
        // swept: below the threshold (3 σ) nothing is found, from 5 σ ≥ 95 % is.
        let mut rates = Vec::new();
        for high_e in [30.0, 40.0, 45.0, 50.0, 60.0] {
            let cfg = RtsConfig {
                fraction: 0.02,
                tau_high_s: 0.3,
                tau_low_s: 0.7,
                dark_step_e_per_s: high_e * 2.0 / 3.0 / 0.015,
                offset_step_e: high_e / 3.0,
            };
            let (stack, planted) = dark_sequence(&cfg, 300, 96, 96);
            let found = find_rts_pixels(stack.view(), &RtsSearch::default()).unwrap();
            let hits = found
                .iter()
                .filter(|d| planted.binary_search(&d.pixel).is_ok())
                .count();
            let rate = hits as f64 / planted.len() as f64;
            println!(
                "step {:.1} σ: {hits}/{} found, {} false positives",
                high_e / 10.0,
                planted.len(),
                found.len() - hits
            );
            assert!(found.len() - hits < 93, "false positives at {high_e}");
            rates.push(rate);
        }
        assert!(rates[0] < 0.05, "{rates:?}");
        assert!(rates.windows(2).all(|w| w[1] >= w[0]), "{rates:?}");
        assert!(rates[3] >= 0.95, "{rates:?}");
    }

    #[test]
    fn a_gaussian_pixel_sits_near_the_half_normal_separation() {
        // Independent check of the null statistic: 2·0.798/0.603 ≈ 2.65 for N → ∞.
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(5);
        let mut s: Vec<f64> = (0..20_000).map(|_| rng.sample(StandardNormal)).collect();
        let n = s.len();
        let (mut p, mut q) = (vec![0.0; n + 1], vec![0.0; n + 1]);
        let (step, frac, pooled) = two_level_split(&mut s, &mut p, &mut q, 3).unwrap();
        let sep = step / pooled;
        let half = (2.0 / std::f64::consts::PI).sqrt();
        let expected = 2.0 * half / (1.0 - half * half).sqrt();
        assert!((sep - expected).abs() < 0.03, "{sep} vs {expected}");
        assert!((frac - 0.5).abs() < 0.02);
    }

    /// A pixel without noise (stuck at one DN) in a noisy quantised stack moves by one DN
    /// with the frame median: two exact levels, no spread. It is not an RTS pixel; a real
    /// two-level pixel beside it is found.
    #[test]
    fn a_noiseless_stuck_pixel_is_not_an_rts_pixel() {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(9);
        let mut stack = Array3::<f64>::zeros((60, 16, 16));
        stack.mapv_inplace(|_| (1000.0 + 4.5 * rng.sample::<f64, _>(StandardNormal)).round());
        for k in 0..60 {
            stack[[k, 3, 3]] = 1200.0; // stuck
            if (k / 7) % 2 == 1 {
                stack[[k, 9, 11]] += 45.0; // RTS, 10 σ
            }
        }
        let found = find_rts_pixels(stack.view(), &RtsSearch::default()).unwrap();
        let at: Vec<(usize, usize)> = found.iter().map(|d| (d.row, d.col)).collect();
        assert_eq!(at, vec![(9, 11)], "{found:?}");
    }

    #[test]
    fn bad_input_is_an_error() {
        let short = Array3::<f64>::zeros((5, 4, 4));
        let e = find_rts_pixels(short.view(), &RtsSearch::default()).unwrap_err();
        assert!(e.to_string().contains("find_rts_pixels.stack"));
        let mut nan = Array3::<f64>::zeros((20, 4, 4));
        nan[[3, 2, 1]] = f64::NAN;
        let e = find_rts_pixels(nan.view(), &RtsSearch::default()).unwrap_err();
        assert!(e.to_string().contains("frame 3, row 2, column 1"), "{e}");
        let ok = Array3::<f64>::zeros((20, 4, 4));
        let bad = RtsSearch {
            threshold_sigma: -1.0,
            ..RtsSearch::default()
        };
        assert!(find_rts_pixels(ok.view(), &bad).is_err());
        // A constant stack has no RTS pixels.
        assert!(find_rts_pixels(ok.view(), &RtsSearch::default())
            .unwrap()
            .is_empty());
    }
}
