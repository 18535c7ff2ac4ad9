//! Tests of `eoir::processing` on synthetic frames with known truth (fixed seeds):
//!
//! - NUC: a perfect correction leaves a flat field flat, so the residual non-uniformity
//!   after correction is compared with the raw one (a ratio), on levels not used in the
//!   calibration; the polynomial orders are compared on pixels with known quadratic
//!   response.
//! - Bad pixels: planted defects at known positions; replacement checked against the value
//!   of a linear ramp at the defect, which the median of a symmetric neighbourhood equals.
//! - Photon transfer: a simulated sensor with known K, read noise, η, PRNU and DSNU (the
//!   PRNU/DSNU truth is the realised map's own spatial spread) and a known clip.
//! - NETD: known responsivity and noise; analytic NETD against closed-form derivatives.
//! - Temperature: the Stefan–Boltzmann total radiance σT⁴/π, inverted in closed form.

use eoir::processing::bad_pixels::{detect, replace, BadPixelCriteria, BadPixelMap, DefectKind};
use eoir::processing::netd::{analytic_netd, measured_netd};
use eoir::processing::nuc::{residual_nonuniformity, NucCoefficients};
use eoir::processing::photon_transfer::{
    photon_transfer, FpnStacks, FramePair, PtcLevel, PtcOptions,
};
use eoir::processing::temperature::{apparent_temperature, LinearCalibration};
use eoir::processing::{mean_frame, to_f64};
use eoir::radiometry::TemperatureLut;
use eoir::Error;
use ndarray::{Array2, Array3, Axis};
use rand::{RngExt, SeedableRng};
use rand_distr::{Normal, Poisson};
use rand_xoshiro::Xoshiro256PlusPlus;

fn rng(seed: u64) -> Xoshiro256PlusPlus {
    Xoshiro256PlusPlus::seed_from_u64(seed)
}

fn normal_map(r: &mut Xoshiro256PlusPlus, n: usize, mean: f64, sigma: f64) -> Array2<f64> {
    let d = Normal::new(mean, sigma).unwrap();
    Array2::from_shape_fn((n, n), |_| r.sample(d))
}

/// Spatial σ / mean of a map (population normalisation), computed directly.
fn spread(a: &Array2<f64>) -> f64 {
    let m = a.mean().unwrap();
    (a.mapv(|v| (v - m) * (v - m)).mean().unwrap()).sqrt() / m
}

// ---------------------------------------------------------------------------------------
// NUC
// ---------------------------------------------------------------------------------------

/// A pixel array with response x = offset + gain·φ·(1 + β·φ/φ_max) plus temporal noise.
struct SyntheticArray {
    gain: Array2<f64>,
    offset: Array2<f64>,
    beta: Array2<f64>,
    phi_max: f64,
    noise_dn: f64,
}

impl SyntheticArray {
    fn expected(&self, phi: f64) -> Array2<f64> {
        let mut out = self.offset.clone();
        ndarray::Zip::from(&mut out)
            .and(&self.gain)
            .and(&self.beta)
            .for_each(|o, &g, &b| *o += g * phi * (1.0 + b * phi / self.phi_max));
        out
    }

    /// Average of `m` noisy frames at flux φ.
    fn averaged(&self, r: &mut Xoshiro256PlusPlus, phi: f64, m: usize) -> Array2<f64> {
        let e = self.expected(phi);
        let d = Normal::new(0.0, self.noise_dn / (m as f64).sqrt()).unwrap();
        e.mapv(|v| v + r.sample(d))
    }
}

fn linear_array(r: &mut Xoshiro256PlusPlus, n: usize) -> SyntheticArray {
    SyntheticArray {
        gain: normal_map(r, n, 1.0, 0.05),
        // Offset σ = 10 % of the mid-range signal (1000).
        offset: normal_map(r, n, 200.0, 100.0),
        beta: Array2::zeros((n, n)),
        phi_max: 2000.0,
        noise_dn: 2.0,
    }
}

