//! ONNX Runtime location and start-up.
