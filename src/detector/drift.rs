//! Drift of the fixed pattern: the per-pixel offsets and gains of a real focal plane do
//! not stay where a non-uniformity correction (NUC) measured them, so the residual
//! non-uniformity after a NUC grows with the time since it was made.
//!
//! Per pixel i, at time t (seconds since the start of the sequence):
//!
//! ```text
//!   gain factor  g_i(t) = 1 + W^g_i(t) + β^g_i · ΔT(t)
//!   offset       o_i(t) =     W^o_i(t) + β^o_i · ΔT(t)        [e⁻]
//! ```
//!
//! - `W_i` is a random walk (Brownian motion; the model chosen here for an unpredictable
//!   drift — the residual non-uniformity it leaves is what limits a staring camera, Mooney,
//!   Shepherd et al. 1989, "Responsivity nonuniformity limited performance of infrared
//!   staring cameras", Opt. Eng. 28, 1151): independent Gaussian increments of
//!   variance σ_w²·Δ on a fixed time grid of step Δ (`walk_step_s`), W(0) = 0, linear
//!   between grid points. So Var W(kΔ) = σ_w²·kΔ exactly; between grid points
//!   Var W((k+u)Δ) = σ_w²Δ(k + u²) ([`walk_variance_s`]).
//! - `β_i` is a per-pixel temperature coefficient, zero-mean Gaussian with standard
//!   deviation σ_β (a common coefficient shifts every pixel alike and is no
//!   non-uniformity), and ΔT(t) = T(t) − T(0) the change of the focal-plane temperature,
//!   T linear between the points of `fpa_temperature_k` and constant beyond its ends.
//!
//! Each walk increment k is drawn from the stream `(seed, effect, k, row)` and the
//! coefficients from `(seed, effect, 0, row)` (see `rng`), so the drift at any time is a
//! fixed function of the seed and the time alone: the same whatever times were asked
//! before (a later piece of a sequence replays the walk from t = 0 and gets bit-identical
//! values) and whatever the number of threads.
//!
//! **Residual non-uniformity after a two-point NUC** (the quadrature sum of the NUC's own
//! residual and the drift since the NUC). A two-point NUC made at t₀ maps each pixel's
//! gain and offset at t₀ back to the nominal ones; a signal of S electrons seen at t reads,
//! after the NUC, `S·(1 + δg_i) + δo_i` with δ the drift between t₀ and t (to first order
//! in the gain drift when t₀ > 0; exact for t₀ = 0, where the gain factor is 1). The
//! drift terms are independent and zero-mean, so the spatial variance is
//!
//! ```text
//!   σ²(t) = σ_NUC² + (S²·σ_wg² + σ_wo²)·V(t₀, t) + (S²·σ_βg² + σ_βo²)·(T(t) − T(t₀))²
//! ```
//!
//! with V the walk variance per unit σ_w² ([`walk_variance_s`]; V = t − t₀ on the grid).
//! An offset drift is divided by the pixel's gain (1 + PRNU) by the NUC: a relative change
//! of the order of the PRNU variance (1e-4 for a 1 % PRNU), neglected.

use ndarray::Array2;
use rand::RngExt;
use rand_distr::StandardNormal;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::rng::{stream, Effect};
use crate::error::{require_non_negative, require_positive, Error, Result};

/// The `[detector.drift]` table. Every amplitude defaults to 0 (no drift).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriftConfig {
    /// Random-walk amplitude of each pixel's offset, e⁻ per √s: after t seconds the offsets
    /// have spread by this × √t (rms across pixels). Default 0.
    #[serde(default)]
    pub offset_walk_e_per_sqrt_s: f64,
    /// Random-walk amplitude of each pixel's relative gain, per √s (dimensionless gain
    /// change per √s). Default 0.
    #[serde(default)]
    pub gain_walk_per_sqrt_s: f64,
    /// Spread (standard deviation across pixels) of the offset's temperature coefficient,
    /// e⁻ per kelvin of focal-plane temperature change. Default 0.
    #[serde(default)]
    pub offset_sigma_e_per_k: f64,
    /// Spread of the relative gain's temperature coefficient, per kelvin. Default 0.
    #[serde(default)]
    pub gain_sigma_per_k: f64,
    /// Focal-plane temperature trajectory, `[time_s, temperature_k]` points with strictly
    /// increasing times; linear between points, constant beyond the ends. Empty (the
    /// default): the temperature does not change.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub fpa_temperature_k: Vec<[f64; 2]>,
    /// Time step of the random-walk grid, s: increments are drawn every `walk_step_s`
    /// and the walk is linear in between. Default 1 s.
    #[serde(default = "default_walk_step_s")]
    pub walk_step_s: f64,
}

