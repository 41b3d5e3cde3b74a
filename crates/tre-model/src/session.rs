//! One validated ONNX Runtime session per model: built from the manifest entry after its file,
//! SHA-256, opset and tensor names and channels have been checked, and run on NCHW float32
//! arrays.

use std::path::Path;
use std::time::{Duration, Instant};

use ndarray::{Array4, ArrayView4, Ix4};
use ort::session::builder::GraphOptimizationLevel;
use ort::session::Session;
use ort::value::TensorRef;
use serde::{Deserialize, Serialize};

use super::manifest::{sha256_hex, ModelEntry, TensorSpec};
use super::onnx;
use super::{runtime, ModelError};

/// How ONNX Runtime builds each session. The default runs on the CPU with every graph
/// optimisation and ONNX Runtime's own choice of thread count.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct SessionConfig {
    /// Threads inside one operator; 0 lets ONNX Runtime choose (one per core).
    pub intra_threads: usize,
    /// Graph optimisation level.
    pub optimisation: Optimisation,
    /// Where the graph runs.
    pub provider: ExecutionProvider,
    /// Let ONNX Runtime's idle intra-op threads spin between runs. Off by default: the
    /// pipeline's geometry (DSAC, LS fits) runs on the same cores right after each net, and
    /// spinning threads would take the cores from it.
    pub spin: bool,
}

/// ONNX Runtime graph optimisation levels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Optimisation {
    /// No rewriting.
    Disable,
    /// Constant folding and redundant-node removal.
    Basic,
    /// Basic plus complex fusions.
    Extended,
    /// Everything, including layout changes.
    #[default]
    All,
}

/// Execution providers. CUDA and TensorRT exist only when `tre` is built with the cargo
/// features `cuda` or `tensorrt` (which enable `ort`'s features of the same names); the ONNX
/// Runtime library loaded at run time must then be a GPU build. ONNX Runtime falls back to the
/// CPU for operators the provider cannot run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum ExecutionProvider {
    /// ONNX Runtime's CPU kernels.
    #[default]
    Cpu,
    /// NVIDIA CUDA on the given device.
    #[cfg(feature = "cuda")]
    Cuda {
        /// CUDA device index.
        device_id: i32,
    },
    /// NVIDIA TensorRT on the given device.
    #[cfg(feature = "tensorrt")]
    TensorRt {
        /// CUDA device index.
        device_id: i32,
    },
}

/// The execution provider a user names (`tre serve --provider`), whether or not this build
/// has it; [`ExecutionProvider::of`] turns it into one this build can run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Provider {
    /// ONNX Runtime's CPU kernels.
    #[default]
    Cpu,
    /// NVIDIA CUDA (needs a build with `--features cuda` and a GPU build of ONNX Runtime).
    Cuda,
    /// NVIDIA TensorRT (needs a build with `--features tensorrt` and a GPU build of ONNX Runtime).
    Tensorrt,
}

/// A provider this build of tre was compiled without (see [`ExecutionProvider`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error(
    "--provider {provider:?}: this build of tre lacks the cargo feature for it (build with \
     --features cuda or tensorrt)"
)]
pub struct ProviderMissing {
    /// The provider asked for.
    pub provider: Provider,
}

impl ExecutionProvider {
    /// `provider` on GPU `device_id` (the CPU ignores it), if this build has it.
    ///
    /// # Errors
    ///
    /// [`ProviderMissing`] for CUDA or TensorRT in a build without their cargo feature.
    pub fn of(provider: Provider, device_id: i32) -> Result<Self, ProviderMissing> {
        let _ = device_id;
        Ok(match provider {
            Provider::Cpu => Self::Cpu,
            #[cfg(feature = "cuda")]
            Provider::Cuda => Self::Cuda { device_id },
            #[cfg(feature = "tensorrt")]
            Provider::Tensorrt => Self::TensorRt { device_id },
            // Reachable or not depending on the GPU features this build has.
            #[allow(unreachable_patterns)]
            provider => return Err(ProviderMissing { provider }),
        })
    }
}

