//! The `thermal` scene: a vehicle on textured terrain under a sky strip, each region a
//! Lambertian material at its own temperature, lit by the [`Environment`].

use super::*;

/// Value noise: uniform random values in [−1, 1] on a square lattice of spacing `cell`,
/// interpolated with the quintic fade `6t⁵ − 15t⁴ + 10t³` (C² continuous, Perlin 2002).
struct ValueNoise {
    cell: f64,
    nx: usize,
    ny: usize,
    values: Vec<f64>,
}

impl ValueNoise {
    fn new(rng: &mut Xoshiro256PlusPlus, cell: f64, width: f64, height: f64) -> Self {
        let nx = (width / cell).ceil() as usize + 2;
        let ny = (height / cell).ceil() as usize + 2;
        let values = (0..nx * ny)
            .map(|_| 2.0 * rng.random::<f64>() - 1.0)
            .collect();
        ValueNoise {
            cell,
            nx,
            ny,
            values,
        }
    }

    fn eval(&self, x: f64, y: f64) -> f64 {
        let fade = |t: f64| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
        let gx = (x / self.cell).max(0.0);
        let gy = (y / self.cell).max(0.0);
        let ix = (gx.floor() as usize).min(self.nx - 2);
        let iy = (gy.floor() as usize).min(self.ny - 2);
        let tx = fade((gx - ix as f64).clamp(0.0, 1.0));
        let ty = fade((gy - iy as f64).clamp(0.0, 1.0));
        let v = |i: usize, j: usize| self.values[j * self.nx + i];
        let top = v(ix, iy) + (v(ix + 1, iy) - v(ix, iy)) * tx;
        let bottom = v(ix, iy + 1) + (v(ix + 1, iy + 1) - v(ix, iy + 1)) * tx;
        top + (bottom - top) * ty
    }
}

/// Fractal sum of value-noise octaves (cell halves, amplitude × 0.55 per octave), from
/// `base_cell` down to the finest cell not below `min_cell`, standardised to zero mean and
/// unit standard deviation over a fixed 64 × 64 grid of the field. Coordinates are in
/// image heights, so the field does not depend on the oversampling.
pub(super) struct Fbm {
    octaves: Vec<(f64, ValueNoise)>,
    mean: f64,
    scale: f64,
}

impl Fbm {
    /// Independent stream `stream` of `seed` (xoshiro jumps of 2¹²⁸ draws each).
    pub(super) fn new(
        seed: u64,
        stream: usize,
        base_cell: f64,
        min_cell: f64,
        width: f64,
        height: f64,
    ) -> Self {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        for _ in 0..stream {
            rng.jump();
        }
        let mut octaves = Vec::new();
        // Never finer than min_cell, so the lattice stays proportional to the image size.
        let mut cell = base_cell.max(min_cell);
        let mut amplitude = 1.0;
        while octaves.is_empty() || (cell >= min_cell && octaves.len() < 8) {
            octaves.push((amplitude, ValueNoise::new(&mut rng, cell, width, height)));
            cell *= 0.5;
            amplitude *= 0.55;
        }
        let mut f = Fbm {
            octaves,
            mean: 0.0,
            scale: 1.0,
        };
        let n = 64;
        let (mut s1, mut s2) = (0.0, 0.0);
        for j in 0..n {
            for i in 0..n {
                let v = f.raw(
                    (i as f64 + 0.5) / n as f64 * width,
                    (j as f64 + 0.5) / n as f64 * height,
                );
                s1 += v;
                s2 += v * v;
            }
        }
        let count = (n * n) as f64;
        let mean = s1 / count;
        let sd = (s2 / count - mean * mean).max(0.0).sqrt();
        f.mean = mean;
        f.scale = if sd > 1e-12 { 1.0 / sd } else { 1.0 };
        f
    }

    fn raw(&self, x: f64, y: f64) -> f64 {
        self.octaves.iter().map(|(a, n)| a * n.eval(x, y)).sum()
    }

    pub(super) fn eval(&self, x: f64, y: f64) -> f64 {
        (self.raw(x, y) - self.mean) * self.scale
    }
}

