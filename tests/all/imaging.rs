//! The imaging engine against independent truth: the camera equation, per-band blurring
//! with an independent complex FFT, wrap-around, and an analytic footprint-blurred image.

use std::path::PathBuf;

use ndarray::{Array2, Array3};
use num_complex::Complex64;
use rustfft::FftPlanner;

use eoir::imaging::fft::FftPrecision;
use eoir::imaging::{Imager, SpectralWeights, DEFAULT_WRAP_TOLERANCE};
use eoir::io::MemoryCube;
use eoir::radiometry::planck_spectral_radiance;
use eoir::scene::{Cube, CubeMeta, Geometry, RadianceUnits};
use eoir::sensor::{Sensor, SensorConfig};

const H: f64 = 6.626_070_15e-34;
const C: f64 = 299_792_458.0;

fn sensor(rows: usize, cols: usize, extra: &[&str]) -> Sensor {
    let text = format!(
        r#"
name = "test"
[optics]
focal_length_m = 0.1
f_number = 2.0
transmission = {{ kind = "constant", value = 0.9 }}
[filter]
kind = "top_hat"
lo_um = 4.55
hi_um = 5.2
edge_width_um = 0.05
peak = 0.85
[detector]
rows = {rows}
cols = {cols}
pitch_m = 24e-6
active_width_m = 20e-6
integration_time_s = 2.6e-3
quantum_efficiency = {{ kind = "ideal_qe", peak = 0.7, cutoff_um = 5.3 }}
"#
    );
    let o: Vec<String> = extra.iter().map(|s| s.to_string()).collect();
    Sensor::build(&SensorConfig::from_toml_str(&text, "test", PathBuf::from("."), &o).unwrap())
        .unwrap()
}

/// A cube whose scene sampling is `ifov_rad` per sample.
fn cube(data: Array3<f32>, wavelength_um: Vec<f64>, ifov_rad: f64) -> Cube {
    let (_, rows, cols) = data.dim();
    let meta = CubeMeta {
        wavelength_um,
        fwhm_um: None,
        units: RadianceUnits::SpectralPerUm,
        geometry: Some(Geometry::from_ifov(ifov_rad, ifov_rad, rows, cols)),
        rows,
        cols,
    };
    Cube::new(data, meta).unwrap()
}

fn grid(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| lo + (hi - lo) * i as f64 / (n - 1) as f64)
        .collect()
}

fn run(s: &Sensor, c: Cube, tol: f64) -> (Array2<f64>, Imager) {
    let g = c.meta.geometry.unwrap();
    let imager = Imager::new(s, &c.meta, &g, tol).unwrap();
    let mut reader = MemoryCube::new(c);
    let (e, _) = imager.mean_electrons(&mut reader, 0, |_, _| {}).unwrap();
    (e, imager)
}

