//! Wiener restoration (`eoir restore` and `processing::wiener`) on engine-made scenes,
//! measured against the same scene through the same sensor with every blur switched off;
//! and the slanted-edge MTF of an engine-made edge against the analytic system MTF.

use std::path::Path;
use std::process::Command;

use eoir::io::{raster, MemoryCube};
use eoir::pipeline::{self, RunOptions};
use eoir::processing::edge_mtf::slanted_edge_mtf;
use eoir::processing::wiener::{
    psnr_db, replace_invalid_pixels, wiener_restore, FnTransfer, NoiseRule, SensorTransfer,
    IMPULSE_K_SIGMA,
};
use eoir::scene::synthetic::{self, SceneParams};
use eoir::sensor::{presets, Sensor, SensorConfig};
use ndarray::Array2;

fn eoir() -> Command {
    Command::new(env!("CARGO_BIN_EXE_eoir"))
}

/// Detector size of the test sensor.
const N: usize = 96;

/// The sensor overrides of the restoration tests: MultimIR (100 mm F/2, filter 4, with its
/// aberration, motion, jitter, dead pixels) on a 96 × 96 window, a 1.25-pixel Gaussian
/// blur added (defocused optics) and a read noise that makes the noise moderate.
fn overrides() -> Vec<String> {
    vec![
        format!("detector.rows={N}"),
        format!("detector.cols={N}"),
        "gaussian.sigma_rad=3.0e-4".into(),
        "detector.read_noise_e=20000".into(),
    ]
}

fn sensor() -> Sensor {
    Sensor::build(&presets::load("multimir", &[], &overrides()).unwrap()).unwrap()
}

/// The same sensor with every blur switched off: no diffraction, aberration, motion,
/// jitter or Gaussian, and a detector footprint 1/1000 of the pitch (a point sampler).
fn unblurred(s: &Sensor) -> Sensor {
    let mut u: SensorConfig = s.config().clone();
    u.diffraction.enabled = false;
    u.aberration = None;
    u.motion = None;
    u.jitter = None;
    u.gaussian = None;
    u.detector.active_width_m = s.detector.pitch_m * 1e-3;
    u.detector.active_height_m = None;
    Sensor::build(&u).unwrap()
}

/// A scene of `kind` ("bars" or "edge") covering the sensor at 4 scene samples per pixel.
fn scene(s: &Sensor, kind: &str) -> eoir::scene::Cube {
    let p = SceneParams {
        rows: N,
        cols: N,
        oversampling: 4,
        wavelength_um: SceneParams::uniform_grid(3.8, 5.5, 35).unwrap(),
        fov_x_deg: (s.ifov_rad() * N as f64).to_degrees(),
        range_m: Some(1900.0),
        seed: 1,
        sun: false,
    };
    match kind {
        "bars" => synthetic::bars(&p, 310.0, 295.0).unwrap(),
        _ => synthetic::edge(&p, 295.0, 310.0, 5.0).unwrap(),
    }
}

fn run(s: &Sensor, cube: &eoir::scene::Cube) -> pipeline::RunOutput {
    let mut reader = MemoryCube::new(cube.clone());
    let opts = RunOptions {
        calibration: None,
        seed: 5,
        ..Default::default()
    };
    pipeline::run(s, &mut reader, &opts, |_, _| {}).unwrap()
}

/// Recorded DN, conversion gain and black level of a run.
struct Recorded {
    dn: Array2<u16>,
    gain: f64,
    black: f64,
}

fn record(s: &Sensor, cube: &eoir::scene::Cube) -> Recorded {
    let out = run(s, cube);
    let model = s.detector();
    Recorded {
        dn: out.frames[0].dn.clone(),
        gain: model.gain_dn_per_e(),
        black: model.expected_dn(0.0),
    }
}

