//! Slanted-edge MTF (ISO 12233:2017 e-SFR, as in Burns' `sfrmat` reference code).
//!
//! 1. **Orientation.** The image (or region of interest) is transposed if the edge runs
//!    closer to horizontal than to vertical (more gradient energy along the columns than
//!    along the rows), so the edge is near-vertical below.
//! 2. **Edge location.** For every row the derivative `x[c+1] − x[c]` is Hamming-windowed
//!    and its centroid gives the sub-pixel edge position; a straight line `c = a + b·r` is
//!    fitted by least squares. A second pass centres each row's window on the first fit
//!    and refits (Burns 2000, "Slanted-edge MTF for digital camera and scanner analysis",
//!    Proc. IS&T PICS, 135–138).
//! 3. **Super-resolved edge-spread function.** Each pixel is projected onto the edge
//!    normal, `d = (c − a − b·r)·cos θ`, θ = atan b, and the values are averaged in bins
//!    a quarter pixel wide ([`OVERSAMPLING`] = 4). Because the edge is tilted, successive
//!    rows sample the edge at different sub-pixel phases: the bins collect samples of
//!    every phase, so the ESF is sampled 4× finer than the pixel grid and frequencies up
//!    to 2 cycles/pixel are represented without folding. This is how sampling phase and
//!    aliasing are handled: the measurement is the MTF of the continuous pre-sampling
//!    image (optics × detector footprint), averaged over phase, not the phase-dependent
//!    response of one aligned edge.
//!    Measuring along the normal (the cos θ factor, as ISO 12233:2017 does) makes the
//!    frequency axis that of the edge normal: cycles per pixel along the direction
//!    perpendicular to the edge.
//! 4. **Line-spread function.** Central difference of the ESF, `(e[i+1] − e[i−1])/2`,
//!    multiplied by a Hamming window `0.54 + 0.46 cos(π (i − i_c)/W)` centred on the LSF
//!    centroid i_c (W the larger distance to either end), which suppresses the noise of
//!    the flat tails.
//! 5. **MTF.** The modulus of the discrete-time Fourier transform of the windowed LSF,
//!    normalised at zero frequency, evaluated every 1/(4·L) cycles/pixel (L the ESF length
//!    in pixels) up to 1 cycle/pixel.
//! 6. **Corrections.** The finite difference over ±Δ (Δ = ¼ px) has the frequency response
//!    `sin(2πfΔ)/(2πfΔ)` relative to a true derivative, and averaging samples uniformly
//!    spread over a bin of width Δ is a box filter, `sin(πfΔ)/(πfΔ)`: the MTF is divided
//!    by both (ISO 12233:2017 Annex D derivative correction; the bin term follows from
//!    the same argument).
//! 7. **Uncertainty.** The region's lines are resampled with replacement
//!    ([`BOOTSTRAP_REPLICATES`] times, a fixed seed; Efron 1979, Ann. Stat. 7, 1) and steps
//!    3–6 repeated with the fitted edge line kept; the standard deviations of MTF50 and
//!    of the MTF at Nyquist over the replicates are reported. They carry the noise and
//!    the scatter of the lines' sub-pixel phases; the edge-line fit's own error is not
//!    resampled.
//! 8. **Phase sampling.** Line r crosses the edge at column `a + b·r`; its sub-pixel
//!    phase `frac(a + b·r)` falls in one of the [`OVERSAMPLING`] quarter-pixel phases. If
//!    the least-filled phase holds fewer than [`PHASE_FILL_MIN`] (half) of its fair share
//!    `lines/4`, the measurement warns: the ESF bins are then filled unevenly or by few
//!    lines. This happens near 0° (the lines do not sweep a whole pixel), at 45°
//!    (tan θ = 1: every line has the same phase) and near tan θ = 1/2 or 1/3 (the phases
//!    repeat every 2 or 3 lines).

use ndarray::{s, Array2, ArrayView2};

use crate::error::{Error, Result};

/// ESF bins per pixel.
pub const OVERSAMPLING: usize = 4;

/// Bootstrap replicates of [`slanted_edge_mtf`]'s uncertainty.
pub const BOOTSTRAP_REPLICATES: usize = 32;

/// Seed of the bootstrap's row resampling (fixed: the same image gives the same σ).
const BOOTSTRAP_SEED: u64 = 0x5eed_ed6e;

