//! One parser for the radiance unit strings other tools write.
//!
//! A unit string is read as a product of factors, each a symbol with an optional integer
//! exponent: `W m-2 sr-1 um-1`, `W/(m2 sr um)`, `W.m^-2.sr^-1.nm^-1`, `uW/cm^2/sr/nm`,
//! `µW cm-2 sr-1 nm-1` (the AVIRIS convention), `W/m2-sr-µm`. Rules:
//!
//! - factors are separated by white space, `.`, `*`, `·` or `-` (a `-` is a minus sign
//!   only when a digit follows it: `m-2` is m⁻², `m2-sr` is m² then sr);
//! - `/` inverts the factor (or the `(…)` group, or the `-`-joined chain) that follows it;
//! - exponents are written `m2`, `m^2`, `m-2`, `m^-2`, `m^(-2)` is not supported;
//! - symbols (case-insensitive, `µ`/`μ` read as `u`): power `W`, `mW`, `uW`, `nW`, `kW`,
//!   `watt(s)`; length `m`, `cm`, `mm`, `um`, `nm`, `micron(s)`, `micrometer(s)`,
//!   `nanometer(s)`, `meter(s)`/`metre(s)` (also `centimeter`, `millimeter`); solid angle
//!   `sr`; and the words `spectral` / `band` (eoir's short forms).
//!
//! Dimensional check: power¹ · solid angle⁻¹ · length⁻² is band-integrated radiance,
//! power¹ · solid angle⁻¹ · length⁻³ is spectral radiance (per unit wavelength). The scale
//! to eoir's units follows from multiplying the SI value of every factor: a spectral
//! string with SI factor `f` (the value in W m-3 sr-1 per unit of the string) is
//! `f · 1e-6` W m-2 sr-1 µm-1 (1 µm = 1e-6 m), e.g. `W m-2 sr-1 nm-1` → 10⁹ · 10⁻⁶ = 1000,
//! `µW cm-2 sr-1 nm-1` → 10⁻⁶ · 10⁴ · 10⁹ · 10⁻⁶ = 10. Which length factor is the area
//! and which the wavelength does not matter for the product.

use super::RadianceUnits;

/// A parsed radiance unit: what the values are and the factor that converts them to
/// eoir's units (W m-2 sr-1 µm-1 for spectral radiance, W m-2 sr-1 for band-integrated).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RadianceScale {
    /// Spectral or band-integrated.
    pub units: RadianceUnits,
    /// Multiply stored values by this to get eoir's units.
    pub to_eoir: f64,
}

impl RadianceScale {
    /// eoir's own units, factor 1.
    pub fn identity(units: RadianceUnits) -> Self {
        RadianceScale {
            units,
            to_eoir: 1.0,
        }
    }
}

/// The unit spellings listed in error messages.
pub const EXAMPLES: &str = "`W m-2 sr-1 um-1`, `W/(m2 sr um)`, `W m-2 sr-1 nm-1`, `uW cm-2 sr-1 nm-1` (AVIRIS), `uW/cm^2/sr/nm`, or `W m-2 sr-1` (band-integrated)";

