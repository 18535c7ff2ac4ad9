//! Optical transfer functions: aperture diffraction (clear and centrally obscured),
//! defocus, aberration (Shannon), detector footprint, and measured MTF tables.
//!
//! Conventions (docs/design.md §3): spatial frequency is *angular*, cycles/rad in object space.
//! The aperture terms take the normalised frequency `X = f / f_c` with the diffraction cutoff
//! `f_c = D/λ` cycles/rad (see [`cutoff_cy_per_rad`]); in the image plane the same cutoff
//! is `1/(λN)` cycles/m. Transfer functions are real and signed (the sinc and defocus lobes
//! reverse contrast); take |OTF| only when reporting an MTF.
//!
//! The analytic functions are small, pure and unvalidated because they run once per
//! frequency sample in the imaging hot loop; parameter validation belongs to the sensor
//! configuration. All of them are even in frequency (they use |x|).
//! [`MeasuredMtf`] validates its table in its constructors.

use std::f64::consts::{FRAC_2_PI, PI};
use std::path::Path;

use crate::error::{Error, Result};

/// Normalised sinc: `sin(πx)/(πx)`, 1 at `x = 0`, zero at every other integer.
pub fn sinc(x: f64) -> f64 {
    if x == 0.0 {
        1.0
    } else {
        let px = PI * x;
        px.sin() / px
    }
}

/// Diffraction cutoff of a circular aperture, cycles/rad in object space: `f_c = D/λ`
/// (docs/design.md §4.2). `aperture_diameter_m` and `wavelength_m` in metres.
pub fn cutoff_cy_per_rad(aperture_diameter_m: f64, wavelength_m: f64) -> f64 {
    aperture_diameter_m / wavelength_m
}

/// `2/π [acos X − X√(1−X²)]` for `0 ≤ X ≤ 1` (no range checks; callers ensure the range).
#[inline]
fn clear_core(x: f64) -> f64 {
    // (1−X)(1+X) keeps precision near the cutoff, where 1 − X² cancels.
    FRAC_2_PI * (x.acos() - x * ((1.0 - x) * (1.0 + x)).sqrt())
}

/// Diffraction OTF of a clear circular aperture (docs/design.md §4.2):
/// `2/π [acos X − X√(1−X²)]` for `|X| ≤ 1`, 0 beyond, with `X = f/f_c` the normalised
/// frequency (uses |x|). It is 1 at `X = 0` and never negative.
pub fn diffraction_clear(x: f64) -> f64 {
    let x = x.abs();
    if x >= 1.0 {
        0.0
    } else {
        clear_core(x)
    }
}

/// Diffraction OTF of a centrally obscured circular aperture (docs/design.md §4.3).
///
/// `r` is the obscuration ratio (obscuration diameter / aperture diameter, `0 ≤ r < 1`;
/// `r ≤ 0` gives [`diffraction_clear`]), and `x = f/f_c` is normalised to the cutoff of the
/// FULL aperture (uses |x|; 0 for |x| ≥ 1). With `R = r`, `X = |x|`:
///
/// `OTF = (A + B + C) / (1 − R²)`, where
/// - `A = 2/π [acos X − X√(1−X²)]`;
/// - `B = 2R²/π [acos Y − Y√(1−Y²)]`, `Y = X/R`, while `X ≤ R`, else 0;
/// - `C = −2R²` while `X ≤ (1−R)/2`;
///   `C = (2R/π) sin α + ((1+R²)/π) α − (2(1−R²)/π) atan[((1+R)/(1−R)) tan(α/2)] − 2R²`
///   while `(1−R)/2 < X < (1+R)/2`, with `α = acos[(1 + R² − 4X²)/(2R)]`;
///   `C = 0` beyond.
///
/// This is the corrected form of docs/design.md §4.3 (printed versions with `2R²/π sin α`, or a
/// flat branch ending at `(1−R²)/2`, are wrong by up to 0.26). It is normalised to 1 at
/// `X = 0` and, as the autocorrelation of a non-negative pupil, never negative (checked on a
/// dense grid of X and R against this unclipped expression). It agrees with the FFT
/// autocorrelation of a sampled annular pupil to ~1e-4 (tests/optics.rs). `r ≥ 1` (no
/// clear aperture) is not checked here and gives non-finite values; the sensor
/// configuration validates `r`.
pub fn diffraction_obscured(x: f64, r: f64) -> f64 {
    if r <= 0.0 {
        return diffraction_clear(x);
    }
    let x = x.abs();
    if x >= 1.0 {
        return 0.0;
    }
    let r2 = r * r;
    let a = clear_core(x);
    // 2R²/π [acos Y − Y√(1−Y²)] = R² · clear_core(Y).
    let b = if x <= r { r2 * clear_core(x / r) } else { 0.0 };
    let c = if x <= 0.5 * (1.0 - r) {
        -2.0 * r2
    } else if x < 0.5 * (1.0 + r) {
        // Clamp: round-off can push the cosine a hair outside [−1, 1] at the branch ends.
        let cos_alpha = ((1.0 + r2 - 4.0 * x * x) / (2.0 * r)).clamp(-1.0, 1.0);
        let alpha = cos_alpha.acos();
        (2.0 * r / PI) * alpha.sin() + ((1.0 + r2) / PI) * alpha
            - (2.0 * (1.0 - r2) / PI) * (((1.0 + r) / (1.0 - r)) * (0.5 * alpha).tan()).atan()
            - 2.0 * r2
    } else {
        0.0
    };
    (a + b + c) / (1.0 - r2)
}

