//! Spectral OpenEXR (Fichet et al. 2021 layout): round trip, files written the way other
//! tools write them, the channel-order trap, invalid radiance, non-spectral files.

use std::collections::HashMap;
use std::path::Path;

use eoir::io::exr::{self as sexr, ExrReader};
use eoir::io::{read_cube, CubeReader};
use eoir::scene::{Cube, CubeMeta, Geometry, RadianceUnits};
use exr::meta::attribute::AttributeValue;
use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes, ReadChannels,
    ReadLayers, SmallVec, Text, WritableImage,
};
use ndarray::Array3;

const ROWS: usize = 6;
const COLS: usize = 7;

/// A deterministic value pattern spanning many magnitudes (bit-exactness is then a real
/// test of the f32 path, not of a few round numbers).
fn pattern(band: usize, r: usize, c: usize) -> f32 {
    let k = (band * 131 + r * 17 + c * 7) as f32;
    (k * 0.618_034).fract() * 10f32.powi((band % 5) as i32 - 2)
}

fn test_cube(wavelength_um: Vec<f64>, units: RadianceUnits) -> Cube {
    let bands = wavelength_um.len();
    let data = Array3::from_shape_fn((bands, ROWS, COLS), |(b, r, c)| pattern(b, r, c));
    let meta = CubeMeta {
        fwhm_um: Some(wavelength_um.iter().map(|w| w * 0.01).collect()),
        wavelength_um,
        units,
        geometry: Some(Geometry {
            fov_x_deg: 12.345_678_901_234,
            fov_y_deg: 9.876_543_210_987,
            range_m: Some(1234.5),
        }),
        rows: ROWS,
        cols: COLS,
    };
    Cube::new(data, meta).unwrap()
}

/// Writes a file the way another spectral-EXR tool would: the given channels (name →
/// row-major f32 plane) and string attributes, nothing eoir-specific.
fn write_foreign(path: &Path, channels: Vec<(String, Vec<f32>)>, attrs: &[(&str, &str)]) {
    let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = channels
        .into_iter()
        .map(|(n, v)| AnyChannel::new(Text::from(n.as_str()), FlatSamples::F32(v)))
        .collect();
    let mut attributes = LayerAttributes::default();
    for (k, v) in attrs {
        attributes
            .other
            .insert(Text::from(*k), AttributeValue::Text(Text::from(*v)));
    }
    let layer = Layer::new(
        (COLS, ROWS),
        attributes,
        Encoding::UNCOMPRESSED,
        AnyChannels::sort(list),
    );
    Image::from_layer(layer).write().to_file(path).unwrap();
}

fn plane(f: impl Fn(usize, usize) -> f32) -> Vec<f32> {
    (0..ROWS)
        .flat_map(|r| (0..COLS).map(move |c| (r, c)))
        .map(|(r, c)| f(r, c))
        .collect()
}

fn nm_name(nm: f64) -> String {
    format!("S0.{}nm", format!("{nm:.6}").replace('.', ","))
}

/// Channel names exactly as stored in a file, read with the exr crate directly.
fn stored_channel_names(path: &Path) -> Vec<String> {
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .unwrap();
    image
        .layer_data
        .channel_data
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect()
}

