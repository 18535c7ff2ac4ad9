//! Sensor presets: the TOML files in `sensors/`, embedded in the binary so they work from
//! any directory, and the **options** mechanism that selects alternatives inside one file.
//!
//! # Options
//!
//! A sensor file (embedded preset or a file on disk) may declare alternatives as overlay
//! tables, and default choices:
//!
//! ```toml
//! [options.filter.4]        # selected with --option filter=4
//! filter = { kind = "top_hat", lo_um = 4.55, hi_um = 5.2, edge_width_um = 0.05, peak = 0.85 }
//! [options.optics.100mm]
//! optics = { focal_length_m = 0.1, f_number = 2.0 }
//! [defaults]
//! filter = "4"
//! optics = "100mm"
//! ```
//!
//! Loading removes `options` and `defaults`, takes for every declared option the value
//! given with `--option name=value` (or its default) and deep-merges that overlay into the
//! base: tables merge key by key, other values replace, and a table that names its `kind`
//! (a spectrum) or `path` (turbulence) replaces the base table whole, so switching a
//! Gaussian filter for a top-hat leaves no stray keys. Overlays are applied in alphabetical
//! order of option name; two selected overlays may not set the same key (an error, not a
//! silent precedence rule). `--set` overrides are applied after the options. Every option
//! must have a default or be given.
//!
//! The choices are recorded in the resolved description as
//! [`SensorConfig::selected_options`] (serialised as a `[selected_options]` table in the
//! resolved `config.toml`).
//!
//! Multi-channel sensors (the 3-CCD `ccd` and the FOI `threeband`) declare a `channel`
//! option ([`CHANNEL_OPTION`]); one run simulates one channel, and a caller wanting all of
//! them loops over [`PresetInfo::channel_values`]. A Bayer sensor (`ccd-bayer`) has a
//! `[cfa]` section instead; [`super::Sensor::build`] derives the single-colour sensor of
//! each colour plane ([`super::Sensor::cfa_channels`]).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::spectrum::Spectrum;

use super::config::{toml_error, Override};
use super::config::{CfaConfig, SensorConfig, SpectrumConfig};

/// The embedded presets: (name, TOML text).
pub const PRESETS: &[(&str, &str)] = &[
    ("multimir", include_str!("../../sensors/multimir.toml")),
    ("emerald", include_str!("../../sensors/emerald.toml")),
    ("qwip", include_str!("../../sensors/qwip.toml")),
    ("ccd", include_str!("../../sensors/ccd.toml")),
    ("ccd-bayer", include_str!("../../sensors/ccd-bayer.toml")),
    ("threeband", include_str!("../../sensors/threeband.toml")),
];

/// The option whose values are the channels of a multi-channel sensor (one run each).
pub const CHANNEL_OPTION: &str = "channel";

/// A preset as listed by `eoir sensors`.
#[derive(Debug, Clone, PartialEq)]
pub struct PresetInfo {
    /// Preset name (what `--sensor` accepts).
    pub name: String,
    /// One-line description.
    pub description: String,
    /// Declared options, alphabetically: (option name, its values).
    pub options: Vec<(String, Vec<String>)>,
    /// Default value of each option that has one: (option name, value).
    pub defaults: Vec<(String, String)>,
}

impl PresetInfo {
    /// The values of the [`CHANNEL_OPTION`], if this preset has one (a multi-channel sensor).
    pub fn channel_values(&self) -> Option<&[String]> {
        self.options
            .iter()
            .find(|(n, _)| n == CHANNEL_OPTION)
            .map(|(_, v)| v.as_slice())
    }

    /// Every combination of option values (the Cartesian product), each as a list of
    /// `name=value` strings ready for [`load`]. One empty combination if there are no
    /// options.
    pub fn option_combinations(&self) -> Vec<Vec<String>> {
        let mut combos: Vec<Vec<String>> = vec![Vec::new()];
        for (name, values) in &self.options {
            let mut next = Vec::with_capacity(combos.len() * values.len());
            for c in &combos {
                for v in values {
                    let mut c2 = c.clone();
                    c2.push(format!("{name}={v}"));
                    next.push(c2);
                }
            }
            combos = next;
        }
        combos
    }
}

