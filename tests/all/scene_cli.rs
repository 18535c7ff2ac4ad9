//! `eoir scene` sized to a sensor, then `eoir run` on it with no extra flags: every scene
//! kind with all defaults, every preset and option (small detector windows), the fit
//! checked for every preset at full size through the library; and the scene's files
//! written as one set (a failure leaves the earlier pair exactly as it was).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use eoir::imaging::Sampling;
use eoir::scene::sizing::{self, DetectorGrid};
use eoir::scene::synthetic::{self, SceneParams, KINDS};
use eoir::scene::CubeMeta;
use eoir::sensor::{presets, Sensor};

fn eoir(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_eoir"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap()
}

fn ok(o: &Output, what: &str) -> String {
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{what}: {stderr}");
    assert!(!stderr.contains("panicked"), "{what}: {stderr}");
    stderr
}

fn report(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap()
}

/// Names in `dir` that a writer must never leave behind.
fn leftovers(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| {
            n.starts_with(eoir::io::output::STAGING_PREFIX)
                || n.contains(eoir::io::output::TEMP_MARKER)
        })
        .collect()
}

/// The command: `eoir scene K -o s.hdr && eoir run s.hdr -o out`, nothing else, for
/// every kind. The run samples the scene at exactly the default oversampling (integer
/// decimation): for MultimIR's F/2 optics 4 scene samples per detector pixel (the optics
/// would need 6 at 4.55 µm; 4 is the most the default takes) — and the scene covers the
/// detector with 4 pixels to spare on every side.
#[test]
fn every_kind_with_defaults_runs_with_defaults() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // MultimIR (the default sensor), 100 mm optics: IFOV 24 µm / 100 mm.
    let ifov = 24e-6 / 0.1;
    for (kind, _) in KINDS {
        let file = format!("{kind}.hdr");
        let out = format!("out-{kind}");
        ok(&eoir(d, &["scene", kind, "-o", &file]), kind);
        let stderr = ok(&eoir(d, &["run", &file, "-o", &out, "--quiet"]), kind);
        assert!(!stderr.contains("coarser"), "{kind}: {stderr}");
        let r = report(&d.join(&out));
        for axis in ["ratio_x", "ratio_y"] {
            let k = r["sampling"][axis].as_f64().unwrap();
            assert!((k - 4.0).abs() < 1e-12, "{kind}: {axis} {k}");
        }
        assert!(r["sampling"]["method"]
            .as_str()
            .unwrap()
            .starts_with("integer"));
        let fov = &r["input"]["fov_deg"];
        let (fx, fy) = (fov[0].as_f64().unwrap(), fov[1].as_f64().unwrap());
        assert!(
            (fx.to_radians() / ifov - (384.0 + 8.0)).abs() < 1e-9,
            "{kind}: {fx}°"
        );
        assert!(
            (fy.to_radians() / ifov - (288.0 + 8.0)).abs() < 1e-9,
            "{kind}: {fy}°"
        );
        assert_eq!(r["input"]["cols"].as_u64(), Some(4 * 392));
        assert_eq!(r["input"]["rows"].as_u64(), Some(4 * 296));
        assert!(d.join(&out).join("dn.tiff").exists());
    }
    assert!(leftovers(d).is_empty(), "{:?}", leftovers(d));
}

