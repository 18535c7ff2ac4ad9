//! The fast imaging paths (issue 9): f32 forward transforms against the f64 reference
//! path, results independent of the thread count for both precisions, and bands read in
//! bounded chunks (memory flat in the band count).

use std::path::PathBuf;

use ndarray::{Array2, Array3};

use eoir::imaging::fft::FftPrecision;
use eoir::imaging::{Imager, BANDS_PER_CHUNK, DEFAULT_WRAP_TOLERANCE};
use eoir::io::{CubeReader, MemoryCube};
use eoir::scene::{Cube, CubeMeta, Geometry, RadianceUnits};
use eoir::sensor::{Sensor, SensorConfig};

/// SWIR sensor with every transfer-function component on (the benchmark's sensor, small).
/// The all-components SWIR sensor of the benchmarks, at a small detector size.
const SWIR: &str = include_str!("../../benches/swir_all_components.toml");

fn sensor() -> Sensor {
    let c = SensorConfig::from_toml_str(
        SWIR,
        "swir_all_components.toml",
        PathBuf::from("."),
        &["detector.rows=40".into(), "detector.cols=54".into()],
    )
    .unwrap();
    Sensor::build(&c).unwrap()
}

/// A texture cube (incommensurate cosines plus hash noise, different per band) of
/// `bands` bands over 0.95–1.75 µm, `rows × cols` samples of `ifov_rad`.
fn texture(bands: usize, rows: usize, cols: usize, ifov_rad: f64) -> Cube {
    let wl: Vec<f64> = (0..bands)
        .map(|i| 0.95 + 0.8 * i as f64 / (bands - 1) as f64)
        .collect();
    let data = Array3::from_shape_fn((bands, rows, cols), |(b, r, c)| {
        let (r, c, b) = (r as f32, c as f32, b as f32);
        10.0 + 3.0 * (0.071 * r + 0.013 * c + 0.1 * b).cos()
            + 2.0 * (0.31 * c - 0.05 * r).cos() * (0.02 * b).sin()
            + ((r * 0.77 + c * 1.31).sin() * 43_758.547).fract()
    });
    let meta = CubeMeta {
        wavelength_um: wl,
        fwhm_um: None,
        units: RadianceUnits::SpectralPerUm,
        geometry: Some(Geometry::from_ifov(ifov_rad, ifov_rad, rows, cols)),
        rows,
        cols,
    };
    Cube::new(data, meta).unwrap()
}

fn image(s: &Sensor, c: &Cube, precision: FftPrecision, threads: usize) -> Array2<f64> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let imager = Imager::new(
            s,
            &c.meta,
            &c.meta.geometry.unwrap(),
            DEFAULT_WRAP_TOLERANCE,
        )
        .unwrap()
        .with_precision(precision);
        assert_eq!(imager.precision(), precision);
        let mut reader = MemoryCube::new(c.clone());
        let (e, stats) = imager.mean_electrons(&mut reader, 0, |_, _| {}).unwrap();
        assert_eq!(stats.precision, precision);
        e
    })
}

/// The two test cubes: detector/scene ratio 3 (integer path: phase ramp, inverse FFT,
/// point sampling) and 2.5 (trigonometric interpolation path); band counts that are not a
/// multiple of the chunk, frames wider than one column block.
fn cases(s: &Sensor) -> Vec<Cube> {
    let (r, c) = (s.detector.rows, s.detector.cols);
    vec![
        texture(23, 3 * r, 3 * c, s.ifov_rad() / 3.0),
        texture(10, 5 * r / 2, 5 * c / 2, s.ifov_rad() / 2.5),
    ]
}

/// f32 forward transforms with f64 accumulation stay within 1e-6 of the mean signal of
/// the f64 path at every pixel (the bound); and they are a different computation
/// (the error is not exactly zero), so this compares two paths, not one with itself.
#[test]
fn f32_transforms_within_1e_6_of_the_mean_signal() {
    let s = sensor();
    for c in cases(&s) {
        let e64 = image(&s, &c, FftPrecision::F64, 2);
        let e32 = image(&s, &c, FftPrecision::F32, 2);
        let mean = e64.mean().unwrap();
        assert!(mean > 0.0);
        let worst = e64
            .iter()
            .zip(e32.iter())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        eprintln!(
            "{}x{}x{}: max |f32 - f64| = {:.3e} of the mean",
            c.meta.rows,
            c.meta.cols,
            c.meta.wavelength_um.len(),
            worst / mean
        );
        assert!(worst <= 1e-6 * mean, "{:e} of the mean", worst / mean);
        assert!(worst > 0.0, "the f32 path was not used");
    }
}

