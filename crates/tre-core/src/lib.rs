//! The pure core of TRENet: [`geometry`] (cameras, back-projection, plane fits, DSAC plane
//! hypotheses, normals, Eq. 1) and [`roughness`] (the annotation spec, sensor noise, hazards,
//! traversability, metrics). Synchronous Rust with no I/O, no async runtime and no ONNX Runtime:
//! the layers above (`tre-pipeline`, `tre-server`) build on it, and a robot can use it alone on
//! its own depth.
pub mod geometry;
pub mod roughness;
