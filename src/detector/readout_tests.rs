//! Tests of [`super`] (the readout-ordered noise): spectra, banding, white floor,
//! amplitudes, crosstalk, clock, reproducibility and validation.
use super::*;
use rand::SeedableRng;
use realfft::RealFftPlanner;

const DT_S: f64 = 1e-7;

fn base(outputs: usize) -> ReadoutNoiseConfig {
    ReadoutNoiseConfig {
        outputs,
        pixel_time_s: DT_S,
        row_overhead_px: 0,
        frame_overhead_rows: 0,
        alternate_read_direction: false,
        pink_sigma_e: None,
        pink_density_e_per_sqrt_hz: None,
        correlated_pink_sigma_e: None,
        correlated_pink_density_e_per_sqrt_hz: None,
        alternating_column_sigma_e: 0.0,
        row_sigma_e: 0.0,
        output_crosstalk: None,
    }
}

/// Welch estimate of the one-sided PSD (units²/Hz) of `series` sampled every `dt_s`:
/// Hann-windowed segments of `m` samples, half overlapping; returns (f_k, S_k) for
/// k = 1..m/2.
fn welch(series: &[Vec<f64>], m: usize, dt_s: f64) -> (Vec<f64>, Vec<f64>) {
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(m);
    let w: Vec<f64> = (0..m)
        .map(|i| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / m as f64).cos())
        .collect();
    let w2: f64 = w.iter().map(|v| v * v).sum();
    let mut acc = vec![0.0; m / 2 + 1];
    let mut segments = 0usize;
    for s in series {
        let mut start = 0;
        while start + m <= s.len() {
            let seg = &s[start..start + m];
            let mean = seg.iter().sum::<f64>() / m as f64;
            let mut buf: Vec<f64> = seg.iter().zip(&w).map(|(x, w)| (x - mean) * w).collect();
            let mut spec = fft.make_output_vec();
            fft.process(&mut buf, &mut spec).unwrap();
            for (a, c) in acc.iter_mut().zip(&spec) {
                *a += c.norm_sqr();
            }
            segments += 1;
            start += m / 2;
        }
    }
    let f: Vec<f64> = (1..=m / 2).map(|k| k as f64 / (m as f64 * dt_s)).collect();
    let s: Vec<f64> = (1..=m / 2)
        .map(|k| 2.0 * dt_s * acc[k] / (w2 * segments as f64))
        .collect();
    (f, s)
}

/// Least-squares slope and intercept of log10 S against log10 f over the bins with
/// f in [f1, f2], after averaging the bins into `n` log-spaced groups.
fn log_slope(f: &[f64], s: &[f64], f1: f64, f2: f64, n: usize) -> (f64, f64) {
    let (l1, l2) = (f1.log10(), f2.log10());
    let mut groups = vec![(0.0, 0.0, 0usize); n];
    for (&fi, &si) in f.iter().zip(s) {
        let u = fi.log10();
        if u < l1 || u > l2 {
            continue;
        }
        let g = (((u - l1) / (l2 - l1)) * n as f64).min(n as f64 - 1.0) as usize;
        groups[g].0 += u;
        groups[g].1 += si;
        groups[g].2 += 1;
    }
    let pts: Vec<(f64, f64)> = groups
        .iter()
        .filter(|g| g.2 > 0)
        .map(|g| (g.0 / g.2 as f64, (g.1 / g.2 as f64).log10()))
        .collect();
    let k = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / k;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / k;
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    let slope = sxy / sxx;
    (slope, my - slope * mx)
}

/// Pixels of output `o` of a `w`-wide stripe layout in the order they are read, with no
/// overheads: rows top to bottom, each row left to right (or right to left if
/// `reversed`).
fn read_order(img: &Array2<f64>, o: usize, w: usize, reversed: bool) -> Vec<f64> {
    let mut v = Vec::with_capacity(img.nrows() * w);
    for r in 0..img.nrows() {
        for j in 0..w {
            let c = if reversed {
                o * w + w - 1 - j
            } else {
                o * w + j
            };
            v.push(img[[r, c]]);
        }
    }
    v
}

