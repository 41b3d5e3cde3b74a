//! `GET /v1/stream`: the WebSocket stream. Latest frame wins: each connection has at most one
//! frame running and one waiting; a newer frame replaces the waiting one, which is answered
//! with `Dropped`. Bad messages get an `Error` and the stream goes on. The server pings idle
//! clients and drops one silent for `--ws-idle-timeout-ms` (one that stops reading is dropped
//! by [`super::stall`]), and closes cleanly (1001) on shutdown, after the frame in flight.
//!
//! A stream takes its `--max-streams` place with its first whole message, not at the upgrade:
//! a client that opens streams and trickles into them holds no place that working clients
//! need (streams waiting for their first message are bounded by `--max-connections`). Every
//! message must keep `--min-body-rate` while it arrives ([`super::pace`]), else the stream is
//! closed (1008). Both refusals are logged.

use std::sync::Arc;
use std::time::{Duration, Instant};

use axum::extract::ws::rejection::WebSocketUpgradeRejection;
use axum::extract::ws::{CloseFrame, Message, WebSocket, WebSocketUpgrade};
use axum::extract::State;
use axum::response::{IntoResponse, Response};
use axum::Extension;
use futures_util::SinkExt;
use tokio::sync::{oneshot, OwnedSemaphorePermit};
use tokio::time::MissedTickBehavior;

use super::access::RequestId;
use super::error::{ApiError, LimitError, ServiceError, StreamError};
use super::map::{MapJob, SessionMap, SharedMap};
use super::pace::{MessagePace, ReadBytes, PACE_WINDOW};
use super::proto::{self, Incoming, StreamFrame, StreamSettings};
use super::workers::JobResult;
use super::{AppState, OVERSIZE_READ_FACTOR};
use tre_proto::ErrorCode;

/// Pings per idle timeout: a silent client is found at most a quarter of it late.
const PINGS_PER_IDLE_TIMEOUT: u32 = 4;
/// How long a stream closed by the server waits for the client's close in reply.
const CLOSE_WAIT: Duration = Duration::from_secs(2);

/// Upgrades the connection, unless `--max-streams` are open already or `--max-connections`
/// streams wait for their first message (429 at once).
#[utoipa::path(
    get,
    path = "/v1/stream",
    summary = "WebSocket stream of frames and results (protobuf roughness.v1.ClientMessage / \
        ServerMessage, binary messages; latest frame wins)",
    responses(
        (status = 101, description = "Switching protocols"),
        (status = 400, response = super::openapi::ErrorResponse),
        (status = 401, response = super::openapi::ErrorResponse),
        (status = 403, response = super::openapi::ErrorResponse),
        (status = 429, response = super::openapi::ErrorResponse),
        (status = 503, response = super::openapi::ErrorResponse),
    ),
)]
pub(crate) async fn stream(
    State(app): State<Arc<AppState>>,
    id: Option<Extension<RequestId>>,
    read: Option<Extension<ReadBytes>>,
    ws: Result<WebSocketUpgrade, WebSocketUpgradeRejection>,
) -> Response {
    let id = id.map_or_else(|| "-".to_owned(), |Extension(RequestId(id))| id);
    let ws = match ws {
        Ok(ws) => ws,
        Err(e) => return ApiError::from(StreamError::NotAWebSocket(e)).into_response(),
    };
    let waiting = if app.streams.available_permits() == 0 {
        None
    } else {
        app.waiting_streams.clone().try_acquire_owned().ok()
    };
    let Some(waiting) = waiting else {
        let why = if app.streams.available_permits() == 0 {
            streams_full(&app)
        } else {
            LimitError::StreamsWaiting {
                max_connections: app.cfg.max_connections,
            }
        };
        return too_many(&app, &id, why).into_response();
    };
    // Frames over the message limit but within this are answered with an error and the stream
    // goes on; larger ones close the connection (1009).
    let hard = app
        .cfg
        .ws_max_message_bytes
        .saturating_mul(OVERSIZE_READ_FACTOR);
    let read = read.map(|Extension(read)| read);
    ws.max_message_size(hard)
        .max_frame_size(hard)
        .on_upgrade(move |socket| async move {
            app.metrics.stream_open(true);
            Connection::new(app.clone(), socket, id, read, waiting)
                .run()
                .await;
            app.metrics.stream_open(false);
        })
}

/// Why a stream is refused when every `--max-streams` place is held.
fn streams_full(app: &AppState) -> LimitError {
    LimitError::StreamsFull {
        max_streams: app.cfg.max_streams,
    }
}

