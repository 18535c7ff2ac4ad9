//! Exposure in whole-frame stages, for the effects that couple pixels or carry state:
//! inter-pixel capacitance ([`super::ipc`]), readout-ordered noise and crosstalk between
//! outputs ([`super::readout`]), and what the focal plane's memory
//! ([`super::memory::FocalPlaneMemory`]) adds to a frame (RTS pixels, persistence, drift).
//!
//! The per-pixel chain is that of [`super::DetectorInstance::expose`] (module
//! documentation of [`super`]); the stages are cut where a step needs the whole frame:
//!
//! 1. mean total electrons `μ = max(signal, 0) + dark + background`, plus what the memory
//!    adds before the charge is collected (RTS dark-current steps, charge released or
//!    trapped by persistence), never below 0;
//! 2. shot noise (one Poisson draw), full-well clip — the collected charge;
//! 3. **inter-pixel capacitance** on the collected charge (it couples the pixels' voltages,
//!    so it also correlates their shot noise; Kannawadi et al. 2016);
//! 4. fixed pattern `e·g·g_drift + o + o_drift + o_RTS`, nonlinearity;
//! 5. white read noise, plus the **readout-ordered correlated noise** of the frame;
//! 6. **crosstalk between outputs** on the analogue values (they carry all the noise);
//! 7. conversion gain, ADC, defects.
//!
//! The random streams are those of the row-by-row path (shot and read noise per row, in
//! the same order), so with every staged effect at its neutral value the DN are the same,
//! bit for bit; the readout noise has streams of its own.

use ndarray::{Array2, ArrayView2, Zip};
use rand::RngExt;
use rand_distr::StandardNormal;
use rayon::prelude::*;

use super::rng::{temporal_stream, Effect};
use super::{
    adc, apply_defect, apply_fpn, apply_nonlinearity, clip_full_well, ipc, mean_total_e, readout,
    shot, DetectorInstance,
};
use crate::error::Result;

/// What the focal plane's memory adds to one frame (every field `None` = nothing).
#[derive(Debug, Clone, Default)]
pub struct FrameExtras {
    /// Mean electrons added before the charge is collected (shot noise applies to them):
    /// RTS dark-current steps and the charge persistence releases (negative: traps).
    pub pre_shot_e: Option<Array2<f64>>,
    /// Factor on each pixel's gain (drift of the PRNU).
    pub gain_factor: Option<Array2<f64>>,
    /// Electrons added to each pixel's offset (drift of the DSNU, RTS offset steps).
    pub offset_e: Option<Array2<f64>>,
}

impl FrameExtras {
    /// `true` when nothing is added.
    pub fn is_empty(&self) -> bool {
        self.pre_shot_e.is_none() && self.gain_factor.is_none() && self.offset_e.is_none()
    }
}

impl DetectorInstance {
    /// One frame through the whole-frame stages (module documentation); `mean_e` checked
    /// by the caller (shape, finite).
    pub(super) fn expose_staged(
        &self,
        mean_e: &Array2<f64>,
        exposure: u64,
        frame: u64,
        extras: &FrameExtras,
    ) -> Result<Array2<u16>> {
        let m = &self.model;
        let (rows, cols) = (m.rows, m.cols);
        for (name, a) in [
            ("pre-shot electrons", &extras.pre_shot_e),
            ("gain factor", &extras.gain_factor),
            ("offset electrons", &extras.offset_e),
        ] {
            if let Some(a) = a {
                if a.dim() != (rows, cols) {
                    return Err(crate::error::Error::param(
                        format!("focal-plane {name}"),
                        format!("{} x {}", a.nrows(), a.ncols()),
                        format!("the detector's {rows} x {cols} pixels"),
                    ));
                }
            }
        }
        // Stages 1–2: the collected charge.
        let mut charge = Array2::<f64>::zeros((rows, cols));
        charge
            .axis_iter_mut(ndarray::Axis(0))
            .into_par_iter()
            .enumerate()
            .for_each(|(i, mut out)| {
                let mut rng = temporal_stream(self.seed, Effect::Shot, exposure, frame, i as u64);
                let pre = extras.pre_shot_e.as_ref().map(|p| p.row(i));
                let signal = mean_e.row(i);
                for j in 0..cols {
                    let mut mu = mean_total_e(signal[j], m.dark_e, m.background_e);
                    if let Some(p) = &pre {
                        mu = (mu + p[j]).max(0.0);
                    }
                    let e = if m.shot_noise {
                        shot(mu, m.full_well_e, &mut rng)
                    } else {
                        mu
                    };
                    out[j] = clip_full_well(e, m.full_well_e);
                }
            });
        // Stage 3: inter-pixel capacitance.
        if let Some(k) = &m.ipc_kernel {
            charge = ipc::apply_ipc(k, &charge);
        }
        // Stages 4–5: fixed pattern, nonlinearity, read noise.
        let correlated = m
            .readout_noise
            .as_ref()
            .map(|r| readout::readout_noise_e(r, rows, cols, self.seed, exposure, frame));
        charge
            .axis_iter_mut(ndarray::Axis(0))
            .into_par_iter()
            .enumerate()
            .for_each(|(i, mut row)| {
                let mut rng = temporal_stream(self.seed, Effect::Read, exposure, frame, i as u64);
                let gain = self.gain.as_ref().map(|g| g.row(i));
                let offset = self.offset_e.as_ref().map(|o| o.row(i));
                let quad = self.quadratic.as_ref().map(|q| q.row(i));
                let gain_factor = extras.gain_factor.as_ref().map(|g| g.row(i));
                let extra_offset = extras.offset_e.as_ref().map(|o| o.row(i));
                let corr = correlated.as_ref().map(|c| c.row(i));
                for j in 0..cols {
                    let g = gain.as_ref().map_or(1.0, |g| g[j])
                        * gain_factor.as_ref().map_or(1.0, |f| f[j]);
                    let o = offset.as_ref().map_or(0.0, |o| o[j])
                        + extra_offset.as_ref().map_or(0.0, |o| o[j]);
                    let mut e = apply_fpn(row[j], g, o);
                    if let Some(q) = &quad {
                        e = apply_nonlinearity(e, q[j]);
                    }
                    if m.read_noise_e > 0.0 {
                        e += m.read_noise_e * rng.sample::<f64, _>(StandardNormal);
                    }
                    if let Some(c) = &corr {
                        e += c[j];
                    }
                    row[j] = e;
                }
            });
        // Stage 6: crosstalk between outputs.
        if let Some(r) = &m.readout_noise {
            readout::apply_output_crosstalk(r, &mut charge);
        }
        // Stage 7: gain, ADC, defects.
        Ok(self.digitise(charge.view()))
    }

    /// Conversion gain, ADC and defects of a frame of analogue values (electrons).
    fn digitise(&self, values_e: ArrayView2<f64>) -> Array2<u16> {
        let m = &self.model;
        let mut dn = Array2::<u16>::zeros(values_e.dim());
        Zip::indexed(&mut dn)
            .and(&values_e)
            .par_for_each(|(i, j), out, &e| {
                let v = adc(m.gain_dn_per_e * e + m.offset_dn, m.max_dn);
                *out = apply_defect(
                    self.defects[[i, j]],
                    v,
                    m.max_dn,
                    self.stuck_dn.as_ref().map(|s| s[[i, j]]),
                );
            });
        dn
    }
}
