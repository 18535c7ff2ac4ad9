//! Per-frame cost of inter-pixel capacitance (`detector::ipc::apply_ipc`) and of the
//! fixed-pattern drift (`detector::drift::Drift::at`) on a 640 × 512 frame (issue 35 asks
//! for ≤ 10 ms each).
//!
//! `cargo run --release --example bench_ipc` prints the median (and for the drift the mean
//! and the slowest) milliseconds per frame. IPC: `EOIR_BENCH_REPEAT` applications (default 30) of
//! a c = 0.02, d = 0.002, a = 0.003 kernel to a random frame. Drift: a 30 Hz sequence of
//! `EOIR_BENCH_REPEAT × 3` frames with every drift term on and a 1 s walk grid, so one
//! frame in 30 also draws a new walk step (that frame is the slowest).

use std::time::Instant;

use ndarray::Array2;

use eoir::detector::drift::{Drift, DriftConfig};
use eoir::detector::ipc::{apply_ipc, ipc_kernel, IpcConfig};

const ROWS: usize = 512;
const COLS: usize = 640;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn main() {
    let repeat: usize = std::env::var("EOIR_BENCH_REPEAT")
        .ok()
        .and_then(|s| s.parse().ok())
        .filter(|&n| n > 0)
        .unwrap_or(30);
    let threads = rayon::current_num_threads();

    let kernel = ipc_kernel(&IpcConfig {
        coupling: 0.02,
        diagonal: 0.002,
        anisotropy: 0.003,
    });
    let charge = Array2::from_shape_fn((ROWS, COLS), |(r, c)| {
        ((31 * r + 17 * c) % 101) as f64 * 100.0
    });
    let mut checksum = 0.0;
    let mut ipc_ms = Vec::with_capacity(repeat);
    for _ in 0..repeat {
        let t0 = Instant::now();
        let out = apply_ipc(&kernel, &charge);
        ipc_ms.push(t0.elapsed().as_secs_f64() * 1e3);
        checksum += out[[ROWS / 2, COLS / 2]];
    }

    let cfg = DriftConfig {
        offset_walk_e_per_sqrt_s: 2.0,
        gain_walk_per_sqrt_s: 1e-4,
        offset_sigma_e_per_k: 30.0,
        gain_sigma_per_k: 2e-3,
        fpa_temperature_k: vec![[0.0, 80.0], [600.0, 81.0]],
        walk_step_s: 1.0,
    };
    let t0 = Instant::now();
    let mut drift = Drift::new(&cfg, ROWS, COLS, 1);
    let new_ms = t0.elapsed().as_secs_f64() * 1e3;
    let mut drift_ms = Vec::with_capacity(3 * repeat);
    for k in 1..=3 * repeat {
        let t0 = Instant::now();
        let d = drift.at(k as f64 / 30.0);
        drift_ms.push(t0.elapsed().as_secs_f64() * 1e3);
        checksum += d.offset_e[[0, 0]];
    }
    let drift_max = drift_ms.iter().cloned().fold(0.0, f64::max);
    let drift_mean = drift_ms.iter().sum::<f64>() / drift_ms.len() as f64;

    println!("640 x 512 frame, {threads} rayon threads");
    println!(
        "ipc   apply_ipc      median {:.2} ms/frame ({repeat} runs)",
        median(ipc_ms)
    );
    println!("drift Drift::new     {new_ms:.2} ms (once per sensor)");
    println!(
        "drift Drift::at 30 Hz median {:.2} ms/frame, mean {:.2}, slowest {:.2} ms ({} frames)",
        median(drift_ms),
        drift_mean,
        drift_max,
        3 * repeat
    );
    println!("(checksum {checksum:.3})");
}
