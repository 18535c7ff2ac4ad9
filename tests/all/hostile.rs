//! Hostile input and failure safety (issue 11): every case runs the `eoir` binary as a
//! child with its address space limited to 4 GiB and a hang detector, and must end in one
//! clear error line (or success where the input is valid) — no panic, no abort, no hang —
//! with the working directory exactly as it was (no file left behind, none replaced).

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use super::common::{
    assert_one_error, envi_header, eoir, finish_within, fixture_nuc, fixture_scene, fnv, listing,
    mkfifo, refused, run_args, sensor_with, simulate_emva_set, spawn_limited, LONG_RUN_AFTER,
};

#[test]
fn huge_sizes_from_the_command_line_are_refused_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fixture_scene(d);
    for (extra, needles) in [
        (
            &["--frames", "18446744073709551615"][..],
            &["overflows", "frames"][..],
        ),
        // A sequence streams to disk (its memory does not grow with the frame count), so
        // the disk bounds it: 10¹¹ frames of 16 × 16 pixels need at least 200 TB.
        (
            &["--frames", "100000000000"],
            &["fit on the disk", "100000000000 frames"],
        ),
        (&["--frames", "0"], &["--frames 0"]),
        (&["--nuc-degree", "1000000000"], &["--nuc-degree", "0 to 8"]),
        (&["--nuc-degree", "9"], &["0 to 8"]),
        (&["--max-memory", "1K"], &["max-memory", "at least 1 MiB"]),
        (&["--max-memory", "lots"], &["max-memory", "lots"]),
    ] {
        refused(d, &run_args("s.hdr", "out", extra), needles);
    }
    refused(
        d,
        &["mtf", "--sensor", "multimir", "--points", "10000000000"],
        &["--points", "memory limit"],
    );
    refused(
        d,
        &[
            "mtf",
            "--sensor",
            "multimir",
            "--set",
            "detector.rows=4000000000",
            "--set",
            "detector.cols=4000000000",
        ],
        &["detector", "memory limit"],
    );
    // Valid: a sequence of 3 frames still runs.
    let o = eoir(d, &run_args("s.hdr", "seq", &["--frames", "3"]));
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    assert!(d.join("seq/frame_0002_dn.tiff").is_file());
}

#[test]
fn huge_sizes_from_file_headers_are_refused_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // ENVI: 2·10⁹ samples with a matching sparse data file (8 GB, no blocks on disk).
    std::fs::write(d.join("wide.hdr"), envi_header(2_000_000_000, 1, 1)).unwrap();
    let f = std::fs::File::create(d.join("wide.img")).unwrap();
    f.set_len(8_000_000_000).unwrap();
    drop(f);
    refused(
        d,
        &run_args("wide.hdr", "out", &[]),
        &["wide.hdr", "memory limit"],
    );

    // ENVI: a size whose product overflows 64 bits.
    std::fs::write(d.join("ovf.hdr"), envi_header(1 << 40, 1 << 40, 1)).unwrap();
    std::fs::write(d.join("ovf.img"), [0u8; 16]).unwrap();
    refused(d, &run_args("ovf.hdr", "out", &[]), &["ovf"]);

    // NPY: a 35 KB header whose shape tuple nests 17,000 deep.
    let mut header = String::from("{'descr': '<f4', 'fortran_order': False, 'shape': ");
    header.push_str(&"(".repeat(17_000));
    header.push_str(&")".repeat(17_000));
    header.push_str(", }");
    std::fs::write(d.join("deep.npy"), npy_bytes(&header, &[])).unwrap();
    std::fs::write(d.join("deep.json"), "{\"wavelength_um\": [4.8]}").unwrap();
    refused(d, &run_args("deep.npy", "out", &[]), &["nesting deeper"]);

    // NPY: shape 2³¹ × 2³¹ × 2³¹ on a 16-byte payload.
    let header =
        "{'descr': '<f4', 'fortran_order': False, 'shape': (2147483648, 2147483648, 2147483648), }";
    std::fs::write(d.join("big.npy"), npy_bytes(header, &[0u8; 16])).unwrap();
    std::fs::write(d.join("big.json"), "{\"wavelength_um\": [4.8]}").unwrap();
    refused(d, &run_args("big.npy", "out", &[]), &["big.npy"]);

    // TIFF: a 4 × 4 file whose header claims 2³¹ × 2³¹ pixels.
    std::fs::write(d.join("big.tiff"), tiff_claiming(1 << 31, 1 << 31)).unwrap();
    refused(
        d,
        &[
            "temperature",
            "--sensor",
            "multimir",
            "big.tiff",
            "-o",
            "out",
        ],
        &["big.tiff"],
    );

    // EXR: a valid file whose data window is patched to 2³⁰ × 2³⁰.
    let fov = (16.0 * 0.24e-3f64).to_degrees().to_string();
    let o = eoir(
        d,
        &[
            "scene",
            "blackbody",
            "--rows",
            "16",
            "--cols",
            "16",
            "--lo-um",
            "4.4",
            "--hi-um",
            "5.4",
            "--bands",
            "5",
            "--fov-deg",
            &fov,
            "-o",
            "e.exr",
        ],
    );
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    let mut bytes = std::fs::read(d.join("e.exr")).unwrap();
    let key = b"dataWindow\0box2i\0";
    let at = bytes
        .windows(key.len())
        .position(|w| w == key)
        .expect("dataWindow attribute")
        + key.len()
        + 4;
    bytes[at + 8..at + 12].copy_from_slice(&(1i32 << 30).to_le_bytes());
    bytes[at + 12..at + 16].copy_from_slice(&(1i32 << 30).to_le_bytes());
    std::fs::write(d.join("huge.exr"), bytes).unwrap();
    refused(d, &run_args("huge.exr", "out", &[]), &["huge.exr"]);
}

