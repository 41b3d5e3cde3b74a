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

use anyhow::{bail, Context};
use serde::{Deserialize, Serialize};

use crate::geometry::{Grid, Intrinsics};
use crate::io::sheet::{
    categorical_legend, colour_bar_legend, contact_sheet, roughness_panel, stack, Panel,
};
use crate::io::{self, CameraFile};
use crate::pipeline::frame::SensorMaps;
use crate::pipeline::{FrameInput, GeometricMethod, Mode, Pipeline, PipelineConfig};
use crate::roughness::hazard::{
    box_values, floor_stats, FloorStats, RangeScores, ScoreMetrics, FLAT_M, HAZARD_M, RANGE_BINS,
};
use crate::roughness::metrics::DepthMetrics;
use crate::roughness::noise::SensorNoise;
use crate::roughness::traversal::Traversal;
use crate::roughness::{annotate, AnnotateConfig, AnnotateInput, Annotation, DepthAccumulator};
use image::Rgb;

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
pub fn find_frames(dir: &Path, limit: Option<usize>) -> anyhow::Result<Vec<RealFrame>> {
    let sequences: Vec<PathBuf> = if dir.join("intrinsics.json").is_file() {
        vec![dir.to_owned()]
    } else {
        let mut subs: Vec<PathBuf> = std::fs::read_dir(dir)
            .with_context(|| format!("reading {}", dir.display()))?
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.join("intrinsics.json").is_file())
            .collect();
        subs.sort();
        subs
    };
    if sequences.is_empty() {
        bail!(
            "{}: no intrinsics.json in it or in its folders (see `tre eval --help` for the layout)",
            dir.display()
        );
    }
    let mut frames = Vec::new();
    for seq in &sequences {
        frames.extend(sequence_frames(seq)?);
    }
    frames.truncate(limit.unwrap_or(usize::MAX));
    if frames.is_empty() {
        bail!("{}: no RGB-D frames found", dir.display());
    }
    Ok(frames)
}

