//! CLI glue for `eoir run` and `eoir demo`.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use eoir::io::output::ProductSet;
use eoir::pipeline::{self, RunOptions};
use eoir::scene::sizing;
use eoir::scene::synthetic::{self, SceneParams};
use eoir::scene::Geometry;
use eoir::sensor::{presets, Sensor};

use super::sensor_args::{build, SensorArgs};

/// Arguments of `eoir run`.
#[derive(Debug, clap::Args)]
pub struct RunArgs {
    #[command(flatten)]
    sensor: SensorArgs,
    /// Input radiance cube (.hdr ENVI, .exr spectral OpenEXR, .npy + .json, .h5 HDF5).
    input: PathBuf,
    /// Output directory.
    #[arg(short, long)]
    output: PathBuf,
    /// Seed for all random effects.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Frames to expose of a static scene (fixed pattern identical, temporal noise fresh).
    #[arg(long, default_value_t = 1)]
    frames: usize,
    /// Precision of the per-band forward FFTs: f32 (accumulated in f64; the default,
    /// faster) or f64 (the reference path).
    #[arg(long, default_value = "f32", value_name = "f32|f64")]
    fft_precision: String,
    /// Degree of the per-pixel NUC polynomial for thermal sensors (1 = two-point).
    #[arg(long, default_value_t = 1)]
    nuc_degree: usize,
    /// Frames of a sequence imaged at the same time, each with its own reader (default:
    /// one per thread, fewer if the memory budget does not allow them; 1 = one after
    /// another). The products are the same for every value.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    frames_in_flight: Option<u64>,
    /// For a preset with a `channel` option (3-CCD, three-band): run every channel into
    /// OUTDIR/channel-<value>/ and write a false-colour composite OUTDIR/composite.png.
    #[arg(long)]
    composite: bool,
    /// Scene field of view `H,V` in degrees; wins over any field of view in the file.
    #[arg(long, value_name = "H,V")]
    fov_deg: Option<String>,
    /// Blackbody calibration temperatures of a thermal sensor, K (default: the sensor
    /// file's `[calibration] temperatures_k`, else about 10/50/90 % of full scale).
    #[arg(long, value_name = "T1,T2,...", value_delimiter = ',')]
    calibration_temperatures: Vec<f64>,
    /// Fail (exit non-zero, nothing written) when no temperature product can be made.
    #[arg(long)]
    require_temperature: bool,
    /// Radiance units of the input, overriding what the file states, e.g.
    /// `"W m-2 sr-1 nm-1"`, `"uW cm-2 sr-1 nm-1"` (AVIRIS), `"W/(m2 sr um)"`.
    #[arg(long, value_name = "UNITS")]
    radiance_units: Option<String>,
    /// Read the input with `read()` only, never from a memory map of the file. Maps (the
    /// default for ENVI band-sequential f32 and NPY `<f4` input) save a copy per band, but a file
    /// truncated by another process during the run then stops eoir with `SIGBUS`.
    #[arg(long)]
    no_mmap: bool,
    /// Add the sensor's analytic figures of merit (NETD, MTF50, RER, MRTD, GIQE 5 NIIRS,
    /// TTP detection/recognition/identification ranges for the default target) to
    /// report.json and report.html, with their curves; `eoir assess` has the other
    /// targets and the measured figures.
    #[arg(long)]
    assess: bool,
    /// The unblurred reference ("truth image") of the run: every transfer function off
    /// (diffraction, the detector footprint, aberration, defocus, motion, jitter,
    /// turbulence, aerosol, Gaussian, measured MTF, and `[optics.wavefront]`), so each
    /// pixel samples the scene at its centre through the same radiometry, noise and
    /// gain; report.json says `"unblurred": true` (docs/way-back.md).
    #[arg(long)]
    unblurred: bool,
    /// No progress bar or summary.
    #[arg(long)]
    quiet: bool,
}

/// How [`run_file`] behaves around the pipeline.
#[derive(Debug, Clone, Copy, Default)]
struct FileRun {
    /// No progress bar or summary.
    quiet: bool,
    /// Fail when no temperature product can be made.
    require_temperature: bool,
    /// Add the analytic figures of merit to the report (`--assess`).
    assess: bool,
}

