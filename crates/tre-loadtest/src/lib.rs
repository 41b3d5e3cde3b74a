//! Load testing of `tre serve`: open- and closed-loop load over HTTP and the WebSocket stream,
//! latency measured from each request's intended send time (coordinated omission corrected),
//! HDR histograms, text and JSON reports, a hand-written SVG plot and rate sweeps with their knee.
//!
//! In open loop the client sends request `i` at `t0 + i / rate` whatever the answers do, and
//! measures its latency from that intended time: a stall in the service shows up in every
//! request scheduled during it, not only in the one that met it. Closed loop is `N` clients that
//! each send the next request when the previous answer is back.
//!
//! ```no_run
//! # async fn demo() -> Result<(), tre_loadtest::LoadError> {
//! use std::time::Duration;
//! use tre_loadtest::{run, Load, LoadConfig};
//! let cfg = LoadConfig {
//!     load: Load::Open { rate_per_s: 10.0 },
//!     duration: Some(Duration::from_secs(5)),
//!     ..LoadConfig::default()
//! };
//! let report = run(&cfg).await?;
//! println!("{}", tre_loadtest::report::text(&report));
//! # Ok(())
//! # }
//! ```

#[cfg(feature = "cli")]
mod cli;
mod frames;
mod http;
mod plan;
mod problems;
pub mod report;
mod stats;
pub mod svg;
mod target;
mod ws;

use std::path::PathBuf;
use std::time::Duration;

use report::SweepReport;
use serde::{Deserialize, Serialize};

#[cfg(feature = "cli")]
pub use cli::{ArgsError, LoadtestArgs};
pub use frames::{Frames, LoadFrame, LoadSource};
pub use problems::{AnswerProblem, FirstAnswer, FrameProblem, StreamProblem, UrlProblem};
pub use stats::{Percentiles, Report};
pub use target::Target;

/// Which interface of the service is loaded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Protocol {
    /// `POST /v1/roughness`, one frame per request.
    Http,
    /// `GET /v1/stream` (WebSocket, protobuf frames).
    Ws,
}

impl Protocol {
    /// `http` or `ws`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Http => "http",
            Self::Ws => "ws",
        }
    }
}

/// How requests are issued.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Load {
    /// Requests at constant intended send times `t0 + i / rate_per_s`, whatever the answers do
    /// (up to [`LoadConfig::max_in_flight`] outstanding); over WebSocket, round robin over the
    /// connections.
    Open {
        /// Requests per second.
        rate_per_s: f64,
    },
    /// [`LoadConfig::connections`] clients, each sending its next request when the previous
    /// answer is back.
    Closed,
}

/// Settings of one load-test run; checked by [`LoadConfig::validate`].
#[derive(Debug, Clone)]
pub struct LoadConfig {
    /// Base URL of the service (`http://host:port`, optionally with a path prefix; `https://`
    /// for TLS, the stream then over `wss://`).
    pub url: String,
    /// API key of a server started with `--api-key`, sent as `Authorization: Bearer KEY`.
    pub api_key: Option<String>,
    /// PEM file of a private CA to trust beside the public roots (TLS only).
    pub ca_cert: Option<std::path::PathBuf>,
    /// Accept host names that resolve to addresses other than loopback.
    pub allow_remote: bool,
    /// HTTP or WebSocket.
    pub protocol: Protocol,
    /// Open or closed loop.
    pub load: Load,
    /// Closed loop: concurrent clients; WebSocket open loop: connections, used round robin.
    pub connections: usize,
    /// Open loop: most requests outstanding at once; a request due beyond it is counted as
    /// `client_saturated` instead of being sent late.
    pub max_in_flight: usize,
    /// Length of the measured window (after the warm-up); `None`: until `requests`.
    pub duration: Option<Duration>,
    /// Measured requests to issue; `None`: until `duration`. The run stops at whichever comes
    /// first.
    pub requests: Option<u64>,
    /// Load before the measured window, left out of every statistic.
    pub warmup: Duration,
    /// Time one request may take before it counts as a `timeout` error.
    pub timeout: Duration,
    /// The frames sent, cycled.
    pub frames: LoadSource,
    /// Depth sent with each frame (files paired with the frames in order, or a folder of
    /// `.png`/`.npy`), as `tre client --depth` sends it.
    pub depth: Option<LoadSource>,
    /// Send the depth alone, no image (the geometric mode's input).
    pub depth_only: bool,
    /// What every frame asks for.
    pub ask: Ask,
}