#[test]
fn nuc_two_point_cuts_residual_nonuniformity_tenfold() {
    let mut r = rng(1);
    let n = 128;
    let arr = linear_array(&mut r, n);
    let lo = arr.averaged(&mut r, 500.0, 16);
    let hi = arr.averaged(&mut r, 1500.0, 16);
    let nuc = NucCoefficients::fit(&[(500.0, lo.view()), (1500.0, hi.view())], 1).unwrap();
    assert!(nuc.rank_deficient().is_empty());
    // A single noisy frame at a level not used in the calibration.
    for phi in [1000.0, 300.0, 1800.0] {
        let flat = arr.averaged(&mut r, phi, 1);
        let raw = residual_nonuniformity(flat.view(), None).unwrap();
        let corrected = nuc.apply(flat.view()).unwrap();
        let res = residual_nonuniformity(corrected.view(), None).unwrap();
        assert!(raw > 0.05, "raw non-uniformity {raw}");
        assert!(raw / res >= 10.0, "φ = {phi}: raw {raw}, corrected {res}");
        // The correction maps onto the reference scale: the mean equals the flux.
        let mean = corrected.mean().unwrap();
        assert!((mean - phi).abs() < 0.01 * phi, "mean {mean} vs {phi}");
    }
}

#[test]
fn nuc_polynomial_orders_on_nonlinear_pixels() {
    let mut r = rng(2);
    let n = 96;
    let mut arr = linear_array(&mut r, n);
    arr.beta = normal_map(&mut r, n, 0.05, 0.03);
    arr.noise_dn = 0.5;
    let phis = [200.0, 600.0, 1000.0, 1400.0, 1800.0];
    let frames: Vec<Array2<f64>> = phis.iter().map(|&p| arr.averaged(&mut r, p, 64)).collect();
    let levels: Vec<(f64, ndarray::ArrayView2<f64>)> = phis
        .iter()
        .zip(&frames)
        .map(|(&p, f)| (p, f.view()))
        .collect();
    let fits: Vec<NucCoefficients> = (1..=3)
        .map(|d| NucCoefficients::fit(&levels, d).unwrap())
        .collect();
    for phi in [400.0, 800.0, 1250.0, 1650.0] {
        // Noise-free flat field, so only the NUC model error remains.
        let flat = arr.expected(phi);
        let raw = residual_nonuniformity(flat.view(), None).unwrap();
        let res: Vec<f64> = fits
            .iter()
            .map(|f| residual_nonuniformity(f.apply(flat.view()).unwrap().view(), None).unwrap())
            .collect();
        assert!(res[0] < raw, "φ = {phi}: degree 1 {} vs raw {raw}", res[0]);
        assert!(
            res[1] < 0.5 * res[0],
            "φ = {phi}: degree 2 {} should beat degree 1 {}",
            res[1],
            res[0]
        );
        assert!(
            res[2] <= 1.1 * res[1],
            "φ = {phi}: degree 3 {} vs degree 2 {}",
            res[2],
            res[1]
        );
    }
}

#[test]
fn nuc_too_few_levels_and_bad_shapes_are_errors() {
    let a = Array2::<f64>::from_elem((4, 4), 1.0);
    let b = Array2::<f64>::from_elem((4, 4), 2.0);
    let c = Array2::<f64>::from_elem((4, 5), 3.0);
    let err = NucCoefficients::fit(&[(1.0, a.view()), (2.0, b.view())], 2).unwrap_err();
    assert!(matches!(err, Error::InvalidParameter { .. }), "{err}");
    assert!(err.to_string().contains("levels"));
    assert!(NucCoefficients::fit(&[(1.0, a.view())], 1).is_err());
    assert!(NucCoefficients::fit(&[(1.0, a.view()), (2.0, c.view())], 1).is_err());
    // Equal levels carry no information about the gain.
    assert!(NucCoefficients::fit(&[(1.0, a.view()), (2.0, a.view())], 1).is_err());
    let nuc = NucCoefficients::fit(&[(1.0, a.view()), (2.0, b.view())], 1).unwrap();
    assert!(nuc.apply(c.view()).is_err());
}

#[test]
fn nuc_dead_pixel_is_rank_deficient() {
    let mut r = rng(3);
    let arr = linear_array(&mut r, 16);
    let mut lo = arr.averaged(&mut r, 500.0, 4);
    let mut hi = arr.averaged(&mut r, 1500.0, 4);
    lo[[3, 7]] = 42.0;
    hi[[3, 7]] = 42.0;
    hi[[5, 5]] = f64::NAN;
    let nuc = NucCoefficients::fit(&[(500.0, lo.view()), (1500.0, hi.view())], 1).unwrap();
    assert_eq!(nuc.rank_deficient(), &[(3, 7), (5, 5)]);
    // The dead pixel falls back to the mean reference; the NaN pixel stays NaN.
    let out = nuc.apply(lo.view()).unwrap();
    assert!((out[[3, 7]] - 1000.0).abs() < 1e-9);
    assert!(out[[5, 5]].is_nan());
    let map = nuc.rank_deficient_map();
    assert_eq!(map.count(), 2);
    let res = residual_nonuniformity(out.view(), Some(&map)).unwrap();
    assert!(res.is_finite());
}

