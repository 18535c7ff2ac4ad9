//! The system transfer function: the product of every enabled component of a sensor.
//!
//! Frequencies are angular, cycles/rad in object space (docs/design.md §3). Components that do
//! not depend on wavelength (detector footprint, motion, jitter, Gaussian, measured MTF)
//! are evaluated once per frequency grid; the others (diffraction with aberration and
//! defocus, turbulence, aerosol) once per wavelength.

use std::f64::consts::PI;

use ndarray::{Array2, Zip};

use crate::atmosphere;
use crate::error::Result;
use crate::motion;
use crate::optics::{self, MeasuredMtf};

use super::config::{SensorConfig, TurbulenceConfig};

/// One transfer-function component; its name is the sensor-file section that enables it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Component {
    /// Aperture diffraction, clear or centrally obscured (docs/design.md §4.2–4.3).
    Diffraction,
    /// Shannon aberration factor (§4.5).
    Aberration,
    /// Defocus factor 2J1(a)/a (§4.4).
    Defocus,
    /// Detector footprint (§4.6).
    Detector,
    /// Linear motion smear (§4.6).
    Motion,
    /// Line-of-sight jitter (§4.6).
    Jitter,
    /// Long-exposure turbulence (§4.7).
    Turbulence,
    /// Aerosol scattering (§4.8).
    Aerosol,
    /// Global Gaussian blur.
    Gaussian,
    /// Measured MTF table.
    Measured,
}

impl Component {
    /// Every component, in the order they are listed in reports.
    pub const ALL: [Component; 10] = [
        Component::Diffraction,
        Component::Aberration,
        Component::Defocus,
        Component::Detector,
        Component::Motion,
        Component::Jitter,
        Component::Turbulence,
        Component::Aerosol,
        Component::Gaussian,
        Component::Measured,
    ];

    /// The component's name: the sensor-file section and report column.
    pub fn name(self) -> &'static str {
        match self {
            Component::Diffraction => "diffraction",
            Component::Aberration => "aberration",
            Component::Defocus => "defocus",
            Component::Detector => "detector",
            Component::Motion => "motion",
            Component::Jitter => "jitter",
            Component::Turbulence => "turbulence",
            Component::Aerosol => "aerosol",
            Component::Gaussian => "gaussian",
            Component::Measured => "measured",
        }
    }

    /// Whether the component depends on wavelength.
    pub fn is_chromatic(self) -> bool {
        matches!(
            self,
            Component::Diffraction
                | Component::Aberration
                | Component::Defocus
                | Component::Turbulence
                | Component::Aerosol
        )
    }
}

/// How the defocus amount is given.
#[derive(Debug, Clone, Copy, PartialEq)]
enum DefocusAmount {
    /// W020 in waves at every wavelength.
    Waves(f64),
    /// Focus shift δz, m: W020 = δz / (8 N² λ).
    FocusShift(f64),
}

/// How the turbulence r0 is obtained at a wavelength.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Turbulence {
    /// Horizontal path (closed form, docs/design.md §4.7).
    Horizontal { cn2: f64, range_m: f64 },
    /// Slant path: the spherical-wave weighted ∫Cn² (m^1/3), computed once, and the path
    /// it was computed for.
    Slant {
        weighted_cn2: f64,
        path: atmosphere::SlantPath,
    },
}

/// The resolved cascade of a sensor's transfer functions.
#[derive(Debug, Clone)]
pub struct SystemOtf {
    components: Vec<Component>,
    aperture_diameter_m: f64,
    f_number: f64,
    obscuration_ratio: f64,
    aberration_rms_waves: f64,
    defocus: Option<DefocusAmount>,
    focal_length_m: f64,
    active_width_x_m: f64,
    active_width_y_m: f64,
    smear_rad: f64,
    smear_direction_rad: f64,
    jitter_sigma_rad: f64,
    gaussian_sigma_rad: (f64, f64),
    turbulence: Option<Turbulence>,
    aerosol: Option<super::config::AerosolConfig>,
    measured: Option<MeasuredMtf>,
}

