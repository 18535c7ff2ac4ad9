//! The `eoir` command line: parses arguments, calls the library, prints what it did.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};

use eoir::report::{mean_wavelength_um, MtfCurves};
use eoir::sensor::presets;

mod run;

/// eoir — turns synthetic hyperspectral radiance into the imagery a real EO/IR camera records.
#[derive(Debug, Parser)]
#[command(name = "eoir", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run a radiance cube through a sensor: writes DN, mean electrons, config and report.
    Run(run::RunArgs),
    /// Generate the built-in thermal scene and run it through the default MWIR sensor.
    Demo(run::DemoArgs),
    /// Write a built-in synthetic scene as a radiance cube (any supported format).
    Scene(run::SceneArgs),
    /// Convert a DN image (or in-band radiance) to apparent temperature through a sensor.
    Temperature(run::TemperatureArgs),
    /// Print or plot the transfer functions (MTF) of a sensor along the x axis.
    Mtf(MtfArgs),
    /// List the built-in sensor presets, or print one fully resolved (`sensors show NAME`).
    Sensors(SensorsArgs),
}

#[derive(Debug, clap::Args)]
struct SensorsArgs {
    /// `show` to print a preset's resolved TOML.
    action: Option<String>,
    /// The preset to show.
    name: Option<String>,
    /// Select a preset option, e.g. `--option filter=3` (repeatable).
    #[arg(long = "option", value_name = "NAME=VALUE")]
    option: Vec<String>,
}

#[derive(Debug, clap::Args)]
struct MtfArgs {
    #[command(flatten)]
    sensor: run::SensorArgs,
    /// Wavelength, µm (default: the response-weighted mean wavelength of the sensor).
    #[arg(long)]
    wavelength_um: Option<f64>,
    /// Highest frequency, cycles/mrad (default: max of optical cutoff and 2 × Nyquist).
    #[arg(long)]
    max_cy_per_mrad: Option<f64>,
    /// Number of frequency points.
    #[arg(long, default_value_t = 201)]
    points: usize,
    /// Write the curves as CSV.
    #[arg(long)]
    csv: Option<PathBuf>,
    /// Write a PNG plot.
    #[arg(long)]
    png: Option<PathBuf>,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run(args) => run::run(args),
        Command::Demo(args) => run::demo(args),
        Command::Scene(args) => run::scene(args),
        Command::Temperature(args) => run::temperature(args),
        Command::Mtf(args) => mtf(args),
        Command::Sensors(args) => sensors(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", one_line(&e));
            ExitCode::FAILURE
        }
    }
}

/// The error and its causes on one line.
fn one_line(e: &anyhow::Error) -> String {
    e.chain()
        .map(|c| c.to_string())
        .collect::<Vec<_>>()
        .join(": ")
}

/// Parses `H,V` (two numbers).
fn parse_pair(text: &str, what: &str) -> Result<(f64, f64)> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != 2 {
        bail!("{what} `{text}`: expected two comma-separated numbers, e.g. 5.3,4.0");
    }
    let a: f64 = parts[0]
        .parse()
        .with_context(|| format!("{what} `{text}`"))?;
    let b: f64 = parts[1]
        .parse()
        .with_context(|| format!("{what} `{text}`"))?;
    Ok((a, b))
}

fn sensors(args: SensorsArgs) -> Result<()> {
    match (args.action.as_deref(), args.name.as_deref()) {
        (None, _) => {
            for p in presets::list() {
                println!("{:<12} {}", p.name, p.description);
                for (opt, values) in &p.options {
                    let default = p
                        .defaults
                        .iter()
                        .find(|(o, _)| o == opt)
                        .map(|(_, v)| format!(" (default {v})"))
                        .unwrap_or_default();
                    println!("{:<12}   --option {opt}={}{default}", "", values.join("|"));
                }
            }
            Ok(())
        }
        (Some("show"), Some(name)) => {
            print!("{}", presets::resolved_toml(name, &args.option)?);
            Ok(())
        }
        (Some("show"), None) => {
            bail!("`eoir sensors show NAME`: name a preset (see `eoir sensors`)")
        }
        (Some(other), _) => {
            bail!("unknown action `{other}`: use `eoir sensors` or `eoir sensors show NAME`")
        }
    }
}

fn mtf(args: MtfArgs) -> Result<()> {
    let sensor = args.sensor.load()?;
    for w in sensor.warnings() {
        eprintln!("warning: {w}");
    }
    let wavelength_um = match args.wavelength_um {
        Some(w) => w,
        None => mean_wavelength_um(&sensor).context("choosing the default wavelength")?,
    };
    let curves = MtfCurves::compute(&sensor, wavelength_um, args.max_cy_per_mrad, args.points)?;
    let at_nyquist = curves.system_at_nyquist;
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