/// The frames of one sequence folder, by the layout's three rules.
fn sequence_frames(seq: &Path) -> anyhow::Result<Vec<RealFrame>> {
    let cam_path = seq.join("intrinsics.json");
    let (camera, intrinsics) = io::read_camera(&cam_path)?;
    let text = std::fs::read_to_string(&cam_path)?;
    let listed: ListedFrames = serde_json::from_str(&text)
        .with_context(|| format!("{}: \"frames\"", cam_path.display()))?;
    let pairs = match listed.frames {
        Some(pairs) => pairs,
        None => paired_files(seq)?,
    };
    let sequence = seq
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let mut frames = Vec::new();
    for (rgb, depth) in pairs {
        let (rgb_path, depth_path) = (seq.join(&rgb), seq.join(&depth));
        for p in [&rgb_path, &depth_path] {
            if !p.is_file() {
                bail!(
                    "{}: listed frame file {} is missing",
                    seq.display(),
                    p.display()
                );
            }
        }
        frames.push(RealFrame {
            sequence: sequence.clone(),
            rgb: rgb_path,
            depth: depth_path,
            depth_rel: depth,
            camera: camera.clone(),
            intrinsics,
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
fn paired_files(seq: &Path) -> anyhow::Result<Vec<(String, String)>> {
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
    Ok(pairs)
}

/// Floor boxes by `(sequence, depth path)`.
pub type Floors = BTreeMap<(String, String), [usize; 4]>;

/// Reads a floor-box file (the layout in the module's documentation).
///
/// # Errors
///
/// When the file does not read or parse.
pub fn read_floors(path: &Path) -> anyhow::Result<Floors> {
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
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let file: File =
        serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))?;
    Ok(file
        .frames
        .into_iter()
        .map(|e| ((e.dir, e.depth), e.floor))
        .collect())
}

/// One configuration's scores on one frame or pooled over frames.
#[derive(Debug, Clone, Serialize)]
pub struct RealRow {
    /// `mode:label`, as in `tre eval`.
    pub key: String,
    /// Over every pixel with spec roughness.
    pub all: ScoreMetrics,
    /// Per range bin (sensor depth).
    pub by_range: BTreeMap<String, ScoreMetrics>,
    /// Roughness inside the floor box, when there is one.
    pub floor: Option<FloorStats>,
    /// Depth errors against the sensor (`rgb` mode only).
    pub depth: Option<DepthMetrics>,
    /// The three-state map under the sensor's noise model (modes that read sensor depth).
    pub traversal: Option<TraversalMetrics>,
    /// Wall time per stage, ms (mean per frame when pooled).
    pub ms: BTreeMap<String, f64>,
}

/// How the three-state map reads a frame (or pooled frames): shares of all pixels and per
/// range bin, and the three checks of DESIGN.md: near floor traversable, far noisy range
/// unknown, drops hazards.
#[derive(Debug, Clone, Serialize)]
pub struct TraversalMetrics {
    /// Shares of every pixel of the frame (no depth: unknown).
    pub all: StateShares,
    /// Shares of the pixels with sensor depth in each range bin.
    pub by_range: BTreeMap<String, StateShares>,
    /// Median uncertainty (metres) of the pixels with depth in each range bin.
    pub median_uncertainty_m: BTreeMap<String, f64>,
    /// Floor-box pixels within 2 m: shares (when a floor box is given).
    pub near_floor: Option<StateShares>,
    /// Pixels beyond 4 m that the spec calls hazards (≥ 5 cm): shares.
    pub far_spec_rough: StateShares,
    /// Drops (spec ≥ 10 cm) within 4 m: shares.
    pub near_drops: StateShares,
}

/// Shares of traversable, hazard and unknown pixels in a set.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct StateShares {
    /// Pixels in the set.
    pub pixels: u64,
    /// Share traversable.
    pub traversable: f64,
    /// Share hazard.
    pub hazard: f64,
    /// Share unknown.
    pub unknown: f64,
}

/// Counts of the three states in a set of pixels.
#[derive(Debug, Clone, Copy, Default)]
struct StateCounts([u64; 3]);

impl StateCounts {
    fn add(&mut self, t: Traversal) {
        self.0[t as usize] += 1;
    }

    fn merge(&mut self, o: &Self) {
        (0..3).for_each(|i| self.0[i] += o.0[i]);
    }

    fn shares(&self) -> StateShares {
        let n: u64 = self.0.iter().sum();
        let share = |k: Traversal| {
            if n == 0 {
                f64::NAN
            } else {
                self.0[k as usize] as f64 / n as f64
            }
        };
        StateShares {
            pixels: n,
            traversable: share(Traversal::Traversable),
            hazard: share(Traversal::Hazard),
            unknown: share(Traversal::Unknown),
        }
    }
}

/// Three-state accumulators of one configuration.
#[derive(Debug, Clone, Default)]
struct TraversalAcc {
    all: StateCounts,
    by_range: [StateCounts; 3],
    uncertainty: [Vec<f64>; 3],
    near_floor: StateCounts,
    far_spec_rough: StateCounts,
    near_drops: StateCounts,
}

/// Spec roughness of a drop, metres.
const DROP_M: f64 = 0.10;

impl TraversalAcc {
    /// Adds one frame's three-state and uncertainty maps.
    fn add(&mut self, maps: &SensorMaps, loaded: &LoadedFrame, floor_box: Option<[usize; 4]>) {
        let Some(depth) = loaded.input.depth_m.as_ref() else {
            return;
        };
        let (w, _) = depth.size();
        let cells = maps.traversal.as_slice().iter().zip(depth.as_slice());
        let spec = loaded.spec.roughness_m.as_slice();
        let u = maps.uncertainty_m.as_slice();
        for (i, (&t, &z)) in cells.enumerate() {
            self.all.add(t);
            if let Some(b) = RANGE_BINS.iter().position(|&(_, a, b)| z >= a && z < b) {
                self.by_range[b].add(t);
                if u[i].is_finite() {
                    self.uncertainty[b].push(u[i]);
                }
            }
            if z >= 4.0 && spec[i] >= HAZARD_M {
                self.far_spec_rough.add(t);
            }
            if z > 0.0 && z < 4.0 && spec[i] >= DROP_M {
                self.near_drops.add(t);
            }
            let (x, y) = (i % w, i / w);
            let in_box = |[x0, y0, x1, y1]: [usize; 4]| x >= x0 && x < x1 && y >= y0 && y < y1;
            if z > 0.0 && z < 2.0 && floor_box.is_some_and(in_box) {
                self.near_floor.add(t);
            }
        }
    }

    fn merge(&mut self, o: &Self) {
        self.all.merge(&o.all);
        for b in 0..3 {
            self.by_range[b].merge(&o.by_range[b]);
            self.uncertainty[b].extend_from_slice(&o.uncertainty[b]);
        }
        self.near_floor.merge(&o.near_floor);
        self.far_spec_rough.merge(&o.far_spec_rough);
        self.near_drops.merge(&o.near_drops);
    }

    fn finish(&self, has_floor: bool) -> TraversalMetrics {
        let names = RANGE_BINS.iter().map(|&(n, _, _)| n.to_owned());
        TraversalMetrics {
            all: self.all.shares(),
            by_range: names
                .clone()
                .zip(self.by_range.iter().map(StateCounts::shares))
                .collect(),
            median_uncertainty_m: names
                .zip(self.uncertainty.iter().map(|u| median(u.clone())))
                .collect(),
            near_floor: has_floor.then(|| self.near_floor.shares()),
            far_spec_rough: self.far_spec_rough.shares(),
            near_drops: self.near_drops.shares(),
        }
    }
}

/// The median of `values` (NaN for none).
fn median(mut values: Vec<f64>) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mid = values.len() / 2;
    *values.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// The spec on one frame, or pooled.
#[derive(Debug, Clone, Serialize)]
pub struct SpecSummary {
    /// Roughness inside the floor box, when there is one.
    pub floor: Option<FloorStats>,
    /// Pixels with depth.
    pub valid_px: usize,
    /// Boundary pixels.
    pub boundary_px: usize,
    /// Pixels at or above the hazard threshold.
    pub hazard_px: usize,
    /// Time of `annotate` on the frame, ms (mean when pooled).
    pub ms: f64,
}

/// One frame's results.
#[derive(Debug, Clone, Serialize)]
pub struct FrameReport {
    /// `sequence/depth`.
    pub name: String,
    /// The RGB file.
    pub rgb: PathBuf,
    /// The depth file.
    pub depth: PathBuf,
    /// `(width, height)`.
    pub size: (usize, usize),
    /// The floor box, if any.
    pub floor_box: Option<[usize; 4]>,
    /// The spec on the sensor depth.
    pub spec: SpecSummary,
    /// Each configuration.
    pub rows: Vec<RealRow>,
}

/// The whole report (`--json`).
#[derive(Debug, Clone, Serialize)]
pub struct RealReport {
    /// The folder scored.
    pub data: PathBuf,
    /// Frames scored.
    pub frames: usize,
    /// Hazard threshold, metres.
    pub hazard_m: f64,
    /// Flat threshold of the false-hazard rate, metres.
    pub flat_m: f64,
    /// Range bins: `(name, from_m, to_m)`.
    pub range_bins: Vec<(String, f64, f64)>,
    /// The spec pooled over frames.
    pub spec: SpecSummary,
    /// Each configuration pooled over frames (pixels pooled).
    pub pooled: Vec<RealRow>,
    /// Each frame.
    pub per_frame: Vec<FrameReport>,
}

/// The configurations scored: the learned modes asked for with `base`'s switches, and the
/// geometric mode both as the spec (default) and as the paper's surface-only baseline; slope
/// is left out of traversability (the frames' mountings are unknown).
pub fn real_rows(modes: &[Mode], base: &PipelineConfig) -> Vec<(String, PipelineConfig)> {
    // The frames' mountings are unknown, so slope (which needs the pitch) does not count:
    // the three-state map judges roughness and noise alone.
    let base = &PipelineConfig {
        traversability: crate::pipeline::Traversability {
            max_slope_rad: std::f64::consts::FRAC_PI_2,
            ..base.traversability
        },
        ..*base
    };
    let mut cfgs = Vec::new();
    for &mode in modes {
        if mode == Mode::Geometric {
            for geometric in [GeometricMethod::Spec, GeometricMethod::SurfaceOnly] {
                cfgs.push(PipelineConfig {
                    mode,
                    geometric,
                    ..*base
                });
            }
        } else {
            cfgs.push(PipelineConfig { mode, ..*base });
        }
    }
    cfgs.into_iter()
        .map(|c| (super::eval::row_key(&c), c))
        .collect()
}

/// Accumulators of one configuration.
#[derive(Default)]
struct RowAcc {
    scores: RangeScores,
    floor: Vec<f64>,
    floor_missing: usize,
    depth: DepthAccumulator,
    has_depth: bool,
    traversal: Option<TraversalAcc>,
    ms: BTreeMap<String, f64>,
}

impl RowAcc {
    fn finish(&self, key: &str, frames: usize, has_floor: bool) -> RealRow {
        let n = frames.max(1) as f64;
        RealRow {
            key: key.to_owned(),
            all: self.scores.all.finish(),
            by_range: RANGE_BINS
                .iter()
                .zip(&self.scores.by_range)
                .map(|(&(name, _, _), s)| (name.to_owned(), s.finish()))
                .collect(),
            floor: has_floor.then(|| floor_stats(self.floor.clone(), self.floor_missing)),
            depth: self.has_depth.then(|| self.depth.finish()),
            traversal: self.traversal.as_ref().map(|t| t.finish(has_floor)),
            ms: self.ms.iter().map(|(k, v)| (k.clone(), v / n)).collect(),
        }
    }

    fn merge(&mut self, other: &Self) {
        self.scores.merge(&other.scores);
        self.floor.extend_from_slice(&other.floor);
        self.floor_missing += other.floor_missing;
        self.depth.merge(&other.depth);
        self.has_depth |= other.has_depth;
        if let Some(t) = &other.traversal {
            self.traversal.get_or_insert_with(Default::default).merge(t);
        }
        for (k, v) in &other.ms {
            *self.ms.entry(k.clone()).or_default() += v;
        }
    }
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
pub fn load_frame(frame: &RealFrame) -> anyhow::Result<LoadedFrame> {
    let scale = frame.camera.depth_scale.unwrap_or(1000.0);
    let depth_m = io::read_depth(&frame.depth, scale)?;
    let rgb = io::read_image(&frame.rgb)?.to_rgb8();
    let start = Instant::now();
    let spec = annotate(
        &AnnotateInput {
            depth_m: &depth_m,
            intrinsics: &frame.intrinsics,
            normals: None,
            labels: None,
        },
        &AnnotateConfig::default(),
    )?;
    let spec_ms = start.elapsed().as_secs_f64() * 1e3;
    let input = FrameInput {
        rgb: Some(rgb),
        depth_m: Some(depth_m),
        intrinsics: Some(frame.intrinsics),
        mounting: frame.camera.mounting()?,
    };
    Ok(LoadedFrame {
        input,
        spec,
        spec_ms,
    })
}

/// Runs the benchmark: every frame, every configuration; the modes that read sensor depth also
/// get the uncertainty and three-state maps under `sensor`'s noise model (or the frame's camera
/// file's, when it names one). Calls `on_frame` with each frame's maps (for the contact
/// sheets) once it is scored.
///
/// # Errors
///
/// When a frame does not read or a configuration fails on it.
pub fn run_benchmark(
    data: &Path,
    frames: &[RealFrame],
    floors: &Floors,
    rows: &[(String, PipelineConfig)],
    pipeline: &mut Pipeline,
    sensor: &SensorNoise,
    mut on_frame: impl FnMut(&RealFrame, &LoadedFrame, &[RowMaps]) -> anyhow::Result<()>,
) -> anyhow::Result<RealReport> {
    let mut pooled: Vec<RowAcc> = rows.iter().map(|_| RowAcc::default()).collect();
    let (mut spec_floor, mut spec_missing, mut spec_ms) = (Vec::new(), 0, 0.0);
    let (mut valid_px, mut boundary_px, mut hazard_px) = (0, 0, 0);
    let mut per_frame = Vec::new();
    let any_floor = frames
        .iter()
        .any(|f| floors.contains_key(&(f.sequence.clone(), f.depth_rel.clone())));
    for (i, frame) in frames.iter().enumerate() {
        let loaded = load_frame(frame).with_context(|| frame.name())?;
        let floor_box = floors
            .get(&(frame.sequence.clone(), frame.depth_rel.clone()))
            .copied();
        let spec = spec_summary(&loaded, floor_box);
        if let Some(b) = floor_box {
            let (v, m) = box_values(&loaded.spec.roughness_m, b);
            spec_floor.extend(v);
            spec_missing += m;
        }
        (valid_px, boundary_px, hazard_px, spec_ms) = (
            valid_px + spec.valid_px,
            boundary_px + spec.boundary_px,
            hazard_px + spec.hazard_px,
            spec_ms + spec.ms,
        );
        let mut maps = Vec::new();
        let mut reports = Vec::new();
        for ((key, cfg), acc) in rows.iter().zip(&mut pooled) {
            let sensor = frame_sensor(frame, sensor);
            let (one, map) = score_row(pipeline, &loaded, cfg, floor_box, &sensor)
                .with_context(|| format!("{}: {key}", frame.name()))?;
            reports.push(one.finish(key, 1, floor_box.is_some()));
            acc.merge(&one);
            maps.push(map);
        }
        on_frame(frame, &loaded, &maps)?;
        per_frame.push(FrameReport {
            name: frame.name(),
            rgb: frame.rgb.clone(),
            depth: frame.depth.clone(),
            size: loaded.spec.roughness_m.size(),
            floor_box,
            spec,
            rows: reports,
        });
        tracing::info!("{}/{} frames: {}", i + 1, frames.len(), frame.name());
    }
    let n = frames.len();
    Ok(RealReport {
        data: data.to_owned(),
        frames: n,
        hazard_m: HAZARD_M,
        flat_m: FLAT_M,
        range_bins: RANGE_BINS
            .iter()
            .map(|&(name, a, b)| (name.to_owned(), a, b))
            .collect(),
        spec: SpecSummary {
            floor: any_floor.then(|| floor_stats(spec_floor, spec_missing)),
            valid_px,
            boundary_px,
            hazard_px,
            ms: spec_ms / n.max(1) as f64,
        },
        pooled: rows
            .iter()
            .zip(&pooled)
            .map(|((key, _), acc)| acc.finish(key, n, any_floor))
            .collect(),
        per_frame,
    })
}

/// The spec's own figures on a frame.
fn spec_summary(loaded: &LoadedFrame, floor_box: Option<[usize; 4]>) -> SpecSummary {
    let r = &loaded.spec.roughness_m;
    SpecSummary {
        floor: floor_box.map(|b| {
            let (v, m) = box_values(r, b);
            floor_stats(v, m)
        }),
        valid_px: r.as_slice().iter().filter(|v| v.is_finite()).count(),
        boundary_px: loaded
            .spec
            .boundary
            .as_slice()
            .iter()
            .filter(|&&b| b)
            .count(),
        hazard_px: r.as_slice().iter().filter(|&&v| v >= HAZARD_M).count(),
        ms: loaded.spec_ms,
    }
}

/// Runs one configuration on a loaded frame and scores it; returns its roughness map too.
fn score_row(
    pipeline: &mut Pipeline,
    loaded: &LoadedFrame,
    cfg: &PipelineConfig,
    floor_box: Option<[usize; 4]>,
    sensor: &SensorNoise,
) -> anyhow::Result<(RowAcc, RowMaps)> {
    let out = pipeline.run(&loaded.input, cfg)?;
    let sensor_depth = loaded
        .input
        .depth_m
        .as_ref()
        .context("a real frame has depth")?;
    let mut acc = RowAcc::default();
    let spec = &loaded.spec;
    acc.scores.add(
        &out.roughness_m,
        &spec.roughness_m,
        &spec.boundary,
        sensor_depth,
    )?;
    if let Some(b) = floor_box {
        let (v, m) = box_values(&out.roughness_m, b);
        acc.floor = v;
        acc.floor_missing = m;
    }
    if cfg.mode == Mode::Rgb {
        if let Some(depth) = out.depth_m() {
            acc.depth.add(&depth, sensor_depth)?;
            acc.has_depth = true;
        }
    }
    for (name, took) in out.timings.iter() {
        *acc.ms.entry(name.to_owned()).or_default() += took.as_secs_f64() * 1e3;
    }
    acc.ms
        .insert("total".to_owned(), out.timings.total().as_secs_f64() * 1e3);
    let mut traversal = None;
    if cfg.mode != Mode::Rgb {
        let maps = out.sensor_maps(&loaded.input, cfg.mode, Some(sensor), None)?;
        let mut t = TraversalAcc::default();
        t.add(&maps, loaded, floor_box);
        acc.traversal = Some(t);
        traversal = Some(maps.traversal);
    }
    let maps = RowMaps {
        roughness_m: out.roughness_m.clone(),
        traversal,
    };
    pipeline.recycle(out);
    Ok((acc, maps))
}

/// One configuration's maps on a frame, for the contact sheet.
pub struct RowMaps {
    /// Roughness, metres (NaN: none).
    pub roughness_m: Grid<f64>,
    /// The three-state map, for modes that read sensor depth.
    pub traversal: Option<Grid<Traversal>>,
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

/// `x` as a percentage with one decimal, `–` for NaN.
fn pct(x: f64) -> String {
    if x.is_nan() {
        "–".to_owned()
    } else {
        format!("{:.1}%", 100.0 * x)
    }
}

/// `x` with `d` decimals, `–` for NaN or none.
fn num(x: Option<f64>, d: usize) -> String {
    match x {
        Some(v) if v.is_finite() => format!("{v:.d$}"),
        _ => "–".to_owned(),
    }
}

/// The report as markdown: pooled figures, the split by range, each frame, and the `rgb`
/// depth errors.
pub fn markdown(report: &RealReport) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Real frames: {} from {}; the spec is annotation spec v1 on the same sensor depth \
         (`tre annotate`). Edge recall: spec ≥ {} cm read ≥ {} cm; false hazards: spec < {} cm \
         read ≥ {} cm.\n",
        report.frames,
        report.data.display(),
        100.0 * report.hazard_m,
        100.0 * report.hazard_m,
        100.0 * report.flat_m,
        100.0 * report.hazard_m
    );
    let floor =
        |f: &Option<FloorStats>| (num(f.map(|f| f.median_cm), 2), num(f.map(|f| f.p90_cm), 2));
    out.push_str("| row | RMSE | B-RMSE | F-RMSE | edge recall | false hazards | floor median (cm) | floor p90 (cm) | ms/frame |\n|---|---|---|---|---|---|---|---|---|\n");
    let (m, p) = floor(&report.spec.floor);
    let _ = writeln!(
        out,
        "| spec (`tre annotate`) | 0 | 0 | 0 | – | – | {m} | {p} | {:.1} |",
        report.spec.ms
    );
    for r in &report.pooled {
        let (m, p) = floor(&r.floor);
        let rough = &r.all.roughness;
        let _ = writeln!(
            out,
            "| {} | {:.3} | {:.3} | {:.3} | {} | {} | {m} | {p} | {} |",
            r.key,
            rough.rmse_cm,
            rough.b_rmse_cm,
            rough.f_rmse_cm,
            pct(r.all.hazard.edge_recall),
            pct(r.all.hazard.false_hazards),
            num(r.ms.get("total").copied(), 1),
        );
    }
    out.push_str("\nBy range (sensor depth), pooled:\n\n| row | range | px | RMSE (cm) | edge recall | false hazards |\n|---|---|---|---|---|---|\n");
    for r in &report.pooled {
        for (name, s) in &r.by_range {
            let _ = writeln!(
                out,
                "| {} | {name} | {} | {} | {} | {} |",
                r.key,
                s.roughness.pixels,
                num(Some(s.roughness.rmse_cm), 3),
                pct(s.hazard.edge_recall),
                pct(s.hazard.false_hazards),
            );
        }
    }
    out.push_str("\nPer frame:\n\n| frame | row | floor median (cm) | floor p90 (cm) | edge recall | false hazards | RMSE (cm) |\n|---|---|---|---|---|---|---|\n");
    for f in &report.per_frame {
        let (m, p) = floor(&f.spec.floor);
        let _ = writeln!(out, "| {} | spec | {m} | {p} | – | – | 0 |", f.name);
        for r in &f.rows {
            let (m, p) = floor(&r.floor);
            let _ = writeln!(
                out,
                "| {} | {} | {m} | {p} | {} | {} | {:.3} |",
                f.name,
                r.key,
                pct(r.all.hazard.edge_recall),
                pct(r.all.hazard.false_hazards),
                r.all.roughness.rmse_cm,
            );
        }
    }
    traversal_table(&mut out, report);
    depth_table(&mut out, report);
    out
}

/// The three-state maps, pooled: shares over every pixel and the three checks.
fn traversal_table(out: &mut String, report: &RealReport) {
    use std::fmt::Write;
    out.push_str("\nThree-state traversability under the sensor's noise model (slope left out: the mountings are unknown), pooled:\n\n| row | traversable | hazard | unknown | floor boxes within 2 m: traversable | … unknown | beyond 4 m, spec ≥ 5 cm: unknown | … hazard | drops (spec ≥ 10 cm) within 4 m: hazard | median uncertainty < 2 m / 2–4 m / > 4 m (cm) |\n|---|---|---|---|---|---|---|---|---|---|\n");
    for r in &report.pooled {
        let Some(t) = &r.traversal else { continue };
        let u = |k: &str| num(t.median_uncertainty_m.get(k).map(|u| 100.0 * u), 2);
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} / {} / {} |",
            r.key,
            pct(t.all.traversable),
            pct(t.all.hazard),
            pct(t.all.unknown),
            t.near_floor.map_or("–".to_owned(), |f| pct(f.traversable)),
            t.near_floor.map_or("–".to_owned(), |f| pct(f.unknown)),
            pct(t.far_spec_rough.unknown),
            pct(t.far_spec_rough.hazard),
            pct(t.near_drops.hazard),
            u("0_2m"),
            u("2_4m"),
            u("4m_up"),
        );
    }
}