impl SystemOtf {
    /// Resolves the enabled components of `sensor`, with its measured MTF (the `[measured]`
    /// section, already loaded by the build step).
    ///
    /// Only [`super::Sensor::build`] constructs a cascade: it validates the configuration
    /// and reads every file first, so no stage can build a transfer function from an
    /// unresolved description (read it with [`super::Sensor::otf`]).
    pub(super) fn new(sensor: &SensorConfig, measured: Option<MeasuredMtf>) -> Result<Self> {
        // A section with `enabled = false` is read and checked but left out.
        let measured = measured.filter(|_| sensor.measured.as_ref().is_some_and(|m| m.enabled));
        let mut components = Vec::new();
        if sensor.diffraction.enabled {
            components.push(Component::Diffraction);
        }
        let aberration = sensor.aberration.as_ref().filter(|a| a.enabled);
        let aberration_rms_waves = aberration.map_or(0.0, |a| a.rms_waves);
        if aberration.is_some() {
            components.push(Component::Aberration);
        }
        let defocus = sensor.defocus.as_ref().filter(|d| d.enabled).map(|d| {
            match (d.w020_waves, d.focus_shift_m) {
                (Some(w), _) => DefocusAmount::Waves(w),
                (None, Some(z)) => DefocusAmount::FocusShift(z),
                (None, None) => DefocusAmount::Waves(0.0),
            }
        });
        if defocus.is_some() {
            components.push(Component::Defocus);
        }
        if sensor.detector.footprint_enabled {
            components.push(Component::Detector);
        }
        let (smear_rad, smear_direction_rad) = match sensor.motion.as_ref().filter(|m| m.enabled) {
            Some(m) => {
                components.push(Component::Motion);
                let t = sensor.detector.integration_time_s;
                let smear = if let Some(s) = m.smear_rad {
                    s
                } else if let Some(w) = m.angular_rate_rad_s {
                    motion::smear_from_angular_rate(w, t).abs()
                } else {
                    let v = m.velocity_m_s.unwrap_or(0.0);
                    motion::smear_from_velocity(v, t, m.range_m.unwrap_or(1.0)).abs()
                };
                (smear, m.direction_deg.to_radians())
            }
            None => (0.0, 0.0),
        };
        let jitter = sensor.jitter.as_ref().filter(|j| j.enabled);
        let jitter_sigma_rad = jitter.map_or(0.0, |j| j.sigma_rad);
        if jitter.is_some() {
            components.push(Component::Jitter);
        }
        let turbulence = match sensor.turbulence.as_ref().filter(|t| t.is_enabled()) {
            Some(TurbulenceConfig::Horizontal { cn2, range_m, .. }) => {
                Some(Turbulence::Horizontal {
                    cn2: *cn2,
                    range_m: *range_m,
                })
            }
            Some(TurbulenceConfig::Slant {
                cn2_at_1m,
                sensor_height_m,
                target_height_m,
                range_m,
                ..
            }) => {
                let path = atmosphere::SlantPath::new(
                    *cn2_at_1m,
                    *sensor_height_m,
                    *target_height_m,
                    *range_m,
                )?;
                Some(Turbulence::Slant {
                    weighted_cn2: path.spherical_weighted_cn2(),
                    path,
                })
            }
            None => None,
        };
        if turbulence.is_some() {
            components.push(Component::Turbulence);
        }
        let aerosol = sensor.aerosol.clone().filter(|a| a.enabled);
        if aerosol.is_some() {
            components.push(Component::Aerosol);
        }
        let gaussian = sensor.gaussian.as_ref().filter(|g| g.enabled);
        let gaussian_sigma_rad = gaussian.map_or((0.0, 0.0), |g| {
            (g.sigma_rad, g.sigma_y_rad.unwrap_or(g.sigma_rad))
        });
        if gaussian.is_some() {
            components.push(Component::Gaussian);
        }
        if measured.is_some() {
            components.push(Component::Measured);
        }
        Ok(SystemOtf {
            components,
            aperture_diameter_m: sensor.aperture_diameter_m(),
            f_number: sensor.optics.f_number,
            obscuration_ratio: sensor.optics.obscuration_ratio,
            aberration_rms_waves,
            defocus,
            focal_length_m: sensor.optics.focal_length_m,
            active_width_x_m: sensor.detector.active_width_m,
            active_width_y_m: sensor.detector.active_height(),
            smear_rad,
            smear_direction_rad,
            jitter_sigma_rad,
            gaussian_sigma_rad,
            turbulence,
            aerosol,
            measured,
        })
    }

