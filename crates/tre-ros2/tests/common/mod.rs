//! What the node's integration tests share: the kitchen sequence of `../shared` and the node's
//! processor on it (geometric mode, the kinect_v1 noise model, the indoor map levelled by the
//! sequence's gravity).
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::path::{Path, PathBuf};

use tre_core::geometry::Vec3;
use tre_core::map::{MapParams, MapPreset, LAYER_NAMES};
use tre_core::roughness::noise::{SensorNoise, SensorPreset};
use tre_pipeline::{Mode, Pipeline, PipelineConfig};
use tre_ros2::{MapSettings, Processor};

/// `real-rgbd-2/sevenscenes_redkitchen` under `TRE_SHARED_DIR`, else `../shared` beside the
/// repository; `None` where it is not.
pub(crate) fn kitchen_dir() -> Option<PathBuf> {
    let base = match std::env::var_os("TRE_SHARED_DIR") {
        Some(d) if !d.is_empty() => PathBuf::from(d),
        _ => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared"),
    };
    let dir = base.join("data/real-rgbd-2/sevenscenes_redkitchen");
    dir.is_dir().then_some(dir)
}

/// The sequence's gravity (down, in the poses' frame).
fn gravity(dir: &Path) -> Vec3 {
    let g: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("gravity.json")).unwrap()).unwrap();
    let c = |i: usize| g["gravity"][i].as_f64().unwrap();
    Vec3::new(c(0), c(1), c(2))
}

/// The indoor map levelled by the sequence's gravity, in `world`: every layer, a grid map
/// with every fused frame.
pub(crate) fn indoor_map(dir: &Path) -> MapSettings {
    MapSettings {
        params: MapParams::preset(MapPreset::Indoor),
        down: gravity(dir),
        frame_id: "world".into(),
        grid_layers: LAYER_NAMES.to_vec(),
        grid_period: std::time::Duration::ZERO,
    }
}

/// The geometric mode with the kinect_v1 noise model and `map`.
pub(crate) fn kinect_processor(map: MapSettings) -> Processor {
    let cfg = PipelineConfig {
        mode: Mode::Geometric,
        ..PipelineConfig::default()
    };
    let sensor = SensorNoise::Preset(SensorPreset::KinectV1);
    Processor::new(Pipeline::new(None), cfg, Some(sensor), Some(map))
}
