//! The zones' OTF tables and their lookup: each zone's pupil OTF stored on the window of
//! the normalised-frequency grid the frame reaches, and the per-band bilinear taps shared
//! by every zone and wavelength node (docs/field-optics.md, "Speed of the space-variant
//! wavefront path").

use super::*;

/// The part of the zones' common OTF grid (normalised frequency, `n` pupil samples across,
/// `m × m` grid, half plane `cols = m/2 + 1` columns from X = 0) that the frame's
/// frequencies reach at the longest wavelength in use: rows `row0 .. row0 + rows`, columns
/// `0 .. width`. Only this window is stored: at F/2 in the MWIR on a 0.6 mrad grid it is a
/// ninth of the grid, which keeps K zones × their wavelength nodes small and in cache.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct TableWindow {
    pub(super) n: usize,
    pub(super) m: usize,
    pub(super) cols: usize,
    pub(super) row0: usize,
    pub(super) rows: usize,
    pub(super) width: usize,
}

impl TableWindow {
    /// The window of an `n`-across, `m × m` grid holding every bilinear tap of the
    /// normalised frequencies |X| ≤ `reach_x`, |Y| ≤ `reach_y` (two samples of margin).
    pub(super) fn new(n: usize, m: usize, reach_x: f64, reach_y: f64) -> Self {
        let cols = m / 2 + 1;
        let nf = n as f64;
        let half = (m / 2) as f64;
        let clamp = |v: f64, hi: usize| {
            if v.is_finite() {
                (v.max(0.0) as usize).min(hi)
            } else {
                hi
            }
        };
        let width = clamp((reach_x * nf).ceil() + 2.0, cols);
        let row0 = clamp((half - reach_y * nf).floor() - 2.0, m);
        let end = clamp((half + reach_y * nf).ceil() + 3.0, m);
        TableWindow {
            n,
            m,
            cols,
            row0,
            rows: end.saturating_sub(row0),
            width,
        }
    }

    /// Bilinear tap along the columns at X ≥ 0 (`c = X n`); `None` beyond the grid (the
    /// OTF is 0 there) or beyond the window.
    #[inline]
    pub(super) fn column_tap(&self, x: f64) -> Option<Tap> {
        let c = x * self.n as f64;
        if !(c >= 0.0 && c <= (self.cols - 1) as f64) {
            return None;
        }
        let c0 = c as usize;
        let c1 = (c0 + 1).min(self.cols - 1);
        let t = (c - c0 as f64) as f32;
        (c1 < self.width).then_some(Tap {
            i0: c0,
            i1: c1,
            w0: 1.0 - t,
            w1: t,
        })
    }

    /// Bilinear tap along the rows at Y (`r = Y n + m/2`), row indices relative to the
    /// window's first row; `None` beyond the grid or the window.
    #[inline]
    pub(super) fn row_tap(&self, y: f64) -> Option<Tap> {
        let r = y * self.n as f64 + (self.m / 2) as f64;
        if !(r >= 0.0 && r <= (self.m - 1) as f64) {
            return None;
        }
        let r0 = r as usize;
        let r1 = (r0 + 1).min(self.m - 1);
        let t = (r - r0 as f64) as f32;
        (r0 >= self.row0 && r1 < self.row0 + self.rows).then_some(Tap {
            i0: r0 - self.row0,
            i1: r1 - self.row0,
            w0: 1.0 - t,
            w1: t,
        })
    }
}

/// One axis of a bilinear interpolation: the two neighbouring indices and their weights
/// (`1 − t`, `t`, f32 as the tables).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Tap {
    pub(super) i0: usize,
    pub(super) i1: usize,
    pub(super) w0: f32,
    pub(super) w1: f32,
}

/// One zone's OTF at one wavelength node on the half plane X ≥ 0 (normalised frequency
/// X = f/f_c, f_c = D/λ): grid element `(r, c)` at `X = c/n`, `Y = (r − m/2)/n`, f32, the
/// [`TableWindow`] of it only.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct HalfPlaneOtf {
    pub(super) window: TableWindow,
    pub(super) data: Vec<Complex32>,
}

impl HalfPlaneOtf {
    pub(super) fn from_transfer(t: &PupilTransfer, window: TableWindow) -> Self {
        let g = t.otf_grid();
        let m = g.nrows();
        debug_assert_eq!((window.m, window.n), (m, t.sampling().samples_across));
        let mut data = vec![Complex32::new(0.0, 0.0); window.rows * window.width];
        for (i, r) in (window.row0..window.row0 + window.rows).enumerate() {
            for c in 0..window.width {
                let cc = m / 2 + c;
                if cc < m {
                    let v = g[(r, cc)];
                    data[i * window.width + c] = Complex32::new(v.re as f32, v.im as f32);
                }
            }
        }
        HalfPlaneOtf { window, data }
    }

    /// The table of the zone mirrored across the field's vertical axis (`flip_x`: the
    /// pupil and PSF mirrored in x, `OTF(−X, Y) = conj OTF(X, −Y)` for a real PSF) and/or
    /// its horizontal axis (`flip_y`: `OTF(X, −Y)`); both: `conj OTF(X, Y)`. Row r of the
    /// grid is at −Y in row m − r, which the window holds (it is symmetric about m/2 to
    /// within its margin); row 0 (Y = −padding/2, beyond the cutoff) mirrors to 0.
    pub(super) fn mirrored(&self, flip_x: bool, flip_y: bool) -> Self {
        if !flip_x && !flip_y {
            return self.clone();
        }
        let w = self.window;
        let mut data = vec![Complex32::new(0.0, 0.0); self.data.len()];
        for i in 0..w.rows {
            let r = w.row0 + i;
            let from = if flip_x != flip_y { w.m - r } else { r };
            if from < w.row0 || from >= w.row0 + w.rows {
                continue;
            }
            let src = &self.data[(from - w.row0) * w.width..][..w.width];
            for (o, v) in data[i * w.width..][..w.width].iter_mut().zip(src) {
                *o = if flip_x { v.conj() } else { *v };
            }
        }
        HalfPlaneOtf { window: w, data }
    }

    /// Bilinear interpolation between the taps `row` and `col`: the four weighted samples
    /// summed in a fixed order.
    #[inline]
    pub(super) fn tapped(&self, row: Tap, col: Tap) -> Complex32 {
        let w = self.window.width;
        let (a, b) = (row.i0 * w, row.i1 * w);
        let d = &self.data;
        d[a + col.i0] * (col.w0 * row.w0)
            + d[a + col.i1] * (col.w1 * row.w0)
            + d[b + col.i0] * (col.w0 * row.w1)
            + d[b + col.i1] * (col.w1 * row.w1)
    }

    /// Bilinear interpolation at (X ≥ 0, Y); 0 beyond the grid (and beyond the stored
    /// window, which the frame's frequencies do not reach).
    #[inline]
    pub(super) fn at(&self, x: f64, y: f64) -> Complex64 {
        match (self.window.row_tap(y), self.window.column_tap(x)) {
            (Some(r), Some(c)) => {
                let v = self.tapped(r, c);
                Complex64::new(v.re as f64, v.im as f64)
            }
            _ => Complex64::new(0.0, 0.0),
        }
    }
}

/// The bilinear taps of one band on the frame's half-plane grid: the table column depends
/// only on fx (`X = fx λ/D`) and the row only on fy, so they are computed once per band
/// (`rows.len()` + `cols.len()` taps) and shared by every zone and wavelength node.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct BandTaps {
    pub(super) rows: Vec<Option<Tap>>,
    pub(super) cols: Vec<Option<Tap>>,
}
