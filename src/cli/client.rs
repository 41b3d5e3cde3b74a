//! `tre client`: streams frames from a folder, a video file or a camera to `tre serve` over the
//! WebSocket, writes each result's roughness map and a per-frame CSV, and prints a live summary.
//! The options become a [`RecorderConfig`]; [`crate::client::recorder`] does the recording.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{bail, Context};
use clap::Args;

use super::options::dsac_hypotheses_arg;
use crate::client::recorder::{record, RecorderConfig};
use crate::client::source::SourceSpec;
use crate::client::{Backoff, ClientConfig, Format, Rate};
use crate::io;
use crate::pipeline::{Mode, NormalsMethod};
use crate::roughness::noise::SensorNoise;

/// Stream frames to `tre serve` and write the roughness maps it sends back.
#[derive(Debug, Args)]
pub(crate) struct Client {
    /// Server: ws://host:port/v1/stream, ws://host:port, http://host:port or host:port;
    /// wss:// or https:// for TLS (a TLS-terminating proxy in front of the service).
    #[arg(long, env = "TRE_SERVER")]
    pub server: String,
    /// API key of a server started with --api-key (sent as `Authorization: Bearer KEY`).
    #[arg(long, env = "TRE_API_KEY", hide_env_values = true)]
    pub api_key: Option<String>,
    /// PEM file of a private CA to trust beside the public roots, for a wss:// or https://
    /// server whose certificate it issued.
    #[arg(long, env = "TRE_CA_CERT")]
    pub ca_cert: Option<PathBuf>,
    /// Folder of frames (PNG or JPEG), sent in file-name order as they are on disk.
    #[arg(long, env = "TRE_CLIENT_FRAMES", required_unless_present_any = ["video", "device"], conflicts_with_all = ["video", "device"])]
    pub frames: Option<PathBuf>,
    /// Folder of registered depth frames: frame FRAMES/NAME.EXT takes DEPTH/NAME.png (16-bit,
    /// the camera's depth_scale units per metre, default 1000) or DEPTH/NAME.npy (metres).
    /// Every frame must have one.
    #[arg(long, env = "TRE_CLIENT_DEPTH")]
    pub depth: Option<PathBuf>,
    /// Video file, decoded by ffmpeg (which must be on PATH).
    #[arg(long, env = "TRE_CLIENT_VIDEO", conflicts_with = "device")]
    pub video: Option<PathBuf>,
    /// V4L2 camera device (e.g. /dev/video0), read by ffmpeg (which must be on PATH); frames
    /// the stream has no time for are skipped.
    #[arg(long, env = "TRE_CLIENT_DEVICE")]
    pub device: Option<PathBuf>,
    /// Camera JSON (cameras/README.md), read as `tre infer` reads it: fx, fy, cx, cy in pixels
    /// of the frames; optional depth_scale, sensor, pitch_deg, height_m; metadata under
    /// "notes". Without it the server assumes a 60° field of view, and says so.
    #[arg(long, env = "TRE_CAMERA")]
    pub camera: Option<PathBuf>,
    /// Depth sensor noise model, overriding the camera JSON's "sensor" (as `tre infer
    /// --sensor`): a preset (kinect_v1, realsense_d435, azure_kinect, lidar, exact) or a,b,c.
    #[arg(long, env = "TRE_SENSOR", value_parser = super::infer::parse_sensor)]
    pub sensor: Option<SensorNoise>,
    /// Frames per second to send (the server drops frames it has no time for and says so).
    #[arg(long, env = "TRE_CLIENT_RATE", conflicts_with = "as_fast_as_results")]
    pub rate: Option<f64>,
    /// Send each frame once the previous one has its answer (the default without --rate).
    #[arg(long, env = "TRE_CLIENT_AS_FAST_AS_RESULTS")]
    pub as_fast_as_results: bool,
    /// Input mode; default: rgbd for frames with depth, else rgb.
    #[arg(long, env = "TRE_MODE", value_enum)]
    pub mode: Option<Mode>,
    /// Encoding of the maps asked of the server: png16 (SEQ_NAME.png, 16-bit, 0.1 mm per
    /// unit), color (a preview PNG) or f32 (SEQ_NAME.npy, float32 metres).
    #[arg(long, env = "TRE_CLIENT_FORMAT", value_enum, default_value = "png16")]
    pub format: Format,
    /// Seed of the DSAC sampler: the same seed gives the same output.
    #[arg(long, env = "TRE_SEED", default_value_t = 0)]
    pub seed: u64,
    /// Initial normals: dsac (the paper's method) or ls (faster); default: the server's.
    #[arg(long, env = "TRE_CLIENT_NORMALS", value_enum)]
    pub normals: Option<NormalsMethod>,
    /// DSAC hypotheses per pixel, 1 to 64 (fewer are faster); default: the server's.
    #[arg(long, env = "TRE_CLIENT_DSAC_HYPOTHESES",
          value_parser = dsac_hypotheses_arg())]
    pub dsac_hypotheses: Option<u32>,
    /// Also ask for traversability, written as SEQ_NAME_traversable.png (255 = traversable).
    #[arg(long, env = "TRE_CLIENT_TRAVERSABLE")]
    pub traversable: bool,
    /// Also ask for the three-state map and the uncertainty (the camera must name a sensor
    /// noise model, docs/sensor-noise.md), written as SEQ_NAME_traversal.png (0 unknown,
    /// 1 traversable, 2 hazard) and SEQ_NAME_uncertainty.png (16-bit, 0.1 mm per unit).
    #[arg(long, env = "TRE_CLIENT_TRAVERSAL")]
    pub traversal: bool,
    /// Traversability: the largest roughness, centimetres (default 5).
    #[arg(long, env = "TRE_CLIENT_MAX_ROUGHNESS_CM")]
    pub max_roughness_cm: Option<f64>,
    /// Traversability: the steepest slope, degrees (default 20).
    #[arg(long, env = "TRE_CLIENT_MAX_SLOPE_DEG")]
    pub max_slope_deg: Option<f64>,
    /// Stop after this many frames.
    #[arg(long, env = "TRE_CLIENT_LIMIT")]
    pub limit: Option<u64>,
    /// Start over at the end of the folder or video (until --limit or Ctrl-C).
    #[arg(long = "loop", env = "TRE_CLIENT_LOOP")]
    pub repeat: bool,
    /// Output folder: SEQ_NAME.png per result (NAME: the frame's file stem) and frames.csv.
    #[arg(long, short, env = "TRE_CLIENT_OUT")]
    pub out: PathBuf,
    /// A frame without an answer after this long is counted lost, milliseconds.
    #[arg(long, env = "TRE_CLIENT_FRAME_TIMEOUT_MS", default_value_t = 30_000)]
    pub frame_timeout_ms: u64,
    /// First wait between connection attempts, milliseconds (doubling, see --reconnect-factor).
    #[arg(long, env = "TRE_CLIENT_RECONNECT_INITIAL_MS", default_value_t = 200)]
    pub reconnect_initial_ms: u64,
    /// Longest wait between connection attempts, milliseconds.
    #[arg(long, env = "TRE_CLIENT_RECONNECT_MAX_MS", default_value_t = 5_000)]
    pub reconnect_max_ms: u64,
    /// Growth of the wait per failed attempt.
    #[arg(long, env = "TRE_CLIENT_RECONNECT_FACTOR", default_value_t = 2.0)]
    pub reconnect_factor: f64,
    /// Failed connection attempts in a row before giving up (0: never).
    #[arg(long, env = "TRE_CLIENT_RECONNECT_ATTEMPTS", default_value_t = 20)]
    pub reconnect_attempts: u32,
}
impl Client {
    /// The checked run configuration.
    pub(crate) fn config(&self) -> anyhow::Result<RecorderConfig> {
        let source = match (&self.frames, &self.video, &self.device) {
            (Some(frames), None, None) => SourceSpec::Folder {
                frames: frames.clone(),
                depth: self.depth.clone(),
            },
            (None, Some(video), None) => SourceSpec::Video(video.clone()),
            (None, None, Some(device)) => SourceSpec::Device(device.clone()),
            _ => bail!("give exactly one of --frames, --video and --device"),
        };
        if self.depth.is_some() && self.frames.is_none() {
            bail!("--depth goes with --frames (video and camera input have no depth)");
        }
        let camera = self.camera.as_deref().map(io::read_camera).transpose()?;
        let session = ClientConfig {
            server: self.server.clone(),
            api_key: self.api_key.clone(),
            ca_cert: self.ca_cert.clone(),
            camera: camera.map(|(c, _)| c),
            mode: self.mode,
            format: self.format,
            seed: self.seed,
            normals: self.normals,
            dsac_hypotheses: self.dsac_hypotheses,
            want_traversable: self.traversable,
            want_traversal: self.traversal,
            max_roughness_cm: self.max_roughness_cm,
            max_slope_deg: self.max_slope_deg,
            sensor: self.sensor,
            rate: self.rate.map_or(Rate::AsFastAsResults, Rate::Fixed),
            reconnect: Backoff {
                initial: Duration::from_millis(self.reconnect_initial_ms),
                max: Duration::from_millis(self.reconnect_max_ms),
                factor: self.reconnect_factor,
                give_up_after: (self.reconnect_attempts > 0).then_some(self.reconnect_attempts),
            },
            frame_timeout: Duration::from_millis(self.frame_timeout_ms),
            ..ClientConfig::default()
        };
        session.validate()?;
        if self.limit == Some(0) {
            bail!("--limit must be at least 1");
        }
        Ok(RecorderConfig {
            session,
            source,
            out: self.out.clone(),
            limit: self.limit,
            repeat: self.repeat,
        })
    }

