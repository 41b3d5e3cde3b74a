//! The options of `tre loadtest` (the `cli` feature), checked into a [`LoadConfig`], and the
//! files they name: the earlier report to compare with, the JSON and the plot to write.

use std::path::{Path, PathBuf};
use std::time::{Duration, TryFromFloatSecsError};

use tre_core::kinds::{Mode, NormalsMethod};
use tre_core::roughness::noise::SensorNoise;
use tre_io::IoError;

use crate::{Ask, Load, LoadConfig, LoadError, LoadSource, Protocol, Report};

/// Load a running `tre serve` and report throughput and latency (coordinated omission
/// corrected in open loop).
#[derive(Debug, Clone, clap::Args)]
pub struct LoadtestArgs {
    /// Base URL of the service. Only loopback unless you write the address here yourself; host
    /// names must resolve to loopback unless --allow-remote.
    #[arg(
        long,
        env = "TRE_LOADTEST_URL",
        default_value = "http://127.0.0.1:8080"
    )]
    pub url: String,
    /// API key of a server started with --api-key (sent as `Authorization: Bearer KEY`).
    #[arg(long, env = "TRE_API_KEY", hide_env_values = true)]
    pub api_key: Option<String>,
    /// PEM file of a private CA to trust beside the public roots, for an https:// --url whose
    /// certificate it issued (the stream then goes over wss://).
    #[arg(long, env = "TRE_CA_CERT")]
    pub ca_cert: Option<PathBuf>,
    /// Allow a host name in --url that resolves to a non-loopback address (load a remote
    /// service on purpose).
    #[arg(long, env = "TRE_LOADTEST_ALLOW_REMOTE")]
    pub allow_remote: bool,
    /// Interface to load.
    #[arg(
        long,
        env = "TRE_LOADTEST_PROTOCOL",
        value_enum,
        default_value = "http"
    )]
    pub protocol: Protocol,
    /// A PNG or JPEG frame to send (repeat for several, cycled). Default: a synthetic 256×256
    /// terrain frame rendered in memory.
    #[arg(long = "frame", env = "TRE_LOADTEST_FRAME", conflicts_with = "frames")]
    pub frame: Vec<PathBuf>,
    /// A folder whose .png/.jpg/.jpeg files are sent, cycled in name order.
    #[arg(long, env = "TRE_LOADTEST_FRAMES")]
    pub frames: Option<PathBuf>,
    /// A registered depth frame sent with the --frame at the same place (repeat, one per
    /// --frame): a 16-bit PNG (the camera's depth_scale, default millimetres) or a float .npy
    /// in metres. Without --frame or --frames, depth alone is sent (the geometric mode).
    #[arg(long, env = "TRE_LOADTEST_DEPTH", conflicts_with = "depth_dir")]
    pub depth: Vec<PathBuf>,
    /// A folder of depth frames (.png/.npy), paired with the frames in name order (as
    /// --depth); alone, depth only.
    #[arg(long, env = "TRE_LOADTEST_DEPTH_DIR")]
    pub depth_dir: Option<PathBuf>,
    /// Camera JSON sent with every frame (the HTTP `camera` part, the stream's Hello), read as
    /// `tre infer` reads it (cameras/README.md).
    #[arg(long, env = "TRE_CAMERA")]
    pub camera: Option<PathBuf>,
    /// Input mode asked for; default: the server's choice from the inputs.
    #[arg(long, env = "TRE_MODE", value_enum)]
    pub mode: Option<Mode>,
    /// Depth sensor noise model, overriding the camera's (as `tre infer --sensor`).
    #[arg(long, env = "TRE_SENSOR")]
    pub sensor: Option<SensorNoise>,
    /// Initial normals asked for: dsac or ls; default: the server's.
    #[arg(long, env = "TRE_LOADTEST_NORMALS", value_enum)]
    pub normals: Option<NormalsMethod>,
    /// DSAC hypotheses per pixel asked for, 1 to 64; default: the server's.
    #[arg(long, env = "TRE_LOADTEST_DSAC_HYPOTHESES",
          value_parser = tre_core::kinds::dsac_hypotheses_parser())]
    pub dsac_hypotheses: Option<u32>,
    /// Also ask for the three-state map and the uncertainty (a sensor noise model needed).
    #[arg(long, env = "TRE_LOADTEST_TRAVERSAL")]
    pub traversal: bool,
    /// Side of the synthetic square frame, pixels (when no --frame or --frames).
    #[arg(long, env = "TRE_LOADTEST_SYNTH_SIZE", default_value_t = 256)]
    pub synth_size: usize,
    /// Open loop: requests per second at constant intended send times. Without it: closed loop.
    #[arg(long, env = "TRE_LOADTEST_RATE", conflicts_with = "sweep")]
    pub rate: Option<f64>,
    /// Closed loop: concurrent clients. WebSocket open loop: connections, used round robin.
    #[arg(long, env = "TRE_LOADTEST_CONNECTIONS", default_value_t = 1)]
    pub connections: usize,
    /// Open loop: most requests outstanding; a request due beyond it is not sent and counts as
    /// client_saturated.
    #[arg(long, env = "TRE_LOADTEST_MAX_IN_FLIGHT", default_value_t = 256)]
    pub max_in_flight: usize,
    /// Measured seconds (per rate with --sweep). Default 10 unless --requests is given.
    #[arg(long, env = "TRE_LOADTEST_DURATION")]
    pub duration: Option<f64>,
    /// Measured requests; the run stops at --duration or --requests, whichever comes first.
    #[arg(long, env = "TRE_LOADTEST_REQUESTS")]
    pub requests: Option<u64>,
    /// Seconds of load before the measured window, left out of every number.
    #[arg(long, env = "TRE_LOADTEST_WARMUP", default_value_t = 0.0)]
    pub warmup: f64,
    /// Time one request may take before it counts as a timeout error, milliseconds.
    #[arg(long, env = "TRE_LOADTEST_TIMEOUT_MS", default_value_t = 30_000)]
    pub timeout_ms: u64,
    /// Open-loop rates to run one after the other (e.g. 5,10,15), each for --duration; prints a
    /// row per rate and the knee.
    #[arg(long, env = "TRE_LOADTEST_SWEEP", value_delimiter = ',')]
    pub sweep: Vec<f64>,
    /// Objective on the p99 latency of results, milliseconds (the sweep's knee).
    #[arg(long, env = "TRE_LOADTEST_SLO_MS", default_value_t = 150.0)]
    pub slo_ms: f64,
    /// Write the report (or the sweep) as JSON to this file.
    #[arg(long, env = "TRE_LOADTEST_JSON")]
    pub json: Option<PathBuf>,
    /// Write an SVG latency plot to this file.
    #[arg(long, env = "TRE_LOADTEST_PLOT")]
    pub plot: Option<PathBuf>,
    /// Compare with an earlier run's --json report: key numbers side by side with ratios.
    #[arg(long, env = "TRE_LOADTEST_COMPARE")]
    pub compare: Option<PathBuf>,
}

