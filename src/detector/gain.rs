//! Dark and background electrons, and the automatic choice of the conversion gain K.

use crate::error::{Error, Result};
use crate::radiometry::CameraEquation;
use crate::scene::synthetic::solar_spectral_irradiance;
use crate::spectrum::Spectrum;

use super::config::{AutoGainConfig, AutoGainReference, DetectorConfig};
use super::{apply_nonlinearity, clip_full_well, DetectorModel};

/// Upper edge of the spectral response, µm, at or below which [`AutoGainConfig`] uses the
/// reflected-sun reference by default. The brief's rule of thumb was "visible (< 1 µm)";
/// 2.5 µm also covers SWIR sensors, where a 300 K blackbody gives ~10⁻⁵ of the electrons
/// of sunlit ground and would set an absurdly high gain, while any band reaching the
/// MWIR (≥ 3 µm) keeps the thermal reference.
pub const REFLECTIVE_LIMIT_UM: f64 = 2.5;

/// Shortest and longest wavelengths of the reflected-sun integral, µm (used when the
/// spectral response itself is unbounded, e.g. all constants).
const SUN_BAND_UM: (f64, f64) = (0.2, 100.0);

/// Mean dark electrons per pixel per frame: the dark current (the `[detector.dark_model]`
/// rate if present, else `dark_current_e_per_s`, else 0) × integration time.
pub(crate) fn dark_e_per_frame(d: &DetectorConfig) -> f64 {
    let rate = match (&d.dark_model, d.dark_current_e_per_s) {
        (Some(m), _) => m.rate_e_per_s(),
        (None, Some(r)) => r,
        (None, None) => 0.0,
    };
    rate * d.integration_time_s
}

/// Mean background electrons per pixel per frame from `[detector.background]` (0 when
/// absent): the camera equation (docs/design.md §4.1, same cone and obscuration as the
/// scene) applied to the grey-body radiance `ε·B(λ, T)` through `filter_qe` =
/// τ_filter(λ)·η(λ), without the optics and atmosphere transmissions (the emitter is the
/// optics itself).
///
/// Errors: a filter × QE product with unbounded support (e.g. both constant: the
/// blackbody integral needs a band), or an invalid temperature.
pub fn background_electrons(
    d: &DetectorConfig,
    filter_qe: &Spectrum,
    camera: &CameraEquation,
) -> Result<f64> {
    let Some(b) = &d.background else {
        return Ok(0.0);
    };
    if b.emissivity == 0.0 {
        return Ok(0.0);
    }
    let e = camera
        .electrons_blackbody(b.temperature_k, filter_qe)
        .map_err(|e| {
            Error::param(
                "detector.background",
                format!("{e}"),
                "a filter × quantum efficiency with a bounded band (the background integral needs one)",
            )
        })?;
    Ok(b.emissivity * e)
}

/// Mean signal electrons (without dark and background) of the auto-gain reference scene,
/// and which reference was used:
///
/// - [`AutoGainReference::Blackbody`]: a uniform blackbody at `reference_temperature_k`
///   through the whole spectral chain, `camera_equation.electrons_blackbody(T, response)`
///   (docs/design.md §4.1).
/// - [`AutoGainReference::ReflectedSun`]: a Lambertian reflector of reflectance ρ lit by
///   the Sun at zenith angle θz, `L(λ) = ρ E₀(λ) cos θz / π`, with E₀ the solar spectral
///   irradiance of a 5772 K blackbody filling the solar disc (1361 W m-2 in total; see
///   [`crate::scene::synthetic::solar_spectral_irradiance`]), no atmospheric loss on the
///   way down; FOI report §2.2.2 (sunlight scattered by ground of 10–90 % reflectance).
///
/// Omitted `reference`: reflected sun if the spectral response ends at or below
/// [`REFLECTIVE_LIMIT_UM`], else the blackbody.
pub fn reference_electrons(
    d: &DetectorConfig,
    response: &Spectrum,
    camera: &CameraEquation,
    config: &AutoGainConfig,
) -> Result<(AutoGainReference, f64)> {
    let (lo, hi) = response.support_um();
    let kind = config.reference.unwrap_or(if hi <= REFLECTIVE_LIMIT_UM {
        AutoGainReference::ReflectedSun
    } else {
        AutoGainReference::Blackbody
    });
    let e = match kind {
        // Not known until the scene is imaged; the full well stands in until then.
        AutoGainReference::SceneMean => d.full_well_e,
        AutoGainReference::Blackbody => camera
            .electrons_blackbody(config.reference_temperature_k, response)
            .map_err(|e| {
                Error::param(
                    "detector.auto_gain",
                    format!("{e}"),
                    "a spectral response with a bounded band for the blackbody reference",
                )
            })?,
        AutoGainReference::ReflectedSun => {
            let lo = lo.max(SUN_BAND_UM.0);
            let hi = hi.min(SUN_BAND_UM.1);
            if hi <= lo {
                0.0
            } else {
                let rho = config.reflectance;
                let zenith = config.sun_zenith_deg;
                camera.electrons_spectral(
                    response,
                    |w| rho * solar_spectral_irradiance(w, 1.0, zenith) / std::f64::consts::PI,
                    lo,
                    hi,
                )?
            }
        }
    };
    Ok((kind, e))
}

/// The conversion gain K (DN/e-) that puts `reference_e` electrons (signal + dark +
/// background) at `fraction` of the range above the offset:
/// `K = fraction · (2^bits − 1 − offset_dn) / n(min(e, full well))`, with n the mean
/// quadratic nonlinearity `e + ā e²` (FOI report §2.2.2: half the dynamic range for a
/// 300 K source).
pub(crate) fn gain_for(model: &DetectorModel, fraction: f64, reference_e: f64) -> Result<f64> {
    let a = model
        .nonlinearity
        .as_ref()
        .map_or(0.0, |n| n.quadratic_mean_per_e);
    let e = apply_nonlinearity(clip_full_well(reference_e, model.full_well_e), a);
    if !(e.is_finite() && e > 0.0) {
        return Err(Error::param(
            "detector.auto_gain",
            format!("{e} reference electrons"),
            "a reference scene that gives a positive signal in the sensor's band (check the reference kind, temperature and spectral response)",
        ));
    }
    Ok(fraction * (model.max_dn - model.offset_dn) / e)
}
