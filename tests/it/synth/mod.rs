//! Synthetic dataset: determinism, depth and normals against the rendered geometry, and the
//! annotator on known scenes (flat pavement, stairs), the depth-sensor models (noise against
//! their presets, holes, realism against real Kinect floor), the indoor and urban content
//! (objects, labels, edges in the ground truth, natural output unchanged) and resumed runs.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::path::Path;

use crate::common::synth_config;

use tre::geometry::{is_valid_point, Grid, Intrinsics, Mounting, Vec3};
use tre::roughness::noise::SensorPreset;
use tre::roughness::{annotate, AnnotateConfig, AnnotateInput, Annotation};
use tre::synth::imaging::ImageEffect;
use tre::synth::terrain::{Region, Steps};
use tre::synth::{
    render, Category, Conditions, HeightGrid, Lighting, RenderedFrame, Scene, SynthConfig, Terrain,
    View, Weather,
};

mod content;
mod eval;
mod realism;
mod scenes;
mod sensors;

fn small_config(out: &Path, seed: u64) -> SynthConfig {
    SynthConfig {
        sensors: SensorPreset::ALL.to_vec(),
        effects: ImageEffect::ALL.to_vec(),
        ..synth_config(out, 2, seed, (64, 48), 3)
    }
}

/// Every file under `dir`, relative path → bytes.
fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_owned()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push((
                    p.strip_prefix(dir).unwrap().display().to_string(),
                    std::fs::read(&p).unwrap(),
                ));
            }
        }
    }
    out.sort();
    out
}

fn robot_view(size: usize) -> View {
    View {
        mounting: Mounting::default(),
        yaw_rad: 0.0,
        roll_rad: 0.0,
        intrinsics: Intrinsics::from_hfov(size, size, 60.0).unwrap(),
        width: size,
        height: size,
    }
}

fn scene_of(terrain: Terrain) -> Scene {
    let grid = HeightGrid::sample(&terrain, (-3.0, -0.8), (3.0, 3.0), 0.004);
    Scene { terrain, grid }
}

fn clear_noon() -> Conditions {
    Conditions {
        lighting: Lighting::HighSun,
        weather: Weather::Clear,
        sun_azimuth_rad: 0.5,
    }
}

fn annotate_frame(f: &RenderedFrame, view: &View) -> Annotation {
    let input = AnnotateInput {
        depth_m: &f.depth_m,
        intrinsics: &view.intrinsics,
        normals: Some(&f.normals_cam),
        labels: Some(&f.labels),
    };
    annotate(&input, &AnnotateConfig::default()).unwrap()
}
