//! Opening input files: the helpers live in [`crate::input`] (above `spectrum` and `optics`
//! in the module order, which read tables too); re-exported here for the readers.

pub use crate::input::*;
