//! A sensor's figures of merit, analytic and measured side by side (docs/figures-of-merit.md).
//!
//! *Analytic*: from the resolved [`Sensor`] — its system transfer function
//! ([`SensorTransfer`], spectrally weighted), its detector model (noise, gain, fixed
//! pattern) and the camera equation — through the pure formulas of [`super::noise3d`],
//! [`super::giqe`], [`super::mrtd`] and [`super::ttp`].
//!
//! *Measured*: on frames the same sensor simulates:
//! - a uniform blackbody at the reference temperature exposed `frames` times through one
//!   detector instance (fixed pattern fixed, temporal noise independent) on a
//!   `window` × `window` crop of the array, decomposed by [`super::noise3d::noise3d`]; a
//!   second stack 1 K warmer gives the measured NETD
//!   ([`crate::processing::netd::measured_netd`]). Defective pixels (dead, hot, stuck) are
//!   left out of this instance (they are outliers, not noise), and the focal-plane memory
//!   effects (RTS, persistence, drift) and readout-ordered noise are not exposed here;
//! - a slanted edge (5°) imaged by the whole engine ([`crate::pipeline::run`]) on the same
//!   window at 4 scene samples per pixel (the same defect-free array), measured by
//!   [`crate::processing::edge_mtf::slanted_edge_mtf`]: MTF50, MTF at Nyquist and RER from
//!   its edge-spread function. A thermal sensor sees a 295 K / 310 K edge; a reflective one
//!   a 5000 K / 5772 K blackbody edge scaled so that the bright side fills half the well.

use ndarray::{Array2, Array3, Axis};
use serde::Serialize;

use super::giqe;
use super::mrtd::{self, MrtdObserver, MrtdPoint};
use super::noise3d::{self, DetectorNoiseModel, Noise3d, Noise3dComponents};
use super::ttp::{self, CtfSample, Display, TtpSensor, TtpTarget};
use crate::detector::DetectorInstance;
use crate::error::{Error, Result};
use crate::io::MemoryCube;
use crate::pipeline::{self, RunOptions};
use crate::processing::edge_mtf::{self, slanted_edge_mtf};
use crate::processing::wiener::SensorTransfer;
use crate::scene::synthetic::{self, SceneParams};
use crate::sensor::{Sensor, SensorConfig};

/// Solid angle of the sun seen from the earth, sr (mean distance): a Lambertian ground of
/// reflectance ρ under the sun at zenith has radiance `ρ·B(λ, 5772 K)·Ω_sun/π`.
pub const SUN_SOLID_ANGLE_SR: f64 = 6.8e-5;

/// Reflectances of the two targets whose signal difference is GIQE 5's SNR (the 7 % and
/// 15 % targets of the GIQE definition, as pyBSM uses).
pub const GIQE_REFLECTANCES: (f64, f64) = (0.07, 0.15);

/// Rows of the CTF_sys tables (frequencies over (0, Nyquist]).
pub const CTF_TABLE_POINTS: usize = 200;

/// The target of the range performance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TargetSpec {
    /// Characteristic size √area, m.
    pub size_m: f64,
    /// Thermal: temperature difference to the background, K.
    pub delta_t_k: f64,
    /// Reflective: inherent contrast C₀.
    pub contrast: f64,
    /// Scene contrast temperature, K (thermal).
    pub sct_k: f64,
    /// Extinction coefficient of the path, 1/km; `None`: from the sensor's `[aerosol]`
    /// (absorption + scattering), or 0 without one.
    pub extinction_per_km: Option<f64>,
}

impl Default for TargetSpec {
    /// A 2.3 m target (NVESD's tactical-vehicle critical dimension) of ΔT 2 K, reflective
    /// contrast 0.3, SCT [`ttp::DEFAULT_SCT_K`], the sensor's extinction.
    fn default() -> Self {
        TargetSpec {
            size_m: 2.3,
            delta_t_k: 2.0,
            contrast: 0.3,
            sct_k: ttp::DEFAULT_SCT_K,
            extinction_per_km: None,
        }
    }
}

