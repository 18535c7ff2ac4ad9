//! Stage 4, calibrate (thermal sensors): the way back from DN to in-band radiance and
//! apparent temperature, through the same sensor instance that recorded the scene
//! ([`crate::calibration::Calibration`]).

use crate::calibration::{measured_netd_sampled, Calibration, CalibrationOptions, NetdSample};
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

/// Temperature (K) and step (K) of the NETD figures in the report.
const NETD_AT_K: f64 = 300.0;
const NETD_DELTA_K: f64 = 0.25;

/// Wanted relative standard error of the measured NETD.
const NETD_RELATIVE_PRECISION: f64 = 0.005;

/// Most frames per temperature of the measured NETD.
const NETD_MAX_FRAMES: usize = 16;

/// The frames and rows of the report's measured NETD for a `rows × cols` detector: the
/// cheapest sample reaching `NETD_RELATIVE_PRECISION` ([`NetdSample::for_precision`]:
/// 2 frames of 55 evenly spaced rows of a 384 × 288 array; every row and 5 frames of a
/// 64 × 80 one), at most `NETD_MAX_FRAMES` frames.
///
/// Errors: an empty detector.
pub fn netd_sample(rows: usize, cols: usize) -> Result<NetdSample> {
    NetdSample::for_precision(rows, cols, NETD_RELATIVE_PRECISION, NETD_MAX_FRAMES)
}

/// Frames per temperature of the measured NETD of an array of `pixels` pixels (in one
/// row), for a progress estimate in frame exposures ([`netd_sample`] gives the rows too).
pub fn netd_frames(pixels: usize) -> usize {
    netd_sample(1, pixels.max(1)).map_or(2, |s| s.frames)
}

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

/// Start of the warning of a failed calibration (what [`missing_temperature`] reports).
pub const FAILURE_PREFIX: &str = "no radiance/temperature products: ";

/// ADC resolutions (bits) at or below which a failed calibration names `detector.bits`.
const FEW_BITS: u32 = 4;

/// The warning for a calibration that failed with `e`: the reason, and with very few ADC
/// bits (`detector.bits` ≤ 4) the hint that the blackbody levels quantise to a handful of
/// DN and cannot be told apart.
fn failure_warning(sensor: &Sensor, e: &Error) -> String {
    let bits = sensor.config().detector.bits;
    let hint = if bits <= FEW_BITS {
        format!(
            "; with detector.bits = {bits} ({} DN levels) the blackbody calibration levels cannot be told apart — use more ADC bits",
            1u64 << bits.min(63)
        )
    } else {
        String::new()
    };
    format!(
        "{FAILURE_PREFIX}the radiometric calibration of `{}` failed: {e}{hint}",
        sensor.config().name
    )
}

/// Why a run of a thermal sensor has no temperature products (the calibration failure's
/// reason), or `None` when every frame has them or the sensor is not thermal: for the
/// prominent summary line and `--require-temperature`.
pub fn missing_temperature(sensor: &Sensor, out: &super::RunOutput) -> Option<String> {
    if !sensor.is_thermal() || out.frames.iter().all(|f| f.temperature.is_some()) {
        return None;
    }
    Some(failure_reason(&out.warnings))
}

/// [`missing_temperature`] of a run summary (e.g. of a [`super::StreamedRun`]): a run's
/// frames are calibrated all or none, so frame 0 tells.
pub fn missing_temperature_of(sensor: &Sensor, run: &super::RunSummary) -> Option<String> {
    if !sensor.is_thermal() || run.first.temperature.is_some() {
        return None;
    }
    Some(failure_reason(run.warnings))
}

/// The calibration failure's reason among `warnings`.
fn failure_reason(warnings: &[String]) -> String {
    warnings
        .iter()
        .find_map(|w| w.strip_prefix(FAILURE_PREFIX))
        .unwrap_or("the radiometric calibration was not run")
        .to_string()
}

