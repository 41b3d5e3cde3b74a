//! The accept loop: every connection is served by hyper's HTTP/1 with upgrades (the WebSocket
//! stream), with two limits on what a client may hold without doing anything:
//!
//! - its request headers must arrive within `--header-timeout-ms` of the server starting to
//!   wait for them; a client that sent part of them is answered 408 `request_timeout` (and the
//!   refusal logged), a kept-alive connection left idle that long is closed without a word.
//!   Without it, a client that sent its headers a byte at a time, or a connection left open
//!   with nothing on it, was kept until the server stopped (a task and a file descriptor each,
//!   so enough of them exhaust the process's descriptors);
//! - its writes are guarded against a stalled client ([`super::stall`], `--stall-timeout-ms`).
//!
//! Every request carries the connection's [`ReadBytes`], the bytes read from its socket so far,
//! from which a stream judges the pace of its messages ([`super::pace`]).
//!
//! and a limit on how many connections may be open at once (`--max-connections`; a stream
//! counts until its upgrade, then against `--max-streams`). A connection over it gets its
//! request answered with 503 `overloaded` and `Retry-After`, under the same two limits, and is
//! closed (its body read and dropped first, up to `--max-body-bytes`); past as many such
//! refusals at once again, a new connection is closed unanswered, so that a flood cannot take
//! more than twice the limit in file descriptors.
//!
//! On the shutdown signal it stops accepting, lets each connection finish the request in
//! flight (hyper's graceful shutdown), and returns once all have closed. Upgraded streams are
//! no longer connections here: the caller waits for them.

use std::future::Future;
use std::io;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Duration;

use axum::body::{Bytes, HttpBody};
use axum::extract::Request;
use axum::serve::Listener;
use axum::Router;
use http_body_util::BodyExt;
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{watch, OwnedSemaphorePermit, Semaphore};

use super::error::{ApiError, LimitError};
use super::metrics::Metrics;
use super::pace::ReadBytes;
use super::refusals::RefusalLog;
use super::stall::Stall;
use super::watched::{Watch, Watched, WriteOp};

/// What a client may hold without doing anything.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ConnectionLimits {
    /// Request headers must arrive within this (an idle kept-alive connection is closed then).
    pub header_read: Duration,
    /// A write without progress for this long fails, which ends the connection.
    pub write_stall: Duration,
    /// Connections open at once; beyond, requests are answered 503.
    pub max_open: usize,
    /// Body bytes read and dropped before a refusal is answered (`--max-body-bytes`).
    pub drain_bytes: usize,
}

/// The answer to every request on a connection over `--max-connections`: 503 once the body
/// has been read and dropped (up to `--max-body-bytes`, within the request timeout), so that a
/// client that sends everything before reading, like Python's `http.client`, gets the answer
/// rather than a broken pipe.
fn refuse_router(limits: ConnectionLimits) -> Router {
    Router::new().fallback(move |req: Request| async move {
        let drain = async {
            let mut body = req.into_body();
            let declared = usize::try_from(body.size_hint().lower()).unwrap_or(usize::MAX);
            // A body declared larger than the limit is not read: the answer goes at once.
            let mut seen = if declared > limits.drain_bytes {
                declared
            } else {
                0
            };
            while seen <= limits.drain_bytes {
                match body.frame().await {
                    Some(Ok(frame)) => {
                        let n = frame.data_ref().map_or(0, Bytes::len);
                        seen = seen.saturating_add(n);
                    }
                    Some(Err(_)) | None => break,
                }
            }
        };
        let _ = tokio::time::timeout(limits.header_read, drain).await;
        ApiError::from(LimitError::TooManyConnections {
            max_open: limits.max_open,
        })
    })
}

