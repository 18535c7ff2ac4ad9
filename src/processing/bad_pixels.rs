//! Bad-pixel detection and replacement.
//!
//! A pixel is judged against its family, the whole array, with robust statistics: the
//! median and the median absolute deviation (MAD), scaled by 1.4826 so that it estimates
//! σ for Gaussian data (Rousseeuw & Croux, JASA 88, 1273 (1993)). From a calibration
//! response — the per-pixel average of a dark (or cold) flat field and of a bright (or
//! warm) one — [`detect`] forms the pixel's offset `o = dark` and response
//! `g = bright − dark` and classifies it ([`DefectKind`]):
//!
//! 1. **non-finite**: NaN or ±∞ in either level;
//! 2. **dead**: no response, `|g| < dead_response_fraction · |median g|`, at a low level;
//! 3. **stuck** (hot and saturated, or stuck high): no response as above, with the mean
//!    level `(dark + bright)/2` above the mid-point of the array's median dark and bright
//!    levels;
//! 4. **gain outlier**: `|g − median g| > k · σ_MAD(g)`;
//! 5. **hot** / **cold**: offset `o − median o` above `+k · σ_MAD(o)` / below `−k · σ_MAD(o)`.
//!
//! [`flag_outliers`] applies the same median/MAD test to any other per-pixel statistic
//! (a temporal-noise map finds blinking pixels) and [`BadPixelMap::union`] combines maps.
//! [`replace`] substitutes each flagged pixel by the median of its valid 3×3 neighbours,
//! growing the window to 5×5, 7×7 … until a valid neighbour exists.

use ndarray::{Array2, ArrayView2, Zip};
use rayon::prelude::*;

use super::{check_frame, check_shape, median_in_place};
use crate::error::{require_non_negative, require_positive, Error, Result};

/// Scale factor turning a median absolute deviation into a Gaussian σ estimate, 1/Φ⁻¹(3/4).
pub const MAD_TO_SIGMA: f64 = 1.482_602_218_505_602;

/// A map of defective pixels: `true` where the pixel is bad.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BadPixelMap {
    mask: Array2<bool>,
}

impl BadPixelMap {
    /// A map with no bad pixels for a `rows × cols` frame.
    pub fn new(rows: usize, cols: usize) -> Self {
        BadPixelMap {
            mask: Array2::from_elem((rows, cols), false),
        }
    }

    /// Wraps a boolean mask (`true` = bad).
    pub fn from_mask(mask: Array2<bool>) -> Self {
        BadPixelMap { mask }
    }

    /// The boolean mask (`true` = bad), `[row, col]`.
    pub fn mask(&self) -> &Array2<bool> {
        &self.mask
    }

    /// The frame shape `(rows, cols)`.
    pub fn dim(&self) -> (usize, usize) {
        self.mask.dim()
    }

    /// Whether pixel `(row, col)` is flagged (false outside the frame).
    pub fn is_bad(&self, row: usize, col: usize) -> bool {
        self.mask.get((row, col)).copied().unwrap_or(false)
    }

    /// Flags (or clears) pixel `(row, col)`.
    ///
    /// Errors: a position outside the frame.
    pub fn set(&mut self, row: usize, col: usize, bad: bool) -> Result<()> {
        let (r, c) = self.mask.dim();
        match self.mask.get_mut((row, col)) {
            Some(v) => {
                *v = bad;
                Ok(())
            }
            None => Err(Error::param(
                "bad pixel position",
                format!("({row}, {col})"),
                format!("a (row, col) inside the {r}×{c} frame"),
            )),
        }
    }

    /// Number of flagged pixels.
    pub fn count(&self) -> usize {
        self.mask.iter().filter(|&&b| b).count()
    }

    /// Positions `(row, col)` of the flagged pixels, in row-major order.
    pub fn positions(&self) -> Vec<(usize, usize)> {
        self.mask
            .indexed_iter()
            .filter(|(_, &b)| b)
            .map(|(p, _)| p)
            .collect()
    }

    /// The union of two maps of the same shape (a pixel bad in either is bad).
    ///
    /// Errors: different shapes.
    pub fn union(&self, other: &BadPixelMap) -> Result<BadPixelMap> {
        check_shape("other bad-pixel map", other.dim(), self.dim())?;
        Ok(BadPixelMap {
            mask: Zip::from(&self.mask)
                .and(&other.mask)
                .map_collect(|&a, &b| a || b),
        })
    }
}

