//! Single-plane product writers (and the readers tests and tools need): 16-bit grey and
//! 8-bit RGB PNG, 16-bit and f32 grey TIFF, one-channel f32 OpenEXR, and animated 8-bit
//! grey PNG (APNG) previews.
//!
//! Arrays are `[row, col]` (`[row, col, channel]` for RGB); row 0 is the top of the
//! image. Every writer goes through [`atomic_write`]: on any error
//! the target is left untouched and no temporary file remains.

use std::io::BufReader;
use std::path::Path;

use ndarray::{Array2, ArrayView2, ArrayView3};

use crate::error::{Error, Result};

use super::atomic_write;

/// Checks an image size and converts it to the `(width, height)` the encoders take.
fn dims(path: &Path, rows: usize, cols: usize) -> Result<(u32, u32)> {
    if rows == 0 || cols == 0 {
        return Err(Error::format(
            path,
            format!("cannot write an empty image ({rows} rows × {cols} columns)"),
        ));
    }
    match (u32::try_from(cols), u32::try_from(rows)) {
        (Ok(w), Ok(h)) => Ok((w, h)),
        _ => Err(Error::format(
            path,
            format!("image of {rows} × {cols} pixels is too large for the format"),
        )),
    }
}

fn png_err(path: &Path, e: png::EncodingError) -> Error {
    match e {
        png::EncodingError::IoError(io) => Error::io(path, io),
        other => Error::format(path, format!("PNG encoding failed: {other}")),
    }
}

fn png_dec_err(path: &Path, e: png::DecodingError) -> Error {
    match e {
        png::DecodingError::IoError(io) => Error::io(path, io),
        other => Error::format(path, format!("cannot decode PNG: {other}")),
    }
}

fn tiff_err(path: &Path, e: tiff::TiffError) -> Error {
    match e {
        tiff::TiffError::IoError(io) => Error::io(path, io),
        other => Error::format(path, format!("TIFF: {other}")),
    }
}

/// Writes a PNG with the given colour type and depth from packed sample bytes.
fn write_png(
    path: &Path,
    (w, h): (u32, u32),
    color: png::ColorType,
    depth: png::BitDepth,
    bytes: &[u8],
) -> Result<()> {
    atomic_write(path, |out| {
        let mut enc = png::Encoder::new(&mut *out, w, h);
        enc.set_color(color);
        enc.set_depth(depth);
        let mut writer = enc.write_header().map_err(|e| png_err(path, e))?;
        writer
            .write_image_data(bytes)
            .map_err(|e| png_err(path, e))?;
        writer.finish().map_err(|e| png_err(path, e))
    })
}

/// Writes a 16-bit greyscale PNG (`[row, col]`).
pub fn write_png_u16(path: &Path, image: ArrayView2<u16>) -> Result<()> {
    let (rows, cols) = image.dim();
    let size = dims(path, rows, cols)?;
    // PNG stores 16-bit samples big-endian.
    let bytes: Vec<u8> = image.iter().flat_map(|v| v.to_be_bytes()).collect();
    write_png(
        path,
        size,
        png::ColorType::Grayscale,
        png::BitDepth::Sixteen,
        &bytes,
    )
}

/// Writes an 8-bit RGB PNG from `[row, col, 3]`.
pub fn write_png_rgb8(path: &Path, rgb: ArrayView3<u8>) -> Result<()> {
    let (rows, cols, ch) = rgb.dim();
    if ch != 3 {
        return Err(Error::param(
            "rgb image shape",
            format!("[{rows}, {cols}, {ch}]"),
            "[rows, cols, 3]",
        ));
    }
    let size = dims(path, rows, cols)?;
    let bytes: Vec<u8> = rgb.iter().copied().collect();
    write_png(
        path,
        size,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        &bytes,
    )
}

/// Writes a 16-bit greyscale TIFF (uncompressed).
pub fn write_tiff_u16(path: &Path, image: ArrayView2<u16>) -> Result<()> {
    let (rows, cols) = image.dim();
    let (w, h) = dims(path, rows, cols)?;
    let data: Vec<u16> = image.iter().copied().collect();
    atomic_write(path, |out| {
        let mut enc = tiff::encoder::TiffEncoder::new(&mut *out).map_err(|e| tiff_err(path, e))?;
        enc.write_image::<tiff::encoder::colortype::Gray16>(w, h, &data)
            .map_err(|e| tiff_err(path, e))
    })
}

