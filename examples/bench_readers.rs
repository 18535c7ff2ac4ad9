//! Reader benchmark: writes the same texture cube of SIZE² pixels at several band counts in
//! every input format (ENVI BSQ, BIL, BIP, NPY, spectral EXR and, built with
//! `--features hdf5`, HDF5), runs `eoir run` on each file as a child under
//! `/usr/bin/time -v`, and prints BENCHMARKS.md table rows: wall time, peak RSS, and per
//! format the RSS ratio between the largest and the smallest band count (the flat-memory
//! requirement is ≤ 1.2) and the wall time relative to BSQ at the same band count.
//!
//! `cargo run --release --example bench_readers -- [SIZE] [BANDS,BANDS,...]`
//! (default `1024 32,256`). Environment: `EOIR_BENCH_DIR` (default
//! `/tmp/eoir-bench-readers`; needs about 4 × SIZE² × Σ BANDS × 6 bytes), `EOIR_BENCH_EXE`
//! (the `eoir` binary to time; default the one next to this example, so a second build
//! can be compared), `EOIR_BENCH_READERS_ONLY` (set: only the in-process reader table).
//! The files are written once and reused; each is read once before
//! timing so every format runs from a warm page cache.
//!
//! The sensor is diffraction-limited SWIR (1.02–1.68 µm response, the cube's grid, detector = SIZE/3
//! square): every band of the cube has sensor response and is read, and the engine's
//! share is the same for every format, so differences between formats are the readers'.

mod bench_common;
use bench_common::peak_rss_mib;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use ndarray::Array3;

use eoir::scene::{Cube, CubeMeta, Geometry, RadianceUnits};

/// Scene sampling, rad; the detector IFOV is 3 scene samples.
const SCENE_IFOV_RAD: f64 = 50e-6;

fn sensor_toml(det: usize) -> String {
    format!(
        r#"
name = "bench-readers-swir"
[optics]
focal_length_m = 0.3
f_number = 2.0
[filter]
kind = "top_hat"
lo_um = 1.02
hi_um = 1.68
[detector]
rows = {det}
cols = {det}
pitch_m = 45e-6
active_width_m = 40e-6
integration_time_s = 1e-3
quantum_efficiency = {{ kind = "ideal_qe", peak = 0.8, cutoff_um = 1.75 }}
"#
    )
}

/// Radiance of band `b` at (r, c): a texture of incommensurate cosines, per band different.
fn texture(b: usize, r: usize, c: usize) -> f32 {
    let (r, c, b) = (r as f32, c as f32, b as f32);
    10.0 + 3.0 * (0.071 * r + 0.013 * c + 0.1 * b).cos()
        + 2.0 * (0.31 * c - 0.05 * r).cos() * (0.02 * b).sin()
        + ((r * 0.77 + c * 1.31).sin() * 43_758.547).fract()
}

/// Writes `cube` as ENVI with interleave `il` (BIL and BIP by hand, BSQ by eoir's writer).
fn write_envi(cube: &Cube, hdr: &Path, il: &str) -> Result<(), Box<dyn std::error::Error>> {
    let data_path = hdr.with_extension("img");
    if il == "bsq" {
        eoir::io::envi::write(&data_path, cube)?;
        return Ok(());
    }
    let (nb, nr, nc) = cube.data.dim();
    let mut bytes = Vec::with_capacity(nb * nr * nc * 4);
    for r in 0..nr {
        if il == "bil" {
            for b in 0..nb {
                for c in 0..nc {
                    bytes.extend(cube.data[[b, r, c]].to_le_bytes());
                }
            }
        } else {
            for c in 0..nc {
                for b in 0..nb {
                    bytes.extend(cube.data[[b, r, c]].to_le_bytes());
                }
            }
        }
    }
    std::fs::write(&data_path, bytes)?;
    let wl: Vec<String> = cube
        .meta
        .wavelength_um
        .iter()
        .map(|w| w.to_string())
        .collect();
    let g = cube.meta.geometry.ok_or("the bench cube has a geometry")?;
    std::fs::write(
        hdr,
        format!(
            "ENVI\nsamples = {nc}\nlines = {nr}\nbands = {nb}\nheader offset = 0\ndata type = 4\ninterleave = {il}\nbyte order = 0\nwavelength units = Micrometers\nwavelength = {{{}}}\neoir radiance units = {}\neoir fov deg = {{{}, {}}}\n",
            wl.join(", "),
            cube.meta.units.as_str(),
            g.fov_x_deg,
            g.fov_y_deg
        ),
    )?;
    Ok(())
}