/// An NPY v1 file with `header` (padded to a multiple of 64) and `payload`.
fn npy_bytes(header: &str, payload: &[u8]) -> Vec<u8> {
    let mut h = header.as_bytes().to_vec();
    while (10 + h.len() + 1) % 64 != 0 {
        h.push(b' ');
    }
    h.push(b'\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(h.len() as u16).to_le_bytes());
    out.extend_from_slice(&h);
    out.extend_from_slice(payload);
    out
}

/// A little-endian baseline TIFF with 32 bytes of 16-bit grey data whose IFD claims
/// `width × height` pixels in one strip.
fn tiff_claiming(width: u32, height: u32) -> Vec<u8> {
    let mut out = b"II*\0".to_vec();
    out.extend_from_slice(&8u32.to_le_bytes());
    // (tag, type, count, value); type 3 = SHORT, 4 = LONG.
    let entries: [(u16, u16, u32, u32); 9] = [
        (256, 4, 1, width),
        (257, 4, 1, height),
        (258, 3, 1, 16),
        (259, 3, 1, 1),
        (262, 3, 1, 1),
        (273, 4, 1, 8 + 2 + 9 * 12 + 4),
        (277, 3, 1, 1),
        (278, 4, 1, height),
        (279, 4, 1, 32),
    ];
    out.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for (tag, ty, count, value) in entries {
        out.extend_from_slice(&tag.to_le_bytes());
        out.extend_from_slice(&ty.to_le_bytes());
        out.extend_from_slice(&count.to_le_bytes());
        out.extend_from_slice(&value.to_le_bytes());
    }
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&[0u8; 32]);
    out
}

#[test]
fn special_files_as_inputs_are_refused_without_blocking() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fixture_scene(d);
    // A FIFO as the cube.
    mkfifo(&d.join("pipe.npy"));
    std::fs::write(d.join("pipe.json"), "{\"wavelength_um\": [4.8]}").unwrap();
    refused(d, &run_args("pipe.npy", "out", &[]), &["pipe.npy", "FIFO"]);
    // A FIFO as a sensor-file table (a CSV spectrum).
    mkfifo(&d.join("filter.csv"));
    let toml = sensor_with(d, "filter", "kind = \"csv\"\npath = \"filter.csv\"");
    std::fs::write(d.join("fifo-sensor.toml"), toml).unwrap();
    refused(
        d,
        &["mtf", "--sensor", "fifo-sensor.toml"],
        &["filter.csv", "FIFO"],
    );
    // A directory as the cube, and a device as the ENVI data file.
    std::fs::create_dir(d.join("dir.npy")).unwrap();
    refused(d, &run_args("dir.npy", "out", &[]), &["directory"]);
    std::fs::write(d.join("zero.hdr"), envi_header(16, 16, 11)).unwrap();
    std::os::unix::fs::symlink("/dev/zero", d.join("zero.img")).unwrap();
    refused(d, &run_args("zero.hdr", "out", &[]), &["zero"]);
}

#[test]
fn private_files_are_not_echoed_and_relative_paths_follow_the_sensor_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let secret = "root:$6$SECRETSECRETSECRETSECRETSECRETSECRETSECRET_TAIL_MUST_NOT_APPEAR:19000:0:99999:7:::";
    std::fs::write(d.join("shadow"), format!("{secret}\n{secret}\n")).unwrap();
    let toml = sensor_with(d, "filter", "kind = \"csv\"\npath = \"shadow\"");
    std::fs::write(d.join("s.toml"), toml).unwrap();
    let o = refused(d, &["mtf", "--sensor", "s.toml"], &["shadow", "line"]);
    assert!(!o.stderr.contains("TAIL_MUST_NOT_APPEAR"), "{}", o.stderr);

    // A TOML syntax error on a long line quotes at most a short escaped token of it.
    let mut bad = sensor_with(
        d,
        "filter",
        "kind = \"top_hat\"\nlo_um = 4.55\nhi_um = 5.2\nedge_width_um = 0.05\npeak = 0.85",
    );
    bad.push_str(&format!("\n[x]\n{secret} = \n"));
    std::fs::write(d.join("bad.toml"), bad).unwrap();
    let o = refused(d, &["mtf", "--sensor", "bad.toml"], &["bad.toml"]);
    assert!(!o.stderr.contains("TAIL_MUST_NOT_APPEAR"), "{}", o.stderr);

    // Relative table paths resolve against the sensor file's directory, not the cwd.
    std::fs::create_dir(d.join("sub")).unwrap();
    std::fs::write(
        d.join("sub/filter.csv"),
        "wavelength_um,value\n4.0,0\n4.5,0.8\n5.0,0.8\n5.5,0\n",
    )
    .unwrap();
    let toml = sensor_with(d, "filter", "kind = \"csv\"\npath = \"filter.csv\"");
    std::fs::write(d.join("sub/rel.toml"), toml).unwrap();
    let o = eoir(d, &["mtf", "--sensor", "sub/rel.toml"]);
    assert_eq!(o.code, Some(0), "{}", o.stderr);

    // Binary junk in an ENVI header is escaped, never echoed raw.
    let mut h = envi_header(16, 16, 11);
    h = h.replace("interleave = bsq", "interleave = \u{1b}[31mbsq\u{7}");
    std::fs::write(d.join("esc.hdr"), h).unwrap();
    std::fs::write(d.join("esc.img"), vec![0u8; 16 * 16 * 11 * 4]).unwrap();
    refused(d, &run_args("esc.hdr", "out", &[]), &["esc.hdr"]);
}