// ---------------------------------------------------------------------------------------
// Thermal scene
// ---------------------------------------------------------------------------------------

/// What each pixel of the [`thermal`] scene shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Region {
    /// Sky above the tree line.
    Sky,
    /// Tree line along the horizon (vegetation).
    Treeline,
    /// Open terrain: a mixture of vegetation and soil.
    Terrain,
    /// Terrain in the vehicle's shadow (no direct sun; only with `sun`).
    Shadow,
    /// Painted hull side.
    Hull,
    /// Rear part of the hull over the engine (warmer).
    EngineDeck,
    /// Painted turret.
    Turret,
    /// Gun barrel (painted).
    Barrel,
    /// Track and running gear.
    Track,
    /// Road wheels (warm bearings and rubber).
    Wheel,
    /// Hot exhaust outlet.
    Exhaust,
}

impl Region {
    /// True for the parts of the vehicle (the target).
    pub fn is_target(self) -> bool {
        matches!(
            self,
            Region::Hull
                | Region::EngineDeck
                | Region::Turret
                | Region::Barrel
                | Region::Track
                | Region::Wheel
                | Region::Exhaust
        )
    }
}

/// The [`thermal`] scene with the maps it was built from (useful as ground truth).
#[derive(Debug, Clone)]
pub struct ThermalScene {
    /// The spectral radiance cube.
    pub cube: Cube,
    /// What each cube pixel shows, `[row, col]`.
    pub region: Array2<Region>,
    /// Physical (thermodynamic) surface temperature, K, `[row, col]`; sky pixels carry the
    /// air temperature.
    pub temperature_k: Array2<f32>,
    /// Fraction of vegetation in the terrain mixture (1 on the tree line, 0 on the vehicle
    /// and the sky), `[row, col]`.
    pub vegetation_fraction: Array2<f32>,
}

/// Temperatures of the scene's parts, K.
struct Temperatures {
    air: f64,
    vegetation: f64,
    soil_dry: f64,
    /// Change of soil temperature from dry to fully moist soil (higher thermal inertia).
    soil_moist_delta: f64,
    treeline: f64,
    hull: f64,
    engine_extra: f64,
    exhaust: f64,
}

impl Temperatures {
    /// Night: the ground has cooled below the air by radiation to the sky, moist soil keeps
    /// its heat longer, the vehicle keeps some heat of its engine. Day: soil heats most in
    /// the sun, transpiring vegetation least, painted steel more than the ground.
    fn new(air: f64, sun: bool) -> Self {
        if sun {
            Temperatures {
                air,
                vegetation: air + 2.5,
                soil_dry: air + 11.0,
                soil_moist_delta: -6.0,
                treeline: air + 1.5,
                hull: air + 11.0,
                engine_extra: 10.0,
                exhaust: 550.0,
            }
        } else {
            Temperatures {
                air,
                vegetation: air - 1.5,
                soil_dry: air - 3.0,
                soil_moist_delta: 2.0,
                treeline: air - 0.8,
                hull: air + 3.0,
                engine_extra: 10.0,
                exhaust: 550.0,
            }
        }
    }
}

/// How to compute one pixel's spectrum: reflectance weights over [`Material::ALL`]
/// (`ρ = Σ wᵢ ρᵢ`), physical temperature and the fraction of direct sun it receives.
#[derive(Debug, Clone, Copy)]
struct Recipe {
    sky: bool,
    t_k: f32,
    sun: f32,
    weights: [f32; 5],
}

/// Point in polygon by the crossing-number rule.
fn in_polygon(x: f64, y: f64, poly: &[(f64, f64)]) -> bool {
    let mut inside = false;
    let mut j = poly.len() - 1;
    for i in 0..poly.len() {
        let (xi, yi) = poly[i];
        let (xj, yj) = poly[j];
        if (yi > y) != (yj > y) && x < (xj - xi) * (y - yi) / (yj - yi) + xi {
            inside = !inside;
        }
        j = i;
    }
    inside
}

