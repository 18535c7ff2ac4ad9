//! ENVI reader/writer tests. Files "from other tools" are built byte by byte here from the
//! ENVI layout definitions (BSQ = [band,row,col], BIL = [row,band,col], BIP =
//! [row,col,band]), so the truth is the layout, not eoir's own writer.

use std::path::{Path, PathBuf};

use eoir::io::envi::{self, EnviReader};
use eoir::io::{self, CubeReader};
use eoir::scene::{Cube, CubeMeta, Geometry, RadianceUnits};
use ndarray::Array3;

/// SplitMix64: a fixed-seed source of test values.
struct Mix(u64);
impl Mix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 100).
    fn f32(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32 * 100.0
    }
}

fn test_cube(bands: usize, rows: usize, cols: usize, seed: u64) -> Cube {
    let mut m = Mix(seed);
    let data = Array3::from_shape_simple_fn((bands, rows, cols), || m.f32());
    let meta = CubeMeta {
        wavelength_um: (0..bands).map(|b| 3.0 + 0.37 * b as f64).collect(),
        fwhm_um: Some((0..bands).map(|b| 0.1 + 0.013 * b as f64).collect()),
        units: RadianceUnits::BandIntegrated,
        geometry: Some(Geometry {
            fov_x_deg: 12.345678901234,
            fov_y_deg: 9.87654321,
            range_m: Some(1234.5),
        }),
        rows,
        cols,
    };
    Cube::new(data, meta).unwrap()
}

/// The value every hand-built file stores at (band, row, col): exact in f32, i16, u16, i32.
fn truth(b: usize, r: usize, c: usize) -> f64 {
    (1000 * b + 10 * r + c) as f64
}

#[derive(Clone, Copy)]
enum Layout {
    Bsq,
    Bil,
    Bip,
}

/// Stored band order for a layout, via the layout's own index formula.
fn index(l: Layout, (nb, nr, nc): (usize, usize, usize), b: usize, r: usize, c: usize) -> usize {
    match l {
        Layout::Bsq => (b * nr + r) * nc + c,
        Layout::Bil => (r * nb + b) * nc + c,
        Layout::Bip => (r * nc + c) * nb + b,
    }
}

/// Packs stored values (one per element, already in stored band order) into bytes.
fn pack(values: &[f64], data_type: u32, big_endian: bool) -> Vec<u8> {
    let mut out = Vec::new();
    for &v in values {
        let bytes: Vec<u8> = match (data_type, big_endian) {
            (2, false) => (v as i16).to_le_bytes().to_vec(),
            (2, true) => (v as i16).to_be_bytes().to_vec(),
            (3, false) => (v as i32).to_le_bytes().to_vec(),
            (3, true) => (v as i32).to_be_bytes().to_vec(),
            (4, false) => (v as f32).to_le_bytes().to_vec(),
            (4, true) => (v as f32).to_be_bytes().to_vec(),
            (5, false) => v.to_le_bytes().to_vec(),
            (5, true) => v.to_be_bytes().to_vec(),
            (12, false) => (v as u16).to_le_bytes().to_vec(),
            (12, true) => (v as u16).to_be_bytes().to_vec(),
            _ => panic!("test packs types 2, 3, 4, 5, 12"),
        };
        out.extend(bytes);
    }
    out
}

/// Stored values of a `(nb, nr, nc)` cube in `layout`, from `f(b, r, c)`.
fn arrange(
    l: Layout,
    dims: (usize, usize, usize),
    f: impl Fn(usize, usize, usize) -> f64,
) -> Vec<f64> {
    let (nb, nr, nc) = dims;
    let mut v = vec![0.0; nb * nr * nc];
    for b in 0..nb {
        for r in 0..nr {
            for c in 0..nc {
                v[index(l, dims, b, r, c)] = f(b, r, c);
            }
        }
    }
    v
}

