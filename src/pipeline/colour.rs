//! Stage 3, demosaic (colour-filter-array sensors): raw mosaic DN → a display colour image.
//! Black level subtracted, Malvar–He–Cutler demosaicking ([`crate::cfa::demosaic_malvar`]),
//! white balance for a 5772 K sun ([`Sensor::white_balance`]), one display scale (zero
//! stays black, the 99.5th percentile of all channels → 255).

use ndarray::{Array2, Array3, Axis};

use crate::detector::DetectorModel;
use crate::sensor::Sensor;

/// The colour image `[row, col, 3]` of one raw frame, or `None` for a sensor without a
/// colour filter array. The black level is the offset plus the mean dark and background
/// signal, `offset_dn + K·(dark + background)`.
pub fn colour_image(
    sensor: &Sensor,
    model: &DetectorModel,
    dn: &Array2<u16>,
) -> Option<Array3<u8>> {
    let cfa = sensor.cfa.as_ref()?;
    let black =
        sensor.detector.offset_dn + model.gain_dn_per_e() * (model.dark_e() + model.background_e());
    let raw = dn.mapv(|v| v as f64 - black);
    let mut planes = crate::cfa::demosaic_malvar(raw.view(), cfa.pattern);
    if let Some(gains) = sensor.white_balance() {
        for (c, g) in gains.iter().enumerate() {
            planes.index_axis_mut(Axis(0), c).mapv_inplace(|v| v * g);
        }
    }
    Some(display_rgb(&planes))
}

/// A `[3, rows, cols]` linear colour image as display bytes `[rows, cols, 3]`: zero stays
/// black and the 99.5th percentile of all channels maps to 255 (one scale for all three, so
/// channel ratios — grey — are kept).
pub fn display_rgb(planes: &Array3<f64>) -> Array3<u8> {
    let mut all: Vec<f64> = planes.iter().copied().filter(|v| v.is_finite()).collect();
    all.sort_by(f64::total_cmp);
    let white = all
        .get(((all.len().max(1) - 1) as f64 * 0.995) as usize)
        .copied()
        .filter(|w| *w > 0.0)
        .unwrap_or(1.0);
    let (_, rows, cols) = planes.dim();
    Array3::from_shape_fn((rows, cols, 3), |(r, c, k)| {
        (planes[[k, r, c]] / white * 255.0)
            .round()
            .clamp(0.0, 255.0) as u8
    })
}
