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

/// HDF5 file options as eoir uses them: without HDF5's file lock (libhdf5 refuses to open
/// a file twice in one process with different locking flags).
fn unlocked() -> hdf5_metno::FileBuilder {
    let mut b = File::with_options();
    b.with_fapl(|p| p.file_locking(false));
    b
}

/// Opens a file the test has just written. HDF5 locks its files with `flock` and opens them
/// without close-on-exec, so an `eoir` child spawned at that moment by a test running in
/// parallel inherits the descriptor, and with it the lock, until it exits: the open is
/// retried for a few seconds while the file is locked.
fn open_locked(path: &Path, open: impl Fn(&Path) -> hdf5_metno::Result<File>) -> File {
    let start = std::time::Instant::now();
    loop {
        match open(path) {
            Ok(f) => return f,
            Err(e)
                if e.to_string().contains("unable to lock file")
                    && start.elapsed() < std::time::Duration::from_secs(20) =>
            {
                std::thread::sleep(std::time::Duration::from_millis(50))
            }
            Err(e) => panic!("{}: {e}", path.display()),
        }
    }
}

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
    let file = unlocked().create(path).unwrap();
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
    let file = open_locked(&path, |p| unlocked().open(p));
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
        let file = unlocked().create(&path).unwrap();
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
    unlocked().create(&path).unwrap();
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
        let file = open_locked(&path, |p| unlocked().open_rw(p));
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

    let file = open_locked(&path, |p| unlocked().open(p));
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

// ---------------------------------------------------------------------------------------
// The shared metadata path (issue 8 / 12): units through the one unit parser, the field
// of view from `fov_deg` / `ifov_rad` / `fov`, `--radiance-units`, extra attributes as
// warnings, the wavelength checks of every reader.

/// The third-party fixtures' field of view (44 x 36 samples of 120 µrad; see
/// tests/fixtures/third_party/make_fixtures.py).
const FIXTURE_FOV_DEG: [f64; 2] = [0.30252171582907467, 0.24751776749651563];

fn fixture(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/third_party")
        .join(name)
}

/// MultimIR with a 16 x 20 detector (inside the fixtures' field of view).
fn small_sensor() -> eoir::sensor::Sensor {
    eoir::sensor::presets::load(
        "multimir",
        &[],
        &["detector.rows=16".into(), "detector.cols=20".into()],
    )
    .and_then(|c| eoir::sensor::Sensor::build(&c))
    .unwrap()
}

fn mean_electrons(reader: &mut dyn CubeReader) -> Array2<f32> {
    let opts = eoir::pipeline::RunOptions::default();
    let out = eoir::pipeline::run(&small_sensor(), reader, &opts, |_, _| {}).unwrap();
    out.frames[0].electrons_mean.clone()
}

fn worst_relative(a: &Array2<f32>, b: &Array2<f32>) -> f32 {
    assert_eq!(a.dim(), b.dim());
    a.iter()
        .zip(b.iter())
        .map(|(x, y)| ((x - y) / y).abs())
        .fold(0.0f32, f32::max)
}

/// h5py_nm.h5 (written by h5py: values per nm, `units` a numpy byte string, `fov = [h, v]`,
/// wavelengths in decreasing order, two foreign attributes) gives the electrons of the
/// per-µm ENVI cube (SPy) with no extra flags.
#[test]
fn h5py_cube_with_fov_and_per_nm_units_gives_the_envi_electrons() {
    let mut h5 = eoir::io::open(&fixture("h5py_nm.h5")).unwrap();
    let m = h5.meta().clone();
    assert_eq!(m.units, RadianceUnits::SpectralPerUm);
    let g = m.geometry.expect("geometry from `fov`");
    assert!((g.fov_x_deg - FIXTURE_FOV_DEG[0]).abs() < 1e-15, "{g:?}");
    assert!((g.fov_y_deg - FIXTURE_FOV_DEG[1]).abs() < 1e-15, "{g:?}");
    assert!(m.wavelength_um.windows(2).all(|w| w[1] > w[0]));
    let source = h5.units_source();
    assert!(
        source.starts_with("stated:") && source.contains("nm-1") && source.contains("1000"),
        "{source}"
    );
    let w = h5.warnings();
    for key in ["`description`", "`instrument_id`", "decreasing order"] {
        assert!(w.iter().any(|x| x.contains(key)), "{key}: {w:?}");
    }

    let mut envi = eoir::io::open(&fixture("envi_bsq.hdr")).unwrap();
    assert_eq!(envi.meta().wavelength_um.len(), m.wavelength_um.len());
    for (a, b) in envi.meta().wavelength_um.iter().zip(&m.wavelength_um) {
        assert!((a - b).abs() < 1e-12, "{a} vs {b}");
    }
    // The values, converted to W m-2 sr-1 µm-1 and put in increasing order, are the
    // ENVI file's to float32 rounding.
    for b in 0..m.bands() {
        let x = h5.read_band(0, b).unwrap();
        let y = envi.read_band(0, b).unwrap();
        assert!(worst_relative(&x, &y) < 1e-6, "band {b}");
    }
    let e_h5 = mean_electrons(h5.as_mut());
    let e_envi = mean_electrons(envi.as_mut());
    let mean = e_envi.iter().map(|v| *v as f64).sum::<f64>() / e_envi.len() as f64;
    assert!(mean > 1e6, "{mean} e-");
    let worst = worst_relative(&e_h5, &e_envi);
    assert!(worst < 1e-3, "relative difference {worst}");
}

