//! `tre synth`: scenes → views → frames on disk, with a manifest split by scene and a contact
//! sheet. Deterministic by seed: the same seed gives the same bytes.

use std::path::{Path, PathBuf};

use image::{DynamicImage, RgbImage};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::appearance::{Conditions, Lighting, Weather};
use super::content::Content;
use super::heightgrid::HeightGrid;
use super::imaging::{ImageEffect, Imaging};
use super::render::{render, RenderedFrame, Scene, View};
use super::sensor::{simulate, SensorInput, SensorModel};
use super::terrain::{Category, Terrain};
use tre_core::geometry::hash::splitmix64;
use tre_core::geometry::{Grid, Intrinsics, Mounting, Vec3};
use tre_core::roughness::noise::SensorPreset;
use tre_core::roughness::{annotate, AnnotateConfig, AnnotateInput, RoughnessError};
use tre_io::{self as io, IoError};

/// Dataset settings, with the paper's camera by default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SynthConfig {
    /// Output folder (not written to the manifest, so that a dataset is the same wherever it
    /// is written).
    #[serde(skip)]
    pub out: PathBuf,
    /// Number of scenes.
    pub scenes: u32,
    /// Dataset seed.
    pub seed: u64,
    /// Image width and height, pixels.
    pub size: (usize, usize),
    /// Horizontal field of view, degrees.
    pub hfov_deg: f64,
    /// Views per scene, spread evenly over `[-yaw_span, +yaw_span]` (9 over ±60°: 15° steps).
    pub views: u32,
    /// Half the yaw span, degrees.
    pub yaw_span_deg: f64,
    /// Draw camera height (0.4–1.2 m) and pitch (40–75°) per scene instead of 1 m and 60°.
    pub random_mounting: bool,
    /// Share of scenes in the test split.
    pub test_fraction: f64,
    /// Grid spacing of the rendered surface, metres.
    pub cell_m: f64,
    /// Write a PLY point cloud per frame.
    pub ply: bool,
    /// Depth sensors: one is used for every frame; with several, each frame draws one
    /// (uniformly, from the frame's seed). `exact` copies the exact depth.
    #[serde(default = "default_sensors")]
    pub sensors: Vec<SensorPreset>,
    /// Image-formation effects applied to `rgb.png`, each drawn per frame (none by default:
    /// the rendered image as it is).
    #[serde(default)]
    pub effects: Vec<ImageEffect>,
    /// What the scenes show: natural terrain (the default, left out of `dataset.json` so that
    /// natural datasets keep their bytes), indoor rooms, urban street edges, or a mix.
    #[serde(default, skip_serializing_if = "Content::is_natural")]
    pub content: Content,
    /// Draw every frame's mounting and optics from [`OPTICS`]: pitch, height, roll, horizontal
    /// field of view and frame shape (the width stays `size.0`). Overrides `random_mounting`,
    /// `hfov_deg` and `size.1`. Left out of `dataset.json` when off.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub random_optics: bool,
    /// Keep the complete frames of an interrupted run with the same settings and write only
    /// the others (a run option, not written to the manifest).
    #[serde(skip)]
    pub resume: bool,
}

fn default_sensors() -> Vec<SensorPreset> {
    vec![SensorPreset::Exact]
}

impl Default for SynthConfig {
    fn default() -> Self {
        Self {
            out: PathBuf::from("data/synth"),
            scenes: 4,
            seed: 0,
            size: (512, 512),
            hfov_deg: 60.0,
            views: 9,
            yaw_span_deg: 60.0,
            random_mounting: false,
            test_fraction: 0.2,
            cell_m: 0.004,
            ply: true,
            sensors: default_sensors(),
            effects: Vec::new(),
            content: Content::Natural,
            random_optics: false,
            resume: false,
        }
    }
}

