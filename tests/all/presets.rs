//! Sensor presets and their options: every combination loads and validates, geometry and
//! fill factors agree with the FOI report's figures, option errors list what is valid, and
//! the overlay merge rules hold.

use eoir::cfa::{BLUE, GREEN, RED};
use eoir::sensor::presets::{self, PresetInfo};
use eoir::sensor::{Sensor, SensorConfig, SpectrumConfig};

fn opts(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}

fn load(name: &str, options: &[&str]) -> SensorConfig {
    presets::load(name, &opts(options), &[]).unwrap_or_else(|e| panic!("{name} {options:?}: {e}"))
}

fn info(name: &str) -> PresetInfo {
    presets::list()
        .into_iter()
        .find(|p| p.name == name)
        .unwrap_or_else(|| panic!("preset {name} not listed"))
}

/// Mean wavelength of the chain's response, by midpoint quadrature on a 0.5 nm grid.
fn centroid_um(s: &SensorConfig) -> f64 {
    let r = Sensor::build(s).unwrap().response().clone();
    let (lo, hi) = r.support_um();
    let hi = hi.min(20.0);
    let n = ((hi - lo) / 0.0005).ceil() as usize;
    let (mut w, mut wl) = (0.0, 0.0);
    for i in 0..n {
        let l = lo + (hi - lo) * (i as f64 + 0.5) / n as f64;
        let v = r.eval(l);
        w += v;
        wl += v * l;
    }
    assert!(w > 0.0, "{}: zero response", s.name);
    wl / w
}

#[test]
fn every_preset_and_option_combination_loads_and_validates() {
    let list = presets::list();
    let names: Vec<&str> = list.iter().map(|p| p.name.as_str()).collect();
    for n in [
        "multimir",
        "emerald",
        "qwip",
        "ccd",
        "ccd-bayer",
        "threeband",
    ] {
        assert!(names.contains(&n), "{n} missing from {names:?}");
    }
    let mut count = 0;
    for p in &list {
        assert!(!p.description.is_empty(), "{}", p.name);
        assert!(!p.description.starts_with("(invalid"), "{}", p.description);
        // Every option has a default, so the preset loads with no choices at all.
        for (o, values) in &p.options {
            assert!(p.defaults.iter().any(|(d, _)| d == o), "{}: {o}", p.name);
            assert!(!values.is_empty());
        }
        let plain = presets::load(&p.name, &[], &[]).unwrap();
        for combo in p.option_combinations() {
            let s = presets::load(&p.name, &combo, &[])
                .unwrap_or_else(|e| panic!("{} {combo:?}: {e}", p.name));
            Sensor::build(&s).unwrap();
            let (lo, hi) = Sensor::build(&s).unwrap().response().clone().support_um();
            assert!(hi > lo, "{} {combo:?}: empty band", p.name);
            // The choices are recorded.
            for c in &combo {
                let (k, v) = c.split_once('=').unwrap();
                assert_eq!(s.selected_options.get(k).map(String::as_str), Some(v));
            }
            // The resolved TOML reloads to the same description (what `sensors show`
            // prints and what is written next to every output).
            let text = presets::resolved_toml(&p.name, &combo).unwrap();
            let back =
                SensorConfig::from_toml_str(&text, "resolved", std::path::PathBuf::from("."), &[])
                    .unwrap();
            assert_eq!(back, s, "{} {combo:?}", p.name);
            count += 1;
        }
        // The defaults are one of the combinations.
        let defaults: Vec<String> = p.defaults.iter().map(|(k, v)| format!("{k}={v}")).collect();
        assert_eq!(presets::load(&p.name, &defaults, &[]).unwrap(), plain);
    }
    // 4 filters x 3 optics (15mm, 15mm-aberrated, 100mm) x 2 sequence clocks + 3 bands x 2
    // lenses + 1 + 3 channels + 1 + 3 channels x 2 shutters.
    assert_eq!(count, 24 + 6 + 1 + 3 + 1 + 6);
}

