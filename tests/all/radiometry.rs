//! Tests of `eoir::radiometry` against independent truth: the Stefan–Boltzmann law, Wien's
//! displacement law, the classical series for fractional blackbody integrals, brute-force
//! composite Simpson quadrature, closed-form integrals, and a camera equation evaluated by a
//! different route (aperture area × A_det / f²).
//!
//! The required accuracy is 1e-6 relative; where the reference itself is exact to ~1e-13
//! (series, fine Simpson) the tests assert 1e-9 so that a regression shows early.

use eoir::radiometry::{
    band_photon_radiance, band_photon_radiance_between, band_radiance, band_radiance_between,
    integrate, planck_photon_radiance, planck_spectral_radiance, CameraEquation, TemperatureLut,
};
use eoir::spectrum::Spectrum;
use eoir::Error;

// Independent copies of the constants (CODATA 2018 / SI 2019 exact values).
const H: f64 = 6.626_070_15e-34;
const C: f64 = 299_792_458.0;
const K: f64 = 1.380_649e-23;
/// CODATA 2018 Stefan–Boltzmann constant, W m-2 K-4.
const SIGMA: f64 = 5.670_374_419e-8;
/// CODATA 2018 Wien wavelength displacement constant, µm K.
const WIEN_B_UM_K: f64 = 2_897.771_955;

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// G(x) = ∫_x^∞ t³/(eᵗ − 1) dt = Σ_n e^{−nx}(x³/n + 3x²/n² + 6x/n³ + 6/n⁴).
fn series_energy(x: f64) -> f64 {
    let mut sum = 0.0;
    for n in 1..100_000 {
        let n = n as f64;
        let term = (-n * x).exp()
            * (x.powi(3) / n + 3.0 * x * x / n.powi(2) + 6.0 * x / n.powi(3) + 6.0 / n.powi(4));
        sum += term;
        if term < 1e-18 * sum {
            break;
        }
    }
    sum
}

/// Q(x) = ∫_x^∞ t²/(eᵗ − 1) dt = Σ_n e^{−nx}(x²/n + 2x/n² + 2/n³).
fn series_photon(x: f64) -> f64 {
    let mut sum = 0.0;
    for n in 1..100_000 {
        let n = n as f64;
        let term = (-n * x).exp() * (x * x / n + 2.0 * x / n.powi(2) + 2.0 / n.powi(3));
        sum += term;
        if term < 1e-18 * sum {
            break;
        }
    }
    sum
}

/// ∫_{λ1}^{λ2} L_λ dλ, W m-2 sr-1, by the series (λ in µm).
fn series_band_radiance(t: f64, l1_um: f64, l2_um: f64) -> f64 {
    let x = |l_um: f64| H * C / (l_um * 1e-6 * K * t);
    2.0 * K.powi(4) * t.powi(4) / (H.powi(3) * C * C)
        * (series_energy(x(l2_um)) - series_energy(x(l1_um)))
}

/// ∫_{λ1}^{λ2} L_q dλ, photons s-1 m-2 sr-1, by the series.
fn series_band_photons(t: f64, l1_um: f64, l2_um: f64) -> f64 {
    let x = |l_um: f64| H * C / (l_um * 1e-6 * K * t);
    2.0 * K.powi(3) * t.powi(3) / (H.powi(3) * C * C)
        * (series_photon(x(l2_um)) - series_photon(x(l1_um)))
}

/// Composite Simpson with `n` (even) intervals.
fn simpson(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
    let h = (b - a) / n as f64;
    let mut sum = f(a) + f(b);
    for i in 1..n {
        sum += if i % 2 == 1 { 4.0 } else { 2.0 } * f(a + h * i as f64);
    }
    sum * h / 3.0
}

