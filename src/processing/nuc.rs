//! Non-uniformity correction (NUC): a per-pixel polynomial that maps each pixel's own
//! signal onto a common reference.
//!
//! Calibration views L uniform sources (flat fields, blackbodies) and averages M frames
//! at each, giving per pixel the signal `x_l(i,j)` and for the level a reference value
//! `r_l` (the source radiance, or simply the array mean at that level). Each pixel gets
//! the least-squares polynomial of degree N
//!
//! `r ≈ Σ_k a_k(i,j) · zᵏ`,  `z = (x − c)/s`,
//!
//! the classical two-point correction for N = 1 and two levels (gain and offset per
//! pixel; FOI report §2.2.2.1, the "two point correction scheme"), and a multi-point
//! polynomial NUC for N ≥ 2 that also absorbs per-pixel nonlinearity. The pixel signal is
//! centred and scaled by array-wide constants (`c` = mean signal over all levels, `s` =
//! largest distance of a level's mean signal from `c`), so z spans about [−1, 1] for every
//! pixel and the small least-squares problems stay well conditioned; each is solved by a
//! QR factorisation (modified Gram–Schmidt with re-orthogonalisation) of its L × (N+1)
//! Vandermonde matrix, pixels in parallel. A pixel whose signal does not vary enough to
//! determine all N+1 coefficients (a dead pixel) gets the highest degree it supports
//! (down to a constant, the mean reference) and is listed in
//! [`NucCoefficients::rank_deficient`]; a pixel with a non-finite signal gets NaN
//! coefficients and is listed too.
//!
//! ## Coefficient files
//!
//! [`NucCoefficients::save`] writes `<stem>.npy`, a little-endian `f64` NPY array of shape
//! `[N+1, rows, cols]` whose plane k holds `a_k` (the coefficient of zᵏ), and the sidecar
//! `<stem>.json`:
//!
//! ```json
//! {
//!   "format": "eoir-nuc",
//!   "version": 2,
//!   "degree": 1,
//!   "signal_centre": 2051.37,
//!   "signal_scale": 1024.5,
//!   "rows": 480,
//!   "cols": 640,
//!   "rank_deficient": [[12, 40]],
//!   "bad_pixels": [[3, 7]],
//!   "coefficients_fnv1a64": "5f0e2c0a91d4b7e3"
//! }
//! ```
//!
//! `z = (x − signal_centre) / signal_scale`; `rank_deficient` lists `[row, col]` of the
//! pixels described above; the optional `bad_pixels` those flagged by the calibration
//! ([`NucCoefficients::set_bad_pixels`]), to be replaced after correction;
//! `coefficients_fnv1a64` (version 2) the FNV-1a checksum of the coefficients, so a
//! sidecar is never used with another array. Unknown keys are errors. Both files are
//! written as one product set (moved into place together), and
//! `signal_centre`/`signal_scale` are checked against [`MAX_SIGNAL_CENTRE`] and
//! [`SIGNAL_SCALE_RANGE`] on writing and reading.

use std::io::BufReader;
use std::path::{Path, PathBuf};

use ndarray::{Array2, Array3, ArrayView1, ArrayView2, Axis, Zip};
use ndarray_npy::{ReadNpyExt, WriteNpyExt};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::bad_pixels::BadPixelMap;
use super::{check_frame, check_shape, mean_variance};
use crate::error::{Error, Result};
use crate::io::atomic_write;
use crate::io::output::ProductSet;

/// A Vandermonde column zᵏ whose part orthogonal to the lower powers is shorter than this
/// fraction of max(‖zᵏ‖, √L) (z spans about [−1, 1]) is taken as linearly dependent.
const RANK_TOL: f64 = 1e-9;

/// Highest polynomial degree accepted (monomials beyond this are ill-conditioned even on
/// the scaled signal).
pub const MAX_DEGREE: usize = 8;

/// Per-pixel polynomial NUC coefficients (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct NucCoefficients {
    degree: usize,
    signal_centre: f64,
    signal_scale: f64,
    /// `[degree + 1, rows, cols]`, plane k = coefficient of zᵏ.
    coefficients: Array3<f64>,
    rank_deficient: Vec<(usize, usize)>,
    /// Pixels flagged bad by the calibration (e.g. [`super::bad_pixels::detect`]), to be
    /// replaced after correction; saved in the sidecar as `bad_pixels`.
    bad_pixels: Vec<(usize, usize)>,
}