/// Writes a 32-bit float greyscale TIFF (uncompressed, IEEE sample format).
pub fn write_tiff_f32(path: &Path, image: ArrayView2<f32>) -> Result<()> {
    let (rows, cols) = image.dim();
    let (w, h) = dims(path, rows, cols)?;
    let data: Vec<f32> = image.iter().copied().collect();
    atomic_write(path, |out| {
        let mut enc = tiff::encoder::TiffEncoder::new(&mut *out).map_err(|e| tiff_err(path, e))?;
        enc.write_image::<tiff::encoder::colortype::Gray32Float>(w, h, &data)
            .map_err(|e| tiff_err(path, e))
    })
}

/// `encoding` with its blocks stored in increasing order: the exr crate compresses blocks
/// in parallel, and in its default (unspecified) order writes each as it finishes, so two
/// runs of the same data would give files that differ in block order and offset table.
/// Increasing order makes the bytes a function of the data alone (reproducible runs give
/// identical files).
pub(crate) fn deterministic(encoding: exr::prelude::Encoding) -> exr::prelude::Encoding {
    exr::prelude::Encoding {
        line_order: exr::prelude::LineOrder::Increasing,
        ..encoding
    }
}

/// EXR magic number (OpenEXR file layout: the first four bytes of every file).
const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

/// Version-field flag of a multi-part file (OpenEXR file layout, bit 12).
const EXR_MULTIPART: u32 = 0x1000;

/// Largest header this reorders (bytes); a longer one is left as written.
const MAX_SORTED_HEADER: u64 = 64 << 20;

/// Puts the header attributes of the single-part OpenEXR file just written through `w` in
/// name order, in place. The exr crate keeps custom attributes in a `HashMap`, whose
/// iteration order differs from one map to the next, so the same image written twice had
/// its attributes in different orders. Readers look attributes up by name (OpenEXR file
/// layout: `name\0 type\0 size:i32 value`, the list ended by a 0 byte), and the list's
/// length does not change, so the offset table after it stays valid. Multi-part files and
/// anything unexpected are left as written.
pub(crate) fn sort_exr_header(
    w: &mut std::io::BufWriter<std::fs::File>,
    path: &Path,
) -> Result<()> {
    use std::io::{Read, Seek, SeekFrom, Write};
    w.flush().map_err(|e| Error::io(path, e))?;
    let file = w.get_mut();
    let len = file
        .seek(SeekFrom::End(0))
        .map_err(|e| Error::io(path, e))?;
    // The header is a few KiB (a channel name per band); read more only if it is longer.
    let mut sorted = None;
    for limit in [64 << 10, MAX_SORTED_HEADER] {
        let mut head = vec![0u8; len.min(limit) as usize];
        file.seek(SeekFrom::Start(0))
            .map_err(|e| Error::io(path, e))?;
        file.read_exact(&mut head).map_err(|e| Error::io(path, e))?;
        sorted = sorted_header(&head);
        if sorted.is_some() || len <= limit {
            break;
        }
    }
    let Some(sorted) = sorted else {
        return Ok(());
    };
    file.seek(SeekFrom::Start(8))
        .map_err(|e| Error::io(path, e))?;
    file.write_all(&sorted).map_err(|e| Error::io(path, e))?;
    file.seek(SeekFrom::End(0))
        .map_err(|e| Error::io(path, e))?;
    Ok(())
}

/// The attribute list of a single-part EXR file (`bytes` from its start) with the
/// attributes in name order, terminator included; `None` if it is not one or is cut short.
fn sorted_header(bytes: &[u8]) -> Option<Vec<u8>> {
    if bytes.get(..4)? != EXR_MAGIC {
        return None;
    }
    let version = u32::from_le_bytes(bytes.get(4..8)?.try_into().ok()?);
    if version & EXR_MULTIPART != 0 {
        return None;
    }
    let cstr_end = |from: usize| {
        bytes
            .get(from..)?
            .iter()
            .position(|b| *b == 0)
            .map(|n| from + n)
    };
    let mut attrs: Vec<(&[u8], &[u8])> = Vec::new();
    let mut pos = 8;
    while *bytes.get(pos)? != 0 {
        let name_end = cstr_end(pos)?;
        let type_end = cstr_end(name_end + 1)?;
        let size_at = type_end + 1;
        let size = i32::from_le_bytes(bytes.get(size_at..size_at + 4)?.try_into().ok()?);
        let end = size_at + 4 + usize::try_from(size).ok()?;
        bytes.get(pos..end)?;
        attrs.push((&bytes[pos..name_end], &bytes[pos..end]));
        pos = end;
    }
    attrs.sort_by(|a, b| a.0.cmp(b.0));
    let mut out: Vec<u8> = attrs.iter().flat_map(|a| a.1.iter().copied()).collect();
    out.push(0);
    Some(out)
}

