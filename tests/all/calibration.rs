//! Radiometric calibration through the simulated sensor (`eoir::calibration`): NUC,
//! bad pixels and the way back from DN to apparent temperature, on a 64 × 80 MultimIR
//! (filter 4, 4.55–5.2 µm, 100 mm F/2) with PRNU, DSNU and read noise.

use eoir::calibration::flat_field::{self, InstanceMaps};
use eoir::calibration::{measured_netd, Calibration, CalibrationOptions, FrameRoute};
use eoir::detector::{DetectorInstance, DetectorModel};
use eoir::radiometry::planck_spectral_radiance;
use eoir::sensor::{presets, Sensor};
use ndarray::Array2;

const SEED: u64 = 7;

fn sensor(extra: &[&str]) -> Sensor {
    let mut o: Vec<String> = [
        "detector.rows=64",
        "detector.cols=80",
        "detector.read_noise_e=200",
        "detector.fpn.prnu_sigma_rel=0.02",
        "detector.fpn.dsnu_sigma_e=2e4",
        "detector.auto_gain.reference_temperature_k=300",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    o.extend(extra.iter().map(|s| s.to_string()));
    Sensor::build(&presets::load("multimir", &[], &o).unwrap()).unwrap()
}

fn setup(extra: &[&str]) -> (Sensor, DetectorModel, DetectorInstance) {
    let s = sensor(extra);
    let model = s.detector().clone();
    let inst = DetectorInstance::new(&model, SEED).unwrap();
    (s, model, inst)
}

fn mean_std(v: impl Iterator<Item = f64>) -> (f64, f64, usize) {
    let v: Vec<f64> = v.collect();
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0);
    (m, var.sqrt(), v.len())
}

/// Temporal noise (DN², shot + read + quantisation) of the model at `t_k`.
fn noise_var(cal: &Calibration, model: &DetectorModel, t_k: f64) -> f64 {
    let s = model.temporal_noise_dn(cal.blackbody_electrons(t_k).unwrap());
    s * s + 1.0 / 12.0
}

/// Linear pixels: the two-point NUC (280 K, 320 K) removes the 2 % fixed pattern down to
/// the temporal-noise floor. Truth: the raw σ/mean is the PRNU/DSNU of the instance
/// (≥ 1 %), and the corrected σ/mean is predicted from noise propagation alone: the
/// validation average carries σ(310)/√M and the two fitted levels σ(T_l)/√M with the
/// Lagrange weights w_l of 310 K between them, so σ_pred² = [σ(310)² + Σ w_l² σ(T_l)²]/M.
#[test]
fn two_point_nuc_cuts_residual_nonuniformity_to_noise_floor() {
    let (s, model, inst) = setup(&[]);
    let opts = CalibrationOptions {
        temperatures_k: vec![280.0, 320.0],
        ..CalibrationOptions::default()
    };
    let cal = Calibration::new(&s, &model, &inst, &opts).unwrap();
    let (raw, corrected) = cal.residual_nonuniformity(&inst, 310.0).unwrap();
    let (d0, d1, dx) = (
        cal.ideal_dn(280.0),
        cal.ideal_dn(320.0),
        cal.ideal_dn(310.0),
    );
    let w1 = (dx - d0) / (d1 - d0);
    let w0 = 1.0 - w1;
    let m = opts.frames_per_level as f64;
    let pred = ((noise_var(&cal, &model, 310.0)
        + w0 * w0 * noise_var(&cal, &model, 280.0)
        + w1 * w1 * noise_var(&cal, &model, 320.0))
        / m)
        .sqrt()
        / dx;
    println!(
        "raw {raw:.5}, corrected {corrected:.3e}, noise-floor prediction {pred:.3e}, ratio {:.0}",
        raw / corrected
    );
    assert!(raw > 0.01, "raw non-uniformity {raw}");
    assert!(corrected * 10.0 <= raw, "raw {raw} corrected {corrected}");
    // The σ of 5120 pixels is known to ~1 %; allow 15 % for PRNU-scaled noise and rounding.
    assert!(
        (corrected / pred - 1.0).abs() < 0.15,
        "corrected {corrected} vs predicted {pred}"
    );
}

