//! `[optics.wavefront]`: the lens's wavefront for transfer functions from the pupil
//! (docs/wavefront.md). Optional; absent, nothing changes.
//!
//! ```toml
//! [optics.wavefront]
//! reference_wavelength_um = 4.0
//! zernike_convention = "noll_rms"      # the only convention: Noll 1976, RMS-normalised
//! field_dependence = "seidel"          # or "table"
//! w040_waves = 0.1                     # Seidel, waves at the reference wavelength,
//! w131_waves = 0.2                     # full-field (H = 1) values
//! zernike_noll_rms_waves = [0, 0, 0, 0.02]   # Z1, Z2, …: field-independent terms
//! spider_vanes = 0
//! ```
//!
//! With `field_dependence = "table"`, the coefficients are given per field point instead:
//! `[[optics.wavefront.field_point]]` tables with `h` and the same coefficient keys, local
//! values at that field height, interpolated linearly in H.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::wavefront::{
    FieldDependence, LocalWavefront, Pupil, PupilTransfer, Sampling, Seidel, WavefrontModel,
};

/// How the coefficients depend on the normalised field height H.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FieldLaw {
    /// Seidel field law on full-field coefficients (coma ∝ H, astigmatism and field
    /// curvature ∝ H², distortion ∝ H³, defocus and spherical constant).
    #[default]
    Seidel,
    /// Local coefficients at field points (`field_point`), linear in H.
    Table,
}

/// The Zernike ordering and normalisation of `zernike_noll_rms_waves`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ZernikeConvention {
    /// Noll (1976) ordering, RMS-normalised polynomials.
    #[default]
    NollRms,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// Seidel and Zernike coefficients, waves at the reference wavelength (as read from a
/// `[optics.wavefront]` table or a field point).
#[derive(Debug, Clone, Default, PartialEq)]
struct CoefficientsConfig {
    seidel: Seidel,
    zernike_noll_rms_waves: Vec<f64>,
}

macro_rules! coefficients_of {
    ($c:expr) => {
        CoefficientsConfig {
            seidel: Seidel {
                w020: $c.w020_waves,
                w040: $c.w040_waves,
                w131: $c.w131_waves,
                w222: $c.w222_waves,
                w220: $c.w220_waves,
                w311: $c.w311_waves,
            },
            zernike_noll_rms_waves: $c.zernike_noll_rms_waves.clone(),
        }
    };
}

impl CoefficientsConfig {
    fn is_empty(&self) -> bool {
        *self == CoefficientsConfig::default()
    }
}

/// One row of a field table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FieldPointConfig {
    /// Normalised field height H in [0, 1].
    pub h: f64,
    /// Defocus W020 ρ².
    #[serde(default, skip_serializing_if = "is_zero")]
    pub w020_waves: f64,
    /// Spherical aberration W040 ρ⁴.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub w040_waves: f64,
    /// Coma W131 ρ³ cos φ.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub w131_waves: f64,
    /// Astigmatism W222 ρ² cos² φ.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub w222_waves: f64,
    /// Field curvature W220 ρ².
    #[serde(default, skip_serializing_if = "is_zero")]
    pub w220_waves: f64,
    /// Distortion W311 ρ cos φ.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub w311_waves: f64,
    /// Noll Zernike coefficients, RMS waves: element i is Z_{i+1}.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub zernike_noll_rms_waves: Vec<f64>,
}

