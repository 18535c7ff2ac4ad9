//! The sensor configuration schema (TOML), its validation and `--set` overrides.
//!
//! A sensor file has one section per stage of the chain. Transfer-function sections are
//! optional: a section that is present is enabled unless it says `enabled = false`, and
//! its name is the name of the component everywhere else (the `eoir mtf` CSV columns,
//! reports). Every transfer function can be switched off that way, the detector footprint
//! with `detector.footprint_enabled = false`, so that `--set …enabled=false` makes the
//! unblurred reference ("truth image") of any run. Unknown keys are errors. Relative paths inside the file (CSV tables) are resolved against the file's
//! directory.
//!
//! ```toml
//! name = "example-mwir"
//! [optics]
//! focal_length_m = 0.1
//! f_number = 2.0
//! transmission = { kind = "constant", value = 0.9 }
//! [filter]
//! kind = "top_hat"
//! lo_um = 4.55
//! hi_um = 5.2
//! [detector]
//! rows = 288
//! cols = 384
//! pitch_m = 24e-6
//! active_width_m = 20e-6
//! integration_time_s = 2.6e-3
//! quantum_efficiency = { kind = "ideal_qe", peak = 0.7, cutoff_um = 5.2 }
//! [jitter]
//! sigma_rad = 20e-6
//! ```

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{require_in_range, require_non_negative, require_positive, Error, Result};

pub(crate) use crate::spectrum::resolve_path as resolve;
pub use crate::spectrum::SpectrumConfig;

pub use super::optics_config::OpticsConfig;
pub use crate::detector::config::DetectorConfig;

pub(crate) fn yes() -> bool {
    true
}

pub(crate) fn is_true(v: &bool) -> bool {
    *v
}

pub(crate) fn unit_spectrum() -> SpectrumConfig {
    SpectrumConfig::Constant { value: 1.0 }
}

/// `[diffraction]`: the aperture (clear or obscured, from `[optics]`). On by default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DiffractionConfig {
    /// Include the aperture diffraction transfer function.
    #[serde(default = "yes")]
    pub enabled: bool,
}

impl Default for DiffractionConfig {
    fn default() -> Self {
        DiffractionConfig { enabled: true }
    }
}

/// `[aberration]`: residual wavefront error (Shannon's approximation, docs/design.md §4.5).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AberrationConfig {
    /// Include this component (`false` keeps the section but leaves it out of the
    /// cascade, e.g. for the unblurred reference of a run).
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub enabled: bool,
    /// RMS wavefront error, waves (reliable up to ~0.1; W_pp/3.5 is a rule of thumb).
    pub rms_waves: f64,
}

/// `[defocus]`: give exactly one of `w020_waves` or `focus_shift_m`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DefocusConfig {
    /// Include this component (`false` keeps the section but leaves it out of the
    /// cascade, e.g. for the unblurred reference of a run).
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub enabled: bool,
    /// Edge wavefront error W020, waves (the same at every wavelength).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub w020_waves: Option<f64>,
    /// Focus shift δz, m; W020 = δz / (8 N² λ) then depends on wavelength.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub focus_shift_m: Option<f64>,
}

/// `[motion]` lives with the line of sight it drives over a sequence.
pub use crate::los::MotionConfig;

/// `[jitter]`: random line-of-sight jitter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JitterConfig {
    /// Include this component (`false` keeps the section but leaves it out of the
    /// cascade, e.g. for the unblurred reference of a run).
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub enabled: bool,
    /// RMS jitter per axis, rad.
    pub sigma_rad: f64,
}

/// `[gaussian]`: a global Gaussian blur (e.g. to stand for unmodelled effects).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GaussianConfig {
    /// Include this component (`false` keeps the section but leaves it out of the
    /// cascade, e.g. for the unblurred reference of a run).
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub enabled: bool,
    /// RMS width along x, rad.
    pub sigma_rad: f64,
    /// RMS width along y, rad (defaults to `sigma_rad`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_y_rad: Option<f64>,
}

