//! [`Pipeline`]: checks a frame, runs the stages in order at the working size, and brings the
//! maps back to the frame's size. It owns the models and the tensors and maps it reuses across
//! frames; like [`Models`], it belongs to one worker thread. The normal and centroid stages are
//! in `run/stages.rs`.

use std::time::Duration;

use ndarray::Array4;

use super::check::check_input;
use super::depth::{prior_depth_into, MAX_PRIOR_DEPTH_M};
use super::frame::{FrameInput, FrameOutput, StageMaps, DEFAULT_HFOV_DEG};
use super::gravity::{Gravity, GravityUnknown};
use super::normals::InitialNormals;
use super::plausible::Implausible;
use super::resize::{resize_nearest_reusing, resize_rgb};
use super::spares::Spares;
use super::tensors::{depth_from_tensor_into, points_tensors, rgb_tensor, scalar_tensor};
use super::timings::StageTimings;
use super::{
    check_dsac_hypotheses, CentroidMethod, Method, Mode, PipelineConfig, PipelineError,
    MAX_WORKING_SIDE,
};
use tre_core::geometry::dsac::DsacScratch;
use tre_core::geometry::floor::{fit_floor, FloorFitConfig};
use tre_core::geometry::normals::PackedPoints;
use tre_core::geometry::sums::SummedMoments;
use tre_core::geometry::{Grid, Intrinsics, PointMap, Vec3};
use tre_core::roughness::annotate::AnnotateConfig;
use tre_core::roughness::annotate::{spec_roughness_into, surface_term_into, SpecMaps, SpecPlanes};
use tre_core::roughness::interval::{Calibration, IntervalTable};
use tre_core::roughness::noise::SensorNoise;
use tre_core::roughness::terrain::{clean_points_into, terrain_into, TerrainConfig, TerrainMaps};
use tre_model::Models;

mod stages;

use stages::{loaded, Stages};

/// A frame's gravity: its stated mounting, else (with sensor depth) a confident fit of the
/// ground in its points at the working size, else unknown.
fn frame_gravity(input: &FrameInput, mode: Mode, points: &PointMap) -> Gravity {
    if let Some(m) = input.mounting {
        return Gravity::Stated(m);
    }
    if mode == Mode::Rgb {
        return Gravity::Unknown(GravityUnknown::NoDepth);
    }
    match fit_floor(points, &FloorFitConfig::default()) {
        Ok(fit) if fit.confident => Gravity::Estimated(fit),
        Ok(fit) => Gravity::Unknown(GravityUnknown::NotConfident(fit)),
        Err(e) => Gravity::Unknown(GravityUnknown::NoFloor(e)),
    }
}

/// Normals, roughness and the terrain estimate's uncertainty (its method only), at the working
/// size.
type RoughnessMaps = (Grid<Vec3>, Grid<f64>, Option<Grid<f64>>);

/// Working size when no models are loaded, `(width, height)`.
pub const DEFAULT_WORKING_SIZE: (usize, usize) = (256, 256);
/// Stride assumed for network inputs when no models are loaded.
const DEFAULT_STRIDE: usize = 16;

/// The working size for a `(w0, h0)` frame: the longer side takes the manifest's size for it,
/// the shorter side keeps the frame's aspect ratio, rounded to a multiple of `stride` (at least
/// one stride), so the nets never see a stretched image (examples in the tests at the end of this file).
pub(crate) fn fit_aspect(
    working: (usize, usize),
    (w0, h0): (usize, usize),
    stride: usize,
) -> (usize, usize) {
    let round = |v: f64| ((v / stride as f64).round() as usize).max(1) * stride;
    if w0 >= h0 {
        (
            working.0,
            round(working.0 as f64 * h0 as f64 / w0.max(1) as f64),
        )
    } else {
        (
            round(working.1 as f64 * w0 as f64 / h0.max(1) as f64),
            working.1,
        )
    }
}

/// Tensors and geometry buffers reused from frame to frame (reallocated only when the working
/// size grows), and the maps of earlier frames handed back by [`Pipeline::recycle`].
#[derive(Debug, Default)]
struct Scratch {
    rgb: Array4<f32>,
    prior_m: Grid<f64>,
    prior: Array4<f32>,
    points: Array4<f32>,
    valid: Array4<f32>,
    normals: Array4<f32>,
    packed: PackedPoints,
    dsac: DsacScratch,
    spec: SpecMaps,
    sums: SummedMoments,
    spares: Spares,
}

