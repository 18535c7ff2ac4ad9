//! The imager's fixed and per-chunk costs outside the transforms (issue 9): the setup
//! (`Imager::new`: frequency samples and chromatic tables) and one chunk's OTF profile
//! (`Imager::chunk_profile`), on one thread and on all.
//!
//! `cargo run --release --example bench_profile -- [SIZE] [ROUNDS]` (default 1024, 5):
//! the every-component SWIR sensor (`benches/swir_all_components.toml`, k = 3) on a SIZE²
//! scene of 128 bands over 0.95–1.75 µm, as `bench_run` writes it. Prints medians in ms.

mod bench_common;
use bench_common::{median, swir_meta, swir_sensor_config};
use std::time::Instant;

use eoir::imaging::{Imager, BANDS_PER_CHUNK, DEFAULT_WRAP_TOLERANCE};
use eoir::sensor::Sensor;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().map_or(Ok(1024), |a| a.parse())?;
    let rounds: usize = args.next().map_or(Ok(5), |a| a.parse())?;
    let sensor = Sensor::build(&swir_sensor_config(n / 3)?)?;
    let wl: Vec<f64> = (0..128).map(|i| 0.95 + 0.8 * i as f64 / 127.0).collect();
    let meta = swir_meta(n, wl);
    let geometry = meta.geometry.unwrap();
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    for (label, pool) in [("1 thread", Some(&one)), ("all threads", None)] {
        let run = |f: &mut (dyn FnMut() + Send)| match pool {
            Some(p) => p.install(f),
            None => f(),
        };
        let (mut setup, mut profile) = (Vec::new(), Vec::new());
        let mut intervals = 0;
        for _ in 0..rounds {
            let mut im = None;
            run(&mut || {
                let t = Instant::now();
                im = Some(Imager::new(&sensor, &meta, &geometry, DEFAULT_WRAP_TOLERANCE).unwrap());
                setup.push(t.elapsed().as_secs_f64() * 1e3);
            });
            let im = im.unwrap();
            let active: Vec<f64> = im
                .weights()
                .active_bands()
                .iter()
                .map(|&b| im.weights().wavelength_um[b])
                .collect();
            for chunk in active.chunks(BANDS_PER_CHUNK) {
                run(&mut || {
                    let t = Instant::now();
                    let p = im.chunk_profile(chunk);
                    profile.push(t.elapsed().as_secs_f64() * 1e3);
                    intervals = intervals.max(p.intervals());
                });
            }
        }
        println!(
            "{n}², {label}: setup {:.2} ms, chunk profile {:.3} ms (largest {intervals} intervals)",
            median(setup),
            median(profile)
        );
    }
    Ok(())
}
