//! Spectral curves — value against wavelength in µm — for filters, quantum efficiencies,
//! transmissions and band responses, plus trapezoid integration weights on a wavelength grid.
//!
//! A [`Spectrum`] is either an analytic shape (constant, top-hat, Gaussian, ideal photon
//! detector), a sampled table, or an exact pointwise product of those. Analytic shapes are
//! evaluated exactly rather than through a sampled table, so band integrals of Gaussians and
//! top-hats reach the accuracy of the quadrature (see `radiometry::integrate`) instead of the
//! accuracy of a coarse grid.
//!
//! Domain: every spectrum is defined for wavelengths λ > 0. [`Spectrum::eval`] returns 0 for
//! λ ≤ 0 and NaN for a NaN wavelength.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{require_non_negative, Error, Result};

/// Number of standard deviations at which a Gaussian is truncated: exp(−8.5²/2) ≈ 2.0e-16,
/// so the truncated tail changes the curve by ~1e-16 relative to its peak.
const GAUSSIAN_TRUNCATION_SIGMA: f64 = 8.5;

/// FWHM = 2√(2 ln 2) σ for a Gaussian.
const FWHM_PER_SIGMA: f64 = 2.354_820_045_030_949_3;

/// The analytic or sampled shape behind a [`Spectrum`].
#[derive(Debug, Clone, PartialEq)]
enum Kind {
    /// The same value at every λ > 0.
    Constant { value: f64 },
    /// Top-hat with linear edges; `lo_um`/`hi_um` are the 50 % points, `edge_um` the full
    /// width of each edge (0 = sharp).
    TopHat {
        lo_um: f64,
        hi_um: f64,
        edge_um: f64,
        peak: f64,
    },
    /// Gaussian peak · exp(−(λ − c)²/(2σ²)), truncated at c ± 8.5 σ.
    Gaussian {
        center_um: f64,
        sigma_um: f64,
        peak: f64,
    },
    /// Ideal photon detector QE: scale · λ/λc for 0 < λ ≤ λc.
    PhotonDetector { scale: f64, cutoff_um: f64 },
    /// Linear interpolation of sampled values, zero outside [first, last].
    Table {
        wavelength_um: Vec<f64>,
        value: Vec<f64>,
    },
    /// Pointwise product of at least two non-constant factors (never nested).
    Product { factors: Vec<Kind> },
}

/// A spectral curve: a dimensionless or dimensioned value against wavelength in µm.
///
/// Build one with [`Spectrum::constant`], [`Spectrum::top_hat`], [`Spectrum::gaussian`],
/// [`Spectrum::photon_detector`], [`Spectrum::table`] or [`Spectrum::from_csv`], and combine
/// them with [`Spectrum::product`] (exact, evaluated pointwise) and [`Spectrum::scaled`].
#[derive(Debug, Clone, PartialEq)]
pub struct Spectrum {
    kind: Kind,
}

impl Spectrum {
    /// The same `value` at every wavelength λ > 0 (e.g. a grey transmission). Its support
    /// is unbounded: `(0, +inf)`.
    pub fn constant(value: f64) -> Spectrum {
        Spectrum {
            kind: Kind::Constant { value },
        }
    }

