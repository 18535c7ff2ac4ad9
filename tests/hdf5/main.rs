//! Integration tests of the optional `hdf5` feature that call the library:
//! `cargo test --release --features hdf5 --test hdf5`. The HDF5 reader and writer
//! (`io_hdf5`), and the parallel HDF5 sequence (`frames_parallel`'s HDF5 case; its other
//! tests also run here, being in the same file). The CLI's tests of product sets (which
//! then hold `products.h5`) are in `tests/all`, and check whichever `eoir` they run
//! against (`eoir --version` names the optional features); `.ci/run` runs them against
//! the HDF5 build.

#[path = "../all/frames_parallel.rs"]
mod frames_parallel;
mod io_hdf5;
