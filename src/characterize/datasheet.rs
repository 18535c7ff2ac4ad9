//! The characterisation outputs: `characterization.json`, the plots (PNG: photon transfer,
//! SNR, linearity, DSNU and PRNU histograms), and a self-contained datasheet page
//! `characterization.html` with the plots inlined as base64 `data:` URIs (RFC 2397, base64
//! of RFC 4648 §4).

use std::fmt::Write as _;
use std::path::Path;

use super::analysis::Characterization;
use crate::display::base64;
use crate::error::{Error, Result};
use crate::io::{atomic_write, write_all};
use crate::plot::{
    self, significant, write_line_plot_with, HistogramPlot, LinePlot, Marker, PlotOptions, Series,
};

/// Quantisation noise variance of an ideal ADC, DN² (uniform rounding error: 1/12).
const QUANTISATION_VARIANCE_DN2: f64 = 1.0 / 12.0;
/// Points of the model curves of the SNR plot.
const MODEL_POINTS: usize = 200;
/// Bins of the DSNU and PRNU histograms.
const MAP_BINS: usize = 50;

/// Writes `OUT/characterization.json`, the plots `OUT/ptc.png`, `OUT/snr.png`,
/// `OUT/linearity.png` (when the set gives photon counts or varies the exposure time),
/// `OUT/dsnu.png`, `OUT/prnu.png` and `OUT/characterization.html` (each file atomically;
/// the directory is created).
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
/// The abscissa a plot takes from each level of the set.
type LevelAxis = Box<dyn Fn(&super::analysis::PairLevel) -> f64>;

fn write_into(c: &Characterization, out: &Path, title: &str) -> Result<()> {
    crate::io::output::create_dir_all_guarded(out)?;
    let mut json = serde_json::to_string_pretty(c)
        .map_err(|e| Error::OutOfRange(format!("cannot encode characterization.json: {e}")))?;
    json.push('\n');
    let jp = out.join("characterization.json");
    atomic_write(&jp, |w| write_all(w, json.as_bytes(), &jp))?;

    let mut figures: Vec<(&str, String, std::path::PathBuf)> = Vec::new();
    let ptc = out.join("ptc.png");
    write_ptc(c, &ptc)?;
    figures.push((
        "Photon transfer",
        format!(
            "Net temporal variance against net signal, linear axes (EMVA 1288 §6.4). Dots: frame pairs, blue in the fit (up to 70 % of saturation), grey outside it; line: the fit, slope K = {} DN/e⁻.",
            significant(c.K_DN_per_e, 4)
        ),
        ptc,
    ));
    let snr = out.join("snr.png");
    write_snr(c, &snr)?;
    figures.push((
        "Signal-to-noise ratio",
        "SNR against the net signal in electrons, log–log, up to saturation: measured pairs, the model with the measured σ_d and quantisation noise, and the ideal shot-noise limit √μₑ.".to_string(),
        snr,
    ));
    let lin = out.join("linearity.png");
    if let Some(caption) = write_linearity(c, &lin)? {
        figures.push(("Linearity", caption, lin));
    }
    let dsnu = out.join("dsnu.png");
    if write_map_histogram(c, &dsnu, MapKind::Dark)? {
        figures.push((
            "Dark signal non-uniformity",
            format!(
                "Per-pixel dark signal, averaged over the {} frames of the dark stack, minus its mean; DSNU₁₂₈₈ = {} e⁻ ({} DN) after removing the temporal noise left in the average.",
                c.spatial_frames[0],
                significant(c.DSNU1288_e, 4),
                significant(c.DSNU1288_DN, 4)
            ),
            dsnu,
        ));
    }
    let prnu = out.join("prnu.png");
    if write_map_histogram(c, &prnu, MapKind::Photo)? {
        figures.push((
            "Photo-response non-uniformity",
            format!(
                "Per-pixel net signal (bright stack average minus dark stack average) relative to its mean; PRNU₁₂₈₈ = {} % after removing the temporal noise and the DSNU.",
                significant(c.PRNU1288_percent, 4)
            ),
            prnu,
        ));
    }

    // The plots just written are read back through the regular-file guard: a FIFO or
    // device swapped in meanwhile is refused rather than blocking or streaming forever.
    let mut inline = Vec::new();
    for (name, caption, path) in &figures {
        let bytes = crate::input::read_regular(path, crate::input::MAX_TEXT_BYTES)?;
        inline.push((
            *name,
            caption.as_str(),
            format!("data:image/png;base64,{}", base64(&bytes)),
        ));
    }
    let html = page(c, title, &inline);
    let hp = out.join("characterization.html");
    atomic_write(&hp, |w| write_all(w, html.as_bytes(), &hp))
}