/// `[turbulence]`: long-exposure atmospheric turbulence, selected by `path`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "path", rename_all = "snake_case", deny_unknown_fields)]
pub enum TurbulenceConfig {
    /// Horizontal path with constant Cn².
    Horizontal {
        /// Include turbulence (`false` leaves it out of the cascade).
        #[serde(default = "yes", skip_serializing_if = "is_true")]
        enabled: bool,
        /// Refractive-index structure constant Cn², m^-2/3.
        cn2: f64,
        /// Path length, m.
        range_m: f64,
    },
    /// Slant path through Cn²(h) = Cn²₀ h^(−4/3).
    Slant {
        /// Include turbulence (`false` leaves it out of the cascade).
        #[serde(default = "yes", skip_serializing_if = "is_true")]
        enabled: bool,
        /// Cn² at 1 m height, m^-2/3.
        cn2_at_1m: f64,
        /// Sensor height above ground, m (> 0).
        sensor_height_m: f64,
        /// Target height above ground, m (> 0).
        target_height_m: f64,
        /// Slant range, m.
        range_m: f64,
    },
}

impl TurbulenceConfig {
    /// Whether the section is enabled (`enabled`, true unless set to false).
    pub fn is_enabled(&self) -> bool {
        match self {
            TurbulenceConfig::Horizontal { enabled, .. }
            | TurbulenceConfig::Slant { enabled, .. } => *enabled,
        }
    }
}

/// `[aerosol]`: aerosol forward-scattering transfer function (docs/design.md §4.8).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AerosolConfig {
    /// Include this component (`false` keeps the section but leaves it out of the
    /// cascade, e.g. for the unblurred reference of a run).
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub enabled: bool,
    /// Absorption coefficient k, 1/m.
    pub absorption_per_m: f64,
    /// Scattering coefficient σ, 1/m.
    pub scattering_per_m: f64,
    /// Path length, m.
    pub range_m: f64,
    /// Typical particle radius a, m.
    pub particle_radius_m: f64,
    /// Divide by the DC value exp(−kR) (use when `[atmosphere] transmission` already holds
    /// the path absorption, so it is not counted twice).
    #[serde(default)]
    pub dc_normalised: bool,
}

/// `[measured]`: a measured rotationally symmetric MTF (cycles/mrad, MTF): a CSV file or
/// an inline table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeasuredConfig {
    /// Include this component (`false` keeps the section but leaves it out of the
    /// cascade, e.g. for the unblurred reference of a run).
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub enabled: bool,
    /// Two-column CSV (cycles/mrad, MTF), relative to the sensor file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub csv: Option<PathBuf>,
    /// Inline frequencies, cycles/mrad.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub freq_cy_per_mrad: Option<Vec<f64>>,
    /// Inline MTF values.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mtf: Option<Vec<f64>>,
}

/// `[atmosphere]`: the path's spectral transmission, applied in the spectral chain.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AtmosphereConfig {
    /// Path transmission τ_atm(λ).
    pub transmission: SpectrumConfig,
}

/// `[calibration]`: the radiometric calibration of a thermal sensor (crate::calibration).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationConfig {
    /// Blackbody reference temperatures, K (at least two distinct, each finite and > 0).
    /// Absent: chosen from the sensor's own range (about 10/50/90 % of full scale).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temperatures_k: Option<Vec<f64>>,
}

impl CalibrationConfig {
    /// Checks the temperatures, naming the field.
    pub fn validate(&self) -> Result<()> {
        let Some(t) = &self.temperatures_k else {
            return Ok(());
        };
        for (i, &v) in t.iter().enumerate() {
            require_positive(&format!("calibration.temperatures_k[{i}]"), v)?;
        }
        let mut d = t.clone();
        d.sort_by(f64::total_cmp);
        d.dedup();
        if d.len() < 2 {
            return Err(Error::param(
                "calibration.temperatures_k",
                format!("{t:?}"),
                "at least two distinct blackbody temperatures in K",
            ));
        }
        Ok(())
    }
}

/// `[cfa]`: a colour filter array (Bayer mosaic) over the detector. Each pixel sees the
/// chain's response times the transmission of its own colour filter; see [`crate::cfa`]
/// for mosaicking and demosaicking.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CfaConfig {
    /// The 2 × 2 tile, read row by row from the top-left pixel: `"RGGB"`, `"BGGR"`,
    /// `"GRBG"` or `"GBRG"`.
    pub pattern: crate::cfa::CfaPattern,
    /// Transmission of the red filter (dye, times any IR-cut filter not in `[filter]`).
    pub red: SpectrumConfig,
    /// Transmission of the green filter.
    pub green: SpectrumConfig,
    /// Transmission of the blue filter.
    pub blue: SpectrumConfig,
}

