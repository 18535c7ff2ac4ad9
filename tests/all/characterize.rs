//! EMVA 1288 characterisation: simulated acquisition sets analysed back to the
//! configured camera (truth.json), the datasheet outputs, bad acquisition sets, and the
//! per-exposure temporal-noise streams.

use std::path::Path;
use std::process::Command;

use eoir::characterize::{self, SimulateOptions};
use eoir::detector::{DetectorInstance, DetectorModel};
use eoir::sensor::Sensor;

fn model_of(config: &eoir::sensor::SensorConfig) -> DetectorModel {
    Sensor::build(config).unwrap().detector().clone()
}
use eoir::sensor::presets;
use ndarray::Array2;

fn eoir() -> Command {
    Command::new(env!("CARGO_BIN_EXE_eoir"))
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// Overrides that give every preset a measurable camera: read noise 3 DN, DSNU 2 DN,
/// PRNU 1 %, a black level that keeps the darks off 0 DN, no defects clipping… (the
/// preset's own K, full well, QE, dark current and background are kept).
fn measurable(name: &str) -> Vec<String> {
    let base = presets::load(name, &[], &[]).unwrap();
    let k = model_of(&base).gain_dn_per_e();
    vec![
        format!("detector.read_noise_e={}", 3.0 / k),
        format!("detector.fpn.dsnu_sigma_e={}", 2.0 / k),
        "detector.fpn.prnu_sigma_rel=0.01".to_string(),
        "detector.offset_dn=40".to_string(),
    ]
}

/// The must-show: for every preset the analysis of its simulated set recovers K, QE,
/// σ_d, DSNU and PRNU within 2 % of truth.json and the saturation capacity within 5 %.
/// 128 × 128 pixel window (16 384 pixels: a sample standard deviation then scatters by
/// 1/√(2N) = 0.55 %), 54 photon-transfer levels, 16-frame stacks, seed 7.
#[test]
fn simulated_sets_recover_the_configured_camera_for_every_preset() {
    let dir = tempfile::tempdir().unwrap();
    for info in presets::list() {
        let name = info.name.clone();
        let sensor = presets::load(&name, &[], &measurable(&name)).unwrap();
        let set = dir.path().join(&name);
        let truth = characterize::simulate(
            &sensor,
            &set,
            &SimulateOptions {
                seed: 7,
                window: 128,
            },
        )
        .unwrap();
        assert!(truth.warnings.is_empty(), "{name}: {:?}", truth.warnings);
        let c = characterize::characterize(&set.join("descriptor.txt")).unwrap();
        let checks = [
            ("K", c.K_DN_per_e, truth.K_DN_per_e, 0.02),
            ("QE", c.QE_percent.unwrap(), truth.QE_percent, 0.02),
            ("sigma_d", c.sigma_d_e, truth.sigma_d_e, 0.02),
            ("DSNU", c.DSNU1288_e, truth.DSNU1288_e, 0.02),
            ("PRNU", c.PRNU1288_percent, truth.PRNU1288_percent, 0.02),
            ("u_e_sat", c.u_e_sat_e, truth.u_e_sat_e, 0.05),
        ];
        for (what, got, want, tol) in checks {
            eprintln!(
                "{name}: {what} measured {got:.6e}, truth {want:.6e}, {:.3} %",
                100.0 * rel(got, want)
            );
            assert!(
                rel(got, want) <= tol,
                "{name}: {what} {got} vs truth {want}"
            );
        }
        assert_eq!(
            c.defective_pixels, truth.defective_pixels,
            "{name}: defects excluded"
        );
        assert!(c.levels.len() >= 50);
        // Dark current from the mean dark signal at five exposure times: the configured
        // rate where it is measurable (≥ 1 DN over the series), else just finite.
        let dc = c.dark_current_mean_e_per_s.unwrap();
        let span_dn =
            truth.dark_current_e_per_s * 3.75 * truth.exposure_ns * 1e-9 * truth.K_DN_per_e;
        if span_dn > 20.0 {
            assert!(
                rel(dc, truth.dark_current_e_per_s) < 0.02,
                "{name}: dark current {dc}"
            );
        } else {
            assert!(dc.is_finite());
        }
    }
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let p = e.path();
        if p.is_dir() {
            copy_dir(&p, &to.join(e.file_name()));
        } else {
            std::fs::copy(&p, to.join(e.file_name())).unwrap();
        }
    }
}

