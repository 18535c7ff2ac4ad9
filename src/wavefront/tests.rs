//! Tests of the pupil OTF against independent truths: the analytic diffraction OTFs, the
//! exact defocus integral, the centroid theorem (G-tilt), the astigmatic line foci, and
//! energy conservation with spider vanes.

use std::f64::consts::PI;

use super::*;
use crate::optics;

const LAMBDA: f64 = 4e-6;
const D: f64 = 0.05;

fn transfer(pupil: &Pupil, w: &LocalWavefront, n: usize, padding: usize) -> PupilTransfer {
    let s = Sampling {
        samples_across: n,
        padding,
    };
    PupilTransfer::compute(pupil, w, LAMBDA, LAMBDA, D, s).unwrap()
}

/// Largest |OTF − truth(ρ)| over every grid frequency with ρ = |(X, Y)| < 1.
fn max_radial_error(t: &PupilTransfer, truth: impl Fn(f64) -> f64) -> f64 {
    max_error_where(t, truth, |_, _| true)
}

/// Largest |OTF − truth(ρ)| over the grid frequencies on the axes and diagonals with
/// ρ < 1 (for truths that are slow to evaluate).
fn max_error_on_axes(t: &PupilTransfer, truth: impl Fn(f64) -> f64) -> f64 {
    max_error_where(t, truth, |i, j| i == 0 || j == 0 || i.abs() == j.abs())
}

fn max_error_where(
    t: &PupilTransfer,
    truth: impl Fn(f64) -> f64,
    keep: impl Fn(i64, i64) -> bool,
) -> f64 {
    let m = t.otf_grid().nrows();
    let n = t.sampling().samples_across as f64;
    let h = (m / 2) as f64;
    let mut worst: f64 = 0.0;
    for ((r, c), v) in t.otf_grid().indexed_iter() {
        let (i, j) = (c as i64 - h as i64, r as i64 - h as i64);
        let (x, y) = (i as f64 / n, j as f64 / n);
        let rho = x.hypot(y);
        if rho < 1.0 && keep(i, j) {
            worst = worst.max((v - num_complex::Complex64::new(truth(rho), 0.0)).norm());
        }
    }
    worst
}