/// A uniform 300 K blackbody through a blurred sensor: every pixel equals the camera
/// equation written out independently (aperture area × A_det / f² × t × trapezoid Σ) on
/// the same spectral sampling (1e-4: the trapezoid rule's own error at the filter edges
/// with ≥ 100 bands over the band), and the continuous band integral (the engine
/// integrates the response exactly against the linearly interpolated radiance: 1e-6).
#[test]
fn uniform_blackbody_matches_camera_equation_whatever_the_blur() {
    let s = sensor(
        12,
        16,
        &[
            "aberration.rms_waves=0.07",
            "defocus.w020_waves=0.5",
            "jitter.sigma_rad=4e-5",
            "motion.smear_rad=1e-4",
            "motion.direction_deg=20",
        ],
    );
    let wl = grid(4.45, 5.3, 150); // 0.0057 µm spacing: 114 bands within 4.55–5.2 µm
    let (rows, cols, k) = (24, 32, 2usize);
    let ifov = s.ifov_rad() / k as f64;
    let mut data = Array3::<f32>::zeros((wl.len(), rows, cols));
    for (b, l) in wl.iter().enumerate() {
        data.index_axis_mut(ndarray::Axis(0), b)
            .fill(planck_spectral_radiance(*l, 300.0) as f32);
    }
    let c = cube(data.clone(), wl.clone(), ifov);
    let (e, _) = run(&s, c, DEFAULT_WRAP_TOLERANCE);
    assert_eq!(e.dim(), (12, 16));

    // Independent: étendue from the aperture area, Σ over the same bands with trapezoid
    // widths written out here, radiance as stored (f32).
    let d_ap = 0.1 / 2.0;
    let etendue = std::f64::consts::PI * d_ap * d_ap / 4.0 * (20e-6 * 20e-6) / (0.1 * 0.1);
    let resp = Sensor::build(&s).unwrap().response().clone();
    let mut sum = 0.0;
    for (b, l) in wl.iter().enumerate() {
        let dl = if b == 0 {
            (wl[1] - wl[0]) / 2.0
        } else if b == wl.len() - 1 {
            (wl[b] - wl[b - 1]) / 2.0
        } else {
            (wl[b + 1] - wl[b - 1]) / 2.0
        };
        let rad = data[[b, 0, 0]] as f64;
        sum += resp.eval(*l) * rad * dl * (l * 1e-6) / (H * C);
    }
    let expected = etendue * 2.6e-3 * sum;
    let continuous = s.camera().electrons_blackbody(300.0, &resp).unwrap();
    for v in e.iter() {
        assert!(
            ((v - expected) / expected).abs() < 1e-4,
            "{v} vs {expected}"
        );
        assert!(
            ((v - continuous) / continuous).abs() < 1e-6,
            "{v} vs {continuous}"
        );
    }
    // Order of magnitude, by hand: L_λ(4.9 µm, 300 K) ≈ 3.3 W m-2 sr-1 µm-1 → ×λ/(hc) ≈
    // 8e19 photons s-1 m-2 sr-1 µm-1; × 0.65 µm × mean response ≈ 0.35 → 2e19; × étendue·t
    // = π/16 · (20 µm)² · 2.6 ms = 2.0e-13 m² sr s → ≈ 4e6 electrons.
    assert!(expected > 2e6 && expected < 8e6, "{expected}");
}

/// Test pattern, different per band.
fn pattern(bands: usize, rows: usize, cols: usize) -> Array3<f32> {
    Array3::from_shape_fn((bands, rows, cols), |(b, r, c)| {
        let x = c as f64 / cols as f64;
        let y = r as f64 / rows as f64;
        let v = 1.0
            + 0.5 * (7.0 * x + 3.0 * y + b as f64).sin()
            + 0.3 * ((13.0 + 2.0 * b as f64) * x * y).cos()
            + if (r / 5 + c / 7) % 3 == 0 { 0.4 } else { 0.0 };
        v as f32
    })
}