/// The TOML text of a preset, if `name` is one (case-insensitive).
pub fn preset_text(name: &str) -> Option<&'static str> {
    PRESETS
        .iter()
        .find(|(n, _)| n.eq_ignore_ascii_case(name))
        .map(|(_, t)| *t)
}

fn preset_names() -> String {
    PRESETS
        .iter()
        .map(|(n, _)| *n)
        .collect::<Vec<_>>()
        .join(", ")
}

/// Loads a sensor given as a file path or a preset name, with `--option name=value`
/// choices and `--set` overrides, and validates it. A path that exists wins over a preset
/// of the same name, except a folder (`--sensor qwip` beside an output folder `qwip/`
/// means the preset).
pub fn load(spec: &str, options: &[String], overrides: &[String]) -> Result<SensorConfig> {
    let overrides: Vec<Override> = overrides
        .iter()
        .map(|o| Override::parse(o))
        .collect::<Result<_>>()?;
    load_with(spec, options, &overrides)
}

/// As [`load`], with the overrides already split into key paths and typed values
/// ([`Override`]), as the Python API gives them.
pub fn load_with(spec: &str, options: &[String], overrides: &[Override]) -> Result<SensorConfig> {
    let path = Path::new(spec);
    // A folder that happens to share a preset's name (e.g. an earlier `-o qwip`) is not a
    // sensor file: the preset is meant.
    let shadowed_preset = path.is_dir() && preset_text(spec).is_some();
    if path.exists() && !shadowed_preset {
        let text = crate::io::input::read_text(path)?;
        let base_dir = path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."));
        return load_text(
            &text,
            &path.display().to_string(),
            base_dir,
            options,
            overrides,
        );
    }
    match preset_text(spec) {
        Some(text) => load_text(
            text,
            &format!("preset `{spec}`"),
            PathBuf::from("."),
            options,
            overrides,
        ),
        None => Err(Error::param(
            "--sensor",
            spec,
            format!(
                "an existing sensor file or a preset name ({})",
                preset_names()
            ),
        )),
    }
}

/// Resolves a sensor description's text: options, then overrides, then validation.
fn load_text(
    text: &str,
    source: &str,
    base_dir: PathBuf,
    options: &[String],
    overrides: &[Override],
) -> Result<SensorConfig> {
    let table: toml::Table = toml::from_str(text).map_err(|e| toml_error(source, text, &e))?;
    if !table.contains_key("options") && !table.contains_key("defaults") {
        if let Some(first) = options.first() {
            return Err(Error::param(
                "--option",
                first,
                format!("nothing: {source} declares no options"),
            ));
        }
        // No options: parse the text directly so errors point at its lines.
        return SensorConfig::from_toml_str_with(text, source, base_dir, overrides);
    }
    let merged = apply_options(table, source, options)?;
    SensorConfig::from_table_with(merged, source, base_dir, overrides)
}

/// The option declarations of a parsed sensor table: name → value → overlay.
type Declarations = BTreeMap<String, BTreeMap<String, toml::Table>>;

/// Splits the `options` and `defaults` tables off `table` and checks their shape.
fn split_declarations(
    table: &mut toml::Table,
    source: &str,
) -> Result<(Declarations, BTreeMap<String, String>)> {
    let mut decl = Declarations::new();
    if let Some(v) = table.remove("options") {
        let toml::Value::Table(opts) = v else {
            return Err(Error::format(
                source,
                "`options` must be a table of option names ([options.NAME.VALUE])",
            ));
        };
        for (name, values) in opts {
            let toml::Value::Table(values) = values else {
                return Err(Error::format(
                    source,
                    format!("`options.{name}` must be a table of values ([options.{name}.VALUE])"),
                ));
            };
            if values.is_empty() {
                return Err(Error::format(
                    source,
                    format!("option `{name}` declares no values"),
                ));
            }
            let mut vals = BTreeMap::new();
            for (value, overlay) in values {
                let toml::Value::Table(overlay) = overlay else {
                    return Err(Error::format(
                        source,
                        format!(
                            "`options.{name}.{value}` must be a table of settings to merge into the sensor"
                        ),
                    ));
                };
                vals.insert(value, overlay);
            }
            decl.insert(name, vals);
        }
    }
    let mut defaults = BTreeMap::new();
    if let Some(v) = table.remove("defaults") {
        let toml::Value::Table(d) = v else {
            return Err(Error::format(
                source,
                "`defaults` must be a table `option = \"value\"`",
            ));
        };
        for (name, value) in d {
            let value = match value {
                toml::Value::String(s) => s,
                toml::Value::Integer(i) => i.to_string(),
                other => {
                    return Err(Error::format(
                        source,
                        format!(
                            "defaults.{name} = {other}: expected the name of one of its values, as a string"
                        ),
                    ))
                }
            };
            let Some(values) = decl.get(&name) else {
                return Err(Error::format(
                    source,
                    format!(
                        "defaults.{name}: no such option (declared: {})",
                        join_keys(decl.keys())
                    ),
                ));
            };
            if !values.contains_key(&value) {
                return Err(Error::format(
                    source,
                    format!(
                        "defaults.{name} = \"{value}\": not one of its values ({})",
                        join_keys(values.keys())
                    ),
                ));
            }
            defaults.insert(name, value);
        }
    }
    Ok((decl, defaults))
}