/// A complete sensor description, as read from a TOML file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorConfig {
    /// Short name.
    pub name: String,
    /// One-line description.
    #[serde(default)]
    pub description: String,
    /// The lens.
    pub optics: OpticsConfig,
    /// Spectral filter (band-pass); omitted = 1.
    #[serde(default = "unit_spectrum")]
    pub filter: SpectrumConfig,
    /// The focal-plane array and electronics.
    pub detector: DetectorConfig,
    /// Path transmission in the spectral chain.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub atmosphere: Option<AtmosphereConfig>,
    /// Aperture diffraction (on by default).
    #[serde(default)]
    pub diffraction: DiffractionConfig,
    /// Shannon aberration.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aberration: Option<AberrationConfig>,
    /// Defocus.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub defocus: Option<DefocusConfig>,
    /// Linear motion smear.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion: Option<MotionConfig>,
    /// Line-of-sight jitter.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub jitter: Option<JitterConfig>,
    /// Atmospheric turbulence.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub turbulence: Option<TurbulenceConfig>,
    /// Aerosol scattering.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aerosol: Option<AerosolConfig>,
    /// Global Gaussian blur.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gaussian: Option<GaussianConfig>,
    /// Measured MTF.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub measured: Option<MeasuredConfig>,
    /// Colour filter array (a Bayer sensor); absent for a monochrome sensor.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cfa: Option<CfaConfig>,
    /// Radiometric calibration (`[calibration]`, thermal sensors).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<CalibrationConfig>,
    /// The sequence clock (`[clock]`): frame times, shutter; absent = a still camera.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clock: Option<crate::los::ClockConfig>,
    /// Line-of-sight trajectory over a sequence (`[trajectory]`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trajectory: Option<crate::los::TrajectoryConfig>,
    /// The preset options this description was resolved with (`--option name=value`, or
    /// the preset's defaults), recorded for provenance; informational only.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub selected_options: BTreeMap<String, String>,
    /// Directory that relative paths in this description are resolved against.
    #[serde(skip)]
    pub base_dir: PathBuf,
}

impl SensorConfig {
    /// Loads a sensor file, applies `overrides` (`key.path=value`, see
    /// [`apply_override`]) and validates the result. Errors name the file, the line or key,
    /// and what is valid.
    pub fn load(path: &Path, overrides: &[String]) -> Result<Self> {
        let text = crate::io::input::read_text(path)?;
        let base_dir = path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."));
        Self::from_toml_str(&text, &path.display().to_string(), base_dir, overrides)
    }

    /// Parses a sensor description from TOML text. `source` names it in errors (a file
    /// name or a preset name); `base_dir` resolves relative paths.
    pub fn from_toml_str(
        text: &str,
        source: &str,
        base_dir: PathBuf,
        overrides: &[String],
    ) -> Result<Self> {
        let parsed = parse_overrides(overrides)?;
        Self::from_toml_str_with(text, source, base_dir, &parsed)
    }

    /// As [`SensorConfig::from_toml_str`], with overrides already split into key paths
    /// and values ([`Override`]; the Python API builds them from a dict, so no key or
    /// value is ever parsed as TOML text).
    pub fn from_toml_str_with(
        text: &str,
        source: &str,
        base_dir: PathBuf,
        overrides: &[Override],
    ) -> Result<Self> {
        // Parse the text as written first, so errors point at its lines.
        let mut config: SensorConfig =
            toml::from_str(text).map_err(|e| toml_error(source, text, &e))?;
        if !overrides.is_empty() {
            let mut value: toml::Table =
                toml::from_str(text).map_err(|e| toml_error(source, text, &e))?;
            for o in overrides {
                o.apply(&mut value)?;
            }
            config = toml::Value::Table(value)
                .try_into()
                .map_err(|e: toml::de::Error| after_overrides(source, overrides, &e))?;
        }
        Self::finish(config, source, base_dir)
    }

