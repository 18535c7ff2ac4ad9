//! Tabulated transfer functions (imaging::otf_table) against direct evaluation of every
//! component, the aperture cutoff with diffraction off, and thread-count independence of
//! the imaging engine.

use std::path::PathBuf;

use ndarray::Array3;

use eoir::imaging::otf_table::{RadialTables, TABLE_TOLERANCE};
use eoir::imaging::{Imager, DEFAULT_WRAP_TOLERANCE};
use eoir::io::MemoryCube;
use eoir::scene::{Cube, CubeMeta, Geometry, RadianceUnits};
use eoir::sensor::{Component, Sensor, SensorConfig, SystemOtf};

const BASE: &str = r#"
name = "t"
[optics]
focal_length_m = 0.1
f_number = 2.0
[filter]
kind = "top_hat"
lo_um = 3.0
hi_um = 5.0
[detector]
rows = 24
cols = 30
pitch_m = 24e-6
active_width_m = 20e-6
integration_time_s = 1e-3
quantum_efficiency = { kind = "ideal_qe", peak = 0.7, cutoff_um = 5.2 }
"#;

fn sensor(overrides: &[&str]) -> SensorConfig {
    let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    SensorConfig::from_toml_str(BASE, "test.toml", PathBuf::from("."), &o).unwrap()
}

/// Every chromatic component in some combination, both defocus forms, both turbulence
/// paths, aerosol plain and DC-normalised, diffraction on and off.
fn cases() -> Vec<Vec<&'static str>> {
    vec![
        vec![
            "optics.obscuration_ratio=0.3",
            "aberration.rms_waves=0.05",
            "defocus.w020_waves=0.6",
        ],
        vec![
            "defocus.focus_shift_m=6e-5",
            "turbulence.path=\"horizontal\"",
            "turbulence.cn2=5e-14",
            "turbulence.range_m=3000",
            "aerosol.absorption_per_m=1e-4",
            "aerosol.scattering_per_m=2e-4",
            "aerosol.range_m=3000",
            "aerosol.particle_radius_m=2e-6",
        ],
        vec![
            "diffraction.enabled=false",
            "defocus.w020_waves=1.5",
            "turbulence.path=\"slant\"",
            "turbulence.cn2_at_1m=1e-13",
            "turbulence.sensor_height_m=2",
            "turbulence.target_height_m=300",
            "turbulence.range_m=5000",
            "aerosol.absorption_per_m=5e-5",
            "aerosol.scattering_per_m=3e-4",
            "aerosol.range_m=5000",
            "aerosol.particle_radius_m=1e-6",
            "aerosol.dc_normalised=true",
        ],
        vec![
            "optics.obscuration_ratio=0.5",
            "aberration.rms_waves=0.1",
            "defocus.focus_shift_m=-3e-5",
            "turbulence.path=\"horizontal\"",
            "turbulence.cn2=1e-13",
            "turbulence.range_m=2000",
            "aerosol.absorption_per_m=1e-4",
            "aerosol.scattering_per_m=1e-4",
            "aerosol.range_m=2000",
            "aerosol.particle_radius_m=3e-6",
        ],
    ]
}

/// The product of the chromatic components, evaluated directly (radial: fy = 0).
fn direct_chromatic(otf: &SystemOtf, rho: f64, lambda_um: f64) -> f64 {
    otf.components()
        .iter()
        .filter(|c| c.is_chromatic())
        .map(|c| otf.component(*c, rho, 0.0, lambda_um))
        .product()
}

