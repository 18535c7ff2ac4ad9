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

/// Half-width of the square window of [`find_image_defects`]' local median: 2, a 5 × 5
/// window whose 24 neighbours outvote a cluster of up to [`MAX_CLUSTER_PIXELS`].
pub const CLUSTER_WINDOW_RADIUS: usize = 2;

/// Largest defect cluster [`find_image_defects`] accepts, pixels: a connected group of
/// outliers with more pixels (or wider than [`MAX_CLUSTER_EXTENT_PX`]) is scene structure
/// (a thin line, a point source's blur, a clipped region), not a defect.
pub const MAX_CLUSTER_PIXELS: usize = 6;

/// Largest extent of a defect cluster along a row or column, pixels.
pub const MAX_CLUSTER_EXTENT_PX: usize = 3;

/// Defects found in a single recorded image by [`find_image_defects`].
#[derive(Debug, Clone, PartialEq)]
pub struct ImageDefects {
    /// Pixels to replace before a Fourier-domain filter: non-finite values and the
    /// dead, hot and stuck clusters.
    pub defects: BadPixelMap,
    /// Pixels at the ADC's full scale in a cluster too large to be a defect: a clipped
    /// (saturated) part of the scene. Kept, but masked out of noise estimates; the
    /// truth there is at least the recorded value.
    pub saturated: BadPixelMap,
    /// Number of defect clusters (8-connected groups of flagged pixels).
    pub clusters: usize,
    /// Pixels in the largest defect cluster.
    pub largest_cluster: usize,
    /// Robust σ of the residual from the local median (1.4826 · MAD), image units: the
    /// scale of the outlier test.
    pub residual_sigma: f64,
}

