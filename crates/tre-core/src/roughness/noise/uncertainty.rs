//! The uncertainty map: the roughness that a sensor's noise alone gives annotation spec v1 on a
//! flat surface, per pixel (docs/sensor-noise.md).

use rayon::prelude::*;

use super::SensorNoise;
use crate::geometry::neighbours::neighbour_counts_into;
use crate::geometry::normals::PackedPoints;
use crate::geometry::{is_valid_point, PointMap};
use crate::geometry::{Grid, Intrinsics, Vec3};
use crate::roughness::annotate::{edge_term, AnnotateConfig};

/// The 95th percentile of a half-normal distribution, in units of its σ.
pub const HALF_NORMAL_P95: f64 = 1.959_964;

/// Fraction of neighbour joins that noise alone must fail (spec step 2, the ε test) for the
/// segments to break up and the edge term to fire on flat ground (see docs/sensor-noise.md).
pub const SEGMENT_BREAK_FRACTION: f64 = 0.05;

/// The 95th percentile of the largest of 8 half-normal values, in units of their σ: solves
/// `(2Φ(t) − 1)^8 = 0.95` (the edge weight W is the largest of 8 neighbour distances).
pub const MAX_OF_8_HALF_NORMAL_P95: f64 = 2.728;

/// Per-pixel noise statistics behind the uncertainty map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelNoise {
    /// σ of the point's offset along the surface normal, metres.
    pub sigma_normal_m: f64,
    /// Points in the surface term's neighbourhood (the pixel's own included).
    pub neighbours: usize,
    /// Predicted p95 of the surface term, metres.
    pub surface_p95_m: f64,
    /// Fraction of 4-neighbour joins failing the ε test on noise alone.
    pub break_fraction: f64,
    /// Predicted edge term where segments break up (0 where they hold), metres.
    pub edge_m: f64,
}

impl PixelNoise {
    /// The uncertainty: the larger of the surface and edge predictions, metres.
    pub fn uncertainty_m(&self) -> f64 {
        self.surface_p95_m.max(self.edge_m)
    }
}

/// The uncertainty map: at each valid pixel, the p95 of the roughness that sensor noise alone
/// gives spec v1 on a flat surface with the pixel's normal (NaN where there is no depth).
/// `normals` (unit, camera frame; NaN: unknown, read as facing the camera) are the surface's,
/// e.g. the LS normals of the annotation or the pipeline's.
///
/// ```
/// use tre_core::geometry::{Grid, Intrinsics, Vec3};
/// use tre_core::roughness::noise::{uncertainty_map, SensorNoise, SensorPreset};
/// let k = Intrinsics::new(525.0, 525.0, 16.0, 12.0).unwrap();
/// let normals = Grid::new(32, 24, Vec3::new(0.0, 0.0, -1.0));
/// let kinect = SensorNoise::Preset(SensorPreset::KinectV1);
/// let at = |z: f64| {
///     let u = uncertainty_map(&Grid::new(32, 24, z), &k, &normals, &kinect, &Default::default());
///     u[(16, 12)]
/// };
/// // 1 m: σ_z = 1.88 mm, 225 points in the window: 1.96 · 1.88 · √(224/225) ≈ 3.7 mm.
/// assert!((at(1.0) - 0.003_676).abs() < 2e-5, "{}", at(1.0));
/// // 2 m: σ_z = 6.06 mm breaks 8% of the segment joins; the edge term takes over.
/// assert!(at(2.0) > 0.02, "{}", at(2.0));
/// ```
pub fn uncertainty_map(
    depth_m: &Grid<f64>,
    intrinsics: &Intrinsics,
    normals: &Grid<Vec3>,
    sensor: &SensorNoise,
    cfg: &AnnotateConfig,
) -> Grid<f64> {
    with_counts(depth_m, intrinsics, normals, cfg, |frame| {
        let mut out = Grid::new(frame.points.width(), frame.points.height(), f64::NAN);
        out.par_rows_mut().for_each(|(y, row)| {
            for (x, u) in row.iter_mut().enumerate() {
                if let Some(n) = frame.noise_at((x, y), sensor, cfg) {
                    *u = n.uncertainty_m();
                }
            }
        });
        out
    })
}

