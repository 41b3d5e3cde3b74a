//! What one run of the pipeline does: input mode, method, the ablation switches of the paper's
//! Table IV, the DSAC seed, the working size and the traversability thresholds.

use serde::{Deserialize, Serialize};

use super::PipelineError;
use tre_core::geometry::normals::Neighbourhood;

// The choices are defined once, with their string forms, beside the geometry: the client and
// the CLI share them without depending on this crate.
pub use tre_core::kinds::{
    CentroidMethod, GeometricMethod, Method, Mode, NormalsMethod, Traversability,
};

/// Largest input frame accepted by default, pixels (about 40 MP).
pub const DEFAULT_MAX_INPUT_PIXELS: usize = 40_000_000;

/// Largest working size accepted, pixels per side.
pub const MAX_WORKING_SIDE: usize = 4096;

/// The key in `models/uncertainty.json` of the intervals of the spec on cleaned depth
/// (`geometric --geometric spec-cleaned`).
pub const SPEC_CLEANED_TABLE: &str = "geometric-spec-cleaned";

pub use tre_core::kinds::{DEFAULT_DSAC_HYPOTHESES, MAX_DSAC_HYPOTHESES};

/// `k` when it is a number of DSAC hypotheses the pipeline accepts (1 to
/// [`MAX_DSAC_HYPOTHESES`]).
///
/// # Errors
///
/// [`PipelineError::BadHypotheses`] otherwise.
pub fn check_dsac_hypotheses(k: u32) -> Result<u32, PipelineError> {
    if (1..=MAX_DSAC_HYPOTHESES).contains(&k) {
        Ok(k)
    } else {
        Err(PipelineError::BadHypotheses { got: k })
    }
}

fn default_dsac_hypotheses() -> u32 {
    DEFAULT_DSAC_HYPOTHESES
}

/// Everything one run of the pipeline needs besides the frame. The default is the full
/// pipeline on RGB: depth net, DSAC normals, refiner, centroid net. The switches are options of
/// `tre infer`, `eval`, `map` and `calibrate` (clap's, behind the `cli` feature: each doc
/// comment is its `--help`); each command sets the mode its own way. Geometric mode ignores
/// them: it uses LS normals, no refiner and window centroids ([`PipelineConfig::effective`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct PipelineConfig {
    /// Where depth comes from.
    #[cfg_attr(feature = "cli", arg(skip = Mode::Rgb))]
    pub mode: Mode,
    /// Staged pipeline or end-to-end baseline.
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value = "pipeline"))]
    pub method: Method,
    /// Initial normals (ignored in geometric mode).
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value = "dsac"))]
    pub normals: NormalsMethod,
    /// Normal refiner (ignored in geometric mode).
    #[cfg_attr(feature = "cli", arg(long, default_value = "on",
        action = clap::ArgAction::Set, value_parser = super::cli::on_off()))]
    pub refine: bool,
    /// Centroids (ignored in geometric mode).
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value = "net"))]
    pub centroid: CentroidMethod,
    /// What the geometric mode computes (ignored in the other modes).
    #[serde(default)]
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value = "terrain"))]
    pub geometric: GeometricMethod,
    /// Seed of the DSAC sampler: the same seed gives the same output.
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_SEED", default_value_t = 0))]
    pub seed: u64,
    /// DSAC hypotheses per pixel, 1 to 64 (12: as trained; fewer are faster, see
    /// docs/evaluation.md).
    #[serde(default = "default_dsac_hypotheses")]
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_DSAC_HYPOTHESES",
        default_value_t = DEFAULT_DSAC_HYPOTHESES,
        value_parser = tre_core::kinds::dsac_hypotheses_parser()))]
    pub dsac_hypotheses: u32,
    /// Size the stages run at, WIDTHxHEIGHT (e.g. 320x240; the outputs have this size). Default:
    /// with a network, the longer side of the frame takes the models' working size (256
    /// without models) and the other keeps the aspect ratio; in geometric mode, the input's own
    /// size. With networks, both sides must be multiples of the models' stride. Depth is
    /// resized nearest-neighbour, the intrinsics scaled.
    #[cfg_attr(feature = "cli", arg(long, value_parser = super::cli::working_size))]
    pub working_size: Option<(usize, usize)>,
    /// Neighbourhood of LS normals and window centroids.
    #[cfg_attr(feature = "cli", arg(skip))]
    pub neighbourhood: Neighbourhood,
    /// Traversability thresholds.
    #[cfg_attr(feature = "cli", arg(skip))]
    pub traversability: Traversability,
    /// Largest input frame, pixels.
    #[cfg_attr(feature = "cli", arg(skip = DEFAULT_MAX_INPUT_PIXELS))]
    pub max_input_pixels: usize,
}

