//! Colour filter arrays: mosaicking, bilinear and Malvar–He–Cutler demosaicking, and
//! false-colour composites, checked against scenes whose true colour planes are known.

use eoir::cfa::{
    demosaic_bilinear, demosaic_malvar, false_colour, false_colour_common, mosaic, CfaPattern,
    BLUE, GREEN, RED,
};
use ndarray::{Array2, Array3};

type Demosaic = fn(ndarray::ArrayView2<f64>, CfaPattern) -> Array3<f64>;
const ALGORITHMS: [(&str, Demosaic); 2] =
    [("bilinear", demosaic_bilinear), ("malvar", demosaic_malvar)];

fn through_cfa(planes: &[Array2<f64>; 3], pattern: CfaPattern, f: Demosaic) -> Array3<f64> {
    let raw = mosaic([&planes[0], &planes[1], &planes[2]], pattern).unwrap();
    f(raw.view(), pattern)
}

#[test]
fn mosaic_takes_each_pixel_from_the_colour_the_pattern_names() {
    let (rows, cols) = (6, 7);
    let planes: Vec<Array2<f64>> = (0..3)
        .map(|k| Array2::from_elem((rows, cols), [10.0, 20.0, 30.0][k]))
        .collect();
    for p in CfaPattern::ALL {
        // The truth is the pattern's own name, read row by row.
        let letters: Vec<char> = p.name().chars().collect();
        let raw = mosaic([&planes[0], &planes[1], &planes[2]], p).unwrap();
        for r in 0..rows {
            for c in 0..cols {
                let expect = match letters[(r % 2) * 2 + c % 2] {
                    'R' => 10.0,
                    'G' => 20.0,
                    'B' => 30.0,
                    other => panic!("{other}"),
                };
                assert_eq!(raw[[r, c]], expect, "{p} ({r},{c})");
            }
        }
        assert_eq!(p.name().parse::<CfaPattern>().unwrap(), p);
        assert_eq!(p.name().to_lowercase().parse::<CfaPattern>().unwrap(), p);
    }
    assert!("RGBG".parse::<CfaPattern>().is_err());
    let small = Array2::<f64>::zeros((3, 3));
    assert!(mosaic([&planes[0], &small, &planes[2]], CfaPattern::Rggb).is_err());
}

#[test]
fn constant_per_channel_image_is_reconstructed_exactly() {
    let (rows, cols) = (20, 27);
    let values = [3.0, 7.0, 11.5];
    let planes = values.map(|v| Array2::from_elem((rows, cols), v));
    for p in CfaPattern::ALL {
        for (name, f) in ALGORITHMS {
            let out = through_cfa(&planes, p, f);
            assert_eq!(out.dim(), (3, rows, cols));
            for k in 0..3 {
                for r in 0..rows {
                    for c in 0..cols {
                        let err = (out[[k, r, c]] - values[k]).abs();
                        let interior = r >= 2 && c >= 2 && r + 2 < rows && c + 2 < cols;
                        // Exact away from the borders; the parity-preserving mirror makes it
                        // exact at the borders too.
                        if interior {
                            assert!(err < 1e-12, "{name} {p} ch{k} ({r},{c}): {err}");
                        }
                        assert!(err < 1e-12, "{name} {p} border ch{k} ({r},{c}): {err}");
                    }
                }
            }
        }
    }
}

/// A grey scene with structure: smooth variation, a sinusoid and a sharp-edged disc.
fn grey_scene(rows: usize, cols: usize) -> Array2<f64> {
    Array2::from_shape_fn((rows, cols), |(r, c)| {
        let (y, x) = (r as f64, c as f64);
        let disc = if (x - 70.0).powi(2) + (y - 50.0).powi(2) < 400.0 {
            300.0
        } else {
            0.0
        };
        500.0
            + 200.0
                * (2.0 * std::f64::consts::PI * x / 37.0).sin()
                * (2.0 * std::f64::consts::PI * y / 23.0).cos()
            + 2.0 * x
            + disc
    })
}

#[test]
fn grey_scene_demosaics_to_grey() {
    let (rows, cols) = (128, 144);
    let g = grey_scene(rows, cols);
    let truth_mean = g.mean().unwrap();
    let planes = [g.clone(), g.clone(), g.clone()];
    for p in CfaPattern::ALL {
        for (name, f) in ALGORITHMS {
            let out = through_cfa(&planes, p, f);
            let means: Vec<f64> = (0..3)
                .map(|k| out.index_axis(ndarray::Axis(0), k).mean().unwrap())
                .collect();
            for (k, m) in means.iter().enumerate() {
                assert!(
                    (m / truth_mean - 1.0).abs() < 0.01,
                    "{name} {p} channel {k}: {m} vs {truth_mean}"
                );
                for other in &means {
                    assert!((m / other - 1.0).abs() < 0.01, "{name} {p}: {means:?}");
                }
            }
        }
    }
}

