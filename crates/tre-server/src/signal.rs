//! Serving as a process does: bind, say where, warn about an open address without a key, and
//! stop on SIGTERM or Ctrl-C.

use std::net::SocketAddr;

use crate::{serve, ServeConfig, ServeError};

/// Binds `cfg.addr`, calls `listening` with the bound address (`tre serve` prints it), and
/// serves until SIGTERM or Ctrl-C ([`shutdown_signal`]). Warns when the address is beyond
/// loopback and no API key is set.
pub async fn serve_until_signal(
    cfg: ServeConfig,
    listening: impl FnOnce(SocketAddr),
) -> Result<(), ServeError> {
    let listener = tokio::net::TcpListener::bind(cfg.addr).await?;
    let addr = listener.local_addr()?;
    listening(addr);
    tracing::info!(
        %addr,
        workers = cfg.workers,
        queue = cfg.queue,
        normals = ?cfg.defaults.normals,
        dsac_hypotheses = cfg.defaults.dsac_hypotheses,
        "listening; loading models"
    );
    if !addr.ip().is_loopback() && cfg.api_key.is_none() {
        tracing::warn!(
            %addr,
            "listening beyond loopback without an API key: anyone who can reach this address may use the service; set --api-key or TRE_API_KEY (see docs/security.md)"
        );
    }
    serve(cfg, listener, shutdown_signal()).await?;
    tracing::info!("stopped");
    Ok(())
}

/// Completes on SIGTERM or Ctrl-C.
pub async fn shutdown_signal() {
    let ctrl_c = async {
        if tokio::signal::ctrl_c().await.is_err() {
            std::future::pending::<()>().await;
        }
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        () = ctrl_c => {},
        () = term => {},
    }
}