#[test]
fn round_trip_is_bit_exact() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cube.exr");
    // 0.95 and 1.0 µm sort the wrong way round as channel names; 0.551234567891 needs
    // more digits than the names carry.
    let wl = vec![0.45, 0.551_234_567_891, 0.95, 1.0, 3.7, 11.25];
    let cube = test_cube(wl.clone(), RadianceUnits::SpectralPerUm);
    eoir::io::write_cube(&path, &cube).unwrap();

    let mut reader = ExrReader::open(&path).unwrap();
    assert!(reader.warnings().is_empty(), "{:?}", reader.warnings());
    assert_eq!(reader.frames(), 1);
    let back = eoir::io::read_cube_frame(&mut reader, 0).unwrap();
    assert_eq!(back.meta, cube.meta);
    for (a, b) in back.data.iter().zip(cube.data.iter()) {
        assert_eq!(a.to_bits(), b.to_bits());
    }

    // The names alone (as another tool sees them) give the wavelengths to 1e-6 µm.
    let names = stored_channel_names(&path);
    assert_eq!(names.len(), wl.len());
    let mut from_names: Vec<f64> = names
        .iter()
        .map(|n| {
            let v = n
                .strip_prefix("S0.")
                .and_then(|s| s.strip_suffix("nm"))
                .unwrap()
                .replace(',', ".");
            v.parse::<f64>().unwrap() / 1000.0
        })
        .collect();
    from_names.sort_by(f64::total_cmp);
    for (n, w) in from_names.iter().zip(&wl) {
        assert!((n - w).abs() < 1e-6, "{n} vs {w}");
    }
    assert!(names.contains(&"S0.950,000000nm".to_string()));
    assert!(names.contains(&"S0.1000,000000nm".to_string()));
    // No temporary file left behind.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn band_integrated_round_trip_and_no_geometry() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("band.exr");
    let mut cube = test_cube(vec![3.5, 4.0, 4.5], RadianceUnits::BandIntegrated);
    cube.meta.geometry = None;
    cube.meta.fwhm_um = None;
    sexr::write(&path, &cube).unwrap();
    let back = read_cube(&path).unwrap();
    assert_eq!(back, cube);
}

#[test]
fn foreign_nm_file_is_ordered_scaled_and_warned() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("foreign.exr");
    // Per-nm radiance, each band a distinct constant times the pattern; RGB preview too.
    let nms = [400.0, 550.0, 700.0, 950.0, 1000.0];
    let mut channels: Vec<(String, Vec<f32>)> = nms
        .iter()
        .enumerate()
        .map(|(i, &nm)| {
            (
                nm_name(nm),
                plane(|r, c| (i as f32 + 1.0) * 1e-3 + pattern(i, r, c) * 1e-3),
            )
        })
        .collect();
    for rgb in ["R", "G", "B"] {
        channels.push((rgb.to_string(), plane(|_, _| 0.5)));
    }
    write_foreign(
        &path,
        channels,
        &[
            ("spectralLayoutVersion", "1.0"),
            ("emissiveUnits", "W.m^-2.sr^-1"),
        ],
    );

    let mut reader = eoir::io::open(&path).unwrap();
    let meta = reader.meta().clone();
    let expected_um: Vec<f64> = nms.iter().map(|nm| nm / 1000.0).collect();
    assert_eq!(meta.bands(), 5);
    for (w, e) in meta.wavelength_um.iter().zip(&expected_um) {
        assert!((w - e).abs() < 1e-12, "{w} vs {e}");
    }
    assert_eq!(meta.units, RadianceUnits::SpectralPerUm);
    assert_eq!(meta.geometry, None);
    assert_eq!((meta.rows, meta.cols), (ROWS, COLS));

    // 1 µm = 1000 nm: a density per nm is 1000 times smaller than per µm.
    for (i, _) in nms.iter().enumerate() {
        let got = reader.read_band(0, i).unwrap();
        for ((r, c), v) in got.indexed_iter() {
            let per_nm = (i as f32 + 1.0) * 1e-3 + pattern(i, r, c) * 1e-3;
            let want = f64::from(per_nm) * 1000.0;
            assert!(
                (f64::from(*v) - want).abs() <= 1e-6 * want,
                "band {i} ({r},{c}): {v} vs {want}"
            );
        }
    }

    // Scaled bands are read for the engine too, checked (the scratch file holds the
    // stored values, not the cube's).
    let (planes, owed) = reader.read_planes_deferred(0, &[1, 3]).unwrap();
    assert!(matches!(planes, eoir::io::BandPlanes::Owned(_)) && owed.is_none());
    assert_eq!(planes.views()[1], reader.read_band(0, 3).unwrap());

    let warnings = reader.warnings().join("\n");
    assert!(
        warnings.contains("assumed the unit of the channel names (nm)"),
        "{warnings}"
    );
    assert!(
        warnings.contains("`R`") && warnings.contains("`G`") && warnings.contains("`B`"),
        "{warnings}"
    );
    assert!(
        !warnings.contains("`S0."),
        "spectral channels must not be listed as ignored: {warnings}"
    );
}

