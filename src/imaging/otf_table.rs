//! Transfer functions from 1-D tables (docs/design.md §4.15).
//!
//! Every wavelength-dependent component of the cascade is radial and depends on frequency
//! only through a λ-scaled argument:
//!
//! | component | argument | table |
//! |---|---|---|
//! | diffraction × aberration (× defocus given in waves) | `X = ρλ/D` | [`RadialTables::aperture`], 0 beyond X = 1 |
//! | defocus given as a focus shift | `a = 8π W020(λ) X(1 − X)` | `2J1(a)/a` |
//! | defocus without diffraction or aberration (geometric blur disc) | `a = 8π W020(λ) X` | `2J1(a)/a`, no cutoff; direct beyond the table |
//! | turbulence | `u = λρ/r0(λ)` | `exp(−3.44 u^{5/3})` |
//! | aerosol | `v = ρλ/a` | constant beyond v = 1 |
//!
//! with ρ = √(fx² + fy²) (cycles/rad). Each component is tabulated ONCE per run
//! ([`RadialTables::new`]). Per chunk of up to four bands, the product of the chromatic
//! components of each band is then tabulated as a function of ρ alone on one common grid
//! ([`RadialTables::chunk_profile`], a few thousand lookups per band), and the
//! accumulation loop finds a frequency sample's grid position once and interpolates all
//! bands of the chunk from two adjacent groups of values (ρ computed once per frame size,
//! `imaging::RadialGrid`). A band's jump to 0 at its aperture cutoff is applied exactly,
//! not interpolated.
//!
//! **Accuracy.** Every table is uniform with linear interpolation and is refined (its step
//! halved) until the interpolation error measured at every interval midpoint against the
//! function it tabulates is ≤ [`COMPONENT_MIDPOINT_TOLERANCE`] (component tables, measured
//! against direct evaluation of the component) or ≤ [`PROFILE_MIDPOINT_TOLERANCE`] (per-band
//! ρ profile, for every band of the chunk, against the product of the component tables). For a function with bounded
//! curvature the midpoint error is the interval's largest; at a kink of a piecewise-linear
//! function it can be up to 2× smaller than the largest. The total error against direct
//! evaluation is therefore at most 2·(Σ component + profile) ≈ 2·(4·5e-8 + 1.5e-7) =
//! 7e-7 < [`TABLE_TOLERANCE`] = 1e-6 absolute, which tests/all/otf_table.rs checks on dense
//! frequency and wavelength grids for every component.

use rayon::prelude::*;

