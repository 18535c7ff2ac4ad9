//! `report.html` and the EMVA 1288 datasheet in a real browser: headless Chromium renders
//! the page of a demo run and the datasheet of a simulated characterisation; the
//! screenshots must not be blank, the rendered DOM must hold the run's key numbers, and no
//! number on either page may be printed with more than 6 significant digits.
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

/// The luminance of a screenshot spreads widely: a page, not a blank.
fn assert_not_blank(ch: usize, px: &[u8]) {
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
}

/// The text of an HTML page: tags (with their attributes, so the inline images) removed.
pub(crate) fn visible_text(html: &str) -> String {
    let mut out = String::with_capacity(html.len() / 4);
    let mut in_tag = false;
    let mut in_style = false;
    for (i, c) in html.char_indices() {
        if c == '<' {
            in_tag = true;
            let rest = html[i..].get(..7).unwrap_or("").to_ascii_lowercase();
            if rest.starts_with("<style") {
                in_style = true;
            } else if rest.starts_with("</style") {
                in_style = false;
            }
        } else if c == '>' {
            in_tag = false;
            out.push(' ');
        } else if !in_tag && !in_style {
            out.push(c);
        }
    }
    out
}

/// Decimal numbers in `text` (a run of digits with one decimal point, optionally an
/// exponent) printed with more than 6 significant digits. Runs with several points
/// (versions such as 0.1.0) are not numbers.
pub(crate) fn long_floats(text: &str) -> Vec<String> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        if !chars[i].is_ascii_digit() {
            i += 1;
            continue;
        }
        let start = i;
        while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '.') {
            i += 1;
        }
        let run: String = chars[start..i].iter().collect();
        let run = run.trim_end_matches('.');
        if run.matches('.').count() != 1 {
            continue;
        }
        let digits: String = run.chars().filter(char::is_ascii_digit).collect();
        let significant = digits.trim_start_matches('0').len();
        if significant > 6 {
            out.push(run.to_string());
        }
    }
    out
}

#[test]
fn long_floats_are_found() {
    assert_eq!(
        long_floats("257.72102733608335 K"),
        vec!["257.72102733608335"]
    );
    assert!(long_floats("257.7 K, 0.001234, 3.668e6, eoir 0.1.0, 110592 px").is_empty());
    assert_eq!(long_floats("K = 0.04932517"), vec!["0.04932517"]);
    assert!(long_floats("K = 0.0493251").is_empty());
    assert_eq!(
        visible_text("<p a=\"1.23456789\">x 1.5</p><style>b{w:1.23456789}</style>").trim(),
        "x 1.5"
    );
}

/// The pages' text holds no number with more than 6 significant digits (the source,
/// without a browser): `report.html` of a demo run and the datasheet of a simulated set.
#[test]
fn report_and_datasheet_print_no_long_floats() {
    let dir = tempfile::tempdir().unwrap();
    small_demo("multimir", dir.path());
    let page = std::fs::read_to_string(dir.path().join("report.html")).unwrap();
    let long = long_floats(&visible_text(&page));
    assert!(long.is_empty(), "report.html: {long:?}");
    let sheet = simulated_datasheet(dir.path());
    let text = std::fs::read_to_string(&sheet).unwrap();
    let long = long_floats(&visible_text(&text));
    assert!(long.is_empty(), "characterization.html: {long:?}");
}

/// Simulates a small EMVA 1288 set in `dir/set` and characterises it into `dir/emva`;
/// returns the datasheet's path.
fn simulated_datasheet(dir: &Path) -> std::path::PathBuf {
    let eoir = env!("CARGO_BIN_EXE_eoir");
    let set = dir.join("set");
    let emva = dir.join("emva");
    let ok = |out: std::process::Output| {
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        )
    };
    ok(Command::new(eoir)
        .args([
            "characterize",
            "--simulate",
            "--sensor",
            "ccd",
            "--window",
            "48",
        ])
        .args([
            "--set",
            "detector.read_noise_e=60",
            "--set",
            "detector.offset_dn=40",
        ])
        .args([
            "--set",
            "detector.fpn.dsnu_sigma_e=40",
            "--set",
            "detector.fpn.prnu_sigma_rel=0.01",
        ])
        .arg("-o")
        .arg(&set)
        .output()
        .unwrap());
    ok(Command::new(eoir)
        .arg("characterize")
        .arg(&set)
        .arg("-o")
        .arg(&emva)
        .output()
        .unwrap());
    emva.join("characterization.html")
}

#[test]
#[ignore = "needs chromium; run by .ci/run with -- --ignored"]
fn browser_renders_the_emva_datasheet_with_its_plots() {
    let dir = tempfile::tempdir().unwrap();
    let page = simulated_datasheet(dir.path());
    let profile = tempfile::tempdir().unwrap();
    let dom = run_chromium(profile.path(), &["--dump-dom".to_string()], &page);
    let dom = String::from_utf8(dom.stdout).unwrap();
    assert!(dom.contains("System gain K"), "datasheet not rendered");
    // Photon transfer, SNR, linearity, DSNU and PRNU.
    assert_eq!(dom.matches("data:image/png;base64,").count(), 5);
    let long = long_floats(&visible_text(&dom));
    assert!(
        long.is_empty(),
        "numbers with more than 6 significant digits: {long:?}"
    );
    let shot = dir.path().join("datasheet.png");
    let profile = tempfile::tempdir().unwrap();
    run_chromium(
        profile.path(),
        &[
            format!("--screenshot={}", shot.display()),
            "--window-size=1200,2400".to_string(),
        ],
        &page,
    );
    let (w, h, ch, px) = read_png8(&shot);
    assert_eq!((w, h), (1200, 2400));
    assert_not_blank(ch, &px);
    // The plots' blue measurement dots are on the page.
    let blue = px
        .chunks(ch)
        .filter(|c| c[2] > 150 && c[0] < 80 && c[1] > 90 && c[1] < 150)
        .count();
    assert!(blue > 200, "{blue} blue pixels: the plots are missing");
    if let Ok(keep) = std::env::var("EOIR_KEEP_DATASHEET_SCREENSHOT") {
        std::fs::copy(&shot, keep).unwrap();
    }
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
    // dn, temperature, spectral response, MTF, histogram.
    assert_eq!(dom.matches("data:image/png;base64,").count(), 5);
    let long = long_floats(&visible_text(&dom));
    assert!(
        long.is_empty(),
        "numbers with more than 6 significant digits: {long:?}"
    );
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
    assert_not_blank(ch, &px);
    let orange = px
        .chunks(ch)
        .filter(|c| c[0] > 200 && c[1] > 60 && c[1] < 160 && c[2] < 80)
        .count();
    assert!(orange > 500, "{orange} inferno-orange pixels");
    if let Ok(keep) = std::env::var("EOIR_KEEP_SCREENSHOT") {
        std::fs::copy(&shot, keep).unwrap();
    }
}