/// `eoir scene --sensor P [--option …]` then `eoir run --sensor P [--option …]` for every
/// preset and every combination of its options, on 24 × 32 detector windows (`--set`, the
/// same for both commands) at the default oversampling.
#[test]
fn every_preset_and_option_fits_its_scene() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let window = ["--set", "detector.rows=24", "--set", "detector.cols=32"];
    let mut runs = 0;
    for info in presets::list() {
        // The aberrated lenses (imaged through the pupil, much slower) run once each in
        // presets_run::aberrated_lenses_run_the_demo_scene.
        for combo in info.option_combinations() {
            if combo.iter().any(|o| o.contains("aberrated")) {
                continue;
            }
            let what = format!("{} {combo:?}", info.name);
            let mut sensor_args = vec!["--sensor", info.name.as_str()];
            for o in &combo {
                sensor_args.extend(["--option", o.as_str()]);
            }
            sensor_args.extend(window);
            let tag = runs.to_string();
            let file = format!("s{tag}.npy");
            let out = format!("out{tag}");
            let mut a = vec!["scene", "thermal", "-o", &file];
            a.extend(&sensor_args);
            ok(&eoir(d, &a), &what);
            let mut a = vec!["run", &file, "-o", &out, "--quiet"];
            a.extend(&sensor_args);
            let stderr = ok(&eoir(d, &a), &what);
            assert!(!stderr.contains("coarser"), "{what}: {stderr}");
            let r = report(&d.join(&out));
            // The default oversampling: the smallest k whose Nyquist reaches the optics'
            // cutoff at the scene's shortest wavelength, between 2 and 4.
            let sensor = presets::load(
                &info.name,
                &combo,
                &[
                    "detector.rows=24".to_string(),
                    "detector.cols=32".to_string(),
                ],
            )
            .unwrap();
            let sensor = eoir::sensor::Sensor::build(&sensor).unwrap();
            let lo = sensor.response().support_um().0;
            let cutoff = eoir::imaging::scene_band::optical_cutoff_cy_per_rad(sensor.otf(), lo)
                .filter(|c| c.is_finite());
            let want = eoir::scene::sizing::default_oversampling(sensor.ifov_rad(), cutoff);
            let k = r["sampling"]["ratio_x"].as_f64().unwrap();
            assert!(
                (k - want as f64).abs() < 1e-12,
                "{what}: ratio {k}, want {want}"
            );
            assert_eq!(
                r["input"]["cols"].as_u64(),
                Some(want as u64 * (32 + 8)),
                "{what}"
            );
            // The scene spans the sensor's band: no band of the response left uncovered.
            assert!(r["input"]["bands_used"].as_u64().unwrap() >= 2, "{what}");
            runs += 1;
        }
    }
    assert!(runs >= 19, "{runs} preset/option combinations");
}

/// The meta of a scene made with `params` (what the generators return), without making it.
fn meta_of(params: &SceneParams) -> CubeMeta {
    CubeMeta {
        wavelength_um: params.wavelength_um.clone(),
        fwhm_um: None,
        units: eoir::scene::RadianceUnits::SpectralPerUm,
        geometry: Some(params.geometry()),
        rows: params.cube_rows(),
        cols: params.cube_cols(),
    }
}

/// At full detector size, for every preset and option, oversampling 1–3 and margins 0 and
/// the default: the scene [`sizing::covering`] makes is accepted by the run's own check and
/// sampled at exactly k scene samples per pixel; a scene sized to the datasheet field of
/// view 2·atan(n·p/2f) is refused, as the 5.28° scene was.
#[test]
fn covering_scene_fits_every_preset_at_full_size() {
    let mut n = 0;
    for info in presets::list() {
        for combo in info.option_combinations() {
            let what = format!("{} {combo:?}", info.name);
            let sensor = Sensor::build(&presets::load(&info.name, &combo, &[]).unwrap()).unwrap();
            let grid = DetectorGrid {
                rows: sensor.detector.rows,
                cols: sensor.detector.cols,
                ifov_rad: sensor.ifov_rad(),
            };
            for k in 1..=3 {
                for m in [0, sizing::DEFAULT_MARGIN_PX] {
                    let params = SceneParams {
                        wavelength_um: vec![4.0],
                        ..sizing::covering(&grid, k, m).unwrap()
                    };
                    let meta = meta_of(&params);
                    let s = Sampling::new(&sensor, &meta, &params.geometry())
                        .unwrap_or_else(|e| panic!("{what} k {k} m {m}: {e}"));
                    assert_eq!(s.x.integer_ratio(), Some(k), "{what}");
                    assert_eq!(s.y.integer_ratio(), Some(k), "{what}");
                    assert!(s.warnings.is_empty(), "{what}: {:?}", s.warnings);
                    n += 1;
                }
            }
            // The flat-focal-plane field of view is smaller than the paraxial extent the
            // engine samples, so a scene sized to it does not cover the detector.
            let (fx, _) = sensor.fov_deg();
            let flat = SceneParams {
                rows: sensor.detector.rows,
                cols: sensor.detector.cols,
                fov_x_deg: fx,
                wavelength_um: vec![4.0],
                ..SceneParams::default()
            };
            let err = Sampling::new(&sensor, &meta_of(&flat), &flat.geometry()).unwrap_err();
            assert!(
                err.to_string().contains("inside the scene"),
                "{what}: {err}"
            );
        }
    }
    assert!(n >= 19 * 6);
}

