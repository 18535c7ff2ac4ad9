//! Band planes served straight from read-only memory maps of the input file (`mmap`), so
//! that f32 planes stored contiguously in the machine's byte order and in eoir's units
//! (ENVI band-sequential, NPY `<f4`, and the band-order scratch file an ENVI BIP frame is
//! transposed into, `io::spill`) cost no copy at all: the imaging engine's row pass
//! reads the page cache itself. One map per plane, unmapped as soon as the engine is done
//! with it, so the mapped pages counted in the resident set stay those of the two chunks
//! in flight (memory stays flat in the band count). A `read()` into a
//! buffer costs the kernel's copy (≈ 14 % of the samples of a 1024² × 128 run) and the
//! buffer's own memory traffic on top.
//!
//! A memory map has one failure mode a `read()` has not: if another process truncates
//! the file while it is mapped, touching a page past the new end raises `SIGBUS`. The
//! readers check the file's size when they open it and again right after mapping, and
//! the `eoir` command installs a handler that turns a `SIGBUS` into a one-line error
//! naming the cause ([`install_sigbus_message`]); a library user who cannot accept the
//! risk turns mapping off with [`crate::io::ReadOptions::no_memory_map`].

use std::ffi::c_void;
use std::fs::File;
use std::sync::atomic::{AtomicBool, Ordering};

use ndarray::ArrayView2;

/// A read-only, private memory map of a byte range of a file, unmapped on drop.
#[derive(Debug)]
pub struct Mapping {
    /// Start of the mapping (page-aligned).
    base: *mut c_void,
    /// Length of the mapping, bytes.
    len: usize,
    /// Offset of the requested range from `base`, bytes.
    start: usize,
    /// Length of the requested range, bytes.
    bytes: usize,
}

// SAFETY: the mapping is read-only (PROT_READ, MAP_PRIVATE) and owned by this value: no
// one writes through it, so sharing and sending references to it is sound.
unsafe impl Send for Mapping {}
// SAFETY: as above.
unsafe impl Sync for Mapping {}

impl Mapping {
    /// Maps `bytes` bytes of `file` from `offset` (any alignment), read-only, with the
    /// pages mapped at once (one call instead of a fault per page; on Linux in 2 MiB
    /// pages where the page cache holds or can read 2 MiB folios, see
    /// `advise_and_populate`). Fails (and the caller falls back to reading) if the file
    /// cannot be mapped or no longer covers the range.
    pub fn new(file: &File, offset: u64, bytes: usize) -> std::io::Result<Self> {
        let file_len = file.metadata()?.len();
        let end = offset.checked_add(bytes as u64);
        if bytes == 0 || end.is_none_or(|e| e > file_len) {
            return Err(std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                "the range to map is empty or past the end of the file",
            ));
        }
        let page = page_size();
        let aligned = offset - offset % page;
        let start = (offset - aligned) as usize;
        let len = start + bytes;
        let base = map_read_only(file, aligned, len)?;
        let map = Mapping {
            base,
            len,
            start,
            bytes,
        };
        // The file may have been truncated between the check and the mapping.
        if file.metadata()?.len() < offset + bytes as u64 {
            return Err(std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                "the file was truncated while it was being mapped",
            ));
        }
        Ok(map)
    }

    /// The mapped range as f32 values in the machine's byte order, if it starts on a
    /// 4-byte boundary and holds a whole number of them.
    pub fn as_f32(&self) -> Option<&[f32]> {
        // SAFETY: `base + start .. base + start + bytes` lies inside the live mapping.
        let ptr = unsafe { (self.base as *const u8).add(self.start) };
        if (ptr as usize) % std::mem::align_of::<f32>() != 0 || self.bytes % 4 != 0 {
            return None;
        }
        // SAFETY: aligned (checked), inside the mapping, which lives as long as `self`
        // and is never written; every bit pattern is a valid f32.
        Some(unsafe { std::slice::from_raw_parts(ptr as *const f32, self.bytes / 4) })
    }
}

