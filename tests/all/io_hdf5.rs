//! HDF5 cubes, sequences and bundles. Files are checked and, for the reader tests, written
//! with the HDF5 library directly, so reader and writer are each tested against an
//! independent path.

use std::path::Path;

use eoir::io::hdf5::{self as h5io, BundleData, BundleItem, Hdf5Reader};
use eoir::io::{read_cube, CubeReader};
use eoir::scene::{Cube, CubeMeta, Geometry, RadianceUnits};
use hdf5_metno::types::{FixedAscii, VarLenUnicode};
use hdf5_metno::File;
use ndarray::{Array2, Array3, Array4};

fn value(f: usize, b: usize, r: usize, c: usize) -> f32 {
    let k = (f * 1009 + b * 131 + r * 17 + c * 7) as f32;
    (k * 0.618_034).fract() * 10f32.powi((b % 4) as i32 - 1)
}

fn test_meta(bands: usize, rows: usize, cols: usize) -> CubeMeta {
    let wavelength_um: Vec<f64> = (0..bands).map(|b| 3.0 + 0.123_456_789 * b as f64).collect();
    CubeMeta {
        fwhm_um: Some(wavelength_um.iter().map(|w| w * 0.02).collect()),
        wavelength_um,
        units: RadianceUnits::SpectralPerUm,
        geometry: Some(Geometry {
            fov_x_deg: 5.123_456_789,
            fov_y_deg: 3.987_654_321,
            range_m: Some(2500.0),
        }),
        rows,
        cols,
    }
}

fn test_cube() -> Cube {
    let meta = test_meta(5, 6, 7);
    let data = Array3::from_shape_fn((5, 6, 7), |(b, r, c)| value(0, b, r, c));
    Cube::new(data, meta).unwrap()
}

fn put_str(loc: &hdf5_metno::Location, name: &str, v: &str) {
    let v: VarLenUnicode = v.parse().unwrap();
    loc.new_attr::<VarLenUnicode>()
        .create(name)
        .unwrap()
        .write_scalar(&v)
        .unwrap();
}

/// Writes `/radiance` with the HDF5 library directly, with only the attributes listed.
fn write_direct(path: &Path, data: &Array3<f32>, wavelength: Option<&[f64]>, units: Option<&str>) {
    let file = File::create(path).unwrap();
    let ds = file
        .new_dataset_builder()
        .with_data(data.view())
        .create("radiance")
        .unwrap();
    if let Some(w) = wavelength {
        ds.new_attr_builder()
            .with_data(w)
            .create("wavelength_um")
            .unwrap();
    }
    if let Some(u) = units {
        put_str(&ds, "units", u);
    }
}

#[test]
fn round_trip_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cube.h5");
    let cube = test_cube();
    eoir::io::write_cube(&path, &cube).unwrap();

    let mut reader = eoir::io::open(&path).unwrap();
    assert_eq!(reader.frames(), 1);
    assert_eq!(reader.frame_time_s(), None);
    assert!(reader.warnings().is_empty());
    let back = eoir::io::read_cube_frame(reader.as_mut(), 0).unwrap();
    assert_eq!(back.meta, cube.meta);
    for (a, b) in back.data.iter().zip(cube.data.iter()) {
        assert_eq!(a.to_bits(), b.to_bits());
    }

    // The layout, checked with the HDF5 library: f32 [band,row,col] and the attributes.
    let file = File::open(&path).unwrap();
    let ds = file.dataset("radiance").unwrap();
    assert_eq!(ds.shape(), vec![5, 6, 7]);
    let raw: Array3<f32> = ds.as_reader().no_convert().read().unwrap();
    assert_eq!(raw, cube.data);
    let wl = ds.attr("wavelength_um").unwrap().read_raw::<f64>().unwrap();
    assert_eq!(wl, cube.meta.wavelength_um);
    let fov = ds.attr("fov_deg").unwrap().read_raw::<f64>().unwrap();
    assert_eq!(fov, vec![5.123_456_789, 3.987_654_321]);
    let units = ds
        .attr("units")
        .unwrap()
        .read_scalar::<VarLenUnicode>()
        .unwrap();
    assert_eq!(units.as_str(), "W m-2 sr-1 um-1");
    assert_eq!(
        ds.attr("range_m").unwrap().read_scalar::<f64>().unwrap(),
        2500.0
    );
    drop(ds);
    drop(file);
    // Only the file itself in the directory: the temporary was renamed.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);

    // A cube without geometry or widths round-trips as such.
    let mut bare = test_cube();
    bare.meta.geometry = None;
    bare.meta.fwhm_um = None;
    bare.meta.units = RadianceUnits::BandIntegrated;
    let p2 = dir.path().join("bare.hdf5");
    h5io::write(&p2, &bare).unwrap();
    assert_eq!(read_cube(&p2).unwrap(), bare);
}

