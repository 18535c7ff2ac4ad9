//! The aperture of the generalised pupil: a circular pupil with an optional central
//! obscuration and spider vanes, sampled on a square grid.
//!
//! Pupil coordinates are normalised to the pupil radius (`ρ ≤ 1`); `x` is the sagittal
//! axis and `y` the tangential one (the field point lies along +y, docs/wavefront.md).

use crate::error::{Error, Result};

/// A clear or centrally obscured circular pupil with optional radial spider vanes.
#[derive(Debug, Clone, PartialEq)]
pub struct Pupil {
    /// Central obscuration ratio, obscuration diameter / pupil diameter, in [0, 1).
    obscuration_ratio: f64,
    /// Number of radial vanes (0 = none), each from the centre to the rim.
    spider_vanes: u32,
    /// Width of each vane as a fraction of the pupil diameter, in [0, 0.5).
    spider_width_fraction: f64,
    /// Direction of the first vane, radians counter-clockwise from +x; the others follow
    /// at equal angles `2π/spider_vanes`.
    spider_angle_rad: f64,
}

impl Pupil {
    /// A clear circular pupil.
    pub fn clear() -> Self {
        Pupil {
            obscuration_ratio: 0.0,
            spider_vanes: 0,
            spider_width_fraction: 0.0,
            spider_angle_rad: 0.0,
        }
    }

    /// A circular pupil with central obscuration ratio `obscuration_ratio` in [0, 1).
    pub fn obscured(obscuration_ratio: f64) -> Result<Self> {
        if !(obscuration_ratio.is_finite() && (0.0..1.0).contains(&obscuration_ratio)) {
            return Err(Error::param(
                "obscuration_ratio",
                obscuration_ratio,
                "a number in [0, 1)",
            ));
        }
        Ok(Pupil {
            obscuration_ratio,
            ..Pupil::clear()
        })
    }

    /// Adds `vanes` radial spider vanes of width `width_fraction` × the pupil diameter
    /// (in [0, 0.5)), the first at `angle_rad` from +x, the others equally spaced.
    pub fn with_spider(mut self, vanes: u32, width_fraction: f64, angle_rad: f64) -> Result<Self> {
        if vanes > 16 {
            return Err(Error::param("spider_vanes", vanes, "an integer in 0..=16"));
        }
        if !(width_fraction.is_finite() && (0.0..0.5).contains(&width_fraction)) {
            return Err(Error::param(
                "spider_width_fraction",
                width_fraction,
                "a fraction of the pupil diameter in [0, 0.5)",
            ));
        }
        if !angle_rad.is_finite() {
            return Err(Error::param("spider_angle", angle_rad, "a finite angle"));
        }
        self.spider_vanes = vanes;
        self.spider_width_fraction = width_fraction;
        self.spider_angle_rad = angle_rad;
        Ok(self)
    }

    /// The central obscuration ratio.
    pub fn obscuration_ratio(&self) -> f64 {
        self.obscuration_ratio
    }

    /// The number of spider vanes.
    pub fn spider_vanes(&self) -> u32 {
        self.spider_vanes
    }

    /// Whether the pupil is rotationally symmetric (no spider vanes).
    pub fn is_radially_symmetric(&self) -> bool {
        self.spider_vanes == 0 || self.spider_width_fraction == 0.0
    }

    /// Whether the point (`x`, `y`), in units of the pupil radius, transmits (1) or not (0).
    pub fn transmits(&self, x: f64, y: f64) -> bool {
        let r2 = x * x + y * y;
        if r2 > 1.0 || r2 < self.obscuration_ratio * self.obscuration_ratio {
            return false;
        }
        // A vane of width w·D has half-width w in units of the radius D/2.
        let half_width = self.spider_width_fraction;
        if self.spider_vanes > 0 && half_width > 0.0 {
            let step = std::f64::consts::TAU / f64::from(self.spider_vanes);
            for k in 0..self.spider_vanes {
                let a = self.spider_angle_rad + step * f64::from(k);
                let (s, c) = a.sin_cos();
                let along = x * c + y * s;
                let across = -x * s + y * c;
                if along >= 0.0 && across.abs() <= half_width {
                    return false;
                }
            }
        }
        true
    }
}
