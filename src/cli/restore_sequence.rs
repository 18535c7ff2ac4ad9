//! `eoir restore DIR` (or `eoir restore stack.npy`): multi-frame restoration of a sequence
//! (docs/multi-frame.md) — register the frames, shift-and-add them onto a grid finer by
//! `--upsample`, and Wiener-restore the result with the sensor's transfer function on that
//! grid ([`eoir::processing::multi_frame`]).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use ndarray::Array3;
use serde_json::json;

use eoir::processing::bad_pixels;
use eoir::processing::multi_frame::{restore_sequence as restore_stack, SequenceNoise};
use eoir::processing::wiener::{ImageStats, SensorTransfer, IMPULSE_K_SIGMA};
use eoir::sensor::{presets, Sensor};

use super::restore::RestoreArgs;

/// The stack file of an eoir sequence output folder.
const STACK_FILE: &str = "dn_stack.npy";
/// The truth table of an eoir sequence output folder.
const TRUTH_FILE: &str = "los.csv";
/// Default upsampling factor.
const DEFAULT_UPSAMPLE: usize = 2;

/// The flags of `eoir restore` that apply to sequences only.
#[derive(Debug, clap::Args)]
pub struct SequenceArgs {
    /// Sequences: the fine grid's factor R (an integer 1–8; default 2).
    #[arg(long, value_name = "R")]
    pub upsample: Option<usize>,
    /// Sequences: registration by `phase` correlation (default) or the run's `truth`
    /// table (los.csv).
    #[arg(long, value_parser = ["phase", "truth"])]
    pub register: Option<String>,
}

/// Whether `input` is a sequence: a directory or a `.npy` stack.
pub fn is_sequence(input: &Path) -> bool {
    input.is_dir()
        || input
            .extension()
            .is_some_and(|e| e.to_string_lossy().eq_ignore_ascii_case("npy"))
}

/// Refuses the sequence-only flags for a single image.
pub fn refuse_for_single_image(args: &SequenceArgs) -> Result<()> {
    if args.upsample.is_some() || args.register.is_some() {
        bail!("--upsample and --register apply to a sequence (an eoir output folder with dn_stack.npy, or a .npy stack); the input is a single image");
    }
    Ok(())
}

/// Reads the truth table: (dx, dy) per frame, relative to the first line's frame.
fn read_truth(path: &Path, frames: usize) -> Result<Vec<(f64, f64)>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read the truth table", path.display()))?;
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let Some((_, header)) = lines.next() else {
        bail!("{}: empty truth table", path.display());
    };
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let col = |name: &str| {
        names.iter().position(|n| *n == name).with_context(|| {
            format!(
                "{}: the header has no column `{name}` (expected frame,…,dx_px,dy_px,…)",
                path.display()
            )
        })
    };
    let (ci, cx, cy) = (col("frame")?, col("dx_px")?, col("dy_px")?);
    let mut out: Vec<(u64, f64, f64)> = Vec::new();
    for (i, line) in lines {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let get = |c: usize| -> Result<f64> {
            fields
                .get(c)
                .and_then(|v| v.parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .with_context(|| {
                    format!(
                        "{}: line {}: column {} is not a finite number",
                        path.display(),
                        i + 1,
                        c + 1
                    )
                })
        };
        let frame = get(ci)?;
        out.push((frame as u64, get(cx)?, get(cy)?));
    }
    if out.len() != frames {
        bail!(
            "{}: {} lines for {frames} frames; --register truth needs one line per frame (a global shutter; a rolling shutter's table has one per row: use --register phase)",
            path.display(),
            out.len()
        );
    }
    if out.windows(2).any(|w| w[1].0 != w[0].0 + 1) {
        bail!("{}: the frame numbers are not consecutive", path.display());
    }
    let (x0, y0) = (out[0].1, out[0].2);
    Ok(out.iter().map(|(_, x, y)| (x - x0, y - y0)).collect())
}