    /// A top-hat band with its 50 % points at `lo_um` and `hi_um` and value `peak` inside.
    ///
    /// Each edge is a linear ramp of full width `edge_width_um` centred on `lo_um` (resp.
    /// `hi_um`), so the curve is 0 below `lo_um − edge/2`, rises linearly to `peak` at
    /// `lo_um + edge/2`, and mirrors that at the upper edge. Its integral is therefore
    /// exactly `peak · (hi_um − lo_um)` for any edge width. With `edge_width_um = 0` the edges
    /// are sharp and the value is `peak` on the closed interval `[lo_um, hi_um]`.
    ///
    /// Errors: non-finite bounds, `lo_um ≥ hi_um`, `edge_width_um < 0`,
    /// `edge_width_um > hi_um − lo_um`, a ramp starting below λ = 0
    /// (`lo_um − edge/2 < 0`), or `peak` negative or not finite.
    pub fn top_hat(lo_um: f64, hi_um: f64, edge_width_um: f64, peak: f64) -> Result<Spectrum> {
        if !lo_um.is_finite() {
            return Err(Error::param("lo_um", lo_um, "a finite wavelength in µm"));
        }
        if !hi_um.is_finite() || hi_um <= lo_um {
            return Err(Error::param(
                "hi_um",
                hi_um,
                format!("a finite wavelength in µm greater than lo_um = {lo_um}"),
            ));
        }
        if !edge_width_um.is_finite() || edge_width_um < 0.0 || edge_width_um > hi_um - lo_um {
            return Err(Error::param(
                "edge_width_um",
                edge_width_um,
                format!(
                    "a width in µm within [0, hi_um − lo_um = {}]",
                    hi_um - lo_um
                ),
            ));
        }
        if lo_um - 0.5 * edge_width_um < 0.0 {
            return Err(Error::param(
                "lo_um",
                lo_um,
                format!(
                    "a wavelength in µm with lo_um − edge_width_um/2 ≥ 0 (edge_width_um = {edge_width_um})"
                ),
            ));
        }
        crate::error::require_non_negative("peak", peak)?;
        Ok(Spectrum {
            kind: Kind::TopHat {
                lo_um,
                hi_um,
                edge_um: edge_width_um,
                peak,
            },
        })
    }

    /// A Gaussian band `peak · exp(−(λ − center)²/(2σ²))`, σ = FWHM / (2√(2 ln 2)).
    ///
    /// The curve is truncated to `center ± 8.5 σ` (and to λ > 0): the discarded tail is
    /// below 2.1e-16 of the peak everywhere and ~1e-16 relative of the integral, so
    /// [`Spectrum::support_um`] is finite and [`Spectrum::eval`] is exactly 0 outside it.
    ///
    /// Errors: `center_um` or `fwhm_um` not finite and > 0, `peak` negative or not finite.
    pub fn gaussian(center_um: f64, fwhm_um: f64, peak: f64) -> Result<Spectrum> {
        crate::error::require_positive("center_um", center_um)?;
        crate::error::require_positive("fwhm_um", fwhm_um)?;
        crate::error::require_non_negative("peak", peak)?;
        Ok(Spectrum {
            kind: Kind::Gaussian {
                center_um,
                sigma_um: fwhm_um / FWHM_PER_SIGMA,
                peak,
            },
        })
    }

    /// Relative spectral responsivity *per unit power* of an ideal photon detector with
    /// cut-off wavelength `cutoff_um`: `eta_peak · λ/λc` for 0 < λ ≤ λc and 0 above (every
    /// photon above the band-gap energy yields one electron, so the signal per watt rises
    /// linearly with λ — the "relative response" R_rel(λ) of the FOI report).
    ///
    /// This is **not** a quantum efficiency: eoir's spectral chain already converts power
    /// to photons with λ/(hc), so using this curve as electrons per photon would count λ
    /// twice. The quantum efficiency of the same ideal detector is flat:
    /// [`Spectrum::ideal_quantum_efficiency`].
    ///
    /// Errors: `eta_peak` outside (0, 1], `cutoff_um` not finite and > 0.
    pub fn photon_detector(eta_peak: f64, cutoff_um: f64) -> Result<Spectrum> {
        Self::check_photon_detector(eta_peak, cutoff_um)?;
        Ok(Spectrum {
            kind: Kind::PhotonDetector {
                scale: eta_peak,
                cutoff_um,
            },
        })
    }

    /// Quantum efficiency (electrons per photon) of an ideal photon detector: `eta` at every
    /// wavelength up to the cut-off `cutoff_um`, 0 above.
    ///
    /// Errors: `eta` outside (0, 1], `cutoff_um` not finite and > 0.
    pub fn ideal_quantum_efficiency(eta: f64, cutoff_um: f64) -> Result<Spectrum> {
        Self::check_photon_detector(eta, cutoff_um)?;
        // A sharp top-hat from just above 0 µm; its lower 50 % point is far below any
        // optical band.
        Spectrum::top_hat(1e-6_f64.min(cutoff_um / 2.0), cutoff_um, 0.0, eta)
    }

