//! Built-in synthetic scenes checked against independent truth: Planck's law written out
//! here from CODATA radiation constants, the measured solar constant, symmetry and area
//! conservation of anti-aliased edges, measurements of bar periods and edge angles made on
//! the output, and known spectral behaviour of vegetation.

use eoir::scene::synthetic::{
    bars, bars_frequencies_cy_per_mrad, bars_layout, blackbody, edge, generate, ramp,
    solar_spectral_irradiance, solar_spectral_irradiance_toa, thermal, thermal_scene, Environment,
    Material, Region, SceneParams, KINDS,
};
use eoir::scene::{check_radiance_plane, Cube};

/// First radiation constant for spectral radiance, 2hc², W µm⁴ m-2 sr-1 (CODATA 2018).
const C1L_W_UM4: f64 = 1.191_042_972e8;
/// Second radiation constant hc/k, µm K (CODATA 2018).
const C2_UM_K: f64 = 14_387.768_775;

/// Planck spectral radiance, W m-2 sr-1 µm-1, written independently of the crate.
fn planck(wavelength_um: f64, t_k: f64) -> f64 {
    C1L_W_UM4 / wavelength_um.powi(5) / ((C2_UM_K / (wavelength_um * t_k)).exp() - 1.0)
}

/// Brightness temperature from spectral radiance (Planck inverted in closed form).
fn brightness_temperature(wavelength_um: f64, radiance: f64) -> f64 {
    C2_UM_K / (wavelength_um * (1.0 + C1L_W_UM4 / (wavelength_um.powi(5) * radiance)).ln())
}

fn params(rows: usize, cols: usize, k: usize, wavelength_um: Vec<f64>) -> SceneParams {
    SceneParams {
        rows,
        cols,
        oversampling: k,
        wavelength_um,
        fov_x_deg: 8.0,
        range_m: Some(2000.0),
        seed: 42,
        sun: false,
    }
}

fn band_index(cube: &Cube, wavelength_um: f64) -> usize {
    cube.meta
        .wavelength_um
        .iter()
        .position(|w| (w - wavelength_um).abs() < 1e-9)
        .expect("band on the grid")
}

/// Normalised plane `(L − L0)/(L1 − L0)` of a two-temperature test pattern.
fn normalised(cube: &Cube, band: usize, t_zero: f64, t_one: f64) -> ndarray::Array2<f64> {
    let l = cube.meta.wavelength_um[band];
    let (l0, l1) = (planck(l, t_zero), planck(l, t_one));
    cube.data
        .index_axis(ndarray::Axis(0), band)
        .mapv(|v| (v as f64 - l0) / (l1 - l0))
}

#[test]
fn solar_constant_from_blackbody_sun() {
    // Trapezoid rule on a logarithmic grid 0.05–1000 µm: the measured total solar
    // irradiance is 1360.8 ± 0.5 W m-2 (Kopp & Lean 2011).
    let n = 20_000;
    let (lo, hi) = (0.05f64.ln(), 1000f64.ln());
    let mut total = 0.0;
    let mut prev: Option<(f64, f64)> = None;
    for i in 0..=n {
        let l = (lo + (hi - lo) * i as f64 / n as f64).exp();
        let e = solar_spectral_irradiance_toa(l);
        if let Some((pl, pe)) = prev {
            total += 0.5 * (e + pe) * (l - pl);
        }
        prev = Some((l, e));
    }
    assert!((total - 1361.0).abs() < 2.0, "solar constant {total} W/m²");
    // τ = 1 and the Sun overhead leave the top-of-atmosphere value; 60° halves it.
    let e0 = solar_spectral_irradiance_toa(0.55);
    assert!((solar_spectral_irradiance(0.55, 1.0, 0.0) - e0).abs() < 1e-12 * e0);
    assert!((solar_spectral_irradiance(0.55, 1.0, 60.0) - 0.5 * e0).abs() < 1e-12 * e0);
}