    /// Builds a sensor description from an already parsed TOML table (e.g. a preset with
    /// its options merged in, see [`crate::sensor::presets`]), applies `overrides` and
    /// validates the result. `source` names it in errors; `base_dir` resolves relative
    /// paths.
    pub fn from_table(
        table: toml::Table,
        source: &str,
        base_dir: PathBuf,
        overrides: &[String],
    ) -> Result<Self> {
        let parsed = parse_overrides(overrides)?;
        Self::from_table_with(table, source, base_dir, &parsed)
    }

    /// As [`SensorConfig::from_table`], with overrides already split ([`Override`]).
    pub fn from_table_with(
        mut table: toml::Table,
        source: &str,
        base_dir: PathBuf,
        overrides: &[Override],
    ) -> Result<Self> {
        for o in overrides {
            o.apply(&mut table)?;
        }
        let config: SensorConfig =
            toml::Value::Table(table)
                .try_into()
                .map_err(|e: toml::de::Error| {
                    if overrides.is_empty() {
                        Error::format(
                            source,
                            crate::error::redact_quoted(e.message().trim(), 160, true),
                        )
                    } else {
                        after_overrides(source, overrides, &e)
                    }
                })?;
        Self::finish(config, source, base_dir)
    }

    /// Sets the base directory and validates, naming `source` in errors.
    fn finish(mut config: SensorConfig, source: &str, base_dir: PathBuf) -> Result<Self> {
        config.base_dir = base_dir;
        config.validate().map_err(|e| match e {
            Error::InvalidParameter { .. } => Error::format(source, e.to_string()),
            other => other,
        })?;
        Ok(config)
    }

    /// The fully resolved description as TOML (what `eoir` writes next to every output).
    pub fn to_toml_string(&self) -> Result<String> {
        toml::to_string_pretty(self)
            .map_err(|e| Error::param("sensor", &self.name, format!("serialisable to TOML: {e}")))
    }

