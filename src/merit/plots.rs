//! The figures-of-merit curves as PNG pictures, shared by `eoir assess` and the run's
//! `report.html` (`eoir run --assess`): task probability against range (TTP), MRTD against
//! bar frequency, and GIQE 5 NIIRS against range.

use super::assess::Analytic;
use crate::error::Result;
use crate::plot::{self, LinePlot, Marker, PlotOptions, Series};

/// Pixel size of every figures-of-merit plot.
const SIZE_PX: (u32, u32) = (900, 600);

/// `probability.png`: the probability of each task (detection, recognition,
/// identification) against range, labelled with its V50.
pub fn probability_png(an: &Analytic) -> Result<Vec<u8>> {
    let ranges_km: Vec<f64> = an.ranges_m.iter().map(|r| r * 1e-3).collect();
    let labels: Vec<String> = an
        .tasks
        .iter()
        .map(|t| format!("{} (V50 {})", t.task, plot::significant(t.v50, 3)))
        .collect();
    let series: Vec<Series> = an
        .tasks
        .iter()
        .zip(&labels)
        .map(|(t, l)| Series {
            label: l,
            x: &ranges_km,
            y: &t.probability,
        })
        .collect();
    let title = format!(
        "TTP task probability, {} m target",
        plot::significant(an.target.size_m, 3)
    );
    plot::render_line_plot(&LinePlot {
        title: &title,
        x_label: "range (km)",
        y_label: "probability",
        series,
        markers: vec![],
        y_range: Some((0.0, 1.0)),
        size_px: SIZE_PX,
    })
}

/// `mrtd.png`: the analytic MRTD against bar frequency on a logarithmic axis (as MRTD
/// curves are drawn), the Nyquist frequency marked (thermal sensors; `None` otherwise).
/// Points above 1000× the lowest MRTD (the divergence toward the cutoff) are left out
/// rather than clipped to the frame, so no drawn segment is an artefact of the axis.
pub fn mrtd_png(an: &Analytic) -> Result<Option<Vec<u8>>> {
    let Some(mrtd) = &an.mrtd else {
        return Ok(None);
    };
    let lowest = mrtd
        .iter()
        .map(|p| p.mrtd_k)
        .filter(|m| m.is_finite() && *m > 0.0)
        .fold(f64::INFINITY, f64::min);
    if !lowest.is_finite() {
        return Ok(None);
    }
    let pts: Vec<_> = mrtd
        .iter()
        .filter(|p| p.mrtd_k.is_finite() && p.mrtd_k <= MRTD_SPAN * lowest)
        .collect();
    let f: Vec<f64> = pts.iter().map(|p| p.freq_cy_per_px).collect();
    let m: Vec<f64> = pts.iter().map(|p| p.mrtd_k).collect();
    plot::render_line_plot_with(
        &LinePlot {
            title: "MRTD (FLIR92 form)",
            x_label: "bar frequency (cycles/pixel)",
            y_label: "MRTD (K)",
            series: vec![Series {
                label: "analytic",
                x: &f,
                y: &m,
            }],
            markers: vec![Marker {
                label: "Nyquist",
                x: 0.5,
            }],
            y_range: None,
            size_px: SIZE_PX,
        },
        &PlotOptions {
            log_y: true,
            x_range: Some((0.0, 0.5)),
            ..Default::default()
        },
    )
    .map(Some)
}

/// Span of the MRTD plot: its largest value drawn over its lowest.
const MRTD_SPAN: f64 = 1000.0;

/// `niirs.png`: GIQE 5 NIIRS against range (reflective sensors; `None` otherwise).
pub fn niirs_png(an: &Analytic) -> Result<Option<Vec<u8>>> {
    let Some(n) = &an.niirs else {
        return Ok(None);
    };
    let ranges_km: Vec<f64> = an.ranges_m.iter().map(|r| r * 1e-3).collect();
    plot::render_line_plot(&LinePlot {
        title: "GIQE 5 NIIRS",
        x_label: "range (km)",
        y_label: "NIIRS",
        series: vec![Series {
            label: "analytic",
            x: &ranges_km,
            y: n,
        }],
        markers: vec![],
        y_range: None,
        size_px: SIZE_PX,
    })
    .map(Some)
}