/// The CLI runs the h5py file with no extra flags and records where the units came from.
#[test]
fn cli_runs_the_h5py_cube_with_no_extra_flags() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_eoir"))
        .args(["run", "--quiet", "--set", "detector.rows=16", "--set"])
        .arg("detector.cols=20")
        .arg(fixture("h5py_nm.h5"))
        .arg("-o")
        .arg(&out_dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("report.json")).unwrap())
            .unwrap();
    let source = report["input"]["units_source"].as_str().unwrap();
    assert!(
        source.starts_with("stated:") && source.contains("nm-1"),
        "{source}"
    );
}

/// Writes `/radiance` (2 bands, 3 x 4) with `wavelength_um` and the given extra attributes.
fn write_with(
    path: &Path,
    wavelength: &[f64],
    f64_attrs: &[(&str, &[f64])],
    strs: &[(&str, &str)],
) {
    let data = Array3::from_shape_fn((wavelength.len(), 3, 4), |(b, r, c)| {
        1.0 + b as f32 + 0.1 * r as f32 + 0.01 * c as f32
    });
    write_direct(path, &data, Some(wavelength), None);
    let file = open_locked(path, |p| unlocked().open_rw(p));
    let ds = file.dataset("radiance").unwrap();
    for (name, v) in f64_attrs {
        ds.new_attr_builder().with_data(*v).create(*name).unwrap();
    }
    for (name, v) in strs {
        put_str(&ds, name, v);
    }
}

#[test]
fn units_go_through_the_one_parser_and_the_override() {
    let dir = tempfile::tempdir().unwrap();
    // AVIRIS units: 1 µW cm-2 sr-1 nm-1 = 10 W m-2 sr-1 µm-1.
    let p = dir.path().join("aviris.h5");
    write_with(&p, &[1.0, 2.0], &[], &[("units", "uW cm-2 sr-1 nm-1")]);
    let mut r = Hdf5Reader::open(&p).unwrap();
    assert_eq!(r.meta().units, RadianceUnits::SpectralPerUm);
    let plane = r.read_band(0, 1).unwrap();
    assert!((plane[[0, 0]] - 20.0).abs() < 1e-5, "{}", plane[[0, 0]]);

    // `radiance_units` is read when `units` is absent; a disagreeing second statement is a
    // warning and the first wins.
    let p = dir.path().join("two.h5");
    write_with(
        &p,
        &[1.0, 2.0],
        &[],
        &[
            ("units", "W/(m2 sr um)"),
            ("radiance_units", "W m-2 sr-1 nm-1"),
        ],
    );
    let mut r = Hdf5Reader::open(&p).unwrap();
    assert!((r.read_band(0, 0).unwrap()[[0, 0]] - 1.0).abs() < 1e-6);
    assert!(
        r.warnings().iter().any(|w| w.contains("disagrees")),
        "{:?}",
        r.warnings()
    );

    // No statement: an error naming the attribute and the override.
    let p = dir.path().join("none.h5");
    write_with(&p, &[1.0, 2.0], &[], &[]);
    let e = Hdf5Reader::open(&p).err().unwrap().to_string();
    assert!(
        e.contains("`units`") && e.contains("--radiance-units"),
        "{e}"
    );
    // ... which the override satisfies, scaling the values.
    let opts = eoir::io::ReadOptions {
        radiance_units: Some("W m-2 sr-1 nm-1".into()),
        ..Default::default()
    };
    let mut r = eoir::io::open_with(&p, &opts).unwrap();
    assert!((r.read_band(0, 0).unwrap()[[0, 0]] - 1000.0).abs() < 1e-3);
    assert!(
        r.units_source().starts_with("override:"),
        "{}",
        r.units_source()
    );
    // An override against a stated unit wins with a warning.
    let p = dir.path().join("stated.h5");
    write_with(&p, &[1.0, 2.0], &[], &[("units", "W m-2 sr-1 um-1")]);
    let r = eoir::io::open_with(&p, &opts).unwrap();
    assert!(
        r.warnings().iter().any(|w| w.contains("overrides")),
        "{:?}",
        r.warnings()
    );
    // A non-radiance override is refused naming the option.
    let bad = eoir::io::ReadOptions {
        radiance_units: Some("K".into()),
        ..Default::default()
    };
    let e = eoir::io::open_with(&p, &bad).err().unwrap().to_string();
    assert!(e.contains("--radiance-units") && e.contains("`K`"), "{e}");
}

