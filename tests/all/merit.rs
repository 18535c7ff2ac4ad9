//! Figures of merit (docs/figures-of-merit.md): analytic against measured on frames the
//! same sensor simulates, the TTP value against an independent quadrature of the printed
//! CTF_sys table, and the range trends.

use eoir::merit::assess::{self, AssessOptions, Assessment, TargetSpec};
use eoir::merit::ttp::{self, CtfSample};
use eoir::sensor::{presets, Sensor};

fn sensor(preset: &str, options: &[&str], sets: &[&str]) -> Sensor {
    let options: Vec<String> = options.iter().map(|s| s.to_string()).collect();
    let mut all = vec![
        "detector.rows=64".to_string(),
        "detector.cols=64".to_string(),
    ];
    all.extend(sets.iter().map(|s| s.to_string()));
    Sensor::build(&presets::load(preset, &options, &all).unwrap()).unwrap()
}

/// The fixed-pattern overrides of the thermal assessment: every component the detector
/// model can predict is on.
/// The per-pixel pattern is kept small enough that its leakage into the row and column
/// means (σ_vh²/64) does not swamp the row and column offsets.
const FPN: [&str; 4] = [
    "detector.fpn.prnu_sigma_rel=0.001",
    "detector.fpn.dsnu_sigma_e=2000",
    "detector.fpn.row_sigma_e=2000",
    "detector.fpn.column_sigma_e=2500",
];

fn rel(a: f64, b: f64) -> f64 {
    (a / b - 1.0).abs()
}

/// Composite Simpson over the table's evenly spaced frequencies, ξ = 0 included with a
/// zero integrand (an independent route to ∫ √(C/CTF_sys) dξ; the library integrates by
/// the trapezoid rule).
fn simpson(table: &[CtfSample], contrast: f64) -> f64 {
    let mut y = vec![0.0];
    y.extend(table.iter().map(|s| {
        if contrast > s.ctf_sys {
            (contrast / s.ctf_sys).sqrt()
        } else {
            0.0
        }
    }));
    let h = table[0].freq_cy_per_mrad;
    assert!(
        table.len() % 2 == 0,
        "Simpson needs an even number of intervals"
    );
    let n = y.len() - 1;
    let mut s = y[0] + y[n];
    for (i, v) in y.iter().enumerate().take(n).skip(1) {
        s += if i % 2 == 1 { 4.0 * v } else { 2.0 * v };
    }
    s * h / 3.0
}

