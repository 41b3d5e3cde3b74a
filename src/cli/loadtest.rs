//! `tre loadtest`: open- or closed-loop load on a running `tre serve` over HTTP or WebSocket,
//! with a text report, JSON, an SVG latency plot, a comparison with an earlier run and rate
//! sweeps that find the knee.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{bail, Context};
use clap::{Args, ValueEnum};

use crate::io;
use crate::loadtest::report::{self, SweepReport};
use crate::loadtest::{run, svg, sweep, Ask, Load, LoadConfig, LoadSource, Protocol, Report};

/// Interface to load.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum ProtocolArg {
    /// `POST /v1/roughness`, one frame per request.
    Http,
    /// `GET /v1/stream` (WebSocket, protobuf frames).
    Ws,
}

/// Load a running `tre serve` and report throughput and latency (coordinated omission
/// corrected in open loop).
///
/// Open loop (`--rate`): requests at constant intended times, latency counted from the intended
/// time. Closed loop (no `--rate`): `--connections` clients that each wait for their answer.
/// Safety: only loopback addresses are loaded unless you give the address yourself in `--url`;
/// a host name that resolves to a non-loopback address is refused unless `--allow-remote`.
#[derive(Debug, Args)]
pub(crate) struct Loadtest {
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
    pub ca_cert: Option<std::path::PathBuf>,
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
    pub protocol: ProtocolArg,
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
    pub mode: Option<crate::pipeline::Mode>,
    /// Depth sensor noise model, overriding the camera's (as `tre infer --sensor`).
    #[arg(long, env = "TRE_SENSOR", value_parser = super::infer::parse_sensor)]
    pub sensor: Option<crate::roughness::noise::SensorNoise>,
    /// Initial normals asked for: dsac or ls; default: the server's.
    #[arg(long, env = "TRE_LOADTEST_NORMALS", value_enum)]
    pub normals: Option<crate::pipeline::NormalsMethod>,
    /// DSAC hypotheses per pixel asked for, 1 to 64; default: the server's.
    #[arg(long, env = "TRE_LOADTEST_DSAC_HYPOTHESES", value_parser = super::options::dsac_hypotheses_arg())]
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

fn seconds(name: &str, s: f64) -> anyhow::Result<Duration> {
    Duration::try_from_secs_f64(s).with_context(|| format!("--{name} {s}: not a duration"))
}

impl Loadtest {
    /// The service's base URL and what every frame asks for: a query on --url
    /// (`…/v1/roughness?normals=ls&outputs=slope`, as curl is given it) goes with every HTTP
    /// request, the endpoint's path is dropped, and the camera file is read as `tre infer`
    /// reads it.
    fn ask(&self) -> anyhow::Result<(String, Ask)> {
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
                let (cam, _) = io::read_camera(path)?;
                let json =
                    std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
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

    /// The checked configuration.
    pub(crate) fn config(&self) -> anyhow::Result<LoadConfig> {
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
            protocol: match self.protocol {
                ProtocolArg::Http => Protocol::Http,
                ProtocolArg::Ws => Protocol::Ws,
            },
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
            bail!("--compare works on a single run, not with --sweep");
        }
        Ok(cfg)
    }

    /// Runs the load, prints the report and writes the files asked for.
    pub(crate) fn run(self) -> anyhow::Result<()> {
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
        crate::io::paths::refuse_overwriting(&outputs, &inputs)?;
        let cfg = self.config()?;
        let old = self.compare.as_deref().map(read_report).transpose()?;
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .thread_name("tre-loadtest")
            .enable_all()
            .build()
            .context("starting the async runtime")?;
        if self.sweep.is_empty() {
            let r = runtime.block_on(run(&cfg))?;
            print!("{}", report::text(&r));
            if let Some(old) = &old {
                println!("\ncompared with {}:", self.compare_path());
                print!("{}", report::compare(old, &r));
            }
            self.write(&r.to_json(), || svg::plot_run(&r))?;
            no_result_is_a_failure(r.ok, r.requests)
        } else {
            // The header comes with the first row: a sweep refused before it runs prints none.
            let mut header = Some(report::sweep_header());
            let sw: SweepReport = runtime.block_on(sweep(&cfg, &self.sweep, self.slo_ms, |r| {
                if let Some(h) = header.take() {
                    println!("{h}");
                }
                println!("{}", report::sweep_row(r));
            }))?;
            print!("{}", report::sweep_summary(&sw));
            self.write(&sw.to_json(), || svg::plot_sweep(&sw))?;
            let (ok, requests) = sw
                .rows
                .iter()
                .fold((0, 0), |(o, n), r| (o + r.ok, n + r.requests));
            no_result_is_a_failure(ok, requests)
        }
    }

    fn compare_path(&self) -> String {
        self.compare
            .as_deref()
            .map_or_else(String::new, |p| p.display().to_string())
    }

    /// Writes the JSON and the plot if asked for.
    fn write(&self, json: &str, plot: impl FnOnce() -> String) -> anyhow::Result<()> {
        if let Some(path) = &self.json {
            crate::io::paths::write_text(path, json)?;
        }
        if let Some(path) = &self.plot {
            crate::io::paths::write_text(path, &plot())?;
        }
        Ok(())
    }
}

/// A load test in which no request got a roughness map measured nothing about the service: it
/// fails (after its report is printed and written), so that a script does not take it for a
/// result.
fn no_result_is_a_failure(ok: u64, requests: u64) -> anyhow::Result<()> {
    if ok == 0 {
        anyhow::bail!(
            "none of the {requests} requests got a roughness map: is the target a running tre \
             serve (see the errors above)?"
        );
    }
    Ok(())
}

fn read_report(path: &Path) -> anyhow::Result<Report> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    Report::from_json(&text).with_context(|| {
        format!(
            "{}: not a tre loadtest --json report of a single run",
            path.display()
        )
    })
}
