//! Per-transform benchmark (issue 9): the engine's real 2-D FFT (`RealFft2<T>::forward` and
//! `::inverse`) against `scipy.fft.rfft2` / `irfft2` at the same frame size and precision,
//! back to back, and a BENCHMARKS.md table of the medians.
//!
//! Fair by construction: the same input (`x[r, c] = (31 r + 17 c) mod 101`), the same
//! output layout (`[rows, cols/2 + 1]` complex, standard layout, as `rfft2` returns; the
//! inverse returns the `[rows, cols]` real frame, normalised, as `irfft2`), all workers on
//! both sides (rayon's pool; `workers=-1`), plans warmed on both sides before timing.
//! Each round times `EOIR_BENCH_REPEAT` transforms of each kind with eoir, then the same
//! with SciPy in a child Python; the medians are over all rounds, so both sides see the
//! same minute of machine load.
//!
//! `cargo run --release --example bench_fft -- [N ...]` (square frames; default
//! `576 1080 2160`, the padded frames of the 512²/1024²/2048² scenes at k = 3). Environment:
//! `EOIR_BENCH_PYTHON` (a Python with numpy and scipy; default `python3`; empty: eoir
//! only), `EOIR_BENCH_REPEAT` (transforms per round and kind, default 15), `EOIR_BENCH_ROUNDS`
//! (default 3), `EOIR_BENCH_PHASES=1` (also print where eoir's forward time goes: row pass,
//! in-place column pass).

mod bench_common;
use bench_common::median;
use std::process::Command;
use std::time::Instant;

use ndarray::Array2;
use num_complex::Complex;

use eoir::imaging::fft::{FftFloat, RealFft2};

/// The SciPy side: `python -c SCRIPT N REPEAT`, prints JSON lists of seconds per call.
const SCRIPT: &str = r#"
import json, sys, time
import numpy as np
import scipy.fft
n, rep = int(sys.argv[1]), int(sys.argv[2])
r = np.arange(n, dtype=np.int64)[:, None]
c = np.arange(n, dtype=np.int64)[None, :]
base = (31 * r + 17 * c) % 101
out = {}
for name, dt in (("f32", np.float32), ("f64", np.float64)):
    x = base.astype(dt)
    s = scipy.fft.rfft2(x, workers=-1)
    scipy.fft.irfft2(s, s=x.shape, workers=-1)
    for kind, f in (("fwd", lambda: scipy.fft.rfft2(x, workers=-1)),
                    ("inv", lambda: scipy.fft.irfft2(s, s=x.shape, workers=-1))):
        ts = []
        for _ in range(rep):
            t0 = time.perf_counter()
            f()
            ts.append(time.perf_counter() - t0)
        out[kind + name] = ts
print(json.dumps(out))
"#;

fn frame<T: FftFloat>(n: usize) -> Array2<T> {
    Array2::from_shape_fn((n, n), |(r, c)| {
        T::nearest_from_f64(((31 * r + 17 * c) % 101) as f64)
    })
}

/// Seconds of `rep` forward and `rep` inverse transforms (each timed alone).
fn eoir_times<T: FftFloat>(fft: &RealFft2<T>, rep: usize) -> (Vec<f64>, Vec<f64>) {
    let n = fft.shape().0;
    let mut x = frame::<T>(n);
    let mut spec = Array2::<Complex<T>>::zeros(fft.spectrum_shape());
    let mut scratch = Vec::new();
    fft.forward(&mut x, &mut spec, &mut scratch); // warm up
    let mut fwd = Vec::with_capacity(rep);
    for _ in 0..rep {
        let t = Instant::now();
        fft.forward(&mut x, &mut spec, &mut scratch);
        fwd.push(t.elapsed().as_secs_f64());
    }
    let mut out = Array2::<T>::zeros((n, n));
    let mut work = spec.clone();
    fft.inverse(&mut work, &mut out, &mut scratch); // warm up
    let mut inv = Vec::with_capacity(rep);
    for _ in 0..rep {
        work.assign(&spec); // inverse uses its input as scratch
        let t = Instant::now();
        fft.inverse(&mut work, &mut out, &mut scratch);
        inv.push(t.elapsed().as_secs_f64());
    }
    (fwd, inv)
}