/// The ideal image in signal electrons: the unblurred sensor's noise-free electrons,
/// scaled by the ratio of photosensitive areas.
fn ideal_electrons(s: &Sensor, cube: &eoir::scene::Cube) -> Array2<f64> {
    let u = unblurred(s);
    let out = run(&u, cube);
    let area = s.detector.active_area_m2() / u.detector.active_area_m2();
    out.frames[0].electrons_mean.mapv(|v| v as f64 * area)
}

fn restore_cli(input: &Path, out: &Path, extra: &[&str]) -> Array2<f64> {
    let mut cmd = eoir();
    cmd.arg("restore").arg(input).args(["--sensor", "multimir"]);
    for o in overrides() {
        cmd.args(["--set", &o]);
    }
    let res = cmd.args(extra).arg("-o").arg(out).output().unwrap();
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    raster::read_tiff_f32(&out.join("restored.tiff"))
        .unwrap()
        .mapv(f64::from)
}

#[test]
fn restoration_of_a_bar_scene_gains_psnr_and_auto_is_near_the_best_constant() {
    let s = sensor();
    let cube = scene(&s, "bars");
    let rec = record(&s, &cube);
    let ideal = ideal_electrons(&s, &cube);
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("dn.tiff");
    raster::write_tiff_u16(&input, rec.dn.view()).unwrap();
    let restored_dn = restore_cli(&input, &dir.path().join("out"), &[]);
    let to_e = |dn: &Array2<f64>| dn.mapv(|v| (v - rec.black) / rec.gain);
    // The raw image with its dead pixels replaced the same way, for a fair comparison.
    let (raw_clean, replaced) =
        replace_invalid_pixels(rec.dn.mapv(f64::from).view(), IMPULSE_K_SIGMA).unwrap();
    assert!(
        replaced >= 20,
        "0.5 % of 9216 pixels are dead: {replaced} replaced"
    );
    let raw_e = to_e(&raw_clean);
    let restored_e = to_e(&restored_dn);
    let psnr_raw = psnr_db(raw_e.view(), ideal.view()).unwrap();
    let psnr_auto = psnr_db(restored_e.view(), ideal.view()).unwrap();
    // Best constant NSR by search, same pre-processing, through the library.
    let transfer = SensorTransfer::new(&s).unwrap();
    let mut best = (f64::NEG_INFINITY, 0.0);
    for i in 0..29 {
        let nsr = 10f64.powf(-6.0 + 0.25 * i as f64);
        let r = wiener_restore(raw_e.view(), &transfer, NoiseRule::Constant(nsr)).unwrap();
        let p = psnr_db(r.image.view(), ideal.view()).unwrap();
        if p > best.0 {
            best = (p, nsr);
        }
    }
    // The library's auto rule on the same electrons matches the CLI (units cancel).
    let lib_auto = eoir::processing::wiener::restore(
        raw_e.view(),
        &transfer,
        NoiseRule::Auto,
        eoir::processing::wiener::Method::Auto,
        Default::default(),
    )
    .unwrap();
    let psnr_lib = psnr_db(lib_auto.image.view(), ideal.view()).unwrap();
    let model_var = {
        let m = s.detector();
        m.temporal_noise_e(raw_e.mean().unwrap()).powi(2)
    };
    let lib_model = wiener_restore(
        raw_e.view(),
        &transfer,
        NoiseRule::Model {
            noise_variance: model_var,
        },
    )
    .unwrap();
    let psnr_model = psnr_db(lib_model.image.view(), ideal.view()).unwrap();
    eprintln!(
        "PSNR raw {psnr_raw:.2} dB, auto (CLI) {psnr_auto:.2}, auto (lib) {psnr_lib:.2}, model {psnr_model:.2}, best constant {:.2} at NSR {:.2e}; auto noise σ {:.1} e- vs model {:.1} e-",
        best.0,
        best.1,
        lib_auto.noise_sigma.unwrap(),
        model_var.sqrt()
    );
    assert!((psnr_lib - psnr_auto).abs() < 0.05);
    assert!(psnr_auto >= psnr_raw + 3.0, "{psnr_auto} vs raw {psnr_raw}");
    assert!(psnr_auto >= best.0 - 1.0, "{psnr_auto} vs best {}", best.0);
    assert!(
        psnr_model >= psnr_raw + 3.0,
        "{psnr_model} vs raw {psnr_raw}"
    );
    // Restoration keeps the mean (the DC gain is 1).
    let (mr, mo) = (raw_e.mean().unwrap(), restored_e.mean().unwrap());
    assert!((mr - mo).abs() < 1e-3 * mr.abs(), "{mr} vs {mo}");
}

