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

/// The log filter `spec` with the DDS libraries' chatter (`rustdds`: a warning per large
/// datagram; `ros2_client`: two lines per topic made) at `error`, each unless `spec` names it.
fn log_filter(spec: &str) -> String {
    let mut out = spec.to_owned();
    for target in ["rustdds", "ros2_client"] {
        if !spec.contains(target) {
            out += &format!(",{target}=error");
        }
    }
    out
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let filter = tracing_subscriber::EnvFilter::try_new(log_filter(&cli.log))
        .unwrap_or_else(|_| log_filter("info,ort=warn").into());
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

#[cfg(test)]
mod tests {
    use super::log_filter;

    #[test]
    fn the_dds_library_logs_errors_only_unless_asked() {
        assert_eq!(
            log_filter("info,ort=warn"),
            "info,ort=warn,rustdds=error,ros2_client=error"
        );
        assert_eq!(log_filter("debug"), "debug,rustdds=error,ros2_client=error");
        assert_eq!(
            log_filter("info,rustdds=debug"),
            "info,rustdds=debug,ros2_client=error"
        );
    }
}
