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
// Its `pub` items are in `request`'s signatures: public with the `bench` feature only.
#[cfg_attr(not(feature = "bench"), allow(unreachable_pub))]
mod map;
mod metrics;
mod openapi;
// The frame options and a request's stages: public for the pipeline bench's server-worker
// figures only (`bench` feature, benches/pipeline.rs), never the service's API. Without the
// feature their `pub` items reach no further than the crate.
#[cfg(feature = "bench")]
pub mod options;
#[cfg(not(feature = "bench"))]
#[allow(unreachable_pub)]
mod options;
mod pace;
mod proto;
mod query;
mod refusals;
#[cfg(feature = "bench")]
pub mod request;
#[cfg(not(feature = "bench"))]
#[allow(unreachable_pub)]
mod request;
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
pub use error::{
    BodyError, CameraError, ImageError, LimitError, OptionError, RequestError, ServiceError,
    StreamError,
};
pub use signal::{serve_until_signal, shutdown_signal};

use metrics::Metrics;
use refusals::RefusalLog;
use request::{DecodeLimits, FrameDefaults};
use tre_model::{Manifest, Provider};
use tre_pipeline::check_dsac_hypotheses;
use workers::{PoolConfig, Workers};

/// How far past its limit an oversize input (an HTTP body, a WebSocket message) is still read
/// and answered with a `too_large` error: up to this many times the limit. Reading it through
/// lets a client that sends everything before reading (Python's `http.client`, for one) see the
/// error, and keeps a stream open; beyond it the connection closes.
pub(crate) const OVERSIZE_READ_FACTOR: usize = 4;