/// Tables built once for 3–5 µm, per-band profiles at 9 wavelengths across (and at the
/// ends of) the range, 40 001 radial frequencies from 0 to 1.3× the cutoff at the shortest
/// wavelength (dense through every kink, the cutoff and the plateau): |table − direct| ≤ 1e-6.
/// Also for tables covering only part of those frequencies (`RadialTables::covering`, a
/// shorter turbulence table): beyond it the turbulence is evaluated directly.
#[test]
fn tabulated_profiles_match_direct_evaluation_for_every_component() {
    let (lo, hi) = (3.0, 5.0);
    let mut worst_overall: f64 = 0.0;
    for (case, cover) in cases()
        .into_iter()
        .flat_map(|c| [(c.clone(), None), (c.clone(), Some(0.3)), (c, Some(1.0))])
    {
        let s = sensor(&case);
        let otf = Sensor::build(&s).unwrap().otf().clone();
        assert!(otf.components().iter().any(|c| c.is_chromatic()));
        let rho_max = 1.3 * otf.cutoff_cy_per_rad(lo);
        let tables = match cover {
            None => RadialTables::new(&otf, lo, hi),
            Some(f) => {
                let t = RadialTables::covering(&otf, lo, hi, f * rho_max);
                // The table covering fewer frequencies is shorter (it is the same
                // function on a shorter range).
                let full = RadialTables::new(&otf, lo, hi);
                if let (Some(part), Some(full)) = (&t.turbulence, &full.turbulence) {
                    assert!(
                        part.len() < full.len(),
                        "{case:?}: {} vs {}",
                        part.len(),
                        full.len()
                    );
                }
                t
            }
        };
        let mut worst: f64 = 0.0;
        for i in 0..9 {
            let lambda = lo + (hi - lo) * i as f64 / 8.0;
            let profile = tables.band_profile(&otf, lambda, rho_max);
            let n = 40_000;
            // Dense over the whole range, then through the aerosol core (ρ < a/λ, about
            // one cycle/rad) and the start of every curve near ρ = 0.
            let rhos = (0..=n)
                .map(|j| rho_max * ((j as f64 + 0.377_1) / (n as f64 + 1.0)))
                .chain((0..=4000).map(|j| 10.0 * (j as f64 + 0.377_1) / 4001.0));
            for rho in rhos {
                // An irrational offset so that samples do not sit on table nodes.
                let err = (profile.eval(rho) - direct_chromatic(&otf, rho, lambda)).abs();
                worst = worst.max(err);
                assert!(
                    err <= TABLE_TOLERANCE,
                    "{case:?} λ {lambda} ρ {rho}: error {err:e}"
                );
            }
        }
        println!("{case:?} (covering {cover:?}): max |table − direct| = {worst:.2e}");
        worst_overall = worst_overall.max(worst);
    }
    // The tables are not trivially exact either (the check above can fail).
    assert!(worst_overall > 0.0);
}

/// The engine interpolates the 4 bands of a chunk from ONE common ρ grid
/// (`RadialTables::chunk_profile`): every band of a chunk matches its direct evaluation to
/// 1e-6 (for each component case, chunks spanning the range, bands with different cutoffs,
/// through the aerosol cores),
/// and beyond each band's own aperture cutoff its value is exactly 0 (with an aperture
/// term).
#[test]
fn chunk_profiles_match_direct_evaluation_for_every_band() {
    let (lo, hi) = (3.0, 5.0);
    for case in cases() {
        let s = sensor(&case);
        let otf = Sensor::build(&s).unwrap().otf().clone();
        let tables = RadialTables::new(&otf, lo, hi);
        let rho_max = 1.3 * otf.cutoff_cy_per_rad(lo);
        for chunk in [[3.0, 3.1, 3.2, 3.3], [3.0, 3.7, 4.4, 5.0]] {
            let p = tables.chunk_profile(&otf, &chunk, rho_max);
            assert_eq!(p.bands(), 4);
            let n = 20_000;
            // Dense over the whole range, then through the aerosol cores (ρ < a/λ, below
            // one cycle/rad, where some lanes are past their aerosol table and some not).
            let rhos = (0..=n)
                .map(|j| rho_max * ((j as f64 + 0.377_1) / (n as f64 + 1.0)))
                .chain((0..=4000).map(|j| 10.0 * (j as f64 + 0.377_1) / 4001.0));
            for rho in rhos {
                let mut all = [0.0; 4];
                p.eval_all(rho, &mut all);
                for (c, lambda) in chunk.iter().enumerate() {
                    let err = (all[c] - direct_chromatic(&otf, rho, *lambda)).abs();
                    assert!(
                        err <= TABLE_TOLERANCE,
                        "{case:?} chunk {chunk:?} λ {lambda} ρ {rho}: error {err:e}"
                    );
                    // Zero beyond the cutoff when an aperture term bounds the band
                    // (defocus alone is the geometric blur disc, with no cutoff).
                    if otf.defocus_bounded() && rho > otf.cutoff_cy_per_rad(*lambda) {
                        assert_eq!(all[c], 0.0, "{case:?} λ {lambda} beyond its cutoff");
                    }
                }
            }
        }
    }
}

