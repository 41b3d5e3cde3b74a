//! DSAC plane hypotheses for initial normals (DESIGN.md, "DSAC normals"): per pixel, K triples of
//! 7×7 neighbours drawn from the neighbour net's probabilities ρ, scored by soft inlier counts;
//! serving keeps the best hypothesis and refits it by least squares on its inliers.
//!
//! # Exact definition
//!
//! The training code mirrors the steps below. Every floating-point operation is one correctly
//! rounded IEEE-754 operation in the type and order written (no FMA; `f32(x)` rounds a float64 to
//! float32), so numpy elementwise float32/float64 arithmetic reproduces each step bit for bit.
//! For pixel `(x, y)` of a `W × H` point map, `i = y·W + x`, whose point `p` is valid
//! ([`is_valid_point`]; other pixels get no normal):
//!
//! 1. **Candidates.** `k = (dy + 3)·7 + (dx + 3)` for `dx, dy ∈ −3..=3`; candidate `k` is valid
//!    when `(x + dx, y + dy)` lies inside the image and its point `q_k` is valid.
//! 2. **ρ** ([`candidate_probabilities`], float32). Candidate `k` is *usable* when it is valid and
//!    its logit `l_k` is finite. `m` = the largest usable logit; `e_k = fastmath::exp(l_k − m)`
//!    for usable `k`, else 0; `S` = the lane sum of `e`; `ρ_k = e_k / S`, then widened exactly
//!    to float64. With no usable candidate, ρ = 0 and the pixel gets no normal.
//!    [`fastmath::exp`] has a relative error below 2e-7, so ρ is within 4e-7 (relative) of the
//!    float64 softmax.
//! 3. **Sampler** ([`sample_triple`], float64), hypothesis `j`, draws `d = 0, 1, 2`.
//!    `P_k` = sequential float64 prefix sums of ρ (`P_k = P_{k−1} + ρ_k`, `P_{−1} = 0`). With
//!    the candidates already drawn `e1` (, `e2`) in draw order: `T_0 = P_48`;
//!    `T_1 = T_0 − ρ_{e1}`; `T_2 = T_1 − ρ_{e2}`; if `!(T_d > 0)` there is no triple.
//!    `t = uniform(seed, i, j, d) · T_d` ([`super::hash::uniform`]). `F_d(k) = P_k`, then minus
//!    `ρ_{e1}` if `k ≥ e1`, then minus `ρ_{e2}` if `k ≥ e2` (the subtractions done in that
//!    order, each rounded in float64; subtracting 0.0 when the condition is false). The draw is
//!    the smallest `k` not already drawn with `ρ_k > 0` and `t < F_d(k)`; if no `k` qualifies,
//!    the largest `k` not already drawn with `ρ_k > 0` (no triple if none).
//! 4. **Scores** (float32). The hypothesis plane is [`Plane::through`]`(q_a, q_b, q_c)` for the
//!    triple `[a, b, c]` in draw order (float64: point `q_a`, unit normal `n`); a missing triple
//!    or a degenerate plane scores −∞. Otherwise, with `τ` = `inlier_threshold_m` and
//!    `g = softness / τ · log₂e` (float64, `log₂e` rounded to float64): `m = g·n` and
//!    `u = q_a − p` per coordinate (float64); `n″ = f32(m)` per coordinate;
//!    `o″ = f32((m_x·u_x + m_y·u_y) + m_z·u_z)`; `τ″ = f32(min(g·τ, 120))`;
//!    `r_k = f32(q_k − p)` per coordinate (float64 difference, then rounded; 0 for invalid `k`);
//!    `s_k = ((n″_x·r_kx + n″_y·r_ky) + n″_z·r_kz) − o″`; `y_k = |s_k| − τ″`;
//!    `v_k = fastmath::recip_one_plus_exp2(y_k)`, which is `sigmoid(β(τ − dist_k))` with
//!    `β = softness / τ`; the score is the lane sum of `v_k`, invalid candidates contributing
//!    exactly 0. Against the same sum in float64, the float32 score differs by about 1e-5 for
//!    windows spanning a few centimetres (relative coordinates rounded to float32, the
//!    sigmoid's relative error below 7e-7), growing with the window's extent; hypotheses whose
//!    scores differ by less than that may rank differently in a float64 reference.
//! 5. **Best and refit** (float64). The best hypothesis is the first one with the largest score
//!    (−∞ never wins). The inliers of its plane are the valid `k` with
//!    `plane.distance(q_k) < τ` ([`Plane::distance`], Eq. 1); their [`Moments`] of `q_k − p`,
//!    added in `k` order, give the LS normal: the smallest eigenvector of their covariance
//!    ([`Moments::covariance`], [`fit_normals`]), or, with fewer than 3 inliers or
//!    no unique plane, the hypothesis' normal. It is flipped if `n · p > 0` (towards the
//!    camera).
//!
//! *Lane sums* (float32) add 56 lanes, the candidates `0..49` then seven zeros, as seven blocks of
//! eight: accumulator `a_l = ((0 + v_l) + v_{8+l}) + … + v_{48+l}` for `l = 0..8`, then
//! [`fastmath::sum_block`]`(a) = ((a₀ + a₄) + (a₂ + a₆)) + ((a₁ + a₅) + (a₃ + a₇))`.
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

use std::hint::select_unpredictable;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::camera::{is_valid_point, PointMap, INVALID_POINT};
use super::fastmath::{self, recip_one_plus_exp2, sum_block, BLOCK};
use super::hash::splitmix64;
use super::plane::{fit_normals, orient_towards_camera, Moments, Plane};
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
    /// Soft inlier score of one candidate at distance `dist_m` from a hypothesis plane, in f64:
    /// the reference for the f32 scorer (module docs, step 4).
    ///
    /// ```
    /// let cfg = tre::geometry::DsacConfig::default();
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
/// use tre::geometry::{dsac, Grid, Vec3};
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
/// use tre::geometry::{dsac, Grid, Vec3};
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
    std::array::from_fn(|k| f64::from(rho[k]))
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
/// let t = tre::geometry::dsac::sample_triple(&rho, 1, 77, 0).unwrap();
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
/// use tre::geometry::{dsac, DsacConfig, Grid, Vec3};
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
/// use tre::geometry::{dsac, DsacConfig, Grid, Vec3};
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
/// use tre::geometry::dsac::{dsac_normals, dsac_normals_into, DsacScratch};
/// use tre::geometry::{DsacConfig, Grid, Vec3};
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
    out.par_rows_mut().for_each(|(y, row)| {
        for (x0, cells) in (0..w).step_by(REFIT_LANES).zip(row.chunks_mut(REFIT_LANES)) {
            for (n, normal) in cells.iter_mut().zip(frame.group_normals(x0, y)) {
                if let Some(normal) = normal {
                    *n = normal;
                }
            }
        }
    });
    Ok(())
}