#[test]
fn special_files_and_links_as_outputs_are_never_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mtf = |target: &str| -> Vec<String> {
        ["mtf", "--sensor", "multimir", "--csv", target]
            .iter()
            .map(|s| s.to_string())
            .collect()
    };
    mkfifo(&d.join("fifo.csv"));
    let a = mtf("fifo.csv");
    refused(
        d,
        &a.iter().map(String::as_str).collect::<Vec<_>>(),
        &["FIFO"],
    );

    std::fs::write(d.join("target.csv"), "old\n").unwrap();
    std::os::unix::fs::symlink("target.csv", d.join("link.csv")).unwrap();
    let a = mtf("link.csv");
    refused(
        d,
        &a.iter().map(String::as_str).collect::<Vec<_>>(),
        &["symbolic link"],
    );

    let sock = std::os::unix::net::UnixListener::bind(d.join("sock.csv")).unwrap();
    let a = mtf("sock.csv");
    refused(
        d,
        &a.iter().map(String::as_str).collect::<Vec<_>>(),
        &["socket"],
    );
    drop(sock);

    // A character device (made here, never the system's /dev/null) when we may mknod.
    let dev = d.join("null.csv");
    let c = std::ffi::CString::new(dev.as_os_str().as_encoded_bytes()).unwrap();
    // SAFETY: plain libc call; makedev(1, 3) is the null device's number.
    let made = unsafe { libc::mknod(c.as_ptr(), libc::S_IFCHR | 0o666, libc::makedev(1, 3)) } == 0;
    if made {
        let a = mtf("null.csv");
        refused(
            d,
            &a.iter().map(String::as_str).collect::<Vec<_>>(),
            &["character device"],
        );
    }

    // A product name inside the output directory taken by a FIFO: nothing is written.
    fixture_scene(d);
    std::fs::create_dir(d.join("out")).unwrap();
    mkfifo(&d.join("out/dn.tiff"));
    refused(d, &run_args("s.hdr", "out", &[]), &["dn.tiff", "FIFO"]);
    // The output directory is a regular file.
    std::fs::write(d.join("plain"), "x").unwrap();
    refused(
        d,
        &run_args("s.hdr", "plain", &[]),
        &["plain", "not a directory"],
    );

    // A missing directory: the error names the target, once, not the temporary file.
    let a = mtf("nodir/x.csv");
    let o = refused(
        d,
        &a.iter().map(String::as_str).collect::<Vec<_>>(),
        &["nodir/x.csv", "No such file or directory"],
    );
    assert!(!o.stderr.contains("eoir-tmp"), "{}", o.stderr);
    assert_eq!(o.stderr.matches("No such file").count(), 1, "{}", o.stderr);

    // `-` is standard output for the CSV.
    let before = listing(d);
    let o = eoir(d, &mtf("-").iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    assert!(o.stdout.starts_with("freq_cy_per_mrad,"), "{}", o.stdout);
    assert!(o.stdout.lines().count() > 100);
    assert_eq!(listing(d), before);
}

#[test]
fn non_finite_and_impossible_values_are_errors_naming_the_setting() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fixture_scene(d);
    // Radiance 3e38 W m-2 sr-1 µm-1 (a finite f32) overflows the electron count.
    let n = 16 * 16 * 11;
    let data: Vec<u8> = (0..n).flat_map(|_| 3.0e38f32.to_le_bytes()).collect();
    std::fs::write(d.join("hot.hdr"), envi_header(16, 16, 11)).unwrap();
    std::fs::write(d.join("hot.img"), data).unwrap();
    refused(
        d,
        &run_args("hot.hdr", "out", &[]),
        &["hot.hdr", "overflowed"],
    );
    // QE 3.4e38 and QE 7.0, a transmission of 1.5.
    for (name, body, field) in [
        (
            "qe-huge.toml",
            "kind = \"ideal_qe\"\npeak = 3.4e38\ncutoff_um = 5.4",
            "detector.quantum_efficiency",
        ),
        (
            "qe-7.toml",
            "kind = \"table\"\nwavelength_um = [4.0, 5.5]\nvalue = [7.0, 7.0]",
            "detector.quantum_efficiency",
        ),
    ] {
        std::fs::write(
            d.join(name),
            sensor_with(d, "detector.quantum_efficiency", body),
        )
        .unwrap();
        let mut args = run_args("s.hdr", "out", &[]);
        args[2] = name;
        refused(d, &args, &[field]);
    }
    std::fs::write(
        d.join("tau.toml"),
        sensor_with(d, "optics.transmission", "kind = \"constant\"\nvalue = 1.5"),
    )
    .unwrap();
    let mut args = run_args("s.hdr", "out", &[]);
    args[2] = "tau.toml";
    refused(d, &args, &["optics.transmission"]);
    // Field of view inf or ≥ 180°, or ≤ 0.
    for fov in ["inf,inf", "200,4", "0,4", "nan,1"] {
        refused(
            d,
            &run_args("s.hdr", "out", &["--fov-deg", fov]),
            &["--fov-deg", "(0, 180)"],
        );
    }
    // bits = 1: a thermal sensor cannot calibrate with 2 DN levels (clear message; the
    // run itself makes DN-only products unless a temperature is required) …
    refused(
        d,
        &run_args(
            "s.hdr",
            "out",
            &["--set", "detector.bits=1", "--require-temperature"],
        ),
        &["detector.bits = 1", "more ADC bits"],
    );
    // … and DN-only products are still made with 1 bit by a visible camera.
    let o = eoir(
        d,
        &[
            "scene",
            "blackbody",
            "--rows",
            "16",
            "--cols",
            "16",
            "--lo-um",
            "0.4",
            "--hi-um",
            "1.0",
            "--bands",
            "13",
            "--fov-deg",
            "0.2",
            "--temperature-k",
            "5800",
            "-o",
            "vis.hdr",
        ],
    );
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    let o = eoir(
        d,
        &[
            "run",
            "--sensor",
            "ccd",
            "--quiet",
            "--set",
            "detector.rows=4",
            "--set",
            "detector.cols=4",
            "--set",
            "detector.bits=1",
            // The preset's 16 DN black level does not fit a 1-bit ADC.
            "--set",
            "detector.offset_dn=0",
            "--fov-deg",
            "0.2,0.2",
            "vis.hdr",
            "-o",
            "vis-out",
        ],
    );
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    let dn = std::fs::read(d.join("vis-out/dn.tiff")).unwrap();
    assert!(!dn.is_empty());
}

