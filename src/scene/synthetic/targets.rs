//! Laboratory targets: 4-bar groups tied to the detector Nyquist frequency, a slanted
//! edge, a uniform blackbody and a temperature ramp (emitted radiance only, as in a
//! collimator with a cold surround).

use super::*;

/// Fills a cube whose pixels are area mixtures of two blackbodies:
/// `L = f·B(λ, t_one) + (1 − f)·B(λ, t_zero)` with `f` the covered fraction of the pixel.
fn two_temperature_cube(
    p: &SceneParams,
    coverage: &Array2<f64>,
    t_one: f64,
    t_zero: f64,
) -> Result<Cube> {
    let (rows, cols) = coverage.dim();
    let mut data = Array3::<f32>::zeros((p.wavelength_um.len(), rows, cols));
    data.axis_iter_mut(Axis(0))
        .into_par_iter()
        .zip(p.wavelength_um.par_iter())
        .for_each(|(mut plane, &l)| {
            let one = planck_spectral_radiance(l, t_one);
            let zero = planck_spectral_radiance(l, t_zero);
            plane.zip_mut_with(coverage, |v, &f| *v = (f * one + (1.0 - f) * zero) as f32);
        });
    Cube::new(data, p.meta())
}

/// One 4-bar pattern of the [`bars`] scene, in cube pixel coordinates (pixel `i` spans
/// `[i, i+1)`, x to the right, y down).
#[derive(Debug, Clone, PartialEq)]
pub struct BarGroup {
    /// Spatial frequency of the bars, cycles/mrad (one cycle = one bar + one space).
    pub frequency_cy_per_mrad: f64,
    /// Width of one bar (= one space), cube pixels.
    pub bar_width_px: f64,
    /// false: vertical bars (modulation along x, measured on a row cut);
    /// true: horizontal bars (modulation along y, measured on a column cut).
    pub horizontal_bars: bool,
    /// Left edge of the pattern's 7w × 7w square.
    pub x0_px: f64,
    /// Top edge of the pattern's 7w × 7w square.
    pub y0_px: f64,
}

impl BarGroup {
    /// The four bars as rectangles `(x0, x1, y0, y1)` in cube pixels: bar `j` spans
    /// `[2jw, (2j+1)w]` across and `7w` along (7:1 aspect).
    pub fn bars(&self) -> [(f64, f64, f64, f64); 4] {
        let w = self.bar_width_px;
        std::array::from_fn(|j| {
            let a = 2.0 * j as f64 * w;
            if self.horizontal_bars {
                (
                    self.x0_px,
                    self.x0_px + 7.0 * w,
                    self.y0_px + a,
                    self.y0_px + a + w,
                )
            } else {
                (
                    self.x0_px + a,
                    self.x0_px + a + w,
                    self.y0_px,
                    self.y0_px + 7.0 * w,
                )
            }
        })
    }
}

/// Most 4-bar groups in the [`bars`] scene.
const MAX_BAR_GROUPS: usize = 6;

/// The layout of the [`bars`] scene.
///
/// Frequencies: the detector Nyquist frequency `f_N = 1/(2·IFOV)` (IFOV = fov_x/cols) and
/// below it by factors of √2, up to six groups (`f_N`, 0.71 f_N, … 0.18 f_N), so bar widths
/// are 1, √2, 2, … detector pixels. As many groups as fit are kept, highest frequencies
/// first: one row of vertical-bar patterns left to right from low to high frequency,
/// spaced by the widest bar width (at least 2 detector pixels), and, when the image is tall
/// enough, a second row below with the same groups as horizontal bars. The layout is
/// centred in the image; bar edges fall anywhere (area-weighted pixels).
pub fn bars_layout(p: &SceneParams) -> Result<Vec<BarGroup>> {
    p.validate()?;
    let (rows, cols) = (p.rows as f64, p.cols as f64);
    let f_nyquist_cy_per_mrad = 1.0 / (2.0 * p.detector_ifov_rad()) / 1000.0;
    let ratio = std::f64::consts::SQRT_2;
    let k = p.oversampling as f64;
    for groups in (1..=MAX_BAR_GROUPS).rev() {
        // Detector pixels, from the lowest frequency (widest bars) to the highest.
        let widths: Vec<f64> = (0..groups).rev().map(|j| ratio.powi(j as i32)).collect();
        let w_max = widths[0];
        let gap = w_max.max(2.0);
        let total_w = 7.0 * widths.iter().sum::<f64>() + (groups as f64 + 1.0) * gap;
        let one_row_h = 7.0 * w_max + 2.0 * gap;
        if total_w > cols || one_row_h > rows {
            continue;
        }
        let two_rows = 14.0 * w_max + 3.0 * gap <= rows;
        let row_centres: Vec<(bool, f64)> = if two_rows {
            let off = 3.5 * w_max + 0.5 * gap;
            vec![(false, rows / 2.0 - off), (true, rows / 2.0 + off)]
        } else {
            vec![(false, rows / 2.0)]
        };
        let mut layout = Vec::new();
        for (horizontal_bars, yc) in row_centres {
            let mut x = (cols - total_w) / 2.0 + gap;
            for &w in &widths {
                layout.push(BarGroup {
                    frequency_cy_per_mrad: f_nyquist_cy_per_mrad / w,
                    bar_width_px: w * k,
                    horizontal_bars,
                    x0_px: x * k,
                    y0_px: (yc - 3.5 * w) * k,
                });
                x += 7.0 * w + gap;
            }
        }
        return Ok(layout);
    }
    Err(Error::param(
        "rows × cols",
        format!("{} × {}", p.rows, p.cols),
        "at least 11 × 11 detector pixels for one 4-bar group at the Nyquist frequency with its margins",
    ))
}