/// The per-pixel random stream: `splitmix64(seed_key ^ pixel)` with `seed_key =
/// splitmix64(seed)`, so that `uniform(seed, pixel, j, d)` is [`stream_uniform`]`(stream, j, d)`.
#[inline]
fn pixel_stream(seed_key: u64, pixel: u64) -> u64 {
    splitmix64(seed_key ^ pixel)
}

/// [`super::hash::uniform`] from the pixel's stream.
#[inline]
fn stream_uniform(stream: u64, hypothesis: u32, draw: u32) -> f64 {
    let key = (u64::from(hypothesis) << 8) | u64::from(draw);
    (splitmix64(stream ^ key) >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// Everything the per-pixel kernel reads, shared by all rows.
struct Frame<'a> {
    points: &'a PaddedPoints,
    logits: &'a [f32],
    width: usize,
    seed_key: u64,
    cfg: &'a DsacConfig,
}

impl Frame<'_> {
    /// The best hypothesis plane of pixel `(x, y)` and the pixel's point, or `None` (invalid
    /// pixel, or no usable hypothesis).
    fn pixel_best(&self, x: usize, y: usize) -> Option<(Plane, Vec3)> {
        if !self.points.is_valid(x, y) {
            return None;
        }
        let window = Window::new(self.points, x, y);
        let i = y * self.width + x;
        let plane_len = self.logits.len() / CANDIDATES;
        let mut lanes = [0.0; LANES];
        for (k, l) in lanes[..CANDIDATES].iter_mut().enumerate() {
            *l = self.logits[k * plane_len + i];
        }
        let cdf = Cdf::from_softmax(&softmax(&lanes, &window.valid));
        let stream = pixel_stream(self.seed_key, i as u64);
        let (_, plane) = best_hypothesis(&window, &cdf, stream, self.cfg, None)?;
        Some((plane, window.origin))
    }

    /// The DSAC normals of the pixels `(x0 + l, y)`, `l < REFIT_LANES` (`None` past the row's
    /// end, for invalid pixels and where no hypothesis is usable): best hypotheses pixel by
    /// pixel, then the refits' inlier moments and eigen-solves over the lanes.
    fn group_normals(&self, x0: usize, y: usize) -> [Option<Vec3>; REFIT_LANES] {
        let best: [Option<(Plane, Vec3)>; REFIT_LANES] =
            std::array::from_fn(|l| (x0 + l < self.width).then(|| self.pixel_best(x0 + l, y))?);
        let base = y * self.points.stride + x0;
        let tau = self.cfg.inlier_threshold_m;
        let moments: [Moments; REFIT_LANES] = if x0 + REFIT_LANES <= self.width {
            // Lanes without a plane get NaN ones: no inliers, and their moments are not used.
            let none = Plane {
                centroid: INVALID_POINT,
                normal: INVALID_POINT,
            };
            let planes = best.map(|b| b.map_or(none, |(p, _)| p));
            let origins = best.map(|b| b.map_or(INVALID_POINT, |(_, o)| o));
            // Four f64 lanes at a time, one AVX2 vector per sum: eight would not fit the registers.
            let mut moments = [Moments::default(); REFIT_LANES];
            for (h, m) in moments.chunks_exact_mut(MOMENT_LANES).enumerate() {
                let lanes = h * MOMENT_LANES..(h + 1) * MOMENT_LANES;
                m.copy_from_slice(&inlier_moments::<MOMENT_LANES>(
                    self.points,
                    base + h * MOMENT_LANES,
                    planes[lanes.clone()].try_into().expect("whole chunks"),
                    origins[lanes].try_into().expect("whole chunks"),
                    tau,
                ));
            }
            moments
        } else {
            // The row's last, partial group: its windows would reach past the padding.
            std::array::from_fn(|l| match best[l] {
                Some((p, o)) => inlier_moments(self.points, base + l, &[p], &[o], tau)[0],
                None => Moments::default(),
            })
        };
        let refits = std::array::from_fn(|l| {
            best[l].map(|(plane, origin)| Refit {
                moments: moments[l],
                hypothesis: plane.normal,
                origin,
            })
        });
        finish_refits(&refits)
    }
}

/// A hypothesis' triple and score, as [`pixel_hypotheses`] records them.
type Record<'r> = &'r mut dyn FnMut(Option<[usize; 3]>, f32);

/// Samples and scores `cfg.hypotheses` hypotheses in batches; returns the index and plane of
/// the best one (first of the largest scores). With `record`, every triple and score is passed
/// to it; without, each batch scores first the hypothesis that leads after
/// [`LEAD_BLOCKS`] blocks, then the others only as long as they might still beat the best
/// ([`Window::finish_above`]), which leaves the answer unchanged.
fn best_hypothesis(
    window: &Window<'_>,
    cdf: &Cdf,
    stream: u64,
    cfg: &DsacConfig,
    mut record: Option<Record<'_>>,
) -> Option<(usize, Plane)> {
    let scorer = Scorer::new(cfg);
    let mut best = Best::default();
    let mut first = 0;
    while first < cfg.hypotheses {
        let count = (cfg.hypotheses - first).min(BATCH as u32) as usize;
        let triples = cdf.triples(stream, first, count);
        let hyps: [Option<(Plane, Hyp32)>; BATCH] = std::array::from_fn(|j| {
            let [a, b, c] = triples[j]?;
            let plane = Plane::through(&window.point(a), &window.point(b), &window.point(c))?;
            Some((plane, window.hyp32(&plane, &scorer)))
        });
        let base = first as usize;
        match record.as_mut() {
            Some(r) => {
                for (j, (&triple, hyp)) in triples.iter().zip(&hyps).enumerate().take(count) {
                    let score = hyp.map(|(p, h)| (p, window.full_score(&h)));
                    r(triple, score.map_or(f32::NEG_INFINITY, |(_, s)| s));
                    if let Some((p, s)) = score {
                        best.offer(base + j, s, p);
                    }
                }
            }
            None => best_of_batch(window, &hyps[..count], base, scorer.most, &mut best),
        }
        first += count as u32;
    }
    best.found.map(|(j, _, p)| (j, p))
}