fn default_walk_step_s() -> f64 {
    1.0
}

impl Default for DriftConfig {
    fn default() -> Self {
        DriftConfig {
            offset_walk_e_per_sqrt_s: 0.0,
            gain_walk_per_sqrt_s: 0.0,
            offset_sigma_e_per_k: 0.0,
            gain_sigma_per_k: 0.0,
            fpa_temperature_k: Vec::new(),
            walk_step_s: default_walk_step_s(),
        }
    }
}

impl DriftConfig {
    /// Checks every amplitude is finite and ≥ 0, the walk step finite and > 0, and the
    /// trajectory's times finite and strictly increasing with finite temperatures > 0 K.
    pub fn validate(&self) -> Result<()> {
        require_non_negative(
            "detector.drift.offset_walk_e_per_sqrt_s",
            self.offset_walk_e_per_sqrt_s,
        )?;
        require_non_negative(
            "detector.drift.gain_walk_per_sqrt_s",
            self.gain_walk_per_sqrt_s,
        )?;
        require_non_negative(
            "detector.drift.offset_sigma_e_per_k",
            self.offset_sigma_e_per_k,
        )?;
        require_non_negative("detector.drift.gain_sigma_per_k", self.gain_sigma_per_k)?;
        require_positive("detector.drift.walk_step_s", self.walk_step_s)?;
        let mut previous: Option<f64> = None;
        for (i, &[t, k]) in self.fpa_temperature_k.iter().enumerate() {
            if !t.is_finite() || previous.is_some_and(|p| t <= p) {
                return Err(Error::param(
                    format!("detector.drift.fpa_temperature_k[{i}] time"),
                    t,
                    "a finite time in s, greater than the previous point's",
                ));
            }
            require_positive(
                &format!("detector.drift.fpa_temperature_k[{i}] temperature"),
                k,
            )?;
            previous = Some(t);
        }
        Ok(())
    }

    /// The focal-plane temperature at `t_s`, K: linear between the trajectory's points,
    /// constant beyond its ends; `None` without a trajectory.
    pub fn fpa_temperature_at_k(&self, t_s: f64) -> Option<f64> {
        let pts = &self.fpa_temperature_k;
        let first = pts.first()?;
        let last = pts.last()?;
        if t_s <= first[0] {
            return Some(first[1]);
        }
        if t_s >= last[0] {
            return Some(last[1]);
        }
        // t is strictly inside: find the segment [p0, p1] with p0.t <= t < p1.t.
        let i = pts.partition_point(|p| p[0] <= t_s);
        let (p0, p1) = (pts[i - 1], pts[i]);
        let u = (t_s - p0[0]) / (p1[0] - p0[0]);
        Some(p0[1] + u * (p1[1] - p0[1]))
    }

    /// The focal-plane temperature change from `t0_s` to `t1_s`, K (0 without a trajectory).
    pub fn temperature_change_k(&self, t0_s: f64, t1_s: f64) -> f64 {
        match (
            self.fpa_temperature_at_k(t0_s),
            self.fpa_temperature_at_k(t1_s),
        ) {
            (Some(a), Some(b)) => b - a,
            _ => 0.0,
        }
    }
}