/// A quarter-pixel phase of the edge holding fewer than this fraction of its fair share
/// (lines / [`OVERSAMPLING`]) makes [`slanted_edge_mtf`] warn.
pub const PHASE_FILL_MIN: f64 = 0.5;

/// Smallest edge angle from the nearer axis, degrees: below it the rows of a ROI do not
/// sweep the sub-pixel phase.
pub const MIN_ANGLE_DEG: f64 = 1.0;

/// A rectangular region of interest, pixels: column `x`, row `y` of the top-left corner,
/// width and height.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Roi {
    /// First column.
    pub x: usize,
    /// First row.
    pub y: usize,
    /// Number of columns.
    pub width: usize,
    /// Number of rows.
    pub height: usize,
}

impl Roi {
    /// Parses `X,Y,W,H`.
    pub fn parse(text: &str) -> Result<Self> {
        let parts: Vec<&str> = text.split(',').map(str::trim).collect();
        let bad = || {
            Error::param(
                "--roi",
                format!("`{text}`"),
                "X,Y,W,H: four non-negative integers (pixels)",
            )
        };
        if parts.len() != 4 {
            return Err(bad());
        }
        let v: Vec<usize> = parts
            .iter()
            .map(|p| p.parse::<usize>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|_| bad())?;
        Ok(Roi {
            x: v[0],
            y: v[1],
            width: v[2],
            height: v[3],
        })
    }

    /// Checks the ROI lies inside a `rows × cols` image and is at least 8 × 8 pixels.
    pub fn check(&self, rows: usize, cols: usize) -> Result<()> {
        if self.width < 8 || self.height < 8 {
            return Err(Error::param(
                "--roi",
                format!("{}x{} pixels", self.width, self.height),
                "a region of at least 8 × 8 pixels",
            ));
        }
        // Checked sums: `--roi 18446744073709551615,0,10,10` must not wrap past the test.
        let right = self.x.checked_add(self.width);
        let bottom = self.y.checked_add(self.height);
        if right.is_none_or(|r| r > cols) || bottom.is_none_or(|b| b > rows) {
            return Err(Error::param(
                "--roi",
                format!("{},{},{},{}", self.x, self.y, self.width, self.height),
                format!("a region inside the {cols} × {rows} (width × height) image"),
            ));
        }
        Ok(())
    }
}

/// The result of a slanted-edge measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct EdgeMtf {
    /// Frequencies along the edge normal, cycles per pixel (0 … 1).
    pub freq_cy_per_px: Vec<f64>,
    /// MTF at those frequencies (1 at zero frequency).
    pub mtf: Vec<f64>,
    /// First frequency at which the MTF falls to 0.5 (linear interpolation), if it does.
    pub mtf50_cy_per_px: Option<f64>,
    /// Edge angle from the nearer image axis, degrees, signed: the edge line is
    /// `c = a + tan(angle)·r` (near-vertical) or `r = a + tan(angle)·c` (near-horizontal).
    pub angle_deg: f64,
    /// Whether the edge runs closer to vertical (`true`) or horizontal.
    pub vertical: bool,
    /// The region measured.
    pub roi: Roi,
    /// The super-resolved edge-spread function (bin width 1/[`OVERSAMPLING`] px along the
    /// normal, dark to bright as in the image's direction of increasing column / row).
    pub esf: Vec<f64>,
    /// MTF at the detector Nyquist frequency, 0.5 cycles/pixel (interpolated).
    pub mtf_nyquist: Option<f64>,
    /// Standard deviation of MTF50 over [`BOOTSTRAP_REPLICATES`] bootstrap resamplings
    /// of the region's lines (with replacement; Efron 1979), cycles/pixel: the
    /// measurement's uncertainty from noise and from the phase sampling of the lines
    /// kept. `None` if fewer than half the replicates reach 0.5.
    pub mtf50_sigma_cy_per_px: Option<f64>,
    /// Standard deviation of the MTF at Nyquist over the same bootstrap replicates.
    pub mtf_nyquist_sigma: Option<f64>,
    /// Number of lines whose edge crossing falls in each quarter-pixel phase
    /// (`frac(c_edge)` in [k/4, (k+1)/4)).
    pub phase_fill: Vec<usize>,
    /// Warnings: poor phase sampling (a phase with fewer than [`PHASE_FILL_MIN`] of its
    /// share of lines, e.g. near 0°, at tan θ = 1/3, 1/2 or 45°, where lines repeat
    /// phases).
    pub warnings: Vec<String>,
    /// Step height of the edge (bright − dark side means), image units.
    pub contrast: f64,
    /// Noise of the image, image units rms (from row-to-row differences along the edge).
    pub noise_rms: f64,
}

