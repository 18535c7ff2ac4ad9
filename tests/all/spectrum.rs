//! Tests of `eoir::spectrum`: constructors and their validation, evaluation against the
//! defining formulas at characteristic points, supports and breakpoints, CSV parsing, and
//! trapezoid weights against exact integrals of linear and quadratic functions.

use std::io::Write;

use eoir::spectrum::{trapezoid_weights, Spectrum};
use eoir::Error;

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * b.abs().max(1e-300)
}

/// Exact integral of a piecewise-linear curve: the trapezoid rule on a grid that contains
/// every kink is exact, so integrate over the breakpoints refined by 10 sub-steps.
fn piecewise_linear_integral(s: &Spectrum) -> f64 {
    let mut nodes = s.breakpoints_um();
    let (lo, hi) = s.support_um();
    nodes.push(lo);
    nodes.push(hi);
    nodes.sort_by(f64::total_cmp);
    nodes.dedup();
    let mut grid = Vec::new();
    for w in nodes.windows(2) {
        for k in 0..10 {
            grid.push(w[0] + (w[1] - w[0]) * k as f64 / 10.0);
        }
    }
    grid.push(*nodes.last().unwrap());
    let weights = trapezoid_weights(&grid).unwrap();
    grid.iter()
        .zip(&weights)
        .map(|(&x, &w)| w * s.eval(x))
        .sum()
}

#[test]
fn constant_is_flat_with_unbounded_support() {
    let s = Spectrum::constant(0.7);
    for w in [1e-3, 0.5, 4.0, 1e4] {
        assert_eq!(s.eval(w), 0.7);
    }
    assert_eq!(
        s.eval(0.0),
        0.0,
        "wavelengths <= 0 are outside every spectrum"
    );
    assert!(s.eval(f64::NAN).is_nan());
    assert_eq!(s.support_um(), (0.0, f64::INFINITY));
    assert!(s.breakpoints_um().is_empty());
}

#[test]
fn top_hat_edges_and_area() {
    let s = Spectrum::top_hat(3.0, 5.0, 0.2, 0.8).unwrap();
    // 50 % points at lo and hi, feet and shoulders at ± edge/2.
    assert!(close(s.eval(3.0), 0.4, 1e-12));
    assert!(close(s.eval(5.0), 0.4, 1e-12));
    assert_eq!(s.eval(2.9), 0.0);
    assert_eq!(s.eval(2.85), 0.0);
    assert!(close(s.eval(3.1), 0.8, 1e-12));
    assert!(close(s.eval(4.0), 0.8, 1e-12));
    assert!(close(s.eval(3.05), 0.6, 1e-12));
    assert_eq!(s.eval(5.1), 0.0);
    let (lo, hi) = s.support_um();
    assert!(close(lo, 2.9, 1e-12) && close(hi, 5.1, 1e-12));
    let bp = s.breakpoints_um();
    let expect = [2.9, 3.1, 4.9, 5.1];
    assert_eq!(bp.len(), 4);
    for (a, b) in bp.iter().zip(expect) {
        assert!(close(*a, b, 1e-12));
    }
    // Area = peak · (hi − lo) for any edge width.
    assert!(close(piecewise_linear_integral(&s), 0.8 * 2.0, 1e-12));

    let sharp = Spectrum::top_hat(8.0, 12.0, 0.0, 1.0).unwrap();
    assert_eq!(sharp.eval(8.0), 1.0);
    assert_eq!(sharp.eval(12.0), 1.0);
    assert_eq!(sharp.eval(7.999_999), 0.0);
    assert_eq!(sharp.eval(12.000_001), 0.0);
    assert_eq!(sharp.support_um(), (8.0, 12.0));
    assert_eq!(sharp.breakpoints_um(), vec![8.0, 12.0]);

    // Edge width equal to the band width: a triangle of height peak, area peak·(hi−lo).
    let tri = Spectrum::top_hat(4.0, 5.0, 1.0, 2.0).unwrap();
    assert!(close(tri.eval(4.5), 2.0, 1e-12));
    assert!(close(piecewise_linear_integral(&tri), 2.0, 1e-12));
}

