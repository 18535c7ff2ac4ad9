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
    // Native-order f32 without scaling (the common case), 4-byte aligned: the stored
    // values themselves, picked without decoding (the same values; only a signalling
    // NaN keeps its payload, which the decode's round trip through f64 would quieten).
    if ty == SampleType::F32 && big_endian == cfg!(target_endian = "big") && scale.is_none() {
        let within = |len: usize| count == 0 || first + (count - 1) * stride < len;
        if let Some(values) = bytemuck::try_cast_slice::<u8, f32>(bytes)
            .ok()
            .filter(|v| within(v.len()))
        {
            // One sample from each pixel's `stride` samples, from sample `first` on.
            let start = out.len();
            out.resize(start + count, 0.0);
            let pixels = values[first..].chunks(stride.max(1));
            for (o, pixel) in out[start..].iter_mut().zip(pixels) {
                *o = pixel[0];
            }
            return;
        }
    }
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

/// Bytes of band-interleaved pixels [`decode_interleaved`] takes from at a time (32 KiB):
/// a tile that stays in L1 while every requested band is picked out of it (measured on a
/// 1024² × 128 BIP run: `read` 0.83 of its time with 128 KiB tiles, which stay in L2
/// only; 16 KiB tiles: 0.85).
const INTERLEAVED_TILE_BYTES: usize = 32 << 10;

/// Bands `bands` (with their scalings `scales`) of `pixels` band-interleaved pixels of
/// `stride` samples each (`bytes`, as in a BIP row), appended to `out[k]` for band
/// `bands[k]`: exactly what [`decode_strided`] appends for each band, taken from a tile
/// of pixels at a time ([`INTERLEAVED_TILE_BYTES`]), so the bands' strided reads hit the
/// cache instead of sweeping the whole buffer once per band.
#[allow(clippy::too_many_arguments)]
pub(crate) fn decode_interleaved(
    bytes: &[u8],
    ty: SampleType,
    big_endian: bool,
    scales: &[Option<(f64, f64)>],
    bands: &[usize],
    stride: usize,
    pixels: usize,
    out: &mut [Vec<f32>],
) {
    let pixel_bytes = (stride * ty.size()).max(1);
    let tile = (INTERLEAVED_TILE_BYTES / pixel_bytes).max(1);
    let mut p0 = 0;
    while p0 < pixels {
        let n = tile.min(pixels - p0);
        let part = &bytes[p0 * pixel_bytes..(p0 + n) * pixel_bytes];
        for ((&band, &scale), out) in bands.iter().zip(scales).zip(out.iter_mut()) {
            decode_strided(part, ty, big_endian, scale, band, stride, n, out);
        }
        p0 += n;
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Sample `i` of `bytes` decoded by its definition: the stored value in the given byte
    /// order, scaled in f64, rounded to f32.
    fn definition(
        bytes: &[u8],
        ty: SampleType,
        be: bool,
        scale: Option<(f64, f64)>,
        i: usize,
    ) -> f32 {
        let n = ty.size();
        let b = &bytes[i * n..(i + 1) * n];
        let v = match (ty, be) {
            (SampleType::I16, false) => i16::from_le_bytes([b[0], b[1]]) as f64,
            (SampleType::I16, true) => i16::from_be_bytes([b[0], b[1]]) as f64,
            (SampleType::F32, false) => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            (SampleType::F32, true) => f32::from_be_bytes([b[0], b[1], b[2], b[3]]) as f64,
            (SampleType::F64, false) => f64::from_le_bytes(b.try_into().unwrap()),
            (SampleType::F64, true) => f64::from_be_bytes(b.try_into().unwrap()),
            _ => unreachable!("not used here"),
        };
        match scale {
            Some((g, o)) => (g * v + o) as f32,
            None => v as f32,
        }
    }

    /// Every band picked out of band-interleaved pixels, a tile at a time, is each
    /// sample's decoded value in pixel order: native f32 read in place (aligned) and
    /// through the decode (misaligned, big-endian, scaled), i16 and f64; one, three and
    /// 128 samples per pixel, over several tiles with a partial last one.
    #[test]
    fn interleaved_bands_are_the_samples_decoded_in_pixel_order() {
        for (ty, be, scale) in [
            (SampleType::F32, false, None),
            (SampleType::F32, true, None),
            (SampleType::F32, false, Some((0.5, 2.0))),
            (SampleType::I16, false, Some((0.01, -1.0))),
            (SampleType::F64, true, None),
        ] {
            for stride in [1usize, 3, 128] {
                let n = ty.size();
                let tile = (INTERLEAVED_TILE_BYTES / (stride * n)).max(1);
                let pixels = 2 * tile + tile / 3 + 1;
                // Words, so that `&all[0..]` is 4-byte aligned and `&all[1..]` is not.
                let mut words: Vec<u32> = (0..(pixels * stride * n / 4 + 2) as u32)
                    .map(|k| 0x3f80_0000 ^ k.wrapping_mul(2_654_435_761) >> 9)
                    .collect();
                words[0] = 0x4049_0fdb;
                let all: &[u8] = bytemuck::cast_slice(&words);
                for offset in [0usize, 1] {
                    let bytes = &all[offset..offset + pixels * stride * n];
                    let bands: Vec<usize> = [0, stride / 2, stride - 1].to_vec();
                    let scales = vec![scale; bands.len()];
                    let mut out = vec![Vec::new(); bands.len()];
                    decode_interleaved(bytes, ty, be, &scales, &bands, stride, pixels, &mut out);
                    for (band, got) in bands.iter().zip(&out) {
                        assert_eq!(got.len(), pixels);
                        for (p, g) in got.iter().enumerate() {
                            let want = definition(bytes, ty, be, scale, p * stride + band);
                            assert!(
                                g.to_bits() == want.to_bits() || (g.is_nan() && want.is_nan()),
                                "{ty:?} be {be} scale {scale:?} stride {stride} offset {offset} band {band} pixel {p}: {g} vs {want}"
                            );
                        }
                    }
                }
            }
        }
    }
}
