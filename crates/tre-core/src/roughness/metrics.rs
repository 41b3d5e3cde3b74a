//! Evaluation metrics as the paper reports them: roughness RMSE, B-RMSE (boundary pixels) and
//! F-RMSE (the rest) in cm; normal angle errors; depth AbsRel, RMSE and δ < 1.25. Accumulators
//! pool pixels over any number of frames.

use serde::Serialize;

use super::RoughnessError;
use crate::geometry::{Grid, Vec3};

fn check_size(
    what: &'static str,
    a: (usize, usize),
    b: (usize, usize),
) -> Result<(), RoughnessError> {
    if a == b {
        Ok(())
    } else {
        Err(RoughnessError::SizeMismatch {
            what,
            depth: a,
            other: b,
        })
    }
}

/// Pooled squared errors of roughness over frames.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RoughnessAccumulator {
    sse: [f64; 2],
    count: [u64; 2],
    missing: u64,
}

/// Roughness errors in centimetres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RoughnessMetrics {
    /// RMSE over all pixels with ground truth, cm.
    pub rmse_cm: f64,
    /// RMSE over boundary pixels (B = 1), cm.
    pub b_rmse_cm: f64,
    /// RMSE over the other pixels (B = 0), cm.
    pub f_rmse_cm: f64,
    /// Pixels scored.
    pub pixels: u64,
    /// Pixels with ground truth but no prediction (not scored).
    pub missing: u64,
}

impl RoughnessAccumulator {
    /// Adds one frame: prediction and ground truth in metres (NaN: none), boundary mask.
    pub fn add(
        &mut self,
        pred_m: &Grid<f64>,
        gt_m: &Grid<f64>,
        boundary: &Grid<bool>,
    ) -> Result<(), RoughnessError> {
        check_size("prediction", gt_m.size(), pred_m.size())?;
        check_size("boundary mask", gt_m.size(), boundary.size())?;
        for ((p, g), b) in pred_m
            .as_slice()
            .iter()
            .zip(gt_m.as_slice())
            .zip(boundary.as_slice())
        {
            if !g.is_finite() {
                continue;
            }
            if !p.is_finite() {
                self.missing += 1;
                continue;
            }
            let k = usize::from(*b);
            self.sse[k] += (p - g) * (p - g);
            self.count[k] += 1;
        }
        Ok(())
    }

    /// Adds another accumulator's pixels.
    pub fn merge(&mut self, other: &Self) {
        for k in 0..2 {
            self.sse[k] += other.sse[k];
            self.count[k] += other.count[k];
        }
        self.missing += other.missing;
    }

    /// The metrics so far (NaN for an empty set).
    pub fn finish(&self) -> RoughnessMetrics {
        let rmse_cm = |sse: f64, n: u64| {
            if n == 0 {
                f64::NAN
            } else {
                100.0 * (sse / n as f64).sqrt()
            }
        };
        RoughnessMetrics {
            rmse_cm: rmse_cm(self.sse[0] + self.sse[1], self.count[0] + self.count[1]),
            b_rmse_cm: rmse_cm(self.sse[1], self.count[1]),
            f_rmse_cm: rmse_cm(self.sse[0], self.count[0]),
            pixels: self.count[0] + self.count[1],
            missing: self.missing,
        }
    }
}

/// Pooled angle errors of normals.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct NormalAccumulator {
    angles_deg: Vec<f32>,
}

/// Normal errors in degrees and the share of pixels under the paper's thresholds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NormalMetrics {
    /// Mean angle error, degrees.
    pub mean_deg: f64,
    /// Median angle error, degrees.
    pub median_deg: f64,
    /// % of pixels under 11.25°.
    pub under_11_25_pct: f64,
    /// % of pixels under 22.5°.
    pub under_22_5_pct: f64,
    /// % of pixels under 30°.
    pub under_30_pct: f64,
    /// Pixels scored.
    pub pixels: u64,
}

impl NormalAccumulator {
    /// Adds one frame of predicted and true normals (NaN: none; need not be unit length).
    pub fn add(&mut self, pred: &Grid<Vec3>, gt: &Grid<Vec3>) -> Result<(), RoughnessError> {
        check_size("predicted normals", gt.size(), pred.size())?;
        for (p, g) in pred.as_slice().iter().zip(gt.as_slice()) {
            let cos = p.dot(g) / (p.norm() * g.norm());
            if cos.is_finite() {
                self.angles_deg
                    .push(cos.clamp(-1.0, 1.0).acos().to_degrees() as f32);
            }
        }
        Ok(())
    }

    /// The metrics so far (NaN for an empty set).
    pub fn finish(&self) -> NormalMetrics {
        let n = self.angles_deg.len();
        let mut sorted = self.angles_deg.clone();
        sorted.sort_by(f32::total_cmp);
        let pct = |t: f32| 100.0 * sorted.iter().filter(|&&a| a < t).count() as f64 / n as f64;
        let median = match n {
            0 => f64::NAN,
            _ if n % 2 == 1 => f64::from(sorted[n / 2]),
            _ => 0.5 * (f64::from(sorted[n / 2 - 1]) + f64::from(sorted[n / 2])),
        };
        NormalMetrics {
            mean_deg: sorted.iter().map(|&a| f64::from(a)).sum::<f64>() / n as f64,
            median_deg: median,
            under_11_25_pct: pct(11.25),
            under_22_5_pct: pct(22.5),
            under_30_pct: pct(30.0),
            pixels: n as u64,
        }
    }
}

