//! Transfer functions from 1-D tables (docs/design.md §4.14).
//!
//! Every wavelength-dependent component of the cascade is radial and depends on frequency
//! only through a λ-scaled argument:
//!
//! | component | argument | table |
//! |---|---|---|
//! | diffraction × aberration (× defocus given in waves) | `X = ρλ/D` | [`RadialTables::aperture`], 0 beyond X = 1 |
//! | defocus given as a focus shift | `a = 8π W020(λ) X(1 − X)` | `2J1(a)/a` |
//! | turbulence | `u = λρ/r0(λ)` | `exp(−3.44 u^{5/3})` |
//! | aerosol | `v = ρλ/a` | constant beyond v = 1 |
//!
//! with ρ = √(fx² + fy²) (cycles/rad). Each component is tabulated ONCE per run
//! ([`RadialTables::new`]). Per band, the product of the chromatic components is then
//! tabulated as a function of ρ alone ([`RadialTables::band_profile`], a few thousand
//! lookups), and the accumulation loop does one interpolation per frequency sample
//! (ρ precomputed once per frame size).
//!
//! **Accuracy.** Every table is uniform with linear interpolation and is refined (its step
//! halved) until the interpolation error measured at every interval midpoint against the
//! function it tabulates is ≤ [`COMPONENT_MIDPOINT_TOLERANCE`] (component tables, measured
//! against direct evaluation of the component) or ≤ [`PROFILE_MIDPOINT_TOLERANCE`] (per-band
//! ρ profile, against the product of the component tables). For a function with bounded
//! curvature the midpoint error is the interval's largest; at a kink of a piecewise-linear
//! function it can be up to 2× smaller than the largest. The total error against direct
//! evaluation is therefore at most 2·(Σ component + profile) ≈ 2·(4·5e-8 + 1.5e-7) =
//! 7e-7 < [`TABLE_TOLERANCE`] = 1e-6 absolute, which tests/all/otf_table.rs checks on dense
//! frequency and wavelength grids for every component.

use crate::optics;
use crate::sensor::{Component, SystemOtf};

/// Largest absolute error of the tabulated transfer function against direct evaluation.
pub const TABLE_TOLERANCE: f64 = 1e-6;

/// Midpoint error to which each component table is refined.
pub const COMPONENT_MIDPOINT_TOLERANCE: f64 = 5e-8;

/// Midpoint error to which each per-band ρ profile is refined.
pub const PROFILE_MIDPOINT_TOLERANCE: f64 = 1.5e-7;

/// Largest number of intervals of any table (2^22: 32 MiB of f64; never reached by the
/// transfer functions of docs/design.md §4 at the tolerances above).
const MAX_INTERVALS: usize = 1 << 22;

/// Turbulence is tabulated up to the u where `exp(−3.44 u^{5/3}) = 1e-9` and is 0 beyond.
const TURBULENCE_FLOOR: f64 = 1e-9;

/// A function sampled uniformly on `[0, end]`, evaluated by linear interpolation, with a
/// fixed value beyond `end`.
#[derive(Debug, Clone, PartialEq)]
pub struct Table1d {
    /// Samples at `i · end / (len − 1)`.
    values: Vec<f64>,
    /// 1 / step.
    inv_step: f64,
    /// Argument of the last sample.
    end: f64,
    /// Value for arguments beyond `end`.
    beyond: f64,
}

impl Table1d {
    /// Tabulates `f` on `[0, end]` starting from `intervals` intervals and doubling until
    /// every midpoint is within `tolerance` of `f` (or [`MAX_INTERVALS`] is reached).
    pub fn build(
        f: impl Fn(f64) -> f64,
        end: f64,
        beyond: f64,
        intervals: usize,
        tolerance: f64,
    ) -> Self {
        let mut n = intervals.max(8);
        let mut values: Vec<f64> = sample(&f, end, n);
        loop {
            let step = end / n as f64;
            // Midpoints are the new samples of the doubled table: compute them once.
            let mids: Vec<f64> = (0..n).map(|i| f((i as f64 + 0.5) * step)).collect();
            let worst = mids
                .iter()
                .enumerate()
                .map(|(i, m)| (m - 0.5 * (values[i] + values[i + 1])).abs())
                .fold(0.0, f64::max);
            if worst <= tolerance || 2 * n > MAX_INTERVALS || end <= 0.0 {
                return Table1d {
                    inv_step: if end > 0.0 { n as f64 / end } else { 0.0 },
                    values,
                    end,
                    beyond,
                };
            }
            let mut finer = Vec::with_capacity(2 * n + 1);
            for i in 0..n {
                finer.push(values[i]);
                finer.push(mids[i]);
            }
            finer.push(values[n]);
            values = finer;
            n *= 2;
        }
    }

