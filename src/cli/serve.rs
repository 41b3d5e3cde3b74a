//! `tre serve`: the HTTP and WebSocket service.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{bail, Context};
use clap::{Args, ValueEnum};

use super::options::{dsac_hypotheses_arg, find_models};
use crate::io;
use crate::model::{cores, ExecutionProvider, SessionConfig};
use crate::pipeline::{NormalsMethod, DEFAULT_DSAC_HYPOTHESES};
use crate::server::request::FrameDefaults;
use crate::server::{serve_until_signal, ServeConfig};

/// Execution provider of the ONNX Runtime sessions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum ProviderArg {
    /// ONNX Runtime's CPU kernels.
    Cpu,
    /// NVIDIA CUDA (needs a build with `--features cuda` and a GPU build of ONNX Runtime).
    Cuda,
    /// NVIDIA TensorRT (needs a build with `--features tensorrt` and a GPU build of ONNX Runtime).
    Tensorrt,
}

/// Serve roughness over HTTP (`POST /v1/roughness`) and WebSocket (`GET /v1/stream`).
#[derive(Debug, Args)]
pub(crate) struct Serve {
    /// Address to listen on (port 0: any free port; the address is printed on stdout). The
    /// default is loopback only; to serve a network, give its address (and an --api-key).
    #[arg(long, env = "TRE_ADDR", default_value = "127.0.0.1:8080")]
    pub addr: SocketAddr,
    /// Folder with manifest.json and the ONNX models. When not given: TRE_MODELS, then
    /// models/ beside the executable, ../share/tre/models relative to it, then models/ in the
    /// working directory.
    #[arg(long, env = "TRE_MODELS")]
    pub models: Option<PathBuf>,
    /// Inference worker threads, each with its own sessions (0: one per core).
    #[arg(long, env = "TRE_WORKERS", default_value_t = 0)]
    pub workers: usize,
    /// ONNX Runtime threads per operator in each worker (0: cores / workers, at least 1).
    #[arg(long, env = "TRE_ORT_THREADS", default_value_t = 0)]
    pub ort_threads: usize,
    /// Execution provider.
    #[arg(long, env = "TRE_PROVIDER", value_enum, default_value = "cpu")]
    pub provider: ProviderArg,
    /// GPU index for the cuda and tensorrt providers.
    #[arg(long, env = "TRE_DEVICE_ID", default_value_t = 0)]
    pub device_id: i32,
    /// Frames that may wait for a worker; beyond, requests get 503 at once (0: 2 per worker).
    #[arg(long, env = "TRE_QUEUE", default_value_t = 0)]
    pub queue: usize,
    /// Largest request body, bytes: a number with an optional k, M or G suffix (KiB, MiB,
    /// GiB).
    #[arg(long, env = "TRE_MAX_BODY_BYTES", default_value = "32MiB", value_parser = io::units::parse_size)]
    pub max_body_bytes: usize,
    /// Largest image, pixels (checked from the header, before decoding). The costliest frame
    /// is depth-only in the geometric mode, which runs at the frame's own size: at 4 Mpx (the
    /// default) about 1.6 s of one worker and 0.6 GB resident; at 16 Mpx 7.4 s and 1.3 GB
    /// (docs/security.md). RGB frames run at the working size and cost far less.
    /// A number with an optional k, M or G suffix (binary: 4Mi = 4,194,304).
    #[arg(long, env = "TRE_MAX_PIXELS", default_value = "4Mi", value_parser = io::units::parse_size)]
    pub max_pixels: usize,
    /// Longest image side, pixels (checked from the header, before decoding; beyond: 413).
    #[arg(long, env = "TRE_MAX_SIDE", default_value_t = 8192)]
    pub max_side: usize,
    /// Largest ratio of an image's longer side to its shorter one (checked from the header,
    /// before decoding; beyond: 422). A 16777216×1 image otherwise costs seconds of resizing.
    #[arg(long, env = "TRE_MAX_ASPECT", default_value_t = 8)]
    pub max_aspect: usize,
    /// Time a client has to send a request's headers, milliseconds: one that sent part of them
    /// gets 408, an idle kept-alive connection is closed.
    #[arg(long, env = "TRE_HEADER_TIMEOUT_MS", default_value_t = 10_000)]
    pub header_timeout_ms: u64,
    /// Time a client has to send a request's body once its headers are in, milliseconds (then
    /// 408). Uploads hold no --max-concurrent place.
    #[arg(long, env = "TRE_BODY_TIMEOUT_MS", default_value_t = 20_000)]
    pub body_timeout_ms: u64,
    /// Least rate of a request's body, bytes a second, averaged over each 5 s from the headers
    /// on (the first 5 s are the grace): a body slower than this gets 408 at the end of the
    /// window, before --body-timeout-ms. 0 turns it off.
    #[arg(long, env = "TRE_MIN_BODY_RATE", default_value_t = 1024)]
    pub min_body_rate: u64,
    /// API key: every route and the stream upgrade except /healthz and /readyz then want
    /// `Authorization: Bearer KEY` (401 without). Prefer the environment to the command line.
    #[arg(long, env = "TRE_API_KEY", hide_env_values = true)]
    pub api_key: Option<String>,
    /// Browser origins allowed to call the service and open the stream, such as
    /// `https://ops.example` (repeat, or comma-separate; `*` allows any). Others get 403; a
    /// page the server itself serves (the demo) is same-origin and always allowed.
    #[arg(long, env = "TRE_ALLOW_ORIGIN", value_delimiter = ',')]
    pub allow_origin: Vec<String>,
    /// HTTP requests handled at once (counted once the body is in); beyond, 429 at once.
    #[arg(long, env = "TRE_MAX_CONCURRENT", default_value_t = 64)]
    pub max_concurrent: usize,
    /// Time one HTTP request may take once its body is in, the queue and the run, milliseconds
    /// (then 503 `timeout`).
    #[arg(long, env = "TRE_REQUEST_TIMEOUT_MS", default_value_t = 30_000)]
    pub request_timeout_ms: u64,
    /// Largest WebSocket message, bytes, with an optional k, M or G suffix (up to 4× this gets
    /// an error message; beyond, the connection is closed with 1009).
    #[arg(long, env = "TRE_WS_MAX_MESSAGE_BYTES", default_value = "16MiB", value_parser = io::units::parse_size)]
    pub ws_max_message_bytes: usize,
    /// Initial normals of frames that do not choose: dsac (the paper's method) or ls (faster;
    /// see docs/evaluation.md and docs/benchmarks.md). Requests override it with `normals=`.
    #[arg(long, env = "TRE_NORMALS", value_enum, default_value = "dsac")]
    pub normals: NormalsMethod,
    /// DSAC hypotheses per pixel, 1 to 64: 12 as the neighbour net was trained; fewer are
    /// faster at some cost in accuracy (see docs/evaluation.md).
    #[arg(long, env = "TRE_DSAC_HYPOTHESES", default_value_t = DEFAULT_DSAC_HYPOTHESES,
          value_parser = dsac_hypotheses_arg())]
    pub dsac_hypotheses: u32,
    /// WebSocket streams open at once; beyond, the upgrade gets 429 at once.
    #[arg(long, env = "TRE_MAX_STREAMS", default_value_t = 64)]
    pub max_streams: usize,
    /// A stream whose client sends nothing (no message, no answer to the server's pings) for
    /// this long is closed, milliseconds; its `--max-streams` place is freed.
    #[arg(long, env = "TRE_WS_IDLE_TIMEOUT_MS", default_value_t = 60_000)]
    pub ws_idle_timeout_ms: u64,
    /// A connection whose client takes no byte of an answer for this long (it stopped reading,
    /// like a hung process with its socket open) is closed, milliseconds: HTTP requests and
    /// streams alike. A slow client that keeps reading is not affected.
    #[arg(long, env = "TRE_STALL_TIMEOUT_MS", default_value_t = 30_000)]
    pub stall_timeout_ms: u64,
    /// HTTP connections open at once (a stream counts until its upgrade, then against
    /// `--max-streams`); beyond, requests get 503 and the connection is closed. Each open
    /// connection takes a file descriptor: `ulimit -n` should allow twice this plus
    /// `--max-streams` and about 100 more.
    #[arg(long, env = "TRE_MAX_CONNECTIONS", default_value_t = 1024)]
    pub max_connections: usize,
    /// Seconds in-flight work may take to finish after SIGTERM or Ctrl-C.
    #[arg(long, env = "TRE_SHUTDOWN_GRACE_S", default_value_t = 30)]
    pub shutdown_grace_s: u64,
}

