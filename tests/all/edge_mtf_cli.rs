//! `eoir edge-mtf` end to end: a 16-bit PNG of a Gaussian-blurred slanted edge in, the CSV,
//! PNG and JSON out; with `--sensor` the CSV gains cycles/mrad; a bad ROI writes nothing.

use std::path::Path;
use std::process::Command;

use ndarray::Array2;

/// A point-sampled edge at `angle_deg` from the columns, blurred by a Gaussian of `sigma_px`:
/// pixel = lo + (hi − lo)·Φ(d/σ), d the signed distance from the edge line through the centre.
fn gaussian_edge(rows: usize, cols: usize, angle_deg: f64, sigma_px: f64) -> Array2<u16> {
    let (lo, hi) = (1000.0, 20000.0);
    let (s, c) = angle_deg.to_radians().sin_cos();
    let (y0, x0) = ((rows as f64 - 1.0) / 2.0, (cols as f64 - 1.0) / 2.0);
    Array2::from_shape_fn((rows, cols), |(y, x)| {
        let d = (x as f64 - x0) * c - (y as f64 - y0) * s;
        let phi = 0.5 * (1.0 + libm::erf(d / (sigma_px * std::f64::consts::SQRT_2)));
        (lo + (hi - lo) * phi).round() as u16
    })
}

fn eoir(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_eoir"))
        .args(args)
        .output()
        .expect("run eoir")
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn edge_mtf_cli_writes_csv_png_json_and_measures_a_known_gaussian() {
    let dir = tempfile::tempdir().unwrap();
    let sigma = 1.2;
    let img = dir.path().join("edge.png");
    eoir::io::raster::write_png_u16(&img, gaussian_edge(96, 96, 5.0, sigma).view()).unwrap();
    let out = dir.path().join("mtf");
    let o = eoir(&[
        "edge-mtf",
        img.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // MTF50 of a Gaussian LSF: exp(−2π²σ²f²) = ½ ⇒ f = √(ln2/2)/(πσ).
    let expected = (std::f64::consts::LN_2 / 2.0).sqrt() / (std::f64::consts::PI * sigma);
    let j = json(&out.join("edge_mtf.json"));
    let mtf50 = j["mtf50_cy_per_px"].as_f64().unwrap();
    assert!(
        (mtf50 / expected - 1.0).abs() < 0.02,
        "MTF50 {mtf50} vs {expected}"
    );
    let angle = j.to_string();
    assert!(
        angle.contains("angle"),
        "the JSON names the edge angle: {angle}"
    );
    let csv = std::fs::read_to_string(out.join("edge_mtf.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next().unwrap(), "freq_cy_per_px,mtf");
    let first: Vec<f64> = lines
        .next()
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(first[0], 0.0);
    assert!(
        (first[1] - 1.0).abs() < 1e-6,
        "MTF at zero frequency {}",
        first[1]
    );
    let png = std::fs::read(out.join("edge_mtf.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");

    // With a sensor (sized to the image) the CSV carries cycles/mrad = cycles/px / IFOV(mrad).
    let out2 = dir.path().join("mtf-sensor");
    let o = eoir(&[
        "edge-mtf",
        img.to_str().unwrap(),
        "--sensor",
        "multimir",
        "--set",
        "detector.rows=96",
        "--set",
        "detector.cols=96",
        "-o",
        out2.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let config = eoir::sensor::presets::load(
        "multimir",
        &[],
        &["detector.rows=96".into(), "detector.cols=96".into()],
    )
    .unwrap();
    let ifov_mrad = config.ifov_rad() * 1e3;
    let csv = std::fs::read_to_string(out2.join("edge_mtf.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next().unwrap(), "freq_cy_per_px,freq_cy_per_mrad,mtf");
    // The CSV prints 6 decimals: allow half a unit of the last place on both columns.
    let tol = 0.5e-6 / ifov_mrad + 0.5e-6 + 1e-12;
    for line in lines.take(20) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        assert!(
            (v[1] - v[0] / ifov_mrad).abs() <= tol,
            "{line} (IFOV {ifov_mrad} mrad)"
        );
    }
}

#[test]
fn edge_mtf_cli_bad_roi_and_no_edge_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let img = dir.path().join("edge.png");
    eoir::io::raster::write_png_u16(&img, gaussian_edge(64, 64, 5.0, 1.0).view()).unwrap();
    let flat = dir.path().join("flat.png");
    eoir::io::raster::write_png_u16(&flat, Array2::from_elem((64, 64), 5000u16).view()).unwrap();
    for (input, extra) in [
        (&img, vec!["--roi", "50,50,40,40"]),
        (&img, vec!["--roi", "nonsense"]),
        (&flat, vec![]),
    ] {
        let out = dir.path().join("never");
        let mut args = vec![
            "edge-mtf",
            input.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend(extra.iter().copied());
        let o = eoir(&args);
        assert!(!o.status.success(), "{args:?} should fail");
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(
            err.lines().filter(|l| l.starts_with("error:")).count(),
            1,
            "{err}"
        );
        assert!(!out.exists(), "{args:?} left {out:?} behind");
    }
}
