//! Spectral channel names and units of an OpenEXR cube: parsing a channel's name into its
//! wavelength and unit, the `emissiveUnits` density, and the number lists of attributes
//! (see the [parent module](super) for the conventions).

use std::path::Path;

use crate::constants::SPEED_OF_LIGHT_C;
use crate::error::{Error, Result};

/// A spectral unit of a channel name or a density: an SI-prefixed metre or hertz, kept as
/// the prefix's power of ten so that conversions like nm → µm are correctly rounded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum SpectralUnit {
    /// A length unit of 10^`exp10` m.
    Length { exp10: i32 },
    /// A frequency unit of 10^`exp10` Hz.
    Frequency { exp10: i32 },
}

/// `value · 10^k`, correctly rounded for |k| ≤ 22 (where 10^|k| is exact in f64).
pub(super) fn times_pow10(value: f64, k: i32) -> f64 {
    if k >= 0 {
        value * 10f64.powi(k)
    } else {
        value / 10f64.powi(-k)
    }
}

impl SpectralUnit {
    /// Parses `<prefix>m` or `<prefix>Hz` with the layout's SI prefixes (plus `µ`/`μ`).
    pub(super) fn parse(s: &str) -> Option<Self> {
        let (prefix, frequency) = if let Some(p) = s.strip_suffix("Hz") {
            (p, true)
        } else if let Some(p) = s.strip_suffix('m') {
            (p, false)
        } else {
            return None;
        };
        let exp10 = match prefix {
            "" => 0,
            "Y" => 24,
            "Z" => 21,
            "E" => 18,
            "P" => 15,
            "T" => 12,
            "G" => 9,
            "M" => 6,
            "k" => 3,
            "h" => 2,
            "da" => 1,
            "d" => -1,
            "c" => -2,
            "m" => -3,
            "u" | "µ" | "μ" => -6,
            "n" => -9,
            "p" => -12,
            _ => return None,
        };
        Some(if frequency {
            SpectralUnit::Frequency { exp10 }
        } else {
            SpectralUnit::Length { exp10 }
        })
    }

    /// Wavelength in µm of a channel whose name gives `value` in this unit (λ = c/ν for
    /// frequencies).
    pub(super) fn wavelength_um(self, value: f64) -> f64 {
        match self {
            SpectralUnit::Length { exp10 } => times_pow10(value, exp10 + 6),
            SpectralUnit::Frequency { exp10 } => {
                times_pow10(SPEED_OF_LIGHT_C / times_pow10(value, exp10), 6)
            }
        }
    }

    /// Factor turning a spectral density per this unit into one per µm at `wavelength_um`.
    ///
    /// Per length unit ℓ = 10^e m: `L_per_µm = L_per_unit · (1 µm / ℓ) = L_per_unit ·
    /// 10^(−6−e)`. Per frequency unit h = 10^e Hz: `L_ν = L_per_unit / h` per Hz, and
    /// `L_λ = L_ν · |dν/dλ| = L_ν · c / λ²` per metre (ν = c/λ), i.e.
    /// `L_per_µm = L_ν · c · 1e-6 / λ_m²`.
    pub(super) fn per_um_factor(self, wavelength_um: f64) -> f64 {
        match self {
            SpectralUnit::Length { exp10 } => times_pow10(1.0, -6 - exp10),
            SpectralUnit::Frequency { exp10 } => {
                let wavelength_m = wavelength_um * 1e-6;
                times_pow10(
                    SPEED_OF_LIGHT_C * 1e-6 / (wavelength_m * wavelength_m),
                    -exp10,
                )
            }
        }
    }
}

/// The kind of channel a name denotes under the layout.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum ChannelKind {
    /// `S<k>.…`: Stokes component `k` of emitted radiance (0 = total).
    Emissive(u8),
    /// `T.…`: reflectance (not radiance).
    Reflective,
}

/// A channel name parsed under the layout: kind, value and unit as written.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct SpectralName {
    pub(super) kind: ChannelKind,
    pub(super) value: f64,
    pub(super) unit: SpectralUnit,
    pub(super) unit_text: String,
}