/// Writes a single-channel f32 OpenEXR image (lossless compression) whose channel is
/// called `channel` (e.g. `"Y"`, `"radiance"`, `"T"`).
pub fn write_exr_f32(path: &Path, image: ArrayView2<f32>, channel: &str) -> Result<()> {
    use exr::prelude::{
        AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, SmallVec,
        WritableImage,
    };
    let (rows, cols) = image.dim();
    dims(path, rows, cols)?;
    if channel.is_empty() || channel.starts_with('.') || channel.ends_with('.') {
        return Err(Error::param(
            "EXR channel name",
            format!("`{channel}`"),
            "a non-empty name not starting or ending with `.`",
        ));
    }
    let data: Vec<f32> = image.iter().copied().collect();
    let ch = AnyChannel::new(channel, FlatSamples::F32(data));
    let layer = Layer::new(
        (cols, rows),
        LayerAttributes::default(),
        deterministic(Encoding::FAST_LOSSLESS),
        AnyChannels::sort(SmallVec::from_vec(vec![ch])),
    );
    let img = Image::from_layer(layer);
    atomic_write(path, |out| {
        img.write().to_buffered(&mut *out).map_err(|e| match e {
            exr::error::Error::Io(io) => Error::io(path, io),
            other => Error::format(path, format!("OpenEXR encoding failed: {other}")),
        })?;
        sort_exr_header(out, path)
    })
}

/// The TIFF decoder's own limits: the decoding buffer bounded by the memory budget
/// ([`crate::limits`]), the IFD-value and intermediate-buffer limits at the crate defaults.
fn tiff_limits() -> tiff::decoder::Limits {
    let mut l = tiff::decoder::Limits::default();
    l.decoding_buffer_size =
        usize::try_from(crate::limits::max_memory_bytes()).unwrap_or(usize::MAX);
    l
}

/// Opens a TIFF and decodes its first image, checking it is single-channel.
fn read_tiff(path: &Path, want: &str) -> Result<(usize, usize, tiff::decoder::DecodingResult)> {
    let file = crate::io::input::open_regular(path)?;
    let mut dec = tiff::decoder::Decoder::new(BufReader::new(file))
        .map_err(|e| tiff_err(path, e))?
        .with_limits(tiff_limits());
    let (w, h) = dec.dimensions().map_err(|e| tiff_err(path, e))?;
    let ct = dec.colortype().map_err(|e| tiff_err(path, e))?;
    crate::limits::check_alloc(
        &format!("decoding {}", path.display()),
        &[("rows", h as u64), ("columns", w as u64)],
        u64::from(ct.bit_depth().div_ceil(8).max(1)),
    )?;
    if !matches!(ct, tiff::ColorType::Gray(_)) {
        return Err(Error::format(
            path,
            format!("expected a single-channel {want} TIFF, found colour type {ct:?}"),
        ));
    }
    let data = dec.read_image().map_err(|e| tiff_err(path, e))?;
    Ok((h as usize, w as usize, data))
}

fn to_array<T>(path: &Path, rows: usize, cols: usize, v: Vec<T>) -> Result<Array2<T>> {
    Array2::from_shape_vec((rows, cols), v).map_err(|e| {
        Error::format(
            path,
            format!("image data does not fill {rows} × {cols}: {e}"),
        )
    })
}

/// Reads a 16-bit greyscale TIFF.
pub fn read_tiff_u16(path: &Path) -> Result<Array2<u16>> {
    match read_tiff(path, "16-bit unsigned")? {
        (r, c, tiff::decoder::DecodingResult::U16(v)) => to_array(path, r, c, v),
        (_, _, other) => Err(Error::format(
            path,
            format!(
                "expected 16-bit unsigned samples, found {}",
                tiff_kind(&other)
            ),
        )),
    }
}

