//! Conformance: eoir against numbers published by other projects and standards, each with
//! its source (docs/conformance.md lists them with the conventions converted).

use std::f64::consts::PI;

use eoir::characterize::uncertainty::{figures, Measured};
use eoir::processing::edge_mtf::slanted_edge_mtf;
use eoir::sensor::{Component, Sensor, SensorConfig};
use ndarray::Array2;

/// A diffraction-only sensor (footprint off) with aperture D = 50 mm and obscuration `r`.
fn aperture(r: f64, extra: &[&str]) -> Sensor {
    let text = format!(
        r#"
name = "aperture"
[optics]
focal_length_m = 0.1
f_number = 2.0
obscuration_ratio = {r}
[detector]
rows = 8
cols = 8
pitch_m = 24e-6
active_width_m = 20e-6
footprint_enabled = false
integration_time_s = 1e-3
quantum_efficiency = {{ kind = "ideal_qe", peak = 0.7, cutoff_um = 5.3 }}
"#
    );
    let o: Vec<String> = extra.iter().map(|s| s.to_string()).collect();
    Sensor::build(
        &SensorConfig::from_toml_str(&text, "aperture", std::path::PathBuf::from("."), &o).unwrap(),
    )
    .unwrap()
}

const LAMBDA_UM: f64 = 5.0;

/// eoir's system OTF of `s` at normalised frequency X = ρλ/D (radial).
fn otf_x(s: &Sensor, x: f64) -> f64 {
    let fc = s.otf().cutoff_cy_per_rad(LAMBDA_UM);
    s.otf().evaluate(x * fc, 0.0, LAMBDA_UM)
}

