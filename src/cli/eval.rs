//! `tre eval`: scores the pipeline (any mode and switches, or the end-to-end baseline) on a
//! split of a `tre synth` dataset against annotation spec v1: roughness RMSE, B-RMSE, F-RMSE;
//! normal angle errors; depth errors in rgb mode; mean time per stage. `--tables` runs every
//! row of the paper's Tables II, IV and V and prints them as markdown.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use clap::Args;
use tre_eval::synthetic::{self, DepthSource, RowSpec, SplitReport};
use tre_eval::{real, tables};

use super::options::StageArgs;
use crate::pipeline::{Mode, PipelineConfig};
use crate::roughness::noise::SensorNoise;

/// Score a method on a synthetic dataset's split, or every mode on real RGB-D frames.
#[derive(Debug, Args)]
pub(crate) struct Eval {
    /// Dataset folder written by `tre synth` (holds dataset.json).
    #[arg(long, required_unless_present = "real")]
    pub data: Option<PathBuf>,
    /// Real-frame benchmark: a folder of RGB-D frames with their intrinsics (one sequence
    /// folder with intrinsics.json, or a folder of them, as ../shared/data/real-rgbd). Every
    /// mode in --modes runs on each frame and is scored against annotation spec v1 on the same
    /// sensor depth; the geometric mode runs as the spec and as the surface-only baseline.
    /// Give it more than once to pool several folders (../shared/data/real-rgbd and
    /// ../shared/data/real-rgbd-2).
    #[arg(long, conflicts_with_all = ["data", "tables"])]
    pub real: Vec<PathBuf>,
    /// Real-frame benchmark: score only the frames of --split in this splits file
    /// (models/real_splits.json: train / val / test by sequence, docs/real-splits.md).
    #[arg(long, requires = "real")]
    pub real_splits: Option<PathBuf>,
    /// Real-frame benchmark: read every camera file as if it stated no mounting (pitch_deg,
    /// height_m), so that the modes run as for a camera of unknown mounting.
    #[arg(long, requires = "real")]
    pub no_mounting: bool,
    /// Floor boxes of the real frames (JSON, as tests/fixtures/real_floor.json): floor median
    /// and p90 per frame.
    #[arg(long, requires = "real")]
    pub floors: Option<PathBuf>,
    /// Modes, comma-separated: the real-frame benchmark runs each (default: rgb, rgbd and
    /// geometric); the synthetic split scores one (default: geometric).
    #[arg(long, alias = "modes", value_enum, value_delimiter = ',')]
    pub mode: Vec<Mode>,
    /// Real-frame benchmark: write a contact sheet PNG per frame into this folder (RGB | spec
    /// | each mode, one colour scale, and the three-state map).
    #[arg(long, requires = "real")]
    pub sheets: Option<PathBuf>,
    /// Real-frame benchmark: the depth sensor's noise model for the uncertainty and
    /// three-state maps when a sequence's intrinsics.json names none (a preset: kinect_v1,
    /// realsense_d435, azure_kinect, lidar, exact; or a,b,c for σ_z = a + b·z + c·z² mm).
    /// Unlike `tre infer --sensor` (no default), this has one: the shared real-rgbd frames are
    /// all Kinect v1 but name it in free text.
    #[arg(long, requires = "real", default_value = "kinect_v1", value_parser = parse_sensor)]
    pub sensor: SensorNoise,
    /// Pipeline switches and models.
    #[command(flatten)]
    pub stages: StageArgs,
    /// Split to score.
    #[arg(long, default_value = "test")]
    pub split: String,
    /// Score only the first N frames of the split.
    #[arg(long)]
    pub limit: Option<usize>,
    /// Run every row of the paper's Tables II, IV and V (ignores --mode and the switches).
    #[arg(long)]
    pub tables: bool,
    /// Also write the numbers as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Synthetic split: the depth the `rgbd` and `geometric` modes read, `exact` (depth.png)
    /// or `sensor` (depth_sensor.png, the frame's depth-sensor model, docs/synth.md). Ground
    /// truth is always the spec on the exact depth.
    #[arg(
        long,
        value_enum,
        default_value = "exact",
        env = "TRE_EVAL_DEPTH_SOURCE"
    )]
    pub depth_source: DepthSource,
}

/// `--sensor`: a preset name or `a,b,c`.
fn parse_sensor(s: &str) -> Result<SensorNoise, String> {
    s.parse()
}

