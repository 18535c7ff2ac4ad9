//! What a run reports: the typed [`RunReport`] (written as `report.json`, printed by the
//! CLI), assembled from what the stages return; and figures of merit of the sensor itself
//! (MTF curves and their plots, the response-weighted mean wavelength).
//!
//! The report structs are plain data with `Serialize`; their field names are the JSON keys.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;

use ndarray::Array2;
use serde::Serialize;

use crate::detector::DetectorModel;
use crate::error::{Error, Result};
use crate::imaging::{ImagingStats, Sampling};
use crate::plot::{self, LinePlot, Marker, Series};
use crate::radiometry;
use crate::scene::{CubeMeta, Geometry};
use crate::sensor::Sensor;

/// The report's `focal_plane` section (docs/focal-plane.md).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FocalPlaneReport {
    /// The effects on: `readout_noise`, `ipc`, `rts`, `persistence`, `drift`.
    pub effects: Vec<String>,
    /// Number of RTS pixels (with `[detector.rts]`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rts_pixels: Option<usize>,
    /// The signal the drift figures are for: the first frame's mean, e⁻.
    pub signal_e: f64,
    /// Temporal noise at that signal, e⁻ rms.
    pub temporal_noise_e: f64,
    /// With `[detector.drift]`: per frame, the residual non-uniformity since a two-point
    /// NUC at the sequence start.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub drift: Option<Vec<DriftPoint>>,
}

/// The residual non-uniformity a drifting fixed pattern leaves at one frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DriftPoint {
    /// Time since the NUC (the frame's start), s.
    pub time_since_nuc_s: f64,
    /// Expected spatial σ of the drift since the NUC (the drift model's quadrature sum), e⁻.
    pub residual_nonuniformity_e_expected: f64,
    /// Spatial σ measured on the drift applied to this frame, e⁻.
    pub residual_nonuniformity_e_measured: f64,
    /// NETD at 300 K with the measured residual added in quadrature to the temporal
    /// noise, mK (thermal sensors with a calibration).
    pub netd_with_spatial_noise_mk: Option<f64>,
}

/// Everything one run reports (`report.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunReport {
    /// The preset options chosen (`name = value`).
    pub options: BTreeMap<String, String>,
    /// Lens and system figures of merit.
    pub optics: OpticsReport,
    /// Version of eoir that made the run.
    pub eoir_version: String,
    /// Sensor name.
    pub sensor: String,
    /// Seed of every random effect.
    pub seed: u64,
    /// Whether the run is an unblurred reference: no transfer function in the cascade
    /// and no `[optics.wavefront]` (`eoir run --unblurred`, [`SensorConfig::unblurred`]
    /// of the sensor), so each pixel samples the scene at its centre.
    ///
    /// [`SensorConfig::unblurred`]: crate::sensor::SensorConfig::unblurred
    pub unblurred: bool,
    /// Hash of the resolved sensor ([`crate::calibration::instance::sensor_hash`]); with
    /// the seed it identifies the sensor instance (fixed pattern) of the DN.
    pub sensor_hash: String,
    /// The input cube.
    pub input: InputReport,
    /// How the scene grid maps onto the detector.
    pub sampling: SamplingReport,
    /// The detector model as used (gain after any auto gain).
    pub detector: DetectorReport,
    /// Signal statistics of the first frame.
    pub signal: SignalReport,
    /// Radiometric calibration (thermal sensors); `null` when not done.
    pub calibration: Option<CalibrationReport>,
    /// Warnings collected on the way.
    pub warnings: Vec<String>,
    /// The focal plane's effects beyond the per-pixel chain (readout-ordered noise, IPC,
    /// RTS pixels, persistence, drift); absent when none is on (docs/focal-plane.md).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub focal_plane: Option<FocalPlaneReport>,
    /// The sensor's analytic figures of merit when the run was asked for them
    /// (`eoir run --assess`; the same object as `eoir assess`'s `analytic`,
    /// docs/figures-of-merit.md).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub figures_of_merit: Option<serde_json::Value>,
    /// How `[optics.wavefront]` entered the imaging chain: zones across the field, their
    /// point-source error against direct summation, wavelength nodes (docs/wavefront.md,
    /// "Across the field"); absent without the section.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wavefront_imaging: Option<crate::imaging::space_variant::WavefrontImagingReport>,
    /// How the run was executed (threads, frames imaged at once); like the timings, it
    /// does not change any product.
    pub execution: ExecutionReport,
    /// Wall-clock seconds per stage.
    pub timings_s: Timings,
}

