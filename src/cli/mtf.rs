//! `eoir mtf`: print or plot a sensor's transfer functions.

use std::path::PathBuf;

use anyhow::{Context, Result};

use eoir::report::{mean_wavelength_um, MtfCurves};

/// Arguments of `eoir mtf`.
#[derive(Debug, clap::Args)]
pub struct MtfArgs {
    #[command(flatten)]
    pub sensor: super::sensor_args::SensorArgs,
    /// Wavelength, µm (default: the response-weighted mean wavelength of the sensor).
    #[arg(long)]
    pub wavelength_um: Option<f64>,
    /// Highest frequency, cycles/mrad (default: max of optical cutoff and 2 × Nyquist).
    #[arg(long)]
    pub max_cy_per_mrad: Option<f64>,
    /// Number of frequency points.
    #[arg(long, default_value_t = 201)]
    pub points: usize,
    /// Write the curves as CSV (`-`: standard output).
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write a PNG plot.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Add the tangential and sagittal pupil MTF at this normalised field height (0..1),
    /// from `[optics.wavefront]` (docs/wavefront.md): columns `pupil_tangential_H…` and
    /// `pupil_sagittal_H…`.
    #[arg(long)]
    pub field: Option<f64>,
}

/// Prints the transfer functions, or writes them as CSV / PNG.
pub fn mtf(args: MtfArgs) -> Result<()> {
    let sensor = args.sensor.load()?;
    for w in sensor.warnings() {
        eprintln!("warning: {w}");
    }
    let wavelength_um = match args.wavelength_um {
        Some(w) => w,
        None => mean_wavelength_um(&sensor).context("choosing the default wavelength")?,
    };
    // Every curve (about a dozen components) holds one f64 per point, plus the CSV text.
    eoir::limits::check_alloc("--points", &[("points", args.points as u64)], 16 * 8 + 200)?;
    let to_stdout = args.csv.as_deref().is_some_and(eoir::io::output::is_stdout);
    let mut curves = MtfCurves::compute(&sensor, wavelength_um, args.max_cy_per_mrad, args.points)?;
    if let Some(h) = args.field {
        let config = args.sensor.load_config()?;
        let t = eoir::sensor::wavefront::pupil_transfer(&config, h, wavelength_um * 1e-6, 2)
            .with_context(|| format!("--field {h}"))?;
        // Frequency along the field direction (tangential) and across it (sagittal).
        let f_cy_per_rad: Vec<f64> = curves.freq_cy_per_mrad.iter().map(|f| f * 1e3).collect();
        let (tan, sag) = t.tangential_sagittal_cy_per_rad(&f_cy_per_rad);
        curves.columns.push((format!("pupil_tangential_H{h}"), tan));
        curves.columns.push((format!("pupil_sagittal_H{h}"), sag));
    }
    let at_nyquist = curves.system_at_nyquist;
    if to_stdout {
        use std::io::Write;
        let mut out = std::io::stdout().lock();
        out.write_all(curves.csv_text().as_bytes())
            .and_then(|_| out.flush())
            .context("writing the CSV to standard output")?;
        if let Some(path) = &args.png {
            curves.write_png(path, &sensor.name)?;
            eprintln!("wrote {}", path.display());
        }
        return Ok(());
    }
    println!(
        "{}: λ = {:.3} µm, optical cutoff {:.3} cy/mrad, detector Nyquist {:.3} cy/mrad, system MTF at Nyquist {:.4}",
        sensor.name, wavelength_um, curves.cutoff_cy_per_mrad, curves.nyquist_cy_per_mrad, at_nyquist
    );
    println!(
        "components: {}",
        curves
            .columns
            .iter()
            .map(|(n, _)| n.as_str())
            .filter(|n| *n != "system")
            .collect::<Vec<_>>()
            .join(", ")
    );
    if let Some(path) = &args.csv {
        curves.write_csv(path)?;
        println!("wrote {}", path.display());
    }
    if let Some(path) = &args.png {
        curves.write_png(path, &sensor.name)?;
        println!("wrote {}", path.display());
    }
    if args.csv.is_none() && args.png.is_none() {
        print!("{:>12}", "cy/mrad");
        for (n, _) in &curves.columns {
            print!(" {n:>11}");
        }
        println!();
        let step = (curves.freq_cy_per_mrad.len() / 20).max(1);
        for i in (0..curves.freq_cy_per_mrad.len()).step_by(step) {
            print!("{:>12.4}", curves.freq_cy_per_mrad[i]);
            for (_, v) in &curves.columns {
                print!(" {:>11.5}", v[i]);
            }
            println!();
        }
    }
    Ok(())
}