impl Default for PipelineConfig {
    fn default() -> Self {
        Self {
            mode: Mode::Rgb,
            method: Method::Pipeline,
            normals: NormalsMethod::Dsac,
            refine: true,
            centroid: CentroidMethod::Net,
            geometric: GeometricMethod::Terrain,
            seed: 0,
            dsac_hypotheses: DEFAULT_DSAC_HYPOTHESES,
            working_size: None,
            neighbourhood: Neighbourhood::default(),
            traversability: Traversability::default(),
            max_input_pixels: DEFAULT_MAX_INPUT_PIXELS,
        }
    }
}

impl PipelineConfig {
    /// The full pipeline in `mode` (geometric mode: the classical baseline).
    pub fn for_mode(mode: Mode) -> Self {
        Self {
            mode,
            ..Self::default()
        }
    }

    /// Refuses depth given to a configuration that would not read it: the pipeline in `rgb`
    /// mode predicts its own depth, so sensor depth sent with it would be dropped without a
    /// word. (The end-to-end baseline reads no depth either; its callers refuse it with their
    /// own fix.)
    ///
    /// # Errors
    ///
    /// [`PipelineError::UnusedDepth`] for depth in `rgb` mode.
    pub fn check_depth_used(&self, has_depth: bool) -> Result<(), PipelineError> {
        if has_depth && self.method == Method::Pipeline && self.mode == Mode::Rgb {
            return Err(PipelineError::UnusedDepth);
        }
        Ok(())
    }

    /// True where the geometric mode runs the terrain estimate (no LS normals, no window
    /// centroids: its own supports).
    pub fn is_terrain(&self) -> bool {
        self.mode == Mode::Geometric && self.geometric == GeometricMethod::Terrain
    }