#[test]
fn pink_psd_in_readout_order_has_slope_minus_one_over_two_decades() {
    // Two outputs, the second mirrored; 256 × 512 → 65536 ticks per frame.
    let mut cfg = base(2);
    cfg.alternate_read_direction = true;
    cfg.pink_density_e_per_sqrt_hz = Some(1.0);
    let (rows, cols, w) = (256, 512, 256);
    let mut per_output = vec![Vec::new(), Vec::new()];
    for frame in 0..4 {
        let img = readout_noise_e(&cfg, rows, cols, 7, 0, frame);
        per_output[0].push(read_order(&img, 0, w, false));
        per_output[1].push(read_order(&img, 1, w, true));
    }
    let m = 4096;
    let df = 1.0 / (m as f64 * DT_S);
    for series in &per_output {
        let (f, s) = welch(series, m, DT_S);
        // Two decades: bins 8..800 of the 4096-sample segments.
        let (slope, _) = log_slope(&f, &s, 8.0 * df, 800.0 * df, 16);
        // Level: S·f = A² = 1 (e⁻/√Hz at 1 Hz)² over the same band (≈ 800 bins of
        // ≈ 124 segments each: ≈ 1 % statistical; bound 5 %).
        let band: Vec<f64> = f
            .iter()
            .zip(&s)
            .filter(|(fi, _)| **fi >= 8.0 * df && **fi <= 800.0 * df)
            .map(|(fi, si)| fi * si)
            .collect();
        let mean_sf = band.iter().sum::<f64>() / band.len() as f64;
        println!("readout-order PSD: slope {slope:.4} over bins 8–800, mean S·f {mean_sf:.4}");
        assert!((slope + 1.0).abs() < 0.1, "slope {slope}");
        assert!((mean_sf - 1.0).abs() < 0.05, "S·f = {mean_sf}, A² = 1");
    }
    // The two outputs' series are independent: their correlation is ~0 (σ ≈ 1/√dof
    // with dof ≈ 2·(Σ1/k)²/Σ1/k² ≈ 250 per frame, 4 frames → σ ≈ 0.03; bound 5σ).
    let (a, b): (Vec<f64>, Vec<f64>) = (per_output[0].concat(), per_output[1].concat());
    let ab: f64 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
    let aa: f64 = a.iter().map(|x| x * x).sum();
    let bb: f64 = b.iter().map(|x| x * x).sum();
    let rho = ab / (aa * bb).sqrt();
    assert!(rho.abs() < 0.15, "correlation between outputs {rho}");
}

/// Fits S(f) = a/f + b by iteratively reweighted least squares (weights 1/model², the
/// variance of a Welch average scales with its mean²).
fn fit_pink_plus_white(f: &[f64], s: &[f64]) -> (f64, f64) {
    let (mut a, mut b) = (1.0, 1.0);
    for iter in 0..6 {
        let (mut s11, mut s12, mut s22, mut t1, mut t2) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (&fi, &si) in f.iter().zip(s) {
            let x1 = 1.0 / fi;
            let wgt = if iter == 0 {
                1.0 / (si * si)
            } else {
                1.0 / (a * x1 + b).powi(2)
            };
            s11 += wgt * x1 * x1;
            s12 += wgt * x1;
            s22 += wgt;
            t1 += wgt * x1 * si;
            t2 += wgt * si;
        }
        let det = s11 * s22 - s12 * s12;
        a = (t1 * s22 - t2 * s12) / det;
        b = (s11 * t2 - s12 * t1) / det;
    }
    (a, b)
}

#[test]
fn white_floor_equals_the_white_read_noise() {
    // Pink density A = 1 e⁻/√Hz at 1 Hz plus white read noise σ_w = 10 e⁻ added here:
    // the spectrum is A²/f + 2·dt·σ_w², crossing over at f = A²/(2·dt·σ_w²) = 50 kHz,
    // a decade and a half below Nyquist (5 MHz).
    let mut cfg = base(1);
    cfg.pink_density_e_per_sqrt_hz = Some(1.0);
    let sigma_w = 10.0;
    let mut white = Xoshiro256PlusPlus::seed_from_u64(99);
    let series: Vec<Vec<f64>> = (0..4)
        .map(|frame| {
            let img = readout_noise_e(&cfg, 256, 256, 11, 0, frame);
            read_order(&img, 0, 256, false)
                .into_iter()
                .map(|v| v + sigma_w * white.sample::<f64, _>(StandardNormal))
                .collect()
        })
        .collect();
    let (f, s) = welch(&series, 4096, DT_S);
    let (f, s) = (&f[1..], &s[1..]);
    let (a, b) = fit_pink_plus_white(f, s);
    let sigma_hat = (b / (2.0 * DT_S)).sqrt();
    println!("white floor: σ̂ = {sigma_hat:.4} e⁻ (σ_w = {sigma_w}); pink A² = {a:.4} (1)");
    // ~2000 bins × 124 segments: the floor is known to ~0.1 %; bound 1 %.
    assert!((sigma_hat / sigma_w - 1.0).abs() < 0.01, "σ̂ = {sigma_hat}");
    assert!((a - 1.0).abs() < 0.05, "A² = {a}");
}