/// The `rgb` mode's depth errors against the sensor, per frame and pooled.
fn depth_table(out: &mut String, report: &RealReport) {
    use std::fmt::Write;
    let Some(pooled) = report.pooled.iter().find_map(|r| r.depth.map(|d| (r, d))) else {
        return;
    };
    let _ = writeln!(
        out,
        "\nDepth of `{}` against the sensor:\n\n| frame | AbsRel | RMSE (m) | δ < 1.25 |\n|---|---|---|---|",
        pooled.0.key
    );
    let line = |out: &mut String, name: &str, d: &DepthMetrics| {
        let _ = writeln!(
            out,
            "| {name} | {:.3} | {:.3} | {} |",
            d.abs_rel,
            d.rmse_m,
            pct(d.delta_1_25)
        );
    };
    for f in &report.per_frame {
        if let Some(d) = f.rows.iter().find_map(|r| r.depth) {
            line(out, &f.name, &d);
        }
    }
    line(out, "pooled", &pooled.1);
}

/// Top of the contact sheets' shared colour scale, metres.
pub const SHEET_MAX_M: f64 = 0.10;

/// `map` at half size, each pixel the largest of its 2×2 block (NaN where all four are), so
/// one-pixel edges stay visible.
fn max_pool2(map: &Grid<f64>) -> Grid<f64> {
    let (w, h) = map.size();
    Grid::from_fn(w.div_ceil(2), h.div_ceil(2), |x, y| {
        let mut best = f64::NAN;
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            if let Some(&v) = map.get(2 * x + dx, 2 * y + dy) {
                best = best.max(v);
            }
        }
        best
    })
}

