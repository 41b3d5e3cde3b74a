//! Gravity from depth: the up direction and the camera's height estimated from the points
//! themselves, for frames that state no mounting.
//!
//! A RANSAC fit of the ground: plane hypotheses from one point and its local normal (three
//! points for sparse depth such as projected LiDAR), each kept only if it could
//! be ground under a camera the way robots carry one (the camera above it, pitch at most 80°
//! down and 30° up, roll within 35°), scored by the points within a depth-dependent tolerance.
//! Among the hypotheses with at least half the best support, the lowest wins (the floor
//! under a table top, the road under a car's roof), then two least-squares refits on its
//! inliers. The fit is *confident* when at least [`FloorFitConfig::min_support`] of the
//! valid points lie on the plane and at most [`FloorFitConfig::max_below`] lie clearly below
//! it (nothing should: the ground is the lowest surface the camera sees).

use nalgebra::{Matrix3, SymmetricEigen};

use super::{is_valid_point, PointMap, Vec3};

/// Settings of [`fit_floor`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FloorFitConfig {
    /// Plane hypotheses drawn.
    pub hypotheses: usize,
    /// Largest number of points scored (an even subsample of the valid ones).
    pub max_points: usize,
    /// Inlier tolerance at the camera, metres.
    pub tolerance_m: f64,
    /// Inlier tolerance added per metre of depth.
    pub tolerance_per_m: f64,
    /// Largest angle between a point's local normal and the plane's for the point to be on
    /// the plane, degrees.
    pub max_normal_angle_deg: f64,
    /// Smallest fraction of the valid points on the plane for a confident fit.
    pub min_support: f64,
    /// Largest fraction of the valid points more than three tolerances below the plane.
    pub max_below: f64,
    /// Seed of the hypothesis sampler (the fit is deterministic).
    pub seed: u64,
}

impl Default for FloorFitConfig {
    fn default() -> Self {
        Self {
            hypotheses: 128,
            max_points: 4000,
            tolerance_m: 0.02,
            tolerance_per_m: 0.01,
            max_normal_angle_deg: 15.0,
            min_support: 0.05,
            max_below: 0.01,
            seed: 0x07ef_1004,
        }
    }
}

/// The ground plane found in a frame's points, with gravity's up axis in the camera frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FloorFit {
    /// Gravity's up axis in the camera frame (x right, y down, z forward), a unit vector.
    pub up_in_cam: Vec3,
    /// The camera's height above the plane, metres.
    pub height_m: f64,
    /// Pitch of the optical axis below the horizon, radians (negative: looking up).
    pub pitch_rad: f64,
    /// Roll about the optical axis, radians (positive: the image's right side lower).
    pub roll_rad: f64,
    /// Fraction of the sampled points on the plane: the fit's confidence measure.
    pub support: f64,
    /// Fraction of the sampled points more than three tolerances below the plane.
    pub below: f64,
    /// Valid points scored.
    pub points: usize,
    /// Whether the fit meets [`FloorFitConfig::min_support`] and
    /// [`FloorFitConfig::max_below`].
    pub confident: bool,
}

impl FloorFit {
    /// Pitch and roll of a camera whose up axis in the camera frame is `up` (unit):
    /// `up = (cos p · sin r, −cos p · cos r, −sin p)`.
    ///
    /// ```
    /// use tre_core::geometry::{floor::FloorFit, Mounting};
    /// let m = Mounting::new(25f64.to_radians(), 1.0).unwrap();
    /// let (pitch, roll) = FloorFit::pitch_roll(&m.up_in_cam());
    /// assert!((pitch.to_degrees() - 25.0).abs() < 1e-9 && roll.abs() < 1e-12);
    /// ```
    pub fn pitch_roll(up: &Vec3) -> (f64, f64) {
        ((-up.z).clamp(-1.0, 1.0).asin(), up.x.atan2(-up.y))
    }
}

/// Why no ground plane came out of a frame.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum NoFloor {
    /// Too few valid points to fit a plane.
    #[error("{valid} valid points, too few to find the ground")]
    TooFewPoints {
        /// Valid points in the frame.
        valid: usize,
    },
    /// No hypothesis could be ground under a camera carried as robots carry one.
    #[error("no plane in view could be the ground (none below the camera within 80° of pitch and 35° of roll)")]
    NoGroundPlane,
}

