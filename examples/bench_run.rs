//! End-to-end benchmark (issue 9): writes SWIR texture cubes to ENVI, times `eoir run` on
//! them as a child process (wall, Mvoxel/s, peak RSS from `/usr/bin/time -v`, the engine's
//! time (`timings_s.total`) from the run's report.json), the FFT bound (B forward + 1 inverse real
//! 2-D FFTs of the padded frame with the engine's own `RealFft2`, in the run's precision; on
//! one frame that stays in cache, and "streamed" over distinct frames as the engine's bands)
//! and the NumPy/SciPy script `benches/baseline.py` on the same files, back to back, and
//! prints BENCHMARKS.md tables: one row per case (medians over the repeats) and the
//! per-transform comparison with `scipy.fft.rfft2` at the same size and precision. The
//! bounds are measured right after each run and the engine/bound ratios are the medians
//! of those pairs (the host's load moves the bound by up to 2× within a session; each
//! pair's ratio, and the range, are printed after the table).
//!
//! `cargo build --release && cargo run --release --example bench_run -- [SIZE:BANDS ...]`
//! (default `1024:128`). Environment: `EOIR_BENCH_DIR` (default /tmp/eoir-bench),
//! `EOIR_BENCH_PYTHON` (a Python with numpy and scipy; default `python3`; empty: skip the
//! baseline), `EOIR_BENCH_REPEAT` (runs per case, default 3), `EOIR_BENCH_PRECISION`
//! (`f32` default, or `f64`), `EOIR_BENCH_INTERLEAVE` (`bsq` default, `bil`, `bip`: the
//! layout of the ENVI file), `EOIR_BENCH_BASELINE_MAX_VOXELS` (skip the baseline above
//! this many voxels; default 2^28), `EOIR_BENCH_RECACHE` (default 1: before each case the
//! cube is dropped from the page cache and read back by one untimed `eoir run`, so the
//! timings do not depend on how the file was cached before; 0: keep the cache as it is).

mod bench_common;
use bench_common::{median, peak_rss_mib, swir_meta, swir_sensor_config};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use ndarray::{Array2, Array3};
use num_complex::Complex;

use eoir::imaging::fft::{FftFloat, RealFft2};
use eoir::imaging::{Imager, DEFAULT_WRAP_TOLERANCE};
use eoir::scene::Cube;
use eoir::sensor::Sensor;

/// Scene sampling, rad, and detector/scene ratio.
const SCENE_IFOV_RAD: f64 = 50e-6;
const K: usize = 3;

/// Distinct frames the streamed FFT bound cycles through (8 inputs and 8 outputs of a
/// 1080² f32 frame are 75 MB, more than the last-level cache).
const STREAM_FRAMES: usize = 8;

/// Median seconds of one forward transform and of `bands` forward + 1 inverse (the FFT
/// bound) with the engine's transform code in `T`, on a `ny × nx` frame.
fn fft_bound<T: FftFloat>(ny: usize, nx: usize, bands: usize, repeats: usize) -> (f64, f64) {
    fft_bounds::<T>(ny, nx, bands, repeats, false)
}