    /// The same cascade with the motion component replaced: `Some((smear_rad,
    /// direction_rad))` a linear smear over that angle along that direction (from +x toward
    /// +y), `None` no motion component. A moving camera's sequence puts the smear of its
    /// constant-rate motion here, or removes it when the blur is computed from the
    /// trajectory per frame (docs/motion.md).
    pub fn with_motion_smear(&self, smear: Option<(f64, f64)>) -> SystemOtf {
        let mut otf = self.clone();
        otf.components.retain(|c| *c != Component::Motion);
        match smear {
            Some((d, theta)) => {
                // Report order: after the detector footprint, as `new` puts it.
                let at = otf
                    .components
                    .iter()
                    .position(|c| *c == Component::Detector)
                    .map_or(otf.components.len(), |i| i + 1);
                otf.components.insert(at, Component::Motion);
                (otf.smear_rad, otf.smear_direction_rad) = (d.abs(), theta);
            }
            None => (otf.smear_rad, otf.smear_direction_rad) = (0.0, 0.0),
        }
        otf
    }

    /// The same cascade without the aperture components (diffraction, Shannon
    /// aberration, defocus): what stays cascaded when the pupil's own transfer function
    /// (`[optics.wavefront]`, docs/wavefront.md "In the imaging chain") replaces them,
    /// since both describe the same aperture and wavefront.
    pub fn without_aperture(&self) -> SystemOtf {
        let mut otf = self.clone();
        otf.components.retain(|c| {
            !matches!(
                c,
                Component::Diffraction | Component::Aberration | Component::Defocus
            )
        });
        otf.defocus = None;
        otf.aberration_rms_waves = 0.0;
        otf
    }

    /// Whether the cascade holds a component that depends on the path length to the
    /// scene (turbulence, aerosol).
    pub fn depends_on_range(&self) -> bool {
        self.turbulence.is_some() || self.aerosol.is_some()
    }

    /// The same cascade with the turbulence and aerosol components evaluated over a path of
    /// `range_m` instead of the sensor file's own range (the range performance of
    /// `merit::assess` at each range). A slant path keeps its end heights; a range
    /// shorter than their difference is taken as the vertical path (the shortest path
    /// the heights allow).
    ///
    /// Errors: `range_m` not finite and > 0.
    pub fn over_range(&self, range_m: f64) -> Result<SystemOtf> {
        if !(range_m.is_finite() && range_m > 0.0) {
            return Err(crate::error::Error::param(
                "range_m",
                range_m,
                "a finite path length > 0 m",
            ));
        }
        let mut otf = self.clone();
        otf.turbulence = match self.turbulence {
            Some(Turbulence::Horizontal { cn2, .. }) => {
                Some(Turbulence::Horizontal { cn2, range_m })
            }
            Some(Turbulence::Slant { path, .. }) => {
                let shortest = (path.target_height_m - path.sensor_height_m).abs();
                let path = atmosphere::SlantPath::new(
                    path.cn2_at_1m,
                    path.sensor_height_m,
                    path.target_height_m,
                    range_m.max(shortest),
                )?;
                Some(Turbulence::Slant {
                    weighted_cn2: path.spherical_weighted_cn2(),
                    path,
                })
            }
            None => None,
        };
        if let Some(a) = otf.aerosol.as_mut() {
            a.range_m = range_m;
        }
        Ok(otf)
    }

    /// The enabled components, in report order.
    pub fn components(&self) -> &[Component] {
        &self.components
    }

    /// Diffraction cutoff D/λ, cycles/rad.
    pub fn cutoff_cy_per_rad(&self, wavelength_um: f64) -> f64 {
        optics::cutoff_cy_per_rad(self.aperture_diameter_m, wavelength_um * 1e-6)
    }