/// Snapshot of a product directory: file name → content hash (report.json excluded when
/// `skip_report`, since it holds timings).
fn products(dir: &Path, skip_report: bool) -> BTreeMap<String, u64> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap())
        .filter(|e| !(skip_report && e.file_name() == "report.json"))
        .map(|e| {
            (
                e.file_name().to_string_lossy().into_owned(),
                fnv(&std::fs::read(e.path()).unwrap_or_default()),
            )
        })
        .collect()
}

/// Under `--features hdf5` the set includes `products.h5`, written last by libhdf5; the
/// handler's clean-up copes with the HDF5 writer still creating its temporary file (see
/// `io::output`, "Signals"), and the attempts below can land in that write.
#[test]
fn sigint_while_writing_a_sequence_leaves_the_old_set_or_the_complete_new_one() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fixture_scene(d);
    let frames = "150";
    let seq = |out: &str, seed: &str| -> Vec<OsString> {
        run_args("s.hdr", out, &["--frames", frames, "--seed", seed])
            .iter()
            .map(OsString::from)
            .collect()
    };
    let o = finish_within(
        spawn_limited(d, &seq("out", "1")),
        "old run",
        LONG_RUN_AFTER,
    );
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    let o = finish_within(
        spawn_limited(d, &seq("reference", "2")),
        "reference run",
        LONG_RUN_AFTER,
    );
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    let mut old = products(&d.join("out"), false);
    let new = products(&d.join("reference"), true);
    assert_eq!(
        old.len(),
        // + the set's list `.eoir-products-run`; + products.h5 with HDF5
        150 * 8 + 11 + usize::from(super::common::cli_has_hdf5()),
        "{:?}",
        old.keys().take(5).collect::<Vec<_>>()
    );

    // Signal once the staging directory holds k files (k differs per attempt) or, for the
    // last attempt, as late as possible (when the staging directory disappears: the move).
    let mut interrupted = 0;
    // With HDF5 one more attempt signals as soon as products.h5 (written last, by libhdf5)
    // has appeared in the staging directory.
    const DURING_HDF5: usize = usize::MAX;
    let mut attempts = vec![
        (1usize, libc::SIGINT),
        (400, libc::SIGTERM),
        (1100, libc::SIGINT),
    ];
    if super::common::cli_has_hdf5() {
        attempts.push((DURING_HDF5, libc::SIGINT));
    }
    for (attempt, signal) in attempts {
        let child = spawn_limited(d, &seq("out", "2"));
        let pid = child.id() as i32;
        let start = Instant::now();
        loop {
            let staging: Vec<PathBuf> = std::fs::read_dir(d.join("out"))
                .unwrap()
                .filter_map(|e| e.ok())
                .filter(|e| {
                    e.file_name()
                        .to_string_lossy()
                        .starts_with(".eoir-staging-")
                })
                .map(|e| e.path())
                .collect();
            let names: Vec<String> = staging
                .iter()
                .flat_map(|p| std::fs::read_dir(p).into_iter().flatten())
                .filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect();
            let reached = if attempt == DURING_HDF5 {
                names.iter().any(|n| n.contains("products.h5"))
            } else {
                names.len() >= attempt
            };
            if reached || start.elapsed() > LONG_RUN_AFTER {
                break;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        // SAFETY: signalling our own child by its pid.
        unsafe { libc::kill(pid, signal) };
        let o = finish_within(child, "interrupted run", LONG_RUN_AFTER);
        assert!(!o.stderr.contains("panicked"), "{}", o.stderr);
        let after = listing(&d.join("out"));
        for name in after.keys() {
            let n = name.to_string_lossy();
            assert!(
                !n.contains(".eoir-staging-") && !n.contains(".eoir-tmp-"),
                "attempt {attempt}: left behind {n}"
            );
        }
        match o.code {
            Some(c) if c == 128 + signal => {
                interrupted += 1;
                assert_eq!(
                    products(&d.join("out"), false),
                    old,
                    "attempt {attempt}: interrupted, but the old set changed"
                );
            }
            Some(0) => {
                // Finished (signal came after the move): the complete new set.
                assert_eq!(products(&d.join("out"), true), new);
                // Restore the old set for the next attempt.
                std::fs::remove_dir_all(d.join("out")).unwrap();
                let o = finish_within(
                    spawn_limited(d, &seq("out", "1")),
                    "old run again",
                    LONG_RUN_AFTER,
                );
                assert_eq!(o.code, Some(0), "{}", o.stderr);
                let again = products(&d.join("out"), false);
                let mut a = again.clone();
                let mut b = old.clone();
                a.remove("report.json");
                b.remove("report.json");
                assert_eq!(a, b, "the seed-1 run is not reproducible");
                old = again;
            }
            other => panic!("attempt {attempt}: exit {other:?}: {}", o.stderr),
        }
    }
    assert!(interrupted >= 1, "no attempt was interrupted while writing");
}

/// CRC-32 (ISO-HDLC, the PNG chunk checksum), bitwise.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xffff_ffffu32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xedb8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// A ~100-byte 16-bit greyscale PNG whose header claims `width × height` pixels (the
/// image data is a few zero rows: the decoder must refuse before allocating the frame).
fn png_claiming(width: u32, height: u32) -> Vec<u8> {
    let chunk = |ty: &[u8], data: &[u8]| -> Vec<u8> {
        let mut out = (data.len() as u32).to_be_bytes().to_vec();
        let mut body = ty.to_vec();
        body.extend_from_slice(data);
        out.extend_from_slice(&body);
        out.extend_from_slice(&crc32(&body).to_be_bytes());
        out
    };
    let mut ihdr = width.to_be_bytes().to_vec();
    ihdr.extend_from_slice(&height.to_be_bytes());
    ihdr.extend_from_slice(&[16, 0, 0, 0, 0]);
    // A stored (uncompressed) zlib stream of 8 zero bytes.
    let idat = [
        0x78, 0x01, 0x01, 0x08, 0x00, 0xf7, 0xff, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1,
    ];
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    out.extend(chunk(b"IHDR", &ihdr));
    out.extend(chunk(b"IDAT", &idat));
    out.extend(chunk(b"IEND", &[]));
    out
}

/// An uncompressed 16-bit TIFF of `width × height` pixels, one strip per row, whose pixel
/// data is a hole of a sparse file (no disk blocks): a valid, huge image in a few KB.
fn sparse_tiff(path: &Path, width: u32, height: u32) {
    let row_bytes = width * 2;
    let ifd_len = 2 + 9 * 12 + 4;
    let offsets_at = 8 + ifd_len;
    let counts_at = offsets_at + 4 * height;
    let data_at = counts_at + 4 * height;
    let mut out = b"II*\0".to_vec();
    out.extend_from_slice(&8u32.to_le_bytes());
    let entries: [(u16, u16, u32, u32); 9] = [
        (256, 4, 1, width),
        (257, 4, 1, height),
        (258, 3, 1, 16),
        (259, 3, 1, 1),
        (262, 3, 1, 1),
        (273, 4, height, offsets_at),
        (277, 3, 1, 1),
        (278, 4, 1, 1),
        (279, 4, height, counts_at),
    ];
    out.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for (tag, ty, count, value) in entries {
        out.extend_from_slice(&tag.to_le_bytes());
        out.extend_from_slice(&ty.to_le_bytes());
        out.extend_from_slice(&count.to_le_bytes());
        out.extend_from_slice(&value.to_le_bytes());
    }
    out.extend_from_slice(&0u32.to_le_bytes());
    for r in 0..height {
        out.extend_from_slice(&(data_at + r * row_bytes).to_le_bytes());
    }
    for _ in 0..height {
        out.extend_from_slice(&row_bytes.to_le_bytes());
    }
    std::fs::write(path, &out).unwrap();
    let f = std::fs::OpenOptions::new().write(true).open(path).unwrap();
    f.set_len(data_at as u64 + row_bytes as u64 * height as u64)
        .unwrap();
}

#[test]
fn images_tables_and_descriptors_of_every_command_are_bounded_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A 120-byte PNG claiming 100000 × 100000 pixels, given to every image reader.
    std::fs::write(d.join("bomb.png"), png_claiming(100_000, 100_000)).unwrap();
    // A valid 20000 × 20000 16-bit TIFF (800 MB of pixels, all a sparse hole).
    sparse_tiff(&d.join("wide.tiff"), 20_000, 20_000);
    fixture_nuc(d);
    for (args, needles) in [
        (
            &["edge-mtf", "bomb.png", "-o", "e"][..],
            &["bomb.png", "memory limit"][..],
        ),
        (
            &["edge-mtf", "wide.tiff", "-o", "e"],
            &["wide.tiff", "memory limit"],
        ),
        (
            &["restore", "bomb.png", "--sensor", "multimir", "-o", "r"],
            &["bomb.png", "100000 × 100000"],
        ),
        (
            &["restore", "wide.tiff", "--sensor", "multimir", "-o", "r"],
            &["wide.tiff", "20000 × 20000"],
        ),
        (
            &[
                "nuc",
                "fit",
                "wide.tiff",
                "wide.tiff",
                "--temperatures-k",
                "280,300",
                "-o",
                "n.json",
            ],
            &["nuc fit", "memory limit"],
        ),
        (
            &[
                "nuc",
                "fit",
                "lo.png",
                "bomb.png",
                "--temperatures-k",
                "280,300",
                "-o",
                "n.json",
            ],
            &["bomb.png", "one size"],
        ),
        (
            &[
                "nuc",
                "fit",
                "lo.png",
                "hi.png",
                "--temperatures-k",
                "280,300",
                "--degree",
                "18446744073709551615",
                "-o",
                "n.json",
            ],
            &["--degree", "0 to 8"],
        ),
        (
            &[
                "edge-mtf",
                "lo.png",
                "--roi",
                "18446744073709551615,0,10,10",
                "-o",
                "e",
            ],
            &["--roi", "inside the 8 × 8"],
        ),
        (
            &[
                "nuc", "apply", "bomb.png", "--nuc", "nuc.json", "-o", "a.tiff",
            ],
            &["bomb.png", "100000 x 100000"],
        ),
        (
            &["temperature", "--sensor", "multimir", "bomb.png", "-o", "t"],
            &["bomb.png"],
        ),
        // Synthetic scenes: the band count and the generators' working set.
        (
            &[
                "scene",
                "blackbody",
                "--rows",
                "16",
                "--cols",
                "16",
                "--bands",
                "18446744073709551615",
                "--fov-deg",
                "0.2",
                "-o",
                "s.hdr",
            ],
            &["bands"],
        ),
        (
            &[
                "scene",
                "blackbody",
                "--rows",
                "50000",
                "--cols",
                "50000",
                "--bands",
                "1",
                "--fov-deg",
                "0.2",
                "-o",
                "s.hdr",
            ],
            &["synthetic scene", "memory limit"],
        ),
        (
            &[
                "scene",
                "thermal",
                "--rows",
                "30000",
                "--cols",
                "30000",
                "--bands",
                "2",
                "--fov-deg",
                "0.2",
                "-o",
                "s.npy",
            ],
            &["synthetic scene", "memory limit"],
        ),
    ] {
        refused(d, args, needles);
    }

    // NUC coefficient files: the sidecar's size and the NPY header are checked before the
    // array is decoded.
    let sidecar = std::fs::read_to_string(d.join("nuc.json")).unwrap();
    let npy = std::fs::read(d.join("nuc.npy")).unwrap();
    std::fs::write(
        d.join("rows.json"),
        sidecar
            .replace("\"rows\": 8", "\"rows\": 4000000000")
            .replace("\"cols\": 8", "\"cols\": 4000000000"),
    )
    .unwrap();
    std::fs::write(d.join("rows.npy"), &npy).unwrap();
    let shape =
        "{'descr': '<f8', 'fortran_order': False, 'shape': (2147483648, 2147483648, 2147483648), }";
    let deep = format!(
        "{{'descr': '<f8', 'fortran_order': False, 'shape': {}{}, }}",
        "(".repeat(17_000),
        ")".repeat(17_000)
    );
    std::fs::write(d.join("shape.json"), &sidecar).unwrap();
    std::fs::write(d.join("shape.npy"), npy_bytes(shape, &[0u8; 64])).unwrap();
    std::fs::write(d.join("deep.json"), &sidecar).unwrap();
    std::fs::write(d.join("deep.npy"), npy_bytes(&deep, &[])).unwrap();
    // NPY v2 whose header length field claims 4 GiB.
    let mut long = b"\x93NUMPY\x02\x00".to_vec();
    long.extend_from_slice(&u32::MAX.to_le_bytes());
    long.extend_from_slice(b"{'descr': '<f8'");
    std::fs::write(d.join("long.json"), &sidecar).unwrap();
    std::fs::write(d.join("long.npy"), long).unwrap();
    for (nuc, needles) in [
        ("rows.json", &["rows.npy", "memory limit"][..]),
        ("shape.json", &["shape.npy", "do not match the sidecar"]),
        ("deep.json", &["deep.npy", "nesting deeper"]),
        ("long.json", &["long.npy", "truncated"]),
    ] {
        refused(
            d,
            &["nuc", "apply", "lo.png", "--nuc", nuc, "-o", "a.tiff"],
            needles,
        );
    }

    // EMVA 1288 descriptor: the image size it states is budgeted before the analysis.
    simulate_emva_set(d);
    let desc = std::fs::read_to_string(d.join("set/descriptor.txt")).unwrap();
    assert!(desc.contains("\nn 14 16 16\n"), "{desc}");
    std::fs::write(
        d.join("set/descriptor.txt"),
        desc.replace("\nn 14 16 16\n", "\nn 14 1000000 1000000\n"),
    )
    .unwrap();
    refused(
        d,
        &["characterize", "set", "-o", "c"],
        &["descriptor.txt", "memory limit"],
    );
}

