//! The detector model (electrons → DN) against independent truth: Poisson statistics,
//! EMVA-1288 photon transfer, the sample statistics of the drawn maps, binomial defect
//! counts, closed-form band integrals for background and auto gain, and reproducibility.

use std::path::PathBuf;
use std::time::Instant;

use ndarray::Array2;

use eoir::detector::{DetectorInstance, DetectorModel};
use eoir::radiometry::planck_spectral_radiance;
use eoir::sensor::{Sensor, SensorConfig};

const H: f64 = 6.626_070_15e-34;
const C: f64 = 299_792_458.0;
const K_B: f64 = 1.380_649e-23;
const Q_E: f64 = 1.602_176_634e-19;

/// An MWIR sensor (3–5 µm filter, F/2, 20 µm active pixels, 1 ms) with `--set` overrides.
fn sensor(rows: usize, cols: usize, extra: &[&str]) -> eoir::Result<SensorConfig> {
    let text = format!(
        r#"
name = "det"
[optics]
focal_length_m = 0.1
f_number = 2.0
[filter]
kind = "top_hat"
lo_um = 3.0
hi_um = 5.0
[detector]
rows = {rows}
cols = {cols}
pitch_m = 24e-6
active_width_m = 20e-6
integration_time_s = 1e-3
quantum_efficiency = {{ kind = "ideal_qe", peak = 0.7, cutoff_um = 5.2 }}
"#
    );
    let o: Vec<String> = extra.iter().map(|s| s.to_string()).collect();
    SensorConfig::from_toml_str(&text, "det.toml", PathBuf::from("."), &o)
}

fn model(rows: usize, cols: usize, extra: &[&str]) -> DetectorModel {
    Sensor::build(&sensor(rows, cols, extra).unwrap())
        .unwrap()
        .detector()
        .clone()
}

fn flat(rows: usize, cols: usize, e: f64) -> Array2<f64> {
    Array2::from_elem((rows, cols), e)
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    s / n as f64
}

/// (mean, unbiased variance) of the values.
fn stats(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0);
    (m, var)
}

fn to_f64(a: &Array2<u16>) -> Vec<f64> {
    a.iter().map(|v| *v as f64).collect()
}

/// Pearson correlation coefficient.
fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let (ma, va) = stats(a);
    let (mb, vb) = stats(b);
    let n = a.len() as f64;
    let cov = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - ma) * (y - mb))
        .sum::<f64>()
        / (n - 1.0);
    cov / (va * vb).sqrt()
}

/// Shot noise: over a flat field the variance equals the mean (Poisson), at a large mean
/// (Ahrens–Dieter branch) and a small one (Knuth branch). With K = 1 DN/e- and no offset,
/// DN are the electron counts. Tolerance 4 σ of the sample variance,
/// Var(s²) = σ⁴ (2/(N−1) + κ/N) with excess kurtosis κ = 1/λ.
#[test]
fn shot_noise_variance_equals_mean() {
    let (r, c) = (256, 256);
    let m = model(r, c, &["detector.bits=16", "detector.gain_dn_per_e=1"]);
    let inst = DetectorInstance::new(&m, 11).unwrap();
    let n = (r * c) as f64;
    for lambda in [3.5, 1000.0, 40_000.0] {
        let dn = to_f64(&inst.expose(&flat(r, c, lambda), 0).unwrap());
        let (mu, var) = stats(&dn);
        let se_mean = (lambda / n).sqrt();
        let se_var = lambda * (2.0 / (n - 1.0) + 1.0 / (lambda * n)).sqrt();
        assert!((mu - lambda).abs() < 4.0 * se_mean, "mean {mu} vs {lambda}");
        assert!(
            (var - lambda).abs() < 4.0 * se_var,
            "variance {var} vs {lambda} (±{})",
            4.0 * se_var
        );
        // Integer counts: every DN is an integer number of electrons.
        assert!(dn.iter().all(|v| v.fract() == 0.0));
    }
    // Expected temporal noise agrees with the model's own prediction formula's input.
    assert!((m.temporal_noise_e(1000.0) - 1000f64.sqrt()).abs() < 1e-12);
}

/// Weighted least squares fit y = a + b x with weights w.
fn wls(x: &[f64], y: &[f64], w: &[f64]) -> (f64, f64) {
    let sw: f64 = w.iter().sum();
    let sx: f64 = x.iter().zip(w).map(|(x, w)| w * x).sum();
    let sy: f64 = y.iter().zip(w).map(|(y, w)| w * y).sum();
    let sxx: f64 = x.iter().zip(w).map(|(x, w)| w * x * x).sum();
    let sxy: f64 = x.iter().zip(y).zip(w).map(|((x, y), w)| w * x * y).sum();
    let b = (sw * sxy - sx * sy) / (sw * sxx - sx * sx);
    let a = (sy - b * sx) / sw;
    (a, b)
}

