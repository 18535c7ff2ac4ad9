//! Inter-pixel capacitance (IPC): the deterministic electrical coupling of a hybrid
//! (CMOS-multiplexed) focal plane, which makes part of the charge collected in one pixel
//! read out in its neighbours.
//!
//! The coupling is the 3 × 3 kernel of Kannawadi et al. (2016, "The impact of interpixel
//! capacitance in CMOS detectors on PSF shapes and implications for WFIRST", PASP 128,
//! 095001), with the nearest-neighbour coupling c (their α), the diagonal coupling d (α′)
//! and an anisotropy a between the two image axes:
//!
//! ```text
//!            x−1      x        x+1
//!   y−1  [ d,       c − a,   d      ]
//!   y    [ c + a,   1−4(c+d), c + a ]
//!   y+1  [ d,       c − a,   d      ]
//! ```
//!
//! The row index of the kernel is the image row (y), the column index the image column
//! (x): a > 0 couples more charge along a row (to the left and right neighbours, c + a)
//! than along a column (to the neighbours above and below, c − a). The entries sum to 1, so
//! the kernel moves charge between pixels without creating or destroying any.
//!
//! [`apply_ipc`] spreads every pixel's charge over its 3 × 3 neighbourhood. At the edges of
//! the array the share a pixel would pass to a neighbour that does not exist stays in the
//! pixel, so the total charge is conserved exactly and a flat field is unchanged (a real
//! array's edge pixels couple to reference pixels or to nothing; keeping the share is the
//! choice that conserves charge).

use ndarray::Array2;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// Tolerance on the sum of a kernel's entries (charge conservation), absolute.
const KERNEL_SUM_TOLERANCE: f64 = 1e-9;

/// The `[detector.ipc]` table: the parameters of the Kannawadi et al. (2016) kernel.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IpcConfig {
    /// Nearest-neighbour coupling c (Kannawadi's α): the fraction of a pixel's charge read
    /// in each of its four edge neighbours (before anisotropy), dimensionless. Required;
    /// typical HgCdTe arrays have 0.005–0.02.
    pub coupling: f64,
    /// Diagonal coupling d (Kannawadi's α′): the fraction read in each of the four corner
    /// neighbours, dimensionless. Default 0.
    #[serde(default)]
    pub diagonal: f64,
    /// Anisotropy a: the left/right neighbours (same row) get c + a, the neighbours above
    /// and below (same column) get c − a, dimensionless. Default 0.
    #[serde(default)]
    pub anisotropy: f64,
}

impl IpcConfig {
    /// Checks the constraints of Kannawadi et al. (2016): every parameter finite,
    /// d < c, |a| < c and 0 ≤ c + d ≤ 0.25 (so every edge coupling c ± a is positive and
    /// the centre 1 − 4(c + d) is in [0, 1]); then checks the kernel itself
    /// ([`validate_kernel`]).
    pub fn validate(&self) -> Result<()> {
        for (field, value) in [
            ("detector.ipc.coupling", self.coupling),
            ("detector.ipc.diagonal", self.diagonal),
            ("detector.ipc.anisotropy", self.anisotropy),
        ] {
            if !value.is_finite() {
                return Err(Error::param(field, value, "a finite number"));
            }
        }
        let (c, d, a) = (self.coupling, self.diagonal, self.anisotropy);
        if c <= 0.0 || c > 0.25 {
            return Err(Error::param(
                "detector.ipc.coupling",
                c,
                "a number in (0, 0.25] (omit [detector.ipc] for no coupling)",
            ));
        }
        if d >= c {
            return Err(Error::param(
                "detector.ipc.diagonal",
                d,
                format!("a number below detector.ipc.coupling = {c}"),
            ));
        }
        if a.abs() >= c {
            return Err(Error::param(
                "detector.ipc.anisotropy",
                a,
                format!("a number with |a| below detector.ipc.coupling = {c}"),
            ));
        }
        if !(0.0..=0.25).contains(&(c + d)) {
            return Err(Error::param(
                "detector.ipc.diagonal",
                d,
                format!("a number with 0 <= coupling + diagonal <= 0.25 (coupling = {c})"),
            ));
        }
        validate_kernel("detector.ipc", &ipc_kernel(self))
    }
}