/// What every frame of a load test asks for, as `tre client` asks it: over HTTP as the query
/// (and a `camera` part), over the stream as the Hello.
#[derive(Debug, Clone, Default)]
pub struct Ask {
    /// Input mode; `None`: the server's choice from the inputs.
    pub mode: Option<tre_core::kinds::Mode>,
    /// The camera file as written (sent as the HTTP `camera` part) and as read (the Hello).
    pub camera: Option<(Vec<u8>, tre_io::CameraFile)>,
    /// Sensor noise model, overriding the camera's.
    pub sensor: Option<tre_core::roughness::noise::SensorNoise>,
    /// Initial normals; `None`: the server's.
    pub normals: Option<tre_core::kinds::NormalsMethod>,
    /// DSAC hypotheses; `None`: the server's.
    pub dsac_hypotheses: Option<u32>,
    /// Also ask for the three-state map and the uncertainty.
    pub traversal: bool,
    /// More HTTP query parameters (`key=value&…`), passed as given (HTTP only).
    pub query: String,
}

impl Ask {
    /// The HTTP query (without `?`): the typed choices, then [`query`](Self::query).
    pub fn http_query(&self) -> String {
        let mut q: Vec<String> = Vec::new();
        if let Some(m) = self.mode {
            q.push(format!("mode={m}"));
        }
        if let Some(n) = self.normals {
            q.push(format!("normals={n}"));
        }
        if let Some(k) = self.dsac_hypotheses {
            q.push(format!("dsac_hypotheses={k}"));
        }
        match self.sensor {
            Some(tre_core::roughness::noise::SensorNoise::Preset(p)) => {
                q.push(format!("sensor={p}"))
            }
            Some(tre_core::roughness::noise::SensorNoise::Coefficients {
                sigma_mm: [a, b, c],
            }) => {
                q.push(format!("sensor={a},{b},{c}"));
            }
            // The query has no stereo rig: its σ_z as coefficients.
            Some(tre_core::roughness::noise::SensorNoise::Stereo { stereo }) => {
                let [a, b, c] = stereo.sigma_mm();
                q.push(format!("sensor={a},{b},{c}"));
            }
            None => {}
        }
        if self.traversal {
            q.push("outputs=traversal,uncertainty".into());
        }
        if !self.query.is_empty() {
            q.push(self.query.clone());
        }
        q.join("&")
    }

    /// The stream's Hello: what `tre client` sends for the same choices.
    pub fn hello(&self) -> tre_proto::v1::Hello {
        let cfg = tre_client::ClientConfig {
            camera: self.camera.as_ref().map(|(_, c)| c.clone()),
            mode: self.mode,
            sensor: self.sensor,
            normals: self.normals,
            dsac_hypotheses: self.dsac_hypotheses,
            want_traversal: self.traversal,
            ..tre_client::ClientConfig::default()
        };
        tre_proto::v1::Hello::from(&cfg)
    }

    /// The camera JSON as written, or nothing.
    pub fn camera_json(&self) -> &[u8] {
        self.camera.as_ref().map_or(&[], |(j, _)| j.as_slice())
    }
}

impl Default for LoadConfig {
    fn default() -> Self {
        Self {
            url: "http://127.0.0.1:8080".into(),
            api_key: None,
            ca_cert: None,
            allow_remote: false,
            protocol: Protocol::Http,
            load: Load::Closed,
            connections: 1,
            max_in_flight: 256,
            duration: Some(Duration::from_secs(10)),
            requests: None,
            warmup: Duration::ZERO,
            timeout: Duration::from_secs(30),
            frames: LoadSource::default(),
            depth: None,
            depth_only: false,
            ask: Ask::default(),
        }
    }
}

impl LoadConfig {
    /// Checks the settings; the error names the bad one.
    pub fn validate(&self) -> Result<(), LoadError> {
        self.problem().map_or(Ok(()), |p| Err(LoadError::Config(p)))
    }

