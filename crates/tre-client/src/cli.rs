//! The options of `tre client` (the `cli` feature): the session's settings, which are
//! [`ClientConfig`]'s own, and where frames come from and where results go, checked into a
//! [`RecorderConfig`].

use std::path::PathBuf;

use crate::recorder::RecorderConfig;
use crate::source::SourceSpec;
use crate::{ClientConfig, ClientError, MapRequest, Rate};
use tre_core::kinds::Mode;

/// Stream frames to `tre serve` and write the roughness maps it sends back.
#[derive(Debug, Clone, clap::Args)]
pub struct ClientArgs {
    /// The session's settings.
    #[command(flatten)]
    pub session: ClientConfig,
    /// Folder of frames (PNG or JPEG), sent in file-name order as they are on disk.
    #[arg(long, env = "TRE_CLIENT_FRAMES",
          required_unless_present_any = ["video", "device", "depth"],
          conflicts_with_all = ["video", "device"])]
    pub frames: Option<PathBuf>,
    /// Folder of depth frames: DEPTH/NAME.png (16-bit, the camera's depth_scale units per
    /// metre, default 1000) or DEPTH/NAME.npy (metres). With --frames, frame FRAMES/NAME.EXT
    /// takes DEPTH/NAME.* (every frame must have one); alone, every depth file is sent as a
    /// depth-only frame in file-name order (the geometric mode, the default then).
    #[arg(long, env = "TRE_CLIENT_DEPTH", conflicts_with_all = ["video", "device"])]
    pub depth: Option<PathBuf>,
    /// Camera-to-world poses of the frames (for --map): a folder of NAME.txt (a 4×4 matrix row
    /// by row, as `tre map`'s poses/), or a file with one pose a line in the frames' order:
    /// 16 numbers (4×4 row by row), 12 (3×4) or 8 (TUM: t tx ty tz qx qy qz qw).
    #[arg(long, env = "TRE_CLIENT_POSES", conflicts_with_all = ["video", "device"])]
    pub poses: Option<PathBuf>,
    /// Ask the server to keep the stream's grid map (docs/map.md) and write the last one into
    /// this folder at the end, as `tre map` writes its map. Needs a sensor noise model (the
    /// camera's "sensor" or --sensor); without --poses every frame restarts the map.
    #[arg(long, env = "TRE_CLIENT_MAP")]
    pub map: Option<PathBuf>,
    /// The map's cell side, centimetres.
    #[arg(long, env = "TRE_CLIENT_MAP_CELL_CM", default_value_t = 4.0)]
    pub map_cell_cm: f64,
    /// Side of the square map, metres.
    #[arg(long, env = "TRE_CLIENT_MAP_SIZE_M", default_value_t = 8.0)]
    pub map_size_m: f64,
    /// The world's down direction in the poses' frame, for the map: X,Y,Z or a gravity.json
    /// file ({"gravity": [x, y, z]}); default: from the first fused frame (its stated pitch,
    /// or its depth's ground plane).
    #[arg(long, env = "TRE_CLIENT_MAP_GRAVITY")]
    pub map_gravity: Option<String>,
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
    /// Also record every frame sent and every answer to this MCAP file (ROS 2 messages,
    /// zstd chunks; docs/ros2.md).
    #[arg(long, env = "TRE_CLIENT_RECORD")]
    pub record: Option<PathBuf>,
    /// Also record the outputs in Foxglove's JSON schemas (rosbag2 refuses such a file).
    #[arg(long, env = "TRE_CLIENT_RECORD_FOXGLOVE", requires = "record")]
    pub record_foxglove: bool,
}

