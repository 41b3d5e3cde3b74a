//! The three-state map's figures for the real-frame benchmark: shares of traversable, hazard
//! and unknown pixels, overall, per range bin and for the checks of docs/design.md.

use super::*;

/// How the three-state map reads a frame (or pooled frames): shares of all pixels and per
/// range bin, and the three checks of docs/design.md: near floor traversable, far noisy range
/// unknown, drops hazards.
#[derive(Debug, Clone, Serialize)]
pub struct TraversalMetrics {
    /// Shares of every pixel of the frame (no depth: unknown).
    pub all: StateShares,
    /// Shares of the pixels with sensor depth in each range bin.
    pub by_range: BTreeMap<String, StateShares>,
    /// Median uncertainty (metres) of the pixels with depth in each range bin.
    pub median_uncertainty_m: BTreeMap<String, f64>,
    /// Floor-box pixels within 2 m: shares (when a floor box is given).
    pub near_floor: Option<StateShares>,
    /// Pixels beyond 4 m that the spec calls hazards (≥ 5 cm): shares.
    pub far_spec_rough: StateShares,
    /// Drops (spec ≥ 10 cm) within 4 m: shares.
    pub near_drops: StateShares,
}

/// Shares of traversable, hazard and unknown pixels in a set.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct StateShares {
    /// Pixels in the set.
    pub pixels: u64,
    /// Share traversable.
    pub traversable: f64,
    /// Share hazard.
    pub hazard: f64,
    /// Share unknown.
    pub unknown: f64,
}

/// Counts of the three states in a set of pixels.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct StateCounts([u64; 3]);

impl StateCounts {
    pub(super) fn add(&mut self, t: Traversal) {
        self.0[t as usize] += 1;
    }

    pub(super) fn merge(&mut self, o: &Self) {
        (0..3).for_each(|i| self.0[i] += o.0[i]);
    }

    fn shares(&self) -> StateShares {
        let n: u64 = self.0.iter().sum();
        let share = |k: Traversal| {
            if n == 0 {
                f64::NAN
            } else {
                self.0[k as usize] as f64 / n as f64
            }
        };
        StateShares {
            pixels: n,
            traversable: share(Traversal::Traversable),
            hazard: share(Traversal::Hazard),
            unknown: share(Traversal::Unknown),
        }
    }
}

/// Three-state accumulators of one configuration.
#[derive(Debug, Clone, Default)]
pub(super) struct TraversalAcc {
    all: StateCounts,
    by_range: [StateCounts; 3],
    uncertainty: [Vec<f64>; 3],
    near_floor: StateCounts,
    far_spec_rough: StateCounts,
    near_drops: StateCounts,
}

/// Spec roughness of a drop, metres.
pub(super) const DROP_M: f64 = 0.10;

impl TraversalAcc {
    /// Adds one frame's three-state and uncertainty maps.
    pub(super) fn add(
        &mut self,
        maps: &SensorMaps,
        loaded: &LoadedFrame,
        floor_box: Option<[usize; 4]>,
    ) {
        let Some(depth) = loaded.input.depth_m.as_ref() else {
            return;
        };
        let (w, _) = depth.size();
        let cells = maps.traversal.as_slice().iter().zip(depth.as_slice());
        let spec = loaded.spec.roughness_m.as_slice();
        let u = maps.uncertainty_m.as_slice();
        for (i, (&t, &z)) in cells.enumerate() {
            self.all.add(t);
            if let Some(b) = RANGE_BINS.iter().position(|&(_, a, b)| z >= a && z < b) {
                self.by_range[b].add(t);
                if u[i].is_finite() {
                    self.uncertainty[b].push(u[i]);
                }
            }
            if z >= 4.0 && spec[i] >= HAZARD_M {
                self.far_spec_rough.add(t);
            }
            if z > 0.0 && z < 4.0 && spec[i] >= DROP_M {
                self.near_drops.add(t);
            }
            let (x, y) = (i % w, i / w);
            let in_box = |[x0, y0, x1, y1]: [usize; 4]| x >= x0 && x < x1 && y >= y0 && y < y1;
            if z > 0.0 && z < 2.0 && floor_box.is_some_and(in_box) {
                self.near_floor.add(t);
            }
        }
    }

    pub(super) fn merge(&mut self, o: &Self) {
        self.all.merge(&o.all);
        for b in 0..3 {
            self.by_range[b].merge(&o.by_range[b]);
            self.uncertainty[b].extend_from_slice(&o.uncertainty[b]);
        }
        self.near_floor.merge(&o.near_floor);
        self.far_spec_rough.merge(&o.far_spec_rough);
        self.near_drops.merge(&o.near_drops);
    }

    pub(super) fn finish(&self, has_floor: bool) -> TraversalMetrics {
        let names = RANGE_BINS.iter().map(|&(n, _, _)| n.to_owned());
        TraversalMetrics {
            all: self.all.shares(),
            by_range: names
                .clone()
                .zip(self.by_range.iter().map(StateCounts::shares))
                .collect(),
            median_uncertainty_m: names
                .zip(self.uncertainty.iter().map(|u| median(u.clone())))
                .collect(),
            near_floor: has_floor.then(|| self.near_floor.shares()),
            far_spec_rough: self.far_spec_rough.shares(),
            near_drops: self.near_drops.shares(),
        }
    }
}
