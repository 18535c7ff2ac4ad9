//! Tests for `eoir::optics`. Every analytic transfer function is compared against truth
//! obtained another way: FFT autocorrelation of a sampled (annular, optionally defocused)
//! pupil, quadrature of the exact defocus OTF integral, numerical integration of the pixel
//! aperture, and hand computations.

use std::f64::consts::PI;
use std::io::Write;
use std::sync::Arc;

use eoir::optics::{
    aberration_shannon, cutoff_cy_per_rad, defocus, defocus_w020_from_focus_shift,
    detector_footprint, diffraction_clear, diffraction_obscured, sinc, MeasuredMtf,
};
use eoir::Error;
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};

// ---------------------------------------------------------------------------------------
// Numerical pupil autocorrelation (independent route to the diffraction OTF)
// ---------------------------------------------------------------------------------------

/// FFT grid size (zero padded: the autocorrelation support, 2 × PUPIL_DIAMETER, fits).
const GRID: usize = 2048;
/// Pupil diameter in samples; a shift of k samples is X = k / PUPIL_DIAMETER.
const PUPIL_DIAMETER: usize = 1000;
/// Sub-samples per axis used to weight rim pixels by their area inside the annulus.
const SUPERSAMPLE: usize = 16;

/// Forward and inverse complex FFT plans of length GRID with shared scratch space.
struct Fft2 {
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
    scratch: Vec<Complex<f64>>,
    tmp: Vec<Complex<f64>>,
}

impl Fft2 {
    fn new() -> Self {
        let mut planner = FftPlanner::new();
        let forward = planner.plan_fft_forward(GRID);
        let inverse = planner.plan_fft_inverse(GRID);
        let scratch_len = forward
            .get_inplace_scratch_len()
            .max(inverse.get_inplace_scratch_len());
        Fft2 {
            forward,
            inverse,
            scratch: vec![Complex::new(0.0, 0.0); scratch_len],
            tmp: vec![Complex::new(0.0, 0.0); GRID * GRID],
        }
    }

    /// 2-D transform of a GRID × GRID array: rows, transpose, rows, transpose back.
    fn transform(&mut self, data: &mut [Complex<f64>], inverse: bool) {
        let plan = if inverse {
            &self.inverse
        } else {
            &self.forward
        };
        for _ in 0..2 {
            plan.process_with_scratch(data, &mut self.scratch);
            transpose::transpose(data, &mut self.tmp, GRID, GRID);
            data.copy_from_slice(&self.tmp);
        }
    }

    /// Autocorrelation Σ_r P(r + s) P*(r) of a sampled pupil via |FFT|², returned along
    /// the row axis for shifts s = 0 … GRID/2 and divided by the pupil AREA (Σ of the
    /// area-fraction weights). The area, not the zero-shift value Σ|P|², is the right
    /// normaliser: rim pixels with fractional weight w contribute w² at zero shift but ≈ w
    /// once the shift exceeds a pixel, so Σ|P|² would bias every X > 0 by ~1e-3.
    fn autocorrelation_row(&mut self, pupil: SampledPupil) -> Vec<Complex<f64>> {
        let SampledPupil { mut field, area } = pupil;
        self.transform(&mut field, false);
        for z in field.iter_mut() {
            *z = Complex::new(z.norm_sqr(), 0.0);
        }
        self.transform(&mut field, true);
        // rustfft does not normalise: forward + inverse 2-D scales by GRID².
        let scale = (GRID * GRID) as f64 * area;
        field[..=GRID / 2].iter().map(|z| z / scale).collect()
    }
}

/// A sampled complex pupil on the GRID × GRID array and its area in samples.
struct SampledPupil {
    field: Vec<Complex<f64>>,
    area: f64,
}