#[test]
fn channel_order_comes_from_wavelengths_not_names() {
    // The trap: as strings, 1000 nm sorts before 950 nm, and OpenEXR stores channels
    // sorted by name.
    assert!(nm_name(1000.0) < nm_name(950.0));
    assert!("S0.1000,000000nm" < "S0.950,000000nm");

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("order.exr");
    write_foreign(
        &path,
        vec![
            (nm_name(950.0), plane(|_, _| 9.5)),
            (nm_name(1000.0), plane(|_, _| 10.0)),
            // A micrometre-named channel in between, mixing units as the layout allows.
            ("S0.0,975um".to_string(), plane(|_, _| 9.75)),
        ],
        &[
            ("spectralLayoutVersion", "1.0"),
            ("emissiveUnits", "W.m^-2.sr^-1.um^-1"),
        ],
    );
    // The stored order really is the string order.
    assert_eq!(
        stored_channel_names(&path),
        vec!["S0.0,975um", "S0.1000,000000nm", "S0.950,000000nm"]
    );
    let mut reader = ExrReader::open(&path).unwrap();
    assert_eq!(reader.meta().wavelength_um, vec![0.95, 0.975, 1.0]);
    // emissiveUnits names the density unit (per µm): no scaling, no assumption.
    for (b, want) in [9.5f32, 9.75, 10.0].into_iter().enumerate() {
        let p = reader.read_band(0, b).unwrap();
        assert!(p.iter().all(|v| *v == want), "band {b}");
    }
    assert!(
        !reader.warnings().iter().any(|w| w.contains("assumed")),
        "{:?}",
        reader.warnings()
    );
}

#[test]
fn frequency_named_channels_convert_to_wavelength_and_per_um() {
    // Channels named in THz with values per THz: λ = c/ν, and L_λ = L_ν |dν/dλ|, checked
    // here against a finite difference of ν(λ) rather than the closed form.
    let c = 299_792_458.0f64;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("thz.exr");
    write_foreign(
        &path,
        vec![
            ("S0.300THz".to_string(), plane(|_, _| 2.0)),
            ("S0.600THz".to_string(), plane(|_, _| 1.0)),
        ],
        &[
            ("spectralLayoutVersion", "1.0"),
            ("emissiveUnits", "W.m^-2.sr^-1"),
        ],
    );
    let mut reader = ExrReader::open(&path).unwrap();
    let wl = reader.meta().wavelength_um.clone();
    // 600 THz is the shorter wavelength, so it is band 0.
    let expect_wl = [c / 600e12 * 1e6, c / 300e12 * 1e6];
    for (w, e) in wl.iter().zip(expect_wl) {
        assert!((w - e).abs() < 1e-12);
    }
    for (b, (l_per_thz, lam_um)) in [(1.0f64, expect_wl[0]), (2.0, expect_wl[1])]
        .into_iter()
        .enumerate()
    {
        let h = 1e-6 * lam_um;
        let dnu_thz = (c / ((lam_um - h) * 1e-6) - c / ((lam_um + h) * 1e-6)) / 1e12;
        let want = l_per_thz * dnu_thz / (2.0 * h); // per µm
        let p = reader.read_band(0, b).unwrap();
        let got = f64::from(p[[0, 0]]);
        assert!(
            (got - want).abs() / want < 1e-6,
            "band {b}: {got} vs {want}"
        );
    }
}