/// Serves `app` on `listener` until `signal` completes, then stops accepting and waits for the
/// connections to finish their requests in flight and close.
pub(crate) async fn serve_connections(
    mut listener: TcpListener,
    app: Router,
    limits: ConnectionLimits,
    (metrics, refusals): (Arc<Metrics>, Arc<RefusalLog>),
    signal: impl Future<Output = ()>,
) {
    let (stop_tx, stop_rx) = watch::channel(());
    // Each connection holds a receiver: all dropped means all closed.
    let (open_tx, open_rx) = watch::channel(());
    let mut builder = http1::Builder::new();
    builder
        .timer(TokioTimer::new())
        .header_read_timeout(limits.header_read);
    let mut refusing = builder.clone();
    refusing.keep_alive(false);
    let refuse = refuse_router(limits);
    let served = Arc::new(Semaphore::new(limits.max_open));
    let refused = Arc::new(Semaphore::new(limits.max_open));
    let mut signal = std::pin::pin!(signal);
    loop {
        // axum's accept for a TCP listener skips connections that failed before they were
        // taken, and logs other errors (such as running out of file descriptors) and retries
        // a second later.
        let (io, peer) = tokio::select! {
            accepted = Listener::accept(&mut listener) => accepted,
            () = &mut signal => break,
        };
        let (place, builder, app) = match served.clone().try_acquire_owned() {
            Ok(place) => (Place::served(place, &metrics), &builder, app.clone()),
            Err(_) => {
                let Some(place) = refusal_place(&refused, &metrics, &refusals, peer) else {
                    continue;
                };
                (Place::refused(place), &refusing, refuse.clone())
            }
        };
        let conn = Connection {
            _place: place,
            peer,
            limits,
            refusals: refusals.clone(),
            _open: open_rx.clone(),
        };
        conn.spawn(io, (builder, app), stop_rx.clone());
    }
    drop(listener);
    drop(open_rx);
    let _ = stop_tx.send(());
    open_tx.closed().await;
}

/// A place among the connections being refused for a connection over `--max-connections`,
/// with the refusal counted and logged; `None` (the connection is closed unanswered) when as
/// many are being refused already.
fn refusal_place(
    refused: &Arc<Semaphore>,
    metrics: &Metrics,
    refusals: &RefusalLog,
    peer: SocketAddr,
) -> Option<OwnedSemaphorePermit> {
    metrics.connection_refused();
    let Ok(place) = refused.clone().try_acquire_owned() else {
        let why = "closed unanswered: --max-connections open and as many being refused";
        refusals.refused("connection", &peer.to_string(), "overloaded", why);
        return None;
    };
    let why = "answered 503: --max-connections open";
    refusals.refused("connection", &peer.to_string(), "overloaded", why);
    Some(place)
}

/// An accepted connection and what its task holds until it closes: its place, and a receiver
/// of the count of open connections.
struct Connection {
    /// Held until the connection closes: its place within its limit.
    _place: Place,
    peer: SocketAddr,
    limits: ConnectionLimits,
    refusals: Arc<RefusalLog>,
    /// Held until the connection closes: counts it open.
    _open: watch::Receiver<()>,
}

impl Connection {
    /// Serves the connection on its own task with `builder` and `app` until it closes, or once
    /// `stop` has changed and the request in flight is answered.
    fn spawn(
        self,
        io: TcpStream,
        (builder, app): (&http1::Builder, Router),
        mut stop: watch::Receiver<()>,
    ) {
        let peer = self.peer;
        let (io, spare) = match spare_handle(io) {
            Ok(both) => both,
            Err(e) => {
                tracing::warn!(%peer, error = %e, "connection dropped: its socket could not be set up");
                return;
            }
        };
        let head = Arc::new(AtomicBool::new(false));
        let read = ReadBytes::default();
        let io = Watched::new(
            Stall::guard(io, self.limits.write_stall),
            HeadWatch {
                head_started: head.clone(),
                read: read.clone(),
            },
        );
        let app = WithReadBytes { app, read };
        let conn = builder
            .serve_connection(TokioIo::new(io), TowerToHyperService::new(app))
            .with_upgrades();
        tokio::spawn(async move {
            let mut conn = std::pin::pin!(conn);
            let mut stopping = false;
            loop {
                tokio::select! {
                    served = conn.as_mut() => {
                        if let Err(e) = served {
                            self.ended_with(&e, head.load(Ordering::Relaxed), spare.as_ref());
                        }
                        break;
                    }
                    _ = stop.changed(), if !stopping => {
                        stopping = true;
                        conn.as_mut().graceful_shutdown();
                    }
                }
            }
            // Frees the connection's place and counts it closed.
            drop(self);
        });
    }

