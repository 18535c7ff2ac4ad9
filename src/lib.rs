//! # eoir — electro-optical / infrared sensor model
//!
//! eoir turns the spectral radiance a scene generator computed for every pixel into the
//! image a real camera records, and back into radiance and apparent temperature.
//!
//! The crate follows the flow of `docs/design.md`: spectra and radiometry feed a spectral
//! chain, transfer functions (optics, atmosphere, motion) form a cascade evaluated in
//! angular frequency (cycles/rad), and the resolved [`sensor::Sensor`] ties them together.
//! A configuration ([`sensor::SensorConfig`], what files and `--set` speak) is resolved
//! once by [`sensor::Sensor::build`]; every stage of [`pipeline::run`] takes the `Sensor`.
//!
//! Modules, in dependency order (a module uses only those above it):
//! - [`constants`]: SI constants (2019 exact values).
//! - [`error`]: the typed error every fallible function returns.
//! - [`limits`]: the memory budget every size from a file or the command line is checked against.
//! - [`input`]: opening input files (regular files only, without blocking, size-bounded).
//! - [`spectrum`]: spectral curves (filters, QE, transmissions), their file form
//!   ([`spectrum::SpectrumConfig`]) and integration weights.
//! - [`radiometry`]: Planck's law, band integrals, the camera equation, apparent temperature.
//! - [`optics`]: aperture, aberration, defocus, detector-footprint transfer functions.
//! - [`motion`]: linear smear, jitter and global Gaussian transfer functions.
//! - [`atmosphere`]: Fried parameter, turbulence and aerosol transfer functions.
//! - [`scene`]: the spectral radiance cube type, its geometry, and built-in synthetic scenes.
//! - [`io`]: cube readers/writers (ENVI, spectral EXR, NPY, HDF5) and product writers.
//! - [`cfa`]: colour filter arrays: mosaicking, demosaicking, false-colour composites.
//! - [`plot`]: PNG line plots with an embedded font (no system font libraries).
//! - [`detector`]: the `[detector]` table and the detector model: electrons → DN.
//! - [`los`]: the sequence clock (frame and row exposure times) and the line of sight
//!   (drift, pan, vibration, wander, measured pointing) with its per-window motion OTF.
//! - [`sensor`]: the configuration schema, presets, the transfer-function cascade and the
//!   resolved [`sensor::Sensor`].
//! - [`imaging`]: the engine — spectral weights, frequency-domain accumulation, detector sampling.
//! - [`processing`]: NUC, bad pixels, NETD, photon transfer, temperature tables.
//! - [`calibration`]: the way back from DN to radiance and apparent temperature.
//! - [`report`]: the typed run report and figures of merit (MTF curves) with their plots.
//! - [`display`]: display stretches and colour maps for the pictures a person looks at.
//! - [`pipeline::report_html`]: the pictures of a run and the self-contained `report.html`.
//! - [`pipeline`]: the whole chain, stage by stage, and the products it writes.
//! - [`merit`]: figures of merit (3-D noise, GIQE 5, MRTD, TTP), analytic and measured.
//!
//! ```no_run
//! use eoir::{io, pipeline, sensor::{presets, Sensor}};
//!
//! # fn main() -> eoir::Result<()> {
//! let options = ["filter=4".to_string()]; // preset options
//! let overrides = ["detector.integration_time_s=2e-3".to_string()]; // like --set
//! let config = presets::load("multimir", &options, &overrides)?;
//! let sensor = Sensor::build(&config)?; // validates, reads every referenced file once
//! let mut cube = io::open(std::path::Path::new("scene.hdr"))?; // band-by-band reader
//! let out = pipeline::run(&sensor, cube.as_mut(), &pipeline::RunOptions::default(), |_, _| {})?;
//! let dn = &out.frames[0].dn; // Array2<u16>
//! assert_eq!(dn.dim(), (sensor.detector.rows, sensor.detector.cols));
//! println!("SNR {:.1}", out.report.signal.snr); // the typed report (report.json)
//! out.write(std::path::Path::new("out"))?;
//! # Ok(())
//! # }
//! ```
#![warn(missing_docs)]

pub mod atmosphere;
pub mod calibration;
pub mod cfa;
pub mod characterize;
pub mod constants;
pub mod detector;
pub mod display;
pub mod error;
pub mod fft_size;
pub mod imaging;
pub mod input;
pub mod io;
pub mod limits;
pub mod los;
pub mod memory;
pub mod merit;
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
