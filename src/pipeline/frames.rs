//! The frame loop of a run: every frame of the input is imaged (several at once where the
//! thread pool, the memory budget and the reader allow) and exposed in frame order.
//!
//! **Frames in flight.** A sequence's frames are independent until the detector: the
//! imaging stage holds only immutable tables and plans, so `K` frames can be imaged at once,
//! each by a task of the thread pool with its own reader ([`CubeReader::reopen`]) and its
//! own accumulator, row spectra and chunk planes. Each task takes the next frame index from
//! a shared counter and hands the mean image to the calling thread, which exposes the
//! frames strictly in frame order (a scene-mean auto gain is fixed from frame 0, as in a
//! one-at-a-time run) and reports progress. A frame's mean image depends only on its
//! planes (the accumulation is deterministic for any thread count) and its temporal noise
//! only on its index (`first_frame + f`), so the products are the same, bit for bit, for
//! any `K` and any thread count. `K` is the smallest of the request (default: the thread
//! count), the frames to image, and what the memory budget leaves after the run's own
//! needs ([`ImagingStage::frame_bytes_in_flight`] per extra frame); a reader that cannot
//! be reopened gives `K = 1`. The report's `execution` section says which limit applied.
//!
//! **Frames handed on.** Each exposed frame is calibrated (thermal sensors) and handed to
//! the run's [`FrameConsumer`] at once, in frame order: the loop keeps only a copy of
//! frame 0 (for the report), so what a run holds does not grow with the frame count unless
//! the consumer keeps the frames (the collecting consumer of [`super::run`] does).
//!
//! **Errors.** The first failing frame (lowest index) decides the error, as in a
//! one-at-a-time run: no new frame is started once a frame failed, the frames in flight
//! finish, and the run returns the error without products. An error of the consumer
//! (e.g. a full disk while writing frame 50) is the error of that frame.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender, TryRecvError};
use std::time::{Duration, Instant};

use ndarray::Array2;

use crate::error::{Error, Result};
use crate::imaging::ImagingStats;
use crate::io::CubeReader;
use crate::report::ExecutionReport;
use crate::scene::CubeMeta;
use crate::sensor::Sensor;

use super::calibrate::FrameCalibration;
use super::expose::Exposure;
use super::image::{add_stats, ImagingStage};
use super::{colour, finite_mean, FrameConsumer, FrameProducts, RunOptions};

/// What the frame loop hands back to the run.
pub(super) struct FramesDone {
    /// Frame 0's products (calibrated), kept for the report; every frame went to the
    /// consumer.
    pub first: FrameProducts,
    /// The calibration applied to the frames, to be finished with the report's checks.
    pub calibration: FrameCalibration,
    /// Seconds spent calibrating (making the calibration and applying it to the frames).
    pub calibration_s: f64,
    /// The exposure stage (gain fixed, sensor instance).
    pub exposure: Exposure,
    /// Imaging timings summed over the frames, padded shape, precision.
    pub stats: ImagingStats,
    /// Seconds in the detector stage.
    pub detector_s: f64,
    /// Threads and frames in flight.
    pub execution: ExecutionReport,
    /// Warnings of the extra readers (a run with frames in flight reads through reopened
    /// readers), to be merged with the input reader's.
    pub reader_warnings: Vec<String>,
}

/// What a run is to image: the stage, the input's metadata and frame count, the sensor,
/// the options, the number of frames to produce and the memory the run already needs.
pub(super) struct FrameJob<'a> {
    /// The imaging stage.
    pub stage: &'a ImagingStage,
    /// The input's metadata.
    pub meta: &'a CubeMeta,
    /// The sensor.
    pub sensor: &'a Sensor,
    /// The run's options.
    pub options: &'a RunOptions,
    /// Frames of the input (1 = a static scene, imaged once, unless `rendered`).
    pub input_frames: usize,
    /// The input is time-varying (several frames, or a one-frame piece of a 4-D input,
    /// [`RunOptions::time_varying`]): each frame is imaged from its own planes, never
    /// from another frame's.
    pub rendered: bool,
    /// Frames to produce.
    pub n_frames: usize,
    /// Bytes the run needs with one frame in flight ([`crate::limits::check_run`]).
    pub run_bytes: u64,
}