fn write(path: &Path, bytes: impl AsRef<[u8]>) {
    std::fs::write(path, bytes).unwrap();
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

fn open_err(path: &Path) -> String {
    match EnviReader::open(path) {
        Ok(_) => panic!("{} opened but should not", path.display()),
        Err(e) => e.to_string(),
    }
}

/// A minimal header for a float32 cube; `extra` lines are appended.
fn header(dims: (usize, usize, usize), data_type: u32, interleave: &str, extra: &str) -> String {
    let (nb, nr, nc) = dims;
    let wl: Vec<String> = (0..nb).map(|b| format!("{}", 8 + b)).collect();
    format!(
        "ENVI\nsamples = {nc}\nlines = {nr}\nbands = {nb}\nheader offset = 0\ndata type = {data_type}\ninterleave = {interleave}\nbyte order = 0\nwavelength units = Micrometers\nwavelength = {{{}}}\neoir radiance units = W m-2 sr-1 um-1\n{extra}",
        wl.join(", ")
    )
}

#[test]
fn round_trip_is_bit_exact_and_layout_is_bsq_f32_le() {
    let dir = tempfile::tempdir().unwrap();
    let cube = test_cube(4, 5, 7, 1);
    let img = dir.path().join("cube.img");
    io::write_cube(&img, &cube).unwrap();
    assert_eq!(names(dir.path()), ["cube.hdr", "cube.img"]);

    // The data file is exactly BSQ float32 little-endian (the ENVI definition).
    let bytes = std::fs::read(&img).unwrap();
    assert_eq!(bytes.len(), 4 * 5 * 7 * 4);
    for ((b, r, c), v) in cube.data.indexed_iter() {
        let i = 4 * ((b * 5 + r) * 7 + c);
        assert_eq!(bytes[i..i + 4], v.to_le_bytes());
    }

    // Read back through both files of the pair.
    for p in [dir.path().join("cube.hdr"), img.clone()] {
        let back = io::read_cube(&p).unwrap();
        assert_eq!(back.meta, cube.meta);
        assert!(back
            .data
            .iter()
            .zip(cube.data.iter())
            .all(|(a, b)| a.to_bits() == b.to_bits()));
        let r = EnviReader::open(&p).unwrap();
        assert!(r.warnings().is_empty(), "{:?}", r.warnings());
        assert_eq!(r.frames(), 1);
    }

    // Writing to the header name puts the data in <stem>.img.
    let dir2 = tempfile::tempdir().unwrap();
    envi::write(&dir2.path().join("x.hdr"), &cube).unwrap();
    assert_eq!(names(dir2.path()), ["x.hdr", "x.img"]);
    // A .bsq data name keeps its extension, header is <stem>.hdr.
    envi::write(&dir2.path().join("y.bsq"), &cube).unwrap();
    assert_eq!(names(dir2.path()), ["x.hdr", "x.img", "y.bsq", "y.hdr"]);
    assert_eq!(io::read_cube(&dir2.path().join("y.hdr")).unwrap(), cube);
}

#[test]
fn bil_and_bip_match_bsq_band_by_band() {
    let dir = tempfile::tempdir().unwrap();
    let dims = (3, 4, 5);
    for (layout, name, ty) in [
        (Layout::Bsq, "bsq", 4),
        (Layout::Bil, "bil", 4),
        (Layout::Bip, "bip", 4),
        (Layout::Bil, "bil", 3),
        (Layout::Bip, "bip", 3),
    ] {
        let stem = format!("{name}{ty}");
        write(
            &dir.path().join(format!("{stem}.hdr")),
            header(dims, ty, name, ""),
        );
        write(
            &dir.path().join(format!("{stem}.{name}")),
            pack(&arrange(layout, dims, truth), ty, false),
        );
        let mut r = EnviReader::open(&dir.path().join(format!("{stem}.hdr"))).unwrap();
        // Read bands out of order to exercise the seeks.
        for b in [2, 0, 1] {
            let plane = r.read_band(0, b).unwrap();
            for ((row, col), v) in plane.indexed_iter() {
                assert_eq!(
                    f64::from(*v),
                    truth(b, row, col),
                    "{stem} band {b} ({row},{col})"
                );
            }
        }
    }
}

#[test]
fn big_endian_int16_float32_float64() {
    let dir = tempfile::tempdir().unwrap();
    let dims = (2, 3, 4);
    for ty in [2u32, 4, 5] {
        let h = header(dims, ty, "bip", "").replace("byte order = 0", "byte order = 1");
        write(&dir.path().join(format!("be{ty}.hdr")), h);
        write(
            &dir.path().join(format!("be{ty}.dat")),
            pack(&arrange(Layout::Bip, dims, truth), ty, true),
        );
        let cube = io::read_cube(&dir.path().join(format!("be{ty}.dat"))).unwrap();
        for ((b, r, c), v) in cube.data.indexed_iter() {
            assert_eq!(f64::from(*v), truth(b, r, c), "type {ty}");
        }
    }
}

#[test]
fn nanometre_and_millimetre_units_are_converted() {
    let dir = tempfile::tempdir().unwrap();
    let dims = (3, 2, 2);
    let data = pack(&arrange(Layout::Bsq, dims, truth), 4, false);
    for (units, wl, fw, want_wl, want_fw) in [
        (
            "Nanometers",
            "450, 550, 650",
            "10, 20, 30",
            [0.45, 0.55, 0.65],
            [0.01, 0.02, 0.03],
        ),
        (
            "nm",
            "450, 550, 650",
            "10, 20, 30",
            [0.45, 0.55, 0.65],
            [0.01, 0.02, 0.03],
        ),
        (
            "micron",
            "4.5, 5.5, 6.5",
            "0.1, 0.2, 0.3",
            [4.5, 5.5, 6.5],
            [0.1, 0.2, 0.3],
        ),
        (
            "Millimeters",
            "0.008, 0.009, 0.01",
            "0.001, 0.001, 0.001",
            [8.0, 9.0, 10.0],
            [1.0, 1.0, 1.0],
        ),
    ] {
        let h = header(dims, 4, "bsq", &format!("fwhm = {{{fw}}}\n"))
            .replace(
                "wavelength units = Micrometers",
                &format!("wavelength units = {units}"),
            )
            .replace("wavelength = {8, 9, 10}", &format!("wavelength = {{{wl}}}"));
        write(&dir.path().join("n.hdr"), h);
        write(&dir.path().join("n.img"), &data);
        let r = EnviReader::open(&dir.path().join("n.hdr")).unwrap();
        let m = r.meta();
        for i in 0..3 {
            assert!(
                (m.wavelength_um[i] - want_wl[i]).abs() < 1e-12,
                "{units}: {:?}",
                m.wavelength_um
            );
            let f = m.fwhm_um.as_ref().unwrap()[i];
            assert!((f - want_fw[i]).abs() < 1e-12, "{units}: {:?}", m.fwhm_um);
        }
    }
}

#[test]
fn wavenumber_grid_is_converted_and_reversed() {
    let dir = tempfile::tempdir().unwrap();
    // Increasing wavenumbers = decreasing wavelengths: 12.5, 10, 8 µm.
    let nu = [800.0, 1000.0, 1250.0];
    let dnu = 4.0;
    let dims = (3, 2, 3);
    let h = header(dims, 4, "bil", "fwhm = {4, 4, 4}\n")
        .replace(
            "wavelength units = Micrometers",
            "wavelength units = Wavenumber",
        )
        .replace("wavelength = {8, 9, 10}", "wavelength = {800, 1000, 1250}");
    write(&dir.path().join("w.hdr"), h);
    write(
        &dir.path().join("w.img"),
        pack(&arrange(Layout::Bil, dims, truth), 4, false),
    );
    let mut r = EnviReader::open(&dir.path().join("w.img")).unwrap();
    let m = r.meta().clone();
    assert_eq!(m.wavelength_um, vec![8.0, 10.0, 12.5]);
    for (i, f) in m.fwhm_um.as_ref().unwrap().iter().enumerate() {
        // Exact width of the interval [ν - Δν/2, ν + Δν/2] in µm; the first-order
        // conversion differs from it by a relative (Δν / 2ν)² ≈ 6e-6.
        let n = nu[2 - i];
        let exact = 1e4 / (n - dnu / 2.0) - 1e4 / (n + dnu / 2.0);
        assert!(
            ((f - exact) / exact).abs() < 1e-5,
            "band {i}: {f} vs {exact}"
        );
    }
    assert!(r.warnings().iter().any(|w| w.contains("decreasing")));
    // Band 0 (8 µm) is the stored band 2.
    for b in 0..3 {
        let plane = r.read_band(0, b).unwrap();
        for ((row, col), v) in plane.indexed_iter() {
            assert_eq!(f64::from(*v), truth(2 - b, row, col));
        }
    }
}

#[test]
fn int16_and_uint16_with_gain_and_offset() {
    let dir = tempfile::tempdir().unwrap();
    let dims = (2, 3, 3);
    // Stored integers, including negative int16 counts that the offset lifts above zero
    // and uint16 values above i16::MAX.
    let raw16 = |b: usize, r: usize, c: usize| -300.0 + (b * 100 + r * 10 + c) as f64;
    let rawu = |b: usize, r: usize, c: usize| 40000.0 + (b * 1000 + r * 100 + c) as f64;
    for (ty, raw) in [
        (2u32, &raw16 as &dyn Fn(usize, usize, usize) -> f64),
        (12, &rawu),
    ] {
        let h = header(
            dims,
            ty,
            "bsq",
            "data gain values = {0.01, 0.5}\ndata offset values = {5, 200.25}\n",
        );
        write(&dir.path().join(format!("g{ty}.hdr")), h);
        write(
            &dir.path().join(format!("g{ty}.raw")),
            pack(&arrange(Layout::Bsq, dims, raw), ty, false),
        );
        let cube = io::read_cube(&dir.path().join(format!("g{ty}.hdr"))).unwrap();
        let gain = [0.01, 0.5];
        let off = [5.0, 200.25];
        for ((b, r, c), v) in cube.data.indexed_iter() {
            let want = gain[b] * raw(b, r, c) + off[b];
            assert!(
                (f64::from(*v) - want).abs() <= want * 1e-7,
                "type {ty} ({b},{r},{c}): {v} vs {want}"
            );
        }
    }
}

#[test]
fn wrapped_braces_comments_messy_keys_offset_and_letter_case() {
    let dir = tempfile::tempdir().unwrap();
    let dims = (3, 2, 4);
    let h = "ENVI\n\
; written by another tool\n\
description = {A cube whose description\n  runs over = two lines}\n\
Samples   =  4\n\
LINES=2\n\
  bands = 3\n\
Header   Offset = 16\n\
data type = 4\n\
Interleave = BSQ\n\
byte order = 0\n\
; the spectral axis\n\
Wavelength  Units = Micrometers\n\
wavelength = {\n 8.0,\n ; in-list comment\n 9.0,\n 10.0 }\n\
fwhm = {0.5,0.5,\n0.5}\n\
data ignore value = -9999\n\
EOIR Radiance Units = {W m-2 sr-1}\n\
eoir  fov deg = {20,\n 10}\n";
    write(&dir.path().join("Mixed.HDR"), h);
    let mut bytes = vec![0xAB; 16];
    bytes.extend(pack(&arrange(Layout::Bsq, dims, truth), 4, false));
    write(&dir.path().join("Mixed.IMG"), bytes);
    let cube = io::read_cube(&dir.path().join("Mixed.HDR")).unwrap();
    assert_eq!(cube.meta.wavelength_um, vec![8.0, 9.0, 10.0]);
    assert_eq!(cube.meta.fwhm_um, Some(vec![0.5; 3]));
    assert_eq!(cube.meta.units, RadianceUnits::BandIntegrated);
    let g = cube.meta.geometry.unwrap();
    assert_eq!((g.fov_x_deg, g.fov_y_deg, g.range_m), (20.0, 10.0, None));
    for ((b, r, c), v) in cube.data.indexed_iter() {
        assert_eq!(f64::from(*v), truth(b, r, c));
    }
    // And from the data file, whose header differs in letter case.
    assert_eq!(io::read_cube(&dir.path().join("Mixed.IMG")).unwrap(), cube);
}

#[test]
fn missing_wavelength_units_are_inferred_with_a_warning_or_refused() {
    let dir = tempfile::tempdir().unwrap();
    let dims = (2, 2, 2);
    let data = pack(&arrange(Layout::Bsq, dims, truth), 4, false);
    for (wl, want) in [
        ("3.5, 4.5", Some([3.5, 4.5])),
        ("800, 900", Some([0.8, 0.9])),
        ("50, 100", None),
    ] {
        let h = header(dims, 4, "bsq", "")
            .replace("wavelength units = Micrometers\n", "")
            .replace("wavelength = {8, 9}", &format!("wavelength = {{{wl}}}"));
        write(&dir.path().join("u.hdr"), h);
        write(&dir.path().join("u.img"), &data);
        match want {
            Some(w) => {
                let r = EnviReader::open(&dir.path().join("u.hdr")).unwrap();
                assert!((r.meta().wavelength_um[0] - w[0]).abs() < 1e-12);
                assert!((r.meta().wavelength_um[1] - w[1]).abs() < 1e-12);
                assert_eq!(r.warnings().len(), 1, "{:?}", r.warnings());
                assert!(r.warnings()[0].contains("wavelength units"));
            }
            None => {
                let e = open_err(&dir.path().join("u.hdr"));
                assert!(
                    e.contains("no `wavelength units`") && e.contains("50"),
                    "{e}"
                );
            }
        }
    }
}

#[test]
fn missing_radiance_units_warn_and_geometry_keys_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let dims = (2, 3, 4);
    let data = pack(&arrange(Layout::Bsq, dims, truth), 4, false);
    write(&dir.path().join("g.img"), &data);

    let h = header(
        dims,
        4,
        "bsq",
        "eoir ifov rad = {0.001, 0.002}\neoir range m = 500\n",
    )
    .replace("eoir radiance units = W m-2 sr-1 um-1\n", "");
    write(&dir.path().join("g.hdr"), h);
    let r = EnviReader::open(&dir.path().join("g.hdr")).unwrap();
    assert_eq!(r.meta().units, RadianceUnits::SpectralPerUm);
    assert!(
        r.warnings()
            .iter()
            .any(|w| w.contains("eoir radiance units")),
        "{:?}",
        r.warnings()
    );
    let g = r.meta().geometry.unwrap();
    // 4 columns of 1 mrad and 3 rows of 2 mrad.
    assert!((g.fov_x_deg - (0.004f64).to_degrees()).abs() < 1e-12);
    assert!((g.fov_y_deg - (0.006f64).to_degrees()).abs() < 1e-12);
    assert_eq!(g.range_m, Some(500.0));

    // No geometry keys: no geometry.
    write(&dir.path().join("g.hdr"), header(dims, 4, "bsq", ""));
    assert_eq!(
        EnviReader::open(&dir.path().join("g.hdr"))
            .unwrap()
            .meta()
            .geometry,
        None
    );

    // Both forms at once, or a range alone, are refused.
    write(
        &dir.path().join("g.hdr"),
        header(
            dims,
            4,
            "bsq",
            "eoir ifov rad = {0.001, 0.002}\neoir fov deg = {1, 1}\n",
        ),
    );
    let e = open_err(&dir.path().join("g.hdr"));
    assert!(e.contains("only one"), "{e}");
    write(
        &dir.path().join("g.hdr"),
        header(dims, 4, "bsq", "eoir range m = 100\n"),
    );
    let e = open_err(&dir.path().join("g.hdr"));
    assert!(e.contains("without a field of view"), "{e}");
    // An unknown radiance unit is named.
    write(
        &dir.path().join("g.hdr"),
        header(dims, 4, "bsq", "").replace("W m-2 sr-1 um-1", "photons"),
    );
    let e = open_err(&dir.path().join("g.hdr"));
    assert!(
        e.contains("`photons`") && e.contains("W m-2 sr-1 um-1"),
        "{e}"
    );
}

