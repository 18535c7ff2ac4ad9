//! Writing outputs safely: whole product sets or none, and never over a special file.
//!
//! # Semantics
//! - **One file** ([`super::atomic_write`]): written to a hidden temporary file
//!   (`.NAME.eoir-tmp-PID`) in the same directory, synced, and renamed over the target
//!   only when complete. The target must be absent or a regular file: a directory,
//!   device, FIFO, socket **or symbolic link** is refused ([`check_output_target`]) —
//!   renaming over it would replace the special file (e.g. `/dev/null`) instead of writing
//!   through it, and following a link would let a planted link redirect the write.
//!   Symlinks in the *directories* of the path are followed.
//! - **A product set** ([`ProductSet`]): every product of a run is written into a staging
//!   directory `.eoir-staging-PID-N` inside the output directory. Only when all of them
//!   succeeded are the targets checked (all of them, before anything moves) and the files
//!   renamed into place; the staging directory is then removed. On any error the staging
//!   directory is removed and the output directory is left exactly as it was (or
//!   removed again, if empty, when the set created it). Products of an earlier run whose
//!   names the new run does not write (e.g. frames beyond the new frame count) are left
//!   alone. Every command that writes more than one file uses it; see [`ProductSet`] for
//!   the API a new command uses.
//! - **One writer at a time**: [`ProductSet::commit`] holds an exclusive `flock` on the
//!   output directory ([`super::dir_lock`]) while it checks and moves, so two processes
//!   writing into one directory end with one complete set from one of them.
//! - **Signals**: [`install_signal_handler`] (the CLI calls it first thing) catches
//!   SIGINT and SIGTERM on a dedicated thread, removes every registered staging directory,
//!   temporary file and (empty) output directory a set created, and exits with status
//!   128 + signal. It also ignores SIGXFSZ, so a write beyond `ulimit -f` fails with
//!   EFBIG like any I/O error and the set is cleaned up instead of the process dying. The move into place holds
//!   the same lock, so a signal during the move waits for it to finish: the directory
//!   then holds either the complete old set or the complete new set.
//!
//!   The main thread keeps running while the handler cleans up, so a writer that had
//!   registered its temporary file just before the signal may still create it (libhdf5's
//!   `H5Fcreate`, which first initialises the library, makes that window milliseconds
//!   wide). The clean-up therefore removes a staging directory until it is really gone
//!   (a file created while `remove_dir_all` walked the directory made its final `rmdir`
//!   fail), a staging directory is created under the lock, so it exists whenever it is
//!   registered, and the handler never releases the lock, so no writer starts another
//!   file. The process then ends with `_exit`: no `atexit` handler runs, in particular not
//!   libhdf5's library shutdown, which would close and flush the HDF5 file the main thread
//!   is still writing.
//! - **`-`** names standard output where a single text stream makes sense (`eoir mtf
//!   --csv -`); see [`is_stdout`].

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard};

use crate::error::{Error, Result};

/// What the signal handler removes before exiting.
#[derive(Debug, Clone, PartialEq)]
enum Cleanup {
    /// A staging directory or temporary file, removed with everything in it.
    Remove(PathBuf),
    /// Output directories a [`ProductSet`] created: `dir` and its parents up to `top`,
    /// each removed only if empty (nothing anybody else put there is touched).
    EmptyDirs { dir: PathBuf, top: PathBuf },
}

/// Staging directories, temporary files and created directories to remove if the
/// process is interrupted.
static CLEANUP: Mutex<Vec<Cleanup>> = Mutex::new(Vec::new());

/// Counter making staging-directory names unique within the process.
static STAGING_SEQ: AtomicUsize = AtomicUsize::new(0);

/// Prefix of staging directory names (for tests and cleanup tools).
pub const STAGING_PREFIX: &str = ".eoir-staging-";

/// Marker contained in every temporary file name.
pub const TEMP_MARKER: &str = ".eoir-tmp-";

fn cleanup_list() -> MutexGuard<'static, Vec<Cleanup>> {
    CLEANUP.lock().unwrap_or_else(|p| p.into_inner())
}

/// Registers `path` (a temporary file or staging directory) for removal on SIGINT/SIGTERM.
pub fn register_cleanup(path: &Path) {
    cleanup_list().push(Cleanup::Remove(path.to_path_buf()));
}