/// The frame at the working size, as the stages see it.
struct Working {
    size: (usize, usize),
    k: Intrinsics,
}

/// The pipeline: optional models (geometric mode needs none) and scratch buffers.
#[derive(Debug)]
pub struct Pipeline {
    models: Option<Models>,
    calibration: Option<Calibration>,
    scratch: Scratch,
}

/// Whether a configuration reads a frame's depth cleaned through the terrain supports
/// ([`clean_points_into`]), under which noise model, and whether the pixels the cleaning fills
/// reach the output.
#[derive(Debug, Clone, Copy)]
struct Cleaning {
    /// The frame's noise model (`None`: exact depth, nothing cleaned).
    noise: Option<SensorNoise>,
    /// The filled pixels are read: only a LiDAR's scan gaps, in `rgbd`. A camera's holes stay
    /// empty: beside an edge (a Kinect's shadow) a hole filled from a support's plane reads
    /// flat where the ground drops (docs/terrain.md).
    reads_filled: bool,
}

impl Cleaning {
    /// `rgbd` with a noise model, and the spec on cleaned depth; `None` for the rest.
    fn of(cfg: &PipelineConfig, input: &FrameInput) -> Option<Self> {
        match (cfg.mode, input.sensor) {
            (Mode::Rgbd, Some(noise)) => Some(Self {
                noise: Some(noise),
                reads_filled: noise.fills_scan_gaps(),
            }),
            _ if cfg.is_spec_cleaned() => Some(Self {
                noise: input.sensor,
                reads_filled: false,
            }),
            _ => None,
        }
    }
}

impl Pipeline {
    /// A pipeline over `models` (`None`: only configurations without networks can run).
    pub fn new(models: Option<Models>) -> Self {
        Self {
            models,
            calibration: None,
            scratch: Scratch::default(),
        }
    }

    /// The same pipeline with calibrated roughness intervals (docs/uncertainty.md; `None`:
    /// the depth modes' maps read the sensor model alone and `rgb` has none).
    pub fn with_calibration(mut self, calibration: Option<Calibration>) -> Self {
        self.calibration = calibration;
        self
    }

    /// The calibration table of `mode`, if the pipeline has one.
    pub fn interval_table(&self, mode: Mode) -> Option<&IntervalTable> {
        self.calibration.as_ref()?.table(mode.as_ref())
    }

    /// The calibrated intervals that apply to what `cfg` runs
    /// ([`PipelineConfig::interval_key`]). The one rule of `tre infer`, the service and the
    /// benchmark.
    pub fn interval_table_for(&self, cfg: &PipelineConfig) -> Option<&IntervalTable> {
        self.calibration.as_ref()?.table(cfg.interval_key()?)
    }

    /// The loaded models, if any.
    pub fn models(&self) -> Option<&Models> {
        self.models.as_ref()
    }

    /// Runs every stage `cfg` chooses on one frame.
    ///
    /// # Errors
    ///
    /// [`PipelineError`] for a frame that is empty, too large, lacks an input the mode needs
    /// or has depth of another size than its RGB; for a configuration whose networks are not
    /// loaded or whose working size is bad; and when a stage fails.
    pub fn run(
        &mut self,
        input: &FrameInput,
        cfg: &PipelineConfig,
    ) -> Result<FrameOutput, PipelineError> {
        let before = self.onnx_runtime_time();
        let mut out = self.run_stages(input, cfg)?;
        let onnx = self.onnx_runtime_time().saturating_sub(before);
        out.timings.set_onnx_runtime(onnx);
        Ok(out)
    }

    /// Takes back the maps of a frame's output once the caller is done with it, so that the
    /// next frames write into their buffers instead of allocating new ones. Optional: a
    /// pipeline whose outputs are simply dropped allocates its maps afresh for every frame.
    /// The next frames' outputs are the same either way.
    pub fn recycle(&mut self, out: FrameOutput) {
        out.give_maps(&mut self.scratch.spares);
    }

    /// Drops every buffer kept from frame to frame (tensors, geometry scratch, the spec's maps,
    /// recycled maps), so that a large frame does not pin its memory until the process ends;
    /// the next frame allocates afresh, as the first one did. The models keep theirs.
    pub fn release_buffers(&mut self) {
        self.scratch = Scratch::default();
    }