#[test]
fn truncated_data_file_is_one_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let dims = (2, 3, 4); // 96 bytes of float32
    write(&dir.path().join("t.hdr"), header(dims, 4, "bsq", ""));
    let mut data = pack(&arrange(Layout::Bsq, dims, truth), 4, false);
    data.truncate(90);
    write(&dir.path().join("t.img"), &data);
    let e = open_err(&dir.path().join("t.hdr"));
    assert!(
        e.contains("truncated") && e.contains("96 bytes") && e.contains("90 bytes"),
        "{e}"
    );
}

#[test]
fn header_that_lies_about_the_size_is_one_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let dims = (2, 3, 4);
    // The header claims 2 bands; the file holds 3.
    write(&dir.path().join("l.hdr"), header(dims, 4, "bsq", ""));
    write(
        &dir.path().join("l.img"),
        pack(&arrange(Layout::Bsq, (3, 3, 4), truth), 4, false),
    );
    let e = open_err(&dir.path().join("l.img"));
    assert!(
        e.contains("header says 96 bytes") && e.contains("file has 144 bytes"),
        "{e}"
    );
}

#[test]
fn nan_inf_and_negative_radiance_name_the_band_and_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let dims = (4, 3, 3);
    let bad = |b: usize, r: usize, c: usize| match (b, r, c) {
        (1, 1, 2) => f64::NAN,
        (2, 0, 1) => f64::INFINITY,
        (3, 2, 0) => -0.5,
        _ => truth(b, r, c),
    };
    write(&dir.path().join("bad.hdr"), header(dims, 4, "bsq", ""));
    write(
        &dir.path().join("bad.img"),
        pack(&arrange(Layout::Bsq, dims, bad), 4, false),
    );
    let mut r = EnviReader::open(&dir.path().join("bad.hdr")).unwrap();
    assert!(r.read_band(0, 0).is_ok());
    assert!(matches!(
        r.read_planes(0, &[0]).unwrap(),
        eoir::io::BandPlanes::Mapped(_)
    ));
    for (b, needle) in [
        (1, "row 1, col 2: radiance NaN"),
        (2, "row 0, col 1: radiance inf"),
        (3, "row 2, col 0: radiance -0.5"),
    ] {
        let e = r.read_band(0, b).unwrap_err().to_string();
        // A memory-mapped plane is checked the same way, with the same message.
        let mapped = r.read_planes(0, &[0, b]).unwrap_err().to_string();
        assert_eq!(mapped, e);
        assert!(
            e.contains(&format!("band {b} (")) && e.contains(needle),
            "{e}"
        );
    }
    // Negative values produced by an offset are caught as well.
    let h = header((1, 1, 2), 2, "bsq", "data offset values = {-100}\n");
    write(&dir.path().join("neg.hdr"), h);
    write(&dir.path().join("neg.img"), pack(&[150.0, 50.0], 2, false));
    let e = io::read_cube(&dir.path().join("neg.hdr"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("col 1: radiance -50"), "{e}");
    // Out-of-range requests.
    assert!(r
        .read_band(0, 4)
        .unwrap_err()
        .to_string()
        .contains("band 4"));
    assert!(r
        .read_band(1, 0)
        .unwrap_err()
        .to_string()
        .contains("frame 1"));
}