/// Nonlinear pixels (per-pixel quadratic a ~ N(−1e-8, (3e-9)²) per electron, ~4 %
/// compression at 300 K): a degree-1 NUC leaves the spread of the pixels' curvature, a
/// degree-2 NUC models it; degree 3 can do no better than the noise floor.
#[test]
fn polynomial_nuc_beats_linear_for_nonlinear_pixels() {
    let (s, model, inst) = setup(&[
        "detector.nonlinearity.quadratic_mean_per_e=-1e-8",
        "detector.nonlinearity.quadratic_sigma_per_e=3e-9",
    ]);
    let mut r = Vec::new();
    for degree in 1..=3 {
        let opts = CalibrationOptions {
            temperatures_k: vec![270.0, 280.0, 290.0, 300.0, 310.0, 320.0],
            degree,
            ..CalibrationOptions::default()
        };
        let cal = Calibration::new(&s, &model, &inst, &opts).unwrap();
        let (raw, cor) = cal.residual_nonuniformity(&inst, 305.0).unwrap();
        println!("degree {degree}: raw {raw:.5}, corrected {cor:.3e}");
        r.push(cor);
    }
    assert!(r[1] < 0.5 * r[0], "degree 2 {} vs degree 1 {}", r[1], r[0]);
    assert!(r[2] < 1.3 * r[1], "degree 3 {} vs degree 2 {}", r[2], r[1]);
}

/// A uniform 300 K scene (one frame, fresh noise) through FPN, NUC and inversion: the
/// mean apparent temperature is 300 K and the spatial σ equals the analytic NETD. After
/// the NUC the fixed pattern is gone, so the per-pixel spread is the single frame's
/// temporal noise (σ_T = NETD) plus the calibration noise of the fitted coefficients, a
/// fraction ~Σw²/M ≈ 0.6/16 of the variance (+2 % in σ); 10 % covers that and the ±1 %
/// sampling error of σ over 5120 pixels.
#[test]
fn uniform_300k_scene_recovers_temperature_with_netd_spread() {
    let (s, model, inst) = setup(&["detector.defects.dead_fraction=0.002"]);
    let cal = Calibration::new(&s, &model, &inst, &CalibrationOptions::default()).unwrap();
    let e = cal.blackbody_electrons(300.0).unwrap();
    let dn = inst.expose(&Array2::from_elem((64, 80), e), 0).unwrap();
    let corrected = cal.correct(dn.view()).unwrap();
    let (t, l, nan) = cal.to_temperature(corrected.view());
    assert_eq!(nan, 0);
    let bad = cal.bad_pixels();
    let (mt, st, n) = mean_std(
        t.indexed_iter()
            .filter(|(p, _)| !bad.is_bad(p.0, p.1))
            .map(|(_, &v)| v),
    );
    let netd = cal.netd_analytic_k(300.0).unwrap();
    println!(
        "mean {mt:.4} K, σ {st:.4} K over {n} px, analytic NETD {netd:.4} K, {} bad",
        bad.count()
    );
    assert!(bad.count() >= 1, "the dead pixels are flagged");
    assert!((mt - 300.0).abs() < 0.05, "mean apparent temperature {mt}");
    assert!((st / netd - 1.0).abs() < 0.10, "σ {st} vs NETD {netd}");
    // Radiance image: L_band of the apparent temperature; its mean is L_band(300 K) to
    // first order (the spread is ~NETD, 1e-4 of T).
    let (ml, _, _) = mean_std(l.iter().copied());
    let l300 = cal.band_radiance(300.0);
    assert!((ml / l300 - 1.0).abs() < 1e-3, "{ml} vs {l300}");
}

/// The in-band radiance definition, ∫ S L_λ dλ / max S, against an independent
/// composite-Simpson quadrature of Planck × the response, and max S against the closed
/// form 0.85 (filter) × 0.9 (optics) × 0.7 (QE plateau).
#[test]
fn in_band_radiance_matches_independent_quadrature() {
    let (s, model, inst) = setup(&[]);
    let cal = Calibration::new(&s, &model, &inst, &CalibrationOptions::default()).unwrap();
    assert!((cal.peak_response() - 0.85 * 0.9 * 0.7).abs() < 1e-12);
    let resp = s.response().clone();
    for t in [250.0, 300.0, 320.0] {
        let (a, b, n) = (4.0, 5.6, 20_000usize);
        let h = (b - a) / n as f64;
        let f = |w: f64| resp.eval(w) * planck_spectral_radiance(w, t);
        let mut sum = f(a) + f(b);
        for k in 1..n {
            sum += if k % 2 == 1 { 4.0 } else { 2.0 } * f(a + k as f64 * h);
        }
        let simpson = sum * h / 3.0 / (0.85 * 0.9 * 0.7);
        let got = cal.band_radiance(t);
        assert!(
            (got / simpson - 1.0).abs() < 1e-6,
            "{t} K: {got} vs {simpson}"
        );
    }
}