/// A sampled annular pupil of outer diameter PUPIL_DIAMETER samples and obscuration ratio
/// `r`, centred at a pixel corner of the GRID × GRID array, with defocus phase
/// exp(i 2π W020 ρ²) (ρ normalised to the outer radius). Rim pixels carry the mean of the
/// complex pupil over their SUPERSAMPLE² sub-samples inside the annulus, i.e. they are
/// weighted by the fraction of their area inside.
fn annular_pupil(r: f64, w020_waves: f64) -> SampledPupil {
    let outer = PUPIL_DIAMETER as f64 / 2.0;
    let inner = r * outer;
    let centre = (GRID / 2) as f64;
    let field = |rho: f64| {
        let phase = 2.0 * PI * w020_waves * (rho / outer).powi(2);
        Complex::new(phase.cos(), phase.sin())
    };
    // A pixel whose centre is farther than this from a circle lies entirely on one side.
    let half_diag = 0.75;
    let mut pupil = vec![Complex::new(0.0, 0.0); GRID * GRID];
    let mut area = 0.0;
    let lo = GRID / 2 - PUPIL_DIAMETER / 2 - 2;
    let hi = GRID / 2 + PUPIL_DIAMETER / 2 + 2;
    for i in lo..hi {
        for j in lo..hi {
            let y = i as f64 + 0.5 - centre;
            let x = j as f64 + 0.5 - centre;
            let rho = x.hypot(y);
            if rho - half_diag > outer || rho + half_diag < inner {
                continue;
            }
            let fully_inside = rho + half_diag < outer && (r == 0.0 || rho - half_diag > inner);
            pupil[i * GRID + j] = if fully_inside {
                area += 1.0;
                field(rho)
            } else {
                let mut sum = Complex::new(0.0, 0.0);
                let mut inside = 0usize;
                for a in 0..SUPERSAMPLE {
                    for b in 0..SUPERSAMPLE {
                        let ys = y + (a as f64 + 0.5) / SUPERSAMPLE as f64 - 0.5;
                        let xs = x + (b as f64 + 0.5) / SUPERSAMPLE as f64 - 0.5;
                        let rs = xs.hypot(ys);
                        if rs <= outer && rs >= inner {
                            sum += field(rs);
                            inside += 1;
                        }
                    }
                }
                let n_sub = (SUPERSAMPLE * SUPERSAMPLE) as f64;
                area += inside as f64 / n_sub;
                sum / n_sub
            };
        }
    }
    SampledPupil { field: pupil, area }
}

/// Integer shifts (samples) at which to compare: 20 evenly spread values plus points on
/// both sides of the branch boundaries of §4.3 (X = R, (1−R)/2, (1+R)/2).
fn comparison_shifts(r: f64) -> Vec<usize> {
    let d = PUPIL_DIAMETER as f64;
    let mut shifts: Vec<usize> = (0..20).map(|m| 25 + 50 * m).collect();
    for edge in [r, 0.5 * (1.0 - r), 0.5 * (1.0 + r)] {
        let k = (edge * d).round() as i64;
        for dk in [-7, -1, 0, 1, 7] {
            let s = k + dk;
            if s > 0 && s < PUPIL_DIAMETER as i64 {
                shifts.push(s as usize);
            }
        }
    }
    shifts.push(PUPIL_DIAMETER - 3);
    shifts
}

#[test]
fn obscured_and_clear_match_numerical_pupil_autocorrelation() {
    let mut fft = Fft2::new();
    let mut worst = 0.0_f64;
    for r in [0.0, 0.1, 0.25, 0.33, 0.5, 0.7] {
        let acf = fft.autocorrelation_row(annular_pupil(r, 0.0));
        for k in comparison_shifts(r) {
            let x = k as f64 / PUPIL_DIAMETER as f64;
            let numeric = acf[k].re;
            let analytic = diffraction_obscured(x, r);
            let err = (analytic - numeric).abs();
            worst = worst.max(err);
            assert!(
                err < 1e-3,
                "R = {r}, X = {x}: analytic {analytic}, numerical autocorrelation {numeric}"
            );
            if r == 0.0 {
                let clear = diffraction_clear(x);
                assert!(
                    (clear - numeric).abs() < 1e-3,
                    "clear aperture, X = {x}: analytic {clear}, numerical {numeric}"
                );
            }
        }
        // Beyond the cutoff the autocorrelation of the sampled pupil is (numerically) zero.
        let beyond = acf[PUPIL_DIAMETER + 2].re;
        assert!(beyond.abs() < 1e-9, "R = {r}: ACF beyond cutoff {beyond}");
        assert_eq!(diffraction_obscured(1.002, r), 0.0);
    }
    eprintln!("worst |analytic - autocorrelation| = {worst:.2e}");
}

#[test]
fn obscured_is_never_negative_and_reduces_to_clear_at_r0() {
    for ir in 0..=19 {
        let r = ir as f64 * 0.05;
        for ix in 0..=11_000 {
            let x = ix as f64 * 1e-4;
            let v = diffraction_obscured(x, r);
            assert!(v.is_finite() && v >= 0.0, "R = {r}, X = {x}: {v}");
            assert!(v <= 1.0 + 1e-12, "R = {r}, X = {x}: {v} > 1");
            // Even in frequency.
            assert_eq!(v, diffraction_obscured(-x, r));
        }
        assert!((diffraction_obscured(0.0, r) - 1.0).abs() < 1e-12);
    }
    for ix in 0..=11_000 {
        let x = ix as f64 * 1e-4;
        assert_eq!(diffraction_obscured(x, 0.0), diffraction_clear(x));
    }
}

