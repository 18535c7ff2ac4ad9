//! eoir's integration tests, one crate (one link of the library) with a module per area.

mod atmosphere;
mod calibration;
mod cfa;
mod cli;
mod detector;
mod fuzz;
mod hostile;
mod imaging;
mod io_envi;
mod io_exr;
#[cfg(feature = "hdf5")]
mod io_hdf5;
mod io_npy;
mod io_raster;
mod motion;
mod optics;
mod presets;
mod presets_run;
mod processing;
mod radiometry;
mod scenes;
mod sensor_config;
mod spectrum;
