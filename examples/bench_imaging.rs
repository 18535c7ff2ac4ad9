//! Prints timings of the imaging engine on synthetic cubes of several sizes.
//!
//! `cargo run --release --example bench_imaging` — figures go into BENCHMARKS.md.

use std::time::Instant;

use ndarray::Array3;

use eoir::imaging::{Imager, DEFAULT_WRAP_TOLERANCE};
use eoir::io::MemoryCube;
use eoir::scene::{Cube, CubeMeta, Geometry, RadianceUnits};
use eoir::sensor::presets;

fn main() -> eoir::Result<()> {
    let threads = rayon::current_num_threads();
    println!("rayon threads: {threads}");
    println!(
        "{:>14} {:>6} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "scene", "bands", "padded", "setup_s", "fft_s", "otf_s", "inv_s", "total_s"
    );
    for (k, bands) in [(1usize, 30usize), (2, 30), (3, 30), (3, 60)] {
        let sensor = eoir::sensor::Sensor::build(&presets::load("multimir", &[], &[])?)?;
        let (rows, cols) = (sensor.detector.rows * k, sensor.detector.cols * k);
        let wl: Vec<f64> = (0..bands)
            .map(|i| 4.4 + 0.9 * i as f64 / (bands - 1) as f64)
            .collect();
        let data = Array3::from_shape_fn((bands, rows, cols), |(b, r, c)| {
            (1.0 + 0.5 * ((r * 7 + c * 13 + b) % 17) as f64 / 17.0) as f32
        });
        let ifov = sensor.ifov_rad() / k as f64;
        let meta = CubeMeta {
            wavelength_um: wl,
            fwhm_um: None,
            units: RadianceUnits::SpectralPerUm,
            geometry: Some(Geometry::from_ifov(ifov, ifov, rows, cols)),
            rows,
            cols,
        };
        let cube = Cube::new(data, meta.clone())?;
        let t0 = Instant::now();
        let imager = Imager::new(
            &sensor,
            &meta,
            &meta.geometry.unwrap(),
            DEFAULT_WRAP_TOLERANCE,
        )?;
        let setup = t0.elapsed().as_secs_f64();
        let mut reader = MemoryCube::new(cube);
        let t1 = Instant::now();
        let (_, stats) = imager.mean_electrons(&mut reader, 0, |_, _| {})?;
        let total = t1.elapsed().as_secs_f64();
        println!(
            "{:>14} {:>6} {:>9} {:>9.3} {:>9.3} {:>9.3} {:>9.3} {:>9.3}",
            format!("{cols}x{rows}"),
            bands,
            format!("{}x{}", stats.padded_shape.1, stats.padded_shape.0),
            setup,
            stats.fft_s,
            stats.otf_s,
            stats.inverse_s,
            total
        );
    }
    Ok(())
}