impl TargetSpec {
    /// Checks every value; errors name the field (`target.<field>`) and what is valid.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("target.size_m", self.size_m),
            ("target.delta_t_k", self.delta_t_k),
            ("target.contrast", self.contrast),
            ("target.sct_k", self.sct_k),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::param(name, v, "a finite value > 0"));
            }
        }
        if let Some(b) = self.extinction_per_km {
            if !(b.is_finite() && b >= 0.0) {
                return Err(Error::param(
                    "target.extinction_per_km",
                    b,
                    "a finite extinction ≥ 0 per km",
                ));
            }
        }
        Ok(())
    }
}

/// What to assess and how.
#[derive(Debug, Clone, PartialEq)]
pub struct AssessOptions {
    /// Seed of the simulated frames.
    pub seed: u64,
    /// Reference blackbody temperature of the noise measurements, K.
    pub temperature_k: f64,
    /// Frames of the 3-D noise sequence.
    pub frames: usize,
    /// Side of the square detector window the measurements simulate, pixels.
    pub window_px: usize,
    /// The target.
    pub target: TargetSpec,
    /// Ranges of the range curves, m (increasing, > 0).
    pub ranges_m: Vec<f64>,
    /// Elevation of the line of sight above the ground for GIQE's GSD, degrees (90 = nadir).
    pub elevation_deg: f64,
    /// Display and eye assumptions; `None`: [`Display::default_for`] the array width.
    pub display: Option<Display>,
    /// Skip the simulations (analytic figures only, e.g. for sweeps).
    pub analytic_only: bool,
}

impl Default for AssessOptions {
    /// Seed 1, 300 K, 32 frames on a 64-pixel window, the default target, 40 ranges from
    /// 0.5 to 20 km, nadir.
    fn default() -> Self {
        AssessOptions {
            seed: 1,
            temperature_k: 300.0,
            frames: 32,
            window_px: 64,
            target: TargetSpec::default(),
            ranges_m: (0..40)
                .map(|i| 500.0 + i as f64 * 19_500.0 / 39.0)
                .collect(),
            elevation_deg: 90.0,
            display: None,
            analytic_only: false,
        }
    }
}

impl AssessOptions {
    /// Checks every value; errors name the option and what is valid.
    pub fn validate(&self) -> Result<()> {
        self.target.validate()?;
        if !(self.temperature_k.is_finite() && self.temperature_k > 0.0) {
            return Err(Error::param(
                "temperature_k",
                self.temperature_k,
                "a temperature > 0 K",
            ));
        }
        if self.frames < 2 {
            return Err(Error::param("frames", self.frames, "at least 2 frames"));
        }
        if !(16..=1024).contains(&self.window_px) {
            return Err(Error::param(
                "window_px",
                self.window_px,
                "16 to 1024 pixels",
            ));
        }
        if self.ranges_m.len() < 2
            || self.ranges_m.iter().any(|r| !(r.is_finite() && *r > 0.0))
            || self.ranges_m.windows(2).any(|w| w[1] <= w[0])
        {
            return Err(Error::param(
                "ranges",
                format!("{} values", self.ranges_m.len()),
                "at least 2 strictly increasing ranges > 0",
            ));
        }
        if !(self.elevation_deg > 0.0 && self.elevation_deg <= 90.0) {
            return Err(Error::param(
                "elevation_deg",
                self.elevation_deg,
                "an elevation in (0, 90] degrees",
            ));
        }
        Ok(())
    }
}

/// 3-D noise in three units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Noise3dUnits {
    /// DN.
    pub dn: Noise3dComponents,
    /// Electrons.
    pub electrons: Noise3dComponents,
    /// Equivalent temperature, K (thermal sensors; `None` otherwise).
    pub kelvin: Option<Noise3dComponents>,
}

