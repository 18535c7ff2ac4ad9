//! Readout-ordered correlated noise and crosstalk between outputs (`[detector.readout_noise]`,
//! docs/focal-plane.md).
//!
//! The noise of a read-out integrated circuit is a time series: 1/f ("pink") noise in the
//! output amplifiers and the shared bias is sampled one pixel per clock tick, so a
//! fluctuation slower than a row becomes an offset of a whole row (row banding). This module
//! generates that noise in pixel-clock order, as the NGHXRG model does (Rauscher et al.
//! 2015, "NGHXRG — a noise generator for Teledyne HxRG detector arrays", PASP 127, 1144),
//! then lays it out as an image.
//!
//! **Clock and layout.** The array has `outputs` outputs; output o reads the column stripe
//! `[o·w, (o+1)·w)` with `w = cols / outputs`, all outputs in step (one pixel each per tick
//! of `pixel_time_s`). Rows are read from row 0 down; within a row output o reads its
//! stripe from its left edge to the right (column o·w first), or — with
//! `alternate_read_direction` — odd outputs read right to left (mirrored stripes, as the
//! HxRG's alternating fast-scan direction). After the w pixels of a row come
//! `row_overhead_px` idle ticks, and after the last row `frame_overhead_rows` idle rows, so
//! one frame is `N = (w + row_overhead_px)·(rows + frame_overhead_rows)` ticks and pixel
//! (r, j-th read of its stripe) is read at tick `r·(w + row_overhead_px) + j`.
//!
//! **Components** (each off when its amplitude is 0 or absent; each from its own random
//! stream, `super::rng`): uncorrelated pink noise, one series per output; correlated pink
//! noise, one series common to all outputs (the same value at the same tick); alternating-
//! column noise (ACN), two independent pink series per output, one for the even and one for
//! the odd columns, sampled every second tick; and a white per-row offset (the whole row,
//! all outputs). The white read noise (`detector.read_noise_e`) is not here: it is white in
//! any order and the detector adds it.
//!
//! **Pink spectrum.** A pink series has the one-sided power spectral density
//! `S(f) = A²/f` (A the noise density at 1 Hz, e⁻/√Hz) between `f_lo = 1/T` (T the frame
//! readout time, [`ReadoutNoiseConfig::frame_readout_s`]) and the Nyquist frequency `f_N`
//! of its sampling, and 0 below `f_lo` (slower drifts are not modelled: frames are
//! independent). So its variance is `σ² = ∫ S df = A²·ln(f_N/f_lo)`, i.e. `A²·ln(N/2)` for a
//! series sampled every tick and `A²·ln(N/4)` for the ACN series sampled every second tick;
//! an amplitude given as σ per frame is turned into A with that relation. The series is
//! drawn in the Fourier domain (Timmer & König 1995, A&A 300, 707: independent Gaussian
//! real and imaginary parts per frequency bin, with the variance of the PSD integrated over
//! the bin), inverted with one real FFT on a grid of L ≥ 2N samples, and the first N
//! samples kept, so the series is not periodic over the frame (NGHXRG also generates twice
//! the length and keeps half). The periodic series' covariance at lag τ is the model's,
//! `A²·[ln(N/2) − Cin(πτ) + Cin(2πτ/N)]`, with the lags τ + mL aliased onto it: within
//! 1.1 % of the variance at every lag of the frame with L = 2N (a grid of 1.25 N: 4.4 %;
//! `pink_covariance_over_the_frame_matches_the_model_at_every_lag`). The draws and the
//! FFT are in single precision (relative rounding ≈ 6e-8 of the noise, far below any
//! effect on its statistics), which halves their cost.

use std::cell::RefCell;

use ndarray::{Array2, ArrayView1, ArrayViewMut1, Axis};
use num_complex::Complex;
use rand::RngExt;
use rand_distr::StandardNormal;
use rand_xoshiro::Xoshiro256PlusPlus;
use rayon::prelude::*;
use realfft::RealFftPlanner;
use serde::{Deserialize, Serialize};

use super::rng::{temporal_stream, Effect};
use crate::error::{require_non_negative, require_positive, Error, Result};

/// Largest number of clock ticks per frame accepted (the pink series and its FFT grid are
/// held in memory: 2³¹ ticks is already 16 GiB of f64 per series).
pub const MAX_TICKS_PER_FRAME: usize = 1 << 31;

