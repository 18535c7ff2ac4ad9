//! Colour filter arrays (Bayer mosaics): mosaicking, demosaicking and false-colour
//! composites.
//!
//! A Bayer sensor (Bayer 1976; FOI report §3.5, figure 3.3) covers each pixel with one
//! colour filter tiled in a 2 × 2 pattern with two greens on a diagonal, so half the pixels
//! are green and a quarter each red and blue. [`mosaic`] samples a three-channel electron
//! image through the pattern; [`demosaic_bilinear`] and [`demosaic_malvar`] fill in the two
//! missing colours at every pixel; [`false_colour`] turns three channels (RGB, or three
//! spectral bands such as the FOI three-band model of report §4.2) into an 8-bit image for
//! `crate::io::raster::write_png_rgb8`.
//!
//! Channel indices are [`RED`] = 0, [`GREEN`] = 1, [`BLUE`] = 2 throughout; demosaicked
//! images are `[3, rows, cols]` (band-major, as every cube in eoir).
//!
//! Boundaries are mirrored without repeating the edge sample (index −1 ↦ 1, −2 ↦ 2). That
//! reflection keeps the parity of the index, so the mirrored neighbour of a pixel always
//! carries the same colour as the pixel the pattern would have put there, and the
//! interpolators see a valid mosaic up to the border.

use std::str::FromStr;

use ndarray::{Array2, Array3, ArrayView2};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// Index of the red channel.
pub const RED: usize = 0;
/// Index of the green channel.
pub const GREEN: usize = 1;
/// Index of the blue channel.
pub const BLUE: usize = 2;

/// Channel names by index, for messages and file names.
pub const CHANNEL_NAMES: [&str; 3] = ["red", "green", "blue"];

/// The 2 × 2 Bayer tile, named by its colours read row by row from the top-left pixel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum CfaPattern {
    /// R G / G B.
    #[serde(rename = "RGGB", alias = "rggb")]
    Rggb,
    /// B G / G R.
    #[serde(rename = "BGGR", alias = "bggr")]
    Bggr,
    /// G R / B G.
    #[serde(rename = "GRBG", alias = "grbg")]
    Grbg,
    /// G B / R G.
    #[serde(rename = "GBRG", alias = "gbrg")]
    Gbrg,
}

impl CfaPattern {
    /// Every pattern.
    pub const ALL: [CfaPattern; 4] = [
        CfaPattern::Rggb,
        CfaPattern::Bggr,
        CfaPattern::Grbg,
        CfaPattern::Gbrg,
    ];

    /// The pattern's name, e.g. `"RGGB"`.
    pub fn name(self) -> &'static str {
        match self {
            CfaPattern::Rggb => "RGGB",
            CfaPattern::Bggr => "BGGR",
            CfaPattern::Grbg => "GRBG",
            CfaPattern::Gbrg => "GBRG",
        }
    }

    /// Channel indices of the tile, row-major: (0,0), (0,1), (1,0), (1,1).
    fn tile(self) -> [usize; 4] {
        match self {
            CfaPattern::Rggb => [RED, GREEN, GREEN, BLUE],
            CfaPattern::Bggr => [BLUE, GREEN, GREEN, RED],
            CfaPattern::Grbg => [GREEN, RED, BLUE, GREEN],
            CfaPattern::Gbrg => [GREEN, BLUE, RED, GREEN],
        }
    }

    /// The channel ([`RED`], [`GREEN`] or [`BLUE`]) the filter over pixel (`row`, `col`)
    /// passes.
    pub fn colour_at(self, row: usize, col: usize) -> usize {
        self.tile()[(row % 2) * 2 + col % 2]
    }
}

impl FromStr for CfaPattern {
    type Err = Error;

    /// Parses `RGGB`, `BGGR`, `GRBG` or `GBRG` (any case).
    fn from_str(s: &str) -> Result<Self> {
        let t = s.trim();
        CfaPattern::ALL
            .into_iter()
            .find(|p| p.name().eq_ignore_ascii_case(t))
            .ok_or_else(|| Error::param("cfa.pattern", s, "one of RGGB, BGGR, GRBG, GBRG"))
    }
}

