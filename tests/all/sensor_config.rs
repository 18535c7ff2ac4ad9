//! Sensor files: loading, validation errors that name the field, `--set` overrides, and the
//! transfer-function cascade on a real-FFT grid.

use std::path::PathBuf;

use eoir::sensor::{presets, Component, FrequencyGrid, Sensor, SensorConfig};

const MINIMAL: &str = r#"
name = "t"
[optics]
focal_length_m = 0.1
f_number = 2.0
[filter]
kind = "top_hat"
lo_um = 3.0
hi_um = 5.0
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

/// The error as the CLI prints it: must be one line naming `needle`.
fn assert_one_line_error(r: eoir::Result<SensorConfig>, needles: &[&str]) {
    let e = r.expect_err("expected an error").to_string();
    assert!(!e.contains('\n'), "error spans several lines: {e}");
    for n in needles {
        assert!(e.contains(n), "error `{e}` does not mention `{n}`");
    }
}

#[test]
fn minimal_file_loads_with_defaults() {
    let s = parse(MINIMAL, &[]).unwrap();
    assert!(s.diffraction.enabled);
    assert!((s.detector.fill_factor() - (20.0f64 / 24.0).powi(2)).abs() < 1e-12);
    let otf = Sensor::build(&s).unwrap().otf().clone();
    assert_eq!(
        otf.components(),
        &[Component::Diffraction, Component::Detector]
    );
}

#[test]
fn impossible_values_name_the_field() {
    let cases: &[(&str, &[&str])] = &[
        ("optics.f_number=0", &["optics.f_number", "0"]),
        ("optics.f_number=-2", &["optics.f_number"]),
        (
            "optics.obscuration_ratio=1.0",
            &["optics.obscuration_ratio", "[0, 1)"],
        ),
        (
            "detector.active_width_m=30e-6",
            &["detector.active_width_m", "fill factor"],
        ),
        (
            "detector.integration_time_s=-1e-3",
            &["detector.integration_time_s"],
        ),
        ("detector.full_well_e=-5", &["detector.full_well_e"]),
        ("detector.bits=0", &["detector.bits"]),
        ("jitter.sigma_rad=-1", &["jitter.sigma_rad"]),
        ("filter.lo_um=6.0", &["filter"]),
    ];
    for (o, needles) in cases {
        assert_one_line_error(parse(MINIMAL, &[o]), needles);
    }
}

#[test]
fn unknown_keys_are_errors_with_line_numbers() {
    let text = MINIMAL.replace("f_number = 2.0", "f_numbr = 2.0");
    let e = parse(&text, &[]).unwrap_err().to_string();
    assert!(e.contains("f_numbr") && e.contains("line 5"), "{e}");
    assert!(!e.contains('\n'));
    // Unknown section.
    let text = format!("{MINIMAL}\n[optcs]\nx = 1\n");
    assert_one_line_error(parse(&text, &[]), &["optcs"]);
    // Unknown key through --set.
    assert_one_line_error(
        parse(MINIMAL, &["optics.focal_lenght_m=0.2"]),
        &["focal_lenght_m"],
    );
    // Unknown spectrum kind.
    let text = MINIMAL.replace("kind = \"top_hat\"", "kind = \"tophat\"");
    assert_one_line_error(parse(&text, &[]), &["tophat"]);
}

#[test]
fn slant_turbulence_rejects_ground_level() {
    let text = format!(
        "{MINIMAL}\n[turbulence]\npath = \"slant\"\ncn2_at_1m = 1e-13\nsensor_height_m = 0.0\ntarget_height_m = 100.0\nrange_m = 1000.0\n"
    );
    assert_one_line_error(parse(&text, &[]), &["sensor_height_m"]);
}

#[test]
fn overrides_change_values_and_enable_sections() {
    let s = parse(MINIMAL, &["optics.f_number=4", "jitter.sigma_rad=1e-5"]).unwrap();
    assert_eq!(s.optics.f_number, 4.0);
    assert_eq!(s.jitter.as_ref().unwrap().sigma_rad, 1e-5);
    let s = parse(
        MINIMAL,
        &["optics.transmission={ kind = \"constant\", value = 0.5 }"],
    )
    .unwrap();
    assert_eq!(
        s.optics.transmission,
        eoir::sensor::SpectrumConfig::Constant { value: 0.5 }
    );
    assert_one_line_error(parse(MINIMAL, &["optics"]), &["--set"]);
    assert_one_line_error(parse(MINIMAL, &["name.x=1"]), &["name"]);
}

#[test]
fn resolved_config_round_trips_through_toml() {
    let s = parse(
        MINIMAL,
        &["defocus.w020_waves=0.5", "motion.smear_rad=1e-4"],
    )
    .unwrap();
    let text = s.to_toml_string().unwrap();
    let back = parse(&text, &[]).unwrap();
    assert_eq!(s, back);
}

#[test]
fn embedded_presets_load_and_validate() {
    for (name, _) in presets::PRESETS {
        let s = presets::load(name, &[], &[]).unwrap();
        assert!(!s.description.is_empty());
        Sensor::build(&s).unwrap();
    }
    let e = presets::load("no-such-sensor", &[], &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("multimir"), "{e}");
}

#[test]
fn multimir_geometry_matches_the_report() {
    // FOI report table 3.1: 100 mm optics, 5.3° x 4.0° field of view.
    let s = presets::load("multimir", &[], &[]).unwrap();
    let (h, v) = s.fov_deg();
    assert!(
        (h - 5.3).abs() < 0.05 && (v - 4.0).abs() < 0.05,
        "{h} x {v}"
    );
}