#[test]
fn field_of_view_precedence_and_checks() {
    let dir = tempfile::tempdir().unwrap();
    let u = [("units", "W m-2 sr-1 um-1")];
    // `fov` alone, one value: the vertical follows from square samples (3 rows, 4 cols).
    let p = dir.path().join("h.h5");
    write_with(&p, &[1.0, 2.0], &[("fov", &[2.0])], &u);
    let g = Hdf5Reader::open(&p).unwrap().meta().geometry.unwrap();
    assert_eq!((g.fov_x_deg, g.fov_y_deg), (2.0, 1.5));

    // `fov_deg` wins over a disagreeing `fov`, with a warning naming both.
    let p = dir.path().join("both.h5");
    write_with(
        &p,
        &[1.0, 2.0],
        &[("fov_deg", &[4.0, 3.0]), ("fov", &[2.0, 1.5])],
        &u,
    );
    let r = Hdf5Reader::open(&p).unwrap();
    let g = r.meta().geometry.unwrap();
    assert_eq!((g.fov_x_deg, g.fov_y_deg), (4.0, 3.0));
    assert!(
        r.warnings()
            .iter()
            .any(|w| w.contains("`fov`") && w.contains("fov_deg")),
        "{:?}",
        r.warnings()
    );

    // `ifov_rad`: the field of view of 4 x 3 samples.
    let p = dir.path().join("ifov.h5");
    write_with(
        &p,
        &[1.0, 2.0],
        &[("ifov_rad", &[1e-3, 1e-3]), ("range_m", &[500.0])],
        &u,
    );
    let g = Hdf5Reader::open(&p).unwrap().meta().geometry.unwrap();
    assert!((g.fov_x_deg - (4e-3f64).to_degrees()).abs() < 1e-9, "{g:?}");
    assert_eq!(g.range_m, Some(500.0));

    // The checks and wording every reader shares.
    for (name, attrs, want) in [
        (
            "fov180.h5",
            vec![("fov", &[200.0, 1.0][..])],
            "(0, 180) degrees",
        ),
        (
            "two.h5",
            vec![
                ("fov_deg", &[1.0, 1.0][..]),
                ("ifov_rad", &[1e-3, 1e-3][..]),
            ],
            "give only one",
        ),
        (
            "range.h5",
            vec![("range_m", &[100.0][..])],
            "without a field of view",
        ),
        (
            "three.h5",
            vec![("fov_deg", &[1.0, 1.0, 1.0][..])],
            "has 3 values",
        ),
    ] {
        let p = dir.path().join(name);
        write_with(&p, &[1.0, 2.0], &attrs, &u);
        let e = Hdf5Reader::open(&p).err().unwrap().to_string();
        assert!(e.contains(want) && e.contains(name), "{name}: {e}");
    }
}

#[test]
fn wavelength_checks_are_the_shared_ones() {
    let dir = tempfile::tempdir().unwrap();
    let u = [("units", "W m-2 sr-1 um-1")];
    let p = dir.path().join("order.h5");
    write_with(&p, &[1.0, 3.0, 2.0], &[], &u);
    let e = Hdf5Reader::open(&p).err().unwrap().to_string();
    assert!(
        e.contains("strictly increasing or strictly decreasing") && e.contains("wavelength[1]"),
        "{e}"
    );
    let p = dir.path().join("neg.h5");
    write_with(&p, &[-1.0, 2.0], &[], &u);
    let e = Hdf5Reader::open(&p).err().unwrap().to_string();
    assert!(e.contains("not a positive number"), "{e}");
    let p = dir.path().join("fwhm.h5");
    write_with(&p, &[1.0, 2.0], &[("fwhm_um", &[0.1])], &u);
    let e = Hdf5Reader::open(&p).err().unwrap().to_string();
    assert!(e.contains("`fwhm_um`") && e.contains("1 values"), "{e}");

    // Decreasing: handed out in increasing order, widths with them.
    let p = dir.path().join("down.h5");
    write_with(&p, &[2.0, 1.0], &[("fwhm_um", &[0.2, 0.1])], &u);
    let mut r = Hdf5Reader::open(&p).unwrap();
    assert_eq!(r.meta().wavelength_um, vec![1.0, 2.0]);
    assert_eq!(r.meta().fwhm_um, Some(vec![0.1, 0.2]));
    // Stored band 1 (value 2.0 at [0, 0]) is output band 0.
    assert!((r.read_band(0, 0).unwrap()[[0, 0]] - 2.0).abs() < 1e-6);
    assert!((r.read_band(0, 1).unwrap()[[0, 0]] - 1.0).abs() < 1e-6);
}