#[test]
fn nan_or_negative_radiance_is_one_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    for (bad, label) in [(f32::NAN, "NaN"), (-1.0f32, "-1")] {
        let path = dir.path().join(format!("bad_{label}.exr"));
        write_foreign(
            &path,
            vec![
                (nm_name(500.0), plane(|_, _| 1.0)),
                (
                    nm_name(600.0),
                    plane(|r, c| if (r, c) == (2, 3) { bad } else { 1.0 }),
                ),
            ],
            &[
                ("spectralLayoutVersion", "1.0"),
                ("emissiveUnits", "W.m^-2.sr^-1"),
            ],
        );
        let mut reader = ExrReader::open(&path).unwrap();
        assert!(reader.read_band(0, 0).is_ok());
        let err = reader.read_band(0, 1).unwrap_err().to_string();
        assert!(
            err.contains("band 1") && err.contains("row 2, col 3"),
            "{err}"
        );
        assert!(
            err.contains(label) && err.contains(&format!("bad_{label}.exr")),
            "{err}"
        );
        // Reading the whole cube stops at the same single error.
        let err2 = read_cube(&path).unwrap_err().to_string();
        assert_eq!(err, err2);
    }

    // The writer refuses too, and leaves nothing behind.
    let mut cube = test_cube(vec![0.5, 0.6], RadianceUnits::SpectralPerUm);
    cube.data[[1, 0, 0]] = f32::NAN;
    let out = dir.path().join("refused.exr");
    let err = sexr::write(&out, &cube).unwrap_err().to_string();
    assert!(err.contains("NaN"), "{err}");
    assert!(!out.exists());
}

#[test]
fn rgb_only_file_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rgb.exr");
    write_foreign(
        &path,
        ["R", "G", "B"]
            .iter()
            .map(|n| (n.to_string(), plane(|_, _| 0.25)))
            .collect(),
        &[],
    );
    let err = match ExrReader::open(&path) {
        Ok(_) => panic!("an RGB file must not open as a spectral cube"),
        Err(e) => e.to_string(),
    };
    assert!(err.contains("no spectral radiance channels"), "{err}");
    assert!(err.contains("S0.550,000000nm"), "{err}");
    assert!(err.contains("`R`") && err.contains("rgb.exr"), "{err}");

    // Only reflective / polarised channels: still not radiance eoir can use.
    let path = dir.path().join("reflective.exr");
    write_foreign(
        &path,
        vec![
            ("T.550nm".to_string(), plane(|_, _| 0.5)),
            ("S1.550nm".to_string(), plane(|_, _| 0.5)),
        ],
        &[],
    );
    let err = ExrReader::open(&path)
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(
        err.contains("`T.550nm`") && err.contains("`S1.550nm`"),
        "{err}"
    );
}

#[test]
fn eoir_attributes_are_what_the_module_documents() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("attrs.exr");
    let cube = test_cube(vec![0.5, 0.6], RadianceUnits::SpectralPerUm);
    sexr::write(&path, &cube).unwrap();
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(&path)
        .unwrap();
    let attrs: HashMap<String, AttributeValue> = image
        .layer_data
        .attributes
        .other
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect();
    let text = |k: &str| match attrs.get(k) {
        Some(AttributeValue::Text(t)) => t.to_string(),
        other => panic!("{k}: {other:?}"),
    };
    assert_eq!(text("spectralLayoutVersion"), "1.0");
    assert_eq!(text("emissiveUnits"), "W.m^-2.sr^-1");
    assert_eq!(text("eoirSpectralDensityUnit"), "um");
    assert_eq!(
        RadianceUnits::parse(&text("eoirRadianceUnits")),
        Some(RadianceUnits::SpectralPerUm)
    );
    match attrs.get("eoirFovDeg") {
        Some(AttributeValue::Custom { kind, bytes }) => {
            assert_eq!(kind.to_string(), "v2d");
            let x = f64::from_le_bytes(bytes[..8].try_into().unwrap());
            let y = f64::from_le_bytes(bytes[8..].try_into().unwrap());
            assert_eq!((x, y), (12.345_678_901_234, 9.876_543_210_987));
        }
        other => panic!("eoirFovDeg: {other:?}"),
    }
    assert!(matches!(attrs.get("eoirRangeM"), Some(AttributeValue::F64(r)) if *r == 1234.5));
    // Every channel is f32.
    assert!(image
        .layer_data
        .channel_data
        .list
        .iter()
        .all(|c| matches!(c.sample_data, FlatSamples::F32(_))));
}

