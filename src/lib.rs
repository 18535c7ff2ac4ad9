//! # eoir — electro-optical / infrared sensor model
//!
//! eoir turns the spectral radiance a scene generator computed for every pixel into the
//! image a real camera records, and back into radiance and apparent temperature.
//!
//! The crate follows the flow of `DESIGN.md`: spectra and radiometry feed a spectral
//! chain, transfer functions (optics, atmosphere, motion) form a cascade evaluated in
//! angular frequency (cycles/rad), and the sensor description ties them together.
//!
//! Modules, in dependency order (a module uses only those above it):
//! - [`constants`]: SI constants (2019 exact values).
//! - [`error`]: the typed error every fallible function returns.
//! - [`limits`]: the memory budget every size from a file or the command line is checked against.
//! - [`spectrum`]: spectral curves (filters, QE, transmissions) and integration weights.
//! - [`radiometry`]: Planck's law, band integrals, the camera equation, apparent temperature.
//! - [`optics`]: aperture, aberration, defocus, detector-footprint transfer functions.
//! - [`motion`]: linear smear, jitter and global Gaussian transfer functions.
//! - [`atmosphere`]: Fried parameter, turbulence and aerosol transfer functions.
//! - [`cfa`]: colour filter arrays: mosaicking, demosaicking, false-colour composites.
//! - [`sensor`]: the sensor configuration schema, validation and the system OTF cascade.
//! - [`plot`]: PNG line plots with an embedded font (no system font libraries).
//! - [`report`]: figures of merit (MTF curves, …) and their plots.
//! - [`imaging`]: the engine — spectral weights, frequency-domain accumulation, detector sampling.
//! - [`pipeline`]: the whole chain top to bottom, and the products it writes.
//! - [`scene`]: the spectral radiance cube type and its geometry.
//! - [`io`]: cube readers/writers (ENVI, spectral EXR, NPY, HDF5) and product writers.
//!
//! ```no_run
//! use eoir::{io, pipeline, sensor::presets};
//!
//! # fn main() -> eoir::Result<()> {
//! let options = ["filter=4".to_string()]; // preset options
//! let overrides = ["detector.integration_time_s=2e-3".to_string()]; // like --set
//! let sensor = presets::load("multimir", &options, &overrides)?;
//! let mut cube = io::open(std::path::Path::new("scene.hdr"))?; // band-by-band reader
//! let out = pipeline::run(&sensor, cube.as_mut(), &pipeline::RunOptions::default(), |_, _| {})?;
//! let dn = &out.frames[0].dn; // Array2<u16>
//! assert_eq!(dn.dim(), (sensor.detector.rows, sensor.detector.cols));
//! out.write(std::path::Path::new("out"))?;
//! # Ok(())
//! # }
//! ```
#![warn(missing_docs)]

pub mod atmosphere;
pub mod calibration;
pub mod cfa;
pub mod constants;
pub mod detector;
pub mod error;
pub mod imaging;
pub mod io;
pub mod limits;
pub mod motion;
pub mod optics;
pub mod pipeline;
pub mod plot;
pub mod processing;
pub mod radiometry;
pub mod report;
pub mod scene;
pub mod sensor;
pub mod spectrum;

pub use error::{Error, Result};
