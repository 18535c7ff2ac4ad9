//! The whole chain in one place, top to bottom: input cube → spectral weights and
//! transfer functions → mean electrons on the detector → detector → DN → products.
//!
//! ```text
//! read      io::open(path)                       CubeReader (band by band)
//! image     imaging::Imager::mean_electrons       mean photo-electrons per pixel
//! detect    detector::DetectorInstance::expose    dark, shot noise, full well, FPN,
//!                                                 nonlinearity, read noise, K, ADC, defects
//! write     RunOutput::write                      dn.tiff/png, electrons_mean.tiff, config, report
//! ```

use std::path::{Path, PathBuf};
use std::time::Instant;

use ndarray::Array2;
use serde_json::json;

use crate::calibration::{Calibration, CalibrationOptions};
use crate::detector::{DetectorInstance, DetectorModel};
use crate::error::{Error, Result};
use crate::imaging::{Imager, ImagingStats, DEFAULT_WRAP_TOLERANCE};
use crate::io::{raster, CubeReader};
use crate::scene::Geometry;
use crate::sensor::SensorConfig;

/// Options of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunOptions {
    /// Seed for every random effect (noise, fixed pattern, defects).
    pub seed: u64,
    /// Field of view to use when the input does not carry one (or to override it).
    pub geometry: Option<Geometry>,
    /// Wrap-around tolerance that sets the FFT padding (see [`crate::imaging::pad_width`]).
    pub wrap_tolerance: f64,
    /// Where the input came from (for the report).
    pub input_name: String,
    /// Number of frames to expose of a single-frame (static) input: the mean image is
    /// formed once and exposed `frames` times (fixed pattern identical, temporal noise
    /// independent). Ignored for a multi-frame input.
    pub frames: usize,
    /// Radiometric calibration for thermal sensors (response beyond 3 µm): NUC fitted on
    /// blackbody frames through the same sensor instance, then DN → in-band radiance →
    /// apparent temperature. `None` skips it.
    pub calibration: Option<CalibrationOptions>,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            seed: 1,
            geometry: None,
            wrap_tolerance: DEFAULT_WRAP_TOLERANCE,
            input_name: String::from("memory"),
            frames: 1,
            calibration: Some(CalibrationOptions::default()),
        }
    }
}

/// The products of one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameProducts {
    /// Noise-free expected photo-electrons per pixel (the ground truth).
    pub electrons_mean: Array2<f32>,
    /// Digital numbers (for a colour-filter-array sensor: the raw mosaic).
    pub dn: Array2<u16>,
    /// For a colour-filter-array sensor: the demosaicked (Malvar–He–Cutler), black-level
    /// subtracted, sunlight white-balanced colour image, `[row, col, 3]`, with the 99.5th
    /// percentile at 255 (one scale, so grey stays grey).
    pub rgb: Option<ndarray::Array3<u8>>,
    /// Thermal sensors: in-band radiance (W m-2 sr-1, response-weighted, normalised to peak
    /// response 1) after NUC and bad-pixel replacement; NaN where it cannot be inverted.
    pub radiance: Option<Array2<f32>>,
    /// Thermal sensors: apparent (blackbody-equivalent) temperature, K; NaN outside the
    /// calibrated range.
    pub temperature: Option<Array2<f32>>,
}

/// Everything a run produced.
#[derive(Debug, Clone)]
pub struct RunOutput {
    /// One entry per frame.
    pub frames: Vec<FrameProducts>,
    /// The sensor as resolved (written as `config.toml`).
    pub sensor: SensorConfig,
    /// Figures of merit, input summary and timings (written as `report.json`).
    pub report: serde_json::Value,
    /// Warnings collected on the way.
    pub warnings: Vec<String>,
}

/// A false-colour composite of runs of the channels of one camera (3-CCD, three-band): the
/// channels are ordered by their response-weighted mean wavelength and the longest goes to
/// red, the middle to green, the shortest to blue (so near-IR-bright vegetation is red, as
/// in a colour-infrared photograph). Each channel's DN image is stretched between
/// its own 0.5 and 99.5 percentiles. Returns `[row, col, 3]` bytes.
pub fn false_colour_composite(channels: &[(f64, &RunOutput)]) -> Result<ndarray::Array3<u8>> {
    if channels.len() != 3 {
        return Err(Error::param(
            "composite channels",
            channels.len(),
            "exactly 3 channel runs",
        ));
    }
    let mut order: Vec<&(f64, &RunOutput)> = channels.iter().collect();
    order.sort_by(|a, b| b.0.total_cmp(&a.0));
    let planes: Vec<Array2<f64>> = order
        .iter()
        .map(|(_, out)| out.frames[0].dn.mapv(|v| v as f64))
        .collect();
    crate::cfa::false_colour([planes[0].view(), planes[1].view(), planes[2].view()], 0.5)
}

