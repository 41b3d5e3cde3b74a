//! What a robot needs from a roughness map, scored against the spec on the same depth: edge
//! recall (spec hazards read as hazards), false hazards (flat ground read as a hazard), floor
//! roughness, all of it split by range since a depth sensor's error grows with it.

use serde::Serialize;

use super::metrics::{RoughnessAccumulator, RoughnessMetrics};
use super::RoughnessError;
use crate::geometry::Grid;

/// Roughness at or above which a pixel is a hazard, metres (the default robot threshold, 5 cm).
pub const HAZARD_M: f64 = 0.05;
/// Spec roughness below which a pixel counts as flat for the false-hazard rate, metres (1 cm).
pub const FLAT_M: f64 = 0.01;

/// The range bins, by sensor depth: `(name, from_m, to_m)`, from inclusive, to exclusive.
pub const RANGE_BINS: [(&str, f64, f64); 3] = [
    ("0_2m", 0.0, 2.0),
    ("2_4m", 2.0, 4.0),
    ("4m_up", 4.0, f64::INFINITY),
];

/// Pooled edge recall and false hazards over frames.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct HazardAccumulator {
    edges: u64,
    edges_found: u64,
    flat: u64,
    flat_as_hazard: u64,
}

/// Edge recall and false-hazard rate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct HazardMetrics {
    /// Of the pixels the spec calls hazards (≥ 5 cm), the share the prediction calls hazards
    /// too (a pixel without prediction is a miss); NaN when there are none.
    pub edge_recall: f64,
    /// Of the pixels the spec calls flat (< 1 cm), the share the prediction calls hazards;
    /// NaN when there are none.
    pub false_hazards: f64,
    /// Spec hazard pixels.
    pub edges: u64,
    /// Spec flat pixels.
    pub flat: u64,
}

impl HazardAccumulator {
    /// Adds one pixel: predicted and spec roughness, metres (NaN: none).
    pub fn add_pixel(&mut self, pred_m: f64, spec_m: f64) {
        let hazard = pred_m >= HAZARD_M;
        if spec_m >= HAZARD_M {
            self.edges += 1;
            self.edges_found += u64::from(hazard);
        } else if spec_m < FLAT_M {
            self.flat += 1;
            self.flat_as_hazard += u64::from(hazard);
        }
    }

    /// Adds another accumulator's counts.
    pub fn merge(&mut self, other: &Self) {
        self.edges += other.edges;
        self.edges_found += other.edges_found;
        self.flat += other.flat;
        self.flat_as_hazard += other.flat_as_hazard;
    }

    /// The rates so far.
    ///
    /// ```
    /// use tre_core::roughness::hazard::HazardAccumulator;
    /// let mut h = HazardAccumulator::default();
    /// h.add_pixel(0.12, 0.10); // a drop, found
    /// h.add_pixel(f64::NAN, 0.08); // a drop, no prediction: missed
    /// h.add_pixel(0.06, 0.001); // flat read as a hazard
    /// h.add_pixel(0.002, 0.0); // flat read as flat
    /// let m = h.finish();
    /// assert_eq!((m.edge_recall, m.false_hazards), (0.5, 0.5));
    /// ```
    pub fn finish(&self) -> HazardMetrics {
        HazardMetrics {
            edge_recall: rate(self.edges_found, self.edges),
            false_hazards: rate(self.flat_as_hazard, self.flat),
            edges: self.edges,
            flat: self.flat,
        }
    }
}

/// `k` of `n` as a share; NaN when `n` is 0 (no pixel of that kind: no rate, not 0%).
pub fn rate(k: u64, n: u64) -> f64 {
    if n == 0 {
        f64::NAN
    } else {
        k as f64 / n as f64
    }
}

/// Roughness errors and hazard rates of one set of pixels.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Scores {
    /// RMSE, B-RMSE and F-RMSE against the spec.
    pub roughness: RoughnessAccumulator,
    /// Edge recall and false hazards.
    pub hazard: HazardAccumulator,
}

/// [`Scores`] as numbers.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ScoreMetrics {
    /// Roughness errors against the spec, cm.
    pub roughness: RoughnessMetrics,
    /// Edge recall and false hazards.
    #[serde(flatten)]
    pub hazard: HazardMetrics,
}

impl Scores {
    /// Adds another set's counts.
    pub fn merge(&mut self, other: &Self) {
        self.roughness.merge(&other.roughness);
        self.hazard.merge(&other.hazard);
    }

    /// The metrics so far.
    pub fn finish(&self) -> ScoreMetrics {
        ScoreMetrics {
            roughness: self.roughness.finish(),
            hazard: self.hazard.finish(),
        }
    }
}

/// Scores of one frame (or pooled frames): over all pixels and per range bin.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RangeScores {
    /// Every pixel with spec roughness.
    pub all: Scores,
    /// Per [`RANGE_BINS`] entry.
    pub by_range: [Scores; 3],
}

