//! Sizing a synthetic scene to a detector: the angular extent a scene must cover, by the
//! one paraxial rule the engine samples with, an integer oversampling and a margin.
//!
//! # The rule
//!
//! The engine's geometry is paraxial (docs/design.md §5): sample `c` of `n` samples spaced
//! `s` radians apart looks at `(c − (n − 1)/2)·s` from the boresight and stands for the
//! interval of width `s` around it, so `n` samples cover [`paraxial_extent_rad`]` = n·s`.
//! A detector of `n` pixels of pitch `p` behind a focal length `f` samples every
//! `s = p/f` and so covers `n·p/f`; a scene of `N` samples over a field of view `F` samples
//! every `F/N` and covers `F`. `eoir run` (`imaging::Sampling`) refuses a scene whose extent
//! is smaller than the detector's, both computed with [`paraxial_extent_rad`].
//!
//! This is *not* the field of view of a flat focal plane, `2·atan(n·p/(2f))`
//! (`SensorConfig::fov_deg`, what a datasheet quotes): that is smaller, by
//! `x − 2 atan(x/2) ≈ x³/12` for `x = n·p/f`: MultimIR's 384 columns cover 5.2804° by
//! the paraxial rule and 5.2766° as a flat focal plane with the 100 mm optics (0.07 %),
//! 35.20° and 34.15° with the 15 mm optics (3 %). A scene sized to the datasheet field of view is therefore
//! always refused; a scene sized with [`covering`] always fits.
//!
//! # Sizing
//!
//! [`covering`] gives a scene `(rows + 2m)·k × (cols + 2m)·k` samples over
//! `(cols + 2m)·p/f × (rows + 2m)·p/f`: `k` scene samples per detector pixel along both axes
//! (an integer ratio, so the engine point-samples after an exact phase-ramp shift instead of
//! resampling), and a margin of `m` detector pixels of real scene beyond each edge of the
//! detector, so the blur at the edge pixels reaches scene content rather than the engine's
//! mirror padding, and a field of view written with a few digits less still covers the
//! detector.

use super::synthetic::SceneParams;
use crate::error::{Error, Result};

/// Fewest scene samples per detector pixel when none is given: 2 (the demo's), enough for
/// the detector footprint and the optics' transfer function to act on a finer grid than
/// the detector samples. [`default_oversampling`] asks more when the optics pass more.
pub const DEFAULT_OVERSAMPLING: usize = 2;

/// Most scene samples per detector pixel [`default_oversampling`] picks: 4 (16× the
/// detector's samples per band). Beyond it the engine's taper at the scene's Nyquist
/// (`imaging::scene_band`) handles the rest of the optical band, with a warning; a user
/// who wants the whole band asks for more with `--oversampling`.
pub const MAX_DEFAULT_OVERSAMPLING: usize = 4;

/// Detector pixels of scene beyond each edge of the detector when none is given.
pub const DEFAULT_MARGIN_PX: usize = 4;

/// Largest margin [`covering`] accepts, detector pixels per side.
pub const MAX_MARGIN_PX: usize = 4096;

/// Widest band spacing of [`response_grid_um`], µm.
pub const SPECTRAL_STEP_UM: f64 = 0.02;

/// Fewest bands of [`response_grid_um`].
pub const MIN_BANDS: usize = 24;

/// Most bands of [`response_grid_um`]: a band wider than 120 × 0.02 = 2.4 µm is sampled
/// more coarsely than [`SPECTRAL_STEP_UM`] rather than with hundreds of bands (QWIP's
/// Gaussian response spans 4.9–12.1 µm: 121 bands 0.06 µm apart instead of 362). The
/// engine integrates the response exactly between samples (product integration), so the
/// spacing only has to follow the scene spectrum, which is smooth for the built-in scenes.
pub const MAX_GRID_BANDS: usize = 121;

/// The smallest integer number of scene samples per detector pixel whose Nyquist frequency
/// `k/(2·IFOV)` reaches the optical cutoff `cutoff_cy_per_rad` (cycles/rad), so that the
/// scene grid holds every frequency the optics pass: `⌈2·IFOV·cutoff⌉`, at least 1;
/// `None` for an unbounded or invalid cutoff.
pub fn oversampling_for_cutoff(ifov_rad: f64, cutoff_cy_per_rad: f64) -> Option<usize> {
    let k = (2.0 * ifov_rad * cutoff_cy_per_rad * (1.0 - 1e-12)).ceil();
    (k.is_finite() && (0.0..1e6).contains(&k)).then(|| (k as usize).max(1))
}

/// The oversampling `eoir scene` uses when none is given: [`oversampling_for_cutoff`] for
/// the optics' cutoff (D/λ at the scene's shortest wavelength, cycles/rad; `None` without
/// an aperture term), between [`DEFAULT_OVERSAMPLING`] and [`MAX_DEFAULT_OVERSAMPLING`].
pub fn default_oversampling(ifov_rad: f64, optical_cutoff_cy_per_rad: Option<f64>) -> usize {
    optical_cutoff_cy_per_rad
        .and_then(|c| oversampling_for_cutoff(ifov_rad, c))
        .unwrap_or(DEFAULT_OVERSAMPLING)
        .clamp(DEFAULT_OVERSAMPLING, MAX_DEFAULT_OVERSAMPLING)
}

