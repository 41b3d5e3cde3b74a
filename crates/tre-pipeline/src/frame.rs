//! One frame in and its maps out, with per-stage timings; its sensor-noise maps in
//! `frame/sensor.rs`.

use image::RgbImage;
use rayon::prelude::*;

use super::centroid::{slopes, traversable};
use super::gravity::Gravity;
use super::resize::{resize_nearest, resize_nearest_reusing};
use super::spares::Spares;
use super::timings::StageTimings;
use super::Traversability;
use tre_core::geometry::{Grid, Intrinsics, Mounting, PointMap, Vec3, INVALID_POINT};
use tre_core::roughness::annotate::AnnotateConfig;
use tre_core::roughness::annotate::{boundary_mask, segment};
use tre_core::roughness::noise::SensorNoise;

mod sensor;

pub use sensor::SensorMaps;

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
    /// Camera pitch and height, if stated. `None`: slope and traversability take gravity
    /// from the depth's ground plane ([`Gravity`]), unknown without depth; the `rgb` depth
    /// prior assumes 60° down and 1 m ([`Mounting::default`]).
    pub mounting: Option<Mounting>,
    /// The depth sensor's noise model, if known: the `geometric` mode's terrain estimate sizes
    /// its supports and noise margins by it (`None`: read as exact depth).
    pub sensor: Option<SensorNoise>,
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

/// The maps of one frame. Roughness comes at the input frame's size; the other maps stay at the
/// working size and are brought to the frame's size (nearest-neighbour, so no value is blended
/// across an edge) only when asked for, by the methods below.
#[derive(Debug, Clone)]
pub struct FrameOutput {
    /// Roughness (Eq. 1), metres; NaN where there is no data.
    pub roughness_m: Grid<f64>,
    /// The size the stages ran at, `(width, height)`.
    pub working_size: (usize, usize),
    /// Wall time of each stage, in order.
    pub timings: StageTimings,
    /// Where gravity's up axis came from (slope and traversability use it).
    pub gravity: Gravity,
    /// Whether the sensor depth looks wrongly scaled (depth modes).
    pub implausible: Option<super::Implausible>,
    working: WorkingMaps,
}

/// The maps behind a [`FrameOutput`]'s methods, at the working size.
#[derive(Debug, Clone)]
struct WorkingMaps {
    /// Roughness at the working size; `None` when the frame is at the working size.
    roughness_m: Option<Grid<f64>>,
    /// `None` for the end-to-end baseline.
    stages: Option<StageMaps>,
    /// Gravity's up axis in the camera frame; `None`: unknown.
    up_in_cam: Option<Vec3>,
    limits: Traversability,
    /// The terrain estimate's noise margin at the working size (geometric mode, terrain
    /// method): its uncertainty map, in place of the spec's noise model.
    terrain_uncertainty_m: Option<Grid<f64>>,
}

/// The staged pipeline's depth, points and final normals at the working size.
#[derive(Debug, Clone)]
pub(crate) struct StageMaps {
    pub(crate) depth_m: Grid<f64>,
    pub(crate) points: PointMap,
    pub(crate) normals: Grid<Vec3>,
}

impl FrameOutput {
    /// The output of a frame of `size` from maps at the working size: roughness (always), the
    /// stages' maps (`None` for the end-to-end baseline), gravity and the traversability
    /// thresholds. A grid from `spare` becomes the roughness at the
    /// frame's size when that differs from the working size.
    pub(crate) fn new(
        size: (usize, usize),
        roughness_m: Grid<f64>,
        stages: Option<StageMaps>,
        gravity: Gravity,
        limits: Traversability,
        spare: &mut Spares,
    ) -> Self {
        let working_size = roughness_m.size();
        let (roughness_m, working_roughness) = if working_size == size {
            (roughness_m, None)
        } else {
            let mut full = spare.take();
            resize_nearest_reusing(&roughness_m, size, f64::NAN, &mut full);
            (full, Some(roughness_m))
        };
        Self {
            roughness_m,
            working_size,
            timings: StageTimings::default(),
            gravity,
            implausible: None,
            working: WorkingMaps {
                roughness_m: working_roughness,
                stages,
                up_in_cam: gravity.up_in_cam(),
                limits,
                terrain_uncertainty_m: None,
            },
        }
    }

