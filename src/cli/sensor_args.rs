//! How a command names its sensor (`--sensor`, `--option`, `--set`): shared by every
//! command that loads one, below them all (no command imports another for it).

use anyhow::{Context, Result};

use eoir::sensor::{presets, Sensor, SensorConfig};

/// How a command names its sensor: a file or preset, options and overrides.
#[derive(Debug, Clone, clap::Args)]
pub struct SensorArgs {
    /// Sensor: a TOML file or a preset name (see `eoir sensors`).
    #[arg(long, default_value = "multimir")]
    pub sensor: String,
    /// Select a preset option, e.g. `--option filter=4 --option optics=100mm` (repeatable).
    #[arg(long = "option", value_name = "NAME=VALUE")]
    pub option: Vec<String>,
    /// Override a sensor field, e.g. `--set detector.integration_time_s=2e-3` (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

impl SensorArgs {
    /// Loads the configuration of the sensor these arguments name.
    pub fn load_config(&self) -> Result<SensorConfig> {
        Ok(presets::load(&self.sensor, &self.option, &self.set)?)
    }

    /// Loads and resolves the sensor these arguments name.
    pub fn load(&self) -> Result<Sensor> {
        build(&self.load_config()?)
    }
}

/// Resolves a sensor configuration (reads the files it refers to), naming it in errors.
pub fn build(config: &SensorConfig) -> Result<Sensor> {
    Sensor::build(config).with_context(|| format!("resolving sensor `{}`", config.name))
}