/// Points fewer than this give no fit.
const MIN_POINTS: usize = 50;
/// Steepest pitch a ground plane may imply, down and up, and the largest roll, degrees.
const MAX_PITCH_DOWN_DEG: f64 = 80.0;
const MAX_PITCH_UP_DEG: f64 = 30.0;
const MAX_ROLL_DEG: f64 = 35.0;
/// Weight of a point below a hypothesis against one on it: the ground has nothing below it,
/// so a table top (the floor's points under it) or a slanted plane through the scene loses.
const BELOW_WEIGHT: f64 = 3.0;
/// Lowest and highest camera above a ground plane, metres.
const HEIGHT_RANGE_M: (f64, f64) = (0.05, 10.0);

/// A plane `n·p = -d` with unit `n` pointing to the camera's side (`d` > 0 is the height).
#[derive(Debug, Clone, Copy)]
struct Hyp {
    n: Vec3,
    d: f64,
}

impl Hyp {
    /// The plane through three points, oriented up.
    fn through(a: &Vec3, b: &Vec3, c: &Vec3) -> Option<Self> {
        let n = (b - a).cross(&(c - a));
        let len = n.norm();
        if !(len > 1e-9) {
            return None;
        }
        Self::oriented(n / len, a)
    }

    /// The plane with normal `n` through `p`, oriented so the camera is above it.
    fn oriented(n: Vec3, p: &Vec3) -> Option<Self> {
        let d = -n.dot(p);
        let (n, d) = if d < 0.0 { (-n, -d) } else { (n, d) };
        d.is_finite().then_some(Self { n, d })
    }

    /// The camera above it within the height range, the implied pitch and roll within bounds.
    fn plausible(&self) -> bool {
        let (pitch, roll) = FloorFit::pitch_roll(&self.n);
        let (lo, hi) = HEIGHT_RANGE_M;
        (lo..=hi).contains(&self.d)
            && pitch.to_degrees() <= MAX_PITCH_DOWN_DEG
            && pitch.to_degrees() >= -MAX_PITCH_UP_DEG
            && roll.to_degrees().abs() <= MAX_ROLL_DEG
    }

    /// Signed height of `p` above the plane.
    fn height_of(&self, p: &Vec3) -> f64 {
        self.n.dot(p) + self.d
    }
}

/// A small deterministic generator (xorshift64*) for the hypothesis sampler.
struct Rng(u64);

impl Rng {
    fn below(&mut self, n: usize) -> usize {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 33) as usize % n.max(1)
    }
}

/// The ground plane of `points` (a frame's back-projected depth) and gravity's up axis.
///
/// ```
/// use tre_core::geometry::{floor::{fit_floor, FloorFitConfig}, Grid, Intrinsics, Mounting};
/// // A flat floor seen by a camera 1.2 m up, pitched 20° down.
/// let m = Mounting::new(20f64.to_radians(), 1.2).unwrap();
/// let k = Intrinsics::from_hfov(160, 120, 60.0).unwrap();
/// let up = m.up_in_cam();
/// let points = Grid::from_fn(160, 120, |x, y| {
///     let ray = k.back_project(x as f64, y as f64, 1.0);
///     let down = -up.dot(&ray);
///     if down > 0.0 { ray * (1.2 / down) } else { tre_core::geometry::INVALID_POINT }
/// });
/// let fit = fit_floor(&points, &FloorFitConfig::default()).unwrap();
/// assert!(fit.confident);
/// assert!((fit.pitch_rad.to_degrees() - 20.0).abs() < 0.01);
/// assert!((fit.height_m - 1.2).abs() < 1e-3);
/// ```
///
/// # Errors
///
/// [`NoFloor`] when there are too few points or no plausible ground plane.
pub fn fit_floor(points: &PointMap, cfg: &FloorFitConfig) -> Result<FloorFit, NoFloor> {
    let valid = points
        .as_slice()
        .iter()
        .filter(|p| is_valid_point(p))
        .count();
    if valid < MIN_POINTS {
        return Err(NoFloor::TooFewPoints { valid });
    }
    let sampled = Sampled::new(points, valid, cfg);
    let mut h = sampled.ransac(cfg).ok_or(NoFloor::NoGroundPlane)?;
    for _ in 0..2 {
        let inliers: Vec<&Vec3> = (0..sampled.pts.len())
            .filter(|&i| sampled.on(&h, i))
            .map(|i| &sampled.pts[i])
            .collect();
        match refit(&inliers) {
            Some(r) if r.plausible() && sampled.score(&r) >= sampled.score(&h) => h = r,
            _ => break,
        }
    }
    let (on, below) = sampled.count(&h);
    let n = sampled.pts.len() as f64;
    let (support, below) = (on as f64 / n, below as f64 / n);
    let (pitch_rad, roll_rad) = FloorFit::pitch_roll(&h.n);
    Ok(FloorFit {
        up_in_cam: h.n,
        height_m: h.d,
        pitch_rad,
        roll_rad,
        support,
        below,
        points: sampled.pts.len(),
        confident: support >= cfg.min_support && below <= cfg.max_below,
    })
}