    /// Marks no roughness wherever the frame's own depth (`depth_m`, at the frame's size) has
    /// none: a hole's nearest pixel at the working size may have had depth, and depth cleaned
    /// with its holes `filled` has points there. (Otherwise pixels whose nearest working pixel
    /// was a hole have no roughness already.) A no-op when the depth is of another size, or
    /// the frame was run at its own size and nothing was filled.
    pub(crate) fn keep_holes(&mut self, depth_m: &Grid<f64>, filled: bool) {
        let own_size = self.working.roughness_m.is_none();
        if (own_size && !filled) || depth_m.size() != self.roughness_m.size() {
            return;
        }
        let r = self.roughness_m.as_mut_slice();
        r.par_iter_mut()
            .zip(depth_m.as_slice())
            .for_each(|(r, &d)| {
                if !(d.is_finite() && d > 0.0) {
                    *r = f64::NAN;
                }
            });
    }

    /// Keeps the terrain estimate's uncertainty (at the working size) for [`Self::sensor_maps`].
    pub(crate) fn set_terrain_uncertainty(&mut self, u: Grid<f64>) {
        self.working.terrain_uncertainty_m = Some(u);
    }

    /// Hands every map of this output to `spares`, for the next frames.
    pub(crate) fn give_maps(self, spares: &mut Spares) {
        spares.keep(self.roughness_m);
        let WorkingMaps {
            roughness_m,
            stages,
            terrain_uncertainty_m,
            ..
        } = self.working;
        if let Some(r) = roughness_m {
            spares.keep(r);
        }
        if let Some(u) = terrain_uncertainty_m {
            spares.keep(u);
        }
        if let Some(m) = stages {
            spares.keep(m.depth_m);
            spares.keep(m.points);
            spares.keep(m.normals);
        }
    }

    /// `map` (at the working size) at the frame's size.
    fn full_size<T: Clone + Send + Sync>(&self, map: &Grid<T>, fill: T) -> Grid<T> {
        let (w, h) = self.roughness_m.size();
        resize_nearest(map, w, h, fill)
    }

    /// Depth used, metres (0: none); `None` for the end-to-end baseline.
    pub fn depth_m(&self) -> Option<Grid<f64>> {
        let d = &self.working.stages.as_ref()?.depth_m;
        Some(self.full_size(d, 0.0))
    }

    /// Unit normals in the camera frame, facing the camera (NaN: none); `None` for the
    /// end-to-end baseline.
    pub fn normals(&self) -> Option<Grid<Vec3>> {
        let n = &self.working.stages.as_ref()?.normals;
        Some(self.full_size(n, INVALID_POINT))
    }

    /// Slope of the normals in the gravity frame, radians (NaN: none, or gravity unknown);
    /// `None` for the end-to-end baseline.
    pub fn slope_rad(&self) -> Option<Grid<f64>> {
        let n = &self.working.stages.as_ref()?.normals;
        let Some(up) = self.working.up_in_cam else {
            let (w, h) = self.roughness_m.size();
            return Some(Grid::new(w, h, f64::NAN));
        };
        Some(self.full_size(&slopes(n, &up), f64::NAN))
    }

    /// Boundary pixels by annotation spec v1, steps 2 and 3, on the pipeline's own points and
    /// normals (one label): valid pixels with a valid 8-neighbour in another smooth segment,
    /// i.e. depth steps and creases; no pixel without roughness (a sensor's hole) is one.
    /// `None` for the end-to-end baseline.
    pub fn boundary(&self) -> Option<Grid<bool>> {
        let m = self.working.stages.as_ref()?;
        let segments = segment(&m.points, &m.normals, None, &AnnotateConfig::default());
        let mut full = self.full_size(&boundary_mask(&m.points, &segments), false);
        self.only_with_roughness(&mut full);
        Some(full)
    }

