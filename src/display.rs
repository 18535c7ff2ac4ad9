//! Pictures a person can look at: a percentile stretch of raw DN to 8-bit grey, a perceptual
//! colour map (inferno) with a labelled colour bar for temperature images, and in-memory PNG
//! encoding so the same bytes go to a file and into `report.html`.
//!
//! The display products never replace the data: raw DN stay in `dn.tiff`, temperatures in
//! `temperature.tiff`; the pictures are for eyes only.

use ndarray::{Array3, ArrayView2};
use plotters::prelude::*;

use crate::error::{Error, Result};

/// Lower percentile of the display stretch of `dn.png`, %.
pub const DN_STRETCH_LO_PERCENT: f64 = 0.5;
/// Upper percentile of the display stretch of `dn.png`, %.
pub const DN_STRETCH_HI_PERCENT: f64 = 99.5;
/// Lower/upper percentiles of the colour scale of `temperature.png`, %.
pub const TEMPERATURE_STRETCH_PERCENT: (f64, f64) = (1.0, 99.0);
/// Colour of pixels without a value (NaN: outside the calibrated range) in a colour-mapped
/// picture: a cyan that does not occur in inferno.
pub const NO_VALUE_RGB: [u8; 3] = [0, 200, 220];

/// A linear display stretch: `lo` maps to 0, `hi` to 255, values outside are clipped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stretch {
    /// Value shown black (0), in the data's units.
    pub lo: f64,
    /// Value shown white (255), in the data's units.
    pub hi: f64,
}

impl Stretch {
    /// The stretch between the `lo_percent` and `hi_percent` percentiles of the finite
    /// values ([`percentile_sorted`]: linear interpolation between ranks). `None` if there is no finite value.
    /// A constant image gets `hi = lo + 1` so that it shows as black rather than dividing
    /// by zero.
    pub fn from_percentiles(
        values: impl Iterator<Item = f64>,
        lo_percent: f64,
        hi_percent: f64,
    ) -> Option<Stretch> {
        let mut v: Vec<f64> = values.filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        let lo = percentile_sorted(&v, lo_percent);
        let mut hi = percentile_sorted(&v, hi_percent);
        if hi <= lo {
            hi = lo + 1.0;
        }
        Some(Stretch { lo, hi })
    }

    /// Position of `v` in the stretch, clipped to [0, 1]; NaN stays NaN.
    pub fn unit(&self, v: f64) -> f64 {
        ((v - self.lo) / (self.hi - self.lo)).clamp(0.0, 1.0)
    }

    /// `v` as an 8-bit grey level: `round(255 · clip((v − lo)/(hi − lo), 0, 1))`.
    pub fn to_u8(&self, v: f64) -> u8 {
        (255.0 * self.unit(v)).round() as u8
    }
}

/// The `p`-th percentile (0–100) of sorted values, by linear interpolation between the
/// nearest ranks (NumPy's default "linear" method): index `p/100 · (n − 1)`.
pub fn percentile_sorted(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let x = (p / 100.0).clamp(0.0, 1.0) * (sorted.len() - 1) as f64;
    let i = x.floor() as usize;
    let j = (i + 1).min(sorted.len() - 1);
    let w = x - i as f64;
    sorted[i] * (1.0 - w) + sorted[j] * w
}

/// Raw DN as an 8-bit display image: a linear stretch between the
/// [`DN_STRETCH_LO_PERCENT`] and [`DN_STRETCH_HI_PERCENT`] percentiles of the frame (so one
/// percent of the pixels, dead and hot ones included, may clip), returned with the stretch
/// used. The DN themselves are unchanged in `dn.tiff`.
pub fn dn_display(dn: ArrayView2<u16>) -> (ndarray::Array2<u8>, Stretch) {
    let stretch = Stretch::from_percentiles(
        dn.iter().map(|v| *v as f64),
        DN_STRETCH_LO_PERCENT,
        DN_STRETCH_HI_PERCENT,
    )
    .unwrap_or(Stretch { lo: 0.0, hi: 1.0 });
    (dn.mapv(|v| stretch.to_u8(v as f64)), stretch)
}