    /// Checks every value against its physical range.
    pub fn validate(&self) -> Result<()> {
        if let Some(c) = &self.calibration {
            c.validate()?;
        }
        let o = &self.optics;
        require_positive("optics.focal_length_m", o.focal_length_m)?;
        require_positive("optics.f_number", o.f_number)?;
        if !(o.obscuration_ratio.is_finite() && (0.0..1.0).contains(&o.obscuration_ratio)) {
            return Err(Error::param(
                "optics.obscuration_ratio",
                o.obscuration_ratio,
                "a number in [0, 1)",
            ));
        }
        super::wavefront::validate(o)?;
        super::field_optics::validate(o.relative_illumination.as_ref(), o.distortion.as_ref())?;
        let d = &self.detector;
        // The detector instance holds about eight per-pixel f64 maps (FPN, dark, defects,
        // calibration) besides the frames checked per run (crate::limits::check_run).
        crate::limits::check_alloc(
            "the detector (detector.rows × detector.cols per-pixel maps)",
            &[("rows", d.rows as u64), ("cols", d.cols as u64)],
            64,
        )?;
        if d.rows == 0 || d.cols == 0 {
            return Err(Error::param(
                "detector.rows/cols",
                format!("{} x {}", d.rows, d.cols),
                "at least 1 x 1 pixels",
            ));
        }
        require_positive("detector.pitch_m", d.pitch_m)?;
        require_positive("detector.active_width_m", d.active_width_m)?;
        if let Some(h) = d.active_height_m {
            require_positive("detector.active_height_m", h)?;
        }
        if d.active_width_m > d.pitch_m * (1.0 + 1e-12) {
            return Err(Error::param(
                "detector.active_width_m",
                d.active_width_m,
                format!("at most the pitch ({} m): fill factor ≤ 1", d.pitch_m),
            ));
        }
        if d.active_height() > d.pitch_m * (1.0 + 1e-12) {
            return Err(Error::param(
                "detector.active_height_m",
                d.active_height(),
                format!("at most the pitch ({} m): fill factor ≤ 1", d.pitch_m),
            ));
        }
        require_positive("detector.integration_time_s", d.integration_time_s)?;
        if let SpectrumConfig::PhotonDetector { peak, cutoff_um } = &d.quantum_efficiency {
            return Err(Error::param(
                "detector.quantum_efficiency",
                format!("{{ kind = \"photon_detector\", peak = {peak}, cutoff_um = {cutoff_um} }}"),
                format!(
                    "electrons per photon: `photon_detector` is a response per watt (∝ λ) and would count λ twice; an ideal detector's QE is {{ kind = \"ideal_qe\", peak = {peak}, cutoff_um = {cutoff_um} }}"
                ),
            ));
        }
        require_positive("detector.full_well_e", d.full_well_e)?;
        if !(1..=16).contains(&d.bits) {
            return Err(Error::param(
                "detector.bits",
                d.bits,
                "an integer in [1, 16] (DN products are 16-bit)",
            ));
        }
        if let Some(k) = d.gain_dn_per_e {
            require_positive("detector.gain_dn_per_e", k)?;
        }
        require_in_range("detector.offset_dn", d.offset_dn, 0.0, d.max_dn())?;
        crate::detector::config::validate_effects(d)?;
        if let Some(a) = &self.aberration {
            require_non_negative("aberration.rms_waves", a.rms_waves)?;
        }
        if let Some(df) = &self.defocus {
            match (df.w020_waves, df.focus_shift_m) {
                (Some(w), None) => {
                    if !w.is_finite() {
                        return Err(Error::param("defocus.w020_waves", w, "a finite number"));
                    }
                }
                (None, Some(z)) => {
                    if !z.is_finite() {
                        return Err(Error::param("defocus.focus_shift_m", z, "a finite number"));
                    }
                }
                _ => {
                    return Err(Error::param(
                        "defocus",
                        "w020_waves and focus_shift_m",
                        "exactly one of `w020_waves` or `focus_shift_m`",
                    ))
                }
            }
        }
        if let Some(m) = &self.motion {
            let given = [
                m.smear_rad.is_some(),
                m.angular_rate_rad_s.is_some(),
                m.velocity_m_s.is_some(),
            ]
            .iter()
            .filter(|g| **g)
            .count();
            if given != 1 {
                return Err(Error::param(
                    "motion",
                    format!("{given} of smear_rad / angular_rate_rad_s / velocity_m_s"),
                    "exactly one of them",
                ));
            }
            if let Some(s) = m.smear_rad {
                require_non_negative("motion.smear_rad", s)?;
            }
            if let Some(w) = m.angular_rate_rad_s {
                if !w.is_finite() {
                    return Err(Error::param(
                        "motion.angular_rate_rad_s",
                        w,
                        "a finite number",
                    ));
                }
            }
            if let Some(v) = m.velocity_m_s {
                if !v.is_finite() {
                    return Err(Error::param("motion.velocity_m_s", v, "a finite number"));
                }
                match m.range_m {
                    Some(r) => {
                        require_positive("motion.range_m", r)?;
                    }
                    None => {
                        return Err(Error::param(
                            "motion.range_m",
                            "missing",
                            "the range to the moving scene, m, when velocity_m_s is given",
                        ))
                    }
                }
            }
            if !m.direction_deg.is_finite() {
                return Err(Error::param(
                    "motion.direction_deg",
                    m.direction_deg,
                    "a finite angle",
                ));
            }
        }
        if let Some(c) = &self.clock {
            c.validate(d.integration_time_s, d.rows)?;
        }
        if self.clock.is_none() {
            for (on, key) in [
                (d.rts.is_some(), "detector.rts"),
                (d.persistence.is_some(), "detector.persistence"),
                (d.drift.is_some(), "detector.drift"),
            ] {
                if on {
                    return Err(Error::param(
                        key,
                        "given without [clock]",
                        "a [clock] section with the frame times it happens on (e.g. --set clock.frame_rate_hz=50)",
                    ));
                }
            }
        }
        if let Some(t) = &self.trajectory {
            t.validate()?;
        }
        if let Some(j) = &self.jitter {
            require_non_negative("jitter.sigma_rad", j.sigma_rad)?;
        }
        if let Some(g) = &self.gaussian {
            require_non_negative("gaussian.sigma_rad", g.sigma_rad)?;
            if let Some(s) = g.sigma_y_rad {
                require_non_negative("gaussian.sigma_y_rad", s)?;
            }
        }
        match &self.turbulence {
            Some(TurbulenceConfig::Horizontal { cn2, range_m, .. }) => {
                require_non_negative("turbulence.cn2", *cn2)?;
                require_positive("turbulence.range_m", *range_m)?;
            }
            Some(TurbulenceConfig::Slant {
                cn2_at_1m,
                sensor_height_m,
                target_height_m,
                range_m,
                ..
            }) => {
                crate::atmosphere::SlantPath::new(
                    *cn2_at_1m,
                    *sensor_height_m,
                    *target_height_m,
                    *range_m,
                )
                .map_err(|e| prefix_field("turbulence", e))?;
            }
            None => {}
        }
        if let Some(a) = &self.aerosol {
            require_non_negative("aerosol.absorption_per_m", a.absorption_per_m)?;
            require_non_negative("aerosol.scattering_per_m", a.scattering_per_m)?;
            require_non_negative("aerosol.range_m", a.range_m)?;
            require_positive("aerosol.particle_radius_m", a.particle_radius_m)?;
        }
        if let Some(m) = &self.measured {
            let inline = m.freq_cy_per_mrad.is_some() || m.mtf.is_some();
            if m.csv.is_some() == inline {
                return Err(Error::param(
                    "measured",
                    if inline {
                        "csv and an inline table"
                    } else {
                        "nothing"
                    },
                    "either `csv = \"file.csv\"` or both `freq_cy_per_mrad` and `mtf`",
                ));
            }
        }
        // Inline spectra are checked by building them; files are read by `Sensor::build`.
        let spectra = [
            (&self.filter, "filter"),
            (&self.optics.transmission, "optics.transmission"),
            (&d.quantum_efficiency, "detector.quantum_efficiency"),
        ];
        let atmosphere = self
            .atmosphere
            .as_ref()
            .map(|a| (&a.transmission, "atmosphere.transmission"));
        let cfa = self.cfa.iter().flat_map(|c| {
            [
                (&c.red, "cfa.red"),
                (&c.green, "cfa.green"),
                (&c.blue, "cfa.blue"),
            ]
        });
        for (spectrum, field) in spectra.into_iter().chain(atmosphere).chain(cfa) {
            if !matches!(spectrum, SpectrumConfig::Csv { .. }) {
                spectrum.build(&self.base_dir, field)?;
            }
        }
        Ok(())
    }