/// Why a pixel was flagged by [`detect`] (the first matching test, in this order).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DefectKind {
    /// NaN or infinite output in a calibration level.
    NonFinite,
    /// No response, low level.
    Dead,
    /// No response at a high level (hot and saturated, or stuck high).
    Stuck,
    /// Response (gain) out of family.
    GainOutlier,
    /// Offset out of family, high.
    Hot,
    /// Offset out of family, low.
    Cold,
}

/// Thresholds of [`detect`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BadPixelCriteria {
    /// Out-of-family threshold k, in robust σ (1.4826 · MAD). Default 6.
    pub k_sigma: f64,
    /// A pixel whose response is below this fraction of the median response has "no
    /// response" (dead or stuck). Default 0.2.
    pub dead_response_fraction: f64,
    /// Lower bound on the robust σ used in the outlier tests, in the frame's units (so
    /// that a perfectly uniform, e.g. heavily quantised, array does not flag every pixel
    /// that differs by one count). Default 0.
    pub min_sigma: f64,
}

impl Default for BadPixelCriteria {
    fn default() -> Self {
        BadPixelCriteria {
            k_sigma: 6.0,
            dead_response_fraction: 0.2,
            min_sigma: 0.0,
        }
    }
}

impl BadPixelCriteria {
    /// Checks every threshold.
    pub fn validate(&self) -> Result<()> {
        require_positive("k_sigma", self.k_sigma)?;
        require_non_negative("dead_response_fraction", self.dead_response_fraction)?;
        require_non_negative("min_sigma", self.min_sigma)?;
        Ok(())
    }
}

/// The result of [`detect`]: the map, each flagged pixel's reason, and the family
/// statistics the tests used.
#[derive(Debug, Clone, PartialEq)]
pub struct BadPixelDetection {
    /// All flagged pixels.
    pub map: BadPixelMap,
    /// The reason per pixel (`None` for good pixels).
    pub kind: Array2<Option<DefectKind>>,
    /// Median response `bright − dark` over finite pixels.
    pub median_response: f64,
    /// Robust σ (1.4826 · MAD, at least `min_sigma`) of the response.
    pub sigma_response: f64,
    /// Median offset (dark level) over finite pixels.
    pub median_offset: f64,
    /// Robust σ of the offset.
    pub sigma_offset: f64,
}

impl BadPixelDetection {
    /// Number of pixels flagged for `kind`.
    pub fn count(&self, kind: DefectKind) -> usize {
        self.kind.iter().filter(|k| **k == Some(kind)).count()
    }
}

/// Median and robust σ (1.4826 · MAD) of the finite values of `values`; `None` if none
/// is finite.
pub fn median_and_robust_sigma(values: ArrayView2<f64>) -> Option<(f64, f64)> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    let med = median_in_place(&mut v)?;
    for x in v.iter_mut() {
        *x = (*x - med).abs();
    }
    let mad = median_in_place(&mut v)?;
    Some((med, MAD_TO_SIGMA * mad))
}

/// Flags the pixels of a per-pixel statistic (offset, response, temporal σ …) that lie
/// more than `k_sigma` robust σ (1.4826 · MAD, at least `min_sigma`) from the median, and
/// every non-finite value.
///
/// Errors: an empty frame, non-positive `k_sigma`, negative `min_sigma`, or no finite value.
pub fn flag_outliers(values: ArrayView2<f64>, k_sigma: f64, min_sigma: f64) -> Result<BadPixelMap> {
    check_frame("values", values)?;
    require_positive("k_sigma", k_sigma)?;
    require_non_negative("min_sigma", min_sigma)?;
    let (med, sigma) = median_and_robust_sigma(values).ok_or_else(|| {
        Error::param(
            "values",
            "no finite pixel",
            "at least one finite pixel value",
        )
    })?;
    let limit = k_sigma * sigma.max(min_sigma);
    Ok(BadPixelMap::from_mask(
        values.mapv(|x| !x.is_finite() || (x - med).abs() > limit),
    ))
}