#[test]
fn top_hat_rejects_invalid_arguments() {
    assert!(Spectrum::top_hat(5.0, 3.0, 0.0, 1.0).is_err(), "lo > hi");
    assert!(Spectrum::top_hat(3.0, 3.0, 0.0, 1.0).is_err(), "lo == hi");
    assert!(Spectrum::top_hat(3.0, 5.0, -0.1, 1.0).is_err(), "edge < 0");
    assert!(
        Spectrum::top_hat(3.0, 5.0, 2.5, 1.0).is_err(),
        "edge > hi - lo"
    );
    assert!(Spectrum::top_hat(3.0, 5.0, 0.0, -1.0).is_err(), "peak < 0");
    assert!(Spectrum::top_hat(3.0, 5.0, 0.0, f64::NAN).is_err());
    assert!(Spectrum::top_hat(3.0, 5.0, 0.0, f64::INFINITY).is_err());
    assert!(Spectrum::top_hat(f64::NAN, 5.0, 0.0, 1.0).is_err());
    assert!(
        Spectrum::top_hat(0.1, 5.0, 0.4, 1.0).is_err(),
        "ramp below 0 µm"
    );
    match Spectrum::top_hat(3.0, 5.0, 2.5, 1.0) {
        Err(Error::InvalidParameter { field, .. }) => assert_eq!(field, "edge_width_um"),
        other => panic!("expected InvalidParameter, got {other:?}"),
    }
}

#[test]
fn gaussian_half_maximum_support_and_area() {
    let (c, fwhm, peak) = (4.0, 0.5, 0.9);
    let s = Spectrum::gaussian(c, fwhm, peak).unwrap();
    assert!(close(s.eval(c), peak, 1e-15));
    assert!(close(s.eval(c - fwhm / 2.0), peak / 2.0, 1e-12));
    assert!(close(s.eval(c + fwhm / 2.0), peak / 2.0, 1e-12));
    let sigma = fwhm / (2.0 * (2.0 * 2f64.ln()).sqrt());
    let (lo, hi) = s.support_um();
    assert!(close(lo, c - 8.5 * sigma, 1e-12) && close(hi, c + 8.5 * sigma, 1e-12));
    assert_eq!(s.eval(hi + 1e-9), 0.0);
    assert_eq!(s.eval(lo - 1e-9), 0.0);
    assert!(s.eval(hi - 1e-9) > 0.0 && s.eval(hi - 1e-9) < 3e-16 * peak);
    assert!(s.breakpoints_um().is_empty());
    // Area by composite Simpson (2e5 intervals) against the closed form peak·σ·√(2π).
    let n = 200_000;
    let h = (hi - lo) / n as f64;
    let mut sum = s.eval(lo) + s.eval(hi);
    for i in 1..n {
        sum += if i % 2 == 1 { 4.0 } else { 2.0 } * s.eval(lo + h * i as f64);
    }
    let area = sum * h / 3.0;
    assert!(close(
        area,
        peak * sigma * (2.0 * std::f64::consts::PI).sqrt(),
        1e-12
    ));

    assert!(Spectrum::gaussian(4.0, 0.0, 1.0).is_err());
    assert!(Spectrum::gaussian(4.0, -0.1, 1.0).is_err());
    assert!(Spectrum::gaussian(-4.0, 0.1, 1.0).is_err());
    assert!(Spectrum::gaussian(4.0, 0.1, -1.0).is_err());
    assert!(Spectrum::gaussian(4.0, f64::NAN, 1.0).is_err());

    // A wide Gaussian near 0 µm is clipped at λ = 0.
    let wide = Spectrum::gaussian(0.5, 1.0, 1.0).unwrap();
    assert_eq!(wide.support_um().0, 0.0);
}

