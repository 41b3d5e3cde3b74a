//! DSAC plane hypotheses for initial normals (DESIGN.md, "DSAC normals"): per pixel, K triples of
//! 7×7 neighbours drawn from the neighbour net's probabilities ρ, scored by soft inlier counts;
//! serving keeps the best hypothesis and refits it by least squares on its inliers.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::camera::{is_valid_point, PointMap, INVALID_POINT};
use super::hash::uniform;
use super::plane::{orient_towards_camera, Moments, Plane};
use super::{GeometryError, Grid, Vec3};

/// Side of the candidate window.
pub const WINDOW: usize = 7;
/// Candidates per pixel (7 × 7), index `k = (dy + 3)·7 + (dx + 3)`.
pub const CANDIDATES: usize = WINDOW * WINDOW;

/// The pixel offset `(dx, dy)` of candidate `k`.
///
/// ```
/// assert_eq!(tre::geometry::dsac::candidate_offset(0), (-3, -3));
/// assert_eq!(tre::geometry::dsac::candidate_offset(24), (0, 0));
/// assert_eq!(tre::geometry::dsac::candidate_offset(48), (3, 3));
/// ```
pub fn candidate_offset(k: usize) -> (isize, isize) {
    ((k % WINDOW) as isize - 3, (k / WINDOW) as isize - 3)
}

/// Sampler and scorer settings; they must match the training code.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DsacConfig {
    /// Hypotheses per pixel, K (default 12).
    pub hypotheses: u32,
    /// Inlier threshold τ, metres (default 0.01).
    pub inlier_threshold_m: f64,
    /// Sigmoid sharpness as a multiple of 1/τ: β = softness / τ (default 5).
    pub softness: f64,
    /// Seed of the per-request random stream.
    pub seed: u64,
}

impl Default for DsacConfig {
    fn default() -> Self {
        Self {
            hypotheses: 12,
            inlier_threshold_m: 0.01,
            softness: 5.0,
            seed: 0,
        }
    }
}

impl DsacConfig {
    /// Soft inlier score of one candidate at distance `dist_m` from a hypothesis plane.
    #[inline]
    pub fn soft_inlier(&self, dist_m: f64) -> f64 {
        let beta = self.softness / self.inlier_threshold_m;
        1.0 / (1.0 + (-beta * (self.inlier_threshold_m - dist_m)).exp())
    }
}

/// The 49 candidate points of pixel `(x, y)` (invalid or outside the image: NaN).
pub fn candidates(points: &PointMap, x: usize, y: usize) -> [Vec3; CANDIDATES] {
    let mut out = [INVALID_POINT; CANDIDATES];
    let (w, h) = points.size();
    for (k, c) in out.iter_mut().enumerate() {
        let (dx, dy) = candidate_offset(k);
        let (cx, cy) = (x as isize + dx, y as isize + dy);
        if cx >= 0 && cy >= 0 && (cx as usize) < w && (cy as usize) < h {
            *c = points[(cx as usize, cy as usize)];
        }
    }
    out
}

/// ρ: the softmax of the 49 logits over the valid candidates (0 for invalid ones), in f64.
pub fn candidate_probabilities(
    logits: &[f32; CANDIDATES],
    cands: &[Vec3; CANDIDATES],
) -> [f64; CANDIDATES] {
    let mut rho = [0.0; CANDIDATES];
    let valid = |k: usize| is_valid_point(&cands[k]) && logits[k].is_finite();
    let max = (0..CANDIDATES)
        .filter(|&k| valid(k))
        .map(|k| f64::from(logits[k]))
        .fold(f64::NEG_INFINITY, f64::max);
    if max == f64::NEG_INFINITY {
        return rho;
    }
    let mut total = 0.0;
    for k in (0..CANDIDATES).filter(|&k| valid(k)) {
        rho[k] = (f64::from(logits[k]) - max).exp();
        total += rho[k];
    }
    for r in rho.iter_mut() {
        *r /= total;
    }
    rho
}

/// Draws 3 distinct candidates for hypothesis `hypothesis` of pixel `pixel`: each draw inverts
/// the CDF of ρ renormalised without the candidates already drawn. `None` when fewer than 3
/// candidates carry probability.
pub fn sample_triple(
    rho: &[f64; CANDIDATES],
    seed: u64,
    pixel: u64,
    hypothesis: u32,
) -> Option<[usize; 3]> {
    let mut drawn = [usize::MAX; 3];
    for d in 0..3 {
        let taken = |k: usize| drawn[..d].contains(&k);
        let mut total = 0.0;
        for (k, r) in rho.iter().enumerate() {
            if !taken(k) {
                total += r;
            }
        }
        if !(total > 0.0) {
            return None;
        }
        let t = uniform(seed, pixel, hypothesis, d as u32) * total;
        let (mut acc, mut pick) = (0.0, None);
        for (k, &r) in rho.iter().enumerate() {
            if taken(k) || r <= 0.0 {
                continue;
            }
            acc += r;
            pick = Some(k);
            if t < acc {
                break;
            }
        }
        drawn[d] = pick?;
    }
    Some(drawn)
}

