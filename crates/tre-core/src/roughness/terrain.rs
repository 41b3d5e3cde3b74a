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

use super::noise::{shared_mean_variance, SensorNoise};
use crate::geometry::sums::SummedMoments;
use crate::geometry::{eigen_planes_of, SymLanes};
use crate::geometry::{is_valid_point, Grid, Intrinsics, Moments, PointMap, Vec3, INVALID_POINT};

/// The largest half-width of a support window, pixels.
pub const MAX_HALF_PX: usize = 64;

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

/// The terrain estimate of `points` (camera frame, metres) seen through intrinsics `k` (their
/// focal lengths: the supports' pixels and the noise's correlation window) with noise model
/// `noise` (`None`: exact depth), into `out` (its grids reused).
pub fn terrain_into(
    points: &PointMap,
    k: &Intrinsics,
    noise: Option<&SensorNoise>,
    cfg: &TerrainConfig,
    sums: &mut SummedMoments,
    out: &mut TerrainMaps,
) {
    let (w, h) = points.size();
    let frame = Frame::new(points, sums, k, noise, cfg);
    // Pass 1: supports, surface terms and the steps of the seams right of and below each pixel.
    let per_pixel: Vec<(f64, f64, f64, Vec3)> = (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            let frame = &frame;
            frame.row(y)
        })
        .collect();
    // Pass 2: each step spreads over its band; roughness is the larger term.
    let across = band_across(&per_pixel, (w, h), cfg.band_px);
    out.roughness_m.reset(w, h, f64::NAN);
    out.uncertainty_m.reset(w, h, f64::NAN);
    out.normals.reset(w, h, Vec3::repeat(f64::NAN));
    let band = cfg.band_px;
    out.roughness_m
        .as_mut_slice()
        .par_chunks_mut(w)
        .zip(out.uncertainty_m.as_mut_slice().par_chunks_mut(w))
        .zip(out.normals.as_mut_slice().par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, ((roughness, uncertainty), normals))| {
            let rows = y.saturating_sub(band)..(y + band + 1).min(h);
            for x in 0..w {
                let (surface, _, u, n) = per_pixel[y * w + x];
                if !surface.is_finite() {
                    continue;
                }
                let r = rows
                    .clone()
                    .fold(surface, |m, yy| m.max(across[yy * w + x]));
                roughness[x] = r;
                if r.is_finite() {
                    uncertainty[x] = u;
                    normals[x] = n;
                }
            }
        });
}

/// Per pixel, the largest step within `band` pixels of it along its row; the band's box
/// maximum is this taken down the columns: ten values a pixel instead of 25 at a band of 2,
/// the same maximum.
fn band_across(
    per_pixel: &[(f64, f64, f64, Vec3)],
    (w, h): (usize, usize),
    band: usize,
) -> Vec<f64> {
    let mut across = vec![0.0; w * h];
    across.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        let row = &per_pixel[y * w..(y + 1) * w];
        for (x, o) in out.iter_mut().enumerate() {
            *o = row[x.saturating_sub(band)..(x + band + 1).min(w)]
                .iter()
                .fold(f64::NEG_INFINITY, |m, p| m.max(p.1));
        }
    });
    across
}

/// [`terrain_into`] into fresh maps.
pub fn terrain(
    points: &PointMap,
    k: &Intrinsics,
    noise: Option<&SensorNoise>,
    cfg: &TerrainConfig,
) -> TerrainMaps {
    let mut out = TerrainMaps::default();
    terrain_into(
        points,
        k,
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
    let frame = Frame::new(points, sums, k, noise, cfg);
    out.reset(w, h, INVALID_POINT);
    out.par_rows_mut().for_each(|(y, row)| {
        let found = frame.row_supports(y);
        for (x, q) in row.iter_mut().enumerate() {
            let p = points[(x, y)];
            let ray = Vec3::new(
                (x as f64 - k.cx_px) / k.fx_px,
                (y as f64 - k.cy_px) / k.fy_px,
                1.0,
            );
            *q = frame.on_support((x, y), p, &ray, found[x]).unwrap_or(p);
        }
    });
}

/// One frame's inputs to the per-pixel estimate.
struct Frame<'a> {
    points: &'a PointMap,
    sums: &'a SummedMoments,
    origin: Vec3,
    fx_px: f64,
    /// The noise's correlation window in this frame's pixels ([`SensorNoise::correlation_in`]).
    correlation: Option<(f64, f64)>,
    noise: Option<&'a SensorNoise>,
    cfg: &'a TerrainConfig,
}

impl<'a> Frame<'a> {
    /// The frame of `points`, its summed-area tables built into `sums`.
    fn new(
        points: &'a PointMap,
        sums: &'a mut SummedMoments,
        k: &Intrinsics,
        noise: Option<&'a SensorNoise>,
        cfg: &'a TerrainConfig,
    ) -> Self {
        sums.build(points);
        let sums = &*sums;
        Frame {
            points,
            sums,
            origin: sums.origin(),
            fx_px: k.fx_px,
            correlation: noise.map(|n| n.correlation_in((k.fx_px, k.fy_px))),
            noise,
            cfg,
        }
    }
    /// The variance of the mean of `n` neighbours' noise, in units of one point's
    /// ([`SensorNoise::mean_variance`]; independent points without a noise model).
    fn mean_var(&self, n: f64) -> f64 {
        self.correlation
            .map_or(1.0 / n.max(1.0), |c| shared_mean_variance(c, n))
    }