#[test]
fn blackbody_equals_planck_at_every_band_and_scales_with_emissivity() {
    let grid = SceneParams::uniform_grid(0.4, 14.0, 35).unwrap();
    let p = params(6, 8, 2, grid.clone());
    let t = 320.0;
    let full = blackbody(&p, t, 1.0).unwrap();
    let grey = blackbody(&p, t, 0.6).unwrap();
    assert_eq!(full.data.dim(), (35, 12, 16));
    for (b, &l) in grid.iter().enumerate() {
        let truth = planck(l, t);
        for (&v, &g) in full
            .data
            .index_axis(ndarray::Axis(0), b)
            .iter()
            .zip(grey.data.index_axis(ndarray::Axis(0), b).iter())
        {
            assert!(
                (v as f64 - truth).abs() <= 1e-6 * truth + 1e-37,
                "band {b} ({l} µm): {v} vs Planck {truth}"
            );
            assert!(
                (g as f64 - 0.6 * truth).abs() <= 1e-6 * truth + 1e-37,
                "band {b}: ε = 0.6 gives {g}, expected {}",
                0.6 * truth
            );
        }
    }
    let g = full.meta.geometry.unwrap();
    assert_eq!(g.fov_x_deg, 8.0);
    assert!((g.fov_y_deg - 8.0 * 6.0 / 8.0).abs() < 1e-12);
    assert_eq!(g.range_m, Some(2000.0));
}

#[test]
fn ramp_is_linear_in_temperature_by_column() {
    let grid = vec![3.5, 4.5, 8.0, 10.0, 12.0];
    let p = params(4, 50, 2, grid.clone());
    let (t_min, t_max) = (280.0, 330.0);
    let cube = ramp(&p, t_min, t_max).unwrap();
    let cols = p.cube_cols();
    for (b, &l) in grid.iter().enumerate() {
        for r in 0..p.cube_rows() {
            for c in 0..cols {
                let t = brightness_temperature(l, cube.data[[b, r, c]] as f64);
                let expected = t_min + (t_max - t_min) * (c as f64 + 0.5) / cols as f64;
                assert!(
                    (t - expected).abs() < 2e-3,
                    "band {l} µm col {c}: {t} K vs {expected} K"
                );
            }
        }
    }
}

#[test]
fn edge_splits_the_image_in_half() {
    let p = params(60, 80, 2, vec![10.0]);
    let (lo, hi) = (300.0, 310.0);
    let cube = edge(&p, lo, hi, 5.0).unwrap();
    let v = normalised(&cube, 0, lo, hi);
    let n = v.len() as f64;
    // Area conservation + point symmetry about the centre: exactly half the area is hot.
    let area = v.sum() / n;
    assert!((area - 0.5).abs() < 1e-5, "hot area fraction {area}");
    // Counting pixels more than half hot: within one pixel per row of ½.
    let count = v.iter().filter(|&&x| x > 0.5).count() as f64;
    assert!(
        (count / n - 0.5).abs() <= p.cube_rows() as f64 / n,
        "hot pixel fraction {}",
        count / n
    );
    // The hot side is on the right for small angles.
    let (rows, cols) = v.dim();
    for r in 0..rows {
        assert!(v[[r, 0]].abs() < 1e-5 && (v[[r, cols - 1]] - 1.0).abs() < 1e-5);
    }
}

/// Least-squares slope of x against y.
fn slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let my = points.iter().map(|p| p.1).sum::<f64>() / n;
    let mx = points.iter().map(|p| p.0).sum::<f64>() / n;
    let sxy: f64 = points.iter().map(|p| (p.1 - my) * (p.0 - mx)).sum();
    let syy: f64 = points.iter().map(|p| (p.1 - my).powi(2)).sum();
    sxy / syy
}

#[test]
fn edge_angle_measured_from_row_transitions() {
    for angle in [5.0, -8.0, 12.5] {
        let p = params(100, 100, 2, vec![10.0]);
        let cube = edge(&p, 290.0, 300.0, angle).unwrap();
        let v = normalised(&cube, 0, 290.0, 300.0);
        let (rows, cols) = v.dim();
        let mut crossings = Vec::new();
        let mut area_edges = Vec::new();
        for r in 0..rows {
            let row = v.row(r);
            // 50 % crossing by linear interpolation between pixel centres (as an ESF
            // analysis would do).
            for c in 0..cols - 1 {
                if row[c] < 0.5 && row[c + 1] >= 0.5 {
                    let x = c as f64 + 0.5 + (0.5 - row[c]) / (row[c + 1] - row[c]);
                    crossings.push((x, r as f64 + 0.5));
                    break;
                }
            }
            // The cold area of a row equals the edge position at the row centre.
            area_edges.push((cols as f64 - row.sum(), r as f64 + 0.5));
        }
        assert_eq!(crossings.len(), rows);
        let measured = slope(&crossings).atan().to_degrees();
        assert!(
            (measured - angle).abs() < 0.1,
            "edge at {angle}°: measured {measured}°"
        );
        let exact = slope(&area_edges).atan().to_degrees();
        assert!(
            (exact - angle).abs() < 1e-3,
            "edge at {angle}°: area method {exact}°"
        );
    }
}