/// `sin(πx)/(πx)`.
fn sinc(x: f64) -> f64 {
    if x.abs() < 1e-12 {
        1.0
    } else {
        let p = std::f64::consts::PI * x;
        p.sin() / p
    }
}

/// Hamming-windowed centroid of `d` (window centred at `centre`, half-width `half`).
fn windowed_centroid(d: &[f64], centre: f64, half: f64) -> Option<f64> {
    let (mut num, mut den) = (0.0, 0.0);
    for (i, v) in d.iter().enumerate() {
        let x = i as f64 + 0.5; // derivative i sits between pixels i and i + 1
        let t = (x - centre) / half;
        if t.abs() > 1.0 {
            continue;
        }
        let w = 0.54 + 0.46 * (std::f64::consts::PI * t).cos();
        num += w * v * x;
        den += w * v;
    }
    (den.abs() > 0.0).then(|| num / den)
}

/// Measures the MTF of the straight edge in `image` (or its `roi`).
///
/// Errors (nothing is measured): a ROI outside the image or smaller than 8 × 8 pixels;
/// non-finite pixels; no edge (step smaller than 5 × the noise, or an edge that leaves
/// the region); an edge within [`MIN_ANGLE_DEG`] of an axis.
pub fn slanted_edge_mtf(image: ArrayView2<f64>, roi: Option<Roi>) -> Result<EdgeMtf> {
    let (rows, cols) = image.dim();
    let roi = roi.unwrap_or(Roi {
        x: 0,
        y: 0,
        width: cols,
        height: rows,
    });
    roi.check(rows, cols)?;
    let region = image.slice(s![roi.y..roi.y + roi.height, roi.x..roi.x + roi.width]);
    if let Some(((r, c), v)) = region.indexed_iter().find(|(_, v)| !v.is_finite()) {
        return Err(Error::param(
            format!("image[{}, {}]", r + roi.y, c + roi.x),
            v,
            "finite pixel values in the region of interest",
        ));
    }
    // Orientation: an edge at θ from the vertical has gradient energy ∝ cos²θ across the
    // columns and ∝ sin²θ across the rows (white noise adds the same to both).
    let gx: f64 = region
        .windows((1, 2))
        .into_iter()
        .map(|w| (w[[0, 1]] - w[[0, 0]]).powi(2))
        .sum();
    let gy: f64 = region
        .windows((2, 1))
        .into_iter()
        .map(|w| (w[[1, 0]] - w[[0, 0]]).powi(2))
        .sum();
    let vertical = gx >= gy;
    let data: Array2<f64> = if vertical {
        region.to_owned()
    } else {
        region.t().to_owned()
    };
    let (nr, nc) = data.dim();
    // Noise from differences along the edge direction (rows), robust (MAD).
    let mut diffs: Vec<f64> = (0..nr - 1)
        .flat_map(|r| (0..nc).map(move |c| (r, c)))
        .map(|(r, c)| (data[[r + 1, c]] - data[[r, c]]).abs())
        .collect();
    let noise_rms = crate::processing::median_in_place(&mut diffs).unwrap_or(0.0)
        * super::bad_pixels::MAD_TO_SIGMA
        / std::f64::consts::SQRT_2;
    // Step height from the mean profile's ends.
    let profile: Vec<f64> = (0..nc)
        .map(|c| data.column(c).mean().unwrap_or(0.0))
        .collect();
    let k = (nc / 8).max(1);
    let left = profile[..k].iter().sum::<f64>() / k as f64;
    let right = profile[nc - k..].iter().sum::<f64>() / k as f64;
    let contrast = right - left;
    let no_edge = |why: String| {
        Error::param(
            "edge",
            why,
            "one straight edge crossing the region (2–45° from a row or column), with a step larger than 5 × the noise",
        )
    };
    if contrast.is_nan() || contrast.abs() <= 5.0 * noise_rms || contrast == 0.0 {
        return Err(no_edge(format!(
            "step {contrast:.4} against noise {noise_rms:.4} rms"
        )));
    }
    // Edge location: two passes of windowed derivative centroids and a line fit.
    let derivs: Vec<Vec<f64>> = (0..nr)
        .map(|r| {
            (0..nc - 1)
                .map(|c| data[[r, c + 1]] - data[[r, c]])
                .collect()
        })
        .collect();
    let mut line: Option<(f64, f64)> = None; // (slope b, intercept a): c = a + b r
    for pass in 0..2 {
        let pts: Vec<(f64, f64)> = derivs
            .iter()
            .enumerate()
            .filter_map(|(r, d)| {
                let (centre, half) = match (pass, line) {
                    (1, Some((b, a))) => (a + b * r as f64, (nc as f64 / 4.0).max(4.0)),
                    _ => (nc as f64 / 2.0, nc as f64 / 2.0),
                };
                windowed_centroid(d, centre, half).map(|c| (r as f64, c))
            })
            .filter(|(_, c)| c.is_finite() && *c > 0.0 && *c < nc as f64)
            .collect();
        if pts.len() < nr.div_ceil(2) {
            return Err(no_edge(format!(
                "edge found in only {} of {} lines",
                pts.len(),
                nr
            )));
        }
        line = crate::processing::fit_line(&pts);
        if line.is_none() {
            return Err(no_edge("edge positions could not be fitted".into()));
        }
    }
    let (b, a) = line.ok_or_else(|| no_edge("no line".into()))?;
    let theta = b.atan();
    let angle_deg = theta.to_degrees();
    let (c_top, c_bottom) = (a, a + b * (nr as f64 - 1.0));
    if c_top.min(c_bottom) < 2.0 || c_top.max(c_bottom) > nc as f64 - 2.0 {
        return Err(no_edge(format!(
            "the fitted edge leaves the region (column {c_top:.1} at the first line, {c_bottom:.1} at the last)"
        )));
    }
    if angle_deg.abs() < MIN_ANGLE_DEG {
        return Err(Error::param(
            "edge angle",
            format!("{angle_deg:.2}°"),
            format!(
                "an edge tilted at least {MIN_ANGLE_DEG}° (ideally 2–45°) from the pixel rows or columns, so the lines sample every sub-pixel phase"
            ),
        ));
    }
    // Super-resolved ESF along the normal.
    let cos_t = theta.cos();
    let delta = 1.0 / OVERSAMPLING as f64;
    let mut d_min = f64::INFINITY;
    let mut d_max = f64::NEG_INFINITY;
    for r in 0..nr {
        let e = a + b * r as f64;
        d_min = d_min.min((0.0 - e) * cos_t);
        d_max = d_max.max((nc as f64 - 1.0 - e) * cos_t);
    }
    let half_bins = ((d_max.min(-d_min)) / delta).floor() as isize;
    if half_bins < 2 * OVERSAMPLING as isize {
        return Err(no_edge(
            "the edge is too close to the region's border".into(),
        ));
    }
    let nbins = (2 * half_bins) as usize;
    let all_rows: Vec<usize> = (0..nr).collect();
    let (esf, freq, mtf, empty) = esf_mtf(&data, &all_rows, (b, a), cos_t, half_bins)
        .ok_or_else(|| no_edge("zero line-spread function".into()))?;
    if empty * 10 > nbins {
        return Err(no_edge(format!(
            "{empty} of {nbins} quarter-pixel bins received no sample (the region has too few lines for this angle)"
        )));
    }
    let uncertainty = bootstrap(&data, (b, a), cos_t, half_bins);
    let phase_fill = phase_fill(a, b, nr);
    let mut warnings = Vec::new();
    let share = nr as f64 / OVERSAMPLING as f64;
    let least = phase_fill.iter().copied().min().unwrap_or(0);
    if (least as f64) < PHASE_FILL_MIN * share {
        warnings.push(format!(
            "edge angle {angle_deg:.2}°: the {nr} lines sample the edge's sub-pixel phase unevenly (quarter-pixel phase counts {phase_fill:?}; the least filled holds fewer than half its share of {share:.1}); the super-resolved edge has gaps or uneven bins and the MTF near and above Nyquist is unreliable — tilt the edge so that tan(angle) is not near 0, 1/3, 1/2 or 1 (e.g. 5°) or use more lines"
        ));
    }
    let mtf50 = crossing(&freq, &mtf, 0.5);
    let mtf_nyquist = interpolate(&freq, &mtf, 0.5);
    Ok(EdgeMtf {
        freq_cy_per_px: freq,
        mtf,
        mtf50_cy_per_px: mtf50,
        mtf_nyquist,
        mtf50_sigma_cy_per_px: uncertainty.0,
        mtf_nyquist_sigma: uncertainty.1,
        phase_fill,
        warnings,
        angle_deg,
        vertical,
        roi,
        esf,
        contrast,
        noise_rms,
    })
}