impl From<Optimisation> for GraphOptimizationLevel {
    fn from(level: Optimisation) -> Self {
        match level {
            Optimisation::Disable => GraphOptimizationLevel::Disable,
            Optimisation::Basic => GraphOptimizationLevel::Level1,
            Optimisation::Extended => GraphOptimizationLevel::Level2,
            Optimisation::All => GraphOptimizationLevel::All,
        }
    }
}

/// A checked session for one model. `Session::run` needs `&mut self`, so a `ModelSession`
/// belongs to one worker thread.
#[derive(Debug)]
pub struct ModelSession {
    name: String,
    entry: ModelEntry,
    stride: usize,
    session: Session,
    /// Wall time spent inside ONNX Runtime's `run`, over the session's life.
    busy: Duration,
}

impl ModelSession {
    /// Checks model `name`'s file in `dir` against its manifest `entry` (existence, SHA-256,
    /// opset), builds its session and checks the session's inputs and outputs (count, names,
    /// float32, channels). H and W of every run must be multiples of `stride`.
    ///
    /// # Errors
    ///
    /// [`ModelError::MissingFile`], [`ModelError::Mismatch`] naming the model and the field,
    /// [`ModelError::BadOnnx`], [`ModelError::Runtime`] or [`ModelError::Ort`].
    pub fn load(
        dir: &Path,
        name: &str,
        entry: &ModelEntry,
        stride: usize,
        cfg: &SessionConfig,
    ) -> Result<Self, ModelError> {
        let path = dir.join(&entry.file);
        check_file(name, &path, entry)?;
        let session = build_session(name, &path, cfg)?;
        check_outlets(name, "inputs", &entry.inputs, session.inputs())?;
        check_outlets(name, "outputs", &entry.outputs, session.outputs())?;
        Ok(Self {
            name: name.to_owned(),
            entry: entry.clone(),
            stride,
            session,
            busy: Duration::ZERO,
        })
    }

    /// The model's name in the manifest.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Wall time spent inside ONNX Runtime's `run` so far, over all runs (input checks and
    /// the handling of outputs are not counted).
    pub fn onnx_runtime_time(&self) -> Duration {
        self.busy
    }

    /// The model's manifest entry.
    pub fn entry(&self) -> &ModelEntry {
        &self.entry
    }

