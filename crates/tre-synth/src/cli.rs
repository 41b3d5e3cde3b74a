//! The options of `tre synth` (the `cli` feature): [`SynthConfig`]'s own, and the frame size.

use crate::dataset::SynthConfig;

/// Generate a synthetic terrain dataset.
#[derive(Debug, Clone, clap::Args)]
pub struct SynthArgs {
    /// The dataset's settings.
    #[command(flatten)]
    pub config: SynthConfig,
    /// Image width, pixels.
    #[arg(long, default_value_t = 512)]
    pub width: usize,
    /// Image height, pixels.
    #[arg(long, default_value_t = 512)]
    pub height: usize,
}

impl From<SynthArgs> for SynthConfig {
    fn from(args: SynthArgs) -> Self {
        Self {
            size: (args.width, args.height),
            ..args.config
        }
    }
}