impl std::fmt::Display for CfaPattern {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Samples a three-channel image through the colour filter array: pixel (r, c) of the
/// result is taken from channel `pattern.colour_at(r, c)` of `rgb_electrons`
/// (`[red, green, blue]`, all the same shape).
///
/// Errors: the three planes differ in shape.
pub fn mosaic(rgb_electrons: [&Array2<f64>; 3], pattern: CfaPattern) -> Result<Array2<f64>> {
    let dim = rgb_electrons[0].dim();
    for (k, plane) in rgb_electrons.iter().enumerate().skip(1) {
        if plane.dim() != dim {
            return Err(Error::param(
                format!("{} plane shape", CHANNEL_NAMES[k]),
                format!("{:?}", plane.dim()),
                format!("the red plane's shape {dim:?}"),
            ));
        }
    }
    Ok(Array2::from_shape_fn(dim, |(r, c)| {
        rgb_electrons[pattern.colour_at(r, c)][[r, c]]
    }))
}

/// Mirrors index `i` into `0..n` without repeating the edge sample (period 2(n − 1)). The
/// reflection preserves the parity of `i`, hence the CFA colour.
fn reflect(i: isize, n: usize) -> usize {
    if n <= 1 {
        return 0;
    }
    let period = 2 * (n as isize - 1);
    let m = i.rem_euclid(period);
    if m >= n as isize {
        (period - m) as usize
    } else {
        m as usize
    }
}

/// A linear interpolation kernel: taps (Δrow, Δcol, weight).
type Kernel = &'static [(isize, isize, f64)];

/// The four kernels a linear Bayer demosaicker needs.
struct Kernels {
    /// Green at a red or blue pixel.
    green_at_rb: Kernel,
    /// At a green pixel: the colour of its left/right neighbours.
    row_colour_at_green: Kernel,
    /// At a green pixel: the colour of its upper/lower neighbours.
    col_colour_at_green: Kernel,
    /// Red at a blue pixel, or blue at a red pixel (diagonal neighbours).
    diagonal: Kernel,
}

/// Bilinear interpolation: each missing value is the mean of its nearest neighbours of that
/// colour (4 for green, 2 along the row or column or 4 on the diagonals for red/blue).
const BILINEAR: Kernels = Kernels {
    green_at_rb: &[(-1, 0, 0.25), (1, 0, 0.25), (0, -1, 0.25), (0, 1, 0.25)],
    row_colour_at_green: &[(0, -1, 0.5), (0, 1, 0.5)],
    col_colour_at_green: &[(-1, 0, 0.5), (1, 0, 0.5)],
    diagonal: &[(-1, -1, 0.25), (-1, 1, 0.25), (1, -1, 0.25), (1, 1, 0.25)],
};

/// Malvar, He & Cutler (2004), "High-quality linear interpolation for demosaicing of
/// Bayer-patterned color images", Proc. IEEE ICASSP 2004, vol. 3, pp. III-485–488,
/// figure 2: bilinear interpolation plus a gain times the Laplacian of the colour measured
/// at the pixel (gains α = 1/2 for green, β = 5/8 for red/blue at green, γ = 3/4 for
/// red/blue at blue/red), written as 5 × 5 kernels in units of 1/8.
const MALVAR: Kernels = Kernels {
    green_at_rb: &[
        (0, 0, 4.0 / 8.0),
        (-1, 0, 2.0 / 8.0),
        (1, 0, 2.0 / 8.0),
        (0, -1, 2.0 / 8.0),
        (0, 1, 2.0 / 8.0),
        (-2, 0, -1.0 / 8.0),
        (2, 0, -1.0 / 8.0),
        (0, -2, -1.0 / 8.0),
        (0, 2, -1.0 / 8.0),
    ],
    row_colour_at_green: &[
        (0, 0, 5.0 / 8.0),
        (0, -1, 4.0 / 8.0),
        (0, 1, 4.0 / 8.0),
        (0, -2, -1.0 / 8.0),
        (0, 2, -1.0 / 8.0),
        (-1, -1, -1.0 / 8.0),
        (-1, 1, -1.0 / 8.0),
        (1, -1, -1.0 / 8.0),
        (1, 1, -1.0 / 8.0),
        (-2, 0, 0.5 / 8.0),
        (2, 0, 0.5 / 8.0),
    ],
    col_colour_at_green: &[
        (0, 0, 5.0 / 8.0),
        (-1, 0, 4.0 / 8.0),
        (1, 0, 4.0 / 8.0),
        (-2, 0, -1.0 / 8.0),
        (2, 0, -1.0 / 8.0),
        (-1, -1, -1.0 / 8.0),
        (-1, 1, -1.0 / 8.0),
        (1, -1, -1.0 / 8.0),
        (1, 1, -1.0 / 8.0),
        (0, -2, 0.5 / 8.0),
        (0, 2, 0.5 / 8.0),
    ],
    diagonal: &[
        (0, 0, 6.0 / 8.0),
        (-1, -1, 2.0 / 8.0),
        (-1, 1, 2.0 / 8.0),
        (1, -1, 2.0 / 8.0),
        (1, 1, 2.0 / 8.0),
        (-2, 0, -1.5 / 8.0),
        (2, 0, -1.5 / 8.0),
        (0, -2, -1.5 / 8.0),
        (0, 2, -1.5 / 8.0),
    ],
};

/// Applies a linear demosaicker with the given kernels.
fn demosaic_linear(raw: ArrayView2<f64>, pattern: CfaPattern, k: &Kernels) -> Array3<f64> {
    let (rows, cols) = raw.dim();
    let mut out = Array3::<f64>::zeros((3, rows, cols));
    if rows == 0 || cols == 0 {
        return out;
    }
    // Mirror-padded copy (2 samples each side, the reach of the 5 × 5 kernels).
    const PAD: usize = 2;
    let padded = Array2::from_shape_fn((rows + 2 * PAD, cols + 2 * PAD), |(r, c)| {
        raw[[
            reflect(r as isize - PAD as isize, rows),
            reflect(c as isize - PAD as isize, cols),
        ]]
    });
    let apply = |kernel: Kernel, r: usize, c: usize| -> f64 {
        kernel
            .iter()
            .map(|&(dr, dc, w)| {
                let rr = (r + PAD) as isize + dr;
                let cc = (c + PAD) as isize + dc;
                w * padded[[rr as usize, cc as usize]]
            })
            .sum()
    };
    for r in 0..rows {
        for c in 0..cols {
            let own = pattern.colour_at(r, c);
            out[[own, r, c]] = raw[[r, c]];
            if own == GREEN {
                let row_colour = pattern.colour_at(r, c + 1);
                let col_colour = pattern.colour_at(r + 1, c);
                out[[row_colour, r, c]] = apply(k.row_colour_at_green, r, c);
                out[[col_colour, r, c]] = apply(k.col_colour_at_green, r, c);
            } else {
                out[[GREEN, r, c]] = apply(k.green_at_rb, r, c);
                out[[2 - own, r, c]] = apply(k.diagonal, r, c);
            }
        }
    }
    out
}

/// Bilinear demosaicking: every missing colour is the mean of the nearest pixels of that
/// colour (mirrored at the borders). Returns `[3, rows, cols]` = (red, green, blue).
pub fn demosaic_bilinear(raw: ArrayView2<f64>, pattern: CfaPattern) -> Array3<f64> {
    demosaic_linear(raw, pattern, &BILINEAR)
}

/// Gradient-corrected linear demosaicking of Malvar, He & Cutler (2004, Proc. IEEE ICASSP,
/// vol. 3, pp. III-485–488): bilinear interpolation corrected by the Laplacian of the
/// colour sampled at the pixel, with the paper's 5 × 5 filters (gains 1/2, 5/8, 3/4).
/// Borders are mirrored. Returns `[3, rows, cols]` = (red, green, blue).
///
/// Like any linear demosaicker it reproduces a constant-per-channel image exactly (each
/// kernel's weights sum to 1 and its Laplacian terms to 0); unlike bilinear it uses the
/// correlation between channels, so edges shared by all channels come out sharper and with
/// less colour fringing.
pub fn demosaic_malvar(raw: ArrayView2<f64>, pattern: CfaPattern) -> Array3<f64> {
    demosaic_linear(raw, pattern, &MALVAR)
}

/// The `p`-th percentile (0–100) of the finite values of `values`, interpolating linearly
/// between order statistics; `None` if there are no finite values.
fn percentile_pair(values: &mut [f64], lo_pct: f64, hi_pct: f64) -> Option<(f64, f64)> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let at = |p: f64| {
        let pos = p / 100.0 * (values.len() - 1) as f64;
        let i = pos.floor() as usize;
        let j = (i + 1).min(values.len() - 1);
        let t = pos - i as f64;
        values[i] * (1.0 - t) + values[j] * t
    };
    Some((at(lo_pct), at(hi_pct)))
}

