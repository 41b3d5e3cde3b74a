//! `tre eval`: scores the pipeline (any mode and switches, or the end-to-end baseline) on a
//! split of a `tre synth` dataset against annotation spec v1: roughness RMSE, B-RMSE, F-RMSE;
//! normal angle errors; depth errors in rgb mode; mean time per stage. `--tables` runs every
//! row of the paper's Tables II, IV and V and prints them as markdown.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use clap::Args;
use serde::Serialize;

use super::options::StageArgs;
use super::{real, tables};
use crate::geometry::{Grid, Vec3};
use crate::io;
use crate::pipeline::{FrameInput, Method, Mode, Pipeline, PipelineConfig};
use crate::roughness::metrics::{DepthMetrics, NormalMetrics, RoughnessMetrics};
use crate::roughness::noise::SensorNoise;
use crate::roughness::{DepthAccumulator, NormalAccumulator, RoughnessAccumulator};
use crate::synth::dataset::Manifest;

/// Score a method on a synthetic dataset's split, or every mode on real RGB-D frames.
#[derive(Debug, Args)]
pub struct Eval {
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

/// Which depth of a `tre synth` frame the modes read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum DepthSource {
    /// The exact rendered depth (`depth.png`).
    Exact,
    /// The depth-sensor model's depth (`depth_sensor.png`).
    Sensor,
}

impl DepthSource {
    /// The frame's file holding that depth.
    fn file_name(self) -> &'static str {
        match self {
            Self::Exact => "depth.png",
            Self::Sensor => "depth_sensor.png",
        }
    }
}

/// `--sensor`: a preset name or `a,b,c`.
fn parse_sensor(s: &str) -> Result<SensorNoise, String> {
    s.parse()
}

/// One configuration to score, with a stable key (`mode:label`).
#[derive(Debug, Clone)]
pub struct RowSpec {
    /// `rgb:DE+DSAC+NR+ESR`, `geometric:LS+window`, `e2e:E2E`, ...
    pub key: String,
    /// What runs.
    pub cfg: PipelineConfig,
}

/// The scores of one configuration over the split.
#[derive(Debug, Clone, Serialize)]
pub struct RowResult {
    /// The row's key.
    pub key: String,
    /// What ran.
    pub config: PipelineConfig,
    /// Roughness errors, cm.
    pub roughness: RoughnessMetrics,
    /// Normal errors (none for the end-to-end baseline).
    pub normals: Option<NormalMetrics>,
    /// Depth errors (rgb mode only: elsewhere depth is given).
    pub depth: Option<DepthMetrics>,
    /// Mean wall time per frame of each stage, ms.
    pub mean_ms: BTreeMap<String, f64>,
}

/// The JSON report.
#[derive(Debug, Serialize)]
struct Report<'a> {
    data: &'a Path,
    split: &'a str,
    frames: usize,
    rows: &'a [RowResult],
}

/// Accumulators of one row.
#[derive(Default)]
struct Score {
    roughness: RoughnessAccumulator,
    normals: NormalAccumulator,
    depth: DepthAccumulator,
    has_normals: bool,
    has_depth: bool,
    total_ms: BTreeMap<String, f64>,
}

/// One frame's inputs and ground truth.
struct Frame {
    input: FrameInput,
    roughness_m: Grid<f64>,
    boundary: Grid<bool>,
    normals: Grid<Vec3>,
    depth_m: Grid<f64>,
}

