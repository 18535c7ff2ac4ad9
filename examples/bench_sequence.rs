//! Moving-camera sequence benchmark (issue 34): a static `N² × B` SWIR texture scene
//! (every transfer-function component but the `[motion]` smear on,
//! benches/swir_all_components.toml, detector k = 3 × coarser, 40 px inside the scene)
//! run in process through `eoir::pipeline::run` as
//! - one frame of a still camera,
//! - `F` frames of a camera that drifts and wanders (global shutter),
//! - `F` frames of the same motion with a rolling shutter,
//!
//! alternating the three back to back `EOIR_BENCH_REPEAT` times (default 5), and prints
//! one BENCHMARKS.md row: median seconds of each, the sequence/single ratio (median of the
//! back-to-back ratios), the cost of each frame after the first as a fraction of the
//! single-frame run, the rolling/global ratio per frame, and the peak RSS growth.
//! Products are not written (the engine, detector and report only).
//!
//! `cargo run --release --example bench_sequence -- [SIZE:BANDS:FRAMES]` (default
//! `1024:64:64`).

mod bench_common;
use bench_common::{median, swir_meta, swir_sensor_config_with};
use std::time::Instant;

use ndarray::Array3;

use eoir::io::MemoryCube;
use eoir::pipeline::{self, RunOptions};
use eoir::scene::Cube;
use eoir::sensor::Sensor;

const SCENE_IFOV_RAD: f64 = 50e-6;
const K: usize = 3;

fn texture(n: usize, bands: usize) -> Cube {
    let data = Array3::from_shape_fn((bands, n, n), |(b, r, c)| {
        let (r, c, b) = (r as f32, c as f32, b as f32);
        10.0 + 3.0 * (0.071 * r + 0.013 * c + 0.1 * b).cos()
            + 2.0 * (0.31 * c - 0.05 * r).cos() * (0.02 * b).sin()
            + ((r * 0.77 + c * 1.31).sin() * 43_758.547).fract()
    });
    let wl: Vec<f64> = (0..bands)
        .map(|i| 0.95 + 0.8 * i as f64 / (bands - 1) as f64)
        .collect();
    Cube::new(data, swir_meta(n, wl)).expect("a valid cube")
}

fn sensor(det: usize, extra: &[String]) -> Sensor {
    let mut config = swir_sensor_config_with(det, extra).expect("the bench sensor");
    // The bench sensor's [motion] smear is kept out of every case: over a clocked sequence
    // it would drift the image by 4 px per frame, beyond the scene.
    config.motion = None;
    Sensor::build(&config).expect("builds")
}

fn peak_rss_kib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("VmHWM:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        })
        .unwrap_or(f64::NAN)
}

fn main() {
    let arg = std::env::args().nth(1).unwrap_or("1024:64:64".into());
    let p: Vec<usize> = arg
        .split(':')
        .map(|v| v.parse().expect("SIZE:BANDS:FRAMES"))
        .collect();
    let (n, bands, frames) = (p[0], p[1], p[2]);
    let repeat: usize = std::env::var("EOIR_BENCH_REPEAT")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(5);
    let det = n / K;
    let ifov = SCENE_IFOV_RAD * K as f64;
    // Drift of 0.25 px per frame at 100 frames/s plus 0.3 px rms wander (1–20 Hz): the
    // whole sequence stays within 40 px of the start, inside the scene's margin.
    let psd = 0.09 * ifov * ifov / 19.0;
    let moving = vec![
        "clock.frame_rate_hz=100".to_string(),
        format!("trajectory.pan_rate_rad_s=[{}, 0.0]", 0.25 * ifov * 100.0),
        format!("trajectory.wander={{kind = \"table\", frequency_hz = [1.0, 20.0], psd_rad2_per_hz = [{psd}, {psd}]}}"),
    ];
    let mut rolling = moving.clone();
    rolling.push("clock.shutter=\"rolling\"".into());
    rolling.push(format!("clock.line_time_s={}", 2e-3 / det as f64));
    // The detector 40 px inside the scene on each side: the pan (16 px over 64 frames)
    // and the wander stay inside.
    let det_in = det - 2 * 40;
    let still_s = sensor(det_in, &[]);
    let moving_s = sensor(det_in, &moving);
    let rolling_s = sensor(det_in, &rolling);
    let cube = texture(n, bands);
    let opts = |frames| RunOptions {
        frames,
        calibration: None,
        ..RunOptions::default()
    };
    let time = |s: &Sensor, frames: usize| {
        let mut r = MemoryCube::new(cube.clone());
        let t = Instant::now();
        let out = pipeline::run(s, &mut r, &opts(frames), |_, _| {}).expect("runs");
        assert_eq!(out.frames.len(), frames);
        t.elapsed().as_secs_f64()
    };
    time(&still_s, 1); // warm up
    let rss0 = peak_rss_kib();
    let (mut one, mut seq, mut roll) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..repeat {
        one.push(time(&still_s, 1));
        seq.push(time(&moving_s, frames));
        roll.push(time(&rolling_s, frames));
    }
    let ratio = median(seq.iter().zip(&one).map(|(a, b)| a / b).collect());
    let per_frame = median(
        seq.iter()
            .zip(&one)
            .map(|(a, b)| (a - b) / (frames as f64 - 1.0) / b)
            .collect(),
    );
    let roll_per_frame = median(
        roll.iter()
            .zip(&seq)
            .zip(&one)
            .map(|((r, s), o)| (r - o) / (s - o))
            .collect(),
    );
    println!("| scene | detector | frames | single (s) | sequence (s) | rolling (s) | sequence / single | each later frame / single | rolling / global (per frame) | peak RSS growth (MiB) |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    println!(
        "| {n}² × {bands} | {det_in}² | {frames} | {:.3} | {:.3} | {:.3} | {ratio:.2} | {:.1} % | {roll_per_frame:.2} | {:.0} |",
        median(one.clone()),
        median(seq.clone()),
        median(roll.clone()),
        100.0 * per_frame,
        (peak_rss_kib() - rss0) / 1024.0
    );
}