#[test]
fn special_files_given_to_any_command_are_refused_without_blocking() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fixture_nuc(d);
    for name in ["f.png", "f.tiff", "f.exr", "f.toml", "g.json", "g.npy"] {
        mkfifo(&d.join(name));
    }
    // A NUC whose coefficient array is a FIFO (the sidecar is genuine).
    std::fs::copy(d.join("nuc.json"), d.join("g.json.tmp")).unwrap();
    std::fs::remove_file(d.join("g.json")).unwrap();
    std::fs::rename(d.join("g.json.tmp"), d.join("g.json")).unwrap();
    mkfifo(&d.join("h.json"));
    for (args, needles) in [
        (
            &["edge-mtf", "f.png", "-o", "e"][..],
            &["f.png", "FIFO"][..],
        ),
        (&["edge-mtf", "f.tiff", "-o", "e"], &["f.tiff", "FIFO"]),
        (
            &["restore", "f.exr", "--sensor", "multimir", "-o", "r"],
            &["f.exr", "FIFO"],
        ),
        (
            &["restore", "f.tiff", "--sensor", "multimir", "-o", "r"],
            &["f.tiff", "FIFO"],
        ),
        (
            &[
                "nuc",
                "fit",
                "lo.png",
                "f.png",
                "--temperatures-k",
                "280,300",
                "-o",
                "n.json",
            ],
            &["f.png", "FIFO"],
        ),
        (
            &["nuc", "apply", "f.png", "--nuc", "nuc.json", "-o", "a.tiff"],
            &["f.png", "FIFO"],
        ),
        (
            &["nuc", "apply", "lo.png", "--nuc", "g.json", "-o", "a.tiff"],
            &["g.npy", "FIFO"],
        ),
        (
            &["nuc", "apply", "lo.png", "--nuc", "h.json", "-o", "a.tiff"],
            &["h.json", "FIFO"],
        ),
        (
            &["temperature", "--sensor", "multimir", "f.tiff", "-o", "t"],
            &["f.tiff", "FIFO"],
        ),
        (&["mtf", "--sensor", "f.toml"], &["f.toml", "FIFO"]),
        (&["sensors", "show", "f.toml"], &["f.toml", "FIFO"]),
    ] {
        refused(d, args, needles);
    }

    // `characterize`: the descriptor, and an image it lists, as FIFOs.
    simulate_emva_set(d);
    std::fs::remove_file(d.join("set/dark/d0_0.png")).unwrap();
    mkfifo(&d.join("set/dark/d0_0.png"));
    refused(
        d,
        &["characterize", "set", "-o", "c"],
        &["d0_0.png", "FIFO"],
    );
    std::fs::rename(d.join("set/descriptor.txt"), d.join("descriptor.txt")).unwrap();
    mkfifo(&d.join("set/descriptor.txt"));
    refused(
        d,
        &["characterize", "set", "-o", "c"],
        &["descriptor.txt", "FIFO"],
    );
}

