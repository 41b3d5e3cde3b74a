//! The connection task behind a session: it owns the WebSocket, sends the Hello and waits for
//! Ready, writes frames, matches answers to frames by sequence number (send times kept in a
//! bounded map), times frames out, and on a dropped connection reports the frames in flight as
//! lost and reconnects with exponential back-off. One connection attempt is `attempt`'s.

mod attempt;

use std::collections::BTreeMap;
use std::future::Future;
use std::sync::Arc;
use std::time::Instant;

use futures_util::stream::SplitSink;
use futures_util::{SinkExt, StreamExt};
use tokio::sync::{mpsc, oneshot, watch};
use tokio_tungstenite::tungstenite::{self, Message};

use super::clock::Stamp;
use super::config::{ClientConfig, Endpoints};
use super::error::ConfigProblem;
use super::event::{DisconnectReason, ErrorKind, Event, FrameResult, LostReason, ServerInfo};
use super::proto::{self, Incoming, WireResult};
use super::ClientError;
use attempt::{attempt, bearer};

/// The WebSocket of one connection.
type Ws =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

/// A frame on its way from the sender to the socket.
#[derive(Debug)]
pub(crate) struct Outgoing {
    /// Its sequence number.
    pub sequence: u64,
    /// The encoded `ClientMessage`.
    pub bytes: Vec<u8>,
    /// When `send` stamped it (the start of its latency).
    pub sent: Stamp,
}

/// What the sending half sees of the link.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct LinkState {
    /// A connection is up and its Hello accepted.
    pub connected: bool,
    /// Frames that have had their final event.
    pub settled: u64,
    /// The session has ended.
    pub closed: bool,
    /// The server's largest message, bytes (0: not known yet).
    pub max_message_bytes: usize,
}

/// Settings every connection attempt needs.
struct Shared {
    cfg: ClientConfig,
    endpoints: Endpoints,
    hello: Vec<u8>,
    http: Option<reqwest::Client>,
    /// TLS settings of `wss://` and `https://` servers.
    tls: Option<Arc<rustls::ClientConfig>>,
}

/// Why a connection's pump returned.
enum Ended {
    /// The sender is gone and every frame has its answer.
    Finished,
    /// The connection dropped.
    Dropped(DisconnectReason),
}

/// The state of the connection task.
pub(crate) struct Link {
    shared: Arc<Shared>,
    frames: mpsc::Receiver<Outgoing>,
    frames_open: bool,
    events: mpsc::Sender<Event>,
    state: watch::Sender<LinkState>,
    /// Send time of each frame awaiting its answer, by sequence number (so also by age).
    pending: BTreeMap<u64, Stamp>,
    /// With a map asked for: until when the map that follows the last Result is awaited
    /// before the session may finish (`None`: it came, or no map is asked for).
    map_due: Option<Instant>,
}

/// How long the map that follows a Result is awaited at the end of a session.
const MAP_WAIT: std::time::Duration = std::time::Duration::from_secs(3);

impl Link {
    /// A link for the checked `cfg`.
    pub(crate) fn new(
        cfg: ClientConfig,
        endpoints: Endpoints,
        frames: mpsc::Receiver<Outgoing>,
        events: mpsc::Sender<Event>,
        state: watch::Sender<LinkState>,
    ) -> Result<Self, ClientError> {
        let tls = match endpoints.tls {
            true => Some(
                super::tls::client_config(cfg.ca_cert.as_deref()).map_err(|e| {
                    ClientError::BadConfig {
                        field: "ca_cert",
                        reason: ConfigProblem::Tls(Box::new(e)),
                    }
                })?,
            ),
            false => None,
        };
        let http = if cfg.wait_ready {
            // No idle connection is kept between checks: it would hold one of the server's
            // `--max-connections` places for the whole session, and on a server at its limit
            // keep the stream's own connection out.
            let mut headers = reqwest::header::HeaderMap::new();
            if let Some(key) = &cfg.api_key {
                headers.insert(reqwest::header::AUTHORIZATION, bearer(key)?);
            }
            let mut builder = reqwest::Client::builder()
                .default_headers(headers)
                .timeout(cfg.connect_timeout)
                .pool_max_idle_per_host(0);
            if let Some(tls) = &tls {
                builder = builder.use_preconfigured_tls(rustls::ClientConfig::clone(tls));
            }
            let client = builder.build().map_err(|e| ClientError::BadConfig {
                field: "wait_ready",
                reason: ConfigProblem::HttpClient(e),
            })?;
            Some(client)
        } else {
            None
        };
        let hello = proto::hello(&cfg);
        Ok(Self {
            shared: Arc::new(Shared {
                cfg,
                endpoints,
                hello,
                http,
                tls,
            }),
            frames,
            frames_open: true,
            events,
            state,
            pending: BTreeMap::new(),
            map_due: None,
        })
    }