    /// The first setting out of its range, if any.
    fn problem(&self) -> Option<LoadConfigProblem> {
        if let Load::Open { rate_per_s } = self.load {
            if !(rate_per_s.is_finite() && rate_per_s > 0.0) {
                return Some(LoadConfigProblem::Rate { rate_per_s });
            }
        }
        if self.connections == 0 {
            return Some(LoadConfigProblem::NoConnections);
        }
        if self.max_in_flight == 0 {
            return Some(LoadConfigProblem::NoInFlight);
        }
        if self.duration.is_none() && self.requests.is_none() {
            return Some(LoadConfigProblem::NoEnd);
        }
        if self.duration.is_some_and(|d| d.is_zero()) || self.requests == Some(0) {
            return Some(LoadConfigProblem::EmptyWindow);
        }
        if self.timeout.is_zero() {
            return Some(LoadConfigProblem::NoTimeout);
        }
        if self.depth_only && self.depth.is_none() {
            return Some(LoadConfigProblem::DepthOnlyWithoutDepth);
        }
        if self.protocol == Protocol::Ws && !self.ask.query.is_empty() {
            return Some(LoadConfigProblem::QueryOnStream {
                query: self.ask.query.clone(),
            });
        }
        None
    }

    /// The frames of this run: images, depth and the camera as configured.
    pub fn load_frames(&self) -> Result<Frames, LoadError> {
        let images = (!self.depth_only).then_some(&self.frames);
        Frames::with_depth(images, self.depth.as_ref(), self.ask.camera_json())
    }

    /// The offered rate of an open-loop run.
    pub fn rate_per_s(&self) -> Option<f64> {
        match self.load {
            Load::Open { rate_per_s } => Some(rate_per_s),
            Load::Closed => None,
        }
    }
}

/// The `Authorization: Bearer KEY` value of `key`, marked sensitive (kept out of debug output).
pub(crate) fn bearer(key: &str) -> Result<reqwest::header::HeaderValue, LoadError> {
    let mut v = reqwest::header::HeaderValue::from_str(&format!("Bearer {key}"))
        .map_err(|_| LoadError::Config(LoadConfigProblem::ApiKey))?;
    v.set_sensitive(true);
    Ok(v)
}

/// Errors of the load tester (answers of the service are outcomes, not errors).
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// A bad setting.
    #[error(transparent)]
    Config(LoadConfigProblem),
    /// The TLS configuration (`--ca-cert`) cannot be built.
    #[error(transparent)]
    Tls(#[from] tre_client::tls::TlsError),
    /// The synthetic frame cannot be encoded.
    #[error("synthetic frame: {0}")]
    Synthetic(image::ImageError),
    /// The URL does not parse or is not `http(s)://` / `ws(s)://`.
    #[error("url {url:?}: {why}")]
    Url {
        /// The URL given.
        url: String,
        /// What is wrong with it.
        why: UrlProblem,
    },
    /// The host name resolves to addresses that are not loopback and `allow_remote` is off.
    #[error("{host} resolves to {addrs} (not loopback); pass --allow-remote to load a remote service, or give the IP address itself in --url")]
    Remote {
        /// The host name.
        host: String,
        /// The addresses it resolves to.
        addrs: String,
    },
    /// The host name does not resolve.
    #[error("cannot resolve {host}: {error}")]
    Resolve {
        /// The host name.
        host: String,
        /// Why.
        error: std::io::Error,
    },
    /// No address of the target accepts connections.
    #[error("cannot connect to {addrs}: {error}")]
    Connect {
        /// The addresses tried.
        addrs: String,
        /// The last failure.
        error: std::io::Error,
    },
    /// A frame file cannot be read or is not a PNG or JPEG.
    #[error("frame {path}: {why}")]
    Frame {
        /// The file.
        path: PathBuf,
        /// Why.
        why: FrameProblem,
    },
    /// The WebSocket handshake or the Hello failed.
    #[error("websocket {url}: {why}")]
    Stream {
        /// The stream URL.
        url: String,
        /// Why.
        why: StreamProblem,
    },
    /// The HTTP client could not be built.
    #[error("http client: {0}")]
    Client(#[from] reqwest::Error),
}

/// A setting of a load test out of its range, or settings that do not go together; the
/// message names the setting as the `tre loadtest` option spells it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LoadConfigProblem {
    /// An open-loop rate that is not a positive number.
    #[error("rate: must be a positive number, got {rate_per_s}")]
    Rate {
        /// The rate given, requests a second.
        rate_per_s: f64,
    },
    /// No connection.
    #[error("connections: must be at least 1")]
    NoConnections,
    /// No request may be outstanding.
    #[error("max-in-flight: must be at least 1")]
    NoInFlight,
    /// Neither a duration nor a number of requests: the run would not end.
    #[error("give a duration, a number of requests or both")]
    NoEnd,
    /// A duration or number of requests of 0.
    #[error("duration and requests: must be positive")]
    EmptyWindow,
    /// A request timeout of 0.
    #[error("timeout: must be positive")]
    NoTimeout,
    /// Depth alone, without depth frames.
    #[error("depth only: give the depth frames")]
    DepthOnlyWithoutDepth,
    /// Extra query parameters for the stream, which has no query.
    #[error(
        "query {query:?}: extra query parameters go to HTTP only; the stream takes the mode, \
         camera, sensor, normals, DSAC hypotheses and traversal options"
    )]
    QueryOnStream {
        /// The parameters given.
        query: String,
    },
    /// An API key that cannot be a header value.
    #[error("--api-key: not a valid header value")]
    ApiKey,
    /// A sweep without rates.
    #[error("sweep: give at least one rate")]
    NoRates,
    /// A sweep's latency objective that is not positive.
    #[error("slo-ms: must be positive, got {slo_ms}")]
    Slo {
        /// The objective given, milliseconds.
        slo_ms: f64,
    },
    /// Synthetic depth, which the load tester does not render.
    #[error("depth: give depth files or a folder of them")]
    SyntheticDepth,
    /// Image and depth files that do not pair up.
    #[error("{images} images but {depths} depth frames: give one depth frame per image")]
    DepthCount {
        /// Images given.
        images: usize,
        /// Depth frames given.
        depths: usize,
    },
    /// A synthetic frame of no pixels, or of more than 16 million.
    #[error("synthetic frame: size {}×{} out of range", size.0, size.1)]
    SyntheticSize {
        /// The size asked for, `(width, height)`.
        size: (usize, usize),
    },
}

