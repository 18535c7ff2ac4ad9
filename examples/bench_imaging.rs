//! Scaling of the imaging engine with threads and precision, in memory (no file I/O).
//!
//! `cargo run --release --example bench_imaging -- [SIZE:BANDS ...]` (default `1024:32`).
//! For each case, precision (f32, f64) and rayon pool size (1, 2, … up to the number of
//! cores), prints the median wall time of `Imager::mean_electrons` over 3 runs, the CPU
//! time of the process during those runs (getrusage), the speed-up over one thread and the
//! parallel efficiency (speed-up / threads). On a shared machine the CPU time is the more
//! stable figure; figures go into BENCHMARKS.md.

mod bench_common;
use bench_common::{swir_meta, swir_sensor_config};
use std::time::Instant;

use ndarray::Array3;

use eoir::imaging::fft::FftPrecision;
use eoir::imaging::{Imager, DEFAULT_WRAP_TOLERANCE};
use eoir::io::MemoryCube;
use eoir::scene::Cube;
use eoir::sensor::Sensor;

/// CPU seconds (user + system) of this process so far.
fn cpu_s() -> f64 {
    // SAFETY: getrusage writes into the zeroed struct we pass; no other effect.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) };
    let t = |v: libc::timeval| v.tv_sec as f64 + v.tv_usec as f64 * 1e-6;
    t(u.ru_utime) + t(u.ru_stime)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let cases: Vec<String> = std::env::args().skip(1).collect();
    let cases = if cases.is_empty() {
        vec!["1024:32".to_string()]
    } else {
        cases
    };
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!("| scene × bands | precision | threads | wall (s, median of 3) | CPU (s per run) | speed-up vs 1 thread | efficiency |");
    println!("|---|---|---|---|---|---|---|");
    for c in cases {
        let (n, bands) = c.split_once(':').ok_or("cases are SIZE:BANDS")?;
        let (n, bands): (usize, usize) = (n.parse()?, bands.parse()?);
        let sensor = Sensor::build(&swir_sensor_config(n / 3)?)?;
        let wl: Vec<f64> = (0..bands)
            .map(|i| 0.95 + 0.8 * i as f64 / (bands - 1) as f64)
            .collect();
        let data = Array3::from_shape_fn((bands, n, n), |(b, r, c)| {
            let (r, c, b) = (r as f32, c as f32, b as f32);
            10.0 + 3.0 * (0.071 * r + 0.013 * c + 0.1 * b).cos()
                + ((r * 0.77 + c * 1.31).sin() * 43_758.547).fract()
        });
        let meta = swir_meta(n, wl);
        let cube = Cube::new(data, meta.clone())?;
        for precision in [FftPrecision::F32, FftPrecision::F64] {
            let mut one = f64::NAN;
            let mut threads = 1;
            while threads <= cores {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()?;
                let (mut walls, c0) = (Vec::new(), cpu_s());
                for _ in 0..3 {
                    let r: eoir::Result<f64> = pool.install(|| {
                        let im = Imager::new(
                            &sensor,
                            &meta,
                            &meta.geometry.unwrap(),
                            DEFAULT_WRAP_TOLERANCE,
                        )?
                        .with_precision(precision);
                        let mut reader = MemoryCube::new(cube.clone());
                        let t = Instant::now();
                        im.mean_electrons(&mut reader, 0, |_, _| {})?;
                        Ok(t.elapsed().as_secs_f64())
                    });
                    walls.push(r?);
                }
                let cpu = (cpu_s() - c0) / 3.0;
                walls.sort_by(|a, b| a.total_cmp(b));
                let wall = walls[1];
                if threads == 1 {
                    one = wall;
                }
                println!(
                    "| {n}² × {bands} | {} | {threads} | {wall:.3} | {cpu:.3} | {:.2} | {:.2} |",
                    precision.as_str(),
                    one / wall,
                    one / wall / threads as f64
                );
                threads *= 2;
            }
        }
    }
    Ok(())
}