#[test]
fn the_library_refuses_zero_frames_and_wrapping_frame_indices() {
    // The CLI refuses `--frames 0` itself; the library (and through it the Python
    // package) must too, not quietly run one frame.
    use eoir::scene::synthetic::{self, SceneParams};
    let small = ["detector.rows=8".to_string(), "detector.cols=8".to_string()];
    let config = eoir::sensor::presets::load("multimir", &[], &small).unwrap();
    let sensor = eoir::sensor::Sensor::build(&config).unwrap();
    let params = SceneParams {
        rows: 8,
        cols: 8,
        wavelength_um: SceneParams::uniform_grid(4.4, 5.4, 5).unwrap(),
        fov_x_deg: (sensor.ifov_rad() * 8.0).to_degrees(),
        ..SceneParams::default()
    };
    let cube = synthetic::generate("blackbody", &params).unwrap();
    let mut reader = eoir::io::MemoryCube::new(cube);
    let options = eoir::pipeline::RunOptions {
        frames: 0,
        calibration: None,
        ..Default::default()
    };
    let e = eoir::pipeline::run(&sensor, &mut reader, &options, |_, _| {}).unwrap_err();
    assert!(e.to_string().contains("`frames` = 0"), "{e}");
    // A first frame index whose sequence would wrap past 2⁶⁴ − 1.
    let options = eoir::pipeline::RunOptions {
        frames: 2,
        first_frame: u64::MAX - 1,
        calibration: None,
        ..Default::default()
    };
    let e = eoir::pipeline::run(&sensor, &mut reader, &options, |_, _| {}).unwrap_err();
    assert!(e.to_string().contains("first_frame"), "{e}");
}

