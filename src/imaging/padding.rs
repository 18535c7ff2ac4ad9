//! Padding of a band plane into the FFT frame: the image in the middle, a raised-cosine
//! cross-fade between the mirror images of the two edges in the pad (see [`PadMap`]), so
//! the circular frame has no jump.

use ndarray::ArrayView2;

use super::fft::FftFloat;

/// One padded sample as a blend of two image samples: `w·x[a] + (1 − w)·x[b]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Tap {
    a: usize,
    b: usize,
    w: f64,
}

/// How the padded FFT frame is filled along one axis.
///
/// Inside the image: the image. In the pad (which, the FFT being circular, runs from the
/// image's last sample round to its first): a raised-cosine cross-fade from the mirror
/// image of the trailing edge to the mirror image of the leading edge. Next to each edge
/// the pad is a pure mirror (continuous, as a half-sample-symmetric extension), and the
/// periodic frame has no jump where the two mirrors meet — a plain mirror pad has one
/// there, only P samples from the image, which any transfer function that is not small at
/// the Nyquist frequency rings on.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct PadMap {
    taps: Vec<Tap>,
    /// Padded index of image sample 0 (the interior is `before .. before + n`, where every
    /// tap is the image sample itself with weight 1).
    before: usize,
    /// Image length along the axis.
    n: usize,
}

impl PadMap {
    /// The padded indices that hold the image samples themselves, in order.
    pub(super) fn image_range(&self) -> std::ops::Range<usize> {
        self.before..self.before + self.n
    }

    pub(super) fn new(n: usize, pad_before: usize, padded_len: usize) -> Self {
        let pad_total = padded_len - n;
        let taps = (0..padded_len)
            .map(|c| {
                let t = c as isize - pad_before as isize;
                if t >= 0 && (t as usize) < n {
                    return Tap {
                        a: t as usize,
                        b: t as usize,
                        w: 1.0,
                    };
                }
                // Distance into the pad from the trailing edge, 0 … pad_total − 1.
                let q = (t - n as isize).rem_euclid(padded_len as isize) as usize;
                let trailing = mirror_index((n + q) as isize, n);
                let leading = mirror_index(q as isize - pad_total as isize, n);
                let w = 0.5
                    * (1.0 + (std::f64::consts::PI * (q as f64 + 0.5) / pad_total as f64).cos());
                Tap {
                    a: trailing,
                    b: leading,
                    w,
                }
            })
            .collect();
        PadMap {
            taps,
            before: pad_before,
            n,
        }
    }
}

/// Mirror (half-sample symmetric) index: maps any integer onto `0..n`.
fn mirror_index(i: isize, n: usize) -> usize {
    let n = n as isize;
    let period = 2 * n;
    let m = i.rem_euclid(period);
    (if m < n { m } else { period - 1 - m }) as usize
}

/// The padding of both axes of a frame.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct FramePad {
    /// Rows.
    pub(super) y: PadMap,
    /// Columns.
    pub(super) x: PadMap,
}