/// Frequencies of the [`bars`] groups, cycles/mrad, in layout order (low to high); empty
/// when the parameters are invalid or the image is too small for one group.
pub fn bars_frequencies_cy_per_mrad(p: &SceneParams) -> Vec<f64> {
    bars_layout(p)
        .map(|groups| {
            groups
                .iter()
                .filter(|g| !g.horizontal_bars)
                .map(|g| g.frequency_cy_per_mrad)
                .collect()
        })
        .unwrap_or_default()
}

/// Length of the overlap of `[a0, a1]` and `[b0, b1]`.
fn overlap(a0: f64, a1: f64, b0: f64, b1: f64) -> f64 {
    (a1.min(b1) - a0.max(b0)).max(0.0)
}

/// 4-bar targets: blackbody bars at `t_bar_k` on a blackbody background at
/// `t_background_k` (see [`bars_layout`] for the geometry). Edge pixels hold the exact
/// area mixture of the two radiances.
pub fn bars(p: &SceneParams, t_bar_k: f64, t_background_k: f64) -> Result<Cube> {
    check_temperature("t_bar_k", t_bar_k)?;
    check_temperature("t_background_k", t_background_k)?;
    let layout = bars_layout(p)?;
    let (rows, cols) = (p.cube_rows(), p.cube_cols());
    let mut coverage = Array2::<f64>::zeros((rows, cols));
    for group in &layout {
        for (x0, x1, y0, y1) in group.bars() {
            let (c0, c1) = (x0.floor().max(0.0) as usize, (x1.ceil() as usize).min(cols));
            let (r0, r1) = (y0.floor().max(0.0) as usize, (y1.ceil() as usize).min(rows));
            for r in r0..r1 {
                let fy = overlap(r as f64, r as f64 + 1.0, y0, y1);
                for c in c0..c1 {
                    coverage[[r, c]] += fy * overlap(c as f64, c as f64 + 1.0, x0, x1);
                }
            }
        }
    }
    coverage.mapv_inplace(|f| f.min(1.0));
    two_temperature_cube(p, &coverage, t_bar_k, t_background_k)
}

/// Area of the unit pixel `[x0, x0+1] × [y0, y0+1]` where `nx·x + ny·y ≥ d` (|n| = 1),
/// by clipping the square with the half-plane (Sutherland–Hodgman) and the shoelace formula.
pub(super) fn half_plane_coverage(x0: f64, y0: f64, nx: f64, ny: f64, d: f64) -> f64 {
    let centre = nx * (x0 + 0.5) + ny * (y0 + 0.5) - d;
    let reach = 0.5 * (nx.abs() + ny.abs());
    if centre >= reach {
        return 1.0;
    }
    if centre <= -reach {
        return 0.0;
    }
    let square = [
        (x0, y0),
        (x0 + 1.0, y0),
        (x0 + 1.0, y0 + 1.0),
        (x0, y0 + 1.0),
    ];
    let side = |(x, y): (f64, f64)| nx * x + ny * y - d;
    let mut clipped: Vec<(f64, f64)> = Vec::with_capacity(5);
    for i in 0..4 {
        let a = square[i];
        let b = square[(i + 1) % 4];
        let (sa, sb) = (side(a), side(b));
        if sa >= 0.0 {
            clipped.push(a);
        }
        if (sa >= 0.0) != (sb >= 0.0) {
            let t = sa / (sa - sb);
            clipped.push((a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1)));
        }
    }
    if clipped.len() < 3 {
        return 0.0;
    }
    let n = clipped.len();
    let twice_area: f64 = (0..n)
        .map(|i| {
            let (xa, ya) = clipped[i];
            let (xb, yb) = clipped[(i + 1) % n];
            xa * yb - xb * ya
        })
        .sum();
    (0.5 * twice_area.abs()).clamp(0.0, 1.0)
}