#[test]
fn photon_detector_is_linear_up_to_cutoff() {
    let s = Spectrum::photon_detector(0.8, 5.0).unwrap();
    assert!(close(s.eval(2.5), 0.4, 1e-15));
    assert!(close(s.eval(5.0), 0.8, 1e-15));
    assert_eq!(s.eval(5.000_001), 0.0);
    assert_eq!(s.eval(-1.0), 0.0);
    assert_eq!(s.support_um(), (0.0, 5.0));
    assert_eq!(s.breakpoints_um(), vec![5.0]);
    // ∫_0^λc η dλ = η_peak λc / 2.
    assert!(close(piecewise_linear_integral(&s), 2.0, 1e-12));
    assert!(Spectrum::photon_detector(0.0, 5.0).is_err());
    assert!(Spectrum::photon_detector(1.1, 5.0).is_err());
    assert!(Spectrum::photon_detector(f64::NAN, 5.0).is_err());
    assert!(Spectrum::photon_detector(0.5, 0.0).is_err());
    assert!(Spectrum::photon_detector(0.5, f64::INFINITY).is_err());
    assert!(Spectrum::photon_detector(1.0, 1.7).is_ok());
}

#[test]
fn table_interpolates_and_is_zero_outside() {
    let s = Spectrum::table(vec![1.0, 2.0, 4.0], vec![0.2, 0.6, 0.4]).unwrap();
    assert!(close(s.eval(1.0), 0.2, 1e-15));
    assert!(close(s.eval(1.5), 0.4, 1e-15));
    assert!(close(s.eval(3.0), 0.5, 1e-15));
    assert!(close(s.eval(4.0), 0.4, 1e-15));
    assert_eq!(s.eval(0.999), 0.0, "zero below the first node");
    assert_eq!(s.eval(4.001), 0.0, "zero above the last node");
    assert_eq!(s.support_um(), (1.0, 4.0));
    assert_eq!(s.breakpoints_um(), vec![1.0, 2.0, 4.0]);
    assert_eq!(
        s.resample(&[0.5, 1.5, 3.0, 5.0]),
        vec![0.0, s.eval(1.5), s.eval(3.0), 0.0]
    );
    // Trapezoid area of the nodes: 0.4·1 + 0.5·2.
    assert!(close(piecewise_linear_integral(&s), 1.4, 1e-12));
}

#[test]
fn table_rejects_invalid_data() {
    assert!(Spectrum::table(vec![1.0], vec![1.0]).is_err(), "one point");
    assert!(
        Spectrum::table(vec![1.0, 2.0], vec![1.0]).is_err(),
        "lengths"
    );
    assert!(Spectrum::table(vec![2.0, 1.0], vec![1.0, 1.0]).is_err());
    assert!(Spectrum::table(vec![1.0, 1.0], vec![1.0, 1.0]).is_err());
    assert!(Spectrum::table(vec![0.0, 1.0], vec![1.0, 1.0]).is_err());
    assert!(Spectrum::table(vec![1.0, f64::NAN], vec![1.0, 1.0]).is_err());
    assert!(Spectrum::table(vec![1.0, 2.0], vec![1.0, -0.1]).is_err());
    assert!(Spectrum::table(vec![1.0, 2.0], vec![1.0, f64::INFINITY]).is_err());
    match Spectrum::table(vec![1.0, 3.0, 2.0], vec![1.0, 1.0, 1.0]) {
        Err(Error::InvalidParameter { field, .. }) => assert_eq!(field, "wavelength_um[2]"),
        other => panic!("expected InvalidParameter, got {other:?}"),
    }
}

