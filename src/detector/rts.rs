//! Random telegraph signal (RTS) pixels: a fraction of the pixels switch between two
//! states, a low state and a high state with a higher dark current and/or offset, as a
//! two-state continuous-time Markov process (a random telegraph signal; Kandiah, Deighton
//! & Whiting 1989, J. Appl. Phys. 66, 937; for image sensors Bogaerts et al. 2002, IEEE
//! Trans. Nucl. Sci. 49, 249; Goiffon et al. 2009, IEEE Trans. Nucl. Sci. 56, 2132).
//!
//! The dwell time in each state is exponential with mean `tau_high_s` or `tau_low_s`
//! (Poisson switching: the rate of leaving the state is 1/τ). The stationary probability
//! of the high state is `P(high) = τ_high / (τ_high + τ_low)` and the process starts in it
//! at t = 0: the initial state is drawn with that probability and, by the memorylessness
//! of the exponential, the residual time of the first dwell is exponential with the same
//! τ. The state autocorrelation is
//! `P(high at t+Δ | high at t) = p + (1 − p)·exp(−Δ/τ_c)`, `1/τ_c = 1/τ_high + 1/τ_low`
//! (the two-state master equation; Machlup 1954, J. Appl. Phys. 25, 341).
//!
//! A pixel's extra charge in a frame is `dark_step_e_per_s × (time high inside the
//! integration window) + offset_step_e × [high when the row is read]`. The windows and the
//! readout times come from the sequence clock (rolling shutter: every row has its own), so
//! the state is carried from frame to frame and within a frame by the clock.
//!
//! Randomness: which pixels are RTS pixels comes from `Effect::RtsPixel` (one stream per
//! row, frame key 0, a fixed pattern); each RTS pixel's switching times come from its own
//! stream `Effect::RtsSwitch` keyed by its flat index, drawn sequentially from t = 0. The
//! realisation is therefore a function of the seed alone: a run that starts at frame k
//! (a Dask piece) gets exactly the same states as a run from frame 0 (it draws and
//! discards the switches before its first window, [`RtsPixels::advance_to`]), and the
//! result does not depend on the number of threads.

use std::collections::VecDeque;

use rand::RngExt;
use rand_distr::{Distribution, Exp1};
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::{Deserialize, Serialize};

use super::rng::{stream, Effect};
use crate::error::{require_in_range, require_non_negative, require_positive, Error, Result};

/// `[detector.rts]`: random telegraph pixels (off when the table is absent).
///
/// ```toml
/// [detector.rts]
/// fraction = 0.001
/// tau_high_s = 0.05
/// tau_low_s = 0.5
/// dark_step_e_per_s = 20000.0
/// offset_step_e = 0.0
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RtsConfig {
    /// Fraction of the pixels that are RTS pixels, in [0, 1] (default 0.001).
    #[serde(default = "default_fraction")]
    pub fraction: f64,
    /// Mean dwell time in the high state, seconds, > 0 (default 0.05 s).
    #[serde(default = "default_tau_high_s")]
    pub tau_high_s: f64,
    /// Mean dwell time in the low state, seconds, > 0 (default 0.5 s).
    #[serde(default = "default_tau_low_s")]
    pub tau_low_s: f64,
    /// Extra dark current in the high state, e⁻/s, ≥ 0 (default 0).
    #[serde(default)]
    pub dark_step_e_per_s: f64,
    /// Extra offset in the high state, e⁻, added when the row is read high, ≥ 0
    /// (default 0). At least one of the two steps must be > 0.
    #[serde(default)]
    pub offset_step_e: f64,
}

fn default_fraction() -> f64 {
    0.001
}
fn default_tau_high_s() -> f64 {
    0.05
}
fn default_tau_low_s() -> f64 {
    0.5
}

impl RtsConfig {
    /// Every impossible value is an error naming `detector.rts.<field>`.
    pub fn validate(&self) -> Result<()> {
        require_in_range("detector.rts.fraction", self.fraction, 0.0, 1.0)?;
        require_positive("detector.rts.tau_high_s", self.tau_high_s)?;
        require_positive("detector.rts.tau_low_s", self.tau_low_s)?;
        require_non_negative("detector.rts.dark_step_e_per_s", self.dark_step_e_per_s)?;
        require_non_negative("detector.rts.offset_step_e", self.offset_step_e)?;
        if self.dark_step_e_per_s == 0.0 && self.offset_step_e == 0.0 {
            return Err(Error::param(
                "detector.rts.dark_step_e_per_s",
                self.dark_step_e_per_s,
                "a step > 0 in dark_step_e_per_s or offset_step_e (both are 0, so the RTS \
                 pixels would not differ from the others)",
            ));
        }
        Ok(())
    }

