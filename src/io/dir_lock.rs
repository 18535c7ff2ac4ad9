//! A cross-process advisory lock on an output directory.
//!
//! [`DirLock::acquire`] takes an exclusive `flock(2)` on the directory itself (opened
//! read-only), so no lock file is ever left behind and a process that dies — even by
//! SIGKILL — releases it with its descriptors. [`super::output::ProductSet::commit`]
//! holds it while it checks the targets and moves a set into place: two eoir processes
//! writing into one directory may stage at the same time, but their moves never
//! interleave, so the directory ends with one complete set from one of them (the one
//! that moved last). A writer that finds the lock taken says so on stderr once and
//! waits; the move it waits for takes milliseconds.
//!
//! The lock is advisory: it orders eoir processes (and any tool that takes the same
//! `flock`), not arbitrary writers. Where the file system does not support `flock` on a
//! directory (some network file systems answer `ENOLCK` or `EOPNOTSUPP`) the move goes
//! ahead unlocked, as it did before the lock existed; every other failure is an error.

use std::fs::File;
use std::path::Path;

use crate::error::{Error, Result};

/// An exclusive lock on a directory, released when dropped.
#[derive(Debug)]
pub struct DirLock {
    /// The open directory holding the lock (`None` where the file system has no `flock`).
    _file: Option<File>,
}

impl DirLock {
    /// Locks `dir` (which must exist) exclusively, waiting for another holder to finish.
    /// `waiting` is called once if the lock is taken, before waiting (the CLI prints a
    /// line).
    ///
    /// Errors: the directory cannot be opened, or `flock` fails for another reason than
    /// the file system not supporting it.
    pub fn acquire(dir: &Path, waiting: impl FnOnce()) -> Result<Self> {
        let file = File::open(dir).map_err(|e| Error::io(dir, e))?;
        #[cfg(unix)]
        {
            use std::os::fd::AsRawFd;
            let fd = file.as_raw_fd();
            // SAFETY: `fd` is an open descriptor owned by `file` for the whole call.
            if unsafe { libc::flock(fd, libc::LOCK_EX | libc::LOCK_NB) } == 0 {
                return Ok(DirLock { _file: Some(file) });
            }
            let e = std::io::Error::last_os_error();
            match e.raw_os_error() {
                Some(libc::EWOULDBLOCK) => {
                    waiting();
                    loop {
                        // SAFETY: as above.
                        if unsafe { libc::flock(fd, libc::LOCK_EX) } == 0 {
                            return Ok(DirLock { _file: Some(file) });
                        }
                        let e = std::io::Error::last_os_error();
                        if e.kind() != std::io::ErrorKind::Interrupted {
                            return Err(Error::io(dir, e));
                        }
                    }
                }
                Some(libc::ENOLCK) | Some(libc::EOPNOTSUPP) | Some(libc::EINVAL) => {
                    Ok(DirLock { _file: None })
                }
                _ => Err(Error::io(dir, e)),
            }
        }
        #[cfg(not(unix))]
        {
            let _ = waiting;
            Ok(DirLock { _file: Some(file) })
        }
    }
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    use std::time::Duration;

    /// A second holder (another open description, as another process has) waits until
    /// the first releases the lock, and is told it waits.
    #[test]
    fn a_second_holder_waits_for_the_first() {
        let dir = tempfile::tempdir().unwrap();
        let first =
            DirLock::acquire(dir.path(), || panic!("the first holder cannot wait")).unwrap();
        let released = Arc::new(AtomicBool::new(false));
        let waited = Arc::new(AtomicBool::new(false));
        let (r, w, p) = (released.clone(), waited.clone(), dir.path().to_path_buf());
        let second = std::thread::spawn(move || {
            let _lock = DirLock::acquire(&p, || w.store(true, Ordering::SeqCst)).unwrap();
            // Only after the first holder let go.
            assert!(r.load(Ordering::SeqCst), "took the lock while it was held");
        });
        std::thread::sleep(Duration::from_millis(100));
        released.store(true, Ordering::SeqCst);
        drop(first);
        second.join().unwrap();
        assert!(
            waited.load(Ordering::SeqCst),
            "the waiting callback never ran"
        );
    }
}
