//! `RunOptions::first_frame`: a sequence run in pieces (as the Python package's Dask
//! scale-out does, one chunk of frames per task) equals one run of the whole sequence, bit
//! for bit, because temporal noise is keyed by the sequence frame index and the fixed
//! pattern by the seed alone.

use eoir::io::MemoryCube;
use eoir::pipeline::{self, RunOptions};
use eoir::scene::synthetic::{self, SceneParams};
use eoir::scene::Cube;
use eoir::sensor::presets;

/// A 5-frame sequence (the thermal scene scaled 0.9 … 1.1) for a 24 × 32 MultimIR.
fn sequence() -> (eoir::sensor::Sensor, Vec<Cube>) {
    let small = [
        "detector.rows=24".to_string(),
        "detector.cols=32".to_string(),
    ];
    let config = presets::load("multimir", &[], &small).unwrap();
    let sensor = eoir::sensor::Sensor::build(&config).unwrap();
    let (lo, hi) = sensor.response().support_um();
    let params = SceneParams {
        rows: 24,
        cols: 32,
        oversampling: 2,
        wavelength_um: SceneParams::uniform_grid(lo, hi, 20).unwrap(),
        fov_x_deg: (config.ifov_rad() * 32.0).to_degrees(),
        range_m: Some(1000.0),
        seed: 5,
        sun: true,
    };
    let base = synthetic::thermal(&params).unwrap();
    let frames = (0..5)
        .map(|i| {
            let k = 0.9 + 0.05 * i as f32;
            Cube::new(base.data.mapv(|v| v * k), base.meta.clone()).unwrap()
        })
        .collect();
    (sensor, frames)
}

fn run(
    sensor: &eoir::sensor::Sensor,
    frames: &[Cube],
    first_frame: u64,
) -> Vec<ndarray::Array2<u16>> {
    let mut reader = MemoryCube::sequence(frames.to_vec(), None).unwrap();
    let opts = RunOptions {
        seed: 17,
        calibration: None,
        first_frame,
        ..RunOptions::default()
    };
    pipeline::run(sensor, &mut reader, &opts, |_, _| {})
        .unwrap()
        .frames
        .into_iter()
        .map(|f| f.dn)
        .collect()
}

#[test]
fn sequence_in_pieces_equals_one_run() {
    let (sensor, frames) = sequence();
    let whole = run(&sensor, &frames, 0);
    // Pieces of 2 + 2 + 1 frames, and a single frame on its own, each told where it starts.
    let mut pieces = Vec::new();
    for start in [0usize, 2, 4] {
        let end = (start + 2).min(frames.len());
        pieces.extend(run(&sensor, &frames[start..end], start as u64));
    }
    assert_eq!(pieces, whole);
    assert_eq!(run(&sensor, &frames[3..4], 3), vec![whole[3].clone()]);
    // Without the offset a piece repeats the first frames' noise: the test can fail.
    assert_ne!(run(&sensor, &frames[3..4], 0), vec![whole[3].clone()]);
}
