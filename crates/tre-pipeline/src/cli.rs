//! The pipeline's options as `tre infer`, `eval`, `map` and `calibrate` take them (the `cli`
//! feature): the switches of [`PipelineConfig`], the models folder and the threads.

use std::path::PathBuf;

use clap::builder::TypedValueParser;

use super::{Mode, Pipeline, PipelineConfig, PipelineError};

/// The pipeline's switches and models.
#[derive(Debug, Clone, clap::Args)]
pub struct StageArgs {
    /// The switches (the mode is each command's).
    #[command(flatten)]
    pub config: PipelineConfig,
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
    pub fn config(&self, mode: Mode) -> PipelineConfig {
        PipelineConfig {
            mode,
            ..self.config
        }
    }

    /// A pipeline for `configs` ([`Pipeline::for_configs`]).
    ///
    /// # Errors
    ///
    /// As [`Pipeline::for_configs`].
    pub fn pipeline(&self, configs: &[PipelineConfig]) -> Result<Pipeline, PipelineError> {
        Pipeline::for_configs(self.models.as_deref(), self.ort_threads, configs)
    }
}

/// A `--working-size` that is not `WIDTHxHEIGHT`.
#[derive(Debug, thiserror::Error)]
#[error("{0:?}: expected WIDTHxHEIGHT in pixels, e.g. 320x240")]
pub(crate) struct WorkingSizeError(String);

/// clap's parser of `--working-size WIDTHxHEIGHT` (the range is checked where the frame is
/// known: `PipelineError::BadWorkingSize`).
pub(crate) fn working_size(s: &str) -> Result<(usize, usize), WorkingSizeError> {
    let bad = || WorkingSizeError(s.to_owned());
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    Ok((
        w.trim().parse().map_err(|_| bad())?,
        h.trim().parse().map_err(|_| bad())?,
    ))
}

/// On or off.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum Switch {
    /// Enabled.
    On,
    /// Disabled.
    Off,
}

/// clap's parser of an on/off switch into a `bool` (`--refine on`).
pub(crate) fn on_off() -> impl TypedValueParser<Value = bool> {
    clap::builder::EnumValueParser::<Switch>::new().map(|s| s == Switch::On)
}