/// A straight edge through the centre of the image between blackbodies at `t_low_k` and
/// `t_high_k`, tilted by `angle_deg` from the vertical ([`DEFAULT_EDGE_ANGLE_DEG`] is the
/// usual slanted-edge choice).
///
/// The edge is the line `x = x_c + (y − y_c)·tan θ` (y down, so a positive angle makes the
/// edge cross lower rows further right: a counter-clockwise tilt as displayed); the hot side
/// is `(x − x_c) cos θ − (y − y_c) sin θ > 0`, i.e. the right for |θ| < 90°, the top for
/// θ = 90°. Pixels cut by the edge hold the exact area mixture of the two radiances, so
/// exactly half of the image area is hot.
pub fn edge(p: &SceneParams, t_low_k: f64, t_high_k: f64, angle_deg: f64) -> Result<Cube> {
    p.validate()?;
    check_temperature("t_low_k", t_low_k)?;
    check_temperature("t_high_k", t_high_k)?;
    if !(angle_deg.is_finite() && (-180.0..=180.0).contains(&angle_deg)) {
        return Err(Error::param(
            "angle_deg",
            angle_deg,
            "an edge angle from the vertical in [-180, 180] degrees",
        ));
    }
    let (rows, cols) = (p.cube_rows(), p.cube_cols());
    let theta = angle_deg.to_radians();
    let (nx, ny) = (theta.cos(), -theta.sin());
    // Coordinates relative to the image centre keep the arithmetic exact near the edge.
    let (xc, yc) = (cols as f64 / 2.0, rows as f64 / 2.0);
    let mut coverage = Array2::<f64>::zeros((rows, cols));
    coverage
        .axis_iter_mut(Axis(0))
        .into_par_iter()
        .enumerate()
        .for_each(|(r, mut row)| {
            for (c, f) in row.iter_mut().enumerate() {
                *f = half_plane_coverage(c as f64 - xc, r as f64 - yc, nx, ny, 0.0);
            }
        });
    two_temperature_cube(p, &coverage, t_high_k, t_low_k)
}

/// A uniform grey body: `L = ε·B(λ, T)` at every pixel (emitted radiance only, as for a
/// laboratory source seen against a cold surround).
pub fn blackbody(p: &SceneParams, t_k: f64, emissivity: f64) -> Result<Cube> {
    p.validate()?;
    check_temperature("t_k", t_k)?;
    if !(emissivity.is_finite() && (0.0..=1.0).contains(&emissivity)) {
        return Err(Error::param("emissivity", emissivity, "a number in [0, 1]"));
    }
    let (rows, cols) = (p.cube_rows(), p.cube_cols());
    let mut data = Array3::<f32>::zeros((p.wavelength_um.len(), rows, cols));
    data.axis_iter_mut(Axis(0))
        .into_par_iter()
        .zip(p.wavelength_um.par_iter())
        .for_each(|(mut plane, &l)| {
            plane.fill((emissivity * planck_spectral_radiance(l, t_k)) as f32);
        });
    Cube::new(data, p.meta())
}

/// A blackbody whose temperature rises linearly across the field, from `t_min_k` at the
/// left edge to `t_max_k` at the right edge; each pixel has the temperature at its centre,
/// `T = t_min + (t_max − t_min)·(c + ½)/cols` (cube columns), the same on every row.
pub fn ramp(p: &SceneParams, t_min_k: f64, t_max_k: f64) -> Result<Cube> {
    p.validate()?;
    check_temperature("t_min_k", t_min_k)?;
    check_temperature("t_max_k", t_max_k)?;
    if t_max_k < t_min_k {
        return Err(Error::param(
            "t_max_k",
            t_max_k,
            format!("a temperature >= t_min_k = {t_min_k} K"),
        ));
    }
    let (rows, cols) = (p.cube_rows(), p.cube_cols());
    let temperatures: Vec<f64> = (0..cols)
        .map(|c| t_min_k + (t_max_k - t_min_k) * (c as f64 + 0.5) / cols as f64)
        .collect();
    let mut data = Array3::<f32>::zeros((p.wavelength_um.len(), rows, cols));
    data.axis_iter_mut(Axis(0))
        .into_par_iter()
        .zip(p.wavelength_um.par_iter())
        .for_each(|(mut plane, &l)| {
            let planck = PlanckBand::new(l);
            let column: Vec<f32> = temperatures
                .iter()
                .map(|&t| planck.radiance(t) as f32)
                .collect();
            for mut row in plane.outer_iter_mut() {
                for (v, &x) in row.iter_mut().zip(&column) {
                    *v = x;
                }
            }
        });
    Cube::new(data, p.meta())
}