#[test]
fn thermal_assessment_measured_agrees_with_predicted() {
    let s = sensor("multimir", &[], &FPN);
    let a: Assessment = assess::assess(&s, &AssessOptions::default()).unwrap();
    let (an, me) = (&a.analytic, a.measured.as_ref().unwrap());
    eprintln!("{}", serde_json::to_string_pretty(&me.noise3d).unwrap());
    eprintln!(
        "NETD {:?} vs {:?}; RER {:?} (ESF {:?}) vs {:?}; MTF50 {:?} vs {:?}; notes {:?}",
        me.netd_k,
        an.netd_k,
        me.rer,
        me.rer_esf,
        me.rer_analytic_along_normal,
        me.mtf50_cy_per_px,
        an.mtf50_cy_per_px,
        me.notes
    );
    // 3-D noise in DN: white noise and per-pixel pattern from 131 072 and 4 096 samples
    // (scatter ≈ 0.2 % and 1.1 %) within 5 %; row and column offsets from 64 draws each
    // (sampling scatter ≈ 9 %) within 25 %; the components the model does not have stay
    // below 5 % of the white noise.
    let (p, m) = (an.noise3d.dn, me.noise3d.dn);
    assert!(rel(m.sigma_tvh, p.sigma_tvh) < 0.05, "{m:?} vs {p:?}");
    assert!(rel(m.sigma_vh, p.sigma_vh) < 0.05, "{m:?} vs {p:?}");
    assert!(rel(m.sigma_v, p.sigma_v) < 0.25, "{m:?} vs {p:?}");
    assert!(rel(m.sigma_h, p.sigma_h) < 0.25, "{m:?} vs {p:?}");
    for x in [m.sigma_t, m.sigma_tv, m.sigma_th] {
        assert!(x < 0.05 * p.sigma_tvh, "{m:?}");
    }
    // The same in electrons and kelvin (one gain, one responsivity).
    let (pk, mk) = (an.noise3d.kelvin.unwrap(), me.noise3d.kelvin.unwrap());
    assert!(rel(mk.sigma_tvh, pk.sigma_tvh) < 0.05);
    assert!(rel(me.noise3d.electrons.sigma_vh, an.noise3d.electrons.sigma_vh) < 0.05);
    // NETD: the measured temporal NETD and the analytic one use the same noise.
    assert!(rel(me.netd_k.unwrap(), an.netd_k.unwrap()) < 0.05);
    assert!(rel(pk.sigma_tvh, an.netd_k.unwrap()) < 1e-9);
    // RER measured on the engine's slanted edge vs RER of the system MTF along its normal.
    assert!(
        rel(me.rer.unwrap(), me.rer_analytic_along_normal.unwrap()) < 0.03,
        "RER {:?} vs {:?}",
        me.rer,
        me.rer_analytic_along_normal
    );
    assert!(rel(me.mtf50_cy_per_px.unwrap(), an.mtf50_cy_per_px.unwrap()) < 0.05);

    // TTP: V at every range from the printed tables by an independent quadrature.
    for (k, &r) in an.ranges_m.iter().enumerate() {
        let c = an.contrast[k];
        let v = an.target.size_m / r
            * 1e3
            * (simpson(&an.ctf_sys_h, c) * simpson(&an.ctf_sys_v, c)).sqrt();
        assert!(
            (v - an.ttp_v[k]).abs() <= 0.01 * an.ttp_v[k] + 1e-9,
            "range {r}: {v} vs {}",
            an.ttp_v[k]
        );
    }
    // Probabilities fall with range; detection reaches further than identification.
    for t in &an.tasks {
        assert!(t.probability.windows(2).all(|w| w[1] <= w[0]), "{}", t.task);
    }
    let p50 = |name: &str| {
        an.tasks
            .iter()
            .find(|t| t.task == name)
            .unwrap()
            .range_p50_m
            .unwrap()
    };
    assert!(p50("detection") > p50("recognition") && p50("recognition") > p50("identification"));
    // MRTD diverges toward the cutoff and is ∝ NETD at low frequency.
    let mrtd = an.mrtd.as_ref().unwrap();
    assert!(mrtd.last().unwrap().mrtd_k > 10.0 * mrtd[0].mrtd_k);
}

/// Identification range at P = 0.5 of the analytic assessment.
fn id_p50(s: &Sensor, target: TargetSpec) -> f64 {
    let opts = AssessOptions {
        target,
        analytic_only: true,
        ranges_m: (0..80).map(|i| 100.0 + 250.0 * i as f64).collect(),
        ..Default::default()
    };
    let a = assess::analytic(s, &opts).unwrap();
    a.tasks
        .iter()
        .find(|t| t.task == "identification")
        .unwrap()
        .range_p50_m
        .unwrap()
}

#[test]
fn range_at_p50_follows_netd_target_size_atmosphere_and_focal_length() {
    let base = sensor("multimir", &[], &[]);
    let t = TargetSpec::default();
    let r0 = id_p50(&base, t);
    let noisy = sensor("multimir", &[], &["detector.read_noise_e=30000"]);
    let r_noisy = id_p50(&noisy, t);
    let small = id_p50(&base, TargetSpec { size_m: 1.5, ..t });
    let hazy = id_p50(
        &base,
        TargetSpec {
            extinction_per_km: Some(0.3),
            ..t
        },
    );
    let long = sensor("multimir", &[], &["optics.focal_length_m=0.2"]);
    let r_long = id_p50(&long, t);
    eprintln!("ID P50: base {r0:.0} m, noisy {r_noisy:.0}, small {small:.0}, hazy {hazy:.0}, 200 mm {r_long:.0}");
    assert!(r_noisy < 0.97 * r0);
    assert!(small < 0.9 * r0);
    assert!(hazy < 0.9 * r0);
    assert!(r_long > 1.1 * r0);
}

#[test]
fn reflective_assessment_gives_niirs_falling_with_range_and_a_measured_rer() {
    let s = sensor("ccd", &[], &[]);
    let opts = AssessOptions {
        frames: 8,
        ..Default::default()
    };
    let a = assess::assess(&s, &opts).unwrap();
    let an = &a.analytic;
    assert!(!an.thermal && an.netd_k.is_none() && an.mrtd.is_none());
    let niirs = an.niirs.as_ref().unwrap();
    assert!(niirs.windows(2).all(|w| w[1] < w[0]), "{niirs:?}");
    // GSD doubles between 1 and 2 km: NIIRS falls by about 3.32·log10(2) ≈ 1 (the SNR
    // term changes a little with the range through the atmosphere only).
    let me = a.measured.as_ref().unwrap();
    eprintln!(
        "reflective RER {:?} (ESF {:?}) vs {:?}; notes {:?}",
        me.rer, me.rer_esf, me.rer_analytic_along_normal, me.notes
    );
    assert!(rel(me.rer.unwrap(), me.rer_analytic_along_normal.unwrap()) < 0.03);
}