/// Errors of dataset generation.
#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    /// Writing failed.
    #[error(transparent)]
    Io(#[from] IoError),
    /// Annotation failed (a frame saw no ground).
    #[error("scene {scene} view {view}: {source}")]
    Annotate {
        /// Scene index.
        scene: u32,
        /// View index.
        view: u32,
        /// Why.
        source: RoughnessError,
    },
    /// A bad setting.
    #[error("{0}")]
    Config(String),
}

/// One frame's entry in the manifest.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FrameEntry {
    /// Folder of the frame, relative to the dataset root.
    pub dir: String,
    /// View index within the scene.
    pub view: u32,
    /// Heading, degrees.
    pub yaw_deg: f64,
    /// Light.
    pub lighting: Lighting,
    /// Weather.
    pub weather: Weather,
    /// The depth sensor of `depth_sensor.png`.
    #[serde(default = "exact_sensor")]
    pub sensor: SensorPreset,
}

fn exact_sensor() -> SensorPreset {
    SensorPreset::Exact
}

/// One scene's entry in the manifest.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SceneEntry {
    /// Scene index.
    pub scene: u32,
    /// `train` or `test`.
    pub split: String,
    /// Camera height, metres.
    pub height_m: f64,
    /// Camera pitch, degrees below the horizon.
    pub pitch_deg: f64,
    /// The scene's family (indoor or urban; left out for natural scenes).
    #[serde(default, skip_serializing_if = "Content::is_natural")]
    pub content: Content,
    /// Categories of the scene's regions, then of its objects (indoor and urban scenes).
    pub categories: Vec<Category>,
    /// Frames.
    pub frames: Vec<FrameEntry>,
}

/// The dataset manifest (`dataset.json`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Manifest {
    /// Settings used.
    pub config: SynthConfig,
    /// Label values and names.
    pub labels: Vec<(u8, String)>,
    /// Scenes with their split and frames.
    pub scenes: Vec<SceneEntry>,
    /// Frames in the train and test splits.
    pub counts: (usize, usize),
}

/// Generates the dataset described by `cfg`; returns its manifest (also written to disk).
pub fn generate(cfg: &SynthConfig) -> Result<Manifest, SynthError> {
    check(cfg)?;
    start_run(cfg)?;
    // Scenes in parallel, and the views of each (rayon's pool: every core).
    let done: Vec<(SceneEntry, Vec<RgbImage>)> = (0..cfg.scenes)
        .into_par_iter()
        .map(|s| generate_scene(cfg, s))
        .collect::<Result<_, _>>()?;
    let mut scenes = Vec::new();
    let mut sheet = Vec::new();
    for (entry, preview) in done {
        sheet.extend(preview);
        scenes.push(entry);
    }
    let count = |split: &str| {
        scenes
            .iter()
            .filter(|e| e.split == split)
            .map(|e| e.frames.len())
            .sum()
    };
    let labels = (cfg.content.labels().iter())
        .map(|c| (c.label(), c.name().to_string()))
        .collect();
    let manifest = Manifest {
        config: cfg.clone(),
        labels,
        counts: (count("train"), count("test")),
        scenes,
    };
    let json =
        serde_json::to_string_pretty(&manifest).map_err(|e| SynthError::Config(e.to_string()))?;
    std::fs::write(cfg.out.join("dataset.json"), json).map_err(IoError::from)?;
    io::save(
        &cfg.out.join("contact_sheet.png"),
        &DynamicImage::ImageRgb8(contact_sheet(&sheet)),
    )?;
    std::fs::remove_file(cfg.out.join(RUN_FILE)).map_err(IoError::from)?;
    Ok(manifest)
}

/// The settings of a run in progress, beside its frames until `dataset.json` is written.
pub const RUN_FILE: &str = "dataset.partial.json";