fn cube(bands: usize, rows: usize, cols: usize, ifov_rad: f64) -> Cube {
    let wl: Vec<f64> = (0..bands)
        .map(|i| 2.9 + 2.3 * i as f64 / (bands - 1) as f64)
        .collect();
    let data = Array3::from_shape_fn((bands, rows, cols), |(b, r, c)| {
        (1.0 + 0.5 * ((r * 7 + c * 13 + 3 * b) % 17) as f64 / 17.0 + 0.01 * b as f64) as f32
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

/// The OTF the engine applies on its FFT grid (achromatic product × tabulated profile)
/// equals the cascade evaluated directly at every frequency sample, with every component
/// on (achromatic ones included), times the scene-grid taper, to 1e-6.
#[test]
fn engine_grid_otf_matches_direct_cascade() {
    let mut o = cases()[3].clone();
    o.extend([
        "motion.smear_rad=3e-5",
        "motion.direction_deg=30",
        "jitter.sigma_rad=1e-5",
        "gaussian.sigma_rad=5e-6",
    ]);
    let s = sensor(&o);
    // k = 3 scene samples per detector pixel.
    let c = cube(12, 72, 90, s.ifov_rad() / 3.0);
    let resolved = eoir::sensor::Sensor::build(&s).unwrap();
    let imager = Imager::new(&resolved, &c.meta, &c.meta.geometry.unwrap(), 1e-4).unwrap();
    let otf = imager.otf();
    assert_eq!(otf.components().len(), 9);
    let grid = imager.frequency_grid().clone();
    let mut worst: f64 = 0.0;
    for lambda in [3.0, 3.77, 4.6, 5.0] {
        let t = imager.tabulated_otf(lambda);
        for (j, fy) in grid.fy.iter().enumerate() {
            for (k, fx) in grid.fx.iter().enumerate() {
                // Times the engine's taper at the scene grid's Nyquist circle, when the
                // optics pass more than the grid holds (imaging::scene_band).
                let taper = imager.grid_taper().map_or(1.0, |t| t.factor(fx.hypot(*fy)));
                let err = (t[[j, k]] - otf.evaluate(*fx, *fy, lambda) * taper).abs();
                worst = worst.max(err);
                assert!(err <= TABLE_TOLERANCE, "λ {lambda} ({j},{k}): {err:e}");
            }
        }
    }
    println!("grid: max |table − direct| = {worst:.2e}");
}

/// Audit fix: aberration without diffraction passes nothing beyond the aperture cutoff
/// D/λ (it used to pass 0.10 at 1.2× the cutoff), directly and tabulated; inside the
/// cutoff the factor alone is (close to) 1 at the cutoff itself. Defocus without an
/// aperture term is instead the geometric blur disc (issue 38: a physical roll-off, not a
/// brick wall at D/λ): `2J1(8πW020 X)/(8πW020 X)` beyond the cutoff too, directly and
/// tabulated (within the table tolerance), and continuous through X = 1.
#[test]
fn no_aperture_term_passes_beyond_the_cutoff() {
    for o in [
        vec!["diffraction.enabled=false", "defocus.w020_waves=0.8"],
        vec!["diffraction.enabled=false", "defocus.focus_shift_m=5e-5"],
        vec!["diffraction.enabled=false", "aberration.rms_waves=0.07"],
    ] {
        let s = sensor(&o);
        let otf = Sensor::build(&s).unwrap().otf().clone();
        assert!(!otf.components().contains(&Component::Diffraction));
        let geometric = otf.components().contains(&Component::Defocus);
        let tables = RadialTables::new(&otf, 3.0, 5.0);
        for lambda in [3.0, 4.0, 5.0] {
            let fc = otf.cutoff_cy_per_rad(lambda);
            let profile = tables.band_profile(&otf, lambda, 2.0 * fc);
            for m in [0.3, 0.9999, 1.0001, 1.05, 1.2, 1.5, 1.99] {
                if geometric {
                    let w = otf.defocus_w020_waves(lambda).unwrap();
                    let want = eoir::optics::defocus_geometric(m, w);
                    let got = otf.component(Component::Defocus, m * fc, 0.0, lambda);
                    assert!((got - want).abs() < 1e-12, "{o:?} {m}: {got} vs {want}");
                    let tab = profile.eval(m * fc);
                    assert!(
                        (tab - want).abs() <= TABLE_TOLERANCE,
                        "{o:?} tabulated at {m}× cutoff: {tab} vs {want}"
                    );
                } else if m > 1.0 {
                    for c in otf.components().iter().filter(|c| c.is_chromatic()) {
                        assert_eq!(
                            otf.component(*c, m * fc, 0.0, lambda),
                            0.0,
                            "{o:?} {c:?} {m}"
                        );
                    }
                    assert_eq!(otf.evaluate(m * fc * 0.6, m * fc * 0.8, lambda), 0.0);
                    assert_eq!(profile.eval(m * fc), 0.0, "{o:?} tabulated at {m}× cutoff");
                }
            }
            if !geometric {
                // Just inside, the factor is (close to) 1 for aberration.
                let inside = direct_chromatic(&otf, 0.9999 * fc, lambda);
                assert!((inside - 1.0).abs() < 1e-2, "{o:?}: {inside}");
            }
        }
    }
}

/// Imaging on a 1-thread and a 2-thread pool gives bit-identical electrons (every sample
/// of the accumulation and of the FFTs is computed the same way whatever the split).
#[test]
fn one_and_two_threads_give_identical_output() {
    let s = sensor(&cases()[3]);
    let c = cube(9, 75, 93, s.ifov_rad() / 3.0);
    let resolved = eoir::sensor::Sensor::build(&s).unwrap();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let imager = Imager::new(
                &resolved,
                &c.meta,
                &c.meta.geometry.unwrap(),
                DEFAULT_WRAP_TOLERANCE,
            )
            .unwrap();
            let mut reader = MemoryCube::new(c.clone());
            imager.mean_electrons(&mut reader, 0, |_, _| {}).unwrap().0
        })
    };
    let one = run(1);
    let two = run(2);
    assert!(one.iter().all(|v| v.is_finite() && *v > 0.0));
    assert_eq!(one.dim(), two.dim());
    for (a, b) in one.iter().zip(two.iter()) {
        assert_eq!(a.to_bits(), b.to_bits());
    }
}