    /// Runs the model on its inputs, in manifest order (each `1..N × C × H × W`, the same N, H
    /// and W, H and W multiples of the stride) and returns its first output.
    ///
    /// # Errors
    ///
    /// [`ModelError::InputShape`] for inputs of the wrong number or shape,
    /// [`ModelError::Ort`] when ONNX Runtime fails, [`ModelError::OutputShape`] for an output
    /// that is not `N × C × H × W`.
    pub fn run(&mut self, inputs: &[ArrayView4<'_, f32>]) -> Result<Array4<f32>, ModelError> {
        self.run_with(inputs, |y| y.as_standard_layout().into_owned())
    }

    /// Runs the model like [`ModelSession::run`] and hands its first output to `consume` as a
    /// view of ONNX Runtime's own buffer, without copying it (the neighbour net's 49 logits per
    /// pixel are 12.8 MB at 256×256).
    ///
    /// # Errors
    ///
    /// Those of [`ModelSession::run`].
    pub fn run_with<R>(
        &mut self,
        inputs: &[ArrayView4<'_, f32>],
        consume: impl FnOnce(ArrayView4<'_, f32>) -> R,
    ) -> Result<R, ModelError> {
        let (n, h, w) = self.check_inputs(inputs)?;
        let ort_err = |reason| ModelError::Ort {
            model: self.name.clone(),
            reason,
        };
        let mut values = Vec::with_capacity(inputs.len());
        for (spec, x) in self.entry.inputs.iter().zip(inputs) {
            let tensor = TensorRef::from_array_view(x.view()).map_err(ort_err)?;
            values.push((spec.name.as_str(), tensor));
        }
        let out_spec = &self.entry.outputs[0];
        let start = Instant::now();
        let outputs = self.session.run(values);
        self.busy += start.elapsed();
        let outputs = outputs.map_err(ort_err)?;
        let y = outputs[out_spec.name.as_str()]
            .try_extract_array::<f32>()
            .map_err(ort_err)?;
        let c = out_spec
            .channels()
            .unwrap_or(y.shape()[1.min(y.ndim() - 1)]);
        let y4 = y
            .into_dimensionality::<Ix4>()
            .ok()
            .filter(|y| y.dim() == (n, c, h, w));
        match y4 {
            Some(y) => Ok(consume(y)),
            None => Err(ModelError::OutputShape {
                model: self.name.clone(),
                output: out_spec.name.clone(),
                expected: vec![n, c, h, w],
            }),
        }
    }

    /// Checks inputs as [`ModelSession::run`] does, without running the model.
    ///
    /// # Errors
    ///
    /// [`ModelError::InputShape`] for inputs of the wrong number or shape.
    pub fn check(&self, inputs: &[ArrayView4<'_, f32>]) -> Result<(), ModelError> {
        self.check_inputs(inputs).map(|_| ())
    }

    /// Checks the inputs against the manifest; returns their N, H and W.
    fn check_inputs(
        &self,
        inputs: &[ArrayView4<'_, f32>],
    ) -> Result<(usize, usize, usize), ModelError> {
        let bad = |input: &str, reason| ModelError::InputShape {
            model: self.name.clone(),
            input: input.to_owned(),
            reason,
        };
        if inputs.len() != self.entry.inputs.len() {
            let reason = InputProblem::Count {
                given: inputs.len(),
                expected: self.entry.inputs.len(),
            };
            return Err(bad("*", reason));
        }
        let (n, _, h, w) = inputs.first().map_or((0, 0, 0, 0), ArrayView4::dim);
        if n == 0 || h == 0 || w == 0 || h % self.stride != 0 || w % self.stride != 0 {
            let reason = InputProblem::Size {
                n,
                h,
                w,
                stride: self.stride,
            };
            return Err(bad(&self.entry.inputs[0].name, reason));
        }
        for (spec, x) in self.entry.inputs.iter().zip(inputs) {
            let (xn, xc, xh, xw) = x.dim();
            let c_ok = spec.channels().is_none_or(|c| c == xc);
            if (xn, xh, xw) != (n, h, w) || !c_ok {
                let reason = InputProblem::Shape {
                    shape: x.shape().to_vec(),
                    expected: (n, spec.channels(), h, w),
                };
                return Err(bad(&spec.name, reason));
            }
        }
        Ok((n, h, w))
    }
}

/// Why inputs do not fit a model ([`ModelError::InputShape`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum InputProblem {
    /// Another number of inputs than the model has.
    #[error("{given} inputs given, {expected} expected")]
    Count {
        /// Inputs given.
        given: usize,
        /// Inputs the model has.
        expected: usize,
    },
    /// A batch or size of 0, or H or W not a multiple of the stride.
    #[error("N×H×W = {n}×{h}×{w}: all must be positive, H and W multiples of {stride}")]
    Size {
        /// Batch size.
        n: usize,
        /// Height.
        h: usize,
        /// Width.
        w: usize,
        /// The stride H and W must be multiples of.
        stride: usize,
    },
    /// An input of another N, H or W than the first, or of other channels than the manifest's.
    #[error(
        "shape {shape:?}, expected {}×{}×{}×{}",
        expected.0,
        expected.1.map_or("C".to_owned(), |c| c.to_string()),
        expected.2,
        expected.3
    )]
    Shape {
        /// The input's shape.
        shape: Vec<usize>,
        /// The N, channels (if the manifest fixes them; else any, shown as `C`), H and W
        /// expected.
        expected: (usize, Option<usize>, usize, usize),
    },
}

/// Why a model's file cannot be checked ([`ModelError::BadOnnx`]).
#[derive(Debug, thiserror::Error)]
pub enum OnnxProblem {
    /// The file cannot be read.
    #[error(transparent)]
    Read(std::io::Error),
    /// The bytes are not an ONNX model.
    #[error(transparent)]
    Parse(onnx::OnnxParseError),
}

/// The file exists, hashes to the manifest's SHA-256 and imports the manifest's opset.
fn check_file(model: &str, path: &Path, entry: &ModelEntry) -> Result<(), ModelError> {
    if !path.is_file() {
        return Err(ModelError::MissingFile {
            model: model.to_owned(),
            path: path.to_owned(),
        });
    }
    let bad_onnx = |reason| ModelError::BadOnnx {
        model: model.to_owned(),
        path: path.to_owned(),
        reason,
    };
    let bytes = std::fs::read(path).map_err(|e| bad_onnx(OnnxProblem::Read(e)))?;
    let sha = sha256_hex(&bytes);
    if !sha.eq_ignore_ascii_case(entry.sha256.trim()) {
        return Err(ModelError::mismatch(model, "sha256", &entry.sha256, sha));
    }
    let imports = onnx::opset_imports(&bytes).map_err(|e| bad_onnx(OnnxProblem::Parse(e)))?;
    let found = onnx::default_opset(&imports).map_or_else(|| "none".to_owned(), |v| v.to_string());
    if found != entry.opset.to_string() {
        return Err(ModelError::mismatch(model, "opset", entry.opset, found));
    }
    Ok(())
}

/// Builds the session with the configured threads, optimisation and provider.
fn build_session(model: &str, path: &Path, cfg: &SessionConfig) -> Result<Session, ModelError> {
    let env = runtime::environment()?;
    let ort_err = |e: ort::Error<_>| ModelError::Ort {
        model: model.to_owned(),
        reason: ort::Error::new_with_code(e.code(), e.message()),
    };
    let builder = Session::builder(env).map_err(|reason| ModelError::Ort {
        model: model.to_owned(),
        reason,
    })?;
    let mut builder = builder
        .with_optimization_level(cfg.optimisation.into())
        .map_err(ort_err)?;
    builder = builder.with_intra_op_spinning(cfg.spin).map_err(ort_err)?;
    if cfg.intra_threads > 0 {
        builder = builder
            .with_intra_threads(cfg.intra_threads)
            .map_err(ort_err)?;
    }
    if let Some(provider) = provider_dispatch(cfg.provider) {
        builder = builder
            .with_execution_providers([provider])
            .map_err(ort_err)?;
    }
    builder
        .commit_from_file(path)
        .map_err(|reason| ModelError::Ort {
            model: model.to_owned(),
            reason,
        })
}

/// The `ort` provider to register (none for the CPU, ONNX Runtime's default).
fn provider_dispatch(provider: ExecutionProvider) -> Option<ort::ep::ExecutionProviderDispatch> {
    match provider {
        ExecutionProvider::Cpu => None,
        #[cfg(feature = "cuda")]
        ExecutionProvider::Cuda { device_id } => Some(
            ort::ep::CUDA::default()
                .with_device_id(device_id)
                .build()
                .error_on_failure(),
        ),
        #[cfg(feature = "tensorrt")]
        ExecutionProvider::TensorRt { device_id } => Some(
            ort::ep::TensorRT::default()
                .with_device_id(device_id)
                .build()
                .error_on_failure(),
        ),
    }
}

/// The session's inputs or outputs (`which`) agree with the manifest: count, names in order,
/// float32, and fixed channel counts.
fn check_outlets(
    model: &str,
    which: &str,
    specs: &[TensorSpec],
    outlets: &[ort::value::Outlet],
) -> Result<(), ModelError> {
    if specs.len() != outlets.len() {
        let field = format!("{which}.count");
        return Err(ModelError::mismatch(
            model,
            &field,
            specs.len(),
            outlets.len(),
        ));
    }
    for (i, (spec, outlet)) in specs.iter().zip(outlets).enumerate() {
        if spec.name != outlet.name() {
            let field = format!("{which}[{i}].name");
            return Err(ModelError::mismatch(
                model,
                &field,
                &spec.name,
                outlet.name(),
            ));
        }
        let dtype = outlet.dtype();
        let is_f32 = matches!(
            dtype,
            ort::value::ValueType::Tensor {
                ty: ort::value::TensorElementType::Float32,
                ..
            }
        );
        if spec.dtype != "float32" || !is_f32 {
            let field = format!("{which}[{i}].dtype");
            return Err(ModelError::mismatch(model, &field, &spec.dtype, dtype));
        }
        let found_c = dtype.tensor_shape().and_then(|s| s.get(1).copied());
        let found_c = found_c.filter(|&c| c > 0);
        if let (Some(want), Some(got)) = (spec.channels(), found_c) {
            if i64::try_from(want).ok() != Some(got) {
                let field = format!("{which}[{i}].channels");
                return Err(ModelError::mismatch(model, &field, want, got));
            }
        }
    }
    Ok(())
}

/// Inference workers allowed per core.
pub const MAX_WORKERS_PER_CORE: usize = 4;

/// A thread count that the cores cannot use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum ThreadsError {
    /// More ONNX Runtime threads per operator than cores.
    #[error(
        "--ort-threads {threads}: at most {cores}, the cores this process may use (0 chooses); \
         more threads per operator than cores only slow each frame"
    )]
    OrtThreads {
        /// Threads asked for.
        threads: usize,
        /// Cores this process may use.
        cores: usize,
    },
    /// More workers than [`MAX_WORKERS_PER_CORE`] per core.
    #[error(
        "--workers {workers}: at most {} ({MAX_WORKERS_PER_CORE} per core, {cores} cores here; 0 \
         chooses one per core); each worker holds its own sessions and frame buffers",
        MAX_WORKERS_PER_CORE * cores
    )]
    Workers {
        /// Workers asked for.
        workers: usize,
        /// Cores this process may use.
        cores: usize,
    },
}