/// Variance, per unit squared walk amplitude (so in seconds), of the walk's change from
/// `t0_s` to `t1_s` (order does not matter; negative times count as 0): with the grid
/// step Δ, a = t0/Δ = j + v and b = t1/Δ = k + u (j, k integers, u, v ∈ [0, 1)),
/// W(b) − W(a) = (1 − v)·Z_j + Σ_{j<i<k} Z_i + u·Z_k for k > j and (u − v)·Z_j for k = j,
/// the Z independent with variance Δ. So V = Δ[(1 − v)² + (k − j − 1) + u²] or Δ(u − v)²;
/// on the grid it is |t1 − t0|.
pub fn walk_variance_s(walk_step_s: f64, t0_s: f64, t1_s: f64) -> f64 {
    let (a, b) = (
        t0_s.max(0.0).min(t1_s.max(0.0)),
        t0_s.max(0.0).max(t1_s.max(0.0)),
    );
    let (j, v) = grid_position(walk_step_s, a);
    let (k, u) = grid_position(walk_step_s, b);
    if k == j {
        walk_step_s * (u - v) * (u - v)
    } else {
        walk_step_s * ((1.0 - v) * (1.0 - v) + (k - j - 1) as f64 + u * u)
    }
}

/// The grid interval k = ⌊t/Δ⌋ holding `t_s` and the fraction u ∈ [0, 1) through it.
fn grid_position(walk_step_s: f64, t_s: f64) -> (u64, f64) {
    let x = t_s.max(0.0) / walk_step_s;
    let k = x.floor();
    (k as u64, (x - k).clamp(0.0, 1.0))
}

/// Expected spatial residual non-uniformity, e⁻ rms, of a two-point NUC made at t = 0
/// seen at time `t_s` with `signal_e` electrons (those the pixel gain multiplies): the
/// quadrature sum of the NUC's own residual `nuc_residual_e` and the drift accumulated
/// since (module docs). Equals [`residual_nonuniformity_since_e`] with t₀ = 0.
pub fn residual_nonuniformity_e(
    cfg: &DriftConfig,
    nuc_residual_e: f64,
    signal_e: f64,
    t_s: f64,
) -> f64 {
    residual_nonuniformity_since_e(cfg, nuc_residual_e, signal_e, 0.0, t_s)
}

/// Expected spatial residual non-uniformity, e⁻ rms, at `t_s` of a two-point NUC made at
/// `t_nuc_s` (with its own residual `nuc_residual_e`) for `signal_e` electrons:
/// `√(σ_NUC² + (S²σ_wg² + σ_wo²)·V + (S²σ_βg² + σ_βo²)·(T(t) − T(t_nuc))²)` (module docs),
/// V from [`walk_variance_s`].
pub fn residual_nonuniformity_since_e(
    cfg: &DriftConfig,
    nuc_residual_e: f64,
    signal_e: f64,
    t_nuc_s: f64,
    t_s: f64,
) -> f64 {
    let s2 = signal_e * signal_e;
    let walk = s2 * cfg.gain_walk_per_sqrt_s.powi(2) + cfg.offset_walk_e_per_sqrt_s.powi(2);
    let tempco = s2 * cfg.gain_sigma_per_k.powi(2) + cfg.offset_sigma_e_per_k.powi(2);
    let dt_k = cfg.temperature_change_k(t_nuc_s, t_s);
    (nuc_residual_e * nuc_residual_e
        + walk * walk_variance_s(cfg.walk_step_s, t_nuc_s, t_s)
        + tempco * dt_k * dt_k)
        .sqrt()
}

/// The drift to apply at one time: multiply each pixel's gain by `gain_factor` and add
/// `offset_e` (electrons, before the conversion to DN).
#[derive(Debug, Clone, PartialEq)]
pub struct DriftState {
    /// Factor on each pixel's gain (1 = no drift), dimensionless.
    pub gain_factor: Array2<f64>,
    /// Offset added to each pixel, e⁻.
    pub offset_e: Array2<f64>,
}

/// One per-pixel random walk on the grid: its values at the ends of the current interval.
#[derive(Debug, Clone)]
struct Walk {
    effect: Effect,
    /// Standard deviation of one grid increment, σ_w·√Δ.
    step_sigma: f64,
    /// W at grid point k (row-major rows × cols).
    lo: Vec<f64>,
    /// W at grid point k + 1.
    hi: Vec<f64>,
}

