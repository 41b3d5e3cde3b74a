//! The pure core of TRENet: [`geometry`] (cameras, back-projection, plane fits, DSAC plane
//! hypotheses, normals, Eq. 1), [`roughness`] (the annotation spec, sensor noise, hazards,
//! traversability, metrics) and [`kinds`] (the domain choices that the pipeline, the service,
//! its client and the CLI share, each with its string forms derived once). Synchronous Rust with
//! no I/O, no async runtime and no ONNX Runtime: the layers above (`tre-pipeline`,
//! `tre-server`) build on it, and a robot can use it alone on its own depth.
pub mod geometry;
pub mod kinds;
pub mod map;
pub mod roughness;
