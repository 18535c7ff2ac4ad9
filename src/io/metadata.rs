//! The metadata path every cube reader shares: the wavelength grid check and band
//! order, the viewing geometry from the keys eoir writes and the ones other tools write,
//! and the radiance units through one parser ([`crate::scene::units`]).
//!
//! # Field of view: which key wins
//!
//! 1. `--fov-deg` on the command line (applied by the pipeline, always wins);
//! 2. eoir's own keys: a full field of view in degrees (`eoir fov deg` in ENVI, `fov_deg`
//!    in an NPY sidecar, `eoirFovDeg` in EXR) **or** the angular pixel spacing
//!    (`eoir ifov rad`, `ifov_rad`), never both;
//! 3. the common keys, in the order each reader lists them: ENVI `fov` (as written by
//!    SPy, `{h, v}`), `field of view`; EXR `fov_deg`, `fov`; NPY `fov`.
//!
//! A common key holds the horizontal and vertical full field of view in degrees, or one
//! number, the horizontal one, in which case the vertical follows from square samples
//! (`fov_y = fov_x · rows / cols`, the paraxial convention of [`Geometry`]). When a
//! lower-ranked key is also present and disagrees, the reader says so in its warnings.
//!
//! # Radiance units: which statement wins
//!
//! 1. `--radiance-units` (a [`ReadOptions::radiance_units`]);
//! 2. the unit statements of the file, in the order each reader lists them (eoir's key
//!    first); the first one present is used, later ones that disagree are warnings;
//! 3. the reader's documented default (spectral radiance per µm with a warning; for a
//!    spectral EXR, the unit of the channel names).
//!
//! Every reader records which of these applied in [`CubeReader::units_source`]
//! (`report.json`, `input.units_source`).
//!
//! [`CubeReader::units_source`]: super::CubeReader::units_source

use std::path::Path;

use crate::error::{Error, Result};
use crate::scene::units::{parse_radiance, RadianceScale, EXAMPLES};
use crate::scene::{Geometry, RadianceUnits};

/// Options that change how a file's metadata is read.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReadOptions {
    /// Radiance units to use instead of whatever the file states (`--radiance-units`), in
    /// any spelling [`parse_radiance`] understands.
    pub radiance_units: Option<String>,
    /// Read every band with `read()` into a buffer, never from a memory map of the file
    /// (`--no-mmap`). By default f32 planes stored contiguously in the machine's byte
    /// order (ENVI band-sequential, NPY `<f4`) are served zero-copy from maps
    /// ([`super::mapped`]), which is faster but ends the process with `SIGBUS` if another
    /// process truncates the file during the run.
    pub no_memory_map: bool,
}

impl ReadOptions {
    /// The parsed override, or an error naming `--radiance-units` and the valid spellings.
    pub fn radiance_override(&self) -> Result<Option<RadianceScale>> {
        self.radiance_units
            .as_deref()
            .map(|u| {
                parse_radiance(u).ok_or_else(|| {
                    Error::param(
                        "--radiance-units",
                        format!("`{u}`"),
                        format!("a radiance unit such as {EXAMPLES}"),
                    )
                })
            })
            .transpose()
    }
}

/// The units a reader settled on, and why (for warnings and the run report).
#[derive(Debug, Clone, PartialEq)]
pub struct ResolvedUnits {
    /// Units and the factor to eoir's units.
    pub scale: RadianceScale,
    /// Where they came from, e.g. ``stated: `radiance units = W/(m2 sr nm)` (x1000)``.
    pub source: String,
}

/// Describes a scale for messages: `` `key = value` `` plus the factor when it is not 1.
fn describe(key: &str, value: &str, scale: &RadianceScale) -> String {
    if (scale.to_eoir - 1.0).abs() < 1e-12 {
        format!("`{key} = {value}`")
    } else {
        format!(
            "`{key} = {value}` (values x {} to {})",
            scale.to_eoir,
            scale.units.as_str()
        )
    }
}

/// Resolves the radiance units from an override and the file's statements
/// `(key, value)` in precedence order (see the module documentation). `Ok(None)` when
/// neither exists: the caller applies its default rule.
///
/// Errors: an override that does not parse; a statement that does not parse when no
/// override is given (with an override it is a warning).
pub(crate) fn resolve_units(
    source: &Path,
    statements: &[(String, String)],
    options: &ReadOptions,
    warnings: &mut Vec<String>,
) -> Result<Option<ResolvedUnits>> {
    let over = options.radiance_override()?;
    let mut parsed = Vec::new();
    for (key, value) in statements {
        match parse_radiance(value) {
            Some(s) => parsed.push((key, value, s)),
            None if over.is_some() => warnings.push(format!(
                "{}: `{key} = {value}` is not a radiance unit eoir understands; ignored because --radiance-units is given",
                source.display()
            )),
            None => {
                return Err(Error::format(
                    source,
                    format!(
                        "{key} = `{value}` is not a radiance unit eoir understands; use e.g. {EXAMPLES}, or pass --radiance-units"
                    ),
                ))
            }
        }
    }
    if let Some(s) = over {
        let text = options.radiance_units.clone().unwrap_or_default();
        if let Some((key, value, f)) = parsed.first() {
            if !same(f, &s) {
                warnings.push(format!(
                    "{}: the file states `{key} = {value}`; --radiance-units {text} overrides it",
                    source.display()
                ));
            }
        }
        return Ok(Some(ResolvedUnits {
            scale: s,
            source: format!("override: {}", describe("--radiance-units", &text, &s)),
        }));
    }
    let Some((key, value, first)) = parsed.first().cloned() else {
        return Ok(None);
    };
    for (k, v, s) in parsed.iter().skip(1) {
        if !same(s, &first) {
            warnings.push(format!(
                "{}: `{k} = {v}` disagrees with `{key} = {value}`, which takes precedence",
                source.display()
            ));
        }
    }
    Ok(Some(ResolvedUnits {
        scale: first,
        source: format!("stated: {}", describe(key, value, &first)),
    }))
}

