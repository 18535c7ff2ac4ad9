//! `eoir psf`: pictures of the pupil PSF across the field (docs/wavefront.md).

use std::path::PathBuf;

use anyhow::{Context, Result};

use eoir::report::mean_wavelength_um;

/// Arguments of `eoir psf`.
#[derive(Debug, clap::Args)]
pub struct PsfArgs {
    #[command(flatten)]
    pub sensor: super::sensor_args::SensorArgs,
    /// Normalised field heights H in [0, 1], comma-separated (the field lies along the
    /// tangential axis, up in the picture).
    #[arg(long, value_delimiter = ',', default_values_t = [0.0, 0.5, 0.7, 1.0])]
    pub field: Vec<f64>,
    /// Wavelength, µm (default: the response-weighted mean wavelength of the sensor).
    #[arg(long)]
    pub wavelength_um: Option<f64>,
    /// Half-width of each PSF picture, in λ/D.
    #[arg(long, default_value_t = 12.0)]
    pub half_width_lambda_over_d: f64,
    /// Output directory (`psf_grid.png`, `psf.json`).
    #[arg(short = 'o', long, default_value = "psf")]
    pub out: PathBuf,
}

/// One field point of `psf.json`.
#[derive(Debug, serde::Serialize)]
struct FieldPsfReport {
    field_h: f64,
    wavelength_um: f64,
    centroid_x_urad: f64,
    centroid_y_urad: f64,
    fwhm_urad: f64,
    strehl: f64,
    samples_across_pupil: usize,
}

/// Pictures per field point, each normalised to its own peak, log stretch over 4 decades.
const DECADES: f64 = eoir::pipeline::field_pictures::PSF_DECADES;

/// Computes the PSF at each field height and writes `psf_grid.png` and `psf.json`.
pub fn psf(args: PsfArgs) -> Result<()> {
    let sensor = args.sensor.load()?;
    let config = args.sensor.load_config()?;
    if config.optics.wavefront.is_none() {
        eprintln!(
            "note: {} has no [optics.wavefront]: the PSFs are diffraction-limited",
            sensor.name
        );
    }
    let wavelength_um = match args.wavelength_um {
        Some(w) if w.is_finite() && w > 0.0 => w,
        Some(w) => anyhow::bail!("--wavelength-um {w}: expected a wavelength > 0"),
        None => mean_wavelength_um(&sensor).context("choosing the default wavelength")?,
    };
    let hw = args.half_width_lambda_over_d;
    if !(hw.is_finite() && (1.0..=64.0).contains(&hw)) {
        anyhow::bail!("--half-width-lambda-over-d {hw}: expected a number in [1, 64]");
    }
    if args.field.is_empty() || args.field.len() > 16 {
        anyhow::bail!("--field: expected 1 to 16 field heights");
    }
    let (png_bytes, transfers) =
        eoir::pipeline::field_pictures::psf_grid_png(&config, &args.field, wavelength_um, hw)
            .context("PSF grid")?;
    let reports: Vec<FieldPsfReport> = transfers
        .iter()
        .zip(&args.field)
        .map(|(t, &h)| {
            let (cx, cy) = t.centroid_rad();
            FieldPsfReport {
                field_h: h,
                wavelength_um,
                centroid_x_urad: cx * 1e6,
                centroid_y_urad: cy * 1e6,
                fwhm_urad: t.fwhm_rad() * 1e6,
                strehl: t.strehl(),
                samples_across_pupil: t.sampling().samples_across,
            }
        })
        .collect();
    eoir::io::output::create_dir_all_guarded(&args.out)?;
    let png = args.out.join("psf_grid.png");
    eoir::display::write_png_bytes(&png, &png_bytes)?;
    let json = args.out.join("psf.json");
    let text = serde_json::to_string_pretty(&serde_json::json!({
        "sensor": sensor.name,
        "wavelength_um": wavelength_um,
        "picture": format!(
            "one tile per field height, left to right, labelled H = …; each ±{hw} λ/D, normalised to its peak, \
             log10 stretch over {DECADES} decades (inferno); tangential axis up"
        ),
        "fields": reports,
    }))?;
    eoir::io::atomic_write(&json, |w| eoir::io::write_all(w, text.as_bytes(), &json))?;
    for r in &reports {
        println!(
            "H = {:.2}: centroid ({:.2}, {:.2}) µrad, FWHM {:.2} µrad, Strehl {:.3}",
            r.field_h, r.centroid_x_urad, r.centroid_y_urad, r.fwhm_urad, r.strehl
        );
    }
    println!("wrote {}", png.display());
    println!("wrote {}", json.display());
    Ok(())
}
