//! `tre calibrate`: fits the calibrated roughness intervals of every mode on real frames of a
//! split (docs/uncertainty.md) and writes them beside the models (`uncertainty.json`).
//!
//! Samples: every `--stride`-th pixel (in x and y) with spec roughness. `rgb`: the reading,
//! its 7×7 maximum and the depth net's depth, against the spec on the sensor depth. `rgbd`:
//! the same with the sensor model's uncertainty instead of depth. `geometric`: the spec's own
//! reading and uncertainty, against the spec of the same surface in the previous frame of a
//! sequence with poses (pixels the two frames share, docs/uncertainty.md).

use std::path::PathBuf;

use clap::Args;

use tre_eval::calibrate::{fit_tables, Samples};
use tre_eval::real::{self, RealFrame};

use super::options::StageArgs;
use crate::pipeline::{models_key, GeometricMethod, Mode, PipelineConfig};
use crate::roughness::interval::{Calibration, CALIBRATION_FILE};
use crate::roughness::noise::SensorNoise;

/// Fit every mode's 90% roughness intervals on real frames.
#[derive(Debug, Args)]
pub(crate) struct Calibrate {
    /// Folders of real RGB-D frames (as `tre eval --real` reads them); give it once per
    /// folder.
    #[arg(long, required = true)]
    pub real: Vec<PathBuf>,
    /// The splits file (train / val / test by sequence).
    #[arg(long, default_value = "models/real_splits.json")]
    pub real_splits: PathBuf,
    /// The split to fit on. Never the test split: the figures of `tre eval` are read there.
    #[arg(long, default_value = "val")]
    pub split: String,
    /// Noise model of sequences whose intrinsics.json names none.
    #[arg(long, default_value = "kinect_v1", value_parser = parse_sensor)]
    pub sensor: SensorNoise,
    /// Take every N-th pixel in x and in y as a sample.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u16).range(1..=64))]
    pub stride: u16,
    /// Output file (default: uncertainty.json in the models folder).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Pipeline switches and models.
    #[command(flatten)]
    pub stages: StageArgs,
}

/// `--sensor`: a preset name or `a,b,c`.
fn parse_sensor(s: &str) -> Result<SensorNoise, String> {
    s.parse()
}

impl Calibrate {
    /// Runs the command.
    pub(crate) fn run(self) -> anyhow::Result<()> {
        if self.split == "test" {
            anyhow::bail!(
                "--split test: the intervals are judged on the test frames; fit them on val"
            );
        }
        let frames = real::frames_of(&self.real, Some(&self.real_splits), &self.split, None)?;
        let base = self.stages.config(Mode::Rgb);
        let cfgs: Vec<PipelineConfig> = [Mode::Rgb, Mode::Rgbd, Mode::Geometric]
            .into_iter()
            .map(|mode| PipelineConfig {
                mode,
                geometric: GeometricMethod::Spec,
                ..base
            })
            .collect();
        let mut pipeline = self.stages.pipeline(&cfgs)?;
        let models = pipeline
            .models()
            .map_or_else(String::new, |m| models_key(m.manifest()));
        let samples = Samples::collect(
            &frames,
            &mut pipeline,
            &cfgs,
            &self.sensor,
            usize::from(self.stride),
        )?;
        let (tables, lines) = fit_tables(&samples);
        lines.iter().for_each(|l| println!("{l}"));
        let cal = Calibration {
            format: 1,
            note: format!(
                "tre calibrate, split {:?} of {}, every {}th pixel: rgb and rgbd against the spec \
                 on the same sensor depth; geometric against the spec of the same surface in the \
                 previous frame of a sequence with poses",
                self.split,
                self.real_splits.display(),
                self.stride
            ),
            frames: frames.iter().map(RealFrame::name).collect(),
            models,
            tables,
        };
        let out = match &self.out {
            Some(p) => p.clone(),
            None => {
                super::options::find_models(self.stages.models.as_deref())?.join(CALIBRATION_FILE)
            }
        };
        crate::io::paths::write_text(&out, &serde_json::to_string_pretty(&cal)?)?;
        println!("wrote {}", out.display());
        Ok(())
    }
}
