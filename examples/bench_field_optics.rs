//! Space-variant wavefront benchmark (issue 36, "Speed"): the cost of a field-dependent
//! `[optics.wavefront]` run with K zones against the field-independent run, paired in one
//! process.
//!
//! One MWIR scene (`N² × B`, a smooth texture, 0.6 mrad samples, 3.5–4.9 µm) and one F/2
//! camera (25 mm, 15 µm pitch, detector `(N − 32)²` centred in the scene, no other
//! transfer-function component than its footprint), imaged in process by
//! `Imager::new` + `Imager::mean_electrons` as
//! - (a) the analytic engine without `[optics.wavefront]` (diffraction only),
//! - (b) **the field-independent run**: the same wavefront at every pixel (a field table
//!   whose rows all hold the corner's Seidel coefficients, so one zone, the same pupil
//!   sampling and wavelength nodes as (c)),
//! - (c) the field-dependent Seidel law (coma W131 and astigmatism W222 at the corner,
//!   spherical W040), zones chosen automatically for 1e-3 of the PSF peak,
//! - (d) the same with 2 × 2 and 3 × 3 zones forced,
//!
//! alternating the cases back to back `EOIR_BENCH_REPEAT` times (default 3). Prints, per
//! case, the median set-up time (`Imager::new`: pupil OTFs, zone choice), imaging time and
//! their sum, and the ratios (c)/(b) against the target (K + 1)·1.2, and (b)/(a).
//!
//! `cargo run --release --example bench_field_optics -- [SIZE:BANDS]` (default `256:16`);
//! `EOIR_BENCH_SEIDEL=w040,w131,w222` (waves at 4 µm, default `0.05,0.03,0.03`: under
//! 0.01 wave rms of coma and of astigmatism at the corner, for which the automatic choice
//! meets 1e-3 within its cap of 6 × 6 zones).

mod bench_common;
use bench_common::median;
use std::path::PathBuf;
use std::time::Instant;

use ndarray::Array3;

use eoir::imaging::{Imager, DEFAULT_WRAP_TOLERANCE};
use eoir::io::MemoryCube;
use eoir::scene::{Cube, CubeMeta, Geometry, RadianceUnits};
use eoir::sensor::{Sensor, SensorConfig};

/// Scene (and detector) sample, rad: 15 µm / 25 mm.
const IFOV_RAD: f64 = 6e-4;

/// Default Seidel coefficients at the corner, waves at 4 µm: spherical, coma,
/// astigmatism (`EOIR_BENCH_SEIDEL=w040,w131,w222` sets others).
const SEIDEL: [f64; 3] = [0.05, 0.03, 0.03];

fn sensor(det: usize, wavefront: Option<&str>) -> Sensor {
    let mut text = format!(
        r#"
name = "bench-field"
[optics]
focal_length_m = 0.025
f_number = 2.0
transmission = {{ kind = "constant", value = 0.9 }}
[filter]
kind = "top_hat"
lo_um = 3.6
hi_um = 4.8
edge_width_um = 0.05
peak = 0.85
[detector]
rows = {det}
cols = {det}
pitch_m = 15e-6
active_width_m = 14e-6
integration_time_s = 1e-3
quantum_efficiency = {{ kind = "ideal_qe", peak = 0.7, cutoff_um = 5.0 }}
"#
    );
    if let Some(w) = wavefront {
        text.push_str("[optics.wavefront]\nreference_wavelength_um = 4.0\n");
        text.push_str(w);
    }
    let c = SensorConfig::from_toml_str(&text, "bench", PathBuf::from("."), &[])
        .expect("the bench sensor parses");
    Sensor::build(&c).expect("the bench sensor builds")
}

fn scene(n: usize, bands: usize) -> Cube {
    let data = Array3::from_shape_fn((bands, n, n), |(b, r, c)| {
        let (r, c, b) = (r as f32, c as f32, b as f32);
        10.0 + 3.0 * (0.071 * r + 0.013 * c + 0.1 * b).cos()
            + 2.0 * (0.31 * c - 0.05 * r).cos() * (0.02 * b).sin()
            + ((r * 0.77 + c * 1.31).sin() * 43_758.547).fract()
    });
    let wavelength_um: Vec<f64> = (0..bands)
        .map(|i| 3.5 + 1.4 * i as f64 / (bands - 1) as f64)
        .collect();
    let meta = CubeMeta {
        wavelength_um,
        fwhm_um: None,
        units: RadianceUnits::SpectralPerUm,
        geometry: Some(Geometry::from_ifov(IFOV_RAD, IFOV_RAD, n, n)),
        rows: n,
        cols: n,
    };
    Cube::new(data, meta).expect("a valid cube")
}

struct Case {
    name: String,
    sensor: Sensor,
    setup: Vec<f64>,
    imaging: Vec<f64>,
    zones: usize,
    nodes: usize,
    samples: usize,
    choice: String,
    error: f64,
}