/// Pooled depth errors.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DepthAccumulator {
    abs_rel: f64,
    sse: f64,
    within: u64,
    count: u64,
}

/// Depth errors.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DepthMetrics {
    /// Mean |d − d*| / d*.
    pub abs_rel: f64,
    /// RMSE, metres.
    pub rmse_m: f64,
    /// Share of pixels with max(d/d*, d*/d) < 1.25.
    pub delta_1_25: f64,
    /// Pixels scored.
    pub pixels: u64,
}

impl DepthAccumulator {
    /// Adds another accumulator's pixels.
    pub fn merge(&mut self, other: &Self) {
        self.abs_rel += other.abs_rel;
        self.sse += other.sse;
        self.within += other.within;
        self.count += other.count;
    }

    /// Adds one frame (metres; ≤ 0 or non-finite: none).
    pub fn add(&mut self, pred_m: &Grid<f64>, gt_m: &Grid<f64>) -> Result<(), RoughnessError> {
        check_size("predicted depth", gt_m.size(), pred_m.size())?;
        for (&p, &g) in pred_m.as_slice().iter().zip(gt_m.as_slice()) {
            if !(p > 0.0 && g > 0.0 && p.is_finite() && g.is_finite()) {
                continue;
            }
            self.abs_rel += (p - g).abs() / g;
            self.sse += (p - g) * (p - g);
            self.within += u64::from((p / g).max(g / p) < 1.25);
            self.count += 1;
        }
        Ok(())
    }

    /// The metrics so far (NaN for an empty set).
    pub fn finish(&self) -> DepthMetrics {
        let n = self.count as f64;
        DepthMetrics {
            abs_rel: self.abs_rel / n,
            rmse_m: (self.sse / n).sqrt(),
            delta_1_25: self.within as f64 / n,
            pixels: self.count,
        }
    }
}

/// The finite values of a map, sorted ascending (for quantiles such as a summary's median).
///
/// ```
/// use tre_core::geometry::Grid;
/// use tre_core::roughness::metrics::finite_sorted;
/// let g = Grid::from_vec(3, 1, vec![0.3, f64::NAN, 0.1]).unwrap();
/// assert_eq!(finite_sorted(&g), vec![0.1, 0.3]);
/// ```
#[must_use]
pub fn finite_sorted(map: &Grid<f64>) -> Vec<f64> {
    let mut v: Vec<f64> = map
        .as_slice()
        .iter()
        .copied()
        .filter(|r| r.is_finite())
        .collect();
    v.sort_by(f64::total_cmp);
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn roughness_rmse_splits_boundary_and_flat() {
        let gt = Grid::from_vec(2, 2, vec![0.0, 0.0, 0.1, f64::NAN]).unwrap();
        let pred = Grid::from_vec(2, 2, vec![0.01, 0.0, 0.07, 0.5]).unwrap();
        let b = Grid::from_vec(2, 2, vec![false, false, true, true]).unwrap();
        let mut acc = RoughnessAccumulator::default();
        acc.add(&pred, &gt, &b).unwrap();
        let m = acc.finish();
        assert_relative_eq!(m.b_rmse_cm, 3.0, epsilon = 1e-9);
        assert_relative_eq!(m.f_rmse_cm, (0.5f64).sqrt(), epsilon = 1e-9);
        assert_relative_eq!(m.rmse_cm, ((1.0 + 9.0) / 3.0f64).sqrt(), epsilon = 1e-9);
        assert_eq!(m.pixels, 3);
    }

    #[test]
    fn normal_errors() {
        let z = Vec3::z();
        let tilted = Vec3::new(0.0, 20f64.to_radians().sin(), 20f64.to_radians().cos());
        let gt = Grid::from_vec(3, 1, vec![z, z, z]).unwrap();
        let pred = Grid::from_vec(3, 1, vec![z, tilted, 2.0 * z]).unwrap();
        let mut acc = NormalAccumulator::default();
        acc.add(&pred, &gt).unwrap();
        let m = acc.finish();
        assert_relative_eq!(m.mean_deg, 20.0 / 3.0, epsilon = 1e-4);
        assert_relative_eq!(m.median_deg, 0.0, epsilon = 1e-4);
        assert_relative_eq!(m.under_11_25_pct, 200.0 / 3.0, epsilon = 1e-9);
        assert_relative_eq!(m.under_22_5_pct, 100.0, epsilon = 1e-9);
    }

    #[test]
    fn depth_errors() {
        let gt = Grid::from_vec(3, 1, vec![1.0, 2.0, 0.0]).unwrap();
        let pred = Grid::from_vec(3, 1, vec![1.1, 3.0, 1.0]).unwrap();
        let mut acc = DepthAccumulator::default();
        acc.add(&pred, &gt).unwrap();
        let m = acc.finish();
        assert_relative_eq!(m.abs_rel, (0.1 + 0.5) / 2.0, epsilon = 1e-12);
        assert_relative_eq!(m.rmse_m, ((0.01 + 1.0) / 2.0f64).sqrt(), epsilon = 1e-12);
        assert_relative_eq!(m.delta_1_25, 0.5, epsilon = 1e-12);
    }

    #[test]
    fn size_mismatch_is_an_error() {
        let a = Grid::new(2, 2, 0.0);
        let b = Grid::new(3, 2, 0.0);
        assert!(DepthAccumulator::default().add(&a, &b).is_err());
    }
}