#[test]
fn sequence_in_frames_dataset() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("seq.h5");
    let (n, bands, rows, cols) = (3, 2, 4, 5);
    let truth = Array4::from_shape_fn((n, bands, rows, cols), |(f, b, r, c)| value(f, b, r, c));
    {
        // Written by "another tool": the HDF5 library directly, wavelengths as f32.
        let file = File::create(&path).unwrap();
        let ds = file
            .new_dataset_builder()
            .with_data(truth.view())
            .create("frames")
            .unwrap();
        ds.new_attr_builder()
            .with_data(&[8.5f32, 9.5][..])
            .create("wavelength_um")
            .unwrap();
        put_str(&ds, "units", "W m-2 sr-1 um-1");
        ds.new_attr_builder()
            .with_data(&[4.0f64, 3.2][..])
            .create("fov_deg")
            .unwrap();
        ds.new_attr::<f64>()
            .create("frame_time_s")
            .unwrap()
            .write_scalar(&0.04)
            .unwrap();
    }
    let mut reader = Hdf5Reader::open(&path).unwrap();
    assert_eq!(reader.frames(), 3);
    assert_eq!(reader.frame_time_s(), Some(0.04));
    assert_eq!(reader.meta().wavelength_um, vec![8.5, 9.5]);
    assert_eq!(reader.meta().geometry.unwrap().fov_x_deg, 4.0);
    for f in 0..n {
        for b in 0..bands {
            let p = reader.read_band(f, b).unwrap();
            assert_eq!(p, truth.slice(ndarray::s![f, b, .., ..]));
        }
    }
    let err = reader.read_band(3, 0).unwrap_err().to_string();
    assert!(err.contains("frame") && err.contains('3'), "{err}");

    // eoir's own sequence writer gives the same file content back.
    let p2 = dir.path().join("seq2.h5");
    let meta = reader.meta().clone();
    h5io::write_frames(&p2, &meta, truth.view(), Some(0.04)).unwrap();
    let mut r2 = Hdf5Reader::open(&p2).unwrap();
    assert_eq!(r2.meta(), &meta);
    assert_eq!((r2.frames(), r2.frame_time_s()), (3, Some(0.04)));
    assert_eq!(
        r2.read_band(2, 1).unwrap(),
        truth.slice(ndarray::s![2, 1, .., ..])
    );
}

#[test]
fn missing_attribute_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let data = Array3::from_elem((2, 3, 4), 1.0f32);

    let path = dir.path().join("no_wl.h5");
    write_direct(&path, &data, None, Some("W m-2 sr-1 um-1"));
    let err = Hdf5Reader::open(&path).err().unwrap().to_string();
    assert!(
        err.contains("`wavelength_um`") && err.contains("no_wl.h5"),
        "{err}"
    );

    let path = dir.path().join("no_units.h5");
    write_direct(&path, &data, Some(&[1.0, 2.0]), None);
    let err = Hdf5Reader::open(&path).err().unwrap().to_string();
    assert!(err.contains("`units`"), "{err}");

    let path = dir.path().join("bad_units.h5");
    write_direct(&path, &data, Some(&[1.0, 2.0]), Some("furlongs"));
    let err = Hdf5Reader::open(&path).err().unwrap().to_string();
    assert!(err.contains("furlongs"), "{err}");

    let path = dir.path().join("count.h5");
    write_direct(&path, &data, Some(&[1.0, 2.0, 3.0]), Some("W m-2 sr-1"));
    let err = Hdf5Reader::open(&path).err().unwrap().to_string();
    assert!(err.contains("3 values") && err.contains("2 bands"), "{err}");

    let path = dir.path().join("empty.h5");
    File::create(&path).unwrap();
    let err = Hdf5Reader::open(&path).err().unwrap().to_string();
    assert!(
        err.contains("/radiance") && err.contains("/frames"),
        "{err}"
    );
}

#[test]
fn fixed_length_string_attribute_is_read() {
    // numpy byte strings arrive as fixed-length ASCII.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fixed.h5");
    let data = Array3::from_elem((1, 2, 2), 0.5f32);
    write_direct(&path, &data, Some(&[10.0]), None);
    {
        let file = File::open_rw(&path).unwrap();
        let ds = file.dataset("radiance").unwrap();
        let v = FixedAscii::<10>::from_ascii(b"W m-2 sr-1").unwrap();
        ds.new_attr::<FixedAscii<10>>()
            .create("units")
            .unwrap()
            .write_scalar(&v)
            .unwrap();
    }
    let r = Hdf5Reader::open(&path).unwrap();
    assert_eq!(r.meta().units, RadianceUnits::BandIntegrated);
}

