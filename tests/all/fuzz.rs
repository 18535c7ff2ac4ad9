//! Mutation fuzzing of the readers on stable Rust (issue 11): seed inputs written by the
//! library's own writers plus hostile seeds from `tests/fuzz_corpus/`, mutated with a fixed
//! seed (byte flips, insertions, deletions, chunk duplication, splices of "interesting"
//! tokens such as huge numbers, NaN, deep nesting) and fed to the ENVI, NPY, TOML sensor,
//! spectral EXR and TIFF readers, the NUC coefficient reader (sidecar and array), the
//! EMVA 1288 descriptor (with its images) and `restore`'s image inputs (16-bit PNG,
//! TIFF, single-channel OpenEXR). Every case must return `Ok` or a typed `Err`; a panic is
//! caught with `catch_unwind` and fails the test printing the input.
//!
//! `cargo test --release` runs a bounded number of cases per reader (default 300);
//! `EOIR_FUZZ_CASES=100000 cargo test --release --test all fuzz -- --nocapture` runs the
//! long campaign (see docs/robustness.md), `EOIR_FUZZ_SEED` changes the mutation seed.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

use ndarray::Array3;
use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

use eoir::io::{self, CubeReader};
use eoir::scene::{Cube, CubeMeta, Geometry, RadianceUnits};

/// Cases per reader: `EOIR_FUZZ_CASES`, default 300 (bounded so that all five readers
/// take a few seconds inside `cargo test --release`).
fn cases() -> usize {
    std::env::var("EOIR_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(300)
}

fn seed() -> u64 {
    std::env::var("EOIR_FUZZ_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(11)
}

/// The memory limit for the fuzzed readers (1 GiB), so a mutated header that claims a
/// large size gets the typed error rather than allocating. Set for the fuzzing thread
/// only: a process-wide limit would make other tests running alongside fail their own
/// (legitimately larger) budget checks.
const FUZZ_MAX_MEMORY_BYTES: u64 = 1 << 30;

/// Tokens spliced into inputs: sizes at and beyond every integer width, non-finite and
/// extreme floats, nesting and separators.
const TOKENS: &[&str] = &[
    "0",
    "-1",
    "1",
    "255",
    "65536",
    "2147483648",
    "4294967296",
    "18446744073709551615",
    "99999999999999999999999",
    "1e308",
    "1e309",
    "-1e309",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "3.4e38",
    "((((((((((((((((((((((((((((((((((((",
    "[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[",
    "{{{{{{{{{{{{{{{{{{{{{{{{",
    ",",
    "=",
    "\n",
    "\"",
    "'",
    "}",
    ")",
    "\0",
    "\u{1b}[31m",
    "/dev/zero",
    "../../../../etc/passwd",
];

/// One random mutation of `data` (at least one change).
fn mutate(rng: &mut Xoshiro256PlusPlus, data: &[u8]) -> Vec<u8> {
    let mut d = data.to_vec();
    let rounds = 1 + rng.random_range(0..4usize);
    for _ in 0..rounds {
        let len = d.len();
        let at = if len == 0 {
            0
        } else {
            rng.random_range(0..len)
        };
        match rng.random_range(0..8u32) {
            0 if len > 0 => d[at] ^= 1 << rng.random_range(0..8u32),
            1 if len > 0 => d[at] = rng.random(),
            2 => {
                let n = rng.random_range(1..9usize);
                for _ in 0..n {
                    d.insert(at.min(d.len()), rng.random());
                }
            }
            3 if len > 0 => {
                let n = rng.random_range(1..=len.min(64));
                d.drain(at..(at + n).min(len));
            }
            4 if len > 0 => {
                let n = rng.random_range(1..=(len - at).min(256));
                let chunk: Vec<u8> = d[at..at + n].to_vec();
                let to = rng.random_range(0..=d.len());
                d.splice(to..to, chunk);
            }
            5 => {
                let t = TOKENS[rng.random_range(0..TOKENS.len())].as_bytes();
                // Replace a run of digits (a number in a text header) or insert.
                let end = d[at.min(len)..]
                    .iter()
                    .position(|b| !b.is_ascii_digit() && *b != b'.')
                    .map_or(len, |p| at.min(len) + p);
                d.splice(at.min(len)..end, t.iter().copied());
            }
            6 if len > 0 => d.truncate(at),
            7 if len >= 4 => {
                // A 32-bit field set to an extreme value (binary headers).
                let v: u32 = match rng.random_range(0..4u32) {
                    0 => u32::MAX,
                    1 => 1 << 31,
                    2 => 0,
                    _ => rng.random(),
                };
                let at = at.min(len - 4);
                d[at..at + 4].copy_from_slice(&v.to_le_bytes());
            }
            _ => {
                if len > 0 {
                    d[at] = d[at].wrapping_add(1);
                }
            }
        }
    }
    d
}

/// Runs `cases()` mutations of the seeds through `check` (given the path the mutated
/// bytes were written to); a panic fails the test with the input printed.
fn campaign(name: &str, seeds: &[(String, Vec<u8>)], check: impl Fn(&Path, &Path) -> bool) {
    eoir::limits::with_thread_max_memory(FUZZ_MAX_MEMORY_BYTES, || {
        campaign_inner(name, seeds, check)
    })
    .unwrap();
}

fn campaign_inner(name: &str, seeds: &[(String, Vec<u8>)], check: impl Fn(&Path, &Path) -> bool) {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed() ^ fnv_str(name));
    let n = cases();
    let (mut ok, mut err) = (0usize, 0usize);
    for case in 0..n {
        let (file, base) = &seeds[case % seeds.len()];
        let input = if case < seeds.len() {
            base.clone()
        } else {
            mutate(&mut rng, base)
        };
        let path = dir.path().join(file);
        std::fs::write(&path, &input).unwrap();
        let result = catch_unwind(AssertUnwindSafe(|| check(&path, dir.path())));
        match result {
            Ok(true) => ok += 1,
            Ok(false) => err += 1,
            Err(_) => panic!(
                "{name}: the reader panicked on case {case} (seed {}) — input {} bytes: {}",
                seed(),
                input.len(),
                show(&input)
            ),
        }
    }
    eprintln!("fuzz {name}: {n} cases, {ok} accepted, {err} typed errors, 0 panics");
}

fn fnv_str(s: &str) -> u64 {
    s.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0100_0000_01b3)
    })
}

