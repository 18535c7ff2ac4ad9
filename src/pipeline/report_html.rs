//! The pictures of a run and `report.html`: one self-contained page (images inline as
//! base64 PNG data URIs, no scripts, no external resources) that a person opens in any
//! browser to see what the sensor did — sensor, options, optics, sampling, noise, SNR, NETD,
//! saturation, warnings, the DN and temperature pictures, the MTF curves and the DN
//! histogram. The numbers are taken from the run's report (the same values as
//! `report.json`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde_json::Value;

use super::RunSummary;
use crate::display::{self, base64, Stretch};
use crate::error::{Error, Result};
use crate::plot::{self, HistogramPlot, Marker};
use crate::report::MtfCurves;

/// Bins of the DN histogram.
pub const HISTOGRAM_BINS: usize = 200;
/// Frequencies at which `mtf.png`'s curves are evaluated.
pub const MTF_POINTS: usize = 300;
/// Width, CSS px, the page enlarges a small `dn.png` towards, by a whole factor (each
/// detector pixel a square of equal size; `image-rendering: pixelated`, no smoothing).
pub const DN_DISPLAY_WIDTH_PX: usize = 768;
/// The DN histogram's axis runs from the display stretch's black level to its white level
/// (the `dn.png` percentiles) widened by this fraction of that span on each side (clipped
/// to 0 and the ADC full scale), so dead and hot pixels (0.5 % in some presets) do not
/// squeeze the distribution into a third of the plot; the caption counts what lies outside.
pub const HISTOGRAM_WIDEN: f64 = 0.25;

/// A picture as PNG bytes with the file name it is written under.
#[derive(Debug, Clone, PartialEq)]
pub struct Picture {
    /// File name in the output directory, e.g. `dn.png`.
    pub file_name: &'static str,
    /// PNG bytes.
    pub png: Vec<u8>,
    /// One-line caption: what is shown and how it is scaled.
    pub caption: String,
}

/// A section a caller adds to the page after the run ([`super::RunOutput::extra_sections`]):
/// a table of labelled values, notes, and pictures (written beside `report.html` too).
#[derive(Debug, Clone, PartialEq)]
pub struct ExtraSection {
    /// HTML id of the section, e.g. `figures-of-merit`.
    pub id: &'static str,
    /// Heading.
    pub title: String,
    /// Table rows: label and value, as text (escaped when written).
    pub rows: Vec<(String, String)>,
    /// Notes below the table (escaped when written).
    pub notes: Vec<String>,
    /// Pictures shown after the table.
    pub pictures: Vec<Picture>,
}

/// The pictures of the first frame of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunPictures {
    /// `dn.png`: 8-bit display of the DN with the stretch of
    /// [`display::dn_display`].
    pub dn: Picture,
    /// The stretch of `dn.png`, DN.
    pub dn_stretch: Stretch,
    /// `temperature.png` (thermal sensors with temperature products): inferno colour map
    /// and a colour bar in K.
    pub temperature: Option<Picture>,
    /// `dn_histogram.png`.
    pub histogram: Picture,
    /// `mtf.png`: the transfer functions at the response-weighted mean wavelength (absent
    /// when the sensor's band is unbounded).
    pub mtf: Option<Picture>,
    /// `trajectory.png`: a moving camera's line of sight per exposure window (the truth
    /// table `los.csv`), absent for a still camera.
    pub trajectory: Option<Picture>,
    /// `nuc_drift.png`: the residual non-uniformity against time since the NUC (a
    /// detector with `[detector.drift]`, two or more frames; docs/focal-plane.md).
    pub nuc_drift: Option<Picture>,
    /// `spectral_response.png`: filter, optics, quantum efficiency, atmosphere and their
    /// product (absent when the sensor's band is unbounded).
    pub spectral: Option<Picture>,
    /// `psf_grid.png` and `field_mtf.png`: the PSFs and the tangential/sagittal MTF at
    /// field heights 0, 0.7 and 1 (a sensor with `[optics.wavefront]`,
    /// [`super::field_pictures`]).
    pub field: Vec<Picture>,
}

