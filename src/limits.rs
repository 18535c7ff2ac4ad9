//! The resource budget: every size that comes from a file or the command line is
//! multiplied out with overflow checks and compared with a memory limit *before* anything
//! is allocated, so a hostile header (2³¹ × 2³¹ pixels, 2·10⁹ samples, `--frames 2⁶⁴−1`)
//! gives one clear error instead of an allocation abort.
//!
//! The limit is, by default, three quarters of the physical memory (`MemTotal` in
//! `/proc/meminfo`), further capped at half of the process's address-space limit
//! (`RLIMIT_AS`) when one is set; where neither can be read it is 4 GiB. The CLI's
//! `--max-memory` (library: [`set_max_memory_bytes`]) replaces it for the process;
//! [`with_thread_max_memory`] sets a tighter one for the checks made on one thread only
//! (a harness that feeds hostile files to the readers, without changing the limit other
//! threads of the process see).
//!
//! The checks bound the *largest single structures* a step allocates (a band plane, the
//! padded FFT frame and its spectra, the detector frames of a run); they are an honest
//! lower bound of the peak, not an exact accounting of every temporary.

use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{Error, Result};

/// 0 = not set: use [`default_max_memory_bytes`].
static MAX_MEMORY_BYTES: AtomicU64 = AtomicU64::new(0);

thread_local! {
    /// 0 = not set on this thread: use the process limit.
    static THREAD_MAX_MEMORY_BYTES: Cell<u64> = const { Cell::new(0) };
}

/// Fallback limit when physical memory cannot be read, bytes (4 GiB).
pub const FALLBACK_MAX_MEMORY_BYTES: u64 = 4 << 30;

/// Replaces the memory limit for this process (bytes, ≥ 1 MiB).
pub fn set_max_memory_bytes(bytes: u64) -> Result<()> {
    if bytes < (1 << 20) {
        return Err(Error::param(
            "max-memory",
            bytes,
            "at least 1 MiB (e.g. 512M, 8G)",
        ));
    }
    MAX_MEMORY_BYTES.store(bytes, Ordering::Relaxed);
    Ok(())
}

/// Runs `f` with the memory limit `bytes` (≥ 1 MiB) for the checks made on the calling
/// thread; other threads keep the process limit, and the previous limit of this thread is
/// restored afterwards (also when `f` panics).
pub fn with_thread_max_memory<R>(bytes: u64, f: impl FnOnce() -> R) -> Result<R> {
    if bytes < (1 << 20) {
        return Err(Error::param(
            "max-memory",
            bytes,
            "at least 1 MiB (e.g. 512M, 8G)",
        ));
    }
    /// Restores the thread's previous limit when dropped.
    struct Restore(u64);
    impl Drop for Restore {
        fn drop(&mut self) {
            THREAD_MAX_MEMORY_BYTES.with(|c| c.set(self.0));
        }
    }
    let _restore = Restore(THREAD_MAX_MEMORY_BYTES.with(|c| c.replace(bytes)));
    Ok(f())
}

/// The memory limit in force on the calling thread, bytes.
pub fn max_memory_bytes() -> u64 {
    match THREAD_MAX_MEMORY_BYTES.with(Cell::get) {
        0 => match MAX_MEMORY_BYTES.load(Ordering::Relaxed) {
            0 => default_max_memory_bytes(),
            b => b,
        },
        b => b,
    }
}

/// Three quarters of `MemTotal` from `/proc/meminfo`, capped at half of `RLIMIT_AS`;
/// [`FALLBACK_MAX_MEMORY_BYTES`] if the physical memory cannot be read.
pub fn default_max_memory_bytes() -> u64 {
    let physical = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|t| mem_total_bytes(&t));
    let mut limit = physical.map_or(FALLBACK_MAX_MEMORY_BYTES, |p| p / 4 * 3);
    if let Some(a) = address_space_limit_bytes() {
        limit = limit.min(a / 2);
    }
    limit
}

/// `MemTotal` of a `/proc/meminfo` text, bytes (the file states kB = 1024 B).
pub fn mem_total_bytes(meminfo: &str) -> Option<u64> {
    let line = meminfo.lines().find(|l| l.starts_with("MemTotal:"))?;
    let mut it = line["MemTotal:".len()..].split_whitespace();
    let value: u64 = it.next()?.parse().ok()?;
    let scale = match it.next() {
        Some("kB") | Some("KB") => 1024,
        None => 1,
        Some(_) => return None,
    };
    value.checked_mul(scale)
}

