//! Depth-sensor models for synthetic frames: from exact depth to what a structured-light,
//! active-stereo, time-of-flight or spinning-LiDAR sensor would have measured (docs/synth.md).
//!
//! Every model keeps the noise of its [`SensorPreset`]: the depth error on a flat surface has
//! the standard deviation σ_z(z) of `tre_core::roughness::noise` (along the optical axis for the
//! triangulating sensors, along the ray for time of flight and LiDAR), quantisation included.
//! Holes are 0. Deterministic: the same input and seed give the same depth on any number of
//! threads.

mod maps;
mod model;
mod pixel;

use image::RgbImage;
use rayon::prelude::*;

use tre_core::geometry::hash::uniform;
use tre_core::geometry::{Grid, Intrinsics, Vec3};
use tre_core::roughness::noise::SensorPreset;

use maps::{concavity, fatten, flying_mask, texture};
use pixel::PixelContext;

pub use maps::{lidar_mask, noise_field, projector_shadow};
pub use model::SensorModel;

/// What a sensor model reads from a rendered frame.
pub struct SensorInput<'a> {
    /// Exact depth (camera z), metres; 0 where nothing is seen.
    pub depth_m: &'a Grid<f64>,
    /// Unit normals in the camera frame, towards the camera; NaN where none.
    pub normals_cam: &'a Grid<Vec3>,
    /// The frame's image (dark materials and texture are read from it).
    pub rgb: &'a RgbImage,
    /// Pinhole intrinsics of the frame.
    pub intrinsics: &'a Intrinsics,
}

/// Independent random streams of one frame.
#[derive(Clone, Copy)]
enum Stream {
    White = 1,
    Correlated = 2,
    Dropout = 3,
    Flying = 4,
}

/// A standard normal number for pixel `i` of `stream` (Box–Muller on the counter hash).
fn normal(seed: u64, i: u64, stream: Stream) -> f64 {
    let u1 = uniform(seed, i, stream as u32, 0);
    let u2 = uniform(seed, i, stream as u32, 1);
    (-2.0 * (1.0 - u1).ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// The sensor depth (metres, 0 = no return) of `input` under `model`, seeded by `seed`.
pub fn simulate(model: &SensorModel, input: &SensorInput<'_>, seed: u64) -> Grid<f64> {
    let exact = input.depth_m;
    if model.sensor == SensorPreset::Exact {
        return exact.clone();
    }
    let scale = model.scale(input.intrinsics);
    let mut depth = if model.fatten_native_px > 0.0 {
        fatten(exact, (model.fatten_native_px * scale).round() as usize)
    } else {
        exact.clone()
    };
    let noise = noise_field(model, exact.size(), scale, seed);
    let flying = flying_mask(model, exact);
    let concavity = if model.multipath_gain_m > 0.0 {
        Some(concavity(input, scale))
    } else {
        None
    };
    let texture = (model.min_texture > 0.0).then(|| texture(input.rgb, 3));
    let lidar = (model.lidar_rings > 0).then(|| lidar_mask(model, input.intrinsics, exact.size()));
    let shadow = model
        .projector_shadow
        .then(|| projector_shadow(exact, input.intrinsics, model.baseline_m));
    let ctx = PixelContext {
        model,
        input,
        seed,
        scale,
        noise: &noise,
        flying: &flying,
        concavity: concavity.as_ref(),
        texture: texture.as_ref(),
        lidar: lidar.as_ref(),
        shadow: shadow.as_ref(),
    };
    let (w, _) = exact.size();
    depth
        .as_mut_slice()
        .par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, z) in row.iter_mut().enumerate() {
                *z = ctx.pixel(x, y, *z);
            }
        });
    depth
}
