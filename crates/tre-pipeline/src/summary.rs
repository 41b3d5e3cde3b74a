//! A frame's result in words, as `tre infer` prints it: the mode and its stages, the pixels
//! with roughness and their median, gravity, the binary map's count and the time per stage.

use tre_core::roughness::metrics::finite_sorted;
use tre_core::roughness::traversal::shares;

use crate::{FrameOutput, Method, PipelineConfig, SensorMaps};

impl PipelineConfig {
    /// The stages in words: the label's abbreviations spelt out (`depth net + DSAC normals
    /// (DSAC) + ...`).
    #[must_use]
    pub fn stage_names(&self) -> String {
        self.label()
            .split('+')
            .map(|p| match p {
                "DE" => "depth net".to_owned(),
                "LS" => "least-squares normals".to_owned(),
                "NR" => "normal refiner".to_owned(),
                "ESR" => "centroid net".to_owned(),
                "window" => "window centroids".to_owned(),
                "edge" => "edge term".to_owned(),
                "E2E" => "end-to-end net".to_owned(),
                d if d.starts_with("DSAC") => format!("DSAC normals ({d})"),
                other => other.to_owned(),
            })
            .collect::<Vec<_>>()
            .join(" + ")
    }
}

impl FrameOutput {
    /// The result of `cfg` on a frame in four lines: what ran and the roughness found, gravity,
    /// the binary map's count (and why it is empty when gravity is unknown), milliseconds per
    /// stage.
    #[must_use]
    pub fn summary(&self, cfg: &PipelineConfig) -> Vec<String> {
        let valid = finite_sorted(&self.roughness_m);
        let median_cm = valid.get(valid.len() / 2).map_or(f64::NAN, |r| 100.0 * r);
        let (w, h) = self.working_size;
        let mode = if cfg.method == Method::EndToEnd {
            "the end-to-end baseline".to_owned()
        } else {
            format!("mode {}", cfg.mode)
        };
        let slope_limit = cfg.traversability.max_slope_rad.to_degrees();
        let rough_limit = 100.0 * cfg.traversability.max_roughness_m;
        let ok = self.traversable().as_slice().iter().filter(|&&t| t).count();
        let binary = if self.slope_rad().is_none() {
            format!(
                "binary map: {ok} px with roughness < {rough_limit} cm (no normals, so no slope)"
            )
        } else if self.gravity.up_in_cam().is_none() {
            format!(
                "binary map: none traversable: gravity unknown, so no slope < {slope_limit}° can \
                 be shown"
            )
        } else {
            format!(
                "binary map: {ok} px with roughness < {rough_limit} cm and slope < {slope_limit}°"
            )
        };
        let stages: Vec<String> = self
            .timings
            .iter()
            .map(|(name, d)| format!("{name} {:.1}", d.as_secs_f64() * 1e3))
            .collect();
        vec![
            format!(
                "{mode} ({}) at {w}×{h}: {} px with roughness, median {median_cm:.3} cm",
                cfg.stage_names(),
                valid.len()
            ),
            format!("gravity: {}", self.gravity),
            binary,
            format!("ms: {}", stages.join(", ")),
        ]
    }
}

/// The share of unknown pixels from which a three-state map is called mostly unknown
/// ([`SensorMaps::mostly_unknown`]): its roughness map, however detailed it looks, answers
/// almost nothing.
pub const MOSTLY_UNKNOWN_SHARE: f64 = 0.9;

impl SensorMaps {
    /// The caveat of a three-state map at least [`MOSTLY_UNKNOWN_SHARE`] unknown, for a
    /// preview's title and the console (`97.5% unknown: ...`); `None` for a map that answers.
    #[must_use]
    pub fn mostly_unknown(&self) -> Option<String> {
        let (_, _, unknown) = shares(&self.traversal);
        (unknown >= MOSTLY_UNKNOWN_SHARE).then(|| {
            format!(
                "{:.1}% unknown: the roughness is no answer here",
                100.0 * unknown
            )
        })
    }

    /// The three states' shares in one line, naming where they come from (`what`).
    #[must_use]
    pub fn shares_line(&self, what: &str) -> String {
        let (t, h, u) = shares(&self.traversal);
        format!(
            "{what}: {:.1}% traversable, {:.1}% hazard, {:.1}% unknown",
            100.0 * t,
            100.0 * h,
            100.0 * u
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tre_core::geometry::Grid;
    use tre_core::roughness::traversal::Traversal;

    /// Maps of 20 pixels, `unknown` of them unknown and the rest traversable.
    fn maps(unknown: usize) -> SensorMaps {
        let t = (0..20)
            .map(|i| {
                if i < unknown {
                    Traversal::Unknown
                } else {
                    Traversal::Traversable
                }
            })
            .collect();
        SensorMaps {
            uncertainty_m: Grid::new(20, 1, f64::NAN),
            interval_m: None,
            traversal: Grid::from_vec(20, 1, t).expect("20 pixels"),
        }
    }

    #[test]
    fn a_map_at_least_nine_tenths_unknown_says_so() {
        assert_eq!(maps(17).mostly_unknown(), None);
        let said = maps(18).mostly_unknown().expect("18 of 20 is 90%");
        assert!(said.starts_with("90.0% unknown"), "{said}");
        let said = maps(20).mostly_unknown().expect("all unknown");
        assert!(said.starts_with("100.0% unknown"), "{said}");
    }
}
