//! Frames of a sequence imaged in parallel (`RunOptions::frames_in_flight`, each frame
//! with its own reopened reader) give the products of the one-frame-at-a-time run, bit for
//! bit, whatever the thread count; the memory budget, a reader that cannot be reopened
//! and a frame that fails to read are handled as the design says.

use std::fs::File;
use std::path::{Path, PathBuf};

use ndarray::{Array2, Array4, Axis};
use ndarray_npy::WriteNpyExt;

use eoir::io::{self, CubeReader, MemoryCube};
use eoir::pipeline::frames::plan_frames_in_flight;
use eoir::pipeline::{self, RunOptions, RunOutput};
use eoir::report::{ExecutionReport, Timings};
use eoir::scene::synthetic::{self, SceneParams};
use eoir::scene::{Cube, CubeMeta};
use eoir::sensor::{presets, Sensor};

/// MultimIR at `rows × cols`, and `n` frames of its thermal scene (2× oversampled,
/// `bands` bands): frame f is the scene scaled by 0.9 + 0.04 f and rolled by f columns,
/// so every frame differs.
fn sequence(rows: usize, cols: usize, bands: usize, n: usize) -> (Sensor, Vec<Cube>) {
    let small = [
        format!("detector.rows={rows}"),
        format!("detector.cols={cols}"),
    ];
    // A still camera: these tests are about frames in flight, not motion.
    let still = ["sequence=still".to_string()];
    let sensor = Sensor::build(&presets::load("multimir", &still, &small).unwrap()).unwrap();
    let (lo, hi) = sensor.response().support_um();
    let params = SceneParams {
        rows,
        cols,
        oversampling: 2,
        wavelength_um: SceneParams::uniform_grid(lo, hi, bands).unwrap(),
        fov_x_deg: (sensor.ifov_rad() * cols as f64).to_degrees(),
        range_m: Some(1000.0),
        seed: 5,
        sun: true,
    };
    let base = synthetic::thermal(&params).unwrap();
    let frames = (0..n)
        .map(|f| {
            let k = 0.9 + 0.04 * f as f32;
            let c = base.meta.cols;
            let data = ndarray::Array3::from_shape_fn(base.data.dim(), |(b, r, x)| {
                base.data[[b, r, (x + f) % c]] * k
            });
            Cube::new(data, base.meta.clone()).unwrap()
        })
        .collect();
    (sensor, frames)
}

/// Writes the frames as one `[frame, band, row, col]` NPY with its JSON sidecar.
fn write_npy_sequence(dir: &Path, frames: &[Cube]) -> PathBuf {
    let m = &frames[0].meta;
    let mut all = Array4::<f32>::zeros((frames.len(), m.bands(), m.rows, m.cols));
    for (f, cube) in frames.iter().enumerate() {
        all.index_axis_mut(Axis(0), f).assign(&cube.data);
    }
    let path = dir.join("seq.npy");
    all.write_npy(File::create(&path).unwrap()).unwrap();
    write_sidecar(&path, m);
    path
}

fn write_sidecar(path: &Path, m: &CubeMeta) {
    let g = m.geometry.unwrap();
    let side = serde_json::json!({
        "wavelength_um": m.wavelength_um,
        "units": m.units.as_str(),
        "fov_deg": [g.fov_x_deg, g.fov_y_deg],
        "range_m": g.range_m,
    });
    std::fs::write(path.with_extension("json"), side.to_string()).unwrap();
}

fn in_pool<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

fn options(frames_in_flight: Option<usize>, calibrate: bool) -> RunOptions {
    let mut o = RunOptions {
        seed: 11,
        frames_in_flight,
        ..RunOptions::default()
    };
    if !calibrate {
        o.calibration = None;
    }
    o
}

/// Runs `reader` with `threads` threads, checking the progress callback climbs to its
/// total.
fn run(
    sensor: &Sensor,
    open: Opener,
    threads: usize,
    opts: &RunOptions,
) -> eoir::Result<RunOutput> {
    run_within(
        sensor,
        open,
        threads,
        opts,
        eoir::limits::max_memory_bytes(),
    )
}

/// Makes the run's input reader (on the pool's thread: readers need not be `Send`).
type Opener<'a> = &'a (dyn Fn() -> Box<dyn CubeReader> + Sync);

