//! The inference service: axum's routing over hyper's HTTP/1 on tokio (`connections.rs`) for HTTP
//! and the WebSocket stream, with the pipeline on named worker threads (`workers.rs`) fed by a
//! bounded queue. One mapping turns every error into a status and a code (`error.rs`); limits
//! answer overload at once (429/503 with `Retry-After`) instead of queueing without bound.
//!
//! ```no_run
//! # async fn demo() -> Result<(), Box<dyn std::error::Error>> {
//! let cfg = tre_server::ServeConfig::default();
//! let listener = tokio::net::TcpListener::bind(cfg.addr).await?;
//! tre_server::serve(cfg, listener, std::future::pending()).await?;
//! # Ok(())
//! # }
//! ```

mod access;
mod config;
mod connections;
mod error;
#[cfg(any(test, feature = "fuzzing"))]
pub mod fuzzing;
mod http;
mod map;
mod metrics;
mod openapi;
pub mod options;
mod pace;
mod proto;
mod query;
mod refusals;
pub mod request;
mod signal;
mod stall;
mod stream;
mod watched;
mod workers;

use std::future::Future;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use axum::extract::DefaultBodyLimit;
use axum::Router;
use tokio::sync::{watch, Semaphore};
use utoipa::OpenApi;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

pub use config::{ConfigError, MIN_API_KEY_CHARS};
pub use error::RequestError;
pub use signal::{serve_until_signal, shutdown_signal};

use metrics::Metrics;
use refusals::RefusalLog;
use request::{DecodeLimits, FrameDefaults};
use tre_model::{Manifest, SessionConfig};
use tre_pipeline::check_dsac_hypotheses;
use workers::{PoolConfig, Workers};

/// How far past its limit an oversize input (an HTTP body, a WebSocket message) is still read
/// and answered with a `too_large` error: up to this many times the limit. Reading it through
/// lets a client that sends everything before reading (Python's `http.client`, for one) see the
/// error, and keeps a stream open; beyond it the connection closes.
pub(crate) const OVERSIZE_READ_FACTOR: usize = 4;

/// Settings of the service; every field has a `tre serve` option.
#[derive(Debug, Clone)]
pub struct ServeConfig {
    /// Address to listen on.
    pub addr: SocketAddr,
    /// Folder with `manifest.json` and the models.
    pub models: PathBuf,
    /// Inference worker threads.
    pub workers: usize,
    /// ONNX Runtime settings of each worker.
    pub session: SessionConfig,
    /// Frames that may wait for a worker.
    pub queue: usize,
    /// Largest request body, bytes.
    pub max_body_bytes: usize,
    /// Largest image, pixels (checked from the header before decoding).
    pub max_pixels: usize,
    /// Longest image side, pixels (checked from the header before decoding).
    pub max_side: usize,
    /// Largest ratio of an image's longer side to its shorter one (from the header).
    pub max_aspect: usize,
    /// Time a client has to send a request's headers (408 when some came); an idle
    /// kept-alive connection is closed after it.
    pub header_timeout: Duration,
    /// Time a client has to send a request's body once its headers have arrived (408).
    pub body_timeout: Duration,
    /// Least average rate of a request's body, bytes a second over each
    /// `BODY_RATE_WINDOW` (`http.rs`) (408 below it); 0: none.
    pub min_body_rate: u64,
    /// Bearer key wanted on every route but `/healthz` and `/readyz`; `None`: no key.
    pub api_key: Option<String>,
    /// Browser origins allowed to call the service and open the stream (`*`: any); a page
    /// the server itself served is always allowed.
    pub allow_origins: Vec<String>,
    /// Requests handled at once; more get 429.
    pub max_concurrent: usize,
    /// Time an HTTP request may take once its body has arrived: queue wait and run.
    pub request_timeout: Duration,
    /// Largest WebSocket message, bytes.
    pub ws_max_message_bytes: usize,
    /// WebSocket streams open at once; more get 429.
    pub max_streams: usize,
    /// A stream whose client sends nothing (no message, no pong) for this long is closed.
    pub ws_idle_timeout: Duration,
    /// A connection (HTTP or stream) whose client takes nothing of an answer for this long is
    /// closed (`stall.rs`).
    pub stall_timeout: Duration,
    /// HTTP connections open at once (a stream until its upgrade); more are answered 503 and
    /// closed (`connections.rs`).
    pub max_connections: usize,
    /// Time in-flight work may take to finish after SIGTERM.
    pub shutdown_grace: Duration,
    /// What frames get for the settings they do not choose: initial normals (DSAC, the paper's
    /// method) and DSAC hypotheses per pixel (12, as trained).
    pub defaults: FrameDefaults,
}

