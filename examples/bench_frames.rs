//! Sequences benchmark (issue 9, "frames in parallel where memory allows"): writes a
//! `[frame, band, row, col]` NPY sequence of the SWIR texture (every transfer-function
//! component on: benches/swir_all_components.toml, detector k = 3 × coarser than the scene)
//! and times `eoir run` on it as a child process with `--frames-in-flight 1` (one frame
//! after another, each frame's transforms on every thread) and `--frames-in-flight N`,
//! alternating the two back to back, and prints a BENCHMARKS.md table row per case: median
//! wall, CPU time (user + system) and peak RSS (`/usr/bin/time -v`), engine total
//! (`timings_s.total`), the ratio
//! sequential / parallel (the median of the back-to-back pairs' wall ratios, as the host's
//! load moves between pairs), and the load (`/proc/loadavg`) before and after.
//!
//! `cargo build --release && cargo run --release --example bench_frames -- [SIZE:BANDS:FRAMES ...]`
//! (default `256:32:16 512:32:16`). Environment: `EOIR_BENCH_DIR` (default
//! /tmp/eoir-bench-frames), `EOIR_BENCH_REPEAT` (runs per setting, default 5),
//! `EOIR_BENCH_IN_FLIGHT` (N, default the number of CPUs).

mod bench_common;
use bench_common::{median, peak_rss_mib, swir_sensor_config, time_v_field};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// Scene sampling, rad, and detector/scene ratio (as examples/bench_run.rs).
const SCENE_IFOV_RAD: f64 = 50e-6;
const K: usize = 3;

fn loadavg() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_default()
}

/// Writes an NPY v1.0 `<f4` array `[frames, bands, n, n]` frame by frame (a texture of
/// incommensurate cosines that moves by one sample per frame) and its JSON sidecar.
fn write_sequence(path: &Path, n: usize, bands: usize, frames: usize) -> std::io::Result<()> {
    let dict = format!(
        "{{'descr': '<f4', 'fortran_order': False, 'shape': ({frames}, {bands}, {n}, {n}), }}"
    );
    let pad = (64 - (10 + dict.len() + 1) % 64) % 64;
    let header = format!("{dict}{}\n", " ".repeat(pad));
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    w.write_all(b"\x93NUMPY\x01\x00")?;
    w.write_all(&(header.len() as u16).to_le_bytes())?;
    w.write_all(header.as_bytes())?;
    let mut plane = Vec::with_capacity(n * n * 4);
    for f in 0..frames {
        for b in 0..bands {
            plane.clear();
            for r in 0..n {
                for c in 0..n {
                    let (r, c, b) = (r as f32, (c + f) as f32, b as f32);
                    let v = 10.0
                        + 3.0 * (0.071 * r + 0.013 * c + 0.1 * b).cos()
                        + 2.0 * (0.31 * c - 0.05 * r).cos() * (0.02 * b).sin()
                        + ((r * 0.77 + c * 1.31).sin() * 43_758.547).fract();
                    plane.extend_from_slice(&v.to_le_bytes());
                }
            }
            w.write_all(&plane)?;
        }
    }
    w.flush()?;
    let wl: Vec<f64> = (0..bands)
        .map(|i| 0.95 + 0.8 * i as f64 / (bands - 1) as f64)
        .collect();
    let fov = (SCENE_IFOV_RAD * n as f64).to_degrees();
    let side = serde_json::json!({
        "wavelength_um": wl, "units": "W m-2 sr-1 um-1", "fov_deg": [fov, fov],
    });
    std::fs::write(path.with_extension("json"), side.to_string())
}

/// One run's figures: (wall s, peak RSS MiB, engine total s, CPU s, frames in flight).
type Run = (f64, f64, f64, f64, u64);

