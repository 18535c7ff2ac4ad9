//! The Poisson draw of the shot noise for means of 12 electrons and more: Ahrens and
//! Dieter's algorithm PD (J. H. Ahrens, U. Dieter, "Computer generation of Poisson
//! deviates from modified normal distributions", ACM Trans. Math. Softw. 8(2), 163–179,
//! 1982), step for step as `rand_distr` 0.6's `Poisson` implements it (its
//! `RejectionMethod`), so every draw and the generator's state after it are the same to
//! the bit as `Poisson::new(mean).sample(rng)` (test). Below 12 the crate's own
//! multiplication method stays in use ([`super::shot`]).
//!
//! What differs is only when the work is done. The crate computes every constant of the
//! algorithm (the step-F polynomial c₀…c₃, ω, c: five divisions) when the distribution is
//! built, i.e. for every pixel, since each pixel has its own mean. Steps N, I and S accept
//! nearly every draw with only `s = √μ`, `L = ⌊μ − 1.1484⌋` and `d = 6μ²` (step S rejects
//! a draw with probability about E|z|³/(12√μ), under 1 % for μ ≥ 1000), so here the
//! other constants are computed, by the same expressions, only when a draw reaches step
//! P; and the draw is a plain function the detector's row loop inlines (compiled for AVX2
//! with it, the `floor`s become single instructions) instead of a call into code built
//! for the baseline CPU.

use rand::{Rng, RngExt};
use rand_distr::{Distribution, Exp1, StandardNormal};

/// The smallest mean drawn by [`ahrens_dieter`]; below it the multiplication method
/// (`rand_distr`'s Knuth branch), as `rand_distr::Poisson` chooses.
pub(crate) const SMALLEST_MEAN: f64 = 12.0;

/// One Poisson deviate of mean `mu` (12 ≤ `mu` ≤ `rand_distr::Poisson::MAX_LAMBDA`, the
/// caller's to check), as a whole number in an `f64`: Ahrens–Dieter's steps N, I and S
/// (a normal deviate `g = μ + √μ·z` floored, accepted when `⌊g⌋ ≥ L`, or when a uniform
/// `u` has `6μ²·u ≥ (μ − ⌊g⌋)³`), then steps P, E and H ([`steps_p_to_h`]) for the rest.
#[inline(always)]
pub(crate) fn ahrens_dieter<R: Rng + ?Sized>(mu: f64, rng: &mut R) -> f64 {
    let s = mu.sqrt();
    let l = (mu - 1.1484).floor();
    // Step N (rand_distr: `Normal::new(μ, s)`, sampled as μ + s·z).
    let g = mu + s * rng.sample::<f64, _>(StandardNormal);
    if g >= 0.0 {
        let k = g.floor();
        // Step I.
        if k >= l {
            return k;
        }
        // Step S.
        let u: f64 = rng.random();
        let d = 6.0 * mu.powi(2);
        if d * u >= (mu - k).powi(3) {
            return k;
        }
        return steps_p_to_h(mu, s, Some((k, u)), rng);
    }
    steps_p_to_h(mu, s, None, rng)
}

