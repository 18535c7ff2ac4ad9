//! The measured NETD of a sensor instance (issues 4 and 9): exposed blackbody frames at T
//! and T + ΔT through the instance, on every row or on a sample of rows sized for a stated
//! precision ([`NetdSample`]), measured by [`crate::processing::netd::measured_netd`].

use ndarray::{Array2, Array3, Axis, Zip};

use super::{cos4_map, NETD_FRAME_BASE};
use crate::detector::DetectorInstance;
use crate::error::{require_positive, Error, Result};
use crate::processing::bad_pixels::BadPixelMap;
use crate::processing::netd;
use crate::sensor::Sensor;

/// The frames and detector rows of a measured NETD ([`measured_netd_sampled`]).
///
/// The NETD `σ/R` is estimated from the pooled temporal variance of F frames at T over the
/// N sampled pixels, which has (F − 1)·N degrees of freedom, so its relative standard error
/// is √(2/((F − 1)N)) and that of the NETD half of it; the responsivity R, a mean over N
/// pixels of F-frame averages, adds √(2/F)·NETD/(ΔT√N) (~3e-4 for the demo). A sample
/// reaching a relative precision p therefore needs `(F − 1)·N ≥ 1/(2p²)` pixel-frames: for
/// p = 0.5 % that is 20 000, i.e. 2 frames of 20 000 pixels — a fifth of a 384 × 288 array,
/// which is why large arrays are sampled by rows instead of exposed whole (issue 9).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NetdSample {
    /// Frames per temperature (F ≥ 2).
    pub frames: usize,
    /// Detector rows exposed, increasing.
    pub rows: Vec<usize>,
}

/// Margin on the sampled pixel count for pixels excluded as bad (the demo flags 0.5 %).
const NETD_SAMPLE_MARGIN: f64 = 1.05;

impl NetdSample {
    /// Every row of a `rows`-row detector, `frames` frames per temperature.
    pub fn all_rows(rows: usize, frames: usize) -> Self {
        NetdSample {
            frames,
            rows: (0..rows).collect(),
        }
    }

    /// The cheapest sample of a `rows × cols` detector whose NETD has a relative standard
    /// error of at most `relative_precision` (see the type documentation), with at most
    /// `max_frames` frames: 2 frames of evenly spaced rows holding 1/(2p²) pixels (plus
    /// 5 % for excluded pixels) when the array has that many, else every row and the
    /// fewest frames F with `(F − 1)·rows·cols ≥ 1/(2p²)`, capped at `max_frames`.
    ///
    /// Errors: a precision that is not finite and > 0, an empty detector, or
    /// `max_frames` < 2.
    pub fn for_precision(
        rows: usize,
        cols: usize,
        relative_precision: f64,
        max_frames: usize,
    ) -> Result<Self> {
        require_positive("relative_precision", relative_precision)?;
        if rows == 0 || cols == 0 {
            return Err(Error::param(
                "detector",
                format!("{rows} x {cols} pixels"),
                "a detector with at least one pixel",
            ));
        }
        if max_frames < 2 {
            return Err(Error::param(
                "max_frames",
                max_frames,
                "at least 2 frames per temperature",
            ));
        }
        let pixel_frames = 1.0 / (2.0 * relative_precision * relative_precision);
        let wanted_rows = (NETD_SAMPLE_MARGIN * pixel_frames / cols as f64).ceil();
        if wanted_rows < rows as f64 {
            let n = wanted_rows as usize;
            return Ok(NetdSample {
                frames: 2,
                rows: (0..n).map(|k| k * rows / n).collect(),
            });
        }
        let f = 1.0 + (pixel_frames / (rows * cols) as f64).ceil();
        Ok(NetdSample::all_rows(
            rows,
            (f.min(max_frames as f64) as usize).max(2),
        ))
    }
}

/// Measured NETD (K) of `instance` from simulated frames (docs/design.md §4.10 style
/// measurement, [`netd::measured_netd`]) over the whole array: [`measured_netd_sampled`]
/// with every row and `frames` frames per temperature.
///
/// Errors: as [`measured_netd_sampled`].
pub fn measured_netd(
    sensor: &Sensor,
    instance: &DetectorInstance,
    t_k: f64,
    delta_t_k: f64,
    frames: usize,
    exclude: Option<&BadPixelMap>,
) -> Result<f64> {
    let sample = NetdSample::all_rows(instance.model().rows(), frames);
    measured_netd_sampled(sensor, instance, t_k, delta_t_k, &sample, exclude)
}

