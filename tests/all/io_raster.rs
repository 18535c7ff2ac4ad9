//! Product writer tests: bit-exact round trips through the TIFF and PNG decoders, EXR
//! checked with the `exr` crate's own reader, APNG frames and timing checked with the
//! `png` crate's decoder, and atomicity on failure.

use std::fs::File;
use std::io::{BufReader, Write};
use std::path::Path;

use eoir::io::atomic_write;
use eoir::io::raster::*;
use eoir::Error;
use ndarray::{Array2, Array3};

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// A non-square u16 image covering the full range, including 0 and 65535.
fn u16_image() -> Array2<u16> {
    let mut s = 7u32;
    let mut a = Array2::from_shape_simple_fn((5, 9), || {
        s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (s >> 16) as u16
    });
    a[[0, 0]] = 0;
    a[[4, 8]] = u16::MAX;
    a[[1, 0]] = 0x0102; // byte-order sensitive
    a
}

/// A non-square f32 image with awkward values: subnormal, -0, huge, tiny, negative.
fn f32_image() -> Array2<f32> {
    let mut a = Array2::from_shape_fn((6, 4), |(r, c)| {
        (r as f32 * 4.0 + c as f32) * 0.1 + 1.0 / 3.0
    });
    a[[0, 1]] = f32::from_bits(1); // smallest subnormal
    a[[1, 2]] = -0.0;
    a[[2, 3]] = f32::MAX;
    a[[3, 0]] = -1.5e-30;
    a[[5, 3]] = f32::MIN_POSITIVE;
    a
}

#[test]
fn tiff_u16_and_f32_round_trip_bit_exact() {
    let dir = tempfile::tempdir().unwrap();
    let u = u16_image();
    let p = dir.path().join("dn.tif");
    write_tiff_u16(&p, u.view()).unwrap();
    assert_eq!(read_tiff_u16(&p).unwrap(), u);

    let f = f32_image();
    let p = dir.path().join("rad.tif");
    write_tiff_f32(&p, f.view()).unwrap();
    let back = read_tiff_f32(&p).unwrap();
    assert_eq!(back.dim(), f.dim());
    assert!(back
        .iter()
        .zip(f.iter())
        .all(|(a, b)| a.to_bits() == b.to_bits()));

    // A transposed (non-contiguous) view is written in its logical order.
    let p = dir.path().join("t.tif");
    write_tiff_f32(&p, f.t()).unwrap();
    assert_eq!(read_tiff_f32(&p).unwrap(), f.t().to_owned());

    // Asking for the wrong sample type is a clear error.
    let e = read_tiff_u16(&dir.path().join("rad.tif"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("expected 16-bit unsigned samples, found 32-bit float"),
        "{e}"
    );
    let e = read_tiff_f32(&dir.path().join("dn.tif"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("expected 32-bit float samples, found 16-bit unsigned"),
        "{e}"
    );
    assert_eq!(names(dir.path()), ["dn.tif", "rad.tif", "t.tif"]);
}

#[test]
fn png_u16_round_trip_bit_exact_and_is_16_bit_grey() {
    let dir = tempfile::tempdir().unwrap();
    let u = u16_image();
    let p = dir.path().join("dn.png");
    write_png_u16(&p, u.view()).unwrap();
    assert_eq!(read_png_u16(&p).unwrap(), u);
    // Check the encoding with the decoder directly: grey, 16 bit, width = columns.
    let r = png::Decoder::new(BufReader::new(File::open(&p).unwrap()))
        .read_info()
        .unwrap();
    let info = r.info();
    assert_eq!((info.width, info.height), (9, 5));
    assert_eq!(
        (info.color_type, info.bit_depth),
        (png::ColorType::Grayscale, png::BitDepth::Sixteen)
    );
}

#[test]
fn png_rgb8_decodes_to_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let rgb = Array3::from_shape_fn((3, 4, 3), |(r, c, k)| (r * 64 + c * 16 + k * 5) as u8);
    let p = dir.path().join("rgb.png");
    write_png_rgb8(&p, rgb.view()).unwrap();
    let mut r = png::Decoder::new(BufReader::new(File::open(&p).unwrap()))
        .read_info()
        .unwrap();
    assert_eq!(r.info().color_type, png::ColorType::Rgb);
    let mut buf = vec![0u8; r.output_buffer_size().unwrap()];
    let out = r.next_frame(&mut buf).unwrap();
    assert_eq!((out.width, out.height), (4, 3));
    assert_eq!(&buf[..out.buffer_size()], rgb.as_slice().unwrap());
    // A read as u16 grey is refused clearly.
    let e = read_png_u16(&p).unwrap_err().to_string();
    assert!(e.contains("expected a 16-bit greyscale PNG"), "{e}");
    // Wrong channel count.
    let bad = Array3::<u8>::zeros((2, 2, 4));
    let e = write_png_rgb8(&dir.path().join("x.png"), bad.view())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("[2, 2, 4]") && e.contains("[rows, cols, 3]"),
        "{e}"
    );
    assert_eq!(names(dir.path()), ["rgb.png"]);
}