/// The real-FFT grid must list the frequencies of the DFT bins: bin j of an N-point DFT
/// with spacing d is the frequency whose complex exponential exp(2πi f n d) equals
/// exp(2πi j n / N) at every sample n.
#[test]
fn frequency_grid_matches_dft_bins() {
    let (rows, cols, dy, dx) = (6usize, 9usize, 2e-4, 3e-4);
    let g = FrequencyGrid::real_fft(rows, cols, dy, dx);
    assert_eq!(g.fy.len(), rows);
    assert_eq!(g.fx.len(), cols / 2 + 1);
    for (j, f) in g.fy.iter().enumerate() {
        for n in 0..rows {
            let a = 2.0 * std::f64::consts::PI * f * n as f64 * dy;
            let b = 2.0 * std::f64::consts::PI * (j * n) as f64 / rows as f64;
            assert!((a.cos() - b.cos()).abs() < 1e-9 && (a.sin() - b.sin()).abs() < 1e-9);
        }
        assert!(f.abs() <= 0.5 / dy + 1e-9);
    }
    for (k, f) in g.fx.iter().enumerate() {
        assert!((f - k as f64 / (cols as f64 * dx)).abs() < 1e-6);
    }
}

/// The grid cascade equals the product of the individual components evaluated pointwise,
/// and the cached achromatic part does not depend on wavelength.
#[test]
fn grid_otf_is_the_product_of_components() {
    let s = parse(
        MINIMAL,
        &[
            "aberration.rms_waves=0.05",
            "defocus.focus_shift_m=2e-5",
            "motion.smear_rad=1e-4",
            "motion.direction_deg=30",
            "jitter.sigma_rad=3e-5",
            "gaussian.sigma_rad=2e-5",
            "turbulence.path=\"horizontal\"",
            "turbulence.cn2=1e-14",
            "turbulence.range_m=2000",
        ],
    )
    .unwrap();
    let otf = Sensor::build(&s).unwrap().otf().clone();
    assert_eq!(otf.components().len(), 8);
    let ifov = s.ifov_rad() / 3.0;
    let grid = FrequencyGrid::real_fft(16, 20, ifov, ifov);
    let g = otf.on_grid(&grid);
    for lambda in [3.5, 4.7] {
        let m = g.at_wavelength(lambda);
        for (j, fy) in grid.fy.iter().enumerate() {
            for (k, fx) in grid.fx.iter().enumerate() {
                let direct: f64 = otf
                    .components()
                    .iter()
                    .map(|c| otf.component(*c, *fx, *fy, lambda))
                    .product();
                assert!((m[[j, k]] - direct).abs() < 1e-12, "{j} {k}");
            }
        }
    }
    // DC passes everything (no aerosol here).
    assert!((g.at_wavelength(4.0)[[0, 0]] - 1.0).abs() < 1e-12);
}

/// Detector sinc at the detector Nyquist with 100 % fill is 2/π (issue 2).
#[test]
fn detector_at_nyquist_full_fill_is_two_over_pi() {
    let s = parse(MINIMAL, &["detector.active_width_m=24e-6"]).unwrap();
    let otf = Sensor::build(&s).unwrap().otf().clone();
    let v = otf.component(Component::Detector, s.nyquist_cy_per_rad(), 0.0, 4.0);
    assert!((v - 2.0 / std::f64::consts::PI).abs() < 1e-12);
}

/// A per-watt responsivity curve is not a quantum efficiency: the error says what to use.
#[test]
fn photon_detector_curve_is_rejected_as_quantum_efficiency() {
    let text = MINIMAL.replace("kind = \"ideal_qe\"", "kind = \"photon_detector\"");
    assert_one_line_error(
        parse(&text, &[]),
        &["detector.quantum_efficiency", "ideal_qe"],
    );
}

/// Issue 39: an override's key is a key path and its value one TOML value; neither can
/// smuggle a second assignment or a table header into the description.
#[test]
fn overrides_are_key_paths_and_single_values_never_toml_text() {
    use eoir::sensor::Override;
    // `--set`: a value holding a newline and a table header is not one TOML value; it is
    // taken as a string, which the numeric field refuses, and f_number stays as written.
    let base = parse(MINIMAL, &[]).unwrap();
    let e = parse(
        MINIMAL,
        &["detector.integration_time_s=1e-3\n[optics]\nf_number=9"],
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("integration_time_s"), "{e}");
    // The typed path (Python): a key with `=`, a newline or a header is refused outright.
    for key in [
        "detector.integration_time_s=1e-3\n[optics]\nf_number",
        "optics.\"f_number\"",
        "optics..f_number",
        "",
    ] {
        let e = Override::new(key, toml::Value::Float(9.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("dotted key"), "{e}");
        assert!(!e.contains('\n'), "{e}");
    }
    // A well-formed typed override sets exactly its field.
    let o = Override::new("optics.f_number", toml::Value::Float(4.0)).unwrap();
    let s = SensorConfig::from_toml_str_with(MINIMAL, "t", PathBuf::from("."), &[o]).unwrap();
    assert_eq!(s.optics.f_number, 4.0);
    assert_eq!(s.detector, base.detector);
    // A value nested deeper than the limit is an error, not a stack overflow.
    let mut v = toml::Value::Integer(1);
    for _ in 0..10_000 {
        v = toml::Value::Array(vec![v]);
    }
    let e = Override::new("optics.f_number", v).unwrap_err().to_string();
    assert!(e.contains("levels"), "{e}");
}