#[test]
fn nuc_save_load_round_trip_is_exact() {
    let mut r = rng(4);
    let mut arr = linear_array(&mut r, 24);
    arr.beta = normal_map(&mut r, 24, 0.05, 0.03);
    let phis = [100.0, 700.0, 1300.0, 1900.0];
    let frames: Vec<Array2<f64>> = phis.iter().map(|&p| arr.averaged(&mut r, p, 4)).collect();
    let mut frames_dead = frames.clone();
    for f in frames_dead.iter_mut() {
        f[[1, 2]] = 5.0;
    }
    let levels: Vec<(f64, ndarray::ArrayView2<f64>)> = phis
        .iter()
        .zip(&frames_dead)
        .map(|(&p, f)| (p, f.view()))
        .collect();
    let nuc = NucCoefficients::fit(&levels, 3).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nuc.npy");
    nuc.save(&path).unwrap();
    assert!(dir.path().join("nuc.json").exists());
    let back = NucCoefficients::load(&path).unwrap();
    assert_eq!(back, nuc);
    assert_eq!(back.rank_deficient(), &[(1, 2)]);
    let test = arr.expected(1000.0);
    assert_eq!(
        back.apply(test.view()).unwrap(),
        nuc.apply(test.view()).unwrap()
    );

    // A sidecar that disagrees with the array is rejected, naming the file.
    let json = std::fs::read_to_string(dir.path().join("nuc.json")).unwrap();
    std::fs::write(
        dir.path().join("nuc.json"),
        json.replace("\"degree\": 3", "\"degree\": 2"),
    )
    .unwrap();
    let err = NucCoefficients::load(&path).unwrap_err();
    assert!(matches!(err, Error::Format { .. }), "{err}");
    assert!(NucCoefficients::load(&dir.path().join("missing.npy")).is_err());
    assert!(nuc.save(&dir.path().join("nuc.bin")).is_err());
}

// ---------------------------------------------------------------------------------------
// Bad pixels
// ---------------------------------------------------------------------------------------

#[test]
fn bad_pixels_planted_defects_are_found() {
    let mut r = rng(5);
    let n = 128;
    let offset = normal_map(&mut r, n, 100.0, 5.0);
    let gain = normal_map(&mut r, n, 1.0, 0.02);
    let noise = Normal::new(0.0, 0.5).unwrap();
    let mut dark = offset.mapv(|o| o + r.sample(noise));
    let mut bright = &offset + &(gain.mapv(|g| 1000.0 * g)) + &normal_map(&mut r, n, 0.0, 0.5);

    // 41 distinct random positions, then a defect kind for each.
    let mut positions: Vec<(usize, usize)> = Vec::new();
    while positions.len() < 41 {
        let p = (r.random_range(0..n), r.random_range(0..n));
        if !positions.contains(&p) {
            positions.push(p);
        }
    }
    let mut plant = Vec::new();
    for (k, &p) in positions.iter().enumerate() {
        let kind = match k {
            0..=9 => {
                dark[p] = 0.0;
                bright[p] = 0.3;
                DefectKind::Dead
            }
            10..=19 => {
                dark[p] = 4095.0;
                bright[p] = 4095.0;
                DefectKind::Stuck
            }
            20..=29 => {
                dark[p] += 300.0;
                bright[p] += 300.0;
                DefectKind::Hot
            }
            30..=34 => {
                bright[p] = dark[p] + 500.0;
                DefectKind::GainOutlier
            }
            35..=39 => {
                dark[p] -= 80.0;
                bright[p] -= 80.0;
                DefectKind::Cold
            }
            _ => {
                bright[p] = f64::NAN;
                DefectKind::NonFinite
            }
        };
        plant.push((p, kind));
    }

    let det = detect(dark.view(), bright.view(), &BadPixelCriteria::default()).unwrap();
    for (p, kind) in &plant {
        assert!(
            det.map.is_bad(p.0, p.1),
            "planted {kind:?} at {p:?} not found"
        );
        assert_eq!(det.kind[*p], Some(*kind), "at {p:?}");
    }
    let false_positives = det.map.count() - plant.len();
    assert!(
        false_positives as f64 <= 1e-3 * (n * n) as f64,
        "{false_positives} false positives"
    );
    assert_eq!(det.count(DefectKind::Dead), 10);
    assert!((det.median_response - 1000.0).abs() < 5.0);
    assert!((det.sigma_response / 20.0 - 1.0).abs() < 0.1);
}