/// 1 and 2 worker threads give the same electrons bit for bit, in both precisions (each
/// accumulator sample is updated by one worker, bands in order).
#[test]
fn one_and_two_threads_identical_in_both_precisions() {
    let s = sensor();
    for c in cases(&s) {
        for p in [FftPrecision::F32, FftPrecision::F64] {
            let one = image(&s, &c, p, 1);
            let two = image(&s, &c, p, 2);
            assert!(one.iter().all(|v| v.is_finite() && *v > 0.0));
            assert_eq!(one.dim(), two.dim());
            for (a, b) in one.iter().zip(two.iter()) {
                assert_eq!(a.to_bits(), b.to_bits(), "{p:?}");
            }
        }
    }
}

/// A reader that records how the engine asks for bands.
struct Recording {
    inner: MemoryCube,
    calls: Vec<Vec<usize>>,
}

impl CubeReader for Recording {
    fn meta(&self) -> &CubeMeta {
        self.inner.meta()
    }
    fn read_band(&mut self, frame: usize, band: usize) -> eoir::Result<Array2<f32>> {
        self.calls.push(vec![band]);
        self.inner.read_band(frame, band)
    }
    fn read_bands(&mut self, frame: usize, bands: &[usize]) -> eoir::Result<Vec<Array2<f32>>> {
        self.calls.push(bands.to_vec());
        bands
            .iter()
            .map(|b| self.inner.read_band(frame, *b))
            .collect()
    }
}

/// The engine reads each contributing band exactly once, in order, through `read_bands`
/// chunks of at most `BANDS_PER_CHUNK` bands: the planes held at once do not grow with
/// the band count. Bands outside the sensor response (here 0.5–0.9 µm and beyond 1.75 µm)
/// are never read.
#[test]
fn bands_read_once_in_bounded_chunks_and_inactive_bands_skipped() {
    let s = sensor();
    let (r, c) = (3 * s.detector.rows, 3 * s.detector.cols);
    let wl: Vec<f64> = (0..40).map(|i| 0.5 + 0.04 * i as f64).collect();
    let data = Array3::from_elem((wl.len(), r, c), 5.0f32);
    let ifov = s.ifov_rad() / 3.0;
    let meta = CubeMeta {
        wavelength_um: wl.clone(),
        fwhm_um: None,
        units: RadianceUnits::SpectralPerUm,
        geometry: Some(Geometry::from_ifov(ifov, ifov, r, c)),
        rows: r,
        cols: c,
    };
    let cube = Cube::new(data, meta.clone()).unwrap();
    let imager = Imager::new(&s, &meta, &meta.geometry.unwrap(), DEFAULT_WRAP_TOLERANCE).unwrap();
    let active = imager.weights().active_bands();
    assert!(active.len() > BANDS_PER_CHUNK && active.len() < wl.len());
    let mut reader = Recording {
        inner: MemoryCube::new(cube),
        calls: Vec::new(),
    };
    let mut seen = Vec::new();
    imager
        .mean_electrons(&mut reader, 0, |done, total| seen.push((done, total)))
        .unwrap();
    assert!(reader
        .calls
        .iter()
        .all(|c| !c.is_empty() && c.len() <= BANDS_PER_CHUNK));
    let read: Vec<usize> = reader.calls.concat();
    assert_eq!(read, active);
    assert_eq!(seen.last(), Some(&(active.len(), active.len())));
}