/// Photon transfer (EMVA 1288, FOI report eq. 2.49): flat fields at 20 levels, two frames
/// each; temporal variance from the difference image, var(A − B)/2, against the
/// dark-subtracted mean DN. The slope is K, the intercept K²(σ_r² + μ_dark,e) + 1/12
/// (quantisation). Weighted fit with weights 1/var² (the sampling variance of a variance
/// is 2σ⁴/N), iterated once. K within 1 %, read noise within 3 %.
#[test]
fn photon_transfer_recovers_gain_and_read_noise() {
    let (r, c) = (256, 256);
    let k_true = 0.5;
    let read_true = 40.0;
    let m = model(
        r,
        c,
        &[
            "detector.bits=16",
            "detector.gain_dn_per_e=0.5",
            "detector.offset_dn=300",
            "detector.read_noise_e=40",
            "detector.dark_current_e_per_s=2e6",
            "detector.full_well_e=2e5",
        ],
    );
    let inst = DetectorInstance::new(&m, 5).unwrap();
    let levels: Vec<f64> = (0..20).map(|k| 100_000.0 * k as f64 / 19.0).collect();
    let mut mu = Vec::new();
    let mut var = Vec::new();
    for (k, e) in levels.iter().enumerate() {
        let a = to_f64(&inst.expose(&flat(r, c, *e), 2 * k as u64).unwrap());
        let b = to_f64(&inst.expose(&flat(r, c, *e), 2 * k as u64 + 1).unwrap());
        let diff: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x - y).collect();
        mu.push(0.5 * (mean(a.iter().copied()) + mean(b.iter().copied())));
        var.push(stats(&diff).1 / 2.0);
    }
    let dark = mu[0];
    let x: Vec<f64> = mu.iter().map(|m| m - dark).collect();
    let mut w: Vec<f64> = var.iter().map(|v| 1.0 / (v * v)).collect();
    let (mut a, mut b) = wls(&x, &var, &w);
    for _ in 0..2 {
        w = x.iter().map(|x| 1.0 / (a + b * x).powi(2)).collect();
        (a, b) = wls(&x, &var, &w);
    }
    assert!(((b - k_true) / k_true).abs() < 0.01, "K = {b} vs {k_true}");
    let dark_e = (dark - 300.0) / b;
    let read = ((a - 1.0 / 12.0) / (b * b) - dark_e).sqrt();
    assert!(
        ((read - read_true) / read_true).abs() < 0.03,
        "read noise {read} vs {read_true} (intercept {a}, dark {dark_e} e-)"
    );
    assert!((dark_e - 2000.0).abs() < 10.0, "dark {dark_e} e-");
    // The model's expected temporal noise matches the measurement at the top level.
    let top = *levels.last().unwrap_or(&0.0);
    let predicted = m.temporal_noise_dn(top).powi(2) + m.quantisation_noise_dn().powi(2);
    let measured = *var.last().unwrap_or(&0.0);
    assert!(
        ((measured - predicted) / predicted).abs() < 4.0 * (2.0 / (r * c) as f64).sqrt(),
        "{measured} vs {predicted}"
    );
}

/// The drawn gain and offset maps have the configured PRNU, DSNU and bias–gain
/// correlation within sampling error (N = 65536: σ(s)/s ≈ 1/√(2N) = 0.28 %, σ(ρ̂) ≈
/// (1−ρ²)/√N), and exposing a noise-free flat field shows exactly that pattern.
#[test]
fn fpn_maps_recover_prnu_dsnu_and_correlation() {
    let (r, c) = (256, 256);
    let n = (r * c) as f64;
    let m = model(
        r,
        c,
        &[
            "detector.fpn.prnu_sigma_rel=0.02",
            "detector.fpn.dsnu_sigma_e=200",
            "detector.fpn.bias_gain_correlation=0.6",
        ],
    );
    let inst = DetectorInstance::new(&m, 42).unwrap();
    let g: Vec<f64> = inst.gain_map().iter().copied().collect();
    let o: Vec<f64> = inst.offset_map_e().iter().copied().collect();
    let (gm, gv) = stats(&g);
    let (om, ov) = stats(&o);
    assert!((gm - 1.0).abs() < 4.0 * 0.02 / n.sqrt(), "mean gain {gm}");
    assert!(om.abs() < 4.0 * 200.0 / n.sqrt(), "mean offset {om}");
    let tol_s = 4.0 / (2.0 * n).sqrt();
    assert!((gv.sqrt() / 0.02 - 1.0).abs() < tol_s, "PRNU {}", gv.sqrt());
    assert!(
        (ov.sqrt() / 200.0 - 1.0).abs() < tol_s,
        "DSNU {}",
        ov.sqrt()
    );
    let rho = correlation(&g, &o);
    assert!(
        (rho - 0.6).abs() < 4.0 * (1.0 - 0.36) / n.sqrt(),
        "ρ = {rho}"
    );
    // Column and row offsets: the column means of the offset map scatter by σ_col.
    let m2 = model(
        r,
        c,
        &[
            "detector.fpn.column_sigma_e=50",
            "detector.fpn.row_sigma_e=0",
        ],
    );
    let off = DetectorInstance::new(&m2, 1).unwrap().offset_map_e();
    let cols: Vec<f64> = (0..c).map(|j| off[[0, j]]).collect();
    assert!((0..r).all(|i| (0..c).all(|j| off[[i, j]] == cols[j])));
    let (_, cv) = stats(&cols);
    let tol = 4.0 / (2.0 * c as f64).sqrt();
    assert!(
        (cv.sqrt() / 50.0 - 1.0).abs() < tol,
        "column σ {}",
        cv.sqrt()
    );
}