/// How many frames to image at once, and what set that number. `requested` is the option
/// (`None` = as many as threads); `budget_bytes` the memory limit, `run_bytes` what the run
/// needs with one frame in flight and `frame_bytes` what each further frame adds.
pub fn plan_frames_in_flight(
    requested: Option<usize>,
    frames_to_image: usize,
    threads: usize,
    run_bytes: u64,
    frame_bytes: u64,
    budget_bytes: u64,
) -> (usize, String) {
    if frames_to_image <= 1 {
        return (1, "one frame to image".to_string());
    }
    let (mut k, mut limit) = match requested {
        Some(n) => (n.max(1), format!("requested ({n})")),
        None => (threads.max(1), format!("thread count ({threads})")),
    };
    if frames_to_image < k {
        (k, limit) = (frames_to_image, format!("frames ({frames_to_image})"));
    }
    let spare = budget_bytes.saturating_sub(run_bytes);
    let by_memory = 1 + spare.checked_div(frame_bytes).unwrap_or(u64::MAX);
    if by_memory < k as u64 {
        k = by_memory as usize;
        limit = format!(
            "memory budget ({}: the run needs {} with one frame in flight, each further frame {})",
            crate::limits::human_bytes(budget_bytes),
            crate::limits::human_bytes(run_bytes),
            crate::limits::human_bytes(frame_bytes)
        );
    }
    (k, limit)
}

/// Images and exposes every frame of the job; see the [module documentation](self).
/// `progress(done, total)` is called on the calling thread, `done` counting bands over all
/// frames up to `total`.
pub(super) fn image_and_expose(
    job: &FrameJob,
    reader: &mut dyn CubeReader,
    progress: &mut dyn FnMut(usize, usize),
    consumer: &mut dyn FrameConsumer,
) -> Result<FramesDone> {
    // `[optics.distortion]`: every band is read resampled (imaging::distortion).
    let mut distorted;
    let reader: &mut dyn CubeReader =
        match crate::imaging::distortion::resampler_for(job.sensor, job.stage.sampling())? {
            Some(r) => {
                distorted = crate::imaging::distortion::DistortedReader::new(reader, r);
                &mut distorted
            }
            None => reader,
        };
    let threads = rayon::current_num_threads();
    let to_image = if job.input_frames == 1 {
        1
    } else {
        job.n_frames
    };
    if job.options.frames_in_flight == Some(0) {
        return Err(Error::param(
            "frames_in_flight",
            0,
            "at least 1 (frames imaged at once), or unset for one per thread",
        ));
    }
    let frame_bytes = job.stage.frame_bytes_in_flight(
        job.meta,
        (job.sensor.detector.rows, job.sensor.detector.cols),
    );
    let (mut k, mut limit) = plan_frames_in_flight(
        job.options.frames_in_flight,
        to_image,
        threads,
        job.run_bytes,
        frame_bytes,
        crate::limits::max_memory_bytes(),
    );
    let mut readers: Vec<Box<dyn CubeReader + Send>> = Vec::new();
    while k > 1 && readers.len() < k {
        match reader.reopen() {
            Some(Ok(r)) if r.meta() == job.meta && r.frames() == job.input_frames => {
                readers.push(r)
            }
            Some(Ok(_)) => {
                (k, limit) = (1, "the input changed since it was opened".into());
            }
            Some(Err(e)) => (k, limit) = (1, format!("the input could not be reopened: {e}")),
            None => (k, limit) = (1, "the reader cannot be reopened".into()),
        }
    }
    // The frames of a sequence reuse the chunks' OTF profiles the first one builds, in
    // memory the plan leaves free (at most PROFILE_CACHE_BYTES).
    if to_image > 1 {
        let planned = job
            .run_bytes
            .saturating_add((k as u64).saturating_mul(frame_bytes));
        let left = crate::limits::max_memory_bytes().saturating_sub(planned);
        let cap = crate::imaging::PROFILE_CACHE_BYTES as u64;
        job.stage
            .keep_chunk_profiles(usize::try_from(left.min(cap)).unwrap_or(0));
    }
    consumer.start(job.n_frames)?;
    let mut sink = Sink::new(job, to_image, consumer);
    let mut done = Done::default();
    if k == 1 {
        sequential(job, reader, &mut sink, &mut done, progress)?;
    } else {
        in_parallel(job, readers, &mut sink, &mut done, progress)?;
    }
    let kept = sink.finish()?;
    Ok(FramesDone {
        first: kept.first,
        calibration: kept.calibration,
        calibration_s: kept.calibration_s,
        exposure: kept.exposure,
        detector_s: kept.detector_s,
        stats: done.stats,
        execution: ExecutionReport {
            threads,
            frames_in_flight: k,
            frames_in_flight_limit: limit,
            run_bytes: job.run_bytes,
            frame_bytes_in_flight: frame_bytes,
        },
        reader_warnings: done.reader_warnings,
    })
}