/// Mean of x² over every pixel of `frames` frames (the process is zero-mean).
fn mean_square(frames: &[Array2<f64>]) -> f64 {
    let n: usize = frames.iter().map(|f| f.len()).sum();
    frames
        .iter()
        .map(|f| f.iter().map(|v| v * v).sum::<f64>())
        .sum::<f64>()
        / n as f64
}

#[test]
fn sigma_per_frame_is_the_ensemble_rms_of_each_component() {
    // 4 outputs with overheads; each component alone, 40 frames of 128 × 256.
    // The ensemble variance of a pink series has ≈ 2·(Σ1/k)²/Σ1/k² ≈ 200 degrees of
    // freedom per frame (k over the ≈ 4000 bins of the band), so 40 frames give a
    // relative σ of ≈ 1.6 %; bound 6 %.
    let (rows, cols) = (128, 256);
    let mut cfg = base(4);
    cfg.row_overhead_px = 6;
    cfg.frame_overhead_rows = 3;
    cfg.alternate_read_direction = true;
    let cases: Vec<(&str, ReadoutNoiseConfig, f64)> = vec![
        (
            "pink",
            ReadoutNoiseConfig {
                pink_sigma_e: Some(3.0),
                ..cfg.clone()
            },
            3.0,
        ),
        (
            "correlated",
            ReadoutNoiseConfig {
                correlated_pink_sigma_e: Some(4.0),
                ..cfg.clone()
            },
            4.0,
        ),
        (
            "acn",
            ReadoutNoiseConfig {
                alternating_column_sigma_e: 2.0,
                ..cfg.clone()
            },
            2.0,
        ),
        (
            "row",
            ReadoutNoiseConfig {
                row_sigma_e: 1.5,
                ..cfg.clone()
            },
            1.5,
        ),
    ];
    for (name, c, sigma) in cases {
        c.validate(rows, cols).unwrap();
        let frames: Vec<Array2<f64>> = (0..40)
            .map(|f| readout_noise_e(&c, rows, cols, 3, 0, f))
            .collect();
        let ms = mean_square(&frames);
        println!(
            "σ per frame, {name}: rms {:.4} e⁻ for σ = {sigma}",
            ms.sqrt()
        );
        assert!(
            (ms / (sigma * sigma) - 1.0).abs() < 0.06,
            "{name}: rms {} for σ {sigma}",
            ms.sqrt()
        );
    }
}

/// ∫ A²/f · D(f)² df over [f_lo, f_N] by the trapezoid rule in ln f, with
/// D(f) = sin(π f w dt) / (w sin(π f dt)) the response of a mean over w consecutive
/// ticks.
fn row_mean_variance_quadrature(a: f64, w: usize, f_lo: f64, f_n: f64) -> f64 {
    let n = 400_000;
    let (u0, u1) = (f_lo.ln(), f_n.ln());
    let h = (u1 - u0) / n as f64;
    let g = |u: f64| {
        let f = u.exp();
        let x = std::f64::consts::PI * f * DT_S;
        let d = if x.sin().abs() < 1e-300 {
            1.0
        } else {
            (w as f64 * x).sin() / (w as f64 * x.sin())
        };
        a * a * d * d
    };
    (0..=n)
        .map(|i| {
            let wgt = if i == 0 || i == n { 0.5 } else { 1.0 };
            wgt * g(u0 + i as f64 * h)
        })
        .sum::<f64>()
        * h
}

