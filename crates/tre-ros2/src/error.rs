//! What can go wrong: a message on a topic that cannot be used ([`InputError`]: logged,
//! rate-limited, and skipped; the node keeps running) and what stops the node from starting or
//! a recording from being written ([`Ros2Error`]).

use tre_core::geometry::GeometryError;
use tre_io::DepthError;
use tre_pipeline::PipelineError;

/// Why a frame from the topics was skipped. Each cause is in the message (the node logs the
/// message alone).
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// An image encoding the node does not read.
    #[error("{topic} image: encoding {encoding:?} is not read; expected {expected}")]
    Encoding {
        /// Which input.
        topic: &'static str,
        /// The encoding sent.
        encoding: String,
        /// What is read.
        expected: &'static str,
    },
    /// An image of no pixels.
    #[error("image of no pixels")]
    Empty,
    /// Fewer bytes than `step × height`, or a step shorter than a row.
    #[error(
        "image data of {bytes} bytes does not hold {width}×{height} pixels at a step of {step} bytes"
    )]
    ShortData {
        /// Bytes per row.
        step: u32,
        /// Columns.
        width: u32,
        /// Rows.
        height: u32,
        /// Bytes sent.
        bytes: usize,
    },
    /// A depth frame that cannot be depth (nothing valid, or the wrong units).
    #[error("depth image: {0}")]
    Depth(DepthError),
    /// A camera_info whose size is not the image's.
    #[error(
        "camera_info is {}×{} but the image is {}×{}: they must describe the same frame",
        info.0, info.1, image.0, image.1
    )]
    SizeMismatch {
        /// `(width, height)` of the camera_info.
        info: (u32, u32),
        /// `(width, height)` of the image.
        image: (u32, u32),
    },
    /// No camera_info has arrived yet.
    #[error("no camera_info received yet: the frame's intrinsics are unknown")]
    NoCameraInfo,
    /// Intrinsics that are not a pinhole for this image.
    #[error("camera_info intrinsics (p, or k): {0}")]
    Intrinsics(GeometryError),
    /// A distortion `--undistort` does not model.
    #[error(
        "camera_info distortion model {model:?} with {coefficients} coefficients is not \
         modelled by --undistort (plumb_bob and rational_polynomial, at most 8): rectify the \
         image first (image_proc) and subscribe to the rectified topic"
    )]
    Distortion {
        /// The model named.
        model: String,
        /// How many coefficients `d` has.
        coefficients: usize,
    },
    /// A pose whose orientation is not a unit quaternion, or not finite.
    #[error(
        "pose: the orientation is not a unit quaternion (norm {norm}) or a value is not finite"
    )]
    Pose {
        /// The quaternion's norm.
        norm: f64,
    },
    /// The pipeline refused the frame.
    #[error("pipeline: {0}")]
    Pipeline(PipelineError),
}

impl InputError {
    /// A short name of the kind of problem, for rate-limited logging (one line per kind).
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Encoding { .. } => "encoding",
            Self::Empty | Self::ShortData { .. } => "image size",
            Self::Depth(_) => "depth",
            Self::SizeMismatch { .. } => "camera_info size",
            Self::NoCameraInfo => "camera_info missing",
            Self::Intrinsics(_) => "camera_info intrinsics",
            Self::Distortion { .. } => "camera_info distortion",
            Self::Pose { .. } => "pose",
            Self::Pipeline(_) => "pipeline",
        }
    }
}

/// Why the node could not start, or a recording could not be written.
#[derive(Debug, thiserror::Error)]
pub enum Ros2Error {
    /// A DDS participant, node, topic or endpoint could not be made.
    #[error("ROS 2 ({what}): {fault}")]
    Dds {
        /// What was being made.
        what: &'static str,
        /// What failed.
        fault: DdsFault,
    },
    /// A topic or node name ROS 2 does not accept.
    #[error("ROS 2 name {name:?}: {why:?}")]
    Name {
        /// The name.
        name: String,
        /// ros2-client's error, which prints itself through `Debug` only.
        why: Box<dyn std::fmt::Debug + Send + Sync>,
    },
    /// Options that do not go together.
    #[error("{0}")]
    Config(ConfigProblem),
    /// The pipeline could not be made (its models did not load).
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
    /// The MCAP recording could not be written.
    #[error(transparent)]
    Record(#[from] tre_record::RecordError),
}

/// What failed in making a DDS participant, node, topic, endpoint or thread.
#[derive(Debug, thiserror::Error)]
pub enum DdsFault {
    /// RustDDS or ros2-client refused; their errors print themselves through `Debug` only.
    #[error("{0:?}")]
    Refused(Box<dyn std::fmt::Debug + Send + Sync>),
    /// A thread could not be started.
    #[error(transparent)]
    Thread(#[from] std::io::Error),
    /// A thread panicked.
    #[error("panicked")]
    Panicked,
}

/// Options of the node that do not go together.
#[derive(Debug, thiserror::Error)]
pub enum ConfigProblem {
    /// A map was asked for (a pose topic) without the sensor model its heights need.
    #[error(
        "the map (--pose-topic) needs the depth sensor's noise model for its height variance: \
         give --sensor"
    )]
    MapWithoutSensor,
    /// A map in a mode without sensor depth.
    #[error("the map (--pose-topic) fuses sensor depth: the rgb mode has none")]
    MapWithoutDepth,
    /// A gravity direction of zero length or not finite.
    #[error("--gravity {0:?} has no direction")]
    Gravity([f64; 3]),
    /// A domain id beyond the RTPS limit.
    #[error("--domain-id {0}: ROS 2 domain ids are 0 to 232")]
    DomainId(u16),
    /// A map settings file that cannot be used (`--map-params`).
    #[error("--map-params: {0}")]
    MapParams(#[from] tre_io::map_params::MapParamsError),
    /// A layer name the map does not have (`--grid-layers`).
    #[error(
        "--grid-layers: no layer {0:?}; the map's layers: {layers}",
        layers = tre_core::map::LAYER_NAMES.join(", ")
    )]
    GridLayer(String),
    /// A map setting out of its range (`--cell-cm`, `--size-m`, `--max-range-m`).
    #[error("{0}")]
    MapRange(#[from] tre_core::map::ParamsError),
}
