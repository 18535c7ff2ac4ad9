//! Stage 2, expose: mean electrons → DN through one physical sensor instance
//! ([`crate::detector::DetectorInstance`]).

use ndarray::Array2;

use crate::detector::{DetectorInstance, DetectorModel};
use crate::error::Result;
use crate::sensor::Sensor;

/// The exposure stage: the detector model with its conversion gain fixed and the instance
/// (fixed pattern, defects) drawn from the run's seed, shared by every frame.
#[derive(Debug)]
pub struct Exposure {
    instance: DetectorInstance,
}

impl Exposure {
    /// Fixes the gain and draws the instance. A model whose gain is pending
    /// (`[detector.auto_gain] reference = "scene_mean"`, FOI report §4.2) takes K from
    /// `first_frame_e`, the first frame's mean signal electrons: the scene mean lands at
    /// the configured fraction of the range.
    pub fn new(sensor: &Sensor, first_frame_e: &Array2<f64>, seed: u64) -> Result<Self> {
        let mut model = sensor.detector().clone();
        if let Some(fraction) = model.scene_mean_gain_fraction() {
            let mean_e = first_frame_e.iter().sum::<f64>() / first_frame_e.len().max(1) as f64;
            model.set_gain_from_scene_mean(mean_e, fraction)?;
        }
        Ok(Exposure {
            instance: DetectorInstance::new(&model, seed)?,
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

    /// DN of sequence frame `frame` (its temporal noise stream) for the mean signal
    /// electrons `mean_e`.
    pub fn expose(&self, mean_e: &Array2<f64>, frame: u64) -> Result<Array2<u16>> {
        self.instance.expose(mean_e, frame)
    }
}
