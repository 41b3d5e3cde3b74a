//! `tre eval --real DIR`: the real-frame benchmark. Every mode runs on real RGB-D frames and is
//! scored against annotation spec v1 computed on the same sensor depth (what `tre annotate`
//! writes): RMSE, B-RMSE, F-RMSE, edge recall, false hazards, floor roughness, all split by
//! range; depth errors of the `rgb` mode against the sensor; time per stage. Prints markdown,
//! writes every number as JSON and a contact sheet per frame.
//!
//! # Folder layout
//!
//! `DIR` is one sequence folder, or a folder of them (taken in name order). A sequence folder
//! holds `intrinsics.json` (a camera file: `fx`, `fy`, `cx`, `cy`, `depth_scale` in depth-PNG
//! units per metre, optional `pitch_deg`, `height_m`) and its frames, found in this order:
//!
//! 1. `"frames": [["rgb/a.jpg", "depth/a.png"], ...]` in `intrinsics.json`;
//! 2. `color/NAME.png` (or `.jpg`) with `depth/NAME.png`;
//! 3. `NAME.png` (or `.jpg`) with `NAME_depth.png` beside it.
//!
//! Floor boxes (`--floors`): `{"frames": [{"dir": SEQUENCE, "depth": DEPTH_PATH, "floor": [x0,
//! y0, x1, y1]}]}`, pixels of the frame, end exclusive, as `tests/fixtures/real_floor.json`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::{Deserialize, Serialize};

use image::Rgb;
use tre_core::geometry::{Grid, Intrinsics};
use tre_core::roughness::hazard::{
    box_values, floor_stats, FloorStats, RangeScores, ScoreMetrics, FLAT_M, HAZARD_M, RANGE_BINS,
};
use tre_core::roughness::metrics::DepthMetrics;
use tre_core::roughness::noise::SensorNoise;
use tre_core::roughness::traversal::Traversal;
use tre_core::roughness::{
    annotate::{annotate, AnnotateConfig, AnnotateInput, Annotation},
    metrics::DepthAccumulator,
};
use tre_io::sheet::{
    categorical_legend, colour_bar_legend, contact_sheet, roughness_panel, stack, Panel,
};
use tre_io::{self as io, CameraFile};
use tre_pipeline::SensorMaps;
use tre_pipeline::{FrameInput, GeometricMethod, Mode, Pipeline, PipelineConfig};

use crate::error::{
    read_json, read_text, BenchError, FrameLoadError, FramesError, JsonFileError, RunError,
};

/// One real frame on disk.
#[derive(Debug, Clone)]
pub struct RealFrame {
    /// The sequence folder's name.
    pub sequence: String,
    /// The RGB image.
    pub rgb: PathBuf,
    /// The depth PNG.
    pub depth: PathBuf,
    /// The depth path relative to the sequence folder, as floor boxes name it.
    pub depth_rel: String,
    /// The sequence's camera file.
    pub camera: CameraFile,
    /// Its intrinsics.
    pub intrinsics: Intrinsics,
    /// Its place in the sequence's frame list.
    pub index: usize,
}

impl RealFrame {
    /// `sequence/depth_rel`, the frame's name in tables.
    pub fn name(&self) -> String {
        format!("{}/{}", self.sequence, self.depth_rel)
    }
}

/// The frames of `dir` (a sequence folder or a folder of them), at most `limit`.
///
/// # Errors
///
/// When no sequence folder or no frame is found, or a camera file does not read.
pub fn find_frames(dir: &Path, limit: Option<usize>) -> Result<Vec<RealFrame>, FramesError> {
    let sequences: Vec<PathBuf> = if dir.join("intrinsics.json").is_file() {
        vec![dir.to_owned()]
    } else {
        let mut subs: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(|source| FramesError::ReadDir {
                dir: dir.to_owned(),
                source,
            })?
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.join("intrinsics.json").is_file())
            .collect();
        subs.sort();
        subs
    };
    if sequences.is_empty() {
        return Err(FramesError::NoSequence {
            dir: dir.to_owned(),
        });
    }
    let mut frames = Vec::new();
    for seq in &sequences {
        frames.extend(sequence_frames(seq)?);
    }
    frames.truncate(limit.unwrap_or(usize::MAX));
    if frames.is_empty() {
        return Err(FramesError::NoFrames {
            dir: dir.to_owned(),
        });
    }
    Ok(frames)
}

/// The frames of every folder of `dirs` (each as [`find_frames`] reads it), only those of
/// split `split` when a splits file is given, at most `limit`.
///
/// # Errors
///
/// Those of [`find_frames`] and [`Splits`]; none left after the split.
pub fn frames_of(
    dirs: &[PathBuf],
    splits: Option<&Path>,
    split: &str,
    limit: Option<usize>,
) -> Result<Vec<RealFrame>, FramesError> {
    let mut frames = Vec::new();
    for dir in dirs {
        frames.extend(find_frames(dir, None)?);
    }
    if let Some(path) = splits {
        frames = Splits::read(path)?.select(frames, split)?;
        if frames.is_empty() {
            return Err(FramesError::EmptySplit {
                path: path.to_owned(),
                split: split.to_owned(),
            });
        }
    }
    frames.truncate(limit.unwrap_or(usize::MAX));
    Ok(frames)
}

