//! `tre synth`: scenes → views → frames on disk, with a manifest split by scene and a contact
//! sheet. Deterministic by seed: the same seed gives the same bytes.
//!
//! [`generate`] checks the settings and runs the scenes in parallel: `scene` draws each scene's
//! views, terrain, lighting and sensors; `frame` renders and writes its frames (the files of
//! one frame by `writer`, the contact-sheet rows by `sheet`); `manifest` holds what is written
//! about the dataset (`dataset.json`, each frame's `camera.json`, the run file).

mod frame;
mod manifest;
mod scene;
mod sheet;
mod writer;

use std::path::PathBuf;

use image::{DynamicImage, RgbImage};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::content::Content;
use super::imaging::ImageEffect;
use tre_core::roughness::noise::SensorPreset;
use tre_core::roughness::RoughnessError;
use tre_io::{self as io, IoError};

use frame::generate_scene;
use manifest::start_run;
use sheet::contact_sheet;

pub use manifest::{FrameCamera, FrameEntry, Manifest, SceneEntry, SensorMeta, RUN_FILE};
pub use scene::{
    build_scene, scene_mounting, scene_terrain, scene_views, view_conditions, view_sensor,
    OpticsRanges, OPTICS,
};

/// Dataset settings, with the paper's camera by default. Those a user states are options of
/// `tre synth` (clap's, behind the `cli` feature: each doc comment is its `--help`; the frame
/// size is [`SynthArgs`](crate::SynthArgs)' `--width` and `--height`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct SynthConfig {
    /// Output folder (created if missing).
    // Not written to the manifest, so that a dataset is the same wherever it is written.
    #[serde(skip)]
    #[cfg_attr(feature = "cli", arg(long))]
    pub out: PathBuf,
    /// Number of scenes (9 views each by default).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 4))]
    pub scenes: u32,
    /// Dataset seed: the same seed gives the same bytes.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 0))]
    pub seed: u64,
    /// Image width and height, pixels.
    #[cfg_attr(feature = "cli", arg(skip = SynthConfig::default().size))]
    pub size: (usize, usize),
    /// Horizontal field of view, degrees.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 60.0))]
    pub hfov_deg: f64,
    /// Views per scene, spread over ±60° of yaw.
    // Evenly over ±yaw_span_deg: 9 views, 15° apart.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 9))]
    pub views: u32,
    /// Half the yaw span, degrees.
    #[cfg_attr(feature = "cli", arg(skip = SynthConfig::default().yaw_span_deg))]
    pub yaw_span_deg: f64,
    /// Draw camera height (0.4–1.2 m) and pitch (40–75°) per scene instead of 1 m and 60°.
    #[cfg_attr(feature = "cli", arg(long))]
    pub random_mounting: bool,
    /// Share of scenes in the test split.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 0.2))]
    pub test_fraction: f64,
    /// Grid spacing of the rendered surface, metres.
    #[cfg_attr(feature = "cli", arg(skip = SynthConfig::default().cell_m))]
    pub cell_m: f64,
    /// Write a PLY point cloud per frame.
    #[cfg_attr(feature = "cli", arg(long = "no-ply", action = clap::ArgAction::SetFalse,
        help = "Skip the PLY point clouds (they are the largest files)"))]
    pub ply: bool,
    /// Depth sensor(s) of `depth_sensor.png`: kinect_v1, realsense_d435, azure_kinect, lidar,
    /// lidar_accumulated, passive_stereo or exact; a comma-separated list draws one per frame
    /// (docs/synth.md).
    // Drawn uniformly, from the frame's seed; `exact` copies the exact depth.
    #[serde(default = "default_sensors")]
    #[cfg_attr(
        feature = "cli",
        arg(
            long = "sensor",
            value_name = "SENSOR",
            env = "TRE_SYNTH_SENSOR",
            value_delimiter = ',',
            default_value = "exact"
        )
    )]
    pub sensors: Vec<SensorPreset>,
    /// Image-formation effects on rgb.png, each drawn per frame: exposure, white_balance,
    /// vignetting, defocus, motion_blur, noise, jpeg (comma-separated; leave one out to turn it
    /// off; none by default). Ranges in docs/synth.md.
    #[serde(default)]
    #[cfg_attr(
        feature = "cli",
        arg(long, env = "TRE_SYNTH_EFFECTS", value_delimiter = ',')
    )]
    pub effects: Vec<ImageEffect>,
    /// What the scenes show: natural (the paper's six terrain categories), indoor (floors,
    /// walls, sills, cables, boxes, furniture, stairs), urban (road, sidewalk, curb, kerb ramp,
    /// drains, posts) or mixed (each scene draws one). Labels in docs/synth.md.
    // Natural, the default, is left out of `dataset.json`, so that natural datasets keep their
    // bytes.
    #[serde(default, skip_serializing_if = "Content::is_natural")]
    #[cfg_attr(
        feature = "cli",
        arg(long, env = "TRE_SYNTH_CONTENT", default_value = "natural")
    )]
    pub content: Content,
    /// Draw every frame's camera: pitch 0–85°, height 0.2–2.0 m, roll ±10°, horizontal field
    /// of view 45–110° and shape 4:3, 16:9 or 1242:375 (the width stays --width); overrides
    /// --random-mounting, --hfov-deg and --height.
    // Left out of `dataset.json` when off.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    #[cfg_attr(feature = "cli", arg(long))]
    pub random_optics: bool,
    /// Continue an interrupted run into the same --out with the same settings: complete
    /// frames are kept, the others written.
    // A run option, not written to the manifest.
    #[serde(skip)]
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_SYNTH_RESUME"))]
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
    #[error(transparent)]
    Config(#[from] SynthConfigProblem),
    /// The settings or the manifest do not serialise.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

/// Settings that cannot make a dataset, or cannot resume the one in the output folder.
#[derive(Debug, thiserror::Error)]
pub enum SynthConfigProblem {
    /// An image size of 0 or over 4096×4096.
    #[error("image size {width}×{height} must be between 1×1 and 4096×4096")]
    ImageSize {
        /// Width, pixels.
        width: usize,
        /// Height, pixels.
        height: usize,
    },
    /// A field of view, number of views or cell size out of range.
    #[error("need 1° < hfov < 170°, at least one view, cell ≥ 0.5 mm")]
    Camera,
    /// No scene.
    #[error("need at least one scene")]
    NoScene,
    /// No depth sensor.
    #[error("need at least one depth sensor (one of {})", SensorPreset::names())]
    NoSensor,
    /// A test fraction outside [0, 1].
    #[error("the test fraction must be between 0 and 1, got {0}")]
    TestFraction(f64),
    /// `--resume` of a folder started with other settings.
    #[error(
        "cannot resume {}: it was started with other settings ({previous}); use them, \
         or another --out",
        out.display()
    )]
    OtherSettings {
        /// The output folder.
        out: PathBuf,
        /// The settings it was started with.
        previous: serde_json::Value,
    },
    /// `--resume` of a folder whose frames carry no record of their settings.
    #[error("cannot resume {}: its frames carry no record of their settings", out.display())]
    Unrecorded {
        /// The output folder.
        out: PathBuf,
    },
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
    let json = serde_json::to_string_pretty(&manifest)?;
    std::fs::write(cfg.out.join("dataset.json"), json).map_err(IoError::from)?;
    io::save(
        &cfg.out.join("contact_sheet.png"),
        &DynamicImage::ImageRgb8(contact_sheet(&sheet)),
    )?;
    std::fs::remove_file(cfg.out.join(RUN_FILE)).map_err(IoError::from)?;
    Ok(manifest)
}

/// Refuses settings that cannot make a dataset, saying which.
fn check(cfg: &SynthConfig) -> Result<(), SynthError> {
    let (w, h) = cfg.size;
    if w == 0 || h == 0 || w.checked_mul(h).is_none_or(|n| n > 4096 * 4096) {
        return Err(SynthConfigProblem::ImageSize {
            width: w,
            height: h,
        }
        .into());
    }
    if !(cfg.hfov_deg > 1.0 && cfg.hfov_deg < 170.0) || cfg.views == 0 || !(cfg.cell_m > 0.0005) {
        return Err(SynthConfigProblem::Camera.into());
    }
    if cfg.scenes == 0 {
        return Err(SynthConfigProblem::NoScene.into());
    }
    if cfg.sensors.is_empty() {
        return Err(SynthConfigProblem::NoSensor.into());
    }
    if !(0.0..=1.0).contains(&cfg.test_fraction) {
        return Err(SynthConfigProblem::TestFraction(cfg.test_fraction).into());
    }
    Ok(())
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