#[test]
fn exr_f32_is_readable_by_the_exr_crate() {
    use exr::prelude::{read, FlatSamples, ReadChannels, ReadLayers};
    let dir = tempfile::tempdir().unwrap();
    let f = f32_image();
    let p = dir.path().join("rad.exr");
    write_exr_f32(&p, f.view(), "radiance").unwrap();
    let img = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(&p)
        .unwrap();
    let layer = &img.layer_data;
    assert_eq!((layer.size.width(), layer.size.height()), (4, 6));
    assert_eq!(layer.channel_data.list.len(), 1);
    let ch = &layer.channel_data.list[0];
    assert_eq!(ch.name.to_string(), "radiance");
    let FlatSamples::F32(v) = &ch.sample_data else {
        panic!("expected f32 samples, got {:?}", ch.sample_data);
    };
    // Row-major, row 0 at the top.
    assert!(v
        .iter()
        .zip(f.iter())
        .all(|(a, b)| a.to_bits() == b.to_bits()));

    let e = write_exr_f32(&dir.path().join("x.exr"), f.view(), "")
        .unwrap_err()
        .to_string();
    assert!(e.contains("EXR channel name"), "{e}");
    assert_eq!(names(dir.path()), ["rad.exr"]);
}

#[test]
fn apng_has_every_frame_and_the_delay() {
    let dir = tempfile::tempdir().unwrap();
    let frames: Vec<Array2<u8>> = (0..4)
        .map(|k| Array2::from_shape_fn((3, 5), |(r, c)| (k * 60 + r * 5 + c) as u8))
        .collect();
    let p = dir.path().join("anim.png");
    write_apng_gray8(&p, &frames, 40).unwrap();
    let mut r = png::Decoder::new(BufReader::new(File::open(&p).unwrap()))
        .read_info()
        .unwrap();
    let actl = r.info().animation_control.unwrap();
    assert_eq!((actl.num_frames, actl.num_plays), (4, 0));
    let mut buf = vec![0u8; r.output_buffer_size().unwrap()];
    for f in &frames {
        let out = r.next_frame(&mut buf).unwrap();
        assert_eq!((out.width, out.height), (5, 3));
        assert_eq!(&buf[..out.buffer_size()], f.as_slice().unwrap());
        let fc = r.info().frame_control.unwrap();
        // 40 ms as a fraction of a second.
        assert_eq!(f64::from(fc.delay_num) / f64::from(fc.delay_den), 0.040);
    }

    // Mismatched frame sizes and an empty list are refused without creating a file.
    let mut bad = frames.clone();
    bad[2] = Array2::zeros((3, 4));
    let e = write_apng_gray8(&dir.path().join("bad.png"), &bad, 40)
        .unwrap_err()
        .to_string();
    assert!(e.contains("frames[2]"), "{e}");
    assert!(write_apng_gray8(&dir.path().join("none.png"), &[], 40).is_err());
    assert_eq!(names(dir.path()), ["anim.png"]);
}