/// Exact defocused OTF (H. H. Hopkins, Proc. R. Soc. A 231, 91, 1955; derived in
/// docs/wavefront.md):
/// `(4/π) ∫₀^{acos X} sin²φ cos(8π W020 X (cos φ − X)) dφ`, by Simpson's rule.
fn defocus_exact(x: f64, w020: f64) -> f64 {
    if x >= 1.0 {
        return 0.0;
    }
    let b = x.acos();
    let k = 2000;
    let f = |p: f64| p.sin().powi(2) * (8.0 * PI * w020 * x * (p.cos() - x)).cos();
    let h = b / k as f64;
    let mut s = f(0.0) + f(b);
    for i in 1..k {
        s += f(i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    4.0 / PI * s * h / 3.0
}

fn seidel(s: Seidel) -> LocalWavefront {
    LocalWavefront {
        seidel: s,
        zernike_rms_waves: vec![],
    }
}

/// The OTF along one axis at the grid frequencies X = k/n, k = 0..n.
fn axis(t: &PupilTransfer, tangential: bool) -> Vec<(f64, num_complex::Complex64)> {
    let n = t.sampling().samples_across;
    (0..n)
        .map(|k| {
            let x = k as f64 / n as f64;
            let v = if tangential {
                t.at_normalised(0.0, x)
            } else {
                t.at_normalised(x, 0.0)
            };
            (x, v)
        })
        .collect()
}

#[test]
fn zero_wavefront_is_the_analytic_diffraction_otf_and_the_sampling_bound_holds() {
    let zero = LocalWavefront::default();
    // (samples across, bound): the stated sampling error (docs/wavefront.md).
    for (n, bound) in [(64, 5e-3), (128, 1.2e-3), (256, 1e-3)] {
        for r in [0.0, 0.3, 0.5] {
            let p = Pupil::obscured(r).unwrap();
            let t = transfer(&p, &zero, n, 2);
            let e = max_radial_error(&t, |x| optics::diffraction_obscured(x, r));
            eprintln!("zero wavefront n = {n}, R = {r}: max |OTF - analytic| = {e:.2e}");
            assert!(e < bound, "n = {n}, R = {r}: {e:.2e} >= {bound:.0e}");
            assert_eq!(t.strehl(), 1.0);
        }
    }
    // λ scaling of the frequency axis: X = f λ / D. At f = 0.5 D/λ the OTF is the clear
    // OTF at X = 0.5; at twice the wavelength the same f is the cutoff.
    let t = PupilTransfer::compute(
        &Pupil::clear(),
        &zero,
        LAMBDA,
        LAMBDA,
        D,
        Sampling::default(),
    )
    .unwrap();
    let f = 0.5 * D / LAMBDA;
    assert!((t.at_cy_per_rad(f, 0.0).re - optics::diffraction_clear(0.5)).abs() < 1e-3);
    let t2 = PupilTransfer::compute(
        &Pupil::clear(),
        &zero,
        LAMBDA,
        2.0 * LAMBDA,
        D,
        Sampling::default(),
    )
    .unwrap();
    assert!(t2.at_cy_per_rad(f, 0.0).norm() < 1e-3);
    assert!((t2.at_cy_per_rad(0.5 * f, 0.0).re - optics::diffraction_clear(0.5)).abs() < 1e-3);
}

#[test]
fn defocus_matches_the_exact_integral_and_the_hopkins_form() {
    for w020 in [0.1, 0.25, 0.5, 1.0] {
        let t = transfer(
            &Pupil::clear(),
            &seidel(Seidel {
                w020,
                ..Seidel::default()
            }),
            256,
            2,
        );
        let exact = max_error_on_axes(&t, |x| defocus_exact(x, w020));
        let hopkins = max_radial_error(&t, |x| {
            optics::diffraction_clear(x) * optics::defocus(x, w020)
        });
        eprintln!("defocus W020 = {w020}: vs exact {exact:.2e}, vs optics::defocus {hopkins:.2e}");
        assert!(exact < 2e-3, "W020 = {w020}: {exact:.2e}");
        // optics::defocus is Hopkins' approximation: within 2e-3 of the pupil OTF for a
        // small defocus, within its documented 0.015 beyond.
        let tol = if w020 <= 0.1 { 2e-3 } else { 0.015 };
        assert!(hopkins < tol, "W020 = {w020}: {hopkins:.2e}");
    }
    // A fixed optical path difference: W020 = 0.5 wave at λ_ref is 0.25 wave at 2 λ_ref.
    let w = seidel(Seidel {
        w020: 0.5,
        ..Seidel::default()
    });
    let s = Sampling::default();
    let t = PupilTransfer::compute(&Pupil::clear(), &w, LAMBDA, 2.0 * LAMBDA, D, s).unwrap();
    let e = max_error_on_axes(&t, |x| defocus_exact(x, 0.25));
    assert!(e < 2e-3, "{e:.2e}");
}

/// Largest |PSF(r, c) − PSF(mirror)| summed, mirrored in y (`flip_y`) or x.
fn asymmetry(t: &PupilTransfer, flip_y: bool) -> f64 {
    let psf = t.psf();
    let m = psf.nrows();
    let mut s = 0.0;
    for ((r, c), &v) in psf.indexed_iter() {
        let (rr, cc) = if flip_y {
            ((m - r) % m, c)
        } else {
            (r, (m - c) % m)
        };
        s += (v - psf[(rr, cc)]).abs();
    }
    s / 2.0
}

#[test]
fn coma_moves_the_centroid_by_the_mean_wavefront_slope() {
    // Centroid theorem (G-tilt; Tyler 1994, JOSA A 11, 358; Teague 1982): the PSF centroid
    // is the pupil average of the wavefront gradient, which by the divergence theorem is
    // (1/πa²) ∮ W n dl. Seidel coma W131 ρ³cos φ (φ from +y): edge value W131 y, so the
    // centroid is 2 W131 λ/D along +y. Noll Z7 = √8(3ρ³−2ρ) sin θ: edge value √8 y, so
    // c·Z7 moves it by 2√8 c λ/D, although Z7 has no Zernike tilt.
    let cases = [
        (
            seidel(Seidel {
                w131: 0.3,
                ..Seidel::default()
            }),
            2.0 * 0.3,
        ),
        (
            LocalWavefront {
                seidel: Seidel::default(),
                zernike_rms_waves: vec![0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.1],
            },
            2.0 * 8f64.sqrt() * 0.1,
        ),
    ];
    for (w, shift_lambda_over_d) in cases {
        let t = transfer(&Pupil::clear(), &w, 256, 2);
        let (cx, cy) = t.centroid_rad();
        let want = shift_lambda_over_d * LAMBDA / D;
        eprintln!(
            "coma centroid y {:.5} λ/D, theory {shift_lambda_over_d:.5}",
            cy * D / LAMBDA
        );
        assert!((cy / want - 1.0).abs() < 0.02, "centroid {cy} vs {want}");
        assert!(cx.abs() < 1e-3 * want, "x centroid {cx}");
        // Coma is asymmetric along the field (y) and mirror-symmetric across it (x).
        let ay = asymmetry(&t, true);
        let ax = asymmetry(&t, false);
        eprintln!("coma asymmetry: y {ay:.3}, x {ax:.2e}");
        assert!(ay > 0.05, "PSF y-asymmetry {ay}");
        assert!(ax < 1e-9, "PSF x-asymmetry {ax}");
        assert!(t.strehl() < 0.97);
    }
}

#[test]
fn astigmatism_tangential_and_sagittal_are_defocus_curves() {
    // W222 y² (φ from +y): along the tangential axis the pupil phase difference of a shift
    // s is 2 W222 y s, that of a defocus W020 = W222; along the sagittal axis the wavefront
    // is constant, so the OTF is the diffraction one. With a defocus W020 = −W222/2 (medial
    // focus) the wavefront is (W222/2)(y² − x²): the two sections are the defocus OTFs of
    // +W222/2 and −W222/2, equal since the defocus OTF is even in W020.
    let w222 = 0.5;
    let t = transfer(
        &Pupil::clear(),
        &seidel(Seidel {
            w222,
            ..Seidel::default()
        }),
        256,
        2,
    );
    let mut gap: f64 = 0.0;
    for ((x, tv), (_, sv)) in axis(&t, true).into_iter().zip(axis(&t, false)) {
        assert!((tv.re - defocus_exact(x, w222)).abs() < 2e-3, "T at {x}");
        assert!(
            (sv.re - optics::diffraction_clear(x)).abs() < 2e-3,
            "S at {x}"
        );
        gap = gap.max((t.tangential_mtf(x) - t.sagittal_mtf(x)).abs());
    }
    assert!(gap > 0.2, "T and S should differ: {gap}");
    let medial = Seidel {
        w222,
        w020: -w222 / 2.0,
        ..Seidel::default()
    };
    let t = transfer(&Pupil::clear(), &seidel(medial), 256, 2);
    for ((x, tv), (_, sv)) in axis(&t, true).into_iter().zip(axis(&t, false)) {
        let want = defocus_exact(x, w222 / 2.0);
        assert!((tv.re - want).abs() < 2e-3, "T at {x}");
        assert!((sv.re - want).abs() < 2e-3, "S at {x}");
    }
}

#[test]
fn spider_vanes_conserve_energy_and_make_spikes_across_the_vanes() {
    let (r, width, n) = (0.3, 0.02, 256);
    let base = Pupil::obscured(r).unwrap();
    let spider = base.clone().with_spider(3, width, PI / 2.0).unwrap();
    let zero = LocalWavefront::default();
    let t0 = transfer(&base, &zero, n, 2);
    let t = transfer(&spider, &zero, n, 2);
    // Energy: the transmitting area equals the annulus less three vanes of width w·D from
    // the obscuration to the rim (in samples; the pixelated edge makes ≲ 0.5 %).
    let a = n as f64 / 2.0;
    let area = PI * a * a * (1.0 - r * r) - 3.0 * (width * n as f64) * a * (1.0 - r);
    assert!(
        (t.pupil_energy() / area - 1.0).abs() < 5e-3,
        "{} vs {area}",
        t.pupil_energy()
    );
    assert!((t.psf().sum() - 1.0).abs() < 1e-12);
    assert!((t.otf_grid()[(n, n)].re - 1.0).abs() < 1e-12);
    // Spikes: the light the vanes add, in 10° sectors of the annulus 6–40 λ/D, peaks
    // perpendicular to each vane: vanes at 90°, 210°, 330° give six spikes at 0°, 60°, …
    let m = t.psf().nrows();
    let h = (m / 2) as f64;
    let per = D / LAMBDA * t.psf_sample_rad(); // λ/D per sample = 1/per
    let mut sector = [0.0f64; 36];
    for ((rr, cc), &v) in t.psf().indexed_iter() {
        let (x, y) = ((cc as f64 - h) * per, (rr as f64 - h) * per);
        let rho = x.hypot(y);
        if (6.0..40.0).contains(&rho) {
            let ang = y.atan2(x).to_degrees().rem_euclid(360.0);
            let k = ((ang + 5.0) / 10.0).floor() as usize % 36;
            sector[k] += (v - t0.psf()[(rr, cc)]).max(0.0);
        }
    }
    for k in 0..6 {
        let spike = sector[6 * k];
        let between = sector[6 * k + 3];
        eprintln!("spike {}°: {spike:.2e}, between: {between:.2e}", 60 * k);
        assert!(
            spike > 10.0 * between,
            "{}°: {spike:.2e} vs {between:.2e}",
            60 * k
        );
    }
}

/// Gauss–Legendre nodes and weights on [−1, 1] (Newton's method on the Legendre
/// recurrence; Abramowitz & Stegun 25.4.29).
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (1..=n)
        .map(|i| {
            let mut x = (PI * (i as f64 - 0.25) / (n as f64 + 0.5)).cos();
            let mut dp = 1.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let k = k as f64;
                    (p0, p1) = (p1, ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k);
                }
                dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-15 {
                    break;
                }
            }
            (x, 2.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

/// The OTF at normalised frequency X along the tangential (y) or sagittal (x) axis by
/// direct quadrature of the overlap integral of the shifted pupils (Goodman §6.4.1;
/// Hopkins 1955): `(1/π) ∬ exp(2πi [W(r + s/2) − W(r − s/2)]) d²r` over the lens where
/// the unit discs centred at ±s/2 overlap, |s| = 2X in units of the radius. The outer
/// variable runs across the lens (|u| ≤ 1 − X, split at 0 where the chord's half-width
/// `√(1 − (|u| + X)²)` has a kink) with u = (1 − X) sin θ, which removes the square-root
/// ends; 48 Gauss–Legendre points in θ on each half and 48 along each chord (converged
/// to 1e-5).
fn overlap_otf(w: &LocalWavefront, x: f64, tangential: bool) -> num_complex::Complex64 {
    let gl = gauss_legendre(48);
    let mut total = num_complex::Complex64::new(0.0, 0.0);
    for sign in [1.0, -1.0] {
        for &(t, wt) in &gl {
            let theta = (t + 1.0) * PI / 4.0;
            let u = sign * (1.0 - x) * theta.sin();
            let du = (1.0 - x) * theta.cos() * wt * PI / 4.0;
            let b = (1.0 - (u.abs() + x).powi(2)).max(0.0).sqrt();
            for &(v0, wv) in &gl {
                let v = v0 * b;
                let d = if tangential {
                    w.waves(v, u + x) - w.waves(v, u - x)
                } else {
                    w.waves(u + x, v) - w.waves(u - x, v)
                };
                total += num_complex::Complex64::from_polar(wv * b * du, 2.0 * PI * d);
            }
        }
    }
    total / PI
}

#[test]
fn coma_tangential_and_sagittal_mtfs_match_the_overlap_integral() {
    // Seidel coma W131 = 1 wave, and the Zernike coma Z7 = √8(3ρ³ − 2ρ) sin θ with the
    // same ρ³ term (c = 1/(3√8)): its −2ρ part is a tilt, which changes the OTF's phase
    // only, so both have the same MTFs. Coma blurs more along the field (T) than across
    // it (S); the differences are 0.09–0.18 at these frequencies.
    let cases = [
        seidel(Seidel {
            w131: 1.0,
            ..Seidel::default()
        }),
        LocalWavefront {
            seidel: Seidel::default(),
            zernike_rms_waves: vec![0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0 / (3.0 * 8f64.sqrt())],
        },
    ];
    let seidel_coma = cases[0].clone();
    for w in &cases {
        let t = transfer(&Pupil::clear(), w, 256, 2);
        for x in [0.125, 0.25, 0.375, 0.5] {
            let (tq, sq) = (
                overlap_otf(&seidel_coma, x, true).norm(),
                overlap_otf(&seidel_coma, x, false).norm(),
            );
            let (tp, sp) = (t.tangential_mtf(x), t.sagittal_mtf(x));
            let (gap_q, gap_p) = (sq - tq, sp - tp);
            eprintln!(
                "coma X = {x}: T {tp:.4} (quadrature {tq:.4}), S {sp:.4} ({sq:.4}); S − T {gap_p:.4} ({gap_q:.4})"
            );
            assert!(gap_q > 0.05, "S − T at {x}: {gap_q}");
            assert!(
                (gap_p - gap_q).abs() <= 0.02 * gap_q,
                "X = {x}: S − T {gap_p} vs {gap_q}"
            );
            assert!((tp - tq).abs() < 2e-3 && (sp - sq).abs() < 2e-3, "X = {x}");
        }
    }
}
