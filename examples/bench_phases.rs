//! Where the engine's per-band time goes against its FFT bound, in memory (issue 9).
//!
//! `cargo run --release --example bench_phases -- [SIZE] [ROUNDS]` (default 1024, 5).
//! Builds the imager of the every-component SWIR sensor (`benches/swir_all_components.toml`,
//! k = 3) for a SIZE² scene and times, per chunk of [`BANDS_PER_CHUNK`] bands of distinct
//! data (so each chunk streams from memory as in a run):
//! - **rows**: the engine's row pass (padding + row transforms into the block-major layout),
//!   the chunk's bands in parallel, as `Imager::mean_electrons` runs it;
//! - **columns + OTF + accumulate**: the chunk's profile and [`accumulate_chunk`];
//! - **bound**: the same number of forward transforms `RealFft2::forward` of one frame (the
//!   FFT bound of `bench_run`).
//!
//! Prints the medians over all chunks of all rounds, in ms per band, and engine/bound.

mod bench_common;
use bench_common::{median, swir_meta, swir_sensor_config};
use std::time::Instant;

use ndarray::Array2;
use num_complex::{Complex, Complex64};
use rayon::prelude::*;

use eoir::imaging::fft::{RealFft2, SpectrumBuffer};
use eoir::imaging::{
    accumulate_chunk, ColumnWorkspace, Imager, BANDS_PER_CHUNK, DEFAULT_WRAP_TOLERANCE,
};
use eoir::sensor::Sensor;

const CHUNKS: usize = 8;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().map_or(Ok(1024), |a| a.parse())?;
    let rounds: usize = args.next().map_or(Ok(5), |a| a.parse())?;
    let sensor = Sensor::build(&swir_sensor_config(n / 3)?)?;
    let bands = CHUNKS * BANDS_PER_CHUNK;
    let wl: Vec<f64> = (0..bands)
        .map(|i| 1.0 + 0.7 * i as f64 / (bands - 1) as f64)
        .collect();
    let meta = swir_meta(n, wl.clone());
    let im = Imager::new(
        &sensor,
        &meta,
        &meta.geometry.unwrap(),
        DEFAULT_WRAP_TOLERANCE,
    )?;
    let (ny, nx) = (im.sampling().y.padded_len, im.sampling().x.padded_len);
    let hc = nx / 2 + 1;
    let fft = RealFft2::<f32>::new(ny, nx);
    let planes: Vec<Array2<f32>> = (0..bands)
        .map(|b| {
            Array2::from_shape_fn((n, n), |(r, c)| {
                let (r, c, b) = (r as f32, c as f32, b as f32);
                10.0 + 3.0 * (0.071 * r + 0.013 * c + 0.1 * b).cos()
                    + ((r * 0.77 + c * 1.31 + b).sin() * 43_758.547).fract().abs()
            })
        })
        .collect();
    let mut rowspecs: Vec<SpectrumBuffer<f32>> = (0..BANDS_PER_CHUNK)
        .map(|_| SpectrumBuffer::new(ny * hc))
        .collect();
    let mut acc = vec![Complex64::new(0.0, 0.0); ny * hc];
    let mut frame = Array2::from_shape_fn((ny, nx), |(r, c)| ((31 * r + 17 * c) % 101) as f32);
    let mut spec = Array2::<Complex<f32>>::zeros(fft.spectrum_shape());
    // The same transforms on distinct frames and outputs (a chunk's worth each), so that
    // every transform reads its input from memory and writes a fresh output, as the engine
    // must: the "streamed" bound.
    let mut frames: Vec<Array2<f32>> = (0..BANDS_PER_CHUNK)
        .map(|b| Array2::from_shape_fn((ny, nx), |(r, c)| ((31 * r + 17 * c + b) % 101) as f32))
        .collect();
    let mut specs: Vec<Array2<Complex<f32>>> = (0..BANDS_PER_CHUNK)
        .map(|_| Array2::zeros(fft.spectrum_shape()))
        .collect();
    let mut stream_t = Vec::new();
    let mut scratch = Vec::new();
    let weights = vec![1.0; BANDS_PER_CHUNK];
    let (mut rows_t, mut cols_t, mut bound_t) = (Vec::new(), Vec::new(), Vec::new());
    let workspace = ColumnWorkspace::new();
    for round in 0..=rounds {
        for (ci, chunk) in planes.chunks(BANDS_PER_CHUNK).enumerate() {
            let t0 = Instant::now();
            rowspecs
                .par_iter_mut()
                .zip(chunk.par_iter())
                .for_each(|(rs, p)| im.rows_forward_band(&fft, p.view(), rs.as_mut_slice()));
            let t1 = Instant::now();
            let profile = im.chunk_profile(&wl[ci * BANDS_PER_CHUNK..(ci + 1) * BANDS_PER_CHUNK]);
            accumulate_chunk(
                &fft,
                &rowspecs,
                &weights,
                &profile,
                im.radial_grid(),
                &mut acc,
                &workspace,
            );
            let t2 = Instant::now();
            for _ in 0..BANDS_PER_CHUNK {
                fft.forward(&mut frame, &mut spec, &mut scratch);
            }
            let t3 = Instant::now();
            // Evict the frames of the last chunk: touch the band planes of this one again.
            std::hint::black_box(chunk.iter().map(|p| p.sum()).sum::<f32>());
            let t4 = Instant::now();
            for (f, o) in frames.iter_mut().zip(specs.iter_mut()) {
                fft.forward(f, o, &mut scratch);
            }
            let t5 = Instant::now();
            if round > 0 {
                stream_t.push((t5 - t4).as_secs_f64() * 1e3 / BANDS_PER_CHUNK as f64);
                let per_band =
                    |d: std::time::Duration| d.as_secs_f64() * 1e3 / BANDS_PER_CHUNK as f64;
                rows_t.push(per_band(t1 - t0));
                cols_t.push(per_band(t2 - t1));
                bound_t.push(per_band(t3 - t2));
            }
        }
    }
    std::hint::black_box((&acc, &spec, &specs));
    let streamed = median(stream_t.clone());
    println!(
        "streamed FFT bound (distinct frames): median {streamed:.3}, min {:.3} ms/band",
        stream_t.iter().copied().fold(f64::INFINITY, f64::min)
    );
    let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
    println!(
        "minima: rows {:.3}, columns+OTF+accumulate {:.3}, bound {:.3} ms/band",
        min(&rows_t),
        min(&cols_t),
        min(&bound_t)
    );
    let (r, c, b) = (median(rows_t), median(cols_t), median(bound_t));
    println!(
        "{n}² scene, {ny}×{nx} frame, {} threads: rows {r:.3} ms/band, columns+OTF+accumulate {c:.3} ms/band, engine {:.3} ms/band; FFT bound {b:.3} ms/band; engine/bound {:.2}",
        rayon::current_num_threads(),
        r + c,
        (r + c) / b
    );
    Ok(())
}
