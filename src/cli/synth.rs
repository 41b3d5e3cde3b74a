//! `tre synth`: generate a synthetic terrain dataset (RougE-style) with exact ground truth.

use std::time::Instant;

use clap::Args;

use crate::synth::dataset::{generate, SynthConfig};
use crate::synth::SynthArgs;

/// Generate a synthetic terrain dataset.
#[derive(Debug, Args)]
pub(crate) struct Synth {
    /// The dataset's settings.
    #[command(flatten)]
    pub args: SynthArgs,
}

impl Synth {
    /// Generates the dataset and prints its size and speed.
    pub(crate) fn run(self) -> anyhow::Result<()> {
        let cfg = SynthConfig::from(self.args);
        let start = Instant::now();
        let m = generate(&cfg)?;
        let secs = start.elapsed().as_secs_f64();
        let frames = m.counts.0 + m.counts.1;
        println!(
            "{} scenes, {frames} frames ({} train, {} test) in {secs:.1} s ({:.2} frames/s) → {}",
            m.scenes.len(),
            m.counts.0,
            m.counts.1,
            frames as f64 / secs,
            cfg.out.display()
        );
        Ok(())
    }
}
