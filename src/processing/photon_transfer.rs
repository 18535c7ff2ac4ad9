//! Photon-transfer characterisation after EMVA Standard 1288 (Release 3.1, 2016, the linear
//! camera model and its measurement methods; Release 4.0 keeps these equations),
//! docs/design.md §4.10.
//!
//! Input: a pair of dark frames, a pair of frames (A, B) at each of several uniform
//! illumination levels (EMVA asks for ≥ 50 levels; 20 do well), optionally the mean
//! number of photons per pixel μ_p at each level, and optionally stacks of frames for the
//! spatial (fixed-pattern) statistics. With N pixels per frame, y the signal in DN:
//!
//! - **Mean** of a pair: `μ_y = (⟨y_A⟩ + ⟨y_B⟩)/2`.
//! - **Temporal variance** from the difference, which cancels all fixed-pattern noise:
//!   `σ_y² = 1/(2N) Σ ((y_A − y_B) − (⟨y_A⟩ − ⟨y_B⟩))²` (with the mean difference
//!   removed as in Release 4.0 so a small illumination drift between A and B cancels).
//! - **Photon transfer** (linear sensor, Poisson electrons):
//!   `σ_y² − σ_y.dark² = K (μ_y − μ_y.dark)`: the conversion gain K (DN/e⁻) is the slope
//!   of a least-squares line through the levels from dark up to `fit_fraction` (EMVA: 70 %)
//!   of the saturation net signal. The line's intercept is reported too (≈ 0 for an ideal
//!   sensor).
//! - **Dark (read) noise**: `σ_y.dark² = K² σ_d² + σ_q²`, so
//!   `σ_d = √(σ_y.dark² − σ_q²) / K` electrons, `σ_q² = q²/12` for a quantisation step q
//!   DN (0 when the frames are not quantised).
//! - **Sensitivity**: `μ_y − μ_y.dark = K η μ_p`; the responsivity R = Kη is the
//!   slope of the net mean against μ_p over the same fit range, and `η = R / K`.
//! - **Saturation**: the level of maximum temporal variance (the saturation point is the
//!   maximum of the photon transfer curve); saturation capacity
//!   `μ_e.sat = (μ_y.sat − μ_y.dark) / K` electrons (= η μ_p.sat for a linear sensor).
//!   If the brightest level is still below saturation, the variance keeps rising and the
//!   brightest level is reported: the saturation capacity is then only a lower bound.
//!   `fit_fraction = 1` fits all the way up to the variance maximum.
//! - **Spatial non-uniformity**: from a stack of L frames averaged per pixel, the
//!   spatial variance over pixels minus the temporal variance that survives the averaging,
//!   `s_y² = var_pixels(⟨y⟩_L) − σ_y²/L`, at dark and at a bright level
//!   (EMVA: 50 % saturation). `DSNU₁₂₈₈ = s_y.dark / K` electrons,
//!   `PRNU₁₂₈₈ = √(s_y.bright² − s_y.dark²) / (μ_y.bright − μ_y.dark)` (as a fraction). Without stacks, the dark pair and the pair nearest 50 % saturation serve
//!   as two-frame stacks.

use ndarray::{Array2, Array3, ArrayView2, ArrayView3, Axis};

use super::{check_frame, check_shape, check_stack, fit_line, mean_variance};
use crate::error::{require_in_range, require_non_negative, Error, Result};

/// Two frames taken under identical conditions.
#[derive(Debug, Clone, Copy)]
pub struct FramePair<'a> {
    /// First frame `[row, col]`, DN.
    pub a: ArrayView2<'a, f64>,
    /// Second frame, same shape.
    pub b: ArrayView2<'a, f64>,
}

/// One illumination level of the photon-transfer measurement.
#[derive(Debug, Clone, Copy)]
pub struct PtcLevel<'a> {
    /// The frame pair at this level.
    pub pair: FramePair<'a>,
    /// Mean number of photons reaching a pixel during the exposure, μ_p (if known).
    pub photons_per_pixel: Option<f64>,
}

/// Frame stacks `[frame, row, col]` (L ≥ 2 frames each) for the spatial statistics.
#[derive(Debug, Clone, Copy)]
pub struct FpnStacks<'a> {
    /// Dark frames.
    pub dark: ArrayView3<'a, f64>,
    /// Frames at a uniform bright level (EMVA: about 50 % of saturation).
    pub bright: ArrayView3<'a, f64>,
}