/// The net signal at saturation, DN (at the variance maximum).
fn saturation_net_dn(c: &Characterization) -> f64 {
    c.u_y_sat_DN
}

/// The photon-transfer plot: linear axes, pairs in and out of the fit, the fit line.
fn write_ptc(c: &Characterization, path: &Path) -> Result<()> {
    let (fit_x, fit_y): (Vec<f64>, Vec<f64>) = c
        .levels
        .iter()
        .filter(|l| l.in_fit)
        .map(|l| (l.net_mean_dn, l.net_variance_dn2))
        .unzip();
    let (out_x, out_y): (Vec<f64>, Vec<f64>) = c
        .levels
        .iter()
        .filter(|l| !l.in_fit && l.net_mean_dn.is_finite() && l.net_variance_dn2.is_finite())
        .map(|l| (l.net_mean_dn, l.net_variance_dn2))
        .unzip();
    let sat = saturation_net_dn(c);
    let line_x = vec![0.0, sat];
    let line_y: Vec<f64> = line_x
        .iter()
        .map(|x| c.K_DN_per_e * x + c.ptc_intercept_DN2)
        .collect();
    let fit_label = format!(
        "fit σ²_y.net = K μ_y.net + b, K = {} DN/e⁻",
        significant(c.K_DN_per_e, 4)
    );
    write_line_plot_with(
        path,
        &LinePlot {
            title: "Photon transfer",
            x_label: "net signal μ_y − μ_y.dark (DN)",
            y_label: "net variance σ²_y − σ²_y.dark (DN²)",
            series: vec![
                Series {
                    label: "pairs in the fit",
                    x: &fit_x,
                    y: &fit_y,
                },
                Series {
                    label: "pairs outside the fit",
                    x: &out_x,
                    y: &out_y,
                },
                Series {
                    label: &fit_label,
                    x: &line_x,
                    y: &line_y,
                },
            ],
            markers: vec![Marker {
                label: "saturation μ_y.sat",
                x: sat,
            }],
            y_range: None,
            size_px: (800, 560),
        },
        &PlotOptions {
            dot_series: vec![0],
            muted_series: vec![1],
            ..PlotOptions::default()
        },
    )
}

/// The SNR plot: log–log against net electrons, measured pairs up to saturation (past it
/// the variance collapses and the ratio means nothing), the model `μ_e / √(σ_d² + σ_q²/K² + μ_e)` (EMVA 1288 eq. 15) and the ideal
/// `√μ_e`, both drawn from the smallest measured signal to saturation.
fn write_snr(c: &Characterization, path: &Path) -> Result<()> {
    let k = c.K_DN_per_e;
    let sat_e = c.u_e_sat_e;
    let pts = |below: bool| -> (Vec<f64>, Vec<f64>) {
        c.levels
            .iter()
            .filter(|l| l.net_mean_dn > 0.0 && l.snr > 0.0)
            .filter(|l| (l.net_mean_dn / k <= sat_e * 1.000_001) == below)
            .map(|l| (l.net_mean_dn / k, l.snr))
            .unzip()
    };
    let (mx, my) = pts(true);
    let lo = mx.iter().copied().fold(f64::INFINITY, f64::min);
    let lo = if lo.is_finite() { lo } else { 1.0 };
    let hi = sat_e.max(lo * 10.0);
    let xs: Vec<f64> = (0..MODEL_POINTS)
        .map(|i| lo * (hi / lo).powf(i as f64 / (MODEL_POINTS - 1) as f64))
        .collect();
    let sd2 = c.sigma_d_e * c.sigma_d_e + QUANTISATION_VARIANCE_DN2 / (k * k);
    let model: Vec<f64> = xs.iter().map(|e| e / (sd2 + e).sqrt()).collect();
    let ideal: Vec<f64> = xs.iter().map(|e| e.sqrt()).collect();
    write_line_plot_with(
        path,
        &LinePlot {
            title: "Signal-to-noise ratio",
            x_label: "net signal μₑ (e⁻)",
            y_label: "SNR",
            series: vec![
                Series {
                    label: "measured",
                    x: &mx,
                    y: &my,
                },
                Series {
                    label: "model μₑ / √(σ_d² + σ_q²/K² + μₑ)",
                    x: &xs,
                    y: &model,
                },
                Series {
                    label: "ideal √μₑ",
                    x: &xs,
                    y: &ideal,
                },
            ],
            markers: vec![],
            y_range: None,
            size_px: (800, 560),
        },
        &PlotOptions {
            dot_series: vec![0],
            log_x: true,
            log_y: true,
            ..PlotOptions::default()
        },
    )
}