/// Angular extent, rad, of `samples` samples spaced `spacing_rad` apart under the engine's
/// paraxial convention: `samples · spacing_rad` (module documentation). Used for the
/// detector and the scene alike wherever one is compared with the other.
pub fn paraxial_extent_rad(samples: usize, spacing_rad: f64) -> f64 {
    samples as f64 * spacing_rad
}

/// The detector grid a scene is sized to: pixel counts and the angular sample spacing
/// (IFOV = pitch / focal length, rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectorGrid {
    /// Detector rows.
    pub rows: usize,
    /// Detector columns.
    pub cols: usize,
    /// Angular pixel spacing, rad.
    pub ifov_rad: f64,
}

impl DetectorGrid {
    /// Paraxial field of view (horizontal, vertical), degrees: `cols·IFOV`, `rows·IFOV`.
    pub fn fov_deg(&self) -> (f64, f64) {
        (
            paraxial_extent_rad(self.cols, self.ifov_rad).to_degrees(),
            paraxial_extent_rad(self.rows, self.ifov_rad).to_degrees(),
        )
    }
}

/// Scene parameters covering `grid` at `oversampling` scene samples per detector pixel with
/// `margin_px` detector pixels of scene beyond each edge (module documentation). The other
/// fields (wavelengths, range, seed, sun) are [`SceneParams::default`]'s, for the caller to
/// set. Errors name the value and what is valid.
pub fn covering(grid: &DetectorGrid, oversampling: usize, margin_px: usize) -> Result<SceneParams> {
    if !(grid.ifov_rad.is_finite() && grid.ifov_rad > 0.0) {
        return Err(Error::param(
            "detector IFOV (pitch / focal length)",
            grid.ifov_rad,
            "a finite angle > 0 rad",
        ));
    }
    if margin_px > MAX_MARGIN_PX {
        return Err(Error::param(
            "margin_px",
            margin_px,
            format!("at most {MAX_MARGIN_PX} detector pixels per side"),
        ));
    }
    // rows, cols come from a validated sensor; the margin is bounded: no overflow, but check.
    let grow = |n: usize, axis: &str| {
        n.checked_add(2 * margin_px)
            .ok_or_else(|| Error::param(axis, n, "a detector size that fits in memory"))
    };
    let rows = grow(grid.rows, "detector rows")?;
    let cols = grow(grid.cols, "detector cols")?;
    let params = SceneParams {
        rows,
        cols,
        oversampling,
        fov_x_deg: paraxial_extent_rad(cols, grid.ifov_rad).to_degrees(),
        ..SceneParams::default()
    };
    params.validate()?;
    Ok(params)
}

/// A wavelength grid across a sensor's response support `[lo_um, hi_um]`: evenly spaced,
/// both ends included, at most [`SPECTRAL_STEP_UM`] apart (or [`MAX_GRID_BANDS`] bands
/// for a wider band) and at least [`MIN_BANDS`] bands.
/// Errors for an unbounded or empty support.
pub fn response_grid_um(lo_um: f64, hi_um: f64) -> Result<Vec<f64>> {
    if !(lo_um.is_finite() && hi_um.is_finite() && hi_um > lo_um && lo_um > 0.0) {
        return Err(Error::param(
            "spectral response support",
            format!("[{lo_um}, {hi_um}] µm"),
            "a bounded band (give the sensor a [filter], or give the wavelengths explicitly)",
        ));
    }
    let steps = ((hi_um - lo_um) / SPECTRAL_STEP_UM).ceil();
    let bands = if steps >= (MAX_GRID_BANDS - 1) as f64 {
        MAX_GRID_BANDS
    } else {
        (steps as usize + 1).max(MIN_BANDS)
    };
    SceneParams::uniform_grid(lo_um, hi_um, bands)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The oversampling rule is the smallest k with k/(2·IFOV) ≥ cutoff (checked by
    /// search), MultimIR F/2 at 3.7 µm: 24 µm/100 mm, D/λ = 13 514 cy/rad → 2·2.4e-4·13514
    /// = 6.49 → 7.
    #[test]
    fn oversampling_is_the_smallest_that_reaches_the_cutoff() {
        for (ifov, cut) in [
            (2.4e-4, 0.05 / 3.7e-6),
            (2.4e-4, 0.05 / 4.55e-6),
            (1e-4, 5e3),
        ] {
            let k = oversampling_for_cutoff(ifov, cut).unwrap();
            let search = (1..100).find(|k| *k as f64 / (2.0 * ifov) >= cut * (1.0 - 1e-12));
            assert_eq!(Some(k), search, "{ifov} {cut}");
        }
        assert_eq!(oversampling_for_cutoff(2.4e-4, 0.05 / 3.7e-6), Some(7));
        assert_eq!(oversampling_for_cutoff(1e-4, f64::INFINITY), None);
    }

    /// The default stays between 2 and 4: 4 for MultimIR's F/2 (needs 6 at 4.55 µm), 2 for
    /// optics that the detector-rate grid already holds, 2 without an aperture cutoff.
    #[test]
    fn default_oversampling_is_clamped() {
        assert_eq!(default_oversampling(2.4e-4, Some(0.05 / 4.55e-6)), 4);
        assert_eq!(default_oversampling(2.4e-4, Some(3e3)), 2);
        assert_eq!(default_oversampling(2.4e-4, Some(7.0e3)), 4);
        assert_eq!(default_oversampling(2.4e-4, Some(6.0e3)), 3);
        assert_eq!(default_oversampling(2.4e-4, None), 2);
    }
}
