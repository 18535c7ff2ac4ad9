//! The sensor: its configuration schema ([`config`]) and the cascade of transfer functions
//! it implies ([`otf`]).
//!
//! The cascade lives here rather than in `optics` because it combines optics, atmosphere
//! and motion terms as one sensor description configures them; `optics`, `atmosphere` and
//! `motion` hold only the pure component functions.

pub mod config;
pub mod otf;
pub mod presets;

pub use config::{apply_override, SensorConfig, SpectrumConfig};
pub use otf::{Component, FrequencyGrid, GridOtf, SystemOtf};