/// Offers the hypotheses of a batch (indices from `base`) to `best`, the one leading after
/// [`LEAD_BLOCKS`] blocks first, the others with pruning (`most`: [`Scorer::most`]).
fn best_of_batch(
    window: &Window<'_>,
    hyps: &[Option<(Plane, Hyp32)>],
    base: usize,
    most: f32,
    best: &mut Best,
) {
    let mut leads = [[0.0; BLOCK]; BATCH];
    let mut lead: Option<(usize, f32)> = None;
    for (j, hyp) in hyps.iter().enumerate() {
        if let Some((_, h)) = hyp {
            window.add_blocks(h, &mut leads[j], 0..LEAD_BLOCKS);
            let partial = sum_block(leads[j]);
            if lead.is_none_or(|(_, p)| partial > p) {
                lead = Some((j, partial));
            }
        }
    }
    let order = lead.map(|(j, _)| j).into_iter();
    let rest = (0..hyps.len()).filter(|&j| lead.is_none_or(|(l, _)| l != j));
    for j in order.chain(rest) {
        if let Some((plane, h)) = hyps[j] {
            if let Some(score) = window.finish_above(&h, leads[j], best.score(), most) {
                best.offer(base + j, score, plane);
            }
        }
    }
}

/// The best hypothesis so far: the largest score, and the first of equal ones.
#[derive(Default)]
struct Best {
    found: Option<(usize, f32, Plane)>,
}

impl Best {
    /// Its score (−∞ before any).
    fn score(&self) -> f32 {
        self.found.map_or(f32::NEG_INFINITY, |(_, s, _)| s)
    }

    /// Keeps hypothesis `j` if it scores more, or as much with a smaller index.
    fn offer(&mut self, j: usize, score: f32, plane: Plane) {
        let better = match self.found {
            None => true,
            Some((i, s, _)) => score > s || (score == s && j < i),
        };
        if better {
            self.found = Some((j, score, plane));
        }
    }
}

/// A hypothesis plane in the f32 form the scorer uses (module docs, step 4): `n″` and `o″`.
#[derive(Clone, Copy)]
struct Hyp32 {
    n: [f32; 3],
    o: f32,
    tau: f32,
}

/// Blocks scored for every hypothesis of a batch before the leading one is finished.
const LEAD_BLOCKS: usize = 2;

/// The constants of the f32 soft inlier score (module docs, step 4).
struct Scorer {
    /// β · log₂e, f64.
    gain: f64,
    /// `f32(min(β · log₂e · τ, 120))`.
    tau: f32,
    /// An upper bound of one candidate's soft inlier value: the value at distance 0,
    /// `recip_one_plus_exp2(−τ″)`, raised by 4e-6 (relative). `y = |s| − τ″ ≥ −τ″` for every
    /// candidate, 1/(1 + 2ʸ) decreases, and the approximation is within 7e-7 (relative) of it,
    /// so no candidate adds more.
    most: f32,
}

impl Scorer {
    fn new(cfg: &DsacConfig) -> Self {
        let gain = cfg.softness / cfg.inlier_threshold_m * std::f64::consts::LOG2_E;
        let tau = (gain * cfg.inlier_threshold_m).min(120.0) as f32;
        Self {
            gain,
            tau,
            most: (f64::from(recip_one_plus_exp2(-tau)) * (1.0 + 4e-6)) as f32,
        }
    }
}

/// ρ (f32 lanes) from the logits and the validity mask: module docs, step 2.
fn softmax(logits: &[f32; LANES], valid: &[u32; LANES]) -> [f32; LANES] {
    let mut usable = [0; LANES];
    for ((u, &v), &l) in usable.iter_mut().zip(valid).zip(logits) {
        *u = if l.abs() < f32::INFINITY { v } else { 0 };
    }
    let mut lane_max = [f32::NEG_INFINITY; BLOCK];
    for b in 0..BLOCKS {
        for (l, m) in lane_max.iter_mut().enumerate() {
            let k = b * BLOCK + l;
            let v = if usable[k] != 0 { logits[k] } else { *m };
            *m = if v > *m { v } else { *m };
        }
    }
    let max = lane_max.into_iter().fold(f32::NEG_INFINITY, f32::max);
    let mut e = [0.0; LANES];
    if max == f32::NEG_INFINITY {
        return e;
    }
    for ((e, &l), &u) in e.iter_mut().zip(logits).zip(&usable) {
        *e = f32::from_bits(fastmath::exp(l - max).to_bits() & u);
    }
    let total = lane_sum(&e);
    for v in &mut e {
        *v /= total;
    }
    e
}

/// The lane sum of the module docs: per-lane accumulation over the blocks, then
/// [`sum_block`].
#[inline]
fn lane_sum(v: &[f32; LANES]) -> f32 {
    let mut acc = [0.0; BLOCK];
    for b in 0..BLOCKS {
        for (l, a) in acc.iter_mut().enumerate() {
            *a += v[b * BLOCK + l];
        }
    }
    sum_block(acc)
}

/// The point map as three coordinate planes padded by [`RADIUS`] invalid pixels on every side,
/// so that every window is read without bounds checks; invalid points are NaN, so that a point
/// is valid exactly when its z is positive.
#[derive(Debug, Default)]
struct PaddedPoints {
    stride: usize,
    planes: [Vec<f64>; 3],
}

impl PaddedPoints {
    fn new(points: &PointMap) -> Self {
        let mut padded = Self::default();
        padded.pack(points);
        padded
    }

    /// Copies `points` in, reusing this buffer's allocations.
    fn pack(&mut self, points: &PointMap) {
        let (w, h) = points.size();
        self.stride = w + 2 * RADIUS;
        let stride = self.stride;
        for (a, plane) in self.planes.iter_mut().enumerate() {
            plane.clear();
            plane.resize(stride * (h + 2 * RADIUS), f64::NAN);
            plane
                .par_chunks_mut(stride)
                .skip(RADIUS)
                .take(h)
                .enumerate()
                .for_each(|(y, row)| {
                    for (dst, p) in row[RADIUS..].iter_mut().zip(points.row(y)) {
                        *dst = if is_valid_point(p) { p[a] } else { f64::NAN };
                    }
                });
        }
    }

    /// A 7 × 7 map holding `cands`, whose window at `(RADIUS, RADIUS)` is theirs.
    fn of_candidates(cands: &[Vec3; CANDIDATES]) -> Self {
        Self::new(&Grid::from_fn(WINDOW, WINDOW, |x, y| cands[y * WINDOW + x]))
    }

    /// Whether pixel `(x, y)` holds a valid point.
    fn is_valid(&self, x: usize, y: usize) -> bool {
        self.planes[2][(y + RADIUS) * self.stride + x + RADIUS] > 0.0
    }
}

