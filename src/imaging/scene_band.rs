//! The scene grid's band limit: what the engine does when the optics pass frequencies the
//! scene grid cannot hold (docs/design.md, "Scene sampling coarser than the optics").
//!
//! The transform of a scene sampled every `d` radians holds frequencies up to the square
//! `|fx|, |fy| ≤ 1/(2d)`. When the system OTF is still non-zero there (the aperture cutoff
//! `D/λ` beyond the scene's Nyquist), the filter the engine applies is the OTF cut off at
//! that square and repeated periodically. It is even, so its value is continuous across the
//! square's edges, but its slope is not (`∂OTF/∂fx` on one side, its negative on the
//! other): a kink along the whole line `fx = ±1/(2d)`, whose transform is a kernel that
//! falls off only as `1/n²` along the x axis, and likewise along y. That is the faint cross
//! through bright sources (issue 38: +0.8 % along the column of a saturated exhaust).
//!
//! The treatment is a radial raised-cosine taper of the OTF, `T(ρ) = 1` up to
//! `ρ_a = `[`TAPER_START_FRACTION`]`·ρ_N` (half of it), `½(1 + cos(π(ρ − ρ_a)/(ρ_N − ρ_a)))` up to the
//! grid's *inscribed* Nyquist circle `ρ_N = min(1/(2dx), 1/(2dy))`, and 0 beyond. The
//! tapered OTF is zero in a neighbourhood of the square's edges, so its periodic
//! repetition is smooth and isotropic: no cross. It is radial, so it multiplies the
//! achromatic product once per frame size (no per-sample pass in the accumulation).
//!
//! It applies only when it is needed: when an aperture term (diffraction, aberration or
//! defocus) sets a cutoff `D/λ_min` above `ρ_N` at the shortest wavelength in use, or when
//! no aperture term bounds the OTF while some other component shapes it. A system with no
//! component at all (a truth image) passes the scene untouched.

use crate::sensor::{Component, SystemOtf};

/// Where the taper starts, as a fraction of the inscribed Nyquist frequency `ρ_N`: 0.5.
///
/// The ramp's width sets how far the taper's own ringing reaches (it is isotropic, rings
/// rather than a cross, but the detector samples those rings at one phase along a row):
/// over 0.5 … 1 ρ_N, a quarter cycle per scene sample, it spans a few samples. Its start
/// sets which genuine content of the scene is attenuated: at k = 2 scene samples per
/// pixel, 0.5 ρ_N is the detector's own Nyquist frequency, so only frequencies the
/// detector aliases are touched (at k = 1 the upper half of the detector's band is).
/// A ramp over 0.8 … 1 ρ_N left its rings 30 % above the halo 30–44 px from a point
/// source at k = 2 (`imaging::bright_sources_leave_no_cross_at_k2_and_k4`).
pub const TAPER_START_FRACTION: f64 = 0.5;

/// The radial taper applied to the system OTF of a scene grid sampled more coarsely than
/// the optics (module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridTaper {
    /// Where the ramp starts, cycles/rad.
    pub start_cy_per_rad: f64,
    /// The inscribed Nyquist frequency, where the taper reaches 0, cycles/rad.
    pub nyquist_cy_per_rad: f64,
}

impl GridTaper {
    /// The taper of a grid sampled every `dy_rad` (rows) and `dx_rad` (columns).
    pub fn new(dy_rad: f64, dx_rad: f64) -> Self {
        let nyquist = inscribed_nyquist_cy_per_rad(dy_rad, dx_rad);
        GridTaper {
            start_cy_per_rad: TAPER_START_FRACTION * nyquist,
            nyquist_cy_per_rad: nyquist,
        }
    }

    /// `T(ρ)` at radial frequency `rho` (cycles/rad): 1, the raised cosine, or 0.
    #[inline]
    pub fn factor(&self, rho: f64) -> f64 {
        if rho <= self.start_cy_per_rad {
            1.0
        } else if rho >= self.nyquist_cy_per_rad {
            0.0
        } else {
            let t =
                (rho - self.start_cy_per_rad) / (self.nyquist_cy_per_rad - self.start_cy_per_rad);
            0.5 * (1.0 + (std::f64::consts::PI * t).cos())
        }
    }
}

