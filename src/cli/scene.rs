//! CLI glue for `eoir scene`: a built-in synthetic scene sized to a sensor (or to explicit
//! rows, columns and field of view), written as one set of files.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};

use eoir::scene::sizing::{self, DetectorGrid};
use eoir::scene::synthetic::{self, SceneParams};
use eoir::sensor::Sensor;

use crate::cli::sensor_args::SensorArgs;

/// Arguments of `eoir scene`.
#[derive(Debug, clap::Args)]
pub struct SceneArgs {
    /// Scene kind: thermal, bars, edge, blackbody, ramp.
    kind: String,
    /// Output file; the format follows the extension (.hdr ENVI, .exr, .npy, .h5).
    #[arg(short, long)]
    output: PathBuf,
    /// The sensor the scene is made for: it covers the sensor's field of view (plus
    /// --margin-px) at --oversampling scene samples per pixel, over the sensor's band.
    #[command(flatten)]
    sensor: SensorArgs,
    /// Scene samples per detector pixel, an integer k: the cube is k times the detector plus
    /// margin along each axis [default: the smallest k whose Nyquist frequency reaches the
    /// optics' cutoff D/λ at the shortest wavelength, between 2 and 4; 1 with explicit
    /// --rows/--cols/--fov-deg, where the cube is rows·k × cols·k].
    #[arg(long)]
    oversampling: Option<usize>,
    /// Detector pixels of scene beyond each edge of the sensor's field of view.
    #[arg(long, default_value_t = sizing::DEFAULT_MARGIN_PX)]
    margin_px: usize,
    /// Explicit size instead of sizing to the sensor: rows before oversampling (needs
    /// --cols and --fov-deg).
    #[arg(long, requires_all = ["cols", "fov_deg"])]
    rows: Option<usize>,
    /// Explicit size: columns before oversampling (needs --rows and --fov-deg).
    #[arg(long, requires_all = ["rows", "fov_deg"])]
    cols: Option<usize>,
    /// Explicit size: horizontal field of view, degrees (the vertical one follows from
    /// rows/cols; needs --rows and --cols).
    #[arg(long, requires_all = ["rows", "cols"], conflicts_with = "margin_px")]
    fov_deg: Option<f64>,
    /// Shortest wavelength, µm (default: where the sensor's response begins).
    #[arg(long)]
    lo_um: Option<f64>,
    /// Longest wavelength, µm (default: where the sensor's response ends).
    #[arg(long)]
    hi_um: Option<f64>,
    /// Number of bands (default: one every 0.02 µm or less, at least 24).
    #[arg(long)]
    bands: Option<usize>,
    /// Range to the scene, m.
    #[arg(long)]
    range_m: Option<f64>,
    /// Seed for textures.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Night: no reflected sunlight.
    #[arg(long)]
    night: bool,
    /// Temperature for `blackbody`, K.
    #[arg(long, default_value_t = 300.0)]
    temperature_k: f64,
    /// Emissivity for `blackbody`.
    #[arg(long, default_value_t = 1.0)]
    emissivity: f64,
    /// Low temperature (`edge`, `ramp`, `bars` background), K.
    #[arg(long, default_value_t = 295.0)]
    t_low_k: f64,
    /// High temperature (`edge`, `ramp`, `bars` bars), K.
    #[arg(long, default_value_t = 305.0)]
    t_high_k: f64,
    /// Edge angle, degrees.
    #[arg(long, default_value_t = synthetic::DEFAULT_EDGE_ANGLE_DEG)]
    angle_deg: f64,
}

/// The detector grid of `sensor` (pixel counts and IFOV) for scene sizing.
pub fn detector_grid(sensor: &Sensor) -> DetectorGrid {
    DetectorGrid {
        rows: sensor.detector.rows,
        cols: sensor.detector.cols,
        ifov_rad: sensor.ifov_rad(),
    }
}

/// The wavelength grid: explicit bounds and count where given, the sensor's response
/// support and [`sizing::response_grid_um`]'s spacing otherwise.
fn wavelengths(sensor: &Sensor, args: &SceneArgs) -> Result<Vec<f64>> {
    let (lo, hi) = sensor.response().support_um();
    let lo = args.lo_um.unwrap_or(lo);
    let hi = args.hi_um.unwrap_or(hi);
    let grid = match args.bands {
        Some(b) => SceneParams::uniform_grid(lo, hi, b)?,
        None => sizing::response_grid_um(lo, hi).with_context(|| {
            format!(
                "sensor `{}`: give --lo-um and --hi-um for the scene's wavelengths",
                sensor.name
            )
        })?,
    };
    Ok(grid)
}