#[test]
fn row_means_band_single_frames() {
    // 4 outputs of 64 columns, 8 idle ticks per row, 4 idle rows: 72 × 260 ticks.
    let (rows, cols, w) = (256, 256, 64);
    let mut cfg = base(4);
    cfg.row_overhead_px = 8;
    cfg.frame_overhead_rows = 4;
    let ticks = 72 * 260;
    let f_lo = 1.0 / (ticks as f64 * DT_S);
    let predicted = row_mean_variance_quadrature(1.0, w, f_lo, 0.5 / DT_S);
    let correlated = ReadoutNoiseConfig {
        correlated_pink_density_e_per_sqrt_hz: Some(1.0),
        ..cfg.clone()
    };
    let uncorrelated = ReadoutNoiseConfig {
        pink_density_e_per_sqrt_hz: Some(1.0),
        ..cfg.clone()
    };
    let frames = 48;
    let mut ensemble = [0.0, 0.0];
    for (i, c) in [&correlated, &uncorrelated].into_iter().enumerate() {
        for frame in 0..frames {
            let img = readout_noise_e(c, rows, cols, 5, 0, frame);
            let row_means = img.mean_axis(Axis(1)).unwrap();
            let col_means = img.mean_axis(Axis(0)).unwrap();
            let var = |v: &ndarray::Array1<f64>| {
                let m = v.mean().unwrap();
                v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / v.len() as f64
            };
            let pixel_var = img.iter().map(|x| x * x).sum::<f64>() / img.len() as f64;
            // Banding, visible in every single frame: row means scatter far more than
            // column means, and far more than white noise of the same rms would
            // (σ²/cols).
            if i == 0 {
                assert!(var(&row_means) > 10.0 * var(&col_means), "frame {frame}");
                assert!(
                    var(&row_means) > 10.0 * pixel_var / cols as f64,
                    "frame {frame}"
                );
            }
            ensemble[i] += row_means.iter().map(|x| x * x).sum::<f64>() / rows as f64;
        }
        ensemble[i] /= frames as f64;
    }
    // The row-mean variance is the 1/f spectrum through the w-tick mean (quadrature);
    // uncorrelated outputs average it down by the number of outputs. Monte Carlo:
    // ≈ 50 dof per frame × 48 frames → relative σ ≈ 3 %; bound 12 %.
    println!(
        "row-mean variance: {:.4} / {:.4}, quadrature {predicted:.4}",
        ensemble[0], ensemble[1]
    );
    assert!(
        (ensemble[0] / predicted - 1.0).abs() < 0.12,
        "{} vs {predicted}",
        ensemble[0]
    );
    assert!(
        (4.0 * ensemble[1] / predicted - 1.0).abs() < 0.12,
        "{} vs {}",
        ensemble[1],
        predicted / 4.0
    );
}

#[test]
fn row_mean_spectrum_of_single_frames_is_pink() {
    // One output of 32 columns, 2048 rows: the row-mean series of a frame, sampled once
    // per row, has the 1/f spectrum of the clock series below the row rate.
    let (rows, cols) = (2048, 32);
    let cfg = ReadoutNoiseConfig {
        correlated_pink_sigma_e: Some(5.0),
        ..base(1)
    };
    let series: Vec<Vec<f64>> = (0..8)
        .map(|frame| {
            readout_noise_e(&cfg, rows, cols, 9, 0, frame)
                .mean_axis(Axis(1))
                .unwrap()
                .to_vec()
        })
        .collect();
    let row_dt = cols as f64 * DT_S;
    let m = 1024;
    let (f, s) = welch(&series, m, row_dt);
    let df = 1.0 / (m as f64 * row_dt);
    // Row frequencies 4..300 bins: well below the row rate, where the w-tick mean
    // passes the spectrum and aliasing is small.
    let (slope, _) = log_slope(&f, &s, 4.0 * df, 300.0 * df, 12);
    println!("row-mean spectrum: slope {slope:.4} over row-frequency bins 4–300");
    assert!(
        (slope + 1.0).abs() < 0.15,
        "row-mean spectrum slope {slope}"
    );
}

