//! Line-of-sight motion at the inverse transform: what moves between frames and within a
//! frame's exposure, applied to the band-summed spectrum of a frame (docs/motion.md).
//!
//! Motion is achromatic, so it multiplies the band sum `S(f) = Σ_b w_b·OTF_b(f)·X_b(f)`
//! once, after the accumulation: a static scene's `S` is accumulated once and every frame
//! of its sequence costs one multiplication and one inverse transform
//! ([`super::Imager::detector_image_moving`]).
//!
//! A frame's motion is a set of [`MotionGroup`]s of detector rows. Each row has its own
//! displacement (the mean image position over its exposure window, an exact sub-pixel
//! shift: the sampling position moves, the integer part picks other frame rows or
//! columns and the fraction is a Fourier phase ramp); each group has one blur, the
//! transfer function of the path about its mean (exact for the piecewise-linear path,
//! [`crate::los::WindowPath`]). A global shutter has one group whose rows share one
//! displacement; a rolling shutter groups rows whose blurs agree within the stated
//! tolerance, and inside a group the engine shifts every row by its own displacement:
//! exactly along x (a phase ramp on that row's spectrum alone, after the column
//! transforms), and along y to within [`ROW_POSITION_TOLERANCE_PX`] (rows whose fractional
//! y positions agree that closely share one column pass).

use ndarray::Array2;
use num_complex::Complex64;
use rayon::prelude::*;

use super::lattice::ColumnFactors;
use super::sampling::shift_phase;
use super::Imager;
use crate::error::{Error, Result};
use crate::los::WindowPath;
use crate::sensor::FrequencyGrid;

/// The largest error, in detector pixels, of a row's position under a rolling shutter's
/// row-dependent vertical displacement: rows whose fractional y positions lie within twice
/// this of each other share one column transform at their common middle position. The
/// horizontal displacement of every row is exact.
pub const ROW_POSITION_TOLERANCE_PX: f64 = 0.02;

/// Detector rows that share one blur, each with its own displacement.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionGroup {
    /// Detector rows of the group.
    pub rows: Vec<usize>,
    /// Image displacement of each row, rad `[x, y]` (x along columns, y along rows, the
    /// scene content moving by +d): the mean over the row's exposure window.
    pub displacement_rad: Vec<[f64; 2]>,
    /// The path about its mean during the exposure, whose transfer function blurs the
    /// group; `None` when the blur is already in the achromatic product (a constant-rate
    /// motion's sinc) or there is none.
    pub blur: Option<WindowPath>,
}

/// The motion of one frame: every detector row in exactly one group.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameMotion {
    /// The groups of rows.
    pub groups: Vec<MotionGroup>,
}

impl FrameMotion {
    /// Every one of `rows` detector rows displaced by `displacement_rad`, blurred by
    /// `blur` (a global shutter).
    pub fn uniform(rows: usize, displacement_rad: [f64; 2], blur: Option<WindowPath>) -> Self {
        FrameMotion {
            groups: vec![MotionGroup {
                rows: (0..rows).collect(),
                displacement_rad: vec![displacement_rad; rows],
                blur,
            }],
        }
    }

    /// Whether the frame is the still image: no displacement and no blur anywhere.
    pub fn is_identity(&self) -> bool {
        self.groups.iter().all(|g| {
            g.blur.is_none()
                && g.displacement_rad
                    .iter()
                    .all(|d| d[0] == 0.0 && d[1] == 0.0)
        })
    }

    /// Checks that every detector row of `rows` is in exactly one group, with one
    /// displacement per row; `Err` names what is wrong (a caller error).
    pub fn check(&self, rows: usize) -> std::result::Result<(), String> {
        let mut seen = vec![false; rows];
        for (gi, g) in self.groups.iter().enumerate() {
            if g.rows.len() != g.displacement_rad.len() {
                return Err(format!(
                    "motion group {gi}: {} rows but {} displacements",
                    g.rows.len(),
                    g.displacement_rad.len()
                ));
            }
            for (&r, d) in g.rows.iter().zip(&g.displacement_rad) {
                if r >= rows || std::mem::replace(&mut seen[r], true) {
                    return Err(format!(
                        "motion group {gi}: row {r} is outside 0..{rows} or in two groups"
                    ));
                }
                if !(d[0].is_finite() && d[1].is_finite()) {
                    return Err(format!("motion group {gi}: row {r}: displacement {d:?}"));
                }
            }
        }
        match seen.iter().position(|s| !s) {
            Some(r) => Err(format!("detector row {r} is in no motion group")),
            None => Ok(()),
        }
    }
}