/// Audit fix: a slant path between equal heights and the horizontal path with the Cn² of
/// that height give the same r0 and the same turbulence OTF through the sensor cascade
/// (one constant set, 0.423, for both).
#[test]
fn slant_path_at_equal_heights_equals_horizontal_in_the_cascade() {
    let (cn2_1m, h, range) = (2e-13, 25.0_f64, 4000.0);
    let cn2_h = cn2_1m * h.powf(-4.0 / 3.0);
    let horizontal = Sensor::build(&sensor(&[
        "turbulence.path=\"horizontal\"",
        &format!("turbulence.cn2={cn2_h:e}"),
        "turbulence.range_m=4000",
    ]))
    .unwrap()
    .otf()
    .clone();
    let slant = Sensor::build(&sensor(&[
        "turbulence.path=\"slant\"",
        &format!("turbulence.cn2_at_1m={cn2_1m:e}"),
        "turbulence.sensor_height_m=25",
        "turbulence.target_height_m=25",
        &format!("turbulence.range_m={range}"),
    ]))
    .unwrap()
    .otf()
    .clone();
    for lambda in [0.6, 1.6, 4.0, 10.0] {
        let (a, b) = (
            horizontal.fried_r0_m(lambda).unwrap(),
            slant.fried_r0_m(lambda).unwrap(),
        );
        assert!(((a - b) / a).abs() < 1e-9, "λ {lambda}: {a} vs {b}");
        for u in [0.3, 1.0, 2.0] {
            let f = u * a / (lambda * 1e-6);
            let (ta, tb) = (
                horizontal.component(Component::Turbulence, f, 0.0, lambda),
                slant.component(Component::Turbulence, f, 0.0, lambda),
            );
            assert!((ta - tb).abs() < 1e-9, "{ta} vs {tb}");
        }
    }
}