#[test]
fn clear_aperture_limits() {
    assert_eq!(diffraction_clear(0.0), 1.0);
    assert_eq!(diffraction_clear(1.0), 0.0);
    assert_eq!(diffraction_clear(1.5), 0.0);
    assert_eq!(diffraction_clear(-0.3), diffraction_clear(0.3));
    // X = ½: 2/π [π/3 − (½)(√3/2)] = 2/3 − √3/(2π) (hand computation).
    let half = 2.0 / 3.0 - 3f64.sqrt() / (2.0 * PI);
    assert!((diffraction_clear(0.5) - half).abs() < 1e-15);
    // Near the cutoff the OTF vanishes as (8√2 / 3π)(1 − X)^{3/2} (series of acos and √).
    let e: f64 = 1e-6;
    let asym = 8.0 * 2f64.sqrt() / (3.0 * PI) * e.powf(1.5);
    assert!((diffraction_clear(1.0 - e) / asym - 1.0).abs() < 1e-5);
    // No negative round-off right at the cutoff (the largest doubles below 1).
    for k in 1..10_000 {
        let x = 1.0 - k as f64 * f64::EPSILON / 2.0;
        assert!(
            diffraction_clear(x) >= 0.0,
            "X = {x}: {}",
            diffraction_clear(x)
        );
        assert!(diffraction_obscured(x, 0.4) >= 0.0);
    }
}

#[test]
fn cutoff_frequency() {
    // D = 100 mm, λ = 4 µm: f_c = 0.1 / 4e-6 = 25 000 cycles/rad = 25 cycles/mrad.
    let fc = cutoff_cy_per_rad(0.1, 4e-6);
    assert!((fc - 25_000.0).abs() < 1e-9);
    // Image-plane cutoff 1/(λN): focal length 200 mm → N = 2, 1/(4e-6 · 2) = 125 000 /m,
    // and angular / focal length = 25 000 / 0.2 = 125 000 /m.
    assert!((fc / 0.2 - 1.0 / (4e-6 * 2.0)).abs() < 1e-6);
}

// ---------------------------------------------------------------------------------------
// Defocus
// ---------------------------------------------------------------------------------------

/// Exact defocused OTF of a clear circular pupil (docs/design.md §4.4):
/// (4/π) ∫₀^{acos X} sin²φ · cos(8π W020 X (cos φ − X)) dφ, composite Simpson, 4000
/// intervals.
fn defocus_otf_exact(x: f64, w020: f64) -> f64 {
    let upper = x.acos();
    let n = 4000;
    let h = upper / n as f64;
    let g = |phi: f64| phi.sin().powi(2) * (8.0 * PI * w020 * x * (phi.cos() - x)).cos();
    let mut sum = g(0.0) + g(upper);
    for i in 1..n {
        let w = if i % 2 == 1 { 4.0 } else { 2.0 };
        sum += w * g(i as f64 * h);
    }
    4.0 / PI * sum * h / 3.0
}

#[test]
fn defocus_product_matches_exact_integral() {
    for w020 in [0.25, 0.5, 1.0, 2.0] {
        let mut worst = 0.0_f64;
        for i in 0..=200 {
            let x = i as f64 / 200.0;
            let exact = if x >= 1.0 {
                0.0
            } else {
                defocus_otf_exact(x, w020)
            };
            let approx = diffraction_clear(x) * defocus(x, w020);
            let err = (approx - exact).abs();
            worst = worst.max(err);
            assert!(
                err < 0.02,
                "W020 = {w020}, X = {x}: 2J1(a)/a product {approx}, exact {exact}"
            );
        }
        eprintln!("W020 = {w020}: worst |product - exact| = {worst:.4}");
    }
}

#[test]
fn defocus_zero_is_clear_aperture() {
    for i in 0..=1000 {
        let x = i as f64 / 1000.0;
        assert_eq!(defocus(x, 0.0), 1.0);
        assert_eq!(diffraction_clear(x) * defocus(x, 0.0), diffraction_clear(x));
        // The exact integral at W020 = 0 is the clear aperture too (checks the reference).
        if x < 1.0 {
            assert!((defocus_otf_exact(x, 0.0) - diffraction_clear(x)).abs() < 1e-9);
        }
    }
    // 1 at both ends of the passband; even in X and in W020.
    assert_eq!(defocus(0.0, 1.3), 1.0);
    assert_eq!(defocus(1.0, 1.3), 1.0);
    assert_eq!(defocus(0.3, 1.3), defocus(-0.3, 1.3));
    assert_eq!(defocus(0.3, 1.3), defocus(0.3, -1.3));
    // W020 = 1 at X = ½: a = 2π, 2 J1(2π)/(2π) with J1(2π) = −0.2123... (hand value
    // 2·(−0.21238253)/(2π) = −0.067603); checks the sign (contrast reversal).
    assert!((defocus(0.5, 1.0) - (-0.0676036)).abs() < 1e-6);
    assert_eq!(defocus(1.2, 0.5), 0.0);
}

