//! EMVA 1288 (Release 4.0 Linear) analysis of an acquisition set described by a
//! [`Descriptor`].
//!
//! With y the pixel value (DN), per series of the set:
//!
//! - **Temporal pairs** (two frames A, B): `μ_y = (⟨y_A⟩ + ⟨y_B⟩)/2` and
//!   `σ_y² = ⟨((y_A − y_B) − (⟨y_A⟩ − ⟨y_B⟩))²⟩/2`
//!   ([`pair_statistics`]); each bright pair is dark-corrected with the dark pair at
//!   *its own* exposure time (so sets that vary the exposure time work too).
//! - **Saturation**: the bright pair of maximum σ_y²; `μ_e.sat = (μ_y.sat − μ_y.dark)/K`.
//! - **System gain K** (DN/e⁻): least-squares slope of `σ_y² − σ_y.dark²` against
//!   `μ_y − μ_y.dark` over the pairs from dark up to 70 % of the saturation net signal.
//! - **Responsivity** `R = Kη`: slope of `μ_y − μ_y.dark` against the photons μ_p over the
//!   same range; quantum efficiency `η = R/K`.
//! - **Temporal dark noise** `σ_y.dark² ← max(σ_y.dark², 0.24 DN²)` (Release 4.0: below
//!   0.24 DN² the dark noise is quantisation-dominated and the limit is used instead; the
//!   measured value is kept as `sigma_y_dark_measured_DN`), then
//!   `σ_d = √(σ_y.dark² − σ_q²)/K`, `σ_q² = 1/12 DN²` (integer data), from the dark pair at
//!   the photon-transfer exposure time.
//! - **SNR** per pair `(μ_y − μ_y.dark)/σ_y`, and the model curve
//!   `SNR(μ_p) = ημ_p/√(σ_d² + σ_q²/K² + ημ_p)` (`= μ_e/√(σ_y.dark²/K² + μ_e)`);
//!   `SNR_max = √μ_e.sat`.
//! - **Absolute sensitivity threshold** (Release 4.0): `μ_e.min = σ_y.dark/K + ½`
//!   electrons (with the floored σ_y.dark), `μ_p.min = μ_e.min/η`; **dynamic range**
//!   `DR = μ_e.sat/μ_e.min` (also in dB, 20 log₁₀). These are the formulas of the
//!   `emva1288` reference package (`Results1288.u_e_min`, `.DR`).
//! - **Uncertainties**: the standard uncertainty of every figure, propagated from the
//!   fits' and the pair statistics' own (`super::uncertainty`).
//! - **Clipped darks**: a warning when dark frames have pixels at 0 DN or at the ADC
//!   maximum (the ADC clips them and the dark statistics are biased).
//! - **Linearity error**: a line fitted to `μ_y − μ_y.dark` against μ_p (or the exposure
//!   time when no photon counts are given and it varies) between 5 % and 95 % of the
//!   saturation net signal; `LE = (max δ − min δ)/2` with `δ` the relative deviation from
//!   the line, in percent.
//! - **Dark current** from the dark pairs at two or more exposure times: slope of `μ_y.dark`
//!   against t divided by K (e⁻/s), and from the variance, slope of `σ_y.dark²` against t
//!   divided by K² (the two agree when the dark signal is Poisson). The dark pairs come
//!   from the descriptor and, when it exists, from `dark_current.txt` beside it (the same
//!   format, dark series only): the reference package reads a descriptor only when every
//!   exposure time has bright images too, so a set keeps its dark-current series apart.
//! - **Spatial stacks** (more than two frames) of L frames: per-pixel averages, spatial
//!   variance with the surviving temporal part removed, `s² = var(⟨y⟩_L) − σ_y²/L`
//!   ([`spatial_statistics`]). `DSNU₁₂₈₈ = s_y.dark/K` electrons,
//!   `PRNU₁₂₈₈ = √(s_y.50² − s_y.dark²)/(μ_y.50 − μ_y.dark)` in percent. Without stacks the
//!   dark pair and the pair nearest 50 % of saturation serve as two-frame stacks.
//! - **Defective pixels**: a pixel whose value is identical in every frame of the dark and
//!   bright spatial stacks, and the same in both, neither responds to light nor shows
//!   temporal noise (dead, hot or stuck); such pixels are excluded from every statistic
//!   and counted. (A working pixel with temporal noise of a few DN cannot repeat one value
//!   over 2L frames.)
//!
//! The equations follow EMVA Standard 1288, Release 4.0 Linear (2021), §§ 6–8, which
//! keep those of Release 3.1.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use ndarray::{Array2, Array3, ArrayView2, ArrayView3};
use serde::{Deserialize, Serialize};