/// Shannon's aberration factor (docs/design.md §4.5; R. R. Shannon, *The Art and Science of
/// Optical Design*): `1 − (W_rms/0.18)² [1 − 4(X − ½)²]`, clipped at 0, for `0 ≤ |X| ≤ 1`.
///
/// `w_rms_waves` is the rms wavefront error in waves (configure it directly; `W_pp/3.5` is
/// only a rule of thumb), `x = f/f_c` (uses |x|). The bracket vanishes at both ends, so the
/// factor is 1 at `X = 0` and at `X = 1` and has its minimum `1 − (W_rms/0.18)²` at
/// `X = ½`. It multiplies the diffraction term and is rough beyond ~0.1 wave rms.
///
/// Beyond the cutoff (`|X| > 1`) this returns 0: no aberrated aperture transfers anything
/// there, and 0 keeps the factor safe even if it is used without the diffraction term (the
/// bracket would otherwise go negative and the factor exceed 1).
pub fn aberration_shannon(x: f64, w_rms_waves: f64) -> f64 {
    let x = x.abs();
    if x > 1.0 {
        return 0.0;
    }
    let k = w_rms_waves / 0.18;
    let d = x - 0.5;
    (1.0 - k * k * (1.0 - 4.0 * d * d)).max(0.0)
}

/// Defocus factor (docs/design.md §4.4): `2 J1(a)/a` with `a = 8π W020 X(1 − X)`, 1 at `a = 0`
/// (J1 from `libm::j1`).
///
/// `w020_waves` is the edge (marginal) wavefront error of the defocus in waves (see
/// [`defocus_w020_from_focus_shift`]); `x = f/f_c` (uses |x|). It MULTIPLIES the diffraction
/// term: on its own it is 1 at `X = 0` and at the cutoff. It is signed (contrast reversal
/// for strong defocus) and even in `W020`. `W020 = 1` gives the commonly printed
/// `2J1(8πv(1−v))/(8πv(1−v))`. Beyond the cutoff (`|X| > 1`) it returns 0, like
/// [`aberration_shannon`].
///
/// Accuracy: `diffraction_clear(X) · defocus(X, W020)` is within 0.015 of the exact
/// defocused OTF `(4/π) ∫₀^{acos X} sin²φ cos(8π W020 X (cos φ − X)) dφ` for
/// W020 = 0.25 … 2 waves (tests/optics.rs).
pub fn defocus(x: f64, w020_waves: f64) -> f64 {
    let x = x.abs();
    if x > 1.0 {
        return 0.0;
    }
    jinc(8.0 * PI * w020_waves * x * (1.0 - x))
}

