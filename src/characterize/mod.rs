//! EMVA 1288 camera characterisation: acquisition-set descriptors, simulated acquisition
//! sets made by the detector model, the analysis of a set (simulated or recorded by a real
//! camera), and the datasheet outputs.

pub mod analysis;
pub mod datasheet;
pub mod descriptor;
pub mod rts;
pub mod simulate;
pub mod uncertainty;

pub use analysis::{characterize, descriptor_path, Characterization, PairLevel};
pub use datasheet::write_outputs;
pub use descriptor::{Descriptor, Series};
pub use simulate::{simulate, SimulateOptions, Truth};