#[test]
fn multimir_fields_of_view_match_the_report() {
    // FOI report table 3.1: 35° x 26° with the 15 mm optics, 5.3° x 4.0° with 100 mm. The
    // report rounds: 2 atan(384 * 24 µm / 30 mm) = 34.1°, so allow 1° on the wide field.
    let wide = load("multimir", &["optics=15mm"]);
    let (h, v) = wide.fov_deg();
    assert!(
        (h - 35.0).abs() < 1.0 && (v - 26.0).abs() < 0.5,
        "{h} x {v}"
    );
    let narrow = load("multimir", &["optics=100mm"]);
    let (h, v) = narrow.fov_deg();
    assert!(
        (h - 5.3).abs() < 0.05 && (v - 4.0).abs() < 0.05,
        "{h} x {v}"
    );
    // The default is the report's §4.1 example: filter 4 and the 100 mm optics.
    let d = load("multimir", &[]);
    assert_eq!(d.fov_deg(), narrow.fov_deg());
    assert_eq!(d.selected_options.get("filter").unwrap(), "4");
    assert_eq!(d.optics.f_number, 2.0);
    assert_eq!(wide.optics.f_number, 2.0);
}

#[test]
fn emerald_field_of_view_matches_the_report() {
    // §3.3: 50 mm F/2, 17° x 14° (640 x 512 at 24 µm give 17.5° x 14.0°).
    for band in ["1", "2", "3"] {
        let s = load("emerald", &[&format!("band={band}")]);
        let (h, v) = s.fov_deg();
        assert!(
            (h - 17.0).abs() < 0.6 && (v - 14.0).abs() < 0.1,
            "{h} x {v}"
        );
        assert_eq!((s.detector.cols, s.detector.rows), (640, 512));
    }
}

#[test]
fn qwip_field_of_view_follows_pitch_and_focal_length_and_the_file_says_so() {
    let s = load("qwip", &[]);
    // 2 atan(320 * 38 µm / (2 * 40 mm)), computed here from the report's numbers.
    let expect_h = 2.0 * (320.0 * 38e-6 / 0.08f64).atan().to_degrees();
    let expect_v = 2.0 * (240.0 * 38e-6 / 0.08f64).atan().to_degrees();
    let (h, v) = s.fov_deg();
    assert!((h - expect_h).abs() < 1e-9 && (v - expect_v).abs() < 1e-9);
    assert!(
        (h - 17.3).abs() < 0.05 && (v - 13.0).abs() < 0.05,
        "{h} x {v}"
    );
    // The report's 20° x 15° disagrees with its own numbers; the preset documents it.
    let text = presets::preset_text("qwip").unwrap();
    assert!(text.contains("20 x 15") && text.contains("17.3 x 13.0"));
    // §3.4: F/1, ideal optics, fill factor ~62 %, response in the 8-9 µm region.
    assert_eq!(s.optics.f_number, 1.0);
    assert_eq!(
        s.optics.transmission,
        SpectrumConfig::Constant { value: 1.0 }
    );
    assert!((s.detector.fill_factor() - 0.62).abs() < 0.01);
    let c = centroid_um(&s);
    assert!((8.0..9.0).contains(&c), "{c}");
}

#[test]
fn fill_factors_match_the_report() {
    // Table 3.1: 69 %; §3.4: ~62 %; §3.5: ~72 %.
    for (name, ff) in [
        ("multimir", 0.69),
        ("emerald", 0.69),
        ("qwip", 0.62),
        ("ccd", 0.72),
        ("ccd-bayer", 0.72),
        ("threeband", 0.72),
    ] {
        let s = load(name, &[]);
        assert!(
            (s.detector.fill_factor() - ff).abs() < 0.01,
            "{name}: {}",
            s.detector.fill_factor()
        );
    }
}