/// Defocus in the geometric-optics limit, the transfer function of a defocus *without*
/// diffraction (`[diffraction] enabled = false`): `2 J1(a)/a` with `a = 8π W020 X`, for
/// every `X = f/f_c ≥ 0` (no cutoff).
///
/// Derivation: with the wavefront `W(ρ) = W020 λ ρ²` (ρ the normalised pupil radius), the
/// transverse ray error in the image is `ε = (R/a_p) ∂W/∂ρ = 2N · 2 W020 λ ρ`
/// (R/a_p = 2N for an image distance R and pupil radius a_p), so a point images as a
/// uniform disc of radius `r_b = 4 N λ W020` — the same as the focus shift's cone,
/// `δz/(2N)` with `δz = 8 N² λ W020`. A uniform disc of radius r_b has the transfer
/// function `2 J1(2π ν r_b)/(2π ν r_b)`, and at the image-plane frequency
/// `ν = X/(λN)` the argument is `2π (X/(λN)) 4NλW020 = 8π W020 X`. It is the large-W020
/// limit of the diffraction form [`defocus`] (`a = 8π W020 X(1 − X)`, Hopkins 1955; the
/// `(1 − X)` comes from the shrinking pupil overlap, which geometric optics does not
/// have), equal to it to first order in X, and it rolls off as `X^{−3/2}` instead of
/// stopping at the cutoff D/λ. Checked against the numerical Fourier transform of the
/// uniform disc (tests/all/optics.rs).
pub fn defocus_geometric(x: f64, w020_waves: f64) -> f64 {
    jinc(8.0 * PI * w020_waves * x.abs())
}

/// The Airy amplitude `2 J1(a)/a` (1 at `a = 0`; J1 from `libm::j1`), the factor of
/// [`defocus`] as a function of its argument `a = 8π W020 X(1 − X)`.
pub fn jinc(a: f64) -> f64 {
    if a.abs() < 1e-6 {
        // Series 2J1(a)/a = 1 − a²/8 + …; avoids 0/0 at a = 0.
        1.0 - a * a / 8.0
    } else {
        2.0 * libm::j1(a) / a
    }
}

/// Edge wavefront error (waves) produced by a focus shift (docs/design.md §4.4):
/// `W020 = δz / (8 N² λ)`, with `focus_shift_m` = δz (image-side focus error, m),
/// `f_number` = N and `wavelength_m` = λ (m).
pub fn defocus_w020_from_focus_shift(focus_shift_m: f64, f_number: f64, wavelength_m: f64) -> f64 {
    focus_shift_m / (8.0 * f_number * f_number * wavelength_m)
}

/// Detector footprint transfer function (docs/design.md §4.6):
/// `sinc(fx·wx/fl) · sinc(fy·wy/fl)`, with `fx_cy_per_rad`, `fy_cy_per_rad` the angular
/// frequencies (cycles/rad), `active_width_x_m`, `active_width_y_m` the ACTIVE (photosensitive)
/// widths of the pixel (m) and `focal_length_m` the focal length (m). Signed.
pub fn detector_footprint(
    fx_cy_per_rad: f64,
    fy_cy_per_rad: f64,
    active_width_x_m: f64,
    active_width_y_m: f64,
    focal_length_m: f64,
) -> f64 {
    sinc(fx_cy_per_rad * active_width_x_m / focal_length_m)
        * sinc(fy_cy_per_rad * active_width_y_m / focal_length_m)
}

/// A measured, rotationally symmetric MTF from a table of (frequency in cycles/mrad, MTF).
///
/// The table starts at frequency 0 and is normalised to its value there. [`eval`]
/// interpolates linearly in radial frequency; beyond the last tabulated frequency the MTF
/// is taken as 0 (a measured table should extend to where the MTF has become negligible;
/// if it does not, the step to 0 at its end is visible in the output).
///
/// [`eval`]: MeasuredMtf::eval
#[derive(Debug, Clone, PartialEq)]
pub struct MeasuredMtf {
    /// Tabulated radial frequencies, cycles/mrad, strictly increasing, first = 0.
    freq_cy_per_mrad: Vec<f64>,
    /// MTF values normalised so that the value at frequency 0 is 1.
    mtf: Vec<f64>,
}

/// Largest raw MTF value accepted in a table (measured MTFs may overshoot 1 a little,
/// e.g. with edge enhancement).
const MEASURED_MTF_MAX: f64 = 1.5;