/// The linearity plot: net signal against photons per pixel (or exposure time when the
/// set gives no photon counts but varies it), the straight-line fit over 5–95 % of
/// saturation (EMVA 1288 §6.6), points outside that range grey. Returns the caption, or
/// `None` (nothing written) when the set has no abscissa.
fn write_linearity(c: &Characterization, path: &Path) -> Result<Option<String>> {
    let with_photons = c.levels.iter().all(|l| l.photons_per_pixel.is_some());
    let varies = c
        .levels
        .iter()
        .any(|l| l.exposure_ns != c.levels[0].exposure_ns);
    let (x_of, x_label): (LevelAxis, &str) = if with_photons {
        (
            Box::new(|l| l.photons_per_pixel.unwrap_or(f64::NAN)),
            "photons per pixel μₚ",
        )
    } else if varies {
        (Box::new(|l| l.exposure_ns * 1e-6), "exposure time (ms)")
    } else {
        return Ok(None);
    };
    let sat = saturation_net_dn(c);
    let inside = |l: &&super::analysis::PairLevel| {
        l.net_mean_dn >= 0.05 * sat && l.net_mean_dn <= 0.95 * sat
    };
    let (ix, iy): (Vec<f64>, Vec<f64>) = c
        .levels
        .iter()
        .filter(inside)
        .map(|l| (x_of(l), l.net_mean_dn))
        .unzip();
    let (ox, oy): (Vec<f64>, Vec<f64>) = c
        .levels
        .iter()
        .filter(|l| !inside(l))
        .map(|l| (x_of(l), l.net_mean_dn))
        .unzip();
    let pts: Vec<(f64, f64)> = ix.iter().copied().zip(iy.iter().copied()).collect();
    let Some((slope, offset)) = crate::processing::fit_line(&pts) else {
        return Ok(None);
    };
    let x_max = ix
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let line_x = vec![0.0, 1.05 * x_max];
    let line_y: Vec<f64> = line_x.iter().map(|x| slope * x + offset).collect();
    write_line_plot_with(
        path,
        &LinePlot {
            title: "Linearity",
            x_label,
            y_label: "net signal μ_y − μ_y.dark (DN)",
            series: vec![
                Series {
                    label: "pairs in 5–95 % of saturation",
                    x: &ix,
                    y: &iy,
                },
                Series {
                    label: "other pairs",
                    x: &ox,
                    y: &oy,
                },
                Series {
                    label: "straight-line fit",
                    x: &line_x,
                    y: &line_y,
                },
            ],
            markers: vec![],
            y_range: None,
            size_px: (800, 560),
        },
        &PlotOptions {
            dot_series: vec![0],
            muted_series: vec![1],
            ..PlotOptions::default()
        },
    )?;
    Ok(Some(format!(
        "Net signal against {}: the least-squares line over 5–95 % of saturation; linearity error LE = {} % (half the spread of the relative deviations from the line).",
        if with_photons { "the photons per pixel" } else { "the exposure time" },
        c.linearity_error_percent
            .map_or("—".to_string(), |v| significant(v, 3))
    )))
}

/// Which per-pixel map a histogram shows.
#[derive(Clone, Copy)]
enum MapKind {
    /// Dark stack average minus its mean, DN.
    Dark,
    /// Net signal (bright − dark averages) relative to its mean, %.
    Photo,
}

