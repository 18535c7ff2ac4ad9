//! The figures of merit in a run's products (`eoir run --assess`, Python
//! `eoir.run(..., assess=True)`): the sensor's analytic figures ([`assess::analytic`]) in
//! `report.json` (`figures_of_merit`, the same object as `eoir assess`'s `analytic`) and
//! as a section of `report.html` with the TTP probability, MRTD and NIIRS curves beside the
//! run's own pictures. The measured figures need simulations of their own: `eoir assess`.

use super::assess::{self, Analytic, AssessOptions};
use super::plots;
use crate::error::{Error, Result};
use crate::pipeline::report_html::{ExtraSection, Picture};
use crate::pipeline::RunOutput;
use crate::plot::significant;
use crate::report::RunReport;
use crate::sensor::Sensor;

/// What [`attach_to`] adds to: the parts of a run's output (a [`RunOutput`] or a
/// streamed run, `crate::pipeline::StreamedRun`) that its report is written from.
pub struct RunParts<'a> {
    /// The run's sensor.
    pub sensor: &'a Sensor,
    /// The run's report (`report.json`).
    pub report: &'a mut RunReport,
    /// The run's warnings.
    pub warnings: &'a mut Vec<String>,
    /// The sections added to `report.html`.
    pub extra_sections: &'a mut Vec<ExtraSection>,
}

/// [`attach_to`] for a collected run.
pub fn attach(out: &mut RunOutput, opts: &AssessOptions) -> Result<()> {
    attach_to(
        RunParts {
            sensor: &out.sensor,
            report: &mut out.report,
            warnings: &mut out.warnings,
            extra_sections: &mut out.extra_sections,
        },
        opts,
    )
}

/// Evaluates the analytic figures of the run's sensor with `opts` and adds them to its
/// report and page. A sensor without figures (e.g. its reference level saturates) is not
/// an error of the run: the reason becomes a warning of the run and the page's section
/// says so.
pub fn attach_to(run: RunParts<'_>, opts: &AssessOptions) -> Result<()> {
    let opts = AssessOptions {
        analytic_only: true,
        ..opts.clone()
    };
    opts.validate()?;
    match assess::analytic(run.sensor, &opts) {
        Ok(an) => {
            run.report.figures_of_merit =
                Some(serde_json::to_value(&an).map_err(|e| {
                    Error::param("figures of merit", e.to_string(), "serialisable")
                })?);
            run.extra_sections.push(section(&an)?);
        }
        Err(e) => {
            let w = format!("figures of merit not evaluated: {e}");
            run.report.warnings.push(w.clone());
            run.warnings.push(w.clone());
            run.extra_sections.push(ExtraSection {
                id: "figures-of-merit",
                title: "Figures of merit (analytic)".into(),
                rows: vec![],
                notes: vec![w],
                pictures: vec![],
            });
        }
    }
    Ok(())
}

/// `value` in km with 4 significant digits, or a dash when outside the range grid.
fn km(v: Option<f64>) -> String {
    v.map_or_else(
        || "— (outside the range grid)".to_string(),
        |m| format!("{} km", significant(m * 1e-3, 4)),
    )
}

/// The page's section for `an`: the figures as a table, then the curves.
pub fn section(an: &Analytic) -> Result<ExtraSection> {
    let mut rows = Vec::new();
    if let Some(n) = an.netd_k {
        rows.push(("NETD (analytic)".into(), format!("{} K", significant(n, 3))));
    }
    if let Some(m) = an.mtf50_cy_per_px {
        rows.push((
            "MTF50 along x".into(),
            format!("{} cycles/px", significant(m, 3)),
        ));
    }
    rows.push(("MTF at Nyquist".into(), significant(an.mtf_nyquist, 3)));
    rows.push(("RER (GIQE 5)".into(), significant(an.rer, 3)));
    let target = &an.target;
    for t in &an.tasks {
        rows.push((
            format!("{}: range at P = 0.5 / 0.8", t.task),
            format!("{} / {}", km(t.range_p50_m), km(t.range_p80_m)),
        ));
    }
    if let (Some(n), Some(r)) = (&an.niirs, an.ranges_m.first()) {
        rows.push((
            format!("NIIRS at {} km", significant(r * 1e-3, 3)),
            significant(n[0], 3),
        ));
    }
    let notes = vec![format!(
        "TTP (Vollmerhausen & Jacobs 2004) for a {} m target of inherent contrast {}, extinction {} km⁻¹, at {} frame/s; other targets and the measured figures: eoir assess (docs/figures-of-merit.md). Values in report.json, figures_of_merit.",
        significant(target.size_m, 3),
        significant(target.contrast, 3),
        significant(target.extinction_per_m * 1e3, 3),
        significant(an.frame_rate_hz, 3)
    )];
    let mut pictures = vec![Picture {
        file_name: "probability.png",
        png: plots::probability_png(an)?,
        caption: "TTP probability of detection, recognition and identification against range"
            .into(),
    }];
    if let Some(png) = plots::mrtd_png(an)? {
        pictures.push(Picture {
            file_name: "mrtd.png",
            png,
            caption:
                "minimum resolvable temperature difference (FLIR92 form) against bar frequency"
                    .into(),
        });
    }
    if let Some(png) = plots::niirs_png(an)? {
        pictures.push(Picture {
            file_name: "niirs.png",
            png,
            caption: "GIQE 5 NIIRS against range".into(),
        });
    }
    Ok(ExtraSection {
        id: "figures-of-merit",
        title: "Figures of merit (analytic)".into(),
        rows,
        notes,
        pictures,
    })
}