/// The super-resolved ESF and its MTF from the lines `rows` of `data` (a near-vertical
/// edge `c = a + b·r`, steps 3–6 of the module documentation): (ESF, frequencies, MTF,
/// number of empty ESF bins), or `None` for a zero line-spread function.
#[allow(clippy::type_complexity)]
fn esf_mtf(
    data: &Array2<f64>,
    rows: &[usize],
    (b, a): (f64, f64),
    cos_t: f64,
    half_bins: isize,
) -> Option<(Vec<f64>, Vec<f64>, Vec<f64>, usize)> {
    let nc = data.ncols();
    let delta = 1.0 / OVERSAMPLING as f64;
    let nbins = (2 * half_bins) as usize;
    let mut sum = vec![0.0f64; nbins];
    let mut count = vec![0usize; nbins];
    for &r in rows {
        let e = a + b * r as f64;
        for c in 0..nc {
            let d = (c as f64 - e) * cos_t;
            let i = (d / delta).floor() as isize + half_bins;
            if i >= 0 && (i as usize) < nbins {
                sum[i as usize] += data[[r, c]];
                count[i as usize] += 1;
            }
        }
    }
    let empty = count.iter().filter(|n| **n == 0).count();
    let mut esf: Vec<f64> = sum
        .iter()
        .zip(&count)
        .map(|(s, n)| if *n > 0 { s / *n as f64 } else { f64::NAN })
        .collect();
    fill_gaps(&mut esf);
    // LSF by central difference, Hamming window centred on its centroid.
    let n = esf.len();
    let mut lsf: Vec<f64> = (0..n)
        .map(|i| {
            let (lo, hi) = (i.saturating_sub(1), (i + 1).min(n - 1));
            (esf[hi] - esf[lo]) / (hi - lo) as f64
        })
        .collect();
    let total: f64 = lsf.iter().sum();
    let centre = lsf
        .iter()
        .enumerate()
        .map(|(i, v)| i as f64 * v)
        .sum::<f64>()
        / total;
    let centre = if centre.is_finite() {
        centre.clamp(0.0, n as f64 - 1.0)
    } else {
        n as f64 / 2.0
    };
    let half = centre.max(n as f64 - 1.0 - centre).max(1.0);
    for (i, v) in lsf.iter_mut().enumerate() {
        *v *= 0.54 + 0.46 * (std::f64::consts::PI * (i as f64 - centre) / half).cos();
    }
    // DTFT up to 1 cycle/pixel, 4× finer than the natural spacing 1/(n Δ).
    let df = 1.0 / (n as f64 * delta) / 4.0;
    let kmax = (1.0 / df).round() as usize;
    let two_pi = 2.0 * std::f64::consts::PI;
    // |Σ v_i e^{−2πi f (i − i_c) Δ}| = |Σ v_i zⁱ|, z = e^{−2πi f Δ}: the phase of the
    // centre drops out of the modulus and the powers of z follow by multiplication.
    let dft = |f: f64| -> f64 {
        let step = num_complex::Complex64::from_polar(1.0, -two_pi * f * delta);
        let mut z = num_complex::Complex64::new(1.0, 0.0);
        let mut acc = num_complex::Complex64::new(0.0, 0.0);
        for v in &lsf {
            acc += z * v;
            z *= step;
        }
        acc.norm()
    };
    let dc = dft(0.0);
    if dc.is_nan() || dc <= 0.0 {
        return None;
    }
    let freq: Vec<f64> = (0..=kmax).map(|k| k as f64 * df).collect();
    let mtf: Vec<f64> = freq
        .iter()
        .map(|f| {
            let correction = sinc(2.0 * f * delta) * sinc(f * delta);
            dft(*f) / dc / correction
        })
        .collect();
    Some((esf, freq, mtf, empty))
}