/// Whether two scales mean the same thing.
fn same(a: &RadianceScale, b: &RadianceScale) -> bool {
    a.units == b.units && (a.to_eoir - b.to_eoir).abs() <= 1e-12 * a.to_eoir.abs()
}

/// The default when nothing states the units: spectral radiance per µm, with a warning
/// naming the keys that were looked for.
pub(crate) fn default_units(
    source: &Path,
    keys: &str,
    warnings: &mut Vec<String>,
) -> ResolvedUnits {
    warnings.push(format!(
        "{}: no {keys}: no radiance unit is stated, so the values are taken as spectral radiance, {} (pass --radiance-units to choose)",
        source.display(),
        RadianceUnits::SpectralPerUm.as_str()
    ));
    ResolvedUnits {
        scale: RadianceScale::identity(RadianceUnits::SpectralPerUm),
        source: format!(
            "assumed: nothing stated, taken as {}",
            RadianceUnits::SpectralPerUm.as_str()
        ),
    }
}

/// Full field of view from a common key: `[h, v]` degrees, or `[h]` with the vertical
/// from square samples (`v = h · rows / cols`).
pub(crate) fn fov_from_values(
    source: &Path,
    key: &str,
    values: &[f64],
    rows: usize,
    cols: usize,
) -> Result<[f64; 2]> {
    let fov = match values {
        [h, v] => [*h, *v],
        [h] => [*h, h * rows as f64 / cols as f64],
        _ => {
            return Err(Error::format(
                source,
                format!(
                    "`{key}` has {} values; expected the full field of view in degrees, `{{horizontal, vertical}}` or one horizontal value",
                    values.len()
                ),
            ))
        }
    };
    for (name, x) in [("horizontal", fov[0]), ("vertical", fov[1])] {
        if !(x.is_finite() && x > 0.0 && x < 180.0) {
            return Err(Error::format(
                source,
                format!("`{key}`: {name} field of view {x} must be in (0, 180) degrees"),
            ));
        }
    }
    Ok(fov)
}

/// Geometry from eoir's own keys (a full field of view `own_fov` or a pixel spacing
/// `own_ifov`, named by `keys` = `[fov, ifov, range]` as in [`geometry_from`]) or else the
/// first common field-of-view key present in `common` (`(key, values)` in precedence
/// order, see [`fov_from_values`]). Common keys that are present and disagree with the
/// field of view used are warnings.
#[allow(clippy::too_many_arguments)]
pub(crate) fn resolve_geometry(
    source: &Path,
    keys: [&str; 3],
    own_fov: Option<[f64; 2]>,
    own_ifov: Option<[f64; 2]>,
    common: &[(String, Vec<f64>)],
    range_m: Option<f64>,
    rows: usize,
    cols: usize,
    warnings: &mut Vec<String>,
) -> Result<Option<Geometry>> {
    let mut found: Vec<(&str, [f64; 2])> = Vec::new();
    for (key, values) in common {
        found.push((key, fov_from_values(source, key, values, rows, cols)?));
    }
    let (used_key, geometry) = match found.first() {
        Some((key, [h, v])) if own_fov.is_none() && own_ifov.is_none() => {
            let g = geometry_from(source, keys, Some([*h, *v]), None, range_m, rows, cols)?;
            (format!("`{key}`"), g)
        }
        _ => (
            format!("{} / {}", keys[0], keys[1]),
            geometry_from(source, keys, own_fov, own_ifov, range_m, rows, cols)?,
        ),
    };
    let Some(g) = geometry else {
        return Ok(None);
    };
    for (key, [h, v]) in &found {
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-6 * b.abs();
        if format!("`{key}`") != used_key && !(close(*h, g.fov_x_deg) && close(*v, g.fov_y_deg)) {
            warnings.push(format!(
                "{}: `{key}` = {{{h}, {v}}} degrees disagrees with {used_key} ({}, {} degrees), which takes precedence",
                source.display(),
                g.fov_x_deg,
                g.fov_y_deg
            ));
        }
    }
    Ok(Some(g))
}

