//! Stage 1, image: the input cube → mean photo-electrons on the detector grid, through
//! [`crate::imaging::Imager`]. A colour-filter-array sensor is imaged once per filter
//! colour (each through its own spectral response) and the three mean images are
//! mosaicked before the detector ([`crate::cfa::mosaic`]): the CFA stage.

use ndarray::Array2;

use crate::error::Result;
use crate::imaging::{Imager, ImagingStats, Sampling};
use crate::io::CubeReader;
use crate::scene::{CubeMeta, Geometry};
use crate::sensor::Sensor;

/// The imaging stage of a run: one [`Imager`] per colour channel (one for a sensor
/// without a colour filter array), reusable across the frames of a sequence.
#[derive(Debug)]
pub struct ImagingStage {
    imagers: Vec<Imager>,
    pattern: Option<crate::cfa::CfaPattern>,
    stats: ImagingStats,
}

impl ImagingStage {
    /// Prepares the imagers of `sensor` for an input of `meta` with field of view
    /// `geometry` (padding from `options.wrap_tolerance`, see
    /// [`crate::imaging::pad_width`]; transforms in `options.fft_precision`).
    pub fn new(
        sensor: &Sensor,
        meta: &CubeMeta,
        geometry: &Geometry,
        options: &super::RunOptions,
    ) -> Result<Self> {
        let channels: Vec<&Sensor> = match sensor.cfa_channels() {
            [] => vec![sensor],
            cs => cs.iter().collect(),
        };
        let imagers = channels
            .into_iter()
            .map(|s| {
                Imager::new(s, meta, geometry, options.wrap_tolerance)
                    .map(|i| i.with_precision(options.fft_precision))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(ImagingStage {
            imagers,
            pattern: sensor.cfa.as_ref().map(|c| c.pattern),
            stats: ImagingStats::default(),
        })
    }

    /// Bands with a non-zero weight, summed over the colour channels (the progress total
    /// of one frame).
    pub fn bands_used(&self) -> usize {
        self.imagers
            .iter()
            .map(|i| i.weights().active_bands().len())
            .sum()
    }

    /// The input bands no colour channel uses (zero spectral weight), as one warning:
    /// the engine never reads them, so they are not checked for NaN, ±Inf or negative
    /// radiance (README, "Input"). `None` when every band is read.
    pub fn unread_bands_warning(&self, meta: &CubeMeta) -> Option<String> {
        let mut used = vec![false; meta.bands()];
        for im in &self.imagers {
            for b in im.weights().active_bands() {
                used[b] = true;
            }
        }
        let unread: Vec<usize> = (0..used.len()).filter(|&b| !used[b]).collect();
        if unread.is_empty() {
            return None;
        }
        // Runs of consecutive bands, as `a–b (λa–λb µm)`.
        let mut runs: Vec<String> = Vec::new();
        let mut i = 0;
        while i < unread.len() {
            let mut j = i;
            while j + 1 < unread.len() && unread[j + 1] == unread[j] + 1 {
                j += 1;
            }
            let (a, b) = (unread[i], unread[j]);
            let (la, lb) = (meta.wavelength_um[a], meta.wavelength_um[b]);
            runs.push(if a == b {
                format!("{a} ({la} µm)")
            } else {
                format!("{a}–{b} ({la}–{lb} µm)")
            });
            i = j + 1;
        }
        Some(format!(
            "{} of {} input bands have zero sensor response and were not read (so not checked for NaN, ±Inf or negative radiance): band {}",
            unread.len(),
            meta.bands(),
            runs.join(", ")
        ))
    }

    /// Scene → detector sampling (the same for every channel).
    pub fn sampling(&self) -> &Sampling {
        self.imagers[0].sampling()
    }

    /// Timings and padded shape accumulated over the frames imaged so far.
    pub fn stats(&self) -> &ImagingStats {
        &self.stats
    }

    /// Mean signal electrons of frame `frame` (mosaicked for a CFA sensor).
    /// `progress(bands done in this frame)` is called after each band.
    pub fn mean_electrons(
        &mut self,
        reader: &mut dyn CubeReader,
        frame: usize,
        mut progress: impl FnMut(usize),
    ) -> Result<Array2<f64>> {
        let mut planes = Vec::with_capacity(self.imagers.len());
        let mut done = 0;
        for im in &self.imagers {
            let (e, s) = im.mean_electrons(reader, frame, |b, _| progress(done + b))?;
            done += s.bands_used;
            self.stats.read_s += s.read_s;
            self.stats.fft_s += s.fft_s;
            self.stats.otf_s += s.otf_s;
            self.stats.inverse_s += s.inverse_s;
            self.stats.bands_used += s.bands_used;
            self.stats.padded_shape = s.padded_shape;
            self.stats.precision = s.precision;
            planes.push(e);
        }
        match self.pattern {
            Some(p) => crate::cfa::mosaic([&planes[0], &planes[1], &planes[2]], p),
            None => Ok(planes.swap_remove(0)),
        }
    }
}