/// The `.json` sidecar of a coefficient file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct NucSidecar {
    format: String,
    version: u32,
    degree: usize,
    signal_centre: f64,
    signal_scale: f64,
    rows: usize,
    cols: usize,
    #[serde(default)]
    rank_deficient: Vec<[usize; 2]>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    bad_pixels: Vec<[usize; 2]>,
    /// [`content_hash`] of the coefficient array, in hexadecimal (version 2 on): ties the
    /// sidecar to the one `.npy` it was written with.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    coefficients_fnv1a64: Option<String>,
}

const FORMAT_NAME: &str = "eoir-nuc";
/// Version 2 adds `coefficients_fnv1a64`; version 1 sidecars (no hash) are still read.
const FORMAT_VERSION: u32 = 2;

/// The largest |signal_centre| accepted, DN: far beyond any recorded signal (16-bit
/// DN, or f32 radiance in any unit eoir writes), small enough that `x − c` stays exact
/// to about 1e-4 of a DN-sized step and `z` finite.
pub const MAX_SIGNAL_CENTRE: f64 = 1e12;
/// The accepted range of signal_scale, DN: with |x − c| ≤ 2·[`MAX_SIGNAL_CENTRE`] and
/// scale ≥ 1e-9, |z| ≤ 2e21 and z^[`MAX_DEGREE`] ≤ 3e170, finite in f64; a subnormal
/// scale (1e-320) would make every z infinite.
pub const SIGNAL_SCALE_RANGE: (f64, f64) = (1e-9, 1e12);

/// FNV-1a (64 bit) of the coefficients' little-endian f64 bytes in array order: a
/// checksum that tells a coefficient file from another, not a cryptographic digest.
fn content_hash(a: &Array3<f64>) -> String {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for v in a.iter() {
        for b in v.to_le_bytes() {
            h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
        }
    }
    format!("{h:016x}")
}

/// Checks the normalisation constants (`side` names the sidecar in errors).
fn check_normalisation(side: &Path, centre: f64, scale: f64) -> Result<()> {
    let (lo, hi) = SIGNAL_SCALE_RANGE;
    if !(centre.is_finite() && centre.abs() <= MAX_SIGNAL_CENTRE) {
        return Err(Error::format(
            side,
            format!(
                "signal_centre = {centre:e}: expected a finite number of DN with |value| <= {MAX_SIGNAL_CENTRE:e}"
            ),
        ));
    }
    if !(scale.is_finite() && (lo..=hi).contains(&scale)) {
        return Err(Error::format(
            side,
            format!("signal_scale = {scale:e}: expected a number of DN from {lo:e} to {hi:e}"),
        ));
    }
    Ok(())
}

/// Rounds to 9 significant digits, so the value is written and re-read exactly by any
/// JSON parser (the shortest decimal form then has at most 9 digits).
fn round_sig(x: f64) -> f64 {
    format!("{x:.8e}").parse().unwrap_or(x)
}