/// Creates the output folder and records the run's settings in [`RUN_FILE`]. With `resume`, the
/// settings of the run found there (in progress, or finished in `dataset.json`) must be these.
fn start_run(cfg: &SynthConfig) -> Result<(), SynthError> {
    std::fs::create_dir_all(&cfg.out).map_err(IoError::from)?;
    let settings = serde_json::to_value(cfg).map_err(|e| SynthError::Config(e.to_string()))?;
    let run_file = cfg.out.join(RUN_FILE);
    if cfg.resume {
        let read = |path: &Path| -> Option<serde_json::Value> {
            let text = std::fs::read_to_string(path).ok()?;
            serde_json::from_str(&text).ok()
        };
        let previous = read(&run_file)
            .or_else(|| read(&cfg.out.join("dataset.json")).map(|m| m["config"].clone()));
        match previous {
            Some(p) if p != settings => {
                return Err(SynthError::Config(format!(
                    "cannot resume {}: it was started with other settings ({}); use them, \
                     or another --out",
                    cfg.out.display(),
                    serde_json::to_string(&p).unwrap_or_default()
                )))
            }
            None if cfg.out.join("scene_00000").exists() => {
                return Err(SynthError::Config(format!(
                    "cannot resume {}: its frames carry no record of their settings",
                    cfg.out.display()
                )))
            }
            _ => {}
        }
    }
    let json =
        serde_json::to_string_pretty(&settings).map_err(|e| SynthError::Config(e.to_string()))?;
    std::fs::write(run_file, json).map_err(IoError::from)?;
    Ok(())
}

fn check(cfg: &SynthConfig) -> Result<(), SynthError> {
    let (w, h) = cfg.size;
    if w == 0 || h == 0 || w.checked_mul(h).is_none_or(|n| n > 4096 * 4096) {
        return Err(SynthError::Config(format!(
            "image size {w}×{h} must be between 1×1 and 4096×4096"
        )));
    }
    if !(cfg.hfov_deg > 1.0 && cfg.hfov_deg < 170.0) || cfg.views == 0 || !(cfg.cell_m > 0.0005) {
        return Err(SynthError::Config(
            "need 1° < hfov < 170°, at least one view, cell ≥ 0.5 mm".into(),
        ));
    }
    if cfg.scenes == 0 {
        return Err(SynthError::Config("need at least one scene".into()));
    }
    if cfg.sensors.is_empty() {
        return Err(SynthError::Config(format!(
            "need at least one depth sensor (one of {})",
            SensorPreset::names()
        )));
    }
    if !(0.0..=1.0).contains(&cfg.test_fraction) {
        return Err(SynthError::Config(format!(
            "the test fraction must be between 0 and 1, got {}",
            cfg.test_fraction
        )));
    }
    Ok(())
}