/// The frequency-domain sum equals blurring each band separately (a complex 2-D FFT per
/// band of the engine's padded frame, written here with rustfft) and summing with the
/// spectral weights.
#[test]
fn frequency_domain_sum_equals_per_band_blur() {
    let (rows, cols) = (20, 26);
    let s = sensor(
        rows,
        cols,
        &["aberration.rms_waves=0.05", "jitter.sigma_rad=5e-5"],
    );
    let wl = grid(4.5, 5.25, 6);
    let data = pattern(wl.len(), rows, cols);
    let c = cube(data.clone(), wl.clone(), s.ifov_rad());
    let (e, imager) = run(&s, c.clone(), DEFAULT_WRAP_TOLERANCE);
    let sy = imager.sampling().y;
    let sx = imager.sampling().x;
    let (ny, nx) = (sy.padded_len, sx.padded_len);
    let w = SpectralWeights::new(&s, &c.meta).unwrap();
    let otf = imager.otf();
    // The scene is sampled at the detector pitch, 20.8 cy/mm Nyquist, and the F/2 optics
    // pass 110 cy/mm: the engine tapers the OTF to 0 at the scene's Nyquist circle.
    let taper = *imager.grid_taper().expect("scene coarser than the optics");
    let mut planner = FftPlanner::<f64>::new();
    let (fwd_x, inv_x) = (planner.plan_fft_forward(nx), planner.plan_fft_inverse(nx));
    let (fwd_y, inv_y) = (planner.plan_fft_forward(ny), planner.plan_fft_inverse(ny));
    let fft2 =
        |a: &mut Array2<Complex64>, fx: &dyn rustfft::Fft<f64>, fy: &dyn rustfft::Fft<f64>| {
            for mut row in a.rows_mut() {
                let mut v = row.to_vec();
                fx.process(&mut v);
                row.assign(&ndarray::Array1::from(v));
            }
            for mut col in a.columns_mut() {
                let mut v = col.to_vec();
                fy.process(&mut v);
                col.assign(&ndarray::Array1::from(v));
            }
        };
    let freq = |k: usize, n: usize, d: f64| {
        let kk = if k <= n / 2 {
            k as f64
        } else {
            k as f64 - n as f64
        };
        kk / (n as f64 * d)
    };
    let ifov = s.ifov_rad();
    let mut total = Array2::<f64>::zeros((rows, cols));
    for (b, lambda) in wl.iter().enumerate() {
        // The engine's padded frame of this band, blurred on its own.
        let padded = imager.padded_band(data.index_axis(ndarray::Axis(0), b));
        let mut a = padded.mapv(|v| Complex64::new(v, 0.0));
        fft2(&mut a, fwd_x.as_ref(), fwd_y.as_ref());
        for ((v, u), z) in a.indexed_iter_mut() {
            let (fx, fy) = (freq(u, nx, ifov).abs(), freq(v, ny, ifov));
            *z *= otf.evaluate(fx, fy, *lambda) * taper.factor(fx.hypot(fy));
        }
        fft2(&mut a, inv_x.as_ref(), inv_y.as_ref());
        for r in 0..rows {
            for cc in 0..cols {
                total[[r, cc]] += w.electrons_per_unit[b]
                    * a[[r + sy.pad_before, cc + sx.pad_before]].re
                    / (nx * ny) as f64;
            }
        }
    }
    let max = total.iter().cloned().fold(0.0, f64::max);
    for (a, b) in e.iter().zip(total.iter()) {
        assert!((a - b).abs() / max < 1e-5, "{a} vs {b}");
    }
}

/// No wrap-around: a hot column at the left edge changes the right edge by less than 1e-3
/// of its excess (diffraction-limited sensor, scene sampled at the detector pitch).
#[test]
fn hot_left_column_does_not_wrap_to_the_right_edge() {
    let (rows, cols) = (32, 64);
    let s = sensor(rows, cols, &[]);
    let wl = grid(4.5, 5.25, 4);
    let mut data = Array3::<f32>::from_elem((wl.len(), rows, cols), 1.0);
    let base = {
        let c = cube(data.clone(), wl.clone(), s.ifov_rad());
        run(&s, c, DEFAULT_WRAP_TOLERANCE).0
    };
    for b in 0..wl.len() {
        for r in 0..rows {
            data[[b, r, 0]] = 101.0;
        }
    }
    let c = cube(data, wl.clone(), s.ifov_rad());
    let (hot, imager) = run(&s, c, DEFAULT_WRAP_TOLERANCE);
    // Excess of the hot column in electrons: 100 × the uniform level.
    let excess = 100.0 * base[[0, 0]];
    for r in 0..rows {
        let change = (hot[[r, cols - 1]] - base[[r, cols - 1]]).abs();
        assert!(change < 1e-3 * excess, "row {r}: {}", change / excess);
    }
    assert!(imager.sampling().x.pad_before >= 4);
}

/// Standard normal CDF.
fn phi(z: f64) -> f64 {
    0.5 * (1.0 + libm::erf(z / std::f64::consts::SQRT_2))
}