/// One task's range performance.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TaskRange {
    /// Task name.
    pub task: String,
    /// V50 used.
    pub v50: f64,
    /// Probability at each range of [`Analytic::ranges_m`].
    pub probability: Vec<f64>,
    /// Range at P = 0.5, m (`None`: outside the range grid).
    pub range_p50_m: Option<f64>,
    /// Range at P = 0.8, m.
    pub range_p80_m: Option<f64>,
}

/// The CTF_sys tables at one range of a path-dependent system MTF.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RangeCtf {
    /// Range, m.
    pub range_m: f64,
    /// Horizontal CTF_sys at the frequencies of [`Analytic::ctf_sys_h`] (null where the MTF
    /// is ≤ 0).
    pub ctf_sys_h: Vec<f64>,
    /// Vertical CTF_sys, likewise.
    pub ctf_sys_v: Vec<f64>,
}

/// The analytic figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Analytic {
    /// Thermal sensor (response beyond 3 µm).
    pub thermal: bool,
    /// IFOV, rad.
    pub ifov_rad: f64,
    /// Frame rate used by MRTD and TTP, Hz (`[clock]`, else 30).
    pub frame_rate_hz: f64,
    /// Mean signal electrons of the reference scene (thermal: blackbody at the reference
    /// temperature; reflective: the 11 % ground under the zenith sun).
    pub signal_e: f64,
    /// NETD, K (thermal).
    pub netd_k: Option<f64>,
    /// Responsivity, DN/K (thermal).
    pub responsivity_dn_per_k: Option<f64>,
    /// MTF50 along x, cycles/pixel.
    pub mtf50_cy_per_px: Option<f64>,
    /// MTF at Nyquist along x.
    pub mtf_nyquist: f64,
    /// RER along x and y and their geometric mean.
    pub rer_x: f64,
    /// RER along y.
    pub rer_y: f64,
    /// √(RER_x·RER_y).
    pub rer: f64,
    /// Predicted 3-D noise.
    pub noise3d: Noise3dUnits,
    /// MRTD curve (thermal).
    pub mrtd: Option<Vec<MrtdPoint>>,
    /// Ranges of the range curves, m.
    pub ranges_m: Vec<f64>,
    /// GIQE 5 NIIRS at each range (reflective sensors).
    pub niirs: Option<Vec<f64>>,
    /// GIQE 5 SNR at each range (reflective).
    pub giqe_snr: Option<Vec<f64>>,
    /// The display assumptions of the TTP.
    pub display: Display,
    /// Per-frame noise relative to the display mean used by the TTP.
    pub noise_rel: f64,
    /// The target.
    pub target: TtpTarget,
    /// Horizontal CTF_sys table.
    pub ctf_sys_h: Vec<CtfSample>,
    /// Vertical CTF_sys table.
    pub ctf_sys_v: Vec<CtfSample>,
    /// Target contrast at each range.
    pub contrast: Vec<f64>,
    /// TTP value V at each range.
    pub ttp_v: Vec<f64>,
    /// When the sensor has turbulence or aerosol: CTF_sys at each range, with those
    /// components evaluated over that range (V at each range integrates these, on the
    /// frequencies of [`Analytic::ctf_sys_h`]); `None` otherwise (the tables above hold
    /// at every range).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ctf_sys_at_range: Option<Vec<RangeCtf>>,
    /// Task probabilities and ranges.
    pub tasks: Vec<TaskRange>,
}