#[test]
fn non_monotone_wavelengths_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let dims = (3, 2, 2);
    let h = header(dims, 4, "bsq", "").replace("{8, 9, 10}", "{8, 10, 9}");
    write(&dir.path().join("m.hdr"), h);
    write(
        &dir.path().join("m.img"),
        pack(&arrange(Layout::Bsq, dims, truth), 4, false),
    );
    let e = open_err(&dir.path().join("m.hdr"));
    assert!(
        e.contains("strictly increasing or strictly decreasing")
            && e.contains("wavelength[1] = 10"),
        "{e}"
    );
    // Equal neighbours are not strictly increasing either.
    let h = header(dims, 4, "bsq", "").replace("{8, 9, 10}", "{8, 9, 9}");
    write(&dir.path().join("m.hdr"), h);
    assert!(open_err(&dir.path().join("m.hdr")).contains("wavelength[1] = 9"));
}

#[test]
fn malformed_headers_give_one_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let dims = (2, 2, 2);
    let data = pack(&arrange(Layout::Bsq, dims, truth), 4, false);
    write(&dir.path().join("h.img"), &data);
    let cases: Vec<(String, &str)> = vec![
        (
            header(dims, 6, "bsq", ""),
            "data type 6 (complex float32) is not supported",
        ),
        (
            header(dims, 4, "bsq", "").replace("ENVI\n", "NOT ENVI\n"),
            "expected `ENVI` as the first line",
        ),
        (
            header(dims, 4, "bsq", "").replace("samples = 2", "samples = two"),
            "`samples = two`: expected a whole number > 0",
        ),
        (
            header(dims, 4, "bsq", "").replace("samples = 2\n", ""),
            "no `samples`",
        ),
        (
            header(dims, 4, "bsq", "").replace("wavelength = {8, 9}\n", ""),
            "no `wavelength`",
        ),
        (
            header(dims, 4, "bsq", "").replace("{8, 9}", "{8, 9, 10}"),
            "`wavelength` has 3 values but the header says bands = 2",
        ),
        (
            header(dims, 4, "bsq", "").replace("{8, 9}", "{8, nine}"),
            "`nine`",
        ),
        (
            header(dims, 4, "bsq", "").replace("{8, 9}", "{8, 9"),
            "never closed",
        ),
        (
            header(dims, 4, "bsq", "").replace("= bsq", "= bxq"),
            "bsq, bil or bip",
        ),
        (
            header(dims, 4, "bsq", "").replace("byte order = 0", "byte order = 2"),
            "0 (little-endian) or 1 (big-endian)",
        ),
        (
            header(dims, 4, "bsq", "").replace("Micrometers", "furlongs"),
            "`wavelength units = furlongs`",
        ),
    ];
    for (h, needle) in cases {
        write(&dir.path().join("h.hdr"), &h);
        let e = open_err(&dir.path().join("h.hdr"));
        assert!(e.contains(needle), "expected `{needle}` in: {e}");
        assert!(e.contains("h.hdr"), "{e}");
    }
}

#[test]
fn missing_partner_file_lists_what_was_tried() {
    let dir = tempfile::tempdir().unwrap();
    write(
        &dir.path().join("lonely.hdr"),
        header((1, 1, 1), 4, "bsq", ""),
    );
    let e = open_err(&dir.path().join("lonely.hdr"));
    for n in [
        "lonely, ",
        "lonely.img",
        "lonely.dat",
        "lonely.raw",
        "lonely.bsq",
        "lonely.bil",
        "lonely.bip",
    ] {
        assert!(e.contains(n), "{n} missing from: {e}");
    }
    write(&dir.path().join("orphan.img"), [0u8; 4]);
    let e = open_err(&dir.path().join("orphan.img"));
    assert!(
        e.contains("orphan.img.hdr") && e.contains("orphan.hdr"),
        "{e}"
    );
    let e = open_err(&dir.path().join("nothing.hdr"));
    assert!(e.contains("nothing.hdr"), "{e}");
}