#[test]
fn failures_leave_no_target_and_no_temporary_file() {
    let dir = tempfile::tempdir().unwrap();
    // Empty image: refused before anything is created.
    let e = write_png_u16(
        &dir.path().join("e.png"),
        Array2::<u16>::zeros((0, 3)).view(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("empty image"), "{e}");
    assert!(write_tiff_f32(
        &dir.path().join("e.tif"),
        Array2::<f32>::zeros((2, 0)).view()
    )
    .is_err());
    assert!(names(dir.path()).is_empty());

    // The target name is taken by a directory: the encoders run, the final rename
    // fails, and the temporary file is removed.
    std::fs::create_dir(dir.path().join("taken.tif")).unwrap();
    assert!(write_tiff_u16(&dir.path().join("taken.tif"), u16_image().view()).is_err());
    assert!(write_tiff_f32(&dir.path().join("taken.tif"), f32_image().view()).is_err());
    assert!(write_png_u16(&dir.path().join("taken.tif"), u16_image().view()).is_err());
    assert!(write_exr_f32(&dir.path().join("taken.tif"), f32_image().view(), "Y").is_err());
    assert_eq!(names(dir.path()), ["taken.tif"]);

    // A write that fails midway, after bytes went out, leaves an existing target as it
    // was and no temporary file.
    let target = dir.path().join("keep.txt");
    std::fs::write(&target, "old").unwrap();
    let r = atomic_write(&target, |w| {
        w.write_all(&[1u8; 10_000]).unwrap();
        w.flush().unwrap();
        Err(Error::OutOfRange("stopped midway".into()))
    });
    assert!(r.unwrap_err().to_string().contains("stopped midway"));
    assert_eq!(std::fs::read_to_string(&target).unwrap(), "old");
    // And when there was no target, none appears.
    let fresh = dir.path().join("fresh.txt");
    assert!(atomic_write(&fresh, |w| {
        w.write_all(b"partial").unwrap();
        Err(Error::OutOfRange("stop".into()))
    })
    .is_err());
    assert_eq!(names(dir.path()), ["keep.txt", "taken.tif"]);

    // Reading something that is not there names the file.
    let e = read_tiff_u16(&dir.path().join("missing.tif"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("missing.tif"), "{e}");
}

/// The block order of the file: `lineOrder` from the header, read with the `exr` crate.
fn exr_line_order(path: &Path) -> exr::meta::attribute::LineOrder {
    let meta = exr::meta::MetaData::read_from_file(path, false).unwrap();
    meta.headers[0].line_order
}

/// Reproducible runs give identical files: the exr crate compresses blocks in parallel,
/// and in its default order writes each as it finishes, so the same image written twice
/// could differ in block order (the demo's temperature.exr did, run to run). Written
/// with increasing block order, the bytes depend on the data alone. The image has many
/// blocks (RLE tiles of 64 × 64) and varied content, so a parallel writer that reorders
/// them would show it.
#[test]
fn exr_products_are_byte_identical_run_to_run() {
    let dir = tempfile::tempdir().unwrap();
    let image = Array2::from_shape_fn((300, 517), |(r, c)| {
        ((r * 517 + c) as f32 * 0.618_034).fract() * (1.0 + (r % 7) as f32)
    });
    let mut files = Vec::new();
    for i in 0..4 {
        let p = dir.path().join(format!("t{i}.exr"));
        write_exr_f32(&p, image.view(), "T").unwrap();
        assert_eq!(
            exr_line_order(&p),
            exr::meta::attribute::LineOrder::Increasing
        );
        files.push(std::fs::read(&p).unwrap());
    }
    assert!(files.windows(2).all(|w| w[0] == w[1]));
}