#[test]
fn product_scaled_support_and_breakpoints() {
    let filter = Spectrum::top_hat(3.0, 5.0, 0.2, 0.9).unwrap();
    let qe = Spectrum::photon_detector(0.7, 4.6).unwrap();
    let optics = Spectrum::table(vec![2.0, 4.0, 6.0], vec![0.8, 0.9, 0.7]).unwrap();
    let p = filter.product(&qe).product(&optics);
    for w in [2.5, 2.95, 3.05, 3.7, 4.0, 4.6, 4.61, 4.95, 5.5] {
        let expect = filter.eval(w) * qe.eval(w) * optics.eval(w);
        assert!((p.eval(w) - expect).abs() <= 1e-15, "at {w} µm");
    }
    let (lo, hi) = p.support_um();
    assert!(close(lo, 2.9, 1e-12));
    assert!(close(hi, 4.6, 1e-12), "cut-off limits the product");
    let bp = p.breakpoints_um();
    for x in [2.0, 2.9, 3.1, 4.0, 4.6, 4.9, 5.1, 6.0] {
        assert!(bp.iter().any(|&b| close(b, x, 1e-12)), "missing {x}");
    }
    assert!(bp.windows(2).all(|w| w[0] < w[1]), "sorted, no duplicates");

    // Constants fold into a scale factor and keep the other factor's support.
    let c = Spectrum::constant(0.5);
    let pc = c.product(&filter);
    assert_eq!(pc.support_um(), filter.support_um());
    assert_eq!(pc, filter.scaled(0.5));
    assert!(close(pc.eval(4.0), 0.45, 1e-15));
    assert_eq!(c.product(&c), Spectrum::constant(0.25));

    let ps = p.scaled(2.0);
    for w in [3.05, 4.0, 4.5] {
        assert!(close(ps.eval(w), 2.0 * p.eval(w), 1e-15));
    }

    // Disjoint supports: zero everywhere, degenerate support.
    let a = Spectrum::top_hat(1.0, 2.0, 0.0, 1.0).unwrap();
    let b = Spectrum::top_hat(3.0, 4.0, 0.0, 1.0).unwrap();
    let ab = a.product(&b);
    let (lo, hi) = ab.support_um();
    assert_eq!(lo, hi);
    for w in [0.5, 1.5, 2.5, 3.5, 4.5] {
        assert_eq!(ab.eval(w), 0.0);
    }
}

fn write_temp(content: &str) -> tempfile::NamedTempFile {
    let mut f = tempfile::Builder::new().suffix(".csv").tempfile().unwrap();
    f.write_all(content.as_bytes()).unwrap();
    f.flush().unwrap();
    f
}

#[test]
fn csv_with_header_comments_and_mixed_separators() {
    let f = write_temp(
        "# filter transmission\n\
         \n\
         wavelength_um, transmission\n\
         3.0, 0.0\n\
         3.5;0.5   # comment after data\n\
         4.0\t0.9\n\
         \n\
         4.5   0.9\n\
         5.0 ,\t 0.1\n",
    );
    let s = Spectrum::from_csv(f.path()).unwrap();
    assert_eq!(s.support_um(), (3.0, 5.0));
    assert_eq!(s.breakpoints_um(), vec![3.0, 3.5, 4.0, 4.5, 5.0]);
    assert!(close(s.eval(3.25), 0.25, 1e-15));
    assert!(close(s.eval(4.25), 0.9, 1e-15));
    assert!(close(s.eval(4.75), 0.5, 1e-15));
    assert_eq!(s.eval(5.5), 0.0);

    // No header at all is fine too.
    let g = write_temp("1 2\n2 3\n");
    assert!(Spectrum::from_csv(g.path()).is_ok());
}

