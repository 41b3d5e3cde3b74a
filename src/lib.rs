//! Terrain roughness estimation (TRENet): geometry, roughness annotation, models and service.
//!
//! This crate is a facade over the workspace's layers (the `tre` command line is its binary), each
//! a crate of its own so that the compiler enforces the dependency rule. Layers depend downward
//! only: [`geometry`], [`roughness`] and [`kinds`] (the domain choices; `tre-core`) are pure and
//! synchronous; [`io`] (`tre-io`) reads and writes the on-disk formats; [`synth`] (`tre-synth`)
//! makes synthetic scenes; [`model`] (`tre-model`) owns ONNX Runtime and the manifest;
//! [`pipeline`] (`tre-pipeline`) runs one frame through every stage; [`server`] (`tre-server`)
//! serves it over HTTP and a WebSocket stream whose messages are [`proto`] (`tre-proto`);
//! [`client`] (`tre-client`) is the robot's end of that stream; [`record`] (`tre-record`) writes ROS 2 messages and MCAP recordings, and `ros2` (`tre-ros2`) is the ROS 2 node and [`loadtest`]
//! (`tre-loadtest`) measures a running service; [`eval`] (`tre-eval`) scores the modes on real and synthetic frames.
pub use tre_client as client;
pub use tre_core::{geometry, kinds, map, roughness};
pub use tre_eval as eval;
pub use tre_io as io;
pub use tre_loadtest as loadtest;
pub use tre_model as model;
pub use tre_pipeline as pipeline;
pub use tre_proto as proto;
pub use tre_record as record;
/// The ROS 2 node (`tre-ros2`; cargo feature `ros2`, on by default).
#[cfg(feature = "ros2")]
pub use tre_ros2 as ros2;
pub use tre_server as server;
pub use tre_synth as synth;
