//! Transfer functions from the wavefront: a sampled generalised pupil (aperture, central
//! obscuration, spider vanes, and a wavefront in Zernike or Seidel terms), its PSF and its
//! complex 2-D OTF at any wavelength, and the wavefront's dependence on field height.
//!
//! - [`pupil`]: the aperture.
//! - [`aberration`]: Zernike (Noll) and Seidel wavefronts, field dependence.
//! - [`transfer`]: PSF = |FFT(P)|², OTF = normalised autocorrelation of P.
//!
//! Conventions and accuracy: docs/wavefront.md.

pub mod aberration;
pub mod pupil;
pub mod transfer;

pub use aberration::{FieldDependence, LocalWavefront, Seidel, WavefrontModel};
pub use pupil::Pupil;
pub use transfer::{PupilTransfer, Sampling};

#[cfg(test)]
mod tests;