/// Writes every format of a `n² × bands` cube into `dir` (once); returns (label, path).
fn write_inputs(
    n: usize,
    bands: usize,
    dir: &Path,
) -> Result<Vec<(String, PathBuf)>, Box<dyn std::error::Error>> {
    let case = dir.join(format!("{n}x{bands}"));
    std::fs::create_dir_all(&case)?;
    let mut inputs: Vec<(String, PathBuf)> = ["bsq", "bil", "bip"]
        .iter()
        .map(|il| {
            (
                format!("ENVI {}", il.to_uppercase()),
                case.join(format!("{il}.hdr")),
            )
        })
        .collect();
    inputs.push(("NPY".into(), case.join("cube.npy")));
    inputs.push(("EXR".into(), case.join("cube.exr")));
    if cfg!(feature = "hdf5") {
        inputs.push(("HDF5".into(), case.join("cube.h5")));
    }
    if inputs.iter().all(|(_, p)| p.exists()) {
        return Ok(inputs);
    }
    let wl: Vec<f64> = (0..bands)
        .map(|i| 1.02 + 0.66 * i as f64 / (bands - 1) as f64)
        .collect();
    let meta = CubeMeta {
        wavelength_um: wl,
        fwhm_um: None,
        units: RadianceUnits::SpectralPerUm,
        geometry: Some(Geometry::from_ifov(SCENE_IFOV_RAD, SCENE_IFOV_RAD, n, n)),
        rows: n,
        cols: n,
    };
    let cube = Cube::new(
        Array3::from_shape_fn((bands, n, n), |(b, r, c)| texture(b, r, c)),
        meta,
    )?;
    for (label, path) in &inputs {
        match label.as_str() {
            "ENVI BSQ" => write_envi(&cube, path, "bsq")?,
            "ENVI BIL" => write_envi(&cube, path, "bil")?,
            "ENVI BIP" => write_envi(&cube, path, "bip")?,
            _ => eoir::io::write_cube(path, &cube)?,
        }
    }
    Ok(inputs)
}

/// Runs `eoir run` on `input` under `/usr/bin/time -v`: (wall s, peak RSS MiB).
fn time_run(
    eoir: &Path,
    sensor: &Path,
    input: &Path,
    out: &Path,
) -> Result<(f64, f64), Box<dyn std::error::Error>> {
    let _ = std::fs::remove_dir_all(out);
    let t = Instant::now();
    let o = Command::new("/usr/bin/time")
        .arg("-v")
        .arg(eoir)
        .args(["run", "--quiet", "--sensor"])
        .arg(sensor)
        .arg(input)
        .arg("-o")
        .arg(out)
        .output()?;
    let wall = t.elapsed().as_secs_f64();
    let err = String::from_utf8_lossy(&o.stderr);
    if !o.status.success() {
        return Err(format!("eoir run {} failed: {err}", input.display()).into());
    }
    let rss = peak_rss_mib(&err);
    Ok((wall, rss))
}

/// One timed run: (bands, wall s, peak RSS MiB).
type Measured = (usize, f64, f64);

