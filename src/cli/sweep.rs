//! `eoir sweep`: the analytic figures of merit over a grid of sensor parameters (a trade
//! study), evaluated in parallel: `sweep.csv` and one plot per figure against the first
//! varied parameter (docs/figures-of-merit.md).

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use rayon::prelude::*;

use eoir::merit::assess::{self, AssessOptions};
use eoir::plot::{self, LinePlot, Series};
use eoir::sensor::{presets, Sensor};

use super::assess::{parse_grid, TaskArgs};
use super::sensor_args::SensorArgs;

/// Arguments of `eoir sweep`.
#[derive(Debug, clap::Args)]
pub struct SweepArgs {
    /// The sensor and its fixed options and overrides.
    #[command(flatten)]
    pub sensor: SensorArgs,
    /// A varied sensor field, `KEY=START:STOP:N` (repeatable; the grid is their product).
    #[arg(long = "vary", value_name = "KEY=START:STOP:N", required = true)]
    pub vary: Vec<String>,
    /// The target and the ranges, as for `eoir assess`.
    #[command(flatten)]
    pub task: TaskArgs,
    /// Output directory (sweep.csv, one PNG per figure).
    #[arg(short, long)]
    pub output: PathBuf,
}

/// Largest number of grid points.
pub const MAX_POINTS: usize = 100_000;

/// One varied key and its values.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    /// Sensor field (dotted path, as `--set` takes).
    pub key: String,
    /// Values.
    pub values: Vec<f64>,
}

/// Parses `--vary KEY=START:STOP:N`.
pub fn parse_vary(text: &str) -> Result<Axis> {
    let Some((k, grid)) = text.split_once('=') else {
        bail!("--vary `{text}`: expected KEY=START:STOP:N, e.g. optics.f_number=1.5:4:6");
    };
    let key = k.trim();
    if key.is_empty() {
        bail!("--vary `{text}`: the key is empty");
    }
    Ok(Axis {
        key: key.to_string(),
        values: parse_grid(grid, &format!("--vary {key}"))?,
    })
}

/// The grid points (one value per axis), the first axis varying slowest.
pub fn grid(axes: &[Axis]) -> Result<Vec<Vec<f64>>> {
    let n: usize = axes
        .iter()
        .try_fold(1usize, |acc, a| acc.checked_mul(a.values.len()))
        .unwrap_or(usize::MAX);
    if n > MAX_POINTS {
        bail!("--vary: the grid has {n} points, more than {MAX_POINTS}");
    }
    let mut points = vec![Vec::new()];
    for a in axes {
        points = points
            .into_iter()
            .flat_map(|p| {
                a.values.iter().map(move |v| {
                    let mut q = p.clone();
                    q.push(*v);
                    q
                })
            })
            .collect();
    }
    Ok(points)
}

/// Names of the figures in `sweep.csv`, in column order.
pub const FIGURES: [&str; 10] = [
    "netd_k",
    "mtf50_cy_per_px",
    "mtf_nyquist",
    "rer",
    "detection_p50_m",
    "detection_p80_m",
    "recognition_p50_m",
    "recognition_p80_m",
    "identification_p50_m",
    "identification_p80_m",
];

/// The analytic figures at one grid point ([`FIGURES`] order; NaN where absent), and a
/// note when the point's sensor is valid but has no figures (e.g. its reference level
/// saturates): such a point is a NaN row of the trade study, not the end of it. A sensor
/// the point's values make invalid (e.g. F-number ≤ 0) is an error.
pub fn figures_at(
    sensor: &str,
    options: &[String],
    sets: &[String],
    axes: &[Axis],
    point: &[f64],
    opts: &AssessOptions,
) -> Result<(Vec<f64>, Option<String>)> {
    let mut all = sets.to_vec();
    for (a, v) in axes.iter().zip(point) {
        all.push(format!("{}={v}", a.key));
    }
    let config = presets::load(sensor, options, &all)?;
    let s = Sensor::build(&config)?;
    let an = match assess::analytic(&s, opts) {
        Ok(an) => an,
        Err(e) => return Ok((vec![f64::NAN; FIGURES.len()], Some(e.to_string()))),
    };
    let mut row = vec![
        an.netd_k.unwrap_or(f64::NAN),
        an.mtf50_cy_per_px.unwrap_or(f64::NAN),
        an.mtf_nyquist,
        an.rer,
    ];
    for t in &an.tasks {
        row.push(t.range_p50_m.unwrap_or(f64::NAN));
        row.push(t.range_p80_m.unwrap_or(f64::NAN));
    }
    Ok((row, None))
}