#[test]
fn integrate_closed_forms() {
    let pi = std::f64::consts::PI;
    // Smooth, finite.
    let v = integrate(|x| x.sin(), 0.0, pi, &[], 1e-12);
    assert!(rel(v, 2.0) < 1e-12, "{v}");
    // Reversed limits and an empty interval.
    assert!(rel(integrate(|x| x.sin(), pi, 0.0, &[], 1e-12), -2.0) < 1e-12);
    assert_eq!(integrate(|x| x.sin(), 1.0, 1.0, &[], 1e-12), 0.0);
    // Infinite limits.
    assert!(
        rel(
            integrate(|x| (-x).exp(), 0.0, f64::INFINITY, &[], 1e-12),
            1.0
        ) < 1e-10
    );
    let g = integrate(
        |x| (-x * x).exp(),
        f64::NEG_INFINITY,
        f64::INFINITY,
        &[],
        1e-12,
    );
    assert!(rel(g, pi.sqrt()) < 1e-10, "{g}");
    assert!(
        rel(
            integrate(|x| x.exp(), f64::NEG_INFINITY, 0.0, &[], 1e-12),
            1.0
        ) < 1e-10
    );
    // A jump at a breakpoint: ∫_0^2 x·[x > 1] dx = 1.5.
    let step = |x: f64| if x > 1.0 { x } else { 0.0 };
    assert!(rel(integrate(step, 0.0, 2.0, &[1.0], 1e-12), 1.5) < 1e-14);
    // Without the breakpoint the jump is found adaptively.
    assert!(rel(integrate(step, 0.0, 2.0, &[], 1e-10), 1.5) < 1e-9);
    // Endpoint singularity in the derivative: ∫_0^1 √x dx = 2/3.
    assert!(
        rel(
            integrate(|x: f64| x.sqrt(), 0.0, 1.0, &[], 1e-10),
            2.0 / 3.0
        ) < 1e-9
    );
    // A NaN limit gives NaN.
    assert!(integrate(|x| x, f64::NAN, 1.0, &[], 1e-10).is_nan());
}

#[test]
fn stefan_boltzmann_total_radiance() {
    for t in [200.0, 300.0, 500.0, 1000.0, 3000.0, 6000.0] {
        let sigma_t4 = SIGMA * f64::powi(t, 4);
        // Finite range 0 … 10⁴ × the Wien peak: the tail beyond is ~1e-11 of the total.
        let peak = WIEN_B_UM_K / t;
        let finite = std::f64::consts::PI
            * integrate(
                |w| planck_spectral_radiance(w, t),
                0.0,
                1e4 * peak,
                &[],
                1e-12,
            );
        assert!(
            rel(finite, sigma_t4) < 1e-6,
            "T = {t}: {finite} vs {sigma_t4}"
        );
        // And the whole half-line.
        let whole = std::f64::consts::PI
            * integrate(
                |w| planck_spectral_radiance(w, t),
                0.0,
                f64::INFINITY,
                &[],
                1e-12,
            );
        assert!(
            rel(whole, sigma_t4) < 1e-6,
            "T = {t}: {whole} vs {sigma_t4}"
        );
        // Via the band function with a constant weight.
        let band = std::f64::consts::PI
            * band_radiance_between(t, &Spectrum::constant(1.0), 0.0, f64::INFINITY).unwrap();
        assert!(rel(band, sigma_t4) < 1e-6, "T = {t}: {band}");
    }
}

#[test]
fn wien_peak_by_golden_section() {
    for t in [250.0, 300.0, 1000.0, 5800.0] {
        let f = |w: f64| planck_spectral_radiance(w, t);
        let (mut a, mut b) = (0.5 * WIEN_B_UM_K / t, 2.0 * WIEN_B_UM_K / t);
        let g = (5f64.sqrt() - 1.0) / 2.0;
        let mut c = b - g * (b - a);
        let mut d = a + g * (b - a);
        let (mut fc, mut fd) = (f(c), f(d));
        while (b - a) > 1e-12 * b {
            if fc > fd {
                b = d;
                d = c;
                fd = fc;
                c = b - g * (b - a);
                fc = f(c);
            } else {
                a = c;
                c = d;
                fc = fd;
                d = a + g * (b - a);
                fd = f(d);
            }
        }
        let peak = 0.5 * (a + b);
        assert!(rel(peak, WIEN_B_UM_K / t) < 1e-6, "T = {t}: peak {peak} µm");
    }
}