#[test]
fn bands_lie_where_the_report_puts_them() {
    // MultimIR filters (table 3.1): the response centroid lies inside each filter's band.
    for (f, lo, hi) in [
        ("1", 1.55, 1.75),
        ("2", 2.05, 2.45),
        ("3", 3.45, 4.15),
        ("4", 4.55, 5.2),
    ] {
        let c = centroid_um(&load("multimir", &[&format!("filter={f}")]));
        assert!(c > lo && c < hi, "filter {f}: {c}");
    }
    // Emerald bands (§3.3): band 1 < 3.9 µm, band 2 ~3.3-5.1 µm, band 3 > 4.6 µm.
    let e: Vec<SensorConfig> = ["1", "2", "3"]
        .iter()
        .map(|b| load("emerald", &[&format!("band={b}")]))
        .collect();
    let support = |s: &SensorConfig| Sensor::build(s).unwrap().response().clone().support_um();
    assert!(support(&e[0]).1 < 3.95);
    assert!(support(&e[2]).0 > 4.55);
    let s2 = support(&e[1]);
    assert!(s2.0 > 3.2 && s2.1 < 5.2, "{s2:?}");
    // The Si sensors respond nowhere beyond the 1.1 µm cutoff (§3.5).
    for name in ["ccd", "ccd-bayer", "threeband"] {
        for combo in info(name).option_combinations() {
            let s = presets::load(name, &combo, &[]).unwrap();
            let r = Sensor::build(&s).unwrap().response().clone();
            assert_eq!(r.eval(1.1), 0.0);
            assert_eq!(r.eval(1.2), 0.0);
        }
    }
    // 3-CCD channels and three-band channels are ordered in wavelength.
    let ccd: Vec<f64> = ["green", "red", "nir"]
        .iter()
        .map(|c| centroid_um(&load("ccd", &[&format!("channel={c}")])))
        .collect();
    assert!(ccd[0] < ccd[1] && ccd[1] < ccd[2], "{ccd:?}");
    let three: Vec<f64> = ["1", "2", "3"]
        .iter()
        .map(|c| centroid_um(&load("threeband", &[&format!("channel={c}")])))
        .collect();
    assert!(three[0] < three[1] && three[1] < three[2], "{three:?}");
    assert!(three[0] > 0.45 && three[2] < 0.88, "{three:?}");
}

#[test]
fn threeband_matches_section_4_2() {
    let s = load("threeband", &[]);
    assert_eq!((s.detector.cols, s.detector.rows), (696, 520));
    assert_eq!(s.optics.focal_length_m, 0.028);
    assert_eq!(s.optics.f_number, 11.0);
    assert_eq!(s.detector.bits, 10);
    assert_eq!(info("threeband").channel_values().unwrap(), ["1", "2", "3"]);
    assert_eq!(info("ccd").channel_values().unwrap().len(), 3);
    assert!(info("multimir").channel_values().is_none());
}

#[test]
fn unknown_options_are_errors_that_list_the_valid_ones() {
    let err = |spec: &str, o: &[&str]| {
        let e = presets::load(spec, &opts(o), &[]).unwrap_err().to_string();
        assert!(!e.contains('\n'), "{e}");
        e
    };
    let e = err("multimir", &["filter=7"]);
    assert!(
        e.contains("filter") && e.contains('7') && e.contains("1, 2, 3, 4"),
        "{e}"
    );
    let e = err("multimir", &["lens=15mm"]);
    assert!(
        e.contains("lens") && e.contains("filter") && e.contains("optics") && e.contains("100mm"),
        "{e}"
    );
    let e = err("multimir", &["filter"]);
    assert!(e.contains("name=value"), "{e}");
    let e = err("multimir", &["filter=1", "filter=2"]);
    assert!(e.contains("one value per option"), "{e}");
    let e = err("qwip", &["band=1"]);
    assert!(e.contains("declares no options"), "{e}");
    let e = err("emerald", &["band=4"]);
    assert!(e.contains("1, 2, 3"), "{e}");
    // A repeated identical choice is harmless.
    load("multimir", &["filter=1", "filter=1"]);
}