    /// Streams the frames, writes the maps and the CSV, prints the summaries.
    pub(crate) fn run(self) -> anyhow::Result<()> {
        run(self.config()?)
    }
}

/// Records `cfg` on its own async runtime, printing the recorder's notices on stderr; Ctrl-C
/// stops the sending. An error if no result came back.
pub(crate) fn run(cfg: RecorderConfig) -> anyhow::Result<()> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("tre-client")
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    let stop = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    runtime.block_on(record(&cfg, stop, |notice| eprintln!("{notice}")))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        client: Client,
    }

    fn parse(args: &[&str]) -> Result<RecorderConfig, String> {
        let cli = Cli::try_parse_from(std::iter::once("tre").chain(args.iter().copied()))
            .map_err(|e| e.to_string())?;
        cli.client.config().map_err(|e| format!("{e:#}"))
    }

    #[test]
    fn options_become_a_checked_run() {
        let run = parse(&[
            "--server",
            "http://127.0.0.1:9",
            "--frames",
            "f",
            "--depth",
            "d",
            "--rate",
            "5",
            "--format",
            "f32",
            "--reconnect-attempts",
            "0",
            "--limit",
            "3",
            "--out",
            "o",
        ])
        .unwrap();
        assert_eq!(run.session.rate, Rate::Fixed(5.0));
        assert_eq!(run.session.format, Format::F32);
        assert_eq!(run.session.reconnect.give_up_after, None);
        assert_eq!(
            run.source,
            SourceSpec::Folder {
                frames: "f".into(),
                depth: Some("d".into())
            }
        );
        assert_eq!(run.limit, Some(3));
        let d = parse(&["--server", "h:1", "--video", "v.mp4", "-o", "o"]).unwrap();
        assert_eq!(d.session.rate, Rate::AsFastAsResults);
        assert_eq!(d.session.reconnect.give_up_after, Some(20));
    }

    #[test]
    fn conflicting_or_bad_options_are_refused() {
        for args in [
            &["--server", "h:1", "-o", "o"][..],
            &[
                "--server", "h:1", "--frames", "f", "--video", "v", "-o", "o",
            ],
            &["--server", "h:1", "--video", "v", "--depth", "d", "-o", "o"],
            &[
                "--server",
                "h:1",
                "--frames",
                "f",
                "--rate",
                "2",
                "--as-fast-as-results",
                "-o",
                "o",
            ],
            &[
                "--server", "h:1", "--frames", "f", "--rate", "-2", "-o", "o",
            ],
            &["--server", "ftp://h:1", "--frames", "f", "-o", "o"],
            &[
                "--server", "h:1", "--frames", "f", "--limit", "0", "-o", "o",
            ],
        ] {
            assert!(parse(args).is_err(), "{args:?}");
        }
    }
}
