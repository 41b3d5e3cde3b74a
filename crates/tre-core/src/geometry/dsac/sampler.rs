//! The sampler (module docs, step 3): the CDF of ρ without the drawn candidates, inverted by binary search in lockstep.

use super::*;

/// Bits `0..k` of a candidate mask.
#[inline]
pub(super) fn below(k: usize) -> u64 {
    (1u64 << k) - 1
}

/// The highest candidate in a mask, 0 for an empty one.
#[inline]
pub(super) fn highest_or_zero(mask: u64) -> usize {
    63 - (mask | 1).leading_zeros() as usize
}

/// The highest candidate in a mask.
#[inline]
pub(super) fn highest(mask: u64) -> Option<usize> {
    (mask != 0).then(|| highest_or_zero(mask))
}

/// A run of undrawn candidates from `start`: its candidates with probability (`inside`) and the
/// subtrahends of `F_d = (P − c1) − c2` there.
#[derive(Clone, Copy)]
pub(super) struct Run {
    pub(super) start: usize,
    pub(super) inside: u64,
    pub(super) c1: f64,
    pub(super) c2: f64,
}

impl Run {
    #[inline]
    pub(super) fn new(start: usize, inside: u64, c1: f64, c2: f64) -> Self {
        Self {
            start,
            inside,
            c1,
            c2,
        }
    }

    /// `F_d` of a prefix sum in this run.
    #[inline]
    pub(super) fn f(&self, prefix: f64) -> f64 {
        (prefix - self.c1) - self.c2
    }
}

/// ρ prepared for sampling: module docs, step 3.
pub(super) struct Cdf {
    /// ρ_k (0 past the 49th).
    pub(super) rho: [f64; TABLE],
    /// P_k (P_48 past the 49th).
    pub(super) prefix: [f64; TABLE],
    /// Bit k set when ρ_k > 0.
    pub(super) nonzero: u64,
    /// ρ finite and non-negative, so that the prefix sums are monotone and the search applies.
    pub(super) monotone: bool,
}

impl Cdf {
    /// The sampler's view of any ρ.
    pub(super) fn new(rho: &[f64; CANDIDATES]) -> Self {
        let mut table = [0.0; TABLE];
        table[..CANDIDATES].copy_from_slice(rho);
        let monotone = rho.iter().all(|&r| r >= 0.0 && r.is_finite());
        let nonzero = (0..CANDIDATES).fold(0, |m, k| m | (u64::from(rho[k] > 0.0) << k));
        Self::with_prefix(table, nonzero, monotone)
    }

    /// The sampler's view of ρ as [`softmax`] returns it: finite and non-negative.
    #[inline(always)]
    pub(super) fn from_softmax(rho32: &[f32; LANES]) -> Self {
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
    pub(super) fn with_prefix(rho: [f64; TABLE], nonzero: u64, monotone: bool) -> Self {
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
    pub(super) fn triple(&self, stream: u64, hypothesis: u32) -> Option<[usize; 3]> {
        self.triples(stream, hypothesis, 1)[0]
    }

    /// The triples of hypotheses `first..first + count` (`count ≤ BATCH`), drawn stage by stage
    /// (every first draw, then every second one, …) and with their binary searches in
    /// lockstep, so that the hypotheses' independent searches overlap in the processor.
    #[inline(always)]
    pub(super) fn triples(
        &self,
        stream: u64,
        first: u32,
        count: usize,
    ) -> [Option<[usize; 3]>; BATCH] {
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
        from_fn(|j| alive[j].then_some(drawn[j]))
    }

    /// The draw for `t`, given the candidates already drawn: settled, or a search to run.
    #[inline(always)]
    pub(super) fn plan(&self, t: f64, drawn: &[usize]) -> Draw {
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
    pub(super) fn plan_in_runs<const N: usize>(&self, t: f64, runs: [Run; N]) -> Draw {
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
    pub(super) fn pick_by_scan(&self, t: f64, drawn: &[usize]) -> Option<usize> {
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
pub(super) const SEARCH_STEPS: usize = 6;

/// One draw in progress: settled, or a branch-free binary search (a lower bound after Khuong
/// and Morin) for the first `k` in `base..base + n` of a run with `t < F(k)` (which exists),
/// followed by a step to the run's next candidate with probability.
#[derive(Clone, Copy)]
pub(super) struct Draw {
    pub(super) t: f64,
    pub(super) run: Run,
    pub(super) base: usize,
    pub(super) n: usize,
    /// `Some(answer)` when known without a search.
    pub(super) settled: Option<Option<usize>>,
}

impl Draw {
    pub(super) fn settled(answer: Option<usize>) -> Self {
        Self {
            t: 0.0,
            run: Run::new(0, 0, 0.0, 0.0),
            base: 0,
            n: 1,
            settled: Some(answer),
        }
    }

    /// A search of `run.start..=last`, given `t < F(last)`.
    pub(super) fn search(t: f64, run: Run, last: usize) -> Self {
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
    pub(super) fn fails(&self, prefix: &[f64; TABLE], k: usize) -> bool {
        !(self.t < self.run.f(prefix[k % TABLE]))
    }

    /// One halving of the search range (a no-op once it holds one candidate).
    #[inline(always)]
    pub(super) fn step(&mut self, prefix: &[f64; TABLE]) {
        let half = self.n / 2;
        let probe = self.base + half;
        self.base = select_unpredictable(self.fails(prefix, probe), probe, self.base);
        self.n -= half;
    }

    /// The drawn candidate, after [`SEARCH_STEPS`] steps.
    #[inline(always)]
    pub(super) fn finish(&self, prefix: &[f64; TABLE]) -> Option<usize> {
        if let Some(answer) = self.settled {
            return answer;
        }
        let k = self.base + usize::from(self.fails(prefix, self.base));
        Some(k + (self.run.inside >> k).trailing_zeros() as usize)
    }
}
