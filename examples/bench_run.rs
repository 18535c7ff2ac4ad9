//! End-to-end benchmark: writes SWIR texture cubes to ENVI, times `eoir run` on them (wall,
//! Mvoxel/s, peak RSS from `/usr/bin/time -v`), the FFT bound (B forward + 1 inverse real
//! 2-D FFTs of the padded frame with the engine's own transform code) and the NumPy/SciPy
//! script `benches/baseline.py` on the same files, and prints BENCHMARKS.md table rows.
//!
//! `cargo build --release && cargo run --release --example bench_run -- [SIZE:BANDS ...]`
//! (default `1024:128`). Environment: `EOIR_BENCH_DIR` (default /tmp/eoir-bench),
//! `EOIR_BENCH_PYTHON` (a Python with numpy and scipy; default `python3`; empty: skip).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use ndarray::{Array2, Array3};
use num_complex::Complex64;

use eoir::imaging::fft::RealFft2;
use eoir::imaging::{Imager, DEFAULT_WRAP_TOLERANCE};
use eoir::scene::{Cube, CubeMeta, Geometry, RadianceUnits};
use eoir::sensor::{Sensor, SensorConfig};

/// Scene sampling, rad, and detector/scene ratio.
const SCENE_IFOV_RAD: f64 = 50e-6;
const K: usize = 3;

fn sensor_toml(det: usize) -> String {
    format!(
        r#"
name = "bench-swir"
[optics]
focal_length_m = 0.1
f_number = 2.0
obscuration_ratio = 0.3
[filter]
kind = "top_hat"
lo_um = 1.0
hi_um = 1.7
[detector]
rows = {det}
cols = {det}
pitch_m = 15e-6
active_width_m = 14e-6
integration_time_s = 1e-3
quantum_efficiency = {{ kind = "ideal_qe", peak = 0.8, cutoff_um = 1.7 }}
[aberration]
rms_waves = 0.05
[defocus]
w020_waves = 0.3
[motion]
smear_rad = 60e-6
direction_deg = 30
[jitter]
sigma_rad = 10e-6
[turbulence]
path = "horizontal"
cn2 = 1e-15
range_m = 2000
[aerosol]
absorption_per_m = 1e-5
scattering_per_m = 2e-5
range_m = 2000
particle_radius_m = 1e-6
[gaussian]
sigma_rad = 5e-6
"#
    )
}

