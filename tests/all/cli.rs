//! The `eoir` binary end to end: commands, products and error behaviour.

use std::path::Path;
use std::process::Command;

fn eoir() -> Command {
    Command::new(env!("CARGO_BIN_EXE_eoir"))
}

fn tempdir() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

#[test]
fn mtf_writes_csv_with_component_columns_and_png() {
    let dir = tempdir();
    let csv = dir.path().join("mtf.csv");
    let png = dir.path().join("mtf.png");
    let out = eoir()
        .args(["mtf", "--sensor", "multimir", "--points", "51", "--csv"])
        .arg(&csv)
        .arg("--png")
        .arg(&png)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "freq_cy_per_mrad,diffraction,aberration,detector,motion,jitter,system"
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 51);
    // Row 0 is DC: everything 1. System = product of the components in every row.
    assert!(rows[0][1..].iter().all(|v| (v - 1.0).abs() < 1e-9));
    for r in &rows {
        let prod: f64 = r[1..r.len() - 1].iter().product();
        assert!((prod - r[r.len() - 1]).abs() < 1e-7);
    }
    // Default range: max(cutoff, 2 x Nyquist). MultimIR 100 mm F/2 at ~4.9 µm: cutoff
    // D/λ = 0.05 m / 4.9e-6 m ≈ 10.3 cy/mrad; Nyquist = 0.1/(2·24e-6)/1000 ≈ 2.08 cy/mrad.
    let last = rows.last().unwrap()[0];
    assert!(last > 9.5 && last < 11.5, "{last}");
    let png_bytes = std::fs::read(&png).unwrap();
    assert_eq!(&png_bytes[1..4], b"PNG");
}

#[test]
fn invalid_sensor_file_gives_one_error_line_naming_the_field() {
    let dir = tempdir();
    let bad = dir.path().join("bad.toml");
    let text = eoir::sensor::presets::preset_text("multimir")
        .unwrap()
        .replace("f_number = 2.0", "f_number = 0.0");
    std::fs::write(&bad, text).unwrap();
    let out = eoir().args(["mtf", "--sensor"]).arg(&bad).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.contains("optics.f_number") && err.contains("bad.toml"),
        "{err}"
    );
    assert!(!err.contains("panicked"));
}

