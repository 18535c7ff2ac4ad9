//! `eoir psf`: pictures of the pupil PSF across the field (docs/wavefront.md).

use std::path::PathBuf;

use anyhow::{Context, Result};
use ndarray::Array3;

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
const DECADES: f64 = 4.0;
/// Pixels between pictures.
const GAP: usize = 4;
/// Each PSF sample (λ/(4D)) is drawn as ZOOM × ZOOM pixels.
const ZOOM: usize = 2;

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
    let wavelength_m = wavelength_um * 1e-6;
    let mut tiles = Vec::new();
    let mut reports = Vec::new();
    for &h in &args.field {
        let t = eoir::sensor::wavefront::pupil_transfer(&config, h, wavelength_m, 4)
            .with_context(|| format!("PSF at field height {h}"))?;
        let (cx, cy) = t.centroid_rad();
        reports.push(FieldPsfReport {
            field_h: h,
            wavelength_um,
            centroid_x_urad: cx * 1e6,
            centroid_y_urad: cy * 1e6,
            fwhm_urad: t.fwhm_rad() * 1e6,
            strehl: t.strehl(),
            samples_across_pupil: t.sampling().samples_across,
        });
        // λ/D is `padding` = 4 PSF samples.
        let psf = t.psf();
        let m = psf.nrows() as i64;
        let half = ((hw * 4.0).round() as i64).min(m / 2 - 1);
        let peak = psf.iter().cloned().fold(0.0, f64::max);
        let side = (2 * half + 1) as usize;
        let mut tile = vec![[0u8; 3]; side * side];
        for (i, row) in (-half..=half).rev().enumerate() {
            for (j, col) in (-half..=half).enumerate() {
                let v = psf[((m / 2 + row) as usize, (m / 2 + col) as usize)] / peak;
                let t = (v.max(10f64.powf(-DECADES)).log10() + DECADES) / DECADES;
                tile[i * side + j] = eoir::display::inferno(t);
            }
        }
        tiles.push((side, tile));
    }
    let side = tiles[0].0;
    let zside = side * ZOOM;
    let width = tiles.len() * zside + (tiles.len() - 1) * GAP;
    let mut rgb = Array3::<u8>::zeros((zside, width, 3));
    for (k, (_, tile)) in tiles.iter().enumerate() {
        let x0 = k * (zside + GAP);
        for r in 0..zside {
            for c in 0..zside {
                for ch in 0..3 {
                    rgb[(r, x0 + c, ch)] = tile[(r / ZOOM) * side + c / ZOOM][ch];
                }
            }
        }
    }
    eoir::io::output::create_dir_all_guarded(&args.out)?;
    let png = args.out.join("psf_grid.png");
    eoir::io::raster::write_png_rgb8(&png, rgb.view())?;
    let json = args.out.join("psf.json");
    let text = serde_json::to_string_pretty(&serde_json::json!({
        "sensor": sensor.name,
        "wavelength_um": wavelength_um,
        "picture": format!(
            "one tile per field height, left to right; each ±{hw} λ/D, normalised to its peak, \
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