/// Per-pixel drift of the fixed pattern (random walk in offset and gain, plus per-pixel
/// temperature coefficients times the focal-plane temperature change since t = 0); see
/// the module docs for the model and its randomness.
#[derive(Debug, Clone)]
pub struct Drift {
    cfg: DriftConfig,
    rows: usize,
    cols: usize,
    seed: u64,
    /// Current grid interval k of the walks (they hold W_k and W_{k+1}).
    k: u64,
    offset_walk: Option<Walk>,
    gain_walk: Option<Walk>,
    /// Per-pixel offset temperature coefficients, e⁻/K (None when σ = 0 or no trajectory).
    offset_tempco: Option<Vec<f64>>,
    /// Per-pixel gain temperature coefficients, 1/K.
    gain_tempco: Option<Vec<f64>>,
}

impl Drift {
    /// The drift of one sensor (`seed`) of `rows × cols` pixels, at t = 0. Effects with a
    /// zero amplitude cost nothing.
    pub fn new(cfg: &DriftConfig, rows: usize, cols: usize, seed: u64) -> Self {
        let n = rows * cols;
        let has_trajectory = cfg.fpa_temperature_k.len() > 1;
        let tempco = |sigma: f64, effect: Effect| -> Option<Vec<f64>> {
            (sigma > 0.0 && has_trajectory).then(|| {
                let mut v = vec![0.0; n];
                fill_rows(&mut v, cols, |row, out| {
                    let mut rng = stream(seed, effect, 0, row as u64);
                    for o in out.iter_mut() {
                        *o = sigma * rng.sample::<f64, _>(StandardNormal);
                    }
                });
                v
            })
        };
        let walk = |sigma: f64, effect: Effect| -> Option<Walk> {
            (sigma > 0.0).then(|| {
                let mut w = Walk {
                    effect,
                    step_sigma: sigma * cfg.walk_step_s.sqrt(),
                    lo: vec![0.0; n],
                    hi: vec![0.0; n],
                };
                w.reset(seed, cols);
                w
            })
        };
        Drift {
            cfg: cfg.clone(),
            rows,
            cols,
            seed,
            k: 0,
            offset_walk: walk(cfg.offset_walk_e_per_sqrt_s, Effect::DriftOffsetWalk),
            gain_walk: walk(cfg.gain_walk_per_sqrt_s, Effect::DriftGainWalk),
            offset_tempco: tempco(cfg.offset_sigma_e_per_k, Effect::DriftOffsetTempco),
            gain_tempco: tempco(cfg.gain_sigma_per_k, Effect::DriftGainTempco),
        }
    }

    /// The drift at time `t_s` (seconds since the sequence start; a negative or
    /// non-finite time counts as 0): multiply the pixel's gain by `gain_factor` and add `offset_e`. t = 0 gives
    /// none (factor exactly 1, offset exactly 0). Calls are cheapest in increasing time
    /// (each advances the walk by the grid steps since the previous call); an earlier
    /// time replays the walk from t = 0, with the same result as a fresh instance.
    pub fn at(&mut self, t_s: f64) -> DriftState {
        let t = if t_s.is_finite() { t_s.max(0.0) } else { 0.0 };
        let (k, u) = grid_position(self.cfg.walk_step_s, t);
        if k < self.k {
            for w in [&mut self.offset_walk, &mut self.gain_walk]
                .into_iter()
                .flatten()
            {
                w.reset(self.seed, self.cols);
            }
            self.k = 0;
        }
        for w in [&mut self.offset_walk, &mut self.gain_walk]
            .into_iter()
            .flatten()
        {
            w.advance(self.seed, self.cols, self.k, k);
        }
        self.k = k;
        let dt_k = self.cfg.temperature_change_k(0.0, t);
        let shape = (self.rows, self.cols);
        let gain_factor = self.field(
            1.0,
            self.gain_walk.as_ref(),
            self.gain_tempco.as_deref(),
            u,
            dt_k,
        );
        let offset_e = self.field(
            0.0,
            self.offset_walk.as_ref(),
            self.offset_tempco.as_deref(),
            u,
            dt_k,
        );
        DriftState {
            gain_factor: Array2::from_shape_vec(shape, gain_factor)
                .unwrap_or_else(|_| Array2::from_elem(shape, 1.0)),
            offset_e: Array2::from_shape_vec(shape, offset_e)
                .unwrap_or_else(|_| Array2::zeros(shape)),
        }
    }