/// One `eoir run`: (wall s, peak RSS MiB, engine total s, CPU s (user + system), frames in
/// flight reported).
fn eoir_run(
    eoir: &Path,
    sensor: &Path,
    input: &Path,
    out: &Path,
    in_flight: usize,
) -> Result<Run, Box<dyn std::error::Error>> {
    let _ = std::fs::remove_dir_all(out);
    let t = Instant::now();
    let o = Command::new("/usr/bin/time")
        .arg("-v")
        .arg(eoir)
        .args([
            "run",
            "--quiet",
            "--frames-in-flight",
            &in_flight.to_string(),
        ])
        .arg("--sensor")
        .arg(sensor)
        .arg(input)
        .arg("-o")
        .arg(out)
        .output()?;
    let wall = t.elapsed().as_secs_f64();
    let err = String::from_utf8_lossy(&o.stderr);
    if !o.status.success() {
        return Err(format!("eoir run failed: {err}").into());
    }
    let field = |key: &str| time_v_field(&err, key);
    let rss = peak_rss_mib(&err);
    let cpu = field("User time (seconds): ") + field("System time (seconds): ");
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json"))?)?;
    let engine = report["timings_s"]["total"].as_f64().unwrap_or(f64::NAN);
    let k = report["execution"]["frames_in_flight"]
        .as_u64()
        .unwrap_or(0);
    Ok((wall, rss, engine, cpu, k))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let env = |k: &str, d: &str| std::env::var(k).unwrap_or(d.into());
    let dir = PathBuf::from(env("EOIR_BENCH_DIR", "/tmp/eoir-bench-frames"));
    let repeat: usize = env("EOIR_BENCH_REPEAT", "5").parse()?;
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    let n_flight: usize = env("EOIR_BENCH_IN_FLIGHT", &cpus.to_string()).parse()?;
    let cases: Vec<String> = std::env::args().skip(1).collect();
    let cases = if cases.is_empty() {
        vec!["256:32:16".to_string(), "512:32:16".to_string()]
    } else {
        cases
    };
    let exe = std::env::current_exe()?;
    let eoir = exe
        .parent()
        .and_then(|p| p.parent())
        .map(|p| p.join("eoir"))
        .ok_or("no eoir binary")?;
    println!("{cpus} CPUs, {repeat} repeats per setting (medians), 1 vs {n_flight} frames in flight, alternating");
    println!("| scene × bands × frames | load before | 1 in flight: wall (s) | engine (s) | CPU (s) | peak RSS (MiB) | {n_flight} in flight: wall (s) | engine (s) | CPU (s) | peak RSS (MiB) | wall 1 / wall {n_flight} | load after |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    for c in cases {
        let p: Vec<usize> = c.split(':').map(|v| v.parse()).collect::<Result<_, _>>()?;
        let [n, bands, frames] = p[..] else {
            return Err("cases are SIZE:BANDS:FRAMES".into());
        };
        let case = dir.join(format!("{n}x{bands}x{frames}"));
        std::fs::create_dir_all(&case)?;
        let det = n / K;
        let config = swir_sensor_config(det)?;
        let sensor = case.join("sensor.toml");
        std::fs::write(&sensor, config.to_toml_string()?)?;
        let input = case.join("seq.npy");
        if !input.exists() {
            write_sequence(&input, n, bands, frames)?;
        }
        let load_before = loadavg();
        let out = case.join("out");
        // Warm the page cache and the binary.
        eoir_run(&eoir, &sensor, &input, &out, 1)?;
        let (mut one, mut many) = (Vec::new(), Vec::new());
        for _ in 0..repeat {
            one.push(eoir_run(&eoir, &sensor, &input, &out, 1)?);
            many.push(eoir_run(&eoir, &sensor, &input, &out, n_flight)?);
        }
        let k = many.iter().map(|r| r.4).max().unwrap_or(0);
        let col = |v: &[Run], i: usize| {
            median(
                v.iter()
                    .map(|r| [r.0, r.1, r.2, r.3][i])
                    .collect::<Vec<f64>>(),
            )
        };
        println!(
            "| {n}² × {bands} × {frames} | {load_before} | {:.2} | {:.2} | {:.2} | {:.0} | {:.2} | {:.2} | {:.2} | {:.0} | {:.2} (k = {k}) | {} |",
            col(&one, 0),
            col(&one, 2),
            col(&one, 3),
            col(&one, 1),
            col(&many, 0),
            col(&many, 2),
            col(&many, 3),
            col(&many, 1),
            median(one.iter().zip(&many).map(|(a, b)| a.0 / b.0).collect()),
            loadavg()
        );
    }
    Ok(())
}
