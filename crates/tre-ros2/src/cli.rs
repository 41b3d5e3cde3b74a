//! The options of `tre ros2` (the `cli` feature): topics, QoS, the pose source, the map and the
//! recording, checked into a [`NodeConfig`] and the [`Processor`]'s settings.

use std::path::PathBuf;
use std::time::Duration;

use clap::{Args, ValueEnum};
use tre_core::geometry::Vec3;
use tre_core::map::{Pose, LAYER_NAMES};
use tre_core::roughness::noise::SensorNoise;
use tre_pipeline::{Assumption, Mode, StageArgs};

use crate::{
    ConfigProblem, ImageOutputs, InputError, MapSettings, NodeConfig, PoseSource, Processor,
    Reliability, Ros2Error, RoughnessEncoding,
};

/// Reliability of the input subscriptions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum InputReliability {
    /// Best effort (ROS's sensor-data profile): matches every publisher.
    BestEffort,
    /// Reliable: matches reliable publishers only.
    Reliable,
}

/// The roughness image's encoding.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RoughnessImage {
    /// `32FC1`, metres, NaN for no data: the pipeline's values bit for bit.
    #[value(name = "32fc1")]
    Float32,
    /// `mono16`, millimetres rounded, 0 for no data: half the bytes.
    #[value(name = "mono16")]
    Mono16,
}

