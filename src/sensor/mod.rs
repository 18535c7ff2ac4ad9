//! The sensor: its configuration schema ([`config`], with the `[detector]` table from
//! [`crate::detector::config`]), the embedded presets ([`presets`]), the cascade of
//! transfer functions it implies ([`otf`]), and the resolved [`Sensor`] that every stage of
//! a run takes ([`resolved`]: built once, validated, every referenced file read once), and
//! the optional `[optics.wavefront]` table ([`wavefront`]), and the `[optics]` table
//! ([`optics_config`]) with relative illumination and distortion ([`field_optics`]);
//! [`SensorConfig::unblurred`] ([`unblurred`]) switches every transfer function off.
//!
//! The cascade lives here rather than in `optics` because it combines optics, atmosphere
//! and motion terms as one sensor description configures them; `optics`, `atmosphere` and
//! `motion` hold only the pure component functions.

pub mod config;
pub mod field_optics;
pub mod optics_config;
pub mod otf;
pub mod presets;
pub mod resolved;
pub mod unblurred;
pub mod wavefront;

pub use config::MotionConfig;
pub use config::{apply_override, Override, SensorConfig, SpectrumConfig};
pub use otf::{AchromaticSampler, Component, FrequencyGrid, GridOtf, SystemOtf};
pub use resolved::{Sensor, Spectra};