/// Side view of the vehicle in its own coordinates, in units of the scene scale `s`:
/// ξ along the hull from the front (left), η height above the ground line.
mod vehicle {
    /// Hull side (front glacis sloping up to the left).
    pub const HULL: [(f64, f64); 6] = [
        (0.0, 0.062),
        (0.06, 0.112),
        (0.45, 0.112),
        (0.45, 0.066),
        (0.43, 0.055),
        (0.02, 0.055),
    ];
    /// Turret side.
    pub const TURRET: [(f64, f64); 4] =
        [(0.12, 0.112), (0.15, 0.158), (0.29, 0.158), (0.31, 0.112)];
    /// Engine compartment starts at this ξ.
    pub const ENGINE_START: f64 = 0.31;
    /// Barrel: ξ range and η range.
    pub const BARREL: (f64, f64, f64, f64) = (-0.16, 0.13, 0.131, 0.141);
    /// Track: a capsule around the segment ξ ∈ [0.035, 0.415] at η = 0.03, radius 0.03.
    pub const TRACK: (f64, f64, f64, f64) = (0.035, 0.415, 0.03, 0.03);
    /// Road wheels: count, first and last centre ξ, centre η, radius.
    pub const WHEELS: (usize, f64, f64, f64, f64) = (6, 0.065, 0.385, 0.03, 0.021);
    /// Exhaust outlet ellipse: centre ξ, η and semi-axes.
    pub const EXHAUST: (f64, f64, f64, f64) = (0.43, 0.095, 0.014, 0.009);
    /// Shadow on the ground: centre ξ, η and semi-axes.
    pub const SHADOW: (f64, f64, f64, f64) = (0.25, -0.004, 0.25, 0.022);
    /// Bounding box of everything above (ξ_min, ξ_max, η_min, η_max).
    pub const BBOX: (f64, f64, f64, f64) = (-0.17, 0.46, -0.03, 0.17);
}

/// Everything the thermal scene's pixels are computed from; coordinates in image heights,
/// x from the left edge (0…aspect), v from the top (0…1).
struct ThermalLayout {
    aspect: f64,
    /// Scene scale: 1 image height for 4:3 and wider images, less for narrower ones.
    scale: f64,
    x_front: f64,
    v_ground: f64,
    /// Geometric horizon (behind the trees), used for sky elevations.
    v_horizon: f64,
    sun: bool,
    temps: Temperatures,
    vegetation: Fbm,
    moisture: Fbm,
    texture: Fbm,
    crowns: Fbm,
    forest_edge: Fbm,
}

impl ThermalLayout {
    fn new(p: &SceneParams, env: &Environment) -> Self {
        let aspect = p.cols as f64 / p.rows as f64;
        let scale = (aspect / (4.0 / 3.0)).min(1.0);
        // The finest texture octave spans two detector pixels: the same scene for any k.
        let min_cell = 2.0 / p.rows as f64;
        let seed = p.seed;
        ThermalLayout {
            aspect,
            scale,
            x_front: 0.5 * aspect - 0.5 * 0.45 * scale,
            v_ground: 0.72,
            v_horizon: 0.235,
            sun: p.sun,
            temps: Temperatures::new(env.air_temperature_k, p.sun),
            vegetation: Fbm::new(seed, 0, 0.35, min_cell, aspect, 1.0),
            moisture: Fbm::new(seed, 1, 0.5, min_cell, aspect, 1.0),
            texture: Fbm::new(seed, 2, 0.25, min_cell, aspect, 1.0),
            crowns: Fbm::new(seed, 3, 0.05, min_cell, aspect, 1.0),
            forest_edge: Fbm::new(seed, 4, 0.2, min_cell, aspect, 1.0),
        }
    }