/// `execution` of the report.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ExecutionReport {
    /// Worker threads of the pool the run used.
    pub threads: usize,
    /// Frames of a sequence imaged at the same time (1 = one after another). With more
    /// than one, the stage timings are sums over frames imaged at once: they overlap and
    /// can add up to more than the total.
    pub frames_in_flight: usize,
    /// What set that number (the request, the thread count, the memory budget, the
    /// reader, the frame count).
    pub frames_in_flight_limit: String,
    /// Bytes the run needs with one frame in flight (checked against the memory budget).
    pub run_bytes: u64,
    /// Bytes each further frame in flight adds (its accumulator, row spectra and planes).
    pub frame_bytes_in_flight: u64,
}

/// `optics` of the report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OpticsReport {
    /// Effective focal length, m.
    pub focal_length_m: f64,
    /// F-number.
    pub f_number: f64,
    /// Detector IFOV (pitch / focal length), µrad.
    pub ifov_urad: f64,
    /// Full field of view (horizontal, vertical), degrees.
    pub fov_deg: [f64; 2],
    /// Response-weighted mean wavelength, µm ([`mean_wavelength_um`]).
    pub mean_wavelength_um: Option<f64>,
    /// λ·N/p at the mean wavelength (the Q of the optics–detector match).
    pub lambda_f_number_over_pitch: Option<f64>,
    /// The system transfer function at the detector Nyquist frequency (along x) at the
    /// mean wavelength.
    pub mtf_at_nyquist: Option<f64>,
    /// Names of the enabled transfer-function components, in cascade order.
    pub components: Vec<String>,
}

/// `input` of the report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InputReport {
    /// Where the input came from.
    pub name: String,
    /// Bands in the input.
    pub bands: usize,
    /// Bands with a non-zero weight (read and transformed).
    pub bands_used: usize,
    /// First and last band wavelength, µm.
    pub wavelength_um: [Option<f64>; 2],
    /// Input rows.
    pub rows: usize,
    /// Input columns.
    pub cols: usize,
    /// Frames produced.
    pub frames: usize,
    /// Radiance units of the input.
    pub units: String,
    /// Where the units came from: `override: …`, `stated: <key> = <value>` or
    /// `assumed: <the reader's documented rule>` ([`crate::io::CubeReader::units_source`]).
    pub units_source: String,
    /// Scene field of view (horizontal, vertical), degrees.
    pub fov_deg: [f64; 2],
}

/// `sampling` of the report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SamplingReport {
    /// Detector IFOV, µrad.
    pub detector_ifov_urad: f64,
    /// Scene sample spacing (x, y), µrad.
    pub scene_ifov_urad: [f64; 2],
    /// Scene samples per detector pixel along x.
    pub ratio_x: f64,
    /// Scene samples per detector pixel along y.
    pub ratio_y: f64,
    /// How the detector samples the blurred image.
    pub method: String,
    /// FFT padding before the scene (x, y), scene samples.
    pub pad_px: [usize; 2],
    /// Padded FFT frame (x, y).
    pub padded_shape: [usize; 2],
    /// Wrap-around tolerance that set the padding.
    pub wrap_tolerance: f64,
    /// Precision of the forward FFTs (`"f32"`: f32 transforms, f64 accumulation; `"f64"`).
    pub fft_precision: &'static str,
}

/// `detector` of the report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DetectorReport {
    /// Pixel rows.
    pub rows: usize,
    /// Pixel columns.
    pub cols: usize,
    /// Conversion gain K in use, DN/e-.
    pub gain_dn_per_e: f64,
    /// The auto-gain reference and its signal electrons, when K came from one.
    pub auto_gain_reference: Option<String>,
    /// Black level, DN.
    pub offset_dn: f64,
    /// ADC bits.
    pub bits: u32,
    /// Full well, electrons.
    pub full_well_e: f64,
    /// Mean dark electrons per frame.
    pub dark_e: f64,
    /// Mean optics self-emission electrons per frame.
    pub background_e: f64,
    /// Read noise, electrons rms.
    pub read_noise_e: f64,
    /// Whether shot noise is drawn.
    pub shot_noise: bool,
    /// Whether fixed-pattern noise is on.
    pub fpn: bool,
    /// Whether the nonlinearity is on.
    pub nonlinearity: bool,
    /// Whether defects are on.
    pub defects: bool,
}