#[test]
fn alternating_column_noise_follows_the_column_parity() {
    let (rows, cols) = (128, 128);
    let cfg = ReadoutNoiseConfig {
        alternating_column_sigma_e: 2.0,
        ..base(1)
    };
    let (mut same, mut other, mut aa) = (0.0, 0.0, 0.0);
    let mut nyquist_excess = 0.0;
    let frames = 40;
    for frame in 0..frames {
        let img = readout_noise_e(&cfg, rows, cols, 4, 0, frame);
        for r in 0..rows {
            for c in 0..cols - 2 {
                same += img[[r, c]] * img[[r, c + 2]];
                other += img[[r, c]] * img[[r, c + 1]];
                aa += img[[r, c]] * img[[r, c]];
            }
        }
        // Along each row the even and odd columns follow two slowly varying series:
        // the row's spatial spectrum peaks at 0.5 cycle/pixel (column stripes). Compare
        // the power at that frequency with the mean power at 0.2–0.3 cycle/pixel.
        for row in img.rows() {
            let dft2 = |nu: f64| {
                let (mut re, mut im) = (0.0, 0.0);
                for (c, v) in row.iter().enumerate() {
                    let ph = 2.0 * std::f64::consts::PI * nu * c as f64;
                    re += v * ph.cos();
                    im -= v * ph.sin();
                }
                re * re + im * im
            };
            let mid: f64 = (26..=38).map(|k| dft2(k as f64 / cols as f64)).sum::<f64>() / 13.0;
            nyquist_excess += dft2(0.5) / mid / rows as f64;
        }
    }
    let (rho_same, rho_other) = (same / aa, other / aa);
    println!(
        "acn: ρ(same parity) = {rho_same:.4}, ρ(opposite) = {rho_other:.4}, \
         stripe power / mid-frequency power = {:.1}",
        nyquist_excess / frames as f64
    );
    // Same parity two columns apart: consecutive samples (lag Δ = 2 ticks) of one pink
    // series with PSD A²/f on [f_lo, f_N = 1/(2Δ)]: its autocorrelation is
    // ρ = 1 − ∫(1 − cos 2πfΔ)/f df / ln(f_N/f_lo) = 1 − Cin(π)/ln(N/4), N = 16384
    // ticks, Cin(π) = ∫₀^π (1 − cos x)/x dx by quadrature here (≈ 1.648). Monte Carlo
    // σ ≈ 0.01; bound 0.04.
    let n_q = 100_000;
    let cin_pi: f64 = (0..n_q)
        .map(|i| {
            let x = (i as f64 + 0.5) * std::f64::consts::PI / n_q as f64;
            (1.0 - x.cos()) / x
        })
        .sum::<f64>()
        * std::f64::consts::PI
        / n_q as f64;
    let rho_pred = 1.0 - cin_pi / (16384.0f64 / 4.0).ln();
    assert!(
        (rho_same - rho_pred).abs() < 0.04,
        "same-parity correlation {rho_same} vs {rho_pred}"
    );
    // Neighbours of opposite parity: independent series (σ ≈ 0.02; bound 5σ).
    assert!(
        rho_other.abs() < 0.1,
        "opposite-parity correlation {rho_other}"
    );
    // Stripes: the alternation outweighs mid frequencies by far (white noise: ≈ 1).
    assert!(
        nyquist_excess / frames as f64 > 20.0,
        "{}",
        nyquist_excess / frames as f64
    );
}

#[test]
fn row_noise_offsets_whole_rows() {
    let (rows, cols) = (512, 64);
    let cfg = ReadoutNoiseConfig {
        row_sigma_e: 1.5,
        ..base(2)
    };
    let mut sum2 = 0.0;
    for frame in 0..30 {
        let img = readout_noise_e(&cfg, rows, cols, 8, 0, frame);
        for row in img.rows() {
            assert!(row.iter().all(|v| *v == row[0]));
            sum2 += row[0] * row[0];
        }
    }
    // 15360 normal draws: relative σ of the variance ≈ 1.1 %; bound 5 %.
    let var = sum2 / (30.0 * rows as f64);
    assert!((var / 2.25 - 1.0).abs() < 0.05, "{var}");
}

fn all_on(outputs: usize) -> ReadoutNoiseConfig {
    ReadoutNoiseConfig {
        row_overhead_px: 4,
        frame_overhead_rows: 2,
        alternate_read_direction: true,
        pink_sigma_e: Some(2.0),
        correlated_pink_density_e_per_sqrt_hz: Some(0.5),
        alternating_column_sigma_e: 1.0,
        row_sigma_e: 0.7,
        ..base(outputs)
    }
}

#[test]
fn same_seed_same_frame_bit_identical_on_any_thread_count() {
    let cfg = all_on(4);
    let a = readout_noise_e(&cfg, 64, 96, 1, 2, 3);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let b = pool.install(|| readout_noise_e(&cfg, 64, 96, 1, 2, 3));
    assert_eq!(a, b);
    assert_ne!(a, readout_noise_e(&cfg, 64, 96, 1, 2, 4));
    assert_ne!(a, readout_noise_e(&cfg, 64, 96, 1, 3, 3));
    assert_ne!(a, readout_noise_e(&cfg, 64, 96, 2, 2, 3));
}

