//! `tre calibrate`: fits the calibrated roughness intervals of every mode on real frames of a
//! split (docs/uncertainty.md) and writes them beside the models (`uncertainty.json`).
//!
//! Samples: every `--stride`-th pixel (in x and y) with spec roughness. `rgb`: the reading,
//! its 7×7 maximum and the depth net's depth, against the spec on the sensor depth. `rgbd`:
//! the same with the sensor model's uncertainty instead of depth. `geometric`: the spec's own
//! reading and uncertainty, against the spec of the same surface in the previous frame of a
//! sequence with poses (pixels the two frames share, docs/uncertainty.md).

use clap::Args;
use tre_eval::CalibrateArgs;

/// Fit every mode's 90% roughness intervals on real frames.
#[derive(Debug, Args)]
pub(crate) struct Calibrate {
    /// The frames, the split, the pipeline and the output.
    #[command(flatten)]
    pub args: CalibrateArgs,
}

impl Calibrate {
    /// Fits the intervals, prints the fit and writes the file.
    pub(crate) fn run(self) -> anyhow::Result<()> {
        let fitted = self.args.fit()?;
        fitted.lines.iter().for_each(|l| println!("{l}"));
        let out = self.args.write(&fitted.calibration)?;
        println!("wrote {}", out.display());
        Ok(())
    }
}