    /// The camera equation for this sensor (on axis; docs/design.md §4.1). Resolved once
    /// by [`super::Sensor::build`]; stages use [`super::Sensor::camera`].
    pub(crate) fn camera_equation(&self) -> Result<crate::radiometry::CameraEquation> {
        crate::radiometry::CameraEquation::new(
            self.detector.integration_time_s,
            self.detector.active_area_m2(),
            self.optics.f_number,
        )?
        .with_obscuration(self.optics.obscuration_ratio)
    }

    /// Entrance-pupil (aperture) diameter D = f / N, m.
    pub fn aperture_diameter_m(&self) -> f64 {
        self.optics.focal_length_m / self.optics.f_number
    }

    /// Detector instantaneous field of view (angular pixel pitch) p / f, rad.
    pub fn ifov_rad(&self) -> f64 {
        self.detector.pitch_m / self.optics.focal_length_m
    }

    /// Detector Nyquist frequency 1 / (2 IFOV), cycles/rad.
    pub fn nyquist_cy_per_rad(&self) -> f64 {
        0.5 / self.ifov_rad()
    }

    /// Full field of view (horizontal, vertical) in degrees of a flat focal plane:
    /// 2 atan(n p / 2f).
    pub fn fov_deg(&self) -> (f64, f64) {
        let f = self.optics.focal_length_m;
        let p = self.detector.pitch_m;
        let fov = |n: usize| (2.0 * (n as f64 * p / (2.0 * f)).atan()).to_degrees();
        (fov(self.detector.cols), fov(self.detector.rows))
    }

    /// Things that are valid but probably not what the user meant.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        w.extend(super::wavefront::cascade_warning(self));
        if let (Some(a), Some(_)) = (&self.aerosol, &self.atmosphere) {
            if !a.dc_normalised {
                w.push(
                    "aerosol.dc_normalised = false while [atmosphere] transmission is set: \
                     the path absorption exp(-kR) is counted twice"
                        .to_string(),
                );
            }
        }
        if let Some(a) = &self.aberration {
            if a.rms_waves > 0.1 {
                w.push(format!(
                    "aberration.rms_waves = {} is beyond ~0.1 wave rms, where Shannon's approximation is rough",
                    a.rms_waves
                ));
            }
        }
        w
    }
}