fn run(
    n: usize,
    bands: usize,
    dir: &Path,
    python: &str,
) -> Result<String, Box<dyn std::error::Error>> {
    let det = n / K;
    let case = dir.join(format!("{n}x{bands}"));
    std::fs::create_dir_all(&case)?;
    let sensor_path = case.join("sensor.toml");
    std::fs::write(&sensor_path, sensor_toml(det))?;
    let wl: Vec<f64> = (0..bands)
        .map(|i| 0.95 + 0.8 * i as f64 / (bands - 1) as f64)
        .collect();
    let meta = CubeMeta {
        wavelength_um: wl.clone(),
        fwhm_um: None,
        units: RadianceUnits::SpectralPerUm,
        geometry: Some(Geometry::from_ifov(SCENE_IFOV_RAD, SCENE_IFOV_RAD, n, n)),
        rows: n,
        cols: n,
    };
    let hdr = case.join("cube.hdr");
    if !hdr.exists() {
        // A texture: sums of incommensurate cosines, different per band.
        let data = Array3::from_shape_fn((bands, n, n), |(b, r, c)| {
            let (r, c, b) = (r as f32, c as f32, b as f32);
            10.0 + 3.0 * (0.071 * r + 0.013 * c + 0.1 * b).cos()
                + 2.0 * (0.31 * c - 0.05 * r).cos() * (0.02 * b).sin()
                + ((r * 0.77 + c * 1.31).sin() * 43_758.547).fract()
        });
        eoir::io::envi::write(&hdr, &Cube::new(data, meta.clone())?)?;
    }
    // The engine's padded frame and spectral weights.
    let config = SensorConfig::from_toml_str(&sensor_toml(det), "bench", PathBuf::from("."), &[])?;
    let sensor = Sensor::build(&config)?;
    let imager = Imager::new(
        &sensor,
        &meta,
        &meta.geometry.unwrap(),
        DEFAULT_WRAP_TOLERANCE,
    )?;
    let s = imager.sampling();
    let (ny, nx) = (s.y.padded_len, s.x.padded_len);
    // FFT bound, same transform code, B forward + 1 inverse.
    let fft = RealFft2::new(ny, nx);
    let frame = Array2::from_shape_fn((ny, nx), |(r, c)| ((r * 31 + c * 17) % 101) as f64);
    let mut spec = Array2::<Complex64>::zeros(fft.spectrum_shape());
    let mut scratch = Vec::new();
    let mut out = Array2::<f64>::zeros((ny, nx));
    let active = imager.weights().active_bands().len();
    let t = Instant::now();
    for _ in 0..active {
        fft.forward_rows(
            |r, row| row.copy_from_slice(frame.row(r).as_slice().unwrap()),
            &mut spec,
            &mut scratch,
        );
    }
    fft.inverse(&mut spec, &mut out, &mut scratch);
    let fft_bound = t.elapsed().as_secs_f64();
    // eoir run end to end, as a child under /usr/bin/time -v.
    let exe = std::env::current_exe()?;
    let eoir = exe
        .parent()
        .and_then(|p| p.parent())
        .map(|p| p.join("eoir"))
        .ok_or("no eoir binary")?;
    let outdir = case.join("out");
    let _ = std::fs::remove_dir_all(&outdir);
    let t = Instant::now();
    let o = Command::new("/usr/bin/time")
        .arg("-v")
        .arg(&eoir)
        .args(["run", "--quiet", "--sensor"])
        .arg(&sensor_path)
        .arg(&hdr)
        .arg("-o")
        .arg(&outdir)
        .output()?;
    let wall = t.elapsed().as_secs_f64();
    let err = String::from_utf8_lossy(&o.stderr);
    if !o.status.success() {
        return Err(format!("eoir run failed: {err}").into());
    }
    let rss_mib = err
        .lines()
        .find_map(|l| {
            l.trim()
                .strip_prefix("Maximum resident set size (kbytes): ")
        })
        .and_then(|v| v.trim().parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0);
    let voxels = (n * n * bands) as f64;
    // Baseline on the same file.
    let (mut base_wall, mut base_rss) = (f64::NAN, f64::NAN);
    if !python.is_empty() {
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
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/baseline.py");
        let o = Command::new(python)
            .arg(script)
            .arg(&pj)
            .arg(case.join("cube.img"))
            .output()?;
        if o.status.success() {
            let v: serde_json::Value = serde_json::from_slice(&o.stdout)?;
            base_wall = v["wall_s"].as_f64().unwrap_or(f64::NAN);
            base_rss = v["peak_rss_mib"].as_f64().unwrap_or(f64::NAN);
        } else {
            eprintln!("baseline failed: {}", String::from_utf8_lossy(&o.stderr));
        }
    }
    Ok(format!(
        "| {n}² × {bands} | {nx} × {ny} | {wall:.2} | {:.1} | {rss_mib:.0} | {fft_bound:.2} | {:.2} | {base_wall:.2} | {base_rss:.0} | {:.1}× |",
        voxels / wall / 1e6,
        wall / fft_bound,
        base_wall / wall
    ))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = PathBuf::from(std::env::var("EOIR_BENCH_DIR").unwrap_or("/tmp/eoir-bench".into()));
    let python = std::env::var("EOIR_BENCH_PYTHON").unwrap_or("python3".into());
    let cases: Vec<String> = std::env::args().skip(1).collect();
    let cases = if cases.is_empty() {
        vec!["1024:128".to_string()]
    } else {
        cases
    };
    println!("| scene × bands | padded frame | eoir wall (s) | Mvoxel/s | eoir peak RSS (MiB) | FFT bound (s) | engine/FFT bound | SciPy wall (s) | SciPy peak RSS (MiB) | speed-up |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for c in cases {
        let (n, b) = c.split_once(':').ok_or("cases are SIZE:BANDS")?;
        println!("{}", run(n.parse()?, b.parse()?, &dir, &python)?);
    }
    Ok(())
}
