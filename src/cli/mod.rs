//! Command-line subcommands, one file each; `main.rs` only parses and dispatches.

pub(crate) mod annotate;
pub(crate) mod calibrate;
pub(crate) mod client;
pub(crate) mod eval;
pub(crate) mod infer;
pub(crate) mod loadtest;
pub(crate) mod map;
#[cfg(feature = "ros2")]
pub(crate) mod ros2;
pub(crate) mod serve;
pub(crate) mod synth;

use clap::{Parser, Subcommand};

/// Terrain roughness estimation for robots (TRENet).
#[derive(Debug, Parser)]
#[command(name = "tre", version, about)]
pub(crate) struct Cli {
    /// Log filter (tracing's env-filter syntax), e.g. `info` or `tre=debug`; the DDS libraries
    /// (`rustdds`, `ros2_client`) log errors only unless the filter names them (e.g.
    /// `info,rustdds=warn`).
    #[arg(long, env = "TRE_LOG", default_value = "info,ort=warn", global = true)]
    pub log: String,
    /// Logs as JSON lines (one object per event) instead of text.
    #[arg(long, env = "TRE_LOG_JSON", global = true)]
    pub log_json: bool,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub(crate) enum Command {
    /// Annotate a depth frame with ground-truth roughness (annotation spec v1).
    Annotate(annotate::Annotate),
    /// Generate a synthetic terrain dataset with exact ground truth.
    Synth(synth::Synth),
    /// Estimate roughness for one frame (RGB, RGB-D or depth only).
    Infer(infer::Infer),
    /// Score roughness, normals and depth on a synthetic dataset's split (--tables for the
    /// paper's Tables II, IV and V), or every mode on real RGB-D frames against the spec on
    /// the same sensor depth (--real).
    Eval(eval::Eval),
    /// Fit every mode's calibrated 90% roughness intervals on real validation frames
    /// (models/uncertainty.json; docs/uncertainty.md).
    Calibrate(calibrate::Calibrate),
    /// Fuse a sequence of depth frames (with their poses) into a gravity-aligned roughness grid
    /// map, written layer by layer (docs/map.md).
    Map(map::Map),
    /// Serve roughness over HTTP and a WebSocket stream.
    Serve(serve::Serve),
    /// Stream frames (a folder, a video or a camera) to `tre serve` over the WebSocket and
    /// write the roughness maps that come back.
    Client(Box<client::Client>),
    /// Load a running `tre serve` over HTTP or WebSocket and report throughput and latency.
    ///
    /// Open loop (`--rate`): requests at constant intended times, latency counted from the
    /// intended time (coordinated omission corrected). Closed loop (no `--rate`):
    /// `--connections` clients that each wait for their answer. `--sweep` runs several rates
    /// and finds the knee. Safety: only loopback addresses are loaded unless you write the
    /// address yourself in `--url`; a host name that resolves to a non-loopback address is
    /// refused unless `--allow-remote` is given.
    Loadtest(loadtest::Loadtest),
    /// Run the ROS 2 node: subscribes to a depth (and colour) image, its camera_info and
    /// optionally a pose; publishes roughness, uncertainty and three-state images with the
    /// input's header, and the fused map as grid_map_msgs/GridMap and nav_msgs/OccupancyGrid
    /// (docs/ros2.md). Needs no ROS installation.
    #[cfg(feature = "ros2")]
    // Boxed: its options are the largest by far, and every other command would carry their size.
    Ros2(Box<ros2::Ros2>),
}

impl Command {
    /// Runs the chosen subcommand.
    pub(crate) fn run(self) -> anyhow::Result<()> {
        match self {
            Command::Annotate(cmd) => cmd.run(),
            Command::Synth(cmd) => cmd.run(),
            Command::Infer(cmd) => cmd.run(),
            Command::Eval(cmd) => cmd.run(),
            Command::Calibrate(cmd) => cmd.run(),
            Command::Map(cmd) => cmd.run(),
            Command::Serve(cmd) => cmd.run(),
            Command::Client(cmd) => cmd.run(),
            Command::Loadtest(cmd) => cmd.run(),
            #[cfg(feature = "ros2")]
            Command::Ros2(cmd) => cmd.run(),
        }
    }
}