/// Settings of the service; every field is a `tre serve` option (clap's, behind the `cli`
/// feature: each doc comment here is its `--help`). Zeros and unset values that mean "choose for
/// me" (workers, threads, queue, models folder) are chosen by [`ServeConfig::resolve`], which
/// [`serve`] runs first.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct ServeConfig {
    /// Address to listen on (port 0: any free port; the address is printed on stdout). The
    /// default is loopback only; to serve a network, give its address (and an --api-key).
    #[cfg_attr(
        feature = "cli",
        arg(long, env = "TRE_ADDR", default_value = "127.0.0.1:8080")
    )]
    pub addr: SocketAddr,
    /// Folder with manifest.json and the ONNX models. When not given: TRE_MODELS, then
    /// models/ beside the executable, ../share/tre/models relative to it, then models/ in the
    /// working directory.
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_MODELS"))]
    pub models: Option<PathBuf>,
    /// Inference worker threads, each with its own sessions (0: one per core).
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_WORKERS", default_value_t = 0))]
    pub workers: usize,
    /// ONNX Runtime threads per operator in each worker (0: cores / workers, at least 1).
    #[cfg_attr(
        feature = "cli",
        arg(long, env = "TRE_ORT_THREADS", default_value_t = 0)
    )]
    pub ort_threads: usize,
    /// Execution provider.
    #[cfg_attr(
        feature = "cli",
        arg(long, env = "TRE_PROVIDER", value_enum, default_value = "cpu")
    )]
    pub provider: Provider,
    /// GPU index for the cuda and tensorrt providers.
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_DEVICE_ID", default_value_t = 0))]
    pub device_id: i32,
    /// Frames that may wait for a worker; beyond, requests get 503 at once (0: 2 per worker).
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_QUEUE", default_value_t = 0))]
    pub queue: usize,
    /// Dynamic batching: frames run through each net as one batch at most, 1 to 64 (1: none).
    /// Above 1, each model is loaded once, on a thread of its own that every worker shares, and
    /// a frame's net run waits up to --batch-delay-ms for others of its size. Meant for a GPU;
    /// on a CPU the workers already keep the cores busy.
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_BATCH_MAX", default_value_t = 1))]
    pub batch_max: usize,
    /// How long the first frame of a batch waits for more, milliseconds (at most 1000).
    #[cfg_attr(feature = "cli", arg(long = "batch-delay-ms", value_name = "BATCH_DELAY_MS",
        env = "TRE_BATCH_DELAY_MS", default_value = "2",
        value_parser = tre_io::units::parse_millis))]
    pub batch_delay: Duration,
    /// Largest request body, bytes: a number with an optional k, M or G suffix (KiB, MiB,
    /// GiB).
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_MAX_BODY_BYTES", default_value = "32MiB",
        value_parser = tre_io::units::parse_size))]
    pub max_body_bytes: usize,
    /// Largest image, pixels (checked from the header, before decoding). The costliest frame
    /// is depth-only in the geometric mode, which runs at the frame's own size: at 4 Mpx (the
    /// default) about 1.6 s of one worker and 0.6 GB resident; at 16 Mpx 7.4 s and 1.3 GB
    /// (docs/security.md). RGB frames run at the working size and cost far less.
    /// A number with an optional k, M or G suffix (binary: 4Mi = 4,194,304).
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_MAX_PIXELS", default_value = "4Mi",
        value_parser = tre_io::units::parse_size))]
    pub max_pixels: usize,
    /// Longest image side, pixels (checked from the header, before decoding; beyond: 413).
    #[cfg_attr(
        feature = "cli",
        arg(long, env = "TRE_MAX_SIDE", default_value_t = 8192)
    )]
    pub max_side: usize,
    /// Largest ratio of an image's longer side to its shorter one (checked from the header,
    /// before decoding; beyond: 422). A 16777216×1 image otherwise costs seconds of resizing.
    #[cfg_attr(
        feature = "cli",
        arg(long, env = "TRE_MAX_ASPECT", default_value_t = 8)
    )]
    pub max_aspect: usize,
    /// Time a client has to send a request's headers, milliseconds: one that sent part of them
    /// gets 408, an idle kept-alive connection is closed.
    #[cfg_attr(feature = "cli", arg(long = "header-timeout-ms", value_name = "HEADER_TIMEOUT_MS",
        env = "TRE_HEADER_TIMEOUT_MS", default_value = "10000",
        value_parser = tre_io::units::parse_millis))]
    pub header_timeout: Duration,
    /// Time a client has to send a request's body once its headers are in, milliseconds (then
    /// 408). Uploads hold no --max-concurrent place.
    #[cfg_attr(feature = "cli", arg(long = "body-timeout-ms", value_name = "BODY_TIMEOUT_MS",
        env = "TRE_BODY_TIMEOUT_MS", default_value = "20000",
        value_parser = tre_io::units::parse_millis))]
    pub body_timeout: Duration,
    /// Least rate of a request's body, bytes a second, averaged over each 5 s from the headers
    /// on (the first 5 s are the grace): a body slower than this gets 408 at the end of the
    /// window, before --body-timeout-ms. 0 turns it off.
    #[cfg_attr(
        feature = "cli",
        arg(long, env = "TRE_MIN_BODY_RATE", default_value_t = 1024)
    )]
    pub min_body_rate: u64,
    /// API key: every route and the stream upgrade except /healthz and /readyz then want
    /// `Authorization: Bearer KEY` (401 without). Prefer the environment to the command line.
    #[cfg_attr(
        feature = "cli",
        arg(long, env = "TRE_API_KEY", hide_env_values = true)
    )]
    pub api_key: Option<String>,
    /// Browser origins allowed to call the service and open the stream, such as
    /// `https://ops.example` (repeat, or comma-separate; `*` allows any). Others get 403; a
    /// page the server itself serves (the demo) is same-origin and always allowed.
    #[cfg_attr(
        feature = "cli",
        arg(
            long = "allow-origin",
            value_name = "ALLOW_ORIGIN",
            env = "TRE_ALLOW_ORIGIN",
            value_delimiter = ','
        )
    )]
    pub allow_origins: Vec<String>,
    /// HTTP requests handled at once (counted once the body is in); beyond, 429 at once.
    #[cfg_attr(
        feature = "cli",
        arg(long, env = "TRE_MAX_CONCURRENT", default_value_t = 64)
    )]
    pub max_concurrent: usize,
    /// Time one HTTP request may take once its body is in, the queue and the run, milliseconds
    /// (then 503 `timeout`).
    #[cfg_attr(feature = "cli", arg(long = "request-timeout-ms",
        value_name = "REQUEST_TIMEOUT_MS", env = "TRE_REQUEST_TIMEOUT_MS",
        default_value = "30000", value_parser = tre_io::units::parse_millis))]
    pub request_timeout: Duration,
    /// Largest WebSocket message, bytes, with an optional k, M or G suffix (up to 4× this gets
    /// an error message; beyond, the connection is closed with 1009).
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_WS_MAX_MESSAGE_BYTES",
        default_value = "16MiB", value_parser = tre_io::units::parse_size))]
    pub ws_max_message_bytes: usize,
    /// What frames get for the settings they do not choose.
    #[cfg_attr(feature = "cli", command(flatten))]
    pub defaults: FrameDefaults,
    /// WebSocket streams open at once; beyond, the upgrade gets 429 at once.
    #[cfg_attr(
        feature = "cli",
        arg(long, env = "TRE_MAX_STREAMS", default_value_t = 64)
    )]
    pub max_streams: usize,
    /// A stream whose client sends nothing (no message, no answer to the server's pings) for
    /// this long is closed, milliseconds; its `--max-streams` place is freed.
    #[cfg_attr(feature = "cli", arg(long = "ws-idle-timeout-ms",
        value_name = "WS_IDLE_TIMEOUT_MS", env = "TRE_WS_IDLE_TIMEOUT_MS",
        default_value = "60000", value_parser = tre_io::units::parse_millis))]
    pub ws_idle_timeout: Duration,
    /// A connection whose client takes no byte of an answer for this long (it stopped reading,
    /// like a hung process with its socket open) is closed, milliseconds: HTTP requests and
    /// streams alike. A slow client that keeps reading is not affected.
    #[cfg_attr(feature = "cli", arg(long = "stall-timeout-ms", value_name = "STALL_TIMEOUT_MS",
        env = "TRE_STALL_TIMEOUT_MS", default_value = "30000",
        value_parser = tre_io::units::parse_millis))]
    pub stall_timeout: Duration,
    /// HTTP connections open at once (a stream counts until its upgrade, then against
    /// `--max-streams`); beyond, requests get 503 and the connection is closed. Each open
    /// connection takes a file descriptor: `ulimit -n` should allow twice this plus
    /// `--max-streams` and about 100 more.
    #[cfg_attr(
        feature = "cli",
        arg(long, env = "TRE_MAX_CONNECTIONS", default_value_t = 1024)
    )]
    pub max_connections: usize,
    /// Seconds in-flight work may take to finish after SIGTERM or Ctrl-C.
    #[cfg_attr(feature = "cli", arg(long = "shutdown-grace-s", value_name = "SHUTDOWN_GRACE_S",
        env = "TRE_SHUTDOWN_GRACE_S", default_value = "30",
        value_parser = tre_io::units::parse_seconds))]
    pub shutdown_grace: Duration,
    /// Settings of the streams' maps: a preset (`indoor`: 4 cm cells, an 8 m window, points to
    /// 4 m; `outdoor`: 10 cm cells, a 40 m window, points from 1 to 20 m) or a TOML settings
    /// file (docs/map.md), the same `tre map --params` reads; a Hello's `cell_m` and `side`
    /// change them.
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_MAP_PARAMS", default_value = "indoor",
        value_parser = tre_io::map_params::map_params_arg))]
    pub map_params: tre_core::map::MapParams,
}