/// Composite Simpson rule of `f` on [0, 1] with `n` (even) intervals.
fn simpson(f: impl Fn(f64) -> f64, n: usize) -> f64 {
    let h = 1.0 / n as f64;
    let mut s = f(0.0) + f(1.0);
    for i in 1..n {
        s += f(i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    s * h / 3.0
}

/// The PSF at radius `r` (units λ/D) from the radial OTF (its Hankel transform,
/// `2π ∫₀¹ OTF(X) J0(2π X r) X dX`, normalised to unit total energy since OTF(0) = 1).
fn psf(s: &Sensor, r: f64) -> f64 {
    2.0 * PI * simpson(|x| otf_x(s, x) * libm::j0(2.0 * PI * x * r) * x, 4000)
}

/// The energy inside radius `r` (units λ/D): `2π r ∫₀¹ OTF(X) J1(2π X r) dX` (the OTF
/// times the transform of the disc indicator).
fn encircled(s: &Sensor, r: f64) -> f64 {
    2.0 * PI * r * simpson(|x| otf_x(s, x) * libm::j1(2.0 * PI * x * r), 4000)
}

/// The root of increasing-or-decreasing `f − target` in [a, b] by bisection.
fn solve(f: impl Fn(f64) -> f64, target: f64, mut a: f64, mut b: f64) -> f64 {
    let sa = (f(a) - target).signum();
    for _ in 0..60 {
        let m = 0.5 * (a + b);
        if (f(m) - target).signum() == sa {
            a = m;
        } else {
            b = m;
        }
    }
    0.5 * (a + b)
}

/// GalSim (`galsim.Airy`, obscuration 0): FWHM = 1.028993969962188 λ/D and half-light
/// radius = 0.5348321477242647 λ/D. eoir's PSF, the Hankel transform of its diffraction
/// OTF, gives both within 1e-5 relative.
#[test]
fn airy_fwhm_and_half_light_radius_match_galsim() {
    let s = aperture(0.0, &[]);
    let peak = psf(&s, 0.0);
    // Peak of the unit-energy Airy pattern: π/4 (D/λ)² (Born & Wolf §8.5.2).
    assert!((peak - PI / 4.0).abs() < 1e-7, "{peak}");
    let half = solve(|r| psf(&s, r), 0.5 * peak, 0.3, 0.7);
    let fwhm = 2.0 * half;
    assert!(
        (fwhm / 1.028993969962188 - 1.0).abs() < 1e-5,
        "FWHM {fwhm} λ/D"
    );
    let hlr = solve(|r| encircled(&s, r), 0.5, 0.3, 0.8);
    assert!(
        (hlr / 0.5348321477242647 - 1.0).abs() < 1e-5,
        "half-light radius {hlr} λ/D"
    );
}

/// Rayleigh (1881; Born & Wolf §8.5.2): the Airy pattern's encircled energy is
/// `1 − J0(πr)² − J1(πr)²` (r in λ/D), 0.8378 inside the first dark ring r = 1.2197 λ/D.
#[test]
fn airy_encircled_energy_is_rayleighs() {
    let s = aperture(0.0, &[]);
    for r in [0.25, 0.6, 1.0, 1.21967, 1.8] {
        let v = PI * r;
        let want = 1.0 - libm::j0(v).powi(2) - libm::j1(v).powi(2);
        let got = encircled(&s, r);
        assert!((got - want).abs() < 2e-6, "r {r}: {got} vs {want}");
    }
    let first_dark = encircled(&s, 1.219_67);
    assert!((first_dark - 0.8378).abs() < 1e-4, "{first_dark}");
}

/// Centrally obscured aperture (Born & Wolf §8.6.1, Mahajan 1986): at equal total energy,
/// the PSF peak of an annulus of obscuration ε is (1 − ε²) times the clear aperture's
/// (its central amplitude ∝ 1 − ε², its energy ∝ 1 − ε²). From eoir's obscured OTF
/// (docs/design.md §4.3) within 1e-5.
#[test]
fn obscured_aperture_peak_ratio() {
    let clear = psf(&aperture(0.0, &[]), 0.0);
    for eps in [0.2, 0.33, 0.5, 0.7] {
        let p = psf(&aperture(eps, &[]), 0.0);
        let ratio = p / clear;
        assert!(
            (ratio - (1.0 - eps * eps)).abs() < 1e-5,
            "ε {eps}: {ratio} vs {}",
            1.0 - eps * eps
        );
    }
}

/// Defocus Strehl ratio (Mahajan, "Strehl ratio for primary aberrations", JOSA 72 (1982)
/// 1258): for pure defocus of edge wavefront error W020 waves over a uniform circular
/// pupil, `S = [sin(πW020)/(πW020)]²`. From eoir's OTF (Hopkins' defocus factor times
/// the diffraction OTF, docs/design.md §4.4: an approximation within 0.015 of the exact
/// OTF) as ∫OTF·X dX / ∫OTF_diff·X dX, within 0.03 for W020 ≤ 0.5 wave (the
/// approximation's own error: 0.002, 0.009, 0.020 and 0.026 at 0.1, 0.25, 0.4 and 0.5 wave).
#[test]
fn defocus_strehl_ratio() {
    let clear = psf(&aperture(0.0, &[]), 0.0);
    for w in [0.1, 0.25, 0.4, 0.5] {
        let s = aperture(0.0, &[&format!("defocus.w020_waves={w}")]);
        let strehl = psf(&s, 0.0) / clear;
        let want = ((PI * w).sin() / (PI * w)).powi(2);
        eprintln!("defocus Strehl W020 {w}: eoir {strehl:.4}, Mahajan {want:.4}");
        assert!((strehl - want).abs() < 0.03, "W020 {w}: {strehl} vs {want}");
    }
    // The diffraction component is the only one on without defocus.
    assert_eq!(
        aperture(0.0, &[]).otf().components(),
        &[Component::Diffraction]
    );
}

/// An ideal slanted edge sampled by square pixels of 100 % fill factor (each pixel the
/// mean of the step over its area) has the MTF |sinc(f)| of the pixel aperture: 2/π =
/// 0.6366 at Nyquist (ISO 12233:2017 Annex D's reference case; the value Burns' sfrmat
/// and Imatest report for an ideal sensor). eoir's slanted-edge measurement gives it
/// within 0.01 up to Nyquist, at 5° and 8°.
#[test]
fn slanted_edge_of_an_ideal_pixel_aperture() {
    let (rows, cols, sub) = (100usize, 80usize, 32usize);
    for angle in [5.0f64, 8.0] {
        let t = angle.to_radians();
        let (nx, ny) = (t.cos(), -t.sin());
        let (xc, yc) = ((cols as f64 - 1.0) / 2.0 + 0.3, (rows as f64 - 1.0) / 2.0);
        let img = Array2::from_shape_fn((rows, cols), |(r, c)| {
            let mut bright = 0usize;
            for i in 0..sub {
                for j in 0..sub {
                    let y = r as f64 - 0.5 + (i as f64 + 0.5) / sub as f64;
                    let x = c as f64 - 0.5 + (j as f64 + 0.5) / sub as f64;
                    bright += usize::from((x - xc) * nx + (y - yc) * ny > 0.0);
                }
            }
            100.0 + 1000.0 * bright as f64 / (sub * sub) as f64
        });
        let m = slanted_edge_mtf(img.view(), None).unwrap();
        for (f, v) in m.freq_cy_per_px.iter().zip(&m.mtf) {
            if *f > 0.0 && *f <= 0.5 {
                let want = ((PI * f).sin() / (PI * f)).abs();
                assert!(
                    (v - want).abs() < 0.01,
                    "{angle}°: f {f:.3}: {v:.4} vs {want:.4}"
                );
            }
        }
        let at_nyquist =
            eoir::processing::edge_mtf::interpolate(&m.freq_cy_per_px, &m.mtf, 0.5).unwrap();
        assert!(
            (at_nyquist - 2.0 / PI).abs() < 0.01,
            "{angle}°: {at_nyquist}"
        );
    }
}

/// The `emva1288` reference package (1.0.2, `Results1288`) on the issue's `ccd` frames
/// (every dark pixel at one value: σ²_y.dark = 0, and K = 0.0514 DN/e⁻) reports
/// σ_d = 7.7 e⁻ and μ_e.min = 10.0 e⁻ (issue 38); eoir's Release 4.0 figures from the
/// same measured quantities agree (0.24 DN² floor, μ_e.min = σ_y.dark/K + ½), and the
/// dynamic range is μ_e.sat/μ_e.min.
#[test]
fn emva_threshold_as_the_reference_package() {
    let m = Measured {
        k: 0.0514,
        r: f64::NAN,
        y_sat: 900.0,
        dark_var: 0.0,
        s2_dark: 0.0,
        s2_bright: 1.0,
        net_spatial: 100.0,
    };
    let f = figures(&m);
    assert!((f["sigma_d_e"] - 7.7).abs() < 0.05, "{}", f["sigma_d_e"]);
    assert!((f["u_e_min_e"] - 10.0).abs() < 0.05, "{}", f["u_e_min_e"]);
    let dr = (900.0 / 0.0514) / f["u_e_min_e"];
    assert!((f["DR"] / dr - 1.0).abs() < 1e-12);
}
