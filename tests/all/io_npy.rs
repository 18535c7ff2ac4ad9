//! NPY reader/writer tests. Truth for the file layout comes from an independent NPY
//! implementation (the `ndarray-npy` crate) and from files built byte by byte here after
//! the NPY format specification (magic, version, little-endian header length, dict).

use std::fs::File;
use std::path::Path;

use eoir::io::npy::{self, NpyReader, Sidecar};
use eoir::io::{self, CubeReader};
use eoir::scene::{Cube, CubeMeta, Geometry, RadianceUnits};
use ndarray::{Array3, Array4};
use ndarray_npy::{ReadNpyExt, WriteNpyExt};

fn value(f: usize, b: usize, r: usize, c: usize) -> f64 {
    (10000 * f + 1000 * b + 10 * r + c) as f64
}

fn test_cube() -> Cube {
    let mut s = 12345u32;
    let data = Array3::from_shape_simple_fn((3, 4, 6), || {
        s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (s >> 8) as f32 / 1024.0
    });
    let meta = CubeMeta {
        wavelength_um: vec![0.45, 0.55, 0.65],
        fwhm_um: Some(vec![0.05, 0.051, 0.052]),
        units: RadianceUnits::SpectralPerUm,
        geometry: Some(Geometry {
            fov_x_deg: 3.3,
            fov_y_deg: 2.2,
            range_m: Some(1.0e4),
        }),
        rows: 4,
        cols: 6,
    };
    Cube::new(data, meta).unwrap()
}

/// An NPY file after the format specification, with the dictionary text as given.
fn npy_bytes(version: u8, dict: &str, data: &[u8]) -> Vec<u8> {
    let len_bytes = if version == 1 { 2 } else { 4 };
    let mut d = dict.to_string();
    while (8 + len_bytes + d.len() + 1) % 64 != 0 {
        d.push(' ');
    }
    d.push('\n');
    let mut out = b"\x93NUMPY".to_vec();
    out.extend([version, 0]);
    if version == 1 {
        out.extend((d.len() as u16).to_le_bytes());
    } else {
        out.extend((d.len() as u32).to_le_bytes());
    }
    out.extend(d.as_bytes());
    out.extend(data);
    out
}

