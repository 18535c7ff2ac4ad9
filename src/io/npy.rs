//! npy cube format (being written in a parallel branch; this file is replaced there).

use std::path::Path;

use ndarray::Array2;

use crate::error::{Error, Result};
use crate::scene::{Cube, CubeMeta};

/// Band-by-band reader.
pub struct NpyReader {
    meta: CubeMeta,
}

impl NpyReader {
    /// Opens a file.
    pub fn open(path: &Path) -> Result<Self> {
        Err(Error::format(path, "format not available in this build"))
    }
}

impl super::CubeReader for NpyReader {
    fn meta(&self) -> &CubeMeta {
        &self.meta
    }
    fn read_band(&mut self, _frame: usize, _band: usize) -> Result<Array2<f32>> {
        Err(Error::OutOfRange("format not available in this build".into()))
    }
}

/// Writes a cube.
pub fn write(path: &Path, _cube: &Cube) -> Result<()> {
    Err(Error::format(path, "format not available in this build"))
}
