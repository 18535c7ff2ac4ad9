//! `.npy` stacks of 2-D frames, `[frame, row, col]`, written one frame at a time
//! ([`StackWriter`]) or from frames in memory: a sequence's DN (`dn_stack.npy`) and its
//! per-frame truth maps. The header is the reader's ([`super::npy`]) NPY 1.0 layout.

use std::path::Path;

use crate::error::{Error, Result};

use super::npy::npy_header;
use super::write_all;

/// Writes frames of equal shape as one `<f4` `[frame, row, col]` `.npy` stack, atomically
/// (per-frame truth maps of a sequence, e.g. the charge held in persistence traps).
pub fn write_f32_stack(path: &Path, frames: &[ndarray::ArrayView2<f32>]) -> Result<()> {
    write_stack(path, StackWriter::f32, frames)
}

/// Writes frames of equal shape as one `<u2` `[frame, row, col]` `.npy` stack, atomically
/// (a sequence's DN frames in one file for NumPy: `np.load` gives the stack).
pub fn write_u16_stack(path: &Path, frames: &[ndarray::ArrayView2<u16>]) -> Result<()> {
    write_stack(path, StackWriter::u16, frames)
}

/// One `[frame, row, col]` stack of the frames in memory, through a [`StackWriter`] made
/// by `create` (so a stack written frame by frame has the same bytes).
fn write_stack<T: Copy>(
    path: &Path,
    create: fn(&Path, usize, usize, usize) -> Result<StackWriter<T>>,
    frames: &[ndarray::ArrayView2<T>],
) -> Result<()> {
    let (r, c) = frames.first().map_or((0, 0), |f| f.dim());
    let mut stack = create(path, frames.len(), r, c)?;
    for f in frames {
        stack.push(f.view())?;
    }
    stack.finish()
}

/// A `[frame, row, col]` `.npy` stack written one frame at a time, atomically: the header
/// states the shape given at the start, each [`StackWriter::push`] appends one frame
/// (little-endian, C order), and [`StackWriter::finish`] checks that every frame came and
/// renames the file into place. Dropped unfinished, nothing is left at the path. Only one
/// frame's bytes are held at a time, so a sequence's stack needs no memory for the
/// sequence.
#[derive(Debug)]
pub struct StackWriter<T: Copy> {
    file: super::AtomicFile,
    shape: (usize, usize, usize),
    written: usize,
    put: fn(T, &mut Vec<u8>),
    buf: Vec<u8>,
}

impl StackWriter<u16> {
    /// A `<u2` stack of `frames` frames of `rows × cols`.
    pub fn u16(path: &Path, frames: usize, rows: usize, cols: usize) -> Result<Self> {
        StackWriter::create(path, "<u2", (frames, rows, cols), |v, buf| {
            buf.extend_from_slice(&v.to_le_bytes())
        })
    }
}

impl StackWriter<f32> {
    /// A `<f4` stack of `frames` frames of `rows × cols`.
    pub fn f32(path: &Path, frames: usize, rows: usize, cols: usize) -> Result<Self> {
        StackWriter::create(path, "<f4", (frames, rows, cols), |v, buf| {
            buf.extend_from_slice(&v.to_le_bytes())
        })
    }
}

impl<T: Copy> StackWriter<T> {
    fn create(
        path: &Path,
        descr: &str,
        shape: (usize, usize, usize),
        put: fn(T, &mut Vec<u8>),
    ) -> Result<Self> {
        let mut file = super::AtomicFile::create(path)?;
        write_all(
            file.writer(),
            &npy_header(descr, &[shape.0, shape.1, shape.2]),
            path,
        )?;
        Ok(StackWriter {
            file,
            shape,
            written: 0,
            put,
            buf: Vec::new(),
        })
    }

    /// Appends the next frame.
    ///
    /// Errors: a frame of another shape than the stack's, a frame beyond the count, I/O.
    pub fn push(&mut self, frame: ndarray::ArrayView2<T>) -> Result<()> {
        let (n, r, c) = self.shape;
        let path = self.file.path().to_path_buf();
        if frame.dim() != (r, c) {
            return Err(Error::format(
                &path,
                format!(
                    "frames of different shapes ({r}x{c} and {}x{})",
                    frame.nrows(),
                    frame.ncols()
                ),
            ));
        }
        if self.written >= n {
            return Err(Error::format(
                &path,
                format!("more frames than the {n} the stack's header states"),
            ));
        }
        self.buf.clear();
        for v in frame.iter() {
            (self.put)(*v, &mut self.buf);
        }
        write_all(self.file.writer(), &self.buf, &path)?;
        self.written += 1;
        Ok(())
    }

    /// Renames the complete stack into place.
    ///
    /// Errors: fewer frames than the header states, I/O.
    pub fn finish(self) -> Result<()> {
        if self.written != self.shape.0 {
            return Err(Error::format(
                self.file.path(),
                format!(
                    "{} of the {} frames the stack's header states were written",
                    self.written, self.shape.0
                ),
            ));
        }
        self.file.commit()
    }
}