/// The 429 of a stream over a limit (`why`), counted and logged.
fn too_many(app: &AppState, id: &str, why: LimitError) -> ApiError {
    let e = ApiError::from(why);
    app.metrics.request("stream", e.code.as_str(), None);
    app.refusals
        .refused("stream", id, e.code.as_str(), &e.message);
    e
}

/// Whether a read failed because the message was over the hard size limit.
fn is_too_big(e: axum::Error) -> bool {
    use tokio_tungstenite::tungstenite::Error as WsError;
    e.into_inner()
        .downcast_ref::<WsError>()
        .is_some_and(|e| matches!(e, WsError::Capacity(_)))
}

/// A frame being run by a worker.
struct InFlight {
    frame: StreamFrame,
    arrived: Instant,
    rx: oneshot::Receiver<(JobResult, Duration)>,
}

/// One stream's state.
struct Connection {
    app: Arc<AppState>,
    socket: WebSocket,
    settings: Option<StreamSettings>,
    in_flight: Option<InFlight>,
    waiting: Option<(StreamFrame, Instant)>,
    dropped_total: u64,
    last_heard: Instant,
    /// The upgrade request's id, logged with the stream's refusals.
    id: String,
    /// Its place: among the streams waiting for their first message, then within
    /// `--max-streams`.
    place: Place,
    /// The pace its messages keep; `None` where the connection's reads are not counted.
    pace: Option<MessagePace>,
    /// Its grid map, if the Hello asked for one, and when an update last went out.
    map: Option<(SharedMap, Option<Instant>)>,
}

/// The permit a stream holds.
enum Place {
    /// Among the streams waiting for their first whole message (`--max-connections`).
    Waiting { _permit: OwnedSemaphorePermit },
    /// Within `--max-streams`, from its first whole message on.
    Held { _permit: OwnedSemaphorePermit },
}

/// What woke the connection up.
enum Event {
    Message(Option<Result<Message, axum::Error>>),
    Done(Box<(JobResult, Duration)>),
    WorkerGone,
    Ping,
    Pace,
    Shutdown,
}

impl Connection {
    fn new(
        app: Arc<AppState>,
        socket: WebSocket,
        id: String,
        read: Option<ReadBytes>,
        waiting_place: OwnedSemaphorePermit,
    ) -> Self {
        let min_rate = app.cfg.min_body_rate;
        let now = tokio::time::Instant::now();
        Self {
            place: Place::Waiting {
                _permit: waiting_place,
            },
            pace: read.map(|read| MessagePace::new(read, min_rate, now)),
            app,
            socket,
            settings: None,
            in_flight: None,
            waiting: None,
            dropped_total: 0,
            last_heard: Instant::now(),
            id,
            map: None,
        }
    }

    async fn run(mut self) {
        let every = self.app.cfg.ws_idle_timeout / PINGS_PER_IDLE_TIMEOUT;
        let mut ping = tokio::time::interval(every.max(Duration::from_millis(1)));
        ping.tick().await;
        let mut pace = tokio::time::interval(PACE_WINDOW);
        pace.set_missed_tick_behavior(MissedTickBehavior::Delay);
        pace.tick().await;
        let paced = self.pace.as_ref().is_some_and(MessagePace::enabled);
        let mut shutdown = self.app.shutdown.clone();
        loop {
            let event = tokio::select! {
                m = self.socket.recv() => Event::Message(m),
                r = async { (&mut self.in_flight.as_mut().expect("guarded by the branch condition; this is a bug").rx).await }, if self.in_flight.is_some() => {
                    r.map_or(Event::WorkerGone, |d| Event::Done(Box::new(d)))
                }
                _ = ping.tick() => Event::Ping,
                _ = pace.tick(), if paced => Event::Pace,
                _ = shutdown.changed() => Event::Shutdown,
            };
            let keep_going = match event {
                Event::Message(Some(Ok(msg))) => {
                    self.last_heard = Instant::now();
                    self.account(&msg);
                    self.take_place(&msg).await && self.on_message(msg).await
                }
                Event::Message(Some(Err(e))) => {
                    tracing::debug!(error = %e, "stream read failed; closing");
                    if is_too_big(e) {
                        let why = format!(
                            "a message over {OVERSIZE_READ_FACTOR} × --ws-max-message-bytes; closed with 1009"
                        );
                        self.app
                            .refusals
                            .refused("stream", &self.id, "ws_close_1009", &why);
                        self.close(1009, "message too big").await;
                    }
                    false
                }
                Event::Message(None) => false,
                Event::Done(done) => self.answer(*done).await && self.start_waiting().await,
                Event::WorkerGone => {
                    let frame = self.in_flight.take().map(|f| f.frame.sequence);
                    let e = ApiError::from(ServiceError::WorkerStopped);
                    self.send(proto::error(frame, &e)).await && self.start_waiting().await
                }
                Event::Ping => self.on_ping().await,
                Event::Pace => self.on_pace().await,
                Event::Shutdown => {
                    self.shut_down().await;
                    false
                }
            };
            if !keep_going {
                break;
            }
        }
    }

