//! Terrain roughness estimation (TRENet): geometry, roughness annotation, models and service.
//!
//! Layers depend downward only: [`geometry`] and [`roughness`] are pure and synchronous;
//! [`io`] reads and writes the on-disk formats; [`model`] owns ONNX Runtime and the manifest;
//! [`pipeline`] runs one frame through every stage; [`server`] serves it over HTTP and a
//! WebSocket stream, [`client`] is the robot's end of that stream and [`loadtest`] measures a
//! running service; the CLI sits on top.
pub mod cli;
pub mod client;
pub mod geometry;
pub mod io;
pub mod loadtest;
pub mod model;
pub mod pipeline;
pub mod proto;
pub mod roughness;
pub mod server;
pub mod synth;