    /// Fried parameter r0 at a wavelength, m, if turbulence is enabled.
    pub fn fried_r0_m(&self, wavelength_um: f64) -> Option<f64> {
        let lambda_m = wavelength_um * 1e-6;
        match self.turbulence? {
            Turbulence::Horizontal { cn2, range_m } => {
                atmosphere::fried_r0_horizontal(lambda_m, range_m, cn2).ok()
            }
            Turbulence::Slant { weighted_cn2, .. } => Some(atmosphere::fried_r0_from_weighted_cn2(
                lambda_m,
                weighted_cn2,
            )),
        }
    }

    /// Defocus edge wavefront error W020 (waves) at a wavelength, if defocus is enabled:
    /// the configured value, or `δz / (8 N² λ)` for a focus shift (docs/design.md §4.4).
    pub fn defocus_w020_waves(&self, wavelength_um: f64) -> Option<f64> {
        match self.defocus? {
            DefocusAmount::Waves(w) => Some(w),
            DefocusAmount::FocusShift(z) => Some(optics::defocus_w020_from_focus_shift(
                z,
                self.f_number,
                wavelength_um * 1e-6,
            )),
        }
    }

    /// Whether the defocus amount depends on wavelength (given as a focus shift, so
    /// W020 ∝ 1/λ) rather than as a fixed number of waves.
    pub fn defocus_is_chromatic(&self) -> bool {
        matches!(self.defocus, Some(DefocusAmount::FocusShift(_)))
    }

    /// Whether the defocus factor is the diffraction form, bounded by the aperture cutoff
    /// D/λ (a diffraction or aberration term is on), rather than the geometric-optics
    /// blur disc without a cutoff ([`optics::defocus_geometric`]).
    pub fn defocus_bounded(&self) -> bool {
        self.components
            .iter()
            .any(|c| matches!(c, Component::Diffraction | Component::Aberration))
    }

    /// Aerosol particle radius a (m), if the aerosol component is enabled: its transfer
    /// function depends on frequency through ρλ/a (docs/design.md §4.8).
    pub fn aerosol_particle_radius_m(&self) -> Option<f64> {
        self.aerosol.as_ref().map(|a| a.particle_radius_m)
    }

    /// Value of one component at angular frequency (fx, fy) cycles/rad and wavelength λ.
    /// A component that is not enabled evaluates to 1.
    pub fn component(&self, c: Component, fx: f64, fy: f64, wavelength_um: f64) -> f64 {
        if !self.components.contains(&c) {
            return 1.0;
        }
        // The Fried parameter (two `powf`) only where it is used.
        let r0_m = match c {
            Component::Turbulence => self.fried_r0_m(wavelength_um),
            _ => None,
        };
        self.component_unchecked(c, fx, fy, wavelength_um, r0_m)
    }

    /// The product of the enabled components for which `keep` is true, in the order of
    /// [`SystemOtf::components`], at (fx, fy) cycles/rad and wavelength λ, with `r0_m` the
    /// Fried parameter at λ ([`SystemOtf::fried_r0_m`], computed once by the caller for
    /// many frequencies). Each factor is [`SystemOtf::component`]'s value.
    pub fn product_where(
        &self,
        fx: f64,
        fy: f64,
        wavelength_um: f64,
        r0_m: Option<f64>,
        keep: impl Fn(Component) -> bool,
    ) -> f64 {
        self.components
            .iter()
            .filter(|c| keep(**c))
            .map(|c| self.component_unchecked(*c, fx, fy, wavelength_um, r0_m))
            .product()
    }