/// The measured figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Measured {
    /// 3-D noise of the uniform sequence, corrected estimator, in DN, e⁻ and K.
    pub noise3d: Noise3dUnits,
    /// The raw decomposition in DN (both estimators and the mean).
    pub noise3d_dn: Noise3d,
    /// Measured NETD, K (thermal).
    pub netd_k: Option<f64>,
    /// Slanted-edge MTF50, cycles/pixel along the edge normal.
    pub mtf50_cy_per_px: Option<f64>,
    /// Slanted-edge MTF at Nyquist.
    pub mtf_nyquist: Option<f64>,
    /// RER from the edge's measured MTF ([`giqe::rer_from_sampled_mtf`], up to 1
    /// cycle/pixel).
    pub rer: Option<f64>,
    /// RER read off the edge-spread function at ±0.5 px ([`giqe::rer_from_esf`]; its
    /// quarter-pixel bins blur it slightly).
    pub rer_esf: Option<f64>,
    /// The edge's angle, degrees.
    pub edge_angle_deg: Option<f64>,
    /// RER of the system MTF along the measured edge's normal (for the comparison).
    pub rer_analytic_along_normal: Option<f64>,
    /// The edge MTF curve (cycles/pixel, MTF).
    pub edge_mtf: Option<(Vec<f64>, Vec<f64>)>,
    /// Why a measurement is missing.
    pub notes: Vec<String>,
}

/// A whole assessment.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Assessment {
    /// Sensor name.
    pub sensor: String,
    /// Analytic figures.
    pub analytic: Analytic,
    /// Measured figures (`None` with `analytic_only`).
    pub measured: Option<Measured>,
}

/// The frame rate of `sensor`: `[clock] frame_rate_hz`, else 30 Hz.
pub fn frame_rate_hz(sensor: &Sensor) -> f64 {
    sensor
        .clock
        .as_ref()
        .and_then(|c| c.frame_rate_hz)
        .unwrap_or(30.0)
}

/// Signal electrons of the reference scene (see [`Analytic::signal_e`]) times `scale`
/// (a reflectance for the reflective scene).
///
/// A colour-filter-array sensor's pixel sees one dye: the signal is the mosaic's mean over
/// its channels (a Bayer quad: ¼ red, ½ green, ¼ blue). Shot-noise variance is linear in
/// the signal, so the mean pixel's temporal noise is the mosaic's mean noise power.
fn scene_electrons(sensor: &Sensor, thermal: bool, t_k: f64, reflectance: f64) -> Result<f64> {
    if let [r, g, b] = sensor.cfa_channels() {
        let e = |s: &Sensor| scene_electrons(s, thermal, t_k, reflectance);
        return Ok(0.25 * e(r)? + 0.5 * e(g)? + 0.25 * e(b)?);
    }
    if thermal {
        sensor.camera().electrons_blackbody(t_k, sensor.response())
    } else {
        let sun = sensor
            .camera()
            .electrons_blackbody(5772.0, sensor.response())?;
        Ok(sun * reflectance * SUN_SOLID_ANGLE_SR / std::f64::consts::PI)
    }
}

/// The detector-model inputs of the noise prediction at `mean_signal_e`.
fn noise_model(sensor: &Sensor, mean_signal_e: f64) -> DetectorNoiseModel {
    let m = sensor.detector();
    let d = &sensor.detector;
    let fpn = d.fpn.as_ref();
    DetectorNoiseModel {
        mean_total_e: mean_signal_e + m.dark_e() + m.background_e(),
        shot_noise: m.shot_noise(),
        read_noise_e: m.read_noise_e(),
        prnu_sigma_rel: fpn.map_or(0.0, |f| f.prnu_sigma_rel),
        dsnu_sigma_e: fpn.map_or(0.0, |f| f.dsnu_sigma_e),
        bias_gain_correlation: fpn.map_or(0.0, |f| f.bias_gain_correlation),
        row_sigma_e: fpn.map_or(0.0, |f| f.row_sigma_e),
        column_sigma_e: fpn.map_or(0.0, |f| f.column_sigma_e),
        quantisation_e: m.quantisation_noise_dn() / m.gain_dn_per_e(),
    }
}