/// A Gaussian of rms `sigma` convolved with a unit-area box of width `w`, at offset `u`.
fn gauss_box(u: f64, sigma: f64, w: f64) -> f64 {
    sigma * (2.0 * std::f64::consts::PI).sqrt() / w
        * (phi((u + w / 2.0) / sigma) - phi((u - w / 2.0) / sigma))
}

/// Decimation by an integer factor (odd and even: the even case needs the half-sample
/// shift) and by a non-integer factor equals the analytic footprint-blurred image sampled
/// at the detector pixel centres.
#[test]
fn decimation_equals_analytic_footprint_blur_at_pixel_centres() {
    let (drows, dcols) = (10, 12);
    for k in [3.0, 2.0, 2.5, 1.0] {
        let s = sensor(drows, dcols, &["diffraction.enabled=false"]);
        let d = s.ifov_rad();
        let ifov = d / k;
        // Scene a little larger than the detector field (so even the non-integer case fits).
        let srows = (drows as f64 * k).ceil() as usize + 6;
        let scols = (dcols as f64 * k).ceil() as usize + 8;
        let sigma = 2.2 * ifov.max(d / 3.0);
        let (t0y, t0x) = (0.37 * d, -0.81 * d); // blob off centre: catches shift errors
        let wl = grid(4.4, 5.4, 3);
        let (a, b) = (2.0, 5.0);
        let scene_angle = |c: usize, n: usize| (c as f64 - (n as f64 - 1.0) / 2.0) * ifov;
        let data = Array3::from_shape_fn((wl.len(), srows, scols), |(_, r, c)| {
            let y = scene_angle(r, srows) - t0y;
            let x = scene_angle(c, scols) - t0x;
            (a + b * (-(x * x + y * y) / (2.0 * sigma * sigma)).exp()) as f32
        });
        let c = cube(data, wl.clone(), ifov);
        let w = SpectralWeights::new(&s, &c.meta).unwrap();
        let wsum: f64 = w.electrons_per_unit.iter().sum();
        let (e, _) = run(&s, c, DEFAULT_WRAP_TOLERANCE);
        let w_ang = 20e-6 / 0.1;
        let mut worst: f64 = 0.0;
        for i in 0..drows {
            for j in 0..dcols {
                let py = (i as f64 - (drows as f64 - 1.0) / 2.0) * d - t0y;
                let px = (j as f64 - (dcols as f64 - 1.0) / 2.0) * d - t0x;
                let analytic =
                    wsum * (a + b * gauss_box(py, sigma, w_ang) * gauss_box(px, sigma, w_ang));
                worst = worst.max(((e[[i, j]] - analytic) / (wsum * b)).abs());
            }
        }
        assert!(worst < 1e-4, "k = {k}: worst relative error {worst}");
    }
}

/// A scene that does not cover the sensor band gives an error naming the uncovered range;
/// a sensor looking outside the scene is an error.
#[test]
fn coverage_and_field_of_view_errors() {
    let s = sensor(8, 8, &[]);
    let wl = grid(4.0, 4.9, 20);
    let c = cube(Array3::from_elem((20, 16, 16), 1.0), wl, s.ifov_rad() / 2.0);
    let err = Imager::new(&s, &c.meta, &c.meta.geometry.unwrap(), 1e-4)
        .unwrap_err()
        .to_string();
    assert!(err.contains("4.9000") && err.contains("uncovered"), "{err}");
    let wl = grid(4.4, 5.4, 20);
    let c = cube(Array3::from_elem((20, 10, 10), 1.0), wl, s.ifov_rad() / 1.4);
    let err = Imager::new(&s, &c.meta, &c.meta.geometry.unwrap(), 1e-4)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("field of view") && err.contains("inside the scene"),
        "{err}"
    );
}