impl RunPictures {
    /// Draws the pictures of frame 0 of `out`.
    pub fn render(out: &RunSummary) -> Result<RunPictures> {
        let frame = out.first;
        let (grey, dn_stretch) = display::dn_display(frame.dn.view());
        let (rows, cols) = grey.dim();
        let samples: Vec<u8> = grey.iter().copied().collect();
        let dn = Picture {
            file_name: "dn.png",
            png: display::encode_png(cols, rows, 1, &samples)?,
            caption: format!(
                "DN, linear display stretch: {:.0} DN black to {:.0} DN white (the {} and {} percentiles); raw DN in dn.tiff",
                dn_stretch.lo,
                dn_stretch.hi,
                display::DN_STRETCH_LO_PERCENT,
                display::DN_STRETCH_HI_PERCENT
            ),
        };
        let temperature = match &frame.temperature {
            Some(t) if t.iter().any(|v| v.is_finite()) => {
                let (pic, s) = display::colour_picture(t.view(), "K")?;
                let (h, w, _) = pic.dim();
                let samples: Vec<u8> = pic.iter().copied().collect();
                let (lo_p, hi_p) = display::TEMPERATURE_STRETCH_PERCENT;
                Some(Picture {
                    file_name: "temperature.png",
                    png: display::encode_png(w, h, 3, &samples)?,
                    caption: format!(
                        "apparent temperature, inferno colour map from {:.2} K to {:.2} K (the {lo_p} and {hi_p} percentiles); values in temperature.tiff",
                        s.lo, s.hi
                    ),
                })
            }
            _ => None,
        };
        let histogram = dn_histogram(out, &dn_stretch)?;
        // The run already found the mean wavelength (an adaptive integral over the
        // response) and the system MTF at Nyquist; only the curves (MTF_POINTS analytic
        // evaluations per component) are evaluated here, once for mtf.png and the page.
        let optics = &out.report.optics;
        let mtf = match optics.mean_wavelength_um {
            Some(l) => {
                let curves = MtfCurves::compute(out.sensor, l, None, MTF_POINTS)?;
                Some(Picture {
                    file_name: "mtf.png",
                    png: curves.render_png(&out.sensor.name)?,
                    caption: format!(
                        "transfer functions along x at the response-weighted mean wavelength {l:.3} µm; system MTF at Nyquist {:.3}",
                        optics.mtf_at_nyquist.unwrap_or(curves.system_at_nyquist)
                    ),
                })
            }
            None => None,
        };
        let trajectory = match out.line_of_sight {
            Some(truth) => Some(Picture {
                file_name: "trajectory.png",
                png: super::motion::trajectory_png(truth)?,
                caption: format!(
                    "line of sight: mean image displacement and smear per exposure window, detector pixels ({} windows; values in los.csv){}",
                    truth.len(),
                    if out.frame_count > 1 {
                        "; the sequence itself: preview.png (animated)"
                    } else {
                        ""
                    }
                ),
            }),
            None => None,
        };
        let nuc_drift = match out
            .report
            .focal_plane
            .as_ref()
            .and_then(super::focal_plane::drift_plot)
        {
            Some(png) => Some(Picture {
                file_name: "nuc_drift.png",
                png: png?,
                caption: "residual non-uniformity after a two-point NUC at the sequence start, against time since the NUC: expected from the drift model (line) and measured on the drift applied (dots); values in report.json, focal_plane.drift".to_string(),
            }),
            None => None,
        };
        let spectral = spectral_response(out.sensor)?;
        let field = field_optics(out.sensor, optics.mean_wavelength_um)?;
        Ok(RunPictures {
            dn,
            dn_stretch,
            temperature,
            histogram,
            mtf,
            trajectory,
            nuc_drift,
            spectral,
            field,
        })
    }

    /// The pictures in page order.
    pub fn all(&self) -> Vec<&Picture> {
        let mut v = vec![&self.dn];
        v.extend(self.temperature.as_ref());
        v.extend(self.spectral.as_ref());
        v.extend(self.mtf.as_ref());
        v.push(&self.histogram);
        v.extend(self.trajectory.as_ref());
        v.extend(self.nuc_drift.as_ref());
        v.extend(self.field.iter());
        v
    }

    /// Writes the pictures other than `dn.png` (which [`RunOutput::write`] writes for every
    /// frame) into `dir`, atomically. Returns the paths written.
    pub fn write(&self, dir: &Path) -> Result<Vec<PathBuf>> {
        let mut written = Vec::new();
        for p in self.all().into_iter().skip(1) {
            let path = dir.join(p.file_name);
            display::write_png_bytes(&path, &p.png)?;
            written.push(path);
        }
        Ok(written)
    }
}

