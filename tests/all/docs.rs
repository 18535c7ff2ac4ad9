//! The documentation cannot go stale:
//!
//! - every relative link in `README.md` and `docs/**/*.md` resolves to a file (and a
//!   `#fragment` into a Markdown file to one of its headings);
//! - every `console` block of the README and the user guide (`docs/guide/*.md`) runs as
//!   written: each `$ command` line is run by `sh` in a fresh directory per page, with the
//!   `eoir` under test first on the `PATH`, and the lines printed under it in the page must
//!   appear, in order, among the lines the command prints (`…` stands for any text; a
//!   line of only `…` for any lines). A command whose printed lines start with `error:`
//!   must fail; every other must succeed. So every figure a page prints is the figure the
//!   current code prints.

use std::collections::BTreeSet;
use std::path::PathBuf;
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `README.md` and every `.md` under `docs/`.
fn markdown_files() -> Vec<PathBuf> {
    let mut files = vec![root().join("README.md"), root().join("BENCHMARKS.md")];
    let mut stack = vec![root().join("docs")];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "md") {
                files.push(p);
            }
        }
    }
    files.sort();
    files
}

/// The text outside fenced code blocks and inline code spans.
fn prose(text: &str) -> String {
    let mut out = String::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            continue;
        }
        // Drop inline code spans: `...`.
        let mut in_code = false;
        for c in line.chars() {
            if c == '`' {
                in_code = !in_code;
            } else if !in_code {
                out.push(c);
            }
        }
        out.push('\n');
    }
    out
}

/// Targets of the Markdown links `[text](target)` in `text` (prose only).
fn link_targets(text: &str) -> Vec<String> {
    let p = prose(text);
    let mut out = Vec::new();
    let mut rest = p.as_str();
    while let Some(i) = rest.find("](") {
        rest = &rest[i + 2..];
        if let Some(j) = rest.find(')') {
            let target = rest[..j].trim();
            // `[text](target "title")`: the target is the first word.
            let target = target.split_whitespace().next().unwrap_or("");
            out.push(target.to_string());
            rest = &rest[j..];
        }
    }
    out
}

/// GitHub's anchor of a heading: lower case, punctuation other than `-` and `_` removed,
/// spaces to `-`.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || *c == ' ' || *c == '-' || *c == '_')
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// The anchors of the headings of a Markdown file.
fn anchors(text: &str) -> BTreeSet<String> {
    let mut fenced = false;
    let mut out = BTreeSet::new();
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
        } else if !fenced && line.starts_with('#') {
            out.insert(slug(line.trim_start_matches('#')));
        }
    }
    out
}

#[test]
fn every_relative_link_in_the_docs_resolves() {
    let mut broken = Vec::new();
    let mut checked = 0;
    for file in markdown_files() {
        let text = std::fs::read_to_string(&file).unwrap();
        let dir = file.parent().unwrap();
        for target in link_targets(&text) {
            if target.is_empty()
                || target.contains("://")
                || target.starts_with("mailto:")
                || target.starts_with('<')
            {
                continue;
            }
            checked += 1;
            let (path, fragment) = match target.split_once('#') {
                Some((p, f)) => (p, Some(f)),
                None => (target.as_str(), None),
            };
            let resolved = if path.is_empty() {
                file.clone()
            } else {
                dir.join(path)
            };
            let rel = file.strip_prefix(root()).unwrap().display().to_string();
            if !resolved.exists() {
                broken.push(format!("{rel}: {target} (no such file)"));
                continue;
            }
            if let Some(f) = fragment {
                if resolved.extension().is_some_and(|x| x == "md") {
                    let t = std::fs::read_to_string(&resolved).unwrap();
                    if !anchors(&t).contains(f) {
                        broken.push(format!("{rel}: {target} (no heading with anchor #{f})"));
                    }
                }
            }
        }
    }
    assert!(
        checked > 30,
        "only {checked} links found: is the parser broken?"
    );
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}

/// One `$ command` of a console block with the lines printed under it.
#[derive(Debug)]
struct Step {
    command: String,
    expected: Vec<String>,
}

/// The steps of every ```` ```console ```` block of `text`, in order. A command ends at a
/// line that does not end in `\`.
fn console_steps(text: &str) -> Vec<Step> {
    let mut steps: Vec<Step> = Vec::new();
    let mut in_console = false;
    let mut continuing = false;
    for line in text.lines() {
        let t = line.trim_start();
        if t.starts_with("```") {
            in_console = !in_console && t.trim_start_matches('`').trim() == "console";
            continuing = false;
            continue;
        }
        if !in_console {
            continue;
        }
        if continuing {
            if let Some(s) = steps.last_mut() {
                s.command.push('\n');
                s.command.push_str(line);
                continuing = line.ends_with('\\');
            }
        } else if let Some(cmd) = line.strip_prefix("$ ") {
            steps.push(Step {
                command: cmd.to_string(),
                expected: Vec::new(),
            });
            continuing = cmd.ends_with('\\');
        } else if let Some(s) = steps.last_mut() {
            if !line.trim().is_empty() {
                s.expected.push(line.to_string());
            }
        }
    }
    steps
}

