//! Readout-noise benchmark (issue 35: each focal-plane effect ≤ 10 ms per 640 × 512 frame):
//! times `eoir::detector::readout::readout_noise_e` with every component on (4 outputs,
//! uncorrelated and correlated pink, alternating-column noise, row offsets) and
//! `apply_output_crosstalk` with a full 4 × 4 matrix, on a 640 × 512 frame, and prints the
//! median and the fastest ms per frame over `EOIR_BENCH_REPEAT` frames (default 50) after
//! 3 warm-up frames (and the median CPU time of the noise, all threads), with the load (`/proc/loadavg`) before and after.
//!
//! `cargo run --release --example bench_readout`

use std::time::Instant;

use eoir::detector::readout::{apply_output_crosstalk, readout_noise_e, ReadoutNoiseConfig};

fn loadavg() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "?".into())
}

/// CPU time of the whole process (all threads), ms: less sensitive than the wall clock
/// to other jobs on a shared host.
fn cpu_ms() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec for the duration of the call.
    unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 * 1e3 + ts.tv_nsec as f64 * 1e-6
}

/// Median and minimum of `v`, ms.
fn stats(mut v: Vec<f64>) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    (v[v.len() / 2], v[0])
}

fn main() {
    let (rows, cols) = (512, 640);
    let repeat: usize = std::env::var("EOIR_BENCH_REPEAT")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(50);
    let cfg = ReadoutNoiseConfig {
        outputs: 4,
        pixel_time_s: 1e-7,
        row_overhead_px: 8,
        frame_overhead_rows: 2,
        alternate_read_direction: true,
        pink_sigma_e: Some(3.0),
        pink_density_e_per_sqrt_hz: None,
        correlated_pink_sigma_e: Some(2.0),
        correlated_pink_density_e_per_sqrt_hz: None,
        alternating_column_sigma_e: 1.0,
        row_sigma_e: 1.0,
        output_crosstalk: Some(vec![
            vec![0.0, 1e-3, 1e-3, 1e-3],
            vec![1e-3, 0.0, 1e-3, 1e-3],
            vec![1e-3, 1e-3, 0.0, 1e-3],
            vec![1e-3, 1e-3, 1e-3, 0.0],
        ]),
    };
    if let Err(e) = cfg.validate(rows, cols) {
        eprintln!("{e}");
        std::process::exit(1);
    }
    let load_before = loadavg();
    let mut noise_ms = Vec::new();
    let mut xt_ms = Vec::new();
    let mut noise_cpu_ms = Vec::new();
    let mut checksum = 0.0;
    for frame in 0..repeat as u64 + 3 {
        let t = Instant::now();
        let c = cpu_ms();
        let mut img = readout_noise_e(&cfg, rows, cols, 1, 0, frame);
        let t_noise = t.elapsed().as_secs_f64() * 1e3;
        let c_noise = cpu_ms() - c;
        let t = Instant::now();
        apply_output_crosstalk(&cfg, &mut img);
        let t_xt = t.elapsed().as_secs_f64() * 1e3;
        checksum += img[[0, 0]];
        if frame >= 3 {
            noise_ms.push(t_noise);
            noise_cpu_ms.push(c_noise);
            xt_ms.push(t_xt);
        }
    }
    let (nm, nmin) = stats(noise_ms);
    let (xm, xmin) = stats(xt_ms);
    let (cm, _) = stats(noise_cpu_ms);
    println!(
        "readout_noise_e 640x512, 4 outputs, all components: median {nm:.2} ms/frame (min {nmin:.2}), CPU {cm:.2} ms/frame (all threads)"
    );
    println!("apply_output_crosstalk 640x512, 4x4 matrix: median {xm:.2} ms/frame (min {xmin:.2})");
    println!(
        "threads {}, frames {repeat}, load before {load_before}, after {} (checksum {checksum:.3})",
        rayon::current_num_threads(),
        loadavg()
    );
}