/// The input, escaped, at most 4 KB.
fn show(input: &[u8]) -> String {
    input
        .iter()
        .take(4096)
        .flat_map(|b| std::ascii::escape_default(*b))
        .map(char::from)
        .collect()
}

/// A small valid cube: 3 bands × 6 rows × 5 cols, MWIR.
fn small_cube() -> Cube {
    let data = Array3::from_shape_fn((3, 6, 5), |(b, r, c)| (1.0 + b as f32) * (1 + r + c) as f32);
    let meta = CubeMeta {
        wavelength_um: vec![4.5, 4.8, 5.1],
        fwhm_um: None,
        units: RadianceUnits::SpectralPerUm,
        geometry: Some(Geometry {
            fov_x_deg: 0.1,
            fov_y_deg: 0.12,
            range_m: None,
        }),
        rows: 6,
        cols: 5,
    };
    Cube::new(data, meta).unwrap()
}

/// Reads every band of every frame of an opened reader (exercising the data path too).
fn drain(r: &mut dyn CubeReader) -> bool {
    let (frames, bands) = (r.frames(), r.meta().bands());
    for f in 0..frames.min(2) {
        for b in 0..bands.min(8) {
            if r.read_band(f, b).is_err() {
                return false;
            }
        }
    }
    true
}

fn corpus(dir: &str) -> Vec<(String, Vec<u8>)> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fuzz_corpus")
        .join(dir);
    let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(&root)
        .map(|r| {
            r.filter_map(|e| e.ok())
                .map(|e| {
                    (
                        e.file_name().to_string_lossy().into_owned(),
                        std::fs::read(e.path()).unwrap(),
                    )
                })
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

#[test]
fn fuzz_envi_header() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("c.hdr");
    io::envi::write(&p, &small_cube()).unwrap();
    let header = std::fs::read(&p).unwrap();
    let data = std::fs::read(dir.path().join("c.img")).unwrap();
    let mut seeds = vec![("c.hdr".to_string(), header)];
    seeds.extend(corpus("envi"));
    campaign("ENVI header", &seeds, |path, d| {
        let img = path.with_extension("img");
        if !img.exists() {
            std::fs::write(&img, &data).unwrap();
        }
        let _ = d;
        match io::envi::EnviReader::open(path) {
            Ok(mut r) => drain(&mut r),
            Err(_) => false,
        }
    });
}

#[test]
fn fuzz_npy_header() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("c.npy");
    io::npy::write(&p, &small_cube()).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    let sidecar = std::fs::read(dir.path().join("c.json")).unwrap();
    let mut seeds = vec![("c.npy".to_string(), bytes)];
    seeds.extend(corpus("npy"));
    campaign("NPY header", &seeds, |path, _| {
        let side = io::npy::sidecar_path(path);
        if !side.exists() {
            std::fs::write(&side, &sidecar).unwrap();
        }
        match io::npy::NpyReader::open(path) {
            Ok(mut r) => drain(&mut r),
            Err(_) => false,
        }
    });
}

