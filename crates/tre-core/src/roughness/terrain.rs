//! The terrain estimate behind the `geometric` mode: the roughness of the ground, not of the
//! sensor's holes, scan-line gaps, registration layers, disparity steps and range noise
//! (docs/terrain.md). Annotation spec v1 (`tre annotate`) stays the definition on the depth as
//! given; this reads the same quantities through the sensor's noise model:
//!
//! 1. **Support in metres, with evidence.** Each pixel's plane is fitted over the smallest
//!    square window whose half-width reaches `max(R, k·σ_z)` at the pixel's range and that
//!    holds at least `min_points` valid points spread in two directions (the plane's second
//!    eigenvalue `conditioning` times the noise variance along its normal, twice its smallest,
//!    and over half the radius); windows grow along a ladder up to
//!    [`MAX_HALF_PX`] pixels, so sparse LiDAR finds its neighbours across scan-line gaps.
//!    No such window: where the largest window's points scatter off their plane by more than
//!    the noise explains, the ground there is rough (an obstacle, a rock field) and reads that
//!    scatter; where noise explains it, no estimate.
//! 2. **Surface term, debiased.** The distance along the plane's normal from the mean point of
//!    an inner window (a third of the support) to the plane's centroid, less the spread noise
//!    alone gives it (`debias` times its σ, subtracted in quadrature).
//! 3. **Step term with evidence on both sides.** For the seams right of and below the pixel:
//!    two half windows, one on each side, each with enough points; their offset along the
//!    pooled normal (each side's scatter about its own centroid, so a step does not tilt it) is
//!    the step, less what noise (white and registration) gives. A hole or a scan-line gap
//!    between two sides on one plane has no offset, and one side without points is no
//!    evidence. The step spreads over a band of `band_px` pixels, as the spec's edge transient.
//! 4. **Uncertainty**: the margin subtracted in 2 and 3 (the smallest step the estimate can
//!    resolve), for the three-state map.

use rayon::prelude::*;

use super::noise::{SensorNoise, HALF_NORMAL_P95};
use crate::geometry::sums::SummedMoments;
use crate::geometry::{covariance_lanes, eigen_plane, eigen_plane_near, SymLanes};
use crate::geometry::{is_valid_point, Grid, Intrinsics, Moments, PointMap, Vec3, INVALID_POINT};

/// The largest half-width of a support window, pixels.
pub const MAX_HALF_PX: usize = 64;

/// Scatter off a support's plane, beyond the noise, below which it holds no step, metres.
const PLANAR_M: f64 = 0.002;

/// Half-widths tried above the one the metric radius asks for, pixels.
const LADDER: [usize; 12] = [1, 2, 3, 4, 6, 8, 11, 16, 23, 32, 45, 64];

/// Settings of the terrain estimate, with their defaults.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TerrainConfig {
    /// Smallest support radius R, metres (the spec's 0.05).
    pub radius_m: f64,
    /// The support radius is at least this many σ_z at the pixel's range.
    pub noise_radii: f64,
    /// Fewest valid points in a support window.
    pub min_points: u32,
    /// The plane's second eigenvalue must be this many times the noise variance along its
    /// normal (points spread in two directions, well beyond the noise).
    pub conditioning: f64,
    /// Noise margins are this many σ.
    pub debias: f64,
    /// Half-width of the band a step spreads over, pixels.
    pub band_px: usize,
}

impl Default for TerrainConfig {
    fn default() -> Self {
        Self {
            radius_m: 0.05,
            noise_radii: 4.0,
            min_points: 12,
            conditioning: 9.0,
            debias: 2.0,
            band_px: 2,
        }
    }
}

/// The terrain estimate of one frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TerrainMaps {
    /// Roughness, metres: the larger of the surface and step terms (NaN: no point, or no
    /// support with enough evidence).
    pub roughness_m: Grid<f64>,
    /// Unit normals of the support planes, oriented towards the camera (NaN: none).
    pub normals: Grid<Vec3>,
    /// The margin subtracted for noise (the smallest roughness the estimate resolves), metres.
    pub uncertainty_m: Grid<f64>,
}

