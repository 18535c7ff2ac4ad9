//! Slanted-edge MTF: against the closed form of a Gaussian-blurred edge, and against the
//! analytic system MTF of an engine-made edge.

use eoir::processing::edge_mtf::{slanted_edge_mtf, Roi};
use ndarray::Array2;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rand_xoshiro::Xoshiro256PlusPlus;

/// A point-sampled straight edge blurred by a Gaussian of σ pixels: pixel (r, c) holds
/// `lo + (hi − lo) Φ(d/σ)` with d the signed distance of the pixel centre from the line
/// through the image centre at `angle_deg` from the vertical (transposed when
/// `horizontal`), plus white Gaussian noise.
#[allow(clippy::too_many_arguments)]
fn gaussian_edge(
    rows: usize,
    cols: usize,
    angle_deg: f64,
    sigma_px: f64,
    horizontal: bool,
    falling: bool,
    noise: f64,
    seed: u64,
) -> Array2<f64> {
    let t = angle_deg.to_radians();
    let (nx, ny) = (t.cos(), -t.sin());
    let (xc, yc) = ((cols as f64 - 1.0) / 2.0 + 0.3, (rows as f64 - 1.0) / 2.0);
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let n = Normal::new(0.0, noise.max(1e-300)).unwrap();
    let (lo, hi) = (100.0, 1100.0);
    let img = Array2::from_shape_fn((rows, cols), |(r, c)| {
        let d = (c as f64 - xc) * nx + (r as f64 - yc) * ny;
        let d = if falling { -d } else { d };
        let phi = 0.5 * (1.0 + libm::erf(d / (sigma_px * std::f64::consts::SQRT_2)));
        lo + (hi - lo) * phi
    });
    let mut img = if horizontal { img.t().to_owned() } else { img };
    if noise > 0.0 {
        img.mapv_inplace(|v| v + n.sample(&mut rng));
    }
    img
}

/// MTF50 of a Gaussian of σ px: exp(−2π²σ²f²) = ½ ⇒ f = √(ln 2 / 2) / (π σ).
fn gaussian_mtf50(sigma_px: f64) -> f64 {
    (std::f64::consts::LN_2 / 2.0).sqrt() / (std::f64::consts::PI * sigma_px)
}

#[test]
fn gaussian_edge_mtf50_within_two_percent_at_any_angle_and_orientation() {
    let sigma = 1.0;
    let truth = gaussian_mtf50(sigma);
    // (angle from the nearer axis, near-horizontal, bright-to-dark, rows, cols before
    // transposition): the edge must cross the region from its top to its bottom line.
    for (angle, horizontal, falling, rows, cols) in [
        (5.0, false, false, 100, 80),
        (2.5, false, true, 100, 80),
        (-8.0, true, false, 100, 80),
        (20.0, false, false, 100, 80),
        (40.0, true, true, 60, 100),
    ] {
        let img = gaussian_edge(rows, cols, angle, sigma, horizontal, falling, 2.0, 7);
        let m = slanted_edge_mtf(img.view(), None).unwrap();
        let got = m.mtf50_cy_per_px.unwrap();
        let rel = (got - truth).abs() / truth;
        assert!(
            rel < 0.02,
            "angle {angle} horizontal {horizontal}: MTF50 {got:.5} vs {truth:.5} ({:.2} %)",
            rel * 100.0
        );
        assert_eq!(m.vertical, !horizontal, "angle {angle}");
        assert!(
            (m.angle_deg.abs() - angle.abs()).abs() < 0.2,
            "angle {} vs {angle}",
            m.angle_deg
        );
        // The whole curve follows the Gaussian up to Nyquist.
        for (f, v) in m.freq_cy_per_px.iter().zip(&m.mtf) {
            if *f <= 0.5 {
                let g = (-2.0 * std::f64::consts::PI.powi(2) * sigma * sigma * f * f).exp();
                assert!(
                    (v - g).abs() < 0.02,
                    "angle {angle}: f {f:.3}: {v:.4} vs {g:.4}"
                );
            }
        }
    }
}

#[test]
fn sharp_gaussian_edge_is_not_aliased() {
    // σ = 0.6 px: the MTF at Nyquist is 0.17, so the point-sampled edge is aliased; the
    // slanted edge's phase averaging still recovers the pre-sampling MTF.
    let sigma = 0.6;
    let img = gaussian_edge(120, 64, 6.0, sigma, false, false, 0.5, 3);
    let m = slanted_edge_mtf(img.view(), None).unwrap();
    let truth = gaussian_mtf50(sigma);
    let got = m.mtf50_cy_per_px.unwrap();
    assert!((got - truth).abs() / truth < 0.02, "{got} vs {truth}");
    let at = |f0: f64| {
        let i = m.freq_cy_per_px.iter().position(|f| *f >= f0).unwrap();
        m.mtf[i]
    };
    let g = |f: f64| (-2.0 * std::f64::consts::PI.powi(2) * sigma * sigma * f * f).exp();
    for f in [0.5, 0.75] {
        assert!((at(f) - g(f)).abs() < 0.03, "f {f}: {} vs {}", at(f), g(f));
    }
}

