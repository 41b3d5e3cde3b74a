//! Options shared by `tre infer` and `tre eval`: input mode, method, the pipeline's ablation
//! switches and the models, turned into a [`PipelineConfig`] and a [`Pipeline`].

use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::{Args, ValueEnum};

use crate::model::{locate_models, Models, SessionConfig};
use crate::pipeline::{
    CentroidMethod, GeometricMethod, Method, Mode, NormalsMethod, Pipeline, PipelineConfig,
    DEFAULT_DSAC_HYPOTHESES, MAX_DSAC_HYPOTHESES,
};

/// Input mode (the paper's Table IV rows).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ModeArg {
    /// One RGB frame: the depth net predicts depth.
    Rgb,
    /// RGB plus a registered depth frame: the depth net is skipped.
    Rgbd,
    /// Depth only, no networks: annotation spec v1 (surface and edge terms), as `tre annotate`.
    Geometric,
}

/// What the geometric mode computes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum GeometricArg {
    /// The whole annotation spec v1: surface term and edge term (drops and steps are hazards).
    Spec,
    /// The paper's surface-only baseline: Eq. 1 with LS normals and window centroids, no edge
    /// term.
    SurfaceOnly,
}

impl From<GeometricArg> for GeometricMethod {
    fn from(g: GeometricArg) -> Self {
        match g {
            GeometricArg::Spec => GeometricMethod::Spec,
            GeometricArg::SurfaceOnly => GeometricMethod::SurfaceOnly,
        }
    }
}

/// The staged pipeline or the end-to-end baseline.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum MethodArg {
    /// The staged pipeline of the paper's Fig. 5.
    Pipeline,
    /// The end-to-end baseline (end_to_end.onnx; RGB only).
    EndToEnd,
}

/// Initial normals.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum NormalsArg {
    /// Least-squares planes.
    Ls,
    /// Neighbour net and DSAC hypotheses.
    Dsac,
}

/// Centroids of Eq. 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum CentroidArg {
    /// The centroid net.
    Net,
    /// The mean of the metric neighbourhood.
    Window,
}

/// On or off.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Switch {
    /// Enabled.
    On,
    /// Disabled.
    Off,
}

impl From<ModeArg> for Mode {
    fn from(m: ModeArg) -> Self {
        match m {
            ModeArg::Rgb => Mode::Rgb,
            ModeArg::Rgbd => Mode::Rgbd,
            ModeArg::Geometric => Mode::Geometric,
        }
    }
}

impl From<NormalsArg> for NormalsMethod {
    fn from(n: NormalsArg) -> Self {
        match n {
            NormalsArg::Ls => NormalsMethod::Ls,
            NormalsArg::Dsac => NormalsMethod::Dsac,
        }
    }
}

/// Parser of `--dsac-hypotheses` (`infer`, `eval`, `serve`, `client`): 1 to
/// [`MAX_DSAC_HYPOTHESES`].
pub fn dsac_hypotheses_arg() -> clap::builder::RangedI64ValueParser<u32> {
    clap::value_parser!(u32).range(1..=i64::from(MAX_DSAC_HYPOTHESES))
}

/// The models folder for the `--models` value (see [`locate_models`]), logged with the rule
/// that found it; shared by every subcommand that loads models.
pub fn find_models(flag: Option<&Path>) -> anyhow::Result<PathBuf> {
    let found = locate_models(flag)?;
    tracing::info!(path = %found.dir.display(), "models folder found by {}", found.rule);
    Ok(found.dir)
}

/// The pipeline's switches and models, shared by `infer` and `eval`.
#[derive(Debug, Clone, Args)]
pub struct StageArgs {
    /// Staged pipeline or end-to-end baseline.
    #[arg(long, value_enum, default_value = "pipeline")]
    pub method: MethodArg,
    /// Initial normals (ignored in geometric mode).
    #[arg(long, value_enum, default_value = "dsac")]
    pub normals: NormalsArg,
    /// Normal refiner (ignored in geometric mode).
    #[arg(long, value_enum, default_value = "on")]
    pub refine: Switch,
    /// Centroids (ignored in geometric mode).
    #[arg(long, value_enum, default_value = "net")]
    pub centroid: CentroidArg,
    /// What the geometric mode computes (ignored in the other modes).
    #[arg(long, value_enum, default_value = "spec")]
    pub geometric: GeometricArg,
    /// Seed of the DSAC sampler: the same seed gives the same output.
    #[arg(long, env = "TRE_SEED", default_value_t = 0)]
    pub seed: u64,
    /// DSAC hypotheses per pixel, 1 to 64 (12: as trained; fewer are faster, see docs/evaluation.md).
    #[arg(long, env = "TRE_DSAC_HYPOTHESES", default_value_t = DEFAULT_DSAC_HYPOTHESES,
          value_parser = dsac_hypotheses_arg())]
    pub dsac_hypotheses: u32,
    /// Folder with manifest.json and the ONNX models (only read when a network runs). When
    /// not given: TRE_MODELS, then models/ beside the executable, ../share/tre/models
    /// relative to it, then models/ in the working directory.
    #[arg(long, env = "TRE_MODELS")]
    pub models: Option<PathBuf>,
    /// ONNX Runtime threads per operator (0: one per core).
    #[arg(long, env = "TRE_ORT_THREADS", default_value_t = 0)]
    pub ort_threads: usize,
}

impl StageArgs {
    /// The pipeline configuration for `mode`.
    pub fn config(&self, mode: ModeArg) -> PipelineConfig {
        PipelineConfig {
            mode: mode.into(),
            method: match self.method {
                MethodArg::Pipeline => Method::Pipeline,
                MethodArg::EndToEnd => Method::EndToEnd,
            },
            normals: self.normals.into(),
            refine: self.refine == Switch::On,
            centroid: match self.centroid {
                CentroidArg::Net => CentroidMethod::Net,
                CentroidArg::Window => CentroidMethod::Window,
            },
            geometric: self.geometric.into(),
            seed: self.seed,
            dsac_hypotheses: self.dsac_hypotheses,
            ..PipelineConfig::default()
        }
    }

    /// A pipeline with the models loaded when any of `configs` runs a network.
    pub fn pipeline(&self, configs: &[PipelineConfig]) -> anyhow::Result<Pipeline> {
        if configs.iter().all(|c| c.networks().is_empty()) {
            return Ok(Pipeline::new(None));
        }
        super::check_threads(None, self.ort_threads, super::cores())?;
        let session = SessionConfig {
            intra_threads: self.ort_threads,
            ..SessionConfig::default()
        };
        let dir = find_models(self.models.as_deref())?;
        let models = Models::load(&dir, &session)
            .with_context(|| format!("loading models from {}", dir.display()))?;
        Ok(Pipeline::new(Some(models)))
    }
}