    /// Value at `x ≥ 0` (linear interpolation; `beyond` past the end).
    #[inline]
    pub fn eval(&self, x: f64) -> f64 {
        if x > self.end {
            return self.beyond;
        }
        let t = x * self.inv_step;
        // `build` makes at least 8 intervals, so `last ≥ 8`; t ≤ last (+ rounding) < 2^32
        // (MAX_INTERVALS = 2^22), so the u32 conversion (cheaper than to usize) is exact.
        let last = self.values.len() - 1;
        let i = (t as u32 as usize).min(last - 1);
        let (a, b) = (self.values[i], self.values[i + 1]);
        a + (t - i as f64) * (b - a)
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// Whether the table is empty (never, by construction).
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }
}

fn sample(f: &impl Fn(f64) -> f64, end: f64, n: usize) -> Vec<f64> {
    let step = end / n as f64;
    (0..=n).map(|i| f(i as f64 * step)).collect()
}

/// The chromatic components of a [`SystemOtf`] as 1-D tables in their λ-scaled arguments,
/// built once per run for the wavelength range in use.
#[derive(Debug, Clone)]
pub struct RadialTables {
    /// Diffraction × aberration (× defocus in waves) in `X = ρλ/D`; `None` if none is on.
    pub aperture: Option<Table1d>,
    /// `2J1(a)/a` in `a`, when defocus is given as a focus shift (W020 ∝ 1/λ).
    pub defocus: Option<Table1d>,
    /// `exp(−3.44 u^{5/3})` in `u = λρ/r0`, if turbulence is on.
    pub turbulence: Option<Table1d>,
    /// The aerosol MTF in `v = ρλ/a`, if aerosol is on.
    pub aerosol: Option<Table1d>,
    /// Aperture diameter D, m (from the cutoff).
    aperture_diameter_m: f64,
}

impl RadialTables {
    /// Tabulates the chromatic components of `otf` for wavelengths in
    /// `[min_wavelength_um, max_wavelength_um]`.
    ///
    /// Each table's function is the direct evaluation [`SystemOtf::component`] at a
    /// reference wavelength with the frequency that gives the table argument, so the table
    /// reproduces exactly what the cascade computes.
    pub fn new(otf: &SystemOtf, min_wavelength_um: f64, max_wavelength_um: f64) -> Self {
        let on = |c: Component| otf.components().contains(&c);
        let lambda_ref_um = max_wavelength_um;
        let fc_ref = otf.cutoff_cy_per_rad(lambda_ref_um);
        let aperture_diameter_m = fc_ref * lambda_ref_um * 1e-6;
        let defocus_chromatic = otf.defocus_is_chromatic();
        let mut aperture_parts: Vec<Component> = [
            Component::Diffraction,
            Component::Aberration,
            Component::Defocus,
        ]
        .into_iter()
        .filter(|c| on(*c))
        .collect();
        if defocus_chromatic {
            aperture_parts.retain(|c| *c != Component::Defocus);
        }
        let aperture = (!aperture_parts.is_empty()
            || (defocus_chromatic && on(Component::Defocus)))
        .then(|| {
            Table1d::build(
                |x| {
                    aperture_parts
                        .iter()
                        .map(|c| otf.component(*c, x * fc_ref, 0.0, lambda_ref_um))
                        .product::<f64>()
                        * if x <= 1.0 { 1.0 } else { 0.0 }
                },
                1.0,
                0.0,
                1024,
                COMPONENT_MIDPOINT_TOLERANCE,
            )
        });
        let defocus = (defocus_chromatic && on(Component::Defocus)).then(|| {
            // a = 8π W020 X(1 − X) ≤ 2π W020; W020 is largest at the shortest wavelength.
            let w = otf
                .defocus_w020_waves(min_wavelength_um)
                .unwrap_or(0.0)
                .abs()
                .max(
                    otf.defocus_w020_waves(max_wavelength_um)
                        .unwrap_or(0.0)
                        .abs(),
                );
            let a_end = (2.0 * std::f64::consts::PI * w).max(1e-3);
            Table1d::build(
                optics::jinc,
                a_end,
                optics::jinc(a_end),
                1024,
                COMPONENT_MIDPOINT_TOLERANCE,
            )
        });
        let turbulence = otf
            .fried_r0_m(lambda_ref_um)
            .filter(|r0| on(Component::Turbulence) && r0.is_finite())
            .map(|r0| {
                let lambda_m = lambda_ref_um * 1e-6;
                let u_end = ((-TURBULENCE_FLOOR.ln()) / 3.44).powf(0.6);
                Table1d::build(
                    |u| otf.component(Component::Turbulence, u * r0 / lambda_m, 0.0, lambda_ref_um),
                    u_end,
                    0.0,
                    4096,
                    COMPONENT_MIDPOINT_TOLERANCE,
                )
            });
        let aerosol = otf.aerosol_particle_radius_m().map(|a_m| {
            let lambda_m = lambda_ref_um * 1e-6;
            let f =
                |v: f64| otf.component(Component::Aerosol, v * a_m / lambda_m, 0.0, lambda_ref_um);
            Table1d::build(f, 1.0, f(2.0), 256, COMPONENT_MIDPOINT_TOLERANCE)
        });
        RadialTables {
            aperture,
            defocus,
            turbulence,
            aerosol,
            aperture_diameter_m,
        }
    }