fn join_keys<'a>(keys: impl Iterator<Item = &'a String>) -> String {
    keys.map(String::as_str).collect::<Vec<_>>().join(", ")
}

/// Applies option choices to a parsed sensor table: removes `options` and `defaults`,
/// deep-merges the selected overlays (given `name=value` choices, else the defaults; see
/// the [module documentation](self)) and records the choices in `selected_options`. A
/// table without `options` is returned unchanged (and any choice is an error).
///
/// Errors name `source` and list the valid option names or values.
pub fn apply_options(
    mut table: toml::Table,
    source: &str,
    options: &[String],
) -> Result<toml::Table> {
    let (decl, defaults) = split_declarations(&mut table, source)?;
    let mut chosen: BTreeMap<String, String> = BTreeMap::new();
    for o in options {
        let (name, value) = o.split_once('=').ok_or_else(|| {
            Error::param(
                "--option",
                o,
                format!(
                    "`name=value`; options of {source}: {}",
                    describe_options(&decl)
                ),
            )
        })?;
        let (name, value) = (name.trim(), value.trim());
        let Some(values) = decl.get(name) else {
            return Err(Error::param(
                "--option",
                o,
                if decl.is_empty() {
                    format!("nothing: {source} declares no options")
                } else {
                    format!("an option of {source}: {}", describe_options(&decl))
                },
            ));
        };
        if !values.contains_key(value) {
            return Err(Error::param(
                format!("--option {name}"),
                value,
                format!("one of {}", join_keys(values.keys())),
            ));
        }
        if let Some(prev) = chosen.get(name) {
            if prev != value {
                return Err(Error::param(
                    format!("--option {name}"),
                    format!("{prev} and {value}"),
                    "one value per option",
                ));
            }
        }
        chosen.insert(name.to_string(), value.to_string());
    }
    for (name, values) in &decl {
        if !chosen.contains_key(name) {
            match defaults.get(name) {
                Some(d) => {
                    chosen.insert(name.clone(), d.clone());
                }
                None => {
                    return Err(Error::param(
                        format!("--option {name}"),
                        "missing",
                        format!(
                            "one of {} ({source} has no default for it)",
                            join_keys(values.keys())
                        ),
                    ))
                }
            }
        }
    }
    // Check that no two selected overlays set the same key, then merge.
    let mut set_by: Vec<(String, &str)> = Vec::new();
    for (name, value) in &chosen {
        let overlay = &decl[name][value];
        let mut paths = Vec::new();
        leaf_paths(overlay, "", &mut paths);
        for p in paths {
            for (q, other) in &set_by {
                let overlap =
                    p == *q || p.starts_with(&format!("{q}.")) || q.starts_with(&format!("{p}."));
                if overlap {
                    return Err(Error::format(
                        source,
                        format!(
                            "options `{other}` and `{name}` both set `{}`; an overlay may not change what another option sets",
                            if p.len() < q.len() { &p } else { q }
                        ),
                    ));
                }
            }
            set_by.push((p, name.as_str()));
        }
    }
    for (name, value) in &chosen {
        deep_merge(&mut table, decl[name][value].clone());
    }
    if !chosen.is_empty() {
        let rec: toml::Table = chosen
            .into_iter()
            .map(|(k, v)| (k, toml::Value::String(v)))
            .collect();
        table.insert("selected_options".to_string(), toml::Value::Table(rec));
    }
    Ok(table)
}