/// `[optics.wavefront]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WavefrontConfig {
    /// Wavelength the coefficients are given at, µm (the optical path difference is
    /// coefficient × this wavelength at every wavelength).
    pub reference_wavelength_um: f64,
    /// Zernike convention (only `noll_rms`).
    #[serde(default)]
    pub zernike_convention: ZernikeConvention,
    /// `seidel` (full-field coefficients and the Seidel field law) or `table`.
    #[serde(default)]
    pub field_dependence: FieldLaw,
    /// Defocus W020 ρ² (with `seidel`: full-field values; must be absent with `table`).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub w020_waves: f64,
    /// Spherical aberration W040 ρ⁴.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub w040_waves: f64,
    /// Coma W131 ρ³ cos φ.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub w131_waves: f64,
    /// Astigmatism W222 ρ² cos² φ.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub w222_waves: f64,
    /// Field curvature W220 ρ².
    #[serde(default, skip_serializing_if = "is_zero")]
    pub w220_waves: f64,
    /// Distortion W311 ρ cos φ.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub w311_waves: f64,
    /// Noll Zernike coefficients, RMS waves: element i is Z_{i+1}.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub zernike_noll_rms_waves: Vec<f64>,
    /// Field points (`table`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub field_point: Vec<FieldPointConfig>,
    /// Number of radial spider vanes (0..=16).
    #[serde(default, skip_serializing_if = "u32_is_zero")]
    pub spider_vanes: u32,
    /// Vane width as a fraction of the aperture diameter, [0, 0.5).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub spider_width_fraction: f64,
    /// Direction of the first vane, degrees counter-clockwise from the sagittal axis.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub spider_angle_deg: f64,
    /// Pupil samples across the diameter for the imaging chain's OTFs (even, 32..=1024;
    /// default 256, refined for steep wavefronts). Fewer is faster and less exact
    /// (docs/wavefront.md, "Accuracy of the sampled pupil").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pupil_samples_across: Option<usize>,
    /// Zones per field axis of space-variant imaging (1..=16; K = zones² in all). Absent:
    /// chosen automatically from `zone_tolerance` (docs/wavefront.md, "Across the field").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zones_per_axis: Option<usize>,
    /// The largest error of a point source's image against direct space-variant
    /// summation, as a fraction of its PSF peak, that the automatic zone count aims at
    /// (0 < t ≤ 0.5; default 1e-3).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zone_tolerance: Option<f64>,
    /// The most zones per axis the automatic choice may take (1..=16; default 6).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_zones_per_axis: Option<usize>,
    /// Measure the zones' error on this run's frame: point sources at a few field
    /// positions (the middle, zone-cell centres, an edge midpoint, the corner) imaged
    /// through the zones and by exact direct space-variant summation, the largest
    /// difference reported in report.json (`wavefront_imaging.measured_error_of_peak`).
    /// Slow (one pupil computation per point, mirror copy and band); default false.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub measure_error: bool,
}

/// Default [`WavefrontConfig::zone_tolerance`].
pub const DEFAULT_ZONE_TOLERANCE: f64 = 1e-3;

/// Default [`WavefrontConfig::max_zones_per_axis`].
pub const DEFAULT_MAX_ZONES_PER_AXIS: usize = 6;

/// Largest zones per axis accepted.
pub const MAX_ZONES_PER_AXIS: usize = 16;

/// How the imaging chain uses `[optics.wavefront]` (the resolved imaging keys).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ZoneSettings {
    /// Pupil samples across the diameter (before refinement for steep wavefronts).
    pub pupil_samples_across: usize,
    /// Zones per axis if set by the user.
    pub zones_per_axis: Option<usize>,
    /// Target point-source error, fraction of the PSF peak.
    pub zone_tolerance: f64,
    /// Most zones per axis of the automatic choice.
    pub max_zones_per_axis: usize,
}

fn u32_is_zero(v: &u32) -> bool {
    *v == 0
}

const PREFIX: &str = "optics.wavefront.";

/// Prefixes the field of a parameter error with `optics.wavefront.`.
fn named(e: Error) -> Error {
    super::config::prefix_field("optics.wavefront", e)
}

impl WavefrontConfig {
    /// The wavefront model; errors name the `optics.wavefront.` key, its value and what is
    /// valid.
    pub fn model(&self) -> Result<WavefrontModel> {
        let lambda_um = self.reference_wavelength_um;
        if !(lambda_um.is_finite() && lambda_um > 0.0 && lambda_um <= 1000.0) {
            return Err(Error::param(
                format!("{PREFIX}reference_wavelength_um"),
                lambda_um,
                "a wavelength in (0, 1000] µm",
            ));
        }
        let top = coefficients_of!(self);
        let field = match self.field_dependence {
            FieldLaw::Seidel => {
                if !self.field_point.is_empty() {
                    return Err(Error::param(
                        format!("{PREFIX}field_point"),
                        format!("{} rows", self.field_point.len()),
                        "no field points with field_dependence = \"seidel\" (use \"table\")",
                    ));
                }
                FieldDependence::Seidel {
                    full_field: top.seidel,
                    zernike_rms_waves: top.zernike_noll_rms_waves,
                }
            }
            FieldLaw::Table => {
                if !top.is_empty() {
                    return Err(Error::param(
                        format!("{PREFIX}field_dependence"),
                        "\"table\"",
                        "coefficients only inside [[optics.wavefront.field_point]] rows \
                         (top-level w…_waves / zernike_noll_rms_waves are for \"seidel\")",
                    ));
                }
                FieldDependence::Table(
                    self.field_point
                        .iter()
                        .map(|p| {
                            let c = coefficients_of!(p);
                            (
                                p.h,
                                LocalWavefront {
                                    seidel: c.seidel,
                                    zernike_rms_waves: c.zernike_noll_rms_waves,
                                },
                            )
                        })
                        .collect(),
                )
            }
        };
        WavefrontModel::new(lambda_um * 1e-6, field).map_err(named)
    }