/// Options that make no run.
#[derive(Debug, thiserror::Error)]
pub enum ArgsError {
    /// Seconds that are no duration (negative, not finite, too large).
    #[error("--{option} {seconds}: not a duration")]
    Seconds {
        /// The option.
        option: &'static str,
        /// What it was given.
        seconds: f64,
        /// Why.
        #[source]
        source: TryFromFloatSecsError,
    },
    /// A file that does not read.
    #[error("reading {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A `--compare` file that is not a single run's report.
    #[error("{}: not a tre loadtest --json report of a single run", path.display())]
    NotAReport {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: serde_json::Error,
    },
    /// `--compare` with `--sweep`.
    #[error("--compare works on a single run, not with --sweep")]
    CompareSweep,
    /// An output that would replace an input.
    #[error(transparent)]
    Overwrite(#[from] tre_io::paths::WouldOverwrite),
    /// The camera file, or an output that could not be written.
    #[error(transparent)]
    Io(#[from] IoError),
    /// A setting the load test refuses ([`LoadConfig::validate`]).
    #[error(transparent)]
    Config(#[from] LoadError),
}

impl LoadtestArgs {
    /// The checked configuration: the frames and depth to send, the service's base URL and
    /// what every frame asks for ([`ask`](Self::ask)), the load and its window.
    ///
    /// # Errors
    ///
    /// [`ArgsError`].
    pub fn config(&self) -> Result<LoadConfig, ArgsError> {
        let frames = if let Some(dir) = &self.frames {
            LoadSource::Dir(dir.clone())
        } else if !self.frame.is_empty() {
            LoadSource::Files(self.frame.clone())
        } else {
            LoadSource::Synthetic {
                size: (self.synth_size, self.synth_size),
            }
        };
        let duration = match (self.duration, self.requests) {
            (None, None) => Some(Duration::from_secs(10)),
            (d, _) => d.map(|d| seconds("duration", d)).transpose()?,
        };
        let (url, ask) = self.ask()?;
        let depth = if let Some(dir) = &self.depth_dir {
            Some(LoadSource::Dir(dir.clone()))
        } else if !self.depth.is_empty() {
            Some(LoadSource::Files(self.depth.clone()))
        } else {
            None
        };
        let depth_only = depth.is_some() && self.frame.is_empty() && self.frames.is_none();
        let cfg = LoadConfig {
            url,
            api_key: self.api_key.clone(),
            ca_cert: self.ca_cert.clone(),
            allow_remote: self.allow_remote,
            protocol: self.protocol,
            load: self
                .rate
                .map_or(Load::Closed, |rate_per_s| Load::Open { rate_per_s }),
            connections: self.connections,
            max_in_flight: self.max_in_flight,
            duration,
            requests: self.requests,
            warmup: seconds("warmup", self.warmup)?,
            timeout: Duration::from_millis(self.timeout_ms),
            frames,
            depth,
            depth_only,
            ask,
        };
        cfg.validate()?;
        if !self.sweep.is_empty() && self.compare.is_some() {
            return Err(ArgsError::CompareSweep);
        }
        Ok(cfg)
    }

    /// The service's base URL and what every frame asks for: a query on --url
    /// (`…/v1/roughness?normals=ls&outputs=slope`, as curl is given it) goes with every HTTP
    /// request, the endpoint's path is dropped, and the camera file is read as `tre infer`
    /// reads it.
    ///
    /// # Errors
    ///
    /// [`ArgsError::Io`] or [`ArgsError::Read`] for a camera file that does not read.
    pub fn ask(&self) -> Result<(String, Ask), ArgsError> {
        let (url, query) = match self.url.split_once('?') {
            Some((base, q)) => (base.to_owned(), q.to_owned()),
            None => (self.url.clone(), String::new()),
        };
        let url = ["/v1/roughness", "/v1/stream"]
            .iter()
            .find_map(|e| url.strip_suffix(e))
            .unwrap_or(&url)
            .to_owned();
        let camera = match &self.camera {
            Some(path) => {
                let (cam, _) = tre_io::read_camera(path)?;
                let json = std::fs::read(path).map_err(|source| ArgsError::Read {
                    path: path.clone(),
                    source,
                })?;
                Some((json, cam))
            }
            None => None,
        };
        let ask = Ask {
            mode: self.mode,
            camera,
            sensor: self.sensor,
            normals: self.normals,
            dsac_hypotheses: self.dsac_hypotheses,
            traversal: self.traversal,
            query,
        };
        Ok((url, ask))
    }

    /// Refuses, before any load, a `--json` or `--plot` that would replace an input.
    ///
    /// # Errors
    ///
    /// [`ArgsError::Overwrite`].
    pub fn check_outputs(&self) -> Result<(), ArgsError> {
        let outputs: Vec<&Path> = [&self.json, &self.plot]
            .into_iter()
            .flatten()
            .map(PathBuf::as_path)
            .collect();
        let inputs: Vec<&Path> = self
            .frame
            .iter()
            .chain(&self.frames)
            .chain(&self.depth)
            .chain(&self.depth_dir)
            .chain(&self.camera)
            .map(PathBuf::as_path)
            .collect();
        Ok(tre_io::paths::refuse_overwriting(&outputs, &inputs)?)
    }

    /// The `--compare` report, if one is given.
    ///
    /// # Errors
    ///
    /// [`ArgsError::Read`] or [`ArgsError::NotAReport`].
    pub fn compared(&self) -> Result<Option<Report>, ArgsError> {
        let Some(path) = &self.compare else {
            return Ok(None);
        };
        let read = |source| ArgsError::Read {
            path: path.clone(),
            source,
        };
        let text = std::fs::read_to_string(path).map_err(read)?;
        let report = Report::from_json(&text).map_err(|source| ArgsError::NotAReport {
            path: path.clone(),
            source,
        })?;
        Ok(Some(report))
    }

    /// Writes the JSON and the plot (made only if asked for) to the files given.
    ///
    /// # Errors
    ///
    /// [`ArgsError::Io`] when one cannot be written.
    pub fn write(&self, json: &str, plot: impl FnOnce() -> String) -> Result<(), ArgsError> {
        if let Some(path) = &self.json {
            tre_io::paths::write_text(path, json)?;
        }
        if let Some(path) = &self.plot {
            tre_io::paths::write_text(path, &plot())?;
        }
        Ok(())
    }
}

/// `seconds` of option `option` as a duration.
fn seconds(option: &'static str, seconds: f64) -> Result<Duration, ArgsError> {
    Duration::try_from_secs_f64(seconds).map_err(|source| ArgsError::Seconds {
        option,
        seconds,
        source,
    })
}
