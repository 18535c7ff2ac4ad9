//! The characterisation outputs: `characterization.json`, the photon-transfer and SNR
//! plots (PNG), and a self-contained datasheet page `characterization.html` with the plots
//! inlined as base64 `data:` URIs (RFC 2397, base64 of RFC 4648 §4).

use std::fmt::Write as _;
use std::path::Path;

use super::analysis::Characterization;
use crate::display::base64;
use crate::error::{Error, Result};
use crate::io::{atomic_write, write_all};
use crate::plot::{write_line_plot, LinePlot, Series};

/// Writes `OUT/characterization.json`, `OUT/ptc.png`, `OUT/snr.png` and
/// `OUT/characterization.html` (each file atomically; the directory is created).
///
/// Errors: I/O failures, naming the file.
pub fn write_outputs(c: &Characterization, out: &Path, title: &str) -> Result<()> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let mut json = serde_json::to_string_pretty(c)
        .map_err(|e| Error::OutOfRange(format!("cannot encode characterization.json: {e}")))?;
    json.push('\n');
    let jp = out.join("characterization.json");
    atomic_write(&jp, |w| write_all(w, json.as_bytes(), &jp))?;

    // Photon-transfer curve, log-log: net variance vs net signal, with the fit σ² = K μ.
    let pos: Vec<_> = c
        .levels
        .iter()
        .filter(|l| l.net_mean_dn > 0.0 && l.net_variance_dn2 > 0.0)
        .collect();
    let x: Vec<f64> = pos.iter().map(|l| l.net_mean_dn.log10()).collect();
    let y: Vec<f64> = pos.iter().map(|l| l.net_variance_dn2.log10()).collect();
    let yfit: Vec<f64> = pos
        .iter()
        .map(|l| {
            (c.K_DN_per_e * l.net_mean_dn + c.ptc_intercept_DN2)
                .max(1e-12)
                .log10()
        })
        .collect();
    let ptc = out.join("ptc.png");
    write_line_plot(
        &ptc,
        &LinePlot {
            title: "Photon transfer (log-log)",
            x_label: "log10 net signal  mu_y - mu_y.dark  [DN]",
            y_label: "log10 net variance [DN^2]",
            series: vec![
                Series {
                    label: "measured",
                    x: &x,
                    y: &y,
                },
                Series {
                    label: "fit: K x + b",
                    x: &x,
                    y: &yfit,
                },
            ],
            markers: vec![],
            y_range: None,
            size_px: (800, 560),
        },
    )?;

    // SNR vs signal in electrons, log-log, with the model μ_e/√(σ_d² + μ_e) and the ideal √μ_e.
    let pos: Vec<_> = c
        .levels
        .iter()
        .filter(|l| l.net_mean_dn > 0.0 && l.snr > 0.0)
        .collect();
    let xe: Vec<f64> = pos
        .iter()
        .map(|l| (l.net_mean_dn / c.K_DN_per_e).log10())
        .collect();
    let ys: Vec<f64> = pos.iter().map(|l| l.snr.log10()).collect();
    // EMVA 1288 Release 4.0: SNR = μ_e/√(σ_d² + σ_q²/K² + μ_e), σ_d² + σ_q²/K² being
    // σ_y.dark²/K² (the floored σ_y.dark).
    let sd2 = (c.sigma_y_dark_DN / c.K_DN_per_e).powi(2);
    let model: Vec<f64> = pos
        .iter()
        .map(|l| {
            let e = l.net_mean_dn / c.K_DN_per_e;
            (e / (sd2 + e).sqrt()).log10()
        })
        .collect();
    let ideal: Vec<f64> = xe.iter().map(|v| 0.5 * v).collect();
    let snr = out.join("snr.png");
    write_line_plot(
        &snr,
        &LinePlot {
            title: "Signal-to-noise ratio (log-log)",
            x_label: "log10 net signal [e-]",
            y_label: "log10 SNR",
            series: vec![
                Series {
                    label: "measured",
                    x: &xe,
                    y: &ys,
                },
                Series {
                    label: "model  mu_e / sqrt(sigma_d^2 + sigma_q^2/K^2 + mu_e)",
                    x: &xe,
                    y: &model,
                },
                Series {
                    label: "ideal  sqrt(mu_e)",
                    x: &xe,
                    y: &ideal,
                },
            ],
            markers: vec![],
            y_range: None,
            size_px: (800, 560),
        },
    )?;

    // The plots just written are read back through the regular-file guard: a FIFO or
    // device swapped in meanwhile is refused rather than blocking or streaming forever.
    let img = |p: &Path| -> Result<String> {
        let bytes = crate::input::read_regular(p, crate::input::MAX_TEXT_BYTES)?;
        Ok(format!("data:image/png;base64,{}", base64(&bytes)))
    };
    let html = page(c, title, &img(&ptc)?, &img(&snr)?);
    let hp = out.join("characterization.html");
    atomic_write(&hp, |w| write_all(w, html.as_bytes(), &hp))
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or_else(|| "—".to_string(), |x| format!("{x:.digits$}"))
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The datasheet page.
fn page(c: &Characterization, title: &str, ptc_uri: &str, snr_uri: &str) -> String {
    let mut rows = String::new();
    // The standard uncertainty of the figure a row shows, with the row's own digits.
    let pm = |field: &str, digits: usize| -> String {
        c.uncertainties
            .get(field)
            .map_or_else(String::new, |u| format!("{u:.digits$}"))
    };
    let mut row = |name: &str, value: String, unit: &str, u: String| {
        let _ =
            writeln!(
            rows,
            "<tr><td>{name}</td><td class=v>{value}</td><td class=v>{}</td><td>{unit}</td></tr>",
            if u.is_empty() { String::new() } else { format!("± {u}") }
        );
    };
    row(
        "System gain K",
        format!("{:.5}", c.K_DN_per_e),
        "DN/e⁻",
        pm("K_DN_per_e", 5),
    );
    row(
        "Inverse system gain 1/K",
        format!("{:.4}", 1.0 / c.K_DN_per_e),
        "e⁻/DN",
        pm("inverse_K_e_per_DN", 4),
    );
    row(
        "Quantum efficiency η",
        opt(c.QE_percent, 2),
        "%",
        pm("QE_percent", 2),
    );
    row(
        "Temporal dark noise σ_d",
        format!("{:.3}", c.sigma_d_e),
        "e⁻",
        pm("sigma_d_e", 3),
    );
    row(
        "Temporal dark noise σ_y.dark",
        format!("{:.3}", c.sigma_y_dark_DN),
        "DN",
        pm("sigma_y_dark_DN", 3),
    );
    row(
        "DSNU₁₂₈₈",
        format!("{:.3}", c.DSNU1288_e),
        "e⁻",
        pm("DSNU1288_e", 3),
    );
    row(
        "PRNU₁₂₈₈",
        format!("{:.3}", c.PRNU1288_percent),
        "%",
        pm("PRNU1288_percent", 3),
    );
    row(
        "Saturation capacity μ_e.sat",
        format!("{:.1}", c.u_e_sat_e),
        "e⁻",
        pm("u_e_sat_e", 1),
    );
    row(
        "Absolute sensitivity threshold μ_e.min",
        format!("{:.3}", c.u_e_min_e),
        "e⁻",
        pm("u_e_min_e", 3),
    );
    row(
        "Absolute sensitivity threshold μ_p.min",
        opt(c.u_p_min, 2),
        "photons",
        pm("u_p_min", 2),
    );
    row(
        "SNR_max",
        format!("{:.1} ({:.1} dB)", c.SNR_max, c.SNR_max_dB),
        "",
        pm("SNR_max", 1),
    );
    row(
        "Dynamic range",
        format!("{:.1} ({:.1} dB)", c.DR, c.DR_dB),
        "",
        pm("DR", 1),
    );
    row(
        "Linearity error LE",
        opt(c.linearity_error_percent, 3),
        "%",
        pm("linearity_error_percent", 3),
    );
    row(
        "Dark current (mean)",
        opt(c.dark_current_mean_e_per_s, 4),
        "e⁻/s",
        pm("dark_current_mean_e_per_s", 4),
    );
    row(
        "Dark current (variance)",
        opt(c.dark_current_variance_e_per_s, 4),
        "e⁻/s",
        pm("dark_current_variance_e_per_s", 4),
    );
    row(
        "Pixels used / defective",
        format!("{} / {}", c.pixels_used, c.defective_pixels),
        "",
        String::new(),
    );
    row(
        "Photon-transfer pairs / in fit",
        format!("{} / {}", c.levels.len(), c.fit_levels),
        "",
        String::new(),
    );
    let mut notes = String::new();
    for w in &c.warnings {
        let _ = write!(notes, "<p class=warn>{}</p>", escape(w));
    }
    if c.saturation_at_brightest_level {
        notes.push_str("<p class=warn>The temporal variance still rises at the brightest level: the saturation capacity is only a lower bound.</p>");
    }

    format!(
        "<!DOCTYPE html>\n<html lang=en><head><meta charset=utf-8><title>EMVA 1288 characterisation — {t}</title>\n<style>body{{font-family:sans-serif;max-width:900px;margin:2em auto;color:#222}}table{{border-collapse:collapse}}td{{padding:3px 10px;border-bottom:1px solid #ddd}}td.v{{text-align:right;font-variant-numeric:tabular-nums}}.warn{{color:#a40}}img{{max-width:100%}}</style></head>\n<body><h1>EMVA 1288 characterisation</h1><p>{t} — {w} × {h} pixels, {bits} bit. Method: EMVA Standard 1288 Release 4.0 Linear (photon transfer from frame pairs, non-uniformity from averaged stacks); ± is the standard uncertainty (1σ, statistical).</p>\n<table>\n{rows}</table>\n{notes}<h2>Photon transfer</h2><img alt=\"photon transfer curve\" src=\"{ptc_uri}\">\n<h2>SNR</h2><img alt=\"SNR curve\" src=\"{snr_uri}\">\n</body></html>\n",
        t = escape(title),
        w = c.image_size[0],
        h = c.image_size[1],
        bits = c.bits,
    )
}