/// Whether the sensor sees thermal emission (its response reaches beyond 3 µm), so that
/// apparent temperature is a meaningful product.
pub fn is_thermal(sensor: &SensorConfig) -> bool {
    sensor
        .spectral_response()
        .map(|s| s.support_um().1 > 3.0)
        .unwrap_or(false)
}

/// A `[3, rows, cols]` linear colour image as display bytes `[rows, cols, 3]`: zero stays
/// black and the 99.5th percentile of all channels maps to 255 (one scale for all three, so
/// channel ratios — grey — are kept).
fn display_rgb(planes: &ndarray::Array3<f64>) -> ndarray::Array3<u8> {
    let mut all: Vec<f64> = planes.iter().copied().filter(|v| v.is_finite()).collect();
    all.sort_by(f64::total_cmp);
    let white = all
        .get(((all.len().max(1) - 1) as f64 * 0.995) as usize)
        .copied()
        .filter(|w| *w > 0.0)
        .unwrap_or(1.0);
    let (_, rows, cols) = planes.dim();
    ndarray::Array3::from_shape_fn((rows, cols, 3), |(r, c, k)| {
        (planes[[k, r, c]] / white * 255.0)
            .round()
            .clamp(0.0, 255.0) as u8
    })
}

/// White-balance gains of the colour channels of a colour-filter-array sensor (all 1 for a
/// single channel): each channel is scaled so that a spectrally grey surface lit by the sun
/// (radiance shaped like a 5772 K blackbody) gives the same signal as in green.
fn white_balance(channels: &[SensorConfig]) -> Result<Vec<f64>> {
    if channels.len() != 3 {
        return Ok(vec![1.0; channels.len()]);
    }
    let mut e = Vec::with_capacity(3);
    for s in channels {
        let resp = s.spectral_response()?;
        let (lo, hi) = resp.support_um();
        let sun = |l: f64| crate::radiometry::planck_spectral_radiance(l, 5772.0);
        e.push(
            s.camera_equation()?
                .electrons_spectral(&resp, sun, lo, hi.min(50.0))?,
        );
    }
    Ok(e.iter()
        .map(|v| if *v > 0.0 { e[1] / v } else { 1.0 })
        .collect())
}

/// The error for a calibration whose flat fields give no usable pixels: with very few
/// ADC bits (`detector.bits` = 1 or 2) the 280–320 K blackbody levels all quantise to the
/// same DN, so no NUC, radiance or temperature can be derived. Names the setting.
fn calibration_failed(sensor: &SensorConfig, e: Error) -> Error {
    Error::OutOfRange(format!(
        "the radiometric calibration of `{}` found no usable pixels ({e}); with detector.bits = {} ({} DN levels) the blackbody calibration levels cannot be told apart — use more ADC bits (at least 3 for this sensor), or call the library with RunOptions::calibration = None for DN-only products",
        sensor.name,
        sensor.detector.bits,
        1u64 << sensor.detector.bits.min(63)
    ))
}