#[test]
fn defocused_pupil_autocorrelation_matches_exact_integral() {
    // Stronger, fully independent check of the reference integral itself: FFT
    // autocorrelation of a pupil carrying the quadratic phase 2π W020 ρ².
    let mut fft = Fft2::new();
    for w020 in [0.5, 1.0] {
        let acf = fft.autocorrelation_row(annular_pupil(0.0, w020));
        for k in (25..PUPIL_DIAMETER).step_by(50) {
            let x = k as f64 / PUPIL_DIAMETER as f64;
            let exact = defocus_otf_exact(x, w020);
            assert!(
                (acf[k].re - exact).abs() < 2e-3,
                "W020 = {w020}, X = {x}: autocorrelation {}, integral {exact}",
                acf[k].re
            );
            assert!(acf[k].im.abs() < 1e-6, "defocus OTF should be real");
            let approx = diffraction_clear(x) * defocus(x, w020);
            assert!((approx - acf[k].re).abs() < 0.02);
        }
    }
}

#[test]
fn w020_from_focus_shift_hand_computation() {
    // δz = 100 µm, N = 2, λ = 4 µm:
    // W020 = δz / (8 N² λ) = 100e-6 / (8 · 4 · 4e-6) = 100e-6 / 128e-6 = 0.78125 waves.
    let w = defocus_w020_from_focus_shift(100e-6, 2.0, 4e-6);
    assert!((w - 0.78125).abs() < 1e-12, "{w}");
    // Geometric route: the marginal ray has slope 1/(2N); a focus shift δz changes the
    // optical path at the pupil edge by δz·(1 − cos θ) ≈ δz·sin²θ/2 = δz/(8N²) for small θ.
    let theta = (1.0 / (2.0 * 8.0_f64)).atan(); // F/8: paraxial enough
    let opd = 100e-6 * (1.0 - theta.cos());
    let w_geo = opd / 4e-6;
    let w_f8 = defocus_w020_from_focus_shift(100e-6, 8.0, 4e-6);
    assert!((w_geo / w_f8 - 1.0).abs() < 0.01, "{w_geo} vs {w_f8}");
}

// ---------------------------------------------------------------------------------------
// Aberration (Shannon)
// ---------------------------------------------------------------------------------------

#[test]
fn shannon_aberration_shape() {
    for w in [0.02, 0.05, 0.1, 0.15] {
        assert!((aberration_shannon(0.0, w) - 1.0).abs() < 1e-15);
        assert!((aberration_shannon(1.0, w) - 1.0).abs() < 1e-15);
        // Locate the minimum on a grid independently of the formula's algebra.
        let (mut xmin, mut vmin) = (0.0, f64::INFINITY);
        for i in 0..=1000 {
            let x = i as f64 / 1000.0;
            let v = aberration_shannon(x, w);
            assert!((0.0..=1.0).contains(&v));
            if v < vmin {
                (xmin, vmin) = (x, v);
            }
        }
        assert!((xmin - 0.5).abs() < 1e-9, "min at {xmin}");
        assert!((vmin - (1.0 - (w / 0.18f64).powi(2))).abs() < 1e-12);
        assert_eq!(aberration_shannon(-0.3, w), aberration_shannon(0.3, w));
    }
    // Perfect optics: factor 1 across the passband.
    assert_eq!(aberration_shannon(0.37, 0.0), 1.0);
    // Strong aberration: 1 − (0.2/0.18)² < 0 is clipped at 0 around X = ½.
    assert_eq!(aberration_shannon(0.5, 0.2), 0.0);
    for i in 0..=1000 {
        assert!(aberration_shannon(i as f64 / 1000.0, 0.3) >= 0.0);
    }
    // Beyond the cutoff: documented as 0.
    assert_eq!(aberration_shannon(1.01, 0.05), 0.0);
}

// ---------------------------------------------------------------------------------------
// sinc and detector footprint
// ---------------------------------------------------------------------------------------

#[test]
fn sinc_values() {
    assert_eq!(sinc(0.0), 1.0);
    for n in 1..=50 {
        assert!(
            sinc(n as f64).abs() < 1e-15,
            "sinc({n}) = {}",
            sinc(n as f64)
        );
        assert!(sinc(-(n as f64)).abs() < 1e-15);
    }
    assert!((sinc(0.5) - 2.0 / PI).abs() < 1e-15);
    assert!((sinc(1.5) + 2.0 / (3.0 * PI)).abs() < 1e-15);
    // Small argument: series 1 − (πx)²/6.
    let x = 1e-5;
    assert!((sinc(x) - (1.0 - (PI * x).powi(2) / 6.0)).abs() < 1e-15);
}