    async fn send(&mut self, bytes: Vec<u8>) -> bool {
        self.send_message(Message::Binary(bytes.into())).await
    }

    /// Sends `msg`; false when the connection is over (a client that stops reading makes the
    /// send fail after `--stall-timeout-ms`: [`super::stall`]).
    async fn send_message(&mut self, msg: Message) -> bool {
        self.socket.send(msg).await.is_ok()
    }

    async fn close(&mut self, code: u16, reason: &'static str) {
        let frame = CloseFrame {
            code,
            reason: reason.into(),
        };
        let _ = self.send_message(Message::Close(Some(frame))).await;
    }

    /// Tells the pace which of the bytes read a whole message accounts for.
    fn account(&mut self, msg: &Message) {
        let Some(pace) = self.pace.as_mut() else {
            return;
        };
        match msg {
            Message::Ping(p) | Message::Pong(p) => pace.control_frame(p.len()),
            Message::Binary(_) | Message::Text(_) | Message::Close(_) => {
                pace.data_message();
            }
        }
    }

    /// Takes the stream's `--max-streams` place with its first data message; false (after an
    /// error and a 1013 close) when none is free.
    async fn take_place(&mut self, msg: &Message) -> bool {
        if matches!(self.place, Place::Held { .. })
            || !matches!(msg, Message::Binary(_) | Message::Text(_))
        {
            return true;
        }
        if let Ok(place) = self.app.streams.clone().try_acquire_owned() {
            self.place = Place::Held { _permit: place };
            return true;
        }
        let e = too_many(&self.app, &self.id, streams_full(&self.app));
        let _ = self.send(proto::error(None, &e)).await;
        self.close(1013, "try again later").await;
        false
    }

    /// The end of a pace window: a message arriving too slowly closes the stream (1008).
    async fn on_pace(&mut self) -> bool {
        let now = tokio::time::Instant::now();
        let Some(Err(slow)) = self.pace.as_mut().map(|p| p.end_window(now)) else {
            return true;
        };
        let e = ApiError::from(LimitError::from(slow));
        self.app
            .refusals
            .refused("stream", &self.id, "ws_close_1008_slow", &e.message);
        self.app.metrics.request("stream", e.code.as_str(), None);
        let _ = self.send(proto::error(None, &e)).await;
        self.close(1008, "message too slow").await;
        false
    }

    async fn on_ping(&mut self) -> bool {
        if self.last_heard.elapsed() > self.app.cfg.ws_idle_timeout {
            self.close(1001, "idle").await;
            return false;
        }
        self.send_message(Message::Ping(Vec::new().into())).await
    }

    async fn on_message(&mut self, msg: Message) -> bool {
        let bytes = match msg {
            Message::Binary(b) => b,
            Message::Text(_) => {
                return self.refuse(None, StreamError::TextMessage).await;
            }
            Message::Close(_) => {
                // The reply the WebSocket queued on reading the client's close goes out now.
                let _ = SinkExt::flush(&mut self.socket).await;
                return false;
            }
            Message::Ping(_) | Message::Pong(_) => return true,
        };
        let limit = self.app.cfg.ws_max_message_bytes;
        if bytes.len() > limit {
            let e = LimitError::MessageTooLarge {
                bytes: bytes.len(),
                limit,
            };
            return self.refuse(proto::peek_frame_sequence(&bytes), e).await;
        }
        match proto::decode_client(&bytes) {
            Ok(Incoming::Hello(settings)) => {
                self.map = settings.map.map(|m| {
                    let m = m.on(&self.app.cfg.map_params);
                    let shared = Arc::new(std::sync::Mutex::new(SessionMap::new(m)));
                    self.app.maps.insert(&self.id, &shared);
                    (shared, None)
                });
                self.settings = Some(settings);
                let models = self.app.model_names.clone();
                self.send(proto::ready(limit, models, &self.id)).await
            }
            Ok(Incoming::Frame(frame)) => self.on_frame(frame).await,
            Err((seq, e)) => self.refuse(seq, e).await,
        }
    }