#[test]
fn invalid_targets_and_ranges_are_errors_naming_the_field() {
    let s = sensor("multimir", &[], &[]);
    let bad = AssessOptions {
        target: TargetSpec {
            size_m: -1.0,
            ..Default::default()
        },
        ..Default::default()
    };
    let e = assess::analytic(&s, &bad).unwrap_err().to_string();
    assert!(e.contains("target.size_m"), "{e}");
    let bad = AssessOptions {
        ranges_m: vec![1000.0, 500.0],
        ..Default::default()
    };
    let e = assess::analytic(&s, &bad).unwrap_err().to_string();
    assert!(e.contains("ranges") && e.contains("increasing"), "{e}");
    assert_eq!(ttp::probability(20.8, 20.8), 0.5);
}

/// The worked TTP example of docs/figures-of-merit.md: every intermediate number is
/// computed here and must appear, to 4 significant digits, in that page.
#[test]
fn worked_ttp_example_matches_the_docs() {
    use eoir::plot::significant;
    let sigma_px = 0.4;
    let mtf = |f: f64| {
        let s = if f == 0.0 {
            1.0
        } else {
            (std::f64::consts::PI * f).sin() / (std::f64::consts::PI * f)
        };
        s * (-2.0 * std::f64::consts::PI.powi(2) * sigma_px * sigma_px * f * f).exp()
    };
    let sensor = ttp::TtpSensor {
        ifov_rad: 1e-4,
        frame_rate_hz: 50.0,
        noise_rel: 0.05 / 4.0, // NETD 0.05 K over SCT 4 K
    };
    let display = ttp::Display {
        luminance_cd_m2: 10.0,
        pixel_arcmin: 2.0,
        field_deg: 640.0 * 2.0 / 60.0,
    };
    let table = ttp::ctf_sys_table(mtf, &sensor, &display, 200).unwrap();
    let row = table[99]; // f = 0.25 cycles/pixel
    let target = ttp::TtpTarget {
        size_m: 2.3,
        contrast: 2.0 / (2.0 * 4.0),
        extinction_per_m: 0.2e-3,
    };
    let range = 3000.0;
    let c = target.contrast_at(range);
    let integral = ttp::ttp_integral(&table, c);
    let v = target.value_at(&table, &table, range);
    // The band edge: the last frequency where C > CTF_sys.
    let edge = table
        .iter()
        .rev()
        .find(|s| c > s.ctf_sys)
        .unwrap()
        .freq_cy_per_mrad;
    let mut numbers = vec![
        ("ξ", row.freq_cy_per_mrad),
        ("MTF", row.mtf),
        ("CTF_eye", row.ctf_eye),
        ("noise factor", row.noise_factor),
        ("CTF_sys", row.ctf_sys),
        ("C(R)", c),
        ("band edge", edge),
        ("I", integral),
        ("V", v),
    ];
    for (name, v50) in ttp::DEFAULT_TASKS {
        numbers.push((name, ttp::probability(v, v50)));
    }
    let doc = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/figures-of-merit.md"),
    )
    .unwrap();
    let mut missing = Vec::new();
    for (name, x) in numbers {
        let s = significant(x, 4);
        eprintln!("{name}: {s}");
        if !doc.contains(&s) {
            missing.push(format!("{name} = {s}"));
        }
    }
    assert!(
        missing.is_empty(),
        "docs/figures-of-merit.md lacks {missing:?}"
    );
}

fn eoir(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_eoir"))
        .args(args)
        .output()
        .unwrap()
}

