//! `eoir temperature`: a DN image (through NUC, bad-pixel replacement and the sensor's
//! blackbody response) or an in-band radiance image → apparent temperature; and the
//! calibration options `eoir run`, `eoir demo` and this command share.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};

use eoir::calibration::instance::{sensor_hash, SensorInstance, INSTANCE_FILE};
use eoir::calibration::{band_radiance_lut, Calibration, CalibrationOptions};
use eoir::detector::DetectorInstance;
use eoir::io::output::ProductSet;

use crate::cli::sensor_args::SensorArgs;

/// Calibration options for a NUC of `degree` with the blackbody temperatures
/// `temperatures_k` (empty: the sensor file's `[calibration]`, else chosen from the sensor's
/// range). Errors for a degree outside 0..=[`eoir::processing::nuc::MAX_DEGREE`] or invalid
/// temperatures, naming the flag.
pub fn calibration_options(degree: usize, temperatures_k: &[f64]) -> Result<CalibrationOptions> {
    let max = eoir::processing::nuc::MAX_DEGREE;
    if degree > max {
        bail!("--nuc-degree {degree}: the NUC polynomial degree must be 0 to {max}");
    }
    let opts = CalibrationOptions {
        temperatures_k: temperatures_k.to_vec(),
        degree,
        ..Default::default()
    };
    opts.validate()
        .with_context(|| format!("--calibration-temperatures {temperatures_k:?}"))?;
    Ok(opts)
}

/// Arguments of `eoir temperature`.
#[derive(Debug, clap::Args)]
pub struct TemperatureArgs {
    /// The sensor that recorded the image (for a product set of `eoir run`, its
    /// `config.toml` is that sensor).
    #[command(flatten)]
    sensor: SensorArgs,
    /// Seed of the sensor instance that recorded the DN image (its fixed pattern). Default:
    /// the seed in `instance.json` beside the image, else 1.
    #[arg(long)]
    seed: Option<u64>,
    /// Degree of the NUC polynomial (as the run used).
    #[arg(long, default_value_t = 1)]
    nuc_degree: usize,
    /// Blackbody calibration temperatures, K (as the run used; default: the sensor file's
    /// `[calibration]`, else chosen from the sensor's range).
    #[arg(long, value_name = "T1,T2,...", value_delimiter = ',')]
    calibration_temperatures: Vec<f64>,
    /// Use the sensor and seed given even when they differ from the instance recorded
    /// beside the image (`instance.json`).
    #[arg(long)]
    allow_instance_mismatch: bool,
    /// Input: a 16-bit DN TIFF (as `eoir run` writes) or an f32 TIFF of in-band radiance.
    input: PathBuf,
    /// Output directory (writes temperature.tiff, and radiance.tiff for DN input).
    #[arg(short, long)]
    output: PathBuf,
}

/// What `eoir temperature` converts.
enum Input {
    /// Raw DN of a run (16-bit TIFF).
    Dn(ndarray::Array2<u16>),
    /// In-band radiance, W m-2 sr-1 (f32 TIFF).
    Radiance(ndarray::Array2<f32>),
}

/// The seed to calibrate with: `--seed`, else the recorded one, else 1; refuses a sensor or
/// seed that differs from the recorded instance unless `--allow-instance-mismatch`.
fn instance_seed(
    args: &TemperatureArgs,
    sensor: &eoir::sensor::Sensor,
    dn_input: bool,
) -> Result<u64> {
    let recorded = SensorInstance::beside(&args.input)?;
    let Some(rec) = recorded else {
        if dn_input && args.seed.is_none() {
            eprintln!(
                "note: no {INSTANCE_FILE} beside {}: assuming the sensor instance of seed 1 (pass --seed to name the run's seed)",
                args.input.display()
            );
        }
        return Ok(args.seed.unwrap_or(1));
    };
    let hash = sensor_hash(sensor)?;
    let mut problems = Vec::new();
    if hash != rec.sensor_hash {
        problems.push(format!(
            "the sensor `{}` given resolves to {hash}, but the image was recorded by `{}` ({}); pass the run's sensor, e.g. --sensor {}",
            sensor.config().name,
            rec.sensor,
            rec.sensor_hash,
            args.input
                .parent()
                .unwrap_or_else(|| std::path::Path::new("."))
                .join("config.toml")
                .display()
        ));
    }
    if dn_input {
        if let Some(s) = args.seed.filter(|&s| s != rec.seed) {
            problems.push(format!(
                "--seed {s} differs from the recorded seed {} (the fixed pattern of another instance gives errors of kelvins)",
                rec.seed
            ));
        }
    }
    if !problems.is_empty() {
        if !args.allow_instance_mismatch {
            bail!(
                "{} does not match the sensor instance recorded in {}: {}; pass --allow-instance-mismatch to convert anyway",
                args.input.display(),
                args.input
                    .parent()
                    .unwrap_or_else(|| std::path::Path::new("."))
                    .join(INSTANCE_FILE)
                    .display(),
                problems.join("; ")
            );
        }
        for p in &problems {
            eprintln!("warning: {p} (--allow-instance-mismatch)");
        }
    }
    Ok(args.seed.unwrap_or(rec.seed))
}