impl Eval {
    /// Scores every frame of the split and prints the metrics (and the tables), or runs the
    /// real-frame benchmark.
    pub(crate) fn run(self) -> anyhow::Result<()> {
        if !self.real.is_empty() {
            return self.run_real(&self.real);
        }
        let data = self.data.clone().context("--data or --real is needed")?;
        if let Some(json) = &self.json {
            // The dataset's manifest and its scene folders are inputs; a report beside them
            // is fine.
            let inputs = synthetic::dataset_inputs(&data);
            let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
            crate::io::paths::refuse_overwriting(&[json], &inputs)?;
        }
        let dirs = synthetic::frame_dirs(&data, &self.split, self.limit)?;
        let specs = if self.tables {
            tables::row_specs(&self.stages.config(self.synthetic_mode()?))
        } else {
            let cfg = self.stages.config(self.synthetic_mode()?);
            vec![RowSpec {
                key: synthetic::row_key(&cfg),
                cfg,
            }]
        };
        let configs: Vec<PipelineConfig> = specs.iter().map(|s| s.cfg).collect();
        let mut pipeline = self.stages.pipeline(&configs)?;
        let rows = synthetic::score_split(&mut pipeline, &dirs, &specs, self.depth_source)?;
        println!(
            "{}, split {}, {} frames\n",
            data.display(),
            self.split,
            dirs.len()
        );
        if self.tables {
            println!("{}", tables::markdown(&rows));
        } else {
            rows.iter()
                .for_each(|r| print!("{}", synthetic::row_text(r)));
        }
        self.write_json(&data, dirs.len(), &rows)
    }

    /// The one mode of a synthetic run: `--mode`'s, geometric by default.
    fn synthetic_mode(&self) -> anyhow::Result<Mode> {
        match self.mode.as_slice() {
            [] => Ok(Mode::Geometric),
            [one] => Ok(*one),
            more => bail!(
                "--mode: the synthetic split scores one mode at a time, got {}",
                more.iter()
                    .map(ToString::to_string)
                    .collect::<Vec<_>>()
                    .join(",")
            ),
        }
    }

    /// The real-frame benchmark (`--real`): markdown on stdout, `--json`, `--sheets`.
    fn run_real(&self, dirs: &[PathBuf]) -> anyhow::Result<()> {
        if let Some(json) = &self.json {
            let inputs: Vec<&Path> = dirs.iter().map(PathBuf::as_path).collect();
            crate::io::paths::refuse_overwriting(&[json], &inputs)?;
        }
        let mut frames =
            real::frames_of(dirs, self.real_splits.as_deref(), &self.split, self.limit)?;
        if self.no_mounting {
            for f in &mut frames {
                (f.camera.pitch_deg, f.camera.height_m) = (None, None);
            }
        }
        let floors = match &self.floors {
            Some(path) => real::read_floors(path)?,
            None => real::Floors::new(),
        };
        let modes = if self.mode.is_empty() {
            vec![Mode::Rgb, Mode::Rgbd, Mode::Geometric]
        } else {
            self.mode.clone()
        };
        let rows = real::real_rows(&modes, &self.stages.config(Mode::Rgb));
        let configs: Vec<PipelineConfig> = rows.iter().map(|(_, c)| *c).collect();
        let mut pipeline = self.stages.pipeline(&configs)?;
        if let Some(sheets) = &self.sheets {
            std::fs::create_dir_all(sheets)
                .with_context(|| format!("creating {}", sheets.display()))?;
        }
        let sheets = self.sheets.as_deref();
        let split = self.real_splits.as_ref().map(|_| self.split.as_str());
        let mut report = real::run_benchmark(
            (dirs, split),
            &frames,
            &floors,
            &rows,
            &mut pipeline,
            &self.sensor,
            |f, l, maps| match sheets {
                Some(sheets) => real::write_sheet(sheets, f, l, &rows, maps),
                None => Ok(()),
            },
        )?;
        report.mounting_ignored = self.no_mounting;
        println!("{}", real::markdown(&report));
        if let Some(path) = &self.json {
            crate::io::paths::write_text(path, &serde_json::to_string_pretty(&report)?)?;
        }
        Ok(())
    }

    fn write_json(
        &self,
        data: &Path,
        frames: usize,
        rows: &[synthetic::RowResult],
    ) -> anyhow::Result<()> {
        let Some(path) = &self.json else {
            return Ok(());
        };
        let report = SplitReport {
            data,
            split: &self.split,
            frames,
            rows,
        };
        Ok(crate::io::paths::write_text(
            path,
            &serde_json::to_string_pretty(&report)?,
        )?)
    }
}
