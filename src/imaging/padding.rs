//! Padding of a band plane into the FFT frame: the image in the middle, a raised-cosine
//! cross-fade between the mirror images of the two edges in the pad (see [`PadMap`]), so
//! the circular frame has no jump.

use ndarray::ArrayView2;
use num_complex::Complex64;
use rayon::prelude::*;

use super::fft::FftFloat;
use crate::sensor::{Component, SystemOtf};

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

/// The shortest line-spread function `pad_width` computes, samples.
const MIN_LSF_LEN: usize = 1 << 10;

/// Pad width (samples) along one axis so that wrap-around stays below `tolerance`.
///
/// The FFT is circular: a scene sample at one edge leaks into the opposite edge through
/// the padding, at a distance of at least 2P samples (the pad, filled as in `PadMap`,
/// mirrors the edge sample one sample outside it). The line-spread function (LSF) along
/// the axis is computed numerically from the system OTF (inverse real FFT of OTF(f, 0)
/// sampled at the scene spacing on a period of m samples) at the given wavelengths,
/// normalised to unit sum, and P is the smallest width with `|lsf[n]| ≤ tolerance` for
/// every |n| ≥ 2P (at most `max_pad`): a one-sample-wide feature at one edge then changes
/// the far edge by at most `tolerance` of its excess.
///
/// The period m starts at 1024 and doubles until that choice of P is certain, or until m
/// reaches `8·max_pad` (at least 4096), the only period used before. Sampling the OTF on a
/// period-m grid adds to every LSF sample its copies from `n ± m, n ± 2m, …`. Over the
/// middle half of the period, `[m/4, 3m/4]`, the computed LSF is nothing but such tail
/// samples, so its largest magnitude there, `e`, measures what the copies add (for a tail
/// that does not grow beyond m/4). A period is accepted when the samples that decide P lie
/// within m/4 and P is the same whether the threshold is `tolerance − 2e` or
/// `tolerance + 2e`: no sample is close enough to the tolerance for the copies, here or on
/// the longest period, to move it across. P is then the one the longest period gives,
/// from a tenth of the OTF evaluations when the pad is a few samples; a sample that sits
/// on the threshold sends the search on to the longest period.
///
/// Diffraction LSF tails fall only as 1/n², so the *summed* tail of a wide bright region
/// converges slowly; that light is physically spread by the optics, and mirror padding
/// supplies it from the nearest scene content rather than from the opposite edge.
/// Components that are flat in frequency at high frequency (aerosol) are excluded: their
/// scattered fraction spreads evenly over the padded frame by design (docs/design.md §5).
pub fn pad_width(
    otf: &SystemOtf,
    spacing_rad: f64,
    along_x: bool,
    wavelengths_um: &[f64],
    tolerance: f64,
    max_pad: usize,
) -> usize {
    let first_period = MIN_LSF_LEN;
    pad_width_from(
        otf,
        spacing_rad,
        along_x,
        wavelengths_um,
        tolerance,
        max_pad,
        first_period,
    )
}

/// [`pad_width`] with the search starting at a period of `first_period` samples (at most
/// the longest; given the longest, the search is the direct computation on it).
fn pad_width_from(
    otf: &SystemOtf,
    spacing_rad: f64,
    along_x: bool,
    wavelengths_um: &[f64],
    tolerance: f64,
    max_pad: usize,
    first_period: usize,
) -> usize {
    let longest: usize = (8 * max_pad).next_power_of_two().max(1 << 12);
    let mut worst = 1usize;
    for &lambda in wavelengths_um {
        let mut m = first_period.min(longest);
        let far = loop {
            let Some(lsf) = line_spread(otf, spacing_rad, along_x, lambda, m) else {
                return max_pad;
            };
            let reach = |threshold: f64| reach(&lsf, threshold);
            let far = reach(tolerance);
            if m >= longest {
                break far;
            }
            let e = lsf[m / 4..=3 * m / 4]
                .iter()
                .fold(0.0f64, |a, v| a.max(v.abs()));
            let wide = reach(tolerance - 2.0 * e);
            if wide < m / 4 && wide == reach(tolerance + 2.0 * e) {
                break far;
            }
            m *= 2;
        };
        // Need 2P > far.
        worst = worst.max((far / 2 + 1).min(max_pad));
    }
    worst
}