    /// The vehicle part at (x, v), if any.
    fn vehicle_part(&self, x: f64, v: f64) -> Option<Region> {
        use vehicle::*;
        let xi = (x - self.x_front) / self.scale;
        let eta = (self.v_ground - v) / self.scale;
        if xi < BBOX.0 || xi > BBOX.1 || eta < BBOX.2 || eta > BBOX.3 {
            return None;
        }
        let in_ellipse = |(cx, cy, ax, ay): (f64, f64, f64, f64)| {
            let (dx, dy) = ((xi - cx) / ax, (eta - cy) / ay);
            dx * dx + dy * dy <= 1.0
        };
        if in_ellipse(EXHAUST) {
            return Some(Region::Exhaust);
        }
        let (count, first, last, wheel_eta, radius) = WHEELS;
        for i in 0..count {
            let cx = first + (last - first) * i as f64 / (count - 1) as f64;
            if (xi - cx).hypot(eta - wheel_eta) <= radius {
                return Some(Region::Wheel);
            }
        }
        let (t0, t1, t_eta, t_r) = TRACK;
        if (xi - xi.clamp(t0, t1)).hypot(eta - t_eta) <= t_r {
            return Some(Region::Track);
        }
        if in_polygon(xi, eta, &HULL) {
            return Some(if xi >= ENGINE_START {
                Region::EngineDeck
            } else {
                Region::Hull
            });
        }
        if in_polygon(xi, eta, &TURRET) {
            return Some(Region::Turret);
        }
        let (b0, b1, b_lo, b_hi) = BARREL;
        if (b0..=b1).contains(&xi) && (b_lo..=b_hi).contains(&eta) {
            return Some(Region::Barrel);
        }
        if self.sun && in_ellipse(SHADOW) {
            return Some(Region::Shadow);
        }
        None
    }

    /// Top of the tree line (sky above) and its lower edge (open terrain below) at x.
    fn treeline(&self, x: f64) -> (f64, f64) {
        let v_top = 0.205 - 0.035 * (0.5 + 0.35 * self.crowns.eval(x, 0.5)).clamp(0.0, 1.0);
        let v_forest = 0.265 + 0.01 * self.forest_edge.eval(x, 0.5);
        (v_top, v_forest)
    }

    /// Region, recipe and vegetation fraction of the scene point (x, v), given the
    /// [`treeline`](Self::treeline) at x.
    fn pixel(&self, x: f64, v: f64, (v_top, v_forest): (f64, f64)) -> (Region, Recipe, f32) {
        let t = &self.temps;
        if v < v_top {
            let r = Recipe {
                sky: true,
                t_k: t.air as f32,
                sun: 0.0,
                weights: [0.0; 5],
            };
            return (Region::Sky, r, 0.0);
        }
        let n_t = self.texture.eval(x, v);
        let paint = |t_k: f64| Recipe {
            sky: false,
            t_k: (t_k + 0.3 * n_t) as f32,
            sun: 1.0,
            weights: [0.0, 0.0, 1.0, 0.0, 0.0],
        };
        let track = |t_k: f64| Recipe {
            sky: false,
            t_k: (t_k + 0.3 * n_t) as f32,
            sun: 1.0,
            weights: [0.0, 0.0, 0.0, 1.0, 0.0],
        };
        let part = self.vehicle_part(x, v);
        match part {
            Some(Region::Exhaust) => {
                let r = Recipe {
                    sky: false,
                    t_k: t.exhaust as f32,
                    sun: 1.0,
                    weights: [0.0, 0.0, 0.0, 0.0, 1.0],
                };
                return (Region::Exhaust, r, 0.0);
            }
            Some(Region::Wheel) => return (Region::Wheel, track(t.hull + 6.0), 0.0),
            Some(Region::Track) => return (Region::Track, track(t.hull + 3.0), 0.0),
            Some(Region::Hull) => return (Region::Hull, paint(t.hull), 0.0),
            Some(Region::EngineDeck) => {
                let xi = (x - self.x_front) / self.scale;
                let warm = smoothstep(vehicle::ENGINE_START, vehicle::ENGINE_START + 0.09, xi);
                return (
                    Region::EngineDeck,
                    paint(t.hull + t.engine_extra * warm),
                    0.0,
                );
            }
            Some(Region::Turret) => return (Region::Turret, paint(t.hull - 0.5), 0.0),
            Some(Region::Barrel) => return (Region::Barrel, paint(t.hull - 1.0), 0.0),
            _ => {}
        }
        if v < v_forest {
            let r = Recipe {
                sky: false,
                t_k: (t.treeline + 0.6 * n_t) as f32,
                sun: 1.0,
                weights: [1.0, 0.0, 0.0, 0.0, 0.0],
            };
            return (Region::Treeline, r, 1.0);
        }
        let a = smoothstep(-0.35, 0.35, self.vegetation.eval(x, v) + 0.15);
        let m = smoothstep(-1.2, 1.2, self.moisture.eval(x, v));
        let soil_t = t.soil_dry + t.soil_moist_delta * m;
        let mut t_k = a * t.vegetation + (1.0 - a) * soil_t + 0.8 * n_t;
        let shadow = part == Some(Region::Shadow);
        if shadow {
            // Shaded ground stays close to the air temperature.
            t_k = t.air + 0.3 * (t_k - t.air);
        }
        let r = Recipe {
            sky: false,
            t_k: t_k as f32,
            sun: if shadow { 0.0 } else { 1.0 },
            // Wet soil is darker at all wavelengths (and so more emissive).
            weights: [
                a as f32,
                ((1.0 - a) * (1.0 - 0.35 * m)) as f32,
                0.0,
                0.0,
                0.0,
            ],
        };
        let region = if shadow {
            Region::Shadow
        } else {
            Region::Terrain
        };
        (region, r, a as f32)
    }
}