/// Histogram of a per-pixel map over its 0.05–99.95 % range. Returns `false` (nothing
/// written) when the maps are absent or constant.
fn write_map_histogram(c: &Characterization, path: &Path, kind: MapKind) -> Result<bool> {
    let dark = &c.dark_mean_map_dn;
    let bright = &c.bright_mean_map_dn;
    if dark.len() < 2 || (matches!(kind, MapKind::Photo) && bright.len() != dark.len()) {
        return Ok(false);
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let values: Vec<f64> = match kind {
        MapKind::Dark => {
            let m = mean(dark);
            dark.iter().map(|v| v - m).collect()
        }
        MapKind::Photo => {
            let net: Vec<f64> = bright.iter().zip(dark).map(|(b, d)| b - d).collect();
            let m = mean(&net);
            if m <= 0.0 {
                return Ok(false);
            }
            net.iter().map(|v| 100.0 * (v / m - 1.0)).collect()
        }
    };
    let mut sorted: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    sorted.sort_by(f64::total_cmp);
    if sorted.len() < 2 {
        return Ok(false);
    }
    let lo = crate::display::percentile_sorted(&sorted, 0.05);
    let hi = crate::display::percentile_sorted(&sorted, 99.95);
    if hi <= lo {
        return Ok(false);
    }
    let (edges, counts) = plot::histogram(sorted.iter().copied(), lo, hi, MAP_BINS);
    let (title, x_label) = match kind {
        MapKind::Dark => ("Dark signal non-uniformity", "dark signal − mean (DN)"),
        MapKind::Photo => ("Photo-response non-uniformity", "net signal / mean − 1 (%)"),
    };
    let png = plot::render_histogram(&HistogramPlot {
        title,
        x_label,
        edges: &edges,
        counts: &counts,
        markers: vec![],
        size_px: (800, 420),
    })?;
    crate::io::raster::write_png_bytes(path, &png)?;
    Ok(true)
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or_else(|| "—".to_string(), |x| format!("{x:.digits$}"))
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The datasheet page; `figures` are (heading, caption, data URI).
fn page(c: &Characterization, title: &str, figures: &[(&str, &str, String)]) -> String {
    let mut rows = String::new();
    let mut row = |name: &str, value: String, unit: &str, note: Option<&str>| {
        let (class, note) = match note {
            Some(n) => (" class=warn", format!("<td class=warn>{n}</td>")),
            None => ("", "<td></td>".to_string()),
        };
        let _ = writeln!(
            rows,
            "<tr{class}><td>{name}</td><td class=v>{value}</td><td>{unit}</td>{note}</tr>"
        );
    };
    row(
        "System gain K",
        format!("{:.5}", c.K_DN_per_e),
        "DN/e⁻",
        None,
    );
    row(
        "Inverse system gain 1/K",
        format!("{:.4}", 1.0 / c.K_DN_per_e),
        "e⁻/DN",
        None,
    );
    row("Quantum efficiency η", opt(c.QE_percent, 2), "%", None);
    row(
        "Temporal dark noise σ<sub>d</sub>",
        format!("{:.3}", c.sigma_d_e),
        "e⁻",
        c.sigma_d_quantisation_limited
            .then_some("upper limit: quantisation-limited"),
    );
    row(
        "Temporal dark noise σ<sub>y.dark</sub>",
        format!("{:.3}", c.sigma_y_dark_DN),
        "DN",
        None,
    );
    row(
        "DSNU<sub>1288</sub>",
        format!("{:.3}", c.DSNU1288_e),
        "e⁻",
        None,
    );
    row(
        "PRNU<sub>1288</sub>",
        format!("{:.3}", c.PRNU1288_percent),
        "%",
        None,
    );
    row(
        "Saturation capacity μ<sub>e.sat</sub>",
        significant(c.u_e_sat_e, 5),
        "e⁻",
        c.saturation_at_brightest_level
            .then_some("lower bound: the variance still rises at the brightest level"),
    );
    row(
        "Absolute sensitivity threshold μ<sub>e.min</sub>",
        format!("{:.3}", c.u_e_min_e),
        "e⁻",
        None,
    );
    row(
        "Absolute sensitivity threshold μ<sub>p.min</sub>",
        opt(c.u_p_min, 2),
        "photons",
        None,
    );
    row(
        "SNR<sub>max</sub>",
        format!("{:.1} ({:.1} dB)", c.SNR_max, c.SNR_max_dB),
        "",
        None,
    );
    row(
        "Dynamic range",
        format!("{:.1} ({:.1} dB)", c.DR, c.DR_dB),
        "",
        None,
    );
    row(
        "Linearity error LE",
        opt(c.linearity_error_percent, 3),
        "%",
        None,
    );
    let negative = "negative: not a physical value — the dark signal does not grow measurably with exposure time at these times (too little dark current, or too few dark exposures)";
    let dc_note = |v: Option<f64>| v.filter(|x| *x < 0.0).map(|_| negative);
    row(
        "Dark current (from the mean)",
        c.dark_current_mean_e_per_s
            .map_or("—".to_string(), |v| significant(v, 4)),
        "e⁻/s",
        dc_note(c.dark_current_mean_e_per_s),
    );
    row(
        "Dark current (from the variance)",
        c.dark_current_variance_e_per_s
            .map_or("—".to_string(), |v| significant(v, 4)),
        "e⁻/s",
        dc_note(c.dark_current_variance_e_per_s),
    );
    row(
        "Pixels used / defective",
        format!("{} / {}", c.pixels_used, c.defective_pixels),
        "",
        None,
    );
    row(
        "Photon-transfer pairs / in fit",
        format!("{} / {}", c.levels.len(), c.fit_levels),
        "",
        None,
    );
    let mut notes = String::new();
    if c.saturation_at_brightest_level {
        notes.push_str("<p class=warn>The temporal variance still rises at the brightest level: the saturation capacity is only a lower bound.</p>");
    }
    if c.sigma_d_quantisation_limited {
        notes.push_str("<p class=warn>σ<sub>y.dark</sub>² &lt; 0.24 DN²: the dark noise is quantisation-limited and σ<sub>d</sub> is an upper limit.</p>");
    }
    if [c.dark_current_mean_e_per_s, c.dark_current_variance_e_per_s]
        .iter()
        .any(|v| v.is_some_and(|x| x < 0.0))
    {
        notes.push_str("<p class=warn>A dark current came out negative: it is the slope of the dark signal against exposure time, and within its noise the slope is zero. Record dark pairs over a wider range of exposure times to measure it.</p>");
    }
    let mut figs = String::new();
    for (name, caption, uri) in figures {
        let _ = writeln!(
            figs,
            "<figure><h2>{name}</h2><img alt=\"{name}\" src=\"{uri}\"><figcaption>{}</figcaption></figure>",
            escape(caption)
        );
    }
    format!(
        "<!DOCTYPE html>\n<html lang=en><head><meta charset=utf-8><title>EMVA 1288 characterisation — {t}</title>\n<style>body{{font-family:-apple-system,'Segoe UI',Roboto,'DejaVu Sans',sans-serif;max-width:960px;margin:2em auto;padding:0 16px;color:#1d2330;background:#f6f7f9}}h1{{font-size:26px;margin-bottom:4px}}table{{border-collapse:collapse;background:#fff;box-shadow:0 1px 3px rgba(0,0,0,.12)}}td{{padding:4px 10px;border-bottom:1px solid #e4e6ee}}td.v{{text-align:right;font-variant-numeric:tabular-nums}}tr.warn td{{background:#fff4e0}}.warn{{color:#a40}}figure{{background:#fff;border-radius:8px;padding:12px;margin:16px 0;box-shadow:0 1px 3px rgba(0,0,0,.12)}}figure h2{{font-size:17px;margin:0 0 8px;color:#3b4a6b}}img{{max-width:100%;display:block;margin:0 auto}}figcaption{{font-size:13px;color:#445;margin-top:6px}}</style></head>\n<body><h1>EMVA 1288 characterisation</h1><p>{t} — {w} × {h} pixels, {bits} bit. Method: EMVA Standard 1288 Release 4.0 Linear (photon transfer from frame pairs, non-uniformity from averaged stacks).</p>\n<table>\n{rows}</table>\n{notes}{figs}</body></html>\n",
        t = escape(title),
        w = c.image_size[0],
        h = c.image_size[1],
        bits = c.bits,
    )
}