/// A spectral grid in increasing order and how it maps onto the stored bands.
pub(crate) struct BandOrder {
    /// Band centres, µm, strictly increasing.
    pub(crate) wavelength_um: Vec<f64>,
    /// Band widths, µm, in the same order.
    pub(crate) fwhm_um: Option<Vec<f64>>,
    /// Output band index → stored band index.
    pub(crate) band_map: Vec<usize>,
    /// Whether the stored order was reversed.
    pub(crate) reversed: bool,
}

/// Checks a wavelength list (µm) and brings it into strictly increasing order. A strictly
/// decreasing list is reversed; any other order is an error naming the first pair out of
/// order.
pub(crate) fn order_bands(
    source: &Path,
    wavelength_um: Vec<f64>,
    fwhm_um: Option<Vec<f64>>,
) -> Result<BandOrder> {
    if wavelength_um.is_empty() {
        return Err(Error::format(source, "the wavelength list is empty"));
    }
    if let Some((i, w)) = wavelength_um
        .iter()
        .enumerate()
        .find(|(_, w)| !(w.is_finite() && **w > 0.0))
    {
        return Err(Error::format(
            source,
            format!("wavelength[{i}] = {w} µm is not a positive number"),
        ));
    }
    if let Some(f) = &fwhm_um {
        if f.len() != wavelength_um.len() {
            return Err(Error::format(
                source,
                format!(
                    "{} fwhm values for {} wavelengths",
                    f.len(),
                    wavelength_um.len()
                ),
            ));
        }
    }
    let n = wavelength_um.len();
    let increasing = wavelength_um.windows(2).all(|w| w[1] > w[0]);
    let decreasing = wavelength_um.windows(2).all(|w| w[1] < w[0]);
    if increasing {
        return Ok(BandOrder {
            wavelength_um,
            fwhm_um,
            band_map: (0..n).collect(),
            reversed: false,
        });
    }
    if decreasing {
        let mut wl = wavelength_um;
        wl.reverse();
        let fw = fwhm_um.map(|mut f| {
            f.reverse();
            f
        });
        return Ok(BandOrder {
            wavelength_um: wl,
            fwhm_um: fw,
            band_map: (0..n).rev().collect(),
            reversed: true,
        });
    }
    // Name the first pair that breaks the direction the list starts in.
    let up = wavelength_um[1] > wavelength_um[0];
    let i = wavelength_um
        .windows(2)
        .position(|w| if up { w[1] <= w[0] } else { w[1] >= w[0] })
        .unwrap_or(0);
    Err(Error::format(
        source,
        format!(
            "wavelengths must be strictly increasing or strictly decreasing, but wavelength[{i}] = {} µm and wavelength[{}] = {} µm break the order",
            wavelength_um[i],
            i + 1,
            wavelength_um[i + 1]
        ),
    ))
}

/// Builds the cube geometry from either a full field of view (degrees) or an angular
/// pixel spacing (rad), plus an optional range; `keys` names the fields for messages as
/// `[fov, ifov, range]`.
pub(crate) fn geometry_from(
    source: &Path,
    keys: [&str; 3],
    fov_deg: Option<[f64; 2]>,
    ifov_rad: Option<[f64; 2]>,
    range_m: Option<f64>,
    rows: usize,
    cols: usize,
) -> Result<Option<Geometry>> {
    let [k_fov, k_ifov, k_range] = keys;
    if let Some(r) = range_m {
        if !(r.is_finite() && r > 0.0) {
            return Err(Error::format(
                source,
                format!("{k_range} = {r}: expected a range > 0 m"),
            ));
        }
    }
    let mut g = match (fov_deg, ifov_rad) {
        (Some(_), Some(_)) => {
            return Err(Error::format(
                source,
                format!("both {k_fov} and {k_ifov} are given; give only one of them"),
            ))
        }
        (None, None) => {
            if range_m.is_some() {
                return Err(Error::format(
                    source,
                    format!("{k_range} is given without a field of view; add {k_fov} = [h, v] (degrees) or {k_ifov} = [x, y] (rad)"),
                ));
            }
            return Ok(None);
        }
        (Some([h, v]), None) => {
            for (name, x) in [("horizontal", h), ("vertical", v)] {
                if !(x.is_finite() && x > 0.0 && x < 180.0) {
                    return Err(Error::format(
                        source,
                        format!("{k_fov}: {name} field of view {x} must be in (0, 180) degrees"),
                    ));
                }
            }
            Geometry {
                fov_x_deg: h,
                fov_y_deg: v,
                range_m: None,
            }
        }
        (None, Some([x, y])) => {
            for (name, a) in [("x", x), ("y", y)] {
                if !(a.is_finite() && a > 0.0) {
                    return Err(Error::format(
                        source,
                        format!("{k_ifov}: {name} pixel spacing {a} must be > 0 rad"),
                    ));
                }
            }
            Geometry::from_ifov(x, y, rows, cols)
        }
    };
    g.range_m = range_m;
    Ok(Some(g))
}