/// Runs one load test as `cfg` says and reports on its measured window.
pub async fn run(cfg: &LoadConfig) -> Result<Report, LoadError> {
    cfg.validate()?;
    let target = Target::resolve(&cfg.url, cfg.allow_remote).await?;
    let frames = cfg.load_frames()?;
    run_on(cfg, &target, &frames).await
}

/// Runs one load test against a resolved target with loaded frames (what [`run`] and
/// [`sweep`] do per run).
pub async fn run_on(
    cfg: &LoadConfig,
    target: &Target,
    frames: &Frames,
) -> Result<Report, LoadError> {
    cfg.validate()?;
    match cfg.protocol {
        Protocol::Http => http::drive(cfg, target, frames).await,
        Protocol::Ws => ws::drive(cfg, target, frames).await,
    }
}

/// Runs `cfg` in open loop once per rate of `rates_per_s` (ascending), each for the configured
/// duration and warm-up, and finds the knee: the first rate with refusals, errors, saturated
/// client or a p99 above `slo_ms`.
pub async fn sweep(
    cfg: &LoadConfig,
    rates_per_s: &[f64],
    slo_ms: f64,
    mut progress: impl FnMut(&Report),
) -> Result<SweepReport, LoadError> {
    if rates_per_s.is_empty() {
        return Err(LoadError::Config(LoadConfigProblem::NoRates));
    }
    if !(slo_ms.is_finite() && slo_ms > 0.0) {
        return Err(LoadError::Config(LoadConfigProblem::Slo { slo_ms }));
    }
    let mut rates = rates_per_s.to_vec();
    rates.sort_by(f64::total_cmp);
    rates.dedup();
    cfg.validate()?;
    let target = Target::resolve(&cfg.url, cfg.allow_remote).await?;
    let frames = cfg.load_frames()?;
    let mut rows = Vec::with_capacity(rates.len());
    for rate_per_s in rates {
        let one = LoadConfig {
            load: Load::Open { rate_per_s },
            ..cfg.clone()
        };
        let row = run_on(&one, &target, &frames).await?;
        progress(&row);
        rows.push(row);
    }
    Ok(SweepReport::new(rows, slo_ms))
}