use super::descriptor::{image_path, Descriptor, Series};
use crate::error::{Error, Result};
use crate::io::raster;
use crate::processing::fit_line;
use crate::processing::photon_transfer::{pair_statistics, spatial_statistics, FramePair};

use super::uncertainty::{figures, propagate, slope_standard_error, Measured};

/// Upper end of the K and R fit range, fraction of the saturation net signal.
pub const FIT_FRACTION: f64 = 0.7;
pub use super::uncertainty::{QUANTISATION_LIMIT_DN2, QUANTISATION_VARIANCE_DN2};

/// The file beside a descriptor that holds the dark-current series (dark pairs at several
/// exposure times), if the set has one.
pub const DARK_CURRENT_FILE: &str = "dark_current.txt";

/// Statistics of one temporal pair.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PairLevel {
    /// Exposure time, ns.
    pub exposure_ns: f64,
    /// Mean photons per pixel (bright pairs with known photons).
    pub photons_per_pixel: Option<f64>,
    /// Mean signal μ_y, DN.
    pub mean_dn: f64,
    /// Temporal variance σ_y², DN².
    pub variance_dn2: f64,
    /// Net signal μ_y − μ_y.dark, DN (0 for dark pairs).
    pub net_mean_dn: f64,
    /// Net variance σ_y² − σ_y.dark², DN² (0 for dark pairs).
    pub net_variance_dn2: f64,
    /// SNR = net signal / σ_y (bright pairs).
    pub snr: f64,
    /// Whether the pair lies in the K / R fit range.
    pub in_fit: bool,
}

/// Results of [`characterize`]; the field names are those of `characterization.json`.
#[allow(non_snake_case)]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Characterization {
    /// Image width × height, pixels.
    pub image_size: [usize; 2],
    /// Bits per pixel (from the descriptor).
    pub bits: u32,
    /// Pixels used (all minus defective).
    pub pixels_used: usize,
    /// Defective (constant) pixels excluded.
    pub defective_pixels: usize,
    /// System gain K, DN per electron.
    pub K_DN_per_e: f64,
    /// Intercept of the photon-transfer line, DN².
    pub ptc_intercept_DN2: f64,
    /// Quantum efficiency η in percent (when photon counts are given).
    pub QE_percent: Option<f64>,
    /// Responsivity R = Kη, DN per photon (when photon counts are given).
    pub responsivity_DN_per_photon: Option<f64>,
    /// Temporal dark noise σ_d, electrons.
    pub sigma_d_e: f64,
    /// Temporal dark noise σ_y.dark, DN (quantisation included; at least √0.24 DN, the
    /// Release 4.0 limit).
    pub sigma_y_dark_DN: f64,
    /// σ_y.dark as measured, before the 0.24 DN² limit, DN.
    pub sigma_y_dark_measured_DN: f64,
    /// Whether σ_y.dark² < 0.24 DN² (σ_d is then an upper limit).
    pub sigma_d_quantisation_limited: bool,
    /// DSNU₁₂₈₈, electrons.
    pub DSNU1288_e: f64,
    /// DSNU₁₂₈₈, DN.
    pub DSNU1288_DN: f64,
    /// PRNU₁₂₈₈, percent.
    pub PRNU1288_percent: f64,
    /// Saturation capacity μ_e.sat (at the variance maximum), electrons.
    pub u_e_sat_e: f64,
    /// Saturation net signal μ_y.sat − μ_y.dark, DN.
    pub u_y_sat_DN: f64,
    /// Photons at saturation (when given).
    pub u_p_sat: Option<f64>,
    /// Whether the variance maximum is the brightest pair (saturation then only a lower
    /// bound).
    pub saturation_at_brightest_level: bool,
    /// Absolute sensitivity threshold μ_e.min (SNR = 1), electrons.
    pub u_e_min_e: f64,
    /// Absolute sensitivity threshold in photons (when η is known).
    pub u_p_min: Option<f64>,
    /// Maximum SNR √μ_e.sat.
    pub SNR_max: f64,
    /// Maximum SNR, dB (20 log₁₀).
    pub SNR_max_dB: f64,
    /// Dynamic range μ_e.sat / μ_e.min.
    pub DR: f64,
    /// Dynamic range, dB (20 log₁₀).
    pub DR_dB: f64,
    /// Linearity error LE, percent (None without photons or varying exposure).
    pub linearity_error_percent: Option<f64>,
    /// Dark current from the mean dark signal, e⁻/s (None with one dark exposure time).
    pub dark_current_mean_e_per_s: Option<f64>,
    /// Dark current from the dark variance, e⁻/s.
    pub dark_current_variance_e_per_s: Option<f64>,
    /// Pairs in the K fit.
    pub fit_levels: usize,
    /// Exposure time of the photon-transfer series (dark noise reference), ns.
    pub ptc_exposure_ns: f64,
    /// Bright pairs, sorted by net signal.
    pub levels: Vec<PairLevel>,
    /// Dark pairs, sorted by exposure time.
    pub darks: Vec<PairLevel>,
    /// Frames in the dark / bright spatial stacks (2 = fallback on pairs).
    pub spatial_frames: [usize; 2],
    /// Per-pixel average of the dark spatial stack, DN, over the pixels used (for the
    /// datasheet's DSNU histogram; not written to the JSON).
    #[serde(skip)]
    pub dark_mean_map_dn: Vec<f64>,
    /// Per-pixel average of the bright spatial stack, DN, over the pixels used (for the
    /// datasheet's PRNU histogram; not written to the JSON).
    #[serde(skip)]
    pub bright_mean_map_dn: Vec<f64>,
    /// Standard uncertainty (1σ, statistical) of each figure, by field name
    /// (`super::uncertainty`).
    pub uncertainties: BTreeMap<String, f64>,
    /// Things the analysis found questionable (e.g. clipped dark frames).
    pub warnings: Vec<String>,
}