/// Reads a 32-bit float greyscale TIFF.
pub fn read_tiff_f32(path: &Path) -> Result<Array2<f32>> {
    match read_tiff(path, "32-bit float")? {
        (r, c, tiff::decoder::DecodingResult::F32(v)) => to_array(path, r, c, v),
        (_, _, other) => Err(Error::format(
            path,
            format!("expected 32-bit float samples, found {}", tiff_kind(&other)),
        )),
    }
}

fn tiff_kind(d: &tiff::decoder::DecodingResult) -> &'static str {
    use tiff::decoder::DecodingResult as D;
    match d {
        D::U8(_) => "8-bit unsigned",
        D::U16(_) => "16-bit unsigned",
        D::U32(_) => "32-bit unsigned",
        D::U64(_) => "64-bit unsigned",
        D::F16(_) => "16-bit float",
        D::F32(_) => "32-bit float",
        D::F64(_) => "64-bit float",
        D::I8(_) => "8-bit signed",
        D::I16(_) => "16-bit signed",
        D::I32(_) => "32-bit signed",
        D::I64(_) => "64-bit signed",
    }
}

/// The size `(rows, cols)` of a PNG, TIFF or OpenEXR image (chosen by the extension, case
/// insensitive) read from its header alone, so that a caller can check its own working
/// set against the memory budget ([`crate::limits`]) before any pixel is decoded. For an
/// OpenEXR file it is the first part's data window.
///
/// Errors: an unsupported extension, a file that is not a regular file, or a header the
/// decoder rejects, naming the file.
pub fn image_dimensions(path: &Path) -> Result<(usize, usize)> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let file = BufReader::new(crate::io::input::open_regular(path)?);
    let (w, h): (u64, u64) = match ext.as_str() {
        "png" => {
            let reader = png::Decoder::new(file)
                .read_info()
                .map_err(|e| png_dec_err(path, e))?;
            let (w, h) = reader.info().size();
            (w.into(), h.into())
        }
        "tif" | "tiff" => {
            let mut dec = tiff::decoder::Decoder::new(file)
                .map_err(|e| tiff_err(path, e))?
                .with_limits(tiff_limits());
            let (w, h) = dec.dimensions().map_err(|e| tiff_err(path, e))?;
            (w.into(), h.into())
        }
        "exr" => {
            let mut file = file;
            let meta =
                exr::meta::MetaData::read_from_buffered(&mut file, false).map_err(|e| match e {
                    exr::error::Error::Io(io) => Error::io(path, io),
                    other => Error::format(path, format!("not a readable OpenEXR file: {other}")),
                })?;
            let h = meta
                .headers
                .first()
                .ok_or_else(|| Error::format(path, "OpenEXR file without a part"))?;
            (h.layer_size.0 as u64, h.layer_size.1 as u64)
        }
        other => {
            return Err(Error::format(
                path,
                format!(
                    "unsupported image type `.{}`; expected .png, .tif/.tiff or .exr",
                    crate::limits::escape_token(other)
                ),
            ))
        }
    };
    let to = |v: u64| usize::try_from(v).map_err(|_| Error::format(path, "image too large"));
    Ok((to(h)?, to(w)?))
}

/// Reads a 16-bit greyscale PNG.
pub fn read_png_u16(path: &Path) -> Result<Array2<u16>> {
    let file = crate::io::input::open_regular(path)?;
    let mut reader = png::Decoder::new(BufReader::new(file))
        .read_info()
        .map_err(|e| png_dec_err(path, e))?;
    let (ct, depth) = {
        let info = reader.info();
        (info.color_type, info.bit_depth)
    };
    if ct != png::ColorType::Grayscale || depth != png::BitDepth::Sixteen {
        return Err(Error::format(
            path,
            format!("expected a 16-bit greyscale PNG, found {ct:?} at {depth:?}"),
        ));
    }
    let (w, h) = reader.info().size();
    // The decode buffer (2 bytes per sample) and the u16 array made from it, checked
    // before either is allocated: a 200-byte PNG can claim 100000 × 100000 pixels.
    crate::limits::check_alloc(
        &format!("decoding {}", path.display()),
        &[("rows", u64::from(h)), ("columns", u64::from(w))],
        4,
    )?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| Error::format(path, "PNG image is too large"))?;
    let mut buf = vec![0u8; size];
    let out = reader
        .next_frame(&mut buf)
        .map_err(|e| png_dec_err(path, e))?;
    let (w, h) = (out.width as usize, out.height as usize);
    let v: Vec<u16> = buf[..out.buffer_size()]
        .chunks_exact(2)
        .map(|b| u16::from_be_bytes([b[0], b[1]]))
        .collect();
    to_array(path, h, w, v)
}

