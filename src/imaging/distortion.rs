//! Radial distortion as a geometric resampling of the scene (`[optics.distortion]`,
//! docs/field-optics.md).
//!
//! The engine images the scene grid onto the focal plane paraxially: scene sample `j` at
//! angle `u_j` lands at `f·u_j`. A distorted lens moves the image of paraxial height `H`
//! to `H_real = H (1 + k1 H² + k2 H⁴)` or a table of real against paraxial height
//! ([`DistortionConfig`], [`DistortionLaw`]; H normalised to the array's corner). Before the transfer functions, every band's radiance is therefore resampled:
//! the value at scene grid point `q` (a real image position) is the scene at the paraxial
//! position `D⁻¹(q)` that lands there, divided by the mapping's area ratio
//! `J = (H_real/H)·(dH_real/dH)` at that point.
//!
//! **What is conserved: flux.** The power a lens collects from an object's solid angle is
//! the same with or without distortion; distortion only spreads it over `J` times the
//! paraxial image area, so the image irradiance is divided by J (a barrel lens, J < 1 at
//! the edge, is brighter there than its cos⁴θ alone). A point source keeps its total
//! signal, and a uniform scene shows the factor 1/J, which the calibration's flat field
//! includes ([`super::relative_illumination::calibration_map`]).
//!
//! **Band-limited interpolation.** The scene is read at the non-grid positions `D⁻¹(q)`
//! with a separable Lanczos-3 kernel, `sinc(x)·sinc(x/3)` for |x| < 3 (C. E. Duchon,
//! "Lanczos filtering in one and two dimensions", J. Appl. Meteor. 18, 1016, 1979), its six
//! weights per axis normalised to sum 1 (a constant stays constant). Taps beyond the
//! scene's edge take the edge sample. The kernel passes the scene's band almost flat and
//! reproduces a sampled sinusoid's position exactly at the grid points; between them the
//! interpolation error is that of the window (Duchon, Fig. 2).
//!
//! The resampling is done in the scene's (object) frame: with a moving line of sight the
//! distortion follows the scene rather than the camera (stated in docs/field-optics.md).

use std::ops::DerefMut;
use std::sync::Arc;

use ndarray::{Array2, Axis};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::io::CubeReader;
use crate::scene::CubeMeta;
use crate::sensor::field_optics::{DistortionConfig, DistortionLaw};
use crate::sensor::Sensor;

use super::relative_illumination::corner_height_m;
use super::Sampling;

/// Half-width of the Lanczos kernel, samples.
const LANCZOS_A: i64 = 3;

/// Taps per axis.
const TAPS: usize = 2 * LANCZOS_A as usize;

/// The Lanczos-3 kernel at `x` samples.
fn lanczos(x: f64) -> f64 {
    let sinc = |t: f64| {
        if t.abs() < 1e-12 {
            1.0
        } else {
            let p = std::f64::consts::PI * t;
            p.sin() / p
        }
    };
    if x.abs() >= LANCZOS_A as f64 {
        0.0
    } else {
        sinc(x) * sinc(x / LANCZOS_A as f64)
    }
}

/// The first tap and the six normalised weights of position `t` (samples).
fn taps(t: f64) -> (i64, [f32; TAPS]) {
    let base = t.floor() as i64 - (LANCZOS_A - 1);
    let mut w = [0.0f64; TAPS];
    for (k, v) in w.iter_mut().enumerate() {
        *v = lanczos(t - (base + k as i64) as f64);
    }
    let sum: f64 = w.iter().sum();
    (base, w.map(|v| (v / sum) as f32))
}

/// Where one output sample reads the scene.
#[derive(Debug, Clone, Copy)]
struct Source {
    row0: i64,
    col0: i64,
    wy: [f32; TAPS],
    wx: [f32; TAPS],
    /// 1/J at the source position.
    flux: f32,
}

/// The resampling of one scene grid by a distortion law: for every scene sample, where it
/// reads the undistorted scene and its flux factor.
#[derive(Debug)]
pub struct Resampler {
    rows: usize,
    cols: usize,
    sources: Vec<Source>,
}