#[test]
fn photon_form_is_energy_times_lambda_over_hc() {
    // Rayleigh–Jeans limit as an independent check of the energy form: L → 2ckT/λ⁴.
    let (w_um, t): (f64, f64) = (1e5, 300.0);
    let lam = w_um * 1e-6;
    let rj = 2.0 * C * K * t / lam.powi(4) * 1e-6;
    assert!(rel(planck_spectral_radiance(w_um, t), rj) < 1e-3);
    // Photon form: per-photon energy hc/λ.
    let w = 4.0;
    let q = planck_photon_radiance(w, t);
    assert!(rel(q * H * C / (w * 1e-6), planck_spectral_radiance(w, t)) < 1e-14);
    assert_eq!(planck_spectral_radiance(0.0, t), 0.0);
    assert_eq!(
        planck_spectral_radiance(1e-4, t),
        0.0,
        "deep Wien tail underflows to 0"
    );
    assert_eq!(planck_spectral_radiance(4.0, 0.0), 0.0);
}

#[test]
fn band_integrals_match_the_series() {
    let t = 300.0;
    for (lo, hi) in [(3.0, 5.0), (8.0, 12.0)] {
        let truth_e = series_band_radiance(t, lo, hi);
        let truth_q = series_band_photons(t, lo, hi);
        let sharp = Spectrum::top_hat(lo, hi, 0.0, 1.0).unwrap();
        let e = band_radiance(t, &sharp).unwrap();
        let q = band_photon_radiance(t, &sharp).unwrap();
        assert!(rel(e, truth_e) < 1e-9, "{lo}-{hi} µm: {e} vs {truth_e}");
        assert!(rel(q, truth_q) < 1e-9, "{lo}-{hi} µm: {q} vs {truth_q}");
        let one = Spectrum::constant(1.0);
        let e2 = band_radiance_between(t, &one, lo, hi).unwrap();
        let q2 = band_photon_radiance_between(t, &one, lo, hi).unwrap();
        assert!(rel(e2, truth_e) < 1e-6 && rel(q2, truth_q) < 1e-6);
        // Limits wider than the support are clipped to it.
        let e3 = band_radiance_between(t, &sharp, 0.0, 100.0).unwrap();
        assert!(rel(e3, truth_e) < 1e-6);
    }
    // Magnitude check: 8–12 µm at 300 K is about 39 W m-2 sr-1, 3–5 µm about 1.9.
    let lw = series_band_radiance(300.0, 8.0, 12.0);
    let mw = series_band_radiance(300.0, 3.0, 5.0);
    assert!(
        (35.0..45.0).contains(&lw) && (1.5..2.5).contains(&mw),
        "{lw} {mw}"
    );
}

#[test]
fn band_integral_errors() {
    let one = Spectrum::constant(1.0);
    assert!(matches!(
        band_radiance(300.0, &one),
        Err(Error::InvalidParameter { .. })
    ));
    assert!(band_photon_radiance(300.0, &one).is_err());
    let th = Spectrum::top_hat(3.0, 5.0, 0.0, 1.0).unwrap();
    assert!(band_radiance(0.0, &th).is_err());
    assert!(band_radiance(f64::NAN, &th).is_err());
    assert!(band_radiance_between(300.0, &th, 5.0, 3.0).is_err());
    assert!(band_radiance_between(300.0, &th, -1.0, 3.0).is_err());
    // Disjoint limits give zero, not an error.
    assert_eq!(band_radiance_between(300.0, &th, 6.0, 7.0).unwrap(), 0.0);
}

