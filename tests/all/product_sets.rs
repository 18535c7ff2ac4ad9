//! Every command that writes more than one file writes its whole set or nothing (issue
//! 39): SIGINT/SIGTERM at random moments, a FIFO in place of any product, a write over
//! `ulimit -f`, a full disk (a small tmpfs, where the test may mount one) — each leaves
//! the output folder holding the complete old set or the complete new one, never a mix,
//! and no staging or temporary litter. Two runs into one folder end with one complete
//! set from one of them.
//!
//! Kept fast: 16 × 16 sensors, 8 × 8 NUC frames, 16-pixel EMVA windows, a few trials per
//! command with a fixed seed.

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

use super::common::{
    assert_one_error, eoir, finish, finish_within, fixture_scene, listing, mkfifo, spawn_limited,
    spawn_limited_with, Outcome, LONG_RUN_AFTER,
};

/// A multi-file command: how to write the old set and the new one into `out`.
struct Case {
    name: &'static str,
    old: Vec<String>,
    new: Vec<String>,
    /// Products whose bytes differ between identical runs (timings): compared by name.
    volatile: &'static [&'static str],
}

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

fn os(v: &[String]) -> Vec<OsString> {
    v.iter().map(OsString::from).collect()
}

const SMALL: [&str; 4] = ["--set", "detector.rows=16", "--set", "detector.cols=16"];

/// A Gaussian-blurred slanted edge, 64 × 64, 16-bit.
fn edge_png(path: &Path, sigma_px: f64) {
    let (lo, hi) = (1000.0, 20000.0);
    let (s, c) = 5f64.to_radians().sin_cos();
    let img = ndarray::Array2::from_shape_fn((64, 64), |(y, x)| {
        let d = (x as f64 - 31.5) * c - (y as f64 - 31.5) * s;
        let phi = 0.5 * (1.0 + libm::erf(d / (sigma_px * std::f64::consts::SQRT_2)));
        (lo + (hi - lo) * phi).round() as u16
    });
    eoir::io::raster::write_png_u16(path, img.view()).unwrap();
}

/// NUC frames `NAME-lo.png`, `NAME-hi.png` (8 × 8) at levels scaled by `k`.
fn nuc_frames(d: &Path, name: &str, k: u16) {
    let lo = ndarray::Array2::<u16>::from_shape_fn((8, 8), |(r, c)| k * 1000 + (r * 8 + c) as u16);
    let hi = lo.mapv(|v| v * 2);
    eoir::io::raster::write_png_u16(&d.join(format!("{name}-lo.png")), lo.view()).unwrap();
    eoir::io::raster::write_png_u16(&d.join(format!("{name}-hi.png")), hi.view()).unwrap();
}

fn simulate(d: &Path, out: &str, seed: &str) {
    let o = eoir(
        d,
        &[
            "characterize",
            "--simulate",
            "--sensor",
            "multimir",
            "--window",
            "16",
            "--seed",
            seed,
            "-o",
            out,
        ],
    );
    assert_eq!(o.code, Some(0), "{}", o.stderr);
}

/// Writes every fixture into `d` and returns the cases (all writing into `out`).
fn cases(d: &Path) -> Vec<Case> {
    fixture_scene(d);
    let mut run = vec!["run", "--sensor", "multimir", "--quiet"];
    run.extend(SMALL);
    let run_seed = |seed: &str| {
        let mut v = strings(&run);
        v.extend(strings(&["s.hdr", "-o", "out", "--seed", seed]));
        v
    };
    // A DN image of the 16 × 16 sensor for restore.
    let mut a = run.clone();
    a.extend(["s.hdr", "-o", "recorded"]);
    let o = eoir(d, &a);
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    let restore = |nsr: &str| {
        let mut v = strings(&["restore", "recorded/dn.tiff", "--sensor", "multimir"]);
        v.extend(strings(&SMALL));
        v.extend(strings(&["--nsr", nsr, "-o", "out"]));
        v
    };
    edge_png(&d.join("edge1.png"), 1.0);
    edge_png(&d.join("edge2.png"), 1.6);
    simulate(d, "set1", "1");
    simulate(d, "set2", "2");
    nuc_frames(d, "a", 1);
    nuc_frames(d, "b", 3);
    let nuc = |n: &str| {
        strings(&[
            "nuc",
            "fit",
            &format!("{n}-lo.png"),
            &format!("{n}-hi.png"),
            "--temperatures-k",
            "290,310",
            "-o",
            "out/nuc.json",
        ])
    };
    vec![
        Case {
            name: "run",
            old: run_seed("1"),
            new: run_seed("2"),
            volatile: &["report.json", "report.html"],
        },
        Case {
            name: "restore",
            old: restore("0.01"),
            new: restore("0.1"),
            volatile: &[],
        },
        Case {
            name: "edge-mtf",
            old: strings(&["edge-mtf", "edge1.png", "-o", "out"]),
            new: strings(&["edge-mtf", "edge2.png", "-o", "out"]),
            volatile: &[],
        },
        Case {
            name: "characterize",
            old: strings(&["characterize", "set1", "-o", "out"]),
            new: strings(&["characterize", "set2", "-o", "out"]),
            volatile: &[],
        },
        Case {
            name: "nuc fit",
            old: nuc("a"),
            new: nuc("b"),
            volatile: &[],
        },
    ]
}