#[cfg(unix)]
fn address_space_limit_bytes() -> Option<u64> {
    let mut r = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit writes into the struct we pass and has no other effect.
    let ok = unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut r) } == 0;
    (ok && r.rlim_cur != libc::RLIM_INFINITY).then_some(r.rlim_cur)
}

#[cfg(not(unix))]
fn address_space_limit_bytes() -> Option<u64> {
    None
}

/// Parses a memory size: a number with an optional binary suffix `K`, `M`, `G`, `T`
/// (also `KiB`, `MB`, … — all powers of 1024) or none (bytes). `1.5G` = 1.5 · 2³⁰ B.
pub fn parse_bytes(text: &str) -> Result<u64> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, suffix) = t.split_at(split);
    let scale: f64 = match suffix.trim().to_ascii_uppercase().as_str() {
        "" | "B" => 1.0,
        "K" | "KB" | "KIB" => 1024.0,
        "M" | "MB" | "MIB" => 1024.0 * 1024.0,
        "G" | "GB" | "GIB" => 1024.0 * 1024.0 * 1024.0,
        "T" | "TB" | "TIB" => 1024.0 * 1024.0 * 1024.0 * 1024.0,
        _ => f64::NAN,
    };
    let value: f64 = num.parse().unwrap_or(f64::NAN);
    let bytes = value * scale;
    if !(1.0..1.8e19).contains(&bytes) {
        return Err(Error::param(
            "max-memory",
            crate::limits::escape_token(text),
            "a size such as 512M, 8G or 1073741824 (bytes; K/M/G/T are powers of 1024)",
        ));
    }
    Ok(bytes as u64)
}

/// Multiplies `dims` with overflow checks. `what` names the structure, each dimension
/// is `(name, value)`; the error says which product overflowed.
pub fn checked_count(what: &str, dims: &[(&str, u64)]) -> Result<u64> {
    let mut n: u64 = 1;
    for (_, d) in dims {
        n = n.checked_mul(*d).ok_or_else(|| overflow(what, dims))?;
    }
    Ok(n)
}

fn overflow(what: &str, dims: &[(&str, u64)]) -> Error {
    Error::TooLarge {
        what: what.to_string(),
        needed: format!("{} (overflows 64 bits)", describe(dims)),
        limit: max_memory_bytes(),
    }
}

fn describe(dims: &[(&str, u64)]) -> String {
    dims.iter()
        .map(|(n, v)| format!("{v} {n}"))
        .collect::<Vec<_>>()
        .join(" × ")
}

/// Checks that an allocation of `dims` elements of `bytes_per_element` each fits the
/// memory limit and returns its size in bytes. Call before allocating.
pub fn check_alloc(what: &str, dims: &[(&str, u64)], bytes_per_element: u64) -> Result<u64> {
    let mut all: Vec<(&str, u64)> = dims.to_vec();
    all.push(("bytes", bytes_per_element));
    let bytes = checked_count(what, &all)?;
    check_bytes(what, &describe(&all), bytes)
}

/// Checks a byte count already computed (`detail` says how) against the limit.
pub fn check_bytes(what: &str, detail: &str, bytes: u64) -> Result<u64> {
    let limit = max_memory_bytes();
    if bytes > limit || usize::try_from(bytes).is_err() {
        return Err(Error::TooLarge {
            what: what.to_string(),
            needed: format!("{detail} = {}", human_bytes(bytes)),
            limit,
        });
    }
    Ok(bytes)
}

// The message helpers live in `error` (below it in the module order), re-exported here.
pub use crate::error::{escape_bounded, escape_controls, escape_token, human_bytes};

/// A sensor-file size as a count for the checks above.
pub fn dim(v: usize) -> u64 {
    v as u64
}