#[test]
fn restored_edge_is_sharper_by_at_least_a_fifth() {
    let s = sensor();
    let cube = scene(&s, "edge");
    let rec = record(&s, &cube);
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("edge.png");
    raster::write_png_u16(&input, rec.dn.view()).unwrap();
    let restored = restore_cli(&input, &dir.path().join("out"), &[]);
    let (raw, _) = replace_invalid_pixels(rec.dn.mapv(f64::from).view(), IMPULSE_K_SIGMA).unwrap();
    let m_raw = slanted_edge_mtf(raw.view(), None).unwrap();
    let m_res = slanted_edge_mtf(restored.view(), None).unwrap();
    let (a, b) = (
        m_raw.mtf50_cy_per_px.unwrap(),
        m_res.mtf50_cy_per_px.unwrap(),
    );
    eprintln!(
        "MTF50 raw {a:.4} cy/px, restored {b:.4} cy/px ({:.2}×)",
        b / a
    );
    assert!(b >= 1.2 * a, "{b} vs {a}");
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("out/restore.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(json["noise_rule"], "auto");
    let h_nyq = json["transfer_function"]["mtf_at_nyquist_x"]
        .as_f64()
        .unwrap();
    let direct = SensorTransfer::new(&s).unwrap().eval(0.5, 0.0);
    assert!((h_nyq - direct).abs() < 1e-12);
    assert_eq!(
        &std::fs::read(dir.path().join("out/restored.png")).unwrap()[1..4],
        b"PNG"
    );
}

#[test]
fn engine_edge_mtf_matches_the_analytic_system_mtf_up_to_0_8_nyquist() {
    // Noise-free mean electrons of an oversampled (4 scene samples per pixel) edge through
    // the stock MultimIR optics on a 96 × 96 window: the slanted edge measures the
    // pre-sampling MTF along the edge normal, compared with the cascade's transfer function
    // (detector footprint included) evaluated along that normal, spectrally weighted.
    let s = Sensor::build(
        &presets::load(
            "multimir",
            &[],
            &[format!("detector.rows={N}"), format!("detector.cols={N}")],
        )
        .unwrap(),
    )
    .unwrap();
    let cube = scene(&s, "edge");
    let out = run(&s, &cube);
    let e = out.frames[0].electrons_mean.mapv(f64::from);
    let m = slanted_edge_mtf(e.view(), None).unwrap();
    assert!(m.vertical);
    // The scene edge is tilted 5° counter-clockwise: the fitted line c = a + tan(θ) r.
    assert!((m.angle_deg - 5.0).abs() < 0.1, "{}", m.angle_deg);
    let theta = m.angle_deg.to_radians();
    let transfer = SensorTransfer::new(&s).unwrap();
    // Normal to the edge line c = a + b r: direction (cos θ, −sin θ) in (x, y).
    let analytic = |f: f64| transfer.eval(f * theta.cos(), -f * theta.sin()).abs();
    let mut worst: f64 = 0.0;
    for (f, v) in m.freq_cy_per_px.iter().zip(&m.mtf) {
        if *f <= 0.4 {
            worst = worst.max((v - analytic(*f)).abs());
        }
    }
    eprintln!(
        "engine edge: MTF50 {:.4} cy/px, worst |measured − analytic| up to 0.8 Nyquist {worst:.4}",
        m.mtf50_cy_per_px.unwrap()
    );
    assert!(worst < 0.03, "{worst}");
    // The comparison covers the whole cascade: diffraction, aberration, footprint,
    // motion and jitter.
    assert_eq!(s.otf().components().len(), 5);
}

#[test]
fn library_restores_a_known_gaussian_blur_exactly_without_noise() {
    // A Gaussian blob (σ = 3 px, negligible within the mirrored pads) blurred by a
    // Gaussian transfer function with no noise: with a tiny constant NSR the Wiener filter
    // is the exact inverse (the smallest |H| on the grid is 1.8e-3, so H² ≫ NSR).
    let sigma = 0.8;
    let h = move |fx: f64, fy: f64| {
        (-2.0 * std::f64::consts::PI.powi(2) * sigma * sigma * (fx * fx + fy * fy)).exp()
    };
    let sharp = Array2::from_shape_fn((64, 80), |(r, c)| {
        let x = c as f64 - 40.0;
        let y = r as f64 - 32.0;
        (-(x * x + y * y) / (2.0 * 9.0)).exp() * 100.0 + 10.0
    });
    // Blur by the same transfer function through the same padding: restore with H = 1/H.
    let blurred = wiener_restore(
        sharp.view(),
        &FnTransfer(move |fx, fy| 1.0 / h(fx, fy)),
        NoiseRule::Constant(0.0),
    )
    .unwrap()
    .image;
    let restored = wiener_restore(blurred.view(), &FnTransfer(h), NoiseRule::Constant(1e-12))
        .unwrap()
        .image;
    let err = (&restored - &sharp).mapv(f64::abs);
    let (at, worst) =
        err.indexed_iter().fold(
            ((0, 0), 0.0f64),
            |acc, (i, v)| if *v > acc.1 { (i, *v) } else { acc },
        );
    let interior = err
        .slice(ndarray::s![8..56, 8..72])
        .iter()
        .fold(0.0f64, |a, v| a.max(*v));
    assert!(worst < 1e-3, "worst {worst} at {at:?}, interior {interior}");
}

#[test]
fn restore_refuses_wrong_size_8_bit_and_colour_images_writing_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let cases: Vec<(std::path::PathBuf, &str)> = {
        let small = dir.path().join("small.tiff");
        raster::write_tiff_u16(&small, Array2::<u16>::zeros((10, 12)).view()).unwrap();
        let rgb = dir.path().join("rgb.png");
        raster::write_png_rgb8(&rgb, ndarray::Array3::<u8>::zeros((N, N, 3)).view()).unwrap();
        let grey8 = dir.path().join("grey8.png");
        write_png_gray8(&grey8, N, N);
        vec![
            (small, "12 × 10"),
            (rgb, "16-bit greyscale"),
            (grey8, "16-bit greyscale"),
        ]
    };
    for (input, needle) in cases {
        let out = dir.path().join("out");
        let mut cmd = eoir();
        cmd.arg("restore")
            .arg(&input)
            .args(["--sensor", "multimir"]);
        for o in overrides() {
            cmd.args(["--set", &o]);
        }
        let res = cmd.arg("-o").arg(&out).output().unwrap();
        let err = String::from_utf8_lossy(&res.stderr);
        assert!(!res.status.success());
        assert!(err.contains(needle), "{}: {err}", input.display());
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(!out.exists());
    }
}

