//! The accept loop: every connection is served by hyper's HTTP/1 with upgrades (the WebSocket
//! stream), with two limits on what a client may hold without doing anything:
//!
//! - its request headers must arrive within `--request-timeout-ms` of the server starting to
//!   wait for them, which also ends a kept-alive connection left idle that long. Without it, a
//!   client that sent its headers a byte at a time, or a connection left open with nothing on
//!   it, was kept until the server stopped (a task and a file descriptor each, so enough of
//!   them exhaust the process's descriptors);
//! - its writes are [`StallGuard`]ed (`--stall-timeout-ms`).
//!
//! On the shutdown signal it stops accepting, lets each connection finish the request in
//! flight (hyper's graceful shutdown), and returns once all have closed. Upgraded streams are
//! no longer connections here: the caller waits for them.

use std::future::Future;
use std::time::Duration;

use axum::serve::Listener;
use axum::Router;
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use tokio::net::TcpListener;
use tokio::sync::watch;

use super::stall::StallGuard;

/// What a client may hold without doing anything.
#[derive(Debug, Clone, Copy)]
pub struct ConnectionLimits {
    /// Request headers must arrive within this (an idle kept-alive connection is closed then).
    pub header_read: Duration,
    /// A write without progress for this long fails, which ends the connection.
    pub write_stall: Duration,
}

/// Serves `app` on `listener` until `signal` completes, then stops accepting and waits for the
/// connections to finish their requests in flight and close.
pub async fn serve_connections(
    mut listener: TcpListener,
    app: Router,
    limits: ConnectionLimits,
    signal: impl Future<Output = ()>,
) {
    let (stop_tx, stop_rx) = watch::channel(());
    // Each connection holds a receiver: all dropped means all closed.
    let (open_tx, open_rx) = watch::channel(());
    let mut builder = http1::Builder::new();
    builder
        .timer(TokioTimer::new())
        .header_read_timeout(limits.header_read);
    let mut signal = std::pin::pin!(signal);
    loop {
        // axum's accept for a TCP listener skips connections that failed before they were
        // taken, and logs other errors (such as running out of file descriptors) and retries
        // a second later.
        let (io, _) = tokio::select! {
            accepted = Listener::accept(&mut listener) => accepted,
            () = &mut signal => break,
        };
        let io = TokioIo::new(StallGuard::new(io, limits.write_stall));
        let conn = builder
            .serve_connection(io, TowerToHyperService::new(app.clone()))
            .with_upgrades();
        let mut stop = stop_rx.clone();
        let open = open_rx.clone();
        tokio::spawn(async move {
            let mut conn = std::pin::pin!(conn);
            let mut stopping = false;
            loop {
                tokio::select! {
                    served = conn.as_mut() => {
                        if let Err(e) = served {
                            tracing::debug!(error = %e, "connection ended with an error");
                        }
                        break;
                    }
                    _ = stop.changed(), if !stopping => {
                        stopping = true;
                        conn.as_mut().graceful_shutdown();
                    }
                }
            }
            drop(open);
        });
    }
    drop(listener);
    drop(open_rx);
    let _ = stop_tx.send(());
    open_tx.closed().await;
}