/// Multiplies a half-plane spectrum held transposed (`spec_t[u·rows + v]`, the engine's
/// accumulator layout) of a real `frame = (rows, cols)` frame with frequencies `grid` by
/// the transfer function of `path` ([`WindowPath::otf`]).
///
/// Each segment j of the piecewise-linear path contributes
/// `w_j·exp(−2πi f·m_j)·sinc(f·Δ_j)` (m_j its midpoint, Δ_j its extent). Along a column
/// both arguments are linear in the row frequency, so they advance by one complex
/// multiplication per sample (restarted on each half of the column), instead of a sine
/// and cosine per sample and segment; the result agrees with [`WindowPath::otf`] to
/// ~1e-12 (test). On an even axis the Nyquist bin stands for both ±f_N, so it takes the
/// average of the two values (docs/design.md §5), which keeps the frame real.
pub fn apply_path_otf(
    spec_t: &mut [Complex64],
    frame: (usize, usize),
    grid: &FrequencyGrid,
    path: &WindowPath,
) {
    let (rows, cols) = frame;
    if rows == 0 || cols == 0 {
        return;
    }
    debug_assert_eq!(spec_t.len(), rows * (cols / 2 + 1));
    let columns = PathColumns::new(frame, grid, path);
    let zero = Complex64::new(0.0, 0.0);
    spec_t.par_chunks_mut(rows).enumerate().for_each_init(
        || vec![zero; rows],
        |h, (u, col)| {
            columns.fill(u, h);
            for (a, f) in col.iter_mut().zip(h.iter()) {
                *a *= f;
            }
        },
    );
}

/// A path's transfer function column by column on a frame's half-plane frequency grid
/// (see [`apply_path_otf`]).
struct PathColumns<'a> {
    segments: Segments,
    grid: &'a FrequencyGrid,
    path: &'a WindowPath,
    nyquist_col: Option<usize>,
    nyquist_row: Option<usize>,
}

impl<'a> PathColumns<'a> {
    fn new(frame: (usize, usize), grid: &'a FrequencyGrid, path: &'a WindowPath) -> Self {
        let (rows, cols) = frame;
        debug_assert_eq!((grid.fy.len(), grid.fx.len()), (rows, cols / 2 + 1));
        PathColumns {
            segments: Segments::of(path),
            grid,
            path,
            nyquist_col: (cols % 2 == 0).then_some(cols / 2),
            nyquist_row: (rows % 2 == 0).then_some(rows / 2),
        }
    }

    /// Column u's transfer function at every row frequency, into `h`.
    fn fill(&self, u: usize, h: &mut [Complex64]) {
        self.fill_outside(u, (h.len(), h.len()), h);
    }

    /// Column u's transfer function at the row frequencies outside the rows `gap.0..gap.1`
    /// (which are left as they are), into `h`.
    fn fill_outside(&self, u: usize, gap: (usize, usize), h: &mut [Complex64]) {
        let (grid, path) = (self.grid, self.path);
        let fx = grid.fx[u];
        self.segments.column(fx, &grid.fy, gap, h);
        let both_x = self.nyquist_col == Some(u);
        if both_x {
            let mut h2 = vec![Complex64::new(0.0, 0.0); h.len()];
            self.segments.column(-fx, &grid.fy, gap, &mut h2);
            for (a, b) in h.iter_mut().zip(h2.iter()) {
                *a = 0.5 * (*a + *b);
            }
        }
        if let Some(v) = self.nyquist_row.filter(|&v| v < gap.0 || v >= gap.1) {
            let fy = grid.fy[v];
            let xs: &[f64] = if both_x { &[1.0, -1.0] } else { &[1.0] };
            let sum: Complex64 = xs
                .iter()
                .map(|s| path.otf(s * fx, fy) + path.otf(s * fx, -fy))
                .sum();
            h[v] = sum / (2.0 * xs.len() as f64);
        }
    }
}

/// Interleaved recurrences in [`Segments::column`].
const LANES: usize = 4;

/// A path's segments as the column evaluation uses them.
struct Segments {
    /// (weight, midpoint [x, y] rad, extent [x, y] rad) of every segment.
    seg: Vec<(f64, [f64; 2], [f64; 2])>,
}

impl Segments {
    fn of(path: &WindowPath) -> Self {
        let p = &path.points_rad;
        let n = p.len().saturating_sub(1).max(1);
        let w = 1.0 / n as f64;
        let seg = p
            .windows(2)
            .map(|s| {
                (
                    w,
                    [0.5 * (s[0][0] + s[1][0]), 0.5 * (s[0][1] + s[1][1])],
                    [s[1][0] - s[0][0], s[1][1] - s[0][1]],
                )
            })
            .collect();
        Segments { seg }
    }

