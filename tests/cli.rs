//! The `eoir` binary end to end: commands, products and error behaviour.

use std::path::Path;
use std::process::Command;

fn eoir() -> Command {
    Command::new(env!("CARGO_BIN_EXE_eoir"))
}

fn tempdir() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

#[test]
fn mtf_writes_csv_with_component_columns_and_png() {
    let dir = tempdir();
    let csv = dir.path().join("mtf.csv");
    let png = dir.path().join("mtf.png");
    let out = eoir()
        .args(["mtf", "--sensor", "multimir", "--points", "51", "--csv"])
        .arg(&csv)
        .arg("--png")
        .arg(&png)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "freq_cy_per_mrad,diffraction,aberration,detector,motion,jitter,system"
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 51);
    // Row 0 is DC: everything 1. System = product of the components in every row.
    assert!(rows[0][1..].iter().all(|v| (v - 1.0).abs() < 1e-9));
    for r in &rows {
        let prod: f64 = r[1..r.len() - 1].iter().product();
        assert!((prod - r[r.len() - 1]).abs() < 1e-7);
    }
    // Default range: max(cutoff, 2 x Nyquist). MultimIR 100 mm F/2 at ~4.9 µm: cutoff
    // D/λ = 0.05 m / 4.9e-6 m ≈ 10.3 cy/mrad; Nyquist = 0.1/(2·24e-6)/1000 ≈ 2.08 cy/mrad.
    let last = rows.last().unwrap()[0];
    assert!(last > 9.5 && last < 11.5, "{last}");
    let png_bytes = std::fs::read(&png).unwrap();
    assert_eq!(&png_bytes[1..4], b"PNG");
}

#[test]
fn invalid_sensor_file_gives_one_error_line_naming_the_field() {
    let dir = tempdir();
    let bad = dir.path().join("bad.toml");
    let text = eoir::sensor::presets::preset_text("multimir")
        .unwrap()
        .replace("f_number = 2.0", "f_number = 0.0");
    std::fs::write(&bad, text).unwrap();
    let out = eoir().args(["mtf", "--sensor"]).arg(&bad).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.contains("optics.f_number") && err.contains("bad.toml"),
        "{err}"
    );
    assert!(!err.contains("panicked"));
}

#[test]
fn unknown_set_key_is_an_error() {
    let out = eoir()
        .args(["mtf", "--sensor", "multimir", "--set", "optics.fnumber=3"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("fnumber"), "{err}");
}

#[test]
fn missing_file_is_named() {
    let out = eoir()
        .args(["mtf", "--sensor", "/nonexistent/s.toml"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("/nonexistent/s.toml"), "{err}");
    assert!(!Path::new("/nonexistent").exists());
}