#[test]
fn fuzz_sensor_toml() {
    let mut seeds: Vec<(String, Vec<u8>)> = ["multimir", "qwip", "ccd-bayer"]
        .iter()
        .map(|n| {
            let s = eoir::sensor::presets::load(n, &[], &[]).unwrap();
            (
                format!("{n}.toml"),
                s.to_toml_string().unwrap().into_bytes(),
            )
        })
        .collect();
    seeds.extend(corpus("toml"));
    campaign(
        "TOML sensor file",
        &seeds,
        |path, _| match eoir::sensor::SensorConfig::load(path, &[]) {
            Ok(s) => {
                // Resolving builds the spectral chain and the camera equation.
                let ok = eoir::sensor::Sensor::build(&s).is_ok();
                let _ = s.warnings();
                ok
            }
            Err(_) => false,
        },
    );
}

#[test]
fn fuzz_spectral_exr() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("c.exr");
    io::exr::write(&p, &small_cube()).unwrap();
    let mut seeds = vec![("c.exr".to_string(), std::fs::read(&p).unwrap())];
    seeds.extend(corpus("exr"));
    campaign(
        "spectral EXR",
        &seeds,
        |path, _| match io::exr::ExrReader::open(path) {
            Ok(mut r) => drain(&mut r),
            Err(_) => false,
        },
    );
}

#[test]
fn fuzz_tiff() {
    let dir = tempfile::tempdir().unwrap();
    let img = ndarray::Array2::from_shape_fn((7, 9), |(r, c)| (r * 9 + c) as u16 * 300);
    let p16 = dir.path().join("u16.tiff");
    io::raster::write_tiff_u16(&p16, img.view()).unwrap();
    let p32 = dir.path().join("f32.tiff");
    io::raster::write_tiff_f32(&p32, img.mapv(|v| v as f32 * 0.5).view()).unwrap();
    let mut seeds = vec![
        ("u16.tiff".to_string(), std::fs::read(&p16).unwrap()),
        ("f32.tiff".to_string(), std::fs::read(&p32).unwrap()),
    ];
    seeds.extend(corpus("tiff"));
    campaign("TIFF", &seeds, |path, _| {
        let a = io::raster::read_tiff_u16(path).is_ok();
        let b = io::raster::read_tiff_f32(path).is_ok();
        a || b
    });
}

/// A NUC fitted on two 6 × 5 levels, saved as `NAME.npy` + `NAME.json`; `version1`
/// drops the checksum (a version-1 sidecar), so a mutated array reaches the array reader
/// instead of stopping at the checksum.
fn nuc_pair(dir: &Path, name: &str, version1: bool) -> (Vec<u8>, Vec<u8>) {
    use eoir::processing::nuc::NucCoefficients;
    let lo = ndarray::Array2::from_shape_fn((6, 5), |(r, c)| 1000.0 + (r * 5 + c) as f64);
    let hi = lo.mapv(|v| 2.0 * v);
    let levels = [
        (lo.mean().unwrap(), lo.view()),
        (hi.mean().unwrap(), hi.view()),
    ];
    let coeffs = NucCoefficients::fit(&levels, 1).unwrap();
    let npy = dir.join(format!("{name}.npy"));
    coeffs.save(&npy).unwrap();
    let mut json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(npy.with_extension("json")).unwrap()).unwrap();
    if version1 {
        let m = json.as_object_mut().unwrap();
        m.remove("coefficients_fnv1a64");
        m.insert("version".into(), 1.into());
    }
    (
        serde_json::to_vec_pretty(&json).unwrap(),
        std::fs::read(&npy).unwrap(),
    )
}