#[test]
fn nan_is_an_error_in_every_band_the_sensor_sees_and_unread_outside_its_response() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 3.0 µm (where multimir's response is zero) and 4.4–5.4 µm in 0.1 µm steps.
    let wl: Vec<f64> = std::iter::once(3.0)
        .chain((0..11).map(|i| 4.4 + 0.1 * i as f64))
        .collect();
    let header = |name: &str| {
        let w: Vec<String> = wl.iter().map(|w| format!("{w:.3}")).collect();
        std::fs::write(
            d.join(format!("{name}.hdr")),
            format!(
                "ENVI\nsamples = 16\nlines = 16\nbands = {}\nheader offset = 0\nfile type = ENVI Standard\ndata type = 4\ninterleave = bsq\nbyte order = 0\nwavelength units = Micrometers\nwavelength = {{{}}}\neoir radiance units = W m-2 sr-1 um-1\neoir fov deg = {{0.23, 0.23}}\n",
                wl.len(),
                w.join(", ")
            ),
        )
        .unwrap();
    };
    let data = |nan_band: usize| -> Vec<u8> {
        (0..wl.len())
            .flat_map(|b| {
                let v = if b == nan_band { f32::NAN } else { 0.5 };
                std::iter::repeat_n(v, 256)
            })
            .flat_map(f32::to_le_bytes)
            .collect()
    };
    header("outside");
    std::fs::write(d.join("outside.img"), data(0)).unwrap();
    let o = eoir(d, &run_args("outside.hdr", "out", &[]));
    assert_eq!(
        o.code,
        Some(0),
        "NaN at 3.0 µm is outside the response: {}",
        o.stderr
    );
    header("inside");
    std::fs::write(d.join("inside.img"), data(5)).unwrap();
    refused(d, &run_args("inside.hdr", "out2", &[]), &["inside", "NaN"]);
}

/// Issue 39: a private file reached through a sensor file, `--sensor`, a NUC sidecar,
/// an EMVA descriptor or an ENVI header is never shown — no 6-character piece of its
/// marker appears in any message — while the message still names the file and the line.
#[test]
fn no_piece_of_a_private_file_reaches_any_message() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let marker = "S3CR3T-MARKER-9f0d27c1";
    let shadow = format!(
        "root:$6${marker}$hash:19000:0:99999:7:::\n{marker},{marker}\ntoken = \"{marker}\"\n"
    );
    std::fs::write(d.join("private"), &shadow).unwrap();
    let leaks = |o: &super::common::Outcome| -> Option<String> {
        let text = format!("{}{}", o.stdout, o.stderr);
        (0..=marker.len() - 6)
            .map(|i| &marker[i..i + 6])
            .find(|piece| text.contains(piece))
            .map(|p| format!("`{p}` in {text}"))
    };
    let check = |args: &[&str], needles: &[&str]| {
        let o = refused(d, args, needles);
        assert!(leaks(&o).is_none(), "{args:?}: {}", leaks(&o).unwrap());
    };
    // --sensor naming the private file itself (the `/etc/passwd` case).
    check(&["mtf", "--sensor", "private"], &["private", "line 1"]);
    // A sensor file whose filter table is the private file.
    let toml = sensor_with(d, "filter", "kind = \"csv\"\npath = \"private\"");
    std::fs::write(d.join("s.toml"), toml).unwrap();
    check(&["mtf", "--sensor", "s.toml"], &["private", "line 2"]);
    // A sensor value holding the private text as a string where a number belongs.
    let toml = sensor_with(
        d,
        "filter",
        &format!("kind = \"top_hat\"\nlo_um = \"{marker}\"\nhi_um = 5.2\nedge_width_um = 0.05\npeak = 0.85"),
    );
    std::fs::write(d.join("v.toml"), toml).unwrap();
    check(&["mtf", "--sensor", "v.toml"], &["v.toml", "line"]);
    // NUC sidecars: the private file as the sidecar, and sidecars quoting it in a value
    // and in a key.
    fixture_nuc(d);
    std::fs::copy(d.join("nuc.npy"), d.join("p.npy")).unwrap();
    std::fs::copy(d.join("private"), d.join("p.json")).unwrap();
    check(
        &["nuc", "apply", "lo.png", "--nuc", "p.json", "-o", "c.tiff"],
        &["p.json", "line 1"],
    );
    let side: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("nuc.json")).unwrap()).unwrap();
    let mut v = side.clone();
    v["format"] = marker.into();
    std::fs::write(d.join("p.json"), v.to_string()).unwrap();
    check(
        &["nuc", "apply", "lo.png", "--nuc", "p.json", "-o", "c.tiff"],
        &["p.json", "eoir-nuc"],
    );
    let mut v = side.clone();
    v[marker] = 1.into();
    std::fs::write(d.join("p.json"), v.to_string()).unwrap();
    check(
        &["nuc", "apply", "lo.png", "--nuc", "p.json", "-o", "c.tiff"],
        &["p.json", "unknown field"],
    );
    // An EMVA descriptor and an ENVI header that are the private file.
    std::fs::create_dir(d.join("emva")).unwrap();
    std::fs::copy(d.join("private"), d.join("emva/descriptor.txt")).unwrap();
    check(
        &["characterize", "emva", "-o", "never"],
        &["descriptor.txt", "line 1"],
    );
    std::fs::copy(d.join("private"), d.join("p.hdr")).unwrap();
    std::fs::write(d.join("p.img"), [0u8; 16]).unwrap();
    check(&run_args("p.hdr", "never", &[]), &["p.hdr", "line 1"]);
}

