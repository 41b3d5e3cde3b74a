//! Ray casting of height fields `z = f(x, y)` in the gravity frame: exact depth for synthetic
//! scenes and tests (steps and curbs included, since bisection lands on vertical faces).

use rayon::prelude::*;

use super::{Grid, Intrinsics, Mounting, Vec3};

/// A terrain height field in the gravity frame (metres, z up).
pub trait HeightField: Sync {
    /// Terrain height at ground position `(x, y)`.
    fn height(&self, x: f64, y: f64) -> f64;
}

impl<F: Fn(f64, f64) -> f64 + Sync> HeightField for F {
    fn height(&self, x: f64, y: f64) -> f64 {
        self(x, y)
    }
}

/// How rays march: step = clamp(gap · `step_fraction`, `min_step_m`, `max_step_m`), where gap is
/// the ray's height above the terrain; bisection refines every crossing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarchConfig {
    /// Fraction of the current height gap taken as the next step.
    pub step_fraction: f64,
    /// Smallest step, metres (features thinner than this may be missed).
    pub min_step_m: f64,
    /// Largest step, metres.
    pub max_step_m: f64,
    /// Range beyond which a ray reports no hit, metres.
    pub max_range_m: f64,
}

impl Default for MarchConfig {
    fn default() -> Self {
        Self {
            step_fraction: 0.5,
            min_step_m: 5e-4,
            max_step_m: 0.02,
            max_range_m: 20.0,
        }
    }
}

/// The distance along the unit ray `origin + t·dir` (gravity frame) to the terrain, if any.
pub fn cast_ray(
    field: &dyn HeightField,
    origin: &Vec3,
    dir: &Vec3,
    cfg: &MarchConfig,
) -> Option<f64> {
    let gap = |t: f64| {
        let p = origin + dir * t;
        p.z - field.height(p.x, p.y)
    };
    let (mut t0, mut g0) = (0.0, gap(0.0));
    if g0 <= 0.0 {
        return None;
    }
    while t0 < cfg.max_range_m {
        let t1 = t0 + (g0 * cfg.step_fraction).clamp(cfg.min_step_m, cfg.max_step_m);
        let g1 = gap(t1);
        if g1 <= 0.0 {
            return Some(bisect(&gap, t0, t1));
        }
        (t0, g0) = (t1, g1);
    }
    None
}

/// Bisection of a sign change of `gap` (positive at `lo`, non-positive at `hi`).
fn bisect(gap: &dyn Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if gap(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-12 {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// Renders the depth (camera z, metres; 0 where no terrain is hit) of a `width × height` frame.
pub fn render_depth(
    field: &dyn HeightField,
    intrinsics: &Intrinsics,
    mounting: &Mounting,
    (width, height): (usize, usize),
    cfg: &MarchConfig,
) -> Grid<f64> {
    let rot = mounting.gravity_from_cam();
    let origin = Vec3::new(0.0, 0.0, mounting.height_m);
    let mut depth = Grid::new(width, height, 0.0);
    depth
        .as_mut_slice()
        .par_chunks_mut(width.max(1))
        .enumerate()
        .for_each(|(v, row)| {
            for (u, d) in row.iter_mut().enumerate() {
                let ray_cam = intrinsics.back_project(u as f64, v as f64, 1.0);
                let dir = rot * ray_cam.normalize();
                if let Some(t) = cast_ray(field, &origin, &dir, cfg) {
                    *d = t / ray_cam.norm();
                }
            }
        });
    depth
}
