//! Products a person looks at: the 8-bit `dn.png`, `temperature.png` with its colour bar,
//! the DN histogram, `report.html`, and the provenance notes of `eoir sensors show`.

use std::path::Path;
use std::process::Command;

use eoir::display::{self, Stretch};
use eoir::sensor::presets;

fn eoir() -> Command {
    Command::new(env!("CARGO_BIN_EXE_eoir"))
}

/// Runs `eoir demo` on a small detector (48 × 64 px) of `preset` into `dir`.
pub(crate) fn small_demo(preset: &str, dir: &Path) {
    let out = eoir()
        .args(["demo", "--quiet", "--sensor", preset])
        .args(["--set", "detector.rows=48", "--set", "detector.cols=64"])
        .arg("-o")
        .arg(dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{preset}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Decodes an 8-bit PNG: (width, height, channels, samples).
pub(crate) fn read_png8(path: &Path) -> (usize, usize, usize, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.bit_depth, png::BitDepth::Eight, "{}", path.display());
    let channels = match info.color_type {
        png::ColorType::Grayscale => 1,
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        other => panic!("unexpected colour type {other:?}"),
    };
    buf.truncate(info.buffer_size());
    (info.width as usize, info.height as usize, channels, buf)
}

fn percentile(values: &[u8], p: f64) -> f64 {
    let mut v: Vec<f64> = values.iter().map(|x| *x as f64).collect();
    v.sort_by(f64::total_cmp);
    display::percentile_sorted(&v, p)
}

#[test]
fn dn_png_of_every_preset_demo_is_bright_and_spread() {
    for p in presets::list() {
        let dir = tempfile::tempdir().unwrap();
        small_demo(&p.name, dir.path());
        let (w, h, ch, grey) = read_png8(&dir.path().join("dn.png"));
        assert_eq!((w, h, ch), (64, 48, 1), "{}", p.name);
        let mean = grey.iter().map(|v| *v as f64).sum::<f64>() / grey.len() as f64;
        let spread = percentile(&grey, 99.0) - percentile(&grey, 1.0);
        assert!(mean > 0.15 * 255.0, "{}: mean grey {mean:.1}", p.name);
        assert!(
            spread > 0.30 * 255.0,
            "{}: 1–99 % spread {spread:.1}",
            p.name
        );
        // The picture is the documented stretch of the raw DN in dn.tiff, recomputed here
        // from the sorted DN (NumPy-style linear percentiles).
        let dn = eoir::io::raster::read_tiff_u16(&dir.path().join("dn.tiff")).unwrap();
        let mut sorted: Vec<f64> = dn.iter().map(|v| *v as f64).collect();
        sorted.sort_by(f64::total_cmp);
        let rank = |q: f64| {
            let x = q * (sorted.len() - 1) as f64;
            let (i, f) = (x.floor() as usize, x - x.floor());
            sorted[i] + f * (sorted[(i + 1).min(sorted.len() - 1)] - sorted[i])
        };
        let (lo, hi) = (rank(0.005), rank(0.995));
        for (d, g) in dn.iter().zip(&grey) {
            let exact = if hi > lo {
                255.0 * ((*d as f64 - lo) / (hi - lo)).clamp(0.0, 1.0)
            } else {
                0.0
            };
            // A value on a rounding edge (x.5 to within float rounding of the stretch's
            // own arithmetic) may go either way; everywhere else the grey is exact.
            let tie = (exact - exact.floor() - 0.5).abs() < 1e-9;
            let ok = *g as f64 == exact.round() || (tie && *g as f64 == exact.floor());
            assert!(ok, "{}: DN {d}: grey {g}, stretch {exact}", p.name);
        }
    }
}

#[test]
fn thermal_demo_writes_colour_temperature_histogram_and_self_contained_page() {
    let dir = tempfile::tempdir().unwrap();
    small_demo("multimir", dir.path());
    let (w, h, ch, rgb) = read_png8(&dir.path().join("temperature.png"));
    assert_eq!(ch, 3);
    // Enlarged to at least 320 px high, with a colour bar and labels to the right.
    assert!(h >= 320 && w > 64 * 7, "{w} x {h}");
    let distinct: std::collections::HashSet<&[u8]> = rgb.chunks(3).collect();
    assert!(distinct.len() > 100, "{} colours", distinct.len());
    let (_, _, _, hist) = read_png8(&dir.path().join("dn_histogram.png"));
    assert!(hist.iter().any(|v| *v < 200));
    let html = std::fs::read_to_string(dir.path().join("report.html")).unwrap();
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap())
            .unwrap();
    // Self-contained: five inline pictures (DN, temperature, spectral response, MTF,
    // histogram), no external resource or script.
    assert_eq!(html.matches("src=\"data:image/png;base64,").count(), 5);
    let spectral = std::fs::read(dir.path().join("spectral_response.png")).unwrap();
    assert!(html.contains(&eoir::display::base64(&spectral)));
    for forbidden in ["http://", "https://", "<script", "<link"] {
        assert!(!html.contains(forbidden), "{forbidden}");
    }
    // The inline DN picture is byte-for-byte dn.png.
    let dn_png = std::fs::read(dir.path().join("dn.png")).unwrap();
    assert!(html.contains(&eoir::display::base64(&dn_png)));
    // Key numbers as report.json has them.
    let netd_mk = report["calibration"]["netd_analytic_k_at_300k"]
        .as_f64()
        .unwrap()
        * 1e3;
    let shown = span_value(&html, "netd_mk");
    assert!(
        (shown - netd_mk).abs() <= 0.006 * netd_mk,
        "{shown} vs {netd_mk}"
    );
    let snr = report["signal"]["snr"].as_f64().unwrap();
    let shown = span_value(&html, "snr");
    assert!((shown - snr).abs() <= 1e-3 * snr, "{shown} vs {snr}");
    // MultimIR has no fixed pattern: the raw flat-field non-uniformity is the temporal
    // noise left in the frame average, σ_t/(μ√M), which the report states independently;
    // the NUC cannot go below that floor.
    let nu = &report["calibration"]["residual_nonuniformity"];
    let (raw, floor) = (
        nu["raw"].as_f64().unwrap(),
        nu["temporal_floor"].as_f64().unwrap(),
    );
    assert!(
        (raw / floor - 1.0).abs() < 0.1,
        "raw {raw} vs floor {floor}"
    );
    assert!(nu["corrected"].as_f64().unwrap() > 0.9 * floor);
}