    /// Clears `mask` wherever the frame-size roughness is missing.
    fn only_with_roughness(&self, mask: &mut Grid<bool>) {
        for (t, r) in mask
            .as_mut_slice()
            .iter_mut()
            .zip(self.roughness_m.as_slice())
        {
            *t &= r.is_finite();
        }
    }

    /// Pixels whose roughness and slope are within the thresholds (roughness only for the
    /// end-to-end baseline; no data is not traversable, and with gravity unknown no pixel is
    /// unless the slope threshold is 90°).
    pub fn traversable(&self) -> Grid<bool> {
        self.within(&self.working.limits)
    }

    /// Pixels within `limits` at the frame's size; no pixel without roughness at the frame's
    /// size passes (a sensor's hole).
    fn within(&self, limits: &Traversability) -> Grid<bool> {
        let w = &self.working;
        let roughness = w.roughness_m.as_ref().unwrap_or(&self.roughness_m);
        if self.slope_without_gravity(limits) {
            let (w, h) = self.roughness_m.size();
            return Grid::new(w, h, false);
        }
        let tilt = w
            .stages
            .as_ref()
            .zip(w.up_in_cam.as_ref())
            .map(|(m, up)| (&m.normals, up));
        let mut full = self.full_size(&traversable(roughness, tilt, limits), false);
        self.only_with_roughness(&mut full);
        full
    }

    /// Whether `limits` test a slope (below 90°) that this output cannot judge: it has normals
    /// but no gravity.
    fn slope_without_gravity(&self, limits: &Traversability) -> bool {
        let w = &self.working;
        limits.max_slope_rad < std::f64::consts::FRAC_PI_2
            && w.stages.is_some()
            && w.up_in_cam.is_none()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Mode, PipelineError};
    use tre_core::roughness::noise::SensorPreset;
    use tre_core::roughness::traversal::Traversal;

    /// A 2×2 working-size result for a 4×2 frame: left column rough, bottom-right too steep.
    fn output() -> FrameOutput {
        output_with(Gravity::Stated(Mounting::default()))
    }

    /// [`output`] with another gravity.
    fn output_with(gravity: Gravity) -> FrameOutput {
        let up = Mounting::default().up_in_cam();
        let roughness = Grid::from_fn(2, 2, |x, _| if x == 0 { 0.2 } else { 0.01 });
        let normals = Grid::from_fn(2, 2, |x, y| {
            if (x, y) == (1, 1) {
                Vec3::new(1.0, 0.0, 0.0)
            } else {
                -up
            }
        });
        let depth_m = Grid::from_fn(2, 2, |x, y| 1.0 + x as f64 + 2.0 * y as f64);
        let points = Grid::new(2, 2, Vec3::new(0.0, 0.0, 1.0));
        let maps = StageMaps {
            depth_m,
            points,
            normals,
        };
        FrameOutput::new(
            (4, 2),
            roughness,
            Some(maps),
            gravity,
            Traversability::default(),
            &mut Spares::default(),
        )
    }

    #[test]
    fn maps_come_at_the_frame_size_when_asked_for() {
        let out = output();
        assert_eq!(out.working_size, (2, 2));
        assert_eq!(out.roughness_m.size(), (4, 2));
        assert_eq!(out.roughness_m.row(0), &[0.2, 0.2, 0.01, 0.01]);
        let depth = out.depth_m().expect("depth");
        assert_eq!(depth.row(1), &[3.0, 3.0, 4.0, 4.0]);
        let ok = out.traversable();
        assert_eq!(ok.row(0), &[false, false, true, true]);
        assert_eq!(ok.row(1), &[false, false, false, false]);
        let slope = out.slope_rad().expect("slope");
        assert!(slope[(3, 0)].abs() < 1e-7);
        assert!(slope[(3, 1)] > 20f64.to_radians());
        assert_eq!(out.normals().expect("normals").size(), (4, 2));
    }

