//! [`Models`]: the manifest plus one checked session per learned stage, with typed run methods
//! (NCHW float32 in, NCHW float32 out). One `Models` is owned by one worker thread: either with
//! sessions of its own ([`Models::load`]) or with handles on models shared by every worker and
//! run in batches ([`Models::shared`], [`SharedModels`]).

use std::path::Path;
use std::time::Duration;

use ndarray::{Array4, ArrayView4};

use super::batcher::{SharedModels, SharedNet};
use super::manifest::Manifest;
use super::session::{ModelSession, SessionConfig};
use super::ModelError;

/// Manifest name of the depth net: `rgb`, `prior_depth_m` → `depth_m`.
pub const DEPTH_NET: &str = "depth_net";
/// Manifest name of the neighbour net: `rgb`, `points_m`, `valid` → `logits` (49 channels).
pub const NEIGHBOUR_NET: &str = "neighbour_net";
/// Manifest name of the normal refiner: `rgb`, `points_m`, `valid`, `normals_init` → `normals`.
pub const NORMAL_REFINER: &str = "normal_refiner";
/// Manifest name of the centroid net: `rgb`, `points_m`, `valid`, `normals` → `centroid_m`.
pub const CENTROID_NET: &str = "centroid_net";
/// Manifest name of the end-to-end baseline: `rgb`, `prior_depth_m` → `roughness_m`.
pub const END_TO_END: &str = "end_to_end";

/// One model: a session of the worker's own, or a handle on a shared, batching one.
#[derive(Debug)]
enum Net {
    Own(Box<ModelSession>),
    Shared(SharedNet),
}