/// Parses a channel name of the layout; `None` for anything else (RGB, depth, bi-spectral
/// re-radiation, malformed numbers…).
pub(super) fn parse_channel_name(name: &str) -> Option<SpectralName> {
    let (layer, rest) = name.split_once('.')?;
    let kind = match layer {
        "S0" => ChannelKind::Emissive(0),
        "S1" => ChannelKind::Emissive(1),
        "S2" => ChannelKind::Emissive(2),
        "S3" => ChannelKind::Emissive(3),
        "T" => ChannelKind::Reflective,
        _ => return None,
    };
    // Number: digits, optional comma, digits, optional exponent [Ee][+-]?digits.
    let bytes = rest.as_bytes();
    let mut i = 0;
    let mut digits = 0;
    while i < bytes.len() && bytes[i].is_ascii_digit() {
        i += 1;
        digits += 1;
    }
    if i < bytes.len() && bytes[i] == b',' {
        i += 1;
        while i < bytes.len() && bytes[i].is_ascii_digit() {
            i += 1;
            digits += 1;
        }
    }
    if digits == 0 {
        return None;
    }
    if i < bytes.len() && (bytes[i] == b'e' || bytes[i] == b'E') {
        let mut j = i + 1;
        if j < bytes.len() && (bytes[j] == b'+' || bytes[j] == b'-') {
            j += 1;
        }
        let start = j;
        while j < bytes.len() && bytes[j].is_ascii_digit() {
            j += 1;
        }
        // Without digits the letter is the exa prefix, not an exponent.
        if j > start {
            i = j;
        }
    }
    let number = rest[..i].replace(',', ".");
    let unit_text = &rest[i..];
    let unit = SpectralUnit::parse(unit_text)?;
    let value: f64 = number.parse().ok()?;
    if !(value.is_finite() && value > 0.0) {
        return None;
    }
    Some(SpectralName {
        kind,
        value,
        unit,
        unit_text: unit_text.to_string(),
    })
}

/// The name eoir gives the channel of a band centred on `wavelength_um`: nanometres with
/// six decimals and a comma, e.g. 0.55 µm → `S0.550,000000nm`.
pub fn channel_name(wavelength_um: f64) -> String {
    let value = format!("{:.6}", wavelength_um * 1e3).replace('.', ",");
    format!("S0.{value}nm")
}

/// Parses an `emissiveUnits` string such as `W.m^-2.sr^-1` or `W.m^-2.sr^-1.nm^-1`.
/// `Ok(Some(unit))` if it names a spectral density unit, `Ok(None)` for plain radiance,
/// `Err(())` if it is not a radiance unit eoir understands.
pub(super) fn parse_emissive_units(
    s: &str,
) -> std::result::Result<Option<(SpectralUnit, String)>, ()> {
    let mut watt = false;
    let mut area = false;
    let mut solid_angle = false;
    let mut density = None;
    for token in s.split(['.', ' ', '*']).filter(|t| !t.is_empty()) {
        match token {
            "W" if !watt => watt = true,
            "m^-2" | "m-2" if !area => area = true,
            "sr^-1" | "sr-1" if !solid_angle => solid_angle = true,
            t => {
                let per = t
                    .strip_suffix("^-1")
                    .or_else(|| t.strip_suffix("-1"))
                    .ok_or(())?;
                if density.is_some() {
                    return Err(());
                }
                density = Some((SpectralUnit::parse(per).ok_or(())?, per.to_string()));
            }
        }
    }
    if watt && area && solid_angle {
        Ok(density)
    } else {
        Err(())
    }
}