/// One pixel's candidates: f32 lane arrays (candidate `k` in lane `k`; the lanes after the 49th
/// are padding and invalid) and the way back to their f64 points.
struct Window<'a> {
    points: &'a PaddedPoints,
    /// Index of candidate 0 in the padded planes.
    base: usize,
    /// Coordinates relative to `origin`, rounded to f32; 0 for invalid candidates.
    rel: [[f32; LANES]; 3],
    /// All bits set for valid candidates, 0 otherwise.
    valid: [u32; LANES],
    /// After block `b`: the number of valid candidates in later blocks.
    to_come: [f32; BLOCKS],
    /// The centre point (the camera origin if the centre is invalid).
    origin: Vec3,
}

impl<'a> Window<'a> {
    /// The window centred on pixel `(x, y)`.
    fn new(points: &'a PaddedPoints, x: usize, y: usize) -> Self {
        let base = y * points.stride + x;
        let centre = base + RADIUS * points.stride + RADIUS;
        let c = points.planes.each_ref().map(|p| p[centre]);
        let origin = if c[2] > 0.0 {
            Vec3::from(c)
        } else {
            Vec3::zeros()
        };
        let mut valid = [0; LANES];
        let mut rel = [[0.0; LANES]; 3];
        for r in 0..WINDOW {
            let src = base + r * points.stride..base + r * points.stride + WINDOW;
            let lanes = r * WINDOW..(r + 1) * WINDOW;
            for (v, &z) in valid[lanes.clone()]
                .iter_mut()
                .zip(&points.planes[2][src.clone()])
            {
                *v = if z > 0.0 { u32::MAX } else { 0 };
            }
            for (a, plane) in points.planes.iter().enumerate() {
                let dst = rel[a][lanes.clone()].iter_mut().zip(&valid[lanes.clone()]);
                for ((d, &m), &q) in dst.zip(&plane[src.clone()]) {
                    *d = f32::from_bits(((q - origin[a]) as f32).to_bits() & m);
                }
            }
        }
        let mut to_come = [0.0; BLOCKS];
        for b in (0..BLOCKS - 1).rev() {
            let next = &valid[(b + 1) * BLOCK..(b + 2) * BLOCK];
            to_come[b] = to_come[b + 1] + next.iter().filter(|&&v| v != 0).count() as f32;
        }
        Self {
            points,
            base,
            rel,
            valid,
            to_come,
            origin,
        }
    }

    /// Candidate `k`'s point.
    #[inline]
    fn point(&self, k: usize) -> Vec3 {
        let i = self.base + (k / WINDOW) * self.points.stride + k % WINDOW;
        Vec3::from(self.points.planes.each_ref().map(|p| p[i]))
    }

    /// `plane` in the scorer's f32 form.
    fn hyp32(&self, plane: &Plane, scorer: &Scorer) -> Hyp32 {
        let m = plane.normal * scorer.gain;
        let u = plane.centroid - self.origin;
        let o = (m.x * u.x + m.y * u.y) + m.z * u.z;
        Hyp32 {
            n: [m.x as f32, m.y as f32, m.z as f32],
            o: o as f32,
            tau: scorer.tau,
        }
    }

    /// Adds blocks `blocks` of `h`'s soft inlier terms to the lane accumulators `acc`.
    #[inline(always)]
    fn add_blocks(&self, h: &Hyp32, acc: &mut [f32; BLOCK], blocks: std::ops::Range<usize>) {
        let [nx, ny, nz] = h.n;
        let [rx, ry, rz] = &self.rel;
        for b in blocks {
            for (l, a) in acc.iter_mut().enumerate() {
                let k = b * BLOCK + l;
                let s = (nx * rx[k] + ny * ry[k]) + nz * rz[k] - h.o;
                let v = recip_one_plus_exp2(s.abs() - h.tau);
                *a += f32::from_bits(v.to_bits() & self.valid[k]);
            }
        }
    }

    /// The f32 soft inlier count of `h` over the valid candidates (module docs, step 4).
    fn full_score(&self, h: &Hyp32) -> f32 {
        let mut acc = [0.0; BLOCK];
        self.add_blocks(h, &mut acc, 0..BLOCKS);
        sum_block(acc)
    }

    /// The score of `h` from its accumulators after [`LEAD_BLOCKS`] blocks, or `None` once it
    /// provably is below `floor`: the partial sum plus `most` ([`Scorer::most`]) per valid
    /// candidate still to come, plus [`PRUNE_MARGIN`] for the f32 rounding of the sums (at most
    /// 56 · 10 · 2⁻²⁴ relative), bounds it from above.
    fn finish_above(&self, h: &Hyp32, mut acc: [f32; BLOCK], floor: f32, most: f32) -> Option<f32> {
        for b in LEAD_BLOCKS..BLOCKS {
            if sum_block(acc) + (self.to_come[b - 1] * most + PRUNE_MARGIN) <= floor {
                return None;
            }
            self.add_blocks(h, &mut acc, b..b + 1);
        }
        Some(sum_block(acc))
    }

    /// What the LS refit on the inliers of `plane` needs ([`inlier_moments`]).
    fn refit_input(&self, plane: &Plane, tau_m: f64) -> Refit {
        let [moments] = inlier_moments(self.points, self.base, &[*plane], &[self.origin], tau_m);
        Refit {
            moments,
            hypothesis: plane.normal,
            origin: self.origin,
        }
    }
}

/// The moments, about `origins[l]`, of the inliers (distance < `tau_m`) of `planes[l]` among
/// the candidates of the window whose candidate 0 is at `base + l` in the padded planes, for
/// each lane `l`: adjacent pixels of a row, solved together. Each lane adds its inliers in `k`
/// order, with the operations of [`Plane::distance`] and [`Moments::add`]; outliers add zeros
/// instead of branching, which leaves every sum unchanged bit for bit (`x + 0.0 = x`, and no
/// sum is −0). So a lane's moments do not depend on `N` or on the other lanes.
fn inlier_moments<const N: usize>(
    points: &PaddedPoints,
    base: usize,
    planes: &[Plane; N],
    origins: &[Vec3; N],
    tau_m: f64,
) -> [Moments; N] {
    let by_axis = |v: [Vec3; N]| -> [[f64; N]; 3] { std::array::from_fn(|a| v.map(|v| v[a])) };
    let n = by_axis(planes.map(|p| p.normal));
    let c = by_axis(planes.map(|p| p.centroid));
    let o = by_axis(*origins);
    let mut count = [0u64; N];
    // Σd (x, y, z), then Σddᵀ (xx, xy, xz, yy, yz, zz).
    let mut acc = [[0.0f64; N]; 9];
    for k in 0..CANDIDATES {
        let i = base + (k / WINDOW) * points.stride + k % WINDOW;
        let q = points.planes.each_ref().map(|p| {
            p[i..]
                .first_chunk::<N>()
                .expect("the lanes' windows lie inside the padded planes; this is a bug")
        });
        add_inliers(&mut count, &mut acc, q, [&n, &c, &o], tau_m);
    }
    std::array::from_fn(|l| Moments {
        count: count[l] as u32,
        sum: Vec3::new(acc[0][l], acc[1][l], acc[2][l]),
        sum_sq: std::array::from_fn(|e| acc[3 + e][l]),
    })
}