/// `eoir assess` writes its whole product set; V recomputed from the CTF_sys table in
/// assess.json equals the V it reports; bad flags are errors that write nothing.
#[test]
fn assess_cli_writes_products_whose_table_reproduces_v_and_refuses_bad_flags() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a");
    let o = out.to_str().unwrap();
    let base = [
        "assess",
        "--sensor",
        "multimir",
        "--set",
        "detector.rows=64",
        "--set",
        "detector.cols=64",
        "--frames",
        "8",
    ];
    let mut args = base.to_vec();
    args.extend(["--range-km", "0.5:6:12", "-o", o]);
    let r = eoir(&args);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    for f in [
        "assess.json",
        "assess.html",
        "noise3d.csv",
        "ranges.csv",
        "ctf_sys.csv",
        "mrtd.csv",
        "probability.png",
        "mrtd.png",
        "mtf.png",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("assess.json")).unwrap()).unwrap();
    let an = &j["analytic"];
    let table = |key: &str| -> Vec<CtfSample> {
        an[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| CtfSample {
                freq_cy_per_mrad: r["freq_cy_per_mrad"].as_f64().unwrap(),
                mtf: r["mtf"].as_f64().unwrap(),
                ctf_eye: r["ctf_eye"].as_f64().unwrap(),
                noise_factor: r["noise_factor"].as_f64().unwrap(),
                ctf_sys: r["ctf_sys"].as_f64().unwrap_or(f64::INFINITY),
            })
            .collect()
    };
    let (h, v) = (table("ctf_sys_h"), table("ctf_sys_v"));
    let size = an["target"]["size_m"].as_f64().unwrap();
    let ranges = an["ranges_m"].as_array().unwrap();
    for (k, r) in ranges.iter().enumerate() {
        let r = r.as_f64().unwrap();
        let c = an["contrast"][k].as_f64().unwrap();
        let got = an["ttp_v"][k].as_f64().unwrap();
        let v_simpson = size / r * 1e3 * (simpson(&h, c) * simpson(&v, c)).sqrt();
        assert!(
            (v_simpson - got).abs() <= 0.01 * got + 1e-9,
            "{r}: {v_simpson} vs {got}"
        );
    }
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(stdout.contains("identification: P50 at"), "{stdout}");

    for (flag, value, expect) in [
        ("--range-km", "5:1:10", "STOP must exceed START"),
        ("--range-km", "0:5:10", "must be > 0"),
        ("--range-km", "1:5", "START:STOP:N"),
        ("--target", "size_m=-2", "target.size_m"),
        ("--target", "width=2", "unknown key `width`"),
    ] {
        let bad = dir.path().join("bad");
        let mut args = base.to_vec();
        args.extend([flag, value, "-o", bad.to_str().unwrap()]);
        let r = eoir(&args);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(
            !r.status.success() && err.contains(expect),
            "{flag} {value}: {err}"
        );
        assert!(
            err.contains(flag.trim_start_matches('-').split('-').next().unwrap()),
            "{err}"
        );
        assert!(!bad.exists(), "{flag} {value} wrote output");
    }
}

/// `eoir sweep` of a 64 × 64 MultimIR with `extra` arguments into `out`.
fn small_sweep(extra: &[&str], out: &std::path::Path) -> std::process::Output {
    let mut args = vec![
        "sweep",
        "--sensor",
        "multimir",
        "--set",
        "detector.rows=64",
        "--set",
        "detector.cols=64",
    ];
    args.extend(extra);
    args.extend(["-o", out.to_str().unwrap()]);
    eoir(&args)
}