/// [`PixelNoise`] at every pixel (`None` where there is no depth).
pub fn pixel_noise_map(
    depth_m: &Grid<f64>,
    intrinsics: &Intrinsics,
    normals: &Grid<Vec3>,
    sensor: &SensorNoise,
    cfg: &AnnotateConfig,
) -> Grid<Option<PixelNoise>> {
    with_counts(depth_m, intrinsics, normals, cfg, |frame| {
        let (w, h) = frame.points.size();
        Grid::par_from_fn(w, h, |x, y| frame.noise_at((x, y), sensor, cfg))
    })
}

/// The buffers of [`with_counts`], kept per thread from frame to frame: a 640×480 frame's
/// points, packed points and counts are about 12 MB, which the allocator would otherwise map
/// and fault in afresh for every frame.
#[derive(Default)]
struct CountScratch {
    points: PointMap,
    packed: PackedPoints,
    counts: Grid<u32>,
}

thread_local! {
    static COUNT_SCRATCH: std::cell::RefCell<CountScratch> = Default::default();
}

/// Runs `f` on the frame of `depth_m`: its points and their neighbour counts (spec
/// neighbourhood of `cfg`) in this thread's buffers (fresh ones where they are in use, as when
/// a rayon task started inside `f` on this thread computes another frame's maps), `normals`
/// and `k`.
fn with_counts<T>(
    depth_m: &Grid<f64>,
    k: &Intrinsics,
    normals: &Grid<Vec3>,
    cfg: &AnnotateConfig,
    f: impl FnOnce(&NoiseFrame<'_>) -> T,
) -> T {
    let run = |s: &mut CountScratch| {
        k.back_project_map_into(depth_m, &mut s.points);
        neighbour_counts_into(&s.points, k.fx_px, &cfg.hood, &mut s.packed, &mut s.counts);
        f(&NoiseFrame {
            points: &s.points,
            counts: &s.counts,
            normals,
            k,
        })
    };
    COUNT_SCRATCH.with(|cell| match cell.try_borrow_mut() {
        Ok(mut s) => run(&mut s),
        Err(_) => run(&mut CountScratch::default()),
    })
}

/// A frame's points, their neighbour counts and normals, and its intrinsics.
struct NoiseFrame<'a> {
    points: &'a PointMap,
    counts: &'a Grid<u32>,
    normals: &'a Grid<Vec3>,
    k: &'a Intrinsics,
}

impl NoiseFrame<'_> {
    /// The noise statistics at pixel `(x, y)` (`None` where there is no depth); a missing or
    /// zero normal reads as facing the camera.
    fn noise_at(
        &self,
        (x, y): (usize, usize),
        sensor: &SensorNoise,
        cfg: &AnnotateConfig,
    ) -> Option<PixelNoise> {
        let p = self.points[(x, y)];
        if !is_valid_point(&p) {
            return None;
        }
        let n = self
            .normals
            .get(x, y)
            .copied()
            .filter(|n| n.norm().is_finite() && n.norm() > 0.0);
        let n = n.map_or(-p / p.norm(), |n| n / n.norm());
        let pixel = Pixel {
            xy: (x, y),
            neighbours: self.counts[(x, y)] as usize,
        };
        Some(pixel_noise(self.points, self.k, &pixel, &n, sensor, cfg))
    }
}

/// A valid pixel and its neighbour count ([`crate::geometry::neighbours::count_within`] in its
/// window).
struct Pixel {
    xy: (usize, usize),
    neighbours: usize,
}

/// The noise statistics of `pixel` (valid) with unit normal `n`.
fn pixel_noise(
    points: &PointMap,
    k: &Intrinsics,
    pixel: &Pixel,
    n: &Vec3,
    sensor: &SensorNoise,
    cfg: &AnnotateConfig,
) -> PixelNoise {
    let (x, y) = pixel.xy;
    let p = points[(x, y)];
    let sigma_z = sensor.sigma_z_m(p.z).max(0.0);
    // Depth noise δz moves the point along its ray by δz·p/z: along the normal by δz·(n·p)/z.
    let sigma_normal_m = sigma_z * n.dot(&p).abs() / p.z;
    let half = cfg.hood.half_width(k.fx_px, p.z);
    let neighbours = pixel.neighbours;
    let residual = (1.0 - 1.0 / neighbours.max(1) as f64).sqrt();
    let surface_p95_m = HALF_NORMAL_P95 * sigma_normal_m * residual;
    let sigma_ray_m = sigma_z * p.norm() / p.z;
    let extent_m = (half as f64 * p.z / k.fx_px).min(cfg.hood.radius_m);
    let (break_fraction, noisy_normals) =
        joins_broken(sigma_ray_m, sigma_normal_m, extent_m, cfg.epsilon_m);
    let edge_m = if break_fraction >= SEGMENT_BREAK_FRACTION {
        // A neighbour's distance moves by the difference of two ray offsets, σ√2 each.
        // A noise-led normal says nothing of the surface: the spacing facing the camera then.
        let facing = -p / p.norm();
        let spacing = neighbour_spacing(k, (x, y), &p, if noisy_normals { &facing } else { n });
        let spread = MAX_OF_8_HALF_NORMAL_P95 * std::f64::consts::SQRT_2 * sigma_ray_m;
        edge_term(spacing.hypot(spread), cfg.epsilon_m)
    } else {
        0.0
    };
    PixelNoise {
        sigma_normal_m,
        neighbours,
        surface_p95_m,
        break_fraction,
        edge_m,
    }
}

