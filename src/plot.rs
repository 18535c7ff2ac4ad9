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

/// Draws `plot` into a PNG file at `path`, written atomically.
pub fn write_line_plot(path: &Path, plot: &LinePlot<'_>) -> Result<()> {
    let bytes = render_line_plot(plot)?;
    crate::io::raster::write_png_bytes(path, &bytes)
}

/// Draws `plot` and returns the PNG bytes (for a file or an inline image).
pub fn render_line_plot(plot: &LinePlot<'_>) -> Result<Vec<u8>> {
    ensure_font();
    let (x_lo, x_hi) = range_of(plot.series.iter().flat_map(|s| s.x.iter().copied()))
        .ok_or_else(|| Error::param("plot series", "empty", "at least one finite point"))?;
    let (y_lo, y_hi) = match plot.y_range {
        Some(r) => r,
        None => range_of(plot.series.iter().flat_map(|s| s.y.iter().copied()))
            .ok_or_else(|| Error::param("plot series", "empty", "at least one finite point"))?,
    };
    let pad = if y_hi > y_lo { 0.0 } else { 0.5 };
    let draw_err = |e: String| Error::param("plot", format!("cannot draw: {e}"), "a drawable plot");
    let (w, h) = plot.size_px;
    let mut buf = vec![255u8; w as usize * h as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| draw_err(e.to_string()))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(plot.title, (FONT, 22))
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(x_lo..x_hi, (y_lo - pad)..(y_hi + pad))
            .map_err(|e| draw_err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc(plot.x_label)
            .y_desc(plot.y_label)
            .label_style((FONT, 14))
            .axis_desc_style((FONT, 16))
            .draw()
            .map_err(|e| draw_err(e.to_string()))?;
        for (i, s) in plot.series.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            let style = if s.label == "system" {
                ShapeStyle::from(&BLACK).stroke_width(3)
            } else {
                ShapeStyle::from(&color).stroke_width(2)
            };
            let legend_style = style;
            chart
                .draw_series(LineSeries::new(
                    s.x.iter().zip(s.y).map(|(x, y)| (*x, *y)),
                    style,
                ))
                .map_err(|e| draw_err(e.to_string()))?
                .label(s.label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], legend_style));
        }
        for m in &plot.markers {
            let style = ShapeStyle::from(&RGBColor(90, 90, 90)).stroke_width(1);
            chart
                .draw_series(LineSeries::new(
                    vec![(m.x, y_lo - pad), (m.x, y_hi + pad)],
                    style,
                ))
                .map_err(|e| draw_err(e.to_string()))?;
            chart
                .draw_series(std::iter::once(Text::new(
                    m.label.to_string(),
                    (m.x, y_hi + pad - 0.04 * (y_hi - y_lo + 2.0 * pad)),
                    (FONT, 14).into_font().color(&RGBColor(60, 60, 60)),
                )))
                .map_err(|e| draw_err(e.to_string()))?;
        }
        if plot.series.len() > 1 || plot.series.iter().any(|s| !s.label.is_empty()) {
            chart
                .configure_series_labels()
                .label_font((FONT, 14))
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .position(SeriesLabelPosition::UpperRight)
                .draw()
                .map_err(|e| draw_err(e.to_string()))?;
        }
        root.present().map_err(|e| draw_err(e.to_string()))?;
    }
    crate::io::raster::encode_png(w as usize, h as usize, 3, &buf)
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

/// Draws a histogram as filled bars and returns the PNG bytes.
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
    let x_lo = plot.edges[0];
    let x_hi = plot.edges[plot.edges.len() - 1];
    let y_hi = plot.counts.iter().copied().max().unwrap_or(1).max(1) as f64 * 1.08;
    let (w, h) = plot.size_px;
    let mut buf = vec![255u8; w as usize * h as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| draw_err(e.to_string()))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(plot.title, (FONT, 22))
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(x_lo..x_hi, 0.0..y_hi)
            .map_err(|e| draw_err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc(plot.x_label)
            .y_desc("pixels")
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| format!("{v:.0}"))
            .light_line_style(RGBColor(245, 245, 245))
            .label_style((FONT, 14))
            .axis_desc_style((FONT, 16))
            .draw()
            .map_err(|e| draw_err(e.to_string()))?;
        let fill = PALETTE[0].filled();
        chart
            .draw_series(plot.counts.iter().enumerate().map(|(i, c)| {
                Rectangle::new([(plot.edges[i], 0.0), (plot.edges[i + 1], *c as f64)], fill)
            }))
            .map_err(|e| draw_err(e.to_string()))?;
        for m in &plot.markers {
            let style = ShapeStyle::from(&RGBColor(200, 40, 40)).stroke_width(1);
            chart
                .draw_series(LineSeries::new(vec![(m.x, 0.0), (m.x, y_hi)], style))
                .map_err(|e| draw_err(e.to_string()))?;
            // A label near the right edge goes left of its line, so it is not cut off.
            let h_pos = if m.x > x_lo + 0.8 * (x_hi - x_lo) {
                HPos::Right
            } else {
                HPos::Left
            };
            chart
                .draw_series(std::iter::once(Text::new(
                    format!(" {} ", m.label),
                    (m.x, y_hi * 0.97),
                    (FONT, 14)
                        .into_font()
                        .color(&RGBColor(160, 30, 30))
                        .pos(Pos::new(h_pos, VPos::Top)),
                )))
                .map_err(|e| draw_err(e.to_string()))?;
        }
        root.present().map_err(|e| draw_err(e.to_string()))?;
    }
    crate::io::raster::encode_png(w as usize, h as usize, 3, &buf)
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