#[test]
fn overrides_apply_after_options() {
    let s = presets::load(
        "multimir",
        &opts(&["optics=15mm", "filter=2"]),
        &opts(&["optics.f_number=4", "detector.integration_time_s=1e-3"]),
    )
    .unwrap();
    assert_eq!(s.optics.focal_length_m, 0.015);
    assert_eq!(s.optics.f_number, 4.0);
    assert_eq!(s.detector.integration_time_s, 1e-3);
    assert!(matches!(s.filter, SpectrumConfig::TopHat { lo_um, .. } if lo_um == 2.05));
    // An invalid override still names the field and the preset.
    let e = presets::load("emerald", &opts(&["band=1"]), &opts(&["optics.f_number=0"]))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("optics.f_number") && e.contains("emerald"),
        "{e}"
    );
}

const WITH_OPTIONS: &str = r#"
name = "custom"
[optics]
focal_length_m = 0.1
f_number = 2.0
[filter]
kind = "gaussian"
center_um = 4.0
fwhm_um = 0.5
[detector]
rows = 16
cols = 16
pitch_m = 20e-6
active_width_m = 18e-6
integration_time_s = 1e-3
quantum_efficiency = { kind = "constant", value = 0.7 }
[options.band.wide]
filter = { kind = "top_hat", lo_um = 3.0, hi_um = 5.0 }
[options.band.narrow]
filter = { center_um = 4.2 }
[options.speed.slow]
detector = { integration_time_s = 4e-3 }
[options.speed.fast]
detector = { integration_time_s = 5e-4 }
[defaults]
speed = "slow"
"#;

#[test]
fn sensor_files_may_declare_options_and_merge_rules_hold() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("custom.toml");
    std::fs::write(&path, WITH_OPTIONS).unwrap();
    let p = path.to_str().unwrap();
    // `band` has no default: it must be given, and the error says which values exist.
    let e = presets::load(p, &[], &[]).unwrap_err().to_string();
    assert!(
        e.contains("band") && e.contains("narrow, wide") && e.contains("no default"),
        "{e}"
    );
    // A `kind` table replaces the base spectrum whole (no stray `center_um`) ...
    let s = presets::load(p, &opts(&["band=wide"]), &[]).unwrap();
    assert_eq!(
        s.filter,
        SpectrumConfig::TopHat {
            lo_um: 3.0,
            hi_um: 5.0,
            edge_width_um: 0.0,
            peak: 1.0
        }
    );
    assert_eq!(s.detector.integration_time_s, 4e-3);
    // ... while a table without `kind` merges key by key, keeping the rest of the base.
    let s = presets::load(p, &opts(&["band=narrow", "speed=fast"]), &[]).unwrap();
    assert_eq!(
        s.filter,
        SpectrumConfig::Gaussian {
            center_um: 4.2,
            fwhm_um: 0.5,
            peak: 1.0
        }
    );
    assert_eq!(s.detector.integration_time_s, 5e-4);
    assert_eq!(s.detector.rows, 16);
    assert_eq!(s.selected_options.len(), 2);

    // Two options setting the same key are rejected, naming both.
    let clash = WITH_OPTIONS.replace(
        "[options.speed.slow]\n",
        "[options.speed.slow]\nfilter = { kind = \"constant\", value = 1.0 }\n",
    );
    let path2 = dir.path().join("clash.toml");
    std::fs::write(&path2, clash).unwrap();
    let e = presets::load(path2.to_str().unwrap(), &opts(&["band=wide"]), &[])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("band")
            && e.contains("speed")
            && e.contains("filter")
            && e.contains("clash.toml"),
        "{e}"
    );

    // A default naming a value that does not exist is an error in the file.
    let bad = WITH_OPTIONS.replace("speed = \"slow\"", "speed = \"warp\"");
    let path3 = dir.path().join("bad.toml");
    std::fs::write(&path3, bad).unwrap();
    let e = presets::load(path3.to_str().unwrap(), &opts(&["band=wide"]), &[])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("warp") && e.contains("fast, slow") && e.contains("bad.toml"),
        "{e}"
    );
}