/// The fraction of segment joins (spec step 2) that noise breaks on a plane, and whether the LS
/// normals follow the noise. Two neighbours' offsets along the normal differ by N(0, 2σ_n²), so
/// the ε test fails with erfc(ε/2σ_n). Where 3σ along the ray exceeds the window's extent
/// (`extent_m`), LS normals follow the noise and the 10° test breaks every join; the estimated
/// normal cannot tell, being the noisy one.
fn joins_broken(
    sigma_ray_m: f64,
    sigma_normal_m: f64,
    extent_m: f64,
    epsilon_m: f64,
) -> (f64, bool) {
    if 3.0 * sigma_ray_m > extent_m {
        (1.0, true)
    } else if sigma_normal_m > 0.0 {
        (erfc(epsilon_m / (2.0 * sigma_normal_m)), false)
    } else {
        (0.0, false)
    }
}

/// The largest distance from `p` (pixel `(x, y)`) to its 8 neighbours' rays where they meet
/// the plane through `p` with normal `n` (rays that miss it are left out).
fn neighbour_spacing(k: &Intrinsics, (x, y): (usize, usize), p: &Vec3, n: &Vec3) -> f64 {
    let d = n.dot(p);
    let mut far: f64 = 0.0;
    for (dx, dy) in crate::geometry::NEIGHBOURS_8 {
        let ray = Vec3::new(
            (x as f64 + f64::from(dx) - k.cx_px) / k.fx_px,
            (y as f64 + f64::from(dy) - k.cy_px) / k.fy_px,
            1.0,
        );
        let t = d / n.dot(&ray);
        if t.is_finite() && t > 0.0 {
            far = far.max((ray * t - p).norm());
        }
    }
    far
}

/// The complementary error function (Abramowitz and Stegun 7.1.26, error below 1.5e-7).
///
/// ```
/// use tre_core::roughness::noise::erfc;
/// assert!((erfc(0.0) - 1.0).abs() < 1e-6);
/// assert!((erfc(1.0) - 0.157_299_2).abs() < 1e-6);
/// assert!((erfc(-1.0) - 1.842_700_8).abs() < 1e-6);
/// ```
pub fn erfc(x: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
    let poly = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let tail = poly * (-x * x).exp();
    if x >= 0.0 {
        tail
    } else {
        2.0 - tail
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::roughness::noise::SensorPreset;

    #[test]
    fn grazing_views_see_less_noise_along_the_normal_and_exact_sees_none() {
        let k = Intrinsics::new(500.0, 500.0, 10.0, 10.0).unwrap();
        let depth = Grid::new(21, 21, 3.0);
        let facing = Grid::new(21, 21, Vec3::new(0.0, 0.0, -1.0));
        let tilted = Grid::new(21, 21, Vec3::new(0.0, -0.8, -0.6));
        let cfg = AnnotateConfig::default();
        let s = SensorNoise::Preset(SensorPreset::KinectV1);
        let a = pixel_noise_map(&depth, &k, &facing, &s, &cfg)[(10, 10)].unwrap();
        let b = pixel_noise_map(&depth, &k, &tilted, &s, &cfg)[(10, 10)].unwrap();
        assert!((b.sigma_normal_m / a.sigma_normal_m - 0.6).abs() < 1e-9);
        let exact = SensorNoise::Preset(SensorPreset::Exact);
        let u = uncertainty_map(&depth, &k, &facing, &exact, &cfg);
        assert!(u.as_slice().iter().all(|&v| v == 0.0));
    }
}