/// Hue in degrees of an 8-bit RGB triple (HSV definition).
fn hue_deg(rgb: [f64; 3]) -> f64 {
    let [r, g, b] = rgb;
    let max = r.max(g).max(b);
    let min = r.min(g).min(b);
    let d = max - min;
    assert!(d > 30.0, "unsaturated colour {rgb:?}");
    let h = if max == r {
        60.0 * ((g - b) / d)
    } else if max == g {
        60.0 * ((b - r) / d + 2.0)
    } else {
        60.0 * ((r - g) / d + 4.0)
    };
    h.rem_euclid(360.0)
}

#[test]
fn colour_bars_keep_their_hue_order() {
    // Red, yellow, green, cyan, blue, magenta bars: hues 0, 60, ..., 300 degrees.
    let bars: [[f64; 3]; 6] = [
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 1.0, 1.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
    ];
    let (rows, width) = (24, 16);
    let cols = width * bars.len();
    let planes: [Array2<f64>; 3] = [RED, GREEN, BLUE]
        .map(|k| Array2::from_shape_fn((rows, cols), |(_, c)| 100.0 + 900.0 * bars[c / width][k]));
    let bg = [0.0, 0.0, 0.0];
    for p in CfaPattern::ALL {
        for (name, f) in ALGORITHMS {
            let out = through_cfa(&planes, p, f);
            let views = [0, 1, 2].map(|k| out.index_axis(ndarray::Axis(0), k));
            let img = false_colour(views, 1.0).unwrap();
            assert_eq!(img.dim(), (rows, cols, 3));
            let mut prev = f64::NEG_INFINITY;
            for (i, expect) in [0.0, 60.0, 120.0, 180.0, 240.0, 300.0].iter().enumerate() {
                // Mean colour of the bar's middle, away from its edges.
                let mut sum = bg;
                let mut n = 0.0;
                for r in 4..rows - 4 {
                    for c in i * width + 5..(i + 1) * width - 5 {
                        for k in 0..3 {
                            sum[k] += img[[r, c, k]] as f64;
                        }
                        n += 1.0;
                    }
                }
                let h = hue_deg(sum.map(|s| s / n));
                let dh = ((h - expect + 180.0).rem_euclid(360.0) - 180.0).abs();
                // Within 20°: the stretch percentiles include the demosaicker's overshoot at the
                // bars' edges, which lifts the "off" channels slightly.
                assert!(dh < 20.0, "{name} {p} bar {i}: hue {h} vs {expect}");
                let unwrapped = if i == 0 && h > 180.0 { h - 360.0 } else { h };
                assert!(unwrapped > prev, "{name} {p}: hue order broken at bar {i}");
                prev = unwrapped;
            }
        }
    }
}

/// Mean squared error over the interior (3-pixel border excluded) of all three channels.
fn interior_mse(a: &Array3<f64>, planes: &[Array2<f64>; 3]) -> f64 {
    let (_, rows, cols) = a.dim();
    let mut s = 0.0;
    let mut n = 0.0;
    for k in 0..3 {
        for r in 3..rows - 3 {
            for c in 3..cols - 3 {
                s += (a[[k, r, c]] - planes[k][[r, c]]).powi(2);
                n += 1.0;
            }
        }
    }
    s / n
}

#[test]
fn malvar_beats_bilinear_on_a_smooth_colour_image_with_edges() {
    // Channels share the luminance structure (a soft slanted edge, a disc and a fine
    // sinusoid) with different gains plus a slow chroma variation: the inter-channel
    // correlation of natural images that Malvar et al.'s gradient correction exploits.
    let (rows, cols) = (96, 112);
    let lum = Array2::from_shape_fn((rows, cols), |(r, c)| {
        let (y, x) = (r as f64, c as f64);
        let edge = (((x - 40.0 - 0.3 * y) / 1.2).tanh() + 1.0) * 0.5;
        let d = ((x - 80.0).powi(2) + (y - 60.0).powi(2)).sqrt();
        let disc = 0.5 * (1.0 - ((d - 15.0) / 0.8).tanh());
        0.3 + 0.4 * edge
            + 0.2 * disc
            + 0.08 * (2.0 * std::f64::consts::PI * (x + 0.5 * y) / 9.0).sin()
    });
    let gains = [1.0, 0.8, 0.55];
    let planes: [Array2<f64>; 3] = [0, 1, 2].map(|k| {
        Array2::from_shape_fn((rows, cols), |(r, c)| {
            let chroma = 0.05
                * (2.0 * std::f64::consts::PI * (c as f64 + k as f64 * 20.0) / 80.0).sin()
                + 0.03 * (r as f64 / rows as f64);
            1000.0 * (gains[k] * lum[[r, c]] + chroma)
        })
    });
    for p in CfaPattern::ALL {
        let bil = interior_mse(&through_cfa(&planes, p, demosaic_bilinear), &planes);
        let mal = interior_mse(&through_cfa(&planes, p, demosaic_malvar), &planes);
        assert!(mal < 0.7 * bil, "{p}: Malvar MSE {mal} vs bilinear {bil}");
    }
}