use crate::atmosphere;
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
    /// every midpoint is within `tolerance` of `f` (or `MAX_INTERVALS`, 2^22, is reached;
    /// see `refine`).
    pub fn build(
        f: impl Fn(f64) -> f64 + Sync,
        end: f64,
        beyond: f64,
        intervals: usize,
        tolerance: f64,
    ) -> Self {
        let (values, n) = refine(|x| [f(x)], end, intervals.max(8), tolerance);
        Table1d {
            inv_step: if end > 0.0 { n as f64 / end } else { 0.0 },
            values: values.into_iter().map(|[v]| v).collect(),
            end,
            beyond,
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

/// The samples of `f` (`L` lanes at each argument) on a uniform grid over `[0, end]`, and
/// its number of intervals n: from `start` intervals, the step halved until every lane's
/// value at every interval midpoint is within `tolerance` of the linear interpolation of
/// the interval's ends (a NaN never counts as beyond it), or until n would pass
/// `MAX_INTERVALS`. The scan of a level stops at the first midpoint beyond the
/// tolerance (a level that is not fine enough usually fails early), and a level's
/// midpoints are the new samples of the next, so `f` is evaluated once per node. The
/// refinement of [`Table1d::build`] (one lane) and of [`RadialTables::chunk_profile`]
/// (a chunk's bands).
fn refine<const L: usize>(
    f: impl Fn(f64) -> [f64; L] + Sync,
    end: f64,
    start: usize,
    tolerance: f64,
) -> (Vec<[f64; L]>, usize) {
    // `count` arguments `(i + offset)·step` of the grid of n intervals.
    let sample = |n: usize, offset: f64, count: usize| -> Vec<[f64; L]> {
        let step = end / n as f64;
        (0..count)
            .into_par_iter()
            .map(|i| f((i as f64 + offset) * step))
            .collect()
    };
    let mut n = start;
    let mut values = sample(n, 0.0, n + 1);
    loop {
        let mids = sample(n, 0.5, n);
        let within = !mids.iter().enumerate().any(|(i, m)| {
            let (a, b) = (values[i], values[i + 1]);
            (0..L).any(|c| (m[c] - 0.5 * (a[c] + b[c])).abs() > tolerance)
        });
        if within || 2 * n > MAX_INTERVALS || end <= 0.0 {
            return (values, n);
        }
        values = interleave(&values, &mids);
        n *= 2;
    }
}

/// The samples of a table with its step halved: `values[0], mids[0], values[1], …,
/// mids[n−1], values[n]` (`mids[i]` the function at the midpoint of interval i).
fn interleave<V: Copy>(values: &[V], mids: &[V]) -> Vec<V> {
    let mut finer = Vec::with_capacity(values.len() + mids.len());
    for (v, m) in values.iter().zip(mids) {
        finer.push(*v);
        finer.push(*m);
    }
    finer.extend(values.last());
    finer
}

/// The chromatic components of a [`SystemOtf`] as 1-D tables in their λ-scaled arguments,
/// built once per run for the wavelength range in use.
#[derive(Debug, Clone)]
pub struct RadialTables {
    /// Diffraction × aberration (× defocus in waves) in `X = ρλ/D`; `None` if none is on.
    pub aperture: Option<Table1d>,
    /// `2J1(a)/a` in `a`, when defocus is given as a focus shift (W020 ∝ 1/λ).
    pub defocus: Option<Table1d>,
    /// `exp(−3.44 u^{5/3})` in `u = λρ/r0`, if turbulence is on: up to the largest u of
    /// the frequencies and wavelengths the tables were built for
    /// ([`RadialTables::covering`]), or to the turbulence floor.
    pub turbulence: Option<Table1d>,
    /// The u beyond which turbulence is taken as 0 (`exp(−3.44 u^{5/3}) = 1e-9`).
    turbulence_floor_u: f64,
    /// The aerosol MTF in `v = ρλ/a`, if aerosol is on.
    pub aerosol: Option<Table1d>,
    /// Aperture diameter D, m (from the cutoff).
    aperture_diameter_m: f64,
    /// Whether the defocus table's argument is `8π W020 X(1 − X)`, 0 beyond X = 1 (an
    /// aperture term is on), or the geometric `8π W020 X` without a cutoff.
    defocus_bounded: bool,
}

impl RadialTables {
    /// Tabulates the chromatic components of `otf` for wavelengths in
    /// `[min_wavelength_um, max_wavelength_um]`.
    ///
    /// Each table's function is the direct evaluation [`SystemOtf::component`] at a
    /// reference wavelength with the frequency that gives the table argument, so the table
    /// reproduces exactly what the cascade computes.
    pub fn new(otf: &SystemOtf, min_wavelength_um: f64, max_wavelength_um: f64) -> Self {
        Self::covering(otf, min_wavelength_um, max_wavelength_um, f64::INFINITY)
    }

    /// [`RadialTables::new`] for radial frequencies up to `rho_max` (cycles/rad; a frame's
    /// largest, `imaging::RadialGrid::rho_max`): the turbulence table then stops at the
    /// largest `u = λρ/r0(λ)` of those frequencies at the two ends of the wavelength range
    /// (u ∝ λ^{−1/5}, monotonic), instead of running to the turbulence floor. Its cusp at
    /// u = 0 sets a uniform step, so for a weak path (r0 of tenths of a metre, u ≤ 0.1 on
    /// a 50 µrad grid) the table is 16× shorter at the same tolerance. Frequencies or
    /// wavelengths outside the range are still right: between the table's end and the
    /// floor the profile evaluates the turbulence MTF directly.
    pub fn covering(
        otf: &SystemOtf,
        min_wavelength_um: f64,
        max_wavelength_um: f64,
        rho_max: f64,
    ) -> Self {
        let on = |c: Component| otf.components().contains(&c);
        let lambda_ref_um = max_wavelength_um;
        let fc_ref = otf.cutoff_cy_per_rad(lambda_ref_um);
        let aperture_diameter_m = fc_ref * lambda_ref_um * 1e-6;
        // Defocus gets its own table in its argument `a` when it depends on wavelength
        // (a focus shift) or when no aperture term bounds it (the geometric blur disc,
        // `a = 8π W020 X` without a cutoff).
        let defocus_bounded = otf.defocus_bounded();
        let defocus_chromatic = otf.defocus_is_chromatic() || !defocus_bounded;
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
        // An aperture table (0 beyond X = 1) only with an aperture term; defocus without
        // one is the geometric blur disc, which has no cutoff.
        let aperture = (!aperture_parts.is_empty()).then(|| {
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
            // Bounded: a = 8π W020 X(1 − X) ≤ 2π W020. Geometric: a = 8π W020 X up to the
            // largest X of the frequencies covered (X = ρλ/D, at most 4 when no largest
            // frequency is given); beyond the table `chromatic_at` evaluates 2J1(a)/a
            // directly.
            let a_end = if defocus_bounded {
                2.0 * std::f64::consts::PI * w
            } else {
                let x_max = if rho_max.is_finite() {
                    rho_max / otf.cutoff_cy_per_rad(max_wavelength_um)
                } else {
                    4.0
                };
                8.0 * std::f64::consts::PI * w * x_max * (1.0 + 1e-9)
            }
            .max(1e-3);
            Table1d::build(
                optics::jinc,
                a_end,
                optics::jinc(a_end),
                1024,
                COMPONENT_MIDPOINT_TOLERANCE,
            )
        });
        let turbulence_floor_u = ((-TURBULENCE_FLOOR.ln()) / 3.44).powf(0.6);
        // The largest u the given frequencies reach (a hair beyond, for the roundings of
        // λρ/r0), at most the floor.
        let u_needed = [min_wavelength_um, max_wavelength_um]
            .iter()
            .filter_map(|&l| otf.fried_r0_m(l).map(|r0| l * 1e-6 * rho_max / r0))
            .fold(0.0, f64::max)
            * (1.0 + 1e-9);
        let turbulence = otf
            .fried_r0_m(lambda_ref_um)
            .filter(|r0| on(Component::Turbulence) && r0.is_finite())
            .map(|r0| {
                let lambda_m = lambda_ref_um * 1e-6;
                let u_end = if u_needed > 0.0 && u_needed.is_finite() {
                    turbulence_floor_u.min(u_needed)
                } else {
                    turbulence_floor_u
                };
                // r0 computed once above, not once per table sample.
                let turbulence = |u: f64| {
                    let f = u * r0 / lambda_m;
                    otf.product_where(f, 0.0, lambda_ref_um, Some(r0), |c| {
                        c == Component::Turbulence
                    })
                };
                // Past the end: 0 at the floor; otherwise never read (`chromatic_at`
                // evaluates directly between the end and the floor).
                Table1d::build(turbulence, u_end, 0.0, 4096, COMPONENT_MIDPOINT_TOLERANCE)
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
            turbulence_floor_u,
            aerosol,
            aperture_diameter_m,
            defocus_bounded,
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
            v *= if !self.defocus_bounded {
                let a = (8.0 * std::f64::consts::PI * w020 * x).abs();
                if a <= t.end {
                    t.eval(a)
                } else {
                    optics::jinc(a)
                }
            } else if x <= 1.0 {
                t.eval((8.0 * std::f64::consts::PI * w020 * x * (1.0 - x)).abs())
            } else {
                0.0
            };
        }
        if let (Some(t), Some(r0)) = (&self.turbulence, r0_m) {
            if r0.is_finite() {
                let u = lambda_m * rho / r0;
                v *= if u <= t.end || u > self.turbulence_floor_u {
                    t.eval(u)
                } else {
                    // Beyond a table built for fewer frequencies (`covering`).
                    atmosphere::turbulence_long_exposure(rho, lambda_m, r0)
                };
            }
        }
        v
    }

    /// The chromatic product at one band as a function of ρ over `[0, rho_max]`
    /// (cycles/rad): a one-band [`RadialTables::chunk_profile`].
    pub fn band_profile(&self, otf: &SystemOtf, wavelength_um: f64, rho_max: f64) -> BandProfile {
        BandProfile {
            chunk: self.chunk_profile(otf, &[wavelength_um], rho_max),
        }
    }

    /// The chromatic products of up to [`CHUNK_LANES`] bands as functions of ρ on ONE
    /// common uniform grid over `[0, rho_max]` (cycles/rad), interleaved by band, so that
    /// the accumulation computes the grid position of a frequency sample once and
    /// interpolates every band of a chunk from two adjacent groups of [`CHUNK_LANES`]
    /// values. Aperture, defocus and turbulence are one table per band, refined (step
    /// halved) until every band's midpoint error against the product of the component
    /// tables is ≤ [`PROFILE_MIDPOINT_TOLERANCE`]; they are 0 beyond the aperture cutoff
    /// and the turbulence floor by construction of the component tables. The aerosol
    /// factor, whose core is only `a/λ` cycles/rad wide (well below one frequency sample
    /// for real particles), is kept apart: its own table below `a/λ`, its plateau above.
    ///
    /// # Panics
    /// If more than [`CHUNK_LANES`] wavelengths are given (a caller error).
    pub fn chunk_profile(
        &self,
        otf: &SystemOtf,
        wavelengths_um: &[f64],
        rho_max: f64,
    ) -> ChunkProfile {
        assert!(
            wavelengths_um.len() <= CHUNK_LANES,
            "chunk_profile: at most {CHUNK_LANES} bands"
        );
        let end = rho_max.max(0.0);
        // Per band: λ, r0(λ), W020(λ), and where the band's transfer function ends (the
        // aperture cutoff D/λ, or the turbulence floor), if inside the grid.
        let params: Vec<(f64, Option<f64>, f64, f64)> = wavelengths_um
            .iter()
            .map(|&l| {
                let w020 = if self.defocus.is_some() {
                    otf.defocus_w020_waves(l).unwrap_or(0.0)
                } else {
                    0.0
                };
                let r0 = otf.fried_r0_m(l);
                (l, r0, w020, self.band_end(l, r0, end))
            })
            .collect();
        // Tabulated: each band's function held constant beyond its end (continuous, so
        // the refinement converges); `eval_all` zeroes it there (the jump at the cutoff
        // is exact, not interpolated).
        let f = |rho: f64| {
            let mut lanes = [0.0; CHUNK_LANES];
            for (v, (l, r0, w020, e)) in lanes.iter_mut().zip(&params) {
                *v = self.chromatic_at(rho.min(*e), *l, *r0, *w020);
            }
            lanes
        };
        let (values, n) = refine(f, end, 256, PROFILE_MIDPOINT_TOLERANCE);
        let aerosol: Vec<Option<AerosolFactor>> = wavelengths_um
            .iter()
            .map(
                |&l| match (&self.aerosol, otf.aerosol_particle_radius_m()) {
                    (Some(t), Some(a_m)) => Some(AerosolFactor {
                        scale: l * 1e-6 / a_m,
                        table: t.clone(),
                    }),
                    _ => None,
                },
            )
            .collect();
        let mut cut = [f64::INFINITY; CHUNK_LANES];
        for (c, p) in cut.iter_mut().zip(&params) {
            if p.3 < end {
                *c = p.3;
            }
        }
        ChunkProfile {
            inv_step: if end > 0.0 { n as f64 / end } else { 0.0 },
            values,
            cut,
            bands: wavelengths_um.len(),
            plateau: AerosolPlateau::new(&aerosol),
            aerosol,
        }
    }

    /// Where the band at `wavelength_um` ends within `[0, rho_max]`: the aperture cutoff
    /// D/λ when an aperture term (diffraction, aberration, defocus) is on, the turbulence
    /// floor λ·u_end/r0, or `rho_max`, whichever is smallest. Beyond it the product is 0
    /// (except when it is `rho_max`).
    fn band_end(&self, wavelength_um: f64, r0_m: Option<f64>, rho_max: f64) -> f64 {
        let lambda_m = wavelength_um * 1e-6;
        let mut end = rho_max;
        if self.aperture.is_some() || (self.defocus.is_some() && self.defocus_bounded) {
            end = end.min(self.aperture_diameter_m / lambda_m);
        }
        if let (Some(_), Some(r0)) = (&self.turbulence, r0_m) {
            if r0.is_finite() {
                end = end.min(self.turbulence_floor_u * r0 / lambda_m);
            }
        }
        end.max(0.0)
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

/// Bands per [`ChunkProfile`], one 256-bit vector of f64; the engine's bands per chunk
/// (`imaging::BANDS_PER_CHUNK`) are defined as this.
pub const CHUNK_LANES: usize = 4;

/// The chromatic transfer functions of the bands of one chunk on one common ρ grid (see
/// [`RadialTables::chunk_profile`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ChunkProfile {
    /// `values[i][c]`: band c at ρ = i·step (unused lanes 0).
    values: Vec<[f64; CHUNK_LANES]>,
    /// 1 / step.
    inv_step: f64,
    /// Per lane, the ρ beyond which the band's product is 0 (+∞: none inside the grid).
    cut: [f64; CHUNK_LANES],
    /// Bands in use (≤ [`CHUNK_LANES`]).
    bands: usize,
    /// Per band, the aerosol factor if aerosol is on.
    aerosol: Vec<Option<AerosolFactor>>,
    /// The aerosol factors' plateaus by lane, if aerosol is on.
    plateau: Option<AerosolPlateau>,
}

/// Where each lane's aerosol table ends and the constant beyond it, as lanes (unused lanes:
/// scale 1, end −1, value 1, so they are always "past the end" and multiply by 1).
#[derive(Debug, Clone, PartialEq)]
struct AerosolPlateau {
    scale: [f64; CHUNK_LANES],
    end: [f64; CHUNK_LANES],
    beyond: [f64; CHUNK_LANES],
    /// A ρ above which every lane is certainly past its table (see
    /// [`AerosolPlateau::surely_past_from`]): one comparison instead of four products.
    past_from: f64,
}

impl AerosolPlateau {
    /// `None` when no band has an aerosol factor.
    fn new(aerosol: &[Option<AerosolFactor>]) -> Option<Self> {
        if aerosol.iter().all(Option::is_none) {
            return None;
        }
        let mut p = AerosolPlateau {
            scale: [1.0; CHUNK_LANES],
            end: [-1.0; CHUNK_LANES],
            beyond: [1.0; CHUNK_LANES],
            past_from: f64::INFINITY,
        };
        for (c, a) in aerosol.iter().enumerate() {
            if let Some(a) = a {
                p.scale[c] = a.scale;
                p.end[c] = a.table.end;
                p.beyond[c] = a.table.beyond;
            }
        }
        p.past_from = Self::surely_past_from(&p.scale, &p.end);
        Some(p)
    }

    /// A ρ above which `ρ·scale[c] > end[c]` holds in floating point for every lane c:
    /// the largest `(end/scale)(1 + 1e-12)` (the margin is far above the roundings of the
    /// quotient and of `ρ·scale`); lanes past from ρ = 0 on (end < 0) do not limit it.
    /// +∞ (the exact per-lane test always) if a lane's scale or end does not allow the
    /// bound.
    fn surely_past_from(scale: &[f64; CHUNK_LANES], end: &[f64; CHUNK_LANES]) -> f64 {
        scale
            .iter()
            .zip(end)
            .fold(0.0, |from: f64, (&s, &e)| match (s > 0.0, e) {
                (true, e) if e < 0.0 => from,
                (true, e) if e > 0.0 && e.is_finite() => from.max(e / s * (1.0 + 1e-12)),
                _ => f64::INFINITY,
            })
    }

    /// Whether every lane is past its aerosol table at `rho` (`ρ·scale > end` for all):
    /// the bound first, the exact test only below it.
    #[inline(always)]
    fn all_past(&self, rho: f64) -> bool {
        rho > self.past_from
            || self
                .scale
                .iter()
                .zip(&self.end)
                .fold(true, |all, (s, e)| all & (rho * s > *e))
    }
}

impl ChunkProfile {
    /// Number of bands.
    pub fn bands(&self) -> usize {
        self.bands
    }

    /// Number of grid intervals.
    pub fn intervals(&self) -> usize {
        self.values.len() - 1
    }

    /// Bytes the profile holds on the heap (its grid and aerosol tables).
    pub fn heap_bytes(&self) -> usize {
        std::mem::size_of_val(self.values.as_slice())
            + self
                .aerosol
                .iter()
                .flatten()
                .map(|a| a.table.len() * std::mem::size_of::<f64>())
                .sum::<usize>()
    }

    /// Every band's chromatic product at radial frequency `rho` ≥ 0 (cycles/rad) into
    /// `out[..bands]` (lanes beyond are 0): one grid position, one linear interpolation
    /// per lane (vectorised). Beyond the grid's end the last value holds.
    ///
    /// The aerosol factor is a table lookup per lane in its own argument `ρλ/a`; past the
    /// end of its table (its plateau, which for particles of a few µm starts within a few
    /// cycles/rad of ρ = 0) it is a per-lane constant, and when every lane is there the
    /// lookups are skipped (the same value: the table returns that constant).
    #[inline(always)]
    pub fn eval_all(&self, rho: f64, out: &mut [f64; CHUNK_LANES]) {
        let t = rho * self.inv_step;
        // At least 256 intervals (`last ≥ 256`), at most MAX_INTERVALS = 2^22 < 2^32, so
        // the u32 conversion (cheaper than to usize; saturating) is exact where it matters.
        let last = self.values.len() - 1;
        let i = (t as u32 as usize).min(last - 1);
        let frac = (t - i as f64).min(1.0);
        let [a, b] = self.values[i..i + 2] else {
            unreachable!("i ≤ last − 1")
        };
        for c in 0..CHUNK_LANES {
            let v = a[c] + frac * (b[c] - a[c]);
            out[c] = if rho > self.cut[c] { 0.0 } else { v };
        }
        if let Some(p) = &self.plateau {
            if p.all_past(rho) {
                for (o, b) in out.iter_mut().zip(&p.beyond) {
                    *o *= b;
                }
                return;
            }
            for (o, aer) in out.iter_mut().zip(&self.aerosol) {
                if let Some(a) = aer {
                    *o *= a.table.eval(rho * a.scale);
                }
            }
        }
    }

    /// The parts of the profile that a vectorised [`ChunkProfile::eval_all`] reads (the
    /// AVX2 sample loop of `imaging::accumulate`).
    pub(super) fn lanes(&self) -> ProfileLanes<'_> {
        ProfileLanes {
            values: &self.values,
            inv_step: self.inv_step,
            cut: self.cut,
            plateau: self
                .plateau
                .as_ref()
                .map(|p| (p.scale, p.end, p.beyond, p.past_from)),
        }
    }

    /// Band `band`'s chromatic product at `rho` (as [`ChunkProfile::eval_all`]).
    pub fn eval(&self, band: usize, rho: f64) -> f64 {
        let mut v = [0.0; CHUNK_LANES];
        self.eval_all(rho, &mut v);
        v[band]
    }
}

/// An aerosol plateau by lane: `(scale, end, beyond, past_from)`.
pub(super) type PlateauLanes = (
    [f64; CHUNK_LANES],
    [f64; CHUNK_LANES],
    [f64; CHUNK_LANES],
    f64,
);

/// A [`ChunkProfile`]'s raw parts, as [`ChunkProfile::eval_all`] uses them: for ρ ≥ 0,
/// `t = ρ·inv_step`, `i = min(⌊t⌋, len − 2)`, `frac = min(t − i, 1)`, lane c is
/// `values[i][c] + frac·(values[i+1][c] − values[i][c])`, 0 where `ρ > cut[c]`; with a
/// plateau `(scale, end, beyond, past_from)`, where `ρ·scale[c] > end[c]` for every lane
/// c (always so for ρ > `past_from`) each lane is then multiplied by `beyond[c]`
/// (otherwise [`ChunkProfile::eval_all`] evaluates the aerosol tables).
pub(super) struct ProfileLanes<'a> {
    /// The samples, `values[i][c]` (at least 2).
    pub values: &'a [[f64; CHUNK_LANES]],
    /// 1 / step.
    pub inv_step: f64,
    /// Per lane, where the band is cut to 0.
    pub cut: [f64; CHUNK_LANES],
    /// The aerosol plateau, `(scale, end, beyond)` by lane and the ρ above which every
    /// lane is certainly on it, if aerosol is on.
    pub plateau: Option<PlateauLanes>,
}

/// The chromatic transfer function of one band as a function of the radial frequency ρ
/// (cycles/rad): a one-band [`ChunkProfile`] (see [`RadialTables::band_profile`]).
#[derive(Debug, Clone, PartialEq)]
pub struct BandProfile {
    chunk: ChunkProfile,
}

impl BandProfile {
    /// The chromatic product at radial frequency `rho` ≥ 0, cycles/rad.
    #[inline]
    pub fn eval(&self, rho: f64) -> f64 {
        self.chunk.eval(0, rho)
    }

    /// Number of grid intervals of the ρ table.
    pub fn intervals(&self) -> usize {
        self.chunk.intervals()
    }
}

/// The system OTF of the benchmarks' every-component SWIR sensor
/// (`benches/swir_all_components.toml`: aperture cutoffs, turbulence cusp, aerosol), for
/// the imaging module's unit tests.
#[cfg(test)]
pub(super) fn bench_swir_otf() -> SystemOtf {
    let cfg = crate::sensor::SensorConfig::from_toml_str(
        include_str!("../../benches/swir_all_components.toml"),
        "swir_all_components.toml",
        std::path::PathBuf::from("."),
        &[],
    )
    .expect("the bench sensor parses");
    crate::sensor::Sensor::build(&cfg)
        .expect("the bench sensor builds")
        .otf()
        .clone()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The number of intervals the refinement rule asks for, computed the plain way: the
    /// first `n = start · 2^k` whose largest midpoint error (a max fold, which ignores
    /// NaN) is within `tolerance`, from `f` evaluated afresh at every level.
    fn first_passing_level<const L: usize>(
        f: impl Fn(f64) -> [f64; L],
        end: f64,
        start: usize,
        tolerance: f64,
    ) -> usize {
        let mut n = start;
        loop {
            let step = end / n as f64;
            let worst = (0..n)
                .flat_map(|i| {
                    let (a, b, m) = (
                        f(i as f64 * step),
                        f((i + 1) as f64 * step),
                        f((i as f64 + 0.5) * step),
                    );
                    (0..L).map(move |c| (m[c] - 0.5 * (a[c] + b[c])).abs())
                })
                .fold(0.0, f64::max);
            if worst <= tolerance || 2 * n > MAX_INTERVALS {
                return n;
            }
            n *= 2;
        }
    }

    /// The refinement stops at the first level whose midpoints are all within the
    /// tolerance, as the plain rule does: for component tables (a smooth function, a
    /// u^{5/3} cusp, one with NaN at a node) and for chunk profiles of the every-component
    /// SWIR sensor (its aperture cutoffs, turbulence cusp and aerosol).
    #[test]
    fn refinement_stops_at_the_first_level_within_tolerance() {
        let tol = COMPONENT_MIDPOINT_TOLERANCE;
        let smooth = |x: f64| (3.0 * x).sin();
        let cusp = |x: f64| (-3.44 * x.powf(5.0 / 3.0)).exp();
        let nan_at_0 = |x: f64| if x == 0.0 { f64::NAN } else { x.cos() };
        for (f, start) in [
            (&smooth as &(dyn Fn(f64) -> f64 + Sync), 8),
            (&cusp, 4096),
            (&nan_at_0, 16),
        ] {
            let t = Table1d::build(f, 2.0, 0.0, start, tol);
            assert_eq!(
                t.len() - 1,
                first_passing_level(|x| [f(x)], 2.0, start, tol)
            );
        }

        let otf = bench_swir_otf();
        let tables = RadialTables::new(&otf, 1.0, 1.7);
        let rho_max = 14_142.0;
        for wavelengths in [[1.0, 1.1, 1.2, 1.3], [1.35, 1.45, 1.55, 1.7]] {
            let p = tables.chunk_profile(&otf, &wavelengths, rho_max);
            let lane = |rho: f64| {
                wavelengths.map(|l| {
                    let r0 = otf.fried_r0_m(l);
                    let e = tables.band_end(l, r0, rho_max);
                    tables.chromatic_at(rho.min(e), l, r0, 0.0)
                })
            };
            let want = first_passing_level(lane, rho_max, 256, PROFILE_MIDPOINT_TOLERANCE);
            assert!(want >= 1024, "{want}");
            assert_eq!(p.intervals(), want, "{wavelengths:?}");
        }
    }
}