/// Prefixes the field of an [`Error::InvalidParameter`] with `section.`.
pub(crate) fn prefix_field(section: &str, e: Error) -> Error {
    match e {
        Error::InvalidParameter {
            field,
            value,
            expected,
        } => Error::InvalidParameter {
            field: format!("{section}.{field}"),
            value,
            expected,
        },
        other => other,
    }
}

/// Turns a TOML error into one line: `source: line L, column C: message`. Neither the
/// line's text nor anything the parser quoted from it is shown ([`crate::error::redact_quoted`]):
/// `--sensor` may name a file that is not meant to be printed (`/etc/passwd`).
pub(crate) fn toml_error(source: &str, text: &str, e: &toml::de::Error) -> Error {
    let msg = crate::error::redact_quoted(e.message().trim(), 160, true);
    match e.span() {
        Some(span) => {
            let start = floor_char_boundary(text, span.start.min(text.len()));
            let before = &text[..start];
            let line_no = before.matches('\n').count() + 1;
            let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
            Error::format(source, format!("line {line_no}, column {column}: {msg}"))
        }
        None => Error::format(source, msg),
    }
}

/// The largest char boundary of `text` at or below `i`.
fn floor_char_boundary(text: &str, mut i: usize) -> usize {
    while !text.is_char_boundary(i) {
        i -= 1;
    }
    i
}

/// Applies one override `a.b.c=value` to a parsed TOML table (see [`Override::parse`]).
pub fn apply_override(table: &mut toml::Table, assignment: &str) -> Result<()> {
    Override::parse(assignment)?.apply(table)
}

/// Most levels of tables and arrays an override value may nest (a sensor file's deepest
/// field is three tables down; a value nested deeper is a mistake, not a configuration).
pub const MAX_OVERRIDE_DEPTH: usize = 16;

/// One override of a sensor field: the key path (`["detector", "integration_time_s"]`)
/// and the value. Built from `key.path=value` text by [`Override::parse`] (the CLI's
/// `--set`), or from a key path and an already typed value by [`Override::new`] (the
/// Python API), where neither the key nor the value is ever parsed as TOML text, so a
/// key holding `=`, a newline or a table header cannot reach another field.
#[derive(Debug, Clone, PartialEq)]
pub struct Override {
    /// Key path, outermost table first, never empty; each part a TOML bare key
    /// (`A-Za-z0-9_-`).
    path: Vec<String>,
    /// The value set at the end of the path, nested at most [`MAX_OVERRIDE_DEPTH`] deep.
    value: toml::Value,
}

impl Override {
    /// An override of the field at the dotted `key` (`detector.integration_time_s`) with
    /// `value`. Each part of the key must be a TOML bare key (letters, digits, `_`, `-`),
    /// as every field of a sensor file is; the value may nest at most
    /// [`MAX_OVERRIDE_DEPTH`] levels of arrays and tables.
    pub fn new(key: &str, value: toml::Value) -> Result<Self> {
        let path = key_path(key, "overrides")?;
        check_depth(&path, &value, "overrides")?;
        Ok(Override { path, value })
    }

    /// The key path, outermost table first.
    pub fn path(&self) -> &[String] {
        &self.path
    }

    /// The value.
    pub fn value(&self) -> &toml::Value {
        &self.value
    }

    /// Parses `a.b.c=value` (the CLI's `--set`). The key is split at the first `=`; the
    /// value is read as one TOML value (`2e-3`, `true`, `"text"`, `[1, 2]`,
    /// `{ kind = "constant", value = 1 }`) and, when it is not exactly one TOML value
    /// (e.g. it holds a newline and a table header), taken as a string, so it can never
    /// set a second field. Missing intermediate tables are created when applied, so
    /// `--set jitter.sigma_rad=1e-5` enables jitter. Whether the key exists is checked
    /// when the result is deserialised (unknown keys are errors).
    pub fn parse(assignment: &str) -> Result<Self> {
        let (key, raw) = assignment.split_once('=').ok_or_else(|| {
            Error::param(
                "--set",
                crate::limits::escape_token(assignment),
                "`section.key=value`, e.g. optics.f_number=2.5",
            )
        })?;
        let path = key_path(key.trim(), "--set")?;
        let raw = raw.trim();
        let value = match toml::from_str::<toml::Table>(&format!("v = {raw}")) {
            Ok(mut t) if t.len() == 1 => t
                .remove("v")
                .unwrap_or_else(|| toml::Value::String(raw.to_string())),
            _ => toml::Value::String(raw.to_string()),
        };
        check_depth(&path, &value, "--set")?;
        Ok(Override { path, value })
    }

