//! The unblurred reference ("truth image") of a sensor: the same description with every
//! transfer function switched off, so each detector pixel records the scene sampled at
//! its centre through the same radiometry, noise and gain (`eoir run --unblurred`,
//! `Sensor.unblurred()` in Python; docs/way-back.md, "The unblurred truth").

use super::config::{SensorConfig, TurbulenceConfig};

impl SensorConfig {
    /// This description with every transfer function of the cascade off:
    /// `diffraction.enabled = false`, `detector.footprint_enabled = false` (a point
    /// sampler at each pixel centre), `enabled = false` on every optics, motion and
    /// atmosphere section present (`[aberration]`, `[defocus]`, `[motion]`, `[jitter]`,
    /// `[turbulence]`, `[aerosol]`, `[gaussian]`, `[measured]`), and `[optics.wavefront]`
    /// removed (the section has no switch; without it the pupil's transfer function
    /// leaves the chain, and with diffraction off nothing of the aperture remains).
    ///
    /// Kept: the radiometry (transmissions, filter, quantum efficiency, `[atmosphere]`
    /// path transmission, cos⁴ and `[optics.relative_illumination]`), the geometry
    /// (`[optics.distortion]`, the `[trajectory]` and `[clock]` of a sequence, whose
    /// line of sight decides where each frame looks) and the whole detector (noise,
    /// defects, gain, its focal-plane effects such as IPC). The photosensitive area
    /// keeps its size, so the signal per pixel is the blurred run's at the same radiance.
    pub fn unblurred(&self) -> SensorConfig {
        let mut u = self.clone();
        u.diffraction.enabled = false;
        u.detector.footprint_enabled = false;
        u.optics.wavefront = None;
        if let Some(x) = u.aberration.as_mut() {
            x.enabled = false;
        }
        if let Some(x) = u.defocus.as_mut() {
            x.enabled = false;
        }
        if let Some(x) = u.motion.as_mut() {
            x.enabled = false;
        }
        if let Some(x) = u.jitter.as_mut() {
            x.enabled = false;
        }
        if let Some(x) = u.aerosol.as_mut() {
            x.enabled = false;
        }
        if let Some(x) = u.gaussian.as_mut() {
            x.enabled = false;
        }
        if let Some(x) = u.measured.as_mut() {
            x.enabled = false;
        }
        match u.turbulence.as_mut() {
            Some(TurbulenceConfig::Horizontal { enabled, .. })
            | Some(TurbulenceConfig::Slant { enabled, .. }) => *enabled = false,
            None => {}
        }
        u
    }
}
