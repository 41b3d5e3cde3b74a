//! DSAC plane hypotheses for initial normals (docs/design.md, "DSAC normals"): per pixel, K triples of
//! 7×7 neighbours drawn from the neighbour net's probabilities ρ, scored by soft inlier counts;
//! serving keeps the best hypothesis and refits it by least squares on its inliers.
//!
//! The exact definition, the contract that the training code follows too, is `SAMPLER.md` in
//! this folder (included below, "The DSAC sampler contract"), with the parity vectors that both
//! sides are tested against beside it in `vectors.json`.
//!
//! # Implementation
//!
//! [`dsac_normals`] reads every window from a copy of the point map padded by three invalid
//! pixels (no bounds checks), keeps ρ and the scores in f32 lane arrays that auto-vectorise
//! (SSE2 and up), allocates nothing per pixel, and runs rows in parallel with rayon; every
//! pixel's draws depend only on `(seed, i)`, so the result does not depend on the thread count.
//!
//! The sampler draws by binary search instead of a scan. Within a run of undrawn candidates
//! between drawn ones, `F_d` subtracts the same constants from `P_k`; `P` is monotone and
//! `x ↦ fl(x − c)` is monotone, so `F_d` is monotone there, and `F_d(k) = F_d(k − 1)` wherever
//! `ρ_k = 0`. Hence, in the first run whose last candidate with `ρ > 0` satisfies `t < F_d`,
//! the first `k` with `t < F_d(k)` followed by a step forward to the next `k` with `ρ_k > 0` is
//! exactly the scan's answer; if no run has one, the answer is the last candidate with `ρ > 0`.
//! The hypotheses' searches run in lockstep. ρ that is negative or not finite (possible only
//! through [`sample_triple`]) falls back to the scan itself.
//!
//! Scoring stops early for a hypothesis that provably cannot beat the best one so far: its
//! partial sum plus, per valid candidate still to come, the most one candidate can add (the
//! value at distance 0), with a margin for rounding, is not above the best score. Each batch
//! of hypotheses finishes first the one leading after two blocks, to raise that bar early. The
//! chosen hypothesis, and so the result, are those of the full computation, which
//! [`pixel_hypotheses`] performs.
//!
//! The refits run eight pixels of a row at a time once their best hypotheses are known: the
//! inlier moments over four f64 lanes (one pixel each, outliers adding zeros, so every sum is
//! the one-pixel sum bit for bit) and the eigen-solves over eight.
#![doc = include_str!("SAMPLER.md")]

use std::hint::select_unpredictable;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::camera::{is_valid_point, PointMap, INVALID_POINT};
use super::fastmath::{self, recip_one_plus_exp2, sum_block, BLOCK};
use super::hash::{pixel_stream, splitmix64, stream_uniform};
use super::plane::{fit_normals, orient_towards_camera, Moments, Plane};
use super::simd::from_fn;
use super::{GeometryError, Grid, Vec3};

/// Side of the candidate window.
pub const WINDOW: usize = 7;
/// Candidates per pixel (7 × 7), index `k = (dy + 3)·7 + (dx + 3)`.
pub const CANDIDATES: usize = WINDOW * WINDOW;

/// Lanes of the per-pixel lane arrays: the candidates padded to whole blocks.
const LANES: usize = 56;
/// Blocks of [`BLOCK`] lanes.
const BLOCKS: usize = LANES / BLOCK;
/// Entries of the prefix-sum table (a power of two above [`CANDIDATES`], for the search).
const TABLE: usize = 64;
/// Half-window: pixels of padding on every side of [`PaddedPoints`].
const RADIUS: usize = WINDOW / 2;
/// Hypotheses sampled together, stage by stage.
const BATCH: usize = 12;
/// Slack for the f32 rounding in the pruning bound of [`Window::finish_above`] (the bound needs
/// 2e-4 for scores up to 49).
const PRUNE_MARGIN: f32 = 1e-3;

/// The pixel offset `(dx, dy)` of candidate `k`.
///
/// ```
/// assert_eq!(tre_core::geometry::dsac::candidate_offset(0), (-3, -3));
/// assert_eq!(tre_core::geometry::dsac::candidate_offset(24), (0, 0));
/// assert_eq!(tre_core::geometry::dsac::candidate_offset(48), (3, 3));
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
    /// Soft inlier score of one candidate at distance `dist_m` from a hypothesis plane, in f64:
    /// the reference for the f32 scorer (module docs, step 4).
    ///
    /// ```
    /// let cfg = tre_core::geometry::dsac::DsacConfig::default();
    /// assert_eq!(cfg.soft_inlier(0.01), 0.5);
    /// ```
    #[inline]
    pub fn soft_inlier(&self, dist_m: f64) -> f64 {
        let beta = self.softness / self.inlier_threshold_m;
        1.0 / (1.0 + (-beta * (self.inlier_threshold_m - dist_m)).exp())
    }
}

