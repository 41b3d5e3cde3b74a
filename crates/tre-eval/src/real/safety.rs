//! The safety figures of a three-state map (issue: "a learned mode must say unknown, never
//! flat, where it cannot see"): *missed hazards* (spec ≥ 5 cm read traversable), *floor
//! coverage* (spec < 1 cm within 3 m read traversable) and the *interval coverage* (share of
//! pixels whose target lies inside the stated 90% interval), pooled and by range of the sensor
//! depth.

use super::*;
use tre_core::roughness::hazard::rate;

/// Floor coverage counts flat pixels nearer than this, metres.
pub(super) const FLOOR_RANGE_M: f64 = 3.0;

/// One set's safety figures.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct SafetyFigures {
    /// Pixels the spec calls hazards (≥ 5 cm).
    pub hazard_px: u64,
    /// Share of them read traversable.
    pub missed_hazards: f64,
    /// Pixels the spec calls flat (< 1 cm); pooled: within 3 m only.
    pub flat_px: u64,
    /// Share of them read traversable.
    pub floor_coverage: f64,
    /// Pixels with an interval and a target.
    pub interval_px: u64,
    /// Share of them whose target lies inside the interval.
    pub interval_coverage: f64,
}

/// A configuration's safety figures, pooled and per range bin.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Safety {
    /// Every pixel with depth (floor coverage: within 3 m).
    pub all: SafetyFigures,
    /// Per range bin of the sensor depth (floor coverage: the whole bin).
    pub by_range: BTreeMap<String, SafetyFigures>,
    /// What the interval is checked against: `same depth` (the spec on the frame's own depth)
    /// or `another view` (the spec of the same surface in the next frame of a sequence with
    /// poses).
    pub coverage_target: String,
}

/// Counts behind [`SafetyFigures`].
#[derive(Debug, Clone, Copy, Default)]
struct Counts {
    hazards: u64,
    missed: u64,
    flat: u64,
    flat_traversable: u64,
    covered: u64,
    inside: u64,
}

impl Counts {
    fn merge(&mut self, o: &Self) {
        self.hazards += o.hazards;
        self.missed += o.missed;
        self.flat += o.flat;
        self.flat_traversable += o.flat_traversable;
        self.covered += o.covered;
        self.inside += o.inside;
    }

    fn figures(&self) -> SafetyFigures {
        SafetyFigures {
            hazard_px: self.hazards,
            missed_hazards: rate(self.missed, self.hazards),
            flat_px: self.flat,
            floor_coverage: rate(self.flat_traversable, self.flat),
            interval_px: self.covered,
            interval_coverage: rate(self.inside, self.covered),
        }
    }
}

/// Safety accumulators of one configuration.
#[derive(Debug, Clone, Default)]
pub struct SafetyAcc {
    all: Counts,
    by_range: [Counts; 3],
    target: Option<&'static str>,
}

/// The range bin of depth `z`.
fn range_bin(z: f64) -> Option<usize> {
    RANGE_BINS
        .iter()
        .position(|&(_, a, b)| z > 0.0 && z >= a && z < b)
}

impl SafetyAcc {
    /// Adds a frame's three-state map against the spec on its depth.
    pub fn add_states(&mut self, traversal: &Grid<Traversal>, spec: &Grid<f64>, depth: &Grid<f64>) {
        let cells = traversal.as_slice().iter().zip(spec.as_slice());
        for ((&t, &s), &z) in cells.zip(depth.as_slice()) {
            let Some(b) = range_bin(z).filter(|_| s.is_finite()) else {
                continue;
            };
            let go = u64::from(t == Traversal::Traversable);
            for (c, counts_flat) in [
                (&mut self.all, z < FLOOR_RANGE_M),
                (&mut self.by_range[b], true),
            ] {
                if s >= HAZARD_M {
                    c.hazards += 1;
                    c.missed += go;
                }
                if s < FLAT_M && counts_flat {
                    c.flat += 1;
                    c.flat_traversable += go;
                }
            }
        }
    }

    /// Adds interval checks: `(pixel, target)` pairs against the interval maps; `z` the
    /// sensor depth; `what`: the target's name.
    pub fn add_coverage(
        &mut self,
        (lo, hi): (&Grid<f64>, &Grid<f64>),
        targets: impl Iterator<Item = (usize, f64)>,
        depth: &Grid<f64>,
        what: &'static str,
    ) {
        self.target = Some(what);
        for (i, target) in targets {
            let (l, h, z) = (lo.as_slice()[i], hi.as_slice()[i], depth.as_slice()[i]);
            let Some(b) = range_bin(z) else { continue };
            if !(l.is_finite() && h.is_finite() && target.is_finite()) {
                continue;
            }
            let inside = u64::from(target >= l && target <= h);
            for c in [&mut self.all, &mut self.by_range[b]] {
                c.covered += 1;
                c.inside += inside;
            }
        }
    }

    /// Pools another accumulator into this one.
    pub fn merge(&mut self, o: &Self) {
        self.all.merge(&o.all);
        (0..3).for_each(|b| self.by_range[b].merge(&o.by_range[b]));
        self.target = self.target.or(o.target);
    }

    /// The figures.
    pub fn finish(&self) -> Safety {
        Safety {
            all: self.all.figures(),
            by_range: RANGE_BINS
                .iter()
                .zip(&self.by_range)
                .map(|(&(n, _, _), c)| (n.to_owned(), c.figures()))
                .collect(),
            coverage_target: self.target.unwrap_or("none").to_owned(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missed_step_and_a_covered_floor_count_where_they_should() {
        use Traversal::{Hazard, Traversable, Unknown};
        let states = Grid::from_fn(4, 1, |x, _| [Traversable, Traversable, Hazard, Unknown][x]);
        let spec = Grid::from_fn(4, 1, |x, _| [0.06, 0.002, 0.08, 0.003][x]);
        let depth = Grid::from_fn(4, 1, |x, _| [1.0, 1.0, 2.5, 3.5][x]);
        let mut acc = SafetyAcc::default();
        acc.add_states(&states, &spec, &depth);
        let lo = Grid::new(4, 1, 0.0);
        let hi = Grid::new(4, 1, 0.05);
        acc.add_coverage(
            (&lo, &hi),
            spec.as_slice().iter().copied().enumerate(),
            &depth,
            "same depth",
        );
        let f = acc.finish();
        assert_eq!((f.all.hazard_px, f.all.missed_hazards), (2, 0.5));
        // The flat pixel at 3.5 m is beyond the pooled floor range, not beyond its bin's.
        assert_eq!((f.all.flat_px, f.all.floor_coverage), (1, 1.0));
        assert_eq!(f.by_range["2_4m"].flat_px, 1);
        assert_eq!(f.by_range["2_4m"].floor_coverage, 0.0);
        assert_eq!((f.all.interval_px, f.all.interval_coverage), (4, 0.5));
        assert_eq!(f.coverage_target, "same depth");
    }
}