#[test]
fn half_float_channels_are_read_as_f32() {
    use exr::prelude::f16;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("half.exr");
    // Values exactly representable in f16, per µm (named by emissiveUnits).
    let values: Vec<f16> = plane(|r, c| (r * COLS + c) as f32 * 0.25)
        .into_iter()
        .map(f16::from_f32)
        .collect();
    let mut attributes = LayerAttributes::default();
    for (k, v) in [
        ("spectralLayoutVersion", "1.0"),
        ("emissiveUnits", "W.m^-2.sr^-1.um^-1"),
    ] {
        attributes
            .other
            .insert(Text::from(k), AttributeValue::Text(Text::from(v)));
    }
    let layer = Layer::new(
        (COLS, ROWS),
        attributes,
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(vec![AnyChannel::new(
            "S0.10um",
            FlatSamples::F16(values),
        )])),
    );
    Image::from_layer(layer).write().to_file(&path).unwrap();
    let cube = read_cube(&path).unwrap();
    assert_eq!(cube.meta.wavelength_um, vec![10.0]);
    for ((_, r, c), v) in cube.data.indexed_iter() {
        assert_eq!(*v, (r * COLS + c) as f32 * 0.25);
    }
}

/// Writes `channels` (name → f32 or f16 plane of `rows × cols`) with `encoding`.
fn write_blocks(
    path: &Path,
    rows: usize,
    cols: usize,
    channels: Vec<(String, FlatSamples)>,
    encoding: Encoding,
) {
    let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = channels
        .into_iter()
        .map(|(n, v)| AnyChannel::new(Text::from(n.as_str()), v))
        .collect();
    let mut attributes = LayerAttributes::default();
    attributes.other.insert(
        Text::from("emissiveUnits"),
        AttributeValue::Text(Text::from("W.m^-2.sr^-1.um^-1")),
    );
    let layer = Layer::new((cols, rows), attributes, encoding, AnyChannels::sort(list));
    Image::from_layer(layer).write().to_file(path).unwrap();
}