/// Largest |coupling| accepted in `output_crosstalk` (a coupling of 1 or more would make
/// the victim respond more to another output than to its own pixel).
pub const MAX_CROSSTALK: f64 = 1.0;

fn default_outputs() -> usize {
    1
}

/// `[detector.readout_noise]`: correlated noise generated in pixel-clock order and the
/// electronic crosstalk between outputs (module docs for the clock and the layout).
///
/// Each pink amplitude may be given either as σ per frame (`*_sigma_e`) or as a noise
/// density at 1 Hz (`*_density_e_per_sqrt_hz`), not both (giving both is an error); they
/// are related by `σ² = A²·ln(N/2)`, N the ticks per frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReadoutNoiseConfig {
    /// Number of outputs (parallel read channels), ≥ 1, dividing `detector.cols`; output o
    /// reads the column stripe `[o·cols/outputs, (o+1)·cols/outputs)`. Default 1.
    #[serde(default = "default_outputs")]
    pub outputs: usize,
    /// Time per pixel (one clock tick), seconds, > 0.
    pub pixel_time_s: f64,
    /// Idle clock ticks after each row of a stripe (line overhead), pixels. Default 0.
    #[serde(default)]
    pub row_overhead_px: usize,
    /// Idle rows after the last row of a frame (frame overhead), rows. Default 0.
    #[serde(default)]
    pub frame_overhead_rows: usize,
    /// Odd outputs read their stripe right to left (mirrored), even outputs left to right.
    /// Default false (every output left to right).
    #[serde(default)]
    pub alternate_read_direction: bool,
    /// Uncorrelated pink noise (one independent series per output) as σ per frame, e⁻.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pink_sigma_e: Option<f64>,
    /// Uncorrelated pink noise as a density at 1 Hz, e⁻/√Hz (instead of `pink_sigma_e`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pink_density_e_per_sqrt_hz: Option<f64>,
    /// Correlated pink noise (one series common to all outputs) as σ per frame, e⁻.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub correlated_pink_sigma_e: Option<f64>,
    /// Correlated pink noise as a density at 1 Hz, e⁻/√Hz (instead of
    /// `correlated_pink_sigma_e`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub correlated_pink_density_e_per_sqrt_hz: Option<f64>,
    /// Alternating-column noise: σ per frame, e⁻, of each of the two independent pink
    /// series (even columns, odd columns) of every output. Default 0.
    #[serde(default)]
    pub alternating_column_sigma_e: f64,
    /// Temporal per-row offset: rms, e⁻, of a white offset drawn per row and frame, common
    /// to the whole row. Default 0.
    #[serde(default)]
    pub row_sigma_e: f64,
    /// Crosstalk between outputs: `outputs × outputs` matrix M, `M[o][p]` the fraction of
    /// output p's pixel that appears in output o's pixel read at the same tick (row =
    /// victim, column = aggressor); the diagonal must be 0. Absent = no crosstalk.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output_crosstalk: Option<Vec<Vec<f64>>>,
}

/// Field name under `detector.readout_noise`.
fn field(name: &str) -> String {
    format!("detector.readout_noise.{name}")
}

/// σ or density of one pink component: non-negative, finite, and not both.
fn validate_pink(
    sigma_name: &str,
    sigma: Option<f64>,
    density_name: &str,
    density: Option<f64>,
) -> Result<()> {
    if let Some(s) = sigma {
        require_non_negative(&field(sigma_name), s)?;
    }
    if let Some(a) = density {
        require_non_negative(&field(density_name), a)?;
        if sigma.is_some() {
            return Err(Error::param(
                field(density_name),
                a,
                format!("absent when {sigma_name} is given (give the amplitude one way only)"),
            ));
        }
    }
    Ok(())
}