/// `eoir sweep` over two keys: the grid in order, the identification range rising with
/// focal length, and the same figures as `assess::analytic` at each point.
#[test]
fn sweep_cli_tabulates_the_grid_and_matches_assess() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s");
    let r = small_sweep(
        &[
            "--vary",
            "optics.focal_length_m=0.1:0.2:3",
            "--vary",
            "detector.read_noise_e=600:6000:2",
            "--range-km",
            "0.1:20:80",
        ],
        &out,
    );
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let csv = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 1 + 6);
    let head: Vec<&str> = lines[0].split(',').collect();
    let id = head
        .iter()
        .position(|h| *h == "identification_p50_m")
        .unwrap();
    let netd = head.iter().position(|h| *h == "netd_k").unwrap();
    let row = |i: usize| -> Vec<f64> {
        lines[1 + i]
            .split(',')
            .map(|v| v.parse().unwrap_or(f64::NAN))
            .collect()
    };
    // Rows: (f, noise) = (0.1, 600), (0.1, 6000), (0.15, 600), …
    assert_eq!((row(1)[0], row(1)[1]), (0.1, 6000.0));
    assert!(row(2)[id] > row(0)[id] && row(4)[id] > row(2)[id]);
    assert!(row(1)[netd] > row(0)[netd]);
    // The first point equals the library's assessment of that sensor.
    let s = sensor(
        "multimir",
        &[],
        &["optics.focal_length_m=0.1", "detector.read_noise_e=600"],
    );
    let opts = AssessOptions {
        analytic_only: true,
        ranges_m: (0..80)
            .map(|i| 100.0 + i as f64 * 19_900.0 / 79.0)
            .collect(),
        ..Default::default()
    };
    let a = assess::analytic(&s, &opts).unwrap();
    let want = a.tasks[2].range_p50_m.unwrap();
    assert!(
        (row(0)[id] / want - 1.0).abs() < 1e-5,
        "{} vs {want}",
        row(0)[id]
    );
    assert!(out.join("identification_p50_m.png").is_file());
    // Grid values are printed as the decimals they stand for (0.15, not 0.15000000000000002).
    assert!(lines[3].starts_with("0.15,600,"), "{}", lines[3]);
    // A point whose reference saturates is an empty row with a note, not a failed sweep.
    let sat = dir.path().join("sat");
    let r = small_sweep(
        &["--vary", "detector.integration_time_s=0.001:0.04:2"],
        &sat,
    );
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(
        err.contains("sweep point detector.integration_time_s=0.04"),
        "{err}"
    );
    let csv = std::fs::read_to_string(sat.join("sweep.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert!(lines[0].ends_with(",note"), "{}", lines[0]);
    assert!(
        lines[1].ends_with(','),
        "a good point has no note: {}",
        lines[1]
    );
    assert!(
        lines[2].starts_with("0.04,,") && lines[2].contains("saturated"),
        "{}",
        lines[2]
    );
    // A bad grid is an error naming the flag.
    let r = eoir(&[
        "sweep",
        "--vary",
        "optics.f_number=2:1:3",
        "-o",
        dir.path().join("bad").to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        !r.status.success() && err.contains("--vary optics.f_number"),
        "{err}"
    );
}

/// Every preset with its own defaults: the 3-D noise measured on its simulated uniform
/// sequence agrees with the prediction from its detector model within 5 % (σ_tvh from
/// 64 × 64 × 16 samples, scatter ≈ 0.3 %; σ_vh where the preset has a pixel pattern, from
/// 4 096 pixels, ≈ 1.1 %); the measured NETD of the thermal ones agrees with the analytic
/// one within 5 %.
#[test]
fn every_preset_measures_the_noise_it_predicts() {
    let opts = AssessOptions {
        frames: 16,
        ..Default::default()
    };
    for preset in [
        "multimir",
        "emerald",
        "qwip",
        "ccd",
        "ccd-bayer",
        "threeband",
    ] {
        let s = sensor(preset, &[], &[]);
        let a = assess::assess(&s, &opts).unwrap_or_else(|e| panic!("{preset}: {e}"));
        let (an, me) = (&a.analytic, a.measured.as_ref().unwrap());
        let (p, m) = (an.noise3d.dn, me.noise3d.dn);
        eprintln!(
            "{preset}: measured {m:?}\n  predicted {p:?}\n  NETD {:?} vs {:?}",
            me.netd_k, an.netd_k
        );
        assert!(
            rel(m.sigma_tvh, p.sigma_tvh) < 0.05,
            "{preset}: {m:?} vs {p:?}"
        );
        if p.sigma_vh > 0.2 * p.sigma_tvh {
            assert!(
                rel(m.sigma_vh, p.sigma_vh) < 0.05,
                "{preset}: {m:?} vs {p:?}"
            );
        }
        if let (Some(x), Some(y)) = (me.netd_k, an.netd_k) {
            assert!(rel(x, y) < 0.05, "{preset}: NETD {x} vs {y}");
        }
    }
}

/// `eoir run --assess`: the run's report.json carries the sensor's analytic figures of
/// merit (the same numbers as `assess::analytic`), report.html shows them with the TTP
/// and MRTD curves beside the run's own pictures, and no number on the page is printed
/// with more than 6 significant digits. A run without `--assess` has none of it.
#[test]
fn run_with_assess_puts_the_figures_of_merit_in_the_report() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.hdr");
    let sets = ["--set", "detector.rows=48", "--set", "detector.cols=64"];
    let mut args = vec!["scene", "thermal", "--sensor", "multimir"];
    args.extend(sets);
    args.extend(["-o", scene.to_str().unwrap()]);
    let r = eoir(&args);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let out = dir.path().join("run");
    let mut args = vec!["run", "--sensor", "multimir", "--assess", "--quiet"];
    args.extend(sets);
    args.extend([scene.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    let r = eoir(&args);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let fom = &report["figures_of_merit"];
    let s = sensor("multimir", &[], &["detector.rows=48", "detector.cols=64"]);
    let an = assess::analytic(
        &s,
        &AssessOptions {
            analytic_only: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(fom["netd_k"].as_f64(), an.netd_k);
    assert_eq!(
        fom["tasks"][2]["range_p50_m"].as_f64(),
        an.tasks[2].range_p50_m
    );
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    let section = &html[html.find("id=\"figures-of-merit\"").expect("section")..];
    let netd = eoir::plot::significant(an.netd_k.unwrap(), 3);
    assert!(section.contains(&format!("{netd} K")), "{netd}");
    for pic in ["fig-probability", "fig-mrtd"] {
        assert!(section.contains(pic), "{pic}");
    }
    assert!(out.join("probability.png").is_file() && out.join("mrtd.png").is_file());
    assert!(html.find("fig-dn").unwrap() < html.find("id=\"figures-of-merit\"").unwrap());
    let long = crate::browser::long_floats(&crate::browser::visible_text(&html));
    assert!(long.is_empty(), "{long:?}");
    // Without --assess: no section, no curves.
    let plain = dir.path().join("plain");
    let mut args = vec!["run", "--sensor", "multimir", "--quiet"];
    args.extend(sets);
    args.extend([scene.to_str().unwrap(), "-o", plain.to_str().unwrap()]);
    assert!(eoir(&args).status.success());
    let html = std::fs::read_to_string(plain.join("report.html")).unwrap();
    assert!(!html.contains("figures-of-merit") && !plain.join("probability.png").exists());
}

/// A sensor with turbulence: the TTP value at each range is computed with the turbulence
/// MTF of that range (the printed per-range CTF_sys tables integrate to the reported V by
/// an independent quadrature; at the sensor file's own range they equal its table), and
/// the identification range is shorter than without turbulence.
#[test]
fn turbulence_is_evaluated_over_each_range() {
    use eoir::sensor::config::TurbulenceConfig;
    let base = presets::load(
        "multimir",
        &[],
        &["detector.rows=64".into(), "detector.cols=64".into()],
    )
    .unwrap();
    let mut c = base.clone();
    c.turbulence = Some(TurbulenceConfig::Horizontal {
        enabled: true,
        cn2: 1e-13,
        range_m: 1000.0,
    });
    let (clear, turb) = (Sensor::build(&base).unwrap(), Sensor::build(&c).unwrap());
    let opts = AssessOptions {
        analytic_only: true,
        ranges_m: vec![500.0, 1000.0, 2000.0, 4000.0],
        ..Default::default()
    };
    let a = assess::analytic(&turb, &opts).unwrap();
    let rows = a.ctf_sys_at_range.as_ref().expect("per-range tables");
    assert!(assess::analytic(&clear, &opts)
        .unwrap()
        .ctf_sys_at_range
        .is_none());
    // At the file's own range (1000 m) the per-range table is the sensor's own.
    for (x, y) in rows[1].ctf_sys_h.iter().zip(&a.ctf_sys_h) {
        assert!(
            (x / y.ctf_sys - 1.0).abs() < 1e-12 || (x.is_infinite() && y.ctf_sys.is_infinite())
        );
    }
    // The table degrades with range (the turbulence MTF falls as the path lengthens).
    let mid = rows[0].ctf_sys_h.len() / 4;
    assert!(
        rows[3].ctf_sys_h[mid] > rows[2].ctf_sys_h[mid]
            && rows[2].ctf_sys_h[mid] > rows[0].ctf_sys_h[mid]
    );
    // V at each range by Simpson over that range's tables.
    let with = |t: &[f64]| -> Vec<CtfSample> {
        a.ctf_sys_h
            .iter()
            .zip(t)
            .map(|(s, &c)| CtfSample { ctf_sys: c, ..*s })
            .collect()
    };
    for (k, row) in rows.iter().enumerate() {
        let c = a.contrast[k];
        let v = a.target.size_m / row.range_m
            * 1e3
            * (simpson(&with(&row.ctf_sys_h), c) * simpson(&with(&row.ctf_sys_v), c)).sqrt();
        assert!(
            (v / a.ttp_v[k] - 1.0).abs() < 0.01,
            "{} m: {v} vs {}",
            row.range_m,
            a.ttp_v[k]
        );
    }
    let id = |a: &assess::Analytic| a.tasks[2].range_p50_m.unwrap();
    let plain = assess::analytic(&clear, &opts).unwrap();
    assert!(id(&a) < id(&plain), "{} vs {}", id(&a), id(&plain));
}