#[test]
fn gaussian_and_edged_top_hat_against_brute_force_simpson() {
    let n = 1_000_000;
    for t in [250.0, 300.0, 400.0] {
        // Gaussian: Simpson over ±10σ.
        let g = Spectrum::gaussian(4.0, 0.5, 0.8).unwrap();
        let sigma = 0.5 / 2.354_820_045_030_949;
        let (a, b) = (4.0 - 10.0 * sigma, 4.0 + 10.0 * sigma);
        let truth = simpson(
            |w| 0.8 * (-0.5 * ((w - 4.0) / sigma).powi(2)).exp() * planck_spectral_radiance(w, t),
            a,
            b,
            n,
        );
        let got = band_radiance(t, &g).unwrap();
        assert!(rel(got, truth) < 1e-9, "gaussian T = {t}: {got} vs {truth}");
        let truth_q = simpson(
            |w| 0.8 * (-0.5 * ((w - 4.0) / sigma).powi(2)).exp() * planck_photon_radiance(w, t),
            a,
            b,
            n,
        );
        assert!(rel(band_photon_radiance(t, &g).unwrap(), truth_q) < 1e-6);

        // Top-hat with linear edges × ideal photon detector, written out independently.
        let th = Spectrum::top_hat(8.0, 10.0, 0.4, 0.9).unwrap();
        let det = Spectrum::photon_detector(0.7, 9.5).unwrap();
        let resp = th.product(&det);
        let by_hand = |w: f64| {
            let filter = if !(7.8..=10.2).contains(&w) {
                0.0
            } else if w < 8.2 {
                0.9 * (w - 7.8) / 0.4
            } else if w <= 9.8 {
                0.9
            } else {
                0.9 * (10.2 - w) / 0.4
            };
            let qe = if w <= 9.5 { 0.7 * w / 9.5 } else { 0.0 };
            filter * qe
        };
        let truth = simpson(
            |w| by_hand(w) * planck_spectral_radiance(w, t),
            7.5,
            10.5,
            n,
        );
        let got = band_radiance(t, &resp).unwrap();
        assert!(
            rel(got, truth) < 1e-6,
            "top-hat×detector T = {t}: {got} vs {truth}"
        );
    }
}

#[test]
fn table_band_integral_matches_trapezoid_of_fine_grid() {
    // A filter table with non-zero ends (jumps at its ends): compare with Simpson per node
    // interval of the hand-interpolated curve.
    let wl = vec![3.4, 3.6, 4.1, 4.8, 5.0];
    let val = vec![0.3, 0.9, 0.85, 0.95, 0.4];
    let s = Spectrum::table(wl.clone(), val.clone()).unwrap();
    let t = 320.0;
    let mut truth = 0.0;
    for i in 0..wl.len() - 1 {
        let (x0, x1, y0, y1) = (wl[i], wl[i + 1], val[i], val[i + 1]);
        truth += simpson(
            |w| (y0 + (y1 - y0) * (w - x0) / (x1 - x0)) * planck_photon_radiance(w, t),
            x0,
            x1,
            20_000,
        );
    }
    let got = band_photon_radiance(t, &s).unwrap();
    assert!(rel(got, truth) < 1e-9, "{got} vs {truth}");
}

/// The camera of the brief: F/2, 20 µm active width, 2.6 ms, 4.55–5.2 µm, 300 K.
fn mwir_camera() -> (CameraEquation, Spectrum) {
    let cam = CameraEquation::new(2.6e-3, 20e-6 * 20e-6, 2.0).unwrap();
    let band = Spectrum::top_hat(4.55, 5.2, 0.0, 1.0).unwrap();
    (cam, band)
}

