//! The defects an analysis command replaces before it measures (`edge-mtf`): the
//! recording sensor instance's own defect map when `instance.json` beside the image names
//! the same sensor, else the clusters of dead, hot and stuck pixels found in the image
//! ([`find_image_defects`]; docs/way-back.md).

use std::path::Path;

use anyhow::{Context, Result};
use ndarray::Array2;

use eoir::calibration::instance::{sensor_hash, SensorInstance};
use eoir::detector::DetectorInstance;
use eoir::processing::bad_pixels::{self, find_image_defects, BadPixelMap};
use eoir::processing::wiener::IMPULSE_K_SIGMA;
use eoir::sensor::Sensor;

/// The defects of an image to replace before analysis, and where they came from.
pub struct FoundDefects {
    /// Pixels to replace.
    pub defects: BadPixelMap,
    /// Saturated (clipped) pixels, kept but masked.
    pub saturated: BadPixelMap,
    /// `instance` (the recording sensor instance's own defect map, rebuilt from the seed
    /// in `instance.json`) or `image` (found in the image by
    /// [`find_image_defects`]).
    pub source: &'static str,
    /// Number of defect clusters.
    pub clusters: usize,
    /// Pixels in the largest cluster.
    pub largest_cluster: usize,
}

/// The defect map of the sensor instance that recorded `image` — when `instance.json`
/// beside it names `sensor` (the same resolved-sensor hash) — rebuilt from its seed
/// ([`DetectorInstance::new`] draws the same defects), as a bad-pixel mask; `None` when
/// there is no sidecar or it names another sensor (a note says so).
///
/// Errors: an unreadable sidecar, or a detector that cannot be rebuilt.
pub fn instance_defects(image: &Path, sensor: &Sensor) -> Result<Option<BadPixelMap>> {
    let Some(inst) = SensorInstance::beside(image)? else {
        return Ok(None);
    };
    if inst.sensor_hash != sensor_hash(sensor)? {
        eprintln!(
            "note: {} was recorded by another sensor instance than `{}` ({}): finding defects in the image instead",
            image.display(),
            sensor.name,
            inst.sensor
        );
        return Ok(None);
    }
    let det = DetectorInstance::new(sensor.detector(), inst.seed)?;
    Ok(Some(BadPixelMap::from_mask(
        det.defect_map().mapv(|c| c != 0),
    )))
}

/// The defects of `image`: the recording instance's own map ([`instance_defects`]) with
/// the non-finite pixels added, else those [`find_image_defects`] finds (`full_scale`:
/// the ADC's full scale of a DN image). Saturated regions always come from the image.
pub fn image_defects(
    path: &Path,
    image: &Array2<f64>,
    sensor: &Sensor,
    full_scale: Option<f64>,
) -> Result<FoundDefects> {
    let found = find_image_defects(image.view(), IMPULSE_K_SIGMA, full_scale)
        .context("finding defective pixels")?;
    match instance_defects(path, sensor)? {
        Some(map) if map.dim() == image.dim() => {
            let map = map.union(&BadPixelMap::from_mask(image.mapv(|v| !v.is_finite())))?;
            let saturated = BadPixelMap::from_mask(
                ndarray::Zip::from(found.saturated.mask())
                    .and(map.mask())
                    .map_collect(|&s, &d| s && !d),
            );
            let sizes = bad_pixels::cluster_sizes(&map);
            Ok(FoundDefects {
                clusters: sizes.len(),
                largest_cluster: sizes.iter().copied().max().unwrap_or(0),
                defects: map,
                saturated,
                source: "instance",
            })
        }
        _ => Ok(FoundDefects {
            defects: found.defects,
            saturated: found.saturated,
            source: "image",
            clusters: found.clusters,
            largest_cluster: found.largest_cluster,
        }),
    }
}