impl RangeScores {
    /// Adds one frame: prediction and spec roughness (metres, NaN: none), the spec's boundary
    /// mask and the sensor depth that bins the pixels by range.
    ///
    /// # Errors
    ///
    /// [`RoughnessError::SizeMismatch`] when the maps differ in size.
    pub fn add(
        &mut self,
        pred_m: &Grid<f64>,
        spec_m: &Grid<f64>,
        boundary: &Grid<bool>,
        depth_m: &Grid<f64>,
    ) -> Result<(), RoughnessError> {
        self.all.roughness.add(pred_m, spec_m, boundary)?;
        for (bin, &(_, from, to)) in self.by_range.iter_mut().zip(&RANGE_BINS) {
            let in_bin = depth_m.map(|&z| z >= from && z < to);
            let masked = |g: &Grid<f64>| {
                let mut g = g.clone();
                let keep = in_bin.as_slice().iter();
                g.as_mut_slice().iter_mut().zip(keep).for_each(|(v, &k)| {
                    if !k {
                        *v = f64::NAN;
                    }
                });
                g
            };
            bin.roughness.add(pred_m, &masked(spec_m), boundary)?;
        }
        let cells = pred_m.as_slice().iter().zip(spec_m.as_slice());
        for ((&p, &s), &z) in cells.zip(depth_m.as_slice()) {
            if !s.is_finite() {
                continue;
            }
            self.all.hazard.add_pixel(p, s);
            if let Some(i) = RANGE_BINS.iter().position(|&(_, a, b)| z >= a && z < b) {
                self.by_range[i].hazard.add_pixel(p, s);
            }
        }
        Ok(())
    }

    /// Adds another frame's scores.
    pub fn merge(&mut self, other: &Self) {
        self.all.merge(&other.all);
        for (a, b) in self.by_range.iter_mut().zip(&other.by_range) {
            a.merge(b);
        }
    }
}

/// Median and 90th percentile of a set of roughness values, cm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FloorStats {
    /// Median, cm.
    pub median_cm: f64,
    /// 90th percentile, cm.
    pub p90_cm: f64,
    /// Pixels with roughness in the box.
    pub pixels: usize,
    /// Pixels of the box without roughness.
    pub missing: usize,
}

/// The roughness values (metres) inside the box `[x0, y0, x1, y1)` (end exclusive, clipped to
/// the map), and how many of its pixels have none.
pub fn box_values(map_m: &Grid<f64>, [x0, y0, x1, y1]: [usize; 4]) -> (Vec<f64>, usize) {
    let (w, h) = map_m.size();
    let (mut values, mut missing) = (Vec::new(), 0);
    for y in y0.min(h)..y1.min(h) {
        for &v in &map_m.row(y)[x0.min(w)..x1.min(w)] {
            if v.is_finite() {
                values.push(v);
            } else {
                missing += 1;
            }
        }
    }
    (values, missing)
}

/// Median and p90 (nearest rank) of `values_m` in cm; NaN for an empty set.
///
/// ```
/// use tre_core::roughness::hazard::floor_stats;
/// let s = floor_stats((1..=10).map(|i| f64::from(i) / 100.0).collect(), 0);
/// assert_eq!((s.median_cm, s.p90_cm, s.pixels), (5.0, 9.0, 10));
/// ```
pub fn floor_stats(mut values_m: Vec<f64>, missing: usize) -> FloorStats {
    values_m.sort_by(f64::total_cmp);
    let rank = |q: f64| {
        let n = values_m.len();
        if n == 0 {
            return f64::NAN;
        }
        let i = ((q * n as f64).ceil() as usize).clamp(1, n) - 1;
        100.0 * values_m[i]
    };
    FloorStats {
        median_cm: rank(0.5),
        p90_cm: rank(0.9),
        pixels: values_m.len(),
        missing,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn range_bins_split_pixels_by_sensor_depth() {
        // Four pixels at 1, 3, 5 m and one without depth; a drop at 3 m missed, flat elsewhere.
        let spec = Grid::from_vec(4, 1, vec![0.0, 0.1, 0.002, f64::NAN]).unwrap();
        let pred = Grid::from_vec(4, 1, vec![0.06, 0.01, 0.0, 0.0]).unwrap();
        let depth = Grid::from_vec(4, 1, vec![1.0, 3.0, 5.0, 0.0]).unwrap();
        let boundary = Grid::from_vec(4, 1, vec![false, true, false, false]).unwrap();
        let mut s = RangeScores::default();
        s.add(&pred, &spec, &boundary, &depth).unwrap();
        let all = s.all.finish();
        assert_eq!((all.hazard.edges, all.hazard.flat), (1, 2));
        assert_eq!(all.hazard.edge_recall, 0.0);
        assert_eq!(all.hazard.false_hazards, 0.5);
        let near = s.by_range[0].finish();
        assert_eq!((near.hazard.flat, near.hazard.false_hazards), (1, 1.0));
        assert_eq!(near.roughness.pixels, 1);
        let mid = s.by_range[1].finish();
        assert_eq!((mid.hazard.edges, mid.roughness.pixels), (1, 1));
        assert!((mid.roughness.b_rmse_cm - 9.0).abs() < 1e-9);
        let far = s.by_range[2].finish();
        assert_eq!((far.hazard.false_hazards, far.roughness.pixels), (0.0, 1));
        let mut pooled = RangeScores::default();
        pooled.merge(&s);
        pooled.merge(&s);
        assert_eq!(pooled.all.finish().hazard.edges, 2);
    }

    #[test]
    fn box_values_clip_to_the_map_and_count_holes() {
        let g = Grid::from_fn(4, 3, |x, y| if x == y { f64::NAN } else { 0.01 });
        let (v, missing) = box_values(&g, [1, 1, 10, 10]);
        assert_eq!((v.len(), missing), (4, 2));
    }
}
