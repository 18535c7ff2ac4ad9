//! The sensor instance that recorded a DN product (issue 12): its seed and a hash of the
//! resolved sensor, stored beside the DN as `instance.json` (and in `report.json`) so
//! that `eoir temperature` rebuilds the *same* fixed pattern, or refuses a mismatch.
//!
//! The fixed pattern (PRNU, DSNU, defects) is drawn from the seed
//! ([`crate::detector::DetectorInstance::new`]); a NUC for another seed corrects the wrong
//! pattern and gives errors of several kelvin without any sign of trouble. The sensor hash
//! is FNV-1a (64 bit; Fowler, Noll & Vo, IETF draft-eastlake-fnv) of the resolved sensor's
//! canonical TOML ([`crate::sensor::SensorConfig::to_toml_string`]) with the two purely
//! descriptive fields (`description`, `selected_options`) cleared: any change of a value
//! that shapes the DN or the calibration changes the hash.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::sensor::Sensor;

/// File name of the sidecar in a product set.
pub const INSTANCE_FILE: &str = "instance.json";

/// Format name written in the sidecar.
const FORMAT_NAME: &str = "eoir-sensor-instance";
/// Format version written in the sidecar.
const FORMAT_VERSION: u32 = 1;

/// The identity of one simulated camera: the resolved sensor and the seed of its fixed
/// pattern.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorInstance {
    /// Always `"eoir-sensor-instance"`.
    pub format: String,
    /// Format version (1).
    pub version: u32,
    /// Sensor name (informational).
    pub sensor: String,
    /// Hash of the resolved sensor, `fnv1a64:` and 16 hex digits ([`sensor_hash`]).
    pub sensor_hash: String,
    /// Seed of the fixed pattern and defects.
    pub seed: u64,
}

/// FNV-1a, 64 bit.
fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// The hash of the resolved sensor (module documentation), `fnv1a64:0123456789abcdef`.
///
/// Errors: a configuration that cannot be written as TOML.
pub fn sensor_hash(sensor: &Sensor) -> Result<String> {
    let mut config = sensor.config().clone();
    config.description.clear();
    config.selected_options.clear();
    Ok(format!(
        "fnv1a64:{:016x}",
        fnv1a64(config.to_toml_string()?.as_bytes())
    ))
}

impl SensorInstance {
    /// The instance of `sensor` with `seed`.
    ///
    /// Errors: as [`sensor_hash`].
    pub fn of(sensor: &Sensor, seed: u64) -> Result<Self> {
        Ok(SensorInstance {
            format: FORMAT_NAME.to_string(),
            version: FORMAT_VERSION,
            sensor: sensor.config().name.clone(),
            sensor_hash: sensor_hash(sensor)?,
            seed,
        })
    }

    /// Writes `dir/instance.json` atomically; returns its path.
    ///
    /// Errors: the file cannot be written.
    pub fn write(&self, dir: &Path) -> Result<PathBuf> {
        let p = dir.join(INSTANCE_FILE);
        let text =
            serde_json::to_string_pretty(self).map_err(|e| Error::format(&p, e.to_string()))?;
        crate::io::atomic_write(&p, |w| crate::io::write_all(w, text.as_bytes(), &p))?;
        Ok(p)
    }

    /// The sidecar in the directory of the image `image`, if there is one.
    ///
    /// Errors: a sidecar that cannot be read, is not JSON of this format, or has another
    /// format name or version (naming the file and field).
    pub fn beside(image: &Path) -> Result<Option<Self>> {
        let dir = image.parent().unwrap_or_else(|| Path::new("."));
        let p = dir.join(INSTANCE_FILE);
        if !p.exists() {
            return Ok(None);
        }
        let text = crate::input::read_text(&p)?;
        let inst: SensorInstance =
            serde_json::from_str(&text).map_err(|e| Error::format(&p, e.to_string()))?;
        if inst.format != FORMAT_NAME || inst.version != FORMAT_VERSION {
            return Err(Error::format(
                &p,
                format!(
                    "format `{}` version {}: expected `{FORMAT_NAME}` version {FORMAT_VERSION}",
                    inst.format, inst.version
                ),
            ));
        }
        Ok(Some(inst))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// FNV-1a 64 reference values (the FNV authors' test vectors).
    #[test]
    fn fnv1a64_matches_reference_vectors() {
        assert_eq!(fnv1a64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x8594_4171_f739_67e8);
    }
}