/// NETD measured from frame stacks (16 frames at 300 K and 300.25 K, raw DN) against the
/// analytic value. Sampling error: the pixel-averaged variance has 5120 × 15 degrees of
/// freedom (σ known to 0.26 %); the one-sided difference is biased by
/// ΔT·(x − 2)/(2T) ≈ 0.33 % (x = hc/λkT ≈ 9.9); PRNU adds ~σ_g² = 0.04 %. 1.5 % is ~4σ.
#[test]
fn measured_netd_agrees_with_analytic() {
    let (s, model, inst) = setup(&[]);
    let cal = Calibration::new(&s, &model, &inst, &CalibrationOptions::default()).unwrap();
    let analytic = cal.netd_analytic_k(300.0).unwrap();
    let measured = measured_netd(&s, &inst, 300.0, 0.25, 16, Some(cal.bad_pixels())).unwrap();
    println!("NETD analytic {analytic:.5} K, measured {measured:.5} K");
    assert!((measured / analytic - 1.0).abs() < 0.015);
}

/// Out-of-range values become NaN and are counted, never a wrong number: corrected DN
/// below/above the table, NaN, and through the sensor a scene with an ADC-saturating
/// 400 K half and a 150 K half below the table.
#[test]
fn out_of_range_dn_gives_nan_and_is_counted() {
    let (s, model, inst) = setup(&["detector.defects.dead_fraction=0.002"]);
    let cal = Calibration::new(&s, &model, &inst, &CalibrationOptions::default()).unwrap();
    let (lo, hi) = cal.dn_lut().value_range();
    let d300 = cal.ideal_dn(300.0);
    let frame = Array2::from_shape_vec((1, 4), vec![lo - 10.0, hi + 10.0, f64::NAN, d300]).unwrap();
    let (t, l, nan) = cal.to_temperature(frame.view());
    assert_eq!(nan, 3);
    assert!(t[[0, 0]].is_nan() && t[[0, 1]].is_nan() && t[[0, 2]].is_nan());
    assert!(l[[0, 0]].is_nan() && l[[0, 1]].is_nan());
    assert!((t[[0, 3]] - 300.0).abs() < 1e-6, "{}", t[[0, 3]]);

    // Left third 150 K (below the 200 K table), middle 300 K, right third 400 K (the
    // ideal pixel saturates at ~323 K).
    let (e150, e300, e400) = (
        cal.blackbody_electrons(150.0).unwrap(),
        cal.blackbody_electrons(300.0).unwrap(),
        cal.blackbody_electrons(400.0).unwrap(),
    );
    assert!(cal.lut_range_k().1 < 400.0);
    let mean_e = Array2::from_shape_fn((64, 80), |(_, c)| match c {
        0..=25 => e150,
        26..=53 => e300,
        _ => e400,
    });
    let dn = inst.expose(&mean_e, 5).unwrap();
    let corrected = cal.correct(dn.view()).unwrap();
    let (t, _, nan) = cal.to_temperature(corrected.view());
    let netd = cal.netd_analytic_k(300.0).unwrap();
    for ((r, c), &v) in t.indexed_iter() {
        match c {
            0..=24 | 55.. => assert!(v.is_nan(), "({r}, {c}) gave {v} K"),
            27..=52 => assert!((v - 300.0).abs() < 6.0 * netd, "({r}, {c}) gave {v} K"),
            _ => assert!(
                v.is_nan() || (v - 300.0).abs() < 6.0 * netd,
                "({r}, {c}) {v}"
            ),
        }
    }
    let expected_min = 64 * (25 + 25);
    assert!(nan >= expected_min && nan <= 64 * (26 + 26), "{nan} NaN");
}