/// An 8-bit greyscale PNG (the raster module writes only 16-bit grey and 8-bit RGB).
fn write_png_gray8(path: &Path, rows: usize, cols: usize) {
    let file = std::fs::File::create(path).unwrap();
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), cols as u32, rows as u32);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header().unwrap();
    w.write_image_data(&vec![128u8; rows * cols]).unwrap();
}

// ---- The restoration matrix (issue 38): every preset × built-in scene × noise level ----

/// One cell of the restoration matrix.
struct Cell {
    preset: &'static str,
    scene: &'static str,
    noise: &'static str,
    method: &'static str,
    psnr_input: f64,
    psnr_restored: f64,
    psnr_best_constant: f64,
    mtf50: Option<(f64, f64)>,
    saturated: usize,
    defects: usize,
}

/// The unblurred twin of any sensor: every transfer-function component off and a
/// point-sampling footprint (1/1000 of the pitch).
fn unblurred_any(s: &Sensor) -> Sensor {
    let mut u: SensorConfig = s.config().clone();
    u.diffraction.enabled = false;
    u.aberration = None;
    u.defocus = None;
    u.motion = None;
    u.jitter = None;
    u.turbulence = None;
    u.aerosol = None;
    u.gaussian = None;
    u.measured = None;
    u.detector.active_width_m = s.detector.pitch_m * 1e-3;
    u.detector.active_height_m = None;
    Sensor::build(&u).unwrap()
}

