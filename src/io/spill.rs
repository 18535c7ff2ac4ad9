//! A band-sequential scratch file: where a reader whose format interleaves the bands
//! (ENVI BIP, OpenEXR scan-line blocks) puts a frame after decoding it once, so that any
//! band can then be read back with one sequential read while memory holds only one block.
//!
//! Why a file and not memory: a pixel-interleaved frame can only be read band by band by
//! reading the *whole* frame for every chunk of bands (B/C passes for chunks of C of B
//! bands) or by holding every band (memory ∝ B). Transposing it once into band order on
//! disk costs one read and one write of the frame, and every later band read is a single
//! contiguous read: I/O stays O(frame), memory O(block).
//!
//! The file is created in the system temporary directory (`TMPDIR`, default `/tmp`) and,
//! on Unix, unlinked immediately after creation, so nothing is left behind whatever way
//! the process ends; elsewhere it is removed when the spill is dropped. It holds f32
//! samples in native byte order, `[band][row][col]`. If the temporary directory is a RAM
//! disk (tmpfs) the spill lives in memory after all; point `TMPDIR` at a disk then.

use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use super::mapped::{map_plane, BandPlanes};
use crate::error::{Error, Result};

/// Distinguishes the spill files of one process.
static SPILL_COUNTER: AtomicU64 = AtomicU64::new(0);

/// A `[band][row][col]` f32 scratch file (see the module documentation).
#[derive(Debug)]
pub(crate) struct BandSpill {
    file: File,
    /// Where the file was created (already unlinked on Unix).
    path: PathBuf,
    /// Still to be removed on drop (non-Unix systems).
    remove_on_drop: bool,
    rows: usize,
    cols: usize,
    bands: usize,
}

impl BandSpill {
    /// Creates an empty spill for `bands` planes of `rows × cols` on behalf of `source`
    /// (named in errors).
    pub(crate) fn create(source: &Path, bands: usize, rows: usize, cols: usize) -> Result<Self> {
        let bytes = crate::limits::checked_count(
            &format!("the band-order scratch file for {}", source.display()),
            &[
                ("bands", bands as u64),
                ("rows", rows as u64),
                ("cols", cols as u64),
                ("bytes", 4),
            ],
        )?;
        let n = SPILL_COUNTER.fetch_add(1, Ordering::Relaxed);
        let path =
            std::env::temp_dir().join(format!(".eoir-band-spill-{}-{n}.f32", std::process::id()));
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(true)
            .open(&path)
            .map_err(|e| spill_error(source, &path, "cannot create", e))?;
        // Unlinked now, the file lives as long as the handle (Unix semantics); nothing to
        // clean up after a crash or a signal.
        let remove_on_drop = !cfg!(unix) || std::fs::remove_file(&path).is_err();
        file.set_len(bytes)
            .map_err(|e| spill_error(source, &path, "cannot size", e))?;
        Ok(BandSpill {
            file,
            path,
            remove_on_drop,
            rows,
            cols,
            bands,
        })
    }

    /// Writes `values` (a whole number of samples) into band `band` starting at
    /// `(row, col)`, continuing row-major: a run of full rows when `col = 0` and
    /// `values.len()` is a multiple of the row length.
    pub(crate) fn write(
        &mut self,
        source: &Path,
        band: usize,
        row: usize,
        col: usize,
        values: &[f32],
    ) -> Result<()> {
        let start = (band * self.rows + row) * self.cols + col;
        let end = start + values.len();
        if band >= self.bands || end > (band + 1) * self.rows * self.cols {
            return Err(Error::format(
                source,
                format!(
                    "a block at band {band}, row {row}, col {col} of {} samples lies outside the {} × {} image",
                    values.len(),
                    self.rows,
                    self.cols
                ),
            ));
        }
        // The values' native bytes, as they are in memory (`to_ne_bytes` of each).
        let bytes: &[u8] = bytemuck::cast_slice(values);
        self.file
            .seek(SeekFrom::Start(start as u64 * 4))
            .and_then(|_| self.file.write_all(bytes))
            .map_err(|e| spill_error(source, &self.path, "cannot write", e))
    }

    /// Bands `bands` mapped read-only (the values [`BandSpill::read`] returns, straight
    /// from the page cache, as `map_plane` maps a band-sequential input), or `None` if
    /// one cannot be mapped or is not in the file (the caller then reads them).
    pub(crate) fn map_bands(&self, bands: &[usize]) -> Option<BandPlanes> {
        let n = self.rows * self.cols;
        let map = |b: usize| {
            (b < self.bands).then_some(())?;
            map_plane(&self.file, (b * n) as u64 * 4, self.rows, self.cols)
        };
        let planes: Option<Vec<_>> = bands.iter().map(|&b| map(b)).collect();
        planes.map(BandPlanes::Mapped)
    }

    /// Reads band `band` back (`rows × cols` samples, row-major) with one read.
    pub(crate) fn read(&mut self, source: &Path, band: usize) -> Result<Vec<f32>> {
        let n = self.rows * self.cols;
        // Read straight into the plane: the file holds the values' native bytes.
        let mut values = vec![0f32; n];
        self.file
            .seek(SeekFrom::Start((band * n) as u64 * 4))
            .and_then(|_| {
                self.file
                    .read_exact(bytemuck::cast_slice_mut(&mut values[..]))
            })
            .map_err(|e| spill_error(source, &self.path, "cannot read", e))?;
        Ok(values)
    }
}

impl Drop for BandSpill {
    fn drop(&mut self) {
        if self.remove_on_drop {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// An I/O error on the scratch file, naming the input it serves and where it lives.
fn spill_error(source: &Path, path: &Path, what: &str, e: std::io::Error) -> Error {
    Error::format(
        source,
        format!(
            "{what} the band-order scratch file {} ({e}); it needs as much free space as one frame of the cube in the temporary directory (set TMPDIR to choose it)",
            path.display()
        ),
    )
}
