//! The moving camera (docs/motion.md) measured on its own products, against analytic
//! truth: the centroid and second moment of a well-sampled spot (independent of how the
//! engine shifts and blurs), a still camera looking at a shifted crop of the same scene,
//! the slanted-edge MTF under fast vibration (J0), and the skew of a rolling shutter.

use eoir::io::MemoryCube;
use eoir::pipeline::{self, RunOptions, RunOutput};
use eoir::scene::synthetic::{self, SceneParams};
use eoir::scene::Cube;
use eoir::sensor::{presets, Sensor, SensorConfig};
use ndarray::{s, Array2, Array3};

/// Detector size of the tests (rows, cols).
const DET: (usize, usize) = (48, 64);

/// A MultimIR-like sensor of `DET` pixels with a Gaussian blur of 0.7 px (so the frames
/// are well sampled: aliasing below 1e-3, centroids exact to ~1e-4 px), no defects,
/// `overrides` applied, `edit` on the configuration.
fn sensor(overrides: &[&str], edit: impl FnOnce(&mut SensorConfig)) -> Sensor {
    let mut all: Vec<String> = vec![
        format!("detector.rows={}", DET.0),
        format!("detector.cols={}", DET.1),
        "detector.defects.dead_fraction=0".into(),
        "gaussian.sigma_rad=1.68e-4".into(), // 0.7 × IFOV (24 µm / 100 mm)
    ];
    all.extend(overrides.iter().map(|s| s.to_string()));
    let mut config = presets::load("multimir", &[], &all).unwrap();
    edit(&mut config);
    Sensor::build(&config).unwrap()
}

/// Scene parameters: the detector plus `margin` pixels on each side, `k` samples per
/// pixel, the sensor's band in 12 bands.
fn params(sensor: &Sensor, margin: usize, k: usize) -> SceneParams {
    let (lo, hi) = sensor.response().support_um();
    let cols = DET.1 + 2 * margin;
    SceneParams {
        rows: DET.0 + 2 * margin,
        cols,
        oversampling: k,
        wavelength_um: SceneParams::uniform_grid(lo, hi, 12).unwrap(),
        fov_x_deg: (sensor.ifov_rad() * cols as f64).to_degrees(),
        range_m: Some(1900.0),
        seed: 3,
        sun: false,
    }
}

/// A 300 K blackbody scene with Gaussian hot spots (radiance × (1 + 2·g), σ = `sigma_px`
/// detector pixels) at `spots` (detector-pixel offsets from the scene centre, [x, y]).
fn spots(p: &SceneParams, spots: &[[f64; 2]], sigma_px: f64) -> Cube {
    let base = synthetic::blackbody(p, 300.0, 1.0).unwrap();
    let k = p.oversampling as f64;
    let (rows, cols) = (base.data.dim().1, base.data.dim().2);
    let g = Array2::from_shape_fn((rows, cols), |(r, c)| {
        spots
            .iter()
            .map(|s| {
                let x = (c as f64 - (cols as f64 - 1.0) / 2.0) / k - s[0];
                let y = (r as f64 - (rows as f64 - 1.0) / 2.0) / k - s[1];
                (-(x * x + y * y) / (2.0 * sigma_px * sigma_px)).exp()
            })
            .sum::<f64>()
    });
    let mut data = base.data.clone();
    for mut plane in data.outer_iter_mut() {
        plane.zip_mut_with(&g, |v, g| *v *= (1.0 + 2.0 * g) as f32);
    }
    Cube::new(data, base.meta.clone()).unwrap()
}

/// Runs `cube` through `sensor` for `frames` frames (seed 1, no calibration).
fn run(sensor: &Sensor, cube: Cube, frames: usize) -> RunOutput {
    let mut reader = MemoryCube::new(cube);
    let opts = RunOptions {
        frames,
        calibration: None,
        ..RunOptions::default()
    };
    pipeline::run(sensor, &mut reader, &opts, |_, _| {}).unwrap()
}