    /// Connects (reporting the outcome on `first`), then serves the connection and every
    /// reconnection until the sender is gone and all frames are answered, or reconnecting
    /// fails for good.
    pub(crate) async fn run(mut self, first: oneshot::Sender<Result<ServerInfo, ClientError>>) {
        let mut ws = match self.connect().await {
            Ok((ws, info, _)) => {
                self.up(&info);
                let _ = first.send(Ok(info));
                ws
            }
            Err(e) => {
                let _ = first.send(Err(e));
                self.close();
                return;
            }
        };
        loop {
            let reason = match self.pump(ws).await {
                Ended::Finished => break,
                Ended::Dropped(reason) => reason,
            };
            let down_since = Instant::now();
            tracing::warn!(%reason, url = %self.shared.endpoints.stream, "stream connection dropped; reconnecting");
            self.state.send_modify(|s| s.connected = false);
            self.emit(Event::Disconnected { reason }).await;
            self.lose_pending(LostReason::Disconnected).await;
            match self.connect().await {
                Ok((next, server, attempts)) => {
                    self.up(&server);
                    let downtime = down_since.elapsed();
                    tracing::info!(
                        attempts,
                        downtime_ms = downtime.as_millis() as u64,
                        "stream reconnected"
                    );
                    self.emit(Event::Reconnected {
                        attempts,
                        downtime,
                        server,
                    })
                    .await;
                    ws = next;
                }
                Err(ClientError::Closed) => break,
                Err(e) => {
                    tracing::error!(error = %e, "stream session ended");
                    self.emit(Event::GaveUp {
                        reason: Arc::new(e),
                    })
                    .await;
                    break;
                }
            }
        }
        self.close();
    }

    /// Connection attempts with back-off until one succeeds, one is refused for good, the
    /// allowance runs out or the sender is gone ([`ClientError::Closed`]).
    async fn connect(&mut self) -> Result<(Ws, ServerInfo, u32), ClientError> {
        let backoff = self.shared.cfg.reconnect;
        let mut failed = 0u32;
        loop {
            match self.while_down(attempt(self.shared.clone())).await? {
                Ok((ws, info)) => return Ok((ws, info, failed + 1)),
                Err(e) if !e.is_retryable() => return Err(e),
                Err(e) => {
                    failed += 1;
                    if backoff.exhausted(failed) {
                        return Err(ClientError::GaveUp {
                            attempts: failed,
                            last: Box::new(e),
                        });
                    }
                    let wait = backoff.delay(failed);
                    tracing::info!(error = %e, attempt = failed, retry_in_ms = wait.as_millis() as u64, "stream connection attempt failed");
                    self.while_down(tokio::time::sleep(wait)).await?;
                }
            }
        }
    }

    /// Runs `fut` while there is no connection: frames sent meanwhile are reported lost at once.
    /// [`ClientError::Closed`] when the sender is gone.
    async fn while_down<T>(&mut self, fut: impl Future<Output = T>) -> Result<T, ClientError> {
        tokio::pin!(fut);
        loop {
            if !self.frames_open {
                return Err(ClientError::Closed);
            }
            tokio::select! {
                out = &mut fut => return Ok(out),
                f = self.frames.recv() => match f {
                    Some(o) => {
                        let lost = Event::Lost { sequence: o.sequence, reason: LostReason::NotConnected };
                        self.settle(lost).await;
                    }
                    None => self.frames_open = false,
                },
            }
        }
    }