    /// Whether any chromatic component is on (else every profile is 1).
    pub fn is_empty(&self) -> bool {
        self.aperture.is_none()
            && self.defocus.is_none()
            && self.turbulence.is_none()
            && self.aerosol.is_none()
    }

    /// The product of the chromatic components at wavelength λ as a function of the radial
    /// frequency ρ (cycles/rad), from the component tables. `r0_m` is r0(λ) (None or +∞: no
    /// turbulence); `w020_waves` the focus-shift W020(λ) when defocus is chromatic.
    fn chromatic_at(&self, rho: f64, wavelength_um: f64, r0_m: Option<f64>, w020: f64) -> f64 {
        let lambda_m = wavelength_um * 1e-6;
        let x = rho * lambda_m / self.aperture_diameter_m;
        let mut v = 1.0;
        if let Some(t) = &self.aperture {
            v *= t.eval(x);
        }
        if let Some(t) = &self.defocus {
            v *= if x <= 1.0 {
                t.eval((8.0 * std::f64::consts::PI * w020 * x * (1.0 - x)).abs())
            } else {
                0.0
            };
        }
        if let (Some(t), Some(r0)) = (&self.turbulence, r0_m) {
            if r0.is_finite() {
                v *= t.eval(lambda_m * rho / r0);
            }
        }
        v
    }

    /// The chromatic product at one band as a function of ρ over `[0, rho_max]`
    /// (cycles/rad): aperture, defocus and turbulence as one table in ρ, refined to
    /// [`PROFILE_MIDPOINT_TOLERANCE`] against the component tables, 0 beyond the aperture
    /// cutoff (and beyond the turbulence floor); the aerosol factor, whose core is only
    /// `a/λ` cycles/rad wide (well below one frequency sample for real particles), is kept
    /// apart: its own table below `a/λ`, its plateau above.
    pub fn band_profile(&self, otf: &SystemOtf, wavelength_um: f64, rho_max: f64) -> BandProfile {
        let lambda_m = wavelength_um * 1e-6;
        let r0 = otf.fried_r0_m(wavelength_um);
        let w020 = if self.defocus.is_some() {
            otf.defocus_w020_waves(wavelength_um).unwrap_or(0.0)
        } else {
            0.0
        };
        let f = |rho: f64| self.chromatic_at(rho, wavelength_um, r0, w020);
        let mut end = rho_max;
        let mut cut = false;
        if self.aperture.is_some() || self.defocus.is_some() {
            let cutoff = self.aperture_diameter_m / lambda_m;
            if cutoff < end {
                end = cutoff;
                cut = true;
            }
        }
        if let (Some(t), Some(r0)) = (&self.turbulence, r0) {
            let floor = t.end * r0 / lambda_m;
            if r0.is_finite() && floor < end {
                end = floor;
                cut = true;
            }
        }
        let end = end.max(0.0);
        let beyond = if cut { 0.0 } else { f(end) };
        let table = Table1d::build(f, end, beyond, 256, PROFILE_MIDPOINT_TOLERANCE);
        let aerosol = match (&self.aerosol, otf.aerosol_particle_radius_m()) {
            (Some(t), Some(a_m)) => Some(AerosolFactor {
                scale: lambda_m / a_m,
                table: t.clone(),
            }),
            _ => None,
        };
        BandProfile { table, aerosol }
    }
}

/// The aerosol factor of one band: its table in `v = ρλ/a`.
#[derive(Debug, Clone, PartialEq)]
struct AerosolFactor {
    /// λ/a, rad.
    scale: f64,
    /// The aerosol MTF in v (its plateau beyond v = 1).
    table: Table1d,
}

/// The chromatic transfer function of one band as a function of the radial frequency ρ
/// (cycles/rad), from the run's tables (see [`RadialTables::band_profile`]).
#[derive(Debug, Clone, PartialEq)]
pub struct BandProfile {
    table: Table1d,
    aerosol: Option<AerosolFactor>,
}

impl BandProfile {
    /// The chromatic product at radial frequency `rho` ≥ 0, cycles/rad.
    #[inline]
    pub fn eval(&self, rho: f64) -> f64 {
        let v = self.table.eval(rho);
        match &self.aerosol {
            Some(a) => v * a.table.eval(rho * a.scale),
            None => v,
        }
    }

    /// The ρ table (without the aerosol factor).
    pub fn table(&self) -> &Table1d {
        &self.table
    }
}