impl Eval {
    /// Scores every frame of the split and prints the metrics (and the tables), or runs the
    /// real-frame benchmark.
    pub fn run(self) -> anyhow::Result<()> {
        if !self.real.is_empty() {
            return self.run_real(&self.real);
        }
        let data = self.data.clone().context("--data or --real is needed")?;
        if let Some(json) = &self.json {
            // The dataset's manifest and its scene folders are inputs; a report beside them
            // is fine.
            let mut inputs = vec![data.join("dataset.json")];
            if let Ok(entries) = std::fs::read_dir(&data) {
                inputs.extend(entries.flatten().map(|e| e.path()).filter(|p| p.is_dir()));
            }
            let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
            super::refuse_overwriting(&[json], &inputs)?;
        }
        let dirs = self.frame_dirs(&data)?;
        let specs = if self.tables {
            tables::row_specs(&self.stages.config(self.synthetic_mode()?))
        } else {
            let cfg = self.stages.config(self.synthetic_mode()?);
            vec![RowSpec {
                key: row_key(&cfg),
                cfg,
            }]
        };
        let configs: Vec<PipelineConfig> = specs.iter().map(|s| s.cfg).collect();
        let mut pipeline = self.stages.pipeline(&configs)?;
        let mut scores: Vec<Score> = specs.iter().map(|_| Score::default()).collect();
        for (i, dir) in dirs.iter().enumerate() {
            let frame = read_frame(dir, self.depth_source)
                .with_context(|| format!("frame {}", dir.display()))?;
            for (spec, score) in specs.iter().zip(&mut scores) {
                score_frame(&mut pipeline, &frame, spec, score)
                    .with_context(|| format!("frame {}, {}", dir.display(), spec.key))?;
            }
            tracing::info!("{}/{} frames", i + 1, dirs.len());
        }
        let rows: Vec<RowResult> = specs
            .iter()
            .zip(&scores)
            .map(|(spec, score)| score.finish(spec, dirs.len()))
            .collect();
        println!(
            "{}, split {}, {} frames\n",
            data.display(),
            self.split,
            dirs.len()
        );
        if self.tables {
            println!("{}", tables::markdown(&rows));
        } else {
            rows.iter().for_each(print_row);
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
            super::refuse_overwriting(&[json], &inputs)?;
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
            super::write_file(path, &serde_json::to_string_pretty(&report)?)?;
        }
        Ok(())
    }

    /// The frame folders of the split, at most `--limit`.
    fn frame_dirs(&self, data: &Path) -> anyhow::Result<Vec<PathBuf>> {
        let path = data.join("dataset.json");
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("reading {}", path.display()))?;
        let manifest: Manifest = serde_json::from_str(&text).context("parsing dataset.json")?;
        let dirs: Vec<PathBuf> = manifest
            .scenes
            .iter()
            .filter(|s| s.split == self.split)
            .flat_map(|s| s.frames.iter().map(|f| data.join(&f.dir)))
            .take(self.limit.unwrap_or(usize::MAX))
            .collect();
        if dirs.is_empty() {
            bail!("no frames in split {:?}", self.split);
        }
        Ok(dirs)
    }

    fn write_json(&self, data: &Path, frames: usize, rows: &[RowResult]) -> anyhow::Result<()> {
        let Some(path) = &self.json else {
            return Ok(());
        };
        let report = Report {
            data,
            split: &self.split,
            frames,
            rows,
        };
        super::write_file(path, &serde_json::to_string_pretty(&report)?)
    }
}

/// `mode:label`, e.g. `rgbd:DSAC+NR+ESR`; `e2e:E2E` for the baseline.
pub fn row_key(cfg: &PipelineConfig) -> String {
    let mode = match cfg.method {
        Method::EndToEnd => "e2e",
        Method::Pipeline => cfg.mode.into(),
    };
    format!("{mode}:{}", cfg.label())
}

/// Reads a `tre synth` frame folder: inputs (depth from `source`) and ground truth.
fn read_frame(dir: &Path, source: DepthSource) -> anyhow::Result<Frame> {
    let (cam, k) = io::read_camera(&dir.join("camera.json"))?;
    let scale = cam.depth_scale.unwrap_or(1000.0);
    let depth_m = io::read_depth(&dir.join("depth.png"), scale)?;
    let input_depth_m = match source {
        DepthSource::Exact => Some(depth_m.clone()),
        other => read_sensor_depth(&dir.join(other.file_name()), scale)?,
    };
    let input = FrameInput {
        rgb: Some(io::read_image(&dir.join("rgb.png"))?.to_rgb8()),
        depth_m: input_depth_m,
        intrinsics: Some(k),
        mounting: cam.mounting()?,
    };
    Ok(Frame {
        input,
        roughness_m: io::decode_roughness_png16(&io::read_image(&dir.join("roughness.png"))?),
        boundary: io::read_labels(&dir.join("boundary.png"))?.map(|&b| b > 0),
        normals: io::read_normals(&dir.join("normals.npy"))?,
        depth_m,
    })
}