/// Invalid options and clipped calibration levels are errors naming the field.
#[test]
fn invalid_options_are_errors() {
    let (s, model, inst) = setup(&[]);
    let too_few = CalibrationOptions {
        temperatures_k: vec![280.0, 300.0],
        degree: 2,
        ..CalibrationOptions::default()
    };
    let e = Calibration::new(&s, &model, &inst, &too_few).unwrap_err();
    assert!(e.to_string().contains("temperatures_k"), "{e}");
    let saturating = CalibrationOptions {
        temperatures_k: vec![280.0, 400.0],
        ..CalibrationOptions::default()
    };
    let e = Calibration::new(&s, &model, &inst, &saturating).unwrap_err();
    assert!(e.to_string().contains("temperatures_k[1]"), "{e}");
    let zero_frames = CalibrationOptions {
        frames_per_level: 0,
        ..CalibrationOptions::default()
    };
    assert!(Calibration::new(&s, &model, &inst, &zero_frames).is_err());
    assert!(measured_netd(&s, &inst, 300.0, 0.25, 1, None).is_err());
}

/// With `optics.cos4` (15 mm optics: up to 1.8 % fall-off at the corners) the flat field
/// through the instance carries the cos⁴θ roll-off; the NUC, referenced to the on-axis
/// ideal DN, removes it, so a uniform 300 K scene still reads 300 K everywhere.
#[test]
fn cos4_rolloff_is_flattened_by_the_nuc() {
    let s = presets::load(
        "multimir",
        &["optics=15mm".to_string()],
        &[
            "detector.rows=64",
            "detector.cols=80",
            "detector.read_noise_e=200",
            "detector.fpn.prnu_sigma_rel=0.02",
            "detector.fpn.dsnu_sigma_e=2e4",
            "detector.auto_gain.reference_temperature_k=300",
            "optics.cos4=true",
        ]
        .map(String::from),
    )
    .unwrap();
    let s = Sensor::build(&s).unwrap();
    assert!(s.optics.cos4);
    let model = s.detector().clone();
    let inst = DetectorInstance::new(&model, SEED).unwrap();
    let cal = Calibration::new(&s, &model, &inst, &CalibrationOptions::default()).unwrap();
    let (raw, cor) = cal.residual_nonuniformity(&inst, 310.0).unwrap();
    assert!(cor * 10.0 < raw, "raw {raw} corrected {cor}");
    // The scene as the imaging engine delivers it: uniform radiance × cos⁴θ per pixel ×
    // the preset's vignetting table (the engine's map, checked against cos⁴θ and the
    // table in tests/all/field_optics.rs).
    let e = cal.blackbody_electrons(300.0).unwrap();
    let ri = eoir::imaging::relative_illumination::map(&s, 64, 80)
        .unwrap()
        .unwrap();
    let mean_e = ri.mapv(|v| e * v);
    let corrected = cal
        .correct(inst.expose(&mean_e, 1).unwrap().view())
        .unwrap();
    let (t, _, nan) = cal.to_temperature(corrected.view());
    assert_eq!(nan, 0);
    let netd = cal.netd_analytic_k(300.0).unwrap();
    let corner = (t[[0, 0]] + t[[0, 79]] + t[[63, 0]] + t[[63, 79]]) / 4.0;
    let (mt, _, _) = mean_std(t.iter().copied());
    assert!((mt - 300.0).abs() < 0.05, "mean {mt}");
    assert!((corner - 300.0).abs() < 5.0 * netd, "corners {corner}");
}

/// The radiance table is not trimmed where the DN saturate: default MultimIR DN saturate
/// near 323 K, yet an in-band radiance of a 400 K blackbody inverts to 400 K (issue 12).
#[test]
fn radiance_lut_is_not_limited_by_the_adc() {
    let s = presets::load(
        "multimir",
        &[],
        &["detector.rows=8".into(), "detector.cols=8".into()],
    )
    .and_then(|c| Sensor::build(&c))
    .unwrap();
    let model = s.detector().clone();
    let inst = DetectorInstance::new(&model, 1).unwrap();
    let cal = Calibration::new(&s, &model, &inst, &CalibrationOptions::default()).unwrap();
    let (_, dn_top) = cal.lut_range_k();
    assert!(dn_top < 400.0, "DN table top {dn_top} K");
    for t in [350.0, 400.0, 480.0] {
        let l = cal.band_radiance(t);
        let back = cal.radiance_lut().temperature_or_nan(l);
        assert!((back - t).abs() < 1e-3, "{t} K -> {back} K");
    }
}