impl NucCoefficients {
    /// Fits the per-pixel polynomial of degree `degree` mapping each pixel's signal onto
    /// the reference. `levels` holds, per calibration level, the reference value and the
    /// per-pixel average of the frames recorded at that level (see
    /// [`mean_frame`](super::mean_frame)).
    ///
    /// Errors: `degree` above [`MAX_DEGREE`]; fewer than `degree + 1` levels; empty or
    /// differently shaped frames; a non-finite reference; levels whose mean signals are
    /// all equal (nothing to fit).
    pub fn fit(levels: &[(f64, ArrayView2<f64>)], degree: usize) -> Result<Self> {
        if degree > MAX_DEGREE {
            return Err(Error::param(
                "degree",
                degree,
                format!("a polynomial degree from 0 to {MAX_DEGREE}"),
            ));
        }
        if levels.len() < degree + 1 {
            return Err(Error::param(
                "levels",
                format!("{} calibration levels", levels.len()),
                format!(
                    "at least degree + 1 = {} levels for a degree-{degree} NUC",
                    degree + 1
                ),
            ));
        }
        let shape = levels[0].1.dim();
        check_frame("levels[0]", levels[0].1)?;
        for (l, (reference, frame)) in levels.iter().enumerate() {
            check_shape(&format!("levels[{l}]"), frame.dim(), shape)?;
            if !reference.is_finite() {
                return Err(Error::param(
                    format!("levels[{l}] reference"),
                    reference,
                    "a finite reference signal",
                ));
            }
        }
        // Each level's sum of finite pixels in row-major order (the levels side by side:
        // each sum is one serial chain of additions, the same whatever the thread count).
        let sums: Vec<(f64, usize)> = levels
            .par_iter()
            .map(|(_, frame)| {
                let add = |(s, n): (f64, usize), &v: &f64| {
                    if v.is_finite() {
                        (s + v, n + 1)
                    } else {
                        (s, n)
                    }
                };
                match frame.as_slice() {
                    Some(values) => values.iter().fold((0.0, 0usize), add),
                    None => frame.iter().fold((0.0, 0usize), add),
                }
            })
            .collect();
        let mut level_means = Vec::with_capacity(levels.len());
        for (l, &(sum, n)) in sums.iter().enumerate() {
            if n == 0 {
                return Err(Error::param(
                    format!("levels[{l}]"),
                    "no finite pixel",
                    "a frame with finite pixel values",
                ));
            }
            level_means.push(sum / n as f64);
        }
        let centre = level_means.iter().sum::<f64>() / level_means.len() as f64;
        let spread = level_means
            .iter()
            .map(|m| (m - centre).abs())
            .fold(0.0, f64::max);
        if degree > 0 && (spread.is_nan() || spread <= 0.0) {
            return Err(Error::param(
                "levels",
                "all levels have the same mean signal",
                "calibration levels at different signal levels",
            ));
        }
        let signal_centre = round_sig(centre);
        let signal_scale = if spread > 0.0 { round_sig(spread) } else { 1.0 };
        let (rows, cols) = shape;
        let references: Vec<f64> = levels.iter().map(|l| l.0).collect();
        let frames: Vec<ArrayView2<f64>> = levels.iter().map(|l| l.1).collect();

        // One row per task, written straight into the coefficient planes, with per-thread
        // scratch; each task returns the rank-deficient columns of its row.
        let n1 = degree + 1;
        let mut coefficients = Array3::zeros((n1, rows, cols));
        let deficient: Vec<Vec<usize>> = coefficients
            .axis_iter_mut(Axis(1))
            .into_par_iter()
            .enumerate()
            .map_init(
                || {
                    (
                        FitScratch::default(),
                        vec![0.0; frames.len()],
                        vec![0.0; n1],
                    )
                },
                |(scratch, z, a), (i, mut planes)| {
                    let rows: Vec<ArrayView1<f64>> = frames.iter().map(|f| f.row(i)).collect();
                    let mut deficient = Vec::new();
                    for j in 0..cols {
                        for (zl, row) in z.iter_mut().zip(&rows) {
                            *zl = (row[j] - signal_centre) / signal_scale;
                        }
                        let full = if degree == 1 {
                            fit_line_qr(z, &references, a)
                        } else {
                            fit_polynomial(z, &references, degree, scratch, a)
                        };
                        if !full {
                            deficient.push(j);
                        }
                        for (k, &v) in a.iter().enumerate() {
                            planes[[k, j]] = v;
                        }
                    }
                    deficient
                },
            )
            .collect();
        let rank_deficient = deficient
            .into_iter()
            .enumerate()
            .flat_map(|(i, js)| js.into_iter().map(move |j| (i, j)))
            .collect();
        Ok(NucCoefficients {
            degree,
            signal_centre,
            signal_scale,
            coefficients,
            rank_deficient,
            bad_pixels: Vec::new(),
        })
    }

    /// Records the bad-pixel map found during calibration (saved with the coefficients).
    ///
    /// Errors: a map of another shape than the coefficients.
    pub fn set_bad_pixels(&mut self, map: &BadPixelMap) -> Result<()> {
        check_shape("bad-pixel map", map.dim(), self.dim())?;
        self.bad_pixels = map.positions();
        Ok(())
    }