#[test]
fn components_are_independent_streams() {
    // Switching the row noise on adds exactly the row offsets and leaves the pink
    // components' numbers unchanged.
    let pink = ReadoutNoiseConfig {
        row_sigma_e: 0.0,
        ..all_on(2)
    };
    let rows_only = ReadoutNoiseConfig {
        pink_sigma_e: None,
        correlated_pink_density_e_per_sqrt_hz: None,
        alternating_column_sigma_e: 0.0,
        ..all_on(2)
    };
    let both = readout_noise_e(&all_on(2), 32, 64, 5, 0, 1);
    let p = readout_noise_e(&pink, 32, 64, 5, 0, 1);
    let r = readout_noise_e(&rows_only, 32, 64, 5, 0, 1);
    for ((b, p), r) in both.iter().zip(&p).zip(&r) {
        assert!((b - p - r).abs() < 1e-12);
    }
}

/// `Cin(x) = ∫₀ˣ (1 − cos t)/t dt` by composite Simpson, 32 intervals per period of cos
/// (the integrand is smooth, ≈ t/2 at 0).
fn cin(x: f64) -> f64 {
    if x == 0.0 {
        return 0.0;
    }
    let n = 2 * ((x / std::f64::consts::TAU * 16.0).ceil() as usize).max(8);
    let h = x / n as f64;
    let f = |t: f64| {
        if t == 0.0 {
            0.0
        } else {
            (1.0 - t.cos()) / t
        }
    };
    let inner: f64 = (1..n)
        .map(|i| if i % 2 == 1 { 4.0 } else { 2.0 } * f(i as f64 * h))
        .sum();
    (f(0.0) + inner + f(x)) * h / 3.0
}

#[test]
fn pink_covariance_over_the_frame_matches_the_model_at_every_lag() {
    // The covariance of the synthesised series at lag τ follows from the bin table alone:
    // x_t = X_0 + X_{L/2}(−1)^t + 2 Σ Re(X_k e^{2πikt/L}) with X_k = sd_k·(g + i g'), so
    // R(τ) = Σ_k 4·sd_k²·cos(2πkτ/L) + sd_{L/2}²·(−1)^τ (per unit density). The model's is
    // ∫ cos(2πfτΔt)/f df over [1/(NΔt), 1/(2Δt)] = ln(N/2) − Cin(πτ) + Cin(2πτ/N).
    // Frame of N = 65536 ticks (the PSD test's); lags from 0 to N − 1, dense at the far
    // end where a short grid wraps around.
    let n = 65536usize;
    let series = PinkSeries {
        len: n,
        step: 1,
        frame_ticks: n,
    };
    let mut lags: Vec<usize> = vec![0, 1, 2, 3, 5, 10, 30, 100, 300, 1000, 3000, 10_000];
    lags.extend((1..128).map(|i| i * n / 128));
    lags.push(n - 1);
    let pi = std::f64::consts::PI;
    let var = (n as f64 / 2.0).ln();
    let model: Vec<f64> = lags
        .iter()
        .map(|&t| var - cin(pi * t as f64) + cin(2.0 * pi * t as f64 / n as f64))
        .collect();
    let covariance = |l: usize| -> Vec<f64> {
        let table = series.bin_table_on(l);
        let half = l / 2;
        lags.iter()
            .map(|&t| {
                let w = std::f64::consts::TAU * t as f64 / l as f64;
                let interior: f64 = (table.first..half)
                    .map(|k| {
                        let sd = f64::from(table.sd[k]);
                        4.0 * sd * sd * (w * k as f64).cos()
                    })
                    .sum();
                let nyq = f64::from(table.sd[half]).powi(2);
                interior + if t % 2 == 0 { nyq } else { -nyq }
            })
            .collect()
    };
    let worst = |l: usize| -> (f64, usize) {
        let c = covariance(l);
        c.iter()
            .zip(&model)
            .zip(&lags)
            .map(|((c, m), &t)| ((c - m).abs() / var, t))
            .fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a })
    };
    let used = series.grid_len();
    let c0 = covariance(used)[0];
    let (e_used, t_used) = worst(used);
    let (e_short, t_short) = worst(crate::fft_size::next_fast_even_len(n + n / 4));
    println!(
        "pink covariance against the model, max |ΔR|/R(0) over the frame's lags: \
         L = {used} (2 N) {:.2} % at lag {:.2} N; L = 1.25 N {:.2} % at {:.2} N; \
         variance {c0:.6} (model {var:.6})",
        100.0 * e_used,
        t_used as f64 / n as f64,
        100.0 * e_short,
        t_short as f64 / n as f64,
    );
    // The variance is the model's exactly (f32 rounding of the table: ~1e-7).
    assert!((c0 / var - 1.0).abs() < 1e-5, "variance {c0} vs {var}");
    // Every lag within 1.5 % of the variance (measured 1.04 % at 0.79 N, where the model's
    // own ringing from its cut at f_lo is aliased back from beyond the frame); a grid too
    // short to stop the wrap-around (1.25 N) fails the bound.
    assert!(e_used < 0.015, "{e_used}");
    assert!(e_short > 0.03, "{e_short}");
}