/// What one pixel's support gives: its plane and the noise along its normal.
#[derive(Debug, Clone, Copy)]
struct Support {
    half: usize,
    count: f64,
    centroid: Vec3,
    normal: Vec3,
    /// σ of a point's offset along the normal from white range noise, metres.
    sigma_n: f64,
    /// Registration offset σ at this range, metres.
    sigma_c: f64,
    /// The points' variance off the plane, m².
    l_min: f64,
    /// The plane's smaller in-plane variance, m².
    l_mid: f64,
    /// The larger in-plane variance, m².
    l_max: f64,
}

impl Support {
    /// The variance of the plane's tilt (radians²), bounded by its smaller in-plane spread,
    /// from white noise (`mean_var`: the mean of its points' noise, in units of one point's)
    /// and the registration offsets, one per scan line (image row) of the window. Bounded: a
    /// tilt along the larger spread is better known, but the bound also covers what the noise
    /// model leaves out (docs/terrain.md).
    fn tilt2(&self, mean_var: f64) -> f64 {
        let lines = 2.0 * self.half as f64 + 1.0;
        let noise2 = self.sigma_n.powi(2) * mean_var + self.sigma_c.powi(2) / lines;
        noise2 / self.l_mid.max(f64::MIN_POSITIVE)
    }
}

/// The terrain estimate of `points` (camera frame, metres) seen with focal length `fx_px` and
/// noise model `noise` (`None`: exact depth), into `out` (its grids reused).
pub fn terrain_into(
    points: &PointMap,
    fx_px: f64,
    noise: Option<&SensorNoise>,
    cfg: &TerrainConfig,
    sums: &mut SummedMoments,
    out: &mut TerrainMaps,
) {
    let (w, h) = points.size();
    let frame = Frame::new(points, sums, fx_px, noise, cfg);
    // Pass 1: supports, surface terms and the steps of the seams right of and below each pixel.
    let per_pixel: Vec<(f64, f64, f64, Vec3)> = (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            let frame = &frame;
            // Each support's plane starts its solve from the left neighbour's (rows are
            // independent, so the result does not depend on the threads).
            let mut left = None;
            (0..w).map(move |x| frame.pixel((x, y), &mut left))
        })
        .collect();
    // Pass 2: each step spreads over its band; roughness is the larger term.
    let rows = band_max(&per_pixel, (w, h), cfg.band_px);
    out.roughness_m.reset(w, h, f64::NAN);
    out.uncertainty_m.reset(w, h, f64::NAN);
    out.normals.reset(w, h, Vec3::repeat(f64::NAN));
    for (y, row) in rows {
        for (x, r) in row.into_iter().enumerate() {
            let (_, _, u, n) = per_pixel[y * w + x];
            out.roughness_m[(x, y)] = r;
            if r.is_finite() {
                out.uncertainty_m[(x, y)] = u;
                out.normals[(x, y)] = n;
            }
        }
    }
}

/// Per row, the larger of each pixel's surface term and the steps within `band` pixels of it
/// (NaN where the pixel has no estimate). The box's largest step is taken along the rows, then
/// down the columns: ten values a pixel instead of 25 at a band of 2, the same maximum.
fn band_max(
    per_pixel: &[(f64, f64, f64, Vec3)],
    (w, h): (usize, usize),
    band: usize,
) -> Vec<(usize, Vec<f64>)> {
    let across: Vec<f64> = (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            let row = &per_pixel[y * w..(y + 1) * w];
            (0..w).map(move |x| {
                row[x.saturating_sub(band)..(x + band + 1).min(w)]
                    .iter()
                    .fold(f64::NEG_INFINITY, |m, p| m.max(p.1))
            })
        })
        .collect();
    (0..h)
        .into_par_iter()
        .map(|y| {
            let rows = y.saturating_sub(band)..(y + band + 1).min(h);
            let row = (0..w)
                .map(|x| {
                    let surface = per_pixel[y * w + x].0;
                    if !surface.is_finite() {
                        return f64::NAN;
                    }
                    rows.clone()
                        .fold(surface, |m, yy| m.max(across[yy * w + x]))
                })
                .collect();
            (y, row)
        })
        .collect()
}