/// (min, max) of the finite non-candidate pixels within two pixels of the box of rows
/// `r0..=r1`, columns `c0..=c1` ((+∞, −∞) if there is none).
fn good_range(
    image: ArrayView2<f64>,
    candidate: &Array2<bool>,
    (r0, r1): (usize, usize),
    (c0, c1): (usize, usize),
) -> (f64, f64) {
    let (rows, cols) = image.dim();
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for i in r0.saturating_sub(2)..=(r1 + 2).min(rows - 1) {
        for j in c0.saturating_sub(2)..=(c1 + 2).min(cols - 1) {
            let v = image[[i, j]];
            if !candidate[[i, j]] && v.is_finite() {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
    }
    (lo, hi)
}

/// 8-connected components of the `true` pixels of `mask`, each as its pixel list.
fn components(mask: &Array2<bool>) -> Vec<Vec<(usize, usize)>> {
    let (rows, cols) = mask.dim();
    let mut seen = Array2::from_elem((rows, cols), false);
    let mut out = Vec::new();
    for ((r, c), &m) in mask.indexed_iter() {
        if !m || seen[[r, c]] {
            continue;
        }
        seen[[r, c]] = true;
        let mut stack = vec![(r, c)];
        let mut comp = Vec::new();
        while let Some((i, j)) = stack.pop() {
            comp.push((i, j));
            for y in i.saturating_sub(1)..=(i + 1).min(rows - 1) {
                for x in j.saturating_sub(1)..=(j + 1).min(cols - 1) {
                    if mask[[y, x]] && !seen[[y, x]] {
                        seen[[y, x]] = true;
                        stack.push((y, x));
                    }
                }
            }
        }
        out.push(comp);
    }
    out
}

/// The 8-connected clusters of flagged pixels in `map`, each as its pixel list, in
/// row-major order of each cluster's first pixel.
pub fn clusters(map: &BadPixelMap) -> Vec<Vec<(usize, usize)>> {
    components(map.mask())
}

/// Sizes (pixels) of the 8-connected clusters of flagged pixels in `map`, in row-major
/// order of each cluster's first pixel.
pub fn cluster_sizes(map: &BadPixelMap) -> Vec<usize> {
    components(map.mask()).iter().map(Vec::len).collect()
}

/// Finds dead, hot and stuck pixels — single ones and clusters (pairs, short lines, small
/// blobs) — in one recorded image, with no calibration frames:
///
/// 1. **Candidates.** Every pixel is compared with the median of its finite neighbours in
///    the 5 × 5 window ([`CLUSTER_WINDOW_RADIUS`]); the residual's robust σ over the
///    image (1.4826 · MAD, Rousseeuw & Croux 1993) sets the scale, and a pixel whose
///    residual exceeds `k_sigma` σ is a candidate. The 24-neighbour median is not moved
///    by a cluster of up to [`MAX_CLUSTER_PIXELS`] (a 3 × 3 test compares each pixel of a
///    dead pair with the other, equally dead one, and misses both), while a straight edge
///    through the window leaves its own pixels near the median. Pixels at exactly 0 or
///    at `full_scale` (dead, hot, clipped; DN images) and non-finite pixels are
///    candidates too.
/// 2. **Clusters.** Candidates are grouped 8-connected. A group of at most
///    [`MAX_CLUSTER_PIXELS`] pixels spanning at most [`MAX_CLUSTER_EXTENT_PX`] rows and
///    columns is a defect cluster if its pixels lie outside the range of the
///    non-candidate pixels around it (within two pixels of the group) by more than
///    `k_sigma` σ: each such pixel is flagged. A larger group at full scale is a clipped
///    part of the scene ([`ImageDefects::saturated`]); any other larger group is scene
///    structure and left alone, except its pixels at exactly 0 (DN images) whose good
///    neighbours within two pixels all lie more than `k_sigma` σ above: a dead pixel on a
///    sharp edge joins the edge's candidates, and is judged on its own. Non-finite pixels
///    are always flagged.
/// 3. **Iteration.** The medians are recomputed without the flagged pixels and the test
///    repeated (at most three passes) until no pixel is added, so a defect next to a
///    defect is judged against good pixels only.
///
/// What it cannot tell apart: a compact feature sharper than the optics allow (a point
/// source imaged into fewer than 3 × 3 pixels far above its surroundings) from a hot
/// cluster; a stuck pixel whose value lies within the range of its neighbours. When the
/// sensor instance's own defect map is known, use it instead.
///
/// Errors: an empty image, a non-positive `k_sigma`, or no finite pixel.
pub fn find_image_defects(
    image: ArrayView2<f64>,
    k_sigma: f64,
    full_scale: Option<f64>,
) -> Result<ImageDefects> {
    check_frame("image", image)?;
    require_positive("k_sigma", k_sigma)?;
    let (rows, cols) = image.dim();
    if !image.iter().any(|v| v.is_finite()) {
        return Err(Error::param(
            "image",
            "no finite pixel",
            "an image with finite pixel values",
        ));
    }
    let at_limit = |v: f64| full_scale.is_some_and(|f| v == 0.0 || v == f);
    let mut flagged = image.mapv(|v| !v.is_finite());
    let mut saturated = Array2::from_elem((rows, cols), false);
    let rad = CLUSTER_WINDOW_RADIUS;
    let mut residual_sigma = 0.0;
    for _pass in 0..3 {
        // Local median of the finite, unflagged neighbours.
        let medians: Vec<f64> = (0..rows)
            .into_par_iter()
            .flat_map_iter(|r| {
                let flagged = &flagged;
                let mut buf = Vec::with_capacity((2 * rad + 1).pow(2));
                (0..cols)
                    .map(move |c| {
                        buf.clear();
                        for i in r.saturating_sub(rad)..=(r + rad).min(rows - 1) {
                            for j in c.saturating_sub(rad)..=(c + rad).min(cols - 1) {
                                let v = image[[i, j]];
                                if (i, j) != (r, c) && !flagged[[i, j]] && v.is_finite() {
                                    buf.push(v);
                                }
                            }
                        }
                        median_in_place(&mut buf).unwrap_or(f64::NAN)
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        let resid: Vec<f64> = image.iter().zip(&medians).map(|(v, m)| v - m).collect();
        let mut abs: Vec<f64> = resid
            .iter()
            .zip(flagged.iter())
            .filter(|(r, f)| r.is_finite() && !**f)
            .map(|(r, _)| r.abs())
            .collect();
        let sigma = median_in_place(&mut abs).unwrap_or(0.0) * MAD_TO_SIGMA;
        // A noise-free (e.g. quantised) image has σ = 0: any departure is then an outlier.
        let scale = if sigma > 0.0 {
            sigma
        } else {
            f64::MIN_POSITIVE
        };
        residual_sigma = sigma;
        let limit = k_sigma * scale;
        let candidate = Array2::from_shape_fn((rows, cols), |(r, c)| {
            let v = image[[r, c]];
            let res = resid[r * cols + c];
            flagged[[r, c]] || !v.is_finite() || at_limit(v) || res.abs() > limit
        });
        let mut added = 0usize;
        for comp in components(&candidate) {
            let (r0, r1) = comp
                .iter()
                .fold((usize::MAX, 0), |a, p| (a.0.min(p.0), a.1.max(p.0)));
            let (c0, c1) = comp
                .iter()
                .fold((usize::MAX, 0), |a, p| (a.0.min(p.1), a.1.max(p.1)));
            let small = comp.len() <= MAX_CLUSTER_PIXELS
                && r1 - r0 < MAX_CLUSTER_EXTENT_PX
                && c1 - c0 < MAX_CLUSTER_EXTENT_PX;
            if !small {
                for &(r, c) in &comp {
                    let v = image[[r, c]];
                    if full_scale.is_some_and(|f| v == f) {
                        saturated[[r, c]] = true;
                    }
                    // A dead pixel (exactly 0 DN) on a sharp scene edge joins the edge's
                    // candidates in one large group; judged on its own, it lies below
                    // every good pixel around it by more than the limit.
                    if full_scale.is_some() && v == 0.0 && !flagged[[r, c]] {
                        let lo = good_range(image, &candidate, (r, r), (c, c)).0;
                        if !(lo.is_finite() && lo > limit) {
                            continue;
                        }
                        flagged[[r, c]] = true;
                        added += 1;
                    }
                }
                continue;
            }
            // The range of the good pixels around the group.
            let (lo, hi) = good_range(image, &candidate, (r0, r1), (c0, c1));
            for &(r, c) in &comp {
                let v = image[[r, c]];
                let bad = !v.is_finite()
                    || (lo <= hi && (v > hi + limit || v < lo - limit))
                    || flagged[[r, c]];
                if bad && !flagged[[r, c]] {
                    flagged[[r, c]] = true;
                    added += 1;
                }
            }
        }
        if added == 0 {
            break;
        }
    }
    // Pixels flagged as defects are not part of a saturated region.
    Zip::from(&mut saturated)
        .and(&flagged)
        .for_each(|s, &f| *s = *s && !f);
    let groups = components(&flagged);
    let largest_cluster = groups.iter().map(Vec::len).max().unwrap_or(0);
    Ok(ImageDefects {
        defects: BadPixelMap::from_mask(flagged),
        saturated: BadPixelMap::from_mask(saturated),
        clusters: groups.len(),
        largest_cluster,
        residual_sigma,
    })
}