#[test]
fn bad_pixel_replacement_gives_neighbour_median() {
    // A linear ramp: any neighbourhood symmetric about a pixel has the pixel's own value
    // as its median.
    let ramp = Array2::from_shape_fn((40, 50), |(i, j)| 100.0 + 2.0 * i as f64 + 3.0 * j as f64);
    let mut frame = ramp.clone();
    let mut map = BadPixelMap::new(40, 50);
    // Isolated defect: 3×3 median.
    frame[[10, 20]] = 1e6;
    map.set(10, 20, true).unwrap();
    // A 3×3 cluster: the centre needs the 5×5 ring.
    for i in 24..=26 {
        for j in 30..=32 {
            frame[[i, j]] = f64::NAN;
            map.set(i, j, true).unwrap();
        }
    }
    // Corner: neighbours (0,1) = 103, (1,0) = 102, (1,1) = 105 → median 103.
    frame[[0, 0]] = -5.0;
    map.set(0, 0, true).unwrap();
    let out = replace(frame.view(), &map).unwrap();
    assert_eq!(out[[10, 20]], ramp[[10, 20]]);
    assert_eq!(out[[25, 31]], ramp[[25, 31]]);
    assert_eq!(out[[0, 0]], 103.0);
    // Unflagged pixels are untouched; every flagged one is finite now.
    assert_eq!(out[[5, 5]], ramp[[5, 5]]);
    assert!(out.iter().all(|v| v.is_finite()));
    // Shape mismatch and all-bad maps are errors.
    assert!(replace(frame.view(), &BadPixelMap::new(3, 3)).is_err());
    let all_bad = BadPixelMap::from_mask(Array2::from_elem((40, 50), true));
    assert!(replace(frame.view(), &all_bad).is_err());
    assert!(map.set(40, 0, true).is_err());
}

// ---------------------------------------------------------------------------------------
// Photon transfer
// ---------------------------------------------------------------------------------------

struct PtcSensor {
    k_dn_per_e: f64,
    read_noise_e: f64,
    eta: f64,
    bias_dn: f64,
    full_well_e: f64,
    /// Per-pixel relative gain (PRNU) and dark offset in electrons (DSNU).
    prnu: Array2<f64>,
    dsnu_e: Array2<f64>,
}

impl PtcSensor {
    /// One frame at μ_p photons per pixel: Poisson electrons, clipped at the full well,
    /// read noise, conversion to DN and rounding (integer ADC output).
    fn frame(&self, r: &mut Xoshiro256PlusPlus, photons: f64) -> Array2<f64> {
        let read = Normal::new(0.0, self.read_noise_e).unwrap();
        let mut out = Array2::zeros(self.prnu.dim());
        ndarray::Zip::from(&mut out)
            .and(&self.prnu)
            .and(&self.dsnu_e)
            .for_each(|o, &g, &d| {
                let mean_e = self.eta * photons * g;
                let e = if mean_e > 0.0 {
                    r.sample(Poisson::new(mean_e).unwrap())
                } else {
                    0.0
                };
                let e = e.min(self.full_well_e) + d + r.sample(read);
                *o = (self.bias_dn + self.k_dn_per_e * e).round();
            });
        out
    }

    fn stack(&self, r: &mut Xoshiro256PlusPlus, photons: f64, l: usize) -> Array3<f64> {
        let (rows, cols) = self.prnu.dim();
        let mut s = Array3::zeros((l, rows, cols));
        for mut plane in s.outer_iter_mut() {
            plane.assign(&self.frame(r, photons));
        }
        s
    }
}

fn ptc_sensor(r: &mut Xoshiro256PlusPlus, n: usize) -> PtcSensor {
    PtcSensor {
        k_dn_per_e: 0.25,
        read_noise_e: 12.0,
        eta: 0.6,
        bias_dn: 100.0,
        full_well_e: 20_000.0,
        prnu: normal_map(r, n, 1.0, 0.01),
        dsnu_e: normal_map(r, n, 0.0, 8.0),
    }
}