/// The number in the element with `id` of an HTML text.
pub(crate) fn span_value(html: &str, id: &str) -> f64 {
    let start = html
        .find(&format!("id=\"{id}\">"))
        .unwrap_or_else(|| panic!("no element {id}"))
        + id.len()
        + 6;
    let end = start + html[start..].find('<').unwrap();
    html[start..end].trim().parse().unwrap()
}

#[test]
fn inferno_follows_the_published_table_and_brightens_monotonically() {
    // Entries of matplotlib's 256-entry inferno table that are not knots.
    for (i, rgb) in [
        (100, [0.565854, 0.143567, 0.408258]),
        (196, [0.982881, 0.586606, 0.024661]),
        (248, [0.954529, 0.965896, 0.540361]),
    ] {
        let c = display::inferno(i as f64 / 255.0);
        for k in 0..3 {
            assert!(
                (c[k] as f64 - 255.0 * rgb[k]).abs() <= 0.02 * 255.0,
                "entry {i}: {c:?} vs {rgb:?}"
            );
        }
    }
    assert_eq!(display::inferno(0.0), [0, 0, 4]);
    assert_eq!(display::inferno(1.0), [252, 255, 164]);
    assert_eq!(display::inferno(f64::NAN), display::NO_VALUE_RGB);
    // Relative luminance rises along the map (it is designed monotonic in lightness).
    let lum = |c: [u8; 3]| 0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64;
    let mut last = -1.0;
    for i in 0..=64 {
        let l = lum(display::inferno(i as f64 / 64.0));
        assert!(l > last, "luminance falls at {i}/64");
        last = l;
    }
}

