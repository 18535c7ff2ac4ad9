//! Every preset and option combination runs a (reduced) demo scene end to end, and the
//! MultimIR example lands a 300 K blackbody at half of its 14-bit range.

use eoir::io::MemoryCube;
use eoir::pipeline::{self, RunOptions};
use eoir::scene::synthetic::{self, SceneParams};
use eoir::sensor::{presets, Sensor};

/// A scene covering the sensor's band and field of view at 2× oversampling.
fn scene_for(sensor: &Sensor, kind: &str) -> eoir::scene::Cube {
    let (lo, hi) = sensor.response().support_um();
    let params = SceneParams {
        rows: sensor.detector.rows,
        cols: sensor.detector.cols,
        oversampling: 2,
        wavelength_um: SceneParams::uniform_grid(lo, hi, 30).unwrap(),
        fov_x_deg: (sensor.ifov_rad() * sensor.detector.cols as f64).to_degrees(),
        range_m: Some(1000.0),
        seed: 3,
        sun: true,
    };
    match kind {
        "blackbody" => synthetic::blackbody(&params, 300.0, 1.0).unwrap(),
        _ => synthetic::thermal(&params).unwrap(),
    }
}

#[test]
fn every_preset_and_option_runs_the_demo_scene() {
    let small = [
        "detector.rows=24".to_string(),
        "detector.cols=32".to_string(),
    ];
    let mut runs = 0;
    for info in presets::list() {
        // The aberrated lenses (imaged through the pupil, much slower): once each, below.
        for combo in info.option_combinations() {
            if combo.iter().any(|o| o.contains("aberrated")) {
                continue;
            }
            let sensor = presets::load(&info.name, &combo, &small)
                .and_then(|c| Sensor::build(&c))
                .unwrap_or_else(|e| panic!("{} {combo:?}: {e}", info.name));
            let cube = scene_for(&sensor, "thermal");
            let mut reader = MemoryCube::new(cube);
            let out = pipeline::run(&sensor, &mut reader, &RunOptions::default(), |_, _| {})
                .unwrap_or_else(|e| panic!("{} {combo:?}: {e}", info.name));
            let dn = &out.frames[0].dn;
            assert_eq!(dn.dim(), (24, 32));
            let max = sensor.detector.max_dn();
            assert!(dn.iter().all(|v| (*v as f64) <= max));
            let mean_e = out.report.signal.mean_electrons;
            assert!(mean_e > 0.0, "{} {combo:?}: no signal", info.name);
            runs += 1;
        }
    }
    assert!(runs >= 15, "{runs} runs");
}

/// The presets' aberrated lenses (MultimIR `optics=15mm-aberrated`, Emerald
/// `lens=aberrated`) image the demo scene through the pupil: a signal, DN within range,
/// and the space-variant zones stated in the report.
#[test]
fn aberrated_lenses_run_the_demo_scene() {
    let small = [
        "detector.rows=24".to_string(),
        "detector.cols=32".to_string(),
    ];
    for (name, option) in [
        ("multimir", "optics=15mm-aberrated"),
        ("emerald", "lens=aberrated"),
    ] {
        let sensor = presets::load(name, &[option.to_string()], &small)
            .and_then(|c| Sensor::build(&c))
            .unwrap_or_else(|e| panic!("{name} {option}: {e}"));
        assert!(sensor.optics.wavefront.is_some(), "{name} {option}");
        let cube = scene_for(&sensor, "thermal");
        let mut reader = MemoryCube::new(cube);
        let out = pipeline::run(&sensor, &mut reader, &RunOptions::default(), |_, _| {})
            .unwrap_or_else(|e| panic!("{name} {option}: {e}"));
        let dn = &out.frames[0].dn;
        assert_eq!(dn.dim(), (24, 32));
        assert!(dn.iter().all(|v| (*v as f64) <= sensor.detector.max_dn()));
        assert!(
            out.report.signal.mean_electrons > 0.0,
            "{name} {option}: no signal"
        );
        assert!(
            out.report.wavefront_imaging.is_some(),
            "{name} {option}: no wavefront imaging in the report"
        );
    }
}

/// FOI report §4.1: gain set so that a 300 K blackbody is at the middle of the 14-bit range.
/// Measured on the output of the whole chain (noise, dead pixels and all), ±1 %.
#[test]
fn multimir_300k_blackbody_lands_at_half_range() {
    let sensor = presets::load(
        "multimir",
        &["filter=4".into(), "optics=100mm".into()],
        &["detector.rows=48".into(), "detector.cols=64".into()],
    )
    .and_then(|c| Sensor::build(&c))
    .unwrap();
    let cube = scene_for(&sensor, "blackbody");
    let mut reader = MemoryCube::new(cube);
    let out = pipeline::run(&sensor, &mut reader, &RunOptions::default(), |_, _| {}).unwrap();
    // Median: robust to the 0.5 % dead pixels of the preset.
    let mut v: Vec<u16> = out.frames[0].dn.iter().copied().collect();
    v.sort_unstable();
    let median = v[v.len() / 2] as f64;
    let half = (2f64.powi(14) - 1.0) / 2.0;
    assert!(
        (median / half - 1.0).abs() < 0.01,
        "median DN {median} vs {half}"
    );
}