#[test]
fn detector_footprint_at_nyquist_and_against_box_integral() {
    let pitch = 15e-6;
    let fl = 0.1;
    // Detector Nyquist, cycles/rad: fl / (2 pitch); 100 % fill → sinc(½) = 2/π.
    let f_nyq = fl / (2.0 * pitch);
    let v = detector_footprint(f_nyq, 0.0, pitch, pitch, fl);
    assert!((v - 2.0 / PI).abs() < 1e-12, "{v}");
    let v2 = detector_footprint(f_nyq, f_nyq, pitch, pitch, fl);
    assert!((v2 - 4.0 / (PI * PI)).abs() < 1e-12);
    assert_eq!(
        detector_footprint(-f_nyq, 0.0, pitch, pitch, fl),
        detector_footprint(f_nyq, 0.0, pitch, pitch, fl)
    );

    // Independent route: the transfer function of a uniform active area of width w is the
    // mean of cos(2π ξ u) over the area, ξ = f / fl the image-plane frequency. Midpoint rule.
    let (wx, wy) = (12e-6, 9e-6); // 80 % and 60 % fill along x and y
    let box_tf = |f: f64, w: f64| {
        let n = 20_000;
        let xi = f / fl;
        (0..n)
            .map(|i| {
                let u = (-0.5 + (i as f64 + 0.5) / n as f64) * w;
                (2.0 * PI * xi * u).cos()
            })
            .sum::<f64>()
            / n as f64
    };
    for (fx, fy) in [(0.3, 0.1), (1.0, 0.7), (1.7, 2.3), (2.6, 0.0)] {
        let (fx, fy) = (fx * f_nyq, fy * f_nyq);
        let expect = box_tf(fx, wx) * box_tf(fy, wy);
        let got = detector_footprint(fx, fy, wx, wy, fl);
        assert!(
            (got - expect).abs() < 1e-7,
            "({fx}, {fy}): {got} vs {expect}"
        );
    }
    // A negative lobe beyond the first zero (contrast reversal is kept, signed).
    assert!(detector_footprint(1.5 * fl / wx, 0.0, wx, wy, fl) < 0.0);
}

// ---------------------------------------------------------------------------------------
// Measured MTF
// ---------------------------------------------------------------------------------------

#[test]
fn measured_mtf_interpolates_and_normalises() {
    let m = MeasuredMtf::new(vec![0.0, 10.0, 20.0, 40.0], vec![0.8, 0.4, 0.2, 0.08]).unwrap();
    for (got, want) in m.mtf().iter().zip([1.0, 0.5, 0.25, 0.1]) {
        assert!((got - want).abs() < 1e-15, "{got} vs {want}");
    }
    assert_eq!(m.freq_cy_per_mrad(), &[0.0, 10.0, 20.0, 40.0]);
    // 1 cycle/mrad = 1000 cycles/rad.
    assert_eq!(m.eval(0.0), 1.0);
    assert!((m.eval(5_000.0) - 0.75).abs() < 1e-12);
    assert!((m.eval(10_000.0) - 0.5).abs() < 1e-12);
    assert!((m.eval(15_000.0) - 0.375).abs() < 1e-12);
    assert!((m.eval(30_000.0) - 0.175).abs() < 1e-12);
    assert!((m.eval(-15_000.0) - 0.375).abs() < 1e-12);
    assert!((m.eval(40_000.0) - 0.1).abs() < 1e-12);
    // Beyond the table: 0.
    assert_eq!(m.eval(40_000.001), 0.0);
    assert_eq!(m.eval(1e9), 0.0);
    assert_eq!(m.eval(f64::NAN), 0.0);
}

fn param_field(e: Error) -> String {
    match e {
        Error::InvalidParameter { field, .. } => field,
        other => panic!("expected InvalidParameter, got {other}"),
    }
}

