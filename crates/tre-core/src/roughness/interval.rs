//! Calibrated roughness intervals: for every pixel a 90% interval `[lo, hi]` on the value the
//! annotation spec gives there, and the three-state map that reads it (traversable only where
//! `hi` is below the threshold, hazard only where `lo` is above it, unknown otherwise).
//!
//! An [`IntervalTable`] is a conformal quantile table: pixels are binned by two features, the
//! largest reading within a few pixels (a learned mode that reads a step 2 px off, or misses
//! a thin one next to a rough reading, is caught by its neighbours) and either the sensor
//! model's uncertainty (`u`, modes that read sensor depth) or the depth (`z`, the `rgb` mode's
//! predicted depth). In each bin the table holds the 5th and 95th percentiles of
//! `target − reading` over real calibration frames, so the interval is
//! `[max(0, r + q05), r + q95]`. Bins with too few samples take their row's (same reading bin,
//! every second-axis bin) percentiles, and then the whole table's. The targets: for the
//! learned modes, the spec on the same sensor depth; for `geometric` (which is the spec), the
//! spec of the same surface seen from another pose of a real sequence, so that its interval
//! states what noise does to the spec between views. `tre calibrate` writes the tables
//! (`models/uncertainty.json`); docs/uncertainty.md has the method and the figures.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::traversal::Traversal;
use crate::geometry::Grid;

/// The interval's coverage the tables are fitted for.
pub const COVERAGE: f64 = 0.9;
/// Fewest samples a bin needs to use its own percentiles.
pub const MIN_BIN_SAMPLES: usize = 400;
/// Half-width of the window of the reading feature (7×7 pixels at the output size).
pub const FEATURE_RADIUS_PX: usize = 3;

/// Edges of the reading feature's bins, metres (the last bin is open).
pub const READING_EDGES_M: [f64; 10] = [0.0, 0.005, 0.01, 0.02, 0.035, 0.05, 0.075, 0.1, 0.2, 0.5];
/// Edges of the uncertainty axis, metres.
pub const UNCERTAINTY_EDGES_M: [f64; 8] = [0.0, 0.0025, 0.005, 0.01, 0.02, 0.04, 0.08, 0.16];
/// Edges of the depth axis, metres.
pub const DEPTH_EDGES_M: [f64; 9] = [0.0, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 10.0, 20.0];

/// The second feature of a table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SecondAxis {
    /// The sensor model's uncertainty map, metres.
    Uncertainty,
    /// Depth, metres (predicted depth for `rgb`).
    Depth,
}

impl SecondAxis {
    /// The bin edges of this axis.
    pub fn edges(self) -> &'static [f64] {
        match self {
            Self::Uncertainty => &UNCERTAINTY_EDGES_M,
            Self::Depth => &DEPTH_EDGES_M,
        }
    }
}

/// The first feature of a table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FirstAxis {
    /// The largest reading within [`FEATURE_RADIUS_PX`].
    #[default]
    Reading,
    /// The larger of that and the largest depth step (metres between 8-neighbours of the
    /// mode's depth) within the same window: a learned mode that reads a step flat is still
    /// binned with the steps, since its depth shows the step.
    ReadingOrStep,
}

/// One calibration sample: the reading feature, the second feature, the reading itself and
/// the target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Largest reading within [`FEATURE_RADIUS_PX`], metres.
    pub feature_m: f64,
    /// The second feature (uncertainty or depth), metres.
    pub second: f64,
    /// The pixel's reading, metres.
    pub reading_m: f64,
    /// The value the interval must hold, metres.
    pub target_m: f64,
}

/// A conformal quantile table (the module's documentation).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IntervalTable {
    /// The first feature.
    #[serde(default)]
    pub first_axis: FirstAxis,
    /// The second feature.
    pub second_axis: SecondAxis,
    /// Coverage of the percentiles taken (0.9, or more where `tre calibrate` found that 90%
    /// held out of the calibration blocks needed it).
    pub coverage: f64,
    /// Per bin, row-major (reading bins × second-axis bins): lower offset, metres.
    pub lo_m: Vec<f64>,
    /// Per bin: upper offset, metres.
    pub hi_m: Vec<f64>,
    /// Per bin: calibration samples that fell in it.
    pub samples: Vec<u64>,
    /// Per bin: whether the offsets are the bin's own (else its row's or the table's).
    pub own: Vec<bool>,
}

/// The bin of `v` among `edges` (values past the last edge fall in the last bin).
fn bin(edges: &[f64], v: f64) -> usize {
    edges.iter().rposition(|&e| v >= e).unwrap_or(0)
}