/// Removes `path` from the cleanup list (it was renamed into place or removed).
pub fn unregister_cleanup(path: &Path) {
    let mut l = cleanup_list();
    unregister_in(&mut l, &Cleanup::Remove(path.to_path_buf()));
}

fn unregister_in(list: &mut Vec<Cleanup>, entry: &Cleanup) {
    if let Some(i) = list.iter().rposition(|p| p == entry) {
        list.remove(i);
    }
}

/// Removes `dir` and its parents up to and including `top` while they are empty,
/// innermost first (`remove_dir` only removes empty directories).
fn remove_empty_dirs(dir: &Path, top: &Path) {
    let mut d = Some(dir);
    while let Some(p) = d {
        if std::fs::remove_dir(p).is_err() || p == top {
            break;
        }
        d = p.parent();
    }
}

/// `std::fs::create_dir_all` for directories inside a staging directory, holding the
/// clean-up lock: once the signal handler has removed the staging directory (and kept
/// the lock), a writer still running cannot create it again and leave it behind — it
/// blocks here until the process exits, like a writer registering its next file.
pub fn create_dir_all_guarded(path: &Path) -> Result<()> {
    let _list = cleanup_list();
    std::fs::create_dir_all(path).map_err(|e| Error::io(path, e))
}

/// Passes of [`remove_any`] over a directory that another thread may still be adding a
/// file to (each writer adds at most one once the clean-up holds the lock).
const REMOVE_PASSES: usize = 100;