    fn component_unchecked(
        &self,
        c: Component,
        fx: f64,
        fy: f64,
        wavelength_um: f64,
        r0_m: Option<f64>,
    ) -> f64 {
        let lambda_m = wavelength_um * 1e-6;
        // Radial frequency and its ratio to the cutoff, for the radial components only.
        let f = || fx.hypot(fy);
        let x = || f() / self.cutoff_cy_per_rad(wavelength_um);
        match c {
            Component::Diffraction => optics::diffraction_obscured(x(), self.obscuration_ratio),
            Component::Aberration => optics::aberration_shannon(x(), self.aberration_rms_waves),
            Component::Defocus => {
                let w020 = match self.defocus {
                    Some(DefocusAmount::Waves(w)) => w,
                    Some(DefocusAmount::FocusShift(z)) => {
                        optics::defocus_w020_from_focus_shift(z, self.f_number, lambda_m)
                    }
                    None => 0.0,
                };
                // With the diffraction (or aberration) term, the Hopkins factor, 0 beyond
                // the cutoff D/λ; without an aperture term, defocus in the
                // geometric-optics limit, the blur disc's transfer function, which rolls
                // off without a cutoff (optics::defocus_geometric).
                if self.defocus_bounded() {
                    optics::defocus(x(), w020)
                } else {
                    optics::defocus_geometric(x(), w020)
                }
            }
            Component::Detector => optics::detector_footprint(
                fx,
                fy,
                self.active_width_x_m,
                self.active_width_y_m,
                self.focal_length_m,
            ),
            Component::Motion => {
                motion::linear_motion(fx, fy, self.smear_rad, self.smear_direction_rad)
            }
            Component::Jitter => motion::jitter(fx, fy, self.jitter_sigma_rad),
            Component::Gaussian => {
                motion::gaussian(fx, fy, self.gaussian_sigma_rad.0, self.gaussian_sigma_rad.1)
            }
            Component::Turbulence => match r0_m {
                Some(r0) => atmosphere::turbulence_long_exposure(f(), lambda_m, r0),
                None => 1.0,
            },
            Component::Aerosol => match &self.aerosol {
                Some(a) => atmosphere::aerosol(
                    f(),
                    lambda_m,
                    a.absorption_per_m,
                    a.scattering_per_m,
                    a.range_m,
                    a.particle_radius_m,
                    a.dc_normalised,
                ),
                None => 1.0,
            },
            Component::Measured => self.measured.as_ref().map_or(1.0, |m| m.eval(f())),
        }
    }

    /// The wavelength-independent product on the samples of `grid`, one sample at a time
    /// ([`AchromaticSampler::at`]), with no transcendental function per sample for the
    /// separable components: their row and column terms are computed here, once.
    /// - detector footprint: `sinc(fx·wx/F) · sinc(fy·wy/F)`, a product of two terms, the
    ///   same bits as the pointwise function;
    /// - jitter and Gaussian: `exp(−2π²(ax² + ay²)) = exp(−2π² ax²) · exp(−2π² ay²)`, a
    ///   product of two terms (within 2 ulp of the pointwise exponential of the sum);
    /// - linear motion: `sinc(f_along·d)` with `π f_along d = tx + ty`, its sine from the
    ///   addition formula `sin tx cos ty + cos tx sin ty` where the two terms do not
    ///   cancel (`|tx + ty| ≥ (|tx| + |ty|)/2`), so the result is within a few ulp of 1 of
    ///   the pointwise sinc; where they do cancel, `sin(tx + ty)` directly.
    ///
    /// The components are multiplied in the order of [`SystemOtf::components`]. The whole
    /// product is within 1e-15 of the pointwise product
    /// (`achromatic_grid_matches_the_pointwise_product`); at 1024² this evaluation takes
    /// about a fifth of the per-sample sine and exponentials it replaces.
    pub fn achromatic_sampler<'a>(&'a self, grid: &'a FrequencyGrid) -> AchromaticSampler<'a> {
        let (fx, fy) = (&grid.fx, &grid.fy);
        let terms = self
            .components
            .iter()
            .filter(|c| !c.is_chromatic())
            .map(|&c| match c {
                Component::Detector => {
                    // optics::detector_footprint: sinc(fx·wx/F) · sinc(fy·wy/F).
                    let fl = self.focal_length_m;
                    let footprint = |w: f64| move |f: &f64| optics::sinc(f * w / fl);
                    AchromaticTerm::Product(
                        fx.iter().map(footprint(self.active_width_x_m)).collect(),
                        fy.iter().map(footprint(self.active_width_y_m)).collect(),
                    )
                }
                Component::Motion => {
                    // motion::linear_motion: sinc((fx cos θ + fy sin θ) · d).
                    let (sin_t, cos_t) = self.smear_direction_rad.sin_cos();
                    let d = self.smear_rad;
                    AchromaticTerm::SincOfSum(
                        SineAxis::new(fx.iter().map(|f| PI * (f * cos_t) * d)),
                        SineAxis::new(fy.iter().map(|f| PI * (f * sin_t) * d)),
                    )
                }
                Component::Jitter | Component::Gaussian => {
                    let (sx, sy) = if c == Component::Jitter {
                        (self.jitter_sigma_rad, self.jitter_sigma_rad)
                    } else {
                        self.gaussian_sigma_rad
                    };
                    // motion::gaussian is exp(−2π²((σx fx)² + (σy fy)²)): one factor per axis.
                    AchromaticTerm::Product(
                        fx.iter()
                            .map(|f| motion::gaussian(*f, 0.0, sx, sy))
                            .collect(),
                        fy.iter()
                            .map(|f| motion::gaussian(0.0, *f, sx, sy))
                            .collect(),
                    )
                }
                _ => AchromaticTerm::Direct(c),
            })
            .collect();
        AchromaticSampler {
            otf: self,
            fx,
            fy,
            terms,
        }
    }