/// Deterministic uniform number for (seed, scene, what).
fn draw(seed: u64, scene: u32, what: u64) -> f64 {
    let h = splitmix64(splitmix64(seed ^ 0xDA7A) ^ (u64::from(scene) << 16) ^ what);
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// The scene's camera mounting.
pub fn scene_mounting(cfg: &SynthConfig, scene: u32) -> Mounting {
    if !cfg.random_mounting {
        return Mounting::default();
    }
    let height = 0.4 + 0.8 * draw(cfg.seed, scene, 1);
    let pitch = (40.0 + 35.0 * draw(cfg.seed, scene, 2)).to_radians();
    Mounting::new(pitch, height).expect("pitch and height drawn in range; this is a bug")
}

/// The ranges `--random-optics` draws each frame's camera from, uniformly.
pub struct OpticsRanges {
    /// Pitch below the horizon, degrees.
    pub pitch_deg: (f64, f64),
    /// Height above the ground, metres.
    pub height_m: (f64, f64),
    /// Roll about the optical axis, degrees.
    pub roll_deg: (f64, f64),
    /// Horizontal field of view, degrees.
    pub hfov_deg: (f64, f64),
    /// Frame shapes, height over width: 4:3, 16:9 and KITTI's 1242×375.
    pub aspects: [f64; 3],
}

/// The documented ranges of `--random-optics`.
pub const OPTICS: OpticsRanges = OpticsRanges {
    pitch_deg: (0.0, 85.0),
    height_m: (0.2, 2.0),
    roll_deg: (-10.0, 10.0),
    hfov_deg: (45.0, 110.0),
    aspects: [3.0 / 4.0, 9.0 / 16.0, 375.0 / 1242.0],
};

/// A frame's view under `--random-optics`: every quantity drawn from [`OPTICS`] with the
/// dataset seed, the scene and the view.
fn random_view(cfg: &SynthConfig, scene: u32, view: u32, yaw_rad: f64) -> View {
    let pick = |what: u64| {
        draw(
            cfg.seed,
            scene,
            (u64::from(view) << 32) | (0x0F71 << 8) | what,
        )
    };
    let lerp = |(lo, hi): (f64, f64), t: f64| lo + (hi - lo) * t;
    let pitch = lerp(OPTICS.pitch_deg, pick(1)).to_radians();
    let height = lerp(OPTICS.height_m, pick(2));
    let roll = lerp(OPTICS.roll_deg, pick(3)).to_radians();
    let hfov = lerp(OPTICS.hfov_deg, pick(4));
    let aspect = OPTICS.aspects[((pick(5) * 3.0) as usize).min(2)];
    let w = cfg.size.0;
    let h = ((w as f64 * aspect / 2.0).round() as usize * 2).max(2);
    View {
        mounting: Mounting::new(pitch, height)
            .expect("pitch and height drawn in range; this is a bug"),
        yaw_rad,
        roll_rad: roll,
        intrinsics: Intrinsics::from_hfov(w, h, hfov).expect("hfov drawn in range; this is a bug"),
        width: w,
        height: h,
    }
}

/// The views of a scene.
pub fn scene_views(cfg: &SynthConfig, scene: u32) -> Vec<View> {
    // The fixed camera of every view, unless each view draws its own.
    let (w, h) = cfg.size;
    let fixed = (!cfg.random_optics).then(|| {
        let k = Intrinsics::from_hfov(w, h, cfg.hfov_deg).expect("hfov checked; this is a bug");
        (k, scene_mounting(cfg, scene))
    });
    (0..cfg.views)
        .map(|v| {
            let f = if cfg.views == 1 {
                0.5
            } else {
                f64::from(v) / f64::from(cfg.views - 1)
            };
            let yaw = (-cfg.yaw_span_deg + 2.0 * cfg.yaw_span_deg * f).to_radians();
            match fixed {
                Some((intrinsics, mounting)) => View {
                    mounting,
                    yaw_rad: yaw,
                    roll_rad: 0.0,
                    intrinsics,
                    width: w,
                    height: h,
                },
                None => random_view(cfg, scene, v, yaw),
            }
        })
        .collect()
}

/// How far ahead a view can see ground, metres (capped at 12 m).
fn reach(view: &View) -> f64 {
    let vfov_half = (view.height as f64 / 2.0 / view.intrinsics.fy_px).atan();
    let lowest = (view.mounting.pitch_rad - vfov_half).max(5f64.to_radians());
    (view.mounting.height_m / lowest.tan()).min(12.0)
}

/// Builds scene `s`: terrain and its sampled grid, covering what its views can see.
pub fn build_scene(cfg: &SynthConfig, s: u32, views: &[View]) -> Scene {
    let terrain = scene_terrain(cfg, s, views);
    sample_scene(cfg, views, terrain)
}

/// How far the scene's grid reaches: the farthest ground its views see, plus 0.5 m.
fn scene_reach(views: &[View]) -> f64 {
    views.iter().map(reach).fold(1.0f64, f64::max) + 0.5
}

/// The terrain of scene `s` (of the dataset's content), with content within its views' reach.
pub fn scene_terrain(cfg: &SynthConfig, s: u32, views: &[View]) -> Terrain {
    let r = scene_reach(views);
    cfg.content.terrain(cfg.seed, u64::from(s), r.min(4.0))
}

/// Samples `terrain`'s grid over what `views` can see.
fn sample_scene(cfg: &SynthConfig, views: &[View], terrain: Terrain) -> Scene {
    let r = scene_reach(views);
    let grid = HeightGrid::sample(&terrain, (-r, -0.8), (r, r), cfg.cell_m);
    Scene { terrain, grid }
}

/// Conditions of view `v` of scene `s`: the 4 lightings × 5 weathers cycle so that every 20
/// consecutive frames hold each combination once; the sun's azimuth is drawn per scene.
pub fn view_conditions(cfg: &SynthConfig, s: u32, v: u32) -> Conditions {
    // Frame k takes combination 7k mod 20 (7 is prime to 20): every 20 frames hold all 20.
    let k = (u64::from(s) * u64::from(cfg.views) + u64::from(v)) as usize;
    let combo = (7 * k) % 20;
    Conditions {
        lighting: Lighting::ALL[combo % 4],
        weather: Weather::ALL[combo / 4],
        sun_azimuth_rad: draw(cfg.seed, s, 3) * std::f64::consts::TAU,
    }
}

/// The depth sensor of view `v` of scene `s` and the seed of its noise.
pub fn view_sensor(cfg: &SynthConfig, s: u32, v: u32) -> (SensorPreset, u64) {
    let what = 0x5E45_0000 | u64::from(v);
    let seed = splitmix64(splitmix64(cfg.seed ^ 0x5E45) ^ (u64::from(s) << 20) ^ what);
    let n = cfg.sensors.len().max(1);
    let pick = ((draw(cfg.seed, s, what) * n as f64) as usize).min(n - 1);
    let sensor = cfg
        .sensors
        .get(pick)
        .copied()
        .unwrap_or(SensorPreset::Exact);
    (sensor, seed)
}

/// The folder of view `v` of scene `s`, relative to the dataset root.
fn frame_dir(s: u32, v: u32) -> String {
    format!("scene_{s:05}/view_{v}")
}

/// Whether view `v` of scene `s` gives a row of the dataset's contact sheet.
fn in_sheet(s: u32, v: u32) -> bool {
    s < 2 && v.is_multiple_of(4)
}

fn generate_scene(cfg: &SynthConfig, s: u32) -> Result<(SceneEntry, Vec<RgbImage>), SynthError> {
    let views = scene_views(cfg, s);
    let terrain = scene_terrain(cfg, s, &views);
    let categories = (terrain.regions.iter().map(|r| r.category))
        .chain(terrain.objects.iter().map(|o| o.category))
        .collect();
    // A resumed run keeps complete frames (their folders exist: each is renamed into place
    // once written); the scene is sampled only if a frame is missing or gives a sheet row.
    let kept: Vec<bool> = (0..cfg.views)
        .map(|v| cfg.resume && cfg.out.join(frame_dir(s, v)).is_dir())
        .collect();
    let needed = (0..cfg.views).any(|v| !kept[v as usize] || in_sheet(s, v));
    let scene = needed.then(|| sample_scene(cfg, &views, terrain));
    // Views render, annotate and encode in parallel (each also parallel inside).
    let done: Vec<(FrameEntry, Option<RgbImage>)> = views
        .par_iter()
        .enumerate()
        .map(|(v, view)| {
            let v = v as u32;
            let job = FrameJob { cfg, s, v, view };
            let tiles = match &scene {
                Some(scene) if !kept[v as usize] => Some(job.write(scene)?),
                Some(scene) if in_sheet(s, v) => Some(job.preview(scene)?),
                _ => None,
            };
            Ok((job.entry(), tiles))
        })
        .collect::<Result<_, SynthError>>()?;
    let previews = done
        .iter()
        .filter(|(e, _)| in_sheet(s, e.view))
        .filter_map(|(_, t)| t.clone())
        .collect();
    let frames = done.into_iter().map(|(e, _)| e).collect();
    let m = views[0].mounting;
    let split = if draw(cfg.seed, s, 4) < cfg.test_fraction {
        "test"
    } else {
        "train"
    };
    let entry = SceneEntry {
        scene: s,
        split: split.into(),
        height_m: m.height_m,
        pitch_deg: m.pitch_rad.to_degrees(),
        content: cfg.content.family(cfg.seed, u64::from(s)),
        categories,
        frames,
    };
    Ok((entry, previews))
}

/// One frame of the dataset: view `v` of scene `s`.
struct FrameJob<'a> {
    cfg: &'a SynthConfig,
    s: u32,
    v: u32,
    view: &'a View,
}

