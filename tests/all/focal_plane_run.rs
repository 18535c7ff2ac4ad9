//! The focal plane's memory in whole runs (docs/focal-plane.md): neutral effects change no
//! DN, pieces of a sequence replay the memory bit for bit, the truth products and the
//! report's drift curve are written, a persistence ghost in the DN is the charge the traps
//! released, and the clock is required.

use eoir::detector::persistence::PersistenceConfig;
use eoir::io::MemoryCube;
use eoir::pipeline::{self, RunOptions, RunOutput};
use eoir::scene::synthetic::{self, SceneParams};
use eoir::scene::Cube;
use eoir::sensor::{presets, Sensor, SensorConfig};
use ndarray::s;

/// Detector size of the tests (rows, cols).
const DET: (usize, usize) = (24, 32);

/// A small MultimIR without defects or motion, `overrides` applied, then `edit`.
fn sensor(overrides: &[&str], edit: impl FnOnce(&mut SensorConfig)) -> Sensor {
    let mut all: Vec<String> = vec![
        format!("detector.rows={}", DET.0),
        format!("detector.cols={}", DET.1),
        "detector.defects.dead_fraction=0".into(),
        "detector.defects.hot_fraction=0".into(),
        // A still camera on the clock: every frame sees the same image.
        "motion.enabled=false".into(),
    ];
    all.extend(overrides.iter().map(|s| s.to_string()));
    let mut config = presets::load("multimir", &["sequence=still".to_string()], &all).unwrap();
    edit(&mut config);
    Sensor::build(&config).unwrap()
}

/// A 300 K blackbody scene covering the detector and 4 pixels beyond each edge (k = 1).
fn scene(sensor: &Sensor) -> Cube {
    let (lo, hi) = sensor.response().support_um();
    let p = SceneParams {
        rows: DET.0 + 8,
        cols: DET.1 + 8,
        oversampling: 1,
        wavelength_um: SceneParams::uniform_grid(lo, hi, 8).unwrap(),
        fov_x_deg: (sensor.ifov_rad() * (DET.1 + 8) as f64).to_degrees(),
        range_m: Some(1000.0),
        seed: 3,
        sun: false,
    };
    synthetic::blackbody(&p, 300.0, 1.0).unwrap()
}

fn options(frames: usize, first_frame: u64, sequence_frames: Option<u64>) -> RunOptions {
    RunOptions {
        frames,
        first_frame,
        sequence_frames,
        calibration: None,
        ..RunOptions::default()
    }
}

fn run(sensor: &Sensor, cube: &Cube, o: &RunOptions) -> eoir::error::Result<RunOutput> {
    let mut reader = MemoryCube::new(cube.clone());
    pipeline::run(sensor, &mut reader, o, |_, _| {})
}

fn dn(out: &RunOutput) -> Vec<ndarray::Array2<u16>> {
    out.frames.iter().map(|f| f.dn.clone()).collect()
}

/// Every memory effect on: RTS pixels (dark and offset steps), persistence, drift.
fn with_memory(c: &mut SensorConfig) {
    c.detector.persistence = Some(PersistenceConfig {
        tau_s: vec![0.01, 0.1],
        density: vec![0.02, 0.03],
    });
}

const MEMORY_SETS: [&str; 8] = [
    "clock.frame_rate_hz=50",
    "detector.rts.fraction=0.05",
    "detector.rts.tau_high_s=0.03",
    "detector.rts.tau_low_s=0.05",
    "detector.rts.dark_step_e_per_s=2e6",
    "detector.rts.offset_step_e=300",
    "detector.drift.offset_walk_e_per_sqrt_s=500",
    "detector.drift.walk_step_s=0.01",
];

