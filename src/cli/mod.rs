//! Command-line subcommands, one file each; `main.rs` only parses and dispatches.

pub mod annotate;
pub mod calibrate;
pub mod client;
pub mod eval;
pub mod infer;
pub mod loadtest;
pub mod map;
pub mod options;
pub mod serve;
pub mod synth;

use clap::{Parser, Subcommand};

/// Terrain roughness estimation for robots (TRENet).
#[derive(Debug, Parser)]
#[command(name = "tre", version, about)]
pub struct Cli {
    /// Log filter (tracing's env-filter syntax), e.g. `info` or `tre=debug`.
    #[arg(long, env = "TRE_LOG", default_value = "info,ort=warn", global = true)]
    pub log: String,
    /// Logs as JSON lines (one object per event) instead of text.
    #[arg(long, env = "TRE_LOG_JSON", global = true)]
    pub log_json: bool,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Annotate a depth frame with ground-truth roughness (annotation spec v1).
    Annotate(annotate::Annotate),
    /// Generate a synthetic terrain dataset with exact ground truth.
    Synth(synth::Synth),
    /// Estimate roughness for one frame (RGB, RGB-D or depth only).
    Infer(infer::Infer),
    /// Score roughness, normals and depth on a synthetic dataset's split (--tables for the
    /// paper's Tables II, IV and V), or every mode on real RGB-D frames against the spec on
    /// the same sensor depth (--real).
    Eval(eval::Eval),
    /// Fit every mode's calibrated 90% roughness intervals on real validation frames
    /// (models/uncertainty.json; docs/uncertainty.md).
    Calibrate(calibrate::Calibrate),
    /// Fuse a sequence of depth frames (with their poses) into a gravity-aligned roughness grid
    /// map, written layer by layer (docs/map.md).
    Map(map::Map),
    /// Serve roughness over HTTP and a WebSocket stream.
    Serve(serve::Serve),
    /// Stream frames (a folder, a video or a camera) to `tre serve` over the WebSocket and
    /// write the roughness maps that come back.
    Client(client::Client),
    /// Load a running `tre serve` over HTTP or WebSocket and report throughput and latency.
    ///
    /// Open loop (`--rate`): requests at constant intended times, latency counted from the
    /// intended time (coordinated omission corrected). Closed loop (no `--rate`):
    /// `--connections` clients that each wait for their answer. `--sweep` runs several rates
    /// and finds the knee. Safety: only loopback addresses are loaded unless you write the
    /// address yourself in `--url`; a host name that resolves to a non-loopback address is
    /// refused unless `--allow-remote` is given.
    Loadtest(loadtest::Loadtest),
}

impl Command {
    /// Runs the chosen subcommand.
    pub fn run(self) -> anyhow::Result<()> {
        match self {
            Command::Annotate(cmd) => cmd.run(),
            Command::Synth(cmd) => cmd.run(),
            Command::Infer(cmd) => cmd.run(),
            Command::Eval(cmd) => cmd.run(),
            Command::Calibrate(cmd) => cmd.run(),
            Command::Map(cmd) => cmd.run(),
            Command::Serve(cmd) => cmd.run(),
            Command::Client(cmd) => cmd.run(),
            Command::Loadtest(cmd) => cmd.run(),
        }
    }
}

/// The finite values of a roughness map, sorted ascending (for the summaries' quantiles).
fn finite_sorted(map: &crate::geometry::Grid<f64>) -> Vec<f64> {
    let mut v: Vec<f64> = map
        .as_slice()
        .iter()
        .copied()
        .filter(|r| r.is_finite())
        .collect();
    v.sort_by(f64::total_cmp);
    v
}

/// Writes `text` to `path`, creating its folder if missing.
fn write_file(path: &std::path::Path, text: &str) -> anyhow::Result<()> {
    use anyhow::Context;
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}

/// `path` as the file system names it: its longest existing ancestor made canonical, with the
/// rest appended (so that `out.png` and `./dir/../out.png` compare equal before either exists).
fn resolved(path: &std::path::Path) -> std::path::PathBuf {
    let path = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    for base in path.ancestors() {
        if let Ok(canonical) = base.canonicalize() {
            let rest = path.strip_prefix(base).unwrap_or(std::path::Path::new(""));
            return canonical.join(rest);
        }
    }
    path
}

/// Refuses, before any work, to write an output over one of the command's inputs, or (for an
/// input that is a folder) inside it: `tre infer rgb.png -o rgb.png` would replace the frame,
/// `tre eval --json DATA/dataset.json` the dataset's manifest.
fn refuse_overwriting(
    outputs: &[&std::path::Path],
    inputs: &[&std::path::Path],
) -> anyhow::Result<()> {
    for out in outputs {
        let o = resolved(out);
        for input in inputs {
            let i = resolved(input);
            if o == i || (i.is_dir() && o.starts_with(&i)) {
                anyhow::bail!(
                    "{} would be written over or inside the input {}; choose another output path",
                    out.display(),
                    input.display()
                );
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_may_not_replace_inputs() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("rgb.png");
        std::fs::write(&input, b"x").unwrap();
        let data = dir.path().join("data");
        std::fs::create_dir(&data).unwrap();
        let same = dir.path().join("data/../rgb.png");
        assert!(refuse_overwriting(&[&same], &[&input]).is_err());
        assert!(refuse_overwriting(&[&data.join("new/report.json")], &[&data]).is_err());
        let elsewhere = dir.path().join("out.png");
        assert!(refuse_overwriting(&[&elsewhere], &[&input, &data]).is_ok());
    }
}