/// Responsivity dDN/dT of the mean pixel at `t_k`, DN/K.
fn responsivity(sensor: &Sensor, t_k: f64) -> Result<f64> {
    let m = sensor.detector();
    let cam = sensor.camera();
    let resp = sensor.response();
    crate::processing::netd::responsivity_dn_per_k(
        |t| {
            cam.electrons_blackbody(t, resp)
                .map_or(f64::NAN, |e| m.expected_dn(e))
        },
        t_k,
    )
}

/// The analytic figures of `sensor` (module documentation).
///
/// Errors: invalid options, a sensor without a bounded band, or a saturated reference.
pub fn analytic(sensor: &Sensor, opts: &AssessOptions) -> Result<Analytic> {
    opts.validate()?;
    let thermal = sensor.is_thermal();
    let model = sensor.detector();
    let gain = model.gain_dn_per_e();
    let ifov = sensor.ifov_rad();
    let rate = frame_rate_hz(sensor);
    let mid = 0.5 * (GIQE_REFLECTANCES.0 + GIQE_REFLECTANCES.1);
    let signal_e = scene_electrons(sensor, thermal, opts.temperature_k, mid)?;
    let transfer = SensorTransfer::new(sensor)?;
    let hx = |f: f64| transfer.eval(f, 0.0);
    let hy = |f: f64| transfer.eval(0.0, f);

    // Noise and NETD.
    let predicted_e = noise3d::predict_noise3d_e(&noise_model(sensor, signal_e));
    let temporal_dn =
        (model.temporal_noise_dn(signal_e).powi(2) + model.quantisation_noise_dn().powi(2)).sqrt();
    let (netd_k, resp) = if thermal {
        let r = responsivity(sensor, opts.temperature_k)?;
        if r == 0.0 {
            return Err(Error::OutOfRange(format!(
                "NETD: the signal does not change with temperature at {} K (saturated?)",
                opts.temperature_k
            )));
        }
        (Some(temporal_dn / r.abs()), Some(r))
    } else {
        (None, None)
    };
    let noise = Noise3dUnits {
        dn: predicted_e.scaled(gain),
        electrons: predicted_e,
        kelvin: resp.map(|r| predicted_e.scaled(gain / r)),
    };

    // MTF figures.
    let mtf50 = {
        let f: Vec<f64> = (0..=400).map(|i| i as f64 * 0.0025).collect();
        let m: Vec<f64> = f.iter().map(|&x| hx(x)).collect();
        edge_mtf::crossing(&f, &m, 0.5)
    };
    let mtf_nyquist = hx(0.5);
    let rer_x = giqe::rer_from_mtf(hx, giqe::RER_MAX_CY_PER_PX)?;
    let rer_y = giqe::rer_from_mtf(hy, giqe::RER_MAX_CY_PER_PX)?;
    let rer = (rer_x.max(0.0) * rer_y.max(0.0)).sqrt();

    // MRTD.
    let mrtd = match netd_k {
        Some(n) => Some(mrtd::mrtd_curve(
            hx,
            n,
            &MrtdObserver::flir92(rate),
            0.5,
            50,
        )?),
        None => None,
    };

    // Atmosphere.
    let extinction_per_m = match opts.target.extinction_per_km {
        Some(b) => b * 1e-3,
        None => sensor
            .aerosol
            .as_ref()
            .filter(|a| a.enabled)
            .map_or(0.0, |a| a.absorption_per_m + a.scattering_per_m),
    };
    let tau = |r: f64| (-extinction_per_m * r).exp();

    // GIQE 5 (reflective).
    let (niirs, giqe_snr) = if thermal {
        (None, None)
    } else {
        let (lo, hi) = GIQE_REFLECTANCES;
        let e_lo = scene_electrons(sensor, false, 0.0, lo)?;
        let e_hi = scene_electrons(sensor, false, 0.0, hi)?;
        let elevation = opts.elevation_deg.to_radians();
        let mut n = Vec::new();
        let mut s = Vec::new();
        for &r in &opts.ranges_m {
            let t = tau(r);
            let sigma = model.temporal_noise_e(0.5 * (e_lo + e_hi) * t);
            let snr = (e_hi - e_lo) * t / sigma.max(f64::MIN_POSITIVE);
            // Slant range r at elevation: the ground sample is IFOV·r.
            let gsd_in = giqe::oblique_gsd_in(ifov * r, elevation)?;
            n.push(giqe::giqe5_niirs(gsd_in, rer.max(1e-6), snr.max(1e-6))?);
            s.push(snr);
        }
        (Some(n), Some(s))
    };

    // TTP.
    let display = opts
        .display
        .unwrap_or_else(|| Display::default_for(sensor.detector.cols));
    let (noise_rel, contrast0) = if thermal {
        (
            netd_k.unwrap_or(0.0) / opts.target.sct_k,
            opts.target.delta_t_k / (2.0 * opts.target.sct_k),
        )
    } else {
        (
            model.temporal_noise_e(signal_e) / signal_e.max(f64::MIN_POSITIVE),
            opts.target.contrast,
        )
    };
    let ts = TtpSensor {
        ifov_rad: ifov,
        frame_rate_hz: rate,
        noise_rel,
    };
    let ctf_h = ttp::ctf_sys_table(hx, &ts, &display, CTF_TABLE_POINTS)?;
    let ctf_v = ttp::ctf_sys_table(hy, &ts, &display, CTF_TABLE_POINTS)?;
    let target = TtpTarget {
        size_m: opts.target.size_m,
        contrast: contrast0,
        extinction_per_m,
    };
    let contrast: Vec<f64> = opts
        .ranges_m
        .iter()
        .map(|&r| target.contrast_at(r))
        .collect();
    // The CTF_sys tables at range r: the sensor's own when no component depends on the
    // path, else with turbulence and aerosol evaluated over r.
    let over_range = sensor.otf().depends_on_range();
    let tables_at = |r: f64| -> Result<(Vec<CtfSample>, Vec<CtfSample>)> {
        let t = transfer.over_range(r)?;
        Ok((
            ttp::ctf_sys_table(|f| t.eval(f, 0.0), &ts, &display, CTF_TABLE_POINTS)?,
            ttp::ctf_sys_table(|f| t.eval(0.0, f), &ts, &display, CTF_TABLE_POINTS)?,
        ))
    };
    let value_at = |r: f64| -> f64 {
        if !over_range {
            return target.value_at(&ctf_h, &ctf_v, r);
        }
        tables_at(r).map_or(f64::NAN, |(h, v)| target.value_at(&h, &v, r))
    };
    // V on the range grid, and for a path-dependent MTF each range's tables (computed once
    // for both).
    let (ttp_v, ctf_sys_at_range) = if over_range {
        let mut v = Vec::with_capacity(opts.ranges_m.len());
        let mut rows = Vec::with_capacity(opts.ranges_m.len());
        for &r in &opts.ranges_m {
            let (h, vt) = tables_at(r)?;
            v.push(target.value_at(&h, &vt, r));
            rows.push(RangeCtf {
                range_m: r,
                ctf_sys_h: h.iter().map(|c| c.ctf_sys).collect(),
                ctf_sys_v: vt.iter().map(|c| c.ctf_sys).collect(),
            });
        }
        (v, Some(rows))
    } else {
        let v = opts.ranges_m.iter().map(|&r| value_at(r)).collect();
        (v, None)
    };
    let (rmin, rmax) = (opts.ranges_m[0], *opts.ranges_m.last().expect("≥ 2 ranges"));
    let tasks = ttp::DEFAULT_TASKS
        .iter()
        .map(|&(name, v50)| {
            let at = &value_at;
            TaskRange {
                task: name.to_string(),
                v50,
                probability: ttp_v.iter().map(|&v| ttp::probability(v, v50)).collect(),
                range_p50_m: ttp::range_at_probability(0.5, v50, at, rmin, rmax),
                range_p80_m: ttp::range_at_probability(0.8, v50, at, rmin, rmax),
            }
        })
        .collect();

    Ok(Analytic {
        thermal,
        ifov_rad: ifov,
        frame_rate_hz: rate,
        signal_e,
        netd_k,
        responsivity_dn_per_k: resp,
        mtf50_cy_per_px: mtf50,
        mtf_nyquist,
        rer_x,
        rer_y,
        rer,
        noise3d: noise,
        mrtd,
        ranges_m: opts.ranges_m.clone(),
        niirs,
        giqe_snr,
        display,
        noise_rel,
        target,
        ctf_sys_h: ctf_h,
        ctf_sys_v: ctf_v,
        contrast,
        ttp_v,
        ctf_sys_at_range,
        tasks,
    })
}