/// `Imager::detector_image` (spectrum `[fy, fx]`) and `detector_image_transposed` (the
/// engine's `[fx][fy]` layout) give the same bits, for an integer detector/scene ratio
/// (point sampling) and a non-integer one (trigonometric interpolation), cos⁴ on; and a
/// spectrum holding only a DC value c images to the constant c/(rows·cols) of the padded
/// frame when cos⁴ is off.
#[test]
fn detector_image_in_either_layout_and_of_a_constant() {
    for (ratio, cos4) in [(2.0, true), (2.5, true), (2.0, false), (2.5, false)] {
        let extra = format!("optics.cos4={cos4}");
        let s = sensor(12, 16, &[extra.as_str()]);
        let wl = grid(4.45, 5.3, 8);
        let (rows, cols) = (40, 52);
        let c = cube(
            Array3::from_elem((wl.len(), rows, cols), 1.0f32),
            wl,
            s.ifov_rad() / ratio,
        );
        let imager = Imager::new(&s, &c.meta, &c.meta.geometry.unwrap(), 1e-4).unwrap();
        let (ny, nx) = (
            imager.sampling().y.padded_len,
            imager.sampling().x.padded_len,
        );
        let hc = nx / 2 + 1;
        let spec = Array2::from_shape_fn((ny, hc), |(v, u)| {
            let (v, u) = (v as f64, u as f64);
            Complex64::new((0.3 * v + 0.7 * u).sin(), (0.05 * v * u).cos() - 0.5)
        });
        let mut spec_t: Vec<Complex64> = (0..hc * ny).map(|i| spec[[i % ny, i / ny]]).collect();
        let a = imager.detector_image(&spec);
        let b = imager.detector_image_transposed(&mut spec_t);
        assert_eq!(a.dim(), (12, 16));
        let bits = |e: &Array2<f64>| e.iter().map(|v| v.to_bits()).collect::<Vec<u64>>();
        assert_eq!(bits(&a), bits(&b), "ratio {ratio}, cos4 {cos4}");
        if !cos4 {
            let mut dc = Array2::<Complex64>::zeros((ny, hc));
            dc[[0, 0]] = Complex64::new(3.0, 0.0);
            let want = 3.0 / (ny * nx) as f64;
            for v in imager.detector_image(&dc).iter() {
                assert!(
                    (v - want).abs() <= 1e-15 * want,
                    "ratio {ratio}: {v} vs {want}"
                );
            }
        }
    }
}

/// Frames imaged one after another by one imager reuse its frame buffers (one set kept,
/// the accumulator zeroed in between) and give, bit for bit, what a fresh imager gives for
/// each frame; an f64 frame between f32 ones gets its own set and its own values; once
/// released, none is kept.
#[test]
fn an_imager_reuses_its_frame_buffers_without_carrying_values_over() {
    let s = sensor(12, 16, &["jitter.sigma_rad=4e-5"]);
    let wl = grid(4.45, 5.3, 40);
    let (rows, cols) = (24, 32);
    let ifov = s.ifov_rad() / 2.0;
    let scene = |seed: f32| {
        Array3::from_shape_fn((wl.len(), rows, cols), |(b, r, c)| {
            seed * (1.0 + ((r * 7 + c * 3 + b) % 11) as f32)
        })
    };
    let fresh = |seed: f32, precision: FftPrecision| {
        let c = cube(scene(seed), wl.clone(), ifov);
        let g = c.meta.geometry.unwrap();
        let imager = Imager::new(&s, &c.meta, &g, 1e-4)
            .unwrap()
            .with_precision(precision);
        let mut reader = MemoryCube::new(c);
        imager.mean_electrons(&mut reader, 0, |_, _| {}).unwrap().0
    };
    let g = Geometry::from_ifov(ifov, ifov, rows, cols);
    let meta = cube(scene(1.0), wl.clone(), ifov).meta;
    let imager = Imager::new(&s, &meta, &g, 1e-4).unwrap();
    assert_eq!(imager.kept_frame_buffers(), 0);
    let steps = [
        (1.0, FftPrecision::F32, 1),
        (7.0, FftPrecision::F32, 1),
        (3.0, FftPrecision::F64, 2),
        (5.0, FftPrecision::F32, 2),
    ];
    let mut imager = imager;
    for (seed, precision, kept) in steps {
        imager = imager.with_precision(precision);
        let mut reader = MemoryCube::new(cube(scene(seed), wl.clone(), ifov));
        let (e, _) = imager.mean_electrons(&mut reader, 0, |_, _| {}).unwrap();
        let want = fresh(seed, precision);
        assert!(
            e.iter().zip(&want).all(|(a, b)| a.to_bits() == b.to_bits()),
            "seed {seed}, {precision:?}"
        );
        assert_eq!(
            imager.kept_frame_buffers(),
            kept,
            "seed {seed}, {precision:?}"
        );
    }
    imager.release_frame_buffers();
    assert_eq!(imager.kept_frame_buffers(), 0);
}