    /// The recorded bad pixels together with the rank-deficient ones: every pixel the
    /// correction cannot be trusted for.
    pub fn bad_pixel_map(&self) -> BadPixelMap {
        let mut map = self.rank_deficient_map();
        let (r, c) = self.dim();
        for &(i, j) in &self.bad_pixels {
            if i < r && j < c {
                let _ = map.set(i, j, true);
            }
        }
        map
    }

    /// The polynomial degree N.
    pub fn degree(&self) -> usize {
        self.degree
    }

    /// The frame shape `(rows, cols)`.
    pub fn dim(&self) -> (usize, usize) {
        let (_, r, c) = self.coefficients.dim();
        (r, c)
    }

    /// The centre c and scale s of the normalised signal `z = (x − c)/s`.
    pub fn signal_normalisation(&self) -> (f64, f64) {
        (self.signal_centre, self.signal_scale)
    }

    /// The coefficients `[N+1, rows, cols]`, plane k multiplying zᵏ.
    pub fn coefficients(&self) -> &Array3<f64> {
        &self.coefficients
    }

    /// Pixels whose signal did not determine all N+1 coefficients, or was not finite.
    pub fn rank_deficient(&self) -> &[(usize, usize)] {
        &self.rank_deficient
    }

    /// The rank-deficient pixels as a [`BadPixelMap`].
    pub fn rank_deficient_map(&self) -> BadPixelMap {
        let (r, c) = self.dim();
        let mut mask = Array2::from_elem((r, c), false);
        for &(i, j) in &self.rank_deficient {
            mask[[i, j]] = true;
        }
        BadPixelMap::from_mask(mask)
    }

    /// Corrects a frame: each pixel's polynomial evaluated (Horner) at its signal.
    ///
    /// Errors: a frame of another shape.
    pub fn apply(&self, frame: ArrayView2<f64>) -> Result<Array2<f64>> {
        self.apply_masked(frame, |x| x, |_| false)
    }

    /// [`NucCoefficients::apply`] of a frame of any sample type in one pass: `to_f64`
    /// converts each raw sample to the DN x the polynomial takes, and the corrected value
    /// is NaN where `clipped(x)` (e.g. a raw value at an ADC limit). The same values as
    /// `apply` of the converted frame with those pixels set to NaN afterwards.
    ///
    /// Errors: as [`NucCoefficients::apply`].
    pub fn apply_masked<T: Copy + Send + Sync>(
        &self,
        frame: ArrayView2<T>,
        to_f64: impl Fn(T) -> f64 + Sync,
        clipped: impl Fn(f64) -> bool + Sync,
    ) -> Result<Array2<f64>> {
        check_shape("frame", frame.dim(), self.dim())?;
        let (c, s) = (self.signal_centre, self.signal_scale);
        let n = self.degree;
        let coeffs = &self.coefficients;
        let mut out = Array2::zeros(frame.dim());
        Zip::indexed(&mut out)
            .and(&frame)
            .par_for_each(|(i, j), o, &raw| {
                let x = to_f64(raw);
                if clipped(x) {
                    *o = f64::NAN;
                    return;
                }
                let z = (x - c) / s;
                let mut acc = coeffs[[n, i, j]];
                for k in (0..n).rev() {
                    acc = acc * z + coeffs[[k, i, j]];
                }
                *o = acc;
            });
        Ok(out)
    }