/// The Nyquist frequency of the circle inscribed in the grid's frequency square,
/// `min(1/(2dx), 1/(2dy))`, cycles/rad.
pub fn inscribed_nyquist_cy_per_rad(dy_rad: f64, dx_rad: f64) -> f64 {
    0.5 / dy_rad.max(dx_rad)
}

/// The highest frequency the system passes at `min_wavelength_um`, cycles/rad: the
/// aperture cutoff `D/λ_min` when an aperture term (diffraction, aberration, defocus) is
/// on; +∞ when no aperture term is on but another component is; `None` when no component
/// is on (the identity).
pub fn optical_cutoff_cy_per_rad(otf: &SystemOtf, min_wavelength_um: f64) -> Option<f64> {
    let c = otf.components();
    if c.is_empty() {
        return None;
    }
    let aperture = c.iter().any(|c| {
        matches!(
            c,
            Component::Diffraction | Component::Aberration | Component::Defocus
        )
    });
    Some(if aperture {
        otf.cutoff_cy_per_rad(min_wavelength_um)
    } else {
        f64::INFINITY
    })
}

/// The taper to apply for a scene grid sampled every `(dy_rad, dx_rad)` and the shortest
/// wavelength in use, or `None` when the system's cutoff lies within the grid's inscribed
/// Nyquist circle (or no component is on).
pub fn grid_taper(
    otf: &SystemOtf,
    scene_ifov_rad: (f64, f64),
    min_wavelength_um: f64,
) -> Option<GridTaper> {
    let taper = GridTaper::new(scene_ifov_rad.0, scene_ifov_rad.1);
    let cutoff = optical_cutoff_cy_per_rad(otf, min_wavelength_um)?;
    (cutoff > taper.nyquist_cy_per_rad).then_some(taper)
}

/// The warning for a scene whose grid cannot hold the optics' band: the two frequencies,
/// what the engine does, and the oversampling that would avoid it.
pub fn coarse_scene_warning(
    taper: &GridTaper,
    cutoff_cy_per_rad: f64,
    detector_ifov_rad: f64,
    scene_ifov_rad: (f64, f64),
) -> String {
    let k_now = detector_ifov_rad / scene_ifov_rad.0.max(scene_ifov_rad.1);
    let remedy = match crate::scene::sizing::oversampling_for_cutoff(detector_ifov_rad, cutoff_cy_per_rad) {
        Some(k) => format!(
            "a scene with at least {k} samples per detector pixel (`eoir scene --oversampling {k}`) holds the whole optical band"
        ),
        None => "no finite oversampling holds a transfer function without a cutoff".to_string(),
    };
    format!(
        "the scene's Nyquist frequency {:.3} cy/mrad ({k_now:.3} scene samples per detector pixel) is below the optical cutoff {} at the shortest wavelength: the system OTF is tapered to 0 between {:.3} and {:.3} cy/mrad (radial raised cosine, so bright sources leave no cross; docs/design.md, scene sampling); {remedy}",
        taper.nyquist_cy_per_rad * 1e-3,
        if cutoff_cy_per_rad.is_finite() {
            format!("{:.3} cy/mrad", cutoff_cy_per_rad * 1e-3)
        } else {
            "(none: no aperture term bounds the OTF)".to_string()
        },
        taper.start_cy_per_rad * 1e-3,
        taper.nyquist_cy_per_rad * 1e-3,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The taper is 1 up to its start, 0 from the inscribed Nyquist on, ½ halfway, and
    /// continuous with a continuous slope (C¹) at both ends of the ramp.
    #[test]
    fn taper_values_and_smoothness() {
        let t = GridTaper::new(2e-5, 1e-5);
        let n = 0.5 / 2e-5;
        assert_eq!(t.nyquist_cy_per_rad, n);
        assert_eq!(t.factor(0.0), 1.0);
        assert_eq!(t.factor(0.5 * n), 1.0);
        assert!((t.factor(0.75 * n) - 0.5).abs() < 1e-12);
        assert_eq!(t.factor(n), 0.0);
        assert_eq!(t.factor(2.0 * n), 0.0);
        let h = 1e-6 * n;
        for edge in [0.5 * n, n] {
            let slope_in = (t.factor(edge) - t.factor(edge - h)) / h;
            let slope_out = (t.factor(edge + h) - t.factor(edge)) / h;
            assert!((slope_in - slope_out).abs() * n < 1e-4, "{edge}");
        }
    }
}
