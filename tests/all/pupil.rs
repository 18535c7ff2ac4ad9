//! `eoir psf` and `eoir mtf --field` end to end (docs/wavefront.md): the PSF centroid a
//! coma wavefront writes into psf.json follows the centroid theorem and the Seidel field
//! law, and the pupil MTF columns of `eoir mtf --field` split into tangential and sagittal
//! as astigmatism does.

use crate::common::eoir;

/// A 50 mm aperture (f = 100 mm, F/2), coefficients at 4 µm, evaluated at 4 µm.
const BASE: &[&str] = &[
    "--sensor",
    "multimir",
    "--set",
    "optics.focal_length_m=0.1",
    "--set",
    "optics.f_number=2.0",
    "--set",
    "optics.wavefront.reference_wavelength_um=4.0",
    "--wavelength-um",
    "4.0",
];

#[test]
fn psf_json_centroids_follow_coma_and_the_field_law() {
    let dir = tempfile::tempdir().unwrap();
    let mut args = vec!["psf"];
    args.extend_from_slice(BASE);
    args.extend_from_slice(&[
        "--set",
        "optics.wavefront.w131_waves=0.3",
        "--field",
        "0,0.5,1",
        "-o",
        "out",
    ]);
    let o = eoir(dir.path(), &args);
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    assert!(dir.path().join("out/psf_grid.png").is_file());
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("out/psf.json")).unwrap())
            .unwrap();
    let fields = json["fields"].as_array().unwrap();
    assert_eq!(fields.len(), 3);
    // Centroid = 2 W131 H λ/D along the tangential axis (pupil-averaged wavefront slope).
    let lambda_over_d_urad = 4e-6 / 0.05 * 1e6;
    for (f, h) in fields.iter().zip([0.0, 0.5, 1.0]) {
        let cy = f["centroid_y_urad"].as_f64().unwrap();
        let cx = f["centroid_x_urad"].as_f64().unwrap();
        let want = 2.0 * 0.3 * h * lambda_over_d_urad;
        assert!(
            (cy - want).abs() <= 0.02 * want + 1e-9,
            "H = {h}: {cy} vs {want}"
        );
        assert!(cx.abs() < 1e-6, "H = {h}: x centroid {cx}");
        let strehl = f["strehl"].as_f64().unwrap();
        assert!(strehl > 0.0 && strehl <= 1.0);
    }
    assert!(fields[2]["strehl"].as_f64().unwrap() < fields[0]["strehl"].as_f64().unwrap());
    // A field height outside [0, 1] is a named error.
    let mut bad = vec!["psf"];
    bad.extend_from_slice(BASE);
    bad.extend_from_slice(&["--field", "1.5", "-o", "bad"]);
    let o = eoir(dir.path(), &bad);
    assert_ne!(o.code, Some(0));
    assert!(
        o.stderr.contains("field") && o.stderr.contains("[0, 1]"),
        "{}",
        o.stderr
    );
}

#[test]
fn mtf_field_adds_tangential_and_sagittal_pupil_mtfs() {
    let dir = tempfile::tempdir().unwrap();
    let mut args = vec!["mtf"];
    args.extend_from_slice(BASE);
    args.extend_from_slice(&[
        "--set",
        "optics.wavefront.w222_waves=0.5",
        "--field",
        "1",
        "--max-cy-per-mrad",
        "12.5",
        "--points",
        "51",
        "--csv",
        "mtf.csv",
    ]);
    let o = eoir(dir.path(), &args);
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    let text = std::fs::read_to_string(dir.path().join("mtf.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (d, t, s) = (
        col("diffraction"),
        col("pupil_tangential_H1"),
        col("pupil_sagittal_H1"),
    );
    let mut gap: f64 = 0.0;
    for line in lines {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        // Astigmatism W222 y² leaves the sagittal section diffraction-limited.
        assert!((v[s] - v[d].abs()).abs() < 2e-3, "{line}");
        gap = gap.max(v[s] - v[t]);
    }
    assert!(gap > 0.2, "tangential should fall below sagittal: {gap}");
}