fn small_set(dir: &Path) -> std::path::PathBuf {
    let set = dir.join("set");
    let out = eoir()
        .args([
            "characterize",
            "--simulate",
            "--sensor",
            "ccd",
            "--window",
            "32",
            "--seed",
            "3",
        ])
        .args(measurable("ccd").iter().flat_map(|s| ["--set", s.as_str()]))
        .arg("-o")
        .arg(&set)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    set
}

#[test]
fn cli_simulates_and_characterises_with_datasheet() {
    let dir = tempfile::tempdir().unwrap();
    let set = small_set(dir.path());
    let text = std::fs::read_to_string(set.join("descriptor.txt")).unwrap();
    assert!(text.contains("\nv 3.0\n") && text.contains("\nn 10 32 32\n"));
    let parsed = characterize::Descriptor::parse(&text, Path::new("descriptor.txt")).unwrap();
    let bright_pairs = parsed
        .series
        .iter()
        .filter(|s| s.is_temporal() && !s.is_dark())
        .count();
    assert!(bright_pairs >= 50);
    let stacks: Vec<_> = parsed.series.iter().filter(|s| !s.is_temporal()).collect();
    assert_eq!(stacks.len(), 2);
    assert!(stacks.iter().all(|s| s.images.len() >= 16));
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(set.join("truth.json")).unwrap()).unwrap();
    for key in [
        "K_DN_per_e",
        "QE_percent",
        "read_noise_e",
        "DSNU1288_e",
        "PRNU1288_percent",
        "full_well_e",
    ] {
        assert!(truth[key].is_number(), "truth.json lacks {key}");
    }
    let out_dir = dir.path().join("out");
    let out = eoir()
        .args(["characterize"])
        .arg(&set)
        .arg("-o")
        .arg(&out_dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out_dir.join("characterization.json")).unwrap(),
    )
    .unwrap();
    for key in [
        "K_DN_per_e",
        "QE_percent",
        "sigma_d_e",
        "DSNU1288_e",
        "PRNU1288_percent",
        "u_e_sat_e",
        "SNR_max",
        "DR",
        "linearity_error_percent",
        "dark_current_mean_e_per_s",
    ] {
        assert!(json[key].is_number(), "characterization.json lacks {key}");
    }
    // 1024 pixels only: K within 5 % here (the 2 % test uses 16 384 pixels).
    let k = json["K_DN_per_e"].as_f64().unwrap();
    assert!(rel(k, truth["K_DN_per_e"].as_f64().unwrap()) < 0.05);
    let html = std::fs::read_to_string(out_dir.join("characterization.html")).unwrap();
    // A simulated set gives photon counts: the linearity plot is drawn too, and the DSNU
    // and PRNU histograms of its stacks.
    let pngs = [
        "ptc.png",
        "snr.png",
        "linearity.png",
        "dsnu.png",
        "prnu.png",
    ];
    assert_eq!(
        html.matches("src=\"data:image/png;base64,").count(),
        pngs.len()
    );
    assert!(!html.contains("src=\"ptc.png\""));
    for png in pngs {
        let bytes = std::fs::read(out_dir.join(png)).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        // The inlined image is this file, base64-encoded.
        assert!(html.contains(&eoir::display::base64(&bytes)));
    }
}

/// Runs `eoir characterize SET -o OUT` on a broken copy of a set: it must fail with a
/// message containing `expect` and write nothing.
fn fails_cleanly(set: &Path, expect: &str) {
    let out_dir = set.parent().unwrap().join(format!(
        "out-{}",
        set.file_name().unwrap().to_string_lossy()
    ));
    let out = eoir()
        .args(["characterize"])
        .arg(set)
        .arg("-o")
        .arg(&out_dir)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains(expect), "expected `{expect}` in: {err}");
    assert_eq!(err.lines().count(), 1, "one clear error: {err}");
    assert!(!out_dir.exists(), "nothing written");
}