/// Reads every byte of the file(s) of `input` once (warm page cache).
fn warm(input: &Path) {
    let stem = input.with_extension("");
    for ext in ["img", "npy", "exr", "h5", "hdr", "json"] {
        let _ = std::fs::read(stem.with_extension(ext));
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let n: usize = args.first().map_or(Ok(1024), |s| s.parse())?;
    let band_counts: Vec<usize> = args
        .get(1)
        .map_or("32,256", String::as_str)
        .split(',')
        .map(str::parse)
        .collect::<Result<_, _>>()?;
    let dir =
        PathBuf::from(std::env::var("EOIR_BENCH_DIR").unwrap_or("/tmp/eoir-bench-readers".into()));
    let eoir = match std::env::var("EOIR_BENCH_EXE") {
        Ok(p) => PathBuf::from(p),
        Err(_) => std::env::current_exe()?
            .parent()
            .and_then(|p| p.parent())
            .map(|p| p.join("eoir"))
            .ok_or("no eoir binary")?,
    };
    std::fs::create_dir_all(&dir)?;
    let sensor = dir.join(format!("sensor-{n}.toml"));
    std::fs::write(&sensor, sensor_toml(n / 3))?;
    let mut results: Vec<(String, Vec<Measured>)> = Vec::new();
    println!("| input | bands | eoir wall (s) | wall / BSQ wall | peak RSS (MiB) |");
    println!("|---|---|---|---|---|");
    // EOIR_BENCH_READERS_ONLY=1: skip the `eoir run` table.
    let runs = std::env::var("EOIR_BENCH_READERS_ONLY").is_err();
    for &bands in band_counts.iter().filter(|_| runs) {
        let inputs = write_inputs(n, bands, &dir)?;
        let mut bsq_wall = f64::NAN;
        for (label, path) in inputs {
            warm(&path);
            let out = dir.join(format!("out-{n}x{bands}"));
            let (wall, rss) = match time_run(&eoir, &sensor, &path, &out) {
                Ok(m) => m,
                Err(e) => {
                    println!(
                        "| {label} | {bands} | failed: {} | | |",
                        e.to_string().lines().next().unwrap_or("")
                    );
                    continue;
                }
            };
            if label == "ENVI BSQ" {
                bsq_wall = wall;
            }
            println!(
                "| {label} | {bands} | {wall:.2} | {:.2} | {rss:.0} |",
                wall / bsq_wall
            );
            match results.iter_mut().find(|(l, _)| *l == label) {
                Some((_, v)) => v.push((bands, wall, rss)),
                None => results.push((label, vec![(bands, wall, rss)])),
            }
        }
    }
    // The readers alone, in this process: every band read, in chunks of 1 and 16 bands.
    println!();
    println!("| input | bands | chunk | read all bands (s) | MB/s of f32 planes |");
    println!("|---|---|---|---|---|");
    for &bands in &band_counts {
        for (label, path) in write_inputs(n, bands, &dir)? {
            warm(&path);
            for chunk in [1usize, 16] {
                let t = Instant::now();
                let mut reader = eoir::io::open(&path)?;
                let all: Vec<usize> = (0..reader.meta().bands()).collect();
                let mut sum = 0.0f64;
                for c in all.chunks(chunk) {
                    for plane in reader.read_bands(0, c)? {
                        sum += f64::from(plane[[0, 0]]);
                    }
                }
                let s = t.elapsed().as_secs_f64();
                assert!(sum > 0.0, "planes were read");
                let mb = (n * n * bands * 4) as f64 / 1e6;
                println!("| {label} | {bands} | {chunk} | {s:.2} | {:.0} |", mb / s);
            }
        }
    }
    if band_counts.len() > 1 && runs {
        println!();
        println!(
            "| input | RSS({}) / RSS({}) |",
            band_counts[band_counts.len() - 1],
            band_counts[0]
        );
        println!("|---|---|");
        for (label, v) in &results {
            let (first, last) = (v[0].2, v[v.len() - 1].2);
            println!("| {label} | {:.2} |", last / first);
        }
    }
    Ok(())
}