impl ReadoutNoiseConfig {
    /// Checks every field against an array of `rows × cols` pixels: `outputs` ≥ 1 divides
    /// `cols`, `pixel_time_s` > 0, amplitudes finite and ≥ 0 (each pink amplitude given at
    /// most one way), a frame of at most [`MAX_TICKS_PER_FRAME`] ticks, and the crosstalk
    /// matrix `outputs × outputs`, finite, |M| < [`MAX_CROSSTALK`], zero diagonal.
    pub fn validate(&self, rows: usize, cols: usize) -> Result<()> {
        if self.outputs == 0 || cols % self.outputs != 0 {
            return Err(Error::param(
                field("outputs"),
                self.outputs,
                format!("an integer >= 1 that divides detector.cols = {cols}"),
            ));
        }
        require_positive(&field("pixel_time_s"), self.pixel_time_s)?;
        let ticks = (cols / self.outputs)
            .checked_add(self.row_overhead_px)
            .and_then(|s| s.checked_mul(rows.checked_add(self.frame_overhead_rows)?));
        match ticks {
            Some(t) if t <= MAX_TICKS_PER_FRAME => {}
            _ => {
                return Err(Error::param(
                    field("row_overhead_px"),
                    self.row_overhead_px,
                    format!(
                        "a frame of (cols/outputs + row_overhead_px)·(rows + frame_overhead_rows) \
                         <= {MAX_TICKS_PER_FRAME} clock ticks"
                    ),
                ))
            }
        }
        validate_pink(
            "pink_sigma_e",
            self.pink_sigma_e,
            "pink_density_e_per_sqrt_hz",
            self.pink_density_e_per_sqrt_hz,
        )?;
        validate_pink(
            "correlated_pink_sigma_e",
            self.correlated_pink_sigma_e,
            "correlated_pink_density_e_per_sqrt_hz",
            self.correlated_pink_density_e_per_sqrt_hz,
        )?;
        require_non_negative(
            &field("alternating_column_sigma_e"),
            self.alternating_column_sigma_e,
        )?;
        require_non_negative(&field("row_sigma_e"), self.row_sigma_e)?;
        if let Some(m) = &self.output_crosstalk {
            let n = self.outputs;
            if m.len() != n {
                return Err(Error::param(
                    field("output_crosstalk"),
                    format!("{} rows", m.len()),
                    format!("an outputs × outputs matrix ({n} rows of {n})"),
                ));
            }
            for (o, row) in m.iter().enumerate() {
                if row.len() != n {
                    return Err(Error::param(
                        field(&format!("output_crosstalk[{o}]")),
                        format!("{} entries", row.len()),
                        format!("{n} entries (one per output)"),
                    ));
                }
                for (p, &c) in row.iter().enumerate() {
                    let name = field(&format!("output_crosstalk[{o}][{p}]"));
                    if !(c.is_finite() && c.abs() < MAX_CROSSTALK) {
                        return Err(Error::param(name, c, "a finite coupling in (-1, 1)"));
                    }
                    if o == p && c != 0.0 {
                        return Err(Error::param(
                            name,
                            c,
                            "0 (the diagonal: an output does not couple into itself)",
                        ));
                    }
                }
            }
        }
        Ok(())
    }

    /// Seconds to read one frame, overheads included:
    /// `(cols/outputs + row_overhead_px)·(rows + frame_overhead_rows)·pixel_time_s`.
    pub fn frame_readout_s(&self, rows: usize, cols: usize) -> f64 {
        let w = cols / self.outputs.max(1);
        ((w + self.row_overhead_px) as f64)
            * ((rows + self.frame_overhead_rows) as f64)
            * self.pixel_time_s
    }

    /// Seconds from the start of a frame's readout to the read of pixel (`row`, `col`) of
    /// an array `cols` wide (the tick of that pixel times `pixel_time_s`).
    pub fn pixel_read_time_s(&self, cols: usize, row: usize, col: usize) -> f64 {
        let g = Clock::new(self, 0, cols);
        (g.tick(row, col) as f64) * self.pixel_time_s
    }
}

/// The pixel clock of one array: stripe width, ticks per row and per frame.
#[derive(Debug, Clone, Copy)]
struct Clock {
    outputs: usize,
    width: usize,
    stride: usize,
    ticks: usize,
    mirrored: bool,
}

impl Clock {
    fn new(cfg: &ReadoutNoiseConfig, rows: usize, cols: usize) -> Clock {
        let outputs = cfg.outputs.max(1);
        let width = cols / outputs;
        let stride = width + cfg.row_overhead_px;
        Clock {
            outputs,
            width,
            stride,
            ticks: stride * (rows + cfg.frame_overhead_rows),
            mirrored: cfg.alternate_read_direction,
        }
    }

    /// `true` when output `o` reads its stripe right to left.
    fn reversed(&self, o: usize) -> bool {
        self.mirrored && o % 2 == 1
    }

    /// Output and position in the read of a row of column `col`.
    fn output_and_read(&self, col: usize) -> (usize, usize) {
        let o = col / self.width.max(1);
        let k = col - o * self.width;
        let j = if self.reversed(o) {
            self.width - 1 - k
        } else {
            k
        };
        (o, j)
    }