/// `sensor`'s configuration on a `window` × `window` array without defective pixels.
fn windowed(sensor: &Sensor, window: usize) -> Result<Sensor> {
    let mut c: SensorConfig = sensor.config().clone();
    c.detector.rows = window;
    c.detector.cols = window;
    c.detector.defects = None;
    Sensor::build(&c)
}

/// `frames` exposures `[t, v, h]` (DN as f64) of a uniform `mean_e` through `instance`,
/// frame indices from `first`.
fn uniform_stack(
    instance: &DetectorInstance,
    mean_e: f64,
    frames: usize,
    first: u64,
) -> Result<Array3<f64>> {
    let m = instance.model();
    let plane = Array2::from_elem((m.rows(), m.cols()), mean_e);
    let mut cube = Array3::<f64>::zeros((frames, m.rows(), m.cols()));
    for (k, mut out) in cube.axis_iter_mut(Axis(0)).enumerate() {
        let dn = instance.expose(&plane, first + k as u64)?;
        out.assign(&dn.mapv(f64::from));
    }
    Ok(cube)
}

/// The measured figures of `sensor` (module documentation), given its analytic figures.
///
/// Errors: invalid options or a failed simulation; a failed edge measurement is a note.
pub fn measure(sensor: &Sensor, opts: &AssessOptions, analytic: &Analytic) -> Result<Measured> {
    opts.validate()?;
    let thermal = analytic.thermal;
    let w = opts.window_px;
    let mut notes = Vec::new();

    // 3-D noise and NETD on a defect-free instance.
    let clean = windowed(sensor, w)?;
    let model = clean.detector();
    let instance = DetectorInstance::new(model, opts.seed)?;
    let cube = uniform_stack(&instance, analytic.signal_e, opts.frames, 0)?;
    let max = model.max_dn();
    if cube.iter().any(|&v| v <= 0.0 || v >= max) {
        notes.push("the uniform sequence clips at the ADC limits: 3-D noise is biased".into());
    }
    let n3 = noise3d::noise3d(cube.view())?;
    let gain = model.gain_dn_per_e();
    let (netd_k, kelvin) = if thermal {
        let warmer = scene_electrons(&clean, true, opts.temperature_k + 1.0, 0.0)?;
        let cube2 = uniform_stack(&instance, warmer, opts.frames, opts.frames as u64)?;
        let m = crate::processing::netd::measured_netd(cube.view(), cube2.view(), 1.0, None)?;
        let r = m.responsivity_dn_per_k;
        (Some(m.netd_k), Some(n3.corrected.scaled(1.0 / r)))
    } else {
        (None, None)
    };
    let noise = Noise3dUnits {
        dn: n3.corrected,
        electrons: n3.corrected.scaled(1.0 / gain),
        kelvin,
    };

    // Slanted edge through the whole engine.
    let edge_sensor = clean;
    let mut m50 = None;
    let mut nyq = None;
    let mut rer = None;
    let mut rer_esf = None;
    let mut angle = None;
    let mut rer_normal = None;
    let mut curve = None;
    match edge_frame(&edge_sensor, opts.seed, thermal)
        .and_then(|img| slanted_edge_mtf(img.view(), None))
    {
        Ok(m) => {
            m50 = m.mtf50_cy_per_px;
            nyq = m.mtf_nyquist;
            angle = Some(m.angle_deg);
            match giqe::rer_from_esf(&m.esf, 1.0 / edge_mtf::OVERSAMPLING as f64, 0.15) {
                Ok(r) => rer_esf = Some(r),
                Err(e) => notes.push(format!("RER of the edge-spread function: {e}")),
            }
            rer = Some(giqe::rer_from_sampled_mtf(&m.freq_cy_per_px, &m.mtf)?);
            let transfer = SensorTransfer::new(&edge_sensor)?;
            let th = m.angle_deg.to_radians();
            let (c, s) = if m.vertical {
                (th.cos(), -th.sin())
            } else {
                (-th.sin(), th.cos())
            };
            rer_normal = Some(giqe::rer_from_mtf(
                |f| transfer.eval(f * c, f * s),
                giqe::RER_MAX_CY_PER_PX,
            )?);
            curve = Some((m.freq_cy_per_px.clone(), m.mtf.clone()));
            notes.extend(m.warnings.iter().map(|w| format!("edge: {w}")));
        }
        Err(e) => notes.push(format!("edge MTF not measured: {e}")),
    }

    Ok(Measured {
        noise3d: noise,
        noise3d_dn: n3,
        netd_k,
        mtf50_cy_per_px: m50,
        mtf_nyquist: nyq,
        rer,
        rer_esf,
        edge_angle_deg: angle,
        rer_analytic_along_normal: rer_normal,
        edge_mtf: curve,
        notes,
    })
}