/// Autocorrelation of the map at lag (dy, dx), normalised by the variance.
fn autocorrelation(a: &Array2<f64>, dy: usize, dx: usize) -> f64 {
    let (r, c) = a.dim();
    let m = a.mean().unwrap_or(0.0);
    let var = a.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (r * c) as f64;
    let mut s = 0.0;
    let mut n = 0usize;
    for i in 0..r - dy {
        for j in 0..c - dx {
            s += (a[[i, j]] - m) * (a[[i + dy, j + dx]] - m);
            n += 1;
        }
    }
    s / n as f64 / var
}

/// A spatially correlated pattern (L = 6 px): the autocorrelation is exp(−(d/L)²) —
/// exp(−1) at lag L and exp(−1/4) at L/2 along both axes — within ±0.06 (the pattern
/// has only ~N/L² ≈ 1800 independent patches), and the rms is still the configured σ
/// (±15 %).
#[test]
fn correlated_fpn_has_the_configured_correlation_length() {
    let (r, c) = (256, 256);
    let m = model(
        r,
        c,
        &[
            "detector.fpn.prnu_sigma_rel=0.01",
            "detector.fpn.correlation_length_px=6",
        ],
    );
    let g = DetectorInstance::new(&m, 3).unwrap().gain_map();
    for (d, expected) in [(6, (-1.0f64).exp()), (3, (-0.25f64).exp())] {
        let ax = autocorrelation(&g, 0, d);
        let ay = autocorrelation(&g, d, 0);
        assert!(
            (ax - expected).abs() < 0.06,
            "x lag {d}: {ax} vs {expected}"
        );
        assert!(
            (ay - expected).abs() < 0.06,
            "y lag {d}: {ay} vs {expected}"
        );
    }
    let (_, v) = stats(&g.iter().copied().collect::<Vec<_>>());
    assert!((v.sqrt() / 0.01 - 1.0).abs() < 0.15, "σ = {}", v.sqrt());
}

/// Every DN lies in [0, 2^bits − 1] for a ramp from below zero to far beyond full scale;
/// dead, hot and stuck fractions are within 4 σ binomial bounds (each kind drawn
/// independently, priority dead > hot > stuck, so P(hot) = f_h(1−f_d) …); dead pixels read
/// 0, hot ones full scale, stuck ones the same value whatever the scene and frame.
#[test]
fn adc_range_and_defect_fractions() {
    let (r, c) = (512, 512);
    let m = model(
        r,
        c,
        &[
            "detector.bits=12",
            "detector.read_noise_e=500",
            "detector.fpn.dsnu_sigma_e=2000",
            "detector.defects.dead_fraction=0.001",
            "detector.defects.hot_fraction=0.0005",
            "detector.defects.stuck_fraction=0.002",
        ],
    );
    let inst = DetectorInstance::new(&m, 9).unwrap();
    let ramp = Array2::from_shape_fn((r, c), |(_, j)| -1e5 + 2e7 * j as f64 / c as f64);
    let dn = inst.expose(&ramp, 0).unwrap();
    assert!(dn.iter().all(|v| *v <= 4095));
    assert!(dn.iter().any(|v| *v == 0) && dn.iter().any(|v| *v == 4095));
    let map = inst.defect_map();
    let n = (r * c) as f64;
    let (fd, fh, fs) = (0.001, 0.0005, 0.002);
    for (code, p) in [
        (1u8, fd),
        (2u8, fh * (1.0 - fd)),
        (3u8, fs * (1.0 - fd) * (1.0 - fh)),
    ] {
        let count = map.iter().filter(|v| **v == code).count() as f64;
        let sd = (n * p * (1.0 - p)).sqrt();
        assert!(
            (count - n * p).abs() < 4.0 * sd,
            "code {code}: {count} vs {} ± {}",
            n * p,
            4.0 * sd
        );
    }
    let dn2 = inst.expose(&flat(r, c, 1e6), 3).unwrap();
    for ((idx, code), (a, b)) in map.indexed_iter().zip(dn.iter().zip(dn2.iter())) {
        match code {
            1 => assert_eq!((*a, *b), (0, 0), "dead {idx:?}"),
            2 => assert_eq!((*a, *b), (4095, 4095), "hot {idx:?}"),
            3 => assert_eq!(a, b, "stuck {idx:?}"),
            _ => {}
        }
    }
}