/// Options that make no run.
#[derive(Debug, thiserror::Error)]
pub enum ArgsError {
    /// Not exactly one source of frames.
    #[error("give exactly one of --frames, --video and --device")]
    Source,
    /// The geometric mode without depth.
    #[error("--mode geometric reads depth only: give --depth DIR (with or without --frames)")]
    GeometricWithoutDepth,
    /// Depth-only frames in a mode that reads colour.
    #[error("--depth without --frames sends depth-only frames: the mode must be geometric")]
    DepthOnlyNeedsGeometric,
    /// Map settings that make no map.
    #[error("--map: {0}")]
    Map(MapArgProblem),
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
        let (source, mode) = self.source()?;
        let camera = self
            .camera
            .as_deref()
            .map(tre_io::read_camera)
            .transpose()?;
        let session = ClientConfig {
            camera: camera.map(|(c, _)| c),
            rate: self.rate.map_or(Rate::AsFastAsResults, Rate::Fixed),
            mode,
            map: self.map.as_ref().map(|_| self.map_request()).transpose()?,
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
            mcap_foxglove: self.record_foxglove,
            map_out: self.map.clone(),
        })
    }

    /// Where frames come from, and the mode (geometric by default for depth-only frames).
    fn source(&self) -> Result<(SourceSpec, Option<Mode>), ArgsError> {
        let mode = self.session.mode;
        let source = match (&self.frames, &self.depth, &self.video, &self.device) {
            (Some(frames), depth, None, None) => SourceSpec::Folder {
                frames: frames.clone(),
                depth: depth.clone(),
                poses: self.poses.clone(),
            },
            (None, Some(depth), None, None) => {
                if mode.is_some_and(|m| m != Mode::Geometric) {
                    return Err(ArgsError::DepthOnlyNeedsGeometric);
                }
                let spec = SourceSpec::Depth {
                    depth: depth.clone(),
                    poses: self.poses.clone(),
                };
                return Ok((spec, Some(Mode::Geometric)));
            }
            (None, None, Some(video), None) => SourceSpec::Video(video.clone()),
            (None, None, None, Some(device)) => SourceSpec::Device(device.clone()),
            _ => return Err(ArgsError::Source),
        };
        if mode == Some(Mode::Geometric) && self.depth.is_none() {
            return Err(ArgsError::GeometricWithoutDepth);
        }
        Ok((source, mode))
    }

    /// The map asked for by `--map-cell-cm`, `--map-size-m` and `--map-gravity`.
    fn map_request(&self) -> Result<MapRequest, ArgsError> {
        let cell_m = self.map_cell_cm / 100.0;
        let cells = (self.map_size_m / cell_m).round();
        if !(cell_m.is_finite()
            && cell_m > 0.0
            && cells.is_finite()
            && (1.0..=1000.0).contains(&cells))
        {
            return Err(ArgsError::Map(MapArgProblem::Cells {
                size_m: self.map_size_m,
                cell_cm: self.map_cell_cm,
            }));
        }
        let gravity = self.map_gravity.as_deref().map(gravity).transpose()?;
        Ok(MapRequest {
            cell_m,
            side: cells as u32,
            gravity,
        })
    }
}

/// `--map-gravity`: `X,Y,Z`, or a gravity.json file.
fn gravity(text: &str) -> Result<[f64; 3], ArgsError> {
    let numbers: Result<Vec<f64>, _> = text.split(',').map(|t| t.trim().parse()).collect();
    if let Ok(&[x, y, z]) = numbers.as_deref() {
        return Ok([x, y, z]);
    }
    #[derive(serde::Deserialize)]
    struct GravityFile {
        gravity: [f64; 3],
    }
    let bytes = std::fs::read(text).map_err(|reason| {
        ArgsError::Map(MapArgProblem::GravityRead {
            text: text.to_owned(),
            reason,
        })
    })?;
    let g: GravityFile = serde_json::from_slice(&bytes).map_err(|reason| {
        ArgsError::Map(MapArgProblem::GravityFile {
            path: text.to_owned(),
            reason,
        })
    })?;
    Ok(g.gravity)
}