#[test]
fn photon_transfer_recovers_sensor_parameters() {
    let mut r = rng(6);
    let n = 256;
    let s = ptc_sensor(&mut r, n);
    // 20 levels up to 1.2 × the full well, equally spaced in photons.
    let photons_sat = s.full_well_e / s.eta;
    let photons: Vec<f64> = (1..=20)
        .map(|k| 1.2 * photons_sat * k as f64 / 20.0)
        .collect();
    let pairs: Vec<(Array2<f64>, Array2<f64>)> = photons
        .iter()
        .map(|&p| (s.frame(&mut r, p), s.frame(&mut r, p)))
        .collect();
    let dark = (s.frame(&mut r, 0.0), s.frame(&mut r, 0.0));
    let levels: Vec<PtcLevel> = pairs
        .iter()
        .zip(&photons)
        .map(|((a, b), &p)| PtcLevel {
            pair: FramePair {
                a: a.view(),
                b: b.view(),
            },
            photons_per_pixel: Some(p),
        })
        .collect();
    let dark_stack = s.stack(&mut r, 0.0, 16);
    let bright_stack = s.stack(&mut r, 0.5 * photons_sat, 16);
    let stacks = FpnStacks {
        dark: dark_stack.view(),
        bright: bright_stack.view(),
    };
    let options = PtcOptions {
        quantisation_step_dn: 1.0,
        ..PtcOptions::default()
    };
    let dark_pair = FramePair {
        a: dark.0.view(),
        b: dark.1.view(),
    };
    let res = photon_transfer(dark_pair, &levels, Some(&stacks), &options).unwrap();

    let rel = |a: f64, b: f64| (a - b).abs() / b.abs();
    assert!(
        rel(res.conversion_gain_dn_per_e, s.k_dn_per_e) < 0.01,
        "K = {}",
        res.conversion_gain_dn_per_e
    );
    assert!(
        rel(res.read_noise_e, s.read_noise_e) < 0.03,
        "read noise {} e-",
        res.read_noise_e
    );
    assert!(
        rel(res.read_noise_dn, 3.0) < 0.03,
        "read noise {} DN",
        res.read_noise_dn
    );
    let eta = res.quantum_efficiency.unwrap();
    assert!(rel(eta, s.eta * s.prnu.mean().unwrap()) < 0.02, "η = {eta}");
    // PRNU and DSNU truth: the realised maps' own spatial spread.
    let prnu_true = spread(&s.prnu);
    assert!(
        rel(res.prnu, prnu_true) < 0.05,
        "PRNU {} vs {prnu_true}",
        res.prnu
    );
    let d_mean = s.dsnu_e.mean().unwrap();
    let dsnu_true = (s
        .dsnu_e
        .mapv(|v| (v - d_mean) * (v - d_mean))
        .mean()
        .unwrap())
    .sqrt();
    assert!(
        rel(res.dsnu_e, dsnu_true) < 0.05,
        "DSNU {} vs {dsnu_true}",
        res.dsnu_e
    );
    // Saturation at the clip: the variance peaks within one level step below the full well.
    let step_e = 1.2 * s.full_well_e / 20.0;
    assert!(
        res.saturation_capacity_e <= s.full_well_e
            && res.saturation_capacity_e >= s.full_well_e - 1.5 * step_e,
        "saturation capacity {} e-",
        res.saturation_capacity_e
    );
    assert!(res.saturation_level >= 14 && res.saturation_level <= 16);
    assert!(res.fit_levels >= 9, "{} fit levels", res.fit_levels);
    assert!((res.dark_mean_dn - s.bias_dn).abs() < 0.5);

    // Without stacks the pairs give DSNU / PRNU too (fewer frames, looser).
    let res2 = photon_transfer(dark_pair, &levels, None, &options).unwrap();
    assert_eq!(res2.conversion_gain_dn_per_e, res.conversion_gain_dn_per_e);
    assert!(
        rel(res2.prnu, prnu_true) < 0.1,
        "PRNU (pairs) {}",
        res2.prnu
    );
    assert!(
        rel(res2.dsnu_e, dsnu_true) < 0.1,
        "DSNU (pairs) {}",
        res2.dsnu_e
    );
}

