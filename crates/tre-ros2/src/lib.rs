//! The ROS 2 node of tre (docs/ros2.md); its messages and recordings are `tre-record`'s.
//!
//! The node speaks DDS through `ros2-client` (pure Rust, over RustDDS): no ROS installation is
//! needed to build or run it. It subscribes to a depth image (`16UC1` millimetres or `32FC1`
//! metres, REP 118), a colour image in the rgb and rgbd modes, their `CameraInfo` and
//! optionally a pose (`nav_msgs/Odometry` or `geometry_msgs/PoseStamped`); it publishes, with
//! the input's header, roughness (`32FC1` metres, or `mono16` millimetres), on request the
//! uncertainty (`32FC1`, metres) and the three-state map (`mono8`), each also as a PNG
//! `sensor_msgs/CompressedImage` on `{topic}/compressed`, and with a pose the fused map as
//! `grid_map_msgs/GridMap` and `nav_msgs/OccupancyGrid` (transient-local, for Nav2's static
//! layer).
//!
//! - [`convert`]: messages to the pipeline's inputs (the way back is `tre_record::encode`);
//! - [`rectify`]: a raw, distorted image remapped into its camera_info's pinhole (`--undistort`);
//! - [`Processor`]: one frame through the pipeline and the map, without DDS;
//! - [`start`]: the node, which records with `tre_record::Recorder`.

// One ROS 2 distribution's wire details at a time (ros2-client's Gid size and more differ).
#[cfg(all(feature = "jazzy", feature = "humble"))]
compile_error!(
    "tre-ros2: the features `jazzy` and `humble` exclude each other; for Humble build the tre \
     package with `--no-default-features --features ros2-humble`"
);

#[cfg(feature = "cli")]
mod cli;
mod compressed;
pub mod convert;
mod error;
mod limiter;
mod node;
mod process;
pub mod rectify;

#[cfg(feature = "cli")]
pub use cli::{InputReliability, Ros2Args, RoughnessImage};
pub use error::{ConfigProblem, DdsFault, InputError, Ros2Error};
pub use node::{start, NodeConfig, NodeStats, PoseSource, Reliability, RunningNode};
pub use process::{FrameMsgs, ImageOutputs, MapSettings, Outputs, Processor, RoughnessEncoding};
/// The ROS 2 distribution the node was built for (cargo feature `jazzy` or `humble`).
pub use ros2_client::COMPILED_ROS_DISTRO;