#[test]
fn bayer_channels_are_the_chain_times_each_colour_filter() {
    let s = load("ccd-bayer", &[]);
    let cfa = s.cfa.clone().expect("ccd-bayer has a [cfa] section");
    assert_eq!(cfa.pattern, eoir::cfa::CfaPattern::Rggb);
    let built = Sensor::build(&s).unwrap();
    let base = built.response().clone();
    // The channels come from the build step only (one per colour, in RED, GREEN, BLUE order).
    assert_eq!(built.cfa_channels().len(), 3);
    let channel = |ch: usize| built.cfa_channels()[ch].config().clone();
    for (ch, dye) in [(RED, &cfa.red), (GREEN, &cfa.green), (BLUE, &cfa.blue)] {
        let c = channel(ch);
        assert!(c.cfa.is_none());
        let r = Sensor::build(&c).unwrap().response().clone();
        // The channel sensor's own response is the same curve.
        let own = built.cfa_channels()[ch].response();
        for i in 0..50 {
            let l = 0.4 + 0.006 * i as f64;
            assert!((own.eval(l) - r.eval(l)).abs() < 1e-15, "{ch} at {l}");
        }
        let d = dye.build(std::path::Path::new("."), "dye").unwrap();
        // Pointwise product, checked at wavelengths that are not table nodes.
        for i in 0..200 {
            let l = 0.353 + 0.0037 * i as f64;
            let expect = base.eval(l) * d.eval(l);
            assert!((r.eval(l) - expect).abs() < 1e-12, "{ch} at {l}");
        }
    }
    // Red, green, blue centroids in the right order.
    let c: Vec<f64> = [RED, GREEN, BLUE]
        .iter()
        .map(|&ch| centroid_um(&channel(ch)))
        .collect();
    assert!(c[0] > c[1] && c[1] > c[2], "{c:?}");
    // A sensor without [cfa] has no channels.
    assert!(Sensor::build(&load("ccd", &[]))
        .unwrap()
        .cfa_channels()
        .is_empty());

    // A non-constant base filter is tabulated: still the pointwise product, to the
    // interpolation error of a 1 nm grid.
    let mut s2 = s.clone();
    s2.filter = SpectrumConfig::TopHat {
        lo_um: 0.5,
        hi_um: 0.6,
        edge_width_um: 0.02,
        peak: 0.9,
    };
    let c = Sensor::build(&s2).unwrap().cfa_channels()[GREEN]
        .config()
        .clone();
    let f = s2.filter.build(std::path::Path::new("."), "f").unwrap();
    let d = cfa.green.build(std::path::Path::new("."), "g").unwrap();
    let q = s2
        .optics
        .transmission
        .build(std::path::Path::new("."), "t")
        .unwrap()
        .product(
            &s2.detector
                .quantum_efficiency
                .build(std::path::Path::new("."), "qe")
                .unwrap(),
        );
    let r = Sensor::build(&c).unwrap().response().clone();
    for i in 0..300 {
        let l = 0.47 + 0.00053 * i as f64;
        let expect = f.eval(l) * d.eval(l) * q.eval(l);
        assert!((r.eval(l) - expect).abs() < 1e-4, "at {l}");
    }
}

/// A folder named like a preset (an earlier run's `-o qwip`) does not hide the preset; a
/// folder given by any other spelling is still an error naming it.
#[test]
fn a_folder_named_like_a_preset_means_the_preset() {
    let dir = tempfile::tempdir().unwrap();
    let qwip = dir.path().join("qwip");
    std::fs::create_dir(&qwip).unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_eoir"))
        .args(["sensors", "show", "qwip"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("name = \"qwip\""));
    let e = presets::load(qwip.to_str().unwrap(), &[], &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("qwip"), "{e}");
}
