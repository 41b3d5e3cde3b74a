//! The options of `tre eval` and `tre calibrate` (the `cli` feature): the frames, the split,
//! the pipeline's switches and models and the outputs, and the choices they imply.

use std::path::PathBuf;

use tre_core::kinds::{GeometricMethod, Mode};
use tre_core::roughness::interval::{Calibration, CALIBRATION_FILE};
use tre_core::roughness::noise::SensorNoise;
use tre_io::IoError;
use tre_model::ModelError;
use tre_pipeline::{models_key, PipelineConfig, PipelineError, StageArgs};

use crate::calibrate::{fit_tables, Samples};
use crate::error::{BenchError, FramesError};
use crate::real::{self, RealFrame};
use crate::synthetic::{self, DepthSource, RowSpec};
use crate::tables;

/// Score a method on a synthetic dataset's split, or every mode on real RGB-D frames.
#[derive(Debug, Clone, clap::Args)]
pub struct EvalArgs {
    /// Dataset folder written by `tre synth` (holds dataset.json).
    #[arg(long, required_unless_present = "real")]
    pub data: Option<PathBuf>,
    /// Real-frame benchmark: a folder of RGB-D frames with their intrinsics (one sequence
    /// folder with intrinsics.json, or a folder of them, as ../shared/data/real-rgbd). Every
    /// mode in --modes runs on each frame and is scored against annotation spec v1 on the same
    /// sensor depth; the geometric mode runs as the terrain estimate, the spec, the surface-only
    /// baseline and the spec on cleaned depth.
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
    /// Known-flat and known-hazard regions of the real frames (JSON, as
    /// tests/fixtures/real_regions.json, with each set's sensor class): instead of the
    /// benchmark against the spec, scores the geometric mode (terrain estimate, spec, spec on
    /// cleaned depth) and the other modes of --mode against these regions, per sensor class.
    #[arg(long, requires = "real")]
    pub regions: Option<PathBuf>,
    /// Real-frame benchmark: what the modes are scored against: `raw`, the spec on each
    /// frame's own sensor depth (a reference, not truth), or `fused`, the spec on depth fused
    /// from the 8 neighbouring posed frames on each side among those scored (frames without a
    /// pose are left out).
    #[arg(long, requires = "real", value_enum, default_value = "raw")]
    pub reference: real::Reference,
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
    /// realsense_d435, azure_kinect, lidar, lidar_accumulated, passive_stereo, exact; or a,b,c
    /// for σ_z = a + b·z + c·z² mm).
    /// Unlike `tre infer --sensor` (no default), this has one: the shared real-rgbd frames are
    /// all Kinect v1 but name it in free text.
    #[arg(long, requires = "real", default_value = "kinect_v1")]
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

impl EvalArgs {
    /// The one mode of a synthetic run: `--mode`'s, geometric by default.
    ///
    /// # Errors
    ///
    /// When `--mode` names more than one.
    pub fn synthetic_mode(&self) -> Result<Mode, OneModeError> {
        match self.mode.as_slice() {
            [] => Ok(Mode::Geometric),
            [one] => Ok(*one),
            more => Err(OneModeError {
                modes: more.to_vec(),
            }),
        }
    }

    /// The rows a synthetic run scores: every row of the paper's tables with `--tables`, else
    /// the one configuration of the switches and [`synthetic_mode`](Self::synthetic_mode).
    ///
    /// # Errors
    ///
    /// As [`synthetic_mode`](Self::synthetic_mode).
    pub fn synthetic_rows(&self) -> Result<Vec<RowSpec>, OneModeError> {
        let cfg = self.stages.config(self.synthetic_mode()?);
        Ok(if self.tables {
            tables::row_specs(&cfg)
        } else {
            vec![RowSpec {
                key: synthetic::row_key(&cfg),
                cfg,
            }]
        })
    }

    /// The rows of the real-frame benchmark: each of `--mode`'s (every mode by default) over
    /// the switches ([`real::real_rows`]).
    pub fn real_rows(&self) -> Vec<(String, PipelineConfig)> {
        let modes = if self.mode.is_empty() {
            vec![Mode::Rgb, Mode::Rgbd, Mode::Geometric]
        } else {
            self.mode.clone()
        };
        real::real_rows(&modes, &self.stages.config(Mode::Rgb))
    }

    /// The rows of the region scoring: the geometric mode as the terrain estimate and as the
    /// spec, and each other mode of `--mode` (default: rgbd), with the default traversability
    /// thresholds (slope included).
    pub fn region_rows(&self) -> Vec<(String, PipelineConfig)> {
        let base = self.stages.config(Mode::Rgb);
        let mut rows = Vec::new();
        for geometric in [
            GeometricMethod::Terrain,
            GeometricMethod::Spec,
            GeometricMethod::SpecCleaned,
        ] {
            let cfg = PipelineConfig {
                mode: Mode::Geometric,
                geometric,
                ..base
            };
            rows.push((format!("geometric:{}", cfg.label()), cfg));
        }
        let others = if self.mode.is_empty() {
            vec![Mode::Rgbd]
        } else {
            self.mode.clone()
        };
        for mode in others.into_iter().filter(|&m| m != Mode::Geometric) {
            let cfg = PipelineConfig { mode, ..base };
            rows.push((format!("{mode}:{}", cfg.label()), cfg));
        }
        rows
    }