/// One pixel's DSAC outcome, with what is needed to compare against the training code.
#[derive(Debug, Clone, PartialEq)]
pub struct PixelHypotheses {
    /// Sampled candidate triples (`None`: fewer than 3 candidates with probability).
    pub triples: Vec<Option<[usize; 3]>>,
    /// Soft inlier score of each hypothesis (−∞ for degenerate ones).
    pub scores: Vec<f64>,
    /// Index of the best hypothesis (first of equal scores), if any is non-degenerate.
    pub best: Option<usize>,
    /// Final normal: LS refit on the best hypothesis' inliers, oriented towards the camera.
    pub normal: Option<Vec3>,
}

/// Runs the sampler and scorer for one pixel given its candidates and ρ.
pub fn pixel_hypotheses(
    cands: &[Vec3; CANDIDATES],
    rho: &[f64; CANDIDATES],
    pixel: u64,
    cfg: &DsacConfig,
) -> PixelHypotheses {
    let triples: Vec<_> = (0..cfg.hypotheses)
        .map(|j| sample_triple(rho, cfg.seed, pixel, j))
        .collect();
    let planes: Vec<_> = triples
        .iter()
        .map(|t| t.and_then(|[a, b, c]| Plane::through(&cands[a], &cands[b], &cands[c])))
        .collect();
    let scores: Vec<f64> = planes
        .iter()
        .map(|p| p.map_or(f64::NEG_INFINITY, |p| score(&p, cands, cfg)))
        .collect();
    let mut best = None;
    for (j, s) in scores.iter().enumerate() {
        if *s > f64::NEG_INFINITY && best.is_none_or(|b: usize| *s > scores[b]) {
            best = Some(j);
        }
    }
    let normal = best.and_then(|b| planes[b]).map(|p| refit(&p, cands, cfg));
    PixelHypotheses {
        triples,
        scores,
        best,
        normal,
    }
}

/// Soft inlier count of `plane` over the valid candidates.
fn score(plane: &Plane, cands: &[Vec3; CANDIDATES], cfg: &DsacConfig) -> f64 {
    cands
        .iter()
        .filter(|q| is_valid_point(q))
        .map(|q| cfg.soft_inlier(plane.distance(q)))
        .sum()
}

/// LS refit on the inliers (distance < τ) of `plane`, oriented towards the camera; the
/// hypothesis' own normal if the refit is degenerate.
fn refit(plane: &Plane, cands: &[Vec3; CANDIDATES], cfg: &DsacConfig) -> Vec3 {
    let origin = cands[CANDIDATES / 2];
    let mut m = Moments::default();
    for q in cands
        .iter()
        .filter(|q| is_valid_point(q) && plane.distance(q) < cfg.inlier_threshold_m)
    {
        m.add(&(q - origin));
    }
    let n = m.fit(&origin).map_or(plane.normal, |p| p.normal);
    orient_towards_camera(&n, &origin)
}

/// DSAC initial normals for a whole frame. `logits` holds the neighbour net's output for one
/// image in channel-major order (49 × H × W, as NCHW with N = 1). Row-parallel and seeded per
/// pixel, so the answer does not depend on the number of threads.
pub fn dsac_normals(
    points: &PointMap,
    logits: &[f32],
    cfg: &DsacConfig,
) -> Result<Grid<Vec3>, GeometryError> {
    let (w, h) = points.size();
    if logits.len() != CANDIDATES * w * h {
        return Err(GeometryError::LogitsSize {
            expected: CANDIDATES * w * h,
            got: logits.len(),
        });
    }
    let mut out = Grid::new(w, h, INVALID_POINT);
    out.as_mut_slice()
        .par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, n) in row.iter_mut().enumerate() {
                if !is_valid_point(&points[(x, y)]) {
                    continue;
                }
                let i = y * w + x;
                let pixel_logits: [f32; CANDIDATES] =
                    std::array::from_fn(|k| logits[k * w * h + i]);
                let cands = candidates(points, x, y);
                let rho = candidate_probabilities(&pixel_logits, &cands);
                if let Some(normal) = pixel_hypotheses(&cands, &rho, i as u64, cfg).normal {
                    *n = normal;
                }
            }
        });
    Ok(out)
}
