//! The zones' error measured on a run's own frame (`optics.wavefront.measure_error`,
//! docs/field-optics.md, "The zones' error measured on the run").
//!
//! `report.json`'s `point_source_error_of_peak` is derived from pupil PSFs at the shortest
//! wavelength (the zone-count criterion of [`super::space_variant`]). This module measures
//! the error instead, on the run's frame, bands and cascade: point sources of unit
//! radiance in every band at a few field positions — the middle of the field, the centre
//! of the zone cell nearest it and of a corner cell (where bilinear blending of the zones'
//! PSFs errs most), the midpoint of the top edge between two zone centres, and the corner
//! pixel — are imaged through the zones (the engine) and by exact direct space-variant
//! summation ([`super::space_variant::direct_summation`], every source sample blurred by
//! the PSF of its own position), and the largest `|zones − direct|` over the detector image
//! is reported as a fraction of the direct image's peak. By linearity a scene's error is at
//! most that per unit of its flux at those positions.
//!
//! Direct summation computes one pupil transfer function per non-zero frame sample and
//! band (the points and the mirror copies the padding adds near the scene's edges), so
//! the measurement is opt-in.

use ndarray::Array2;

use super::space_variant::direct_summation;
use super::Imager;
use crate::error::Result;
use crate::io::CubeReader;
use crate::scene::CubeMeta;

/// A cube of point sources: unit radiance at `points` in every band, 0 elsewhere.
struct PointCube {
    meta: CubeMeta,
    points: Vec<(usize, usize)>,
}

impl CubeReader for PointCube {
    fn meta(&self) -> &CubeMeta {
        &self.meta
    }

    fn read_band(&mut self, _frame: usize, _band: usize) -> Result<Array2<f32>> {
        let mut plane = Array2::<f32>::zeros((self.meta.rows, self.meta.cols));
        for &(r, c) in &self.points {
            plane[[r, c]] = 1.0;
        }
        Ok(plane)
    }
}

/// The scene samples (row, col) of the sample point sources for a `g × g` zone grid
/// (module documentation), distinct and inside the detector's field.
pub fn sample_points(imager: &Imager, zones_per_axis: usize) -> Vec<(usize, usize)> {
    let s = imager.sampling();
    let g = zones_per_axis.max(1);
    // Scene coordinate of node coordinate t (0 ..= g − 1) along an axis, clamped to the
    // first and last pixel centres, rounded to a scene sample.
    let at = |a: &super::AxisSampling, t: f64| -> usize {
        let first = a.first;
        let last = a.first + (a.detector_len as f64 - 1.0) * a.ratio;
        let centre = 0.5 * (first + last);
        let half = a.detector_len as f64 * a.ratio / 2.0;
        let x = if g == 1 {
            centre - half + 2.0 * half * t
        } else {
            centre - half + 2.0 * half * t / (g - 1) as f64
        };
        (x.clamp(first, last).round().max(0.0) as usize).min(a.scene_len - 1)
    };
    let span = if g == 1 { 1.0 } else { (g - 1) as f64 };
    let middle = span / 2.0;
    let inner_cell = if g == 1 {
        middle
    } else {
        (middle - 0.5).floor() + 0.5
    };
    let coords = [
        (middle, middle),
        (inner_cell, inner_cell),
        (0.5f64.min(span), 0.5f64.min(span)),
        (0.0, 0.5f64.min(span)),
        (0.0, 0.0),
    ];
    let mut points: Vec<(usize, usize)> = Vec::new();
    for (ty, tx) in coords {
        let p = (at(&s.y, ty), at(&s.x, tx));
        if !points.contains(&p) {
            points.push(p);
        }
    }
    points
}

/// The zones' error on `imager`'s frame (module documentation): point sources at
/// [`sample_points`] imaged through the zones and by direct summation; returns
/// `max |zones − direct| / max direct` and the points. `meta` is the run's cube metadata
/// (bands, size, units).
///
/// Errors: the imager has no `[optics.wavefront]`, or a pupil computation fails.
pub fn measure(imager: &Imager, meta: &CubeMeta) -> Result<(f64, Vec<(usize, usize)>)> {
    let g = imager
        .wavefront_report()
        .map(|r| r.zones_per_axis)
        .unwrap_or(1);
    let points = sample_points(imager, g);
    let mut cube = PointCube {
        meta: meta.clone(),
        points: points.clone(),
    };
    let (zones, _) = imager.mean_electrons(&mut cube, 0, |_, _| {})?;
    let exact = direct_summation(imager, &mut cube, 0)?;
    let peak = exact.iter().cloned().fold(0.0, f64::max);
    let worst = zones
        .iter()
        .zip(&exact)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    let error = if peak > 0.0 { worst / peak } else { 0.0 };
    Ok((error, points))
}