/// `eoir sweep`.
pub fn sweep(args: SweepArgs) -> Result<()> {
    let axes: Vec<Axis> = args
        .vary
        .iter()
        .map(|v| parse_vary(v))
        .collect::<Result<_>>()?;
    let (target, ranges_m) = args.task.parse()?;
    let opts = AssessOptions {
        target,
        ranges_m,
        analytic_only: true,
        ..Default::default()
    };
    opts.validate().context("--target/--range-km")?;
    let points = grid(&axes)?;
    let results: Vec<(Vec<f64>, Option<String>)> = points
        .par_iter()
        .map(|p| {
            figures_at(
                &args.sensor.sensor,
                &args.sensor.option,
                &args.sensor.set,
                &axes,
                p,
                &opts,
            )
            .with_context(|| {
                let at: Vec<String> = axes
                    .iter()
                    .zip(p)
                    .map(|(a, v)| format!("{}={v}", a.key))
                    .collect();
                format!("sweep point {}", at.join(", "))
            })
        })
        .collect::<Result<_>>()?;
    let failed: Vec<(&Vec<f64>, &String)> = points
        .iter()
        .zip(&results)
        .filter_map(|(p, (_, note))| note.as_ref().map(|n| (p, n)))
        .collect();
    if failed.len() == points.len() {
        bail!(
            "no sweep point has figures of merit; the first: {}",
            failed[0].1
        );
    }
    for (p, note) in &failed {
        let at: Vec<String> = axes
            .iter()
            .zip(p.iter())
            .map(|(a, v)| format!("{}={v}", a.key))
            .collect();
        eprintln!(
            "warning: sweep point {}: {note} (its row is empty)",
            at.join(", ")
        );
    }
    let rows: Vec<&Vec<f64>> = results.iter().map(|(r, _)| r).collect();

    let mut csv = String::new();
    for a in &axes {
        let _ = write!(csv, "{},", a.key);
    }
    csv.push_str(&FIGURES.join(","));
    csv.push_str(",note\n");
    for (p, (r, note)) in points.iter().zip(&results) {
        for v in p {
            let _ = write!(csv, "{v},");
        }
        let cells: Vec<String> = r
            .iter()
            .map(|v| {
                if v.is_finite() {
                    format!("{v:.6e}")
                } else {
                    String::new()
                }
            })
            .collect();
        csv.push_str(&cells.join(","));
        csv.push(',');
        if let Some(n) = note {
            // One CSV field: quoted, inner quotes doubled, on one line.
            let _ = write!(csv, "\"{}\"", n.replace('"', "\"\"").replace('\n', " "));
        }
        csv.push('\n');
    }
    let set = eoir::io::output::ProductSet::begin(&args.output)?;
    set.write_bytes("sweep.csv", csv.as_bytes())?;
    // One plot per figure against the first axis; one curve per combination of the others.
    let inner: usize = axes[1..].iter().map(|a| a.values.len()).product();
    let x = &axes[0].values;
    for (fi, name) in FIGURES.iter().enumerate() {
        let mut curves: Vec<(String, Vec<f64>, Vec<f64>)> = Vec::new();
        for c in 0..inner.min(8) {
            let (mut xs, mut ys) = (Vec::new(), Vec::new());
            for (i, xv) in x.iter().enumerate() {
                let y = rows[i * inner + c][fi];
                if y.is_finite() {
                    xs.push(*xv);
                    ys.push(y);
                }
            }
            let label = if axes.len() == 1 {
                name.to_string()
            } else {
                axes[1..]
                    .iter()
                    .zip(&points[c][1..])
                    .map(|(a, v)| format!("{}={}", a.key, plot::significant(*v, 4)))
                    .collect::<Vec<_>>()
                    .join(", ")
            };
            if !xs.is_empty() {
                curves.push((label, xs, ys));
            }
        }
        if curves.is_empty() {
            continue;
        }
        let series: Vec<Series> = curves
            .iter()
            .map(|(l, xs, ys)| Series {
                label: l,
                x: xs,
                y: ys,
            })
            .collect();
        set.write(format!("{name}.png"), |p| {
            plot::write_line_plot(
                p,
                &LinePlot {
                    title: name,
                    x_label: &axes[0].key,
                    y_label: name,
                    series,
                    markers: vec![],
                    y_range: None,
                    size_px: (900, 600),
                },
            )
        })?;
    }
    let written = set.commit()?;
    println!("{} grid points", points.len());
    for p in written {
        println!("wrote {}", p.display());
    }
    Ok(())
}
