//! Independent random streams (docs/design.md §3).
//!
//! Every random effect draws from its own stream, keyed by `(seed, effect, frame, row)`:
//! the key is hashed with the SplitMix64 finaliser (Steele, Lea & Flood, "Fast splittable
//! pseudorandom number generators", OOPSLA 2014) one component at a time, and the result
//! seeds a Xoshiro256++ generator (which expands it with SplitMix64 again). So
//!
//! - switching one effect on or off never changes the numbers another effect sees,
//! - fixed-pattern maps (frame 0 of their effect) are the same in every frame,
//! - temporal noise has its own key per *exposure* and frame: the stream of frame f of
//!   exposure x is `(seed, effect, f, row)` keyed further by x ([`temporal_stream`]), so
//!   frame 0 of a run at one exposure setting and frame 0 at another are independent
//!   draws, not the same noise rescaled. [`DetectorInstance::expose`] takes x from the
//!   integration time (its IEEE-754 bit pattern, so any change of the exposure time gives
//!   a fresh stream); [`DetectorInstance::expose_exposure`] lets a caller that varies the
//!   illumination at a fixed integration time (photon-transfer series, calibration
//!   levels) number its exposures itself. The same seed, exposure and frame always give
//!   the same draw,
//!
//! [`DetectorInstance::expose`]: super::DetectorInstance::expose
//! [`DetectorInstance::expose_exposure`]: super::DetectorInstance::expose_exposure
//! - each row has its own stream, so rows can be processed in parallel in any order and
//!   the result does not depend on the number of threads.

use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;

/// The random effects, each with a fixed stream constant (never renumber: changing one
/// changes every realisation drawn with it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Effect {
    /// Gain (PRNU) unit field z_g.
    Gain = 0x5052_4e55,
    /// Independent part of the offset (DSNU) unit field z_o.
    Offset = 0x4453_4e55,
    /// Per-column offsets.
    Column = 0x434f_4c53,
    /// Per-row offsets.
    Row = 0x524f_5753,
    /// Per-pixel quadratic coefficients.
    Nonlinearity = 0x4e4c_494e,
    /// Dead-pixel draw.
    Dead = 0x4445_4144,
    /// Hot-pixel draw.
    Hot = 0x484f_5420,
    /// Stuck-pixel draw.
    Stuck = 0x5354_434b,
    /// Values of stuck pixels.
    StuckValue = 0x5354_5641,
    /// Temporal shot noise.
    Shot = 0x5348_4f54,
    /// Temporal read noise.
    Read = 0x5245_4144,
    /// Line-of-sight wander (`crate::los`), one stream per image axis (the `row` key).
    LosWander = 0x4c4f_5357,
    /// Which pixels are random-telegraph pixels (`detector::rts`), one stream per row.
    RtsPixel = 0x5254_5350,
    /// The two-state switching process of one RTS pixel (`detector::rts`), keyed by the
    /// pixel's flat index (the `row` key) and drawn from t = 0.
    RtsSwitch = 0x5254_5357,
    /// Random-walk increments of the per-pixel offset drift (`drift`), one stream per
    /// grid step (the `frame` key) and row.
    DriftOffsetWalk = 0x444f_574b,
    /// Random-walk increments of the per-pixel gain drift (`drift`).
    DriftGainWalk = 0x4447_574b,
    /// Per-pixel offset temperature coefficients (`drift`).
    DriftOffsetTempco = 0x444f_5443,
    /// Per-pixel gain temperature coefficients (`drift`).
    DriftGainTempco = 0x4447_5443,
    /// Uncorrelated pink readout noise, one stream per output (the `row` key)
    /// (`super::readout`).
    ReadoutPink = 0x5049_4e4b,
    /// Correlated pink readout noise common to all outputs (`super::readout`).
    ReadoutCorrelatedPink = 0x4350_4e4b,
    /// Alternating-column pink noise, one stream per output and column parity (the `row`
    /// key is 2·output + parity) (`super::readout`).
    ReadoutAlternatingColumn = 0x4143_4e20,
    /// Temporal per-row offsets of the readout (`super::readout`).
    ReadoutRow = 0x524f_574e,
}

/// SplitMix64 finaliser: a bijective 64-bit mix with full avalanche.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// The generator for `(seed, effect, frame, row)` (fixed-pattern maps use frame 0).
pub(crate) fn stream(seed: u64, effect: Effect, frame: u64, row: u64) -> Xoshiro256PlusPlus {
    Xoshiro256PlusPlus::seed_from_u64(key(seed, effect, frame, row))
}

/// The hashed key of `(seed, effect, frame, row)`.
fn key(seed: u64, effect: Effect, frame: u64, row: u64) -> u64 {
    let mut h = mix(seed);
    h = mix(h ^ effect as u64);
    h = mix(h ^ frame);
    mix(h ^ row)
}

/// The temporal-noise generator for `(seed, effect, exposure, frame, row)`: the key of
/// [`stream`] mixed once more with the exposure key, so different exposures never share
/// a draw (the mix is a bijection, so distinct exposure keys give distinct seeds for the
/// same remaining components).
pub(crate) fn temporal_stream(
    seed: u64,
    effect: Effect,
    exposure: u64,
    frame: u64,
    row: u64,
) -> Xoshiro256PlusPlus {
    let h = mix(key(seed, effect, frame, row) ^ mix(exposure ^ 0x4558_504f_5355_5245));
    Xoshiro256PlusPlus::seed_from_u64(h)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;

    #[test]
    fn streams_differ_by_every_key_component() {
        let a: u64 = stream(1, Effect::Gain, 0, 0).random();
        assert_eq!(a, stream(1, Effect::Gain, 0, 0).random::<u64>());
        assert_ne!(a, stream(2, Effect::Gain, 0, 0).random::<u64>());
        assert_ne!(a, stream(1, Effect::Offset, 0, 0).random::<u64>());
        assert_ne!(a, stream(1, Effect::Gain, 1, 0).random::<u64>());
        assert_ne!(a, stream(1, Effect::Gain, 0, 1).random::<u64>());
    }

    #[test]
    fn temporal_streams_differ_by_exposure_and_repeat() {
        let a: u64 = temporal_stream(1, Effect::Shot, 7, 0, 0).random();
        assert_eq!(a, temporal_stream(1, Effect::Shot, 7, 0, 0).random::<u64>());
        assert_ne!(a, temporal_stream(1, Effect::Shot, 8, 0, 0).random::<u64>());
        assert_ne!(a, temporal_stream(1, Effect::Shot, 7, 1, 0).random::<u64>());
        assert_ne!(a, temporal_stream(1, Effect::Read, 7, 0, 0).random::<u64>());
        assert_ne!(a, stream(1, Effect::Shot, 0, 0).random::<u64>());
    }
}
