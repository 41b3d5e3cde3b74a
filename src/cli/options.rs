//! Options shared by `tre infer` and `tre eval`: input mode, method, the pipeline's ablation
//! switches and the models, turned into a [`PipelineConfig`] and a [`Pipeline`]. The choices
//! are the pipeline's own enums (`tre_core::kinds`, with clap's `ValueEnum`): their values and
//! help are written once, there.

use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::{Args, ValueEnum};

use crate::model::{locate_models, Models, SessionConfig};
use crate::pipeline::{
    read_calibration, stale_calibration, CentroidMethod, GeometricMethod, Method, Mode,
    NormalsMethod, Pipeline, PipelineConfig, DEFAULT_DSAC_HYPOTHESES, MAX_DSAC_HYPOTHESES,
};

/// On or off.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum Switch {
    /// Enabled.
    On,
    /// Disabled.
    Off,
}

/// Parser of `--dsac-hypotheses` (`infer`, `eval`, `serve`, `client`): 1 to
/// [`MAX_DSAC_HYPOTHESES`].
pub(crate) fn dsac_hypotheses_arg() -> clap::builder::RangedI64ValueParser<u32> {
    clap::value_parser!(u32).range(1..=i64::from(MAX_DSAC_HYPOTHESES))
}

/// The models folder for the `--models` value (see [`locate_models`]), logged with the rule
/// that found it; shared by every subcommand that loads models.
pub(crate) fn find_models(flag: Option<&Path>) -> anyhow::Result<PathBuf> {
    let found = locate_models(flag)?;
    tracing::info!(path = %found.dir.display(), "models folder found by {}", found.rule);
    Ok(found.dir)
}

/// The pipeline's switches and models, shared by `infer` and `eval`.
#[derive(Debug, Clone, Args)]
pub(crate) struct StageArgs {
    /// Staged pipeline or end-to-end baseline.
    #[arg(long, value_enum, default_value = "pipeline")]
    pub method: Method,
    /// Initial normals (ignored in geometric mode).
    #[arg(long, value_enum, default_value = "dsac")]
    pub normals: NormalsMethod,
    /// Normal refiner (ignored in geometric mode).
    #[arg(long, value_enum, default_value = "on")]
    pub refine: Switch,
    /// Centroids (ignored in geometric mode).
    #[arg(long, value_enum, default_value = "net")]
    pub centroid: CentroidMethod,
    /// What the geometric mode computes (ignored in the other modes).
    #[arg(long, value_enum, default_value = "spec")]
    pub geometric: GeometricMethod,
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
    pub(crate) fn config(&self, mode: Mode) -> PipelineConfig {
        PipelineConfig {
            mode,
            method: self.method,
            normals: self.normals,
            refine: self.refine == Switch::On,
            centroid: self.centroid,
            geometric: self.geometric,
            seed: self.seed,
            dsac_hypotheses: self.dsac_hypotheses,
            ..PipelineConfig::default()
        }
    }

    /// A pipeline with the models loaded when any of `configs` runs a network.
    pub(crate) fn pipeline(&self, configs: &[PipelineConfig]) -> anyhow::Result<Pipeline> {
        if configs.iter().all(|c| c.networks().is_empty()) {
            // The geometric mode needs no models, but reads their calibrated intervals when
            // a models folder is found.
            let calibration = match locate_models(self.models.as_deref()) {
                Ok(found) => read_calibration(&found.dir)?,
                Err(_) => None,
            };
            return Ok(Pipeline::new(None).with_calibration(calibration));
        }
        crate::model::check_threads(None, self.ort_threads, crate::model::cores())?;
        let session = SessionConfig {
            intra_threads: self.ort_threads,
            ..SessionConfig::default()
        };
        let dir = find_models(self.models.as_deref())?;
        let models = Models::load(&dir, &session)
            .with_context(|| format!("loading models from {}", dir.display()))?;
        let calibration = read_calibration(&dir)?;
        if let Some(stale) = calibration
            .as_ref()
            .and_then(|c| stale_calibration(c, models.manifest()))
        {
            tracing::warn!("{}: {stale}", dir.display());
        }
        let pipeline = Pipeline::new(Some(models));
        Ok(pipeline.with_calibration(calibration))
    }
}
