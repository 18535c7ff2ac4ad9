//! The line of sight and the clock (`eoir::los`) against independent truths: the motion
//! OTF of a linear path against the closed-form sinc, of whole-period vibration against
//! J0 (libm), of a curved path against brute-force quadrature, of a long Gaussian wander
//! against exp(−2π²σ²f²); the wander's variance and periodogram against its PSD; the
//! window sampler's error bound measured; the clock's windows and refusals; the CSV reader
//! and its errors; the `[clock]` / `[trajectory]` schema through `--set`.

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use eoir::los::{
    Clock, ClockConfig, LineOfSight, LosAxis, MeasuredTrajectory, Shutter, TrajectoryConfig,
    VibrationConfig, WanderConfig,
};
use eoir::sensor::{MotionConfig, SensorConfig};
use num_complex::Complex64;

/// sin(πx)/(πx), written out here (not the library's).
fn sinc(x: f64) -> f64 {
    if x == 0.0 {
        1.0
    } else {
        (PI * x).sin() / (PI * x)
    }
}

fn vib(axis: LosAxis, amplitude_rad: f64, frequency_hz: f64, phase_deg: f64) -> VibrationConfig {
    VibrationConfig {
        axis,
        amplitude_rad,
        frequency_hz,
        phase_deg,
    }
}

fn trajectory() -> TrajectoryConfig {
    TrajectoryConfig::default()
}

fn los(t: &TrajectoryConfig, integration_time_s: f64, seed: u64, span: (f64, f64)) -> LineOfSight {
    LineOfSight::new(Some(t), None, integration_time_s, seed, span, None).unwrap()
}

#[test]
fn linear_path_otf_is_the_closed_form_sinc() {
    // 10 m/s at 1 km (0.01 rad/s) at 30°, plus a pan: one constant rate.
    let motion = MotionConfig {
        enabled: true,
        smear_rad: None,
        angular_rate_rad_s: None,
        velocity_m_s: Some(10.0),
        range_m: Some(1000.0),
        direction_deg: 30.0,
    };
    let mut t = trajectory();
    t.pan_rate_rad_s = Some([2e-3, -1e-3]);
    let t_int = 2e-3;
    let l = LineOfSight::new(Some(&t), Some(&motion), t_int, 1, (0.0, 1.0), None).unwrap();
    assert!(l.is_linear() && !l.is_still());
    let rate = [
        0.01 * 30f64.to_radians().cos() + 2e-3,
        0.01 * 30f64.to_radians().sin() - 1e-3,
    ];
    let r = l.rate_rad_s();
    assert!((r[0] - rate[0]).abs() < 1e-15 && (r[1] - rate[1]).abs() < 1e-15);
    let (t0, t1) = (0.3, 0.3 + t_int);
    let w = l.window(t0, t1, 1e-12);
    assert_eq!(w.segments(), 1, "a linear motion needs one segment");
    // The mean is the position at mid-window.
    for (m, r) in w.mean_rad.iter().zip(rate) {
        assert!((m - r * 0.5 * (t0 + t1)).abs() < 1e-15);
    }
    let smear = [rate[0] * t_int, rate[1] * t_int];
    assert!((w.smear_rad() - smear[0].hypot(smear[1])).abs() < 1e-15);
    for i in 0..40 {
        let fx = -3e5 + i as f64 * 1.7e4;
        let fy = 2e5 - i as f64 * 0.9e4;
        let h = w.otf(fx, fy);
        let truth = sinc(fx * smear[0] + fy * smear[1]);
        assert!(
            (h.re - truth).abs() < 1e-12 && h.im.abs() < 1e-12,
            "{h} vs {truth}"
        );
    }
    // A still line of sight.
    let still = LineOfSight::new(None, None, t_int, 1, (0.0, 1.0), None).unwrap();
    assert!(still.is_still());
    assert_eq!(still.displacement_rad(0.7), [0.0, 0.0]);
    assert_eq!(
        still.window(0.0, t_int, 1e-9).otf(1e4, 1e4),
        Complex64::new(1.0, 0.0)
    );
}