    /// Time spent inside ONNX Runtime by the loaded models so far.
    fn onnx_runtime_time(&self) -> Duration {
        self.models
            .as_ref()
            .map_or(Duration::ZERO, Models::onnx_runtime_time)
    }

    /// [`run`](Self::run) without the ONNX Runtime tally.
    fn run_stages(
        &mut self,
        input: &FrameInput,
        cfg: &PipelineConfig,
    ) -> Result<FrameOutput, PipelineError> {
        let size = check_input(input, cfg)?;
        check_dsac_hypotheses(cfg.dsac_hypotheses)?;
        self.check_models(cfg)?;
        let work = self.working(input, cfg, size)?;
        let mut timings = StageTimings::default();
        // RGB goes only to the networks: the geometric mode leaves a frame's image alone.
        let nets_rgb = input.rgb.as_ref().filter(|_| !cfg.networks().is_empty());
        let rgb = timings.time("resize", || {
            nets_rgb.map(|rgb| {
                let small = resize_rgb(rgb, work.size.0, work.size.1);
                rgb_tensor(&small, &mut self.scratch.rgb);
            })
        });
        // Some only when a network runs.
        let has_rgb = rgb.is_some();
        if cfg.method == Method::EndToEnd {
            return self.end_to_end(input, cfg, &work, size, timings);
        }
        let depth_m = timings.time("depth", || self.depth(input, cfg, &work))?;
        let points = timings.time("back_project", || {
            let mut points = self.scratch.spares.take();
            work.k.back_project_map_into(&depth_m, &mut points);
            points
        });
        let cleaning = Cleaning::of(cfg, input);
        let points = match cleaning {
            Some(c) => timings.time("clean", || self.clean(points, &work, c.noise.as_ref())),
            None => points,
        };
        let points = timings.time("tensors", || {
            if has_rgb {
                points_tensors(&points, &mut self.scratch.points, &mut self.scratch.valid);
            }
            points
        });
        let (normals, roughness_m, terrain_u) =
            self.roughness_stages(input, cfg, (&work, &points), &mut timings)?;
        let maps = StageMaps {
            depth_m,
            points,
            normals,
        };
        let gravity = timings.time("gravity", || frame_gravity(input, cfg.mode, &maps.points));
        let mut out = timings.time("outputs", || {
            let (limits, spares) = (cfg.traversability, &mut self.scratch.spares);
            let mut out = FrameOutput::new(size, roughness_m, Some(maps), gravity, limits, spares);
            if let (Mode::Rgbd | Mode::Geometric, Some(given)) = (cfg.mode, &input.depth_m) {
                let filled = cleaning.is_some_and(|c| !c.reads_filled);
                out.keep_holes(given, filled);
                out.implausible = Implausible::of(given, &gravity);
            }
            if let Some(u) = terrain_u {
                out.set_terrain_uncertainty(u);
            }
            out
        });
        out.timings = timings;
        Ok(out)
    }

    /// Normals, roughness and (the terrain estimate's) uncertainty of the working-size points:
    /// the terrain estimate, or the normal and centroid stages and the roughness stage.
    fn roughness_stages(
        &mut self,
        input: &FrameInput,
        cfg: &PipelineConfig,
        (work, points): (&Working, &PointMap),
        timings: &mut StageTimings,
    ) -> Result<RoughnessMaps, PipelineError> {
        if cfg.is_terrain() {
            let maps = timings.time("terrain", || self.terrain(input, work, points));
            return Ok((maps.normals, maps.roughness_m, Some(maps.uncertainty_m)));
        }
        let (normals, centroids) = self.normals_and_centroids(cfg, work, points, timings)?;
        let mut roughness_m = self.scratch.spares.take();
        timings.time("roughness", || {
            let planes = SpecPlanes {
                points,
                normals: &normals,
                centroids: &centroids,
            };
            self.roughness_into(cfg, work.size, &planes, &mut roughness_m);
        });
        self.scratch.spares.keep(centroids);
        Ok((normals, roughness_m, None))
    }