    /// A connection that ended with `e`: a header timeout once a request head had started
    /// (`head_started`) is answered 408 `request_timeout` and logged as a refusal; anything
    /// else is logged at debug level.
    fn ended_with(
        &self,
        e: &hyper::Error,
        head_started: bool,
        spare: Option<&std::net::TcpStream>,
    ) {
        if e.is_timeout() && head_started {
            let why = format!(
                "the request headers did not arrive within {} ms (--header-timeout-ms)",
                self.limits.header_read.as_millis()
            );
            let peer = self.peer.to_string();
            self.refusals
                .refused("connection", &peer, "request_timeout", &why);
            answer_408(spare, &why);
        } else {
            tracing::debug!(error = %e, "connection ended with an error");
        }
    }
}

/// A second handle on the connection's socket, through which a 408 can still be written
/// after hyper has given up the connection on its header timeout.
fn spare_handle(io: TcpStream) -> io::Result<(TcpStream, Option<std::net::TcpStream>)> {
    let std = io.into_std()?;
    let spare = std.try_clone().ok();
    Ok((TcpStream::from_std(std)?, spare))
}

/// Writes a 408 `request_timeout` and closes, best effort: the socket is non-blocking and the
/// answer small, so it goes at once into the empty send buffer or not at all.
fn answer_408(spare: Option<&std::net::TcpStream>, why: &str) {
    use std::io::Write;
    let Some(mut socket) = spare else { return };
    let body =
        serde_json::json!({"error": {"code": "request_timeout", "message": why}}).to_string();
    let answer = format!(
        "HTTP/1.1 408 Request Timeout\r\ncontent-type: application/json\r\ncontent-length: {}\r\nconnection: close\r\n\r\n{body}",
        body.len()
    );
    let _ = socket.write_all(answer.as_bytes());
    let _ = socket.shutdown(std::net::Shutdown::Write);
}

/// The router with the connection's [`ReadBytes`] put into every request's extensions.
#[derive(Clone)]
struct WithReadBytes {
    app: Router,
    read: ReadBytes,
}

impl<B> tower_service::Service<hyper::Request<B>> for WithReadBytes
where
    Router: tower_service::Service<hyper::Request<B>>,
{
    type Response = <Router as tower_service::Service<hyper::Request<B>>>::Response;
    type Error = <Router as tower_service::Service<hyper::Request<B>>>::Error;
    type Future = <Router as tower_service::Service<hyper::Request<B>>>::Future;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), Self::Error>> {
        tower_service::Service::<hyper::Request<B>>::poll_ready(&mut self.app, cx)
    }

    fn call(&mut self, mut req: hyper::Request<B>) -> Self::Future {
        req.extensions_mut().insert(self.read.clone());
        self.app.call(req)
    }
}

/// Notes whether bytes of a request head have arrived since the last answer was written, so
/// that a header timeout can be told from an idle kept-alive connection (HTTP/1 without
/// pipelining: what is read after an answer is the next request's head), and counts the bytes
/// read.
struct HeadWatch {
    head_started: Arc<AtomicBool>,
    read: ReadBytes,
}

impl Watch for HeadWatch {
    fn read(&mut self, n: usize) {
        self.head_started.store(true, Ordering::Relaxed);
        self.read.add(n);
    }

    fn wrote<R>(
        &mut self,
        _cx: &mut Context<'_>,
        op: WriteOp,
        poll: Poll<io::Result<R>>,
    ) -> Poll<io::Result<R>> {
        if op == WriteOp::Write && matches!(poll, Poll::Ready(Ok(_))) {
            self.head_started.store(false, Ordering::Relaxed);
        }
        poll
    }
}

/// A connection's place within `--max-connections` or among those being refused; a served
/// one is counted open in the metrics until it is dropped.
struct Place {
    _permit: OwnedSemaphorePermit,
    served: Option<Arc<Metrics>>,
}

impl Place {
    fn served(permit: OwnedSemaphorePermit, metrics: &Arc<Metrics>) -> Self {
        metrics.connection_open(true);
        Self {
            _permit: permit,
            served: Some(metrics.clone()),
        }
    }

    fn refused(permit: OwnedSemaphorePermit) -> Self {
        Self {
            _permit: permit,
            served: None,
        }
    }
}

impl Drop for Place {
    fn drop(&mut self) {
        if let Some(metrics) = &self.served {
            metrics.connection_open(false);
        }
    }
}
