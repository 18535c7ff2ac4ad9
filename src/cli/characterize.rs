//! `eoir characterize`: EMVA 1288 characterisation of an acquisition set, or the
//! simulation of one from a sensor model.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};

use eoir::characterize::{self, SimulateOptions};

/// Arguments of `eoir characterize`.
#[derive(Debug, clap::Args)]
pub struct CharacterizeArgs {
    /// Acquisition set to analyse: a directory holding `descriptor.txt`, or a descriptor
    /// file (EMVA 1288 reference-implementation format). Omit with `--simulate`.
    #[arg(value_name = "SET")]
    pub acquisition_set: Option<PathBuf>,
    /// Write a simulated acquisition set for `--sensor` into the output directory instead.
    #[arg(long)]
    pub simulate: bool,
    #[command(flatten)]
    pub sensor: super::sensor_args::SensorArgs,
    /// Seed of the simulated sensor instance and its temporal noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Side of the simulated pixel window (the statistics need pixels, not the full frame).
    #[arg(long, default_value_t = characterize::simulate::DEFAULT_WINDOW)]
    pub window: usize,
    /// Output directory.
    #[arg(short, long)]
    pub output: PathBuf,
}

/// Runs `eoir characterize`.
pub fn characterize(args: CharacterizeArgs) -> Result<()> {
    if args.simulate {
        if let Some(set) = &args.acquisition_set {
            bail!(
                "--simulate writes a new set into --output; do not also give a set to analyse ({})",
                set.display()
            );
        }
        let sensor = args.sensor.load()?;
        let truth = characterize::simulate(
            &sensor,
            &args.output,
            &SimulateOptions {
                seed: args.seed,
                window: args.window,
            },
        )
        .with_context(|| format!("simulating an EMVA 1288 set into {}", args.output.display()))?;
        for w in &truth.warnings {
            eprintln!("warning: {w}");
        }
        println!(
            "{}: wrote an EMVA 1288 acquisition set ({} x {} px, λ0 = {:.3} µm) to {}: K = {:.5} DN/e-, QE = {:.2} %, σ_d = {:.2} e-, μ_e.sat = {:.4e} e-",
            truth.sensor,
            truth.window[0],
            truth.window[1],
            truth.wavelength_um,
            args.output.display(),
            truth.K_DN_per_e,
            truth.QE_percent,
            truth.sigma_d_e,
            truth.u_e_sat_e
        );
        return Ok(());
    }
    let Some(set) = &args.acquisition_set else {
        bail!(
            "give an acquisition set to analyse (a directory with descriptor.txt), or --simulate"
        );
    };
    let descriptor = characterize::descriptor_path(set);
    let c = characterize::characterize(&descriptor)
        .with_context(|| format!("characterising {}", descriptor.display()))?;
    for w in &c.warnings {
        eprintln!("warning: {w}");
    }
    let title = set.display().to_string();
    characterize::write_outputs(&c, &args.output, &title)
        .with_context(|| format!("writing the characterisation to {}", args.output.display()))?;
    println!(
        "K = {:.5} DN/e-, QE = {}, σ_d = {:.3} e-, DSNU = {:.3} e-, PRNU = {:.3} %, μ_e.sat = {:.4e} e-, DR = {:.1} dB; wrote {}",
        c.K_DN_per_e,
        c.QE_percent.map_or("—".to_string(), |q| format!("{q:.2} %")),
        c.sigma_d_e,
        c.DSNU1288_e,
        c.PRNU1288_percent,
        c.u_e_sat_e,
        c.DR_dB,
        args.output.join("characterization.json").display()
    );
    Ok(())
}