/// Lines per quarter-pixel phase of the edge crossing `c = a + b·r`, r = 0 … nr − 1.
fn phase_fill(a: f64, b: f64, nr: usize) -> Vec<usize> {
    let mut fill = vec![0usize; OVERSAMPLING];
    for r in 0..nr {
        let phase = (a + b * r as f64).rem_euclid(1.0);
        fill[((phase * OVERSAMPLING as f64) as usize).min(OVERSAMPLING - 1)] += 1;
    }
    fill
}

/// SplitMix64 (Steele, Lea & Flood 2014): the next 64-bit value of the state.
fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Standard deviations of MTF50 and of the MTF at Nyquist over
/// [`BOOTSTRAP_REPLICATES`] resamplings of the lines with replacement (the edge line
/// kept); each `None` when fewer than half the replicates give a value.
fn bootstrap(
    data: &Array2<f64>,
    line: (f64, f64),
    cos_t: f64,
    half_bins: isize,
) -> (Option<f64>, Option<f64>) {
    let nr = data.nrows();
    let mut state = BOOTSTRAP_SEED;
    let mut m50 = Vec::new();
    let mut nyq = Vec::new();
    for _ in 0..BOOTSTRAP_REPLICATES {
        let rows: Vec<usize> = (0..nr)
            .map(|_| (((splitmix64(&mut state) >> 32) * nr as u64) >> 32) as usize)
            .collect();
        if let Some((_, f, m, _)) = esf_mtf(data, &rows, line, cos_t, half_bins) {
            m50.extend(crossing(&f, &m, 0.5));
            nyq.extend(interpolate(&f, &m, 0.5));
        }
    }
    let sd = |v: &[f64]| {
        (2 * v.len() >= BOOTSTRAP_REPLICATES)
            .then(|| crate::processing::mean_variance(v.iter().copied()))
            .flatten()
            .map(|(_, var)| var.sqrt())
    };
    (sd(&m50), sd(&nyq))
}