/// The achromatic product on a grid (`SystemOtf::on_grid`, built from per-row and
/// per-column terms, with no sine or exponential per sample) matches the pointwise product
/// of the same components at every sample: footprint with unequal widths, smear at an
/// oblique angle (samples where the two sine arguments cancel and where they do not),
/// jitter and an anisotropic Gaussian, on a grid with negative row frequencies and a
/// non-square frame. The difference is within 1e-15 · (1 + |t|), with t the larger of
/// the smear's sine arguments (the conditioning of the sinc in them). The engine's
/// per-sample `achromatic_sampler` gives `on_grid`'s values bit for bit, its column-wise
/// fill the same, and the grid it feeds (`RadialGrid::from_fn`, `from_columns`) the f32
/// of each.
#[test]
fn achromatic_grid_matches_the_pointwise_product() {
    for smear_rad in [7e-5, 2e-3] {
        let smear = format!("motion.smear_rad={smear_rad}");
        let s = sensor(&[
            "detector.active_height_m=17e-6",
            &smear,
            "motion.direction_deg=33",
            "jitter.sigma_rad=1.1e-5",
            "gaussian.sigma_rad=6e-6",
            "gaussian.sigma_y_rad=9e-6",
        ]);
        let otf = Sensor::build(&s).unwrap().otf().clone();
        for c in [
            Component::Detector,
            Component::Motion,
            Component::Jitter,
            Component::Gaussian,
        ] {
            assert!(otf.components().contains(&c), "{c:?} not enabled");
        }
        let grid = eoir::sensor::FrequencyGrid::real_fft(37, 50, 4e-5, 3e-5);
        let a = otf.on_grid(&grid).into_achromatic();
        assert_eq!(a.dim(), (37, 26));
        let sampler = otf.achromatic_sampler(&grid);
        let radial = eoir::imaging::RadialGrid::from_fn(&grid, |u, v| sampler.at(u, v));
        // The engine's column-wise fill gives the same grid, and each column the
        // per-sample values bit for bit.
        let by_columns =
            eoir::imaging::RadialGrid::from_columns(&grid, |u, c| sampler.column(u, c));
        assert_eq!(by_columns, radial);
        let mut column = vec![0.0; grid.fy.len()];
        for k in 0..grid.fx.len() {
            sampler.column(k, &mut column);
            for (j, c) in column.iter().enumerate() {
                assert_eq!(c.to_bits(), sampler.at(k, j).to_bits(), "column ({j}, {k})");
            }
        }
        let (sin_t, cos_t) = 33f64.to_radians().sin_cos();
        let mut distinct = std::collections::BTreeSet::new();
        let (mut cancelling, mut worst) = (0, 0.0f64);
        for ((j, k), v) in a.indexed_iter() {
            let (fx, fy) = (grid.fx[k], grid.fy[j]);
            let want = otf.product_where(fx, fy, 1.0, None, |c| !c.is_chromatic());
            let (tx, ty) = (fx * cos_t * smear_rad, fy * sin_t * smear_rad);
            let t = std::f64::consts::PI * tx.abs().max(ty.abs());
            let err = (v - want).abs() / (1.0 + t);
            assert!(err <= 1e-15, "sample ({j}, {k}): {v} vs {want}");
            worst = worst.max(err);
            if (tx + ty).abs() < 0.5 * (tx.abs() + ty.abs()) {
                cancelling += 1;
            }
            assert_eq!(
                sampler.at(k, j).to_bits(),
                v.to_bits(),
                "sampler ({j}, {k})"
            );
            assert_eq!(
                radial.achromatic(k, j),
                *v as f32 as f64,
                "radial ({j}, {k})"
            );
            distinct.insert(v.to_bits());
        }
        // Not a trivial grid: the product takes many values, signed ones included, and
        // both ways of taking the smear's sine are used.
        assert!(distinct.len() > 500);
        assert!(a.iter().any(|v| *v < 0.0));
        assert!(cancelling > 50 && cancelling < a.len() / 2, "{cancelling}");
        // The evaluation is not the pointwise one bit for bit (else this test would not
        // test the separated terms).
        assert!(worst > 0.0);
    }
}