/// `signal` of the report (first frame).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SignalReport {
    /// Mean noise-free signal electrons per pixel.
    pub mean_electrons: f64,
    /// Mean DN.
    pub mean_dn: f64,
    /// Pixels at full well or full scale, %.
    pub saturated_percent: f64,
    /// Expected temporal noise at the mean signal, electrons rms.
    pub temporal_noise_e: f64,
    /// mean_electrons / temporal_noise_e (`null` for a noiseless sensor).
    pub snr: f64,
}

/// `calibration` of the report (thermal sensors).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CalibrationReport {
    /// Degree of the per-pixel NUC polynomial.
    pub nuc_degree: usize,
    /// Blackbody temperatures of the calibration levels, K.
    pub temperatures_k: Vec<f64>,
    /// Frames averaged per level.
    pub frames_per_level: usize,
    /// Pixels flagged bad.
    pub bad_pixels: usize,
    /// Residual non-uniformity of a flat field between the levels.
    pub residual_nonuniformity: ResidualNonuniformity,
    /// Analytic NETD at 300 K, K.
    pub netd_analytic_k_at_300k: Option<f64>,
    /// NETD measured from simulated frame stacks at 300 K, K.
    pub netd_measured_k_at_300k: Option<f64>,
    /// Pixels of all frames that could not be inverted to a temperature (NaN).
    pub uninvertible_pixels: usize,
    /// What "radiance" means in the products.
    pub radiance_definition: String,
}

/// σ/mean of a flat field at `at_k`, raw and after NUC.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResidualNonuniformity {
    /// Flat-field temperature, K.
    pub at_k: f64,
    /// Raw σ/mean.
    pub raw: f64,
    /// σ/mean after NUC.
    pub corrected: f64,
    /// The temporal noise left in the frame average, σ_t / (μ √M): the floor under both
    /// values (without fixed pattern the raw value sits on it, and the NUC adds its own
    /// fit noise).
    pub temporal_floor: f64,
    /// What is measured, in words.
    pub measured: String,
}

/// `timings_s` of the report, seconds.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Timings {
    /// Preparing the imaging chain (spectral weights, padding, frequency grid, the
    /// wavelength-independent transfer function on the grid, component tables, FFT plans).
    pub setup: f64,
    /// Reading bands.
    pub read: f64,
    /// Forward FFTs.
    pub forward_fft: f64,
    /// OTF evaluation and accumulation.
    pub otf_and_accumulate: f64,
    /// Inverse FFT and sampling.
    pub inverse_and_sampling: f64,
    /// Detector (electrons → DN).
    pub detector: f64,
    /// Calibration and the way back.
    pub calibration: f64,
    /// The whole run.
    pub total: f64,
}

/// What the stages of a run hand to [`RunReport::assemble`].
#[derive(Debug)]
pub struct RunFacts<'a> {
    /// The sensor.
    pub sensor: &'a Sensor,
    /// The detector model as exposed (K fixed).
    pub model: &'a DetectorModel,
    /// Seed of the run.
    pub seed: u64,
    /// Input name.
    pub input_name: &'a str,
    /// Input metadata.
    pub meta: &'a CubeMeta,
    /// Scene field of view used.
    pub geometry: &'a Geometry,
    /// Frames produced.
    pub frames: usize,
    /// Bands used by the imaging stage (summed over colour channels).
    pub bands_used: usize,
    /// Scene → detector sampling.
    pub sampling: &'a Sampling,
    /// Imaging timings and padded shape.
    pub imaging: &'a ImagingStats,
    /// Wrap-around tolerance of the run.
    pub wrap_tolerance: f64,
    /// Mean electrons of the first frame.
    pub first_electrons: &'a Array2<f32>,
    /// DN of the first frame.
    pub first_dn: &'a Array2<u16>,
    /// The calibration stage's report.
    pub calibration: Option<CalibrationReport>,
    /// Warnings collected.
    pub warnings: Vec<String>,
    /// Seconds preparing the imaging chain.
    pub setup_s: f64,
    /// Seconds in the detector stage.
    pub detector_s: f64,
    /// Seconds in the calibration stage.
    pub calibration_s: f64,
    /// Seconds of the whole run.
    pub total_s: f64,
    /// Threads and frames in flight.
    pub execution: ExecutionReport,
}