/// Options of [`photon_transfer`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PtcOptions {
    /// Upper end of the fit range as a fraction of the saturation net signal
    /// (EMVA 1288: 0.7). Must lie in (0, 1].
    pub fit_fraction: f64,
    /// Quantisation step q of the frames, DN (1 for raw integer DN, 0 for unquantised
    /// data); its variance q²/12 is removed from the dark noise.
    pub quantisation_step_dn: f64,
}

impl Default for PtcOptions {
    fn default() -> Self {
        PtcOptions {
            fit_fraction: 0.7,
            quantisation_step_dn: 0.0,
        }
    }
}

/// Statistics of one illumination level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LevelStatistics {
    /// Mean signal μ_y, DN.
    pub mean_dn: f64,
    /// Temporal variance σ_y², DN².
    pub temporal_variance_dn2: f64,
    /// Mean photons per pixel μ_p, if given.
    pub photons_per_pixel: Option<f64>,
    /// Whether the level lies in the fit range.
    pub in_fit: bool,
}

/// Results of [`photon_transfer`] (EMVA 1288 quantities; equations in the module
/// documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct PhotonTransfer {
    /// Per-level statistics, in input order.
    pub levels: Vec<LevelStatistics>,
    /// Mean dark signal μ_y.dark, DN.
    pub dark_mean_dn: f64,
    /// Dark temporal variance σ_y.dark², DN².
    pub dark_variance_dn2: f64,
    /// Conversion gain K, DN per electron.
    pub conversion_gain_dn_per_e: f64,
    /// Intercept of the photon-transfer line (net variance at zero net signal), DN².
    pub ptc_intercept_dn2: f64,
    /// Dark temporal noise σ_y.dark, DN (including quantisation).
    pub read_noise_dn: f64,
    /// Dark temporal noise σ_d referred to the input, electrons (quantisation removed).
    pub read_noise_e: f64,
    /// Responsivity R = Kη, DN per photon, if photons were given.
    pub responsivity_dn_per_photon: Option<f64>,
    /// Quantum efficiency η, if photons were given.
    pub quantum_efficiency: Option<f64>,
    /// Index (input order) of the level of maximum temporal variance.
    pub saturation_level: usize,
    /// Mean signal at saturation μ_y.sat, DN.
    pub saturation_mean_dn: f64,
    /// Saturation capacity μ_e.sat, electrons.
    pub saturation_capacity_e: f64,
    /// Number of levels in the fit range.
    pub fit_levels: usize,
    /// Dark signal non-uniformity s_y.dark, DN.
    pub dsnu_dn: f64,
    /// DSNU₁₂₈₈ = s_y.dark / K, electrons.
    pub dsnu_e: f64,
    /// PRNU₁₂₈₈, as a fraction of the net signal (0.01 = 1 %).
    pub prnu: f64,
}

/// Mean μ_y and temporal variance σ_y² of a frame pair (EMVA 1288, mean difference
/// removed), over all pixels.
///
/// Errors: empty or differently shaped frames, or non-finite values.
pub fn pair_statistics(pair: &FramePair) -> Result<(f64, f64)> {
    check_frame("pair.a", pair.a)?;
    check_shape("pair.b", pair.b.dim(), pair.a.dim())?;
    let n = pair.a.len() as f64;
    let mean_a = pair.a.sum() / n;
    let mean_b = pair.b.sum() / n;
    let dm = mean_a - mean_b;
    let ss: f64 = pair
        .a
        .iter()
        .zip(pair.b.iter())
        .map(|(&a, &b)| {
            let d = a - b - dm;
            d * d
        })
        .sum();
    let mean = 0.5 * (mean_a + mean_b);
    let var = ss / (2.0 * n);
    if !(mean.is_finite() && var.is_finite()) {
        return Err(Error::param(
            "frame pair",
            "non-finite pixel values",
            "frames with finite values (replace or crop bad pixels first)",
        ));
    }
    Ok((mean, var))
}

