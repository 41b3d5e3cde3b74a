//! Learned stages: ONNX Runtime provisioning, the model manifest, and one checked session per
//! stage of the paper's Fig. 5.
//!
//! [`Models::load`] reads `models/manifest.json`, checks every listed file (existence, SHA-256,
//! opset) and every session's inputs and outputs (names, dtype, channels) against it, and
//! refuses a mismatch with an error naming the model and the field:
//!
//! ```no_run
//! # fn main() -> Result<(), tre_model::ModelError> {
//! use tre_model::{Models, SessionConfig};
//! let mut models = Models::load("models".as_ref(), &SessionConfig::default())?;
//! let rgb = ndarray::Array4::<f32>::zeros((1, 3, 256, 256));
//! let prior = ndarray::Array4::<f32>::ones((1, 1, 256, 256));
//! let depth_m = models.depth(rgb.view(), prior.view())?;
//! assert_eq!(depth_m.dim(), (1, 1, 256, 256));
//! # Ok(())
//! # }
//! ```

mod batcher;
mod locate;
mod manifest;
mod models;
mod onnx;
pub mod runtime;
mod session;

use std::fmt::Display;
use std::path::PathBuf;

pub use batcher::{
    BatchObserver, Batching, BatchingError, SharedModels, SharedNet, MAX_BATCH, MAX_BATCH_DELAY,
};
pub use locate::{find_models, locate_models, FoundModels, ModelSearch, ModelsRule, MODELS_ENV};
pub use manifest::{Dim, Manifest, ManifestProblem, ModelEntry, TensorSpec, MANIFEST_FORMAT};
pub use models::{Models, CENTROID_NET, DEPTH_NET, END_TO_END, NEIGHBOUR_NET, NORMAL_REFINER};
pub use onnx::OnnxParseError;
use runtime::RuntimeError;
pub use session::{
    check_threads, cores, ExecutionProvider, InputProblem, ModelSession, OnnxProblem, Optimisation,
    Provider, ProviderMissing, SessionConfig, ThreadsError, MAX_WORKERS_PER_CORE,
};

/// Errors of the model layer; every variant about one model names it.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The folder named by `--models` or `TRE_MODELS` holds no `manifest.json`.
    #[error("{rule} names {}, which holds no manifest.json; point it at a folder holding manifest.json and the .onnx files it lists, or drop it to search the usual places", dir.display())]
    ModelsDirMissing {
        /// The rule that named it (`--models` or `TRE_MODELS`).
        rule: ModelsRule,
        /// The folder.
        dir: PathBuf,
    },
    /// No models folder in any of the places searched.
    #[error(
        "no models folder (one holding manifest.json) found; looked, in order, at: {}; {}",
        locate::list_searched(searched),
        locate::MODELS_FIX
    )]
    ModelsNotFound {
        /// Every folder tried, in order, with the rule that named it.
        searched: Vec<(ModelsRule, PathBuf)>,
    },
    /// `manifest.json` is missing, unreadable or malformed.
    // Here and below, the reason is in the message, not a `source`: a report that prints the
    // chain would say it twice. The server answers with the message alone, so it must carry
    // the reason.
    #[error("{}: {reason}", path.display())]
    Manifest {
        /// The manifest file.
        path: PathBuf,
        /// What is wrong.
        reason: ManifestProblem,
    },
    /// The manifest does not list a model the caller needs.
    #[error("model {model}: not listed in the manifest")]
    NotInManifest {
        /// The model's name.
        model: String,
    },
    /// The manifest lists a file that does not exist.
    #[error("model {model}: file {} does not exist", path.display())]
    MissingFile {
        /// The model's name.
        model: String,
        /// The missing file.
        path: PathBuf,
    },
    /// A file or session that disagrees with its manifest entry.
    #[error("model {model}: manifest field `{field}` says {expected}, but the model has {found}")]
    Mismatch {
        /// The model's name.
        model: String,
        /// The manifest field, e.g. `sha256`, `opset`, `inputs[1].name`.
        field: String,
        /// What the manifest says.
        expected: String,
        /// What the file or session has.
        found: String,
    },
    /// A file that cannot be read or is not an ONNX model.
    #[error("model {model}: {}: {reason}", path.display())]
    BadOnnx {
        /// The model's name.
        model: String,
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: OnnxProblem,
    },
    /// ONNX Runtime could not be found or started.
    #[error(transparent)]
    Runtime(#[from] RuntimeError),
    /// ONNX Runtime failed to build or run a session.
    #[error("model {model}: ONNX Runtime: {reason}")]
    Ort {
        /// The model's name.
        model: String,
        /// What ONNX Runtime said.
        reason: ort::Error,
    },
    /// An input of the wrong number, shape or size for the model.
    #[error("model {model}: input {input}: {reason}")]
    InputShape {
        /// The model's name.
        model: String,
        /// The input's name (`*` for the input count).
        input: String,
        /// What is wrong.
        reason: InputProblem,
    },
    /// The model returned an output of an unexpected shape.
    #[error("model {model}: output {output} is not of shape {expected:?}")]
    OutputShape {
        /// The model's name.
        model: String,
        /// The output's name.
        output: String,
        /// The expected N, C, H, W.
        expected: Vec<usize>,
    },
    /// Batching bounds out of range.
    #[error("{0}")]
    Batching(BatchingError),
    /// A model's batching thread could not be started.
    #[error("model {model}: starting its batching thread: {reason}")]
    BatcherStart {
        /// The model's name.
        model: String,
        /// What the system said.
        reason: String,
    },
    /// A model's batching thread gave no answer: it has stopped (the service is stopping) or
    /// the batch hit a bug.
    #[error("model {model}: no answer from its batching thread (stopped, or the batch hit a bug)")]
    BatcherStopped {
        /// The model's name.
        model: String,
    },
    /// The inputs of a batch could not be joined (a bug: they were checked one by one).
    #[error("model {model}: joining a batch: {reason}")]
    BatchJoin {
        /// The model's name.
        model: String,
        /// What went wrong.
        reason: String,
    },
    /// The batch this request ran in failed; the first request of the batch got the error
    /// itself.
    #[error("model {model}: the batch failed: {reason}")]
    BatchFailed {
        /// The model's name.
        model: String,
        /// The batch's error.
        reason: String,
    },
}

impl ModelError {
    /// A [`ModelError::Mismatch`].
    pub fn mismatch(model: &str, field: &str, expected: impl Display, found: impl Display) -> Self {
        Self::Mismatch {
            model: model.to_owned(),
            field: field.to_owned(),
            expected: expected.to_string(),
            found: found.to_string(),
        }
    }
}