#[test]
fn camera_equation_by_aperture_route() {
    let (cam, band) = mwir_camera();
    let t = 300.0;
    // Different route: aperture area × A_det / f² × t × series photon radiance.
    let focal_m = 0.1;
    let diameter_m = focal_m / 2.0;
    let aperture_area = std::f64::consts::PI * diameter_m * diameter_m / 4.0;
    let a_det = 20e-6 * 20e-6;
    let photons = series_band_photons(t, 4.55, 5.2);
    let truth = aperture_area * a_det / (focal_m * focal_m) * 2.6e-3 * photons;
    let got = cam.electrons_blackbody(t, &band).unwrap();
    assert!(rel(got, truth) < 1e-9, "{got} vs {truth}");
    // The generic spectral route with a Planck radiance gives the same.
    let spectral = cam
        .electrons_spectral(&band, |w| planck_spectral_radiance(w, t), 4.0, 6.0)
        .unwrap();
    assert!(rel(spectral, truth) < 1e-6, "{spectral} vs {truth}");

    // Magnitude (checked by hand): L_λ(5 µm, 300 K) ≈ 2.6 W m-2 sr-1 µm-1, so the
    // 4.55–5.2 µm band carries ≈ 1.5 W m-2 sr-1 ≈ 3.7e19 photons s-1 m-2 sr-1. The F/2 cone
    // (π/16 sr) onto a 4e-10 m² detector for 2.6 ms then collects ≈ 7.6e6 electrons at unit
    // QE: order 1e6–1e7, i.e. a 300 K background alone fills a typical few-Me- MWIR well in a
    // few ms, which is why such cameras run ~1–3 ms at F/2. (The wrong `A_pix·Ω` form,
    // Ω = A_pix/f², would replace the 1.96e-3 m² aperture by the 4e-10 m² pixel: ~2e-7 of this.)
    assert!((1e6..1e7).contains(&got), "{got}");
    assert!((7.0e6..8.2e6).contains(&got), "{got}");

    // Obscuration: the annulus area ratio (D² − (RD)²)/D².
    let r = 0.3;
    let obscured = cam
        .with_obscuration(r)
        .unwrap()
        .electrons_blackbody(t, &band)
        .unwrap();
    let annulus = (diameter_m.powi(2) - (r * diameter_m).powi(2)) / diameter_m.powi(2);
    assert!(rel(obscured, truth * annulus) < 1e-6);

    // cos⁴θ: 1 on axis, (√3/2)⁴ = 9/16 at 30°.
    let on_axis = cam.with_cos4(0.0).unwrap();
    assert_eq!(on_axis.etendue_time(), cam.etendue_time());
    let off = cam.with_cos4(std::f64::consts::PI / 6.0).unwrap();
    assert!(rel(off.etendue_time(), cam.etendue_time() * 9.0 / 16.0) < 1e-14);

    // Étendue-time in m² sr s against the aperture route.
    assert!(
        rel(
            cam.etendue_time(),
            aperture_area * a_det / (focal_m * focal_m) * 2.6e-3
        ) < 1e-14
    );
}

#[test]
fn camera_equation_validation() {
    assert!(CameraEquation::new(0.0, 1e-10, 2.0).is_err());
    assert!(CameraEquation::new(1e-3, -1e-10, 2.0).is_err());
    assert!(CameraEquation::new(1e-3, 1e-10, f64::NAN).is_err());
    let (cam, band) = mwir_camera();
    assert!(cam.with_obscuration(1.0).is_err());
    assert!(cam.with_obscuration(-0.1).is_err());
    assert!(cam.with_cos4(std::f64::consts::FRAC_PI_2).is_err());
    let mut bad = cam;
    bad.f_number = 0.0;
    assert!(bad.validate().is_err());
    assert!(bad.electrons_blackbody(300.0, &band).is_err());
    assert!(cam.electrons_spectral(&band, |_| 1.0, 5.0, 4.0).is_err());
    assert!(cam
        .electrons_spectral(&band, |_| f64::NAN, 4.0, 6.0)
        .is_err());
    assert!(cam
        .electrons_blackbody(300.0, &Spectrum::constant(1.0))
        .is_err());
}