/// Removes a file, or a directory with everything in it. A directory is removed again
/// while it still exists (up to [`REMOVE_PASSES`] times, 1 ms apart), because a file
/// created in it while `remove_dir_all` walked it makes the final `rmdir` fail.
fn remove_any(path: &Path) {
    for _ in 0..REMOVE_PASSES {
        match std::fs::symlink_metadata(path) {
            Ok(m) if m.is_dir() => {
                if std::fs::remove_dir_all(path).is_ok() {
                    return;
                }
            }
            Ok(_) => {
                let _ = std::fs::remove_file(path);
                return;
            }
            Err(_) => return,
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
}

/// What the signal handler does before exiting: removes every registered path, newest
/// first (a staging directory before the output directory created for it), holding (and
/// keeping) the lock `list` so that nothing new is registered.
fn remove_registered(list: &[Cleanup]) {
    for p in list.iter().rev() {
        match p {
            Cleanup::Remove(p) => remove_any(p),
            Cleanup::EmptyDirs { dir, top } => remove_empty_dirs(dir, top),
        }
    }
}

/// Installs the SIGINT/SIGTERM handler described in the module documentation. Call once,
/// early; later calls do nothing. Errors if the handler cannot be registered.
#[cfg(unix)]
pub fn install_signal_handler() -> Result<()> {
    use signal_hook::consts::{SIGINT, SIGTERM};
    static INSTALLED: std::sync::Once = std::sync::Once::new();
    let mut result = Ok(());
    INSTALLED.call_once(|| {
        // A write beyond `ulimit -f` then fails with EFBIG, an ordinary I/O error that
        // the writer reports and the product set cleans up, instead of SIGXFSZ killing
        // the process with its staging directory and temporary files left behind.
        // SAFETY: setting a signal's disposition to "ignore" has no handler to run.
        unsafe { libc::signal(libc::SIGXFSZ, libc::SIG_IGN) };
        match signal_hook::iterator::Signals::new([SIGINT, SIGTERM]) {
            Ok(mut signals) => {
                let spawned = std::thread::Builder::new()
                    .name("eoir-signals".into())
                    .spawn(move || {
                        if let Some(sig) = signals.forever().next() {
                            // Holding the lock: a product set being moved into place
                            // finishes first, and nothing new is registered meanwhile.
                            let list = cleanup_list();
                            // Nothing registered: no set was being staged (none begun, or
                            // the last one already moved into place, complete).
                            let what = if list.is_empty() {
                                "no unfinished outputs to remove"
                            } else {
                                "removed unfinished outputs"
                            };
                            remove_registered(&list);
                            // A SIGBUS on a mapped input sends SIGTERM to get here
                            // (`mapped::install_sigbus_message`, which said why).
                            let code = if super::mapped::sigbus_seen() {
                                eprintln!("eoir: {what}");
                                super::mapped::SIGBUS_EXIT_STATUS
                            } else {
                                eprintln!("eoir: interrupted (signal {sig}); {what}");
                                128 + sig
                            };
                            // `_exit`, still holding the lock: no atexit handlers (libhdf5's
                            // shutdown would touch the file the main thread is writing).
                            signal_hook::low_level::exit(code);
                        }
                    });
                if let Err(e) = spawned {
                    result = Err(Error::io("signal handler thread", e));
                }
            }
            Err(e) => result = Err(Error::io("signal handler", e)),
        }
    });
    result
}

/// Installs nothing where POSIX signals do not exist.
#[cfg(not(unix))]
pub fn install_signal_handler() -> Result<()> {
    Ok(())
}

/// `true` when `path` is `-`, i.e. standard output.
pub fn is_stdout(path: &Path) -> bool {
    path.as_os_str() == "-"
}

/// Checks that `path` may be (re)written as an output file: it must not exist, or be a
/// regular file. Directories, devices, FIFOs, sockets and symbolic links are refused
/// with an error naming what the path is.
pub fn check_output_target(path: &Path) -> Result<()> {
    match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(Error::io(path, e)),
        Ok(m) if m.file_type().is_file() => Ok(()),
        Ok(m) => Err(Error::format(
            path,
            format!(
                "is {}; eoir writes outputs only as regular files and never replaces {} (give a new file name{})",
                super::input::kind_name(&m),
                if m.file_type().is_symlink() { "a symbolic link" } else { "a special file or directory" },
                if m.file_type().is_symlink() { " or the link's real target" } else { "" },
            ),
        )),
    }
}

/// A set of products written together: into a staging directory first, moved into the
/// output directory by [`ProductSet::commit`] only when all were written, removed (with
/// the output directory untouched, or removed again if this set created it) when dropped
/// uncommitted. Every command that writes more than one file writes them through one.
///
/// # Using it
///
/// ```no_run
/// use std::path::Path;
/// use eoir::io::output::ProductSet;
///
/// # fn main() -> eoir::error::Result<()> {
/// # let frame = ndarray::Array2::<f32>::zeros((4, 4));
/// let set = ProductSet::begin(Path::new("out"))?;       // creates out/ if needed
/// // Any writer that takes a path: it is given the staged path, and errors name the
/// // final one (`out/frames/frame-0000.tiff`). Subdirectories are created as needed.
/// set.write("frames/frame-0000.tiff", |p| {
///     eoir::io::raster::write_tiff_f32(p, frame.view())
/// })?;
/// set.write_bytes("los.csv", b"frame,x_px,y_px\n0,0.0,0.0\n")?;
/// set.write_json("summary.json", &serde_json::json!({ "frames": 1 }))?;
/// // Nothing in out/ has changed until here; now every product moves into place.
/// for p in set.commit()? {
///     println!("wrote {}", p.display());
/// }
/// # Ok(()) }
/// ```
///
/// - Write everything first and call [`ProductSet::commit`] last: a `?` that returns
///   early drops the set, which removes what was staged and leaves `out/` as it was.
/// - Check values before writing them ([`check_finite`]) so a bad result is an error,
///   not a product.
/// - Writers that want a directory rather than a file name can write under
///   [`ProductSet::staging_dir`] directly; [`ProductSet::name_final`] turns their errors
///   into errors naming the final paths.
/// - SIGINT/SIGTERM at any moment (after [`install_signal_handler`]) leaves the old set
///   or the complete new one; a full disk, `ulimit -f` (SIGXFSZ is ignored, so the write
///   fails with EFBIG) or a special file in place of a product is an error before
///   anything moves.
/// - [`ProductSet::commit`] holds a cross-process lock on the output directory
///   ([`super::dir_lock::DirLock`]) while it moves the set: two processes writing into one
///   directory end with one complete set from one of them.
#[derive(Debug)]
pub struct ProductSet {
    dir: PathBuf,
    staging: PathBuf,
    /// The outermost output directory level [`ProductSet::begin`] created.
    created: Option<PathBuf>,
    committed: bool,
    /// The kind of set this one replaces ([`ProductSet::replacing`]).
    replaces: Option<String>,
}

/// Prefix of the file listing the products of the last set of a kind
/// ([`ProductSet::replacing`]): `.eoir-products-<kind>` in the output directory.
pub const MANIFEST_PREFIX: &str = ".eoir-products-";

/// Attempts at creating the staging directory when the output directory disappears in
/// between (another process's uncommitted set removed it, empty, as its own creation).
const BEGIN_ATTEMPTS: usize = 5;

impl ProductSet {
    /// Creates the output directory if needed and a fresh staging directory inside it.
    ///
    /// Errors: `dir` exists and is not a directory, or it cannot be created.
    pub fn begin(dir: &Path) -> Result<Self> {
        if let Ok(m) = std::fs::metadata(dir) {
            if !m.is_dir() {
                return Err(Error::format(
                    dir,
                    format!(
                        "the output directory is {}, not a directory",
                        super::input::kind_name(&m)
                    ),
                ));
            }
        }
        // The outermost directory this call creates, removed again if nothing is committed.
        let mut created = None;
        let mut a = Some(dir);
        while let Some(d) = a.filter(|d| !d.as_os_str().is_empty() && !d.exists()) {
            created = Some(d.to_path_buf());
            a = d.parent();
        }
        let n = STAGING_SEQ.fetch_add(1, Ordering::Relaxed);
        let staging = dir.join(format!("{STAGING_PREFIX}{}-{n}", std::process::id()));
        let mut attempt = 0;
        loop {
            // Created and registered under the lock: the signal handler sees the staging
            // directory either not at all (and nothing exists) or registered and
            // existing, and once it has cleaned up (keeping the lock) no output or
            // staging directory is created again (a set staged inside another's staging
            // directory blocks here).
            let mut list = cleanup_list();
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
            match std::fs::create_dir(&staging) {
                Ok(()) => {
                    if let Some(top) = &created {
                        list.push(Cleanup::EmptyDirs {
                            dir: dir.to_path_buf(),
                            top: top.clone(),
                        });
                    }
                    list.push(Cleanup::Remove(staging.clone()));
                    break;
                }
                Err(e) if e.kind() == std::io::ErrorKind::NotFound && attempt < BEGIN_ATTEMPTS => {
                    attempt += 1;
                }
                Err(e) => return Err(Error::io(&staging, e)),
            }
        }
        Ok(ProductSet {
            dir: dir.to_path_buf(),
            staging,
            created,
            committed: false,
            replaces: None,
        })
    }

    /// Makes this set replace the last set of the same `kind` (e.g. `"run"`) committed
    /// into the output directory: files that set wrote and this one does not are removed
    /// when this one commits, so a 3-frame run into the folder of a 12-frame run leaves
    /// the 3 frames, not 3 new frames beside 9 old ones. The set's file names are kept in
    /// `.eoir-products-<kind>` (one relative path per line); only regular files named
    /// there are ever removed, never anything else in the folder.
    pub fn replacing(mut self, kind: &str) -> Self {
        self.replaces = Some(kind.to_string());
        self
    }

    /// Where the products are to be written (same relative names as in the output).
    pub fn staging_dir(&self) -> &Path {
        &self.staging
    }

    /// The final output directory.
    pub fn output_dir(&self) -> &Path {
        &self.dir
    }

    /// The staged path of the product `name` (a relative path such as `a.tiff` or
    /// `frames/0001.tiff`). Parent directories are not created (see [`ProductSet::write`]).
    pub fn path(&self, name: impl AsRef<Path>) -> PathBuf {
        self.staging.join(name)
    }

    /// The final path of a product written at `staged` inside the staging directory.
    pub fn final_path(&self, staged: &Path) -> PathBuf {
        match staged.strip_prefix(&self.staging) {
            Ok(rel) => self.dir.join(rel),
            Err(_) => staged.to_path_buf(),
        }
    }

    /// `e` with a staged path replaced by the final path it stands for, so an error names
    /// the file the user asked for, not its hidden staging place.
    pub fn name_final(&self, e: Error) -> Error {
        match e {
            Error::Io { path, source } => Error::Io {
                path: self.final_path(&path),
                source,
            },
            Error::Format { path, message } => Error::Format {
                path: self.final_path(&path),
                message,
            },
            other => other,
        }
    }

    /// Writes the product `name` (relative, e.g. `frames/frame-0001.tiff`) by calling
    /// `write` with its staged path; creates the parent directories it needs. Returns the
    /// final path. Errors (from `write` or creating directories) name the final path.
    pub fn write<F>(&self, name: impl AsRef<Path>, write: F) -> Result<PathBuf>
    where
        F: FnOnce(&Path) -> Result<()>,
    {
        let name = name.as_ref();
        if name.is_absolute()
            || name
                .components()
                .any(|c| !matches!(c, std::path::Component::Normal(_)))
        {
            return Err(Error::param(
                "product name",
                name.display(),
                "a relative path without `..` (the product set's own file names)",
            ));
        }
        let staged = self.staging.join(name);
        if let Some(parent) = staged.parent() {
            create_dir_all_guarded(parent).map_err(|e| self.name_final(e))?;
        }
        write(&staged).map_err(|e| self.name_final(e))?;
        Ok(self.dir.join(name))
    }

    /// Writes the product `name` with the bytes `bytes` ([`ProductSet::write`]).
    pub fn write_bytes(&self, name: impl AsRef<Path>, bytes: &[u8]) -> Result<PathBuf> {
        self.write(name, |p| {
            super::atomic_write(p, |w| super::write_all(w, bytes, p))
        })
    }

    /// Writes the product `name` as pretty-printed JSON with a final newline.
    pub fn write_json<T: serde::Serialize>(
        &self,
        name: impl AsRef<Path>,
        value: &T,
    ) -> Result<PathBuf> {
        let name = name.as_ref();
        let mut text = serde_json::to_string_pretty(value).map_err(|e| {
            Error::format(self.dir.join(name), format!("cannot encode the JSON: {e}"))
        })?;
        text.push('\n');
        self.write_bytes(name, text.as_bytes())
    }

    /// Moves every staged file into place and returns their final paths (sorted). All
    /// targets are checked first ([`check_output_target`]; a staged subdirectory needs a
    /// directory or nothing at its place), so a refusal moves nothing. The checks and the
    /// move hold the output directory's cross-process lock
    /// ([`super::dir_lock::DirLock`]); a process that finds it held says so on stderr
    /// and waits for it.
    pub fn commit(mut self) -> Result<Vec<PathBuf>> {
        let mut files = Vec::new();
        let mut dirs = Vec::new();
        collect(&self.staging, Path::new(""), &mut files, &mut dirs)?;
        // The set's list of files moves in with it (a plain write: the staging directory
        // is already registered for clean-up).
        let manifest = self
            .replaces
            .as_ref()
            .map(|kind| PathBuf::from(format!("{MANIFEST_PREFIX}{kind}")));
        if let Some(m) = &manifest {
            files.retain(|f| f != m);
            let mut text = String::new();
            for f in &files {
                text.push_str(&f.to_string_lossy());
                text.push('\n');
            }
            let staged = self.staging.join(m);
            std::fs::write(&staged, text).map_err(|e| Error::io(self.dir.join(m), e))?;
        }
        let dir = self.dir.clone();
        let _lock = super::dir_lock::DirLock::acquire(&self.dir, || {
            eprintln!(
                "eoir: another process is moving its products into {}; waiting for it",
                dir.display()
            )
        })?;
        for d in &dirs {
            let target = self.dir.join(d);
            if let Ok(m) = std::fs::symlink_metadata(&target) {
                if !m.is_dir() {
                    return Err(Error::format(
                        &target,
                        format!(
                            "is {}; a directory of products belongs here",
                            super::input::kind_name(&m)
                        ),
                    ));
                }
            }
        }
        for f in &files {
            check_output_target(&self.dir.join(f))?;
        }
        // The last set of this kind, read before the move replaces its list.
        let stale = match &manifest {
            Some(m) => stale_products(&self.dir.join(m), &files)?,
            None => Vec::new(),
        };
        // The signal handler waits for this lock: the move completes or never starts.
        let mut list = cleanup_list();
        let mut result = Ok(());
        for d in &dirs {
            let target = self.dir.join(d);
            if let Err(e) = std::fs::create_dir_all(&target) {
                result = Err(Error::io(&target, e));
                break;
            }
        }
        if result.is_ok() {
            for f in &files {
                let target = self.dir.join(f);
                if let Err(e) = std::fs::rename(self.staging.join(f), &target) {
                    result = Err(Error::io(&target, e));
                    break;
                }
            }
        }
        if result.is_ok() {
            if let Some(m) = &manifest {
                let target = self.dir.join(m);
                match std::fs::rename(self.staging.join(m), &target) {
                    Ok(()) => result = remove_stale(&self.dir, &stale),
                    Err(e) => result = Err(Error::io(&target, e)),
                }
            }
        }
        unregister_in(&mut list, &Cleanup::Remove(self.staging.clone()));
        if let Some(top) = &self.created {
            unregister_in(
                &mut list,
                &Cleanup::EmptyDirs {
                    dir: self.dir.clone(),
                    top: top.clone(),
                },
            );
        }
        let _ = std::fs::remove_dir_all(&self.staging);
        self.committed = true;
        drop(list);
        result?;
        let mut out: Vec<PathBuf> = files.iter().map(|f| self.dir.join(f)).collect();
        out.sort();
        Ok(out)
    }
}

impl Drop for ProductSet {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.staging);
            let mut list = cleanup_list();
            unregister_in(&mut list, &Cleanup::Remove(self.staging.clone()));
            // Directories this set created, innermost first; `remove_dir` only removes
            // empty ones, so nothing anybody else put there is touched.
            if let Some(top) = &self.created {
                remove_empty_dirs(&self.dir, top);
                unregister_in(
                    &mut list,
                    &Cleanup::EmptyDirs {
                        dir: self.dir.clone(),
                        top: top.clone(),
                    },
                );
            }
        }
    }
}