/// Run the ROS 2 node: the roughness image for every frame (uncertainty and three-state on
/// request), and
/// with a pose topic the fused map as grid_map_msgs/GridMap and nav_msgs/OccupancyGrid.
#[derive(Debug, Args)]
pub struct Ros2Args {
    /// DDS domain.
    #[arg(long, env = "ROS_DOMAIN_ID", default_value_t = 0)]
    pub domain_id: u16,
    /// Node name, with its namespace.
    #[arg(long, default_value = "/tre")]
    pub node_name: String,
    /// Input mode: geometric (depth alone), rgbd (colour and depth of the same stamp), rgb.
    #[arg(long, value_enum, default_value = "geometric")]
    pub mode: Mode,
    /// Depth image topic: 16UC1 millimetres or 32FC1 metres (REP 118).
    #[arg(long, default_value = "/camera/depth/image_rect_raw")]
    pub depth_topic: String,
    /// Colour image topic (rgb8 or bgr8), read in the rgb and rgbd modes.
    #[arg(long, default_value = "/camera/color/image_raw")]
    pub colour_topic: String,
    /// camera_info of the image the mode reads (the depth's; the colour's in rgb mode).
    #[arg(long, default_value = "/camera/depth/camera_info")]
    pub info_topic: String,
    /// Pose source for the map: a nav_msgs/Odometry topic. Without a pose topic, no map.
    #[arg(long, conflicts_with = "pose_topic")]
    pub odom_topic: Option<String>,
    /// Pose source for the map: a geometry_msgs/PoseStamped topic.
    #[arg(long)]
    pub pose_topic: Option<String>,
    /// The camera's optical frame in the frame the pose places (base_link for odometry):
    /// x,y,z,qx,qy,qz,qw. Default: the pose is the camera's.
    #[arg(long, value_parser = parse_pose, allow_hyphen_values = true)]
    pub camera_in_body: Option<Pose>,
    /// Largest gap between a frame's stamp and its pose's, milliseconds.
    #[arg(long, default_value_t = 50)]
    pub pose_tolerance_ms: u64,
    /// Gravity (down) in the pose's frame: x,y,z (ROS frames have z up, REP 103).
    #[arg(long, value_parser = parse_vec3, default_value = "0,0,-1", allow_hyphen_values = true)]
    pub gravity: Vec3,
    /// frame_id of the published map (the pose's frame, levelled by --gravity).
    #[arg(long, default_value = "odom")]
    pub map_frame: String,
    /// Map settings: a preset (`indoor`: 4 cm cells, an 8 m window, points to 4 m; `outdoor`:
    /// 10 cm cells, a 40 m window, points from 1 to 20 m) or a TOML settings file
    /// (docs/map.md), the same `tre map --params` reads.
    #[arg(long, default_value = "indoor")]
    pub map_params: String,
    /// Map cell side, centimetres (default: the settings').
    #[arg(long)]
    pub cell_cm: Option<f64>,
    /// The layers the grid_map message carries, comma-separated (default: every layer; 160 KB
    /// a layer at the default 200×200 cells): elevation, variance, count, upper, clearance,
    /// roughness, slope, step, score, traversal, last_update.
    #[arg(long, value_delimiter = ',')]
    pub grid_layers: Option<Vec<String>>,
    /// Publish the grid_map message at most once this period, milliseconds, by the frames'
    /// stamps (0: every fused frame); the occupancy grid goes out with every fused frame.
    #[arg(long, default_value_t = 200)]
    pub grid_period_ms: u64,
    /// Map side, metres; the window follows the camera (default: the settings').
    #[arg(long)]
    pub size_m: Option<f64>,
    /// Points farther than this from the camera are left out of the map, metres (default: the
    /// settings').
    #[arg(long)]
    pub max_range_m: Option<f64>,
    /// Depth sensor noise model (kinect_v1, realsense_d435, azure_kinect, lidar, lidar_accumulated, passive_stereo, exact, or
    /// a,b,c with σ_z = a + b·z + c·z² mm): the uncertainty and three-state images, and the
    /// map's height variance. Without it, neither is published and no map is made.
    #[arg(long, env = "TRE_SENSOR")]
    pub sensor: Option<SensorNoise>,
    /// The images are raw and distorted (an Azure Kinect's depth/image_raw): remap each into
    /// its camera_info's pinhole p before the pipeline, through its distortion d (plumb_bob or
    /// rational_polynomial), nearest-neighbour. The outputs are then in p's pixels. Without
    /// it the images are read as rectified.
    #[arg(long)]
    pub undistort: bool,
    /// Also publish the uncertainty image (32FC1, metres; needs --sensor). Off by default:
    /// another 1.2 MB a 640×480 frame.
    #[arg(long)]
    pub publish_uncertainty: bool,
    /// Also publish the three-state image (mono8; needs --sensor). Off by default.
    #[arg(long)]
    pub publish_traversal: bool,
    /// Encoding of the roughness image: 32fc1 (metres, exact) or mono16 (millimetres, half
    /// the bytes).
    #[arg(long, value_enum, default_value = "32fc1")]
    pub roughness_encoding: RoughnessImage,
    /// Do not publish the images as PNGs on `{topic}/compressed` (sensor_msgs/CompressedImage,
    /// image_transport's `compressed`: the roughness as mono16 millimetres), which a subscriber
    /// with stock socket buffers receives where it loses raw 640×480 images.
    #[arg(long)]
    pub no_compressed: bool,
    /// Prefix of the output topics (roughness, uncertainty, traversal, grid_map, occupancy).
    #[arg(long, default_value = "/tre")]
    pub output_prefix: String,
    /// Reliability of the input subscriptions.
    #[arg(long, value_enum, default_value = "best-effort")]
    pub input_reliability: InputReliability,
    /// Record inputs and outputs to this MCAP file (ROS 2 messages, zstd chunks).
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// Also record the outputs in Foxglove's JSON schemas (rosbag2 refuses such a file).
    #[arg(long, requires = "record")]
    pub record_foxglove: bool,
    /// Make the recording's folder a rosbag2 bag: metadata.yaml beside the .mcap (give
    /// --record a file in a folder of its own). Not with --record-foxglove.
    #[arg(long, requires = "record", conflicts_with = "record_foxglove")]
    pub record_bag: bool,
    /// Stop after this many seconds (default: at Ctrl-C or SIGTERM).
    #[arg(long)]
    pub duration_s: Option<f64>,
    /// Pipeline switches and models.
    #[command(flatten)]
    pub stages: StageArgs,
}

/// A `--gravity` or `--camera-in-body` value that cannot be used.
#[derive(Debug, thiserror::Error)]
pub(crate) enum VectorArgError {
    /// A part that is not a number.
    #[error("{part:?}: {source}")]
    Number {
        /// The part as given.
        part: String,
        /// Why it does not parse.
        #[source]
        source: std::num::ParseFloatError,
    },
    /// Not `count` finite numbers.
    #[error("{count} finite numbers separated by commas, got {given:?}")]
    Count {
        /// How many were expected.
        count: usize,
        /// The value as given.
        given: String,
    },
    /// A direction of zero length.
    #[error("a direction of zero length")]
    ZeroDirection,
    /// A pose the map cannot use (its quaternion).
    #[error(transparent)]
    Pose(#[from] InputError),
}

fn parse_vec3(s: &str) -> Result<Vec3, VectorArgError> {
    let v = numbers(s, 3)?;
    let d = Vec3::new(v[0], v[1], v[2]);
    if !(d.norm().is_finite() && d.norm() > 0.0) {
        return Err(VectorArgError::ZeroDirection);
    }
    Ok(d)
}

fn parse_pose(s: &str) -> Result<Pose, VectorArgError> {
    let v = numbers(s, 7)?;
    let msg = tre_record::msgs::Pose {
        position: tre_record::msgs::Point {
            x: v[0],
            y: v[1],
            z: v[2],
        },
        orientation: tre_record::msgs::Quaternion {
            x: v[3],
            y: v[4],
            z: v[5],
            w: v[6],
        },
    };
    Ok(crate::convert::map_pose(&msg, &Pose::identity())?)
}

fn numbers(s: &str, n: usize) -> Result<Vec<f64>, VectorArgError> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| {
            p.trim()
                .parse::<f64>()
                .map_err(|source| VectorArgError::Number {
                    part: p.to_owned(),
                    source,
                })
        })
        .collect::<Result<_, _>>()?;
    if v.len() != n || !v.iter().all(|x| x.is_finite()) {
        return Err(VectorArgError::Count {
            count: n,
            given: s.to_owned(),
        });
    }
    Ok(v)
}