    /// Stationary probability of the high state, `τ_high / (τ_high + τ_low)`.
    pub fn high_probability(&self) -> f64 {
        self.tau_high_s / (self.tau_high_s + self.tau_low_s)
    }

    /// Correlation time of the state, `τ_c = 1 / (1/τ_high + 1/τ_low)`, seconds:
    /// `P(high at t+Δ | high at t) = p + (1 − p)·exp(−Δ/τ_c)`.
    pub fn correlation_time_s(&self) -> f64 {
        1.0 / (1.0 / self.tau_high_s + 1.0 / self.tau_low_s)
    }
}

/// One exponential dwell time of mean `tau_s` seconds.
fn dwell_s(rng: &mut Xoshiro256PlusPlus, tau_s: f64) -> f64 {
    let e: f64 = Exp1.sample(rng);
    tau_s * e
}

/// One pixel's telegraph process: the state is known from `anchor_s` on; `switches` holds
/// the switching times after it that have been drawn so far (ascending, never empty).
#[derive(Debug, Clone)]
struct Telegraph {
    rng: Xoshiro256PlusPlus,
    anchor_s: f64,
    anchor_high: bool,
    switches: VecDeque<f64>,
}

impl Telegraph {
    /// The stationary process of one pixel from t = 0.
    fn new(mut rng: Xoshiro256PlusPlus, p_high: f64, tau_high_s: f64, tau_low_s: f64) -> Self {
        let u: f64 = rng.random();
        let high = u < p_high;
        let tau = if high { tau_high_s } else { tau_low_s };
        let first = dwell_s(&mut rng, tau);
        let mut switches = VecDeque::with_capacity(8);
        switches.push_back(first);
        Telegraph {
            rng,
            anchor_s: 0.0,
            anchor_high: high,
            switches,
        }
    }

    /// Draw dwell times until the last known switch is after `t_s`.
    fn extend_past(&mut self, t_s: f64, tau_high_s: f64, tau_low_s: f64) {
        while let Some(&last) = self.switches.back() {
            if last > t_s {
                break;
            }
            // The state after the last switch: the anchor state flipped len times.
            let high_after = self.anchor_high ^ (self.switches.len() % 2 == 1);
            let tau = if high_after { tau_high_s } else { tau_low_s };
            let dwell = dwell_s(&mut self.rng, tau);
            self.switches.push_back(last + dwell);
        }
    }

    /// State at `t_s` (≥ the anchor; earlier times read the anchor state). The state at a
    /// switching time is the state after it.
    fn high_at(&self, t_s: f64) -> bool {
        let flips = self.switches.iter().take_while(|&&s| s <= t_s).count();
        self.anchor_high ^ (flips % 2 == 1)
    }

    /// Seconds spent high in [a, b] (needs `extend_past(b)` first).
    fn high_time(&self, a_s: f64, b_s: f64) -> f64 {
        let a = a_s.max(self.anchor_s);
        if b_s <= a {
            return 0.0;
        }
        let mut high = self.anchor_high;
        let mut t = a;
        let mut total = 0.0;
        for &s in &self.switches {
            if s <= a {
                high = !high;
                continue;
            }
            if s >= b_s {
                break;
            }
            if high {
                total += s - t;
            }
            t = s;
            high = !high;
        }
        if high {
            total += b_s - t;
        }
        total
    }

    /// Forget the history before `t_s` (drawing the switches up to it first, so at least
    /// one switch after `t_s` stays known).
    fn advance(&mut self, t_s: f64, tau_high_s: f64, tau_low_s: f64) {
        if t_s <= self.anchor_s {
            return;
        }
        self.extend_past(t_s, tau_high_s, tau_low_s);
        while self.switches.front().is_some_and(|&s| s <= t_s) {
            self.switches.pop_front();
            self.anchor_high = !self.anchor_high;
        }
        self.anchor_s = t_s;
    }
}

