//! The `eoir` command line: parses arguments, calls the library, prints what it did.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod cli;

use cli::{characterize, edge_mtf, mtf, nuc, restore, run, sensors};

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
    Mtf(mtf::MtfArgs),
    /// Sharpen a recorded image with the sensor's own transfer function (Wiener filter).
    Restore(restore::RestoreArgs),
    /// Measure the MTF of a slanted edge in an image (ISO 12233).
    EdgeMtf(edge_mtf::EdgeMtfArgs),
    /// List the built-in sensor presets, or print one fully resolved (`sensors show NAME`).
    Sensors(sensors::SensorsArgs),
    /// EMVA 1288 characterisation of an acquisition set, or simulate one (`--simulate`).
    Characterize(characterize::CharacterizeArgs),
    /// Non-uniformity correction from blackbody frames: `nuc fit`, `nuc apply`.
    Nuc(nuc::NucArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run(args) => run::run(args),
        Command::Demo(args) => run::demo(args),
        Command::Scene(args) => run::scene(args),
        Command::Temperature(args) => run::temperature(args),
        Command::Mtf(args) => mtf::mtf(args),
        Command::Sensors(args) => sensors::sensors(args),
        Command::Restore(args) => restore::restore(args),
        Command::EdgeMtf(args) => edge_mtf::edge_mtf(args),
        Command::Characterize(args) => characterize::characterize(args),
        Command::Nuc(args) => nuc::nuc(args),
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