impl Drop for Mapping {
    fn drop(&mut self) {
        unmap(self.base, self.len);
    }
}

/// The system's page size (mappings start on a page boundary).
#[cfg(unix)]
fn page_size() -> u64 {
    // SAFETY: sysconf has no preconditions.
    let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
    u64::try_from(page).ok().filter(|&p| p > 0).unwrap_or(4096)
}

/// Set once `MADV_POPULATE_READ` has been refused as unknown (Linux before 5.14): later
/// maps go straight to `MAP_POPULATE`.
#[cfg(target_os = "linux")]
static POPULATE_READ_REFUSED: AtomicBool = AtomicBool::new(false);

/// `mmap` flags of a read-only private map populated when it is made, where the system
/// can (`MAP_POPULATE`); elsewhere the pages are mapped as they are first touched.
#[cfg(any(target_os = "linux", target_os = "android"))]
const MAP_POPULATED: libc::c_int = libc::MAP_PRIVATE | libc::MAP_POPULATE;
#[cfg(all(unix, not(any(target_os = "linux", target_os = "android"))))]
const MAP_POPULATED: libc::c_int = libc::MAP_PRIVATE;

/// Maps `len` bytes of `file` from the page-aligned `offset`, read-only and private,
/// the pages populated at once where the system can: on Linux mapped, then advised and
/// populated in 2 MiB pages ([`advise_and_populate`]), or with `MAP_POPULATE` on kernels
/// that do not know `MADV_POPULATE_READ`; elsewhere with `MAP_POPULATE` where it exists.
#[cfg(unix)]
fn map_read_only(file: &File, offset: u64, len: usize) -> std::io::Result<*mut c_void> {
    #[cfg(target_os = "linux")]
    if !POPULATE_READ_REFUSED.load(Ordering::Relaxed) {
        let base = map_file(file, offset, len, libc::MAP_PRIVATE)?;
        if advise_and_populate(base, len) {
            return Ok(base);
        }
        unmap(base, len);
        POPULATE_READ_REFUSED.store(true, Ordering::Relaxed);
    }
    map_file(file, offset, len, MAP_POPULATED)
}

/// `mmap` of `len` bytes of `file` from the page-aligned `offset`, read-only, `flags`.
#[cfg(unix)]
fn map_file(
    file: &File,
    offset: u64,
    len: usize,
    flags: libc::c_int,
) -> std::io::Result<*mut c_void> {
    use std::os::fd::AsRawFd;
    let off = libc::off_t::try_from(offset).map_err(std::io::Error::other)?;
    // SAFETY: a fresh mapping (null hint) of a file descriptor the caller holds open, of a
    // range the file covers (checked by the caller); read-only and private, so the memory
    // is never written through it. Ownership of the mapping passes to the caller.
    let base = unsafe {
        libc::mmap(
            std::ptr::null_mut(),
            len,
            libc::PROT_READ,
            flags,
            file.as_raw_fd(),
            off,
        )
    };
    if base == libc::MAP_FAILED {
        return Err(std::io::Error::last_os_error());
    }
    Ok(base)
}