/// Calibrates `exposure`'s instance with `options` (when given and the sensor is thermal)
/// and fills `radiance` and `temperature` of every frame: [`FrameCalibration`] made once,
/// applied to each frame, finished.
///
/// A calibration that cannot be made (no usable range, clipped levels, too few ADC bits,
/// no usable pixels) is [`CalibrationOutcome::Failed`] with the reason: the DN products
/// are still made.
///
/// Errors: a frame of the wrong shape (cannot happen for frames of this run).
pub fn calibrate_frames(
    sensor: &Sensor,
    exposure: &Exposure,
    options: Option<&CalibrationOptions>,
    frames: &mut [FrameProducts],
) -> Result<CalibrationOutcome> {
    let mut calibration = FrameCalibration::new(sensor, exposure, options);
    for f in frames.iter_mut() {
        calibration.apply(f)?;
    }
    calibration.finish(sensor, exposure)
}

/// The radiometric calibration of a run as its frames stream past: made once, as soon as
/// the exposure stage exists (the first frame's mean image fixed the gain; the sensor
/// instance does not change from frame to frame, so a calibration made then is the one
/// made after the last frame), applied to each frame as it is exposed (so no frame has to
/// wait for the whole sequence), and finished with the report's checks (residual
/// non-uniformity, measured NETD) once every frame passed.
#[derive(Debug)]
pub enum FrameCalibration {
    /// Not asked for, or the sensor is not thermal.
    Skipped,
    /// The calibration could not be made; the warning says why.
    Failed(String),
    /// Calibrated: frames get radiance and temperature.
    Ready {
        /// The calibration of the run's instance.
        cal: Box<Calibration>,
        /// Its options.
        options: CalibrationOptions,
        /// Pixels that could not be inverted, summed over the frames so far.
        uninvertible: usize,
    },
}

impl FrameCalibration {
    /// Calibrates `exposure`'s instance with `options` when given and the sensor is thermal.
    pub fn new(sensor: &Sensor, exposure: &Exposure, options: Option<&CalibrationOptions>) -> Self {
        let Some(opts) = options.filter(|_| sensor.is_thermal()) else {
            return FrameCalibration::Skipped;
        };
        match Calibration::new(sensor, exposure.model(), exposure.instance(), opts) {
            Ok(cal) => FrameCalibration::Ready {
                cal: Box::new(cal),
                options: opts.clone(),
                uninvertible: 0,
            },
            Err(e) => FrameCalibration::Failed(failure_warning(sensor, &e)),
        }
    }

    /// Fills `frame`'s radiance and temperature from its DN (nothing when not calibrated).
    ///
    /// Errors: a frame of another shape than the detector.
    pub fn apply(&mut self, frame: &mut FrameProducts) -> Result<()> {
        if let FrameCalibration::Ready {
            cal, uninvertible, ..
        } = self
        {
            let corrected = cal.correct(frame.dn.view())?;
            let (t, l, nan) = cal.to_temperature_f32(corrected.view());
            *uninvertible += nan;
            frame.temperature = Some(t);
            frame.radiance = Some(l);
        }
        Ok(())
    }

    /// The outcome once every frame was applied: the residual non-uniformity check and the
    /// measured NETD (independent and each deterministic: side by side on the worker pool).
    pub fn finish(self, sensor: &Sensor, exposure: &Exposure) -> Result<CalibrationOutcome> {
        let (cal, opts, nan_total) = match self {
            FrameCalibration::Skipped => return Ok(CalibrationOutcome::Skipped),
            FrameCalibration::Failed(w) => return Ok(CalibrationOutcome::Failed(w)),
            FrameCalibration::Ready {
                cal,
                options,
                uninvertible,
            } => (cal, options, uninvertible),
        };
        let instance = exposure.instance();
        let temps = cal.temperatures_k();
        let lo = temps.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = temps.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let t_check = 0.5 * (lo + hi) + CHECK_OFFSET_K;
        let (rnu, netd_measured) = rayon::join(
            || cal.residual_nonuniformity(instance, t_check),
            || {
                netd_sample(exposure.model().rows(), exposure.model().cols())
                    .and_then(|sample| {
                        measured_netd_sampled(
                            sensor,
                            instance,
                            NETD_AT_K,
                            NETD_DELTA_K,
                            &sample,
                            Some(cal.bad_pixels()),
                        )
                    })
                    .ok()
            },
        );
        let (raw, corrected) = match rnu {
            Ok(r) => r,
            Err(e) => return Ok(CalibrationOutcome::Failed(failure_warning(sensor, &e))),
        };
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
            netd_measured_k_at_300k: netd_measured,
            uninvertible_pixels: nan_total,
            radiance_definition: RADIANCE_DEFINITION.to_string(),
        })))
    }
}