    /// The points read through the terrain supports under the sensor's noise model
    /// ([`clean_points_into`]; `None`: exact depth): what the learned `rgbd` mode and the
    /// spec on cleaned depth read of a sensor's depth.
    fn clean(&mut self, points: PointMap, work: &Working, noise: Option<&SensorNoise>) -> PointMap {
        let mut cleaned = self.scratch.spares.take();
        let (cfg, sums) = (TerrainConfig::default(), &mut self.scratch.sums);
        clean_points_into(&points, &work.k, noise, &cfg, sums, &mut cleaned);
        self.scratch.spares.keep(points);
        cleaned
    }

    /// The terrain estimate of the working-size points, through the frame's noise model.
    fn terrain(&mut self, input: &FrameInput, work: &Working, points: &PointMap) -> TerrainMaps {
        let spares = &mut self.scratch.spares;
        let mut maps = TerrainMaps {
            roughness_m: spares.take(),
            normals: spares.take(),
            uncertainty_m: spares.take(),
        };
        let (noise, sums) = (input.sensor.as_ref(), &mut self.scratch.sums);
        let cfg = TerrainConfig::default();
        terrain_into(points, &work.k, noise, &cfg, sums, &mut maps);
        maps
    }

    /// The roughness stage at the working `size`, into `roughness_m`: spec v1's plane fit for
    /// the geometric mode with the spec method, else the surface term of the normals and
    /// centroids.
    fn roughness_into(
        &mut self,
        cfg: &PipelineConfig,
        (w, h): (usize, usize),
        planes: &SpecPlanes<'_>,
        roughness_m: &mut Grid<f64>,
    ) {
        roughness_m.reset(w, h, f64::NAN);
        if cfg.is_spec() {
            let spec = AnnotateConfig {
                hood: cfg.neighbourhood,
                ..AnnotateConfig::default()
            };
            let maps = &mut self.scratch.spec;
            spec_roughness_into(planes, None, &spec, maps, roughness_m);
        } else {
            surface_term_into(planes.points, planes.normals, planes.centroids, roughness_m);
        }
    }

    /// Normals (initial, refined) and centroids, each timed as its stage.
    fn normals_and_centroids(
        &mut self,
        cfg: &PipelineConfig,
        work: &Working,
        points: &PointMap,
        timings: &mut StageTimings,
    ) -> Result<(Grid<Vec3>, PointMap), PipelineError> {
        let (normals_method, do_refine, centroid_method) = cfg.effective();
        let mut stages = Stages::new(&mut self.models, &mut self.scratch, points);
        let start = std::time::Instant::now();
        let InitialNormals {
            mut normals,
            window_centroids,
        } = stages.initial_normals(normals_method, work.k.fx_px, cfg)?;
        timings.add("normals", start.elapsed());
        if do_refine {
            let start = std::time::Instant::now();
            normals = stages.refined(normals)?;
            timings.add("refine", start.elapsed());
        }
        let start = std::time::Instant::now();
        let centroids = match (centroid_method, window_centroids) {
            (CentroidMethod::Window, Some(c)) => c,
            (CentroidMethod::Window, None) => stages.window_centroids(work.k.fx_px, cfg),
            (CentroidMethod::Net, unused) => stages.net_centroids(&normals, unused)?,
        };
        timings.add("centroid", start.elapsed());
        Ok((normals, centroids))
    }

    /// Depth at the working size: the depth net on RGB and the prior, or the given depth
    /// resized nearest-neighbour.
    fn depth(
        &mut self,
        input: &FrameInput,
        cfg: &PipelineConfig,
        work: &Working,
    ) -> Result<Grid<f64>, PipelineError> {
        let (w, h) = work.size;
        if cfg.mode != Mode::Rgb {
            let given = input.depth_m.as_ref().ok_or(PipelineError::MissingInput {
                mode: "this mode",
                input: "depth",
            })?;
            let mut depth_m = self.scratch.spares.take();
            resize_nearest_reusing(given, (w, h), 0.0, &mut depth_m);
            return Ok(depth_m);
        }
        self.prior_tensor(work, input);
        let models = loaded(&mut self.models)?;
        let (rgb, prior) = (self.scratch.rgb.view(), self.scratch.prior.view());
        let mut depth_m = self.scratch.spares.take();
        models.depth_with(rgb, prior, |t| depth_from_tensor_into(t, &mut depth_m))?;
        Ok(depth_m)
    }

