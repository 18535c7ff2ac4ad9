//! The subcommands of the `eoir` binary, one module each, and the argument helpers they share.

use anyhow::{bail, Context, Result};

pub mod assess;
pub mod characterize;
pub mod defects;
pub mod edge_mtf;
pub mod mtf;
pub mod nuc;
pub mod progress;
pub mod restore;
pub mod restore_sequence;
pub mod rts;
pub mod run;
pub mod scene;
pub mod sensor_args;
pub mod sensors;
pub mod sweep;
pub mod temperature;

/// Parses `H,V` (two numbers).
pub fn parse_pair(text: &str, what: &str) -> Result<(f64, f64)> {
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