/// Writes an animated preview of 8-bit grey frames (APNG via the png crate's animation
/// support), `delay_ms` between frames, looping forever.
pub fn write_apng_gray8(path: &Path, frames: &[Array2<u8>], delay_ms: u16) -> Result<()> {
    let Some(first) = frames.first() else {
        return Err(Error::param("frames", "none", "at least one frame"));
    };
    write_apng_gray8_with(path, frames.len(), first.dim(), delay_ms, |i| {
        Ok(frames[i].clone())
    })
}

/// [`write_apng_gray8`] of `count` frames of `shape` (rows, cols) made one at a time by
/// `frame(i)`, `i` = 0, 1, … in order: only one frame is held at a time (the animated
/// preview of a long sequence, built from frames on disk). The bytes are those of
/// [`write_apng_gray8`] of the same frames.
///
/// Errors: no frame, a frame of another shape, `frame`'s errors, I/O.
pub fn write_apng_gray8_with(
    path: &Path,
    count: usize,
    shape: (usize, usize),
    delay_ms: u16,
    mut frame: impl FnMut(usize) -> Result<Array2<u8>>,
) -> Result<()> {
    if count == 0 {
        return Err(Error::param("frames", "none", "at least one frame"));
    }
    let (rows, cols) = shape;
    let (w, h) = dims(path, rows, cols)?;
    let n = u32::try_from(count)
        .map_err(|_| Error::param("frames", count, "at most 2^32 - 1 frames"))?;
    atomic_write(path, |out| {
        let mut enc = png::Encoder::new(&mut *out, w, h);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_animated(n, 0).map_err(|e| png_err(path, e))?;
        // Delay = numerator / denominator seconds.
        enc.set_frame_delay(delay_ms, 1000)
            .map_err(|e| png_err(path, e))?;
        let mut writer = enc.write_header().map_err(|e| png_err(path, e))?;
        for i in 0..count {
            let f = frame(i)?;
            if f.dim() != (rows, cols) {
                return Err(Error::param(
                    format!("frames[{i}] shape"),
                    format!("{:?}", f.dim()),
                    format!("({rows}, {cols}) like frame 0"),
                ));
            }
            let bytes: Vec<u8> = f.iter().copied().collect();
            writer
                .write_image_data(&bytes)
                .map_err(|e| png_err(path, e))?;
        }
        writer.finish().map_err(|e| png_err(path, e))
    })
}

/// Encodes 8-bit grey (`channels` = 1) or RGB (`channels` = 3) samples, row-major, as PNG
/// bytes in memory.
pub fn encode_png(width: usize, height: usize, channels: usize, samples: &[u8]) -> Result<Vec<u8>> {
    let colour = match channels {
        1 => png::ColorType::Grayscale,
        3 => png::ColorType::Rgb,
        n => return Err(Error::param("PNG channels", n, "1 (grey) or 3 (RGB)")),
    };
    if samples.len() != width * height * channels || width == 0 || height == 0 {
        return Err(Error::param(
            "PNG samples",
            samples.len(),
            format!("{width} × {height} × {channels} > 0 samples"),
        ));
    }
    let (w, h) = (
        u32::try_from(width).map_err(|_| Error::param("PNG width", width, "< 2^32"))?,
        u32::try_from(height).map_err(|_| Error::param("PNG height", height, "< 2^32"))?,
    );
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, w, h);
        enc.set_color(colour);
        enc.set_depth(png::BitDepth::Eight);
        let png_err = |e: png::EncodingError| Error::param("PNG encoding", e.to_string(), "valid");
        let mut writer = enc.write_header().map_err(png_err)?;
        writer.write_image_data(samples).map_err(png_err)?;
        writer.finish().map_err(png_err)?;
    }
    Ok(out)
}

/// Writes PNG `bytes` to `path` atomically.
pub fn write_png_bytes(path: &Path, bytes: &[u8]) -> Result<()> {
    super::atomic_write(path, |w| super::write_all(w, bytes, path))
}