/// The points a fit scores: a subsample with local normals (dense depth) or without (sparse),
/// and each point's inlier tolerance.
struct Sampled {
    pts: Vec<Vec3>,
    normals: Vec<Vec3>,
    tol: Vec<f64>,
    /// Whether the points have normals.
    dense: bool,
    /// Smallest `|n·normal|` of a point on the plane (0 without normals).
    min_cos: f64,
}

impl Sampled {
    /// The subsample of `points` (`valid` of them valid). Sparse depth (projected LiDAR) has
    /// no local normals: then every point within the tolerance is on a plane.
    fn new(points: &PointMap, valid: usize, cfg: &FloorFitConfig) -> Self {
        let max_points = cfg.max_points.max(MIN_POINTS);
        let (mut pts, mut normals) = sample(points, valid, max_points);
        let dense = pts.len() >= MIN_POINTS;
        if !dense {
            pts = points
                .as_slice()
                .iter()
                .filter(|p| is_valid_point(p))
                .step_by(valid.div_ceil(max_points))
                .copied()
                .collect();
            normals = vec![Vec3::zeros(); pts.len()];
        }
        let tol = pts
            .iter()
            .map(|p| cfg.tolerance_m + cfg.tolerance_per_m * p.z)
            .collect();
        let min_cos = if dense {
            cfg.max_normal_angle_deg.to_radians().cos()
        } else {
            0.0
        };
        Self {
            pts,
            normals,
            tol,
            dense,
            min_cos,
        }
    }

    /// Point `i` is on `h`: within its tolerance and with a local normal along the plane's, so
    /// that a slanted plane cutting across walls and cabinet fronts gains nothing from them.
    fn on(&self, h: &Hyp, i: usize) -> bool {
        h.height_of(&self.pts[i]).abs() <= self.tol[i]
            && h.n.dot(&self.normals[i]).abs() >= self.min_cos
    }

    /// Points on `h` and points clearly below it (which the ground should not have).
    fn count(&self, h: &Hyp) -> (usize, usize) {
        (0..self.pts.len()).fold((0, 0), |(on, below), i| {
            let z = h.height_of(&self.pts[i]);
            (
                on + usize::from(self.on(h, i)),
                below + usize::from(z < -3.0 * self.tol[i]),
            )
        })
    }

    /// Points on `h` less [`BELOW_WEIGHT`] times those below it.
    fn score(&self, h: &Hyp) -> f64 {
        let (on, below) = self.count(h);
        on as f64 - BELOW_WEIGHT * below as f64
    }

    /// The best plausible hypothesis, if one scores at least 3.
    fn ransac(&self, cfg: &FloorFitConfig) -> Option<Hyp> {
        let n = self.pts.len();
        let mut rng = Rng(cfg.seed | 1);
        let mut best: Option<(Hyp, f64)> = None;
        for _ in 0..cfg.hypotheses {
            // A hypothesis from one point and its local normal, as DSAC draws them, or from
            // three points where there are no normals.
            let i = rng.below(n);
            let h = if self.dense {
                Hyp::oriented(self.normals[i], &self.pts[i])
            } else {
                let (j, k) = (rng.below(n), rng.below(n));
                Hyp::through(&self.pts[i], &self.pts[j], &self.pts[k])
            };
            let Some(h) = h.filter(Hyp::plausible) else {
                continue;
            };
            let s = self.score(&h);
            if best.is_none_or(|(_, b)| s > b) {
                best = Some((h, s));
            }
        }
        best.filter(|&(_, s)| s >= 3.0).map(|(h, _)| h)
    }
}