impl FrameJob<'_> {
    fn entry(&self) -> FrameEntry {
        let cond = view_conditions(self.cfg, self.s, self.v);
        FrameEntry {
            dir: frame_dir(self.s, self.v),
            view: self.v,
            yaw_deg: self.view.yaw_rad.to_degrees(),
            lighting: cond.lighting,
            weather: cond.weather,
            sensor: view_sensor(self.cfg, self.s, self.v).0,
        }
    }

    fn error(&self, e: FrameError) -> SynthError {
        match e {
            FrameError::Io(e) => SynthError::Io(e),
            FrameError::Annotate(source) => SynthError::Annotate {
                scene: self.s,
                view: self.v,
                source,
            },
        }
    }

    /// Renders and writes the frame into `view_V.partial`, then renames that folder to
    /// `view_V` (replacing an older one): a frame folder is complete or absent. Returns its
    /// contact-sheet row.
    fn write(&self, scene: &Scene) -> Result<RgbImage, SynthError> {
        let (cfg, s, v) = (self.cfg, self.s, self.v);
        let cond = view_conditions(cfg, s, v);
        let frame = render(scene, self.view, &cond);
        let sensor = view_sensor(cfg, s, v);
        let dir = cfg.out.join(frame_dir(s, v));
        let partial = dir.with_extension("partial");
        remove_dir_if_there(&partial)?;
        let out = FrameOut {
            dir: &partial,
            view: self.view,
            cond: &cond,
            sensor,
            imaging: Imaging::draw(&cfg.effects, sensor.1 ^ 0x1A6E),
            ply: cfg.ply,
        };
        let tiles = write_frame(&out, &frame).map_err(|e| self.error(e))?;
        remove_dir_if_there(&dir)?;
        std::fs::rename(&partial, &dir).map_err(IoError::from)?;
        Ok(tiles)
    }

    /// The contact-sheet row of a kept frame, rendered and annotated again (not written).
    fn preview(&self, scene: &Scene) -> Result<RgbImage, SynthError> {
        let cond = view_conditions(self.cfg, self.s, self.v);
        let f = render(scene, self.view, &cond);
        let ann = annotate_frame(&f, &self.view.intrinsics).map_err(|e| self.error(e))?;
        Ok(tiles(&f, &ann.roughness_m))
    }
}