    /// `base + W(t) + β·ΔT` per pixel, W interpolated at fraction `u` of the interval.
    fn field(
        &self,
        base: f64,
        walk: Option<&Walk>,
        tempco: Option<&[f64]>,
        u: f64,
        dt_k: f64,
    ) -> Vec<f64> {
        let n = self.rows * self.cols;
        let chunk = self.cols.max(1);
        let mut out = vec![0.0; n];
        let beta = tempco.filter(|_| dt_k != 0.0);
        out.par_chunks_mut(chunk).enumerate().for_each(|(row, o)| {
            let span = row * chunk..row * chunk + o.len();
            match walk {
                Some(w) => {
                    for ((v, &lo), &hi) in o
                        .iter_mut()
                        .zip(&w.lo[span.clone()])
                        .zip(&w.hi[span.clone()])
                    {
                        *v = base + (lo + u * (hi - lo));
                    }
                }
                None => o.iter_mut().for_each(|v| *v = base),
            }
            if let Some(beta) = beta {
                for (v, &b) in o.iter_mut().zip(&beta[span]) {
                    *v += b * dt_k;
                }
            }
        });
        out
    }
}

impl Walk {
    /// Back to grid interval 0: W_0 = 0, W_1 = the first increment.
    fn reset(&mut self, seed: u64, cols: usize) {
        self.lo.iter_mut().for_each(|v| *v = 0.0);
        self.hi.iter_mut().for_each(|v| *v = 0.0);
        let (effect, sigma) = (self.effect, self.step_sigma);
        fill_rows(&mut self.hi, cols, |row, out| {
            add_increment(out, seed, effect, 0, row, sigma);
        });
    }

    /// From grid interval `from` to `to` (≥ from): each step W_k ← W_{k+1},
    /// W_{k+2} = W_{k+1} + increment k + 1.
    fn advance(&mut self, seed: u64, cols: usize, from: u64, to: u64) {
        if to <= from {
            return;
        }
        let (effect, sigma) = (self.effect, self.step_sigma);
        self.lo
            .par_chunks_mut(cols.max(1))
            .zip(self.hi.par_chunks_mut(cols.max(1)))
            .enumerate()
            .for_each(|(row, (lo, hi))| {
                for step in from + 1..=to {
                    lo.copy_from_slice(hi);
                    add_increment(hi, seed, effect, step, row, sigma);
                }
            });
    }
}

/// Adds increment `step` of the walk (σ·z, z standard normal from the stream
/// `(seed, effect, step, row)`) to one row.
fn add_increment(
    row_values: &mut [f64],
    seed: u64,
    effect: Effect,
    step: u64,
    row: usize,
    sigma: f64,
) {
    let mut rng = stream(seed, effect, step, row as u64);
    for v in row_values.iter_mut() {
        *v += sigma * rng.sample::<f64, _>(StandardNormal);
    }
}