    /// The transfer function at column frequency `fx` and every row frequency of `fy`
    /// (the real FFT's order: 0, Δ, 2Δ, …, then the negative half) outside the rows
    /// `gap.0..gap.1` (`gap.0 ≤ rows/2 + 1 ≤ gap.1`, or the gap empty at the end), into
    /// `out`; the rows of the gap are left as they are.
    fn column(&self, fx: f64, fy: &[f64], gap: (usize, usize), out: &mut [Complex64]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe { self.column_avx2(fx, fy, gap, out) };
        }
        self.column_portable(fx, fy, gap, out)
    }

    /// [`Segments::column`] compiled for AVX2: the same operations on every value (no
    /// fused multiply-add may form), so the same result to the bit.
    ///
    /// # Safety
    /// The CPU must support AVX2 (`is_x86_feature_detected!("avx2")`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn column_avx2(&self, fx: f64, fy: &[f64], gap: (usize, usize), out: &mut [Complex64]) {
        self.column_portable(fx, fy, gap, out)
    }

    /// [`Segments::column`] for any CPU.
    #[inline(always)]
    fn column_portable(&self, fx: f64, fy: &[f64], gap: (usize, usize), out: &mut [Complex64]) {
        use std::f64::consts::PI;
        let rows = fy.len();
        // The two halves, each an arithmetic progression of fy: [0, split) and [split, rows),
        // less the gap.
        let split = (rows / 2 + 1).min(rows);
        let (g0, g1) = if gap.0 >= gap.1 {
            (split, split)
        } else {
            (gap.0.min(split), gap.1.max(split))
        };
        for (start, end) in [(0, g0), (g1, rows)] {
            out[start..end].fill(Complex64::new(0.0, 0.0));
        }
        for &(w, m, d) in &self.seg {
            for (start, end) in [(0, g0), (g1, rows)] {
                if start >= end {
                    continue;
                }
                let f0 = fy[start];
                let step = if end - start > 1 {
                    fy[start + 1] - fy[start]
                } else {
                    0.0
                };
                // Phase exp(−2πi f·m) and e^{iπ f·Δ} (whose imaginary part over π f·Δ is the
                // sinc), both advanced by a constant factor per row.
                let ph = Complex64::from_polar(w, -2.0 * PI * (fx * m[0] + f0 * m[1]));
                let ph_step = Complex64::from_polar(1.0, -2.0 * PI * step * m[1]);
                let a0 = fx * d[0] + f0 * d[1];
                let a_step = step * d[1];
                let e_step = Complex64::from_polar(1.0, PI * a_step);
                // LANES interleaved recurrences (lane l at rows l, l + LANES, …), so that
                // the multiplications of successive rows do not wait for each other.
                let mut phs = [ph; LANES];
                let mut es = [Complex64::from_polar(1.0, PI * a0); LANES];
                let mut as_ = [a0; LANES];
                for l in 1..LANES {
                    phs[l] = phs[l - 1] * ph_step;
                    es[l] = es[l - 1] * e_step;
                    as_[l] = a0 + l as f64 * a_step;
                }
                let (ph_jump, e_jump) = (ph_step.powu(LANES as u32), e_step.powu(LANES as u32));
                let a_jump = LANES as f64 * a_step;
                // The lanes held as arrays of real and imaginary parts (the same operations
                // as `Complex64`'s, in the same order, so the same values to the bit): the
                // compiler keeps each array in one vector register.
                let mut pr: [f64; LANES] = std::array::from_fn(|l| phs[l].re);
                let mut pi: [f64; LANES] = std::array::from_fn(|l| phs[l].im);
                let mut er: [f64; LANES] = std::array::from_fn(|l| es[l].re);
                let mut ei: [f64; LANES] = std::array::from_fn(|l| es[l].im);
                let mut av = as_;
                // sin(πa)/(πa) of every lane from e^{iπa}'s imaginary part: near a = 0 the
                // ratio loses digits and the series is exact to 1e-16 there. The ratio of
                // every lane at once (one vector division), the series only in the rare
                // chunks with a lane that needs it (its two divisions would otherwise
                // triple the cost).
                let sinc = |ei: &[f64; LANES], av: &[f64; LANES]| -> [f64; LANES] {
                    let x: [f64; LANES] = std::array::from_fn(|l| PI * av[l]);
                    let mut s: [f64; LANES] = std::array::from_fn(|l| ei[l] / x[l]);
                    let small = x.map(|x| x.abs() < 1e-3);
                    if small.iter().fold(false, |any, &b| any | b) {
                        for l in 0..LANES {
                            if small[l] {
                                s[l] = 1.0 - x[l] * x[l] / 6.0 * (1.0 - x[l] * x[l] / 20.0);
                            }
                        }
                    }
                    s
                };
                // A phase that does not advance (m_y = 0, e.g. a single segment, whose
                // midpoint is the path's mean): the recurrence would multiply by (1, ±0)
                // and return every lane unchanged but for the sign of a zero part, which
                // adds nothing to `out` (its sums start at +0), so it is skipped.
                let still = ph_jump.re == 1.0 && ph_jump.im == 0.0;
                let (jr, ji, qr, qi) = (ph_jump.re, ph_jump.im, e_jump.re, e_jump.im);
                let mut chunks = out[start..end].chunks_exact_mut(LANES);
                for c in &mut chunks {
                    let s = sinc(&ei, &av);
                    for l in 0..LANES {
                        c[l].re += pr[l] * s[l];
                        c[l].im += pi[l] * s[l];
                    }
                    if !still {
                        for l in 0..LANES {
                            let r = pr[l];
                            pr[l] = r * jr - pi[l] * ji;
                            pi[l] = pi[l] * jr + r * ji;
                        }
                    }
                    for l in 0..LANES {
                        let r = er[l];
                        er[l] = r * qr - ei[l] * qi;
                        ei[l] = ei[l] * qr + r * qi;
                        av[l] += a_jump;
                    }
                }
                let s = sinc(&ei, &av);
                for (l, o) in chunks.into_remainder().iter_mut().enumerate() {
                    o.re += pr[l] * s[l];
                    o.im += pi[l] * s[l];
                }
            }
        }
    }
}