#[test]
fn bad_acquisition_sets_give_one_clear_error_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let set = small_set(dir.path());
    let text = std::fs::read_to_string(set.join("descriptor.txt")).unwrap();
    let variant = |name: &str, edit: &dyn Fn(&Path)| {
        let p = dir.path().join(name);
        copy_dir(&set, &p);
        edit(&p);
        p
    };
    // Missing darks: drop the dark pair at the photon-transfer exposure time.
    let no_dark = variant("nodark", &|p| {
        let t = text.replace("d 5000000\ni dark/d2_0.png\ni dark/d2_1.png\n", "");
        assert_ne!(t, text);
        std::fs::write(p.join("descriptor.txt"), t).unwrap();
    });
    fails_cleanly(&no_dark, "no dark pair");
    // One frame for a level.
    let one = variant("oneframe", &|p| {
        let t = text.replace("i ptc/b005_1.png\n", "");
        std::fs::write(p.join("descriptor.txt"), t).unwrap();
    });
    fails_cleanly(&one, "at least 2");
    // A referenced file is missing.
    let missing = variant("missing", &|p| {
        std::fs::remove_file(p.join("ptc/b010_0.png")).unwrap()
    });
    fails_cleanly(&missing, "b010_0.png` does not exist");
    // Wrong size.
    let size = variant("size", &|p| {
        eoir::io::raster::write_png_u16(
            &p.join("ptc/b011_0.png"),
            Array2::<u16>::zeros((16, 32)).view(),
        )
        .unwrap()
    });
    fails_cleanly(&size, "is 32 x 16 pixels");
    // 8-bit and colour images where DN are expected.
    let eight = variant("eight", &|p| {
        let f = std::fs::File::create(p.join("ptc/b012_0.png")).unwrap();
        let mut enc = png::Encoder::new(f, 32, 32);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Eight);
        enc.write_header()
            .unwrap()
            .write_image_data(&[0u8; 1024])
            .unwrap();
    });
    fails_cleanly(&eight, "16-bit greyscale");
    let colour = variant("colour", &|p| {
        eoir::io::raster::write_png_rgb8(
            &p.join("ptc/b013_0.png"),
            ndarray::Array3::<u8>::zeros((32, 32, 3)).view(),
        )
        .unwrap()
    });
    fails_cleanly(&colour, "16-bit greyscale");
}

#[test]
fn simulate_refuses_a_non_empty_directory_and_leaves_it_alone() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("keep.txt"), "x").unwrap();
    let out = eoir()
        .args([
            "characterize",
            "--simulate",
            "--sensor",
            "ccd",
            "--window",
            "16",
            "-o",
        ])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("not empty"));
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

/// Temporal noise has a stream per exposure: frame 0 at two exposure times (or two
/// exposure keys) are independent draws — their noise is uncorrelated — while the same
/// seed, exposure and frame repeat bit for bit and the fixed pattern is shared.
#[test]
fn each_exposure_draws_its_own_temporal_noise() {
    let overrides = |t: &str| {
        vec![
            "detector.rows=64".to_string(),
            "detector.cols=64".to_string(),
            format!("detector.integration_time_s={t}"),
            "detector.gain_dn_per_e=0.5".to_string(),
            "detector.read_noise_e=20".to_string(),
            "detector.offset_dn=200".to_string(),
            "detector.fpn.prnu_sigma_rel=0.02".to_string(),
        ]
    };
    let m1 = model_of(&presets::load("ccd", &[], &overrides("5e-3")).unwrap());
    let m2 = model_of(&presets::load("ccd", &[], &overrides("6e-3")).unwrap());
    let i1 = DetectorInstance::new(&m1, 11).unwrap();
    let i2 = DetectorInstance::new(&m2, 11).unwrap();
    assert_eq!(i1.gain_map(), i2.gain_map(), "fixed pattern shared");
    let mean = Array2::from_elem((64, 64), 1000.0);
    let a = i1.expose(&mean, 0).unwrap();
    assert_eq!(a, i1.expose(&mean, 0).unwrap(), "same seed, same output");
    let b = i2.expose(&mean, 0).unwrap();
    let c = i1.expose_exposure(&mean, 1, 0).unwrap();
    let d = i1.expose_exposure(&mean, 2, 0).unwrap();
    // Noise of a frame: the frame minus the noiseless fixed-pattern response.
    let g = i1.gain_map();
    let noise = |f: &Array2<u16>| -> Vec<f64> {
        f.iter()
            .zip(g.iter())
            .map(|(&v, &gg)| v as f64 - (0.5 * 1000.0 * gg + 200.0))
            .collect()
    };
    let corr = |x: &[f64], y: &[f64]| {
        let n = x.len() as f64;
        let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
        let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
        let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
        let syy: f64 = y.iter().map(|b| (b - my) * (b - my)).sum();
        sxy / (sxx * syy).sqrt()
    };
    // Independent draws: |r| below 4/√N = 0.0625 (N = 4096).
    for (x, y, what) in [
        (&a, &b, "t = 5 vs 6 ms"),
        (&c, &d, "exposure keys 1 vs 2"),
        (&a, &c, "default vs key 1"),
    ] {
        let r = corr(&noise(x), &noise(y));
        assert!(r.abs() < 0.0625, "{what}: correlation {r}");
    }
}
