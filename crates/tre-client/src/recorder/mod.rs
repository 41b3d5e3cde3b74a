//! Recording a stream session to disk (what `tre client` does): frames from a [`SourceSpec`]
//! go to the server through a [`Session`], and each answer is written into an output folder as
//! it comes: `SEQ_NAME.png` per result (the roughness map as received; `f32` maps as the same
//! 16-bit PNG as `png16`), `SEQ_NAME_traversable.png`, `SEQ_NAME_traversal.png` and
//! `SEQ_NAME_uncertainty.png` when asked for, and one `frames.csv` row per frame sent (its
//! result, or why it has none). The person running it is kept informed through [`Notice`]s:
//! the connection, a progress line a second, reconnections, the final counts.
//!
//! ```no_run
//! # async fn demo() -> Result<(), tre_client::recorder::RecordError> {
//! use tre_client::recorder::{record, RecorderConfig};
//! use tre_client::source::SourceSpec;
//! use tre_client::ClientConfig;
//! let cfg = RecorderConfig {
//!     session: ClientConfig {
//!         server: "ws://10.0.0.2:8080/v1/stream".into(),
//!         ..ClientConfig::default()
//!     },
//!     source: SourceSpec::Folder {
//!         frames: "frames".into(),
//!         depth: None,
//!         poses: None,
//!     },
//!     out: "out".into(),
//!     limit: Some(100),
//!     ..RecorderConfig::default()
//! };
//! // Stops sending on Ctrl-C; the frames in flight still get their answers.
//! let stop = async {
//!     let _ = tokio::signal::ctrl_c().await;
//! };
//! let done = record(&cfg, stop, |notice| eprintln!("{notice}")).await?;
//! println!("{} results, {} lost", done.results, done.lost);
//! # Ok(())
//! # }
//! ```

mod send;
mod sink;
mod stats;
mod writer;

use std::fmt;
use std::future::Future;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use tokio::sync::mpsc;

use super::source::{FrameSource, SourceSpec};
use super::{ClientConfig, ClientError, DisconnectReason, Session, StreamMap};
use send::{send_frames, start_reader};
use sink::Sink;
use stats::Stats;
use tre_io::map_files::{write_map_window, MapRun, MapWindow};
use writer::start_writer;

pub use stats::Progress;

/// What to record: the session's settings, where frames come from and where results go.
#[derive(Debug, Clone, PartialEq)]
pub struct RecorderConfig {
    /// The session's settings (checked when it connects).
    pub session: ClientConfig,
    /// Where frames come from.
    pub source: SourceSpec,
    /// Output folder (created if missing).
    pub out: PathBuf,
    /// Frames to send at most.
    pub limit: Option<u64>,
    /// Start the source over at its end (until `limit` or the stop signal; not for a camera).
    pub repeat: bool,
    /// Also record every frame sent and every answer to this MCAP file (ROS 2 messages;
    /// `tre_record::topics`).
    pub mcap: Option<PathBuf>,
    /// Add the Foxglove JSON-schema channels to the MCAP file (rosbag2 then refuses it).
    pub mcap_foxglove: bool,
    /// Write the stream's grid map into this folder at the end, as `tre map` writes its map
    /// (the session must ask for one: [`ClientConfig::map`]).
    pub map_out: Option<PathBuf>,
}

impl Default for RecorderConfig {
    fn default() -> Self {
        Self {
            session: ClientConfig::default(),
            source: SourceSpec::Folder {
                frames: PathBuf::from("frames"),
                depth: None,
                poses: None,
            },
            out: PathBuf::from("out"),
            limit: None,
            repeat: false,
            mcap: None,
            mcap_foxglove: false,
            map_out: None,
        }
    }
}