/// Share of a frame's pixels (percent) above which a run warns that it saturates: 1 %.
pub const SATURATION_WARNING_PERCENT: f64 = 1.0;

/// The warning for a frame with more than [`SATURATION_WARNING_PERCENT`] of its pixels
/// saturated (mean electrons at the full well, or DN at the ADC maximum), naming the
/// remedy for each kind: at the ADC ceiling under auto gain, `detector.auto_gain.fraction`
/// (the auto gain rescales K, so a shorter integration time changes nothing there); at
/// the ADC ceiling with a fixed gain, `detector.gain_dn_per_e` or the integration time;
/// at the full well, `detector.integration_time_s` (or the F-number), whatever the gain.
/// `None` below the threshold.
pub fn saturation_warning(
    sensor: &Sensor,
    electrons: &Array2<f32>,
    dn: &Array2<u16>,
) -> Option<String> {
    let d = &sensor.detector;
    let n = dn.len().max(1) as f64;
    let (mut well, mut adc, mut any) = (0usize, 0usize, 0usize);
    for (e, v) in electrons.iter().zip(dn.iter()) {
        let at_well = *e as f64 >= d.full_well_e;
        let at_adc = *v as f64 >= d.max_dn();
        well += at_well as usize;
        adc += at_adc as usize;
        any += (at_well || at_adc) as usize;
    }
    let percent = 100.0 * any as f64 / n;
    if percent <= SATURATION_WARNING_PERCENT {
        return None;
    }
    let mut remedies = Vec::new();
    if adc > 0 {
        match &d.auto_gain {
            Some(a) => {
                use crate::detector::config::AutoGainReference as R;
                // The second remedy is the reference the gain is set from.
                let raise = match a.reference {
                    Some(R::SceneMean) => "",
                    Some(R::ReflectedSun) => " or raise `detector.auto_gain.reflectance`",
                    _ => " or raise `detector.auto_gain.reference_temperature_k`",
                };
                remedies.push(format!(
                    "{:.2} % at the ADC maximum ({} DN): lower `detector.auto_gain.fraction` (now {}){raise} — the auto gain rescales K, so a shorter integration time does not help there",
                    100.0 * adc as f64 / n,
                    d.max_dn(),
                    a.fraction
                ))
            }
            None => remedies.push(format!(
                "{:.2} % at the ADC maximum ({} DN): lower `detector.gain_dn_per_e` or shorten `detector.integration_time_s` (now {} s)",
                100.0 * adc as f64 / n,
                d.max_dn(),
                d.integration_time_s
            )),
        }
    }
    if well > 0 {
        remedies.push(format!(
            "{:.2} % at the full well ({} e-): shorten `detector.integration_time_s` (now {} s) or raise `optics.f_number`",
            100.0 * well as f64 / n,
            d.full_well_e,
            d.integration_time_s
        ));
    }
    Some(format!(
        "{percent:.2} % of the pixels are saturated (more than {SATURATION_WARNING_PERCENT} %): {}",
        remedies.join("; ")
    ))
}