fn remove_dir_if_there(dir: &Path) -> Result<(), IoError> {
    match std::fs::remove_dir_all(dir) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(e.into()),
        _ => Ok(()),
    }
}

/// Spec v1 on a rendered frame's exact depth, normals and labels.
fn annotate_frame(
    f: &RenderedFrame,
    k: &tre_core::geometry::Intrinsics,
) -> Result<tre_core::roughness::Annotation, FrameError> {
    let input = AnnotateInput {
        depth_m: &f.depth_m,
        intrinsics: k,
        normals: Some(&f.normals_cam),
        labels: Some(&f.labels),
    };
    annotate(&input, &AnnotateConfig::default()).map_err(FrameError::Annotate)
}

enum FrameError {
    Io(IoError),
    Annotate(RoughnessError),
}

impl From<IoError> for FrameError {
    fn from(e: IoError) -> Self {
        FrameError::Io(e)
    }
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// Camera description written with each frame.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FrameCamera {
    /// fx, pixels.
    pub fx: f64,
    /// fy, pixels.
    pub fy: f64,
    /// cx, pixels.
    pub cx: f64,
    /// cy, pixels.
    pub cy: f64,
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Depth PNG units per metre.
    pub depth_scale: f64,
    /// Pitch below the horizon, degrees.
    pub pitch_deg: f64,
    /// Height above the ground, metres.
    pub height_m: f64,
    /// Heading, degrees.
    pub yaw_deg: f64,
    /// Roll about the optical axis, degrees (left out when 0).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub roll_deg: f64,
    /// Lighting and weather.
    pub conditions: Conditions,
    /// The sensor of `depth_sensor.png` (a preset name, read by `tre infer` as the noise model).
    pub sensor: SensorPreset,
    /// That sensor's model parameters and noise seed.
    pub sensor_model: SensorMeta,
    /// The image formation of `rgb.png` (effects on, their drawn parameters).
    pub imaging: Imaging,
}

