//! Wavefront aberrations: Zernike polynomials (Noll 1976 ordering, RMS-normalised) and the
//! Seidel wave aberration with its field dependence.
//!
//! All coefficients are in waves at a reference wavelength λ_ref (the optical path
//! difference is `coefficient × λ_ref`, the same at every wavelength, so at wavelength λ
//! the phase in waves is `coefficient × λ_ref/λ`). Pupil coordinates `(x, y)` are normalised
//! to the pupil radius; `x` is sagittal, `y` tangential (the field point lies along +y).
//!
//! **Zernike** (Noll, "Zernike polynomials and atmospheric turbulence", JOSA 66, 207, 1976,
//! eq. 3 and Table 1): `Z_j = √(n+1) R_n^m(ρ) √2 cos(mθ)` for `m ≠ 0` and even `j`,
//! `√(n+1) R_n^m(ρ) √2 sin(mθ)` for `m ≠ 0` and odd `j`, `√(n+1) R_n^0(ρ)` for `m = 0`;
//! θ is measured counter-clockwise from +x. Each `Z_j` has unit RMS over the unit disc, so a
//! coefficient is the RMS wavefront error of its term. Z4 = √3(2ρ²−1) is defocus, Z5/Z6
//! astigmatism, Z7 = √8(3ρ³−2ρ) sin θ coma along y (tangential), Z8 coma along x, Z11
//! spherical aberration.
//!
//! **Seidel** (Hopkins, *Wave Theory of Aberrations*, 1950; Mahajan, *Optical Imaging and
//! Aberrations*, Part I; Wyant & Creath, "Basic wavefront aberration theory for optical
//! metrology", Applied Optics and Optical Engineering XI, 1992):
//! `W = W020 ρ² + W040 ρ⁴ + W131 H ρ³ cos φ + W222 H² ρ² cos² φ + W220 H² ρ² + W311 H³ ρ cos φ`,
//! φ measured from the tangential (+y) axis (so `ρ cos φ = y`), H the normalised field
//! height in [0, 1]. Coefficients are peak values at the pupil edge and, for the field
//! terms, at full field (H = 1).

use crate::error::{Error, Result};

/// Highest Noll index accepted (radial order 10).
pub const MAX_NOLL_INDEX: usize = 66;

/// Radial order `n` and azimuthal frequency `m ≥ 0` of the Noll index `j ≥ 1`
/// (Noll 1976, Table 1: within order n, m increases with j; even j take cos, odd j sin).
pub fn noll_to_nm(j: usize) -> (usize, usize) {
    // The largest n with n(n+1)/2 < j.
    let mut n = 0;
    while (n + 1) * (n + 2) / 2 < j {
        n += 1;
    }
    let k = j - n * (n + 1) / 2 - 1; // 0..=n, position within the order
    let m = if n % 2 == 0 {
        2 * k.div_ceil(2)
    } else {
        2 * (k / 2) + 1
    };
    (n, m)
}

/// Zernike radial polynomial `R_n^m(ρ) = Σ_s (−1)^s (n−s)! / [s! ((n+m)/2−s)! ((n−m)/2−s)!] ρ^{n−2s}`
/// (Noll 1976, eq. 2). `n − m` must be even.
pub fn zernike_radial(n: usize, m: usize, rho: f64) -> f64 {
    let fact = |k: usize| (1..=k).map(|i| i as f64).product::<f64>();
    let mut sum = 0.0;
    for s in 0..=(n - m) / 2 {
        let c = fact(n - s) / (fact(s) * fact((n + m) / 2 - s) * fact((n - m) / 2 - s));
        let sign = if s % 2 == 0 { 1.0 } else { -1.0 };
        sum += sign * c * rho.powi((n - 2 * s) as i32);
    }
    sum
}

/// The RMS-normalised Zernike polynomial `Z_j` (Noll index `j ≥ 1`) at pupil point
/// (`x`, `y`) in units of the radius.
pub fn zernike_noll(j: usize, x: f64, y: f64) -> f64 {
    let (n, m) = noll_to_nm(j);
    let rho = x.hypot(y);
    let radial = zernike_radial(n, m, rho);
    if m == 0 {
        ((n + 1) as f64).sqrt() * radial
    } else {
        let theta = y.atan2(x);
        let angular = if j % 2 == 0 {
            (m as f64 * theta).cos()
        } else {
            (m as f64 * theta).sin()
        };
        (2.0 * (n + 1) as f64).sqrt() * radial * angular
    }
}