/// An even subsample of about `max_points` of the `valid` points of `points`, each with its
/// local normal (the cross product of its row and column neighbours a few pixels away);
/// points without valid neighbours are left out.
fn sample(points: &PointMap, valid: usize, max_points: usize) -> (Vec<Vec3>, Vec<Vec3>) {
    let (w, h) = points.size();
    let stride = ((valid as f64 / max_points as f64).sqrt().ceil() as usize).max(1);
    // The neighbours' distance: a hundredth of the width, at least two pixels.
    let step = (w / 100).max(2);
    let (mut pts, mut normals) = (Vec::new(), Vec::new());
    for y in (step..h.saturating_sub(step)).step_by(stride) {
        for x in (step..w.saturating_sub(step)).step_by(stride) {
            let p = points[(x, y)];
            let (l, r) = (points[(x - step, y)], points[(x + step, y)]);
            let (u, d) = (points[(x, y - step)], points[(x, y + step)]);
            if ![p, l, r, u, d].iter().all(is_valid_point) {
                continue;
            }
            let n = (r - l).cross(&(d - u));
            let len = n.norm();
            if len > 0.0 && len.is_finite() {
                pts.push(p);
                normals.push(n / len);
            }
        }
    }
    (pts, normals)
}

/// The least-squares plane of `inliers` (smallest principal axis), oriented up.
fn refit(inliers: &[&Vec3]) -> Option<Hyp> {
    if inliers.len() < 3 {
        return None;
    }
    let n = inliers.len() as f64;
    let mean = inliers.iter().fold(Vec3::zeros(), |s, p| s + **p) / n;
    let cov = inliers.iter().fold(Matrix3::zeros(), |s, p| {
        let d = **p - mean;
        s + d * d.transpose()
    }) / n;
    let eig = SymmetricEigen::new(cov);
    let i = eig.eigenvalues.imin();
    let normal: Vec3 = eig.eigenvectors.column(i).into_owned();
    Hyp::oriented(normal.normalize(), &mean)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Grid, Intrinsics, Mounting, INVALID_POINT};

    /// Points of a floor `height_m` below a camera with up axis `up`, plus a box on it.
    fn scene(up: Vec3, height_m: f64, box_top_m: Option<f64>) -> PointMap {
        let k = Intrinsics::from_hfov(160, 120, 60.0).unwrap();
        Grid::from_fn(160, 120, |x, y| {
            let ray = k.back_project(x as f64, y as f64, 1.0);
            let down = -up.dot(&ray);
            if down <= 0.0 {
                return INVALID_POINT;
            }
            let floor = ray * (height_m / down);
            match box_top_m {
                // A table top covering the middle third of the image, `top` above the floor.
                Some(top) if (55..105).contains(&x) && y > 40 => ray * ((height_m - top) / down),
                _ => floor,
            }
        })
    }

    #[test]
    fn finds_pitch_roll_and_height_of_a_rolled_camera() {
        let m = Mounting::new(35f64.to_radians(), 0.8).unwrap();
        let roll = 10f64.to_radians();
        let u = m.up_in_cam();
        // Roll the up axis about the optical axis: up = R_z(roll) · up₀.
        let up = Vec3::new(
            u.x * roll.cos() - u.y * roll.sin(),
            u.x * roll.sin() + u.y * roll.cos(),
            u.z,
        );
        let fit = fit_floor(&scene(up, 0.8, None), &FloorFitConfig::default()).unwrap();
        assert!(fit.confident, "{fit:?}");
        assert!((fit.pitch_rad.to_degrees() - 35.0).abs() < 0.05, "{fit:?}");
        assert!((fit.roll_rad.to_degrees() - 10.0).abs() < 0.05, "{fit:?}");
        assert!((fit.height_m - 0.8).abs() < 1e-3, "{fit:?}");
    }

    #[test]
    fn prefers_the_floor_to_a_table_top_above_it() {
        let up = Mounting::new(30f64.to_radians(), 1.0).unwrap().up_in_cam();
        let fit = fit_floor(&scene(up, 1.0, Some(0.4)), &FloorFitConfig::default()).unwrap();
        assert!((fit.height_m - 1.0).abs() < 0.01, "{fit:?}");
        assert!(fit.confident, "{fit:?}");
    }

    #[test]
    fn a_wall_alone_is_no_ground() {
        // A wall 2 m in front of a level camera: no plane under the camera.
        let k = Intrinsics::from_hfov(160, 120, 60.0).unwrap();
        let wall = Grid::from_fn(160, 120, |x, y| k.back_project(x as f64, y as f64, 2.0));
        assert_eq!(
            fit_floor(&wall, &FloorFitConfig::default()),
            Err(NoFloor::NoGroundPlane)
        );
    }

    #[test]
    fn too_few_points_is_an_error() {
        let empty = Grid::new(10, 10, INVALID_POINT);
        assert_eq!(
            fit_floor(&empty, &FloorFitConfig::default()),
            Err(NoFloor::TooFewPoints { valid: 0 })
        );
    }
}
