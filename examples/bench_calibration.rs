//! Wall time of the calibration stage of a run, as `eoir demo` does it, without the
//! imaging around it.
//!
//! `cargo run --release --example bench_calibration -- [RUNS] [SENSOR]` (default 15 runs,
//! `multimir`, the demo's sensor: 384 × 288, filter 4, 100 mm optics). Each run calls
//! `pipeline::calibrate::calibrate_frames` — blackbody levels, NUC, bad pixels, lookup
//! tables, the residual non-uniformity check, one scene frame to radiance and
//! temperature, analytic and measured NETD — on one frame of a 270–330 K ramp exposed
//! through the same instance (seed 1), with the run's default calibration options. Prints
//! every run, the median and the load average (read from /proc/loadavg before and after);
//! figures go into BENCHMARKS.md, Calibration.

use std::time::Instant;

use ndarray::Array2;

use eoir::calibration::CalibrationOptions;
use eoir::pipeline::calibrate::{calibrate_frames, CalibrationOutcome};
use eoir::pipeline::expose::Exposure;
use eoir::pipeline::FrameProducts;
use eoir::sensor::{presets, Sensor};

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "?".to_string())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let runs: usize = args.first().map_or(Ok(15), |a| a.parse())?.max(1);
    let name = args.get(1).map_or("multimir", String::as_str);
    let sensor = Sensor::build(&presets::load(name, &[], &[])?)?;
    let (rows, cols) = (sensor.detector().rows(), sensor.detector().cols());
    // A left-to-right blackbody ramp, 270 → 330 K, through the camera equation.
    let camera = *sensor.camera();
    let column_e: Vec<f64> = (0..cols)
        .map(|c| {
            let t = 270.0 + 60.0 * c as f64 / (cols - 1).max(1) as f64;
            camera.electrons_blackbody(t, sensor.response())
        })
        .collect::<Result<_, _>>()?;
    let mean_e = Array2::from_shape_fn((rows, cols), |(_, c)| column_e[c]);
    let mut exposure = Exposure::new(&sensor, &mean_e, 1, 1)?;
    let dn = exposure.expose(&mean_e, 0)?;
    let options = CalibrationOptions::default();
    println!(
        "sensor {name}, {rows} x {cols}, {} threads, load average {}",
        rayon::current_num_threads(),
        load_average()
    );
    let mut times = Vec::with_capacity(runs);
    for run in 0..runs {
        let mut frames = vec![FrameProducts {
            electrons_mean: mean_e.mapv(|v| v as f32),
            dn: dn.clone(),
            rgb: None,
            radiance: None,
            temperature: None,
        }];
        let t0 = Instant::now();
        let outcome = calibrate_frames(&sensor, &exposure, Some(&options), &mut frames)?;
        let s = t0.elapsed().as_secs_f64();
        let CalibrationOutcome::Done(report) = outcome else {
            return Err(format!("calibration of {name} did not complete: {outcome:?}").into());
        };
        println!(
            "run {run:2}: {:7.2} ms  (NETD analytic {:.5} K, measured {:.5} K, {} bad pixels)",
            s * 1e3,
            report.netd_analytic_k_at_300k.unwrap_or(f64::NAN),
            report.netd_measured_k_at_300k.unwrap_or(f64::NAN),
            report.bad_pixels
        );
        times.push(s);
    }
    times.sort_by(f64::total_cmp);
    println!(
        "median {:.2} ms over {runs} runs (min {:.2} ms); load average after {}",
        times[runs / 2] * 1e3,
        times[0] * 1e3,
        load_average()
    );
    Ok(())
}