/// One DN frame (as f64) of a 5° slanted edge through the whole engine (module
/// documentation), on the sensor's (windowed) array.
fn edge_frame(sensor: &Sensor, seed: u64, thermal: bool) -> Result<Array2<f64>> {
    let (lo, hi) = sensor.response().support_um();
    let (rows, cols) = (sensor.detector.rows, sensor.detector.cols);
    let p = SceneParams {
        rows,
        cols,
        oversampling: 4,
        wavelength_um: SceneParams::uniform_grid(lo, hi, 24)?,
        fov_x_deg: (sensor.ifov_rad() * cols as f64).to_degrees(),
        range_m: None,
        seed,
        sun: false,
    };
    let mut cube = if thermal {
        synthetic::edge(&p, 295.0, 310.0, 5.0)?
    } else {
        synthetic::edge(&p, 5000.0, 5772.0, 5.0)?
    };
    if !thermal {
        // Scale the bright side to half the full well.
        let e = sensor
            .camera()
            .electrons_blackbody(5772.0, sensor.response())?;
        let scale = 0.5 * sensor.detector().full_well_e() / e.max(f64::MIN_POSITIVE);
        cube.data.mapv_inplace(|v| (v as f64 * scale) as f32);
    }
    let mut reader = MemoryCube::new(cube);
    let opts = RunOptions {
        seed,
        calibration: None,
        ..Default::default()
    };
    let out = pipeline::run(sensor, &mut reader, &opts, |_, _| {})?;
    Ok(out.frames[0].dn.mapv(f64::from))
}

/// The whole assessment: [`analytic`], then [`measure`] unless `analytic_only`.
pub fn assess(sensor: &Sensor, opts: &AssessOptions) -> Result<Assessment> {
    let a = analytic(sensor, opts)?;
    let m = if opts.analytic_only {
        None
    } else {
        Some(measure(sensor, opts, &a)?)
    };
    Ok(Assessment {
        sensor: sensor.name.clone(),
        analytic: a,
        measured: m,
    })
}