/// The cores this process may use (its CPU affinity and quota).
#[must_use]
pub fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, usize::from)
}

/// Refuses thread counts that `cores` cannot use: more ONNX Runtime threads per operator than
/// cores, or more than [`MAX_WORKERS_PER_CORE`] workers per core, only slow every frame, and
/// large ones exhaust the system's threads (`--ort-threads 50000` stalls every process of the
/// user, the robot's own included). `workers` is `None` for a single pipeline.
pub fn check_threads(
    workers: Option<usize>,
    ort_threads: usize,
    cores: usize,
) -> Result<(), ThreadsError> {
    if ort_threads > cores {
        return Err(ThreadsError::OrtThreads {
            threads: ort_threads,
            cores,
        });
    }
    if let Some(w) = workers.filter(|&w| w > MAX_WORKERS_PER_CORE * cores) {
        return Err(ThreadsError::Workers { workers: w, cores });
    }
    Ok(())
}

#[cfg(test)]
mod thread_tests {
    use super::*;

    #[test]
    fn thread_counts_beyond_the_cores_are_refused() {
        for (workers, ort) in [(None, 0), (None, 2), (Some(8), 2), (Some(1), 1)] {
            check_threads(workers, ort, 2).unwrap();
        }
        let e = check_threads(None, 3, 2).unwrap_err().to_string();
        assert!(e.contains("--ort-threads 3: at most 2"), "{e}");
        let e = check_threads(Some(9), 1, 2).unwrap_err().to_string();
        assert!(e.contains("--workers 9: at most 8"), "{e}");
        assert!(check_threads(Some(1), 50_000, 16).is_err());
    }
}