/// The fixed pattern is identical in every frame (without temporal noise frames 0 and 7
/// are bit-identical and differ from a flat response), and the temporal noise of two
/// frames — each frame minus the noise-free frame of the same instance, which has the
/// same maps because streams are independent — is uncorrelated (|ρ| < 0.02; σ(ρ̂) = 1/√N
/// = 0.004).
#[test]
fn fixed_pattern_is_fixed_and_temporal_noise_is_uncorrelated() {
    let (r, c) = (256, 256);
    let fpn = [
        "detector.bits=16",
        "detector.fpn.prnu_sigma_rel=0.02",
        "detector.fpn.dsnu_sigma_e=1000",
        "detector.fpn.bias_gain_correlation=-0.3",
    ];
    let clean_cfg: Vec<&str> = fpn
        .iter()
        .copied()
        .chain(["detector.shot_noise=false"])
        .collect();
    let noisy_cfg: Vec<&str> = fpn
        .iter()
        .copied()
        .chain(["detector.read_noise_e=300"])
        .collect();
    let clean = DetectorInstance::new(&model(r, c, &clean_cfg), 77).unwrap();
    let noisy = DetectorInstance::new(&model(r, c, &noisy_cfg), 77).unwrap();
    assert_eq!(clean.gain_map(), noisy.gain_map());
    assert_eq!(clean.offset_map_e(), noisy.offset_map_e());
    let scene = flat(r, c, 2e6);
    let c0 = clean.expose(&scene, 0).unwrap();
    let c7 = clean.expose(&scene, 7).unwrap();
    assert_eq!(c0, c7);
    let (_, spatial) = stats(&to_f64(&c0));
    assert!(spatial > 100.0, "no fixed pattern visible: {spatial}");
    let res = |f: u64| -> Vec<f64> {
        let d = noisy.expose(&scene, f).unwrap();
        d.iter()
            .zip(c0.iter())
            .map(|(a, b)| *a as f64 - *b as f64)
            .collect()
    };
    let (r0, r1) = (res(0), res(1));
    let rho = correlation(&r0, &r1);
    assert!(rho.abs() < 0.02, "temporal correlation {rho}");
    // Residuals are temporal noise only: their variance is K²(μ + σ_r²) (+ 1/12).
    let (_, v) = stats(&r0);
    let k = noisy.model().gain_dn_per_e();
    let expected = k * k * (2e6 + 300.0 * 300.0);
    assert!(
        ((v - expected) / expected).abs() < 0.15,
        "{v} vs {expected}"
    );
}