/// Steps P (the quotient acceptance of the normal deviate `k` with its uniform `u`, when
/// step N gave one with `g ≥ 0`), then E and H (double-exponential proposals until one is
/// accepted) of [`ahrens_dieter`], with the constants of step F computed here.
#[cold]
#[inline(never)]
fn steps_p_to_h<R: Rng + ?Sized>(mu: f64, s: f64, first: Option<(f64, f64)>, rng: &mut R) -> f64 {
    // Step F's constants (Ahrens–Dieter's table 2; the expressions of rand_distr 0.6).
    let b1 = (1.0 / 24.0) / mu;
    let b2 = 0.3 * b1 * b1;
    let c3 = (1.0 / 7.0) * b1 * b2;
    let c2 = b2 - 15.0 * c3;
    let c1 = b1 - 6.0 * b2 + 45.0 * c3;
    let c0 = 1.0 - b1 + 3.0 * b2 - 15.0 * c3;
    let c = 0.1069 / mu;
    let omega = 1.0 / (2.0 * std::f64::consts::PI).sqrt() / mu.sqrt();
    // Step F: (p_x, p_y, f_x, f_y) at k.
    let f = |k: f64| {
        /// 0! … 9!.
        const FACT: [f64; 10] = [
            1.0, 1.0, 2.0, 6.0, 24.0, 120.0, 720.0, 5040.0, 40320.0, 362880.0,
        ];
        /// The coefficients a₀…a₉ of Ahrens–Dieter's table 1.
        const A: [f64; 10] = [
            -0.5000000002,
            0.3333333343,
            -0.2499998565,
            0.1999997049,
            -0.1666848753,
            0.1428833286,
            -0.1241963125,
            0.1101687109,
            -0.1142650302,
            0.1055093006,
        ];
        let (px, py) = if k < 10.0 {
            // k ≥ 0 here: k = ⌊g⌋ with g ≥ 0, or ⌊μ + s·t⌋ with t > −0.6744 and μ ≥ 12.
            (-mu, mu.powf(k) / FACT[k as usize])
        } else {
            let delta = (12.0 * k).recip();
            let delta = delta - 4.8 * delta.powi(3);
            let v = (mu - k) / k;
            let px = if v.abs() <= 0.25 {
                k * v.powi(2) * A.iter().rev().fold(0.0, |acc, &a| acc * v + a) - delta
            } else {
                k * (1.0 + v).ln() - (mu - k) - delta
            };
            (px, 1.0 / (2.0 * std::f64::consts::PI).sqrt() / k.sqrt())
        };
        let x = (k - mu + 0.5) / s;
        let fx = -0.5 * x * x;
        let fy = omega * (((c3 * x * x + c2) * x * x + c1) * x * x + c0);
        (px, py, fx, fy)
    };
    // Step P.
    if let Some((k, u)) = first {
        let (px, py, fx, fy) = f(k);
        if fy * (1.0 - u) <= py * (px - fx).exp() {
            return k;
        }
    }
    loop {
        // Step E.
        let e: f64 = Exp1.sample(rng);
        let u: f64 = rng.random::<f64>() * 2.0 - 1.0;
        let t = 1.8 + e * u.signum();
        if t > -0.6744 {
            let k = (mu + s * t).floor();
            let (px, py, fx, fy) = f(k);
            // Step H.
            if c * u.abs() <= py * (px + e).exp() - fy * (fx + e).exp() {
                return k;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::Poisson;
    use rand_xoshiro::Xoshiro256PlusPlus;

    /// Every draw and the generator's state after it equal `rand_distr`'s `Poisson` to the
    /// bit, for means from 12 (where steps P, E and H run most often: a few draws in 100)
    /// to 10¹⁵; the draws that leave step I (the normal deviate below L, about half) are
    /// counted, so steps S and beyond are known to be exercised.
    #[test]
    fn draws_are_rand_distr_poissons_to_the_bit() {
        let mut means = Xoshiro256PlusPlus::seed_from_u64(11);
        let mut a = Xoshiro256PlusPlus::seed_from_u64(5);
        let mut b = a.clone();
        let mut slow = 0;
        for i in 0..200_000u32 {
            let mu: f64 = match i % 4 {
                0 => 12.0 + 28.0 * means.random::<f64>(),
                1 => 12.0 + (i % 997) as f64 * 1e-3,
                2 => 10f64.powf(1.08 + 14.0 * means.random::<f64>()),
                _ => 12.0 * (1.0 + 1e4 * means.random::<f64>()),
            };
            let s = mu.sqrt();
            let l = (mu - 1.1484).floor();
            let mut probe = b.clone();
            let g = mu + s * probe.sample::<f64, _>(StandardNormal);
            slow += usize::from(g.floor() < l);
            let want = Poisson::new(mu).expect("a valid mean").sample(&mut a);
            let got = ahrens_dieter(mu, &mut b);
            assert_eq!(want.to_bits(), got.to_bits(), "mean {mu}, draw {i}");
        }
        assert_eq!(a.random::<u64>(), b.random::<u64>(), "generator states");
        // About half the draws leave step I (g below L): steps S and beyond are exercised.
        assert!(slow > 80_000, "{slow} draws past step I");
    }

    /// Independent truth: at μ = 20 the histogram of 200 000 draws against the Poisson pmf
    /// (`p₀ = e^{−μ}`, `p_k = p_{k−1}·μ/k`), Pearson's χ² over the bins k = 5…40 (the
    /// tails pooled into the end bins) below the 99.9 % point of χ² with 35 degrees of
    /// freedom (66.6); mean and variance within 5 standard errors of μ.
    #[test]
    fn histogram_follows_the_poisson_pmf() {
        let mu = 20.0;
        let n = 200_000;
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(3);
        let (lo, hi) = (5usize, 40usize);
        let mut counts = vec![0f64; hi - lo + 1];
        let (mut sum, mut sum2) = (0.0, 0.0);
        for _ in 0..n {
            let k = ahrens_dieter(mu, &mut rng);
            assert!(k >= 0.0 && k.fract() == 0.0, "{k}");
            sum += k;
            sum2 += k * k;
            counts[(k as usize).clamp(lo, hi) - lo] += 1.0;
        }
        let mut pmf = vec![(-mu).exp()];
        for k in 1..=hi {
            pmf.push(pmf[k - 1] * mu / k as f64);
        }
        let mut expected: Vec<f64> = (lo..=hi).map(|k| pmf[k]).collect();
        expected[0] = pmf[..=lo].iter().sum();
        expected[hi - lo] = 1.0 - pmf[..hi].iter().sum::<f64>();
        let chi2: f64 = counts
            .iter()
            .zip(&expected)
            .map(|(o, p)| (o - n as f64 * p).powi(2) / (n as f64 * p))
            .sum();
        assert!(chi2 < 66.6, "χ² = {chi2}");
        let mean = sum / n as f64;
        let var = sum2 / n as f64 - mean * mean;
        assert!(
            (mean - mu).abs() < 5.0 * (mu / n as f64).sqrt(),
            "mean {mean}"
        );
        // Var of the sample variance ≈ (μ₄ − σ⁴)/n with μ₄ = μ + 3μ² for a Poisson.
        let se_var = ((mu + 3.0 * mu * mu - mu * mu) / n as f64).sqrt();
        assert!((var - mu).abs() < 5.0 * se_var, "variance {var}");
    }
}