    fn check_photon_detector(eta_peak: f64, cutoff_um: f64) -> Result<()> {
        if !(eta_peak.is_finite() && eta_peak > 0.0 && eta_peak <= 1.0) {
            return Err(Error::param(
                "eta_peak",
                eta_peak,
                "a quantum efficiency in (0, 1]",
            ));
        }
        if !(cutoff_um.is_finite() && cutoff_um > 0.0) {
            return Err(Error::param(
                "cutoff_um",
                cutoff_um,
                "a finite cut-off wavelength > 0 µm",
            ));
        }
        Ok(())
    }

    /// A sampled curve, linearly interpolated between the nodes and **zero outside
    /// `[first, last]` wavelength** (a filter or QE table ends where its data ends; it is
    /// not extrapolated). Note that this makes a jump at either end when the end values
    /// are not zero; [`Spectrum::breakpoints_um`] lists the nodes so quadrature splits there.
    ///
    /// Errors: different lengths, fewer than 2 points, a wavelength not finite and > 0,
    /// wavelengths not strictly increasing, a value not finite or negative.
    pub fn table(wavelength_um: Vec<f64>, value: Vec<f64>) -> Result<Spectrum> {
        if wavelength_um.len() != value.len() {
            return Err(Error::param(
                "value",
                format!("{} entries", value.len()),
                format!("as many values as wavelengths ({})", wavelength_um.len()),
            ));
        }
        if wavelength_um.len() < 2 {
            return Err(Error::param(
                "wavelength_um",
                format!("{} entries", wavelength_um.len()),
                "at least 2 points",
            ));
        }
        for (i, (&w, &v)) in wavelength_um.iter().zip(&value).enumerate() {
            if !(w.is_finite() && w > 0.0) {
                return Err(Error::param(
                    format!("wavelength_um[{i}]"),
                    w,
                    "a finite wavelength in µm > 0",
                ));
            }
            if i > 0 && w <= wavelength_um[i - 1] {
                return Err(Error::param(
                    format!("wavelength_um[{i}]"),
                    w,
                    format!(
                        "strictly increasing wavelengths (previous is {})",
                        wavelength_um[i - 1]
                    ),
                ));
            }
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::param(
                    format!("value[{i}]"),
                    v,
                    "a finite number >= 0",
                ));
            }
        }
        Ok(Spectrum {
            kind: Kind::Table {
                wavelength_um,
                value,
            },
        })
    }

    /// Reads a two-column text table (wavelength in µm, value) into [`Spectrum::table`].
    ///
    /// Columns may be separated by commas, semicolons, tabs or spaces (runs of separators
    /// count as one). Everything after a `#` is a comment; blank lines are skipped. The first
    /// content line may be a header: it is recognised by its first field not being a number.
    /// Any other line must hold exactly two numbers. Errors name the file, the line number
    /// and the offending text; table rules (increasing λ > 0, finite values ≥ 0, ≥ 2 rows)
    /// are checked with line numbers too.
    pub fn from_csv(path: &Path) -> Result<Spectrum> {
        let text = crate::input::read_text(path)?;
        let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
        let mut wavelength_um = Vec::new();
        let mut value = Vec::new();
        let mut prev: Option<(usize, f64)> = None;
        let mut seen_content = false;
        for (index, raw_line) in text.lines().enumerate() {
            let line_no = index + 1;
            let content = match raw_line.find('#') {
                Some(pos) => &raw_line[..pos],
                None => raw_line,
            };
            let fields: Vec<&str> = content
                .split(|c: char| c == ',' || c == ';' || c.is_whitespace())
                .filter(|s| !s.is_empty())
                .collect();
            if fields.is_empty() {
                continue;
            }
            let first_content = !seen_content;
            seen_content = true;
            if first_content && fields[0].parse::<f64>().is_err() {
                // The one optional header line.
                continue;
            }
            if fields.len() != 2 {
                return Err(Error::format(
                    path,
                    format!(
                        "line {line_no}: expected 2 columns (wavelength µm, value) separated by commas, semicolons or spaces, found {}",
                        fields.len()
                    ),
                ));
            }
            let mut numbers = [0.0; 2];
            for (k, (field, name)) in fields.iter().zip(["wavelength", "value"]).enumerate() {
                numbers[k] = field.parse::<f64>().map_err(|_| {
                    Error::format(
                        path,
                        format!(
                            "line {line_no}, column {}: expected the {name} as a number (the file's text is not shown)",
                            k + 1
                        ),
                    )
                })?;
            }
            let [w, v] = numbers;
            if !(w.is_finite() && w > 0.0) {
                return Err(Error::format(
                    path,
                    format!("line {line_no}: wavelength {w}: expected a finite number of µm > 0"),
                ));
            }
            if let Some((prev_line, prev_w)) = prev {
                if w <= prev_w {
                    return Err(Error::format(
                        path,
                        format!(
                            "line {line_no}: wavelength {w} µm is not greater than {prev_w} µm on line {prev_line}; wavelengths must strictly increase"
                        ),
                    ));
                }
            }
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::format(
                    path,
                    format!("line {line_no}: value {v}: expected a finite number >= 0"),
                ));
            }
            prev = Some((line_no, w));
            wavelength_um.push(w);
            value.push(v);
        }
        if wavelength_um.len() < 2 {
            return Err(Error::format(
                path,
                format!(
                    "found {} data row(s); a spectrum table needs at least 2 (wavelength µm, value)",
                    wavelength_um.len()
                ),
            ));
        }
        Spectrum::table(wavelength_um, value).map_err(|e| Error::format(path, e.to_string()))
    }

    /// The curve's value at `wavelength_um`: 0 for λ ≤ 0 and outside
    /// [`Spectrum::support_um`], NaN for a NaN wavelength.
    pub fn eval(&self, wavelength_um: f64) -> f64 {
        if wavelength_um.is_nan() {
            return f64::NAN;
        }
        if wavelength_um <= 0.0 {
            return 0.0;
        }
        self.kind.eval(wavelength_um)
    }

    /// The exact pointwise product `self(λ) · other(λ)` (e.g. filter × optics × QE). It is
    /// not resampled: each factor keeps its own analytic form or table.
    pub fn product(&self, other: &Spectrum) -> Spectrum {
        let kind = match (&self.kind, &other.kind) {
            (Kind::Constant { value: a }, Kind::Constant { value: b }) => {
                Kind::Constant { value: a * b }
            }
            (Kind::Constant { value }, k) | (k, Kind::Constant { value }) => k.scaled(*value),
            (a, b) => {
                let mut factors = Vec::new();
                for k in [a, b] {
                    match k {
                        Kind::Product { factors: f } => factors.extend(f.iter().cloned()),
                        other => factors.push(other.clone()),
                    }
                }
                Kind::Product { factors }
            }
        };
        Spectrum { kind }
    }

    /// The curve multiplied by `factor` at every wavelength.
    pub fn scaled(&self, factor: f64) -> Spectrum {
        Spectrum {
            kind: self.kind.scaled(factor),
        }
    }

    /// A closed interval `(lo, hi)` in µm outside which [`Spectrum::eval`] is 0.
    ///
    /// Constant → `(0, +inf)`; top-hat → the feet of its edge ramps; Gaussian →
    /// `center ± 8.5 σ` (lower end clipped at 0; see [`Spectrum::gaussian`] for the
    /// ~1e-16 truncation); photon detector → `(0, cutoff)`; table → first and last node;
    /// product → the intersection of its factors' supports. When that intersection is
    /// empty the product is 0 everywhere and a degenerate interval `(x, x)` is returned.
    pub fn support_um(&self) -> (f64, f64) {
        self.kind.support()
    }

    /// Sorted, de-duplicated wavelengths (µm) where the curve has a kink or a jump (top-hat
    /// edge corners, the photon-detector cut-off, table nodes, the union over the factors of
    /// a product). Quadrature should split there. Empty for constants and Gaussians.
    pub fn breakpoints_um(&self) -> Vec<f64> {
        let mut points = Vec::new();
        self.kind.push_breakpoints(&mut points);
        points.sort_by(f64::total_cmp);
        points.dedup();
        points
    }

    /// The largest value the curve takes: exact for a single shape (constant, top-hat and
    /// Gaussian peak, photon-detector value at cut-off, table maximum), and for a product
    /// the product of its factors' peaks (an upper bound). Used to reject a transmission
    /// or quantum efficiency above 1.
    pub fn peak_value(&self) -> f64 {
        fn peak(k: &Kind) -> f64 {
            match k {
                Kind::Constant { value } => *value,
                Kind::TopHat { peak, .. } | Kind::Gaussian { peak, .. } => *peak,
                Kind::PhotonDetector { scale, .. } => *scale,
                Kind::Table { value, .. } => value.iter().copied().fold(0.0, f64::max),
                Kind::Product { factors } => factors.iter().map(peak).product(),
            }
        }
        peak(&self.kind)
    }

    /// The curve evaluated at each wavelength of `grid_um` (µm).
    pub fn resample(&self, grid_um: &[f64]) -> Vec<f64> {
        grid_um.iter().map(|&w| self.eval(w)).collect()
    }
}