/// The panels of a frame's contact sheet at half size: the RGB image, the spec, then each
/// configuration's roughness, titled; roughness in one colour scale ([`SHEET_MAX_M`]).
pub fn sheet_panels(
    loaded: &LoadedFrame,
    rows: &[(String, PipelineConfig)],
    maps: &[RowMaps],
) -> Vec<Panel> {
    let colour = |m: &Grid<f64>| roughness_panel(&max_pool2(m), SHEET_MAX_M);
    let mut panels = Vec::new();
    if let Some(rgb) = &loaded.input.rgb {
        let (w, h) = (rgb.width().div_ceil(2), rgb.height().div_ceil(2));
        let small = image::imageops::resize(rgb, w, h, image::imageops::FilterType::Triangle);
        panels.push(Panel::new("RGB", small));
    }
    panels.push(Panel::new(
        "spec (tre annotate)",
        colour(&loaded.spec.roughness_m),
    ));
    for ((key, _), map) in rows.iter().zip(maps) {
        panels.push(Panel::new(key.clone(), colour(&map.roughness_m)));
    }
    // The three-state map of the geometric mode (the spec), else of the first that has one.
    let with_map = || {
        rows.iter()
            .zip(maps)
            .filter_map(|(r, m)| m.traversal.as_ref().map(|t| (r, t)))
    };
    let spec_first = with_map()
        .find(|((_, c), _)| c.mode == Mode::Geometric && c.geometric == GeometricMethod::Spec)
        .or_else(|| with_map().next());
    if let Some(((key, _), t)) = spec_first {
        let half = Grid::from_fn(t.width().div_ceil(2), t.height().div_ceil(2), |x, y| {
            t[(2 * x, 2 * y)]
        });
        let mode = key.split(':').next().unwrap_or(key);
        panels.push(Panel::new(
            format!("three-state ({mode})"),
            traversal_panel(&half),
        ));
    }
    panels
}