/// Spatial statistics of a stack `[frame, row, col]`: the mean over all pixels and
/// frames, and the EMVA 1288 spatial variance of the averaged image with the temporal
/// residue removed, `s² = var_pixels(⟨y⟩) − σ_temporal²/L` (σ_temporal² = mean over pixels
/// of the per-pixel (L − 1)-normalised variance). Returns `(mean, s²)`.
///
/// Errors: fewer than 2 frames or 2 pixels, or non-finite values.
pub fn spatial_statistics(stack: ArrayView3<f64>) -> Result<(f64, f64)> {
    check_stack("stack", stack)?;
    let l = stack.len_of(Axis(0));
    if l < 2 {
        return Err(Error::param(
            "stack",
            format!("{l} frame"),
            "at least 2 frames (to separate temporal from spatial variance)",
        ));
    }
    let mean_img: Array2<f64> = stack
        .mean_axis(Axis(0))
        .ok_or_else(|| Error::param("stack", "0 frames", "at least 2 frames"))?;
    let mut temporal = 0.0;
    for frame in stack.outer_iter() {
        temporal += frame
            .iter()
            .zip(mean_img.iter())
            .map(|(&y, &m)| (y - m) * (y - m))
            .sum::<f64>();
    }
    let npix = mean_img.len() as f64;
    let temporal_var = temporal / ((l - 1) as f64 * npix);
    let (mean, spatial) = mean_variance(mean_img.iter().copied())
        .ok_or_else(|| Error::param("stack", "1 pixel", "frames of at least 2 pixels"))?;
    let s2 = spatial - temporal_var / l as f64;
    if !(mean.is_finite() && s2.is_finite()) {
        return Err(Error::param(
            "stack",
            "non-finite pixel values",
            "frames with finite values",
        ));
    }
    Ok((mean, s2))
}

