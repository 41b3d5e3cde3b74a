//! Learned stages: ONNX Runtime provisioning and sessions.
pub mod runtime;