/// Populates a fresh file map's page tables in one call, in 2 MiB pages where it can.
///
/// The map is first advised `MADV_HUGEPAGE`. The kernel then reads the pages that are not
/// yet in the page cache in 2 MiB folios (its readahead for such maps), and maps 2 MiB
/// folios of the page cache with one page-table entry each instead of 512. On this
/// project's benchmark machine a 4 MiB plane in 2 MiB folios maps in 0.05 ms and unmaps
/// in 0.01 ms, against 0.5 and 0.1 ms in 4 KiB folios; the row pass reading it needs 512
/// times fewer TLB entries. Then `MADV_POPULATE_READ` (Linux 5.14) maps every page, as
/// `MAP_POPULATE` would, which cannot be used here because it populates before any
/// advice can be given. The huge-page advice is a hint (refused where transparent huge
/// pages are off; the values never depend on it). False: the kernel does not know
/// `MADV_POPULATE_READ` (`EINVAL`). Any other failure of it (an I/O error, a file
/// truncated meanwhile) is left, as `MAP_POPULATE` leaves it, to the first touch and to
/// [`Mapping::new`]'s size check.
#[cfg(target_os = "linux")]
fn advise_and_populate(base: *mut c_void, len: usize) -> bool {
    // SAFETY: advice on exactly the mapping just made, which nothing references yet;
    // neither call changes its contents or validity.
    unsafe {
        libc::madvise(base, len, libc::MADV_HUGEPAGE);
        libc::madvise(base, len, libc::MADV_POPULATE_READ) == 0
            || std::io::Error::last_os_error().raw_os_error() != Some(libc::EINVAL)
    }
}

/// Unmaps what [`map_read_only`] mapped.
#[cfg(unix)]
fn unmap(base: *mut c_void, len: usize) {
    // SAFETY: `base`/`len` are exactly what mmap returned, and the owning `Mapping` is
    // being dropped: no reference into the mapping outlives it (they all borrow it).
    unsafe {
        libc::munmap(base, len);
    }
}

#[cfg(not(unix))]
fn page_size() -> u64 {
    4096
}

/// No memory maps off Unix: readers fall back to reading.
#[cfg(not(unix))]
fn map_read_only(_: &File, _: u64, _: usize) -> std::io::Result<*mut c_void> {
    Err(std::io::Error::new(
        std::io::ErrorKind::Unsupported,
        "memory maps are used on Unix only",
    ))
}

#[cfg(not(unix))]
fn unmap(_: *mut c_void, _: usize) {}

/// A `rows × cols` plane of f32 values in the machine's byte order stored at `offset`
/// of `file`, mapped: `None` if it cannot be (mapping fails, or the offset is not on a
/// 4-byte boundary), and the caller reads it instead.
pub(crate) fn map_plane(
    file: &File,
    offset: u64,
    rows: usize,
    cols: usize,
) -> Option<(Mapping, usize, usize)> {
    let map = Mapping::new(file, offset, rows * cols * 4).ok()?;
    map.as_f32().is_some().then_some((map, rows, cols))
}

/// What a caller needs to check planes read with
/// [`crate::io::CubeReader::read_planes_deferred`] itself: their source and, per plane,
/// band index and wavelength.
#[derive(Debug, Clone)]
pub struct DeferredCheck {
    path: std::path::PathBuf,
    bands: Vec<usize>,
    wavelength_um: Vec<f64>,
}

impl DeferredCheck {
    /// The check of `bands` of `path`, with the cube's wavelengths (indexed by band).
    pub fn new(path: &std::path::Path, bands: &[usize], wavelength_um: &[f64]) -> Self {
        DeferredCheck {
            path: path.to_path_buf(),
            bands: bands.to_vec(),
            wavelength_um: wavelength_um.to_vec(),
        }
    }

    /// The full check of `planes` (the planes it was made for), with the error every
    /// reader gives ([`BandPlanes::check`]): for a caller whose own fast test
    /// ([`crate::scene::radiance_is_physical`]) found a bad value, to name it.
    pub fn run(&self, planes: &BandPlanes) -> crate::error::Result<()> {
        planes.check(&self.path, &self.bands, &self.wavelength_um)
    }
}

/// Band planes of one read ([`crate::io::CubeReader::read_planes`]): owned buffers, or
/// views of memory maps of the input file (one per plane).
#[derive(Debug)]
pub enum BandPlanes {
    /// Planes read into buffers (given back with [`crate::io::CubeReader::recycle`]).
    Owned(Vec<ndarray::Array2<f32>>),
    /// Planes served from memory maps: `(mapping, rows, cols)` per plane.
    Mapped(Vec<(Mapping, usize, usize)>),
}

