//! `eoir restore`: Wiener restoration of a recorded image with the sensor's own transfer
//! function; also the single-plane image reader `eoir edge-mtf` shares.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use ndarray::Array2;
use serde_json::json;

use eoir::display;
use eoir::io::output::ProductSet;
use eoir::io::raster;
use eoir::processing::bad_pixels;
use eoir::processing::wiener::{self, ImageStats, Method, NoiseRule, RestoreMasks, SensorTransfer};

use super::defects::image_defects;
use super::sensor_args::SensorArgs;

/// What the pixel values of an input image are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputKind {
    /// 16-bit digital numbers (PNG or TIFF).
    Dn,
    /// 32-bit float values (TIFF or EXR): radiance or electrons.
    Float,
}

/// Peak memory of `eoir restore` per image pixel, bytes: 140 B/px measured (peak resident
/// set of a 2000 × 2000 run, 562 MB) for the f64 image, the padded FFT and its spectra,
/// the restored image and the products; rounded up to 192.
pub const RESTORE_BYTES_PER_PIXEL: u64 = 192;

/// Reads a single-plane image: a 16-bit greyscale PNG or TIFF (DN), a 32-bit float
/// greyscale TIFF, or a one-channel float OpenEXR. 8-bit, colour and multi-channel images
/// are refused with the reason. Before any pixel is decoded, the size in the header times
/// `working_bytes_per_pixel` (the caller's peak memory per pixel) is checked against the
/// memory budget ([`eoir::limits`]); only regular files are opened.
pub fn read_image(path: &Path, working_bytes_per_pixel: u64) -> Result<(Array2<f64>, InputKind)> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if matches!(ext.as_str(), "png" | "tif" | "tiff" | "exr") {
        let (rows, cols) = raster::image_dimensions(path)?;
        eoir::limits::check_alloc(
            &format!("processing {}", path.display()),
            &[("rows", rows as u64), ("columns", cols as u64)],
            working_bytes_per_pixel,
        )?;
    }
    match ext.as_str() {
        "png" => {
            let dn = raster::read_png_u16(path).with_context(|| {
                "a PNG input must be a 16-bit greyscale image of DN (8-bit or colour images carry no calibrated DN)"
            })?;
            Ok((dn.mapv(f64::from), InputKind::Dn))
        }
        "tif" | "tiff" => match raster::read_tiff_u16(path) {
            Ok(dn) => Ok((dn.mapv(f64::from), InputKind::Dn)),
            Err(e16) => match raster::read_tiff_f32(path) {
                Ok(v) => Ok((v.mapv(f64::from), InputKind::Float)),
                Err(e32) => bail!(
                    "{}: not a 16-bit DN TIFF ({e16}) nor a 32-bit float TIFF ({e32})",
                    path.display()
                ),
            },
        },
        "exr" => Ok((read_exr_single(path)?, InputKind::Float)),
        other => bail!(
            "{}: unsupported image type `.{other}`: give a 16-bit PNG/TIFF (DN) or an f32 TIFF/EXR",
            path.display()
        ),
    }
}