#[test]
fn roi_selects_the_edge_and_bad_regions_are_errors() {
    let img = gaussian_edge(100, 100, 5.0, 1.0, false, false, 1.0, 1);
    let m = slanted_edge_mtf(
        img.view(),
        Some(Roi {
            x: 20,
            y: 10,
            width: 60,
            height: 80,
        }),
    )
    .unwrap();
    assert!((m.mtf50_cy_per_px.unwrap() - gaussian_mtf50(1.0)).abs() / gaussian_mtf50(1.0) < 0.02);
    // Outside the image.
    let e = slanted_edge_mtf(
        img.view(),
        Some(Roi {
            x: 60,
            y: 0,
            width: 60,
            height: 50,
        }),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("--roi") && e.contains("inside"), "{e}");
    // A region with no edge in it (the flat left part).
    let e = slanted_edge_mtf(
        img.view(),
        Some(Roi {
            x: 0,
            y: 0,
            width: 30,
            height: 100,
        }),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("edge"), "{e}");
    // Pure noise.
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(9);
    let n = Normal::new(0.0, 1.0).unwrap();
    let noise = Array2::from_shape_fn((64, 64), |_| n.sample(&mut rng));
    assert!(slanted_edge_mtf(noise.view(), None).is_err());
    // An edge aligned with the columns cannot be super-resolved.
    let aligned = gaussian_edge(64, 64, 0.0, 1.0, false, false, 0.5, 4);
    let e = slanted_edge_mtf(aligned.view(), None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("angle"), "{e}");
}

/// The bootstrap σ of MTF50 and of the MTF at Nyquist agrees with the scatter of the
/// measurement over independent noise realisations of the same edge (Monte Carlo, 24
/// realisations: their own standard deviation scatters by ±15 %), within a factor 1.6.
#[test]
fn bootstrap_uncertainty_matches_the_scatter_over_noise_realisations() {
    let (sigma, noise) = (1.0, 40.0);
    let one = slanted_edge_mtf(
        gaussian_edge(64, 64, 5.0, sigma, false, false, noise, 1).view(),
        None,
    )
    .unwrap();
    let (mut m50, mut nyq) = (Vec::new(), Vec::new());
    for seed in 100..124 {
        let m = slanted_edge_mtf(
            gaussian_edge(64, 64, 5.0, sigma, false, false, noise, seed).view(),
            None,
        )
        .unwrap();
        m50.push(m.mtf50_cy_per_px.unwrap());
        nyq.push(m.mtf_nyquist.unwrap());
    }
    let sd = |v: &[f64]| {
        let n = v.len() as f64;
        let m = v.iter().sum::<f64>() / n;
        (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
    };
    let (mc50, mcn) = (sd(&m50), sd(&nyq));
    let (b50, bn) = (
        one.mtf50_sigma_cy_per_px.unwrap(),
        one.mtf_nyquist_sigma.unwrap(),
    );
    eprintln!(
        "MTF50 σ bootstrap {b50:.5} vs Monte Carlo {mc50:.5}; MTF(Nyquist) σ {bn:.5} vs {mcn:.5}"
    );
    assert!((b50 / mc50).ln().abs() < 1.6f64.ln(), "{b50} vs {mc50}");
    assert!((bn / mcn).ln().abs() < 1.6f64.ln(), "{bn} vs {mcn}");
    assert!(one.warnings.is_empty(), "{:?}", one.warnings);
}

/// Phase sampling: at tan θ = 1/2 (26.57°) the lines alternate between two sub-pixel
/// phases and two quarter-pixel phases stay empty: a warning. At 5° every phase is filled.
#[test]
fn poor_phase_sampling_is_warned_and_good_sampling_is_not() {
    let bad = slanted_edge_mtf(
        gaussian_edge(
            64,
            64,
            0.5f64.atan().to_degrees(),
            1.0,
            false,
            false,
            2.0,
            3,
        )
        .view(),
        None,
    );
    match bad {
        Ok(m) => {
            assert!(
                m.warnings.iter().any(|w| w.contains("phase")),
                "{:?} {:?}",
                m.phase_fill,
                m.warnings
            );
            assert_eq!(m.phase_fill.iter().filter(|n| **n == 0).count(), 2);
        }
        // Too few filled bins is refused outright, which is as good as a warning.
        Err(e) => assert!(e.to_string().contains("bins"), "{e}"),
    }
    let good = slanted_edge_mtf(
        gaussian_edge(64, 64, 5.0, 1.0, false, false, 2.0, 3).view(),
        None,
    )
    .unwrap();
    assert!(good.warnings.is_empty(), "{:?}", good.warnings);
    let share = 64 / 4;
    assert!(
        good.phase_fill.iter().all(|n| *n >= share / 2),
        "{:?}",
        good.phase_fill
    );
}