#[test]
fn nan_radiance_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nan.h5");
    let mut data = Array3::from_elem((2, 3, 4), 1.0f32);
    data[[1, 2, 1]] = f32::NAN;
    write_direct(&path, &data, Some(&[1.0, 2.0]), Some("W m-2 sr-1 um-1"));
    let mut r = Hdf5Reader::open(&path).unwrap();
    assert!(r.read_band(0, 0).is_ok());
    let err = r.read_band(0, 1).unwrap_err().to_string();
    assert!(
        err.contains("NaN") && err.contains("band 1") && err.contains("row 2, col 1"),
        "{err}"
    );

    // The writer refuses to create such a file.
    let mut cube = test_cube();
    cube.data[[0, 0, 0]] = -2.0;
    let out = dir.path().join("refused.h5");
    let err = h5io::write(&out, &cube).unwrap_err().to_string();
    assert!(err.contains("-2"), "{err}");
    assert!(!out.exists());
}

#[test]
fn bundle_is_readable_back() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bundle.h5");
    let dn = Array2::from_shape_fn((4, 6), |(r, c)| (r * 1000 + c * 7 + 60000) as u16);
    let temp = Array2::from_shape_fn((4, 6), |(r, c)| 290.0 + r as f32 * 0.25 - c as f32);
    let mut electrons = Array2::from_elem((4, 6), 1.5e4f32);
    electrons[[0, 0]] = f32::NAN; // products may carry NaN (e.g. failed inversions)
    let products = [
        BundleItem {
            name: "dn",
            data: BundleData::U16(dn.view()),
            attrs: vec![("units", "DN".to_string())],
        },
        BundleItem {
            name: "temperature",
            data: BundleData::F32(temp.view()),
            attrs: vec![
                ("units", "K".to_string()),
                ("method", "apparent".to_string()),
            ],
        },
        BundleItem {
            name: "electrons_mean",
            data: BundleData::F32(electrons.t()), // non-standard layout on purpose
            attrs: vec![],
        },
    ];
    h5io::write_bundle(
        &path,
        &products,
        &[
            ("sensor", "LWIR test".to_string()),
            ("seed", "42".to_string()),
        ],
    )
    .unwrap();

    let file = File::open(&path).unwrap();
    let ds = file.dataset("dn").unwrap();
    let back: Array2<u16> = ds.as_reader().no_convert().read_2d().unwrap();
    assert_eq!(back, dn);
    let units = ds
        .attr("units")
        .unwrap()
        .read_scalar::<VarLenUnicode>()
        .unwrap();
    assert_eq!(units.as_str(), "DN");
    let t: Array2<f32> = file
        .dataset("temperature")
        .unwrap()
        .as_reader()
        .no_convert()
        .read_2d()
        .unwrap();
    assert_eq!(t, temp);
    let method = file
        .dataset("temperature")
        .unwrap()
        .attr("method")
        .unwrap()
        .read_scalar::<VarLenUnicode>()
        .unwrap();
    assert_eq!(method.as_str(), "apparent");
    let e: Array2<f32> = file.dataset("electrons_mean").unwrap().read_2d().unwrap();
    assert_eq!(e.dim(), (6, 4));
    assert!(e[[0, 0]].is_nan());
    assert_eq!(e[[5, 3]], 1.5e4);
    let seed = file
        .attr("seed")
        .unwrap()
        .read_scalar::<VarLenUnicode>()
        .unwrap();
    assert_eq!(seed.as_str(), "42");
    let sensor = file
        .attr("sensor")
        .unwrap()
        .read_scalar::<VarLenUnicode>()
        .unwrap();
    assert_eq!(sensor.as_str(), "LWIR test");

    // Duplicate product names are refused before anything is written.
    let dup = [
        BundleItem {
            name: "dn",
            data: BundleData::U16(dn.view()),
            attrs: vec![],
        },
        BundleItem {
            name: "dn",
            data: BundleData::U16(dn.view()),
            attrs: vec![],
        },
    ];
    let out = dir.path().join("dup.h5");
    let err = h5io::write_bundle(&out, &dup, &[]).unwrap_err().to_string();
    assert!(err.contains("dn"), "{err}");
    assert!(!out.exists());
}
