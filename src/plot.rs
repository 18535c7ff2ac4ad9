//! PNG line plots with an embedded font.
//!
//! Plots are drawn with `plotters` on its bitmap backend. Text uses the DejaVu Sans font
//! committed in `assets/fonts/` (Bitstream Vera licence, see `LICENSE-DejaVu.txt`) through
//! plotters' `ab_glyph` renderer, so no system font libraries (fontconfig, freetype) are
//! needed on the user's machine.

use std::path::Path;
use std::sync::Once;

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::FontStyle;

use crate::error::{Error, Result};

static FONT_BYTES: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");
static REGISTER_FONT: Once = Once::new();
/// Name under which the embedded font is registered with plotters.
pub(crate) const FONT: &str = "eoir-sans";

/// Registers the embedded font with plotters (once per process).
pub(crate) fn ensure_font() {
    REGISTER_FONT.call_once(|| {
        // The font is compiled in and known to parse; a failure would only mean text
        // is not drawn, never wrong numbers, so it is not an error.
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, FONT_BYTES);
    });
}

/// One curve of a line plot.
#[derive(Debug, Clone)]
pub struct Series<'a> {
    /// Legend label.
    pub label: &'a str,
    /// Abscissae.
    pub x: &'a [f64],
    /// Ordinates (same length as `x`).
    pub y: &'a [f64],
}

/// A labelled vertical marker line (e.g. the detector Nyquist frequency).
#[derive(Debug, Clone)]
pub struct Marker<'a> {
    /// Label drawn next to the line.
    pub label: &'a str,
    /// Abscissa of the line.
    pub x: f64,
}

/// Description of a line plot.
#[derive(Debug, Clone)]
pub struct LinePlot<'a> {
    /// Title above the plot.
    pub title: &'a str,
    /// Label of the x axis.
    pub x_label: &'a str,
    /// Label of the y axis.
    pub y_label: &'a str,
    /// Curves.
    pub series: Vec<Series<'a>>,
    /// Vertical markers.
    pub markers: Vec<Marker<'a>>,
    /// y range; `None` fits the data.
    pub y_range: Option<(f64, f64)>,
    /// Image size in pixels (width, height).
    pub size_px: (u32, u32),
}

/// Options of a line plot beyond [`LinePlot`]'s (a separate type so that every existing
/// `LinePlot { … }` stays valid).
#[derive(Debug, Clone, Default)]
pub struct PlotOptions {
    /// Indices of series drawn as dots (measured points) instead of lines.
    pub dot_series: Vec<usize>,
    /// Indices of series drawn in grey dots (points outside a fit or past saturation).
    pub muted_series: Vec<usize>,
    /// Logarithmic x axis (values ≤ 0 are left out; tick labels in data units).
    pub log_x: bool,
    /// Logarithmic y axis (values ≤ 0 are left out; tick labels in data units).
    pub log_y: bool,
    /// x range; `None` fits the data.
    pub x_range: Option<(f64, f64)>,
}

const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Supersampling factor: plots are drawn at `SUPERSAMPLE`× the size in each direction and
/// averaged down over `SUPERSAMPLE`² pixel boxes, so lines, dots and bar edges are
/// anti-aliased (plotters' bitmap backend fills wide lines as hard-edged polygons).
pub const SUPERSAMPLE: u32 = 3;

/// Draws `plot` into a PNG file at `path`, written atomically.
pub fn write_line_plot(path: &Path, plot: &LinePlot<'_>) -> Result<()> {
    let bytes = render_line_plot(plot)?;
    crate::io::raster::write_png_bytes(path, &bytes)
}

/// Draws `plot` with `options` into a PNG file at `path`, written atomically.
pub fn write_line_plot_with(path: &Path, plot: &LinePlot<'_>, options: &PlotOptions) -> Result<()> {
    let bytes = render_line_plot_with(plot, options)?;
    crate::io::raster::write_png_bytes(path, &bytes)
}

/// Draws `plot` and returns the PNG bytes (for a file or an inline image).
pub fn render_line_plot(plot: &LinePlot<'_>) -> Result<Vec<u8>> {
    render_line_plot_with(plot, &PlotOptions::default())
}