#[test]
fn many_blocks_tiles_mixed_sample_types_and_other_channels_decode_exactly() {
    // 70 rows × 45 columns: ZIP scan-line blocks of 16 lines (the last one short), PIZ
    // blocks of 32, RLE blocks of 1, and 16 × 16 tiles (partial tiles at the right and
    // bottom edges). Spectral channels f32 and f16 are interleaved by name with an alpha
    // channel (`A`), a reflective channel (`T.…`) and a u32 id channel, all of which share
    // every block; each band must come out exactly as written.
    use exr::math::Vec2;
    use exr::meta::attribute::LineOrder;
    use exr::prelude::{f16, Blocks, Compression};
    let (rows, cols) = (70, 45);
    let value = |band: usize, r: usize, c: usize| ((band * 1000 + r * 45 + c) % 2048) as f32 * 0.5;
    let bands = [(2.0, false), (3.5, true), (4.25, false), (10.0, true)];
    let mut channels: Vec<(String, FlatSamples)> = bands
        .iter()
        .enumerate()
        .map(|(b, &(um, half))| {
            let v: Vec<f32> = (0..rows * cols)
                .map(|i| value(b, i / cols, i % cols))
                .collect();
            let samples = if half {
                FlatSamples::F16(v.into_iter().map(f16::from_f32).collect())
            } else {
                FlatSamples::F32(v)
            };
            (
                format!("S0.{}um", format!("{um}").replace('.', ",")),
                samples,
            )
        })
        .collect();
    channels.push(("A".into(), FlatSamples::F32(vec![1.0; rows * cols])));
    channels.push((
        "T.500nm".into(),
        FlatSamples::F16(vec![f16::from_f32(0.5); rows * cols]),
    ));
    channels.push((
        "id".into(),
        FlatSamples::U32((0..(rows * cols) as u32).collect()),
    ));
    let dir = tempfile::tempdir().unwrap();
    let encodings = [
        ("zip", Compression::ZIP16, Blocks::ScanLines),
        ("piz", Compression::PIZ, Blocks::ScanLines),
        ("rle", Compression::RLE, Blocks::ScanLines),
        ("tiles", Compression::ZIP1, Blocks::Tiles(Vec2(16, 16))),
    ];
    for (name, compression, blocks) in encodings {
        let path = dir.path().join(format!("{name}.exr"));
        let encoding = Encoding {
            compression,
            blocks,
            line_order: LineOrder::Increasing,
        };
        write_blocks(&path, rows, cols, channels.clone(), encoding);
        let mut r = ExrReader::open(&path).unwrap();
        assert_eq!(r.meta().wavelength_um, vec![2.0, 3.5, 4.25, 10.0], "{name}");
        let planes = r.read_bands(0, &[3, 0, 2, 1]).unwrap();
        for (plane, b) in planes.iter().zip([3usize, 0, 2, 1]) {
            for ((row, col), v) in plane.indexed_iter() {
                assert_eq!(*v, value(b, row, col), "{name} band {b} ({row},{col})");
            }
        }
        assert!(
            r.warnings()
                .iter()
                .any(|w| w.contains("ignored 3 channel(s)")),
            "{name}: {:?}",
            r.warnings()
        );
    }
}

#[test]
fn nan_in_a_band_not_read_is_not_seen_and_in_a_band_read_names_band_and_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nan.exr");
    let mut channels = Vec::new();
    for (b, nm) in [800.0, 900.0, 1000.0].iter().enumerate() {
        let mut v = plane(|r, c| pattern(b, r, c));
        if b == 1 {
            v[2 * COLS + 5] = f32::NAN;
        }
        channels.push((nm_name(*nm), v));
    }
    write_foreign(&path, channels, &[("emissiveUnits", "W.m^-2.sr^-1.um^-1")]);
    let mut r = ExrReader::open(&path).unwrap();
    assert_eq!(r.read_bands(0, &[2, 0]).unwrap().len(), 2);
    let e = r.read_bands(0, &[0, 1]).unwrap_err().to_string();
    assert!(
        e.contains("band 1 (0.9 µm), row 2, col 5: radiance NaN") && e.contains("nan.exr"),
        "{e}"
    );
    // The engine's read: the planes mapped from the scratch file, bit for bit those
    // read_bands returns, with the check owed, whose error is the reader's own.
    let (planes, owed) = r.read_planes_deferred(0, &[2, 0]).unwrap();
    assert!(matches!(planes, eoir::io::BandPlanes::Mapped(_)));
    for (got, want) in planes.views().iter().zip(r.read_bands(0, &[2, 0]).unwrap()) {
        assert!(got
            .iter()
            .zip(&want)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
    }
    owed.expect("mapped planes owe the check")
        .run(&planes)
        .unwrap();
    let (planes, owed) = r.read_planes_deferred(0, &[0, 1]).unwrap();
    assert_eq!(owed.unwrap().run(&planes).unwrap_err().to_string(), e);
    // With mapping off, read and checked at once.
    let opts = eoir::io::ReadOptions {
        no_memory_map: true,
        ..Default::default()
    };
    let mut r = ExrReader::open_with(&path, &opts).unwrap();
    assert_eq!(
        r.read_planes_deferred(0, &[0, 1]).unwrap_err().to_string(),
        e
    );
}