/// Replaces NaN entries by linear interpolation between the nearest finite neighbours
/// (or the nearest finite value at the ends).
fn fill_gaps(v: &mut [f64]) {
    let finite: Vec<usize> = (0..v.len()).filter(|i| v[*i].is_finite()).collect();
    if finite.is_empty() {
        return;
    }
    for i in 0..v.len() {
        if v[i].is_finite() {
            continue;
        }
        let next = finite.iter().find(|j| **j > i).copied();
        let prev = finite.iter().rev().find(|j| **j < i).copied();
        v[i] = match (prev, next) {
            (Some(p), Some(n)) => v[p] + (v[n] - v[p]) * (i - p) as f64 / (n - p) as f64,
            (Some(p), None) => v[p],
            (None, Some(n)) => v[n],
            (None, None) => 0.0,
        };
    }
}

/// First abscissa at which `y` falls to `level` (linear interpolation), if it does.
pub fn crossing(x: &[f64], y: &[f64], level: f64) -> Option<f64> {
    for i in 1..x.len().min(y.len()) {
        if y[i - 1] >= level && y[i] < level {
            let t = (y[i - 1] - level) / (y[i - 1] - y[i]);
            return Some(x[i - 1] + t * (x[i] - x[i - 1]));
        }
    }
    None
}

/// Linear interpolation of `y(x)` at `x0` (x ascending); `None` outside the range.
pub fn interpolate(x: &[f64], y: &[f64], x0: f64) -> Option<f64> {
    let i = x.iter().position(|v| *v >= x0)?;
    if i == 0 {
        return (x[0] == x0).then(|| y[0]);
    }
    let t = (x0 - x[i - 1]) / (x[i] - x[i - 1]);
    Some(y[i - 1] + t * (y[i] - y[i - 1]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roi_parses_and_rejects() {
        assert_eq!(
            Roi::parse("1, 2,30,40").unwrap(),
            Roi {
                x: 1,
                y: 2,
                width: 30,
                height: 40
            }
        );
        assert!(Roi::parse("1,2,3").is_err());
        assert!(Roi::parse("1,2,-3,4").is_err());
        assert!(Roi::parse("0,0,100,10").unwrap().check(50, 50).is_err());
    }

    #[test]
    fn crossing_interpolates() {
        let x = [0.0, 1.0, 2.0];
        let y = [1.0, 0.6, 0.2];
        assert!((crossing(&x, &y, 0.5).unwrap() - 1.25).abs() < 1e-12);
        assert_eq!(crossing(&x, &y, 0.1), None);
    }
}