/// A table defect found by [`check_table`]: which row (if any), which column, the value and
/// what would be valid. Turned into a parameter error by [`MeasuredMtf::new`] and into a
/// file/line error by [`MeasuredMtf::from_csv`].
struct TableFault {
    row: Option<usize>,
    field: &'static str,
    value: String,
    expected: String,
}

/// Validates a measured-MTF table (see [`MeasuredMtf::new`] for the rules).
fn check_table(freq: &[f64], mtf: &[f64]) -> std::result::Result<(), TableFault> {
    if freq.len() != mtf.len() {
        return Err(TableFault {
            row: None,
            field: "mtf",
            value: format!("{} values", mtf.len()),
            expected: format!("as many values as frequencies ({} frequencies)", freq.len()),
        });
    }
    if freq.len() < 2 {
        return Err(TableFault {
            row: None,
            field: "freq_cy_per_mrad",
            value: format!("{} points", freq.len()),
            expected: "at least 2 (frequency, MTF) points".into(),
        });
    }
    for (i, (&f, &m)) in freq.iter().zip(mtf).enumerate() {
        if !f.is_finite() || f < 0.0 {
            return Err(TableFault {
                row: Some(i),
                field: "freq_cy_per_mrad",
                value: f.to_string(),
                expected: "a finite frequency >= 0 (cycles/mrad)".into(),
            });
        }
        if i == 0 && f != 0.0 {
            return Err(TableFault {
                row: Some(0),
                field: "freq_cy_per_mrad",
                value: f.to_string(),
                expected: "the first frequency to be 0 (the table is normalised to its value at 0)"
                    .into(),
            });
        }
        if i > 0 && f <= freq[i - 1] {
            return Err(TableFault {
                row: Some(i),
                field: "freq_cy_per_mrad",
                value: f.to_string(),
                expected: format!(
                    "frequencies strictly increasing (previous frequency {})",
                    freq[i - 1]
                ),
            });
        }
        if !m.is_finite() || !(0.0..=MEASURED_MTF_MAX).contains(&m) {
            return Err(TableFault {
                row: Some(i),
                field: "mtf",
                value: m.to_string(),
                expected: format!("a finite MTF in [0, {MEASURED_MTF_MAX}]"),
            });
        }
        if i == 0 && m <= 0.0 {
            return Err(TableFault {
                row: Some(0),
                field: "mtf",
                value: m.to_string(),
                expected: "an MTF > 0 at frequency 0 (the table is normalised to it)".into(),
            });
        }
    }
    Ok(())
}

