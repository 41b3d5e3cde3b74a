//! `tre`: parses arguments, sets up tracing and dispatches to a subcommand in `tre::cli`.

mod cli;

// The layers, as the subcommands name them (`crate::io`, `crate::pipeline`, ...).
#[cfg(feature = "ros2")]
use tre::ros2;
use tre::{
    client, geometry, io, kinds, loadtest, map, model, pipeline, record, roughness, server, synth,
};

use clap::Parser;
use cli::Cli;

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let filter =
        tracing_subscriber::EnvFilter::try_new(&cli.log).unwrap_or_else(|_| "info,ort=warn".into());
    // Colour only on a terminal: redirected logs carry no escape codes.
    let ansi = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let logs = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(ansi)
        .with_writer(std::io::stderr);
    if cli.log_json {
        logs.json().init();
    } else {
        logs.init();
    }
    match cli.command.run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