/// Relative excess of `e` over the uniform run `base` at (r, c).
fn excess(e: &Array2<f64>, base: &Array2<f64>, r: usize, c: usize) -> f64 {
    (e[[r, c]] - base[[r, c]]) / base[[r, c]]
}

/// No artefact cross (issue 38): a bright source on a uniform 300 K blackbody scene
/// through the MultimIR-like F/2 sensor (optics pass 110 cy/mm, more than the scene grid's
/// Nyquist of 41.7 cy/mm at k = 2 and 83.3 cy/mm at k = 4) leaves no more excess in the
/// mean electrons along its own row and column than 6 px beside them, at 30–44 px from it
/// (4–8 px, averaged; summed over the four directions and every distance). Before the
/// scene-grid taper, a 20× hot square at k = 2 left 3–6× more along the axes (the
/// issue's measurement). The bound 1.2 leaves room for the isotropic diffraction halo,
/// which beside is at a radius up to 3 % larger (≤ 10 % less for its 1/r³ tail) — a
/// cross of the size measured before would exceed it several times. Two sources: a 2 × 2-pixel square at
/// 20× the background radiance, and a single scene sample at 400·(k/2)² × (a point source
/// of the same flux at both k).
#[test]
fn bright_sources_leave_no_cross_at_k2_and_k4() {
    let n = 100usize;
    let (r0, c0) = (50usize, 50usize);
    let s = sensor(n, n, &[]);
    let wl = grid(4.5, 5.25, 5);
    for k in [2usize, 4] {
        let ns = (n + 8) * k;
        let ifov = s.ifov_rad() / k as f64;
        let mut data = Array3::<f32>::zeros((wl.len(), ns, ns));
        for (b, l) in wl.iter().enumerate() {
            data.index_axis_mut(ndarray::Axis(0), b)
                .fill(planck_spectral_radiance(*l, 300.0) as f32);
        }
        let run64 = |d: Array3<f32>| {
            let c = cube(d, wl.clone(), ifov);
            let g = c.meta.geometry.unwrap();
            let imager = Imager::new(&s, &c.meta, &g, DEFAULT_WRAP_TOLERANCE)
                .unwrap()
                .with_precision(FftPrecision::F64);
            assert!(imager.grid_taper().is_some(), "k = {k}");
            assert!(
                imager
                    .sampling()
                    .warnings
                    .iter()
                    .any(|w| w.contains("optical cutoff")),
                "k = {k}: {:?}",
                imager.sampling().warnings
            );
            let mut reader = MemoryCube::new(c);
            imager.mean_electrons(&mut reader, 0, |_, _| {}).unwrap().0
        };
        let base = run64(data.clone());
        // Scene coordinate of detector pixel j's centre: first + j·k.
        let first = (ns as f64 - 1.0) / 2.0 - (n as f64 - 1.0) / 2.0 * k as f64;
        let (cy, cx) = (first + (r0 * k) as f64, first + (c0 * k) as f64);
        let square = |d: &mut Array3<f32>| {
            for b in 0..wl.len() {
                for i in 0..ns {
                    for j in 0..ns {
                        if (i as f64 - cy).abs() < k as f64 && (j as f64 - cx).abs() < k as f64 {
                            d[[b, i, j]] *= 20.0;
                        }
                    }
                }
            }
        };
        let point = |d: &mut Array3<f32>| {
            let gain = 400.0 * (k as f32 / 2.0).powi(2);
            for b in 0..wl.len() {
                d[[b, cy.round() as usize, cx.round() as usize]] *= gain;
            }
        };
        for (name, source) in [
            ("square", &square as &dyn Fn(&mut Array3<f32>)),
            ("point", &point),
        ] {
            let mut d = data.clone();
            source(&mut d);
            let e = run64(d);
            // Every distance, and beside at 4–8 px on either side (averaged), so that the
            // isotropic rings the detector samples at one phase along a row do not pass
            // for a cross.
            let (mut along, mut beside) = (0.0, 0.0);
            for dist in 30..=44i64 {
                for (sr, sc) in [(0i64, 1i64), (0, -1), (1, 0), (-1, 0)] {
                    let at = |off: i64| {
                        let r = (r0 as i64 + sr * dist + sc.abs() * off) as usize;
                        let c = (c0 as i64 + sc * dist + sr.abs() * off) as usize;
                        excess(&e, &base, r, c)
                    };
                    along += at(0);
                    beside += (4..=8).map(|o| at(o) + at(-o)).sum::<f64>() / 10.0;
                }
            }
            assert!(
                beside > 0.0,
                "{name}, k = {k}: no halo measured ({beside:e})"
            );
            assert!(
                along <= 1.2 * beside,
                "{name}, k = {k}: excess along the axes {along:e}, beside {beside:e} (ratio {:.2})",
                along / beside
            );
        }
    }
}

