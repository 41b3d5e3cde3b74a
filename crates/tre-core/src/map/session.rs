//! One map session: how `tre map`, the stream and `tre ros2` start a map (its centre and
//! gravity), fuse frames into it, skip the ones it cannot take with a typed reason, and read
//! its layers (docs/map.md).

use nalgebra::Vector3;

use super::{FuseStats, GridMap, Layers, MapError, MapFrame, MapParams, Pose};
use crate::geometry::floor::{fit_floor, FloorFitConfig};
use crate::geometry::{PointMap, Vec3};
use crate::roughness::noise::SensorNoise;

/// Where a session's up comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GravitySource {
    /// The world's down direction in the poses' frame (a sequence's `gravity.json`, a robot's
    /// levelled odometry frame): the map frame is fixed by it.
    Given(Vec3),
    /// The camera's up direction as mounted (its stated pitch), turned into the world by the
    /// first fused frame's pose.
    Stated(Vec3),
    /// The ground: every frame's confident ground fit turned into the world by its pose,
    /// averaged over the frames; the map starts at the first confident fit and is levelled
    /// again as the average moves.
    Ground,
}

/// One frame as the map takes it.
#[derive(Debug, Clone, Copy)]
pub struct SessionFrame<'a> {
    /// The frame's points in the camera frame (its back-projected depth).
    pub points: &'a PointMap,
    /// The camera-to-world pose; `None`: the frame alone, a map centred on the camera that
    /// restarts with every frame.
    pub pose: Option<Pose>,
    /// The frame's time, seconds.
    pub t_s: f64,
    /// The frame's confident ground fit (the up axis in the camera frame), when its caller
    /// already has one; the session fits the ground itself when it needs one and has none.
    pub ground_up_in_cam: Option<Vec3>,
}

/// Levels below which the average up is taken to have moved, radians (0.1°).
const RELEVEL_RAD: f64 = 0.1 * std::f64::consts::PI / 180.0;

/// A map session: the settings, the gravity source, the map once started and its counts.
#[derive(Debug, Clone)]
pub struct MapSession {
    params: MapParams,
    gravity: GravitySource,
    sensor: SensorNoise,
    map: Option<GridMap>,
    /// Sum of the confident ground fits' up directions in the world, and their count.
    up_sum: (Vec3, u32),
    fused: u64,
    skipped: u64,
    last_skip: Option<MapError>,
}

impl MapSession {
    /// A session with these settings, not yet started, for a depth sensor of noise model
    /// `sensor` (the heights' variances come from it).
    pub fn new(params: MapParams, gravity: GravitySource, sensor: SensorNoise) -> Self {
        Self {
            params,
            gravity,
            sensor,
            map: None,
            up_sum: (Vec3::zeros(), 0),
            fused: 0,
            skipped: 0,
            last_skip: None,
        }
    }

    /// Fuses `frame`, starting the map at the first frame it can (the window centred under
    /// the camera, levelled by the gravity source).
    ///
    /// # Errors
    ///
    /// Why the frame was skipped ([`MapError`]: a camera beyond the window, nothing in range,
    /// no gravity to start by); it is counted, and the map keeps what it had.
    pub fn fuse(&mut self, frame: &SessionFrame<'_>) -> Result<FuseStats, MapError> {
        match self.try_fuse(frame) {
            Ok(stats) => {
                self.fused += 1;
                Ok(stats)
            }
            Err(e) => {
                self.skipped += 1;
                self.last_skip = Some(e.clone());
                Err(e)
            }
        }
    }

    fn try_fuse(&mut self, frame: &SessionFrame<'_>) -> Result<FuseStats, MapError> {
        let pose = match frame.pose {
            Some(p) => p,
            None => {
                self.map = None;
                self.up_sum = (Vec3::zeros(), 0);
                Pose::identity()
            }
        };
        if let GravitySource::Ground = self.gravity {
            self.add_ground(frame, &pose)?;
        }
        let map = match &mut self.map {
            Some(m) => m,
            None => {
                let down = self.down(&pose)?;
                let m = GridMap::under(self.params.config, MapFrame::from_gravity(&down)?, &pose)?;
                self.map.insert(m)
            }
        };
        map.fuse(frame.points, &pose, frame.t_s, &self.sensor)
    }

    /// The world's down direction to start the map by.
    fn down(&self, pose: &Pose) -> Result<Vec3, MapError> {
        match self.gravity {
            GravitySource::Given(down) => Ok(down),
            GravitySource::Stated(up) => Ok(-(pose.rotation * up)),
            GravitySource::Ground => {
                let (sum, n) = self.up_sum;
                if n == 0 {
                    return Err(MapError::NoGround);
                }
                Ok(-sum)
            }
        }
    }

    /// Adds the frame's ground fit (its own, or one fitted here while the map waits for one)
    /// to the average up, and levels the map again when the average has moved.
    fn add_ground(&mut self, frame: &SessionFrame<'_>, pose: &Pose) -> Result<(), MapError> {
        let up = match frame.ground_up_in_cam {
            Some(up) => Some(up),
            None if self.map.is_none() => {
                let fit = fit_floor(frame.points, &FloorFitConfig::default())
                    .map_err(|_| MapError::NoGround)?;
                if !fit.confident {
                    return Err(MapError::GroundNotConfident {
                        support: fit.support,
                    });
                }
                Some(fit.up_in_cam)
            }
            None => None,
        };
        let Some(up) = up.and_then(|u| u.try_normalize(1e-9)) else {
            return Ok(());
        };
        self.up_sum.0 += pose.rotation * up;
        self.up_sum.1 += 1;
        if let Some(map) = &mut self.map {
            let now = map.frame().map_from_world.transpose() * Vector3::z();
            if now.angle(&self.up_sum.0) > RELEVEL_RAD {
                map.relevel(MapFrame::from_gravity(&-self.up_sum.0)?);
            }
        }
        Ok(())
    }

    /// The settings.
    pub fn params(&self) -> &MapParams {
        &self.params
    }

    /// The map, once a frame started it.
    pub fn map(&self) -> Option<&GridMap> {
        self.map.as_ref()
    }

    /// The map's layers under the session's limits, once a frame started it.
    pub fn layers(&self) -> Option<Layers> {
        self.map.as_ref().map(|m| m.layers(&self.params.limits))
    }

    /// Frames fused.
    pub fn fused(&self) -> u64 {
        self.fused
    }

    /// Frames skipped, and why the last one was.
    pub fn skipped(&self) -> (u64, Option<&MapError>) {
        (self.skipped, self.last_skip.as_ref())
    }

    /// Gravity's up axis in the camera frame of `pose`, as the map holds it (the sequence's
    /// gravity, not one frame's), once the map has started.
    pub fn up_in_cam(&self, pose: &Pose) -> Option<Vec3> {
        let map = self.map.as_ref()?;
        let up_world = map.frame().map_from_world.transpose() * Vector3::z();
        Some(pose.rotation.transpose() * up_world)
    }
}
