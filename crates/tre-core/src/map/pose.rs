//! Where the map lies: its frame (the poses' world turned so that z is gravity's up) and the
//! camera's rigid pose in that world.

use nalgebra::{Matrix3, Matrix4, Vector3};

use super::MapError;
use crate::geometry::floor::{fit_floor, FloorFitConfig};
use crate::geometry::{PointMap, Vec3};

/// The map frame: the world frame of the poses turned so that z is gravity's up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapFrame {
    /// Rotation from the world frame to the map frame.
    pub map_from_world: Matrix3<f64>,
}

impl MapFrame {
    /// The map frame of a world whose gravity (pointing down) is `down`: the rotation taking
    /// `-down` to +z by the shortest turn.
    ///
    /// ```
    /// use tre_core::map::MapFrame;
    /// let f = MapFrame::from_gravity(&nalgebra::Vector3::new(0.0, 1.0, 0.0)).unwrap();
    /// let up = f.map_from_world * nalgebra::Vector3::new(0.0, -1.0, 0.0);
    /// assert!((up - nalgebra::Vector3::z()).norm() < 1e-12);
    /// ```
    pub fn from_gravity(down: &Vec3) -> Result<Self, MapError> {
        let up = -down
            .try_normalize(1e-9)
            .ok_or(MapError::NoGravityDirection([down.x, down.y, down.z]))?;
        let rot = nalgebra::Rotation3::rotation_between(&up, &Vector3::z()).unwrap_or_else(|| {
            nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
        });
        Ok(Self {
            map_from_world: *rot.matrix(),
        })
    }
}

impl MapFrame {
    /// The map frame of a sequence, from the first of: the world's gravity `down` (a
    /// sequence's `gravity.json`), the camera's stated up direction `up_in_cam` (its mounting)
    /// turned into the world by the first frame's `pose`, the ground plane fitted on the first
    /// frame's `points` (only when the fit is confident).
    pub fn levelled(
        down: Option<Vec3>,
        up_in_cam: Option<Vec3>,
        points: &PointMap,
        pose: &Pose,
    ) -> Result<Self, MapError> {
        if let Some(down) = down {
            return Self::from_gravity(&down);
        }
        let up_cam = match up_in_cam {
            Some(up) => up,
            None => {
                let fit = fit_floor(points, &FloorFitConfig::default())
                    .map_err(|_| MapError::NoGround)?;
                if !fit.confident {
                    return Err(MapError::GroundNotConfident {
                        support: fit.support,
                    });
                }
                fit.up_in_cam
            }
        };
        Self::from_gravity(&-(pose.rotation * up_cam))
    }
}

/// A camera-to-world pose checked to be rigid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Rotation, camera to world.
    pub rotation: Matrix3<f64>,
    /// The camera's centre in the world, metres.
    pub translation: Vec3,
}

impl Pose {
    /// The pose of a 4×4 camera-to-world matrix, if it is rigid (within 1e-3).
    ///
    /// ```
    /// use tre_core::map::Pose;
    /// assert!(Pose::from_matrix(&nalgebra::Matrix4::identity()).is_ok());
    /// let mut m = nalgebra::Matrix4::identity();
    /// m[(0, 0)] = 2.0;
    /// assert!(Pose::from_matrix(&m).is_err());
    /// ```
    pub fn from_matrix(m: &Matrix4<f64>) -> Result<Self, MapError> {
        let r: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
        let orth = (r.transpose() * r - Matrix3::identity()).abs().max();
        let det = (r.determinant() - 1.0).abs();
        let last = (m[(3, 0)].abs() + m[(3, 1)].abs() + m[(3, 2)].abs() + (m[(3, 3)] - 1.0).abs())
            .max(0.0);
        let error = orth.max(det).max(last);
        if !(error <= 1e-3) || m.iter().any(|v| !v.is_finite()) {
            return Err(MapError::NotRigid {
                error: if error.is_finite() {
                    error
                } else {
                    f64::INFINITY
                },
            });
        }
        Ok(Self {
            rotation: r,
            translation: Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]),
        })
    }

    /// The pose of 16 numbers, a 4×4 camera-to-world matrix row by row, if it is rigid.
    pub fn from_row_major(v: &[f64]) -> Result<Self, MapError> {
        if v.len() != 16 {
            return Err(MapError::NotRigid {
                error: f64::INFINITY,
            });
        }
        Self::from_matrix(&Matrix4::from_row_slice(v))
    }

    /// The identity: the camera is the world (a robot-centred map of one frame).
    pub fn identity() -> Self {
        Self {
            rotation: Matrix3::identity(),
            translation: Vec3::zeros(),
        }
    }
}