/// `eoir restore` of a sequence.
pub fn restore_sequence(args: &RestoreArgs) -> Result<()> {
    let seq = &args.sequence;
    let factor = seq.upsample.unwrap_or(DEFAULT_UPSAMPLE);
    eoir::processing::shift_and_add::check_factor(factor)?;
    let (stack_path, dir): (PathBuf, PathBuf) = if args.input.is_dir() {
        let p = args.input.join(STACK_FILE);
        if !p.is_file() {
            bail!(
                "{}: no {STACK_FILE} — not an eoir sequence output folder (a run with --frames 2 or more writes one)",
                args.input.display()
            );
        }
        (p, args.input.clone())
    } else {
        let parent = args
            .input
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."));
        (args.input.clone(), parent)
    };
    // The sensor: a folder's own config.toml, else the one named.
    let own = dir.join("config.toml");
    let sensor: Sensor = if args.input.is_dir() && own.is_file() {
        if args.sensor.sensor != "multimir"
            || !args.sensor.option.is_empty()
            || !args.sensor.set.is_empty()
        {
            bail!(
                "{}: a sequence folder is restored with the sensor that recorded it (its config.toml); --sensor, --option and --set apply to a .npy stack",
                args.input.display()
            );
        }
        let config = presets::load(&own.display().to_string(), &[], &[])?;
        Sensor::build(&config).with_context(|| format!("resolving {}", own.display()))?
    } else {
        args.sensor.load()?
    };
    let raw = eoir::io::npy::read_stack(&stack_path)?;
    let (frames, rows, cols) = raw.dim();
    if frames < 2 {
        bail!(
            "{}: {frames} frame(s); multi-frame restoration needs at least 2 (restore a single image with `eoir restore IMAGE`)",
            stack_path.display()
        );
    }
    if (rows, cols) != (sensor.detector.rows, sensor.detector.cols) {
        bail!(
            "{}: the frames are {cols} × {rows} pixels (width × height) but sensor `{}` records {} × {}; restore a stack with the sensor that recorded it",
            stack_path.display(),
            sensor.name,
            sensor.detector.cols,
            sensor.detector.rows
        );
    }
    if args.units != "electrons" {
        bail!("--units applies to f32 single images; a stack holds DN");
    }
    let model = sensor.detector();
    let black = args.black_level.unwrap_or_else(|| model.expected_dn(0.0));
    if !black.is_finite() || black < 0.0 {
        bail!("--black-level {black}: expected a finite DN >= 0");
    }
    // Defects (the recording instance's map when instance.json beside the stack names
    // this sensor, else found on the mean frame) and saturated pixels are skipped (NaN).
    let mut stack: Array3<f64> = raw.mapv(f64::from);
    let mean_frame = stack.mean_axis(ndarray::Axis(0)).context("empty stack")?;
    let full_scale = model.max_dn();
    let found =
        bad_pixels::find_image_defects(mean_frame.view(), IMPULSE_K_SIGMA, Some(full_scale))
            .context("finding defective pixels")?;
    let (defects, source) = match super::defects::instance_defects(&stack_path, &sensor)? {
        Some(map) if map.dim() == (rows, cols) => (map, "instance"),
        _ => (found.defects, "image"),
    };
    let mut skipped = 0usize;
    for mut frame in stack.outer_iter_mut() {
        for ((r, c), v) in frame.indexed_iter_mut() {
            if defects.mask()[[r, c]] || *v >= full_scale || *v <= 0.0 {
                *v = f64::NAN;
                skipped += 1;
            } else {
                *v -= black;
            }
        }
    }
    let truth_path = dir.join(TRUTH_FILE);
    let truth = if truth_path.is_file() {
        Some(read_truth(&truth_path, frames))
    } else {
        None
    };
    let register = seq.register.as_deref().unwrap_or("phase");
    let given = match register {
        "truth" => match truth {
            Some(Ok(ref t)) => Some(t.clone()),
            Some(Err(e)) => return Err(e),
            None => bail!(
                "--register truth: {} does not exist (only runs of a moving camera write one)",
                truth_path.display()
            ),
        },
        _ => None,
    };
    let noise = SequenceNoise::from_rule(args.nsr, &args.noise, stack.view(), model)?;
    let transfer = SensorTransfer::new(&sensor)?;
    let r = restore_stack(stack.view(), given.as_deref(), factor, &transfer, noise)?;
    let restored = r.restoration.image.mapv(|v| v + black);
    let residual = match &truth {
        Some(Ok(t)) => {
            let d: Vec<(f64, f64)> = r
                .shifts
                .iter()
                .zip(t)
                .map(|(e, t)| (e.dx_px - t.0, e.dy_px - t.1))
                .collect();
            let max = d
                .iter()
                .map(|(x, y)| x.abs().max(y.abs()))
                .fold(0.0f64, f64::max);
            let rms = (d.iter().map(|(x, y)| x * x + y * y).sum::<f64>() / d.len() as f64).sqrt();
            Some(
                json!({"max_px": max, "rms_px": rms, "per_frame": d.iter().map(|(x, y)| [x, y]).collect::<Vec<_>>()}),
            )
        }
        _ => None,
    };
    let report = json!({
        "input": args.input.display().to_string(),
        "sensor": sensor.name,
        "frames": frames,
        "upsample": factor,
        "fine_shape": [rows * factor, cols * factor],
        "registration": register,
        "shifts_px": r.shifts.iter().map(|t| json!({"dx": t.dx_px, "dy": t.dy_px, "peak": if t.peak.is_finite() { json!(t.peak) } else { json!(null) }})).collect::<Vec<_>>(),
        "shift_residual_vs_truth": residual,
        "black_level_dn": black,
        "defects_source": source,
        "samples_skipped": skipped,
        "holes_filled": r.fine.holes_filled,
        "noise_rule": noise.name(),
        "nsr": match noise { SequenceNoise::Constant(x) => json!(x), _ => json!(null) },
        "fine_noise_variance_dn2": r.fine_noise_variance,
        "sample_variance_dn2": r.fine.sample_variance,
        "nsr_median": r.restoration.nsr_median,
        "object_spectrum_exponent": r.restoration.spectrum_exponent,
        "padded_shape": [r.restoration.padded_shape.0, r.restoration.padded_shape.1],
        "output_stats": ImageStats::of(&restored),
    });
    let written = super::restore::write_restored(
        &args.output,
        &restored,
        &report,
        "the restoration holds values too large to be stored",
    )?;
    println!(
        "{}: {frames} frames registered by {register}, shift-and-add ×{factor} ({} holes filled), Wiener ({})",
        sensor.name,
        r.fine.holes_filled,
        report["noise_rule"].as_str().unwrap_or("")
    );
    for p in written {
        println!("wrote {}", p.display());
    }
    Ok(())
}