/// Edges of a 0/1 profile with area-weighted transition pixels, exact: between an empty
/// pixel j and a full pixel i the covered length gives the edge position.
fn profile_edges(v: &[f64]) -> Vec<(f64, bool)> {
    let tol = 1e-4;
    let mut edges = Vec::new();
    let mut prev: Option<(usize, bool)> = None;
    for (i, &x) in v.iter().enumerate() {
        let state = if x > 1.0 - tol {
            Some(true)
        } else if x < tol {
            Some(false)
        } else {
            None
        };
        let Some(full) = state else { continue };
        if let Some((j, was_full)) = prev {
            if was_full != full {
                let sum: f64 = v[j..=i].iter().sum();
                let e = if full {
                    (i + 1) as f64 - sum
                } else {
                    j as f64 + sum
                };
                edges.push((e, full));
            }
        }
        prev = Some((i, full));
    }
    edges
}

#[test]
fn bar_periods_match_the_requested_frequencies() {
    let p = params(120, 160, 3, vec![9.0, 11.0]);
    let (t_bar, t_bg) = (303.0, 298.0);
    let cube = bars(&p, t_bar, t_bg).unwrap();
    let v = normalised(&cube, 1, t_bg, t_bar);
    let freqs = bars_frequencies_cy_per_mrad(&p);
    assert_eq!(freqs.len(), 6, "6 groups fit in 160 × 120: {freqs:?}");
    // Spaced by √2, highest at the detector Nyquist frequency.
    let ifov_rad = 8f64.to_radians() / 160.0;
    let nyquist = 1.0 / (2.0 * ifov_rad) / 1000.0;
    assert!((freqs[5] - nyquist).abs() < 1e-9 * nyquist);
    for w in freqs.windows(2) {
        assert!((w[1] / w[0] - 2f64.sqrt()).abs() < 1e-9);
    }
    let layout = bars_layout(&p).unwrap();
    assert_eq!(layout.len(), 12, "vertical and horizontal rows");
    let cube_ifov_mrad = ifov_rad / 3.0 * 1000.0;
    for g in &layout {
        let w = g.bar_width_px;
        // Cut through the pattern's middle, across the bars, from gap to gap.
        let (profile, along): (Vec<f64>, Vec<f64>) = if g.horizontal_bars {
            let c = (g.x0_px + 3.5 * w) as usize;
            let r0 = (g.y0_px - 1.5).floor() as usize;
            let r1 = (g.y0_px + 7.0 * w + 1.5).ceil() as usize;
            let centre_r = (g.y0_px + 0.5 * w) as usize;
            (
                (r0..r1).map(|r| v[[r, c]]).collect(),
                (0..v.ncols()).map(|c| v[[centre_r, c]]).collect(),
            )
        } else {
            let r = (g.y0_px + 3.5 * w) as usize;
            let c0 = (g.x0_px - 1.5).floor() as usize;
            let c1 = (g.x0_px + 7.0 * w + 1.5).ceil() as usize;
            let centre_c = (g.x0_px + 0.5 * w) as usize;
            (
                (c0..c1).map(|c| v[[r, c]]).collect(),
                (0..v.nrows()).map(|r| v[[r, centre_c]]).collect(),
            )
        };
        let edges = profile_edges(&profile);
        assert_eq!(edges.len(), 8, "4 bars in group {g:?}: {edges:?}");
        let rises: Vec<f64> = edges.iter().filter(|e| e.1).map(|e| e.0).collect();
        let falls: Vec<f64> = edges.iter().filter(|e| !e.1).map(|e| e.0).collect();
        let period_px = ((rises[3] - rises[0]) + (falls[3] - falls[0])) / 6.0;
        let measured = 1.0 / (period_px * cube_ifov_mrad);
        assert!(
            (measured / g.frequency_cy_per_mrad - 1.0).abs() < 1e-4,
            "group {g:?}: measured {measured} cy/mrad"
        );
        // Bar width = space = half the period; bar length = 7 widths (from the sum along
        // the bar, which crosses no other bar of this group).
        let width: f64 = rises.iter().zip(&falls).map(|(r, f)| f - r).sum::<f64>() / 4.0;
        assert!(
            (width / period_px - 0.5).abs() < 1e-4,
            "width {width} period {period_px}"
        );
        let lo = if g.horizontal_bars { g.x0_px } else { g.y0_px };
        let hi = lo + 7.0 * w;
        let length: f64 = along[lo.floor() as usize..hi.ceil() as usize].iter().sum();
        assert!(
            (length / width - 7.0).abs() < 1e-3,
            "bar length {length} width {width}"
        );
    }
}