/// Adds candidate points `q` (one per lane) to the lanes' inlier moments: [`inlier_moments`].
#[inline(always)]
fn add_inliers<const N: usize>(
    count: &mut [u64; N],
    acc: &mut [[f64; N]; 9],
    q: [&[f64; N]; 3],
    [n, c, o]: [&[[f64; N]; 3]; 3],
    tau_m: f64,
) {
    for l in 0..N {
        let [qx, qy, qz] = [q[0][l], q[1][l], q[2][l]];
        let dist = ((n[0][l] * (qx - c[0][l]) + n[1][l] * (qy - c[1][l]))
            + n[2][l] * (qz - c[2][l]))
            .abs();
        let mask = if dist < tau_m { u64::MAX } else { 0 };
        // The count in integer lanes (the mask is −1 where kept).
        count[l] = count[l].wrapping_sub(mask);
        let [dx, dy, dz] =
            [qx - o[0][l], qy - o[1][l], qz - o[2][l]].map(|d| f64::from_bits(d.to_bits() & mask));
        acc[0][l] += dx;
        acc[1][l] += dy;
        acc[2][l] += dz;
        acc[3][l] += dx * dx;
        acc[4][l] += dx * dy;
        acc[5][l] += dx * dz;
        acc[6][l] += dy * dy;
        acc[7][l] += dy * dz;
        acc[8][l] += dz * dz;
    }
}

/// A pixel's LS refit before its eigen-solve: the inliers' moments, the best hypothesis' normal
/// (kept if the refit is degenerate) and the centre point.
#[derive(Clone, Copy)]
struct Refit {
    moments: Moments,
    hypothesis: Vec3,
    origin: Vec3,
}

/// Pixels whose refits are solved together.
const REFIT_LANES: usize = 8;
/// Lanes of one [`inlier_moments`] call in a group.
const MOMENT_LANES: usize = 4;

/// Finishes the refits of up to `N` pixels: the LS plane of each one's inliers (the smallest
/// eigenvector of their covariance, solved over lanes), or the hypothesis' normal when there
/// are fewer than 3 inliers or no unique plane; oriented towards the camera. Each lane's
/// result depends only on its own refit.
fn finish_refits<const N: usize>(refits: &[Option<Refit>; N]) -> [Option<Vec3>; N] {
    let fits = fit_normals(&refits.map(|r| r.map_or(Moments::default(), |r| r.moments)));
    std::array::from_fn(|l| {
        let r = refits[l]?;
        let n = fits[l].unwrap_or(r.hypothesis);
        Some(orient_towards_camera(&n, &r.origin))
    })
}

/// Bits `0..k` of a candidate mask.
#[inline]
fn below(k: usize) -> u64 {
    (1u64 << k) - 1
}

/// The highest candidate in a mask, 0 for an empty one.
#[inline]
fn highest_or_zero(mask: u64) -> usize {
    63 - (mask | 1).leading_zeros() as usize
}

/// The highest candidate in a mask.
#[inline]
fn highest(mask: u64) -> Option<usize> {
    (mask != 0).then(|| highest_or_zero(mask))
}

/// A run of undrawn candidates from `start`: its candidates with probability (`inside`) and the
/// subtrahends of `F_d = (P − c1) − c2` there.
#[derive(Clone, Copy)]
struct Run {
    start: usize,
    inside: u64,
    c1: f64,
    c2: f64,
}

impl Run {
    #[inline]
    fn new(start: usize, inside: u64, c1: f64, c2: f64) -> Self {
        Self {
            start,
            inside,
            c1,
            c2,
        }
    }

    /// `F_d` of a prefix sum in this run.
    #[inline]
    fn f(&self, prefix: f64) -> f64 {
        (prefix - self.c1) - self.c2
    }
}

/// ρ prepared for sampling: module docs, step 3.
struct Cdf {
    /// ρ_k (0 past the 49th).
    rho: [f64; TABLE],
    /// P_k (P_48 past the 49th).
    prefix: [f64; TABLE],
    /// Bit k set when ρ_k > 0.
    nonzero: u64,
    /// ρ finite and non-negative, so that the prefix sums are monotone and the search applies.
    monotone: bool,
}

impl Cdf {
    /// The sampler's view of any ρ.
    fn new(rho: &[f64; CANDIDATES]) -> Self {
        let mut table = [0.0; TABLE];
        table[..CANDIDATES].copy_from_slice(rho);
        let monotone = rho.iter().all(|&r| r >= 0.0 && r.is_finite());
        let nonzero = (0..CANDIDATES).fold(0, |m, k| m | (u64::from(rho[k] > 0.0) << k));
        Self::with_prefix(table, nonzero, monotone)
    }

    /// The sampler's view of ρ as [`softmax`] returns it: finite and non-negative.
    fn from_softmax(rho32: &[f32; LANES]) -> Self {
        let mut rho = [0.0; TABLE];
        for (r, &r32) in rho.iter_mut().zip(rho32) {
            *r = f64::from(r32);
        }
        let mut nonzero = 0;
        for (b, block) in rho32.chunks_exact(BLOCK).enumerate() {
            let bits = (0..BLOCK).fold(0u64, |m, l| m | (u64::from(block[l] > 0.0) << l));
            nonzero |= bits << (b * BLOCK);
        }
        Self::with_prefix(rho, nonzero, true)
    }

    /// The prefix sums of `rho`.
    fn with_prefix(rho: [f64; TABLE], nonzero: u64, monotone: bool) -> Self {
        let mut prefix = [0.0; TABLE];
        let mut acc = 0.0;
        for (p, &r) in prefix[..CANDIDATES].iter_mut().zip(&rho) {
            acc += r;
            *p = acc;
        }
        prefix[CANDIDATES..].fill(acc);
        Self {
            rho,
            prefix,
            nonzero,
            monotone,
        }
    }

    /// The triple of hypothesis `hypothesis` of the pixel whose stream is `stream`.
    fn triple(&self, stream: u64, hypothesis: u32) -> Option<[usize; 3]> {
        self.triples(stream, hypothesis, 1)[0]
    }