#[test]
fn demosaic_keeps_the_measured_samples() {
    let g = grey_scene(17, 23);
    let planes = [g.clone(), &g * 0.5, &g * 2.0];
    for p in CfaPattern::ALL {
        let raw = mosaic([&planes[0], &planes[1], &planes[2]], p).unwrap();
        for (_, f) in ALGORITHMS {
            let out = f(raw.view(), p);
            for r in 0..17 {
                for c in 0..23 {
                    assert_eq!(out[[p.colour_at(r, c), r, c]], raw[[r, c]]);
                }
            }
        }
    }
    // Degenerate sizes do not panic.
    for (rows, cols) in [(0, 0), (1, 1), (1, 5), (2, 2), (3, 1)] {
        let raw = Array2::from_elem((rows, cols), 4.0);
        for (_, f) in ALGORITHMS {
            assert_eq!(f(raw.view(), CfaPattern::Bggr).dim(), (3, rows, cols));
        }
    }
}

#[test]
fn false_colour_stretches_between_percentiles() {
    // 101 values 0..=100: the 10th and 90th percentiles are exactly 10 and 90.
    let ramp = Array2::from_shape_fn((1, 101), |(_, c)| c as f64);
    let twice = &ramp * 2.0;
    let thrice = &ramp * 3.0 + 7.0;
    let img = false_colour([ramp.view(), twice.view(), thrice.view()], 10.0).unwrap();
    for k in 0..3 {
        assert_eq!(img[[0, 5, k]], 0);
        assert_eq!(img[[0, 10, k]], 0);
        assert_eq!(img[[0, 50, k]], 128); // (50 − 10) / 80 · 255 = 127.5
        assert_eq!(img[[0, 90, k]], 255);
        assert_eq!(img[[0, 100, k]], 255);
        for c in 1..101 {
            assert!(img[[0, c, k]] >= img[[0, c - 1, k]]);
        }
    }
    // The common stretch keeps the channels' relative levels: equal inputs stay grey,
    // a brighter channel stays brighter.
    let img = false_colour_common([ramp.view(), ramp.view(), ramp.view()], 0.0).unwrap();
    for c in 0..101 {
        assert_eq!(img[[0, c, 0]], img[[0, c, 1]]);
        assert_eq!(img[[0, c, 1]], img[[0, c, 2]]);
    }
    let img = false_colour_common([ramp.view(), twice.view(), thrice.view()], 0.0).unwrap();
    assert!(img[[0, 50, 0]] < img[[0, 50, 1]] && img[[0, 50, 1]] < img[[0, 50, 2]]);
    // NaN pixels are black and ignored by the percentiles; bad arguments are errors.
    let mut holes = ramp.clone();
    holes[[0, 3]] = f64::NAN;
    let img = false_colour([holes.view(), ramp.view(), ramp.view()], 0.0).unwrap();
    assert_eq!(img[[0, 3, 0]], 0);
    assert_eq!(img[[0, 100, 0]], 255);
    assert!(false_colour([ramp.view(), ramp.view(), ramp.view()], 50.0).is_err());
    assert!(false_colour([ramp.view(), ramp.view(), ramp.view()], f64::NAN).is_err());
    let other = Array2::<f64>::zeros((2, 2));
    assert!(false_colour([ramp.view(), other.view(), ramp.view()], 1.0).is_err());
}

#[test]
fn composite_writes_as_png() {
    let g = grey_scene(32, 40);
    let planes = [
        g.clone(),
        g.t().to_owned().slice_move(ndarray::s![..32, ..32]),
        g.clone(),
    ];
    // Different shapes are rejected; same shapes write.
    assert!(false_colour([planes[0].view(), planes[1].view(), planes[2].view()], 1.0).is_err());
    let img = false_colour([g.view(), (&g * 0.3).view(), (&g * 3.0).view()], 1.0).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("composite.png");
    eoir::io::raster::write_png_rgb8(&path, img.view()).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
}
