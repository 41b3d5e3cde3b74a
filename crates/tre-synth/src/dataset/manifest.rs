//! What is written about a dataset: the manifest (`dataset.json`), each frame's
//! `camera.json`, and the run file that records the settings of a run in progress.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::{SynthConfig, SynthConfigProblem, SynthError};
use crate::appearance::{Conditions, Lighting, Weather};
use crate::content::Content;
use crate::imaging::Imaging;
use crate::sensor::SensorModel;
use crate::surface::Category;
use tre_core::roughness::noise::SensorPreset;
use tre_io::IoError;

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

/// The settings of a run in progress, beside its frames until `dataset.json` is written.
pub const RUN_FILE: &str = "dataset.partial.json";

/// Creates the output folder and records the run's settings in [`RUN_FILE`]. With `resume`, the
/// settings of the run found there (in progress, or finished in `dataset.json`) must be these.
pub(super) fn start_run(cfg: &SynthConfig) -> Result<(), SynthError> {
    std::fs::create_dir_all(&cfg.out).map_err(IoError::from)?;
    let settings = serde_json::to_value(cfg)?;
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
                return Err(SynthConfigProblem::OtherSettings {
                    out: cfg.out.clone(),
                    previous: p,
                }
                .into())
            }
            None if cfg.out.join("scene_00000").exists() => {
                return Err(SynthConfigProblem::Unrecorded {
                    out: cfg.out.clone(),
                }
                .into())
            }
            _ => {}
        }
    }
    let json = serde_json::to_string_pretty(&settings)?;
    std::fs::write(run_file, json).map_err(IoError::from)?;
    Ok(())
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