/// Issue 39: values that would be written non-finite, NUC sidecars out of range, a NUC
/// pair that does not belong together and impossible blackbody temperatures are errors
/// naming what is valid, and nothing is written.
#[test]
fn non_finite_outputs_bad_sidecars_and_mismatched_nuc_pairs_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // restore of f32 images near the f32 limit: a step from 0 to 3.3e38 (the Wiener
    // overshoot passes 3.4e38) is refused; one 3e38 pixel is refused too or, should the
    // defect detection replace it, restored finite — never written as +inf.
    let write = |name: &str, f: &dyn Fn(usize, usize) -> f32| {
        let img = ndarray::Array2::<f32>::from_shape_fn((16, 16), |(r, c)| f(r, c));
        eoir::io::raster::write_tiff_f32(&d.join(name), img.view()).unwrap();
    };
    write("edge.tiff", &|_, c| if c < 8 { 0.0 } else { 3.3e38 });
    write("hot.tiff", &|r, c| {
        if (r, c) == (8, 8) {
            3e38
        } else {
            100.0
        }
    });
    let restore = |input: &str| -> Vec<String> {
        [
            "restore",
            input,
            "--sensor",
            "multimir",
            "--set",
            "detector.rows=16",
            "--set",
            "detector.cols=16",
            "--units",
            "electrons",
            "--nsr",
            "0.01",
            "-o",
            "out",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect()
    };
    let args = restore("edge.tiff");
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    refused(d, &args, &["restored.tiff", "non-finite", "3.4e38"]);
    let args = restore("hot.tiff");
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = eoir(d, &args);
    if o.code == Some(0) {
        let r = eoir::io::raster::read_tiff_f32(&d.join("out/restored.tiff")).unwrap();
        assert!(r.iter().all(|v| v.is_finite()), "{}", o.stdout);
        std::fs::remove_dir_all(d.join("out")).unwrap();
    } else {
        assert_one_error(&o, "restore hot.tiff", &["restored.tiff", "non-finite"]);
        assert!(!d.join("out").exists());
    }
    // nuc fit: a temperature no blackbody has.
    fixture_nuc(d);
    refused(
        d,
        &[
            "nuc",
            "fit",
            "lo.png",
            "hi.png",
            "lo.png",
            "--temperatures-k",
            "280,300,1e30",
            "-o",
            "x.json",
        ],
        &["--temperatures-k", "1e30", "150", "1000"],
    );
    // Sidecar normalisation out of range.
    let side: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("nuc.json")).unwrap()).unwrap();
    std::fs::copy(d.join("nuc.npy"), d.join("p.npy")).unwrap();
    for (key, value, needles) in [
        (
            "signal_scale",
            serde_json::json!(1e-320),
            ["signal_scale", "1e-9"],
        ),
        (
            "signal_centre",
            serde_json::json!(1e308),
            ["signal_centre", "1e12"],
        ),
    ] {
        let mut v = side.clone();
        v[key] = value;
        std::fs::write(d.join("p.json"), v.to_string()).unwrap();
        refused(
            d,
            &["nuc", "apply", "lo.png", "--nuc", "p.json", "-o", "c.tiff"],
            &needles,
        );
    }
    // New coefficients beside the old sidecar (what an interrupted fit used to leave).
    std::fs::create_dir(d.join("b")).unwrap();
    let hi3 = ndarray::Array2::<u16>::from_shape_fn((8, 8), |(r, c)| 3000 + (r * 8 + c) as u16 * 3);
    eoir::io::raster::write_png_u16(&d.join("b/hi3.png"), hi3.view()).unwrap();
    let o = eoir(
        d,
        &[
            "nuc",
            "fit",
            "lo.png",
            "b/hi3.png",
            "--temperatures-k",
            "290,310",
            "-o",
            "b/nuc.json",
        ],
    );
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    std::fs::copy(d.join("b/nuc.npy"), d.join("p.npy")).unwrap();
    std::fs::copy(d.join("nuc.json"), d.join("p.json")).unwrap();
    refused(
        d,
        &["nuc", "apply", "lo.png", "--nuc", "p.json", "-o", "c.tiff"],
        &["p.npy", "do not belong", "p.json"],
    );
    // A NaN coefficient at a pixel the sidecar does not list (a version-1 sidecar, which
    // has no checksum to stop at first).
    let mut a: ndarray::Array3<f64> = ndarray_npy::read_npy(d.join("nuc.npy")).unwrap();
    // A pixel the calibration did not flag (a flagged one is replaced anyway).
    let flagged = side["bad_pixels"].as_array().cloned().unwrap_or_default();
    let (r, c) = [(2usize, 3usize), (5, 6), (6, 1)]
        .into_iter()
        .find(|&(r, c)| !flagged.contains(&serde_json::json!([r, c])))
        .unwrap();
    a[[0, r, c]] = f64::NAN;
    ndarray_npy::write_npy(d.join("p.npy"), &a).unwrap();
    let mut v = side.clone();
    v.as_object_mut().unwrap().remove("coefficients_fnv1a64");
    v["version"] = 1.into();
    std::fs::write(d.join("p.json"), v.to_string()).unwrap();
    refused(
        d,
        &["nuc", "apply", "lo.png", "--nuc", "p.json", "-o", "c.tiff"],
        &["p.npy", &format!("[{r}, {c}]"), "NaN"],
    );
    // Listed as rank-deficient, the NaN pixel is replaced and counted (the summary also
    // counts pixels left non-finite by the correction itself).
    v["rank_deficient"] = serde_json::json!([[r, c]]);
    std::fs::write(d.join("p.json"), v.to_string()).unwrap();
    let o = eoir(
        d,
        &["nuc", "apply", "lo.png", "--nuc", "p.json", "-o", "c.tiff"],
    );
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    // Rank-deficient pixels belong to the calibration's map of pixels to replace.
    assert!(
        o.stdout
            .contains("1 bad pixel(s) replaced: 1 from the calibration's map"),
        "{}",
        o.stdout
    );
    let c = eoir::io::raster::read_tiff_f32(&d.join("c.tiff")).unwrap();
    assert!(c.iter().all(|v| v.is_finite()));
}
