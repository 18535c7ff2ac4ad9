//! Persistence (image lag): charge trapped during bright exposures and released over later
//! frames, so a bright source leaves a decaying ghost.
//!
//! The model is Tulloch's (S. Tulloch 2019, "Persistence characterisation and modelling
//! for the MOONS H4RG detectors", arXiv:1908.06469), as implemented in Pyxel
//! (`simple_persistence`): trap species i, with time constant τ_i and density d_i (the
//! fraction of a pixel's charge Q the species holds at equilibrium), exchange charge with
//! the pixel at the rate
//!
//! ```text
//!   dq_i/dt = (d_i·Q − q_i) / τ_i .
//! ```
//!
//! Tulloch steps it with forward Euler, `Δq_i = (Δt/τ_i)(d_i·Q − q_i)`, which overshoots
//! (and oscillates for Δt > 2τ_i) when the frame period is longer than a time constant.
//! Here Q is held at the frame's mean charge over the frame and the linear equation is
//! integrated exactly:
//!
//! ```text
//!   Δq_i = (1 − exp(−Δt/τ_i))·(d_i·Q − q_i),      Q_out = Q_in − Σ_i Δq_i ,
//! ```
//!
//! which equals Tulloch's step for Δt ≪ τ_i and stays between q_i and d_i·Q for any Δt.
//! Clipping is never needed: with Σ d_i ≤ 1 the charge captured in a step,
//! Σ_{Δq_i>0} Δq_i ≤ Σ d_i·Q ≤ Q, never exceeds what the pixel holds, and a release
//! never exceeds q_i. After a bright phase, in the dark (Q = 0) the ghost of frame n is
//! `Σ_i q_i(0)·exp(−(n−1)Δt/τ_i)·(1 − exp(−Δt/τ_i))`: a sum of exponentials with the
//! configured time constants.
//!
//! The model acts on the MEAN electrons of a frame (before shot noise), with Q clipped to
//! the full well (charge above it is not in the pixel and cannot be trapped). It carries
//! no randomness: the state after frame k depends only on the mean frames 0..=k, so a
//! sequence split into pieces reproduces it exactly when each piece replays the mean
//! frames from the sequence start (or receives the state from the previous piece).

use ndarray::{Array2, Axis};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{require_non_negative, require_positive, Error, Result};

/// `[detector.persistence]`: trap species for persistence (off when the table is absent).
///
/// ```toml
/// [detector.persistence]
/// tau_s = [1.0, 10.0, 100.0, 1000.0, 10000.0]
/// density = [0.00307, 0.00175, 0.00188, 0.00136, 0.00194]
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PersistenceConfig {
    /// Time constant of each trap species, seconds, > 0 (default: Tulloch's MOONS H4RG
    /// species, 1, 10, 100, 1000, 10000 s).
    #[serde(default = "default_tau_s")]
    pub tau_s: Vec<f64>,
    /// Fraction of the pixel's charge each species holds at equilibrium, ≥ 0, one per
    /// time constant, summing to ≤ 1 (default: Tulloch's MOONS proportions 0.307, 0.175,
    /// 0.188, 0.136, 0.194 scaled to an illustrative total of 1 %).
    #[serde(default = "default_density")]
    pub density: Vec<f64>,
}

fn default_tau_s() -> Vec<f64> {
    vec![1.0, 10.0, 100.0, 1000.0, 10000.0]
}
fn default_density() -> Vec<f64> {
    [0.307, 0.175, 0.188, 0.136, 0.194]
        .iter()
        .map(|p| p * 0.01)
        .collect()
}

impl Default for PersistenceConfig {
    fn default() -> Self {
        PersistenceConfig {
            tau_s: default_tau_s(),
            density: default_density(),
        }
    }
}