    /// The real frames of the split (`--real-splits`) in `dirs`, read as if their cameras
    /// stated no mounting with `--no-mounting`.
    ///
    /// # Errors
    ///
    /// As [`real::frames_of`].
    pub fn real_frames(&self, dirs: &[PathBuf]) -> Result<Vec<RealFrame>, FramesError> {
        let mut frames =
            real::frames_of(dirs, self.real_splits.as_deref(), &self.split, self.limit)?;
        if self.no_mounting {
            for f in &mut frames {
                (f.camera.pitch_deg, f.camera.height_m) = (None, None);
            }
        }
        Ok(frames)
    }
}

/// Fit every mode's 90% roughness intervals on real frames.
#[derive(Debug, Clone, clap::Args)]
pub struct CalibrateArgs {
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
    #[arg(long, default_value = "kinect_v1")]
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

/// What [`CalibrateArgs::fit`] fitted.
#[derive(Debug, Clone)]
pub struct Fitted {
    /// The calibration file's contents.
    pub calibration: Calibration,
    /// A line per mode and range on the fit (for people).
    pub lines: Vec<String>,
}

impl CalibrateArgs {
    /// Fits every mode's intervals on the frames of the split: `rgb` and `rgbd` against the
    /// spec on the same sensor depth, `geometric` (as the spec, on the depth as given and on
    /// cleaned depth) against the spec of the same surface in the previous frame of a
    /// sequence with poses.
    ///
    /// # Errors
    ///
    /// For the test split (the intervals are judged there), and when the frames, the models
    /// or a frame's run fail.
    pub fn fit(&self) -> Result<Fitted, CalibrateError> {
        if self.split == "test" {
            return Err(CalibrateError::TestSplit);
        }
        let frames = real::frames_of(&self.real, Some(&self.real_splits), &self.split, None)?;
        let base = self.stages.config(Mode::Rgb);
        let cfgs: Vec<PipelineConfig> = [
            (Mode::Rgb, GeometricMethod::Spec),
            (Mode::Rgbd, GeometricMethod::Spec),
            (Mode::Geometric, GeometricMethod::Spec),
            (Mode::Geometric, GeometricMethod::SpecCleaned),
        ]
        .into_iter()
        .map(|(mode, geometric)| PipelineConfig {
            mode,
            geometric,
            ..base
        })
        .collect();
        let mut pipeline = self.stages.pipeline(&cfgs)?;
        let models = pipeline
            .models()
            .map_or_else(String::new, |m| models_key(m.manifest()));
        let stride = usize::from(self.stride);
        let samples = Samples::collect(&frames, &mut pipeline, &cfgs, &self.sensor, stride)?;
        let (tables, lines) = fit_tables(&samples);
        let calibration = Calibration {
            format: 1,
            note: format!(
                "tre calibrate, split {:?} of {}, every {}th pixel: rgb and rgbd against the spec \
                 on the same sensor depth; geometric (the spec on the depth as given, and on \
                 cleaned depth) against the spec of the same surface in the previous frame of a \
                 sequence with poses",
                self.split,
                self.real_splits.display(),
                self.stride
            ),
            frames: frames.iter().map(RealFrame::name).collect(),
            models,
            tables,
        };
        Ok(Fitted { calibration, lines })
    }

    /// Writes `calibration` to `--out`, else to uncertainty.json in the models folder; returns
    /// where.
    ///
    /// # Errors
    ///
    /// When no models folder is found or the file cannot be written.
    pub fn write(&self, calibration: &Calibration) -> Result<PathBuf, CalibrateError> {
        let out = match &self.out {
            Some(p) => p.clone(),
            None => tre_model::find_models(self.stages.models.as_deref())?.join(CALIBRATION_FILE),
        };
        tre_io::paths::write_text(&out, &serde_json::to_string_pretty(calibration)?)?;
        Ok(out)
    }
}

/// `--mode` naming more than one mode for the synthetic split.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "--mode: the synthetic split scores one mode at a time, got {}",
    modes.iter().map(ToString::to_string).collect::<Vec<_>>().join(",")
)]
pub struct OneModeError {
    /// The modes given.
    pub modes: Vec<Mode>,
}

/// Why `tre calibrate` cannot fit or write the intervals.
#[derive(Debug, thiserror::Error)]
pub enum CalibrateError {
    /// `--split test`.
    #[error("--split test: the intervals are judged on the test frames; fit them on val")]
    TestSplit,
    /// The frames of the split cannot be found.
    #[error(transparent)]
    Frames(#[from] FramesError),
    /// The pipeline cannot be built.
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
    /// A frame does not read or a mode fails on it.
    #[error(transparent)]
    Samples(#[from] BenchError),
    /// No models folder to write to.
    #[error(transparent)]
    Models(#[from] ModelError),
    /// The calibration does not serialise.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// The file cannot be written.
    #[error(transparent)]
    Write(#[from] IoError),
}