/// Shifts one row's half spectrum (`cols/2+1` column frequencies of a `cols`-long real
/// row) by `s` samples: multiplies bin u by `e^{2πi u s / cols}` (the factor of
/// [`super::sampling::shift_phase`], advanced by one complex multiplication per bin),
/// and the Nyquist bin of an even row by `cos(πs)`.
fn shift_row(row: &mut [Complex64], cols: usize, s: f64) {
    if s == 0.0 {
        return;
    }
    let step = Complex64::from_polar(1.0, 2.0 * std::f64::consts::PI * s / cols as f64);
    let mut p = Complex64::new(1.0, 0.0);
    for (u, x) in row.iter_mut().enumerate() {
        if cols % 2 == 0 && u == cols / 2 {
            *x *= (std::f64::consts::PI * s).cos();
        } else {
            *x *= p;
        }
        p *= step;
    }
}

/// One detector row's sampling under motion: its row, and the padded-frame positions of
/// its own sample and of its first column (scene samples).
#[derive(Debug, Clone, Copy)]
struct RowAt {
    row: usize,
    y: f64,
    x0: f64,
}

impl Imager {
    /// The detector image of the band-summed spectrum `spectrum` (transposed, as
    /// [`Imager::with_spectrum`] hands it; not changed) for a frame that moved by
    /// `motion`: per group, the spectrum times the group's blur, each row sampled at its
    /// displaced position (see the [module documentation](self)), then cos⁴ if the optics
    /// ask for it. `scratch` is reused between calls. A displacement that would take a
    /// detector pixel's view outside the scene is an error naming the margin needed.
    pub fn detector_image_moving(
        &self,
        spectrum: &[Complex64],
        motion: &FrameMotion,
        scratch: &mut Vec<Complex64>,
    ) -> Result<Array2<f64>> {
        self.moving_image(spectrum, None, motion, scratch, ROW_POSITION_TOLERANCE_PX)
    }

    /// The zero gaps of `spectrum`'s columns (transposed, as [`Imager::with_spectrum`]
    /// hands it; [`super::lattice::column_zero_gaps`]), for
    /// [`Imager::detector_image_moving_with_gaps`]: found once for a sequence whose
    /// frames all sample the same spectrum instead of once per frame.
    pub fn spectrum_zero_gaps(&self, spectrum: &[Complex64]) -> Vec<(usize, usize)> {
        super::lattice::column_zero_gaps(spectrum, self.sampling.y.padded_len)
    }

    /// [`Imager::detector_image_moving`] with the zero gaps of `spectrum`'s columns found
    /// beforehand (`gaps`: [`Imager::spectrum_zero_gaps`] of this very `spectrum`), the
    /// same image to the bit (test).
    pub fn detector_image_moving_with_gaps(
        &self,
        spectrum: &[Complex64],
        gaps: &[(usize, usize)],
        motion: &FrameMotion,
        scratch: &mut Vec<Complex64>,
    ) -> Result<Array2<f64>> {
        self.moving_image(
            spectrum,
            Some(gaps),
            motion,
            scratch,
            ROW_POSITION_TOLERANCE_PX,
        )
    }