/// The geometry shared by [`Resampler`] and [`truth_rows`]: the focal-plane metres per
/// scene sample along y and x, and the corner height, m.
fn scene_scale(sensor: &Sensor, sampling: &Sampling) -> (f64, f64, f64) {
    let pitch = sensor.detector.pitch_m;
    (
        pitch / sampling.y.ratio,
        pitch / sampling.x.ratio,
        corner_height_m(sensor),
    )
}

impl Resampler {
    /// The resampling of the scene grid `sampling` describes by `law`. Errs when the scene
    /// reaches beyond the field height the law was checked on
    /// ([`crate::sensor::field_optics::DISTORTION_CHECKED_H`]) or the tables exceed the
    /// memory budget.
    pub fn new(sensor: &Sensor, sampling: &Sampling, law: &DistortionConfig) -> Result<Self> {
        let (rows, cols) = (sampling.y.scene_len, sampling.x.scene_len);
        crate::limits::check_alloc(
            "the distortion resampling table (scene rows × cols)",
            &[("rows", rows as u64), ("cols", cols as u64)],
            std::mem::size_of::<Source>() as u64,
        )?;
        let (my, mx, corner) = scene_scale(sensor, sampling);
        let law = law.law(corner)?;
        let (cy, cx) = ((rows as f64 - 1.0) / 2.0, (cols as f64 - 1.0) / 2.0);
        let mut sources = Vec::with_capacity(rows * cols);
        for i in 0..rows {
            for j in 0..cols {
                let (y, x) = ((i as f64 - cy) * my, (j as f64 - cx) * mx);
                let h_real = (x * x + y * y).sqrt() / corner;
                let h = law.paraxial(h_real).ok_or_else(|| {
                    Error::param(
                        "optics.distortion",
                        format!("a scene reaching field height {h_real:.3}"),
                        format!(
                            "a scene within field height {:.3} (where the law is checked one to one): a smaller scene or a smaller distortion",
                            law.real(crate::sensor::field_optics::DISTORTION_CHECKED_H)
                        ),
                    )
                })?;
                let s = if h_real > 0.0 {
                    h / h_real
                } else {
                    1.0 / law.ratio(0.0)
                };
                let (row0, wy) = taps(cy + (i as f64 - cy) * s);
                let (col0, wx) = taps(cx + (j as f64 - cx) * s);
                sources.push(Source {
                    row0,
                    col0,
                    wy,
                    wx,
                    flux: (1.0 / law.jacobian(h)) as f32,
                });
            }
        }
        Ok(Resampler {
            rows,
            cols,
            sources,
        })
    }

    /// The distorted image of one band plane (same shape).
    pub fn apply(&self, plane: &Array2<f32>) -> Result<Array2<f32>> {
        if plane.dim() != (self.rows, self.cols) {
            return Err(Error::OutOfRange(format!(
                "a band plane of {:?} samples for a distortion table of {:?}",
                plane.dim(),
                (self.rows, self.cols)
            )));
        }
        let (rows, cols) = (self.rows as i64, self.cols as i64);
        let mut out = Array2::<f32>::zeros((self.rows, self.cols));
        out.axis_iter_mut(Axis(0))
            .into_par_iter()
            .enumerate()
            .for_each(|(i, mut row)| {
                for (j, v) in row.iter_mut().enumerate() {
                    let s = &self.sources[i * self.cols + j];
                    let mut acc = 0.0f64;
                    for (a, wy) in s.wy.iter().enumerate() {
                        let r = (s.row0 + a as i64).clamp(0, rows - 1) as usize;
                        let mut line = 0.0f64;
                        for (b, wx) in s.wx.iter().enumerate() {
                            let c = (s.col0 + b as i64).clamp(0, cols - 1) as usize;
                            line += f64::from(*wx) * f64::from(plane[[r, c]]);
                        }
                        acc += f64::from(*wy) * line;
                    }
                    // Not clipped at 0: the kernel's negative lobes are part of the
                    // band-limited interpolant (clipping them would add flux and move
                    // centroids); the optics' blur follows.
                    *v = (acc * f64::from(s.flux)) as f32;
                }
            });
        Ok(out)
    }
}