/// The field pictures of a sensor with `[optics.wavefront]` at the mean wavelength.
fn field_optics(
    sensor: &crate::sensor::Sensor,
    wavelength_um: Option<f64>,
) -> Result<Vec<Picture>> {
    use super::field_pictures::{field_mtf_png, psf_grid_png, PSF_DECADES, REPORT_FIELDS};
    let (Some(l), Some(_)) = (wavelength_um, sensor.optics.wavefront.as_ref()) else {
        return Ok(Vec::new());
    };
    let (grid, transfers) = psf_grid_png(sensor.config(), &REPORT_FIELDS, l, 8.0)?;
    Ok(vec![
        Picture {
            file_name: "psf_grid.png",
            png: grid,
            caption: format!("pupil PSF ([optics.wavefront]) at {l:.3} µm and field heights 0, 0.7, 1 (1 = array corner, field along +y, tangential axis up); each ±8 λ/D, normalised to its peak, log10 stretch over {PSF_DECADES} decades (inferno)"),
        },
        Picture {
            file_name: "field_mtf.png",
            png: field_mtf_png(&transfers, &REPORT_FIELDS, l)?,
            caption: format!("tangential (T) and sagittal (S) pupil MTF at field heights 0, 0.7, 1, {l:.3} µm, up to the cutoff D/λ (the pupil alone: no detector, motion or atmosphere)"),
        },
    ])
}

/// Points of the spectral-response plot.
pub const SPECTRAL_POINTS: usize = 600;

/// The spectral chain of `sensor` (filter, optics, quantum efficiency, atmosphere and
/// their product, the response [`crate::sensor::Sensor::response`]) over the response's
/// support widened by 8 % each side; `None` when the support is unbounded.
fn spectral_response(sensor: &crate::sensor::Sensor) -> Result<Option<Picture>> {
    let (lo, hi) = sensor.response().support_um();
    if !(lo.is_finite() && hi.is_finite() && hi > lo) {
        return Ok(None);
    }
    let margin = 0.08 * (hi - lo);
    let (a, b) = ((lo - margin).max(0.0), hi + margin);
    let x: Vec<f64> = (0..SPECTRAL_POINTS)
        .map(|i| a + (b - a) * i as f64 / (SPECTRAL_POINTS - 1) as f64)
        .collect();
    let chain = sensor.spectral_chain();
    let sample =
        |s: &crate::spectrum::Spectrum| -> Vec<f64> { x.iter().map(|l| s.eval(*l)).collect() };
    let mut curves: Vec<(&str, Vec<f64>)> = vec![
        ("filter", sample(&chain.filter)),
        ("optics", sample(&chain.optics)),
        ("quantum efficiency", sample(&chain.qe)),
    ];
    if let Some(atm) = &chain.atmosphere {
        curves.push(("atmosphere", sample(atm)));
    }
    curves.push(("product", sample(sensor.response())));
    let peak = curves
        .last()
        .map_or(0.0, |(_, v)| v.iter().copied().fold(0.0, f64::max));
    let title = format!("{}: spectral response", sensor.name);
    let series = curves
        .iter()
        .map(|(label, y)| plot::Series { label, x: &x, y })
        .collect();
    let png = plot::render_line_plot(&plot::LinePlot {
        title: &title,
        x_label: "wavelength (µm)",
        y_label: "transmission, quantum efficiency",
        series,
        markers: vec![],
        y_range: Some((0.0, 1.05)),
        size_px: (900, 480),
    })?;
    Ok(Some(Picture {
        file_name: "spectral_response.png",
        png,
        caption: format!(
            "the spectral chain from {} to {} µm: filter transmission, optics transmission, quantum efficiency{}, and their product, the electrons per photon at the aperture (peak {})",
            plot::significant(lo, 4),
            plot::significant(hi, 4),
            if chain.atmosphere.is_some() { ", atmospheric path transmission" } else { "" },
            plot::significant(peak, 3)
        ),
    }))
}

