//! The `eoir` command line: parses arguments, calls the library, prints what it did.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod cli;

use cli::{characterize, edge_mtf, mtf, nuc, restore, run, scene, sensors};

/// `eoir --version`: the version and the optional features compiled in, so a user (and
/// the tests run against a build with `--features hdf5`) can tell which build this is.
const LONG_VERSION: &str = if cfg!(feature = "hdf5") {
    concat!(env!("CARGO_PKG_VERSION"), " (optional features: hdf5)")
} else {
    concat!(env!("CARGO_PKG_VERSION"), " (optional features: none)")
};

/// eoir — turns synthetic hyperspectral radiance into the imagery a real EO/IR camera records.
#[derive(Debug, Parser)]
#[command(name = "eoir", version, long_version = LONG_VERSION, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Memory limit for any single run, e.g. 512M or 8G (default: 3/4 of physical memory).
    /// Sizes from files and options are checked against it before allocating.
    #[arg(long, global = true, value_name = "SIZE")]
    max_memory: Option<String>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run a radiance cube through a sensor: writes DN, mean electrons, config and report.
    Run(run::RunArgs),
    /// Generate the built-in thermal scene and run it through the default MWIR sensor.
    Demo(run::DemoArgs),
    /// Write a built-in synthetic scene as a radiance cube sized to a sensor (any format).
    Scene(scene::SceneArgs),
    /// Convert a DN image (or in-band radiance) to apparent temperature through a sensor.
    Temperature(cli::temperature::TemperatureArgs),
    /// Print or plot the transfer functions (MTF) of a sensor along the x axis.
    Mtf(mtf::MtfArgs),
    /// Pictures of the pupil PSF across the field (`[optics.wavefront]`): psf_grid.png,
    /// psf.json.
    Psf(cli::psf::PsfArgs),
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
    /// Find random telegraph (RTS) pixels in a dark sequence (a run's `dn_stack.npy`).
    Rts(cli::rts::RtsArgs),
    /// Figures of merit of a sensor (3-D noise, NETD, MTF, MRTD, GIQE 5, TTP ranges),
    /// analytic and measured on simulated frames.
    Assess(cli::assess::AssessArgs),
    /// Trade study: the analytic figures of merit over a grid of sensor parameters.
    Sweep(cli::sweep::SweepArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Err(e) = setup(&cli) {
        eprintln!("error: {}", one_line(&e));
        return ExitCode::FAILURE;
    }
    let result = match cli.command {
        Command::Run(args) => run::run(args),
        Command::Demo(args) => run::demo(args),
        Command::Scene(args) => scene::scene(args),
        Command::Temperature(args) => cli::temperature::temperature(args),
        Command::Mtf(args) => mtf::mtf(args),
        Command::Psf(args) => cli::psf::psf(args),
        Command::Sensors(args) => sensors::sensors(args),
        Command::Restore(args) => restore::restore(args),
        Command::EdgeMtf(args) => edge_mtf::edge_mtf(args),
        Command::Characterize(args) => characterize::characterize(args),
        Command::Nuc(args) => nuc::nuc(args),
        Command::Rts(args) => cli::rts::rts(args),
        Command::Assess(args) => cli::assess::assess(args),
        Command::Sweep(args) => cli::sweep::sweep(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", one_line(&e));
            ExitCode::FAILURE
        }
    }
}

/// Process-wide safety settings: the SIGINT/SIGTERM handler that removes unfinished
/// outputs, and the memory limit.
fn setup(cli: &Cli) -> anyhow::Result<()> {
    eoir::io::output::install_signal_handler()?;
    eoir::io::mapped::install_sigbus_message();
    // The main thread is one of rayon's workers (the pool keeps RAYON_NUM_THREADS or one
    // thread per core, this one included): while it reads the next chunk of bands the
    // other workers transform the current one, and when it is done reading it helps with
    // them, instead of a reading thread competing with a full pool for the cores (-14 %
    // engine time at 1024² × 128 on 2 cores, BENCHMARKS.md).
    rayon::ThreadPoolBuilder::new()
        .use_current_thread()
        .build_global()
        .map_err(|e| anyhow::anyhow!("could not start the thread pool: {e}"))?;
    if let Some(m) = &cli.max_memory {
        eoir::limits::set_max_memory_bytes(eoir::limits::parse_bytes(m)?)?;
    }
    Ok(())
}

/// The error and its causes on one line; a cause whose text the message already
/// contains (an I/O error the typed error printed) is not repeated.
fn one_line(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for c in e.chain() {
        let text = c.to_string();
        if line.contains(&text) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&text);
    }
    line
}