    async fn refuse(&mut self, seq: Option<u64>, e: impl Into<ApiError>) -> bool {
        let e = e.into();
        self.app.metrics.request("stream", e.code.as_str(), None);
        if e.code == ErrorCode::Internal {
            tracing::error!(request_id = %self.id, error = %e.message, "stream frame failed");
        } else {
            self.app
                .refusals
                .refused("stream", &self.id, e.code.as_str(), &e.message);
        }
        self.send(proto::error(seq, &e)).await
    }

    async fn on_frame(&mut self, frame: StreamFrame) -> bool {
        if self.settings.is_none() {
            let e = StreamError::FrameBeforeHello;
            return self.refuse(Some(frame.sequence), e).await;
        }
        if self.in_flight.is_none() {
            return self.start(frame, Instant::now()).await;
        }
        if let Some((old, _)) = self.waiting.replace((frame, Instant::now())) {
            self.dropped_total += 1;
            self.app.metrics.dropped();
            return self
                .send(proto::dropped(old.sequence, self.dropped_total))
                .await;
        }
        true
    }

    /// Submits `frame`; a refusal (queue full) is reported for that frame.
    async fn start(&mut self, frame: StreamFrame, arrived: Instant) -> bool {
        let settings = self.settings.clone().unwrap_or_default();
        let mut request = frame.clone().into_request(&settings);
        request.map = self.map.as_ref().map(|(m, _)| MapJob {
            map: m.clone(),
            pose: frame.pose,
            sequence: frame.sequence,
        });
        match self.app.workers.submit(request) {
            Ok(rx) => {
                self.in_flight = Some(InFlight { frame, arrived, rx });
                true
            }
            Err(e) => self.refuse(Some(frame.sequence), e).await,
        }
    }

    async fn start_waiting(&mut self) -> bool {
        match self.waiting.take() {
            Some((frame, arrived)) => self.start(frame, arrived).await,
            None => true,
        }
    }

    /// Sends the answer of the frame in flight.
    async fn answer(&mut self, (result, _queued): (JobResult, Duration)) -> bool {
        let Some(done) = self.in_flight.take() else {
            return true;
        };
        match result {
            Ok(reply) => {
                let latency = done.arrived.elapsed();
                self.app.metrics.request("stream", "ok", Some(latency));
                let msg = proto::result(
                    done.frame.sequence,
                    done.frame.timestamp_us,
                    reply,
                    latency.as_secs_f64() * 1e3,
                    self.dropped_total,
                );
                self.send(msg).await && self.send_map().await
            }
            Err(e) => self.refuse(Some(done.frame.sequence), e).await,
        }
    }

    /// Sends the map when the stream keeps one and its rate allows (`send_hz`; 0: every time).
    async fn send_map(&mut self) -> bool {
        let Some((map, last)) = self.map.as_mut() else {
            return true;
        };
        let update = {
            let m = map
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            let hz = m.settings.send_hz;
            let due = hz <= 0.0 || last.is_none_or(|t| t.elapsed().as_secs_f64() >= 1.0 / hz);
            if !due {
                return true;
            }
            m.update()
        };
        let Some(update) = update else {
            return true;
        };
        *last = Some(Instant::now());
        self.send(proto::map_update(update)).await
    }

    /// On shutdown: takes the messages that have already arrived as usual, answers the frame
    /// in flight and reports the waiting one dropped, closes with 1001, then reads on until the
    /// client's close (at most [`CLOSE_WAIT`]; frames still arriving then go unanswered, as the
    /// client has been told the stream is over). Leaving a message unread would make the
    /// system reset the connection, and the client could lose the answers sent before.
    async fn shut_down(&mut self) {
        while let Ok(Some(Ok(msg))) = tokio::time::timeout(Duration::ZERO, self.socket.recv()).await
        {
            if !self.on_message(msg).await {
                return;
            }
        }
        self.finish_in_flight().await;
        self.close(1001, "server shutting down").await;
        let _ = tokio::time::timeout(CLOSE_WAIT, async {
            while let Some(Ok(msg)) = self.socket.recv().await {
                if matches!(msg, Message::Close(_)) {
                    break;
                }
            }
        })
        .await;
    }

    /// Waits for the frame in flight and sends its result; the waiting one is reported dropped.
    async fn finish_in_flight(&mut self) {
        if let Some(f) = self.in_flight.as_mut() {
            if let Ok(done) = (&mut f.rx).await {
                let _ = self.answer(done).await;
            }
        }
        if let Some((frame, _)) = self.waiting.take() {
            self.dropped_total += 1;
            let _ = self
                .send(proto::dropped(frame.sequence, self.dropped_total))
                .await;
        }
    }
}