/// `v` rounded to `digits` significant figures, for people: plain notation for
/// 1e-3 ≤ |v| < 1e6 (`257.7`, `0.0536`), scientific outside (`3.668e6`); zeros after the
/// decimal point are kept to the requested precision (`300.0`). `—` when not finite.
pub fn significant(v: f64, digits: usize) -> String {
    let digits = digits.max(1);
    if !v.is_finite() {
        return "—".to_string();
    }
    if v == 0.0 {
        return "0".to_string();
    }
    let a = v.abs();
    if !(1e-3..1e6).contains(&a) {
        return format!("{:.*e}", digits - 1, v);
    }
    // Round first, so 999.96 with 4 digits becomes 1000 (4 integer digits, 0 decimals).
    let exponent = a.log10().floor() as i32;
    let scale = 10f64.powi(digits as i32 - 1 - exponent);
    let rounded = (v * scale).round() / scale;
    let exponent = rounded.abs().log10().floor() as i32;
    let decimals = (digits as i32 - 1 - exponent).max(0) as usize;
    format!("{rounded:.decimals$}")
}

/// The text of a tick at `v`: three significant figures without trailing zeros (`0.8`,
/// `-0.2`, `1`, `2.5e4`).
fn tick(v: f64) -> String {
    let t = significant(v, 3);
    match t.split_once('e') {
        Some((m, e)) if m.contains('.') => {
            format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.'))
        }
        None if t.contains('.') => t.trim_end_matches('0').trim_end_matches('.').to_string(),
        _ => t,
    }
}

/// The text of a tick on a log axis at log10 value `v`.
fn log_tick(v: f64) -> String {
    tick(significant(10f64.powf(v), 2).parse().unwrap_or(f64::NAN))
}

/// Height (final px) of the band between the title and the plotting area that holds the
/// labels of `markers` vertical markers (two rows when labels may need to stagger).
fn marker_band(markers: usize) -> u32 {
    match markers {
        0 => 0,
        1 => 8,
        _ => 24,
    }
}

/// A plot area's pixel buffer at [`SUPERSAMPLE`]× size and its final size.
struct Canvas {
    w: u32,
    h: u32,
    buf: Vec<u8>,
}

impl Canvas {
    fn new((w, h): (u32, u32)) -> Self {
        let s = SUPERSAMPLE as usize;
        Canvas {
            w,
            h,
            buf: vec![255u8; w as usize * h as usize * 3 * s * s],
        }
    }

    /// Averages the supersampled buffer down to the final size and encodes it as PNG.
    fn into_png(self) -> Result<Vec<u8>> {
        let s = SUPERSAMPLE as usize;
        let (w, h) = (self.w as usize, self.h as usize);
        let big_w = w * s;
        let mut out = vec![0u8; w * h * 3];
        for y in 0..h {
            for x in 0..w {
                for c in 0..3 {
                    let mut sum = 0u32;
                    for dy in 0..s {
                        let row = (y * s + dy) * big_w;
                        for dx in 0..s {
                            sum += self.buf[(row + x * s + dx) * 3 + c] as u32;
                        }
                    }
                    let n = (s * s) as u32;
                    out[(y * w + x) * 3 + c] = ((sum + n / 2) / n) as u8;
                }
            }
        }
        crate::io::raster::encode_png(w, h, 3, &out)
    }
}

/// Font size `px` (of the final picture) at the supersampled scale.
fn font_px(px: u32) -> f64 {
    (px * SUPERSAMPLE) as f64
}

/// Scaled length.
fn sc(px: u32) -> u32 {
    px * SUPERSAMPLE
}

/// One legend entry: label, colour, stroke width (final px), dot instead of line.
struct LegendItem {
    label: String,
    color: RGBColor,
    width: u32,
    dot: bool,
}