#[test]
fn log_ratio_series_matches_the_logarithm() {
    for k in 8..2000 {
        let (hi, lo) = (k as f64 + 0.5, k as f64 - 0.5);
        let exact = (hi / lo).ln();
        assert!((log_ratio(hi, lo) / exact - 1.0).abs() < 1e-10, "k = {k}");
    }
    assert_eq!(log_ratio(3.5, 2.25), (3.5f64 / 2.25).ln());
}

#[test]
fn zero_amplitudes_give_zeros() {
    let img = readout_noise_e(&base(4), 16, 32, 1, 0, 0);
    assert!(img.iter().all(|v| *v == 0.0));
    let cfg = ReadoutNoiseConfig {
        pink_sigma_e: Some(0.0),
        ..base(4)
    };
    assert!(readout_noise_e(&cfg, 16, 32, 1, 0, 0)
        .iter()
        .all(|v| *v == 0.0));
}

#[test]
fn frame_and_pixel_read_times_follow_the_clock() {
    // 640 × 512, 4 outputs of 160 columns, 8 idle ticks per row, 2 idle rows, 100 ns.
    let cfg = ReadoutNoiseConfig {
        row_overhead_px: 8,
        frame_overhead_rows: 2,
        alternate_read_direction: true,
        ..base(4)
    };
    let t = cfg.frame_readout_s(512, 640);
    assert!((t - 168.0 * 514.0 * 1e-7).abs() < 1e-15, "{t}");
    assert_eq!(cfg.pixel_read_time_s(640, 0, 0), 0.0);
    // Output 1 is mirrored: its first read is its rightmost column, 319.
    assert_eq!(cfg.pixel_read_time_s(640, 0, 319), 0.0);
    assert!((cfg.pixel_read_time_s(640, 0, 160) - 159e-7).abs() < 1e-18);
    // Column 161 is output 1's second column from the left: its 159th read (j = 158).
    assert!((cfg.pixel_read_time_s(640, 2, 161) - (2.0 * 168.0 + 158.0) * 1e-7).abs() < 1e-15);
    assert!((cfg.pixel_read_time_s(640, 2, 321) - (2.0 * 168.0 + 1.0) * 1e-7).abs() < 1e-15);
    // The last pixel is read one row overhead plus the frame overhead before the end.
    let last = cfg.pixel_read_time_s(640, 511, 159);
    assert!((t - last - (8.0 + 1.0 + 2.0 * 168.0) * 1e-7).abs() < 1e-15);
}

#[test]
fn crosstalk_copies_a_bright_pixel_to_the_same_clock_step_of_the_other_outputs() {
    let m = vec![
        vec![0.0, 1e-3, 2e-3, 3e-3],
        vec![4e-3, 0.0, 5e-3, 6e-3],
        vec![7e-3, 8e-3, 0.0, 9e-3],
        vec![1e-2, 2e-2, 3e-2, 0.0],
    ];
    let cfg = ReadoutNoiseConfig {
        alternate_read_direction: true,
        output_crosstalk: Some(m),
        ..base(4)
    };
    cfg.validate(6, 32).unwrap();
    // Stripes of 8: output 0 reads columns 0..8 left to right, output 1 columns 15..8,
    // output 2 16..24, output 3 31..24. Column 2 is output 0's third read.
    let mut img = Array2::zeros((6, 32));
    img[[3, 2]] = 1000.0;
    apply_output_crosstalk(&cfg, &mut img);
    let mut expected = Array2::zeros((6, 32));
    expected[[3, 2]] = 1000.0;
    expected[[3, 13]] = 4.0;
    expected[[3, 18]] = 7.0;
    expected[[3, 29]] = 10.0;
    for (a, b) in img.iter().zip(&expected) {
        assert!((a - b).abs() < 1e-12, "{img:?}");
    }
    // A flat field v: output o reads v·(1 + Σ_p M[o][p]).
    let mut flat = Array2::from_elem((6, 32), 100.0);
    apply_output_crosstalk(&cfg, &mut flat);
    for (o, sum) in [0.006, 0.015, 0.024, 0.06].into_iter().enumerate() {
        for c in o * 8..o * 8 + 8 {
            assert!((flat[[0, c]] - 100.0 * (1.0 + sum)).abs() < 1e-10);
        }
    }
    // Absent matrix: unchanged.
    let mut same = expected.clone();
    apply_output_crosstalk(&base(4), &mut same);
    assert_eq!(same, expected);
}