/// The 49 candidate points of pixel `(x, y)` (invalid or outside the image: NaN).
///
/// ```
/// use tre_core::geometry::{dsac, Grid, Vec3};
/// let points = Grid::new(4, 4, Vec3::new(0.0, 0.0, 1.0));
/// let c = dsac::candidates(&points, 0, 0);
/// assert!(c[0].x.is_nan() && c[dsac::CANDIDATES / 2].z == 1.0);
/// ```
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

/// ρ: the softmax of the 49 logits over the usable candidates (valid, finite logit; 0 for the
/// others), computed in f32 with [`fastmath::exp`] and widened to f64 (module docs, step 2):
/// within about 4e-7 (relative) of the f64 softmax, and bit-identical to what
/// [`dsac_normals`] samples from.
///
/// ```
/// use tre_core::geometry::{dsac, Grid, Vec3};
/// let points = Grid::new(9, 9, Vec3::new(0.0, 0.0, 1.0));
/// let rho = dsac::candidate_probabilities(&[0.0; 49], &dsac::candidates(&points, 4, 4));
/// assert!(rho.iter().all(|&r| (r - 1.0 / 49.0).abs() < 1e-8));
/// ```
pub fn candidate_probabilities(
    logits: &[f32; CANDIDATES],
    cands: &[Vec3; CANDIDATES],
) -> [f64; CANDIDATES] {
    let mut lanes = [0.0; LANES];
    lanes[..CANDIDATES].copy_from_slice(logits);
    let points = PaddedPoints::of_candidates(cands);
    let rho = softmax(&lanes, &Window::new(&points, RADIUS, RADIUS).valid);
    from_fn(|k| f64::from(rho[k]))
}

/// Draws 3 distinct candidates for hypothesis `hypothesis` of pixel `pixel`, inverting the CDF of
/// ρ renormalised without the candidates already drawn, exactly as defined in the module docs
/// (step 3). `None` when fewer than 3 candidates carry probability.
///
/// ```
/// let mut rho = [0.0; 49];
/// for k in [3, 10, 24, 40] {
///     rho[k] = 0.25;
/// }
/// let t = tre_core::geometry::dsac::sample_triple(&rho, 1, 77, 0).unwrap();
/// assert!(t.iter().all(|&k| rho[k] > 0.0) && t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
/// ```
pub fn sample_triple(
    rho: &[f64; CANDIDATES],
    seed: u64,
    pixel: u64,
    hypothesis: u32,
) -> Option<[usize; 3]> {
    Cdf::new(rho).triple(pixel_stream(splitmix64(seed), pixel), hypothesis)
}

/// One pixel's DSAC outcome, with what is needed to compare against the training code.
#[derive(Debug, Clone, PartialEq)]
pub struct PixelHypotheses {
    /// Sampled candidate triples (`None`: fewer than 3 candidates with probability).
    pub triples: Vec<Option<[usize; 3]>>,
    /// Soft inlier score of each hypothesis, computed in f32 (−∞ for degenerate ones).
    pub scores: Vec<f64>,
    /// Index of the best hypothesis (first of equal scores), if any is non-degenerate.
    pub best: Option<usize>,
    /// Final normal: LS refit on the best hypothesis' inliers, oriented towards the camera.
    pub normal: Option<Vec3>,
}

/// Runs the sampler and scorer for one pixel given its candidates and ρ, as [`dsac_normals`]
/// does (bit-identical normal), recording every hypothesis. Meant for tests and debugging: it
/// allocates. The centre candidate should be valid; if it is not, coordinates are taken about
/// the camera origin.
///
/// ```
/// use tre_core::geometry::dsac::{self, DsacConfig};
/// use tre_core::geometry::{Grid, Vec3};
/// let points = Grid::from_fn(9, 9, |x, y| Vec3::new(0.01 * x as f64, 0.01 * y as f64, 1.0));
/// let cands = dsac::candidates(&points, 4, 4);
/// let rho = dsac::candidate_probabilities(&[0.0; 49], &cands);
/// let h = dsac::pixel_hypotheses(&cands, &rho, 40, &DsacConfig::default());
/// assert_eq!(h.triples.len(), 12);
/// assert!((h.normal.unwrap().z + 1.0).abs() < 1e-9);
/// ```
pub fn pixel_hypotheses(
    cands: &[Vec3; CANDIDATES],
    rho: &[f64; CANDIDATES],
    pixel: u64,
    cfg: &DsacConfig,
) -> PixelHypotheses {
    let points = PaddedPoints::of_candidates(cands);
    let window = Window::new(&points, RADIUS, RADIUS);
    let stream = pixel_stream(splitmix64(cfg.seed), pixel);
    let mut triples = Vec::with_capacity(cfg.hypotheses as usize);
    let mut scores = Vec::with_capacity(cfg.hypotheses as usize);
    let mut record = |triple, score| {
        triples.push(triple);
        scores.push(f64::from(score));
    };
    let best = best_hypothesis(&window, &Cdf::new(rho), stream, cfg, Some(&mut record));
    PixelHypotheses {
        triples,
        scores,
        best: best.map(|(j, _)| j),
        normal: best.and_then(|(_, plane)| {
            finish_refits(&[Some(window.refit_input(&plane, cfg.inlier_threshold_m))])[0]
        }),
    }
}