/// [`run`] with the memory limit `budget` on the thread that calls `pipeline::run`.
fn run_within(
    sensor: &Sensor,
    open: Opener,
    threads: usize,
    opts: &RunOptions,
    budget: u64,
) -> eoir::Result<RunOutput> {
    let mut seen: Vec<(usize, usize)> = Vec::new();
    let out = in_pool(threads, || {
        eoir::limits::with_thread_max_memory(budget, || {
            pipeline::run(sensor, open().as_mut(), opts, |d, t| seen.push((d, t)))
        })
    })??;
    let (last, total) = *seen.last().expect("progress was reported");
    assert_eq!(last, total, "progress ends at its total: {seen:?}");
    assert!(seen.windows(2).all(|w| w[0].0 <= w[1].0), "{seen:?}");
    Ok(out)
}

fn bits(a: &Array2<f32>) -> Vec<u32> {
    a.iter().map(|v| v.to_bits()).collect()
}

/// Every product bit for bit, and the report but for timings and execution facts.
fn assert_same(a: &RunOutput, b: &RunOutput, what: &str) {
    assert_eq!(a.frames.len(), b.frames.len(), "{what}");
    for (f, (x, y)) in a.frames.iter().zip(&b.frames).enumerate() {
        assert_eq!(x.dn, y.dn, "{what}: DN of frame {f}");
        assert_eq!(bits(&x.electrons_mean), bits(&y.electrons_mean), "{what}");
        assert_eq!(x.radiance.as_ref().map(bits), y.radiance.as_ref().map(bits));
        assert_eq!(
            x.temperature.as_ref().map(bits),
            y.temperature.as_ref().map(bits)
        );
        assert_eq!(x.rgb, y.rgb, "{what}");
    }
    let blank = |o: &RunOutput| {
        let mut r = o.report.clone();
        r.timings_s = Timings::default();
        r.execution = ExecutionReport::default();
        r.to_json_pretty().unwrap()
    };
    assert_eq!(blank(a), blank(b), "{what}: report");
    assert_eq!(a.warnings, b.warnings, "{what}: warnings");
}

#[test]
fn npy_sequence_in_parallel_equals_one_frame_at_a_time() {
    let (sensor, frames) = sequence(24, 32, 16, 5);
    let dir = tempfile::tempdir().unwrap();
    let path = write_npy_sequence(dir.path(), &frames);
    let open = || io::open(&path).unwrap();
    let reference = run(&sensor, &open, 1, &options(Some(1), true)).unwrap();
    assert_eq!(reference.report.execution.frames_in_flight, 1);
    assert!(reference.frames[0].temperature.is_some(), "calibrated");
    // The frames differ, so equal products cannot come from one frame repeated.
    assert_ne!(reference.frames[0].dn, reference.frames[1].dn);
    for threads in [1, 2] {
        for (request, expect) in [(Some(1), 1), (Some(2), 2), (Some(3), 3), (Some(9), 5)] {
            let out = run(&sensor, &open, threads, &options(request, true)).unwrap();
            let what = format!("{threads} thread(s), {request:?} in flight");
            assert_same(&reference, &out, &what);
            let e = &out.report.execution;
            assert_eq!((e.threads, e.frames_in_flight), (threads, expect), "{what}");
        }
        // Unset: one frame per thread.
        let out = run(&sensor, &open, threads, &options(None, true)).unwrap();
        assert_same(&reference, &out, "default");
        let e = &out.report.execution;
        assert_eq!(e.frames_in_flight, threads);
        assert!(
            e.frames_in_flight_limit.starts_with("thread count"),
            "{e:?}"
        );
    }
}

#[test]
fn bayer_sequence_from_memory_in_parallel_equals_one_at_a_time() {
    // Three colour channels per frame, mosaicked, then demosaicked: the CFA stage in the
    // frame tasks.
    let small = [
        "detector.rows=24".to_string(),
        "detector.cols=32".to_string(),
    ];
    let sensor = Sensor::build(&presets::load("ccd-bayer", &[], &small).unwrap()).unwrap();
    let (lo, hi) = sensor.response().support_um();
    let params = SceneParams {
        rows: 24,
        cols: 32,
        oversampling: 2,
        wavelength_um: SceneParams::uniform_grid(lo, hi, 12).unwrap(),
        fov_x_deg: (sensor.ifov_rad() * 32.0).to_degrees(),
        range_m: Some(1000.0),
        seed: 2,
        sun: true,
    };
    let base = synthetic::generate("thermal", &params).unwrap();
    let frames: Vec<Cube> = (0..4)
        .map(|f| {
            Cube::new(
                base.data.mapv(|v| v * (1.0 + 0.1 * f as f32)),
                base.meta.clone(),
            )
        })
        .collect::<eoir::Result<_>>()
        .unwrap();
    let cube = MemoryCube::sequence(frames, None).unwrap();
    let open = || Box::new(cube.clone()) as Box<dyn CubeReader>;
    let one = run(&sensor, &open, 2, &options(Some(1), false)).unwrap();
    let two = run(&sensor, &open, 2, &options(Some(2), false)).unwrap();
    assert!(one.frames[0].rgb.is_some());
    assert_same(&one, &two, "Bayer");
    assert_eq!(two.report.execution.frames_in_flight, 2);
}

