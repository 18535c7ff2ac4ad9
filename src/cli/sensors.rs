//! `eoir sensors`: list the presets or print one resolved.

use anyhow::{bail, Result};

use eoir::sensor::presets;

/// Arguments of `eoir sensors`.
#[derive(Debug, clap::Args)]
pub struct SensorsArgs {
    /// `show` to print a preset's resolved TOML.
    pub action: Option<String>,
    /// The preset to show.
    pub name: Option<String>,
    /// Select a preset option, e.g. `--option filter=3` (repeatable).
    #[arg(long = "option", value_name = "NAME=VALUE")]
    pub option: Vec<String>,
}

/// Lists the presets or prints one fully resolved.
pub fn sensors(args: SensorsArgs) -> Result<()> {
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