/// `eoir temperature`: DN (through NUC, bad-pixel replacement and the sensor's response) or
/// in-band radiance → apparent temperature.
pub fn temperature(args: TemperatureArgs) -> Result<()> {
    let sensor = args.sensor.load()?;
    if !sensor.is_thermal() {
        bail!(
            "sensor `{}` does not respond beyond 3 µm: apparent temperature needs a thermal sensor",
            sensor.name
        );
    }
    let opts = calibration_options(args.nuc_degree, &args.calibration_temperatures)?;
    // The input's size from its header, before anything costly: a FIFO, a bomb or a frame
    // of another sensor is refused at once.
    let (rows, cols) = eoir::io::raster::image_dimensions(&args.input)?;
    if (rows, cols) != (sensor.detector.rows, sensor.detector.cols) {
        bail!(
            "{}: the image is {cols} × {rows} pixels (width × height) but sensor `{}` records {} × {}",
            args.input.display(),
            sensor.name,
            sensor.detector.cols,
            sensor.detector.rows
        );
    }
    let input = match eoir::io::raster::read_tiff_u16(&args.input) {
        Ok(dn) => Input::Dn(dn),
        Err(_) => Input::Radiance(eoir::io::raster::read_tiff_f32(&args.input).with_context(
            || {
                format!(
                    "{}: input is neither a 16-bit DN TIFF nor an f32 radiance TIFF",
                    args.input.display()
                )
            },
        )?),
    };
    let seed = instance_seed(&args, &sensor, matches!(input, Input::Dn(_)))?;
    let (temperature, radiance, nan, range, netd) = match input {
        Input::Dn(dn) => {
            let model = sensor.detector();
            let instance = DetectorInstance::new(model, seed)?;
            let cal = Calibration::new(&sensor, model, &instance, &opts)?;
            let corrected = cal.correct(dn.view())?;
            // The f32 images the products store, as `eoir run` makes them.
            let (t, l, nan) = cal.to_temperature_f32(corrected.view());
            let netd = cal.netd_analytic_k(300.0).ok();
            (t, Some(l), nan, cal.lut_range_k(), netd)
        }
        Input::Radiance(l) => {
            // Radiance does not pass the ADC: the table spans the physical range.
            let lut = band_radiance_lut(&sensor, opts.radiance_range_k)?;
            let t = l.mapv(|v| lut.temperature_or_nan(v as f64) as f32);
            let nan = t.iter().filter(|v| v.is_nan()).count();
            (t, None, nan, lut.range_k(), None)
        }
    };
    let set = ProductSet::begin(&args.output)?.replacing("temperature");
    // Errors while staging name the product's final path, not its hidden staging place.
    set.write("temperature.tiff", |p| {
        eoir::io::raster::write_tiff_f32(p, temperature.view())
    })?;
    if let Some(l) = radiance {
        set.write("radiance.tiff", |p| {
            eoir::io::raster::write_tiff_f32(p, l.view())
        })?;
    }
    for p in set.commit()? {
        println!("wrote {}", p.display());
    }
    let (lo, hi) = range;
    println!(
        "{nan} pixels outside the calibrated range {lo:.1}–{hi:.1} K (NaN){}",
        match netd {
            Some(n) => format!("; NETD at 300 K {:.1} mK", n * 1e3),
            None => String::new(),
        }
    );
    Ok(())
}