    /// Writes `<stem>.npy` and `<stem>.json` (format in the module documentation) as one
    /// [`ProductSet`]: both are staged and moved into place together, so an error or a
    /// signal leaves the earlier pair (if any) whole, never a new array beside an old
    /// sidecar. The sidecar also carries the array's checksum, which
    /// [`load`](Self::load) checks.
    ///
    /// Errors: a path not ending in `.npy`, normalisation constants outside the valid
    /// range, or an I/O failure (naming the file).
    pub fn save(&self, path: &Path) -> Result<()> {
        let side = sidecar_path(path)?;
        check_normalisation(&side, self.signal_centre, self.signal_scale)?;
        let (rows, cols) = self.dim();
        let sc = NucSidecar {
            format: FORMAT_NAME.to_string(),
            version: FORMAT_VERSION,
            degree: self.degree,
            signal_centre: self.signal_centre,
            signal_scale: self.signal_scale,
            rows,
            cols,
            rank_deficient: self.rank_deficient.iter().map(|&(i, j)| [i, j]).collect(),
            bad_pixels: self.bad_pixels.iter().map(|&(i, j)| [i, j]).collect(),
            coefficients_fnv1a64: Some(content_hash(&self.coefficients)),
        };
        let (Some(npy_name), Some(side_name)) = (path.file_name(), side.file_name()) else {
            return Err(Error::format(path, "names no file to write the NUC to"));
        };
        let dir = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        let set = ProductSet::begin(dir)?;
        set.write(npy_name, |p| {
            atomic_write(p, |w| {
                self.coefficients
                    .write_npy(&mut *w)
                    .map_err(|e| Error::format(p, format!("cannot write the NPY array: {e}")))
            })
        })?;
        set.write_json(side_name, &sc)?;
        set.commit()?;
        Ok(())
    }

    /// Reads coefficients written by [`save`](Self::save), checking the sidecar (format,
    /// version, degree, normalisation) against the array shape `[degree+1, rows, cols]`.
    ///
    /// Errors: missing or unreadable files, an unknown format or version, unknown keys,
    /// inconsistent shapes, a non-positive scale, or rank-deficient positions outside the
    /// frame.
    pub fn load(path: &Path) -> Result<Self> {
        let side = sidecar_path(path)?;
        let text = crate::input::read_text(&side)?;
        let sc: NucSidecar = serde_json::from_str(&text).map_err(|e| {
            Error::format(
                &side,
                format!(
                    "line {}, column {}: invalid NUC sidecar: {}",
                    e.line(),
                    e.column(),
                    crate::error::redact_quoted(&e.to_string(), 200, false)
                ),
            )
        })?;
        if sc.format != FORMAT_NAME || !(1..=FORMAT_VERSION).contains(&sc.version) {
            return Err(Error::format(
                &side,
                format!(
                    "format/version not supported (the file's text is not shown); expected `\"format\": \"{FORMAT_NAME}\"` with version 1 to {FORMAT_VERSION}"
                ),
            ));
        }
        match (&sc.coefficients_fnv1a64, sc.version) {
            (None, v) if v >= 2 => {
                return Err(Error::format(
                    &side,
                    "coefficients_fnv1a64 is missing; a version-2 sidecar names the checksum of its .npy",
                ))
            }
            (Some(_), 1) => {
                return Err(Error::format(
                    &side,
                    "coefficients_fnv1a64 is a version-2 key; expected version 2",
                ))
            }
            _ => {}
        }
        if sc.degree > MAX_DEGREE {
            return Err(Error::format(
                &side,
                format!("degree {} is above the maximum {MAX_DEGREE}", sc.degree),
            ));
        }
        check_normalisation(&side, sc.signal_centre, sc.signal_scale)?;
        let coefficients = read_coefficients(path, [sc.degree + 1, sc.rows, sc.cols])?;
        let coefficients = coefficients.map_err(|e| {
            Error::format(
                path,
                format!("cannot read a 3-D little-endian f64 NPY array: {e}"),
            )
        })?;
        let expected = (sc.degree + 1, sc.rows, sc.cols);
        if coefficients.dim() != expected || sc.rows == 0 || sc.cols == 0 {
            let (a, b, c) = coefficients.dim();
            return Err(Error::format(
                path,
                format!(
                    "array shape [{a}, {b}, {c}] does not match the sidecar: expected [degree + 1, rows, cols] = [{}, {}, {}] with rows, cols > 0",
                    expected.0, expected.1, expected.2
                ),
            ));
        }
        let positions = |list: Vec<[usize; 2]>, key: &str| -> Result<Vec<(usize, usize)>> {
            let mut out = Vec::with_capacity(list.len());
            for [i, j] in list {
                if i >= sc.rows || j >= sc.cols {
                    return Err(Error::format(
                        &side,
                        format!(
                            "{key} pixel [{i}, {j}] lies outside the {}×{} frame",
                            sc.rows, sc.cols
                        ),
                    ));
                }
                out.push((i, j));
            }
            Ok(out)
        };
        if let Some(expected) = &sc.coefficients_fnv1a64 {
            let found = content_hash(&coefficients);
            if !found.eq_ignore_ascii_case(expected) {
                return Err(Error::format(
                    path,
                    format!(
                        "the coefficients do not belong to {}: their checksum is {found}, the sidecar's coefficients_fnv1a64 names another array; use the .npy and .json written together by one `eoir nuc fit`",
                        side.display()
                    ),
                ));
            }
        }
        let rank_deficient = positions(sc.rank_deficient, "rank_deficient")?;
        let bad_pixels = positions(sc.bad_pixels, "bad_pixels")?;
        // A non-finite coefficient is written by `fit` only for a pixel it lists as
        // rank-deficient (a non-finite signal); anywhere else the file is damaged.
        let mut listed = Array2::from_elem((sc.rows, sc.cols), false);
        for &(i, j) in &rank_deficient {
            listed[[i, j]] = true;
        }
        if let Some(((k, i, j), v)) = coefficients
            .indexed_iter()
            .find(|((_, i, j), v)| !v.is_finite() && !listed[[*i, *j]])
        {
            return Err(Error::format(
                path,
                format!(
                    "coefficient {k} of pixel [{i}, {j}] is {v}; expected finite coefficients (only pixels listed as rank_deficient may hold NaN)"
                ),
            ));
        }
        Ok(NucCoefficients {
            degree: sc.degree,
            signal_centre: sc.signal_centre,
            signal_scale: sc.signal_scale,
            coefficients,
            rank_deficient,
            bad_pixels,
        })
    }
}