#[test]
fn csv_errors_name_file_and_line_but_never_the_text() {
    let f = write_temp("wl,value\n3.0,0.1\n3.5,abc\n4.0,0.2\n");
    let err = Spectrum::from_csv(f.path()).unwrap_err();
    let msg = err.to_string();
    let name = f.path().file_name().unwrap().to_string_lossy().to_string();
    assert!(matches!(err, Error::Format { .. }), "{msg}");
    assert!(msg.contains(&name), "{msg}");
    assert!(msg.contains("line 3, column 2"), "{msg}");
    assert!(!msg.contains("abc"), "{msg}");

    // A second non-numeric line is not a header.
    let f = write_temp("wl value\n# note\nunits um\n3 1\n4 1\n");
    let msg = Spectrum::from_csv(f.path()).unwrap_err().to_string();
    assert!(
        msg.contains("line 3, column 1") && !msg.contains("units"),
        "{msg}"
    );

    // Wrong column count.
    let f = write_temp("3 1\n4 1 7\n");
    let msg = Spectrum::from_csv(f.path()).unwrap_err().to_string();
    assert!(msg.contains("line 2") && msg.contains("found 3"), "{msg}");
    assert!(!msg.contains("4 1 7"), "{msg}");

    // Non-increasing wavelength, negative value, non-positive wavelength.
    let f = write_temp("3 1\n# c\n5 1\n4 1\n");
    let msg = Spectrum::from_csv(f.path()).unwrap_err().to_string();
    assert!(msg.contains("line 4") && msg.contains("line 3"), "{msg}");
    let f = write_temp("3 1\n4 -0.5\n");
    let msg = Spectrum::from_csv(f.path()).unwrap_err().to_string();
    assert!(msg.contains("line 2") && msg.contains("-0.5"), "{msg}");
    let f = write_temp("0 1\n4 1\n");
    let msg = Spectrum::from_csv(f.path()).unwrap_err().to_string();
    assert!(msg.contains("line 1"), "{msg}");

    // Too few rows, and a missing file.
    let f = write_temp("wavelength value\n# only one row\n3 1\n");
    assert!(matches!(
        Spectrum::from_csv(f.path()),
        Err(Error::Format { .. })
    ));
    let missing = std::path::Path::new("/nonexistent/dir/filter.csv");
    match Spectrum::from_csv(missing) {
        Err(e @ Error::Io { .. }) => assert!(e.to_string().contains("filter.csv")),
        other => panic!("expected Io error, got {other:?}"),
    }
}

#[test]
fn trapezoid_weights_linear_exact_quadratic_known_error() {
    // Non-uniform grid.
    let grid = [1.0, 1.1, 1.35, 1.4, 2.0, 2.05, 3.2, 4.0];
    let w = trapezoid_weights(&grid).unwrap();
    assert_eq!(w.len(), grid.len());
    assert!(
        close(w.iter().sum::<f64>(), 3.0, 1e-15),
        "weights sum to the width"
    );
    // Linear f = 3x + 2: exact integral over [1, 4] = 1.5(16 − 1) + 2·3 = 28.5.
    let lin: f64 = grid
        .iter()
        .zip(&w)
        .map(|(&x, &wi)| wi * (3.0 * x + 2.0))
        .sum();
    assert!(close(lin, 28.5, 1e-14));
    // Quadratic f = x²: trapezoid overestimates by Σ f'' h³ / 12 = Σ h³ / 6.
    let quad: f64 = grid.iter().zip(&w).map(|(&x, &wi)| wi * x * x).sum();
    let exact = (64.0 - 1.0) / 3.0;
    let predicted: f64 = grid.windows(2).map(|p| (p[1] - p[0]).powi(3) / 6.0).sum();
    assert!(close(quad - exact, predicted, 1e-10));

    assert!(
        trapezoid_weights(&[1.0]).is_err(),
        "a single point has no width"
    );
    assert!(trapezoid_weights(&[]).is_err());
    assert!(trapezoid_weights(&[1.0, 1.0]).is_err());
    assert!(trapezoid_weights(&[2.0, 1.0]).is_err());
    assert!(trapezoid_weights(&[1.0, f64::NAN]).is_err());
    assert!(trapezoid_weights(&[1.0, f64::INFINITY]).is_err());
}