type Listing = BTreeMap<PathBuf, (String, u64, u64)>;

/// `l` with the sizes and hashes of volatile products zeroed.
fn stable(mut l: Listing, volatile: &[&str]) -> Listing {
    for (k, v) in l.iter_mut() {
        if volatile
            .iter()
            .any(|n| k.file_name().is_some_and(|f| f == *n))
        {
            v.1 = 0;
            v.2 = 0;
        }
    }
    l
}

/// Staging directories, temporary files or partial folders anywhere under `d`.
fn litter(d: &Path) -> Vec<PathBuf> {
    listing(d)
        .into_keys()
        .filter(|p| {
            let n = p.to_string_lossy();
            n.contains(".eoir-staging-") || n.contains(".eoir-tmp-") || n.contains(".partial-")
        })
        .collect()
}

fn copy_dir(from: &Path, to: &Path) {
    let _ = std::fs::remove_dir_all(to);
    let st = std::process::Command::new("cp")
        .arg("-a")
        .arg(from)
        .arg(to)
        .status()
        .unwrap();
    assert!(st.success());
}

/// Prepares `out` (the old set, kept in `old-NAME`) and `new-NAME` (the reference new set)
/// for `case`; returns (old, new) listings.
fn prepare(d: &Path, case: &Case) -> (Listing, Listing) {
    let _ = std::fs::remove_dir_all(d.join("out"));
    let o = finish_within(spawn_limited(d, &os(&case.new)), case.name, LONG_RUN_AFTER);
    assert_eq!(o.code, Some(0), "{}: {}", case.name, o.stderr);
    let new = stable(listing(&d.join("out")), case.volatile);
    std::fs::remove_dir_all(d.join("out")).unwrap();
    let o = finish_within(spawn_limited(d, &os(&case.old)), case.name, LONG_RUN_AFTER);
    assert_eq!(o.code, Some(0), "{}: {}", case.name, o.stderr);
    let old = stable(listing(&d.join("out")), case.volatile);
    assert_ne!(
        old, new,
        "{}: the old and the new set must differ",
        case.name
    );
    copy_dir(&d.join("out"), &d.join("pristine"));
    (old, new)
}

/// After an attempt: the folder holds the old set or the complete new set, and no litter.
fn assert_old_or_new(d: &Path, case: &Case, old: &Listing, new: &Listing, o: &Outcome, what: &str) {
    assert!(!o.stderr.contains("panicked"), "{what}: {}", o.stderr);
    assert!(
        litter(d).is_empty(),
        "{what}: exit {:?}, litter {:?}: {}",
        o.code,
        litter(d),
        o.stderr
    );
    let now = stable(listing(&d.join("out")), case.volatile);
    if o.code == Some(0) {
        assert_eq!(
            &now, new,
            "{what}: succeeded but the set is not the new one"
        );
    } else if o.stderr.contains("no unfinished outputs to remove") {
        // The signal came after the set moved into place (or before any was begun): the
        // folder holds one complete set.
        assert!(
            &now == new || &now == old,
            "{what}: exit {:?}, nothing unfinished, but the folder mixes: {}",
            o.code,
            o.stderr
        );
    } else {
        assert_eq!(
            &now, old,
            "{what}: exit {:?} but the old set changed: {}",
            o.code, o.stderr
        );
    }
}