/// Reads one image of the set as f64, checking size and bit depth.
fn read_image(
    descriptor_path: &Path,
    d: &Descriptor,
    s: &Series,
    rel: &str,
) -> Result<Array2<u16>> {
    let dir = descriptor_path.parent().unwrap_or(Path::new("."));
    let p = image_path(dir, rel);
    let ext = p
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let img = match ext.as_str() {
        "png" => raster::read_png_u16(&p)?,
        "tif" | "tiff" => raster::read_tiff_u16(&p)?,
        _ => {
            return Err(Error::format(
                &p,
                format!(
                    "descriptor line {}: unsupported image type `.{ext}`; expected 16-bit greyscale .png or .tif/.tiff",
                    s.line
                ),
            ))
        }
    };
    if img.dim() != (d.height, d.width) {
        return Err(Error::format(
            &p,
            format!(
                "the image is {} x {} pixels (width x height) but the descriptor says {} x {}",
                img.ncols(),
                img.nrows(),
                d.width,
                d.height
            ),
        ));
    }
    let max = if d.bits >= 16 {
        u16::MAX
    } else {
        ((1u32 << d.bits) - 1) as u16
    };
    if let Some(v) = img.iter().find(|v| **v > max) {
        return Err(Error::format(
            &p,
            format!(
                "pixel value {v} exceeds {max}, the largest {}-bit value the descriptor declares",
                d.bits
            ),
        ));
    }
    Ok(img)
}

/// A stack of the valid pixels of a series' frames, `[frame, 1, n_valid]`.
fn load_series(path: &Path, d: &Descriptor, s: &Series, valid: &[usize]) -> Result<Array3<f64>> {
    let mut out = Array3::zeros((s.images.len(), 1, valid.len()));
    for (f, rel) in s.images.iter().enumerate() {
        let img = read_image(path, d, s, rel)?;
        let flat = img
            .as_slice()
            .map(|v| v.to_vec())
            .unwrap_or_else(|| img.iter().copied().collect());
        for (k, &p) in valid.iter().enumerate() {
            out[[f, 0, k]] = flat[p] as f64;
        }
    }
    Ok(out)
}

fn pair_stats(stack: ArrayView3<f64>) -> Result<(f64, f64)> {
    let a: ArrayView2<f64> = stack.index_axis(ndarray::Axis(0), 0);
    let b: ArrayView2<f64> = stack.index_axis(ndarray::Axis(0), 1);
    pair_statistics(&FramePair { a, b })
}

