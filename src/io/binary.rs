//! Raw binary samples shared by the ENVI and NPY readers: sample types, decoding with
//! an optional linear scaling, positioned reads and the data-file size check.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use crate::error::{Error, Result};

/// How the samples of one pixel value are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum SampleType {
    /// Signed 16-bit integer.
    I16,
    /// Unsigned 16-bit integer.
    U16,
    /// Signed 32-bit integer.
    I32,
    /// IEEE single precision.
    F32,
    /// IEEE double precision.
    F64,
}

impl SampleType {
    /// Bytes per sample.
    pub(crate) fn size(self) -> usize {
        match self {
            SampleType::I16 | SampleType::U16 => 2,
            SampleType::I32 | SampleType::F32 => 4,
            SampleType::F64 => 8,
        }
    }

    /// Decodes one sample from the first `size()` bytes of `b`.
    #[inline]
    pub(crate) fn decode(self, b: &[u8], big_endian: bool) -> f64 {
        macro_rules! get {
            ($t:ty, $n:expr) => {{
                let mut a = [0u8; $n];
                a.copy_from_slice(&b[..$n]);
                if big_endian {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }
            }};
        }
        match self {
            SampleType::I16 => f64::from(get!(i16, 2)),
            SampleType::U16 => f64::from(get!(u16, 2)),
            SampleType::I32 => f64::from(get!(i32, 4)),
            SampleType::F32 => f64::from(get!(f32, 4)),
            SampleType::F64 => get!(f64, 8),
        }
    }
}

/// Converts packed samples to f32, applying `value = gain · stored + offset` when a
/// scaling is given, and appends them to `out`.
pub(crate) fn decode_into(
    bytes: &[u8],
    ty: SampleType,
    big_endian: bool,
    scale: Option<(f64, f64)>,
    out: &mut Vec<f32>,
) {
    let n = ty.size();
    match scale {
        None => out.extend(
            bytes
                .chunks_exact(n)
                .map(|c| ty.decode(c, big_endian) as f32),
        ),
        Some((gain, offset)) => out.extend(
            bytes
                .chunks_exact(n)
                .map(|c| (gain * ty.decode(c, big_endian) + offset) as f32),
        ),
    }
}

/// Reads exactly `buf.len()` bytes at `offset`, naming `path` on failure.
pub(crate) fn read_at(file: &mut File, path: &Path, offset: u64, buf: &mut [u8]) -> Result<()> {
    file.seek(SeekFrom::Start(offset))
        .map_err(|e| Error::io(path, e))?;
    file.read_exact(buf).map_err(|e| Error::io(path, e))
}

/// Checks that a data file holds exactly `expected` bytes.
pub(crate) fn check_size(path: &Path, actual: u64, expected: u64, layout: &str) -> Result<()> {
    if actual < expected {
        Err(Error::format(
            path,
            format!(
                "data file is truncated: the header says {expected} bytes ({layout}) but the file has {actual} bytes"
            ),
        ))
    } else if actual > expected {
        Err(Error::format(
            path,
            format!(
                "the header says {expected} bytes ({layout}) but the file has {actual} bytes; check samples, lines, bands, data type and header offset"
            ),
        ))
    } else {
        Ok(())
    }
}