impl Net {
    fn run_with<R>(
        &mut self,
        inputs: &[ArrayView4<'_, f32>],
        consume: impl FnOnce(ArrayView4<'_, f32>) -> R,
    ) -> Result<R, ModelError> {
        match self {
            Self::Own(s) => s.run_with(inputs, consume),
            Self::Shared(s) => s.run_with(inputs, consume),
        }
    }

    fn run(&mut self, inputs: &[ArrayView4<'_, f32>]) -> Result<Array4<f32>, ModelError> {
        self.run_with(inputs, |y| y.as_standard_layout().into_owned())
    }

    fn onnx_runtime_time(&self) -> Duration {
        match self {
            Self::Own(s) => s.onnx_runtime_time(),
            Self::Shared(s) => s.onnx_runtime_time(),
        }
    }
}

/// The four pipeline stages (required) and the end-to-end baseline (loaded when listed).
#[derive(Debug)]
pub struct Models {
    manifest: Manifest,
    depth: Net,
    neighbour: Net,
    refiner: Net,
    centroid: Net,
    end_to_end: Option<Net>,
}

impl Models {
    /// Reads `dir/manifest.json`, checks every model it lists and builds their sessions.
    ///
    /// # Errors
    ///
    /// [`ModelError::Manifest`] for a bad manifest, [`ModelError::NotInManifest`] when a
    /// pipeline stage is not listed, and the errors of [`ModelSession::load`], which name the
    /// model and the field that disagrees.
    pub fn load(dir: &Path, cfg: &SessionConfig) -> Result<Self, ModelError> {
        let manifest = Manifest::read(dir)?;
        let load = |name: &str| {
            ModelSession::load(dir, name, manifest.entry(name)?, manifest.stride, cfg)
                .map(|s| Net::Own(Box::new(s)))
        };
        let end_to_end = match manifest.models.contains_key(END_TO_END) {
            true => Some(load(END_TO_END)?),
            false => None,
        };
        Ok(Self {
            depth: load(DEPTH_NET)?,
            neighbour: load(NEIGHBOUR_NET)?,
            refiner: load(NORMAL_REFINER)?,
            centroid: load(CENTROID_NET)?,
            end_to_end,
            manifest,
        })
    }

    /// A worker's handles on `shared`'s models: each run joins a batch of its model's thread.
    ///
    /// # Errors
    ///
    /// [`ModelError::NotInManifest`] when a pipeline stage is not listed.
    pub fn shared(shared: &SharedModels) -> Result<Self, ModelError> {
        let manifest = shared.manifest().clone();
        let net = |name: &str| {
            shared
                .net(name)
                .map(Net::Shared)
                .ok_or_else(|| ModelError::NotInManifest {
                    model: name.to_owned(),
                })
        };
        Ok(Self {
            depth: net(DEPTH_NET)?,
            neighbour: net(NEIGHBOUR_NET)?,
            refiner: net(NORMAL_REFINER)?,
            centroid: net(CENTROID_NET)?,
            end_to_end: shared.net(END_TO_END).map(Net::Shared),
            manifest,
        })
    }

    /// Wall time spent inside ONNX Runtime so far, over all models and runs (for shared
    /// models, the time of the batches this worker's runs were part of).
    pub fn onnx_runtime_time(&self) -> Duration {
        [&self.depth, &self.neighbour, &self.refiner, &self.centroid]
            .into_iter()
            .chain(&self.end_to_end)
            .map(Net::onnx_runtime_time)
            .sum()
    }

    /// The manifest the models were checked against.
    pub fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    /// H and W of every input must be multiples of this.
    pub fn stride(&self) -> usize {
        self.manifest.stride
    }

    /// The default working size, `(width, height)` pixels.
    pub fn working_size(&self) -> (usize, usize) {
        let [w, h] = self.manifest.working_size;
        (w, h)
    }

    /// Whether the end-to-end baseline is loaded.
    pub fn has_end_to_end(&self) -> bool {
        self.end_to_end.is_some()
    }

    /// Depth net: RGB in [0, 1] (N×3×H×W) and the flat-ground prior (N×1×H×W, metres) →
    /// depth in metres (N×1×H×W).
    ///
    /// # Errors
    ///
    /// Those of [`ModelSession::run`].
    pub fn depth(
        &mut self,
        rgb: ArrayView4<'_, f32>,
        prior_depth_m: ArrayView4<'_, f32>,
    ) -> Result<Array4<f32>, ModelError> {
        self.depth.run(&[rgb, prior_depth_m])
    }

    /// The depth net like [`Models::depth`], its output handed to `consume` without a copy.
    ///
    /// # Errors
    ///
    /// Those of [`ModelSession::run`].
    pub fn depth_with<R>(
        &mut self,
        rgb: ArrayView4<'_, f32>,
        prior_depth_m: ArrayView4<'_, f32>,
        consume: impl FnOnce(ArrayView4<'_, f32>) -> R,
    ) -> Result<R, ModelError> {
        self.depth.run_with(&[rgb, prior_depth_m], consume)
    }

    /// Neighbour net: RGB, camera-frame points (N×3×H×W, 0 where invalid) and validity (N×1×H×W,
    /// 1/0) → 49 logits per pixel over its 7×7 window (N×49×H×W), handed to `consume` without a
    /// copy (12.8 MB at 256×256).
    ///
    /// # Errors
    ///
    /// Those of [`ModelSession::run`].
    pub fn neighbour_logits_with<R>(
        &mut self,
        rgb: ArrayView4<'_, f32>,
        points_m: ArrayView4<'_, f32>,
        valid: ArrayView4<'_, f32>,
        consume: impl FnOnce(ArrayView4<'_, f32>) -> R,
    ) -> Result<R, ModelError> {
        self.neighbour.run_with(&[rgb, points_m, valid], consume)
    }

    /// Normal refiner: RGB, points, validity and initial normals (N×3×H×W, 0 where none) →
    /// unit normals (N×3×H×W), handed to `consume` without a copy.
    ///
    /// # Errors
    ///
    /// Those of [`ModelSession::run`].
    pub fn refine_normals_with<R>(
        &mut self,
        inputs: [ArrayView4<'_, f32>; 4],
        consume: impl FnOnce(ArrayView4<'_, f32>) -> R,
    ) -> Result<R, ModelError> {
        self.refiner.run_with(&inputs, consume)
    }

    /// Centroid net: RGB, points, validity and normals → local-plane centroids in metres
    /// (N×3×H×W), handed to `consume` without a copy.
    ///
    /// # Errors
    ///
    /// Those of [`ModelSession::run`].
    pub fn centroids_with<R>(
        &mut self,
        inputs: [ArrayView4<'_, f32>; 4],
        consume: impl FnOnce(ArrayView4<'_, f32>) -> R,
    ) -> Result<R, ModelError> {
        self.centroid.run_with(&inputs, consume)
    }

    /// End-to-end baseline: RGB and the flat-ground prior → roughness in metres (N×1×H×W).
    ///
    /// # Errors
    ///
    /// [`ModelError::NotInManifest`] when the manifest has no `end_to_end`, else those of
    /// [`ModelSession::run`].
    pub fn end_to_end(
        &mut self,
        rgb: ArrayView4<'_, f32>,
        prior_depth_m: ArrayView4<'_, f32>,
    ) -> Result<Array4<f32>, ModelError> {
        let session = self.end_to_end.as_mut().ok_or(ModelError::NotInManifest {
            model: END_TO_END.to_owned(),
        })?;
        session.run(&[rgb, prior_depth_m])
    }
}