impl Kind {
    /// Value at λ > 0 (the caller handles λ ≤ 0 and NaN).
    fn eval(&self, w: f64) -> f64 {
        match self {
            Kind::Constant { value } => *value,
            Kind::TopHat {
                lo_um,
                hi_um,
                edge_um,
                peak,
            } => {
                if *edge_um == 0.0 {
                    if w >= *lo_um && w <= *hi_um {
                        *peak
                    } else {
                        0.0
                    }
                } else {
                    let half = 0.5 * edge_um;
                    let rise = (w - (lo_um - half)) / edge_um;
                    let fall = ((hi_um + half) - w) / edge_um;
                    peak * rise.min(fall).clamp(0.0, 1.0)
                }
            }
            Kind::Gaussian {
                center_um,
                sigma_um,
                peak,
            } => {
                let z = (w - center_um) / sigma_um;
                if z.abs() > GAUSSIAN_TRUNCATION_SIGMA {
                    0.0
                } else {
                    peak * (-0.5 * z * z).exp()
                }
            }
            Kind::PhotonDetector { scale, cutoff_um } => {
                if w <= *cutoff_um {
                    scale * w / cutoff_um
                } else {
                    0.0
                }
            }
            Kind::Table {
                wavelength_um,
                value,
            } => table_eval(wavelength_um, value, w),
            Kind::Product { factors } => {
                let mut p = 1.0;
                for f in factors {
                    p *= f.eval(w);
                    if p == 0.0 {
                        break;
                    }
                }
                p
            }
        }
    }