#[test]
fn signals_at_random_moments_leave_the_old_set_or_the_new_one() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(39);
    let mut interrupted_while_staging = 0;
    for case in cases(d) {
        let (old, new) = prepare(d, &case);
        // How long the command takes here, to spread the signals over its run.
        copy_dir(&d.join("pristine"), &d.join("out"));
        let t0 = Instant::now();
        let o = finish_within(spawn_limited(d, &os(&case.new)), case.name, LONG_RUN_AFTER);
        let took = t0.elapsed();
        assert_eq!(o.code, Some(0), "{}", o.stderr);
        for trial in 0..4 {
            copy_dir(&d.join("pristine"), &d.join("out"));
            let signal = if trial % 2 == 0 {
                libc::SIGINT
            } else {
                libc::SIGTERM
            };
            let child = spawn_limited(d, &os(&case.new));
            let pid = child.id() as i32;
            let start = Instant::now();
            if trial < 2 {
                // When the staging directory appears (the products are being written).
                while start.elapsed() < took * 3 {
                    let staging = std::fs::read_dir(d.join("out"))
                        .into_iter()
                        .flatten()
                        .flatten()
                        .any(|e| {
                            e.file_name()
                                .to_string_lossy()
                                .starts_with(".eoir-staging-")
                        });
                    if staging {
                        interrupted_while_staging += 1;
                        break;
                    }
                    std::thread::sleep(Duration::from_micros(200));
                }
            } else {
                std::thread::sleep(took.mul_f64(rng.random_range(0.0..1.2)));
            }
            // SAFETY: signalling our own child by its pid.
            unsafe { libc::kill(pid, signal) };
            let o = finish_within(child, case.name, LONG_RUN_AFTER);
            let what = format!("{} trial {trial} (signal {signal})", case.name);
            assert!(
                o.code == Some(0) || o.code == Some(128 + signal) || o.code.is_none(),
                "{what}: exit {:?}: {}",
                o.code,
                o.stderr
            );
            assert_old_or_new(d, &case, &old, &new, &o, &what);
        }
    }
    assert!(
        interrupted_while_staging > 0,
        "no signal reached a command while it staged"
    );
}

#[test]
fn characterize_simulate_leaves_the_whole_set_or_nothing_when_interrupted() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = os(&strings(&[
        "characterize",
        "--simulate",
        "--sensor",
        "multimir",
        "--window",
        "16",
        "-o",
        "sim",
    ]));
    let t0 = Instant::now();
    let o = finish_within(spawn_limited(d, &args), "simulate", LONG_RUN_AFTER);
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    let took = t0.elapsed();
    let complete = listing(&d.join("sim"));
    std::fs::remove_dir_all(d.join("sim")).unwrap();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(3939);
    for trial in 0..4 {
        let signal = if trial % 2 == 0 {
            libc::SIGINT
        } else {
            libc::SIGTERM
        };
        let child = spawn_limited(d, &args);
        std::thread::sleep(took.mul_f64(rng.random_range(0.05..0.9)));
        // SAFETY: signalling our own child by its pid.
        unsafe { libc::kill(child.id() as i32, signal) };
        let o = finish_within(child, "interrupted simulate", LONG_RUN_AFTER);
        assert!(
            litter(d).is_empty(),
            "trial {trial}: litter {:?}",
            litter(d)
        );
        // Whatever the exit status, the folder holds the complete set or nothing: a
        // signal that lands after the set was moved into place (the handler then says
        // "no unfinished outputs to remove" and exits 128 + signal) leaves it whole.
        if o.code == Some(0) || d.join("sim").exists() {
            assert_eq!(
                listing(&d.join("sim")),
                complete,
                "trial {trial}: exit {:?} left an incomplete set",
                o.code
            );
            std::fs::remove_dir_all(d.join("sim")).unwrap();
        }
    }
}

#[test]
fn a_fifo_in_place_of_any_product_is_refused_and_nothing_moves() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for case in cases(d) {
        let (old, new) = prepare(d, &case);
        let names: Vec<PathBuf> = new
            .iter()
            .filter(|(_, v)| v.0 == "file")
            .map(|(k, _)| k.clone())
            .collect();
        // Every product of the small commands; for `run`, the first, a middle and the last.
        let picks: Vec<&PathBuf> = if names.len() > 6 {
            vec![&names[0], &names[names.len() / 2], &names[names.len() - 1]]
        } else {
            names.iter().collect()
        };
        for p in picks {
            copy_dir(&d.join("pristine"), &d.join("out"));
            let target = d.join("out").join(p);
            let _ = std::fs::remove_file(&target);
            mkfifo(&target);
            let before = listing(&d.join("out"));
            let o = finish(spawn_limited(d, &os(&case.new)), case.name);
            let what = format!("{}: FIFO at {}", case.name, p.display());
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            assert_one_error(&o, &what, &[name.as_str()]);
            assert_eq!(
                listing(&d.join("out")),
                before,
                "{what}: the folder changed"
            );
            assert!(litter(d).is_empty(), "{what}: litter {:?}", litter(d));
        }
        let _ = old;
    }
}