/// Knots of matplotlib's `inferno` colour map (van der Walt & Smith, 2015, CC0): every
/// 16th entry of its published 256-entry table (indices 0, 16, …, 240, 255) plus entry 200
/// (the blue minimum), as RGB in [0, 1]. Linear interpolation between these knots stays
/// within 0.02 of the full table.
const INFERNO_KNOTS: [(f64, [f64; 3]); 18] = [
    (0.0, [0.001462, 0.000466, 0.013866]),
    (16.0, [0.042253, 0.028139, 0.141141]),
    (32.0, [0.129285, 0.047293, 0.290788]),
    (48.0, [0.238273, 0.036621, 0.396353]),
    (64.0, [0.341500, 0.062325, 0.429425]),
    (80.0, [0.441207, 0.099338, 0.431594]),
    (96.0, [0.540920, 0.134729, 0.415123]),
    (112.0, [0.640135, 0.171438, 0.381065]),
    (128.0, [0.735683, 0.215906, 0.330245]),
    (144.0, [0.822386, 0.275197, 0.266085]),
    (160.0, [0.894305, 0.353399, 0.193584]),
    (176.0, [0.946965, 0.449191, 0.115272]),
    (192.0, [0.978422, 0.557937, 0.034931]),
    (200.0, [0.985952, 0.615750, 0.025592]),
    (208.0, [0.987874, 0.675267, 0.065257]),
    (224.0, [0.974638, 0.797692, 0.206332]),
    (240.0, [0.947594, 0.917399, 0.410665]),
    (255.0, [0.988362, 0.998364, 0.644924]),
];

/// The inferno colour map at `t` ∈ [0, 1] (clipped) as 8-bit RGB; NaN gives
/// [`NO_VALUE_RGB`]. Perceptually uniform and monotonic in lightness, readable in grey.
pub fn inferno(t: f64) -> [u8; 3] {
    if t.is_nan() {
        return NO_VALUE_RGB;
    }
    let x = t.clamp(0.0, 1.0) * 255.0;
    let k = INFERNO_KNOTS
        .windows(2)
        .position(|w| x <= w[1].0)
        .unwrap_or(INFERNO_KNOTS.len() - 2);
    let (x0, c0) = INFERNO_KNOTS[k];
    let (x1, c1) = INFERNO_KNOTS[k + 1];
    let w = (x - x0) / (x1 - x0);
    let mut rgb = [0u8; 3];
    for (i, out) in rgb.iter_mut().enumerate() {
        *out = (255.0 * (c0[i] * (1.0 - w) + c1[i] * w)).round() as u8;
    }
    rgb
}

/// Minimum height, pixels, of a colour-mapped picture: smaller images are enlarged by an
/// integer factor (pixel replication) so the colour bar's labels fit.
const MIN_PICTURE_HEIGHT_PX: usize = 320;
/// Width of the colour bar, pixels.
const BAR_WIDTH_PX: usize = 24;
/// Width right of the image holding the bar and its labels, pixels.
const LEGEND_WIDTH_PX: usize = 130;
/// Margin around the picture, pixels.
const MARGIN_PX: usize = 12;

/// A colour-mapped picture of `image` (e.g. apparent temperature) with a vertical colour bar
/// to its right labelled in `unit`: inferno between the
/// [`TEMPERATURE_STRETCH_PERCENT`] percentiles of the finite values, NaN pixels in
/// [`NO_VALUE_RGB`] (noted under the bar). Returns `[row, col, 3]` bytes and the stretch.
///
/// Errors: no finite value to scale by.
pub fn colour_picture(image: ArrayView2<f32>, unit: &str) -> Result<(Array3<u8>, Stretch)> {
    let (lo_p, hi_p) = TEMPERATURE_STRETCH_PERCENT;
    let stretch = Stretch::from_percentiles(image.iter().map(|v| *v as f64), lo_p, hi_p)
        .ok_or_else(|| {
            Error::param(
                "colour picture",
                "no finite value",
                "an image with at least one finite pixel",
            )
        })?;
    let (rows, cols) = image.dim();
    let zoom = MIN_PICTURE_HEIGHT_PX.div_ceil(rows.max(1)).max(1);
    let (ih, iw) = (rows * zoom, cols * zoom);
    let width = MARGIN_PX + iw + MARGIN_PX + LEGEND_WIDTH_PX;
    let height = MARGIN_PX + ih.max(MIN_PICTURE_HEIGHT_PX) + MARGIN_PX + 20;
    let mut buf = vec![255u8; width * height * 3];
    let mut put = |x: usize, y: usize, c: [u8; 3]| {
        let o = (y * width + x) * 3;
        buf[o..o + 3].copy_from_slice(&c);
    };
    for r in 0..ih {
        for c in 0..iw {
            let v = image[[r / zoom, c / zoom]] as f64;
            let colour = if v.is_finite() {
                inferno(stretch.unit(v))
            } else {
                NO_VALUE_RGB
            };
            put(MARGIN_PX + c, MARGIN_PX + r, colour);
        }
    }
    let bar_x = MARGIN_PX + iw + MARGIN_PX;
    let bar_h = ih.max(MIN_PICTURE_HEIGHT_PX);
    for y in 0..bar_h {
        let t = 1.0 - y as f64 / (bar_h - 1).max(1) as f64;
        for x in 0..BAR_WIDTH_PX {
            put(bar_x + x, MARGIN_PX + y, inferno(t));
        }
    }
    let nan = image.iter().filter(|v| !v.is_finite()).count();
    draw_bar_labels(
        &mut buf,
        (width, height),
        (bar_x, MARGIN_PX, bar_h),
        &stretch,
        unit,
        nan,
    )?;
    let picture = Array3::from_shape_vec((height, width, 3), buf)
        .map_err(|e| Error::param("colour picture", e.to_string(), "a consistent shape"))?;
    Ok((picture, stretch))
}