/// The statistical level averages (exact per-pixel moments, one draw) against exposed
/// frames, on an instance with PRNU, DSNU, per-pixel nonlinearity, read noise and dead, hot
/// and stuck pixels: per pixel, (statistical − exposed) / √(2 var/M) must be N(0, 1) over
/// the array (mean within 4/√N, variance within 10 %), with var the exposed frames' own
/// temporal variance; the clipped masks agree exactly; and the NUC gains of the two routes
/// differ by their combined statistical error only (standardised rms within 10 % of 1).
#[test]
fn statistical_route_matches_exposed_frames() {
    let (s, model, inst) = setup(&[
        "detector.nonlinearity.quadratic_mean_per_e=-2e-9",
        "detector.nonlinearity.quadratic_sigma_per_e=5e-10",
        "detector.defects.dead_fraction=0.003",
        "detector.defects.hot_fraction=0.003",
        "detector.defects.stuck_fraction=0.003",
    ]);
    let m = 16;
    let e = Calibration::new(&s, &model, &inst, &CalibrationOptions::default())
        .unwrap()
        .blackbody_electrons(300.0)
        .unwrap();
    let mean_e = Array2::from_elem((64, 80), e);
    let maps = InstanceMaps::of(&inst);
    let (stat, stat_clip) = flat_field::average(&inst, &maps, &mean_e, m, 42).unwrap();
    // Exposed: M frames, their mean and per-pixel temporal variance.
    let frames: Vec<Array2<f64>> = (0..m)
        .map(|i| {
            inst.expose(&mean_e, 500 + i as u64)
                .unwrap()
                .mapv(|v| v as f64)
        })
        .collect();
    let mean = frames
        .iter()
        .fold(Array2::<f64>::zeros((64, 80)), |a, f| a + f)
        / m as f64;
    let var = frames.iter().fold(Array2::<f64>::zeros((64, 80)), |a, f| {
        a + (f - &mean).mapv(|d| d * d)
    }) / (m - 1) as f64;
    let max = model.max_dn();
    let exposed_clip = frames
        .iter()
        .fold(Array2::from_elem((64, 80), false), |a, f| {
            ndarray::Zip::from(&a)
                .and(f)
                .map_collect(|&c, &v| c || v <= 0.0 || v >= max)
        });
    let defects = inst.defect_map();
    let mut z = Vec::new();
    for ((p, &d), &v) in defects.indexed_iter().zip(var.iter()) {
        if d != 0 {
            // Defects read their fixed value in both routes.
            assert_eq!(stat[p], mean[p], "defect {p:?}");
            continue;
        }
        z.push((stat[p] - mean[p]) / (2.0 * v / m as f64).sqrt());
    }
    let (zm, zs, n) = mean_std(z.into_iter());
    println!("standardised difference: mean {zm:.4}, sd {zs:.4} over {n} pixels");
    assert!(zm.abs() < 4.0 / (n as f64).sqrt(), "mean {zm}");
    // The sample variance of 16 frames scatters by √(2/15): the ratio's sd is ~1.04.
    assert!((zs - 1.04).abs() < 0.1, "sd {zs}");
    assert_eq!(stat_clip, exposed_clip);

    // NUC gains of both routes against each other.
    let cal = |route| {
        let o = CalibrationOptions {
            temperatures_k: vec![280.0, 300.0, 320.0],
            route,
            ..CalibrationOptions::default()
        };
        Calibration::new(&s, &model, &inst, &o).unwrap()
    };
    let (a, b) = (cal(FrameRoute::Statistical), cal(FrameRoute::Exposed));
    let bad = a.bad_pixels().mask() | b.bad_pixels().mask();
    // Fit noise of the slope: the NUC of a level average with σ_l/√M per pixel.
    let (ga, gb) = (a.nuc().coefficients(), b.nuc().coefficients());
    let d: Vec<f64> = bad
        .indexed_iter()
        .filter(|(_, &x)| !x)
        .map(|((i, j), _)| ga[[1, i, j]] - gb[[1, i, j]])
        .collect();
    let (dm, ds, n) = mean_std(d.iter().copied());
    // Predicted sd of one route's slope: the regression of 3 levels with noise σ_l/√M.
    let (c, sc) = a.nuc().signal_normalisation();
    let zs: Vec<f64> = [280.0, 300.0, 320.0]
        .iter()
        .map(|&t| (a.ideal_dn(t) - c) / sc)
        .collect();
    let zbar = zs.iter().sum::<f64>() / 3.0;
    let sxx: f64 = zs.iter().map(|z| (z - zbar).powi(2)).sum();
    // Noise in the signal z (σ_z,l = σ_l/(√M·scale) at level l) moves the fitted slope by
    // −a1 Σ(z_l − z̄)δz_l / Sxx: Var a1 = a1² Σ(z_l − z̄)² σ_z,l² / Sxx²; two independent
    // routes differ by √2 times that.
    let var_slope: f64 = [280.0, 300.0, 320.0]
        .iter()
        .zip(&zs)
        .map(|(&t, z)| (z - zbar).powi(2) * noise_var(&a, &model, t) / m as f64 / (sc * sc))
        .sum::<f64>()
        / (sxx * sxx);
    let a1 = ga[[1, 32, 40]];
    let predicted = a1.abs() * (2.0 * var_slope).sqrt();
    println!("slope differences: mean {dm:.3e}, sd {ds:.3e} (predicted {predicted:.3e}) over {n}");
    assert!(dm.abs() < 4.0 * ds / (n as f64).sqrt());
    assert!((ds / predicted - 1.0).abs() < 0.1, "{ds} vs {predicted}");
    // Both flag every defect.
    for (p, &d) in defects.indexed_iter() {
        if d != 0 {
            assert!(
                a.bad_pixels().mask()[p] && b.bad_pixels().mask()[p],
                "{p:?}"
            );
        }
    }
}