#[test]
fn a_budget_without_room_for_a_second_frame_images_one_at_a_time() {
    // Big enough that the budget in question is above the 1 MiB floor of the limit.
    let (sensor, frames) = sequence(96, 96, 6, 3);
    let cube = MemoryCube::sequence(frames, None).unwrap();
    let open = || Box::new(cube.clone()) as Box<dyn CubeReader>;
    let opts = options(Some(2), false);
    let free = run(&sensor, &open, 2, &opts).unwrap();
    let e = free.report.execution.clone();
    assert_eq!(e.frames_in_flight, 2, "{e:?}");
    assert!(
        e.run_bytes > 1 << 20 && e.frame_bytes_in_flight > 1 << 20,
        "{e:?}"
    );
    // Room for the run and all but one byte of a second frame: one at a time.
    let tight = e.run_bytes + e.frame_bytes_in_flight - 1;
    let one = run_within(&sensor, &open, 2, &opts, tight).unwrap();
    let x = &one.report.execution;
    assert_eq!(x.frames_in_flight, 1, "{x:?}");
    assert!(
        x.frames_in_flight_limit.starts_with("memory budget"),
        "{x:?}"
    );
    assert_same(&free, &one, "budget fallback");
    // Exactly room for two.
    let two = run_within(&sensor, &open, 2, &opts, tight + 1).unwrap();
    assert_eq!(two.report.execution.frames_in_flight, 2);
    assert_same(&free, &two, "budget of exactly two");
}

#[test]
fn planning_takes_the_smallest_limit_and_names_it() {
    let mib = 1u64 << 20;
    let plan = |req, frames, threads, budget| {
        plan_frames_in_flight(req, frames, threads, 10 * mib, 4 * mib, budget)
    };
    assert_eq!(plan(None, 8, 4, 1 << 40).0, 4);
    assert!(plan(None, 8, 4, 1 << 40).1.starts_with("thread count"));
    assert_eq!(plan(Some(6), 8, 2, 1 << 40).0, 6);
    assert_eq!(plan(Some(6), 3, 2, 1 << 40).0, 3);
    assert!(plan(Some(6), 3, 2, 1 << 40).1.starts_with("frames"));
    // 10 MiB for the run + 4 MiB per further frame: 21 MiB holds 3 frames in flight.
    assert_eq!(plan(Some(8), 8, 8, 21 * mib).0, 3);
    assert!(plan(Some(8), 8, 8, 21 * mib).1.starts_with("memory budget"));
    assert_eq!(plan(Some(8), 8, 8, 14 * mib - 1).0, 1);
    assert_eq!(
        plan(Some(8), 1, 8, 1 << 40),
        (1, "one frame to image".into())
    );
}

#[test]
fn a_reader_error_in_frame_k_of_a_parallel_run_is_the_run_error() {
    let (sensor, mut frames) = sequence(24, 32, 8, 6);
    // A NaN in frame 4 (band 2) and in frame 2 (band 5): a one-at-a-time run meets
    // frame 2's first, and so must the parallel run, whichever task reads first.
    frames[4].data[[2, 3, 4]] = f32::NAN;
    frames[2].data[[5, 7, 1]] = f32::NAN;
    let dir = tempfile::tempdir().unwrap();
    let path = write_npy_sequence(dir.path(), &frames);
    let fail = |threads, k| {
        let o = options(Some(k), false);
        in_pool(threads, || {
            pipeline::run(&sensor, io::open(&path).unwrap().as_mut(), &o, |_, _| {})
        })
        .unwrap_err()
        .to_string()
    };
    let sequential = fail(1, 1);
    assert!(
        sequential.contains("band 5") && sequential.contains("NaN"),
        "{sequential}"
    );
    for (threads, k) in [(1, 2), (2, 2), (2, 3), (2, 6)] {
        assert_eq!(
            fail(threads, k),
            sequential,
            "{threads} threads, {k} in flight"
        );
    }
    // Only frame 4 bad: frames 0–3 are imaged (and exposed) before it, the error stands.
    frames[2].data[[5, 7, 1]] = 1.0;
    let path = write_npy_sequence(dir.path(), &frames);
    let e = in_pool(2, || {
        let mut r = io::open(&path).unwrap();
        pipeline::run(&sensor, r.as_mut(), &options(Some(2), false), |_, _| {})
    })
    .unwrap_err()
    .to_string();
    assert!(e.contains("band 2") && e.contains("NaN"), "{e}");
}