/// The largest distance |n| (folded on the period: min(n, m − n)) at which `|lsf[n]|`
/// exceeds `threshold`; 0 if none does.
fn reach(lsf: &[f64], threshold: f64) -> usize {
    let m = lsf.len();
    (1..m)
        .filter(|n| lsf[*n].abs() > threshold)
        .map(|n| n.min(m - n))
        .max()
        .unwrap_or(0)
}

/// The LSF along one axis at `wavelength_um`, on a period of `m` samples of
/// `spacing_rad`, normalised to unit sum: the inverse real FFT of the OTF (without the
/// aerosol, see [`pad_width`]) at `u / (m · spacing_rad)`, u = 0 … m/2. `None` if the
/// transform fails (it cannot for these lengths).
fn line_spread(
    otf: &SystemOtf,
    spacing_rad: f64,
    along_x: bool,
    wavelength_um: f64,
    m: usize,
) -> Option<Vec<f64>> {
    let r0 = otf.fried_r0_m(wavelength_um);
    let mut spec: Vec<Complex64> = (0..m / 2 + 1)
        .into_par_iter()
        .map(|u| {
            let f = u as f64 / (m as f64 * spacing_rad);
            let (fx, fy) = if along_x { (f, 0.0) } else { (0.0, f) };
            let v = otf.product_where(fx, fy, wavelength_um, r0, |c| c != Component::Aerosol);
            Complex64::new(v, 0.0)
        })
        .collect();
    spec[m / 2].im = 0.0;
    let mut lsf = vec![0.0; m];
    let fft = realfft::RealFftPlanner::<f64>::new().plan_fft_inverse(m);
    fft.process(&mut spec, &mut lsf).ok()?;
    let norm = lsf.iter().sum::<f64>().abs().max(f64::MIN_POSITIVE);
    lsf.iter_mut().for_each(|v| *v /= norm);
    Some(lsf)
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

    /// The pad found on a period grown from 1024 samples is the one of the longest period,
    /// for every preset and for a defocused, a turbulent and a diffraction-only sensor, at
    /// the scene spacings of k = 1, 3 and 8 scene samples per pixel, two tolerances and
    /// both axes; and the cases cover pads from a few samples to the cap.
    #[test]
    fn pad_width_equals_the_longest_period_result() {
        let mut pads = std::collections::BTreeSet::new();
        let sensors: Vec<(&str, Vec<String>)> = vec![
            ("multimir", vec![]),
            ("emerald", vec![]),
            ("qwip", vec![]),
            ("ccd", vec![]),
            ("threeband", vec![]),
            ("multimir", vec!["defocus.w020_waves=2.0".into()]),
            (
                "emerald",
                vec![
                    "turbulence.path=\"horizontal\"".into(),
                    "turbulence.cn2=1e-13".into(),
                    "turbulence.range_m=3000".into(),
                ],
            ),
        ];
        for (name, overrides) in &sensors {
            let config = crate::sensor::presets::load(name, &[], overrides).unwrap();
            let sensor = crate::sensor::Sensor::build(&config).unwrap();
            let otf = sensor.otf();
            let (lo, hi) = sensor.response().support_um();
            for k in [1.0, 3.0, 8.0] {
                let spacing = config.ifov_rad() / k;
                for tolerance in [1e-4, 1e-6] {
                    for along_x in [false, true] {
                        for max_pad in [64, 4096] {
                            let got =
                                pad_width(otf, spacing, along_x, &[lo, hi], tolerance, max_pad);
                            // Straight to the longest period: the computation before the
                            // period grew from 1024.
                            let want = pad_width_from(
                                otf,
                                spacing,
                                along_x,
                                &[lo, hi],
                                tolerance,
                                max_pad,
                                usize::MAX,
                            );
                            assert_eq!(got, want, "{name} {overrides:?} k {k} tol {tolerance}");
                            pads.insert(got);
                        }
                    }
                }
            }
        }
        assert!(pads.len() > 5, "{pads:?}");
        assert!(pads.contains(&64), "{pads:?}");
    }
}
