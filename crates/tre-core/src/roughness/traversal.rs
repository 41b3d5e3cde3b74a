//! Three-state traversability: traversable, hazard, or unknown where there is no data or where
//! sensor noise is too large to tell the robot's roughness threshold apart.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::geometry::Grid;

/// One pixel's traversability. The discriminants are the 8-bit map's values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
#[repr(u8)]
pub enum Traversal {
    /// No data, or noise too large to judge: the robot must look again or go around.
    Unknown = 0,
    /// Roughness and slope within the thresholds, with noise well below them.
    Traversable = 1,
    /// Too rough or too steep, or a drop.
    Hazard = 2,
}

/// The thresholds of the three-state map.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ThreeStateRule {
    /// The robot's roughness threshold, metres (the binary map's, default 0.05).
    pub max_roughness_m: f64,
    /// Roughness of a drop, metres (0.1): a hazard wherever it exceeds the uncertainty.
    pub drop_m: f64,
    /// Uncertainty, as a fraction of the threshold, from which the threshold cannot be told
    /// apart (0.5: noise alone reaches half the threshold at its 95th percentile).
    pub unknown_fraction: f64,
}

impl Default for ThreeStateRule {
    fn default() -> Self {
        Self {
            max_roughness_m: 0.05,
            drop_m: 0.1,
            unknown_fraction: 0.5,
        }
    }
}

impl ThreeStateRule {
    /// One pixel: roughness `r` and uncertainty `u` (metres; NaN `u`: no noise model, read as
    /// none) and whether it passes the binary map's tests (roughness and slope).
    ///
    /// ```
    /// use tre_core::roughness::traversal::{ThreeStateRule, Traversal};
    /// let rule = ThreeStateRule::default();
    /// assert_eq!(rule.classify(0.01, 0.005, true), Traversal::Traversable);
    /// assert_eq!(rule.classify(0.04, 0.03, false), Traversal::Unknown);
    /// assert_eq!(rule.classify(0.12, 0.06, false), Traversal::Hazard); // a drop
    /// assert_eq!(rule.classify(0.12, 0.15, false), Traversal::Unknown); // or noise
    /// assert_eq!(rule.classify(f64::NAN, 0.0, false), Traversal::Unknown);
    /// ```
    pub fn classify(&self, r: f64, u: f64, binary_ok: bool) -> Traversal {
        if !r.is_finite() {
            return Traversal::Unknown;
        }
        let noisy = u >= self.unknown_fraction * self.max_roughness_m;
        if !noisy {
            return if binary_ok && r < self.drop_m {
                Traversal::Traversable
            } else {
                Traversal::Hazard
            };
        }
        // Above the threshold by more than the noise, or a drop above what noise gives.
        let clearly_above = r >= self.max_roughness_m + u;
        let drop = r >= self.drop_m && r > u;
        if clearly_above || drop {
            Traversal::Hazard
        } else {
            Traversal::Unknown
        }
    }

    /// The three-state map from roughness, uncertainty and the binary map (same sizes).
    pub fn map(
        &self,
        roughness_m: &Grid<f64>,
        uncertainty_m: &Grid<f64>,
        binary_ok: &Grid<bool>,
    ) -> Grid<Traversal> {
        let (w, h) = roughness_m.size();
        let mut out = Grid::new(w, h, Traversal::Unknown);
        out.as_mut_slice()
            .par_iter_mut()
            .zip(roughness_m.as_slice())
            .zip(
                uncertainty_m
                    .as_slice()
                    .par_iter()
                    .zip(binary_ok.as_slice()),
            )
            .for_each(|((t, &r), (&u, &ok))| *t = self.classify(r, u, ok));
        out
    }
}

/// Shares of a three-state map: (traversable, hazard, unknown), each 0 to 1.
pub fn shares(map: &Grid<Traversal>) -> (f64, f64, f64) {
    let n = map.as_slice().len().max(1) as f64;
    let count = |s: Traversal| map.as_slice().iter().filter(|&&t| t == s).count() as f64 / n;
    (
        count(Traversal::Traversable),
        count(Traversal::Hazard),
        count(Traversal::Unknown),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_makes_near_threshold_unknown_but_not_clear_hazards() {
        let rule = ThreeStateRule::default();
        // Noise of half the threshold: a 3 cm reading could be anything up to 5.5 cm.
        assert_eq!(rule.classify(0.03, 0.025, true), Traversal::Unknown);
        // 8 cm is above 5 + 2.5 cm: a hazard even through the noise.
        assert_eq!(rule.classify(0.08, 0.025, false), Traversal::Hazard);
        // Small noise leaves the binary answer as it is.
        assert_eq!(rule.classify(0.06, 0.01, false), Traversal::Hazard);
        assert_eq!(rule.classify(0.02, f64::NAN, true), Traversal::Traversable);
    }
}