impl Default for ServeConfig {
    fn default() -> Self {
        let cores = std::thread::available_parallelism().map_or(1, usize::from);
        Self {
            addr: SocketAddr::from(([127, 0, 0, 1], 8080)),
            models: PathBuf::from("models"),
            workers: cores,
            session: SessionConfig {
                intra_threads: 1,
                ..SessionConfig::default()
            },
            queue: 2 * cores,
            max_body_bytes: 32 << 20,
            max_pixels: 4 << 20,
            max_side: 8192,
            max_aspect: 8,
            header_timeout: Duration::from_secs(10),
            body_timeout: Duration::from_secs(20),
            min_body_rate: 1024,
            api_key: None,
            allow_origins: Vec::new(),
            max_concurrent: 64,
            request_timeout: Duration::from_secs(30),
            ws_max_message_bytes: 16 << 20,
            max_streams: 64,
            ws_idle_timeout: Duration::from_secs(60),
            stall_timeout: Duration::from_secs(30),
            max_connections: 1024,
            shutdown_grace: Duration::from_secs(30),
            defaults: FrameDefaults::default(),
        }
    }
}

/// Shared state of the handlers.
#[derive(Debug)]
pub(crate) struct AppState {
    /// The settings.
    pub cfg: ServeConfig,
    /// The inference workers.
    pub workers: Workers,
    /// The metrics.
    pub metrics: Arc<Metrics>,
    /// Permits for concurrent HTTP requests.
    pub concurrency: Arc<Semaphore>,
    /// Permits for open streams (`--max-streams`), taken with a stream's first message.
    pub streams: Arc<Semaphore>,
    /// Permits for streams waiting for their first message (`--max-connections`).
    pub waiting_streams: Arc<Semaphore>,
    /// The manifest, as served by `/v1/models`.
    pub manifest_json: String,
    /// Model names, for the stream's Ready.
    pub model_names: Vec<String>,
    /// Becomes `true` when shutdown begins.
    pub shutdown: watch::Receiver<bool>,
    /// The rate-limited log of refusals.
    pub refusals: Arc<RefusalLog>,
    /// The grid maps of the open streams that keep one.
    pub maps: map::MapRegistry,
}

impl ServeConfig {
    /// The decoding limits of these settings.
    pub fn decode_limits(&self) -> DecodeLimits {
        DecodeLimits {
            max_pixels: self.max_pixels,
            max_side: self.max_side,
            max_aspect: self.max_aspect,
        }
    }
}

/// Errors that keep the service from starting or serving.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// A setting out of its range (the frames' default DSAC hypotheses), or a calibration
    /// file beside the models that does not read.
    #[error(transparent)]
    Config(tre_pipeline::PipelineError),
    /// The manifest is missing or malformed.
    #[error(transparent)]
    Manifest(#[from] tre_model::ModelError),
    /// A setting the service cannot run with ([`ServeConfig::validate`]).
    #[error(transparent)]
    Settings(#[from] config::ConfigError),
    /// A worker could not load or warm up the models.
    #[error(transparent)]
    Workers(Arc<workers::WorkerError>),
    /// Socket or thread failure.
    #[error(transparent)]
    Io(#[from] std::io::Error),
}

/// Every route: each handler with the method and path of its `#[utoipa::path]`. The router
/// ([`router`]) and the OpenAPI document ([`openapi::document`]) are both made from this list.
pub(crate) fn routes() -> OpenApiRouter<Arc<AppState>> {
    OpenApiRouter::with_openapi(openapi::ApiDoc::openapi())
        .routes(routes!(http::demo))
        .routes(routes!(http::healthz))
        .routes(routes!(http::readyz))
        .routes(routes!(http::metrics))
        .routes(routes!(http::openapi))
        .routes(routes!(http::models))
        .routes(routes!(http::roughness))
        .routes(routes!(http::stream_map))
        .routes(routes!(stream::stream))
}

/// The routes over `state`.
pub(crate) fn router(state: Arc<AppState>) -> Router {
    let (routes, _) = routes().split_for_parts();
    routes
        .fallback(http::not_found)
        .method_not_allowed_fallback(http::method_not_allowed)
        .layer(DefaultBodyLimit::disable())
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            access::guard,
        ))
        .with_state(state)
}