/// The frames of one sequence folder, by the layout's three rules.
fn sequence_frames(seq: &Path) -> Result<Vec<RealFrame>, FramesError> {
    let cam_path = seq.join("intrinsics.json");
    let (camera, intrinsics) = io::read_camera(&cam_path)?;
    let text = read_text(&cam_path)?;
    let listed: ListedFrames =
        serde_json::from_str(&text).map_err(|source| FramesError::FrameList {
            path: cam_path.clone(),
            source,
        })?;
    let pairs = match listed.frames {
        Some(pairs) => pairs,
        None => paired_files(seq),
    };
    let sequence = seq
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let mut frames = Vec::new();
    for (index, (rgb, depth)) in pairs.into_iter().enumerate() {
        let (rgb_path, depth_path) = (seq.join(&rgb), seq.join(&depth));
        for p in [&rgb_path, &depth_path] {
            if !p.is_file() {
                return Err(FramesError::MissingFile {
                    sequence: seq.to_owned(),
                    file: p.clone(),
                });
            }
        }
        frames.push(RealFrame {
            sequence: sequence.clone(),
            rgb: rgb_path,
            depth: depth_path,
            depth_rel: depth,
            camera: camera.clone(),
            intrinsics,
            index,
        });
    }
    Ok(frames)
}

/// The optional frame list of a sequence's `intrinsics.json`.
#[derive(Deserialize)]
struct ListedFrames {
    #[serde(default)]
    frames: Option<Vec<(String, String)>>,
}

/// `(rgb, depth)` pairs by rule 2 (`color/` + `depth/`) or rule 3 (`NAME` + `NAME_depth`).
fn paired_files(seq: &Path) -> Vec<(String, String)> {
    let images = |dir: &Path| -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .into_iter()
            .flatten()
            .flatten()
            .filter_map(|e| e.file_name().to_str().map(str::to_owned))
            .filter(|n| n.ends_with(".png") || n.ends_with(".jpg"))
            .collect();
        names.sort();
        names
    };
    let stem = |n: &str| n.rsplit_once('.').map_or(n, |(s, _)| s).to_owned();
    let mut pairs = Vec::new();
    if seq.join("color").is_dir() && seq.join("depth").is_dir() {
        for name in images(&seq.join("color")) {
            let depth = format!("depth/{}.png", stem(&name));
            if seq.join(&depth).is_file() {
                pairs.push((format!("color/{name}"), depth));
            }
        }
    } else {
        for name in images(seq) {
            let depth = format!("{}_depth.png", stem(&name));
            if !name.ends_with("_depth.png") && seq.join(&depth).is_file() {
                pairs.push((name, depth));
            }
        }
    }
    pairs
}

/// Floor boxes by `(sequence, depth path)`.
pub type Floors = BTreeMap<(String, String), [usize; 4]>;

/// Reads a floor-box file (the layout in the module's documentation).
///
/// # Errors
///
/// When the file does not read or parse.
pub fn read_floors(path: &Path) -> Result<Floors, JsonFileError> {
    #[derive(Deserialize)]
    struct File {
        frames: Vec<Entry>,
    }
    #[derive(Deserialize)]
    struct Entry {
        dir: String,
        depth: String,
        floor: [usize; 4],
    }
    let file: File = read_json(path)?;
    Ok(file
        .frames
        .into_iter()
        .map(|e| ((e.dir, e.depth), e.floor))
        .collect())
}

/// One frame read and annotated.
pub struct LoadedFrame {
    /// The pipeline's input (RGB, sensor depth, intrinsics, mounting).
    pub input: FrameInput,
    /// The spec on the sensor depth.
    pub spec: Annotation,
    /// `annotate`'s time, ms.
    pub spec_ms: f64,
}

/// Reads a frame and computes the spec on its depth.
///
/// # Errors
///
/// When a file does not read or the depth has no valid pixel.
pub fn load_frame(frame: &RealFrame) -> Result<LoadedFrame, FrameLoadError> {
    let scale = frame.camera.depth_scale.unwrap_or(1000.0);
    let depth_m = io::read_depth(&frame.depth, scale)?;
    let rgb = io::read_image(&frame.rgb)?.to_rgb8();
    let start = Instant::now();
    let spec = annotate(
        &AnnotateInput::depth(&depth_m, &frame.intrinsics),
        &AnnotateConfig::default(),
    )?;
    let spec_ms = start.elapsed().as_secs_f64() * 1e3;
    let input = FrameInput {
        rgb: Some(rgb),
        depth_m: Some(depth_m),
        intrinsics: Some(frame.intrinsics),
        mounting: frame.camera.mounting()?,
        sensor: frame.camera.sensor.as_ref().and_then(|s| s.noise()),
    };
    Ok(LoadedFrame {
        input,
        spec,
        spec_ms,
    })
}

impl LoadedFrame {
    /// The frame with its sensor's noise model ([`frame_sensor`]) in its input.
    #[must_use]
    pub fn sensed(mut self, frame: &RealFrame, default: &SensorNoise) -> Self {
        self.input.sensor = Some(frame_sensor(frame, default));
        self
    }
}

/// The noise model of a frame's sensor: the camera file's, when it names one, else `default`.
pub fn frame_sensor(frame: &RealFrame, default: &SensorNoise) -> SensorNoise {
    frame
        .camera
        .sensor
        .as_ref()
        .and_then(|s| s.noise())
        .unwrap_or(*default)
}

mod bench;
mod fused;
mod regions;
mod report;
mod safety;
mod sheet;
mod splits;
mod traversal;
mod views;

pub use bench::*;
pub use fused::{fuse_depth, FuseConfig, Reference};
pub use regions::{regions_markdown, score_regions, RegionFigures, RegionFile, RegionReport};
pub use report::markdown;
pub use safety::{Safety, SafetyAcc, SafetyFigures};
pub use sheet::{sheet_panels, write_sheet, SHEET_MAX_M};
pub use splits::Splits;
use traversal::TraversalAcc;
pub use traversal::{StateShares, TraversalMetrics};
pub use views::{shared_with, OtherView, Pose, PrevView, View, ViewPair};