/// Same seed ⇒ bit-identical frames; another seed ⇒ different noise and pattern but the
/// same mean (within 4 σ of the pixel-mean sampling error); turning dead pixels on does
/// not change the PRNU map or the other pixels; the number of threads does not matter.
#[test]
fn reproducible_independent_streams_and_thread_count() {
    let (r, c) = (128, 160);
    let base = [
        "detector.read_noise_e=100",
        "detector.fpn.prnu_sigma_rel=0.01",
        "detector.fpn.dsnu_sigma_e=300",
        "detector.fpn.correlation_length_px=2",
        "detector.nonlinearity.quadratic_mean_per_e=-1e-9",
        "detector.nonlinearity.quadratic_sigma_per_e=1e-10",
    ];
    let m = model(r, c, &base);
    let scene = Array2::from_shape_fn((r, c), |(i, j)| 1e6 + 1e3 * (i + j) as f64);
    let a = DetectorInstance::new(&m, 1).unwrap();
    let f1 = a.expose(&scene, 4).unwrap();
    assert_eq!(
        f1,
        DetectorInstance::new(&m, 1)
            .unwrap()
            .expose(&scene, 4)
            .unwrap()
    );
    let b = DetectorInstance::new(&m, 2).unwrap();
    let f2 = b.expose(&scene, 4).unwrap();
    assert_ne!(f1, f2);
    let d1 = to_f64(&f1);
    let d2 = to_f64(&f2);
    let (m1, v1) = stats(&d1);
    let (m2, _) = stats(&d2);
    assert!(
        (m1 - m2).abs() < 4.0 * (2.0 * v1 / d1.len() as f64).sqrt(),
        "{m1} vs {m2}"
    );

    let with_dead: Vec<&str> = base
        .iter()
        .copied()
        .chain(["detector.defects.dead_fraction=0.01"])
        .collect();
    let md = model(r, c, &with_dead);
    let ad = DetectorInstance::new(&md, 1).unwrap();
    assert_eq!(ad.gain_map(), a.gain_map());
    assert_eq!(ad.offset_map_e(), a.offset_map_e());
    assert_eq!(ad.quadratic_map_per_e(), a.quadratic_map_per_e());
    let fd = ad.expose(&scene, 4).unwrap();
    let dead = ad.defect_map();
    assert!(dead.iter().any(|v| *v == 1));
    for ((x, y), d) in fd.iter().zip(f1.iter()).zip(dead.iter()) {
        if *d == 0 {
            assert_eq!(x, y);
        } else {
            assert_eq!(*x, 0);
        }
    }

    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                DetectorInstance::new(&m, 1)
                    .unwrap()
                    .expose(&scene, 4)
                    .unwrap()
            })
    };
    assert_eq!(run(1), f1);
    assert_eq!(run(3), f1);
}

/// Trapezoid Σ of S(λ) L(λ) λ/(hc) over a fine grid: the band integral by another route.
fn photon_integral(s: &SensorConfig, lo: f64, hi: f64, radiance: impl Fn(f64) -> f64) -> f64 {
    let resp = Sensor::build(s).unwrap().response().clone();
    let n = 20_000;
    let h = (hi - lo) / n as f64;
    (0..=n)
        .map(|i| {
            let l = lo + h * i as f64;
            let w = if i == 0 || i == n { 0.5 } else { 1.0 };
            w * h * resp.eval(l) * radiance(l) * l * 1e-6 / (H * C)
        })
        .sum()
}

/// Étendue × time written out: aperture area × A_det / f² × t.
fn etendue_time(s: &SensorConfig) -> f64 {
    let d = s.optics.focal_length_m / s.optics.f_number;
    std::f64::consts::PI * d * d / 4.0 * s.detector.active_area_m2()
        / (s.optics.focal_length_m * s.optics.focal_length_m)
        * s.detector.integration_time_s
}

/// Auto gain, thermal: a 300 K blackbody (electrons by an independent trapezoid band
/// integral, plus dark and background) exposed through the full detector with shot and
/// read noise and PRNU lands at `fraction` of the range above the offset within 0.5 %.
#[test]
fn auto_gain_puts_the_reference_blackbody_at_the_fraction() {
    let (r, c) = (64, 64);
    let s = sensor(
        r,
        c,
        &[
            "detector.offset_dn=1000",
            "detector.dark_current_e_per_s=1e8",
            "detector.read_noise_e=200",
            "detector.fpn.prnu_sigma_rel=0.01",
            "detector.background.temperature_k=290",
            "detector.background.emissivity=0.05",
            "detector.auto_gain.reference_temperature_k=300",
            "detector.auto_gain.fraction=0.4",
        ],
    )
    .unwrap();
    let m = Sensor::build(&s).map(|s| s.detector().clone()).unwrap();
    let signal =
        etendue_time(&s) * photon_integral(&s, 2.9, 5.3, |l| planck_spectral_radiance(l, 300.0));
    let e_total = signal + 1e8 * 1e-3 + m.background_e();
    assert!(m.background_e() > 0.0);
    let inst = DetectorInstance::new(&m, 8).unwrap();
    let dn = inst.expose(&flat(r, c, signal), 0).unwrap();
    let mu = mean(dn.iter().map(|v| *v as f64));
    let target = 1000.0 + 0.4 * (16383.0 - 1000.0);
    assert!(((mu - target) / target).abs() < 0.005, "{mu} vs {target}");
    let k = m.gain_dn_per_e();
    assert!(((k * e_total + 1000.0 - target) / target).abs() < 1e-4);
    let k2 = Sensor::build(&s)
        .unwrap()
        .auto_gain(s.detector.auto_gain.as_ref().unwrap())
        .unwrap();
    assert_eq!(k, k2);
}