    /// The key of the calibrated intervals (`models/uncertainty.json`) that apply to what this
    /// configuration runs: its mode's, `geometric-spec-cleaned` for the spec on cleaned depth,
    /// none for the terrain estimate (it reads its own noise margins) and the end-to-end
    /// baseline (the tables were fitted on the staged pipeline's readings).
    pub fn interval_key(&self) -> Option<&'static str> {
        match self.method {
            Method::EndToEnd => None,
            Method::Pipeline if self.is_terrain() => None,
            Method::Pipeline if self.is_spec_cleaned() => Some(SPEC_CLEANED_TABLE),
            Method::Pipeline => Some(self.mode.into()),
        }
    }

    /// True where the geometric mode runs annotation spec v1 on cleaned depth.
    pub fn is_spec_cleaned(&self) -> bool {
        self.mode == Mode::Geometric && self.geometric == GeometricMethod::SpecCleaned
    }

    /// True where the geometric mode runs annotation spec v1 (on the depth as given, or
    /// cleaned).
    pub fn is_spec(&self) -> bool {
        self.mode == Mode::Geometric
            && matches!(
                self.geometric,
                GeometricMethod::Spec | GeometricMethod::SpecCleaned
            )
    }

    /// The stages that actually run: geometric mode forces LS normals, no refiner and window
    /// centroids.
    pub fn effective(&self) -> (NormalsMethod, bool, CentroidMethod) {
        match self.mode {
            Mode::Geometric => (NormalsMethod::Ls, false, CentroidMethod::Window),
            Mode::Rgb | Mode::Rgbd => (self.normals, self.refine, self.centroid),
        }
    }

    /// This configuration with the switches that run: in the geometric mode, LS normals, no
    /// refiner and window centroids whatever was asked (for records of what ran).
    ///
    /// ```
    /// use tre_pipeline::{CentroidMethod, Mode, NormalsMethod, PipelineConfig};
    /// let asked = PipelineConfig { mode: Mode::Geometric, ..PipelineConfig::default() };
    /// let ran = asked.as_run();
    /// assert_eq!((ran.normals, ran.refine, ran.centroid), (NormalsMethod::Ls, false, CentroidMethod::Window));
    /// assert_eq!(ran.label(), asked.label());
    /// ```
    pub fn as_run(&self) -> Self {
        let (normals, refine, centroid) = self.effective();
        Self {
            normals,
            refine,
            centroid,
            ..*self
        }
    }

    /// DSAC in [`label`](Self::label): `DSAC`, or `DSAC(K=4)` with other than
    /// [`DEFAULT_DSAC_HYPOTHESES`] hypotheses.
    pub fn dsac_label(&self) -> String {
        match self.dsac_hypotheses {
            DEFAULT_DSAC_HYPOTHESES => "DSAC".to_owned(),
            k => format!("DSAC(K={k})"),
        }
    }

    /// The networks this configuration runs, by manifest name (empty: no models needed).
    pub fn networks(&self) -> Vec<&'static str> {
        use tre_model::{CENTROID_NET, DEPTH_NET, END_TO_END, NEIGHBOUR_NET, NORMAL_REFINER};
        if self.method == Method::EndToEnd {
            return vec![END_TO_END];
        }
        let (normals, refine, centroid) = self.effective();
        let mut nets = Vec::new();
        if self.mode == Mode::Rgb {
            nets.push(DEPTH_NET);
        }
        if normals == NormalsMethod::Dsac {
            nets.push(NEIGHBOUR_NET);
        }
        if refine {
            nets.push(NORMAL_REFINER);
        }
        if centroid == CentroidMethod::Net {
            nets.push(CENTROID_NET);
        }
        nets
    }

    /// A short name of the stages, in the paper's notation: `DE+DSAC+NR+ESR`, `LS+window+edge`
    /// (the geometric mode's spec), `cleaned+LS+window+edge` (the spec on cleaned depth),
    /// `LS+window` (its surface-only baseline), `E2E`;
    /// DSAC with other than [`DEFAULT_DSAC_HYPOTHESES`] hypotheses reads `DSAC(K=4)`.
    pub fn label(&self) -> String {
        if self.method == Method::EndToEnd {
            return "E2E".to_owned();
        }
        if self.is_terrain() {
            return "terrain".to_owned();
        }
        let (normals, refine, centroid) = self.effective();
        let mut parts = Vec::new();
        if self.mode == Mode::Rgb {
            parts.push("DE");
        }
        if self.is_spec_cleaned() {
            parts.push("cleaned");
        }
        let dsac = self.dsac_label();
        parts.push(match normals {
            NormalsMethod::Ls => "LS",
            NormalsMethod::Dsac => &dsac,
        });
        if refine {
            parts.push("NR");
        }
        parts.push(match centroid {
            CentroidMethod::Net => "ESR",
            CentroidMethod::Window => "window",
        });
        if self.is_spec() {
            parts.push("edge");
        }
        parts.join("+")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geometric_mode_needs_no_network_and_the_default_needs_all_four() {
        assert!(PipelineConfig::for_mode(Mode::Geometric)
            .networks()
            .is_empty());
        assert_eq!(PipelineConfig::default().networks().len(), 4);
        assert_eq!(PipelineConfig::default().label(), "DE+DSAC+NR+ESR");
        let rgbd_ls = PipelineConfig {
            mode: Mode::Rgbd,
            normals: NormalsMethod::Ls,
            refine: false,
            centroid: CentroidMethod::Window,
            ..PipelineConfig::default()
        };
        assert!(rgbd_ls.networks().is_empty());
        assert_eq!(rgbd_ls.label(), "LS+window");
        let fewer = PipelineConfig {
            dsac_hypotheses: 4,
            ..PipelineConfig::default()
        };
        assert_eq!(fewer.label(), "DE+DSAC(K=4)+NR+ESR");
        let ls_fewer = PipelineConfig {
            normals: NormalsMethod::Ls,
            ..fewer
        };
        assert_eq!(ls_fewer.label(), "DE+LS+NR+ESR");
    }

    #[test]
    fn each_geometric_method_has_its_label_and_its_intervals() {
        let geometric = |geometric| PipelineConfig {
            mode: Mode::Geometric,
            geometric,
            ..PipelineConfig::default()
        };
        for (method, label, key) in [
            (GeometricMethod::Terrain, "terrain", None),
            (GeometricMethod::Spec, "LS+window+edge", Some("geometric")),
            (
                GeometricMethod::SpecCleaned,
                "cleaned+LS+window+edge",
                Some(SPEC_CLEANED_TABLE),
            ),
            (GeometricMethod::SurfaceOnly, "LS+window", Some("geometric")),
        ] {
            let cfg = geometric(method);
            assert_eq!(cfg.label(), label, "{method:?}");
            assert_eq!(cfg.interval_key(), key, "{method:?}");
            assert_eq!(
                cfg.is_spec(),
                matches!(method, GeometricMethod::Spec | GeometricMethod::SpecCleaned)
            );
        }
        assert_eq!(PipelineConfig::default().interval_key(), Some("rgb"));
        let e2e = PipelineConfig {
            method: Method::EndToEnd,
            ..PipelineConfig::default()
        };
        assert_eq!(e2e.interval_key(), None);
    }

    #[test]
    fn depth_in_rgb_mode_is_refused_with_the_modes_that_use_it() {
        let rgb = PipelineConfig::for_mode(Mode::Rgb);
        let e = rgb.check_depth_used(true).unwrap_err().to_string();
        assert!(e.contains("rgbd") && e.contains("geometric"), "{e}");
        assert!(rgb.check_depth_used(false).is_ok());
        for mode in [Mode::Rgbd, Mode::Geometric] {
            assert!(PipelineConfig::for_mode(mode)
                .check_depth_used(true)
                .is_ok());
        }
    }
}