#[test]
fn stretch_and_histogram_count_what_they_should() {
    let s = Stretch::from_percentiles((0..=1000).map(f64::from), 1.0, 99.0).unwrap();
    assert!((s.lo - 10.0).abs() < 1e-9 && (s.hi - 990.0).abs() < 1e-9);
    assert_eq!(s.to_u8(500.0), 128);
    assert_eq!(s.to_u8(-5.0), 0);
    assert_eq!(s.to_u8(2000.0), 255);
    let flat = Stretch::from_percentiles(std::iter::repeat_n(7.0, 10), 1.0, 99.0).unwrap();
    assert_eq!(flat.to_u8(7.0), 0);
    let (edges, counts) = eoir::plot::histogram((0..100).map(f64::from), 0.0, 100.0, 10);
    assert_eq!(edges.len(), 11);
    assert_eq!(counts, vec![10; 10]);
    let (_, counts) = eoir::plot::histogram(
        [-1.0, 0.0, 100.0, 101.0, f64::NAN].into_iter(),
        0.0,
        100.0,
        4,
    );
    assert_eq!(counts, vec![1, 0, 0, 1]);
}

#[test]
fn sensors_show_keeps_provenance_notes_and_the_values() {
    for p in presets::list() {
        let out = eoir().args(["sensors", "show", &p.name]).output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = String::from_utf8(out.stdout).unwrap();
        let source = presets::preset_text(&p.name).unwrap();
        if source.contains("ASSUMED") {
            assert!(text.contains("ASSUMED"), "{}", p.name);
        }
        // Comments do not change the values: the output is the resolved sensor.
        let shown: toml::Value = toml::from_str(&text).unwrap();
        let resolved: toml::Value = toml::from_str(
            &presets::load(&p.name, &[], &[])
                .unwrap()
                .to_toml_string()
                .unwrap(),
        )
        .unwrap();
        assert_eq!(shown, resolved, "{}", p.name);
    }
    let out = eoir()
        .args(["sensors", "show", "multimir"])
        .output()
        .unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    // The note sits right above the value it explains.
    assert!(
        text.contains("# ASSUMED: typical MWIR HgCdTe read-out capacity\nfull_well_e = 15000000.0")
    );
}

#[test]
fn scene_mean_auto_gain_raises_no_full_well_warning() {
    let dir = tempfile::tempdir().unwrap();
    small_demo("threeband", dir.path());
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap())
            .unwrap();
    let warnings = report["warnings"].as_array().unwrap();
    assert!(
        warnings
            .iter()
            .all(|w| !w.as_str().unwrap().contains("beyond the full well")),
        "{warnings:?}"
    );
    assert!(report["detector"]["auto_gain_reference"]
        .as_str()
        .unwrap()
        .starts_with("SceneMean"));
}

#[test]
fn coarser_scene_warning_has_a_tolerance_and_enough_digits() {
    use eoir::imaging::Sampling;
    use eoir::scene::{CubeMeta, Geometry, RadianceUnits};
    let sensor = presets::load("multimir", &[], &[]).unwrap();
    let d = sensor.ifov_rad();
    let warnings = |ratio: f64| {
        let (rows, cols) = (320, 420);
        let g = Geometry::from_ifov(d / ratio, d / ratio, rows, cols);
        let meta = CubeMeta {
            wavelength_um: vec![4.5, 5.3],
            fwhm_um: None,
            units: RadianceUnits::SpectralPerUm,
            geometry: Some(g),
            rows,
            cols,
        };
        let built = eoir::sensor::Sensor::build(&sensor).unwrap();
        Sampling::new(&built, &meta, &g).unwrap().warnings
    };
    // A field of view rounded in the fifth digit is not a coarser scene.
    assert!(warnings(0.99997).is_empty(), "{:?}", warnings(0.99997));
    let w = warnings(0.9);
    assert_eq!(w.len(), 1);
    assert!(w[0].contains("0.90000 x 0.90000"), "{}", w[0]);
}