/// Runs one cell: `preset` (its default options) on a 96 × 96 window, the built-in
/// scene `kind` (`eoir scene` defaults, 4 scene samples per pixel, over the sensor's
/// band, sunlit below 3 µm), at the preset's read noise or 10× it; the recorded DN's
/// defects found and replaced ([`find_image_defects`]), converted to electrons; restored
/// with the defaults (`--noise auto --method auto`); and compared with the unblurred
/// sensor's noise-free electrons.
fn matrix_cell(preset: &'static str, kind: &'static str, x10: bool) -> Cell {
    use eoir::processing::bad_pixels::{find_image_defects, replace};
    use eoir::processing::wiener::{restore, Method, RestoreMasks};
    let base = presets::load(preset, &[], &[]).unwrap();
    let read = base.detector.read_noise_e.unwrap_or(0.0);
    let mut o = vec![format!("detector.rows={N}"), format!("detector.cols={N}")];
    if x10 {
        o.push(format!("detector.read_noise_e={}", 10.0 * read.max(1.0)));
    }
    let s = Sensor::build(&presets::load(preset, &[], &o).unwrap()).unwrap();
    let (lo, hi) = s.response().support_um();
    let p = SceneParams {
        rows: N,
        cols: N,
        oversampling: 4,
        wavelength_um: SceneParams::uniform_grid(lo, hi, 24).unwrap(),
        fov_x_deg: (s.ifov_rad() * N as f64).to_degrees(),
        range_m: Some(1900.0),
        seed: 1,
        sun: hi < 3.0,
    };
    let cube = synthetic::generate(kind, &p).unwrap();
    let rec = record(&s, &cube);
    let model = s.detector();
    let truth = {
        let u = unblurred_any(&s);
        let out = run(&u, &cube);
        let area = s.detector.active_area_m2() / u.detector.active_area_m2();
        out.frames[0].electrons_mean.mapv(|v| v as f64 * area)
    };
    let dn = rec.dn.mapv(f64::from);
    let found = find_image_defects(dn.view(), IMPULSE_K_SIGMA, Some(model.max_dn())).unwrap();
    let clean = replace(dn.view(), &found.defects).unwrap();
    let input = clean.mapv(|v| (v - rec.black) / rec.gain);
    let noise_mask = found.defects.union(&found.saturated).unwrap();
    let masks = RestoreMasks {
        noise: Some(&noise_mask),
        saturated: Some(&found.saturated),
    };
    let transfer = SensorTransfer::new(&s).unwrap();
    let r = restore(
        input.view(),
        &transfer,
        NoiseRule::Auto,
        Method::Auto,
        masks,
    )
    .unwrap();
    let psnr_input = psnr_db(input.view(), truth.view()).unwrap();
    let psnr_restored = psnr_db(r.image.view(), truth.view()).unwrap();
    let psnr_best_constant = (0..29)
        .map(|i| {
            let nsr = 10f64.powf(-6.0 + 0.25 * i as f64);
            let c = restore(
                input.view(),
                &transfer,
                NoiseRule::Constant(nsr),
                Method::Wiener,
                masks,
            )
            .unwrap();
            psnr_db(c.image.view(), truth.view()).unwrap()
        })
        .fold(f64::NEG_INFINITY, f64::max);
    let mtf50 = (kind == "edge").then(|| {
        let a = slanted_edge_mtf(input.view(), None)
            .unwrap()
            .mtf50_cy_per_px
            .unwrap_or(f64::NAN);
        let b = slanted_edge_mtf(r.image.view(), None)
            .unwrap()
            .mtf50_cy_per_px
            .unwrap_or(f64::NAN);
        (a, b)
    });
    Cell {
        preset,
        scene: kind,
        noise: if x10 { "10× read" } else { "preset" },
        method: r.method,
        psnr_input,
        psnr_restored,
        psnr_best_constant,
        mtf50,
        saturated: found.saturated.count(),
        defects: found.defects.count(),
    }
}