#[test]
fn photon_transfer_rejects_bad_input() {
    let a = Array2::<f64>::zeros((8, 8));
    let b = Array2::<f64>::zeros((8, 9));
    let pair = FramePair {
        a: a.view(),
        b: a.view(),
    };
    let lvl = PtcLevel {
        pair,
        photons_per_pixel: None,
    };
    let opts = PtcOptions::default();
    assert!(photon_transfer(pair, &[lvl], None, &opts).is_err());
    let bad = PtcLevel {
        pair: FramePair {
            a: a.view(),
            b: b.view(),
        },
        photons_per_pixel: None,
    };
    assert!(photon_transfer(pair, &[lvl, bad], None, &opts).is_err());
    let with = PtcLevel {
        photons_per_pixel: Some(10.0),
        ..lvl
    };
    assert!(photon_transfer(pair, &[lvl, with], None, &opts).is_err());
    let bad_opts = PtcOptions {
        fit_fraction: 1.5,
        ..opts
    };
    assert!(photon_transfer(pair, &[lvl, lvl], None, &bad_opts).is_err());
}

// ---------------------------------------------------------------------------------------
// NETD
// ---------------------------------------------------------------------------------------

#[test]
fn measured_netd_matches_noise_over_responsivity() {
    let mut r = rng(7);
    let n = 64;
    let l = 32;
    let resp = normal_map(&mut r, n, 20.0, 1.0); // DN/K
    let offset = normal_map(&mut r, n, 5000.0, 200.0);
    let sigma = 4.0;
    let noise = Normal::new(0.0, sigma).unwrap();
    let (t, dt) = (300.0, 1.0);
    let mut stack = |temp: f64| {
        Array3::from_shape_fn((l, n, n), |(_, i, j)| {
            offset[[i, j]] + resp[[i, j]] * (temp - 290.0) + r.sample(noise)
        })
    };
    let cold = stack(t);
    let hot = stack(t + dt);
    let m = measured_netd(cold.view(), hot.view(), dt, None).unwrap();
    let truth = sigma / resp.mean().unwrap();
    assert!(
        (m.netd_k / truth - 1.0).abs() < 0.01,
        "NETD {} vs {truth}",
        m.netd_k
    );
    assert!((m.temporal_noise_dn / sigma - 1.0).abs() < 0.01);
    assert!((m.responsivity_dn_per_k / resp.mean().unwrap() - 1.0).abs() < 0.002);
    assert_eq!(m.pixels, n * n);
    // Excluding pixels: they become NaN in the per-pixel map.
    let mut map = BadPixelMap::new(n, n);
    map.set(0, 0, true).unwrap();
    let m2 = measured_netd(cold.view(), hot.view(), dt, Some(&map)).unwrap();
    assert_eq!(m2.pixels, n * n - 1);
    assert!(m2.pixel_netd_k[[0, 0]].is_nan());
    assert!((m2.median_pixel_netd_k / truth - 1.0).abs() < 0.1);
    // One frame cannot give a temporal noise.
    let one = cold.slice(ndarray::s![0..1, .., ..]);
    assert!(measured_netd(one, hot.view(), dt, None).is_err());
    assert!(measured_netd(cold.view(), hot.view(), 0.0, None).is_err());
}

#[test]
fn analytic_netd_against_closed_forms() {
    // Linear response: NETD = σ / slope exactly.
    let netd = analytic_netd(|t| 1000.0 + 25.0 * t, 300.0, 5.0).unwrap();
    assert!((netd - 0.2).abs() < 1e-12, "{netd}");
    // S = c T⁴: dS/dT = 4 c T³.
    let c = 1e-6;
    let netd = analytic_netd(move |t| c * t.powi(4), 300.0, 3.0).unwrap();
    let truth = 3.0 / (4.0 * c * 300f64.powi(3));
    assert!((netd / truth - 1.0).abs() < 1e-5, "{netd} vs {truth}");
    // Monochromatic Planck response at 10 µm: dL/dT = L · x eˣ / ((eˣ − 1) T), x = c2/(λT).
    let c2 = 6.626_070_15e-34 * 299_792_458.0 / 1.380_649e-23;
    let lambda = 10e-6;
    let planck = move |t: f64| 1.0 / ((c2 / (lambda * t)).exp() - 1.0) * 1e4;
    let t = 290.0;
    let x: f64 = c2 / (lambda * t);
    let dl = planck(t) * x * x.exp() / ((x.exp() - 1.0) * t);
    let netd = analytic_netd(planck, t, 2.0).unwrap();
    assert!((netd / (2.0 / dl) - 1.0).abs() < 1e-5);
    assert!(analytic_netd(|_| 7.0, 300.0, 1.0).is_err());
    assert!(analytic_netd(|t| t, -1.0, 1.0).is_err());
}