/// Bytes free to an unprivileged writer on the file system holding `dir` (`statvfs`:
/// available blocks × fragment size); `None` where it cannot be asked (not Unix, or the
/// call fails).
pub fn free_bytes(dir: &Path) -> Option<u64> {
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        let c = std::ffi::CString::new(dir.as_os_str().as_bytes()).ok()?;
        let mut st = std::mem::MaybeUninit::<libc::statvfs>::uninit();
        // SAFETY: `c` is a NUL-terminated path and `st` a buffer of the right type, which
        // statvfs fills on success (return 0); it is read only then.
        if unsafe { libc::statvfs(c.as_ptr(), st.as_mut_ptr()) } != 0 {
            return None;
        }
        // SAFETY: statvfs returned 0, so it initialised `st`.
        let st = unsafe { st.assume_init() };
        // The field types are c_ulong / fsblkcnt_t: u64 here, narrower on other targets.
        #[allow(clippy::unnecessary_cast)]
        (st.f_bavail as u64).checked_mul(st.f_frsize as u64)
    }
    #[cfg(not(unix))]
    {
        let _ = dir;
        None
    }
}

/// Checks that a sequence of `frames` frames of `pixels` pixels fits on the file system of
/// `dir` before a run streams it there: its products take at least `bytes_per_pixel` bytes
/// per pixel and frame (the uncompressed rasters every frame writes), which must not
/// overflow and must be below the free space (when it can be asked, [`free_bytes`]).
///
/// A single frame is not checked: a disk too full for it fails at the write with the
/// system's "no space left".
///
/// Errors: an overflowing size, or (two frames or more) more than the free space; both
/// name the frame count.
pub fn check_room_for_frames(
    dir: &Path,
    frames: usize,
    pixels: usize,
    bytes_per_pixel: u64,
) -> Result<()> {
    let need = (frames as u64)
        .checked_mul(pixels as u64)
        .and_then(|v| v.checked_mul(bytes_per_pixel))
        .ok_or_else(|| {
            Error::param(
                "frames",
                frames,
                format!(
                    "a count whose products fit in a file system: {frames} frames of {pixels} pixels overflows a 64-bit byte count"
                ),
            )
        })?;
    // One frame is the ordinary case: a disk too full for it fails at the write, with the
    // system's own "no space left" error. The check is for sequences long enough to fill it.
    if frames < 2 {
        return Ok(());
    }
    if let Some(free) = free_bytes(dir) {
        if need > free {
            return Err(Error::param(
                "frames",
                frames,
                format!(
                    "a count whose products fit on the disk: {frames} frames of {pixels} pixels take at least {}, and the output's file system has {} free",
                    crate::error::human_bytes(need),
                    crate::error::human_bytes(free)
                ),
            ));
        }
    }
    Ok(())
}

