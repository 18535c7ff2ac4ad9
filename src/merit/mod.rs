//! Figures of merit of a sensor (docs/figures-of-merit.md): 3-D noise, GIQE 5 NIIRS, MRTD
//! and TTP range performance, each as a pure function of the quantities it needs, and
//! [`assess`], which evaluates them analytically from a [`crate::sensor::Sensor`] and
//! measures them on frames the same sensor simulates.

pub mod assess;
pub mod giqe;
pub mod mrtd;
pub mod noise3d;
pub mod plots;
pub mod run_report;
pub mod ttp;