    fn scaled(&self, factor: f64) -> Kind {
        match self {
            Kind::Constant { value } => Kind::Constant {
                value: value * factor,
            },
            Kind::TopHat {
                lo_um,
                hi_um,
                edge_um,
                peak,
            } => Kind::TopHat {
                lo_um: *lo_um,
                hi_um: *hi_um,
                edge_um: *edge_um,
                peak: peak * factor,
            },
            Kind::Gaussian {
                center_um,
                sigma_um,
                peak,
            } => Kind::Gaussian {
                center_um: *center_um,
                sigma_um: *sigma_um,
                peak: peak * factor,
            },
            Kind::PhotonDetector { scale, cutoff_um } => Kind::PhotonDetector {
                scale: scale * factor,
                cutoff_um: *cutoff_um,
            },
            Kind::Table {
                wavelength_um,
                value,
            } => Kind::Table {
                wavelength_um: wavelength_um.clone(),
                value: value.iter().map(|v| v * factor).collect(),
            },
            Kind::Product { factors } => {
                let mut factors = factors.clone();
                if let Some(first) = factors.first_mut() {
                    *first = first.scaled(factor);
                }
                Kind::Product { factors }
            }
        }
    }

    fn support(&self) -> (f64, f64) {
        match self {
            Kind::Constant { .. } => (0.0, f64::INFINITY),
            Kind::TopHat {
                lo_um,
                hi_um,
                edge_um,
                ..
            } => (lo_um - 0.5 * edge_um, hi_um + 0.5 * edge_um),
            Kind::Gaussian {
                center_um,
                sigma_um,
                ..
            } => (
                (center_um - GAUSSIAN_TRUNCATION_SIGMA * sigma_um).max(0.0),
                center_um + GAUSSIAN_TRUNCATION_SIGMA * sigma_um,
            ),
            Kind::PhotonDetector { cutoff_um, .. } => (0.0, *cutoff_um),
            Kind::Table { wavelength_um, .. } => {
                (wavelength_um[0], wavelength_um[wavelength_um.len() - 1])
            }
            Kind::Product { factors } => {
                let mut lo: f64 = 0.0;
                let mut hi = f64::INFINITY;
                for f in factors {
                    let (a, b) = f.support();
                    lo = lo.max(a);
                    hi = hi.min(b);
                }
                if lo > hi {
                    (lo, lo)
                } else {
                    (lo, hi)
                }
            }
        }
    }