#[test]
fn failed_write_leaves_no_file_behind() {
    let dir = tempfile::tempdir().unwrap();
    let cube = test_cube(2, 3, 4, 7);
    // The header cannot be renamed into place (a directory holds its name): the data
    // file was already written and must be removed again, and no temporary remains.
    std::fs::create_dir(dir.path().join("c.hdr")).unwrap();
    let e = envi::write(&dir.path().join("c.img"), &cube).unwrap_err();
    assert!(e.to_string().contains("c.hdr"), "{e}");
    assert_eq!(names(dir.path()), ["c.hdr"]);
    // Nothing is created in a directory that does not exist.
    let missing: PathBuf = dir.path().join("no/such/dir/c.img");
    assert!(envi::write(&missing, &cube).is_err());
    assert_eq!(names(dir.path()), ["c.hdr"]);
    // A cube whose array disagrees with its metadata is refused before any file exists.
    let mut broken = cube.clone();
    broken.meta.rows = 5;
    let e = envi::write(&dir.path().join("d.img"), &broken)
        .unwrap_err()
        .to_string();
    assert!(e.contains("cube shape"), "{e}");
    assert_eq!(names(dir.path()), ["c.hdr"]);
}

#[test]
fn documented_minimal_header_opens_and_unknown_units_count_as_missing() {
    let dir = tempfile::tempdir().unwrap();
    // The hand-written header of the module documentation and the README.
    let h = "ENVI\nsamples = 640\nlines = 480\nbands = 2\ndata type = 4\ninterleave = bsq\nbyte order = 0\nwavelength units = Micrometers\nwavelength = {8.5, 10.5}\neoir radiance units = W m-2 sr-1 um-1\neoir fov deg = {10.0, 7.5}\n";
    write(&dir.path().join("scene.hdr"), h);
    let data = pack(
        &arrange(Layout::Bsq, (2, 480, 640), |b, r, c| (b + r + c) as f64),
        4,
        false,
    );
    write(&dir.path().join("scene.img"), data);
    let mut r = EnviReader::open(&dir.path().join("scene.hdr")).unwrap();
    assert!(r.warnings().is_empty(), "{:?}", r.warnings());
    assert_eq!(
        (r.meta().rows, r.meta().cols, r.meta().bands()),
        (480, 640, 2)
    );
    assert_eq!(
        r.read_band(0, 1).unwrap()[[479, 639]],
        (1 + 479 + 639) as f32
    );

    let h = h.replace("Micrometers", "Unknown");
    write(&dir.path().join("scene.hdr"), h);
    let r = EnviReader::open(&dir.path().join("scene.hdr")).unwrap();
    assert_eq!(r.meta().wavelength_um, vec![8.5, 10.5]);
    assert!(r.warnings()[0].contains("below 30"), "{:?}", r.warnings());
}

/// The requests a chunked reader must serve exactly: every band in order, one band, an
/// unsorted non-contiguous set, a contiguous run, a repeated band, nothing.
const REQUESTS: [&[usize]; 6] = [
    &[0, 1, 2, 3, 4, 5, 6],
    &[3],
    &[6, 0, 3],
    &[2, 3, 4],
    &[5, 5],
    &[],
];

/// Opens `hdr` once per read path: as is, and (BIP) forced through the band-order scratch
/// file (direct size 0) or forced direct (direct size ∞).
fn readers_for(hdr: &Path) -> Vec<(String, EnviReader)> {
    let mut out = vec![("default".to_string(), EnviReader::open(hdr).unwrap())];
    for (name, bytes) in [("scratch", 0), ("direct", u64::MAX)] {
        let mut r = EnviReader::open(hdr).unwrap();
        r.set_bip_direct_frame_bytes(bytes);
        out.push((name.to_string(), r));
    }
    out
}

#[test]
fn chunked_reads_give_the_layout_truth_for_every_interleave_type_and_order() {
    let dir = tempfile::tempdir().unwrap();
    let dims = (7, 6, 5);
    let offset = 37;
    for (layout, il) in [
        (Layout::Bsq, "bsq"),
        (Layout::Bil, "bil"),
        (Layout::Bip, "bip"),
    ] {
        for ty in [2u32, 3, 4, 5, 12] {
            for big in [false, true] {
                let stem = format!("{il}{ty}{}", if big { "be" } else { "le" });
                let spec = (layout, il, ty, big, offset);
                write_truth_cube(dir.path(), &stem, dims, spec, "");
                for (path, mut r) in readers_for(&dir.path().join(format!("{stem}.hdr"))) {
                    for req in REQUESTS {
                        let planes = r.read_bands(0, req).unwrap();
                        assert_eq!(planes.len(), req.len());
                        for (plane, &b) in planes.iter().zip(req) {
                            assert_is_truth(plane.view(), b, &format!("{stem} ({path}) {req:?}"));
                        }
                    }
                    // read_band is the one-band chunk.
                    for b in [4, 1] {
                        assert_eq!(
                            r.read_band(0, b).unwrap(),
                            r.read_bands(0, &[b]).unwrap()[0]
                        );
                    }
                    let spilled = layout_is_bip(il) && path == "scratch";
                    assert_eq!(r.uses_scratch_file(), spilled, "{stem} ({path})");
                    // The engine's read: the same values, mapped (check owed) where the
                    // file is native f32 BSQ with aligned planes (not at this header
                    // offset) or BIP goes through the scratch file.
                    let native_bsq = il == "bsq" && ty == 4 && !big && offset % 4 == 0;
                    for req in REQUESTS.iter().filter(|q| !q.is_empty()) {
                        let (planes, owed) = r.read_planes_deferred(0, req).unwrap();
                        let mapped = matches!(planes, io::BandPlanes::Mapped(_));
                        assert_eq!(mapped, native_bsq || spilled, "{stem} ({path}) {req:?}");
                        assert_eq!(owed.is_some(), mapped, "{stem} ({path}) {req:?}");
                        for (plane, &b) in planes.views().iter().zip(*req) {
                            assert_is_truth(plane.view(), b, &format!("{stem} ({path}) {req:?}"));
                        }
                    }
                }
            }
        }
    }
}

/// Writes `<stem>.hdr` and `<stem>.img`: the layout-truth cube of `dims` in `spec`
/// (layout, its `interleave` name, ENVI data type, big-endian, header offset: the data
/// after that many 0xA5 bytes), with `extra` header lines; returns the header's path.
fn write_truth_cube(
    dir: &Path,
    stem: &str,
    dims: (usize, usize, usize),
    (layout, il, ty, big, offset): (Layout, &str, u32, bool, usize),
    extra: &str,
) -> PathBuf {
    let order = if big {
        "byte order = 1"
    } else {
        "byte order = 0"
    };
    let h = header(dims, ty, il, &format!("header offset = {offset}\n{extra}"))
        .replace("byte order = 0", order)
        .replace("header offset = 0\n", "");
    let hdr = dir.join(format!("{stem}.hdr"));
    write(&hdr, h);
    let mut bytes = vec![0xA5u8; offset];
    bytes.extend(pack(&arrange(layout, dims, truth), ty, big));
    write(&dir.join(format!("{stem}.img")), bytes);
    hdr
}

