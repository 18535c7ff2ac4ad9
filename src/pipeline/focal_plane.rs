//! The focal plane's memory in a run's products (docs/focal-plane.md): the truth an
//! algorithm under test is scored against — `rts.csv` (which pixels are RTS and their
//! state in every frame), `trapped_e.npy` (charge held by persistence traps after each
//! frame), `drift_gain.npy` and `drift_offset_e.npy` (the drift applied) — and the
//! report's `focal_plane` section with the residual non-uniformity against time since the
//! NUC (`nuc_drift.png`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use ndarray::Array2;

use crate::detector::memory::FrameTruth;
use crate::error::Result;
use crate::report::{DriftPoint, FocalPlaneReport, RunReport};

use super::expose::Exposure;

/// The focal plane's truth over the frames of a run.
#[derive(Debug, Clone)]
pub struct FocalPlaneTruth {
    /// Sequence index of the first frame.
    pub first_frame: u64,
    /// Detector columns (to turn flat pixel indices into row, column).
    pub cols: usize,
    /// Flat indices (row · cols + col) of the RTS pixels, ascending.
    pub rts_pixels: Vec<usize>,
    /// One entry per frame of the run.
    pub frames: Vec<FrameTruth>,
}

impl FocalPlaneTruth {
    /// The truth the exposure stage kept, `None` without a focal-plane memory.
    pub(super) fn take(exposure: &mut Exposure, first_frame: u64) -> Option<Self> {
        let cols = exposure.model().cols();
        exposure
            .take_truth()
            .map(|(frames, rts_pixels)| FocalPlaneTruth {
                first_frame,
                cols,
                rts_pixels,
                frames,
            })
    }

    /// `rts.csv`: one line per RTS pixel per frame — `frame,start_s,row,col,high_fraction,
    /// high_at_readout` (the fraction of the pixel's integration window spent in the high
    /// state, and its state when read: 1 high, 0 low).
    pub fn rts_csv(&self) -> Option<String> {
        if self.frames.iter().all(|f| f.rts.is_none()) {
            return None;
        }
        let mut s = String::from("frame,start_s,row,col,high_fraction,high_at_readout\n");
        for (k, f) in self.frames.iter().enumerate() {
            let Some(r) = &f.rts else { continue };
            for (i, &p) in self.rts_pixels.iter().enumerate() {
                let _ = writeln!(
                    s,
                    "{},{},{},{},{},{}",
                    self.first_frame + k as u64,
                    f.start_s,
                    p / self.cols,
                    p % self.cols,
                    r.high_fraction[i],
                    u8::from(r.high_at_readout[i])
                );
            }
        }
        Some(s)
    }

    /// Writes the truth files into `dir`; returns their paths.
    pub fn write(&self, dir: &Path) -> Result<Vec<PathBuf>> {
        let mut written = Vec::new();
        if let Some(text) = self.rts_csv() {
            let p = dir.join("rts.csv");
            crate::io::atomic_write(&p, |w| crate::io::write_all(w, text.as_bytes(), &p))?;
            written.push(p);
        }
        let trapped: Vec<_> = self
            .frames
            .iter()
            .filter_map(|f| f.trapped_e.as_ref())
            .collect();
        if !trapped.is_empty() {
            let p = dir.join("trapped_e.npy");
            let views: Vec<_> = trapped.iter().map(|a| a.view()).collect();
            crate::io::npy::write_f32_stack(&p, &views)?;
            written.push(p);
        }
        let drift: Vec<_> = self
            .frames
            .iter()
            .filter_map(|f| f.drift.as_ref())
            .collect();
        if !drift.is_empty() {
            for (name, pick) in [("drift_gain.npy", 0usize), ("drift_offset_e.npy", 1usize)] {
                let p = dir.join(name);
                let views: Vec<_> = drift
                    .iter()
                    .map(|(g, o)| if pick == 0 { g.view() } else { o.view() })
                    .collect();
                crate::io::npy::write_f32_stack(&p, &views)?;
                written.push(p);
            }
        }
        Ok(written)
    }
}

