//! The architecture as `docs/design.md` states it, checked against the source: the module
//! table is the `src/` layout, every `use crate::…` points up the table (no import cycle),
//! no source file exceeds 1000 lines, `pipeline::run_streaming` reads as a short
//! chain without inline JSON, and only the build step and the readers see `base_dir`.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Every `.rs` file under `dir`, recursively, sorted.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let p = entry.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| e == "rs") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// The top-level library module a file under `src/` belongs to (`None` for the crate
/// root, the binary and the CLI).
fn module_of(path: &Path) -> Option<String> {
    let rel = path.strip_prefix(root().join("src")).unwrap();
    let first = rel.components().next()?.as_os_str().to_str()?.to_string();
    let name = first.trim_end_matches(".rs").to_string();
    match name.as_str() {
        "lib" | "main" | "cli" => None,
        _ => Some(name),
    }
}

/// The module names of the table in `docs/design.md` §2, in order.
fn design_table() -> Vec<String> {
    let text = std::fs::read_to_string(root().join("docs/design.md")).unwrap();
    let section = text
        .split("## 2. Module map")
        .nth(1)
        .and_then(|s| s.split("\n## ").next())
        .expect("docs/design.md has a `## 2. Module map` section");
    section
        .lines()
        .filter_map(|l| l.strip_prefix("| `"))
        .filter_map(|l| l.split('`').next())
        .map(str::to_string)
        .collect()
}

/// The modules named after `crate::` in the code of `text` (line comments stripped).
fn crate_deps(text: &str) -> BTreeSet<String> {
    let mut deps = BTreeSet::new();
    for line in text.lines() {
        let code = line.split("//").next().unwrap_or("");
        for piece in code.split("crate::").skip(1) {
            let name: String = piece
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            if !name.is_empty() {
                deps.insert(name);
            }
        }
    }
    deps
}

#[test]
fn module_table_is_the_src_layout() {
    let table = design_table();
    let in_src: BTreeSet<String> = rust_files(&root().join("src"))
        .iter()
        .filter_map(|p| module_of(p))
        .collect();
    let in_table: BTreeSet<String> = table.iter().cloned().collect();
    assert_eq!(
        in_table.len(),
        table.len(),
        "a module listed twice: {table:?}"
    );
    assert_eq!(in_src, in_table, "src/ modules vs docs/design.md table");
    // And lib.rs declares exactly these modules.
    let lib = std::fs::read_to_string(root().join("src/lib.rs")).unwrap();
    let declared: BTreeSet<String> = lib
        .lines()
        .filter_map(|l| l.strip_prefix("pub mod "))
        .map(|l| l.trim_end_matches(';').to_string())
        .collect();
    assert_eq!(declared, in_table);
}

#[test]
fn every_import_points_up_the_module_table() {
    let table = design_table();
    let rank = |m: &str| table.iter().position(|t| t == m);
    let mut violations = Vec::new();
    let mut edges = 0;
    for file in rust_files(&root().join("src")) {
        let Some(m) = module_of(&file) else { continue };
        let text = std::fs::read_to_string(&file).unwrap();
        for dep in crate_deps(&text) {
            let Some(d) = rank(&dep) else { continue }; // `crate::Result` etc.
            if dep == m {
                continue;
            }
            edges += 1;
            if d >= rank(&m).unwrap() {
                violations.push(format!("{} uses {dep}", file.display()));
            }
        }
    }
    assert!(edges > 30, "only {edges} imports found: the scan is broken");
    assert!(
        violations.is_empty(),
        "imports against the table:\n{}",
        violations.join("\n")
    );
}

#[test]
fn no_source_file_exceeds_1000_lines() {
    let mut long = Vec::new();
    for file in rust_files(&root().join("src")) {
        let n = std::fs::read_to_string(&file).unwrap().lines().count();
        if n > 1000 {
            long.push(format!("{}: {n} lines", file.display()));
        }
    }
    assert!(long.is_empty(), "{long:?}");
}