/// The DN histogram of frame 0, with the display stretch and full scale marked.
fn dn_histogram(out: &RunSummary, stretch: &Stretch) -> Result<Picture> {
    let dn = &out.first.dn;
    let mut sorted: Vec<f64> = dn.iter().map(|v| *v as f64).collect();
    sorted.sort_by(f64::total_cmp);
    let span = (stretch.hi - stretch.lo).max(10.0);
    let full_scale = out.sensor.detector.max_dn();
    let lo = (stretch.lo - HISTOGRAM_WIDEN * span).max(0.0).floor();
    let hi = (stretch.hi + HISTOGRAM_WIDEN * span).min(full_scale).ceil();
    let below = sorted.partition_point(|v| *v < lo);
    let above = sorted.len() - sorted.partition_point(|v| *v <= hi);
    let (edges, counts) = plot::histogram(sorted.iter().copied(), lo, hi, HISTOGRAM_BINS);
    let shown: u64 = counts.iter().sum();
    let mut markers = vec![
        Marker {
            label: "black",
            x: stretch.lo,
        },
        Marker {
            label: "white",
            x: stretch.hi,
        },
    ];
    if full_scale <= hi {
        markers.push(Marker {
            label: "full scale",
            x: full_scale,
        });
    }
    let title = format!("DN histogram ({shown} of {} pixels in range)", sorted.len());
    let png = plot::render_histogram(&HistogramPlot {
        title: &title,
        x_label: "DN",
        edges: &edges,
        counts: &counts,
        markers,
        size_px: (900, 450),
    })?;
    Ok(Picture {
        file_name: "dn_histogram.png",
        png,
        caption: format!(
            "DN of frame 0 in {HISTOGRAM_BINS} bins from {lo:.0} to {hi:.0} DN (the display range widened by {:.0} % each side); {below} pixels below and {above} above it; red lines: display black/white levels{}",
            HISTOGRAM_WIDEN * 100.0,
            if full_scale <= hi {
                " and ADC full scale".to_string()
            } else {
                format!(" (the ADC full scale, {full_scale:.0} DN, lies beyond the plotted range)")
            }
        ),
    })
}

/// Width and height of a PNG from its IHDR chunk (the first chunk, PNG spec §11.2.2);
/// `None` if `png` does not start like a PNG.
pub fn png_size(png: &[u8]) -> Option<(usize, usize)> {
    const SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a];
    if png.len() < 24 || png[..8] != SIGNATURE || &png[12..16] != b"IHDR" {
        return None;
    }
    let be = |b: &[u8]| u32::from_be_bytes([b[0], b[1], b[2], b[3]]) as usize;
    Some((be(&png[16..20]), be(&png[20..24])))
}

/// The whole factor `dn.png` (`width_px` wide) is enlarged by on the page: the largest
/// that keeps it within [`DN_DISPLAY_WIDTH_PX`], at least 1.
pub fn dn_display_scale(width_px: usize) -> usize {
    (DN_DISPLAY_WIDTH_PX / width_px.max(1)).max(1)
}