    /// The imaging keys, checked; errors name the key, its value and what is valid.
    pub fn zone_settings(&self) -> Result<ZoneSettings> {
        let samples = self
            .pupil_samples_across
            .unwrap_or(crate::wavefront::transfer::DEFAULT_SAMPLES_ACROSS);
        if !(32..=1024).contains(&samples) || samples % 2 != 0 {
            return Err(Error::param(
                format!("{PREFIX}pupil_samples_across"),
                samples,
                "an even number of pupil samples in 32..=1024",
            ));
        }
        for (key, v) in [
            ("zones_per_axis", self.zones_per_axis),
            ("max_zones_per_axis", self.max_zones_per_axis),
        ] {
            if let Some(v) = v {
                if !(1..=MAX_ZONES_PER_AXIS).contains(&v) {
                    return Err(Error::param(
                        format!("{PREFIX}{key}"),
                        v,
                        format!("an integer in 1..={MAX_ZONES_PER_AXIS}"),
                    ));
                }
            }
        }
        let tol = self.zone_tolerance.unwrap_or(DEFAULT_ZONE_TOLERANCE);
        if !(tol.is_finite() && tol > 0.0 && tol <= 0.5) {
            return Err(Error::param(
                format!("{PREFIX}zone_tolerance"),
                tol,
                "a fraction of the PSF peak in (0, 0.5]",
            ));
        }
        Ok(ZoneSettings {
            pupil_samples_across: samples,
            zones_per_axis: self.zones_per_axis,
            zone_tolerance: tol,
            max_zones_per_axis: self
                .max_zones_per_axis
                .unwrap_or(DEFAULT_MAX_ZONES_PER_AXIS),
        })
    }

    /// The pupil: the `[optics]` obscuration with these spider vanes.
    pub fn pupil(&self, obscuration_ratio: f64) -> Result<Pupil> {
        if !self.spider_angle_deg.is_finite() {
            return Err(Error::param(
                format!("{PREFIX}spider_angle_deg"),
                self.spider_angle_deg,
                "a finite angle in degrees",
            ));
        }
        Pupil::obscured(obscuration_ratio)
            .map_err(|e| match e {
                Error::InvalidParameter {
                    value, expected, ..
                } => Error::InvalidParameter {
                    field: "optics.obscuration_ratio".into(),
                    value,
                    expected,
                },
                other => other,
            })?
            .with_spider(
                self.spider_vanes,
                self.spider_width_fraction,
                self.spider_angle_deg.to_radians(),
            )
            .map_err(named)
    }
}

/// Checks `[optics.wavefront]`, if present, with the `[optics]` obscuration.
pub fn validate(optics: &super::config::OpticsConfig) -> Result<()> {
    if let Some(w) = &optics.wavefront {
        w.model()?;
        w.pupil(optics.obscuration_ratio)?;
        w.zone_settings()?;
    }
    Ok(())
}

/// The warning of a sensor with `[optics.wavefront]` and an enabled `[aberration]` or
/// `[defocus]`: the pupil's transfer function replaces them (and `[diffraction]`) in the
/// imaging chain, so they are not applied (docs/wavefront.md, "In the imaging chain").
pub fn cascade_warning(sensor: &super::SensorConfig) -> Option<String> {
    sensor.optics.wavefront.as_ref()?;
    let mut replaced = Vec::new();
    if sensor.aberration.as_ref().is_some_and(|a| a.enabled) {
        replaced.push("[aberration]");
    }
    if sensor.defocus.as_ref().is_some_and(|d| d.enabled) {
        replaced.push("[defocus]");
    }
    (!replaced.is_empty()).then(|| {
        format!(
            "[optics.wavefront] replaces {} in the imaging chain (the pupil's transfer \
             function holds the aperture and the whole wavefront): put the aberration into \
             the wavefront coefficients (e.g. w020_waves for defocus)",
            replaced.join(" and ")
        )
    })
}

