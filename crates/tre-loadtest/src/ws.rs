//! WebSocket load on `GET /v1/stream`: open loop sends frames on a schedule round robin over the
//! connections and matches answers by sequence number; closed loop has each connection wait for
//! its frame's `Result`, `Dropped` or `Error` before sending the next. The protobuf types stay
//! in this file: they are turned into [`Answer`]s as they arrive.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use futures_util::stream::{SplitSink, SplitStream};
use futures_util::{SinkExt, StreamExt};
use prost::Message as _;
use tokio::net::TcpStream;
use tokio::sync::mpsc;
use tokio::task::JoinSet;
use tokio::time::Instant;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream};

use super::frames::Frames;
use super::plan::Plan;
use super::problems::{AnswerProblem, FirstAnswer, StreamProblem};
use super::stats::{Outcome, Recorder, Report, RunInfo};
use super::{Load, LoadConfig, LoadError, Target};
use tre_proto::v1 as pb;

/// Frames that may wait for one connection's writer (open loop); beyond, `client_saturated`.
const WRITER_QUEUE: usize = 64;
/// Poll interval while waiting for the last answers.
const DRAIN_POLL: Duration = Duration::from_millis(5);
/// Error codes of the service that mean "overloaded, retry later".
const RETRYABLE: [&str; 4] = ["too_many_requests", "overloaded", "not_ready", "timeout"];

type Socket = WebSocketStream<MaybeTlsStream<TcpStream>>;

/// A server message, as far as the load test cares.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Answer {
    /// The Hello was accepted.
    Ready,
    /// A result for frame `sequence`.
    Result(u64),
    /// Frame `sequence` was skipped for a newer one.
    Dropped(u64),
    /// An error, for one frame or for the stream.
    Error {
        /// The frame, if the error concerns one.
        sequence: Option<u64>,
        /// Stable error code.
        code: String,
    },
}

impl Answer {
    /// Decodes a `ServerMessage`.
    pub(crate) fn decode(bytes: &[u8]) -> Result<Self, AnswerProblem> {
        use pb::server_message::Msg;
        let msg = pb::ServerMessage::decode(bytes)?;
        match msg.msg {
            Some(Msg::Ready(_)) => Ok(Self::Ready),
            Some(Msg::Result(r)) => Ok(Self::Result(r.sequence)),
            Some(Msg::Dropped(d)) => Ok(Self::Dropped(d.sequence)),
            Some(Msg::Error(e)) => Ok(Self::Error {
                sequence: e.sequence,
                code: e.code,
            }),
            // The load test's Hello asks for no map; one would be no frame's answer.
            Some(Msg::Map(_)) => Ok(Self::Ready),
            None => Err(AnswerProblem::Empty),
        }
    }

    /// The frame this answer is for, and what became of it.
    pub(crate) fn outcome(&self) -> Option<(u64, Outcome)> {
        match self {
            Self::Ready => None,
            Self::Result(seq) => Some((*seq, Outcome::Ok)),
            Self::Dropped(seq) => Some((*seq, Outcome::Dropped)),
            Self::Error { sequence, code } => {
                let outcome = if RETRYABLE.contains(&code.as_str()) {
                    Outcome::Refused(code.clone())
                } else {
                    Outcome::Error(format!("ws {code}"))
                };
                Some(((*sequence)?, outcome))
            }
        }
    }
}

/// A `ClientMessage` with the Hello of `ask` (what `tre client` sends for the same choices).
fn hello(ask: &super::Ask) -> Message {
    let msg = pb::ClientMessage {
        msg: Some(pb::client_message::Msg::Hello(ask.hello())),
    };
    Message::Binary(msg.encode_to_vec().into())
}

/// A `ClientMessage` carrying frame `sequence`.
fn frame(sequence: u64, frames: &Frames) -> Message {
    let timestamp_us = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_micros()).unwrap_or(i64::MAX));
    let msg = pb::ClientMessage {
        msg: Some(pb::client_message::Msg::Frame(pb::Frame {
            sequence,
            timestamp_us,
            image: frames.get(sequence).image.to_vec(),
            depth: frames.get(sequence).depth.to_vec(),
            ..pb::Frame::default()
        })),
    };
    Message::Binary(msg.encode_to_vec().into())
}