/// [`fft_bound`], or with `streamed` the same transforms on [`STREAM_FRAMES`] distinct
/// frames and outputs in turn, so that each reads its input from memory and writes a
/// fresh output as the engine must (the one-frame bound keeps its frame in cache).
fn fft_bounds<T: FftFloat>(
    ny: usize,
    nx: usize,
    bands: usize,
    repeats: usize,
    streamed: bool,
) -> (f64, f64) {
    if streamed {
        let fft = RealFft2::<T>::new(ny, nx);
        let inv = RealFft2::<f64>::new(ny, nx);
        let mut frames: Vec<Array2<T>> = (0..STREAM_FRAMES)
            .map(|b| {
                Array2::from_shape_fn((ny, nx), |(r, c)| {
                    T::nearest_from_f64(((r * 31 + c * 17 + b) % 101) as f64)
                })
            })
            .collect();
        let mut specs: Vec<Array2<Complex<T>>> = (0..STREAM_FRAMES)
            .map(|_| Array2::zeros(fft.spectrum_shape()))
            .collect();
        let mut spec64 = Array2::<Complex<f64>>::zeros(fft.spectrum_shape());
        let (mut scratch, mut scratch64) = (Vec::new(), Vec::new());
        let mut out = Array2::<f64>::zeros((ny, nx));
        let mut bound = Vec::new();
        for _ in 0..repeats {
            let t = Instant::now();
            for b in 0..bands {
                let i = b % STREAM_FRAMES;
                fft.forward(&mut frames[i], &mut specs[i], &mut scratch);
            }
            inv.inverse(&mut spec64, &mut out, &mut scratch64);
            bound.push(t.elapsed().as_secs_f64());
        }
        return (f64::NAN, median(bound));
    }
    let fft = RealFft2::<T>::new(ny, nx);
    let inv = RealFft2::<f64>::new(ny, nx);
    let mut frame = Array2::from_shape_fn((ny, nx), |(r, c)| {
        T::nearest_from_f64(((r * 31 + c * 17) % 101) as f64)
    });
    let mut spec = Array2::<Complex<T>>::zeros(fft.spectrum_shape());
    let mut spec64 = Array2::<Complex<f64>>::zeros(fft.spectrum_shape());
    let mut scratch = Vec::new();
    let mut scratch64 = Vec::new();
    let mut out = Array2::<f64>::zeros((ny, nx));
    fft.forward(&mut frame, &mut spec, &mut scratch); // warm up
    let mut one = Vec::new();
    for _ in 0..9 {
        let t = Instant::now();
        fft.forward(&mut frame, &mut spec, &mut scratch);
        one.push(t.elapsed().as_secs_f64());
    }
    let mut bound = Vec::new();
    for _ in 0..repeats {
        let t = Instant::now();
        for _ in 0..bands {
            fft.forward(&mut frame, &mut spec, &mut scratch);
        }
        inv.inverse(&mut spec64, &mut out, &mut scratch64);
        bound.push(t.elapsed().as_secs_f64());
    }
    (median(one), median(bound))
}

/// Rewrites a BSQ ENVI cube as BIL or BIP (data and the header's `interleave`).
fn reinterleave(hdr: &Path, data: &Array3<f32>, interleave: &str) -> std::io::Result<()> {
    let (b, r, c) = data.dim();
    let order: Vec<f32> = match interleave {
        "bil" => (0..r)
            .flat_map(|y| (0..b).flat_map(move |z| (0..c).map(move |x| (z, y, x))))
            .map(|i| data[i])
            .collect(),
        _ => (0..r)
            .flat_map(|y| (0..c).flat_map(move |x| (0..b).map(move |z| (z, y, x))))
            .map(|i| data[i])
            .collect(),
    };
    let bytes: Vec<u8> = order.iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(hdr.with_extension("img"), bytes)?;
    let h = std::fs::read_to_string(hdr)?;
    std::fs::write(
        hdr,
        h.replace("interleave = bsq", &format!("interleave = {interleave}")),
    )
}

/// Asks the kernel to drop `path`'s cached pages (`POSIX_FADV_DONTNEED`; the file is
/// synced, so none is dirty). A no-op off Linux.
fn drop_from_page_cache(path: &Path) -> std::io::Result<()> {
    let f = std::fs::File::open(path)?;
    #[cfg(target_os = "linux")]
    {
        use std::os::fd::AsRawFd;
        // SAFETY: advice on a file descriptor we hold open; it changes no data.
        let r = unsafe { libc::posix_fadvise(f.as_raw_fd(), 0, 0, libc::POSIX_FADV_DONTNEED) };
        if r != 0 {
            return Err(std::io::Error::from_raw_os_error(r));
        }
    }
    drop(f);
    Ok(())
}