/// The `q` quantile of `v` (sorted in place); NaN for none.
fn quantile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_unstable_by(f64::total_cmp);
    let i = ((v.len() - 1) as f64 * q).round() as usize;
    v[i]
}

impl IntervalTable {
    /// Fits the table to `samples` (the module's documentation). `None` when there are fewer
    /// than [`MIN_BIN_SAMPLES`] samples in all.
    pub fn fit(axes: (FirstAxis, SecondAxis), samples: &[Sample]) -> Option<Self> {
        Self::fit_level(axes, samples, COVERAGE)
    }

    /// [`IntervalTable::fit`] with the percentiles of `level` (the `(1 − level)/2` and
    /// `(1 + level)/2` quantiles) instead of 90%.
    pub fn fit_level(
        axes: (FirstAxis, SecondAxis),
        samples: &[Sample],
        level: f64,
    ) -> Option<Self> {
        let (first_axis, second_axis) = axes;
        if samples.len() < MIN_BIN_SAMPLES {
            return None;
        }
        let (nr, ns) = (READING_EDGES_M.len(), second_axis.edges().len());
        let mut bins: Vec<Vec<f64>> = vec![Vec::new(); nr * ns];
        for s in samples {
            let i = bin(&READING_EDGES_M, s.feature_m) * ns + bin(second_axis.edges(), s.second);
            bins[i].push(s.target_m - s.reading_m);
        }
        let tail = (1.0 - level) / 2.0;
        let bounds = |v: &mut Vec<f64>| (quantile(v, tail), quantile(v, 1.0 - tail));
        let mut all: Vec<f64> = bins.iter().flatten().copied().collect();
        let whole = bounds(&mut all);
        let mut table = Self {
            first_axis,
            second_axis,
            coverage: level,
            lo_m: vec![whole.0; nr * ns],
            hi_m: vec![whole.1; nr * ns],
            samples: bins.iter().map(|b| b.len() as u64).collect(),
            own: vec![false; nr * ns],
        };
        for r in 0..nr {
            let mut row: Vec<f64> = bins[r * ns..(r + 1) * ns]
                .iter()
                .flatten()
                .copied()
                .collect();
            let row_bounds = (row.len() >= MIN_BIN_SAMPLES).then(|| bounds(&mut row));
            for s in 0..ns {
                let i = r * ns + s;
                let own = bins[i].len() >= MIN_BIN_SAMPLES;
                let b = if own {
                    Some(bounds(&mut bins[i]))
                } else {
                    row_bounds
                };
                if let Some((lo, hi)) = b {
                    (table.lo_m[i], table.hi_m[i]) = (lo, hi);
                }
                table.own[i] = own;
            }
        }
        Some(table)
    }

    /// The interval of one pixel: reading `r`, its feature and its second feature. NaN `r`:
    /// `(NaN, NaN)`.
    pub fn interval(&self, r: f64, feature_m: f64, second: f64) -> (f64, f64) {
        if !r.is_finite() {
            return (f64::NAN, f64::NAN);
        }
        let ns = self.second_axis.edges().len();
        let second = if second.is_finite() { second } else { f64::MAX };
        let i =
            bin(&READING_EDGES_M, feature_m.max(r)) * ns + bin(self.second_axis.edges(), second);
        match (self.lo_m.get(i), self.hi_m.get(i)) {
            (Some(lo), Some(hi)) => ((r + lo).max(0.0), (r + hi).max(0.0)),
            _ => (f64::NAN, f64::NAN),
        }
    }

    /// The first feature of a roughness map: its [`local_max`], or with
    /// [`FirstAxis::ReadingOrStep`] the larger of that and the local maximum of `depth_m`'s
    /// [`depth_steps`].
    pub fn feature(&self, roughness_m: &Grid<f64>, depth_m: &Grid<f64>) -> Grid<f64> {
        feature_map(self.first_axis, roughness_m, depth_m)
    }

    /// The share of `samples` whose target lies inside its interval.
    pub fn coverage_of(&self, samples: &[Sample]) -> f64 {
        let inside = samples
            .iter()
            .filter(|s| {
                let (lo, hi) = self.interval(s.reading_m, s.feature_m, s.second);
                s.target_m >= lo && s.target_m <= hi
            })
            .count();
        inside as f64 / samples.len().max(1) as f64
    }

