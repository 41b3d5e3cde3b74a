//! tre-model's integration tests, one test binary (`cargo test -p tre-model --test model`): ONNX
//! Runtime loaded and run on a tiny model, every shipped model against the PyTorch outputs of
//! its export, the manifest check refusing models that disagree with `models/manifest.json`, and
//! dynamic batching on the committed models.

mod batching;
mod model_manifest;
mod onnx_parity;
mod ort_runtime;