#[test]
fn bars_drop_low_frequencies_on_small_images_and_reject_tiny_ones() {
    let small = params(20, 30, 1, vec![10.0]);
    let f = bars_frequencies_cy_per_mrad(&small);
    assert!(!f.is_empty() && f.len() < 6, "{f:?}");
    let ifov_rad = 8f64.to_radians() / 30.0;
    let nyquist = 1.0 / (2.0 * ifov_rad) / 1000.0;
    assert!((f.last().unwrap() - nyquist).abs() < 1e-9 * nyquist);
    let tiny = params(8, 8, 1, vec![10.0]);
    assert!(bars(&tiny, 300.0, 301.0).is_err());
    assert!(bars_frequencies_cy_per_mrad(&tiny).is_empty());
}

#[test]
fn thermal_is_reproducible_by_seed() {
    let mut p = params(48, 64, 1, vec![4.0, 10.0]);
    let a = thermal(&p).unwrap();
    let b = thermal(&p).unwrap();
    assert_eq!(a.data, b.data);
    p.seed = 43;
    let c = thermal(&p).unwrap();
    let differ = a
        .data
        .iter()
        .zip(c.data.iter())
        .filter(|(x, y)| x != y)
        .count();
    assert!(
        differ as f64 > 0.3 * a.data.len() as f64,
        "only {differ} values differ"
    );
    for (b, plane) in a.data.outer_iter().enumerate() {
        check_radiance_plane("thermal", b, a.meta.wavelength_um[b], plane).unwrap();
    }
}

#[test]
fn thermal_target_is_warmer_than_terrain() {
    for sun in [false, true] {
        let mut p = params(96, 128, 1, vec![8.0, 10.0, 12.0]);
        p.sun = sun;
        let scene = thermal_scene(&p, &Environment::default()).unwrap();
        let b = band_index(&scene.cube, 10.0);
        let mean_bt = |keep: &dyn Fn(Region) -> bool, min_count: usize| {
            let (mut s, mut n) = (0.0, 0usize);
            for ((r, c), &region) in scene.region.indexed_iter() {
                if keep(region) {
                    s += brightness_temperature(10.0, scene.cube.data[[b, r, c]] as f64);
                    n += 1;
                }
            }
            assert!(n >= min_count, "too few pixels ({n})");
            s / n as f64
        };
        let target = mean_bt(&|r: Region| r.is_target(), 20);
        let hull = mean_bt(&|r: Region| r == Region::Hull, 20);
        let terrain = mean_bt(&|r: Region| r == Region::Terrain, 20);
        let sky = mean_bt(&|r: Region| r == Region::Sky, 20);
        eprintln!("sun {sun}: target {target:.2} K, hull {hull:.2} K, terrain {terrain:.2} K, sky {sky:.2} K");
        assert!(
            target > terrain + 2.0,
            "sun {sun}: target {target} K, terrain {terrain} K"
        );
        assert!(
            hull > terrain + 1.0,
            "sun {sun}: hull {hull} K, terrain {terrain} K"
        );
        // The surface appears colder than its physical temperature: ε < 1 and the sky
        // it reflects is colder than the ground.
        let t_phys: f64 = scene
            .region
            .indexed_iter()
            .filter(|(_, &r)| r == Region::Terrain)
            .map(|((r, c), _)| scene.temperature_k[[r, c]] as f64)
            .sum::<f64>()
            / scene
                .region
                .iter()
                .filter(|&&r| r == Region::Terrain)
                .count() as f64;
        assert!(
            terrain < t_phys && terrain > t_phys - 5.0,
            "{terrain} vs physical {t_phys}"
        );
        // Exhaust near its 550 K (ε = 0.9 lowers the brightness temperature).
        let exhaust = mean_bt(&|r: Region| r == Region::Exhaust, 2);
        assert!(exhaust > 500.0 && exhaust < 550.0, "exhaust {exhaust} K");
    }
}

