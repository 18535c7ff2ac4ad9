//! The focal plane's memory across a sequence: the state that one frame leaves to the
//! next — random telegraph pixels ([`super::rts`]), charge held in traps
//! ([`super::persistence`]) and the drift of the fixed pattern ([`super::drift`]) —
//! stepped on the sequence clock, one frame after another (docs/focal-plane.md).
//!
//! [`FocalPlaneMemory::step`] takes the frame's mean signal electrons and its timing and
//! returns what the frame gets ([`FrameExtras`], exposed by
//! [`super::DetectorInstance::expose_with`]) and the truth of that frame
//! ([`FrameTruth`]: which pixels are RTS and their states, the trapped charge, the drift).
//! Every state starts at the sequence's t = 0 and depends only on the seed, the clock and
//! the mean images of the frames before, so a run that starts at frame k reproduces the
//! state by stepping frames 0 … k − 1 first ([`FocalPlaneMemory::step`] without exposing
//! them): the same bits as one run over the whole sequence.

use ndarray::Array2;

use super::{drift, mean_total_e, persistence, rts, staged::FrameExtras, DetectorModel};

/// When one frame is exposed: its start, integration time and (rolling shutter) line time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameTiming {
    /// Start of the first row's integration, s from the sequence start.
    pub start_s: f64,
    /// Integration time, s.
    pub integration_time_s: f64,
    /// Delay between the starts of successive rows, s (0 for a global shutter).
    pub line_time_s: f64,
}

impl FrameTiming {
    /// The integration window of `row`, s.
    pub fn window_s(&self, row: usize) -> (f64, f64) {
        let t0 = self.start_s + row as f64 * self.line_time_s;
        (t0, t0 + self.integration_time_s)
    }

    /// When `row` is read: the end of its integration, s.
    pub fn readout_s(&self, row: usize) -> f64 {
        self.window_s(row).1
    }
}

/// The truth of one frame, for scoring algorithms under test.
#[derive(Debug, Clone)]
pub struct FrameTruth {
    /// Start of the frame, s.
    pub start_s: f64,
    /// RTS pixels of this frame: the fraction of each pixel's window spent in the high
    /// state and its state when read (same order as [`FocalPlaneMemory::rts_pixels`]).
    pub rts: Option<rts::RtsFrame>,
    /// Charge held in traps after the frame, e⁻ per pixel.
    pub trapped_e: Option<Array2<f32>>,
    /// Drift at the frame's start: gain factor and offset (e⁻) per pixel.
    pub drift: Option<(Array2<f32>, Array2<f32>)>,
}

/// The state a focal plane carries from frame to frame.
#[derive(Debug, Clone)]
pub struct FocalPlaneMemory {
    rts: Option<(rts::RtsConfig, rts::RtsPixels)>,
    persistence: Option<persistence::Persistence>,
    drift: Option<drift::Drift>,
    rows: usize,
    cols: usize,
    last_start_s: Option<f64>,
}

impl FocalPlaneMemory {
    /// The memory of the sensor instance drawn from `seed`, at the sequence start; `None`
    /// when the model has none of the effects with a memory.
    pub fn new(model: &DetectorModel, seed: u64) -> Option<Self> {
        let (r, p, d) = model.memory_effects();
        if r.is_none() && p.is_none() && d.is_none() {
            return None;
        }
        let (rows, cols) = (model.rows(), model.cols());
        Some(FocalPlaneMemory {
            rts: r.map(|c| (c.clone(), rts::RtsPixels::new(c, rows, cols, seed))),
            persistence: p.map(|c| persistence::Persistence::new(c, rows, cols)),
            drift: d.map(|c| drift::Drift::new(c, rows, cols, seed)),
            rows,
            cols,
            last_start_s: None,
        })
    }

    /// Flat indices (row · cols + col) of the RTS pixels (empty without RTS).
    pub fn rts_pixels(&self) -> &[usize] {
        self.rts.as_ref().map_or(&[], |(_, p)| p.pixels())
    }

    /// Steps the memory over one frame of mean signal electrons `signal_e` (the imaging
    /// stage's output) with timing `t`, and returns what the frame gets and its truth.
    /// Frames must come in time order.
    pub fn step(
        &mut self,
        model: &DetectorModel,
        signal_e: &Array2<f64>,
        t: &FrameTiming,
    ) -> (FrameExtras, FrameTruth) {
        let (rows, cols) = (self.rows, self.cols);
        let mut extras = FrameExtras::default();
        let mut truth = FrameTruth {
            start_s: t.start_s,
            rts: None,
            trapped_e: None,
            drift: None,
        };
        if let Some((cfg, pixels)) = &mut self.rts {
            let f = pixels.frame(&|r| t.window_s(r), &|r| t.readout_s(r));
            // The dark-current step integrates over the time spent high (shot noise
            // applies); the offset step is read as a level (no shot noise).
            // Only the steps that are on get a frame-sized map.
            let map = |value: &dyn Fn(usize) -> f64| {
                let mut a = Array2::<f64>::zeros((rows, cols));
                for (k, &p) in pixels.pixels().iter().enumerate() {
                    a[[p / cols, p % cols]] = value(k);
                }
                a
            };
            if cfg.dark_step_e_per_s != 0.0 {
                extras.pre_shot_e = Some(map(&|k| {
                    cfg.dark_step_e_per_s * f.high_fraction[k] * t.integration_time_s
                }));
            }
            if cfg.offset_step_e != 0.0 {
                extras.offset_e = Some(map(&|k| {
                    if f.high_at_readout[k] {
                        cfg.offset_step_e
                    } else {
                        0.0
                    }
                }));
            }
            truth.rts = Some(f);
        }
        if let Some(p) = &mut self.persistence {
            // The traps see the whole mean charge of the frame (signal, dark, background,
            // RTS steps); what they take or give back is added before shot noise.
            let mut total =
                signal_e.mapv(|s| mean_total_e(s, model.dark_e(), model.background_e()));
            if let Some(d) = &extras.pre_shot_e {
                total += d;
            }
            let before = total.clone();
            let dt_s = self.last_start_s.map_or(0.0, |s| t.start_s - s);
            p.step(&mut total, model.full_well_e(), dt_s);
            let delta = total - before;
            extras.pre_shot_e = Some(match extras.pre_shot_e.take() {
                Some(d) => d + delta,
                None => delta,
            });
            truth.trapped_e = Some(p.trapped_e().mapv(|v| v as f32));
        }
        if let Some(d) = &mut self.drift {
            let state = d.at(t.start_s);
            truth.drift = Some((
                state.gain_factor.mapv(|v| v as f32),
                state.offset_e.mapv(|v| v as f32),
            ));
            extras.gain_factor = Some(state.gain_factor);
            extras.offset_e = Some(match extras.offset_e.take() {
                Some(o) => o + state.offset_e,
                None => state.offset_e,
            });
        }
        self.last_start_s = Some(t.start_s);
        (extras, truth)
    }
}