/// Plane buffers given back to a file reader (`CubeReader::recycle`) are filled again by
/// the next reads: the same buffers (no fresh allocation), holding exactly the values a
/// fresh reader reads, for ENVI BSQ and NPY.
#[test]
fn recycled_plane_buffers_are_reused_and_read_correctly() {
    let cube = texture(8, 24, 17, 50e-6);
    let dir = tempfile::tempdir().unwrap();
    let envi = dir.path().join("c.hdr");
    let npy = dir.path().join("c.npy");
    eoir::io::envi::write(&envi, &cube).unwrap();
    eoir::io::npy::write(&npy, &cube).unwrap();
    let open = |p: &PathBuf| -> Box<dyn CubeReader> {
        if p.extension().unwrap() == "hdr" {
            Box::new(eoir::io::envi::EnviReader::open(p).unwrap())
        } else {
            Box::new(eoir::io::npy::NpyReader::open(p).unwrap())
        }
    };
    for path in [&envi, &npy] {
        let mut r = open(path);
        let first = r.read_bands(0, &[0, 1, 2, 3]).unwrap();
        let ptrs: Vec<*const f32> = first.iter().map(|p| p.as_ptr()).collect();
        r.recycle(first);
        let second = r.read_bands(0, &[4, 5, 6, 7]).unwrap();
        let mut fresh = open(path);
        let want = fresh.read_bands(0, &[4, 5, 6, 7]).unwrap();
        for (k, (got, want)) in second.iter().zip(&want).enumerate() {
            assert_eq!(got, want, "{} band {}", path.display(), 4 + k);
            assert_eq!(got, &cube.data.index_axis(ndarray::Axis(0), 4 + k));
            assert!(
                ptrs.contains(&got.as_ptr()),
                "{}: band {} was not read into a recycled buffer",
                path.display(),
                4 + k
            );
        }
    }
}

/// The engine gives the same mean electrons, bit for bit, whether an ENVI band-sequential
/// f32 file's planes come from memory maps (the default), from `read()` (`--no-mmap`) or
/// from the cube in memory: the same values enter the same arithmetic.
#[test]
fn mapped_read_and_in_memory_planes_image_identically() {
    let s = sensor();
    let cube = &cases(&s)[0];
    let dir = tempfile::tempdir().unwrap();
    let hdr = dir.path().join("c.hdr");
    eoir::io::envi::write(&hdr, cube).unwrap();
    let imager = Imager::new(
        &s,
        &cube.meta,
        &cube.meta.geometry.unwrap(),
        DEFAULT_WRAP_TOLERANCE,
    )
    .unwrap();
    let want = imager
        .mean_electrons(&mut MemoryCube::new(cube.clone()), 0, |_, _| {})
        .unwrap()
        .0;
    for no_memory_map in [false, true] {
        let opts = eoir::io::ReadOptions {
            no_memory_map,
            ..Default::default()
        };
        let mut r = eoir::io::envi::EnviReader::open_with(&hdr, &opts).unwrap();
        assert_eq!(
            matches!(
                r.read_planes(0, &[0]).unwrap(),
                eoir::io::BandPlanes::Mapped(_)
            ),
            !no_memory_map
        );
        let got = imager.mean_electrons(&mut r, 0, |_, _| {}).unwrap().0;
        assert!(
            got.iter()
                .zip(&want)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "mapping off: {no_memory_map}"
        );
    }
}