    /// Sets the value in `table`, creating missing intermediate tables; an intermediate
    /// key that holds a value rather than a table is an error naming it.
    pub fn apply(&self, table: &mut toml::Table) -> Result<()> {
        let Some((leaf, parents)) = self.path.split_last() else {
            return Err(Error::param(
                "overrides",
                "an empty key path",
                "a dotted key such as optics.f_number",
            ));
        };
        let mut cur = table;
        for (i, part) in parents.iter().enumerate() {
            let entry = cur
                .entry(part.clone())
                .or_insert_with(|| toml::Value::Table(toml::Table::new()));
            cur = match entry {
                toml::Value::Table(t) => t,
                other => {
                    return Err(Error::param(
                        self.path.join("."),
                        crate::limits::escape_bounded(&self.value.to_string(), 80),
                        format!(
                            "`{}` is a value ({}), not a section",
                            self.path[..=i].join("."),
                            other.type_str()
                        ),
                    ))
                }
            };
        }
        cur.insert(leaf.clone(), self.value.clone());
        Ok(())
    }
}

impl std::fmt::Display for Override {
    /// `a.b.c=value`, the value as TOML (at most 80 characters, control characters
    /// escaped).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}={}",
            self.path.join("."),
            crate::limits::escape_bounded(&self.value.to_string(), 80)
        )
    }
}

/// Splits a dotted key into its parts, each a non-empty TOML bare key; `what` names the
/// setting in the error.
fn key_path(key: &str, what: &str) -> Result<Vec<String>> {
    let parts: Vec<&str> = key.split('.').map(str::trim).collect();
    let bare = |p: &str| {
        !p.is_empty()
            && p.chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    };
    if key.trim().is_empty() || !parts.iter().all(|p| bare(p)) {
        return Err(Error::param(
            what,
            crate::limits::escape_token(key),
            "a dotted key of letters, digits, `_` and `-`, such as optics.f_number",
        ));
    }
    Ok(parts.into_iter().map(str::to_string).collect())
}

/// Refuses a value nested deeper than [`MAX_OVERRIDE_DEPTH`]; `what` names the setting.
fn check_depth(path: &[String], value: &toml::Value, what: &str) -> Result<()> {
    if depth(value) > MAX_OVERRIDE_DEPTH {
        return Err(Error::param(
            format!("{what}[{}]", path.join(".")),
            "a value nested deeper than the limit",
            format!("at most {MAX_OVERRIDE_DEPTH} levels of lists and tables"),
        ));
    }
    Ok(())
}

/// Nesting depth of a TOML value (a scalar is 0).
fn depth(v: &toml::Value) -> usize {
    // Iterative, so a hostile value cannot overflow the stack here.
    let mut deepest = 0;
    let mut stack: Vec<(&toml::Value, usize)> = vec![(v, 0)];
    while let Some((v, d)) = stack.pop() {
        deepest = deepest.max(d);
        match v {
            toml::Value::Array(a) => stack.extend(a.iter().map(|x| (x, d + 1))),
            toml::Value::Table(t) => stack.extend(t.values().map(|x| (x, d + 1))),
            _ => {}
        }
    }
    deepest
}

/// Parses `--set` assignments.
fn parse_overrides(overrides: &[String]) -> Result<Vec<Override>> {
    overrides.iter().map(|o| Override::parse(o)).collect()
}

/// The error of a description that no longer deserialises after `overrides`.
fn after_overrides(source: &str, overrides: &[Override], e: &toml::de::Error) -> Error {
    Error::format(
        source,
        format!(
            "after setting {}: {}",
            overrides
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join(", "),
            crate::error::redact_quoted(e.message().trim(), 160, true)
        ),
    )
}
