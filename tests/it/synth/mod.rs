//! The synthetic dataset through the `tre` binary and against the real frames: `tre eval` on a
//! generated split, and the Kinect model's roughness against real Kinect floor. The generator's
//! own tests (determinism, geometry, content, sensor models) are tre-synth's:
//! `crates/tre-synth/tests/synth/`.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::path::Path;

use crate::common::synth_config;

use tre::geometry::{Grid, Intrinsics, Mounting};
use tre::roughness::noise::SensorPreset;
use tre::synth::{
    dataset::SynthConfig, render, surface::Category, Conditions, HeightGrid, Lighting,
    RenderedFrame, Scene, Terrain, View, Weather,
};

mod eval;
mod realism;

fn clear_noon() -> Conditions {
    Conditions {
        lighting: Lighting::HighSun,
        weather: Weather::Clear,
        sun_azimuth_rad: 0.5,
    }
}