/// A cube reader whose bands come out distorted ([`Resampler`]); everything else is the
/// inner reader's.
pub struct DistortedReader<P> {
    inner: P,
    resampler: Arc<Resampler>,
}

impl<P> DistortedReader<P> {
    /// `inner` read through `resampler`.
    pub fn new(inner: P, resampler: Arc<Resampler>) -> Self {
        DistortedReader { inner, resampler }
    }
}

impl<P> CubeReader for DistortedReader<P>
where
    P: DerefMut,
    P::Target: CubeReader,
{
    fn meta(&self) -> &CubeMeta {
        self.inner.meta()
    }
    fn frames(&self) -> usize {
        self.inner.frames()
    }
    fn frame_time_s(&self) -> Option<f64> {
        self.inner.frame_time_s()
    }
    fn read_band(&mut self, frame: usize, band: usize) -> Result<Array2<f32>> {
        let plane = self.inner.read_band(frame, band)?;
        let out = self.resampler.apply(&plane);
        self.inner.recycle(vec![plane]);
        out
    }
    fn read_bands(&mut self, frame: usize, bands: &[usize]) -> Result<Vec<Array2<f32>>> {
        let planes = self.inner.read_bands(frame, bands)?;
        let out = planes.iter().map(|p| self.resampler.apply(p)).collect();
        self.inner.recycle(planes);
        out
    }
    fn warnings(&self) -> Vec<String> {
        self.inner.warnings()
    }
    fn units_source(&self) -> String {
        self.inner.units_source()
    }
    fn reopen(&self) -> Option<Result<Box<dyn CubeReader + Send>>> {
        let resampler = Arc::clone(&self.resampler);
        self.inner.reopen().map(|r| {
            r.map(|b| Box::new(DistortedReader::new(b, resampler)) as Box<dyn CubeReader + Send>)
        })
    }
}

/// The truth mapping at detector pixel centres, every `step`-th row and column and the
/// last ones: `(row, col, object angle x, object angle y (rad, the paraxial direction
/// imaged at that centre, in the scene's angular coordinates), paraxial H, real H)`.
///
/// Errors: an invalid law ([`DistortionConfig::validate`]).
pub fn truth_rows(sensor: &Sensor, law: &DistortionConfig, step: usize) -> Result<Vec<[f64; 6]>> {
    let d = &sensor.detector;
    let (rows, cols) = (d.rows, d.cols);
    let ifov = sensor.ifov_rad();
    let corner = corner_height_m(sensor);
    let law: DistortionLaw = law.law(corner)?;
    let pick = |n: usize| -> Vec<usize> {
        let mut v: Vec<usize> = (0..n).step_by(step.max(1)).collect();
        if v.last() != Some(&(n - 1)) {
            v.push(n - 1);
        }
        v
    };
    let mut out = Vec::new();
    for r in pick(rows) {
        for c in pick(cols) {
            let y = (r as f64 - (rows as f64 - 1.0) / 2.0) * d.pitch_m;
            let x = (c as f64 - (cols as f64 - 1.0) / 2.0) * d.pitch_m;
            let h_real = (x * x + y * y).sqrt() / corner;
            // Pixel centres lie within H = 1, where the law is checked one to one.
            let h = law.paraxial(h_real).unwrap_or(h_real);
            let s = if h_real > 0.0 { h / h_real } else { 1.0 };
            let to_angle = ifov / d.pitch_m;
            out.push([
                r as f64,
                c as f64,
                x * s * to_angle,
                y * s * to_angle,
                h,
                h_real,
            ]);
        }
    }
    Ok(out)
}

/// `distortion.csv`: [`truth_rows`] with a header, at most about 33 × 33 points.
///
/// Errors: an invalid law ([`DistortionConfig::validate`]).
pub fn truth_csv(sensor: &Sensor, law: &DistortionConfig) -> Result<String> {
    let d = &sensor.detector;
    let step = d.rows.max(d.cols).div_ceil(32).max(1);
    let mut s = String::from(
        "# detector pixel centre (row, col; 0 = first) -> the object direction imaged there (rad, +x right, +y down, from the axis); field heights normalised to the array corner\nrow,col,object_x_rad,object_y_rad,paraxial_h,real_h\n",
    );
    for [r, c, x, y, h, hr] in truth_rows(sensor, law, step)? {
        s.push_str(&format!("{r},{c},{x:.9e},{y:.9e},{h:.9},{hr:.9}\n"));
    }
    Ok(s)
}