/// The sidecar path `<stem>.json` of a coefficient file `<stem>.npy`.
fn sidecar_path(path: &Path) -> Result<PathBuf> {
    let is_npy = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"));
    if !is_npy {
        return Err(Error::format(
            path,
            "a NUC coefficient file name must end in .npy (its sidecar is <stem>.json)",
        ));
    }
    Ok(path.with_extension("json"))
}

/// Per-thread working storage of [`fit_polynomial`] (no allocation per pixel).
#[derive(Debug, Default)]
struct FitScratch {
    /// Orthonormal columns, `q[k·L + i]`.
    q: Vec<f64>,
    /// Column being orthogonalised.
    v: Vec<f64>,
    /// R, `r[k·(N+1) + j]` = entry (j, k).
    r: Vec<f64>,
}

/// Least-squares polynomial `y ≈ Σ_k a_k zᵏ`, k ≤ `degree`, by QR (modified Gram–Schmidt,
/// two passes) of the Vandermonde matrix, written to `a` (length `degree + 1`). Columns
/// that are (numerically) dependent on the lower powers end the basis: the coefficients of
/// higher powers are 0 and the result is false. Non-finite input gives NaN coefficients
/// and false.
fn fit_polynomial(z: &[f64], y: &[f64], degree: usize, w: &mut FitScratch, a: &mut [f64]) -> bool {
    let l = z.len();
    let n1 = degree + 1;
    if z.iter().chain(y).any(|v| !v.is_finite()) {
        a.fill(f64::NAN);
        return false;
    }
    w.q.clear();
    w.r.clear();
    w.r.resize(n1 * n1, 0.0);
    let mut m = 0;
    let mut full = true;
    for k in 0..=degree {
        w.v.clear();
        w.v.extend(z.iter().map(|&x| x.powi(k as i32)));
        let scale = (w.v.iter().map(|x| x * x).sum::<f64>().sqrt()).max((l as f64).sqrt());
        for _pass in 0..2 {
            for j in 0..m {
                let qj = &w.q[j * l..(j + 1) * l];
                let d: f64 = qj.iter().zip(&w.v).map(|(a, b)| a * b).sum();
                w.r[k * n1 + j] += d;
                for (vi, qi) in w.v.iter_mut().zip(qj) {
                    *vi -= d * qi;
                }
            }
        }
        let norm = w.v.iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm.is_nan() || norm <= RANK_TOL * scale {
            full = false;
            break;
        }
        w.r[k * n1 + k] = norm;
        w.q.extend(w.v.iter().map(|vi| vi / norm));
        m += 1;
    }
    // Solve R a = Qᵀ y by back substitution.
    a.fill(0.0);
    for k in (0..m).rev() {
        let qk = &w.q[k * l..(k + 1) * l];
        let mut s: f64 = qk.iter().zip(y).map(|(a, b)| a * b).sum();
        for (j, aj) in a.iter().enumerate().take(m).skip(k + 1) {
            s -= w.r[j * n1 + k] * aj;
        }
        a[k] = s / w.r[k * n1 + k];
    }
    full
}