/// What a recording tells the person running it; each displays as the line `tre client` prints.
/// Notices compare as [`Event`](crate::Event)s do: a `GaveUp` equals its clones.
#[derive(Debug, Clone)]
pub enum Notice {
    /// The session is up.
    Connected {
        /// The server address as given.
        server: String,
        /// The models the server runs.
        models: Vec<String>,
    },
    /// The counts so far, once a second.
    Progress(Progress),
    /// The stop signal came: no more frames are sent, those in flight still get their answers.
    Stopping,
    /// The connection dropped; the session is reconnecting.
    Disconnected {
        /// What ended it.
        reason: DisconnectReason,
    },
    /// A new connection is up.
    Reconnected {
        /// Attempts it took.
        attempts: u32,
        /// Time without a connection.
        downtime: Duration,
    },
    /// Reconnecting failed for good; the recording ends.
    GaveUp {
        /// What failed last.
        reason: Arc<ClientError>,
    },
    /// The recording's final counts.
    Finished(Progress),
    /// The first answer, and any answer whose mode, stand-ins or gravity source differs from
    /// the last told: what ran and what the server assumed.
    Answering {
        /// The mode that ran.
        mode: String,
        /// What stood in for what was not given (`intrinsics`, `depth_scale`, `mounting`,
        /// `mode`).
        assumed: Vec<String>,
        /// Where gravity came from, as the server words it.
        gravity: String,
    },
    /// The stream's grid map was written (`tre map`'s files).
    MapWritten {
        /// The folder.
        dir: PathBuf,
        /// Frames fused into it, and skipped.
        fused: u64,
        /// Frames the map skipped.
        skipped: u64,
    },
    /// A map was asked for and none came back (no frame could start it).
    NoMap,
    /// Where the maps and `frames.csv` are.
    Written {
        /// The output folder.
        out: PathBuf,
        /// Frames answered (each with its maps).
        maps: u64,
    },
}

impl PartialEq for Notice {
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (
                Self::Connected {
                    server: a,
                    models: x,
                },
                Self::Connected {
                    server: b,
                    models: y,
                },
            ) => (a, x) == (b, y),
            (Self::Progress(a), Self::Progress(b)) | (Self::Finished(a), Self::Finished(b)) => {
                a == b
            }
            (Self::Stopping, Self::Stopping) | (Self::NoMap, Self::NoMap) => true,
            (
                Self::MapWritten {
                    dir: a,
                    fused: x,
                    skipped: m,
                },
                Self::MapWritten {
                    dir: b,
                    fused: y,
                    skipped: n,
                },
            ) => (a, x, m) == (b, y, n),
            (Self::Disconnected { reason: a }, Self::Disconnected { reason: b }) => a == b,
            (
                Self::Reconnected {
                    attempts: a,
                    downtime: x,
                },
                Self::Reconnected {
                    attempts: b,
                    downtime: y,
                },
            ) => (a, x) == (b, y),
            (Self::GaveUp { reason: a }, Self::GaveUp { reason: b }) => Arc::ptr_eq(a, b),
            (
                Self::Answering {
                    mode: a,
                    assumed: x,
                    gravity: m,
                },
                Self::Answering {
                    mode: b,
                    assumed: y,
                    gravity: n,
                },
            ) => (a, x, m) == (b, y, n),
            (Self::Written { out: a, maps: x }, Self::Written { out: b, maps: y }) => {
                (a, x) == (b, y)
            }
            _ => false,
        }
    }
}

impl fmt::Display for Notice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Connected { server, models } => {
                write!(f, "connected to {server} (models: {})", models.join(", "))
            }
            Self::Progress(p) | Self::Finished(p) => write!(f, "{p}"),
            Self::Stopping => f.write_str("stopping: waiting for the frames in flight"),
            Self::Disconnected { reason } => write!(f, "disconnected: {reason}; reconnecting"),
            Self::Reconnected { attempts, downtime } => write!(
                f,
                "reconnected after {:.1} s ({attempts} attempts)",
                downtime.as_secs_f64()
            ),
            Self::GaveUp { reason } => write!(f, "gave up: {reason}"),
            Self::Answering {
                mode,
                assumed,
                gravity,
            } => {
                write!(f, "answers: mode {mode}, gravity {gravity}")?;
                if !assumed.is_empty() {
                    write!(
                        f,
                        "\nwarning: the server assumed {} (not given: see docs/service.md, \
                         \"What the answer assumed\")",
                        assumed.join(", ")
                    )?;
                }
                Ok(())
            }
            Self::MapWritten {
                dir,
                fused,
                skipped,
            } => write!(
                f,
                "map of {fused} fused frames ({skipped} skipped) in {}",
                dir.display()
            ),
            Self::NoMap => f.write_str(
                "warning: no map came back (no frame could start it: gravity unknown, or no \
                 depth)",
            ),
            Self::Written { out, maps: 0 } => write!(
                f,
                "frames.csv in {} (no maps: no frame was answered)",
                out.display()
            ),
            Self::Written { out, maps } => {
                write!(
                    f,
                    "maps of {maps} frames and frames.csv in {}",
                    out.display()
                )
            }
        }
    }
}

