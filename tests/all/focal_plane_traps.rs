//! Telegraph pixels and persistence through the public API, driven by the sequence clock
//! (`eoir::los::Clock`, rolling shutter): a sequence split into pieces reproduces the
//! states of one run bit for bit (the RTS pieces replay the switching from t = 0, the
//! persistence pieces replay the mean frames), and the RTS finder recovers the planted
//! pixels of a rolling-shutter dark sequence.

use eoir::characterize::rts::{find_rts_pixels, RtsSearch};
use eoir::detector::persistence::{Persistence, PersistenceConfig};
use eoir::detector::rts::{RtsConfig, RtsFrame, RtsPixels};
use eoir::los::{Clock, ClockConfig};
use ndarray::{Array2, Array3, Axis};
use rand::{RngExt, SeedableRng};
use rand_distr::StandardNormal;
use rand_xoshiro::Xoshiro256PlusPlus;

const ROWS: usize = 64;
const COLS: usize = 48;

fn clock(frames: usize) -> Clock {
    let cfg: ClockConfig =
        toml::from_str("frame_rate_hz = 50.0\nshutter = \"rolling\"\nline_time_s = 1e-4").unwrap();
    Clock::new(&cfg, 0.01, ROWS, frames).unwrap()
}

fn rts_cfg() -> RtsConfig {
    RtsConfig {
        fraction: 0.05,
        tau_high_s: 0.04,
        tau_low_s: 0.1,
        dark_step_e_per_s: 3000.0,
        offset_step_e: 30.0,
    }
}

/// Frames `range` of the clock, each row read at the end of its window.
fn rts_frames(rts: &mut RtsPixels, clock: &Clock, range: std::ops::Range<usize>) -> Vec<RtsFrame> {
    range
        .map(|k| {
            rts.frame(&|r| clock.row_window_s(k, r), &|r| {
                clock.row_window_s(k, r).1
            })
        })
        .collect()
}

#[test]
fn rts_pieces_of_a_rolling_shutter_sequence_replay_one_run() {
    let clock = clock(30);
    let cfg = rts_cfg();
    cfg.validate().unwrap();
    let mut whole = RtsPixels::new(&cfg, ROWS, COLS, 11);
    let all = rts_frames(&mut whole, &clock, 0..30);
    for first in [1, 7, 20] {
        let mut piece = RtsPixels::new(&cfg, ROWS, COLS, 11);
        piece.advance_to(clock.frame_start_s(first));
        assert_eq!(rts_frames(&mut piece, &clock, first..30), all[first..]);
    }
    // Within a frame the rows see the process at their own times; over the sequence the
    // high fraction averages to p = τ_high/(τ_high+τ_low) within 4σ,
    // σ = sqrt(2p(1−p)τ_c/(T·N)) for N pixels over T seconds.
    let n = all[0].high_fraction.len();
    assert!(n > 100);
    let mean: f64 = all.iter().flat_map(|f| &f.high_fraction).sum::<f64>() / (30 * n) as f64;
    let p = cfg.high_probability();
    let sigma = (2.0 * p * (1.0 - p) * cfg.correlation_time_s() / (0.6 * n as f64)).sqrt();
    assert!((mean - p).abs() < 4.0 * sigma, "{mean} vs {p} (σ {sigma})");
}

#[test]
fn persistence_pieces_replaying_the_mean_frames_match_one_run() {
    let cfg = PersistenceConfig::default();
    cfg.validate().unwrap();
    let scene = |k: usize| {
        Array2::from_shape_fn((ROWS, COLS), |(r, c)| {
            let spot = if r / 8 == k % 8 && c / 8 == 2 {
                2e5
            } else {
                0.0
            };
            50.0 + spot + (r + c) as f64
        })
    };
    let dt = 0.02;
    let mut whole = Persistence::new(&cfg, ROWS, COLS);
    let outputs: Vec<Array2<f64>> = (0..20)
        .map(|k| {
            let mut f = scene(k);
            whole.step(&mut f, 1e5, dt);
            f
        })
        .collect();
    // A piece from frame 12 replays the mean frames 0..12 first.
    let mut piece = Persistence::new(&cfg, ROWS, COLS);
    for k in 0..12 {
        piece.step(&mut scene(k), 1e5, dt);
    }
    for (k, expected) in outputs.iter().enumerate().skip(12) {
        let mut f = scene(k);
        piece.step(&mut f, 1e5, dt);
        assert_eq!(&f, expected);
    }
    assert_eq!(piece.trapped_e(), whole.trapped_e());
    // The spot left a ghost: the frame after it moved away is brighter than the scene.
    assert!(outputs[9][[0, 16]] > scene(9)[[0, 16]]);
}

#[test]
fn the_finder_recovers_the_rts_pixels_of_a_rolling_shutter_dark_sequence() {
    let frames = 150;
    let clock = clock(frames);
    let mut rts = RtsPixels::new(&rts_cfg(), ROWS, COLS, 4);
    let planted = rts.pixels().to_vec();
    // Gaussian read noise σ = 5 e⁻, far below the 30 e⁻ + 3000 e⁻/s × 10 ms = 60 e⁻ step.
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(8);
    let mut stack = Array3::zeros((frames, ROWS, COLS));
    for (k, frame) in rts_frames(&mut rts, &clock, 0..frames).iter().enumerate() {
        let mut plane = stack.index_axis_mut(Axis(0), k);
        for v in plane.iter_mut() {
            *v = 200.0 + 5.0 * rng.sample::<f64, _>(StandardNormal);
        }
        for (&p, e) in planted.iter().zip(&frame.extra_e) {
            plane[[p / COLS, p % COLS]] += e;
        }
    }
    let found = find_rts_pixels(stack.view(), &RtsSearch::default()).unwrap();
    let hits = found
        .iter()
        .filter(|d| planted.binary_search(&d.pixel).is_ok())
        .count();
    assert!(
        hits as f64 >= 0.95 * planted.len() as f64,
        "{hits}/{}",
        planted.len()
    );
    assert!(((found.len() - hits) as f64) < 0.01 * (ROWS * COLS - planted.len()) as f64);
}