/// Rows of the legend strip below the chart for `items` in a `width_px`-wide picture
/// (final pixels); items are laid out left to right and wrap.
fn legend_rows(
    root: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    items: &[LegendItem],
    width_px: u32,
) -> Vec<Vec<(usize, u32)>> {
    let font: TextStyle = (FONT, font_px(14)).into();
    let mut rows: Vec<Vec<(usize, u32)>> = vec![Vec::new()];
    let mut x = sc(70);
    for (i, it) in items.iter().enumerate() {
        let text_w = root
            .estimate_text_size(&it.label, &font)
            .map(|(w, _)| w)
            .unwrap_or(sc(8) * it.label.chars().count() as u32);
        let item_w = sc(34) + text_w + sc(22);
        if x + item_w > sc(width_px) && !rows.last().is_some_and(Vec::is_empty) {
            rows.push(Vec::new());
            x = sc(70);
        }
        if let Some(r) = rows.last_mut() {
            r.push((i, x));
        }
        x += item_w;
    }
    rows
}

/// Height of one legend row, final px.
const LEGEND_ROW_PX: u32 = 22;

/// Draws the legend rows into `area` (the strip below the chart).
fn draw_legend(
    area: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    items: &[LegendItem],
    rows: &[Vec<(usize, u32)>],
) -> std::result::Result<(), String> {
    let font = (FONT, font_px(14))
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(HPos::Left, VPos::Center));
    for (r, row) in rows.iter().enumerate() {
        let y = (sc(LEGEND_ROW_PX) * r as u32 + sc(LEGEND_ROW_PX) / 2) as i32;
        for &(i, x) in row {
            let it = &items[i];
            let x = x as i32;
            if it.dot {
                area.draw(&Circle::new(
                    (x + sc(12) as i32, y),
                    sc(4),
                    it.color.filled(),
                ))
                .map_err(|e| e.to_string())?;
            } else {
                area.draw(&PathElement::new(
                    vec![(x, y), (x + sc(26) as i32, y)],
                    ShapeStyle::from(&it.color).stroke_width(sc(it.width)),
                ))
                .map_err(|e| e.to_string())?;
            }
            area.draw(&Text::new(
                it.label.clone(),
                (x + sc(34) as i32, y),
                font.clone(),
            ))
            .map_err(|e| e.to_string())?;
        }
    }
    Ok(())
}