/// Finds defective pixels from a calibration response: `dark` and `bright` are per-pixel
/// averages of flat fields at a low and a high level (see the module documentation for
/// the tests and their order).
///
/// Errors: empty or differently shaped frames, invalid criteria, no finite pixel, or a
/// median response of zero (the two levels do not differ, so "no response" is undefined).
pub fn detect(
    dark: ArrayView2<f64>,
    bright: ArrayView2<f64>,
    criteria: &BadPixelCriteria,
) -> Result<BadPixelDetection> {
    check_frame("dark", dark)?;
    check_shape("bright", bright.dim(), dark.dim())?;
    criteria.validate()?;
    let response = &bright - &dark;
    // The three family statistics are independent: computed side by side.
    let ((response_stats, dark_stats), bright_median) = rayon::join(
        || {
            rayon::join(
                || median_and_robust_sigma(response.view()),
                || median_and_robust_sigma(dark),
            )
        },
        || {
            let mut v: Vec<f64> = bright.iter().copied().filter(|x| x.is_finite()).collect();
            median_in_place(&mut v)
        },
    );
    let (median_response, sigma_g) = response_stats.ok_or_else(|| {
        Error::param(
            "dark/bright",
            "no finite pixel",
            "at least one finite pixel in both levels",
        )
    })?;
    if median_response == 0.0 {
        return Err(Error::param(
            "bright",
            "median response 0",
            "a bright level that differs from the dark level (median bright − dark ≠ 0)",
        ));
    }
    let (median_offset, sigma_o) = dark_stats
        .ok_or_else(|| Error::param("dark", "no finite pixel", "at least one finite pixel"))?;
    let median_bright = bright_median.unwrap_or(median_offset);
    let sigma_response = sigma_g.max(criteria.min_sigma);
    let sigma_offset = sigma_o.max(criteria.min_sigma);
    let k = criteria.k_sigma;
    let no_response = criteria.dead_response_fraction * median_response.abs();
    let mid_level = 0.5 * (median_offset + median_bright);
    let high_is_up = median_response > 0.0;

    let kind = Zip::from(&dark)
        .and(&bright)
        .and(&response)
        .map_collect(|&d, &b, &g| {
            if !(d.is_finite() && b.is_finite()) {
                Some(DefectKind::NonFinite)
            } else if g.abs() < no_response {
                let level = 0.5 * (d + b);
                let high = if high_is_up {
                    level > mid_level
                } else {
                    level < mid_level
                };
                Some(if high {
                    DefectKind::Stuck
                } else {
                    DefectKind::Dead
                })
            } else if (g - median_response).abs() > k * sigma_response {
                Some(DefectKind::GainOutlier)
            } else if d - median_offset > k * sigma_offset {
                Some(DefectKind::Hot)
            } else if median_offset - d > k * sigma_offset {
                Some(DefectKind::Cold)
            } else {
                None
            }
        });
    let map = BadPixelMap::from_mask(kind.mapv(|k| k.is_some()));
    Ok(BadPixelDetection {
        map,
        kind,
        median_response,
        sigma_response,
        median_offset,
        sigma_offset,
    })
}

/// Replaces every flagged pixel by the median of the valid (unflagged, finite) pixels in
/// the 3×3 window around it; if there is none, the window grows to 5×5, 7×7 … Unflagged
/// pixels are copied unchanged (even if non-finite: flag them to have them replaced).
///
/// Errors: a map of another shape, or a flagged pixel with no valid pixel anywhere in
/// the frame.
pub fn replace(frame: ArrayView2<f64>, map: &BadPixelMap) -> Result<Array2<f64>> {
    check_frame("frame", frame)?;
    check_shape("bad-pixel map", map.dim(), frame.dim())?;
    let (rows, cols) = frame.dim();
    let mask = map.mask();
    let bad = map.positions();
    let max_radius = rows.max(cols);
    let replacements: Vec<Option<f64>> = bad
        .par_iter()
        .map(|&(r, c)| {
            let mut buf = Vec::with_capacity(24);
            for radius in 1..=max_radius {
                buf.clear();
                let (r0, r1) = (r.saturating_sub(radius), (r + radius).min(rows - 1));
                let (c0, c1) = (c.saturating_sub(radius), (c + radius).min(cols - 1));
                for i in r0..=r1 {
                    for j in c0..=c1 {
                        let v = frame[[i, j]];
                        if !mask[[i, j]] && v.is_finite() {
                            buf.push(v);
                        }
                    }
                }
                if let Some(m) = median_in_place(&mut buf) {
                    return Some(m);
                }
            }
            None
        })
        .collect();
    let mut out = frame.to_owned();
    for (&(r, c), v) in bad.iter().zip(&replacements) {
        match v {
            Some(v) => out[[r, c]] = *v,
            None => {
                return Err(Error::param(
                    "bad-pixel map",
                    format!("{} of {} pixels flagged", bad.len(), rows * cols),
                    "at least one valid (unflagged, finite) pixel to replace defects from",
                ))
            }
        }
    }
    Ok(out)
}