struct Settings {
    dir: PathBuf,
    python: String,
    repeat: usize,
    precision: String,
    interleave: String,
    baseline_max_voxels: usize,
    recache: bool,
}

/// One case: (table row, per-transform row).
fn run(
    n: usize,
    bands: usize,
    set: &Settings,
) -> Result<(String, String), Box<dyn std::error::Error>> {
    let det = n / K;
    let case = set.dir.join(format!("{n}x{bands}-{}", set.interleave));
    std::fs::create_dir_all(&case)?;
    let sensor_path = case.join("sensor.toml");
    let config = swir_sensor_config(det)?;
    std::fs::write(&sensor_path, config.to_toml_string()?)?;
    let wl: Vec<f64> = (0..bands)
        .map(|i| 0.95 + 0.8 * i as f64 / (bands - 1) as f64)
        .collect();
    let meta = swir_meta(n, wl.clone());
    let hdr = case.join("cube.hdr");
    if !hdr.exists() {
        // A texture: sums of incommensurate cosines, different per band.
        let data = Array3::from_shape_fn((bands, n, n), |(b, r, c)| {
            let (r, c, b) = (r as f32, c as f32, b as f32);
            10.0 + 3.0 * (0.071 * r + 0.013 * c + 0.1 * b).cos()
                + 2.0 * (0.31 * c - 0.05 * r).cos() * (0.02 * b).sin()
                + ((r * 0.77 + c * 1.31).sin() * 43_758.547).fract()
        });
        let cube = Cube::new(data, meta.clone())?;
        eoir::io::envi::write(&hdr, &cube)?;
        if set.interleave != "bsq" {
            reinterleave(&hdr, &cube.data, &set.interleave)?;
        }
        // Flush the new cube to disk before timing: otherwise the kernel writes the 1–4 GiB
        // back while eoir reads it (2048² × 128 measured 5.0 s that way, 3.0 s after sync).
        std::fs::File::open(hdr.with_extension("img"))?.sync_all()?;
    }
    // The engine's padded frame and spectral weights.
    let config = swir_sensor_config(det)?;
    let sensor = Sensor::build(&config)?;
    let imager = Imager::new(
        &sensor,
        &meta,
        &meta.geometry.unwrap(),
        DEFAULT_WRAP_TOLERANCE,
    )?;
    let s = imager.sampling();
    let (ny, nx) = (s.y.padded_len, s.x.padded_len);
    let active = imager.weights().active_bands().len();
    let exe = std::env::current_exe()?;
    let eoir = exe
        .parent()
        .and_then(|p| p.parent())
        .map(|p| p.join("eoir"))
        .ok_or("no eoir binary")?;
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/baseline.py");
    let params = serde_json::json!({
        "bands": bands, "rows": n, "cols": n,
        "padded_rows": ny, "padded_cols": nx,
        "pad_rows": s.y.pad_before, "pad_cols": s.x.pad_before,
        "scene_ifov_rad": SCENE_IFOV_RAD, "k": K,
        "weights": imager.weights().electrons_per_unit,
        "wavelength_um": wl,
        "aperture_m": 0.05, "obscuration": 0.3, "w_rms_waves": 0.05, "w020_waves": 0.3,
        "active_m": 14e-6, "focal_m": 0.1, "smear_rad": 60e-6, "smear_direction_deg": 30.0,
        "jitter_rad": 10e-6, "gaussian_rad": 5e-6, "cn2": 1e-15, "turb_range_m": 2000.0,
        "particle_m": 1e-6, "absorb_per_m": 1e-5, "scatter_per_m": 2e-5, "aer_range_m": 2000.0,
    });
    let pj = case.join("params.json");
    std::fs::write(&pj, params.to_string())?;
    let run_baseline = !set.python.is_empty()
        && set.interleave == "bsq"
        && n * n * bands <= set.baseline_max_voxels;
    let (mut walls, mut rsss, mut engines, mut bounds) = (vec![], vec![], vec![], vec![]);
    let mut streams = vec![];
    let (mut base_walls, mut base_rsss) = (vec![], vec![]);
    let mut one_fft = f64::NAN;
    // eoir run end to end, as a child under /usr/bin/time -v.
    let outdir = case.join("out");
    let eoir_run = || -> Result<std::process::Output, Box<dyn std::error::Error>> {
        let _ = std::fs::remove_dir_all(&outdir);
        let o = Command::new("/usr/bin/time")
            .arg("-v")
            .arg(&eoir)
            .args([
                "run",
                "--quiet",
                "--fft-precision",
                &set.precision,
                "--sensor",
            ])
            .arg(&sensor_path)
            .arg(&hdr)
            .arg("-o")
            .arg(&outdir)
            .output()?;
        if !o.status.success() {
            let err = String::from_utf8_lossy(&o.stderr);
            return Err(format!("eoir run failed: {err}").into());
        }
        Ok(o)
    };
    if set.recache {
        // The cube's page-cache state changes the timings by ~10 % at 1024² (plane maps of
        // 4 KiB folios cost ten times those of 2 MiB folios; BENCHMARKS.md round 13), and
        // it depends on how the file was last read. Drop it from the cache and let one
        // untimed run read it back, so every series starts from the state eoir leaves.
        drop_from_page_cache(&hdr.with_extension("img"))?;
        eoir_run()?;
    }
    for _ in 0..set.repeat {
        let t = Instant::now();
        let o = eoir_run()?;
        walls.push(t.elapsed().as_secs_f64());
        let err = String::from_utf8_lossy(&o.stderr);
        rsss.push(peak_rss_mib(&err));
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(outdir.join("report.json"))?)?;
        let t = &report["timings_s"];
        let part = |k: &str| t[k].as_f64().unwrap_or(f64::NAN);
        // Engine time: the report's total (reading, imaging, detector; the products are
        // written after it).
        engines.push(part("total"));
        // FFT bound, same transform code and precision, B forward + 1 inverse.
        let (one, bound) = if set.precision == "f64" {
            fft_bound::<f64>(ny, nx, active, 1)
        } else {
            fft_bound::<f32>(ny, nx, active, 1)
        };
        one_fft = one;
        bounds.push(bound);
        let (_, streamed) = if set.precision == "f64" {
            fft_bounds::<f64>(ny, nx, active, 1, true)
        } else {
            fft_bounds::<f32>(ny, nx, active, 1, true)
        };
        streams.push(streamed);
        // Baseline on the same file, right after.
        if run_baseline {
            let o = Command::new(&set.python)
                .arg(&script)
                .arg(&pj)
                .arg(case.join("cube.img"))
                .output()?;
            if o.status.success() {
                let v: serde_json::Value = serde_json::from_slice(&o.stdout)?;
                base_walls.push(v["wall_s"].as_f64().unwrap_or(f64::NAN));
                base_rsss.push(v["peak_rss_mib"].as_f64().unwrap_or(f64::NAN));
            } else {
                eprintln!("baseline failed: {}", String::from_utf8_lossy(&o.stderr));
            }
        }
    }
    // One transform against scipy.fft.rfft2 at the same size, both precisions.
    let (ours32, _) = fft_bound::<f32>(ny, nx, 1, 1);
    let (ours64, _) = fft_bound::<f64>(ny, nx, 1, 1);
    let (mut sp32, mut sp64) = (f64::NAN, f64::NAN);
    if !set.python.is_empty() {
        let o = Command::new(&set.python)
            .arg(&script)
            .args(["rfft2", &ny.to_string(), &nx.to_string(), "15"])
            .output()?;
        if o.status.success() {
            let v: serde_json::Value = serde_json::from_slice(&o.stdout)?;
            sp32 = v["f32"].as_f64().unwrap_or(f64::NAN);
            sp64 = v["f64"].as_f64().unwrap_or(f64::NAN);
        }
    }
    let _ = one_fft;
    // Engine/bound per repeat: each bound was measured right after its run.
    let paired = |b: &[f64]| -> Vec<f64> { engines.iter().zip(b).map(|(e, b)| e / b).collect() };
    let (in_cache, from_memory) = (paired(&bounds), paired(&streams));
    let (in_cache_median, from_memory_median) =
        (median(in_cache.clone()), median(from_memory.clone()));
    let range = |r: &[f64]| {
        let lo = r.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = r.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        format!("{lo:.2}–{hi:.2}")
    };
    let pairs: Vec<String> = engines
        .iter()
        .zip(&bounds)
        .zip(&streams)
        .map(|((e, b), s)| format!("{e:.3}/{b:.3}/{s:.3}"))
        .collect();
    eprintln!(
        "{n}² × {bands}: engine/bound/streamed bound per repeat (s) {}; engine/bound {} (median {:.2}), engine/streamed {} (median {:.2})",
        pairs.join(", "),
        range(&in_cache),
        in_cache_median,
        range(&from_memory),
        from_memory_median
    );
    let (wall, rss, engine, bound) = (median(walls), median(rsss), median(engines), median(bounds));
    let (bw, br) = (median(base_walls), median(base_rsss));
    let streamed = median(streams);
    let voxels = (n * n * bands) as f64;
    let row = format!(
        "| {n}² × {bands} ({}) | {nx} × {ny} | {active} | {wall:.2} | {:.1} | {rss:.0} | {engine:.2} | {bound:.2} | {:.2} | {streamed:.2} | {:.2} | {bw:.2} | {br:.0} | {:.1}× |",
        set.interleave,
        voxels / wall / 1e6,
        in_cache_median,
        from_memory_median,
        bw / wall
    );
    let fft_row = format!(
        "| {nx} × {ny} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} |",
        ours32 * 1e3,
        sp32 * 1e3,
        sp32 / ours32,
        ours64 * 1e3,
        sp64 * 1e3,
        sp64 / ours64
    );
    Ok((row, fft_row))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let env = |k: &str, d: &str| std::env::var(k).unwrap_or(d.into());
    let set = Settings {
        dir: PathBuf::from(env("EOIR_BENCH_DIR", "/tmp/eoir-bench")),
        python: env("EOIR_BENCH_PYTHON", "python3"),
        repeat: env("EOIR_BENCH_REPEAT", "3").parse()?,
        precision: env("EOIR_BENCH_PRECISION", "f32"),
        interleave: env("EOIR_BENCH_INTERLEAVE", "bsq"),
        baseline_max_voxels: env("EOIR_BENCH_BASELINE_MAX_VOXELS", "268435456").parse()?,
        recache: env("EOIR_BENCH_RECACHE", "1") != "0",
    };
    let cases: Vec<String> = std::env::args().skip(1).collect();
    let cases = if cases.is_empty() {
        vec!["1024:128".to_string()]
    } else {
        cases
    };
    println!(
        "rayon threads {}, precision {}, {} repeats (medians)",
        rayon::current_num_threads(),
        set.precision,
        set.repeat
    );
    println!("| scene × bands (layout) | padded frame | bands used | eoir wall (s) | Mvoxel/s | eoir peak RSS (MiB) | engine total (s) | FFT bound (s) | engine/FFT bound | FFT bound, streamed (s) | engine/streamed | SciPy wall (s) | SciPy peak RSS (MiB) | speed-up |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut fft_rows = Vec::new();
    for c in cases {
        let (n, b) = c.split_once(':').ok_or("cases are SIZE:BANDS")?;
        let (row, fft_row) = run(n.parse()?, b.parse()?, &set)?;
        println!("{row}");
        fft_rows.push(fft_row);
    }
    println!();
    println!("| frame | eoir f32 (ms) | rfft2 f32 (ms) | SciPy/eoir | eoir f64 (ms) | rfft2 f64 (ms) | SciPy/eoir |");
    println!("|---|---|---|---|---|---|---|");
    for r in fft_rows {
        println!("{r}");
    }
    Ok(())
}
