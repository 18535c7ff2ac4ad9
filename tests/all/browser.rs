//! `report.html` in a real browser: headless Chromium renders the page of a demo run, the
//! screenshot must not be blank and the rendered DOM must hold the run's key numbers.
//!
//! Needs Chromium (Debian: `apt-get install -y chromium`), so it is ignored by default;
//! `.ci/run` installs it and runs
//! `cargo test --release --test all browser -- --ignored`. The browser is `chromium` on the
//! PATH or the program named by `EOIR_CHROMIUM`.

use std::path::Path;
use std::process::Command;

use super::products::{read_png8, small_demo, span_value};

fn chromium() -> Command {
    let program = std::env::var("EOIR_CHROMIUM").unwrap_or_else(|_| "chromium".to_string());
    let mut c = Command::new(program);
    c.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--no-first-run",
        "--hide-scrollbars",
    ]);
    c
}

fn run_chromium(profile: &Path, extra: &[String], page: &Path) -> std::process::Output {
    let out = chromium()
        .arg(format!("--user-data-dir={}", profile.display()))
        .args(extra)
        .arg(format!("file://{}", page.display()))
        .output()
        .expect(
            "chromium not found: install it (apt-get install -y chromium) or set EOIR_CHROMIUM",
        );
    assert!(
        out.status.success(),
        "chromium failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

#[test]
#[ignore = "needs chromium; run by .ci/run with -- --ignored"]
fn browser_renders_report_html_with_pictures_and_key_numbers() {
    let dir = tempfile::tempdir().unwrap();
    small_demo("multimir", dir.path());
    let page = dir.path().join("report.html");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap())
            .unwrap();

    // The DOM after rendering holds the numbers of report.json.
    let profile = tempfile::tempdir().unwrap();
    let dom = run_chromium(profile.path(), &["--dump-dom".to_string()], &page);
    let dom = String::from_utf8(dom.stdout).unwrap();
    let netd_mk = report["calibration"]["netd_analytic_k_at_300k"]
        .as_f64()
        .unwrap()
        * 1e3;
    let shown = span_value(&dom, "netd_mk");
    assert!(
        (shown - netd_mk).abs() <= 0.006 * netd_mk,
        "NETD {shown} vs {netd_mk}"
    );
    let snr = report["signal"]["snr"].as_f64().unwrap();
    let shown = span_value(&dom, "snr");
    assert!((shown - snr).abs() <= 1e-3 * snr, "SNR {shown} vs {snr}");
    assert_eq!(dom.matches("data:image/png;base64,").count(), 4);
    // The 64-px-wide dn.png is shown 12× enlarged (768 px), pixels kept square and sharp.
    assert!(
        dom.contains("<img class=\"pixels\" width=\"768\" height=\"576\""),
        "dn.png not enlarged"
    );

    // The screenshot shows a page, not a blank: many grey levels with a real spread, and
    // the inferno colours of the temperature picture somewhere on it.
    let shot = dir.path().join("screenshot.png");
    let profile = tempfile::tempdir().unwrap();
    run_chromium(
        profile.path(),
        &[
            format!("--screenshot={}", shot.display()),
            "--window-size=1200,2000".to_string(),
        ],
        &page,
    );
    let (w, h, ch, px) = read_png8(&shot);
    assert_eq!((w, h), (1200, 2000));
    let lum: Vec<f64> = px
        .chunks(ch)
        .map(|c| 0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64)
        .collect();
    let mean = lum.iter().sum::<f64>() / lum.len() as f64;
    let var = lum.iter().map(|l| (l - mean) * (l - mean)).sum::<f64>() / lum.len() as f64;
    assert!(
        var.sqrt() > 20.0,
        "screenshot nearly uniform: σ = {:.1}",
        var.sqrt()
    );
    let orange = px
        .chunks(ch)
        .filter(|c| c[0] > 200 && c[1] > 60 && c[1] < 160 && c[2] < 80)
        .count();
    assert!(orange > 500, "{orange} inferno-orange pixels");
    if let Ok(keep) = std::env::var("EOIR_KEEP_SCREENSHOT") {
        std::fs::copy(&shot, keep).unwrap();
    }
}