/// Background-subtracted centroid [x, y] and variance [x, y] (pixels, pixels²) of the
/// spot in `e` within `half` px of `at` (detector coordinates).
fn moments(e: &Array2<f32>, at: [f64; 2], half: usize) -> ([f64; 2], [f64; 2]) {
    let bg = e[[0, 0]] as f64;
    let (cx, cy) = (at[0].round() as isize, at[1].round() as isize);
    let h = half as isize;
    let (mut m0, mut mx, mut my, mut mxx, mut myy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for r in cy - h..=cy + h {
        for c in cx - h..=cx + h {
            let w = e[[r as usize, c as usize]] as f64 - bg;
            let (x, y) = (c as f64, r as f64);
            m0 += w;
            mx += w * x;
            my += w * y;
            mxx += w * x * x;
            myy += w * y * y;
        }
    }
    let (x, y) = (mx / m0, my / m0);
    ([x, y], [mxx / m0 - x * x, myy / m0 - y * y])
}

/// Detector coordinates of a scene-centre offset `s` (px).
fn detector_at(s: [f64; 2]) -> [f64; 2] {
    [
        (DET.1 as f64 - 1.0) / 2.0 + s[0],
        (DET.0 as f64 - 1.0) / 2.0 + s[1],
    ]
}

/// Reads the truth table back: (frame, dx, dy, smear) per line.
fn truth(out: &RunOutput) -> Vec<(u64, f64, f64, f64)> {
    out.line_of_sight
        .as_ref()
        .unwrap()
        .iter()
        .map(|r| {
            (
                r.frame,
                r.displacement_px[0],
                r.displacement_px[1],
                r.smear_px,
            )
        })
        .collect()
}

/// IFOV of the test sensor, rad.
const IFOV: f64 = 24e-6 / 0.1;

#[test]
fn a_drifting_spot_moves_by_the_drift_and_its_width_grows_by_the_smear() {
    // 4 px of smear in 2.6 ms; 200 frames/s: 7.7 px between frames.
    let v = 4.0 * IFOV * 1900.0 / 2.6e-3;
    let moving = sensor(
        &[
            &format!("motion.velocity_m_s={v}"),
            "clock.frame_rate_hz=200",
        ],
        |_| {},
    );
    let still = sensor(&[], |c| c.motion = None);
    let p = params(&moving, 22, 2);
    let at = [-12.0, 0.0];
    let cube = spots(&p, &[at], 1.5);
    let out = run(&moving, cube.clone(), 3);
    let reference = run(&still, cube, 1);
    let (_, var_still) = moments(&reference.frames[0].electrons_mean, detector_at(at), 12);
    let smear_px = v * 2.6e-3 / 1900.0 / IFOV;
    let step_px = v / 200.0 / 1900.0 / IFOV;
    let t = truth(&out);
    for (g, f) in out.frames.iter().enumerate() {
        let want = [at[0] + g as f64 * step_px, at[1]];
        let (c, var) = moments(&f.electrons_mean, detector_at(want), 12);
        let got = c[0] - detector_at(at)[0];
        assert!(
            (got - g as f64 * step_px).abs() < 0.02,
            "frame {g}: moved {got} px, drift {}",
            g as f64 * step_px
        );
        assert!(
            (t[g].1 - g as f64 * step_px).abs() < 1e-9,
            "truth {:?}",
            t[g]
        );
        assert!((t[g].3 - smear_px).abs() < 1e-9, "truth smear {:?}", t[g]);
        // Variances add under convolution: a box of length L adds L²/12.
        let width = (12.0 * (var[0] - var_still[0])).sqrt();
        assert!(
            (width / smear_px - 1.0).abs() < 0.05,
            "frame {g}: smear measured {width} px, configured {smear_px}"
        );
        assert!(
            (var[1] - var_still[1]).abs() < 0.01,
            "no smear across the motion"
        );
    }
}

#[test]
fn a_still_trajectory_gives_the_still_cameras_products_byte_for_byte() {
    let p = |s: &Sensor| params(s, 4, 2);
    let plain = sensor(&[], |_| {});
    let clocked = sensor(&["clock.frame_rate_hz=50"], |c| c.motion = None);
    let unclocked = sensor(&[], |c| c.motion = None);
    let cube = synthetic::thermal(&p(&plain)).unwrap();
    // No motion at all: the clock changes nothing.
    let a = run(&clocked, cube.clone(), 2);
    let b = run(&unclocked, cube.clone(), 2);
    assert!(a.line_of_sight.is_none());
    for (x, y) in a.frames.iter().zip(&b.frames) {
        assert_eq!(x.dn, y.dn);
        assert_eq!(x.electrons_mean, y.electrons_mean);
    }
    // [motion] with a clock: frame 0 is the still camera's frame (the drift starts there).
    let clocked = sensor(&["clock.frame_rate_hz=50"], |_| {});
    let m = run(&clocked, cube.clone(), 2);
    let s = run(&plain, cube, 1);
    assert_eq!(m.frames[0].dn, s.frames[0].dn);
    assert_eq!(m.frames[0].electrons_mean, s.frames[0].electrons_mean);
    assert_ne!(m.frames[1].electrons_mean, m.frames[0].electrons_mean);
}

/// Columns `first .. first + cols` of `cube`, its field of view scaled to the columns
/// kept: the same scene seen `first` samples further right.
fn crop_columns(cube: &Cube, first: usize, cols: usize) -> Cube {
    let data: Array3<f32> = cube.data.slice(s![.., .., first..first + cols]).to_owned();
    let mut meta = cube.meta.clone();
    let g = meta.geometry.as_mut().unwrap();
    let per_col = g.fov_x_deg / cube.meta.cols as f64;
    g.fov_x_deg = per_col * cols as f64;
    meta.cols = cols;
    Cube::new(data, meta).unwrap()
}

#[test]
fn a_shift_between_frames_equals_the_still_camera_on_a_shifted_crop() {
    // The Fourier phase ramp against real-space cropping: a drift of exactly 3 scene
    // samples (0.75 px at k = 4) per frame, and the same scene cropped 3 samples further
    // left for each frame, seen by a still camera.
    let k = 4;
    let per_frame_rad = 3.0 * IFOV / k as f64;
    let v = per_frame_rad * 100.0 * 1900.0; // 100 frames/s, 1900 m
    let moving = sensor(
        &[
            &format!("motion.velocity_m_s={v}"),
            "clock.frame_rate_hz=100",
        ],
        |_| {},
    );
    let p = params(&moving, 8, k);
    let wide = synthetic::thermal(&p).unwrap();
    let cols = wide.meta.cols - 2 * 3 * 2;
    let out = run(&moving, crop_columns(&wide, 6, cols), 3);
    for g in 0..3usize {
        // The scene moves +x (to higher columns): frame g sees the content that was
        // 3g samples to its left, i.e. a crop starting 3g samples earlier.
        let still = run(&moving, crop_columns(&wide, 6 - 3 * g, cols), 1);
        let (a, b) = (
            &out.frames[g].electrons_mean,
            &still.frames[0].electrons_mean,
        );
        let scale = b.iter().fold(0.0f32, |m, v| m.max(v.abs())) as f64;
        let worst = a
            .slice(s![2..DET.0 - 2, 2..DET.1 - 2])
            .iter()
            .zip(b.slice(s![2..DET.0 - 2, 2..DET.1 - 2]).iter())
            .map(|(x, y)| (x - y).abs() as f64)
            .fold(0.0, f64::max);
        assert!(
            worst < 2e-4 * scale,
            "frame {g}: moving vs shifted still differ by {worst} of {scale}"
        );
    }
}

#[test]
fn wander_moves_spots_by_the_truth_table_displacement() {
    // A random wander of 0.8 px rms below 20 Hz plus a pan, over 6 frames at 50 Hz: each
    // frame's spot centroids move by the truth table's displacement.
    let psd = 0.8f64.powi(2) * IFOV * IFOV / 19.0; // flat 1–20 Hz
    let moving = sensor(
        &[
            "clock.frame_rate_hz=50",
            "trajectory.pan_rate_rad_s=[5e-3, -2e-3]",
            &format!(
                "trajectory.wander={{kind = \"table\", frequency_hz = [1.0, 20.0], psd_rad2_per_hz = [{psd}, {psd}]}}"
            ),
        ],
        |c| c.motion = None,
    );
    let p = params(&moving, 14, 2);
    let at = [[-8.0, -5.0], [9.0, 6.0]];
    let out = run(&moving, spots(&p, &at, 1.5), 6);
    let t = truth(&out);
    let mut worst: f64 = 0.0;
    let mut largest: f64 = 0.0;
    for (g, f) in out.frames.iter().enumerate() {
        for s0 in at {
            let d = [t[g].1, t[g].2];
            let want = detector_at([s0[0] + d[0], s0[1] + d[1]]);
            let (c, _) = moments(&f.electrons_mean, want, 9);
            worst = worst
                .max((c[0] - want[0]).abs())
                .max((c[1] - want[1]).abs());
            largest = largest.max(d[0].abs()).max(d[1].abs());
        }
    }
    assert!(worst < 0.05, "centroid off the truth by {worst} px");
    assert!(
        largest > 2.0,
        "the test should move by several pixels ({largest})"
    );
}

#[test]
fn fast_vibration_blurs_as_j0_and_slow_vibration_only_shifts() {
    // x vibration of amplitude a = 1 px: at 2 kHz (5 periods in 2.5 ms) the frame is
    // blurred by J0(2π a f); at 1.3 Hz it moves without blur.
    let a = IFOV;
    let vib = |hz: f64| {
        format!("trajectory.vibration=[{{axis = \"x\", amplitude_rad = {a}, frequency_hz = {hz}}}]")
    };
    let fast = sensor(
        &[
            "clock.frame_rate_hz=50",
            "detector.integration_time_s=2.5e-3",
            &vib(2000.0),
        ],
        |c| c.motion = None,
    );
    let still = sensor(&["detector.integration_time_s=2.5e-3"], |c| c.motion = None);
    let p = params(&fast, 6, 4);
    let at = [0.0, 0.0];
    let cube = spots(&p, &[at], 1.2);
    let f = run(&fast, cube.clone(), 1);
    let s0 = run(&still, cube.clone(), 1);
    // 5 whole periods: the path's variance is a²/2 exactly; its piecewise-linear form
    // (chords within 0.005 px, 0.2 rad of phase) has (2 + cos 0.2)/6 = 0.4967. The
    // windowed second moment also counts the diffraction PSF's 1/x³ tails, which the blur
    // moves across the window's edge: measured over ±10 and ±20 px.
    let added = |half| {
        let (_, vf) = moments(&f.frames[0].electrons_mean, detector_at(at), half);
        let (_, vs) = moments(&s0.frames[0].electrons_mean, detector_at(at), half);
        vf[0] - vs[0]
    };
    let (a10, a20) = (added(10), added(20));
    eprintln!("vibration variance added: {a10} (±10 px), {a20} (±20 px), chords 0.4967");
    assert!(
        (a20 / 0.4967 - 1.0).abs() < 0.015,
        "variance added {a20} px² (±10 px: {a10}), a²/2 of the chords = 0.4967"
    );
    // The transfer function: ratio of the spot's spectra along x against J0(2π a f).
    let row = |e: &Array2<f32>| -> Vec<f64> {
        let c = detector_at(at);
        let r = c[1].round() as usize;
        (0..DET.1)
            .map(|x| {
                (r - 6..=r + 6)
                    .map(|y| e[[y, x]] as f64 - e[[0, 0]] as f64)
                    .sum()
            })
            .collect()
    };
    let (lf, ls) = (
        row(&f.frames[0].electrons_mean),
        row(&s0.frames[0].electrons_mean),
    );
    for fr in [0.05, 0.1, 0.15, 0.2] {
        let ft = |l: &[f64]| -> f64 {
            let (re, im) = l.iter().enumerate().fold((0.0, 0.0), |(re, im), (x, v)| {
                let ph = -2.0 * std::f64::consts::PI * fr * x as f64;
                (re + v * ph.cos(), im + v * ph.sin())
            });
            re.hypot(im)
        };
        let h = ft(&lf) / ft(&ls);
        let j0 = libm::j0(2.0 * std::f64::consts::PI * fr).abs();
        assert!((h - j0).abs() < 0.02, "f = {fr} cy/px: |H| {h}, |J0| {j0}");
    }
    // Slow: the spot moves with the vibration, its width unchanged.
    // (1.3 Hz at 4 frames/s: the frames sample the sine at different phases.)
    let slow = sensor(&["clock.frame_rate_hz=4", &vib(1.3)], |c| c.motion = None);
    let still = sensor(&[], |c| c.motion = None);
    let out = run(&slow, cube.clone(), 3);
    let s1 = run(&still, cube, 1);
    let (_, v0) = moments(&s1.frames[0].electrons_mean, detector_at(at), 10);
    let t = truth(&out);
    for (g, fr) in out.frames.iter().enumerate() {
        let want = detector_at([t[g].1, t[g].2]);
        let (c, v) = moments(&fr.electrons_mean, want, 10);
        assert!((c[0] - want[0]).abs() < 0.02 && (c[1] - want[1]).abs() < 0.02);
        assert!(
            (v[0] - v0[0]).abs() < 0.02,
            "slow vibration blurred: {} vs {}",
            v[0],
            v0[0]
        );
    }
    assert!(
        t.iter().any(|r| r.1.abs() > 0.5),
        "frames should move: {t:?}"
    );
}

/// Least-squares slope of the rows' x centroids of a vertical line of spots against the
/// row index, over `rows`.
fn skew(e: &Array2<f32>, rows: std::ops::Range<usize>) -> f64 {
    let bg = e[[0, 0]] as f64;
    let pts: Vec<(f64, f64)> = rows
        .map(|r| {
            let (m0, m1) = (0..DET.1).fold((0.0, 0.0), |(a, b), c| {
                let w = e[[r, c]] as f64 - bg;
                (a + w, b + w * c as f64)
            });
            (r as f64, m1 / m0)
        })
        .collect();
    let n = pts.len() as f64;
    let (sx, sy) = pts.iter().fold((0.0, 0.0), |(a, b), p| (a + p.0, b + p.1));
    let (mx, my) = (sx / n, sy / n);
    let (sxy, sxx) = pts.iter().fold((0.0, 0.0), |(a, b), p| {
        (a + (p.0 - mx) * (p.1 - my), b + (p.0 - mx).powi(2))
    });
    sxy / sxx
}

#[test]
fn a_rolling_shutter_skews_a_vertical_line_under_a_pan() {
    // A vertical hot line (a column of overlapping spots) and a pan of 0.2 rad/s: each
    // row is exposed t_line later, so it lands rate·t_line/IFOV px further right.
    let (rate, line) = (0.2, 20e-6);
    let spots_at: Vec<[f64; 2]> = (-30..=30).map(|y| [0.0, y as f64]).collect();
    let rolling = sensor(
        &[
            "clock.frame_rate_hz=100",
            "clock.shutter=\"rolling\"",
            &format!("clock.line_time_s={line}"),
            &format!("trajectory.pan_rate_rad_s=[{rate}, 0.0]"),
        ],
        |c| c.motion = None,
    );
    let p = params(&rolling, 8, 2);
    let cube = spots(&p, &spots_at, 1.2);
    let out = run(&rolling, cube.clone(), 1);
    let want = rate * line / IFOV;
    let got = skew(&out.frames[0].electrons_mean, 6..DET.0 - 6);
    assert!(
        (got.atan() / want.atan() - 1.0).abs() < 0.02,
        "skew {} rad, atan(rate·t_line/IFOV) = {} rad",
        got.atan(),
        want.atan()
    );
    let global = sensor(
        &[
            "clock.frame_rate_hz=100",
            &format!("trajectory.pan_rate_rad_s=[{rate}, 0.0]"),
        ],
        |c| c.motion = None,
    );
    let g = run(&global, cube, 1);
    let none = skew(&g.frames[0].electrons_mean, 6..DET.0 - 6);
    assert!(none.abs() < 1e-4, "a global shutter shows no skew ({none})");
}

#[test]
fn a_rolling_shutter_row_bound_holds() {
    // A tilt under a rolling shutter: row r displaced by r·0.0137 px down and r·0.021 px
    // right. The engine (vertical positions within 0.02 px, horizontal exact) against the
    // exact per-row computation (every row its own column pass): the difference stays
    // within 0.02 px times the image's vertical gradient.
    use eoir::imaging::motion::{FrameMotion, MotionGroup};
    use eoir::imaging::{Imager, DEFAULT_WRAP_TOLERANCE};
    let s = sensor(&[], |c| c.motion = None);
    let p = params(&s, 4, 2);
    let cube = synthetic::thermal(&p).unwrap();
    let geometry = cube.meta.geometry.unwrap();
    let imager = Imager::new(&s, &cube.meta, &geometry, DEFAULT_WRAP_TOLERANCE).unwrap();
    let mut reader = MemoryCube::new(cube.clone());
    let (spectrum, _) = imager
        .with_spectrum(&mut reader, 0, |_, _| {}, |acc| Ok(acc.to_vec()))
        .unwrap();
    let motion = FrameMotion {
        groups: vec![MotionGroup {
            rows: (0..DET.0).collect(),
            displacement_rad: (0..DET.0)
                .map(|r| [0.021 * r as f64 * IFOV, 0.0137 * r as f64 * IFOV])
                .collect(),
            blur: None,
        }],
    };
    let mut scratch = Vec::new();
    let fast = imager
        .detector_image_moving(&spectrum, &motion, &mut scratch)
        .unwrap();
    let exact = imager
        .detector_image_moving_within(&spectrum, &motion, &mut scratch, 0.0)
        .unwrap();
    let gradient = (1..DET.0 - 1)
        .flat_map(|r| (0..DET.1).map(move |c| (r, c)))
        .map(|(r, c)| ((exact[[r + 1, c]] - exact[[r - 1, c]]) / 2.0).abs())
        .fold(0.0, f64::max);
    let worst = fast
        .iter()
        .zip(exact.iter())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(
        worst > 0.0,
        "the bins should differ from the exact rows somewhere"
    );
    assert!(
        worst <= 1.5 * 0.02 * gradient,
        "difference {worst} against 0.02 px × gradient {gradient}"
    );
}