/// A reader without `reopen` (the trait's default).
struct NoReopen(MemoryCube);

impl CubeReader for NoReopen {
    fn meta(&self) -> &CubeMeta {
        self.0.meta()
    }
    fn frames(&self) -> usize {
        self.0.frames()
    }
    fn read_band(&mut self, frame: usize, band: usize) -> eoir::Result<Array2<f32>> {
        self.0.read_band(frame, band)
    }
}

#[test]
fn a_reader_that_cannot_be_reopened_images_one_frame_at_a_time() {
    let (sensor, frames) = sequence(24, 32, 8, 3);
    let cube = MemoryCube::sequence(frames, None).unwrap();
    let opts = options(Some(3), false);
    let shared = run(&sensor, &|| Box::new(cube.clone()), 2, &opts).unwrap();
    assert_eq!(shared.report.execution.frames_in_flight, 3);
    let plain = run(&sensor, &|| Box::new(NoReopen(cube.clone())), 2, &opts).unwrap();
    let x = &plain.report.execution;
    assert_eq!(x.frames_in_flight, 1);
    assert_eq!(x.frames_in_flight_limit, "the reader cannot be reopened");
    assert_same(&shared, &plain, "no reopen");
}

#[test]
fn a_static_input_is_imaged_once_and_zero_in_flight_is_refused() {
    let (sensor, frames) = sequence(24, 32, 8, 1);
    let mut cube = MemoryCube::new(frames[0].clone());
    let mut o = options(Some(4), false);
    o.frames = 3;
    let out = run(&sensor, &|| Box::new(cube.clone()), 2, &o).unwrap();
    assert_eq!(out.frames.len(), 3);
    let x = &out.report.execution;
    assert_eq!(
        (x.frames_in_flight, x.frames_in_flight_limit.as_str()),
        (1, "one frame to image")
    );
    o.frames_in_flight = Some(0);
    let e = pipeline::run(&sensor, &mut cube, &o, |_, _| {}).unwrap_err();
    assert!(e.to_string().contains("frames_in_flight"), "{e}");
}

#[test]
fn reopened_envi_and_npy_readers_read_the_same_planes() {
    let (_, frames) = sequence(12, 16, 5, 2);
    let dir = tempfile::tempdir().unwrap();
    let hdr = dir.path().join("c.hdr");
    io::write_cube(&hdr, &frames[0]).unwrap();
    let npy = write_npy_sequence(dir.path(), &frames);
    for path in [hdr, npy] {
        let mut a = io::open(&path).unwrap();
        let mut b = a.reopen().expect("file readers reopen").unwrap();
        assert_eq!(a.meta(), b.meta());
        assert_eq!(a.units_source(), b.units_source());
        for f in (0..a.frames()).rev() {
            // Interleaved reads on the two readers: each keeps its own position.
            for band in [3, 0, 4] {
                let (x, y) = (a.read_band(f, band).unwrap(), b.read_band(f, band).unwrap());
                assert_eq!(
                    bits(&x),
                    bits(&y),
                    "{} frame {f} band {band}",
                    path.display()
                );
                assert_eq!(
                    bits(&x),
                    bits(&frames[f].data.index_axis(Axis(0), band).to_owned())
                );
            }
        }
    }
}