    /// The product of the enabled components whose chromatic-ness is `chromatic`.
    fn product(
        &self,
        fx: f64,
        fy: f64,
        wavelength_um: f64,
        chromatic: bool,
        r0: Option<f64>,
    ) -> f64 {
        self.product_where(fx, fy, wavelength_um, r0, |c| c.is_chromatic() == chromatic)
    }

    /// The system OTF (product of all enabled components) at one frequency and wavelength.
    pub fn evaluate(&self, fx: f64, fy: f64, wavelength_um: f64) -> f64 {
        let r0 = self.fried_r0_m(wavelength_um);
        self.product(fx, fy, wavelength_um, false, r0)
            * self.product(fx, fy, wavelength_um, true, r0)
    }

    /// Prepares evaluation on a frequency grid: the wavelength-independent product is
    /// computed here, once, at every sample ([`SystemOtf::achromatic_sampler`]: within
    /// 1e-15·(1 + |t|) of the pointwise product, t the smear's sine argument).
    pub fn on_grid(&self, grid: &FrequencyGrid) -> GridOtf<'_> {
        let sampler = self.achromatic_sampler(grid);
        let mut achromatic = Array2::<f64>::zeros((grid.fy.len(), grid.fx.len()));
        Zip::indexed(&mut achromatic).par_for_each(|(v, u), a| *a = sampler.at(u, v));
        GridOtf {
            otf: self,
            fx: grid.fx.clone(),
            fy: grid.fy.clone(),
            achromatic,
        }
    }
}

/// One wavelength-independent component on a grid, as [`AchromaticSampler`] evaluates it:
/// from a column term (fx) and a row term (fy), or directly.
#[derive(Debug, Clone)]
enum AchromaticTerm {
    /// `x[u] · y[v]`.
    Product(Vec<f64>, Vec<f64>),
    /// `sin(tx + ty) / (tx + ty)` (1 at 0): `sinc((tx + ty)/π)` of a column and a row
    /// argument ([`SineAxis::sinc_of_sum`]).
    SincOfSum(SineAxis, SineAxis),
    /// The component evaluated at (fx, fy).
    Direct(Component),
}

/// The arguments `t` of a sine along one grid axis, with their sines and cosines.
#[derive(Debug, Clone)]
struct SineAxis {
    t: Vec<f64>,
    sin: Vec<f64>,
    cos: Vec<f64>,
}

impl SineAxis {
    fn new(t: impl Iterator<Item = f64>) -> Self {
        let t: Vec<f64> = t.collect();
        let (sin, cos) = t.iter().map(|t| t.sin_cos()).unzip();
        SineAxis { t, sin, cos }
    }

    /// `sin(t)/t` at `t = self.t[u] + other.t[v]` (1 at t = 0). Where the two arguments do
    /// not cancel, `|t| ≥ (|tx| + |ty|)/2`, the sine is `sin tx cos ty + cos tx sin ty`:
    /// its rounding error, a few ulp of `|tx| + |ty| ≤ 2|t|`, is then a few ulp of 1 in
    /// the quotient. Where they cancel, that error would be large against `t`, and the
    /// sine of the sum is taken directly, as `optics::sinc` does.
    #[inline]
    fn sinc_of_sum(&self, u: usize, other: &SineAxis, v: usize) -> f64 {
        let (tx, ty) = (self.t[u], other.t[v]);
        let t = tx + ty;
        if t == 0.0 {
            1.0
        } else if 2.0 * t.abs() >= tx.abs() + ty.abs() {
            (self.sin[u] * other.cos[v] + self.cos[u] * other.sin[v]) / t
        } else {
            t.sin() / t
        }
    }
}