#[test]
fn sunlit_vegetation_is_nir_bright() {
    let grid = SceneParams::uniform_grid(0.40, 1.00, 61).unwrap();
    let mut p = params(96, 128, 1, grid);
    p.sun = true;
    let scene = thermal_scene(&p, &Environment::default()).unwrap();
    let (red, nir) = (band_index(&scene.cube, 0.66), band_index(&scene.cube, 0.86));
    let mean = |band: usize, keep: &dyn Fn(usize, usize) -> bool| {
        let (mut s, mut n) = (0.0, 0usize);
        for ((r, c), _) in scene.region.indexed_iter() {
            if keep(r, c) {
                s += scene.cube.data[[band, r, c]] as f64;
                n += 1;
            }
        }
        assert!(n > 20, "too few pixels ({n})");
        s / n as f64
    };
    let veg = |r: usize, c: usize| {
        scene.region[[r, c]] == Region::Terrain && scene.vegetation_fraction[[r, c]] > 0.95
    };
    let soil = |r: usize, c: usize| {
        scene.region[[r, c]] == Region::Terrain && scene.vegetation_fraction[[r, c]] < 0.05
    };
    let paint = |r: usize, c: usize| scene.region[[r, c]] == Region::Hull;
    let veg_ratio = mean(nir, &veg) / mean(red, &veg);
    let soil_ratio = mean(nir, &soil) / mean(red, &soil);
    eprintln!("NIR/red: vegetation {veg_ratio:.2}, soil {soil_ratio:.2}");
    assert!(veg_ratio > 3.0, "vegetation NIR/red {veg_ratio}");
    assert!(soil_ratio < 2.0, "soil NIR/red {soil_ratio}");
    assert!(
        mean(nir, &paint) < mean(nir, &veg),
        "paint must be less NIR-bright than vegetation"
    );
    // The daylight sky away from the horizon is bluer than sunlight itself (Rayleigh
    // scattering ∝ λ⁻⁴).
    let env = Environment::default();
    let sky_ratio = env.sky_radiance(0.45, 50.0, true) / env.sky_radiance(0.66, 50.0, true);
    let sun_ratio = solar_spectral_irradiance_toa(0.45) / solar_spectral_irradiance_toa(0.66);
    assert!(
        sky_ratio > 1.5 * sun_ratio,
        "sky blue/red {sky_ratio} vs sunlight {sun_ratio}"
    );
    // At night only the 550 K exhaust emits measurably below 1 µm (Planck at 300 K and
    // 1 µm is 2e-13 W m-2 sr-1 µm-1).
    p.sun = false;
    let night = thermal_scene(&p, &Environment::default()).unwrap();
    for ((b, r, c), &v) in night.cube.data.indexed_iter() {
        if night.region[[r, c]] == Region::Exhaust {
            if b == 60 {
                assert!(v > 1e-4, "exhaust at 1 µm: {v}");
            }
        } else {
            assert!((0.0..1e-11).contains(&v), "band {b} pixel ({r}, {c}): {v}");
        }
    }
}