    /// [`Imager::detector_image_moving`] with rows' vertical positions within
    /// `row_tolerance_px` detector pixels of exact (0: every distinct position its own
    /// column pass, the exact per-row computation the tolerance is tested against).
    pub fn detector_image_moving_within(
        &self,
        spectrum: &[Complex64],
        motion: &FrameMotion,
        scratch: &mut Vec<Complex64>,
        row_tolerance_px: f64,
    ) -> Result<Array2<f64>> {
        self.moving_image(spectrum, None, motion, scratch, row_tolerance_px)
    }

    /// [`Imager::detector_image_moving_within`] with `spectrum`'s column gaps when known.
    fn moving_image(
        &self,
        spectrum: &[Complex64],
        gaps: Option<&[(usize, usize)]>,
        motion: &FrameMotion,
        scratch: &mut Vec<Complex64>,
        row_tolerance_px: f64,
    ) -> Result<Array2<f64>> {
        let (sy, sx) = (&self.sampling.y, &self.sampling.x);
        motion
            .check(sy.detector_len)
            .map_err(|m| Error::OutOfRange(format!("frame motion: {m}")))?;
        let (dy, dx) = self.sampling.scene_ifov_rad;
        let mut out = Array2::<f64>::zeros((sy.detector_len, sx.detector_len));
        for g in &motion.groups {
            let rows: Vec<RowAt> = g
                .rows
                .iter()
                .zip(&g.displacement_rad)
                .map(|(&row, d)| RowAt {
                    row,
                    y: sy.position(row) - d[1] / dy,
                    x0: sx.position(0) - d[0] / dx,
                })
                .collect();
            self.check_inside(&rows)?;
            if self.sampling.integer {
                self.sample_rows_integer(
                    spectrum,
                    gaps,
                    g.blur.as_ref(),
                    &rows,
                    row_tolerance_px,
                    scratch,
                    &mut out,
                );
            } else {
                scratch.clear();
                scratch.extend_from_slice(spectrum);
                if let Some(path) = &g.blur {
                    let frame = (sy.padded_len, sx.padded_len);
                    apply_path_otf(scratch, frame, &self.grid, path);
                }
                self.sample_rows_trigonometric(scratch, &rows, &mut out);
            }
        }
        Ok(self.with_cos4(out))
    }

    /// Errs when a displaced row or column leaves the scene's samples (it would read the
    /// padding): the scene must extend beyond the detector's field by the motion.
    fn check_inside(&self, rows: &[RowAt]) -> Result<()> {
        let (sy, sx) = (&self.sampling.y, &self.sampling.x);
        let inside = |p: f64, a: &super::AxisSampling| {
            let lo = a.pad_before as f64;
            let hi = lo + a.scene_len as f64 - 1.0;
            // How far outside [lo, hi], in detector pixels (0 inside).
            ((lo - p).max(p - hi).max(0.0)) / a.ratio
        };
        let span_x = (sx.detector_len as f64 - 1.0) * sx.ratio;
        let worst = rows
            .iter()
            .map(|r| {
                inside(r.y, sy)
                    .max(inside(r.x0, sx))
                    .max(inside(r.x0 + span_x, sx))
            })
            .fold(0.0, f64::max);
        if worst > 1e-9 {
            return Err(Error::param(
                "line-of-sight motion",
                format!(
                    "the detector's view moves {worst:.2} px beyond the scene's edge"
                ),
                format!(
                    "a scene that extends beyond the detector's field of view by the motion of the whole sequence: at least {} more detector pixels on each side (e.g. `eoir scene … --margin-px N`), or less motion / fewer frames",
                    worst.ceil() as u64 + 1
                ),
            ));
        }
        Ok(())
    }