#[test]
fn measured_mtf_rejects_bad_tables() {
    let bad = |f: Vec<f64>, m: Vec<f64>| param_field(MeasuredMtf::new(f, m).unwrap_err());
    assert_eq!(bad(vec![1.0, 2.0], vec![1.0, 0.5]), "freq_cy_per_mrad[0]");
    assert_eq!(
        bad(vec![0.0, 2.0, 2.0], vec![1.0, 0.5, 0.4]),
        "freq_cy_per_mrad[2]"
    );
    assert_eq!(
        bad(vec![0.0, 2.0, 1.0], vec![1.0, 0.5, 0.4]),
        "freq_cy_per_mrad[2]"
    );
    assert_eq!(
        bad(vec![0.0, f64::NAN], vec![1.0, 0.5]),
        "freq_cy_per_mrad[1]"
    );
    assert_eq!(bad(vec![0.0, 1.0], vec![1.0, 1.6]), "mtf[1]");
    assert_eq!(bad(vec![0.0, 1.0], vec![1.0, -0.1]), "mtf[1]");
    assert_eq!(bad(vec![0.0, 1.0], vec![f64::INFINITY, 0.5]), "mtf[0]");
    assert_eq!(bad(vec![0.0, 1.0], vec![0.0, 0.0]), "mtf[0]");
    assert_eq!(bad(vec![0.0], vec![1.0]), "freq_cy_per_mrad");
    assert_eq!(bad(vec![0.0, 1.0], vec![1.0]), "mtf");
    // Overshoot up to 1.5 is accepted (and normalised).
    let m = MeasuredMtf::new(vec![0.0, 1.0, 2.0], vec![1.0, 1.2, 0.3]).unwrap();
    assert!((m.eval(1_000.0) - 1.2).abs() < 1e-12);
}

fn write_temp(content: &str) -> tempfile::NamedTempFile {
    let mut f = tempfile::Builder::new().suffix(".csv").tempfile().unwrap();
    f.write_all(content.as_bytes()).unwrap();
    f.flush().unwrap();
    f
}

#[test]
fn measured_mtf_from_csv_formats() {
    let content = "\u{feff}# lens MTF, measured on axis\r\n\
                   freq_cy_per_mrad, MTF\r\n\
                   \r\n\
                   0, 0.9   # DC\r\n\
                   10;0.45\r\n\
                   20\t0.18\r\n\
                   \t 40    0.09 \r\n\
                   # end\r\n";
    let f = write_temp(content);
    let m = MeasuredMtf::from_csv(f.path()).unwrap();
    let expected =
        MeasuredMtf::new(vec![0.0, 10.0, 20.0, 40.0], vec![0.9, 0.45, 0.18, 0.09]).unwrap();
    assert_eq!(m, expected);
    assert!((m.eval(30_000.0) - 0.15).abs() < 1e-12);
    // No header at all is fine too.
    let f = write_temp("0 1\n5 0.5\n");
    assert_eq!(
        MeasuredMtf::from_csv(f.path()).unwrap().mtf(),
        &[1.0, 0.5][..]
    );
}

fn format_message(e: Error) -> String {
    match e {
        Error::Format { path, message } => format!("{}: {message}", path.display()),
        other => panic!("expected Format error, got {other}"),
    }
}

#[test]
fn measured_mtf_csv_errors_name_file_and_line() {
    // (content, expected line tag, text expected in the message, file text that must not
    // be shown: the table may be a file that is not meant to be printed)
    let cases: &[(&str, &str, &str, &str)] = &[
        (
            "f,mtf\n0,1\n10,0.5\n20,abc\n",
            "line 4, column 2:",
            "expected a number",
            "abc",
        ),
        (
            "f,mtf\n0,1\n10,0.5,7\n",
            "line 3:",
            "expected 2 columns",
            "0.5,7",
        ),
        (
            "f,mtf\n0,1\nfreq,mtf\n",
            "line 3, column 1:",
            "expected a number",
            "freq,mtf",
        ),
        (
            "# c\nf,mtf\n\n0,1\n10,0.5\n10,0.4\n",
            "line 6:",
            "expected",
            "10,0.4",
        ),
        ("f,mtf\n1,1\n10,0.5\n", "line 2:", "expected", "1,1"),
        ("f,mtf\n0,1\n10,1.7\n", "line 3:", "expected", "10,1.7"),
        ("f,mtf\n0,0\n10,0.5\n", "line 2:", "expected", "0,0"),
        ("f,mtf\n0,1\n10,-0.5\n", "line 3:", "expected", "10,-0.5"),
        ("f,mtf\n0;1\n", "1 data rows", "at least 2", "0;1"),
        ("# empty\n", "0 data rows", "at least 2", "# empty"),
    ];
    for (content, line_tag, text, hidden) in cases {
        let f = write_temp(content);
        let msg = format_message(MeasuredMtf::from_csv(f.path()).unwrap_err());
        let name = f.path().file_name().unwrap().to_string_lossy().to_string();
        assert!(msg.contains(&name), "no file name in: {msg}");
        assert!(msg.contains(line_tag), "no `{line_tag}` in: {msg}");
        assert!(msg.contains(text), "no `{text}` in: {msg}");
        assert!(
            !msg.contains(hidden),
            "the file's text `{hidden}` in: {msg}"
        );
    }
    // Missing file: an I/O error naming it.
    let missing = std::path::Path::new("/nonexistent/dir/mtf.csv");
    match MeasuredMtf::from_csv(missing).unwrap_err() {
        Error::Io { path, .. } => assert_eq!(path, missing),
        other => panic!("expected Io error, got {other}"),
    }
}