/// Seidel wave-aberration coefficients, waves at the reference wavelength (peak at the pupil
/// edge). As a field law they are the full-field (H = 1) values; as a local wavefront
/// ([`LocalWavefront`]) they are the values at one field point.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Seidel {
    /// Defocus ρ² (field-independent).
    pub w020: f64,
    /// Spherical aberration ρ⁴ (field-independent).
    pub w040: f64,
    /// Coma ρ³ cos φ (∝ H).
    pub w131: f64,
    /// Astigmatism ρ² cos² φ (∝ H²).
    pub w222: f64,
    /// Field curvature ρ² (∝ H²).
    pub w220: f64,
    /// Distortion (a tilt) ρ cos φ (∝ H³).
    pub w311: f64,
}

impl Seidel {
    /// The local coefficients at normalised field height `h` under the Seidel field law
    /// (defocus and spherical constant, coma ∝ H, astigmatism and field curvature ∝ H²,
    /// distortion ∝ H³).
    pub fn at_field(&self, h: f64) -> Seidel {
        Seidel {
            w020: self.w020,
            w040: self.w040,
            w131: self.w131 * h,
            w222: self.w222 * h * h,
            w220: self.w220 * h * h,
            w311: self.w311 * h * h * h,
        }
    }

    /// The wavefront (waves) of these local coefficients at pupil point (`x`, `y`)
    /// (units of the radius; `y` tangential): `(W020 + W220) ρ² + W040 ρ⁴ + W131 ρ² y +
    /// W222 y² + W311 y`.
    pub fn waves(&self, x: f64, y: f64) -> f64 {
        let r2 = x * x + y * y;
        (self.w020 + self.w220) * r2
            + self.w040 * r2 * r2
            + self.w131 * r2 * y
            + self.w222 * y * y
            + self.w311 * y
    }

    fn lerp(&self, other: &Seidel, t: f64) -> Seidel {
        let l = |a: f64, b: f64| a + t * (b - a);
        Seidel {
            w020: l(self.w020, other.w020),
            w040: l(self.w040, other.w040),
            w131: l(self.w131, other.w131),
            w222: l(self.w222, other.w222),
            w220: l(self.w220, other.w220),
            w311: l(self.w311, other.w311),
        }
    }
}

/// The wavefront at one field point: local Seidel coefficients plus Noll Zernike terms
/// (`zernike_rms_waves[i]` is the coefficient of `Z_{i+1}`), all in waves at the reference
/// wavelength.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LocalWavefront {
    /// Local Seidel coefficients (already evaluated at the field point).
    pub seidel: Seidel,
    /// Noll Zernike coefficients, RMS waves; index i ↔ Z_{i+1}.
    pub zernike_rms_waves: Vec<f64>,
}

impl LocalWavefront {
    /// The wavefront in waves at the reference wavelength at pupil point (`x`, `y`).
    pub fn waves(&self, x: f64, y: f64) -> f64 {
        let mut w = self.seidel.waves(x, y);
        for (i, &c) in self.zernike_rms_waves.iter().enumerate() {
            if c != 0.0 {
                w += c * zernike_noll(i + 1, x, y);
            }
        }
        w
    }

    /// Whether the wavefront depends on ρ only (defocus, spherical and m = 0 Zernike terms),
    /// so that the OTF is radially symmetric for a symmetric pupil.
    pub fn is_radially_symmetric(&self) -> bool {
        let s = &self.seidel;
        s.w131 == 0.0
            && s.w222 == 0.0
            && s.w311 == 0.0
            && self
                .zernike_rms_waves
                .iter()
                .enumerate()
                .all(|(i, &c)| c == 0.0 || noll_to_nm(i + 1).1 == 0)
    }

    fn lerp(&self, other: &LocalWavefront, t: f64) -> LocalWavefront {
        let n = self
            .zernike_rms_waves
            .len()
            .max(other.zernike_rms_waves.len());
        let get = |v: &[f64], i: usize| v.get(i).copied().unwrap_or(0.0);
        LocalWavefront {
            seidel: self.seidel.lerp(&other.seidel, t),
            zernike_rms_waves: (0..n)
                .map(|i| {
                    let a = get(&self.zernike_rms_waves, i);
                    a + t * (get(&other.zernike_rms_waves, i) - a)
                })
                .collect(),
        }
    }
}

/// How the wavefront varies with normalised field height H.
#[derive(Debug, Clone, PartialEq)]
pub enum FieldDependence {
    /// Seidel field law on full-field (H = 1) Seidel coefficients; the Zernike terms are
    /// the same at every field point.
    Seidel {
        /// Full-field Seidel coefficients.
        full_field: Seidel,
        /// Field-independent Noll Zernike terms, RMS waves (index i ↔ Z_{i+1}).
        zernike_rms_waves: Vec<f64>,
    },
    /// A table of local wavefronts at increasing field heights, interpolated linearly in H
    /// (held constant outside the table).
    Table(Vec<(f64, LocalWavefront)>),
}