    /// Tick at which pixel (`row`, `col`) is read.
    fn tick(&self, row: usize, col: usize) -> usize {
        row * self.stride + self.output_and_read(col).1
    }
}

/// A pink series of `len` samples, each `step` ticks apart, in a frame of `frame_ticks`
/// ticks: PSD A²/f from f_lo = 1/(frame_ticks·dt) to the Nyquist frequency 1/(2·step·dt).
#[derive(Debug, Clone, Copy, PartialEq)]
struct PinkSeries {
    len: usize,
    step: usize,
    frame_ticks: usize,
}

impl PinkSeries {
    /// `ln(f_N/f_lo) = ln(frame_ticks/(2·step))`: the variance per unit density² (0 when
    /// the band is empty).
    fn log_band(&self) -> f64 {
        (self.frame_ticks as f64 / (2.0 * self.step as f64))
            .ln()
            .max(0.0)
    }

    /// Density A, e⁻/√Hz, of an amplitude given as σ or as A.
    fn density(&self, sigma: Option<f64>, density: Option<f64>) -> f64 {
        match (sigma, density) {
            (_, Some(a)) => a,
            (Some(s), None) => {
                let band = self.log_band();
                if band > 0.0 {
                    s / band.sqrt()
                } else {
                    0.0
                }
            }
            (None, None) => 0.0,
        }
    }

    /// Length L of the FFT grid: the smallest even 5-smooth length ≥ 2·len
    /// ([`crate::fft_size::next_fast_even_len`]), so the kept `len` samples do not wrap
    /// around (module docs).
    fn grid_len(&self) -> usize {
        crate::fft_size::next_fast_even_len(2 * self.len)
    }

    /// Standard deviation per unit density of each bin's Gaussian parts (the bin table).
    ///
    /// On the FFT grid of L samples (frequency step Δf = 1/(L·step·dt)), bin k covers
    /// [(k − ½)Δf, (k + ½)Δf] ∩ [f_lo, f_N] and gets the variance
    /// `P_k = ∫ A²/f df = A²·ln(hi/lo)` over that band: split evenly between the ±k
    /// complex amplitudes (each Gaussian real and imaginary parts of variance P_k/4, so a
    /// standard deviation `½·√ln(hi/lo)` per unit A), the Nyquist bin real with variance
    /// P_k. Bins wholly below f_lo get 0. The table depends only on the series' shape,
    /// not on the density or the draws, so it is computed once per shape and thread.
    fn bin_table(&self) -> BinTable {
        self.bin_table_on(self.grid_len())
    }

    /// [`PinkSeries::bin_table`] on a grid of `l` samples (even, ≥ 2).
    fn bin_table_on(&self, l: usize) -> BinTable {
        let half = l / 2;
        // In units of Δf: f_lo = L·step/frame_ticks, f_N = L/2.
        let lo_bins = (l * self.step) as f64 / self.frame_ticks as f64;
        let mut sd = vec![0.0f32; half + 1];
        let mut first = half + 1;
        for (k, s) in sd.iter_mut().enumerate().skip(1) {
            let hi = (k as f64 + 0.5).min(half as f64);
            let lo = (k as f64 - 0.5).max(lo_bins);
            if hi <= lo {
                continue;
            }
            first = first.min(k);
            let band = log_ratio(hi, lo);
            *s = if k < half {
                (0.5 * band.sqrt()) as f32
            } else {
                band.sqrt() as f32
            };
        }
        BinTable {
            series: *self,
            first,
            sd,
        }
    }

    /// One realisation with density `a`, drawn from `rng`, written into `dst` (`len`
    /// samples).
    ///
    /// Each bin k ≥ the first in the band (DC and the bins below f_lo stay 0 and draw
    /// nothing) takes its real then its imaginary part from `rng` (the Nyquist bin only a
    /// real part), scaled by `a` times the bin table's standard deviation
    /// ([`PinkSeries::bin_table`], Timmer & König 1995); the unnormalised inverse real FFT
    /// then gives a stationary series of variance Σ P_k = A²·ln(f_N/f_lo) exactly, and the
    /// first `len` of its L samples are kept. The plan, the table and the buffers are the
    /// thread's own ([`Synthesis`]), reused from series to series and frame to frame.
    fn draw_into(&self, a: f64, rng: &mut Xoshiro256PlusPlus, dst: &mut [f32]) {
        SYNTHESIS.with(|s| s.borrow_mut().draw(self, a, rng, dst));
    }
}