/// The Kannawadi et al. (2016, PASP 128, 095001) IPC kernel
/// `[[d, c−a, d], [c+a, 1−4(c+d), c+a], [d, c−a, d]]`, indexed `[1 + dy][1 + dx]`: the
/// fraction of a pixel's charge read at the offset (dy rows, dx columns). The anisotropy
/// a acts along the rows: the left/right neighbours get c + a, those above/below c − a.
pub fn ipc_kernel(cfg: &IpcConfig) -> [[f64; 3]; 3] {
    let (c, d, a) = (cfg.coupling, cfg.diagonal, cfg.anisotropy);
    [
        [d, c - a, d],
        [c + a, 1.0 - 4.0 * (c + d), c + a],
        [d, c - a, d],
    ]
}

/// Checks a 3 × 3 coupling kernel (indexed `[1 + dy][1 + dx]` as [`ipc_kernel`]): every
/// entry finite, the centre in (0, 1], and the entries summing to 1 within 1e-9 (a kernel
/// that does not sum to 1 creates or destroys charge). `field` names the kernel's source
/// in the error.
pub fn validate_kernel(field: &str, kernel: &[[f64; 3]; 3]) -> Result<()> {
    for (i, row) in kernel.iter().enumerate() {
        for (j, &k) in row.iter().enumerate() {
            if !k.is_finite() {
                return Err(Error::param(
                    format!("{field} kernel[{i}][{j}]"),
                    k,
                    "a finite number",
                ));
            }
        }
    }
    let centre = kernel[1][1];
    if centre <= 0.0 || centre > 1.0 {
        return Err(Error::param(
            format!("{field} kernel[1][1]"),
            centre,
            "a number in (0, 1] (the share a pixel keeps)",
        ));
    }
    let sum: f64 = kernel.iter().flatten().sum();
    if (sum - 1.0).abs() > KERNEL_SUM_TOLERANCE {
        return Err(Error::param(
            format!("{field} kernel sum"),
            sum,
            "1 within 1e-9 (the coupling must conserve charge)",
        ));
    }
    Ok(())
}

/// The charge read out after inter-pixel coupling, e⁻ per pixel:
/// `out(y, x) = Σ_{dy,dx} K[1+dy][1+dx] · q(y−dy, x−dx)` over the source pixels inside the
/// array, plus, for a pixel on the edge, `q(y, x)` times the entries of K that point off
/// the array (that share stays in the pixel). So `Σ out = Σ q` exactly (up to rounding)
/// and a uniform `q` is returned unchanged when K sums to 1 (check it with
/// [`validate_kernel`]; [`IpcConfig::validate`] does). Rows are computed in parallel;
/// the result does not depend on the number of threads.
pub fn apply_ipc(kernel: &[[f64; 3]; 3], charge_e: &Array2<f64>) -> Array2<f64> {
    let (rows, cols) = charge_e.dim();
    let q = charge_e.as_standard_layout();
    let Some(q) = q.as_slice() else {
        // A standard-layout array is always contiguous; unreachable in practice.
        return charge_e.clone();
    };
    if rows == 0 || cols == 0 {
        return charge_e.clone();
    }
    let mut out = vec![0.0f64; rows * cols];
    out.par_chunks_mut(cols)
        .enumerate()
        .for_each(|(y, out_row)| {
            ipc_row(kernel, q, rows, cols, y, out_row);
        });
    // `out` has rows · cols elements, so the shape always matches.
    Array2::from_shape_vec((rows, cols), out).unwrap_or_else(|_| charge_e.clone())
}