/// The RTS pixels of one sensor and their two-state Markov processes (exponential dwell
/// times τ_high, τ_low; stationary start, P(high) = τ_high/(τ_high+τ_low)). Each pixel's
/// process is drawn from its own stream from t = 0, so a run that starts at frame k
/// replays it exactly (call `frame` for the earlier frames, or `advance_to`).
#[derive(Debug, Clone)]
pub struct RtsPixels {
    cols: usize,
    tau_high_s: f64,
    tau_low_s: f64,
    dark_step_e_per_s: f64,
    offset_step_e: f64,
    pixels: Vec<usize>,
    processes: Vec<Telegraph>,
}

/// The RTS contribution to one frame, per RTS pixel in the order of [`RtsPixels::pixels`].
#[derive(Debug, Clone, PartialEq)]
pub struct RtsFrame {
    /// Extra mean electrons: dark step × seconds high in the window + offset step if high
    /// when the row is read.
    pub extra_e: Vec<f64>,
    /// Fraction of the integration window spent high (for an empty window: 1 if high at
    /// its start, else 0) (truth).
    pub high_fraction: Vec<f64>,
    /// State when the row is read (truth).
    pub high_at_readout: Vec<bool>,
}

impl RtsPixels {
    /// Draw which pixels are RTS pixels (each independently with probability `fraction`,
    /// from `Effect::RtsPixel`, one stream per row) and start their processes at t = 0.
    /// `cfg` must have passed [`RtsConfig::validate`].
    pub fn new(cfg: &RtsConfig, rows: usize, cols: usize, seed: u64) -> Self {
        let mut pixels = Vec::new();
        if cfg.fraction > 0.0 {
            for r in 0..rows {
                let mut rng = stream(seed, Effect::RtsPixel, 0, r as u64);
                for c in 0..cols {
                    let u: f64 = rng.random();
                    if u < cfg.fraction {
                        pixels.push(r * cols + c);
                    }
                }
            }
        }
        let p_high = cfg.high_probability();
        let processes = pixels
            .iter()
            .map(|&p| {
                Telegraph::new(
                    stream(seed, Effect::RtsSwitch, 0, p as u64),
                    p_high,
                    cfg.tau_high_s,
                    cfg.tau_low_s,
                )
            })
            .collect();
        RtsPixels {
            cols: cols.max(1),
            tau_high_s: cfg.tau_high_s,
            tau_low_s: cfg.tau_low_s,
            dark_step_e_per_s: cfg.dark_step_e_per_s,
            offset_step_e: cfg.offset_step_e,
            pixels,
            processes,
        }
    }

    /// Flat indices (row·cols + col) of the RTS pixels, ascending.
    pub fn pixels(&self) -> &[usize] {
        &self.pixels
    }

    /// Move every process to time `t_s` (seconds from the sequence start) without
    /// producing a frame: the switches before are drawn and forgotten, so later frames
    /// are bit-identical to those of a run that went through every earlier frame.
    /// Times before the last window start have no effect.
    pub fn advance_to(&mut self, t_s: f64) {
        let (th, tl) = (self.tau_high_s, self.tau_low_s);
        for p in &mut self.processes {
            p.advance(t_s, th, tl);
        }
    }

