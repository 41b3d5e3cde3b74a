//! Per-stage wall times of one frame ([`StageTimings`]), in the order the stages ran, and the
//! share of them spent inside ONNX Runtime.

use std::time::Duration;

/// Wall time per named stage, in the order the stages ran.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StageTimings {
    stages: Vec<(&'static str, Duration)>,
    onnx_runtime: Duration,
}

impl StageTimings {
    /// Stage names the pipeline reports.
    pub const NAMES: [&'static str; 10] = [
        "resize",
        "depth",
        "back_project",
        "normals",
        "refine",
        "centroid",
        "roughness",
        "gravity",
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

    /// Records stage `name`, which ran before all the others, as the first one.
    pub fn add_first(&mut self, name: &'static str, took: Duration) {
        self.stages.insert(0, (name, took));
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