impl FramePad {
    /// Row `r` of the padded frame of a band plane (see `PadMap`), blended in f64 and
    /// rounded to the transform's type.
    ///
    /// The two blends are separable: the source row is `w_y·row[a] + (1 − w_y)·row[b]`
    /// (the image row itself inside the image, where `w_y = 1`), then each output sample
    /// is `w_x·v[a] + (1 − w_x)·v[b]` of it (the sample itself inside the image). Inside
    /// the image both blends are the identity, so the interior is a straight conversion
    /// of the image row (vectorised) and only the pad margins go through the taps; `1·v +
    /// 0·v = v` exactly for every finite v (signed zeros included), so the result is the
    /// same, bit for bit, as blending every sample (tested).
    pub(super) fn row<T: FftFloat>(&self, plane: &ArrayView2<f32>, r: usize, out: &mut [T]) {
        let ty = self.y.taps[r];
        let (x0, n) = (self.x.before, self.x.n);
        let taps = &self.x.taps;
        let ra = plane.row(ty.a);
        let rb = plane.row(ty.b);
        let interior_row = ty.w == 1.0 && ty.a == ty.b;
        if let (true, Some(src)) = (interior_row, ra.as_slice()) {
            for (o, v) in out[x0..x0 + n].iter_mut().zip(src) {
                *o = T::nearest_from_f64(*v as f64);
            }
            let v = |c: usize| src[c] as f64;
            for (o, tx) in out[..x0].iter_mut().zip(&taps[..x0]) {
                *o = T::nearest_from_f64(tx.w * v(tx.a) + (1.0 - tx.w) * v(tx.b));
            }
            for (o, tx) in out[x0 + n..].iter_mut().zip(&taps[x0 + n..]) {
                *o = T::nearest_from_f64(tx.w * v(tx.a) + (1.0 - tx.w) * v(tx.b));
            }
            return;
        }
        // A pad row: the blend of the two source rows, sample by sample as it is needed
        // (the same f64 value wherever it is used, so no blended copy of the row).
        let v = |c: usize| ty.w * ra[c] as f64 + (1.0 - ty.w) * rb[c] as f64;
        if let (Some(a), Some(b)) = (ra.as_slice(), rb.as_slice()) {
            for ((o, a), b) in out[x0..x0 + n].iter_mut().zip(a).zip(b) {
                *o = T::nearest_from_f64(ty.w * *a as f64 + (1.0 - ty.w) * *b as f64);
            }
        } else {
            for (c, o) in out[x0..x0 + n].iter_mut().enumerate() {
                *o = T::nearest_from_f64(v(c));
            }
        }
        for (o, tx) in out[..x0].iter_mut().zip(&taps[..x0]) {
            *o = T::nearest_from_f64(tx.w * v(tx.a) + (1.0 - tx.w) * v(tx.b));
        }
        for (o, tx) in out[x0 + n..].iter_mut().zip(&taps[x0 + n..]) {
            *o = T::nearest_from_f64(tx.w * v(tx.a) + (1.0 - tx.w) * v(tx.b));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array2;

    /// Every sample blended through both taps, as the definition reads (the reference the
    /// fast interior path must reproduce bit for bit).
    fn reference<T: FftFloat>(pad: &FramePad, plane: &Array2<f32>, r: usize) -> Vec<T> {
        let ty = pad.y.taps[r];
        let v = |c: usize| ty.w * plane[[ty.a, c]] as f64 + (1.0 - ty.w) * plane[[ty.b, c]] as f64;
        pad.x
            .taps
            .iter()
            .map(|tx| T::nearest_from_f64(tx.w * v(tx.a) + (1.0 - tx.w) * v(tx.b)))
            .collect()
    }

    fn check<T: FftFloat + std::fmt::Debug>(rows: usize, cols: usize, by: usize, bx: usize) {
        let (ly, lx) = (rows + 2 * by + 3, cols + 2 * bx + 1);
        let pad = FramePad {
            y: PadMap::new(rows, by, ly),
            x: PadMap::new(cols, bx, lx),
        };
        // Values with −0.0 and +0.0 among them, and awkward fractions.
        let plane = Array2::from_shape_fn((rows, cols), |(r, c)| match (r * 7 + c * 3) % 5 {
            0 => -0.0,
            1 => 0.0,
            k => (k as f32) * 1.37e3 / (1.0 + (r * c) as f32),
        });
        // The same values in column-major order: rows that are not contiguous slices take
        // the element-wise paths.
        let column_major = plane.t().as_standard_layout().into_owned();
        for view in [plane.view(), column_major.t()] {
            for r in 0..ly {
                let mut out = vec![T::nearest_from_f64(9.0); lx];
                pad.row(&view, r, &mut out);
                let want = reference::<T>(&pad, &plane, r);
                for (c, (a, b)) in out.iter().zip(&want).enumerate() {
                    assert_eq!(
                        a.widen().to_bits(),
                        b.widen().to_bits(),
                        "{rows}x{cols} row {r} col {c}"
                    );
                }
            }
        }
    }

    /// The interior fast path and the pad-row path equal the two-tap definition bit for
    /// bit, for both transform precisions, including signed zeros, whether the plane's
    /// rows are contiguous or not.
    #[test]
    fn rows_match_the_tap_definition_bit_for_bit() {
        check::<f32>(9, 13, 4, 5);
        check::<f64>(9, 13, 4, 5);
        check::<f32>(5, 4, 0, 7);
        check::<f64>(16, 3, 6, 0);
    }
}