#[test]
fn unknown_set_key_is_an_error() {
    let out = eoir()
        .args(["mtf", "--sensor", "multimir", "--set", "optics.fnumber=3"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("fnumber"), "{err}");
}

#[test]
fn missing_file_is_named() {
    let out = eoir()
        .args(["mtf", "--sensor", "/nonexistent/s.toml"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("/nonexistent/s.toml"), "{err}");
    assert!(!Path::new("/nonexistent").exists());
}

/// Writes an ENVI cube by hand (BSQ float32 little-endian), every pixel of band b equal to
/// `value(λ_b)`, and returns the header path.
fn write_envi_with(
    dir: &Path,
    name: &str,
    bands: &[f64],
    rows: usize,
    cols: usize,
    value: impl Fn(f64) -> f32,
    fov: Option<(f64, f64)>,
) -> std::path::PathBuf {
    let hdr = dir.join(format!("{name}.hdr"));
    let img = dir.join(format!("{name}.img"));
    let wl: Vec<String> = bands.iter().map(|w| w.to_string()).collect();
    let mut h = format!(
        "ENVI\nsamples = {cols}\nlines = {rows}\nbands = {}\nheader offset = 0\ndata type = 4\ninterleave = bsq\nbyte order = 0\nwavelength units = Micrometers\nwavelength = {{{}}}\n",
        bands.len(),
        wl.join(", ")
    );
    if let Some((a, b)) = fov {
        h.push_str(&format!("eoir fov deg = {{{a}, {b}}}\n"));
    }
    std::fs::write(&hdr, h).unwrap();
    let mut bytes = Vec::new();
    for l in bands {
        let v = value(*l);
        for _ in 0..rows * cols {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(&img, bytes).unwrap();
    hdr
}

/// A spectrally flat ENVI cube of constant `value`.
fn write_envi(
    dir: &Path,
    name: &str,
    bands: &[f64],
    rows: usize,
    cols: usize,
    value: f32,
    fov: Option<(f64, f64)>,
) -> std::path::PathBuf {
    write_envi_with(dir, name, bands, rows, cols, |_| value, fov)
}

fn mwir_grid() -> Vec<f64> {
    (0..40).map(|i| 4.4 + 0.025 * i as f64).collect()
}

/// The multimir sensor's field of view, degrees (paraxial: pixels × IFOV).
const MULTIMIR_FOV: (f64, f64) = (
    384.0 * 0.24e-3 * 57.29577951308232,
    288.0 * 0.24e-3 * 57.29577951308232,
);

#[test]
fn run_writes_every_product_and_the_report() {
    let dir = tempdir();
    let input = write_envi(
        dir.path(),
        "flat",
        &mwir_grid(),
        288,
        384,
        3.0,
        Some(MULTIMIR_FOV),
    );
    let out = dir.path().join("out");
    let res = eoir()
        .args(["run", "--sensor", "multimir", "--quiet"])
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    for f in [
        "dn.tiff",
        "dn.png",
        "electrons_mean.tiff",
        "electrons_mean.exr",
        "config.toml",
        "report.json",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    if super::common::cli_has_hdf5() {
        assert!(out.join("products.h5").exists(), "products.h5 missing");
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["sampling"]["ratio_x"].as_f64().unwrap().round(), 1.0);
    assert!(report["detector"]["gain_dn_per_e"].as_f64().unwrap() > 0.0);
    let total = report["timings_s"]["total"].as_f64().unwrap();
    assert!(total > 0.0);
    let setup = report["timings_s"]["setup"].as_f64().unwrap();
    assert!(setup > 0.0 && setup < total, "setup {setup} s of {total} s");
    // A flat scene gives a flat image; the resolved config loads back as a sensor file.
    let e = eoir::io::raster::read_tiff_f32(&out.join("electrons_mean.tiff")).unwrap();
    let (lo, hi) = e
        .iter()
        .fold((f32::MAX, f32::MIN), |(a, b), v| (a.min(*v), b.max(*v)));
    assert!((hi - lo) / hi < 1e-5, "{lo} {hi}");
    eoir::sensor::SensorConfig::load(&out.join("config.toml"), &[]).unwrap();
    // No temporary files left behind.
    assert!(std::fs::read_dir(&out).unwrap().all(|e| !e
        .unwrap()
        .file_name()
        .to_string_lossy()
        .contains("eoir-tmp")));
}

/// Bad inputs: one clear error line naming the problem, and nothing written.
#[test]
fn bad_inputs_give_one_error_and_write_nothing() {
    let dir = tempdir();
    let cases: Vec<(std::path::PathBuf, &str)> = {
        let truncated = write_envi(
            dir.path(),
            "trunc",
            &mwir_grid(),
            288,
            384,
            3.0,
            Some(MULTIMIR_FOV),
        );
        let img = dir.path().join("trunc.img");
        let len = std::fs::metadata(&img).unwrap().len();
        std::fs::OpenOptions::new()
            .write(true)
            .open(&img)
            .unwrap()
            .set_len(len - 100)
            .unwrap();
        let short = write_envi(
            dir.path(),
            "short",
            &(0..20).map(|i| 4.0 + 0.025 * i as f64).collect::<Vec<_>>(),
            288,
            384,
            3.0,
            Some(MULTIMIR_FOV),
        );
        let nan = write_envi(
            dir.path(),
            "nan",
            &mwir_grid(),
            288,
            384,
            f32::NAN,
            Some(MULTIMIR_FOV),
        );
        let neg = write_envi(
            dir.path(),
            "neg",
            &mwir_grid(),
            288,
            384,
            -1.0,
            Some(MULTIMIR_FOV),
        );
        let nofov = write_envi(dir.path(), "nofov", &mwir_grid(), 288, 384, 3.0, None);
        let small = write_envi(
            dir.path(),
            "small",
            &mwir_grid(),
            200,
            300,
            3.0,
            Some((MULTIMIR_FOV.0 * 0.5, MULTIMIR_FOV.1 * 0.5)),
        );
        vec![
            (truncated, "trunc"),
            (short, "uncovered"),
            (nan, "NaN"),
            (neg, "-1"),
            (nofov, "field of view"),
            (small, "inside the scene"),
        ]
    };
    for (input, needle) in cases {
        let out = dir.path().join(format!("out-{needle}"));
        let res = eoir()
            .args(["run", "--sensor", "multimir"])
            .arg(&input)
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap();
        assert_eq!(res.status.code(), Some(1), "{}", input.display());
        let err = String::from_utf8_lossy(&res.stderr);
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(err.contains(needle), "`{err}` lacks `{needle}`");
        assert!(!err.contains("panicked"));
        assert!(!out.exists(), "output written for {}", input.display());
    }
}

/// `eoir scene` writes each kind in each default format; `eoir run` reads it back.
#[test]
fn scene_then_run_in_every_format() {
    let dir = tempdir();
    for (kind, ext) in [
        ("thermal", "npy"),
        ("bars", "exr"),
        ("edge", "hdr"),
        ("blackbody", "npy"),
        ("ramp", "exr"),
    ] {
        let file = dir.path().join(format!("{kind}.{ext}"));
        let res = eoir()
            .args([
                "scene",
                kind,
                "--rows",
                "36",
                "--cols",
                "48",
                "--oversampling",
                "2",
                "--lo-um",
                "4.4",
                "--hi-um",
                "5.4",
                "--bands",
                "21",
                "--fov-deg",
            ])
            .arg((48.0 * 0.24e-3f64).to_degrees().to_string())
            .arg("-o")
            .arg(&file)
            .output()
            .unwrap();
        assert!(
            res.status.success(),
            "{kind}: {}",
            String::from_utf8_lossy(&res.stderr)
        );
        let out = dir.path().join(format!("out-{kind}"));
        let res = eoir()
            .args([
                "run",
                "--sensor",
                "multimir",
                "--quiet",
                "--set",
                "detector.rows=36",
                "--set",
                "detector.cols=48",
            ])
            .arg(&file)
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap();
        assert!(
            res.status.success(),
            "{kind}: {}",
            String::from_utf8_lossy(&res.stderr)
        );
        assert!(out.join("dn.tiff").exists());
    }
    let res = eoir()
        .args(["scene", "nosuch", "-o"])
        .arg(dir.path().join("x.npy"))
        .output()
        .unwrap();
    assert_eq!(res.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&res.stderr).contains("thermal"));
}

/// A `[frame, band, row, col]` NPY sequence gives one set of products per frame, and the
/// frames differ where the scene does.
#[test]
fn sequence_input_writes_numbered_frames() {
    let dir = tempdir();
    let (frames, bands, rows, cols) = (3usize, 21usize, 24usize, 32usize);
    let data =
        ndarray::Array4::<f32>::from_shape_fn((frames, bands, rows, cols), |(f, _, r, c)| {
            if (c + 2 * f) % 8 < 4 && r > 4 {
                4.0
            } else {
                3.0
            }
        });
    let npy = dir.path().join("seq.npy");
    ndarray_npy::write_npy(&npy, &data).unwrap();
    let wl: Vec<f64> = (0..bands).map(|i| 4.4 + 0.05 * i as f64).collect();
    let fov = (
        (cols as f64 * 0.24e-3).to_degrees(),
        (rows as f64 * 0.24e-3).to_degrees(),
    );
    std::fs::write(
        dir.path().join("seq.json"),
        serde_json::json!({"wavelength_um": wl, "fov_deg": [fov.0, fov.1], "frame_time_s": 0.04})
            .to_string(),
    )
    .unwrap();
    let out = dir.path().join("out");
    let res = eoir()
        .args([
            "run",
            "--sensor",
            "multimir",
            "--quiet",
            "--set",
            "detector.rows=24",
            "--set",
            "detector.cols=32",
        ])
        .arg(&npy)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    let mut dn = Vec::new();
    for f in 0..frames {
        let p = out.join(format!("frame_{f:04}_dn.tiff"));
        dn.push(eoir::io::raster::read_tiff_u16(&p).unwrap());
    }
    assert_ne!(dn[0], dn[1]);
    // An animated preview of the sequence (APNG: an `acTL` chunk announcing 3 frames).
    let preview = std::fs::read(out.join("preview.png")).unwrap();
    let at = preview
        .windows(4)
        .position(|w| w == b"acTL")
        .expect("APNG acTL chunk");
    assert_eq!(
        u32::from_be_bytes(preview[at + 4..at + 8].try_into().unwrap()),
        3
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["input"]["frames"], 3);
}

/// Planck spectral radiance, W m-2 sr-1 µm-1 (written out here, independent of the library).
fn planck(l_um: f64, t: f64) -> f64 {
    let (h, c, k) = (6.626_070_15e-34, 299_792_458.0, 1.380_649e-23);
    let l = l_um * 1e-6;
    2.0 * h * c * c / l.powi(5) / ((h * c / (l * k * t)).exp() - 1.0) * 1e-6
}

/// A uniform blackbody ENVI cube for the multimir band at `rows × cols`.
fn blackbody_envi(dir: &Path, name: &str, t: f64, rows: usize, cols: usize) -> std::path::PathBuf {
    let fov = (
        (cols as f64 * 0.24e-3).to_degrees(),
        (rows as f64 * 0.24e-3).to_degrees(),
    );
    write_envi_with(
        dir,
        name,
        &mwir_grid(),
        rows,
        cols,
        |l| planck(l, t) as f32,
        Some(fov),
    )
}

fn run_multimir(input: &Path, out: &Path, seed: &str, extra: &[&str]) {
    let mut cmd = eoir();
    cmd.args(["run", "--sensor", "multimir", "--quiet", "--seed", seed])
        .args(["--set", "detector.rows=48", "--set", "detector.cols=64"]);
    for e in extra {
        cmd.args(["--set", e]);
    }
    let res = cmd.arg(input).arg("-o").arg(out).output().unwrap();
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
}

/// Issue 4: a uniform 300 K scene through FPN, NUC and inversion gives 300 K ± 0.05 K with
/// a spread consistent with the NETD; `eoir temperature` on the DN image reproduces it;
/// same seed ⇒ bit-identical DN, another seed ⇒ other noise with the same mean.
#[test]
fn uniform_300k_scene_round_trips_to_temperature() {
    let dir = tempdir();
    let input = blackbody_envi(dir.path(), "bb300", 300.0, 48, 64);
    let fpn = [
        "detector.fpn.prnu_sigma_rel=0.02",
        "detector.fpn.dsnu_sigma_e=2e4",
    ];
    let (a, b, c) = (
        dir.path().join("a"),
        dir.path().join("b"),
        dir.path().join("c"),
    );
    run_multimir(&input, &a, "5", &fpn);
    run_multimir(&input, &b, "5", &fpn);
    run_multimir(&input, &c, "6", &fpn);
    let dn = |d: &Path| eoir::io::raster::read_tiff_u16(&d.join("dn.tiff")).unwrap();
    assert_eq!(dn(&a), dn(&b), "same seed must give bit-identical DN");
    assert_ne!(dn(&a), dn(&c));
    let mean = |x: &ndarray::Array2<u16>| x.iter().map(|v| *v as f64).sum::<f64>() / x.len() as f64;
    assert!((mean(&dn(&a)) / mean(&dn(&c)) - 1.0).abs() < 2e-3);

    let t = eoir::io::raster::read_tiff_f32(&a.join("temperature.tiff")).unwrap();
    let valid: Vec<f64> = t
        .iter()
        .filter(|v| v.is_finite())
        .map(|v| *v as f64)
        .collect();
    assert!(valid.len() > t.len() * 95 / 100);
    let m = valid.iter().sum::<f64>() / valid.len() as f64;
    let sd = (valid.iter().map(|v| (v - m).powi(2)).sum::<f64>() / valid.len() as f64).sqrt();
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(a.join("report.json")).unwrap()).unwrap();
    let netd = report["calibration"]["netd_analytic_k_at_300k"]
        .as_f64()
        .unwrap();
    assert!((m - 300.0).abs() < 0.05, "mean apparent temperature {m}");
    // The measured NETD (frame stacks at 300 and 300.25 K) agrees with the analytic one.
    let measured = report["calibration"]["netd_measured_k_at_300k"]
        .as_f64()
        .unwrap();
    assert!(
        (measured / netd - 1.0).abs() < 0.05,
        "measured {measured} vs analytic {netd}"
    );
    assert!(a.join("temperature.exr").exists() && a.join("radiance.exr").exists());
    assert!(
        sd < 1.3 * netd && sd > 0.7 * netd,
        "spread {sd} K vs NETD {netd} K"
    );

    let conv = dir.path().join("conv");
    let res = eoir()
        .args(["temperature", "--sensor", "multimir", "--seed", "5"])
        .args(["--set", "detector.rows=48", "--set", "detector.cols=64"])
        .args(["--set", fpn[0], "--set", fpn[1]])
        .arg(a.join("dn.tiff"))
        .arg("-o")
        .arg(&conv)
        .output()
        .unwrap();
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    let t2 = eoir::io::raster::read_tiff_f32(&conv.join("temperature.tiff")).unwrap();
    for (x, y) in t.iter().zip(t2.iter()) {
        assert!((x.is_nan() && y.is_nan()) || x == y);
    }
}

/// `eoir run --composite` on a three-band preset writes each channel and the composite.
#[test]
fn composite_run_writes_channels_and_png() {
    let dir = tempdir();
    let scene = dir.path().join("vis.npy");
    let ifov: f64 = 5.5e-6 / 0.028;
    let res = eoir()
        .args([
            "scene",
            "thermal",
            "--rows",
            "26",
            "--cols",
            "35",
            "--oversampling",
            "2",
        ])
        .args([
            "--lo-um",
            "0.38",
            "--hi-um",
            "0.98",
            "--bands",
            "31",
            "--fov-deg",
        ])
        .arg((35.0 * ifov).to_degrees().to_string())
        .arg("-o")
        .arg(&scene)
        .output()
        .unwrap();
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    let out = dir.path().join("out");
    let res = eoir()
        .args(["run", "--sensor", "threeband", "--composite", "--quiet"])
        .args(["--set", "detector.rows=26", "--set", "detector.cols=35"])
        .arg(&scene)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    for ch in ["1", "2", "3"] {
        assert!(out.join(format!("channel-{ch}/dn.tiff")).exists());
    }
    let png = std::fs::read(out.join("composite.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    // A sensor without channels is refused with a clear message.
    let res = eoir()
        .args(["run", "--sensor", "qwip", "--composite"])
        .arg(&scene)
        .arg("-o")
        .arg(dir.path().join("x"))
        .output()
        .unwrap();
    assert_eq!(res.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&res.stderr).contains("channel"));
}
