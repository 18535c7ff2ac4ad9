//! Stage 4, calibrate (thermal sensors): the way back from DN to in-band radiance and
//! apparent temperature, through the same sensor instance that recorded the scene
//! ([`crate::calibration::Calibration`]).

use crate::calibration::{measured_netd, Calibration, CalibrationOptions};
use crate::error::{Error, Result};
use crate::report::{CalibrationReport, ResidualNonuniformity};
use crate::sensor::Sensor;

use super::expose::Exposure;
use super::FrameProducts;

/// Definition of the radiance product, as the report states it.
const RADIANCE_DEFINITION: &str = "in-band radiance: integral of S(λ) L(λ) dλ / max S, W m-2 sr-1";

/// Offset (K) of the residual non-uniformity check above the middle of the calibration
/// range, so the check temperature is not one of the fitted levels.
const CHECK_OFFSET_K: f64 = 0.37;

/// Temperature (K), step (K) and frames of the NETD figures in the report.
const NETD_AT_K: f64 = 300.0;
const NETD_DELTA_K: f64 = 0.25;
const NETD_FRAMES: usize = 16;

/// What the calibration stage returns: its report, or why it could not calibrate.
#[derive(Debug)]
pub enum CalibrationOutcome {
    /// Not asked for, or the sensor is not thermal.
    Skipped,
    /// Every frame got radiance and temperature.
    Done(Box<CalibrationReport>),
    /// Calibration failed (the frames keep no radiance/temperature); the warning says why.
    Failed(String),
}

impl CalibrationOutcome {
    /// The report section of a successful calibration; a failure's warning is appended to
    /// `warnings`.
    pub fn into_report(self, warnings: &mut Vec<String>) -> Option<CalibrationReport> {
        match self {
            CalibrationOutcome::Done(report) => Some(*report),
            CalibrationOutcome::Failed(warning) => {
                warnings.push(warning);
                None
            }
            CalibrationOutcome::Skipped => None,
        }
    }
}

/// The error for a calibration whose flat fields give no usable pixels: with very few
/// ADC bits (`detector.bits` = 1 or 2) the 280–320 K blackbody levels all quantise to the
/// same DN, so no NUC, radiance or temperature can be derived. Names the setting.
fn calibration_failed(sensor: &Sensor, e: Error) -> Error {
    let bits = sensor.config().detector.bits;
    Error::OutOfRange(format!(
        "the radiometric calibration of `{}` found no usable pixels ({e}); with detector.bits = {} ({} DN levels) the blackbody calibration levels cannot be told apart — use more ADC bits (at least 3 for this sensor), or call the library with RunOptions::calibration = None for DN-only products",
        sensor.config().name,
        bits,
        1u64 << bits.min(63)
    ))
}

/// Calibrates `exposure`'s instance with `options` (when given and the sensor is thermal)
/// and fills `radiance` and `temperature` of every frame.
///
/// Errors: a frame of the wrong shape (cannot happen for frames of this run) or a failure
/// of the residual non-uniformity check.
pub fn calibrate_frames(
    sensor: &Sensor,
    exposure: &Exposure,
    options: Option<&CalibrationOptions>,
    frames: &mut [FrameProducts],
) -> Result<CalibrationOutcome> {
    let Some(opts) = options.filter(|_| sensor.is_thermal()) else {
        return Ok(CalibrationOutcome::Skipped);
    };
    let instance = exposure.instance();
    let cal = match Calibration::new(sensor, exposure.model(), instance, opts) {
        Ok(cal) => cal,
        Err(e) => {
            return Ok(CalibrationOutcome::Failed(format!(
                "no radiance/temperature products: calibration failed: {e}"
            )))
        }
    };
    let mut nan_total = 0;
    for f in frames.iter_mut() {
        let corrected = cal.correct(f.dn.view())?;
        let (t, l, nan) = cal.to_temperature(corrected.view());
        nan_total += nan;
        f.temperature = Some(t.mapv(|v| v as f32));
        f.radiance = Some(l.mapv(|v| v as f32));
    }
    let temps = cal.temperatures_k();
    let t_check = 0.5 * (temps[0] + temps[temps.len() - 1]) + CHECK_OFFSET_K;
    let (raw, corrected) = cal
        .residual_nonuniformity(instance, t_check)
        .map_err(|e| calibration_failed(sensor, e))?;
    let temporal_floor = exposure
        .model()
        .temporal_noise_dn(cal.blackbody_electrons(t_check)?)
        / (opts.frames_per_level.max(1) as f64).sqrt()
        / cal.ideal_dn(t_check);
    Ok(CalibrationOutcome::Done(Box::new(CalibrationReport {
        nuc_degree: opts.degree,
        temperatures_k: temps.to_vec(),
        frames_per_level: opts.frames_per_level,
        bad_pixels: cal.bad_pixels().count(),
        residual_nonuniformity: ResidualNonuniformity {
            at_k: t_check,
            raw,
            corrected,
            temporal_floor,
            measured: "spatial σ/μ of a blackbody flat field averaged over frames_per_level frames, before and after NUC and bad-pixel replacement; temporal_floor = σ_t/(μ√M) is the temporal noise left in that average".to_string(),
        },
        netd_analytic_k_at_300k: cal.netd_analytic_k(NETD_AT_K).ok(),
        netd_measured_k_at_300k: measured_netd(
            sensor,
            instance,
            NETD_AT_K,
            NETD_DELTA_K,
            NETD_FRAMES,
            Some(cal.bad_pixels()),
        )
        .ok(),
        uninvertible_pixels: nan_total,
        radiance_definition: RADIANCE_DEFINITION.to_string(),
    })))
}