    /// Integer detector/scene ratio: the rows of one group sampled at their positions from
    /// `spectrum` (the band sum, not changed) times the group's `blur`. Rows whose
    /// fractional y positions lie within 2·`tolerance_px` (detector pixels) share a column
    /// pass at their middle fraction; every row's x shift is exact. With the detector's
    /// lattice ([`super::lattice`]) one bin reads the spectrum once, blur and phases
    /// folded in; several bins blur a copy (`scratch`) once and fold it per bin. `gaps`:
    /// `spectrum`'s column zero gaps if known (used only when `spectrum` itself is folded).
    #[allow(clippy::too_many_arguments)]
    fn sample_rows_integer(
        &self,
        spectrum: &[Complex64],
        gaps: Option<&[(usize, usize)]>,
        blur: Option<&WindowPath>,
        rows: &[RowAt],
        tolerance_px: f64,
        scratch: &mut Vec<Complex64>,
        out: &mut Array2<f64>,
    ) {
        let (sy, sx) = (&self.sampling.y, &self.sampling.x);
        let (ny, nx) = (sy.padded_len, sx.padded_len);
        let kx = sx.integer_ratio().unwrap_or(1);
        let tol = tolerance_px * sy.ratio;
        let mut order: Vec<&RowAt> = rows.iter().collect();
        order.sort_by(|a, b| frac(a.y).total_cmp(&frac(b.y)));
        let mut bins: Vec<Vec<&RowAt>> = Vec::new();
        for r in order {
            match bins.last_mut() {
                Some(b) if frac(r.y) - frac(b[0].y) <= 2.0 * tol => b.push(r),
                _ => bins.push(vec![r]),
            }
        }
        let frame = (ny, nx);
        let columns = blur.map(|p| PathColumns::new(frame, &self.grid, p));
        let fill = |u: usize, h: &mut [Complex64]| {
            if let Some(c) = &columns {
                c.fill(u, h);
            }
        };
        // The blurred spectrum: the band sum itself when nothing blurs, fused into the fold
        // for a single bin, else a blurred copy shared by the bins.
        let fused = self.lattice.is_some() && bins.len() == 1;
        let (source, source_gaps): (&[Complex64], _) = match blur {
            Some(path) if !fused => {
                scratch.clear();
                scratch.extend_from_slice(spectrum);
                apply_path_otf(scratch, frame, &self.grid, path);
                (scratch, None)
            }
            _ => (spectrum, gaps),
        };
        let mut work: Vec<Complex64> = Vec::new();
        for bin in &bins {
            let lo = frac(bin[0].y);
            let hi = frac(bin[bin.len() - 1].y);
            let s = 0.5 * (lo + hi);
            let ry: Vec<Complex64> = (0..ny).map(|v| shift_phase(ny, v, s)).collect();
            let wanted: Vec<usize> = bin.iter().map(|r| (r.y - s).round() as usize).collect();
            let shifts: Vec<f64> = bin.iter().map(|r| frac(r.x0)).collect();
            let starts: Vec<usize> = bin.iter().map(|r| r.x0.floor() as usize).collect();
            let common_x = bin.iter().all(|r| r.x0 == bin[0].x0);
            let img = match &self.lattice {
                Some(lattice) if common_x => {
                    // Every row at the same columns (a global shutter): the fold along the
                    // rows on the spectrum, before the column transforms.
                    let fill_outside = |u: usize, gap: (usize, usize), h: &mut [Complex64]| {
                        if let Some(c) = &columns {
                            c.fill_outside(u, gap, h);
                        }
                    };
                    lattice.sample_common_x(
                        source,
                        source_gaps,
                        (fused && blur.is_some()).then_some(&fill_outside as _),
                        (s != 0.0).then_some(&ry[..]),
                        &wanted,
                        starts[0],
                        shifts[0],
                        sx.detector_len,
                    )
                }
                Some(lattice) => {
                    let factors = ColumnFactors {
                        per_column: (fused && blur.is_some()).then_some(&fill as _),
                        per_row: (s != 0.0).then_some(&ry[..]),
                    };
                    lattice.sample(
                        source,
                        &factors,
                        &wanted,
                        &starts,
                        sx.detector_len,
                        |i, row| shift_row(row, nx, shifts[i]),
                    )
                }
                None => {
                    work.clear();
                    work.extend_from_slice(source);
                    if s != 0.0 {
                        work.par_chunks_mut(ny).for_each(|col| {
                            for (a, r) in col.iter_mut().zip(&ry) {
                                *a *= r;
                            }
                        });
                    }
                    let mut full = Array2::<f64>::zeros((wanted.len(), nx));
                    self.fft.inverse_transposed_rows_with(
                        &mut work,
                        &wanted,
                        &mut full,
                        |i, row| shift_row(row, nx, shifts[i]),
                    );
                    Array2::from_shape_fn((wanted.len(), sx.detector_len), |(i, j)| {
                        full[[i, starts[i] + j * kx]]
                    })
                }
            };
            for (i, r) in bin.iter().enumerate() {
                out.row_mut(r.row).assign(&img.row(i));
            }
        }
    }