#[cfg(feature = "hdf5")]
#[test]
fn hdf5_sequence_in_parallel_equals_one_frame_at_a_time() {
    let (sensor, frames) = sequence(24, 32, 8, 4);
    let m = frames[0].meta.clone();
    let mut all = Array4::<f32>::zeros((frames.len(), m.bands(), m.rows, m.cols));
    for (f, cube) in frames.iter().enumerate() {
        all.index_axis_mut(Axis(0), f).assign(&cube.data);
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("seq.h5");
    io::hdf5::write_frames(&path, &m, all.view(), None).unwrap();
    let open = || io::open(&path).unwrap();
    let one = run(&sensor, &open, 2, &options(Some(1), false)).unwrap();
    let two = run(&sensor, &open, 2, &options(Some(2), false)).unwrap();
    assert_eq!(two.report.execution.frames_in_flight, 2);
    assert_same(&one, &two, "HDF5");
}

#[test]
fn cli_frames_in_flight_changes_no_product_byte() {
    let (_, frames) = sequence(24, 32, 8, 4);
    let dir = tempfile::tempdir().unwrap();
    let input = write_npy_sequence(dir.path(), &frames);
    let eoir = env!("CARGO_BIN_EXE_eoir");
    let run = |k: &str| {
        let out = dir.path().join(format!("out{k}"));
        let o = std::process::Command::new(eoir)
            .args([
                "run",
                "--quiet",
                "--sensor",
                "multimir",
                "--frames-in-flight",
                k,
            ])
            .args(["--set", "detector.rows=24", "--set", "detector.cols=32"])
            .arg(&input)
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        out
    };
    let (one, two) = (run("1"), run("2"));
    for name in [
        "frame_0000_dn.tiff",
        "frame_0003_dn.tiff",
        "frame_0002_temperature.tiff",
    ] {
        let (a, b) = (
            std::fs::read(one.join(name)).unwrap(),
            std::fs::read(two.join(name)).unwrap(),
        );
        assert!(a == b, "{name} differs");
    }
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(two.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["execution"]["frames_in_flight"], 2);
    // Zero is refused by the parser.
    let o = std::process::Command::new(eoir)
        .args(["run", "--frames-in-flight", "0", "x.npy", "-o"])
        .arg(dir.path().join("never"))
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--frames-in-flight"));
    assert!(!dir.path().join("never").exists());
}

/// A consumer that checks frames come once each, in order, and records how many bands
/// the run had imaged when each arrived.
struct Recorder<'a> {
    bands_done: &'a std::sync::atomic::AtomicUsize,
    started_with: Option<usize>,
    bands_at: Vec<usize>,
    frames: Vec<pipeline::FrameProducts>,
}

impl pipeline::FrameConsumer for Recorder<'_> {
    fn start(&mut self, frames: usize) -> eoir::Result<()> {
        self.started_with = Some(frames);
        Ok(())
    }

    fn frame(&mut self, index: usize, frame: pipeline::FrameProducts) -> eoir::Result<()> {
        assert_eq!(index, self.frames.len(), "frames in order, once each");
        self.bands_at
            .push(self.bands_done.load(std::sync::atomic::Ordering::Relaxed));
        self.frames.push(frame);
        Ok(())
    }
}