    /// `(surface term, step of the seams right of and below, uncertainty, normal)` of each
    /// pixel of row `y`; NaN surface term (and normal) where it has no point or no support.
    /// The first windows of the row's supports, and the pooled scatters of its seams, are
    /// solved four at a time ([`eigen_planes_of`]).
    fn row(&self, y: usize) -> Vec<(f64, f64, f64, Vec3)> {
        let w = self.points.size().0;
        let found = self.row_supports(y);
        let none: (f64, f64, f64, Vec3) = (f64::NAN, 0.0, f64::NAN, Vec3::repeat(f64::NAN));
        let mut out = vec![none; w];
        // Per pixel with a support plane: the support, the surface term's σ, the steps' σ.
        let mut supports: Vec<Option<(Support, f64, f64)>> = vec![None; w];
        let mut seams: Vec<Seam> = Vec::new();
        for (x, found) in found.into_iter().enumerate() {
            let Some(found) = found else {
                continue;
            };
            let p = self.points[(x, y)];
            let s = match found {
                Found::Plane(s) => s,
                Found::Rough(r, normal, u) => {
                    out[x] = (r, 0.0, u, normal);
                    continue;
                }
                Found::Nothing => continue,
            };
            let k = self.cfg.debias;
            // Surface term: the inner window's mean point against the support's plane.
            let inner = self.sums.window((x, y), (s.half / 3).max(1));
            let n_in = f64::from(inner.count.max(1));
            let q = self.origin + inner.sum / n_in;
            let d = s.normal.dot(&(q - s.centroid)).abs();
            let e_s = s.sigma_n * (self.mean_var(n_in) + self.mean_var(s.count)).sqrt();
            let surface = (d * d - (k * e_s).powi(2)).max(0.0).sqrt();
            let e_j = self.seams((x, y), &p, &s, &mut seams);
            out[x] = (surface, 0.0, f64::NAN, s.normal);
            supports[x] = Some((s, e_s, e_j));
        }
        // The seams' pooled planes, solved in lanes where they may pass the spread test.
        let todo: Vec<usize> = (0..seams.len()).filter(|&i| seams[i].solve).collect();
        let covs: Vec<SymLanes<1>> = todo.iter().map(|&i| seams[i].pooled).collect();
        let mut solved: Vec<Option<(Vec3, f64, f64)>> = vec![None; seams.len()];
        for (&i, plane) in todo.iter().zip(eigen_planes_of(&covs)) {
            solved[i] = plane;
        }
        let var = |n: f64| self.mean_var(n);
        for (seam, plane) in seams.iter().zip(solved) {
            let Some((s, _, e_j)) = supports[seam.x].as_mut() else {
                continue;
            };
            let (jump, e) = pooled_step(seam, plane, &var, s, self.cfg.conditioning);
            *e_j = e_j.max(e);
            out[seam.x].1 = out[seam.x].1.max(jump - self.cfg.debias * e);
        }
        for (o, support) in out.iter_mut().zip(supports) {
            if let Some((_, e_s, e_j)) = support {
                o.1 = o.1.max(0.0);
                o.2 = self.cfg.debias * e_s.max(e_j);
            }
        }
        out
    }

    /// The point of pixel `xy` (point `p`, NaN where it has none) moved along its ray to its
    /// support's plane by what noise explains ([`clean_points_into`]); `None` where it has no
    /// support plane, or no point and no point near it.
    fn on_support(
        &self,
        xy: (usize, usize),
        p: Vec3,
        ray: &Vec3,
        found: Option<Found>,
    ) -> Option<Vec3> {
        let valid = is_valid_point(&p);
        let support = if valid {
            // The row's supports were found for the pixels' own points.
            found?
        } else {
            let near = LADDER
                .into_iter()
                .take_while(|&l| l <= FILL_HALF_PX)
                .map(|l| self.sums.window(xy, l))
                .find(|m| m.count >= self.cfg.min_points)?;
            let mean = self.origin + near.sum / f64::from(near.count);
            self.support(xy, &(ray * mean.z))
        };
        let Found::Plane(s) = support else {
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

    /// The half-width the metric radius asks for at range `z`, and the noise there:
    /// `(half, radius, σ_z, registration σ)`.
    fn need(&self, z: f64) -> (usize, f64, f64, f64) {
        let sigma_z = self.noise.map_or(0.0, |n| n.sigma_z_m(z).max(0.0));
        let sigma_c = self.noise.map_or(0.0, |n| n.registration_m(z));
        let radius = self.cfg.radius_m.max(self.cfg.noise_radii * sigma_z);
        let need = ((radius * self.fx_px / z).ceil() as usize).clamp(1, MAX_HALF_PX);
        (need, radius, sigma_z, sigma_c)
    }
}

/// A support window's moments, covariance and plane ([`eigen_planes`]).
#[derive(Debug, Clone, Copy)]
struct Window {
    half: usize,
    m: Moments,
    cov: SymLanes<1>,
    plane: Option<(Vec3, f64, f64)>,
}

/// What a pixel's windows give.
#[derive(Debug, Clone, Copy)]
enum Found {
    /// A support plane.
    Plane(Support),
    /// No plane: points scattered beyond the noise. `(roughness, normal, uncertainty)`.
    Rough(f64, Vec3, f64),
    /// Too few points, or scatter that noise explains.
    Nothing,
}

mod steps;
mod support;

use steps::{pooled_step, Seam};

#[cfg(test)]
mod tests;