/// Truth image: with every transfer function switched off (`diffraction.enabled=false`,
/// `detector.footprint_enabled=false`, and `enabled=false` on the other sections) the run
/// is the unblurred reference: each detector pixel is the spectral sum `Σ_b w_b L_b` of the
/// scene sample at its centre (odd k = 1 and 3, where centres fall on samples), within
/// 1e-9 relative; and no taper is applied (nothing to ring).
#[test]
fn everything_off_gives_the_unblurred_reference() {
    let (rows, cols) = (10, 12);
    let s = sensor(
        rows,
        cols,
        &[
            "diffraction.enabled=false",
            "detector.footprint_enabled=false",
            "aberration.rms_waves=0.05",
            "aberration.enabled=false",
            "jitter.sigma_rad=4e-5",
            "jitter.enabled=false",
        ],
    );
    assert!(s.otf().components().is_empty());
    let wl = grid(4.5, 5.25, 4);
    for k in [1usize, 3] {
        let (sr, sc) = (rows * k + 6, cols * k + 6);
        let data = pattern(wl.len(), sr, sc);
        let c = cube(data.clone(), wl.clone(), s.ifov_rad() / k as f64);
        let w = SpectralWeights::new(&s, &c.meta).unwrap();
        let g = c.meta.geometry.unwrap();
        let imager = Imager::new(&s, &c.meta, &g, DEFAULT_WRAP_TOLERANCE)
            .unwrap()
            .with_precision(FftPrecision::F64);
        assert!(imager.grid_taper().is_none());
        let mut reader = MemoryCube::new(c);
        let (e, _) = imager.mean_electrons(&mut reader, 0, |_, _| {}).unwrap();
        let first_r = imager.sampling().y.first.round() as usize;
        let first_c = imager.sampling().x.first.round() as usize;
        for r in 0..rows {
            for cc in 0..cols {
                let want: f64 = (0..wl.len())
                    .map(|b| {
                        w.electrons_per_unit[b]
                            * data[[b, first_r + r * k, first_c + cc * k]] as f64
                    })
                    .sum();
                assert!(
                    ((e[[r, cc]] - want) / want).abs() < 1e-9,
                    "k = {k} ({r}, {cc}): {} vs {want}",
                    e[[r, cc]]
                );
            }
        }
    }
}