/// The defect mask (see the module documentation) from full-frame dark and bright stacks.
fn constant_pixels(
    path: &Path,
    d: &Descriptor,
    dark: &Series,
    bright: &Series,
) -> Result<Vec<bool>> {
    let n = d.width * d.height;
    // (first value, constant so far) per pixel, over the dark then the bright stack.
    let mut first: Vec<u16> = Vec::new();
    let mut constant = vec![true; n];
    for s in [dark, bright] {
        for rel in &s.images {
            let img = read_image(path, d, s, rel)?;
            let flat: Vec<u16> = img.iter().copied().collect();
            if first.is_empty() {
                first = flat;
                continue;
            }
            for ((c, &f), &v) in constant.iter_mut().zip(&first).zip(&flat) {
                *c &= f == v;
            }
        }
    }
    Ok(constant)
}

fn too_few(what: &str, path: &Path) -> Error {
    Error::format(path, what.to_string())
}

/// Analyses the acquisition set of the descriptor at `path` (see the module
/// documentation).
///
/// Errors: descriptor errors (see [`Descriptor::read`]), unreadable, 8-bit, colour or
/// wrongly sized images, fewer than 2 bright pairs, a bright series without a dark series
/// at its exposure time, fewer than 2 pairs in the fit range, or a non-positive K.
pub fn characterize(path: &Path) -> Result<Characterization> {
    let d = Descriptor::read(path)?;
    // The image size comes from the descriptor: checked against the memory budget before
    // anything per pixel exists. Per pixel: the defect mask and valid-pixel index (9 B),
    // the defect pass's first frame, current frame and decode buffer (8 B), and the
    // longest series' f64 stack.
    let longest = d.series.iter().map(|s| s.images.len()).max().unwrap_or(0) as u64;
    crate::limits::check_alloc(
        &format!("characterising {}", path.display()),
        &[
            ("width", d.width as u64),
            ("height", d.height as u64),
            ("bytes per pixel", 17 + 8 * longest),
        ],
        1,
    )?;
    let dark_current = dark_current_descriptor(path, &d)?;
    let temporal_dark: Vec<&Series> = d
        .series
        .iter()
        .filter(|s| s.is_temporal() && s.is_dark())
        .collect();
    // Dark pairs of the dark-current file at exposure times the descriptor lacks.
    let extra_dark: Vec<&Series> = dark_current
        .as_ref()
        .map(|dc| {
            dc.series
                .iter()
                .filter(|s| s.is_temporal() && s.is_dark())
                .filter(|s| {
                    !temporal_dark
                        .iter()
                        .any(|t| t.exposure_ns.to_bits() == s.exposure_ns.to_bits())
                })
                .collect()
        })
        .unwrap_or_default();
    let temporal_bright: Vec<&Series> = d
        .series
        .iter()
        .filter(|s| s.is_temporal() && !s.is_dark())
        .collect();
    let spatial_dark = d.series.iter().find(|s| !s.is_temporal() && s.is_dark());
    let spatial_bright = d.series.iter().find(|s| !s.is_temporal() && !s.is_dark());
    if temporal_bright.len() < 2 {
        return Err(too_few(
            &format!(
                "the set has {} bright pair(s) (`b` series of two images); the photon transfer needs at least 2 (EMVA 1288 asks for 50)",
                temporal_bright.len()
            ),
            path,
        ));
    }
    let key = |t: f64| t.to_bits();
    let dark_by_t: BTreeMap<u64, &Series> = temporal_dark
        .iter()
        .map(|s| (key(s.exposure_ns), *s))
        .collect();
    for s in &temporal_bright {
        if !dark_by_t.contains_key(&key(s.exposure_ns)) {
            return Err(too_few(
                &format!(
                    "line {}: no dark pair (`d {}` with two images) at the exposure time of this bright pair; every exposure time needs its darks",
                    s.line, s.exposure_ns
                ),
                path,
            ));
        }
    }
    if let (Some(sd), Some(sb)) = (spatial_dark, spatial_bright) {
        if key(sd.exposure_ns) != key(sb.exposure_ns) {
            return Err(too_few(
                &format!(
                    "line {}: the dark stack's exposure time {} ns differs from the bright stack's {} ns (line {}); the spatial dark must match",
                    sd.line, sd.exposure_ns, sb.exposure_ns, sb.line
                ),
                path,
            ));
        }
    } else if spatial_bright.is_some() {
        return Err(too_few(
            "a bright spatial stack without a dark stack (`d` with more than two images)",
            path,
        ));
    }

    // Defective pixels.
    let npix = d.width * d.height;
    let defect = match (spatial_dark, spatial_bright) {
        (Some(sd), Some(sb)) => constant_pixels(path, &d, sd, sb)?,
        _ => vec![false; npix],
    };
    let valid: Vec<usize> = (0..npix).filter(|&p| !defect[p]).collect();
    if valid.len() < 2 {
        return Err(too_few(
            "fewer than 2 pixels vary between frames; nothing to characterise",
            path,
        ));
    }

    // Dark pairs.
    let mut darks: Vec<PairLevel> = Vec::new();
    let mut dark_stats: BTreeMap<u64, (f64, f64)> = BTreeMap::new();
    let (mut dark_clipped, mut dark_values) = (0usize, 0usize);
    let max_value = if d.bits >= 16 {
        f64::from(u16::MAX)
    } else {
        f64::from((1u32 << d.bits) - 1)
    };
    let dc_path = dark_current_path(path);
    for (s, file) in temporal_dark
        .iter()
        .map(|s| (*s, path))
        .chain(extra_dark.iter().map(|s| (*s, dc_path.as_path())))
    {
        let st = load_series(file, &d, s, &valid)?;
        dark_clipped += st.iter().filter(|v| **v <= 0.0 || **v >= max_value).count();
        dark_values += st.len();
        let (m, v) = pair_stats(st.view())?;
        dark_stats.insert(key(s.exposure_ns), (m, v));
        darks.push(PairLevel {
            exposure_ns: s.exposure_ns,
            photons_per_pixel: None,
            mean_dn: m,
            variance_dn2: v,
            net_mean_dn: 0.0,
            net_variance_dn2: 0.0,
            snr: 0.0,
            in_fit: false,
        });
    }
    darks.sort_by(|a, b| a.exposure_ns.total_cmp(&b.exposure_ns));

    // Bright pairs.
    let with_photons = temporal_bright
        .iter()
        .filter(|s| s.photons_per_pixel.is_some())
        .count();
    let mut levels: Vec<PairLevel> = Vec::with_capacity(temporal_bright.len());
    for s in &temporal_bright {
        let st = load_series(path, &d, s, &valid)?;
        let (m, v) = pair_stats(st.view())?;
        let (dm, dv) = dark_stats[&key(s.exposure_ns)];
        levels.push(PairLevel {
            exposure_ns: s.exposure_ns,
            photons_per_pixel: s.photons_per_pixel,
            mean_dn: m,
            variance_dn2: v,
            net_mean_dn: m - dm,
            net_variance_dn2: v - dv,
            snr: if v > 0.0 {
                (m - dm) / v.sqrt()
            } else {
                f64::NAN
            },
            in_fit: false,
        });
    }
    levels.sort_by(|a, b| a.net_mean_dn.total_cmp(&b.net_mean_dn));
    let sat = levels
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.variance_dn2.total_cmp(&b.1.variance_dn2))
        .map_or(0, |(i, _)| i);
    let u_y_sat = levels[sat].net_mean_dn;
    let limit = FIT_FRACTION * u_y_sat;
    for l in levels.iter_mut() {
        l.in_fit = u_y_sat > 0.0 && l.net_mean_dn > 0.0 && l.net_mean_dn <= limit;
    }
    let ptc: Vec<(f64, f64)> = levels
        .iter()
        .filter(|l| l.in_fit)
        .map(|l| (l.net_mean_dn, l.net_variance_dn2))
        .collect();
    let fit_levels = ptc.len();
    let (k, intercept) = fit_line(&ptc).ok_or_else(|| {
        Error::OutOfRange(format!(
            "photon transfer: only {fit_levels} pair(s) lie between dark and 70 % of the saturation signal ({u_y_sat:.1} DN net); at least 2 are needed — add levels below saturation"
        ))
    })?;
    if !(k.is_finite() && k > 0.0) {
        return Err(Error::OutOfRange(format!(
            "photon transfer: the temporal variance does not grow with the signal (K = {k} DN/e-); check the illumination levels and the dark pairs"
        )));
    }
    let (responsivity, qe) = if with_photons == levels.len() {
        let pts: Vec<(f64, f64)> = levels
            .iter()
            .filter(|l| l.in_fit)
            .filter_map(|l| l.photons_per_pixel.map(|p| (p, l.net_mean_dn)))
            .collect();
        match fit_line(&pts) {
            Some((r, _)) => (Some(r), Some(r / k)),
            None => (None, None),
        }
    } else {
        (None, None)
    };

    // The photon-transfer exposure time: the bright stack's, else the most common.
    let ptc_exposure_ns = match spatial_bright {
        Some(s) => s.exposure_ns,
        None => {
            let mut count: BTreeMap<u64, usize> = BTreeMap::new();
            for s in &temporal_bright {
                *count.entry(key(s.exposure_ns)).or_default() += 1;
            }
            let best = count.iter().max_by_key(|(_, c)| **c).map_or(0, |(t, _)| *t);
            f64::from_bits(best)
        }
    };
    let (dark_var, sigma_y_dark_measured) = match dark_stats.get(&key(ptc_exposure_ns)) {
        Some(&(_, v)) => (v, v.max(0.0).sqrt()),
        None => {
            return Err(too_few(
                &format!("no dark pair at the photon-transfer exposure time {ptc_exposure_ns} ns"),
                path,
            ))
        }
    };

    // Linearity.
    let exposures_vary = levels
        .iter()
        .any(|l| l.exposure_ns != levels[0].exposure_ns);
    let abscissa = |l: &PairLevel| -> Option<f64> {
        if qe.is_some() {
            l.photons_per_pixel
        } else if exposures_vary {
            Some(l.exposure_ns)
        } else {
            None
        }
    };
    let lin_pts: Vec<(f64, f64)> = levels
        .iter()
        .filter(|l| l.net_mean_dn >= 0.05 * u_y_sat && l.net_mean_dn <= 0.95 * u_y_sat)
        .filter_map(|l| abscissa(l).map(|x| (x, l.net_mean_dn)))
        .collect();
    // The uncertainty of a deviation δ_i is its net mean's, 100·u(μ_y − μ_y.dark)/(ax + b)
    // with u² = (σ²_y + σ²_y.dark)/(2N); LE's is half the quadrature sum of those of the
    // largest and smallest deviation.
    let n_px = valid.len() as f64;
    let lin_u: Vec<f64> = levels
        .iter()
        .filter(|l| l.net_mean_dn >= 0.05 * u_y_sat && l.net_mean_dn <= 0.95 * u_y_sat)
        .filter(|l| abscissa(l).is_some())
        .map(|l| ((l.variance_dn2 + (l.variance_dn2 - l.net_variance_dn2)) / (2.0 * n_px)).sqrt())
        .collect();
    let linearity_fit = fit_line(&lin_pts).map(|(a, b)| {
        let devs: Vec<(f64, f64)> = lin_pts
            .iter()
            .zip(&lin_u)
            .map(|(&(x, y), u)| {
                let line = a * x + b;
                (100.0 * (y - line) / line, 100.0 * u / line.abs())
            })
            .collect();
        let hi = devs.iter().copied().fold(
            (f64::NEG_INFINITY, 0.0),
            |m, d| if d.0 > m.0 { d } else { m },
        );
        let lo = devs
            .iter()
            .copied()
            .fold((f64::INFINITY, 0.0), |m, d| if d.0 < m.0 { d } else { m });
        (0.5 * (hi.0 - lo.0), 0.5 * hi.1.hypot(lo.1))
    });
    let linearity = linearity_fit.map(|l| l.0);

    // Dark current.
    // (points, slope, intercept) of the two dark-current fits.
    type Fit = (Vec<(f64, f64)>, f64, f64);
    let (dc_mean_fit, dc_var_fit): (Option<Fit>, Option<Fit>) = if darks.len() >= 2 {
        let m: Vec<(f64, f64)> = darks
            .iter()
            .map(|l| (l.exposure_ns * 1e-9, l.mean_dn))
            .collect();
        let v: Vec<(f64, f64)> = darks
            .iter()
            .map(|l| (l.exposure_ns * 1e-9, l.variance_dn2))
            .collect();
        (
            fit_line(&m).map(|(s, b)| (m, s, b)),
            fit_line(&v).map(|(s, b)| (v, s, b)),
        )
    } else {
        (None, None)
    };
    let dc_mean = dc_mean_fit.as_ref().map(|f| f.1 / k);
    let dc_var = dc_var_fit.as_ref().map(|f| f.1 / (k * k));

    // Spatial non-uniformity.
    let (dark_stack, bright_stack) = match (spatial_dark, spatial_bright) {
        (Some(sd), Some(sb)) => (
            load_series(path, &d, sd, &valid)?,
            load_series(path, &d, sb, &valid)?,
        ),
        _ => {
            let half = 0.5 * u_y_sat;
            let nearest = temporal_bright
                .iter()
                .min_by(|a, b| {
                    let na = load_net(&levels, a);
                    let nb = load_net(&levels, b);
                    (na - half).abs().total_cmp(&(nb - half).abs())
                })
                .copied()
                .ok_or_else(|| too_few("no bright pair", path))?;
            let dark = dark_by_t[&key(nearest.exposure_ns)];
            (
                load_series(path, &d, dark, &valid)?,
                load_series(path, &d, nearest, &valid)?,
            )
        }
    };
    let (dark_mean_s, dark_s2) = spatial_statistics(dark_stack.view())?;
    let (bright_mean_s, bright_s2) = spatial_statistics(bright_stack.view())?;
    let net = bright_mean_s - dark_mean_s;

    // The figures and their uncertainties (super::uncertainty), from the measured
    // quantities.
    let n = valid.len() as f64;
    let measured = Measured {
        k,
        r: responsivity.unwrap_or(f64::NAN),
        y_sat: u_y_sat,
        dark_var,
        s2_dark: dark_s2,
        s2_bright: bright_s2,
        net_spatial: if net > 0.0 { net } else { f64::NAN },
    };
    let r_pts: Vec<(f64, f64)> = levels
        .iter()
        .filter(|l| l.in_fit)
        .filter_map(|l| l.photons_per_pixel.map(|p| (p, l.net_mean_dn)))
        .collect();
    let sat_var = levels[sat].variance_dn2;
    let u_measured = Measured {
        k: slope_standard_error(&ptc, k, intercept).unwrap_or(f64::NAN),
        r: match (responsivity, fit_line(&r_pts)) {
            (Some(_), Some((r, b))) => slope_standard_error(&r_pts, r, b).unwrap_or(f64::NAN),
            _ => f64::NAN,
        },
        y_sat: ((sat_var + dark_var) / (2.0 * n)).sqrt(),
        dark_var: dark_var * (2.0 / n).sqrt(),
        s2_dark: dark_s2.abs() * (2.0 / (n - 1.0)).sqrt(),
        s2_bright: bright_s2.abs() * (2.0 / (n - 1.0)).sqrt(),
        net_spatial: ((dark_s2.abs() + bright_s2.abs()) / n).sqrt(),
    };
    let fig = figures(&measured);
    let mut uncertainties: BTreeMap<String, f64> = propagate(&measured, &u_measured)
        .into_iter()
        .filter(|(_, v)| v.is_finite())
        .map(|(k, v)| (k.to_string(), v))
        .collect();
    let sigma_d_e = fig["sigma_d_e"];
    let u_e_sat = fig["u_e_sat_e"];
    let u_e_min = fig["u_e_min_e"];
    let snr_max = fig["SNR_max"];
    let dr = fig["DR"];
    let dsnu_dn = fig["DSNU1288_DN"];
    let prnu = fig["PRNU1288_percent"];
    let sigma_y_dark_floored = fig["sigma_y_dark_DN"];
    if let (Some(m), Some(v)) = (dc_mean_fit.as_ref(), dc_mean) {
        if let Some(se) = slope_standard_error(&m.0, m.1, m.2) {
            uncertainties.insert(
                "dark_current_mean_e_per_s".to_string(),
                // v = s/K: u² = (u_s/K)² + (v·u_K/K)².
                (se / k).hypot(v * u_measured.k / k),
            );
        }
    }
    if let (Some(m), Some(v)) = (dc_var_fit.as_ref(), dc_var) {
        if let Some(se) = slope_standard_error(&m.0, m.1, m.2) {
            uncertainties.insert(
                "dark_current_variance_e_per_s".to_string(),
                // v = s/K²: u² = (u_s/K²)² + (2v·u_K/K)².
                (se / (k * k)).hypot(2.0 * v * u_measured.k / k),
            );
        }
    }
    if let Some((_, u)) = linearity_fit {
        uncertainties.insert("linearity_error_percent".to_string(), u);
    }
    let mut warnings = Vec::new();
    if dark_clipped > 0 {
        warnings.push(format!(
            "{:.3} % of the dark pixel values are at 0 DN or at the ADC maximum ({max_value} DN): the ADC clips the dark signal, so σ_y.dark, the DSNU and the dark current are biased; raise the black level (offset) so the darks sit clear of 0 DN",
            100.0 * dark_clipped as f64 / dark_values.max(1) as f64
        ));
    }
    if dark_var < QUANTISATION_LIMIT_DN2 {
        warnings.push(format!(
            "σ_y.dark² = {dark_var:.4} DN² is below the 0.24 DN² limit: the dark noise is quantisation-limited; σ_y.dark = √0.24 DN is used (EMVA 1288 Release 4.0), so σ_d, μ_e.min and the dynamic range are limits"
        ));
    }

    Ok(Characterization {
        image_size: [d.width, d.height],
        bits: d.bits,
        pixels_used: valid.len(),
        defective_pixels: npix - valid.len(),
        K_DN_per_e: k,
        ptc_intercept_DN2: intercept,
        QE_percent: qe.map(|q| 100.0 * q),
        responsivity_DN_per_photon: responsivity,
        sigma_d_e,
        sigma_y_dark_DN: sigma_y_dark_floored,
        sigma_y_dark_measured_DN: sigma_y_dark_measured,
        sigma_d_quantisation_limited: dark_var < QUANTISATION_LIMIT_DN2,
        DSNU1288_e: dsnu_dn / k,
        DSNU1288_DN: dsnu_dn,
        PRNU1288_percent: prnu,
        u_e_sat_e: u_e_sat,
        u_y_sat_DN: u_y_sat,
        u_p_sat: levels[sat].photons_per_pixel,
        saturation_at_brightest_level: sat + 1 == levels.len(),
        u_e_min_e: u_e_min,
        u_p_min: qe.map(|q| u_e_min / q),
        SNR_max: snr_max,
        SNR_max_dB: 20.0 * snr_max.log10(),
        DR: dr,
        DR_dB: 20.0 * dr.log10(),
        linearity_error_percent: linearity,
        dark_current_mean_e_per_s: dc_mean,
        dark_current_variance_e_per_s: dc_var,
        fit_levels,
        ptc_exposure_ns,
        levels,
        darks,
        spatial_frames: [
            dark_stack.len_of(ndarray::Axis(0)),
            bright_stack.len_of(ndarray::Axis(0)),
        ],
        dark_mean_map_dn: pixel_means(&dark_stack),
        bright_mean_map_dn: pixel_means(&bright_stack),
        uncertainties,
        warnings,
    })
}