impl Default for BandPlanes {
    fn default() -> Self {
        BandPlanes::Owned(Vec::new())
    }
}

impl BandPlanes {
    /// Number of planes.
    pub fn len(&self) -> usize {
        match self {
            BandPlanes::Owned(v) => v.len(),
            BandPlanes::Mapped(v) => v.len(),
        }
    }

    /// Whether there are no planes.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Checks every plane for NaN, ±Inf and negative radiance
    /// ([`crate::scene::check_radiance_plane`], the message every reader gives), plane k
    /// being band `bands[k]` of `path`, at `wavelength_um[bands[k]]`.
    pub fn check(
        &self,
        path: &std::path::Path,
        bands: &[usize],
        wavelength_um: &[f64],
    ) -> crate::error::Result<()> {
        let source = path.display().to_string();
        for (view, &b) in self.views().into_iter().zip(bands) {
            crate::scene::check_radiance_plane(&source, b, wavelength_um[b], view)?;
        }
        Ok(())
    }

    /// Every plane as a `[row, col]` view.
    pub fn views(&self) -> Vec<ArrayView2<'_, f32>> {
        match self {
            BandPlanes::Owned(v) => v.iter().map(|p| p.view()).collect(),
            BandPlanes::Mapped(v) => v
                .iter()
                .map(|(m, rows, cols)| {
                    let data = m.as_f32().expect("checked when the plane was mapped");
                    ArrayView2::from_shape((*rows, *cols), data)
                        .expect("the mapping holds rows × cols values")
                })
                .collect(),
        }
    }
}

/// Set by the `SIGBUS` handler ([`install_sigbus_message`]) before it asks the
/// clean-up thread to end the process.
static SIGBUS_SEEN: AtomicBool = AtomicBool::new(false);

/// Exit status after a `SIGBUS` on a mapped input (`EX_IOERR`).
pub const SIGBUS_EXIT_STATUS: i32 = 74;

/// Whether a `SIGBUS` was caught ([`install_sigbus_message`]): the clean-up thread of
/// [`crate::io::output::install_signal_handler`] then exits with
/// [`SIGBUS_EXIT_STATUS`] instead of reporting an interruption.
pub fn sigbus_seen() -> bool {
    SIGBUS_SEEN.load(Ordering::SeqCst)
}

/// Installs a `SIGBUS` handler: with input files memory-mapped, a `SIGBUS` means one of
/// them was truncated (or its storage failed) while it was being read, and without the
/// handler the process would die with "Bus error" and no explanation. The handler prints
/// one line naming the cause on standard error, then sends the process `SIGTERM`, so
/// that the clean-up thread of [`crate::io::output::install_signal_handler`] removes the
/// unfinished product set and exits with [`SIGBUS_EXIT_STATUS`]; if nothing has ended
/// the process 5 s later, the handler exits with that status itself. The faulting thread
/// cannot go on (returning would fault again), so it waits. For the `eoir` command
/// only; a library leaves the process's signal handlers alone.
pub fn install_sigbus_message() {
    #[cfg(unix)]
    install_sigbus_handler();
}