/// Reads a one-channel float OpenEXR image.
fn read_exr_single(path: &Path) -> Result<Array2<f64>> {
    use exr::prelude::{read, FlatSamples, ReadChannels, ReadLayers};
    let mut file = std::io::BufReader::new(eoir::io::input::open_regular(path)?);
    eoir::io::exr::check_exr_image_size(path, &mut file)?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(file)
        .map_err(|e| anyhow::anyhow!("{}: cannot read OpenEXR: {e}", path.display()))?;
    let layer = &image.layer_data;
    let channels = &layer.channel_data.list;
    if channels.len() != 1 {
        bail!(
            "{}: expected a single-channel image, found {} channels ({})",
            path.display(),
            channels.len(),
            channels
                .iter()
                .map(|c| c.name.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let (w, h) = (layer.size.width(), layer.size.height());
    let values: Vec<f64> = match &channels[0].sample_data {
        FlatSamples::F32(v) => v.iter().map(|x| f64::from(*x)).collect(),
        FlatSamples::F16(v) => v.iter().map(|x| f64::from(x.to_f32())).collect(),
        FlatSamples::U32(_) => bail!(
            "{}: the channel holds integers; expected float radiance or electrons",
            path.display()
        ),
    };
    Array2::from_shape_vec((h, w), values)
        .with_context(|| format!("{}: image data does not fill {w} × {h}", path.display()))
}

/// Arguments of `eoir restore`.
#[derive(Debug, clap::Args)]
pub struct RestoreArgs {
    /// Recorded image: 16-bit PNG/TIFF of DN, or f32 TIFF/EXR of radiance or electrons;
    /// or a sequence: an eoir output folder with dn_stack.npy, or a .npy stack of DN.
    pub input: PathBuf,
    #[command(flatten)]
    pub sensor: SensorArgs,
    /// Noise level: `auto` (measured on the image by Immerkær's operator, defects and
    /// saturated pixels left out) or `model` (the sensor's shot, read and quantisation
    /// noise at the image's mean level).
    #[arg(long, default_value = "auto", value_parser = ["auto", "model"])]
    pub noise: String,
    /// Filter: `auto` (the least estimated error among Wiener, Wiener–Hunt, a constant NSR
    /// and the unrestored input, so never worse than the input by that estimate),
    /// `wiener` (power-law object spectrum) or `wiener-hunt` (Laplacian smoothness prior).
    #[arg(long, default_value = "auto", value_parser = ["auto", "wiener", "wiener-hunt"])]
    pub method: String,
    /// A constant noise-to-signal power ratio instead of `--noise` and `--method`.
    #[arg(long, conflicts_with_all = ["noise", "method"])]
    pub nsr: Option<f64>,
    /// Black level of a DN image, DN (default: the sensor model's offset plus its dark
    /// and background signal).
    #[arg(long)]
    pub black_level: Option<f64>,
    /// Units of an f32 image: `electrons` or `radiance` (needed by `--noise model`).
    #[arg(long, default_value = "electrons", value_parser = ["electrons", "radiance"])]
    pub units: String,
    /// Output directory (restored.tiff, restored.png, restore.json).
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub sequence: super::restore_sequence::SequenceArgs,
}

/// An 8-bit grey display image with the same percentile stretch as `dn.png`
/// ([`display::DN_STRETCH_LO_PERCENT`]–[`display::DN_STRETCH_HI_PERCENT`]).
fn display_stretch(a: &Array2<f64>) -> ndarray::Array2<u8> {
    let stretch = display::Stretch::from_percentiles(
        a.iter().copied(),
        display::DN_STRETCH_LO_PERCENT,
        display::DN_STRETCH_HI_PERCENT,
    )
    .unwrap_or(display::Stretch { lo: 0.0, hi: 1.0 });
    a.mapv(|v| stretch.to_u8(v))
}

/// Writes a restoration's products into `output` as one set (all or none):
/// `restored.tiff` (f32; `too_large` says why a value beyond f32 cannot be stored),
/// `restored.png` (the DN display stretch) and `restore.json`; returns the paths written.
pub fn write_restored(
    output: &Path,
    restored: &Array2<f64>,
    report: &serde_json::Value,
    too_large: &str,
) -> Result<Vec<PathBuf>> {
    let stored = restored.mapv(|v| v as f32);
    let set = ProductSet::begin(output)?;
    eoir::io::output::check_finite(
        &set.final_path(&set.path("restored.tiff")),
        stored.iter().map(|&v| v as f64),
        &format!("restored.tiff stores 32-bit floats (|value| <= 3.4e38): {too_large}"),
    )?;
    set.write("restored.tiff", |p| {
        raster::write_tiff_f32(p, stored.view())
    })?;
    let grey = display_stretch(restored);
    let samples: Vec<u8> = grey.iter().copied().collect();
    let (rows, cols) = restored.dim();
    let bytes = display::encode_png(cols, rows, 1, &samples)?;
    set.write("restored.png", |p| display::write_png_bytes(p, &bytes))?;
    set.write_json("restore.json", report)?;
    Ok(set.commit()?)
}

/// `eoir restore`.
pub fn restore(args: RestoreArgs) -> Result<()> {
    if super::restore_sequence::is_sequence(&args.input) {
        return super::restore_sequence::restore_sequence(&args);
    }
    super::restore_sequence::refuse_for_single_image(&args.sequence)?;
    let sensor = args.sensor.load()?;
    // The size from the header first: a mismatched (or huge) image is refused undecoded.
    let (rows, cols) = raster::image_dimensions(&args.input)?;
    if (rows, cols) != (sensor.detector.rows, sensor.detector.cols) {
        bail!(
            "{}: the image is {cols} × {rows} pixels (width × height) but sensor `{}` records {} × {}; restore an image with the sensor that recorded it",
            args.input.display(),
            sensor.name,
            sensor.detector.cols,
            sensor.detector.rows
        );
    }
    let (image, kind) = read_image(&args.input, RESTORE_BYTES_PER_PIXEL)?;
    let model = sensor.detector();
    let black = match kind {
        InputKind::Dn => {
            let b = args.black_level.unwrap_or_else(|| model.expected_dn(0.0));
            if !b.is_finite() || b < 0.0 {
                bail!("--black-level {b}: expected a finite DN >= 0");
            }
            b
        }
        InputKind::Float => {
            if args.black_level.is_some() {
                bail!(
                    "--black-level applies to DN images; {} holds f32 values",
                    args.input.display()
                );
            }
            0.0
        }
    };
    let units = match kind {
        InputKind::Dn => "DN",
        InputKind::Float => args.units.as_str(),
    };
    let full_scale = (kind == InputKind::Dn).then(|| model.max_dn());
    let defects = image_defects(&args.input, &image, &sensor, full_scale)?;
    let replaced = defects.defects.count();
    let clean = if replaced > 0 {
        bad_pixels::replace(image.view(), &defects.defects).context("replacing defective pixels")?
    } else {
        image.clone()
    };
    let signal = clean.mapv(|v| v - black);
    // The sensor model's noise at the image's mean level (DN or electrons).
    let mean = signal.mean().unwrap_or(0.0);
    let model_variance = match kind {
        InputKind::Dn => {
            let k = model.gain_dn_per_e();
            let mean_e = (mean / k).max(0.0);
            Some(model.temporal_noise_dn(mean_e).powi(2) + model.quantisation_noise_dn().powi(2))
        }
        InputKind::Float if units == "electrons" => {
            Some(model.temporal_noise_e(mean.max(0.0)).powi(2))
        }
        InputKind::Float => None,
    };
    let rule = match (args.nsr, args.noise.as_str()) {
        (Some(x), _) => NoiseRule::Constant(x),
        (None, "model") => match model_variance {
            Some(v) => NoiseRule::Model { noise_variance: v },
            None => bail!(
                "--noise model needs DN or electrons to know the noise level; for radiance use --noise auto or --nsr"
            ),
        },
        (None, _) => NoiseRule::Auto,
    };
    let method = Method::parse(&args.method)?;
    let noise_mask = defects.defects.union(&defects.saturated)?;
    let saturated = defects.saturated.clone();
    let masks = RestoreMasks {
        noise: Some(&noise_mask),
        saturated: (saturated.count() > 0).then_some(&saturated),
    };
    let transfer = SensorTransfer::new(&sensor)?;
    let r = wiener::restore(signal.view(), &transfer, rule, method, masks)?;
    let model_sigma = model_variance.map(f64::sqrt);
    if let (Some(m), Some(s)) = (r.noise_sigma_measured, model_sigma) {
        if !(0.5..=2.0).contains(&(m / s)) {
            eprintln!(
                "warning: the image's own noise ({m:.4} {units} rms, Immerkær) differs from the sensor model's ({s:.4}) by more than 2×: is this the sensor and black level that recorded it?"
            );
        }
    }
    let restored = r.image.mapv(|v| v + black);
    let mtf_nyquist_x = transfer.eval(0.5, 0.0);
    let mtf_nyquist_y = transfer.eval(0.0, 0.5);
    let report = json!({
        "input": args.input.display().to_string(),
        "sensor": sensor.name,
        "options": sensor.selected_options,
        "units": units,
        "black_level_dn": if kind == InputKind::Dn { Some(black) } else { None },
        "pixels_replaced": replaced,
        "defects": {
            "source": defects.source,
            "replaced": replaced,
            "clusters": defects.clusters,
            "largest_cluster_px": defects.largest_cluster,
            "saturated_px": saturated.count(),
            "saturated_raised_px": r.saturated_raised,
            "saturated_filled_px": r.saturated_filled,
            "saturated_fill_variance": r.saturated_fill_variance,
        },
        "noise_rule": r.rule,
        "method": r.method,
        "method_requested": if args.nsr.is_some() { "constant" } else { args.method.as_str() },
        "candidates": r.candidates.iter().map(|c| json!({"method": c.name, "parameter": c.parameter, "relative_error": c.relative_risk})).collect::<Vec<_>>(),
        "sharpness_guard_bins": r.guarded_bins,
        "nsr": match rule { NoiseRule::Constant(x) => json!(x), _ => json!(null) },
        "nsr_median": r.nsr_median,
        "noise_power": r.noise_power,
        "noise_sigma": r.noise_sigma,
        "noise_sigma_measured": r.noise_sigma_measured,
        "noise_sigma_model": model_sigma,
        "object_spectrum_exponent": r.spectrum_exponent,
        "transfer_function": {
            "mtf_at_nyquist_x": mtf_nyquist_x,
            "mtf_at_nyquist_y": mtf_nyquist_y,
            "spectral_weighting_temperature_k": transfer.reference_temperature_k(),
            "components": sensor.otf().components().iter().map(|c| c.name()).collect::<Vec<_>>(),
        },
        "padded_shape": [r.padded_shape.0, r.padded_shape.1],
        "input_stats": ImageStats::of(&image),
        "output_stats": ImageStats::of(&restored),
    });
    // Everything is computed: only now touch the output directory, all three products
    // as one set (the old set stays whole until the new one is complete).
    let written = write_restored(
        &args.output,
        &restored,
        &report,
        "the input holds values too large for the restoration to be stored",
    )?;
    println!(
        "{}: {} ({}{}), MTF at Nyquist {:.3} (x) {:.3} (y), {} pixels replaced",
        sensor.name,
        r.method,
        r.rule,
        match (rule, r.noise_sigma) {
            (NoiseRule::Constant(x), _) => format!(" NSR {x}"),
            (_, Some(s)) => format!(", noise {s:.4} {units} rms"),
            _ => String::new(),
        },
        mtf_nyquist_x,
        mtf_nyquist_y,
        replaced
    );
    for p in written {
        println!("wrote {}", p.display());
    }
    Ok(())
}