impl RunReport {
    /// Assembles the report from what the stages returned. The signal statistics are
    /// measured on the first frame: a pixel counts as saturated when its mean electrons
    /// reach the full well or its DN the ADC maximum; the temporal noise is
    /// [`DetectorModel::temporal_noise_e`] at the mean signal.
    pub fn assemble(f: RunFacts) -> RunReport {
        let sensor = f.sensor;
        let d = &sensor.detector;
        let n_px = f.first_dn.len() as f64;
        let saturated = f
            .first_electrons
            .iter()
            .zip(f.first_dn.iter())
            .filter(|(e, dn)| **e as f64 >= d.full_well_e || **dn as f64 >= d.max_dn())
            .count() as f64;
        let mean_e = f.first_electrons.iter().map(|v| *v as f64).sum::<f64>() / n_px;
        let noise_e = f.model.temporal_noise_e(mean_e);
        let mean_dn = f.first_dn.iter().map(|v| *v as f64).sum::<f64>() / n_px;
        let s = f.sampling;
        let lambda_mean = mean_wavelength_um(sensor).ok();
        let otf = sensor.otf();
        let (fov_x, fov_y) = sensor.fov_deg();
        RunReport {
            options: sensor.selected_options.clone(),
            optics: OpticsReport {
                focal_length_m: sensor.optics.focal_length_m,
                f_number: sensor.optics.f_number,
                ifov_urad: sensor.ifov_rad() * 1e6,
                fov_deg: [fov_x, fov_y],
                mean_wavelength_um: lambda_mean,
                lambda_f_number_over_pitch: lambda_mean
                    .map(|l| l * 1e-6 * sensor.optics.f_number / d.pitch_m),
                mtf_at_nyquist: lambda_mean
                    .map(|l| otf.evaluate(sensor.nyquist_cy_per_rad(), 0.0, l)),
                components: otf
                    .components()
                    .iter()
                    .map(|c| c.name().to_string())
                    .collect(),
            },
            eoir_version: env!("CARGO_PKG_VERSION").to_string(),
            sensor: sensor.name.clone(),
            seed: f.seed,
            unblurred: otf.components().is_empty() && sensor.optics.wavefront.is_none(),
            sensor_hash: crate::calibration::instance::sensor_hash(sensor).unwrap_or_default(),
            input: InputReport {
                name: f.input_name.to_string(),
                bands: f.meta.bands(),
                bands_used: f.bands_used,
                wavelength_um: [
                    f.meta.wavelength_um.first().copied(),
                    f.meta.wavelength_um.last().copied(),
                ],
                rows: f.meta.rows,
                cols: f.meta.cols,
                frames: f.frames,
                units: f.meta.units.as_str().to_string(),
                units_source: String::new(),
                fov_deg: [f.geometry.fov_x_deg, f.geometry.fov_y_deg],
            },
            sampling: SamplingReport {
                detector_ifov_urad: sensor.ifov_rad() * 1e6,
                scene_ifov_urad: [s.scene_ifov_rad.1 * 1e6, s.scene_ifov_rad.0 * 1e6],
                ratio_x: s.x.ratio,
                ratio_y: s.y.ratio,
                method: if s.integer {
                    "integer decimation (phase-ramp centring, point sampling)"
                } else {
                    "band-limited resampling (trigonometric interpolation)"
                }
                .to_string(),
                pad_px: [s.x.pad_before, s.y.pad_before],
                padded_shape: [f.imaging.padded_shape.1, f.imaging.padded_shape.0],
                wrap_tolerance: f.wrap_tolerance,
                fft_precision: f.imaging.precision.as_str(),
            },
            detector: DetectorReport {
                rows: d.rows,
                cols: d.cols,
                gain_dn_per_e: f.model.gain_dn_per_e(),
                auto_gain_reference: f
                    .model
                    .auto_gain_reference()
                    .map(|(r, e)| auto_gain_text(r, e, d.auto_gain.as_ref())),
                offset_dn: d.offset_dn,
                bits: d.bits,
                full_well_e: d.full_well_e,
                dark_e: f.model.dark_e(),
                background_e: f.model.background_e(),
                read_noise_e: f.model.read_noise_e(),
                shot_noise: f.model.shot_noise(),
                fpn: d.fpn.is_some(),
                nonlinearity: d.nonlinearity.is_some(),
                defects: d.defects.is_some(),
            },
            signal: SignalReport {
                mean_electrons: mean_e,
                mean_dn,
                saturated_percent: 100.0 * saturated / n_px,
                temporal_noise_e: noise_e,
                snr: if noise_e > 0.0 {
                    mean_e / noise_e
                } else {
                    f64::INFINITY
                },
            },
            calibration: f.calibration,
            warnings: f.warnings,
            focal_plane: None,
            figures_of_merit: None,
            wavefront_imaging: f.imaging.wavefront.as_deref().cloned(),
            execution: f.execution,
            timings_s: Timings {
                read: f.imaging.read_s,
                forward_fft: f.imaging.fft_s,
                otf_and_accumulate: f.imaging.otf_s,
                inverse_and_sampling: f.imaging.inverse_s,
                setup: f.setup_s,
                detector: f.detector_s,
                calibration: f.calibration_s,
                total: f.total_s,
            },
        }
    }