/// The bin table of one series shape ([`PinkSeries::bin_table`]).
struct BinTable {
    series: PinkSeries,
    /// First bin with a non-zero standard deviation (`sd.len()` if none).
    first: usize,
    /// Standard deviation per unit density of each bin's real and imaginary parts.
    sd: Vec<f32>,
}

/// Bin tables kept per thread (a frame uses at most two shapes: every tick and every
/// second tick).
const MAX_TABLES: usize = 4;

/// One thread's tools for drawing pink series: the real-FFT planner (plans cached by
/// length), the bin tables of the last shapes drawn, and the spectrum, grid and FFT
/// scratch buffers, reused so that a frame allocates nothing per series.
#[derive(Default)]
struct Synthesis {
    planner: RealFftPlanner<f32>,
    tables: Vec<BinTable>,
    spectrum: Vec<Complex<f32>>,
    grid: Vec<f32>,
    scratch: Vec<Complex<f32>>,
}

impl Synthesis {
    /// [`PinkSeries::draw_into`] with this thread's plan, table and buffers.
    fn draw(&mut self, series: &PinkSeries, a: f64, rng: &mut Xoshiro256PlusPlus, dst: &mut [f32]) {
        let Synthesis {
            planner,
            tables,
            spectrum,
            grid,
            scratch,
        } = self;
        let t = match tables.iter().position(|t| t.series == *series) {
            Some(i) => i,
            None => {
                if tables.len() == MAX_TABLES {
                    tables.remove(0);
                }
                tables.push(series.bin_table());
                tables.len() - 1
            }
        };
        let table = &tables[t];
        let l = series.grid_len();
        let half = l / 2;
        let a = a as f32;
        // Every bin from `first` on is written below; only those before it are cleared
        // (the inverse FFT uses the spectrum as workspace).
        spectrum.resize(half + 1, Complex::new(0.0, 0.0));
        let first = table.first.min(half + 1);
        spectrum[..first].fill(Complex::new(0.0, 0.0));
        for (s, &sd) in spectrum[first..half].iter_mut().zip(&table.sd[first..half]) {
            let amp = a * sd;
            let re: f32 = rng.sample(StandardNormal);
            let im: f32 = rng.sample(StandardNormal);
            *s = Complex::new(amp * re, amp * im);
        }
        if first <= half {
            let re: f32 = rng.sample(StandardNormal);
            spectrum[half] = Complex::new(a * table.sd[half] * re, 0.0);
        }
        let plan = planner.plan_fft_inverse(l);
        grid.resize(l, 0.0);
        scratch.resize(plan.get_scratch_len(), Complex::new(0.0, 0.0));
        // The DC and Nyquist imaginary parts are exactly 0 (set above), the only
        // condition under which realfft's inverse can fail; if it ever did, the series
        // would stay 0 rather than panic.
        if plan.process_with_scratch(spectrum, grid, scratch).is_err() {
            grid.iter_mut().for_each(|v| *v = 0.0);
        }
        let n = dst.len().min(series.len).min(l);
        dst[..n].copy_from_slice(&grid[..n]);
    }
}

/// `ln(hi/lo)` for 0 < lo < hi. For the interior bins (hi − lo = 1, lo ≥ 8) the series
/// `ln((k+½)/(k−½)) = 2·atanh(x) = 2(x + x³/3 + x⁵/5 + x⁷/7 + …)`, x = 1/(2k) ≤ 1/17, whose
/// first omitted term is below 1e-10 of the sum: a logarithm per bin would cost more than
/// the FFT.
fn log_ratio(hi: f64, lo: f64) -> f64 {
    if hi - lo == 1.0 && lo >= 8.0 {
        let x = 1.0 / (hi + lo);
        let x2 = x * x;
        2.0 * x * (1.0 + x2 * (1.0 / 3.0 + x2 * (1.0 / 5.0 + x2 * (1.0 / 7.0))))
    } else {
        (hi / lo).ln()
    }
}

thread_local! {
    /// Each thread's plans, bin tables and buffers for the pink series.
    static SYNTHESIS: RefCell<Synthesis> = RefCell::new(Synthesis::default());
}

/// One pink series to draw: its stream and its density.
struct Job {
    effect: Effect,
    key: u64,
    series: PinkSeries,
    density: f64,
}