/// Serves on `listener` until `shutdown` completes, then stops taking connections, lets
/// in-flight requests and stream frames finish (up to the grace time) and stops the workers.
/// The models load on the workers while `/healthz` already answers; `/readyz` turns 200 once
/// every worker has warmed up. A worker that cannot load the models stops the service with
/// [`ServeError::Workers`].
pub async fn serve(
    cfg: ServeConfig,
    listener: tokio::net::TcpListener,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<(), ServeError> {
    let (state, stop_tx) = start(&cfg)?;
    let refusals = state.refusals.clone();
    tokio::spawn(async move {
        let mut every = tokio::time::interval(refusals::WINDOW);
        loop {
            every.tick().await;
            refusals.flush();
        }
    });
    let (failed_tx, failed_rx) = tokio::sync::oneshot::channel::<Arc<workers::WorkerError>>();
    tokio::spawn(watch_startup(state.clone(), failed_tx));
    let app = router(state.clone());
    let signal = async move {
        tokio::select! {
            () = shutdown => tracing::info!("shutting down: finishing in-flight work"),
            Ok(why) = failed_rx => tracing::error!("{why}"),
        }
        let _ = stop_tx.send(true);
    };
    let limits = connections::ConnectionLimits {
        header_read: cfg.header_timeout,
        write_stall: cfg.stall_timeout,
        max_open: cfg.max_connections,
        drain_bytes: cfg.max_body_bytes,
    };
    let server = connections::serve_connections(
        listener,
        app,
        limits,
        (state.metrics.clone(), state.refusals.clone()),
        signal,
    );
    drain(&state, server).await;
    let st = state.clone();
    tokio::task::spawn_blocking(move || st.workers.shutdown())
        .await
        .map_err(std::io::Error::other)?;
    match state.workers.failure() {
        Some(why) => Err(ServeError::Workers(why)),
        None => Ok(()),
    }
}

/// Checks the settings, reads the manifest and starts the workers: the service's state, and
/// the sender that starts its shutdown.
fn start(cfg: &ServeConfig) -> Result<(Arc<AppState>, watch::Sender<bool>), ServeError> {
    cfg.validate(tre_model::cores())?;
    check_dsac_hypotheses(cfg.defaults.dsac_hypotheses).map_err(ServeError::Config)?;
    let manifest = Manifest::read(&cfg.models)?;
    let calibration = tre_pipeline::read_calibration(&cfg.models).map_err(ServeError::Config)?;
    if let Some(stale) = calibration
        .as_ref()
        .and_then(|c| tre_pipeline::stale_calibration(c, &manifest))
    {
        tracing::warn!("{}: {stale}", cfg.models.display());
    }
    let manifest_json = serde_json::to_string_pretty(&manifest).map_err(std::io::Error::other)?;
    let model_names = manifest.models.keys().cloned().collect();
    let metrics = Arc::new(Metrics::default());
    let pool = PoolConfig {
        workers: cfg.workers,
        queue: cfg.queue,
        models: cfg.models.clone(),
        session: cfg.session,
        limits: cfg.decode_limits(),
        defaults: cfg.defaults,
        calibration,
    };
    let workers = Workers::start(&pool, metrics.clone())?;
    let (stop_tx, stop_rx) = watch::channel(false);
    let state = Arc::new(AppState {
        concurrency: Arc::new(Semaphore::new(cfg.max_concurrent)),
        streams: Arc::new(Semaphore::new(cfg.max_streams)),
        waiting_streams: Arc::new(Semaphore::new(cfg.max_connections)),
        cfg: cfg.clone(),
        workers,
        metrics,
        manifest_json,
        model_names,
        shutdown: stop_rx,
        refusals: Arc::new(RefusalLog::default()),
        maps: map::MapRegistry::default(),
    });
    Ok((state, stop_tx))
}

/// Waits for `server` to stop taking connections and for every stream to close, or for the
/// grace time once shutdown has begun, whichever comes first.
async fn drain(state: &AppState, server: impl Future<Output = ()>) {
    // Upgraded streams are no longer connections of the server: it does not wait for them.
    // Each holds a stream permit (or, before its first message, a waiting one) until it has
    // answered its frame in flight and closed, so holding every permit means they are all done.
    let streams = state.streams.clone();
    let all_streams = u32::try_from(state.cfg.max_streams).unwrap_or(u32::MAX);
    let waiting = state.waiting_streams.clone();
    let all_waiting = u32::try_from(state.cfg.max_connections).unwrap_or(u32::MAX);
    let drained = async move {
        server.await;
        let _closed = streams.acquire_many(all_streams).await;
        let _none_waiting = waiting.acquire_many(all_waiting).await;
    };
    let grace = state.cfg.shutdown_grace;
    let mut stopping = state.shutdown.clone();
    tokio::select! {
        () = drained => {}
        () = async { let _ = stopping.wait_for(|s| *s).await; tokio::time::sleep(grace).await } => {
            tracing::warn!("in-flight work did not finish within {} s; stopping anyway", grace.as_secs());
        }
    }
}

/// Logs readiness, or reports the first worker failure.
async fn watch_startup(
    state: Arc<AppState>,
    failed: tokio::sync::oneshot::Sender<Arc<workers::WorkerError>>,
) {
    let start = std::time::Instant::now();
    loop {
        if let Some(why) = state.workers.failure() {
            let _ = failed.send(why);
            return;
        }
        if state.workers.ready() {
            tracing::info!(
                took_ms = start.elapsed().as_millis() as u64,
                workers = state.workers.count(),
                "ready"
            );
            return;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}