/// `correct` against its definition, assembled here from public parts: the NUC polynomial
/// of the raw DN, NaN where the raw DN is at an ADC limit, and every flagged pixel replaced
/// by the median of its valid (unflagged, finite) 3×3 neighbours, or NaN when it has none.
/// The frame has dead pixels and a saturated block (raw DN at the ADC maximum) wide enough
/// that flagged pixels inside it have no valid neighbour. `to_temperature_f32` gives
/// `to_temperature`'s values rounded to f32 and the same NaN count.
#[test]
fn correct_replaces_flagged_pixels_from_valid_neighbours_only() {
    let (s, model, inst) = setup(&["detector.defects.dead_fraction=0.02"]);
    let cal = Calibration::new(&s, &model, &inst, &CalibrationOptions::default()).unwrap();
    let bad = cal.bad_pixels().mask().clone();
    assert!(bad.iter().filter(|&&b| b).count() >= 20);
    let e300 = cal.blackbody_electrons(300.0).unwrap();
    let e_hot = 50.0 * e300;
    let mean_e = Array2::from_shape_fn((64, 80), |(r, c)| {
        if (20..30).contains(&r) && (30..45).contains(&c) {
            e_hot
        } else {
            e300 * (1.0 + 0.001 * c as f64)
        }
    });
    let dn = inst.expose(&mean_e, 3).unwrap();
    let max = model.max_dn();
    assert!(dn.iter().any(|&v| v as f64 >= max), "the block saturates");
    let got = cal.correct(dn.view()).unwrap();

    let raw = dn.mapv(|v| v as f64);
    let mut nuc = cal.nuc().apply(raw.view()).unwrap();
    for (o, &r) in nuc.iter_mut().zip(&raw) {
        if r <= 0.0 || r >= max {
            *o = f64::NAN;
        }
    }
    let mut isolated = 0;
    for ((r, c), &flagged) in bad.indexed_iter() {
        let want = if flagged {
            let mut v = Vec::new();
            for i in r.saturating_sub(1)..=(r + 1).min(63) {
                for j in c.saturating_sub(1)..=(c + 1).min(79) {
                    if !bad[[i, j]] && nuc[[i, j]].is_finite() {
                        v.push(nuc[[i, j]]);
                    }
                }
            }
            v.sort_by(f64::total_cmp);
            match v.len() {
                0 => {
                    isolated += 1;
                    f64::NAN
                }
                n if n % 2 == 1 => v[n / 2],
                n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
            }
        } else {
            nuc[[r, c]]
        };
        let g = got[[r, c]];
        assert!(
            (g.is_nan() && want.is_nan()) || g == want,
            "({r}, {c}) flagged {flagged}: {g} vs {want}"
        );
    }
    assert!(isolated >= 1, "a flagged pixel inside the saturated block");

    let (t, l, nan) = cal.to_temperature(got.view());
    let (t32, l32, nan32) = cal.to_temperature_f32(got.view());
    assert_eq!(nan, nan32);
    assert!(nan >= 10 * 15);
    for (a, b) in t.iter().zip(&t32).chain(l.iter().zip(&l32)) {
        assert!((a.is_nan() && b.is_nan()) || (*a as f32).to_bits() == b.to_bits());
    }
}