/// Checks that every value of a product is finite before it is written: `values` are
/// the values as they will be stored (e.g. after conversion to f32, where 3.5e38 becomes
/// +inf). Errors name `path` (the final product), the number of non-finite values, the
/// first one's index and what `what` says is valid.
pub fn check_finite(path: &Path, values: impl IntoIterator<Item = f64>, what: &str) -> Result<()> {
    let mut count = 0usize;
    let mut first = None;
    for (i, v) in values.into_iter().enumerate() {
        if !v.is_finite() {
            count += 1;
            first.get_or_insert((i, v));
        }
    }
    match first {
        None => Ok(()),
        Some((i, v)) => Err(Error::format(
            path,
            format!(
                "{count} value(s) would be written non-finite (the first, {v}, at index {i}); nothing was written. {what}"
            ),
        )),
    }
}

/// The files the list `manifest` (of the last set of a kind) names that `files` (the new
/// set) does not: plain relative paths only.
fn stale_products(manifest: &Path, files: &[PathBuf]) -> Result<Vec<PathBuf>> {
    // Never read (or block on) a special file put in its place: refuse it like a product.
    check_output_target(manifest)?;
    let old = match std::fs::read_to_string(manifest) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => String::new(),
        Err(e) => return Err(Error::io(manifest, e)),
    };
    let new: std::collections::BTreeSet<&Path> = files.iter().map(|f| f.as_path()).collect();
    Ok(old
        .lines()
        .map(Path::new)
        .filter(|rel| {
            !rel.as_os_str().is_empty()
                && rel
                    .components()
                    .all(|c| matches!(c, std::path::Component::Normal(_)))
                && !new.contains(rel)
        })
        .map(Path::to_path_buf)
        .collect())
}