/// The must-show of every cell: PSNR against the unblurred truth at least the input's,
/// within 0.5 dB of the best constant NSR (searched over 1e−6 … 1e1, four per decade),
/// and (edge scene) a measured MTF50 at least the input's (1 % allowance for the
/// measurement's own scatter).
fn check(c: &Cell) {
    let id = format!("{} × {} at {} noise", c.preset, c.scene, c.noise);
    assert!(
        c.psnr_restored >= c.psnr_input - 1e-9,
        "{id}: restored {:.2} dB < input {:.2} dB",
        c.psnr_restored,
        c.psnr_input
    );
    assert!(
        c.psnr_restored >= c.psnr_best_constant - 0.5,
        "{id}: restored {:.2} dB vs best constant {:.2} dB",
        c.psnr_restored,
        c.psnr_best_constant
    );
    if let Some((a, b)) = c.mtf50 {
        assert!(b >= 0.99 * a, "{id}: MTF50 {a:.4} → {b:.4}");
    }
}

fn row(c: &Cell) -> String {
    format!(
        "| {} | {} | {} | {} | {:.2} | {:.2} | {:.2} | {} | {} | {} |",
        c.preset,
        c.scene,
        c.noise,
        c.method,
        c.psnr_input,
        c.psnr_restored,
        c.psnr_best_constant,
        c.mtf50
            .map_or("—".to_string(), |(a, b)| format!("{a:.3} → {b:.3}")),
        c.defects,
        c.saturated
    )
}

/// Presets of the matrix: every single-band preset (`ccd-bayer` records a colour mosaic,
/// which a single transfer function does not describe; `threeband` at its default channel).
const MATRIX_PRESETS: [&str; 5] = ["multimir", "emerald", "qwip", "ccd", "threeband"];
const MATRIX_SCENES: [&str; 3] = ["edge", "bars", "thermal"];

#[test]
fn restoration_matrix_multimir_never_loses_and_tracks_the_best_constant() {
    for scene in MATRIX_SCENES {
        for x10 in [false, true] {
            let c = matrix_cell("multimir", scene, x10);
            eprintln!("{}", row(&c));
            check(&c);
        }
    }
}

/// The whole matrix, and its table in docs/way-back.md (between the `restore-matrix`
/// markers) checked against the numbers measured here; `EOIR_UPDATE_DOCS=1` rewrites it.
#[test]
#[ignore = "the full preset × scene × noise matrix (about a minute in release); CI runs it"]
fn restoration_matrix_full_and_its_docs_table() {
    let mut rows = vec![
        "| preset | scene | noise | method | PSNR input (dB) | PSNR restored (dB) | PSNR best constant NSR (dB) | MTF50 input → restored (cy/px) | defects replaced | saturated px |".to_string(),
        "|---|---|---|---|---|---|---|---|---|---|".to_string(),
    ];
    let mut failures = Vec::new();
    for preset in MATRIX_PRESETS {
        for scene in MATRIX_SCENES {
            for x10 in [false, true] {
                let c = matrix_cell(preset, scene, x10);
                eprintln!("{}", row(&c));
                rows.push(row(&c));
                if let Err(e) = std::panic::catch_unwind(|| check(&c)) {
                    failures.push(format!("{:?}", e.downcast_ref::<String>()));
                }
            }
        }
    }
    let table = rows.join("\n");
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/way-back.md");
    let doc = std::fs::read_to_string(&path).unwrap();
    let (begin, end) = (
        "<!-- restore-matrix begin -->\n",
        "<!-- restore-matrix end -->",
    );
    let a = doc.find(begin).expect("begin marker") + begin.len();
    let b = doc.find(end).expect("end marker");
    if std::env::var_os("EOIR_UPDATE_DOCS").is_some() {
        let new = format!("{}{}\n{}", &doc[..a], table, &doc[b..]);
        std::fs::write(&path, new).unwrap();
    } else {
        assert_eq!(
            doc[a..b].trim_end(),
            table,
            "docs/way-back.md's table is stale: rerun with EOIR_UPDATE_DOCS=1"
        );
    }
    assert!(failures.is_empty(), "{failures:?}");
}