#[test]
fn a_run_reads_and_checks_exactly_the_bands_with_sensor_response() {
    use crate::io_envi::{
        check_unread_band_runs, run_fov_deg, run_multimir, run_radiance, RUN_SIZE,
        RUN_WAVELENGTHS_UM,
    };
    let dir = tempfile::tempdir().unwrap();
    let fov = run_fov_deg();
    let mut outcomes = Vec::new();
    for poison in [false, true] {
        let f = run_radiance(poison);
        let channels: Vec<(String, FlatSamples)> = RUN_WAVELENGTHS_UM
            .iter()
            .enumerate()
            .map(|(b, um)| {
                let v = (0..RUN_SIZE * RUN_SIZE)
                    .map(|i| f(b, i / RUN_SIZE, i % RUN_SIZE) as f32)
                    .collect();
                (nm_name(um * 1000.0), FlatSamples::F32(v))
            })
            .collect();
        let path = dir.path().join(format!("run{poison}.exr"));
        let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = channels
            .into_iter()
            .map(|(n, v)| AnyChannel::new(Text::from(n.as_str()), v))
            .collect();
        let mut attributes = LayerAttributes::default();
        attributes.other.insert(
            Text::from("emissiveUnits"),
            AttributeValue::Text(Text::from("W.m^-2.sr^-1.um^-1")),
        );
        attributes.other.insert(
            Text::from("fov"),
            AttributeValue::Text(Text::from(format!("{fov} {fov}").as_str())),
        );
        let layer = Layer::new(
            (RUN_SIZE, RUN_SIZE),
            attributes,
            Encoding::SMALL_LOSSLESS,
            AnyChannels::sort(list),
        );
        Image::from_layer(layer).write().to_file(&path).unwrap();
        outcomes.push(run_multimir(&mut ExrReader::open(&path).unwrap()));
    }
    let poisoned = outcomes.pop().unwrap();
    let clean = outcomes.pop().unwrap();
    check_unread_band_runs("exr", clean, poisoned, "runtrue.exr");
}

/// A spectral cube written twice gives the same bytes: blocks in increasing order (not in
/// the order the parallel compressor finishes them) and the header's attributes in name
/// order (the exr crate keeps custom attributes in a `HashMap`, whose order changed from
/// one write to the next). Many ZIP blocks of 16 lines and five custom attributes, so
/// either kind of reordering would show; the file still reads back bit-exact.
#[test]
fn spectral_exr_is_byte_identical_run_to_run() {
    let dir = tempfile::tempdir().unwrap();
    let (bands, rows, cols) = (5, 200, 96);
    let data = Array3::from_shape_fn((bands, rows, cols), |(b, r, c)| pattern(b, r, c));
    let meta = CubeMeta {
        fwhm_um: Some(vec![0.1; bands]),
        wavelength_um: vec![8.0, 9.0, 10.0, 11.0, 12.0],
        units: RadianceUnits::SpectralPerUm,
        geometry: Some(Geometry {
            fov_x_deg: 1.5,
            fov_y_deg: 2.5,
            range_m: Some(100.0),
        }),
        rows,
        cols,
    };
    let cube = Cube::new(data, meta).unwrap();
    let mut files = Vec::new();
    for i in 0..6 {
        let p = dir.path().join(format!("c{i}.exr"));
        sexr::write(&p, &cube).unwrap();
        let header = exr::meta::MetaData::read_from_file(&p, false).unwrap();
        assert_eq!(
            header.headers[0].line_order,
            exr::meta::attribute::LineOrder::Increasing
        );
        let back = read_cube(&p).unwrap();
        assert_eq!(back.data, cube.data);
        files.push(std::fs::read(&p).unwrap());
    }
    assert!(files.windows(2).all(|w| w[0] == w[1]));
}
