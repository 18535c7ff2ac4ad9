//! Figures of merit and plots of what the sensor does.

use std::io::Write;
use std::path::Path;

use crate::error::{Error, Result};
use crate::plot::{self, LinePlot, Marker, Series};
use crate::radiometry;
use crate::sensor::{SensorConfig, SystemOtf};

/// MTF curves along the x (column) frequency axis: one per enabled component and the
/// system product, at one wavelength.
#[derive(Debug, Clone, PartialEq)]
pub struct MtfCurves {
    /// Wavelength the curves are evaluated at, µm.
    pub wavelength_um: f64,
    /// Angular frequencies, cycles/mrad.
    pub freq_cy_per_mrad: Vec<f64>,
    /// (component name, transfer-function values), in cascade order, then `system` last.
    /// Values are the signed transfer function (the sign shows contrast reversal).
    pub columns: Vec<(String, Vec<f64>)>,
    /// Detector Nyquist frequency, cycles/mrad.
    pub nyquist_cy_per_mrad: f64,
    /// Diffraction cutoff D/λ, cycles/mrad.
    pub cutoff_cy_per_mrad: f64,
    /// The system transfer function at the detector Nyquist frequency (along x).
    pub system_at_nyquist: f64,
}

impl MtfCurves {
    /// Evaluates every enabled component of `sensor` along fx at `points` frequencies from
    /// 0 to `max_cy_per_mrad` (default: the larger of the optical cutoff and twice the
    /// detector Nyquist).
    pub fn compute(
        sensor: &SensorConfig,
        wavelength_um: f64,
        max_cy_per_mrad: Option<f64>,
        points: usize,
    ) -> Result<Self> {
        if !(wavelength_um.is_finite() && wavelength_um > 0.0) {
            return Err(Error::param(
                "--wavelength-um",
                wavelength_um,
                "a wavelength > 0 µm",
            ));
        }
        if points < 2 {
            return Err(Error::param("--points", points, "at least 2"));
        }
        let otf = SystemOtf::new(sensor)?;
        let nyquist = sensor.nyquist_cy_per_rad() * 1e-3;
        let cutoff = otf.cutoff_cy_per_rad(wavelength_um) * 1e-3;
        let f_max = match max_cy_per_mrad {
            Some(f) if f.is_finite() && f > 0.0 => f,
            Some(f) => return Err(Error::param("--max-cy-per-mrad", f, "a frequency > 0")),
            None => cutoff.max(2.0 * nyquist),
        };
        let freq: Vec<f64> = (0..points)
            .map(|i| f_max * i as f64 / (points - 1) as f64)
            .collect();
        let mut columns: Vec<(String, Vec<f64>)> = otf
            .components()
            .iter()
            .map(|c| {
                let v = freq
                    .iter()
                    .map(|f| otf.component(*c, f * 1e3, 0.0, wavelength_um))
                    .collect();
                (c.name().to_string(), v)
            })
            .collect();
        let system = freq
            .iter()
            .map(|f| otf.evaluate(f * 1e3, 0.0, wavelength_um))
            .collect();
        columns.push(("system".to_string(), system));
        let system_at_nyquist = otf.evaluate(sensor.nyquist_cy_per_rad(), 0.0, wavelength_um);
        Ok(MtfCurves {
            system_at_nyquist,
            wavelength_um,
            freq_cy_per_mrad: freq,
            columns,
            nyquist_cy_per_mrad: nyquist,
            cutoff_cy_per_mrad: cutoff,
        })
    }

    /// Writes the curves as CSV: `freq_cy_per_mrad`, one column per component, `system`.
    pub fn write_csv(&self, path: &Path) -> Result<()> {
        let text = self.csv_text();
        crate::io::atomic_write(path, |w| {
            w.write_all(text.as_bytes()).map_err(|e| Error::io(path, e))
        })
    }

    /// The CSV text [`MtfCurves::write_csv`] writes (for `--csv -`, standard output).
    pub fn csv_text(&self) -> String {
        let mut text = String::from("freq_cy_per_mrad");
        for (name, _) in &self.columns {
            text.push(',');
            text.push_str(name);
        }
        text.push('\n');
        for (i, f) in self.freq_cy_per_mrad.iter().enumerate() {
            text.push_str(&format!("{f:.6}"));
            for (_, v) in &self.columns {
                text.push_str(&format!(",{:.8}", v[i]));
            }
            text.push('\n');
        }
        text
    }

    /// Plots the curves as a PNG with the detector Nyquist frequency marked.
    pub fn write_png(&self, path: &Path, sensor_name: &str) -> Result<()> {
        let title = format!(
            "{sensor_name}: transfer functions at {:.3} µm",
            self.wavelength_um
        );
        let series = self
            .columns
            .iter()
            .map(|(name, v)| Series {
                label: name,
                x: &self.freq_cy_per_mrad,
                y: v,
            })
            .collect();
        let y_min = self
            .columns
            .iter()
            .flat_map(|(_, v)| v.iter().copied())
            .fold(0.0f64, f64::min);
        plot::write_line_plot(
            path,
            &LinePlot {
                title: &title,
                x_label: "spatial frequency (cycles/mrad)",
                y_label: "transfer function",
                series,
                markers: vec![Marker {
                    label: "Nyquist",
                    x: self.nyquist_cy_per_mrad,
                }],
                y_range: Some((y_min.min(0.0) - 0.02, 1.05)),
                size_px: (900, 600),
            },
        )
    }
}

/// The response-weighted mean wavelength of a sensor, ∫λ S dλ / ∫S dλ over the support of
/// its spectral response S (µm): the default wavelength for single-wavelength reports.
pub fn mean_wavelength_um(sensor: &SensorConfig) -> Result<f64> {
    let s = sensor.spectral_response()?;
    let (lo, hi) = s.support_um();
    if !(lo.is_finite() && hi.is_finite() && hi > lo) {
        return Err(Error::param(
            "spectral response",
            format!("support [{lo}, {hi}] µm"),
            "a bounded band (give a [filter] or a QE with a cutoff), or pass --wavelength-um",
        ));
    }
    let bp = s.breakpoints_um();
    let num = radiometry::integrate(|l| l * s.eval(l), lo, hi, &bp, 1e-9);
    let den = radiometry::integrate(|l| s.eval(l), lo, hi, &bp, 1e-9);
    if den <= 0.0 {
        return Err(Error::param(
            "spectral response",
            "zero everywhere",
            "a response with some non-zero transmission and quantum efficiency",
        ));
    }
    Ok(num / den)
}