impl PersistenceConfig {
    /// Every impossible value is an error naming `detector.persistence.<field>`.
    pub fn validate(&self) -> Result<()> {
        if self.tau_s.is_empty() {
            return Err(Error::param(
                "detector.persistence.tau_s",
                "[]",
                "at least one trap species",
            ));
        }
        if self.density.len() != self.tau_s.len() {
            return Err(Error::param(
                "detector.persistence.density",
                format!("{} values", self.density.len()),
                format!(
                    "one density per time constant ({} in tau_s)",
                    self.tau_s.len()
                ),
            ));
        }
        for (i, &t) in self.tau_s.iter().enumerate() {
            require_positive(&format!("detector.persistence.tau_s[{i}]"), t)?;
        }
        for (i, &d) in self.density.iter().enumerate() {
            require_non_negative(&format!("detector.persistence.density[{i}]"), d)?;
        }
        let total: f64 = self.density.iter().sum();
        if total > 1.0 {
            return Err(Error::param(
                "detector.persistence.density",
                total,
                "densities summing to at most 1 (the traps cannot hold more than the \
                 pixel's charge)",
            ));
        }
        Ok(())
    }
}

/// Trap state of every pixel (Tulloch 2019, arXiv:1908.06469, as in Pyxel): per species
/// Δq_i = (1 − exp(−Δt/τ_i))·(d_i·Q − q_i) (the exact exponential form of Tulloch's
/// (Δt/τ_i)(d_i Q − q_i), stable for Δt > τ_i), Q −= Σ Δq_i.
#[derive(Debug, Clone)]
pub struct Persistence {
    rows: usize,
    cols: usize,
    tau_s: Vec<f64>,
    density: Vec<f64>,
    /// Trapped electrons, pixel-major: `[(row·cols + col)·species + i]`.
    trapped_e: Vec<f64>,
    started: bool,
}

impl Persistence {
    /// Empty traps for a `rows × cols` array; the first [`Persistence::step`] fills them
    /// to equilibrium. `cfg` must have passed [`PersistenceConfig::validate`].
    pub fn new(cfg: &PersistenceConfig, rows: usize, cols: usize) -> Self {
        Persistence {
            rows,
            cols,
            tau_s: cfg.tau_s.clone(),
            density: cfg.density.clone(),
            trapped_e: vec![0.0; rows * cols * cfg.tau_s.len()],
            started: false,
        }
    }

    /// One frame of `dt_s` seconds (the frame period) on the MEAN electrons of the frame
    /// (before shot noise; Q is clipped to `full_well_e`). The first call starts the traps
    /// at equilibrium with that frame (no bright history before the sequence), so a
    /// static scene is unchanged. A `dt_s` ≤ 0 (or NaN) exchanges nothing.
    ///
    /// # Panics
    /// If `mean_e` is not `rows × cols` (a caller bug, not a data error).
    pub fn step(&mut self, mean_e: &mut Array2<f64>, full_well_e: f64, dt_s: f64) {
        assert_eq!(
            mean_e.dim(),
            (self.rows, self.cols),
            "persistence state and frame shapes differ"
        );
        let ns = self.tau_s.len();
        if ns == 0 || self.rows * self.cols == 0 {
            return;
        }
        let fw = full_well_e.max(0.0);
        let density = &self.density;
        if !self.started {
            self.started = true;
            mean_e
                .axis_iter(Axis(0))
                .into_par_iter()
                .zip(self.trapped_e.par_chunks_mut(self.cols * ns))
                .for_each(|(m_row, q_row)| {
                    for (&m, q) in m_row.iter().zip(q_row.chunks_mut(ns)) {
                        let charge = clip_charge(m, fw);
                        for (qi, &di) in q.iter_mut().zip(density) {
                            *qi = di * charge;
                        }
                    }
                });
            return;
        }
        let dt = if dt_s > 0.0 { dt_s } else { 0.0 };
        // 1 − exp(−Δt/τ_i), computed without cancellation for Δt ≪ τ_i.
        let rate: Vec<f64> = self.tau_s.iter().map(|&t| -(-dt / t).exp_m1()).collect();
        let rate = &rate;
        mean_e
            .axis_iter_mut(Axis(0))
            .into_par_iter()
            .zip(self.trapped_e.par_chunks_mut(self.cols * ns))
            .for_each(|(mut m_row, q_row)| {
                for (m, q) in m_row.iter_mut().zip(q_row.chunks_mut(ns)) {
                    let charge = clip_charge(*m, fw);
                    let mut captured = 0.0;
                    for ((qi, &di), &fi) in q.iter_mut().zip(density).zip(rate) {
                        let dq = fi * (di * charge - *qi);
                        *qi += dq;
                        captured += dq;
                    }
                    *m -= captured;
                }
            });
    }