#[test]
fn sky_model_limits() {
    let env = Environment::default();
    let t_air = env.air_temperature_k;
    // A horizontal path is optically thick even in the LWIR window: blackbody at T_air.
    let horizon = env.sky_radiance(10.0, 0.0, false);
    assert!(
        (horizon / planck(10.0, t_air) - 1.0).abs() < 0.02,
        "horizon {horizon}"
    );
    // The zenith in the window is much colder; in the 6.3 µm water band it is opaque.
    assert!(env.sky_radiance(10.0, 90.0, false) < 0.6 * planck(10.0, t_air));
    assert!((env.sky_radiance(6.3, 90.0, false) / planck(6.3, t_air) - 1.0).abs() < 1e-3);
    // The hemispheric downwelling radiance lies between the zenith and horizon values.
    for &l in &[0.5, 4.0, 10.0] {
        let down = env.downwelling_sky_radiance(l, true);
        let (z, h) = (
            env.sky_radiance(l, 90.0, true),
            env.sky_radiance(l, 0.0, true),
        );
        assert!(
            down > z.min(h) && down < z.max(h),
            "{l} µm: {down} not in [{z}, {h}]"
        );
    }
    // Vegetation and paint emissivities in the LWIR as documented.
    assert!((0.97..=0.98).contains(&Material::Vegetation.emissivity(10.0)));
    assert!((Material::Exhaust.emissivity(4.0) - 0.9).abs() < 1e-12);
}

#[test]
fn oversampling_refines_the_same_scene() {
    // With k = 3 the centre pixel of each 3 × 3 block has the same image coordinates as the
    // k = 1 pixel, so it must show the same thing.
    let p1 = params(40, 52, 1, vec![0.55, 10.0]);
    let p3 = SceneParams {
        oversampling: 3,
        ..p1.clone()
    };
    for sun in [false, true] {
        let a = thermal(&SceneParams { sun, ..p1.clone() }).unwrap();
        let b = thermal(&SceneParams { sun, ..p3.clone() }).unwrap();
        assert_eq!(b.data.dim(), (2, 120, 156));
        let (mut same, mut total) = (0usize, 0usize);
        for ((band, r, c), &v) in a.data.indexed_iter() {
            let w = b.data[[band, 3 * r + 1, 3 * c + 1]];
            total += 1;
            if (v - w).abs() <= 1e-5 * v.abs().max(1e-12) {
                same += 1;
            }
        }
        assert!(
            same as f64 >= 0.99 * total as f64,
            "sun {sun}: {same}/{total} equal"
        );
    }
}

#[test]
fn thermal_works_for_any_size() {
    for (rows, cols) in [(1, 1), (2, 300), (300, 2), (7, 9)] {
        let mut p = params(rows, cols, 2, vec![0.6, 10.0]);
        p.sun = true;
        p.fov_x_deg = 0.5;
        let cube = thermal(&p).unwrap_or_else(|e| panic!("{rows} x {cols}: {e}"));
        assert_eq!(cube.data.dim(), (2, 2 * rows, 2 * cols));
        assert!(cube.data.iter().all(|v| v.is_finite() && *v >= 0.0));
    }
}

#[test]
fn every_kind_is_available_by_name() {
    let p = params(24, 32, 1, vec![10.0]);
    for (name, description) in KINDS {
        assert!(!description.is_empty());
        let cube = generate(name, &p).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(cube.data.dim(), (1, 24, 32));
        assert!(cube.data.iter().all(|v| v.is_finite() && *v >= 0.0));
    }
    assert!(generate("checkerboard", &p).is_err());
}

