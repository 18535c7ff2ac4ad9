//! The line of sight over one exposure window, as a piecewise-linear path, and its motion
//! transfer function.

use num_complex::Complex64;

use crate::optics::sinc;

/// A window's path: the time-average position and the path relative to it, sampled at
/// equal time steps (its piecewise-linear interpolant is the path).
#[derive(Debug, Clone, PartialEq)]
pub struct WindowPath {
    /// Time-average of the (piecewise-linear) path over the window, [x, y] rad: the shift
    /// that moves between frames.
    pub mean_rad: [f64; 2],
    /// Path samples relative to `mean_rad` at equal time steps spanning the window, rad
    /// (at least 2).
    pub points_rad: Vec<[f64; 2]>,
    /// Bound on |interpolant − d(t)| over the window, rad (see
    /// [`crate::los::LineOfSight::window`]).
    bound_rad: f64,
}

impl WindowPath {
    /// The path through `points_abs_rad` (absolute positions at equal time steps, at least
    /// 2; a single point is a still path), with the interpolation bound `bound_rad`: splits
    /// off the piecewise-linear path's exact time-average Σ_j (p_j + p_{j+1}) / 2n.
    pub fn from_points(points_abs_rad: &[[f64; 2]], bound_rad: f64) -> WindowPath {
        let pts: Vec<[f64; 2]> = match points_abs_rad.len() {
            0 => vec![[0.0; 2]; 2],
            1 => vec![points_abs_rad[0]; 2],
            _ => points_abs_rad.to_vec(),
        };
        let n = (pts.len() - 1) as f64;
        let mut mean = [0.0; 2];
        for w in pts.windows(2) {
            for a in 0..2 {
                mean[a] += 0.5 * (w[0][a] + w[1][a]) / n;
            }
        }
        WindowPath {
            mean_rad: mean,
            points_rad: pts
                .iter()
                .map(|p| [p[0] - mean[0], p[1] - mean[1]])
                .collect(),
            bound_rad,
        }
    }

    /// Motion transfer function of the path about its mean (f in cycles/rad):
    ///
    /// H(f) = (1/T) ∫ exp(−2πi f·p(t)) dt = Σ_j w_j exp(−2πi f·(p_j+p_{j+1})/2) sinc(f·(p_{j+1}−p_j)),
    ///
    /// w_j = 1/n for n equal segments, sinc(x) = sin(πx)/(πx). Each segment is a linear
    /// motion, whose transfer function is the phase of its midpoint times the sinc of its
    /// length (Holst, *Electro-Optical Imaging System Performance*, linear-motion MTF), so
    /// the sum is exact for the piecewise-linear path; against the true d(t) the error is
    /// at most 2π|f|·[`Self::interpolation_bound_rad`] (|e^{ia} − e^{ib}| ≤ |a − b|). A
    /// linear path gives the real sinc(f·vT).
    pub fn otf(&self, fx_cy_per_rad: f64, fy_cy_per_rad: f64) -> Complex64 {
        let n = (self.points_rad.len() - 1) as f64;
        let tau = 2.0 * std::f64::consts::PI;
        let mut sum = Complex64::new(0.0, 0.0);
        for w in self.points_rad.windows(2) {
            let (p, q) = (w[0], w[1]);
            let mid = fx_cy_per_rad * 0.5 * (p[0] + q[0]) + fy_cy_per_rad * 0.5 * (p[1] + q[1]);
            let len = fx_cy_per_rad * (q[0] - p[0]) + fy_cy_per_rad * (q[1] - p[1]);
            sum += Complex64::from_polar(sinc(len), -tau * mid);
        }
        sum / n
    }

    /// Largest distance between two points of the path (its diameter), rad: the smear
    /// length of the truth table. Exact for the piecewise-linear path (the diameter of a
    /// polyline is attained at two of its vertices): the vertices' convex hull, then its
    /// antipodal pairs by rotating calipers (Shamos 1978).
    pub fn smear_rad(&self) -> f64 {
        diameter(&convex_hull(&self.points_rad))
    }