/// `eoir scene`.
pub fn scene(args: SceneArgs) -> Result<()> {
    let sensor = args.sensor.load()?;
    let grid = detector_grid(&sensor);
    let wavelength_um = wavelengths(&sensor, &args)?;
    // The optics' cutoff at the shortest wavelength, if an aperture term bounds it.
    let cutoff = wavelength_um
        .first()
        .and_then(|l| eoir::imaging::scene_band::optical_cutoff_cy_per_rad(sensor.otf(), *l))
        .filter(|c| c.is_finite());
    let oversampling = args
        .oversampling
        .unwrap_or_else(|| sizing::default_oversampling(grid.ifov_rad, cutoff));
    let sized = match (args.rows, args.cols, args.fov_deg) {
        (Some(rows), Some(cols), Some(fov_x_deg)) => SceneParams {
            rows,
            cols,
            oversampling: args.oversampling.unwrap_or(1),
            fov_x_deg,
            ..SceneParams::default()
        },
        (None, None, None) => sizing::covering(&grid, oversampling, args.margin_px)
            .with_context(|| format!("sizing the scene to sensor `{}`", sensor.name))?,
        _ => bail!("--rows, --cols and --fov-deg go together (or give none to size the scene to the sensor)"),
    };
    let params = SceneParams {
        wavelength_um,
        range_m: args.range_m,
        seed: args.seed,
        sun: !args.night,
        ..sized
    };
    let cube = match args.kind.as_str() {
        "thermal" => synthetic::thermal(&params)?,
        "bars" => synthetic::bars(&params, args.t_high_k, args.t_low_k)?,
        "edge" => synthetic::edge(&params, args.t_low_k, args.t_high_k, args.angle_deg)?,
        "blackbody" => synthetic::blackbody(&params, args.temperature_k, args.emissivity)?,
        "ramp" => synthetic::ramp(&params, args.t_low_k, args.t_high_k)?,
        other => bail!(
            "unknown scene kind `{other}`; choose one of: {}",
            synthetic::KINDS
                .iter()
                .map(|(n, _)| *n)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let written = eoir::io::write_cube_set(&args.output, &cube)?;
    let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    let w = &params.wavelength_um;
    let (fov_x, fov_y) = (params.fov_x_deg, params.fov_y_deg());
    println!(
        "wrote {} ({} scene, {} x {} px x {} bands, {:.4}–{:.4} µm, field of view {fov_x:.4} x {fov_y:.4}°)",
        names.join(", "),
        args.kind,
        cube.meta.cols,
        cube.meta.rows,
        cube.meta.bands(),
        w[0],
        w[w.len() - 1],
    );
    let (sx, sy) = grid.fov_deg();
    if let Some(k) = cutoff.and_then(|c| sizing::oversampling_for_cutoff(grid.ifov_rad, c)) {
        if args.fov_deg.is_none() && params.oversampling < k {
            println!(
                "  note: the optics pass up to {:.3} cy/mrad; {} scene samples per pixel hold up to {:.3} (`eoir run` tapers the transfer function there); --oversampling {k} holds it all",
                cutoff.unwrap_or(0.0) * 1e-3,
                params.oversampling,
                params.oversampling as f64 / (2.0 * grid.ifov_rad) * 1e-3,
            );
        }
    }
    if args.fov_deg.is_none() {
        println!(
            "  sized for `{}`: {} x {} px ({sx:.4} x {sy:.4}°) plus {} px each side, {} scene samples per pixel",
            sensor.name, grid.cols, grid.rows, args.margin_px, params.oversampling
        );
    } else if fov_x < sx || fov_y < sy {
        eprintln!(
            "warning: the scene's field of view {fov_x:.4} x {fov_y:.4}° is smaller than `{}`'s {sx:.4} x {sy:.4}°: `eoir run` with that sensor will refuse it (omit --rows/--cols/--fov-deg to size the scene to the sensor)",
            sensor.name
        );
    }
    Ok(())
}