// ---------------------------------------------------------------------------------------
// Truth images: every transfer-function section can be switched off; defocus without an
// aperture term is the geometric blur disc
// ---------------------------------------------------------------------------------------

/// The transfer function of a uniform disc of radius `r` at frequency `nu` (same length
/// units), by quadrature of its 2-D Fourier transform along one axis:
/// `(2/(π r²)) ∫_{−r}^{r} √(r² − x²) cos(2π ν x) dx` (midpoint rule, 200 000 intervals in
/// x = r sin t to smooth the square-root ends).
fn disc_otf_numerical(r: f64, nu: f64) -> f64 {
    let n = 200_000;
    let h = PI / n as f64;
    let mut s = 0.0;
    for i in 0..n {
        let t = -PI / 2.0 + (i as f64 + 0.5) * h;
        // x = r sin t, dx = r cos t dt, √(r² − x²) = r cos t.
        let x = r * t.sin();
        s += r * t.cos() * (2.0 * PI * nu * x).cos() * r * t.cos() * h;
    }
    2.0 * s / (PI * r * r)
}

/// Defocus without diffraction is the geometric blur disc of radius 4NλW020: its transfer
/// function `2J1(8πW020 X)/(8πW020 X)` equals the Fourier transform of the uniform disc,
/// computed by quadrature (ν = X/(λN) with λN = 1, so r = 4·W020), within 1e-7, for
/// frequencies far beyond the aperture cutoff X = 1 too.
#[test]
fn geometric_defocus_is_the_blur_disc_transfer_function() {
    for w020 in [0.3, 1.0, 2.5] {
        for x in [0.05, 0.2, 0.5, 0.9, 1.0, 1.3, 2.0, 3.7] {
            let want = disc_otf_numerical(4.0 * w020, x);
            let got = eoir::optics::defocus_geometric(x, w020);
            assert!(
                (got - want).abs() < 1e-7,
                "W020 {w020}, X {x}: {got} vs {want}"
            );
        }
    }
}

fn test_sensor(extra: &[&str]) -> eoir::sensor::Sensor {
    let text = r#"
name = "t"
[optics]
focal_length_m = 0.1
f_number = 2.0
[filter]
kind = "top_hat"
lo_um = 4.5
hi_um = 5.0
[detector]
rows = 8
cols = 8
pitch_m = 24e-6
active_width_m = 20e-6
integration_time_s = 1e-3
quantum_efficiency = { kind = "ideal_qe", peak = 0.7, cutoff_um = 5.3 }
[aberration]
rms_waves = 0.05
[defocus]
w020_waves = 0.7
[motion]
smear_rad = 3e-5
[jitter]
sigma_rad = 1e-5
[gaussian]
sigma_rad = 2e-5
[turbulence]
path = "horizontal"
cn2 = 1e-14
range_m = 1000.0
[aerosol]
absorption_per_m = 1e-4
scattering_per_m = 2e-4
range_m = 1000.0
particle_radius_m = 1e-6
[measured]
freq_cy_per_mrad = [0.0, 10.0, 100.0]
mtf = [1.0, 0.9, 0.5]
"#;
    let o: Vec<String> = extra.iter().map(|s| s.to_string()).collect();
    let cfg =
        eoir::sensor::SensorConfig::from_toml_str(text, "t", std::path::PathBuf::from("."), &o)
            .unwrap();
    eoir::sensor::Sensor::build(&cfg).unwrap()
}