/// Opens a stream (over TLS with `tls`), sends the Hello and waits for Ready.
async fn connect(
    target: &Target,
    ask: &super::Ask,
    timeout: Duration,
    api_key: Option<&str>,
    tls: Option<&Arc<rustls::ClientConfig>>,
) -> Result<Socket, LoadError> {
    let url = target.stream_url();
    let err = |why: StreamProblem| LoadError::Stream {
        url: url.clone(),
        why,
    };
    let setup = async {
        let tcp = TcpStream::connect(target.addr).await.map_err(|source| {
            err(StreamProblem::Connect {
                addr: target.addr,
                source,
            })
        })?;
        tcp.set_nodelay(true)
            .map_err(|e| err(StreamProblem::Socket(e)))?;
        let mut request =
            tokio_tungstenite::tungstenite::client::IntoClientRequest::into_client_request(
                url.as_str(),
            )
            .map_err(|e| err(e.into()))?;
        if let Some(key) = api_key {
            request
                .headers_mut()
                .insert(reqwest::header::AUTHORIZATION, super::bearer(key)?);
        }
        let connector = tls.cloned().map(tokio_tungstenite::Connector::Rustls);
        let (mut ws, _) =
            tokio_tungstenite::client_async_tls_with_config(request, tcp, None, connector)
                .await
                .map_err(|e| err(StreamProblem::Handshake(e)))?;
        ws.send(hello(ask)).await.map_err(|e| err(e.into()))?;
        while let Some(msg) = ws.next().await {
            let Message::Binary(b) = msg.map_err(|e| err(e.into()))? else {
                continue;
            };
            let first = match Answer::decode(&b).map_err(|e| err(e.into()))? {
                Answer::Ready => return Ok(ws),
                Answer::Result(seq) => FirstAnswer::Result(seq),
                Answer::Dropped(seq) => FirstAnswer::Dropped(seq),
                Answer::Error { sequence, code } => FirstAnswer::Error { sequence, code },
            };
            return Err(err(StreamProblem::NotReady(first)));
        }
        Err(err(StreamProblem::Closed))
    };
    tokio::time::timeout(timeout, setup).await.map_err(|_| {
        err(StreamProblem::Timeout {
            timeout_ms: timeout.as_millis(),
        })
    })?
}

/// Runs `cfg` over the stream against `target`.
pub(super) async fn drive(
    cfg: &LoadConfig,
    target: &Target,
    frames: &Frames,
) -> Result<Report, LoadError> {
    let tls = match target.tls {
        true => {
            Some(tre_client::tls::client_config(cfg.ca_cert.as_deref()).map_err(LoadError::Tls)?)
        }
        false => None,
    };
    let mut sockets = Vec::with_capacity(cfg.connections);
    for _ in 0..cfg.connections {
        let key = cfg.api_key.as_deref();
        sockets.push(connect(target, &cfg.ask, cfg.timeout, key, tls.as_ref()).await?);
    }
    let plan = Plan::new(cfg);
    let run = Arc::new(Run {
        rec: Recorder::new(plan.measure_from),
        plan,
        frames: frames.clone(),
        next: AtomicU64::new(0),
        timeout: cfg.timeout,
    });
    let window_s = match cfg.load {
        Load::Open { rate_per_s } => {
            open_loop(&run, sockets, rate_per_s, cfg.max_in_flight).await;
            run.plan.measured() as f64 / rate_per_s
        }
        Load::Closed => {
            let mut tasks = JoinSet::new();
            for socket in sockets {
                tasks.spawn(closed_loop(socket, run.clone()));
            }
            while tasks.join_next().await.is_some() {}
            let end = run.rec.last_done().unwrap_or(run.plan.measure_from);
            end.saturating_duration_since(run.plan.measure_from)
                .as_secs_f64()
        }
    };
    let info = RunInfo::new(cfg, target.stream_url(), frames, &run.plan);
    Ok(run.rec.report(info, window_s))
}

