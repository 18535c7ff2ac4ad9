//! eoir's integration tests, one crate (one link of the library) with a module per area.

mod architecture;
mod atmosphere;
mod browser;
mod calibration;
mod cfa;
mod characterize;
mod cli;
mod detector;
mod edge_mtf;
mod edge_mtf_cli;
mod fuzz;
mod golden;
mod hostile;
mod imaging;
mod io_envi;
mod io_exr;
#[cfg(feature = "hdf5")]
mod io_hdf5;
mod io_npy;
mod io_raster;
mod motion;
mod nuc_cli;
mod optics;
mod otf_table;
mod perf_determinism;
mod presets;
mod presets_run;
mod processing;
mod products;
mod radiometry;
mod restore;
mod scenes;
mod sensor_config;
mod sequence_pieces;
mod spectrum;
mod third_party;