/// Auto gain, visible: a silicon-like 0.4–0.7 µm sensor defaults to the reflected-sun
/// reference (20 % Lambertian, sun at 45°, E₀ = B(5772 K)·Ω_sun): the electrons of that
/// radiance, by an independent band integral, land at the fraction within 0.5 %.
#[test]
fn auto_gain_visible_uses_reflected_sun() {
    let (r, c) = (32, 32);
    let s = sensor(
        r,
        c,
        &[
            "filter.lo_um=0.4",
            "filter.hi_um=0.7",
            "detector.quantum_efficiency={ kind = \"constant\", value = 0.6 }",
            "detector.integration_time_s=1e-4",
            "detector.full_well_e=1e9",
            "detector.auto_gain.fraction=0.5",
        ],
    )
    .unwrap();
    let m = Sensor::build(&s).map(|s| s.detector().clone()).unwrap();
    let (kind, e_ref) = m.auto_gain_reference().unwrap();
    assert_eq!(kind, eoir::detector::AutoGainReference::ReflectedSun);
    let omega_sun = std::f64::consts::PI * (6.957e8f64 / 1.495_978_707e11).powi(2);
    let sun = |l: f64| {
        0.2 * planck_spectral_radiance(l, 5772.0) * omega_sun * 45f64.to_radians().cos()
            / std::f64::consts::PI
    };
    let expected = etendue_time(&s) * photon_integral(&s, 0.39, 0.71, sun);
    assert!(
        ((e_ref - expected) / expected).abs() < 2e-3,
        "{e_ref} vs {expected}"
    );
    let dn = DetectorInstance::new(&m, 1)
        .unwrap()
        .expose(&flat(r, c, expected), 0)
        .unwrap();
    let mu = mean(dn.iter().map(|v| *v as f64));
    assert!(
        ((mu - 0.5 * 16383.0) / (0.5 * 16383.0)).abs() < 0.005,
        "{mu}"
    );
}

/// Background: through a narrow filter (0.01 µm at 10 µm, flat QE) the grey-body
/// electrons are ε · étendue·t · B_q(λ₀, T) · Δλ (closed form, narrow-band limit), and
/// the optics transmission does not attenuate them.
#[test]
fn background_is_grey_body_through_filter_and_qe_only() {
    let s = sensor(
        4,
        4,
        &[
            "filter.lo_um=9.995",
            "filter.hi_um=10.005",
            "detector.quantum_efficiency={ kind = \"constant\", value = 0.5 }",
            "optics.transmission={ kind = \"constant\", value = 0.3 }",
            "detector.background.temperature_k=300",
            "detector.background.emissivity=0.1",
        ],
    )
    .unwrap();
    let m = Sensor::build(&s).map(|s| s.detector().clone()).unwrap();
    let bq = planck_spectral_radiance(10.0, 300.0) * 10e-6 / (H * C);
    let expected = 0.1 * etendue_time(&s) * 0.5 * bq * 0.01;
    assert!(
        ((m.background_e() - expected) / expected).abs() < 1e-4,
        "{} vs {expected}",
        m.background_e()
    );
}

/// Dark current: constant rate × t_int; the temperature models give I_ref at T_ref, and the
/// slope of an Arrhenius plot (ln I against 1/T, measured on the model's output between
/// 75 and 85 K) returns the activation energy plus p·k·T̄ (E_g for diffusion with p = 3,
/// E_g/2 for generation–recombination with p = 1.5).
#[test]
fn dark_current_models() {
    let m = model(4, 4, &["detector.dark_current_e_per_s=5e5"]);
    assert!((m.dark_e() - 500.0).abs() < 1e-9);
    let rate = |kind: &str, t: f64| {
        let s = sensor(
            4,
            4,
            &[
                &format!("detector.dark_model.kind=\"{kind}\""),
                &format!("detector.dark_model.fpa_temperature_k={t}"),
                "detector.dark_model.reference_temperature_k=80",
                "detector.dark_model.reference_e_per_s=1e6",
                "detector.dark_model.bandgap_ev=0.25",
            ],
        )
        .unwrap();
        Sensor::build(&s)
            .map(|s| s.detector().clone())
            .unwrap()
            .dark_e()
            / 1e-3
    };
    for (kind, p, ea) in [
        ("diffusion", 3.0, 0.25),
        ("generation_recombination", 1.5, 0.125),
    ] {
        assert!((rate(kind, 80.0) - 1e6).abs() < 1e-3);
        let (t1, t2) = (75.0, 85.0);
        let slope = (rate(kind, t2).ln() - rate(kind, t1).ln()) / (1.0 / t2 - 1.0 / t1);
        // d ln I / d(1/T) = −E_a/k − p T  (evaluated at the mean; ±0.3 % for the secant)
        let t_mid = 2.0 / (1.0 / t1 + 1.0 / t2);
        let ea_measured = -(slope + p * t_mid) * K_B / Q_E;
        assert!(
            ((ea_measured - ea) / ea).abs() < 3e-3,
            "{kind}: E_a {ea_measured} vs {ea}"
        );
        assert!(rate(kind, 85.0) > rate(kind, 80.0));
    }
}