    /// The interval maps of a roughness map, its first feature ([`IntervalTable::feature`])
    /// and its second (same sizes).
    pub fn maps(
        &self,
        roughness_m: &Grid<f64>,
        feature: &Grid<f64>,
        second: &Grid<f64>,
    ) -> (Grid<f64>, Grid<f64>) {
        let (w, h) = roughness_m.size();
        let mut lo = Grid::new(w, h, f64::NAN);
        let mut hi = Grid::new(w, h, f64::NAN);
        lo.as_mut_slice()
            .par_iter_mut()
            .zip(hi.as_mut_slice().par_iter_mut())
            .enumerate()
            .for_each(|(i, (l, u))| {
                let r = roughness_m.as_slice()[i];
                (*l, *u) = self.interval(r, feature.as_slice()[i], second.as_slice()[i]);
            });
        (lo, hi)
    }
}

/// The first feature of `kind` (see [`IntervalTable::feature`]).
pub fn feature_map(kind: FirstAxis, roughness_m: &Grid<f64>, depth_m: &Grid<f64>) -> Grid<f64> {
    let mut f = local_max(roughness_m, FEATURE_RADIUS_PX);
    if kind == FirstAxis::ReadingOrStep && depth_m.size() == roughness_m.size() {
        let steps = local_max(&depth_steps(depth_m), FEATURE_RADIUS_PX);
        for (v, s) in f.as_mut_slice().iter_mut().zip(steps.as_slice()) {
            if s.is_finite() && (v.is_nan() || *s > *v) {
                *v = *s;
            }
        }
    }
    f
}

/// At each pixel with depth, the largest depth difference to an 8-neighbour with depth,
/// metres (NaN without depth; 0 with no neighbour).
pub fn depth_steps(depth_m: &Grid<f64>) -> Grid<f64> {
    let (w, h) = depth_m.size();
    let ok = |z: f64| z.is_finite() && z > 0.0;
    Grid::from_fn(w, h, |x, y| {
        let z = depth_m[(x, y)];
        if !ok(z) {
            return f64::NAN;
        }
        let mut m: f64 = 0.0;
        for yy in y.saturating_sub(1)..(y + 2).min(h) {
            for xx in x.saturating_sub(1)..(x + 2).min(w) {
                let n = depth_m[(xx, yy)];
                if ok(n) {
                    m = m.max((n - z).abs());
                }
            }
        }
        m
    })
}

/// The largest finite value within `radius` pixels (a square window); NaN where the window has
/// none.
pub fn local_max(map: &Grid<f64>, radius: usize) -> Grid<f64> {
    let (w, h) = map.size();
    let fmax = |a: f64, b: f64| if b > a || a.is_nan() { b } else { a };
    let rows = Grid::from_fn(w, h, |x, y| {
        let (x0, x1) = (x.saturating_sub(radius), (x + radius + 1).min(w));
        (x0..x1).fold(f64::NAN, |m, xx| fmax(m, map[(xx, y)]))
    });
    Grid::from_fn(w, h, |x, y| {
        let (y0, y1) = (y.saturating_sub(radius), (y + radius + 1).min(h));
        (y0..y1).fold(f64::NAN, |m, yy| fmax(m, rows[(x, yy)]))
    })
}

/// The three-state rule on intervals: threshold `max_roughness_m`; `binary_ok` is the binary
/// map's answer (roughness and slope).
///
/// ```
/// use tre_core::roughness::interval::classify;
/// use tre_core::roughness::traversal::Traversal;
/// assert_eq!(classify(0.0, 0.02, 0.05, true), Traversal::Traversable);
/// assert_eq!(classify(0.0, 0.02, 0.05, false), Traversal::Hazard); // too steep
/// assert_eq!(classify(0.03, 0.07, 0.05, true), Traversal::Unknown);
/// assert_eq!(classify(0.06, 0.09, 0.05, false), Traversal::Hazard);
/// assert_eq!(classify(f64::NAN, f64::NAN, 0.05, false), Traversal::Unknown);
/// ```
pub fn classify(lo: f64, hi: f64, max_roughness_m: f64, binary_ok: bool) -> Traversal {
    if !(lo.is_finite() && hi.is_finite()) {
        Traversal::Unknown
    } else if lo >= max_roughness_m {
        Traversal::Hazard
    } else if hi < max_roughness_m {
        if binary_ok {
            Traversal::Traversable
        } else {
            // Flat enough but too steep: the slope test, not the roughness, says no.
            Traversal::Hazard
        }
    } else {
        Traversal::Unknown
    }
}