/// Imaging totals: the timings summed in frame order of arrival, the readers' warnings.
#[derive(Default)]
struct Done {
    stats: ImagingStats,
    reader_warnings: Vec<String>,
}

/// The frames one after another through the input reader, on the calling thread (each
/// frame's transforms still use every thread of the pool).
fn sequential(
    job: &FrameJob,
    reader: &mut dyn CubeReader,
    sink: &mut Sink,
    done: &mut Done,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<()> {
    let active = job.stage.bands_used();
    let total = job.input_frames * active;
    if !job.rendered && job.stage.motion().is_some() {
        // A static scene seen by a moving camera: one spectrum, one inverse per frame.
        let s = job.stage.static_sequence(
            reader,
            job.n_frames,
            |b| progress(b, total),
            |g, e, earlier| sink.expose(g, &e, Some(earlier)),
        )?;
        add_stats(&mut done.stats, &s);
        sink.next = 1;
        return Ok(());
    }
    for f in 0..sink.to_image {
        let (e, s) = job
            .stage
            .mean_electrons(reader, f, |b| progress(f * active + b, total))?;
        add_stats(&mut done.stats, &s);
        sink.imaged(f, e)?;
    }
    Ok(())
}

/// A message from a frame task to the calling thread.
enum Msg {
    /// More bands of some frame were imaged.
    Bands(usize),
    /// Frame `f` was imaged (or failed).
    Imaged(usize, Result<(Array2<f64>, ImagingStats)>),
    /// Task `i` finished; its reader's warnings.
    Finished(usize, Vec<String>),
}

/// `readers.len()` frame tasks on the pool, the calling thread exposing in frame order.
fn in_parallel(
    job: &FrameJob,
    readers: Vec<Box<dyn CubeReader + Send>>,
    sink: &mut Sink,
    done: &mut Done,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<()> {
    let total = job.input_frames * job.stage.bands_used();
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let (tx, rx) = mpsc::channel::<Msg>();
    let to_image = sink.to_image;
    let stage = job.stage;
    let mut failed: Option<(usize, Error)> = None;
    let mut warnings: BTreeMap<usize, Vec<String>> = BTreeMap::new();
    rayon::in_place_scope(|scope| {
        for (i, mut reader) in readers.into_iter().enumerate() {
            let (tx, next, stop) = (tx.clone(), &next, &stop);
            scope.spawn(move |_| {
                frame_task(stage, reader.as_mut(), to_image, next, stop, &tx);
                let _ = tx.send(Msg::Finished(i, reader.warnings()));
            });
        }
        drop(tx);
        let mut pending: BTreeMap<usize, Array2<f64>> = BTreeMap::new();
        let mut bands = 0;
        while let Some(msg) = receive(&rx) {
            match msg {
                Msg::Bands(n) => {
                    bands += n;
                    progress(bands, total);
                }
                Msg::Imaged(f, Ok((e, s))) => {
                    add_stats(&mut done.stats, &s);
                    pending.insert(f, e);
                }
                Msg::Imaged(f, Err(e)) => note_failure(&mut failed, f, e, &stop),
                Msg::Finished(i, w) => {
                    warnings.insert(i, w);
                }
            }
            // Expose whatever is next in frame order, unless an earlier frame failed.
            while failed.as_ref().is_none_or(|(f, _)| sink.next < *f) {
                let Some(e) = pending.remove(&sink.next) else {
                    break;
                };
                let f = sink.next;
                if let Err(err) = sink.imaged(f, e) {
                    note_failure(&mut failed, f, err, &stop);
                }
            }
        }
    });
    if let Some((_, e)) = failed {
        return Err(e);
    }
    done.reader_warnings = warnings.into_values().flatten().collect();
    Ok(())
}

/// Keeps the error of the lowest frame (what a one-at-a-time run would meet first) and
/// tells the tasks to start no new frame.
fn note_failure(failed: &mut Option<(usize, Error)>, f: usize, e: Error, stop: &AtomicBool) {
    stop.store(true, Ordering::Relaxed);
    if failed.as_ref().is_none_or(|(g, _)| f < *g) {
        *failed = Some((f, e));
    }
}

/// One frame task: takes frame indices from `next` until none is left or `stop` is set,
/// images each through its own `reader`, and sends progress and the mean image.
fn frame_task(
    stage: &ImagingStage,
    reader: &mut dyn CubeReader,
    to_image: usize,
    next: &AtomicUsize,
    stop: &AtomicBool,
    tx: &Sender<Msg>,
) {
    while !stop.load(Ordering::Relaxed) {
        let f = next.fetch_add(1, Ordering::Relaxed);
        if f >= to_image {
            break;
        }
        let mut sent = 0;
        let result = stage.mean_electrons(reader, f, |b| {
            let _ = tx.send(Msg::Bands(b - sent));
            sent = b;
        });
        let failed = result.is_err();
        let _ = tx.send(Msg::Imaged(f, result));
        if failed {
            break;
        }
    }
}

/// The next message, `None` once every task has finished. On a thread of the pool (a run
/// called inside `ThreadPool::install`) the wait helps with the pool's work instead of
/// blocking: the frame tasks may be queued behind it, and with one thread nothing else
/// would run them.
fn receive(rx: &Receiver<Msg>) -> Option<Msg> {
    if rayon::current_thread_index().is_none() {
        return rx.recv().ok();
    }
    loop {
        match rx.try_recv() {
            Ok(m) => return Some(m),
            Err(TryRecvError::Disconnected) => return None,
            Err(TryRecvError::Empty) => {}
        }
        if let Some(rayon::Yield::Executed) = rayon::yield_now() {
            continue;
        }
        match rx.recv_timeout(Duration::from_millis(1)) {
            Ok(m) => return Some(m),
            Err(RecvTimeoutError::Disconnected) => return None,
            Err(RecvTimeoutError::Timeout) => {}
        }
    }
}

/// The exposure side of the loop: takes mean images in frame order, exposes them (a static
/// input's single image once per requested frame), calibrates each frame and hands it to
/// the consumer, keeping only frame 0's products.
struct Sink<'a> {
    job: &'a FrameJob<'a>,
    /// Frames to image (1 for a static input).
    to_image: usize,
    /// The next frame to expose.
    next: usize,
    exposure: Option<Exposure>,
    /// Made with the exposure stage (once the first frame fixed the gain).
    calibration: Option<FrameCalibration>,
    consumer: &'a mut dyn FrameConsumer,
    /// Frames handed to the consumer.
    handed: usize,
    /// A copy of frame 0's products.
    first: Option<FrameProducts>,
    detector_s: f64,
    calibration_s: f64,
}

/// What the exposure side keeps once every frame was handed on.
struct Kept {
    first: FrameProducts,
    exposure: Exposure,
    calibration: FrameCalibration,
    detector_s: f64,
    calibration_s: f64,
}

impl<'a> Sink<'a> {
    fn new(job: &'a FrameJob<'a>, to_image: usize, consumer: &'a mut dyn FrameConsumer) -> Self {
        Sink {
            job,
            to_image,
            next: 0,
            exposure: None,
            calibration: None,
            consumer,
            handed: 0,
            first: None,
            detector_s: 0.0,
            calibration_s: 0.0,
        }
    }

    /// Frame `f`'s mean image (`f` must be the next in order): exposes it, and for a
    /// static input every requested frame.
    fn imaged(&mut self, f: usize, e: Array2<f64>) -> Result<()> {
        debug_assert_eq!(f, self.next);
        let job = self.job;
        let repeats = if job.input_frames == 1 {
            job.n_frames
        } else {
            1
        };
        for g in f..f + repeats {
            self.expose(g, &e, None)?;
        }
        self.next = f + 1;
        Ok(())
    }

    /// Exposes frame `g` (the next frame to hand on) of mean image `e`, calibrates it and
    /// hands it to the consumer. `earlier(k)` images frame `k` of the sequence, for the
    /// replay of a piece's persistence (a static scene seen by a moving camera).
    fn expose(
        &mut self,
        g: usize,
        e: &Array2<f64>,
        earlier: Option<&dyn Fn(usize) -> Result<Array2<f64>>>,
    ) -> Result<()> {
        let job = self.job;
        let e = finite_mean(e, g, &job.options.input_name)?;
        let exposure = match &mut self.exposure {
            Some(x) => x,
            None => {
                let first = job.options.first_frame;
                let clock_frames = usize::try_from(first)
                    .ok()
                    .and_then(|f| f.checked_add(job.n_frames))
                    .ok_or_else(|| {
                        Error::param("first_frame", first, "a frame index that fits in memory")
                    })?;
                let mut x = Exposure::new(job.sensor, e, job.options.seed, clock_frames)?;
                if x.has_memory() && first > 0 {
                    self.replay_before(&mut x, e, earlier)?;
                }
                self.exposure.insert(x)
            }
        };
        let t0 = Instant::now();
        let dn = exposure.expose(e, job.options.first_frame + g as u64)?;
        self.detector_s += t0.elapsed().as_secs_f64();
        let rgb = colour::colour_image(job.sensor, exposure.model(), &dn);
        let mut frame = FrameProducts::raw(e, dn, rgb);
        let t0 = Instant::now();
        let calibration = self.calibration.get_or_insert_with(|| {
            FrameCalibration::new(job.sensor, exposure, job.options.calibration.as_ref())
        });
        calibration.apply(&mut frame)?;
        self.calibration_s += t0.elapsed().as_secs_f64();
        if g == 0 {
            self.first = Some(frame.clone());
        }
        self.consumer.frame(g, frame)?;
        self.handed += 1;
        Ok(())
    }

    /// Steps the focal plane's memory over the frames before the run's first
    /// (`options.first_frame` > 0: a piece of a sequence split across processes), so its
    /// state is that of one run over the whole sequence. RTS pixels and drift depend only
    /// on the clock; persistence also on the earlier frames' mean images: `e`, the first
    /// frame's, when every frame sees the same image (a static scene, a still camera);
    /// `earlier(k)` for a static scene seen by a moving camera (each earlier frame imaged
    /// as it moved). A 4-D input's piece holds only its own frames, so persistence there
    /// is an error.
    fn replay_before(
        &self,
        x: &mut Exposure,
        e: &Array2<f64>,
        earlier: Option<&dyn Fn(usize) -> Result<Array2<f64>>>,
    ) -> Result<()> {
        let job = self.job;
        let first = job.options.first_frame;
        let same_image = !job.rendered && job.stage.motion().is_none();
        let persistence = job.sensor.config().detector.persistence.is_some();
        if !persistence || same_image {
            for f in 0..first {
                x.replay(e, f)?;
            }
            return Ok(());
        }
        let Some(earlier) = earlier.filter(|_| !job.rendered) else {
            return Err(Error::param(
                "first_frame",
                first,
                "0 with [detector.persistence] on a 4-D (time-varying) input: the trapped charge depends on every earlier frame's image, which a piece of the input does not hold (run the sequence in one piece, e.g. frames_per_task >= the frame count)",
            ));
        };
        for f in 0..first {
            let k = usize::try_from(f).map_err(|_| {
                Error::param("first_frame", first, "a frame index that fits in memory")
            })?;
            let image = earlier(k)?;
            x.replay(finite_mean(&image, k, &job.options.input_name)?, f)?;
        }
        Ok(())
    }

    /// Frame 0, the exposure stage, the calibration and the seconds, once every frame was
    /// exposed and handed on.
    fn finish(self) -> Result<Kept> {
        let (Some(exposure), Some(first), Some(calibration)) =
            (self.exposure, self.first, self.calibration)
        else {
            return Err(Error::OutOfRange("no frame was exposed".into()));
        };
        if self.handed != self.job.n_frames {
            return Err(Error::OutOfRange(format!(
                "{} of {} frames were exposed",
                self.handed, self.job.n_frames
            )));
        }
        Ok(Kept {
            first,
            exposure,
            calibration,
            detector_s: self.detector_s,
            calibration_s: self.calibration_s,
        })
    }
}