/// The first failing case, from outside as a user would (on a 128 × 128 MultimIR
/// window to stay fast; otherwise every default): `eoir scene edge` → `eoir run` →
/// `eoir restore` → `eoir edge-mtf`. The restored edge must not be blurrier than the
/// recorded one (it was: MTF50 0.359 → 0.179 with the §3.6 noise rule); the defects come
/// from the run's own instance map; the image's measured noise agrees with the model's.
#[test]
fn scene_run_restore_edge_mtf_defaults_never_blur_the_edge() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let set = ["--set", "detector.rows=128", "--set", "detector.cols=128"];
    let ok = |o: std::process::Output| {
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        o
    };
    ok(eoir()
        .current_dir(d)
        .args(["scene", "edge", "-o", "s.hdr", "--sensor", "multimir"])
        .args(set)
        .output()
        .unwrap());
    ok(eoir()
        .current_dir(d)
        .args([
            "run", "--sensor", "multimir", "--quiet", "s.hdr", "-o", "run",
        ])
        .args(set)
        .output()
        .unwrap());
    ok(eoir()
        .current_dir(d)
        .args([
            "restore",
            "run/dn.tiff",
            "--sensor",
            "multimir",
            "-o",
            "res",
        ])
        .args(set)
        .output()
        .unwrap());
    let mtf = |img: &str, out: &str| {
        ok(eoir()
            .current_dir(d)
            .args(["edge-mtf", img, "-o", out])
            .output()
            .unwrap());
        let j: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(d.join(out).join("edge_mtf.json")).unwrap(),
        )
        .unwrap();
        j
    };
    let a = mtf("run/dn.tiff", "m_in");
    let b = mtf("res/restored.tiff", "m_out");
    let (m_in, m_out) = (
        a["mtf50_cy_per_px"].as_f64().unwrap(),
        b["mtf50_cy_per_px"].as_f64().unwrap(),
    );
    let (n_in, n_out) = (
        a["mtf_at_nyquist"].as_f64().unwrap(),
        b["mtf_at_nyquist"].as_f64().unwrap(),
    );
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("res/restore.json")).unwrap())
            .unwrap();
    eprintln!(
        "MTF50 {m_in:.3} → {m_out:.3} cy/px, MTF at Nyquist {n_in:.3} → {n_out:.3}; method {}, noise σ measured {} vs model {}; defects from {}",
        j["method"], j["noise_sigma_measured"], j["noise_sigma_model"], j["defects"]["source"]
    );
    assert!(m_out >= m_in, "{m_out} < {m_in}");
    assert!(n_out >= n_in, "{n_out} < {n_in}");
    assert_eq!(j["defects"]["source"], "instance");
    assert_eq!(a["defects"]["source"], "instance");
    let (sm, sd) = (
        j["noise_sigma_measured"].as_f64().unwrap(),
        j["noise_sigma_model"].as_f64().unwrap(),
    );
    assert!((sm / sd - 1.0).abs() < 0.25, "noise {sm} vs model {sd}");
    // Uncertainties are reported and small against the MTF50 itself.
    let s50 = a["mtf50_sigma_cy_per_px"].as_f64().unwrap();
    assert!(s50 > 0.0 && s50 < 0.1 * m_in, "{s50}");
}
