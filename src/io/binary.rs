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
}

/// Plane buffers handed back through [`super::CubeReader::recycle`], reused by the next
/// reads: a band plane then costs no allocation and, above all, no page faults (a fresh
/// 4 MiB buffer is 1,024 first-touch faults, each zeroing a page).
#[derive(Debug, Default)]
pub(crate) struct PlanePool {
    free: Vec<Vec<f32>>,
}

impl PlanePool {
    /// At most this many idle buffers are kept: two chunks of the engine's
    /// `BANDS_PER_CHUNK` (4) planes, the most it has in flight.
    const MAX_IDLE: usize = 8;

    /// A buffer with room for `n` values (a recycled one if there is one), for
    /// [`read_samples`], which replaces its contents: a recycled buffer keeps its old
    /// values until then, so that a plane read straight into it is not zeroed first (that
    /// memset was 4 % of a 1024² × 128 run).
    pub(crate) fn take(&mut self, n: usize) -> Vec<f32> {
        match self.free.pop() {
            Some(mut v) => {
                v.truncate(n);
                v.reserve(n - v.len());
                v
            }
            // Zeroed by the allocator (fresh pages from the kernel, no memset), so the
            // reads into it need not zero it again; huge pages asked for before the
            // first read touches them.
            None => {
                let v = vec![0.0; n];
                crate::memory::advise_huge_pages(&v);
                v
            }
        }
    }

    /// Keeps the buffers of `planes` (of `n` values each) for later reads.
    pub(crate) fn give(&mut self, planes: Vec<ndarray::Array2<f32>>, n: usize) {
        for p in planes {
            if self.free.len() >= Self::MAX_IDLE {
                break;
            }
            let (v, _) = p.into_raw_vec_and_offset();
            if v.capacity() >= n {
                self.free.push(v);
            }
        }
    }
}

/// Largest buffer a reader fills with one `read` call, bytes (4 MiB): large enough that
/// reads run at disk (or page-cache) speed, small enough that it does not show in the
/// peak memory of a run.
pub(crate) const READ_BLOCK_BYTES: usize = 4 << 20;

/// Converts packed samples to f32, applying `value = gain · stored + offset` when a
/// scaling is given, and appends them to `out`.
pub(crate) fn decode_into(
    bytes: &[u8],
    ty: SampleType,
    big_endian: bool,
    scale: Option<(f64, f64)>,
    out: &mut Vec<f32>,
) {
    let n = bytes.len() / ty.size();
    decode_strided(bytes, ty, big_endian, scale, 0, 1, n, out);
}

/// Appends to `out` the samples `first`, `first + stride`, … (`count` of them, indices in
/// samples) of the packed samples `bytes`, converted as [`decode_into`] converts them.
/// One loop per sample type, so the type is not matched per sample.
#[allow(clippy::too_many_arguments)]
pub(crate) fn decode_strided(
    bytes: &[u8],
    ty: SampleType,
    big_endian: bool,
    scale: Option<(f64, f64)>,
    first: usize,
    stride: usize,
    count: usize,
    out: &mut Vec<f32>,
) {
    macro_rules! run {
        ($t:ty, $n:expr) => {{
            let get = |i: usize| -> f64 {
                let mut a = [0u8; $n];
                a.copy_from_slice(&bytes[i * $n..i * $n + $n]);
                let v = if big_endian {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                };
                v as f64
            };
            if stride == 1 {
                // Contiguous: whole-sample chunks, which the compiler vectorises.
                let conv = |c: &[u8]| -> f64 {
                    let mut a = [0u8; $n];
                    a.copy_from_slice(c);
                    let v = if big_endian {
                        <$t>::from_be_bytes(a)
                    } else {
                        <$t>::from_le_bytes(a)
                    };
                    v as f64
                };
                let run = bytes[first * $n..(first + count) * $n].chunks_exact($n);
                match scale {
                    None => out.extend(run.map(|c| conv(c) as f32)),
                    Some((g, o)) => out.extend(run.map(|c| (g * conv(c) + o) as f32)),
                }
                return;
            }
            let idx = (0..count).map(|k| first + k * stride);
            match scale {
                None => out.extend(idx.map(|i| get(i) as f32)),
                Some((g, o)) => out.extend(idx.map(|i| (g * get(i) + o) as f32)),
            }
        }};
    }
    match ty {
        SampleType::I16 => run!(i16, 2),
        SampleType::U16 => run!(u16, 2),
        SampleType::I32 => run!(i32, 4),
        SampleType::F32 => run!(f32, 4),
        SampleType::F64 => run!(f64, 8),
    }
}

/// Reads `count` contiguous samples starting at byte `offset` and appends them, decoded
/// as [`decode_into`] decodes them, into `out`, replacing what it held: sequential reads
/// of at most [`READ_BLOCK_BYTES`], so a band-sequential plane costs one read (planes up
/// to 4 MiB) or a few, and never a second full-size byte buffer next to the decoded
/// plane; native-order unscaled f32 (the common case) is read straight into `out`'s
/// existing values (a recycled plane, [`PlanePool::take`], is not zeroed first).
#[allow(clippy::too_many_arguments)]
pub(crate) fn read_samples(
    file: &mut File,
    path: &Path,
    offset: u64,
    count: usize,
    ty: SampleType,
    big_endian: bool,
    scale: Option<(f64, f64)>,
    out: &mut Vec<f32>,
) -> Result<()> {
    file.seek(SeekFrom::Start(offset))
        .map_err(|e| Error::io(path, e))?;
    if ty == SampleType::F32 && big_endian == cfg!(target_endian = "big") && scale.is_none() {
        // Native-order f32 without scaling: the stored bytes are the values, so they are
        // read straight into the output (one pass over the data instead of a read into a
        // byte buffer and a decoding pass; `bytemuck` views the f32 slice as bytes).
        out.resize(count, 0.0);
        return file
            .read_exact(bytemuck::cast_slice_mut(&mut out[..]))
            .map_err(|e| Error::io(path, e));
    }
    out.clear();
    let size = ty.size();
    let per_read = (READ_BLOCK_BYTES / size).max(1);
    let mut buf = vec![0u8; count.min(per_read) * size];
    let mut done = 0;
    while done < count {
        let n = (count - done).min(per_read);
        let bytes = &mut buf[..n * size];
        file.read_exact(bytes).map_err(|e| Error::io(path, e))?;
        decode_into(bytes, ty, big_endian, scale, out);
        done += n;
    }
    Ok(())
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