/// EMVA 1288 photon-transfer analysis (equations in the module documentation).
///
/// `levels` are the illuminated pairs in any order (typically increasing exposure);
/// either all or none carry `photons_per_pixel`. `stacks` (optional) give DSNU/PRNU
/// from averaged stacks; otherwise the pairs are used.
///
/// Errors: fewer than 2 levels, frames of different shapes, non-finite data, photons
/// given for some levels only or not finite and > 0, fewer than 2 levels in the fit range
/// (the variance maximum comes too early: add levels below saturation), or a
/// non-positive K.
pub fn photon_transfer(
    dark: FramePair,
    levels: &[PtcLevel],
    stacks: Option<&FpnStacks>,
    options: &PtcOptions,
) -> Result<PhotonTransfer> {
    require_in_range("fit_fraction", options.fit_fraction, f64::MIN_POSITIVE, 1.0)?;
    require_non_negative("quantisation_step_dn", options.quantisation_step_dn)?;
    if levels.len() < 2 {
        return Err(Error::param(
            "levels",
            format!("{} illumination levels", levels.len()),
            "at least 2 illuminated frame pairs (EMVA 1288 recommends 50)",
        ));
    }
    let shape = dark.a.dim();
    let (dark_mean, dark_var) = pair_statistics(&dark)?;
    let with_photons = levels
        .iter()
        .filter(|l| l.photons_per_pixel.is_some())
        .count();
    if with_photons != 0 && with_photons != levels.len() {
        return Err(Error::param(
            "photons_per_pixel",
            format!("given for {with_photons} of {} levels", levels.len()),
            "photons for every level or for none",
        ));
    }
    let mut stats = Vec::with_capacity(levels.len());
    for (i, level) in levels.iter().enumerate() {
        check_shape(&format!("levels[{i}].a"), level.pair.a.dim(), shape)?;
        let (mean, var) = pair_statistics(&level.pair)?;
        if let Some(p) = level.photons_per_pixel {
            if !(p.is_finite() && p >= 0.0) {
                return Err(Error::param(
                    format!("levels[{i}].photons_per_pixel"),
                    p,
                    "a finite number of photons >= 0",
                ));
            }
        }
        stats.push(LevelStatistics {
            mean_dn: mean,
            temporal_variance_dn2: var,
            photons_per_pixel: level.photons_per_pixel,
            in_fit: false,
        });
    }

    // Saturation: the maximum of the photon transfer curve.
    let saturation_level = stats
        .iter()
        .enumerate()
        .max_by(|a, b| {
            a.1.temporal_variance_dn2
                .total_cmp(&b.1.temporal_variance_dn2)
        })
        .map_or(0, |(i, _)| i);
    let saturation_mean_dn = stats[saturation_level].mean_dn;
    let sat_net = saturation_mean_dn - dark_mean;
    let fit_limit = options.fit_fraction * sat_net;
    for s in stats.iter_mut() {
        let net = s.mean_dn - dark_mean;
        s.in_fit = sat_net > 0.0 && net > 0.0 && net <= fit_limit;
    }
    let ptc: Vec<(f64, f64)> = stats
        .iter()
        .filter(|s| s.in_fit)
        .map(|s| (s.mean_dn - dark_mean, s.temporal_variance_dn2 - dark_var))
        .collect();
    let fit_levels = ptc.len();
    let too_few = || {
        Error::OutOfRange(format!(
            "photon transfer: only {fit_levels} level(s) lie between dark and {:.0} % of the saturation signal ({sat_net} DN above dark, at level {saturation_level}); at least 2 are needed — add levels below saturation",
            100.0 * options.fit_fraction
        ))
    };
    let (k, intercept) = fit_line(&ptc).ok_or_else(too_few)?;
    if !(k > 0.0 && k.is_finite()) {
        return Err(Error::OutOfRange(format!(
            "photon transfer: the variance does not grow with the signal (slope K = {k} DN/e-); check the illumination levels and the dark pair"
        )));
    }

    let (responsivity, qe) = if with_photons > 0 {
        let sens: Vec<(f64, f64)> = stats
            .iter()
            .filter(|s| s.in_fit)
            .filter_map(|s| s.photons_per_pixel.map(|p| (p, s.mean_dn - dark_mean)))
            .collect();
        let (r, _) = fit_line(&sens).ok_or_else(|| {
            Error::OutOfRange(
                "photon transfer: the photon counts of the fit levels do not differ, so η cannot be fitted".to_string(),
            )
        })?;
        (Some(r), Some(r / k))
    } else {
        (None, None)
    };

    let q2 = options.quantisation_step_dn * options.quantisation_step_dn / 12.0;
    let read_noise_dn = dark_var.sqrt();
    let read_noise_e = (dark_var - q2).max(0.0).sqrt() / k;
    let saturation_capacity_e = sat_net / k;

    // Spatial non-uniformity.
    let ((dark_s_mean, dark_s2), (bright_s_mean, bright_s2)) = match stacks {
        Some(st) => {
            check_shape(
                "stacks.dark",
                (st.dark.len_of(Axis(1)), st.dark.len_of(Axis(2))),
                shape,
            )?;
            check_shape(
                "stacks.bright",
                (st.bright.len_of(Axis(1)), st.bright.len_of(Axis(2))),
                shape,
            )?;
            (spatial_statistics(st.dark)?, spatial_statistics(st.bright)?)
        }
        None => {
            let half = dark_mean + 0.5 * sat_net;
            let nearest = (0..levels.len())
                .min_by(|&a, &b| {
                    (stats[a].mean_dn - half)
                        .abs()
                        .total_cmp(&(stats[b].mean_dn - half).abs())
                })
                .unwrap_or(0);
            (
                spatial_statistics(pair_stack(&dark).view())?,
                spatial_statistics(pair_stack(&levels[nearest].pair).view())?,
            )
        }
    };
    let dsnu_dn = dark_s2.max(0.0).sqrt();
    let net_bright = bright_s_mean - dark_s_mean;
    let prnu = if net_bright != 0.0 {
        (bright_s2 - dark_s2).max(0.0).sqrt() / net_bright.abs()
    } else {
        f64::NAN
    };

    Ok(PhotonTransfer {
        levels: stats,
        dark_mean_dn: dark_mean,
        dark_variance_dn2: dark_var,
        conversion_gain_dn_per_e: k,
        ptc_intercept_dn2: intercept,
        read_noise_dn,
        read_noise_e,
        responsivity_dn_per_photon: responsivity,
        quantum_efficiency: qe,
        saturation_level,
        saturation_mean_dn,
        saturation_capacity_e,
        fit_levels,
        dsnu_dn,
        dsnu_e: dsnu_dn / k,
        prnu,
    })
}

/// A two-frame stack `[2, row, col]` from a pair.
fn pair_stack(pair: &FramePair) -> Array3<f64> {
    let (r, c) = pair.a.dim();
    let mut s = Array3::zeros((2, r, c));
    s.index_axis_mut(Axis(0), 0).assign(&pair.a);
    s.index_axis_mut(Axis(0), 1).assign(&pair.b);
    s
}