    /// max over the window's normalised time s ∈ [0, 1] of |p_self(s) − p_other(s)|, rad,
    /// both paths about their own means (piecewise-linear interpolants; the difference of
    /// two such is piecewise linear on the union of their breakpoints, so the maximum is at
    /// a breakpoint and this is exact).
    pub fn max_deviation_rad(&self, other: &WindowPath) -> f64 {
        let n = self.points_rad.len() - 1;
        let m = other.points_rad.len() - 1;
        let mut best = 0.0f64;
        let breaks = (0..=n)
            .map(|i| i as f64 / n as f64)
            .chain((0..=m).map(|j| j as f64 / m as f64));
        for s in breaks {
            let a = self.at(s);
            let b = other.at(s);
            best = best.max((a[0] - b[0]).hypot(a[1] - b[1]));
        }
        best
    }

    /// The path (about the mean) at normalised time s ∈ [0, 1], linearly interpolated.
    pub fn at(&self, s: f64) -> [f64; 2] {
        let n = self.points_rad.len() - 1;
        let u = (s.clamp(0.0, 1.0) * n as f64).min(n as f64);
        let i = (u.floor() as usize).min(n - 1);
        let w = u - i as f64;
        let (p, q) = (self.points_rad[i], self.points_rad[i + 1]);
        [p[0] + w * (q[0] - p[0]), p[1] + w * (q[1] - p[1])]
    }

    /// Bound on the distance between this piecewise-linear path and the true d(t) over
    /// the window, rad.
    pub fn interpolation_bound_rad(&self) -> f64 {
        self.bound_rad
    }

    /// Number of equal segments.
    pub fn segments(&self) -> usize {
        self.points_rad.len() - 1
    }
}

/// Diameter of a convex polygon given counter-clockwise without collinear vertices.
fn diameter(hull: &[[f64; 2]]) -> f64 {
    let dist = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
    let n = hull.len();
    match n {
        0 | 1 => return 0.0,
        2 => return dist(hull[0], hull[1]),
        _ => {}
    }
    // Twice the area of triangle (a, b, c).
    let area = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])).abs()
    };
    let mut best = 0.0f64;
    let mut j = 1;
    for i in 0..n {
        let ni = (i + 1) % n;
        // Advance j while it moves away from edge (i, i+1); at most n steps in total per
        // edge, bounded for safety.
        let mut steps = 0;
        while steps < n
            && area(hull[i], hull[ni], hull[(j + 1) % n]) > area(hull[i], hull[ni], hull[j])
        {
            j = (j + 1) % n;
            steps += 1;
        }
        best = best
            .max(dist(hull[i], hull[j]))
            .max(dist(hull[ni], hull[j]));
    }
    best
}

/// The convex hull of `points` (Andrew's monotone chain; collinear points dropped).
fn convex_hull(points: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut p: Vec<[f64; 2]> = points.to_vec();
    p.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * p.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &[f64; 2]>> = if pass == 0 {
            Box::new(p.iter())
        } else {
            Box::new(p.iter().rev())
        };
        for &q in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0
            {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
    }
    hull
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn calipers_diameter_matches_all_pairs() {
        // A deterministic scatter (a low-discrepancy sequence on an ellipse-ish cloud).
        let pts: Vec<[f64; 2]> = (0..700)
            .map(|i| {
                let a = i as f64 * 2.399_963;
                let r = ((i * 7919) % 1000) as f64 / 1000.0;
                [3.0 * r * a.cos(), r * a.sin() + 0.1 * a.cos()]
            })
            .collect();
        let mut brute = 0.0f64;
        for a in &pts {
            for b in &pts {
                brute = brute.max((a[0] - b[0]).hypot(a[1] - b[1]));
            }
        }
        let d = diameter(&convex_hull(&pts));
        assert!((d - brute).abs() <= 1e-12 * brute, "{d} vs {brute}");
        // Degenerate: collinear and repeated points.
        let line = [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [1.0, 1.0]];
        assert!((diameter(&convex_hull(&line)) - 8f64.sqrt()).abs() < 1e-15);
        assert_eq!(diameter(&convex_hull(&[[1.0, 2.0], [1.0, 2.0]])), 0.0);
    }
}
