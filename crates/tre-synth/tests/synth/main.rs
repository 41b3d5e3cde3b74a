//! tre-synth's integration tests, one test binary (`cargo test -p tre-synth --test synth`):
//! determinism, depth and normals against the rendered geometry, the annotator on known scenes
//! (flat pavement, stairs), the depth-sensor models (noise against their presets, holes), the
//! indoor and urban content (objects, labels, edges in the ground truth, natural output
//! unchanged) and resumed runs. `tre eval` on generated data and the Kinect model against the
//! real floor are in the `tre` package's `tests/it/synth/`.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::path::Path;

use tre_core::geometry::{is_valid_point, Grid, Intrinsics, Mounting, Vec3};
use tre_core::roughness::annotate::{annotate, AnnotateConfig, AnnotateInput, Annotation};
use tre_core::roughness::noise::SensorPreset;
use tre_synth::imaging::ImageEffect;
use tre_synth::surface::{Region, Steps};
use tre_synth::{
    dataset::SynthConfig, render, surface::Category, Conditions, HeightGrid, Lighting,
    RenderedFrame, Scene, Terrain, View, Weather,
};

mod content;
mod scenes;
mod sensors;

/// A synthetic-dataset configuration writing to `out`: `scenes` scenes of `views` views each at
/// `size` (width, height), drawn from `seed`; every other setting is the default.
fn synth_config(
    out: &Path,
    scenes: u32,
    seed: u64,
    size: (usize, usize),
    views: u32,
) -> SynthConfig {
    SynthConfig {
        out: out.to_owned(),
        scenes,
        seed,
        size,
        views,
        ..SynthConfig::default()
    }
}

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