    #[test]
    fn sensor_maps_need_sensor_depth_and_a_noise_model() {
        let out = output();
        let frame = FrameInput {
            depth_m: Some(Grid::new(4, 2, 1.5)),
            ..FrameInput::default()
        };
        let kinect = SensorNoise::Preset(SensorPreset::KinectV1);
        let e = out.sensor_maps(&frame, Mode::Rgb, Some(&kinect), None, None);
        assert!(matches!(
            e,
            Err(PipelineError::NoSensorDepth { mode: "rgb" })
        ));
        let e = out.sensor_maps(&frame, Mode::Rgbd, None, Some("Kinect"), None);
        let e = e.err().map(|e| e.to_string()).unwrap_or_default();
        assert!(
            e.contains("kinect_v1") && e.contains("\"Kinect\" names no preset"),
            "{e}"
        );
        let maps = out
            .sensor_maps(&frame, Mode::Rgbd, Some(&kinect), None, None)
            .unwrap();
        // The left column is rough (0.2 m, a drop above the noise): a hazard; the top right
        // is flat with millimetres of noise: traversable.
        assert_eq!(maps.traversal[(0, 0)], Traversal::Hazard);
        assert_eq!(maps.traversal[(3, 0)], Traversal::Traversable);
        // (At 0.43 m per pixel no neighbour lies within R: no surface term, so no noise in it.)
        assert!((0.0..0.01).contains(&maps.uncertainty_m[(3, 0)]));
    }

    #[test]
    fn without_gravity_nothing_is_traversable_and_flat_is_unknown() {
        let out = output_with(Gravity::Unknown(crate::gravity::GravityUnknown::NoDepth));
        assert!(out.traversable().as_slice().iter().all(|&t| !t));
        assert!(out
            .slope_rad()
            .unwrap()
            .as_slice()
            .iter()
            .all(|s| s.is_nan()));
        let frame = FrameInput {
            depth_m: Some(Grid::new(4, 2, 1.5)),
            ..FrameInput::default()
        };
        let kinect = SensorNoise::Preset(SensorPreset::KinectV1);
        let maps = out
            .sensor_maps(&frame, Mode::Rgbd, Some(&kinect), None, None)
            .unwrap();
        // Rough is still a hazard; flat cannot be called traversable without gravity.
        assert_eq!(maps.traversal[(0, 0)], Traversal::Hazard);
        assert_eq!(maps.traversal[(3, 0)], Traversal::Unknown);
        // A slope threshold of 90° needs no gravity.
        let mut flat_only = output_with(Gravity::Unknown(crate::gravity::GravityUnknown::NoDepth));
        flat_only.working.limits.max_slope_rad = std::f64::consts::FRAC_PI_2;
        assert_eq!(flat_only.traversable().row(0), &[false, false, true, true]);
    }

    #[test]
    fn boundary_marks_both_sides_of_a_depth_step() {
        let points = Grid::from_fn(6, 2, |x, y| {
            let z = if x < 3 { 1.0 } else { 1.2 };
            Vec3::new(0.01 * x as f64, 0.01 * y as f64, z)
        });
        let maps = StageMaps {
            depth_m: points.map(|p| p.z),
            normals: Grid::new(6, 2, Vec3::new(0.0, 0.0, -1.0)),
            points,
        };
        let out = FrameOutput::new(
            (12, 2),
            Grid::new(6, 2, 0.0),
            Some(maps),
            Gravity::Stated(Mounting::default()),
            Traversability::default(),
            &mut Spares::default(),
        );
        let b = out.boundary().expect("boundary");
        assert_eq!(b.size(), (12, 2));
        let row: Vec<bool> = (0..12).map(|x| b[(x, 0)]).collect();
        let expect: Vec<bool> = (0..12).map(|x| (4..8).contains(&x)).collect();
        assert_eq!(row, expect);
    }

    #[test]
    fn the_end_to_end_baseline_has_only_roughness_and_traversability() {
        let out = FrameOutput::new(
            (2, 2),
            Grid::new(2, 2, 0.01),
            None,
            Gravity::Stated(Mounting::default()),
            Traversability::default(),
            &mut Spares::default(),
        );
        assert!(out.depth_m().is_none() && out.normals().is_none() && out.slope_rad().is_none());
        assert!(out.boundary().is_none());
        assert!(out.traversable().as_slice().iter().all(|&t| t));
    }
}