/// Per-band constants of the thermal scene.
struct ThermalBand {
    planck: PlanckBand,
    reflectance: [f64; 5],
    /// Downwelling sky radiance E_sky/π.
    sky_down: f64,
    /// Direct sun E_dir/π (0 at night).
    sun_down: f64,
    /// Sky radiance seen by each cube row.
    sky_view: Vec<f64>,
}

/// The [`thermal`] scene under the default [`Environment`].
pub fn thermal(p: &SceneParams) -> Result<Cube> {
    thermal_scene(p, &Environment::default()).map(|s| s.cube)
}

/// A vehicle-like target on textured terrain under a sky strip, with its ground-truth maps.
///
/// Layout (sizes relative to the image height, scaled down for images narrower than 4:3):
/// sky above an undulating tree line near 20 % of the height (sky elevation measured from
/// a geometric horizon at 23.5 %, so the sky strip is warm near the trees and colder
/// higher up in the LWIR window); open terrain below, a seeded fractal mixture of
/// vegetation and soil with correlated soil moisture (darker, more emissive and, at night,
/// warmer) and ±0.8 K correlated temperature texture; a vehicle seen from the side,
/// centred, 0.45 image heights long, standing on a ground line at 72 % of the height:
/// hull (paint), warmer engine compartment at the rear, turret, barrel pointing left,
/// track with six warm road wheels and a hot exhaust outlet (550 K, ε = 0.9). In daylight
/// the vehicle casts a shadow (no direct sun, ground near air temperature) on the ground.
///
/// Temperatures (relative to the air temperature T_air): at night vegetation −1.5 K, dry
/// soil −3 K (moist soil up to +2 K warmer), hull +3 K; by day vegetation +2.5 K, dry soil
/// +11 K (moist soil up to 6 K cooler), hull +11 K; engine compartment up to +10 K above
/// the hull, wheels +6 K, track +3 K. The hull is therefore a few kelvin warmer than the
/// mean terrain.
///
/// Texture fields are defined in image coordinates with their finest detail at two
/// detector pixels, so changing the oversampling refines the same scene. Shapes are
/// point-sampled at the cube's pixel centres (use oversampling for smooth outlines).
pub fn thermal_scene(p: &SceneParams, env: &Environment) -> Result<ThermalScene> {
    p.validate()?;
    env.validate()?;
    let (rows, cols) = (p.cube_rows(), p.cube_cols());
    let layout = ThermalLayout::new(p, env);

    let column_x: Vec<f64> = (0..cols)
        .map(|c| (c as f64 + 0.5) / cols as f64 * layout.aspect)
        .collect();
    let treeline: Vec<(f64, f64)> = column_x.iter().map(|&x| layout.treeline(x)).collect();
    let mut pixels: Vec<(Region, Recipe, f32)> = Vec::with_capacity(rows * cols);
    let per_row: Vec<Vec<(Region, Recipe, f32)>> = (0..rows)
        .into_par_iter()
        .map(|r| {
            let v = (r as f64 + 0.5) / rows as f64;
            column_x
                .iter()
                .zip(&treeline)
                .map(|(&x, &tl)| layout.pixel(x, v, tl))
                .collect()
        })
        .collect();
    for row in per_row {
        pixels.extend(row);
    }

    let fov_y_deg = p.fov_y_deg();
    let row_elevation_deg: Vec<f64> = (0..rows)
        .map(|r| (layout.v_horizon - (r as f64 + 0.5) / rows as f64).max(0.0) * fov_y_deg)
        .collect();
    let bands: Vec<ThermalBand> = p
        .wavelength_um
        .par_iter()
        .map(|&l| {
            let mut reflectance = [0.0; 5];
            for (rho, m) in reflectance.iter_mut().zip(Material::ALL) {
                *rho = m.reflectance(l);
            }
            let sky_view = row_elevation_deg
                .iter()
                .map(|&e| env.sky_radiance(l, e, p.sun))
                .collect();
            ThermalBand {
                planck: PlanckBand::new(l),
                reflectance,
                sky_down: env.downwelling_sky_radiance(l, p.sun),
                sun_down: if p.sun {
                    env.direct_solar_irradiance(l) / std::f64::consts::PI
                } else {
                    0.0
                },
                sky_view,
            }
        })
        .collect();

    let mut data = Array3::<f32>::zeros((p.wavelength_um.len(), rows, cols));
    data.axis_iter_mut(Axis(0))
        .into_par_iter()
        .zip(bands.par_iter())
        .for_each(|(mut plane, band)| {
            for (r, mut row) in plane.outer_iter_mut().enumerate() {
                let recipes = &pixels[r * cols..(r + 1) * cols];
                for (value, (_, recipe, _)) in row.iter_mut().zip(recipes) {
                    *value = if recipe.sky {
                        band.sky_view[r] as f32
                    } else {
                        let rho: f64 = recipe
                            .weights
                            .iter()
                            .zip(band.reflectance)
                            .map(|(&w, rho)| w as f64 * rho)
                            .sum::<f64>()
                            .clamp(0.0, 1.0);
                        let emitted = (1.0 - rho) * band.planck.radiance(recipe.t_k as f64);
                        let reflected = rho * (band.sky_down + recipe.sun as f64 * band.sun_down);
                        (emitted + reflected) as f32
                    };
                }
            }
        });

    let region = Array2::from_shape_vec((rows, cols), pixels.iter().map(|p| p.0).collect())
        .map_err(|e| Error::OutOfRange(format!("thermal scene region map: {e}")))?;
    let temperature_k =
        Array2::from_shape_vec((rows, cols), pixels.iter().map(|p| p.1.t_k).collect())
            .map_err(|e| Error::OutOfRange(format!("thermal scene temperature map: {e}")))?;
    let vegetation_fraction =
        Array2::from_shape_vec((rows, cols), pixels.iter().map(|p| p.2).collect())
            .map_err(|e| Error::OutOfRange(format!("thermal scene vegetation map: {e}")))?;
    Ok(ThermalScene {
        cube: Cube::new(data, p.meta())?,
        region,
        temperature_k,
        vegetation_fraction,
    })
}

// ---------------------------------------------------------------------------------------
// Test patterns
// ---------------------------------------------------------------------------------------

#[cfg(test)]
mod tests {
    use super::*;

    /// The thermal scene holds its per-pixel list twice at the peak (the per-row lists and
    /// the flattened list), then the region, temperature and vegetation maps: that must fit
    /// the per-pixel working set the memory budget assumes.
    #[test]
    fn scene_working_set_bound() {
        let list = std::mem::size_of::<(Region, Recipe, f32)>();
        let maps = std::mem::size_of::<Region>() + 2 * std::mem::size_of::<f32>();
        assert!(
            (2 * list + maps) as u64 <= crate::scene::synthetic::SCENE_BYTES_PER_PIXEL,
            "2 × {list} + {maps} B"
        );
    }
}