/// [`fit_polynomial`] for degree 1 in closed form: the QR route's own arithmetic with the
/// Vandermonde columns `1` and `z` (modified Gram–Schmidt makes the second column
/// `z − z̄`, of norm √Sxx), so `a₁ = Σ(z − z̄)(y − ȳ)/Sxx` and `a₀ = ȳ − a₁ z̄` — the
/// least-squares line — with the same rank test (`√Sxx ≤ RANK_TOL · max(‖z‖, √L)`: a
/// constant, `a = (ȳ, 0)`, and false) and NaN coefficients for non-finite input.
fn fit_line_qr(z: &[f64], y: &[f64], a: &mut [f64]) -> bool {
    let l = z.len() as f64;
    if z.iter().chain(y).any(|v| !v.is_finite()) {
        a.fill(f64::NAN);
        return false;
    }
    let z_mean = z.iter().sum::<f64>() / l;
    let y_mean = y.iter().sum::<f64>() / l;
    let (mut sxx, mut sxy, mut zz) = (0.0, 0.0, 0.0);
    for (&zi, &yi) in z.iter().zip(y) {
        let dz = zi - z_mean;
        sxx += dz * dz;
        sxy += dz * (yi - y_mean);
        zz += zi * zi;
    }
    if sxx.sqrt() <= RANK_TOL * zz.sqrt().max(l.sqrt()) {
        a[0] = y_mean;
        a[1] = 0.0;
        return false;
    }
    a[1] = sxy / sxx;
    a[0] = y_mean - a[1] * z_mean;
    true
}

/// Mean of the finite pixels of `frame` not flagged in `exclude`: the reference level of
/// a NUC that maps every pixel onto the mean response of the *good* pixels (dead, hot and
/// unresponsive pixels would otherwise bias every corrected level by about the defect
/// fraction times their distance from the mean).
///
/// Errors: a map of another shape, or no valid pixel.
pub fn good_pixel_mean(frame: ArrayView2<f64>, exclude: &BadPixelMap) -> Result<f64> {
    check_frame("frame", frame)?;
    check_shape("bad-pixel map", exclude.dim(), frame.dim())?;
    let (sum, n) = Zip::from(&frame)
        .and(exclude.mask())
        .fold((0.0, 0usize), |(s, n), &v, &bad| {
            if !bad && v.is_finite() {
                (s + v, n + 1)
            } else {
                (s, n)
            }
        });
    if n == 0 {
        return Err(Error::param(
            "frame",
            "no good pixel",
            "at least one finite pixel not flagged bad",
        ));
    }
    Ok(sum / n as f64)
}

/// Residual non-uniformity of a (corrected) flat-field frame: spatial standard deviation
/// over mean, `σ_s / μ` (n − 1 normalisation), over the finite pixels not flagged in
/// `exclude`. For a frame averaged over many images this is the fixed-pattern residual;
/// for a single frame it includes the temporal noise.
///
/// Errors: a map of another shape, fewer than two valid pixels, or a zero mean.
pub fn residual_nonuniformity(
    frame: ArrayView2<f64>,
    exclude: Option<&BadPixelMap>,
) -> Result<f64> {
    check_frame("frame", frame)?;
    if let Some(map) = exclude {
        check_shape("bad-pixel map", map.dim(), frame.dim())?;
    }
    let valid = frame
        .indexed_iter()
        .filter(|((i, j), v)| v.is_finite() && !exclude.is_some_and(|m| m.is_bad(*i, *j)))
        .map(|(_, &v)| v);
    let (mean, var) = mean_variance(valid).ok_or_else(|| {
        Error::param(
            "frame",
            "fewer than 2 valid pixels",
            "at least two finite, unflagged pixels",
        )
    })?;
    if mean == 0.0 {
        return Err(Error::OutOfRange(
            "residual non-uniformity: the frame mean is 0, so σ/mean is undefined".to_string(),
        ));
    }
    Ok(var.sqrt() / mean.abs())
}

