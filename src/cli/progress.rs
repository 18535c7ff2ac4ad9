//! One progress bar over a whole run: imaging (per band), exposure (per frame),
//! calibration and writing, with elapsed time, ETA and a frame counter. Silent when stderr
//! is not a terminal or with `--quiet`.
//!
//! The bar counts work in *band-equivalents*: imaging one band of one frame is one unit,
//! and, measured on the demo (384 × 288, both scale with the pixel count), exposing one
//! frame costs about as much as imaging one band (≈ 0.05 s each). The library reports only
//! imaging bands, so the later stages are estimated: exposure one unit per frame,
//! calibration one unit per exposure it makes (levels × frames per level for the NUC, as
//! many again for the non-uniformity check, twice that for the measured NETD), writing
//! [`WRITE_UNITS`]. While a stage the library does not report is running, the bar advances
//! at the rate measured during imaging and never past the end of that stage, so the ETA
//! stays an estimate, not a promise.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

/// Units given to writing the products.
pub const WRITE_UNITS: u64 = 4;

/// The progress of one run.
pub struct RunProgress {
    bar: Option<ProgressBar>,
    frames: usize,
    exposure_units: u64,
    calibration_units: u64,
    imaging_total: Option<u64>,
    imaging_started: Instant,
    ticker: Option<(Arc<AtomicBool>, JoinHandle<()>)>,
}

impl RunProgress {
    /// A bar for a run of `frames` frames; `calibration_exposures` is the number of frame
    /// exposures the calibration makes (0 without calibration). `None`-like (silent) when
    /// `quiet` or stderr is not a terminal.
    pub fn new(quiet: bool, frames: usize, calibration_exposures: u64) -> RunProgress {
        use std::io::IsTerminal;
        let bar = if quiet || !std::io::stderr().is_terminal() {
            None
        } else {
            let pb = ProgressBar::new(1);
            if let Ok(style) = ProgressStyle::with_template(
                "{msg:<28} [{bar:36}] {percent:>3}% ({elapsed}, ETA {eta})",
            ) {
                pb.set_style(style.progress_chars("=> "));
            }
            pb.set_message("imaging");
            Some(pb)
        };
        RunProgress {
            bar,
            frames: frames.max(1),
            exposure_units: frames.max(1) as u64,
            calibration_units: calibration_exposures,
            imaging_total: None,
            imaging_started: Instant::now(),
            ticker: None,
        }
    }

    /// The library's imaging callback: `done` of `total` bands (over all frames).
    pub fn imaging(&mut self, done: usize, total: usize) {
        let Some(bar) = &self.bar else { return };
        let total = total as u64;
        if self.imaging_total.is_none() {
            self.imaging_total = Some(total);
            self.imaging_started = Instant::now();
            bar.set_length(total + self.exposure_units + self.calibration_units + WRITE_UNITS);
        }
        let per_frame = (total / self.frames as u64).max(1);
        let frame = ((done as u64).saturating_sub(1) / per_frame + 1).min(self.frames as u64);
        bar.set_message(format!("imaging frame {frame}/{}", self.frames));
        bar.set_position(done as u64);
        if done as u64 >= total {
            self.start_estimated_stage();
        }
    }

    /// After imaging: exposure and calibration run inside the library without reports;
    /// advance at the imaging rate up to the end of those stages.
    fn start_estimated_stage(&mut self) {
        let (Some(bar), Some(total)) = (self.bar.clone(), self.imaging_total) else {
            return;
        };
        if self.ticker.is_some() {
            return;
        }
        let per_unit = self.imaging_started.elapsed().as_secs_f64() / total.max(1) as f64;
        let (start, exp, cal) = (total, self.exposure_units, self.calibration_units);
        let frames = self.frames;
        let stop = Arc::new(AtomicBool::new(false));
        let stop2 = stop.clone();
        let t0 = Instant::now();
        let handle = std::thread::spawn(move || {
            while !stop2.load(Ordering::Relaxed) {
                let units = if per_unit > 0.0 {
                    (t0.elapsed().as_secs_f64() / per_unit) as u64
                } else {
                    0
                };
                let units = units.min(exp + cal);
                if units < exp {
                    bar.set_message(format!("exposing frame {}/{frames}", units + 1));
                } else {
                    bar.set_message("calibrating (NUC, NETD)".to_string());
                }
                bar.set_position(start + units);
                std::thread::sleep(Duration::from_millis(100));
            }
        });
        self.ticker = Some((stop, handle));
    }

    fn stop_ticker(&mut self) {
        if let Some((stop, handle)) = self.ticker.take() {
            stop.store(true, Ordering::Relaxed);
            let _ = handle.join();
        }
    }

    /// The library returned: the writing stage begins.
    pub fn writing(&mut self) {
        self.stop_ticker();
        if let Some(bar) = &self.bar {
            let len = bar.length().unwrap_or(WRITE_UNITS);
            bar.set_position(len.saturating_sub(WRITE_UNITS));
            bar.set_message("writing products");
        }
    }

    /// Everything is done: clears the bar.
    pub fn finish(mut self) {
        self.stop_ticker();
        if let Some(bar) = self.bar.take() {
            bar.finish_and_clear();
        }
    }
}

impl Drop for RunProgress {
    fn drop(&mut self) {
        self.stop_ticker();
        if let Some(bar) = self.bar.take() {
            bar.finish_and_clear();
        }
    }
}