/// Dimension and SI factor (as a power of ten) of one unit symbol (already lower-cased,
/// µ → u).
fn symbol(s: &str) -> Option<(Dim, i32)> {
    let power = |f| Some((Dim::Power, f));
    let length = |f| Some((Dim::Length, f));
    match s {
        "w" | "watt" | "watts" => power(0),
        "kw" => power(3),
        "mw" => power(-3),
        "uw" | "microwatt" | "microwatts" => power(-6),
        "nw" => power(-9),
        "m" | "meter" | "meters" | "metre" | "metres" => length(0),
        "cm" | "centimeter" | "centimeters" | "centimetre" | "centimetres" => length(-2),
        "mm" | "millimeter" | "millimeters" | "millimetre" | "millimetres" => length(-3),
        "um" | "micron" | "microns" | "micrometer" | "micrometers" | "micrometre"
        | "micrometres" => length(-6),
        "nm" | "nanometer" | "nanometers" | "nanometre" | "nanometres" => length(-9),
        "sr" | "steradian" | "steradians" => Some((Dim::SolidAngle, 0)),
        _ => None,
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Dim {
    Power,
    Length,
    SolidAngle,
}

/// Parses a radiance unit string (see the module documentation); `None` if it is not a
/// radiance unit this parser understands.
pub fn parse_radiance(text: &str) -> Option<RadianceScale> {
    let t: String = text
        .trim()
        .to_lowercase()
        .replace(['µ', 'μ'], "u")
        .replace('·', ".");
    match t.as_str() {
        "spectral" | "spectral radiance" | "spectralradiance" => {
            return Some(RadianceScale::identity(RadianceUnits::SpectralPerUm))
        }
        "band" | "band-integrated" | "bandintegrated" | "band integrated" => {
            return Some(RadianceScale::identity(RadianceUnits::BandIntegrated))
        }
        _ => {}
    }
    let chars: Vec<char> = t.chars().collect();
    let mut i = 0;
    // Sign of the enclosing groups (stack), and whether a `/` applies to what follows.
    let mut groups: Vec<i32> = vec![1];
    let mut pending_div = false;
    // A `/` carried along a `-`-joined chain.
    let mut chain_div = false;
    let (mut p_exp, mut l_exp, mut sr_exp) = (0i32, 0i32, 0i32);
    // The SI factor is a power of ten, kept exact as its exponent.
    let mut exp10 = 0i32;
    let mut any = false;
    while i < chars.len() {
        let c = chars[i];
        if c.is_ascii_alphabetic() {
            let start = i;
            while i < chars.len() && chars[i].is_ascii_alphabetic() {
                i += 1;
            }
            let name: String = chars[start..i].iter().collect();
            // Exponent: optional `^`, optional sign (only before a digit), digits.
            let mut j = i;
            if j < chars.len() && chars[j] == '^' {
                j += 1;
            }
            let mut sign = 1;
            if j + 1 < chars.len()
                && (chars[j] == '-' || chars[j] == '+')
                && chars[j + 1].is_ascii_digit()
            {
                if chars[j] == '-' {
                    sign = -1;
                }
                j += 1;
            }
            let ds = j;
            while j < chars.len() && chars[j].is_ascii_digit() {
                j += 1;
            }
            let exp = if j > ds {
                let n: i32 = chars[ds..j].iter().collect::<String>().parse().ok()?;
                if n > 9 {
                    return None;
                }
                i = j;
                sign * n
            } else if j > i && chars[i] == '^' {
                return None;
            } else {
                1
            };
            let div = pending_div || chain_div;
            let group = *groups.last()?;
            let e = exp * group * if div { -1 } else { 1 };
            // A `-` directly after the factor followed by a letter joins a chain that
            // keeps the division.
            chain_div = div && i < chars.len() && chars[i] == '-';
            pending_div = false;
            let (dim, f) = symbol(&name)?;
            exp10 += f * e;
            match dim {
                Dim::Power => p_exp += e,
                Dim::Length => l_exp += e,
                Dim::SolidAngle => sr_exp += e,
            }
            any = true;
            continue;
        }
        match c {
            '/' => {
                if pending_div {
                    return None;
                }
                pending_div = true;
                chain_div = false;
            }
            '(' => {
                let g = *groups.last()? * if pending_div { -1 } else { 1 };
                groups.push(g);
                pending_div = false;
                chain_div = false;
            }
            ')' => {
                if groups.len() < 2 {
                    return None;
                }
                groups.pop();
                chain_div = false;
            }
            '-' => {} // a joiner (a minus sign is consumed with its exponent)
            ' ' | '\t' | '.' | '*' | ',' => chain_div = false,
            _ => return None,
        }
        i += 1;
    }
    if !any || groups.len() != 1 || pending_div || p_exp != 1 || sr_exp != -1 {
        return None;
    }
    // 10^k correctly rounded (10^|k| is exact in f64 for |k| ≤ 22).
    let pow10 = |k: i32| {
        if k >= 0 {
            10f64.powi(k)
        } else {
            1.0 / 10f64.powi(-k)
        }
    };
    match l_exp {
        -2 => Some(RadianceScale {
            units: RadianceUnits::BandIntegrated,
            to_eoir: pow10(exp10),
        }),
        // SI value in W m-3 sr-1; per µm is 1e-6 of per m.
        -3 => Some(RadianceScale {
            units: RadianceUnits::SpectralPerUm,
            to_eoir: pow10(exp10 - 6),
        }),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scale(s: &str) -> (RadianceUnits, f64) {
        let r = parse_radiance(s).unwrap_or_else(|| panic!("`{s}` did not parse"));
        (r.units, r.to_eoir)
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * b.abs()
    }

    #[test]
    fn spellings_per_um() {
        for s in [
            "W m-2 sr-1 um-1",
            "W/(m2 sr um)",
            "W/(m^2 sr µm)",
            "W.m^-2.sr^-1.um^-1",
            "W/m2/sr/um",
            "W/m^2/sr/micron",
            "W/m2-sr-um",
            "W/(m²sr µm)".replace('²', "2").as_str(),
            "watts/(m^2 sr micrometer)",
            "W·m-2·sr-1·μm-1",
            "spectral",
        ] {
            let (u, f) = scale(s);
            assert_eq!(u, RadianceUnits::SpectralPerUm, "{s}");
            assert!(close(f, 1.0), "{s}: {f}");
        }
    }

    #[test]
    fn per_nm_and_aviris() {
        for (s, want) in [
            ("W m-2 sr-1 nm-1", 1e3),
            ("W/(m2 sr nm)", 1e3),
            ("µW cm-2 sr-1 nm-1", 10.0),
            ("uW/cm^2/sr/nm", 10.0),
            ("microwatts/(cm2 sr nm)", 10.0),
            ("uW cm-2 sr-1 um-1", 1e-2),
            ("mW m-2 sr-1 nm-1", 1.0),
            ("W cm-2 sr-1 um-1", 1e4),
        ] {
            let (u, f) = scale(s);
            assert_eq!(u, RadianceUnits::SpectralPerUm, "{s}");
            assert!(close(f, want), "{s}: {f} vs {want}");
        }
    }

    #[test]
    fn band_integrated() {
        for (s, want) in [
            ("W m-2 sr-1", 1.0),
            ("W/(m2 sr)", 1.0),
            ("uW/cm2/sr", 1e-2),
            ("band", 1.0),
        ] {
            let (u, f) = scale(s);
            assert_eq!(u, RadianceUnits::BandIntegrated, "{s}");
            assert!(close(f, want), "{s}: {f}");
        }
    }

    #[test]
    fn rejects_non_radiance() {
        for s in [
            "",
            "W",
            "W m-2",
            "W m-2 sr-1 um-1 um-1",
            "K",
            "DN",
            "W/m2/sr/um/",
            "W/(m2 sr um",
            "counts",
        ] {
            assert!(parse_radiance(s).is_none(), "`{s}` should not parse");
        }
    }
}
