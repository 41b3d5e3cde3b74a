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

impl SensorMaps {
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
