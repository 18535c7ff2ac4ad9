//! Fast FFT lengths: the 5-smooth numbers (2^a·3^b·5^c) for which the FFT crates are
//! fastest. One home for the imaging engine's padding, the Wiener filter, the line of
//! sight's wander synthesis and the readout noise's series.

/// The smallest 5-smooth integer ≥ `n` (at least 1).
pub fn next_fast_len(n: usize) -> usize {
    let mut m = n.max(1);
    loop {
        let mut r = m;
        for p in [2, 3, 5] {
            while r % p == 0 {
                r /= p;
            }
        }
        if r == 1 {
            return m;
        }
        m += 1;
    }
}

/// The smallest even 5-smooth integer ≥ `n` (a real FFT's half spectrum without a lone
/// Nyquist-less end).
pub fn next_fast_even_len(n: usize) -> usize {
    let mut m = next_fast_len(n.max(2));
    while m % 2 == 1 {
        m = next_fast_len(m + 1);
    }
    m
}

/// The smallest multiple of `k` at least `n` whose quotient by `k` is 5-smooth:
/// `k·next_fast_len(⌈n/k⌉)` (a 5-smooth length itself when `k` is). An axis sampled every
/// k-th sample then has a lattice of whole periods, so its inverse can be folded
/// (`imaging::lattice`). `k = 0` is taken as 1.
pub fn next_fast_multiple(n: usize, k: usize) -> usize {
    let k = k.max(1);
    k * next_fast_len(n.div_ceil(k))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against a brute-force list of the 5-smooth numbers below 1000.
    #[test]
    fn lengths_are_the_next_5_smooth_numbers() {
        let smooth: Vec<usize> = (1..1000)
            .filter(|&m| {
                let mut r = m;
                for p in [2, 3, 5] {
                    while r % p == 0 {
                        r /= p;
                    }
                }
                r == 1
            })
            .collect();
        for n in 1..900 {
            let want = *smooth.iter().find(|&&m| m >= n).unwrap();
            assert_eq!(next_fast_len(n), want, "{n}");
            let even = *smooth
                .iter()
                .find(|&&m| m >= n.max(2) && m % 2 == 0)
                .unwrap();
            assert_eq!(next_fast_even_len(n), even, "{n}");
        }
        assert_eq!(next_fast_len(0), 1);
    }

    /// The fast multiple is a multiple of k, at least n, with a 5-smooth quotient, and no
    /// smaller such length exists (brute force).
    #[test]
    fn fast_multiples_are_the_smallest() {
        let smooth = |m: usize| {
            let mut r = m;
            for p in [2, 3, 5] {
                while r % p == 0 {
                    r /= p;
                }
            }
            r == 1
        };
        for k in 1..8usize {
            for n in 1..300usize {
                let m = next_fast_multiple(n, k);
                assert!(m >= n && m % k == 0 && smooth(m / k), "{n} {k} -> {m}");
                let brute = (n..).find(|&x| x % k == 0 && smooth(x / k)).unwrap();
                assert_eq!(m, brute, "{n} {k}");
            }
        }
    }
}
