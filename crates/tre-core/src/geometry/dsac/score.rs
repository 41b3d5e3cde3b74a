//! Scoring (module docs, steps 2 and 4): ρ from the logits, the f32 soft inlier scorer, the best hypothesis of a pixel with pruning.

use super::*;

/// A hypothesis' triple and score, as [`pixel_hypotheses`] records them.
pub(super) type Record<'r> = &'r mut dyn FnMut(Option<[usize; 3]>, f32);

/// Samples and scores `cfg.hypotheses` hypotheses in batches; returns the index and plane of
/// the best one (first of the largest scores). With `record`, every triple and score is passed
/// to it; without, each batch scores first the hypothesis that leads after
/// [`LEAD_BLOCKS`] blocks, then the others only as long as they might still beat the best
/// ([`Window::finish_above`]), which leaves the answer unchanged.
#[inline(always)]
pub(super) fn best_hypothesis(
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
        // A loop, not `from_fn`: the planes and their f32 forms must inline into each compiled
        // version of the row kernel (see `Frame::group_normals`).
        let mut hyps: [Option<(Plane, Hyp32)>; BATCH] = [None; BATCH];
        for (hyp, triple) in hyps.iter_mut().zip(triples) {
            let Some([a, b, c]) = triple else { continue };
            let plane = Plane::through(&window.point(a), &window.point(b), &window.point(c));
            *hyp = plane.map(|plane| (plane, window.hyp32(&plane, &scorer)));
        }
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
#[inline(always)]
pub(super) fn best_of_batch(
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
pub(super) struct Best {
    pub(super) found: Option<(usize, f32, Plane)>,
}

impl Best {
    /// Its score (−∞ before any).
    pub(super) fn score(&self) -> f32 {
        self.found.map_or(f32::NEG_INFINITY, |(_, s, _)| s)
    }

    /// Keeps hypothesis `j` if it scores more, or as much with a smaller index.
    pub(super) fn offer(&mut self, j: usize, score: f32, plane: Plane) {
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
pub(super) struct Hyp32 {
    pub(super) n: [f32; 3],
    pub(super) o: f32,
    pub(super) tau: f32,
}

/// Blocks scored for every hypothesis of a batch before the leading one is finished.
pub(super) const LEAD_BLOCKS: usize = 2;

/// The constants of the f32 soft inlier score (module docs, step 4).
pub(super) struct Scorer {
    /// β · log₂e, f64.
    pub(super) gain: f64,
    /// `f32(min(β · log₂e · τ, 120))`.
    pub(super) tau: f32,
    /// An upper bound of one candidate's soft inlier value: the value at distance 0,
    /// `recip_one_plus_exp2(−τ″)`, raised by 4e-6 (relative). `y = |s| − τ″ ≥ −τ″` for every
    /// candidate, 1/(1 + 2ʸ) decreases, and the approximation is within 7e-7 (relative) of it,
    /// so no candidate adds more.
    pub(super) most: f32,
}

impl Scorer {
    pub(super) fn new(cfg: &DsacConfig) -> Self {
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
#[inline(always)]
pub(super) fn softmax(logits: &[f32; LANES], valid: &[u32; LANES]) -> [f32; LANES] {
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
pub(super) fn lane_sum(v: &[f32; LANES]) -> f32 {
    let mut acc = [0.0; BLOCK];
    for b in 0..BLOCKS {
        for (l, a) in acc.iter_mut().enumerate() {
            *a += v[b * BLOCK + l];
        }
    }
    sum_block(acc)
}