/// A frame's depth-sensor model with the seed its noise was drawn from.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct SensorMeta {
    /// Noise seed of this frame.
    pub seed: u64,
    /// The model's parameters.
    #[serde(flatten)]
    pub model: SensorModel,
}

/// Where and how one frame is written.
struct FrameOut<'a> {
    dir: &'a Path,
    view: &'a View,
    cond: &'a Conditions,
    sensor: (SensorPreset, u64),
    imaging: Imaging,
    ply: bool,
}

/// Writes every file of one frame; returns the contact-sheet tiles (rgb, depth, normals,
/// labels, roughness).
fn write_frame(out: &FrameOut<'_>, f: &RenderedFrame) -> Result<RgbImage, FrameError> {
    let (dir, view, cond) = (out.dir, out.view, out.cond);
    std::fs::create_dir_all(dir).map_err(IoError::from)?;
    let k = &view.intrinsics;
    let model = SensorModel::preset(out.sensor.0);
    let cam = FrameCamera {
        fx: k.fx_px,
        fy: k.fy_px,
        cx: k.cx_px,
        cy: k.cy_px,
        width: view.width,
        height: view.height,
        depth_scale: 1000.0,
        pitch_deg: view.mounting.pitch_rad.to_degrees(),
        height_m: view.mounting.height_m,
        yaw_deg: view.yaw_rad.to_degrees(),
        roll_deg: view.roll_rad.to_degrees(),
        conditions: *cond,
        sensor: out.sensor.0,
        sensor_model: SensorMeta {
            seed: out.sensor.1,
            model,
        },
        imaging: out.imaging.clone(),
    };
    let json =
        serde_json::to_string_pretty(&cam).map_err(|e| IoError::from(std::io::Error::from(e)))?;
    std::fs::write(dir.join("camera.json"), json).map_err(IoError::from)?;
    let rgb = out.imaging.apply(&f.rgb);
    io::save(&dir.join("rgb.png"), &DynamicImage::ImageRgb8(rgb.clone()))?;
    io::save(
        &dir.join("depth.png"),
        &DynamicImage::ImageLuma16(io::depth_png16(&f.depth_m)),
    )?;
    write_sensor_depth(dir, f, k, &model, out.sensor.1)?;
    io::write_normals_npy(&dir.join("normals.npy"), &f.normals_cam)?;
    let labels = f.labels.map(|&l| l as u8);
    io::save(
        &dir.join("labels.png"),
        &DynamicImage::ImageLuma8(io::gray8(&labels)),
    )?;
    let ann = annotate_frame(f, k)?;
    io::save(
        &dir.join("roughness.png"),
        &DynamicImage::ImageLumaA16(io::roughness_png16(&ann.roughness_m)),
    )?;
    io::write_mask_png(&dir.join("boundary.png"), &ann.boundary)?;
    io::save(
        &dir.join("edge_weight.png"),
        &DynamicImage::ImageLuma16(io::metres_png16(&ann.edge_weight_m)),
    )?;
    if out.ply {
        io::write_ply(
            &dir.join("points.ply"),
            &k.back_project_map(&f.depth_m),
            &rgb,
        )?;
    }
    Ok(tiles(f, &ann.roughness_m))
}