fn main() {
    let arg = std::env::args().nth(1).unwrap_or("256:16".into());
    let p: Vec<usize> = arg
        .split(':')
        .map(|v| v.parse().expect("SIZE:BANDS"))
        .collect();
    let (n, bands) = (p[0], p[1]);
    let repeat: usize = std::env::var("EOIR_BENCH_REPEAT")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3);
    let det = n - 32;
    let cube = scene(n, bands);
    let [w040, w131, w222] = std::env::var("EOIR_BENCH_SEIDEL")
        .ok()
        .map(|v| {
            let c: Vec<f64> = v
                .split(',')
                .map(|x| x.trim().parse().expect("EOIR_BENCH_SEIDEL=w040,w131,w222"))
                .collect();
            [c[0], c[1], c[2]]
        })
        .unwrap_or(SEIDEL);
    let seidel = format!("w040_waves = {w040}\nw131_waves = {w131}\nw222_waves = {w222}\n");
    let corner = format!(
        "field_dependence = \"table\"\n\
         [[optics.wavefront.field_point]]\nh = 0.0\n{seidel}\
         [[optics.wavefront.field_point]]\nh = 1.0\n{seidel}"
    );
    let mut cases: Vec<Case> = [
        ("(a) analytic, no wavefront", None),
        ("(b) field-independent wavefront", Some(corner)),
        ("(c) field-dependent, automatic K", Some(seidel.clone())),
        (
            "(d) field-dependent, 2 × 2",
            Some(format!("{seidel}zones_per_axis = 2\n")),
        ),
        (
            "(d) field-dependent, 3 × 3",
            Some(format!("{seidel}zones_per_axis = 3\n")),
        ),
    ]
    .into_iter()
    .map(|(name, w)| Case {
        name: name.to_string(),
        sensor: sensor(det, w.as_deref()),
        setup: Vec::new(),
        imaging: Vec::new(),
        zones: 0,
        nodes: 0,
        samples: 0,
        choice: String::new(),
        error: 0.0,
    })
    .collect();
    let meta = cube.meta.clone();
    let geometry = meta.geometry.expect("the scene has a geometry");
    let time = |c: &mut Case| {
        let t = Instant::now();
        let im = Imager::new(&c.sensor, &meta, &geometry, DEFAULT_WRAP_TOLERANCE)
            .expect("the imager builds");
        let setup = t.elapsed().as_secs_f64();
        let t = Instant::now();
        im.mean_electrons(&mut MemoryCube::new(cube.clone()), 0, |_, _| {})
            .expect("images");
        c.imaging.push(t.elapsed().as_secs_f64());
        c.setup.push(setup);
        if let Some(r) = im.wavefront_report() {
            c.zones = r.zones;
            c.nodes = r.wavelength_nodes;
            c.samples = r.pupil_samples_across;
            c.choice = r.zone_choice.clone();
            c.error = r.point_source_error_of_peak;
        } else {
            c.zones = 0;
        }
    };
    // Warm up (page faults, FFT plans) on the cheapest wavefront case.
    time(&mut cases[1]);
    cases[1].setup.clear();
    cases[1].imaging.clear();
    for _ in 0..repeat {
        for c in cases.iter_mut() {
            time(c);
        }
    }
    let total = |c: &Case| median(c.setup.iter().zip(&c.imaging).map(|(a, b)| a + b).collect());
    println!(
        "scene {n}² × {bands} bands, detector {det}², Seidel at the corner W040 {w040}, W131 {w131}, W222 {w222} waves at 4 µm; medians of {repeat}"
    );
    println!("| case | zones K | set-up (s) | imaging (s) | run (s) | run / (b) | imaging / (b) | target (K+1)·1.2 | point-source error of peak |");
    println!("|---|---|---|---|---|---|---|---|---|");
    let (b_run, b_img) = (total(&cases[1]), median(cases[1].imaging.clone()));
    for c in &cases {
        let run = total(c);
        let img = median(c.imaging.clone());
        let target = if c.zones > 1 {
            format!("{:.1}", (c.zones as f64 + 1.0) * 1.2)
        } else {
            "–".to_string()
        };
        println!(
            "| {} | {} | {:.3} | {:.3} | {run:.3} | {:.2} | {:.2} | {target} | {} |",
            c.name,
            if c.zones == 0 {
                "–".to_string()
            } else {
                c.zones.to_string()
            },
            median(c.setup.clone()),
            img,
            run / b_run,
            img / b_img,
            if c.zones == 0 {
                "–".to_string()
            } else {
                format!("{:.1e}", c.error)
            },
        );
    }
    let a_run = total(&cases[0]);
    println!(
        "(b)/(a): run {:.2}, imaging {:.2}; (c) zone choice: {}; wavelength nodes (b) {}, (c) {}; pupil samples across (c) {}",
        b_run / a_run,
        b_img / median(cases[0].imaging.clone()),
        cases[2].choice,
        cases[1].nodes,
        cases[2].nodes,
        cases[2].samples
    );
}
