//! Relative illumination: the irradiance at each detector pixel centre relative to the
//! axis, for a uniform extended source (docs/field-optics.md).
//!
//! - **cos⁴θ** (`optics.cos4`; W. J. Smith, *Modern Optical Engineering*, 4th ed., 2008,
//!   §9.7; docs/design.md §4.1): θ is the angle of the pixel centre from the axis seen from
//!   the rear principal point, `tan θ = r / f` with `r` the centre's distance from the
//!   array centre in the focal plane and `f` the focal length. With the pixel pitch p and
//!   the IFOV p/f, `tan²θ = (x·IFOV)² + (y·IFOV)²` (x, y the offsets in pixels): the
//!   geometry holds this exactly, there is no small-angle step.
//! - **A table** (`[optics.relative_illumination]`, [`RelativeIlluminationConfig`]) of
//!   factors against the normalised field height (or image height), interpolated
//!   linearly: it multiplies cos⁴θ when `cos4` is on, else it stands alone.
//! - **Distortion's area ratio** (`[optics.distortion]`): a distorted lens spreads the flux
//!   of a solid angle over `J` times the paraxial area, so a uniform source's irradiance is
//!   divided by J (the resampling of the scene applies it, [`super::distortion`]); the
//!   calibration's flat field ([`calibration_map`]) therefore includes it.
//!
//! The imaging engine and the calibration (flat field, NETD measurement) read these maps,
//! so they see the same fall-off.

use ndarray::Array2;

use crate::error::Result;
use crate::sensor::field_optics::{interpolate_held, HeightUnit, RelativeIlluminationConfig};
use crate::sensor::Sensor;

/// The distance of the array's outer corner from its centre, m: the normalised field
/// height is `H = r / r_corner`.
pub fn corner_height_m(sensor: &Sensor) -> f64 {
    let d = &sensor.detector;
    0.5 * d.pitch_m * ((d.cols as f64).powi(2) + (d.rows as f64).powi(2)).sqrt()
}

/// The relative illumination the imaging engine applies to a `rows × cols` detector image:
/// cos⁴θ (if `optics.cos4`) times the table (if any), `None` when there is neither.
pub fn map(sensor: &Sensor, rows: usize, cols: usize) -> Result<Option<Array2<f64>>> {
    let o = &sensor.optics;
    let table = o
        .relative_illumination
        .as_ref()
        .map(|t| table_of(t, sensor))
        .transpose()?;
    if !o.cos4 && table.is_none() {
        return Ok(None);
    }
    let ifov = sensor.ifov_rad();
    let pitch = sensor.detector.pitch_m;
    let corner = corner_height_m(sensor);
    Ok(Some(Array2::from_shape_fn((rows, cols), |(r, c)| {
        let y = (r as f64 - (rows as f64 - 1.0) / 2.0) * ifov;
        let x = (c as f64 - (cols as f64 - 1.0) / 2.0) * ifov;
        let mut v = 1.0;
        if o.cos4 {
            let cos2 = 1.0 / (1.0 + x * x + y * y);
            v *= cos2 * cos2;
        }
        if let Some((heights, factors)) = &table {
            // The image height r = f·tanθ = √(x² + y²)/IFOV · p.
            let r_m = (x * x + y * y).sqrt() / ifov * pitch;
            v *= interpolate_held(heights, factors, r_m / corner);
        }
        v
    })))
}

/// [`map`] times the distortion's irradiance factor 1/J at each pixel centre (J the area
/// ratio at the paraxial height the centre images): the flat field a uniform source gives,
/// which the calibration divides out. `None` when the optics add no fall-off.
pub fn calibration_map(sensor: &Sensor, rows: usize, cols: usize) -> Result<Option<Array2<f64>>> {
    let ri = map(sensor, rows, cols)?;
    let Some(d) = sensor
        .optics
        .distortion
        .as_ref()
        .filter(|d| !d.is_identity())
    else {
        return Ok(ri);
    };
    let mut m = ri.unwrap_or_else(|| Array2::ones((rows, cols)));
    let pitch = sensor.detector.pitch_m;
    let corner = corner_height_m(sensor);
    let d = d.law(corner)?;
    for ((r, c), v) in m.indexed_iter_mut() {
        let y = (r as f64 - (rows as f64 - 1.0) / 2.0) * pitch;
        let x = (c as f64 - (cols as f64 - 1.0) / 2.0) * pitch;
        let h_real = (x * x + y * y).sqrt() / corner;
        // Pixel centres lie within H = 1, inside the range the law was checked on.
        let h = d.paraxial(h_real).unwrap_or(h_real);
        *v /= d.jacobian(h);
    }
    Ok(Some(m))
}

/// The table's normalised heights and factors.
fn table_of(t: &RelativeIlluminationConfig, sensor: &Sensor) -> Result<(Vec<f64>, Vec<f64>)> {
    let (heights, unit) = t.heights()?;
    let scale = match unit {
        HeightUnit::Normalised => 1.0,
        HeightUnit::ImageM => 1.0 / corner_height_m(sensor),
    };
    Ok((
        heights.iter().map(|h| h * scale).collect(),
        t.factors.clone(),
    ))
}