/// The three-band composite puts near-IR-bright vegetation in red: over pixels that are
/// mostly vegetation, red is the strongest channel; over vegetation-free terrain it is not
/// more dominant than there.
#[test]
fn threeband_composite_puts_vegetation_in_red() {
    let small = [
        "detector.rows=48".to_string(),
        "detector.cols=64".to_string(),
    ];
    let base = presets::load("threeband", &["channel=1".into()], &small).unwrap();
    let (rows, cols, k) = (48usize, 64usize, 2usize);
    let params = SceneParams {
        rows,
        cols,
        oversampling: k,
        wavelength_um: SceneParams::uniform_grid(0.38, 0.98, 61).unwrap(),
        fov_x_deg: (base.ifov_rad() * cols as f64).to_degrees(),
        range_m: Some(1000.0),
        seed: 3,
        sun: true,
    };
    let scene = synthetic::thermal_scene(&params, &synthetic::Environment::default()).unwrap();
    let mut outs = Vec::new();
    for ch in ["1", "2", "3"] {
        let s =
            Sensor::build(&presets::load("threeband", &[format!("channel={ch}")], &small).unwrap())
                .unwrap();
        let mut reader = MemoryCube::new(scene.cube.clone());
        let out = pipeline::run(&s, &mut reader, &RunOptions::default(), |_, _| {}).unwrap();
        outs.push((eoir::report::mean_wavelength_um(&s).unwrap(), out));
    }
    let refs: Vec<(f64, &pipeline::RunOutput)> = outs.iter().map(|(l, o)| (*l, o)).collect();
    let rgb = pipeline::false_colour_composite(&refs).unwrap();
    // Vegetation fraction of each detector pixel: mean over its k × k scene block.
    let veg = |r: usize, c: usize| {
        let mut sum = 0.0;
        for i in 0..k {
            for j in 0..k {
                sum += scene.vegetation_fraction[[r * k + i, c * k + j]] as f64;
            }
        }
        sum / (k * k) as f64
    };
    let (mut n, mut red_lead) = (0usize, 0.0f64);
    for r in 2..rows - 2 {
        for c in 2..cols - 2 {
            if veg(r, c) > 0.9 {
                let p = rgb.slice(ndarray::s![r, c, ..]);
                red_lead += p[0] as f64 - (p[1] as f64).max(p[2] as f64);
                n += 1;
            }
        }
    }
    assert!(n > 20, "only {n} vegetation pixels");
    assert!(
        red_lead / n as f64 > 20.0,
        "red leads by {} on vegetation",
        red_lead / n as f64
    );
}

/// Bayer camera through the whole chain: a grey surface in sunlight (radiance shaped like
/// the 5772 K solar spectrum) comes out grey in `rgb`, channel means within 1 %.
#[test]
fn bayer_grey_scene_comes_out_grey() {
    let small = [
        "detector.rows=48".to_string(),
        "detector.cols=64".to_string(),
    ];
    let s = Sensor::build(&presets::load("ccd-bayer", &[], &small).unwrap()).unwrap();
    let params = SceneParams {
        rows: 48,
        cols: 64,
        oversampling: 2,
        wavelength_um: SceneParams::uniform_grid(0.35, 1.15, 81).unwrap(),
        fov_x_deg: (s.ifov_rad() * 64.0).to_degrees(),
        range_m: None,
        seed: 1,
        sun: false,
    };
    let mut cube = synthetic::blackbody(&params, 5772.0, 1.0).unwrap();
    // A 20 % grey Lambertian surface under the sun: ρ E_sun/π with E_sun = B·Ω_sun.
    cube.data
        .mapv_inplace(|v| v * (0.2 * 6.794e-5 / std::f32::consts::PI));
    let mut reader = MemoryCube::new(cube);
    let out = pipeline::run(&s, &mut reader, &RunOptions::default(), |_, _| {}).unwrap();
    let rgb = out.frames[0]
        .rgb
        .as_ref()
        .expect("a Bayer sensor writes rgb");
    let mean = |c: usize| {
        let v = rgb.slice(ndarray::s![4..44, 4..60, c]);
        v.iter().map(|x| *x as f64).sum::<f64>() / v.len() as f64
    };
    let (r, g, b) = (mean(0), mean(1), mean(2));
    assert!(g > 20.0, "too dark: {g}");
    assert!(
        (r / g - 1.0).abs() < 0.01 && (b / g - 1.0).abs() < 0.01,
        "r {r} g {g} b {b}"
    );
}

/// FOI report §4.2: the three-band camera's gain puts the scene mean of the NIR band at half
/// of the 10-bit range (measured on the output DN, ±1 %).
#[test]
fn threeband_nir_scene_mean_sits_at_half_range() {
    let small = [
        "detector.rows=48".to_string(),
        "detector.cols=64".to_string(),
    ];
    let s =
        Sensor::build(&presets::load("threeband", &["channel=3".into()], &small).unwrap()).unwrap();
    let params = SceneParams {
        rows: 48,
        cols: 64,
        oversampling: 2,
        wavelength_um: SceneParams::uniform_grid(0.38, 0.98, 61).unwrap(),
        fov_x_deg: (s.ifov_rad() * 64.0).to_degrees(),
        range_m: Some(1000.0),
        seed: 4,
        sun: true,
    };
    let cube = synthetic::thermal(&params).unwrap();
    let mut reader = MemoryCube::new(cube);
    let out = pipeline::run(&s, &mut reader, &RunOptions::default(), |_, _| {}).unwrap();
    let dn = &out.frames[0].dn;
    let mean = dn.iter().map(|v| *v as f64).sum::<f64>() / dn.len() as f64;
    let half = (2f64.powi(10) - 1.0) / 2.0;
    assert!((mean / half - 1.0).abs() < 0.01, "mean DN {mean} vs {half}");
}