/// Runs the chain on every frame of `reader`. Nothing is written: call
/// [`RunOutput::write`]. `progress(done, total)` is called after each band of each frame.
pub fn run(
    sensor: &SensorConfig,
    reader: &mut dyn CubeReader,
    options: &RunOptions,
    mut progress: impl FnMut(usize, usize),
) -> Result<RunOutput> {
    let t_start = Instant::now();
    let mut detector_s = 0.0;
    let meta = reader.meta().clone();
    let geometry = options.geometry.or(meta.geometry).ok_or_else(|| {
        Error::param(
            "input field of view",
            "missing",
            "a field of view: pass --fov-deg H,V, or put `eoir fov deg = {H, V}` in the ENVI header / `fov_deg` in the NPY sidecar",
        )
    })?;
    // A geometry given in code or on the command line gets the same checks as a file's.
    crate::scene::CubeMeta {
        geometry: Some(geometry),
        ..meta.clone()
    }
    .validate("the run's geometry (--fov-deg / RunOptions::geometry)")?;
    let mut warnings = reader.warnings();
    warnings.extend(sensor.warnings());
    // A colour-filter-array sensor is imaged once per filter colour (each through its own
    // spectral response) and the three mean images are mosaicked before the detector.
    let channel_sensors: Vec<SensorConfig> = match &sensor.cfa {
        Some(_) => (0..3)
            .map(|c| crate::sensor::presets::cfa_channel(sensor, c))
            .collect::<Result<_>>()?,
        None => vec![sensor.clone()],
    };
    let imagers: Vec<Imager> = channel_sensors
        .iter()
        .map(|s| Imager::new(s, &meta, &geometry, options.wrap_tolerance))
        .collect::<Result<_>>()?;
    let white_balance = white_balance(&channel_sensors)?;
    let imager = &imagers[0];
    warnings.extend(imager.sampling().warnings.iter().cloned());
    let mut model = DetectorModel::from_config(sensor)?;
    warnings.extend(model.warnings().iter().cloned());
    let scene_gain = model.scene_mean_gain_fraction(sensor);
    let mut instance: Option<DetectorInstance> = None;
    let input_frames = reader.frames();
    let static_scene = input_frames == 1;
    let n_frames = if static_scene {
        options.frames.max(1)
    } else {
        input_frames
    };
    let s = imagers[0].sampling();
    crate::limits::check_run(
        (s.y.padded_len, s.x.padded_len),
        (meta.rows, meta.cols),
        (sensor.detector.rows, sensor.detector.cols),
        n_frames,
    )?;
    let active: usize = imagers
        .iter()
        .map(|i| i.weights().active_bands().len())
        .sum();
    let mut frames = Vec::with_capacity(n_frames);
    let mut stats = ImagingStats::default();
    let mut mean: Option<Array2<f64>> = None;
    for f in 0..n_frames {
        if mean.is_none() || !static_scene {
            let mut planes = Vec::with_capacity(imagers.len());
            let mut done = 0;
            for im in &imagers {
                let (e, s) = im.mean_electrons(reader, f, |b, _| {
                    progress(f * active + done + b, input_frames * active)
                })?;
                done += s.bands_used;
                stats.read_s += s.read_s;
                stats.fft_s += s.fft_s;
                stats.otf_s += s.otf_s;
                stats.inverse_s += s.inverse_s;
                stats.bands_used += s.bands_used;
                stats.padded_shape = s.padded_shape;
                planes.push(e);
            }
            mean = Some(match &sensor.cfa {
                Some(cfa) => crate::cfa::mosaic([&planes[0], &planes[1], &planes[2]], cfa.pattern)?,
                None => planes.swap_remove(0),
            });
        }
        let e = mean
            .as_ref()
            .ok_or_else(|| Error::OutOfRange("no frame imaged".into()))?;
        // Products hold electrons as f32: a count beyond f32::MAX would be written as inf.
        if let Some(v) = e
            .iter()
            .find(|v| !(v.is_finite() && v.abs() <= f32::MAX as f64))
        {
            return Err(Error::OutOfRange(format!(
                "frame {f} of `{}`: the mean signal overflowed ({v:e} electrons, beyond the f32 range of the products); the input radiance or the sensor's spectral response (detector.quantum_efficiency, transmissions, integration time, pixel area) is too large to give a finite count",
                options.input_name
            )));
        }
        if instance.is_none() {
            // `reference = "scene_mean"`: K from the first frame's mean signal.
            if let Some(fraction) = scene_gain {
                let mean_e = e.iter().sum::<f64>() / e.len().max(1) as f64;
                model.set_gain_from_scene_mean(mean_e, fraction)?;
            }
            instance = Some(DetectorInstance::new(&model, options.seed)?);
        }
        let instance = instance
            .as_ref()
            .ok_or_else(|| Error::OutOfRange("no detector instance".into()))?;
        let t0 = Instant::now();
        let dn = instance.expose(e, f as u64)?;
        detector_s += t0.elapsed().as_secs_f64();
        let rgb = match &sensor.cfa {
            Some(cfa) => {
                // Black level: offset plus the mean dark and background signal.
                let black = sensor.detector.offset_dn
                    + model.gain_dn_per_e() * (model.dark_e() + model.background_e());
                let raw = dn.mapv(|v| v as f64 - black);
                let mut planes = crate::cfa::demosaic_malvar(raw.view(), cfa.pattern);
                for (c, g) in white_balance.iter().enumerate() {
                    planes
                        .index_axis_mut(ndarray::Axis(0), c)
                        .mapv_inplace(|v| v * g);
                }
                Some(display_rgb(&planes))
            }
            None => None,
        };
        frames.push(FrameProducts {
            electrons_mean: e.mapv(|v| v as f32),
            dn,
            rgb,
            radiance: None,
            temperature: None,
        });
    }
    let instance = instance.ok_or_else(|| Error::OutOfRange("no frame was exposed".into()))?;
    // The way back: calibrate through the same sensor instance, then invert.
    let t_cal = Instant::now();
    let mut calibration_report = serde_json::Value::Null;
    if let Some(opts) = options.calibration.as_ref().filter(|_| is_thermal(sensor)) {
        match Calibration::new(sensor, &model, &instance, opts) {
            Ok(cal) => {
                let mut nan_total = 0;
                for f in frames.iter_mut() {
                    let corrected = cal.correct(f.dn.view())?;
                    let (t, l, nan) = cal.to_temperature(corrected.view());
                    nan_total += nan;
                    f.temperature = Some(t.mapv(|v| v as f32));
                    f.radiance = Some(l.mapv(|v| v as f32));
                }
                let temps = cal.temperatures_k();
                let t_check = 0.5 * (temps[0] + temps[temps.len() - 1]) + 0.37;
                let (raw_nu, nuc_nu) = cal
                    .residual_nonuniformity(&instance, t_check)
                    .map_err(|e| calibration_failed(sensor, e))?;
                calibration_report = json!({
                    "nuc_degree": opts.degree,
                    "temperatures_k": temps,
                    "frames_per_level": opts.frames_per_level,
                    "bad_pixels": cal.bad_pixels().count(),
                    "residual_nonuniformity": {"at_k": t_check, "raw": raw_nu, "corrected": nuc_nu},
                    "netd_analytic_k_at_300k": cal.netd_analytic_k(300.0).ok(),
                    "netd_measured_k_at_300k": crate::calibration::measured_netd(
                        sensor, &instance, 300.0, 0.25, 16, Some(cal.bad_pixels()),
                    ).ok(),
                    "uninvertible_pixels": nan_total,
                    "radiance_definition": "in-band radiance: integral of S(λ) L(λ) dλ / max S, W m-2 sr-1",
                });
            }
            Err(e) => warnings.push(format!(
                "no radiance/temperature products: calibration failed: {e}"
            )),
        }
    }
    let calibration_s = t_cal.elapsed().as_secs_f64();
    let d = &sensor.detector;
    let first = &frames[0];
    let n_px = first.dn.len() as f64;
    let saturated = first
        .electrons_mean
        .iter()
        .zip(first.dn.iter())
        .filter(|(e, dn)| **e as f64 >= d.full_well_e || **dn as f64 >= d.max_dn())
        .count() as f64;
    let mean_e = first.electrons_mean.iter().map(|v| *v as f64).sum::<f64>() / n_px;
    let noise_e = model.temporal_noise_e(mean_e);
    let mean_dn = first.dn.iter().map(|v| *v as f64).sum::<f64>() / n_px;
    let s = imager.sampling();
    let lambda_mean = crate::report::mean_wavelength_um(sensor).ok();
    let mtf_nyquist =
        lambda_mean.map(|l| imager.otf().evaluate(sensor.nyquist_cy_per_rad(), 0.0, l));
    let report = json!({
        "options": sensor.selected_options,
        "optics": {
            "focal_length_m": sensor.optics.focal_length_m,
            "f_number": sensor.optics.f_number,
            "ifov_urad": sensor.ifov_rad() * 1e6,
            "fov_deg": [sensor.fov_deg().0, sensor.fov_deg().1],
            "mean_wavelength_um": lambda_mean,
            "lambda_f_number_over_pitch": lambda_mean.map(|l| l * 1e-6 * sensor.optics.f_number / sensor.detector.pitch_m),
            "mtf_at_nyquist": mtf_nyquist,
            "components": imager.otf().components().iter().map(|c| c.name()).collect::<Vec<_>>(),
        },
        "eoir_version": env!("CARGO_PKG_VERSION"),
        "sensor": sensor.name,
        "seed": options.seed,
        "input": {
            "name": options.input_name,
            "bands": meta.bands(),
            "bands_used": active,
            "wavelength_um": [meta.wavelength_um.first(), meta.wavelength_um.last()],
            "rows": meta.rows,
            "cols": meta.cols,
            "frames": n_frames,
            "units": meta.units.as_str(),
            "fov_deg": [geometry.fov_x_deg, geometry.fov_y_deg],
        },
        "sampling": {
            "detector_ifov_urad": sensor.ifov_rad() * 1e6,
            "scene_ifov_urad": [s.scene_ifov_rad.1 * 1e6, s.scene_ifov_rad.0 * 1e6],
            "ratio_x": s.x.ratio,
            "ratio_y": s.y.ratio,
            "method": if s.integer { "integer decimation (phase-ramp centring, point sampling)" } else { "band-limited resampling (trigonometric interpolation)" },
            "pad_px": [s.x.pad_before, s.y.pad_before],
            "padded_shape": [stats.padded_shape.1, stats.padded_shape.0],
            "wrap_tolerance": options.wrap_tolerance,
        },
        "detector": {
            "rows": d.rows,
            "cols": d.cols,
            "gain_dn_per_e": model.gain_dn_per_e(),
            "auto_gain_reference": model.auto_gain_reference().map(|(r, e)| format!("{r:?}: {e:.6e} e-")),
            "offset_dn": d.offset_dn,
            "bits": d.bits,
            "full_well_e": d.full_well_e,
            "dark_e": model.dark_e(),
            "background_e": model.background_e(),
            "read_noise_e": model.read_noise_e(),
            "shot_noise": model.shot_noise(),
            "fpn": d.fpn.is_some(),
            "nonlinearity": d.nonlinearity.is_some(),
            "defects": d.defects.is_some(),
        },
        "signal": {
            "mean_electrons": mean_e,
            "mean_dn": mean_dn,
            "saturated_percent": 100.0 * saturated / n_px,
            "temporal_noise_e": noise_e,
            "snr": if noise_e > 0.0 { mean_e / noise_e } else { f64::INFINITY },
        },
        "calibration": calibration_report,
        "warnings": warnings,
        "timings_s": {
            "read": stats.read_s,
            "forward_fft": stats.fft_s,
            "otf_and_accumulate": stats.otf_s,
            "inverse_and_sampling": stats.inverse_s,
            "detector": detector_s,
            "calibration": calibration_s,
            "total": t_start.elapsed().as_secs_f64(),
        },
    });
    Ok(RunOutput {
        frames,
        sensor: sensor.clone(),
        report,
        warnings,
    })
}

