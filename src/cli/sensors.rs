//! `eoir sensors`: list the presets or print one resolved, with the preset file's
//! provenance notes (its comments: sources, `ASSUMED` values and their reasoning) kept
//! next to the values they explain.

use std::collections::BTreeMap;

use anyhow::{bail, Result};

use eoir::sensor::presets;

/// Arguments of `eoir sensors`.
#[derive(Debug, clap::Args)]
pub struct SensorsArgs {
    /// `show` to print a preset's resolved TOML with its provenance notes.
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
            let sensor = presets::load(name, &args.option, &[])?;
            let resolved = sensor.to_toml_string()?;
            match presets::preset_text(name) {
                Some(source) => print!("{}", annotate(&resolved, source, &sensor.selected_options)),
                None => print!("{resolved}"),
            }
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

/// The comments of a sensor file, keyed by the dotted path of the table or key they
/// describe, plus the file's preamble.
#[derive(Debug, Default)]
struct Notes {
    preamble: Vec<String>,
    by_path: BTreeMap<String, Vec<String>>,
}

impl Notes {
    fn attach(&mut self, path: &str, lines: &mut Vec<String>) {
        if lines.is_empty() {
            return;
        }
        if path.is_empty() {
            self.preamble.append(lines);
        } else {
            self.by_path
                .entry(path.to_string())
                .or_default()
                .append(lines);
        }
    }
}

/// The position of a `#` that starts a comment in a TOML line (outside strings), if any.
fn comment_start(line: &str) -> Option<usize> {
    let mut quote: Option<char> = None;
    let mut escaped = false;
    for (i, c) in line.char_indices() {
        match quote {
            Some(q) => {
                if escaped {
                    escaped = false;
                } else if c == '\\' && q == '"' {
                    escaped = true;
                } else if c == q {
                    quote = None;
                }
            }
            None => match c {
                '"' | '\'' => quote = Some(c),
                '#' => return Some(i),
                _ => {}
            },
        }
    }
    None
}

/// Collects the comments of a preset file. A comment block (and a key's trailing comment)
/// belongs to the next table header or key; a block followed by a blank line belongs to the
/// table it is in. Comments inside `[options.NAME.VALUE]` overlays count only for the
/// selected value and are attached to the resolved paths (`options.NAME.VALUE.` dropped);
/// a block just before an overlay header describes the whole option and goes to path
/// `NAME` (shown at the table of that name, or with the unplaced notes).
fn collect_notes(source: &str, selected: &BTreeMap<String, String>) -> Notes {
    let mut notes = Notes::default();
    let mut pending: Vec<String> = Vec::new();
    // Current table path; None inside an overlay of an unselected option value or
    // `[defaults]`.
    let mut table: Option<String> = Some(String::new());
    for raw in source.lines() {
        let line = raw.trim();
        if line.is_empty() {
            if let Some(t) = &table {
                notes.attach(t, &mut pending);
            } else {
                pending.clear();
            }
            continue;
        }
        if line.starts_with('#') {
            pending.push(line.to_string());
            continue;
        }
        let (code, trailing) = match comment_start(line) {
            Some(i) => (line[..i].trim(), Some(line[i..].trim().to_string())),
            None => (line, None),
        };
        if code.starts_with('[') {
            let name = code
                .trim_matches(|c| c == '[' || c == ']')
                .trim()
                .to_string();
            let parts: Vec<&str> = name.splitn(4, '.').collect();
            table = if parts[0] == "options" && parts.len() >= 3 {
                let opt = parts[1];
                notes.attach(opt, &mut pending);
                if selected.get(opt).map(String::as_str) == Some(parts[2]) {
                    Some(parts.get(3).map(|s| s.to_string()).unwrap_or_default())
                } else {
                    None
                }
            } else if name == "defaults" || name == "options" {
                pending.clear();
                None
            } else {
                notes.attach(&name, &mut pending);
                Some(name)
            };
            if let (Some(t), Some(c)) = (&table, trailing) {
                notes.attach(t, &mut vec![c]);
            }
            continue;
        }
        let Some(t) = &table else {
            pending.clear();
            continue;
        };
        if let Some(eq) = code.find('=') {
            let key = code[..eq].trim().trim_matches('"');
            let path = if t.is_empty() {
                key.to_string()
            } else {
                format!("{t}.{key}")
            };
            pending.extend(trailing);
            notes.attach(&path, &mut pending);
        }
    }
    notes.attach("", &mut pending);
    notes
}

/// The resolved TOML with the preset's notes as comments before the tables and keys they
/// describe; notes whose key is not in the resolved file are listed at the end. Comments
/// never change the values: the output parses to the same sensor.
fn annotate(resolved: &str, source: &str, selected: &BTreeMap<String, String>) -> String {
    let mut notes = collect_notes(source, selected);
    let mut out = String::new();
    for l in &notes.preamble {
        out.push_str(l);
        out.push('\n');
    }
    let mut table = String::new();
    for line in resolved.lines() {
        let code = line.trim();
        let path = if code.starts_with('[') {
            table = code
                .trim_matches(|c| c == '[' || c == ']')
                .trim()
                .to_string();
            Some(table.clone())
        } else {
            code.find('=').map(|eq| {
                let key = code[..eq].trim().trim_matches('"');
                if table.is_empty() {
                    key.to_string()
                } else {
                    format!("{table}.{key}")
                }
            })
        };
        if let Some(lines) = path.and_then(|p| notes.by_path.remove(&p)) {
            for l in lines {
                out.push_str(&l);
                out.push('\n');
            }
        }
        out.push_str(line);
        out.push('\n');
    }
    if !notes.by_path.is_empty() {
        out.push_str(
            "\n# ---- notes of the preset file about options and keys not shown above ----\n",
        );
        for (path, lines) in notes.by_path {
            out.push_str(&format!("# [{path}]\n"));
            for l in lines {
                out.push_str(&l);
                out.push('\n');
            }
        }
    }
    out
}