/// [`terrain_into`] into fresh maps.
pub fn terrain(
    points: &PointMap,
    fx_px: f64,
    noise: Option<&SensorNoise>,
    cfg: &TerrainConfig,
) -> TerrainMaps {
    let mut out = TerrainMaps::default();
    terrain_into(
        points,
        fx_px,
        noise,
        cfg,
        &mut SummedMoments::default(),
        &mut out,
    );
    out
}

/// Holes of the depth are filled only where points lie within this many pixels around.
pub const FILL_HALF_PX: usize = 8;

/// The points read through the terrain supports, into `out` (the depth the learned `rgbd`
/// mode reads): each point moved along its ray towards its support's plane by what the noise
/// explains (its offset from the plane shrunk by `debias` σ, noise and registration: noise
/// goes, a step or a rock beyond it stays), and each pixel without depth given the point
/// where its ray meets the plane of a support around it (when one with enough points spread
/// lies within [`FILL_HALF_PX`] pixels). A pixel whose support finds no plane (rough ground,
/// an obstacle) keeps its point, or stays without one.
pub fn clean_points_into(
    points: &PointMap,
    k: &Intrinsics,
    noise: Option<&SensorNoise>,
    cfg: &TerrainConfig,
    sums: &mut SummedMoments,
    out: &mut PointMap,
) {
    let (w, h) = points.size();
    let frame = Frame::new(points, sums, k.fx_px, noise, cfg);
    out.reset(w, h, INVALID_POINT);
    out.par_rows_mut().for_each(|(y, row)| {
        let mut left = None;
        for (x, q) in row.iter_mut().enumerate() {
            let p = points[(x, y)];
            let ray = Vec3::new(
                (x as f64 - k.cx_px) / k.fx_px,
                (y as f64 - k.cy_px) / k.fy_px,
                1.0,
            );
            *q = frame.on_support((x, y), p, &ray, &mut left).unwrap_or(p);
        }
    });
}

/// One frame's inputs to the per-pixel estimate.
struct Frame<'a> {
    points: &'a PointMap,
    sums: &'a SummedMoments,
    origin: Vec3,
    fx_px: f64,
    noise: Option<&'a SensorNoise>,
    cfg: &'a TerrainConfig,
}

impl<'a> Frame<'a> {
    /// The frame of `points`, its summed-area tables built into `sums`.
    fn new(
        points: &'a PointMap,
        sums: &'a mut SummedMoments,
        fx_px: f64,
        noise: Option<&'a SensorNoise>,
        cfg: &'a TerrainConfig,
    ) -> Self {
        sums.build(points);
        let sums = &*sums;
        Frame {
            points,
            sums,
            origin: sums.origin(),
            fx_px,
            noise,
            cfg,
        }
    }
    /// The variance of the mean of `n` neighbours' noise, in units of one point's
    /// ([`SensorNoise::mean_variance`]; independent points without a noise model).
    fn mean_var(&self, n: f64) -> f64 {
        self.noise.map_or(1.0 / n.max(1.0), |s| s.mean_variance(n))
    }