/// Formats values so that parsing them gives the same `f64` back.
pub(super) fn format_list(values: &[f64]) -> String {
    values
        .iter()
        .map(|v| format!("{v:?}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Parses a whitespace-separated list of numbers from attribute `name`.
pub(super) fn parse_list(path: &Path, name: &str, text: &str) -> Result<Vec<f64>> {
    text.split_whitespace()
        .map(|t| {
            t.parse::<f64>().map_err(|_| {
                Error::format(
                    path,
                    format!("attribute `{name}`: `{t}` is not a number (expected numbers separated by spaces)"),
                )
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_layout_names() {
        let n = parse_channel_name("S0.550,000000nm").unwrap();
        assert_eq!(n.kind, ChannelKind::Emissive(0));
        assert!((n.unit.wavelength_um(n.value) - 0.55).abs() < 1e-12);
        let n = parse_channel_name("S0.4,5um").unwrap();
        assert!((n.unit.wavelength_um(n.value) - 4.5).abs() < 1e-12);
        let n = parse_channel_name("S0.5E-7m").unwrap();
        assert!((n.unit.wavelength_um(n.value) - 0.5).abs() < 1e-12);
        // 'E' without digits is the exa prefix: 5 Em is a (silly but valid) wavelength.
        let n = parse_channel_name("S0.5Em").unwrap();
        assert_eq!(n.unit, SpectralUnit::Length { exp10: 18 });
        let n = parse_channel_name("S0.,5mm").unwrap();
        assert!((n.unit.wavelength_um(n.value) - 500.0).abs() < 1e-9);
        let n = parse_channel_name("S0.550,nm").unwrap();
        assert_eq!(n.value, 550.0);
        let n = parse_channel_name("S2.550nm").unwrap();
        assert_eq!(n.kind, ChannelKind::Emissive(2));
        let n = parse_channel_name("T.550nm").unwrap();
        assert_eq!(n.kind, ChannelKind::Reflective);
        // 600 THz = c / 600e12 m = 0.4997 µm.
        let n = parse_channel_name("S0.600THz").unwrap();
        let expected = 299_792_458.0 / 600e12 * 1e6;
        assert!((n.unit.wavelength_um(n.value) - expected).abs() < 1e-12);
        for bad in [
            "R",
            "S0",
            "S0.nm",
            "S0.550",
            "S0.550.0nm",
            "S4.550nm",
            "S0.550xm",
            "S0.550nm.600nm",
            "S0.0nm",
            "S0.550,0,0nm",
        ] {
            assert!(parse_channel_name(bad).is_none(), "{bad}");
        }
    }

    #[test]
    fn eoir_names_round_trip_to_1e6_nm() {
        for wl in [0.4, 0.55, 0.95, 1.0, 3.999_999_7, 12.345_678_9] {
            let name = channel_name(wl);
            let n = parse_channel_name(&name).unwrap();
            assert!((n.unit.wavelength_um(n.value) - wl).abs() < 1e-9, "{name}");
        }
        assert_eq!(channel_name(0.55), "S0.550,000000nm");
    }

    #[test]
    fn density_factors() {
        // Per nm → per µm: ×1000 (1 µm = 1000 nm).
        let nm = SpectralUnit::parse("nm").unwrap();
        assert!((nm.per_um_factor(0.5) - 1000.0).abs() < 1e-9);
        // Per Hz → per µm at 1 µm: a 1 µm-wide slice at 1 µm spans c/λ² · 1 µm = 2.998e14 Hz.
        let hz = SpectralUnit::parse("Hz").unwrap();
        let lam = 1e-6;
        let dnu = SPEED_OF_LIGHT_C / (lam - 0.5e-9) - SPEED_OF_LIGHT_C / (lam + 0.5e-9);
        let per_nm = hz.per_um_factor(1.0) / 1000.0;
        assert!((per_nm - dnu).abs() / dnu < 1e-6);
    }

    #[test]
    fn emissive_units_strings() {
        assert_eq!(parse_emissive_units("W.m^-2.sr^-1"), Ok(None));
        let (u, t) = parse_emissive_units("W.m^-2.sr^-1.nm^-1").unwrap().unwrap();
        assert_eq!(u, SpectralUnit::Length { exp10: -9 });
        assert_eq!(t, "nm");
        assert!(parse_emissive_units("W.m^-2").is_err());
        assert!(parse_emissive_units("cd.m^-2").is_err());
    }
}