impl Serve {
    /// The checked service configuration.
    pub(crate) fn config(&self) -> anyhow::Result<ServeConfig> {
        let (workers, ort_threads) = self.threads();
        let cfg = ServeConfig {
            addr: self.addr,
            models: find_models(self.models.as_deref())?,
            workers,
            session: SessionConfig {
                intra_threads: ort_threads,
                provider: self.provider()?,
                ..SessionConfig::default()
            },
            queue: if self.queue == 0 {
                2 * workers
            } else {
                self.queue
            },
            max_body_bytes: self.max_body_bytes,
            max_pixels: self.max_pixels,
            max_side: self.max_side,
            max_aspect: self.max_aspect,
            header_timeout: Duration::from_millis(self.header_timeout_ms),
            body_timeout: Duration::from_millis(self.body_timeout_ms),
            min_body_rate: self.min_body_rate,
            api_key: self.api_key.clone().filter(|k| !k.is_empty()),
            allow_origins: self.allow_origin.clone(),
            max_concurrent: self.max_concurrent,
            request_timeout: Duration::from_millis(self.request_timeout_ms),
            ws_max_message_bytes: self.ws_max_message_bytes,
            max_streams: self.max_streams,
            ws_idle_timeout: Duration::from_millis(self.ws_idle_timeout_ms),
            stall_timeout: Duration::from_millis(self.stall_timeout_ms),
            max_connections: self.max_connections,
            shutdown_grace: Duration::from_secs(self.shutdown_grace_s),
            defaults: FrameDefaults {
                normals: self.normals,
                dsac_hypotheses: self.dsac_hypotheses,
            },
        };
        cfg.validate(cores())?;
        Ok(cfg)
    }

