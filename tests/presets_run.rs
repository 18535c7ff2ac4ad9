//! Every preset and option combination runs a (reduced) demo scene end to end, and the
//! MultimIR example lands a 300 K blackbody at half of its 14-bit range.

use eoir::io::MemoryCube;
use eoir::pipeline::{self, RunOptions};
use eoir::scene::synthetic::{self, SceneParams};
use eoir::sensor::{presets, SensorConfig};

/// A scene covering the sensor's band and field of view at 2× oversampling.
fn scene_for(sensor: &SensorConfig, kind: &str) -> eoir::scene::Cube {
    let (lo, hi) = sensor.spectral_response().unwrap().support_um();
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
        for combo in info.option_combinations() {
            let sensor = presets::load(&info.name, &combo, &small)
                .unwrap_or_else(|e| panic!("{} {combo:?}: {e}", info.name));
            let cube = scene_for(&sensor, "thermal");
            let mut reader = MemoryCube::new(cube);
            let out = pipeline::run(&sensor, &mut reader, &RunOptions::default(), |_, _| {})
                .unwrap_or_else(|e| panic!("{} {combo:?}: {e}", info.name));
            let dn = &out.frames[0].dn;
            assert_eq!(dn.dim(), (24, 32));
            let max = sensor.detector.max_dn();
            assert!(dn.iter().all(|v| (*v as f64) <= max));
            let mean_e = out.report["signal"]["mean_electrons"].as_f64().unwrap();
            assert!(mean_e > 0.0, "{} {combo:?}: no signal", info.name);
            runs += 1;
        }
    }
    assert!(runs >= 15, "{runs} runs");
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