#[test]
fn invalid_parameters_are_rejected() {
    let ok = params(16, 16, 1, vec![8.0, 10.0]);
    assert!(ok.validate().is_ok());
    let bad = [
        SceneParams {
            rows: 0,
            ..ok.clone()
        },
        SceneParams {
            cols: 0,
            ..ok.clone()
        },
        SceneParams {
            oversampling: 0,
            ..ok.clone()
        },
        SceneParams {
            oversampling: 65,
            ..ok.clone()
        },
        SceneParams {
            wavelength_um: vec![],
            ..ok.clone()
        },
        SceneParams {
            wavelength_um: vec![10.0, 10.0],
            ..ok.clone()
        },
        SceneParams {
            wavelength_um: vec![10.0, 9.0],
            ..ok.clone()
        },
        SceneParams {
            wavelength_um: vec![-1.0],
            ..ok.clone()
        },
        SceneParams {
            wavelength_um: vec![f64::NAN],
            ..ok.clone()
        },
        SceneParams {
            fov_x_deg: 0.0,
            ..ok.clone()
        },
        SceneParams {
            fov_x_deg: 180.0,
            ..ok.clone()
        },
        SceneParams {
            fov_x_deg: f64::INFINITY,
            ..ok.clone()
        },
        // Vertical field 100 × 2 = 200° is impossible.
        SceneParams {
            fov_x_deg: 100.0,
            rows: 32,
            ..ok.clone()
        },
        SceneParams {
            range_m: Some(0.0),
            ..ok.clone()
        },
        SceneParams {
            range_m: Some(f64::NAN),
            ..ok.clone()
        },
        SceneParams {
            rows: 100_000,
            cols: 100_000,
            ..ok.clone()
        },
    ];
    for p in &bad {
        assert!(p.validate().is_err(), "accepted {p:?}");
        assert!(thermal(p).is_err() && blackbody(p, 300.0, 1.0).is_err());
        assert!(edge(p, 300.0, 310.0, 5.0).is_err() && ramp(p, 290.0, 300.0).is_err());
        assert!(bars(p, 300.0, 310.0).is_err());
    }
    // The message names the field and the value.
    let msg = SceneParams {
        oversampling: 0,
        ..ok.clone()
    }
    .validate()
    .unwrap_err()
    .to_string();
    assert!(msg.contains("oversampling") && msg.contains('0'), "{msg}");
    let msg = SceneParams {
        wavelength_um: vec![10.0, 9.0],
        ..ok.clone()
    }
    .validate()
    .unwrap_err()
    .to_string();
    assert!(
        msg.contains("wavelength_um[1]") && msg.contains('9'),
        "{msg}"
    );
    // Temperatures, emissivity, angle.
    assert!(blackbody(&ok, 0.0, 1.0).is_err());
    assert!(blackbody(&ok, f64::NAN, 1.0).is_err());
    assert!(blackbody(&ok, 300.0, 1.5).is_err());
    assert!(blackbody(&ok, 300.0, -0.1).is_err());
    assert!(ramp(&ok, 300.0, 290.0).is_err());
    assert!(ramp(&ok, -5.0, 290.0).is_err());
    assert!(edge(&ok, 300.0, 310.0, f64::NAN).is_err());
    assert!(edge(&ok, 300.0, 310.0, 270.0).is_err());
    assert!(edge(&ok, 300.0, 1e6, 5.0).is_err());
    assert!(bars(&ok, -1.0, 300.0).is_err());
    let env = Environment {
        solar_zenith_deg: 95.0,
        ..Environment::default()
    };
    assert!(thermal_scene(&ok, &env).is_err());
    let env = Environment {
        air_temperature_k: f64::NAN,
        ..Environment::default()
    };
    assert!(thermal_scene(&ok, &env).is_err());
    let env = Environment {
        aerosol_optical_depth_550: -0.1,
        ..Environment::default()
    };
    assert!(thermal_scene(&ok, &env).is_err());
    // Wavelength grids.
    assert!(SceneParams::uniform_grid(8.0, 12.0, 0).is_err());
    assert!(SceneParams::uniform_grid(12.0, 8.0, 5).is_err());
    assert!(SceneParams::uniform_grid(8.0, 8.0, 2).is_err());
    assert!(SceneParams::uniform_grid(0.0, 8.0, 2).is_err());
    assert!(SceneParams::uniform_grid(8.0, f64::INFINITY, 2).is_err());
    assert_eq!(
        SceneParams::uniform_grid(8.0, 12.0, 5).unwrap(),
        vec![8.0, 9.0, 10.0, 11.0, 12.0]
    );
    assert_eq!(SceneParams::uniform_grid(8.0, 12.0, 1).unwrap(), vec![10.0]);
}

