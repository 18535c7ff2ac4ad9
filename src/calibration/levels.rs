//! Blackbody reference temperatures from the sensor's own range (issue 12).
//!
//! A laboratory picks its calibration blackbodies inside the range the camera records
//! unclipped: a fixed 280/300/320 K saturates a sensitive band (Emerald band 2, MultimIR
//! filter 3 with the 15 mm optics) and wastes the range of an insensitive one. Here the
//! levels are placed at fixed fractions of the **usable DN range of the ideal pixel**,
//!
//! `DN_f = DN_lo + f · (DN_hi − DN_lo)`,  f = 0.1 … 0.9 evenly spaced,
//!
//! with `DN_lo = max(DN*(0 signal), DN*(T_min))` (offset, dark and background electrons, or
//! the coldest temperature of the table) and `DN_hi = min(DN*(full well), max DN,
//! DN*(T_max))` (the full well or the ADC, whichever clips first, or the hottest
//! temperature of the table). `DN*(T) = model.expected_dn(μ_e(T))` runs through the
//! sensor's spectral response, camera equation (docs/design.md §4.1) and integration time;
//! DN* increases strictly with T below saturation, so each level is the unique root of
//! `DN*(T) = DN_f`, found by bisection to 1 µK.

use crate::error::{Error, Result};

use super::Chain;

/// Temperatures (K) within which automatic levels are searched (the coldest and hottest
/// blackbodies a laboratory would set).
pub const SEARCH_RANGE_K: (f64, f64) = (150.0, 1000.0);

/// Fractions of the usable range of the lowest and highest automatic levels.
pub const FULL_SCALE_FRACTIONS: (f64, f64) = (0.1, 0.9);

/// Bisection tolerance of a level, K.
const LEVEL_TOLERANCE_K: f64 = 1e-6;

/// Usable range narrower than this (DN) cannot be calibrated: the levels would be
/// quantisation steps apart.
const MIN_USABLE_RANGE_DN: f64 = 4.0;

/// `count` (≥ 2) reference temperatures at the fractions 10 % … 90 % of the usable DN range
/// of `chain`'s ideal pixel, searched inside `range_k` (module documentation), coldest
/// first.
///
/// Errors: fewer than 2 levels asked for, or a usable range narrower than 4 DN (the sensor
/// saturates, or does not respond, everywhere in `range_k`), naming both ends.
pub(super) fn automatic(chain: &Chain, range_k: (f64, f64), count: usize) -> Result<Vec<f64>> {
    if count < 2 {
        return Err(Error::param(
            "calibration levels",
            count,
            "at least 2 blackbody levels",
        ));
    }
    let m = &chain.model;
    let (t_min, t_max) = range_k;
    let floor = m.expected_dn(0.0).max(chain.ideal_dn(t_min));
    let full_scale = m
        .expected_dn(m.full_well_e())
        .min(m.max_dn())
        .min(chain.ideal_dn(t_max));
    if !(floor.is_finite() && full_scale.is_finite() && full_scale - floor >= MIN_USABLE_RANGE_DN) {
        return Err(Error::OutOfRange(format!(
            "no usable range for blackbody calibration levels between {t_min} K and {t_max} K: the ideal pixel reads {floor:.1} DN at the bottom and clips at {full_scale:.1} DN (at least {MIN_USABLE_RANGE_DN} DN apart needed); check the integration time, gain and full well, or give [calibration] temperatures_k"
        )));
    }
    let (f0, f1) = FULL_SCALE_FRACTIONS;
    (0..count)
        .map(|i| {
            let f = f0 + (f1 - f0) * i as f64 / (count - 1) as f64;
            solve(chain, floor + f * (full_scale - floor), range_k)
        })
        .collect()
}

/// The temperature in `range_k` at which the ideal pixel reads `target_dn` (bisection on
/// the increasing DN*(T); the result is clamped into the range).
fn solve(chain: &Chain, target_dn: f64, range_k: (f64, f64)) -> Result<f64> {
    let (mut a, mut b) = range_k;
    while b - a > LEVEL_TOLERANCE_K {
        let mid = 0.5 * (a + b);
        let d = chain.ideal_dn(mid);
        if d.is_nan() {
            return Err(Error::OutOfRange(format!(
                "calibration level: the ideal DN at {mid} K is not finite"
            )));
        }
        if d < target_dn {
            a = mid;
        } else {
            b = mid;
        }
    }
    Ok(0.5 * (a + b))
}