/// Nonlinearity: without noise, the mean DN at several levels follows e + a e² with the
/// configured mean a; a least-squares quadratic fit of the output recovers a (1 %).
#[test]
fn nonlinearity_is_recovered_by_a_quadratic_fit() {
    let (r, c) = (64, 64);
    let m = model(
        r,
        c,
        &[
            "detector.bits=16",
            "detector.gain_dn_per_e=0.005",
            "detector.shot_noise=false",
            "detector.nonlinearity.quadratic_mean_per_e=-2e-8",
            "detector.nonlinearity.quadratic_sigma_per_e=1e-9",
        ],
    );
    let inst = DetectorInstance::new(&m, 4).unwrap();
    // y/e = K (1 + a e): fit a straight line to mean DN / e against e.
    let levels: Vec<f64> = (1..=10).map(|k| 1e6 * k as f64).collect();
    let y: Vec<f64> = levels
        .iter()
        .map(|e| {
            mean(
                inst.expose(&flat(r, c, *e), 0)
                    .unwrap()
                    .iter()
                    .map(|v| *v as f64),
            ) / e
        })
        .collect();
    let w = vec![1.0; y.len()];
    let (k0, slope) = wls(&levels, &y, &w);
    let a = slope / k0;
    assert!(((k0 - 0.005) / 0.005).abs() < 1e-3, "K {k0}");
    assert!(((a + 2e-8) / 2e-8).abs() < 0.01, "a = {a}");
}

/// Invalid parameters are errors that name the field.
#[test]
fn invalid_parameters_name_the_field() {
    for (set, field) in [
        ("detector.read_noise_e=-1", "detector.read_noise_e"),
        (
            "detector.dark_current_e_per_s=-5",
            "detector.dark_current_e_per_s",
        ),
        (
            "detector.defects.dead_fraction=1.5",
            "detector.defects.dead_fraction",
        ),
        (
            "detector.defects.hot_fraction=-0.1",
            "detector.defects.hot_fraction",
        ),
        (
            "detector.fpn.bias_gain_correlation=1.2",
            "detector.fpn.bias_gain_correlation",
        ),
        (
            "detector.fpn.prnu_sigma_rel=-0.01",
            "detector.fpn.prnu_sigma_rel",
        ),
        (
            "detector.fpn.correlation_length_px=-2",
            "detector.fpn.correlation_length_px",
        ),
        (
            "detector.background.emissivity=1.5",
            "detector.background.emissivity",
        ),
        (
            "detector.auto_gain.fraction=0",
            "detector.auto_gain.fraction",
        ),
        (
            "detector.nonlinearity.quadratic_sigma_per_e=-1",
            "detector.nonlinearity.quadratic_sigma_per_e",
        ),
    ] {
        let mut o = vec![set];
        if set.starts_with("detector.background") {
            o.push("detector.background.temperature_k=290");
        }
        let e = sensor(8, 8, &o).expect_err(set).to_string();
        assert!(e.contains(field), "`{set}`: {e}");
    }
    let e = sensor(
        8,
        8,
        &[
            "detector.gain_dn_per_e=1",
            "detector.auto_gain.fraction=0.5",
        ],
    )
    .expect_err("gain and auto gain")
    .to_string();
    assert!(e.contains("detector.auto_gain"), "{e}");
    let e = sensor(8, 8, &["detector.fpn.bogus=1"])
        .expect_err("unknown key")
        .to_string();
    assert!(e.contains("bogus"), "{e}");
    let missing = sensor(8, 8, &["detector.fpn.gain_map=\"/nonexistent/gain.tiff\""]).unwrap();
    let e = Sensor::build(&missing)
        .expect_err("missing map")
        .to_string();
    assert!(e.contains("gain.tiff"), "{e}");
    // Wrong shape or NaN in the mean electrons.
    let m = model(8, 8, &[]);
    let inst = DetectorInstance::new(&m, 1).unwrap();
    assert!(inst.expose(&flat(8, 9, 1.0), 0).is_err());
    let mut bad = flat(8, 8, 1.0);
    bad[[2, 3]] = f64::NAN;
    let e = inst.expose(&bad, 0).unwrap_err().to_string();
    assert!(e.contains("row 2, column 3"), "{e}");
}