/// `read_bands` reads runs of adjacent stored bands with one hyperslab; whatever the
/// order asked for (and the stored order), it returns exactly what `read_band` does.
#[test]
fn read_bands_matches_read_band_in_any_order() {
    let dir = tempfile::tempdir().unwrap();
    let (bands, rows, cols) = (7, 5, 6);
    let data = Array3::from_shape_fn((bands, rows, cols), |(b, r, c)| value(0, b, r, c));
    for (name, wavelength, chunked) in [
        (
            "up.h5",
            (0..bands).map(|b| 1.0 + b as f64).collect::<Vec<_>>(),
            false,
        ),
        (
            "down.h5",
            (0..bands).map(|b| 9.0 - b as f64).collect(),
            false,
        ),
        (
            "chunked.h5",
            (0..bands).map(|b| 1.0 + b as f64).collect(),
            true,
        ),
    ] {
        let p = dir.path().join(name);
        {
            let file = unlocked().create(&p).unwrap();
            let builder = file.new_dataset_builder();
            let builder = if chunked {
                builder.chunk((3, 2, cols))
            } else {
                builder
            };
            let ds = builder.with_data(data.view()).create("radiance").unwrap();
            ds.new_attr_builder()
                .with_data(&wavelength[..])
                .create("wavelength_um")
                .unwrap();
            put_str(&ds, "units", "W m-2 sr-1 nm-1");
        }
        let mut r = Hdf5Reader::open(&p).unwrap();
        let singles: Vec<Array2<f32>> = (0..bands).map(|b| r.read_band(0, b).unwrap()).collect();
        for request in [
            vec![0, 1, 2, 3, 4, 5, 6],
            vec![6, 5, 4, 3],
            vec![2, 3, 0, 6, 5, 1],
            vec![4],
            vec![],
            vec![1, 1],
        ] {
            let got = r.read_bands(0, &request).unwrap();
            assert_eq!(got.len(), request.len(), "{name} {request:?}");
            for (plane, &b) in got.iter().zip(&request) {
                assert_eq!(plane, &singles[b], "{name} {request:?} band {b}");
            }
        }
        // Per-nm values arrive ×1000.
        assert!(
            (singles[0][[0, 0]] - 1000.0 * value(0, if name == "down.h5" { 6 } else { 0 }, 0, 0))
                .abs()
                <= 1e-3
        );
        let e = r.read_bands(0, &[0, 7]).unwrap_err().to_string();
        assert!(e.contains("band 7"), "{e}");
    }
}

/// A rerun gives the same bytes: the bundle and the cube writers stamp no object times
/// (HDF5's default would put the time of writing in the root group's header, so two runs
/// with one seed a second apart differed in `products.h5` alone).
#[test]
fn writers_give_the_same_bytes_a_second_later() {
    let dir = tempfile::tempdir().unwrap();
    let dn = Array2::from_shape_fn((3, 5), |(r, c)| (r * 10 + c) as u16);
    let write_all = |tag: &str| -> Vec<Vec<u8>> {
        let bundle = dir.path().join(format!("bundle-{tag}.h5"));
        h5io::write_bundle(
            &bundle,
            &[BundleItem {
                name: "dn",
                data: BundleData::U16(dn.view()),
                attrs: vec![("units", "DN".to_string())],
            }],
            &[("sensor", "test".to_string())],
        )
        .unwrap();
        let cube = dir.path().join(format!("cube-{tag}.h5"));
        h5io::write(&cube, &test_cube()).unwrap();
        [bundle, cube]
            .iter()
            .map(|p| std::fs::read(p).unwrap())
            .collect()
    };
    let first = write_all("a");
    // HDF5 object times have a resolution of one second.
    std::thread::sleep(std::time::Duration::from_millis(1100));
    let second = write_all("b");
    assert!(first[0] == second[0], "the bundle's bytes changed");
    assert!(first[1] == second[1], "the cube's bytes changed");
}