/// `eoir demo` sizes its scene with the same function: its report shows the same sampling
/// and field of view as `eoir scene thermal` gives for the same sensor.
#[test]
fn demo_scene_is_sized_like_scene() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let window = ["--set", "detector.rows=20", "--set", "detector.cols=30"];
    let mut a = vec!["demo", "-o", "demo", "--quiet", "--sensor", "qwip"];
    a.extend(window);
    ok(&eoir(d, &a), "demo");
    // The demo keeps 2 samples per pixel; `eoir scene` picks k from the optics (4 here).
    let mut a = vec![
        "scene",
        "thermal",
        "-o",
        "s.hdr",
        "--sensor",
        "qwip",
        "--oversampling",
        "2",
    ];
    a.extend(window);
    ok(&eoir(d, &a), "scene");
    let demo = report(&d.join("demo"));
    let meta = eoir::io::open(&d.join("s.hdr")).unwrap().meta().clone();
    let g = meta.geometry.unwrap();
    assert_eq!(demo["input"]["cols"].as_u64(), Some(meta.cols as u64));
    assert_eq!(demo["input"]["rows"].as_u64(), Some(meta.rows as u64));
    assert_eq!(demo["input"]["bands"].as_u64(), Some(meta.bands() as u64));
    // (serde_json's default float parsing may be off by one unit in the last place.)
    for (i, want) in [g.fov_x_deg, g.fov_y_deg].into_iter().enumerate() {
        let got = demo["input"]["fov_deg"][i].as_f64().unwrap();
        assert!((got / want - 1.0).abs() < 1e-14, "{got} vs {want}");
    }
    // The report names the scene where it is, not where it was staged.
    let name = demo["input"]["name"].as_str().unwrap();
    assert!(
        name.ends_with("scene.hdr") && !name.contains(".eoir-staging-"),
        "{name}"
    );
}

/// A small cube to write.
fn small_cube(seed: u64) -> eoir::scene::Cube {
    synthetic::thermal(&SceneParams {
        rows: 6,
        cols: 8,
        wavelength_um: vec![4.0, 4.5, 5.0],
        seed,
        ..SceneParams::default()
    })
    .unwrap()
}

fn bytes(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap()
}

/// The ENVI pair is one set: when the header cannot be written (its name is a symbolic
/// link, which eoir never writes through), the data file of the earlier pair is left
/// byte for byte, the link and its target too, and no staging or temporary file remains.
/// Writing the data first and then failing on the header used to replace the old data and
/// then delete it.
#[test]
fn failing_header_write_leaves_the_old_pair() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let hdr = d.join("s.hdr");
    let img = d.join("s.img");
    let written = eoir::io::write_cube_set(&hdr, &small_cube(1)).unwrap();
    assert_eq!(written, vec![hdr.clone(), img.clone()]);
    // The old header moves elsewhere and s.hdr becomes a link to it.
    let old_hdr = d.join("elsewhere.hdr");
    std::fs::rename(&hdr, &old_hdr).unwrap();
    std::os::unix::fs::symlink(&old_hdr, &hdr).unwrap();
    let (old_img_bytes, old_hdr_bytes) = (bytes(&img), bytes(&old_hdr));

    let err = eoir::io::write_cube(&hdr, &small_cube(2)).unwrap_err();
    assert!(
        err.to_string().contains("s.hdr") && err.to_string().contains("symbolic link"),
        "{err}"
    );
    assert_eq!(bytes(&img), old_img_bytes, "the old data file changed");
    assert_eq!(bytes(&old_hdr), old_hdr_bytes);
    assert!(std::fs::symlink_metadata(&hdr).unwrap().is_symlink());
    assert!(leftovers(d).is_empty(), "{:?}", leftovers(d));

    // The same through the CLI: one error line, nothing changed.
    let o = eoir(d, &["scene", "blackbody", "-o", "s.hdr"]);
    assert_eq!(o.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert_eq!(bytes(&img), old_img_bytes);
    assert!(leftovers(d).is_empty(), "{:?}", leftovers(d));
}

/// The other order: the data file's name is taken by a directory, so the data cannot be
/// written; the old header is untouched and nothing is left behind. A later write to a
/// free name writes the whole new pair, which reads back as the cube written.
#[test]
fn failing_data_write_leaves_the_old_header_and_a_good_write_replaces_both() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let hdr = d.join("s.hdr");
    let img = d.join("s.img");
    eoir::io::write_cube(&hdr, &small_cube(1)).unwrap();
    std::fs::remove_file(&img).unwrap();
    std::fs::create_dir(&img).unwrap();
    let old_hdr = bytes(&hdr);
    let err = eoir::io::write_cube(&hdr, &small_cube(2)).unwrap_err();
    assert!(err.to_string().contains("s.img"), "{err}");
    assert_eq!(bytes(&hdr), old_hdr);
    assert!(img.is_dir());
    assert!(leftovers(d).is_empty(), "{:?}", leftovers(d));

    std::fs::remove_dir(&img).unwrap();
    let new = small_cube(2);
    let paths: Vec<PathBuf> = eoir::io::write_cube_set(&hdr, &new).unwrap();
    assert_eq!(paths.len(), 2);
    let back = eoir::io::read_cube(&hdr).unwrap();
    assert_eq!(back.data, new.data);
    assert_eq!(back.meta.geometry, new.meta.geometry);
    assert!(leftovers(d).is_empty(), "{:?}", leftovers(d));
}

