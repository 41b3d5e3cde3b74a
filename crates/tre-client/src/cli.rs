//! The options of `tre client` (the `cli` feature): the session's settings, which are
//! [`ClientConfig`]'s own, and where frames come from and where results go, checked into a
//! [`RecorderConfig`].

use std::path::PathBuf;

use crate::recorder::RecorderConfig;
use crate::source::SourceSpec;
use crate::{ClientConfig, ClientError, Rate};

/// Stream frames to `tre serve` and write the roughness maps it sends back.
#[derive(Debug, Clone, clap::Args)]
pub struct ClientArgs {
    /// The session's settings.
    #[command(flatten)]
    pub session: ClientConfig,
    /// Folder of frames (PNG or JPEG), sent in file-name order as they are on disk.
    #[arg(long, env = "TRE_CLIENT_FRAMES", required_unless_present_any = ["video", "device"],
          conflicts_with_all = ["video", "device"])]
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
    /// Frames per second to send (the server drops frames it has no time for and says so).
    #[arg(long, env = "TRE_CLIENT_RATE", conflicts_with = "as_fast_as_results")]
    pub rate: Option<f64>,
    /// Send each frame once the previous one has its answer (the default without --rate).
    #[arg(long, env = "TRE_CLIENT_AS_FAST_AS_RESULTS")]
    pub as_fast_as_results: bool,
    /// Stop after this many frames.
    #[arg(long, env = "TRE_CLIENT_LIMIT")]
    pub limit: Option<u64>,
    /// Start over at the end of the folder or video (until --limit or Ctrl-C).
    #[arg(long = "loop", env = "TRE_CLIENT_LOOP")]
    pub repeat: bool,
    /// Output folder: SEQ_NAME.png per result (NAME: the frame's file stem) and frames.csv.
    #[arg(long, short, env = "TRE_CLIENT_OUT")]
    pub out: PathBuf,
    /// Also record every frame sent and every answer to this MCAP file (ROS 2 messages and
    /// Foxglove schemas, docs/ros2.md).
    #[arg(long, env = "TRE_CLIENT_RECORD")]
    pub record: Option<PathBuf>,
}

/// Options that make no run.
#[derive(Debug, thiserror::Error)]
pub enum ArgsError {
    /// Not exactly one source of frames.
    #[error("give exactly one of --frames, --video and --device")]
    Source,
    /// Depth without a folder of frames.
    #[error("--depth goes with --frames (video and camera input have no depth)")]
    DepthWithoutFrames,
    /// `--limit 0`.
    #[error("--limit must be at least 1")]
    ZeroLimit,
    /// A camera file that does not read.
    #[error(transparent)]
    Camera(#[from] tre_io::IoError),
    /// A setting the session refuses ([`ClientConfig::validate`]).
    #[error(transparent)]
    Session(#[from] ClientError),
}

impl ClientArgs {
    /// The checked run: the source, the camera file read, the rate, the session's settings
    /// validated.
    ///
    /// # Errors
    ///
    /// [`ArgsError`].
    pub fn config(&self) -> Result<RecorderConfig, ArgsError> {
        let source = match (&self.frames, &self.video, &self.device) {
            (Some(frames), None, None) => SourceSpec::Folder {
                frames: frames.clone(),
                depth: self.depth.clone(),
            },
            (None, Some(video), None) => SourceSpec::Video(video.clone()),
            (None, None, Some(device)) => SourceSpec::Device(device.clone()),
            _ => return Err(ArgsError::Source),
        };
        if self.depth.is_some() && self.frames.is_none() {
            return Err(ArgsError::DepthWithoutFrames);
        }
        let camera = self
            .camera
            .as_deref()
            .map(tre_io::read_camera)
            .transpose()?;
        let session = ClientConfig {
            camera: camera.map(|(c, _)| c),
            rate: self.rate.map_or(Rate::AsFastAsResults, Rate::Fixed),
            ..self.session.clone()
        };
        session.validate()?;
        if self.limit == Some(0) {
            return Err(ArgsError::ZeroLimit);
        }
        Ok(RecorderConfig {
            session,
            source,
            out: self.out.clone(),
            limit: self.limit,
            repeat: self.repeat,
            mcap: self.record.clone(),
        })
    }
}

#[cfg(test)]
mod tests {
    use clap::Parser;
    use tre_core::kinds::MapFormat;

    use super::*;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        client: ClientArgs,
    }

    fn parse(args: &[&str]) -> Result<RecorderConfig, String> {
        let cli = Cli::try_parse_from(std::iter::once("tre").chain(args.iter().copied()))
            .map_err(|e| e.to_string())?;
        cli.client.config().map_err(|e| e.to_string())
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
        assert_eq!(run.session.format, MapFormat::F32);
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
        assert_eq!(
            d.session.connect_timeout,
            ClientConfig::default().connect_timeout
        );
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
            &[
                "--server", "h:1", "--frames", "f", "--format", "npy", "-o", "o",
            ],
        ] {
            assert!(parse(args).is_err(), "{args:?}");
        }
    }
}