/// DSAC initial normals for a whole frame. `logits` holds the neighbour net's output for one
/// image in channel-major order (49 × H × W, as NCHW with N = 1). Row-parallel and seeded per
/// pixel, so the answer does not depend on the number of threads.
///
/// ```
/// use tre_core::geometry::dsac::{self, DsacConfig};
/// use tre_core::geometry::{Grid, Vec3};
/// let points = Grid::from_fn(9, 9, |x, y| Vec3::new(0.01 * x as f64, 0.01 * y as f64, 1.0));
/// let normals = dsac::dsac_normals(&points, &vec![0.0; 49 * 81], &DsacConfig::default()).unwrap();
/// assert!((normals[(4, 4)].z + 1.0).abs() < 1e-9);
/// ```
pub fn dsac_normals(
    points: &PointMap,
    logits: &[f32],
    cfg: &DsacConfig,
) -> Result<Grid<Vec3>, GeometryError> {
    let mut out = Grid::default();
    dsac_normals_into(points, logits, cfg, &mut DsacScratch::default(), &mut out)?;
    Ok(out)
}

/// Buffers of [`dsac_normals_into`] kept from frame to frame: the padded copy of the points.
#[derive(Debug, Default)]
pub struct DsacScratch {
    points: PaddedPoints,
}

/// [`dsac_normals`] into `out` (resized to the size of `points`), with the padded copy of the
/// points in `scratch`: both keep their buffers, so a caller that reuses them from frame to
/// frame allocates nothing once they have reached the frame's size. The result is the same.
///
/// ```
/// use tre_core::geometry::dsac::{dsac_normals, dsac_normals_into, DsacScratch};
/// use tre_core::geometry::dsac::DsacConfig;
/// use tre_core::geometry::{Grid, Vec3};
/// let points = Grid::from_fn(9, 9, |x, y| Vec3::new(0.01 * x as f64, 0.01 * y as f64, 1.0));
/// let logits = vec![0.0; 49 * 81];
/// let (mut scratch, mut out) = (DsacScratch::default(), Grid::default());
/// dsac_normals_into(&points, &logits, &DsacConfig::default(), &mut scratch, &mut out).unwrap();
/// assert_eq!(out, dsac_normals(&points, &logits, &DsacConfig::default()).unwrap());
/// ```
///
/// # Errors
///
/// [`GeometryError::LogitsSize`] when `logits` does not hold 49 × H × W values.
pub fn dsac_normals_into(
    points: &PointMap,
    logits: &[f32],
    cfg: &DsacConfig,
    scratch: &mut DsacScratch,
    out: &mut Grid<Vec3>,
) -> Result<(), GeometryError> {
    let (w, h) = points.size();
    if logits.len() != CANDIDATES * w * h {
        return Err(GeometryError::LogitsSize {
            expected: CANDIDATES * w * h,
            got: logits.len(),
        });
    }
    scratch.points.pack(points);
    let frame = Frame {
        points: &scratch.points,
        logits,
        width: w,
        seed_key: splitmix64(cfg.seed),
        cfg,
    };
    out.reset(w, h, INVALID_POINT);
    out.par_rows_mut()
        .for_each(|(y, row)| dsac_row(&frame, y, row));
    Ok(())
}

/// Row `y` of [`dsac_normals_into`], [`REFIT_LANES`] pixels at a time. Compiled twice, for
/// baseline x86-64 and for AVX2 + FMA, and the CPU's version is chosen at run time
/// ([`super::simd`]); both give the same bits.
#[multiversion(targets("x86_64+avx2+fma"))]
fn dsac_row<'a>(frame: &Frame<'a>, y: usize, row: &mut [Vec3]) {
    for (x0, cells) in (0..row.len())
        .step_by(REFIT_LANES)
        .zip(row.chunks_mut(REFIT_LANES))
    {
        for (n, normal) in cells.iter_mut().zip(frame.group_normals(x0, y)) {
            if let Some(normal) = normal {
                *n = normal;
            }
        }
    }
}

mod frame;
mod refit;
mod sampler;
mod score;
#[cfg(test)]
mod tests;
mod window;

use frame::Frame;
use multiversion::multiversion;
use refit::{finish_refits, inlier_moments, Refit, MOMENT_LANES, REFIT_LANES};
use sampler::Cdf;
use score::{best_hypothesis, softmax, Hyp32, Scorer, LEAD_BLOCKS};
use window::{PaddedPoints, Window};