/// The report's `focal_plane` section: the effects on, the RTS pixel count and, with
/// drift, the residual non-uniformity against time since the NUC (made at the sequence
/// start, t = 0) at the first frame's mean signal — expected
/// ([`crate::detector::drift::residual_nonuniformity_e`]) and measured on the drift
/// applied (the spatial σ of `g_drift·S + o_drift/g` over the pixels, which is what a
/// two-point NUC made at t = 0 leaves) — and the NETD with that spatial noise added in
/// quadrature to the temporal noise at that signal.
pub(super) fn report(
    exposure: &Exposure,
    truth: Option<&FocalPlaneTruth>,
    report: &RunReport,
) -> Option<FocalPlaneReport> {
    let model = exposure.model();
    let d = &report;
    let mut effects = Vec::new();
    if model.readout_noise().is_some() {
        effects.push("readout_noise".to_string());
    }
    if model.ipc_kernel().is_some() {
        effects.push("ipc".to_string());
    }
    let (rts, persistence, drift) = model.memory_effects();
    for (on, name) in [
        (rts.is_some(), "rts"),
        (persistence.is_some(), "persistence"),
        (drift.is_some(), "drift"),
    ] {
        if on {
            effects.push(name.to_string());
        }
    }
    if effects.is_empty() {
        return None;
    }
    let signal_e = d.signal.mean_electrons;
    let temporal_e = model.temporal_noise_e(signal_e);
    let netd_k = d
        .calibration
        .as_ref()
        .and_then(|c| c.netd_analytic_k_at_300k);
    let drift_points = match (drift, truth) {
        (Some(cfg), Some(t)) => {
            let gain = exposure.instance().gain_map();
            Some(
                t.frames
                    .iter()
                    .filter_map(|f| f.drift.as_ref().map(|dr| (f.start_s, dr)))
                    .map(|(t_s, (gf, od))| {
                        let measured = residual_of(&gain, gf, od, signal_e);
                        let expected = crate::detector::drift::residual_nonuniformity_e(
                            cfg, 0.0, signal_e, t_s,
                        );
                        DriftPoint {
                            time_since_nuc_s: t_s,
                            residual_nonuniformity_e_expected: expected,
                            residual_nonuniformity_e_measured: measured,
                            netd_with_spatial_noise_mk: netd_k.map(|n| {
                                n * 1e3
                                    * (1.0 + (measured / temporal_e.max(f64::MIN_POSITIVE)).powi(2))
                                        .sqrt()
                            }),
                        }
                    })
                    .collect(),
            )
        }
        _ => None,
    };
    Some(FocalPlaneReport {
        effects,
        rts_pixels: truth.map(|t| t.rts_pixels.len()).filter(|_| rts.is_some()),
        signal_e,
        temporal_noise_e: temporal_e,
        drift: drift_points,
    })
}

/// Spatial σ (e⁻) over the pixels of `g_drift·S + o_drift/g`: a flat field of `signal_e`
/// at the drift's time, corrected by a two-point NUC made before any drift.
fn residual_of(gain: &Array2<f64>, gf: &Array2<f32>, od: &Array2<f32>, signal_e: f64) -> f64 {
    let n = gf.len().max(1) as f64;
    let values = ndarray::Zip::from(gain)
        .and(gf)
        .and(od)
        .map_collect(|&g, &f, &o| f as f64 * signal_e + o as f64 / g.max(f64::MIN_POSITIVE));
    let mean = values.sum() / n;
    (values.mapv(|v| (v - mean).powi(2)).sum() / n).sqrt()
}

/// `nuc_drift.png`: the residual non-uniformity against time since the NUC, expected
/// (line) and measured on the drift applied (dots).
pub fn drift_plot(r: &FocalPlaneReport) -> Option<Result<Vec<u8>>> {
    let points = r.drift.as_ref().filter(|p| p.len() > 1)?;
    let t: Vec<f64> = points.iter().map(|p| p.time_since_nuc_s).collect();
    let expected: Vec<f64> = points
        .iter()
        .map(|p| p.residual_nonuniformity_e_expected)
        .collect();
    let measured: Vec<f64> = points
        .iter()
        .map(|p| p.residual_nonuniformity_e_measured)
        .collect();
    let plot = crate::plot::LinePlot {
        title: "Residual non-uniformity after a two-point NUC at t = 0",
        x_label: "time since NUC (s)",
        y_label: "residual non-uniformity (e- rms)",
        series: vec![
            crate::plot::Series {
                label: "expected (drift model)",
                x: &t,
                y: &expected,
            },
            crate::plot::Series {
                label: "measured on the drift applied",
                x: &t,
                y: &measured,
            },
        ],
        markers: vec![],
        y_range: None,
        size_px: (720, 420),
    };
    let options = crate::plot::PlotOptions {
        dot_series: vec![1],
        ..Default::default()
    };
    Some(crate::plot::render_line_plot_with(&plot, &options))
}