/// Removes the `stale` products from `dir` — regular files only; what is gone already or
/// is no longer a regular file is left alone.
fn remove_stale(dir: &Path, stale: &[PathBuf]) -> Result<()> {
    for rel in stale {
        let path = dir.join(rel);
        if std::fs::symlink_metadata(&path).is_ok_and(|m| m.file_type().is_file()) {
            match std::fs::remove_file(&path) {
                Ok(()) => {}
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => return Err(Error::io(&path, e)),
            }
        }
    }
    Ok(())
}

/// Relative paths of the files and directories under `root/rel` (directories first-level
/// before their contents). Iterative, so a deep tree cannot exhaust the stack.
fn collect(
    root: &Path,
    rel: &Path,
    files: &mut Vec<PathBuf>,
    dirs: &mut Vec<PathBuf>,
) -> Result<()> {
    let mut stack = vec![rel.to_path_buf()];
    while let Some(rel) = stack.pop() {
        let here = root.join(&rel);
        let entries = std::fs::read_dir(&here).map_err(|e| Error::io(&here, e))?;
        for entry in entries {
            let entry = entry.map_err(|e| Error::io(&here, e))?;
            let t = entry.file_type().map_err(|e| Error::io(entry.path(), e))?;
            let r = rel.join(entry.file_name());
            if t.is_dir() {
                dirs.push(r.clone());
                stack.push(r);
            } else if entry.file_name().to_string_lossy().contains(TEMP_MARKER) {
                // A temporary file a failed writer could not remove: never publish it.
                continue;
            } else {
                files.push(r);
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A writer that creates one file in a staging directory while the clean-up walks it
    /// (the HDF5 case: the temporary file was registered just before the signal) cannot
    /// leave the directory behind.
    #[test]
    fn a_file_created_during_the_cleanup_does_not_keep_the_staging_directory() {
        let root = tempfile::tempdir().unwrap();
        for attempt in 0..40 {
            let staging = root.path().join(format!("{STAGING_PREFIX}test-{attempt}"));
            std::fs::create_dir(&staging).unwrap();
            for i in 0..400 {
                std::fs::write(staging.join(format!("f{i:04}")), b"x").unwrap();
            }
            let late = staging.join(format!(".products.h5{TEMP_MARKER}1"));
            let barrier = std::sync::Arc::new(std::sync::Barrier::new(2));
            let b = barrier.clone();
            let writer = std::thread::spawn(move || {
                b.wait();
                // Spread the creation over the walk of the directory.
                std::thread::sleep(std::time::Duration::from_micros(50 * attempt as u64));
                let _ = std::fs::write(&late, b"hdf5");
            });
            barrier.wait();
            remove_registered(&[Cleanup::Remove(staging.clone())]);
            writer.join().unwrap();
            assert!(
                !staging.exists(),
                "attempt {attempt}: staging directory left"
            );
        }
    }
}
