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
///
/// The four files are one product set ([`crate::io::output::ProductSet`]): an error or
/// a signal leaves an earlier characterisation in `out` whole, never a mix.
pub fn write_outputs(c: &Characterization, out: &Path, title: &str) -> Result<()> {
    let set = crate::io::output::ProductSet::begin(out)?;
    write_into(c, set.staging_dir(), title).map_err(|e| set.name_final(e))?;
    set.commit()?;
    Ok(())
}

/// [`write_outputs`] into the directory `out` itself (the product set's staging place).
fn write_into(c: &Characterization, out: &Path, title: &str) -> Result<()> {
    crate::io::output::create_dir_all_guarded(out)?;
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
    let sd2 = c.sigma_d_e * c.sigma_d_e;
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
                    label: "model  mu_e / sqrt(sigma_d^2 + mu_e)",
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
    let mut row = |name: &str, value: String, unit: &str| {
        let _ = writeln!(
            rows,
            "<tr><td>{name}</td><td class=v>{value}</td><td>{unit}</td></tr>"
        );
    };
    row("System gain K", format!("{:.5}", c.K_DN_per_e), "DN/e⁻");
    row(
        "Inverse system gain 1/K",
        format!("{:.4}", 1.0 / c.K_DN_per_e),
        "e⁻/DN",
    );
    row("Quantum efficiency η", opt(c.QE_percent, 2), "%");
    row(
        "Temporal dark noise σ_d",
        format!("{:.3}", c.sigma_d_e),
        "e⁻",
    );
    row(
        "Temporal dark noise σ_y.dark",
        format!("{:.3}", c.sigma_y_dark_DN),
        "DN",
    );
    row("DSNU₁₂₈₈", format!("{:.3}", c.DSNU1288_e), "e⁻");
    row("PRNU₁₂₈₈", format!("{:.3}", c.PRNU1288_percent), "%");
    row(
        "Saturation capacity μ_e.sat",
        format!("{:.1}", c.u_e_sat_e),
        "e⁻",
    );
    row(
        "Absolute sensitivity threshold μ_e.min",
        format!("{:.3}", c.u_e_min_e),
        "e⁻",
    );
    row(
        "Absolute sensitivity threshold μ_p.min",
        opt(c.u_p_min, 2),
        "photons",
    );
    row(
        "SNR_max",
        format!("{:.1} ({:.1} dB)", c.SNR_max, c.SNR_max_dB),
        "",
    );
    row(
        "Dynamic range",
        format!("{:.1} ({:.1} dB)", c.DR, c.DR_dB),
        "",
    );
    row("Linearity error LE", opt(c.linearity_error_percent, 3), "%");
    row(
        "Dark current (mean)",
        opt(c.dark_current_mean_e_per_s, 4),
        "e⁻/s",
    );
    row(
        "Dark current (variance)",
        opt(c.dark_current_variance_e_per_s, 4),
        "e⁻/s",
    );
    row(
        "Pixels used / defective",
        format!("{} / {}", c.pixels_used, c.defective_pixels),
        "",
    );
    row(
        "Photon-transfer pairs / in fit",
        format!("{} / {}", c.levels.len(), c.fit_levels),
        "",
    );
    let mut notes = String::new();
    if c.saturation_at_brightest_level {
        notes.push_str("<p class=warn>The temporal variance still rises at the brightest level: the saturation capacity is only a lower bound.</p>");
    }
    if c.sigma_d_quantisation_limited {
        notes.push_str("<p class=warn>σ_y.dark² &lt; 0.24 DN²: the dark noise is quantisation-limited and σ_d is an upper limit.</p>");
    }
    format!(
        "<!DOCTYPE html>\n<html lang=en><head><meta charset=utf-8><title>EMVA 1288 characterisation — {t}</title>\n<style>body{{font-family:sans-serif;max-width:900px;margin:2em auto;color:#222}}table{{border-collapse:collapse}}td{{padding:3px 10px;border-bottom:1px solid #ddd}}td.v{{text-align:right;font-variant-numeric:tabular-nums}}.warn{{color:#a40}}img{{max-width:100%}}</style></head>\n<body><h1>EMVA 1288 characterisation</h1><p>{t} — {w} × {h} pixels, {bits} bit. Method: EMVA Standard 1288 Release 4.0 Linear (photon transfer from frame pairs, non-uniformity from averaged stacks).</p>\n<table>\n{rows}</table>\n{notes}<h2>Photon transfer</h2><img alt=\"photon transfer curve\" src=\"{ptc_uri}\">\n<h2>SNR</h2><img alt=\"SNR curve\" src=\"{snr_uri}\">\n</body></html>\n",
        t = escape(title),
        w = c.image_size[0],
        h = c.image_size[1],
        bits = c.bits,
    )
}