    /// The flat-ground prior depth at the working size into the prior tensor (both buffers
    /// reused across frames).
    fn prior_tensor(&mut self, work: &Working, input: &FrameInput) {
        let (w, h) = work.size;
        let grid = &mut self.scratch.prior_m;
        if grid.size() != (w, h) {
            *grid = Grid::new(w, h, MAX_PRIOR_DEPTH_M);
        }
        prior_depth_into(&work.k, &input.mounting.unwrap_or_default(), grid);
        scalar_tensor(grid, &mut self.scratch.prior);
    }

    /// The end-to-end baseline: RGB and the prior straight to roughness.
    fn end_to_end(
        &mut self,
        input: &FrameInput,
        cfg: &PipelineConfig,
        work: &Working,
        size: (usize, usize),
        mut timings: StageTimings,
    ) -> Result<FrameOutput, PipelineError> {
        let start = std::time::Instant::now();
        self.prior_tensor(work, input);
        let models = loaded(&mut self.models)?;
        let r = models.end_to_end(self.scratch.rgb.view(), self.scratch.prior.view())?;
        // Non-positive and non-finite values read as 0: no negative roughness.
        let mut roughness_m = self.scratch.spares.take();
        depth_from_tensor_into(r.view(), &mut roughness_m);
        timings.add("end_to_end", start.elapsed());
        let mut out = timings.time("outputs", || {
            let gravity = input
                .mounting
                .map_or(Gravity::Unknown(GravityUnknown::NoDepth), Gravity::Stated);
            let (limits, spares) = (cfg.traversability, &mut self.scratch.spares);
            FrameOutput::new(size, roughness_m, None, gravity, limits, spares)
        });
        out.timings = timings;
        Ok(out)
    }

    /// Fails when `cfg` runs networks that are not loaded.
    fn check_models(&self, cfg: &PipelineConfig) -> Result<(), PipelineError> {
        let networks = cfg.networks();
        let missing = match &self.models {
            None => !networks.is_empty(),
            Some(m) => networks.contains(&tre_model::END_TO_END) && !m.has_end_to_end(),
        };
        if missing {
            return Err(PipelineError::ModelsRequired {
                label: cfg.label(),
                networks,
                loaded: self.models.is_some(),
            });
        }
        Ok(())
    }

    /// The working size and the intrinsics scaled to it.
    fn working(
        &self,
        input: &FrameInput,
        cfg: &PipelineConfig,
        (w0, h0): (usize, usize),
    ) -> Result<Working, PipelineError> {
        let nets = !cfg.networks().is_empty();
        let stride = nets.then(|| self.models.as_ref().map_or(DEFAULT_STRIDE, Models::stride));
        let size = match (cfg.working_size, cfg.mode, nets) {
            (Some(size), _, _) => size,
            (None, Mode::Geometric, false) => (w0, h0),
            (None, _, _) => fit_aspect(
                self.models
                    .as_ref()
                    .map_or(DEFAULT_WORKING_SIZE, Models::working_size),
                (w0, h0),
                stride.unwrap_or(DEFAULT_STRIDE),
            ),
        };
        let fits = |s: usize| {
            s > 0 && s <= MAX_WORKING_SIDE && stride.is_none_or(|st| s.is_multiple_of(st))
        };
        if !(fits(size.0) && fits(size.1)) {
            return Err(PipelineError::BadWorkingSize { size, stride });
        }
        let k0 = match input.intrinsics {
            Some(k) => {
                k.check_for(w0, h0)?;
                k
            }
            None => Intrinsics::from_hfov(w0, h0, DEFAULT_HFOV_DEG)?,
        };
        let k = k0.scaled(size.0 as f64 / w0 as f64, size.1 as f64 / h0 as f64)?;
        Ok(Working { size, k })
    }
}

#[cfg(test)]
mod tests {
    use super::fit_aspect;

    #[test]
    fn the_working_size_keeps_the_aspect_in_whole_strides() {
        assert_eq!(fit_aspect((256, 256), (640, 480), 16), (256, 192));
        assert_eq!(fit_aspect((256, 256), (375, 1242), 16), (80, 256));
        assert_eq!(fit_aspect((256, 256), (512, 512), 16), (256, 256));
        assert_eq!(fit_aspect((256, 256), (4000, 1), 16), (256, 16));
    }
}