#[test]
fn bad_parameters_are_errors_naming_the_field() {
    let err = |c: &ReadoutNoiseConfig| c.validate(8, 12).unwrap_err().to_string();
    assert!(err(&base(5)).contains("detector.readout_noise.outputs"));
    assert!(err(&base(0)).contains("detector.readout_noise.outputs"));
    assert!(err(&ReadoutNoiseConfig {
        pixel_time_s: f64::NAN,
        ..base(1)
    })
    .contains("pixel_time_s"));
    assert!(err(&ReadoutNoiseConfig {
        pixel_time_s: -1e-7,
        ..base(1)
    })
    .contains("pixel_time_s"));
    assert!(err(&ReadoutNoiseConfig {
        pink_sigma_e: Some(-1.0),
        ..base(1)
    })
    .contains("pink_sigma_e"));
    let both = ReadoutNoiseConfig {
        correlated_pink_sigma_e: Some(1.0),
        correlated_pink_density_e_per_sqrt_hz: Some(1.0),
        ..base(1)
    };
    assert!(err(&both).contains("correlated_pink_density_e_per_sqrt_hz"));
    assert!(err(&ReadoutNoiseConfig {
        alternating_column_sigma_e: f64::INFINITY,
        ..base(1)
    })
    .contains("alternating_column_sigma_e"));
    assert!(err(&ReadoutNoiseConfig {
        row_sigma_e: -0.1,
        ..base(1)
    })
    .contains("row_sigma_e"));
    let xt = |m: Vec<Vec<f64>>| ReadoutNoiseConfig {
        output_crosstalk: Some(m),
        ..base(2)
    };
    assert!(err(&xt(vec![vec![0.0, 0.1]])).contains("output_crosstalk"));
    assert!(err(&xt(vec![vec![0.0, 0.1], vec![0.1]])).contains("output_crosstalk[1]"));
    assert!(err(&xt(vec![vec![0.1, 0.1], vec![0.1, 0.0]])).contains("output_crosstalk[0][0]"));
    assert!(err(&xt(vec![vec![0.0, 1.5], vec![0.1, 0.0]])).contains("output_crosstalk[0][1]"));
    assert!(err(&xt(vec![vec![0.0, f64::NAN], vec![0.1, 0.0]])).contains("output_crosstalk[0][1]"));
    assert!(xt(vec![vec![0.0, -0.01], vec![0.02, 0.0]])
        .validate(8, 12)
        .is_ok());
}

#[test]
fn toml_table_parses_and_refuses_unknown_keys() {
    let text = r#"
        outputs = 4
        pixel_time_s = 1e-7
        row_overhead_px = 8
        frame_overhead_rows = 2
        alternate_read_direction = true
        pink_sigma_e = 3.0
        correlated_pink_density_e_per_sqrt_hz = 0.5
        alternating_column_sigma_e = 1.0
        row_sigma_e = 2.0
        output_crosstalk = [[0, 1e-3, 0, 0], [1e-3, 0, 1e-3, 0], [0, 1e-3, 0, 1e-3], [0, 0, 1e-3, 0]]
    "#;
    let cfg: ReadoutNoiseConfig = toml::from_str(text).unwrap();
    cfg.validate(512, 640).unwrap();
    assert_eq!(cfg.outputs, 4);
    let minimal: ReadoutNoiseConfig = toml::from_str("pixel_time_s = 1e-7").unwrap();
    assert_eq!(minimal, base(1));
    assert!(toml::from_str::<ReadoutNoiseConfig>("pixel_time_s = 1e-7\npink_sigma = 1").is_err());
}