    /// Inference workers and ONNX Runtime threads per worker: 0 takes every core, shared out.
    fn threads(&self) -> (usize, usize) {
        let cores = cores();
        let workers = if self.workers == 0 {
            cores
        } else {
            self.workers
        };
        let ort_threads = if self.ort_threads == 0 {
            (cores / workers).max(1)
        } else {
            self.ort_threads
        };
        (workers, ort_threads)
    }

    fn provider(&self) -> anyhow::Result<ExecutionProvider> {
        let _ = self.device_id;
        Ok(match self.provider {
            ProviderArg::Cpu => ExecutionProvider::Cpu,
            #[cfg(feature = "cuda")]
            ProviderArg::Cuda => ExecutionProvider::Cuda { device_id: self.device_id },
            #[cfg(feature = "tensorrt")]
            ProviderArg::Tensorrt => ExecutionProvider::TensorRt { device_id: self.device_id },
            #[allow(unreachable_patterns)]
            other => bail!("--provider {other:?}: this build of tre lacks the cargo feature for it (build with --features cuda or tensorrt)"),
        })
    }

    /// Binds, prints `listening on http://ADDR` on stdout, and serves until SIGTERM or Ctrl-C.
    pub(crate) fn run(self) -> anyhow::Result<()> {
        let cfg = self.config()?;
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .thread_name("tre-http")
            .enable_all()
            .build()
            .context("starting the async runtime")?;
        let addr = cfg.addr;
        runtime
            .block_on(serve_until_signal(cfg, |a| {
                println!("listening on http://{a}");
            }))
            .with_context(|| format!("serving on {addr}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        serve: Serve,
    }

    fn parse(args: &[&str]) -> Result<ServeConfig, String> {
        let cli = Cli::try_parse_from(std::iter::once("tre").chain(args.iter().copied()))
            .map_err(|e| e.to_string())?;
        cli.serve.config().map_err(|e| format!("{e:#}"))
    }

    #[test]
    fn the_connection_limits_are_set_and_zero_is_refused() {
        let cfg = parse(&[]).unwrap();
        assert_eq!(cfg.ws_idle_timeout, Duration::from_secs(60));
        assert_eq!(cfg.stall_timeout, Duration::from_secs(30));
        assert_eq!(cfg.request_timeout, Duration::from_secs(30));
        assert_eq!(cfg.max_connections, 1024);
        let cfg = parse(&[
            "--ws-idle-timeout-ms",
            "1500",
            "--stall-timeout-ms",
            "700",
            "--request-timeout-ms",
            "250",
            "--max-connections",
            "3",
        ])
        .unwrap();
        assert_eq!(cfg.ws_idle_timeout, Duration::from_millis(1500));
        assert_eq!(cfg.stall_timeout, Duration::from_millis(700));
        assert_eq!(cfg.request_timeout, Duration::from_millis(250));
        assert_eq!(cfg.max_connections, 3);
        for flag in [
            "--ws-idle-timeout-ms",
            "--stall-timeout-ms",
            "--request-timeout-ms",
            "--max-connections",
        ] {
            let e = parse(&[flag, "0"]).unwrap_err();
            assert!(e.contains("must be positive") && e.contains(flag), "{e}");
        }
    }
}