#[test]
fn fuzz_nuc_sidecar_and_coefficients() {
    let dir = tempfile::tempdir().unwrap();
    // `a`: the sidecar mutated beside its own array; `b`: the array mutated beside a
    // version-1 sidecar (no checksum to stop at).
    let (a_json, a_npy) = nuc_pair(dir.path(), "a", false);
    let (b_json, b_npy) = nuc_pair(dir.path(), "b", true);
    let mut seeds = vec![
        ("a.json".to_string(), a_json.clone()),
        ("b.npy".to_string(), b_npy.clone()),
    ];
    seeds.extend(corpus("nuc"));
    campaign("NUC sidecar and coefficients", &seeds, |path, _| {
        let is_json = path.extension().is_some_and(|e| e == "json");
        let partner = if is_json {
            (path.with_extension("npy"), &a_npy)
        } else {
            (path.with_extension("json"), &b_json)
        };
        std::fs::write(&partner.0, partner.1).unwrap();
        let _ = (&a_json, &b_npy);
        match eoir::processing::nuc::NucCoefficients::load(&path.with_extension("npy")) {
            Ok(c) => {
                // What `nuc apply` does with them.
                let frame = ndarray::Array2::from_elem(c.dim(), 1500.0);
                c.apply(frame.view()).is_ok()
            }
            Err(_) => false,
        }
    });
}

#[test]
fn fuzz_emva_descriptor() {
    let set = tempfile::tempdir().unwrap();
    let sensor = eoir::sensor::presets::load("multimir", &[], &[]).unwrap();
    let sim = set.path().join("set");
    eoir::characterize::simulate(
        &sensor,
        &sim,
        &eoir::characterize::SimulateOptions {
            seed: 1,
            window: 16,
        },
    )
    .unwrap();
    let mut seeds = vec![(
        "descriptor.txt".to_string(),
        std::fs::read(sim.join("descriptor.txt")).unwrap(),
    )];
    seeds.extend(corpus("emva"));
    campaign("EMVA 1288 descriptor", &seeds, |path, d| {
        // The descriptor's images beside it, as the simulation wrote them.
        for sub in ["ptc", "dark", "spatial"] {
            if !d.join(sub).exists() {
                std::fs::create_dir(d.join(sub)).unwrap();
                for e in std::fs::read_dir(sim.join(sub)).unwrap() {
                    let e = e.unwrap();
                    std::fs::copy(e.path(), d.join(sub).join(e.file_name())).unwrap();
                }
            }
        }
        eoir::characterize::characterize(path).is_ok()
    });
}

#[test]
fn fuzz_restore_image_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let img = ndarray::Array2::from_shape_fn((7, 9), |(r, c)| (r * 9 + c) as u16 * 300);
    let png = dir.path().join("dn.png");
    io::raster::write_png_u16(&png, img.view()).unwrap();
    let exr = dir.path().join("e.exr");
    io::raster::write_exr_f32(&exr, img.mapv(|v| v as f32 * 0.25).view(), "electrons").unwrap();
    let tif = dir.path().join("f32.tiff");
    io::raster::write_tiff_f32(&tif, img.mapv(|v| v as f32 * 0.5).view()).unwrap();
    let mut seeds = vec![
        ("dn.png".to_string(), std::fs::read(&png).unwrap()),
        ("e.exr".to_string(), std::fs::read(&exr).unwrap()),
        ("f32.tiff".to_string(), std::fs::read(&tif).unwrap()),
    ];
    seeds.extend(corpus("restore"));
    // The calls `eoir restore` makes on its input: the size from the header, then the
    // decoder for the extension (the single-channel EXR read as `cli::restore` does).
    campaign("restore image inputs", &seeds, |path, _| {
        if io::raster::image_dimensions(path).is_err() {
            return false;
        }
        match path.extension().and_then(|e| e.to_str()) {
            Some("png") => io::raster::read_png_u16(path).is_ok(),
            Some("exr") => {
                use exr::prelude::{read, ReadChannels, ReadLayers};
                let Ok(f) = io::input::open_regular(path) else {
                    return false;
                };
                let mut f = std::io::BufReader::new(f);
                if io::exr::check_exr_image_size(path, &mut f).is_err() {
                    return false;
                }
                read()
                    .no_deep_data()
                    .largest_resolution_level()
                    .all_channels()
                    .first_valid_layer()
                    .all_attributes()
                    .from_buffered(f)
                    .is_ok()
            }
            _ => io::raster::read_tiff_u16(path).is_ok() || io::raster::read_tiff_f32(path).is_ok(),
        }
    });
}