    /// Serves one connection until it drops or the session is finished. Reading, writing and
    /// the deadlines run side by side: a frame the server does not take (it is hung, or its
    /// buffers are full) holds up neither the answers, nor the frame timeouts, nor the silence
    /// check that drops the connection. (A write once blocked all three: with a server stopped
    /// mid-stream the client reported nothing and never reconnected.)
    async fn pump(&mut self, ws: Ws) -> Ended {
        let silence = self.shared.cfg.silence_timeout;
        let mut last_heard = Instant::now();
        let (sink, mut stream) = ws.split();
        // The sink when idle; while a frame is being written, the write owns it and hands it
        // back.
        let mut sink = Some(sink);
        let mut writing: Option<Write> = None;
        loop {
            if self.finished(writing.is_some()) {
                if let Some(mut sink) = sink.take() {
                    let _ = sink.close().await;
                }
                return Ended::Finished;
            }
            let expiry = self.wake_at();
            tokio::select! {
                m = stream.next() => {
                    last_heard = Instant::now();
                    if let Some(ended) = self.on_read(m).await {
                        return ended;
                    }
                }
                (idle, written) = async { writing.as_mut().expect("guarded by the branch condition; this is a bug").await }, if writing.is_some() => {
                    writing = None;
                    sink = Some(idle);
                    if let Err(e) = written {
                        return Ended::Dropped(DisconnectReason::Send(Arc::new(e)));
                    }
                }
                f = self.frames.recv(), if self.frames_open && writing.is_none() => match f {
                    Some(o) => {
                        let idle = sink.take().expect("no write in progress; this is a bug");
                        writing = Some(self.start_write(o, idle).await);
                    }
                    None => self.frames_open = false,
                },
                () = sleep_until(expiry), if expiry.is_some() => self.expire().await,
                () = sleep_until(Some(last_heard + silence)) => {
                    return Ended::Dropped(DisconnectReason::Silence(silence));
                }
            }
        }
    }

    /// Handles what the connection read: a server message, or the connection's end (`Some`).
    async fn on_read(&mut self, m: Option<Result<Message, tungstenite::Error>>) -> Option<Ended> {
        match m {
            Some(Ok(Message::Binary(b))) => self.on_message(&b).await,
            Some(Ok(Message::Close(c))) => {
                return Some(Ended::Dropped(DisconnectReason::ServerClosed(c)));
            }
            Some(Ok(_)) => {}
            Some(Err(e)) => return Some(Ended::Dropped(DisconnectReason::Read(Arc::new(e)))),
            None => return Some(Ended::Dropped(DisconnectReason::Ended)),
        }
        None
    }

    /// Tracks frame `o` and starts writing it on the idle `sink`; the write hands the sink back
    /// with its outcome.
    async fn start_write(&mut self, o: Outgoing, mut sink: SplitSink<Ws, Message>) -> Write {
        let msg = self.track(o).await;
        Box::pin(async move {
            let written = sink.send(msg).await;
            (sink, written)
        })
    }

    /// Remembers the frame's send time (forgetting the oldest beyond the bound); returns the
    /// message to write.
    async fn track(&mut self, o: Outgoing) -> Message {
        if self.pending.len() >= self.shared.cfg.max_pending {
            if let Some((sequence, _)) = self.pending.pop_first() {
                let lost = Event::Lost {
                    sequence,
                    reason: LostReason::Evicted,
                };
                self.settle(lost).await;
            }
        }
        self.pending.insert(o.sequence, o.sent);
        Message::Binary(o.bytes.into())
    }