    fn push_breakpoints(&self, out: &mut Vec<f64>) {
        match self {
            Kind::Constant { .. } | Kind::Gaussian { .. } => {}
            Kind::TopHat {
                lo_um,
                hi_um,
                edge_um,
                ..
            } => {
                let half = 0.5 * edge_um;
                out.extend([lo_um - half, lo_um + half, hi_um - half, hi_um + half]);
            }
            Kind::PhotonDetector { cutoff_um, .. } => out.push(*cutoff_um),
            Kind::Table { wavelength_um, .. } => out.extend_from_slice(wavelength_um),
            Kind::Product { factors } => {
                for f in factors {
                    f.push_breakpoints(out);
                }
            }
        }
    }
}

/// Linear interpolation in a validated table, zero outside `[first, last]`.
fn table_eval(wavelength_um: &[f64], value: &[f64], w: f64) -> f64 {
    let n = wavelength_um.len();
    if w < wavelength_um[0] || w > wavelength_um[n - 1] {
        return 0.0;
    }
    // Number of nodes ≤ w; at least 1 here.
    let idx = wavelength_um.partition_point(|&x| x <= w);
    if idx >= n {
        return value[n - 1];
    }
    let i = idx - 1;
    let (w0, w1) = (wavelength_um[i], wavelength_um[i + 1]);
    let t = (w - w0) / (w1 - w0);
    value[i] + t * (value[i + 1] - value[i])
}

/// Trapezoid-rule integration weights (µm) for a strictly increasing wavelength grid, so
/// that `∫ f dλ ≈ Σ w_i f(λ_i)` over `[first, last]`:
/// `w_0 = (λ_1 − λ_0)/2`, `w_i = (λ_{i+1} − λ_{i−1})/2`, `w_{n−1} = (λ_{n−1} − λ_{n−2})/2`.
///
/// Exact for functions linear on every grid interval; for a quadratic with curvature f''
/// the error is `−Σ f'' h_i³ / 12` over the intervals h_i (composite trapezoid rule).
///
/// Errors: fewer than 2 points (a single point has no width), a non-finite value, or a grid
/// that is not strictly increasing.
pub fn trapezoid_weights(grid_um: &[f64]) -> Result<Vec<f64>> {
    if grid_um.len() < 2 {
        return Err(Error::param(
            "grid_um",
            format!("{} point(s)", grid_um.len()),
            "at least 2 wavelengths (a single point has no width)",
        ));
    }
    for (i, &w) in grid_um.iter().enumerate() {
        if !w.is_finite() {
            return Err(Error::param(
                format!("grid_um[{i}]"),
                w,
                "a finite wavelength in µm",
            ));
        }
        if i > 0 && w <= grid_um[i - 1] {
            return Err(Error::param(
                format!("grid_um[{i}]"),
                w,
                format!(
                    "strictly increasing wavelengths (previous is {})",
                    grid_um[i - 1]
                ),
            ));
        }
    }
    let n = grid_um.len();
    let mut weights = vec![0.0; n];
    for i in 0..n - 1 {
        let half = 0.5 * (grid_um[i + 1] - grid_um[i]);
        weights[i] += half;
        weights[i + 1] += half;
    }
    Ok(weights)
}

/// Checks that a transmission, filter or quantum efficiency never exceeds 1 (a
/// transmission > 1 creates energy; a QE > 1 counts more than one electron per photon,
/// which no detector in eoir's scope does) and is finite; `field` names the setting.
pub fn require_fraction(field: &str, s: Spectrum) -> Result<Spectrum> {
    let peak = s.peak_value();
    if !(peak.is_finite() && peak <= 1.0) {
        return Err(Error::param(
            field,
            format!("peak {peak}"),
            "a transmission / quantum efficiency between 0 and 1 at every wavelength",
        ));
    }
    Ok(s)
}