/// `plane` is band `b` of the 6 × 5 layout-truth cube of the chunked-read tests.
fn assert_is_truth(plane: ndarray::ArrayView2<f32>, b: usize, what: &str) {
    assert_eq!(plane.dim(), (6, 5), "{what}");
    for ((row, col), v) in plane.indexed_iter() {
        assert_eq!(
            f64::from(*v),
            truth(b, row, col),
            "{what} band {b} ({row},{col})"
        );
    }
}

fn layout_is_bip(il: &str) -> bool {
    il == "bip"
}

#[test]
fn interleaves_agree_bit_for_bit_with_gain_offset_ignore_value_and_reversed_bands() {
    // Random f32 values (not round numbers), a per-band gain and offset, a `data ignore
    // value` planted at known pixels and a wavenumber grid (stored in decreasing
    // wavelength, handed out reversed): BSQ, BIL and BIP of the same cube must give the
    // same bits for every request, and count the ignored samples of the bands read only.
    let dir = tempfile::tempdir().unwrap();
    let (nb, nr, nc) = (6, 9, 11);
    let mut m = Mix(42);
    let mut stored: Vec<f64> = (0..nb * nr * nc).map(|_| f64::from(m.f32())).collect();
    let ignore = -9999.0;
    // Ignored samples: stored band 1 at 3 pixels, stored band 4 at 1 pixel.
    for (b, r, c) in [(1, 0, 0), (1, 4, 7), (1, 8, 10), (4, 2, 3)] {
        stored[(b * nr + r) * nc + c] = ignore;
    }
    let bsq = |b: usize, r: usize, c: usize| stored[(b * nr + r) * nc + c];
    let gains: Vec<String> = (0..nb)
        .map(|b| format!("{}", 0.5 + 0.25 * b as f64))
        .collect();
    let offsets: Vec<String> = (0..nb).map(|b| format!("{}", 1.5 * b as f64)).collect();
    let wavenumbers: Vec<String> = (0..nb)
        .map(|b| format!("{}", 1750.0 + 50.0 * b as f64))
        .collect();
    let extra = format!(
        "data gain values = {{{}}}\ndata offset values = {{{}}}\ndata ignore value = {ignore}\n",
        gains.join(", "),
        offsets.join(", ")
    );
    let mut results = Vec::new();
    for (layout, il) in [
        (Layout::Bsq, "bsq"),
        (Layout::Bil, "bil"),
        (Layout::Bip, "bip"),
    ] {
        let h = header((nb, nr, nc), 4, il, &extra)
            .replace(
                "wavelength units = Micrometers",
                "wavelength units = Wavenumber",
            )
            .replace(
                &format!(
                    "wavelength = {{{}}}",
                    (0..nb)
                        .map(|b| format!("{}", 8 + b))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
                &format!("wavelength = {{{}}}", wavenumbers.join(", ")),
            );
        write(&dir.path().join(format!("{il}.hdr")), h);
        write(
            &dir.path().join(format!("{il}.img")),
            pack(&arrange(layout, (nb, nr, nc), bsq), 4, false),
        );
        for (path, mut r) in readers_for(&dir.path().join(format!("{il}.hdr"))) {
            // Output band k is stored band nb-1-k (reversed grid).
            let planes = r.read_bands(0, &[4, 1, 3]).unwrap();
            for (plane, k) in planes.iter().zip([4usize, 1, 3]) {
                let fb = nb - 1 - k;
                let (g, o) = (0.5 + 0.25 * fb as f64, 1.5 * fb as f64);
                for ((row, col), v) in plane.indexed_iter() {
                    let s = bsq(fb, row, col);
                    let want = if s == ignore { 0.0 } else { (g * s + o) as f32 };
                    assert_eq!(
                        v.to_bits(),
                        want.to_bits(),
                        "{il} ({path}) band {k} ({row},{col})"
                    );
                }
            }
            // Output bands 4 (stored 1: 3 ignored) and 1 (stored 4: 1 ignored) were read.
            let w = r.warnings().join("\n");
            assert!(
                w.contains("4 samples (pixel × band, in the 3 bands read)"),
                "{il}: {w}"
            );
            results.push(planes);
        }
    }
    assert!(results.windows(2).all(|p| p[0] == p[1]));
}

#[test]
fn nan_in_a_band_not_requested_is_not_seen_and_in_a_requested_band_names_band_and_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let dims = (5, 4, 6);
    let poisoned = |b: usize, r: usize, c: usize| {
        if (b, r, c) == (2, 3, 4) {
            f64::NAN
        } else {
            truth(b, r, c)
        }
    };
    for (layout, il) in [
        (Layout::Bsq, "bsq"),
        (Layout::Bil, "bil"),
        (Layout::Bip, "bip"),
    ] {
        write(
            &dir.path().join(format!("{il}.hdr")),
            header(dims, 4, il, ""),
        );
        write(
            &dir.path().join(format!("{il}.img")),
            pack(&arrange(layout, dims, poisoned), 4, false),
        );
        for (path, mut r) in readers_for(&dir.path().join(format!("{il}.hdr"))) {
            // The chunk around the poisoned band reads and checks fine.
            let planes = r.read_bands(0, &[4, 0, 1, 3]).unwrap();
            assert_eq!(planes.len(), 4, "{il} ({path})");
            let e = r.read_bands(0, &[1, 2]).unwrap_err().to_string();
            assert!(
                e.contains("band 2 (10 µm), row 3, col 4: radiance NaN")
                    && e.contains(&format!("{il}.img")),
                "{il} ({path}): {e}"
            );
            let e = r.read_band(0, 2).unwrap_err().to_string();
            assert!(
                e.contains("band 2 (10 µm), row 3, col 4"),
                "{il} ({path}): {e}"
            );
            // The engine's read: a mapped chunk comes with the check owed, whose error is
            // the reader's own; a chunk read into memory is refused at once.
            let want = r.read_bands(0, &[1, 2]).unwrap_err().to_string();
            match r.read_planes_deferred(0, &[1, 2]) {
                Ok((planes, Some(owed))) => {
                    assert!(matches!(planes, io::BandPlanes::Mapped(_)), "{il} ({path})");
                    assert_eq!(owed.run(&planes).unwrap_err().to_string(), want);
                }
                Ok((_, None)) => panic!("{il} ({path}): a bad plane handed over as checked"),
                Err(e) => assert_eq!(e.to_string(), want, "{il} ({path})"),
            }
        }
    }
}