fn sidecar(path: &Path, json: &str) {
    std::fs::write(path.with_extension("json"), json).unwrap();
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
    match NpyReader::open(path) {
        Ok(_) => panic!("{} opened but should not", path.display()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn round_trip_is_bit_exact_and_readable_by_ndarray_npy() {
    let dir = tempfile::tempdir().unwrap();
    let cube = test_cube();
    let p = dir.path().join("cube.npy");
    io::write_cube(&p, &cube).unwrap();
    assert_eq!(names(dir.path()), ["cube.json", "cube.npy"]);

    // An independent NPY reader sees the same array.
    let other = Array3::<f32>::read_npy(File::open(&p).unwrap()).unwrap();
    assert!(other
        .iter()
        .zip(cube.data.iter())
        .all(|(a, b)| a.to_bits() == b.to_bits()));
    // Data starts on a 64-byte boundary, as the specification recommends.
    let len = std::fs::metadata(&p).unwrap().len();
    assert_eq!((len - 3 * 4 * 6 * 4) % 64, 0);

    let sc: Sidecar =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("cube.json")).unwrap())
            .unwrap();
    assert_eq!(sc.wavelength_um, cube.meta.wavelength_um);
    assert_eq!(sc.units.as_deref(), Some("W m-2 sr-1 um-1"));
    assert_eq!(sc.fov_deg, Some([3.3, 2.2]));

    let back = io::read_cube(&p).unwrap();
    assert_eq!(back.meta, cube.meta);
    assert!(back
        .data
        .iter()
        .zip(cube.data.iter())
        .all(|(a, b)| a.to_bits() == b.to_bits()));
    let r = NpyReader::open(&p).unwrap();
    assert!(r.warnings().is_empty(), "{:?}", r.warnings());
    assert_eq!((r.frames(), r.frame_time_s()), (1, None));
}

#[test]
fn files_written_by_ndarray_npy_f64_and_4d_sequences() {
    let dir = tempfile::tempdir().unwrap();
    // float64 [band, row, col].
    let a = Array3::from_shape_fn((2, 3, 5), |(b, r, c)| value(0, b, r, c) + 0.25);
    let p = dir.path().join("d.npy");
    a.write_npy(File::create(&p).unwrap()).unwrap();
    sidecar(&p, r#"{"wavelength_um": [8, 9], "units": "W m-2 sr-1"}"#);
    let cube = io::read_cube(&p).unwrap();
    assert_eq!(cube.meta.units, RadianceUnits::BandIntegrated);
    for ((b, r, c), v) in cube.data.indexed_iter() {
        assert_eq!(f64::from(*v), value(0, b, r, c) + 0.25);
    }

    // float32 [frame, band, row, col] with a frame time.
    let s = Array4::from_shape_fn((3, 2, 2, 4), |(f, b, r, c)| value(f, b, r, c) as f32);
    let p = dir.path().join("seq.npy");
    s.write_npy(File::create(&p).unwrap()).unwrap();
    sidecar(
        &p,
        r#"{"wavelength_um": [8, 9], "frame_time_s": 0.02, "ifov_rad": [1e-3, 1e-3], "range_m": 50}"#,
    );
    let mut r = NpyReader::open(&p).unwrap();
    assert_eq!((r.frames(), r.frame_time_s()), (3, Some(0.02)));
    let g = r.meta().geometry.unwrap();
    assert!((g.fov_x_deg - 0.004f64.to_degrees()).abs() < 1e-12);
    assert!((g.fov_y_deg - 0.002f64.to_degrees()).abs() < 1e-12);
    assert_eq!(g.range_m, Some(50.0));
    assert!(
        r.warnings().iter().any(|w| w.contains("no `units`")),
        "{:?}",
        r.warnings()
    );
    for f in [2, 0, 1] {
        for b in [1, 0] {
            let plane = r.read_band(f, b).unwrap();
            for ((row, col), v) in plane.indexed_iter() {
                assert_eq!(f64::from(*v), value(f, b, row, col));
            }
        }
    }
    assert!(r
        .read_band(3, 0)
        .unwrap_err()
        .to_string()
        .contains("frame 3"));
    assert!(r
        .read_band(0, 2)
        .unwrap_err()
        .to_string()
        .contains("band 2"));
}

#[test]
fn hand_built_dtypes_and_header_versions() {
    let dir = tempfile::tempdir().unwrap();
    let (nb, nr, nc) = (2usize, 2usize, 3usize);
    let vals: Vec<f64> = (0..nb * nr * nc)
        .map(|i| value(0, i / (nr * nc), (i / nc) % nr, i % nc))
        .collect();
    type Enc = fn(f64) -> Vec<u8>;
    let cases: [(u8, &str, Enc); 8] = [
        (1, "<f4", |v| (v as f32).to_le_bytes().to_vec()),
        (1, ">f4", |v| (v as f32).to_be_bytes().to_vec()),
        (2, "<f8", |v| v.to_le_bytes().to_vec()),
        (3, ">f8", |v| v.to_be_bytes().to_vec()),
        (1, "<u2", |v| (v as u16).to_le_bytes().to_vec()),
        (1, ">u2", |v| (v as u16).to_be_bytes().to_vec()),
        (1, "<i2", |v| (v as i16).to_le_bytes().to_vec()),
        (2, ">i2", |v| (v as i16).to_be_bytes().to_vec()),
    ];
    for (i, (version, descr, enc)) in cases.iter().enumerate() {
        let data: Vec<u8> = vals.iter().flat_map(|v| enc(*v)).collect();
        // Vary the dictionary's spelling: key order, quotes, Python 2 long suffixes.
        let dict = match i % 3 {
            0 => format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': ({nb}, {nr}, {nc}), }}"),
            1 => format!("{{\"shape\": ({nb}L, {nr}L, {nc}L), \"fortran_order\": False, \"descr\": \"{descr}\"}}"),
            _ => format!("{{'fortran_order':False,'descr':'{descr}','shape':({nb},{nr},{nc})}}"),
        };
        let p = dir.path().join(format!("h{i}.npy"));
        std::fs::write(&p, npy_bytes(*version, &dict, &data)).unwrap();
        sidecar(
            &p,
            r#"{"wavelength_um": [3.9, 4.1], "units": "W m-2 sr-1 um-1"}"#,
        );
        let cube = io::read_cube(&p).unwrap_or_else(|e| panic!("{descr} v{version}: {e}"));
        for ((b, r, c), v) in cube.data.indexed_iter() {
            assert_eq!(f64::from(*v), value(0, b, r, c), "{descr} v{version}");
        }
    }
}

#[test]
fn decreasing_wavelengths_are_reversed() {
    let dir = tempfile::tempdir().unwrap();
    let a = Array3::from_shape_fn((3, 2, 2), |(b, r, c)| value(0, b, r, c) as f32);
    let p = dir.path().join("rev.npy");
    a.write_npy(File::create(&p).unwrap()).unwrap();
    sidecar(
        &p,
        r#"{"wavelength_um": [12, 10, 8], "fwhm_um": [0.3, 0.2, 0.1], "units": "W m-2 sr-1 um-1"}"#,
    );
    let cube = io::read_cube(&p).unwrap();
    assert_eq!(cube.meta.wavelength_um, vec![8.0, 10.0, 12.0]);
    assert_eq!(cube.meta.fwhm_um, Some(vec![0.1, 0.2, 0.3]));
    for ((b, r, c), v) in cube.data.indexed_iter() {
        assert_eq!(f64::from(*v), value(0, 2 - b, r, c));
    }
}

#[test]
fn fortran_order_is_one_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("f.npy");
    let data = vec![0u8; 2 * 2 * 2 * 4];
    std::fs::write(
        &p,
        npy_bytes(
            1,
            "{'descr': '<f4', 'fortran_order': True, 'shape': (2, 2, 2), }",
            &data,
        ),
    )
    .unwrap();
    sidecar(&p, r#"{"wavelength_um": [8, 9]}"#);
    let e = open_err(&p);
    assert!(
        e.contains("Fortran") && e.contains("C order") && e.contains("f.npy"),
        "{e}"
    );
}

#[test]
fn missing_or_wrong_sidecar_names_the_file_and_what_it_needs() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("lone.npy");
    Array3::<f32>::ones((2, 2, 2))
        .write_npy(File::create(&p).unwrap())
        .unwrap();
    let e = open_err(&p);
    assert!(
        e.contains("lone.json")
            && e.contains("is missing")
            && e.contains("{\"wavelength_um\": [8, 9]}"),
        "{e}"
    );

    for (json, needle) in [
        (r#"{"fwhm_um": [1, 1]}"#, "missing field `wavelength_um`"),
        (
            r#"{"wavelength_um": [8, 9, 10]}"#,
            "wavelength_um has 3 values but the array has 2 bands",
        ),
        (
            r#"{"wavelength_um": [8, 9], "fwhm_um": [1]}"#,
            "fwhm_um has 1 values",
        ),
        (
            r#"{"wavelength_um": [9, 9]}"#,
            "strictly increasing or strictly decreasing",
        ),
        (
            r#"{"wavelength_um": [8, 9], "units": "lux"}"#,
            "units = `lux`",
        ),
        (
            r#"{"wavelength_um": [8, 9], "fov_deg": [1, 1], "ifov_rad": [1e-3, 1e-3]}"#,
            "only one",
        ),
        (
            r#"{"wavelength_um": [8, 9], "fov_deg": [200, 1]}"#,
            "(0, 180)",
        ),
        (
            r#"{"wavelength_um": [8, 9], "frame_time_s": 0}"#,
            "frame_time_s = 0",
        ),
        (r#"{"wavelength_um": [8, -9]}"#, "wavelength[1] = -9"),
    ] {
        sidecar(&p, json);
        let e = open_err(&p);
        assert!(
            e.contains(needle) && e.contains("lone.json"),
            "expected `{needle}` in: {e}"
        );
    }
}

#[test]
fn truncated_oversized_and_unsupported_files() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("t.npy");
    sidecar(&p, r#"{"wavelength_um": [8, 9]}"#);
    let dict = "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3, 4), }";
    let full = npy_bytes(1, dict, &[0u8; 96]);
    let header = full.len() - 96;

    std::fs::write(&p, &full[..full.len() - 5]).unwrap();
    let e = open_err(&p);
    assert!(
        e.contains("truncated")
            && e.contains(&format!("{} bytes", full.len()))
            && e.contains(&format!("{} bytes", full.len() - 5)),
        "{e}"
    );

    let mut long = full.clone();
    long.extend([0u8; 8]);
    std::fs::write(&p, &long).unwrap();
    let e = open_err(&p);
    assert!(
        e.contains(&format!("header says {} bytes", full.len()))
            && e.contains(&format!("file has {} bytes", full.len() + 8)),
        "{e}"
    );

    // The header itself cut short.
    std::fs::write(&p, &full[..header / 2]).unwrap();
    assert!(open_err(&p).contains("truncated"));

    for (dict, needle) in [
        (
            "{'descr': '<c8', 'fortran_order': False, 'shape': (2, 3, 4), }",
            "dtype `<c8` is not supported",
        ),
        (
            "{'descr': '|u1', 'fortran_order': False, 'shape': (2, 3, 4), }",
            "dtype `|u1` is not supported",
        ),
        (
            "{'descr': [('a', '<f4')], 'fortran_order': False, 'shape': (2, 3, 4), }",
            "structured",
        ),
        (
            "{'descr': '<f4', 'fortran_order': False, 'shape': (6, 16), }",
            "expected [band, row, col] or [frame, band, row, col]",
        ),
        (
            "{'descr': '<f4', 'fortran_order': False, 'shape': (0, 2, 3, 4), }",
            "zero-length",
        ),
        (
            "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3, 4) ",
            "cannot parse the NPY header",
        ),
    ] {
        std::fs::write(&p, npy_bytes(1, dict, &[0u8; 96])).unwrap();
        let e = open_err(&p);
        assert!(e.contains(needle), "expected `{needle}` in: {e}");
    }

    let mut wrong_magic = full.clone();
    wrong_magic[1] = b'X';
    std::fs::write(&p, &wrong_magic).unwrap();
    assert!(open_err(&p).contains("not a NumPy .npy file"));
    let mut v9 = full;
    v9[6] = 9;
    std::fs::write(&p, &v9).unwrap();
    assert!(open_err(&p).contains("version 9.0 is not supported"));
}

#[test]
fn nan_inf_and_negative_radiance_name_the_band() {
    let dir = tempfile::tempdir().unwrap();
    let mut a = Array3::<f32>::ones((4, 2, 3));
    a[[1, 0, 2]] = f32::NAN;
    a[[2, 1, 1]] = f32::NEG_INFINITY;
    a[[3, 1, 0]] = -2.0;
    let p = dir.path().join("bad.npy");
    a.write_npy(File::create(&p).unwrap()).unwrap();
    sidecar(
        &p,
        r#"{"wavelength_um": [1, 2, 3, 4], "units": "W m-2 sr-1 um-1"}"#,
    );
    let mut r = NpyReader::open(&p).unwrap();
    assert!(r.read_band(0, 0).is_ok());
    assert!(matches!(
        r.read_planes(0, &[0]).unwrap(),
        eoir::io::BandPlanes::Mapped(_)
    ));
    for (b, needle) in [
        (1, "band 1 (2 µm), row 0, col 2: radiance NaN"),
        (2, "band 2 (3 µm), row 1, col 1: radiance -inf"),
        (3, "band 3 (4 µm), row 1, col 0: radiance -2"),
    ] {
        let e = r.read_band(0, b).unwrap_err().to_string();
        // A memory-mapped plane is checked the same way, with the same message.
        assert_eq!(r.read_planes(0, &[0, b]).unwrap_err().to_string(), e);
        assert!(e.contains(needle) && e.contains("bad.npy"), "{e}");
    }
}

#[test]
fn failed_write_leaves_no_file_behind() {
    let dir = tempfile::tempdir().unwrap();
    let cube = test_cube();
    // The sidecar cannot be put in place: the array must not stay behind either.
    std::fs::create_dir(dir.path().join("c.json")).unwrap();
    let e = npy::write(&dir.path().join("c.npy"), &cube).unwrap_err();
    assert!(e.to_string().contains("c.json"), "{e}");
    assert_eq!(names(dir.path()), ["c.json"]);
    // A directory that does not exist.
    assert!(npy::write(&dir.path().join("nope/c.npy"), &cube).is_err());
    assert_eq!(names(dir.path()), ["c.json"]);
    // An existing good pair is left as it was when a later write fails before writing.
    npy::write(&dir.path().join("ok.npy"), &cube).unwrap();
    let before = std::fs::read(dir.path().join("ok.npy")).unwrap();
    let mut broken = cube.clone();
    broken.meta.cols = 99;
    assert!(npy::write(&dir.path().join("ok.npy"), &broken)
        .unwrap_err()
        .to_string()
        .contains("cube shape"));
    assert_eq!(std::fs::read(dir.path().join("ok.npy")).unwrap(), before);
    assert_eq!(names(dir.path()), ["c.json", "ok.json", "ok.npy"]);
}

#[test]
fn documented_sidecar_example_is_accepted() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("scene.npy");
    Array4::<f32>::ones((2, 2, 3, 4))
        .write_npy(File::create(&p).unwrap())
        .unwrap();
    // The full sidecar of the module documentation and the README.
    sidecar(
        &p,
        r#"{
  "wavelength_um": [8.5, 10.5],
  "fwhm_um": [1.0, 1.0],
  "units": "W m-2 sr-1 um-1",
  "fov_deg": [10.0, 7.5],
  "range_m": 1000.0,
  "frame_time_s": 0.02
}"#,
    );
    let r = NpyReader::open(&p).unwrap();
    assert!(r.warnings().is_empty(), "{:?}", r.warnings());
    assert_eq!((r.frames(), r.frame_time_s()), (2, Some(0.02)));
    let g = r.meta().geometry.unwrap();
    assert_eq!(
        (g.fov_x_deg, g.fov_y_deg, g.range_m),
        (10.0, 7.5, Some(1000.0))
    );
    // And the minimal one.
    sidecar(&p, r#"{"wavelength_um": [8.5, 10.5]}"#);
    let r = NpyReader::open(&p).unwrap();
    assert_eq!(r.meta().geometry, None);
    assert_eq!(r.warnings().len(), 1);
}

#[test]
fn chunked_reads_of_planes_larger_than_one_read_block_are_exact() {
    // A big-endian f8 sequence [2 frames, 3 bands, 600, 1000]: each plane is 4.8 MB, more
    // than the reader's 4 MiB read block, so a plane arrives in two reads. Any chunk of
    // bands, unsorted, repeated or empty, gives the stored values exactly.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.npy");
    let (nf, nb, nr, nc) = (2, 3, 600, 1000);
    let v = |f: usize, b: usize, r: usize, c: usize| {
        (f * 7 + b) as f64 * 1e6 + (r * nc + c) as f64 * 0.5
    };
    let mut data = Vec::with_capacity(nf * nb * nr * nc * 8);
    for f in 0..nf {
        for b in 0..nb {
            for r in 0..nr {
                for c in 0..nc {
                    data.extend(v(f, b, r, c).to_be_bytes());
                }
            }
        }
    }
    let dict =
        format!("{{'descr': '>f8', 'fortran_order': False, 'shape': ({nf}, {nb}, {nr}, {nc}), }}");
    std::fs::write(&path, npy_bytes(1, &dict, &data)).unwrap();
    sidecar(
        &path,
        r#"{"wavelength_um": [1.0, 2.0, 3.0], "units": "W m-2 sr-1 um-1"}"#,
    );
    let mut r = NpyReader::open(&path).unwrap();
    for frame in [1, 0] {
        for req in [&[0usize, 1, 2][..], &[2, 0], &[1, 1], &[]] {
            let planes = r.read_bands(frame, req).unwrap();
            assert_eq!(planes.len(), req.len());
            for (plane, &b) in planes.iter().zip(req) {
                for (rr, cc) in [
                    (0, 0),
                    (0, nc - 1),
                    (299, 500),
                    (524, 287),
                    (nr - 1, nc - 1),
                ] {
                    assert_eq!(
                        plane[[rr, cc]],
                        v(frame, b, rr, cc) as f32,
                        "frame {frame} band {b} ({rr},{cc})"
                    );
                }
                let want: Vec<f32> = (0..nr * nc)
                    .map(|i| v(frame, b, i / nc, i % nc) as f32)
                    .collect();
                assert!(
                    plane.iter().zip(&want).all(|(a, w)| a == w),
                    "frame {frame} band {b}"
                );
            }
        }
    }
}

/// `read_planes` serves `<f4` data (the machine's byte order on little-endian hosts) in
/// eoir's units from memory maps of the file, frames and bands alike, and `>f4`, `<f8`,
/// integer data, a unit conversion or mapping turned off from `read()`: the same values
/// either way.
#[test]
fn read_planes_maps_native_f32_in_eoir_units_and_reads_the_rest() {
    use eoir::io::{BandPlanes, ReadOptions};
    let dir = tempfile::tempdir().unwrap();
    let (nf, nb, nr, nc) = (2usize, 3usize, 4usize, 5usize);
    let vals: Vec<f64> = (0..nf * nb * nr * nc)
        .map(|i| {
            value(
                i / (nb * nr * nc),
                (i / (nr * nc)) % nb,
                (i / nc) % nr,
                i % nc,
            )
        })
        .collect();
    type Enc = fn(f64) -> Vec<u8>;
    let native_big = cfg!(target_endian = "big");
    let cases: [(&str, Enc, &str, bool); 5] = [
        (
            "<f4",
            |v| (v as f32).to_le_bytes().to_vec(),
            "W m-2 sr-1 um-1",
            !native_big,
        ),
        (
            ">f4",
            |v| (v as f32).to_be_bytes().to_vec(),
            "W m-2 sr-1 um-1",
            native_big,
        ),
        (
            "<f8",
            |v| v.to_le_bytes().to_vec(),
            "W m-2 sr-1 um-1",
            false,
        ),
        (
            "<u2",
            |v| (v as u16).to_le_bytes().to_vec(),
            "W m-2 sr-1 um-1",
            false,
        ),
        // µW cm⁻² sr⁻¹ nm⁻¹ → W m⁻² sr⁻¹ µm⁻¹ is × 10: scaled, so read.
        (
            "<f4",
            |v| (v as f32).to_le_bytes().to_vec(),
            "uW cm-2 sr-1 nm-1",
            false,
        ),
    ];
    for (i, (descr, enc, units, mappable)) in cases.iter().enumerate() {
        let data: Vec<u8> = vals.iter().flat_map(|v| enc(*v)).collect();
        let dict = format!(
            "{{'descr': '{descr}', 'fortran_order': False, 'shape': ({nf}, {nb}, {nr}, {nc}), }}"
        );
        let p = dir.path().join(format!("m{i}.npy"));
        std::fs::write(&p, npy_bytes(1, &dict, &data)).unwrap();
        sidecar(
            &p,
            &format!(r#"{{"wavelength_um": [3.9, 4.0, 4.1], "units": "{units}"}}"#),
        );
        let k = if units.starts_with("uW") { 10.0 } else { 1.0 };
        for no_memory_map in [false, true] {
            let opts = ReadOptions {
                no_memory_map,
                ..Default::default()
            };
            let mut r = NpyReader::open_with(&p, &opts).unwrap();
            for f in [1, 0] {
                let planes = r.read_planes(f, &[2, 0, 1]).unwrap();
                assert_eq!(
                    matches!(planes, BandPlanes::Mapped(_)),
                    *mappable && !no_memory_map,
                    "{descr} {units} mapping off: {no_memory_map}"
                );
                for (view, b) in planes.views().iter().zip([2, 0, 1]) {
                    for ((row, col), v) in view.indexed_iter() {
                        assert_eq!(f64::from(*v), k * value(f, b, row, col), "{descr} {units}");
                    }
                }
            }
            assert!(r
                .read_planes(2, &[0])
                .unwrap_err()
                .to_string()
                .contains("frame 2"));
            assert!(r
                .read_planes(0, &[3])
                .unwrap_err()
                .to_string()
                .contains("band 3"));
        }
    }
}