fn one() -> f64 {
    1.0
}

/// A spectral curve as written in a sensor file, selected by `kind`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum SpectrumConfig {
    /// The same value at every wavelength.
    Constant {
        /// The value (e.g. a transmission in [0, 1]).
        value: f64,
    },
    /// A band-pass with 50 % points at `lo_um` and `hi_um` and linear edges.
    TopHat {
        /// Lower 50 % wavelength, µm.
        lo_um: f64,
        /// Upper 50 % wavelength, µm.
        hi_um: f64,
        /// Full width of each linear edge, µm (0 = sharp).
        #[serde(default)]
        edge_width_um: f64,
        /// In-band value.
        #[serde(default = "one")]
        peak: f64,
    },
    /// A Gaussian response.
    Gaussian {
        /// Centre wavelength, µm.
        center_um: f64,
        /// Full width at half maximum, µm.
        fwhm_um: f64,
        /// Peak value.
        #[serde(default = "one")]
        peak: f64,
    },
    /// Quantum efficiency of an ideal photon detector: `peak` electrons per photon up to
    /// the cutoff, 0 above.
    IdealQe {
        /// Quantum efficiency below the cutoff.
        peak: f64,
        /// Cutoff wavelength, µm.
        cutoff_um: f64,
    },
    /// Relative responsivity per unit power of an ideal photon detector, `peak · λ/λc`
    /// below the cutoff (the report's R_rel(λ)). Not valid as `quantum_efficiency`, which
    /// counts electrons per photon: use `ideal_qe` there.
    PhotonDetector {
        /// Quantum efficiency at the cutoff wavelength.
        peak: f64,
        /// Cutoff wavelength, µm.
        cutoff_um: f64,
    },
    /// A table given inline (linear interpolation, zero outside).
    Table {
        /// Wavelengths, µm, strictly increasing.
        wavelength_um: Vec<f64>,
        /// Values at those wavelengths.
        value: Vec<f64>,
    },
    /// A two-column CSV file (µm, value), relative to the sensor file's directory.
    Csv {
        /// Path of the CSV file.
        path: PathBuf,
    },
}

impl SpectrumConfig {
    /// Builds the spectrum, resolving relative paths against `base_dir` and naming `field`
    /// in errors.
    pub fn build(&self, base_dir: &Path, field: &str) -> Result<Spectrum> {
        let named = |e: Error| match e {
            Error::InvalidParameter {
                field: f,
                value,
                expected,
            } => Error::InvalidParameter {
                field: format!("{field}.{f}"),
                value,
                expected,
            },
            other => other,
        };
        match self {
            SpectrumConfig::Constant { value } => {
                require_non_negative(&format!("{field}.value"), *value)?;
                Ok(Spectrum::constant(*value))
            }
            SpectrumConfig::TopHat {
                lo_um,
                hi_um,
                edge_width_um,
                peak,
            } => Spectrum::top_hat(*lo_um, *hi_um, *edge_width_um, *peak).map_err(named),
            SpectrumConfig::Gaussian {
                center_um,
                fwhm_um,
                peak,
            } => Spectrum::gaussian(*center_um, *fwhm_um, *peak).map_err(named),
            SpectrumConfig::IdealQe { peak, cutoff_um } => {
                Spectrum::ideal_quantum_efficiency(*peak, *cutoff_um).map_err(named)
            }
            SpectrumConfig::PhotonDetector { peak, cutoff_um } => {
                Spectrum::photon_detector(*peak, *cutoff_um).map_err(named)
            }
            SpectrumConfig::Table {
                wavelength_um,
                value,
            } => Spectrum::table(wavelength_um.clone(), value.clone()).map_err(named),
            SpectrumConfig::Csv { path } => Spectrum::from_csv(&resolve_path(base_dir, path)),
        }
    }
}

/// Resolves `path` against `base_dir` unless it is absolute (relative paths in a sensor file
/// are relative to the file's directory).
pub(crate) fn resolve_path(base_dir: &Path, path: &Path) -> PathBuf {
    if path.is_absolute() {
        path.to_path_buf()
    } else {
        base_dir.join(path)
    }
}