#[test]
fn scratch_file_is_never_visible_in_the_temporary_directory() {
    // The BIP scratch file is unlinked as soon as it is created: while the reader is open
    // and after it is dropped, the temporary directory holds nothing of this process.
    let dir = tempfile::tempdir().unwrap();
    let dims = (4, 3, 2);
    write(&dir.path().join("p.hdr"), header(dims, 4, "bip", ""));
    write(
        &dir.path().join("p.img"),
        pack(&arrange(Layout::Bip, dims, truth), 4, false),
    );
    // Other tests of this process create (and at once unlink) scratch files too: a name
    // counts only if it is still there 50 ms later.
    let mine = || -> Vec<String> {
        let tag = format!(".eoir-band-spill-{}-", std::process::id());
        let list = || -> Vec<String> {
            names(&std::env::temp_dir())
                .into_iter()
                .filter(|n| n.starts_with(&tag))
                .collect()
        };
        let first = list();
        std::thread::sleep(std::time::Duration::from_millis(50));
        let second = list();
        first.into_iter().filter(|n| second.contains(n)).collect()
    };
    let mut r = EnviReader::open(&dir.path().join("p.hdr")).unwrap();
    r.set_bip_direct_frame_bytes(0);
    // An empty request reads nothing and creates nothing; every band at once reads
    // directly; a part of the bands goes through the scratch file.
    assert!(r.read_bands(0, &[]).unwrap().is_empty());
    assert_eq!(r.read_bands(0, &[0, 1, 2, 3]).unwrap().len(), 4);
    assert!(!r.uses_scratch_file());
    assert_eq!(
        r.read_bands(0, &[3, 1]).unwrap()[1][[2, 1]],
        truth(1, 2, 1) as f32
    );
    assert!(r.uses_scratch_file());
    assert!(mine().is_empty(), "{:?}", mine());
    drop(r);
    assert!(mine().is_empty(), "{:?}", mine());
}

/// Band centres (µm) of the end-to-end cubes: multimir's filter 4 (4.55–5.2 µm) and its
/// QE cutoff (5.4 µm) give bands 0–2 and 9–10 zero spectral weight.
pub(crate) const RUN_WAVELENGTHS_UM: [f64; 11] =
    [3.0, 3.5, 4.0, 4.4, 4.6, 4.8, 5.0, 5.2, 5.4, 6.0, 7.0];
/// Rows = columns of the end-to-end cubes and of the detector.
pub(crate) const RUN_SIZE: usize = 16;

/// The radiance of band `b` at pixel (r, c) of the end-to-end cubes: 1 W m-2 sr-1 µm-1
/// everywhere, except NaN at band 1 (3.5 µm, unused) pixel (3, 4), −1 at band 10 (7 µm,
/// unused) pixel (0, 0), and, when `poison_used`, NaN at band 5 (4.8 µm) pixel (7, 2).
pub(crate) fn run_radiance(poison_used: bool) -> impl Fn(usize, usize, usize) -> f64 {
    move |b, r, c| match (b, r, c) {
        (1, 3, 4) => f64::NAN,
        (10, 0, 0) => -1.0,
        (5, 7, 2) if poison_used => f64::NAN,
        _ => 1.0,
    }
}

/// The full field of view (degrees) of the end-to-end cubes: one multimir IFOV (24 µm /
/// 100 mm) per sample.
pub(crate) fn run_fov_deg() -> f64 {
    (RUN_SIZE as f64 * 0.24e-3).to_degrees()
}

/// Runs multimir (filter 4, 100 mm optics, 16 × 16 detector, no calibration) on `reader`.
pub(crate) fn run_multimir(
    reader: &mut dyn CubeReader,
) -> eoir::error::Result<eoir::pipeline::RunOutput> {
    let n = RUN_SIZE.to_string();
    let sensor = eoir::sensor::presets::load(
        "multimir",
        &["filter=4".into(), "optics=100mm".into()],
        &[format!("detector.rows={n}"), format!("detector.cols={n}")],
    )
    .and_then(|c| eoir::sensor::Sensor::build(&c))?;
    let options = eoir::pipeline::RunOptions {
        calibration: None,
        ..Default::default()
    };
    eoir::pipeline::run(&sensor, reader, &options, |_, _| {})
}

/// Checks the outcome of [`run_multimir`] on a cube from [`run_radiance`]: the clean
/// cube runs, reports 6 of 11 bands used and warns that bands 0–2 and 9–10 were not read;
/// the poisoned one fails naming band 5 and pixel (7, 2) in `file`.
pub(crate) fn check_unread_band_runs(
    what: &str,
    clean: eoir::error::Result<eoir::pipeline::RunOutput>,
    poisoned: eoir::error::Result<eoir::pipeline::RunOutput>,
    file: &str,
) {
    let out = clean.unwrap_or_else(|e| panic!("{what}: {e}"));
    assert_eq!(
        (out.report.input.bands, out.report.input.bands_used),
        (11, 6),
        "{what}"
    );
    let w = out.report.warnings.join("\n");
    assert!(
        w.contains("5 of 11 input bands have zero sensor response and were not read")
            && w.contains("band 0–2 (3–4 µm), 9–10 (6–7 µm)"),
        "{what}: {w}"
    );
    let e = poisoned.map(|_| ()).unwrap_err().to_string();
    assert!(
        e.contains("band 5 (4.8 µm), row 7, col 2: radiance NaN") && e.contains(file),
        "{what}: {e}"
    );
}