/// Runs `f(row, values)` on every row of a row-major buffer, rows in parallel.
fn fill_rows(values: &mut [f64], cols: usize, f: impl Fn(usize, &mut [f64]) + Sync) {
    values
        .par_chunks_mut(cols.max(1))
        .enumerate()
        .for_each(|(row, out)| f(row, out));
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_xoshiro::Xoshiro256PlusPlus;

    const ROWS: usize = 128;
    const COLS: usize = 256;

    fn drifting() -> DriftConfig {
        DriftConfig {
            offset_walk_e_per_sqrt_s: 2.0,
            gain_walk_per_sqrt_s: 1.0e-4,
            offset_sigma_e_per_k: 30.0,
            gain_sigma_per_k: 2.0e-3,
            fpa_temperature_k: vec![[0.0, 80.0], [300.0, 80.5], [600.0, 79.8], [1000.0, 81.0]],
            walk_step_s: 5.0,
        }
    }

    /// A simulated focal plane: fixed gain g (2 % PRNU) and offset o (20 e⁻ DSNU) per pixel,
    /// the drift on top, Gaussian temporal noise of `noise_e` per frame.
    struct Plane {
        gain: Vec<f64>,
        offset_e: Vec<f64>,
        noise: Xoshiro256PlusPlus,
    }

    impl Plane {
        fn new() -> Self {
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(99);
            let n = ROWS * COLS;
            let gain = (0..n)
                .map(|_| 1.0 + 0.02 * rng.sample::<f64, _>(StandardNormal))
                .collect();
            let offset_e = (0..n)
                .map(|_| 100.0 + 20.0 * rng.sample::<f64, _>(StandardNormal))
                .collect();
            Plane {
                gain,
                offset_e,
                noise: rng,
            }
        }

        /// One raw frame of a flat signal `s_e` under the drift `d`, mean of `frames`
        /// frames each with white noise `noise_e`.
        fn raw(&mut self, s_e: f64, d: &DriftState, noise_e: f64, frames: usize) -> Vec<f64> {
            let gf = d.gain_factor.as_slice().unwrap();
            let off = d.offset_e.as_slice().unwrap();
            (0..self.gain.len())
                .map(|i| {
                    let clean = s_e * self.gain[i] * gf[i] + self.offset_e[i] + off[i];
                    let noise: f64 = (0..frames)
                        .map(|_| noise_e * self.noise.sample::<f64, _>(StandardNormal))
                        .sum();
                    clean + noise / frames as f64
                })
                .collect()
        }
    }

    /// A two-point NUC from two averaged flats: per pixel, signal = s1 + (raw − r1)·m.
    struct Nuc {
        s1: f64,
        r1: Vec<f64>,
        m: Vec<f64>,
    }

    const S1: f64 = 2000.0;
    const S2: f64 = 20000.0;
    const NOISE_E: f64 = 30.0;
    const FLAT_FRAMES: usize = 4;

    impl Nuc {
        fn measure(plane: &mut Plane, d: &DriftState) -> Self {
            let r1 = plane.raw(S1, d, NOISE_E, FLAT_FRAMES);
            let r2 = plane.raw(S2, d, NOISE_E, FLAT_FRAMES);
            let m = r1
                .iter()
                .zip(&r2)
                .map(|(a, b)| (S2 - S1) / (b - a))
                .collect();
            Nuc { s1: S1, r1, m }
        }

        /// Spatial standard deviation of the corrected noiseless frame of signal `s_e`.
        fn residual_e(&self, plane: &mut Plane, s_e: f64, d: &DriftState) -> f64 {
            let raw = plane.raw(s_e, d, 0.0, 1);
            let c: Vec<f64> = raw
                .iter()
                .enumerate()
                .map(|(i, r)| self.s1 + (r - self.r1[i]) * self.m[i])
                .collect();
            let n = c.len() as f64;
            let mean = c.iter().sum::<f64>() / n;
            (c.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
        }
    }

    /// The NUC's own residual at `s_e` (independent of the drift): the flats' averaged
    /// noise σ/√M interpolated with the weights of the two levels.
    fn nuc_own_residual_e(s_e: f64) -> f64 {
        let w1 = (S2 - s_e) / (S2 - S1);
        let w2 = (s_e - S1) / (S2 - S1);
        NOISE_E / (FLAT_FRAMES as f64).sqrt() * (w1 * w1 + w2 * w2).sqrt()
    }

    /// Monte Carlo (fixed seeds, 32 768 pixels, so the sample σ scatters by ≈ 0.4 %): a
    /// two-point NUC at t = 0 seen at later times (on and off the walk grid, with the
    /// temperature up and down) leaves the residual `residual_nonuniformity_e` predicts,
    /// within 5 %.
    #[test]
    fn residual_after_nuc_grows_as_predicted() {
        let cfg = drifting();
        cfg.validate().unwrap();
        let mut drift = Drift::new(&cfg, ROWS, COLS, 7);
        let mut plane = Plane::new();
        let nuc = Nuc::measure(&mut plane, &drift.at(0.0));
        let s = 8000.0;
        let own = nuc_own_residual_e(s);
        for t in [0.0, 40.0, 212.5, 450.5, 1000.0] {
            let d = drift.at(t);
            let got = nuc.residual_e(&mut plane, s, &d);
            let want = residual_nonuniformity_e(&cfg, own, s, t);
            assert!(
                (got / want - 1.0).abs() < 0.05,
                "t = {t} s: measured {got:.3} e, predicted {want:.3} e"
            );
        }
        // The drift dominates at the end, so the test would see a wrong drift model.
        assert!(residual_nonuniformity_e(&cfg, own, s, 1000.0) > 5.0 * own);
    }

    /// A NUC redone at t₁ brings the residual back to the t = 0 level, and it grows again
    /// as `residual_nonuniformity_since_e` predicts.
    #[test]
    fn renuc_resets_the_residual() {
        let cfg = drifting();
        let mut drift = Drift::new(&cfg, ROWS, COLS, 8);
        let mut plane = Plane::new();
        let s = 8000.0;
        let own = nuc_own_residual_e(s);
        let first = Nuc::measure(&mut plane, &drift.at(0.0));
        let t1 = 500.0;
        let d1 = drift.at(t1);
        let stale = first.residual_e(&mut plane, s, &d1);
        let second = Nuc::measure(&mut plane, &d1);
        let fresh = second.residual_e(&mut plane, s, &d1);
        assert!(
            (fresh / own - 1.0).abs() < 0.05,
            "after re-NUC {fresh} vs {own}"
        );
        assert!(stale > 3.0 * fresh, "before re-NUC {stale}, after {fresh}");
        for t in [620.0, 903.0] {
            let got = second.residual_e(&mut plane, s, &drift.at(t));
            let want = residual_nonuniformity_since_e(&cfg, own, s, t1, t);
            assert!((got / want - 1.0).abs() < 0.05, "t = {t}: {got} vs {want}");
        }
    }

    /// The drift at a time depends only on the seed and the time: asked directly, after
    /// other times, or after a later time (replay), it is bit-identical.
    #[test]
    fn drift_is_a_function_of_seed_and_time() {
        let cfg = drifting();
        let direct = Drift::new(&cfg, 16, 24, 3).at(401.7);
        let mut d = Drift::new(&cfg, 16, 24, 3);
        d.at(17.3);
        d.at(250.0);
        d.at(999.0);
        assert_eq!(d.at(401.7), direct);
        assert_ne!(Drift::new(&cfg, 16, 24, 4).at(401.7), direct);
        let zero = Drift::new(&cfg, 16, 24, 3).at(0.0);
        assert!(zero.gain_factor.iter().all(|&g| g == 1.0));
        assert!(zero.offset_e.iter().all(|&o| o == 0.0));
        assert_eq!(Drift::new(&cfg, 16, 24, 3).at(f64::INFINITY), zero);
        let none = Drift::new(&DriftConfig::default(), 4, 5, 3).at(1e4);
        assert!(none.gain_factor.iter().all(|&g| g == 1.0));
        assert!(none.offset_e.iter().all(|&o| o == 0.0));
    }

    /// Temperature part alone: offsets are β·ΔT with ΔT from the linear trajectory
    /// (closed form), the same β at every time, and β spreads by the configured σ.
    #[test]
    fn temperature_coefficients_follow_the_trajectory() {
        let cfg = DriftConfig {
            offset_sigma_e_per_k: 12.0,
            fpa_temperature_k: vec![[10.0, 80.0], [110.0, 82.0]],
            ..DriftConfig::default()
        };
        assert_eq!(cfg.fpa_temperature_at_k(0.0), Some(80.0));
        assert_eq!(cfg.fpa_temperature_at_k(35.0), Some(80.5));
        assert_eq!(cfg.fpa_temperature_at_k(500.0), Some(82.0));
        let mut d = Drift::new(&cfg, ROWS, COLS, 5);
        let a = d.at(35.0).offset_e; // ΔT = 0.5 K
        let b = d.at(300.0).offset_e; // ΔT = 2 K
        for (x, y) in a.iter().zip(&b) {
            assert!((y - 4.0 * x).abs() < 1e-9 * (1.0 + y.abs()));
        }
        let n = a.len() as f64;
        let sd = (b.iter().map(|v| v * v).sum::<f64>() / n).sqrt() / 2.0;
        // σ of a sample σ: σ/√(2n) ≈ 0.4 %; allow 4 of them.
        assert!((sd / 12.0 - 1.0).abs() < 4.0 / (2.0 * n).sqrt(), "{sd}");
    }

    #[test]
    fn walk_variance_is_the_elapsed_time_on_the_grid() {
        assert_eq!(walk_variance_s(5.0, 0.0, 1000.0), 1000.0);
        assert_eq!(walk_variance_s(5.0, 500.0, 100.0), 400.0);
        // Inside one interval: (u − v)²Δ; across: (1−v)² + (k−j−1) + u² steps.
        assert!((walk_variance_s(5.0, 1.0, 4.0) - 5.0 * 0.36).abs() < 1e-12);
        assert!((walk_variance_s(5.0, 1.0, 11.0) - 5.0 * (0.64 + 1.0 + 0.04)).abs() < 1e-12);
    }

    #[test]
    fn bad_parameters_are_errors() {
        let ok = drifting();
        ok.validate().unwrap();
        let cases: Vec<(DriftConfig, &str)> = vec![
            (
                DriftConfig {
                    offset_walk_e_per_sqrt_s: -1.0,
                    ..ok.clone()
                },
                "offset_walk_e_per_sqrt_s",
            ),
            (
                DriftConfig {
                    gain_walk_per_sqrt_s: f64::NAN,
                    ..ok.clone()
                },
                "gain_walk_per_sqrt_s",
            ),
            (
                DriftConfig {
                    offset_sigma_e_per_k: -0.1,
                    ..ok.clone()
                },
                "offset_sigma_e_per_k",
            ),
            (
                DriftConfig {
                    gain_sigma_per_k: f64::INFINITY,
                    ..ok.clone()
                },
                "gain_sigma_per_k",
            ),
            (
                DriftConfig {
                    walk_step_s: 0.0,
                    ..ok.clone()
                },
                "walk_step_s",
            ),
            (
                DriftConfig {
                    fpa_temperature_k: vec![[0.0, 80.0], [0.0, 81.0]],
                    ..ok.clone()
                },
                "fpa_temperature_k[1] time",
            ),
            (
                DriftConfig {
                    fpa_temperature_k: vec![[0.0, 80.0], [5.0, -3.0]],
                    ..ok.clone()
                },
                "fpa_temperature_k[1] temperature",
            ),
        ];
        for (cfg, field) in cases {
            let err = cfg.validate().unwrap_err().to_string();
            assert!(err.contains(&format!("detector.drift.{field}")), "{err}");
        }
    }

    #[test]
    fn unknown_keys_are_refused_and_defaults_apply() {
        let c: DriftConfig = toml::from_str("offset_walk_e_per_sqrt_s = 0.5").unwrap();
        assert_eq!(
            c,
            DriftConfig {
                offset_walk_e_per_sqrt_s: 0.5,
                ..DriftConfig::default()
            }
        );
        assert!(toml::from_str::<DriftConfig>("offset_walk = 0.5").is_err());
        let c: DriftConfig =
            toml::from_str("fpa_temperature_k = [[0.0, 80.0], [60.0, 80.2]]").unwrap();
        assert_eq!(c.fpa_temperature_k, vec![[0.0, 80.0], [60.0, 80.2]]);
    }
}