/// Why a recording failed.
// A cause is either a `source` left out of the message (`Connect`, `Io`, `Spawn`), or in the
// message and not a `source` (`Sending`, `EndedEarly`): never both, so a report that prints the
// chain says each once.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The source cannot be opened or read, or the session failed.
    #[error(transparent)]
    Client(#[from] ClientError),
    /// The first connection failed.
    #[error("connecting to {server}")]
    Connect {
        /// The server address as given.
        server: String,
        /// Why.
        #[source]
        source: ClientError,
    },
    /// A file or folder of the output cannot be made or written.
    #[error("{action} {}", path.display())]
    Io {
        /// `creating` or `writing`.
        action: &'static str,
        /// The file or folder.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A map cannot be encoded or written.
    #[error(transparent)]
    Map(#[from] tre_io::IoError),
    /// The MCAP recording could not be written.
    #[error(transparent)]
    Mcap(#[from] tre_record::RecordError),
    /// A thread of the recording cannot be started.
    #[error("starting the {what}")]
    Spawn {
        /// The thread.
        what: &'static str,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The writer thread stopped before the session ended (it panicked).
    #[error("the writer thread {0}")]
    Writer(&'static str),
    /// The task sending frames failed.
    #[error("the sending task failed: {0}")]
    Sending(tokio::task::JoinError),
    /// The session gave up reconnecting.
    #[error("the stream ended early: {reason}")]
    EndedEarly {
        /// What failed last.
        reason: Arc<ClientError>,
    },
    /// Frames went out but no result came back.
    #[error(
        "no results came back from {server} ({dropped} dropped, {errors} errors, {lost} lost)"
    )]
    NoResults {
        /// The server address as given.
        server: String,
        /// Frames the server skipped.
        dropped: u64,
        /// Frames answered with an error.
        errors: u64,
        /// Frames that got no answer.
        lost: u64,
    },
}

/// Records a session: connects, streams the source's frames (up to `cfg.limit`), writes each
/// answer into `cfg.out` as it comes, and tells `notify` how it goes. `stop` ends the sending
/// early (the frames in flight still get their answers). Returns the final counts.
///
/// # Errors
///
/// [`RecordError`] when the output cannot be written, the source cannot be read, the first
/// connection fails, the session gives up reconnecting, or no result came back.
pub async fn record<N: FnMut(Notice)>(
    cfg: &RecorderConfig,
    stop: impl Future<Output = ()>,
    mut notify: N,
) -> Result<Progress, RecordError> {
    std::fs::create_dir_all(&cfg.out).map_err(|source| RecordError::Io {
        action: "creating",
        path: cfg.out.clone(),
        source,
    })?;
    let source = FrameSource::open(&cfg.source)?;
    let server = cfg.session.server.clone();
    let session = Session::connect(cfg.session.clone())
        .await
        .map_err(|source| RecordError::Connect {
            server: server.clone(),
            source,
        })?;
    let models = session.server().models.clone();
    notify(Notice::Connected { server, models });
    let (sender, mut events) = session.split();
    let (frames_tx, frames_rx) = mpsc::channel(2);
    let reader = start_reader(source, cfg, frames_tx)?;
    let options = tre_record::RecordOptions {
        foxglove: cfg.mcap_foxglove,
    };
    let mcap = cfg.mcap.as_deref().map(|p| (p, options));
    let (jobs, writer) = start_writer(&cfg.out, mcap, cfg.session.camera.as_ref())?;
    let mut sink = Sink::new(&cfg.out, jobs, &mut notify);
    let sending = tokio::spawn(send_frames(
        sender,
        frames_rx,
        sink.log.clone(),
        sink.sent.clone(),
        cfg.mcap.is_some(),
    ));
    sink.drain(&mut events, &sending, stop).await?;
    let sent_outcome = sending.await;
    let (mut stats, sent) = sink.close();
    let written = writer.join().map_err(|_| RecordError::Writer("panicked"))?;
    let _ = reader.join();
    let done = stats.progress(sent.load(Ordering::Relaxed), false);
    notify(Notice::Finished(done.clone()));
    notify(Notice::Written {
        out: cfg.out.clone(),
        maps: stats.results,
    });
    written?;
    if let Some(dir) = &cfg.map_out {
        notify(write_stream_map(dir, stats.map.take())?);
    }
    verdict(&stats, sent_outcome, &cfg.session.server)?;
    Ok(done)
}

/// Writes the stream's last map into `dir` as `tre map` does; the notice that tells it.
fn write_stream_map(dir: &Path, map: Option<Box<StreamMap>>) -> Result<Notice, RecordError> {
    let Some(m) = map else {
        return Ok(Notice::NoMap);
    };
    let window = MapWindow {
        cell_m: m.cell_m,
        side: m.side,
        origin: m.origin,
        map_from_world: m.map_from_world,
        memory_bytes: None,
    };
    let skipped = match m.skipped {
        0 => Vec::new(),
        n => vec![format!(
            "{n} frames skipped by the server's map (see its log)"
        )],
    };
    let run = MapRun {
        fused: usize::try_from(m.fused).unwrap_or(usize::MAX),
        skipped,
        ..MapRun::default()
    };
    write_map_window(dir, &window, &m.layers, &run)?;
    Ok(Notice::MapWritten {
        dir: dir.to_owned(),
        fused: m.fused,
        skipped: m.skipped,
    })
}

/// The recording's verdict: an error if the source failed, the session gave up or nothing came
/// back.
fn verdict(
    stats: &Stats,
    sent: Result<Result<(), ClientError>, tokio::task::JoinError>,
    server: &str,
) -> Result<(), RecordError> {
    match sent {
        Ok(Ok(()) | Err(ClientError::Closed)) => {}
        Ok(Err(e)) => return Err(e.into()),
        Err(e) if e.is_cancelled() => {}
        Err(e) => return Err(RecordError::Sending(e)),
    }
    if let Some(reason) = &stats.gave_up {
        return Err(RecordError::EndedEarly {
            reason: reason.clone(),
        });
    }
    if stats.results == 0 {
        return Err(RecordError::NoResults {
            server: server.to_owned(),
            dropped: stats.dropped,
            errors: stats.errors,
            lost: stats.lost,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn notices_read_as_the_lines_of_tre_client() {
        let connected = Notice::Connected {
            server: "ws://h:1".into(),
            models: vec!["depth".into(), "normals".into()],
        };
        assert_eq!(
            connected.to_string(),
            "connected to ws://h:1 (models: depth, normals)"
        );
        let reconnected = Notice::Reconnected {
            attempts: 3,
            downtime: Duration::from_millis(1300),
        };
        assert_eq!(
            reconnected.to_string(),
            "reconnected after 1.3 s (3 attempts)"
        );
        let written = Notice::Written {
            out: "o".into(),
            maps: 4,
        };
        assert_eq!(written.to_string(), "maps of 4 frames and frames.csv in o");
        let gave_up = Notice::GaveUp {
            reason: Arc::new(ClientError::Closed),
        };
        assert_eq!(gave_up.to_string(), "gave up: the stream session has ended");
        assert_eq!(gave_up.clone(), gave_up);
        let dropped = Notice::Disconnected {
            reason: DisconnectReason::Ended,
        };
        assert_eq!(
            dropped.to_string(),
            "disconnected: the connection ended; reconnecting"
        );
        assert_ne!(dropped, Notice::Stopping);
        let none = Notice::Written {
            out: "o".into(),
            maps: 0,
        };
        assert_eq!(
            none.to_string(),
            "frames.csv in o (no maps: no frame was answered)"
        );
        let answering = Notice::Answering {
            mode: "geometric".into(),
            assumed: vec!["depth_scale".into()],
            gravity: "estimated; pitch_deg=28.2".into(),
        };
        let line = answering.to_string();
        assert!(
            line.starts_with("answers: mode geometric, gravity estimated")
                && line.contains("warning: the server assumed depth_scale"),
            "{line}"
        );
    }

    #[test]
    fn the_verdict_needs_a_result_and_a_session_that_did_not_give_up() {
        let mut stats = Stats::new();
        stats.dropped = 2;
        let e = verdict(&stats, Ok(Ok(())), "h:1").unwrap_err();
        assert_eq!(
            e.to_string(),
            "no results came back from h:1 (2 dropped, 0 errors, 0 lost)"
        );
        stats.results = 1;
        assert!(verdict(&stats, Ok(Err(ClientError::Closed)), "h:1").is_ok());
        stats.gave_up = Some(Arc::new(ClientError::HelloRefused {
            code: crate::ErrorKind::Server(tre_proto::ErrorCode::BadCamera),
            message: "refused".into(),
        }));
        let e = verdict(&stats, Ok(Ok(())), "h:1").unwrap_err();
        assert_eq!(
            e.to_string(),
            "the stream ended early: the server refused the Hello: bad_camera: refused"
        );
    }
}