/// The wavelength-independent product of a [`SystemOtf`] on a [`FrequencyGrid`], sample by
/// sample ([`SystemOtf::achromatic_sampler`]), so that a caller can store it in its own
/// layout and precision without a frame-sized f64 array.
#[derive(Debug, Clone)]
pub struct AchromaticSampler<'a> {
    otf: &'a SystemOtf,
    fx: &'a [f64],
    fy: &'a [f64],
    terms: Vec<AchromaticTerm>,
}

impl AchromaticSampler<'_> {
    /// The product at fx index `u`, fy index `v`: the components multiplied one by one in
    /// the order of [`SystemOtf::components`], starting from 1 (as
    /// [`SystemOtf::evaluate`] takes them).
    #[inline]
    pub fn at(&self, u: usize, v: usize) -> f64 {
        let mut a = 1.0;
        for t in &self.terms {
            a *= match t {
                AchromaticTerm::Product(x, y) => x[u] * y[v],
                AchromaticTerm::SincOfSum(x, y) => x.sinc_of_sum(u, y, v),
                AchromaticTerm::Direct(c) => self
                    .otf
                    .component_unchecked(*c, self.fx[u], self.fy[v], 1.0, None),
            };
        }
        a
    }

    /// The products of column `u` (fx index u) at every fy index v into `out[v]`
    /// (`out.len()` = the grid's rows): [`AchromaticSampler::at`]`(u, v)` bit for bit (the
    /// same operations in the same order per sample), a component at a time down the
    /// column, so that each is one loop the compiler vectorises instead of a dispatch
    /// per sample.
    ///
    /// # Panics
    /// If `out` is longer than the grid's fy axis (a caller error).
    pub fn column(&self, u: usize, out: &mut [f64]) {
        let fy = &self.fy[..out.len()];
        out.fill(1.0);
        for t in &self.terms {
            match t {
                AchromaticTerm::Product(x, y) => {
                    let xu = x[u];
                    for (a, yv) in out.iter_mut().zip(&y[..fy.len()]) {
                        *a *= xu * yv;
                    }
                }
                AchromaticTerm::SincOfSum(x, y) => {
                    for (v, a) in out.iter_mut().enumerate() {
                        *a *= x.sinc_of_sum(u, y, v);
                    }
                }
                AchromaticTerm::Direct(c) => {
                    for (a, fy) in out.iter_mut().zip(fy) {
                        *a *= self.otf.component_unchecked(*c, self.fx[u], *fy, 1.0, None);
                    }
                }
            }
        }
    }
}

/// Frequencies of the half-plane layout of a real 2-D FFT, cycles/rad.
#[derive(Debug, Clone, PartialEq)]
pub struct FrequencyGrid {
    /// Row frequencies, one per FFT row: `j / (rows·dy)` for j ≤ rows/2, else `(j − rows)/(rows·dy)`.
    pub fy: Vec<f64>,
    /// Column frequencies of the real-FFT half plane: `k / (cols·dx)`, k = 0 … cols/2.
    pub fx: Vec<f64>,
}

impl FrequencyGrid {
    /// The grid of a real FFT of a `rows × cols` frame sampled every `dy_rad` (rows) and
    /// `dx_rad` (columns). On an even axis the Nyquist bin is given the positive frequency;
    /// every component is even in frequency, so the sign there does not matter.
    pub fn real_fft(rows: usize, cols: usize, dy_rad: f64, dx_rad: f64) -> Self {
        let fy = (0..rows)
            .map(|j| {
                let jj = if j <= rows / 2 {
                    j as f64
                } else {
                    j as f64 - rows as f64
                };
                jj / (rows as f64 * dy_rad)
            })
            .collect();
        let fx = (0..cols / 2 + 1)
            .map(|k| k as f64 / (cols as f64 * dx_rad))
            .collect();
        FrequencyGrid { fy, fx }
    }