impl Ros2Args {
    /// The pipeline and the map the node runs, the options checked.
    ///
    /// # Errors
    ///
    /// [`Ros2Error::Config`] for options that do not go together; the pipeline's error when its
    /// models do not load.
    pub fn processor(&self) -> Result<Processor, Ros2Error> {
        if self.domain_id > 232 {
            return Err(Ros2Error::Config(ConfigProblem::DomainId(self.domain_id)));
        }
        let cfg = self.stages.config(self.mode);
        let map = self.map_settings().map_err(Ros2Error::Config)?;
        let pipeline = self.stages.pipeline(&[cfg])?;
        Ok(Processor::new(pipeline, cfg, self.sensor, map)
            .with_images(self.images())
            .with_undistort(self.undistort))
    }

    /// What the node will assume on every frame, for want of an option: the depth read as exact
    /// in `geometric` without `--sensor`, the rgb depth prior's default mounting in `rgb`. ROS
    /// messages carry no field for it, so `tre ros2` says it once, when it starts. camera_info
    /// gives the intrinsics and REP 118 the depth's units, so neither is assumed.
    pub fn assumptions(&self) -> Vec<Assumption> {
        Assumption::of_frame(
            true,
            false,
            (false, self.sensor.is_some()),
            (self.mode, true),
        )
    }

    /// [`Self::assumptions`] in the node's words: what each means for every frame, and the
    /// option that removes it (the node takes no mounting: `rgb` has no slope there).
    pub fn assumption_lines(&self) -> Vec<String> {
        self.assumptions()
            .into_iter()
            .map(|a| match a {
                Assumption::Sensor => "no depth-sensor model: the depth is read as exact, with \
                                       no noise margin and no uncertainty (name it: --sensor)"
                    .to_owned(),
                Assumption::Mounting => "no mounting: the rgb depth prior assumes a camera 60° \
                                         down and 1 m up (the node takes no mounting), and \
                                         slope and traversability are unknown"
                    .to_owned(),
                other => other.to_string(),
            })
            .collect()
    }

    /// The images published beside the roughness.
    pub fn images(&self) -> ImageOutputs {
        ImageOutputs {
            uncertainty: self.publish_uncertainty,
            traversal: self.publish_traversal,
            roughness: match self.roughness_encoding {
                RoughnessImage::Float32 => RoughnessEncoding::Float32,
                RoughnessImage::Mono16 => RoughnessEncoding::Mono16Mm,
            },
            compressed: !self.no_compressed,
        }
    }

    /// The input topic the mode reads.
    pub fn input_topic(&self) -> &str {
        match self.mode {
            Mode::Rgb => &self.colour_topic,
            _ => &self.depth_topic,
        }
    }

    fn pose_source(&self) -> Option<PoseSource> {
        match (&self.odom_topic, &self.pose_topic) {
            (Some(t), _) => Some(PoseSource::Odometry(t.clone())),
            (None, Some(t)) => Some(PoseSource::PoseStamped(t.clone())),
            (None, None) => None,
        }
    }

    /// The map's settings: `None` without a pose topic.
    pub fn map_settings(&self) -> Result<Option<MapSettings>, ConfigProblem> {
        if self.pose_source().is_none() {
            return Ok(None);
        }
        if self.sensor.is_none() {
            return Err(ConfigProblem::MapWithoutSensor);
        }
        if self.mode == Mode::Rgb {
            return Err(ConfigProblem::MapWithoutDepth);
        }
        let params = tre_io::map_params::map_params_arg(&self.map_params)?.with_flags(
            self.cell_cm.map(|cm| cm / 100.0),
            self.size_m,
            self.max_range_m,
        )?;
        let grid_layers = match &self.grid_layers {
            None => LAYER_NAMES.to_vec(),
            Some(names) => names
                .iter()
                .map(|n| {
                    LAYER_NAMES
                        .iter()
                        .find(|l| **l == n.as_str())
                        .copied()
                        .ok_or_else(|| ConfigProblem::GridLayer(n.clone()))
                })
                .collect::<Result<_, _>>()?,
        };
        Ok(Some(MapSettings {
            params,
            down: self.gravity,
            frame_id: self.map_frame.clone(),
            grid_layers,
            grid_period: Duration::from_millis(self.grid_period_ms),
        }))
    }