/// The tables of every mode, as `tre calibrate` writes them (`models/uncertainty.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// Format version (1).
    pub format: u32,
    /// How the tables were made, in words: frames, targets, models.
    pub note: String,
    /// The real frames the tables were fitted on, `sequence/depth`.
    pub frames: Vec<String>,
    /// The models' manifest hash (sha256 of each ONNX file, joined), so stale tables are told.
    pub models: String,
    /// Per mode name (`rgb`, `rgbd`, `geometric`): its table.
    pub tables: std::collections::BTreeMap<String, IntervalTable>,
}

/// File name of the calibration beside the models' manifest.
pub const CALIBRATION_FILE: &str = "uncertainty.json";

impl Calibration {
    /// The table of a mode, by name.
    pub fn table(&self, mode: &str) -> Option<&IntervalTable> {
        self.tables.get(mode)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples(n: usize, f: impl Fn(usize) -> Sample) -> Vec<Sample> {
        (0..n).map(f).collect()
    }

    #[test]
    fn the_fitted_interval_covers_ninety_per_cent_of_its_samples() {
        // Readings 1 cm, targets spread uniformly over 0..4 cm: the 5th and 95th percentiles
        // of target − reading are −0.8 and +2.8 cm.
        let s = samples(10_000, |i| Sample {
            feature_m: 0.01,
            second: 0.003,
            reading_m: 0.01,
            target_m: 0.04 * (i as f64 + 0.5) / 10_000.0,
        });
        let t = IntervalTable::fit((FirstAxis::Reading, SecondAxis::Uncertainty), &s)
            .expect("enough samples");
        let (lo, hi) = t.interval(0.01, 0.01, 0.003);
        assert!(
            (lo - 0.002).abs() < 1e-4 && (hi - 0.038).abs() < 1e-4,
            "{lo} {hi}"
        );
        let inside = s.iter().filter(|x| (lo..=hi).contains(&x.target_m)).count();
        assert!((8_900..=9_100).contains(&inside), "{inside}");
        // Another second-axis bin of the same row has no samples: it takes the row's.
        assert_eq!(t.interval(0.01, 0.01, 0.1), (lo, hi));
        assert!(!t.own[bin(&READING_EDGES_M, 0.01) * 8 + bin(&UNCERTAINTY_EDGES_M, 0.1)]);
    }

    #[test]
    fn too_few_samples_fit_nothing_and_nan_reads_nothing() {
        let s = samples(10, |_| Sample {
            feature_m: 0.0,
            second: 1.0,
            reading_m: 0.0,
            target_m: 0.0,
        });
        assert!(IntervalTable::fit((FirstAxis::Reading, SecondAxis::Depth), &s).is_none());
        let many: Vec<Sample> = s.iter().cycle().take(1000).copied().collect();
        let t = IntervalTable::fit((FirstAxis::Reading, SecondAxis::Depth), &many).expect("fits");
        let (lo, hi) = t.interval(f64::NAN, 0.0, 1.0);
        assert!(lo.is_nan() && hi.is_nan());
        assert_eq!(classify(lo, hi, 0.05, true), Traversal::Unknown);
    }

    #[test]
    fn a_depth_step_raises_the_feature_of_a_flat_reading() {
        let depth = Grid::from_fn(12, 1, |x, _| if x < 6 { 1.0 } else { 1.3 });
        let flat = Grid::new(12, 1, 0.001);
        let reading = feature_map(FirstAxis::Reading, &flat, &depth);
        let step = feature_map(FirstAxis::ReadingOrStep, &flat, &depth);
        assert_eq!(reading[(0, 0)], 0.001);
        assert!((step[(4, 0)] - 0.3).abs() < 1e-12, "{}", step[(4, 0)]);
        // Four pixels from the step: outside the 7×7 window.
        assert_eq!(step[(1, 0)], 0.001);
        assert!(depth_steps(&Grid::new(2, 1, 0.0))[(0, 0)].is_nan());
    }

    #[test]
    fn local_max_takes_the_window_and_skips_nan() {
        let mut g = Grid::new(9, 1, f64::NAN);
        g[(4, 0)] = 0.2;
        g[(0, 0)] = 0.1;
        let m = local_max(&g, 3);
        assert_eq!(m[(1, 0)], 0.2);
        assert_eq!(m[(0, 0)], 0.1);
        assert_eq!(m[(7, 0)], 0.2);
        assert!(m[(8, 0)].is_nan() || m[(8, 0)] == 0.2);
        let lone = local_max(&Grid::new(3, 3, f64::NAN), 1);
        assert!(lone.as_slice().iter().all(|v| v.is_nan()));
    }
}