    /// One frame: `window(row)` = (start, end) of that row's integration in seconds,
    /// `readout_s(row)` = when that row is read. Windows never go back in time between
    /// calls (a time before the previous call's window start reads the state at that
    /// start). Returns, per RTS pixel (same order as `pixels()`), the extra electrons
    /// (dark step × time high in the window + offset step if high at readout) and the
    /// fraction of the window spent high and the state at readout (truth).
    pub fn frame(
        &mut self,
        window: &dyn Fn(usize) -> (f64, f64),
        readout_s: &dyn Fn(usize) -> f64,
    ) -> RtsFrame {
        let n = self.pixels.len();
        let mut out = RtsFrame {
            extra_e: Vec::with_capacity(n),
            high_fraction: Vec::with_capacity(n),
            high_at_readout: Vec::with_capacity(n),
        };
        let (th, tl) = (self.tau_high_s, self.tau_low_s);
        let mut cached: Option<(usize, (f64, f64), f64)> = None;
        for (&pix, proc_) in self.pixels.iter().zip(self.processes.iter_mut()) {
            let row = pix / self.cols;
            let (w, ro) = match cached {
                Some((r, w, ro)) if r == row => (w, ro),
                _ => {
                    let w = window(row);
                    let ro = readout_s(row);
                    cached = Some((row, w, ro));
                    (w, ro)
                }
            };
            let (start, end) = (w.0.max(proc_.anchor_s), w.1.max(proc_.anchor_s));
            let ro = ro.max(proc_.anchor_s);
            proc_.extend_past(end.max(ro), th, tl);
            let high_s = proc_.high_time(start, end);
            let len = end - start;
            let fraction = if len > 0.0 {
                (high_s / len).clamp(0.0, 1.0)
            } else if proc_.high_at(start) {
                1.0
            } else {
                0.0
            };
            let high_ro = proc_.high_at(ro);
            let offset = if high_ro { self.offset_step_e } else { 0.0 };
            out.extra_e.push(self.dark_step_e_per_s * high_s + offset);
            out.high_fraction.push(fraction);
            out.high_at_readout.push(high_ro);
            proc_.advance(start.min(ro), th, tl);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg(fraction: f64, tau_high_s: f64, tau_low_s: f64) -> RtsConfig {
        RtsConfig {
            fraction,
            tau_high_s,
            tau_low_s,
            dark_step_e_per_s: 1000.0,
            offset_step_e: 5.0,
        }
    }

    /// Kolmogorov–Smirnov distance between a sample and the exponential CDF of mean τ.
    fn ks_exponential(sample: &mut [f64], tau_s: f64) -> f64 {
        sample.sort_by(|a, b| a.total_cmp(b));
        let n = sample.len() as f64;
        let mut d: f64 = 0.0;
        for (i, &x) in sample.iter().enumerate() {
            let f = 1.0 - (-x / tau_s).exp();
            d = d.max((i as f64 + 1.0) / n - f).max(f - i as f64 / n);
        }
        d
    }

    /// Dwell times (high, low) of one telegraph process over its first `n` switches,
    /// skipping the residual first dwell.
    fn dwell_times(c: &RtsConfig, seed: u64, pixel: u64, n: usize) -> (Vec<f64>, Vec<f64>) {
        let mut t = Telegraph::new(
            stream(seed, Effect::RtsSwitch, 0, pixel),
            c.high_probability(),
            c.tau_high_s,
            c.tau_low_s,
        );
        let (mut high, mut low) = (Vec::new(), Vec::new());
        let mut state = t.anchor_high;
        let mut last = 0.0;
        let mut k = 0;
        while k < n {
            t.extend_past(last, c.tau_high_s, c.tau_low_s);
            let s = *t.switches.iter().find(|&&s| s > last).unwrap();
            if k > 0 {
                if state {
                    high.push(s - last);
                } else {
                    low.push(s - last);
                }
            }
            state = !state;
            last = s;
            t.advance(s, c.tau_high_s, c.tau_low_s);
            k += 1;
        }
        (high, low)
    }

    #[test]
    fn dwell_times_are_exponential_with_the_configured_tau_ks_1_percent() {
        let c = cfg(1.0, 0.02, 0.13);
        let (mut high, mut low) = dwell_times(&c, 11, 4242, 8001);
        // Asymptotic Kolmogorov critical value at α = 1 %: sqrt(−ln(α/2)/2) / sqrt(n).
        let crit = |n: usize| (-(0.005f64).ln() / 2.0).sqrt() / (n as f64).sqrt();
        assert_eq!(high.len(), 4000);
        let d_high = ks_exponential(&mut high, c.tau_high_s);
        let d_low = ks_exponential(&mut low, c.tau_low_s);
        println!(
            "KS: D_high {d_high:.4}, D_low {d_low:.4}, critical {:.4} (n = {})",
            crit(high.len()),
            high.len()
        );
        assert!(d_high < crit(high.len()), "D_high {d_high}");
        assert!(d_low < crit(low.len()), "D_low {d_low}");
        // The test has power: a τ 10 % off is rejected.
        assert!(ks_exponential(&mut high, 1.1 * c.tau_high_s) > crit(high.len()));
        assert!(ks_exponential(&mut low, 0.9 * c.tau_low_s) > crit(low.len()));
    }

    /// Global-shutter frames of `period_s`, integrating the whole period, read at its end.
    fn run_frames(rts: &mut RtsPixels, first: usize, n: usize, period_s: f64) -> Vec<RtsFrame> {
        (first..first + n)
            .map(|k| {
                let t0 = k as f64 * period_s;
                rts.frame(&|_| (t0, t0 + period_s), &|_| t0 + period_s)
            })
            .collect()
    }

    #[test]
    fn high_fraction_is_the_stationary_probability_from_the_first_frame() {
        let c = cfg(1.0, 0.1, 0.3);
        let (rows, cols) = (32, 32);
        let mut rts = RtsPixels::new(&c, rows, cols, 5);
        let n_pix = rts.pixels().len();
        assert_eq!(n_pix, rows * cols);
        let p = c.high_probability();
        let (period, n_frames) = (0.01, 1000);
        let frames = run_frames(&mut rts, 0, n_frames, period);
        // Stationary start: the state at the first readout is Bernoulli(p) over pixels.
        let first = frames[0].high_at_readout.iter().filter(|&&h| h).count() as f64;
        let sigma_first = (p * (1.0 - p) / n_pix as f64).sqrt();
        assert!((first / n_pix as f64 - p).abs() < 4.0 * sigma_first);
        // Time-averaged fraction: variance of a telegraph's time mean over T ≫ τ_c is
        // 2 p (1 − p) τ_c / T, independent over pixels.
        let total_t = period * n_frames as f64;
        let mean: f64 = frames
            .iter()
            .flat_map(|f| f.high_fraction.iter())
            .sum::<f64>()
            / (n_pix * n_frames) as f64;
        let sigma =
            (2.0 * p * (1.0 - p) * c.correlation_time_s() / (total_t * n_pix as f64)).sqrt();
        println!("high fraction {mean:.4} vs p = {p:.4} (σ {sigma:.4})");
        assert!(
            (mean - p).abs() < 4.0 * sigma,
            "mean {mean} p {p} σ {sigma}"
        );
    }

    #[test]
    fn state_autocorrelation_follows_the_two_state_master_equation() {
        let c = cfg(1.0, 0.05, 0.15);
        let mut rts = RtsPixels::new(&c, 16, 64, 9);
        let period = 0.04;
        let frames = run_frames(&mut rts, 0, 400, period);
        let (mut both, mut first) = (0usize, 0usize);
        for w in frames.windows(2) {
            for (a, b) in w[0].high_at_readout.iter().zip(&w[1].high_at_readout) {
                if *a {
                    first += 1;
                    both += usize::from(*b);
                }
            }
        }
        let p = c.high_probability();
        let expected = p + (1.0 - p) * (-period / c.correlation_time_s()).exp();
        let got = both as f64 / first as f64;
        // Binomial error, inflated ×2 for the correlation between successive pairs.
        let sigma = 2.0 * (expected * (1.0 - expected) / first as f64).sqrt();
        println!("P(high | high one frame before) {got:.4} vs {expected:.4}");
        assert!((got - expected).abs() < 4.0 * sigma, "{got} vs {expected}");
    }

    #[test]
    fn charge_is_the_dark_step_times_the_time_high_and_windows_add_up() {
        let c = cfg(1.0, 0.07, 0.11);
        // Rolling shutter: row r integrates [t0 + r·line, t0 + r·line + T], read at the end.
        let (rows, cols, line, t_int) = (8, 8, 1e-3, 0.02);
        let mut split = RtsPixels::new(&c, rows, cols, 3);
        let mut whole = RtsPixels::new(&c, rows, cols, 3);
        // Two half windows vs the whole window: the time high adds up.
        let mut sum = vec![0.0; rows * cols];
        for half in 0..2 {
            let f = split.frame(
                &|r| {
                    let s = r as f64 * line + half as f64 * t_int / 2.0;
                    (s, s + t_int / 2.0)
                },
                &|r| r as f64 * line + t_int,
            );
            for (s, (h, e)) in sum.iter_mut().zip(f.high_fraction.iter().zip(&f.extra_e)) {
                *s += h * t_int / 2.0;
                assert!(*e >= 0.0);
            }
        }
        let f = whole.frame(&|r| (r as f64 * line, r as f64 * line + t_int), &|r| {
            r as f64 * line + t_int
        });
        assert_eq!(sum.len(), rows * cols);
        for (i, &split_s) in sum.iter().enumerate() {
            let high_s = f.high_fraction[i] * t_int;
            assert!((split_s - high_s).abs() < 1e-12);
            let offset = if f.high_at_readout[i] { 5.0 } else { 0.0 };
            assert!((f.extra_e[i] - (1000.0 * high_s + offset)).abs() < 1e-9);
        }
    }

    #[test]
    fn a_run_starting_at_frame_k_replays_the_states_exactly() {
        let c = cfg(0.05, 0.03, 0.08);
        let period = 0.02;
        let mut full = RtsPixels::new(&c, 40, 50, 77);
        let all = run_frames(&mut full, 0, 30, period);
        let mut late = RtsPixels::new(&c, 40, 50, 77);
        late.advance_to(12.0 * period);
        let tail = run_frames(&mut late, 12, 18, period);
        assert_eq!(&all[12..], &tail[..]);
        // Another seed gives another realisation.
        let mut other = RtsPixels::new(&c, 40, 50, 78);
        assert_ne!(other.pixels(), full.pixels());
        let _ = run_frames(&mut other, 0, 1, period);
    }

    #[test]
    fn the_fraction_of_rts_pixels_is_the_configured_one() {
        let c = cfg(0.01, 0.1, 0.1);
        let rts = RtsPixels::new(&c, 200, 300, 1);
        let n = 60_000.0;
        let sigma = (n * 0.01 * 0.99f64).sqrt();
        assert!((rts.pixels().len() as f64 - 600.0).abs() < 4.0 * sigma);
        assert!(rts.pixels().windows(2).all(|w| w[0] < w[1]));
        assert!(RtsPixels::new(&cfg(0.0, 1.0, 1.0), 10, 10, 1)
            .pixels()
            .is_empty());
    }

    #[test]
    fn bad_parameters_are_errors_naming_the_field() {
        let bad = |c: RtsConfig, field: &str| {
            let e = c.validate().unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        };
        let ok = cfg(0.01, 0.1, 0.2);
        ok.validate().unwrap();
        bad(
            RtsConfig {
                fraction: 1.5,
                ..ok.clone()
            },
            "detector.rts.fraction",
        );
        bad(
            RtsConfig {
                fraction: f64::NAN,
                ..ok.clone()
            },
            "detector.rts.fraction",
        );
        bad(
            RtsConfig {
                tau_high_s: -1.0,
                ..ok.clone()
            },
            "detector.rts.tau_high_s",
        );
        bad(
            RtsConfig {
                tau_low_s: 0.0,
                ..ok.clone()
            },
            "detector.rts.tau_low_s",
        );
        bad(
            RtsConfig {
                dark_step_e_per_s: -3.0,
                ..ok.clone()
            },
            "detector.rts.dark_step_e_per_s",
        );
        bad(
            RtsConfig {
                dark_step_e_per_s: 0.0,
                offset_step_e: 0.0,
                ..ok.clone()
            },
            "detector.rts.dark_step_e_per_s",
        );
        let unknown: std::result::Result<RtsConfig, _> = toml::from_str("tau_hi_s = 1.0");
        assert!(unknown.is_err());
        let parsed: RtsConfig = toml::from_str("offset_step_e = 3.0").unwrap();
        assert_eq!(parsed.fraction, 0.001);
        parsed.validate().unwrap();
    }

    /// Median ms per 640 × 512 frame (rolling shutter), 1 % RTS pixels:
    /// `cargo test --release --lib detector::rts::tests::bench -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn bench_rts_640x512() {
        let c = cfg(0.01, 0.05, 0.5);
        let mut rts = RtsPixels::new(&c, 512, 640, 1);
        let mut times = Vec::new();
        for k in 0..200 {
            let t0 = k as f64 / 30.0;
            let s = std::time::Instant::now();
            let f = rts.frame(
                &|r| (t0 + r as f64 * 2e-5, t0 + r as f64 * 2e-5 + 0.01),
                &|r| t0 + r as f64 * 2e-5 + 0.01,
            );
            std::hint::black_box(&f);
            times.push(s.elapsed().as_secs_f64() * 1e3);
        }
        times.sort_by(|a, b| a.total_cmp(b));
        println!(
            "rts: {} pixels, median {:.4} ms/frame",
            rts.pixels().len(),
            times[100]
        );
    }
}