fn check_round_trip(lut: &TemperatureLut, forward: impl Fn(f64) -> f64) -> f64 {
    let mut worst: f64 = 0.0;
    let mut t = 200.0;
    while t <= 500.0 {
        let back = lut.temperature(forward(t)).unwrap();
        worst = worst.max((back - t).abs());
        t += 3.37;
    }
    for t in [200.0, 200.01, 499.99, 500.0] {
        worst = worst.max((lut.temperature(forward(t)).unwrap() - t).abs());
    }
    worst
}

#[test]
fn apparent_temperature_round_trip_radiance_and_electrons() {
    for (lo, hi) in [(3.0, 5.0), (8.0, 12.0)] {
        let band = Spectrum::top_hat(lo, hi, 0.1, 0.85).unwrap();
        let b = band.clone();
        let radiance = move |t: f64| band_radiance(t, &b).unwrap_or(f64::NAN);
        let lut = TemperatureLut::new(radiance.clone(), 200.0, 500.0).unwrap();
        assert_eq!(lut.range_k(), (200.0, 500.0));
        let worst = check_round_trip(&lut, &radiance);
        assert!(
            worst < 1e-6,
            "{lo}-{hi} µm radiance: worst round trip {worst} K"
        );

        let cam = CameraEquation::new(1e-3, (15e-6_f64).powi(2) * 0.8, 2.5)
            .unwrap()
            .with_obscuration(0.25)
            .unwrap();
        let resp = band.product(&Spectrum::photon_detector(0.75, 12.5).unwrap());
        let electrons = move |t: f64| cam.electrons_blackbody(t, &resp).unwrap_or(f64::NAN);
        let lut_e = TemperatureLut::new(electrons.clone(), 200.0, 500.0).unwrap();
        let worst = check_round_trip(&lut_e, &electrons);
        assert!(
            worst < 1e-6,
            "{lo}-{hi} µm electrons: worst round trip {worst} K"
        );

        // Out of range and NaN.
        let (v0, v1) = (radiance(200.0), radiance(500.0));
        match lut.temperature(v1 * 1.01) {
            Err(Error::OutOfRange(msg)) => assert!(msg.contains("outside"), "{msg}"),
            other => panic!("expected OutOfRange, got {other:?}"),
        }
        assert!(lut.temperature(v0 * 0.99).is_err());
        assert!(lut.temperature(f64::NAN).is_err());
        assert!(lut.temperature_or_nan(f64::NAN).is_nan());
        assert!(lut.temperature_or_nan(v1 * 2.0).is_nan());
        assert!((lut.temperature_or_nan(radiance(321.5)) - 321.5).abs() < 1e-6);
    }
}

#[test]
fn temperature_lut_rejects_non_monotone_and_bad_ranges() {
    match TemperatureLut::new(|t| (t - 300.0).abs(), 250.0, 350.0) {
        Err(Error::OutOfRange(msg)) => assert!(msg.contains("T = "), "{msg}"),
        other => panic!("expected an error, got {other:?}"),
    }
    assert!(TemperatureLut::new(|t| t, 300.0, 200.0).is_err());
    assert!(TemperatureLut::new(|t| t, 0.0, 200.0).is_err());
    assert!(TemperatureLut::new(|t| t, 100.0, f64::INFINITY).is_err());
    assert!(TemperatureLut::new(|t| if t > 250.0 { f64::NAN } else { t }, 200.0, 300.0).is_err());
    // A simple analytic response inverts exactly: v = T³.
    let lut = TemperatureLut::new(|t| t * t * t, 10.0, 20.0).unwrap();
    assert!((lut.temperature(15.0f64.powi(3)).unwrap() - 15.0).abs() < 1e-9);
    assert!(format!("{lut:?}").contains("TemperatureLut"));
}
