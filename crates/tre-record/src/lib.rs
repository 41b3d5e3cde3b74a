//! ROS 2 messages and MCAP recordings, without DDS: what `tre ros2`, `tre client` and `tre map`
//! write with `--record FILE.mcap` (docs/ros2.md says which viewer shows which channel).
//!
//! - [`msgs`]: the message types, their CDR and their `ros2msg` definitions;
//! - [`encode`]: tre's frames, poses, outputs and maps as those messages;
//! - [`type_hash`]: their ROS 2 type hashes (REP 2016);
//! - [`Recorder`]: an MCAP file, each message in its ROS 2 type and the outputs again in
//!   Foxglove's own schemas.

pub mod encode;
pub mod msgs;
mod recorder;
pub mod type_hash;

pub use recorder::{
    now_ns, topics, Colour, FrameRecord, RecordError, RecordFault, RecordOptions, Recorder,
};