/// Opens the coefficient array (a regular file only, never blocking on a FIFO) and checks,
/// with the crate's bounded NPY header parser and before anything of that size is
/// allocated, that it holds `<f8`/`>f8` values of exactly the sidecar's `shape` in C
/// order and that the file is exactly header + data long; then decodes it. A hostile
/// header (a 4 GB header length, a shape of 2⁶³ elements, nesting 17,000 deep) is thus
/// a typed error, never an allocation abort or a stack overflow in the decoder.
fn read_coefficients(
    path: &Path,
    shape: [usize; 3],
) -> Result<std::result::Result<Array3<f64>, ndarray_npy::ReadNpyError>> {
    use std::io::{Seek, SeekFrom};
    let mut file = crate::input::open_regular(path)?;
    let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let header = crate::io::npy::read_header(path, &mut file, len)?;
    let dims = [
        ("degree + 1", shape[0] as u64),
        ("rows", shape[1] as u64),
        ("cols", shape[2] as u64),
    ];
    let bytes = crate::limits::check_alloc(&format!("reading {}", path.display()), &dims, 8)?;
    if header.ty != crate::io::binary::SampleType::F64 || header.shape != shape {
        return Err(Error::format(
            path,
            format!(
                "array type/shape do not match the sidecar: expected f8 values of shape [{}, {}, {}] (degree + 1, rows, cols), found {:?} of shape {:?}",
                shape[0],
                shape[1],
                shape[2],
                header.ty,
                crate::limits::escape_bounded(&format!("{:?}", header.shape), 80)
            ),
        ));
    }
    if Some(len) != header.data_start.checked_add(bytes) {
        return Err(Error::format(
            path,
            format!(
                "file is {len} bytes, but its {}-byte header and {bytes} bytes of f8 values make {}",
                header.data_start,
                header.data_start.saturating_add(bytes)
            ),
        ));
    }
    file.seek(SeekFrom::Start(0))
        .map_err(|e| Error::io(path, e))?;
    Ok(Array3::<f64>::read_npy(BufReader::new(file)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The closed-form line agrees with the QR route to rounding on random data (3 to 6
    /// levels), and both treat a constant signal as rank deficient with `a = (ȳ, 0)`.
    #[test]
    fn closed_form_line_matches_qr() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let mut scratch = FitScratch::default();
        for l in 3..=6 {
            for _ in 0..200 {
                let z: Vec<f64> = (0..l).map(|_| next()).collect();
                let y: Vec<f64> = z
                    .iter()
                    .map(|zi| 3000.0 + 900.0 * zi + 5.0 * next())
                    .collect();
                let (mut a, mut b) = ([0.0; 2], [0.0; 2]);
                assert!(fit_line_qr(&z, &y, &mut a));
                assert!(fit_polynomial(&z, &y, 1, &mut scratch, &mut b));
                for k in 0..2 {
                    assert!(
                        (a[k] - b[k]).abs() <= 1e-11 * b[k].abs().max(1.0),
                        "{a:?} {b:?}"
                    );
                }
            }
        }
        let (z, y) = ([0.25; 4], [1.0, 2.0, 3.0, 6.0]);
        let (mut a, mut b) = ([0.0; 2], [0.0; 2]);
        assert!(!fit_line_qr(&z, &y, &mut a));
        assert!(!fit_polynomial(&z, &y, 1, &mut scratch, &mut b));
        assert_eq!(a, [3.0, 0.0]);
        assert!((b[0] - 3.0).abs() < 1e-14 && b[1] == 0.0, "{b:?}");
        assert!(!fit_line_qr(&[f64::NAN, 1.0], &[1.0, 2.0], &mut a) && a[0].is_nan());
    }
}