#[test]
fn a_write_beyond_ulimit_f_is_an_error_that_leaves_the_old_set() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for case in cases(d) {
        let (old, _new) = prepare(d, &case);
        copy_dir(&d.join("pristine"), &d.join("out"));
        // 1 KiB: every command here has a larger product (an f32 TIFF, a plot, the HTML).
        let o = finish(
            spawn_limited_with(d, &os(&case.new), "ulimit -f 1"),
            case.name,
        );
        let what = format!("{} under ulimit -f 1", case.name);
        assert_eq!(
            o.code,
            Some(1),
            "{what}: exit {:?} (SIGXFSZ?): {}",
            o.code,
            o.stderr
        );
        assert_one_error(&o, &what, &["file too large"]);
        assert_eq!(
            stable(listing(&d.join("out")), case.volatile),
            old,
            "{what}"
        );
        assert!(litter(d).is_empty(), "{what}: litter {:?}", litter(d));
    }
}

/// Unmounts the tmpfs when the test ends, whatever happens.
struct Mounted(PathBuf);

impl Drop for Mounted {
    fn drop(&mut self) {
        let _ = std::process::Command::new("umount").arg(&self.0).status();
    }
}

#[test]
fn a_full_disk_is_an_error_that_leaves_the_old_set() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let all = cases(d);
    let disk = d.join("disk");
    std::fs::create_dir(&disk).unwrap();
    let mounted = std::process::Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=4m", "tmpfs"])
        .arg(&disk)
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !mounted {
        eprintln!(
            "full-disk case skipped: mounting a tmpfs needs root; the `ulimit -f` case covers a failing write"
        );
        return;
    }
    let _guard = Mounted(disk.clone());
    for case in all {
        let retarget = |v: &[String]| -> Vec<String> {
            v.iter()
                .map(|a| {
                    if a == "out" {
                        "disk/out".to_string()
                    } else if let Some(rest) = a.strip_prefix("out/") {
                        format!("disk/out/{rest}")
                    } else {
                        a.clone()
                    }
                })
                .collect()
        };
        let _ = std::fs::remove_dir_all(disk.join("out"));
        let _ = std::fs::remove_file(disk.join("filler"));
        let o = finish_within(
            spawn_limited(d, &os(&retarget(&case.old))),
            case.name,
            LONG_RUN_AFTER,
        );
        assert_eq!(o.code, Some(0), "{}: {}", case.name, o.stderr);
        let old = stable(listing(&disk.join("out")), case.volatile);
        // Fill the disk (tmpfs counts whole 4 KiB pages: not one is left for a product).
        // SAFETY: statvfs on a valid NUL-terminated path into a zeroed struct.
        let free = unsafe {
            let c = std::ffi::CString::new(disk.as_os_str().as_encoded_bytes()).unwrap();
            let mut s: libc::statvfs = std::mem::zeroed();
            assert_eq!(libc::statvfs(c.as_ptr(), &mut s), 0);
            s.f_bavail as u64 * s.f_frsize as u64
        };
        let filler = free as usize;
        // A filler cut short by the full disk fills it all the same.
        let _ = std::fs::write(disk.join("filler"), vec![0u8; filler]);
        let o = finish(spawn_limited(d, &os(&retarget(&case.new))), case.name);
        let what = format!("{} on a full disk", case.name);
        assert_one_error(&o, &what, &["no space left"]);
        assert_eq!(
            stable(listing(&disk.join("out")), case.volatile),
            old,
            "{what}"
        );
        assert!(litter(d).is_empty(), "{what}: litter {:?}", litter(d));
    }
}

/// `eoir run` of the fixture scene `s.hdr` through a small still MultimIR into `out`, with
/// `extra` arguments.
fn still_run(out: &str, extra: &[&str]) -> Vec<OsString> {
    // A still camera: a moving one would drift the frames off the fixture scene.
    let mut v = strings(&[
        "run",
        "--sensor",
        "multimir",
        "--option",
        "sequence=still",
        "--quiet",
    ]);
    v.extend(strings(&SMALL));
    v.extend(strings(&["s.hdr", "-o", out]));
    v.extend(strings(extra));
    os(&v)
}