/// The pupil PSF/OTF of a sensor at normalised field height `h` and `wavelength_m`: the
/// `[optics.wavefront]` wavefront and spider vanes, or a zero wavefront (diffraction only)
/// when the section is absent; the `[optics]` aperture and obscuration. The pupil sampling
/// is refined for steep wavefronts ([`Sampling::for_wavefront`]); `padding` is the grid
/// size over the pupil samples (2 for the OTF, 4 for PSF pictures).
pub fn pupil_transfer(
    config: &super::SensorConfig,
    h: f64,
    wavelength_m: f64,
    padding: usize,
) -> Result<PupilTransfer> {
    if !(h.is_finite() && (0.0..=1.0).contains(&h)) {
        return Err(Error::param(
            "field",
            h,
            "a normalised field height in [0, 1]",
        ));
    }
    let o = &config.optics;
    let diameter_m = o.focal_length_m / o.f_number;
    let (pupil, local, reference_m) = match &o.wavefront {
        Some(w) => {
            let model = w.model()?;
            (
                w.pupil(o.obscuration_ratio)?,
                model.at_field(h),
                model.reference_wavelength_m(),
            )
        }
        None => (
            Pupil::obscured(o.obscuration_ratio)?,
            LocalWavefront::default(),
            wavelength_m,
        ),
    };
    let sampling = Sampling::for_wavefront(&local, reference_m, wavelength_m, padding)?;
    PupilTransfer::compute(
        &pupil,
        &local,
        reference_m,
        wavelength_m,
        diameter_m,
        sampling,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> std::result::Result<WavefrontConfig, String> {
        toml::from_str::<WavefrontConfig>(text).map_err(|e| e.to_string())
    }

    #[test]
    fn parses_validates_and_names_bad_fields() {
        let c = parse("reference_wavelength_um = 4.0\nw131_waves = 0.2\nzernike_noll_rms_waves = [0, 0, 0, 0.05]\n")
            .unwrap();
        let m = c.model().unwrap();
        assert!((m.at_field(0.5).seidel.w131 - 0.1).abs() < 1e-15);
        let t = parse(
            "reference_wavelength_um = 4.0\nfield_dependence = \"table\"\n\
             [[field_point]]\nh = 0.0\n[[field_point]]\nh = 1.0\nw222_waves = 0.4\n",
        )
        .unwrap();
        assert!((t.model().unwrap().at_field(0.5).seidel.w222 - 0.2).abs() < 1e-15);
        let e = parse("reference_wavelength_um = -1.0\n")
            .unwrap()
            .model()
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("optics.wavefront.reference_wavelength_um") && e.contains("-1"),
            "{e}"
        );
        let e = parse(
            "reference_wavelength_um = 4.0\nfield_dependence = \"table\"\n\
             [[field_point]]\nh = 1.5\n",
        )
        .unwrap()
        .model()
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("optics.wavefront.field_point[0].h") && e.contains("[0, 1]"),
            "{e}"
        );
        let e = parse("reference_wavelength_um = 4.0\nw040_waves = 1e9\n")
            .unwrap()
            .model()
            .unwrap_err()
            .to_string();
        assert!(e.contains("optics.wavefront.w040_waves"), "{e}");
        let e = parse("reference_wavelength_um = 4.0\nspider_vanes = 40\n")
            .unwrap()
            .pupil(0.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("optics.wavefront.spider_vanes"), "{e}");
        for (text, key) in [
            ("zones_per_axis = 0", "optics.wavefront.zones_per_axis"),
            (
                "max_zones_per_axis = 17",
                "optics.wavefront.max_zones_per_axis",
            ),
            ("zone_tolerance = 2.0", "optics.wavefront.zone_tolerance"),
            (
                "pupil_samples_across = 33",
                "optics.wavefront.pupil_samples_across",
            ),
        ] {
            let e = parse(&format!("reference_wavelength_um = 4.0\n{text}\n"))
                .unwrap()
                .zone_settings()
                .unwrap_err()
                .to_string();
            assert!(e.contains(key), "{e}");
        }
        let z = parse("reference_wavelength_um = 4.0\nzones_per_axis = 3\n")
            .unwrap()
            .zone_settings()
            .unwrap();
        assert_eq!(z.zones_per_axis, Some(3));
        assert_eq!(z.zone_tolerance, DEFAULT_ZONE_TOLERANCE);
        assert!(parse("reference_wavelength_um = 4.0\nzernike_convention = \"fringe\"\n").is_err());
        assert!(parse("reference_wavelength_um = 4.0\nw999_waves = 1\n").is_err());
    }
}