    /// Any ratio: every row of one group evaluated exactly at its displaced position by
    /// the band-limited interpolant ([`Imager::sample_trigonometric_at`]); `spec` is the
    /// group's blurred spectrum, transposed.
    fn sample_rows_trigonometric(&self, spec: &[Complex64], rows: &[RowAt], out: &mut Array2<f64>) {
        let (ny, hc) = self.fft.spectrum_shape();
        let mut acc = Array2::<Complex64>::zeros((ny, hc));
        super::fft::untranspose(spec, acc.as_slice_mut().expect("standard layout"), ny, hc);
        // Rows with the same x position share one interpolation basis.
        let mut by_x: Vec<(f64, Vec<(usize, f64)>)> = Vec::new();
        for r in rows {
            match by_x.iter_mut().find(|(x, _)| *x == r.x0) {
                Some((_, v)) => v.push((r.row, r.y)),
                None => by_x.push((r.x0, vec![(r.row, r.y)])),
            }
        }
        for (x0, rs) in by_x {
            let ys: Vec<f64> = rs.iter().map(|(_, y)| *y).collect();
            let img = self.sample_trigonometric_at(&acc, &ys, x0);
            for (i, (row, _)) in rs.iter().enumerate() {
                out.row_mut(*row).assign(&img.row(i));
            }
        }
    }
}