/// Measured NETD (K) of `instance` from simulated frames (docs/design.md §4.10 style
/// measurement, [`netd::measured_netd`]) on the rows of `sample`: `sample.frames` frames of
/// a uniform blackbody at `t_k` (frame indices from [`NETD_FRAME_BASE`]) and as many at
/// `t_k + delta_t_k`; the temporal noise is the root of the pixel-averaged temporal
/// variance at `t_k` and the responsivity the mean DN difference / ΔT, over the sampled
/// pixels not in `exclude` (a map of the whole array). The sampled rows are those of the
/// full frames, bit for bit ([`DetectorInstance::expose_rows`]). Raw DN are used (NETD is
/// a property of the sensor, not of the correction). The finite difference is one-sided:
/// its relative bias is about `ΔT · S''/(2 S')`, so keep ΔT small (a fraction of a kelvin)
/// when comparing with the analytic value. `optics.cos4` is applied as in the scene.
///
/// Errors: invalid temperatures, fewer than 2 frames, no rows or a row outside the
/// detector, a map of another shape, or the errors of the measurement.
pub fn measured_netd_sampled(
    sensor: &Sensor,
    instance: &DetectorInstance,
    t_k: f64,
    delta_t_k: f64,
    sample: &NetdSample,
    exclude: Option<&BadPixelMap>,
) -> Result<f64> {
    require_positive("t_k", t_k)?;
    require_positive("delta_t_k", delta_t_k)?;
    let frames = sample.frames;
    if frames < 2 {
        return Err(Error::param(
            "frames",
            frames,
            "at least 2 frames per temperature",
        ));
    }
    let model = instance.model();
    let (rows, cols) = (model.rows(), model.cols());
    if sample.rows.is_empty() {
        return Err(Error::param("rows", "none", "at least one detector row"));
    }
    if let Some(&r) = sample.rows.iter().find(|&&r| r >= rows) {
        return Err(Error::param(
            "rows",
            r,
            format!("a row index below the detector's {rows} rows"),
        ));
    }
    let exclude = match exclude {
        Some(map) => {
            if map.dim() != (rows, cols) {
                return Err(Error::param(
                    "bad-pixel map",
                    format!("{} x {}", map.dim().0, map.dim().1),
                    format!("the detector's {rows} x {cols} pixels"),
                ));
            }
            Some(BadPixelMap::from_mask(
                map.mask().select(Axis(0), &sample.rows),
            ))
        }
        None => None,
    };
    let response = sensor.response();
    let camera = sensor.camera();
    let cos4 = cos4_map(sensor, rows, cols)?;
    let field = |t: f64| -> Result<Array2<f64>> {
        let e = camera.electrons_blackbody(t, response)?;
        Ok(match &cos4 {
            Some(m) => m.mapv(|c| c * e),
            None => Array2::from_elem((rows, cols), e),
        })
    };
    let (e0, e1) = (field(t_k)?, field(t_k + delta_t_k)?);
    let (s0, s1) = rayon::join(
        || stack_frames(instance, &e0, &sample.rows, NETD_FRAME_BASE, frames),
        || {
            stack_frames(
                instance,
                &e1,
                &sample.rows,
                NETD_FRAME_BASE + 1_000_000,
                frames,
            )
        },
    );
    let m = netd::measured_netd(s0?.view(), s1?.view(), delta_t_k, exclude.as_ref())?;
    Ok(m.netd_k)
}

/// A stack `[frame, row, col]` of the rows `rows` of `frames` exposures of `mean_e` from
/// frame index `first`.
fn stack_frames(
    instance: &DetectorInstance,
    mean_e: &Array2<f64>,
    rows: &[usize],
    first: u64,
    frames: usize,
) -> Result<Array3<f64>> {
    let mut stack = Array3::zeros((frames, rows.len(), mean_e.ncols()));
    for (i, mut plane) in stack.axis_iter_mut(Axis(0)).enumerate() {
        let dn = instance.expose_rows(mean_e, rows, first + i as u64)?;
        Zip::from(&mut plane)
            .and(&dn)
            .for_each(|p, &d| *p = d as f64);
    }
    Ok(stack)
}