/// Checks the clip percentage and the channel shapes.
fn check_composite(channels: &[ArrayView2<f64>; 3], percentile_clip: f64) -> Result<()> {
    if !(percentile_clip.is_finite() && (0.0..50.0).contains(&percentile_clip)) {
        return Err(Error::param(
            "percentile_clip",
            percentile_clip,
            "a percentage in [0, 50) clipped at each end of the histogram",
        ));
    }
    let dim = channels[0].dim();
    for (k, ch) in channels.iter().enumerate().skip(1) {
        if ch.dim() != dim {
            return Err(Error::param(
                format!("composite channel {k} shape"),
                format!("{:?}", ch.dim()),
                format!("the shape of channel 0, {dim:?}"),
            ));
        }
    }
    Ok(())
}

/// Maps `v` linearly from [lo, hi] to 0–255 (clamped); NaN and a flat range give 0.
fn to_u8(v: f64, lo: f64, hi: f64) -> u8 {
    if !(hi - lo).is_finite() || hi <= lo || !v.is_finite() {
        return 0;
    }
    let t = ((v - lo) / (hi - lo)).clamp(0.0, 1.0);
    (t * 255.0).round() as u8
}

/// Builds the `[rows, cols, 3]` image from per-channel (lo, hi) ranges.
fn composite(channels: &[ArrayView2<f64>; 3], ranges: [(f64, f64); 3]) -> Array3<u8> {
    let (rows, cols) = channels[0].dim();
    Array3::from_shape_fn((rows, cols, 3), |(r, c, k)| {
        to_u8(channels[k][[r, c]], ranges[k].0, ranges[k].1)
    })
}