/// What one run shares with its connection tasks.
struct Run {
    plan: Plan,
    rec: Recorder,
    frames: Frames,
    /// Next request index (closed loop; sequences are indices + 1).
    next: AtomicU64,
    timeout: Duration,
}

/// Frames sent on one connection and not answered yet: sequence → intended send time.
type Pending = Arc<Mutex<HashMap<u64, Instant>>>;

/// One open-loop connection: its writer's queue and its unanswered frames.
struct Conn {
    tx: mpsc::Sender<u64>,
    pending: Pending,
}

fn lock(p: &Pending) -> std::sync::MutexGuard<'_, HashMap<u64, Instant>> {
    p.lock().unwrap_or_else(|e| e.into_inner())
}

/// Sends frame `i` at its intended time round robin over `sockets`, whatever the answers do;
/// a reader per connection matches answers to frames by sequence number. After the schedule,
/// waits up to the timeout for the last answers; frames still unanswered count as timeouts.
async fn open_loop(run: &Arc<Run>, sockets: Vec<Socket>, rate_per_s: f64, max_in_flight: usize) {
    let in_flight = Arc::new(AtomicUsize::new(0));
    let mut writers = JoinSet::new();
    let mut readers = JoinSet::new();
    let mut conns = Vec::with_capacity(sockets.len());
    for socket in sockets {
        let (sink, stream) = socket.split();
        let (tx, rx) = mpsc::channel(WRITER_QUEUE);
        let pending = Pending::default();
        writers.spawn(write(sink, rx, run.clone()));
        readers.spawn(read(
            stream,
            pending.clone(),
            in_flight.clone(),
            run.clone(),
        ));
        conns.push(Conn { tx, pending });
    }
    for i in 0u64.. {
        let intended = run.plan.intended(i, rate_per_s);
        if run.plan.admit(intended).is_none() {
            break;
        }
        tokio::time::sleep_until(intended).await;
        let conn = &conns[(i % conns.len() as u64) as usize];
        if in_flight.load(Ordering::Relaxed) >= max_in_flight {
            run.rec.record(intended, intended, Outcome::ClientSaturated);
            continue;
        }
        let seq = sequence(i);
        lock(&conn.pending).insert(seq, intended);
        in_flight.fetch_add(1, Ordering::Relaxed);
        if let Err(e) = conn.tx.try_send(seq) {
            if lock(&conn.pending).remove(&seq).is_some() {
                in_flight.fetch_sub(1, Ordering::Relaxed);
                let outcome = match e {
                    mpsc::error::TrySendError::Full(_) => Outcome::ClientSaturated,
                    mpsc::error::TrySendError::Closed(_) => Outcome::Error("ws closed".into()),
                };
                run.rec.record(intended, Instant::now(), outcome);
            }
        }
    }
    let deadline = Instant::now() + run.timeout;
    while in_flight.load(Ordering::Relaxed) > 0 && Instant::now() < deadline {
        tokio::time::sleep(DRAIN_POLL).await;
    }
    let now = Instant::now();
    for conn in &conns {
        for (_, intended) in lock(&conn.pending).drain() {
            run.rec
                .record(intended, now, Outcome::Error("timeout".into()));
        }
    }
    drop(conns);
    while writers.join_next().await.is_some() {}
    readers.abort_all();
    while readers.join_next().await.is_some() {}
}

/// Sends the frames queued for one connection; closes it when the queue closes.
async fn write(mut sink: SplitSink<Socket, Message>, mut rx: mpsc::Receiver<u64>, run: Arc<Run>) {
    while let Some(seq) = rx.recv().await {
        if sink.send(frame(seq, &run.frames)).await.is_err() {
            break;
        }
    }
    let _ = sink.close().await;
}