/// Median seconds of the forward transform's two passes in `T`: the row pass
/// ([`RealFft2::rows_forward`]) and the in-place column pass ([`RealFft2::columns_in_place`]).
fn phases<T: FftFloat>(fft: &RealFft2<T>, rep: usize) -> [f64; 2] {
    let (rows, hc) = fft.spectrum_shape();
    let x = frame::<T>(rows);
    let mut spec = vec![Complex::new(T::zero(), T::zero()); rows * hc];
    let mut ts = [vec![], vec![]];
    for i in 0..=rep {
        let t0 = Instant::now();
        fft.rows_forward(
            |r, row| row.copy_from_slice(x.row(r).as_slice().expect("standard")),
            &mut spec,
        );
        let t1 = Instant::now();
        fft.columns_in_place(&mut spec, false);
        let t2 = Instant::now();
        if i > 0 {
            ts[0].push((t1 - t0).as_secs_f64());
            ts[1].push((t2 - t1).as_secs_f64());
        }
    }
    ts.map(median)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let env = |k: &str, d: &str| std::env::var(k).unwrap_or(d.into());
    let python = env("EOIR_BENCH_PYTHON", "python3");
    let rep: usize = env("EOIR_BENCH_REPEAT", "15").parse()?;
    let rounds: usize = env("EOIR_BENCH_ROUNDS", "3").parse()?;
    let show_phases = env("EOIR_BENCH_PHASES", "") == "1";
    let sizes: Vec<usize> = std::env::args()
        .skip(1)
        .map(|s| s.parse())
        .collect::<Result<_, _>>()?;
    let sizes = if sizes.is_empty() {
        vec![576, 1080, 2160]
    } else {
        sizes
    };
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "rayon threads {}, {rounds} rounds × {rep} transforms per kind (medians), load average {}",
        rayon::current_num_threads(),
        load.split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    );
    println!("| frame | eoir f32 (ms) | rfft2 f32 (ms) | SciPy/eoir | eoir f64 (ms) | rfft2 f64 (ms) | SciPy/eoir | eoir inverse f64 (ms) | irfft2 f64 (ms) | SciPy/eoir | eoir inverse f32 (ms) | irfft2 f32 (ms) | SciPy/eoir |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut phase_rows = Vec::new();
    for &n in &sizes {
        let f32fft = RealFft2::<f32>::new(n, n);
        let f64fft = RealFft2::<f64>::new(n, n);
        let mut ours: [Vec<f64>; 4] = Default::default();
        let mut theirs: [Vec<f64>; 4] = Default::default();
        for _ in 0..rounds {
            let (f, i) = eoir_times(&f32fft, rep);
            ours[0].extend(f);
            ours[2].extend(i);
            let (f, i) = eoir_times(&f64fft, rep);
            ours[1].extend(f);
            ours[3].extend(i);
            if python.is_empty() {
                continue;
            }
            let o = Command::new(&python)
                .args(["-c", SCRIPT, &n.to_string(), &rep.to_string()])
                .output()?;
            if !o.status.success() {
                return Err(
                    format!("SciPy side failed: {}", String::from_utf8_lossy(&o.stderr)).into(),
                );
            }
            let v: serde_json::Value = serde_json::from_slice(&o.stdout)?;
            for (k, key) in ["fwdf32", "fwdf64", "invf32", "invf64"].iter().enumerate() {
                if let Some(a) = v[key].as_array() {
                    theirs[k].extend(a.iter().filter_map(|x| x.as_f64()));
                }
            }
        }
        let o = ours.map(|v| median(v) * 1e3);
        let t = theirs.map(|v| median(v) * 1e3);
        println!(
            "| {n} × {n} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} |",
            o[0], t[0], t[0] / o[0],
            o[1], t[1], t[1] / o[1],
            o[3], t[3], t[3] / o[3],
            o[2], t[2], t[2] / o[2],
        );
        if show_phases {
            let p32 = phases(&f32fft, rep);
            let p64 = phases(&f64fft, rep);
            phase_rows.push(format!(
                "| {n} × {n} | {:.2} | {:.2} | {:.2} | {:.2} |",
                p32[0] * 1e3,
                p32[1] * 1e3,
                p64[0] * 1e3,
                p64[1] * 1e3,
            ));
        }
    }
    if show_phases {
        println!();
        println!("| frame | f32 row pass (ms) | f32 column pass (ms) | f64 row pass (ms) | f64 column pass (ms) |");
        println!("|---|---|---|---|---|");
        for r in phase_rows {
            println!("{r}");
        }
    }
    Ok(())
}