/// Zero-mean correlated readout noise of one frame, e⁻ per pixel, generated in pixel-clock
/// order (NGHXRG, Rauscher et al. 2015 PASP 127 1144). Does NOT include the white read
/// noise (`detector.read_noise_e`, added by the detector; white in any order).
///
/// Each component comes from its own stream `(seed, effect, exposure, frame, key)`, so the
/// same arguments give bit-identical frames whatever the number of threads, and switching
/// one component on or off does not change another. All amplitudes 0 gives zeros (and
/// draws nothing). `cfg` must have passed [`ReadoutNoiseConfig::validate`] for this
/// `rows × cols`; a shape it would refuse (cols not a multiple of outputs) gives zeros.
pub fn readout_noise_e(
    cfg: &ReadoutNoiseConfig,
    rows: usize,
    cols: usize,
    seed: u64,
    exposure: u64,
    frame: u64,
) -> Array2<f64> {
    let mut out = Array2::zeros((rows, cols));
    if rows == 0 || cols == 0 || cfg.outputs == 0 || cols % cfg.outputs != 0 {
        return out;
    }
    let clock = Clock::new(cfg, rows, cols);
    let full = PinkSeries {
        len: clock.ticks,
        step: 1,
        frame_ticks: clock.ticks,
    };
    let halfrate = PinkSeries {
        len: clock.ticks.div_ceil(2),
        step: 2,
        frame_ticks: clock.ticks,
    };
    let pink = full.density(cfg.pink_sigma_e, cfg.pink_density_e_per_sqrt_hz);
    let correlated = full.density(
        cfg.correlated_pink_sigma_e,
        cfg.correlated_pink_density_e_per_sqrt_hz,
    );
    let acn = halfrate.density(Some(cfg.alternating_column_sigma_e), None);

    let mut jobs = Vec::new();
    if pink > 0.0 {
        for o in 0..clock.outputs {
            jobs.push(Job {
                effect: Effect::ReadoutPink,
                key: o as u64,
                series: full,
                density: pink,
            });
        }
    }
    if correlated > 0.0 {
        jobs.push(Job {
            effect: Effect::ReadoutCorrelatedPink,
            key: 0,
            series: full,
            density: correlated,
        });
    }
    if acn > 0.0 {
        for key in 0..2 * clock.outputs as u64 {
            jobs.push(Job {
                effect: Effect::ReadoutAlternatingColumn,
                key,
                series: halfrate,
                density: acn,
            });
        }
    }
    if jobs.is_empty() && cfg.row_sigma_e == 0.0 {
        return out;
    }
    // One buffer for every series, cut into one slice per job; each job's stream depends
    // only on its key, so the thread that draws it does not matter.
    let mut buffer = vec![0.0f32; jobs.iter().map(|j| j.series.len).sum()];
    let mut slices: Vec<&mut [f32]> = Vec::with_capacity(jobs.len());
    let mut rest = buffer.as_mut_slice();
    for j in &jobs {
        let (head, tail) = rest.split_at_mut(j.series.len);
        slices.push(head);
        rest = tail;
    }
    jobs.par_iter()
        .zip(slices.into_par_iter())
        .for_each(|(j, dst)| {
            let mut rng = temporal_stream(seed, j.effect, exposure, frame, j.key);
            j.series.draw_into(j.density, &mut rng, dst);
        });
    let mut series = Vec::with_capacity(jobs.len());
    let mut rest = buffer.as_slice();
    for j in &jobs {
        let (head, tail) = rest.split_at(j.series.len);
        series.push(head);
        rest = tail;
    }
    let mut it = series.into_iter();
    let pink_s: Vec<&[f32]> = if pink > 0.0 {
        it.by_ref().take(clock.outputs).collect()
    } else {
        Vec::new()
    };
    let corr_s: Option<&[f32]> = if correlated > 0.0 { it.next() } else { None };
    let acn_s: Vec<&[f32]> = it.collect();

    let row_offset: Vec<f64> = if cfg.row_sigma_e > 0.0 {
        let mut rng = temporal_stream(seed, Effect::ReadoutRow, exposure, frame, 0);
        (0..rows)
            .map(|_| cfg.row_sigma_e * rng.sample::<f64, _>(StandardNormal))
            .collect()
    } else {
        vec![0.0; rows]
    };

    out.axis_iter_mut(Axis(0))
        .into_par_iter()
        .enumerate()
        .for_each(|(r, mut line)| {
            with_row_slice(&mut line, |line| {
                let base = r * clock.stride;
                let w = clock.width;
                for (o, stripe) in line.chunks_exact_mut(w).enumerate() {
                    // Position k of the stripe is the output's read j = k, or w − 1 − k
                    // when it reads right to left: its tick is base + j.
                    let reversed = clock.reversed(o);
                    let mut add = |s: &[f32]| {
                        let s = &s[base..base + w];
                        if reversed {
                            for (v, x) in stripe.iter_mut().zip(s.iter().rev()) {
                                *v += f64::from(*x);
                            }
                        } else {
                            for (v, x) in stripe.iter_mut().zip(s) {
                                *v += f64::from(*x);
                            }
                        }
                    };
                    if let Some(s) = pink_s.get(o) {
                        add(s);
                    }
                    if let Some(s) = corr_s {
                        add(s);
                    }
                    if let (Some(even), Some(odd)) = (acn_s.get(2 * o), acn_s.get(2 * o + 1)) {
                        // Column o·w + k has the parity of (o·w + k); tick t takes
                        // sample ⌊t/2⌋ of that parity's series.
                        for (k, v) in stripe.iter_mut().enumerate() {
                            let j = if reversed { w - 1 - k } else { k };
                            let s = if (o * w + k) % 2 == 0 { even } else { odd };
                            *v += f64::from(s[(base + j) / 2]);
                        }
                    }
                    for v in stripe.iter_mut() {
                        *v += row_offset[r];
                    }
                }
            });
        });
    out
}