    /// The triples of hypotheses `first..first + count` (`count ≤ BATCH`), drawn stage by stage
    /// (every first draw, then every second one, …) and with their binary searches in
    /// lockstep, so that the hypotheses' independent searches overlap in the processor.
    fn triples(&self, stream: u64, first: u32, count: usize) -> [Option<[usize; 3]>; BATCH] {
        let mut drawn = [[0; 3]; BATCH];
        let mut total = [self.prefix[CANDIDATES - 1]; BATCH];
        let mut alive = [false; BATCH];
        alive[..count].fill(true);
        let mut draws = [Draw::settled(None); BATCH];
        for d in 0..3 {
            for j in 0..count {
                if d > 0 {
                    total[j] -= self.rho[drawn[j][d - 1]];
                }
                alive[j] &= total[j] > 0.0;
                draws[j] = if alive[j] {
                    let t = stream_uniform(stream, first + j as u32, d as u32) * total[j];
                    self.plan(t, &drawn[j][..d])
                } else {
                    Draw::settled(None)
                };
            }
            for _ in 0..SEARCH_STEPS {
                for draw in &mut draws[..count] {
                    draw.step(&self.prefix);
                }
            }
            for j in 0..count {
                match draws[j].finish(&self.prefix) {
                    Some(e) => drawn[j][d] = e,
                    None => alive[j] = false,
                }
            }
        }
        std::array::from_fn(|j| alive[j].then_some(drawn[j]))
    }

    /// The draw for `t`, given the candidates already drawn: settled, or a search to run.
    #[inline]
    fn plan(&self, t: f64, drawn: &[usize]) -> Draw {
        if !self.monotone {
            return Draw::settled(self.pick_by_scan(t, drawn));
        }
        match *drawn {
            [] => self.plan_in_runs(t, [Run::new(0, self.nonzero, 0.0, 0.0)]),
            [e1] => self.plan_in_runs(
                t,
                [
                    Run::new(0, self.nonzero & below(e1), 0.0, 0.0),
                    Run::new(e1 + 1, self.nonzero & !below(e1 + 1), self.rho[e1], 0.0),
                ],
            ),
            [e1, e2, ..] => {
                let (lo, hi) = (e1.min(e2), e1.max(e2));
                let between = self.nonzero & below(hi) & !below(lo + 1);
                self.plan_in_runs(
                    t,
                    [
                        Run::new(0, self.nonzero & below(lo), 0.0, 0.0),
                        Run::new(lo + 1, between, self.rho[lo], 0.0),
                        Run::new(
                            hi + 1,
                            self.nonzero & !below(hi + 1),
                            self.rho[e1],
                            self.rho[e2],
                        ),
                    ],
                )
            }
        }
    }

    /// The draw among `runs` (in candidate order): a search in the first run where some
    /// candidate with probability qualifies (`t < F` at its last one); else, settled, the last
    /// candidate with probability. Branch-free up to that rare fallback.
    #[inline(always)]
    fn plan_in_runs<const N: usize>(&self, t: f64, runs: [Run; N]) -> Draw {
        let lasts = runs.map(|r| highest_or_zero(r.inside));
        let mut chosen = N;
        for (r, run) in runs.iter().enumerate().rev() {
            let here = (run.inside != 0) & (t < run.f(self.prefix[lasts[r] % TABLE]));
            chosen = select_unpredictable(here, r, chosen);
        }
        match runs.get(chosen) {
            Some(&run) => Draw::search(t, run, lasts[chosen]),
            None => Draw::settled(highest(runs.iter().fold(0, |m, r| m | r.inside))),
        }
    }

    /// One draw by the linear scan of the definition (for ρ that is not monotone-safe).
    fn pick_by_scan(&self, t: f64, drawn: &[usize]) -> Option<usize> {
        let f = |k: usize| {
            drawn.iter().fold(self.prefix[k], |v, &e| {
                v - if k >= e { self.rho[e] } else { 0.0 }
            })
        };
        let eligible = |k: &usize| self.rho[*k] > 0.0 && !drawn.contains(k);
        (0..CANDIDATES)
            .filter(eligible)
            .find(|&k| t < f(k))
            .or_else(|| (0..CANDIDATES).rev().find(eligible))
    }
}

/// Binary-search steps: enough for runs of up to 64 candidates.
const SEARCH_STEPS: usize = 6;

/// One draw in progress: settled, or a branch-free binary search (a lower bound after Khuong
/// and Morin) for the first `k` in `base..base + n` of a run with `t < F(k)` (which exists),
/// followed by a step to the run's next candidate with probability.
#[derive(Clone, Copy)]
struct Draw {
    t: f64,
    run: Run,
    base: usize,
    n: usize,
    /// `Some(answer)` when known without a search.
    settled: Option<Option<usize>>,
}

impl Draw {
    fn settled(answer: Option<usize>) -> Self {
        Self {
            t: 0.0,
            run: Run::new(0, 0, 0.0, 0.0),
            base: 0,
            n: 1,
            settled: Some(answer),
        }
    }

    /// A search of `run.start..=last`, given `t < F(last)`.
    fn search(t: f64, run: Run, last: usize) -> Self {
        Self {
            t,
            run,
            base: run.start,
            n: last + 1 - run.start,
            settled: None,
        }
    }

    /// Whether candidate `k` fails: `F(k) ≤ t` (or NaN).
    #[inline(always)]
    fn fails(&self, prefix: &[f64; TABLE], k: usize) -> bool {
        !(self.t < self.run.f(prefix[k % TABLE]))
    }

    /// One halving of the search range (a no-op once it holds one candidate).
    #[inline(always)]
    fn step(&mut self, prefix: &[f64; TABLE]) {
        let half = self.n / 2;
        let probe = self.base + half;
        self.base = select_unpredictable(self.fails(prefix, probe), probe, self.base);
        self.n -= half;
    }