    /// The report as pretty-printed JSON (non-finite numbers become `null`).
    pub fn to_json_pretty(&self) -> Result<String> {
        serde_json::to_string_pretty(self)
            .map_err(|e| Error::param("report", "not serialisable", e.to_string()))
    }
}

/// The auto-gain reference as a person reads it: which reference, its conditions, its
/// electrons (4 significant figures) and the fraction of full scale it was set to, e.g.
/// `Blackbody at 300 K: 3.668e6 e⁻ at 50 % of full scale`. Starts with the reference's name.
fn auto_gain_text(
    kind: crate::detector::AutoGainReference,
    electrons: f64,
    config: Option<&crate::detector::AutoGainConfig>,
) -> String {
    use crate::detector::AutoGainReference as R;
    let e = plot::significant(electrons, 4);
    let Some(c) = config else {
        return format!("{kind:?}: {e} e⁻");
    };
    let fraction = plot::significant(100.0 * c.fraction, 3);
    match kind {
        R::Blackbody => format!(
            "Blackbody at {} K: {e} e⁻ at {fraction} % of full scale",
            plot::significant(c.reference_temperature_k, 4)
        ),
        R::ReflectedSun => format!(
            "ReflectedSun (reflectance {}, sun zenith {}°): {e} e⁻ at {fraction} % of full scale",
            plot::significant(c.reflectance, 3),
            plot::significant(c.sun_zenith_deg, 3)
        ),
        R::SceneMean => format!("SceneMean: {e} e⁻ at {fraction} % of full scale"),
    }
}

/// MTF curves along the x (column) frequency axis: one per enabled component and the
/// system product, at one wavelength.
#[derive(Debug, Clone, PartialEq)]
pub struct MtfCurves {
    /// Wavelength the curves are evaluated at, µm.
    pub wavelength_um: f64,
    /// Angular frequencies, cycles/mrad.
    pub freq_cy_per_mrad: Vec<f64>,
    /// (component name, transfer-function values), in cascade order, then `system` last.
    /// Values are the signed transfer function (the sign shows contrast reversal).
    pub columns: Vec<(String, Vec<f64>)>,
    /// Detector Nyquist frequency, cycles/mrad.
    pub nyquist_cy_per_mrad: f64,
    /// Diffraction cutoff D/λ, cycles/mrad.
    pub cutoff_cy_per_mrad: f64,
    /// The system transfer function at the detector Nyquist frequency (along x).
    pub system_at_nyquist: f64,
}

impl MtfCurves {
    /// Evaluates every enabled component of `sensor` along fx at `points` frequencies from
    /// 0 to `max_cy_per_mrad` (default: the larger of the optical cutoff and twice the
    /// detector Nyquist).
    pub fn compute(
        sensor: &Sensor,
        wavelength_um: f64,
        max_cy_per_mrad: Option<f64>,
        points: usize,
    ) -> Result<Self> {
        if !(wavelength_um.is_finite() && wavelength_um > 0.0) {
            return Err(Error::param(
                "--wavelength-um",
                wavelength_um,
                "a wavelength > 0 µm",
            ));
        }
        if points < 2 {
            return Err(Error::param("--points", points, "at least 2"));
        }
        let otf = sensor.otf();
        let nyquist = sensor.nyquist_cy_per_rad() * 1e-3;
        let cutoff = otf.cutoff_cy_per_rad(wavelength_um) * 1e-3;
        let f_max = match max_cy_per_mrad {
            Some(f) if f.is_finite() && f > 0.0 => f,
            Some(f) => return Err(Error::param("--max-cy-per-mrad", f, "a frequency > 0")),
            None => cutoff.max(2.0 * nyquist),
        };
        let freq: Vec<f64> = (0..points)
            .map(|i| f_max * i as f64 / (points - 1) as f64)
            .collect();
        let mut columns: Vec<(String, Vec<f64>)> = otf
            .components()
            .iter()
            .map(|c| {
                let v = freq
                    .iter()
                    .map(|f| otf.component(*c, f * 1e3, 0.0, wavelength_um))
                    .collect();
                (c.name().to_string(), v)
            })
            .collect();
        let system = freq
            .iter()
            .map(|f| otf.evaluate(f * 1e3, 0.0, wavelength_um))
            .collect();
        columns.push(("system".to_string(), system));
        let system_at_nyquist = otf.evaluate(sensor.nyquist_cy_per_rad(), 0.0, wavelength_um);
        Ok(MtfCurves {
            system_at_nyquist,
            wavelength_um,
            freq_cy_per_mrad: freq,
            columns,
            nyquist_cy_per_mrad: nyquist,
            cutoff_cy_per_mrad: cutoff,
        })
    }