impl RunOutput {
    /// The DN frames as 8-bit images with one common stretch (0.5–99.5 percentiles over
    /// all frames), for the animated preview of a sequence.
    pub fn preview_frames(&self) -> Vec<Array2<u8>> {
        let mut all: Vec<u16> = self
            .frames
            .iter()
            .flat_map(|f| f.dn.iter().copied())
            .collect();
        all.sort_unstable();
        let pick = |q: f64| all[((all.len() - 1) as f64 * q) as usize] as f64;
        let (lo, hi) = (pick(0.005), pick(0.995));
        let span = (hi - lo).max(1.0);
        self.frames
            .iter()
            .map(|f| {
                f.dn.mapv(|v| ((v as f64 - lo) / span * 255.0).round().clamp(0.0, 255.0) as u8)
            })
            .collect()
    }

    /// Writes the products into `dir` (created if needed), each file atomically:
    /// `dn.tiff` (u16), `dn.png` (16-bit grey), `electrons_mean.tiff` and
    /// `electrons_mean.exr` (f32), `config.toml` (the resolved sensor), `report.json`, and
    /// with the `hdf5` feature `products.h5` holding every product. A sequence writes
    /// `frame_NNNN_` prefixed DN and electron files. Returns the paths written.
    pub fn write(&self, dir: &Path) -> Result<Vec<PathBuf>> {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let mut written = Vec::new();
        let single = self.frames.len() == 1;
        for (i, f) in self.frames.iter().enumerate() {
            let prefix = if single {
                String::new()
            } else {
                format!("frame_{i:04}_")
            };
            let p = dir.join(format!("{prefix}dn.tiff"));
            raster::write_tiff_u16(&p, f.dn.view())?;
            written.push(p);
            let p = dir.join(format!("{prefix}dn.png"));
            raster::write_png_u16(&p, f.dn.view())?;
            written.push(p);
            let p = dir.join(format!("{prefix}electrons_mean.tiff"));
            raster::write_tiff_f32(&p, f.electrons_mean.view())?;
            written.push(p);
            let p = dir.join(format!("{prefix}electrons_mean.exr"));
            raster::write_exr_f32(&p, f.electrons_mean.view(), "electrons_mean")?;
            written.push(p);
            for (name, img) in [("radiance", &f.radiance), ("temperature", &f.temperature)] {
                if let Some(img) = img {
                    let p = dir.join(format!("{prefix}{name}.tiff"));
                    raster::write_tiff_f32(&p, img.view())?;
                    written.push(p);
                    let p = dir.join(format!("{prefix}{name}.exr"));
                    raster::write_exr_f32(&p, img.view(), name)?;
                    written.push(p);
                }
            }
            if let Some(rgb) = &f.rgb {
                let p = dir.join(format!("{prefix}rgb.png"));
                raster::write_png_rgb8(&p, rgb.view())?;
                written.push(p);
            }
        }
        #[cfg(feature = "hdf5")]
        {
            use crate::io::hdf5::{write_bundle, BundleData, BundleItem};
            let mut items = Vec::new();
            let names: Vec<(String, String)> = (0..self.frames.len())
                .map(|i| {
                    if single {
                        ("dn".to_string(), "electrons_mean".to_string())
                    } else {
                        (
                            format!("frame_{i:04}_dn"),
                            format!("frame_{i:04}_electrons_mean"),
                        )
                    }
                })
                .collect();
            let extra: Vec<(String, String)> = (0..self.frames.len())
                .map(|i| {
                    if single {
                        ("radiance".to_string(), "temperature".to_string())
                    } else {
                        (
                            format!("frame_{i:04}_radiance"),
                            format!("frame_{i:04}_temperature"),
                        )
                    }
                })
                .collect();
            for (f, (rad, temp)) in self.frames.iter().zip(&extra) {
                if let Some(r) = &f.radiance {
                    items.push(BundleItem {
                        name: rad,
                        data: BundleData::F32(r.view()),
                        attrs: vec![(
                            "units",
                            "W m-2 sr-1 (in-band, normalised to peak response)".to_string(),
                        )],
                    });
                }
                if let Some(t) = &f.temperature {
                    items.push(BundleItem {
                        name: temp,
                        data: BundleData::F32(t.view()),
                        attrs: vec![("units", "K (apparent, blackbody-equivalent)".to_string())],
                    });
                }
            }
            for (f, (dn, el)) in self.frames.iter().zip(&names) {
                items.push(BundleItem {
                    name: dn,
                    data: BundleData::U16(f.dn.view()),
                    attrs: vec![("units", "DN".to_string())],
                });
                items.push(BundleItem {
                    name: el,
                    data: BundleData::F32(f.electrons_mean.view()),
                    attrs: vec![("units", "electrons (mean, noise-free)".to_string())],
                });
            }
            let p = dir.join("products.h5");
            let report = serde_json::to_string(&self.report)
                .map_err(|e| Error::format(&p, e.to_string()))?;
            write_bundle(
                &p,
                &items,
                &[
                    ("sensor", self.sensor.to_toml_string()?),
                    ("report", report),
                ],
            )?;
            written.push(p);
        }
        if self.frames.len() > 1 {
            let p = dir.join("preview.png");
            crate::io::raster::write_apng_gray8(&p, &self.preview_frames(), 100)?;
            written.push(p);
        }
        let p = dir.join("config.toml");
        let text = self.sensor.to_toml_string()?;
        crate::io::atomic_write(&p, |w| crate::io::write_all(w, text.as_bytes(), &p))?;
        written.push(p);
        let p = dir.join("report.json");
        let text = serde_json::to_string_pretty(&self.report)
            .map_err(|e| Error::format(&p, e.to_string()))?;
        crate::io::atomic_write(&p, |w| crate::io::write_all(w, text.as_bytes(), &p))?;
        written.push(p);
        Ok(written)
    }
}
