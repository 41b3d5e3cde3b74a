//! The node's settings (topics, frames, QoS, limits) and its counters.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::AtomicU64;
use std::sync::Mutex;
use std::time::Duration;

use tre_core::map::Pose as MapPose;

/// Reliability of the input subscriptions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Reliability {
    /// Best effort (ROS's sensor-data profile): matches every publisher, drops rather than
    /// resends.
    #[default]
    BestEffort,
    /// Reliable: matches reliable publishers only.
    Reliable,
}

/// Where the camera's pose comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum PoseSource {
    /// `nav_msgs/Odometry` on this topic.
    Odometry(String),
    /// `geometry_msgs/PoseStamped` on this topic.
    PoseStamped(String),
}

/// Topics, QoS and frame ids of the node.
#[derive(Debug, Clone)]
pub struct NodeConfig {
    /// DDS domain (`ROS_DOMAIN_ID`).
    pub domain_id: u16,
    /// Node name (`/namespace/name`).
    pub node_name: String,
    /// Depth image topic (16UC1 millimetres or 32FC1 metres).
    pub depth_topic: String,
    /// Colour image topic (rgb8, bgr8), read in the rgb and rgbd modes.
    pub colour_topic: String,
    /// camera_info topic of the image the mode reads (depth, else colour).
    pub info_topic: String,
    /// The pose source for the map; none: no map.
    pub pose: Option<PoseSource>,
    /// The camera's optical frame in the frame the pose places (identity: the pose is the
    /// camera's).
    pub camera_in_body: MapPose,
    /// Largest gap between a frame's stamp and its pose's.
    pub pose_tolerance: Duration,
    /// Prefix of the output topics: `{prefix}/roughness`, `/uncertainty`, `/traversal`,
    /// `/grid_map`, `/occupancy`.
    pub output_prefix: String,
    /// Reliability of the input subscriptions.
    pub input_reliability: Reliability,
    /// Log a kind of bad input at most this often.
    pub log_every: Duration,
    /// Record inputs and outputs to this MCAP file.
    pub record: Option<PathBuf>,
    /// Also record the outputs in Foxglove's JSON schemas.
    pub record_foxglove: bool,
    /// Make the recording's folder a rosbag2 bag (`metadata.yaml` beside the file).
    pub record_bag: bool,
}

impl Default for NodeConfig {
    fn default() -> Self {
        Self {
            domain_id: 0,
            node_name: "/tre".into(),
            depth_topic: "/camera/depth/image_rect_raw".into(),
            colour_topic: "/camera/color/image_raw".into(),
            info_topic: "/camera/depth/camera_info".into(),
            pose: None,
            camera_in_body: MapPose::identity(),
            pose_tolerance: Duration::from_millis(50),
            output_prefix: "/tre".into(),
            input_reliability: Reliability::BestEffort,
            log_every: Duration::from_secs(10),
            record: None,
            record_foxglove: false,
            record_bag: false,
        }
    }
}

/// What the node has done so far.
#[derive(Debug, Default)]
pub struct NodeStats {
    /// Frames received (depth, or colour in rgb mode).
    pub received: AtomicU64,
    /// Frames replaced in the slot before the worker took them, or older than the last one.
    pub dropped: AtomicU64,
    /// Frames skipped for bad input.
    pub skipped: AtomicU64,
    /// Frames processed and their outputs handed to the middleware.
    pub published: AtomicU64,
    /// Frames fused into the map.
    pub fused: AtomicU64,
    /// grid_map messages made (at most one a grid period).
    pub grids: AtomicU64,
    /// Messages the middleware took, by output topic under the prefix (`roughness`,
    /// `roughness/compressed`, `grid_map`, `occupancy`, ...).
    pub written: Mutex<BTreeMap<&'static str, u64>>,
    /// Messages the middleware refused (a reliable writer's send window still full of
    /// unacknowledged samples after its 20 ms wait), each logged; the next frame's replace them.
    pub unsent: AtomicU64,
}

impl NodeStats {
    /// Messages the middleware took on `topic` (under the prefix: `grid_map`, ...).
    pub fn written(&self, topic: &str) -> u64 {
        let w = self.written.lock().unwrap_or_else(|e| e.into_inner());
        w.get(topic).copied().unwrap_or(0)
    }
}