    /// `(surface term, step of the seams right of and below, uncertainty, normal)` at a pixel;
    /// NaN surface term (and normal) where it has no point or no support.
    fn pixel(&self, xy: (usize, usize), left: &mut Option<Vec3>) -> (f64, f64, f64, Vec3) {
        let none = (f64::NAN, 0.0, f64::NAN, Vec3::repeat(f64::NAN));
        let p = self.points[xy];
        if !is_valid_point(&p) {
            return none;
        }
        let s = match self.support(xy, &p, left) {
            Found::Plane(s) => s,
            Found::Rough(r, normal, u) => return (r, 0.0, u, normal),
            Found::Nothing => return none,
        };
        let k = self.cfg.debias;
        // Surface term: the inner window's mean point against the support's plane.
        let inner = self.sums.window(xy, (s.half / 3).max(1));
        let n_in = f64::from(inner.count.max(1));
        let q = self.origin + inner.sum / n_in;
        let d = s.normal.dot(&(q - s.centroid)).abs();
        let e_s = s.sigma_n * (self.mean_var(n_in) + self.mean_var(s.count)).sqrt();
        let surface = (d * d - (k * e_s).powi(2)).max(0.0).sqrt();
        let (step, e_j) = self.step_term(xy, &p, &s);
        let uncertainty = k * e_s.max(e_j);
        (surface, step, uncertainty, s.normal)
    }

    /// The step term of the seams right of and below pixel `xy` (point `p`, support `s`), and
    /// its noise σ: the margin a step must clear.
    fn step_term(&self, xy: (usize, usize), p: &Vec3, s: &Support) -> (f64, f64) {
        let (x, y) = (xy.0 as isize, xy.1 as isize);
        let r = s.half as isize;
        // Each seam's two sides, and the image rows each side spans (the scan lines its
        // registration offsets average over).
        let seams = [
            (
                ((x - r, y - r), (x + 1, y + r + 1)),
                ((x + 1, y - r), (x + r + 2, y + r + 1)),
                2.0 * r as f64 + 1.0,
            ),
            (
                ((x - r, y - r), (x + r + 1, y + 1)),
                ((x - r, y + 1), (x + r + 1, y + r + 2)),
                r as f64 + 1.0,
            ),
        ];
        // The noise as the support predicts it for two halves of itself (measured on the seams
        // below where they are looked at). Two halves' centroids lie √3·σ apart along the
        // window's longer in-plane axis (a uniform spread): metres of ground at grazing views.
        let reach2 = 3.0 * s.l_max;
        let noise2 = s.sigma_n * s.sigma_n + s.sigma_c * s.sigma_c;
        let lines = s.half as f64 + 1.0;
        let mut e_j: f64 = (s.sigma_n.powi(2) * 2.0 * self.mean_var(0.5 * s.count)
            + 2.0 * s.sigma_c.powi(2) / lines
            + s.tilt2(self.mean_var(s.count)) * reach2)
            .sqrt();
        // A support whose points lie on its plane within twice the noise (and 2 mm) holds no
        // step the margin would let through: its seams need no look.
        if s.l_min <= 4.0 * noise2 + PLANAR_M * PLANAR_M {
            return (0.0, e_j);
        }
        let min_side = (self.cfg.min_points / 2).max(3);
        let extent = s.half as f64 * p.z / self.fx_px;
        let var = |n: f64| self.mean_var(n);
        let mut step: f64 = 0.0;
        for ((a0, a1), (b0, b1), lines) in seams {
            let (a, b) = (self.sums.rect(a0, a1), self.sums.rect(b0, b1));
            if a.count < min_side || b.count < min_side {
                continue;
            }
            let test = (self.cfg.conditioning, extent, lines);
            let Some((jump, e)) = pooled_step((&a, &b), &var, s, test) else {
                continue;
            };
            e_j = e_j.max(e);
            step = step.max(jump - self.cfg.debias * e);
        }
        (step.max(0.0), e_j)
    }

