//! Stage 2, expose: mean electrons → DN through one physical sensor instance
//! ([`crate::detector::DetectorInstance`]), with the focal plane's memory
//! ([`crate::detector::memory::FocalPlaneMemory`]) stepped on the sequence clock.

use ndarray::Array2;

use crate::detector::memory::{FocalPlaneMemory, FrameTiming, FrameTruth};
use crate::detector::{DetectorInstance, DetectorModel};
use crate::error::{Error, Result};
use crate::los::Clock;
use crate::sensor::Sensor;

/// The exposure stage: the detector model with its conversion gain fixed and the instance
/// (fixed pattern, defects) drawn from the run's seed, shared by every frame, and the
/// focal plane's memory carried from frame to frame.
#[derive(Debug)]
pub struct Exposure {
    instance: DetectorInstance,
    memory: Option<Memory>,
}

/// The memory of a run: its state, the clock it steps on, the next frame it expects and
/// the truth of the frames exposed so far.
#[derive(Debug)]
struct Memory {
    state: FocalPlaneMemory,
    clock: Clock,
    next: u64,
    truth: Vec<FrameTruth>,
}

impl Exposure {
    /// Fixes the gain and draws the instance. A model whose gain is pending
    /// (`[detector.auto_gain] reference = "scene_mean"`, FOI report §4.2) takes K from
    /// `first_frame_e`, the first frame's mean signal electrons: the scene mean lands at
    /// the configured fraction of the range.
    ///
    /// A detector with a memory (`[detector.rts]`, `[detector.persistence]`,
    /// `[detector.drift]`) steps it on the sensor's `[clock]`, made for `clock_frames`
    /// frames from the sequence start.
    ///
    /// Errors: a detector with a memory and no `[clock]`.
    pub fn new(
        sensor: &Sensor,
        first_frame_e: &Array2<f64>,
        seed: u64,
        clock_frames: usize,
    ) -> Result<Self> {
        let mut model = sensor.detector().clone();
        if let Some(fraction) = model.scene_mean_gain_fraction() {
            let mean_e = first_frame_e.iter().sum::<f64>() / first_frame_e.len().max(1) as f64;
            model.set_gain_from_scene_mean(mean_e, fraction)?;
        }
        let memory = match FocalPlaneMemory::new(&model, seed) {
            None => None,
            Some(state) => {
                let d = &sensor.config().detector;
                let clock = Clock::from_config(
                    sensor.config().clock.as_ref(),
                    d.integration_time_s,
                    d.rows,
                    clock_frames,
                )?
                .ok_or_else(|| {
                    Error::param(
                        "clock",
                        "missing",
                        "a [clock] section (e.g. --set clock.frame_rate_hz=50): RTS pixels, persistence and drift happen in time, frame after frame",
                    )
                })?;
                Some(Memory {
                    state,
                    clock,
                    next: 0,
                    truth: Vec::new(),
                })
            }
        };
        Ok(Exposure {
            instance: DetectorInstance::new(&model, seed)?,
            memory,
        })
    }

    /// The model as exposed (gain fixed).
    pub fn model(&self) -> &DetectorModel {
        self.instance.model()
    }

    /// The sensor instance.
    pub fn instance(&self) -> &DetectorInstance {
        &self.instance
    }

    /// `true` when the focal plane carries a memory from frame to frame.
    pub fn has_memory(&self) -> bool {
        self.memory.is_some()
    }

    /// DN of sequence frame `frame` (its temporal noise stream) for the mean signal
    /// electrons `mean_e`. With a memory, frames must come in order; a first frame after
    /// the sequence start needs [`Exposure::replay`] of the frames before it.
    pub fn expose(&mut self, mean_e: &Array2<f64>, frame: u64) -> Result<Array2<u16>> {
        let Some(m) = &mut self.memory else {
            return self.instance.expose(mean_e, frame);
        };
        let (extras, truth) = m.step(self.instance.model(), mean_e, frame)?;
        m.truth.push(truth);
        self.instance.expose_with(mean_e, frame, &extras)
    }

    /// Steps the memory over frame `frame` without exposing it (a run that starts after
    /// the sequence start replays the frames before it; docs/focal-plane.md).
    pub fn replay(&mut self, mean_e: &Array2<f64>, frame: u64) -> Result<()> {
        if let Some(m) = &mut self.memory {
            m.step(self.instance.model(), mean_e, frame)?;
        }
        Ok(())
    }

    /// The focal plane's truth of every frame exposed (empty without a memory) and the
    /// flat indices of its RTS pixels.
    pub fn take_truth(&mut self) -> Option<(Vec<FrameTruth>, Vec<usize>)> {
        self.memory
            .as_mut()
            .map(|m| (std::mem::take(&mut m.truth), m.state.rts_pixels().to_vec()))
    }
}

impl Memory {
    /// One step of the memory over frame `frame`, which must be the next.
    fn step(
        &mut self,
        model: &DetectorModel,
        mean_e: &Array2<f64>,
        frame: u64,
    ) -> Result<(crate::detector::FrameExtras, FrameTruth)> {
        if frame != self.next || frame as usize >= self.clock.frames() {
            return Err(Error::OutOfRange(format!(
                "focal-plane memory: frame {frame} exposed after frame {} of a {}-frame clock (frames must come in order from the sequence start)",
                self.next,
                self.clock.frames()
            )));
        }
        let k = frame as usize;
        let timing = FrameTiming {
            start_s: self.clock.frame_start_s(k),
            integration_time_s: self.clock.integration_time_s(),
            line_time_s: self.clock.line_time_s().unwrap_or(0.0),
        };
        self.next += 1;
        Ok(self.state.step(model, mean_e, &timing))
    }
}