/// Every transfer-function section takes `enabled = false` (the detector footprint
/// `detector.footprint_enabled = false`): the component leaves the cascade, the others
/// keep their values, and with all of them off the system passes everything (1 at every
/// frequency: the unblurred reference of a run). Checked against the system built
/// without the section.
#[test]
fn every_transfer_function_can_be_switched_off() {
    use eoir::sensor::Component;
    let all = test_sensor(&[]);
    assert_eq!(all.otf().components().len(), Component::ALL.len());
    let keys = [
        (Component::Diffraction, "diffraction.enabled=false"),
        (Component::Aberration, "aberration.enabled=false"),
        (Component::Defocus, "defocus.enabled=false"),
        (Component::Detector, "detector.footprint_enabled=false"),
        (Component::Motion, "motion.enabled=false"),
        (Component::Jitter, "jitter.enabled=false"),
        (Component::Turbulence, "turbulence.enabled=false"),
        (Component::Aerosol, "aerosol.enabled=false"),
        (Component::Gaussian, "gaussian.enabled=false"),
        (Component::Measured, "measured.enabled=false"),
    ];
    for (c, key) in keys {
        let s = test_sensor(&[key]);
        assert!(!s.otf().components().contains(&c), "{key}");
        assert_eq!(
            s.otf().components().len(),
            Component::ALL.len() - 1,
            "{key}"
        );
        for (fx, fy) in [(1000.0, 0.0), (3000.0, -2000.0), (7000.0, 4000.0)] {
            let want: f64 = Component::ALL
                .iter()
                .filter(|o| **o != c)
                .map(|o| s.otf().component(*o, fx, fy, 4.7))
                .product();
            let got = s.otf().evaluate(fx, fy, 4.7);
            assert!((got - want).abs() < 1e-15, "{key}: {got} vs {want}");
            // The components left keep their values (defocus changes form when the
            // aperture terms go: checked below).
            for o in Component::ALL
                .iter()
                .filter(|o| **o != c && **o != Component::Defocus)
            {
                assert_eq!(
                    s.otf().component(*o, fx, fy, 4.7),
                    all.otf().component(*o, fx, fy, 4.7),
                    "{key}: {o:?}"
                );
            }
        }
        // The resolved configuration keeps the switch.
        let toml = s.to_toml_string().unwrap();
        assert!(toml.contains("enabled = false"), "{key}: {toml}");
    }
    let none: Vec<&str> = keys.iter().map(|k| k.1).collect();
    let s = test_sensor(&none);
    assert!(s.otf().components().is_empty());
    for (fx, fy) in [(0.0, 0.0), (5e3, 0.0), (2e4, 3e4)] {
        assert_eq!(s.otf().evaluate(fx, fy, 4.7), 1.0);
    }
}

/// Without diffraction and aberration the defocus component is the geometric blur disc
/// (no cutoff at D/λ: non-zero at X = 1.3, continuous through X = 1); with the aperture
/// terms it is Hopkins' factor, 0 beyond the cutoff.
#[test]
fn defocus_without_diffraction_rolls_off_instead_of_stopping() {
    use eoir::sensor::Component;
    let lambda = 4.7;
    let fc = 0.05 / (lambda * 1e-6);
    let geo = test_sensor(&["diffraction.enabled=false", "aberration.enabled=false"]);
    let with = test_sensor(&[]);
    for x in [0.3, 0.999_999, 1.0, 1.000_001, 1.3, 2.5] {
        let g = geo.otf().component(Component::Defocus, x * fc, 0.0, lambda);
        let want = eoir::optics::defocus_geometric(x, 0.7);
        assert!((g - want).abs() < 1e-12, "X {x}: {g} vs {want}");
        let h = with
            .otf()
            .component(Component::Defocus, x * fc, 0.0, lambda);
        if x > 1.0 {
            assert_eq!(h, 0.0, "X {x}");
        }
    }
    assert!(
        geo.otf()
            .component(Component::Defocus, 1.3 * fc, 0.0, lambda)
            .abs()
            > 1e-3
    );
}

/// `SensorConfig::unblurred` (the library's one switch for the truth image, `eoir run
/// --unblurred`) leaves no transfer function in the cascade and no `[optics.wavefront]`:
/// on the test sensor with every section present plus a wavefront, and on every preset
/// with every value of every option (the aberrated lenses carry a wavefront). The
/// unblurred system passes every frequency at 1; the radiometry is unchanged.
#[test]
fn unblurred_switches_every_transfer_function_and_the_wavefront_off() {
    let all = test_sensor(&[]);
    let mut cfg = all.config().clone();
    cfg.optics.wavefront =
        Some(toml::from_str("reference_wavelength_um = 4.0\nw040_waves = 0.1").unwrap());
    let u = eoir::sensor::Sensor::build(&cfg.unblurred()).unwrap();
    assert!(u.otf().components().is_empty());
    assert!(u.optics.wavefront.is_none());
    for (fx, fy) in [(1000.0, 0.0), (7000.0, 4000.0)] {
        assert_eq!(u.otf().evaluate(fx, fy, 4.7), 1.0);
    }
    assert_eq!(u.camera(), all.camera());
    let mut checked = 0;
    for p in eoir::sensor::presets::list() {
        let mut choices: Vec<Vec<String>> = vec![vec![]];
        for (name, values) in &p.options {
            choices = choices
                .iter()
                .flat_map(|c| {
                    values.iter().map(move |v| {
                        let mut c = c.clone();
                        c.push(format!("{name}={v}"));
                        c
                    })
                })
                .collect();
        }
        for opts in choices.iter().take(64) {
            let c = eoir::sensor::presets::load(&p.name, opts, &[]).unwrap();
            let u = eoir::sensor::Sensor::build(&c.unblurred()).unwrap();
            assert!(u.otf().components().is_empty(), "{} {opts:?}", p.name);
            assert!(u.optics.wavefront.is_none(), "{} {opts:?}", p.name);
            checked += 1;
        }
    }
    assert!(checked >= 6, "{checked}");
}