/// `filter (1, 2, 3, 4), optics (15mm, 100mm)`.
fn describe_options(decl: &Declarations) -> String {
    decl.iter()
        .map(|(n, v)| format!("{n} ({})", join_keys(v.keys())))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Whether an overlay table replaces its base whole (a tagged spectrum or turbulence path).
fn replaces_whole(t: &toml::Table) -> bool {
    t.contains_key("kind") || t.contains_key("path")
}

/// The dotted keys an overlay sets (a whole-replacing table counts as one key).
fn leaf_paths(t: &toml::Table, prefix: &str, out: &mut Vec<String>) {
    for (k, v) in t {
        let p = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        match v {
            toml::Value::Table(sub) if !replaces_whole(sub) => leaf_paths(sub, &p, out),
            _ => out.push(p),
        }
    }
}

/// Merges `overlay` into `base`: tables key by key, everything else (and tables that
/// [`replaces_whole`]) replaced.
fn deep_merge(base: &mut toml::Table, overlay: toml::Table) {
    for (k, v) in overlay {
        match (base.get_mut(&k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) if !replaces_whole(&o) => {
                deep_merge(b, o)
            }
            (_, v) => {
                base.insert(k, v);
            }
        }
    }
}

/// Every embedded preset with its description and options. A preset whose text cannot be
/// parsed (a build defect the test suite guards against) is listed with the error as its
/// description and no options.
pub fn list() -> Vec<PresetInfo> {
    PRESETS
        .iter()
        .map(|(name, text)| {
            let source = format!("preset `{name}`");
            let parsed = toml::from_str::<toml::Table>(text)
                .map_err(|e| toml_error(&source, text, &e))
                .and_then(|mut t| {
                    let (decl, defaults) = split_declarations(&mut t, &source)?;
                    Ok((t, decl, defaults))
                });
            match parsed {
                Ok((t, decl, defaults)) => PresetInfo {
                    name: name.to_string(),
                    description: t
                        .get("description")
                        .and_then(|d| d.as_str())
                        .unwrap_or("")
                        .to_string(),
                    options: decl
                        .iter()
                        .map(|(n, v)| (n.clone(), v.keys().cloned().collect()))
                        .collect(),
                    defaults: defaults.into_iter().collect(),
                },
                Err(e) => PresetInfo {
                    name: name.to_string(),
                    description: format!("(invalid preset: {e})"),
                    options: Vec::new(),
                    defaults: Vec::new(),
                },
            }
        })
        .collect()
}

/// The fully resolved description of a sensor (preset name or file) with the given option
/// choices, as TOML (for `eoir sensors show NAME`).
pub fn resolved_toml(name: &str, options: &[String]) -> Result<String> {
    load(name, options, &[])?.to_toml_string()
}

/// The single-colour sensor seen by the pixels under one filter of a colour filter array:
/// a copy of `config` whose `filter` is `filter × cfa.<colour>` and without `[cfa]`
/// (`channel` is [`crate::cfa::RED`], `GREEN` or `BLUE`), given the filter and dye spectra
/// already built by [`super::Sensor::build`] (the only caller: it reads each file once,
/// and stages use the result through [`super::Sensor::cfa_channels`]). The choice is
/// recorded as `selected_options.cfa_channel`.
///
/// The product is exact when either factor is a constant (the case of the `ccd-bayer`
/// preset, whose `[filter]` is 1); otherwise it is tabulated at every breakpoint of the
/// product and at least every 1 nm across its support.
///
/// Errors: `config` has no `[cfa]`, `channel` > 2, or the product has no support.
pub(super) fn cfa_channel_with(
    config: &SensorConfig,
    channel: usize,
    filter_spectrum: &Spectrum,
    dye_spectrum: &Spectrum,
) -> Result<SensorConfig> {
    let cfa = cfa_table(config)?;
    let dye = dye_config(cfa, channel)?;
    let filter = spectrum_config_product(&config.filter, dye, filter_spectrum, dye_spectrum)?;
    let mut out = config.clone();
    out.filter = filter;
    out.cfa = None;
    out.selected_options.insert(
        "cfa_channel".to_string(),
        crate::cfa::CHANNEL_NAMES[channel].to_string(),
    );
    out.validate()?;
    Ok(out)
}

/// The `[cfa]` table of `config`, or an error naming the sensor.
fn cfa_table(config: &SensorConfig) -> Result<&CfaConfig> {
    config.cfa.as_ref().ok_or_else(|| {
        Error::param(
            "cfa",
            "absent",
            format!("a [cfa] section in sensor `{}`", config.name),
        )
    })
}

/// The dye of colour `channel` (0 red, 1 green, 2 blue).
fn dye_config(cfa: &CfaConfig, channel: usize) -> Result<&SpectrumConfig> {
    match channel {
        crate::cfa::RED => Ok(&cfa.red),
        crate::cfa::GREEN => Ok(&cfa.green),
        crate::cfa::BLUE => Ok(&cfa.blue),
        other => Err(Error::param(
            "cfa channel",
            other,
            "0 (red), 1 (green) or 2 (blue)",
        )),
    }
}

/// `factor × s` as a spectrum description, exactly where the kind allows it.
fn scaled_config(s: &SpectrumConfig, factor: f64) -> Option<SpectrumConfig> {
    Some(match s {
        SpectrumConfig::Constant { value } => SpectrumConfig::Constant {
            value: value * factor,
        },
        SpectrumConfig::IdealQe { peak, cutoff_um } => SpectrumConfig::IdealQe {
            peak: peak * factor,
            cutoff_um: *cutoff_um,
        },
        SpectrumConfig::TopHat {
            lo_um,
            hi_um,
            edge_width_um,
            peak,
        } => SpectrumConfig::TopHat {
            lo_um: *lo_um,
            hi_um: *hi_um,
            edge_width_um: *edge_width_um,
            peak: peak * factor,
        },
        SpectrumConfig::Gaussian {
            center_um,
            fwhm_um,
            peak,
        } => SpectrumConfig::Gaussian {
            center_um: *center_um,
            fwhm_um: *fwhm_um,
            peak: peak * factor,
        },
        SpectrumConfig::Table {
            wavelength_um,
            value,
        } => SpectrumConfig::Table {
            wavelength_um: wavelength_um.clone(),
            value: value.iter().map(|v| v * factor).collect(),
        },
        SpectrumConfig::PhotonDetector { .. } | SpectrumConfig::Csv { .. } => return None,
    })
}

/// The pointwise product of two spectrum descriptions (see [`cfa_channel_with`]).
fn spectrum_config_product(
    a: &SpectrumConfig,
    b: &SpectrumConfig,
    a_spectrum: &Spectrum,
    b_spectrum: &Spectrum,
) -> Result<SpectrumConfig> {
    if let SpectrumConfig::Constant { value } = a {
        if let Some(s) = scaled_config(b, *value) {
            return Ok(s);
        }
    }
    if let SpectrumConfig::Constant { value } = b {
        if let Some(s) = scaled_config(a, *value) {
            return Ok(s);
        }
    }
    let product: Spectrum = a_spectrum.product(b_spectrum);
    let (lo, hi) = product.support_um();
    if !(lo.is_finite() && hi.is_finite() && hi > lo) {
        return Err(Error::param(
            "filter × cfa",
            format!("support ({lo}, {hi}) µm"),
            "a product with a finite, non-empty wavelength support",
        ));
    }
    let n = (((hi - lo) / 0.001).ceil() as usize).clamp(2, 100_000);
    let mut grid: Vec<f64> = (0..=n)
        .map(|i| lo + (hi - lo) * i as f64 / n as f64)
        .collect();
    grid.extend(
        product
            .breakpoints_um()
            .into_iter()
            .filter(|w| *w >= lo && *w <= hi),
    );
    grid.retain(|w| *w > 0.0);
    grid.sort_by(f64::total_cmp);
    grid.dedup_by(|x, y| (*x - *y).abs() < 1e-12);
    let value = product.resample(&grid);
    Ok(SpectrumConfig::Table {
        wavelength_um: grid,
        value,
    })
}