    /// The node's topics, QoS and recording.
    pub fn node_config(&self) -> NodeConfig {
        NodeConfig {
            domain_id: self.domain_id,
            node_name: self.node_name.clone(),
            depth_topic: self.depth_topic.clone(),
            colour_topic: self.colour_topic.clone(),
            info_topic: self.info_topic.clone(),
            pose: self.pose_source(),
            camera_in_body: self.camera_in_body.unwrap_or_else(Pose::identity),
            pose_tolerance: Duration::from_millis(self.pose_tolerance_ms),
            output_prefix: self.output_prefix.clone(),
            input_reliability: match self.input_reliability {
                InputReliability::BestEffort => Reliability::BestEffort,
                InputReliability::Reliable => Reliability::Reliable,
            },
            record: self.record.clone(),
            record_foxglove: self.record_foxglove,
            record_bag: self.record_bag,
            ..NodeConfig::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        ros2: Ros2Args,
    }

    fn grid_layers(list: &str) -> Result<Vec<&'static str>, ConfigProblem> {
        let args = ["tre", "--odom-topic", "/odom", "--sensor", "kinect_v1"];
        let cli = Cli::try_parse_from(args.into_iter().chain(["--grid-layers", list]))
            .expect("the options parse");
        cli.ros2
            .map_settings()
            .map(|m| m.expect("a map with a pose topic").grid_layers)
    }

    #[test]
    fn vectors_and_poses_are_refused_saying_why() {
        let err = |args: &[&str]| {
            Cli::try_parse_from(["tre"].iter().chain(args))
                .err()
                .expect("refused")
                .to_string()
        };
        assert!(err(&["--gravity=0,0,0"]).contains("a direction of zero length"));
        assert!(err(&["--gravity=1,2"]).contains("3 finite numbers separated by commas"));
        assert!(err(&["--gravity=1,x,2"]).contains("\"x\": invalid float literal"));
        assert!(err(&["--camera-in-body=0,0,0,0,0,0,2"]).contains("quaternion"));
        let ok = Cli::try_parse_from(["tre", "--camera-in-body=0.2,0,0.3,-0.5,0.5,-0.5,0.5"]);
        assert!(ok.is_ok());
    }

    #[test]
    fn the_node_says_what_it_assumes() {
        let assumed = |args: &[&str]| {
            Cli::try_parse_from(["tre"].iter().chain(args))
                .expect("the options parse")
                .ros2
                .assumptions()
        };
        assert_eq!(assumed(&[]), [Assumption::Sensor]);
        assert_eq!(assumed(&["--sensor", "lidar"]), []);
        assert_eq!(assumed(&["--mode", "rgbd"]), []);
        assert_eq!(assumed(&["--mode", "rgb"]), [Assumption::Mounting]);
        // Said with the node's option, not the camera file's keys.
        let lines = Cli::try_parse_from(["tre"])
            .expect("parses")
            .ros2
            .assumption_lines();
        assert!(
            lines.len() == 1 && lines[0].contains("--sensor"),
            "{lines:?}"
        );
        let rgb = Cli::try_parse_from(["tre", "--mode", "rgb"]).expect("parses");
        let lines = rgb.ros2.assumption_lines();
        assert!(!lines[0].contains("pitch_deg"), "{lines:?}");
    }

    #[test]
    fn grid_layers_are_checked_against_the_maps_layers() {
        assert_eq!(
            grid_layers("traversal,elevation").expect("known layers"),
            ["traversal", "elevation"]
        );
        let e = grid_layers("elevation,heigth").expect_err("a misspelt layer");
        assert!(e.to_string().contains("\"heigth\""), "{e}");
        let cli = Cli::try_parse_from(["tre", "--odom-topic", "/odom", "--sensor", "kinect_v1"])
            .expect("the options parse");
        let all = cli.ros2.map_settings().expect("valid").expect("a map");
        assert_eq!(all.grid_layers, LAYER_NAMES);
    }
}