/// A false-colour composite of three channels given as (red, green, blue) display
/// channels, `[rows, cols, 3]` 8-bit, ready for `crate::io::raster::write_png_rgb8`.
///
/// **Per-channel stretch**: each channel is mapped linearly from its own
/// `percentile_clip`-th to its (100 − `percentile_clip`)-th percentile (finite values only)
/// onto 0–255 and clamped. This suits composites of spectral bands with different signal
/// levels (e.g. FOI report §4.2: NIR → red, mid band → green, short band → blue), but it
/// white-balances the image: use [`false_colour_common`] to keep the channels' relative
/// levels. A channel with no spread (or no finite value) comes out 0; NaN pixels are 0.
///
/// Errors: `percentile_clip` outside [0, 50), channels of different shapes.
pub fn false_colour(channels: [ArrayView2<f64>; 3], percentile_clip: f64) -> Result<Array3<u8>> {
    check_composite(&channels, percentile_clip)?;
    let mut ranges = [(0.0, 0.0); 3];
    for (k, ch) in channels.iter().enumerate() {
        let mut v: Vec<f64> = ch.iter().copied().filter(|x| x.is_finite()).collect();
        if let Some(r) = percentile_pair(&mut v, percentile_clip, 100.0 - percentile_clip) {
            ranges[k] = r;
        }
    }
    Ok(composite(&channels, ranges))
}

/// Like [`false_colour`] but with one **common stretch** for all three channels (the
/// percentiles of the pooled values), so equal signals in the three channels stay grey and
/// the channels keep their relative levels.
///
/// Errors: `percentile_clip` outside [0, 50), channels of different shapes.
pub fn false_colour_common(
    channels: [ArrayView2<f64>; 3],
    percentile_clip: f64,
) -> Result<Array3<u8>> {
    check_composite(&channels, percentile_clip)?;
    let mut v: Vec<f64> = channels
        .iter()
        .flat_map(|ch| ch.iter().copied())
        .filter(|x| x.is_finite())
        .collect();
    let r = percentile_pair(&mut v, percentile_clip, 100.0 - percentile_clip).unwrap_or((0.0, 0.0));
    Ok(composite(&channels, [r; 3]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reflection_keeps_parity_and_range() {
        for n in 1..7usize {
            for i in -20isize..20 {
                let m = reflect(i, n);
                assert!(m < n);
                if n > 1 {
                    assert_eq!((m as isize - i).rem_euclid(2), 0, "n={n} i={i}");
                }
            }
        }
        assert_eq!(reflect(-1, 5), 1);
        assert_eq!(reflect(5, 5), 3);
    }

    #[test]
    fn kernels_sum_to_one() {
        for k in [&BILINEAR, &MALVAR] {
            for kernel in [
                k.green_at_rb,
                k.row_colour_at_green,
                k.col_colour_at_green,
                k.diagonal,
            ] {
                let s: f64 = kernel.iter().map(|t| t.2).sum();
                assert!((s - 1.0).abs() < 1e-15);
            }
        }
    }
}