#[test]
fn smear_rad_drift_uses_the_integration_time() {
    let motion = MotionConfig {
        enabled: true,
        smear_rad: Some(3e-5),
        angular_rate_rad_s: None,
        velocity_m_s: None,
        range_m: None,
        direction_deg: 90.0,
    };
    let l = LineOfSight::new(None, Some(&motion), 1.5e-3, 0, (0.0, 1.0), None).unwrap();
    let r = l.rate_rad_s();
    assert!(r[0].abs() < 1e-15 && (r[1] - 0.02).abs() < 1e-15, "{r:?}");
    // +90° is +y (down the rows): the displacement grows along +y.
    assert!((l.displacement_rad(0.5)[1] - 0.01).abs() < 1e-15);
}

#[test]
fn vibration_over_whole_periods_gives_j0() {
    // 10 periods of 500 Hz in T = 20 ms: H(f) = J0(2π a f) exactly (Bessel's integral).
    let a = 3e-5;
    for (axis, ex, ey) in [(LosAxis::X, 1.0, 0.0), (LosAxis::Y, 0.0, 1.0)] {
        let mut t = trajectory();
        t.vibration = vec![vib(axis, a, 500.0, 37.0)];
        let l = los(&t, 0.02, 0, (0.0, 1.0));
        assert!(!l.is_linear());
        let w = l.try_window(0.1, 0.12, 1e-10).unwrap();
        assert!(w.interpolation_bound_rad() <= 1e-10);
        for i in 0..=40 {
            let f = i as f64 * 500.0; // f·a up to 0.6
            let h = w.otf(f * ex, f * ey);
            let truth = libm::j0(2.0 * PI * a * f);
            assert!((h - truth).norm() < 1e-3, "f = {f}: {h} vs J0 = {truth}");
        }
        // The blur has no residual shift: the mean is zero over whole periods.
        assert!(w.mean_rad[0].hypot(w.mean_rad[1]) < 1e-9 * a);
    }
}

#[test]
fn curved_path_otf_matches_brute_force_quadrature() {
    // A circular arc: x = r cos ωt, y = r sin ωt over 0.35 of a period.
    let r = 2e-5;
    let nu = 50.0;
    let mut t = trajectory();
    t.vibration = vec![vib(LosAxis::X, r, nu, 90.0), vib(LosAxis::Y, r, nu, 0.0)];
    let l = los(&t, 7e-3, 0, (0.0, 1.0));
    let (t0, t1) = (0.013, 0.020);
    let w = l.try_window(t0, t1, 2e-12).unwrap();
    let d = |s: f64| [r * (2.0 * PI * nu * s).cos(), r * (2.0 * PI * nu * s).sin()];
    let n = 100_000;
    let mut max_im = 0.0f64;
    for (fx, fy) in [
        (1e4, 0.0),
        (0.0, 2e4),
        (2e4, -1.5e4),
        (-9e3, 2.2e4),
        (3e4, 5e3),
    ] {
        let mut brute = Complex64::new(0.0, 0.0);
        for k in 0..n {
            let s = t0 + (k as f64 + 0.5) * (t1 - t0) / n as f64;
            let p = d(s);
            brute += Complex64::from_polar(1.0, -2.0 * PI * (fx * p[0] + fy * p[1]));
        }
        brute /= n as f64;
        // The library's OTF is about the window's mean: put the mean's phase back.
        let shift =
            Complex64::from_polar(1.0, -2.0 * PI * (fx * w.mean_rad[0] + fy * w.mean_rad[1]));
        let h = w.otf(fx, fy) * shift;
        assert!(
            (h - brute).norm() < 1e-6,
            "f = ({fx}, {fy}): {h} vs {brute}"
        );
        max_im = max_im.max(w.otf(fx, fy).im.abs());
    }
    assert!(
        max_im > 1e-2,
        "a curved path has a complex OTF (max |Im| = {max_im})"
    );
}

