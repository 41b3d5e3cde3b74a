//! `tre ros2`: the ROS 2 node (docs/ros2.md), until Ctrl-C or SIGTERM.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use clap::{Args, ValueEnum};

use crate::geometry::Vec3;
use crate::map::{MapConfig, MapLimits, Pose};
use crate::pipeline::{Mode, StageArgs};
use crate::ros2::{self, MapSettings, NodeConfig, PoseSource, Processor, Reliability};
use crate::roughness::noise::SensorNoise;

/// Reliability of the input subscriptions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum InputReliability {
    /// Best effort (ROS's sensor-data profile): matches every publisher.
    BestEffort,
    /// Reliable: matches reliable publishers only.
    Reliable,
}

/// Run the ROS 2 node: roughness, uncertainty and three-state images for every frame, and
/// with a pose topic the fused map as grid_map_msgs/GridMap and nav_msgs/OccupancyGrid.
#[derive(Debug, Args)]
pub(crate) struct Ros2 {
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
    /// Map cell side, centimetres.
    #[arg(long, default_value_t = 4.0)]
    pub cell_cm: f64,
    /// Map side, metres (the window follows the camera).
    #[arg(long, default_value_t = 8.0)]
    pub size_m: f64,
    /// Points farther than this from the camera are left out of the map, metres.
    #[arg(long, default_value_t = 3.0)]
    pub max_range_m: f64,
    /// Depth sensor noise model (kinect_v1, realsense_d435, azure_kinect, lidar, exact, or
    /// a,b,c with σ_z = a + b·z + c·z² mm): the uncertainty and three-state images, and the
    /// map's height variance. Without it, neither is published and no map is made.
    #[arg(long, env = "TRE_SENSOR")]
    pub sensor: Option<SensorNoise>,
    /// Prefix of the output topics (roughness, uncertainty, traversal, grid_map, occupancy).
    #[arg(long, default_value = "/tre")]
    pub output_prefix: String,
    /// Reliability of the input subscriptions.
    #[arg(long, value_enum, default_value = "best-effort")]
    pub input_reliability: InputReliability,
    /// Record inputs and outputs to this MCAP file (ROS 2 messages and Foxglove schemas).
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// Stop after this many seconds (default: at Ctrl-C or SIGTERM).
    #[arg(long)]
    pub duration_s: Option<f64>,
    /// Pipeline switches and models.
    #[command(flatten)]
    pub stages: StageArgs,
}

fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let v = numbers(s, 3)?;
    let d = Vec3::new(v[0], v[1], v[2]);
    if !(d.norm().is_finite() && d.norm() > 0.0) {
        return Err("a direction of zero length".into());
    }
    Ok(d)
}

fn parse_pose(s: &str) -> Result<Pose, String> {
    let v = numbers(s, 7)?;
    let msg = ros2::msgs::Pose {
        position: ros2::msgs::Point {
            x: v[0],
            y: v[1],
            z: v[2],
        },
        orientation: ros2::msgs::Quaternion {
            x: v[3],
            y: v[4],
            z: v[5],
            w: v[6],
        },
    };
    ros2::convert::map_pose(&msg, &Pose::identity()).map_err(|e| e.to_string())
}

fn numbers(s: &str, n: usize) -> Result<Vec<f64>, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>().map_err(|e| format!("{p:?}: {e}")))
        .collect::<Result<_, _>>()?;
    if v.len() != n || !v.iter().all(|x| x.is_finite()) {
        return Err(format!("{n} finite numbers separated by commas, got {s:?}"));
    }
    Ok(v)
}

impl Ros2 {
    pub(crate) fn run(self) -> anyhow::Result<()> {
        if self.domain_id > 232 {
            return Err(ros2::ConfigProblem::DomainId(self.domain_id).into());
        }
        let cfg = self.stages.config(self.mode);
        let map = self.map_settings()?;
        let pipeline = self.stages.pipeline(&[cfg])?;
        let processor = Processor::new(pipeline, cfg, self.sensor, map);
        let node = ros2::start(self.node_config(), processor)?;
        println!(
            "ros2 node {} on domain {} ({}), mode {}: reading {}, publishing under {}",
            self.node_name,
            self.domain_id,
            ros2::COMPILED_ROS_DISTRO,
            self.mode,
            match self.mode {
                Mode::Rgb => self.colour_topic.as_str(),
                _ => self.depth_topic.as_str(),
            },
            self.output_prefix
        );
        self.wait()?;
        let s = node.stats();
        let count = |c: &std::sync::atomic::AtomicU64| c.load(std::sync::atomic::Ordering::Relaxed);
        let line = format!(
            "frames received {}, published {}, dropped (stale) {}, skipped (bad input) {}, fused \
             into the map {}",
            count(&s.received),
            count(&s.published),
            count(&s.dropped),
            count(&s.skipped),
            count(&s.fused),
        );
        if let Some(path) = node.stop()? {
            println!("recorded {}", path.display());
        }
        println!("{line}");
        Ok(())
    }

    fn pose_source(&self) -> Option<PoseSource> {
        match (&self.odom_topic, &self.pose_topic) {
            (Some(t), _) => Some(PoseSource::Odometry(t.clone())),
            (None, Some(t)) => Some(PoseSource::PoseStamped(t.clone())),
            (None, None) => None,
        }
    }

    fn map_settings(&self) -> anyhow::Result<Option<MapSettings>> {
        if self.pose_source().is_none() {
            return Ok(None);
        }
        if self.sensor.is_none() {
            return Err(ros2::ConfigProblem::MapWithoutSensor.into());
        }
        if self.mode == Mode::Rgb {
            return Err(ros2::ConfigProblem::MapWithoutDepth.into());
        }
        Ok(Some(MapSettings {
            config: MapConfig {
                cell_m: self.cell_cm / 100.0,
                side: (self.size_m / (self.cell_cm / 100.0)).round() as usize,
                max_range_m: self.max_range_m,
                ..MapConfig::default()
            },
            limits: MapLimits::default(),
            down: self.gravity,
            frame_id: self.map_frame.clone(),
        }))
    }

    fn node_config(&self) -> NodeConfig {
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
            ..NodeConfig::default()
        }
    }

    /// Until Ctrl-C, SIGTERM or `--duration-s`.
    fn wait(&self) -> anyhow::Result<()> {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .context("signal runtime")?;
        rt.block_on(async {
            match self.duration_s {
                Some(s) => {
                    tokio::select! {
                        () = tokio::time::sleep(Duration::from_secs_f64(s.max(0.0))) => {},
                        () = crate::server::shutdown_signal() => {},
                    }
                }
                None => crate::server::shutdown_signal().await,
            }
        });
        Ok(())
    }
}