// ---------------------------------------------------------------------------------------
// Apparent temperature
// ---------------------------------------------------------------------------------------

const SIGMA_SB: f64 = 5.670_374_419e-8;

fn total_radiance(t: f64) -> f64 {
    SIGMA_SB * t.powi(4) / std::f64::consts::PI
}

#[test]
fn apparent_temperature_image_inverts_stefan_boltzmann() {
    let lut = TemperatureLut::new(total_radiance, 200.0, 400.0).unwrap();
    let truth = Array2::from_shape_fn((20, 30), |(i, j)| 210.0 + 5.0 * i as f64 + 0.37 * j as f64);
    let mut radiance = truth.mapv(total_radiance);
    radiance[[0, 0]] = total_radiance(150.0);
    radiance[[1, 0]] = total_radiance(500.0);
    radiance[[2, 0]] = f64::NAN;
    let img = apparent_temperature(radiance.view(), &lut);
    assert_eq!(img.nan_count, 3);
    for ((i, j), &t) in img.temperature_k.indexed_iter() {
        if j == 0 && i < 3 {
            assert!(t.is_nan());
            continue;
        }
        // Closed-form inverse T = (π L / σ)^(1/4).
        let exact = (std::f64::consts::PI * radiance[[i, j]] / SIGMA_SB).powf(0.25);
        assert!((t - exact).abs() < 1e-6, "{t} vs {exact}");
        assert!((t - truth[[i, j]]).abs() < 1e-6);
    }
}

#[test]
fn linear_calibration_dn_to_temperature() {
    let lut = TemperatureLut::new(total_radiance, 250.0, 350.0).unwrap();
    // DN = 40 · L + 1200, from two blackbody points.
    let (g, o) = (40.0, 1200.0);
    let l1 = total_radiance(270.0);
    let l2 = total_radiance(330.0);
    let cal = LinearCalibration::from_two_points((l1, g * l1 + o), (l2, g * l2 + o)).unwrap();
    assert!((cal.gain_dn_per_radiance - g).abs() < 1e-9);
    assert!((cal.offset_dn - o).abs() < 1e-7);
    let truth = Array2::from_shape_fn((8, 8), |(i, j)| 260.0 + 10.0 * i as f64 + j as f64);
    let dn = cal.dn_image(truth.mapv(total_radiance).view());
    let img = cal.temperature_image(dn.view(), &lut);
    assert_eq!(img.nan_count, 0);
    for (t, tt) in img.temperature_k.iter().zip(truth.iter()) {
        assert!((t - tt).abs() < 1e-6);
    }
    assert!((cal.radiance(cal.dn(12.5)) - 12.5).abs() < 1e-12);
    // Three collinear points fit exactly; degenerate points are errors.
    let cal3 = LinearCalibration::fit(&[(1.0, 1240.0), (2.0, 1280.0), (4.0, 1360.0)]).unwrap();
    assert!((cal3.gain_dn_per_radiance - g).abs() < 1e-9);
    assert!(LinearCalibration::from_two_points((1.0, 5.0), (1.0, 6.0)).is_err());
    assert!(LinearCalibration::from_two_points((1.0, 5.0), (2.0, 5.0)).is_err());
    assert!(LinearCalibration::fit(&[(1.0, f64::NAN), (2.0, 3.0)]).is_err());
}

#[test]
fn helpers_convert_and_average() {
    let raw = Array2::<u16>::from_shape_fn((3, 4), |(i, j)| (i * 4 + j) as u16);
    let f = to_f64(raw.view());
    assert_eq!(f[[2, 3]], 11.0);
    let stack = Array3::from_shape_fn((4, 3, 4), |(k, i, j)| (k + i + j) as f64);
    let m = mean_frame(stack.view()).unwrap();
    assert_eq!(m[[1, 1]], 1.5 + 2.0);
    assert!(mean_frame(stack.slice_axis(Axis(0), (0..0).into())).is_err());
}