/// A measured trajectory file in a temporary directory.
fn write_csv(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn window_interpolant_stays_within_its_bound() {
    let mut t = trajectory();
    t.pan_rate_rad_s = Some([1e-3, 2e-3]);
    t.vibration = vec![
        vib(LosAxis::X, 4e-6, 230.0, 10.0),
        vib(LosAxis::Y, 2e-6, 710.0, 0.0),
    ];
    t.wander = Some(WanderConfig::PowerLaw {
        psd_at_1hz_rad2_per_hz: 1e-11,
        exponent: -1.0,
        f_min_hz: 0.5,
        f_max_hz: 300.0,
    });
    let l = los(&t, 5e-3, 9, (0.0, 0.5));
    let dir = tempfile::tempdir().unwrap();
    let csv = write_csv(
        dir.path(),
        "los.csv",
        "t_s,az_rad,el_rad\n0,0,0\n0.011,2e-5,-1e-5\n0.013,-3e-5,1e-5\n0.02,0,0\n0.6,1e-4,1e-4\n",
    );
    let mut tm = trajectory();
    tm.file = Some(csv);
    let m = LineOfSight::new(Some(&tm), None, 5e-3, 0, (0.0, 0.5), None).unwrap();
    for (line, name) in [(&l, "modelled"), (&m, "measured")] {
        for (k, t0) in [0.0, 0.0105, 0.2, 0.4951].into_iter().enumerate() {
            let t1 = t0 + 5e-3;
            for tol in [1e-7, 1e-9] {
                let w = line.try_window(t0, t1, tol).unwrap();
                let bound = w.interpolation_bound_rad();
                assert!(
                    bound <= tol * (1.0 + 1e-12),
                    "{name} {k}: bound {bound} > {tol}"
                );
                let mut worst = 0.0f64;
                for i in 0..=3000 {
                    let s = i as f64 / 3000.0;
                    let p = w.at(s);
                    let d = line.displacement_rad(t0 + s * (t1 - t0));
                    let e = (p[0] + w.mean_rad[0] - d[0]).hypot(p[1] + w.mean_rad[1] - d[1]);
                    worst = worst.max(e);
                }
                // Rounding of positions ~1e-3 rad at 1e-16 relative is far below.
                assert!(
                    worst <= bound + 1e-15,
                    "{name} {k}: error {worst} > bound {bound}"
                );
            }
        }
    }
}

/// ∫ A f^e df over [lo, hi], closed form (e ≠ −1).
fn power_law_variance(a: f64, e: f64, lo: f64, hi: f64) -> f64 {
    a * (hi.powf(e + 1.0) - lo.powf(e + 1.0)) / (e + 1.0)
}

#[test]
fn wander_variance_is_the_psd_integral() {
    // S = A f^(−1.5) on [1, 20] Hz; E[x²] = ∫S df per axis. Each realisation's mean square
    // over 10 s is one estimate; the tolerance is 5 standard errors of their mean, the
    // standard error estimated from the realisations themselves.
    let (a, e, lo, hi) = (1e-10, -1.5, 1.0, 20.0);
    let var = power_law_variance(a, e, lo, hi);
    let mut t = trajectory();
    t.wander = Some(WanderConfig::PowerLaw {
        psd_at_1hz_rad2_per_hz: a,
        exponent: e,
        f_min_hz: lo,
        f_max_hz: hi,
    });
    let mut estimates = Vec::new();
    for seed in 0..40 {
        let l = los(&t, 0.01, seed, (0.0, 10.0));
        for axis in 0..2 {
            let ms: f64 = (0..2000)
                .map(|i| l.displacement_rad(i as f64 * 5e-3)[axis].powi(2))
                .sum::<f64>()
                / 2000.0;
            estimates.push(ms);
        }
    }
    let k = estimates.len() as f64;
    let mean = estimates.iter().sum::<f64>() / k;
    let sd = (estimates.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (k - 1.0)).sqrt();
    let se = sd / k.sqrt();
    assert!(
        (mean - var).abs() < 5.0 * se,
        "mean square {mean:.4e} vs ∫S df {var:.4e} (standard error {se:.2e})"
    );
    assert!(se < 0.1 * var, "the test has power: se {se:.2e}");
}

/// S(f) of a log-log table, written out here.
fn table_psd(f_hz: &[f64], s: &[f64], f: f64) -> f64 {
    if f < f_hz[0] || f > f_hz[f_hz.len() - 1] {
        return 0.0;
    }
    let j = (1..f_hz.len()).find(|&j| f <= f_hz[j]).unwrap();
    let b = (s[j] / s[j - 1]).ln() / (f_hz[j] / f_hz[j - 1]).ln();
    s[j - 1] * (f / f_hz[j - 1]).powf(b)
}

#[test]
fn wander_periodogram_matches_the_psd() {
    // Averaged one-sided periodograms of 4 s blocks (rectangular window, 0.25 Hz bins)
    // from 2 seeds × 2 axes × 50 blocks, and 3 adjacent bins: each bin's periodogram is
    // S·χ²₂/2 (mean S, relative sd 1), so the average of K = 600 has relative sd
    // 1/√600 = 0.041. Tolerance: 5 sd, plus 3 % for the rectangular window's leakage from
    // the band edges (≥ 1 Hz away from every test frequency).
    let f_hz = vec![1.0, 5.0, 20.0];
    let s = vec![1e-10, 4e-11, 1e-11];
    let mut t = trajectory();
    t.wander = Some(WanderConfig::Table {
        frequency_hz: f_hz.clone(),
        psd_rad2_per_hz: s.clone(),
    });
    let dt = 0.01;
    let block = 400;
    let blocks = 50;
    let test_bins = [8usize, 12, 24, 40, 60]; // 2, 3, 6, 10, 15 Hz
    let mut sums = vec![0.0; test_bins.len()];
    let mut count: f64 = 0.0;
    for seed in [3u64, 4] {
        let l = los(&t, 0.01, seed, (0.0, block as f64 * blocks as f64 * dt));
        for axis in 0..2 {
            for b in 0..blocks {
                let x: Vec<f64> = (0..block)
                    .map(|i| l.displacement_rad((b * block + i) as f64 * dt)[axis])
                    .collect();
                for (n, &j0) in test_bins.iter().enumerate() {
                    for j in j0 - 1..=j0 + 1 {
                        let mut z = Complex64::new(0.0, 0.0);
                        for (i, xi) in x.iter().enumerate() {
                            z += Complex64::from_polar(
                                *xi,
                                -2.0 * PI * (j * i) as f64 / block as f64,
                            );
                        }
                        // One-sided PSD estimate: 2 |X|² Δt / N.
                        sums[n] += 2.0 * z.norm_sqr() * dt / block as f64;
                    }
                }
                count += 3.0;
            }
        }
    }
    let tol = 5.0 / count.sqrt() + 0.03;
    for (n, &j) in test_bins.iter().enumerate() {
        let f = j as f64 / (block as f64 * dt);
        let est = sums[n] / count;
        let truth = table_psd(&f_hz, &s, f);
        assert!(
            (est / truth - 1.0).abs() < tol,
            "f = {f} Hz: periodogram {est:.3e} vs S {truth:.3e} (tolerance {tol:.3})"
        );
    }
}

#[test]
fn wander_is_reproducible_and_seeded() {
    let mut t = trajectory();
    t.wander = Some(WanderConfig::PowerLaw {
        psd_at_1hz_rad2_per_hz: 1e-10,
        exponent: -2.0,
        f_min_hz: 0.5,
        f_max_hz: 40.0,
    });
    let a = los(&t, 1e-3, 42, (0.0, 2.0));
    let b = los(&t, 1e-3, 42, (0.0, 2.0));
    let c = los(&t, 1e-3, 43, (0.0, 2.0));
    let mut differ = 0;
    for i in 0..100 {
        let s = i as f64 * 0.0173;
        let (da, db, dc) = (
            a.displacement_rad(s),
            b.displacement_rad(s),
            c.displacement_rad(s),
        );
        assert_eq!(da[0].to_bits(), db[0].to_bits());
        assert_eq!(da[1].to_bits(), db[1].to_bits());
        differ += usize::from(da != dc);
    }
    assert_eq!(differ, 100);
    // The two axes are independent realisations, not copies.
    assert_ne!(a.displacement_rad(0.5)[0], a.displacement_rad(0.5)[1]);
}

#[test]
fn long_wander_window_approaches_the_gaussian_jitter_mtf() {
    // A Gaussian process averaged over a window of many correlation times: (1/T)∫e^{−2πif·x}
    // → E[e^{−2πif·x}] = exp(−2π²σ²|f|²). Flat PSD on 5–50 Hz, σ = 10 µrad, T_w = 100 s:
    // about 2·B·T_w = 9000 independent samples, so the time average's standard error is
    // ≤ √(1/9000) = 0.011; tolerance 0.04. The path error adds ≤ 2π|f|·8e-9 ≤ 1.1e-3.
    let sigma = 1e-5;
    let a = sigma * sigma / 45.0;
    let mut t = trajectory();
    t.wander = Some(WanderConfig::PowerLaw {
        psd_at_1hz_rad2_per_hz: a,
        exponent: 0.0,
        f_min_hz: 5.0,
        f_max_hz: 50.0,
    });
    let l = los(&t, 100.0, 5, (0.0, 100.0));
    let w = l.try_window(0.0, 100.0, 8e-9).unwrap();
    for (fx, fy) in [(5e3, 0.0), (0.0, 1e4), (1.4e4, 1.4e4), (2e4, 0.0)] {
        let shift =
            Complex64::from_polar(1.0, -2.0 * PI * (fx * w.mean_rad[0] + fy * w.mean_rad[1]));
        let h = w.otf(fx, fy) * shift;
        let truth = (-2.0 * PI * PI * sigma * sigma * (fx * fx + fy * fy)).exp();
        assert!(
            (h - truth).norm() < 0.04,
            "f = ({fx}, {fy}): {h} vs {truth}"
        );
    }
}

fn clock_cfg(rate: f64, shutter: Shutter, line: Option<f64>) -> ClockConfig {
    ClockConfig {
        frame_rate_hz: Some(rate),
        frame_times_s: None,
        shutter,
        line_time_s: line,
    }
}

#[test]
fn clock_gives_frame_and_row_windows() {
    let g = Clock::new(&clock_cfg(50.0, Shutter::Global, None), 1e-3, 10, 4).unwrap();
    assert_eq!(g.frames(), 4);
    assert!((g.frame_start_s(2) - 0.04).abs() < 1e-15);
    let (a, b) = g.row_window_s(2, 7);
    assert!((a - 0.04).abs() < 1e-15 && (b - 0.041).abs() < 1e-15);
    assert_eq!(g.line_time_s(), None);
    let span = g.span_s();
    assert!(span.0 == 0.0 && (span.1 - 0.061).abs() < 1e-15);

    let r = Clock::new(&clock_cfg(50.0, Shutter::Rolling, Some(1e-4)), 1e-3, 10, 4).unwrap();
    assert_eq!(r.line_time_s(), Some(1e-4));
    let (a, b) = r.row_window_s(1, 9);
    assert!((a - (0.02 + 9e-4)).abs() < 1e-15 && (b - (0.02 + 9e-4 + 1e-3)).abs() < 1e-15);
    assert!((r.span_s().1 - (0.06 + 9e-4 + 1e-3)).abs() < 1e-15);
    assert_eq!(r.integration_time_s(), 1e-3);

    let times = ClockConfig {
        frame_rate_hz: None,
        frame_times_s: Some(vec![0.0, 0.1, 0.25, 0.3]),
        shutter: Shutter::Global,
        line_time_s: None,
    };
    let c = Clock::new(&times, 1e-3, 10, 3).unwrap();
    assert_eq!(c.frames(), 3);
    assert_eq!(c.frame_start_s(2), 0.25);
    assert!(Clock::from_config(None, 1e-3, 10, 3).unwrap().is_none());
}

#[test]
fn clock_refuses_overlaps_and_bad_times() {
    let msg =
        |c: &ClockConfig, frames: usize| Clock::new(c, 1e-3, 100, frames).unwrap_err().to_string();
    // Rolling: 99 × 2e-4 + 1e-3 = 20.8 ms > 20 ms period.
    let e = msg(&clock_cfg(50.0, Shutter::Rolling, Some(2e-4)), 2);
    assert!(
        e.contains("clock.frame_rate_hz") && e.contains("overlap"),
        "{e}"
    );
    // … and fits at 1.9e-4 (19.81 ms).
    assert!(Clock::new(
        &clock_cfg(50.0, Shutter::Rolling, Some(1.9e-4)),
        1e-3,
        100,
        2
    )
    .is_ok());
    // Global: T > period.
    let e = Clock::new(&clock_cfg(2000.0, Shutter::Global, None), 1e-3, 100, 2)
        .unwrap_err()
        .to_string();
    assert!(e.contains("clock.frame_rate_hz"), "{e}");
    // Global with a line time; rolling without one.
    let e = msg(&clock_cfg(50.0, Shutter::Global, Some(1e-5)), 2);
    assert!(
        e.contains("clock.line_time_s") && e.contains("global"),
        "{e}"
    );
    let e = msg(&clock_cfg(50.0, Shutter::Rolling, None), 2);
    assert!(e.contains("clock.line_time_s"), "{e}");
    // Rates.
    for bad in [0.0, -5.0, f64::NAN, f64::INFINITY] {
        let e = msg(&clock_cfg(bad, Shutter::Global, None), 2);
        assert!(e.contains("clock.frame_rate_hz"), "{e}");
    }
    // Frame times: non-increasing, not finite, too few, both/neither given.
    let times = |v: Vec<f64>| ClockConfig {
        frame_rate_hz: None,
        frame_times_s: Some(v),
        shutter: Shutter::Global,
        line_time_s: None,
    };
    let e = msg(&times(vec![0.0, 0.1, 0.1]), 3);
    assert!(
        e.contains("clock.frame_times_s[2]") && e.contains("increase"),
        "{e}"
    );
    let e = msg(&times(vec![0.0, 0.2, 0.1]), 3);
    assert!(e.contains("clock.frame_times_s[2]"), "{e}");
    let e = msg(&times(vec![0.0, f64::NAN]), 2);
    assert!(e.contains("clock.frame_times_s[1]"), "{e}");
    let e = msg(&times(vec![0.0, 0.0005]), 2);
    assert!(
        e.contains("clock.frame_times_s[1]") && e.contains("overlap"),
        "{e}"
    );
    let e = msg(&times(vec![0.0, 0.1]), 3);
    assert!(
        e.contains("clock.frame_times_s") && e.contains("3 frames"),
        "{e}"
    );
    let mut both = times(vec![0.0, 0.1]);
    both.frame_rate_hz = Some(10.0);
    assert!(msg(&both, 2).contains("exactly one"));
    let mut neither = both.clone();
    neither.frame_rate_hz = None;
    neither.frame_times_s = None;
    assert!(msg(&neither, 2).contains("exactly one"));
    assert!(msg(&clock_cfg(50.0, Shutter::Global, None), 0).contains("frames"));
}

const MARKER: &str = "ZQXMARKER";

#[test]
fn measured_trajectory_is_interpolated_with_the_stated_signs() {
    let dir = tempfile::tempdir().unwrap();
    // Columns in another order, a comment and a blank line.
    let csv = write_csv(
        dir.path(),
        "track.csv",
        "# a gimbal log\nel_rad, t_s, az_rad\n\n0, 0, 0\n-2e-3, 1, 1e-3\n0, 2, 3e-3 # last\n",
    );
    let m = MeasuredTrajectory::from_csv(&csv).unwrap();
    assert_eq!(m.time_span_s(), (0.0, 2.0));
    assert_eq!(m.pointing_rad(1.0), [1e-3, -2e-3]);
    assert_eq!(m.pointing_rad(2.0), [3e-3, 0.0]);
    // The sensor file's folder resolves the relative path; span starts at 0.5 s, the
    // reference pointing (az 5e-4, el −1e-3).
    let mut t = trajectory();
    t.file = Some(PathBuf::from("track.csv"));
    let motion = MotionConfig {
        enabled: true,
        smear_rad: None,
        angular_rate_rad_s: Some(1e-3),
        velocity_m_s: None,
        range_m: None,
        direction_deg: 0.0,
    };
    let l = LineOfSight::new(
        Some(&t),
        Some(&motion),
        1e-3,
        0,
        (0.5, 1.5),
        Some(dir.path()),
    )
    .unwrap();
    assert!(!l.is_linear());
    let close =
        |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-15 && (a[1] - b[1]).abs() < 1e-15;
    // dx = −Δaz, dy = +Δel, plus the drift 1e-3·t along +x.
    let d = l.displacement_rad(1.0);
    assert!(close(d, [-5e-4 + 1e-3, -1e-3]), "{d:?}");
    let d = l.displacement_rad(1.25);
    assert!(close(d, [-1e-3 + 1.25e-3, -5e-4]), "{d:?}");
    let d = l.displacement_rad(0.5);
    assert!(close(d, [0.5e-3, 0.0]), "{d:?}");
    // from_parts takes the trajectory read beforehand and reads nothing.
    let p = LineOfSight::from_parts(Some(&t), None, 1e-3, 0, (0.5, 1.5), Some(m)).unwrap();
    assert!(close(p.displacement_rad(1.25), [-1e-3, -5e-4]));
}

#[test]
fn measured_trajectory_errors_name_file_and_line_without_content() {
    let dir = tempfile::tempdir().unwrap();
    let cases: &[(&str, String, &[&str])] = &[
        (
            "noheader.csv",
            format!("0, 0, 0\n1, 0, 0 # {MARKER}\n"),
            &["line 1", "header"],
        ),
        (
            "badheader.csv",
            format!("t_s, az_rad, {MARKER}\n0,0,0\n1,0,0\n"),
            &["line 1", "header"],
        ),
        (
            "text.csv",
            format!("t_s,az_rad,el_rad\n0,0,0\n1,{MARKER},0\n"),
            &["line 3", "az_rad"],
        ),
        (
            "nan.csv",
            format!("t_s,az_rad,el_rad\n0,0,0\n1,0,NaN # {MARKER}\n"),
            &["line 3", "el_rad", "finite"],
        ),
        (
            "back.csv",
            format!("t_s,az_rad,el_rad\n0,0,0\n1,0,0\n1,0,0 # {MARKER}\n"),
            &["line 4", "line 3", "increase"],
        ),
        (
            "fields.csv",
            format!("t_s,az_rad,el_rad\n0,0,0\n1,0,0,{MARKER}\n"),
            &["line 3", "3 comma-separated"],
        ),
        (
            "short.csv",
            format!("# {MARKER}\nt_s,az_rad,el_rad\n0,0,0\n"),
            &["1 data line", "at least 2"],
        ),
        ("empty.csv", format!("# {MARKER}\n"), &["header"]),
    ];
    for (name, text, needles) in cases {
        let p = write_csv(dir.path(), name, text);
        let e = MeasuredTrajectory::from_csv(&p).unwrap_err().to_string();
        assert!(e.contains(name), "{name}: {e}");
        assert!(
            !e.contains(MARKER),
            "{name}: the message quotes the file: {e}"
        );
        assert!(!e.contains('\n'), "{name}: {e}");
        for n in *needles {
            assert!(e.contains(n), "{name}: `{e}` lacks `{n}`");
        }
    }
    // Out of the file's span: named with the file's first and last data lines.
    let p = write_csv(dir.path(), "span.csv", "t_s,az_rad,el_rad\n0,0,0\n2,0,0\n");
    let mut t = trajectory();
    t.file = Some(p);
    let e = LineOfSight::new(Some(&t), None, 1e-3, 0, (1.0, 3.0), None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("span.csv") && e.contains("line 2") && e.contains("line 3") && e.contains("3 s"),
        "{e}"
    );
    // A missing file names the path.
    t.file = Some(dir.path().join("absent.csv"));
    let e = LineOfSight::new(Some(&t), None, 1e-3, 0, (0.0, 1.0), None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("absent.csv"), "{e}");
}

const MINIMAL: &str = r#"
name = "t"
[optics]
focal_length_m = 0.1
f_number = 2.0
[detector]
rows = 32
cols = 48
pitch_m = 24e-6
active_width_m = 20e-6
integration_time_s = 1e-3
quantum_efficiency = { kind = "ideal_qe", peak = 0.7, cutoff_um = 5.2 }
"#;

fn parse(text: &str, overrides: &[&str]) -> eoir::Result<SensorConfig> {
    let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    SensorConfig::from_toml_str(text, "test.toml", PathBuf::from("."), &o)
}

fn one_line_error(r: eoir::Result<SensorConfig>, needles: &[&str]) {
    let e = r.expect_err("expected an error").to_string();
    assert!(!e.contains('\n'), "{e}");
    for n in needles {
        assert!(e.contains(n), "`{e}` does not mention `{n}`");
    }
}

#[test]
fn clock_and_trajectory_sections_through_set_and_files() {
    let s = parse(MINIMAL, &[]).unwrap();
    assert!(s.clock.is_none() && s.trajectory.is_none());
    let s = parse(
        MINIMAL,
        &[
            "clock.frame_rate_hz=50",
            "trajectory.pan_rate_rad_s=[1e-3,0]",
            "trajectory.vibration=[{ axis = \"y\", amplitude_rad = 1e-6, frequency_hz = 120 }]",
            "trajectory.wander.kind=power_law",
            "trajectory.wander.psd_at_1hz_rad2_per_hz=1e-12",
            "trajectory.wander.exponent=-2",
            "trajectory.wander.f_min_hz=0.5",
            "trajectory.wander.f_max_hz=50",
        ],
    )
    .unwrap();
    let c = s.clock.as_ref().unwrap();
    assert_eq!(c.frame_rate_hz, Some(50.0));
    assert_eq!(c.shutter, Shutter::Global);
    let t = s.trajectory.as_ref().unwrap();
    assert_eq!(t.pan_rate_rad_s, Some([1e-3, 0.0]));
    assert_eq!(t.vibration[0].axis, LosAxis::Y);
    assert_eq!(t.vibration[0].phase_deg, 0.0);
    // The resolved description round-trips through TOML.
    let back = parse(&s.to_toml_string().unwrap(), &[]).unwrap();
    assert_eq!(back.clock, s.clock);
    assert_eq!(back.trajectory, s.trajectory);
    // A file section.
    let text = format!(
        "{MINIMAL}\n[clock]\nframe_times_s = [0.0, 0.02]\nshutter = \"rolling\"\nline_time_s = 1e-5\n[trajectory.wander]\nkind = \"table\"\nfrequency_hz = [1.0, 10.0]\npsd_rad2_per_hz = [1e-12, 1e-13]\n"
    );
    let s = parse(&text, &[]).unwrap();
    assert_eq!(s.clock.unwrap().shutter, Shutter::Rolling);

    // Unknown keys and values.
    one_line_error(parse(MINIMAL, &["clock.frame_rate=50"]), &["frame_rate"]);
    one_line_error(
        parse(MINIMAL, &["trajectory.pan_rate=[0,0]"]),
        &["pan_rate"],
    );
    one_line_error(
        parse(
            MINIMAL,
            &["clock.frame_rate_hz=50", "clock.shutter=\"diagonal\""],
        ),
        &["diagonal"],
    );
    one_line_error(
        parse(
            MINIMAL,
            &[
                "trajectory.wander.kind=pink",
                "trajectory.wander.f_min_hz=1",
            ],
        ),
        &["pink"],
    );
    // Values checked by name.
    one_line_error(
        parse(
            MINIMAL,
            &["clock.frame_rate_hz=50", "clock.line_time_s=1e-5"],
        ),
        &["clock.line_time_s", "global"],
    );
    one_line_error(
        parse(
            MINIMAL,
            &[
                "clock.frame_rate_hz=1000",
                "clock.shutter=\"rolling\"",
                "clock.line_time_s=1e-4",
            ],
        ),
        &["clock.frame_rate_hz", "overlap"],
    );
    one_line_error(
        parse(
            MINIMAL,
            &["trajectory.vibration=[{ axis = \"x\", amplitude_rad = 1e-6, frequency_hz = 0 }]"],
        ),
        &["trajectory.vibration[0].frequency_hz"],
    );
    one_line_error(
        parse(MINIMAL, &["trajectory.pan_rate_rad_s=[1e-3,nan]"]),
        &["trajectory.pan_rate_rad_s[1]"],
    );
    one_line_error(
        parse(
            MINIMAL,
            &[
                "trajectory.wander={ kind = \"table\", frequency_hz = [1, 1], psd_rad2_per_hz = [1e-12, 1e-12] }",
            ],
        ),
        &["trajectory.wander.frequency_hz[1]"],
    );
    one_line_error(
        parse(
            MINIMAL,
            &[
                "trajectory.wander={ kind = \"power_law\", psd_at_1hz_rad2_per_hz = 1e-12, exponent = -1, f_min_hz = 10, f_max_hz = 5 }",
            ],
        ),
        &["trajectory.wander.f_max_hz"],
    );
    one_line_error(
        parse(
            MINIMAL,
            &[
                "trajectory.file=\"a.csv\"",
                "trajectory.pan_rate_rad_s=[0,0]",
            ],
        ),
        &["trajectory.file"],
    );
}

#[test]
fn wander_grid_too_large_is_refused() {
    // f_min 1e-6 Hz needs a 4e6 s period at a 1/(8·1000 Hz) step: 3e10 samples.
    let mut t = trajectory();
    t.wander = Some(WanderConfig::PowerLaw {
        psd_at_1hz_rad2_per_hz: 1e-12,
        exponent: -1.0,
        f_min_hz: 1e-6,
        f_max_hz: 1000.0,
    });
    let e = LineOfSight::new(Some(&t), None, 1e-3, 0, (0.0, 1.0), None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("trajectory.wander") && e.contains("samples"),
        "{e}"
    );
}