/// A lens's wavefront over the field, in waves at a reference wavelength.
#[derive(Debug, Clone, PartialEq)]
pub struct WavefrontModel {
    reference_wavelength_m: f64,
    field: FieldDependence,
}

impl WavefrontModel {
    /// Builds a model; `reference_wavelength_m > 0`. A table must have at least one row,
    /// field heights finite, in [0, 1] and strictly increasing. Zernike lists may hold at
    /// most [`MAX_NOLL_INDEX`] terms; every coefficient must be finite.
    pub fn new(reference_wavelength_m: f64, field: FieldDependence) -> Result<Self> {
        if !(reference_wavelength_m.is_finite() && reference_wavelength_m > 0.0) {
            return Err(Error::param(
                "reference_wavelength",
                reference_wavelength_m,
                "a wavelength > 0",
            ));
        }
        let check_local = |w: &LocalWavefront, at: &str| -> Result<()> {
            check_seidel(&w.seidel, at)?;
            check_zernike(&w.zernike_rms_waves, at)
        };
        match &field {
            FieldDependence::Seidel {
                full_field,
                zernike_rms_waves,
            } => {
                check_seidel(full_field, "")?;
                check_zernike(zernike_rms_waves, "")?;
            }
            FieldDependence::Table(rows) => {
                if rows.is_empty() {
                    return Err(Error::param(
                        "field_point",
                        "0 rows",
                        "at least one field point",
                    ));
                }
                for (i, (h, w)) in rows.iter().enumerate() {
                    let at = format!("field_point[{i}].");
                    if !(h.is_finite() && (0.0..=1.0).contains(h)) {
                        return Err(Error::param(
                            format!("{at}h"),
                            h,
                            "a field height in [0, 1]",
                        ));
                    }
                    if i > 0 && *h <= rows[i - 1].0 {
                        return Err(Error::param(
                            format!("{at}h"),
                            h,
                            format!(
                                "field heights strictly increasing (previous {})",
                                rows[i - 1].0
                            ),
                        ));
                    }
                    check_local(w, &at)?;
                }
            }
        }
        Ok(WavefrontModel {
            reference_wavelength_m,
            field,
        })
    }

    /// The reference wavelength of the coefficients, m.
    pub fn reference_wavelength_m(&self) -> f64 {
        self.reference_wavelength_m
    }

    /// The field dependence.
    pub fn field(&self) -> &FieldDependence {
        &self.field
    }

    /// The local wavefront at normalised field height `h` (clamped to [0, 1]).
    pub fn at_field(&self, h: f64) -> LocalWavefront {
        let h = if h.is_nan() { 0.0 } else { h.clamp(0.0, 1.0) };
        match &self.field {
            FieldDependence::Seidel {
                full_field,
                zernike_rms_waves,
            } => LocalWavefront {
                seidel: full_field.at_field(h),
                zernike_rms_waves: zernike_rms_waves.clone(),
            },
            FieldDependence::Table(rows) => {
                let j = rows.partition_point(|(hh, _)| *hh < h);
                if j == 0 {
                    rows[0].1.clone()
                } else if j == rows.len() {
                    rows[rows.len() - 1].1.clone()
                } else {
                    let (h0, w0) = &rows[j - 1];
                    let (h1, w1) = &rows[j];
                    w0.lerp(w1, (h - h0) / (h1 - h0))
                }
            }
        }
    }

    /// Whether the wavefront is the same at every field height.
    pub fn is_field_independent(&self) -> bool {
        match &self.field {
            FieldDependence::Seidel { full_field, .. } => {
                full_field.w131 == 0.0
                    && full_field.w222 == 0.0
                    && full_field.w220 == 0.0
                    && full_field.w311 == 0.0
            }
            FieldDependence::Table(rows) => rows.iter().all(|(_, w)| *w == rows[0].1),
        }
    }
}

/// Largest |coefficient| accepted, waves (beyond it the pupil sampling needed to resolve
/// the phase is impractical, and geometric optics is the right model).
pub const MAX_COEFFICIENT_WAVES: f64 = 20.0;

fn check_coefficient(field: String, value: f64) -> Result<()> {
    if !(value.is_finite() && value.abs() <= MAX_COEFFICIENT_WAVES) {
        return Err(Error::param(
            field,
            value,
            format!("a finite coefficient within ±{MAX_COEFFICIENT_WAVES} waves"),
        ));
    }
    Ok(())
}

fn check_seidel(s: &Seidel, at: &str) -> Result<()> {
    for (name, v) in [
        ("w020_waves", s.w020),
        ("w040_waves", s.w040),
        ("w131_waves", s.w131),
        ("w222_waves", s.w222),
        ("w220_waves", s.w220),
        ("w311_waves", s.w311),
    ] {
        check_coefficient(format!("{at}{name}"), v)?;
    }
    Ok(())
}