#[test]
fn two_runs_into_one_folder_end_with_one_complete_set() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fixture_scene(d);
    let run = |out: &str, seed: &str| still_run(out, &["--frames", "12", "--seed", seed]);
    let volatile = ["report.json", "report.html"];
    let mut refs = Vec::new();
    for seed in ["1", "2"] {
        let o = finish_within(
            spawn_limited(d, &run(&format!("ref{seed}"), seed)),
            "reference",
            LONG_RUN_AFTER,
        );
        assert_eq!(o.code, Some(0), "{}", o.stderr);
        refs.push(stable(listing(&d.join(format!("ref{seed}"))), &volatile));
    }
    for trial in 0..2 {
        let _ = std::fs::remove_dir_all(d.join("out"));
        let a = spawn_limited(d, &run("out", "1"));
        let b = spawn_limited(d, &run("out", "2"));
        let oa = finish_within(a, "run 1", LONG_RUN_AFTER);
        let ob = finish_within(b, "run 2", LONG_RUN_AFTER);
        assert_eq!(
            (oa.code, ob.code),
            (Some(0), Some(0)),
            "{}\n{}",
            oa.stderr,
            ob.stderr
        );
        let now = stable(listing(&d.join("out")), &volatile);
        let differs = |r: &Listing| -> Vec<&PathBuf> {
            now.iter()
                .filter(|(k, v)| r.get(*k) != Some(*v))
                .map(|(k, _)| k)
                .collect()
        };
        assert!(
            now == refs[0] || now == refs[1],
            "trial {trial}: the folder mixes the two runs ({} files; unlike run 1: {:?}; unlike run 2: {:?})",
            now.len(),
            differs(&refs[0]),
            differs(&refs[1])
        );
        assert!(
            litter(d).is_empty(),
            "trial {trial}: litter {:?}",
            litter(d)
        );
    }
}

/// A run into the folder of a longer run leaves its own set, not its frames beside the
/// old run's later ones; a file of the user's in the folder stays.
#[test]
fn a_shorter_run_replaces_the_longer_set_and_leaves_other_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fixture_scene(d);
    let run = |out: &str, frames: &str| still_run(out, &["--frames", frames]);
    let volatile = ["report.json", "report.html"];
    for (out, frames) in [("fresh", "3"), ("out", "12")] {
        let o = finish_within(spawn_limited(d, &run(out, frames)), "run", LONG_RUN_AFTER);
        assert_eq!(o.code, Some(0), "{}", o.stderr);
    }
    std::fs::write(d.join("out/notes.txt"), b"mine").unwrap();
    let o = finish_within(spawn_limited(d, &run("out", "3")), "run", LONG_RUN_AFTER);
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    let mut now = stable(listing(&d.join("out")), &volatile);
    assert!(
        now.remove(Path::new("notes.txt")).is_some(),
        "the user's file was removed"
    );
    let fresh = stable(listing(&d.join("fresh")), &volatile);
    let extra: Vec<_> = now.keys().filter(|k| !fresh.contains_key(*k)).collect();
    assert!(extra.is_empty(), "left from the 12-frame run: {extra:?}");
    assert_eq!(now, fresh);
}

/// `eoir run` writes a sequence's frames into the staging set as they are exposed (issue
/// 34): a write that fails part-way through the sequence — here `dn_stack.npy`, which
/// grows by one 32 × 32 DN frame (2 KiB) per frame, passes `ulimit -f 6` (6 KiB) when its
/// buffer is first written out, at frame 3 of 16, long before the products written at
/// the end — is one error, and the output folder keeps the complete old set, with no
/// frames of the failed run and no staging litter.
#[test]
fn a_failure_part_way_through_a_streamed_sequence_leaves_the_old_set() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fov = (32.0 * 0.24e-3f64).to_degrees().to_string();
    let scene = [
        "scene",
        "blackbody",
        "--rows",
        "32",
        "--cols",
        "32",
        "--lo-um",
        "4.4",
        "--hi-um",
        "5.4",
        "--bands",
        "11",
        "--fov-deg",
        &fov,
        "-o",
        "s32.hdr",
    ];
    let o = super::common::eoir(d, &scene);
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    let run = |frames: &str| {
        os(&strings(&[
            "run",
            "--sensor",
            "multimir",
            "--option",
            "sequence=still",
            "--quiet",
            "--set",
            "detector.rows=32",
            "--set",
            "detector.cols=32",
            "s32.hdr",
            "-o",
            "out",
            "--frames",
            frames,
        ]))
    };
    let o = finish_within(spawn_limited(d, &run("3")), "run", LONG_RUN_AFTER);
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    let volatile = ["report.json", "report.html"];
    let old = stable(listing(&d.join("out")), &volatile);
    let what = "a 16-frame run under ulimit -f 6";
    let o = finish(spawn_limited_with(d, &run("16"), "ulimit -f 6"), what);
    assert_one_error(&o, what, &["file too large", "dn_stack.npy"]);
    assert_eq!(stable(listing(&d.join("out")), &volatile), old, "{what}");
    assert!(litter(d).is_empty(), "{what}: litter {:?}", litter(d));
}