    /// The drawn candidate, after [`SEARCH_STEPS`] steps.
    #[inline(always)]
    fn finish(&self, prefix: &[f64; TABLE]) -> Option<usize> {
        if let Some(answer) = self.settled {
            return answer;
        }
        let k = self.base + usize::from(self.fails(prefix, self.base));
        Some(k + (self.run.inside >> k).trailing_zeros() as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::hash::uniform;
    use proptest::prelude::*;

    #[test]
    fn no_candidate_adds_more_than_the_pruning_bound() {
        let scorer = Scorer::new(&DsacConfig::default());
        let tau = scorer.tau;
        // Every f32 y within 4096 ulps above −τ″, then a fine sweep up to the clamp.
        let ulps = (0..4096u32).map(|i| f32::from_bits((-tau).to_bits() - i));
        let sweep = (0..200_000).map(|i| -tau + i as f32 * 1e-3);
        for y in ulps.chain(sweep) {
            assert!(y >= -tau);
            assert!(recip_one_plus_exp2(y) <= scorer.most, "y = {y}");
        }
        assert!(scorer.most < 0.994 && scorer.most > 0.993);
    }

    /// The sampler exactly as the module docs define it, by linear scans.
    fn reference_triple(
        rho: &[f64; CANDIDATES],
        seed: u64,
        pixel: u64,
        hyp: u32,
    ) -> Option<[usize; 3]> {
        let mut prefix = [0.0; CANDIDATES];
        let mut acc = 0.0;
        for k in 0..CANDIDATES {
            acc += rho[k];
            prefix[k] = acc;
        }
        let mut drawn: Vec<usize> = Vec::new();
        let mut total = prefix[CANDIDATES - 1];
        for d in 0..3u32 {
            if let Some(&e) = drawn.last() {
                total -= rho[e];
            }
            if !(total > 0.0) {
                return None;
            }
            let t = uniform(seed, pixel, hyp, d) * total;
            let f = |k: usize| {
                let mut v = prefix[k];
                for &e in &drawn {
                    v -= if k >= e { rho[e] } else { 0.0 };
                }
                v
            };
            let ok = |k: usize| !drawn.contains(&k) && rho[k] > 0.0;
            let pick = (0..CANDIDATES)
                .find(|&k| ok(k) && t < f(k))
                .or_else(|| (0..CANDIDATES).rev().find(|&k| ok(k)))?;
            drawn.push(pick);
        }
        Some([drawn[0], drawn[1], drawn[2]])
    }

    /// One ρ entry: mostly zeros, tiny values, exact ties or random magnitudes.
    fn rho_entry() -> impl Strategy<Value = f64> {
        prop_oneof![
            4 => Just(0.0),
            1 => Just(f64::from_bits(1)),
            1 => Just(1e-300),
            1 => Just(1e-17),
            2 => Just(0.25),
            2 => Just(1.0 / 3.0),
            1 => Just(7.0),
            3 => 0.0..1.0f64,
            1 => (-40.0..0.0f64).prop_map(f64::exp2),
        ]
    }

    /// One ρ entry of a sparse ρ: mostly zeros and tiny values, and a few large ones, so that
    /// the remaining mass after large draws is made of rounding errors.
    fn sparse_rho_entry() -> impl Strategy<Value = f64> {
        prop_oneof![
            14 => Just(0.0),
            2 => Just(f64::from_bits(1)),
            2 => Just(0.3 * f64::EPSILON),
            2 => Just(1e-17),
            2 => (-70.0..-40.0f64).prop_map(f64::exp2),
            1 => Just(1.0),
            1 => Just(0.75),
            1 => 0.5..4.0f64,
        ]
    }

    fn rho_vec() -> impl Strategy<Value = [f64; CANDIDATES]> {
        let entries = prop_oneof![
            prop::collection::vec(rho_entry(), CANDIDATES),
            prop::collection::vec(sparse_rho_entry(), CANDIDATES),
        ];
        entries.prop_map(|v| {
            let mut rho = [0.0; CANDIDATES];
            rho.copy_from_slice(&v);
            rho
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]
        #[test]
        fn fast_sampler_equals_linear_scan(rho in rho_vec(), seed in any::<u64>(), pixel in any::<u64>()) {
            for hyp in 0..48 {
                let p = pixel.wrapping_add(u64::from(hyp / 8));
                prop_assert_eq!(sample_triple(&rho, seed, p, hyp), reference_triple(&rho, seed, p, hyp));
            }
        }

        #[test]
        fn fast_sampler_equals_linear_scan_on_softmax(logits in prop::array::uniform32(-30.0..30.0f32), seed in any::<u64>()) {
            let points = Grid::new(7, 7, Vec3::new(0.0, 0.0, 1.0));
            let mut all = [0.0; CANDIDATES];
            all[..32].copy_from_slice(&logits);
            all[32..].copy_from_slice(&logits[..17]);
            let rho = candidate_probabilities(&all, &candidates(&points, 3, 3));
            for hyp in 0..24 {
                prop_assert_eq!(sample_triple(&rho, seed, 5, hyp), reference_triple(&rho, seed, 5, hyp));
            }
        }
    }

    #[test]
    fn sampler_handles_unsafe_rho_by_scanning() {
        let mut rho = [0.1; CANDIDATES];
        rho[5] = -0.3;
        rho[9] = f64::NAN;
        rho[30] = f64::INFINITY;
        for hyp in 0..50 {
            assert_eq!(
                sample_triple(&rho, 3, 8, hyp),
                reference_triple(&rho, 3, 8, hyp)
            );
        }
    }

    #[test]
    fn stream_uniform_is_hash_uniform() {
        for (seed, pixel, hyp, d) in [(0, 0, 0, 0), (7, 1234, 3, 2), (u64::MAX, 99, 11, 1)] {
            let stream = pixel_stream(splitmix64(seed), pixel);
            assert_eq!(
                stream_uniform(stream, hyp, d).to_bits(),
                uniform(seed, pixel, hyp, d).to_bits()
            );
        }
    }

    #[test]
    fn probabilities_match_the_f64_softmax() {
        let points = Grid::from_fn(7, 7, |x, _| {
            if x == 2 {
                INVALID_POINT
            } else {
                Vec3::new(0.0, 0.0, 1.0)
            }
        });
        let cands = candidates(&points, 3, 3);
        let logits: [f32; CANDIDATES] = std::array::from_fn(|k| ((k * 37) % 23) as f32 - 11.5);
        let rho = candidate_probabilities(&logits, &cands);
        let valid = |k: usize| k % WINDOW != 2;
        let e: Vec<f64> = (0..CANDIDATES)
            .map(|k| {
                if valid(k) {
                    (f64::from(logits[k]) - 11.5).exp()
                } else {
                    0.0
                }
            })
            .collect();
        let total: f64 = e.iter().sum();
        for k in 0..CANDIDATES {
            approx::assert_relative_eq!(rho[k], e[k] / total, max_relative = 4e-7);
        }
    }

    #[test]
    fn non_finite_logits_get_no_probability() {
        let points = Grid::new(7, 7, Vec3::new(0.0, 0.0, 1.0));
        let mut logits = [1.0; CANDIDATES];
        logits[3] = f32::NAN;
        logits[4] = f32::INFINITY;
        let rho = candidate_probabilities(&logits, &candidates(&points, 3, 3));
        assert_eq!((rho[3], rho[4]), (0.0, 0.0));
        approx::assert_relative_eq!(rho[0], 1.0 / 47.0, max_relative = 1e-6);
        let none = candidate_probabilities(&[f32::NAN; CANDIDATES], &candidates(&points, 3, 3));
        assert!(none.iter().all(|&r| r == 0.0));
    }

    /// A bumpy surface seen from 1.5 m, with a 2 cm step along a diagonal and some holes.
    fn bumpy(w: usize, h: usize) -> PointMap {
        Grid::from_fn(w, h, |x, y| {
            let (u, v) = (x as f64 * 0.004, y as f64 * 0.004);
            let step = if x + y > w { 0.02 } else { 0.0 };
            let z = 1.5 + 0.3 * u + 0.006 * (x as f64 * 1.7).sin() * (y as f64 * 2.3).cos() + step;
            if (x * 7 + y * 3) % 17 == 0 {
                INVALID_POINT
            } else {
                Vec3::new(u - 0.1, v - 0.1, z)
            }
        })
    }

    #[test]
    fn f32_scores_match_the_f64_formula() {
        let points = bumpy(20, 20);
        let cfg = DsacConfig::default();
        let scorer = Scorer::new(&cfg);
        let cands = candidates(&points, 9, 11);
        let padded = PaddedPoints::of_candidates(&cands);
        let window = Window::new(&padded, RADIUS, RADIUS);
        for [a, b, c] in [[0, 24, 48], [3, 20, 40], [10, 11, 30], [6, 42, 24]] {
            let plane = Plane::through(&cands[a], &cands[b], &cands[c]).unwrap();
            let reference: f64 = cands
                .iter()
                .filter(|q| is_valid_point(q))
                .map(|q| cfg.soft_inlier(plane.distance(q)))
                .sum();
            let fast = f64::from(window.full_score(&window.hyp32(&plane, &scorer)));
            assert!((fast - reference).abs() < 2e-5, "{fast} vs {reference}");
        }
    }

    #[test]
    fn pixel_hypotheses_agree_with_dsac_normals() {
        // 19 columns: two whole groups of refits and a partial one.
        let (w, h) = (19, 12);
        let points = bumpy(w, h);
        let logits: Vec<f32> = (0..CANDIDATES * w * h)
            .map(|i| ((i * 2_654_435_761usize) % 1000) as f32 / 250.0)
            .collect();
        // One hypothesis, fewer than a batch, a batch, and two batches (pruning across them).
        for hypotheses in [1, 4, 12, 20] {
            let cfg = DsacConfig {
                seed: 5,
                hypotheses,
                ..Default::default()
            };
            check_pixels_against_frame(&points, &logits, &cfg);
        }
    }

    /// [`pixel_hypotheses`] against [`dsac_normals`] at every pixel of `points`.
    fn check_pixels_against_frame(points: &PointMap, logits: &[f32], cfg: &DsacConfig) {
        let (w, h) = points.size();
        let normals = dsac_normals(points, logits, cfg).unwrap();
        for (x, y) in (0..h).flat_map(|y| (0..w).map(move |x| (x, y))) {
            let i = y * w + x;
            let cands = candidates(points, x, y);
            let px_logits: [f32; CANDIDATES] = std::array::from_fn(|k| logits[k * w * h + i]);
            let rho = candidate_probabilities(&px_logits, &cands);
            let hyp = pixel_hypotheses(&cands, &rho, i as u64, cfg);
            assert_eq!(hyp.triples.len(), cfg.hypotheses as usize);
            let expected = match is_valid_point(&points[(x, y)]) {
                true => hyp.normal.unwrap_or(INVALID_POINT),
                false => INVALID_POINT,
            };
            let got = normals[(x, y)];
            let bits = |v: &Vec3| v.map(f64::to_bits);
            let k = cfg.hypotheses;
            assert_eq!(bits(&got), bits(&expected), "pixel ({x}, {y}), K = {k}");
            for (t, s) in hyp.triples.iter().zip(&hyp.scores) {
                assert_eq!(
                    t.is_some_and(|[a, b, c]| {
                        Plane::through(&cands[a], &cands[b], &cands[c]).is_some()
                    }),
                    *s > f64::NEG_INFINITY
                );
            }
        }
    }

    #[test]
    fn reused_buffers_give_the_same_normals_at_any_size() {
        let cfg = DsacConfig::default();
        let logits = |w: usize, h: usize| -> Vec<f32> {
            (0..CANDIDATES * w * h)
                .map(|i| ((i * 2_654_435_761) % 997) as f32 / 300.0)
                .collect()
        };
        let bits = |g: &Grid<Vec3>| -> Vec<[u64; 3]> {
            g.as_slice()
                .iter()
                .map(|v| [v.x, v.y, v.z].map(f64::to_bits))
                .collect()
        };
        let (mut scratch, mut out) = (DsacScratch::default(), Grid::default());
        // Larger, smaller, then larger again: stale values must never leak through.
        for (w, h) in [(20, 16), (9, 13), (23, 11)] {
            let (points, logits) = (bumpy(w, h), logits(w, h));
            dsac_normals_into(&points, &logits, &cfg, &mut scratch, &mut out).unwrap();
            let fresh = dsac_normals(&points, &logits, &cfg).unwrap();
            assert_eq!(out.size(), (w, h));
            assert_eq!(bits(&out), bits(&fresh), "{w}×{h}");
        }
    }

    #[test]
    fn fewer_hypotheses_are_the_first_ones_of_more() {
        let points = bumpy(12, 12);
        let cands = candidates(&points, 6, 6);
        let logits: [f32; CANDIDATES] = std::array::from_fn(|k| (k % 7) as f32 * 0.3);
        let rho = candidate_probabilities(&logits, &cands);
        let run = |hypotheses| {
            let cfg = DsacConfig {
                seed: 9,
                hypotheses,
                ..Default::default()
            };
            pixel_hypotheses(&cands, &rho, 77, &cfg)
        };
        let all = run(24);
        let best_score = |h: &PixelHypotheses| h.best.map(|j| h.scores[j]);
        let mut last_best = f64::NEG_INFINITY;
        for k in [1, 2, 4, 12, 13, 24] {
            let few = run(k);
            assert_eq!(few.triples[..], all.triples[..k as usize], "K = {k}");
            assert_eq!(few.scores[..], all.scores[..k as usize], "K = {k}");
            let best = best_score(&few).unwrap();
            assert!(best >= last_best, "K = {k}: {best} < {last_best}");
            last_best = best;
        }
        // The triples differ between hypotheses: more of them are more chances.
        assert!(all.triples.iter().any(|t| *t != all.triples[0]));
    }

    #[test]
    fn best_is_the_first_largest_score() {
        let points = bumpy(12, 12);
        let cands = candidates(&points, 6, 6);
        let rho = candidate_probabilities(&[0.0; CANDIDATES], &cands);
        let hyp = pixel_hypotheses(&cands, &rho, 3, &DsacConfig::default());
        let best = hyp.best.unwrap();
        let max = hyp.scores.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        assert_eq!(hyp.scores[best], max);
        assert!(hyp.scores[..best].iter().all(|&s| s < max));
    }
}