    /// The point of pixel `xy` (point `p`, NaN where it has none) moved along its ray to its
    /// support's plane by what noise explains ([`clean_points_into`]); `None` where it has no
    /// support plane, or no point and no point near it.
    fn on_support(
        &self,
        xy: (usize, usize),
        p: Vec3,
        ray: &Vec3,
        left: &mut Option<Vec3>,
    ) -> Option<Vec3> {
        let valid = is_valid_point(&p);
        let anchor = if valid {
            p
        } else {
            let near = LADDER
                .into_iter()
                .take_while(|&l| l <= FILL_HALF_PX)
                .map(|l| self.sums.window(xy, l))
                .find(|m| m.count >= self.cfg.min_points)?;
            let mean = self.origin + near.sum / f64::from(near.count);
            ray * mean.z
        };
        let Found::Plane(s) = self.support(xy, &anchor, left) else {
            return None;
        };
        // The offset from the plane, less what noise gives; then n·(X − c) = offset along
        // X = t·ray. A ray nearly in the plane keeps its point.
        let offset = if valid {
            let d = s.normal.dot(&(p - s.centroid));
            let noise = self.cfg.debias * s.sigma_n.hypot(s.sigma_c);
            d.signum() * (d.abs() - noise).max(0.0)
        } else {
            0.0
        };
        let along = s.normal.dot(ray);
        let t = (s.normal.dot(&s.centroid) + offset) / along;
        let grazing = along.abs() < 0.05 * ray.norm();
        (!grazing && t > 0.0).then(|| ray * t)
    }

    /// The smallest support window of pixel `xy` (point `p`) with enough points spread in two
    /// directions, and its plane; else what the largest window with enough points says.
    fn support(&self, xy: (usize, usize), p: &Vec3, left: &mut Option<Vec3>) -> Found {
        let z = p.z;
        let sigma_z = self.noise.map_or(0.0, |n| n.sigma_z_m(z).max(0.0));
        let sigma_c = self.noise.map_or(0.0, |n| n.registration_m(z));
        let radius = self.cfg.radius_m.max(self.cfg.noise_radii * sigma_z);
        let need = ((radius * self.fx_px / z).ceil() as usize).clamp(1, MAX_HALF_PX);
        let halves = std::iter::once(need).chain(LADDER.into_iter().filter(|&l| l > need));
        let mut smallest = None;
        for half in halves {
            let m = self.sums.window(xy, half);
            if m.count < self.cfg.min_points {
                continue;
            }
            let cov = covariance_lanes(&[m]);
            let plane = match left {
                Some(guess) => eigen_plane_near(&cov, guess),
                None => eigen_plane(&cov),
            };
            let Some((normal, l_min, l_mid)) = plane else {
                continue;
            };
            let count = f64::from(m.count);
            let normal = if normal.dot(p) > 0.0 { -normal } else { normal };
            smallest.get_or_insert((normal, l_min, count));
            // The points must spread along the plane: over half the metric radius, by more
            // than the noise along the normal (registration included) by `conditioning`,
            // and more than across it (a rough patch still has a plane; a line has none).
            *left = Some(normal);
            let sigma_n = sigma_z * normal.dot(p).abs() / z;
            let extent = radius.min(half as f64 * z / self.fx_px);
            let noise2 = sigma_n * sigma_n + sigma_c * sigma_c;
            let spread = l_mid >= self.cfg.conditioning * noise2
                && l_mid >= 2.0 * l_min
                && l_mid.sqrt() >= 0.5 * extent;
            if !spread {
                continue;
            }
            return Found::Plane(Support {
                half,
                count,
                centroid: self.origin + m.sum / count,
                normal,
                sigma_n,
                sigma_c,
                l_mid,
                l_min,
                l_max: (cov[0][0] + cov[3][0] + cov[5][0] - l_min - l_mid).max(l_mid),
            });
        }
        // No plane: rough where the scatter off the smallest window's plane exceeds what the
        // noise (as if the surface faced the camera, its largest) explains by the margin.
        let Some((normal, l_min, count)) = smallest else {
            return Found::Nothing;
        };
        let noise = sigma_z.hypot(sigma_c);
        let k = self.cfg.debias;
        let excess = (l_min - (k * noise).powi(2)).max(0.0).sqrt();
        if excess > 0.0 {
            let u = k * noise / count.sqrt();
            Found::Rough(HALF_NORMAL_P95 * excess, normal, u)
        } else {
            Found::Nothing
        }
    }
}