    /// Handles one server message.
    async fn on_message(&mut self, bytes: &[u8]) {
        let incoming = match proto::decode_server(bytes) {
            Ok(m) => m,
            Err(e) => {
                let code = ErrorKind::BadMessage;
                let message = e.to_string();
                return self
                    .emit(Event::Error {
                        sequence: None,
                        code,
                        message,
                    })
                    .await;
            }
        };
        match incoming {
            Incoming::Result(wire) => self.on_result(wire).await,
            Incoming::Event(event @ Event::Map(_)) => {
                self.map_due = None;
                self.emit(event).await;
            }
            Incoming::Event(event) => {
                // A Dropped or Error about a frame still awaited settles it; an Error about
                // none (or one already settled) is reported, a late Dropped is not.
                match event.settles().and_then(|s| self.pending.remove(&s)) {
                    Some(_) => self.settle(event).await,
                    None if matches!(event, Event::Error { .. }) => self.emit(event).await,
                    None => {}
                }
            }
            Incoming::Ready(_) => tracing::debug!("unexpected Ready ignored"),
        }
    }

    /// Settles the frame of a Result with its decoded map (or a `bad_result` error); a Result
    /// for a frame no longer awaited is ignored.
    async fn on_result(&mut self, wire: WireResult) {
        let sequence = wire.sequence();
        let Some(sent) = self.pending.remove(&sequence) else {
            tracing::debug!(
                sequence,
                "result for a frame no longer awaited (timed out or evicted)"
            );
            return;
        };
        if self.shared.cfg.map.is_some() {
            self.map_due = Some(Instant::now() + MAP_WAIT);
        }
        let event = match FrameResult::try_from((wire, sent)) {
            Ok(r) => Event::Result(Box::new(r)),
            Err(e) => Event::Error {
                sequence: Some(sequence),
                code: ErrorKind::BadResult,
                message: e.to_string(),
            },
        };
        self.settle(event).await;
    }

    /// Whether the session is done: the sender gone, no frame awaiting its answer or being
    /// written, and the map that follows the last Result in (or awaited long enough).
    fn finished(&self, writing: bool) -> bool {
        !self.frames_open
            && self.pending.is_empty()
            && !writing
            && self.map_due.is_none_or(|t| t <= Instant::now())
    }

    /// When the pump must look again: the oldest frame's timeout, or the end of the wait for
    /// the last map.
    fn wake_at(&self) -> Option<Instant> {
        match (self.next_expiry(), self.map_due) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// When the oldest frame awaiting an answer times out.
    fn next_expiry(&self) -> Option<Instant> {
        let (_, sent) = self.pending.first_key_value()?;
        Some(sent.at + self.shared.cfg.frame_timeout)
    }

    /// Reports every frame past its timeout lost.
    async fn expire(&mut self) {
        let now = Instant::now();
        while self.next_expiry().is_some_and(|t| t <= now) {
            if let Some((sequence, _)) = self.pending.pop_first() {
                let lost = Event::Lost {
                    sequence,
                    reason: LostReason::TimedOut,
                };
                self.settle(lost).await;
            }
        }
    }

    /// Reports every frame awaiting an answer lost.
    async fn lose_pending(&mut self, reason: LostReason) {
        while let Some((sequence, _)) = self.pending.pop_first() {
            self.settle(Event::Lost { sequence, reason }).await;
        }
    }

    /// Emits a frame's final event and counts it settled.
    async fn settle(&mut self, event: Event) {
        self.state.send_modify(|s| s.settled += 1);
        self.emit(event).await;
    }

    /// Hands an event to the application (which may have stopped listening).
    async fn emit(&mut self, event: Event) {
        let _ = self.events.send(event).await;
    }

    fn up(&mut self, info: &ServerInfo) {
        self.state.send_modify(|s| {
            s.connected = true;
            s.max_message_bytes = info.max_message_bytes;
        });
    }

    fn close(&mut self) {
        self.state.send_modify(|s| {
            s.connected = false;
            s.closed = true;
        });
    }
}

/// A frame being written: the write owns the sink and hands it back with the outcome.
type Write = std::pin::Pin<
    Box<dyn Future<Output = (SplitSink<Ws, Message>, Result<(), tungstenite::Error>)> + Send>,
>;

/// Sleeps until `t` (forever for `None`).
async fn sleep_until(t: Option<Instant>) {
    match t {
        Some(t) => tokio::time::sleep_until(tokio::time::Instant::from_std(t)).await,
        None => std::future::pending().await,
    }
}