/// Why `--map-cell-cm`, `--map-size-m` or `--map-gravity` make no map ([`ArgsError::Map`]).
// The cause is in the message, not a `source` (as the crate's other problems).
#[derive(Debug, thiserror::Error)]
pub enum MapArgProblem {
    /// A size and cell that are not 1 to 1000 cells a side.
    #[error("{size_m} m at {cell_cm} cm a cell is not 1 to 1000 cells a side")]
    Cells {
        /// `--map-size-m`.
        size_m: f64,
        /// `--map-cell-cm`.
        cell_cm: f64,
    },
    /// A `--map-gravity` that is neither `X,Y,Z` nor a file that reads.
    #[error("--map-gravity {text}: not X,Y,Z, nor a file ({reason})")]
    GravityRead {
        /// The value given.
        text: String,
        /// Why it does not read as a file.
        reason: std::io::Error,
    },
    /// A gravity file that is not `{"gravity": [x, y, z]}`.
    #[error("--map-gravity {path}: {reason}")]
    GravityFile {
        /// The file given.
        path: String,
        /// What the parser said.
        reason: serde_json::Error,
    },
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
                depth: Some("d".into()),
                poses: None,
            }
        );
        assert_eq!(run.limit, Some(3));
        let d = parse(&["--server", "h:1", "--video", "v.mp4", "-o", "o"]).unwrap();
        assert_eq!(d.session.rate, Rate::AsFastAsResults);
        assert_eq!(d.session.reconnect.give_up_after, Some(20));
        // One value per default: the options' defaults are the library's.
        assert_eq!(d.session.reconnect, crate::config::Backoff::default());
        assert_eq!(
            d.session.connect_timeout,
            ClientConfig::default().connect_timeout
        );
    }

    #[test]
    fn depth_alone_is_a_depth_only_geometric_run_with_poses_and_a_map() {
        let run = parse(&[
            "--server",
            "h:1",
            "--depth",
            "d",
            "--poses",
            "p.txt",
            "--map",
            "m",
            "--map-cell-cm",
            "5",
            "--map-size-m",
            "6",
            "--map-gravity",
            "0,1,0",
            "-o",
            "o",
        ])
        .unwrap();
        assert_eq!(
            run.source,
            SourceSpec::Depth {
                depth: "d".into(),
                poses: Some("p.txt".into())
            }
        );
        assert_eq!(run.session.mode, Some(Mode::Geometric));
        assert_eq!(
            run.session.map,
            Some(MapRequest {
                cell_m: 0.05,
                side: 120,
                gravity: Some([0.0, 1.0, 0.0])
            })
        );
        assert_eq!(run.map_out, Some("m".into()));
        let plain = parse(&["--server", "h:1", "--depth", "d", "-o", "o"]).unwrap();
        assert_eq!(plain.session.map, None);
    }

    #[test]
    fn depth_only_runs_refuse_colour_modes_and_bad_maps() {
        for (args, why) in [
            (
                &[
                    "--server", "h:1", "--depth", "d", "--mode", "rgbd", "-o", "o",
                ][..],
                "must be geometric",
            ),
            (
                &[
                    "--server",
                    "h:1",
                    "--frames",
                    "f",
                    "--mode",
                    "geometric",
                    "-o",
                    "o",
                ],
                "give --depth",
            ),
            (
                &[
                    "--server",
                    "h:1",
                    "--depth",
                    "d",
                    "--map",
                    "m",
                    "--map-size-m",
                    "100",
                    "-o",
                    "o",
                ],
                "1 to 1000 cells",
            ),
            (
                &[
                    "--server",
                    "h:1",
                    "--depth",
                    "d",
                    "--map",
                    "m",
                    "--map-gravity",
                    "/nonexistent.json",
                    "-o",
                    "o",
                ],
                "--map-gravity",
            ),
        ] {
            let e = parse(args).unwrap_err();
            assert!(e.contains(why), "{args:?}: {e}");
        }
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