/// A NaN, ±Inf or negative value in a band the engine uses stops the run with the
/// reader's own message (band, wavelength, first bad pixel), whether the plane was mapped
/// and checked row by row inside the row pass or read and checked by the reader: first
/// band, a band of a later chunk, the last band; first and last pixel of the image; f32
/// and f64 transforms in turn (the row pass checks the padded row, in the transform's type).
#[test]
fn a_bad_value_in_a_used_band_stops_the_engine_with_the_readers_message() {
    let s = sensor();
    let clean = cases(&s).swap_remove(0);
    let imager = |precision| {
        Imager::new(
            &s,
            &clean.meta,
            &clean.meta.geometry.unwrap(),
            DEFAULT_WRAP_TOLERANCE,
        )
        .unwrap()
        .with_precision(precision)
    };
    let imagers = [imager(FftPrecision::F32), imager(FftPrecision::F64)];
    let active = imagers[0].weights().active_bands();
    assert!(active.len() > 2 * BANDS_PER_CHUNK);
    let (_, rows, cols) = clean.data.dim();
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (active[0], 0, 0, f32::NAN),
        (active[BANDS_PER_CHUNK + 1], rows - 1, cols - 1, -1.0),
        (*active.last().unwrap(), rows / 2, 3, f32::INFINITY),
    ];
    for (k, (band, row, col, value)) in cases.into_iter().enumerate() {
        let hdr = dir.path().join(format!("c{k}.hdr"));
        let npy = dir.path().join(format!("c{k}.npy"));
        eoir::io::envi::write(&hdr, &clean).unwrap();
        eoir::io::npy::write(&npy, &clean).unwrap();
        // Patch the value into each data file (BSQ / C order: [band, row, col] f32 LE at
        // the end of the file).
        let data_bytes = (clean.data.len() * 4) as u64;
        for data in [hdr.with_extension("img"), npy.clone()] {
            use std::io::{Seek, SeekFrom, Write};
            let mut f = std::fs::OpenOptions::new().write(true).open(&data).unwrap();
            let start = f.metadata().unwrap().len() - data_bytes;
            let at = start + (((band * rows + row) * cols + col) * 4) as u64;
            f.seek(SeekFrom::Start(at)).unwrap();
            f.write_all(&value.to_le_bytes()).unwrap();
        }
        for no_memory_map in [false, true] {
            let opts = eoir::io::ReadOptions {
                no_memory_map,
                ..Default::default()
            };
            let mut readers: Vec<Box<dyn CubeReader>> = vec![
                Box::new(eoir::io::envi::EnviReader::open_with(&hdr, &opts).unwrap()),
                Box::new(eoir::io::npy::NpyReader::open_with(&npy, &opts).unwrap()),
            ];
            let mut fresh: Vec<Box<dyn CubeReader>> = vec![
                Box::new(eoir::io::envi::EnviReader::open_with(&hdr, &opts).unwrap()),
                Box::new(eoir::io::npy::NpyReader::open_with(&npy, &opts).unwrap()),
            ];
            for (r, f) in readers.iter_mut().zip(fresh.iter_mut()) {
                let got = imagers[k % 2]
                    .mean_electrons(r.as_mut(), 0, |_, _| {})
                    .unwrap_err()
                    .to_string();
                let want = f.read_band(0, band).unwrap_err().to_string();
                // Mapped, the reader hands the bad plane over unchecked, with the check
                // owed; read, it checks the plane itself and refuses it.
                match r.read_planes_deferred(0, &[band]) {
                    Ok((planes, Some(owed))) => {
                        assert!(!no_memory_map);
                        assert_eq!(owed.run(&planes).unwrap_err().to_string(), want);
                    }
                    Ok((_, None)) => panic!("a bad plane handed over as checked"),
                    Err(e) => {
                        assert!(no_memory_map);
                        assert_eq!(e.to_string(), want);
                    }
                }
                assert_eq!(got, want, "case {k}, mapping off: {no_memory_map}");
                assert!(
                    got.contains(&format!("band {band} ("))
                        && got.contains(&format!("row {row}, col {col}")),
                    "{got}"
                );
            }
        }
    }
}

/// A sequence's chunk profiles are built once and reused (`Imager::keep_chunk_profiles`):
/// the second frame, imaged with the first frame's kept profiles, is bit for bit the
/// frame imaged by a fresh imager that builds its own, on a cube of several chunks (each
/// chunk's profile differs, so a profile served to the wrong chunk changes the image);
/// with keeping off nothing is kept.
#[test]
fn kept_chunk_profiles_image_later_frames_identically() {
    let s = sensor();
    let ifov = s.ifov_rad() / 3.0;
    let first = texture(3 * BANDS_PER_CHUNK + 3, 120, 162, ifov);
    let mut second = first.clone();
    second.data.mapv_inplace(|v| 1.5 * v + 0.25);
    let reader = || MemoryCube::sequence(vec![first.clone(), second.clone()], None).unwrap();
    let meta = &first.meta;
    let new_imager =
        || Imager::new(&s, meta, &meta.geometry.unwrap(), DEFAULT_WRAP_TOLERANCE).unwrap();
    let chunks = new_imager()
        .weights()
        .active_bands()
        .len()
        .div_ceil(BANDS_PER_CHUNK);
    assert!(chunks >= 3, "{chunks} chunks");

    let kept = new_imager();
    kept.keep_chunk_profiles(eoir::imaging::PROFILE_CACHE_BYTES);
    let mut r = reader();
    kept.mean_electrons(&mut r, 0, |_, _| {}).unwrap();
    assert_eq!(kept.kept_chunk_profiles(), chunks);
    let (reused, _) = kept.mean_electrons(&mut r, 1, |_, _| {}).unwrap();

    let fresh = new_imager();
    let (built, _) = fresh.mean_electrons(&mut reader(), 1, |_, _| {}).unwrap();
    assert_eq!(fresh.kept_chunk_profiles(), 0, "keeping is off by default");
    assert!(built.iter().all(|v| v.is_finite() && *v > 0.0));
    for ((i, a), b) in reused.indexed_iter().zip(built.iter()) {
        assert_eq!(a.to_bits(), b.to_bits(), "pixel {i:?}: {a} vs {b}");
    }
}