fn check_zernike(z: &[f64], at: &str) -> Result<()> {
    if z.len() > MAX_NOLL_INDEX {
        return Err(Error::param(
            format!("{at}zernike_noll_rms_waves"),
            format!("{} terms", z.len()),
            format!("at most {MAX_NOLL_INDEX} terms (Noll j = 1..={MAX_NOLL_INDEX})"),
        ));
    }
    for (i, &c) in z.iter().enumerate() {
        check_coefficient(format!("{at}zernike_noll_rms_waves[{i}] (Z{})", i + 1), c)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noll_table_1_orders() {
        // Noll 1976, Table 1.
        let expect = [
            (1, (0, 0)),
            (2, (1, 1)),
            (3, (1, 1)),
            (4, (2, 0)),
            (5, (2, 2)),
            (6, (2, 2)),
            (7, (3, 1)),
            (8, (3, 1)),
            (9, (3, 3)),
            (10, (3, 3)),
            (11, (4, 0)),
            (12, (4, 2)),
            (13, (4, 2)),
            (14, (4, 4)),
            (15, (4, 4)),
            (22, (6, 0)),
        ];
        for (j, nm) in expect {
            assert_eq!(noll_to_nm(j), nm, "j = {j}");
        }
    }

    #[test]
    fn zernike_are_orthonormal_over_the_disc() {
        // Midpoint quadrature over the unit disc (polar grid): <Zi Zj> = δij.
        let (nr, nt) = (200, 256);
        let mut gram = [[0.0f64; 12]; 12];
        let mut area = 0.0;
        for ir in 0..nr {
            let r = (ir as f64 + 0.5) / nr as f64;
            for it in 0..nt {
                let t = (it as f64 + 0.5) / nt as f64 * std::f64::consts::TAU;
                let (x, y) = (r * t.cos(), r * t.sin());
                let w = r;
                area += w;
                let z: Vec<f64> = (1..=12).map(|j| zernike_noll(j, x, y)).collect();
                for a in 0..12 {
                    for b in 0..12 {
                        gram[a][b] += w * z[a] * z[b];
                    }
                }
            }
        }
        for (a, row) in gram.iter().enumerate() {
            for (b, g) in row.iter().enumerate() {
                let v = g / area;
                let want = if a == b { 1.0 } else { 0.0 };
                assert!((v - want).abs() < 2e-3, "<Z{} Z{}> = {v}", a + 1, b + 1);
            }
        }
        // Z7 is tangential (y) coma: √8(3ρ³ − 2ρ) sin θ.
        let (x, y) = (0.3f64, 0.5f64);
        let rho = x.hypot(y);
        let want = 8f64.sqrt() * (3.0 * rho.powi(3) - 2.0 * rho) * (y / rho);
        assert!((zernike_noll(7, x, y) - want).abs() < 1e-12);
    }

    #[test]
    fn seidel_field_law_and_table_interpolation() {
        let full = Seidel {
            w020: 0.1,
            w040: 0.2,
            w131: 0.4,
            w222: 0.8,
            w220: 0.3,
            w311: 0.5,
        };
        let at = full.at_field(0.5);
        assert_eq!(at.w020, 0.1);
        assert_eq!(at.w040, 0.2);
        assert!((at.w131 - 0.2).abs() < 1e-15);
        assert!((at.w222 - 0.2).abs() < 1e-15);
        assert!((at.w220 - 0.075).abs() < 1e-15);
        assert!((at.w311 - 0.0625).abs() < 1e-15);
        let row = |c: f64| LocalWavefront {
            seidel: Seidel {
                w131: c,
                ..Seidel::default()
            },
            zernike_rms_waves: vec![0.0, 0.0, 0.0, c],
        };
        let m = WavefrontModel::new(
            4e-6,
            FieldDependence::Table(vec![(0.0, row(0.0)), (0.5, row(0.2)), (1.0, row(0.6))]),
        )
        .unwrap();
        let w = m.at_field(0.75);
        assert!((w.seidel.w131 - 0.4).abs() < 1e-12);
        assert!((w.zernike_rms_waves[3] - 0.4).abs() < 1e-12);
        assert_eq!(m.at_field(2.0), row(0.6));
        // Bad rows are named.
        let err = WavefrontModel::new(
            4e-6,
            FieldDependence::Table(vec![(0.5, row(0.0)), (0.5, row(0.1))]),
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("field_point[1].h"), "{err}");
        let err = WavefrontModel::new(4e-6, FieldDependence::Table(vec![(0.0, row(f64::NAN))]))
            .unwrap_err()
            .to_string();
        assert!(err.contains("w131_waves"), "{err}");
    }
}