/// Ticks, their values and the unit beside the colour bar at `(x, top, height)`.
fn draw_bar_labels(
    buf: &mut [u8],
    size: (usize, usize),
    bar: (usize, usize, usize),
    stretch: &Stretch,
    unit: &str,
    nan: usize,
) -> Result<()> {
    crate::plot::ensure_font();
    let draw_err = |e: String| Error::param("colour bar", e, "a drawable picture");
    let root = BitMapBackend::with_buffer(buf, (size.0 as u32, size.1 as u32)).into_drawing_area();
    let (bx, top, h) = bar;
    let font = (crate::plot::FONT, 14).into_font().color(&BLACK);
    let ticks = 5;
    let span = stretch.hi - stretch.lo;
    let decimals = if span >= 20.0 {
        0
    } else if span >= 2.0 {
        1
    } else {
        2
    };
    for i in 0..ticks {
        let f = i as f64 / (ticks - 1) as f64;
        let y = (top + ((1.0 - f) * (h - 1) as f64).round() as usize) as i32;
        let x0 = (bx + BAR_WIDTH_PX) as i32;
        root.draw(&PathElement::new(vec![(x0, y), (x0 + 5, y)], BLACK))
            .map_err(|e| draw_err(e.to_string()))?;
        let value = stretch.lo + f * span;
        root.draw(&Text::new(
            format!("{value:.decimals$} {unit}"),
            (x0 + 8, y - 7),
            font.clone(),
        ))
        .map_err(|e| draw_err(e.to_string()))?;
    }
    if nan > 0 {
        let y = (top + h + 4) as i32;
        root.draw(&Rectangle::new(
            [(bx as i32, y), (bx as i32 + 12, y + 12)],
            RGBColor(NO_VALUE_RGB[0], NO_VALUE_RGB[1], NO_VALUE_RGB[2]).filled(),
        ))
        .map_err(|e| draw_err(e.to_string()))?;
        root.draw(&Text::new(
            format!("no value: {nan} px"),
            (bx as i32 + 16, y),
            font,
        ))
        .map_err(|e| draw_err(e.to_string()))?;
    }
    root.present().map_err(|e| draw_err(e.to_string()))?;
    Ok(())
}

pub use crate::io::raster::{encode_png, write_png_bytes};

/// Standard base64 (RFC 4648 §4, with `=` padding) of `bytes`: how pictures are inlined
/// as `data:` URIs (RFC 2397) in the self-contained HTML pages.
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(ALPHABET[((n >> (18 - 6 * i)) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc4648_vectors() {
        // RFC 4648 §10 test vectors.
        for (input, expected) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(input.as_bytes()), expected, "{input}");
        }
    }

    #[test]
    fn percentile_matches_linear_interpolation() {
        let v: Vec<f64> = (0..=100).map(|i| i as f64).collect();
        assert_eq!(percentile_sorted(&v, 0.0), 0.0);
        assert_eq!(percentile_sorted(&v, 100.0), 100.0);
        assert!((percentile_sorted(&v, 37.5) - 37.5).abs() < 1e-12);
        let w = [1.0, 3.0];
        assert!((percentile_sorted(&w, 25.0) - 1.5).abs() < 1e-12);
    }
}