#[test]
fn pipeline_run_is_a_short_chain_without_inline_json() {
    // The chain is `run_streaming`; `run` is it with a collecting consumer.
    let text = std::fs::read_to_string(root().join("src/pipeline/mod.rs")).unwrap();
    let start = text
        .find("pub fn run_streaming(")
        .expect("pipeline::run_streaming");
    let body = &text[start..];
    let end = body.find("\n}\n").expect("end of pipeline::run_streaming");
    let lines = body[..end].lines().count() + 1;
    assert!(lines <= 80, "pipeline::run_streaming is {lines} lines");
    assert!(
        lines > 20,
        "pipeline::run_streaming is {lines} lines: the scan is broken"
    );
    for file in rust_files(&root().join("src/pipeline")) {
        let t = std::fs::read_to_string(&file).unwrap();
        assert!(
            !t.contains("json!"),
            "{} builds JSON inline",
            file.display()
        );
    }
}

#[test]
fn only_the_build_step_and_readers_see_base_dir() {
    // The schema and `Sensor::build` (sensor/), the readers (io/, Spectrum's CSV reader)
    // and the detector model's build inputs, which only `Sensor::build` fills; the line of
    // sight's constructor, which reads a measured trajectory file (`LineOfSight::new`).
    let allowed = [
        "src/sensor/",
        "src/io/",
        "src/spectrum.rs",
        "src/detector/mod.rs",
        "src/los/",
    ];
    let mut seen = Vec::new();
    for file in rust_files(&root().join("src")) {
        let rel = file
            .strip_prefix(root())
            .unwrap()
            .to_string_lossy()
            .to_string();
        let text = std::fs::read_to_string(&file).unwrap();
        if text.contains("base_dir") && !allowed.iter().any(|a| rel.starts_with(a)) {
            seen.push(rel);
        }
    }
    assert!(seen.is_empty(), "base_dir outside the build step: {seen:?}");
}

#[test]
fn only_the_build_step_resolves_what_a_sensor_file_refers_to() {
    // The calls that read a sensor-referenced file or build a resolved piece from the
    // schema: a stage reaching one of them would resolve configuration on its own (the
    // `base_dir` check above misses calls that take the directory from the config
    // internally, as `presets::cfa_channel` did before it became part of the build).
    let resolving = [
        "SystemOtf::new",
        "DetectorModel::build",
        "MeasuredMtf::from_csv",
        "Spectrum::from_csv",
        "resolve_path",
        "cfa_channel(",
        "cfa_channel_with(",
        "MeasuredTrajectory::from_csv",
    ];
    // Where they are defined, and the build step itself.
    let allowed = [
        "src/sensor/",
        "src/io/",
        "src/spectrum.rs",
        "src/optics.rs",
        "src/detector/mod.rs",
        "src/los/",
    ];
    let mut seen = Vec::new();
    for file in rust_files(&root().join("src")) {
        let rel = file
            .strip_prefix(root())
            .unwrap()
            .to_string_lossy()
            .to_string();
        if allowed.iter().any(|a| rel.starts_with(a)) {
            continue;
        }
        let text = std::fs::read_to_string(&file).unwrap();
        for (n, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            for call in resolving {
                if code.contains(call) {
                    seen.push(format!("{rel}:{}: {call}", n + 1));
                }
            }
            // `SpectrumConfig::build(dir, field)` (a `.build(` with arguments that is not
            // `Sensor::build`).
            if let Some(i) = code.find(".build(") {
                let args = &code[i + ".build(".len()..];
                if !args.starts_with(')') && !code.contains("Sensor::build(") {
                    seen.push(format!("{rel}:{}: .build(…)", n + 1));
                }
            }
        }
    }
    assert!(
        seen.is_empty(),
        "configuration resolved outside the build step: {seen:?}"
    );
}