impl Default for ServeConfig {
    /// The options' defaults (a test checks that they agree).
    fn default() -> Self {
        Self {
            addr: SocketAddr::from(([127, 0, 0, 1], 8080)),
            models: None,
            workers: 0,
            ort_threads: 0,
            provider: Provider::Cpu,
            device_id: 0,
            queue: 0,
            batch_max: 1,
            batch_delay: Duration::from_millis(2),
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
            defaults: FrameDefaults::default(),
            max_streams: 64,
            ws_idle_timeout: Duration::from_secs(60),
            stall_timeout: Duration::from_secs(30),
            max_connections: 1024,
            shutdown_grace: Duration::from_secs(30),
            map_params: tre_core::map::MapParams::preset(tre_core::map::MapPreset::Indoor),
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

/// Resolves and checks the settings, reads the manifest and starts the workers: the service's
/// state, and the sender that starts its shutdown.
fn start(cfg: &ServeConfig) -> Result<(Arc<AppState>, watch::Sender<bool>), ServeError> {
    let cores = tre_model::cores();
    let cfg = if cfg.is_resolved() {
        cfg.validate(cores)?;
        cfg.clone()
    } else {
        cfg.clone().resolve(cores)?
    };
    let models = cfg.models_dir().to_path_buf();
    check_dsac_hypotheses(cfg.defaults.dsac_hypotheses).map_err(ServeError::Config)?;
    let manifest = Manifest::read(&models)?;
    let calibration = tre_pipeline::read_calibration(&models).map_err(ServeError::Config)?;
    if let Some(stale) = calibration
        .as_ref()
        .and_then(|c| tre_pipeline::stale_calibration(c, &manifest))
    {
        tracing::warn!("{}: {stale}", models.display());
    }
    let manifest_json = serde_json::to_string_pretty(&manifest).map_err(std::io::Error::other)?;
    let model_names = manifest.models.keys().cloned().collect();
    let metrics = Arc::new(Metrics::default());
    let pool = PoolConfig {
        workers: cfg.workers,
        queue: cfg.queue,
        models,
        session: cfg.session()?,
        batching: cfg.batching(),
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