/// What a pixel's windows give.
enum Found {
    /// A support plane.
    Plane(Support),
    /// No plane: points scattered beyond the noise. `(roughness, normal, uncertainty)`.
    Rough(f64, Vec3, f64),
    /// Too few points, or scatter that noise explains.
    Nothing,
}

/// Whether a covariance's middle eigenvalue can reach `l_mid`: it is at most half the trace
/// (the other two are at least 0 and at least it), with room for the solver's rounding.
fn may_spread(cov: &SymLanes<1>, l_mid: f64) -> bool {
    0.5 * (cov[0][0] + cov[3][0] + cov[5][0]) * (1.0 + 1e-9) >= l_mid
}

/// The largest angle between the pooled normal of a step's two sides and the support's: a
/// real step tilts the support's plane by less; two sides that are each a fronto-parallel
/// terrace of quantised disparity (passive stereo) pool to the viewing axis, far more.
const MAX_POOLED_TILT_DEG: f64 = 30.0;

/// The offset between two sides' centroids along their pooled normal, and its noise σ. Where
/// the pooled scatter is not spread in two directions (each side one scan line, say: then any
/// direction across the lines fits) or tilts from the support's normal by more than
/// [`MAX_POOLED_TILT_DEG`], the support's normal stands in; `(conditioning, extent, lines)`:
/// the support's test, `extent` the support's half-width in metres, and the image rows each
/// side spans (a registration offset is shared by a scan line, so a side's mean averages the
/// offsets of its lines).
fn pooled_step(
    (a, b): (&Moments, &Moments),
    mean_var: &dyn Fn(f64) -> f64,
    s: &Support,
    (conditioning, extent, lines): (f64, f64, f64),
) -> Option<(f64, f64)> {
    let (na, nb) = (f64::from(a.count), f64::from(b.count));
    let covs = covariance_lanes(&[*a, *b]);
    let pooled: SymLanes<1> =
        std::array::from_fn(|e| [(na * covs[e][0] + nb * covs[e][1]) / (na + nb)]);
    // Half the trace bounds the middle eigenvalue: a pooled scatter that cannot pass the
    // spread test needs no solve.
    let plane = if may_spread(&pooled, 0.0625 * extent * extent) {
        eigen_plane_near(&pooled, &s.normal)
    } else {
        None
    };
    let (normal, spread, count) = match plane {
        Some((n, l_min, l_mid))
            if l_mid >= conditioning * l_min
                && l_mid.sqrt() >= 0.25 * extent
                && n.dot(&s.normal).abs() >= MAX_POOLED_TILT_DEG.to_radians().cos() =>
        {
            (n, l_mid, na + nb)
        }
        _ => (s.normal, s.l_mid, s.count),
    };
    let delta = b.sum / nb - a.sum / na;
    let offset = delta.dot(&normal).abs();
    // The normal's own error tilts the offset by its angle times the sides' distance along the
    // plane (large at grazing views, where a window spans metres of ground).
    let tilt2 = s.tilt2(mean_var(count)) * s.l_mid / spread.max(f64::MIN_POSITIVE);
    let along2 = (delta.norm_squared() - offset * offset).max(0.0);
    let sides = mean_var(na) + mean_var(nb);
    let registration2 = 2.0 * s.sigma_c.powi(2) / lines;
    let e = (s.sigma_n.powi(2) * sides + registration2 + tilt2 * along2).sqrt();
    Some((offset, e))
}

#[cfg(test)]
mod tests;