/// Matches one connection's answers to its pending frames; if the stream ends, the frames
/// still pending count as `ws closed`.
async fn read(
    mut stream: SplitStream<Socket>,
    pending: Pending,
    in_flight: Arc<AtomicUsize>,
    run: Arc<Run>,
) {
    while let Some(Ok(msg)) = stream.next().await {
        let Message::Binary(b) = msg else {
            continue;
        };
        let (seq, outcome) = match Answer::decode(&b) {
            Ok(answer) => match answer.outcome() {
                Some(o) => o,
                None => continue,
            },
            Err(e) => {
                tracing::debug!(error = %e, "undecodable stream message");
                continue;
            }
        };
        let done = Instant::now();
        if let Some(intended) = lock(&pending).remove(&seq) {
            in_flight.fetch_sub(1, Ordering::Relaxed);
            run.rec.record(intended, done, outcome);
        }
    }
    let now = Instant::now();
    let lost: Vec<Instant> = lock(&pending).drain().map(|(_, t)| t).collect();
    in_flight.fetch_sub(lost.len(), Ordering::Relaxed);
    for intended in lost {
        run.rec
            .record(intended, now, Outcome::Error("ws closed".into()));
    }
}

/// Sequence number of request `i` (sequences start at 1).
fn sequence(i: u64) -> u64 {
    i + 1
}

/// One connection's closed loop: send, wait for this frame's answer, repeat.
async fn closed_loop(mut ws: Socket, run: Arc<Run>) {
    // As over HTTP: nothing goes before the run's start.
    tokio::time::sleep_until(run.plan.t0).await;
    loop {
        let sent = Instant::now();
        if run.plan.admit(sent).is_none() {
            break;
        }
        let seq = sequence(run.next.fetch_add(1, Ordering::Relaxed));
        if ws.send(frame(seq, &run.frames)).await.is_err() {
            run.rec
                .record(sent, Instant::now(), Outcome::Error("ws closed".into()));
            break;
        }
        let outcome = match tokio::time::timeout(run.timeout, answer_for(&mut ws, seq)).await {
            Ok(Some(outcome)) => outcome,
            Ok(None) => Outcome::Error("ws closed".into()),
            Err(_) => Outcome::Error("timeout".into()),
        };
        let closed = outcome == Outcome::Error("ws closed".into());
        run.rec.record(sent, Instant::now(), outcome);
        if closed {
            return;
        }
    }
    let _ = ws.close(None).await;
}

/// Reads until the answer for `seq` (answers for earlier, timed-out frames are skipped);
/// `None` if the stream ends.
async fn answer_for(ws: &mut Socket, seq: u64) -> Option<Outcome> {
    while let Some(msg) = ws.next().await {
        let Message::Binary(b) = msg.ok()? else {
            continue;
        };
        match Answer::decode(&b).map(|a| a.outcome()) {
            Ok(Some((s, outcome))) if s == seq => return Some(outcome),
            Ok(_) => {}
            Err(e) => return Some(Outcome::Error(format!("ws undecodable: {e}"))),
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn server(msg: pb::server_message::Msg) -> Vec<u8> {
        pb::ServerMessage { msg: Some(msg) }.encode_to_vec()
    }

    #[test]
    fn server_messages_become_outcomes_by_sequence() {
        use pb::server_message::Msg;
        let ok = server(Msg::Result(pb::Result {
            sequence: 7,
            ..pb::Result::default()
        }));
        assert_eq!(
            Answer::decode(&ok).map(|a| a.outcome()),
            Ok(Some((7, Outcome::Ok)))
        );
        let dropped = server(Msg::Dropped(pb::Dropped {
            sequence: 8,
            dropped_total: 1,
        }));
        assert_eq!(
            Answer::decode(&dropped).map(|a| a.outcome()),
            Ok(Some((8, Outcome::Dropped)))
        );
        let refused = server(Msg::Error(pb::Error {
            sequence: Some(9),
            code: "overloaded".into(),
            message: String::new(),
        }));
        assert_eq!(
            Answer::decode(&refused).map(|a| a.outcome()),
            Ok(Some((9, Outcome::Refused("overloaded".into()))))
        );
        let bad = server(Msg::Error(pb::Error {
            sequence: Some(10),
            code: "bad_image".into(),
            message: String::new(),
        }));
        assert_eq!(
            Answer::decode(&bad).map(|a| a.outcome()),
            Ok(Some((10, Outcome::Error("ws bad_image".into()))))
        );
        let ready = server(Msg::Ready(pb::Ready::default()));
        assert_eq!(Answer::decode(&ready), Ok(Answer::Ready));
        assert!(Answer::decode(b"\xff\xff").is_err());
    }
}
