//! Sensor noise: the uncertainty map's prediction against annotation spec v1 run on simulated
//! noisy planes, three-state traversability on the shared real RGB-D frames, and the maps through
//! `tre infer`, HTTP and the stream.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use tre::geometry::{Grid, Intrinsics, Vec3};
use tre::roughness::annotate::{annotate, AnnotateConfig, AnnotateInput};
use tre::roughness::noise::{pixel_noise_map, SensorNoise, SensorPreset};
use tre::roughness::traversal::{shares, ThreeStateRule, Traversal};

mod calibrated;
mod maps;
mod noise_floor;
mod real_frames;