/// The fractional part in [0, 1).
fn frac(p: f64) -> f64 {
    p - p.floor()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::los::WindowPath;

    /// The column recurrence against the path's own transfer function at every sample of
    /// an even and an odd frame, a curved path (complex values) included.
    #[test]
    fn apply_path_otf_matches_the_paths_transfer_function() {
        let points: Vec<[f64; 2]> = (0..7)
            .map(|i| {
                let t = i as f64 / 6.0;
                [3e-4 * (5.0 * t).sin(), 2e-4 * t * t - 1e-4 * t]
            })
            .collect();
        let path = WindowPath::from_points(&points, 0.0);
        for (rows, cols) in [(16usize, 20usize), (15, 21), (8, 9)] {
            let grid = FrequencyGrid::real_fft(rows, cols, 1e-4, 1.2e-4);
            let half = cols / 2 + 1;
            let mut spec = vec![Complex64::new(1.0, 0.0); rows * half];
            apply_path_otf(&mut spec, (rows, cols), &grid, &path);
            for u in 0..half {
                for v in 0..rows {
                    let (fx, fy) = (grid.fx[u], grid.fy[v]);
                    let nyq_x = cols % 2 == 0 && u == cols / 2;
                    let nyq_y = rows % 2 == 0 && v == rows / 2;
                    let xs: &[f64] = if nyq_x { &[1.0, -1.0] } else { &[1.0] };
                    let ys: &[f64] = if nyq_y { &[1.0, -1.0] } else { &[1.0] };
                    let mut want = Complex64::new(0.0, 0.0);
                    for sx in xs {
                        for sy in ys {
                            want += path.otf(sx * fx, sy * fy);
                        }
                    }
                    want /= (xs.len() * ys.len()) as f64;
                    let got = spec[u * rows + v];
                    assert!(
                        (got - want).norm() < 1e-12,
                        "{rows}x{cols} u {u} v {v}: {got} vs {want}"
                    );
                }
            }
        }
    }

    /// The AVX2 build of a path's column gives the portable one's values to the bit, and
    /// leaves the rows of a gap untouched.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_avx2_column_is_the_portable_column() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let points: Vec<[f64; 2]> = (0..5)
            .map(|i| {
                let t = i as f64 / 4.0;
                [3e-4 * (5.0 * t).sin(), 2e-4 * t * t - 1e-4 * t]
            })
            .collect();
        let segments = Segments::of(&WindowPath::from_points(&points, 0.0));
        let grid = FrequencyGrid::real_fft(22, 20, 1e-4, 1.2e-4);
        for gap in [(22usize, 22usize), (7, 15)] {
            let marker = Complex64::new(7.0, -7.0);
            let mut a = vec![marker; 22];
            let mut b = a.clone();
            segments.column_portable(grid.fx[3], &grid.fy, gap, &mut a);
            // SAFETY: AVX2 is present (checked above).
            unsafe { segments.column_avx2(grid.fx[3], &grid.fy, gap, &mut b) };
            for (v, (x, y)) in a.iter().zip(&b).enumerate() {
                assert_eq!(
                    (x.re.to_bits(), x.im.to_bits()),
                    (y.re.to_bits(), y.im.to_bits())
                );
                let in_gap = gap.0 < gap.1 && (gap.0..gap.1).contains(&v);
                assert_eq!(*x == marker, in_gap, "row {v}");
            }
        }
    }

    /// The column evaluation with its lanes split into real and imaginary arrays gives the
    /// values of the plain `Complex64` recurrence (written out here: the phase and
    /// e^{iπa} advanced by one complex multiplication per row, the sinc the ratio or the
    /// series) to the bit, for a curved path, a single segment (whose phase does not
    /// advance) and a path through the origin along x only, with and without a gap.
    #[test]
    fn the_column_is_the_complex_recurrence_to_the_bit() {
        use std::f64::consts::PI;
        fn reference(seg: &Segments, fx: f64, fy: &[f64], gap: (usize, usize)) -> Vec<Complex64> {
            let rows = fy.len();
            let split = rows / 2 + 1;
            let (g0, g1) = if gap.0 >= gap.1 {
                (split, split)
            } else {
                (gap.0.min(split), gap.1.max(split))
            };
            let mut out = vec![Complex64::new(7.0, -7.0); rows];
            for (a, b) in [(0, g0), (g1, rows)] {
                out[a..b].fill(Complex64::new(0.0, 0.0));
            }
            for &(w, m, d) in &seg.seg {
                for (a, b) in [(0, g0), (g1, rows)] {
                    if a >= b {
                        continue;
                    }
                    let step = if b - a > 1 { fy[a + 1] - fy[a] } else { 0.0 };
                    let mut ph =
                        [Complex64::from_polar(w, -2.0 * PI * (fx * m[0] + fy[a] * m[1])); LANES];
                    let ph_step = Complex64::from_polar(1.0, -2.0 * PI * step * m[1]);
                    let a0 = fx * d[0] + fy[a] * d[1];
                    let a_step = step * d[1];
                    let e_step = Complex64::from_polar(1.0, PI * a_step);
                    let mut e = [Complex64::from_polar(1.0, PI * a0); LANES];
                    let mut x = [a0; LANES];
                    for l in 1..LANES {
                        ph[l] = ph[l - 1] * ph_step;
                        e[l] = e[l - 1] * e_step;
                        x[l] = a0 + l as f64 * a_step;
                    }
                    let (pj, ej) = (ph_step.powu(LANES as u32), e_step.powu(LANES as u32));
                    for (i, o) in out[a..b].iter_mut().enumerate() {
                        let l = i % LANES;
                        let t = PI * x[l];
                        let sinc = if t.abs() < 1e-3 {
                            1.0 - t * t / 6.0 * (1.0 - t * t / 20.0)
                        } else {
                            e[l].im / t
                        };
                        *o += ph[l] * sinc;
                        ph[l] *= pj;
                        e[l] *= ej;
                        x[l] += LANES as f64 * a_step;
                    }
                }
            }
            out
        }
        let curved: Vec<[f64; 2]> = (0..5)
            .map(|i| {
                let t = i as f64 / 4.0;
                [3e-4 * (5.0 * t).sin(), 2e-4 * t * t - 1e-4 * t]
            })
            .collect();
        let paths = [
            WindowPath::from_points(&curved, 0.0),
            WindowPath::from_points(&[[0.0, 0.0], [2e-4, 3e-4]], 0.0),
            WindowPath::from_points(&[[-1e-4, 0.0], [0.0, 0.0], [1e-4, 0.0]], 0.0),
        ];
        for path in &paths {
            let segments = Segments::of(path);
            for (rows, cols) in [(22usize, 20usize), (23, 21)] {
                let grid = FrequencyGrid::real_fft(rows, cols, 1e-4, 1.2e-4);
                for gap in [(rows, rows), (7, 15)] {
                    for u in [0, 3, cols / 2] {
                        let want = reference(&segments, grid.fx[u], &grid.fy, gap);
                        let mut got = vec![Complex64::new(7.0, -7.0); rows];
                        segments.column_portable(grid.fx[u], &grid.fy, gap, &mut got);
                        for (v, (x, y)) in got.iter().zip(&want).enumerate() {
                            assert_eq!(
                                (x.re.to_bits(), x.im.to_bits()),
                                (y.re.to_bits(), y.im.to_bits()),
                                "{rows}x{cols} u {u} gap {gap:?} row {v}: {x} vs {y}"
                            );
                        }
                    }
                }
            }
        }
    }

    /// The shift factor of one row equals `shift_phase` bin by bin.
    #[test]
    fn shift_row_is_the_shift_phase() {
        for cols in [10usize, 11] {
            let mut row = vec![Complex64::new(1.0, 0.0); cols / 2 + 1];
            shift_row(&mut row, cols, 0.37);
            for (u, r) in row.iter().enumerate() {
                assert!((r - shift_phase(cols, u, 0.37)).norm() < 1e-13);
            }
        }
    }
}