    /// Charge held in traps now, e⁻ per pixel (truth).
    pub fn trapped_e(&self) -> Array2<f64> {
        let ns = self.tau_s.len().max(1);
        let sums: Vec<f64> = self.trapped_e.chunks(ns).map(|q| q.iter().sum()).collect();
        Array2::from_shape_vec((self.rows, self.cols), sums)
            .unwrap_or_else(|_| Array2::zeros((self.rows, self.cols)))
    }
}

/// The pixel charge the traps see: the mean electrons clipped to [0, full well] (NaN → 0).
fn clip_charge(mean_e: f64, full_well_e: f64) -> f64 {
    if mean_e > 0.0 {
        mean_e.min(full_well_e)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;

    fn cfg() -> PersistenceConfig {
        PersistenceConfig {
            tau_s: vec![0.01, 0.1, 1.0, 10.0],
            density: vec![0.002, 0.003, 0.004, 0.005],
        }
    }

    #[test]
    fn a_static_or_dark_scene_is_unchanged() {
        let c = cfg();
        c.validate().unwrap();
        let mut p = Persistence::new(&c, 6, 7);
        let scene = Array2::from_shape_fn((6, 7), |(r, c)| 100.0 * (r * 7 + c) as f64 + 3.0);
        for _ in 0..50 {
            let mut f = scene.clone();
            p.step(&mut f, 1e5, 0.02);
            assert_eq!(f, scene);
        }
        // No bright history: a constant background from the first frame stays unchanged.
        let mut q = Persistence::new(&c, 4, 4);
        for _ in 0..20 {
            let mut f = Array2::from_elem((4, 4), 250.0);
            q.step(&mut f, 1e5, 0.5);
            assert!(f.iter().all(|&v| v == 250.0));
        }
        let expected = 250.0 * c.density.iter().sum::<f64>();
        assert!(q.trapped_e().iter().all(|&t| (t - expected).abs() < 1e-12));
    }

    /// Truth for the ghost: integrate Tulloch's rate equation dq/dt = (dQ − q)/τ with
    /// forward Euler on 4000 sub-steps per frame (Q held per frame), independent of the
    /// exact-exponential step of the module.
    fn euler_ghost(c: &PersistenceConfig, frames_q: &[f64], dt: f64) -> Vec<f64> {
        let sub = 4000;
        let h = dt / sub as f64;
        let mut q: Vec<f64> = c.density.iter().map(|d| d * frames_q[0]).collect();
        let mut out = vec![0.0];
        for &big_q in &frames_q[1..] {
            let before: f64 = q.iter().sum();
            for _ in 0..sub {
                for ((qi, &di), &ti) in q.iter_mut().zip(&c.density).zip(&c.tau_s) {
                    *qi += h / ti * (di * big_q - *qi);
                }
            }
            out.push(before - q.iter().sum::<f64>());
        }
        out
    }

    #[test]
    fn the_ghost_of_a_saturating_spot_decays_as_the_configured_sum_of_exponentials() {
        let c = cfg();
        let (fw, dt) = (1e5, 0.02);
        let (n_dark0, n_bright, n_dark) = (5, 50, 500);
        let mut p = Persistence::new(&c, 5, 5);
        let mut q_seq = Vec::new();
        let mut ghosts = Vec::new();
        for k in 0..n_dark0 + n_bright + n_dark {
            let bright = (n_dark0..n_dark0 + n_bright).contains(&k);
            let mut f = Array2::zeros((5, 5));
            if bright {
                f[[2, 2]] = 5.0 * fw; // saturating: 5× the full well
            }
            let input = f[[2, 2]];
            p.step(&mut f, fw, dt);
            // Only the spot pixel sees anything.
            assert!(f
                .indexed_iter()
                .all(|((r, cc), &v)| (r, cc) == (2, 2) || v == 0.0));
            q_seq.push(input.min(fw));
            ghosts.push(f[[2, 2]] - input);
        }
        // Closed form: after T_b = n_bright·dt at Q = fw from empty traps,
        // q_i = d_i·fw·(1 − e^(−T_b/τ_i)); dark frame n releases
        // Σ q_i e^(−(n−1)dt/τ_i) (1 − e^(−dt/τ_i)).
        let t_b = n_bright as f64 * dt;
        let euler = euler_ghost(&c, &q_seq, dt);
        let first_dark = n_dark0 + n_bright;
        let peak = ghosts[first_dark];
        assert!(peak > 0.0);
        let mut checked = 0;
        let (mut worst_closed, mut worst_euler): (f64, f64) = (0.0, 0.0);
        for n in 1..=n_dark {
            let closed: f64 = c
                .tau_s
                .iter()
                .zip(&c.density)
                .map(|(&tau, &d)| {
                    d * fw
                        * (1.0 - (-t_b / tau).exp())
                        * (-((n - 1) as f64) * dt / tau).exp()
                        * (1.0 - (-dt / tau).exp())
                })
                .sum();
            let got = ghosts[first_dark + n - 1];
            let num = euler[first_dark + n - 1];
            worst_closed = worst_closed.max((got - closed).abs() / closed);
            worst_euler = worst_euler.max((got - num).abs() / num);
            assert!(
                (got - closed).abs() <= 0.02 * closed,
                "n {n}: {got} vs {closed}"
            );
            assert!(
                (got - num).abs() <= 0.02 * num,
                "n {n}: {got} vs Euler {num}"
            );
            checked += 1;
        }
        assert_eq!(checked, n_dark);
        println!(
            "ghost: peak {peak:.1} e, last {:.3} e; worst relative error vs closed form \
             {worst_closed:.1e}, vs 4000-sub-step Euler {worst_euler:.1e}",
            ghosts[first_dark + n_dark - 1]
        );
        // The ghost spans the species: it falls by > 100× over the dark phase but is
        // still there at the end (τ = 10 s).
        assert!(ghosts[first_dark + n_dark - 1] > 0.0);
        assert!(ghosts[first_dark + n_dark - 1] < peak / 100.0);
        // Forward Euler on whole frames (Tulloch's form) overshoots here (dt = 2τ_0).
        let naive_q0 = c.density[0] * fw * (dt / c.tau_s[0]);
        assert!(naive_q0 > c.density[0] * fw);
    }

    #[test]
    fn charge_is_conserved_and_traps_stay_physical() {
        let c = cfg();
        let (rows, cols, fw, dt) = (9, 11, 5e4, 0.03);
        let mut p = Persistence::new(&c, rows, cols);
        let mut total_in = 0.0;
        let mut total_out = 0.0;
        let mut trapped0 = None;
        let mut max_q: f64 = 0.0;
        for k in 0..200usize {
            // A moving spot, a bright band and a flicker, never saturating except the spot.
            let mut f = Array2::from_shape_fn((rows, cols), |(r, cc)| {
                let spot = if (k / 7) % cols == cc && r == 4 {
                    2.0 * fw
                } else {
                    0.0
                };
                let band = if (k / 50) % 2 == 0 && r < 3 {
                    0.6 * fw
                } else {
                    0.0
                };
                spot + band + 10.0 * ((k * 31 + r * 7 + cc * 3) % 17) as f64
            });
            let input_sum: f64 = f.sum();
            max_q = max_q.max(f.iter().fold(0.0f64, |a, &v| a.max(v.min(fw))));
            p.step(&mut f, fw, dt);
            if trapped0.is_none() {
                trapped0 = Some(p.trapped_e().sum());
                assert_eq!(f.sum(), input_sum);
            }
            total_in += input_sum;
            total_out += f.sum();
            let trapped = p.trapped_e();
            assert!(trapped.iter().all(|&t| t >= 0.0));
            assert!(trapped
                .iter()
                .all(|&t| t <= c.density.iter().sum::<f64>() * max_q + 1e-9));
        }
        // signal in + trapped at the start = signal out + trapped now.
        let balance = total_in + trapped0.unwrap() - total_out - p.trapped_e().sum();
        assert!(balance.abs() < 1e-9 * total_in, "imbalance {balance}");
    }

    #[test]
    fn frame_periods_longer_than_a_time_constant_stay_stable() {
        let c = PersistenceConfig {
            tau_s: vec![1e-3],
            density: vec![0.5],
        };
        let mut p = Persistence::new(&c, 1, 1);
        let mut f = Array2::zeros((1, 1));
        p.step(&mut f, 1e3, 1.0);
        let mut f = Array2::from_elem((1, 1), 100.0);
        p.step(&mut f, 1e3, 1.0); // Δt = 1000 τ: the traps fill to d·Q, no overshoot
        assert!((p.trapped_e()[[0, 0]] - 50.0).abs() < 1e-9);
        assert!((f[[0, 0]] - 50.0).abs() < 1e-9);
        let mut f = Array2::zeros((1, 1));
        p.step(&mut f, 1e3, 1.0);
        assert!((f[[0, 0]] - 50.0).abs() < 1e-9 && p.trapped_e()[[0, 0]].abs() < 1e-9);
    }

    #[test]
    fn bad_parameters_are_errors_naming_the_field() {
        let bad = |c: PersistenceConfig, field: &str| {
            let e = c.validate().unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        };
        PersistenceConfig::default().validate().unwrap();
        bad(
            PersistenceConfig {
                tau_s: vec![1.0, -2.0],
                density: vec![0.1, 0.1],
            },
            "detector.persistence.tau_s[1]",
        );
        bad(
            PersistenceConfig {
                tau_s: vec![1.0],
                density: vec![f64::NAN],
            },
            "detector.persistence.density[0]",
        );
        bad(
            PersistenceConfig {
                tau_s: vec![1.0, 2.0],
                density: vec![0.1],
            },
            "detector.persistence.density",
        );
        bad(
            PersistenceConfig {
                tau_s: vec![1.0, 2.0],
                density: vec![0.7, 0.6],
            },
            "detector.persistence.density",
        );
        bad(
            PersistenceConfig {
                tau_s: vec![],
                density: vec![],
            },
            "detector.persistence.tau_s",
        );
        let unknown: std::result::Result<PersistenceConfig, _> = toml::from_str("taus = [1.0]");
        assert!(unknown.is_err());
        let parsed: PersistenceConfig = toml::from_str("").unwrap();
        assert_eq!(parsed, PersistenceConfig::default());
    }

    /// Median ms per 640 × 512 frame with the 5 default species:
    /// `cargo test --release --lib detector::persistence::tests::bench -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn bench_persistence_640x512() {
        let c = PersistenceConfig::default();
        let mut p = Persistence::new(&c, 512, 640);
        let scene = Array2::from_shape_fn((512, 640), |(r, cc)| ((r * 640 + cc) % 1000) as f64);
        let mut times = Vec::new();
        for k in 0..100 {
            let mut f = scene.clone();
            f[[256, 320]] += k as f64 * 1e3;
            let s = std::time::Instant::now();
            p.step(&mut f, 1e5, 1.0 / 30.0);
            times.push(s.elapsed().as_secs_f64() * 1e3);
            std::hint::black_box(&f);
        }
        times.sort_by(|a, b| a.total_cmp(b));
        println!("persistence: 5 species, median {:.3} ms/frame", times[50]);
    }
}
