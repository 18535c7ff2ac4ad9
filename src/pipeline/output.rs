//! Products on disk: [`RunOutput::write`] and the animated preview of a sequence.

use std::path::{Path, PathBuf};

use ndarray::Array2;

use crate::error::{Error, Result};
use crate::io::raster;

use super::RunOutput;

impl RunOutput {
    /// The DN frames as 8-bit images with one common stretch (0.5–99.5 percentiles over
    /// all frames), for the animated preview of a sequence.
    pub fn preview_frames(&self) -> Vec<Array2<u8>> {
        let mut all: Vec<u16> = self
            .frames
            .iter()
            .flat_map(|f| f.dn.iter().copied())
            .collect();
        all.sort_unstable();
        let pick = |q: f64| all[((all.len() - 1) as f64 * q) as usize] as f64;
        let (lo, hi) = (pick(0.005), pick(0.995));
        let span = (hi - lo).max(1.0);
        self.frames
            .iter()
            .map(|f| {
                f.dn.mapv(|v| ((v as f64 - lo) / span * 255.0).round().clamp(0.0, 255.0) as u8)
            })
            .collect()
    }

    /// Writes the products into `dir` (created if needed), each file atomically:
    /// `dn.tiff` (u16), `dn.png` (8-bit display, [`crate::display::dn_display`]), `electrons_mean.tiff` and
    /// `electrons_mean.exr` (f32), `config.toml` (the resolved sensor), `instance.json` (seed
    /// and sensor hash, [`crate::calibration::instance`]), `report.json`, and
    /// with the `hdf5` feature `products.h5` holding every product. A sequence writes
    /// `frame_NNNN_` prefixed DN and electron files. Returns the paths written.
    pub fn write(&self, dir: &Path) -> Result<Vec<PathBuf>> {
        // Guarded: a signal's clean-up that removed the staging directory is not undone.
        crate::io::output::create_dir_all_guarded(dir)?;
        let mut written = Vec::new();
        let single = self.frames.len() == 1;
        for (i, f) in self.frames.iter().enumerate() {
            let prefix = if single {
                String::new()
            } else {
                format!("frame_{i:04}_")
            };
            let p = dir.join(format!("{prefix}dn.tiff"));
            raster::write_tiff_u16(&p, f.dn.view())?;
            written.push(p);
            let p = dir.join(format!("{prefix}dn.png"));
            let (grey, _) = crate::display::dn_display(f.dn.view());
            let samples: Vec<u8> = grey.iter().copied().collect();
            let png = crate::display::encode_png(grey.ncols(), grey.nrows(), 1, &samples)?;
            crate::display::write_png_bytes(&p, &png)?;
            written.push(p);
            let p = dir.join(format!("{prefix}electrons_mean.tiff"));
            raster::write_tiff_f32(&p, f.electrons_mean.view())?;
            written.push(p);
            let p = dir.join(format!("{prefix}electrons_mean.exr"));
            raster::write_exr_f32(&p, f.electrons_mean.view(), "electrons_mean")?;
            written.push(p);
            for (name, img) in [("radiance", &f.radiance), ("temperature", &f.temperature)] {
                if let Some(img) = img {
                    let p = dir.join(format!("{prefix}{name}.tiff"));
                    raster::write_tiff_f32(&p, img.view())?;
                    written.push(p);
                    let p = dir.join(format!("{prefix}{name}.exr"));
                    raster::write_exr_f32(&p, img.view(), name)?;
                    written.push(p);
                }
            }
            if let Some(rgb) = &f.rgb {
                let p = dir.join(format!("{prefix}rgb.png"));
                raster::write_png_rgb8(&p, rgb.view())?;
                written.push(p);
            }
        }
        #[cfg(feature = "hdf5")]
        {
            use crate::io::hdf5::{write_bundle, BundleData, BundleItem};
            let mut items = Vec::new();
            let names: Vec<(String, String)> = (0..self.frames.len())
                .map(|i| {
                    if single {
                        ("dn".to_string(), "electrons_mean".to_string())
                    } else {
                        (
                            format!("frame_{i:04}_dn"),
                            format!("frame_{i:04}_electrons_mean"),
                        )
                    }
                })
                .collect();
            let extra: Vec<(String, String)> = (0..self.frames.len())
                .map(|i| {
                    if single {
                        ("radiance".to_string(), "temperature".to_string())
                    } else {
                        (
                            format!("frame_{i:04}_radiance"),
                            format!("frame_{i:04}_temperature"),
                        )
                    }
                })
                .collect();
            for (f, (rad, temp)) in self.frames.iter().zip(&extra) {
                if let Some(r) = &f.radiance {
                    items.push(BundleItem {
                        name: rad,
                        data: BundleData::F32(r.view()),
                        attrs: vec![(
                            "units",
                            "W m-2 sr-1 (in-band, normalised to peak response)".to_string(),
                        )],
                    });
                }
                if let Some(t) = &f.temperature {
                    items.push(BundleItem {
                        name: temp,
                        data: BundleData::F32(t.view()),
                        attrs: vec![("units", "K (apparent, blackbody-equivalent)".to_string())],
                    });
                }
            }
            for (f, (dn, el)) in self.frames.iter().zip(&names) {
                items.push(BundleItem {
                    name: dn,
                    data: BundleData::U16(f.dn.view()),
                    attrs: vec![("units", "DN".to_string())],
                });
                items.push(BundleItem {
                    name: el,
                    data: BundleData::F32(f.electrons_mean.view()),
                    attrs: vec![("units", "electrons (mean, noise-free)".to_string())],
                });
            }
            let p = dir.join("products.h5");
            // The report without what varies from one run to the next on the same input
            // and seed (timings; threads and frames in flight): the bundle, like every
            // other product, is the same bytes for the same run (report.json has them).
            let mut report =
                serde_json::to_value(&self.report).map_err(|e| Error::format(&p, e.to_string()))?;
            if let Some(fields) = report.as_object_mut() {
                fields.remove("timings_s");
                fields.remove("execution");
            }
            let report = report.to_string();
            write_bundle(
                &p,
                &items,
                &[
                    ("sensor", self.sensor.to_toml_string()?),
                    ("report", report),
                ],
            )?;
            written.push(p);
        }
        if self.frames.len() > 1 {
            let p = dir.join("preview.png");
            crate::io::raster::write_apng_gray8(&p, &self.preview_frames(), 100)?;
            written.push(p);
            let p = dir.join("dn_stack.npy");
            let views: Vec<_> = self.frames.iter().map(|f| f.dn.view()).collect();
            crate::io::npy::write_u16_stack(&p, &views)?;
            written.push(p);
        }
        if let Some(truth) = &self.line_of_sight {
            let p = dir.join("los.csv");
            let text = super::motion::truth_csv(truth);
            crate::io::atomic_write(&p, |w| crate::io::write_all(w, text.as_bytes(), &p))?;
            written.push(p);
        }
        if let Some(truth) = &self.focal_plane {
            written.extend(truth.write(dir)?);
        }
        let p = dir.join("config.toml");
        let text = self.sensor.to_toml_string()?;
        crate::io::atomic_write(&p, |w| crate::io::write_all(w, text.as_bytes(), &p))?;
        written.push(p);
        let instance =
            crate::calibration::instance::SensorInstance::of(&self.sensor, self.report.seed)?;
        written.push(instance.write(dir)?);
        let p = dir.join("report.json");
        let text = serde_json::to_string_pretty(&self.report)
            .map_err(|e| Error::format(&p, e.to_string()))?;
        crate::io::atomic_write(&p, |w| crate::io::write_all(w, text.as_bytes(), &p))?;
        written.push(p);
        written.extend(super::report_html::write(self, dir)?);
        Ok(written)
    }
}