#[test]
fn a_run_reads_and_checks_exactly_the_bands_with_sensor_response_envi_and_npy() {
    let dir = tempfile::tempdir().unwrap();
    let dims = (RUN_WAVELENGTHS_UM.len(), RUN_SIZE, RUN_SIZE);
    let wl: Vec<String> = RUN_WAVELENGTHS_UM.iter().map(|w| w.to_string()).collect();
    let fov = run_fov_deg();
    for (layout, il) in [
        (Layout::Bsq, "bsq"),
        (Layout::Bil, "bil"),
        (Layout::Bip, "bip"),
    ] {
        let mut outcomes = Vec::new();
        for poison in [false, true] {
            let stem = format!("{il}{poison}");
            let h = format!(
                "ENVI\nsamples = {n}\nlines = {n}\nbands = {}\ndata type = 4\ninterleave = {il}\nbyte order = 0\nwavelength units = Micrometers\nwavelength = {{{}}}\neoir radiance units = W m-2 sr-1 um-1\neoir fov deg = {{{fov}, {fov}}}\n",
                dims.0,
                wl.join(", "),
                n = RUN_SIZE
            );
            write(&dir.path().join(format!("{stem}.hdr")), h);
            let values = arrange(layout, dims, run_radiance(poison));
            write(
                &dir.path().join(format!("{stem}.img")),
                pack(&values, 4, false),
            );
            // BIP twice: direct and through the scratch file.
            let mut r = EnviReader::open(&dir.path().join(format!("{stem}.hdr"))).unwrap();
            r.set_bip_direct_frame_bytes(if poison { u64::MAX } else { 0 });
            outcomes.push(run_multimir(&mut r));
        }
        let poisoned = outcomes.pop().unwrap();
        let clean = outcomes.pop().unwrap();
        check_unread_band_runs(il, clean, poisoned, &format!("{il}true.img"));
    }

    // NPY ([band, row, col] f4) with its sidecar.
    let mut outcomes = Vec::new();
    for poison in [false, true] {
        let path = dir.path().join(format!("cube{poison}.npy"));
        let f = run_radiance(poison);
        let mut dict = format!(
            "{{'descr': '<f4', 'fortran_order': False, 'shape': ({}, {RUN_SIZE}, {RUN_SIZE}), }}",
            dims.0
        );
        while (10 + dict.len() + 1) % 64 != 0 {
            dict.push(' ');
        }
        dict.push('\n');
        let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
        bytes.extend((dict.len() as u16).to_le_bytes());
        bytes.extend(dict.as_bytes());
        bytes.extend(pack(&arrange(Layout::Bsq, dims, f), 4, false));
        write(&path, bytes);
        write(
            &path.with_extension("json"),
            format!(
                "{{\"wavelength_um\": [{}], \"units\": \"W m-2 sr-1 um-1\", \"fov_deg\": [{fov}, {fov}]}}",
                wl.join(", ")
            ),
        );
        outcomes.push(run_multimir(
            &mut eoir::io::npy::NpyReader::open(&path).unwrap(),
        ));
    }
    let poisoned = outcomes.pop().unwrap();
    let clean = outcomes.pop().unwrap();
    check_unread_band_runs("npy", clean, poisoned, "cubetrue.npy");
}

/// `read_planes` serves band-sequential f32 data in the machine's byte order at a
/// 4-byte-aligned offset from memory maps of the file, and everything else (other
/// layouts, types, byte order, an unaligned offset, scaled data, a `data ignore value`,
/// mapping turned off) from `read()`: either way the planes are the layout truth.
#[test]
fn read_planes_maps_exactly_the_bsq_f32_files_it_can_and_gives_the_layout_truth() {
    use eoir::io::{BandPlanes, ReadOptions};
    let dir = tempfile::tempdir().unwrap();
    let dims = (7, 6, 5);
    let native_big = cfg!(target_endian = "big");
    for (layout, il) in [
        (Layout::Bsq, "bsq"),
        (Layout::Bil, "bil"),
        (Layout::Bip, "bip"),
    ] {
        for ty in [2u32, 4, 5] {
            for big in [false, true] {
                for (offset, extra) in [
                    (40, ""),
                    (37, ""),
                    (4096, ""),
                    (40, "data gain values = {1,1,1,1,1,1,1}\n"),
                    (40, "data ignore value = -9999\n"),
                ] {
                    let stem = format!("{il}{ty}{big}{offset}{}", extra.len());
                    let spec = (layout, il, ty, big, offset);
                    let hdr = write_truth_cube(dir.path(), &stem, dims, spec, extra);
                    for no_memory_map in [false, true] {
                        let opts = ReadOptions {
                            no_memory_map,
                            ..Default::default()
                        };
                        let mut r = EnviReader::open_with(&hdr, &opts).unwrap();
                        let mappable = matches!(layout, Layout::Bsq)
                            && ty == 4
                            && big == native_big
                            && offset % 4 == 0
                            && extra.is_empty()
                            && !no_memory_map;
                        for req in REQUESTS {
                            let planes = r.read_planes(0, req).unwrap();
                            assert_eq!(
                                matches!(planes, BandPlanes::Mapped(_)),
                                mappable && !req.is_empty(),
                                "{stem} mapping off: {no_memory_map}"
                            );
                            let views = planes.views();
                            assert_eq!(views.len(), req.len());
                            for (plane, &b) in views.iter().zip(req) {
                                assert_is_truth(plane.view(), b, &stem);
                            }
                        }
                    }
                }
            }
        }
    }
}

/// A file truncated by another process while it is mapped raises SIGBUS when a page past
/// the new end is touched; the handlers `eoir` installs turn that into one line on
/// standard error, remove the unfinished product set as after SIGINT and exit with
/// status 74, instead of "Bus error" and a staging directory left behind. Run in a child process (this test's own binary, selecting itself), since the
/// process ends.
#[cfg(unix)]
#[test]
fn sigbus_on_a_truncated_mapped_file_is_one_clear_line() {
    const CHILD: &str = "EOIR_TEST_SIGBUS_CHILD";
    if let Some(dir) = std::env::var_os(CHILD) {
        let dir = PathBuf::from(dir);
        eoir::io::output::install_signal_handler().unwrap();
        eoir::io::mapped::install_sigbus_message();
        let set = eoir::io::output::ProductSet::begin(&dir.join("out")).unwrap();
        assert!(set.staging_dir().is_dir());
        let mut r = EnviReader::open(&dir.join("c.hdr")).unwrap();
        let planes = r.read_planes(0, &[1]).unwrap();
        assert!(matches!(planes, eoir::io::BandPlanes::Mapped(_)));
        std::fs::OpenOptions::new()
            .write(true)
            .open(dir.join("c.img"))
            .unwrap()
            .set_len(0)
            .unwrap();
        let sum: f32 = planes.views()[0].iter().sum();
        println!("not reached: {sum}");
        std::process::exit(0);
    }
    let dir = tempfile::tempdir().unwrap();
    // Bands of 64 KiB so that the mapped band lies wholly past the truncated end.
    let dims = (2, 128, 128);
    write(&dir.path().join("c.hdr"), header(dims, 4, "bsq", ""));
    write(
        &dir.path().join("c.img"),
        pack(&arrange(Layout::Bsq, dims, truth), 4, false),
    );
    let out = std::process::Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "io_envi::sigbus_on_a_truncated_mapped_file_is_one_clear_line",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(CHILD, dir.path())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(74), "{stderr}");
    assert!(
        stderr.contains("an input file was truncated") && stderr.contains("--no-mmap"),
        "{stderr}"
    );
    assert!(!String::from_utf8_lossy(&out.stdout).contains("not reached"));
    assert!(stderr.contains("removed unfinished outputs"), "{stderr}");
    // As after SIGINT: the staging directory is gone, nothing was written.
    // The set created `out`: the clean-up removes it with its staging directory.
    assert!(!dir.path().join("out").exists(), "{:?}", names(dir.path()));
}
