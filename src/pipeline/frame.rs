//! One frame in and its maps out, with per-stage timings.

use std::time::Duration;

use image::RgbImage;

use crate::geometry::{Grid, Intrinsics, Mounting, Vec3};

/// Horizontal field of view assumed when a frame comes without intrinsics, degrees.
pub const DEFAULT_HFOV_DEG: f64 = 60.0;

/// A frame to estimate roughness for.
#[derive(Debug, Clone, Default)]
pub struct FrameInput {
    /// 8-bit RGB; needed in `rgb` and `rgbd` modes and by the end-to-end baseline.
    pub rgb: Option<RgbImage>,
    /// Depth in metres (0, negative or non-finite: no data), the size of `rgb`; needed in
    /// `rgbd` and `geometric` modes, ignored in `rgb` mode.
    pub depth_m: Option<Grid<f64>>,
    /// Intrinsics in pixels of this frame. `None`: a pinhole with a 60° horizontal field of view
    /// ([`DEFAULT_HFOV_DEG`]), square pixels and the principal point at the image centre.
    pub intrinsics: Option<Intrinsics>,
    /// Camera pitch and height (default 60° down, 1 m).
    pub mounting: Mounting,
}

impl FrameInput {
    /// `(width, height)` of the frame: the RGB image's, else the depth map's.
    pub fn size(&self) -> Option<(usize, usize)> {
        match (&self.rgb, &self.depth_m) {
            (Some(rgb), _) => Some((rgb.width() as usize, rgb.height() as usize)),
            (None, Some(depth)) => Some(depth.size()),
            (None, None) => None,
        }
    }
}

/// The maps of one frame, all at the input frame's size (nearest-neighbour from the working
/// size, so no value is blended across an edge).
#[derive(Debug, Clone)]
pub struct FrameOutput {
    /// Roughness (Eq. 1), metres; NaN where there is no data.
    pub roughness_m: Grid<f64>,
    /// Depth used, metres (0: none); `None` for the end-to-end baseline.
    pub depth_m: Option<Grid<f64>>,
    /// Unit normals in the camera frame, facing the camera (NaN: none); `None` for the
    /// end-to-end baseline.
    pub normals: Option<Grid<Vec3>>,
    /// Gravity's up axis in the camera frame (from the frame's mounting), for
    /// [`slope_rad`](Self::slope_rad).
    pub up_in_cam: Vec3,
    /// Roughness and slope within the thresholds (roughness only for the end-to-end baseline).
    pub traversable: Grid<bool>,
    /// The size the stages ran at, `(width, height)`.
    pub working_size: (usize, usize),
    /// Wall time of each stage, in order.
    pub timings: StageTimings,
}

impl FrameOutput {
    /// Slope of the normals in the gravity frame, radians (NaN: none), computed when asked
    /// for; `None` for the end-to-end baseline.
    pub fn slope_rad(&self) -> Option<Grid<f64>> {
        self.normals
            .as_ref()
            .map(|n| super::centroid::slopes(n, &self.up_in_cam))
    }
}

/// Wall time per named stage, in the order the stages ran.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StageTimings {
    stages: Vec<(&'static str, Duration)>,
    onnx_runtime: Duration,
}

impl StageTimings {
    /// Stage names the pipeline reports.
    pub const NAMES: [&'static str; 9] = [
        "resize",
        "depth",
        "back_project",
        "normals",
        "refine",
        "centroid",
        "roughness",
        "outputs",
        "end_to_end",
    ];

    /// Adds `took` to stage `name` (created at the end if new).
    pub fn add(&mut self, name: &'static str, took: Duration) {
        match self.stages.iter_mut().find(|(n, _)| *n == name) {
            Some((_, d)) => *d += took,
            None => self.stages.push((name, took)),
        }
    }

    /// Runs `f` and adds its wall time to stage `name`.
    pub fn time<T>(&mut self, name: &'static str, f: impl FnOnce() -> T) -> T {
        let start = std::time::Instant::now();
        let out = f();
        self.add(name, start.elapsed());
        out
    }

    /// The time of stage `name`, if it ran.
    pub fn get(&self, name: &str) -> Option<Duration> {
        self.stages
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, d)| *d)
    }

    /// Every stage that ran, in order.
    pub fn iter(&self) -> impl Iterator<Item = (&'static str, Duration)> + '_ {
        self.stages.iter().copied()
    }

    /// Of [`total`](Self::total), the time spent inside ONNX Runtime's session runs (the
    /// rest is decoding, resizing, tensor packing, geometry and outputs).
    pub fn onnx_runtime(&self) -> Duration {
        self.onnx_runtime
    }

    /// Sets the time spent inside ONNX Runtime.
    pub fn set_onnx_runtime(&mut self, took: Duration) {
        self.onnx_runtime = took;
    }

    /// The sum over stages.
    pub fn total(&self) -> Duration {
        self.stages.iter().map(|(_, d)| *d).sum()
    }
}