/// Arguments of `eoir demo`.
#[derive(Debug, clap::Args)]
pub struct DemoArgs {
    /// Output directory.
    #[arg(short, long, default_value = "eoir-demo")]
    output: PathBuf,
    #[command(flatten)]
    sensor: SensorArgs,
    /// Blackbody calibration temperatures of a thermal sensor, K (default: the sensor
    /// file's `[calibration] temperatures_k`, else about 10/50/90 % of full scale).
    #[arg(long, value_name = "T1,T2,...", value_delimiter = ',')]
    calibration_temperatures: Vec<f64>,
    /// Fail (exit non-zero, nothing written) when no temperature product can be made.
    #[arg(long)]
    require_temperature: bool,
    /// Scene samples per detector pixel (integer).
    #[arg(long, default_value_t = sizing::DEFAULT_OVERSAMPLING)]
    oversampling: usize,
    /// Seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

/// Runs the input through the sensor, writing each frame's products into `output` as soon
/// as the frame is exposed ([`pipeline::run_streaming`] into a [`pipeline::ProductWriter`]),
/// so the memory does not grow with the frame count; the products of the whole run are
/// written at the end. On an error `output` holds a partial set: the caller writes into a
/// staging directory that is dropped on error.
fn run_file(
    sensor: &Sensor,
    input: &Path,
    output: &Path,
    mut options: RunOptions,
    read: &eoir::io::ReadOptions,
    how: FileRun,
) -> Result<pipeline::StreamedRun> {
    let FileRun {
        quiet,
        require_temperature,
        assess,
    } = how;
    if require_temperature && !sensor.is_thermal() {
        bail!(
            "--require-temperature: sensor `{}` does not respond beyond 3 µm, so it has no apparent-temperature products",
            sensor.name
        );
    }
    let mut reader = eoir::io::open_with(input, read)?;
    // Calibration work in frame exposures: one per level average and one for the
    // non-uniformity check (each drawn in one pass), and the measured NETD's two stacks.
    let calibration_exposures = match &options.calibration {
        Some(c) if sensor.is_thermal() => {
            let levels = c.temperatures_k.len().max(c.degree + 2).max(3);
            let d = &sensor.detector;
            (levels + 1 + 2 * pipeline::calibrate::netd_frames(d.rows * d.cols)) as u64
        }
        _ => 0,
    };
    let mut progress = crate::cli::progress::RunProgress::new(
        quiet,
        reader.frames().max(options.frames),
        calibration_exposures,
    );
    // A name the caller gave (the demo: where its scene ends up) wins over the path read.
    if options.input_name == RunOptions::default().input_name {
        options.input_name = input.display().to_string();
    }
    // The products stream to disk, so memory no longer bounds the frame count: the disk
    // does. At least 8 bytes per pixel and frame (dn.tiff, electrons_mean.tiff, the stack).
    let frames = if reader.frames() == 1 {
        options.frames
    } else {
        reader.frames()
    };
    let mut writer = pipeline::ProductWriter::new(output)?;
    let d = &sensor.detector;
    eoir::io::output::check_room_for_frames(output, frames, d.rows * d.cols, 8)?;
    let mut out = pipeline::run_streaming(
        sensor,
        reader.as_mut(),
        &options,
        |done, total| progress.imaging(done, total),
        &mut writer,
    )?;
    if assess {
        let parts = eoir::merit::run_report::RunParts {
            sensor: &out.sensor,
            report: &mut out.report,
            warnings: &mut out.warnings,
            extra_sections: &mut out.extra_sections,
        };
        eoir::merit::run_report::attach_to(parts, &Default::default())?;
    }
    let no_temperature = pipeline::calibrate::missing_temperature_of(sensor, &out.summary());
    if let (true, Some(reason)) = (require_temperature, &no_temperature) {
        bail!("--require-temperature: {reason}");
    }
    progress.writing();
    writer.finish(&out.summary())?;
    progress.finish();
    for w in &out.warnings {
        eprintln!("warning: {w}");
    }
    if !quiet {
        let r = &out.report;
        let opts = r
            .options
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect::<Vec<_>>()
            .join(" ");
        let f = |v: Option<f64>| v.unwrap_or(f64::NAN);
        println!(
            "{} {opts} (seed {}): {} x {} px, F/{:.2}, IFOV {:.1} µrad, λF#/pitch {:.2}, MTF at Nyquist {:.3}",
            sensor.name,
            r.seed,
            sensor.detector.cols,
            sensor.detector.rows,
            r.optics.f_number,
            r.optics.ifov_urad,
            f(r.optics.lambda_f_number_over_pitch),
            f(r.optics.mtf_at_nyquist),
        );
        println!(
            "  sampling {:.3} scene px per detector px ({}); K = {:.4} DN/e-; signal {:.4e} e-, noise {:.4e} e-, SNR {:.1}; saturated {:.2} %{}; {:.2} s",
            r.sampling.ratio_x,
            r.sampling.method,
            r.detector.gain_dn_per_e,
            r.signal.mean_electrons,
            r.signal.temporal_noise_e,
            r.signal.snr,
            r.signal.saturated_percent,
            match r.calibration.as_ref().and_then(|c| c.netd_analytic_k_at_300k) {
                Some(n) => format!("; NETD {:.1} mK at 300 K", n * 1e3),
                None => String::new(),
            },
            r.timings_s.total,
        );
        if let Some(reason) = &no_temperature {
            println!("  NO TEMPERATURE PRODUCTS: {reason}");
        }
    }
    Ok(out)
}

/// Prints the final paths of a committed product set.
fn print_written(paths: &[PathBuf], quiet: bool) {
    if !quiet {
        for p in paths {
            println!("wrote {}", p.display());
        }
    }
}

/// `eoir run`.
pub fn run(args: RunArgs) -> Result<()> {
    let geometry = match &args.fov_deg {
        Some(t) => {
            let (h, v) = crate::cli::parse_pair(t, "--fov-deg")?;
            for (axis, deg) in [("H", h), ("V", v)] {
                if !(deg.is_finite() && deg > 0.0 && deg < 180.0) {
                    bail!("--fov-deg {t}: the {axis} field of view {deg}° must be a number in (0, 180) degrees");
                }
            }
            Some(Geometry {
                fov_x_deg: h,
                fov_y_deg: v,
                range_m: None,
            })
        }
        None => None,
    };
    if args.frames == 0 {
        bail!("--frames 0: at least one frame is needed");
    }
    let read = eoir::io::ReadOptions {
        radiance_units: args.radiance_units.clone(),
        no_memory_map: args.no_mmap,
    };
    let options = RunOptions {
        seed: args.seed,
        geometry,
        frames: args.frames,
        calibration: Some(crate::cli::temperature::calibration_options(
            args.nuc_degree,
            &args.calibration_temperatures,
        )?),
        fft_precision: args
            .fft_precision
            .parse()
            .with_context(|| format!("--fft-precision {}", args.fft_precision))?,
        frames_in_flight: args.frames_in_flight.map(|n| n as usize),
        ..Default::default()
    };
    let unblurred = |c: eoir::sensor::SensorConfig| {
        if args.unblurred {
            c.unblurred()
        } else {
            c
        }
    };
    if !args.composite {
        let sensor = build(&unblurred(args.sensor.load_config()?))?;
        let set = ProductSet::begin(&args.output)?.replacing("run");
        run_file(
            &sensor,
            &args.input,
            set.staging_dir(),
            options,
            &read,
            FileRun {
                quiet: args.quiet,
                require_temperature: args.require_temperature,
                assess: args.assess,
            },
        )
        .map_err(|e| name_final(&set, e))?;
        print_written(&set.commit()?, args.quiet);
        return Ok(());
    }
    let info = presets::list()
        .into_iter()
        .find(|p| p.name.eq_ignore_ascii_case(&args.sensor.sensor))
        .with_context(|| {
            format!(
                "--composite needs a preset with a `channel` option, not `{}`",
                args.sensor.sensor
            )
        })?;
    let channels = info
        .channel_values()
        .with_context(|| {
            format!(
                "preset `{}` has no `channel` option to composite",
                info.name
            )
        })?
        .to_vec();
    if channels.len() != 3 {
        bail!(
            "preset `{}` has {} channels; a composite needs 3",
            info.name,
            channels.len()
        );
    }
    // Longest-wavelength channel first: with a scene-mean auto gain it sets K for all.
    let mut sensors = Vec::new();
    for ch in &channels {
        let mut opts = args.sensor.option.clone();
        opts.retain(|o| !o.starts_with("channel="));
        opts.push(format!("channel={ch}"));
        let sensor = unblurred(presets::load(&args.sensor.sensor, &opts, &args.sensor.set)?);
        sensors.push((
            eoir::report::mean_wavelength_um(&build(&sensor)?)?,
            ch.clone(),
            sensor,
        ));
    }
    sensors.sort_by(|a, b| b.0.total_cmp(&a.0));
    let set = ProductSet::begin(&args.output)?.replacing("run-composite");
    let mut outs = Vec::new();
    let mut shared_gain: Option<f64> = None;
    for (lambda, ch, mut sensor) in sensors {
        if let Some(k) = shared_gain {
            sensor.detector.auto_gain = None;
            sensor.detector.gain_dn_per_e = Some(k);
        }
        let out = run_file(
            &build(&sensor)?,
            &args.input,
            &set.staging_dir().join(format!("channel-{ch}")),
            options.clone(),
            &read,
            FileRun {
                quiet: args.quiet,
                require_temperature: args.require_temperature,
                assess: args.assess,
            },
        )
        .map_err(|e| name_final(&set, e))?;
        if shared_gain.is_none() {
            shared_gain = Some(out.report.detector.gain_dn_per_e);
        }
        outs.push((lambda, out));
    }
    let refs: Vec<(f64, &pipeline::FrameProducts)> =
        outs.iter().map(|(l, o)| (*l, &o.first)).collect();
    let rgb = pipeline::false_colour_composite_of(&refs)?;
    let p = set.staging_dir().join("composite.png");
    eoir::io::raster::write_png_rgb8(&p, rgb.view()).map_err(|e| set.name_final(e))?;
    let final_png = set.final_path(&p);
    print_written(&set.commit()?, args.quiet);
    if !args.quiet {
        println!(
            "{} is the false-colour composite (longest-wavelength channel → red)",
            final_png.display()
        );
    }
    Ok(())
}

/// `e` naming the final path of a product where it named its staging place (an I/O
/// error while staging, e.g. `File too large` under `ulimit -f`).
/// An error with context added on top is left as it is (downcasting would drop it).
fn name_final(set: &ProductSet, e: anyhow::Error) -> anyhow::Error {
    let bare = e
        .downcast_ref::<eoir::error::Error>()
        .is_some_and(|err| err.to_string() == e.to_string());
    if !bare {
        return e;
    }
    match e.downcast::<eoir::error::Error>() {
        Ok(err) => set.name_final(err).into(),
        Err(e) => e,
    }
}

/// `eoir demo`: the thermal scene, sized to the sensor by [`sizing::covering`] (as
/// `eoir scene` does) at `oversampling` scene samples per detector pixel over the sensor's
/// band, through the sensor.
pub fn demo(args: DemoArgs) -> Result<()> {
    let sensor = args.sensor.load()?;
    let (lo, hi) = sensor.response().support_um();
    let wavelength_um = sizing::response_grid_um(lo, hi)
        .with_context(|| format!("sensor `{}`: the demo scene follows its band", sensor.name))?;
    let bands = wavelength_um.len();
    let grid = crate::cli::scene::detector_grid(&sensor);
    let params = SceneParams {
        wavelength_um,
        range_m: Some(1900.0),
        seed: args.seed,
        sun: true,
        ..sizing::covering(&grid, args.oversampling, sizing::DEFAULT_MARGIN_PX)
            .with_context(|| format!("sizing the demo scene to sensor `{}`", sensor.name))?
    };
    let set = ProductSet::begin(&args.output)?.replacing("demo");
    let scene_path = set.staging_dir().join("scene.hdr");
    let cube = synthetic::thermal(&params)?;
    eoir::io::write_cube(&scene_path, &cube)?;
    drop(cube);
    if !args.quiet {
        println!(
            "{} holds the thermal scene, {} x {} x {} bands, {:.3}–{:.3} µm",
            set.final_path(&scene_path).display(),
            params.cube_cols(),
            params.cube_rows(),
            bands,
            lo,
            hi
        );
    }
    run_file(
        &sensor,
        &scene_path,
        set.staging_dir(),
        RunOptions {
            seed: args.seed,
            calibration: Some(crate::cli::temperature::calibration_options(
                1,
                &args.calibration_temperatures,
            )?),
            // The report names the scene where it ends up, not its staging place.
            input_name: set.final_path(&scene_path).display().to_string(),
            ..Default::default()
        },
        &eoir::io::ReadOptions::default(),
        FileRun {
            quiet: args.quiet,
            require_temperature: args.require_temperature,
            assess: false,
        },
    )?;
    print_written(&set.commit()?, args.quiet);
    Ok(())
}
