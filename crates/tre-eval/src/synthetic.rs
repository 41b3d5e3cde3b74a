//! Scores on a split of a `tre synth` dataset against annotation spec v1: roughness RMSE,
//! B-RMSE, F-RMSE; normal angle errors; depth errors in `rgb` mode; mean time per stage, for one
//! configuration or every row of the paper's Tables II, IV and V ([`crate::tables`]).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Serialize;
use tre_core::geometry::{Grid, Vec3};
use tre_core::roughness::metrics::{DepthAccumulator, NormalAccumulator, RoughnessAccumulator};
use tre_core::roughness::metrics::{DepthMetrics, NormalMetrics, RoughnessMetrics};
use tre_io as io;
use tre_pipeline::{FrameInput, Method, Mode, Pipeline, PipelineConfig};
use tre_synth::dataset::Manifest;

use crate::error::{read_json, FrameLoadError, RunError, SyntheticError};

/// Which depth of a `tre synth` frame the modes read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
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

/// The JSON report of a synthetic split.
#[derive(Debug, Serialize)]
pub struct SplitReport<'a> {
    /// The dataset folder.
    pub data: &'a Path,
    /// The split scored.
    pub split: &'a str,
    /// Frames scored.
    pub frames: usize,
    /// One result per configuration.
    pub rows: &'a [RowResult],
}

/// The frame folders of `split` in the `tre synth` dataset at `data`, at most `limit`.
///
/// # Errors
///
/// When the manifest does not read or parse, or the split has no frame.
pub fn frame_dirs(
    data: &Path,
    split: &str,
    limit: Option<usize>,
) -> Result<Vec<PathBuf>, SyntheticError> {
    let manifest: Manifest = read_json(&data.join("dataset.json"))?;
    let dirs: Vec<PathBuf> = manifest
        .scenes
        .iter()
        .filter(|s| s.split == split)
        .flat_map(|s| s.frames.iter().map(|f| data.join(&f.dir)))
        .take(limit.unwrap_or(usize::MAX))
        .collect();
    if dirs.is_empty() {
        return Err(SyntheticError::NoFrames {
            split: split.to_owned(),
        });
    }
    Ok(dirs)
}

/// The inputs of a `tre synth` dataset that a report must not be written over: its manifest
/// and its scene folders.
#[must_use]
pub fn dataset_inputs(data: &Path) -> Vec<PathBuf> {
    let mut inputs = vec![data.join("dataset.json")];
    if let Ok(entries) = std::fs::read_dir(data) {
        inputs.extend(entries.flatten().map(|e| e.path()).filter(|p| p.is_dir()));
    }
    inputs
}

/// Scores every configuration of `specs` on every frame folder of `dirs` (the modes that read
/// depth read `source`'s), one result per configuration.
///
/// # Errors
///
/// When a frame does not read or a configuration fails on it.
pub fn score_split(
    pipeline: &mut Pipeline,
    dirs: &[PathBuf],
    specs: &[RowSpec],
    source: DepthSource,
) -> Result<Vec<RowResult>, SyntheticError> {
    let mut scores: Vec<Score> = specs.iter().map(|_| Score::default()).collect();
    for (i, dir) in dirs.iter().enumerate() {
        let frame = read_frame(dir, source).map_err(|source| SyntheticError::Load {
            dir: dir.clone(),
            source: Box::new(source),
        })?;
        for (spec, score) in specs.iter().zip(&mut scores) {
            score_frame(pipeline, &frame, spec, score).map_err(|source| SyntheticError::Run {
                dir: dir.clone(),
                row: spec.key.clone(),
                source: Box::new(source),
            })?;
        }
        tracing::info!("{}/{} frames", i + 1, dirs.len());
    }
    Ok(specs
        .iter()
        .zip(&scores)
        .map(|(spec, score)| score.finish(spec, dirs.len()))
        .collect())
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

/// `mode:label`, e.g. `rgbd:DSAC+NR+ESR`; `e2e:E2E` for the baseline.
pub fn row_key(cfg: &PipelineConfig) -> String {
    let mode = match cfg.method {
        Method::EndToEnd => "e2e",
        Method::Pipeline => cfg.mode.into(),
    };
    format!("{mode}:{}", cfg.label())
}

/// Reads a `tre synth` frame folder: inputs (depth from `source`) and ground truth.
fn read_frame(dir: &Path, source: DepthSource) -> Result<Frame, FrameLoadError> {
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
        sensor: cam.sensor.as_ref().and_then(io::SensorSpec::noise),
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
fn read_sensor_depth(path: &Path, scale: f64) -> Result<Option<Grid<f64>>, FrameLoadError> {
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
    io::check_depth(&depth).map_err(|source| FrameLoadError::SensorDepth {
        path: path.to_owned(),
        source,
    })?;
    Ok(Some(depth))
}

/// Runs one configuration on one frame and adds its errors and timings to `score`. A mode that
/// reads depth on a frame whose sensor saw nothing predicts no pixel.
fn score_frame(
    pipeline: &mut Pipeline,
    frame: &Frame,
    spec: &RowSpec,
    score: &mut Score,
) -> Result<(), RunError> {
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
    if let (Some(depth), Mode::Rgb) = (&out.depth_m(), spec.cfg.mode) {
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

/// The metrics of one row, as lines of text (each ending in a newline).
#[must_use]
pub fn row_text(row: &RowResult) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let r = &row.roughness;
    let _ = writeln!(out, "{}", row.key);
    let _ = writeln!(
        out,
        "roughness  RMSE {:.3} cm  B-RMSE {:.3} cm  F-RMSE {:.3} cm  ({} px, {} without prediction)",
        r.rmse_cm, r.b_rmse_cm, r.f_rmse_cm, r.pixels, r.missing
    );
    if let Some(n) = &row.normals {
        let _ = writeln!(
            out,
            "normals    mean {:.2}°  median {:.2}°  <11.25° {:.1}%  <22.5° {:.1}%  <30° {:.1}%",
            n.mean_deg, n.median_deg, n.under_11_25_pct, n.under_22_5_pct, n.under_30_pct
        );
    }
    if let Some(d) = &row.depth {
        let _ = writeln!(
            out,
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
    let _ = writeln!(out, "mean ms    {}", stages.join(", "));
    out
}