/// [`install_sigbus_message`] on Unix.
#[cfg(unix)]
fn install_sigbus_handler() {
    extern "C" fn on_sigbus(_: libc::c_int) {
        const MSG: &[u8] = b"error: an input file was truncated or became unreadable while eoir was reading it (SIGBUS on its memory map); no products were written. Re-run on an unchanging copy of the file, or with --no-mmap.\n";
        SIGBUS_SEEN.store(true, Ordering::SeqCst);
        // SAFETY: write(2), getpid(2), kill(2), nanosleep(2) and _exit(2) are
        // async-signal-safe, and a lock-free atomic store is too.
        unsafe {
            libc::write(2, MSG.as_ptr() as *const libc::c_void, MSG.len());
            libc::kill(libc::getpid(), libc::SIGTERM);
            let wait = libc::timespec {
                tv_sec: 5,
                tv_nsec: 0,
            };
            libc::nanosleep(&wait, std::ptr::null_mut());
            libc::_exit(SIGBUS_EXIT_STATUS);
        }
    }
    // SAFETY: a zeroed sigaction with a handler that only calls async-signal-safe
    // functions; installing it has no other precondition.
    unsafe {
        let mut sa: libc::sigaction = std::mem::zeroed();
        sa.sa_sigaction = on_sigbus as *const () as usize;
        libc::sigemptyset(&mut sa.sa_mask);
        libc::sigaction(libc::SIGBUS, &sa, std::ptr::null_mut());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    #[test]
    fn maps_unaligned_offsets_and_refuses_ranges_past_the_end() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("data.bin");
        let values: Vec<f32> = (0..5000).map(|i| i as f32 * 0.5).collect();
        let mut f = File::create(&path).unwrap();
        f.write_all(&[0u8; 12]).unwrap();
        for v in &values {
            f.write_all(&v.to_ne_bytes()).unwrap();
        }
        drop(f);
        let f = File::open(&path).unwrap();
        // From value 1000 on: byte offset 12 + 4000, not page-aligned.
        let m = Mapping::new(&f, 12 + 4000, 4 * 3000).unwrap();
        assert_eq!(m.as_f32().unwrap(), &values[1000..4000]);
        // Two bytes off a 4-byte boundary: mapped, but not viewable as f32.
        let m = Mapping::new(&f, 14, 8).unwrap();
        assert!(m.as_f32().is_none());
        assert!(Mapping::new(&f, 12, 4 * 5000 + 1).is_err());
        assert!(Mapping::new(&f, 12, 0).is_err());
    }

    /// Resident bytes of the mapping that starts at `base` (`/proc/self/smaps`).
    #[cfg(target_os = "linux")]
    fn resident_bytes(base: *mut c_void) -> u64 {
        let smaps = std::fs::read_to_string("/proc/self/smaps").unwrap();
        let start = format!("{:x}-", base as usize);
        let mut lines = smaps.lines().skip_while(|l| !l.starts_with(&start));
        assert!(lines.next().is_some(), "mapping not in smaps");
        let rss = lines.find(|l| l.starts_with("Rss:")).unwrap();
        let kib: u64 = rss.split_whitespace().nth(1).unwrap().parse().unwrap();
        kib * 1024
    }

    /// Both ways of populating give the file's values and map every page before the
    /// first touch (the mapping's resident set is its whole length on return).
    #[cfg(target_os = "linux")]
    #[test]
    fn maps_are_populated_either_way() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("plane.bin");
        let values: Vec<f32> = (0..(3 << 18)).map(|i| (i % 977) as f32).collect();
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_ne_bytes()).collect();
        std::fs::write(&path, &bytes).unwrap();
        let f = File::open(&path).unwrap();
        // Advised and populated; then the fallback for kernels before 5.14, which is what
        // runs there (skipped here if this kernel refuses the advice).
        let advised = map_file(&f, 0, bytes.len(), libc::MAP_PRIVATE).unwrap();
        let maps = if advise_and_populate(advised, bytes.len()) {
            vec![("advised", advised)]
        } else {
            unmap(advised, bytes.len());
            vec![]
        };
        let fallback = map_file(&f, 0, bytes.len(), MAP_POPULATED).unwrap();
        for (how, base) in maps.into_iter().chain([("MAP_POPULATE", fallback)]) {
            assert_eq!(resident_bytes(base), bytes.len() as u64, "{how}");
            // SAFETY: a live read-only mapping of `bytes.len()` bytes made above.
            let mapped = unsafe { std::slice::from_raw_parts(base as *const u8, bytes.len()) };
            assert!(mapped == &bytes[..], "{how}");
            unmap(base, bytes.len());
        }
    }
}