/// The factors the spectral-response plot draws are the preset's own curves (the values
/// written in `sensors/multimir.toml`, filter 4: a 0.85 top hat over 4.55–5.2 µm, optics
/// 0.9, QE 0.7 up to 5.0 µm falling to 0.35 at 5.2 µm) and multiply to the response the
/// run integrates.
#[test]
fn spectral_chain_holds_the_preset_curves_and_multiplies_to_the_response() {
    let config = eoir::sensor::presets::load("multimir", &[], &[]).unwrap();
    let sensor = eoir::sensor::Sensor::build(&config).unwrap();
    let chain = sensor.spectral_chain();
    assert!(chain.atmosphere.is_none());
    for (l, filter, qe) in [(4.8, 0.85, 0.7), (5.1, 0.85, 0.525), (4.4, 0.0, 0.7)] {
        assert!(
            (chain.filter.eval(l) - filter).abs() < 1e-12,
            "filter at {l}"
        );
        assert!((chain.optics.eval(l) - 0.9).abs() < 1e-12, "optics at {l}");
        assert!((chain.qe.eval(l) - qe).abs() < 1e-12, "QE at {l}");
        let product = filter * 0.9 * qe;
        assert!(
            (sensor.response().eval(l) - product).abs() < 1e-12,
            "response at {l}: {} vs {product}",
            sensor.response().eval(l)
        );
    }
}

/// Saturation above 1 % of the pixels is a warning that names the remedy (issue 38): with
/// MultimIR's auto gain, `detector.auto_gain.fraction` for pixels at the ADC maximum; with
/// the `ccd` preset's fixed gain, `detector.gain_dn_per_e`; at the full well, the
/// integration time. 0.5 % saturated is no warning; the counted share is the one built.
#[test]
fn saturation_is_a_warning_naming_the_remedy() {
    use eoir::report::saturation_warning;
    use ndarray::Array2;
    let build =
        |name: &str| eoir::sensor::Sensor::build(&presets::load(name, &[], &[]).unwrap()).unwrap();
    let (rows, cols) = (20, 50); // 1000 pixels
    for (name, remedy) in [
        ("multimir", "detector.auto_gain.fraction"),
        ("ccd", "detector.gain_dn_per_e"),
    ] {
        let s = build(name);
        let max_dn = s.detector.max_dn() as u16;
        let electrons = Array2::<f32>::from_elem((rows, cols), 1.0);
        let mut dn = Array2::<u16>::from_elem((rows, cols), 100);
        for i in 0..5 {
            dn[[0, i]] = max_dn;
        }
        assert!(
            saturation_warning(&s, &electrons, &dn).is_none(),
            "{name}: 0.5 %"
        );
        for i in 0..50 {
            dn[[1, i]] = max_dn;
        }
        let w = saturation_warning(&s, &electrons, &dn).expect("5.5 % saturated");
        assert!(
            w.starts_with("5.50 % of the pixels are saturated"),
            "{name}: {w}"
        );
        assert!(w.contains(remedy), "{name}: {w}");
        // At the full well instead: the integration time.
        let dn = Array2::<u16>::from_elem((rows, cols), 100);
        let mut e = electrons.clone();
        for i in 0..cols {
            e[[2, i]] = s.detector.full_well_e as f32 * 1.01;
        }
        let w = saturation_warning(&s, &e, &dn).expect("5 % at the full well");
        assert!(w.contains("detector.integration_time_s"), "{name}: {w}");
    }
}
