//! Opening input files safely: only regular files are read as data or tables.
//!
//! A FIFO named as a cube or a sensor-file table would block the run forever on `open`,
//! a device (`/dev/zero`, `/dev/urandom`) would feed it an endless stream, and a
//! directory gives a confusing OS error. [`open_regular`] checks the metadata (following
//! symlinks) *before* opening, opens with `O_NONBLOCK` so that a path swapped for a FIFO
//! in between cannot block, and checks the opened handle's metadata again; the
//! non-blocking flag is then cleared so reads behave normally. Every reader and table
//! loader goes through it.

use std::fs::File;
use std::io::Read;
use std::path::Path;

use crate::error::{Error, Result};

/// What kind of file system object `meta` describes, for messages.
pub fn kind_name(meta: &std::fs::Metadata) -> &'static str {
    let t = meta.file_type();
    if t.is_dir() {
        return "a directory";
    }
    if t.is_symlink() {
        return "a symbolic link";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if t.is_socket() {
            return "a socket";
        }
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
    }
    if t.is_file() {
        "a regular file"
    } else {
        "not a regular file"
    }
}

fn not_regular(path: &Path, meta: &std::fs::Metadata) -> Error {
    Error::format(
        path,
        format!(
            "is {}; eoir reads data and tables only from regular files",
            kind_name(meta)
        ),
    )
}

/// Opens `path` for reading if it is a regular file (symlinks are followed), without ever
/// blocking on a FIFO; otherwise a typed error naming the path and what it is.
pub fn open_regular(path: &Path) -> Result<File> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(not_regular(path, &meta));
    }
    let file = open_nonblocking(path)?;
    let meta = file.metadata().map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(not_regular(path, &meta));
    }
    clear_nonblocking(&file);
    Ok(file)
}

#[cfg(unix)]
fn open_nonblocking(path: &Path) -> Result<File> {
    use std::os::unix::fs::OpenOptionsExt;
    std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)
        .map_err(|e| Error::io(path, e))
}

#[cfg(not(unix))]
fn open_nonblocking(path: &Path) -> Result<File> {
    File::open(path).map_err(|e| Error::io(path, e))
}

#[cfg(unix)]
fn clear_nonblocking(file: &File) {
    use std::os::unix::io::AsRawFd;
    let fd = file.as_raw_fd();
    // SAFETY: fcntl on a descriptor we own, reading and then clearing one status flag.
    unsafe {
        let flags = libc::fcntl(fd, libc::F_GETFL);
        if flags >= 0 {
            libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK);
        }
    }
}

#[cfg(not(unix))]
fn clear_nonblocking(_file: &File) {}

/// Reads a whole regular file as bytes, refusing files larger than `max_bytes` (a header
/// or table has no business being gigabytes) and anything that is not a regular file.
pub fn read_regular(path: &Path, max_bytes: u64) -> Result<Vec<u8>> {
    let file = open_regular(path)?;
    let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    if len > max_bytes {
        return Err(Error::format(
            path,
            format!(
                "is {} long; a header or table file is at most {}",
                crate::limits::human_bytes(len),
                crate::limits::human_bytes(max_bytes)
            ),
        ));
    }
    let mut out = Vec::with_capacity(len as usize);
    file.take(max_bytes + 1)
        .read_to_end(&mut out)
        .map_err(|e| Error::io(path, e))?;
    if out.len() as u64 > max_bytes {
        return Err(Error::format(
            path,
            format!(
                "grew beyond {} while being read",
                crate::limits::human_bytes(max_bytes)
            ),
        ));
    }
    Ok(out)
}

/// Largest text file (ENVI header, sensor TOML, spectrum CSV, sidecar JSON) read: 64 MiB.
pub const MAX_TEXT_BYTES: u64 = 64 << 20;

/// Reads a UTF-8 text file (header, sensor file, CSV table) through [`read_regular`] with
/// the [`MAX_TEXT_BYTES`] bound. Invalid UTF-8 is an error that does not quote the bytes.
pub fn read_text(path: &Path) -> Result<String> {
    let bytes = read_regular(path, MAX_TEXT_BYTES)?;
    String::from_utf8(bytes).map_err(|e| {
        Error::format(
            path,
            format!(
                "is not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}