#[cfg(test)]
mod input_tests {
    use super::*;

    #[test]
    fn input_problems_read_as_before() {
        let count = InputProblem::Count {
            given: 1,
            expected: 2,
        };
        assert_eq!(count.to_string(), "1 inputs given, 2 expected");
        let size = InputProblem::Size {
            n: 1,
            h: 30,
            w: 64,
            stride: 32,
        };
        assert_eq!(
            size.to_string(),
            "N×H×W = 1×30×64: all must be positive, H and W multiples of 32"
        );
        let shape = InputProblem::Shape {
            shape: vec![1, 1, 64, 64],
            expected: (1, Some(3), 64, 64),
        };
        assert_eq!(
            shape.to_string(),
            "shape [1, 1, 64, 64], expected 1×3×64×64"
        );
        let any_c = InputProblem::Shape {
            shape: vec![2, 1, 64, 64],
            expected: (1, None, 64, 64),
        };
        assert_eq!(
            any_c.to_string(),
            "shape [2, 1, 64, 64], expected 1×C×64×64"
        );
        let e = ModelError::InputShape {
            model: "depth_net".into(),
            input: "rgb".into(),
            reason: shape,
        };
        assert_eq!(
            e.to_string(),
            "model depth_net: input rgb: shape [1, 1, 64, 64], expected 1×3×64×64"
        );
    }
}
