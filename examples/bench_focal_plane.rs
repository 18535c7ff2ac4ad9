//! Focal-plane memory benchmark (issue 35): the detector seconds per 640 × 512 frame that
//! each effect of docs/focal-plane.md adds to a MultimIR run (its detector set to
//! 640 × 512) on a clock (50 Hz, a still camera on a static 300 K scene), measured through
//! `eoir::pipeline::run` (the report's `timings_s.detector`, which covers the memory's step
//! and the exposure).
//!
//! Each configuration runs `F` frames (default 60: 1.2 s, so the drift draws a new step of
//! its 1 s walk grid once), `EOIR_BENCH_REPEAT` times (default 5)
//! back to back with the baseline; the figure is the median over the repeats of
//! (detector s per frame − the baseline's in the same repeat), so a noisy shared host
//! shifts both alike. Products are not written.
//!
//! `cargo run --release --example bench_focal_plane -- [FRAMES]`

use eoir::detector::drift::DriftConfig;
use eoir::detector::ipc::IpcConfig;
use eoir::detector::persistence::PersistenceConfig;
use eoir::detector::readout::ReadoutNoiseConfig;
use eoir::detector::rts::RtsConfig;
use eoir::io::MemoryCube;
use eoir::pipeline::{self, RunOptions};
use eoir::scene::synthetic::{self, SceneParams};
use eoir::sensor::{presets, Sensor, SensorConfig};

fn readout(all: bool) -> ReadoutNoiseConfig {
    let toml = if all {
        "outputs = 4\npixel_time_s = 1e-7\nrow_overhead_px = 8\nframe_overhead_rows = 1\n\
         pink_sigma_e = 5.0\ncorrelated_pink_sigma_e = 3.0\nalternating_column_sigma_e = 2.0\n\
         row_sigma_e = 1.0\noutput_crosstalk = [[0, 1e-3, 0, 0], [1e-3, 0, 1e-3, 0], [0, 1e-3, 0, 1e-3], [0, 0, 1e-3, 0]]\n"
    } else {
        "outputs = 4\npixel_time_s = 1e-7\npink_sigma_e = 5.0\n"
    };
    toml::from_str(toml).expect("readout config")
}

/// One way to switch an effect on.
type Edit = Box<dyn Fn(&mut SensorConfig)>;

fn configs() -> Vec<(&'static str, Edit)> {
    vec![
        (
            "readout noise (pink per output)",
            Box::new(|c| c.detector.readout_noise = Some(readout(false))),
        ),
        (
            "readout noise (all components + crosstalk)",
            Box::new(|c| c.detector.readout_noise = Some(readout(true))),
        ),
        (
            "IPC",
            Box::new(|c| {
                c.detector.ipc = Some(IpcConfig {
                    coupling: 0.01,
                    diagonal: 0.001,
                    anisotropy: 0.0,
                })
            }),
        ),
        (
            "RTS (1 % of pixels)",
            Box::new(|c| {
                c.detector.rts = Some(RtsConfig {
                    fraction: 0.01,
                    tau_high_s: 0.05,
                    tau_low_s: 0.5,
                    dark_step_e_per_s: 1e6,
                    offset_step_e: 50.0,
                })
            }),
        ),
        (
            "persistence (5 species)",
            Box::new(|c| c.detector.persistence = Some(PersistenceConfig::default())),
        ),
        (
            "drift (offset and gain walks, 1 s grid)",
            Box::new(|c| {
                c.detector.drift = Some(DriftConfig {
                    offset_walk_e_per_sqrt_s: 100.0,
                    gain_walk_per_sqrt_s: 1e-4,
                    ..Default::default()
                })
            }),
        ),
    ]
}

fn sensor(edit: &dyn Fn(&mut SensorConfig)) -> Sensor {
    let mut c = presets::load(
        "multimir",
        &[],
        &[
            "clock.frame_rate_hz=50".to_string(),
            "motion.enabled=false".to_string(),
            "detector.rows=512".to_string(),
            "detector.cols=640".to_string(),
        ],
    )
    .expect("multimir");
    edit(&mut c);
    Sensor::build(&c).expect("sensor")
}

fn main() {
    let frames: usize = std::env::args()
        .nth(1)
        .map(|a| a.parse().expect("FRAMES"))
        .unwrap_or(60);
    let repeat: usize = std::env::var("EOIR_BENCH_REPEAT")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(5);
    let base = sensor(&|_| {});
    let d = &base.config().detector;
    let (lo, hi) = base.response().support_um();
    let scene = synthetic::blackbody(
        &SceneParams {
            rows: d.rows,
            cols: d.cols,
            oversampling: 1,
            wavelength_um: SceneParams::uniform_grid(lo, hi, 8).unwrap(),
            fov_x_deg: (base.ifov_rad() * d.cols as f64).to_degrees(),
            range_m: Some(1000.0),
            seed: 3,
            sun: false,
        },
        300.0,
        1.0,
    )
    .unwrap();
    let per_frame = |s: &Sensor| -> f64 {
        let mut reader = MemoryCube::new(scene.clone());
        let o = RunOptions {
            frames,
            calibration: None,
            ..RunOptions::default()
        };
        let out = pipeline::run(s, &mut reader, &o, |_, _| {}).expect("run");
        out.report.timings_s.detector / frames as f64
    };
    let mut all = vec![("baseline (no effect)", base.clone())];
    for (name, edit) in configs() {
        all.push((name, sensor(edit.as_ref())));
    }
    let mut added: Vec<Vec<f64>> = vec![Vec::new(); all.len()];
    let mut baseline = Vec::new();
    for _ in 0..repeat {
        let b = per_frame(&all[0].1);
        baseline.push(b);
        for (i, (_, s)) in all.iter().enumerate().skip(1) {
            added[i].push(per_frame(s) - b);
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    println!(
        "{} x {}, {frames} frames, {repeat} repeats: baseline detector {:.2} ms per frame",
        d.cols,
        d.rows,
        median(&mut baseline) * 1e3
    );
    for (i, (name, _)) in all.iter().enumerate().skip(1) {
        println!(
            "| {name} | {:+.2} ms per frame |",
            median(&mut added[i]) * 1e3
        );
    }
}