/// Writes `depth_sensor.png`: the model's depth, or a copy of `depth.png` (written before)
/// for the exact sensor.
fn write_sensor_depth(
    dir: &Path,
    f: &RenderedFrame,
    k: &tre_core::geometry::Intrinsics,
    model: &SensorModel,
    seed: u64,
) -> Result<(), IoError> {
    let path = dir.join("depth_sensor.png");
    if model.sensor == SensorPreset::Exact {
        std::fs::copy(dir.join("depth.png"), path)?;
        return Ok(());
    }
    let input = SensorInput {
        depth_m: &f.depth_m,
        normals_cam: &f.normals_cam,
        rgb: &f.rgb,
        intrinsics: k,
    };
    let depth_m = simulate(model, &input, seed);
    io::save(&path, &DynamicImage::ImageLuma16(io::depth_png16(&depth_m)))
}

/// One contact-sheet row: rgb | depth | normals | labels | roughness (0–5 cm).
fn tiles(f: &RenderedFrame, roughness_m: &Grid<f64>) -> RgbImage {
    let (w, h) = (f.rgb.width(), f.rgb.height());
    let depth_or_nan = f.depth_m.map(|&d| if d > 0.0 { d } else { f64::NAN });
    let depth = io::colormap::colourise(&depth_or_nan, 0.0, 3.0);
    let normals = RgbImage::from_fn(w, h, |u, v| {
        let n: Vec3 = f.normals_cam[(u as usize, v as usize)];
        image::Rgb(if n.x.is_finite() {
            [0, 1, 2].map(|c| ((0.5 - 0.5 * n[c]) * 255.0) as u8)
        } else {
            [0; 3]
        })
    });
    let labels = io::colormap::labels(&f.labels);
    let rough = io::colormap::colourise(roughness_m, 0.0, 0.05);
    let mut row = RgbImage::new(w * 5, h);
    for (i, t) in [&f.rgb, &depth, &normals, &labels, &rough]
        .into_iter()
        .enumerate()
    {
        image::imageops::replace(&mut row, t, i64::from(w) * i as i64, 0);
    }
    row
}

/// Stacks contact-sheet rows, each scaled to 160 px high.
fn contact_sheet(rows: &[RgbImage]) -> RgbImage {
    let scaled: Vec<RgbImage> = rows
        .iter()
        .map(|r| {
            let w = (r.width() as f64 * 160.0 / r.height() as f64) as u32;
            image::imageops::resize(r, w.max(1), 160, image::imageops::FilterType::Triangle)
        })
        .collect();
    let width = scaled.iter().map(RgbImage::width).max().unwrap_or(1);
    let mut sheet = RgbImage::new(width, 160 * scaled.len().max(1) as u32);
    for (i, r) in scaled.iter().enumerate() {
        image::imageops::replace(&mut sheet, r, 0, 160 * i as i64);
    }
    sheet
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nonsense_settings_are_refused() {
        assert!(check(&SynthConfig::default()).is_ok());
        for cfg in [
            SynthConfig {
                size: (1 << 32, 1 << 32), // w·h wraps to 0
                ..SynthConfig::default()
            },
            SynthConfig {
                scenes: 0,
                ..SynthConfig::default()
            },
            SynthConfig {
                test_fraction: 2.0,
                ..SynthConfig::default()
            },
            SynthConfig {
                test_fraction: f64::NAN,
                ..SynthConfig::default()
            },
        ] {
            assert!(check(&cfg).is_err(), "{cfg:?}");
        }
    }
}