/// Draws the labels of vertical markers in the band above the plotting area (never over
/// the data): `tops` are the markers' (x, top-of-plot y) backend coordinates. Labels that
/// would touch their left neighbour go one row higher.
fn draw_marker_labels(
    root: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    labels: &[(String, (i32, i32))],
    color: RGBColor,
) -> std::result::Result<(), String> {
    let font = (FONT, font_px(13)).into_font();
    let measure: TextStyle = (FONT, font_px(13)).into();
    let mut order: Vec<usize> = (0..labels.len()).collect();
    order.sort_by_key(|&i| labels[i].1 .0);
    let mut right_edge = [i32::MIN; 2];
    for i in order {
        let (text, (x, top)) = &labels[i];
        let w = root
            .estimate_text_size(text, &measure)
            .map(|(w, _)| w as i32)
            .unwrap_or(sc(60) as i32);
        // Centred on its line, but kept inside the picture.
        let (width, _) = root.dim_in_pixel();
        let half = w / 2 + sc(4) as i32;
        let x = &(*x).clamp(half, (width as i32 - half).max(half));
        let left = x - w / 2;
        let row = if left > right_edge[0] + sc(6) as i32 {
            0
        } else {
            1
        };
        right_edge[row] = x + w / 2;
        let y = top - sc(3) as i32 - row as i32 * sc(16) as i32;
        root.draw(&Text::new(
            text.clone(),
            (*x, y),
            font.clone()
                .color(&color)
                .pos(Pos::new(HPos::Center, VPos::Bottom)),
        ))
        .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// Draws `plot` with `options` and returns the PNG bytes: anti-aliased (drawn at
/// [`SUPERSAMPLE`]×), the legend in a strip below the chart and the marker labels above
/// it, so neither covers a curve.
pub fn render_line_plot_with(plot: &LinePlot<'_>, options: &PlotOptions) -> Result<Vec<u8>> {
    ensure_font();
    let tx = |v: f64| if options.log_x { v.log10() } else { v };
    let ty = |v: f64| if options.log_y { v.log10() } else { v };
    let keep = |x: f64, y: f64| {
        x.is_finite() && y.is_finite() && (!options.log_x || x > 0.0) && (!options.log_y || y > 0.0)
    };
    let pts: Vec<Vec<(f64, f64)>> = plot
        .series
        .iter()
        .map(|s| {
            s.x.iter()
                .zip(s.y)
                .filter(|(x, y)| keep(**x, **y))
                .map(|(x, y)| (tx(*x), ty(*y)))
                .collect()
        })
        .collect();
    let empty = || Error::param("plot series", "empty", "at least one finite point");
    let (x_lo, x_hi) = match options.x_range {
        Some((a, b)) => (tx(a), tx(b)),
        None => range_of(pts.iter().flatten().map(|p| p.0)).ok_or_else(empty)?,
    };
    let (y_lo, y_hi) = match plot.y_range {
        Some((a, b)) => (ty(a), ty(b)),
        None => {
            let (a, b) = range_of(pts.iter().flatten().map(|p| p.1)).ok_or_else(empty)?;
            // A little room above and below the data, so no curve runs along the frame.
            let m = 0.04 * (b - a);
            (a - m, b + m)
        }
    };
    let pad_y = if y_hi > y_lo { 0.0 } else { 0.5 };
    let pad_x = if x_hi > x_lo { 0.0 } else { 0.5 };
    let draw_err = |e: String| Error::param("plot", format!("cannot draw: {e}"), "a drawable plot");
    let items: Vec<LegendItem> = plot
        .series
        .iter()
        .enumerate()
        .filter(|(_, s)| !s.label.is_empty())
        .map(|(i, s)| {
            let (color, width) = series_style(i, s.label, options);
            LegendItem {
                label: s.label.to_string(),
                color,
                width,
                dot: options.dot_series.contains(&i) || options.muted_series.contains(&i),
            }
        })
        .collect();
    let (w, h) = plot.size_px;
    let mut canvas = Canvas::new((w, h));
    {
        let root = BitMapBackend::with_buffer(&mut canvas.buf, (sc(w), sc(h))).into_drawing_area();
        root.fill(&WHITE).map_err(|e| draw_err(e.to_string()))?;
        let rows = if items.len() > 1 {
            legend_rows(&root, &items, w)
        } else {
            Vec::new()
        };
        let legend_h = if rows.is_empty() {
            0
        } else {
            sc(LEGEND_ROW_PX) * rows.len() as u32 + sc(6)
        };
        let (upper, lower) = root.split_vertically(sc(h) - legend_h);
        let band = marker_band(plot.markers.len());
        let titled = upper
            .margin(sc(6), 0, 0, 0)
            .titled(plot.title, (FONT, font_px(20)))
            .map_err(|e| draw_err(e.to_string()))?;
        let (_, plot_area) = titled.split_vertically(sc(band));
        let mut builder = ChartBuilder::on(&plot_area);
        builder
            .margin(sc(12))
            .x_label_area_size(sc(48))
            .y_label_area_size(sc(72));
        let mut chart = builder
            .build_cartesian_2d(
                (x_lo - pad_x)..(x_hi + pad_x),
                (y_lo - pad_y)..(y_hi + pad_y),
            )
            .map_err(|e| draw_err(e.to_string()))?;
        let x_fmt = |v: &f64| log_tick(*v);
        let y_fmt = |v: &f64| log_tick(*v);
        let plain = |v: &f64| tick(*v);
        let mut mesh = chart.configure_mesh();
        mesh.x_desc(plot.x_label)
            .y_desc(plot.y_label)
            .label_style((FONT, font_px(14)))
            .axis_desc_style((FONT, font_px(16)))
            .axis_style(ShapeStyle::from(&RGBColor(60, 60, 60)).stroke_width(sc(1)))
            .bold_line_style(ShapeStyle::from(&RGBColor(225, 225, 225)).stroke_width(sc(1)))
            .light_line_style(ShapeStyle::from(&RGBColor(243, 243, 243)).stroke_width(sc(1)))
            .set_all_tick_mark_size(sc(4))
            .x_labels(8)
            .y_labels(8);
        if options.log_x {
            mesh.x_label_formatter(&x_fmt);
        } else {
            mesh.x_label_formatter(&plain);
        }
        if options.log_y {
            mesh.y_label_formatter(&y_fmt);
        } else {
            mesh.y_label_formatter(&plain);
        }
        mesh.draw().map_err(|e| draw_err(e.to_string()))?;
        let marker_style = ShapeStyle::from(&RGBColor(110, 110, 110)).stroke_width(sc(1));
        let mut labels = Vec::new();
        for m in &plot.markers {
            let mx = tx(m.x);
            chart
                .draw_series(LineSeries::new(
                    vec![(mx, y_lo - pad_y), (mx, y_hi + pad_y)],
                    marker_style,
                ))
                .map_err(|e| draw_err(e.to_string()))?;
            labels.push((
                m.label.to_string(),
                chart.backend_coord(&(mx, y_hi + pad_y)),
            ));
        }
        // Muted points first, then the others in order, so fits lie above measurements.
        for (i, s) in plot.series.iter().enumerate() {
            let (color, width) = series_style(i, s.label, options);
            let dot = options.dot_series.contains(&i) || options.muted_series.contains(&i);
            if dot {
                chart
                    .draw_series(
                        pts[i]
                            .iter()
                            .map(|p| Circle::new(*p, sc(3), color.filled())),
                    )
                    .map_err(|e| draw_err(e.to_string()))?;
            } else {
                chart
                    .draw_series(LineSeries::new(
                        pts[i].iter().copied(),
                        ShapeStyle::from(&color).stroke_width(sc(width)),
                    ))
                    .map_err(|e| draw_err(e.to_string()))?;
            }
        }
        draw_marker_labels(&root, &labels, RGBColor(60, 60, 60)).map_err(draw_err)?;
        if !rows.is_empty() {
            draw_legend(&lower, &items, &rows).map_err(draw_err)?;
        }
        root.present().map_err(|e| draw_err(e.to_string()))?;
    }
    canvas.into_png()
}

/// Colour and stroke width (final px) of series `i`: `system` (the product of a cascade)
/// thick black, muted series grey, the others from the palette.
fn series_style(i: usize, label: &str, options: &PlotOptions) -> (RGBColor, u32) {
    if options.muted_series.contains(&i) {
        (RGBColor(170, 170, 170), 2)
    } else if label == "system" || label == "product" {
        (RGBColor(0, 0, 0), 3)
    } else {
        (PALETTE[i % PALETTE.len()], 2)
    }
}

/// A histogram: counts per bin over contiguous bins.
#[derive(Debug, Clone)]
pub struct HistogramPlot<'a> {
    /// Title above the plot.
    pub title: &'a str,
    /// Label of the x axis (the binned quantity and its unit).
    pub x_label: &'a str,
    /// Bin edges, ascending (`counts.len() + 1` values).
    pub edges: &'a [f64],
    /// Pixels per bin.
    pub counts: &'a [u64],
    /// Vertical markers (e.g. the display stretch limits, full scale).
    pub markers: Vec<Marker<'a>>,
    /// Image size in pixels (width, height).
    pub size_px: (u32, u32),
}

/// Counts of `values` in `bins` equal bins over `[lo, hi]` (the top edge included in the
/// last bin; values outside or non-finite are not counted). Returns `(edges, counts)`.
pub fn histogram(
    values: impl Iterator<Item = f64>,
    lo: f64,
    hi: f64,
    bins: usize,
) -> (Vec<f64>, Vec<u64>) {
    let bins = bins.max(1);
    let hi = if hi > lo { hi } else { lo + 1.0 };
    let width = (hi - lo) / bins as f64;
    let edges = (0..=bins).map(|i| lo + width * i as f64).collect();
    let mut counts = vec![0u64; bins];
    for v in values.filter(|v| v.is_finite() && *v >= lo && *v <= hi) {
        let i = (((v - lo) / width) as usize).min(bins - 1);
        counts[i] += 1;
    }
    (edges, counts)
}

/// Draws a histogram as filled bars and returns the PNG bytes. The x axis spans the bins
/// and every marker (with a margin of 2 % of the span when a marker lies on or beyond the
/// last edge), so a marker is always drawn inside the frame; its label sits above the
/// frame.
pub fn render_histogram(plot: &HistogramPlot<'_>) -> Result<Vec<u8>> {
    ensure_font();
    if plot.edges.len() != plot.counts.len() + 1 || plot.counts.is_empty() {
        return Err(Error::param(
            "histogram",
            format!(
                "{} edges for {} counts",
                plot.edges.len(),
                plot.counts.len()
            ),
            "one more edge than counts, at least one bin",
        ));
    }
    let draw_err =
        |e: String| Error::param("histogram", format!("cannot draw: {e}"), "a drawable plot");
    let mut x_lo = plot.edges[0];
    let mut x_hi = plot.edges[plot.edges.len() - 1];
    let span = (x_hi - x_lo).max(f64::MIN_POSITIVE);
    for m in plot.markers.iter().filter(|m| m.x.is_finite()) {
        if m.x >= x_hi {
            x_hi = m.x + 0.02 * span;
        }
        if m.x <= x_lo {
            x_lo = m.x - 0.02 * span;
        }
    }
    let y_hi = plot.counts.iter().copied().max().unwrap_or(1).max(1) as f64 * 1.05;
    let (w, h) = plot.size_px;
    let mut canvas = Canvas::new((w, h));
    {
        let root = BitMapBackend::with_buffer(&mut canvas.buf, (sc(w), sc(h))).into_drawing_area();
        root.fill(&WHITE).map_err(|e| draw_err(e.to_string()))?;
        let band = marker_band(plot.markers.len());
        let titled = root
            .margin(sc(6), 0, 0, 0)
            .titled(plot.title, (FONT, font_px(20)))
            .map_err(|e| draw_err(e.to_string()))?;
        let (_, plot_area) = titled.split_vertically(sc(band));
        let mut builder = ChartBuilder::on(&plot_area);
        builder
            .margin(sc(12))
            .x_label_area_size(sc(48))
            .y_label_area_size(sc(72));
        let mut chart = builder
            .build_cartesian_2d(x_lo..x_hi, 0.0..y_hi)
            .map_err(|e| draw_err(e.to_string()))?;
        let plain = |v: &f64| tick(*v);
        let count = |v: &f64| format!("{v:.0}");
        chart
            .configure_mesh()
            .x_desc(plot.x_label)
            .y_desc("pixels")
            .x_label_formatter(&plain)
            .y_label_formatter(&count)
            .axis_style(ShapeStyle::from(&RGBColor(60, 60, 60)).stroke_width(sc(1)))
            .bold_line_style(ShapeStyle::from(&RGBColor(230, 230, 230)).stroke_width(sc(1)))
            .light_line_style(ShapeStyle::from(&RGBColor(245, 245, 245)).stroke_width(sc(1)))
            .set_all_tick_mark_size(sc(4))
            .label_style((FONT, font_px(14)))
            .axis_desc_style((FONT, font_px(16)))
            .draw()
            .map_err(|e| draw_err(e.to_string()))?;
        let fill = PALETTE[0].filled();
        chart
            .draw_series(plot.counts.iter().enumerate().map(|(i, c)| {
                Rectangle::new([(plot.edges[i], 0.0), (plot.edges[i + 1], *c as f64)], fill)
            }))
            .map_err(|e| draw_err(e.to_string()))?;
        let marker_color = RGBColor(200, 40, 40);
        let mut labels = Vec::new();
        for m in &plot.markers {
            let style = ShapeStyle::from(&marker_color).stroke_width(sc(1));
            chart
                .draw_series(LineSeries::new(vec![(m.x, 0.0), (m.x, y_hi)], style))
                .map_err(|e| draw_err(e.to_string()))?;
            labels.push((m.label.to_string(), chart.backend_coord(&(m.x, y_hi))));
        }
        draw_marker_labels(&root, &labels, RGBColor(160, 30, 30)).map_err(draw_err)?;
        root.present().map_err(|e| draw_err(e.to_string()))?;
    }
    canvas.into_png()
}

/// The finite minimum and maximum of an iterator, if any finite value exists.
fn range_of(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values
        .filter(|v| v.is_finite())
        .fold(None, |acc, v| match acc {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// (width, height, channels, samples) of an 8-bit PNG.
    fn decode_rgb8(png: &[u8]) -> (usize, usize, usize, Vec<u8>) {
        let mut reader = png::Decoder::new(std::io::Cursor::new(png))
            .read_info()
            .unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        buf.truncate(info.buffer_size());
        let ch = info.color_type.samples();
        (info.width as usize, info.height as usize, ch, buf)
    }

    #[test]
    fn significant_rounds_to_the_requested_figures() {
        assert_eq!(significant(257.72102733608335, 4), "257.7");
        assert_eq!(significant(300.0117154093459, 4), "300.0");
        assert_eq!(significant(3.667584e6, 4), "3.668e6");
        assert_eq!(significant(999.96, 4), "1000");
        assert_eq!(significant(0.05361, 3), "0.0536");
        assert_eq!(significant(-784.93, 3), "-785");
        assert_eq!(significant(0.0, 3), "0");
        assert_eq!(significant(f64::NAN, 3), "—");
        assert_eq!(significant(2.5e-5, 2), "2.5e-5");
    }

    /// Pixels of a 1-px-wide diagonal line on a white ground: an aliased line has only the
    /// ground and the line colour; an anti-aliased one has many levels in between.
    #[test]
    fn lines_are_anti_aliased() {
        let x = [0.0, 1.0];
        let y = [0.0, 0.7];
        let plot = LinePlot {
            title: "",
            x_label: "",
            y_label: "",
            series: vec![Series {
                label: "",
                x: &x,
                y: &y,
            }],
            markers: vec![],
            y_range: Some((0.0, 1.0)),
            size_px: (300, 200),
        };
        let png = render_line_plot(&plot).unwrap();
        let (w, h, ch, px) = decode_rgb8(&png);
        assert_eq!((w, h, ch), (300, 200, 3));
        // Blue-ish pixels (the series colour, partly covered): R < G < B, not grey.
        let mut levels = std::collections::BTreeSet::new();
        for p in px.chunks(3) {
            if p[2] > p[0] + 10 {
                levels.insert(p[0] / 8);
            }
        }
        assert!(levels.len() >= 8, "{} blue levels: aliased", levels.len());
    }

    #[test]
    fn histogram_marker_at_the_last_edge_is_inside_the_frame() {
        let edges: Vec<f64> = (0..=10).map(|i| i as f64 * 100.0).collect();
        let counts = vec![5u64; 10];
        let png = render_histogram(&HistogramPlot {
            title: "",
            x_label: "DN",
            edges: &edges,
            counts: &counts,
            markers: vec![Marker {
                label: "full scale",
                x: 1000.0,
            }],
            size_px: (400, 300),
        })
        .unwrap();
        let (w, _, ch, px) = decode_rgb8(&png);
        // The red marker line: some column right of the last bar but left of the image's
        // right edge holds strongly red pixels.
        let red_cols: std::collections::BTreeSet<usize> = px
            .chunks(ch)
            .enumerate()
            .filter(|(_, p)| p[0] > 150 && p[1] < 120 && p[2] < 120)
            .map(|(i, _)| i % w)
            .collect();
        assert!(
            red_cols.iter().any(|c| *c < w - 14),
            "marker not drawn inside the plot: columns {red_cols:?}"
        );
    }

    #[test]
    fn writes_a_png_with_text_and_no_temp_files() {
        let dir = std::env::temp_dir().join(format!("eoir-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("p.png");
        let x: Vec<f64> = (0..50).map(|i| i as f64 / 49.0).collect();
        let y: Vec<f64> = x.iter().map(|v| 1.0 - v).collect();
        let plot = LinePlot {
            title: "test",
            x_label: "x",
            y_label: "y",
            series: vec![Series {
                label: "line",
                x: &x,
                y: &y,
            }],
            markers: vec![Marker {
                label: "Nyquist",
                x: 0.5,
            }],
            y_range: Some((0.0, 1.05)),
            size_px: (400, 300),
        };
        write_line_plot(&path, &plot).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        let leftovers: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().contains("eoir-tmp"))
            .collect();
        assert!(leftovers.is_empty());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
