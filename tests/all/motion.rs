//! Tests of `eoir::motion` against the numerical Fourier transform of the sampled PSFs
//! (direct DFT sums), and the smear geometry.

use std::f64::consts::PI;

use eoir::motion::{gaussian, jitter, linear_motion, smear_from_angular_rate, smear_from_velocity};

/// Direct 2-D Fourier sum of the sampled Gaussian PSF `exp(−x²/2σx² − y²/2σy²)` on a fine
/// grid (step σ/8, out to ±9σ), normalised by its own DC sum: (real, imaginary) parts of
/// `Σ p(x,y) e^{−2πi(fx x + fy y)} / Σ p`.
fn gaussian_psf_dft(fx: f64, fy: f64, sigma_x: f64, sigma_y: f64) -> (f64, f64) {
    let n: i32 = 72; // samples per side: ±9σ at σ/8
    let (dx, dy) = (sigma_x / 8.0, sigma_y / 8.0);
    let (mut re, mut im, mut dc) = (0.0, 0.0, 0.0);
    for j in -n..=n {
        let y = f64::from(j) * dy;
        for i in -n..=n {
            let x = f64::from(i) * dx;
            let p = (-0.5 * (x * x / (sigma_x * sigma_x) + y * y / (sigma_y * sigma_y))).exp();
            let phase = -2.0 * PI * (fx * x + fy * y);
            re += p * phase.cos();
            im += p * phase.sin();
            dc += p;
        }
    }
    (re / dc, im / dc)
}

/// Direct Fourier sum of a box PSF of length `d` along direction θ, sampled with `n`
/// points at the midpoints of equal sub-segments (a line of uniform weight through the
/// origin): (real, imaginary) parts.
fn box_psf_dft(fx: f64, fy: f64, d: f64, theta: f64, n: usize) -> (f64, f64) {
    let (s, c) = theta.sin_cos();
    let (mut re, mut im) = (0.0, 0.0);
    for i in 0..n {
        let t = ((i as f64 + 0.5) / n as f64 - 0.5) * d;
        let phase = -2.0 * PI * (fx * t * c + fy * t * s);
        re += phase.cos();
        im += phase.sin();
    }
    (re / n as f64, im / n as f64)
}

#[test]
fn jitter_matches_dft_of_sampled_gaussian_psf() {
    let sigma = 20e-6; // rad
    for &(fx, fy) in &[
        (0.0, 0.0),
        (5_000.0, 0.0),
        (0.0, -12_000.0),
        (7_000.0, 9_000.0),
        (-15_000.0, 4_000.0),
        (25_000.0, 25_000.0),
    ] {
        let (re, im) = gaussian_psf_dft(fx, fy, sigma, sigma);
        let got = jitter(fx, fy, sigma);
        assert!((got - re).abs() < 1e-6, "({fx}, {fy}): {got} vs {re}");
        assert!(im.abs() < 1e-9);
    }
}

#[test]
fn anisotropic_gaussian_matches_dft_of_sampled_psf() {
    let (sx, sy) = (8e-6, 30e-6);
    for &(fx, fy) in &[
        (10_000.0, 0.0),
        (0.0, 10_000.0),
        (-20_000.0, 6_000.0),
        (40_000.0, -3_000.0),
    ] {
        let (re, _) = gaussian_psf_dft(fx, fy, sx, sy);
        let got = gaussian(fx, fy, sx, sy);
        assert!((got - re).abs() < 1e-6, "({fx}, {fy}): {got} vs {re}");
    }
    // σx = σy reduces to jitter; cascading jitter and blur adds variances.
    assert_eq!(gaussian(3e3, 4e3, 1e-5, 1e-5), jitter(3e3, 4e3, 1e-5));
    let (a, b) = (12e-6, 5e-6);
    let both = jitter(9e3, -2e3, a) * gaussian(9e3, -2e3, b, b);
    let combined = jitter(9e3, -2e3, (a * a + b * b).sqrt());
    assert!((both - combined).abs() < 1e-14);
}

#[test]
fn linear_motion_matches_dft_of_box_psf() {
    let d = 50e-6; // rad of smear
    for &theta in &[0.0, 0.4, PI / 2.0, 2.2, -1.0] {
        let (s, c) = f64::sin_cos(theta);
        // Frequencies along the motion (f·d from 0 to 3.3) plus a perpendicular component
        // that must have no effect.
        for &f_along_d in &[0.0, 0.3, 0.75, 1.0, 1.5, 2.4, 3.3] {
            let f_along = f_along_d / d;
            let f_perp = 7_777.0;
            let fx = f_along * c - f_perp * s;
            let fy = f_along * s + f_perp * c;
            let (re, im) = box_psf_dft(fx, fy, d, theta, 100_000);
            let got = linear_motion(fx, fy, d, theta);
            assert!(
                (got - re).abs() < 1e-6,
                "θ {theta}, f·d {f_along_d}: {got} vs {re}"
            );
            assert!(im.abs() < 1e-9);
        }
    }
}

#[test]
fn linear_motion_changes_sign_past_first_zero() {
    let (d, theta) = (30e-6, 0.7);
    let (s, c) = f64::sin_cos(theta);
    let at = |fd: f64| {
        let f = fd / d;
        linear_motion(f * c, f * s, d, theta)
    };
    // First zero at f·d = 1, contrast reversed between 1 and 2, positive again after 2.
    assert!(at(1.0).abs() < 1e-12);
    assert!(at(0.99) > 0.0);
    assert!(at(1.01) < 0.0);
    let (re, _) = box_psf_dft(1.5 / d * c, 1.5 / d * s, d, theta, 100_000);
    assert!(re < -0.2 && at(1.5) < -0.2);
    assert!((at(1.5) + 2.0 / (3.0 * PI)).abs() < 1e-12); // sin(1.5π)/(1.5π)
    assert!(at(2.5) > 0.0);
    // No smear → no blur.
    assert_eq!(linear_motion(1e5, -3e4, 0.0, theta), 1.0);
}

#[test]
fn smear_lengths() {
    // A target crossing at 10 m/s, 2 km away, 5 ms exposure: 5 cm of travel seen from
    // 2 km is 25 µrad.
    let d = smear_from_velocity(10.0, 5e-3, 2000.0);
    assert!((d - 25e-6).abs() < 1e-18);
    // Slewing at 1°/s for 10 ms covers 0.01°.
    let d = smear_from_angular_rate(1f64.to_radians(), 10e-3);
    assert!((d - 0.01f64.to_radians()).abs() < 1e-18);
}