/// One output row `y` of [`apply_ipc`] from the row-major charge `q` (rows × cols).
fn ipc_row(kernel: &[[f64; 3]; 3], q: &[f64], rows: usize, cols: usize, y: usize, out: &mut [f64]) {
    // Gathering: output (y, x) receives K[1+dy][1+dx] from the source (y−dy, x−dx).
    for (ky, dy) in [(0usize, -1isize), (1, 0), (2, 1)] {
        let sy = y as isize - dy;
        if sy < 0 || sy >= rows as isize {
            continue;
        }
        let src = &q[sy as usize * cols..(sy as usize + 1) * cols];
        let [k_left, k_mid, k_right] = kernel[ky];
        // dx = 0: source x.
        for (o, &s) in out.iter_mut().zip(src) {
            *o += k_mid * s;
        }
        // dx = +1 (kernel column 2): output x receives from source x − 1.
        for (o, &s) in out[1..].iter_mut().zip(&src[..cols - 1]) {
            *o += k_right * s;
        }
        // dx = −1 (kernel column 0): output x receives from source x + 1.
        for (o, &s) in out[..cols - 1].iter_mut().zip(&src[1..]) {
            *o += k_left * s;
        }
    }
    // Edge pixels keep the shares they would pass off the array.
    let own = &q[y * cols..(y + 1) * cols];
    let off_rows = |r: usize| -> f64 { kernel[r].iter().sum() };
    let mut kept_row = 0.0; // share sent off the top/bottom, all three columns.
    if y == 0 {
        kept_row += off_rows(0);
    }
    if y + 1 == rows {
        kept_row += off_rows(2);
    }
    if kept_row != 0.0 {
        for (o, &s) in out.iter_mut().zip(own) {
            *o += kept_row * s;
        }
    }
    // Left and right columns: the kernel column pointing off the array, minus the corner
    // entries already counted with the rows.
    let side = |c: usize| -> f64 {
        let off_array = |r: usize| (r == 0 && y == 0) || (r == 2 && y + 1 == rows);
        (0..3)
            .filter(|&r| !off_array(r))
            .map(|r| kernel[r][c])
            .sum()
    };
    let left = side(0);
    let right = side(2);
    if cols == 1 {
        out[0] += (left + right) * own[0];
    } else {
        out[0] += left * own[0];
        out[cols - 1] += right * own[cols - 1];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;
    use rand_distr::{Distribution, Poisson};

    use crate::detector::rng::{stream, Effect};

    fn cfg(c: f64, d: f64, a: f64) -> IpcConfig {
        IpcConfig {
            coupling: c,
            diagonal: d,
            anisotropy: a,
        }
    }

    /// The kernel written out by hand from Kannawadi et al. (2016) for c = 0.02,
    /// d = 0.002, a = 0.003 (rows = y): the constructor must place each parameter there.
    #[test]
    fn kernel_matches_the_published_layout() {
        let k = ipc_kernel(&cfg(0.02, 0.002, 0.003));
        let expected = [
            [0.002, 0.017, 0.002],
            [0.023, 0.912, 0.023],
            [0.002, 0.017, 0.002],
        ];
        for i in 0..3 {
            for j in 0..3 {
                assert!((k[i][j] - expected[i][j]).abs() < 1e-15, "{i} {j}");
            }
        }
    }

    /// A single bright pixel in the middle: each neighbour reads its kernel fraction of
    /// the charge (within 1e-6 of the charge), nothing else changes, the total is kept.
    #[test]
    fn single_pixel_spreads_by_the_kernel_fractions() {
        let k = ipc_kernel(&cfg(0.018, 0.0015, 0.002));
        let q0 = 1.0e5;
        let mut q = Array2::<f64>::zeros((9, 11));
        q[[4, 5]] = q0;
        let out = apply_ipc(&k, &q);
        // Independent truth: the charge the kernel's definition puts at each offset.
        // Left/right (same row) c + a, above/below c − a, corners d.
        let c = 0.018;
        let d = 0.0015;
        let a = 0.002;
        let truth = |dy: isize, dx: isize| -> f64 {
            match (dy.abs(), dx.abs()) {
                (0, 0) => 1.0 - 4.0 * (c + d),
                (0, 1) => c + a,
                (1, 0) => c - a,
                (1, 1) => d,
                _ => 0.0,
            }
        };
        for y in 0..9 {
            for x in 0..11 {
                let want = truth(y as isize - 4, x as isize - 5) * q0;
                assert!(
                    (out[[y, x]] - want).abs() <= 1e-6 * q0,
                    "({y},{x}): {} vs {want}",
                    out[[y, x]]
                );
            }
        }
        assert!((out.sum() - q0).abs() <= 1e-9 * q0);
    }

    /// In a corner, the three shares that would leave the array stay in the pixel; the
    /// in-array neighbours get their fractions; the total is conserved.
    #[test]
    fn corner_pixel_keeps_the_shares_that_would_leave() {
        let (c, d, a) = (0.02, 0.003, -0.004);
        let k = ipc_kernel(&cfg(c, d, a));
        let q0 = 1000.0;
        for (y0, x0) in [(0usize, 0usize), (0, 6), (4, 0), (4, 6), (0, 3), (2, 0)] {
            let mut q = Array2::<f64>::zeros((5, 7));
            q[[y0, x0]] = q0;
            let out = apply_ipc(&k, &q);
            let mut sent = 0.0;
            for dy in -1isize..=1 {
                for dx in -1isize..=1 {
                    if dy == 0 && dx == 0 {
                        continue;
                    }
                    let (y, x) = (y0 as isize + dy, x0 as isize + dx);
                    let frac = k[(dy + 1) as usize][(dx + 1) as usize];
                    if (0..5).contains(&y) && (0..7).contains(&x) {
                        let got = out[[y as usize, x as usize]];
                        assert!((got - frac * q0).abs() < 1e-9, "{y0},{x0} -> {y},{x}");
                        sent += frac;
                    }
                }
            }
            let kept = out[[y0, x0]] / q0;
            assert!(
                (kept - (1.0 - sent)).abs() < 1e-12,
                "{y0},{x0}: kept {kept}"
            );
            assert!((out.sum() - q0).abs() < 1e-9);
        }
    }

    /// Total charge of a random field (edges included, odd shapes, one row, one column)
    /// is conserved to rounding, and a flat field comes back unchanged.
    #[test]
    fn conserves_charge_and_leaves_flat_fields_alone() {
        let k = ipc_kernel(&cfg(0.015, 0.001, 0.004));
        for (rows, cols) in [(1, 1), (1, 9), (8, 1), (2, 2), (37, 53)] {
            let mut rng = stream(3, Effect::Shot, 0, 0);
            let q = Array2::from_shape_fn((rows, cols), |_| rng.random::<f64>() * 1e4);
            let out = apply_ipc(&k, &q);
            let rel = (out.sum() - q.sum()).abs() / q.sum();
            assert!(rel < 1e-13, "{rows}x{cols}: {rel}");
            let flat = Array2::from_elem((rows, cols), 4321.5);
            let out = apply_ipc(&k, &flat);
            for &v in out.iter() {
                assert!((v - 4321.5).abs() < 1e-9, "{rows}x{cols}: {v}");
            }
        }
    }

    /// Measurement on output (the way IPC is measured on real arrays, Moore et al. 2004):
    /// Poisson flat-field noise is white before coupling; after it, the autocorrelation at
    /// lag (ly, lx) is Σ K(p)·K(p + l) / Σ K² — about 2(c ± a) for the nearest
    /// neighbours. The estimate from a 256² flat matches it within 4 standard errors.
    #[test]
    fn flat_field_noise_correlation_measures_the_kernel() {
        let k = ipc_kernel(&cfg(0.02, 0.002, 0.005));
        let (rows, cols) = (256usize, 256usize);
        let mean = 1.0e4;
        let pois = Poisson::new(mean).unwrap();
        let mut rng = stream(11, Effect::Shot, 0, 0);
        let q = Array2::from_shape_fn((rows, cols), |_| pois.sample(&mut rng));
        let out = apply_ipc(&k, &q);
        let m = out.mean().unwrap();
        // Interior only (the edge pixels' kept shares change their statistics).
        let corr = |ly: usize, lx: usize| -> f64 {
            let (mut sxy, mut sxx) = (0.0, 0.0);
            for y in 1..rows - 1 - ly {
                for x in 1..cols - 1 - lx {
                    let u = out[[y, x]] - m;
                    sxy += u * (out[[y + ly, x + lx]] - m);
                    sxx += u * u;
                }
            }
            sxy / sxx
        };
        let kk = |dy: isize, dx: isize| -> f64 {
            if dy.abs() > 1 || dx.abs() > 1 {
                0.0
            } else {
                k[(dy + 1) as usize][(dx + 1) as usize]
            }
        };
        let auto = |ly: isize, lx: isize| -> f64 {
            let mut s = 0.0;
            for dy in -1..=1 {
                for dx in -1..=1 {
                    s += kk(dy, dx) * kk(dy + ly, dx + lx);
                }
            }
            s
        };
        let n = ((rows - 3) * (cols - 3)) as f64;
        for (ly, lx) in [(0usize, 1usize), (1, 0), (1, 1), (0, 2)] {
            let want = auto(ly as isize, lx as isize) / auto(0, 0);
            let got = corr(ly, lx);
            // Standard error of a sample correlation near 0: 1/√n.
            assert!(
                (got - want).abs() < 4.0 / n.sqrt(),
                "lag ({ly},{lx}): measured {got}, kernel {want}"
            );
        }
    }

    #[test]
    fn bad_parameters_and_kernels_are_errors() {
        assert!(cfg(0.02, 0.002, 0.005).validate().is_ok());
        let cases = [
            (cfg(-0.01, 0.0, 0.0), "detector.ipc.coupling"),
            (cfg(0.0, 0.0, 0.0), "detector.ipc.coupling"),
            (cfg(0.3, 0.0, 0.0), "detector.ipc.coupling"),
            (cfg(f64::NAN, 0.0, 0.0), "detector.ipc.coupling"),
            (cfg(0.02, 0.03, 0.0), "detector.ipc.diagonal"),
            (cfg(0.02, -0.03, 0.0), "detector.ipc.diagonal"),
            (cfg(0.2, 0.1, 0.0), "detector.ipc.diagonal"),
            (cfg(0.02, 0.0, 0.02), "detector.ipc.anisotropy"),
            (cfg(0.02, 0.0, -0.05), "detector.ipc.anisotropy"),
            (cfg(0.02, 0.0, f64::INFINITY), "detector.ipc.anisotropy"),
        ];
        for (c, field) in cases {
            let err = c.validate().expect_err(&format!("{c:?}")).to_string();
            assert!(err.contains(field), "{c:?}: {err}");
        }
        let mut leaky = ipc_kernel(&cfg(0.02, 0.0, 0.0));
        leaky[0][1] += 0.01;
        let err = validate_kernel("ipc", &leaky).unwrap_err().to_string();
        assert!(
            err.contains("kernel sum") && err.contains("conserve"),
            "{err}"
        );
        let mut nan = ipc_kernel(&cfg(0.02, 0.0, 0.0));
        nan[2][2] = f64::NAN;
        assert!(validate_kernel("ipc", &nan).is_err());
        assert!(validate_kernel("ipc", &[[0.0; 3], [0.0, 1.0, 0.0], [0.0; 3]]).is_ok());
    }

    #[test]
    fn unknown_keys_are_refused_and_defaults_apply() {
        let c: IpcConfig = toml::from_str("coupling = 0.01").unwrap();
        assert_eq!(c, cfg(0.01, 0.0, 0.0));
        assert!(toml::from_str::<IpcConfig>("coupling = 0.01\ncoupleing = 2").is_err());
        assert!(toml::from_str::<IpcConfig>("diagonal = 0.001").is_err());
    }
}