/// The memory a run needs at least: the padded FFT frame (f64) with its half-spectrum
/// working set (three complex f64 arrays: spectrum, accumulator, transpose scratch), the
/// widest scene band plane (f32), and per output frame the detector products (u16 DN,
/// f32 mean electrons, f32 radiance and temperature, 3 × u8 preview) plus the f64 mean
/// image. Checked before the run allocates anything of that size.
pub fn check_run(
    padded: (usize, usize),
    scene: (usize, usize),
    sensor: (usize, usize),
    frames: usize,
) -> Result<u64> {
    let what = "the run";
    let (py, px) = (dim(padded.0), dim(padded.1));
    let padded_bytes = checked_count(what, &[("padded rows", py), ("padded cols", px)])?
        .checked_mul(8)
        .ok_or_else(|| overflow(what, &[("padded rows", py), ("padded cols", px)]))?;
    let half = checked_count(
        what,
        &[("padded rows", py), ("spectrum cols", px / 2 + 1), ("", 48)],
    )?;
    let plane = checked_count(
        what,
        &[
            ("scene rows", dim(scene.0)),
            ("scene cols", dim(scene.1)),
            ("", 4),
        ],
    )?;
    let per_frame = checked_count(
        what,
        &[
            ("sensor rows", dim(sensor.0)),
            ("sensor cols", dim(sensor.1)),
            ("", 2 + 4 + 4 + 4 + 3),
        ],
    )?;
    let frame_dims = [
        ("frames", dim(frames)),
        ("sensor rows", dim(sensor.0)),
        ("sensor cols", dim(sensor.1)),
        ("bytes", 17),
    ];
    let frames_bytes = checked_count(what, &frame_dims)?;
    let mean = per_frame / 17 * 8;
    let total = [padded_bytes, half, plane, frames_bytes, mean]
        .iter()
        .try_fold(0u64, |a, b| a.checked_add(*b))
        .ok_or_else(|| overflow(what, &frame_dims))?;
    check_bytes(
        what,
        &format!(
            "padded FFT frame {}×{} + scene band {}×{} + {frames} frame(s) of {}×{} detector products",
            padded.0, padded.1, scene.0, scene.1, sensor.0, sensor.1
        ),
        total,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_thread_limit_binds_only_its_thread_and_is_restored() {
        let process = max_memory_bytes();
        let inner = with_thread_max_memory(2 << 20, || {
            let here = max_memory_bytes();
            let other = std::thread::spawn(max_memory_bytes).join().unwrap();
            let refused = check_bytes("a test", "3 MiB", 3 << 20).is_err();
            (here, other, refused)
        })
        .unwrap();
        assert_eq!(inner, (2 << 20, process, true));
        assert_eq!(max_memory_bytes(), process);
        let _ = std::panic::catch_unwind(|| with_thread_max_memory(2 << 20, || panic!("boom")));
        assert_eq!(max_memory_bytes(), process);
        assert!(with_thread_max_memory(1, || ()).is_err());
    }

    #[test]
    fn meminfo_parses_kibibytes() {
        let t = "MemTotal:       24684084 kB\nMemFree: 1 kB\n";
        assert_eq!(mem_total_bytes(t), Some(24684084 * 1024));
        assert_eq!(mem_total_bytes("MemFree: 1 kB"), None);
    }

    #[test]
    fn sizes_parse_in_binary_units() {
        assert_eq!(parse_bytes("512M").unwrap(), 512 << 20);
        assert_eq!(parse_bytes("1.5G").unwrap(), 3 << 29);
        assert_eq!(parse_bytes("2 GiB").unwrap(), 2 << 30);
        assert_eq!(parse_bytes("4096").unwrap(), 4096);
        for bad in ["", "G", "-1G", "1Q", "nan", "1e30"] {
            assert!(parse_bytes(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn overflowing_products_are_errors_not_wraps() {
        let e = checked_count("x", &[("a", u64::MAX), ("b", 2)]).unwrap_err();
        assert!(e.to_string().contains("overflows"), "{e}");
        assert_eq!(checked_count("x", &[("a", 3), ("b", 5)]).unwrap(), 15);
    }

    #[test]
    fn escaping_bounds_and_neutralises_text() {
        assert_eq!(escape_token("ab\ncd\u{1b}"), "ab\\ncd\\u{1b}");
        let long = "x".repeat(100);
        assert_eq!(escape_token(&long).chars().count(), 41);
    }
}
