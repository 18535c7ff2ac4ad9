//! The zones' tables and taps against their own pupil computations.

use super::*;
use crate::imaging::DEFAULT_WRAP_TOLERANCE;
use crate::scene::{CubeMeta, Geometry, RadianceUnits};
use crate::sensor::SensorConfig;

/// A 40 × 40 F/2 MWIR camera (25 mm, 15 µm: the frame reaches a third of the pupil
/// cutoff, so the tables are cropped) with coma and astigmatism over 2 × 2 zones.
fn imager() -> (Imager, CubeMeta) {
    let text = r#"
name = "lookup"
[optics]
focal_length_m = 0.025
f_number = 2.0
[filter]
kind = "top_hat"
lo_um = 3.6
hi_um = 4.8
[detector]
rows = 40
cols = 40
pitch_m = 15e-6
active_width_m = 14e-6
integration_time_s = 1e-3
quantum_efficiency = { kind = "ideal_qe", peak = 0.7, cutoff_um = 5.0 }
[optics.wavefront]
reference_wavelength_um = 4.0
w131_waves = 0.3
w222_waves = 0.3
zones_per_axis = 2
pupil_samples_across = 64
"#;
    let c = SensorConfig::from_toml_str(text, "test", ".".into(), &[]).unwrap();
    let sensor = Sensor::build(&c).unwrap();
    let meta = CubeMeta {
        wavelength_um: vec![3.5, 4.0, 4.4, 4.9],
        fwhm_um: None,
        units: RadianceUnits::SpectralPerUm,
        geometry: Some(Geometry::from_ifov(6e-4, 6e-4, 48, 48)),
        rows: 48,
        cols: 48,
    };
    let im = Imager::new(
        &sensor,
        &meta,
        &meta.geometry.unwrap(),
        DEFAULT_WRAP_TOLERANCE,
    )
    .unwrap();
    (im, meta)
}

/// The zones' image (separable row passes, per-band taps, rows in parallel) is the
/// same to the bit on 1 and 3 worker threads.
#[test]
fn zones_give_the_same_bits_for_any_number_of_threads() {
    let (im, meta) = imager();
    let data = ndarray::Array3::from_shape_fn((4, 48, 48), |(b, r, c)| {
        let (r, c, b) = (r as f32, c as f32, b as f32);
        let point = if r == 20.0 && c == 30.0 { 500.0 } else { 0.0 };
        10.0 + 3.0 * (0.31 * r + 0.17 * c + b).cos() + point
    });
    let cube = crate::scene::Cube::new(data, meta).unwrap();
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let mut reader = crate::io::MemoryCube::new(cube.clone());
                im.mean_electrons(&mut reader, 0, |_, _| {}).unwrap().0
            })
    };
    let one = run(1);
    assert!(one.sum() > 0.0);
    assert_eq!(one, run(3));
}

/// The cropped tables hold the pupil OTF at every frequency of the frame: each zone's
/// table at each wavelength node (three of the four mirror images of the first)
/// equals the bilinear interpolation of the full pupil OTF grid of the zone's own
/// wavefront ([`PupilTransfer::at_cy_per_rad`], f64) within f32 rounding, and the
/// per-band taps give [`FieldOptics::otf_at`] (the per-sample lookup) to the bit.
#[test]
fn cropped_tables_and_band_taps_are_the_pupil_otf() {
    let (im, _) = imager();
    let field = im.field.as_ref().unwrap();
    let g = field.per_axis;
    assert_eq!(g, 2);
    // One zone computed, three mirrored: the comparison below checks the mirrors.
    assert_eq!(field.computed_zones, 1);
    let w = field.window;
    assert!(w.width < w.cols && w.rows < w.m / 2, "{w:?}");
    let (fx, fy) = (&im.grid.fx, &im.grid.fy);
    let reference_m = field.model.reference_wavelength_m();
    let mut largest = 0.0f64;
    for k in 0..g * g {
        let (row, col) = (
            field.frame.node(0, (k / g) as f64, g),
            field.frame.node(1, (k % g) as f64, g),
        );
        let (h, az) = field.frame.field_point(row, col);
        let (turning, fixed) = field.wavefront_at(h);
        for (j, s) in field.node_scale.iter().enumerate() {
            let lambda_m = reference_m / s;
            let t = PupilTransfer::compute_at_azimuth(
                &field.pupil,
                &turning,
                &fixed,
                az,
                reference_m,
                lambda_m,
                field.diameter_m,
                Sampling {
                    samples_across: field.report.pupil_samples_across,
                    padding: 2,
                },
            )
            .unwrap();
            for &y in fy {
                for &x in fx {
                    let want = t.at_cy_per_rad(x, y);
                    let got = field.otf_at(k, (j, 0.0), x, y, lambda_m * 1e6);
                    assert!((got - want).norm() <= 1e-6, "{k} {j} {x} {y}: {got} {want}");
                    largest = largest.max(want.norm().min(1.0 - want.norm()));
                }
            }
        }
    }
    // The frame reaches well into the OTF (not only its DC peak or zeros).
    assert!(largest > 0.3, "{largest}");
    for &lambda in &im.weights.wavelength_um {
        let node = field.node_of(lambda);
        let taps = field.band_taps(fx, fy, lambda);
        for k in 0..g * g {
            for (v, &y) in fy.iter().enumerate() {
                for (u, &x) in fx.iter().enumerate() {
                    let want = field.otf_at(k, node, x, y, lambda);
                    let got = match (taps.rows[v], taps.cols[u]) {
                        (Some(r), Some(c)) => field.tapped(k, node, r, c),
                        _ => Complex64::new(0.0, 0.0),
                    };
                    assert_eq!(got, want, "{lambda} {k} {u} {v}");
                }
            }
        }
    }
}