/// Runs `f` on the row `line` as a contiguous slice (a copy when the view is strided).
fn with_row_slice(line: &mut ArrayViewMut1<f64>, f: impl FnOnce(&mut [f64])) {
    if let Some(s) = line.as_slice_mut() {
        f(s);
    } else {
        let mut copy = line.to_vec();
        f(&mut copy);
        line.assign(&ArrayView1::from(&copy[..]));
    }
}

/// Electronic crosstalk between outputs: every pixel gets Σ_p M[o][p]·v_p of the pixels
/// read at the same clock step by the other outputs. No-op when the matrix is absent.
///
/// `v_p` are the values before any crosstalk (the matrix is applied once, not iterated), so
/// a pixel of output p read at tick t adds `M[o][p]·v` to the pixel output o reads at t
/// (same row, same position in the read of the stripe; with `alternate_read_direction` the
/// mirrored column). `cfg` must have passed [`ReadoutNoiseConfig::validate`] for this
/// array's width; a shape it would refuse leaves `values_e` unchanged.
pub fn apply_output_crosstalk(cfg: &ReadoutNoiseConfig, values_e: &mut Array2<f64>) {
    let Some(m) = &cfg.output_crosstalk else {
        return;
    };
    let (rows, cols) = values_e.dim();
    let n = cfg.outputs;
    if n == 0 || cols % n != 0 || m.len() != n || m.iter().any(|r| r.len() != n) {
        return;
    }
    let couplings: Vec<(usize, usize, f64)> = (0..n)
        .flat_map(|o| (0..n).map(move |p| (o, p)))
        .filter(|&(o, p)| o != p && m[o][p] != 0.0)
        .map(|(o, p)| (o, p, m[o][p]))
        .collect();
    if couplings.is_empty() {
        return;
    }
    let clock = Clock::new(cfg, rows, cols);
    let w = clock.width;
    values_e
        .axis_iter_mut(Axis(0))
        .into_par_iter()
        .for_each_init(Vec::new, |src, mut line| {
            with_row_slice(&mut line, |line| {
                src.clear();
                src.extend_from_slice(line);
                // Position k of output o's stripe is read at the tick when output p reads
                // position k of its own stripe if both read in the same direction, and
                // position w − 1 − k if one of them is mirrored. For each victim pixel
                // the couplings are added in the matrix's order.
                for &(o, p, c) in &couplings {
                    let from = &src[p * w..(p + 1) * w];
                    let to = &mut line[o * w..(o + 1) * w];
                    if clock.reversed(o) == clock.reversed(p) {
                        for (v, x) in to.iter_mut().zip(from) {
                            *v += c * x;
                        }
                    } else {
                        for (v, x) in to.iter_mut().zip(from.iter().rev()) {
                            *v += c * x;
                        }
                    }
                }
            });
        });
}

#[cfg(test)]
#[path = "readout_tests.rs"]
mod tests;