/// Scene sizing: `covering` gives k scene samples per detector pixel and m pixels of margin
/// on each side, the vertical extent following from square pixels; the paraxial extent is
/// n·IFOV, larger than the flat focal plane's 2·atan(n·p/2f) (MultimIR 100 mm: 5.2804° vs
/// 5.2766°, written out here independently).
#[test]
fn covering_scene_has_k_samples_per_pixel_and_the_margin() {
    use eoir::scene::sizing::{covering, paraxial_extent_rad, DetectorGrid};
    let grid = DetectorGrid {
        rows: 288,
        cols: 384,
        ifov_rad: 24e-6 / 0.1,
    };
    let (fx, fy) = grid.fov_deg();
    assert!((fx - 5.280_379_04).abs() < 1e-8, "{fx}");
    assert!((fy - 288.0 * 0.24e-3f64.to_degrees()).abs() < 1e-12, "{fy}");
    let flat = (2.0 * (384.0 * 24e-6 / (2.0 * 0.1f64)).atan()).to_degrees();
    assert!((flat - 5.276_646_40).abs() < 1e-8 && flat < fx, "{flat}");
    assert_eq!(paraxial_extent_rad(7, 0.5), 3.5);
    for k in [1, 2, 3, 5] {
        for m in [0, 4, 13] {
            let p = covering(&grid, k, m).unwrap();
            assert_eq!(p.cube_cols(), (384 + 2 * m) * k);
            assert_eq!(p.cube_rows(), (288 + 2 * m) * k);
            let g = p.geometry();
            // Scene sample spacing = IFOV / k on both axes, to rounding.
            let sx = g.ifov_x_rad(p.cube_cols());
            let sy = g.ifov_y_rad(p.cube_rows());
            assert!(
                (sx * k as f64 / grid.ifov_rad - 1.0).abs() < 1e-14,
                "{k} {m}"
            );
            assert!(
                (sy * k as f64 / grid.ifov_rad - 1.0).abs() < 1e-14,
                "{k} {m}"
            );
            // Margin: the scene exceeds the detector by 2m pixels per axis.
            let extra_x = (g.fov_x_deg - fx).to_radians() / grid.ifov_rad;
            let extra_y = (g.fov_y_deg - fy).to_radians() / grid.ifov_rad;
            assert!((extra_x - 2.0 * m as f64).abs() < 1e-9, "{extra_x}");
            assert!((extra_y - 2.0 * m as f64).abs() < 1e-9, "{extra_y}");
        }
    }
    for (k, m, bad) in [(0, 4, "oversampling"), (2, 100_000, "margin_px")] {
        let e = covering(&grid, k, m).unwrap_err().to_string();
        assert!(e.contains(bad), "{e}");
    }
    let e = covering(
        &DetectorGrid {
            ifov_rad: f64::NAN,
            ..grid
        },
        2,
        4,
    )
    .unwrap_err();
    assert!(e.to_string().contains("IFOV"), "{e}");
}

/// The wavelength grid for a sensor's band: both ends, even spacing no wider than 0.02 µm
/// (or 121 bands across a wider band), at least 24 bands; an unbounded band is an error that says what to give.
#[test]
fn response_grid_spans_the_band_finely() {
    use eoir::scene::sizing::{response_grid_um, MAX_GRID_BANDS, MIN_BANDS, SPECTRAL_STEP_UM};
    for (lo, hi) in [
        (4.525, 5.225),
        (0.38, 1.02),
        (7.0, 10.0),
        (4.0, 4.1),
        (4.89, 12.11),
    ] {
        let g = response_grid_um(lo, hi).unwrap();
        assert_eq!(g[0], lo);
        assert_eq!(*g.last().unwrap(), hi);
        assert!((MIN_BANDS..=MAX_GRID_BANDS).contains(&g.len()));
        let step = g[1] - g[0];
        let widest = SPECTRAL_STEP_UM.max((hi - lo) / (MAX_GRID_BANDS - 1) as f64);
        assert!(step <= widest + 1e-12, "{lo}-{hi}: {step}");
        assert!(g.windows(2).all(|w| ((w[1] - w[0]) - step).abs() < 1e-12));
    }
    // 4.0–6.0 µm: 100 steps of exactly 0.02 µm; 7–10 µm: capped at 121 bands (0.025 µm).
    assert_eq!(response_grid_um(4.0, 6.0).unwrap().len(), 101);
    assert_eq!(response_grid_um(7.0, 10.0).unwrap().len(), MAX_GRID_BANDS);
    for (lo, hi) in [
        (0.0, 5.0),
        (4.0, f64::INFINITY),
        (5.0, 4.0),
        (f64::NAN, 1.0),
    ] {
        let e = response_grid_um(lo, hi).unwrap_err().to_string();
        assert!(e.contains("spectral response support"), "{e}");
    }
}
