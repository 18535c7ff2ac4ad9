//! Criterion benches of the imaging kernels at the 1024² scene's padded frame (1080²):
//! forward real 2-D FFT (f32 and f64), the fused column pass (column FFTs + OTF profile
//! lookup + accumulation) of a chunk of bands, and the inverse transform + sampling.
//!
//! `cargo bench --bench kernels` (figures in BENCHMARKS.md).

use std::hint::black_box;
use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, Criterion};
use ndarray::Array2;
use num_complex::{Complex, Complex64};

use eoir::imaging::fft::{FftFloat, RealFft2, SpectrumBuffer};
use eoir::imaging::{
    accumulate_chunk, ColumnWorkspace, Imager, BANDS_PER_CHUNK, DEFAULT_WRAP_TOLERANCE,
};
use eoir::scene::{CubeMeta, Geometry, RadianceUnits};
use eoir::sensor::{Sensor, SensorConfig};

const N: usize = 1024;

fn imager() -> Imager {
    let toml = include_str!("swir_all_components.toml");
    let c = SensorConfig::from_toml_str(toml, "bench", PathBuf::from("."), &[]).unwrap();
    let s = Sensor::build(&c).unwrap();
    let meta = CubeMeta {
        wavelength_um: (0..32).map(|i| 0.95 + 0.8 * i as f64 / 31.0).collect(),
        fwhm_um: None,
        units: RadianceUnits::SpectralPerUm,
        geometry: Some(Geometry::from_ifov(50e-6, 50e-6, N, N)),
        rows: N,
        cols: N,
    };
    Imager::new(&s, &meta, &meta.geometry.unwrap(), DEFAULT_WRAP_TOLERANCE).unwrap()
}

fn frame<T: FftFloat>(ny: usize, nx: usize) -> Array2<T> {
    Array2::from_shape_fn((ny, nx), |(r, c)| {
        T::nearest_from_f64(((r * 31 + c * 17) % 101) as f64)
    })
}

fn forward<T: FftFloat>(c: &mut Criterion, name: &str, ny: usize, nx: usize) {
    let fft = RealFft2::<T>::new(ny, nx);
    let mut x = frame::<T>(ny, nx);
    let mut spec = Array2::<Complex<T>>::zeros(fft.spectrum_shape());
    let mut scratch = Vec::new();
    c.bench_function(name, |b| {
        b.iter(|| {
            fft.forward(&mut x, &mut spec, &mut scratch);
            black_box(&spec);
        })
    });
}

fn kernels(c: &mut Criterion) {
    let im = imager();
    let (ny, nx) = (im.sampling().y.padded_len, im.sampling().x.padded_len);
    let hc = nx / 2 + 1;
    forward::<f32>(c, &format!("forward real 2-D FFT f32 {ny}x{nx}"), ny, nx);
    forward::<f64>(c, &format!("forward real 2-D FFT f64 {ny}x{nx}"), ny, nx);
    // The fused column pass of one chunk (f32 row spectra, f64 accumulator).
    let fft = RealFft2::<f32>::new(ny, nx);
    let x = frame::<f32>(ny, nx);
    let mut rowspecs: Vec<SpectrumBuffer<f32>> = (0..BANDS_PER_CHUNK)
        .map(|_| SpectrumBuffer::new(ny * hc))
        .collect();
    for rs in rowspecs.iter_mut() {
        fft.rows_forward_transposed(
            |r, row| row.copy_from_slice(x.row(r).as_slice().unwrap()),
            rs.as_mut_slice(),
            im.row_stores(),
        );
    }
    let weights = vec![1.0; BANDS_PER_CHUNK];
    let wavelengths: Vec<f64> = (0..BANDS_PER_CHUNK).map(|i| 1.0 + 0.1 * i as f64).collect();
    let profile = im.chunk_profile(&wavelengths);
    let mut acc_t = vec![Complex64::new(0.0, 0.0); ny * hc];
    let workspace = ColumnWorkspace::<f32>::new();
    c.bench_function(
        &format!("column FFTs + OTF profile accumulate, {BANDS_PER_CHUNK} bands f32 {ny}x{nx}"),
        |b| {
            b.iter(|| {
                accumulate_chunk(
                    &fft,
                    &rowspecs,
                    &weights,
                    &profile,
                    im.radial_grid(),
                    &mut acc_t,
                    &workspace,
                );
                black_box(&acc_t);
            })
        },
    );
    // Inverse + sampling onto the 341² detector.
    let spec0 = Array2::from_shape_fn((ny, hc), |(v, u)| {
        Complex64::new(1.0 / (1.0 + (u * u + v * v) as f64), 0.0)
    });
    // Transposed, as the engine accumulates it.
    let spec0_t: Vec<Complex64> = (0..hc * ny).map(|i| spec0[[i % ny, i / ny]]).collect();
    c.bench_function(&format!("inverse + sampling {ny}x{nx} -> 341x341"), |b| {
        b.iter(|| {
            let mut s = spec0_t.clone();
            black_box(im.detector_image_transposed(&mut s));
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = kernels
}
criterion_main!(benches);