/// Explicit sizing: the three flags go together, and a scene smaller than the sensor is
/// written with a warning saying `run` will refuse it.
#[test]
fn explicit_size_flags_go_together_and_warn_when_too_small() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = eoir(d, &["scene", "thermal", "-o", "a.hdr", "--rows", "10"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(!d.join("a.hdr").exists());
    let o = eoir(
        d,
        &[
            "scene",
            "ramp",
            "-o",
            "b.npy",
            "--rows",
            "10",
            "--cols",
            "12",
            "--fov-deg",
            "1",
        ],
    );
    let stderr = ok(&o, "explicit");
    assert!(stderr.contains("refuse"), "{stderr}");
    let meta = eoir::io::open(&d.join("b.npy")).unwrap().meta().clone();
    // Explicit size: oversampling 1 unless asked.
    assert_eq!((meta.rows, meta.cols), (10, 12));
    let o = eoir(d, &["scene", "edge", "-o", "c.npy", "--oversampling", "0"]);
    assert_eq!(o.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("oversampling"), "{stderr}");
}

/// SIGINT while `eoir scene` writes its pair (sent once the staging directory appears):
/// afterwards the directory holds the old pair byte for byte, or (if the signal came after
/// the move) the complete new pair, and never a staging directory or temporary file.
#[test]
fn sigint_while_writing_a_scene_leaves_the_old_pair_or_the_new_one() {
    use std::time::{Duration, Instant};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 400 × 500 × 50 bands: 40 MB of data, long enough to be caught while writing.
    let args = |seed: &str| {
        [
            "scene",
            "ramp",
            "-o",
            "s.hdr",
            "--rows",
            "400",
            "--cols",
            "500",
            "--fov-deg",
            "10",
            "--lo-um",
            "4",
            "--hi-um",
            "5",
            "--bands",
            "50",
            "--t-low-k",
            seed,
        ]
        .map(String::from)
    };
    ok(&eoir(d, &args("290").each_ref().map(|s| s.as_str())), "old");
    let (old_hdr, old_img) = (bytes(&d.join("s.hdr")), bytes(&d.join("s.img")));
    let mut interrupted = 0;
    for _attempt in 0..3 {
        let mut child = Command::new(env!("CARGO_BIN_EXE_eoir"))
            .current_dir(d)
            .args(args("280"))
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let start = Instant::now();
        while start.elapsed() < Duration::from_secs(30) {
            let staging = std::fs::read_dir(d).unwrap().any(|e| {
                e.unwrap()
                    .file_name()
                    .to_string_lossy()
                    .starts_with(eoir::io::output::STAGING_PREFIX)
            });
            if staging || child.try_wait().unwrap().is_some() {
                break;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        // SAFETY: signalling our own child by its pid.
        unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
        let o = child.wait_with_output().unwrap();
        assert!(!String::from_utf8_lossy(&o.stderr).contains("panicked"));
        assert!(leftovers(d).is_empty(), "{:?}", leftovers(d));
        match o.status.code() {
            Some(130) => {
                interrupted += 1;
                assert_eq!(bytes(&d.join("s.hdr")), old_hdr, "old header changed");
                assert_eq!(bytes(&d.join("s.img")), old_img, "old data changed");
            }
            Some(0) => {
                // Finished first: the new pair, whole; put the old one back.
                let back = eoir::io::read_cube(&d.join("s.hdr")).unwrap();
                assert_eq!(back.meta.cols, 500);
                assert_ne!(bytes(&d.join("s.img")), old_img);
                std::fs::write(d.join("s.hdr"), &old_hdr).unwrap();
                std::fs::write(d.join("s.img"), &old_img).unwrap();
            }
            other => panic!("exit {other:?}: {}", String::from_utf8_lossy(&o.stderr)),
        }
    }
    assert!(interrupted >= 1, "no attempt was interrupted while writing");
}
