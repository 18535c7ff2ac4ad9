//! Sensor presets: the TOML files in `sensors/`, embedded in the binary so they work from
//! any directory.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

use super::config::SensorConfig;

/// The embedded presets: (name, TOML text).
pub const PRESETS: &[(&str, &str)] = &[("multimir", include_str!("../../sensors/multimir.toml"))];

/// The TOML text of a preset, if `name` is one.
pub fn preset_text(name: &str) -> Option<&'static str> {
    PRESETS
        .iter()
        .find(|(n, _)| n.eq_ignore_ascii_case(name))
        .map(|(_, t)| *t)
}

/// Loads a sensor given as a file path or a preset name, with `--set` overrides. A path
/// that exists wins over a preset of the same name.
pub fn load(spec: &str, overrides: &[String]) -> Result<SensorConfig> {
    let path = Path::new(spec);
    if path.exists() {
        return SensorConfig::load(path, overrides);
    }
    match preset_text(spec) {
        Some(text) => SensorConfig::from_toml_str(
            text,
            &format!("preset `{spec}`"),
            PathBuf::from("."),
            overrides,
        ),
        None => Err(Error::param(
            "--sensor",
            spec,
            format!(
                "an existing sensor file or a preset name ({})",
                PRESETS
                    .iter()
                    .map(|(n, _)| *n)
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )),
    }
}
