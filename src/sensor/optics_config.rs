//! The `[optics]` table: the lens (focal length, aperture, transmission) and its optional
//! sub-tables `[optics.wavefront]` ([`super::wavefront`]), `[optics.relative_illumination]`
//! and `[optics.distortion]` ([`super::field_optics`]).

use serde::{Deserialize, Serialize};

use super::config::SpectrumConfig;
use super::field_optics::{DistortionConfig, RelativeIlluminationConfig};

/// `[optics]`: the lens.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OpticsConfig {
    /// Effective focal length, m.
    pub focal_length_m: f64,
    /// F-number N = focal length / entrance-pupil diameter.
    pub f_number: f64,
    /// Central obscuration ratio R = obscuration diameter / aperture diameter (0 = clear).
    #[serde(default)]
    pub obscuration_ratio: f64,
    /// Spectral transmission of the optics.
    #[serde(default = "super::config::unit_spectrum")]
    pub transmission: SpectrumConfig,
    /// Apply the cos⁴θ off-axis irradiance fall-off.
    #[serde(default)]
    pub cos4: bool,
    /// `[optics.wavefront]` (docs/wavefront.md): `eoir psf`, `eoir mtf --field`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wavefront: Option<super::wavefront::WavefrontConfig>,
    /// `[optics.relative_illumination]` (docs/field-optics.md): a table of relative
    /// illumination against field height (times cos⁴θ when `cos4` is on).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub relative_illumination: Option<RelativeIlluminationConfig>,
    /// `[optics.distortion]` (docs/field-optics.md): radial distortion, applied as a
    /// resampling of the scene.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub distortion: Option<DistortionConfig>,
}