/// Effects at their neutral values take the whole-frame path (or step the memory) and
/// give the same DN as the row-by-row chain without them, bit for bit.
#[test]
fn neutral_effects_give_the_same_dn() {
    let base = sensor(&["clock.frame_rate_hz=50"], |_| {});
    let cube = scene(&base);
    let o = options(3, 0, None);
    let reference = dn(&run(&base, &cube, &o).unwrap());
    // Readout noise without amplitudes: the staged path, no noise added.
    let staged = sensor(
        &[
            "clock.frame_rate_hz=50",
            "detector.readout_noise.pixel_time_s=1e-6",
        ],
        |_| {},
    );
    assert!(staged.detector().couples_pixels());
    assert_eq!(dn(&run(&staged, &cube, &o).unwrap()), reference);
    // Persistence on a static scene starts at equilibrium: nothing is trapped or released.
    let traps = sensor(&["clock.frame_rate_hz=50"], with_memory);
    let out = run(&traps, &cube, &o).unwrap();
    assert_eq!(dn(&out), reference);
    assert!(out.focal_plane.is_some());
}

/// A sequence cut into pieces (`first_frame`, as `eoir.dask.run_frames` does) gives the
/// DN and truth of one run over the whole sequence.
#[test]
fn pieces_replay_the_memory_bit_for_bit() {
    let s = sensor(&MEMORY_SETS, with_memory);
    let cube = scene(&s);
    let whole = run(&s, &cube, &options(6, 0, None)).unwrap();
    let a = run(&s, &cube, &options(2, 0, Some(6))).unwrap();
    let b = run(&s, &cube, &options(4, 2, Some(6))).unwrap();
    let mut pieces = dn(&a);
    pieces.extend(dn(&b));
    assert_eq!(pieces, dn(&whole));
    let t = |o: &RunOutput| -> Vec<String> {
        let fp = o.focal_plane.as_ref().unwrap();
        let csv = fp.rts_csv().unwrap();
        csv.lines().skip(1).map(str::to_string).collect()
    };
    let mut rows = t(&a);
    rows.extend(t(&b));
    assert_eq!(rows, t(&whole));
    // The RTS pixels switch: some are high in some frames and low in others.
    let fp = whole.focal_plane.as_ref().unwrap();
    assert!(!fp.rts_pixels.is_empty());
    let highs: Vec<usize> = fp
        .frames
        .iter()
        .map(|f| {
            f.rts
                .as_ref()
                .unwrap()
                .high_at_readout
                .iter()
                .filter(|h| **h)
                .count()
        })
        .collect();
    assert!(highs.iter().any(|&h| h > 0) && highs.iter().any(|&h| h < fp.rts_pixels.len()));
}

/// A piece of a moving camera's sequence over a static scene replays persistence by
/// imaging the frames before its first as they moved: the pieces give the DN and trapped
/// charge of one run, and persistence does change those DN (a hot square drifting across
/// the detector leaves charge behind).
#[test]
fn pieces_of_a_moving_sequence_replay_persistence_bit_for_bit() {
    let sets = [
        "clock.frame_rate_hz=50",
        "motion.enabled=true",
        // 0.5 px per frame at 1 km: over 6 frames the 4 px margin still covers the detector.
        "motion.velocity_m_s=12.5",
    ];
    let s = sensor(&sets, with_memory);
    let mut cube = scene(&s);
    cube.data
        .slice_mut(s![.., 10..16, 12..18])
        .mapv_inplace(|v| v * 20.0);
    let whole = run(&s, &cube, &options(6, 0, None)).unwrap();
    let a = run(&s, &cube, &options(2, 0, Some(6))).unwrap();
    let b = run(&s, &cube, &options(4, 2, Some(6))).unwrap();
    let mut pieces = dn(&a);
    pieces.extend(dn(&b));
    assert_eq!(pieces, dn(&whole));
    let trapped = |o: &RunOutput| -> Vec<ndarray::Array2<f32>> {
        let fp = o.focal_plane.as_ref().unwrap();
        fp.frames
            .iter()
            .map(|f| f.trapped_e.clone().unwrap())
            .collect()
    };
    let mut t = trapped(&a);
    t.extend(trapped(&b));
    assert_eq!(t, trapped(&whole));
    // Without persistence the later frames' DN differ: the replay had something to do.
    let plain = sensor(&sets, |_| {});
    let without = run(&plain, &cube, &options(6, 0, None)).unwrap();
    assert_ne!(dn(&without)[2..], dn(&whole)[2..]);
}

