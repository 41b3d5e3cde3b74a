//! The gravity frame: the camera frame rotated by the known pitch β and lifted by the camera
//! height h, with x right, y forward (horizontal) and z up; the ground under the robot is z = 0.

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use super::{GeometryError, Vec3};

/// Camera mounting: pitch below the horizon and height above the ground.
///
/// ```
/// use tre_core::geometry::{Intrinsics, Mounting};
/// let m = Mounting::new(60f64.to_radians(), 1.0).unwrap();
/// // The optical axis hits the ground h / sin β in front of the camera.
/// let p_cam = nalgebra::Vector3::new(0.0, 0.0, 1.0 / 60f64.to_radians().sin());
/// let g = m.gravity_from_cam_point(&p_cam);
/// assert!(g.z.abs() < 1e-12);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Mounting {
    /// Pitch of the optical axis below the horizon, radians (default 60°).
    pub pitch_rad: f64,
    /// Height of the camera centre above the ground, metres (default 1 m).
    pub height_m: f64,
}

impl Default for Mounting {
    fn default() -> Self {
        Self {
            pitch_rad: 60f64.to_radians(),
            height_m: 1.0,
        }
    }
}

impl Mounting {
    /// Checked mounting: pitch within [-90°, 90°], height finite and non-negative.
    pub fn new(pitch_rad: f64, height_m: f64) -> Result<Self, GeometryError> {
        let half_pi = std::f64::consts::FRAC_PI_2 + 1e-12;
        if !(pitch_rad.is_finite() && pitch_rad.abs() <= half_pi) {
            return Err(GeometryError::BadPitch { pitch_rad });
        }
        if !(height_m.is_finite() && height_m >= 0.0) {
            return Err(GeometryError::BadHeight { height_m });
        }
        Ok(Self {
            pitch_rad,
            height_m,
        })
    }

    /// Rotation taking camera-frame vectors into the gravity frame.
    pub fn gravity_from_cam(&self) -> Matrix3<f64> {
        let (s, c) = self.pitch_rad.sin_cos();
        // Columns: the camera's x (right), y (down in the image) and z (optical axis).
        Matrix3::from_columns(&[
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.0, -s, -c),
            Vector3::new(0.0, c, -s),
        ])
    }

    /// A camera-frame point in the gravity frame.
    pub fn gravity_from_cam_point(&self, p_cam: &Vec3) -> Vec3 {
        self.gravity_from_cam() * p_cam + Vector3::new(0.0, 0.0, self.height_m)
    }

    /// Gravity's up axis in the camera frame (the last row of
    /// [`gravity_from_cam`](Self::gravity_from_cam)).
    ///
    /// ```
    /// let m = tre_core::geometry::Mounting::default();
    /// let up = m.up_in_cam();
    /// assert!((m.gravity_from_cam() * up - nalgebra::Vector3::z()).norm() < 1e-12);
    /// ```
    pub fn up_in_cam(&self) -> Vec3 {
        let (s, c) = self.pitch_rad.sin_cos();
        Vector3::new(0.0, -c, -s)
    }

    /// Slope of a camera-frame surface normal: its angle to gravity's up, radians in [0, π/2]
    /// (the normal's sign does not matter).
    ///
    /// ```
    /// let m = tre_core::geometry::Mounting::default();
    /// let flat = m.slope_rad(&-m.up_in_cam());
    /// assert!(flat.abs() < 1e-7);
    /// ```
    pub fn slope_rad(&self, normal_cam: &Vec3) -> f64 {
        slope_from_up(&self.up_in_cam(), normal_cam)
    }
}

/// The angle between the line of `normal` and the unit vector `up`, radians in [0, π/2]; NaN
/// for a zero or non-finite normal.
pub fn slope_from_up(up: &Vec3, normal: &Vec3) -> f64 {
    let len = normal.norm();
    if len == 0.0 || !len.is_finite() {
        return f64::NAN;
    }
    (up.dot(normal).abs() / len).min(1.0).acos()
}