    /// Writes the curves as CSV: `freq_cy_per_mrad`, one column per component, `system`.
    pub fn write_csv(&self, path: &Path) -> Result<()> {
        let text = self.csv_text();
        crate::io::atomic_write(path, |w| {
            w.write_all(text.as_bytes()).map_err(|e| Error::io(path, e))
        })
    }

    /// The CSV text [`MtfCurves::write_csv`] writes (for `--csv -`, standard output).
    pub fn csv_text(&self) -> String {
        let mut text = String::from("freq_cy_per_mrad");
        for (name, _) in &self.columns {
            text.push(',');
            text.push_str(name);
        }
        text.push('\n');
        for (i, f) in self.freq_cy_per_mrad.iter().enumerate() {
            text.push_str(&format!("{f:.6}"));
            for (_, v) in &self.columns {
                text.push_str(&format!(",{:.8}", v[i]));
            }
            text.push('\n');
        }
        text
    }

    /// Plots the curves as a PNG with the detector Nyquist frequency marked.
    pub fn write_png(&self, path: &Path, sensor_name: &str) -> Result<()> {
        let bytes = self.render_png(sensor_name)?;
        crate::display::write_png_bytes(path, &bytes)
    }

    /// The plot of [`MtfCurves::write_png`] as PNG bytes.
    pub fn render_png(&self, sensor_name: &str) -> Result<Vec<u8>> {
        let title = format!(
            "{sensor_name}: transfer functions at {:.3} µm",
            self.wavelength_um
        );
        let series = self
            .columns
            .iter()
            .map(|(name, v)| Series {
                label: name,
                x: &self.freq_cy_per_mrad,
                y: v,
            })
            .collect();
        let y_min = self
            .columns
            .iter()
            .flat_map(|(_, v)| v.iter().copied())
            .fold(0.0f64, f64::min);
        plot::render_line_plot(&LinePlot {
            title: &title,
            x_label: "spatial frequency (cycles/mrad)",
            y_label: "transfer function",
            series,
            markers: vec![Marker {
                label: "Nyquist",
                x: self.nyquist_cy_per_mrad,
            }],
            y_range: Some((y_min.min(0.0) - 0.02, 1.05)),
            size_px: (900, 600),
        })
    }
}

/// The response-weighted mean wavelength of a sensor, ∫λ S dλ / ∫S dλ over the support of
/// its spectral response S (µm): the default wavelength for single-wavelength reports.
pub fn mean_wavelength_um(sensor: &Sensor) -> Result<f64> {
    let s = sensor.response();
    let (lo, hi) = s.support_um();
    if !(lo.is_finite() && hi.is_finite() && hi > lo) {
        return Err(Error::param(
            "spectral response",
            format!("support [{lo}, {hi}] µm"),
            "a bounded band (give a [filter] or a QE with a cutoff), or pass --wavelength-um",
        ));
    }
    let bp = s.breakpoints_um();
    let num = radiometry::integrate(|l| l * s.eval(l), lo, hi, &bp, 1e-9);
    let den = radiometry::integrate(|l| s.eval(l), lo, hi, &bp, 1e-9);
    if den <= 0.0 {
        return Err(Error::param(
            "spectral response",
            "zero everywhere",
            "a response with some non-zero transmission and quantum efficiency",
        ));
    }
    Ok(num / den)
}