/// Measured maps from TIFF files replace / add to the random pattern, resolved against
/// the sensor file's directory; a map of the wrong size is an error naming the field.
#[test]
fn measured_maps_are_loaded_relative_to_the_sensor_file() {
    let dir = tempfile::tempdir().unwrap();
    let (r, c) = (6, 5);
    let gain = Array2::from_shape_fn((r, c), |(i, j)| 1.0 + 0.01 * (i * c + j) as f32);
    let offset = Array2::from_shape_fn((r, c), |(i, _)| 10.0 * i as f32);
    let mut defects = Array2::<u16>::zeros((r, c));
    defects[[1, 1]] = 1;
    defects[[2, 2]] = 2;
    eoir::io::raster::write_tiff_f32(&dir.path().join("g.tiff"), gain.view()).unwrap();
    eoir::io::raster::write_tiff_f32(&dir.path().join("o.tiff"), offset.view()).unwrap();
    eoir::io::raster::write_tiff_u16(&dir.path().join("d.tiff"), defects.view()).unwrap();
    let mut s = sensor(
        r,
        c,
        &[
            "detector.fpn.gain_map=\"g.tiff\"",
            "detector.fpn.offset_map=\"o.tiff\"",
            "detector.defects.map=\"d.tiff\"",
            "detector.shot_noise=false",
            "detector.bits=16",
            "detector.gain_dn_per_e=1",
        ],
    )
    .unwrap();
    s.base_dir = dir.path().to_path_buf();
    let m = Sensor::build(&s).map(|s| s.detector().clone()).unwrap();
    let inst = DetectorInstance::new(&m, 1).unwrap();
    let dn = inst.expose(&flat(r, c, 1000.0), 0).unwrap();
    for ((i, j), v) in dn.indexed_iter() {
        let expected = match (i, j) {
            (1, 1) => 0.0,
            (2, 2) => 65535.0,
            _ => (1000.0 * gain[[i, j]] as f64 + offset[[i, j]] as f64).round(),
        };
        assert_eq!(*v as f64, expected, "({i}, {j})");
    }
    let mut wrong = s.clone();
    wrong.detector.rows = 7;
    let e = Sensor::build(&wrong)
        .map(|s| s.detector().clone())
        .unwrap_err()
        .to_string();
    assert!(e.contains("detector.fpn.gain_map"), "{e}");
}

/// Speed: a 1024² frame with every effect on and means above 1e7 electrons (Poisson
/// rejection sampling, constant time per draw) takes well under a few seconds.
#[test]
fn megapixel_frame_with_large_means_is_fast() {
    let n = 1024;
    let m = model(
        n,
        n,
        &[
            "detector.full_well_e=1e9",
            "detector.read_noise_e=300",
            "detector.fpn.prnu_sigma_rel=0.01",
            "detector.fpn.dsnu_sigma_e=1000",
            "detector.defects.dead_fraction=0.001",
        ],
    );
    let inst = DetectorInstance::new(&m, 1).unwrap();
    let scene = Array2::from_shape_fn((n, n), |(i, j)| 2e7 + 1e5 * ((i + j) % 100) as f64);
    let t = Instant::now();
    let dn = inst.expose(&scene, 0).unwrap();
    let dt = t.elapsed().as_secs_f64();
    assert_eq!(dn.dim(), (n, n));
    assert!(dt < 3.0, "{dt} s");
}

/// The resolved configuration written next to every output reads back identically with
/// every detector sub-table present.
#[test]
fn detector_tables_round_trip_through_toml() {
    let s = sensor(
        16,
        16,
        &[
            "detector.read_noise_e=150",
            "detector.shot_noise=true",
            "detector.dark_model.kind=\"generation_recombination\"",
            "detector.dark_model.fpa_temperature_k=300",
            "detector.dark_model.reference_temperature_k=293",
            "detector.dark_model.reference_e_per_s=50",
            "detector.dark_model.bandgap_ev=1.12",
            "detector.background.temperature_k=293",
            "detector.background.emissivity=0.05",
            "detector.fpn.prnu_sigma_rel=0.01",
            "detector.fpn.column_sigma_e=3",
            "detector.nonlinearity.quadratic_mean_per_e=-1e-9",
            "detector.defects.hot_fraction=0.001",
            "detector.auto_gain.reference=\"blackbody\"",
        ],
    )
    .unwrap();
    let text = s.to_toml_string().unwrap();
    let back = SensorConfig::from_toml_str(&text, "round", PathBuf::from("."), &[]).unwrap();
    assert_eq!(back.detector, s.detector, "{text}");
    let m = Sensor::build(&back).map(|s| s.detector().clone()).unwrap();
    // Silicon G-R dark current 7 K above the reference: the rule of thumb "doubles every
    // ~8–9 K near room temperature" gives 1.7–1.8.
    let ratio = m.dark_e() / s.detector.integration_time_s / 50.0;
    assert!(ratio > 1.6 && ratio < 1.9, "{ratio}");
}
