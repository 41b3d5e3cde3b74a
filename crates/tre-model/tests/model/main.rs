//! tre-model's integration tests, one test binary (`cargo test -p tre-model --test model`): ONNX
//! Runtime loaded and run on a tiny model, every shipped model against the PyTorch outputs of
//! its export, the manifest check refusing models that disagree with `models/manifest.json`, and
//! dynamic batching on the committed models.

mod batching;
mod model_manifest;
mod onnx_parity;
mod ort_runtime;

use std::path::{Path, PathBuf};

use tre_model::SessionConfig;

/// The committed models, two folders above this crate.
fn models_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models")
}

/// One ONNX Runtime thread per session.
fn cfg() -> SessionConfig {
    SessionConfig {
        intra_threads: 1,
        ..SessionConfig::default()
    }
}