/// A piece of a 4-D input holds only its own frames, so persistence cannot be replayed:
/// an error that says so.
#[test]
fn persistence_in_a_later_piece_of_a_4d_input_is_an_error() {
    let s = sensor(&["clock.frame_rate_hz=50"], with_memory);
    let cube = scene(&s);
    let mut reader = MemoryCube::sequence(vec![cube.clone(), cube], None).unwrap();
    let err = pipeline::run(&s, &mut reader, &options(2, 2, Some(4)), |_, _| {})
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("first_frame") && err.contains("persistence") && err.contains("4-D"),
        "{err}"
    );
}

/// Without `[clock]` the memory effects are refused when the sensor is loaded.
#[test]
fn memory_effects_need_a_clock() {
    let err = presets::load(
        "multimir",
        &["sequence=still".to_string()],
        &[
            "detector.rts.fraction=0.01".to_string(),
            "detector.rts.dark_step_e_per_s=1e5".to_string(),
        ],
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("detector.rts") && err.contains("[clock]"),
        "{err}"
    );
}

/// The truth files, the report's drift curve and its picture; the measured residual
/// grows as the expected one (√t for a random walk).
#[test]
fn truth_products_and_drift_curve_are_written() {
    let s = sensor(&MEMORY_SETS, with_memory);
    let cube = scene(&s);
    let out = run(&s, &cube, &options(5, 0, None)).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let written = out.write(dir.path()).unwrap();
    let names: Vec<String> = written
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    for n in [
        "rts.csv",
        "trapped_e.npy",
        "drift_gain.npy",
        "drift_offset_e.npy",
        "nuc_drift.png",
    ] {
        assert!(names.iter().any(|x| x == n), "{n} not in {names:?}");
    }
    let fp = out.focal_plane.as_ref().unwrap();
    let csv = std::fs::read_to_string(dir.path().join("rts.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 5 * fp.rts_pixels.len());
    let trapped: ndarray::Array3<f32> =
        ndarray_npy::read_npy(dir.path().join("trapped_e.npy")).unwrap();
    assert_eq!(trapped.dim(), (5, DET.0, DET.1));
    let report = out.report.focal_plane.as_ref().unwrap();
    assert_eq!(
        report.effects,
        ["rts", "persistence", "drift"].map(String::from).to_vec()
    );
    let drift = report.drift.as_ref().unwrap();
    assert_eq!(drift.len(), 5);
    assert_eq!(drift[0].residual_nonuniformity_e_measured, 0.0);
    for p in &drift[1..] {
        // 768 pixels: the measured spread scatters about the expected by ~1/√(2·768) ≈ 3 %
        // per frame; the walk's linear interpolation between grid steps lowers it less.
        let ratio = p.residual_nonuniformity_e_measured / p.residual_nonuniformity_e_expected;
        assert!((0.85..1.15).contains(&ratio), "{p:?}");
    }
}

/// A bright frame followed by dark frames: the excess DN of the dark frames at the bright
/// patch is the charge the traps released (trapped before − trapped after), converted with
/// K, when shot and read noise are off.
#[test]
fn a_persistence_ghost_is_the_charge_the_traps_release() {
    let s = sensor(
        &[
            "clock.frame_rate_hz=50",
            "detector.shot_noise=false",
            "detector.read_noise_e=0",
            "detector.fpn.prnu_sigma_rel=0",
            "detector.fpn.dsnu_sigma_e=0",
        ],
        with_memory,
    );
    let cube = scene(&s);
    let frames: Vec<Cube> = (0..5)
        .map(|k| {
            let mut data = cube.data.clone();
            if k < 2 {
                // A patch 3× brighter in the first two frames.
                data.slice_mut(s![.., 12..20, 14..24])
                    .mapv_inplace(|v| v * 3.0);
            }
            Cube::new(data, cube.meta.clone()).unwrap()
        })
        .collect();
    let mut reader = MemoryCube::sequence(frames.clone(), Some(0.02)).unwrap();
    let out = pipeline::run(&s, &mut reader, &options(1, 0, None), |_, _| {}).unwrap();
    let fp = out.focal_plane.as_ref().unwrap();
    let k_gain = out.report.detector.gain_dn_per_e;
    let (r, c) = (12, 15);
    let trapped = |k: usize| fp.frames[k].trapped_e.as_ref().unwrap()[[r, c]] as f64;
    let released = trapped(2 - 1) - trapped(2);
    assert!(released > 100.0, "released {released} e-");
    // The same pixel without persistence in frame 2 (mean electrons through the chain).
    let plain = sensor(
        &[
            "clock.frame_rate_hz=50",
            "detector.shot_noise=false",
            "detector.read_noise_e=0",
            "detector.fpn.prnu_sigma_rel=0",
            "detector.fpn.dsnu_sigma_e=0",
        ],
        |_| {},
    );
    let mut reader = MemoryCube::sequence(frames, Some(0.02)).unwrap();
    let base = pipeline::run(&plain, &mut reader, &options(1, 0, None), |_, _| {}).unwrap();
    let excess_dn = out.frames[2].dn[[r, c]] as f64 - base.frames[2].dn[[r, c]] as f64;
    // ADC rounding: ±1 DN.
    assert!(
        (excess_dn - released * k_gain).abs() <= 1.0,
        "excess {excess_dn} DN, released {released} e- × K {k_gain}"
    );
}

/// A 4-D input cut into one-frame pieces (Dask chunks of one frame, `time_varying`):
/// each piece is a rendered frame, not a static scene for the moving camera to sweep,
/// so the pieces equal one run over the sequence; with persistence a later piece is
/// refused (its earlier frames are not in it) instead of replaying its own image.
#[test]
fn one_frame_pieces_of_a_4d_input_are_rendered_frames() {
    let sets = [
        "clock.frame_rate_hz=50",
        "motion.enabled=true",
        "motion.velocity_m_s=12.5",
    ];
    let s = sensor(&sets, |_| {});
    let mut c0 = scene(&s);
    c0.data
        .slice_mut(s![.., 10..16, 12..18])
        .mapv_inplace(|v| v * 20.0);
    let mut c1 = c0.clone();
    c1.data
        .slice_mut(s![.., 10..16, 13..19])
        .mapv_inplace(|v| v * 2.0);
    let mut whole_reader = MemoryCube::sequence(vec![c0.clone(), c1.clone()], None).unwrap();
    let whole = pipeline::run(&s, &mut whole_reader, &options(2, 0, None), |_, _| {}).unwrap();
    let piece = |cube: &Cube, first: u64, sensor: &Sensor| {
        let o = RunOptions {
            time_varying: true,
            ..options(1, first, Some(2))
        };
        pipeline::run(sensor, &mut MemoryCube::new(cube.clone()), &o, |_, _| {})
    };
    let mut pieces = dn(&piece(&c0, 0, &s).unwrap());
    pieces.extend(dn(&piece(&c1, 1, &s).unwrap()));
    assert_eq!(pieces, dn(&whole));
    // The same frame as a static scene is swept by the camera: a different image.
    let swept = run(&s, &c1, &options(1, 1, Some(2))).unwrap();
    assert_ne!(dn(&swept)[0], dn(&whole)[1]);
    let traps = sensor(&sets, with_memory);
    let err = piece(&c1, 1, &traps).unwrap_err().to_string();
    assert!(err.contains("persistence") && err.contains("4-D"), "{err}");
}