/// The distorted reader of a run, or `None` when the sensor has no distortion (or an
/// identity law): the run then reads `reader` as it is.
pub fn resampler_for(sensor: &Sensor, sampling: &Sampling) -> Result<Option<Arc<Resampler>>> {
    match sensor
        .optics
        .distortion
        .as_ref()
        .filter(|d| !d.is_identity())
    {
        Some(law) => Ok(Some(Arc::new(Resampler::new(sensor, sampling, law)?))),
        None => Ok(None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One axis of the resampling at a uniform scale: output sample q reads the input at
    /// `centre + s·q`; returns `s·Σ out / Σ in` for a Gaussian of σ = 1 sample at `p`
    /// (the flux the output grid, whose samples each stand for s input samples, holds).
    fn flux_ratio(s: f64, p: f64) -> f64 {
        let input = |k: i64| (-0.5 * (k as f64 - p).powi(2)).exp();
        let total: f64 = (-40..=40).map(input).sum();
        let mut out = 0.0;
        for q in -60i64..=60 {
            let (base, w) = taps(s * q as f64);
            out += w
                .iter()
                .enumerate()
                .map(|(k, w)| f64::from(*w) * input(base + k as i64))
                .sum::<f64>();
        }
        s * out / total
    }

    /// Why a resampled point does not keep its flux exactly (docs/field-optics.md,
    /// "Flux of a resampled point"): the normalised Lanczos-3 weights of one input sample
    /// sum to 1 over the output grid only when that grid is the input's shifted by a
    /// constant (s = 1); at a scale s ≠ 1 the kernel's response beyond the input's
    /// Nyquist frequency lets the input's spectral replica at 1 cycle/sample alias to
    /// |1/s − 1| cycles per sample, a slow beat of the weight each input sample gives.
    /// A point's flux then changes by the beat's value at its position: up to ±5.4e-3
    /// per axis at s = 1.06 (the outer points of the integration test, J = 0.89), with
    /// the sign changing as the point moves by half a beat period; a pure shift keeps it
    /// to rounding, and a uniform input stays exact (the weights of each output sum to 1).
    #[test]
    fn a_point_keeps_its_flux_under_a_shift_and_beats_under_a_scale() {
        for p in [0.0, 0.3, 0.5, 7.7] {
            // A pure shift (s = 1, the output at centre + q with a fractional offset).
            let input = |k: i64| (-0.5 * (k as f64 - p).powi(2)).exp();
            let total: f64 = (-40..=40).map(input).sum();
            let out: f64 = (-60i64..=60)
                .map(|q| {
                    let (base, w) = taps(q as f64 + 0.37);
                    w.iter()
                        .enumerate()
                        .map(|(k, w)| f64::from(*w) * input(base + k as i64))
                        .sum::<f64>()
                })
                .sum();
            assert!((out / total - 1.0).abs() < 1e-6, "shift: {}", out / total);
        }
        let beat: Vec<f64> = (0..36)
            .map(|i| flux_ratio(1.06, i as f64 * 0.5) - 1.0)
            .collect();
        let (lo, hi) = beat
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(*v), b.max(*v))
            });
        println!("Lanczos-3 at s = 1.06: a point's flux error per axis from {lo:.2e} to {hi:.2e}");
        assert!(hi > 4e-3 && hi < 7e-3 && lo < -4e-3, "{lo} {hi}");
        // A milder scale beats less: the error is ∝ the kernel's response near 1 cycle per
        // sample, which grows from 0 as 1/s leaves 1.
        let mild = (0..36)
            .map(|i| (flux_ratio(1.01, i as f64 * 0.5) - 1.0).abs())
            .fold(0.0, f64::max);
        assert!(mild < 0.5 * hi, "{mild}");
    }
}