/// `text` with the five HTML-special characters escaped.
pub fn escape_html(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// A number for the page: `digits` significant figures ([`plot::significant`]); `—` when
/// absent or not finite.
fn num(v: Option<f64>, digits: usize) -> String {
    v.map_or_else(|| "—".to_string(), |x| plot::significant(x, digits))
}

/// Radiance units as a person reads them: `W m-2 sr-1 um-1` → `W m⁻² sr⁻¹ µm⁻¹`
/// (exponents as superscripts, `um` as `µm`); other text unchanged.
pub fn unicode_units(units: &str) -> String {
    units
        .split(' ')
        .map(|word| {
            let (base, exp) = match word.find(|c: char| c == '-' || c.is_ascii_digit()) {
                Some(i)
                    if i > 0
                        && word[i..]
                            .trim_start_matches('-')
                            .chars()
                            .all(|c| c.is_ascii_digit()) =>
                {
                    (&word[..i], &word[i..])
                }
                _ => (word, ""),
            };
            let base = if base == "um" { "µm" } else { base };
            let sup: String = exp
                .chars()
                .map(|c| match c {
                    '-' => '⁻',
                    '0' => '⁰',
                    '1' => '¹',
                    '2' => '²',
                    '3' => '³',
                    '4' => '⁴',
                    '5' => '⁵',
                    '6' => '⁶',
                    '7' => '⁷',
                    '8' => '⁸',
                    _ => '⁹',
                })
                .collect();
            format!("{base}{sup}")
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// Free text (a sensor's description) with `um` as a word written `µm`.
fn prose_units(text: &str) -> String {
    text.split(' ')
        .map(|w| if w == "um" { "µm" } else { w })
        .collect::<Vec<_>>()
        .join(" ")
}

/// One table row; `id`, when given, names the value cell for scripts and tests.
fn row(html: &mut String, label: &str, value: &str, id: Option<&str>) {
    let id = id.map(|i| format!(" id=\"{i}\"")).unwrap_or_default();
    let _ = writeln!(
        html,
        "<tr><th>{}</th><td{id}>{value}</td></tr>",
        escape_html(label)
    );
}

/// The run report as JSON, read by pointer, with numbers rounded for the page.
struct Facts {
    r: Value,
}

impl Facts {
    /// A number.
    fn f(&self, ptr: &str) -> Option<f64> {
        self.r.pointer(ptr).and_then(Value::as_f64)
    }

    /// A value as text: strings as they are, numbers to 6 significant figures (integers
    /// whole), lists as `a, b, c`; `—` when absent.
    fn s(&self, ptr: &str) -> String {
        fn text(v: &Value) -> String {
            match v {
                Value::String(t) => t.clone(),
                Value::Null => "—".to_string(),
                Value::Number(n) if n.is_f64() => {
                    plot::significant(n.as_f64().unwrap_or(f64::NAN), 6)
                }
                Value::Array(items) => items.iter().map(text).collect::<Vec<_>>().join(", "),
                other => other.to_string(),
            }
        }
        self.r.pointer(ptr).map_or_else(|| "—".to_string(), text)
    }

    /// A list of numbers, each to `digits` significant figures, as `a, b, c`.
    fn list(&self, ptr: &str, digits: usize) -> String {
        self.r
            .pointer(ptr)
            .and_then(Value::as_array)
            .map(|a| {
                a.iter()
                    .map(|v| num(v.as_f64(), digits))
                    .collect::<Vec<_>>()
                    .join(", ")
            })
            .unwrap_or_else(|| "—".to_string())
    }
}

/// The page for `out` with `pictures` inline: one function per section, in page order.
pub fn render_page(out: &RunSummary, pictures: &RunPictures) -> Result<String> {
    let facts = Facts {
        r: serde_json::to_value(out.report)
            .map_err(|e| Error::param("run report", e.to_string(), "a serialisable report"))?,
    };
    let mut h = String::new();
    section_head(&mut h, out, &facts);
    section_warnings(&mut h, &facts);
    section_cards(&mut h, &facts);
    h.push_str("<div class=\"grid\">\n");
    section_optics(&mut h, &facts);
    section_sampling(&mut h, &facts);
    section_detector(&mut h, &facts);
    section_calibration(&mut h, &facts);
    h.push_str("</div>\n");
    section_pictures(&mut h, pictures);
    for extra in out.extra_sections {
        section_extra(&mut h, extra);
    }
    section_footer(&mut h, &facts);
    Ok(h)
}

/// `<head>`, title and the header: sensor, description, options, seed, input, version.
fn section_head(h: &mut String, out: &RunSummary, facts: &Facts) {
    let sensor = out.sensor;
    let options = facts
        .r
        .pointer("/options")
        .and_then(Value::as_object)
        .map(|o| {
            o.iter()
                .map(|(k, v)| format!("{k}={}", v.as_str().unwrap_or("")))
                .collect::<Vec<_>>()
                .join(", ")
        })
        .filter(|t| !t.is_empty())
        .unwrap_or_else(|| "none".to_string());
    let title = format!("eoir run: {}", sensor.name);
    let _ = writeln!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>",
        escape_html(&title)
    );
    let _ = writeln!(
        h,
        "<header><h1>{}</h1><p>{}</p><p class=\"meta\">options: {} · seed {} · input {} · eoir {}</p></header>",
        escape_html(&sensor.name),
        escape_html(&prose_units(&sensor.description)),
        escape_html(&options),
        escape_html(&facts.s("/seed")),
        escape_html(&facts.s("/input/name")),
        escape_html(&facts.s("/eoir_version")),
    );
}

/// The run's warnings (or "none").
fn section_warnings(h: &mut String, facts: &Facts) {
    let warnings: Vec<String> = facts
        .r
        .pointer("/warnings")
        .and_then(Value::as_array)
        .map(|a| {
            a.iter()
                .filter_map(|w| w.as_str().map(str::to_string))
                .collect()
        })
        .unwrap_or_default();
    if warnings.is_empty() {
        h.push_str(
            "<section class=\"ok\" id=\"warnings\"><h2>Warnings</h2><p>none</p></section>\n",
        );
    } else {
        h.push_str("<section class=\"warn\" id=\"warnings\"><h2>Warnings</h2><ul>\n");
        for w in &warnings {
            let _ = writeln!(h, "<li>{}</li>", escape_html(w));
        }
        h.push_str("</ul></section>\n");
    }
}

/// The key figures: SNR, NETD, MTF at Nyquist, saturation.
fn section_cards(h: &mut String, facts: &Facts) {
    let netd_mk = facts
        .f("/calibration/netd_analytic_k_at_300k")
        .map(|k| k * 1e3);
    h.push_str("<section class=\"cards\">\n");
    let card = |h: &mut String, label: &str, value: String, unit: &str, id: &str| {
        let _ = writeln!(
            h,
            "<div class=\"card\"><div class=\"label\">{label}</div><div class=\"value\"><span id=\"{id}\">{value}</span> <small>{unit}</small></div></div>"
        );
    };
    card(
        h,
        "SNR (mean signal)",
        num(facts.f("/signal/snr"), 4),
        "",
        "snr",
    );
    if netd_mk.is_some() {
        card(h, "NETD at 300 K", num(netd_mk, 3), "mK", "netd_mk");
    }
    card(
        h,
        "MTF at Nyquist",
        num(facts.f("/optics/mtf_at_nyquist"), 3),
        "",
        "mtf_nyquist",
    );
    card(
        h,
        "saturated",
        num(facts.f("/signal/saturated_percent"), 3),
        "%",
        "saturated_percent",
    );
    h.push_str("</section>\n");
}

/// Optics: focal length, F-number, IFOV, field of view, mean wavelength, λF#/pitch.
fn section_optics(h: &mut String, facts: &Facts) {
    let f = |p: &str| facts.f(p);
    h.push_str("<section><h2>Optics</h2><table>\n");
    row(
        h,
        "focal length",
        &format!(
            "{} mm",
            num(f("/optics/focal_length_m").map(|m| m * 1e3), 4)
        ),
        Some("focal_length_mm"),
    );
    row(
        h,
        "F-number",
        &num(f("/optics/f_number"), 3),
        Some("f_number"),
    );
    row(
        h,
        "IFOV",
        &format!("{} µrad", num(f("/optics/ifov_urad"), 4)),
        Some("ifov_urad"),
    );
    let fov = facts.r.pointer("/optics/fov_deg").and_then(Value::as_array);
    let fov_text = fov
        .map(|a| {
            format!(
                "{} × {}°",
                num(a.first().and_then(Value::as_f64), 4),
                num(a.get(1).and_then(Value::as_f64), 4)
            )
        })
        .unwrap_or_else(|| "—".into());
    row(h, "field of view", &fov_text, None);
    row(
        h,
        "mean wavelength",
        &format!("{} µm", num(f("/optics/mean_wavelength_um"), 4)),
        None,
    );
    row(
        h,
        "λF#/pitch",
        &num(f("/optics/lambda_f_number_over_pitch"), 3),
        Some("lambda_f_number_over_pitch"),
    );
    row(
        h,
        "MTF components",
        &escape_html(&facts.s("/optics/components")),
        None,
    );
    h.push_str("</table></section>\n");
}

/// Sampling: input size and units, scene/detector ratio and method, detector size.
fn section_sampling(h: &mut String, facts: &Facts) {
    let s = |p: &str| facts.s(p);
    h.push_str("<section><h2>Sampling</h2><table>\n");
    row(
        h,
        "input",
        &format!(
            "{} × {} px, {} bands ({} used), {} frame(s)",
            s("/input/cols"),
            s("/input/rows"),
            s("/input/bands"),
            s("/input/bands_used"),
            s("/input/frames")
        ),
        None,
    );
    row(
        h,
        "input units",
        &escape_html(&unicode_units(&s("/input/units"))),
        None,
    );
    row(
        h,
        "scene/detector sampling",
        &format!(
            "{} × {}",
            num(facts.f("/sampling/ratio_x"), 6),
            num(facts.f("/sampling/ratio_y"), 6)
        ),
        Some("sampling_ratio"),
    );
    row(h, "method", &escape_html(&s("/sampling/method")), None);
    row(
        h,
        "detector",
        &format!(
            "{} × {} px, {} bit",
            s("/detector/cols"),
            s("/detector/rows"),
            s("/detector/bits")
        ),
        None,
    );
    h.push_str("</table></section>\n");
}

/// Detector and noise: gain, auto-gain reference, full well, dark, read noise, signal,
/// temporal noise, SNR, saturation.
fn section_detector(h: &mut String, facts: &Facts) {
    let f = |p: &str| facts.f(p);
    h.push_str("<section><h2>Detector and noise</h2><table>\n");
    row(
        h,
        "conversion gain K",
        &format!("{} DN/e⁻", num(f("/detector/gain_dn_per_e"), 4)),
        Some("gain_dn_per_e"),
    );
    row(
        h,
        "auto-gain reference",
        &escape_html(&facts.s("/detector/auto_gain_reference")),
        None,
    );
    row(
        h,
        "full well",
        &format!("{} e⁻", num(f("/detector/full_well_e"), 4)),
        None,
    );
    row(
        h,
        "dark signal",
        &format!("{} e⁻", num(f("/detector/dark_e"), 4)),
        None,
    );
    row(
        h,
        "read noise",
        &format!("{} e⁻", num(f("/detector/read_noise_e"), 4)),
        None,
    );
    row(
        h,
        "mean signal",
        &format!(
            "{} e⁻ ({} DN)",
            num(f("/signal/mean_electrons"), 5),
            num(f("/signal/mean_dn"), 5)
        ),
        Some("mean_electrons"),
    );
    row(
        h,
        "temporal noise",
        &format!("{} e⁻", num(f("/signal/temporal_noise_e"), 4)),
        Some("temporal_noise_e"),
    );
    row(h, "SNR", &num(f("/signal/snr"), 4), None);
    row(
        h,
        "saturated pixels",
        &format!("{} %", num(f("/signal/saturated_percent"), 3)),
        None,
    );
    h.push_str("</table></section>\n");
}

/// Calibration (thermal sensors): NUC, blackbody levels, NETD, bad pixels, residual
/// non-uniformity, pixels without temperature.
fn section_calibration(h: &mut String, facts: &Facts) {
    if facts.r.pointer("/calibration").is_none_or(|c| c.is_null()) {
        return;
    }
    let f = |p: &str| facts.f(p);
    let netd_mk = f("/calibration/netd_analytic_k_at_300k").map(|k| k * 1e3);
    let netd_meas_mk = f("/calibration/netd_measured_k_at_300k").map(|k| k * 1e3);
    h.push_str("<section><h2>Calibration</h2><table>\n");
    row(
        h,
        "NUC degree",
        &escape_html(&facts.s("/calibration/nuc_degree")),
        None,
    );
    row(
        h,
        "blackbody levels",
        &format!("{} K", facts.list("/calibration/temperatures_k", 4)),
        None,
    );
    row(
        h,
        "NETD at 300 K (analytic)",
        &format!("{} mK", num(netd_mk, 4)),
        None,
    );
    row(
        h,
        "NETD at 300 K (measured)",
        &format!("{} mK", num(netd_meas_mk, 4)),
        Some("netd_measured_mk"),
    );
    row(
        h,
        "bad pixels",
        &escape_html(&facts.s("/calibration/bad_pixels")),
        None,
    );
    let nu = |k: &str| f(&format!("/calibration/residual_nonuniformity/{k}")).map(|v| v * 100.0);
    row(
        h,
        "non-uniformity σ/μ (flat field)",
        &format!(
            "raw {} %, after NUC {} %, temporal floor {} %",
            num(nu("raw"), 3),
            num(nu("corrected"), 3),
            num(nu("temporal_floor"), 3)
        ),
        None,
    );
    row(
        h,
        "pixels without temperature",
        &escape_html(&facts.s("/calibration/uninvertible_pixels")),
        None,
    );
    h.push_str("</table></section>\n");
}

/// A caller's section: its table and notes, then its pictures.
fn section_extra(h: &mut String, s: &ExtraSection) {
    let _ = writeln!(
        h,
        "<section id=\"{}\"><h2>{}</h2><table>",
        s.id,
        escape_html(&s.title)
    );
    for (label, value) in &s.rows {
        row(h, label, &escape_html(value), None);
    }
    h.push_str("</table>\n");
    for n in &s.notes {
        let _ = writeln!(h, "<p>{}</p>", escape_html(n));
    }
    h.push_str("</section>\n");
    figures(h, s.pictures.iter());
}

/// The pictures, each a `<figure>` with its caption; a small `dn.png` enlarged by a whole
/// factor with square pixels.
fn section_pictures(h: &mut String, pictures: &RunPictures) {
    figures(h, pictures.all().into_iter());
}

/// Each picture as a `<figure>` with its caption (`dn.png` enlarged, see
/// [`section_pictures`]).
fn figures<'a>(h: &mut String, pictures: impl Iterator<Item = &'a Picture>) {
    for p in pictures {
        let (w, ht) = png_size(&p.png).unwrap_or((0, 0));
        let (scale, class) = if p.file_name == "dn.png" {
            (dn_display_scale(w), " class=\"pixels\"")
        } else {
            (1, "")
        };
        let size = if w > 0 && ht > 0 {
            format!(" width=\"{}\" height=\"{}\"", w * scale, ht * scale)
        } else {
            String::new()
        };
        let _ = writeln!(
            h,
            "<figure id=\"fig-{}\"><img{class}{size} alt=\"{}\" src=\"data:image/png;base64,{}\"><figcaption><b>{}</b>{}: {}</figcaption></figure>",
            p.file_name.trim_end_matches(".png"),
            p.file_name,
            base64(&p.png),
            p.file_name,
            if scale > 1 { format!(" (shown {scale}× enlarged)") } else { String::new() },
            escape_html(&p.caption)
        );
    }
}

/// Run time and the list of raw products.
fn section_footer(h: &mut String, facts: &Facts) {
    let _ = writeln!(
        h,
        "<footer>run time {} s · products: dn.tiff (raw DN), electrons_mean.tiff/.exr, config.toml, report.json</footer>\n</body>\n</html>",
        num(facts.f("/timings_s/total"), 3)
    );
}

/// Writes the pictures and `report.html` into `dir`. Returns the paths written.
pub fn write(out: &RunSummary, dir: &Path) -> Result<Vec<PathBuf>> {
    let pictures = RunPictures::render(out)?;
    let mut written = pictures.write(dir)?;
    for p in out.extra_sections.iter().flat_map(|s| &s.pictures) {
        let path = dir.join(p.file_name);
        display::write_png_bytes(&path, &p.png)?;
        written.push(path);
    }
    let page = render_page(out, &pictures)?;
    let p = dir.join("report.html");
    crate::io::atomic_write(&p, |w| crate::io::write_all(w, page.as_bytes(), &p))?;
    written.push(p);
    Ok(written)
}

const STYLE: &str = "body{font-family:-apple-system,'Segoe UI',Roboto,'DejaVu Sans',sans-serif;margin:0 auto;max-width:1150px;padding:16px 24px;color:#1d2330;background:#f6f7f9}\
header{border-bottom:3px solid #3b4a6b;margin-bottom:12px}h1{margin:8px 0 2px;font-size:28px}\
header p{margin:4px 0;color:#444}.meta{font-size:13px;color:#667}\
h2{font-size:17px;margin:0 0 8px;color:#3b4a6b}\
section{background:#fff;border-radius:8px;padding:12px 16px;margin:10px 0;box-shadow:0 1px 3px rgba(0,0,0,.12)}\
.warn{border-left:6px solid #d98c00;background:#fff8e6}.ok{border-left:6px solid #3a9a4a}\
.warn li{margin:4px 0}\
.cards{display:flex;gap:12px;background:none;box-shadow:none;padding:0}\
.card{flex:1;background:#fff;border-radius:8px;padding:10px 14px;box-shadow:0 1px 3px rgba(0,0,0,.12)}\
.card .label{font-size:13px;color:#667}.card .value{font-size:26px;font-weight:600}\
.grid{display:grid;grid-template-columns:1fr 1fr;gap:0 16px}\
table{border-collapse:collapse;width:100%;font-size:14px}th{text-align:left;font-weight:normal;color:#556;padding:3px 8px 3px 0;width:45%}\
td{padding:3px 0;font-variant-numeric:tabular-nums}tr+tr{border-top:1px solid #eef}\
figure{background:#fff;border-radius:8px;padding:12px;margin:12px 0;box-shadow:0 1px 3px rgba(0,0,0,.12)}\
figure img{max-width:100%;height:auto;display:block;margin:0 auto}img.pixels{image-rendering:pixelated}\
figcaption{font-size:13px;color:#445;margin-top:6px}footer{font-size:12px;color:#778;margin:16px 0}";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn html_is_escaped() {
        assert_eq!(
            escape_html("<a href=\"x\">&'"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&#39;"
        );
    }

    #[test]
    fn png_size_reads_the_header_and_small_pictures_are_enlarged_by_whole_factors() {
        let png = display::encode_png(64, 48, 1, &[0u8; 64 * 48]).unwrap();
        assert_eq!(png_size(&png), Some((64, 48)));
        assert_eq!(png_size(b"GIF89a not a png at all"), None);
        assert_eq!(dn_display_scale(64), 12);
        assert_eq!(dn_display_scale(384), 2);
        assert_eq!(dn_display_scale(640), 1);
        assert_eq!(dn_display_scale(1392), 1);
        assert_eq!(dn_display_scale(0), DN_DISPLAY_WIDTH_PX);
    }

    #[test]
    fn units_are_written_with_superscripts() {
        assert_eq!(unicode_units("W m-2 sr-1 um-1"), "W m⁻² sr⁻¹ µm⁻¹");
        assert_eq!(unicode_units("W m-2 sr-1"), "W m⁻² sr⁻¹");
        assert_eq!(unicode_units("per band"), "per band");
    }

    #[test]
    fn numbers_keep_significant_digits() {
        assert_eq!(num(Some(16.76), 3), "16.8");
        assert_eq!(num(Some(1634.8), 4), "1635");
        assert_eq!(num(Some(0.0536), 3), "0.0536");
        assert_eq!(num(Some(2.9961e6), 5), "2.9961e6");
        assert_eq!(num(Some(257.72102733608335), 4), "257.7");
        assert_eq!(num(None, 3), "—");
        assert_eq!(num(Some(f64::NAN), 3), "—");
    }
}
