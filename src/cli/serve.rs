//! `tre serve`: the HTTP and WebSocket service. Its options are the settings of the service
//! ([`ServeConfig`], whose doc comments are their help).

use anyhow::Context;
use clap::Args;

use crate::model::cores;
use crate::server::{serve_until_signal, ServeConfig};

/// Serve roughness over HTTP (`POST /v1/roughness`) and WebSocket (`GET /v1/stream`).
#[derive(Debug, Args)]
pub(crate) struct Serve {
    /// The service's settings.
    #[command(flatten)]
    pub config: ServeConfig,
}

impl Serve {
    /// Resolves the settings, binds, prints `listening on http://ADDR` on stdout, and serves
    /// until SIGTERM or Ctrl-C.
    pub(crate) fn run(self) -> anyhow::Result<()> {
        let cfg = self.config.resolve(cores())?;
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
