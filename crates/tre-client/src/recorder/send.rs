//! The sending side of a recording: a thread reads the source (again from the start with
//! `repeat`) into a bounded channel, and a task sends each frame through the session, logging
//! its name and send time under its sequence number.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::SystemTime;

use tokio::sync::mpsc;

use super::{RecordError, RecorderConfig};
use crate::source::{FrameSource, SourceFrame, SourceSpec};
use crate::{ClientError, Frame, FrameSender};

/// Name and send time of each frame sent, by sequence number (entries leave as answers come).
pub(super) type SentLog = Arc<Mutex<HashMap<u64, Sent>>>;

/// A frame sent: its name, when it left, and its bytes when the recording keeps them.
#[derive(Debug, Default)]
pub(super) struct Sent {
    /// The frame's file stem.
    pub name: String,
    /// When it was sent.
    pub at: Option<SystemTime>,
    /// Its bytes, for an MCAP recording.
    pub input: Option<Box<SentInput>>,
}

/// A frame's bytes as sent (kept for the MCAP recording until its answer comes).
#[derive(Debug)]
pub(super) struct SentInput {
    /// PNG or JPEG colour (may be empty).
    pub image: Vec<u8>,
    /// 16-bit PNG or `.npy` depth.
    pub depth: Option<Vec<u8>>,
}

/// Frames read from the source, or why reading failed.
type Frames = mpsc::Sender<Result<SourceFrame, ClientError>>;

/// Starts the frame reader thread on the opened `source`.
pub(super) fn start_reader(
    source: FrameSource,
    cfg: &RecorderConfig,
    tx: Frames,
) -> Result<JoinHandle<()>, RecordError> {
    let (spec, limit, repeat) = (cfg.source.clone(), cfg.limit, cfg.repeat);
    std::thread::Builder::new()
        .name("tre-frames".into())
        .spawn(move || read_frames(source, &spec, limit, repeat, &tx))
        .map_err(|source| RecordError::Spawn {
            what: "frame reader",
            source,
        })
}

/// The frame reader thread: the source (reopened with `repeat`) into `tx`, up to `limit`.
fn read_frames(
    first: FrameSource,
    spec: &SourceSpec,
    limit: Option<u64>,
    repeat: bool,
    tx: &Frames,
) {
    let mut source = first;
    let mut n = 0u64;
    loop {
        let mut any = false;
        for item in source.by_ref() {
            if limit.is_some_and(|l| n >= l) {
                return;
            }
            let failed = item.is_err();
            if tx.blocking_send(item).is_err() || failed {
                return;
            }
            any = true;
            n += 1;
        }
        if !(repeat && any) || matches!(spec, SourceSpec::Device(_)) {
            return;
        }
        source = match FrameSource::open(spec) {
            Ok(s) => s,
            Err(e) => {
                let _ = tx.blocking_send(Err(e));
                return;
            }
        };
    }
}

/// The sending task: each frame through the session, its name (and with `keep_inputs` its
/// bytes) logged under its sequence.
pub(super) async fn send_frames(
    mut sender: FrameSender,
    mut frames: mpsc::Receiver<Result<SourceFrame, ClientError>>,
    log: SentLog,
    sent: Arc<AtomicU64>,
    keep_inputs: bool,
) -> Result<(), ClientError> {
    while let Some(item) = frames.recv().await {
        let f = item?;
        let sequence = sender.next_sequence();
        let entry = Sent {
            name: f.name.clone(),
            at: None,
            input: keep_inputs.then(|| {
                Box::new(SentInput {
                    image: f.image.clone(),
                    depth: f.depth.clone(),
                })
            }),
        };
        log_entry(&log, sequence, Some(entry));
        let frame = Frame {
            image: f.image,
            depth: f.depth,
            pose: f.pose,
            ..Frame::default()
        };
        match sender.send(frame).await {
            Ok(_) => {
                sent.fetch_add(1, Ordering::Relaxed);
                if let Some(e) = log
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .get_mut(&sequence)
                {
                    e.at = Some(SystemTime::now());
                }
            }
            Err(e @ ClientError::FrameTooLarge { .. }) => {
                log_entry(&log, sequence, None);
                tracing::warn!(frame = %f.name, "skipped: {e}");
            }
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

/// Sets (`Some`) or removes (`None`) a frame's log entry.
fn log_entry(log: &SentLog, sequence: u64, entry: Option<Sent>) {
    let mut log = log.lock().unwrap_or_else(PoisonError::into_inner);
    match entry {
        Some(e) => log.insert(sequence, e),
        None => log.remove(&sequence),
    };
}