/// A depth-sensor model's depth; `None` when the sensor saw nothing at all (every pixel 0, such
/// as a Kinect whose whole view is beyond its range), which no depth mode can run on. The PNG is
/// decoded once; anything else goes through [`io::read_depth`] and its checks.
fn read_sensor_depth(path: &Path, scale: f64) -> anyhow::Result<Option<Grid<f64>>> {
    let image::DynamicImage::ImageLuma16(img) = io::read_image(path)? else {
        return Ok(Some(io::read_depth(path, scale)?));
    };
    if img.pixels().all(|p| p.0[0] == 0) {
        tracing::warn!(
            "{}: the sensor saw nothing; scored as every pixel without prediction",
            path.display()
        );
        return Ok(None);
    }
    let depth = io::depth_from_luma16(img, scale);
    io::check_depth(&depth).map_err(|why| anyhow::anyhow!("{}: {why}", path.display()))?;
    Ok(Some(depth))
}

/// Runs one configuration on one frame and adds its errors and timings to `score`. A mode that
/// reads depth on a frame whose sensor saw nothing predicts no pixel.
fn score_frame(
    pipeline: &mut Pipeline,
    frame: &Frame,
    spec: &RowSpec,
    score: &mut Score,
) -> anyhow::Result<()> {
    if frame.input.depth_m.is_none()
        && spec.cfg.mode != Mode::Rgb
        && spec.cfg.method != Method::EndToEnd
    {
        let (w, h) = frame.roughness_m.size();
        let none = Grid::new(w, h, f64::NAN);
        score
            .roughness
            .add(&none, &frame.roughness_m, &frame.boundary)?;
        return Ok(());
    }
    let out = pipeline.run(&frame.input, &spec.cfg)?;
    score
        .roughness
        .add(&out.roughness_m, &frame.roughness_m, &frame.boundary)?;
    if let Some(normals) = &out.normals() {
        score.normals.add(normals, &frame.normals)?;
        score.has_normals = true;
    }
    if let (Some(depth), crate::pipeline::Mode::Rgb) = (&out.depth_m(), spec.cfg.mode) {
        score.depth.add(depth, &frame.depth_m)?;
        score.has_depth = true;
    }
    for (name, took) in out.timings.iter() {
        *score.total_ms.entry(name.to_owned()).or_default() += took.as_secs_f64() * 1e3;
    }
    pipeline.recycle(out);
    Ok(())
}

impl Score {
    fn finish(&self, spec: &RowSpec, frames: usize) -> RowResult {
        RowResult {
            key: spec.key.clone(),
            config: spec.cfg.as_run(),
            roughness: self.roughness.finish(),
            normals: self.has_normals.then(|| self.normals.finish()),
            depth: self.has_depth.then(|| self.depth.finish()),
            mean_ms: self
                .total_ms
                .iter()
                .map(|(k, v)| (k.clone(), v / frames.max(1) as f64))
                .collect(),
        }
    }
}

/// The metrics of one row, as lines of text.
fn print_row(row: &RowResult) {
    let r = &row.roughness;
    println!("{}", row.key);
    println!(
        "roughness  RMSE {:.3} cm  B-RMSE {:.3} cm  F-RMSE {:.3} cm  ({} px, {} without prediction)",
        r.rmse_cm, r.b_rmse_cm, r.f_rmse_cm, r.pixels, r.missing
    );
    if let Some(n) = &row.normals {
        println!(
            "normals    mean {:.2}°  median {:.2}°  <11.25° {:.1}%  <22.5° {:.1}%  <30° {:.1}%",
            n.mean_deg, n.median_deg, n.under_11_25_pct, n.under_22_5_pct, n.under_30_pct
        );
    }
    if let Some(d) = &row.depth {
        println!(
            "depth      AbsRel {:.4}  RMSE {:.3} m  δ<1.25 {:.1}%",
            d.abs_rel,
            d.rmse_m,
            100.0 * d.delta_1_25
        );
    }
    let stages: Vec<String> = row
        .mean_ms
        .iter()
        .map(|(k, v)| format!("{k} {v:.1}"))
        .collect();
    println!("mean ms    {}", stages.join(", "));
}