/// Colours of the three states on the contact sheets.
pub const STATE_COLOURS: [(&str, Rgb<u8>); 3] = [
    ("traversable", Rgb([60, 170, 90])),
    ("hazard", Rgb([210, 40, 40])),
    ("unknown (noise or no data)", Rgb([150, 150, 220])),
];

/// A three-state map in [`STATE_COLOURS`].
fn traversal_panel(t: &Grid<Traversal>) -> image::RgbImage {
    image::RgbImage::from_fn(t.width() as u32, t.height() as u32, |x, y| {
        match t[(x as usize, y as usize)] {
            Traversal::Traversable => STATE_COLOURS[0].1,
            Traversal::Hazard => STATE_COLOURS[1].1,
            Traversal::Unknown => STATE_COLOURS[2].1,
        }
    })
}

/// Writes `DIR/<sequence>_<depth stem>.png`: the frame's panels in a grid of three columns
/// over the colour scale's legend.
///
/// # Errors
///
/// When the file cannot be written.
pub fn write_sheet(
    dir: &Path,
    frame: &RealFrame,
    loaded: &LoadedFrame,
    rows: &[(String, PipelineConfig)],
    maps: &[RowMaps],
) -> anyhow::Result<()> {
    let panels = sheet_panels(loaded, rows, maps);
    let width = panels.first().map_or(320, |p| p.image.width()) * 2;
    let legend = stack(&[
        colour_bar_legend(width, SHEET_MAX_M, &[0.0, 1.0, 2.0, 5.0, 10.0]),
        categorical_legend(&STATE_COLOURS),
    ]);
    let sheet = contact_sheet(&panels, 4, Some(&legend));
    let stem = frame
        .depth_rel
        .trim_end_matches(".png")
        .replace(['/', '\\'], "_");
    let path = dir.join(format!("{}_{stem}.png", frame.sequence));
    io::save(&path, &image::DynamicImage::ImageRgb8(sheet))?;
    Ok(())
}