    /// The largest radial frequency ρ = hypot(fx, fy) on the grid, cycles/rad (0 for an
    /// empty grid): at the largest |fx| and |fy|, since hypot grows with each.
    pub fn rho_max(&self) -> f64 {
        let largest = |f: &[f64]| f.iter().fold(0.0, |m: f64, x| m.max(x.abs()));
        largest(&self.fx).hypot(largest(&self.fy))
    }
}

/// A [`SystemOtf`] bound to a frequency grid, with its wavelength-independent part cached.
#[derive(Debug, Clone)]
pub struct GridOtf<'a> {
    otf: &'a SystemOtf,
    fx: Vec<f64>,
    fy: Vec<f64>,
    achromatic: Array2<f64>,
}

impl GridOtf<'_> {
    /// The wavelength-independent product (detector, motion, jitter, Gaussian, measured).
    pub fn achromatic(&self) -> &Array2<f64> {
        &self.achromatic
    }

    /// [`GridOtf::achromatic`], by value (no copy of the frame-sized array).
    pub fn into_achromatic(self) -> Array2<f64> {
        self.achromatic
    }

    /// Writes the full system OTF at `wavelength_um` into `out` (shape `[fy, fx]`).
    pub fn at_wavelength_into(&self, wavelength_um: f64, out: &mut Array2<f64>) {
        let r0 = self.otf.fried_r0_m(wavelength_um);
        Zip::indexed(out)
            .and(&self.achromatic)
            .par_for_each(|(j, k), v, a| {
                *v = if *a == 0.0 {
                    0.0
                } else {
                    a * self
                        .otf
                        .product(self.fx[k], self.fy[j], wavelength_um, true, r0)
                };
            });
    }

    /// The full system OTF at `wavelength_um`, shape `[fy, fx]`.
    pub fn at_wavelength(&self, wavelength_um: f64) -> Array2<f64> {
        let mut out = Array2::zeros(self.achromatic.raw_dim());
        self.at_wavelength_into(wavelength_um, &mut out);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The grid's largest ρ is the largest hypot over every sample (brute force), for
    /// even and odd axes and an empty grid.
    #[test]
    fn rho_max_is_the_largest_sample() {
        for (rows, cols) in [(8, 10), (9, 7), (1, 1), (37, 50)] {
            let g = FrequencyGrid::real_fft(rows, cols, 4e-5, 3e-5);
            let brute =
                g.fx.iter()
                    .flat_map(|x| g.fy.iter().map(move |y| x.hypot(*y)))
                    .fold(0.0, f64::max);
            assert_eq!(g.rho_max().to_bits(), brute.to_bits(), "{rows} x {cols}");
        }
        assert_eq!(FrequencyGrid::real_fft(0, 0, 1.0, 1.0).rho_max(), 0.0);
    }

    /// `sin(t)/t` of a sum of two arguments matches the direct sinc of the sum within a
    /// few ulp of (1 + |tx| + |ty|)/|t|·ε, including pairs that cancel to a tiny sum, where
    /// the addition formula alone would lose every digit (sum 1e-9 of arguments ±1.3).
    #[test]
    fn sinc_of_sum_matches_the_sinc_of_the_sum() {
        let xs = [-40.0, -3.7, -1.3, -0.2, 0.0, 0.45, 1.3, 2.9, 57.0];
        let x = SineAxis::new(xs.iter().copied());
        let ys: Vec<f64> = xs
            .iter()
            .flat_map(|t| [-t, -t + 1e-9, -t - 3e-6, 0.5 * t, -0.6 * t, 0.77])
            .collect();
        let y = SineAxis::new(ys.iter().copied());
        let mut tiny = 0;
        for (u, tx) in xs.iter().enumerate() {
            for (v, ty) in ys.iter().enumerate() {
                let t = tx + ty;
                let want = optics::sinc(t / PI);
                let got = x.sinc_of_sum(u, &y, v);
                let scale = (1.0 + tx.abs() + ty.abs()) * f64::EPSILON;
                assert!(
                    (got - want).abs() <= 4.0 * scale,
                    "t = {tx} + {ty}: {got} vs {want}"
                );
                if t != 0.0 && t.abs() < 1e-5 {
                    tiny += 1;
                }
            }
        }
        assert!(tiny >= 10, "{tiny}");
    }
}