/// Does `actual` match `pattern`, where `…` in the pattern stands for any text?
fn line_matches(pattern: &str, actual: &str) -> bool {
    let pieces: Vec<&str> = pattern.trim().split('…').collect();
    let actual = actual.trim();
    let mut pos = 0;
    for (i, piece) in pieces.iter().enumerate() {
        if piece.is_empty() {
            continue;
        }
        if i == 0 {
            if !actual.starts_with(piece) {
                return false;
            }
            pos = piece.len();
        } else if i == pieces.len() - 1 {
            return actual.len() >= pos + piece.len() && actual[pos..].ends_with(piece);
        } else {
            match actual[pos..].find(piece) {
                Some(j) => pos += j + piece.len(),
                None => return false,
            }
        }
    }
    // The last piece was empty (pattern ends in …) or the only piece matched whole.
    pieces.len() > 1 || actual == pattern.trim()
}

/// Runs the console blocks of `page` (relative to the repository) in a fresh directory.
fn run_console_blocks(page: &str) {
    let text = std::fs::read_to_string(root().join(page)).unwrap();
    let steps = console_steps(&text);
    assert!(!steps.is_empty(), "{page} has no console block");
    let work = tempfile::tempdir().unwrap();
    let bin = tempfile::tempdir().unwrap();
    std::os::unix::fs::symlink(env!("CARGO_BIN_EXE_eoir"), bin.path().join("eoir")).unwrap();
    let path = format!(
        "{}:{}",
        bin.path().display(),
        std::env::var("PATH").unwrap_or_default()
    );
    for step in &steps {
        let out = Command::new("sh")
            .arg("-c")
            .arg(format!("{{ {}\n}} 2>&1", step.command))
            .current_dir(work.path())
            .env("PATH", &path)
            .output()
            .unwrap();
        let printed = String::from_utf8_lossy(&out.stdout).to_string();
        let should_fail = step
            .expected
            .first()
            .is_some_and(|l| l.trim_start().starts_with("error:"));
        assert_eq!(
            out.status.success(),
            !should_fail,
            "{page}: `{}` {}:\n{printed}",
            step.command,
            if should_fail {
                "succeeded but the page shows an error"
            } else {
                "failed"
            }
        );
        let lines: Vec<&str> = printed.lines().collect();
        let mut at = 0;
        for want in step.expected.iter().filter(|l| l.trim() != "…") {
            match lines[at..].iter().position(|l| line_matches(want, l)) {
                Some(i) => at += i + 1,
                None => panic!(
                    "{page}: `{}` did not print, in order, the line the page shows:\n  {want}\nit printed:\n{printed}",
                    step.command
                ),
            }
        }
    }
}

#[test]
fn line_patterns_match_with_ellipses() {
    assert!(line_matches(
        "edge at 4.99° (near-vertical), MTF50 0.1254 cy/px",
        "edge at 4.99° (near-vertical), MTF50 0.1254 cy/px"
    ));
    assert!(!line_matches("MTF50 0.1254", "MTF50 0.1255"));
    assert!(line_matches("…SNR 2842.9; …", "x SNR 2842.9; y"));
    assert!(line_matches("K = 0.04929 …", "K = 0.04929 DN/e-"));
    assert!(!line_matches("K = 0.04929 …", "K = 0.04921 DN/e-"));
    assert!(line_matches("… DR = 50.1 dB", "K … DR = 50.1 dB"));
    assert!(!line_matches("a…b…c", "a c b"));
}

#[test]
fn readme_quick_start_runs_as_written() {
    run_console_blocks("README.md");
}

#[test]
fn user_guide_examples_run_as_written() {
    let mut pages: Vec<String> = std::fs::read_dir(root().join("docs/guide"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .filter(|p| std::fs::read_to_string(p).unwrap().contains("```console"))
        .map(|p| p.strip_prefix(root()).unwrap().display().to_string())
        .collect();
    pages.sort();
    assert!(
        pages.len() >= 4,
        "guide pages with console blocks: {pages:?}"
    );
    for page in &pages {
        run_console_blocks(page);
    }
}

#[test]
fn readme_is_a_short_quick_start_that_opens_with_the_two_commands() {
    let text = std::fs::read_to_string(root().join("README.md")).unwrap();
    assert!(
        text.lines().count() <= 200,
        "README.md has {} lines; details belong in docs/",
        text.lines().count()
    );
    let block: Vec<&str> = text
        .lines()
        .skip_while(|l| !l.starts_with("```"))
        .skip(1)
        .take(2)
        .collect();
    assert!(
        block[0].starts_with("cargo run --release -- demo"),
        "{block:?}"
    );
    assert!(block[1].starts_with("cargo test --release"), "{block:?}");
}
