//! `tre client`: streams frames from a folder, a video file or a camera to `tre serve` over the
//! WebSocket, writes each result's roughness map and a per-frame CSV, and prints a live summary.
//! The options are [`ClientArgs`]; [`crate::client::recorder`] does the recording.

use anyhow::Context;
use clap::Args;

use crate::client::recorder::{record, RecorderConfig};
use crate::client::ClientArgs;

/// Stream frames to `tre serve` and write the roughness maps it sends back.
#[derive(Debug, Args)]
pub(crate) struct Client {
    /// The session, the frames and the outputs.
    #[command(flatten)]
    pub args: ClientArgs,
}

impl Client {
    /// Streams the frames, writes the maps and the CSV, prints the summaries.
    pub(crate) fn run(self) -> anyhow::Result<()> {
        run(self.args.config()?)
    }
}

/// Records `cfg` on its own async runtime, printing the recorder's notices on stderr; Ctrl-C
/// stops the sending. An error if no result came back.
pub(crate) fn run(cfg: RecorderConfig) -> anyhow::Result<()> {
    // The recording's folder, made as `--out` is.
    if let Some(path) = &cfg.mcap {
        crate::io::paths::create_parent(path)?;
    }
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("tre-client")
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    let stop = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    runtime.block_on(record(&cfg, stop, |notice| eprintln!("{notice}")))?;
    if let Some(path) = &cfg.mcap {
        eprintln!("recorded {}", path.display());
    }
    Ok(())
}