/// The average over frames of every pixel of a `[frame, 1, pixel]` stack.
fn pixel_means(stack: &Array3<f64>) -> Vec<f64> {
    stack
        .mean_axis(ndarray::Axis(0))
        .map_or_else(Vec::new, |m| m.iter().copied().collect())
}

/// The dark-current file beside a descriptor ([`DARK_CURRENT_FILE`]).
pub fn dark_current_path(descriptor: &Path) -> PathBuf {
    descriptor
        .parent()
        .unwrap_or(Path::new("."))
        .join(DARK_CURRENT_FILE)
}

/// The dark-current series beside `path`, if the file exists: parsed and checked like a
/// descriptor, with dark series only and the same image format as `d`.
fn dark_current_descriptor(path: &Path, d: &Descriptor) -> Result<Option<Descriptor>> {
    let p = dark_current_path(path);
    if !p.exists() {
        return Ok(None);
    }
    let dc = Descriptor::read(&p)?;
    if (dc.bits, dc.width, dc.height) != (d.bits, d.width, d.height) {
        return Err(Error::format(
            &p,
            format!(
                "`n {} {} {}` differs from the descriptor's `n {} {} {}`",
                dc.bits, dc.width, dc.height, d.bits, d.width, d.height
            ),
        ));
    }
    if let Some(s) = dc.series.iter().find(|s| !s.is_dark()) {
        return Err(Error::format(
            &p,
            format!(
                "line {}: a bright series; the dark-current file holds dark series (`d`) only",
                s.line
            ),
        ));
    }
    Ok(Some(dc))
}

/// The net signal of the level computed from series `s` (matched by exposure and photons).
fn load_net(levels: &[PairLevel], s: &Series) -> f64 {
    levels
        .iter()
        .find(|l| l.exposure_ns == s.exposure_ns && l.photons_per_pixel == s.photons_per_pixel)
        .map_or(f64::INFINITY, |l| l.net_mean_dn)
}

/// The descriptor file of an acquisition set: `dir/descriptor.txt` for a directory, the
/// path itself for a file.
pub fn descriptor_path(set: &Path) -> PathBuf {
    if set.is_dir() {
        set.join("descriptor.txt")
    } else {
        set.to_path_buf()
    }
}