/// The streamed run (issue 34: memory independent of the frame count): each frame is
/// handed on as soon as it is exposed — with one frame in flight, frame i arrives when
/// exactly i + 1 frames' bands were imaged, not after the whole sequence — with the
/// frames and report of the collecting `pipeline::run`, calibrated (radiance and
/// temperature made frame by frame). Its memory check counts only the frames it holds:
/// a budget with room for 7 frames of products refuses the collecting run of 12 and
/// lets the streamed one through. `eoir run` of the same sequence writes, frame by frame,
/// the library's frames: `dn_stack.npy` (read with ndarray-npy) and a frame's TIFFs hold
/// them, and the animated preview's frames use the stretch of the 0.5 and 99.5
/// percentiles of every DN of the sequence, computed here by sorting them all.
#[test]
fn a_streamed_run_hands_each_frame_on_as_exposed_and_writes_the_collected_products() {
    const N: usize = 12;
    let (rows, cols) = (96, 96);
    let (sensor, frames) = sequence(rows, cols, 3, N);
    let cube = MemoryCube::sequence(frames.clone(), None).unwrap();
    let open = || Box::new(cube.clone()) as Box<dyn CubeReader>;
    let opts = options(Some(1), true);
    let collected = run(&sensor, &open, 2, &opts).unwrap();
    let bands_done = std::sync::atomic::AtomicUsize::new(0);
    let mut rec = Recorder {
        bands_done: &bands_done,
        started_with: None,
        bands_at: Vec::new(),
        frames: Vec::new(),
    };
    let mut total = 0;
    let streamed = in_pool(2, || {
        pipeline::run_streaming(
            &sensor,
            open().as_mut(),
            &opts,
            |d, t| {
                bands_done.store(d, std::sync::atomic::Ordering::Relaxed);
                total = t;
            },
            &mut rec,
        )
    })
    .unwrap();
    assert_eq!(rec.started_with, Some(N));
    let per_frame = total / N;
    let want: Vec<usize> = (1..=N).map(|i| i * per_frame).collect();
    assert_eq!(rec.bands_at, want, "frames handed on as they are exposed");
    assert_eq!(streamed.frame_count, N);
    assert!(collected.frames[0].temperature.is_some(), "calibrated");
    assert_same(
        &collected,
        &RunOutput {
            frames: rec.frames,
            ..collected.clone()
        },
        "streamed frames",
    );
    assert_eq!(streamed.first.dn, collected.frames[0].dn);
    assert_eq!(
        streamed.first.temperature.as_ref().map(bits),
        collected.frames[0].temperature.as_ref().map(bits)
    );
    let stable = |r: &eoir::report::RunReport| {
        let mut v = serde_json::to_value(r).unwrap();
        let o = v.as_object_mut().unwrap();
        o.remove("timings_s");
        o.remove("execution");
        v
    };
    assert_eq!(stable(&streamed.report), stable(&collected.report));

    // The memory check: room for 7 frames of detector products (17 bytes a pixel) beyond
    // what the streamed run counts (2 frames held).
    let frame_bytes = (rows * cols * 17) as u64;
    let budget = streamed.report.execution.run_bytes + 5 * frame_bytes;
    let e = run_within(&sensor, &open, 2, &opts, budget).unwrap_err();
    assert!(
        matches!(e, eoir::error::Error::TooLarge { .. }),
        "the collecting run counts all {N} frames: {e}"
    );
    let mut sink = Vec::new();
    let ok = in_pool(2, || {
        eoir::limits::with_thread_max_memory(budget, || {
            pipeline::run_streaming(
                &sensor,
                open().as_mut(),
                &opts,
                |_, _| {},
                &mut DropFrames(&mut sink),
            )
        })
    })
    .unwrap();
    assert!(ok.is_ok(), "{:?}", ok.err());
    assert_eq!(sink, (0..N).collect::<Vec<_>>());

    // The CLI streams the same frames into its product set.
    let dir = tempfile::tempdir().unwrap();
    let input = write_npy_sequence(dir.path(), &frames);
    let out = dir.path().join("out");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_eoir"))
        .args(["run", "--quiet", "--sensor", "multimir", "--option"])
        .args(["sequence=still", "--seed", "11", "--frames-in-flight", "1"])
        .args(["--set", &format!("detector.rows={rows}")])
        .args(["--set", &format!("detector.cols={cols}")])
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stack: ndarray::Array3<u16> =
        ndarray_npy::read_npy(out.join("dn_stack.npy")).expect("dn_stack.npy");
    assert_eq!(stack.dim(), (N, rows, cols));
    for (f, frame) in collected.frames.iter().enumerate() {
        assert_eq!(stack.index_axis(Axis(0), f), frame.dn, "dn_stack frame {f}");
    }
    let f5 = &collected.frames[5];
    let dn5 = io::raster::read_tiff_u16(&out.join("frame_0005_dn.tiff")).unwrap();
    assert_eq!(dn5, f5.dn);
    let t5 = io::raster::read_tiff_f32(&out.join("frame_0005_temperature.tiff")).unwrap();
    assert_eq!(bits(&t5), bits(f5.temperature.as_ref().unwrap()));
    let mut all: Vec<u16> = stack.iter().copied().collect();
    all.sort_unstable();
    let pick = |q: f64| all[((all.len() - 1) as f64 * q) as usize] as f64;
    let (lo, hi) = (pick(0.005), pick(0.995));
    let png = std::fs::read(out.join("preview.png")).unwrap();
    let mut reader = png::Decoder::new(std::io::Cursor::new(png))
        .read_info()
        .unwrap();
    let mut buf = vec![0u8; reader.output_buffer_size().unwrap()];
    for f in 0..N {
        reader.next_frame(&mut buf).unwrap();
        let want: Vec<u8> = stack
            .index_axis(Axis(0), f)
            .iter()
            .map(|&v| {
                ((v as f64 - lo) / (hi - lo).max(1.0) * 255.0)
                    .round()
                    .clamp(0.0, 255.0) as u8
            })
            .collect();
        assert!(buf[..rows * cols] == want[..], "preview frame {f}");
    }
}

/// A consumer that keeps only the indices of the frames it was handed.
struct DropFrames<'a>(&'a mut Vec<usize>);

impl pipeline::FrameConsumer for DropFrames<'_> {
    fn frame(&mut self, index: usize, _frame: pipeline::FrameProducts) -> eoir::Result<()> {
        self.0.push(index);
        Ok(())
    }
}