/// Defect clusters in one image: on a Gaussian-blurred slanted edge with noise, an
/// adjacent dead pair, a vertical hot pair, a dead line of three, an L-shaped stuck
/// triple and single dead and hot pixels are all found (the 3 × 3 impulse test misses
/// the pairs: each compares with its equally bad partner), no edge pixel is flagged, and
/// the replaced values lie within the noise of the clean image. A 4 × 4 clipped blob at
/// full scale is reported as saturated, not as a defect.
#[test]
fn image_defect_clusters_are_found_and_edges_are_not() {
    use eoir::processing::bad_pixels::find_image_defects;
    use rand_distr::Distribution;
    let mut r = rng(11);
    let noise = Normal::new(0.0, 5.0).unwrap();
    let (rows, cols) = (64, 64);
    let clean = Array2::from_shape_fn((rows, cols), |(y, x)| {
        let d = (x as f64 - 32.0) * 0.996 - (y as f64 - 32.0) * 0.087;
        1000.0 + 3000.0 * 0.5 * (1.0 + libm::erf(d / (1.2 * std::f64::consts::SQRT_2)))
    });
    let mut img = clean.mapv(|v| (v + noise.sample(&mut r)).round());
    let full = 16383.0;
    let defects: Vec<((usize, usize), f64)> = vec![
        ((10, 10), 0.0),
        ((10, 11), 0.0),
        ((20, 50), full),
        ((21, 50), full),
        ((40, 5), 0.0),
        ((40, 6), 0.0),
        ((40, 7), 0.0),
        ((50, 45), 9000.0),
        ((50, 46), 9000.0),
        ((51, 45), 9000.0),
        ((5, 40), 0.0),
        ((55, 20), full),
    ];
    for ((y, x), v) in &defects {
        img[[*y, *x]] = *v;
    }
    // A clipped hot spot of the scene.
    for y in 28..32 {
        for x in 54..58 {
            img[[y, x]] = full;
        }
    }
    let found = find_image_defects(img.view(), 6.0, Some(full)).unwrap();
    for ((y, x), _) in &defects {
        assert!(found.defects.is_bad(*y, *x), "missed ({y}, {x})");
    }
    assert_eq!(
        found.defects.count(),
        defects.len(),
        "{:?}",
        found.defects.positions()
    );
    assert_eq!(found.saturated.count(), 16);
    assert_eq!(found.clusters, 6);
    assert_eq!(found.largest_cluster, 3);
    let fixed = replace(img.view(), &found.defects).unwrap();
    for ((y, x), _) in &defects {
        let e = (fixed[[*y, *x]] - clean[[*y, *x]]).abs();
        assert!(
            e < 30.0,
            "({y}, {x}): {} vs {}",
            fixed[[*y, *x]],
            clean[[*y, *x]]
        );
    }
    // Without an ADC limit the statistical test alone still finds every cluster.
    let stat = find_image_defects(img.view(), 6.0, None).unwrap();
    for ((y, x), _) in &defects {
        assert!(
            stat.defects.is_bad(*y, *x),
            "statistical test missed ({y}, {x})"
        );
    }
}

/// Immerkær's operator with a median scale: white Gaussian noise of σ = 3 on a bilinear
/// ramp with a 500-unit step is recovered within 3 % (the operator removes the ramp, the
/// median ignores the step's pixels); a masked column removes the windows touching it.
#[test]
fn immerkaer_recovers_white_noise_on_a_ramp_with_an_edge() {
    use eoir::processing::noise_estimate::immerkaer_sigma;
    use rand_distr::Distribution;
    let mut r = rng(7);
    let n = Normal::new(0.0, 3.0).unwrap();
    let img = Array2::from_shape_fn((128, 128), |(y, x)| {
        let step = if x > 64 { 500.0 } else { 0.0 };
        100.0 + 0.7 * y as f64 - 0.3 * x as f64 + 0.01 * (y * x) as f64 + step + n.sample(&mut r)
    });
    let e = immerkaer_sigma(img.view(), None).unwrap();
    assert!((e.sigma / 3.0 - 1.0).abs() < 0.03, "{}", e.sigma);
    assert_eq!(e.pixels, 126 * 126);
    let mut m = BadPixelMap::new(128, 128);
    for y in 0..128 {
        m.set(y, 10, true).unwrap();
    }
    assert_eq!(
        immerkaer_sigma(img.view(), Some(&m)).unwrap().pixels,
        126 * 123
    );
}