/// Splits a CSV data line into fields on commas, semicolons, tabs and other whitespace.
fn split_fields(line: &str) -> Vec<&str> {
    line.split(|c: char| c == ',' || c == ';' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .collect()
}

impl MeasuredMtf {
    /// Builds a measured MTF from frequencies (cycles/mrad) and MTF values.
    ///
    /// Requirements: at least 2 points, equal lengths; frequencies finite, ≥ 0 and strictly
    /// increasing, the first exactly 0; MTF values finite in [0, 1.5] and > 0 at frequency
    /// 0. The table is normalised to its value at frequency 0. Beyond the last frequency the
    /// MTF is 0. Errors name the offending index, value and what is valid.
    pub fn new(freq_cy_per_mrad: Vec<f64>, mtf: Vec<f64>) -> Result<Self> {
        if let Err(fault) = check_table(&freq_cy_per_mrad, &mtf) {
            let field = match fault.row {
                Some(i) => format!("{}[{i}]", fault.field),
                None => fault.field.to_string(),
            };
            return Err(Error::param(field, fault.value, fault.expected));
        }
        Ok(Self::from_checked(freq_cy_per_mrad, mtf))
    }

    /// Normalises a table that has passed [`check_table`] (so `mtf[0] > 0`).
    fn from_checked(freq_cy_per_mrad: Vec<f64>, mtf: Vec<f64>) -> Self {
        let dc = mtf[0];
        let mtf = mtf.into_iter().map(|m| m / dc).collect();
        MeasuredMtf {
            freq_cy_per_mrad,
            mtf,
        }
    }

    /// Reads a two-column table (frequency in cycles/mrad, MTF) from a text/CSV file.
    ///
    /// Fields may be separated by commas, semicolons, tabs or spaces (so a decimal comma is
    /// not supported). `#` starts a comment (whole-line or trailing); blank lines are
    /// ignored. Before the first data row, ONE header line whose fields are all non-numeric
    /// (e.g. `freq_cy_per_mrad, mtf`) is skipped. The table rules of [`MeasuredMtf::new`]
    /// apply. Errors name the file, the 1-based line number and what was expected, never
    /// the line's text (the path may point at a file that is not meant to be shown).
    pub fn from_csv(path: &Path) -> Result<Self> {
        let text = crate::input::read_text(path)?;
        let mut freq = Vec::new();
        let mut mtf = Vec::new();
        // The line number of every data row, for error messages.
        let mut rows: Vec<usize> = Vec::new();
        let mut header_seen = false;
        for (idx, raw) in text.lines().enumerate() {
            let line_no = idx + 1;
            let raw = if idx == 0 {
                raw.trim_start_matches('\u{feff}')
            } else {
                raw
            };
            let content = match raw.find('#') {
                Some(p) => &raw[..p],
                None => raw,
            };
            let fields = split_fields(content);
            if fields.is_empty() {
                continue;
            }
            let parsed: Vec<Option<f64>> = fields.iter().map(|s| s.parse::<f64>().ok()).collect();
            if rows.is_empty() && !header_seen && parsed.iter().all(Option::is_none) {
                header_seen = true;
                continue;
            }
            if fields.len() != 2 {
                return Err(Error::format(
                    path,
                    format!(
                        "line {line_no}: expected 2 columns (frequency in cycles/mrad, \
                         MTF), found {}",
                        fields.len()
                    ),
                ));
            }
            match (parsed[0], parsed[1]) {
                (Some(f), Some(m)) => {
                    freq.push(f);
                    mtf.push(m);
                    rows.push(line_no);
                }
                _ => {
                    let column = if parsed[0].is_none() { 1 } else { 2 };
                    return Err(Error::format(
                        path,
                        format!(
                            "line {line_no}, column {column}: expected a number (frequency \
                             in cycles/mrad, then MTF)"
                        ),
                    ));
                }
            }
        }
        if let Err(fault) = check_table(&freq, &mtf) {
            let message = match fault.row.and_then(|i| rows.get(i)) {
                Some(line_no) => format!(
                    "line {line_no}: {} = {}: expected {}",
                    fault.field, fault.value, fault.expected
                ),
                None => format!(
                    "{} data rows found ({} = {}): expected {}",
                    rows.len(),
                    fault.field,
                    fault.value,
                    fault.expected
                ),
            };
            return Err(Error::format(path, message));
        }
        Ok(Self::from_checked(freq, mtf))
    }

    /// The MTF at radial angular frequency `f_cy_per_rad` (cycles/rad; uses |f|), by linear
    /// interpolation in the table (which is in cycles/mrad: 1 cycle/mrad = 1000 cycles/rad).
    /// Returns 0 beyond the last tabulated frequency (and for a NaN frequency).
    pub fn eval(&self, f_cy_per_rad: f64) -> f64 {
        let f = f_cy_per_rad.abs() * 1e-3;
        let freq = &self.freq_cy_per_mrad;
        let last = freq.len() - 1;
        if f.is_nan() || f > freq[last] {
            return 0.0;
        }
        // First index whose frequency is ≥ f; the table starts at 0 ≤ f, so j ≥ 0 and
        // j ≤ last.
        let j = freq.partition_point(|&g| g < f);
        if j == 0 {
            return self.mtf[0];
        }
        let (f0, f1) = (freq[j - 1], freq[j]);
        let t = (f - f0) / (f1 - f0);
        self.mtf[j - 1] + t * (self.mtf[j] - self.mtf[j - 1])
    }

    /// The tabulated frequencies, cycles/mrad (first 0, strictly increasing).
    pub fn freq_cy_per_mrad(&self) -> &[f64] {
        &self.freq_cy_per_mrad
    }

    /// The tabulated MTF values, normalised to 1 at frequency 0.
    pub fn mtf(&self) -> &[f64] {
        &self.mtf
    }
}
